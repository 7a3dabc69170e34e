//! GNSS receiver log files as run inputs: NMEA 0183 logs (`[gnss] format = "nmea"`: GGA,
//! RMC, GST, VTG) and u-blox UBX logs (`format = "ubx"`: NAV-PVT), read with the parsers the
//! bridge uses ([`super::gnss::NmeaAssembler`], [`super::gnss::GnssStream`]); options in
//! `[gnss.log]` ([`GnssLogOptions`]).
//!
//! # NMEA
//! One sentence per line (gzip accepted; blank lines and lines not starting with `$` or `!`
//! are skipped). Time: UTC time of day of each epoch with the RMC date (carried over between
//! epochs) converted to GPS time with the leap seconds of [`super::gpstime`] at each epoch's
//! UTC date (a log crossing a leap second stays on GPS time; the 23:59:60 epoch itself is
//! skipped as a bad sentence), or with `leap_seconds` throughout; returned as GPS seconds of
//! the week of the first fix, with that week. Epochs before the first RMC date cannot be timed and are skipped (counted, warned).
//! Position sigmas: GST latitude/longitude/altitude sigmas; an epoch without GST gets
//! `hdop_uere_m` x HDOP when stated, else `default_sigma_ned_m` (warned once), else the read
//! fails naming the line. Velocity: RMC (or VTG) speed over ground and course, down velocity 0,
//! with sigmas `vel_sigma_mps = [horizontal, vertical]`; without them the velocity is not used
//! (warned once).
//!
//! # UBX
//! The file's bytes go through the bridge's stream splitter (UBX, NMEA and RTCM interleaved);
//! NAV-PVT packets become fixes (`iTOW`, lat/lon/height above the ellipsoid, `hAcc`/`vAcc`,
//! `velN/E/D`, `sAcc`); NMEA sentences in a UBX log are ignored (counted, warned). Times are
//! GPS seconds of week (`iTOW`), continued past 604800 across a week rollover. NAV-PVT has no
//! GPS week: it comes from the first packet whose UTC date and time are flagged valid,
//! converted to GPS time with the leap seconds (table or `leap_seconds`); without one the week
//! is unknown (warned).
//!
//! # Both
//! Fixes without a position fix (`NoFix`) and with an RTKLIB-numbered quality above
//! `[gnss] max_q` are dropped and counted. Bad sentences (checksum, malformed field) and bad
//! packets are skipped and counted, with a warning naming the first one's line (NMEA) or byte
//! offset (UBX); with `strict = true` the first one is an error instead.

mod nmea_log;
mod ubx_log;

pub use nmea_log::NmeaLogReader;
pub use ubx_log::{UbxLogReader, UBX_WEEK_LOOKAHEAD};

use super::gpstime::SECONDS_PER_WEEK;
use super::IoError;
use nav_core::types::{FixQuality, GnssFix};
use std::path::{Path, PathBuf};

/// Options of NMEA and UBX log files (`[gnss.log]`, all optional).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GnssLogOptions {
    /// NMEA: position sigmas north, east, down (m) for epochs without GST (and without
    /// `hdop_uere_m`); warned once when used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub default_sigma_ned_m: Option<[f64; 3]>,
    /// NMEA: without GST, sigma north = east = HDOP x this, down = 1.5 x HDOP x this, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hdop_uere_m: Option<f64>,
    /// NMEA: sigmas of the speed/course velocity, `[horizontal, vertical]` m/s (NMEA has no
    /// vertical velocity: the down velocity is 0 with the vertical sigma); absent: the NMEA
    /// velocity is not used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vel_sigma_mps: Option<[f64; 2]>,
    /// NMEA: GPS - UTC in s for the whole log (default: from the leap-second table at each
    /// epoch's UTC date).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub leap_seconds: Option<i64>,
    /// Stop at the first bad sentence or packet instead of skipping it.
    #[serde(default)]
    pub strict: bool,
}

/// Fixes of an NMEA or UBX log file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GnssLogRecord {
    /// Fixes kept, time order (GPS seconds of [`Self::week`], or of the first fix's week).
    pub fixes: Vec<GnssFix>,
    /// Where each fix ended: 1-based line (NMEA) or 0-based byte offset of the packet's last
    /// byte (UBX).
    pub places: Vec<usize>,
    /// GPS week of the first fix (NMEA: from the RMC date; UBX: from the first NAV-PVT with
    /// a valid UTC date and time; `None` when there is none).
    pub week: Option<i64>,
    /// Fixes dropped as no fix or by `max_q`.
    pub dropped_by_quality: usize,
    /// Bad sentences or packets skipped.
    pub bad_skipped: usize,
    /// Things the user should know (each said once).
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

fn fmt_err(path: &Path, line: usize, message: impl Into<String>) -> IoError {
    IoError::Format {
        path: path.to_path_buf(),
        line,
        message: message.into(),
    }
}

fn sig_ok(v: &[f64]) -> bool {
    v.iter().all(|s| s.is_finite() && *s > 0.0)
}

/// Continues seconds of week past 604800 (and keeps order) across week rollovers.
struct Unwrap {
    weeks: f64,
    last: Option<f64>,
}

impl Unwrap {
    fn new() -> Self {
        Self {
            weeks: 0.0,
            last: None,
        }
    }
    fn apply(&mut self, sow: f64) -> f64 {
        if let Some(l) = self.last {
            if sow + self.weeks < l - SECONDS_PER_WEEK / 2.0 {
                self.weeks += SECONDS_PER_WEEK;
            }
        }
        let t = sow + self.weeks;
        self.last = Some(t);
        t
    }
}

/// Keeps a fix when it is a fix of quality within `max_q`; counts the others.
fn keep(f: &GnssFix, max_q: u8, dropped: &mut usize) -> bool {
    let ok = f.quality != FixQuality::NoFix && (f.quality as u8) <= max_q;
    if !ok {
        *dropped += 1;
    }
    ok
}

/// Reads an NMEA 0183 log (see the module notes; [`NmeaLogReader`] collected); `max_q` as
/// `[gnss] max_q`.
pub fn read_nmea_log(
    path: impl AsRef<Path>,
    opts: &GnssLogOptions,
    max_q: u8,
) -> Result<GnssLogRecord, IoError> {
    let mut rd = NmeaLogReader::open(path, opts, max_q)?;
    let mut out = GnssLogRecord::default();
    for r in &mut rd {
        let (fix, line) = r?;
        out.fixes.push(fix);
        out.places.push(line);
    }
    out.week = rd.week();
    out.dropped_by_quality = rd.dropped_by_quality();
    out.bad_skipped = rd.bad_skipped();
    out.warnings = rd.warnings().to_vec();
    out.path = rd.path().to_path_buf();
    Ok(out)
}

/// Reads a u-blox UBX log (see the module notes; [`UbxLogReader`] collected); `max_q` as
/// `[gnss] max_q`.
pub fn read_ubx_log(
    path: impl AsRef<Path>,
    opts: &GnssLogOptions,
    max_q: u8,
) -> Result<GnssLogRecord, IoError> {
    let mut rd = UbxLogReader::open(path, opts, max_q)?;
    let mut out = GnssLogRecord::default();
    for r in &mut rd {
        let (fix, off) = r?;
        out.fixes.push(fix);
        out.places.push(off);
    }
    out.week = rd.week();
    out.dropped_by_quality = rd.dropped_by_quality();
    out.bad_skipped = rd.bad_skipped();
    out.warnings = rd.warnings().to_vec();
    out.path = rd.path().to_path_buf();
    Ok(out)
}
