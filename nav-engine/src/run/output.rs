//! Output files of `host-sim run`: `nav.txt` (nav format), `std.txt` (state standard
//! deviations), `bias.txt` (IMU error estimates) and `innovations.txt`.

use super::{EpochRecord, FixUse, InnovationRecord, RunOutput};
use nav_core::types::NavSolution;
use nav_io::IoError;
use std::io::Write;
use std::path::Path;

fn create(path: &Path) -> Result<std::io::BufWriter<std::fs::File>, IoError> {
    let f = super::outdir::create_new_file(path).map_err(|source| IoError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(std::io::BufWriter::new(f))
}

fn werr(path: &Path) -> impl Fn(std::io::Error) -> IoError + '_ {
    move |source| IoError::Open {
        path: path.to_path_buf(),
        source,
    }
}

/// Writes the navigation solution with the GPS week filled in.
pub fn write_nav(path: &Path, nav: &[NavSolution], week: u16) -> Result<(), IoError> {
    write_nav_with(path, nav, week, 0.0)
}

/// [`write_nav`] with `shift_s` added to every time (record by record: no copy of the
/// solution). Same text as [`nav_io::write_nav_text`] (gzip when the name ends in `.gz`).
pub fn write_nav_with(
    path: &Path,
    nav: &[NavSolution],
    week: u16,
    shift_s: f64,
) -> Result<(), IoError> {
    write_nav_records(path, nav.iter().copied().map(Ok), week, shift_s)
}

/// [`write_nav_with`] on records read one by one (e.g. from a file of records): the same
/// text; the first read error ends the writing and is returned (the file then holds the
/// records before it).
pub fn write_nav_records(
    path: &Path,
    nav: impl IntoIterator<Item = Result<NavSolution, IoError>>,
    week: u16,
    shift_s: f64,
) -> Result<(), IoError> {
    let mut read_err = None;
    let written = nav_io::text::write_with(path, |w| {
        for r in nav {
            let s = match r {
                Ok(s) => s,
                Err(e) => {
                    read_err = Some(e);
                    return Err(std::io::Error::other("the records could not be read"));
                }
            };
            let t_s = if shift_s == 0.0 {
                s.t_s
            } else {
                s.t_s + shift_s
            };
            nav_io::write_nav_line(w, &NavSolution { week, t_s, ..s })?;
        }
        Ok(())
    });
    match read_err {
        Some(e) => Err(e),
        None => written,
    }
}

/// The two header lines of `std.txt`.
pub fn std_header<W: Write + ?Sized>(
    w: &mut W,
    model: super::Model,
    state_names: &[String],
) -> std::io::Result<()> {
    writeln!(
        w,
        "# host-sim run: 1-sigma of the error states (sqrt of the covariance diagonal), model {}",
        model.name()
    )?;
    writeln!(w, "# t_s {}", state_names.join(" "))
}

/// One line of `std.txt`: `{:.4}` time and `{:.6e}` values, written by
/// [`nav_io::LineBuf`] (the same bytes as `core::fmt`, without its float machinery).
pub fn std_line<W: Write + ?Sized>(w: &mut W, r: &EpochRecord) -> std::io::Result<()> {
    let mut lb = nav_io::LineBuf::new();
    lb.push_fixed(w, r.t_s, 4)?;
    lb.push_spaced_exp::<6, _>(w, &r.state_std)?;
    lb.push_byte(w, b'\n')?;
    lb.flush(w)
}

/// [`std_line`] with `write!` (the reference it must equal; tests).
pub fn std_line_fmt<W: Write + ?Sized>(w: &mut W, r: &EpochRecord) -> std::io::Result<()> {
    write!(w, "{:.4}", r.t_s)?;
    for s in &r.state_std {
        write!(w, " {s:.6e}")?;
    }
    writeln!(w)
}

/// `std.txt`: `t_s` then the 1-sigma of every error state (SI units named in the header).
pub fn write_std(path: &Path, run: &RunOutput) -> Result<(), IoError> {
    let mut w = create(path)?;
    let e = werr(path);
    std_header(&mut w, run.model, &run.state_names).map_err(&e)?;
    for r in &run.epochs {
        std_line(&mut w, r).map_err(&e)?;
    }
    w.flush().map_err(&e)
}

fn unit_of(name: &str) -> (&'static str, f64) {
    match name {
        "gyro_bias" => ("deg_per_h", 180.0 / std::f64::consts::PI * 3600.0),
        "accel_bias" => ("mg", 1.0 / (9.806_65e-3)),
        n if n.contains("scale") => ("ppm", 1e6),
        _ => ("si", 1.0),
    }
}

/// The two header lines of `bias.txt` (column names from the first epoch record).
pub fn bias_header<W: Write + ?Sized>(
    w: &mut W,
    first: Option<&EpochRecord>,
) -> std::io::Result<()> {
    writeln!(
        w,
        "# host-sim run: IMU error estimates (total over the block's processes) and 1-sigma"
    )?;
    let mut head = String::from("# t_s");
    if let Some(r) = first {
        for b in &r.blocks {
            let (u, _) = unit_of(&b.name);
            for a in ["x", "y", "z"] {
                head.push_str(&format!(" {}_{a}_{u}", b.name));
            }
            for a in ["x", "y", "z"] {
                head.push_str(&format!(" {}_std_{a}_{u}", b.name));
            }
        }
    }
    writeln!(w, "{head}")
}

/// One line of `bias.txt`: `{:.4}` time and `{:.6}` values, written by
/// [`nav_io::LineBuf`] (the same bytes as `core::fmt`, without its float machinery).
pub fn bias_line<W: Write + ?Sized>(w: &mut W, r: &EpochRecord) -> std::io::Result<()> {
    let mut lb = nav_io::LineBuf::new();
    lb.push_fixed(w, r.t_s, 4)?;
    for b in &r.blocks {
        let (_, k) = unit_of(&b.name);
        let [v0, v1, v2] = b.value;
        let [s0, s1, s2] = b.std;
        let scaled = [v0 * k, v1 * k, v2 * k, s0 * k, s1 * k, s2 * k];
        lb.push_spaced_fixed::<6, _>(w, &scaled)?;
    }
    lb.push_byte(w, b'\n')?;
    lb.flush(w)
}

/// [`bias_line`] with `write!` (the reference it must equal; tests).
pub fn bias_line_fmt<W: Write + ?Sized>(w: &mut W, r: &EpochRecord) -> std::io::Result<()> {
    write!(w, "{:.4}", r.t_s)?;
    for b in &r.blocks {
        let (_, k) = unit_of(&b.name);
        for v in b.value.iter().chain(b.std.iter()) {
            write!(w, " {:.6}", v * k)?;
        }
    }
    writeln!(w)
}

/// `bias.txt`: `t_s` then per IMU error quantity the estimate (x, y, z) and its 1-sigma, in
/// deg/h (gyro bias), mg (accelerometer bias, 1 mg = 9.80665e-3 m/s^2) and ppm (scale factors).
pub fn write_bias(path: &Path, run: &RunOutput) -> Result<(), IoError> {
    let mut w = create(path)?;
    let e = werr(path);
    bias_header(&mut w, run.epochs.first()).map_err(&e)?;
    for r in &run.epochs {
        bias_line(&mut w, r).map_err(&e)?;
    }
    w.flush().map_err(&e)
}

fn use_name(u: FixUse) -> &'static str {
    match u {
        FixUse::Accepted => "accepted",
        FixUse::Forced => "forced",
        FixUse::Rejected => "rejected",
        FixUse::Withheld => "withheld",
        FixUse::Invalid => "invalid",
    }
}

/// The two header lines of `innovations.txt`.
pub fn innovations_header<W: Write + ?Sized>(w: &mut W) -> std::io::Result<()> {
    writeln!(
        w,
        "# host-sim run: GNSS fixes against the solution. innovation = measured - predicted \
         antenna position (NED, m) [and velocity, m/s]; var = diagonal of S = H P H^T + R; \
         withheld = inside an imposed outage (no update, var/NIS not computed)"
    )?;
    writeln!(
        w,
        "# t_s use outage dim q inn_n_m inn_e_m inn_d_m inn_vn_mps inn_ve_mps inn_vd_mps \
         var_n var_e var_d var_vn var_ve var_vd nis nis_threshold"
    )
}

/// One line of `innovations.txt`, assembled in a [`nav_io::LineBuf`] (the text of
/// [`innovation_line_fmt`], byte for byte, without `core::fmt` for the finite numbers).
pub fn innovation_line<W: Write + ?Sized>(w: &mut W, r: &InnovationRecord) -> std::io::Result<()> {
    let mut lb = nav_io::LineBuf::new();
    lb.push_fixed(w, r.t_s, 4)?;
    lb.push_byte(w, b' ')?;
    lb.push_bytes(w, use_name(r.used).as_bytes())?;
    lb.push_byte(w, b' ')?;
    // the outage index as a signed integer, -1 for none
    let outage = r.outage.map_or(-1, |o| o as i64);
    if outage < 0 {
        lb.push_byte(w, b'-')?;
    }
    lb.push_u64(w, outage.unsigned_abs())?;
    lb.push_byte(w, b' ')?;
    lb.push_u64(w, r.dim as u64)?;
    lb.push_byte(w, b' ')?;
    lb.push_u64(w, u64::from(r.quality))?;
    lb.push_spaced_exp::<6, _>(w, &r.innovation)?;
    lb.push_spaced_exp::<6, _>(w, &r.innovation_var)?;
    lb.push_byte(w, b' ')?;
    lb.push_fixed(w, r.nis, 4)?;
    lb.push_byte(w, b' ')?;
    lb.push_fixed(w, r.nis_threshold, 4)?;
    lb.push_byte(w, b'\n')?;
    lb.flush(w)
}

/// [`innovation_line`] with `write!` (the reference it must equal; tests).
pub fn innovation_line_fmt<W: Write + ?Sized>(
    w: &mut W,
    r: &InnovationRecord,
) -> std::io::Result<()> {
    write!(
        w,
        "{:.4} {} {} {} {}",
        r.t_s,
        use_name(r.used),
        r.outage.map_or(-1, |o| o as i64),
        r.dim,
        r.quality
    )?;
    for v in r.innovation.iter().chain(r.innovation_var.iter()) {
        write!(w, " {v:.6e}")?;
    }
    writeln!(w, " {:.4} {:.4}", r.nis, r.nis_threshold)
}

/// `innovations.txt`: one line per GNSS fix.
pub fn write_innovations(path: &Path, recs: &[InnovationRecord]) -> Result<(), IoError> {
    let mut w = create(path)?;
    let e = werr(path);
    innovations_header(&mut w).map_err(&e)?;
    for r in recs {
        innovation_line(&mut w, r).map_err(&e)?;
    }
    w.flush().map_err(&e)
}

/// The output files of `host-sim run`, in the order they are written.
pub const OUTPUT_NAMES: [&str; 5] = [
    "nav.txt",
    "std.txt",
    "bias.txt",
    "innovations.txt",
    "metrics.json",
];

/// Suffix of an output file that is not complete (being written, or the run failed).
pub const PARTIAL_SUFFIX: &str = ".partial";

/// `dir/name.partial`.
pub fn partial_path(dir: &Path, name: &str) -> std::path::PathBuf {
    dir.join(format!("{name}{PARTIAL_SUFFIX}"))
}

/// Writes every output of a run so that a file under its final name is always complete:
/// each file is written to `NAME.partial` (created new: a file or link under that name is
/// replaced, never written through) and synced to disk, and only when all are written and
/// `complete` (the run reached its end) are they renamed to their final names (replacing an
/// earlier run's). On a write error (a full disk) or when `complete` is false the `.partial`
/// files stay. Returns the paths written. The command line writes into the stage folder of an
/// [`super::outdir::OutDir`], which moves them into `--out`.
pub fn write_all(
    dir: &Path,
    run: &RunOutput,
    nav: &[NavSolution],
    week: u16,
    metrics_json: &str,
    complete: bool,
) -> Result<Vec<std::path::PathBuf>, IoError> {
    let [p_nav, p_std, p_bias, p_inn, p_met] = OUTPUT_NAMES.map(|n| partial_path(dir, n));
    write_nav(&p_nav, nav, week)?;
    write_std(&p_std, run)?;
    write_bias(&p_bias, run)?;
    write_innovations(&p_inn, &run.innovations)?;
    super::outdir::create_new_file(&p_met)
        .and_then(|mut f| f.write_all(metrics_json.as_bytes()))
        .map_err(|source| IoError::Write {
            path: p_met.clone(),
            source,
        })?;
    let partial = [p_nav, p_std, p_bias, p_inn, p_met];
    for p in &partial {
        std::fs::File::open(p)
            .and_then(|f| f.sync_all())
            .map_err(|source| IoError::Write {
                path: p.clone(),
                source,
            })?;
    }
    if !complete {
        return Ok(partial.to_vec());
    }
    let mut done = Vec::new();
    for (p, name) in partial.iter().zip(OUTPUT_NAMES) {
        let fin = dir.join(name);
        std::fs::rename(p, &fin).map_err(|source| IoError::Write {
            path: fin.clone(),
            source,
        })?;
        done.push(fin);
    }
    Ok(done)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::run::BlockEstimate;

    /// splitmix64: a fixed pseudo-random sequence.
    fn next(s: &mut u64) -> u64 {
        *s = s.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = *s;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// A value of the kind `std.txt` / `bias.txt` hold (1e-10 .. 1e3, either sign, some
    /// exact decimal halves and exact zeros), or a random bit pattern.
    fn value(s: &mut u64) -> f64 {
        let r = next(s);
        match r % 8 {
            0 => f64::from_bits(next(s)),
            1 => 0.0,
            2 => ((next(s) % 2_000_000) as f64 + 0.5) / 1e7,
            _ => {
                let u = (next(s) >> 11) as f64 / (1u64 << 53) as f64;
                let x = 10f64.powf(-10.0 + 13.0 * u);
                if r & 16 == 0 {
                    x
                } else {
                    -x
                }
            }
        }
    }

    /// `std.txt` and `bias.txt` lines without `core::fmt` floats are `core::fmt`'s, byte for
    /// byte, over 20,000 pseudo-random records (times on the 10 Hz grid and off it).
    #[test]
    fn std_and_bias_lines_equal_core_fmt() {
        let mut s = 17u64;
        let names = ["gyro_bias", "accel_bias", "gyro_scale_factor", "other"];
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for k in 0..20_000u32 {
            let t_s = if k % 2 == 0 {
                200_000.0 + f64::from(k) * 0.1
            } else {
                200_000.0 + value(&mut s).abs()
            };
            let r = EpochRecord {
                t_s,
                nav: NavSolution::default(),
                state_std: (0..21).map(|_| value(&mut s)).collect(),
                estimates: Vec::new(),
                blocks: names
                    .iter()
                    .map(|n| BlockEstimate {
                        name: (*n).to_string(),
                        value: [value(&mut s), value(&mut s), value(&mut s)],
                        std: [value(&mut s), value(&mut s), value(&mut s)],
                    })
                    .collect(),
            };
            a.clear();
            b.clear();
            std_line(&mut a, &r).unwrap();
            std_line_fmt(&mut b, &r).unwrap();
            assert_eq!(
                String::from_utf8_lossy(&a),
                String::from_utf8_lossy(&b),
                "std line {k}"
            );
            a.clear();
            b.clear();
            bias_line(&mut a, &r).unwrap();
            bias_line_fmt(&mut b, &r).unwrap();
            assert_eq!(
                String::from_utf8_lossy(&a),
                String::from_utf8_lossy(&b),
                "bias line {k}"
            );
        }
    }

    /// `innovations.txt` lines without `core::fmt` floats are `core::fmt`'s, byte for byte,
    /// over 20,000 pseudo-random records: every outcome, with and without an outage, NaN
    /// variances, NIS and thresholds (withheld and refused fixes), 3 and 6 dimensions.
    #[test]
    fn innovation_lines_equal_core_fmt() {
        let uses = [
            FixUse::Accepted,
            FixUse::Forced,
            FixUse::Rejected,
            FixUse::Withheld,
            FixUse::Invalid,
        ];
        let mut s = 29u64;
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for k in 0..20_000usize {
            let nan_every = |x: f64, m: usize| if k % m == 0 { f64::NAN } else { x };
            let r = InnovationRecord {
                t_s: 200_000.0 + value(&mut s).abs(),
                used: uses[k % uses.len()],
                outage: (k % 3 == 0).then_some(k % 7),
                dim: if k % 2 == 0 { 3 } else { 6 },
                innovation: std::array::from_fn(|_| value(&mut s)),
                innovation_var: std::array::from_fn(|_| nan_every(value(&mut s), 4)),
                nis: nan_every(value(&mut s).abs(), 5),
                nis_threshold: nan_every(value(&mut s).abs(), 6),
                quality: (k % 256) as u8,
            };
            a.clear();
            b.clear();
            innovation_line(&mut a, &r).unwrap();
            innovation_line_fmt(&mut b, &r).unwrap();
            assert_eq!(
                String::from_utf8_lossy(&a),
                String::from_utf8_lossy(&b),
                "innovation line {k}"
            );
        }
    }
}
