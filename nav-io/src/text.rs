//! The project's text formats (KF-GINS layouts, see DESIGN.md):
//!
//! - IMU: `t dtheta_x dtheta_y dtheta_z dv_x dv_y dv_z [temperature_C]`, t = GPS seconds of
//!   week at the END of the increment interval (t_prev, t], increments in rad and m/s, FRD.
//!   The temperature column may hold `nan` (no reading) when other lines have one.
//! - GNSS: `t lat_deg lon_deg h_m std_n_m std_e_m std_d_m [vn ve vd std_vn std_ve std_vd]`,
//!   7 or 13 fields per line (a line either has all six velocity fields or none).
//!   The format carries no quality flag: fixes read from it have [`FixQuality::Single`] and
//!   `num_sats = 0` (the standard deviations are what the filter uses).
//!   Caution: KF-GINS's own loader (`gnssfileloader.h`) reads the position standard
//!   deviations of a 13-column file from columns 8-10, not 5-7; a 13-column file in this
//!   (DESIGN.md) layout is therefore misread by KF-GINS. Files meant for KF-GINS should be
//!   written without velocities (7 columns), which both read identically.
//! - Navigation/truth: `week sow lat_deg lon_deg h_m vn ve vd roll_deg pitch_deg yaw_deg`.
//!
//! Time must increase strictly from line to line (nav files: week*604800 + sow). IMU time gaps
//! (an interval longer than 1.5x the median interval) are not errors: they are counted and
//! located in [`TimeGapReport`], and no data are invented.
//!
//! Writers print values that are stored in file units with Rust's shortest round-trip
//! representation (bit-exact on re-reading); converted values (rad -> deg) are written as the
//! shortest round-trip form of the degree value, so re-reading gives the radians within 1-2 ulp
//! (~1e-16 rad ~ 1e-9 m on the earth's surface). Fields are separated by one space, without a
//! header line, so KF-GINS reads the files too.

use super::lines::{cut_short, open_text, DataLine, MonotonicTime};
use super::IoError;
use flate2::write::GzEncoder;
use nav_core::types::{FixQuality, GnssFix, ImuSample, NavSolution};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Seconds in a GPS week.
pub const SECONDS_PER_WEEK: f64 = 604_800.0;

/// An IMU time gap: the interval ending at `index` is longer than the gap threshold.
#[derive(Debug, Clone, PartialEq)]
pub struct ImuGap {
    /// Index in the sample vector of the first sample after the gap.
    pub index: usize,
    /// 1-based line of that sample in the file (0 when not from a file).
    pub line: usize,
    /// Time of the last sample before the gap, s.
    pub t_before_s: f64,
    /// Time of the first sample after the gap, s.
    pub t_after_s: f64,
    /// Missing time: interval minus the median interval, s.
    pub missing_s: f64,
}

impl ImuGap {
    /// Length of the interval that spans the gap, s.
    pub fn interval_s(&self) -> f64 {
        self.t_after_s - self.t_before_s
    }
}

/// The documented repair report of an IMU record: time gaps are detected and counted, not
/// filled. A gap is an interval longer than `threshold_s` = 1.5 x `median_dt_s`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TimeGapReport {
    /// Median sample interval, s (0 with fewer than two samples).
    pub median_dt_s: f64,
    /// Gap threshold, s (1.5 x median).
    pub threshold_s: f64,
    /// Every gap, in time order.
    pub gaps: Vec<ImuGap>,
    /// Sum of the gaps' missing time, s.
    pub total_missing_s: f64,
}

impl TimeGapReport {
    /// Ratio of an interval to the median above which the interval is a gap.
    pub const GAP_FACTOR: f64 = 1.5;

    /// Finds the gaps in strictly increasing times `t_s`; `lines[i]` is the file line of
    /// sample i (may be empty: lines reported as 0).
    pub fn detect(t_s: &[f64], lines: &[usize]) -> Self {
        if t_s.len() < 2 {
            return Self::default();
        }
        let mut dts: Vec<f64> = t_s.windows(2).map(|w| w[1] - w[0]).collect();
        dts.sort_by(f64::total_cmp);
        let mid = dts.len() / 2;
        let median = if dts.len() % 2 == 1 {
            dts[mid]
        } else {
            0.5 * (dts[mid - 1] + dts[mid])
        };
        let threshold = Self::GAP_FACTOR * median;
        let mut gaps = Vec::new();
        let mut total = 0.0;
        for (i, w) in t_s.windows(2).enumerate() {
            let dt = w[1] - w[0];
            if dt > threshold {
                let missing = dt - median;
                total += missing;
                gaps.push(ImuGap {
                    index: i + 1,
                    line: lines.get(i + 1).copied().unwrap_or(0),
                    t_before_s: w[0],
                    t_after_s: w[1],
                    missing_s: missing,
                });
            }
        }
        Self {
            median_dt_s: median,
            threshold_s: threshold,
            gaps,
            total_missing_s: total,
        }
    }

    /// Number of gaps.
    pub fn count(&self) -> usize {
        self.gaps.len()
    }
}

impl std::fmt::Display for TimeGapReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} time gap(s) (interval > {:.6} s = 1.5 x median {:.6} s), {:.6} s missing in total",
            self.count(),
            self.threshold_s,
            self.median_dt_s,
            self.total_missing_s
        )?;
        for g in self.gaps.iter().take(10) {
            write!(
                f,
                "; line {}: {:.6} -> {:.6} s ({:.6} s missing)",
                g.line, g.t_before_s, g.t_after_s, g.missing_s
            )?;
        }
        if self.gaps.len() > 10 {
            write!(f, "; ...")?;
        }
        Ok(())
    }
}

/// Where the samples of an IMU record come from: the file and, per sample, its line (1-based;
/// the record number for binary files), for messages that name the offending line.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ImuOrigin {
    /// The file.
    pub path: PathBuf,
    /// File line of each sample (same length and order as the samples).
    pub lines: Vec<usize>,
    /// True when each increment covers the whole interval since the previous sample even
    /// across a time gap (rates converted to increments over the true interval, CSV);
    /// false when a gap may have lost increments (increment files: lines deleted, frames
    /// lost), to be decided per gap (`nav_core::imu_guard::GapIncrements::Auto`).
    pub increments_span_gaps: bool,
}

impl ImuOrigin {
    /// `path:line` of sample `index` (`path, sample index` when the line is unknown).
    pub fn locate(&self, index: usize) -> String {
        match self.lines.get(index) {
            Some(l) => format!("{} line {l}", self.path.display()),
            None => format!("{} sample {}", self.path.display(), index + 1),
        }
    }
}

/// An IMU record as read: the samples (unchanged, nothing invented) and the gap report.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ImuRecord {
    /// The samples in time order.
    pub samples: Vec<ImuSample>,
    /// Detected time gaps (a counted repair, not an error).
    pub gaps: TimeGapReport,
    /// The file and line of each sample (None when built from samples in memory).
    pub origin: Option<ImuOrigin>,
}

impl ImuRecord {
    /// Builds a record from samples, detecting gaps (lines unknown: 0).
    pub fn from_samples(samples: Vec<ImuSample>) -> Self {
        let t: Vec<f64> = samples.iter().map(|s| s.t_s).collect();
        let gaps = TimeGapReport::detect(&t, &[]);
        Self {
            samples,
            gaps,
            origin: None,
        }
    }

    /// Mean sample rate, Hz (0 with fewer than two samples).
    pub fn mean_rate_hz(&self) -> f64 {
        match (self.samples.first(), self.samples.last()) {
            (Some(a), Some(b)) if self.samples.len() > 1 && b.t_s > a.t_s => {
                (self.samples.len() - 1) as f64 / (b.t_s - a.t_s)
            }
            _ => 0.0,
        }
    }
}

const IMU_NAMES: [&str; 8] = [
    "t_s",
    "dtheta_x_rad",
    "dtheta_y_rad",
    "dtheta_z_rad",
    "dv_x_mps",
    "dv_y_mps",
    "dv_z_mps",
    "temperature_c",
];

fn parse_imu_line(dl: &DataLine<'_>) -> Result<ImuSample, IoError> {
    dl.require(7, 8, &IMU_NAMES)?;
    let mut v = [0.0; 7];
    for (i, x) in v.iter_mut().enumerate() {
        *x = dl.num(i, IMU_NAMES[i])?;
    }
    let temperature_c = if dl.len() == 8 {
        dl.num_allow_nan(7, IMU_NAMES[7])?
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

/// Reads an IMU text file (plain or gzip). Errors name file, line and column; time gaps are
/// reported in the record, not filled. The whole-file form of [`ImuTextReader`] (one parser).
pub fn read_imu_text(path: impl AsRef<Path>) -> Result<ImuRecord, IoError> {
    let path = path.as_ref();
    collect_record(path, ImuTextReader::open(path)?)
}

/// Collects a stream of `(sample, line)` into an [`ImuRecord`] of `path` (gaps detected,
/// increments not spanning gaps).
fn collect_record(
    path: &Path,
    rd: impl Iterator<Item = Result<(ImuSample, usize), IoError>>,
) -> Result<ImuRecord, IoError> {
    let mut samples = Vec::new();
    let mut lines = Vec::new();
    for r in rd {
        let (s, line) = r?;
        lines.push(line);
        samples.push(s);
    }
    let t: Vec<f64> = samples.iter().map(|s| s.t_s).collect();
    let gaps = TimeGapReport::detect(&t, &lines);
    Ok(ImuRecord {
        samples,
        gaps,
        origin: Some(ImuOrigin {
            path: path.to_path_buf(),
            lines,
            increments_span_gaps: false,
        }),
    })
}

/// An IMU text file (plain or gzip) read one sample at a time, yielding each sample with its
/// 1-based file line: the one parser of the format ([`read_imu_text`] collects it). Errors
/// name file, line and column; time must increase strictly. Nothing is kept but the current
/// line (one reused buffer; fields are slices of it; no allocation per line).
pub struct ImuTextReader {
    rd: super::lines::LineReader,
    mono: MonotonicTime,
    /// The last sample yielded (an exact repeat of it is passed on, see [`ImuTextReader`]).
    prev: Option<ImuSample>,
    failed: bool,
}

impl ImuTextReader {
    /// Opens `path`.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, IoError> {
        Ok(Self::from_lines(open_text(path.as_ref())?))
    }

    /// Reads from any byte source (gzip detected); `name` is the file name used in errors.
    pub fn from_reader<R: std::io::Read + Send + 'static>(
        name: &Path,
        src: R,
    ) -> Result<Self, IoError> {
        Ok(Self::from_lines(super::lines::LineReader::from_reader(
            name, src,
        )?))
    }

    fn from_lines(rd: super::lines::LineReader) -> Self {
        Self {
            rd,
            mono: MonotonicTime::new(),
            prev: None,
            failed: false,
        }
    }

    /// The file.
    pub fn path(&self) -> &Path {
        self.rd.path()
    }

    fn read(&mut self) -> Result<Option<(ImuSample, usize)>, IoError> {
        match self.read_line() {
            Ok(Some((s, line))) => {
                self.prev = Some(s);
                Ok(Some((s, line)))
            }
            // a last line cut short (a log still being written): the file ends before it
            Err(e) if cut_short(&self.rd, &e) => Ok(None),
            r => r,
        }
    }

    fn read_line(&mut self) -> Result<Option<(ImuSample, usize)>, IoError> {
        loop {
            if !self.rd.advance()? {
                return Ok(None);
            }
            let line = self.rd.line_number();
            // the common line: parsed in one pass over its bytes
            if let Some(s) = parse_imu_fast(self.rd.current_bytes()) {
                if self.mono.accept(line, s.t_s) {
                    return Ok(Some((s, line)));
                }
            }
            // anything else (comments, errors, other spellings): the general parser on the
            // same line, which gives the same values and the errors with their columns
            if let Some(dl) = self.rd.current_data()? {
                let s = parse_imu_line(&dl)?;
                if self.prev.is_some_and(|p| same_sample(&p, &s)) {
                    // an exact repeat of the previous line (a logger writing a record
                    // twice): passed on, the run skips and counts it
                    return Ok(Some((s, line)));
                }
                self.mono.check(&dl, 0, IMU_NAMES[0], s.t_s)?;
                return Ok(Some((s, line)));
            }
        }
    }
}

/// Whether two IMU samples are the same record: equal time, increments and temperature (NaN
/// temperatures equal), bit for bit.
pub fn same_sample(a: &ImuSample, b: &ImuSample) -> bool {
    let same = |x: f64, y: f64| x.to_bits() == y.to_bits();
    // the time first: consecutive samples differ there, and the rest is not looked at
    same(a.t_s, b.t_s)
        && a.dtheta_rad
            .iter()
            .zip(&b.dtheta_rad)
            .chain(a.dv_mps.iter().zip(&b.dv_mps))
            .all(|(x, y)| same(*x, *y))
        && (same(a.temperature_c, b.temperature_c)
            || (a.temperature_c.is_nan() && b.temperature_c.is_nan()))
}

/// An IMU line of 7 or 8 numbers separated by ASCII white space, parsed in one pass (no
/// field list, no UTF-8 check: every accepted byte is ASCII) with the plain-decimal reader
/// (`decimal::parse_plain`) and `fast-float2` for the numbers it leaves, or `None` when the
/// line is anything else (blank, comment, comma-separated, non-ASCII, a field that is not a
/// plain finite number, too few or too many fields). What it accepts, it reads to the bits
/// [`parse_imu_line`] gives (all three readers are correctly rounded, see
/// [`super::lines::parse_f64`]); everything else goes to [`parse_imu_line`].
fn parse_imu_fast(b: &[u8]) -> Option<ImuSample> {
    let skip_space = |mut i: usize| {
        while b.get(i).is_some_and(u8::is_ascii_whitespace) {
            i += 1;
        }
        i
    };
    let mut v = [0.0f64; 8];
    let mut n = 0usize;
    let mut i = skip_space(0);
    for slot in v.iter_mut() {
        let rest = b.get(i..)?;
        if rest.is_empty() {
            break;
        }
        // the common spelling read here, the others by `fast-float2`; a finite result is a
        // plain number ([+-] digits [. digits] [e [+-] digits]): `inf`/`nan` spellings give
        // non-finite values and go to the general parser
        let (x, used) = match super::decimal::parse_plain(rest) {
            Some(r) => r,
            None => fast_float2::parse_partial::<f64, _>(rest).ok()?,
        };
        if used == 0 || !x.is_finite() {
            return None;
        }
        *slot = x;
        n += 1;
        i += used;
        // the separator: usually one space
        match b.get(i) {
            None => break,
            Some(b' ') if !b.get(i + 1).is_some_and(u8::is_ascii_whitespace) => i += 1,
            Some(c) if c.is_ascii_whitespace() => i = skip_space(i),
            Some(_) => return None,
        }
    }
    // a ninth field
    if i < b.len() {
        return None;
    }
    if n < 7 {
        return None;
    }
    let [t_s, gx, gy, gz, ax, ay, az, temp] = v;
    Some(ImuSample {
        t_s,
        dtheta_rad: [gx, gy, gz],
        dv_mps: [ax, ay, az],
        temperature_c: if n == 8 { temp } else { f64::NAN },
    })
}

impl Iterator for ImuTextReader {
    type Item = Result<(ImuSample, usize), IoError>;

    /// The next sample and its line; after an error, `None`.
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

/// Opens `path` for writing (gzip when it ends in `.gz`) and runs `body` on a buffered writer.
pub fn write_with(
    path: &Path,
    body: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<(), IoError> {
    let f = File::create(path).map_err(|source| IoError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    let werr = |source| IoError::Write {
        path: path.to_path_buf(),
        source,
    };
    let gz = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"));
    if gz {
        let mut w = GzEncoder::new(BufWriter::new(f), flate2::Compression::default());
        body(&mut w).map_err(werr)?;
        let mut inner = w.finish().map_err(werr)?;
        inner.flush().map_err(werr)?;
    } else {
        let mut w = BufWriter::new(f);
        body(&mut w).map_err(werr)?;
        w.flush().map_err(werr)?;
    }
    Ok(())
}

/// Writes IMU samples in the IMU text format (gzip when the path ends in `.gz`). The
/// temperature column is written when any sample has a finite temperature (`NaN` for the
/// others). Values are written in shortest round-trip form: re-reading is bit-exact.
pub fn write_imu_text(path: impl AsRef<Path>, samples: &[ImuSample]) -> Result<(), IoError> {
    let path = path.as_ref();
    let with_temp = samples.iter().any(|s| s.temperature_c.is_finite());
    write_with(path, |w| {
        for s in samples {
            write_imu_line(w, s, with_temp)?;
        }
        Ok(())
    })
}

/// One line of the IMU text format (with the temperature column when `with_temp`); the one
/// definition [`write_imu_text`] and streaming writers (hw-bridge) share.
pub fn write_imu_line<W: Write + ?Sized>(
    w: &mut W,
    s: &ImuSample,
    with_temp: bool,
) -> std::io::Result<()> {
    write!(
        w,
        "{} {:e} {:e} {:e} {:e} {:e} {:e}",
        s.t_s,
        s.dtheta_rad[0],
        s.dtheta_rad[1],
        s.dtheta_rad[2],
        s.dv_mps[0],
        s.dv_mps[1],
        s.dv_mps[2]
    )?;
    if with_temp {
        write!(w, " {}", s.temperature_c)?;
    }
    writeln!(w)
}

const GNSS_NAMES: [&str; 13] = [
    "t_s",
    "lat_deg",
    "lon_deg",
    "h_m",
    "std_n_m",
    "std_e_m",
    "std_d_m",
    "vn_mps",
    "ve_mps",
    "vd_mps",
    "std_vn_mps",
    "std_ve_mps",
    "std_vd_mps",
];

fn parse_gnss_line(dl: &DataLine<'_>) -> Result<GnssFix, IoError> {
    dl.require(7, 13, &GNSS_NAMES)?;
    if dl.len() != 7 && dl.len() != 13 {
        return Err(IoError::TooFewFields {
            path: dl.path.to_path_buf(),
            line: dl.line,
            column: dl.len() + 1,
            name: GNSS_NAMES.get(dl.len()).copied().unwrap_or("?").to_string(),
            found: dl.len(),
            expected: "7 or 13".into(),
        });
    }
    let t_s = dl.num(0, GNSS_NAMES[0])?;
    let lat = dl.lat_deg(1, GNSS_NAMES[1])?;
    let lon = dl.lon_deg(2, GNSS_NAMES[2])?;
    let h = dl.num(3, GNSS_NAMES[3])?;
    let mut std = [0.0; 3];
    for (k, s) in std.iter_mut().enumerate() {
        *s = dl.sigma(4 + k, GNSS_NAMES[4 + k])?;
    }
    let mut fix = GnssFix {
        t_s,
        lat_rad: lat.to_radians(),
        lon_rad: lon.to_radians(),
        h_m: h,
        pos_std_ned_m: std,
        quality: FixQuality::Single,
        ..GnssFix::default()
    };
    if dl.len() == 13 {
        for k in 0..3 {
            fix.vel_ned_mps[k] = dl.num(7 + k, GNSS_NAMES[7 + k])?;
            fix.vel_std_ned_mps[k] = dl.sigma(10 + k, GNSS_NAMES[10 + k])?;
        }
        fix.has_velocity = true;
    }
    Ok(fix)
}

/// Reads a GNSS text file (plain or gzip): 7 or 13 fields per line ([`GnssTextReader`]
/// collected).
pub fn read_gnss_text(path: impl AsRef<Path>) -> Result<Vec<GnssFix>, IoError> {
    GnssTextReader::open(path)?.collect()
}

/// A GNSS text file (plain or gzip) read one fix at a time: the one parser of the format
/// ([`read_gnss_text`] collects it). Errors name file, line and column; time must increase
/// strictly. Nothing is kept but the current line.
pub struct GnssTextReader {
    rd: super::lines::LineReader,
    mono: MonotonicTime,
    failed: bool,
}

impl GnssTextReader {
    /// Opens `path`.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, IoError> {
        Ok(Self {
            rd: open_text(path.as_ref())?,
            mono: MonotonicTime::new(),
            failed: false,
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        self.rd.path()
    }

    fn read(&mut self) -> Result<Option<GnssFix>, IoError> {
        match self.read_line() {
            // a last line cut short (a log still being written): the file ends before it
            Err(e) if cut_short(&self.rd, &e) => Ok(None),
            r => r,
        }
    }

    fn read_line(&mut self) -> Result<Option<GnssFix>, IoError> {
        let Some(dl) = self.rd.next_data()? else {
            return Ok(None);
        };
        let f = parse_gnss_line(&dl)?;
        self.mono.check(&dl, 0, GNSS_NAMES[0], f.t_s)?;
        Ok(Some(f))
    }
}

impl Iterator for GnssTextReader {
    type Item = Result<GnssFix, IoError>;

    /// The next fix; after an error, `None`.
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

/// Writes GNSS fixes in the GNSS text format; a fix with `has_velocity` gets the six velocity
/// fields. Quality and satellite count are not part of the format and are not written.
pub fn write_gnss_text(path: impl AsRef<Path>, fixes: &[GnssFix]) -> Result<(), IoError> {
    write_with(path.as_ref(), |w| {
        for f in fixes {
            write_gnss_line(w, f)?;
        }
        Ok(())
    })
}

/// One line of the GNSS text format (the six velocity fields when `has_velocity`); shared by
/// [`write_gnss_text`] and streaming writers (hw-bridge).
pub fn write_gnss_line<W: Write + ?Sized>(w: &mut W, f: &GnssFix) -> std::io::Result<()> {
    write!(
        w,
        "{} {} {} {} {} {} {}",
        f.t_s,
        f.lat_rad.to_degrees(),
        f.lon_rad.to_degrees(),
        f.h_m,
        f.pos_std_ned_m[0],
        f.pos_std_ned_m[1],
        f.pos_std_ned_m[2]
    )?;
    if f.has_velocity {
        write!(
            w,
            " {} {} {} {} {} {}",
            f.vel_ned_mps[0],
            f.vel_ned_mps[1],
            f.vel_ned_mps[2],
            f.vel_std_ned_mps[0],
            f.vel_std_ned_mps[1],
            f.vel_std_ned_mps[2]
        )?;
    }
    writeln!(w)
}

const NAV_NAMES: [&str; 11] = [
    "week",
    "sow_s",
    "lat_deg",
    "lon_deg",
    "h_m",
    "vn_mps",
    "ve_mps",
    "vd_mps",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
];

fn parse_nav_line(dl: &DataLine<'_>) -> Result<NavSolution, IoError> {
    dl.require(11, 11, &NAV_NAMES)?;
    let week = dl.integer(0, NAV_NAMES[0], 0, u16::MAX as i64)? as u16;
    let sow = dl.num(1, NAV_NAMES[1])?;
    let lat = dl.lat_deg(2, NAV_NAMES[2])?;
    let lon = dl.lon_deg(3, NAV_NAMES[3])?;
    let mut v = [0.0; 7];
    for (k, x) in v.iter_mut().enumerate() {
        *x = dl.num(4 + k, NAV_NAMES[4 + k])?;
    }
    Ok(NavSolution {
        week,
        t_s: sow,
        lat_rad: lat.to_radians(),
        lon_rad: lon.to_radians(),
        h_m: v[0],
        vel_ned_mps: [v[1], v[2], v[3]],
        rpy_rad: [v[4].to_radians(), v[5].to_radians(), v[6].to_radians()],
        pos_std_ned_m: [f64::NAN; 3],
        vel_std_ned_mps: [f64::NAN; 3],
        att_std_rad: [f64::NAN; 3],
        status: 0,
    })
}

/// Reads a navigation/truth text file (KF-GINS nav format): [`NavTextReader`] collected. The
/// standard deviations of the returned solutions are NaN (not in the format). Time
/// (week*604800 + sow) must increase.
pub fn read_nav_text(path: impl AsRef<Path>) -> Result<Vec<NavSolution>, IoError> {
    NavTextReader::open(path)?.collect()
}

/// A navigation/truth text file (KF-GINS nav format, plain or gzip) read one record at a
/// time: the one parser of the format ([`read_nav_text`] collects it). Errors name file, line
/// and column; time (week*604800 + sow, s) must increase strictly. Nothing is kept but the
/// current line.
pub struct NavTextReader {
    rd: super::lines::LineReader,
    mono: MonotonicTime,
    failed: bool,
}

impl NavTextReader {
    /// Opens `path`.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, IoError> {
        Ok(Self {
            rd: open_text(path.as_ref())?,
            mono: MonotonicTime::new(),
            failed: false,
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        self.rd.path()
    }

    fn read(&mut self) -> Result<Option<NavSolution>, IoError> {
        match self.read_line() {
            // a last line cut short (a log still being written): the file ends before it
            Err(e) if cut_short(&self.rd, &e) => Ok(None),
            r => r,
        }
    }

    fn read_line(&mut self) -> Result<Option<NavSolution>, IoError> {
        let Some(dl) = self.rd.next_data()? else {
            return Ok(None);
        };
        let n = parse_nav_line(&dl)?;
        self.mono.check(
            &dl,
            1,
            NAV_NAMES[1],
            n.week as f64 * SECONDS_PER_WEEK + n.t_s,
        )?;
        Ok(Some(n))
    }
}

impl Iterator for NavTextReader {
    type Item = Result<NavSolution, IoError>;

    /// The next record. After an error about one line (a field that does not parse, a time
    /// not after the previous record's) the next call reads on from the next line, so a
    /// caller may skip a bad record; after an error about the file (opening, reading, not
    /// text), `None`.
    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        let r = self.read().transpose();
        if let Some(Err(e)) = &r {
            self.failed = !is_line_error(e);
        }
        r
    }
}

/// Whether `e` is about the content of one line (the reader can go on with the next line).
pub fn is_line_error(e: &IoError) -> bool {
    matches!(
        e,
        IoError::TooFewFields { .. }
            | IoError::TooManyFields { .. }
            | IoError::NotANumber { .. }
            | IoError::NonFinite { .. }
            | IoError::InvalidValue { .. }
            | IoError::NonMonotonicTime { .. }
    )
}

/// Writes navigation solutions in the KF-GINS nav format (standard deviations and status are
/// not part of it). Angles and lat/lon are written as the shortest
/// round-trip form of their degree values.
pub fn write_nav_text(path: impl AsRef<Path>, sols: &[NavSolution]) -> Result<(), IoError> {
    write_with(path.as_ref(), |w| {
        for n in sols {
            write_nav_line(w, n)?;
        }
        Ok(())
    })
}

/// One line of the KF-GINS nav format; shared by [`write_nav_text`] and streaming writers
/// (hw-bridge). Numbers in Rust's `Display` form (shortest round-trip digits), byte for byte:
/// the digits come from `zmij` where it agrees with `Display` (everything but exact ties, which
/// go to `Display`; see `numfmt`), about 3x faster than `write!`. The line is assembled on
/// the stack and written with one `write_all`.
pub fn write_nav_line<W: Write + ?Sized>(w: &mut W, n: &NavSolution) -> std::io::Result<()> {
    write_nav_line_with(&mut super::numfmt::LineBuf::new(), w, n)
}

/// [`write_nav_line`] assembling the line in `lb` (a writer of many lines keeps one: no
/// buffer set up per line); whatever `lb` held before is dropped.
pub fn write_nav_line_with<W: Write + ?Sized>(
    lb: &mut super::numfmt::LineBuf,
    w: &mut W,
    n: &NavSolution,
) -> std::io::Result<()> {
    lb.clear();
    push_nav_line(lb, w, n)?;
    lb.flush(w)
}

/// Appends the `nav.txt` line of `n` ([`write_nav_line`]'s bytes) to `lb`, which writes to
/// `w` only when it is full: with a [`super::numfmt::BlockBuf`] many lines go out in one
/// write. The caller flushes `lb` at the end.
pub fn push_nav_line<W: Write + ?Sized, const CAP: usize>(
    lb: &mut super::numfmt::LineBuf<CAP>,
    w: &mut W,
    n: &NavSolution,
) -> std::io::Result<()> {
    push_nav_values(lb, w, n.week, &nav_line_values(n))
}

/// The numbers of the `nav.txt` line of `n` after the week, in the order written: time (s of
/// week), latitude and longitude (deg), height (m), NED velocity (m/s), roll, pitch and yaw
/// (deg). What a writer of `nav.txt` on another thread needs of a solution (80 bytes).
pub fn nav_line_values(n: &NavSolution) -> [f64; 10] {
    [
        n.t_s,
        n.lat_rad.to_degrees(),
        n.lon_rad.to_degrees(),
        n.h_m,
        n.vel_ned_mps[0],
        n.vel_ned_mps[1],
        n.vel_ned_mps[2],
        n.rpy_rad[0].to_degrees(),
        n.rpy_rad[1].to_degrees(),
        n.rpy_rad[2].to_degrees(),
    ]
}

/// Appends the `nav.txt` line of GPS week `week` and the numbers `v` (see
/// [`nav_line_values`]) to `lb`, as [`push_nav_line`] does.
pub fn push_nav_values<W: Write + ?Sized, const CAP: usize>(
    lb: &mut super::numfmt::LineBuf<CAP>,
    w: &mut W,
    week: u16,
    v: &[f64; 10],
) -> std::io::Result<()> {
    lb.push_u64(w, u64::from(week))?;
    lb.push_spaced_f64s(w, v)?;
    lb.push_byte(w, b'\n')
}

/// [`write_nav_line`] with `write!` and `Display` (the reference the fast form must equal;
/// kept for the tests and for measuring).
pub fn write_nav_line_display<W: Write + ?Sized>(
    w: &mut W,
    n: &NavSolution,
) -> std::io::Result<()> {
    writeln!(
        w,
        "{} {} {} {} {} {} {} {} {} {} {}",
        n.week,
        n.t_s,
        n.lat_rad.to_degrees(),
        n.lon_rad.to_degrees(),
        n.h_m,
        n.vel_ned_mps[0],
        n.vel_ned_mps[1],
        n.vel_ned_mps[2],
        n.rpy_rad[0].to_degrees(),
        n.rpy_rad[1].to_degrees(),
        n.rpy_rad[2].to_degrees()
    )
}

/// Bytes of one record of the binary IMU format (7 little-endian f64).
pub const IMU_BIN_RECORD_BYTES: usize = 56;

/// Reads the binary IMU format of awesome-gins-datasets (`*.bin`): records of 7 little-endian
/// f64 `t dtheta_x dtheta_y dtheta_z dv_x dv_y dv_z` (same meaning and units as the text
/// format), gzip accepted. In errors, "line" is the 1-based RECORD number and "column" the
/// 1-based field. A trailing partial record is an error. The whole-file form of
/// [`ImuBinReader`].
pub fn read_imu_bin(path: impl AsRef<Path>) -> Result<ImuRecord, IoError> {
    let path = path.as_ref();
    collect_record(path, ImuBinReader::open(path)?)
}

/// The binary IMU format (see [`read_imu_bin`]) read one record at a time (gzip detected from
/// the magic bytes), yielding each sample with its 1-based record number; a fixed 56-byte
/// record buffer, nothing else kept. After an error, `None`.
pub struct ImuBinReader {
    path: PathBuf,
    inner: Box<dyn std::io::BufRead>,
    record: usize,
    prev_t_s: Option<f64>,
    failed: bool,
}

impl ImuBinReader {
    /// Opens `path`.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, IoError> {
        let path = path.as_ref();
        let f = crate::lines::open_data_file(path)?;
        Self::from_reader(path, f)
    }

    /// Reads from any byte source (gzip detected); `name` is the file name used in errors.
    pub fn from_reader<R: std::io::Read + 'static>(name: &Path, src: R) -> Result<Self, IoError> {
        use std::io::BufRead;
        let mut br = std::io::BufReader::with_capacity(1 << 16, src);
        let head = br.fill_buf().map_err(|source| IoError::Read {
            path: name.to_path_buf(),
            line: 0,
            source,
        })?;
        let gz = head.len() >= 2 && head[0] == 0x1f && head[1] == 0x8b;
        let inner: Box<dyn BufRead> = if gz {
            Box::new(std::io::BufReader::with_capacity(
                1 << 16,
                flate2::read::MultiGzDecoder::new(br),
            ))
        } else {
            Box::new(br)
        };
        Ok(Self {
            path: name.to_path_buf(),
            inner,
            record: 0,
            prev_t_s: None,
            failed: false,
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Fills `rec` from the source: Ok(n) with n < len only at the end of the input.
    fn fill(&mut self, rec: &mut [u8]) -> Result<usize, IoError> {
        let mut got = 0;
        while let Some(dst) = rec.get_mut(got..).filter(|d| !d.is_empty()) {
            match self.inner.read(dst) {
                Ok(0) => break,
                Ok(n) => got += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(source) => {
                    return Err(IoError::Read {
                        path: self.path.clone(),
                        line: self.record + 1,
                        source,
                    })
                }
            }
        }
        Ok(got)
    }

    fn read(&mut self) -> Result<Option<(ImuSample, usize)>, IoError> {
        let mut rec = [0u8; IMU_BIN_RECORD_BYTES];
        let got = self.fill(&mut rec)?;
        if got == 0 {
            return Ok(None);
        }
        let k = self.record;
        if got < IMU_BIN_RECORD_BYTES {
            let total = k * IMU_BIN_RECORD_BYTES + got;
            return Err(IoError::Format {
                path: self.path.clone(),
                line: k + 1,
                message: format!(
                    "truncated record: {total} bytes is not a whole number of {IMU_BIN_RECORD_BYTES}-byte records"
                ),
            });
        }
        let mut v = [0.0; 7];
        for (i, (x, b)) in v.iter_mut().zip(rec.chunks_exact(8)).enumerate() {
            let bytes: [u8; 8] = b.try_into().unwrap_or([0; 8]);
            *x = f64::from_le_bytes(bytes);
            if !x.is_finite() {
                return Err(IoError::NonFinite {
                    path: self.path.clone(),
                    line: k + 1,
                    column: i + 1,
                    name: IMU_NAMES[i].to_string(),
                    text: format!("{x}"),
                });
            }
        }
        if let Some(prev) = self.prev_t_s {
            if v[0] <= prev {
                return Err(IoError::NonMonotonicTime {
                    path: self.path.clone(),
                    line: k + 1,
                    column: 1,
                    name: IMU_NAMES[0].to_string(),
                    t_s: v[0],
                    prev_t_s: prev,
                    prev_line: k,
                });
            }
        }
        self.prev_t_s = Some(v[0]);
        self.record = k + 1;
        Ok(Some((
            ImuSample {
                t_s: v[0],
                dtheta_rad: [v[1], v[2], v[3]],
                dv_mps: [v[4], v[5], v[6]],
                temperature_c: f64::NAN,
            },
            k + 1,
        )))
    }
}

impl Iterator for ImuBinReader {
    type Item = Result<(ImuSample, usize), IoError>;

    /// The next sample and its record number; after an error, `None`.
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

/// Writes IMU samples in the binary format of [`read_imu_bin`] (temperature not written;
/// gzip when the path ends in `.gz`). Bit-exact round trip.
pub fn write_imu_bin(path: impl AsRef<Path>, samples: &[ImuSample]) -> Result<(), IoError> {
    write_with(path.as_ref(), |w| {
        for s in samples {
            for v in [
                s.t_s,
                s.dtheta_rad[0],
                s.dtheta_rad[1],
                s.dtheta_rad[2],
                s.dv_mps[0],
                s.dv_mps[1],
                s.dv_mps[2],
            ] {
                w.write_all(&v.to_le_bytes())?;
            }
        }
        Ok(())
    })
}
