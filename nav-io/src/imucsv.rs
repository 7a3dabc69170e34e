//! Generic IMU CSV logs (rates and specific forces, or increments) with a column/unit mapping,
//! and their conversion to the increments the navigation core integrates.
//!
//! # Mapping ([`ImuCsvFormat`], serde/TOML)
//! - `skip_lines`: physical lines skipped at the start (headers, or data rows to drop);
//!   afterwards blank and `#`/`%` lines are skipped as everywhere; `skip_last_rows`: data rows
//!   dropped at the end;
//! - columns by 1-based index or by name (`names_line`, default the last skipped line: the
//!   names are its comma- or space-separated fields, leading `#`/`%` removed, each reduced to
//!   its first word, matched case-insensitively);
//! - gyro unit `deg/s` or `rad/s`; accelerometer unit `g` (9.80665 m/s^2) or `m/s^2`;
//! - time ([`CsvTime`]): a column of GPS seconds of week (`kind = "gps_sow"`, as for the GNSS
//!   CSV; `"seconds"` also accepted), a GPS week column with one of seconds of week
//!   (`week_sow`, as for the GNSS CSV), Unix seconds or milliseconds (`unix_s`, `unix_ms`, in
//!   the time scale `scale`, UTC by default, as for the GNSS CSV), date-time text (`text`,
//!   with a chrono `format` and a `scale`, as for the GNSS CSV), a tick column in ms
//!   (optionally placed in GPS time with an RTKLIB time-tag file, see below), or a fixed rate
//!   without a time column (row k at `start_s + k / rate_hz`);
//! - `time_offset_s` added to every time stamp last (e.g. a logging delay correction).
//!
//! # Time tags
//! With `ticks_ms` and a tag file, the first USED row is placed at the tag's start time and
//! the last used row at the tag's last tick (start + last tag tick), the rows in between
//! linearly in tick: `t = start + (tick - tick_first) * (tag_last_ms / (tick_last - tick_first))
//! / 1000`. This is what rtklibexplorer's `convert_imu_file.py` does (it also drops the first
//! and last rows: `skip_lines = 1`, `skip_last_rows = 1` reproduce its time stamps exactly).
//! It assumes the first sample arrived when the log file was opened and the last one at the
//! last tag; the stretch factor must be within 1 % of 1 or the tag file is rejected as not
//! belonging to the log.
//!
//! That assumption can be wrong, and was on the one real log we have (rtklibexplorer
//! drive_0708): the tag start is when the logger OPENED the file, and the first row reached it
//! 131 ms later, while every row arrives 130-149 ms after its tick all along (the tag's
//! pairs against the rows' ticks: 12.6 ppm between the two clocks). The stretch (x1.00029)
//! then adds a clock ramp of 0 -> +0.160 s over the 9 minutes that the GNSS confirms (the
//! best IMU time correction goes -0.106 -> -0.300 s with it, -0.095 -> -0.141 s without it).
//! `stretch_to_tag_end = false` places the first used row at the tag start and takes the ticks
//! at face value; the constant offset that remains (the logging delay) is for
//! `time_offset_s` or `host-sim diagnose` to find. See docs/diagnose.md ("The drive0708
//! clock").
//!
//! # Sample convention ([`SampleConvention`])
//! - `trapezoid` (default): each row is the instantaneous rate / specific force AT its time
//!   stamp. The increment over (t_{k-1}, t_k] is `(y_{k-1} + y_k) / 2 * (t_k - t_{k-1})`: exact
//!   for signals linear over the interval, error `dt^3 / 12 * y''` per step (second order).
//! - `interval_mean`: each row is the MEAN rate over the interval ending at its time stamp
//!   (sensors with integrating/decimating filters); the increment is `y_k * (t_k - t_{k-1})`,
//!   exact for such data.
//!
//! - `increments`: each row holds the angle and velocity increments over the interval ending
//!   at its time stamp (devices that output `dtheta`/`dv`); the increment is the row as it is
//!   (in the units' angle and velocity: rad or deg, m/s or g s). The rows are then increments,
//!   not rates, in [`RawImuSample`] too.
//!
//! Every way the first row only opens the first interval and yields no increment, so `n`
//! rows give `n - 1` increments stamped at the rows' times 2..n. Across a time gap the
//! increment spans the whole gap (nothing is invented); gaps are reported in the record.
//! The temperature of an increment is that of its end row.

use super::gnsscsv::{week_and_sow, week_sow_of_epoch, TimeScale};
use super::gpstime::SECONDS_PER_WEEK;
use super::lines::{open_text, split_fields, DataLine, LineReader, MonotonicTime};
use super::tag::{read_time_tag, TimeTag};
use super::text::{ImuRecord, TimeGapReport};
use super::IoError;
use nav_core::types::ImuSample;
use std::path::{Path, PathBuf};

/// Standard gravity used to convert g to m/s^2.
pub const G0_MPS2: f64 = 9.806_65;

/// A column, by 1-based index or by name.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(untagged)]
pub enum Column {
    /// 1-based field index.
    Index(usize),
    /// Name in the names line.
    Name(String),
}

/// Unit of the gyro columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum RateUnit {
    /// Degrees per second.
    #[serde(rename = "deg/s")]
    DegPerS,
    /// Radians per second.
    #[serde(rename = "rad/s")]
    RadPerS,
}

impl RateUnit {
    /// Factor to rad/s.
    pub fn to_radps(self) -> f64 {
        match self {
            RateUnit::DegPerS => std::f64::consts::PI / 180.0,
            RateUnit::RadPerS => 1.0,
        }
    }
}

/// Unit of the accelerometer columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum AccelUnit {
    /// Standard gravities (9.80665 m/s^2).
    #[serde(rename = "g")]
    G,
    /// Metres per second squared.
    #[serde(rename = "m/s^2")]
    Mps2,
}

impl AccelUnit {
    /// Factor to m/s^2.
    pub fn to_mps2(self) -> f64 {
        match self {
            AccelUnit::G => G0_MPS2,
            AccelUnit::Mps2 => 1.0,
        }
    }
}

/// Where time stamps come from.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum CsvTime {
    /// The time column holds GPS seconds of week: `kind = "gps_sow"`, the name the GNSS CSV
    /// uses for the same thing (`"seconds"` is accepted as well).
    #[serde(rename = "gps_sow", alias = "seconds")]
    Seconds,
    /// A GPS week in `columns.week` and its seconds of week in `columns.time`, as for the GNSS
    /// CSV: the time stamps are seconds of the first row's week (continuing past 604,800 s
    /// into the next week).
    WeekSow,
    /// The time column holds ticks in milliseconds. Without a tag file t = tick / 1000 s.
    TicksMs {
        /// RTKLIB time-tag file placing the ticks in GPS time (relative paths: relative to the
        /// CSV file's folder).
        #[serde(default)]
        tag_file: Option<PathBuf>,
        /// Stretch the tick span to the tag span (see the module notes: check it on your log
        /// before trusting it); default true, as the source's converter does.
        #[serde(default = "yes")]
        stretch_to_tag_end: bool,
    },
    /// Seconds since 1970-01-01 00:00:00 in `columns.time` (as for the GNSS CSV), placed in
    /// GPS seconds of the first row's week (continuing past 604800 across a rollover).
    UnixS {
        /// Time scale of the count (`utc`, the default, or `gps`).
        #[serde(default)]
        scale: TimeScale,
    },
    /// Milliseconds since 1970-01-01 00:00:00 in `columns.time`, as `unix_s`.
    UnixMs {
        /// Time scale of the count (`utc`, the default, or `gps`).
        #[serde(default)]
        scale: TimeScale,
    },
    /// Date and time as text in `columns.time`, parsed with a chrono format string (as for the
    /// GNSS CSV; the field must not contain the separator, e.g. `%Y-%m-%dT%H:%M:%S%.f`), placed
    /// in GPS seconds of the first row's week as `unix_s` is.
    Text {
        /// chrono `strftime` format.
        format: String,
        /// Time scale of the text (`utc`, the default, or `gps`).
        #[serde(default)]
        scale: TimeScale,
    },
    /// No time column: row k (0-based, after skipping) is at `start_s + k / rate_hz`.
    FixedRate {
        /// Sample rate, Hz.
        rate_hz: f64,
        /// Time of the first row, s.
        #[serde(default)]
        start_s: f64,
    },
}

fn yes() -> bool {
    true
}

/// The sample convention for converting rates to increments (see the module notes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SampleConvention {
    /// Rows are instantaneous values at their time stamps; trapezoidal integration.
    #[default]
    Trapezoid,
    /// Rows are means over the interval ending at their time stamps.
    IntervalMean,
    /// Rows are the increments over the interval ending at their time stamps: the gyro
    /// columns angle increments (rad with `gyro_unit = "rad/s"`, deg with `"deg/s"`), the
    /// accelerometer columns velocity increments (m/s with `accel_unit = "m/s^2"`, g s with
    /// `"g"`).
    Increments,
}

/// Column assignment.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImuCsvColumns {
    /// Time column (required unless time is `fixed_rate`).
    #[serde(default)]
    pub time: Option<Column>,
    /// Gyro x, y, z columns (sensor axes).
    pub gyro: [Column; 3],
    /// Accelerometer x, y, z columns (sensor axes).
    pub accel: [Column; 3],
    /// Temperature column, deg C (optional; may hold NaN).
    #[serde(default)]
    pub temperature: Option<Column>,
    /// GPS week column (with `time.kind = "week_sow"` only).
    #[serde(default)]
    pub week: Option<Column>,
}

/// How to read an IMU CSV log (see the module notes).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImuCsvFormat {
    /// Physical lines skipped at the start.
    #[serde(default)]
    pub skip_lines: usize,
    /// Data rows dropped at the end.
    #[serde(default)]
    pub skip_last_rows: usize,
    /// 1-based line holding the column names (default: the last skipped line).
    #[serde(default)]
    pub names_line: Option<usize>,
    /// Column assignment.
    pub columns: ImuCsvColumns,
    /// Gyro unit.
    pub gyro_unit: RateUnit,
    /// Accelerometer unit.
    pub accel_unit: AccelUnit,
    /// Time source.
    pub time: CsvTime,
    /// Constant added to every time stamp, s.
    #[serde(default)]
    pub time_offset_s: f64,
    /// Sample convention for the conversion to increments.
    #[serde(default)]
    pub convention: SampleConvention,
}

impl ImuCsvFormat {
    /// The layout of the ADIS16405 static files in `../shared/data/adis16405`: two header
    /// lines, `gx gy gz [deg/s] ax ay az [g]`, no time column, 100 Hz.
    pub fn adis16405() -> Self {
        Self {
            skip_lines: 2,
            skip_last_rows: 0,
            names_line: None,
            columns: ImuCsvColumns {
                time: None,
                gyro: [Column::Index(1), Column::Index(2), Column::Index(3)],
                accel: [Column::Index(4), Column::Index(5), Column::Index(6)],
                temperature: None,
                week: None,
            },
            gyro_unit: RateUnit::DegPerS,
            accel_unit: AccelUnit::G,
            time: CsvTime::FixedRate {
                rate_hz: 100.0,
                start_s: 0.0,
            },
            time_offset_s: 0.0,
            convention: SampleConvention::Trapezoid,
        }
    }

    /// The raw log of the rtklibexplorer drive (`imu_1934.csv`): `ax ay az [g] gx gy gz
    /// [deg/s] tick [ms]`, no header, timed with `imu_1934.csv.tag`, first and last rows
    /// dropped as the source's converter does.
    pub fn rtklib_demo5_icm(tag_file: impl Into<PathBuf>) -> Self {
        Self {
            skip_lines: 1,
            skip_last_rows: 1,
            names_line: None,
            columns: ImuCsvColumns {
                time: Some(Column::Index(7)),
                gyro: [Column::Index(4), Column::Index(5), Column::Index(6)],
                accel: [Column::Index(1), Column::Index(2), Column::Index(3)],
                temperature: None,
                week: None,
            },
            gyro_unit: RateUnit::DegPerS,
            accel_unit: AccelUnit::G,
            time: CsvTime::TicksMs {
                tag_file: Some(tag_file.into()),
                stretch_to_tag_end: true,
            },
            time_offset_s: 0.0,
            convention: SampleConvention::Trapezoid,
        }
    }
}

/// One IMU row in SI units, sensor axes: angular rate and specific force at `t_s`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RawImuSample {
    /// Time stamp (GPS seconds of week, or as the mapping defines), s.
    pub t_s: f64,
    /// Angular rate, rad/s.
    pub gyro_radps: [f64; 3],
    /// Specific force, m/s^2.
    pub accel_mps2: [f64; 3],
    /// Temperature, deg C (NaN when absent).
    pub temperature_c: f64,
}

/// Rows of an IMU CSV log in SI units, with where they came from.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RawImuRecord {
    /// The rows in time order.
    pub samples: Vec<RawImuSample>,
    /// 1-based file line of each row.
    pub lines: Vec<usize>,
    /// The file read.
    pub path: PathBuf,
    /// Time gaps between rows (a counted repair, not an error).
    pub gaps: TimeGapReport,
    /// The time tag used, when there was one.
    pub tag: Option<TimeTag>,
    /// Tick-to-time stretch factor applied (1 without a tag).
    pub stretch: f64,
}

impl RawImuRecord {
    /// Mean sample rate, Hz (0 with fewer than two rows).
    pub fn mean_rate_hz(&self) -> f64 {
        match (self.samples.first(), self.samples.last()) {
            (Some(a), Some(b)) if self.samples.len() > 1 && b.t_s > a.t_s => {
                (self.samples.len() - 1) as f64 / (b.t_s - a.t_s)
            }
            _ => 0.0,
        }
    }

    /// Converts to increments with `conv` (see the module notes); the gap report is that of
    /// the increments (intervals between rows 2..n).
    pub fn to_increments(&self, conv: SampleConvention) -> ImuRecord {
        let samples = rates_to_increments(&self.samples, conv);
        let mut gaps = TimeGapReport::detect(
            &self.samples.iter().map(|s| s.t_s).collect::<Vec<_>>(),
            &self.lines,
        );
        // Re-index: increment i ends at row i + 1.
        for g in &mut gaps.gaps {
            g.index = g.index.saturating_sub(1);
        }
        ImuRecord {
            samples,
            gaps,
            origin: Some(super::text::ImuOrigin {
                path: self.path.clone(),
                lines: self.lines.get(1..).unwrap_or(&[]).to_vec(),
                increments_span_gaps: true,
            }),
        }
    }
}

/// Rates/specific forces to increments (see the module notes for the conventions). `n` rows
/// give `n - 1` increments; a row that repeats the previous one exactly gives the previous
/// increment again (as [`ImuCsvIncrements`] does: the run skips and counts it).
pub fn rates_to_increments(raw: &[RawImuSample], conv: SampleConvention) -> Vec<ImuSample> {
    let mut out: Vec<ImuSample> = Vec::with_capacity(raw.len().saturating_sub(1));
    for w in raw.windows(2) {
        let inc = match out.last() {
            Some(l) if same_row(&w[0], &w[1]) => *l,
            _ => increment(&w[0], &w[1], conv),
        };
        out.push(inc);
    }
    out
}

/// The increment over the interval (a.t, b.t] of rows `a` and `b` (see the module notes).
fn increment(a: &RawImuSample, b: &RawImuSample, conv: SampleConvention) -> ImuSample {
    let dt = b.t_s - a.t_s;
    let inc = |ya: f64, yb: f64| match conv {
        SampleConvention::Trapezoid => 0.5 * (ya + yb) * dt,
        SampleConvention::IntervalMean => yb * dt,
        SampleConvention::Increments => yb,
    };
    ImuSample {
        t_s: b.t_s,
        dtheta_rad: [
            inc(a.gyro_radps[0], b.gyro_radps[0]),
            inc(a.gyro_radps[1], b.gyro_radps[1]),
            inc(a.gyro_radps[2], b.gyro_radps[2]),
        ],
        dv_mps: [
            inc(a.accel_mps2[0], b.accel_mps2[0]),
            inc(a.accel_mps2[1], b.accel_mps2[1]),
            inc(a.accel_mps2[2], b.accel_mps2[2]),
        ],
        temperature_c: b.temperature_c,
    }
}

fn cfg_err(path: &Path, message: impl Into<String>) -> IoError {
    IoError::Config {
        path: path.to_path_buf(),
        message: message.into(),
        source: None,
    }
}

/// Names from a header line: fields (comma or space separated) reduced to their first word,
/// leading `#`/`%` removed.
pub(crate) fn header_names(line: &str) -> Vec<String> {
    let body = line.trim_start().trim_start_matches(['#', '%']);
    split_fields(body)
        .iter()
        .map(|f| f.split_whitespace().next().unwrap_or("").to_string())
        .collect()
}

pub(crate) fn resolve(
    path: &Path,
    c: &Column,
    names: Option<&[String]>,
    what: &str,
) -> Result<usize, IoError> {
    match c {
        Column::Index(0) => Err(cfg_err(
            path,
            format!("{what}: column indices are 1-based, got 0"),
        )),
        Column::Index(i) => Ok(i - 1),
        Column::Name(n) => {
            let names = names.ok_or_else(|| {
                cfg_err(
                    path,
                    format!("{what}: column {n:?} given by name but there is no names line (set skip_lines/names_line)"),
                )
            })?;
            names
                .iter()
                .position(|x| x.eq_ignore_ascii_case(n))
                .ok_or_else(|| {
                    cfg_err(
                        path,
                        format!("{what}: no column named {n:?}; the names line has {names:?}"),
                    )
                })
        }
    }
}

/// Skips the first `skip_lines` physical lines of `rd`, returning the names of the names line
/// (`names_line`, default the last skipped line; see the module notes). Shared by the IMU and
/// GNSS CSV readers.
pub(crate) fn read_header(
    rd: &mut LineReader,
    path: &Path,
    skip_lines: usize,
    names_line: Option<usize>,
) -> Result<Option<Vec<String>>, IoError> {
    let wanted = names_line.unwrap_or(skip_lines);
    let mut names: Option<Vec<String>> = None;
    for _ in 0..skip_lines {
        match rd.next_raw()? {
            Some((n, text)) if n == wanted => names = Some(header_names(text)),
            Some(_) => {}
            None => break,
        }
    }
    if names_line.is_some() && names.is_none() {
        return Err(cfg_err(
            path,
            format!("names_line {wanted} is not among the {skip_lines} skipped lines"),
        ));
    }
    Ok(names)
}

/// The columns of an IMU CSV mapping resolved to 0-based field indices, with the meaning of
/// each used field for error messages.
struct CsvCols {
    gyro: [usize; 3],
    accel: [usize; 3],
    time: Option<usize>,
    temp: Option<usize>,
    week: Option<usize>,
    /// Meaning of field i (0-based), for errors ("(unused)" for the others).
    names: Vec<String>,
    max_idx: usize,
}

fn resolve_imu_cols(
    path: &Path,
    fmt: &ImuCsvFormat,
    nm: Option<&[String]>,
) -> Result<CsvCols, IoError> {
    let c = &fmt.columns;
    let r3 = |cols: &[Column; 3], what: [&str; 3]| -> Result<[usize; 3], IoError> {
        Ok([
            resolve(path, &cols[0], nm, what[0])?,
            resolve(path, &cols[1], nm, what[1])?,
            resolve(path, &cols[2], nm, what[2])?,
        ])
    };
    let gyro = r3(&c.gyro, ["gyro x", "gyro y", "gyro z"])?;
    let accel = r3(&c.accel, ["accel x", "accel y", "accel z"])?;
    let time = match (&fmt.time, &c.time) {
        (CsvTime::FixedRate { .. }, _) | (_, None) => None,
        (_, Some(tc)) => Some(resolve(path, tc, nm, "time")?),
    };
    let temp = c
        .temperature
        .as_ref()
        .map(|tc| resolve(path, tc, nm, "temperature"))
        .transpose()?;
    let week = c
        .week
        .as_ref()
        .map(|wc| resolve(path, wc, nm, "week"))
        .transpose()?;
    let max_idx = gyro
        .iter()
        .chain(accel.iter())
        .chain(time.iter())
        .chain(temp.iter())
        .chain(week.iter())
        .copied()
        .max()
        .unwrap_or(0);
    let mut names = vec!["(unused)".to_string(); max_idx + 1];
    let label = |i: usize, unit: &str, what: &str| -> String {
        match nm.and_then(|n| n.get(i)) {
            Some(h) if !h.is_empty() => format!("{what} [{unit}] \"{h}\""),
            _ => format!("{what} [{unit}]"),
        }
    };
    let gu = match fmt.gyro_unit {
        RateUnit::DegPerS => "deg/s",
        RateUnit::RadPerS => "rad/s",
    };
    let au = match fmt.accel_unit {
        AccelUnit::G => "g",
        AccelUnit::Mps2 => "m/s^2",
    };
    for (k, &i) in gyro.iter().enumerate() {
        names[i] = label(i, gu, ["gyro_x", "gyro_y", "gyro_z"][k]);
    }
    for (k, &i) in accel.iter().enumerate() {
        names[i] = label(i, au, ["accel_x", "accel_y", "accel_z"][k]);
    }
    let tunit = match fmt.time {
        CsvTime::TicksMs { .. } => "ms",
        _ => "s",
    };
    if let Some(i) = time {
        names[i] = label(i, tunit, "time");
    }
    if let Some(i) = temp {
        names[i] = label(i, "deg C", "temperature");
    }
    if let Some(i) = week {
        names[i] = label(i, "GPS week", "week");
    }
    Ok(CsvCols {
        gyro,
        accel,
        time,
        temp,
        week,
        names,
        max_idx,
    })
}

fn check_format(path: &Path, fmt: &ImuCsvFormat) -> Result<(), IoError> {
    if !fmt.time_offset_s.is_finite() {
        return Err(cfg_err(path, "time_offset_s must be finite"));
    }
    if let CsvTime::FixedRate { rate_hz, start_s } = fmt.time {
        if !(rate_hz.is_finite() && rate_hz > 0.0 && start_s.is_finite()) {
            return Err(cfg_err(
                path,
                format!(
                    "fixed_rate: rate_hz must be finite and > 0 (got {rate_hz}), start_s finite"
                ),
            ));
        }
    } else if let CsvTime::Text { format, .. } = &fmt.time {
        if format.trim().is_empty() {
            return Err(cfg_err(path, "imu.csv.time.format is empty"));
        }
    }
    if matches!(fmt.time, CsvTime::WeekSow) != fmt.columns.week.is_some() {
        return Err(cfg_err(
            path,
            "imu.csv: time.kind = \"week_sow\" and a columns.week go together",
        ));
    }
    if !matches!(fmt.time, CsvTime::FixedRate { .. }) && fmt.columns.time.is_none() {
        return Err(cfg_err(
            path,
            "a time column is required unless time.kind = \"fixed_rate\"",
        ));
    }
    Ok(())
}

/// How a row's time column (or its index) becomes its time stamp.
#[derive(Debug, Clone, Copy)]
enum TimeMap {
    /// The column in seconds (or raw ticks, for the tag pre-pass).
    Column,
    /// Ticks in ms without a tag: t = tick / 1000.
    Ticks,
    /// Ticks placed by a tag: t = t0 + (tick - tick0) * stretch / 1000.
    Tagged { t0: f64, tick0: f64, stretch: f64 },
    /// Row k at start + k / rate.
    Fixed { rate_hz: f64, start_s: f64 },
    /// Unix seconds (`ms`: milliseconds) in `scale`, as GPS seconds of the week `week0` (the
    /// first row's, set by it).
    Unix {
        ms: bool,
        scale: TimeScale,
        week0: Option<i64>,
    },
}

/// An IMU CSV log read one row at a time, in SI units (sensor axes), with the final time
/// stamps (see the module notes): the one row parser ([`read_imu_csv_raw`] collects it).
/// Yields each row with its 1-based file line. Memory is constant: a line buffer and the last
/// `skip_last_rows` rows (held back until it is known they are not among the last). With a
/// tag file and `stretch_to_tag_end`, the first and last used ticks are needed first: the file
/// is read twice (a first pass parses the rows for their ticks only).
pub struct ImuCsvReader {
    rd: LineReader,
    path: PathBuf,
    cols: CsvCols,
    kg: f64,
    ka: f64,
    mono: MonotonicTime,
    map: TimeMap,
    offset_s: f64,
    row: usize,
    held: std::collections::VecDeque<(RawImuSample, usize)>,
    skip_last: usize,
    tag: Option<TimeTag>,
    stretch: f64,
    /// The last row parsed (an exact repeat of it is passed on).
    last_row: Option<RawImuSample>,
    /// A date-time text time column (`kind = "text"`): its chrono format, its scale and the
    /// GPS week of the first row (the time stamps are seconds of that week).
    text: Option<(String, TimeScale, Option<i64>)>,
    /// The first row's GPS week with `kind = "week_sow"` (the time stamps are seconds of it).
    week0: Option<i64>,
    failed: bool,
}

/// Whether two rows are the same record, bit for bit (NaN temperatures equal).
fn same_row(a: &RawImuSample, b: &RawImuSample) -> bool {
    let bits = |s: &RawImuSample| {
        [
            s.t_s,
            s.gyro_radps[0],
            s.gyro_radps[1],
            s.gyro_radps[2],
            s.accel_mps2[0],
            s.accel_mps2[1],
            s.accel_mps2[2],
            s.temperature_c,
        ]
        .map(f64::to_bits)
    };
    bits(a) == bits(b)
}

/// Field `i` of `dl`, a date-time text in the chrono format `format` and time scale `scale`,
/// as GPS seconds of the week `week0` (set by the first row; later weeks continue past
/// 604,800 s).
fn text_gps_s(
    dl: &DataLine<'_>,
    i: usize,
    format: &str,
    scale: TimeScale,
    week0: &mut Option<i64>,
) -> Result<f64, IoError> {
    let text = dl.fields.get(i).copied().unwrap_or("");
    let t = chrono::NaiveDateTime::parse_from_str(text, format).map_err(|e| {
        dl.invalid(
            i,
            "time [text]",
            format!("does not match the format {format:?}: {e}"),
        )
    })?;
    let u = t.and_utc();
    let frac = f64::from(u.timestamp_subsec_nanos()) * 1e-9;
    let (w, sow) = week_sow_of_epoch(u.timestamp(), frac, scale)
        .ok_or_else(|| dl.invalid(i, "time [text]", "outside the GPS time scale"))?;
    let w0 = *week0.get_or_insert(w);
    Ok(sow + (w - w0) as f64 * SECONDS_PER_WEEK)
}

impl ImuCsvReader {
    /// Opens `path` with the mapping `fmt` (reads the tag file and, with a tag file, the first
    /// rows for the first tick, or a whole first pass over the rows when the ticks are stretched
    /// to the tag's end).
    pub fn open(path: impl AsRef<Path>, fmt: &ImuCsvFormat) -> Result<Self, IoError> {
        let path = path.as_ref();
        let mut r = Self::open_mapped(path, fmt, TimeMap::Column)?;
        match &fmt.time {
            // a week column with seconds of week: placed as each row is parsed
            CsvTime::Seconds | CsvTime::WeekSow => {}
            // a date-time text is placed in GPS seconds as each row is parsed
            CsvTime::Text { .. } => {}
            CsvTime::UnixS { scale } | CsvTime::UnixMs { scale } => {
                r.map = TimeMap::Unix {
                    ms: matches!(fmt.time, CsvTime::UnixMs { .. }),
                    scale: *scale,
                    week0: None,
                }
            }
            CsvTime::FixedRate { rate_hz, start_s } => {
                r.map = TimeMap::Fixed {
                    rate_hz: *rate_hz,
                    start_s: *start_s,
                }
            }
            CsvTime::TicksMs { tag_file: None, .. } => r.map = TimeMap::Ticks,
            CsvTime::TicksMs {
                tag_file: Some(tf),
                stretch_to_tag_end,
            } => {
                let tf = if tf.is_relative() {
                    path.parent().unwrap_or(Path::new(".")).join(tf)
                } else {
                    tf.clone()
                };
                // first and last used ticks (first pass, ticks as they are; without the
                // stretch only the first tick is needed: the pass stops at the first row, the
                // rest of the file is checked as it is read)
                let mut first = None;
                let mut last = None;
                let mut n = 0usize;
                for row in Self::open_mapped(path, fmt, TimeMap::Column)? {
                    let (s, _) = row?;
                    first.get_or_insert(s.t_s);
                    last = Some(s.t_s);
                    n += 1;
                    if !*stretch_to_tag_end {
                        break;
                    }
                }
                let tg = read_time_tag(&tf)?;
                if let (Some(tick0), Some(tick1)) = (first, last) {
                    let mut stretch = 1.0;
                    if *stretch_to_tag_end {
                        let span_ms = tick1 - tick0;
                        let tag_ms = f64::from(tg.last_tick_ms());
                        if n < 2 || span_ms <= 0.0 || tag_ms <= 0.0 {
                            return Err(IoError::Format {
                                path: tf.clone(),
                                line: 0,
                                message: "cannot stretch ticks to the tag end: fewer than two rows or no tag pairs".into(),
                            });
                        }
                        stretch = tag_ms / span_ms;
                        if (stretch - 1.0).abs() > 0.01 {
                            return Err(IoError::Format {
                                path: tf.clone(),
                                line: 0,
                                message: format!(
                                    "tag span {:.3} s and tick span {:.3} s of {} differ by more than 1 %: wrong tag file?",
                                    tag_ms * 1e-3,
                                    span_ms * 1e-3,
                                    path.display()
                                ),
                            });
                        }
                    }
                    r.stretch = stretch;
                    r.map = TimeMap::Tagged {
                        t0: tg.start_sow_s,
                        tick0,
                        stretch,
                    };
                } else if !*stretch_to_tag_end {
                    // no rows: nothing to place
                    r.map = TimeMap::Ticks;
                }
                r.tag = Some(tg);
            }
        }
        Ok(r)
    }

    /// Opens the rows with time map `map` (no tag handling).
    fn open_mapped(path: &Path, fmt: &ImuCsvFormat, map: TimeMap) -> Result<Self, IoError> {
        check_format(path, fmt)?;
        let mut rd = open_text(path)?;
        let names = read_header(&mut rd, path, fmt.skip_lines, fmt.names_line)?;
        let cols = resolve_imu_cols(path, fmt, names.as_deref())?;
        Ok(Self {
            rd,
            path: path.to_path_buf(),
            cols,
            kg: fmt.gyro_unit.to_radps(),
            ka: fmt.accel_unit.to_mps2(),
            mono: MonotonicTime::new(),
            map,
            offset_s: fmt.time_offset_s,
            row: 0,
            held: std::collections::VecDeque::with_capacity(fmt.skip_last_rows + 1),
            skip_last: fmt.skip_last_rows,
            tag: None,
            stretch: 1.0,
            last_row: None,
            text: match &fmt.time {
                CsvTime::Text { format, scale } => Some((format.clone(), *scale, None)),
                _ => None,
            },
            week0: None,
            failed: false,
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The time tag used, when there is one.
    pub fn tag(&self) -> Option<&TimeTag> {
        self.tag.as_ref()
    }

    /// Tick-to-time stretch factor applied (1 without a tag).
    pub fn stretch(&self) -> f64 {
        self.stretch
    }

    /// The next parsed row (time column as written), before holding back the last rows.
    fn parse_row(&mut self) -> Result<Option<(RawImuSample, usize)>, IoError> {
        let Some(dl) = self.rd.next_data()? else {
            return Ok(None);
        };
        let c = &self.cols;
        let nm = |i: usize| c.names.get(i).map_or("?", String::as_str);
        if dl.len() < c.max_idx + 1 {
            let names: Vec<&str> = c.names.iter().map(String::as_str).collect();
            dl.require(c.max_idx + 1, usize::MAX, &names)?;
        }
        let mut s = RawImuSample {
            temperature_c: f64::NAN,
            ..RawImuSample::default()
        };
        for k in 0..3 {
            s.gyro_radps[k] = dl.num(c.gyro[k], nm(c.gyro[k]))? * self.kg;
            s.accel_mps2[k] = dl.num(c.accel[k], nm(c.accel[k]))? * self.ka;
        }
        if let Some(i) = c.temp {
            s.temperature_c = dl.num_allow_nan(i, nm(i))?;
        }
        if let Some(i) = c.time {
            s.t_s = match (&mut self.text, c.week) {
                (Some((f, scale, week0)), _) => text_gps_s(&dl, i, f, *scale, week0)?,
                (None, Some(wi)) => {
                    let (w, sow) = week_and_sow(&dl, wi, i)?;
                    let w0 = *self.week0.get_or_insert(w);
                    sow + (w - w0) as f64 * SECONDS_PER_WEEK
                }
                (None, None) => dl.num(i, nm(i))?,
            };
            // an exact repeat of the previous row (a logger writing a record twice) is passed
            // on: the increments skip it ([`ImuCsvIncrements`])
            let repeat = self.last_row.is_some_and(|p| same_row(&p, &s));
            if !repeat {
                self.mono.check(&dl, i, nm(i), s.t_s)?;
            }
        }
        self.last_row = Some(s);
        Ok(Some((s, dl.line)))
    }

    fn read(&mut self) -> Result<Option<(RawImuSample, usize)>, IoError> {
        loop {
            let row = match self.parse_row() {
                // a last line cut short (a log still being written): the file ends before it
                Err(e) if super::lines::cut_short(&self.rd, &e) => None,
                r => r?,
            };
            match row {
                Some(r) => {
                    self.held.push_back(r);
                    if self.held.len() > self.skip_last {
                        break;
                    }
                }
                // the rows still held are the last `skip_last_rows`: dropped
                None => return Ok(None),
            }
        }
        let Some((mut s, line)) = self.held.pop_front() else {
            return Ok(None);
        };
        s.t_s = match &mut self.map {
            TimeMap::Unix { ms, scale, week0 } => {
                let v = s.t_s;
                let (whole, frac) = if *ms {
                    // keep the millisecond digits exact
                    let w = (v / 1000.0).floor();
                    (w, (v - w * 1000.0) * 1e-3)
                } else {
                    let w = v.floor();
                    (w, v - w)
                };
                let (w, sow) = (0.0..7.3e9)
                    .contains(&whole)
                    .then(|| week_sow_of_epoch(whole as i64, frac, *scale))
                    .flatten()
                    .ok_or_else(|| IoError::Format {
                        path: self.path.clone(),
                        line,
                        message: format!(
                            "time {v} [Unix {}] is outside 1970..2200",
                            if *ms { "ms" } else { "s" }
                        ),
                    })?;
                let w0 = *week0.get_or_insert(w);
                sow + (w - w0) as f64 * SECONDS_PER_WEEK
            }
            TimeMap::Column => s.t_s,
            TimeMap::Ticks => s.t_s * 1e-3,
            TimeMap::Tagged { t0, tick0, stretch } => *t0 + (s.t_s - *tick0) * *stretch * 1e-3,
            TimeMap::Fixed { rate_hz, start_s } => *start_s + self.row as f64 / *rate_hz,
        };
        if self.offset_s != 0.0 {
            s.t_s += self.offset_s;
        }
        self.row += 1;
        Ok(Some((s, line)))
    }
}

impl Iterator for ImuCsvReader {
    type Item = Result<(RawImuSample, usize), IoError>;

    /// The next row and its line; after an error, `None`.
    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        let r = self.read().transpose();
        if matches!(r, Some(Err(_))) {
            self.failed = true;
        }
        r
    }
}

/// Reads an IMU CSV log into SI rates and specific forces (sensor axes, no mounting rotation,
/// no conversion to increments). This is what the Allan-variance tool wants. The whole-file
/// form of [`ImuCsvReader`].
pub fn read_imu_csv_raw(
    path: impl AsRef<Path>,
    fmt: &ImuCsvFormat,
) -> Result<RawImuRecord, IoError> {
    let path = path.as_ref();
    let mut rd = ImuCsvReader::open(path, fmt)?;
    let mut samples = Vec::new();
    let mut lines = Vec::new();
    for r in &mut rd {
        let (s, line) = r?;
        samples.push(s);
        lines.push(line);
    }
    let t: Vec<f64> = samples.iter().map(|s| s.t_s).collect();
    let gaps = TimeGapReport::detect(&t, &lines);
    Ok(RawImuRecord {
        samples,
        lines,
        path: path.to_path_buf(),
        gaps,
        tag: rd.tag,
        stretch: rd.stretch,
    })
}

/// An IMU CSV log read as increments one at a time (the streaming form of [`read_imu_csv`]):
/// each row after the first gives the increment over the interval it closes (see the module
/// notes), yielded with the row's line.
///
/// A row that repeats the previous one exactly (a logger writing a record twice) gives the
/// previous increment again, with the same time: the run skips and counts it as a rejected
/// sample.
pub struct ImuCsvIncrements {
    rows: ImuCsvReader,
    conv: SampleConvention,
    prev: Option<RawImuSample>,
    last: Option<ImuSample>,
}

impl ImuCsvIncrements {
    /// Opens `path` with the mapping `fmt` and its sample convention.
    pub fn open(path: impl AsRef<Path>, fmt: &ImuCsvFormat) -> Result<Self, IoError> {
        Ok(Self {
            rows: ImuCsvReader::open(path, fmt)?,
            conv: fmt.convention,
            prev: None,
            last: None,
        })
    }
}

impl Iterator for ImuCsvIncrements {
    type Item = Result<(ImuSample, usize), IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            let (b, line) = match self.rows.next()? {
                Ok(r) => r,
                Err(e) => return Some(Err(e)),
            };
            if let Some(a) = self.prev.replace(b) {
                if same_row(&a, &b) {
                    if let Some(l) = self.last {
                        return Some(Ok((l, line)));
                    }
                    continue;
                }
                let inc = increment(&a, &b, self.conv);
                self.last = Some(inc);
                return Some(Ok((inc, line)));
            }
        }
    }
}

/// Reads an IMU CSV log and converts it to increments with the format's sample convention
/// (sensor axes; apply a [`super::Mounting`] for body axes).
pub fn read_imu_csv(path: impl AsRef<Path>, fmt: &ImuCsvFormat) -> Result<ImuRecord, IoError> {
    Ok(read_imu_csv_raw(path, fmt)?.to_increments(fmt.convention))
}
