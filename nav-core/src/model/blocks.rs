//! The error-state blocks ([`Block`], [`BiasModel`], [`BlockKind`]): dimension, coupling into
//! the core, discrete noise, initial variance, IMU correction, measurement Jacobian columns and
//! feedback of each; the per-epoch inputs ([`Regressors`]) and measurement geometry
//! ([`MeasContext`]) they use. See the [module notes](super) for the conventions.

use super::*;

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
    /// `imu_clock_drift`: 2 states `[dt_0, r]`, the IMU-GNSS time offset at the filter's
    /// start `t_0` (s) and its rate (s/s, 1e-6 = 1 ppm: an IMU clock running `r` fast): the
    /// offset is `dt(t) = dt_0 + r (t - t_0)` and enters the GNSS measurement like
    /// [`Block::TimeOffset`]'s (it replaces it: both are [`BlockKind::TimeOffset`]). Priors and
    /// process noise: `EffectsConfig::time_offset` (dt_0) and `EffectsConfig::imu_clock_drift`
    /// (r). Derivation: `docs/derivations/clock_drift_gnss_gm.md`.
    ImuClockDrift,
    /// `gnss_position_gm`: 3 states, a time-correlated error of the GNSS antenna position, NED,
    /// m (measured = true + e), each axis a first-order Gauss-Markov process with the
    /// `EffectsConfig::gnss_position_gm` sigma and correlation time. Measurement-only (position
    /// columns `+I`). Derivation: `docs/derivations/clock_drift_gnss_gm.md`.
    GnssPositionGm,
    /// `odometer_scale`: 1 state, the scale-factor error `k` of a wheel-speed odometer
    /// (dimensionless): measured speed = `(1 + k)` true speed ([`crate::aiding::odometer`]).
    /// Measurement-only (no IMU coupling); not in [`EFFECT_BLOCKS`] (an aiding sensor, not an
    /// IMU effect). Prior and process noise: `EffectsConfig::odometer_scale`.
    OdometerScale,
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
    /// [`Block::TimeOffset`] and [`Block::ImuClockDrift`] (a time offset, constant or
    /// drifting; the first state is the offset).
    TimeOffset,
    /// [`Block::AccelTemperatureBias`].
    AccelTemperatureBias,
    /// [`Block::GyroTemperatureBias`].
    GyroTemperatureBias,
    /// [`Block::GyroGSensitivity`].
    GyroGSensitivity,
    /// [`Block::GnssPositionGm`].
    GnssPositionGm,
    /// [`Block::OdometerScale`].
    OdometerScale,
}

/// Every effect block (the diagnosis vocabulary), in the order of their names in the
/// documentation: scale factors, misalignments, lever arm, time offset, temperature
/// coefficients, g-sensitivity, IMU clock drift, GNSS position Gauss-Markov error.
pub const EFFECT_BLOCKS: [Block; 11] = [
    Block::AccelScaleFactor,
    Block::GyroScaleFactor,
    Block::AccelMisalignment,
    Block::GyroMisalignment,
    Block::LeverArm,
    Block::TimeOffset,
    Block::AccelTemperatureBias,
    Block::GyroTemperatureBias,
    Block::GyroGSensitivity,
    Block::ImuClockDrift,
    Block::GnssPositionGm,
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
            | Self::GyroGSensitivity
            | Self::GnssPositionGm => 3,
            Self::AccelMisalignment | Self::GyroMisalignment => 6,
            Self::ImuClockDrift => 2,
            Self::TimeOffset | Self::OdometerScale => 1,
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
            Self::TimeOffset | Self::ImuClockDrift => BlockKind::TimeOffset,
            Self::GnssPositionGm => BlockKind::GnssPositionGm,
            Self::AccelTemperatureBias => BlockKind::AccelTemperatureBias,
            Self::GyroTemperatureBias => BlockKind::GyroTemperatureBias,
            Self::GyroGSensitivity => BlockKind::GyroGSensitivity,
            Self::OdometerScale => BlockKind::OdometerScale,
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
            Self::ImuClockDrift => "imu_clock_drift",
            Self::GnssPositionGm => "gnss_position_gm",
            Self::OdometerScale => "odometer_scale",
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
            Self::GyroScaleFactor | Self::AccelScaleFactor | Self::OdometerScale => "1",
            Self::AccelMisalignment | Self::GyroMisalignment => "rad",
            Self::LeverArm | Self::GnssPositionGm => "m",
            Self::TimeOffset => "s",
            Self::ImuClockDrift => "s, s/s",
            Self::AccelTemperatureBias => "m/s^2/degC",
            Self::GyroTemperatureBias => "rad/s/degC",
            Self::GyroGSensitivity => "rad/s/(m/s^2)",
        }
    }

    /// The effect block's prior/process noise in `cfg`, if the block is an effect block with
    /// an [`EffectNoise`] (the scale factors and `gnss_position_gm` have their own
    /// Gauss-Markov parameters; for `imu_clock_drift` that of its rate state, its offset state
    /// has `time_offset`'s).
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
            Self::OdometerScale => Some(e.odometer_scale),
            Self::ImuClockDrift => Some(e.imu_clock_drift),
            Self::Core
            | Self::GnssPositionGm
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
    ///
    /// The bias blocks add nothing here: their coupling is `+-C_b^n dt`, whose sum over the
    /// interval the accumulator keeps anyway (`Accumulator::c_dt`); [`Self::add_bias_f`]
    /// puts it in at the discretisation (the same sums, bit for bit, without adding 18 or 36
    /// numbers per IMU epoch).
    pub fn accumulate_f<T: Scalar, const N: usize>(
        self,
        off: usize,
        reg: &Regressors<T>,
        f_top: &mut [[T; N]; CORE_DIM],
    ) {
        let c_dt = scale3(&reg.c_nb, reg.dt);
        match self {
            // the bias blocks: Self::add_bias_f at the discretisation
            Self::Core | Self::GyroBias(_) | Self::AccelBias(_) => {}
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
            Self::LeverArm
            | Self::TimeOffset
            | Self::ImuClockDrift
            | Self::GnssPositionGm
            | Self::OdometerScale => {}
        }
    }

    /// [`Self::accumulate_f`] with the epoch's `C_b^n dt` given (`c_dt`: `reg.c_nb` scaled by
    /// `reg.dt`, formed once for all the blocks of an epoch instead of once per block): the
    /// same sums, bit for bit. Not inlined: inlined into the loop over the blocks, the
    /// products of every arm were formed for every block.
    ///
    /// Host builds only, measured: on the host it takes `Accumulator::add` on the 40-minute
    /// case from 0.470 G to 0.209 G instructions (callgrind). On the MCU it would be faster as
    /// well (`cargo xtask fw bench`, qemu instructions per epoch with the 1 Hz GNSS update:
    /// 7,642 / 8,576 / 9,826 at 15 / 18 / 21 states against 7,989 / 8,938 / 10,654 with
    /// [`Self::accumulate_f`]), but it makes the `bench` image 1,456 B larger, 131,080 B, over
    /// the 131,072 B flash budget (inlined on the MCU: 132,080 B); hence the per-block form
    /// there.
    #[cfg(not(target_os = "none"))]
    #[inline(never)]
    pub fn accumulate_f_scaled<T: Scalar, const N: usize>(
        self,
        off: usize,
        reg: &Regressors<T>,
        c_dt: &[[T; 3]; 3],
        f_top: &mut [[T; N]; CORE_DIM],
    ) {
        // the 3x3 products written out (no array `map`: its drain is not always inlined)
        let scale = |m: &[[T; 3]; 3], s: T| {
            let [[a, b, c], [d, e, f], [g, h, i]] = *m;
            [
                [a * s, b * s, c * s],
                [d * s, e * s, f * s],
                [g * s, h * s, i * s],
            ]
        };
        let diag = |m: &[[T; 3]; 3], v: &[T; 3]| {
            let [[a, b, c], [d, e, f], [g, h, i]] = *m;
            let [x, y, z] = *v;
            [
                [a * x, b * y, c * z],
                [d * x, e * y, f * z],
                [g * x, h * y, i * z],
            ]
        };
        match self {
            Self::Core | Self::GyroBias(_) | Self::AccelBias(_) => {}
            Self::GyroScaleFactor => {
                add3(f_top, IDX_ATT, off, &diag(c_dt, &reg.omega_b));
            }
            Self::AccelScaleFactor => {
                let m = diag(c_dt, &reg.f_b);
                add3(f_top, IDX_VEL, off, &scale(&m, -T::ONE));
            }
            Self::GyroMisalignment => {
                effects::add_block(f_top, IDX_ATT, off, &effects::c_mis(c_dt, &reg.omega_b));
            }
            Self::AccelMisalignment => {
                let neg = scale(c_dt, -T::ONE);
                effects::add_block(f_top, IDX_VEL, off, &effects::c_mis(&neg, &reg.f_b));
            }
            Self::GyroTemperatureBias => {
                let d_t = effects::temperature_regressor(reg.temperature_c);
                if d_t != T::ZERO {
                    add3(f_top, IDX_ATT, off, &scale(c_dt, d_t));
                }
            }
            Self::AccelTemperatureBias => {
                let d_t = effects::temperature_regressor(reg.temperature_c);
                if d_t != T::ZERO {
                    add3(f_top, IDX_VEL, off, &scale(c_dt, -d_t));
                }
            }
            Self::GyroGSensitivity => {
                add3(f_top, IDX_ATT, off, &diag(c_dt, &reg.f_b));
            }
            Self::LeverArm
            | Self::TimeOffset
            | Self::ImuClockDrift
            | Self::GnssPositionGm
            | Self::OdometerScale => {}
        }
    }

    /// Adds the coupling of a bias block integrated over a whole interval to `a_top` (the 9
    /// core rows of the integrated F dt, zero in the block's columns) at column `off`, from
    /// `c_dt` = the sum of `C_b^n dt` over the interval ([`Self::accumulate_f`] left them
    /// out): gyro bias `phi' += C db`, accelerometer bias `dv' -= C db`, every process of the
    /// block alike. Other blocks add nothing. The result equals the per-epoch accumulation
    /// bit for bit: the per-epoch terms were `c dt` (or `-(c dt)`), summed from zero in the
    /// same order as `c_dt`, and IEEE rounding is symmetric under negation.
    pub fn add_bias_f<T: Scalar, const N: usize>(
        self,
        off: usize,
        c_dt: &[[T; 3]; 3],
        a_top: &mut [[T; N]; CORE_DIM],
    ) {
        match self {
            // gyro bias error db: w_hat = w - db  =>  phi' += C db
            Self::GyroBias(m) => {
                for g in 0..m.dim() / 3 {
                    add3(a_top, IDX_ATT, off + 3 * g, c_dt);
                }
            }
            // accel bias error db: f_hat = f - db  =>  dv' -= C db
            Self::AccelBias(m) => {
                let neg = scale3(c_dt, -T::ONE);
                for g in 0..m.dim() / 3 {
                    add3(a_top, IDX_VEL, off + 3 * g, &neg);
                }
            }
            _ => {}
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
            Self::GnssPositionGm => {
                let g = &cfg.effects.gnss_position_gm;
                let d = gm_decay(dt_s, T::of_f64(g.t_s));
                for s in g.sigma_m {
                    w.gauss_markov(T::of_f64(s * s), &d);
                }
            }
            // both states random walks (the offset's growth r (t - t_0) is in the measurement)
            Self::ImuClockDrift => {
                w.random_walk(T::of_f64(cfg.effects.time_offset.rw_psd), dt_s);
                w.random_walk(T::of_f64(cfg.effects.imu_clock_drift.rw_psd), dt_s);
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
            Self::GnssPositionGm => cfg
                .effects
                .gnss_position_gm
                .sigma_m
                .iter()
                .for_each(|s| put(s * s)),
            Self::ImuClockDrift => {
                let (o, r) = (cfg.effects.time_offset, cfg.effects.imu_clock_drift);
                put(o.init_sigma * o.init_sigma);
                put(r.init_sigma * r.init_sigma);
            }
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
            Self::LeverArm
            | Self::TimeOffset
            | Self::ImuClockDrift
            | Self::GnssPositionGm
            | Self::OdometerScale => {}
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
            | Self::TimeOffset
            | Self::ImuClockDrift
            | Self::GnssPositionGm
            | Self::OdometerScale => None,
            other => Some(other.kind()),
        }
    }

    /// Adds the block's columns (at `off`) of the GNSS measurement Jacobians: `h_pos` (antenna
    /// position, 3 rows) and `h_vel` (antenna velocity, 3 rows). Measurement = predicted -
    /// measured, so `z = H dx + noise` with dx = estimate - truth. The rows are [`Rows3`] views
    /// (runtime column count): one instance per scalar type whatever the state dimension.
    pub fn gnss_jacobian<T: Scalar>(
        self,
        off: usize,
        ctx: &MeasContext,
        h_pos: &mut Rows3<'_, T>,
        h_vel: &mut Rows3<'_, T>,
    ) {
        match self {
            Self::Core => {
                // p_ant = r + C l: dz = dr + [(C l) x] phi
                h_pos.set_block(off + IDX_ATT, &to_t(&skew(&ctx.c_l)));
                h_pos.set_block(off + IDX_POS, &to_t(&IDENTITY3));
                // v_ant = v + C (w x l) - w_in x (C l): dz = dv + [(C (w x l)) x] phi
                //   + C [l x] dw_gyro (w_in x terms neglected, < 1e-4 of the rest)
                h_vel.set_block(off + IDX_ATT, &to_t(&skew(&ctx.c_w_x_l)));
                h_vel.set_block(off + IDX_VEL, &to_t(&IDENTITY3));
            }
            // dw = -db  =>  dz_vel = -C [l x] db ... sign: C (dw x l) = -C [l x] dw = C [l x] db
            Self::GyroBias(m) => {
                for g in 0..m.dim() / 3 {
                    h_vel.set_block(off + 3 * g, &to_t(&ctx.c_lx));
                }
            }
            // dw = -diag(w) ds  =>  dz_vel = C [l x] diag(w) ds
            Self::GyroScaleFactor => {
                h_vel.set_block(off, &to_t(&mul_diag3(&ctx.c_lx, &ctx.omega_b_radps)));
            }
            // dw = -J(w) dm  =>  dz_vel = C [l x] J(w) dm
            Self::GyroMisalignment => {
                let m = effects::c_mis(&ctx.c_lx, &ctx.omega_b_radps);
                h_vel.set_block(off, &m.map(|r| r.map(T::of_f64)));
            }
            // dw = -dT dk  =>  dz_vel = C [l x] dT dk
            Self::GyroTemperatureBias => {
                let d_t = effects::temperature_regressor(ctx.temperature_offset_c);
                h_vel.set_block(off, &to_t(&scale3(&ctx.c_lx, d_t)));
            }
            // dw = -diag(f) dg  =>  dz_vel = C [l x] diag(f) dg
            Self::GyroGSensitivity => {
                h_vel.set_block(off, &to_t(&mul_diag3(&ctx.c_lx, &ctx.f_b_mps2)));
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
                h_pos.set_block(off, &to_t(&hp));
                let win_c = effects::mul3(&skew(&ctx.w_in_ned_radps), &ctx.c_nb);
                let mut hv = c_wx;
                for (r, w) in hv.iter_mut().zip(&win_c) {
                    for (a, b) in r.iter_mut().zip(w) {
                        *a -= *b;
                    }
                }
                h_vel.set_block(off, &to_t(&hv));
            }
            // predicted antenna at t_fix + dt_hat: dz_pos = v_ant d(dt), dz_vel = a d(dt); the
            // bridge tau = t_fix + dt_hat - t also multiplies the velocity error, and the
            // bridge's attitude dependence adds tau [(C (w x l)) x] + tau^2/2 [f_n x] (position)
            // and tau [f_n x] (velocity) to the phi columns
            Self::TimeOffset | Self::ImuClockDrift => {
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
                h_pos.add_block(IDX_ATT, &to_t(&hp));
                h_vel.add_block(IDX_ATT, &to_t(&hv));
                for (k, v) in ctx.v_ant_ned_mps.iter().enumerate() {
                    if let Some(x) = h_pos.get_mut(k, off) {
                        *x = T::of_f64(*v);
                    }
                    if let Some(x) = h_pos.get_mut(k, IDX_VEL + k) {
                        *x = T::of_f64(ctx.bridge_s);
                    }
                }
                for (k, a) in ctx.acc_ned_mps2.iter().enumerate() {
                    if let Some(x) = h_vel.get_mut(k, off) {
                        *x = T::of_f64(*a);
                    }
                }
                // the drift: dt = dt_0 + r (t_fix - t_0), so the rate column is the offset
                // column times t_fix - t_0
                if self == Self::ImuClockDrift {
                    let s = ctx.clock_span_s;
                    for (k, (v, a)) in ctx.v_ant_ned_mps.iter().zip(&ctx.acc_ned_mps2).enumerate() {
                        if let Some(x) = h_pos.get_mut(k, off + 1) {
                            *x = T::of_f64(*v * s);
                        }
                        if let Some(x) = h_vel.get_mut(k, off + 1) {
                            *x = T::of_f64(*a * s);
                        }
                    }
                }
            }
            // measured = true + e: dz_pos = +I de
            Self::GnssPositionGm => h_pos.set_block(off, &to_t(&IDENTITY3)),
            Self::AccelBias(_)
            | Self::AccelScaleFactor
            | Self::AccelMisalignment
            | Self::AccelTemperatureBias
            | Self::OdometerScale => {}
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
            | Self::ImuClockDrift
            | Self::GnssPositionGm
            | Self::AccelTemperatureBias
            | Self::GyroTemperatureBias
            | Self::GyroGSensitivity
            | Self::OdometerScale => {
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
    /// The fix's time tag minus the filter's start time `t_fix - t_0`, s (the IMU clock
    /// drift's rate column is its offset column times this).
    pub clock_span_s: f64,
}
