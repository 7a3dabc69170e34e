//! The loosely coupled error-state INS/GNSS Kalman filter.
//!
//! `Filter<T, N>`: nominal state in f64 (a [`Strapdown`]), covariance and gains in `T`
//! (`f32` on the MCU, `f64` on the host), N error states laid out by a [`Layout`]. Per IMU
//! sample [`Filter::propagate`] corrects the raw increments with the estimated sensor errors,
//! runs the mechanisation and accumulates the error dynamics; the covariance is predicted every
//! [`FilterConfig::cov_predict_interval_s`] (see [`crate::model::discrete`]). Per GNSS fix
//! [`Filter::update_gnss`] gates the innovation (chi-square on the NIS), updates in Joseph form,
//! feeds the error estimate back into the nominal state and the sensor-error estimates and
//! resets it to zero (closed loop).
//!
//! Nothing allocates or panics. Bad inputs (NaN/Inf, time going backwards, invalid fixes) are
//! rejected with a [`FilterError`] and leave the filter unchanged and usable; a numerical
//! failure (non-finite covariance, innovation covariance not positive definite) is reported and
//! the previous covariance kept.

mod access;
mod aiding_update;
mod gapnoise;
mod gated;
mod gnss_vel;
pub(crate) mod linalg;
pub mod observe;
mod reacq;
pub mod robust;
mod sigma_scale;

pub use aiding_update::AidingOutcome;

use crate::attitude;
use crate::config::{ConfigError, FilterConfig};
use crate::earth;
use crate::model::discrete::{self, Accumulator, Cov};
use crate::model::{
    BlockKind, ImuCorrection, InverseScales, Layout, LayoutError, Regressors, CORE_DIM, IDX_ATT,
    IDX_POS, IDX_VEL, MAX_BLOCK_DIM,
};
use crate::scalar::Scalar;
use crate::strapdown::{MechError, NavState, StepInfo, StepInfo32, Strapdown, MAX_DT_S};
use crate::types::{GnssFix, ImuSample, NavSolution};
use linalg::{all_finite, cholesky_in_place};
use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use observe::{CovObserver, PredictionRecord};
use robust::{GateState, RejectedFix, RobustStats};
use sigma_scale::ScaleInput;

/// Status bit of [`NavSolution::status`]: the last GNSS fix was rejected by the gate.
pub const STATUS_LAST_FIX_REJECTED: u32 = 1;
/// Status bit: a numerical failure occurred since the filter started.
pub const STATUS_NUMERICAL_FAILURE: u32 = 2;
/// Status bit: no GNSS fix has been accepted yet.
pub const STATUS_NO_FIX_YET: u32 = 4;
/// Status bit: the NIS monitor declares a model mismatch (innovations persistently larger than
/// predicted): the process noise is inflated and the gate widened (robust gating).
pub const STATUS_MODEL_MISMATCH: u32 = 8;
/// Status bit: the last GNSS fix was used with an inflated R (IGG-III down-weighting).
pub const STATUS_LAST_FIX_DOWNWEIGHTED: u32 = 16;
/// Status bit: the last GNSS fix re-initialised position and velocity after consecutive
/// rejections.
pub const STATUS_RESET: u32 = 32;

/// Errors of the filter. The filter is unchanged by the call that returned one (except for the
/// counters) and stays usable.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FilterError {
    /// The state layout does not fit the filter.
    Layout(LayoutError),
    /// The configuration is invalid.
    Config(ConfigError),
    /// The initial state or uncertainty is not finite (or a sigma negative).
    InitialState,
    /// IMU sample with a NaN/Inf time or increment.
    NonFiniteImu,
    /// IMU sample time not after the filter time, or a gap over `strapdown::MAX_DT_S`.
    ImuTimeStep {
        /// Sample time minus filter time, s.
        dt_s: f64,
    },
    /// GNSS fix with NaN/Inf values, non-positive sigmas or no fix.
    InvalidGnss,
    /// GNSS fix too far in time from the filter's epoch (`max_gnss_time_offset_s`).
    GnssTime {
        /// Fix time minus filter time, s.
        offset_s: f64,
    },
    /// The covariance became non-finite, or the innovation covariance is not positive definite.
    Numerical,
    /// `set_block_estimate`: the layout has no such sensor-error block, or the values do not
    /// fit it (length, NaN/Inf).
    NoSuchBlock,
}

impl core::fmt::Display for FilterError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Layout(e) => write!(f, "filter: {e}"),
            Self::Config(e) => write!(f, "filter: {e}"),
            Self::InitialState => f.write_str("filter: initial state or uncertainty not finite"),
            Self::NonFiniteImu => f.write_str("filter: IMU sample has a NaN/Inf time or increment"),
            Self::ImuTimeStep { dt_s } => write!(
                f,
                "filter: IMU sample time step {dt_s} s is not in (0, {MAX_DT_S}] s"
            ),
            Self::InvalidGnss => f.write_str("filter: GNSS fix invalid (NaN/Inf, sigma <= 0 or no fix)"),
            Self::GnssTime { offset_s } => write!(
                f,
                "filter: GNSS fix is {offset_s} s away from the filter epoch"
            ),
            Self::NoSuchBlock => f.write_str("filter: no such sensor-error block in the layout, or the values do not fit it"),
            Self::Numerical => f.write_str("filter: numerical failure (covariance not finite or innovation covariance not positive definite)"),
        }
    }
}

/// The layout and configuration errors are the sources of [`FilterError::Layout`] and
/// [`FilterError::Config`].
impl core::error::Error for FilterError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            Self::Layout(e) => Some(e),
            Self::Config(e) => Some(e),
            _ => None,
        }
    }
}

/// Initial 1-sigma uncertainty of the core states (the sensor-error blocks take theirs from
/// the [`FilterConfig`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InitialUncertainty {
    /// Attitude error phi (north, east, down axes), rad.
    pub att_sigma_rad: [f64; 3],
    /// NED velocity, m/s.
    pub vel_sigma_mps: [f64; 3],
    /// NED position, m.
    pub pos_sigma_m: [f64; 3],
}

/// Event counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Counters {
    /// IMU samples integrated.
    pub imu_epochs: u64,
    /// IMU samples rejected (non-finite or bad time step).
    pub imu_rejected: u32,
    /// Covariance predictions.
    pub cov_predictions: u32,
    /// GNSS fixes used (including forced ones).
    pub gnss_accepted: u32,
    /// GNSS fixes rejected by the innovation gate.
    pub gnss_rejected: u32,
    /// GNSS fixes that re-initialised position and velocity after too many consecutive
    /// rejections (counted in `gnss_accepted` too).
    pub gnss_forced: u32,
    /// GNSS fixes refused as invalid or mistimed.
    pub gnss_invalid: u32,
    /// Numerical failures (prediction or update skipped).
    pub numerical_failures: u32,
    /// GNSS velocities used by their own update ([`crate::config::Gating::velocity`]).
    pub gnss_vel_accepted: u32,
    /// Of those, used with an inflated R (IGG-III down-weighting).
    pub gnss_vel_downweighted: u32,
    /// GNSS velocities rejected by their own gate.
    pub gnss_vel_rejected: u32,
}

/// What a GNSS update did. Vectors hold `dim` valid entries: north, east, down position (m),
/// then (for `dim` = 6) north, east, down velocity (m/s).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UpdateOutcome {
    /// Fix time, s.
    pub t_s: f64,
    /// Measurement dimension (3 position, 6 position + velocity).
    pub dim: usize,
    /// Innovation, measured minus predicted (antenna), m and m/s.
    pub innovation: [f64; 6],
    /// Diagonal of the innovation covariance S = H P H^T + R, m^2 and m^2/s^2.
    pub innovation_var: [f64; 6],
    /// Normalised innovation squared `nu^T S^-1 nu`.
    pub nis: f64,
    /// The gate threshold that applied.
    pub nis_threshold: f64,
    /// Whether the fix was used.
    pub accepted: bool,
    /// Whether it re-initialised position and velocity (after too many consecutive
    /// rejections) instead of a Kalman update.
    pub forced: bool,
    /// Weight of the fix: 1 = full update, in (0, 1) = used with R / weight (IGG-III
    /// down-weighting), 0 = not used by a Kalman update (rejected, or a reset).
    pub weight: f64,
}

/// The error-state filter with N states and covariance scalar T.
#[derive(Debug, Clone)]
pub struct Filter<T: Scalar, const N: usize> {
    layout: Layout,
    cfg: FilterConfig,
    mech: Strapdown,
    p: Cov<T, N>,
    est: [f64; N],
    corr: ImuCorrection,
    inv_scales: InverseScales,
    acc: Accumulator<T, N>,
    last_step: StepInfo,
    counters: Counters,
    consecutive_rejections: u32,
    gate: GateState,
    /// Initial variance of every state (the floor of a reset's re-initialised covariance).
    prior_var: [f64; N],
    status: u32,
    /// Reference temperature of the temperature blocks, degC (NaN until known).
    temperature_ref_c: f64,
    /// Temperature of the last IMU sample, degC (NaN: none).
    last_temperature_c: f64,
    /// Start time of the filter (its initial state's), s: the reference `t_0` of the
    /// [`crate::model::Block::ImuClockDrift`] offset `dt_0 + r (t - t_0)`.
    clock_ref_s: f64,
    /// Error-state corrections fed back since the last covariance prediction (summed), for
    /// [`observe::PredictionRecord::correction`].
    fed_back: [T; N],
    /// Fill noise waiting for the next prediction (body-axis variances of attitude, velocity,
    /// position; [`Filter::widen_for_fill`]).
    fill_var: [f64; 9],
    /// The first fix after an outage, used on probation ([`reacq`]).
    tentative: reacq::Tentative<T, N>,
    /// The current fix must be processed again (its probation check undid the previous one).
    redo: bool,
}

/// A block's estimate and 1-sigma ([`Filter::block_value`]): `dim` valid entries, SI units of
/// the block's states ([`crate::model::Block::unit`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlockValue {
    /// The block.
    pub block: crate::model::Block,
    /// Number of valid entries.
    pub dim: usize,
    /// Estimate of every state (for the sensor and effect blocks the estimated error itself,
    /// e.g. the lever-arm correction in m; zero for the core).
    pub estimate: [f64; MAX_BLOCK_DIM],
    /// 1-sigma of every state.
    pub sigma: [f64; MAX_BLOCK_DIM],
}

impl<T: Scalar, const N: usize> Filter<T, N> {
    /// A filter with the given layout (whose dimension must be N), configuration, initial
    /// nominal state and core uncertainty.
    pub fn new(
        layout: Layout,
        cfg: &FilterConfig,
        init: NavState,
        unc: &InitialUncertainty,
    ) -> Result<Self, FilterError> {
        Self::check_new(&layout, cfg, &init, unc)?;
        Ok(Self::new_checked(layout, cfg, init, unc))
    }

    /// The checks of [`Self::new`] alone (what it would refuse), without building a filter.
    pub fn check_new(
        layout: &Layout,
        cfg: &FilterConfig,
        init: &NavState,
        unc: &InitialUncertainty,
    ) -> Result<(), FilterError> {
        layout.validate(N).map_err(FilterError::Layout)?;
        cfg.validate().map_err(FilterError::Config)?;
        let q = init.q_nb.quaternion();
        let state_ok = init.t_s.is_finite()
            && init.pos.lat_rad.is_finite()
            && init.pos.lon_rad.is_finite()
            && init.pos.h_m.is_finite()
            && init.vel_ned_mps.iter().all(|v| v.is_finite())
            && q.coords.iter().all(|v| v.is_finite());
        let unc_ok = [unc.att_sigma_rad, unc.vel_sigma_mps, unc.pos_sigma_m]
            .iter()
            .all(|a| a.iter().all(|v| v.is_finite() && *v >= 0.0));
        if !(state_ok && unc_ok) {
            return Err(FilterError::InitialState);
        }
        Ok(())
    }

    /// [`Self::new`] after [`Self::check_new`] passed: the filter itself, without a `Result`
    /// around it (`slot = Some(Filter::new_checked(..))` holds one copy of the filter on the
    /// MCU's stack where `Some(Filter::new(..)?)` held two; out of line, so that its own
    /// temporaries stay out of the caller's frame).
    #[inline(never)]
    pub(crate) fn new_checked(
        layout: Layout,
        cfg: &FilterConfig,
        init: NavState,
        unc: &InitialUncertainty,
    ) -> Self {
        let mut var = [0.0f64; N];
        for (dst, src) in [
            (IDX_ATT, unc.att_sigma_rad),
            (IDX_VEL, unc.vel_sigma_mps),
            (IDX_POS, unc.pos_sigma_m),
        ] {
            for (v, s) in var.iter_mut().skip(dst).zip(src) {
                *v = s * s;
            }
        }
        for (off, b) in layout.iter() {
            if let Some(slot) = var.get_mut(off..) {
                b.initial_variance(cfg, slot);
            }
        }
        let mut p = [[T::ZERO; N]; N];
        for (i, (row, v)) in p.iter_mut().zip(var).enumerate() {
            if let Some(x) = row.get_mut(i) {
                *x = T::of_f64(v);
            }
        }
        Self {
            layout,
            cfg: *cfg,
            mech: Strapdown::new(init),
            p,
            est: [0.0; N],
            corr: ImuCorrection {
                temperature_ref_c: cfg.effects.temperature_ref_c.unwrap_or(f64::NAN),
                ..ImuCorrection::default()
            },
            inv_scales: ImuCorrection::default().inverse_scales(),
            acc: Accumulator::default(),
            last_step: StepInfo::default(),
            counters: Counters::default(),
            consecutive_rejections: 0,
            gate: GateState::default(),
            prior_var: var,
            status: STATUS_NO_FIX_YET,
            temperature_ref_c: cfg.effects.temperature_ref_c.unwrap_or(f64::NAN),
            last_temperature_c: f64::NAN,
            clock_ref_s: init.t_s,
            fed_back: [T::ZERO; N],
            fill_var: [0.0; 9],
            tentative: reacq::Tentative::none(),
            redo: false,
        }
    }

    /// Integrates one raw IMU sample: corrects it with the estimated sensor errors,
    /// mechanises, and accumulates the error dynamics; predicts the covariance when the
    /// configured interval is full.
    pub fn propagate(&mut self, imu: &ImuSample) -> Result<(), FilterError> {
        self.propagate_observed(imu, &mut ())
    }

    /// [`Self::propagate`], handing a covariance prediction (when one is due) to `obs`.
    pub fn propagate_observed<O: CovObserver<T, N>>(
        &mut self,
        imu: &ImuSample,
        obs: &mut O,
    ) -> Result<(), FilterError> {
        if !imu.is_finite() {
            self.counters.imu_rejected = self.counters.imu_rejected.saturating_add(1);
            return Err(FilterError::NonFiniteImu);
        }
        let dt = imu.t_s - self.mech.state().t_s;
        if !(dt > 0.0 && dt <= MAX_DT_S) {
            self.counters.imu_rejected = self.counters.imu_rejected.saturating_add(1);
            return Err(FilterError::ImuTimeStep { dt_s: dt });
        }
        if self.temperature_ref_c.is_nan() && imu.temperature_c.is_finite() {
            // T_ref = the first temperature (EffectsConfig::temperature_ref_c = None)
            self.temperature_ref_c = imu.temperature_c;
            self.corr.temperature_ref_c = imu.temperature_c;
        }
        let (dt_s, f_b, omega_b, f_n) = if T::SINGLE_PRECISION_MECHANIZATION {
            let step = self.mech_step_single(imu, dt)?;
            self.last_step = step.to_f64();
            (
                step.dt_s,
                step.f_body_mps2.map(T::of_f32),
                step.omega_ib_body_radps.map(T::of_f32),
                step.f_ned_mps2.map(T::of_f32),
            )
        } else {
            let step = self.mech_step(imu, dt)?;
            self.last_step = step;
            (
                step.dt_s,
                vec_t(&step.f_body_mps2),
                vec_t(&step.omega_ib_body_radps),
                vec_t(&step.f_ned_mps2),
            )
        };
        self.last_temperature_c = imu.temperature_c;
        let reg = Regressors {
            dt: T::of_f64(dt_s),
            c_nb: dcm_t(&self.mech.state().q_nb),
            f_b,
            omega_b,
            temperature_c: T::of_f64(imu.temperature_c - self.temperature_ref_c),
        };
        self.acc.add(&self.layout, &reg, dt_s, &f_n);
        self.counters.imu_epochs = self.counters.imu_epochs.saturating_add(1);
        if self.acc.dt_s + 0.5 * dt_s >= self.cfg.cov_predict_interval_s {
            self.predict_covariance_observed(obs)?;
        }
        Ok(())
    }

    /// The sensor-error correction and the mixed-precision mechanization of one sample
    /// (`f64` increments) of [`Self::propagate_observed`]; `dt` = sample time - filter time, s.
    fn mech_step(&mut self, imu: &ImuSample, dt: f64) -> Result<StepInfo, FilterError> {
        let mut s = *imu;
        self.corr.apply_with(
            &self.inv_scales,
            &mut s.dtheta_rad,
            &mut s.dv_mps,
            dt,
            imu.temperature_c,
        );
        if !s.is_finite() {
            self.counters.imu_rejected = self.counters.imu_rejected.saturating_add(1);
            return Err(FilterError::NonFiniteImu);
        }
        match self.mech.update(&s) {
            Ok(st) => Ok(st),
            Err(e) => {
                self.counters.imu_rejected = self.counters.imu_rejected.saturating_add(1);
                Err(match e {
                    MechError::NonFinite => FilterError::NonFiniteImu,
                    MechError::BadTimeStep => FilterError::ImuTimeStep { dt_s: dt },
                })
            }
        }
    }

    /// [`Self::mech_step`] in single precision: the increments rounded to `f32`, corrected and
    /// integrated by [`Strapdown::update_single`].
    fn mech_step_single(&mut self, imu: &ImuSample, dt: f64) -> Result<StepInfo32, FilterError> {
        let mut dth = imu.dtheta_rad.map(|v| v as f32);
        let mut dv = imu.dv_mps.map(|v| v as f32);
        self.corr.apply_single(
            &self.inv_scales,
            &mut dth,
            &mut dv,
            dt as f32,
            imu.temperature_c,
        );
        match self.mech.update_single(imu.t_s, dth, dv) {
            Ok(st) => Ok(st),
            Err(e) => {
                self.counters.imu_rejected = self.counters.imu_rejected.saturating_add(1);
                Err(match e {
                    MechError::NonFinite => FilterError::NonFiniteImu,
                    MechError::BadTimeStep => FilterError::ImuTimeStep { dt_s: dt },
                })
            }
        }
    }

    /// Predicts the covariance over the IMU epochs accumulated since the last prediction (a
    /// no-op when there are none). Called by [`Self::propagate`] and before every update.
    pub fn predict_covariance(&mut self) -> Result<(), FilterError> {
        self.predict_covariance_observed(&mut ())
    }

    /// [`Self::predict_covariance`], handing the prediction (when there is one) to `obs`.
    pub fn predict_covariance_observed<O: CovObserver<T, N>>(
        &mut self,
        obs: &mut O,
    ) -> Result<(), FilterError> {
        if self.acc.epochs == 0 {
            return Ok(());
        }
        let interval_s = self.acc.dt_s;
        let mut d = discrete::discretize(&self.layout, &self.cfg, self.mech.state(), &self.acc);
        self.acc = Accumulator::default();
        let infl = self.gate.q_inflation();
        if infl > 1.0 {
            // the NIS monitor's adaptive process-noise inflation (model mismatch)
            let k = T::of_f64(infl);
            d.q_att = crate::model::scale3(&d.q_att, k);
            d.q_vel = crate::model::scale3(&d.q_vel, k);
            for q in d.q_diag.iter_mut() {
                *q *= k;
            }
        }
        // the estimates follow their deterministic dynamics (Gauss-Markov means decay)
        let mut decayed = false;
        for (e, k) in self.est.iter_mut().zip(d.est_decay.iter()).skip(CORE_DIM) {
            if *k != T::ONE {
                *e *= k.to_f64();
                decayed = true;
            }
        }
        if decayed {
            self.refresh_correction();
        }
        let mut p = self.p;
        discrete::predict_covariance(&mut p, &d);
        self.add_fill_noise(&mut p);
        if !all_finite(&p) || !diag_nonneg(&p) {
            return Err(self.numerical_failure());
        }
        let t_end_s = self.mech.state().t_s;
        obs.predicted(&PredictionRecord {
            t_start_s: t_end_s - interval_s,
            t_end_s,
            phi: &d.phi,
            p_before: &self.p,
            p_after: &p,
            correction: &self.fed_back,
        });
        self.fed_back = [T::ZERO; N];
        self.p = p;
        self.counters.cov_predictions = self.counters.cov_predictions.saturating_add(1);
        Ok(())
    }

    /// Uses one GNSS fix (antenna position, and velocity when configured and present). Call it
    /// at the IMU epoch nearest the fix time (within `max_gnss_time_offset_s`; the offset is
    /// bridged with the velocity). Returns the innovation and whether the gate accepted it.
    ///
    /// With robust gating, a first fix after an outage that needs the re-acquisition widening
    /// is used on probation: when the next fix disagrees with it (beyond the normal gate), it
    /// is taken back and the next fix is used as the first one (module `filter::reacq`).
    pub fn update_gnss(&mut self, fix: &GnssFix) -> Result<UpdateOutcome, FilterError> {
        let out = self.update_gnss_once(fix)?;
        if core::mem::take(&mut self.redo) {
            return self.update_gnss_once(fix);
        }
        Ok(out)
    }

    fn update_gnss_once(&mut self, fix: &GnssFix) -> Result<UpdateOutcome, FilterError> {
        if !fix.is_valid() {
            self.counters.gnss_invalid = self.counters.gnss_invalid.saturating_add(1);
            return Err(FilterError::InvalidGnss);
        }
        let nav = *self.mech.state();
        let dt_fix = fix.t_s - nav.t_s;
        if dt_fix.is_nan() || dt_fix.abs() > self.cfg.max_gnss_time_offset_s {
            self.counters.gnss_invalid = self.counters.gnss_invalid.saturating_add(1);
            return Err(FilterError::GnssTime { offset_s: dt_fix });
        }
        self.predict_covariance()?;
        let m = self.gnss_model(fix, dt_fix);
        // the learned GNSS sigma scale (robust gating; 1 otherwise) multiplies R before the
        // gate and the IGG-III weights
        let k = self.gate.sigma_scale();
        let rp = fix.pos_std_ned_m.map(|s| s * s * k);
        let force = self.cfg.gating.max_consecutive_rejections > 0
            && self.consecutive_rejections >= self.cfg.gating.max_consecutive_rejections;
        if let (true, true, Some(vg)) = (
            self.cfg.use_gnss_velocity,
            fix.has_velocity,
            self.cfg.gating.velocity,
        ) {
            return self.update_gnss_separate(fix, dt_fix, &m, &rp, force, vg);
        }
        let (out, zv) = if self.cfg.use_gnss_velocity && fix.has_velocity {
            let rv = fix.vel_std_ned_mps.map(|s| s * s * k);
            let [rv0, rv1, rv2] = rv;
            let [rp0, rp1, rp2] = rp;
            let [zp0, zp1, zp2] = m.zp;
            let [zv0, zv1, zv2] = m.zv;
            let [a, b, cc] = m.h_pos;
            let [d, e, f] = m.h_vel;
            let out = self.kalman_update::<6>(
                &[zp0, zp1, zp2, zv0, zv1, zv2],
                &[a, b, cc, d, e, f],
                &[rp0, rp1, rp2, rv0, rv1, rv2],
                force,
                fix.t_s,
            )?;
            (out, Some((m.zv, rv)))
        } else {
            let out = self.kalman_update::<3>(&m.zp, &m.h_pos, &rp, force, fix.t_s)?;
            (out, None)
        };
        if self.redo {
            return Ok(out);
        }
        Ok(self.after_update(out, &m.zp, &rp, zv))
    }

    /// Bookkeeping after the gate decided: counters, status bits, the NIS monitor
    /// ([`note_gnss_outcome`], not generic), and the re-initialisation from the fixes when the
    /// gate forced one.
    fn after_update(
        &mut self,
        out: UpdateOutcome,
        zp: &[f64; 3],
        rp: &[f64; 3],
        zv: Option<([f64; 3], [f64; 3])>,
    ) -> UpdateOutcome {
        let out = note_gnss_outcome(
            GnssBook {
                counters: &mut self.counters,
                consecutive_rejections: &mut self.consecutive_rejections,
                gate: &mut self.gate,
                status: &mut self.status,
            },
            &self.cfg.gating,
            out,
            zp,
            rp,
        );
        if out.forced {
            self.reset_from_fixes(out.t_s, zp, rp, zv);
        }
        out
    }

    /// Re-initialises position and velocity (and the heading when the GNSS course allows)
    /// from the fixes, with consistent covariance: the position from this fix (`zp` =
    /// predicted minus measured antenna position, NED m, variances `rp`), the velocity from
    /// the fix's velocity when used (`zv`, variances) or else from the rate of the position
    /// error through this fix's and the two previous rejected fixes' innovations (a quadratic;
    /// with one previous fix the mean over the interval; the INS carries the acceleration).
    /// The reset states' variances are set from the fix sigmas; every other state keeps its
    /// estimate with its variance raised to at least its initial one; no cross-covariance is
    /// kept (the filter had diverged: its correlations are not to be trusted).
    fn reset_from_fixes(
        &mut self,
        t_s: f64,
        zp: &[f64; 3],
        rp: &[f64; 3],
        zv: Option<([f64; 3], [f64; 3])>,
    ) {
        let nav = *self.mech.state();
        let var_yaw = get2(&self.p, IDX_ATT + 2, IDX_ATT + 2).to_f64().max(0.0);
        let plan = self.gate.reset_plan(&robust::ResetInput {
            t_s,
            z_pos_m: *zp,
            var_pos_m2: *rp,
            vel: zv,
            vel_ned_mps: nav.vel_ned_mps.into(),
            q_nb: nav.q_nb,
            var_yaw_rad2: var_yaw,
            heading_min_speed_mps: self.cfg.gating.reset_heading_min_speed_mps,
        });
        let mut dx = [T::ZERO; N];
        for (idx, d) in plan.idx.iter().zip(plan.dx.iter()) {
            if let Some(x) = dx.get_mut(*idx) {
                *x = T::of_f64(*d);
            }
        }
        self.feedback(&dx);
        // the filter diverged: its correlations are not to be trusted. Every other state keeps
        // its estimate with its variance raised to at least its initial one, and no
        // cross-covariance is kept; the reset states get the fixes' variances.
        let mut p = [[T::ZERO; N]; N];
        for (i, (row, prior)) in p.iter_mut().zip(self.prior_var.iter()).enumerate() {
            let v = get2(&self.p, i, i).to_f64().max(*prior);
            if let Some(x) = row.get_mut(i) {
                *x = T::of_f64(v);
            }
        }
        for (idx, var) in plan.idx.iter().zip(plan.var.iter()) {
            set2(&mut p, *idx, *idx, T::of_f64(*var));
        }
        self.p = p;
    }

    /// Gated Joseph-form update with measurement `z = H dx + v` (z = predicted - measured),
    /// diagonal R, then closed-loop feedback and reset. Between the down-weighting threshold
    /// and the (widened) rejection threshold R is divided by the IGG-III weight (robust
    /// gating); beyond it the fix is not used and nothing changes (`accepted` false; `forced`
    /// true when `force` asks the caller to re-initialise from the fixes instead).
    fn kalman_update<const M: usize>(
        &mut self,
        z64: &[f64; M],
        h: &[[T; N]; M],
        r64: &[f64; M],
        force: bool,
        t_s: f64,
    ) -> Result<UpdateOutcome, FilterError> {
        let th = self.gate.thresholds(&self.cfg.gating, M, t_s);
        let normal_reject = th.normal_reject;
        let z_pos = [0, 1, 2].map(|i| z64.get(i).copied().unwrap_or(0.0));
        // the next fix decides a fix on probation; a first fix after an outage may go on
        // probation: the covariance before it (the gated update hands its copy over), and the
        // correction it feeds back (what `fed_back` gains)
        let check = reacq::FixCheck {
            normal_reject,
            t_s,
            z_pos_m: z_pos,
            fed_back_before: th.after_outage.then_some(self.fed_back),
        };
        let g = self.gated_update(
            z64,
            h,
            r64,
            gated::Gate {
                downweight: th.downweight,
                reject: th.reject,
            },
            Some(&check),
        )?;
        let mut out = UpdateOutcome {
            t_s,
            dim: M,
            innovation: [0.0; 6],
            innovation_var: [0.0; 6],
            nis: g.nis,
            nis_threshold: th.reject,
            accepted: g.accepted,
            forced: false,
            weight: g.weight,
        };
        for (i, (zi, si)) in z64.iter().zip(g.s_diag.iter()).enumerate() {
            if let Some(o) = out.innovation.get_mut(i) {
                *o = -*zi;
            }
            if let Some(o) = out.innovation_var.get_mut(i) {
                *o = *si;
            }
        }
        out.forced = !g.accepted && force;
        // only fixes used by an update teach the scale (not an outlier, a jump or the fixes
        // of a diverged filter, which are rejected and end in a reset)
        if let (Some(r), false, true) = (&self.cfg.gating.robust, self.redo, g.accepted) {
            let k = self.gate.sigma_scale();
            let inp = ScaleInput {
                z: z64,
                s_diag: &g.s_diag,
                r_used: r64,
            };
            self.gate.learn_scale(r, t_s, k, &inp);
        }
        Ok(out)
    }

    /// Closed-loop feedback of the estimated error `dx` (estimate - truth) into the nominal
    /// state and the sensor-error estimates; the error state is then zero again.
    fn feedback(&mut self, dx: &[T; N]) {
        for (a, d) in self.fed_back.iter_mut().zip(dx) {
            *a += *d;
        }
        let dx64: [f64; N] = dx.map(|v| v.to_f64());
        let phi = vec3_at(&dx64, IDX_ATT);
        let dv = vec3_at(&dx64, IDX_VEL);
        let dr = vec3_at(&dx64, IDX_POS);
        let s = self.mech.state_mut();
        // C = (I + [phi x]) C_hat  =>  q = q(phi) q_hat
        s.q_nb = attitude::quat_from_rotvec(&Vector3::from(phi)) * s.q_nb;
        s.vel_ned_mps -= Vector3::from(dv);
        s.pos = earth::displace(&s.pos, &(-Vector3::from(dr)));
        for (off, b) in self.layout.iter() {
            let end = off + b.dim();
            if let (Some(e), Some(d)) = (self.est.get_mut(off..end), dx64.get(off..end)) {
                b.feedback(e, d);
            }
        }
        self.refresh_correction();
    }

    /// Recomputes the cached IMU correction after the estimates changed.
    fn refresh_correction(&mut self) {
        self.corr = self.imu_correction();
        self.inv_scales = self.corr.inverse_scales();
    }

    fn numerical_failure(&mut self) -> FilterError {
        self.counters.numerical_failures = self.counters.numerical_failures.saturating_add(1);
        self.status |= STATUS_NUMERICAL_FAILURE;
        FilterError::Numerical
    }
}

/// The filter's GNSS bookkeeping state that [`note_gnss_outcome`] updates.
struct GnssBook<'a> {
    counters: &'a mut Counters,
    consecutive_rejections: &'a mut u32,
    gate: &'a mut GateState,
    status: &'a mut u32,
}

/// The bookkeeping of a GNSS position update once the gate decided (`out`; `zp`, `rp` its
/// position innovation, m, and variances, m^2): counters, consecutive rejections, status
/// bits, the rejected-fix history and the NIS monitor (robust gating); a forced fix counts as
/// accepted (the caller then re-initialises from the fixes). Not generic over the state
/// dimension: one instance whatever the filter sizes a binary carries (flash).
#[inline(never)]
fn note_gnss_outcome(
    b: GnssBook<'_>,
    gating: &crate::config::Gating,
    mut out: UpdateOutcome,
    zp: &[f64; 3],
    rp: &[f64; 3],
) -> UpdateOutcome {
    *b.status &= !(STATUS_LAST_FIX_REJECTED | STATUS_LAST_FIX_DOWNWEIGHTED | STATUS_RESET);
    if out.accepted {
        b.counters.gnss_accepted = b.counters.gnss_accepted.saturating_add(1);
        *b.consecutive_rejections = 0;
        b.gate.last_rejected = None;
        b.gate.earlier_rejected = None;
        *b.status &= !STATUS_NO_FIX_YET;
        if out.weight < 1.0 {
            *b.status |= STATUS_LAST_FIX_DOWNWEIGHTED;
            b.gate.stats.downweighted = b.gate.stats.downweighted.saturating_add(1);
        }
    } else if !out.forced {
        b.counters.gnss_rejected = b.counters.gnss_rejected.saturating_add(1);
        *b.consecutive_rejections = b.consecutive_rejections.saturating_add(1);
        *b.status |= STATUS_LAST_FIX_REJECTED;
        b.gate.earlier_rejected = b.gate.last_rejected;
        b.gate.last_rejected = Some(RejectedFix {
            t_s: out.t_s,
            z_pos_m: *zp,
            var_pos_m2: *rp,
        });
    }
    if let Some(r) = gating.robust {
        let ends_gap = out.forced || (out.accepted && b.gate.last_within_normal_gate);
        b.gate.note_fix(out.t_s, ends_gap);
        if out.dim > 0 {
            let rejected = !out.accepted && !out.forced;
            let base = if out.dim == 3 {
                gating.nis_threshold_pos
            } else {
                gating.nis_threshold_pos_vel
            };
            let grow = if out.accepted && !out.forced {
                r.growth_per_fix * out.nis / base
            } else {
                0.0
            };
            b.gate
                .monitor(&r, out.t_s, out.nis / out.dim as f64, rejected, grow);
        }
        if b.gate.stats.mismatch {
            *b.status |= STATUS_MODEL_MISMATCH;
        } else {
            *b.status &= !STATUS_MODEL_MISMATCH;
        }
    }
    if out.forced {
        // the caller re-initialises position and velocity from the fixes (it reads none of
        // the counters, status bits or rejection count set here)
        b.counters.gnss_accepted = b.counters.gnss_accepted.saturating_add(1);
        b.counters.gnss_forced = b.counters.gnss_forced.saturating_add(1);
        *b.consecutive_rejections = 0;
        *b.status &= !STATUS_NO_FIX_YET;
        *b.status |= STATUS_RESET;
        out.accepted = true;
    }
    out
}

/// Largest interval between the previous rejected fix and the fix that re-initialises the
/// filter for the velocity to be taken from their difference, s.
pub const RESET_MAX_FIX_INTERVAL_S: f64 = 30.0;

/// Variance added to the course-derived heading of a heading reset for the vehicle's unknown
/// sideslip, rad^2 ((2 deg)^2).
pub const HEADING_RESET_SIDESLIP_VAR_RAD2: f64 =
    (2.0 * core::f64::consts::PI / 180.0) * (2.0 * core::f64::consts::PI / 180.0);

/// The error-state dimension of the core (re-exported for users indexing `state_std`).
pub const CORE_STATES: usize = CORE_DIM;

fn get2<T: Scalar, const R: usize, const C: usize>(a: &[[T; C]; R], i: usize, j: usize) -> T {
    a.get(i).and_then(|r| r.get(j)).copied().unwrap_or(T::ZERO)
}

fn set2<T: Scalar, const R: usize, const C: usize>(a: &mut [[T; C]; R], i: usize, j: usize, v: T) {
    if let Some(x) = a.get_mut(i).and_then(|r| r.get_mut(j)) {
        *x = v;
    }
}

fn diag_nonneg<T: Scalar, const N: usize>(p: &Cov<T, N>) -> bool {
    p.iter()
        .enumerate()
        .all(|(i, r)| r.get(i).is_some_and(|v| *v >= T::ZERO))
}

fn vec3_at(a: &[f64], i: usize) -> [f64; 3] {
    let mut out = [0.0; 3];
    if let Some(s) = a.get(i..i + 3) {
        out.copy_from_slice(s);
    }
    out
}

fn vec_t<T: Scalar>(v: &Vector3<f64>) -> [T; 3] {
    [T::of_f64(v.x), T::of_f64(v.y), T::of_f64(v.z)]
}

/// C_b^n (row-major) from the attitude quaternion, in f64.
pub fn dcm_f64(q: &UnitQuaternion<f64>) -> Matrix3<f64> {
    let q = q.quaternion();
    let (w, x, y, z) = (q.w, q.i, q.j, q.k);
    Matrix3::new(
        1.0 - 2.0 * (y * y + z * z),
        2.0 * (x * y - w * z),
        2.0 * (x * z + w * y),
        2.0 * (x * y + w * z),
        1.0 - 2.0 * (x * x + z * z),
        2.0 * (y * z - w * x),
        2.0 * (x * z - w * y),
        2.0 * (y * z + w * x),
        1.0 - 2.0 * (x * x + y * y),
    )
}

/// C_b^n (row-major) in the scalar type (quaternion rounded first: cheap on the MCU).
fn dcm_t<T: Scalar>(q: &UnitQuaternion<f64>) -> [[T; 3]; 3] {
    let q = q.quaternion();
    let (w, x, y, z) = (
        T::of_f64(q.w),
        T::of_f64(q.i),
        T::of_f64(q.j),
        T::of_f64(q.k),
    );
    let one = T::ONE;
    let two = one + one;
    [
        [
            one - two * (y * y + z * z),
            two * (x * y - w * z),
            two * (x * z + w * y),
        ],
        [
            two * (x * y + w * z),
            one - two * (x * x + z * z),
            two * (y * z - w * x),
        ],
        [
            two * (x * z - w * y),
            two * (y * z + w * x),
            one - two * (x * x + y * y),
        ],
    ]
}

/// Roll/pitch/yaw 1-sigma from the phi covariance: `rho = A d(rpy)` with A's columns the
/// NED rotation axes of roll (R_z R_y e1), pitch (R_z e2) and yaw (e3).
fn euler_std<T: Scalar, const N: usize>(rpy: &[f64; 3], p: &Cov<T, N>) -> [f64; 3] {
    let [_, th, ps] = *rpy;
    let (st, ct) = (libm::sin(th), libm::cos(th));
    let (sp, cp) = (libm::sin(ps), libm::cos(ps));
    let a = Matrix3::new(cp * ct, -sp, 0.0, sp * ct, cp, 0.0, -st, 0.0, 1.0);
    let Some(ai) = a.try_inverse() else {
        return [f64::NAN; 3];
    };
    let sigma = Matrix3::from_fn(|i, j| get2(p, IDX_ATT + i, IDX_ATT + j).to_f64());
    let e = ai * sigma * ai.transpose();
    [
        libm::sqrt(e.m11.max(0.0)),
        libm::sqrt(e.m22.max(0.0)),
        libm::sqrt(e.m33.max(0.0)),
    ]
}
