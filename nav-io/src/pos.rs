//! RTKLIB `.pos` solution files (the output of rtkpost/rnx2rtkp/rtknavi/str2str).
//!
//! Supported layouts (detected from the `%` column-header line, else from the first record):
//! - time: `yyyy/mm/dd hh:mm:ss.sss` or `week tow`, in GPST, UTC (converted to GPST with the
//!   leap-second table) or JST (UTC + 9 h);
//! - position: `latitude(deg) longitude(deg) height(m)`, the d-m-s variant
//!   (`latitude(d'")`: `dd mm ss.sss` for each of lat and lon), or `x-ecef(m) y-ecef(m) z-ecef(m)`
//!   (converted to geodetic with [`nav_core::earth::ecef_to_geodetic`], its covariance rotated to
//!   NED); ENU baselines are rejected;
//! - then `Q ns sd1 sd2 sd3 sd12 sd23 sd31 age ratio` and optionally the nine velocity fields
//!   `v1 v2 v3 sdv1 sdv2 sdv3 sdv12 sdv23 sdv31`.
//!
//! For LLH files the up axis is flipped to down: `vd = -vu`, std_d = sdu. Only the diagonal
//! standard deviations are kept (the cross terms are RTKLIB's signed square roots of the
//! covariances; they are used for the ECEF -> NED rotation only).
//!
//! Time is returned as GPS seconds of week relative to the week of the FIRST record
//! ([`PosRecord::week`]): a file crossing a week boundary continues past 604800 s, so time
//! stays monotonic. RTKLIB's Q flag: 1 fix, 2 float, 3 SBAS, 4 DGPS, 5 single, 6 PPP (0 none,
//! 7 dead reckoning in demo5); records with Q outside `1..=max_q` are dropped and counted.

use super::gpstime::{days_in_month, gpst_minus_utc_s, gpst_week_sow, SECONDS_PER_WEEK};
use super::lines::{open_text, DataLine, MonotonicTime};
use super::IoError;
use nalgebra::{Matrix3, Vector3};
use nav_core::earth::{ecef_to_geodetic, ecef_to_ned_dcm};
use nav_core::types::{FixQuality, GnssFix};
use std::path::Path;

/// Reading options for [`read_rtklib_pos`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PosOptions {
    /// Keep records with RTKLIB quality `1 <= Q <= max_q` (1 = fixed only, 2 = fixed and
    /// float, ..., 6 = all positioned records). Must be in 1..=6.
    pub max_q: u8,
}

impl Default for PosOptions {
    fn default() -> Self {
        Self { max_q: 6 }
    }
}

/// Time system of a `.pos` file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PosTimeSystem {
    /// GPS time (no leap seconds).
    Gpst,
    /// UTC (converted to GPST with the leap-second table).
    Utc,
    /// Japan standard time, UTC + 9 h.
    Jst,
}

/// Position layout of a `.pos` file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PosPositionFormat {
    /// Latitude, longitude in decimal degrees, ellipsoidal height in metres.
    LlhDeg,
    /// Latitude, longitude as degrees, minutes, seconds (three fields each), height in metres.
    LlhDms,
    /// ECEF x, y, z in metres.
    Ecef,
}

/// The content of a `.pos` file after the quality filter.
#[derive(Debug, Clone, PartialEq)]
pub struct PosRecord {
    /// The kept fixes, time in seconds of `week` (see the module notes).
    pub fixes: Vec<GnssFix>,
    /// GPS week of the first record (None for a file without records).
    pub week: Option<i64>,
    /// Data records read (kept + dropped).
    pub epochs: usize,
    /// Records dropped because Q was outside `1..=max_q`.
    pub dropped_by_quality: usize,
    /// Number of records per Q flag value 0..=7 (before filtering).
    pub count_by_q: [usize; 8],
    /// Time system of the file.
    pub time_system: PosTimeSystem,
    /// Position layout of the file.
    pub position_format: PosPositionFormat,
    /// Whether the records carry velocities.
    pub has_velocity: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TimeFormat {
    Calendar,
    WeekTow,
}

struct Layout {
    time_system: PosTimeSystem,
    pos: PosPositionFormat,
    time: TimeFormat,
    names: Vec<String>,
    /// Index of the first field after the position (Q).
    q_idx: usize,
}

impl Layout {
    fn new(time_system: PosTimeSystem, pos: PosPositionFormat, time: TimeFormat) -> Self {
        let mut names: Vec<String> = match time {
            TimeFormat::Calendar => vec!["date".into(), "time".into()],
            TimeFormat::WeekTow => vec!["gps_week".into(), "tow_s".into()],
        };
        let (pos_names, after): (&[&str], [&str; 19]) = match pos {
            PosPositionFormat::LlhDeg | PosPositionFormat::LlhDms => (
                if pos == PosPositionFormat::LlhDeg {
                    &["latitude_deg", "longitude_deg", "height_m"]
                } else {
                    &[
                        "latitude_d",
                        "latitude_m",
                        "latitude_s",
                        "longitude_d",
                        "longitude_m",
                        "longitude_s",
                        "height_m",
                    ]
                },
                [
                    "Q", "ns", "sdn_m", "sde_m", "sdu_m", "sdne_m", "sdeu_m", "sdun_m", "age_s",
                    "ratio", "vn_mps", "ve_mps", "vu_mps", "sdvn_mps", "sdve_mps", "sdvu_mps",
                    "sdvne", "sdveu", "sdvun",
                ],
            ),
            PosPositionFormat::Ecef => (
                &["x_ecef_m", "y_ecef_m", "z_ecef_m"],
                [
                    "Q", "ns", "sdx_m", "sdy_m", "sdz_m", "sdxy_m", "sdyz_m", "sdzx_m", "age_s",
                    "ratio", "vx_mps", "vy_mps", "vz_mps", "sdvx_mps", "sdvy_mps", "sdvz_mps",
                    "sdvxy", "sdvyz", "sdvzx",
                ],
            ),
        };
        names.extend(pos_names.iter().map(|s| s.to_string()));
        let q_idx = names.len();
        names.extend(after.iter().map(|s| s.to_string()));
        Self {
            time_system,
            pos,
            time,
            names,
            q_idx,
        }
    }

    fn base_len(&self) -> usize {
        self.q_idx + 10
    }

    fn name(&self, i: usize) -> &str {
        self.names.get(i).map_or("?", String::as_str)
    }
}

/// Header facts found in `%` lines.
#[derive(Default)]
struct HeaderInfo {
    time_system: Option<PosTimeSystem>,
    pos: Option<PosPositionFormat>,
}

fn parse_header_line(
    line: &str,
    info: &mut HeaderInfo,
    path: &Path,
    line_no: usize,
) -> Result<(), IoError> {
    let body = line.trim_start().trim_start_matches('%').trim();
    let lower = body.to_ascii_lowercase();
    let is_col_header =
        lower.contains("latitude") || lower.contains("ecef") || lower.contains("baseline");
    if !is_col_header {
        return Ok(());
    }
    if lower.contains("baseline") {
        return Err(IoError::Format {
            path: path.to_path_buf(),
            line: line_no,
            message:
                "ENU baseline .pos files are not supported (use lat/lon/height or ECEF output)"
                    .into(),
        });
    }
    info.pos = Some(if lower.contains("latitude(d'") {
        PosPositionFormat::LlhDms
    } else if lower.contains("latitude") {
        PosPositionFormat::LlhDeg
    } else {
        PosPositionFormat::Ecef
    });
    let first = body.split_whitespace().next().unwrap_or("");
    info.time_system = Some(match first.to_ascii_uppercase().as_str() {
        "GPST" => PosTimeSystem::Gpst,
        "UTC" => PosTimeSystem::Utc,
        "JST" => PosTimeSystem::Jst,
        other => {
            return Err(IoError::Format {
                path: path.to_path_buf(),
                line: line_no,
                message: format!(
                    "unknown time system {other:?} in the column header (GPST, UTC or JST)"
                ),
            })
        }
    });
    Ok(())
}

fn parse_int_in(
    dl: &DataLine<'_>,
    idx: usize,
    name: &str,
    s: &str,
    min: i64,
    max: i64,
) -> Result<i64, IoError> {
    match s.trim().parse::<i64>() {
        Ok(v) if (min..=max).contains(&v) => Ok(v),
        _ => Err(dl.invalid(
            idx,
            name,
            format!("expected an integer in {min}..={max}, got {s:?}"),
        )),
    }
}

/// (week, sow) in GPST of the time fields of a record.
fn parse_time(dl: &DataLine<'_>, lay: &Layout) -> Result<(i64, f64), IoError> {
    match lay.time {
        TimeFormat::WeekTow => {
            let week = dl.integer(0, lay.name(0), 0, 1 << 20)?;
            let tow = dl.num(1, lay.name(1))?;
            if !(0.0..SECONDS_PER_WEEK + 1.0).contains(&tow) {
                return Err(dl.invalid(1, lay.name(1), "time of week outside [0, 604801) s"));
            }
            if lay.time_system != PosTimeSystem::Gpst {
                return Err(dl.invalid(
                    0,
                    lay.name(0),
                    "week/tow time in UTC/JST is not supported (RTKLIB writes week/tow in GPST)",
                ));
            }
            Ok((week, tow))
        }
        TimeFormat::Calendar => {
            let date = dl.fields.first().copied().unwrap_or("");
            let dp: Vec<&str> = date.split('/').collect();
            if dp.len() != 3 {
                return Err(dl.invalid(0, "date", "expected yyyy/mm/dd"));
            }
            let y = parse_int_in(dl, 0, "date (year)", dp[0], 1900, 9999)?;
            let mo = parse_int_in(dl, 0, "date (month)", dp[1], 1, 12)? as u32;
            let d = parse_int_in(dl, 0, "date (day)", dp[2], 1, 31)? as u32;
            if d > days_in_month(y, mo) {
                return Err(dl.invalid(0, "date", "day outside the month"));
            }
            let time = dl.fields.get(1).copied().unwrap_or("");
            let tp: Vec<&str> = time.split(':').collect();
            if tp.len() != 3 {
                return Err(dl.invalid(1, "time", "expected hh:mm:ss.sss"));
            }
            let h = parse_int_in(dl, 1, "time (hour)", tp[0], 0, 23)? as u32;
            let mi = parse_int_in(dl, 1, "time (minute)", tp[1], 0, 59)? as u32;
            let sec: f64 = match tp[2].trim().parse::<f64>() {
                Ok(s) if (0.0..61.0).contains(&s) => s,
                _ => return Err(dl.invalid(1, "time (second)", "expected seconds in [0, 61)")),
            };
            let (week, mut sow) = gpst_week_sow(y, mo, d, h, mi, sec);
            match lay.time_system {
                PosTimeSystem::Gpst => {}
                PosTimeSystem::Utc => sow += f64::from(gpst_minus_utc_s(y, mo, d)),
                PosTimeSystem::Jst => sow += f64::from(gpst_minus_utc_s(y, mo, d)) - 9.0 * 3600.0,
            }
            // normalise into the week after the offsets
            let wk_shift = (sow / SECONDS_PER_WEEK).floor();
            Ok((week + wk_shift as i64, sow - wk_shift * SECONDS_PER_WEEK))
        }
    }
}

/// Degrees from three d-m-s fields starting at `idx` (sign taken from the degree field's text,
/// so `-0 30 0` is -0.5 deg).
fn parse_dms(dl: &DataLine<'_>, lay: &Layout, idx: usize, max_deg: f64) -> Result<f64, IoError> {
    let d = dl.num(idx, lay.name(idx))?;
    let m = dl.num(idx + 1, lay.name(idx + 1))?;
    let s = dl.num(idx + 2, lay.name(idx + 2))?;
    if !(0.0..60.0).contains(&m) {
        return Err(dl.invalid(idx + 1, lay.name(idx + 1), "minutes outside [0, 60)"));
    }
    if !(0.0..60.0).contains(&s) {
        return Err(dl.invalid(idx + 2, lay.name(idx + 2), "seconds outside [0, 60)"));
    }
    let neg = dl
        .fields
        .get(idx)
        .is_some_and(|t| t.trim_start().starts_with('-'));
    let v = d.abs() + m / 60.0 + s / 3600.0;
    if v > max_deg {
        return Err(dl.invalid(idx, lay.name(idx), format!("angle beyond {max_deg} deg")));
    }
    Ok(if neg { -v } else { v })
}

/// Symmetric covariance from RTKLIB's (sd1, sd2, sd3, sd12, sd23, sd31) where cross terms are
/// signed square roots.
fn cov_from_rtklib(sd: &[f64; 6]) -> Matrix3<f64> {
    let c = |s: f64| s * s.abs();
    let (xy, yz, zx) = (c(sd[3]), c(sd[4]), c(sd[5]));
    Matrix3::new(
        sd[0] * sd[0],
        xy,
        zx,
        xy,
        sd[1] * sd[1],
        yz,
        zx,
        yz,
        sd[2] * sd[2],
    )
}

fn parse_record(
    dl: &DataLine<'_>,
    lay: &Layout,
    week0: i64,
) -> Result<(GnssFix, i64, u8), IoError> {
    let base = lay.base_len();
    dl.require(
        base,
        base + 9,
        &lay.names.iter().map(String::as_str).collect::<Vec<_>>(),
    )?;
    let has_vel = match dl.len() - base {
        0 => false,
        9 => true,
        k => {
            return Err(IoError::TooFewFields {
                path: dl.path.to_path_buf(),
                line: dl.line,
                column: dl.len() + 1,
                name: lay.name(dl.len()).to_string(),
                found: dl.len(),
                expected: format!(
                    "{base} or {} (with velocities; {k} velocity fields found)",
                    base + 9
                ),
            })
        }
    };
    let (week, sow) = parse_time(dl, lay)?;
    let q_idx = lay.q_idx;
    let q = dl.integer(q_idx, "Q", 0, 7)? as u8;
    let ns = dl.integer(q_idx + 1, "ns", 0, 10_000)?.min(255) as u8;
    let mut sd = [0.0; 6];
    for (k, v) in sd.iter_mut().enumerate() {
        *v = if k < 3 {
            dl.sigma(q_idx + 2 + k, lay.name(q_idx + 2 + k))?
        } else {
            dl.num(q_idx + 2 + k, lay.name(q_idx + 2 + k))?
        };
    }
    let _age = dl.num(q_idx + 8, lay.name(q_idx + 8))?;
    let _ratio = dl.num(q_idx + 9, lay.name(q_idx + 9))?;
    let mut vel = [0.0; 3];
    let mut sdv = [0.0; 6];
    if has_vel {
        let v0 = q_idx + 10;
        for (k, v) in vel.iter_mut().enumerate() {
            *v = dl.num(v0 + k, lay.name(v0 + k))?;
        }
        for (k, v) in sdv.iter_mut().enumerate() {
            *v = if k < 3 {
                dl.sigma(v0 + 3 + k, lay.name(v0 + 3 + k))?
            } else {
                dl.num(v0 + 3 + k, lay.name(v0 + 3 + k))?
            };
        }
    }
    // both time formats take two fields
    let p0 = 2;
    let mut fix = GnssFix {
        t_s: (week - week0) as f64 * SECONDS_PER_WEEK + sow,
        quality: FixQuality::from_rtklib_q(q),
        num_sats: ns,
        has_velocity: has_vel,
        ..GnssFix::default()
    };
    match lay.pos {
        PosPositionFormat::LlhDeg | PosPositionFormat::LlhDms => {
            let (lat, lon, h) = if lay.pos == PosPositionFormat::LlhDeg {
                (
                    dl.lat_deg(p0, lay.name(p0))?,
                    dl.lon_deg(p0 + 1, lay.name(p0 + 1))?,
                    dl.num(p0 + 2, lay.name(p0 + 2))?,
                )
            } else {
                (
                    parse_dms(dl, lay, p0, 90.0)?,
                    parse_dms(dl, lay, p0 + 3, 360.0)?,
                    dl.num(p0 + 6, lay.name(p0 + 6))?,
                )
            };
            fix.lat_rad = lat.to_radians();
            fix.lon_rad = lon.to_radians();
            fix.h_m = h;
            fix.pos_std_ned_m = [sd[0], sd[1], sd[2]];
            if has_vel {
                fix.vel_ned_mps = [vel[0], vel[1], -vel[2]];
                fix.vel_std_ned_mps = [sdv[0], sdv[1], sdv[2]];
            }
        }
        PosPositionFormat::Ecef => {
            ecef_fix(dl, lay, &sd, has_vel.then_some((&vel, &sdv)), &mut fix)?;
        }
    }
    Ok((fix, week, q))
}

/// The position (and velocity) of an ECEF record into `fix`: the ECEF position at fields
/// 2..5 checked for a plausible radius and converted to latitude, longitude and height; the
/// RTKLIB standard deviations `sd` (sdx, sdy, sdz, sdxy, sdyz, sdzx in m) rotated into NED, and
/// likewise the velocity and its deviations when given.
fn ecef_fix(
    dl: &DataLine<'_>,
    lay: &Layout,
    sd: &[f64; 6],
    velocity: Option<(&[f64; 3], &[f64; 6])>,
    fix: &mut GnssFix,
) -> Result<(), IoError> {
    let p0 = 2;
    let r = Vector3::new(
        dl.num(p0, lay.name(p0))?,
        dl.num(p0 + 1, lay.name(p0 + 1))?,
        dl.num(p0 + 2, lay.name(p0 + 2))?,
    );
    let rn = r.norm();
    if !(1.0e6..1.0e8).contains(&rn) {
        return Err(dl.invalid(
            p0,
            lay.name(p0),
            "ECEF position not between 1000 km and 100000 km from the earth's centre",
        ));
    }
    let llh = ecef_to_geodetic(&r);
    if !(llh.lat_rad.is_finite() && llh.lon_rad.is_finite() && llh.h_m.is_finite()) {
        return Err(dl.invalid(
            p0,
            lay.name(p0),
            "ECEF position does not convert to latitude/longitude/height",
        ));
    }
    let c = ecef_to_ned_dcm(&llh);
    fix.lat_rad = llh.lat_rad;
    fix.lon_rad = llh.lon_rad;
    fix.h_m = llh.h_m;
    let p = c * cov_from_rtklib(sd) * c.transpose();
    fix.pos_std_ned_m = [
        p[(0, 0)].max(0.0).sqrt(),
        p[(1, 1)].max(0.0).sqrt(),
        p[(2, 2)].max(0.0).sqrt(),
    ];
    if let Some((vel, sdv)) = velocity {
        let v = c * Vector3::new(vel[0], vel[1], vel[2]);
        fix.vel_ned_mps = [v.x, v.y, v.z];
        let pv = c * cov_from_rtklib(sdv) * c.transpose();
        fix.vel_std_ned_mps = [
            pv[(0, 0)].max(0.0).sqrt(),
            pv[(1, 1)].max(0.0).sqrt(),
            pv[(2, 2)].max(0.0).sqrt(),
        ];
    }
    Ok(())
}

/// Reads an RTKLIB `.pos` file (plain or gzip) and keeps the records with `1 <= Q <= max_q`
/// ([`PosReader`] collected).
pub fn read_rtklib_pos(path: impl AsRef<Path>, opts: &PosOptions) -> Result<PosRecord, IoError> {
    let mut rd = PosReader::open(path, opts)?;
    let mut fixes = Vec::new();
    for r in &mut rd {
        fixes.push(r?.0);
    }
    Ok(PosRecord {
        fixes,
        week: rd.week(),
        epochs: rd.epochs(),
        dropped_by_quality: rd.dropped_by_quality(),
        count_by_q: rd.count_by_q(),
        time_system: rd.time_system(),
        position_format: rd.position_format(),
        has_velocity: rd.has_velocity(),
    })
}

/// An RTKLIB `.pos` file (plain or gzip) read one record at a time: the one parser of the
/// format ([`read_rtklib_pos`] collects it). Yields the kept fixes (`1 <= Q <= max_q`) with
/// their 1-based file line; the counters ([`Self::epochs`], [`Self::dropped_by_quality`],
/// [`Self::count_by_q`], ...) cover the records read so far. The week ([`Self::week`]) is the
/// first record's, known once it is read. Errors name file, line and column; after an error
/// the reader ends. Nothing is kept but the current line and the layout: constant memory.
pub struct PosReader {
    rd: super::lines::LineReader,
    path: std::path::PathBuf,
    max_q: u8,
    info: HeaderInfo,
    layout: Option<Layout>,
    week0: Option<i64>,
    mono: MonotonicTime,
    epochs: usize,
    dropped_by_quality: usize,
    count_by_q: [usize; 8],
    has_velocity: bool,
    failed: bool,
}

impl PosReader {
    /// Opens `path` (an error when `max_q` is outside 1..=6 or the file cannot be opened).
    pub fn open(path: impl AsRef<Path>, opts: &PosOptions) -> Result<Self, IoError> {
        let path = path.as_ref();
        if !(1..=6).contains(&opts.max_q) {
            return Err(IoError::Config {
                path: path.to_path_buf(),
                message: format!("max_q must be in 1..=6, got {}", opts.max_q),
                source: None,
            });
        }
        Ok(Self {
            rd: open_text(path)?,
            path: path.to_path_buf(),
            max_q: opts.max_q,
            info: HeaderInfo::default(),
            layout: None,
            week0: None,
            mono: MonotonicTime::new(),
            epochs: 0,
            dropped_by_quality: 0,
            count_by_q: [0; 8],
            has_velocity: false,
            failed: false,
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// GPS week of the first record (None before it is read, or for a file without records).
    pub fn week(&self) -> Option<i64> {
        self.week0
    }

    /// Data records read so far (kept + dropped).
    pub fn epochs(&self) -> usize {
        self.epochs
    }

    /// Records dropped so far because Q was outside `1..=max_q`.
    pub fn dropped_by_quality(&self) -> usize {
        self.dropped_by_quality
    }

    /// Records read so far per Q flag value 0..=7 (before filtering).
    pub fn count_by_q(&self) -> [usize; 8] {
        self.count_by_q
    }

    /// Time system of the file (GPST until the first record fixes the layout).
    pub fn time_system(&self) -> PosTimeSystem {
        self.layout
            .as_ref()
            .map_or(PosTimeSystem::Gpst, |l| l.time_system)
    }

    /// Position layout of the file (lat/lon in degrees until the first record fixes it).
    pub fn position_format(&self) -> PosPositionFormat {
        self.layout
            .as_ref()
            .map_or(PosPositionFormat::LlhDeg, |l| l.pos)
    }

    /// Whether a record read so far carried velocities.
    pub fn has_velocity(&self) -> bool {
        self.has_velocity
    }

    /// The next kept fix and its line; `None` at the end of the file.
    fn read(&mut self) -> Result<Option<(GnssFix, usize)>, IoError> {
        loop {
            let Some((line_no, text)) = self.rd.next_raw()? else {
                return Ok(None);
            };
            let path = self.path.as_path();
            let t = text.trim_start();
            if t.starts_with('%') || t.starts_with('#') {
                if self.layout.is_none() {
                    parse_header_line(t, &mut self.info, path, line_no)?;
                }
                continue;
            }
            if t.is_empty() {
                continue;
            }
            // .pos: split on commas and white space alike (the date and time are two fields).
            let fields = text
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter(|s| !s.is_empty())
                .collect();
            let dl = DataLine {
                path,
                line: line_no,
                fields,
            };
            let lay = match &self.layout {
                Some(l) => l,
                None => {
                    let tf = if dl.fields.first().is_some_and(|f| f.contains('/')) {
                        TimeFormat::Calendar
                    } else {
                        TimeFormat::WeekTow
                    };
                    self.layout.insert(Layout::new(
                        self.info.time_system.unwrap_or(PosTimeSystem::Gpst),
                        self.info.pos.unwrap_or(PosPositionFormat::LlhDeg),
                        tf,
                    ))
                }
            };
            let w0 = match self.week0 {
                Some(w) => w,
                None => {
                    let (w, _) = parse_time(&dl, lay)?;
                    self.week0 = Some(w);
                    w
                }
            };
            let (fix, _week, q) = parse_record(&dl, lay, w0)?;
            self.mono.check(&dl, 1, lay.name(1), fix.t_s)?;
            self.epochs += 1;
            if let Some(c) = self.count_by_q.get_mut(usize::from(q.min(7))) {
                *c += 1;
            }
            if fix.has_velocity {
                self.has_velocity = true;
            }
            if q >= 1 && q <= self.max_q {
                return Ok(Some((fix, line_no)));
            }
            self.dropped_by_quality += 1;
        }
    }
}

impl Iterator for PosReader {
    type Item = Result<(GnssFix, usize), IoError>;

    /// The next kept fix and its 1-based line; after an error, `None`.
    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        let mut r = self.read().transpose();
        if matches!(&r, Some(Err(e)) if super::lines::cut_short(&self.rd, e)) {
            // a last line cut short (a log still being written): the file ends before it
            r = None;
        }
        if matches!(r, Some(Err(_))) {
            self.failed = true;
        }
        r
    }
}
