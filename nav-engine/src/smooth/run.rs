//! A smoothed run in bounded memory (`host-sim run --smooth`): nothing of the record is held
//! whole.
//!
//! 1. **Forward**: the streaming run ([`crate::run::execute::execute_streaming`]) with the
//!    smoother's recorder, its outputs written to a temporary folder in the output folder
//!    (its `nav.txt` becomes `nav_forward.txt`, its metrics the forward metrics); the nodes go
//!    to the history's temporary file as the run goes.
//! 2. **Backward** ([`super::smooth`]): the history read from its end in blocks, the smoothed
//!    node data written to a second temporary file.
//! 3. **Smoothed outputs**: the same run again (the filter is deterministic: the same records
//!    in the same order; no coasting baselines), each record corrected as it comes
//!    ([`SmoothSink`], the smoothed node data read forward in blocks) and written by the
//!    streaming file sink ([`crate::run::sink::FileSink`]), which computes the smoothed
//!    metrics online. The innovations are recomputed against the smoothed record nearest
//!    their fix (the fixes read again as a stream, the last [`RECENT`] smoothed records kept).
//!
//! The outputs are those of [`super::apply::smooth_run`] on the run held in memory, byte for
//! byte. The temporary files and folder are removed at the end and after an error (except
//! after a fault in the middle of the forward pass: its outputs up to the fault stay in the
//! temporary folder, which the error names).

use super::apply::SmootherReport;
use super::apply::{antenna, correct, nearest, recomputed, reinnovate, smooth_epoch};
use super::{smooth, SmoothError, Smoothed, SmoothedCursor};
use crate::metrics::Metrics;
use crate::run::engine::{RunHead, RunSink};
use crate::run::execute::{execute_streaming, Source};
use crate::run::prepare::{ImuStream, Prepared};
use crate::run::sink::FileSink;
use crate::run::truth::{self, TruthFile, TruthSource};
use crate::run::{
    run_engine, CoastPlan, EpochRecord, FixSource, InnovationRecord, OutageSnapshot, RunError,
    RunOutput,
};
use anyhow::Context;
use nav_core::types::{GnssFix, NavSolution};
use nav_io::IoError;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};

/// Smoothed navigation records kept for the innovations' nearest record (a fix's innovation
/// record comes within a few IMU epochs of its time).
pub const RECENT: usize = 4096;

/// What a smoothed run returns (its outputs are in the output folder).
#[derive(Debug)]
pub struct SmoothedRun {
    /// The forward run's summary (no records, no history).
    pub forward: RunOutput,
    /// Metrics of the forward solution (with the coasting baselines).
    pub forward_metrics: Metrics,
    /// Metrics of the smoothed solution.
    pub smoothed_metrics: Metrics,
    /// Sizes and times of the smoother.
    pub report: SmootherReport,
}

/// Makes the text of `metrics.json` from the forward metrics, the smoothed ones, the
/// smoother's report and the forward run's summary.
pub type MetricsJson<'a> =
    dyn Fn(&Metrics, &Metrics, &SmootherReport, &RunOutput) -> anyhow::Result<String> + 'a;

/// Runs a prepared case smoothed (see the module notes) with the outputs in `dir`: `nav.txt`,
/// `std.txt`, `bias.txt`, `innovations.txt` of the smoothed solution, `metrics.json` (text
/// from `json`) and `nav_forward.txt`. `imu`, `truth`: the streamed IMU (with its GNSS) and
/// truth files of [`crate::run::prepare::load`] with streaming (None: the case's data in
/// memory). `p.opts.smoother_history` must be set. `nav_rate_hz`: rate of `nav.txt` and
/// `nav_forward.txt` (None: every IMU epoch).
pub fn execute_smoothed(
    p: &Prepared,
    imu: Option<&ImuStream>,
    truth: Option<&TruthFile>,
    dir: &Path,
    nav_rate_hz: Option<f64>,
    json: &MetricsJson<'_>,
    progress: &mut dyn FnMut(usize, usize),
) -> anyhow::Result<SmoothedRun> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let tmp = tempfile::Builder::new()
        .prefix(".smooth-forward-")
        .tempdir_in(dir)
        .with_context(|| format!("creating a temporary folder in {}", dir.display()))?;
    let (mut fwd, forward_metrics) =
        match execute_streaming(p, imu, truth, tmp.path(), &[], nav_rate_hz, progress) {
            Ok(r) => r,
            Err(e) => {
                // a fault mid-run leaves the forward outputs up to it: kept where the error
                // says they are
                let partial = std::fs::read_dir(tmp.path()).is_ok_and(|mut d| d.next().is_some());
                if partial {
                    let _ = tmp.keep();
                    return Err(e.context("the forward pass of the smoother (not smoothed)"));
                }
                return Err(e.context("the forward pass of the smoother (no output written)"));
            }
        };
    let h = fwd.history.take().ok_or(SmoothError::Empty)?;
    let t = std::time::Instant::now();
    let sm = smooth(&h)?;
    let backward_s = t.elapsed().as_secs_f64();

    let t = std::time::Instant::now();
    let opts = &p.opts;
    let start = truth::start_records(opts, truth)?;
    let init_truth = start.as_deref().or(p.case.truth.as_deref());
    let metrics_truth: Option<TruthSource<'_>> = match (truth, &p.case.truth) {
        (Some(f), _) => Some(f.records()),
        (None, Some(v)) => Some(Box::new(v.iter().copied().map(Ok))),
        (None, None) => None,
    };
    let files = FileSink::create(dir, p.week, nav_rate_hz, &opts.outages, metrics_truth)?;
    let gnss = imu.and_then(|s| s.gnss.as_ref());
    let fixes: FixSource<'_> = match gnss {
        Some(g) => g.source()?,
        None => Box::new(p.case.gnss.iter().copied().map(Ok)),
    };
    let (lever, dt_off) = antenna(&fwd);
    let mut sink = SmoothSink::new(files, &sm, fixes, lever, dt_off);
    let coast = CoastPlan {
        raw: false,
        static_gyro_bias: false,
    };
    let quiet = &mut |_: usize, _: usize| {};
    let res = Source::Files(imu)
        .open(p, init_truth)
        .and_then(|st| run_engine(st, opts, coast, &mut sink, quiet));
    let res = res.and_then(|_| sink.end());
    if let Some(e) = sink.err.take() {
        return Err(e.into());
    }
    res.context("the smoothed pass")?;
    let mut files = sink.inner;
    files.check_truth_rest()?;
    let apply_s = t.elapsed().as_secs_f64();
    let report = SmootherReport::new(&h, &sm, backward_s, apply_s);
    drop(h);
    let smoothed_metrics = files
        .finish(&fwd, None, |ms| json(&forward_metrics, ms, &report, &fwd))
        .with_context(|| format!("writing the outputs in {}", dir.display()))?;
    let from = tmp.path().join("nav.txt");
    let to = dir.join("nav_forward.txt");
    std::fs::rename(&from, &to).map_err(|source| IoError::Write {
        path: to.clone(),
        source,
    })?;
    tmp.close()
        .with_context(|| format!("removing the temporary folder in {}", dir.display()))?;
    Ok(SmoothedRun {
        forward: fwd,
        forward_metrics,
        smoothed_metrics,
        report,
    })
}

/// A run sink that corrects every record with the smoothed solution and hands it on (see the
/// module notes); the records must come in time order, as a run makes them.
pub struct SmoothSink<'a, S: RunSink> {
    /// The sink the smoothed records go to.
    inner: S,
    nav: SmoothedCursor<'a>,
    epochs: SmoothedCursor<'a>,
    fixes: FixSource<'a>,
    /// The first fix not yet passed (None: not read yet, or the end).
    fix: Option<GnssFix>,
    fixes_ended: bool,
    lever: [f64; 3],
    dt_off: f64,
    /// The last smoothed navigation records (at most [`RECENT`]).
    recent: VecDeque<NavSolution>,
    /// Records have left `recent`.
    dropped: bool,
    /// Innovation records waiting for the smoothed record after their fix.
    pending: VecDeque<InnovationRecord>,
    /// The smoother's error that stopped the run.
    err: Option<SmoothError>,
}

impl<'a, S: RunSink> SmoothSink<'a, S> {
    /// Over `inner`, with the smoothed solution `sm`, the run's fixes in time order, the
    /// antenna lever arm (m, body) and GNSS time offset (s) to recompute the innovations.
    pub fn new(
        inner: S,
        sm: &'a Smoothed,
        fixes: FixSource<'a>,
        lever: [f64; 3],
        dt_off: f64,
    ) -> Self {
        Self {
            inner,
            nav: sm.cursor(),
            epochs: sm.cursor(),
            fixes,
            fix: None,
            fixes_ended: false,
            lever,
            dt_off,
            recent: VecDeque::new(),
            dropped: false,
            pending: VecDeque::new(),
            err: None,
        }
    }

    /// The sink the records went to.
    pub fn into_inner(self) -> S {
        self.inner
    }

    /// After the last record: the waiting innovation records handed on.
    pub fn end(&mut self) -> Result<(), RunError> {
        self.flush(true)
    }

    /// Keeps a smoother error and turns it into the run's error.
    fn fail(&mut self, e: SmoothError) -> RunError {
        let r = RunError::Output(IoError::Write {
            path: PathBuf::from("(smoother)"),
            source: std::io::Error::other(e.to_string()),
        });
        self.err.get_or_insert(e);
        r
    }

    /// The fix at `t_s` (the first fix at or after it, if at it).
    fn fix_at(&mut self, t_s: f64) -> Result<Option<GnssFix>, RunError> {
        loop {
            match self.fix {
                Some(f) if f.t_s < t_s => self.fix = None,
                Some(f) => return Ok((f.t_s == t_s).then_some(f)),
                None if self.fixes_ended => return Ok(None),
                None => match self.fixes.next() {
                    Some(f) => self.fix = Some(f?),
                    None => self.fixes_ended = true,
                },
            }
        }
    }

    /// Hands on the waiting innovation records whose nearest smoothed record is known (all at
    /// the `end`).
    fn flush(&mut self, end: bool) -> Result<(), RunError> {
        while let Some(r) = self.pending.front() {
            let redo = recomputed(r.used);
            if redo && !end && !self.recent.back().is_some_and(|b| b.t_s >= r.t_s) {
                break;
            }
            let Some(mut r) = self.pending.pop_front() else {
                break;
            };
            if redo {
                if let Some(fix) = self.fix_at(r.t_s)? {
                    let recent = self.recent.make_contiguous();
                    if self.dropped && recent.first().is_none_or(|s| s.t_s >= fix.t_s) {
                        let oldest = recent.first().map_or(f64::NAN, |s| s.t_s);
                        let e = SmoothError::OutOfOrder(fix.t_s, oldest);
                        return Err(self.fail(e));
                    }
                    if let Some(s) = nearest(recent, fix.t_s) {
                        reinnovate(&mut r, &fix, s, &self.lever, self.dt_off);
                    }
                }
            }
            self.inner.innovation(&r)?;
        }
        Ok(())
    }
}

impl<S: RunSink> RunSink for SmoothSink<'_, S> {
    fn start(&mut self, head: &RunHead<'_>) -> Result<(), RunError> {
        self.inner.start(head)
    }

    fn nav(&mut self, s: &NavSolution) -> Result<(), RunError> {
        let s = match self.nav.at(s.t_s) {
            Ok(Some(p)) => correct(s, &p),
            Ok(None) => *s,
            Err(e) => return Err(self.fail(e)),
        };
        if self.recent.len() >= RECENT {
            self.recent.pop_front();
            self.dropped = true;
        }
        self.recent.push_back(s);
        self.flush(false)?;
        self.inner.nav(&s)
    }

    fn epoch(&mut self, mut r: EpochRecord) -> Result<(), RunError> {
        match self.epochs.at(r.t_s) {
            Ok(Some(p)) => smooth_epoch(&mut r, &p),
            Ok(None) => {}
            Err(e) => return Err(self.fail(e)),
        }
        self.inner.epoch(r)
    }

    fn innovation(&mut self, r: &InnovationRecord) -> Result<(), RunError> {
        self.pending.push_back(*r);
        self.flush(false)
    }

    fn snapshot(&mut self, s: &OutageSnapshot) {
        self.inner.snapshot(s);
    }

    fn wants_epochs(&self) -> bool {
        self.inner.wants_epochs()
    }
}
