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

/// The rows' tick clock against the logger's clock, from the tag pairs (see
/// [`tick_clock_fit`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TickClockFit {
    /// Arrival lag of the first row: logger time since the file was opened minus the row's
    /// tick since the first row's tick, at the first row, ms (lower envelope).
    pub lag_ms: f64,
    /// Rate of the lag's lower envelope: how much faster the logger's clock runs than the
    /// rows' ticks, parts per million.
    pub rate_ppm: f64,
    /// RMS of the envelope points about the fitted line, ms.
    pub rms_ms: f64,
    /// Largest lag seen (envelope plus buffering), ms.
    pub max_lag_ms: f64,
    /// Tag pairs matched to a row.
    pub pairs_used: usize,
    /// Envelope points fitted (one per window).
    pub windows: usize,
}

/// Fits the rows' ticks against the tag's arrival times: each tag pair (ms since open, bytes
/// logged) is matched to the last row complete at that byte count; its lag is the pair's time
/// minus the row's tick (both from the first row); the smallest lag per `window_ms` of ticks
/// (the rows that waited least in buffers) is fitted with a straight line. `rows` holds each
/// row's end position in the LOGGED byte stream (count the line ends as they were logged) and
/// its tick, ms, in file order. `None` with fewer than two windows.
///
/// A rate near 0 says the ticks run at the logger's rate: stretching the tick span to the tag
/// span is then wrong by (tag span / tick span - 1) whenever the first row did not arrive
/// when the file was opened.
pub fn tick_clock_fit(tag: &TimeTag, rows: &[(u64, f64)], window_ms: f64) -> Option<TickClockFit> {
    let tick0 = rows.first()?.1;
    let mut env: Vec<(f64, f64)> = Vec::new();
    let (mut used, mut max_lag, mut k) = (0usize, f64::NEG_INFINITY, 0usize);
    for &(ms, pos) in &tag.pairs {
        // advance to the last row ending at or before `pos`
        while rows.get(k + 1).is_some_and(|r| r.0 <= u64::from(pos)) {
            k += 1;
        }
        let Some(&(end, tick)) = rows.get(k) else {
            break;
        };
        if end > u64::from(pos) {
            continue;
        }
        let t = tick - tick0;
        let lag = f64::from(ms) - t;
        used += 1;
        max_lag = max_lag.max(lag);
        let w = (t / window_ms).floor();
        match env.last_mut() {
            Some(last) if (last.0 / window_ms).floor() == w => {
                if lag < last.1 {
                    *last = (t, lag);
                }
            }
            _ => env.push((t, lag)),
        }
    }
    if env.len() < 2 {
        return None;
    }
    let n = env.len() as f64;
    let mx = env.iter().map(|p| p.0).sum::<f64>() / n;
    let my = env.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = env.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = env.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    let lag0 = my - slope * mx;
    let rms = (env
        .iter()
        .map(|p| (p.1 - lag0 - slope * p.0).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    Some(TickClockFit {
        lag_ms: lag0,
        rate_ppm: slope * 1e6,
        rms_ms: rms,
        max_lag_ms: max_lag,
        pairs_used: used,
        windows: env.len(),
    })
}
