//! One live run: samples and fixes pushed as they come (a serial link, a capture being
//! decoded), the outputs written as the filter goes, the summary at the end.
//!
//! ```text
//! let mut s = LiveRun::to_dir(prepared, truth_file, dir, inputs, nav_rate_hz, false);
//! for each decoded frame: s.push_imu(sample)? or s.push_fix(fix)?
//! let (output, metrics) = s.finish()?;
//! ```
//!
//! The filter is the engine's ([`super::run_engine`]) run on a worker thread of its own by
//! [`super::execute::run_to_dir`], exactly as `host-sim run` runs it on files: the same
//! outputs, byte for byte. The pushed samples and fixes wait in two queues ([`Feeds`]) that the
//! engine reads as streams. The pushing side blocks while [`QUEUE`] samples (or fixes) wait,
//! unless the engine is waiting for the other kind (it reads fixes ahead of the samples at the
//! start and up to the end of an imposed outage, and samples ahead of the fixes for its
//! start-up window): memory stays flat whatever the length of the record, and the two sides
//! cannot wait for each other.

use super::execute::{run_to_dir, DirOutput, Source};
use super::prepare::Prepared;
use super::truth::TruthFile;
use super::{FixSource, ImuItem, ImuSourceInfo, RunOutput, Streams};
use crate::metrics::Metrics;
use nav_core::types::{GnssFix, ImuSample, NavSolution};
use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;

/// Samples (and fixes) a pushing side may get ahead of the filter before it waits.
pub const QUEUE: usize = 8192;

#[derive(Debug, Default)]
struct Queues {
    imu: VecDeque<ImuItem>,
    fixes: VecDeque<GnssFix>,
    /// No more pushes (the live run is finishing).
    closed: bool,
    /// The engine waits for a sample / a fix.
    wants_imu: bool,
    wants_fix: bool,
    /// The run has ended (normally or not): pushes are refused.
    ended: bool,
}

#[derive(Debug, Default)]
struct Shared {
    q: Mutex<Queues>,
    cv: Condvar,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Queues> {
        // a poisoned lock: the engine thread panicked; its queues are still consistent
        self.q.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn wait<'g>(&self, g: MutexGuard<'g, Queues>) -> MutexGuard<'g, Queues> {
        self.cv.wait(g).unwrap_or_else(|p| p.into_inner())
    }
}

/// The engine's side of a live run's queues: its IMU and fix streams.
#[derive(Debug, Clone)]
pub struct Feeds {
    shared: Arc<Shared>,
}

impl Feeds {
    /// The queues as the engine's streams (samples named by their index: they come from no
    /// file).
    pub fn streams<'b>(self, truth: Option<&'b [NavSolution]>) -> Streams<'b> {
        let fixes = self.clone();
        let gnss: FixSource<'b> = Box::new(std::iter::from_fn(move || fixes.next_fix().map(Ok)));
        Streams {
            imu: Box::new(std::iter::from_fn(move || self.next_imu().map(Ok))),
            info: ImuSourceInfo::default(),
            gnss,
            truth,
        }
    }

    fn next_imu(&self) -> Option<ImuItem> {
        let mut g = self.shared.lock();
        loop {
            if let Some(it) = g.imu.pop_front() {
                g.wants_imu = false;
                self.shared.cv.notify_all();
                return Some(it);
            }
            if g.closed {
                return None;
            }
            g.wants_imu = true;
            self.shared.cv.notify_all();
            g = self.shared.wait(g);
        }
    }

    fn next_fix(&self) -> Option<GnssFix> {
        let mut g = self.shared.lock();
        loop {
            if let Some(f) = g.fixes.pop_front() {
                g.wants_fix = false;
                self.shared.cv.notify_all();
                return Some(f);
            }
            if g.closed {
                return None;
            }
            g.wants_fix = true;
            self.shared.cv.notify_all();
            g = self.shared.wait(g);
        }
    }
}

/// Marks the queues ended when the engine's thread leaves (however it leaves), so that a
/// pushing side waiting for room wakes up.
struct EndOnDrop(Arc<Shared>);

impl Drop for EndOnDrop {
    fn drop(&mut self) {
        let mut g = self.0.lock();
        g.ended = true;
        g.imu.clear();
        g.fixes.clear();
        self.0.cv.notify_all();
    }
}

/// Why a push was refused: the run has already ended (a fault, an output error, an
/// interruption); [`LiveRun::finish`] says why.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("the run has ended; finishing the live run says why")]
pub struct Ended;

/// The engine's thread of a live run, returning the run's summary and metrics.
type Worker = JoinHandle<anyhow::Result<(RunOutput, Metrics)>>;

/// One run fed sample by sample (module notes).
#[derive(Debug)]
pub struct LiveRun {
    shared: Arc<Shared>,
    worker: Option<Result<Worker, String>>,
    /// Samples pushed so far.
    imu_pushed: usize,
}

impl LiveRun {
    /// A live run writing the outputs of `host-sim run` (`nav.txt`, `std.txt`, `bias.txt`,
    /// `innovations.txt`, `metrics.json`) into `dir` as the filter goes
    /// ([`super::execute::execute_streaming`]'s rules: a stage folder, `*.partial` names,
    /// moved in at the end; with `staged`, `dir` is the stage folder of an
    /// [`super::outdir::OutDir`] the caller holds and commits). `p` gives the options, week and (when loaded) truth; `truth` a
    /// truth file read as the solution advances; `inputs` the files the run reads (refused as
    /// `dir`); `nav_rate_hz` the rate of `nav.txt` (None: every IMU epoch). The samples and
    /// fixes of `p.case` are not used: they are pushed.
    pub fn to_dir(
        p: Prepared,
        truth: Option<TruthFile>,
        dir: PathBuf,
        inputs: Vec<PathBuf>,
        nav_rate_hz: Option<f64>,
        staged: bool,
    ) -> Self {
        let shared = Arc::new(Shared::default());
        let feeds = Feeds {
            shared: shared.clone(),
        };
        let worker = std::thread::Builder::new()
            .name("live-run".into())
            .spawn(move || {
                let _end = EndOnDrop(feeds.shared.clone());
                let to = DirOutput {
                    dir: &dir,
                    inputs: &inputs,
                    nav_rate_hz,
                    staged,
                };
                run_to_dir(
                    &p,
                    Source::Pushed(feeds),
                    truth.as_ref(),
                    &to,
                    &mut |_, _| {},
                )
            });
        let worker = worker.map_err(|e| {
            // no thread: the live run ends at once and `finish` says why
            shared.lock().ended = true;
            e.to_string()
        });
        Self {
            shared,
            worker: Some(worker),
            imu_pushed: 0,
        }
    }

    /// Pushes the next IMU sample (time order; the engine checks it). Waits while the filter
    /// is [`QUEUE`] samples behind; [`Ended`] once the run has ended.
    pub fn push_imu(&mut self, sample: ImuSample) -> Result<(), Ended> {
        let mut g = self.shared.lock();
        while g.imu.len() >= QUEUE && !g.wants_fix && !g.ended {
            g = self.shared.wait(g);
        }
        if g.ended {
            return Err(Ended);
        }
        self.imu_pushed += 1;
        g.imu.push_back(ImuItem { sample, line: 0 });
        self.shared.cv.notify_all();
        Ok(())
    }

    /// Pushes the next GNSS fix (time order). Waits while [`QUEUE`] fixes wait for the
    /// filter; [`Ended`] once the run has ended.
    pub fn push_fix(&mut self, fix: GnssFix) -> Result<(), Ended> {
        let mut g = self.shared.lock();
        while g.fixes.len() >= QUEUE && !g.wants_imu && !g.ended {
            g = self.shared.wait(g);
        }
        if g.ended {
            return Err(Ended);
        }
        g.fixes.push_back(fix);
        self.shared.cv.notify_all();
        Ok(())
    }

    /// IMU samples pushed so far.
    pub fn imu_pushed(&self) -> usize {
        self.imu_pushed
    }

    /// Ends the input and waits for the run: its summary and metrics (the outputs written and
    /// moved into place), or the run's error as [`super::execute::execute_streaming`] gives it.
    pub fn finish(mut self) -> anyhow::Result<(RunOutput, Metrics)> {
        {
            let mut g = self.shared.lock();
            g.closed = true;
            self.shared.cv.notify_all();
        }
        let w = match self.worker.take() {
            Some(Ok(w)) => w,
            Some(Err(e)) => anyhow::bail!("starting the live run's thread: {e}"),
            None => anyhow::bail!("the live run has finished already"),
        };
        match w.join() {
            Ok(r) => r,
            Err(_) => Err(anyhow::anyhow!(
                "the live run's thread panicked (a bug): the outputs are incomplete"
            )),
        }
    }
}

impl Drop for LiveRun {
    fn drop(&mut self) {
        // a live run dropped unfinished: the input ends there and the run completes
        let mut g = self.shared.lock();
        g.closed = true;
        self.shared.cv.notify_all();
    }
}
