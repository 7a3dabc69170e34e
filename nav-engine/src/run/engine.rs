//! The streaming run engine: the filter consumes IMU samples as an iterator (a file reader,
//! a generator, or a slice in memory) and hands every record to a [`RunSink`] as it is made.
//!
//! Memory does not grow with the record: the engine keeps a bounded buffer of the first
//! samples ([`NOMINAL_WINDOW`] samples, or the static alignment window when longer), one
//! sample of look-ahead (the nearest-epoch rule needs the next sample's time), the GNSS fixes
//! (small: one per second) and, while an outage is open, a free-inertial coaster per coasting
//! mode fed the same raw samples ([`Coaster`], the online form of
//! [`super::coast::coast_outages`]). What the sink keeps is its business: the in-memory
//! [`Collect`] sink keeps everything (tests, `diagnose`, the study), the file sink of
//! `host-sim run` writes as it goes.
//!
//! # The loop is the navigator's
//!
//! Start-up, the IMU guard and the nearest-epoch fix scheduling are
//! `nav_core::navigator::Navigator`'s (given start: the state `init` found, the guard's
//! nominal interval set here), run with the engine's hooks ([`NavHooks`](nav_core::navigator::NavHooks)): the records of an
//! epoch, its outage snapshots and the coasters they start are made when the navigator
//! completes the epoch (its fixes applied, before the next sample is integrated); fixes inside
//! an imposed outage are withheld, their innovation taken at the epoch of use; the smoother's
//! recorder observes every covariance prediction; the aiding updates follow each integrated
//! sample. Fixes are pushed to the navigator before the first sample after them (they can be
//! due at the epoch before it; at most [`FIX_QUEUE`] wait).
//!
//! The fixes are a stream as well ([`ahead::FixAhead`] over a [`ahead::FixSource`]): the
//! engine holds the fixes not yet pushed, those of the next outage its snapshot takes (read
//! ahead to the outage's end), and during the start-up those the initialisation looked at;
//! the rest of the stream is read only to count it at the end (`gnss_total`).
//!
//! # Differences from loading the record whole
//!
//! - The nominal IMU interval (gap detection) is the median interval of the first
//!   [`NOMINAL_WINDOW`] samples of the record (the whole record before): identical on regular
//!   data; on a record whose rate changes after the first 10 s at 200 Hz the nominal interval
//!   follows the start.
//! - An IMU time that does not increase is found when the engine reaches it (before: before
//!   the run started): the run stops there with [`RunError::Options`] naming the sample.

use super::coast::{CoastMode, CoastTrack};
use super::init::{self, InitData, InitReport};
use super::{
    block_estimates, effect_estimates, filter_err, gating_report, outage, position_innovation,
    state_names, Decimator, EpochRecord, ImuEvent, ImuReport, InnovationRecord, Model,
    OutageSnapshot, RunCounters, RunError, RunOptions, RunOutput, MAX_IMU_EVENTS,
};
use crate::run::FaultCause;
use nav_core::imu_guard::{GapIncrements, GuardConfig, ImuGuard};
use nav_core::model::{ImuCorrection, Layout};
use nav_core::navigator::{
    nearest_epoch_horizon, AlignMode, ImuEvent as ImuEventNav, Navigator, NavigatorConfig,
    NavigatorError, START_TOLERANCE_S,
};
use nav_core::scalar::Scalar;
use nav_core::strapdown::{NavState, Strapdown, MAX_DT_S};
use nav_core::types::{GnssFix, ImuSample, NavSolution};
use std::collections::VecDeque;
use std::path::PathBuf;

pub mod ahead;
mod hooks;
use ahead::{FixAhead, FixSource};
use hooks::EngineHooks;
use std::cell::RefCell;

/// Samples from the start of the record whose median interval is the nominal IMU interval.
pub const NOMINAL_WINDOW: usize = 2001;

/// One IMU sample with the file line it came from (0 when unknown).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ImuItem {
    /// The sample.
    pub sample: ImuSample,
    /// File line (1-based; 0 when unknown).
    pub line: usize,
}

/// Where IMU samples come from (for messages and the gap rule).
#[derive(Debug, Clone, Default)]
pub struct ImuSourceInfo {
    /// The file (None for data in memory).
    pub path: Option<PathBuf>,
    /// True when each increment covers the whole interval since the previous sample even
    /// across a time gap (see [`nav_io::ImuOrigin::increments_span_gaps`]).
    pub increments_span_gaps: bool,
}

impl ImuSourceInfo {
    /// `file line N` of a sample (`IMU sample index` without a file or line), as
    /// [`super::CaseData::locate_imu`] says it.
    pub fn locate(&self, index: usize, line: usize) -> String {
        match &self.path {
            Some(p) if line > 0 => format!("{} line {line}", p.display()),
            _ => format!("IMU sample {index}"),
        }
    }
}

/// The run's state-layout description, given to the sink before the first record.
#[derive(Debug, Clone)]
pub struct RunHead<'a> {
    /// The model run.
    pub model: Model,
    /// Names (with units) of the error states.
    pub state_names: &'a [String],
    /// Coasting tracks the run makes per outage it reaches (its coasting modes, see
    /// [`CoastPlan`]; 0 without coasting).
    pub coast_modes: usize,
}

/// Receives the records of a run as they are made.
pub trait RunSink {
    /// Called once before the first record.
    fn start(&mut self, _head: &RunHead<'_>) -> Result<(), RunError> {
        Ok(())
    }
    /// A navigation record at the nav rate ([`super::RecordOptions::nav_rate_hz`]).
    fn nav(&mut self, s: &NavSolution) -> Result<(), RunError>;
    /// A record at the epoch rate (standard deviations and estimates).
    fn epoch(&mut self, r: EpochRecord) -> Result<(), RunError>;
    /// A GNSS fix against the solution (every fix processed, in time order).
    fn innovation(&mut self, r: &InnovationRecord) -> Result<(), RunError>;
    /// The filter state at the start of an outage.
    fn snapshot(&mut self, _s: &OutageSnapshot) {}
    /// A finished coasting track (`mode` indexes the coasting modes the run was given).
    fn coast(&mut self, _mode: usize, _track: CoastTrack) {}
    /// True when the sink wants [`Self::epoch`] records (building them costs).
    fn wants_epochs(&self) -> bool {
        true
    }
    /// True when the sink reads the standard deviations of the [`Self::nav`] records
    /// (`pos_std_ned_m`, `vel_std_ned_mps`, `att_std_rad`); when false, a navigation record
    /// taken without an epoch record carries NaN there (the attitude sigmas cost a matrix
    /// inverse and four trigonometric calls per record).
    fn wants_nav_std(&self) -> bool {
        true
    }
}

/// The in-memory sink: keeps every record (what [`super::run_filter`] returns).
#[derive(Debug, Default)]
pub struct Collect {
    /// Navigation records.
    pub nav: Vec<NavSolution>,
    /// Epoch records.
    pub epochs: Vec<EpochRecord>,
    /// GNSS fixes against the solution.
    pub innovations: Vec<InnovationRecord>,
    /// Outage snapshots.
    pub snapshots: Vec<OutageSnapshot>,
    /// Coasting tracks per mode.
    pub coast: Vec<(usize, CoastTrack)>,
}

impl RunSink for Collect {
    fn nav(&mut self, s: &NavSolution) -> Result<(), RunError> {
        self.nav.push(*s);
        Ok(())
    }
    fn epoch(&mut self, r: EpochRecord) -> Result<(), RunError> {
        self.epochs.push(r);
        Ok(())
    }
    fn innovation(&mut self, r: &InnovationRecord) -> Result<(), RunError> {
        self.innovations.push(*r);
        Ok(())
    }
    fn snapshot(&mut self, s: &OutageSnapshot) {
        self.snapshots.push(*s);
    }
    fn coast(&mut self, mode: usize, track: CoastTrack) {
        self.coast.push((mode, track));
    }
}

impl Collect {
    /// Moves the records into a run output made by the engine (whose record lists are empty).
    pub fn fill(self, out: &mut RunOutput) {
        out.nav = self.nav;
        out.epochs = self.epochs;
        out.innovations = self.innovations;
        out.snapshots = self.snapshots;
    }
}

/// Which free-inertial coasting baselines the engine runs online through every outage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CoastPlan {
    /// No sensor-error correction ([`CoastMode::Raw`], mode 0).
    pub raw: bool,
    /// The static start-up gyro bias only, when the initialisation measured one
    /// ([`CoastMode::Fixed`], mode 1).
    pub static_gyro_bias: bool,
}

/// Free-inertial integration from an outage snapshot, fed the same raw samples as the run
/// (the online form of [`super::coast::coast_outages`]; identical tracks).
#[derive(Debug)]
pub struct Coaster {
    mode: usize,
    outage: usize,
    end_s: f64,
    corr: ImuCorrection,
    mech: Strapdown,
    nav: Vec<NavSolution>,
    fixes: Vec<GnssFix>,
    /// Index in the run's fixes of each of `fixes`.
    fix_index: Vec<usize>,
    next_fix: usize,
    out_fixes: Vec<InnovationRecord>,
    lever_arm_m: [f64; 3],
}

impl Coaster {
    fn new(
        mode: usize,
        outage: usize,
        end_s: f64,
        corr: ImuCorrection,
        state: NavState,
        (fixes, fix_index): (Vec<GnssFix>, Vec<usize>),
        lever_arm_m: [f64; 3],
    ) -> Self {
        Self {
            mode,
            outage,
            end_s,
            corr,
            mech: Strapdown::new(state),
            nav: vec![state.to_solution()],
            fixes,
            fix_index,
            next_fix: 0,
            out_fixes: Vec::new(),
            lever_arm_m,
        }
    }

    /// Integrates one raw sample (`next_t_s`: the next sample's time); true when done.
    fn step(&mut self, raw: &ImuSample, next_t_s: Option<f64>) -> bool {
        let mut s = *raw;
        let dt = s.t_s - self.mech.state().t_s;
        self.corr.apply(&mut s.dtheta_rad, &mut s.dv_mps, dt);
        if self.mech.update(&s).is_err() {
            return false;
        }
        let st = *self.mech.state();
        self.nav.push(st.to_solution());
        let dt_next = next_t_s.map_or(dt, |n| n - st.t_s);
        while let Some(f) = self.fixes.get(self.next_fix) {
            if f.t_s >= nearest_epoch_horizon(st.t_s, dt_next) {
                break;
            }
            self.next_fix += 1;
            let inn = position_innovation(&st, &self.lever_arm_m, f);
            self.out_fixes
                .push(InnovationRecord::withheld(f, self.outage, inn));
        }
        st.t_s >= self.end_s && self.next_fix >= self.fixes.len()
    }

    /// Keeps only the fixes before index `end` of the run's fixes (those the run reached).
    fn keep_fixes_before(&mut self, end: usize) {
        let n = self.fix_index.iter().take_while(|&&i| i < end).count();
        self.fixes.truncate(n);
        self.fix_index.truncate(n);
    }

    fn finish(self) -> (usize, CoastTrack) {
        (
            self.mode,
            CoastTrack {
                outage: self.outage,
                nav: self.nav,
                fixes: self.out_fixes,
            },
        )
    }
}

/// The IMU samples of a run: a bounded buffer of the first samples, then the source, with
/// one sample of look-ahead.
struct Feed<I> {
    buf: VecDeque<ImuItem>,
    src: I,
    /// Index of the next sample in the record.
    index: usize,
    /// Time of the last sample read (time order check).
    last_t: f64,
    info: ImuSourceInfo,
    peeked: Option<ImuItem>,
    /// The last sample read (an exact repeat of it is skipped).
    last: Option<ImuSample>,
    /// Exact repeats of the previous sample skipped (a record written twice), and the first
    /// of them as events.
    repeats: u64,
    repeat_events: Vec<ImuEvent>,
}

impl<I: Iterator<Item = Result<ImuItem, RunError>>> Feed<I> {
    fn new(src: I, info: ImuSourceInfo) -> Self {
        Self {
            buf: VecDeque::new(),
            src,
            index: 0,
            last_t: f64::NEG_INFINITY,
            info,
            peeked: None,
            last: None,
            repeats: 0,
            repeat_events: Vec::new(),
        }
    }

    fn read(&mut self) -> Result<Option<ImuItem>, RunError> {
        let it = loop {
            let Some(it) = self.src.next().transpose()? else {
                return Ok(None);
            };
            if !self
                .last
                .is_some_and(|p| nav_io::text::same_sample(&p, &it.sample))
            {
                break it;
            }
            // the same record again (a logger writing it twice): skipped, counted with the
            // rejected samples
            self.repeats += 1;
            if self.repeat_events.len() < MAX_IMU_EVENTS {
                let idx = self.index + self.buf.len() + usize::from(self.peeked.is_some());
                self.repeat_events.push(ImuEvent {
                    t_s: it.sample.t_s,
                    location: self.info.locate(idx, it.line),
                    what: "rejected: an exact repeat of the previous sample (same time and \
                           values)"
                        .into(),
                });
            }
        };
        self.last = Some(it.sample);
        // `index` counts the samples handed out; the buffered ones come first
        let idx = self.index + self.buf.len() + usize::from(self.peeked.is_some());
        if self.last_t.is_finite()
            && it.sample.t_s.partial_cmp(&self.last_t) != Some(std::cmp::Ordering::Greater)
        {
            return Err(RunError::Options(format!(
                "{}: IMU time {:.6} s is not after the previous sample's",
                self.info.locate(idx, it.line),
                it.sample.t_s
            )));
        }
        self.last_t = it.sample.t_s;
        Ok(Some(it))
    }

    /// Buffers samples until `enough(buffer)` or the end of the source.
    fn fill(&mut self, enough: impl Fn(&VecDeque<ImuItem>) -> bool) -> Result<(), RunError> {
        while !enough(&self.buf) {
            match self.read()? {
                Some(it) => self.buf.push_back(it),
                None => break,
            }
        }
        Ok(())
    }

    fn next(&mut self) -> Result<Option<(usize, ImuItem)>, RunError> {
        let it = match self.peeked.take() {
            Some(p) => Some(p),
            None => match self.buf.pop_front() {
                Some(b) => Some(b),
                None => self.read()?,
            },
        };
        Ok(it.map(|it| {
            let i = self.index;
            self.index += 1;
            (i, it)
        }))
    }

    fn peek(&mut self) -> Result<Option<&ImuItem>, RunError> {
        if self.peeked.is_none() {
            self.peeked = match self.buf.pop_front() {
                Some(b) => Some(b),
                None => self.read()?,
            };
        }
        Ok(self.peeked.as_ref())
    }
}

/// Median interval of the samples, s (None with fewer than two).
fn median_interval(buf: &VecDeque<ImuItem>) -> Option<f64> {
    let v: Vec<ImuSample> = buf.iter().take(NOMINAL_WINDOW).map(|i| i.sample).collect();
    super::median_imu_interval_s(&v)
}

/// Capacity of the navigator's fix queue in host runs: fixes due at one IMU epoch (more is
/// a fault: an IMU gap longer than the queue at the GNSS rate, which the guard's longest gap
/// rules out at ordinary rates).
pub const FIX_QUEUE: usize = 128;

/// Runs the filter of `layout` on a stream of IMU samples (see the module notes): the
/// navigator (`nav_core::navigator`, given start) with the engine's hooks.
///
/// Returns the run's summary as a [`RunOutput`] whose record lists are empty (the records
/// went to `sink`); a fault mid-run returns [`RunError::Fault`] with that summary.
pub(crate) fn run_layout_stream<T: Scalar, const N: usize>(
    layout: Layout,
    data: super::Streams<'_>,
    opts: &RunOptions,
    coast: CoastPlan,
    sink: &mut dyn RunSink,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<RunOutput, RunError> {
    let mut cfg = opts.filter;
    cfg.lever_arm_body_m = opts.lever_arm_m;
    cfg.validate().map_err(RunError::FilterConfig)?;
    let mut outages = opts.outages.clone();
    outage::normalise(&mut outages).map_err(RunError::Options)?;

    let mut feed = Feed::new(data.imu, data.info);
    fill_start_window(&mut feed, opts)?;
    let nominal = median_interval(&feed.buf).unwrap_or(MAX_DT_S);
    let (start, mut gnss) = initialise(&feed, data.gnss, data.truth, opts, &cfg)?;
    if let Some(fl) = start.gyro_bias_sigma_floor {
        for (s, f) in cfg.gyro.bias_init_sigma.iter_mut().zip(fl) {
            *s = s.max(f);
        }
    }
    let InitReport { t_s: t0, .. } = start.report;
    let guard_cfg = guard_config(opts, &feed.info, nominal, t0)?;
    let mut nav = navigator::<T, N>(layout, cfg, guard_cfg, &start, opts)?;
    let coast_modes = coast_modes(coast, &start.report);

    let end_s = opts.end_s.unwrap_or(f64::INFINITY);
    skip_to_initial_epoch(&mut feed, &mut nav, t0)?;
    let first = feed.index;
    let has_imu = feed.peek()?.is_some_and(|it| it.sample.t_s <= end_s);
    if !has_imu {
        return Err(RunError::NoImu);
    }
    let state_names = state_names(&layout);
    sink.start(&RunHead {
        model: opts.model,
        state_names: &state_names,
        coast_modes: coast_modes.len(),
    })?;
    // fixes before the initial epoch are not used (nor kept)
    let gi0 = gnss.first_at_or_after(t0 - START_TOLERANCE_S);
    gnss.release(gi0, f64::INFINITY);
    let mut hooks =
        engine_hooks::<T, N>(sink, opts, &outages, &coast_modes, gnss, (t0, first, gi0))?;
    hooks.want_epochs = hooks.sink.wants_epochs();
    hooks.want_nav_std = hooks.sink.wants_nav_std();
    if let Some(f) = nav.filter() {
        hooks.record(f);
    }
    if let Some(e) = hooks.err.take() {
        return Err(e);
    }
    let mut imu_report = ImuReport {
        nominal_dt_s: guard_cfg.nominal_dt_s,
        ..ImuReport::default()
    };
    let mut run = Loop {
        feed: &mut feed,
        nav: &mut nav,
        hooks: &mut hooks,
        imu_report: &mut imu_report,
        opts,
        done: 0,
        gi: gi0,
    };
    let mut fault = run.integrate(end_s, progress)?;
    if fault.is_none() {
        fault = run.last_epoch()?;
    }
    progress(run.done, run.done);
    if fault.is_none() {
        finish_coasters(&mut feed, &mut hooks)?;
    }
    let Some(filter) = nav.filter() else {
        return Err(RunError::Options("the navigator did not start".into()));
    };
    let counters = final_counters(&mut hooks, &nav, filter, &mut feed, &mut imu_report)?;
    let out = RunOutput {
        model: opts.model,
        state_names,
        nav: Vec::new(),
        epochs: Vec::new(),
        innovations: Vec::new(),
        counters,
        snapshots: Vec::new(),
        init: start.report,
        final_blocks: block_estimates(filter),
        final_effects: effect_estimates(filter),
        lever_arm_m: opts.lever_arm_m,
        gating: gating_report::GatingReport::new(
            &cfg.gating,
            filter.counters(),
            filter.robust_stats(),
            hooks.status_seen,
        ),
        imu_report,
        history: hooks.rec.finish(
            filter.covariance(),
            filter.pending_correction(),
            u64::from(filter.counters().cov_predictions),
        ),
        aiding: hooks.aid.report(),
        // last: the hooks hold the outages until here
        outages,
    };
    match fault {
        None => Ok(out),
        Some((location, t_s, cause)) => Err(RunError::Fault {
            location,
            t_s,
            cause,
            partial: Box::new(out),
        }),
    }
}

/// The engine's hooks at the start of the loop: `at` = (the initial epoch, the index of the
/// first sample after it, the index of the first fix used).
fn engine_hooks<'a, 'g, T: Scalar, const N: usize>(
    sink: &'a mut dyn RunSink,
    opts: &RunOptions,
    outages: &'a [outage::Outage],
    coast_modes: &'a [CoastMode],
    gnss: FixAhead<'g>,
    at: (f64, usize, usize),
) -> Result<EngineHooks<'a, 'g, T>, RunError> {
    let (t0, first, gi0) = at;
    Ok(EngineHooks::<T> {
        sink,
        err: None,
        fault: None,
        rec: if opts.smoother_history {
            crate::smooth::Recorder::new(N)
        } else {
            crate::smooth::Recorder::disabled()
        },
        aid: super::aiding::RunAiding::<T>::new(&opts.aiding).map_err(RunError::Options)?,
        outages,
        next_outage: outages.partition_point(|o| o.start_s < t0),
        counters: RunCounters {
            imu_before_start: first as u64,
            // the total once the stream is read to its end
            gnss_total: 0,
            gnss_outside_run: gi0 as u64,
            gnss_before_run: gi0 as u64,
            ..Default::default()
        },
        status_seen: 0,
        processed: 0,
        nav_dec: Decimator::new(opts.record.nav_rate_hz, t0),
        ep_dec: Decimator::new(opts.record.epoch_rate_hz, t0),
        want_epochs: false,
        want_nav_std: true,
        coast_modes,
        coasters: Vec::new(),
        raw: None,
        next_index: first,
        gnss,
        gi0,
        lever_arm_m: opts.lever_arm_m,
    })
}

/// A fault that ends a run: where (`file line N`), when (s) and why.
type Fault = (String, f64, FaultCause);

/// Reads the start-up buffer: the nominal-interval window, and the static alignment window
/// when longer (from the start time on).
fn fill_start_window<I: Iterator<Item = Result<ImuItem, RunError>>>(
    feed: &mut Feed<I>,
    opts: &RunOptions,
) -> Result<(), RunError> {
    feed.fill(|b| b.len() >= NOMINAL_WINDOW)?;
    if let init::InitSpec::StaticAlignment(sa) = &opts.init {
        let start_s = opts.start_s.unwrap_or(f64::NEG_INFINITY);
        let secs = sa.seconds;
        let t_a = feed.buf.iter().find(|i| i.sample.t_s >= start_s);
        match t_a.map(|i| i.sample.t_s) {
            Some(t_a) => feed.fill(|b| b.back().is_some_and(|i| i.sample.t_s > t_a + secs))?,
            None => {
                // the start lies beyond the buffer: keep reading until it (drop what is before)
                loop {
                    if feed.buf.len() > NOMINAL_WINDOW {
                        feed.buf.pop_front();
                        feed.index += 1;
                    }
                    match feed.read()? {
                        Some(it) => {
                            let t = it.sample.t_s;
                            feed.buf.push_back(it);
                            if t >= start_s {
                                feed.fill(|b| b.back().is_some_and(|i| i.sample.t_s > t + secs))?;
                                break;
                            }
                        }
                        None => break,
                    }
                }
            }
        }
    }
    Ok(())
}

/// The initial state from the start-up buffer, the fixes (read as far ahead as the start-up
/// looks, the configured sigma scale applied to every fix as it is read) and the truth.
fn initialise<'g, I: Iterator<Item = Result<ImuItem, RunError>>>(
    feed: &Feed<I>,
    gnss: FixSource<'g>,
    truth: Option<&[NavSolution]>,
    opts: &RunOptions,
    cfg: &nav_core::config::FilterConfig,
) -> Result<(init::Start, FixAhead<'g>), RunError> {
    let scale = opts.gnss_sigma_scale;
    let gnss: FixSource<'g> = if scale == nav_io::SigmaScale::ONE {
        gnss
    } else {
        Box::new(gnss.map(move |r| {
            r.map(|mut g| {
                scale.apply(&mut g);
                g
            })
        }))
    };
    let ahead = RefCell::new(FixAhead::new(gnss));
    let start = {
        let prefix: Vec<ImuSample> = feed.buf.iter().map(|i| i.sample).collect();
        init::initialise(
            &InitData {
                imu: &prefix,
                gnss: &ahead,
                truth,
            },
            opts,
            cfg,
        )
    };
    let mut gnss = ahead.into_inner();
    if let Some(e) = gnss.take_err() {
        return Err(e);
    }
    Ok((start?, gnss))
}

/// The IMU guard's settings (checked now: the guard starts with the first sample after the
/// initial epoch `t0`).
fn guard_config(
    opts: &RunOptions,
    info: &ImuSourceInfo,
    nominal_dt_s: f64,
    t0: f64,
) -> Result<GuardConfig, RunError> {
    let guard_cfg = GuardConfig {
        increments: opts
            .imu_checks
            .increments
            .unwrap_or(if info.increments_span_gaps {
                GapIncrements::Span
            } else {
                GapIncrements::Auto
            }),
        limits: opts.imu_checks.limits,
        max_gap_s: opts.imu_checks.max_gap_s,
        ..GuardConfig::new(nominal_dt_s)
    };
    ImuGuard::new(guard_cfg, t0, None).map_err(RunError::Guard)?;
    Ok(guard_cfg)
}

/// The navigator started at the initialisation's state, with its initial sensor-error
/// estimates (the initialisation's and the options').
fn navigator<T: Scalar, const N: usize>(
    layout: Layout,
    cfg: nav_core::config::FilterConfig,
    guard_cfg: GuardConfig,
    start: &init::Start,
    opts: &RunOptions,
) -> Result<Box<Navigator<T, N, FIX_QUEUE>>, RunError> {
    let t0 = start.report.t_s;
    let mut nav = Box::new(
        Navigator::<T, N, FIX_QUEUE>::new(
            layout,
            NavigatorConfig {
                filter: cfg,
                guard: guard_cfg,
                align: AlignMode::Given {
                    state: start.state,
                    unc: start.unc,
                },
            },
        )
        .map_err(|e| match e {
            NavigatorError::Filter(e) => filter_err(t0, e),
            NavigatorError::Guard(e) => RunError::Guard(e),
            e => RunError::Options(e.to_string()),
        })?,
    );
    for (kind, v) in start.estimates.iter().chain(opts.initial_estimates.iter()) {
        if let (Some((_, b)), Some(filter)) = (layout.find(*kind), nav.filter_mut()) {
            let mut full = vec![0.0; b.dim()];
            for (d, s) in full.iter_mut().zip(v.iter()) {
                *d = *s;
            }
            filter
                .set_block_estimate(*kind, &full)
                .map_err(|e| filter_err(t0, e))?;
        }
    }
    Ok(nav)
}

/// The coasting modes of a plan (the static gyro bias only when the start-up measured one).
fn coast_modes(coast: CoastPlan, report: &InitReport) -> Vec<CoastMode> {
    let mut v = Vec::new();
    if coast.raw {
        v.push(CoastMode::Raw);
    }
    if coast.static_gyro_bias {
        if let Some(b) = report.static_gyro_bias_radps {
            v.push(CoastMode::Fixed(Box::new(ImuCorrection {
                gyro_bias_radps: b,
                ..ImuCorrection::default()
            })));
        }
    }
    v
}

/// Samples up to the initial epoch `t0` are not integrated (the navigator keeps the last two
/// for the guard).
fn skip_to_initial_epoch<T: Scalar, const N: usize, I>(
    feed: &mut Feed<I>,
    nav: &mut Navigator<T, N, FIX_QUEUE>,
    t0: f64,
) -> Result<(), RunError>
where
    I: Iterator<Item = Result<ImuItem, RunError>>,
{
    while let Some(it) = feed.peek()? {
        if it.sample.t_s > t0 {
            break;
        }
        if let Some((_, it)) = feed.next()? {
            nav.push_imu(&it.sample)
                .map_err(|e| RunError::Options(e.to_string()))?;
        }
    }
    Ok(())
}

/// The integration loop's state: the samples, the navigator with the engine's hooks, the IMU
/// report, the samples integrated and the fixes pushed to the navigator.
struct Loop<'r, 'a, 'g, I, T: Scalar, const N: usize> {
    feed: &'r mut Feed<I>,
    nav: &'r mut Navigator<T, N, FIX_QUEUE>,
    hooks: &'r mut EngineHooks<'a, 'g, T>,
    imu_report: &'r mut ImuReport,
    opts: &'r RunOptions,
    /// Samples integrated.
    done: usize,
    /// Fixes pushed to the navigator (it applies them at the nearest epoch).
    gi: usize,
}

impl<I, T: Scalar, const N: usize> Loop<'_, '_, '_, I, T, N>
where
    I: Iterator<Item = Result<ImuItem, RunError>>,
{
    /// Integrates the samples up to `end_s` (or a fault, returned).
    fn integrate(
        &mut self,
        end_s: f64,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<Option<Fault>, RunError> {
        let mut imu_step = nav_core::navigator::ImuStep::default();
        while let Some((k, it)) = self.feed.next()? {
            let s = it.sample;
            if s.t_s > end_s {
                // not integrated; the coasters may still want it
                self.feed.peeked = Some(it);
                self.feed.index -= 1;
                break;
            }
            let next_t = self.feed.peek()?.map(|n| n.sample.t_s);
            self.done += 1;
            if self.done.is_multiple_of(4096) {
                progress(self.done, 0);
            }
            // a fix refused (more than the queue holds before this sample: a gap in the IMU
            // data) is reported after the sample: an IMU gap too long to bridge is the cause
            // to name, with its line
            let refused = self.push_fixes_before(s.t_s)?;
            self.hooks.release_fixes(self.gi);
            let dt = self.nav.state().map_or(0.0, |st| s.t_s - st.t_s);
            self.hooks.raw = Some((s, next_t));
            self.hooks.next_index = k;
            // one account kept across samples (no copy of its fix list per sample)
            let step = self
                .nav
                .push_imu_into(&s, &mut *self.hooks, &mut imu_step)
                .map(|()| imu_step.imu);
            // the coasters step on every sample (in the epoch call when there was one)
            self.hooks.step_coasters();
            if let Some(e) = self.hooks.err.take() {
                return Err(e);
            }
            if let Some(f) = self.hooks.fault.take() {
                return Ok(Some(f));
            }
            let at = || self.feed.info.locate(k, it.line);
            match step {
                Ok(ImuEventNav::Rejected(why)) if self.opts.imu_checks.stop_on_implausible => {
                    return Ok(Some((at(), s.t_s, FaultCause::Implausible(why))));
                }
                Ok(ev) => self.imu_event(ev, s.t_s, dt, k, it.line),
                Err(e) => return Ok(Some((at(), s.t_s, e.into()))),
            }
            if let Some((what, t, cause)) = refused {
                let what = format!(
                    "{what}, one of more than {FIX_QUEUE} fixes between two IMU samples (a gap \
                     in the IMU data before {}, t = {:.3} s)",
                    self.feed.info.locate(k, it.line),
                    s.t_s
                );
                return Ok(Some((what, t, cause)));
            }
        }
        Ok(None)
    }

    /// Pushes every fix before `t_s` to the navigator (they can be due at the epoch before
    /// the sample at `t_s`); a fix the navigator refuses is a fault.
    fn push_fixes_before(&mut self, t_s: f64) -> Result<Option<Fault>, RunError> {
        let mut fault = None;
        while let Some(fix) = self.hooks.gnss.get(self.gi).filter(|g| g.t_s < t_s) {
            if let Err(e) = self.nav.push_gnss(&fix) {
                fault = Some((
                    format!("GNSS fix at t = {:.3} s", fix.t_s),
                    fix.t_s,
                    e.into(),
                ));
                break;
            }
            self.gi += 1;
        }
        if let Some(e) = self.hooks.gnss.take_err() {
            return Err(e);
        }
        Ok(fault)
    }

    /// Counts and reports what the guard or the filter did with sample `index` (file line
    /// `line`, 0 when unknown); its location is written out only for a reported event.
    fn imu_event(&mut self, ev: ImuEventNav, t_s: f64, dt: f64, index: usize, line: usize) {
        let report = &mut *self.imu_report;
        let info = &self.feed.info;
        let location = || info.locate(index, line);
        match ev {
            ImuEventNav::Rejected(why) => {
                self.hooks.counters.imu_implausible += 1;
                if report.events.len() < MAX_IMU_EVENTS {
                    report.events.push(ImuEvent {
                        t_s,
                        location: location(),
                        what: format!("rejected: {why}"),
                    });
                }
            }
            ImuEventNav::Refused(_) => self.hooks.counters.imu_rejected += 1,
            ImuEventNav::GapBridged {
                missing, spanned, ..
            } if report.events.len() < MAX_IMU_EVENTS => {
                report.events.push(ImuEvent {
                    t_s,
                    location: location(),
                    what: format!(
                        "gap of {dt:.4} s ({missing} sample(s) missing): {}",
                        if spanned {
                            "increment spans the gap"
                        } else {
                            "lost increments filled by interpolation"
                        }
                    ),
                });
            }
            _ => {}
        }
    }

    /// The last epoch's fixes (with the last interval as the next one) and its records.
    fn last_epoch(&mut self) -> Result<Option<Fault>, RunError> {
        if let Some((t_k, dt)) = self.nav.pending_epoch() {
            while let Some(fix) = self
                .hooks
                .gnss
                .get(self.gi)
                .filter(|g| g.t_s < nearest_epoch_horizon(t_k, dt))
            {
                if self.nav.push_gnss(&fix).is_err() {
                    break;
                }
                self.gi += 1;
            }
            if let Some(e) = self.hooks.gnss.take_err() {
                return Err(e);
            }
        }
        self.hooks.next_index = self.feed.index;
        self.nav.flush_with(&mut *self.hooks);
        if let Some(e) = self.hooks.err.take() {
            return Err(e);
        }
        Ok(self.hooks.fault.take())
    }
}

/// After the run: the coasters see only the fixes the run reached and continue on the rest of
/// the record until their outage ends (or the record does).
fn finish_coasters<T: Scalar, I>(
    feed: &mut Feed<I>,
    hooks: &mut EngineHooks<'_, '_, T>,
) -> Result<(), RunError>
where
    I: Iterator<Item = Result<ImuItem, RunError>>,
{
    let gi = hooks.gi0 + hooks.processed;
    let mut coasters = std::mem::take(&mut hooks.coasters);
    if coasters.is_empty() {
        return Ok(());
    }
    for c in &mut coasters {
        c.keep_fixes_before(gi);
    }
    while !coasters.is_empty() {
        let Some((_, it)) = feed.next()? else {
            break;
        };
        let next_t = feed.peek()?.map(|n| n.sample.t_s);
        let mut i = 0;
        while let Some(c) = coasters.get_mut(i) {
            if c.step(&it.sample, next_t) {
                let (m, t) = coasters.swap_remove(i).finish();
                hooks.sink.coast(m, t);
            } else {
                i += 1;
            }
        }
    }
    // record ended before the outage did
    for c in coasters.drain(..) {
        let (m, t) = c.finish();
        hooks.sink.coast(m, t);
    }
    Ok(())
}

/// The run's counters and IMU report at its end (the rest of the fix stream read, not kept,
/// to count it).
fn final_counters<T: Scalar, const N: usize, I>(
    hooks: &mut EngineHooks<'_, '_, T>,
    nav: &Navigator<T, N, FIX_QUEUE>,
    filter: &nav_core::filter::Filter<T, N>,
    feed: &mut Feed<I>,
    imu_report: &mut ImuReport,
) -> Result<RunCounters, RunError> {
    let gi = hooks.gi0 + hooks.processed;
    let mut counters = hooks.counters;
    // the fixes after the last one reached are read (not kept) to count them
    let total = hooks.gnss.count();
    if let Some(e) = hooks.gnss.take_err() {
        return Err(e);
    }
    counters.gnss_total = total as u64;
    counters.gnss_outside_run += (total - gi.min(total)) as u64;
    counters.absorb(filter.counters());
    counters.imu_rejected = counters
        .imu_rejected
        .max(u64::from(filter.counters().imu_rejected));
    let g = nav.guard_counters();
    counters.imu_gaps = g.gaps;
    counters.imu_missing_samples = g.missing_samples;
    counters.imu_gaps_filled = g.gaps_filled;
    counters.imu_synthetic_samples = g.synthetic_samples;
    imu_report.gaps = g.gaps;
    imu_report.missing_samples = g.missing_samples;
    imu_report.gaps_spanned = g.gaps_spanned;
    imu_report.gaps_filled = g.gaps_filled;
    counters.imu_implausible += feed.repeats;
    for e in feed.repeat_events.drain(..) {
        if imu_report.events.len() < MAX_IMU_EVENTS {
            imu_report.events.push(e);
        }
    }
    imu_report.events.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    imu_report.rejected = counters.imu_implausible;
    Ok(counters)
}
