//! The IMU text reader's one-pass parse of the common line (7 or 8 plain numbers separated by
//! ASCII white space) and its chunked line splitting against the general parser: for random
//! lines (random number spellings, separators, line ends, comments, blank lines) and for
//! broken ones (a field that is not a plain finite number, too few or too many fields,
//! non-ASCII bytes, commas, time not increasing), `ImuTextReader` yields exactly what the
//! general field parser (`DataLine`, the reader's parser before the fast path) gives: the same
//! bits, the same line numbers, the same error text.

use nav_core::types::ImuSample;
use nav_io::{DataLine, ImuTextReader, IoError};
use proptest::prelude::*;
use std::path::Path;

const NAMES: [&str; 8] = [
    "t_s",
    "dtheta_x_rad",
    "dtheta_y_rad",
    "dtheta_z_rad",
    "dv_x_mps",
    "dv_y_mps",
    "dv_z_mps",
    "temperature_c",
];

/// The general parser on one data line (what the reader did for every line before).
fn oracle_line(path: &Path, line: usize, text: &str) -> Result<ImuSample, IoError> {
    let dl = DataLine::new(path, line, text);
    dl.require(7, 8, &NAMES)?;
    let mut v = [0.0; 7];
    for (i, x) in v.iter_mut().enumerate() {
        *x = dl.num(i, NAMES[i])?;
    }
    let temperature_c = if dl.len() == 8 {
        dl.num_allow_nan(7, NAMES[7])?
    } else {
        f64::NAN
    };
    Ok(ImuSample {
        t_s: v[0],
        dtheta_rad: [v[1], v[2], v[3]],
        dv_mps: [v[4], v[5], v[6]],
        temperature_c,
    })
}

/// The general reading of a whole text: lines split on `\n` (trailing `\r` removed),
/// comments and blank lines skipped, time strictly increasing. Ends at the first error
/// (returned as its text).
fn oracle(path: &Path, text: &str) -> (Vec<(ImuSample, usize)>, Option<String>) {
    let mut out = Vec::new();
    let mut prev: Option<(f64, usize)> = None;
    let body = text.strip_suffix('\n').unwrap_or(text);
    if text.is_empty() {
        return (out, None);
    }
    for (i, raw) in body.split('\n').enumerate() {
        let line = i + 1;
        let t = raw.trim_end_matches(['\r', '\n']);
        let s = t.trim_start();
        if s.is_empty() || s.starts_with('#') || s.starts_with('%') {
            continue;
        }
        match oracle_line(path, line, t) {
            Ok(smp) => {
                if let Some((p, pl)) = prev {
                    if smp.t_s <= p {
                        let e = IoError::NonMonotonicTime {
                            path: path.to_path_buf(),
                            line,
                            column: 1,
                            name: NAMES[0].to_string(),
                            t_s: smp.t_s,
                            prev_t_s: p,
                            prev_line: pl,
                        };
                        return (out, Some(e.to_string()));
                    }
                }
                prev = Some((smp.t_s, line));
                out.push((smp, line));
            }
            Err(e) => return (out, Some(e.to_string())),
        }
    }
    (out, None)
}

fn read_all(path: &Path, text: &str) -> (Vec<(ImuSample, usize)>, Option<String>) {
    let src = std::io::Cursor::new(text.as_bytes().to_vec());
    let rd = ImuTextReader::from_reader(path, src).unwrap();
    let mut out = Vec::new();
    for r in rd {
        match r {
            Ok(x) => out.push(x),
            Err(e) => return (out, Some(e.to_string())),
        }
    }
    (out, None)
}

fn bits(s: &ImuSample) -> [u64; 8] {
    [
        s.t_s.to_bits(),
        s.dtheta_rad[0].to_bits(),
        s.dtheta_rad[1].to_bits(),
        s.dtheta_rad[2].to_bits(),
        s.dv_mps[0].to_bits(),
        s.dv_mps[1].to_bits(),
        s.dv_mps[2].to_bits(),
        // NaN temperatures compare as "absent"
        if s.temperature_c.is_nan() {
            0x7ff8_0000_0000_0000
        } else {
            s.temperature_c.to_bits()
        },
    ]
}

fn check(text: &str) -> Result<(), TestCaseError> {
    let path = Path::new("imu.txt");
    let (want, want_err) = oracle(path, text);
    let (got, got_err) = read_all(path, text);
    prop_assert_eq!(got.len(), want.len(), "text:\n{}", text);
    for ((g, gl), (w, wl)) in got.iter().zip(&want) {
        prop_assert_eq!(gl, wl);
        prop_assert_eq!(bits(g), bits(w), "line {}", wl);
    }
    prop_assert_eq!(got_err, want_err, "text:\n{}", text);
    Ok(())
}

/// A finite value: random bits (all magnitudes) or an IMU-like increment.
fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<u64>()
            .prop_map(f64::from_bits)
            .prop_filter("finite", |x| x.is_finite()),
        (-1.0e-2..1.0e-2f64),
        (-1.0..1.0f64).prop_map(|x| x * 1e-7),
    ]
}

/// `x` spelled one of the ways a file may hold it.
fn spell(x: f64, style: u8, prec: usize) -> String {
    match style % 7 {
        0 => format!("{x}"),
        1 => format!("{x:e}"),
        2 => format!("{x:E}"),
        3 => format!("{x:.prec$}"),
        4 => format!("{x:.prec$e}"),
        5 if x >= 0.0 => format!("+{x}"),
        6 if x >= 0.0 => format!("00{x}"),
        _ => format!("{x:?}"),
    }
}

/// Broken or unusual field texts (each must give what the general parser gives).
const ODD: [&str; 22] = [
    "1.5e",
    "inf",
    "-inf",
    "NaN",
    "nan",
    "1,5",
    "abc",
    "1e400",
    "-1e400",
    "0x10",
    "1..2",
    "+",
    "-",
    ".",
    "1.5\u{a0}",
    "\u{661}",
    "1e+",
    "1_0",
    "#1",
    "1.5#",
    "infinity",
    ".5",
];

const SEPS: [&str; 5] = [" ", "  ", "\t", " \t ", "\u{a0}"];

#[derive(Debug, Clone)]
struct LineSpec {
    kind: u8,
    vals: Vec<(f64, u8, usize)>,
    sep: usize,
    lead: bool,
    trail: bool,
    crlf: bool,
    odd: (usize, usize),
}

fn line_spec() -> impl Strategy<Value = LineSpec> {
    (
        0u8..20,
        prop::collection::vec((value(), any::<u8>(), 0usize..18), 6..9),
        0usize..SEPS.len(),
        any::<bool>(),
        any::<bool>(),
        any::<bool>(),
        (0usize..9, 0usize..ODD.len()),
    )
        .prop_map(|(kind, vals, sep, lead, trail, crlf, odd)| LineSpec {
            kind,
            vals,
            sep,
            lead,
            trail,
            crlf,
            odd,
        })
}

/// The text of a file from line specs: mostly good lines (time increasing by 5 ms), some
/// comments and blank lines, and (when `broken`) now and then a broken line.
fn render(specs: &[LineSpec], broken: bool) -> String {
    let mut text = String::new();
    let mut t = 456_300.0;
    for s in specs {
        let end = if s.crlf { "\r\n" } else { "\n" };
        match s.kind {
            0 => text.push_str(&format!("# comment {}{end}", s.odd.1)),
            1 => text.push_str(&format!("  % note{end}")),
            2 => text.push_str(if s.lead { " \t" } else { "" }),
            _ => {
                t += 0.005;
                // time: shortest form (or a repeat of the previous time, when broken)
                let tt = if broken && s.kind == 3 { t - 0.005 } else { t };
                let mut fields = vec![format!("{tt}")];
                // 6 increments and, with 7 values, a temperature
                for &(x, style, prec) in s.vals.iter().skip(1) {
                    fields.push(spell(x, style, prec));
                }
                if broken && s.kind == 4 {
                    let (i, k) = s.odd;
                    match fields.get_mut(i) {
                        Some(f) => *f = ODD[k].to_string(),
                        None => fields.push(ODD[k].to_string()),
                    }
                }
                if broken && s.kind == 5 {
                    fields.truncate(s.odd.0.min(6));
                }
                if broken && s.kind == 6 {
                    fields.push("1".into());
                    fields.push("2".into());
                }
                // the non-ASCII separator only in broken files (the general parser splits
                // on it as Unicode white space; the fast path leaves such lines to it)
                let sep = if !broken && s.sep == SEPS.len() - 1 {
                    " "
                } else {
                    SEPS[s.sep]
                };
                if s.lead {
                    text.push_str(" \t");
                }
                text.push_str(&fields.join(sep));
                if s.trail {
                    text.push_str(" \t ");
                }
            }
        }
        text.push_str(end);
    }
    text
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3_000, ..ProptestConfig::default() })]

    /// Good files: every sample to the bits and its line number, as the general parser.
    #[test]
    fn fast_imu_parse_equals_general_parser(specs in prop::collection::vec(line_spec(), 1..40)) {
        check(&render(&specs, false))?;
    }

    /// Files with broken lines: the same samples up to the first error, and the same error.
    #[test]
    fn fast_imu_parse_errors_equal_general_parser(
        specs in prop::collection::vec(line_spec(), 1..40),
    ) {
        check(&render(&specs, true))?;
    }
}

#[test]
fn every_odd_field_in_every_column_reads_as_the_general_parser() {
    let good = [
        "456300.005",
        "1e-5",
        "-2e-6",
        "3.5e-7",
        "0.049",
        "-0.001",
        "-0.049",
    ];
    for odd in ODD {
        for col in 0..9 {
            let mut f: Vec<&str> = good.to_vec();
            if col < f.len() {
                f[col] = odd;
            } else {
                f.push(odd);
            }
            let text = format!("456300 0 0 0 0 0 0\n{}\n", f.join(" "));
            check(&text).unwrap();
        }
    }
}

#[test]
fn lines_longer_than_the_read_chunk_and_files_without_final_newline_read_the_same() {
    // a comment line of 300 kB (longer than the 128 KiB read chunk), then samples; the
    // last line without its newline
    let mut text = format!("#{}\n", "x".repeat(300_000));
    for k in 0..2000 {
        text.push_str(&format!(
            "{} 1e-5 -2e-6 3.5e-7 0.049 -0.001 -0.049\r\n",
            456_300.0 + 0.005 * f64::from(k)
        ));
    }
    text.push_str("456400.5 1 2 3 4 5 6");
    check(&text).unwrap();
    let (got, err) = read_all(Path::new("imu.txt"), &text);
    assert_eq!(got.len(), 2001);
    assert_eq!(err, None);
    assert_eq!(got.last().map(|g| g.1), Some(2002));
    // a line over 1 MiB is refused with its number, as before
    let long = format!("456300 0 0 0 0 0 0\n{}\n", "1".repeat((1 << 20) + 10));
    let (got, err) = read_all(Path::new("imu.txt"), &long);
    assert_eq!(got.len(), 1);
    let err = err.expect("an error for the long line");
    assert!(err.contains("line 2") || err.contains(":2"), "{err}");
    assert!(err.contains("longer than"), "{err}");
}
