//! The IMU file: the project's increment text, or a CSV of rates and specific forces mapped
//! column by column with its units and time kind, written as the `[imu]` section with its
//! evidence.

use super::table::{increasing, median_step, Table};
use super::Guess;
use std::fmt::Write as _;
use std::path::Path;

const G0: f64 = 9.806_65;

/// What the GNSS file tells the IMU detection.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct GnssHints {
    /// First and last fix time, GPS s of week.
    pub span_s: Option<(f64, f64)>,
    /// The 95th percentile of the course rate while moving, deg/s.
    pub course_rate_degps: Option<f64>,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn quantile(mut v: Vec<f64>, q: f64) -> f64 {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q) as usize]
}

fn norms(t: &Table, c: usize) -> Vec<f64> {
    let (a, b, d) = (t.col(c), t.col(c + 1), t.col(c + 2));
    (0..a.len())
        .map(|i| (a[i] * a[i] + b[i] * b[i] + d[i] * d[i]).sqrt())
        .collect()
}

/// The `[imu]` section of `path` (written as `shown`), without `[imu.mounting]`.
pub(crate) fn detect(
    path: &Path,
    shown: &str,
    hints: &GnssHints,
    g: &mut Guess,
) -> anyhow::Result<String> {
    let t = Table::read(path)?;
    if let Some(sc) = &t.semicolons {
        anyhow::bail!("{}", sc.describe());
    }
    if t.rows.len() < 10 {
        anyhow::bail!("{}: fewer than 10 data rows recognised", path.display());
    }
    let (tc, tv, text) = time_column(path, &t)?;
    let step = median_step(&tv).unwrap_or(f64::NAN);
    // the accelerometer triple: consecutive numeric columns whose median norm is 1 g, 9.8
    // m/s^2, or 9.8 m/s^2 x the interval (increments)
    let triples: Vec<usize> = (0..t.width.saturating_sub(2))
        .filter(|c| !(*c..*c + 3).contains(&tc) && (*c..*c + 3).all(|k| t.numeric(k)))
        .collect();
    let dt_guess = |s: f64| {
        if tv[0] > 1e11 || step >= 1.0 {
            s * 1e-3
        } else {
            s
        }
    };
    let dt = dt_guess(step);
    // (median |f| expected, accelerometer unit, the rows hold increments)
    let score = |m: f64| -> (f64, (&'static str, bool)) {
        [
            (1.0, ("g", false)),
            (G0, ("m/s^2", false)),
            (G0 * dt, ("m/s^2", true)),
            (dt, ("g", true)),
        ]
        .iter()
        .map(|(r, u)| (((m / r).ln()).abs(), *u))
        .fold(
            (f64::INFINITY, ("", false)),
            |a, b| if b.0 < a.0 { b } else { a },
        )
    };
    let (ac, (err, (unit, increments))) = triples
        .iter()
        .map(|c| (*c, score(median(norms(&t, *c)))))
        .min_by(|a, b| a.1 .0.total_cmp(&b.1 .0))
        .ok_or_else(|| {
            anyhow::anyhow!(
                "{}: no three numeric columns for the accelerometer",
                path.display()
            )
        })?;
    if err > 0.3 {
        anyhow::bail!(
            "{}: no column triple looks like specific force (|f| near 1 g or 9.8 m/s^2)",
            path.display()
        );
    }
    let gc = triples
        .iter()
        .copied()
        .find(|c| *c + 3 <= ac || *c >= ac + 3)
        .ok_or_else(|| {
            anyhow::anyhow!("{}: no three numeric columns for the gyro", path.display())
        })?;
    let fmed = median(norms(&t, ac));
    let mut s = String::new();
    let project_text = !t.comma && t.width == 7 && tc == 0 && gc == 1 && ac == 4;
    if increments && unit == "m/s^2" && project_text {
        writeln!(s, "[imu]\npath = {shown:?}\nformat = \"text\"  # 7 white-space columns, |dv| {fmed:.5} m/s = 9.8 m/s^2 x {dt} s: increments `t dtheta(3) dv(3)`, the project's IMU text")?;
        return Ok(s);
    }
    // increments are rates times the interval: the gyro unit is judged on the rates
    let gyro_unit = gyro_unit(&t, gc, if increments { 1.0 / dt } else { 1.0 }, hints, g);
    let (time_toml, dt_s) = match text {
        Some(f) => text_time(&t, tc, f, &tv, g),
        None => time_kind(path, &t, tc, hints, g)?,
    };
    writeln!(
        s,
        "[imu]\npath = {shown:?}\nformat = \"csv\"  # {} separated, {} columns{}",
        t.separator(),
        t.width,
        if t.names.is_some() {
            ", a header"
        } else {
            ", no header"
        }
    )?;
    writeln!(s, "[imu.csv]")?;
    if t.skip_lines > 0 {
        writeln!(
            s,
            "skip_lines = {}  # lines before the first data row",
            t.skip_lines
        )?;
    }
    writeln!(s, "{gyro_unit}")?;
    s.push_str(&accel_lines(unit, increments, fmed, dt, t.rows.len()));
    let r = |c: usize| t.column_ref(c);
    if time_toml.contains("week_sow") {
        writeln!(s, "[imu.csv.columns]\nweek = {}", r(tc - 1))?;
    } else {
        writeln!(s, "[imu.csv.columns]")?;
    }
    writeln!(
        s,
        "time = {}\ngyro = [{}, {}, {}]\naccel = [{}, {}, {}]",
        r(tc),
        r(gc),
        r(gc + 1),
        r(gc + 2),
        r(ac),
        r(ac + 1),
        r(ac + 2)
    )?;
    writeln!(s, "[imu.csv.time]\n{time_toml}")?;
    g.imu_rate_hz = 1.0 / dt_s;
    Ok(s)
}

/// The `accel_unit` and `convention` lines: rates or increments in `unit` (median norm `fmed`
/// over `rows` rows, sample interval `dt` s).
fn accel_lines(unit: &str, increments: bool, fmed: f64, dt: f64, rows: usize) -> String {
    if increments {
        let (inc_unit, per) = if unit == "g" {
            ("g s", 1.0)
        } else {
            ("m/s", G0)
        };
        format!(
            "accel_unit = \"{unit}\"  # median |dv| over the first {rows} rows {fmed:.6} = {per} x the {dt} s interval: increments in {inc_unit}\n\
             convention = \"increments\"  # the rows hold angle and velocity increments over the interval ending at their time\n"
        )
    } else {
        format!(
            "accel_unit = \"{unit}\"  # median |f| over the first {rows} rows {fmed:.3}: units {unit}\n\
             convention = \"trapezoid\"  # rows taken as instantaneous samples (\"interval_mean\" for averaged outputs)\n"
        )
    }
}

/// The gyro unit of the triple at `gc` (`per_s` turns its values into rates: 1 for rates,
/// 1 / the interval for increments).
fn gyro_unit(t: &Table, gc: usize, per_s: f64, hints: &GnssHints, g: &mut Guess) -> String {
    let peak = quantile(norms(t, gc), 0.99) * per_s;
    if let Some(cr) = hints.course_rate_degps.filter(|c| *c > 3.0) {
        let ratio = peak / cr;
        if (0.3..3.0).contains(&ratio) {
            return format!("gyro_unit = \"deg/s\"  # 99th percentile |w| {peak:.3} against the GNSS course rate {cr:.1} deg/s: deg/s");
        }
        if (0.3..3.0).contains(&(ratio * 180.0 / std::f64::consts::PI)) {
            return format!("gyro_unit = \"rad/s\"  # 99th percentile |w| {peak:.4} against the GNSS course rate {cr:.1} deg/s: rad/s");
        }
    }
    if peak > 10.0 {
        return format!(
            "gyro_unit = \"deg/s\"  # 99th percentile |w| {peak:.2}: too large for rad/s"
        );
    }
    g.unknown.push(format!(
        "gyro unit: 99th percentile |w| {peak:.4} and no turns in the GNSS to compare: rad/s assumed"
    ));
    format!(
        "gyro_unit = \"rad/s\"  # GUESS: 99th percentile |w| {peak:.4}, no turns to compare with"
    )
}

/// The time column: a date-time text column (with its format), else the first increasing
/// numeric one; its index, its values (s) and the text format.
fn time_column(path: &Path, t: &Table) -> anyhow::Result<(usize, Vec<f64>, Option<&'static str>)> {
    let text = (0..t.width)
        .filter(|c| !t.numeric(*c))
        .find_map(|c| super::gnss::text_format(t, c).map(|f| (c, f)));
    let (tc, tv) = match text {
        Some((c, f)) => (c, text_seconds(t, c, f)),
        None => {
            let tc = (0..t.width)
                .find(|c| t.numeric(*c) && !week_like(t, *c) && increasing(&t.col(*c)))
                .ok_or_else(|| anyhow::anyhow!("{}: no increasing time column", path.display()))?;
            (tc, t.col(tc))
        }
    };
    if !increasing(&tv) {
        anyhow::bail!(
            "{}: the time column {} does not increase",
            path.display(),
            tc + 1
        );
    }
    Ok((tc, tv, text.map(|(_, f)| f)))
}

/// Whether column `c` looks like a GPS week (integers in 500..5000) with a numeric column after
/// it (its seconds of week).
fn week_like(t: &Table, c: usize) -> bool {
    t.numeric(c + 1)
        && t.col(c)
            .iter()
            .all(|x| x.fract() == 0.0 && (500.0..5000.0).contains(x))
}

/// Column `c`'s date-time texts in the format `f` as seconds since 1970 (NaN where one does
/// not read).
fn text_seconds(t: &Table, c: usize, f: &str) -> Vec<f64> {
    t.rows
        .iter()
        .map(|r| {
            r.get(c)
                .and_then(|v| chrono::NaiveDateTime::parse_from_str(v, f).ok())
                .map_or(f64::NAN, |d| {
                    let u = d.and_utc();
                    u.timestamp() as f64 + f64::from(u.timestamp_subsec_nanos()) * 1e-9
                })
        })
        .collect()
}

/// The `[imu.csv.time]` lines of a date-time text column `c` in the format `f` (times `tv`)
/// and the sample interval in s.
fn text_time(t: &Table, c: usize, f: &str, tv: &[f64], g: &mut Guess) -> (String, f64) {
    let step = median_step(tv).unwrap_or(f64::NAN);
    let gps = t
        .head
        .iter()
        .any(|l| l.to_ascii_lowercase().contains("gps"));
    if !gps {
        g.unknown.push(format!(
            "IMU time scale of the date-time text (column {}): UTC assumed; write scale = \"gps\" if the logger writes GPS time",
            c + 1
        ));
    }
    (
        format!(
            "kind = \"text\"\nformat = {f:?}  # column {} reads as date-time text `{}`, step {step:.4} s\nscale = \"{}\"  # {}",
            c + 1,
            t.rows[0][c],
            if gps { "gps" } else { "utc" },
            if gps { "the header says GPS" } else { "GUESS: not stated in the file" }
        ),
        step,
    )
}

/// The `[imu.csv.time]` lines and the sample interval in s.
fn time_kind(
    path: &Path,
    t: &Table,
    tc: usize,
    hints: &GnssHints,
    g: &mut Guess,
) -> anyhow::Result<(String, f64)> {
    let tv = t.col(tc);
    let v0 = tv[0];
    let step = median_step(&tv).unwrap_or(f64::NAN);
    let c = tc + 1;
    if v0 > 1e11 {
        return Ok((format!("kind = \"unix_ms\"  # column {c} is {v0:.0}: Unix milliseconds, step {step} ms\nscale = \"utc\"  # Unix time counts UTC"), step * 1e-3));
    }
    if v0 > 1e8 {
        return Ok((format!("kind = \"unix_s\"  # column {c} is {v0:.3}: Unix seconds, step {step} s\nscale = \"utc\"  # Unix time counts UTC"), step));
    }
    let integral = tv.iter().all(|v| v.fract() == 0.0);
    if integral && step >= 1.0 {
        let tag = path.with_file_name(format!(
            "{}.tag",
            path.file_name().unwrap_or_default().to_string_lossy()
        ));
        if tag.exists() {
            let name = tag.file_name().unwrap_or_default().to_string_lossy();
            return Ok((format!("kind = \"ticks_ms\"  # column {c} holds integer ticks, step {step}: milliseconds\ntag_file = {name:?}  # the RTKLIB time tag next to the log places the ticks in GPS time\nstretch_to_tag_end = false"), step * 1e-3));
        }
        g.unknown.push(format!("IMU time: column {c} holds ms ticks and there is no time tag file: times since power-up do not match the GNSS time"));
        return Ok((format!("kind = \"ticks_ms\"  # column {c} holds integer ticks, step {step}: milliseconds (no tag file)"), step * 1e-3));
    }
    if tc > 0 && week_like(t, tc - 1) {
        let w = t.col(tc - 1)[0];
        return Ok((format!("kind = \"week_sow\"  # column {} is a GPS week ({w}), column {c} its seconds of week (step {step} s)", c - 1), step));
    }
    let inside = hints
        .span_s
        .is_some_and(|(a, b)| v0 > a - 3600.0 && v0 < b + 3600.0);
    if !inside {
        g.unknown.push(format!(
            "IMU time: column {c} starts at {v0} s, not within an hour of the GNSS times{}: a time since power-up? The files must share a time base",
            hints.span_s.map_or(String::new(), |(a, b)| format!(" ({a:.1} .. {b:.1})"))
        ));
    }
    Ok((
        format!(
            "kind = \"gps_sow\"  # column {c} runs {v0} .. in steps of {step} s{}",
            if inside {
                ", within the GNSS times: GPS seconds of week"
            } else {
                ": GUESS GPS seconds of week"
            }
        ),
        step,
    ))
}
