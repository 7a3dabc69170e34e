//! The GNSS file: its format (u-blox UBX, NMEA, RTKLIB `.pos`, the project's text, or a CSV
//! mapped column by column), written as the `[gnss]` section with its evidence.

use super::table::{increasing, median_step, Table};
use super::Guess;
use std::fmt::Write as _;
use std::path::Path;

/// Common chrono formats of date-time text fields, tried in order.
const TEXT_FORMATS: [&str; 6] = [
    "%Y-%m-%dT%H:%M:%S%.fZ",
    "%Y-%m-%dT%H:%M:%S%.f",
    "%Y-%m-%d %H:%M:%S%.f",
    "%Y/%m/%d %H:%M:%S%.f",
    "%Y_%m_%d_%H_%M_%S_%3f",
    "%Y%m%d%H%M%S%.f",
];

/// Bytes of the file's start searched for NMEA sentences.
const HEAD_BYTES: u64 = 1 << 16;

/// The first `n` bytes of `path` (all of it when shorter): a log of any length costs `n`.
fn read_head(path: &Path, n: u64) -> anyhow::Result<Vec<u8>> {
    use std::io::Read as _;
    let mut head = Vec::new();
    nav_io::open_data_file(path)?
        .take(n)
        .read_to_end(&mut head)?;
    Ok(head)
}

fn is_ubx(path: &Path) -> anyhow::Result<bool> {
    let head = read_head(path, 4096)?;
    let sync = head.windows(2).any(|w| w == [0xb5, 0x62]);
    let binary = head
        .iter()
        .filter(|b| **b < 9 || (**b > 13 && **b < 32))
        .count()
        > head.len() / 20;
    Ok(sync && binary)
}

/// The `[gnss]` section of `path` (written as `shown`).
pub(crate) fn detect(path: &Path, shown: &str, g: &mut Guess) -> anyhow::Result<String> {
    let mut s = String::new();
    if is_ubx(path)? {
        writeln!(s, "[gnss]\npath = {shown:?}\nformat = \"ubx\"  # UBX sync bytes b5 62 in a binary file: u-blox log (NAV-PVT read)")?;
        writeln!(
            s,
            "use_velocity = true  # NAV-PVT carries velN/E/D with sAcc"
        )?;
        return Ok(s);
    }
    let t = Table::read(path)?;
    let raw = read_head(path, HEAD_BYTES)?;
    let text = String::from_utf8_lossy(&raw).into_owned();
    if text
        .lines()
        .any(|l| l.starts_with('$') && l.len() > 6 && &l[3..6] == "GGA")
    {
        writeln!(
            s,
            "[gnss]\npath = {shown:?}\nformat = \"nmea\"  # lines `$..GGA,...`: an NMEA 0183 log"
        )?;
        if !text
            .lines()
            .any(|l| l.starts_with('$') && l.get(3..6) == Some("GST"))
        {
            writeln!(s, "[gnss.log]\nhdop_uere_m = 3.0  # GUESS: no GST sentences, sigmas from HDOP x 3 m (single-point receiver)")?;
            g.unknown.push(
                "GNSS sigmas: the NMEA log has no GST; HDOP x 3 m assumed (hdop_uere_m)".into(),
            );
        }
        return Ok(s);
    }
    if let Some(sc) = &t.semicolons {
        anyhow::bail!("{}", sc.describe());
    }
    if t.head.iter().any(|l| {
        l.starts_with('%')
            && (l.contains("latitude(") || l.contains("x-ecef(") || l.contains("e-baseline("))
    }) {
        writeln!(s, "[gnss]\npath = {shown:?}\nformat = \"rtklib_pos\"  # `%` header with RTKLIB's column names")?;
        if let Some(line) = pos_quality(&t) {
            writeln!(s, "{line}")?;
        }
        let has_vel = t.head.iter().any(|l| l.contains("vn(m/s)"));
        if has_vel {
            writeln!(
                s,
                "use_velocity = true  # the header names vn(m/s) ve(m/s) vu(m/s)"
            )?;
        }
        return Ok(s);
    }
    if project_text(&t) {
        writeln!(s, "[gnss]\npath = {shown:?}\nformat = \"text\"  # {} white-space numeric columns `t lat lon h sN sE sD ...`: the project's GNSS text", t.width)?;
        if t.width >= 13 {
            writeln!(
                s,
                "use_velocity = true  # 13 columns: velocities and their sigmas"
            )?;
        }
        return Ok(s);
    }
    csv(&t, shown, g)
}

/// The `max_q` line of an RTKLIB `.pos` file from the counts of its quality flags (column `Q`
/// of the `%` header): RTK fixed solutions only when they are at least half of the records,
/// else fixed and float when those are, else every quality.
fn pos_quality(t: &Table) -> Option<String> {
    let names: Vec<&str> = t
        .head
        .iter()
        .rev()
        .find(|l| l.starts_with('%') && l.split_whitespace().any(|w| w == "Q"))?
        .trim_start_matches('%')
        .split_whitespace()
        .collect();
    // the time takes two fields in the data (date and time, or week and seconds) and one name
    let col = names.iter().position(|n| *n == "Q")? + t.width.checked_sub(names.len())?;
    let mut counts = [0usize; 7];
    for r in &t.rows {
        let q = r.get(col)?.parse::<f64>().ok()?;
        if !((1.0..=6.0).contains(&q) && q.fract() == 0.0) {
            return None;
        }
        counts[q as usize] += 1;
    }
    let n = t.rows.len();
    if n == 0 {
        return None;
    }
    let seen: Vec<String> = (1..=6)
        .filter(|q| counts[*q] > 0)
        .map(|q| format!("{} x Q{q}", counts[q]))
        .collect();
    let (max_q, why) = if 2 * counts[1] >= n {
        (1, "RTK fixed solutions are at least half: float and single ones are left out (max_q = 2 keeps the floats, with their sigmas)")
    } else if 2 * (counts[1] + counts[2]) >= n {
        (
            2,
            "fixed and float solutions are at least half: single-point ones are left out",
        )
    } else {
        (
            6,
            "no quality dominates: every solution is used with its sigmas",
        )
    };
    Some(format!(
        "max_q = {max_q}  # quality flags of the first {n} records: {}; {why}",
        seen.join(", ")
    ))
}

fn project_text(t: &Table) -> bool {
    !t.comma
        && t.names.is_none()
        && (t.width == 7 || t.width == 13)
        && (0..t.width).all(|c| t.numeric(c))
        && increasing(&t.col(0))
        && t.col(1).iter().all(|v| v.abs() <= 90.0)
        && t.col(4).iter().all(|v| *v > 0.0)
}

fn named(t: &Table, keys: &[&str]) -> Option<usize> {
    (0..t.width).find(|c| {
        let n = t.name(*c);
        keys.iter().any(|k| n == *k)
    })
}

/// The first of the known date-time formats that column `c`'s first value reads in.
pub(super) fn text_format(t: &Table, c: usize) -> Option<&'static str> {
    let v = t.rows.first()?.get(c)?;
    TEXT_FORMATS
        .iter()
        .find(|f| chrono::NaiveDateTime::parse_from_str(v, f).is_ok())
        .copied()
}

/// Time column, kind and its TOML.
fn time_of(t: &Table, g: &mut Guess) -> anyhow::Result<(usize, String)> {
    for c in 0..t.width {
        if let Some(f) = (!t.numeric(c)).then(|| text_format(t, c)).flatten() {
            let gps = t
                .head
                .iter()
                .any(|l| l.to_ascii_lowercase().contains("gps"));
            let scale = if gps { "gps" } else { "utc" };
            if !gps {
                g.unknown.push(format!(
                    "GNSS time scale of the date-time text (column {}): UTC assumed; write \
                     scale = \"gps\" if the receiver logs GPS time",
                    c + 1
                ));
            }
            return Ok((c, format!("kind = \"text\"\nformat = {f:?}  # column {} reads as date-time text `{}`\nscale = \"{scale}\"  # {}", c + 1, t.rows[0][c], if gps { "the header says GPS" } else { "GUESS: not stated in the file" })));
        }
    }
    let c = (0..t.width)
        .find(|c| t.numeric(*c) && increasing(&t.col(*c)))
        .ok_or_else(|| {
            anyhow::anyhow!("no time column found (no increasing numeric or date-time text column)")
        })?;
    let v0 = t.col(c)[0];
    let step = median_step(&t.col(c)).unwrap_or(f64::NAN);
    let kind = if v0 > 1e11 {
        format!("kind = \"unix_ms\"  # column {} is {v0:.0}: Unix milliseconds\nscale = \"utc\"  # Unix time counts UTC", c + 1)
    } else if v0 > 1e8 {
        format!("kind = \"unix_s\"  # column {} is {v0:.3}: Unix seconds\nscale = \"utc\"  # Unix time counts UTC", c + 1)
    } else if let Some(w) = (c > 0).then(|| t.col(c - 1)).filter(|w| {
        w.iter()
            .all(|x| x.fract() == 0.0 && (500.0..5000.0).contains(x))
    }) {
        return Ok((c, format!("kind = \"week_sow\"  # column {} is a GPS week ({}), column {} its seconds (step {step} s)", c, w[0], c + 1)));
    } else {
        format!("kind = \"gps_sow\"  # column {} runs {v0} .. in steps of {step} s: GPS seconds of week", c + 1)
    };
    Ok((c, kind))
}

/// A GNSS CSV/text log mapped by the header's names, else by the columns' content.
fn csv(t: &Table, shown: &str, g: &mut Guess) -> anyhow::Result<String> {
    if t.rows.is_empty() {
        anyhow::bail!("no data rows recognised");
    }
    let (tc, time_toml) = time_of(t, g)?;
    let mut cols = String::new();
    let r = |c: usize| t.column_ref(c);
    writeln!(cols, "time = {}", r(tc))?;
    if time_toml.contains("week_sow") {
        writeln!(cols, "week = {}", r(tc - 1))?;
    }
    let (lat, lon, h) = lat_lon_h(t, tc)?;
    writeln!(cols, "lat = {}\nlon = {}\nh = {}", r(lat), r(lon), r(h))?;
    let mut extra = String::new();
    sigma_columns(t, h, &mut cols, &mut extra, g)?;
    let speed = named(t, &["speed", "spd", "speed_mps", "ground_speed"]);
    let course = named(t, &["bearing", "course", "cog", "heading", "track"]);
    let mut use_vel = false;
    if let (Some(sp), Some(co)) = (speed, course) {
        writeln!(cols, "speed = {}\ncourse = {}", r(sp), r(co))?;
        use_vel = true;
        match named(t, &["speed_acc", "sacc", "speed_accuracy", "s_acc"]) {
            Some(c) => writeln!(cols, "speed_sigma = {}", r(c))?,
            None => {
                writeln!(extra, "default_vel_sigma_ned_mps = [0.3, 0.3, 0.6]  # GUESS: no speed accuracy column")?;
                g.unknown
                    .push("GNSS velocity sigmas: no column; 0.3 m/s horizontal assumed".into());
            }
        }
    }
    let mut quality = String::new();
    if let Some(q) = (0..t.width).find(|c| {
        !t.numeric(*c)
            && *c != tc
            && t.rows
                .iter()
                .all(|row| nav_io::gnsscsv::quality_from_name(&row[*c]).is_some())
    }) {
        let mut seen: Vec<String> = t.rows.iter().map(|row| row[q].clone()).collect();
        seen.sort();
        seen.dedup();
        writeln!(
            quality,
            "[gnss.csv.quality]\ncolumn = {}  # names of fix qualities: {}",
            r(q),
            seen.join(", ")
        )?;
    }
    let mut s = String::new();
    writeln!(
        s,
        "[gnss]\npath = {shown:?}\nformat = \"csv\"  # {} separated, {} columns{}",
        t.separator(),
        t.width,
        if t.names.is_some() { ", a header" } else { "" }
    )?;
    if use_vel {
        writeln!(s, "use_velocity = true  # speed and course columns")?;
    }
    writeln!(s, "[gnss.csv]")?;
    if t.skip_lines > 0 {
        writeln!(s, "skip_lines = {}", t.skip_lines)?;
    }
    s.push_str(&extra);
    writeln!(
        s,
        "[gnss.csv.columns]\n{cols}[gnss.csv.time]\n{time_toml}\n{quality}"
    )?;
    Ok(s)
}

/// The latitude, longitude and height columns: by the header's names, else the first numeric
/// pair with fractions within +-90 and +-180 and the column after it.
fn lat_lon_h(t: &Table, tc: usize) -> anyhow::Result<(usize, usize, usize)> {
    let lat = named(t, &["lat", "latitude", "lat_deg"]);
    let lon = named(t, &["lon", "lng", "longitude", "lon_deg"]);
    let h = named(t, &["alt", "h", "height", "altitude", "height_m", "alt_m"]);
    Ok(match (lat, lon, h) {
        (Some(a), Some(b), Some(c)) => (a, b, c),
        _ => {
            // content: the first numeric pair lat (|v| <= 90) and lon (|v| <= 180) with a
            // fraction, then the height
            let c = (0..t.width.saturating_sub(2))
                .find(|c| {
                    *c != tc
                        && t.numeric(*c)
                        && t.numeric(c + 1)
                        && t.col(*c)
                            .iter()
                            .all(|v| v.abs() <= 90.0 && v.fract() != 0.0)
                        && t.col(c + 1)
                            .iter()
                            .all(|v| v.abs() <= 180.0 && v.fract() != 0.0)
                })
                .ok_or_else(|| anyhow::anyhow!("no latitude/longitude columns found"))?;
            (c, c + 1, c + 2)
        }
    })
}

/// The GNSS sigma columns (N/E/D sigmas, horizontal and vertical accuracies, or three positive
/// columns after the height) into `cols`, or a guessed default into `extra`.
fn sigma_columns(
    t: &Table,
    h: usize,
    cols: &mut String,
    extra: &mut String,
    g: &mut Guess,
) -> std::fmt::Result {
    let sig = [
        named(t, &["sdn", "sigma_n", "sn", "std_n"]),
        named(t, &["sde", "sigma_e", "se", "std_e"]),
        named(
            t,
            &["sdu", "sdd", "sigma_d", "sigma_u", "sd", "std_d", "std_u"],
        ),
    ];
    let hacc = named(
        t,
        &[
            "acc",
            "accuracy",
            "hacc",
            "horizontal_accuracy",
            "h_acc",
            "eph",
        ],
    );
    let vacc = named(t, &["vacc", "vertical_accuracy", "v_acc", "epv"]);
    if let [Some(a), Some(b), Some(c)] = sig {
        writeln!(
            cols,
            "sigma_ned = [{}, {}, {}]",
            t.column_ref(a),
            t.column_ref(b),
            t.column_ref(c)
        )?;
    } else if let Some(a) = hacc {
        writeln!(cols, "sigma_h = {}", t.column_ref(a))?;
        match vacc {
            Some(v) => writeln!(cols, "sigma_v = {}", t.column_ref(v))?,
            None => {
                writeln!(
                    extra,
                    "default_sigma_ned_m = [3.0, 3.0, 6.0]  # GUESS: no vertical accuracy column"
                )?;
                g.unknown
                    .push("GNSS vertical sigma: no column; 6 m assumed".into());
            }
        }
    } else if t.names.is_none()
        && h + 3 < t.width
        && (h + 1..h + 4).all(|c| t.numeric(c) && t.col(c).iter().all(|v| *v > 0.0 && *v < 100.0))
    {
        writeln!(
            cols,
            "sigma_ned = [{}, {}, {}]  # three positive columns after the height: sigmas N/E/D, m",
            t.column_ref(h + 1),
            t.column_ref(h + 2),
            t.column_ref(h + 3)
        )?;
    } else {
        writeln!(
            extra,
            "default_sigma_ned_m = [3.0, 3.0, 6.0]  # GUESS: no accuracy column found"
        )?;
        g.unknown
            .push("GNSS sigmas: no accuracy column; 3 m horizontal, 6 m vertical assumed".into());
    }
    Ok(())
}
