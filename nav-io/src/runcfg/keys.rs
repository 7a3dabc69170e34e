//! Which table of a run configuration a key belongs to, for the error about a key written in
//! the wrong table (`sigma_scale` under `[imu]` instead of `[gnss]`). The tables and their
//! keys are asked of the parser itself, so they follow the configuration's types: a probe key
//! in a table makes the parser refuse it with the list of that table's keys.

use super::RunConfig;
use std::sync::OnceLock;

/// A table of the configuration: its dotted path ("" for the top level) and its keys.
type TableKeys = (String, Vec<String>);

/// The keys of `table` (dotted path, "" for the top level) as the parser lists them when it
/// refuses an unknown key there; `None` when `table` is not a table of fixed keys.
fn probe(table: &str) -> Option<Vec<String>> {
    let text = if table.is_empty() {
        "__probe__ = 1\n".to_string()
    } else {
        format!("[{table}]\n__probe__ = 1\n")
    };
    let e = toml::from_str::<RunConfig>(&text).err()?;
    let (_, list) = e
        .message()
        .split_once("unknown field `__probe__`, expected ")?;
    let keys: Vec<String> = list
        .lines()
        .next()?
        .split('`')
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect();
    (!keys.is_empty()).then_some(keys)
}

/// Every table of fixed keys in a run configuration, with its keys (found once).
fn tables() -> &'static [TableKeys] {
    static TABLES: OnceLock<Vec<TableKeys>> = OnceLock::new();
    TABLES.get_or_init(|| {
        let mut out = Vec::new();
        let mut todo = vec![String::new()];
        while let Some(path) = todo.pop() {
            let Some(keys) = probe(&path) else {
                continue;
            };
            for k in &keys {
                todo.push(if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                });
            }
            out.push((path, keys));
        }
        out.sort();
        out
    })
}

/// `[path]`, or "the top level" for "".
fn shown(path: &str) -> String {
    if path.is_empty() {
        "the top level (before any [table])".to_string()
    } else {
        format!("[{path}]")
    }
}

/// The table whose header precedes byte `at` of `text` ("" before any header).
fn header_before(text: &str, at: usize) -> String {
    let head = text.get(..at).unwrap_or(text);
    head.lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('[') && !l.starts_with("[["))
        .and_then(|l| l.strip_prefix('[')?.split(']').next())
        .map(|t| t.split('.').map(str::trim).collect::<Vec<_>>().join("."))
        .unwrap_or_default()
}

/// For the parser's error about an unknown key that is a key of another table: "`k` is a key
/// of [gnss], not [imu]". `message` is the parser's message (`unknown field `k`, expected one
/// of ...`), `at` the byte offset of the key in `text`. `None` for any other error, or a key
/// of no other table.
pub(super) fn wrong_table_hint(message: &str, text: &str, at: Option<usize>) -> Option<String> {
    let (_, rest) = message.split_once("unknown field `")?;
    let (bad, rest) = rest.split_once('`')?;
    let here: Vec<&str> = rest
        .lines()
        .next()
        .unwrap_or("")
        .split('`')
        .skip(1)
        .step_by(2)
        .collect();
    let tables = tables();
    // the table the key was written in: the one whose keys the parser listed (the header
    // before the key when several tables have the same keys)
    let same: Vec<&str> = tables
        .iter()
        .filter(|(_, keys)| keys.iter().map(String::as_str).eq(here.iter().copied()))
        .map(|(p, _)| p.as_str())
        .collect();
    let header = at.map(|a| header_before(text, a));
    let current = match (same.as_slice(), header) {
        ([one], _) => (*one).to_string(),
        (_, Some(h)) => h,
        _ => return None,
    };
    let homes: Vec<String> = tables
        .iter()
        .filter(|(p, keys)| *p != current && keys.iter().any(|k| k == bad))
        .map(|(p, _)| shown(p))
        .collect();
    if homes.is_empty() {
        return None;
    }
    let listed = match homes.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
        _ => homes.join(""),
    };
    Some(format!(
        "`{bad}` is a key of {listed}, not {}",
        shown(&current)
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tables_are_found_from_the_parser() {
        let t = tables();
        let keys = |p: &str| &t.iter().find(|(q, _)| q == p).unwrap().1;
        assert!(keys("").contains(&"imu".to_string()));
        assert!(keys("gnss").contains(&"sigma_scale".to_string()));
        assert!(keys("imu").contains(&"time_offset_s".to_string()));
        assert!(t.iter().any(|(p, _)| p == "init.align"), "{t:?}");
    }
}
