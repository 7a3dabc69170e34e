//! `replay`: a capture decoded into text files, or streamed back out to a port.

use super::*;
use crate::capture::{CaptureError, CaptureReader, Record, ResyncStats};
use crate::frames::FrameLog;
use crate::outputs::{open_out, partial_name, rename, write_atomically, FrameFiles};
use crate::serial;
use crate::status::decoder_report;
use anyhow::{bail, Context};
use nav_core::types::GnssFix;
use nav_core::wire::{DecoderStats, Frame, FrameDecoder, Payload};
use nav_engine::run::interrupt;
use nav_engine::run::outdir::create_new_file;
use nav_io::gnss::{GnssEvent, GnssStream, NmeaOptions};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Default of `replay --max-gap`, s.
pub const DEFAULT_MAX_GAP_S: f64 = 10.0;

/// What `replay` decodes the capture as (`--input`: `frames`, `gnss`).
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    strum::Display,
    strum::EnumString,
    strum::VariantNames,
)]
#[strum(serialize_all = "kebab-case")]
pub enum InputKind {
    /// Wire-protocol frames (a navigation board or `hw-bridge send`).
    #[default]
    Frames,
    /// A GNSS receiver's NMEA and/or UBX output.
    Gnss,
}

/// `replay` options (the command line's `hw-bridge replay` arguments convert into them).
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayOptions {
    /// Capture file written by `record`.
    pub capture: PathBuf,
    /// Replay at this multiple of the recorded timing, in [[`MIN_SPEED`], [`MAX_SPEED`]]
    /// (None: 1 with `to_port`, else as fast as possible).
    pub speed: Option<f64>,
    /// Longest pause between two records when pacing, in recorded seconds: a larger jump of
    /// the recorded time is paced as this long and counted.
    pub max_gap_s: f64,
    /// Ignore the recorded timing.
    pub as_fast_as_possible: bool,
    /// Also write the recorded bytes, in the recorded chunks, to this port.
    pub to_port: Option<String>,
    /// Baud rate of `to_port`, bit/s.
    pub baud: u32,
    /// Directory for imu.txt, gnss.txt, nav.txt, health.txt and replay-summary.txt (and the
    /// filter's outputs with `config`).
    pub out: Option<PathBuf>,
    /// What the capture contains.
    pub input: InputKind,
    /// GPS - UTC leap seconds for NMEA input, s, in the leap-second table's range [0, 18].
    pub leap_seconds: i64,
    /// Print every rejected chunk with its byte offset.
    pub verbose: bool,
    /// Run the host filter on the decoded IMU and GNSS frames as `host-sim run` does on
    /// files, with this run (its configuration, case folder and overrides; the frames replace
    /// its IMU and GNSS files; its outputs in `out`).
    pub filter: Option<nav_engine::RunSpec>,
    /// Keep every decoded frame in [`ReplayOutcome::log`] (the command line keeps only what
    /// its outputs need: memory independent of the capture's length with `out`).
    pub keep_frames: bool,
}

impl ReplayOptions {
    /// Decoding `capture` as frames as fast as possible, without a port or outputs, keeping
    /// every frame.
    pub fn new(capture: impl Into<PathBuf>) -> Self {
        Self {
            capture: capture.into(),
            speed: None,
            max_gap_s: DEFAULT_MAX_GAP_S,
            as_fast_as_possible: true,
            to_port: None,
            baud: DEFAULT_BAUD,
            out: None,
            input: InputKind::Frames,
            leap_seconds: DEFAULT_LEAP_SECONDS,
            verbose: false,
            filter: None,
            keep_frames: true,
        }
    }
}

/// The result of a replay.
#[derive(Debug, Default)]
pub struct ReplayOutcome {
    /// Decoded frames (frame input): all of them with [`ReplayOptions::keep_frames`], else only
    /// what the outputs need.
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
    /// before it was replayed; corrupt stretches were skipped; the capture ends with the link
    /// lost); `None` when the whole capture was replayed.
    pub incomplete: Option<String>,
    /// Bytes of garbage skipped before the capture's magic.
    pub skipped_bytes: u64,
    /// Corrupt stretches of the capture skipped by resynchronising on the next valid record
    /// header, and their bytes (each one makes the replay incomplete).
    pub resync: ResyncStats,
    /// The capture ends with a link-reset record: the port was lost and the recording
    /// stopped before it came back (the replay is incomplete).
    pub ended_link_lost: bool,
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
    /// The signal (`SIGINT`, `SIGTERM`) that stopped the replay before the end of the
    /// capture, once [`nav_engine::run::interrupt::install`] is in place: the outputs hold
    /// every record before it, under their `.partial` names.
    pub interrupted: Option<String>,
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
/// names, renamed at the end), optionally stream it to a port, and with `--config` and
/// `--out` push the IMU samples and GNSS fixes into the host filter as they are decoded. A
/// truncated or corrupt record ends the replay early: every record before it is replayed and
/// the outcome says [`ReplayOutcome::incomplete`].
///
/// SIGINT or SIGTERM (once [`nav_engine::run::interrupt::install`] is in place) stops the
/// replay before its next record: the outputs hold every record before it, under their
/// `.partial` names (`replay-summary.txt.partial` says `incomplete` and why, the filter's
/// `metrics.json.partial` `"complete": false`), the complete outputs of an earlier replay stay
/// in place, and the result is [`ReplayInterrupted`].
pub fn replay(a: &ReplayOptions) -> anyhow::Result<ReplayOutcome> {
    let _stoppable = interrupt::Stoppable::enter();
    let cap = a.capture.display();
    nav_io::check_leap_seconds(a.leap_seconds)
        .map_err(|e| anyhow::anyhow!("--leap-seconds {e}"))?;
    let file = std::fs::File::open(&a.capture).with_context(|| format!("opening capture {cap}"))?;
    let mut rd = CaptureReader::new(std::io::BufReader::new(file))
        .with_context(|| format!("reading capture {cap}"))?;
    if rd.skipped_bytes() > 0 {
        eprintln!(
            "warning: {cap}: skipped {} bytes before the capture header",
            rd.skipped_bytes()
        );
    }
    let speed = replay_speed(a)?;
    let port = match &a.to_port {
        Some(p) => Some(serial::open_for_writing(p, a.baud, TO_PORT_TIMEOUT, false)?),
        None => None,
    };
    // the output folder checked (none of the inputs in it) and locked before anything is
    // written in it
    let od = match &a.out {
        Some(dir) => Some(open_out(dir, &a.capture, a.filter.as_ref())?),
        None => None,
    };
    let mut dec = Decoding::new(a, &rd, port, od.as_ref())?;
    let start = Instant::now();
    let mut pacer = Pacer::new(a.max_gap_s);
    loop {
        if let Some(sig) = interrupt::requested() {
            dec.out.interrupted = Some(interrupt::signal_name(sig));
            break;
        }
        let rec = match rd.next_record() {
            Ok(Some(r)) => r,
            Ok(None) => break,
            Err(e) => {
                let what = format!("{e}; replayed every record before it");
                eprintln!("warning: {cap}: {what}");
                if matches!(e, CaptureError::TruncatedRecord { .. }) {
                    dec.out.truncated = Some(e.to_string());
                }
                dec.out.incomplete = Some(what);
                break;
            }
        };
        // bytes skipped to resynchronise: a frame in progress is cut
        let rs = rd.resync_stats();
        if rs.resyncs != dec.out.resync.resyncs {
            dec.out.resync = rs;
            dec.frames.reset_link();
        }
        let paced_ns = pacer.advance(rec.t_ns());
        if let Some(s) = speed {
            let due = secs(paced_ns as f64 * 1e-9 / s);
            sleep_until_or_stop(start, due);
        }
        dec.record(rec)?;
    }
    dec.out.resync = rd.resync_stats();
    dec.out.timing = pacer.stats;
    dec.finish(a, od, start)
}

/// Sleeps until `due` after `start`, in slices short enough to see a stop request
/// ([`interrupt::requested`]) at once.
fn sleep_until_or_stop(start: Instant, due: Duration) {
    const SLICE: Duration = Duration::from_millis(20);
    while let Some(wait) = due.checked_sub(start.elapsed()) {
        if wait.is_zero() || interrupt::requested().is_some() {
            break;
        }
        std::thread::sleep(wait.min(SLICE));
    }
}

/// A replay stopped by SIGINT or SIGTERM before the end of its capture (see [`replay`]).
#[derive(Debug, thiserror::Error)]
#[error(
    "replay: interrupted by {signal} after {records} record(s) ({recorded_s:.3} s recorded){}",
    match out {
        Some(o) => format!(
            "; everything replayed so far is in {}/*.partial (replay-summary.txt.partial says \
             incomplete; earlier complete outputs there are unchanged)",
            o.display()
        ),
        None => String::new(),
    }
)]
pub struct ReplayInterrupted {
    /// The signal's name.
    pub signal: String,
    /// Capture records replayed.
    pub records: u64,
    /// Recorded time of the last record replayed, s.
    pub recorded_s: f64,
    /// The output folder holding the `.partial` outputs (`--out`).
    pub out: Option<PathBuf>,
}

/// The pacing of a replay: `Some(speed)`, or None as fast as possible.
fn replay_speed(a: &ReplayOptions) -> anyhow::Result<Option<f64>> {
    Ok(match (a.as_fast_as_possible, a.speed, &a.to_port) {
        (true, _, _) => None,
        (false, Some(s), _) if (MIN_SPEED..=MAX_SPEED).contains(&s) => Some(s),
        (false, Some(s), _) => bail!("--speed {s} is outside [{MIN_SPEED}, {MAX_SPEED}]"),
        (false, None, Some(_)) => Some(1.0),
        (false, None, None) => None,
    })
}

/// A replay in progress: the decoders, the outputs written as it goes, the filter fed as it
/// goes, and the outcome so far.
struct Decoding {
    out: ReplayOutcome,
    input: InputKind,
    verbose: bool,
    port: Option<Box<dyn serialport::SerialPort>>,
    frames: FrameDecoder,
    gnss: GnssStream,
    files: Option<FrameFiles>,
    /// The host filter fed as the frames are decoded (`--config` with `--out`); a
    /// configuration that does not load is reported after the decoded files are written.
    filter: Option<anyhow::Result<FilterFeed>>,
    /// Keep every frame in [`ReplayOutcome::log`] (else only what the outputs need).
    keep_frames: bool,
    /// Keep the IMU samples and GNSS fixes (`--config` without `--out`: the filter runs on
    /// them at the end).
    keep_samples: bool,
    last_imu_t: Option<f64>,
    last_gnss_t: Option<f64>,
}

impl Decoding {
    fn new<R: std::io::Read>(
        a: &ReplayOptions,
        rd: &CaptureReader<R>,
        port: Option<Box<dyn serialport::SerialPort>>,
        od: Option<&nav_engine::run::outdir::OutDir>,
    ) -> anyhow::Result<Self> {
        let files = match &a.out {
            Some(dir) if a.input == InputKind::Frames => Some(FrameFiles::new(dir, CHECKPOINT)?),
            _ => None,
        };
        let mut frames = FrameDecoder::new();
        if rd.header().streams_from_start {
            frames.expect_stream_starts();
        }
        let filter = match (&a.filter, od) {
            (Some(spec), Some(od)) if a.input == InputKind::Frames => {
                Some(FilterFeed::start(spec, od.stage()))
            }
            _ => None,
        };
        Ok(Self {
            out: ReplayOutcome {
                skipped_bytes: rd.skipped_bytes(),
                ..ReplayOutcome::default()
            },
            input: a.input,
            verbose: a.verbose,
            port,
            frames,
            gnss: GnssStream::new(NmeaOptions {
                leap_seconds: a.leap_seconds,
                ..NmeaOptions::default()
            }),
            files,
            filter,
            keep_frames: a.keep_frames,
            keep_samples: a.filter.is_some() && a.out.is_none(),
            last_imu_t: None,
            last_gnss_t: None,
        })
    }

    /// One capture record: counted, written to the port, decoded.
    fn record(&mut self, rec: Record) -> anyhow::Result<()> {
        self.out.ended_link_lost = matches!(rec, Record::LinkReset { .. });
        self.out.records += 1;
        self.out.recorded_s = rec.t_ns() as f64 * 1e-9;
        match rec {
            Record::LinkReset { .. } => self.frames.reset_link(),
            Record::Data { bytes, .. } => {
                self.out.bytes += bytes.len() as u64;
                if let Some(p) = self.port.as_mut() {
                    serial::write_all_within(p.as_mut(), &bytes, TO_PORT_TIMEOUT).with_context(
                        || format!("writing to --to-port (no byte taken for {TO_PORT_TIMEOUT:?}?)"),
                    )?;
                }
                match self.input {
                    InputKind::Frames => {
                        // decoded first (a record holds a few frames), then handled
                        let decoded: Vec<_> = self.frames.feed(&bytes).collect();
                        for r in decoded {
                            match r {
                                Ok(f) => self.frame(f)?,
                                Err(e) if self.verbose => eprintln!("rejected chunk: {e}"),
                                Err(_) => {}
                            }
                        }
                    }
                    InputKind::Gnss => {
                        for ev in self.gnss.feed(&bytes) {
                            match ev {
                                GnssEvent::Fix(f) => self.out.gnss_fixes.push(f),
                                GnssEvent::Error(e) if self.verbose => eprintln!("{e}"),
                                GnssEvent::Error(_) => {}
                            }
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// One decoded frame: into its file, to the filter, and into the log when kept.
    fn frame(&mut self, f: Frame) -> anyhow::Result<()> {
        let log = &mut self.out.log;
        if self.keep_frames {
            log.frames.push(f);
        }
        match f.payload {
            Payload::Imu(i) => {
                if !in_order(i.sample.t_s, self.last_imu_t) {
                    self.out.imu_out_of_order += 1;
                    return Ok(());
                }
                self.last_imu_t = Some(i.sample.t_s);
                if let Some(w) = self.files.as_mut() {
                    w.imu(&i.sample)?;
                }
                if self.keep_frames || self.keep_samples {
                    log.imu.push(i.sample);
                    log.imu_status.push(i.status);
                }
                if let Some(Ok(feed)) = self.filter.as_mut() {
                    feed.imu(&i.sample);
                }
            }
            Payload::Gnss(g) => {
                if !in_order(g.t_s, self.last_gnss_t) {
                    self.out.gnss_out_of_order += 1;
                    return Ok(());
                }
                self.last_gnss_t = Some(g.t_s);
                if self.keep_frames || self.keep_samples {
                    log.gnss.push(g);
                }
                if let Some(w) = self.files.as_mut() {
                    w.gnss(&g)?;
                }
                if let Some(Ok(feed)) = self.filter.as_mut() {
                    feed.fix(&g);
                }
            }
            Payload::Nav(n) => {
                if self.keep_frames {
                    log.nav.push(n);
                }
                if let Some(w) = self.files.as_mut() {
                    w.nav(&n)?;
                }
            }
            Payload::Health(h) => {
                if self.keep_frames {
                    log.health.push(h);
                }
                if let Some(w) = self.files.as_mut() {
                    w.health(&h)?;
                }
            }
            Payload::Config(c) if self.keep_frames => log.config.push(c),
            Payload::Config(_) => {}
        }
        Ok(())
    }

    /// The end of the capture: why the replay is incomplete, the filter's result, the
    /// outputs written and moved into place.
    fn finish(
        mut self,
        a: &ReplayOptions,
        od: Option<nav_engine::run::outdir::OutDir>,
        start: Instant,
    ) -> anyhow::Result<ReplayOutcome> {
        let cap = a.capture.display();
        self.warn_incomplete(a);
        if let Some(sig) = &self.out.interrupted {
            let why = format!(
                "interrupted by {sig} after {} record(s) ({:.3} s recorded): the rest of the \
                 capture was not replayed",
                self.out.records, self.out.recorded_s
            );
            self.out.incomplete = Some(match self.out.incomplete.take() {
                Some(w) => format!("{w}; {why}"),
                None => why,
            });
        }
        let mut out = self.out;
        if a.input == InputKind::Gnss {
            out.gnss_fixes
                .extend(self.gnss.finish().into_iter().filter_map(|e| match e {
                    GnssEvent::Fix(f) => Some(f),
                    GnssEvent::Error(_) => None,
                }));
        }
        out.stats = *self.frames.stats();
        warn_rejected(a, &out.stats);
        out.wall_s = start.elapsed().as_secs_f64();
        // The filter first, so that the summary says whether its result is a navigation
        // solution; a filter run that fails still leaves the decoded files and the summary in
        // place.
        let filter = match (&a.filter, self.filter) {
            (Some(_), _) if a.input != InputKind::Frames => Err(anyhow::anyhow!(
                "--config runs the filter on wire frames: not with --input gnss"
            )),
            (Some(_), Some(feed)) => feed.and_then(FilterFeed::finish).map(Some),
            (Some(spec), None) => run_filter_on_frames(&out.log, spec).map(Some),
            (None, _) => Ok(None),
        };
        // a filter run that could not start for want of a usable fix: not a navigation
        // solution either (the replay's own outputs complete, the filter's none)
        let filter = match filter {
            Err(e) if e.is::<nav_engine::run::gnss_use::NotANavigationSolution>() => {
                let why = format!("the filter run on the capture: {e}");
                eprintln!("warning: {cap}: {why}");
                out.incomplete = Some(match out.incomplete.take() {
                    Some(w) => format!("{w}; {why}"),
                    None => why,
                });
                Ok(None)
            }
            other => other,
        };
        if let Ok(Some(f)) = &filter {
            if let Some(why) = not_a_navigation_solution(f) {
                eprintln!("warning: {cap}: {why}");
                out.incomplete = Some(match out.incomplete.take() {
                    Some(w) => format!("{w}; {why}"),
                    None => why,
                });
            }
        }
        let interrupted = out.interrupted.is_some();
        if let Some(od) = &od {
            match self.files.take() {
                Some(w) if interrupted => drop(w.keep_partial()?),
                Some(w) => drop(w.finish()?),
                None => {}
            }
            write_outputs(od.stage(), &out, a.input, &self.gnss)?;
        }
        // everything written moved into the output folder, the filter's outputs when it ran
        if let Some(od) = od {
            let _moving = interrupt::Stoppable::enter();
            od.commit()?;
        }
        if let Some(signal) = out.interrupted.clone() {
            // the filter's own error says the same (it saw the signal too)
            return Err(ReplayInterrupted {
                signal,
                records: out.records,
                recorded_s: out.recorded_s,
                out: a.out.clone(),
            }
            .into());
        }
        out.filter = filter?;
        if out.filter.is_some() {
            out.wall_s = start.elapsed().as_secs_f64();
        }
        Ok(out)
    }

    /// Warnings (and [`ReplayOutcome::incomplete`]) for a capture that was cut, corrupt,
    /// irregular in time or carried frames out of order.
    fn warn_incomplete(&mut self, a: &ReplayOptions) {
        let cap = a.capture.display();
        let out = &mut self.out;
        let mut why = Vec::new();
        if let Some((rec, off, n)) = out.resync.first {
            why.push(format!(
                "skipped {} corrupt byte(s) in {} stretch(es) by resynchronising on the next valid record header (the first at record {rec}, byte {off}: {n} bytes)",
                out.resync.skipped_bytes, out.resync.resyncs
            ));
        }
        if out.ended_link_lost {
            why.push(
                "the capture ends with the link lost (a link-reset record): the recording stopped before the port came back"
                    .to_string(),
            );
        }
        if !why.is_empty() {
            let why = why.join("; ");
            eprintln!("warning: {cap}: {why}");
            out.incomplete = Some(match out.incomplete.take() {
                Some(w) => format!("{w}; {why}"),
                None => why,
            });
        }
        if out.timing.backwards + out.timing.clamped_gaps > 0 {
            eprintln!(
                "warning: {cap}: {} record time(s) went backwards, {} gap(s) over --max-gap {} s (paced as --max-gap)",
                out.timing.backwards, out.timing.clamped_gaps, a.max_gap_s
            );
        }
        if out.imu_out_of_order + out.gnss_out_of_order > 0 {
            eprintln!(
                "warning: {cap}: left out {} IMU sample(s) and {} GNSS fix(es) whose time is not after the previous one (duplicated or reordered frames)",
                out.imu_out_of_order, out.gnss_out_of_order
            );
        }
    }
}

/// A warning on stderr when the decoder rejected chunks or frames were lost by sequence (the
/// decoded files hold every frame that passed; the counters are in the summary).
fn warn_rejected(a: &ReplayOptions, s: &DecoderStats) {
    if a.input != InputKind::Frames {
        return;
    }
    let rejected = [
        s.cobs_errors,
        s.overflows,
        s.length_errors,
        s.crc_errors,
        s.version_mismatches,
        s.unknown_types,
        s.invalid_fields,
        s.truncated,
    ]
    .iter()
    .map(|&n| u64::from(n))
    .sum::<u64>();
    let lost = s.lost_by_stream.iter().map(|&n| u64::from(n)).sum::<u64>();
    if rejected + lost > 0 {
        eprintln!(
            "warning: {}: {rejected} chunk(s) rejected by the frame decoder ({} CRC errors) and \
             {lost} frame(s) lost by sequence number; the outputs hold the frames that passed \
             (--verbose prints each rejected chunk with its byte offset)",
            a.capture.display(),
            s.crc_errors
        );
    }
}

/// Why the filter's result on a capture is not a navigation solution (no GNSS fix used, or
/// too few: [`nav_engine::run::gnss_use::check`]), or None when it is one.
fn not_a_navigation_solution(f: &FilterRun) -> Option<String> {
    use nav_engine::run::gnss_use::{check, GnssAccount};
    let acc = GnssAccount {
        counters: f.output.counters,
        dropped_by_quality: 0,
        fix_span_s: f.fix_span_s,
        imu_span_s: f.imu_span_s,
    };
    check(&acc)
        .err()
        .map(|e| format!("the filter run on the capture: {e}"))
}

/// Writes `replay-summary.txt` (and, for GNSS input, `gnss.txt`), each through a `.partial`
/// name and a rename; an interrupted replay's stay under their `.partial` names.
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
        "skipped bytes before header {}\ncorrupt stretches skipped {} ({} bytes)\nends with link lost {}\nrecord times backwards {}\ngaps over --max-gap {}\n",
        o.skipped_bytes,
        o.resync.resyncs,
        o.resync.skipped_bytes,
        if o.ended_link_lost { "yes" } else { "no" },
        o.timing.backwards,
        o.timing.clamped_gaps
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
            if o.interrupted.is_none() {
                rename(&tmp, &p)?;
            }
            summary.push_str(&format!("{:?}\n", gnss.stats()));
        }
    }
    let p = dir.join("replay-summary.txt");
    if o.interrupted.is_some() {
        let tmp = partial_name(&p);
        return create_new_file(&tmp)
            .and_then(|mut f| std::io::Write::write_all(&mut f, summary.as_bytes()))
            .with_context(|| format!("writing {}", tmp.display()));
    }
    write_atomically(&p, summary.as_bytes())
}
