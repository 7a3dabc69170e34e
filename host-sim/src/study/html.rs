//! The self-contained HTML version of the study report (plots embedded as data URIs).
use anyhow::Context;
use std::fmt::Write as _;
use std::path::Path;

/// A self-contained HTML page: the Markdown in a `<pre>`-free minimal rendering (headings,
/// lists, tables, paragraphs) with the PNGs embedded as base64 data URIs.
pub(super) fn html(md: &str, out: &Path, names: &[String]) -> anyhow::Result<String> {
    let esc = |t: &str| {
        t.replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;")
    };
    let inline = |t: &str| {
        let mut o = String::new();
        let mut bold = false;
        let mut code = false;
        let e = esc(t);
        let mut it = e.chars().peekable();
        while let Some(c) = it.next() {
            if c == '*' && it.peek() == Some(&'*') {
                it.next();
                o += if bold { "</b>" } else { "<b>" };
                bold = !bold;
            } else if c == '`' {
                o += if code { "</code>" } else { "<code>" };
                code = !code;
            } else {
                o.push(c);
            }
        }
        o
    };
    let mut h = String::from(
        "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>host-sim study</title><style>body{font-family:sans-serif;max-width:1400px;margin:auto;padding:1em}table{border-collapse:collapse}td,th{border:1px solid #aaa;padding:3px 8px}img{max-width:100%}</style></head><body>\n",
    );
    let mut in_table = false;
    let mut in_list = false;
    for line in md.lines() {
        let t = line.trim_end();
        if in_table && !t.starts_with('|') {
            h += "</table>\n";
            in_table = false;
        }
        if in_list && !(t.starts_with("- ") || t.starts_with("  ")) {
            h += "</ul>\n";
            in_list = false;
        }
        if let Some(x) = t.strip_prefix("### ") {
            let _ = writeln!(h, "<h3>{}</h3>", inline(x));
        } else if let Some(x) = t.strip_prefix("## ") {
            let _ = writeln!(h, "<h2>{}</h2>", inline(x));
        } else if let Some(x) = t.strip_prefix("# ") {
            let _ = writeln!(h, "<h1>{}</h1>", inline(x));
        } else if t.starts_with("|---") {
            continue;
        } else if t.starts_with('|') {
            if !in_table {
                h += "<table>\n";
                in_table = true;
            }
            let cells: Vec<&str> = t.trim_matches('|').split('|').collect();
            h += "<tr>";
            for c in cells {
                let _ = write!(h, "<td>{}</td>", inline(c.trim()));
            }
            h += "</tr>\n";
        } else if let Some(x) = t.strip_prefix("- ") {
            if !in_list {
                h += "<ul>\n";
                in_list = true;
            }
            let _ = writeln!(h, "<li>{}</li>", inline(x));
        } else if t.starts_with("![") {
            let name = t
                .rsplit_once('(')
                .map(|x| x.1.trim_end_matches(')'))
                .unwrap_or("");
            if names.iter().any(|n| n == name) {
                let bytes = std::fs::read(out.join(name))
                    .with_context(|| format!("reading {name} for the HTML report"))?;
                let _ = writeln!(
                    h,
                    "<img alt=\"{name}\" src=\"data:image/png;base64,{}\">",
                    base64(&bytes)
                );
            }
        } else if t.is_empty() {
            continue;
        } else {
            let _ = writeln!(h, "<p>{}</p>", inline(t.trim_start()));
        }
    }
    if in_table {
        h += "</table>\n";
    }
    if in_list {
        h += "</ul>\n";
    }
    h += "</body></html>\n";
    Ok(h)
}

/// `data` in standard base64 (RFC 4648, with `=` padding), as the report embeds its PNG plots.
pub fn base64(data: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(data.len().div_ceil(3) * 4);
    for ch in data.chunks(3) {
        let b = [
            ch.first().copied().unwrap_or(0),
            ch.get(1).copied().unwrap_or(0),
            ch.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for (i, shift) in [18, 12, 6, 0].iter().enumerate() {
            if i <= ch.len() {
                out.push(T[((n >> shift) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}
