//! The run engine: the `nav-core` filter on any case (simulated or real), on streams
//! ([`run_engine`], [`engine`]), pushed sample by sample ([`live::LiveRun`]), in memory
//! ([`run_filter`]) and from files ([`prepare`], [`execute`]).
//!
//! # The run loop
//!
//! IMU samples and GNSS fixes are processed in time order. The filter starts at the initial
//! epoch ([`InitSpec`]) and integrates every later IMU sample. A GNSS fix tagged `t_f` is used
//! at the IMU epoch NEAREST to it: after integrating the sample ending at `t_k`, every pending
//! fix with `t_f < t_k + dt_next / 2` is processed (so |t_f - t_k| <= half an IMU interval).
//! The filter bridges the remaining offset by predicting the antenna position to the fix time
//! with the current velocity (`nav_core::filter::Filter::update_gnss`), i.e. it predicts to the
//! fix time to first order; the neglected `a dt^2 / 2` is 12 um for 1 m/s^2 at 100 Hz.
//!
//! Fixes inside an imposed [`Outage`] are *withheld*: not given to the filter, but compared
//! with the predicted antenna position at their time (an [`InnovationRecord`] with
//! [`FixUse::Withheld`]). On real data those are the honest reference for the outage errors.
//!
//! # Models
//!
//! [`Model`] selects the state layout at compile time (`Filter<T, { LAYOUT.dim() }>`), the
//! covariance scalar ([`Precision`]) is f64 by default, f32 allowed. Adding a model is one line
//! in [`run_engine`]'s dispatch macro.

pub mod aiding;
pub mod coast;
pub mod effect;
pub mod engine;
pub mod execute;
mod fault;
pub mod gating_report;
pub mod gnss_use;
pub mod init;
pub mod interrupt;
pub mod live;
pub mod outage;
pub mod outdir;
pub mod output;
pub mod prepare;
mod reader_thread;
pub mod sink;
mod start;
pub mod streams;
pub mod truth;

pub use coast::{coast_outages, coast_outages_with, CoastMode, CoastTrack};
pub use effect::{Effect, UnknownEffect};
pub use engine::ahead::{FixAhead, FixLookup, FixSource};
pub use engine::{
    CoastPlan, Coaster, Collect, ImuItem, ImuSourceInfo, RunHead, RunSink, NOMINAL_WINDOW,
};
pub use fault::FaultCause;
pub use init::{InitData, InitReport, InitSpec, StaticAlign};
pub use outage::{parse_outage, parse_periodic, Outage, PeriodicOutages};
pub use start::STANDING_START_UNCERTAINTY;

use nalgebra::Vector3;
use nav_core::config::FilterConfig;
use nav_core::earth::{self, Llh};
use nav_core::filter::{dcm_f64, Counters, Filter, FilterError, UpdateOutcome};
use nav_core::imu_guard::{GapIncrements, ImuLimits};
use nav_core::model::{
    BiasModel, Block, BlockKind, ImuCorrection, Layout, EFFECT_BLOCKS, LAYOUT_KF_GINS, LAYOUT_N,
    LAYOUT_NBK, LAYOUT_NBK_SINGLE,
};
use nav_core::scalar::Scalar;
use nav_core::strapdown::{NavState, MAX_DT_S};
use nav_core::types::{GnssFix, ImuSample, NavSolution};
use nav_io::ImuOrigin;
use serde::{Deserialize, Serialize};

/// The measurements of a case, in memory (and the truth when there is one).
#[derive(Debug, Clone, Default)]
pub struct CaseData {
    /// IMU increments in time order (body FRD axes, after any mounting rotation).
    pub imu: Vec<ImuSample>,
    /// GNSS fixes in time order (antenna positions).
    pub gnss: Vec<GnssFix>,
    /// Truth at the IMU reference point (nav format), when known.
    pub truth: Option<Vec<NavSolution>>,
    /// File and line of each IMU sample, for messages (used when its length matches `imu`).
    pub imu_origin: Option<ImuOrigin>,
}

impl CaseData {
    /// `file line N` of IMU sample `index` (or `IMU sample index` without an origin).
    pub fn locate_imu(&self, index: usize) -> String {
        match &self.imu_origin {
            Some(o) if o.lines.len() == self.imu.len() => o.locate(index),
            _ => format!("IMU sample {index}"),
        }
    }
}

/// IMU gap handling and plausibility limits of a run (see [`nav_core::imu_guard`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuChecks {
    /// What the increment after a gap covers; `None`: from the data's origin (CSV rates:
    /// spans the gap; increment files and data without origin: decided per gap).
    pub increments: Option<GapIncrements>,
    /// Physical range (default: the widest sensor class, consumer MEMS).
    pub limits: ImuLimits,
    /// Longest gap bridged, s (longer ends the run with an error).
    pub max_gap_s: f64,
    /// An implausible sample ends the run (with the outputs up to it) instead of being
    /// skipped.
    pub stop_on_implausible: bool,
}

impl Default for ImuChecks {
    fn default() -> Self {
        Self {
            increments: None,
            limits: ImuLimits::default(),
            max_gap_s: MAX_DT_S,
            stop_on_implausible: false,
        }
    }
}

/// The error-state model (state layout) of a run; its names (`name`, `FromStr`, `Display`,
/// `strum::VariantNames::VARIANTS`) are those of the command line and the configuration.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Serialize,
    Deserialize,
    strum::Display,
    strum::EnumString,
    strum::VariantNames,
)]
#[serde(rename_all = "kebab-case")]
#[strum(serialize_all = "kebab-case")]
pub enum Model {
    /// The source's classical N model: constant biases, white noise (15 states).
    N,
    /// The source's NBK model with separate Gauss-Markov and random-walk accelerometer bias
    /// states (18 states).
    Nbk,
    /// The source's NBK model as printed: one decaying accelerometer bias state (15 states).
    NbkSingle,
    /// KF-GINS's 21 states: Gauss-Markov biases and scale factors.
    #[serde(rename = "kf-gins")]
    #[strum(serialize = "kf-gins")]
    KfGins21,
    /// KF-GINS's 21 states as its code runs them: bias estimates that do not decay between
    /// updates (the default for a KF-GINS YAML; layout `LAYOUT_KF_GINS_FEEDBACK`, see
    /// docs/kfgins-parity.md).
    #[serde(rename = "kf-gins-feedback")]
    #[strum(serialize = "kf-gins-feedback")]
    KfGinsFeedback,
}

/// KF-GINS's 21 states as KF-GINS's code runs them: its bias errors are fed back into a bias
/// estimate that stays constant between updates (only the covariance follows the
/// Gauss-Markov model), so the biases are random constants driven by a random walk
/// (`S_K = 2 sigma^2 / T`, KF-GINS's `Qc`); the scale factors are Gauss-Markov
/// (`docs/kfgins-parity.md` measures the difference on KF-GINS's own solution).
pub const LAYOUT_KF_GINS_FEEDBACK: Layout = Layout::new(&[
    Block::Core,
    Block::GyroBias(BiasModel::Constant),
    Block::AccelBias(BiasModel::Constant),
    Block::GyroScaleFactor,
    Block::AccelScaleFactor,
]);

impl Model {
    /// The state layout.
    pub fn layout(self) -> Layout {
        match self {
            Self::N => LAYOUT_N,
            Self::Nbk => LAYOUT_NBK,
            Self::NbkSingle => LAYOUT_NBK_SINGLE,
            Self::KfGins21 => LAYOUT_KF_GINS,
            Self::KfGinsFeedback => LAYOUT_KF_GINS_FEEDBACK,
        }
    }

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::N => "n",
            Self::Nbk => "nbk",
            Self::NbkSingle => "nbk-single",
            Self::KfGins21 => "kf-gins",
            Self::KfGinsFeedback => "kf-gins-feedback",
        }
    }
}

/// The covariance scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Precision {
    /// f64 (host default).
    #[default]
    F64,
    /// f32 (what the MCU runs).
    F32,
}

/// What is recorded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordOptions {
    /// Rate of [`RunOutput::nav`], Hz; `None` = every IMU epoch. Decimation keeps the first
    /// IMU epoch at or after each multiple of `1 / rate` from the initial epoch.
    pub nav_rate_hz: Option<f64>,
    /// Rate of [`RunOutput::epochs`] (standard deviations and block estimates), Hz; `None` =
    /// every IMU epoch; `Some(0.0)` = none.
    pub epoch_rate_hz: Option<f64>,
}

impl Default for RecordOptions {
    /// Navigation at every IMU epoch, standard deviations and estimates at 10 Hz.
    fn default() -> Self {
        Self {
            nav_rate_hz: None,
            epoch_rate_hz: Some(10.0),
        }
    }
}

/// Everything a run needs besides the data.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// State layout.
    pub model: Model,
    /// Covariance scalar.
    pub precision: Precision,
    /// Noise and GNSS settings (its `lever_arm_body_m` is replaced by [`Self::lever_arm_m`]).
    pub filter: FilterConfig,
    /// Initial state.
    pub init: InitSpec,
    /// Imposed GNSS outages (absolute GPS seconds of week), any order.
    pub outages: Vec<Outage>,
    /// GNSS antenna position relative to the IMU, body FRD, m.
    pub lever_arm_m: [f64; 3],
    /// Initial sensor-error estimates (SI units, per block kind; e.g. KF-GINS `initgyrbias`).
    /// A value of length 3 fills the first three states of a larger block.
    pub initial_estimates: Vec<(BlockKind, [f64; 3])>,
    /// What to record.
    pub record: RecordOptions,
    /// Ignore data before this time (GPS seconds of week).
    pub start_s: Option<f64>,
    /// Stop after this time (GPS seconds of week).
    pub end_s: Option<f64>,
    /// Effect blocks ([`EFFECT_BLOCKS`]) appended in order to the model's layout (for
    /// `diagnose`), f64 only; the total must stay within [`MIN_EXTRA_DIM`]..=[`MAX_EXTRA_DIM`]
    /// states. Empty runs the model as it is.
    pub extra_blocks: Vec<Block>,
    /// IMU gap handling and plausibility limits.
    pub imu_checks: ImuChecks,
    /// Record what the smoother needs ([`RunOutput::history`], `crate::smooth`).
    pub smoother_history: bool,
    /// Land-vehicle aiding (non-holonomic constraint, zero-velocity/rate updates, odometer,
    /// dual-antenna heading; all off by default), see [`aiding`].
    pub aiding: aiding::RunAidingConfig,
    /// Factors on the fixes' standard deviations (`[gnss] sigma_scale`; the diagnosis's
    /// GNSS noise scale), applied to every fix as the engine reads it (alignment and filter
    /// alike); [`nav_io::SigmaScale::ONE`] uses the file's sigmas.
    pub gnss_sigma_scale: nav_io::SigmaScale,
}

/// Smallest state count of a layout with extra effect blocks ([`RunOptions::extra_blocks`]).
pub const MIN_EXTRA_DIM: usize = 16;
/// Largest state count of a layout with extra effect blocks: the filter's N is a compile-time
/// constant, so `run_filter` instantiates one filter per count in
/// [`MIN_EXTRA_DIM`]..=[`MAX_EXTRA_DIM`] and dispatches on the layout's dimension.
pub const MAX_EXTRA_DIM: usize = 40;

impl RunOptions {
    /// Appends the effect block `b` to [`Self::extra_blocks`] unless it is there already; for
    /// `time_offset` and `imu_clock_drift` also let the filter accept fixes further from an
    /// IMU epoch (the offset's 3-sigma prior plus 0.05 s).
    pub fn add_effect_block(&mut self, b: Block) {
        if !self.extra_blocks.contains(&b) {
            self.extra_blocks.push(b);
        }
        if matches!(b, Block::TimeOffset | Block::ImuClockDrift) {
            let lim = 3.0 * self.filter.effects.time_offset.init_sigma + 0.05;
            self.filter.max_gnss_time_offset_s = self.filter.max_gnss_time_offset_s.max(lim);
        }
    }

    /// Options with defaults: f64, no outages, no lever arm, default recording.
    pub fn new(model: Model, filter: FilterConfig, init: InitSpec) -> Self {
        Self {
            model,
            precision: Precision::F64,
            lever_arm_m: filter.lever_arm_body_m,
            filter,
            init,
            outages: Vec::new(),
            initial_estimates: Vec::new(),
            record: RecordOptions::default(),
            start_s: None,
            end_s: None,
            extra_blocks: Vec::new(),
            imu_checks: ImuChecks::default(),
            smoother_history: false,
            aiding: aiding::RunAidingConfig::OFF,
            gnss_sigma_scale: nav_io::SigmaScale::ONE,
        }
    }
}

/// The estimate and 1-sigma of one IMU error quantity (sum over the block's processes).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BlockEstimate {
    /// Block name (`gyro_bias`, `accel_bias`, `gyro_scale_factor`, ...).
    pub name: String,
    /// Estimate per axis (x, y, z body), SI units (rad/s, m/s^2, dimensionless).
    pub value: [f64; 3],
    /// 1-sigma per axis, same units.
    pub std: [f64; 3],
}

/// The estimate and 1-sigma of every state of one effect block.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EffectEstimate {
    /// Block name (the effect vocabulary, e.g. `lever_arm`).
    pub name: String,
    /// Estimate of each state, SI units of the block ([`Block::unit`]).
    pub value: Vec<f64>,
    /// 1-sigma of each state, same units.
    pub std: Vec<f64>,
}

fn effect_estimates<T: Scalar, const N: usize>(f: &Filter<T, N>) -> Vec<EffectEstimate> {
    f.layout()
        .iter()
        .filter(|(_, b)| EFFECT_BLOCKS.contains(b))
        .filter_map(|(_, b)| {
            let v = f.block_value(b.kind())?;
            Some(EffectEstimate {
                name: b.name().to_string(),
                value: v.estimate.get(..v.dim)?.to_vec(),
                std: v.sigma.get(..v.dim)?.to_vec(),
            })
        })
        .collect()
}

/// State at one recorded epoch.
#[derive(Debug, Clone, PartialEq)]
pub struct EpochRecord {
    /// Time, GPS seconds of week.
    pub t_s: f64,
    /// Navigation solution.
    pub nav: NavSolution,
    /// 1-sigma of every error state (order of [`RunOutput::state_names`]).
    pub state_std: Vec<f64>,
    /// Every error-state's accumulated estimate (core entries are 0: fed back).
    pub estimates: Vec<f64>,
    /// IMU error quantities with their 1-sigma.
    pub blocks: Vec<BlockEstimate>,
}

/// What happened to a GNSS fix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FixUse {
    /// Used by the filter.
    Accepted,
    /// Used without the gate after too many consecutive rejections.
    Forced,
    /// Rejected by the innovation gate.
    Rejected,
    /// Withheld (inside an imposed outage); innovation computed, no update.
    Withheld,
    /// Refused by the filter (invalid, or too far from an IMU epoch), or numerical failure.
    Invalid,
}

/// One GNSS fix against the solution.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct InnovationRecord {
    /// Fix time, GPS seconds of week.
    pub t_s: f64,
    /// Outcome.
    pub used: FixUse,
    /// Index into [`RunOutput::outages`] when withheld.
    pub outage: Option<usize>,
    /// Measurement dimension (3 or 6).
    pub dim: usize,
    /// Measured minus predicted antenna position (N, E, D, m) and velocity (m/s; `dim` = 6).
    pub innovation: [f64; 6],
    /// Diagonal of the innovation covariance (NaN for withheld or invalid fixes).
    pub innovation_var: [f64; 6],
    /// Normalised innovation squared (NaN when not computed).
    pub nis: f64,
    /// Gate threshold that applied (NaN when none).
    pub nis_threshold: f64,
    /// Fix quality.
    pub quality: u8,
}

impl InnovationRecord {
    /// The record of `fix` withheld by the outage `outage` (index into
    /// [`RunOutput::outages`]): its position innovation `inn` (measured minus predicted
    /// antenna position, N, E, D, m), no innovation covariance, NIS or gate.
    pub fn withheld(fix: &GnssFix, outage: usize, inn: [f64; 3]) -> Self {
        Self {
            t_s: fix.t_s,
            used: FixUse::Withheld,
            outage: Some(outage),
            dim: 3,
            innovation: [inn[0], inn[1], inn[2], 0.0, 0.0, 0.0],
            innovation_var: [f64::NAN; 6],
            nis: f64::NAN,
            nis_threshold: f64::NAN,
            quality: fix.quality.rtklib_q(),
        }
    }

    /// Solution error against the fix (predicted minus measured), N, E, D, m.
    pub fn pos_error_ned_m(&self) -> [f64; 3] {
        [
            -self.innovation[0],
            -self.innovation[1],
            -self.innovation[2],
        ]
    }
}

/// Counters of a run.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct RunCounters {
    /// IMU samples integrated.
    pub imu_epochs: u64,
    /// IMU samples rejected by the filter (non-finite).
    pub imu_rejected: u64,
    /// IMU samples before the initial epoch (not used).
    pub imu_before_start: u64,
    /// Covariance predictions.
    pub cov_predictions: u64,
    /// GNSS fixes in the data.
    pub gnss_total: u64,
    /// Fixes before the initial epoch or after the end.
    pub gnss_outside_run: u64,
    /// Of `gnss_outside_run`, the fixes before the initial epoch (the rest are after the
    /// end of the IMU data).
    pub gnss_before_run: u64,
    /// Fixes used.
    pub gnss_accepted: u64,
    /// Fixes that re-initialised position and velocity after consecutive rejections (reset).
    pub gnss_forced: u64,
    /// Fixes rejected by the gate.
    pub gnss_rejected: u64,
    /// Fixes withheld by an imposed outage.
    pub gnss_withheld: u64,
    /// Fixes refused as invalid / mistimed.
    pub gnss_invalid: u64,
    /// Of `gnss_invalid`, the fixes refused as mistimed (too far from the IMU epoch they were
    /// due at); the rest have invalid values (a standard deviation zero or not finite, a
    /// non-finite position, no-fix quality).
    pub gnss_mistimed: u64,
    /// Numerical failures of the filter.
    pub numerical_failures: u64,
    /// IMU time gaps bridged (intervals beyond 1.5 nominal intervals).
    pub imu_gaps: u64,
    /// Nominal IMU intervals missing in those gaps.
    pub imu_missing_samples: u64,
    /// Gaps whose lost increments were filled with interpolated samples.
    pub imu_gaps_filled: u64,
    /// Synthetic IMU samples integrated to fill gaps.
    pub imu_synthetic_samples: u64,
    /// IMU samples rejected as physically implausible (beyond the configured range).
    pub imu_implausible: u64,
    /// GNSS velocities rejected by their own gate (`Gating::velocity`).
    pub gnss_vel_rejected: u64,
}

impl RunCounters {
    fn absorb(&mut self, c: &Counters) {
        self.imu_epochs = c.imu_epochs;
        self.cov_predictions = u64::from(c.cov_predictions);
        self.numerical_failures = u64::from(c.numerical_failures);
        self.gnss_vel_rejected = u64::from(c.gnss_vel_rejected);
    }
}

/// The filter's state when an outage begins (for free-inertial coasting from the same point).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutageSnapshot {
    /// Index into [`RunOutput::outages`].
    pub outage: usize,
    /// Index into the case's IMU samples of the next sample to integrate.
    pub next_imu: usize,
    /// Nominal state (IMU point) at the first IMU epoch at or after the outage start.
    pub state: NavState,
    /// The filter's sensor-error correction at that time.
    pub correction: ImuCorrection,
}

/// What happened to the IMU data at one sample (a gap bridged, a sample rejected).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImuEvent {
    /// Sample time, GPS seconds of week.
    pub t_s: f64,
    /// `file line N` of the sample (or `IMU sample N`).
    pub location: String,
    /// What happened, in words.
    pub what: String,
}

/// How the IMU data were taken: gaps, rejections and the first events with their location.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct ImuReport {
    /// Nominal sample interval used to detect gaps, s (median interval of the record).
    pub nominal_dt_s: f64,
    /// Gaps bridged.
    pub gaps: u64,
    /// Nominal intervals missing in those gaps.
    pub missing_samples: u64,
    /// Gaps whose increment spanned the gap (used over the whole gap).
    pub gaps_spanned: u64,
    /// Gaps whose lost increments were filled with interpolated samples.
    pub gaps_filled: u64,
    /// Samples rejected as physically implausible.
    pub rejected: u64,
    /// The first [`MAX_IMU_EVENTS`] events.
    pub events: Vec<ImuEvent>,
}

/// Events kept in [`ImuReport::events`].
pub const MAX_IMU_EVENTS: usize = 50;

/// The result of a run.
#[derive(Debug, Clone)]
pub struct RunOutput {
    /// Model run.
    pub model: Model,
    /// Names of the error states (with units).
    pub state_names: Vec<String>,
    /// Navigation solution at the nav rate (IMU point).
    pub nav: Vec<NavSolution>,
    /// Standard deviations and estimates at the epoch rate.
    pub epochs: Vec<EpochRecord>,
    /// Every GNSS fix processed, in time order.
    pub innovations: Vec<InnovationRecord>,
    /// Counters.
    pub counters: RunCounters,
    /// The outages applied (sorted).
    pub outages: Vec<Outage>,
    /// The filter state at the start of each outage that the run reached.
    pub snapshots: Vec<OutageSnapshot>,
    /// How the filter was initialised.
    pub init: InitReport,
    /// Final IMU error estimates.
    pub final_blocks: Vec<BlockEstimate>,
    /// Final estimate and 1-sigma of every effect block in the layout ([`EFFECT_BLOCKS`]), all
    /// its states, SI units ([`Block::unit`]).
    pub final_effects: Vec<EffectEstimate>,
    /// Antenna lever arm used, body FRD, m.
    pub lever_arm_m: [f64; 3],
    /// What the innovation gate and its model-mismatch monitor did.
    pub gating: gating_report::GatingReport,
    /// IMU gaps and rejected samples.
    pub imu_report: ImuReport,
    /// The smoother's record of the run (with [`RunOptions::smoother_history`]).
    pub history: Option<crate::smooth::History>,
    /// What the land-vehicle aiding did.
    pub aiding: aiding::AidingReport,
}

/// Errors of a run.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// No IMU data (after the start time).
    #[error("run: no IMU samples to process")]
    NoImu,
    /// IMU time not increasing.
    #[error("run: IMU sample {index} (t = {t_s:.6} s) is not after the previous one")]
    ImuNotMonotonic {
        /// Index in the IMU data.
        index: usize,
        /// Its time, s.
        t_s: f64,
    },
    /// IMU gap longer than the mechanisation accepts.
    #[error(
        "run: IMU gap of {dt_s:.3} s before sample {index} (t = {t_s:.6} s) exceeds {MAX_DT_S} s"
    )]
    ImuGap {
        /// Index in the IMU data.
        index: usize,
        /// Its time, s.
        t_s: f64,
        /// Gap, s.
        dt_s: f64,
    },
    /// Initialisation failed.
    #[error("run: initialisation: {0}")]
    Init(String),
    /// The static alignment found no valid GNSS fix in its window (no position to start
    /// from): nothing was run. A front end names where the data's fixes went with
    /// [`prepare::Loaded::explain_start_failure`].
    #[error("run: initialisation: no valid GNSS fix during the static window {from_s:.3} .. {to_s:.3} s")]
    NoFixToAlign {
        /// Start of the static window, GPS seconds of week.
        from_s: f64,
        /// End of the static window, GPS seconds of week.
        to_s: f64,
    },
    /// The alignment refused the start-up data (`msg` says where and what to do).
    #[error("run: initialisation: {msg}")]
    Align {
        /// What failed, with the way out.
        msg: String,
        /// The alignment's error.
        #[source]
        source: nav_core::align::AlignError,
    },
    /// Invalid options.
    #[error("run: {0}")]
    Options(String),
    /// The filter configuration is invalid.
    #[error("run: filter configuration: {0}")]
    FilterConfig(#[source] nav_core::config::ConfigError),
    /// The state layout (model plus effect blocks) is invalid.
    #[error("run: {0}")]
    Layout(#[source] nav_core::model::LayoutError),
    /// The IMU guard refused its configuration.
    #[error("run: {0}")]
    Guard(#[source] nav_core::imu_guard::GuardError),
    /// A fault in the middle of the data ended the run; `partial` holds everything up to it.
    #[error("run: {location} (t = {t_s:.6} s): {cause}; the run stopped there")]
    Fault {
        /// `file line N` of the offending sample (or `IMU sample N`, `GNSS fix at t`).
        location: String,
        /// Its time, s.
        t_s: f64,
        /// What went wrong: the nav-core error (typed source of this error).
        #[source]
        cause: FaultCause,
        /// The outputs up to the fault.
        partial: Box<RunOutput>,
    },
    /// Reading the input failed in the middle of the run (the error names file, line and
    /// column).
    #[error("run: {0}")]
    Input(#[source] nav_io::IoError),
    /// Writing an output failed.
    #[error("run: writing the outputs: {0}")]
    Output(#[source] nav_io::IoError),
    /// SIGINT or SIGTERM asked the run to stop (see [`interrupt`]).
    #[error("run: interrupted by {signal}")]
    Interrupted {
        /// The signal's name.
        signal: String,
    },
    /// The filter refused its construction or failed.
    #[error("run: filter at t = {t_s:.3} s: {source}")]
    Filter {
        /// Time, s.
        t_s: f64,
        /// The filter's error.
        #[source]
        source: FilterError,
    },
}

impl RunError {
    /// [`RunError::NoFixToAlign`] for the static window `from_s .. to_s`, s.
    pub(crate) fn no_fix_to_align(from_s: f64, to_s: f64) -> Self {
        Self::NoFixToAlign { from_s, to_s }
    }
}

fn filter_err(t_s: f64, source: FilterError) -> RunError {
    RunError::Filter { t_s, source }
}

/// Runs the filter on a case in memory (see the module notes): [`run_engine`] over the
/// case's samples and fixes with the in-memory sink ([`Collect`]); the returned output holds
/// every record. After a fault, [`RunError::Fault`]'s `partial` holds the records up to it.
pub fn run_filter(case: &CaseData, opts: &RunOptions) -> Result<RunOutput, RunError> {
    run_case(case, opts, CoastPlan::default(), &mut |_, _| {}).map(|(out, _)| out)
}

/// [`run_filter`] with a coasting plan and `progress(done, total)` (IMU samples; `total` 0
/// while unknown) called now and then; also returns the coasting tracks the plan made.
pub(crate) fn run_case(
    case: &CaseData,
    opts: &RunOptions,
    coast: CoastPlan,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(RunOutput, Vec<(usize, CoastTrack)>), RunError> {
    let (it, info) = case_imu_stream(case);
    let mut sink = Collect::default();
    let streams = Streams {
        imu: Box::new(it),
        info,
        gnss: Box::new(case.gnss.iter().copied().map(Ok)),
        truth: case.truth.as_deref(),
    };
    let res = run_engine(streams, opts, coast, &mut sink, progress);
    match res {
        Ok(mut out) => {
            let coast = std::mem::take(&mut sink.coast);
            sink.fill(&mut out);
            Ok((out, coast))
        }
        Err(RunError::Fault {
            location,
            t_s,
            cause,
            mut partial,
        }) => {
            sink.fill(&mut partial);
            // a numerical failure is noticed after the fact: drop the records from the
            // first non-finite one on
            if let Some(i) = partial.nav.iter().position(|s| !solution_is_finite(s)) {
                partial.nav.truncate(i);
            }
            if let Some(i) = partial
                .epochs
                .iter()
                .position(|e| !solution_is_finite(&e.nav))
            {
                partial.epochs.truncate(i);
            }
            Err(RunError::Fault {
                location,
                t_s,
                cause,
                partial,
            })
        }
        Err(e) => Err(e),
    }
}

/// The samples of a case in memory as the engine's IMU stream (with their file lines when the
/// case has an origin of the same length).
pub fn case_imu_stream(
    case: &CaseData,
) -> (
    impl Iterator<Item = Result<ImuItem, RunError>> + '_,
    ImuSourceInfo,
) {
    let lines = case
        .imu_origin
        .as_ref()
        .filter(|o| o.lines.len() == case.imu.len())
        .map(|o| o.lines.as_slice());
    let info = ImuSourceInfo {
        path: case.imu_origin.as_ref().map(|o| o.path.clone()),
        increments_span_gaps: case
            .imu_origin
            .as_ref()
            .is_some_and(|o| o.increments_span_gaps),
    };
    let it = case.imu.iter().enumerate().map(move |(i, s)| {
        Ok(ImuItem {
            sample: *s,
            line: lines.and_then(|l| l.get(i)).copied().unwrap_or(0),
        })
    });
    (it, info)
}

/// True when every navigation quantity of a record is finite.
pub fn solution_is_finite(s: &NavSolution) -> bool {
    s.lat_rad.is_finite()
        && s.lon_rad.is_finite()
        && s.h_m.is_finite()
        && s.vel_ned_mps.iter().all(|v| v.is_finite())
        && s.rpy_rad.iter().all(|v| v.is_finite())
}

/// The inputs of one run of the engine, as streams: the IMU samples and the GNSS fixes in
/// time order (a read error in either ends the run with that error) and the truth the
/// initialisation may start from. The engine keeps only the fixes it may still need
/// ([`FixAhead`]) and a bounded window of samples: memory independent of the record's length.
pub struct Streams<'a> {
    /// IMU samples with their file lines.
    pub imu: Box<dyn Iterator<Item = Result<ImuItem, RunError>> + 'a>,
    /// Where the samples come from (messages, the gap rule).
    pub info: ImuSourceInfo,
    /// GNSS fixes (antenna positions).
    pub gnss: FixSource<'a>,
    /// Truth records at the IMU point (for the initialisation from the truth), when known.
    pub truth: Option<&'a [NavSolution]>,
}

/// Runs the filter on streams of IMU samples and fixes, handing every record to `sink` as it
/// is made (see [`engine`]): dispatches on the state layout (the model's, or the model plus
/// [`RunOptions::extra_blocks`]) and the covariance scalar. Returns the run's summary with
/// empty record lists; `progress(done, 0)` is called every 4096 IMU samples.
pub fn run_engine(
    input: Streams<'_>,
    opts: &RunOptions,
    coast: CoastPlan,
    sink: &mut dyn RunSink,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<RunOutput, RunError> {
    macro_rules! go {
        ($layout:expr) => {
            match opts.precision {
                Precision::F64 => engine::run_layout_stream::<f64, { $layout.dim() }>(
                    $layout, input, opts, coast, sink, progress,
                ),
                Precision::F32 => engine::run_layout_stream::<f32, { $layout.dim() }>(
                    $layout, input, opts, coast, sink, progress,
                ),
            }
        };
    }
    if !opts.extra_blocks.is_empty() {
        let layout = extended_layout(opts)?;
        return run_extended(layout, input, opts, coast, sink, progress);
    }
    match opts.model {
        Model::N => go!(LAYOUT_N),
        Model::Nbk => go!(LAYOUT_NBK),
        Model::NbkSingle => go!(LAYOUT_NBK_SINGLE),
        Model::KfGins21 => go!(LAYOUT_KF_GINS),
        Model::KfGinsFeedback => go!(LAYOUT_KF_GINS_FEEDBACK),
    }
}

/// [`run_engine`] on a layout with extra effect blocks: one filter instantiation per state
/// count in [`MIN_EXTRA_DIM`]..=[`MAX_EXTRA_DIM`], dispatched on the layout's dimension.
///
/// In this crate's own unit-test build the 25 instantiations are left out (they are two
/// thirds of the crate's compile time and no unit test runs an extended layout; the
/// integration tests and every dependent crate get the full dispatch): the layout is then
/// refused with [`RunError::Options`].
fn run_extended(
    layout: Layout,
    input: Streams<'_>,
    opts: &RunOptions,
    coast: CoastPlan,
    sink: &mut dyn RunSink,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<RunOutput, RunError> {
    #[cfg(test)]
    {
        let _ = (input, opts, coast, sink, progress);
        Err(RunError::Options(format!(
            "layout of {} states: extended layouts are not compiled into nav-engine's unit tests",
            layout.dim()
        )))
    }
    #[cfg(not(test))]
    {
        macro_rules! dims {
            ($($n:literal)*) => {
                match layout.dim() {
                    $($n => engine::run_layout_stream::<f64, $n>(
                        layout, input, opts, coast, sink, progress,
                    ),)*
                    d => Err(RunError::Options(format!(
                        "layout of {d} states: run supports {MIN_EXTRA_DIM} to {MAX_EXTRA_DIM} \
                         states with extra effect blocks"
                    ))),
                }
            };
        }
        dims!(16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31 32 33 34 35 36 37 38 39 40)
    }
}

/// The model's layout with [`RunOptions::extra_blocks`] appended (f64 only), validated.
fn extended_layout(opts: &RunOptions) -> Result<Layout, RunError> {
    if opts.precision != Precision::F64 {
        return Err(RunError::Options(
            "extra effect blocks need f64 precision".into(),
        ));
    }
    let mut layout = opts.model.layout();
    for b in &opts.extra_blocks {
        // the odometer's scale factor: an aiding state, appended like an effect block
        if !EFFECT_BLOCKS.contains(b) && *b != Block::OdometerScale {
            return Err(RunError::Options(format!(
                "{} is not an effect block",
                b.name()
            )));
        }
        if layout.contains(b.kind()) {
            return Err(RunError::Options(format!(
                "effect block {} is already in the layout",
                b.name()
            )));
        }
        layout = layout.with(*b);
    }
    layout.validate(layout.dim()).map_err(RunError::Layout)?;
    Ok(layout)
}

/// Names (with units) of the error states of a layout.
pub fn state_names(layout: &Layout) -> Vec<String> {
    let mut v = Vec::new();
    let ax = ["x", "y", "z"];
    for (_, b) in layout.iter() {
        match b {
            Block::Core => {
                for n in [
                    "att_n_rad",
                    "att_e_rad",
                    "att_d_rad",
                    "vel_n_mps",
                    "vel_e_mps",
                    "vel_d_mps",
                    "pos_n_m",
                    "pos_e_m",
                    "pos_d_m",
                ] {
                    v.push(n.to_string());
                }
            }
            Block::GyroBias(m) | Block::AccelBias(m) => {
                let (base, unit) = if matches!(b, Block::GyroBias(_)) {
                    ("gyro_bias", "radps")
                } else {
                    ("accel_bias", "mps2")
                };
                let parts: &[&str] = match m {
                    BiasModel::GaussMarkovRandomWalk => &["_gm", "_rw"],
                    _ => &[""],
                };
                for p in parts {
                    for a in ax {
                        v.push(format!("{base}{p}_{a}_{unit}"));
                    }
                }
            }
            other => {
                for i in 0..other.dim() {
                    let a = ax.get(i % 3).copied().unwrap_or("?");
                    let g = i / 3;
                    if other.dim() > 3 {
                        v.push(format!("{}{}_{a}", other.name(), g));
                    } else {
                        v.push(format!("{}_{a}", other.name()));
                    }
                }
            }
        }
    }
    v
}

/// Decimation of records: keep the first epoch at or after each multiple of the period.
struct Decimator {
    period_s: Option<f64>,
    next_s: f64,
    every: bool,
}

impl Decimator {
    fn new(rate_hz: Option<f64>, t0_s: f64) -> Self {
        match rate_hz {
            None => Self {
                period_s: None,
                next_s: t0_s,
                every: true,
            },
            Some(r) if r > 0.0 && r.is_finite() => Self {
                period_s: Some(1.0 / r),
                next_s: t0_s,
                every: false,
            },
            Some(_) => Self {
                period_s: None,
                next_s: f64::INFINITY,
                every: false,
            },
        }
    }

    fn take(&mut self, t_s: f64) -> bool {
        if self.every {
            return true;
        }
        let Some(p) = self.period_s else {
            return false;
        };
        // tolerance for floating time stamps: 1e-6 of the period
        if t_s + 1e-6 * p >= self.next_s {
            while self.next_s <= t_s + 1e-6 * p {
                self.next_s += p;
            }
            true
        } else {
            false
        }
    }
}

fn block_estimates<T: Scalar, const N: usize>(f: &Filter<T, N>) -> Vec<BlockEstimate> {
    f.layout()
        .iter()
        .filter_map(|(_, b)| {
            let (value, std) = f.imu_error(b.kind())?;
            Some(BlockEstimate {
                name: b.name().to_string(),
                value,
                std,
            })
        })
        .collect()
}

fn all_estimates<T: Scalar, const N: usize>(f: &Filter<T, N>) -> Vec<f64> {
    let mut v = vec![0.0; N];
    for (off, b) in f.layout().iter() {
        if let Some(e) = f.block_estimate(b.kind()) {
            if let Some(dst) = v.get_mut(off..off + e.len()) {
                dst.copy_from_slice(e);
            }
        }
    }
    v
}

/// Predicted antenna position at `t_s` from a nominal state: `r + C l + v (t - t_state)`.
pub fn antenna_position(state: &NavState, lever_arm_m: &[f64; 3], t_s: f64) -> Llh {
    let c = dcm_f64(&state.q_nb);
    let l = c * Vector3::from(*lever_arm_m);
    earth::displace(&state.pos, &(l + state.vel_ned_mps * (t_s - state.t_s)))
}

/// Measured minus predicted antenna position (NED at the fix, m).
pub fn position_innovation(state: &NavState, lever_arm_m: &[f64; 3], fix: &GnssFix) -> [f64; 3] {
    let ant = antenna_position(state, lever_arm_m, fix.t_s);
    let meas = Llh {
        lat_rad: fix.lat_rad,
        lon_rad: fix.lon_rad,
        h_m: fix.h_m,
    };
    let d = earth::ned_offset_m(&meas, &ant);
    [-d.x, -d.y, -d.z]
}

fn record_of(out: &UpdateOutcome, fix: &GnssFix) -> InnovationRecord {
    InnovationRecord {
        t_s: fix.t_s,
        used: if out.forced {
            FixUse::Forced
        } else if out.accepted {
            FixUse::Accepted
        } else {
            FixUse::Rejected
        },
        outage: None,
        dim: out.dim,
        innovation: out.innovation,
        innovation_var: out.innovation_var,
        nis: out.nis,
        nis_threshold: out.nis_threshold,
        quality: fix.quality.rtklib_q(),
    }
}

/// Median interval of the IMU record, s (None with fewer than two samples).
pub fn median_imu_interval_s(imu: &[ImuSample]) -> Option<f64> {
    let mut d: Vec<f64> = imu
        .windows(2)
        .filter_map(|w| match w {
            [a, b] => Some(b.t_s - a.t_s),
            _ => None,
        })
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    if d.is_empty() {
        return None;
    }
    let m = d.len() / 2;
    let (_, v, _) = d.select_nth_unstable_by(m, f64::total_cmp);
    Some(*v)
}
