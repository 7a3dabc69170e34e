//! RTKLIB demo5 time-tag files (`<log>.tag`), written next to a stream log by str2str/rtknavi.
//!
//! Layout (little-endian), as written by RTKLIB demo5 and read by rtklibexplorer's
//! `convert_imu_file.py`:
//!
//! | bytes | content |
//! |---|---|
//! | 0..60 | text header `"TIMETAG RTKLIB demo5"`, NUL padded |
//! | 60..64 | `uint32` tick of the logging computer when the file was opened, ms |
//! | 64..68 | `uint32` start time, whole seconds since 1970-01-01 in the GPST time scale (`gtime_t.time`) |
//! | 68..76 | `f64` fraction of the start second |
//! | 76.. | `(uint32 tick_ms, uint32 file_pos)` pairs: ms since the file was opened at which the log reached byte `file_pos` |
//!
//! Older builds wrote an 8-byte `time_t` (pairs from byte 80); that variant is recognised by
//! plausibility (start between 1980 and 2100, fraction in [0, 1)). A partial trailing pair is
//! ignored and reported in [`TimeTag::trailing_bytes`].

use super::gpstime::gpst_week_sow_from_epoch_s;
use super::IoError;
use std::path::Path;

/// The content of a time-tag file.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeTag {
    /// Header text (up to the first NUL), e.g. "TIMETAG RTKLIB demo5".
    pub header: String,
    /// Logging computer's tick when the file was opened, ms.
    pub tick_at_open_ms: u32,
    /// GPS week of the start time.
    pub start_week: i64,
    /// GPS seconds of week of the start time, s.
    pub start_sow_s: f64,
    /// (ms since open, file position in bytes) pairs in file order.
    pub pairs: Vec<(u32, u32)>,
    /// Bytes after the last complete pair (0 for a complete file).
    pub trailing_bytes: usize,
}

impl TimeTag {
    /// Tick of the last pair, ms since the file was opened (0 without pairs).
    pub fn last_tick_ms(&self) -> u32 {
        self.pairs.last().map_or(0, |p| p.0)
    }

    /// GPS seconds of week (of `start_week`) of the last tag, s.
    pub fn end_sow_s(&self) -> f64 {
        self.start_sow_s + f64::from(self.last_tick_ms()) * 1e-3
    }
}

fn fmt_err(path: &Path, message: impl Into<String>) -> IoError {
    IoError::Format {
        path: path.to_path_buf(),
        line: 0,
        message: message.into(),
    }
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    b.get(at..at + 4)
        .and_then(|s| <[u8; 4]>::try_from(s).ok())
        .map(u32::from_le_bytes)
}

fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    b.get(at..at + 8)
        .and_then(|s| <[u8; 8]>::try_from(s).ok())
        .map(u64::from_le_bytes)
}

fn f64_at(b: &[u8], at: usize) -> Option<f64> {
    u64_at(b, at).map(f64::from_bits)
}

/// Start times between 1980 and 2100, fraction in [0, 1).
fn plausible(secs: f64, frac: f64) -> bool {
    (315_964_800.0..4_102_444_800.0).contains(&secs) && (0.0..1.0).contains(&frac)
}

/// Parses the bytes of a time-tag file (`path` is used in errors).
pub fn parse_time_tag(path: &Path, b: &[u8]) -> Result<TimeTag, IoError> {
    const HDR: usize = 60;
    if b.len() < 76 {
        return Err(fmt_err(
            path,
            format!(
                "time-tag file too short ({} bytes, header needs 76)",
                b.len()
            ),
        ));
    }
    let head = b.get(..HDR).unwrap_or_default();
    let end = head.iter().position(|&c| c == 0).unwrap_or(HDR);
    let header = String::from_utf8_lossy(head.get(..end).unwrap_or_default()).into_owned();
    if !header.starts_with("TIMETAG RTKLIB") {
        return Err(fmt_err(
            path,
            format!("not an RTKLIB time-tag file: header {header:?} does not start with \"TIMETAG RTKLIB\""),
        ));
    }
    let tick_at_open_ms = u32_at(b, 60).unwrap_or(0);
    // 4-byte time_t (demo5) first, then the 8-byte variant.
    let t4 = u32_at(b, 64).map(f64::from).unwrap_or(-1.0);
    let f4 = f64_at(b, 68).unwrap_or(-1.0);
    let (start, data_at) = if plausible(t4, f4) {
        (t4 + f4, 76)
    } else {
        let t8 = u64_at(b, 64).map(|v| v as f64).unwrap_or(-1.0);
        let f8 = f64_at(b, 72).unwrap_or(-1.0);
        if b.len() >= 80 && plausible(t8, f8) {
            (t8 + f8, 80)
        } else {
            return Err(fmt_err(
                path,
                format!("implausible start time in the tag header (uint32 {t4} + {f4} s)"),
            ));
        }
    };
    let body = b.get(data_at..).unwrap_or_default();
    let mut pairs = Vec::with_capacity(body.len() / 8);
    for (k, ch) in body.chunks_exact(8).enumerate() {
        let tick = u32_at(ch, 0).unwrap_or(0);
        let pos = u32_at(ch, 4).unwrap_or(0);
        if let Some(&(pt, pp)) = pairs.last() {
            if tick < pt || pos < pp {
                return Err(fmt_err(
                    path,
                    format!(
                        "time-tag pair {} (byte {}) goes backwards: tick {tick} ms, position {pos} after tick {pt} ms, position {pp}",
                        k + 1,
                        data_at + 8 * k
                    ),
                ));
            }
        }
        pairs.push((tick, pos));
    }
    let (start_week, start_sow_s) = gpst_week_sow_from_epoch_s(start);
    Ok(TimeTag {
        header,
        tick_at_open_ms,
        start_week,
        start_sow_s,
        pairs,
        trailing_bytes: body.len() % 8,
    })
}

/// Reads a time-tag file.
pub fn read_time_tag(path: impl AsRef<Path>) -> Result<TimeTag, IoError> {
    let path = path.as_ref();
    let b = std::fs::read(path).map_err(|source| IoError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    parse_time_tag(path, &b)
}
