//! The sub-commands of the `hw-bridge` CLI, as library functions (the binary only parses the
//! command line).
//!
//! One file per job: [`record`](fn@record), [`replay`](fn@replay) (and the host filter on a
//! replay's frames, [`run_filter_on_frames`]), [`send`](fn@send), [`stream`](fn@stream).

mod filter;
mod record;
mod replay;
mod send;
mod stream;

pub use filter::*;
pub use record::*;
pub use replay::*;
pub use send::*;
pub use stream::*;

use std::time::Duration;

/// Default baud rate (a 200 Hz IMU stream needs at least 230400, see docs/wire-protocol.md).
pub const DEFAULT_BAUD: u32 = 921_600;

/// Default GPS - UTC leap seconds for NMEA input (`stream`, `replay --input gnss`), s.
pub const DEFAULT_LEAP_SECONDS: i64 = 18;

/// Slowest replay speed factor accepted (`--speed`, `--rate-x`).
pub const MIN_SPEED: f64 = 1e-3;
/// Fastest replay speed factor accepted (`--speed`, `--rate-x`).
pub const MAX_SPEED: f64 = 1e6;
/// Longest duration or timeout accepted on the command line, s (about 31.7 years: beyond it a
/// number is a typo, and every one of them converts to a `Duration`).
pub const MAX_SECONDS: f64 = 1e9;

fn parse_f64(s: &str) -> Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .map_err(|e| format!("{s:?} is not a number ({e})"))
}

/// Parses a speed factor: a number in [[`MIN_SPEED`], [`MAX_SPEED`]] (clap value parser of
/// `replay --speed` and `send --rate-x`).
pub fn parse_speed(s: &str) -> Result<f64, String> {
    let v = parse_f64(s)?;
    if (MIN_SPEED..=MAX_SPEED).contains(&v) {
        Ok(v)
    } else {
        Err(format!(
            "{v} is outside [{MIN_SPEED}, {MAX_SPEED}] (a speed factor)"
        ))
    }
}

/// Parses a duration in seconds: a number in [0, [`MAX_SECONDS`]] (NaN and infinities are
/// refused).
pub fn parse_seconds(s: &str) -> Result<f64, String> {
    let v = parse_f64(s)?;
    if (0.0..=MAX_SECONDS).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} is outside [0, {MAX_SECONDS}] s"))
    }
}

/// Parses a timeout in seconds: a number in (0, [`MAX_SECONDS`]].
pub fn parse_timeout(s: &str) -> Result<f64, String> {
    let v = parse_seconds(s)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err("a timeout must be positive".into())
    }
}

/// Seconds (validated by the parsers above, or any f64: clamped to [0, `MAX_SECONDS`], NaN as
/// 0) as a `Duration`, without panicking.
pub fn secs(s: f64) -> Duration {
    Duration::try_from_secs_f64(s.clamp(0.0, MAX_SECONDS)).unwrap_or(Duration::ZERO)
}
