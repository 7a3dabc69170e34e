//! The error-state model: which error states the filter carries (a [`Layout`] of [`Block`]s,
//! fixed at compile time), their continuous dynamics F, noise, IMU correction, measurement
//! Jacobian columns and error feedback, and the discretisation ([`discrete`]).
//!
//! # Conventions
//!
//! Every error state is *estimate minus truth*: `dx = x_hat - x`. The attitude error is the
//! phi angle in NED, `C_hat = (I - [phi x]) C` (so `C = (I + [phi x]) C_hat`); the position
//! error is in metres along north, east and down. Closed-loop feedback therefore subtracts the
//! estimated error from every state (`x <- x_hat - dx`; attitude `q <- q(phi) q_hat`) and resets
//! the error state to zero. Derivations: `docs/derivations/error_state.md`.
//!
//! # The state vector
//!
//! `[ phi (3) | dv_ned (3) | dr_ned (3) | block 1 | block 2 | ... ]`: the 9-state
//! [`Block::Core`] comes first, then the sensor-error blocks in layout order. Every non-core
//! state has a *diagonal* self-transition (random constant, random walk or first-order
//! Gauss-Markov) and couples only into the core rows, so the transition matrix has dense core
//! rows and a diagonal below (see [`discrete::Transition`]): that is the sparsity the
//! covariance prediction exploits.
//!
//! # Adding a block (issue 7's effects)
//!
//! Add a variant to [`Block`] (and [`BlockKind`]) and fill its arm in each `match` below:
//! dimension ([`Block::dim`]), per-epoch F coupling into the core ([`Block::accumulate_f`],
//! from the [`Regressors`]), self-dynamics and exact discrete noise ([`Block::discretize`]),
//! initial variance ([`Block::initial_variance`]), IMU correction before mechanisation
//! ([`Block::add_correction`]), GNSS measurement Jacobian columns ([`Block::gnss_jacobian`]) and
//! feedback ([`Block::feedback`]). Nothing else in the filter changes.
//!
//! # Effect blocks
//!
//! Besides the biases and scale factors, the optional *effect* blocks model what a residual
//! analysis may find missing (their [`Block::name`]s are the vocabulary of `host-sim
//! diagnose`): [`Block::AccelMisalignment`], [`Block::GyroMisalignment`], [`Block::LeverArm`],
//! [`Block::TimeOffset`], [`Block::AccelTemperatureBias`], [`Block::GyroTemperatureBias`] and
//! [`Block::GyroGSensitivity`]. Add any subset to a base layout at compile time:
//!
//! ```
//! use nav_core::model::{Block, LAYOUT_NBK};
//! const L: nav_core::model::Layout = LAYOUT_NBK.with(Block::LeverArm).with(Block::TimeOffset);
//! assert_eq!(L.dim(), 18 + 3 + 1);
//! ```
//!
//! The full IMU sensor model the correction inverts (per sample, body FRD):
//!
//! ```text
//! w_meas = (I + diag(s_g) + M_g) w + b_g + diag(g_s) f + k_g (T - T_ref) + n_g
//! f_meas = (I + diag(s_a) + M_a) f + b_a              + k_a (T - T_ref) + n_a
//! ```
//!
//! with `M = [[0, m_xy, m_xz], [m_yx, 0, m_yz], [m_zx, m_zy, 0]]` (6 small angles per triad).

pub mod core_f;
pub mod discrete;
pub mod effects;

use crate::config::{EffectNoise, FilterConfig, SensorNoise};
use crate::scalar::Scalar;

/// Dimension of the core error state (attitude, velocity, position).
pub const CORE_DIM: usize = 9;
/// Index of the attitude error phi (N, E, D), rad.
pub const IDX_ATT: usize = 0;
/// Index of the NED velocity error, m/s.
pub const IDX_VEL: usize = 3;
/// Index of the NED position error, m.
pub const IDX_POS: usize = 6;
/// Largest number of blocks in a layout (the 5 blocks of the KF-GINS layout plus all 7
/// effect blocks fit with room to spare).
pub const MAX_BLOCKS: usize = 16;
/// Largest dimension of one block (the core's 9).
pub const MAX_BLOCK_DIM: usize = CORE_DIM;

/// How a sensor bias triad evolves. Parameters come from the [`SensorNoise`] of the sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BiasModel {
    /// 3 states, `b' = w_K`: a random constant (the source's N model, S_K = 0) or a random
    /// walk with PSD S_K. Initial sigma `bias_init_sigma`.
    Constant,
    /// 3 states, first-order Gauss-Markov `b' = -b/T_B + w_B` (KF-GINS). Initial variance
    /// `S_B T_B / 2 + bias_init_sigma^2`.
    GaussMarkov,
    /// 6 states `[b_GM, b_RW]`, bias = b_GM + b_RW: Gauss-Markov (decay 1/T_B, PSD S_B)
    /// plus a separate random walk (PSD S_K) that does not decay (DESIGN.md's exact NBK model).
    /// b_GM starts at its stationary variance, b_RW at `bias_init_sigma^2`.
    GaussMarkovRandomWalk,
    /// 3 states, the source's detailed model: both S_B and S_K drive one state decaying with
    /// 1/T_B (an approximation: the random walk is made to decay). Initial variance
    /// `S_B T_B / 2 + bias_init_sigma^2`.
    SingleStateGmRw,
}

impl BiasModel {
    /// Number of error states.
    pub const fn dim(self) -> usize {
        match self {
            Self::GaussMarkovRandomWalk => 6,
            Self::Constant | Self::GaussMarkov | Self::SingleStateGmRw => 3,
        }
    }
}

/// One group of error states.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Block {
    /// Attitude (phi, rad), NED velocity (m/s) and NED position (m) errors: 9 states, first.
    Core,
    /// Gyro bias, rad/s.
    GyroBias(BiasModel),
    /// Accelerometer bias, m/s^2.
    AccelBias(BiasModel),
    /// Gyro scale-factor error (dimensionless, Gauss-Markov): measured = (1 + s) true + b.
    GyroScaleFactor,
    /// Accelerometer scale-factor error (dimensionless, Gauss-Markov).
    AccelScaleFactor,
    /// `accel_misalignment`: 6 states, the off-diagonal elements of the accelerometer triad's
    /// sensor matrix `I + diag(s) + M`, rad (dimensionless small angles), in the order
    /// `[m_xy, m_xz, m_yx, m_yz, m_zx, m_zy]`: `m_ij` is the fraction of the specific force
    /// along body axis j that accelerometer i senses (axis non-orthogonality *and* a rotation
    /// of the triad relative to the body frame; the body frame is the gyro triad's). A pure
    /// common rotation of both triads is an attitude offset and unobservable when both
    /// misalignment blocks are present. Random constant / slow random walk.
    AccelMisalignment,
    /// `gyro_misalignment`: 6 states, the off-diagonal elements of the gyro triad's sensor
    /// matrix, rad, same order and meaning as [`Block::AccelMisalignment`] (`m_ij`: fraction of
    /// the body rate about axis j that gyro i senses).
    GyroMisalignment,
    /// `lever_arm`: 3 states, the correction to the configured GNSS antenna lever arm
    /// (`FilterConfig::lever_arm_body_m`), body FRD, m: the antenna is at
    /// `configured + estimate` from the IMU reference point. Enters the GNSS position and
    /// velocity measurement columns only.
    LeverArm,
    /// `time_offset`: 1 state, the IMU-GNSS time offset `dt`, s: the GNSS fix time-tagged
    /// `t_fix` is the antenna position (and velocity) at IMU time `t_fix + dt` (positive: the
    /// fix is `dt` newer than its tag says). Measurement columns: antenna velocity (position
    /// update) and acceleration (velocity update). Keep `max_gnss_time_offset_s` above the
    /// offsets to be bridged.
    TimeOffset,
    /// `accel_temperature_bias`: 3 states, the accelerometer bias temperature coefficient
    /// `k_a`, m/s^2/degC: bias = `k_a (T - T_ref)` with T the IMU sample's temperature
    /// (`ImuSample::temperature_c`) and T_ref from `EffectsConfig::temperature_ref_c` or the
    /// first temperature; zero regressor when the sample has no temperature.
    AccelTemperatureBias,
    /// `gyro_temperature_bias`: 3 states, the gyro bias temperature coefficient `k_g`,
    /// rad/s/degC (as [`Block::AccelTemperatureBias`]).
    GyroTemperatureBias,
    /// `gyro_g_sensitivity`: 3 states, the diagonal g-dependent gyro bias `g_s`, rad/s per
    /// m/s^2: gyro i senses `g_s[i] f_i` (f the specific force). The off-diagonal terms are not
    /// modelled: on a land vehicle they are driven almost only by gravity (f ~ (0, 0, -g)),
    /// i.e. they act as a constant gyro bias and are absorbed by the gyro-bias states.
    GyroGSensitivity,
}

/// What a block estimates, independent of its model (for accessors).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BlockKind {
    /// [`Block::Core`].
    Core,
    /// [`Block::GyroBias`].
    GyroBias,
    /// [`Block::AccelBias`].
    AccelBias,
    /// [`Block::GyroScaleFactor`].
    GyroScaleFactor,
    /// [`Block::AccelScaleFactor`].
    AccelScaleFactor,
    /// [`Block::AccelMisalignment`].
    AccelMisalignment,
    /// [`Block::GyroMisalignment`].
    GyroMisalignment,
    /// [`Block::LeverArm`].
    LeverArm,
    /// [`Block::TimeOffset`].
    TimeOffset,
    /// [`Block::AccelTemperatureBias`].
    AccelTemperatureBias,
    /// [`Block::GyroTemperatureBias`].
    GyroTemperatureBias,
    /// [`Block::GyroGSensitivity`].
    GyroGSensitivity,
}

/// Every effect block (issue 7's vocabulary), in the order of their names in the
/// documentation: scale factors, misalignments, lever arm, time offset, temperature
/// coefficients, g-sensitivity.
pub const EFFECT_BLOCKS: [Block; 9] = [
    Block::AccelScaleFactor,
    Block::GyroScaleFactor,
    Block::AccelMisalignment,
    Block::GyroMisalignment,
    Block::LeverArm,
    Block::TimeOffset,
    Block::AccelTemperatureBias,
    Block::GyroTemperatureBias,
    Block::GyroGSensitivity,
];

impl Block {
    /// Number of error states of the block.
    pub const fn dim(self) -> usize {
        match self {
            Self::Core => CORE_DIM,
            Self::GyroBias(m) | Self::AccelBias(m) => m.dim(),
            Self::GyroScaleFactor
            | Self::AccelScaleFactor
            | Self::LeverArm
            | Self::AccelTemperatureBias
            | Self::GyroTemperatureBias
            | Self::GyroGSensitivity => 3,
            Self::AccelMisalignment | Self::GyroMisalignment => 6,
            Self::TimeOffset => 1,
        }
    }

    /// The block's kind.
    pub const fn kind(self) -> BlockKind {
        match self {
            Self::Core => BlockKind::Core,
            Self::GyroBias(_) => BlockKind::GyroBias,
            Self::AccelBias(_) => BlockKind::AccelBias,
            Self::GyroScaleFactor => BlockKind::GyroScaleFactor,
            Self::AccelScaleFactor => BlockKind::AccelScaleFactor,
            Self::AccelMisalignment => BlockKind::AccelMisalignment,
            Self::GyroMisalignment => BlockKind::GyroMisalignment,
            Self::LeverArm => BlockKind::LeverArm,
            Self::TimeOffset => BlockKind::TimeOffset,
            Self::AccelTemperatureBias => BlockKind::AccelTemperatureBias,
            Self::GyroTemperatureBias => BlockKind::GyroTemperatureBias,
            Self::GyroGSensitivity => BlockKind::GyroGSensitivity,
        }
    }

    /// Short name (the vocabulary of reports).
    pub const fn name(self) -> &'static str {
        match self {
            Self::Core => "core",
            Self::GyroBias(_) => "gyro_bias",
            Self::AccelBias(_) => "accel_bias",
            Self::GyroScaleFactor => "gyro_scale_factor",
            Self::AccelScaleFactor => "accel_scale_factor",
            Self::AccelMisalignment => "accel_misalignment",
            Self::GyroMisalignment => "gyro_misalignment",
            Self::LeverArm => "lever_arm",
            Self::TimeOffset => "time_offset",
            Self::AccelTemperatureBias => "accel_temperature_bias",
            Self::GyroTemperatureBias => "gyro_temperature_bias",
            Self::GyroGSensitivity => "gyro_g_sensitivity",
        }
    }

    /// The block whose [`Block::name`] is `name` among the effect blocks ([`EFFECT_BLOCKS`]),
    /// if any.
    pub fn effect_from_name(name: &str) -> Option<Self> {
        EFFECT_BLOCKS.iter().copied().find(|b| b.name() == name)
    }

    /// The SI unit of the block's states (for reports).
    pub const fn unit(self) -> &'static str {
        match self {
            Self::Core => "rad, m/s, m",
            Self::GyroBias(_) => "rad/s",
            Self::AccelBias(_) => "m/s^2",
            Self::GyroScaleFactor | Self::AccelScaleFactor => "1",
            Self::AccelMisalignment | Self::GyroMisalignment => "rad",
            Self::LeverArm => "m",
            Self::TimeOffset => "s",
            Self::AccelTemperatureBias => "m/s^2/degC",
            Self::GyroTemperatureBias => "rad/s/degC",
            Self::GyroGSensitivity => "rad/s/(m/s^2)",
        }
    }

    /// The effect block's prior/process noise in `cfg`, if the block is an effect block with
    /// an [`EffectNoise`] (the scale factors have their own Gauss-Markov parameters).
    pub fn effect_noise(self, cfg: &FilterConfig) -> Option<EffectNoise> {
        let e = &cfg.effects;
        match self {
            Self::AccelMisalignment => Some(e.accel_misalignment),
            Self::GyroMisalignment => Some(e.gyro_misalignment),
            Self::LeverArm => Some(e.lever_arm),
            Self::TimeOffset => Some(e.time_offset),
            Self::AccelTemperatureBias => Some(e.accel_temperature),
            Self::GyroTemperatureBias => Some(e.gyro_temperature),
            Self::GyroGSensitivity => Some(e.gyro_g_sensitivity),
            Self::Core
            | Self::GyroBias(_)
            | Self::AccelBias(_)
            | Self::GyroScaleFactor
            | Self::AccelScaleFactor => None,
        }
    }

    /// Adds the block's coupling into the core rows, integrated over one IMU epoch
    /// (`F[core, block] * dt`), to `f_top` (the 9 core rows of the accumulated F dt) at
    /// column `off`. Signs follow dx = estimate - truth: a gyro error dw = w_hat - w drives
    /// `phi' = ... - C dw`, an accelerometer error df drives `dv' = ... + C df`.
    pub fn accumulate_f<T: Scalar, const N: usize>(
        self,
        off: usize,
        reg: &Regressors<T>,
        f_top: &mut [[T; N]; CORE_DIM],
    ) {
        let c_dt = scale3(&reg.c_nb, reg.dt);
        match self {
            Self::Core => {}
            // gyro bias error db: w_hat = w - db  =>  phi' += C db
            Self::GyroBias(m) => {
                for g in 0..m.dim() / 3 {
                    add3(f_top, IDX_ATT, off + 3 * g, &c_dt);
                }
            }
            // accel bias error db: f_hat = f - db  =>  dv' -= C db
            Self::AccelBias(m) => {
                let neg = scale3(&c_dt, -T::ONE);
                for g in 0..m.dim() / 3 {
                    add3(f_top, IDX_VEL, off + 3 * g, &neg);
                }
            }
            // gyro scale error ds: w_hat = w - diag(w) ds  =>  phi' += C diag(w) ds
            Self::GyroScaleFactor => {
                add3(f_top, IDX_ATT, off, &mul_diag3(&c_dt, &reg.omega_b));
            }
            // accel scale error ds: f_hat = f - diag(f) ds  =>  dv' -= C diag(f) ds
            Self::AccelScaleFactor => {
                let m = mul_diag3(&c_dt, &reg.f_b);
                add3(f_top, IDX_VEL, off, &scale3(&m, -T::ONE));
            }
            // gyro misalignment dm: w_hat = w - J(w) dm  =>  phi' += C J(w) dm
            Self::GyroMisalignment => {
                effects::add_block(f_top, IDX_ATT, off, &effects::c_mis(&c_dt, &reg.omega_b));
            }
            // accel misalignment dm: f_hat = f - J(f) dm  =>  dv' -= C J(f) dm
            Self::AccelMisalignment => {
                let neg = scale3(&c_dt, -T::ONE);
                effects::add_block(f_top, IDX_VEL, off, &effects::c_mis(&neg, &reg.f_b));
            }
            // gyro temperature coefficient dk: w_hat = w - dT dk  =>  phi' += C dT dk
            Self::GyroTemperatureBias => {
                let d_t = effects::temperature_regressor(reg.temperature_c);
                if d_t != T::ZERO {
                    add3(f_top, IDX_ATT, off, &scale3(&c_dt, d_t));
                }
            }
            // accel temperature coefficient dk: f_hat = f - dT dk  =>  dv' -= C dT dk
            Self::AccelTemperatureBias => {
                let d_t = effects::temperature_regressor(reg.temperature_c);
                if d_t != T::ZERO {
                    add3(f_top, IDX_VEL, off, &scale3(&c_dt, -d_t));
                }
            }
            // gyro g-sensitivity dg: w_hat = w - diag(f) dg  =>  phi' += C diag(f) dg
            Self::GyroGSensitivity => {
                add3(f_top, IDX_ATT, off, &mul_diag3(&c_dt, &reg.f_b));
            }
            // measurement-only blocks
            Self::LeverArm | Self::TimeOffset => {}
        }
    }

    /// The block's self-dynamics over an interval of `dt_s` seconds, per state: the continuous
    /// decay rate times dt (`F_ii dt`, 0 or -dt/T), the exact transition `e^(F_ii dt)` and the
    /// exact discrete driving-noise variance (DESIGN.md: `Q_GM = (S_B T_B / 2)(1 - Phi^2)`,
    /// `Q_RW = S_K dt`), in the covariance scalar type. Writes `dim()` entries into each slice
    /// (the core writes nothing: its white noise is added in [`discrete`]).
    pub fn discretize<T: Scalar>(
        self,
        cfg: &FilterConfig,
        dt_s: T,
        f_dt: &mut [T],
        phi: &mut [T],
        q: &mut [T],
    ) {
        let mut w = DiagWriter { f_dt, phi, q, n: 0 };
        match self {
            Self::Core => {}
            Self::GyroBias(m) => bias_discrete(m, &cfg.gyro, dt_s, &mut w),
            Self::AccelBias(m) => bias_discrete(m, &cfg.accel, dt_s, &mut w),
            Self::GyroScaleFactor => {
                let d = gm_decay(dt_s, T::of_f64(cfg.gyro_scale.t_s));
                for s in cfg.gyro_scale.sigma {
                    w.gauss_markov(T::of_f64(s * s), &d);
                }
            }
            Self::AccelScaleFactor => {
                let d = gm_decay(dt_s, T::of_f64(cfg.accel_scale.t_s));
                for s in cfg.accel_scale.sigma {
                    w.gauss_markov(T::of_f64(s * s), &d);
                }
            }
            other => {
                if let Some(e) = other.effect_noise(cfg) {
                    let psd = T::of_f64(e.rw_psd);
                    for _ in 0..other.dim() {
                        w.random_walk(psd, dt_s);
                    }
                }
            }
        }
    }

    /// Initial variance of each state (the core's comes from the initial uncertainty).
    pub fn initial_variance(self, cfg: &FilterConfig, out: &mut [f64]) {
        let mut it = out.iter_mut();
        let mut put = |v: f64| {
            if let Some(o) = it.next() {
                *o = v;
            }
        };
        let bias = |m: BiasModel, n: &SensorNoise, put: &mut dyn FnMut(f64)| {
            let gm = |i: usize| {
                let s_b = n.s_b.get(i).copied().unwrap_or(0.0);
                0.5 * s_b * n.t_b_s
            };
            let init = |i: usize| {
                let s = n.bias_init_sigma.get(i).copied().unwrap_or(0.0);
                s * s
            };
            match m {
                BiasModel::Constant => (0..3).for_each(|i| put(init(i))),
                BiasModel::GaussMarkov | BiasModel::SingleStateGmRw => {
                    (0..3).for_each(|i| put(gm(i) + init(i)))
                }
                BiasModel::GaussMarkovRandomWalk => {
                    (0..3).for_each(|i| put(gm(i)));
                    (0..3).for_each(|i| put(init(i)));
                }
            }
        };
        match self {
            Self::Core => {}
            Self::GyroBias(m) => bias(m, &cfg.gyro, &mut put),
            Self::AccelBias(m) => bias(m, &cfg.accel, &mut put),
            Self::GyroScaleFactor => cfg.gyro_scale.sigma.iter().for_each(|s| put(s * s)),
            Self::AccelScaleFactor => cfg.accel_scale.sigma.iter().for_each(|s| put(s * s)),
            other => {
                if let Some(e) = other.effect_noise(cfg) {
                    (0..other.dim()).for_each(|_| put(e.init_sigma * e.init_sigma));
                }
            }
        }
    }

    /// Adds the block's current estimate `est` (its `dim()` entries of the sensor-error
    /// estimate vector) to the IMU correction applied before mechanisation.
    pub fn add_correction(self, est: &[f64], corr: &mut ImuCorrection) {
        let add = |acc: &mut [f64; 3], est: &[f64]| {
            for chunk in est.chunks_exact(3) {
                for (a, e) in acc.iter_mut().zip(chunk) {
                    *a += *e;
                }
            }
        };
        match self {
            Self::Core => {}
            Self::GyroBias(_) => add(&mut corr.gyro_bias_radps, est),
            Self::AccelBias(_) => add(&mut corr.accel_bias_mps2, est),
            Self::GyroScaleFactor => add(&mut corr.gyro_scale, est),
            Self::AccelScaleFactor => add(&mut corr.accel_scale, est),
            Self::AccelTemperatureBias => add(&mut corr.accel_temp_coeff_mps2_per_c, est),
            Self::GyroTemperatureBias => add(&mut corr.gyro_temp_coeff_radps_per_c, est),
            Self::GyroGSensitivity => add(&mut corr.gyro_g_sensitivity_radps_per_mps2, est),
            Self::AccelMisalignment => {
                for (a, e) in corr.accel_misalignment_rad.iter_mut().zip(est) {
                    *a += *e;
                }
            }
            Self::GyroMisalignment => {
                for (a, e) in corr.gyro_misalignment_rad.iter_mut().zip(est) {
                    *a += *e;
                }
            }
            Self::LeverArm | Self::TimeOffset => {}
        }
    }

    /// Which per-axis IMU quantity (x, y, z; the sum over the block's 3-state groups) the
    /// block estimates, if any: biases, scale factors, temperature coefficients and
    /// g-sensitivity. None for the core, the 6-state misalignments and the measurement blocks
    /// (read those with `Filter::block_value`).
    pub const fn quantity(self) -> Option<BlockKind> {
        match self {
            Self::Core
            | Self::AccelMisalignment
            | Self::GyroMisalignment
            | Self::LeverArm
            | Self::TimeOffset => None,
            other => Some(other.kind()),
        }
    }

    /// Adds the block's columns (at `off`) of the GNSS measurement Jacobians: `h_pos` (antenna
    /// position, 3 rows) and `h_vel` (antenna velocity, 3 rows). Measurement = predicted -
    /// measured, so `z = H dx + noise` with dx = estimate - truth.
    pub fn gnss_jacobian<T: Scalar, const N: usize>(
        self,
        off: usize,
        ctx: &MeasContext,
        h_pos: &mut [[T; N]; 3],
        h_vel: &mut [[T; N]; 3],
    ) {
        match self {
            Self::Core => {
                // p_ant = r + C l: dz = dr + [(C l) x] phi
                set3(h_pos, 0, off + IDX_ATT, &to_t(&skew(&ctx.c_l)));
                set3(h_pos, 0, off + IDX_POS, &to_t(&IDENTITY3));
                // v_ant = v + C (w x l) - w_in x (C l): dz = dv + [(C (w x l)) x] phi
                //   + C [l x] dw_gyro (w_in x terms neglected, < 1e-4 of the rest)
                set3(h_vel, 0, off + IDX_ATT, &to_t(&skew(&ctx.c_w_x_l)));
                set3(h_vel, 0, off + IDX_VEL, &to_t(&IDENTITY3));
            }
            // dw = -db  =>  dz_vel = -C [l x] db ... sign: C (dw x l) = -C [l x] dw = C [l x] db
            Self::GyroBias(m) => {
                for g in 0..m.dim() / 3 {
                    set3(h_vel, 0, off + 3 * g, &to_t(&ctx.c_lx));
                }
            }
            // dw = -diag(w) ds  =>  dz_vel = C [l x] diag(w) ds
            Self::GyroScaleFactor => {
                set3(
                    h_vel,
                    0,
                    off,
                    &to_t(&mul_diag3(&ctx.c_lx, &ctx.omega_b_radps)),
                );
            }
            // dw = -J(w) dm  =>  dz_vel = C [l x] J(w) dm
            Self::GyroMisalignment => {
                let m = effects::c_mis(&ctx.c_lx, &ctx.omega_b_radps);
                effects::set_block(h_vel, 0, off, &m.map(|r| r.map(T::of_f64)));
            }
            // dw = -dT dk  =>  dz_vel = C [l x] dT dk
            Self::GyroTemperatureBias => {
                let d_t = effects::temperature_regressor(ctx.temperature_offset_c);
                set3(h_vel, 0, off, &to_t(&scale3(&ctx.c_lx, d_t)));
            }
            // dw = -diag(f) dg  =>  dz_vel = C [l x] diag(f) dg
            Self::GyroGSensitivity => {
                set3(h_vel, 0, off, &to_t(&mul_diag3(&ctx.c_lx, &ctx.f_b_mps2)));
            }
            // p_ant = r + C (l + dl) (+ v_ant bridge): dz_pos = (C + bridge C [w x]) dl;
            // v_ant = v + C (w x (l + dl)) - w_in x (C (l + dl)): dz_vel = (C [w x] - [w_in x] C) dl
            Self::LeverArm => {
                let c_wx = effects::mul3(&ctx.c_nb, &skew(&ctx.omega_b_radps));
                let mut hp = ctx.c_nb;
                for (r, w) in hp.iter_mut().zip(&c_wx) {
                    for (a, b) in r.iter_mut().zip(w) {
                        *a += ctx.lever_bridge_s * *b;
                    }
                }
                set3(h_pos, 0, off, &to_t(&hp));
                let win_c = effects::mul3(&skew(&ctx.w_in_ned_radps), &ctx.c_nb);
                let mut hv = c_wx;
                for (r, w) in hv.iter_mut().zip(&win_c) {
                    for (a, b) in r.iter_mut().zip(w) {
                        *a -= *b;
                    }
                }
                set3(h_vel, 0, off, &to_t(&hv));
            }
            // predicted antenna at t_fix + dt_hat: dz_pos = v_ant d(dt), dz_vel = a d(dt); the
            // bridge tau = t_fix + dt_hat - t also multiplies the velocity error, and the
            // bridge's attitude dependence adds tau [(C (w x l)) x] + tau^2/2 [f_n x] (position)
            // and tau [f_n x] (velocity) to the phi columns
            Self::TimeOffset => {
                let t = ctx.bridge_s;
                let f_x = skew(&ctx.f_ned_mps2);
                let mut hp = skew(&ctx.c_w_x_l);
                let mut hv = f_x;
                for ((p_row, v_row), f_row) in hp.iter_mut().zip(hv.iter_mut()).zip(&f_x) {
                    for ((p, v), f) in p_row.iter_mut().zip(v_row.iter_mut()).zip(f_row) {
                        *p = t * *p + 0.5 * t * t * *f;
                        *v = t * *f;
                    }
                }
                add3(h_pos, 0, IDX_ATT, &to_t(&hp));
                add3(h_vel, 0, IDX_ATT, &to_t(&hv));
                for (k, row) in h_pos.iter_mut().enumerate() {
                    if let Some(x) = row.get_mut(off) {
                        *x = T::of_f64(ctx.v_ant_ned_mps.get(k).copied().unwrap_or(0.0));
                    }
                    if let Some(x) = row.get_mut(IDX_VEL + k) {
                        *x = T::of_f64(ctx.bridge_s);
                    }
                }
                for (k, row) in h_vel.iter_mut().enumerate() {
                    if let Some(x) = row.get_mut(off) {
                        *x = T::of_f64(ctx.acc_ned_mps2.get(k).copied().unwrap_or(0.0));
                    }
                }
            }
            Self::AccelBias(_)
            | Self::AccelScaleFactor
            | Self::AccelMisalignment
            | Self::AccelTemperatureBias => {}
        }
    }

    /// Closed-loop feedback of the block's estimated error `dx` into its estimate `est`
    /// (both `dim()` long): `est <- est - dx` for additive sensor errors.
    pub fn feedback(self, est: &mut [f64], dx: &[f64]) {
        match self {
            Self::Core => {}
            // every sensor-error and effect state is additive: x_hat <- x_hat - dx
            Self::GyroBias(_)
            | Self::AccelBias(_)
            | Self::GyroScaleFactor
            | Self::AccelScaleFactor
            | Self::AccelMisalignment
            | Self::GyroMisalignment
            | Self::LeverArm
            | Self::TimeOffset
            | Self::AccelTemperatureBias
            | Self::GyroTemperatureBias
            | Self::GyroGSensitivity => {
                for (e, d) in est.iter_mut().zip(dx) {
                    *e -= *d;
                }
            }
        }
    }
}

fn bias_discrete<T: Scalar>(m: BiasModel, n: &SensorNoise, dt_s: T, w: &mut DiagWriter<'_, T>) {
    let t_b = T::of_f64(n.t_b_s);
    let half_t = 0.5 * n.t_b_s;
    match m {
        BiasModel::Constant => n
            .s_k
            .iter()
            .for_each(|s| w.random_walk(T::of_f64(*s), dt_s)),
        BiasModel::GaussMarkov => {
            let d = gm_decay(dt_s, t_b);
            n.s_b
                .iter()
                .for_each(|s| w.gauss_markov(T::of_f64(s * half_t), &d));
        }
        BiasModel::GaussMarkovRandomWalk => {
            let d = gm_decay(dt_s, t_b);
            n.s_b
                .iter()
                .for_each(|s| w.gauss_markov(T::of_f64(s * half_t), &d));
            n.s_k
                .iter()
                .for_each(|s| w.random_walk(T::of_f64(*s), dt_s));
        }
        BiasModel::SingleStateGmRw => {
            let d = gm_decay(dt_s, t_b);
            n.s_b
                .iter()
                .zip(n.s_k.iter())
                .for_each(|(b, k)| w.gauss_markov(T::of_f64((b + k) * half_t), &d));
        }
    }
}

/// The exact discretisation of a first-order Gauss-Markov decay over `dt`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GmDecay<T> {
    /// `-dt / T`.
    pub f_dt: T,
    /// `e^(-dt/T)`.
    pub phi: T,
    /// `1 - e^(-2 dt/T)`, computed without cancellation.
    pub one_minus_phi2: T,
}

/// `e^(-x)` and `1 - e^(-2x)` for `x = dt_s / t_s`: Taylor series to x^9 for x < 0.02 (exact to
/// the rounding of T, and cheaper than `exp`), `libm` otherwise.
pub fn gm_decay<T: Scalar>(dt_s: T, t_s: T) -> GmDecay<T> {
    /// `1 - z/2 (1 - z/3 (1 - ... (1 - z/10)))`: e^-z = 1 - z * series(z) and
    /// 1 - e^-z = z * series(z), truncated after z^9 (relative error below 1e-19 for z < 0.04).
    fn series<T: Scalar>(z: T) -> T {
        const INV: [f64; 9] = [
            1.0 / 10.0,
            1.0 / 9.0,
            1.0 / 8.0,
            1.0 / 7.0,
            1.0 / 6.0,
            1.0 / 5.0,
            1.0 / 4.0,
            1.0 / 3.0,
            1.0 / 2.0,
        ];
        let mut acc = T::ONE;
        for k in INV {
            acc = T::ONE - z * T::of_f64(k) * acc;
        }
        acc
    }
    let x = dt_s / t_s;
    let two = T::ONE + T::ONE;
    let (phi, omp) = if x < T::of_f64(0.02) {
        let y = two * x;
        (T::ONE - x * series(x), y * series(y))
    } else {
        ((-x).exp_libm(), -(-two * x).expm1_libm())
    };
    GmDecay {
        f_dt: -x,
        phi,
        one_minus_phi2: omp,
    }
}

struct DiagWriter<'a, T> {
    f_dt: &'a mut [T],
    phi: &'a mut [T],
    q: &'a mut [T],
    n: usize,
}

impl<T: Scalar> DiagWriter<'_, T> {
    fn put(&mut self, f_dt: T, phi: T, q: T) {
        if let Some(x) = self.f_dt.get_mut(self.n) {
            *x = f_dt;
        }
        if let Some(x) = self.phi.get_mut(self.n) {
            *x = phi;
        }
        if let Some(x) = self.q.get_mut(self.n) {
            *x = q;
        }
        self.n += 1;
    }
    /// First-order Gauss-Markov with stationary variance `var`, decay from [`gm_decay`].
    fn gauss_markov(&mut self, var: T, d: &GmDecay<T>) {
        self.put(d.f_dt, d.phi, var * d.one_minus_phi2);
    }
    /// Random walk (random constant when `psd` = 0).
    fn random_walk(&mut self, psd: T, dt_s: T) {
        self.put(T::ZERO, T::ONE, psd * dt_s);
    }
}

/// The IMU error estimates applied to a raw sample before mechanisation (the inverse of the
/// sensor model in the module docs), per sample with `dT = T - T_ref` (0 without a
/// temperature):
///
/// ```text
/// f = (I + diag(s_a) + M_a)^-1 (f_meas - b_a - k_a dT)
/// w = (I + diag(s_g) + M_g)^-1 (w_meas - b_g - k_g dT - diag(g_s) f)
/// ```
///
/// applied to the increments (`f dt = dv`, `w dt = dtheta`). With no misalignment,
/// temperature coefficient or g-sensitivity (all zero) it reduces to the per-axis
/// `(x_meas - b)/(1 + s)`, computed exactly as before these were added.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ImuCorrection {
    /// Accelerometer bias, m/s^2.
    pub accel_bias_mps2: [f64; 3],
    /// Gyro bias, rad/s.
    pub gyro_bias_radps: [f64; 3],
    /// Accelerometer scale-factor error (dimensionless).
    pub accel_scale: [f64; 3],
    /// Gyro scale-factor error (dimensionless).
    pub gyro_scale: [f64; 3],
    /// Accelerometer misalignment `[m_xy, m_xz, m_yx, m_yz, m_zx, m_zy]`, rad.
    pub accel_misalignment_rad: [f64; 6],
    /// Gyro misalignment `[m_xy, m_xz, m_yx, m_yz, m_zx, m_zy]`, rad.
    pub gyro_misalignment_rad: [f64; 6],
    /// Accelerometer bias temperature coefficient, m/s^2/degC.
    pub accel_temp_coeff_mps2_per_c: [f64; 3],
    /// Gyro bias temperature coefficient, rad/s/degC.
    pub gyro_temp_coeff_radps_per_c: [f64; 3],
    /// Reference temperature of the coefficients, degC (NaN: none yet, zero regressor).
    pub temperature_ref_c: f64,
    /// Diagonal gyro g-sensitivity, rad/s per m/s^2.
    pub gyro_g_sensitivity_radps_per_mps2: [f64; 3],
}

impl ImuCorrection {
    /// Corrects increments over `dt_s` seconds in place, without a temperature (the
    /// temperature terms are zero; use [`Self::apply_with_temperature`] for samples that carry
    /// one).
    pub fn apply(&self, dtheta_rad: &mut [f64; 3], dv_mps: &mut [f64; 3], dt_s: f64) {
        self.apply_with(&self.inverse_scales(), dtheta_rad, dv_mps, dt_s, f64::NAN);
    }

    /// Corrects increments over `dt_s` seconds of a sample taken at `temperature_c` degC (NaN:
    /// none) in place.
    pub fn apply_with_temperature(
        &self,
        dtheta_rad: &mut [f64; 3],
        dv_mps: &mut [f64; 3],
        dt_s: f64,
        temperature_c: f64,
    ) {
        self.apply_with(
            &self.inverse_scales(),
            dtheta_rad,
            dv_mps,
            dt_s,
            temperature_c,
        );
    }

    /// Whether any misalignment, temperature coefficient or g-sensitivity is non-zero (then
    /// the general correction is needed).
    pub fn is_general(&self) -> bool {
        let nz = |a: &[f64]| a.iter().any(|v| *v != 0.0);
        nz(&self.accel_misalignment_rad)
            || nz(&self.gyro_misalignment_rad)
            || nz(&self.accel_temp_coeff_mps2_per_c)
            || nz(&self.gyro_temp_coeff_radps_per_c)
            || nz(&self.gyro_g_sensitivity_radps_per_mps2)
    }

    /// `1 / (1 + s)` for the gyro and accelerometer scale-factor errors and, when
    /// [`Self::is_general`], what the general correction needs: `(I + diag(s) + M)^-1 - I`
    /// and the bias, temperature and g-sensitivity terms in `f32` (computed once per change of
    /// the estimates, so the per-epoch correction needs no division).
    pub fn inverse_scales(&self) -> InverseScales {
        let general = self.is_general();
        let delta = |s: &[f64; 3], m: &[f64; 6]| {
            if !general {
                return [[0.0f32; 3]; 3];
            }
            let a = effects::sensor_matrix(s, m);
            // the matrix is I + O(1e-3): invertible; identity only if the estimates are absurd
            let inv = effects::inv3(&a).unwrap_or(IDENTITY3);
            let mut d = [[0.0f32; 3]; 3];
            for (i, (drow, irow)) in d.iter_mut().zip(&inv).enumerate() {
                for (j, (x, v)) in drow.iter_mut().zip(irow).enumerate() {
                    *x = (*v - if i == j { 1.0 } else { 0.0 }) as f32;
                }
            }
            d
        };
        let f32s = |a: &[f64; 3]| a.map(|v| v as f32);
        InverseScales {
            gyro: self.gyro_scale.map(|s| 1.0 / (1.0 + s)),
            accel: self.accel_scale.map(|s| 1.0 / (1.0 + s)),
            general,
            gyro_delta: delta(&self.gyro_scale, &self.gyro_misalignment_rad),
            accel_delta: delta(&self.accel_scale, &self.accel_misalignment_rad),
            gyro_bias: f32s(&self.gyro_bias_radps),
            accel_bias: f32s(&self.accel_bias_mps2),
            gyro_temp: f32s(&self.gyro_temp_coeff_radps_per_c),
            accel_temp: f32s(&self.accel_temp_coeff_mps2_per_c),
            g_sens: f32s(&self.gyro_g_sensitivity_radps_per_mps2),
        }
    }

    /// [`Self::apply`] with precomputed [`Self::inverse_scales`] and the sample's temperature,
    /// degC (NaN: none).
    ///
    /// Without misalignment, temperature or g-sensitivity estimates this is the per-axis
    /// `(x - b dt) / (1 + s)` in `f64`. The general correction adds a small `f32` correction to
    /// the `f64` increment, `x_hat = x + c` with `c = -e + D (x - e)` (`e` the bias, temperature
    /// and g-sensitivity terms over the interval, `D = (I + diag(s) + M)^-1 - I`): `c` is about
    /// 1e-3 of the increment, so its `f32` rounding (6e-8 of `c`) is below 1e-10 of the
    /// increment, while on a single-precision FPU it costs a few dozen instructions instead of
    /// the ~60 software `f64` operations of the full product.
    pub fn apply_with(
        &self,
        inv: &InverseScales,
        dtheta_rad: &mut [f64; 3],
        dv_mps: &mut [f64; 3],
        dt_s: f64,
        temperature_c: f64,
    ) {
        if !inv.general {
            for ((d, b), k) in dtheta_rad
                .iter_mut()
                .zip(self.gyro_bias_radps)
                .zip(inv.gyro)
            {
                *d = (*d - b * dt_s) * k;
            }
            for ((d, b), k) in dv_mps.iter_mut().zip(self.accel_bias_mps2).zip(inv.accel) {
                *d = (*d - b * dt_s) * k;
            }
            return;
        }
        let d_t = temperature_c - self.temperature_ref_c;
        let d_t = if d_t.is_finite() { d_t as f32 } else { 0.0 };
        let dt = dt_s as f32;
        // accelerometer: e = (b + k dT) dt
        let mut ea = [0.0f32; 3];
        for ((e, b), k) in ea.iter_mut().zip(inv.accel_bias).zip(inv.accel_temp) {
            *e = (b + k * d_t) * dt;
        }
        let mut ua = [0.0f32; 3];
        for ((u, d), e) in ua.iter_mut().zip(dv_mps.iter()).zip(ea) {
            *u = *d as f32 - e;
        }
        let ca = effects::mat_vec(&inv.accel_delta, &ua);
        let mut dv_hat32 = [0.0f32; 3];
        for (((d, c), e), h) in dv_mps.iter_mut().zip(ca).zip(ea).zip(dv_hat32.iter_mut()) {
            let corr = c - e;
            *h = *d as f32 + corr;
            *d += f64::from(corr);
        }
        // gyro: e = (b + k dT) dt + diag(g_s) dv_hat
        let mut eg = [0.0f32; 3];
        for ((((e, b), k), g), dv) in eg
            .iter_mut()
            .zip(inv.gyro_bias)
            .zip(inv.gyro_temp)
            .zip(inv.g_sens)
            .zip(dv_hat32)
        {
            *e = (b + k * d_t) * dt + g * dv;
        }
        let mut ug = [0.0f32; 3];
        for ((u, d), e) in ug.iter_mut().zip(dtheta_rad.iter()).zip(eg) {
            *u = *d as f32 - e;
        }
        let cg = effects::mat_vec(&inv.gyro_delta, &ug);
        for ((d, c), e) in dtheta_rad.iter_mut().zip(cg).zip(eg) {
            *d += f64::from(c - e);
        }
    }
}

/// Reciprocal scale factors `1 / (1 + s)` of an [`ImuCorrection`], and what its general
/// correction needs (in `f32`, see [`ImuCorrection::apply_with`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseScales {
    /// Gyro x, y, z.
    pub gyro: [f64; 3],
    /// Accelerometer x, y, z.
    pub accel: [f64; 3],
    /// Whether the general (matrix, temperature, g-sensitivity) correction applies.
    pub general: bool,
    /// `(I + diag(s_g) + M_g)^-1 - I` (row-major; zero when not `general`).
    pub gyro_delta: [[f32; 3]; 3],
    /// `(I + diag(s_a) + M_a)^-1 - I` (row-major; zero when not `general`).
    pub accel_delta: [[f32; 3]; 3],
    /// Gyro bias, rad/s.
    pub gyro_bias: [f32; 3],
    /// Accelerometer bias, m/s^2.
    pub accel_bias: [f32; 3],
    /// Gyro temperature coefficient, rad/s/degC.
    pub gyro_temp: [f32; 3],
    /// Accelerometer temperature coefficient, m/s^2/degC.
    pub accel_temp: [f32; 3],
    /// Gyro g-sensitivity, rad/s per m/s^2.
    pub g_sens: [f32; 3],
}

/// What one IMU epoch provides to the error model (in the covariance scalar type).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Regressors<T> {
    /// Epoch length, s.
    pub dt: T,
    /// Body-to-NED rotation C_b^n at the end of the epoch (row-major).
    pub c_nb: [[T; 3]; 3],
    /// Corrected mean specific force, body, m/s^2.
    pub f_b: [T; 3],
    /// Corrected mean angular rate, body, rad/s.
    pub omega_b: [T; 3],
    /// Sensor temperature relative to the reference, `T - T_ref`, degC (NaN when the sample
    /// has no temperature or no reference is known yet: the temperature blocks then have zero
    /// regressor).
    pub temperature_c: T,
}

/// Geometry of a GNSS measurement (all f64, NED / body), for the Jacobian columns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasContext {
    /// C_b^n l: lever arm in NED, m.
    pub c_l: [f64; 3],
    /// C_b^n (w_ib x l): antenna velocity from body rotation, NED, m/s.
    pub c_w_x_l: [f64; 3],
    /// C_b^n [l x] (row-major).
    pub c_lx: [[f64; 3]; 3],
    /// Last corrected angular rate, body, rad/s.
    pub omega_b_radps: [f64; 3],
    /// C_b^n (row-major).
    pub c_nb: [[f64; 3]; 3],
    /// Last corrected specific force, body, m/s^2.
    pub f_b_mps2: [f64; 3],
    /// Last sample's temperature minus T_ref, degC (NaN: none).
    pub temperature_offset_c: f64,
    /// Antenna velocity at the fix's IMU time, `v + C (w x l) + a tau`, NED, m/s (the
    /// time-offset column of a position update).
    pub v_ant_ned_mps: [f64; 3],
    /// Acceleration `C f + g`, NED, m/s^2 (the time-offset column of a velocity update).
    pub acc_ned_mps2: [f64; 3],
    /// Time from the filter epoch to the IMU time the fix refers to, `t_fix + dt_hat - t`, s
    /// (the velocity error's coefficient in the position measurement).
    pub bridge_s: f64,
    /// The time over which the predicted antenna position is bridged with the antenna
    /// velocity `v + C (w x l)`, s (`bridge_s` with the time-offset block, else 0: the
    /// bridge then uses v alone), so the lever-arm column gets `C + bridge [C w x]`.
    pub lever_bridge_s: f64,
    /// `w_in = w_ie + w_en`, NED, rad/s (the lever arm's `- w_in x (C l)` velocity term).
    pub w_in_ned_radps: [f64; 3],
    /// Last specific force in NED, `C f`, m/s^2 (the time-offset bridge's attitude terms).
    pub f_ned_mps2: [f64; 3],
}

/// Errors of a layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LayoutError {
    /// The layout's total dimension differs from the filter's const N.
    DimensionMismatch {
        /// Sum of the block dimensions.
        layout: usize,
        /// The filter's N.
        filter: usize,
    },
    /// The first block is not [`Block::Core`], or Core appears twice.
    CoreNotFirst,
    /// Two blocks of the same kind.
    DuplicateKind,
    /// More than [`MAX_BLOCKS`] blocks were given to [`Layout::new`].
    TooManyBlocks,
}

impl core::fmt::Display for LayoutError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::DimensionMismatch { layout, filter } => write!(
                f,
                "layout: blocks add up to {layout} states but the filter has N = {filter}"
            ),
            Self::CoreNotFirst => {
                f.write_str("layout: the first (and only the first) block must be Core")
            }
            Self::DuplicateKind => f.write_str("layout: two blocks of the same kind"),
            Self::TooManyBlocks => write!(f, "layout: more than {MAX_BLOCKS} blocks"),
        }
    }
}

impl core::error::Error for LayoutError {}

/// An ordered list of blocks, built at compile time:
/// `const L: Layout = Layout::new(&[Block::Core, ...]); type F = Filter<f32, { L.dim() }>;`
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    blocks: [Block; MAX_BLOCKS],
    len: usize,
    overflow: bool,
}

impl Layout {
    /// A layout of `blocks` in order (at most [`MAX_BLOCKS`]; more is reported by
    /// [`Layout::validate`]).
    #[allow(clippy::indexing_slicing)] // both indices bounded by the loop condition
    pub const fn new(blocks: &[Block]) -> Self {
        let mut out = [Block::Core; MAX_BLOCKS];
        let mut i = 0;
        while i < blocks.len() && i < MAX_BLOCKS {
            out[i] = blocks[i];
            i += 1;
        }
        Self {
            blocks: out,
            len: i,
            overflow: blocks.len() > MAX_BLOCKS,
        }
    }

    /// Total number of error states.
    #[allow(clippy::indexing_slicing)] // index bounded by the loop condition
    pub const fn dim(&self) -> usize {
        let mut n = 0;
        let mut i = 0;
        while i < self.len && i < MAX_BLOCKS {
            n += self.blocks[i].dim();
            i += 1;
        }
        n
    }

    /// This layout with `block` appended (compile-time composition: base model + effects,
    /// e.g. `LAYOUT_NBK.with(Block::LeverArm)`). Appending beyond [`MAX_BLOCKS`] is reported
    /// by [`Layout::validate`]; duplicates too.
    #[allow(clippy::indexing_slicing)] // index checked against MAX_BLOCKS
    pub const fn with(self, block: Block) -> Self {
        let mut out = self;
        if out.len < MAX_BLOCKS {
            out.blocks[out.len] = block;
            out.len += 1;
        } else {
            out.overflow = true;
        }
        out
    }

    /// Whether the layout has a block of `kind`.
    pub fn contains(&self, kind: BlockKind) -> bool {
        self.blocks().iter().any(|b| b.kind() == kind)
    }

    /// Number of blocks.
    pub const fn len(&self) -> usize {
        self.len
    }

    /// Whether the layout has no block at all.
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The blocks in order.
    pub fn blocks(&self) -> &[Block] {
        self.blocks.get(..self.len).unwrap_or(&[])
    }

    /// The blocks with their state offsets.
    pub fn iter(&self) -> impl Iterator<Item = (usize, Block)> + '_ {
        self.blocks().iter().scan(0usize, |off, b| {
            let o = *off;
            *off += b.dim();
            Some((o, *b))
        })
    }

    /// The block of `kind` and its state offset.
    pub fn find(&self, kind: BlockKind) -> Option<(usize, Block)> {
        self.iter().find(|(_, b)| b.kind() == kind)
    }

    /// Checks the layout for a filter of `n` states.
    pub fn validate(&self, n: usize) -> Result<(), LayoutError> {
        if self.overflow {
            return Err(LayoutError::TooManyBlocks);
        }
        let bl = self.blocks();
        if bl.first() != Some(&Block::Core) || bl.iter().skip(1).any(|b| *b == Block::Core) {
            return Err(LayoutError::CoreNotFirst);
        }
        for (i, a) in bl.iter().enumerate() {
            if bl.iter().skip(i + 1).any(|b| b.kind() == a.kind()) {
                return Err(LayoutError::DuplicateKind);
            }
        }
        if self.dim() != n {
            return Err(LayoutError::DimensionMismatch {
                layout: self.dim(),
                filter: n,
            });
        }
        Ok(())
    }
}

/// The source's classical N model: core + constant gyro bias + constant accelerometer bias
/// (15 states).
pub const LAYOUT_N: Layout = Layout::new(&[
    Block::Core,
    Block::GyroBias(BiasModel::Constant),
    Block::AccelBias(BiasModel::Constant),
]);

/// The source's detailed NBK model with separate Gauss-Markov and random-walk accelerometer
/// bias states (DESIGN.md's exact form): 18 states.
pub const LAYOUT_NBK: Layout = Layout::new(&[
    Block::Core,
    Block::GyroBias(BiasModel::Constant),
    Block::AccelBias(BiasModel::GaussMarkovRandomWalk),
]);

/// The source's NBK model as printed: one decaying accelerometer bias state driven by both
/// S_B and S_K: 15 states.
pub const LAYOUT_NBK_SINGLE: Layout = Layout::new(&[
    Block::Core,
    Block::GyroBias(BiasModel::Constant),
    Block::AccelBias(BiasModel::SingleStateGmRw),
]);

/// KF-GINS's 21-state model: Gauss-Markov gyro and accelerometer biases and scale factors.
pub const LAYOUT_KF_GINS: Layout = Layout::new(&[
    Block::Core,
    Block::GyroBias(BiasModel::GaussMarkov),
    Block::AccelBias(BiasModel::GaussMarkov),
    Block::GyroScaleFactor,
    Block::AccelScaleFactor,
]);

// ---- small fixed-size helpers (no indexing, no panics) ----

/// 3x3 identity.
pub const IDENTITY3: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// Skew-symmetric matrix `[v x]` (row-major), so `[v x] w = v x w`.
pub fn skew(v: &[f64; 3]) -> [[f64; 3]; 3] {
    let [x, y, z] = *v;
    [[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]]
}

/// Converts a 3x3 f64 matrix to the scalar type.
pub fn to_t<T: Scalar>(m: &[[f64; 3]; 3]) -> [[T; 3]; 3] {
    m.map(|r| r.map(T::of_f64))
}

/// `m * s`.
pub fn scale3<T: Scalar>(m: &[[T; 3]; 3], s: T) -> [[T; 3]; 3] {
    m.map(|r| r.map(|v| v * s))
}

/// `m * diag(d)` (scales column j by d[j]).
pub fn mul_diag3<T: Copy + core::ops::Mul<Output = T>>(m: &[[T; 3]; 3], d: &[T; 3]) -> [[T; 3]; 3] {
    m.map(|r| {
        let [a, b, c] = r;
        let [x, y, z] = *d;
        [a * x, b * y, c * z]
    })
}

/// Adds the 3x3 `m` into `dst` at (row0, col0); entries outside `dst` are ignored.
pub fn add3<T: Scalar, const R: usize, const C: usize>(
    dst: &mut [[T; C]; R],
    row0: usize,
    col0: usize,
    m: &[[T; 3]; 3],
) {
    for (d_row, m_row) in dst.iter_mut().skip(row0).zip(m) {
        for (d, v) in d_row.iter_mut().skip(col0).zip(m_row) {
            *d += *v;
        }
    }
}

/// Writes the 3x3 `m` into `dst` at (row0, col0); entries outside `dst` are ignored.
pub fn set3<T: Scalar, const R: usize, const C: usize>(
    dst: &mut [[T; C]; R],
    row0: usize,
    col0: usize,
    m: &[[T; 3]; 3],
) {
    for (d_row, m_row) in dst.iter_mut().skip(row0).zip(m) {
        for (d, v) in d_row.iter_mut().skip(col0).zip(m_row) {
            *d = *v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_have_the_documented_dimensions_and_validate() {
        assert_eq!(LAYOUT_N.dim(), 15);
        assert_eq!(LAYOUT_NBK.dim(), 18);
        assert_eq!(LAYOUT_NBK_SINGLE.dim(), 15);
        assert_eq!(LAYOUT_KF_GINS.dim(), 21);
        assert!(LAYOUT_NBK.validate(18).is_ok());
        assert_eq!(
            LAYOUT_NBK.validate(15),
            Err(LayoutError::DimensionMismatch {
                layout: 18,
                filter: 15
            })
        );
        let no_core = Layout::new(&[Block::GyroBias(BiasModel::Constant)]);
        assert_eq!(no_core.validate(3), Err(LayoutError::CoreNotFirst));
        let dup = Layout::new(&[
            Block::Core,
            Block::AccelBias(BiasModel::Constant),
            Block::AccelBias(BiasModel::GaussMarkov),
        ]);
        assert_eq!(dup.validate(15), Err(LayoutError::DuplicateKind));
        let many = Layout::new(&[Block::Core; MAX_BLOCKS + 1]);
        assert_eq!(many.validate(9), Err(LayoutError::TooManyBlocks));
        let offs: heapless::Vec<usize, 8> = LAYOUT_KF_GINS.iter().map(|(o, _)| o).collect();
        assert_eq!(offs.as_slice(), &[0, 9, 12, 15, 18]);
        assert_eq!(
            LAYOUT_NBK.find(BlockKind::AccelBias),
            Some((12, Block::AccelBias(BiasModel::GaussMarkovRandomWalk)))
        );
    }

    #[test]
    fn gauss_markov_discretisation_is_exact() {
        let cfg = FilterConfig::source_nbk_model();
        let (mut f, mut p, mut q) = ([0.0; 6], [0.0; 6], [0.0; 6]);
        Block::AccelBias(BiasModel::GaussMarkovRandomWalk)
            .discretize(&cfg, 0.1, &mut f, &mut p, &mut q);
        let e = libm::exp(-0.1 / 45.0);
        assert!((p[0] - e).abs() < 1e-16);
        assert!((q[0] - 0.5 * 2.4360e-11 * 45.0 * (1.0 - e * e)).abs() < 1e-12 * q[0]);
        assert_eq!(p[3], 1.0);
        assert!((q[3] - 2.6731e-12 * 0.1).abs() < 1e-30);
        // single-state variant: both PSDs into one decaying state
        Block::AccelBias(BiasModel::SingleStateGmRw).discretize(&cfg, 0.1, &mut f, &mut p, &mut q);
        assert!(
            (q[0] - 0.5 * (2.4360e-11 + 2.6731e-12) * 45.0 * (1.0 - e * e)).abs() < 1e-12 * q[0]
        );
        assert!((f[1] + 0.1 / 45.0).abs() < 1e-18);
    }

    #[test]
    fn gm_decay_series_matches_libm() {
        for x in [1e-7, 1e-5, 2.2e-3, 9.99e-3, 0.0199, 0.0201, 0.5, 3.0] {
            let d = gm_decay(x * 45.0, 45.0f64);
            let e = libm::exp(-x);
            let m = -libm::expm1(-2.0 * x);
            assert!((d.phi - e).abs() <= 2e-16 * e, "{x}: {} {e}", d.phi);
            assert!(
                (d.one_minus_phi2 - m).abs() <= 4e-16 * m,
                "{x}: {} {m}",
                d.one_minus_phi2
            );
            assert!((d.f_dt + x).abs() <= 3e-16 * x);
        }
    }

    #[test]
    fn imu_correction_inverts_the_sensor_model() {
        // measured = (1 + s) true + b  (increments: b * dt)
        let c = ImuCorrection {
            accel_bias_mps2: [0.01, -0.02, 0.03],
            gyro_bias_radps: [1e-5, 2e-5, -3e-5],
            accel_scale: [1e-3, -2e-3, 5e-4],
            gyro_scale: [-1e-3, 2e-4, 3e-3],
            ..Default::default()
        };
        let dt = 0.005;
        let (w, f) = ([0.1, -0.2, 0.3], [1.0, 2.0, -9.8]);
        let mut dth = [0.0; 3];
        let mut dv = [0.0; 3];
        for i in 0..3 {
            dth[i] = ((1.0 + c.gyro_scale[i]) * w[i] + c.gyro_bias_radps[i]) * dt;
            dv[i] = ((1.0 + c.accel_scale[i]) * f[i] + c.accel_bias_mps2[i]) * dt;
        }
        c.apply(&mut dth, &mut dv, dt);
        for i in 0..3 {
            assert!((dth[i] - w[i] * dt).abs() < 1e-15);
            assert!((dv[i] - f[i] * dt).abs() < 1e-15);
        }
    }

    #[test]
    fn general_imu_correction_inverts_the_full_sensor_model() {
        // w_meas = (I + S_g + M_g) w + b_g + diag(g_s) f + k_g dT
        // f_meas = (I + S_a + M_a) f + b_a + k_a dT
        let c = ImuCorrection {
            accel_bias_mps2: [0.01, -0.02, 0.03],
            gyro_bias_radps: [1e-5, 2e-5, -3e-5],
            accel_scale: [1e-3, -2e-3, 5e-4],
            gyro_scale: [-1e-3, 2e-4, 3e-3],
            accel_misalignment_rad: [3e-4, -2e-4, 1e-4, 5e-4, -4e-4, 2e-4],
            gyro_misalignment_rad: [-3e-4, 2e-4, 4e-4, -1e-4, 3e-4, -5e-4],
            accel_temp_coeff_mps2_per_c: [4e-4, -3e-4, 2e-4],
            gyro_temp_coeff_radps_per_c: [5e-7, -4e-7, 3e-7],
            temperature_ref_c: 20.0,
            gyro_g_sensitivity_radps_per_mps2: [3e-6, -2e-6, 1e-6],
        };
        assert!(c.is_general());
        let (dt, temp) = (0.005, 43.5);
        let d_t = temp - c.temperature_ref_c;
        let (w, f) = ([0.1, -0.2, 0.3], [1.0, 2.0, -9.8]);
        let ga = effects::sensor_matrix(&c.accel_scale, &c.accel_misalignment_rad);
        let gg = effects::sensor_matrix(&c.gyro_scale, &c.gyro_misalignment_rad);
        let fa = effects::mat_vec(&ga, &f);
        let wg = effects::mat_vec(&gg, &w);
        let mut dth = [0.0; 3];
        let mut dv = [0.0; 3];
        for i in 0..3 {
            dv[i] = (fa[i] + c.accel_bias_mps2[i] + c.accel_temp_coeff_mps2_per_c[i] * d_t) * dt;
            dth[i] = (wg[i]
                + c.gyro_bias_radps[i]
                + c.gyro_temp_coeff_radps_per_c[i] * d_t
                + c.gyro_g_sensitivity_radps_per_mps2[i] * f[i])
                * dt;
        }
        c.apply_with_temperature(&mut dth, &mut dv, dt, temp);
        // the general correction is computed in f32: rounding ~6e-8 of a correction ~1e-3 of
        // the increment vector, i.e. below 1e-10 of its norm
        let norm = |v: &[f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt() * dt;
        for i in 0..3 {
            let (a, b) = (w[i] * dt, f[i] * dt);
            assert!((dth[i] - a).abs() < 1e-10 * norm(&w), "{i}: {}", dth[i] - a);
            assert!((dv[i] - b).abs() < 1e-10 * norm(&f), "{i}: {}", dv[i] - b);
        }
        // without a temperature the temperature terms are zero
        let mut dth2 = [0.0; 3];
        let mut dv2 = [0.0; 3];
        let only_t = ImuCorrection {
            accel_temp_coeff_mps2_per_c: [1e-3; 3],
            temperature_ref_c: 20.0,
            ..Default::default()
        };
        dv2[0] = 0.05;
        dth2[1] = 1e-3;
        only_t.apply_with_temperature(&mut dth2, &mut dv2, dt, f64::NAN);
        assert_eq!((dth2, dv2), ([0.0, 1e-3, 0.0], [0.05, 0.0, 0.0]));
    }

    #[test]
    fn layouts_compose_with_effect_blocks_at_compile_time() {
        const ALL: Layout = LAYOUT_NBK
            .with(Block::AccelScaleFactor)
            .with(Block::GyroScaleFactor)
            .with(Block::AccelMisalignment)
            .with(Block::GyroMisalignment)
            .with(Block::LeverArm)
            .with(Block::TimeOffset)
            .with(Block::AccelTemperatureBias)
            .with(Block::GyroTemperatureBias)
            .with(Block::GyroGSensitivity);
        assert_eq!(ALL.dim(), 18 + 3 + 3 + 6 + 6 + 3 + 1 + 3 + 3 + 3);
        assert!(ALL.validate(ALL.dim()).is_ok());
        assert_eq!(ALL.len(), 12);
        assert!(ALL.contains(BlockKind::TimeOffset));
        assert_eq!(
            ALL.find(BlockKind::TimeOffset).map(|(o, _)| o),
            Some(18 + 3 + 3 + 6 + 6 + 3)
        );
        let names: heapless::Vec<&str, 9> = EFFECT_BLOCKS.iter().map(|b| b.name()).collect();
        assert_eq!(
            names.as_slice(),
            &[
                "accel_scale_factor",
                "gyro_scale_factor",
                "accel_misalignment",
                "gyro_misalignment",
                "lever_arm",
                "time_offset",
                "accel_temperature_bias",
                "gyro_temperature_bias",
                "gyro_g_sensitivity",
            ]
        );
        for b in EFFECT_BLOCKS {
            assert_eq!(Block::effect_from_name(b.name()), Some(b));
        }
        assert_eq!(
            LAYOUT_KF_GINS.with(Block::GyroScaleFactor).validate(24),
            Err(LayoutError::DuplicateKind)
        );
        let mut big = LAYOUT_KF_GINS;
        for b in EFFECT_BLOCKS.iter().chain(EFFECT_BLOCKS.iter()) {
            big = big.with(*b);
        }
        assert_eq!(big.validate(big.dim()), Err(LayoutError::TooManyBlocks));
    }

    #[test]
    fn skew_is_the_cross_product() {
        let a = [1.0, -2.0, 0.5];
        let b = [0.3, 0.7, -1.1];
        let s = skew(&a);
        let c = [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ];
        for i in 0..3 {
            let v: f64 = (0..3).map(|j| s[i][j] * b[j]).sum();
            assert!((v - c[i]).abs() < 1e-15);
        }
    }
}
