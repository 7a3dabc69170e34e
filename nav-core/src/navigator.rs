//! The user loop: a [`Navigator`] owns start-up (alignment), the IMU guard
//! ([`crate::imu_guard`]) and the scheduling of GNSS fixes over a [`Filter`]. Push samples and
//! fixes as they come ([`Navigator::push_imu`], [`Navigator::push_gnss`]), call
//! [`Navigator::flush`] at the end; every call returns a small typed account of what happened.
//!
//! # Fix scheduling: the nearest IMU epoch
//!
//! A fix tagged `t_f` is used at the IMU epoch nearest to it (the rule of the host's run loop,
//! `nav-engine/src/run/engine.rs`): after integrating the sample ending at `t_k`, every pending fix
//! with `t_f < t_k + dt_next / 2` is applied, where `dt_next` is the interval to the next
//! sample. In push form the navigator does not know `dt_next` until the next sample arrives,
//! so fixes wait in a fixed-capacity queue (`Q` fixes, [`NavigatorError::FixQueueFull`] when
//! full) and are applied when sample k+1 arrives, *before* it is integrated: those with
//! `t_f < t_k + (t_{k+1} - t_k) / 2`. [`Navigator::flush`] applies what is due after the last
//! sample (with `dt_next` = the last interval). The filter bridges the remaining offset of at
//! most half an IMU interval ([`Filter::update_gnss`]). Used this way the results are bit
//! for bit those of the host's loop on the same data (`nav-core/tests/it/navigator.rs`).
//! A sample rejected by the guard or the filter does not move the epoch: the fixes wait for
//! the next integrated one, as in the host loop.
//!
//! # Start-up ([`AlignMode`])
//!
//! * [`AlignMode::Given`]: a given initial state and uncertainty; samples up to its time are
//!   skipped (the last one seeds the guard's gap fill), fixes before it dropped.
//! * [`AlignMode::FirstFix`] (the firmware's rule): the first valid fix starts the filter at
//!   the latest IMU sample's time (or at the fix's time, [`FirstFixAlign::start_at_fix_time`])
//!   at the fix's position and velocity (zero without one); roll and pitch come from
//!   levelling the mean specific force of the samples before it, yaw from the GNSS course
//!   when the fix has a horizontal speed of at least [`FirstFixAlign::course_min_speed_mps`],
//!   else 0 with a 180 deg sigma. The position is the antenna's (no lever-arm move: the
//!   heading may be unknown).
//! * [`AlignMode::Static`]: static coarse alignment ([`crate::align::StaticWindow`]) over the
//!   first `seconds` of samples, position from the mean of the valid fixes in the window
//!   (moved to the IMU point with the lever arm), heading given or gyrocompassed, optional
//!   gyro-bias start from the static mean ([`crate::align::static_start`]). A window that is
//!   not static (or has no fix) is reported ([`ImuEvent::AlignFailed`]) and a new window
//!   starts. The host's look-ahead heading (the GNSS course of the first metres of motion
//!   *after* the window) is a post-processing rule and stays in `nav-engine`
//!   (`run/init.rs`).
//!
//! # Aiding
//!
//! Aiding measurements other than GNSS (non-holonomic constraint, zero velocity) will enter
//! through [`Navigator::push_aiding`] with the same scheduling; [`AidingInput`] has no
//! variant yet.
//!
//! # Hooks
//!
//! [`Navigator::push_imu_with`] and [`Navigator::flush_with`] take [`NavHooks`]: a call when
//! an epoch is complete (its fixes applied, before the next sample is integrated), the
//! covariance predictions (the smoother's history), fixes withheld (imposed outages), aiding
//! updates after each integrated sample and a call before each GNSS update. The host's run
//! engine (`nav-engine/src/run/engine.rs`) is this loop with its hooks; [`Navigator::push_imu`]
//! and [`Navigator::flush`] pass [`NoHooks`] (the same code as without hooks).
//!
//! # The IMU guard
//!
//! Every sample after the start passes the [`ImuGuard`] (gaps bridged by the data's
//! convention, implausible samples rejected and counted). Its nominal interval is
//! [`NavigatorConfig::guard`]'s, or, when that is not a positive finite number, the mean
//! interval of the samples seen before the start (1 s without any).
//!
//! No allocation, no panic: errors are [`NavigatorError`] values and leave the navigator
//! usable.

use crate::align::{static_start, AlignConfig, HeadingSource, StaticWindow};
use crate::config::FilterConfig;
use crate::earth::Llh;
use crate::filter::{Filter, FilterError, InitialUncertainty, UpdateOutcome};
use crate::imu_guard::{GuardConfig, GuardCounters, GuardError, Implausible, ImuGuard, Verdict};
use crate::model::{BlockKind, Layout, StateModel};
use crate::scalar::Scalar;
use crate::strapdown::{NavState, MAX_DT_S};
use crate::types::{GnssFix, ImuSample, NavSolution};
use nalgebra::Vector3;

mod error;
mod hooks;
pub use error::{AlignFailure, NavigatorError};
mod startup;
pub use hooks::{NavHooks, NoHooks, ObserveWith};
use startup::{check_config, FixMean, Leveller};

/// Default capacity of the fix queue (fixes waiting for the next IMU sample).
pub const DEFAULT_FIX_QUEUE: usize = 4;

/// Fixes earlier than the initial epoch by more than this are not used, s.
pub const START_TOLERANCE_S: f64 = 1e-9;

/// The nearest-epoch rule (module notes): the time before which a fix is due at the IMU epoch
/// `t_k_s`, given the interval `dt_next_s` to the next sample (s, GPS seconds of week): a fix
/// tagged `t_f` is applied at `t_k` when `t_f < nearest_epoch_horizon(t_k, dt_next)`.
#[inline]
pub fn nearest_epoch_horizon(t_k_s: f64, dt_next_s: f64) -> f64 {
    t_k_s + 0.5 * dt_next_s
}

/// The firmware's alignment: first valid fix plus levelling (module notes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FirstFixAlign {
    /// Smallest horizontal GNSS speed whose course initialises the yaw, m/s.
    pub course_min_speed_mps: f64,
    /// 1-sigma of a yaw from the course, rad.
    pub course_sigma_rad: f64,
    /// 1-sigma of the levelled roll and pitch, rad.
    pub tilt_sigma_rad: f64,
    /// Velocity 1-sigma when the fix has no velocity (velocity 0), m/s.
    pub no_velocity_sigma_mps: f64,
    /// Start at the fix's time instead of the latest IMU sample's (a board whose IMU clock
    /// is set from GNSS by the first fix).
    pub start_at_fix_time: bool,
}

impl Default for FirstFixAlign {
    /// Course above 2 m/s with 5 deg, tilt 1 deg, 1 m/s without a GNSS velocity, start at the
    /// latest IMU sample.
    fn default() -> Self {
        Self {
            course_min_speed_mps: 2.0,
            course_sigma_rad: 5.0 * DEG,
            tilt_sigma_rad: 1.0 * DEG,
            no_velocity_sigma_mps: 1.0,
            start_at_fix_time: false,
        }
    }
}

const DEG: f64 = core::f64::consts::PI / 180.0;

/// Static alignment settings ([`AlignMode::Static`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticAlignSettings {
    /// Window length from the first sample, s.
    pub seconds: f64,
    /// Heading: given (rad, with its 1-sigma) or gyrocompassing.
    pub heading: HeadingSource,
    /// Static-test thresholds (the assumed sensor biases are taken from the filter
    /// configuration's initial bias sigmas where set, [`AlignConfig::with_filter_biases`]).
    pub align: AlignConfig,
    /// Overrides the levelling's roll/pitch 1-sigma, rad.
    pub tilt_std_rad: Option<f64>,
    /// Start the gyro-bias estimate at the static mean rate minus the earth rate.
    pub gyro_bias_from_static: bool,
    /// Initial velocity 1-sigma, m/s.
    pub vel_sigma_mps: f64,
}

impl StaticAlignSettings {
    /// `seconds` of static data with a given heading (rad) and its 1-sigma (rad); gyro bias
    /// from the static mean, default thresholds, 0.02 m/s velocity sigma.
    pub fn with_heading(seconds: f64, yaw_rad: f64, std_rad: f64) -> Self {
        Self {
            seconds,
            heading: HeadingSource::Given { yaw_rad, std_rad },
            align: AlignConfig::default(),
            tilt_std_rad: None,
            gyro_bias_from_static: true,
            vel_sigma_mps: 0.02,
        }
    }
}

/// How the navigator obtains its initial state (module notes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AlignMode {
    /// A given nominal state (its time is the initial epoch) and core uncertainty.
    Given {
        /// Initial state at the IMU reference point.
        state: NavState,
        /// Initial 1-sigma of the core states.
        unc: InitialUncertainty,
    },
    /// First valid fix plus levelling (the firmware's rule).
    FirstFix(FirstFixAlign),
    /// Static coarse alignment over a window.
    Static(StaticAlignSettings),
}

/// Configuration of a [`Navigator`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavigatorConfig {
    /// Filter noise, gating and lever-arm configuration.
    pub filter: FilterConfig,
    /// IMU guard settings (a non-positive or NaN nominal interval: measured before the start).
    pub guard: GuardConfig,
    /// Start-up.
    pub align: AlignMode,
}

impl NavigatorConfig {
    /// `filter` with the default guard (nominal interval measured before the start) and
    /// `align`.
    pub fn new(filter: FilterConfig, align: AlignMode) -> Self {
        Self {
            filter,
            guard: GuardConfig::new(f64::NAN),
            align,
        }
    }
}

/// How the filter started ([`ImuStep::aligned`], [`GnssEvent::Aligned`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Aligned {
    /// Initial epoch, s.
    pub t_s: f64,
    /// Initial roll, pitch, yaw, rad.
    pub rpy_rad: [f64; 3],
    /// Initial attitude 1-sigma (phi N/E/D), rad.
    pub att_sigma_rad: [f64; 3],
    /// Whether the yaw is known (given, gyrocompassed or from the GNSS course); false: 0 with
    /// a 180 deg sigma.
    pub heading_known: bool,
}

/// What happened to an IMU sample.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImuEvent {
    /// Taken for the alignment (the filter has not started).
    Aligning,
    /// At or before the given initial epoch: not integrated.
    BeforeStart,
    /// Integrated.
    Propagated,
    /// Integrated after a gap, bridged by the guard.
    GapBridged {
        /// Missing nominal intervals.
        missing: u32,
        /// Whether the increment was taken as spanning the gap (else filled).
        spanned: bool,
        /// Synthetic samples integrated before it.
        filled: u32,
    },
    /// Rejected by the guard as implausible (counted, not integrated).
    Rejected(Implausible),
    /// Refused by the filter (non-finite; counted, not integrated).
    Refused(FilterError),
    /// The static window was not usable; a new one starts with this sample.
    AlignFailed(AlignFailure),
}

/// What a GNSS fix did to the filter.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FixEvent {
    /// Used with full weight.
    Accepted(UpdateOutcome),
    /// Used with an inflated R (robust down-weighting).
    Downweighted(UpdateOutcome),
    /// Rejected by the gate (state unchanged).
    Rejected(UpdateOutcome),
    /// Re-initialised position and velocity after consecutive rejections.
    Reset(UpdateOutcome),
    /// Refused: invalid, mistimed, or a numerical failure (state unchanged).
    Refused {
        /// Fix time, s.
        t_s: f64,
        /// Why.
        error: FilterError,
    },
}

impl FixEvent {
    fn of(r: Result<UpdateOutcome, FilterError>, t_s: f64) -> Self {
        match r {
            Ok(o) if o.forced => Self::Reset(o),
            Ok(o) if !o.accepted => Self::Rejected(o),
            Ok(o) if o.weight < 1.0 => Self::Downweighted(o),
            Ok(o) => Self::Accepted(o),
            Err(error) => Self::Refused { t_s, error },
        }
    }

    /// The update's outcome (None when refused).
    pub fn outcome(&self) -> Option<&UpdateOutcome> {
        match self {
            Self::Accepted(o) | Self::Downweighted(o) | Self::Rejected(o) | Self::Reset(o) => {
                Some(o)
            }
            Self::Refused { .. } => None,
        }
    }

    /// Whether the fix changed the state (accepted, down-weighted or reset).
    pub fn used(&self) -> bool {
        matches!(
            self,
            Self::Accepted(_) | Self::Downweighted(_) | Self::Reset(_)
        )
    }
}

/// The fixes applied by one call, in time order (at most `Q`).
pub type FixEvents<const Q: usize> = heapless::Vec<FixEvent, Q>;

/// The account of [`Navigator::push_imu`].
#[derive(Debug, Clone, PartialEq)]
pub struct ImuStep<const Q: usize> {
    /// Fixes applied before the sample (due at the previous epoch).
    pub fixes: FixEvents<Q>,
    /// The filter started with this sample (the end of a static window).
    pub aligned: Option<Aligned>,
    /// What happened to the sample.
    pub imu: ImuEvent,
}

impl<const Q: usize> Default for ImuStep<Q> {
    /// No fixes, not aligned, [`ImuEvent::Aligning`] (what a call starts from).
    fn default() -> Self {
        Self {
            fixes: FixEvents::new(),
            aligned: None,
            imu: ImuEvent::Aligning,
        }
    }
}

/// What happened to a pushed GNSS fix.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GnssEvent {
    /// Queued for the nearest IMU epoch.
    Queued,
    /// Started the filter (first-fix alignment).
    Aligned(Aligned),
    /// Averaged into the static window's position (and queued when it may follow the
    /// window's end).
    ForAlignment,
    /// Not used: before the initial epoch, or before any IMU sample, or invalid while
    /// aligning on the first fix.
    Dropped,
}

/// Aiding measurements other than GNSS (module notes). No variant yet: non-holonomic and
/// zero-velocity constraints come with their measurement functions.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum AidingInput {}

/// Counters of a [`Navigator`] (the filter and the guard have their own).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NavigatorCounters {
    /// IMU samples integrated (not counting synthetic gap fills).
    pub imu_integrated: u64,
    /// IMU samples taken for the alignment or before the initial epoch.
    pub imu_before_start: u64,
    /// IMU samples rejected by the guard.
    pub imu_implausible: u64,
    /// IMU samples refused by the filter.
    pub imu_refused: u64,
    /// Fixes used (accepted, down-weighted or resets).
    pub gnss_used: u32,
    /// Of those, down-weighted.
    pub gnss_downweighted: u32,
    /// Of those, resets.
    pub gnss_resets: u32,
    /// Fixes rejected by the gate.
    pub gnss_rejected: u32,
    /// Fixes refused by the filter (invalid, mistimed, numerical).
    pub gnss_refused: u32,
    /// Fixes not used: before the start, before any IMU sample, invalid while aligning, or
    /// left after the end ([`Navigator::flush`]).
    pub gnss_dropped: u32,
    /// Fixes dropped because the queue was full.
    pub gnss_queue_overflow: u32,
    /// Static windows that did not align.
    pub align_failures: u32,
}

/// Start-up, IMU guard and fix scheduling over a [`Filter`] with N states and covariance
/// scalar T; up to `Q` fixes wait for the next IMU sample. See the module notes.
#[derive(Debug, Clone)]
pub struct Navigator<T: Scalar, const N: usize, const Q: usize = DEFAULT_FIX_QUEUE> {
    layout: Layout,
    cfg: NavigatorConfig,
    filter: Option<Filter<T, N>>,
    guard: Option<ImuGuard>,
    fixes: heapless::Deque<GnssFix, Q>,
    /// Latest sample seen (any), and the one before it.
    last_imu: Option<ImuSample>,
    prev_imu: Option<ImuSample>,
    /// Time of the last integrated sample whose fixes wait for the next sample's time.
    epoch_s: Option<f64>,
    /// Interval integrated by that sample (gap included), s.
    epoch_dt_s: f64,
    leveller: Leveller,
    window: StaticWindow,
    fix_mean: FixMean,
    counters: NavigatorCounters,
    aligned: Option<Aligned>,
}

impl<T: Scalar, const N: usize, const Q: usize> Navigator<T, N, Q> {
    /// A navigator for `layout` (N states, checked here at run time: the path of layouts built
    /// at run time; a compile-time model uses [`Navigator::for_model`]). With
    /// [`AlignMode::Given`] the filter starts now
    /// (errors: the filter's, for a bad configuration or initial state); the other modes
    /// check the configuration by building a filter at a neutral state.
    pub fn new(layout: Layout, cfg: NavigatorConfig) -> Result<Self, NavigatorError> {
        match cfg.align {
            AlignMode::Given { state, unc } => {
                let mut nav = Self::unstarted(layout, cfg);
                nav.start(state, &unc, &cfg.filter, true)?;
                Ok(nav)
            }
            _ => {
                // the configuration is checked now, not at the first fix
                check_config::<T, N>(layout, &cfg.filter)?;
                Ok(Self::unstarted(layout, cfg))
            }
        }
    }

    /// A navigator of the compile-time model `M` (its layout `M::LAYOUT`; `N` must be
    /// `M::DIM`, checked when this is compiled): [`Navigator::new`] without a run-time layout.
    /// Errors: the filter's, as [`Navigator::new`].
    ///
    /// ```
    /// use nav_core::config::FilterConfig;
    /// use nav_core::model::ModelNbk;
    /// use nav_core::navigator::{AlignMode, FirstFixAlign, NavigatorConfig, NavigatorNbk};
    /// let cfg = NavigatorConfig::new(
    ///     FilterConfig::source_nbk_model(),
    ///     AlignMode::FirstFix(FirstFixAlign::default()),
    /// );
    /// let nav = NavigatorNbk::for_model::<ModelNbk>(cfg).unwrap();
    /// assert!(nav.filter().is_none());
    /// ```
    ///
    /// A navigator whose `N` is not the model's dimension does not compile:
    ///
    /// ```compile_fail
    /// use nav_core::config::FilterConfig;
    /// use nav_core::model::ModelKfGins;
    /// use nav_core::navigator::{AlignMode, FirstFixAlign, NavigatorConfig, NavigatorNbk};
    /// let cfg = NavigatorConfig::new(
    ///     FilterConfig::source_nbk_model(),
    ///     AlignMode::FirstFix(FirstFixAlign::default()),
    /// );
    /// let nav = NavigatorNbk::for_model::<ModelKfGins>(cfg);
    /// ```
    pub fn for_model<M: StateModel>(cfg: NavigatorConfig) -> Result<Self, NavigatorError> {
        const {
            assert!(
                M::DIM == N,
                "the navigator's N differs from its model's dimension"
            )
        };
        Self::new(M::LAYOUT, cfg)
    }

    fn unstarted(layout: Layout, cfg: NavigatorConfig) -> Self {
        let seconds = match cfg.align {
            AlignMode::Static(s) => s.seconds,
            _ => 0.0,
        };
        Self {
            layout,
            cfg,
            filter: None,
            guard: None,
            fixes: heapless::Deque::new(),
            last_imu: None,
            prev_imu: None,
            epoch_s: None,
            epoch_dt_s: 0.0,
            leveller: Leveller::default(),
            window: StaticWindow::new(seconds),
            fix_mean: FixMean::default(),
            counters: NavigatorCounters::default(),
            aligned: None,
        }
    }

    // cold (start-up): kept out of the per-sample frames (MCU stack)
    #[inline(never)]
    fn start(
        &mut self,
        state: NavState,
        unc: &InitialUncertainty,
        cfg: &FilterConfig,
        heading_known: bool,
    ) -> Result<Aligned, FilterError> {
        // checked first, then built without a `Result` around it: one copy of the filter in
        // this frame instead of two (MCU stack)
        Filter::<T, N>::check_new(&self.layout, cfg, &state, unc)?;
        self.filter = Some(Filter::<T, N>::new_checked(self.layout, cfg, state, unc));
        self.guard = None;
        self.epoch_s = None;
        let a = Aligned {
            t_s: state.t_s,
            rpy_rad: state.rpy_rad(),
            att_sigma_rad: unc.att_sigma_rad,
            heading_known,
        };
        self.aligned = Some(a);
        // fixes before the initial epoch are not used
        while let Some(g) = self.fixes.front() {
            if g.t_s >= state.t_s - START_TOLERANCE_S {
                break;
            }
            self.fixes.pop_front();
            self.counters.gnss_dropped = self.counters.gnss_dropped.saturating_add(1);
        }
        Ok(a)
    }

    /// Sets up the guard for the first sample after the start at `t0` (the latest sample
    /// seeds the gap fill when it ends at `t0`).
    // cold (start-up): kept out of the per-sample frames (MCU stack)
    #[inline(never)]
    fn make_guard(&mut self, t0: f64) -> Result<(), GuardError> {
        let mut gc = self.cfg.guard;
        if !(gc.nominal_dt_s.is_finite() && gc.nominal_dt_s > 0.0) {
            gc.nominal_dt_s = self.leveller.mean_dt_s().unwrap_or(MAX_DT_S);
        }
        let prev = match (self.last_imu, self.prev_imu) {
            (Some(p), Some(pp)) if libm::fabs(p.t_s - t0) < 1e-9 => Some((p, p.t_s - pp.t_s)),
            _ => None,
        };
        self.guard = Some(ImuGuard::new(gc, t0, prev)?);
        Ok(())
    }

    /// Applies the queued fixes due before a sample at `t_next_s` (nearest-epoch rule) and
    /// completes the epoch.
    fn apply_due<H: NavHooks<T, N>>(
        &mut self,
        t_next_s: f64,
        events: &mut FixEvents<Q>,
        hooks: &mut H,
    ) {
        let Some(t_k) = self.epoch_s else {
            return;
        };
        let horizon = nearest_epoch_horizon(t_k, t_next_s - t_k);
        self.apply_before(horizon, events, hooks);
        self.epoch_s = None;
        if let Some(f) = self.filter.as_ref() {
            hooks.on_epoch_done(f);
        }
    }

    fn apply_before<H: NavHooks<T, N>>(
        &mut self,
        horizon: f64,
        events: &mut FixEvents<Q>,
        hooks: &mut H,
    ) {
        let Some(filter) = self.filter.as_mut() else {
            return;
        };
        while let Some(fix) = self.fixes.front().copied() {
            if fix.t_s >= horizon {
                break;
            }
            self.fixes.pop_front();
            if hooks.withhold_fix(filter, &fix) {
                continue;
            }
            if hooks.observes_covariance() {
                // the update's own prediction, seen by the observer (a failure is reported by
                // the update)
                let _ = filter.predict_covariance_observed(&mut hooks.observer());
            }
            hooks.before_gnss(&fix);
            let ev = FixEvent::of(filter.update_gnss(&fix), fix.t_s);
            hooks.on_fix(filter, &fix, &ev);
            let c = &mut self.counters;
            match ev {
                FixEvent::Accepted(_) => c.gnss_used = c.gnss_used.saturating_add(1),
                FixEvent::Downweighted(_) => {
                    c.gnss_used = c.gnss_used.saturating_add(1);
                    c.gnss_downweighted = c.gnss_downweighted.saturating_add(1);
                }
                FixEvent::Reset(_) => {
                    c.gnss_used = c.gnss_used.saturating_add(1);
                    c.gnss_resets = c.gnss_resets.saturating_add(1);
                }
                FixEvent::Rejected(_) => c.gnss_rejected = c.gnss_rejected.saturating_add(1),
                FixEvent::Refused { .. } => c.gnss_refused = c.gnss_refused.saturating_add(1),
            }
            // at most Q fixes are queued, so the list never overflows
            let _ = events.push(ev);
        }
    }

    fn remember(&mut self, s: &ImuSample) {
        self.prev_imu = self.last_imu;
        self.last_imu = Some(*s);
    }

    /// One IMU sample (time order): applies the fixes due at the previous epoch, then
    /// aligns, skips or integrates the sample (through the guard). Errors (the sample is not
    /// used; fixes applied before it are lost from the account but counted): a guard fault or
    /// a filter failure other than a non-finite sample.
    pub fn push_imu(&mut self, s: &ImuSample) -> Result<ImuStep<Q>, NavigatorError> {
        self.push_imu_with(s, &mut NoHooks)
    }

    /// [`Self::push_imu`] with hooks into the loop ([`NavHooks`]; the order of the calls is
    /// in its module notes).
    pub fn push_imu_with<H: NavHooks<T, N>>(
        &mut self,
        s: &ImuSample,
        hooks: &mut H,
    ) -> Result<ImuStep<Q>, NavigatorError> {
        let mut step = ImuStep::default();
        self.push_imu_into(s, hooks, &mut step)?;
        Ok(step)
    }

    /// [`Self::push_imu_with`] writing its account into `step` (cleared first) instead of
    /// returning it, for a caller that keeps one account across samples: the account holds
    /// room for `Q` fix outcomes (about 19.5 KB for `Q` = 128), which a return by value
    /// copies on every sample. After an error, `step` holds what happened before it.
    pub fn push_imu_into<H: NavHooks<T, N>>(
        &mut self,
        s: &ImuSample,
        hooks: &mut H,
        step: &mut ImuStep<Q>,
    ) -> Result<(), NavigatorError> {
        step.fixes.clear();
        step.aligned = None;
        step.imu = ImuEvent::Aligning;
        if self.filter.is_none() {
            self.align_with(s, step);
            if self.filter.is_none() || step.aligned.is_none() {
                return Ok(());
            }
        }
        self.apply_due(s.t_s, &mut step.fixes, hooks);
        let Some(t0) = self.filter.as_ref().map(|f| f.nav_state().t_s) else {
            return Ok(());
        };
        if self.guard.is_none() {
            if s.t_s <= t0 {
                self.leveller.add(s, self.last_imu.map(|p| p.t_s));
                self.remember(s);
                self.counters.imu_before_start += 1;
                step.imu = ImuEvent::BeforeStart;
                return Ok(());
            }
            self.make_guard(t0)?;
        }
        let (Some(guard), Some(filter)) = (self.guard.as_mut(), self.filter.as_mut()) else {
            return Ok(());
        };
        let dt = s.t_s - filter.nav_state().t_s;
        // matched by reference: the verdict (about 300 bytes) is not copied out of its
        // result, and the fill is copied (to iterate it) only when there is one
        let verdict = guard.check(s);
        let c = match &verdict {
            Ok(Verdict::Use(c)) => c,
            Ok(Verdict::Reject(why)) => {
                self.counters.imu_implausible += 1;
                step.imu = ImuEvent::Rejected(*why);
                return Ok(());
            }
            Err(e) => return Err((*e).into()),
        };
        let filled = c.fill.len();
        if filled > 0 {
            for f in c.fill {
                filter.propagate_observed(&f, &mut hooks.observer())?;
            }
        }
        filter.widen_for_fill(&c.fill.uncertainty());
        let r = filter.propagate_observed(&c.sample, &mut hooks.observer());
        match r {
            Ok(()) => hooks.after_sample(filter),
            Err(e @ FilterError::NonFiniteImu) => {
                self.counters.imu_refused += 1;
                step.imu = ImuEvent::Refused(e);
                return Ok(());
            }
            Err(e) => return Err(e.into()),
        }
        self.remember(s);
        self.counters.imu_integrated += 1;
        self.epoch_s = Some(s.t_s);
        self.epoch_dt_s = dt;
        step.imu = if c.missing > 0 {
            ImuEvent::GapBridged {
                missing: c.missing,
                spanned: c.spanned,
                filled,
            }
        } else {
            ImuEvent::Propagated
        };
        Ok(())
    }

    /// A sample before the filter runs: levelling or the static window.
    // cold (start-up): kept out of the per-sample frames (MCU stack)
    #[inline(never)]
    fn align_with(&mut self, s: &ImuSample, step: &mut ImuStep<Q>) {
        match self.cfg.align {
            AlignMode::Given { .. } => {}
            AlignMode::FirstFix(_) => {
                self.leveller.add(s, self.last_imu.map(|p| p.t_s));
                self.remember(s);
                self.counters.imu_before_start += 1;
                step.imu = ImuEvent::Aligning;
            }
            AlignMode::Static(sa) => {
                if self.window.contains(s.t_s) {
                    self.leveller.add(s, self.last_imu.map(|p| p.t_s));
                    self.window.push(s);
                    self.remember(s);
                    self.counters.imu_before_start += 1;
                    // queued fixes before this sample cannot follow the window's end: they
                    // served the position mean only
                    while self
                        .fixes
                        .front()
                        .is_some_and(|g| g.t_s < s.t_s - START_TOLERANCE_S)
                    {
                        self.fixes.pop_front();
                    }
                    step.imu = ImuEvent::Aligning;
                    return;
                }
                match self.finish_static(&sa) {
                    Ok(a) => step.aligned = Some(a),
                    Err(why) => {
                        self.counters.align_failures =
                            self.counters.align_failures.saturating_add(1);
                        self.window.clear();
                        self.fix_mean = FixMean::default();
                        self.drop_queued();
                        self.window.push(s);
                        self.remember(s);
                        self.counters.imu_before_start += 1;
                        step.imu = ImuEvent::AlignFailed(why);
                    }
                }
            }
        }
    }

    // cold (start-up): kept out of the per-sample frames (MCU stack)
    #[inline(never)]
    fn finish_static(&mut self, sa: &StaticAlignSettings) -> Result<Aligned, AlignFailure> {
        let (ant, ant_std) = self.fix_mean.mean().ok_or(AlignFailure::NoFix)?;
        let acfg = sa.align.with_filter_biases(&self.cfg.filter);
        let al = self
            .window
            .align(&ant, sa.heading, &acfg)
            .map_err(AlignFailure::Align)?;
        let mut cfg = self.cfg.filter;
        let st = static_start(
            &al,
            &ant,
            &ant_std,
            &cfg.lever_arm_body_m,
            &cfg.gyro.s_n,
            sa.vel_sigma_mps,
            sa.tilt_std_rad,
        );
        if sa.gyro_bias_from_static {
            for (s, f) in cfg
                .gyro
                .bias_init_sigma
                .iter_mut()
                .zip(st.gyro_bias_sigma_floor_radps)
            {
                *s = s.max(f);
            }
        }
        let a = self
            .start(st.state, &st.unc, &cfg, true)
            .map_err(AlignFailure::Filter)?;
        if sa.gyro_bias_from_static {
            if let (Some(f), Some((_, b))) =
                (self.filter.as_mut(), self.layout.find(BlockKind::GyroBias))
            {
                // a bias block of 3 states (constant or Gauss-Markov) takes the estimate; the
                // 6-state form splits it between two processes and is left at zero
                if b.dim() == 3 {
                    f.set_block_estimate(BlockKind::GyroBias, &st.gyro_bias_radps)
                        .map_err(AlignFailure::Filter)?;
                }
            }
        }
        Ok(a)
    }

    /// One GNSS fix (time order among fixes; it may arrive before or after the IMU samples
    /// around it). Queued for the nearest IMU epoch once the filter runs; before, used for
    /// the alignment. Error: the queue is full (the fix is dropped and counted).
    pub fn push_gnss(&mut self, fix: &GnssFix) -> Result<GnssEvent, NavigatorError> {
        if self.filter.is_none() {
            match self.cfg.align {
                AlignMode::FirstFix(ff) => return Ok(self.first_fix(fix, &ff)),
                AlignMode::Static(_) => {
                    let t_a = self.window.start_s();
                    let in_window = self.window.samples() == 0
                        || (fix.t_s >= t_a - 0.5 && fix.t_s <= t_a + self.window_len() + 0.5);
                    let mut used = false;
                    if fix.is_valid() && in_window {
                        self.fix_mean.add(fix);
                        used = true;
                    }
                    // it may be at or after the window's end: keep it for the updates
                    let latest = self.last_imu.map_or(f64::NEG_INFINITY, |s| s.t_s);
                    if fix.t_s >= latest - START_TOLERANCE_S {
                        self.enqueue(fix)?;
                        used = true;
                    }
                    if !used {
                        self.counters.gnss_dropped = self.counters.gnss_dropped.saturating_add(1);
                        return Ok(GnssEvent::Dropped);
                    }
                    return Ok(GnssEvent::ForAlignment);
                }
                AlignMode::Given { .. } => {}
            }
        }
        let t0 = self.aligned.map_or(f64::NEG_INFINITY, |a| a.t_s);
        if fix.t_s < t0 - START_TOLERANCE_S {
            self.counters.gnss_dropped = self.counters.gnss_dropped.saturating_add(1);
            return Ok(GnssEvent::Dropped);
        }
        self.enqueue(fix)?;
        Ok(GnssEvent::Queued)
    }

    fn window_len(&self) -> f64 {
        match self.cfg.align {
            AlignMode::Static(s) => s.seconds,
            _ => 0.0,
        }
    }

    fn enqueue(&mut self, fix: &GnssFix) -> Result<(), NavigatorError> {
        self.fixes.push_back(*fix).map_err(|_| {
            self.counters.gnss_queue_overflow = self.counters.gnss_queue_overflow.saturating_add(1);
            NavigatorError::FixQueueFull { t_s: fix.t_s }
        })
    }

    // cold (start-up): kept out of the per-sample frames (MCU stack)
    #[inline(never)]
    fn first_fix(&mut self, fix: &GnssFix, ff: &FirstFixAlign) -> GnssEvent {
        let Some(last) = self.last_imu else {
            self.counters.gnss_dropped = self.counters.gnss_dropped.saturating_add(1);
            return GnssEvent::Dropped;
        };
        if !fix.is_valid() {
            self.counters.gnss_dropped = self.counters.gnss_dropped.saturating_add(1);
            return GnssEvent::Dropped;
        }
        let t0_s = if ff.start_at_fix_time {
            fix.t_s
        } else {
            last.t_s
        };
        let [roll, pitch] = self.leveller.roll_pitch_rad();
        let (vel, vel_sigma) = if fix.has_velocity {
            (fix.vel_ned_mps, fix.vel_std_ned_mps)
        } else {
            ([0.0; 3], [ff.no_velocity_sigma_mps; 3])
        };
        let speed = libm::sqrt(vel[0] * vel[0] + vel[1] * vel[1]);
        let heading_known = fix.has_velocity && speed >= ff.course_min_speed_mps;
        let (yaw, yaw_sigma) = if heading_known {
            (libm::atan2(vel[1], vel[0]), ff.course_sigma_rad)
        } else {
            (0.0, core::f64::consts::PI)
        };
        let init = NavState::from_rpy(
            t0_s,
            Llh {
                lat_rad: fix.lat_rad,
                lon_rad: fix.lon_rad,
                h_m: fix.h_m,
            },
            Vector3::from(vel),
            [roll, pitch, yaw],
        );
        let unc = InitialUncertainty {
            att_sigma_rad: [ff.tilt_sigma_rad, ff.tilt_sigma_rad, yaw_sigma],
            vel_sigma_mps: vel_sigma,
            pos_sigma_m: fix.pos_std_ned_m,
        };
        let cfg = self.cfg.filter;
        match self.start(init, &unc, &cfg, heading_known) {
            Ok(a) => GnssEvent::Aligned(a),
            Err(_) => {
                self.filter = None;
                self.aligned = None;
                self.counters.gnss_dropped = self.counters.gnss_dropped.saturating_add(1);
                GnssEvent::Dropped
            }
        }
    }

    /// An aiding measurement (module notes; no kind exists yet).
    pub fn push_aiding(&mut self, a: &AidingInput) -> Result<FixEvents<Q>, NavigatorError> {
        match *a {}
    }

    /// At the end of the data: applies the queued fixes due at the last epoch (with the last
    /// interval as `dt_next`) and drops the rest (counted in `gnss_dropped`).
    pub fn flush(&mut self) -> FixEvents<Q> {
        self.flush_with(&mut NoHooks)
    }

    /// [`Self::flush`] with hooks ([`NavHooks`]): the last epoch's fixes, then
    /// [`NavHooks::on_epoch_done`] when an epoch was pending.
    pub fn flush_with<H: NavHooks<T, N>>(&mut self, hooks: &mut H) -> FixEvents<Q> {
        let mut events = FixEvents::new();
        if let Some(t_k) = self.epoch_s.take() {
            self.apply_before(
                nearest_epoch_horizon(t_k, self.epoch_dt_s),
                &mut events,
                hooks,
            );
            if let Some(f) = self.filter.as_ref() {
                hooks.on_epoch_done(f);
            }
        }
        self.drop_queued();
        events
    }

    /// The last integrated epoch whose fixes still wait for the next sample's time: its time
    /// and the interval it integrated, s (what [`Self::flush`] uses: fixes before
    /// `t + dt / 2` are due).
    pub fn pending_epoch(&self) -> Option<(f64, f64)> {
        self.epoch_s.map(|t| (t, self.epoch_dt_s))
    }

    fn drop_queued(&mut self) {
        let left = u32::try_from(self.fixes.len()).unwrap_or(u32::MAX);
        self.fixes.clear();
        self.counters.gnss_dropped = self.counters.gnss_dropped.saturating_add(left);
    }

    /// Whether the filter runs.
    pub fn is_aligned(&self) -> bool {
        self.filter.is_some()
    }

    /// How the filter started (None before).
    pub fn alignment(&self) -> Option<&Aligned> {
        self.aligned.as_ref()
    }

    /// The filter, once started.
    pub fn filter(&self) -> Option<&Filter<T, N>> {
        self.filter.as_ref()
    }

    /// The filter, once started, mutably (e.g. to set block estimates from a calibration).
    pub fn filter_mut(&mut self) -> Option<&mut Filter<T, N>> {
        self.filter.as_mut()
    }

    /// The nominal state now (None before the start).
    pub fn state(&self) -> Option<&NavState> {
        self.filter.as_ref().map(|f| f.nav_state())
    }

    /// The solution with standard deviations now (None before the start).
    pub fn solution(&self) -> Option<NavSolution> {
        self.filter.as_ref().map(|f| f.solution())
    }

    /// The filter status bits (`u32::MAX` before the start).
    pub fn status(&self) -> u32 {
        self.filter.as_ref().map_or(u32::MAX, |f| f.status())
    }

    /// The navigator's counters.
    pub fn counters(&self) -> &NavigatorCounters {
        &self.counters
    }

    /// The guard's counters (zero before the first sample after the start).
    pub fn guard_counters(&self) -> GuardCounters {
        self.guard
            .as_ref()
            .map(|g| *g.counters())
            .unwrap_or_default()
    }

    /// The guard's configuration once it runs (its nominal interval resolved).
    pub fn guard_config(&self) -> Option<&GuardConfig> {
        self.guard.as_ref().map(|g| g.config())
    }

    /// Fixes waiting for the next IMU sample.
    pub fn pending_fixes(&self) -> usize {
        self.fixes.len()
    }

    /// The configuration.
    pub fn config(&self) -> &NavigatorConfig {
        &self.cfg
    }

    /// Replaces the start-up mode before the start (e.g. a board that learns only then that
    /// its IMU clock is set from GNSS). Returns false, changing nothing, once the filter runs
    /// or for [`AlignMode::Given`] (which starts at construction: use [`Self::new`]).
    pub fn set_align_mode(&mut self, align: AlignMode) -> bool {
        if self.filter.is_some() || matches!(align, AlignMode::Given { .. }) {
            return false;
        }
        if let AlignMode::Static(s) = align {
            self.window = StaticWindow::new(s.seconds);
            self.fix_mean = FixMean::default();
        }
        self.cfg.align = align;
        true
    }

    /// Changes the filter configuration used by a later start; a running filter keeps the
    /// configuration it started with.
    pub fn set_filter_config(&mut self, cfg: FilterConfig) {
        self.cfg.filter = cfg;
    }
}

/// The classical 15-state model ([`crate::model::ModelN`]) with the f32 covariance of the MCU
/// (`Navigator<f64, { ModelN::DIM }>` for f64); build it with [`Navigator::for_model`].
pub type NavigatorN = Navigator<f32, { crate::model::ModelN::DIM }>;
/// The NBK model ([`crate::model::ModelNbk`]), 18 states, f32 covariance.
pub type NavigatorNbk = Navigator<f32, { crate::model::ModelNbk::DIM }>;
/// The NBK model as printed ([`crate::model::ModelNbkSingle`]), 15 states, f32 covariance.
pub type NavigatorNbkSingle = Navigator<f32, { crate::model::ModelNbkSingle::DIM }>;
/// KF-GINS's 21 states ([`crate::model::ModelKfGins`]), f32 covariance.
pub type NavigatorKfGins = Navigator<f32, { crate::model::ModelKfGins::DIM }>;
