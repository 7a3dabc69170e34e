//! Generic GNSS CSV/text logs with a column mapping, like [`super::imucsv`] for the IMU.
//!
//! # Mapping ([`GnssCsvFormat`], serde/TOML, `[gnss.csv]` of a run configuration)
//! - `skip_lines`, `names_line`: as for the IMU CSV (columns by 1-based index or by name);
//!   fields are separated by commas when a line holds one, otherwise by white space;
//! - position: `lat`, `lon` (degrees) and `h` (ellipsoidal height, m), or `ecef = [x, y, z]`
//!   (m, converted with [`nav_core::earth::ecef_to_geodetic`]);
//! - position sigmas: `sigma_ned = [n, e, d]` (m), or `sigma_h` (horizontal accuracy, taken as
//!   the north and the east sigma each) and `sigma_v` (vertical, the down sigma); without
//!   them `default_sigma_ned_m = [n, e, d]` must be stated and the reader warns once;
//! - velocity (optional): `vel_ned = [n, e, d]` (m/s), or `speed` (unit `speed_unit`: `m/s`,
//!   `km/h`, `knots`) with `course` (degrees clockwise from north) and optionally `climb`
//!   (vertical speed, up positive, m/s; absent: 0 with the default down sigma); velocity
//!   sigmas `vel_sigma_ned = [n, e, d]` or `speed_sigma` (all three axes), else
//!   `default_vel_sigma_ned_mps` (stated, warned once);
//! - fix quality (optional, [`QualityMap`]): a column holding a name (`RTK_FIXED`, `FLOAT`,
//!   `SINGLE`, `DGPS`, `PPP`, `NONE`, ...) or a number (`codes`: `rtklib` 1 fix .. 6 PPP,
//!   `nmea` GGA 0..8, `ublox` NAV-PVT fixType 0..5), with `accept` listing the values kept
//!   (default: all but no-fix);
//! - `num_sats` (optional);
//! - time ([`GnssCsvTime`]): GPS seconds of week, GPS week + seconds, Unix seconds or
//!   milliseconds, or date-time text parsed with a chrono format string (`%Y_%m_%d_%H_%M_%S_%3f`
//!   reads `2015_11_26_15_00_02_617`); Unix and text times are in the time scale `scale`
//!   (`utc`, the default, converted to GPS time with the leap-second table of
//!   [`super::gpstime`], or `gps`).
//!
//! Times are returned as GPS seconds of the week of the first kept fix (continuing past 604800
//! across a week rollover), with that week in [`GnssCsvRecord::week`] when the file gives it.

use super::gpstime::{gpst_minus_utc_s, SECONDS_PER_WEEK};
use super::imucsv::{read_header, resolve, Column};
use super::lines::{open_text, DataLine, MonotonicTime};
use super::IoError;
use nalgebra::Vector3;
use nav_core::earth::ecef_to_geodetic;
use nav_core::types::{FixQuality, GnssFix};
use std::path::{Path, PathBuf};

/// Time scale of absolute times (Unix, date-time text).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeScale {
    /// UTC (converted to GPS time with the leap seconds).
    #[default]
    Utc,
    /// GPS time (no leap seconds).
    Gps,
}

/// What the time column(s) hold.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum GnssCsvTime {
    /// GPS seconds of week in `columns.time` (no week known): `kind = "gps_sow"` (`"seconds"`,
    /// the IMU CSV's older name for it, is accepted as well).
    #[serde(alias = "seconds")]
    GpsSow,
    /// GPS week in `columns.week`, seconds of week in `columns.time`.
    WeekSow,
    /// Seconds since 1970-01-01 00:00:00 in `columns.time`.
    UnixS {
        /// Time scale of the count.
        #[serde(default)]
        scale: TimeScale,
    },
    /// Milliseconds since 1970-01-01 00:00:00 in `columns.time`.
    UnixMs {
        /// Time scale of the count.
        #[serde(default)]
        scale: TimeScale,
    },
    /// Date and time as text in `columns.time`, parsed with a chrono format string (the field
    /// must not contain the separator; e.g. `%Y-%m-%dT%H:%M:%S%.f`).
    Text {
        /// chrono `strftime` format.
        format: String,
        /// Time scale of the text.
        #[serde(default)]
        scale: TimeScale,
    },
}

/// Unit of a speed column.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum SpeedUnit {
    /// Metres per second.
    #[default]
    #[serde(rename = "m/s")]
    Mps,
    /// Kilometres per hour.
    #[serde(rename = "km/h")]
    Kmph,
    /// Knots (1852 m/h).
    #[serde(rename = "knots")]
    Knots,
}

impl SpeedUnit {
    /// Factor to m/s.
    pub fn to_mps(self) -> f64 {
        match self {
            SpeedUnit::Mps => 1.0,
            SpeedUnit::Kmph => 1.0 / 3.6,
            SpeedUnit::Knots => 1852.0 / 3600.0,
        }
    }
}

/// How numeric fix-quality codes are numbered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum QualityCodes {
    /// RTKLIB Q: 1 fixed, 2 float, 3 SBAS, 4 DGPS, 5 single, 6 PPP (0: none).
    #[default]
    Rtklib,
    /// NMEA GGA: 0 invalid, 1 GPS, 2 DGPS, 3 PPS, 4 RTK fixed, 5 RTK float, 6 estimated,
    /// 7 manual, 8 simulation (6-8 are not fixes).
    Nmea,
    /// u-blox NAV-PVT fixType: 0 none, 1 dead reckoning, 2 2D, 3 3D, 4 GNSS + DR, 5 time only
    /// (2-4 are fixes, of single-point quality).
    Ublox,
}

impl QualityCodes {
    /// The quality of code `c`.
    pub fn quality(self, c: i64) -> FixQuality {
        match self {
            QualityCodes::Rtklib => {
                u8::try_from(c).map_or(FixQuality::NoFix, FixQuality::from_rtklib_q)
            }
            QualityCodes::Nmea => match c {
                1 | 3 => FixQuality::Single,
                2 => FixQuality::Dgnss,
                4 => FixQuality::RtkFixed,
                5 => FixQuality::RtkFloat,
                _ => FixQuality::NoFix,
            },
            QualityCodes::Ublox => match c {
                2..=4 => FixQuality::Single,
                _ => FixQuality::NoFix,
            },
        }
    }
}

/// The fix quality of a name (case, `_`, `-` and blanks ignored), when it is a known one.
pub fn quality_from_name(s: &str) -> Option<FixQuality> {
    let k: String = s
        .chars()
        .filter(|c| !matches!(c, '_' | '-' | ' '))
        .map(|c| c.to_ascii_uppercase())
        .collect();
    Some(match k.as_str() {
        "RTKFIXED" | "FIXED" | "FIX" | "RTKFIX" => FixQuality::RtkFixed,
        "RTKFLOAT" | "FLOAT" => FixQuality::RtkFloat,
        "SBAS" | "WAAS" => FixQuality::Sbas,
        "DGPS" | "DGNSS" | "DIFFERENTIAL" => FixQuality::Dgnss,
        "SINGLE" | "SPP" | "3D" | "2D" | "GPS" | "GNSS" | "AUTONOMOUS" | "STANDALONE" => {
            FixQuality::Single
        }
        "PPP" => FixQuality::Ppp,
        "NOFIX" | "NONE" | "INVALID" | "NO" => FixQuality::NoFix,
        _ => return None,
    })
}

/// The fix-quality column and filter.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct QualityMap {
    /// Column holding a quality name or code.
    pub column: Column,
    /// Values kept (names or codes as written in the file, compared case-insensitively);
    /// empty: every record that is a fix. A name listed here but unknown to the reader is
    /// kept as single-point quality.
    #[serde(default)]
    pub accept: Vec<String>,
    /// Numbering of numeric codes.
    #[serde(default)]
    pub codes: QualityCodes,
}

/// Column assignment of a GNSS CSV log (see the module notes).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GnssCsvColumns {
    /// Time column (seconds of week, Unix seconds/ms or date-time text).
    pub time: Option<Column>,
    /// GPS week column (`time.kind = "week_sow"`).
    #[serde(default)]
    pub week: Option<Column>,
    /// Latitude, deg.
    #[serde(default)]
    pub lat: Option<Column>,
    /// Longitude, deg.
    #[serde(default)]
    pub lon: Option<Column>,
    /// Ellipsoidal height, m.
    #[serde(default)]
    pub h: Option<Column>,
    /// ECEF x, y, z, m (instead of lat/lon/h).
    #[serde(default)]
    pub ecef: Option<[Column; 3]>,
    /// Position sigmas north, east, down, m.
    #[serde(default)]
    pub sigma_ned: Option<[Column; 3]>,
    /// Horizontal accuracy, m (north and east sigma).
    #[serde(default)]
    pub sigma_h: Option<Column>,
    /// Vertical accuracy, m (down sigma).
    #[serde(default)]
    pub sigma_v: Option<Column>,
    /// NED velocity, m/s.
    #[serde(default)]
    pub vel_ned: Option<[Column; 3]>,
    /// Horizontal speed (unit `speed_unit`).
    #[serde(default)]
    pub speed: Option<Column>,
    /// Course over ground, deg clockwise from north.
    #[serde(default)]
    pub course: Option<Column>,
    /// Vertical speed, up positive, m/s.
    #[serde(default)]
    pub climb: Option<Column>,
    /// Velocity sigmas north, east, down, m/s.
    #[serde(default)]
    pub vel_sigma_ned: Option<[Column; 3]>,
    /// Speed accuracy, m/s (all three velocity axes).
    #[serde(default)]
    pub speed_sigma: Option<Column>,
    /// Number of satellites used.
    #[serde(default)]
    pub num_sats: Option<Column>,
}

/// How to read a GNSS CSV/text log (see the module notes).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GnssCsvFormat {
    /// Physical lines skipped at the start.
    #[serde(default)]
    pub skip_lines: usize,
    /// 1-based line holding the column names (default: the last skipped line).
    #[serde(default)]
    pub names_line: Option<usize>,
    /// Column assignment.
    pub columns: GnssCsvColumns,
    /// What the time column holds.
    pub time: GnssCsvTime,
    /// Unit of the `speed` column.
    #[serde(default)]
    pub speed_unit: SpeedUnit,
    /// Fix-quality column and filter.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quality: Option<QualityMap>,
    /// Position sigmas north, east, down (m) for a file without sigma columns.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub default_sigma_ned_m: Option<[f64; 3]>,
    /// Velocity sigmas north, east, down (m/s) for a file with velocity but no velocity sigma
    /// columns.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub default_vel_sigma_ned_mps: Option<[f64; 3]>,
}

/// Fixes of a GNSS CSV log.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GnssCsvRecord {
    /// Fixes kept, time order, GPS seconds of [`Self::week`] (see the module notes).
    pub fixes: Vec<GnssFix>,
    /// 1-based file line of each fix.
    pub lines: Vec<usize>,
    /// GPS week of the first kept fix when the time format gives it.
    pub week: Option<i64>,
    /// Records dropped by the quality filter.
    pub dropped_by_quality: usize,
    /// Things the user should know (each said once): default sigmas used, ...
    pub warnings: Vec<String>,
    /// The file read.
    pub path: PathBuf,
}

fn cfg_err(path: &Path, message: impl Into<String>) -> IoError {
    IoError::Config {
        path: path.to_path_buf(),
        message: message.into(),
        source: None,
    }
}

/// Resolved 0-based column indices.
struct Cols {
    time: usize,
    week: Option<usize>,
    pos: PosCols,
    sig: SigCols,
    vel: VelCols,
    vel_sig: VelSigCols,
    quality: Option<usize>,
    num_sats: Option<usize>,
}

enum PosCols {
    Llh([usize; 3]),
    Ecef([usize; 3]),
}

enum SigCols {
    Ned([usize; 3]),
    Hv(Option<usize>, Option<usize>),
    Default([f64; 3]),
}

enum VelCols {
    None,
    Ned([usize; 3]),
    SpeedCourse(usize, usize, Option<usize>),
}

enum VelSigCols {
    Ned([usize; 3]),
    Speed(usize),
    Default([f64; 3]),
}

fn sig_ok(v: &[f64; 3]) -> bool {
    v.iter().all(|s| s.is_finite() && *s > 0.0)
}

/// Column indices of a GNSS CSV mapping's entries, by header name or number, for the
/// messages of `path`.
struct ColResolver<'a> {
    path: &'a Path,
    nm: Option<&'a [String]>,
}

impl ColResolver<'_> {
    /// The index of column `col` (`what` in messages).
    fn one(&self, col: &Column, what: &str) -> Result<usize, IoError> {
        resolve(self.path, col, self.nm, what)
    }

    /// The index of an optional column.
    fn opt(&self, col: &Option<Column>, what: &str) -> Result<Option<usize>, IoError> {
        col.as_ref().map(|x| self.one(x, what)).transpose()
    }

    /// The indices of three columns (north, east, down or x, y, z).
    fn three(&self, cols: &[Column; 3], what: [&str; 3]) -> Result<[usize; 3], IoError> {
        Ok([
            self.one(&cols[0], what[0])?,
            self.one(&cols[1], what[1])?,
            self.one(&cols[2], what[2])?,
        ])
    }
}

fn resolve_cols(path: &Path, fmt: &GnssCsvFormat, nm: Option<&[String]>) -> Result<Cols, IoError> {
    let c = &fmt.columns;
    let cr = ColResolver { path, nm };
    let r = |col: &Column, what: &str| cr.one(col, what);
    let opt = |col: &Option<Column>, what: &str| cr.opt(col, what);
    let r3 = |cols: &[Column; 3], what: [&str; 3]| cr.three(cols, what);
    let time = r(
        c.time
            .as_ref()
            .ok_or_else(|| cfg_err(path, "gnss.csv.columns.time is required"))?,
        "time",
    )?;
    let week = opt(&c.week, "week")?;
    if matches!(fmt.time, GnssCsvTime::WeekSow) != week.is_some() {
        return Err(cfg_err(
            path,
            "gnss.csv: time.kind = \"week_sow\" and a columns.week go together",
        ));
    }
    let pos = match (&c.ecef, &c.lat, &c.lon, &c.h) {
        (Some(e), None, None, None) => PosCols::Ecef(r3(e, ["ecef_x", "ecef_y", "ecef_z"])?),
        (None, Some(a), Some(b), Some(h)) => PosCols::Llh([r(a, "lat")?, r(b, "lon")?, r(h, "h")?]),
        _ => {
            return Err(cfg_err(
                path,
                "gnss.csv.columns: give either lat, lon and h, or ecef = [x, y, z]",
            ))
        }
    };
    let sig = sigma_cols(&cr, fmt)?;
    let vel = match (&c.vel_ned, &c.speed, &c.course) {
        (None, None, None) => VelCols::None,
        (Some(v), None, None) => VelCols::Ned(r3(v, ["vel_n", "vel_e", "vel_d"])?),
        (None, Some(s), Some(k)) => {
            VelCols::SpeedCourse(r(s, "speed")?, r(k, "course")?, opt(&c.climb, "climb")?)
        }
        _ => {
            return Err(cfg_err(
                path,
                "gnss.csv.columns: give vel_ned = [n, e, d], or speed and course (and optionally climb)",
            ))
        }
    };
    if c.climb.is_some() && !matches!(vel, VelCols::SpeedCourse(..)) {
        return Err(cfg_err(
            path,
            "gnss.csv.columns.climb goes with speed and course",
        ));
    }
    let vel_sig = velocity_sigma_cols(&cr, fmt, &vel)?;
    Ok(Cols {
        time,
        week,
        pos,
        sig,
        vel,
        vel_sig,
        quality: fmt
            .quality
            .as_ref()
            .map(|q| r(&q.column, "quality"))
            .transpose()?,
        num_sats: opt(&c.num_sats, "num_sats")?,
    })
}

/// The position sigma columns of a GNSS CSV mapping (`sigma_ned`, or `sigma_h`/`sigma_v`
/// with `default_sigma_ned_m` for a missing one, or `default_sigma_ned_m` alone), checked.
fn sigma_cols(cr: &ColResolver<'_>, fmt: &GnssCsvFormat) -> Result<SigCols, IoError> {
    let path = cr.path;
    let opt = |col: &Option<Column>, what: &str| cr.opt(col, what);
    let r3 = |cols: &[Column; 3], what: [&str; 3]| cr.three(cols, what);
    let c = &fmt.columns;
    let sig = match (&c.sigma_ned, &c.sigma_h, &c.sigma_v) {
        (Some(s), None, None) => SigCols::Ned(r3(s, ["sigma_n", "sigma_e", "sigma_d"])?),
        (None, h, v) if h.is_some() || v.is_some() => {
            if (h.is_none() || v.is_none()) && fmt.default_sigma_ned_m.is_none() {
                return Err(cfg_err(
                    path,
                    "gnss.csv: with only one of sigma_h and sigma_v, state default_sigma_ned_m = [n, e, d] (m) for the other",
                ));
            }
            SigCols::Hv(opt(h, "sigma_h")?, opt(v, "sigma_v")?)
        }
        (None, None, None) => match fmt.default_sigma_ned_m {
            Some(d) if sig_ok(&d) => SigCols::Default(d),
            Some(d) => {
                return Err(cfg_err(
                    path,
                    format!("gnss.csv.default_sigma_ned_m must be finite and > 0, got {d:?}"),
                ))
            }
            None => {
                return Err(cfg_err(
                    path,
                    "gnss.csv: the mapping has no sigma columns (sigma_ned, or sigma_h/sigma_v): state default_sigma_ned_m = [n, e, d] in metres (for example [0.05, 0.05, 0.1] for RTK fixes, [2, 2, 4] for a phone receiver)",
                ))
            }
        },
        _ => {
            return Err(cfg_err(
                path,
                "gnss.csv.columns: give sigma_ned or sigma_h/sigma_v, not both",
            ))
        }
    };
    if let Some(d) = fmt.default_sigma_ned_m {
        if !sig_ok(&d) {
            return Err(cfg_err(
                path,
                format!("gnss.csv.default_sigma_ned_m must be finite and > 0, got {d:?}"),
            ));
        }
    }
    Ok(sig)
}

/// The velocity sigma columns of a GNSS CSV mapping (`vel_sigma_ned` or `speed_sigma`, or
/// `default_vel_sigma_ned_mps` when the mapping has velocity columns `vel`), checked.
fn velocity_sigma_cols(
    cr: &ColResolver<'_>,
    fmt: &GnssCsvFormat,
    vel: &VelCols,
) -> Result<VelSigCols, IoError> {
    let path = cr.path;
    let r = |col: &Column, what: &str| cr.one(col, what);
    let r3 = |cols: &[Column; 3], what: [&str; 3]| cr.three(cols, what);
    let c = &fmt.columns;
    Ok(match (&c.vel_sigma_ned, &c.speed_sigma) {
        (Some(s), None) => VelSigCols::Ned(r3(s, ["vel_sigma_n", "vel_sigma_e", "vel_sigma_d"])?),
        (None, Some(s)) => VelSigCols::Speed(r(s, "speed_sigma")?),
        (Some(_), Some(_)) => {
            return Err(cfg_err(
                path,
                "gnss.csv.columns: give vel_sigma_ned or speed_sigma, not both",
            ))
        }
        (None, None) => match (fmt.default_vel_sigma_ned_mps, vel) {
            (_, VelCols::None) => VelSigCols::Default([1.0; 3]),
            (Some(d), _) if sig_ok(&d) => VelSigCols::Default(d),
            (Some(d), _) => {
                return Err(cfg_err(
                    path,
                    format!("gnss.csv.default_vel_sigma_ned_mps must be finite and > 0, got {d:?}"),
                ))
            }
            (None, _) => {
                return Err(cfg_err(
                    path,
                    "gnss.csv: velocity columns without velocity sigma columns: state default_vel_sigma_ned_mps = [n, e, d] in m/s (for example [0.2, 0.2, 0.4])",
                ))
            }
        },
    })
}

/// The GPS week in field `wi` and the seconds of week in field `ti` of `dl` (the IMU and
/// GNSS CSV's `kind = "week_sow"`), each checked for its range.
pub(crate) fn week_and_sow(dl: &DataLine<'_>, wi: usize, ti: usize) -> Result<(i64, f64), IoError> {
    let w = dl.integer(wi, "week", 0, 100_000)?;
    let v = dl.num(ti, "time [GPS s of week]")?;
    if !(0.0..SECONDS_PER_WEEK + 1.0).contains(&v) {
        return Err(dl.invalid(
            ti,
            "time [GPS s of week]",
            "seconds of week outside 0..604800",
        ));
    }
    Ok((w, v))
}

/// GPS (week, seconds of week) of `secs` whole + `frac` seconds since 1970 in `scale`.
pub(crate) fn week_sow_of_epoch(secs: i64, frac: f64, scale: TimeScale) -> Option<(i64, f64)> {
    let leap = match scale {
        TimeScale::Gps => 0,
        TimeScale::Utc => {
            let d = chrono::DateTime::from_timestamp(secs, 0)?.date_naive();
            use chrono::Datelike;
            i64::from(gpst_minus_utc_s(i64::from(d.year()), d.month(), d.day()))
        }
    };
    // 1980-01-06 is 3657 days after 1970-01-01
    let from_gps = secs + leap - 3657 * 86_400;
    let week = from_gps.div_euclid(604_800);
    Some((week, from_gps.rem_euclid(604_800) as f64 + frac))
}

/// Splits a non-negative second count into whole seconds and fraction.
fn split_secs(v: f64) -> (i64, f64) {
    let w = v.floor();
    (w as i64, v - w)
}

fn parse_time(
    dl: &DataLine<'_>,
    fmt: &GnssCsvFormat,
    cols: &Cols,
) -> Result<(Option<i64>, f64), IoError> {
    let ti = cols.time;
    let out_of_range = |dl: &DataLine<'_>| dl.invalid(ti, "time", "time outside 1970..2200");
    match &fmt.time {
        GnssCsvTime::GpsSow => {
            let v = dl.num(ti, "time [GPS s of week]")?;
            if !(0.0..SECONDS_PER_WEEK + 1.0).contains(&v) {
                return Err(dl.invalid(
                    ti,
                    "time [GPS s of week]",
                    "seconds of week outside 0..604800",
                ));
            }
            Ok((None, v))
        }
        GnssCsvTime::WeekSow => {
            let (w, v) = week_and_sow(dl, cols.week.unwrap_or(0), ti)?;
            Ok((Some(w), v))
        }
        GnssCsvTime::UnixS { scale } | GnssCsvTime::UnixMs { scale } => {
            let ms = matches!(fmt.time, GnssCsvTime::UnixMs { .. });
            let name = if ms {
                "time [Unix ms]"
            } else {
                "time [Unix s]"
            };
            let v = dl.num(ti, name)?;
            let s = if ms { v * 1e-3 } else { v };
            if !(0.0..7.3e9).contains(&s) {
                return Err(out_of_range(dl));
            }
            let (whole, frac) = if ms {
                // keep the millisecond digits exact
                let w = (v / 1000.0).floor();
                (w as i64, (v - w * 1000.0) * 1e-3)
            } else {
                split_secs(s)
            };
            let (w, sow) =
                week_sow_of_epoch(whole, frac, *scale).ok_or_else(|| out_of_range(dl))?;
            Ok((Some(w), sow))
        }
        GnssCsvTime::Text { format, scale } => {
            let text = dl.fields.get(ti).copied().unwrap_or("");
            let t = chrono::NaiveDateTime::parse_from_str(text, format).map_err(|e| {
                dl.invalid(
                    ti,
                    "time [text]",
                    format!("does not match the format {format:?}: {e}"),
                )
            })?;
            let u = t.and_utc();
            let frac = f64::from(u.timestamp_subsec_nanos()) * 1e-9;
            let (w, sow) =
                week_sow_of_epoch(u.timestamp(), frac, *scale).ok_or_else(|| out_of_range(dl))?;
            Ok((Some(w), sow))
        }
    }
}

/// Reads a GNSS CSV/text log with the mapping `fmt` (see the module notes;
/// [`GnssCsvReader`] collected).
pub fn read_gnss_csv(
    path: impl AsRef<Path>,
    fmt: &GnssCsvFormat,
) -> Result<GnssCsvRecord, IoError> {
    let mut rd = GnssCsvReader::open(path, fmt)?;
    let mut out = GnssCsvRecord::default();
    for r in &mut rd {
        let (fix, line) = r?;
        out.fixes.push(fix);
        out.lines.push(line);
    }
    out.week = rd.week();
    out.dropped_by_quality = rd.dropped_by_quality();
    out.warnings = rd.warnings().to_vec();
    out.path = rd.path;
    Ok(out)
}

/// A GNSS CSV/text log read one record at a time with the mapping `fmt`: the one parser of
/// the format ([`read_gnss_csv`] collects it). Yields the kept fixes with their 1-based file
/// line; the week ([`Self::week`]) is the first kept fix's, known once it is read; the
/// warnings about the mapping are known at opening. A file without a kept fix ends with an
/// error. Errors name file, line and column; after an error the reader ends. Nothing is kept
/// but the current line and the resolved mapping: constant memory.
pub struct GnssCsvReader {
    rd: super::lines::LineReader,
    path: PathBuf,
    fmt: GnssCsvFormat,
    cols: Cols,
    /// `quality.accept`, trimmed and upper case.
    accept: Vec<String>,
    codes: QualityCodes,
    /// Speed unit to m/s.
    kv: f64,
    mono: MonotonicTime,
    week0: Option<i64>,
    kept: usize,
    dropped_by_quality: usize,
    warnings: Vec<String>,
    done: bool,
}

impl GnssCsvReader {
    /// Opens `path` and reads its header lines; mapping errors (columns, sigmas, names not in
    /// the header) come here.
    pub fn open(path: impl AsRef<Path>, fmt: &GnssCsvFormat) -> Result<Self, IoError> {
        let path = path.as_ref();
        if let GnssCsvTime::Text { format, .. } = &fmt.time {
            if format.trim().is_empty() {
                return Err(cfg_err(path, "gnss.csv.time.format is empty"));
            }
        }
        let mut rd = open_text(path)?;
        let names = read_header(&mut rd, path, fmt.skip_lines, fmt.names_line)?;
        let cols = resolve_cols(path, fmt, names.as_deref())?;
        let accept: Vec<String> = fmt
            .quality
            .as_ref()
            .map(|q| {
                q.accept
                    .iter()
                    .map(|s| s.trim().to_ascii_uppercase())
                    .collect()
            })
            .unwrap_or_default();
        let codes = fmt.quality.as_ref().map(|q| q.codes).unwrap_or_default();
        let mut warnings = Vec::new();
        if let SigCols::Default(d) = cols.sig {
            warnings.push(format!(
                "{}: no position accuracy in the file: every fix gets the configured default_sigma_ned_m = {d:?} m",
                path.display()
            ));
        }
        if let (VelSigCols::Default(d), false) = (&cols.vel_sig, matches!(cols.vel, VelCols::None))
        {
            warnings.push(format!(
                "{}: no velocity accuracy in the file: every velocity gets the configured default_vel_sigma_ned_mps = {d:?} m/s",
                path.display()
            ));
        }
        if matches!(cols.vel, VelCols::SpeedCourse(_, _, None)) {
            warnings.push(format!(
                "{}: no vertical speed column: the down velocity is taken as 0 with sigma {} m/s",
                path.display(),
                match cols.vel_sig {
                    VelSigCols::Default(d) => d[2],
                    _ => f64::NAN,
                }
            ));
        }
        Ok(Self {
            rd,
            path: path.to_path_buf(),
            fmt: fmt.clone(),
            cols,
            accept,
            codes,
            kv: fmt.speed_unit.to_mps(),
            mono: MonotonicTime::new(),
            week0: None,
            kept: 0,
            dropped_by_quality: 0,
            warnings,
            done: false,
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// GPS week of the first kept fix when the time format gives it (None before it is
    /// read).
    pub fn week(&self) -> Option<i64> {
        if matches!(self.fmt.time, GnssCsvTime::GpsSow) {
            None
        } else {
            self.week0
        }
    }

    /// Records dropped so far by the quality filter.
    pub fn dropped_by_quality(&self) -> usize {
        self.dropped_by_quality
    }

    /// Things the user should know (each said once): default sigmas used, ...
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The next kept fix and its line; `None` at the end of the file.
    fn read(&mut self) -> Result<Option<(GnssFix, usize)>, IoError> {
        let Self {
            rd,
            fmt,
            cols,
            accept,
            codes,
            kv,
            mono,
            week0,
            dropped_by_quality,
            ..
        } = self;
        let (fmt, cols, accept, codes, kv) = (&*fmt, &*cols, &*accept, *codes, *kv);
        while let Some(dl) = rd.next_data()? {
            // quality first: records that are not kept need not hold a valid position
            let mut quality = FixQuality::Single;
            if let Some(qi) = cols.quality {
                let text = *dl
                    .fields
                    .get(qi)
                    .ok_or_else(|| dl.invalid(qi, "quality", "missing"))?;
                let up = text.trim().to_ascii_uppercase();
                let listed = accept.contains(&up);
                let q = match up.parse::<i64>() {
                    Ok(c) => Some(codes.quality(c)),
                    Err(_) => quality_from_name(&up),
                };
                quality = match q {
                    Some(q) => q,
                    None if listed => FixQuality::Single,
                    None => {
                        return Err(dl.invalid(
                            qi,
                            "quality",
                            "unknown fix quality name: list it in gnss.csv.quality.accept to keep such records",
                        ))
                    }
                };
                let keep = if accept.is_empty() {
                    quality != FixQuality::NoFix
                } else {
                    listed
                };
                if !keep {
                    *dropped_by_quality += 1;
                    continue;
                }
                if quality == FixQuality::NoFix {
                    // accepted explicitly: the user says it is a usable position
                    quality = FixQuality::Single;
                }
            }
            let (week, sow) = parse_time(&dl, fmt, cols)?;
            let w0 = *week0.get_or_insert(week.unwrap_or(0));
            let t_s = sow + (week.unwrap_or(0) - w0) as f64 * SECONDS_PER_WEEK;
            mono.check(&dl, cols.time, "time", t_s)?;
            let mut fix = GnssFix {
                t_s,
                quality,
                ..GnssFix::default()
            };
            fill_position(&dl, cols, fmt, &mut fix)?;
            fill_velocity(&dl, cols, kv, &mut fix)?;
            if let Some(i) = cols.num_sats {
                fix.num_sats = u8::try_from(dl.integer(i, "num_sats", 0, 255)?).unwrap_or(u8::MAX);
            }
            return Ok(Some((fix, dl.line)));
        }
        Ok(None)
    }
}

/// A standard deviation at field `i` (named `n` in messages): a number > 0.
fn positive_sigma(dl: &DataLine<'_>, i: usize, n: &str) -> Result<f64, IoError> {
    let v = dl.sigma(i, n)?;
    if v <= 0.0 {
        return Err(dl.invalid(i, n, "a standard deviation must be > 0"));
    }
    Ok(v)
}

/// The position of a record (latitude/longitude/height or ECEF) and its standard deviations
/// (NED, horizontal/vertical or the mapping's default) into `fix`.
fn fill_position(
    dl: &DataLine<'_>,
    cols: &Cols,
    fmt: &GnssCsvFormat,
    fix: &mut GnssFix,
) -> Result<(), IoError> {
    match cols.pos {
        PosCols::Llh([a, b, h]) => {
            fix.lat_rad = dl.lat_deg(a, "lat [deg]")?.to_radians();
            fix.lon_rad = dl.lon_deg(b, "lon [deg]")?.to_radians();
            fix.h_m = dl.num(h, "h [m]")?;
            if !(-1.0e4..1.0e7).contains(&fix.h_m) {
                return Err(dl.invalid(h, "h [m]", "height outside -10 km .. 10000 km"));
            }
        }
        PosCols::Ecef([x, y, z]) => {
            let r = Vector3::new(
                dl.num(x, "ecef_x [m]")?,
                dl.num(y, "ecef_y [m]")?,
                dl.num(z, "ecef_z [m]")?,
            );
            if !(1.0e6..1.0e8).contains(&r.norm()) {
                return Err(dl.invalid(
                    x,
                    "ecef_x [m]",
                    "ECEF position not between 1000 km and 100000 km from the earth's centre",
                ));
            }
            let llh = ecef_to_geodetic(&r);
            fix.lat_rad = llh.lat_rad;
            fix.lon_rad = llh.lon_rad;
            fix.h_m = llh.h_m;
        }
    }
    fix.pos_std_ned_m = match cols.sig {
        SigCols::Ned([a, b, c]) => [
            positive_sigma(dl, a, "sigma_n [m]")?,
            positive_sigma(dl, b, "sigma_e [m]")?,
            positive_sigma(dl, c, "sigma_d [m]")?,
        ],
        SigCols::Hv(h, v) => {
            let d = fmt.default_sigma_ned_m.unwrap_or([f64::NAN; 3]);
            let sh = match h {
                Some(i) => positive_sigma(dl, i, "sigma_h [m]")?,
                None => d[0],
            };
            let sv = match v {
                Some(i) => positive_sigma(dl, i, "sigma_v [m]")?,
                None => d[2],
            };
            [sh, sh, sv]
        }
        SigCols::Default(d) => d,
    };
    Ok(())
}

/// The velocity of a record (NED, or speed, course and climb with the speed unit `kv` to
/// m/s) and its standard deviations into `fix`; nothing when the mapping has no velocity.
fn fill_velocity(
    dl: &DataLine<'_>,
    cols: &Cols,
    kv: f64,
    fix: &mut GnssFix,
) -> Result<(), IoError> {
    match cols.vel {
        VelCols::None => {}
        VelCols::Ned([a, b, c]) => {
            fix.vel_ned_mps = [
                dl.num(a, "vel_n [m/s]")?,
                dl.num(b, "vel_e [m/s]")?,
                dl.num(c, "vel_d [m/s]")?,
            ];
            fix.has_velocity = true;
        }
        VelCols::SpeedCourse(s, k, climb) => {
            let sp = dl.num(s, "speed")? * kv;
            if sp < 0.0 {
                return Err(dl.invalid(s, "speed", "a speed cannot be negative"));
            }
            let co = dl.num(k, "course [deg]")?;
            if co.abs() > 720.0 {
                return Err(dl.invalid(k, "course [deg]", "course outside -720..720 deg"));
            }
            let up = match climb {
                Some(i) => dl.num(i, "climb [m/s]")?,
                None => 0.0,
            };
            let c = co.to_radians();
            fix.vel_ned_mps = [sp * c.cos(), sp * c.sin(), -up];
            fix.has_velocity = true;
        }
    }
    if fix.has_velocity {
        fix.vel_std_ned_mps = match cols.vel_sig {
            VelSigCols::Ned([a, b, c]) => [
                positive_sigma(dl, a, "vel_sigma_n [m/s]")?,
                positive_sigma(dl, b, "vel_sigma_e [m/s]")?,
                positive_sigma(dl, c, "vel_sigma_d [m/s]")?,
            ],
            VelSigCols::Speed(i) => [positive_sigma(dl, i, "speed_sigma [m/s]")?; 3],
            VelSigCols::Default(d) => d,
        };
    }
    Ok(())
}

impl Iterator for GnssCsvReader {
    type Item = Result<(GnssFix, usize), IoError>;

    /// The next kept fix and its 1-based line; at the end of a file without a kept fix, an
    /// error; after an error, `None`.
    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let r = match self.read() {
            Ok(Some(x)) => {
                self.kept += 1;
                return Some(Ok(x));
            }
            // a last line cut short (a log still being written): the file ends before it
            Err(e) if self.kept > 0 && super::lines::cut_short(&self.rd, &e) => None,
            Ok(None) if self.kept > 0 => None,
            Ok(None) => Some(Err(IoError::Format {
                path: self.path.clone(),
                line: 0,
                message: format!(
                    "no GNSS fixes kept ({} dropped by the quality filter)",
                    self.dropped_by_quality
                ),
            })),
            Err(e) => Some(Err(e)),
        };
        self.done = true;
        r
    }
}
