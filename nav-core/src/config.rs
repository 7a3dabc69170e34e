//! Filter configuration: IMU noise parameters in the source document's terms (two-sided
//! continuous power spectral densities S_N, S_B, S_K and the Gauss-Markov correlation time
//! T_B), scale-factor and GNSS settings, and the conversions from datasheet units.
//!
//! Units (IEEE 952 convention, `N = sqrt(S_N)`, `K = sqrt(S_K)`):
//!
//! | parameter | accelerometer | gyro |
//! |---|---|---|
//! | white noise S_N | m^2/s^3 (velocity random walk^2) | rad^2/s (angle random walk^2) |
//! | Gauss-Markov driving PSD S_B | m^2/s^5 | rad^2/s^3 |
//! | correlation time T_B | s | s |
//! | random walk S_K | m^2/s^5 | rad^2/s^3 |
//! | bias sigma | m/s^2 | rad/s |
//!
//! The stationary variance of a first-order Gauss-Markov process with driving PSD S_B and
//! correlation time T_B is `S_B T_B / 2` (DESIGN.md: `Q_GM = (S_B T_B / 2)(1 - Phi^2)`).
//! Datasheet units are converted only here, at the edge ([`units`]).

use crate::earth::G0_MPS2;

/// Conversions between datasheet units and the SI quantities the filter uses.
pub mod units {
    use super::G0_MPS2;

    /// Degrees to radians.
    pub const DEG: f64 = core::f64::consts::PI / 180.0;
    /// One micro-g in m/s^2 (standard gravity 9.80665 m/s^2).
    pub const UG_MPS2: f64 = 1e-6 * G0_MPS2;
    /// One milligal in m/s^2.
    pub const MGAL_MPS2: f64 = 1e-5;
    /// One part per million (dimensionless).
    pub const PPM: f64 = 1e-6;
    /// Seconds per hour.
    pub const HOUR_S: f64 = 3600.0;
    /// sqrt(seconds per hour) = 60 sqrt(s)/sqrt(h).
    pub const SQRT_HOUR_S: f64 = 60.0;

    /// Peak Allan deviation of a first-order Gauss-Markov process in units of
    /// sqrt(S_B T_B): max over tau of sqrt(f(tau/T_B)) with
    /// `f(x) = (1/x)[1 - (3 - 4 e^-x + e^-2x)/(2x)]`, reached at tau = 1.8926 T_B.
    pub const GM_PEAK_ADEV: f64 = 0.436_542_471;
    /// Allan deviation floor of flicker noise in units of its coefficient B:
    /// sqrt(2 ln 2 / pi) (IEEE 952).
    pub const FLICKER_FLOOR_ADEV: f64 = 0.664_282_470_268;

    /// Accelerometer white-noise PSD S_N (m^2/s^3) from a noise density in ug/sqrt(Hz).
    pub fn accel_psd_from_ug_per_sqrt_hz(n_ug_per_sqrt_hz: f64) -> f64 {
        let n = n_ug_per_sqrt_hz * UG_MPS2;
        n * n
    }
    /// Accelerometer noise density N in ug/sqrt(Hz) from S_N (m^2/s^3).
    pub fn accel_ug_per_sqrt_hz_from_psd(s_n: f64) -> f64 {
        libm::sqrt(s_n) / UG_MPS2
    }
    /// Accelerometer white-noise PSD S_N (m^2/s^3) from a velocity random walk in
    /// m/s/sqrt(h) (KF-GINS `vrw`).
    pub fn accel_psd_from_mps_per_sqrt_h(vrw_mps_per_sqrt_h: f64) -> f64 {
        let n = vrw_mps_per_sqrt_h / SQRT_HOUR_S;
        n * n
    }
    /// Velocity random walk in m/s/sqrt(h) from S_N (m^2/s^3).
    pub fn accel_mps_per_sqrt_h_from_psd(s_n: f64) -> f64 {
        libm::sqrt(s_n) * SQRT_HOUR_S
    }
    /// Gyro white-noise PSD S_N (rad^2/s) from an angle random walk in deg/sqrt(h).
    pub fn gyro_psd_from_deg_per_sqrt_h(arw_deg_per_sqrt_h: f64) -> f64 {
        let n = arw_deg_per_sqrt_h * DEG / SQRT_HOUR_S;
        n * n
    }
    /// Angle random walk in deg/sqrt(h) from S_N (rad^2/s).
    pub fn gyro_deg_per_sqrt_h_from_psd(s_n: f64) -> f64 {
        libm::sqrt(s_n) * SQRT_HOUR_S / DEG
    }
    /// Accelerometer rate-random-walk PSD S_K (m^2/s^5) from K in ug/sqrt(h)
    /// (bias growth per sqrt(hour)).
    pub fn accel_rw_psd_from_ug_per_sqrt_h(k_ug_per_sqrt_h: f64) -> f64 {
        let k = k_ug_per_sqrt_h * UG_MPS2 / SQRT_HOUR_S;
        k * k
    }
    /// K in ug/sqrt(h) from the accelerometer random-walk PSD S_K (m^2/s^5).
    pub fn accel_ug_per_sqrt_h_from_rw_psd(s_k: f64) -> f64 {
        libm::sqrt(s_k) * SQRT_HOUR_S / UG_MPS2
    }
    /// Gyro rate-random-walk PSD S_K (rad^2/s^3) from K in deg/h/sqrt(h).
    pub fn gyro_rw_psd_from_deg_per_h_per_sqrt_h(k: f64) -> f64 {
        let k = k * DEG / HOUR_S / SQRT_HOUR_S;
        k * k
    }
    /// m/s^2 from micro-g.
    pub fn mps2_from_ug(x_ug: f64) -> f64 {
        x_ug * UG_MPS2
    }
    /// micro-g from m/s^2.
    pub fn ug_from_mps2(x_mps2: f64) -> f64 {
        x_mps2 / UG_MPS2
    }
    /// m/s^2 from milligal.
    pub fn mps2_from_mgal(x_mgal: f64) -> f64 {
        x_mgal * MGAL_MPS2
    }
    /// rad/s from deg/h.
    pub fn radps_from_deg_per_h(x_deg_per_h: f64) -> f64 {
        x_deg_per_h * DEG / HOUR_S
    }
    /// deg/h from rad/s.
    pub fn deg_per_h_from_radps(x_radps: f64) -> f64 {
        x_radps * HOUR_S / DEG
    }
    /// Dimensionless factor from ppm.
    pub fn from_ppm(x_ppm: f64) -> f64 {
        x_ppm * PPM
    }
    /// Gauss-Markov driving PSD S_B (unit^2/s) from the stationary sigma (unit) and the
    /// correlation time T (s): S_B = 2 sigma^2 / T.
    pub fn gm_psd_from_sigma(sigma: f64, t_s: f64) -> f64 {
        2.0 * sigma * sigma / t_s
    }
    /// Stationary sigma sqrt(S_B T_B / 2) of a Gauss-Markov process.
    pub fn gm_sigma_from_psd(s_b: f64, t_b_s: f64) -> f64 {
        libm::sqrt(0.5 * s_b * t_b_s)
    }
    /// Flicker (bias instability) coefficient B matched to the Gauss-Markov process's peak
    /// Allan deviation: B = (GM_PEAK_ADEV / FLICKER_FLOOR_ADEV) sqrt(S_B T_B)
    /// = 0.6572 sqrt(S_B T_B). Units: sqrt(S_B T_B)'s (m/s^2 or rad/s).
    pub fn flicker_b_from_gm(s_b: f64, t_b_s: f64) -> f64 {
        GM_PEAK_ADEV / FLICKER_FLOOR_ADEV * libm::sqrt(s_b * t_b_s)
    }
    /// Inverse of [`flicker_b_from_gm`]: S_B for a flicker coefficient B and a chosen T_B.
    pub fn gm_psd_from_flicker_b(b: f64, t_b_s: f64) -> f64 {
        let r = b * FLICKER_FLOOR_ADEV / GM_PEAK_ADEV;
        r * r / t_b_s
    }
}

/// Noise and bias parameters of one sensor triad (accelerometers or gyros), in the source's
/// terms. Per-axis arrays are x, y, z (body FRD). Units in the module table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorNoise {
    /// White-noise PSD S_N: accel m^2/s^3, gyro rad^2/s.
    pub s_n: [f64; 3],
    /// Gauss-Markov bias driving PSD S_B: accel m^2/s^5, gyro rad^2/s^3 (0 = none).
    pub s_b: [f64; 3],
    /// Gauss-Markov correlation time T_B, s (used only by Gauss-Markov bias models).
    pub t_b_s: f64,
    /// Random-walk bias PSD S_K: accel m^2/s^5, gyro rad^2/s^3 (0 = random constant).
    pub s_k: [f64; 3],
    /// Initial 1-sigma of the constant / random-walk part of the bias (turn-on bias):
    /// accel m/s^2, gyro rad/s. The Gauss-Markov part starts at its stationary sigma.
    pub bias_init_sigma: [f64; 3],
}

impl SensorNoise {
    /// Same parameters on all three axes.
    pub const fn isotropic(s_n: f64, s_b: f64, t_b_s: f64, s_k: f64, bias_init_sigma: f64) -> Self {
        Self {
            s_n: [s_n; 3],
            s_b: [s_b; 3],
            t_b_s,
            s_k: [s_k; 3],
            bias_init_sigma: [bias_init_sigma; 3],
        }
    }

    fn is_valid(&self) -> bool {
        let nonneg = |a: &[f64; 3]| a.iter().all(|v| v.is_finite() && *v >= 0.0);
        nonneg(&self.s_n)
            && nonneg(&self.s_b)
            && nonneg(&self.s_k)
            && nonneg(&self.bias_init_sigma)
            && self.t_b_s.is_finite()
            && self.t_b_s > 0.0
    }
}

/// A scale-factor error modelled as a first-order Gauss-Markov process (as KF-GINS does).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaleFactorNoise {
    /// Stationary (and initial) 1-sigma per axis, dimensionless (1e-6 = 1 ppm).
    pub sigma: [f64; 3],
    /// Correlation time, s.
    pub t_s: f64,
}

impl ScaleFactorNoise {
    /// `sigma_ppm` on all axes with correlation time `t_s`.
    pub fn from_ppm(sigma_ppm: f64, t_s: f64) -> Self {
        Self {
            sigma: [units::from_ppm(sigma_ppm); 3],
            t_s,
        }
    }

    fn is_valid(&self) -> bool {
        self.sigma.iter().all(|v| v.is_finite() && *v >= 0.0)
            && self.t_s.is_finite()
            && self.t_s > 0.0
    }
}

/// Prior and process noise of an effect block (the effects: misalignment, lever arm,
/// time offset, temperature coefficients, g-sensitivity): every state of the block is a random
/// constant (`rw_psd` = 0) or a very slow random walk `x' = w`, `E[w w] = rw_psd delta(t)`,
/// starting at `N(0, init_sigma^2)`. Units are those of the block's states (documented on each
/// [`crate::model::Block`] variant): `init_sigma` in the state's unit, `rw_psd` in unit^2/s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EffectNoise {
    /// Initial 1-sigma of every state of the block, in the state's unit.
    pub init_sigma: f64,
    /// Random-walk PSD, state unit^2/s (0 = random constant).
    pub rw_psd: f64,
}

impl EffectNoise {
    /// A random constant with initial sigma `init_sigma` (state unit).
    pub const fn constant(init_sigma: f64) -> Self {
        Self {
            init_sigma,
            rw_psd: 0.0,
        }
    }

    /// A random walk starting at sigma `init_sigma` (state unit) with PSD `rw_psd`
    /// (state unit^2/s).
    pub const fn random_walk(init_sigma: f64, rw_psd: f64) -> Self {
        Self { init_sigma, rw_psd }
    }

    fn is_valid(&self) -> bool {
        self.init_sigma.is_finite()
            && self.init_sigma >= 0.0
            && self.rw_psd.is_finite()
            && self.rw_psd >= 0.0
    }
}

/// A time-correlated GNSS antenna-position error modelled as a first-order Gauss-Markov
/// process per NED axis (`e' = -e/T + w`, stationary variance `sigma^2`): multipath,
/// atmosphere and orbit/clock errors that a white position noise does not describe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssErrorNoise {
    /// Stationary (and initial) 1-sigma per axis (north, east, down), m.
    pub sigma_m: [f64; 3],
    /// Correlation time, s.
    pub t_s: f64,
}

impl GnssErrorNoise {
    fn is_valid(&self) -> bool {
        self.sigma_m.iter().all(|v| v.is_finite() && *v >= 0.0)
            && self.t_s.is_finite()
            && self.t_s > 0.0
    }
}

/// The effect blocks' priors and process noise (used only by the blocks in the layout).
/// Defaults ([`EffectsConfig::default`]) are wide tactical-grade priors, all random constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EffectsConfig {
    /// `accel_misalignment`: the 6 off-diagonal elements of the accelerometer triad's sensor
    /// matrix, rad (dimensionless small angles).
    pub accel_misalignment: EffectNoise,
    /// `gyro_misalignment`: the 6 off-diagonal elements of the gyro triad's sensor matrix, rad.
    pub gyro_misalignment: EffectNoise,
    /// `lever_arm`: correction to the configured GNSS antenna lever arm, body FRD, m.
    pub lever_arm: EffectNoise,
    /// `time_offset`: IMU-GNSS time offset, s (also the offset state of `imu_clock_drift`).
    pub time_offset: EffectNoise,
    /// `imu_clock_drift`: the rate of the IMU-GNSS time offset (IMU clock frequency error),
    /// s/s (1e-6 = 1 ppm).
    pub imu_clock_drift: EffectNoise,
    /// `gnss_position_gm`: time-correlated GNSS antenna-position error, NED, m.
    pub gnss_position_gm: GnssErrorNoise,
    /// `accel_temperature_bias`: accelerometer bias temperature coefficient, m/s^2/degC.
    pub accel_temperature: EffectNoise,
    /// `gyro_temperature_bias`: gyro bias temperature coefficient, rad/s/degC.
    pub gyro_temperature: EffectNoise,
    /// `gyro_g_sensitivity`: diagonal g-dependent gyro bias, rad/s per m/s^2.
    pub gyro_g_sensitivity: EffectNoise,
    /// `odometer_scale`: wheel-speed odometer scale-factor error (dimensionless).
    pub odometer_scale: EffectNoise,
    /// Reference temperature T_ref of the temperature coefficients, degC; `None` = the first
    /// IMU sample that carries a temperature.
    pub temperature_ref_c: Option<f64>,
}

impl Default for EffectsConfig {
    /// Misalignments 1 mrad, lever arm 1 m, time offset 0.1 s, IMU clock drift 100 ppm, GNSS
    /// position Gauss-Markov error 0.5 m (N, E) / 1 m (D) with 300 s, accelerometer temperature
    /// coefficient 100 ug/degC, gyro temperature coefficient 0.1 deg/h/degC, g-sensitivity
    /// 10 deg/h/g (a MEMS tactical gyro's order; a fibre-optic gyro's is under 1), odometer
    /// scale factor 5 %; all random constants; T_ref = the first temperature.
    fn default() -> Self {
        Self {
            accel_misalignment: EffectNoise::constant(1e-3),
            gyro_misalignment: EffectNoise::constant(1e-3),
            lever_arm: EffectNoise::constant(1.0),
            time_offset: EffectNoise::constant(0.1),
            imu_clock_drift: EffectNoise::constant(1e-4),
            gnss_position_gm: GnssErrorNoise {
                sigma_m: [0.5, 0.5, 1.0],
                t_s: 300.0,
            },
            accel_temperature: EffectNoise::constant(100.0 * units::UG_MPS2),
            gyro_temperature: EffectNoise::constant(units::radps_from_deg_per_h(0.1)),
            gyro_g_sensitivity: EffectNoise::constant(units::radps_from_deg_per_h(10.0) / G0_MPS2),
            odometer_scale: EffectNoise::constant(0.05),
            temperature_ref_c: None,
        }
    }
}

impl EffectsConfig {
    fn is_valid(&self) -> bool {
        [
            self.accel_misalignment,
            self.gyro_misalignment,
            self.lever_arm,
            self.time_offset,
            self.imu_clock_drift,
            self.accel_temperature,
            self.gyro_temperature,
            self.gyro_g_sensitivity,
            self.odometer_scale,
        ]
        .iter()
        .all(EffectNoise::is_valid)
            && self.gnss_position_gm.is_valid()
            && self.temperature_ref_c.is_none_or(f64::is_finite)
    }
}

/// Chi-square quantiles for the innovation gate, by measurement dimension and probability.
pub mod chi2 {
    /// 3 degrees of freedom, P = 0.95.
    pub const DIM3_P95: f64 = 7.814_727_903;
    /// 3 degrees of freedom, P = 0.99.
    pub const DIM3_P99: f64 = 11.344_866_730;
    /// 3 degrees of freedom, P = 0.999.
    pub const DIM3_P999: f64 = 16.266_236_196;
    /// 3 degrees of freedom, P = 0.9999.
    pub const DIM3_P9999: f64 = 21.107_513_466;
    /// 6 degrees of freedom, P = 0.95.
    pub const DIM6_P95: f64 = 12.591_587_244;
    /// 6 degrees of freedom, P = 0.99.
    pub const DIM6_P99: f64 = 16.811_893_830;
    /// 6 degrees of freedom, P = 0.999.
    pub const DIM6_P999: f64 = 22.457_744_485;
    /// 6 degrees of freedom, P = 0.9999.
    pub const DIM6_P9999: f64 = 27.856_341_236;
}

/// Gate probability for the chi-square innovation test.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GateProbability {
    /// Accept 95 % of consistent fixes.
    P95,
    /// Accept 99 %.
    P99,
    /// Accept 99.9 %.
    P999,
    /// Accept 99.99 %.
    P9999,
}

/// Innovation gating of GNSS updates: a fix whose normalised innovation squared (NIS) exceeds
/// the threshold for its measurement dimension is rejected and counted; after
/// `max_consecutive_rejections` rejections in a row the filter re-initialises position and
/// velocity (and heading when the GNSS course allows) from the fixes.
///
/// With `robust: Some(..)` (the default) the gate tells an isolated outlier from a persistent
/// model mismatch: fixes between the down-weighting threshold and the gate are used with an
/// inflated R (IGG-III weights) instead of being rejected, and a windowed NIS monitor widens the
/// gate and inflates the process noise while the innovations stay larger than predicted (see
/// `docs/robust-gating.md` and [`RobustGating`]). With `robust: None` the gate is the classical
/// hard chi-square test.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gating {
    /// NIS threshold for a position-only update (3 degrees of freedom); `f64::INFINITY`
    /// disables the gate. With the robust scheme: the rejection threshold before widening.
    pub nis_threshold_pos: f64,
    /// NIS threshold for a position + velocity update (6 degrees of freedom).
    pub nis_threshold_pos_vel: f64,
    /// After this many consecutive rejected fixes the next fix that fails the gate
    /// re-initialises position and velocity from the fixes (so a filter that drifted away
    /// recovers); 0 = never.
    pub max_consecutive_rejections: u32,
    /// A reset re-initialises the heading from the GNSS course (assuming the vehicle moves
    /// forward without sideslip) only when the horizontal speed is at least this and the
    /// course is within 90 deg of the heading, m/s (`f64::INFINITY` = never).
    pub reset_heading_min_speed_mps: f64,
    /// Robust re-weighting and the model-mismatch monitor; `None` = hard gate.
    pub robust: Option<RobustGating>,
    /// GNSS velocity with its own gate: `Some` updates a fix's velocity separately, after its
    /// position (3 + 3 dimensions, each gated on its own: a bad Doppler velocity does not
    /// throw away a good position, nor the reverse); `None` (the default) uses position and
    /// velocity in one 6-dimensional update gated together.
    pub velocity: Option<VelocityGating>,
}

/// The GNSS velocity's own gate ([`Gating::velocity`]): chi-square thresholds on the 3-dof
/// NIS of the velocity update. At or below `downweight_nis` full weight; between it and
/// `reject_nis` R is divided by the IGG-III weight (robust); beyond `reject_nis` the velocity
/// is not used (counted in [`crate::filter::Counters::gnss_vel_rejected`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VelocityGating {
    /// NIS (3 degrees of freedom) above which the velocity is down-weighted (dimensionless).
    pub downweight_nis: f64,
    /// NIS above which it is rejected (dimensionless; infinite: never).
    pub reject_nis: f64,
}

impl VelocityGating {
    /// Robust: down-weighting from the 0.99 chi-square quantile, rejection beyond 0.9999.
    pub const ROBUST: Self = Self {
        downweight_nis: chi2::DIM3_P99,
        reject_nis: chi2::DIM3_P9999,
    };

    /// No gate: every velocity is used with full weight.
    pub const OFF: Self = Self {
        downweight_nis: f64::INFINITY,
        reject_nis: f64::INFINITY,
    };

    /// A hard gate (no down-weighting) at the given probability.
    pub const fn hard(p: GateProbability) -> Self {
        let t = match p {
            GateProbability::P95 => chi2::DIM3_P95,
            GateProbability::P99 => chi2::DIM3_P99,
            GateProbability::P999 => chi2::DIM3_P999,
            GateProbability::P9999 => chi2::DIM3_P9999,
        };
        Self {
            downweight_nis: t,
            reject_nis: t,
        }
    }

    fn is_valid(&self) -> bool {
        self.downweight_nis > 0.0 && self.reject_nis >= self.downweight_nis
    }
}

/// Default [`Gating::reset_heading_min_speed_mps`], m/s.
pub const DEFAULT_RESET_HEADING_MIN_SPEED_MPS: f64 = 5.0;

/// Largest NIS monitor window ([`RobustGating::window`]), fixes.
pub const MAX_NIS_WINDOW: usize = 16;

/// Parameters of the robust gating scheme (IGG-III down-weighting of R plus a windowed NIS
/// monitor with adaptive process-noise inflation). Ratios are of the NIS normalised by the
/// measurement dimension (1 = consistent on average).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobustGating {
    /// NIS threshold (3 degrees of freedom) above which a fix is down-weighted (IGG-III k0^2);
    /// default the 0.99 chi-square quantile.
    pub downweight_nis_pos: f64,
    /// The same for position + velocity updates (6 degrees of freedom).
    pub downweight_nis_pos_vel: f64,
    /// Number of fixes in the NIS monitor window (1..=[`MAX_NIS_WINDOW`]).
    pub window: usize,
    /// The monitor declares a model mismatch when the window median of NIS/dof exceeds this.
    pub mismatch_ratio_on: f64,
    /// It eases the inflation back off while the median is below this.
    pub mismatch_ratio_off: f64,
    /// Factor applied per fix to the process-noise inflation while a mismatch is declared, and
    /// to the gate widening per rejection in a run of two or more, > 1.
    pub inflation_step: f64,
    /// Factor divided out per fix while easing off (median below `mismatch_ratio_off`), > 1.
    pub easing_step: f64,
    /// Largest process-noise inflation factor (multiplies Q while a mismatch is declared,
    /// `inflation_step` per fix), >= 1; 1 = no inflation (the default).
    pub max_q_inflation: f64,
    /// Largest gate widening factor (multiplies the rejection threshold), >= 1. A fix that
    /// ends a gap (see `reacquisition_gap_intervals`) gets it at once.
    pub max_gate_widening: f64,
    /// A fix ends a gap when no fix was used for more than this many nominal fix intervals
    /// (the running mean of the intervals between fixes) ...
    pub reacquisition_gap_intervals: f64,
    /// ... and for more than this long, s.
    pub reacquisition_min_gap_s: f64,
    /// A used fix widens the gate for the next one to this many times its own NIS, >= 1: an
    /// innovation that grows steadily (a mismatch building up) is not rejected, an isolated
    /// jump is.
    pub growth_per_fix: f64,
    /// Fixes after the start (and after a re-initialisation from the fixes) that get the
    /// re-acquisition gate (`max_gate_widening`), 0 = none: until the monitor has seen this
    /// many fixes it does not know their innovation level, and a fix beyond the normal gate
    /// may as well be one of many (understated sigmas) as an outlier.
    pub warmup_fixes: u32,
    /// While a model mismatch is declared the gate is widened to at least this many times
    /// the window median of NIS/dof, >= 1. The median of chi-square/dof is below the mean
    /// (0.79 of it for 3 dof) and scatters: the median of 10 white 3-dof fixes is below half
    /// their level in 1 window of 10, so 2 x the median reaches the level in 9 of 10.
    pub mismatch_median_factor: f64,
    /// Fixes in the window of the learned GNSS sigma scale (0..=[`MAX_NIS_WINDOW`]; 0 = no
    /// learning, the default; 16 is the tested setting): per fix a covariance-matching sample of true over declared variance, of the
    /// innovation and of the difference of consecutive innovations; the smaller window median
    /// is the scale (the white part of the excess; see `docs/robust-gating.md`).
    pub scale_window: usize,
    /// R is multiplied by the learned scale (a variance ratio) once it reaches this, >= 1.
    pub scale_on: f64,
    /// ... and until it drops below this (in `1..=scale_on`).
    pub scale_off: f64,
    /// Largest R multiplier (variance ratio), >= 1.
    pub max_scale: f64,
}

impl Default for RobustGating {
    /// Down-weighting from the 0.99 quantile; window of 10 fixes; mismatch declared above a
    /// median NIS/dof of 4 (or two rejections in a row), cleared below 1.5; the gate widened to
    /// the median NIS/dof, to twice the last used fix's NIS, and x1.5 per rejection in a run
    /// (at most x100), easing /1.1 per fix, to twice the median while a mismatch is declared;
    /// the gate fully widened for a fix that ends a gap of more than 2.5 fix intervals and
    /// 2 s, and for the first 10 fixes (after the start or a re-initialisation); no process-noise inflation (`max_q_inflation` 1:
    /// it made the outage errors 1.7x worse, see `docs/robust-gating.md`); no learned GNSS
    /// sigma scale (`scale_window` 0: on the undeclared-effect drives it learned the model
    /// mismatch as noise; with `scale_window` 16: R multiplied by the scale from 4, i.e. 2x in
    /// sigma, until it drops below 2, at most 1e4).
    fn default() -> Self {
        Self {
            downweight_nis_pos: chi2::DIM3_P99,
            downweight_nis_pos_vel: chi2::DIM6_P99,
            window: 10,
            mismatch_ratio_on: 4.0,
            mismatch_ratio_off: 1.5,
            inflation_step: 1.5,
            easing_step: 1.1,
            max_q_inflation: 1.0,
            max_gate_widening: 100.0,
            reacquisition_gap_intervals: 2.5,
            reacquisition_min_gap_s: 2.0,
            growth_per_fix: 2.0,
            warmup_fixes: 10,
            mismatch_median_factor: 2.0,
            scale_window: 0,
            scale_on: 4.0,
            scale_off: 2.0,
            max_scale: 1e4,
        }
    }
}

impl RobustGating {
    fn is_valid(&self) -> bool {
        self.downweight_nis_pos > 0.0
            && self.downweight_nis_pos_vel > 0.0
            && (1..=MAX_NIS_WINDOW).contains(&self.window)
            && self.mismatch_ratio_on.is_finite()
            && self.mismatch_ratio_off > 0.0
            && self.mismatch_ratio_off <= self.mismatch_ratio_on
            && self.inflation_step.is_finite()
            && self.inflation_step > 1.0
            && self.easing_step.is_finite()
            && self.easing_step > 1.0
            && self.max_q_inflation.is_finite()
            && self.max_q_inflation >= 1.0
            && self.max_gate_widening.is_finite()
            && self.max_gate_widening >= 1.0
            && self.reacquisition_gap_intervals.is_finite()
            && self.reacquisition_gap_intervals >= 1.0
            && self.reacquisition_min_gap_s >= 0.0
            && self.growth_per_fix.is_finite()
            && self.growth_per_fix >= 1.0
            && self.mismatch_median_factor.is_finite()
            && self.mismatch_median_factor >= 1.0
            && self.scale_window <= MAX_NIS_WINDOW
            && self.scale_off >= 1.0
            && self.scale_on >= self.scale_off
            && self.max_scale.is_finite()
            && self.max_scale >= 1.0
    }
}

impl Gating {
    /// Hard chi-square gate with thresholds at the given probability for dimensions 3 and 6
    /// (no down-weighting, no mismatch monitor).
    pub const fn with_probability(p: GateProbability, max_consecutive_rejections: u32) -> Self {
        let (a, b) = match p {
            GateProbability::P95 => (chi2::DIM3_P95, chi2::DIM6_P95),
            GateProbability::P99 => (chi2::DIM3_P99, chi2::DIM6_P99),
            GateProbability::P999 => (chi2::DIM3_P999, chi2::DIM6_P999),
            GateProbability::P9999 => (chi2::DIM3_P9999, chi2::DIM6_P9999),
        };
        Self {
            nis_threshold_pos: a,
            nis_threshold_pos_vel: b,
            max_consecutive_rejections,
            reset_heading_min_speed_mps: DEFAULT_RESET_HEADING_MIN_SPEED_MPS,
            robust: None,
            velocity: None,
        }
    }

    /// The robust gate: rejection at the P = 0.9999 quantile (widened by the monitor),
    /// IGG-III down-weighting from the 0.99 quantile, the default [`RobustGating`], reset after
    /// 10 consecutive rejections.
    pub fn robust() -> Self {
        Self {
            robust: Some(RobustGating::default()),
            ..Self::with_probability(GateProbability::P9999, 10)
        }
    }

    /// No gating: every valid fix is used.
    pub const fn disabled() -> Self {
        Self {
            nis_threshold_pos: f64::INFINITY,
            nis_threshold_pos_vel: f64::INFINITY,
            max_consecutive_rejections: 0,
            reset_heading_min_speed_mps: DEFAULT_RESET_HEADING_MIN_SPEED_MPS,
            robust: None,
            velocity: None,
        }
    }
}

impl Default for Gating {
    /// The robust gate ([`Gating::robust`]).
    fn default() -> Self {
        Self::robust()
    }
}

/// Errors in a [`FilterConfig`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigError {
    /// Accelerometer noise parameters negative, non-finite or T_B not positive.
    AccelNoise,
    /// Gyro noise parameters negative, non-finite or T_B not positive.
    GyroNoise,
    /// Accelerometer scale-factor parameters invalid.
    AccelScaleFactor,
    /// Gyro scale-factor parameters invalid.
    GyroScaleFactor,
    /// Lever arm not finite.
    LeverArm,
    /// Covariance prediction interval not finite or negative.
    PredictInterval,
    /// Gating thresholds NaN or not positive, or the GNSS time tolerance invalid.
    Gnss,
    /// An effect block's prior or process noise is negative or non-finite, or the reference
    /// temperature is not finite.
    Effects,
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::AccelNoise => {
                "config: accelerometer noise parameters invalid (negative, non-finite or T_B <= 0)"
            }
            Self::GyroNoise => {
                "config: gyro noise parameters invalid (negative, non-finite or T_B <= 0)"
            }
            Self::AccelScaleFactor => "config: accelerometer scale-factor sigma/time invalid",
            Self::GyroScaleFactor => "config: gyro scale-factor sigma/time invalid",
            Self::LeverArm => "config: GNSS lever arm not finite",
            Self::PredictInterval => {
                "config: covariance prediction interval not finite or negative"
            }
            Self::Gnss => "config: GNSS gating thresholds or time tolerance invalid",
            Self::Effects => {
                "config: effect-block prior/process noise invalid (negative or non-finite) or reference temperature not finite"
            }
        })
    }
}

impl core::error::Error for ConfigError {}

/// Everything numeric the filter needs besides the state layout and the initial state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilterConfig {
    /// Accelerometer noise and bias parameters (m/s^2 based units).
    pub accel: SensorNoise,
    /// Gyro noise and bias parameters (rad/s based units).
    pub gyro: SensorNoise,
    /// Accelerometer scale-factor model (used when the layout has the block).
    pub accel_scale: ScaleFactorNoise,
    /// Gyro scale-factor model (used when the layout has the block).
    pub gyro_scale: ScaleFactorNoise,
    /// GNSS antenna position relative to the IMU reference point, body FRD, m.
    pub lever_arm_body_m: [f64; 3],
    /// Use the fix's velocity (6-dimensional update) when it carries one.
    pub use_gnss_velocity: bool,
    /// Innovation gating.
    pub gating: Gating,
    /// The covariance is predicted once this much IMU time has accumulated, s (the transition
    /// matrix is integrated over the interval; 0 = every IMU epoch).
    pub cov_predict_interval_s: f64,
    /// Largest accepted |fix time - filter time|, s; the difference is bridged with the
    /// velocity (call `update_gnss` at the IMU epoch nearest the fix).
    pub max_gnss_time_offset_s: f64,
    /// Priors and process noise of the effect blocks (used when the layout has them).
    pub effects: EffectsConfig,
}

/// Default covariance prediction interval, s (10 Hz; see `docs/derivations/error_state.md`
/// for the cost and accuracy measurements behind it).
pub const DEFAULT_COV_PREDICT_INTERVAL_S: f64 = 0.1;

/// Initial accelerometer bias sigma assumed for the source's models, m/s^2 (100 ug; the
/// source does not state its turn-on bias, this is a tactical-grade servo accelerometer value).
pub const SOURCE_ACCEL_BIAS_INIT_SIGMA_MPS2: f64 = 100.0 * units::UG_MPS2;
/// Initial gyro bias sigma assumed for the source's models, rad/s (0.5 deg/h; the source's
/// FOG bias instability is < 0.1 deg/h, its turn-on bias is not stated).
pub const SOURCE_GYRO_BIAS_INIT_SIGMA_RADPS: f64 = 0.5 * units::DEG / units::HOUR_S;

/// The source's identified accelerometer parameters (Tab. 1): S_N, m^2/s^3.
pub const NBK_ACCEL_S_N: f64 = 6.2865e-9;
/// The source's identified accelerometer Gauss-Markov PSD S_B, m^2/s^5.
pub const NBK_ACCEL_S_B: f64 = 2.4360e-11;
/// The source's identified accelerometer Gauss-Markov correlation time T_B, s.
pub const NBK_ACCEL_T_B_S: f64 = 45.0;
/// The source's identified accelerometer random-walk PSD S_K, m^2/s^5.
pub const NBK_ACCEL_S_K: f64 = 2.6731e-12;
/// The source's identified gyro white noise S_N, rad^2/s.
pub const NBK_GYRO_S_N: f64 = 5.3079e-10;

impl FilterConfig {
    /// Defaults for everything that is not a noise parameter: no lever arm, position-only
    /// updates, default gating, 10 Hz covariance prediction, 50 ms GNSS time tolerance,
    /// scale factors of 1000 ppm with a 1 h correlation time, and the default effect priors
    /// ([`EffectsConfig::default`]).
    pub fn with_noise(accel: SensorNoise, gyro: SensorNoise) -> Self {
        Self {
            accel,
            gyro,
            accel_scale: ScaleFactorNoise::from_ppm(1000.0, 3600.0),
            gyro_scale: ScaleFactorNoise::from_ppm(1000.0, 3600.0),
            lever_arm_body_m: [0.0; 3],
            use_gnss_velocity: false,
            gating: Gating::default(),
            cov_predict_interval_s: DEFAULT_COV_PREDICT_INTERVAL_S,
            max_gnss_time_offset_s: 0.05,
            effects: EffectsConfig::default(),
        }
    }

    /// The source's classical N model: manufacturer white-noise specification (accelerometer
    /// 50 ug/sqrt(Hz), gyro 0.15 deg/sqrt(h)), constant biases with the initial sigmas
    /// [`SOURCE_ACCEL_BIAS_INIT_SIGMA_MPS2`] and [`SOURCE_GYRO_BIAS_INIT_SIGMA_RADPS`].
    /// Use with [`crate::model::LAYOUT_N`].
    pub fn source_n_model() -> Self {
        Self::with_noise(
            SensorNoise::isotropic(
                units::accel_psd_from_ug_per_sqrt_hz(50.0),
                0.0,
                NBK_ACCEL_T_B_S,
                0.0,
                SOURCE_ACCEL_BIAS_INIT_SIGMA_MPS2,
            ),
            SensorNoise::isotropic(
                units::gyro_psd_from_deg_per_sqrt_h(0.15),
                0.0,
                NBK_ACCEL_T_B_S,
                0.0,
                SOURCE_GYRO_BIAS_INIT_SIGMA_RADPS,
            ),
        )
    }

    /// The source's detailed NBK model with its identified parameters: accelerometer
    /// S_N = 6.2865e-9 m^2/s^3, S_B = 2.4360e-11 m^2/s^5, T_B = 45 s, S_K = 2.6731e-12 m^2/s^5;
    /// gyro S_N = 5.3079e-10 rad^2/s with constant biases. Use with
    /// [`crate::model::LAYOUT_NBK`] (separate Gauss-Markov and random-walk states) or
    /// [`crate::model::LAYOUT_NBK_SINGLE`] (the source's single decaying state).
    pub fn source_nbk_model() -> Self {
        Self::with_noise(
            SensorNoise::isotropic(
                NBK_ACCEL_S_N,
                NBK_ACCEL_S_B,
                NBK_ACCEL_T_B_S,
                NBK_ACCEL_S_K,
                SOURCE_ACCEL_BIAS_INIT_SIGMA_MPS2,
            ),
            SensorNoise::isotropic(
                NBK_GYRO_S_N,
                0.0,
                NBK_ACCEL_T_B_S,
                0.0,
                SOURCE_GYRO_BIAS_INIT_SIGMA_RADPS,
            ),
        )
    }

    /// Checks every parameter (finite, non-negative, positive times).
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !self.accel.is_valid() {
            return Err(ConfigError::AccelNoise);
        }
        if !self.gyro.is_valid() {
            return Err(ConfigError::GyroNoise);
        }
        if !self.accel_scale.is_valid() {
            return Err(ConfigError::AccelScaleFactor);
        }
        if !self.gyro_scale.is_valid() {
            return Err(ConfigError::GyroScaleFactor);
        }
        if !self.lever_arm_body_m.iter().all(|v| v.is_finite()) {
            return Err(ConfigError::LeverArm);
        }
        if !(self.cov_predict_interval_s.is_finite() && self.cov_predict_interval_s >= 0.0) {
            return Err(ConfigError::PredictInterval);
        }
        let g = &self.gating;
        if !(g.nis_threshold_pos > 0.0
            && g.nis_threshold_pos_vel > 0.0
            && g.robust.is_none_or(|r| r.is_valid())
            && g.velocity.is_none_or(|v| v.is_valid())
            && !g.reset_heading_min_speed_mps.is_nan()
            && g.reset_heading_min_speed_mps >= 0.0
            && self.max_gnss_time_offset_s.is_finite()
            && self.max_gnss_time_offset_s >= 0.0)
        {
            return Err(ConfigError::Gnss);
        }
        if !self.effects.is_valid() {
            return Err(ConfigError::Effects);
        }
        Ok(())
    }
}

/// IMU noise as a KF-GINS configuration file states it (`imunoise` section), in its units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KfGinsImuNoise {
    /// Angle random walk, deg/sqrt(h).
    pub arw_deg_per_sqrt_h: [f64; 3],
    /// Velocity random walk, m/s/sqrt(h).
    pub vrw_mps_per_sqrt_h: [f64; 3],
    /// Gyro bias (Gauss-Markov) sigma, deg/h.
    pub gbstd_deg_per_h: [f64; 3],
    /// Accelerometer bias (Gauss-Markov) sigma, mGal.
    pub abstd_mgal: [f64; 3],
    /// Gyro scale-factor sigma, ppm.
    pub gsstd_ppm: [f64; 3],
    /// Accelerometer scale-factor sigma, ppm.
    pub asstd_ppm: [f64; 3],
    /// Correlation time of all Gauss-Markov states, h.
    pub corrtime_h: f64,
}

impl FilterConfig {
    /// The equivalent configuration of a KF-GINS `imunoise` section, for
    /// [`crate::model::LAYOUT_KF_GINS`] (Gauss-Markov gyro and accelerometer biases and scale
    /// factors with one correlation time; KF-GINS's continuous noise `2 sigma^2 / T`, i.e.
    /// S_B = 2 sigma^2 / T). The biases start at their stationary sigma (KF-GINS's default when
    /// no separate initial std is given), so `bias_init_sigma` is 0 here.
    pub fn from_kf_gins(n: &KfGinsImuNoise) -> Self {
        let t = n.corrtime_h * units::HOUR_S;
        let gyro = SensorNoise {
            s_n: n
                .arw_deg_per_sqrt_h
                .map(units::gyro_psd_from_deg_per_sqrt_h),
            s_b: n
                .gbstd_deg_per_h
                .map(|x| units::gm_psd_from_sigma(units::radps_from_deg_per_h(x), t)),
            t_b_s: t,
            s_k: [0.0; 3],
            bias_init_sigma: [0.0; 3],
        };
        let accel = SensorNoise {
            s_n: n
                .vrw_mps_per_sqrt_h
                .map(units::accel_psd_from_mps_per_sqrt_h),
            s_b: n
                .abstd_mgal
                .map(|x| units::gm_psd_from_sigma(units::mps2_from_mgal(x), t)),
            t_b_s: t,
            s_k: [0.0; 3],
            bias_init_sigma: [0.0; 3],
        };
        let mut c = Self::with_noise(accel, gyro);
        c.accel_scale = ScaleFactorNoise {
            sigma: n.asstd_ppm.map(units::from_ppm),
            t_s: t,
        };
        c.gyro_scale = ScaleFactorNoise {
            sigma: n.gsstd_ppm.map(units::from_ppm),
            t_s: t,
        };
        c
    }
}

#[cfg(test)]
mod tests;
