//! The sub-commands of the `hw-bridge` CLI, as library functions (the binary only parses the
//! command line).

use crate::capture::{CaptureError, CaptureHeader, CaptureReader, CaptureWriter, Record};
use crate::frames::{case_payloads, FrameLog};
use crate::gnss::{GnssEvent, GnssStream, NmeaOptions};
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
    #[arg(long)]
    pub duration: Option<f64>,
    /// Stop when no byte arrived for this many seconds after the first byte (before it, only
    /// `--duration` stops the recording).
    #[arg(long)]
    pub idle_exit: Option<f64>,
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

fn now_unix_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// `record`: raw bytes with receive timestamps into a capture file, live status on stderr.
/// When the port fails (unplugged, pty closed) a link-reset record is written and the port is
/// reopened until it comes back or a stop condition is met.
pub fn record(a: &RecordArgs) -> anyhow::Result<DecoderStats> {
    let file = std::fs::File::create(&a.out)
        .with_context(|| format!("creating capture {}", a.out.display()))?;
    let header = CaptureHeader {
        port: a.port.clone(),
        baud: a.baud,
        start_unix_ns: now_unix_ns(),
        tool: format!("hw-bridge {}", env!("CARGO_PKG_VERSION")),
    };
    let mut w = CaptureWriter::new(BufWriter::new(file), &header)?;
    let timeout = Duration::from_millis(50);
    let mut port = Some(serial::open_with(&a.port, a.baud, timeout, a.shared)?);
    // One line, even with --quiet: scripts (and the pty test) wait for it before sending.
    eprintln!("recording {} -> {}", a.port, a.out.display());
    let start = Instant::now();
    let mut last_data: Option<Instant> = None;
    let mut dec = FrameDecoder::new();
    let mut status = StatusLine::new(Duration::from_millis(500), !a.quiet);
    let mut buf = vec![0u8; 8192];
    loop {
        let now = Instant::now();
        if a.duration
            .is_some_and(|d| now.duration_since(start).as_secs_f64() >= d)
        {
            break;
        }
        if let (Some(d), Some(last)) = (a.idle_exit, last_data) {
            if now.duration_since(last).as_secs_f64() >= d {
                break;
            }
        }
        let Some(p) = port.as_mut() else {
            std::thread::sleep(Duration::from_millis(100));
            port = serial::open_with(&a.port, a.baud, timeout, a.shared).ok();
            continue;
        };
        match p.read(&mut buf) {
            Ok(0) => std::thread::sleep(Duration::from_millis(5)),
            Ok(n) => {
                let t_ns = start.elapsed().as_nanos() as u64;
                last_data = Some(Instant::now());
                w.write(&Record::Data {
                    t_ns,
                    bytes: buf[..n].to_vec(),
                })?;
                w.flush()?;
                if !a.raw {
                    dec.feed(&buf[..n]).for_each(drop);
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => {
                if !a.quiet {
                    eprintln!("\nport {}: {e}; reopening", a.port);
                }
                port = None;
                let t_ns = start.elapsed().as_nanos() as u64;
                w.write(&Record::LinkReset { t_ns })?;
                w.flush()?;
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
    w.flush()?;
    Ok(s)
}

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
    /// Replay at this multiple of the recorded timing (default: 1 with `--to-port`, else as
    /// fast as possible).
    #[arg(long, conflicts_with = "as_fast_as_possible")]
    pub speed: Option<f64>,
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
    /// Wall time of the replay (decoding, and the filter run with `--config`), s.
    pub wall_s: f64,
    /// The host filter's run on the decoded frames (`--config`).
    pub filter: Option<FilterRun>,
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
    output::write_nav(&dir.join("nav.txt"), &f.output.nav, f.prepared.week)?;
    output::write_std(&dir.join("std.txt"), &f.output)?;
    output::write_bias(&dir.join("bias.txt"), &f.output)?;
    output::write_innovations(&dir.join("innovations.txt"), &f.output.innovations)?;
    let mp = dir.join("metrics.json");
    std::fs::write(&mp, serde_json::to_string_pretty(&f.metrics)?)
        .with_context(|| format!("writing {}", mp.display()))?;
    Ok(())
}

/// `replay`: decode a capture (reproducing its chunking, and its timing with `--speed`), write
/// the frames it contains in the project's text formats, optionally stream it to a port.
pub fn replay(a: &ReplayArgs) -> anyhow::Result<ReplayOutcome> {
    let file = std::fs::File::open(&a.capture)
        .with_context(|| format!("opening capture {}", a.capture.display()))?;
    let mut rd = CaptureReader::new(std::io::BufReader::new(file))
        .with_context(|| format!("reading capture {}", a.capture.display()))?;
    let speed = match (a.as_fast_as_possible, a.speed, &a.to_port) {
        (true, _, _) => None,
        (false, Some(s), _) if s > 0.0 && s.is_finite() => Some(s),
        (false, Some(s), _) => bail!("--speed must be positive, got {s}"),
        (false, None, Some(_)) => Some(1.0),
        (false, None, None) => None,
    };
    let mut port = match &a.to_port {
        Some(p) => Some(serial::open(p, a.baud, Duration::from_secs(5))?),
        None => None,
    };
    let mut out = ReplayOutcome::default();
    let mut dec = FrameDecoder::new();
    let mut gnss = GnssStream::new(NmeaOptions {
        leap_seconds: a.leap_seconds,
        ..NmeaOptions::default()
    });
    let start = Instant::now();
    loop {
        let rec = match rd.next_record() {
            Ok(Some(r)) => r,
            Ok(None) => break,
            Err(e @ CaptureError::TruncatedRecord { .. }) => {
                eprintln!("warning: {e}; replayed every complete record");
                out.truncated = Some(e.to_string());
                break;
            }
            Err(e) => return Err(e).with_context(|| format!("reading {}", a.capture.display())),
        };
        out.records += 1;
        out.recorded_s = rec.t_ns() as f64 * 1e-9;
        if let Some(s) = speed {
            let due = Duration::from_secs_f64(rec.t_ns() as f64 * 1e-9 / s);
            if let Some(wait) = due.checked_sub(start.elapsed()) {
                std::thread::sleep(wait);
            }
        }
        match rec {
            Record::LinkReset { .. } => dec.reset_link(),
            Record::Data { bytes, .. } => {
                out.bytes += bytes.len() as u64;
                if let Some(p) = port.as_mut() {
                    p.write_all(&bytes).context("writing to --to-port")?;
                }
                match a.input {
                    InputKind::Frames => {
                        for r in dec.feed(&bytes) {
                            match r {
                                Ok(f) => out.log.push(f),
                                Err(e) if a.verbose => eprintln!("rejected chunk: {e}"),
                                Err(_) => {}
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
    }
    out.wall_s = start.elapsed().as_secs_f64();
    if let Some(dir) = &a.out {
        write_outputs(dir, &out, a.input, &gnss)?;
        if let Some(f) = &out.filter {
            write_filter_outputs(dir, f)?;
        }
    }
    Ok(out)
}

fn write_outputs(
    dir: &Path,
    o: &ReplayOutcome,
    input: InputKind,
    gnss: &GnssStream,
) -> anyhow::Result<()> {
    use host_sim::io::{write_gnss_text, write_imu_text, write_nav_text};
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut summary = format!(
        "capture records {}\ncapture bytes {}\nrecorded duration {:.3} s\n",
        o.records, o.bytes, o.recorded_s
    );
    if let Some(t) = &o.truncated {
        summary.push_str(&format!("warning: {t}\n"));
    }
    match input {
        InputKind::Frames => {
            if !o.log.imu.is_empty() {
                write_imu_text(dir.join("imu.txt"), &o.log.imu)?;
            }
            let gnss_fixes: Vec<GnssFix> = o.log.gnss.clone();
            if !gnss_fixes.is_empty() {
                write_gnss_text(dir.join("gnss.txt"), &gnss_fixes)?;
            }
            if !o.log.nav.is_empty() {
                // the board's own solutions (nav.txt is the host filter's, with --config)
                write_nav_text(dir.join("board-nav.txt"), &o.log.nav)?;
            }
            if !o.log.health.is_empty() {
                let mut h = String::from("# uptime_ms rx_frames_ok rx_rejected rx_crc_errors rx_lost imu_epochs gnss_updates gnss_rejected epoch_ticks_max stack_peak_bytes filter_status\n");
                for x in &o.log.health {
                    h.push_str(&format!(
                        "{} {} {} {} {} {} {} {} {} {} {}\n",
                        x.uptime_ms,
                        x.rx_frames_ok,
                        x.rx_rejected,
                        x.rx_crc_errors,
                        x.rx_lost,
                        x.imu_epochs,
                        x.gnss_updates,
                        x.gnss_rejected,
                        x.epoch_ticks_max,
                        x.stack_peak_bytes,
                        x.filter_status
                    ));
                }
                std::fs::write(dir.join("health.txt"), h)?;
            }
            summary.push_str(&decoder_report(&o.stats));
        }
        InputKind::Gnss => {
            write_gnss_text(dir.join("gnss.txt"), &o.gnss_fixes)?;
            summary.push_str(&format!("{:?}\n", gnss.stats()));
        }
    }
    std::fs::write(dir.join("replay-summary.txt"), summary)?;
    Ok(())
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
    /// Speed-up over real time (sample times).
    #[arg(long, default_value_t = 1.0, conflicts_with = "as_fast_as_possible")]
    pub rate_x: f64,
    /// Send as fast as the port takes it.
    #[arg(long)]
    pub as_fast_as_possible: bool,
    /// Keep the port open this long after the last byte so the receiver drains it, s.
    #[arg(long, default_value_t = 0.5)]
    pub linger_s: f64,
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
    let imu = host_sim::io::read_imu_text(dir.join("imu.txt"))?.samples;
    let gnss_path = dir.join("gnss.txt");
    let gnss = if gnss_path.exists() {
        host_sim::io::read_gnss_text(&gnss_path)?
    } else {
        Vec::new()
    };
    Ok(case_payloads(&imu, &gnss))
}

/// `send`: stream a simulated case into a port as frames, paced by the sample times.
pub fn send(a: &SendArgs) -> anyhow::Result<SendOutcome> {
    if !(a.rate_x > 0.0 && a.rate_x.is_finite()) {
        bail!("--rate-x must be positive, got {}", a.rate_x);
    }
    let payloads = read_case(&a.case)?;
    let mut port = serial::open_with(&a.port, a.baud, Duration::from_secs(10), a.shared)?;
    let mut copy = match &a.copy_to {
        Some(p) => Some(BufWriter::new(
            std::fs::File::create(p).with_context(|| format!("creating {}", p.display()))?,
        )),
        None => None,
    };
    let mut put = |bytes: &[u8]| -> anyhow::Result<()> {
        port.write_all(bytes).context("writing frames")?;
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
            let due = Duration::from_secs_f64(((t - t0) / a.rate_x).max(0.0));
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
    port.flush()?;
    if let Some(mut c) = copy {
        c.flush().context("writing --copy-to")?;
    }
    let (f, b) = (out.frames, out.bytes);
    status.update(f, true, || format!("sent {f} frames, {b} bytes"));
    status.finish();
    std::thread::sleep(Duration::from_secs_f64(a.linger_s.max(0.0)));
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
    #[arg(long)]
    pub duration: Option<f64>,
    /// Run the filter on the host too: the firmware's own application (18-state NBK, f32
    /// covariance, started at the first fix) on the IMU frames of `--port` and the GNSS fixes
    /// of both ports; its solution is shown next to the board's.
    #[arg(long)]
    pub host_filter: bool,
}

/// The wall clock as the application's time base (only its health timing fields use it).
struct WallClock(Instant);
impl crate::time::TimeBase for WallClock {
    const HZ: u32 = 1_000_000;
    fn now_ticks(&mut self) -> u64 {
        self.0.elapsed().as_micros() as u64
    }
}

/// The host filter of `stream --host-filter`.
type HostApp = crate::fwapp::NavApp<{ nav_core::model::LAYOUT_NBK.dim() }>;

fn host_app() -> HostApp {
    crate::fwapp::NavApp::new(
        nav_core::model::LAYOUT_NBK,
        nav_core::config::FilterConfig::source_nbk_model(),
        0,
        0,
    )
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
    let mut host = a.host_filter.then(host_app);
    let mut clock = WallClock(Instant::now());
    let start = Instant::now();
    loop {
        if a.duration
            .is_some_and(|d| start.elapsed().as_secs_f64() >= d)
        {
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
) -> (Option<nav_core::types::NavSolution>, u32, u32) {
    let mut app = host_app();
    let mut clock = WallClock(Instant::now());
    for p in payloads {
        host_feed(&mut app, p, &mut clock);
    }
    let c = *app.counters();
    (
        app.filter().map(|f| f.solution()),
        c.imu_epochs,
        c.gnss_updates,
    )
}
