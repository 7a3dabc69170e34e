//! The first lines of a text file as a table: comment and header lines, the separator, the
//! fields of each data row, which columns are numbers.

use std::path::Path;

/// Lines read at most from a file's start.
pub(crate) const MAX_LINES: usize = 100_000;

/// The start of a text file split into fields.
#[derive(Debug, Clone, Default)]
pub(crate) struct Table {
    /// Physical lines before the first data row (comments, header).
    pub skip_lines: usize,
    /// The header's names (the last non-data line before the data, `#`/`%` removed), when its
    /// fields are not numbers.
    pub names: Option<Vec<String>>,
    /// Comma-separated (else white space).
    pub comma: bool,
    /// Fields of each data row (rows with the modal field count only).
    pub rows: Vec<Vec<String>>,
    /// Field count of the data rows.
    pub width: usize,
    /// The raw lines before the data (comments and header).
    pub head: Vec<String>,
    /// The rows are separated by `;` (a separator init and the readers do not take): the
    /// first such row.
    pub semicolons: Option<SemicolonRows>,
}

/// Rows separated by `;` (see [`Table::semicolons`]).
#[derive(Debug, Clone, Default)]
pub(crate) struct SemicolonRows {
    /// 1-based line of the first such row.
    pub line: usize,
    /// Its text.
    pub text: String,
    /// Its numbers are written with a decimal comma (`9,81`).
    pub decimal_comma: bool,
}

impl SemicolonRows {
    /// What a user is told: the separator, where, and how to convert the file.
    pub fn describe(&self) -> String {
        let mut shown: String = self.text.chars().take(60).collect();
        if shown.len() < self.text.len() {
            shown.push_str("...");
        }
        let (what, sed) = if self.decimal_comma {
            (
                " and the numbers have decimal commas",
                "replace each ',' by '.' and then each ';' by ',' (e.g. `sed 's/,/./g; s/;/,/g'`)",
            )
        } else {
            ("", "replace each ';' by ',' (e.g. `sed 's/;/,/g'`)")
        };
        format!(
            "the rows are separated by ';'{what} (line {}: `{shown}`): init and the readers \
             take commas or white space between the columns; {sed} and give init the converted \
             file",
            self.line
        )
    }
}

/// A row whose fields are separated by `;`: at least 3 fields, most of them numbers (with a
/// decimal point or a decimal comma).
fn semicolon_row(l: &str) -> Option<bool> {
    let f: Vec<&str> = l.split(';').map(str::trim).collect();
    if f.len() < 3 {
        return None;
    }
    let point = f.iter().filter(|x| is_num(x)).count();
    let comma = f.iter().filter(|x| is_num(&x.replace(',', "."))).count();
    (comma * 2 >= f.len()).then_some(comma > point)
}

/// The first row of `lines` separated by `;`, when most rows (not comments or blank) are.
fn semicolons(lines: &[String]) -> Option<SemicolonRows> {
    let rows = lines.iter().enumerate().filter(|(_, l)| {
        let t = l.trim();
        !t.is_empty() && !t.starts_with('#') && !t.starts_with('%')
    });
    let (mut n, mut found) = (0usize, Vec::new());
    for (i, l) in rows {
        n += 1;
        if let Some(dc) = semicolon_row(l.trim()) {
            found.push((i, dc));
        }
    }
    let &(i, decimal_comma) = found.first()?;
    (found.len() * 2 > n).then(|| SemicolonRows {
        line: i + 1,
        text: lines[i].trim().to_string(),
        decimal_comma,
    })
}

fn split(line: &str, comma: bool) -> Vec<String> {
    if comma {
        let mut v: Vec<String> = line.split(',').map(|s| s.trim().to_string()).collect();
        if v.len() > 1 && v.last().is_some_and(String::is_empty) {
            v.pop();
        }
        v
    } else {
        line.split_whitespace().map(str::to_string).collect()
    }
}

fn is_num(s: &str) -> bool {
    nav_io::parse_f64(s).is_some()
}

impl Table {
    /// Reads up to [`MAX_LINES`] lines of `path` (gzip accepted).
    pub fn read(path: &Path) -> anyhow::Result<Self> {
        let mut rd = nav_io::open_text(path)?;
        let mut lines: Vec<String> = Vec::new();
        while let Some((_, l)) = rd.next_raw()? {
            lines.push(l.trim_start_matches('\u{feff}').to_string());
            if lines.len() >= MAX_LINES {
                break;
            }
        }
        Ok(Self::from_lines(&lines))
    }

    /// The table of `lines`: a data row is one whose fields are mostly numbers (or a date-time
    /// text and a name followed by numbers); everything before the first is head.
    pub fn from_lines(lines: &[String]) -> Self {
        let is_data = |l: &str| {
            let t = l.trim();
            if t.is_empty() || t.starts_with('#') || t.starts_with('%') {
                return false;
            }
            let f = split(t, t.contains(','));
            let nums = f.iter().filter(|x| is_num(x)).count();
            f.len() >= 3 && nums * 2 >= f.len()
        };
        let first = lines.iter().position(|l| is_data(l)).unwrap_or(lines.len());
        let comma = lines.get(first).is_some_and(|l| l.contains(','));
        let names = lines[..first]
            .iter()
            .rev()
            .find(|l| !l.trim().is_empty())
            .map(|l| {
                let l = l.trim().trim_start_matches(['#', '%']).trim();
                split(l, comma)
                    .into_iter()
                    .map(|n| n.split_whitespace().next().unwrap_or("").to_string())
                    .collect::<Vec<_>>()
            })
            .filter(|n| n.len() >= 3 && n.iter().all(|x| !is_num(x) && !x.is_empty()));
        let all: Vec<Vec<String>> = lines[first..]
            .iter()
            .map(|l| l.trim())
            .filter(|l| !l.is_empty() && !l.starts_with('#') && !l.starts_with('%'))
            .map(|l| split(l, comma))
            .collect();
        // the modal width
        let mut counts = std::collections::BTreeMap::new();
        for r in &all {
            *counts.entry(r.len()).or_insert(0usize) += 1;
        }
        let width = counts
            .iter()
            .max_by_key(|(_, n)| **n)
            .map_or(0, |(w, _)| *w);
        Self {
            skip_lines: first,
            names,
            comma,
            rows: all.into_iter().filter(|r| r.len() == width).collect(),
            width,
            head: lines[..first].to_vec(),
            semicolons: semicolons(lines),
        }
    }

    /// Column `c` (0-based) as numbers (NaN where not a number).
    pub fn col(&self, c: usize) -> Vec<f64> {
        self.rows
            .iter()
            .map(|r| {
                r.get(c)
                    .and_then(|s| nav_io::parse_f64(s))
                    .unwrap_or(f64::NAN)
            })
            .collect()
    }

    /// Whether column `c` holds numbers in every row.
    pub fn numeric(&self, c: usize) -> bool {
        !self.rows.is_empty() && self.col(c).iter().all(|v| v.is_finite())
    }

    /// The column reference to write: the header's name when it is unique, else the 1-based
    /// index.
    pub fn column_ref(&self, c: usize) -> String {
        match &self.names {
            Some(n) if n.len() == self.width && n.iter().filter(|x| **x == n[c]).count() == 1 => {
                format!("\"{}\"", n[c])
            }
            _ => (c + 1).to_string(),
        }
    }

    /// The header's name of column `c`, lower case ("" without a header).
    pub fn name(&self, c: usize) -> String {
        self.names
            .as_ref()
            .and_then(|n| n.get(c))
            .map_or(String::new(), |s| s.to_ascii_lowercase())
    }

    /// "comma" or "white space".
    pub fn separator(&self) -> &'static str {
        if self.comma {
            "comma"
        } else {
            "white space"
        }
    }
}

/// Median of the positive steps of `v`.
pub(crate) fn median_step(v: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = v
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    if d.is_empty() {
        return None;
    }
    d.sort_by(f64::total_cmp);
    Some(d[d.len() / 2])
}

/// Whether `v` never decreases and grows overall.
pub(crate) fn increasing(v: &[f64]) -> bool {
    v.len() >= 3
        && v.windows(2).all(|w| w[1] >= w[0])
        && v.last().zip(v.first()).is_some_and(|(b, a)| b > a)
}
