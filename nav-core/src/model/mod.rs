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

pub mod core_f;
pub mod discrete;

use crate::config::{FilterConfig, SensorNoise};
use crate::scalar::Scalar;

/// Dimension of the core error state (attitude, velocity, position).
pub const CORE_DIM: usize = 9;
/// Index of the attitude error phi (N, E, D), rad.
pub const IDX_ATT: usize = 0;
/// Index of the NED velocity error, m/s.
pub const IDX_VEL: usize = 3;
/// Index of the NED position error, m.
pub const IDX_POS: usize = 6;
/// Largest number of blocks in a layout.
pub const MAX_BLOCKS: usize = 16;

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
}

impl Block {
    /// Number of error states of the block.
    pub const fn dim(self) -> usize {
        match self {
            Self::Core => CORE_DIM,
            Self::GyroBias(m) | Self::AccelBias(m) => m.dim(),
            Self::GyroScaleFactor | Self::AccelScaleFactor => 3,
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
        }
    }

    /// Which IMU quantity (sum over the block's 3-state groups) the block estimates, if any.
    pub const fn quantity(self) -> Option<BlockKind> {
        match self {
            Self::Core => None,
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
            Self::AccelBias(_) | Self::AccelScaleFactor => {}
        }
    }

    /// Closed-loop feedback of the block's estimated error `dx` into its estimate `est`
    /// (both `dim()` long): `est <- est - dx` for additive sensor errors.
    pub fn feedback(self, est: &mut [f64], dx: &[f64]) {
        match self {
            Self::Core => {}
            Self::GyroBias(_)
            | Self::AccelBias(_)
            | Self::GyroScaleFactor
            | Self::AccelScaleFactor => {
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

/// The IMU error estimates applied to a raw sample before mechanisation:
/// `w = (w_meas - b_g) / (1 + s_g)`, `f = (f_meas - b_a) / (1 + s_a)` per axis.
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
}

impl ImuCorrection {
    /// Corrects increments over `dt_s` seconds in place.
    pub fn apply(&self, dtheta_rad: &mut [f64; 3], dv_mps: &mut [f64; 3], dt_s: f64) {
        self.apply_with(&self.inverse_scales(), dtheta_rad, dv_mps, dt_s);
    }

    /// `1 / (1 + s)` for the gyro and accelerometer scale-factor errors (computed once per
    /// change of the estimates, so the per-epoch correction needs no division).
    pub fn inverse_scales(&self) -> InverseScales {
        InverseScales {
            gyro: self.gyro_scale.map(|s| 1.0 / (1.0 + s)),
            accel: self.accel_scale.map(|s| 1.0 / (1.0 + s)),
        }
    }

    /// [`Self::apply`] with precomputed [`Self::inverse_scales`].
    pub fn apply_with(
        &self,
        inv: &InverseScales,
        dtheta_rad: &mut [f64; 3],
        dv_mps: &mut [f64; 3],
        dt_s: f64,
    ) {
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
    }
}

/// Reciprocal scale factors `1 / (1 + s)` of an [`ImuCorrection`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseScales {
    /// Gyro x, y, z.
    pub gyro: [f64; 3],
    /// Accelerometer x, y, z.
    pub accel: [f64; 3],
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
    /// Sensor temperature, deg C (NaN when absent).
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
