//! `record`: raw bytes from a port into a capture file.

use super::*;
use crate::capture::{CaptureHeader, CaptureWriter, Record};
use crate::serial;
use crate::status::{decoder_summary, StatusLine};
use anyhow::Context;
use nav_core::wire::{DecoderStats, FrameDecoder};
use nav_engine::run::interrupt;
use nav_engine::run::outdir::StagedFile;
use std::io::{BufWriter, Read};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// `record` options (the command line's `hw-bridge record` arguments convert into them).
#[derive(Debug, Clone, PartialEq)]
pub struct RecordOptions {
    /// Serial port (device path; pseudo-terminals by path).
    pub port: String,
    /// Baud rate of `port`, bit/s.
    pub baud: u32,
    /// Capture file to write.
    pub out: PathBuf,
    /// Stop after this many seconds (None: no time limit).
    pub duration_s: Option<f64>,
    /// Stop when no byte arrived for this many seconds after the first byte (before it, only
    /// `duration_s` and `first_byte_timeout_s` stop the recording).
    pub idle_exit_s: Option<f64>,
    /// Fail when no byte at all arrived within this many seconds of the start.
    pub first_byte_timeout_s: Option<f64>,
    /// When the port is lost, try to reopen it for at most this many seconds, then stop and
    /// report the capture incomplete; None: retry until another stop condition.
    pub reopen_timeout_s: Option<f64>,
    /// The recording starts before the sender: every stream begins at sequence number 0, so
    /// frames lost before a stream's first delivered frame are counted too (stored in the
    /// capture header, used by `replay`).
    pub streams_from_start: bool,
    /// Do not decode frames for the status line (e.g. when recording a GNSS receiver).
    pub raw: bool,
    /// Open the port without the exclusive lock, so another program can use it too.
    pub shared: bool,
    /// No live status line.
    pub quiet: bool,
    /// Replace an existing file (or link) at `out`, and remove a leftover `OUT.partial` that
    /// no recorder is writing (without it both are refused, nothing written).
    pub force: bool,
}

impl RecordOptions {
    /// Recording `port` into `out` at [`DEFAULT_BAUD`], quiet, no stop condition set (set
    /// `duration_s` or `idle_exit_s`).
    pub fn new(port: impl Into<String>, out: impl Into<PathBuf>) -> Self {
        Self {
            port: port.into(),
            baud: DEFAULT_BAUD,
            out: out.into(),
            duration_s: None,
            idle_exit_s: None,
            first_byte_timeout_s: None,
            reopen_timeout_s: None,
            streams_from_start: false,
            raw: false,
            shared: false,
            quiet: true,
            force: false,
        }
    }
}

fn now_unix_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

/// What `record` captured.
#[derive(Debug, Clone, Default)]
pub struct RecordOutcome {
    /// Live decoder counters (zero with `--raw`).
    pub stats: DecoderStats,
    /// Data records written.
    pub records: u64,
    /// Data bytes written.
    pub bytes: u64,
    /// Link-reset events written (port lost).
    pub link_resets: u64,
    /// Why the capture is incomplete (the port vanished and did not come back within
    /// `--reopen-timeout`); `None` when the recording ended by a stop condition.
    pub incomplete: Option<String>,
    /// The signal (`SIGINT`: Ctrl-C, `SIGTERM`) that ended the recording, once
    /// [`nav_engine::run::interrupt::install`] is in place: a stop condition like
    /// `duration_s`, the capture complete up to it.
    pub stopped_by: Option<String>,
}

/// What a SIGINT/SIGTERM received by [`record`] does (the message on stderr): the normal end
/// of a recording, the capture complete.
pub const RECORD_KEPT_ON_STOP: &str = "the recording ends here, its capture complete (exit 0)";

/// `record`: raw bytes with receive timestamps into a capture file, live status on stderr.
/// When the port fails (unplugged, pty closed) a link-reset record is written and the port is
/// reopened until it comes back or a stop condition is met; SIGINT (Ctrl-C) and SIGTERM are
/// stop conditions once [`nav_engine::run::interrupt::install`] is in place.
///
/// The capture is written as `OUT.partial` (created new, locked: a second recorder of the
/// same file refuses) and moved to `OUT` at the end ([`StagedFile`]): an existing `OUT` is
/// refused unless [`RecordOptions::force`], a link there is replaced and never written
/// through, and a recording that fails or is killed after data arrived leaves them in
/// `OUT.partial` (the error says so).
pub fn record(a: &RecordOptions) -> anyhow::Result<RecordOutcome> {
    let _stoppable = interrupt::Stoppable::enter();
    // the capture must not be written over its own input (the port's device file)
    nav_engine::run::outdir::check_not_input(&a.out, Path::new(&a.port))?;
    let staged = StagedFile::create(&a.out, a.force)?;
    let mut out = RecordOutcome::default();
    match record_into(a, &staged, &mut out) {
        Ok(no_byte) => {
            staged.commit()?;
            if let Some(e) = no_byte {
                return Err(e);
            }
            Ok(out)
        }
        Err(e) if out.records + out.link_resets == 0 => {
            // nothing received: no capture
            let _ = std::fs::remove_file(staged.partial());
            Err(e)
        }
        Err(e) => Err(e.context(format!(
            "the {} record(s) received so far are kept in {}",
            out.records,
            staged.partial().display()
        ))),
    }
}

/// The port lost at `lost_at`: waits a little and tries to reopen it (`Ok(None)`: not back
/// yet); `Err(why)` once `reopen` (`--reopen-timeout`) has passed.
fn try_reopen(
    a: &RecordOptions,
    reopen: Option<Duration>,
    lost_at: Option<Instant>,
    timeout: Duration,
) -> Result<Option<Box<dyn serialport::SerialPort>>, String> {
    if let (Some(d), Some(t)) = (reopen, lost_at) {
        if t.elapsed() >= d {
            return Err(format!(
                "port {} lost and not back within --reopen-timeout {} s",
                a.port,
                d.as_secs_f64()
            ));
        }
    }
    std::thread::sleep(Duration::from_millis(100));
    Ok(serial::open_with(&a.port, a.baud, timeout, a.shared).ok())
}

/// How long a read of the port waits for bytes.
const READ_TIMEOUT: Duration = Duration::from_millis(50);

/// The capture writer of [`record`] on `staged` (its header written) and the port opened.
#[allow(clippy::type_complexity)]
fn start_capture(
    a: &RecordOptions,
    staged: &StagedFile,
) -> anyhow::Result<(
    CaptureWriter<BufWriter<std::fs::File>>,
    Box<dyn serialport::SerialPort>,
)> {
    let header = CaptureHeader {
        port: a.port.clone(),
        baud: a.baud,
        start_unix_ns: now_unix_ns(),
        tool: format!("hw-bridge {}", env!("CARGO_PKG_VERSION")),
        streams_from_start: a.streams_from_start,
    };
    let w = CaptureWriter::new(BufWriter::new(staged.writer()?), &header)
        .with_context(|| format!("writing {}", staged.partial().display()))?;
    let port = serial::open_with(&a.port, a.baud, READ_TIMEOUT, a.shared)?;
    // One line, even with --quiet: scripts (and the pty test) wait for it before sending.
    eprintln!(
        "recording {} -> {} (written as {} until the recording ends; Ctrl-C ends it)",
        a.port,
        a.out.display(),
        staged.partial().display()
    );
    Ok((w, port))
}

/// The recording loop of [`record`] into `staged`: `Ok(Some(error))` when no byte arrived
/// within `--first-byte-timeout` (the capture, without data, is still moved into place).
fn record_into(
    a: &RecordOptions,
    staged: &StagedFile,
    out: &mut RecordOutcome,
) -> anyhow::Result<Option<anyhow::Error>> {
    let part = staged.partial();
    let werr =
        |e: std::io::Error| anyhow::Error::new(e).context(format!("writing {}", part.display()));
    let timeout = READ_TIMEOUT;
    let (mut w, port) = start_capture(a, staged)?;
    let mut port = Some(port);
    let start = Instant::now();
    let mut last_data: Option<Instant> = None;
    let mut lost_at: Option<Instant> = None;
    let mut dec = FrameDecoder::new();
    if a.streams_from_start {
        dec.expect_stream_starts();
    }
    let mut status = StatusLine::new(Duration::from_millis(500), !a.quiet);
    let mut buf = vec![0u8; 8192];
    let duration = a.duration_s.map(secs);
    let idle = a.idle_exit_s.map(secs);
    let first_byte = a.first_byte_timeout_s.map(secs);
    let reopen = a.reopen_timeout_s.map(secs);
    let t_ns = |start: Instant| u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX);
    loop {
        if let Some(sig) = interrupt::requested() {
            out.stopped_by = Some(interrupt::signal_name(sig));
            break;
        }
        let now = Instant::now();
        let elapsed = now.saturating_duration_since(start);
        if duration.is_some_and(|d| elapsed >= d) {
            break;
        }
        if let (Some(d), Some(last)) = (idle, last_data) {
            if now.saturating_duration_since(last) >= d {
                break;
            }
        }
        if let (Some(d), None) = (first_byte, last_data) {
            if elapsed >= d {
                w.flush().map_err(werr)?;
                return Ok(Some(anyhow::anyhow!(
                    "no byte from {} within --first-byte-timeout {} s (the capture {} holds no data)",
                    a.port,
                    d.as_secs_f64(),
                    a.out.display()
                )));
            }
        }
        let Some(p) = port.as_mut() else {
            match try_reopen(a, reopen, lost_at, timeout) {
                Err(why) => {
                    out.incomplete = Some(why);
                    break;
                }
                Ok(p) => {
                    if p.is_some() {
                        lost_at = None;
                    }
                    port = p;
                }
            }
            continue;
        };
        // A read of 0 bytes after the port polled readable is an end of file: the other side
        // hung up (a pty whose master closed). It is a lost link, like an error.
        let read = match p.read(&mut buf) {
            Ok(0) => Err(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "end of file (the other side hung up)",
            )),
            r => r,
        };
        match read {
            Ok(n) => {
                let data = buf.get(..n).unwrap_or_default();
                last_data = Some(Instant::now());
                w.write(&Record::Data {
                    t_ns: t_ns(start),
                    bytes: data.to_vec(),
                })
                .map_err(werr)?;
                w.flush().map_err(werr)?;
                out.records += 1;
                out.bytes += n as u64;
                if !a.raw {
                    dec.feed(data).for_each(drop);
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => {
                if !a.quiet {
                    status.message(&format!("port {}: {e}; reopening", a.port));
                }
                port = None;
                lost_at = Some(Instant::now());
                w.write(&Record::LinkReset { t_ns: t_ns(start) })
                    .map_err(werr)?;
                w.flush().map_err(werr)?;
                out.link_resets += 1;
                dec.reset_link();
            }
        }
        let s = *dec.stats();
        let el = start.elapsed().as_secs_f64();
        status.update(u64::from(s.frames_ok), false, || {
            format!("{el:7.1} s  {}", decoder_summary(&s))
        });
    }
    let s = *dec.stats();
    status.update(u64::from(s.frames_ok), true, || decoder_summary(&s));
    status.finish();
    w.flush().map_err(werr)?;
    out.stats = s;
    Ok(None)
}
