//! The live status line of `record`, `stream` and `send`.

use nav_core::wire::DecoderStats;
use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

/// Prints a one-line status to stderr at most every `period`: rewritten in place on a
/// terminal, one plain line per update (no terminal control codes) when stderr is a file or
/// a pipe.
pub struct StatusLine {
    period: Duration,
    last: Instant,
    last_frames: u64,
    enabled: bool,
    terminal: bool,
}

impl StatusLine {
    /// A status line printing every `period` (never when `enabled` is false).
    pub fn new(period: Duration, enabled: bool) -> Self {
        Self {
            period,
            last: Instant::now(),
            last_frames: 0,
            enabled,
            terminal: std::io::stderr().is_terminal(),
        }
    }

    /// Prints `text` if the period has elapsed (or `force`); `frames` is the running frame
    /// count used for the frames/s figure, which is prepended.
    pub fn update(&mut self, frames: u64, force: bool, text: impl FnOnce() -> String) {
        let dt = self.last.elapsed();
        if !self.enabled || (!force && dt < self.period) {
            return;
        }
        let rate = (frames - self.last_frames.min(frames)) as f64 / dt.as_secs_f64().max(1e-9);
        self.last = Instant::now();
        self.last_frames = frames;
        let mut e = std::io::stderr().lock();
        let _ = if self.terminal {
            // back to the line's start, the line cleared
            write!(e, "\r\x1b[2K{rate:7.1} frames/s  {}", text())
        } else {
            writeln!(e, "{rate:7.1} frames/s  {}", text())
        };
        let _ = e.flush();
    }

    /// Prints `text` as a line of its own on stderr ([`Self::message_line`]).
    pub fn message(&self, text: &str) {
        eprint!("{}", self.message_line(text));
    }

    /// `text` as a line of its own: on a terminal with the status line shown, the status line
    /// is ended first so the message does not run into it; into a file or a pipe (whole lines
    /// already) a plain line, no blank line before it.
    pub fn message_line(&self, text: &str) -> String {
        if self.enabled && self.terminal {
            format!("\n{text}\n")
        } else {
            format!("{text}\n")
        }
    }

    /// Ends the line (on a terminal: a file or pipe has whole lines already).
    pub fn finish(&self) {
        if self.enabled && self.terminal {
            eprintln!();
        }
    }
}

/// Counters in one line: frames, CRC errors, other rejections, frames lost by sequence.
pub fn decoder_summary(s: &DecoderStats) -> String {
    format!(
        "ok {}  crc errors {}  other rejected {}  lost (seq gaps) {}  bytes {}",
        s.frames_ok,
        s.crc_errors,
        s.rejected() - s.crc_errors,
        s.lost(),
        s.bytes
    )
}

/// A multi-line report of every decoder counter.
pub fn decoder_report(s: &DecoderStats) -> String {
    let names = ["imu", "gnss", "nav", "config", "health"];
    let mut out = format!(
        "bytes {}\nframes delivered {}\nrejected chunks {} (cobs {}, overflow {}, length {}, crc {}, version {}, unknown type {}, invalid field {}, truncated {})\n",
        s.bytes,
        s.frames_ok,
        s.rejected(),
        s.cobs_errors,
        s.overflows,
        s.length_errors,
        s.crc_errors,
        s.version_mismatches,
        s.unknown_types,
        s.invalid_fields,
        s.truncated
    );
    for (i, n) in names.iter().enumerate() {
        out.push_str(&format!(
            "  {n:7} delivered {:8}  lost {:6}  restarts {:3}  backwards {:3}\n",
            s.frames_ok_by_stream[i],
            s.lost_by_stream[i],
            s.restarts_by_stream[i],
            s.backwards_by_stream[i]
        ));
    }
    out
}

/// An error and its causes on one line, each cause said once: a cause whose text the message
/// so far already contains (an error type that prints its source in its own message, as
/// `nav_io::IoError` does) is not repeated, compared without its trailing line end (a message
/// that adds a hint after its cause trims it).
pub fn error_chain(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        let text = text.trim_end();
        if text.is_empty() || out.contains(text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(text);
    }
    out
}
