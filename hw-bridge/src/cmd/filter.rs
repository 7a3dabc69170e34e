//! `replay --config`: the run engine (`nav_engine`) on a replay's frames, as `host-sim run`
//! runs it on files: pushed into a live run ([`nav_engine::LiveRun`]) as they are decoded
//! ([`FilterFeed`]), or on frames decoded into memory ([`run_filter_on_frames`]).

use super::*;
use crate::frames::FrameLog;
use anyhow::{bail, Context};
use nav_core::types::{GnssFix, ImuSample};
use nav_engine::run::gnss_use::{time_span, widen_span};
use std::path::Path;
use std::time::Instant;

/// The host filter run on a replay's frames (`replay --config`).
#[derive(Debug)]
pub struct FilterRun {
    /// The filter's output (the record lists are empty when the records went to files).
    pub output: nav_engine::RunOutput,
    /// Metrics (against the truth when there is one).
    pub metrics: nav_engine::Metrics,
    /// Wall time of the filter run, s.
    pub wall_s: f64,
    /// First and last time of the IMU samples given to the filter, s (None: none).
    pub imu_span_s: Option<(f64, f64)>,
    /// First and last time of the GNSS fixes given to the filter, s (None: none).
    pub fix_span_s: Option<(f64, f64)>,
}

/// Decodes a capture as frames, feeding the recorded chunks in order (no timing, no port);
/// every frame is kept in [`ReplayOutcome::log`].
pub fn decode_capture(path: &Path) -> anyhow::Result<ReplayOutcome> {
    replay(&ReplayOptions::new(path))
}

/// Runs the host filter on decoded frames in memory the way `host-sim run` runs `spec` on
/// files: the run is loaded by the run engine (`nav_engine::load`), then its IMU samples and
/// GNSS fixes are replaced by the frames' (the configuration's GNSS sigma scale applied by
/// the engine, as on files). Same samples, same options: the same solution, bit for bit. The
/// output holds every record.
pub fn run_filter_on_frames(
    log: &FrameLog,
    spec: &nav_engine::RunSpec,
) -> anyhow::Result<FilterRun> {
    let loaded = nav_engine::load(spec, false)
        .with_context(|| format!("preparing the filter from {}", spec.config.display()))?;
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    let mut prepared = loaded.prepared;
    if log.imu.is_empty() {
        bail!("the capture holds no IMU frame: nothing to run the filter on");
    }
    prepared.case.imu = log.imu.clone();
    // the samples are the capture's now: messages name IMU sample indices, not the
    // configuration's file lines
    prepared.case.imu_origin = None;
    prepared.case.gnss = log.gnss.clone();
    let t = Instant::now();
    let imu_span_s = time_span(log.imu.iter().map(|s| s.t_s));
    let fix_span_s = time_span(log.gnss.iter().map(|g| g.t_s));
    let fixes = (
        log.gnss.len() as u64,
        log.gnss.iter().filter(|g| !g.is_valid()).count() as u64,
    );
    let (output, metrics) = nav_engine::execute(&prepared, &mut |_, _| {})
        .map_err(|e| explain_start_failure(e, fixes, imu_span_s, fix_span_s))?;
    Ok(FilterRun {
        output,
        metrics,
        wall_s: t.elapsed().as_secs_f64(),
        imu_span_s,
        fix_span_s,
    })
}

/// The host filter fed a replay's frames as they are decoded: a live run writing the
/// outputs of `host-sim run` (`nav.txt`, `std.txt`, `bias.txt`, `innovations.txt`,
/// `metrics.json`) into a folder as the filter goes. Memory does not grow with the capture.
pub struct FilterFeed {
    run: Option<nav_engine::LiveRun>,
    stage: std::path::PathBuf,
    started: Instant,
    imu_span_s: Option<(f64, f64)>,
    fix_span_s: Option<(f64, f64)>,
    /// GNSS fixes given, and how many of them invalid.
    fixes: (u64, u64),
}

/// The error of a filter run on frames that did not start because the static alignment found
/// no valid GNSS fix in its window (`nav_engine::run::RunError::NoFixToAlign`): when no fix of
/// the frames was usable (none; all before, or all after, the IMU frames; all invalid), a
/// [`NotANavigationSolution`](nav_engine::run::gnss_use::NotANavigationSolution) naming where
/// they went; otherwise `e` as it was. `fixes`: the fixes given and how many were invalid.
fn explain_start_failure(
    e: anyhow::Error,
    fixes: (u64, u64),
    imu_span_s: Option<(f64, f64)>,
    fix_span_s: Option<(f64, f64)>,
) -> anyhow::Error {
    use nav_engine::run::gnss_use::{not_started, GnssAccount};
    use nav_engine::run::{RunCounters, RunError};
    let Some(&RunError::NoFixToAlign { from_s, to_s }) =
        e.chain().find_map(|c| c.downcast_ref::<RunError>())
    else {
        return e;
    };
    let (total, invalid) = fixes;
    let mut c = RunCounters {
        gnss_total: total,
        ..RunCounters::default()
    };
    match (imu_span_s, fix_span_s) {
        (Some((i0, _)), Some((_, f1))) if f1 < i0 => {
            c.gnss_before_run = total;
            c.gnss_outside_run = total;
        }
        (Some((_, i1)), Some((f0, _))) if f0 > i1 => c.gnss_outside_run = total,
        _ => c.gnss_invalid = invalid,
    }
    let a = GnssAccount {
        counters: c,
        dropped_by_quality: 0,
        fix_span_s,
        imu_span_s,
    };
    let why = format!(
        "the static alignment ([init.align]) needs a valid GNSS fix during its window \
         {from_s:.3} .. {to_s:.3} s"
    );
    match not_started(&a, &why) {
        Some(n) => anyhow::Error::new(n),
        None => e,
    }
}

impl FilterFeed {
    /// Loads the run `spec` as `host-sim run` does (its IMU and GNSS files are not read: the
    /// frames replace them; its truth file is read as the solution advances) and starts the
    /// live run writing into `stage` (the stage folder of the replay's output folder, moved
    /// into place by the replay).
    pub fn start(spec: &nav_engine::RunSpec, stage: &Path) -> anyhow::Result<Self> {
        let loaded = nav_engine::load(spec, true)
            .with_context(|| format!("preparing the filter from {}", spec.config.display()))?;
        for w in &loaded.warnings {
            eprintln!("warning: {w}");
        }
        std::fs::create_dir_all(stage).with_context(|| format!("creating {}", stage.display()))?;
        let run = nav_engine::LiveRun::to_dir(
            loaded.prepared,
            loaded.truth_stream,
            stage.to_path_buf(),
            loaded.inputs,
            loaded.nav_rate_hz,
            true,
        );
        Ok(Self {
            run: Some(run),
            stage: stage.to_path_buf(),
            started: Instant::now(),
            imu_span_s: None,
            fix_span_s: None,
            fixes: (0, 0),
        })
    }

    /// Gives the filter the next IMU sample (a run that has ended takes no more: its error
    /// comes with [`Self::finish`]).
    pub fn imu(&mut self, s: &ImuSample) {
        self.imu_span_s = widen_span(self.imu_span_s, s.t_s);
        if let Some(ses) = self.run.as_mut() {
            // a run that has ended takes no more (`finish` gives its error)
            let _ = ses.push_imu(*s);
        }
    }

    /// Gives the filter the next GNSS fix.
    pub fn fix(&mut self, f: &GnssFix) {
        self.fix_span_s = widen_span(self.fix_span_s, f.t_s);
        self.fixes.0 += 1;
        self.fixes.1 += u64::from(!f.is_valid());
        if let Some(ses) = self.run.as_mut() {
            let _ = ses.push_fix(*f);
        }
    }

    /// Ends the input and waits for the filter: its summary and metrics, with its outputs
    /// written in the stage folder.
    pub fn finish(mut self) -> anyhow::Result<FilterRun> {
        let Some(ses) = self.run.take() else {
            bail!("the filter has finished already");
        };
        if self.imu_span_s.is_none() {
            // nothing run: the live run's empty files are not outputs
            let _ = ses.finish();
            for name in nav_engine::run::output::OUTPUT_NAMES {
                let _ =
                    std::fs::remove_file(nav_engine::run::output::partial_path(&self.stage, name));
            }
            bail!("the capture holds no IMU frame: nothing to run the filter on");
        }
        let (output, metrics) = match ses.finish() {
            Ok(r) => r,
            Err(e) => {
                let e = explain_start_failure(e, self.fixes, self.imu_span_s, self.fix_span_s);
                if e.is::<nav_engine::run::gnss_use::NotANavigationSolution>() {
                    // nothing run: the live run's empty files are not outputs
                    for name in nav_engine::run::output::OUTPUT_NAMES {
                        let _ = std::fs::remove_file(nav_engine::run::output::partial_path(
                            &self.stage,
                            name,
                        ));
                    }
                }
                return Err(e);
            }
        };
        Ok(FilterRun {
            output,
            metrics,
            wall_s: self.started.elapsed().as_secs_f64(),
            imu_span_s: self.imu_span_s,
            fix_span_s: self.fix_span_s,
        })
    }
}
