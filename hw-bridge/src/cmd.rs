//! The sub-commands of the `hw-bridge` CLI, as library functions (the binary only parses the
//! command line).

use crate::capture::{CaptureError, CaptureHeader, CaptureReader, CaptureWriter, Record};
use crate::frames::{case_payloads, FrameLog};
use crate::gnss::{GnssEvent, GnssStream, NmeaOptions};
use crate::outputs::{partial_name, rename, write_atomically, FrameFiles};
use crate::serial;
use crate::status::{decoder_report, decoder_summary, StatusLine};
use anyhow::{bail, Context};
use nav_core::types::GnssFix;
use nav_core::wire::{DecoderStats, Encoder, FrameDecoder, Payload, MAX_FRAME_LEN};
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Default baud rate (a 200 Hz IMU stream needs at least 230400, see docs/wire-protocol.md).
pub const DEFAULT_BAUD: u32 = 921_600;

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

/// `record` options.
#[derive(clap::Args, Debug, Clone)]
pub struct RecordArgs {
    /// Serial port (device path; pseudo-terminals by path).
    #[arg(long)]
    pub port: String,
    /// Baud rate.
    #[arg(long, default_value_t = DEFAULT_BAUD)]
    pub baud: u32,
    /// Capture file to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Stop after this many seconds.
    #[arg(long, value_parser = parse_seconds)]
    pub duration: Option<f64>,
    /// Stop when no byte arrived for this many seconds after the first byte (before it, only
    /// `--duration` and `--first-byte-timeout` stop the recording).
    #[arg(long, value_parser = parse_timeout)]
    pub idle_exit: Option<f64>,
    /// Fail (exit 1) when no byte at all arrived within this many seconds of the start.
    #[arg(long, value_parser = parse_timeout)]
    pub first_byte_timeout: Option<f64>,
    /// When the port is lost, try to reopen it for at most this many seconds, then stop and
    /// report the capture incomplete (exit 2); without it, retry until another stop condition.
    #[arg(long, value_parser = parse_timeout)]
    pub reopen_timeout: Option<f64>,
    /// The recording starts before the sender: every stream begins at sequence number 0, so
    /// frames lost before a stream's first delivered frame are counted too (stored in the
    /// capture header, used by `replay`).
    #[arg(long)]
    pub streams_from_start: bool,
    /// Do not decode frames for the status line (e.g. when recording a GNSS receiver).
    #[arg(long)]
    pub raw: bool,
    /// Open the port without the exclusive lock, so another program (e.g. `hw-bridge send`
    /// on the same emulated board's pty) can use it at the same time.
    #[arg(long)]
    pub shared: bool,
    /// No live status line.
    #[arg(long)]
    pub quiet: bool,
}

impl RecordArgs {
    /// Recording `port` into `out` with the defaults of the command line (no stop condition
    /// set: set `duration` or `idle_exit`).
    pub fn new(port: impl Into<String>, out: impl Into<PathBuf>) -> Self {
        Self {
            port: port.into(),
            baud: DEFAULT_BAUD,
            out: out.into(),
            duration: None,
            idle_exit: None,
            first_byte_timeout: None,
            reopen_timeout: None,
            streams_from_start: false,
            raw: false,
            shared: false,
            quiet: true,
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
}

/// `record`: raw bytes with receive timestamps into a capture file, live status on stderr.
/// When the port fails (unplugged, pty closed) a link-reset record is written and the port is
/// reopened until it comes back or a stop condition is met.
pub fn record(a: &RecordArgs) -> anyhow::Result<RecordOutcome> {
    let file = std::fs::File::create(&a.out)
        .with_context(|| format!("creating capture {}", a.out.display()))?;
    let header = CaptureHeader {
        port: a.port.clone(),
        baud: a.baud,
        start_unix_ns: now_unix_ns(),
        tool: format!("hw-bridge {}", env!("CARGO_PKG_VERSION")),
        streams_from_start: a.streams_from_start,
    };
    let werr =
        |e: std::io::Error| anyhow::Error::new(e).context(format!("writing {}", a.out.display()));
    let mut w = CaptureWriter::new(BufWriter::new(file), &header).map_err(werr)?;
    let timeout = Duration::from_millis(50);
    let mut port = Some(serial::open_with(&a.port, a.baud, timeout, a.shared)?);
    // One line, even with --quiet: scripts (and the pty test) wait for it before sending.
    eprintln!("recording {} -> {}", a.port, a.out.display());
    let start = Instant::now();
    let mut last_data: Option<Instant> = None;
    let mut lost_at: Option<Instant> = None;
    let mut dec = FrameDecoder::new();
    if a.streams_from_start {
        dec.expect_stream_starts();
    }
    let mut status = StatusLine::new(Duration::from_millis(500), !a.quiet);
    let mut buf = vec![0u8; 8192];
    let mut out = RecordOutcome::default();
    let duration = a.duration.map(secs);
    let idle = a.idle_exit.map(secs);
    let first_byte = a.first_byte_timeout.map(secs);
    let reopen = a.reopen_timeout.map(secs);
    let t_ns = |start: Instant| u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX);
    loop {
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
                bail!(
                    "no byte from {} within --first-byte-timeout {} s (the capture {} holds no data)",
                    a.port,
                    d.as_secs_f64(),
                    a.out.display()
                );
            }
        }
        let Some(p) = port.as_mut() else {
            if let (Some(d), Some(t)) = (reopen, lost_at) {
                if now.saturating_duration_since(t) >= d {
                    out.incomplete = Some(format!(
                        "port {} lost and not back within --reopen-timeout {} s",
                        a.port,
                        d.as_secs_f64()
                    ));
                    break;
                }
            }
            std::thread::sleep(Duration::from_millis(100));
            port = serial::open_with(&a.port, a.baud, timeout, a.shared).ok();
            if port.is_some() {
                lost_at = None;
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
                    eprintln!("\nport {}: {e}; reopening", a.port);
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
    Ok(out)
}

/// Default of `replay --max-gap`, s.
pub const DEFAULT_MAX_GAP_S: f64 = 10.0;

/// What `replay` decodes the capture as.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum InputKind {
    /// Wire-protocol frames (a navigation board or `hw-bridge send`).
    #[default]
    Frames,
    /// A GNSS receiver's NMEA and/or UBX output.
    Gnss,
}

/// `replay` options.
#[derive(clap::Args, Debug, Clone)]
pub struct ReplayArgs {
    /// Capture file written by `record`.
    pub capture: PathBuf,
    /// Replay at this multiple of the recorded timing, in [0.001, 1e6] (default: 1 with
    /// `--to-port`, else as fast as possible).
    #[arg(long, conflicts_with = "as_fast_as_possible", value_parser = parse_speed)]
    pub speed: Option<f64>,
    /// Longest pause between two records when pacing, in recorded seconds: a larger jump of
    /// the recorded time (a link down for minutes, a damaged timestamp) is paced as this long
    /// and counted. Timestamps going backwards are counted and not waited for.
    #[arg(long, default_value_t = DEFAULT_MAX_GAP_S, value_parser = parse_timeout)]
    pub max_gap: f64,
    /// Ignore the recorded timing.
    #[arg(long)]
    pub as_fast_as_possible: bool,
    /// Also write the recorded bytes, in the recorded chunks, to this port.
    #[arg(long)]
    pub to_port: Option<String>,
    /// Baud rate of `--to-port`.
    #[arg(long, default_value_t = DEFAULT_BAUD)]
    pub baud: u32,
    /// Directory for imu.txt, gnss.txt, nav.txt, health.txt and replay-summary.txt.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// What the capture contains.
    #[arg(long, value_enum, default_value_t = InputKind::Frames)]
    pub input: InputKind,
    /// GPS - UTC leap seconds for NMEA input.
    #[arg(long, default_value_t = 18)]
    pub leap_seconds: i64,
    /// Print every rejected chunk with its byte offset.
    #[arg(long)]
    pub verbose: bool,
    /// Run the host filter on the decoded IMU and GNSS frames as `host-sim run --config`
    /// does on files (same model, noise, initialisation, outages), writing its `nav.txt`,
    /// `std.txt`, `bias.txt`, `innovations.txt` and `metrics.json` into `--out`. The
    /// configuration's own data files (or `--case`'s) are read for the truth, week and
    /// outages; the IMU samples and GNSS fixes come from the capture.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// A case directory written by `host-sim simulate` (truth, outages, GPS week), as in
    /// `host-sim run --case`.
    #[arg(long, requires = "config")]
    pub case: Option<PathBuf>,
    /// Error-state model for `--config` (default: the configuration's).
    #[arg(long, value_enum, requires = "config")]
    pub model: Option<host_sim::run::Model>,
    /// f32 covariance (as on the MCU) for `--config`.
    #[arg(long, requires = "config")]
    pub f32: bool,
}

impl ReplayArgs {
    /// Arguments for decoding `capture` as fast as possible, without a port or outputs.
    pub fn new(capture: impl Into<PathBuf>) -> Self {
        Self {
            capture: capture.into(),
            speed: None,
            max_gap: DEFAULT_MAX_GAP_S,
            as_fast_as_possible: true,
            to_port: None,
            baud: DEFAULT_BAUD,
            out: None,
            input: InputKind::Frames,
            leap_seconds: 18,
            verbose: false,
            config: None,
            case: None,
            model: None,
            f32: false,
        }
    }
}

/// The result of a replay.
#[derive(Debug, Default)]
pub struct ReplayOutcome {
    /// Decoded frames (frame input).
    pub log: FrameLog,
    /// Decoder counters (frame input).
    pub stats: DecoderStats,
    /// GNSS fixes (GNSS receiver input).
    pub gnss_fixes: Vec<GnssFix>,
    /// Bytes in the capture.
    pub bytes: u64,
    /// Records in the capture.
    pub records: u64,
    /// Recorded duration (last record time), s.
    pub recorded_s: f64,
    /// A truncated last record, if any (every complete record was replayed).
    pub truncated: Option<String>,
    /// Why the replay is incomplete (a truncated or corrupt record ended it: every record
    /// before it was replayed); `None` when the whole capture was replayed.
    pub incomplete: Option<String>,
    /// Bytes of garbage skipped before the capture's magic.
    pub skipped_bytes: u64,
    /// Records identical to the previous one (same time and bytes, which a recorder cannot
    /// write): skipped, not replayed.
    pub duplicate_records: u64,
    /// Pacing: timestamps at or before the previous record's (replayed without waiting) and
    /// jumps longer than `--max-gap` (paced as `--max-gap`).
    pub timing: TimingStats,
    /// IMU samples left out of the host filter's input (`--config`) and of `imu.txt` because
    /// their time is not after the previous sample's (duplicated or reordered frames).
    pub imu_out_of_order: u64,
    /// GNSS fixes left out of the filter's input and `gnss.txt` for the same reason.
    pub gnss_out_of_order: u64,
    /// Wall time of the replay (decoding, and the filter run with `--config`), s.
    pub wall_s: f64,
    /// The host filter's run on the decoded frames (`--config`).
    pub filter: Option<FilterRun>,
}

/// Irregular timestamps met while replaying.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct TimingStats {
    /// Records whose time is before the previous record's.
    pub backwards: u64,
    /// Gaps longer than `--max-gap` (each paced as `--max-gap`).
    pub clamped_gaps: u64,
    /// Recorded time the pacing followed (gaps clamped, backward steps ignored), ns.
    pub paced_ns: u64,
}

/// Paces a replay: recorded record times in, the (recorded-time) instant each record is due
/// at out, with saturating arithmetic and validated steps.
#[derive(Debug, Clone)]
pub struct Pacer {
    max_gap_ns: u64,
    prev: u64,
    /// Counters.
    pub stats: TimingStats,
}

impl Pacer {
    /// A pacer allowing gaps up to `max_gap_s` (recorded seconds).
    pub fn new(max_gap_s: f64) -> Self {
        Self {
            max_gap_ns: u64::try_from(secs(max_gap_s).as_nanos()).unwrap_or(u64::MAX),
            prev: 0,
            stats: TimingStats::default(),
        }
    }

    /// The paced time of a record recorded at `t_ns`, ns since the capture start (the first
    /// record is measured from 0, the capture's start).
    pub fn advance(&mut self, t_ns: u64) -> u64 {
        match t_ns.checked_sub(self.prev) {
            None => self.stats.backwards += 1,
            Some(gap) if gap > self.max_gap_ns => {
                self.stats.clamped_gaps += 1;
                self.stats.paced_ns = self.stats.paced_ns.saturating_add(self.max_gap_ns);
            }
            Some(gap) => self.stats.paced_ns = self.stats.paced_ns.saturating_add(gap),
        }
        self.prev = t_ns;
        self.stats.paced_ns
    }
}

/// The host filter run on a replay's frames (`replay --config`).
#[derive(Debug)]
pub struct FilterRun {
    /// Inputs and options as `host-sim run` prepares them, with the capture's IMU samples and
    /// GNSS fixes in place of the files'.
    pub prepared: host_sim::run::cli::Prepared,
    /// The filter's output.
    pub output: host_sim::run::RunOutput,
    /// Metrics (against the truth when there is one).
    pub metrics: host_sim::metrics::Metrics,
    /// Wall time of the filter run alone, s.
    pub wall_s: f64,
}

/// Decodes a capture as frames, feeding the recorded chunks in order (no timing, no port).
pub fn decode_capture(path: &Path) -> anyhow::Result<ReplayOutcome> {
    replay(&ReplayArgs::new(path))
}

/// Runs the host filter on decoded frames the way `host-sim run --config CONFIG [--case DIR]`
/// runs it on files: the configuration is prepared by `host-sim` itself, then its IMU samples
/// and GNSS fixes are replaced by the frames' (with the configuration's GNSS sigma scale
/// applied, as `host-sim` applies it to its files). Same samples, same options: the same
/// solution, bit for bit.
pub fn run_filter_on_frames(
    log: &FrameLog,
    config: &Path,
    case: Option<&Path>,
    model: Option<host_sim::run::Model>,
    f32: bool,
) -> anyhow::Result<FilterRun> {
    use host_sim::run::cli::{execute, prepare, read_config, ConfigKind, RunArgs};
    let mut ra = RunArgs::new(config);
    ra.case = case.map(Path::to_path_buf);
    ra.model = model;
    ra.f32 = f32;
    let mut prepared =
        prepare(&ra).with_context(|| format!("preparing the filter from {}", config.display()))?;
    if log.imu.is_empty() {
        bail!("the capture holds no IMU frame: nothing to run the filter on");
    }
    let sigma_scale = match read_config(config)? {
        ConfigKind::Run(r) => r.gnss.sigma_scale,
        ConfigKind::KfGins(_) => 1.0,
    };
    let mut gnss = log.gnss.clone();
    if sigma_scale != 1.0 {
        for g in &mut gnss {
            for s in g
                .pos_std_ned_m
                .iter_mut()
                .chain(g.vel_std_ned_mps.iter_mut())
            {
                *s *= sigma_scale;
            }
        }
    }
    prepared.case.imu = log.imu.clone();
    // the samples are the capture's now: messages name IMU sample indices, not the
    // configuration's file lines
    prepared.case.imu_origin = None;
    prepared.case.gnss = gnss;
    let t = Instant::now();
    let (output, metrics) = execute(&prepared, &mut |_, _| {})?;
    Ok(FilterRun {
        prepared,
        output,
        metrics,
        wall_s: t.elapsed().as_secs_f64(),
    })
}

/// Writes a filter run's outputs under the names `host-sim run` uses.
pub fn write_filter_outputs(dir: &Path, f: &FilterRun) -> anyhow::Result<()> {
    use host_sim::run::output;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    // each file under its `.partial` name first, renamed when written completely
    let p = |name: &str| partial_name(&dir.join(name));
    output::write_nav(&p("nav.txt"), &f.output.nav, f.prepared.week)?;
    output::write_std(&p("std.txt"), &f.output)?;
    output::write_bias(&p("bias.txt"), &f.output)?;
    output::write_innovations(&p("innovations.txt"), &f.output.innovations)?;
    let mp = p("metrics.json");
    std::fs::write(
        &mp,
        host_sim::run::cli::metrics_json(&f.metrics, &f.output, None)?,
    )
    .with_context(|| format!("writing {}", mp.display()))?;
    for name in [
        "nav.txt",
        "std.txt",
        "bias.txt",
        "innovations.txt",
        "metrics.json",
    ] {
        rename(&p(name), &dir.join(name))?;
    }
    Ok(())
}

/// Longest time `replay --to-port` waits for the port to take a byte.
pub const TO_PORT_TIMEOUT: Duration = Duration::from_secs(5);

/// How often a replay flushes its `.partial` outputs.
pub const CHECKPOINT: Duration = Duration::from_secs(1);

/// Whether `t` can follow `last` in a time series (finite and strictly after it).
fn in_order(t: f64, last: Option<f64>) -> bool {
    t.is_finite() && last.is_none_or(|l| t > l)
}

/// `replay`: decode a capture (reproducing its chunking, and its timing with `--speed`), write
/// the frames it contains in the project's text formats as they are decoded (under `.partial`
/// names, renamed at the end), optionally stream it to a port. A truncated or corrupt record
/// ends the replay early: every record before it is replayed and the outcome says
/// [`ReplayOutcome::incomplete`].
pub fn replay(a: &ReplayArgs) -> anyhow::Result<ReplayOutcome> {
    let cap = a.capture.display();
    let file = std::fs::File::open(&a.capture).with_context(|| format!("opening capture {cap}"))?;
    let mut rd = CaptureReader::new(std::io::BufReader::new(file))
        .with_context(|| format!("reading capture {cap}"))?;
    if rd.skipped_bytes() > 0 {
        eprintln!(
            "warning: {cap}: skipped {} bytes before the capture header",
            rd.skipped_bytes()
        );
    }
    let speed = match (a.as_fast_as_possible, a.speed, &a.to_port) {
        (true, _, _) => None,
        (false, Some(s), _) if (MIN_SPEED..=MAX_SPEED).contains(&s) => Some(s),
        (false, Some(s), _) => bail!("--speed {s} is outside [{MIN_SPEED}, {MAX_SPEED}]"),
        (false, None, Some(_)) => Some(1.0),
        (false, None, None) => None,
    };
    let mut port = match &a.to_port {
        Some(p) => Some(serial::open_for_writing(p, a.baud, TO_PORT_TIMEOUT, false)?),
        None => None,
    };
    let mut out = ReplayOutcome {
        skipped_bytes: rd.skipped_bytes(),
        ..ReplayOutcome::default()
    };
    let mut files = match &a.out {
        Some(dir) if a.input == InputKind::Frames => Some(FrameFiles::new(dir, CHECKPOINT)?),
        _ => None,
    };
    let mut dec = FrameDecoder::new();
    if rd.header().streams_from_start {
        dec.expect_stream_starts();
    }
    let mut gnss = GnssStream::new(NmeaOptions {
        leap_seconds: a.leap_seconds,
        ..NmeaOptions::default()
    });
    let mut pacer = Pacer::new(a.max_gap);
    let mut prev_data: Option<(u64, Vec<u8>)> = None;
    let (mut last_imu_t, mut last_gnss_t) = (None, None);
    let start = Instant::now();
    loop {
        let rec = match rd.next_record() {
            Ok(Some(r)) => r,
            Ok(None) => break,
            Err(e) => {
                let what = format!("{e}; replayed every record before it");
                eprintln!("warning: {cap}: {what}");
                if matches!(e, CaptureError::TruncatedRecord { .. }) {
                    out.truncated = Some(e.to_string());
                }
                out.incomplete = Some(what);
                break;
            }
        };
        if let Record::Data { t_ns, bytes } = &rec {
            if prev_data
                .as_ref()
                .is_some_and(|(t, b)| t == t_ns && b == bytes)
            {
                out.duplicate_records += 1;
                continue;
            }
            prev_data = Some((*t_ns, bytes.clone()));
        }
        out.records += 1;
        out.recorded_s = rec.t_ns() as f64 * 1e-9;
        let paced_ns = pacer.advance(rec.t_ns());
        if let Some(s) = speed {
            let due = secs(paced_ns as f64 * 1e-9 / s);
            if let Some(wait) = due.checked_sub(start.elapsed()) {
                std::thread::sleep(wait);
            }
        }
        match rec {
            Record::LinkReset { .. } => dec.reset_link(),
            Record::Data { bytes, .. } => {
                out.bytes += bytes.len() as u64;
                if let Some(p) = port.as_mut() {
                    serial::write_all_within(p.as_mut(), &bytes, TO_PORT_TIMEOUT).with_context(
                        || format!("writing to --to-port (no byte taken for {TO_PORT_TIMEOUT:?}?)"),
                    )?;
                }
                match a.input {
                    InputKind::Frames => {
                        for r in dec.feed(&bytes) {
                            let f = match r {
                                Ok(f) => f,
                                Err(e) => {
                                    if a.verbose {
                                        eprintln!("rejected chunk: {e}");
                                    }
                                    continue;
                                }
                            };
                            out.log.frames.push(f);
                            match f.payload {
                                Payload::Imu(i) => {
                                    if !in_order(i.sample.t_s, last_imu_t) {
                                        out.imu_out_of_order += 1;
                                        continue;
                                    }
                                    last_imu_t = Some(i.sample.t_s);
                                    out.log.imu.push(i.sample);
                                    out.log.imu_status.push(i.status);
                                    if let Some(w) = files.as_mut() {
                                        w.imu(&i.sample)?;
                                    }
                                }
                                Payload::Gnss(g) => {
                                    if !in_order(g.t_s, last_gnss_t) {
                                        out.gnss_out_of_order += 1;
                                        continue;
                                    }
                                    last_gnss_t = Some(g.t_s);
                                    out.log.gnss.push(g);
                                    if let Some(w) = files.as_mut() {
                                        w.gnss(&g)?;
                                    }
                                }
                                Payload::Nav(n) => {
                                    out.log.nav.push(n);
                                    if let Some(w) = files.as_mut() {
                                        w.nav(&n)?;
                                    }
                                }
                                Payload::Health(h) => {
                                    out.log.health.push(h);
                                    if let Some(w) = files.as_mut() {
                                        w.health(&h)?;
                                    }
                                }
                                Payload::Config(c) => out.log.config.push(c),
                            }
                        }
                    }
                    InputKind::Gnss => {
                        for ev in gnss.feed(&bytes) {
                            match ev {
                                GnssEvent::Fix(f) => out.gnss_fixes.push(f),
                                GnssEvent::Error(e) if a.verbose => eprintln!("{e}"),
                                GnssEvent::Error(_) => {}
                            }
                        }
                    }
                }
            }
        }
    }
    if a.input == InputKind::Gnss {
        out.gnss_fixes
            .extend(gnss.finish().into_iter().filter_map(|e| match e {
                GnssEvent::Fix(f) => Some(f),
                GnssEvent::Error(_) => None,
            }));
    }
    out.stats = *dec.stats();
    out.timing = pacer.stats;
    if out.timing.backwards + out.timing.clamped_gaps > 0 {
        eprintln!(
            "warning: {cap}: {} record time(s) went backwards, {} gap(s) over --max-gap {} s (paced as --max-gap)",
            out.timing.backwards, out.timing.clamped_gaps, a.max_gap
        );
    }
    if out.imu_out_of_order + out.gnss_out_of_order > 0 {
        eprintln!(
            "warning: {cap}: left out {} IMU sample(s) and {} GNSS fix(es) whose time is not after the previous one (duplicated or reordered frames)",
            out.imu_out_of_order, out.gnss_out_of_order
        );
    }
    out.wall_s = start.elapsed().as_secs_f64();
    // The decoded files and the summary first: a filter run that fails leaves them in place.
    if let Some(dir) = &a.out {
        if let Some(w) = files.take() {
            w.finish(&out.log.imu)?;
        }
        write_outputs(dir, &out, a.input, &gnss)?;
    }
    if let Some(cfg) = &a.config {
        if a.input != InputKind::Frames {
            bail!("--config runs the filter on wire frames: not with --input gnss");
        }
        out.filter = Some(run_filter_on_frames(
            &out.log,
            cfg,
            a.case.as_deref(),
            a.model,
            a.f32,
        )?);
        out.wall_s = start.elapsed().as_secs_f64();
        if let (Some(dir), Some(f)) = (&a.out, &out.filter) {
            write_filter_outputs(dir, f)?;
        }
    }
    Ok(out)
}

/// Writes `replay-summary.txt` (and, for GNSS input, `gnss.txt`), each through a `.partial`
/// name and a rename.
fn write_outputs(
    dir: &Path,
    o: &ReplayOutcome,
    input: InputKind,
    gnss: &GnssStream,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut summary = format!(
        "status {}\ncapture records {}\ncapture bytes {}\nrecorded duration {:.3} s\n",
        match &o.incomplete {
            None => "complete".to_string(),
            Some(why) => format!("incomplete: {why}"),
        },
        o.records,
        o.bytes,
        o.recorded_s
    );
    summary.push_str(&format!(
        "skipped bytes before header {}\nduplicate records skipped {}\nrecord times backwards {}\ngaps over --max-gap {}\n",
        o.skipped_bytes, o.duplicate_records, o.timing.backwards, o.timing.clamped_gaps
    ));
    if let Some(t) = &o.truncated {
        summary.push_str(&format!("warning: {t}\n"));
    }
    match input {
        InputKind::Frames => {
            summary.push_str(&format!(
                "imu samples out of order (left out) {}\ngnss fixes out of order (left out) {}\n",
                o.imu_out_of_order, o.gnss_out_of_order
            ));
            summary.push_str(&decoder_report(&o.stats));
        }
        InputKind::Gnss => {
            let p = dir.join("gnss.txt");
            let tmp = partial_name(&p);
            nav_io::write_gnss_text(&tmp, &o.gnss_fixes)?;
            rename(&tmp, &p)?;
            summary.push_str(&format!("{:?}\n", gnss.stats()));
        }
    }
    write_atomically(&dir.join("replay-summary.txt"), summary.as_bytes())
}

/// `send` options.
#[derive(clap::Args, Debug, Clone)]
pub struct SendArgs {
    /// Case directory with imu.txt and optionally gnss.txt (as `host-sim simulate` writes).
    #[arg(long)]
    pub case: PathBuf,
    /// Serial port to send to.
    #[arg(long)]
    pub port: String,
    /// Baud rate.
    #[arg(long, default_value_t = DEFAULT_BAUD)]
    pub baud: u32,
    /// Speed-up over real time (sample times), in [0.001, 1e6].
    #[arg(long, default_value_t = 1.0, conflicts_with = "as_fast_as_possible", value_parser = parse_speed)]
    pub rate_x: f64,
    /// Send as fast as the port takes it.
    #[arg(long)]
    pub as_fast_as_possible: bool,
    /// Keep the port open this long after the last byte so the receiver drains it, s.
    #[arg(long, default_value_t = 0.5, value_parser = parse_seconds)]
    pub linger_s: f64,
    /// Fail (exit 1) when the port takes no byte for this many seconds (nothing reads it),
    /// also while waiting at the end for the bytes written to drain.
    #[arg(long, default_value_t = DEFAULT_WRITE_TIMEOUT_S, value_parser = parse_timeout)]
    pub write_timeout: f64,
    /// No live status line.
    #[arg(long)]
    pub quiet: bool,
    /// Also write every byte sent, exactly as written to the port, to this file (e.g. to run
    /// the same bytes through a host model of the receiver).
    #[arg(long)]
    pub copy_to: Option<PathBuf>,
    /// Open the port without the exclusive lock, so another program (e.g. `hw-bridge send`
    /// on the same emulated board's pty) can use it at the same time.
    #[arg(long)]
    pub shared: bool,
}

/// Default of `send --write-timeout`, s.
pub const DEFAULT_WRITE_TIMEOUT_S: f64 = 10.0;

impl SendArgs {
    /// Sending the case in `case` to `port` with the command line's defaults.
    pub fn new(case: impl Into<PathBuf>, port: impl Into<String>) -> Self {
        Self {
            case: case.into(),
            port: port.into(),
            baud: DEFAULT_BAUD,
            rate_x: 1.0,
            as_fast_as_possible: false,
            linger_s: 0.5,
            write_timeout: DEFAULT_WRITE_TIMEOUT_S,
            quiet: true,
            copy_to: None,
            shared: false,
        }
    }
}

/// Waits until the port's output queue is empty (the reader took every byte), at most
/// `timeout`. A port that cannot report its queue (the ioctl fails) is not waited for. Unlike
/// `flush` (POSIX `tcdrain`), this cannot block forever when nothing reads the port.
fn drain_output(port: &dyn serialport::SerialPort, timeout: Duration) -> anyhow::Result<()> {
    let t0 = Instant::now();
    loop {
        match port.bytes_to_write() {
            Ok(0) | Err(_) => return Ok(()),
            Ok(n) if t0.elapsed() >= timeout => bail!(
                "{n} bytes still not taken by the receiver after --write-timeout {} s (nothing reads the port?)",
                timeout.as_secs_f64()
            ),
            Ok(_) => std::thread::sleep(Duration::from_millis(5)),
        }
    }
}

/// What `send` sent.
#[derive(Debug, Default, Clone, Copy)]
pub struct SendOutcome {
    /// Frames sent.
    pub frames: u64,
    /// Bytes sent.
    pub bytes: u64,
    /// Wall time, s.
    pub wall_s: f64,
}

/// Reads a case directory's imu.txt and (when present) gnss.txt as the payloads to send.
pub fn read_case(dir: &Path) -> anyhow::Result<Vec<(f64, Payload)>> {
    let imu = nav_io::read_imu_text(dir.join("imu.txt"))?.samples;
    let gnss_path = dir.join("gnss.txt");
    let gnss = if gnss_path.exists() {
        nav_io::read_gnss_text(&gnss_path)?
    } else {
        Vec::new()
    };
    Ok(case_payloads(&imu, &gnss))
}

/// `send`: stream a simulated case into a port as frames, paced by the sample times.
pub fn send(a: &SendArgs) -> anyhow::Result<SendOutcome> {
    if !(MIN_SPEED..=MAX_SPEED).contains(&a.rate_x) {
        bail!(
            "--rate-x {} is outside [{MIN_SPEED}, {MAX_SPEED}]",
            a.rate_x
        );
    }
    let payloads = read_case(&a.case)?;
    let write_timeout = secs(a.write_timeout);
    let mut port = serial::open_for_writing(&a.port, a.baud, write_timeout, a.shared)?;
    let timeout_s = write_timeout.as_secs_f64();
    let mut copy = match &a.copy_to {
        Some(p) => Some(BufWriter::new(
            std::fs::File::create(p).with_context(|| format!("creating {}", p.display()))?,
        )),
        None => None,
    };
    let mut put = |bytes: &[u8]| -> anyhow::Result<()> {
        serial::write_all_within(port.as_mut(), bytes, write_timeout).map_err(|e| {
            if e.kind() == std::io::ErrorKind::TimedOut {
                anyhow::anyhow!(
                    "writing frames to {}: the port took no byte within --write-timeout {timeout_s} s (nothing reads it?)",
                    a.port
                )
            } else {
                anyhow::Error::new(e).context(format!("writing frames to {}", a.port))
            }
        })?;
        if let Some(c) = copy.as_mut() {
            c.write_all(bytes).context("writing --copy-to")?;
        }
        Ok(())
    };
    let mut enc = Encoder::new();
    let mut status = StatusLine::new(Duration::from_millis(500), !a.quiet);
    let start = Instant::now();
    let t0 = payloads.first().map_or(0.0, |p| p.0);
    // A leading delimiter: the receiver's first frame is cleanly delimited whatever it had.
    let mut pending = vec![0u8];
    let mut out = SendOutcome::default();
    let mut buf = [0u8; MAX_FRAME_LEN];
    for (t, p) in &payloads {
        if !a.as_fast_as_possible {
            let due = secs((t - t0) / a.rate_x);
            if let Some(wait) = due.checked_sub(start.elapsed()) {
                if wait > Duration::from_millis(2) {
                    put(&pending)?;
                    out.bytes += pending.len() as u64;
                    pending.clear();
                    std::thread::sleep(wait);
                }
            }
        }
        let n = enc.encode(p, &mut buf)?;
        pending.extend_from_slice(&buf[..n]);
        out.frames += 1;
        if pending.len() >= 4096 {
            put(&pending)?;
            out.bytes += pending.len() as u64;
            pending.clear();
        }
        let (f, b) = (out.frames, out.bytes);
        status.update(f, false, || {
            format!("sent {f} frames, {b} bytes, t = {t:.3} s")
        });
    }
    put(&pending)?;
    out.bytes += pending.len() as u64;
    drain_output(port.as_ref(), write_timeout)?;
    if let Some(mut c) = copy {
        c.flush().context("writing --copy-to")?;
    }
    let (f, b) = (out.frames, out.bytes);
    status.update(f, true, || format!("sent {f} frames, {b} bytes"));
    status.finish();
    std::thread::sleep(secs(a.linger_s));
    out.wall_s = start.elapsed().as_secs_f64();
    Ok(out)
}

/// `stream` options.
#[derive(clap::Args, Debug, Clone)]
pub struct StreamArgs {
    /// Port of the navigation board (wire-protocol frames).
    #[arg(long)]
    pub port: String,
    /// Baud rate of `--port`.
    #[arg(long, default_value_t = DEFAULT_BAUD)]
    pub baud: u32,
    /// Port of a separate GNSS receiver (NMEA and/or UBX).
    #[arg(long)]
    pub gnss_port: Option<String>,
    /// Baud rate of `--gnss-port`.
    #[arg(long, default_value_t = 38_400)]
    pub gnss_baud: u32,
    /// GPS - UTC leap seconds for NMEA input.
    #[arg(long, default_value_t = 18)]
    pub leap_seconds: i64,
    /// Stop after this many seconds.
    #[arg(long, value_parser = parse_seconds)]
    pub duration: Option<f64>,
    /// Run the filter on the host too: the firmware's own application (18-state NBK, f32
    /// covariance, started at the first fix) on the IMU frames of `--port` and the GNSS fixes
    /// of both ports; its solution is shown next to the board's.
    #[arg(long)]
    pub host_filter: bool,
}

/// The wall clock as the application's time base (only its health timing fields use it).
struct WallClock(Instant);
impl nav_app::TimeBase for WallClock {
    const HZ: u32 = 1_000_000;
    fn now_ticks(&mut self) -> u64 {
        self.0.elapsed().as_micros() as u64
    }
}

/// The host filter of `stream --host-filter`.
type HostApp = nav_app::NavApp<{ nav_core::model::LAYOUT_NBK.dim() }>;

fn host_app() -> anyhow::Result<HostApp> {
    nav_app::NavApp::new(
        nav_core::model::LAYOUT_NBK,
        nav_core::config::FilterConfig::source_nbk_model(),
        0,
        0,
    )
    .map_err(|e| anyhow::anyhow!("host filter: {e}"))
}

/// Feeds a payload to the host filter (IMU samples and GNSS fixes only; its own output
/// frames are discarded).
fn host_feed(app: &mut HostApp, p: &Payload, clock: &mut WallClock) {
    if matches!(p, Payload::Imu(_) | Payload::Gnss(_)) {
        let mut sink: Vec<u8> = Vec::new();
        let _ = app.handle(p, &mut sink, clock);
    }
}

enum PortEvent {
    Board(Vec<u8>),
    Gnss(Vec<u8>),
    Lost(&'static str, String),
}

fn reader_thread(
    path: String,
    baud: u32,
    tx: mpsc::Sender<PortEvent>,
    wrap: fn(Vec<u8>) -> PortEvent,
    name: &'static str,
) -> anyhow::Result<()> {
    let mut port = serial::open(&path, baud, Duration::from_millis(100))?;
    std::thread::spawn(move || {
        let mut buf = vec![0u8; 4096];
        loop {
            match port.read(&mut buf) {
                Ok(0) => std::thread::sleep(Duration::from_millis(5)),
                Ok(n) => {
                    if tx.send(wrap(buf[..n].to_vec())).is_err() {
                        return;
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => {
                    let _ = tx.send(PortEvent::Lost(name, e.to_string()));
                    std::thread::sleep(Duration::from_millis(200));
                    match serial::open(&path, baud, Duration::from_millis(100)) {
                        Ok(p) => port = p,
                        Err(_) => continue,
                    }
                }
            }
        }
    });
    Ok(())
}

/// `stream`: live decode of a board's frames (and a GNSS receiver's fixes) with a status
/// line showing the latest solution, GNSS fix and link health.
pub fn stream(a: &StreamArgs) -> anyhow::Result<StreamOutcome> {
    let (tx, rx) = mpsc::channel();
    reader_thread(
        a.port.clone(),
        a.baud,
        tx.clone(),
        PortEvent::Board,
        "board",
    )?;
    if let Some(g) = &a.gnss_port {
        reader_thread(g.clone(), a.gnss_baud, tx.clone(), PortEvent::Gnss, "gnss")?;
    }
    drop(tx);
    let mut dec = FrameDecoder::new();
    let mut gnss = GnssStream::new(NmeaOptions {
        leap_seconds: a.leap_seconds,
        ..NmeaOptions::default()
    });
    let mut status = StatusLine::new(Duration::from_millis(250), true);
    let mut log = FrameLog::default();
    let mut last_rx_fix: Option<GnssFix> = None;
    let mut host = a.host_filter.then(host_app).transpose()?;
    let mut clock = WallClock(Instant::now());
    let start = Instant::now();
    loop {
        if a.duration.is_some_and(|d| start.elapsed() >= secs(d)) {
            break;
        }
        match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(PortEvent::Board(b)) => {
                for f in dec.feed(&b).flatten() {
                    if let Some(h) = host.as_mut() {
                        host_feed(h, &f.payload, &mut clock);
                    }
                    log.push(f);
                }
                // Keep only the latest of each kind for display.
                log.frames.clear();
                log.imu.drain(..log.imu.len().saturating_sub(1));
                log.imu_status
                    .drain(..log.imu_status.len().saturating_sub(1));
                log.gnss.drain(..log.gnss.len().saturating_sub(1));
                log.nav.drain(..log.nav.len().saturating_sub(1));
                log.health.drain(..log.health.len().saturating_sub(1));
            }
            Ok(PortEvent::Gnss(b)) => {
                for ev in gnss.feed(&b) {
                    if let GnssEvent::Fix(f) = ev {
                        if let Some(h) = host.as_mut() {
                            host_feed(h, &Payload::Gnss(f), &mut clock);
                        }
                        last_rx_fix = Some(f);
                    }
                }
            }
            Ok(PortEvent::Lost(name, e)) => {
                eprintln!("\n{name} port lost: {e}; reopening");
                if name == "board" {
                    dec.reset_link();
                }
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
        }
        let s = *dec.stats();
        status.update(u64::from(s.frames_ok), false, || {
            let mut t = decoder_summary(&s);
            if let Some(n) = log.nav.last() {
                t.push_str(&format!(
                    " | nav t {:.2} lat {:.7} lon {:.7} h {:.2} v {:.2} {:.2} {:.2} yaw {:.2} st {:#x}",
                    n.t_s,
                    n.lat_rad.to_degrees(),
                    n.lon_rad.to_degrees(),
                    n.h_m,
                    n.vel_ned_mps[0],
                    n.vel_ned_mps[1],
                    n.vel_ned_mps[2],
                    n.rpy_rad[2].to_degrees(),
                    n.status
                ));
            } else if let Some(i) = log.imu.last() {
                t.push_str(&format!(" | imu t {:.3}", i.t_s));
            }
            if let Some(n) = host.as_ref().and_then(|h| h.filter()).map(|f| f.solution()) {
                t.push_str(&format!(
                    " | host t {:.2} lat {:.7} lon {:.7} h {:.2} yaw {:.2} std {:.2} {:.2} {:.2}",
                    n.t_s,
                    n.lat_rad.to_degrees(),
                    n.lon_rad.to_degrees(),
                    n.h_m,
                    n.rpy_rad[2].to_degrees(),
                    n.pos_std_ned_m[0],
                    n.pos_std_ned_m[1],
                    n.pos_std_ned_m[2]
                ));
            }
            if let Some(h) = log.health.last() {
                t.push_str(&format!(
                    " | board rx ok {} crc {} lost {} gnss upd {}",
                    h.rx_frames_ok, h.rx_crc_errors, h.rx_lost, h.gnss_updates
                ));
            }
            if let Some(f) = last_rx_fix {
                t.push_str(&format!(
                    " | rx gnss t {:.1} {:?} sats {} std {:.2} {:.2} {:.2}",
                    f.t_s,
                    f.quality,
                    f.num_sats,
                    f.pos_std_ned_m[0],
                    f.pos_std_ned_m[1],
                    f.pos_std_ned_m[2]
                ));
            }
            t
        });
    }
    status.finish();
    Ok(StreamOutcome {
        stats: *dec.stats(),
        host_solution: host.as_ref().and_then(|h| h.filter()).map(|f| f.solution()),
        host_imu_epochs: host.as_ref().map_or(0, |h| h.counters().imu_epochs),
        host_gnss_updates: host.as_ref().map_or(0, |h| h.counters().gnss_updates),
    })
}

/// What `stream` saw.
#[derive(Debug, Clone, Copy)]
pub struct StreamOutcome {
    /// Decoder counters of the board port.
    pub stats: DecoderStats,
    /// The host filter's last solution (`--host-filter`, once started).
    pub host_solution: Option<nav_core::types::NavSolution>,
    /// IMU epochs the host filter ran.
    pub host_imu_epochs: u32,
    /// GNSS fixes the host filter used.
    pub host_gnss_updates: u32,
}

/// The host filter of `stream --host-filter` run offline on payloads (what a live stream of
/// them must reproduce exactly): its last solution, IMU epochs and GNSS updates.
pub fn host_filter_offline(
    payloads: &[Payload],
) -> anyhow::Result<(Option<nav_core::types::NavSolution>, u32, u32)> {
    let mut app = host_app()?;
    let mut clock = WallClock(Instant::now());
    for p in payloads {
        host_feed(&mut app, p, &mut clock);
    }
    let c = *app.counters();
    Ok((
        app.filter().map(|f| f.solution()),
        c.imu_epochs,
        c.gnss_updates,
    ))
}
