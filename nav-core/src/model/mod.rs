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
//! # Adding a block (the effects)
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
//! [`Block::TimeOffset`], [`Block::AccelTemperatureBias`], [`Block::GyroTemperatureBias`],
//! [`Block::GyroGSensitivity`], [`Block::ImuClockDrift`] (a time offset growing with an IMU
//! clock's frequency error; it replaces `TimeOffset`) and [`Block::GnssPositionGm`] (a
//! time-correlated GNSS position error). Add any subset to a base layout at compile time:
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

mod blocks;
pub(crate) mod core_f;
mod corrections;
pub mod discrete;
pub(crate) mod effects;
mod layouts;

pub use blocks::*;
pub use corrections::*;
pub use layouts::*;

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
/// Largest number of blocks in a layout (the 5 blocks of the KF-GINS layout plus all 11
/// effect blocks; `time_offset` and `imu_clock_drift` exclude each other).
pub const MAX_BLOCKS: usize = 16;
/// Largest dimension of one block (the core's 9).
pub const MAX_BLOCK_DIM: usize = CORE_DIM;

// ---- small fixed-size helpers (no indexing, no panics) ----

/// 3x3 identity.
pub(crate) const IDENTITY3: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// Skew-symmetric matrix `[v x]` (row-major), so `[v x] w = v x w`.
pub(crate) fn skew(v: &[f64; 3]) -> [[f64; 3]; 3] {
    let [x, y, z] = *v;
    [[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]]
}

/// Converts a 3x3 f64 matrix to the scalar type.
pub(crate) fn to_t<T: Scalar>(m: &[[f64; 3]; 3]) -> [[T; 3]; 3] {
    m.map(|r| r.map(T::of_f64))
}

/// `m * s`.
pub(crate) fn scale3<T: Scalar>(m: &[[T; 3]; 3], s: T) -> [[T; 3]; 3] {
    m.map(|r| r.map(|v| v * s))
}

/// `m * diag(d)` (scales column j by d[j]).
pub(crate) fn mul_diag3<T: Copy + core::ops::Mul<Output = T>>(
    m: &[[T; 3]; 3],
    d: &[T; 3],
) -> [[T; 3]; 3] {
    m.map(|r| {
        let [a, b, c] = r;
        let [x, y, z] = *d;
        [a * x, b * y, c * z]
    })
}

/// Adds the 3x3 `m` into `dst` at (row0, col0); entries outside `dst` are ignored.
pub(crate) fn add3<T: Scalar, const R: usize, const C: usize>(
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
pub(crate) fn set3<T: Scalar, const R: usize, const C: usize>(
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

/// Three rows of a measurement Jacobian (`[[T; N]; 3]`, row-major) seen as one slice with the
/// number of columns a runtime value: code that fills Jacobian columns through it is one
/// instance per scalar type whatever the state dimension N (flash: a binary may carry several
/// filter sizes). Writes outside the rows or columns are ignored.
pub struct Rows3<'a, T> {
    data: &'a mut [T],
    cols: usize,
}

impl<'a, T: Scalar> Rows3<'a, T> {
    /// The view of `m` (3 rows of N columns).
    pub fn new<const N: usize>(m: &'a mut [[T; N]; 3]) -> Self {
        Self {
            data: m.as_flattened_mut(),
            cols: N,
        }
    }

    /// Number of columns (the state dimension).
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Entry (row `r`, column `c`), or None outside the rows or columns.
    pub fn get_mut(&mut self, r: usize, c: usize) -> Option<&mut T> {
        if c >= self.cols {
            return None;
        }
        // r < 3 and c < cols: r * cols + c < data.len() = 3 cols (no overflow)
        if r >= 3 {
            return None;
        }
        self.data.get_mut(r * self.cols + c)
    }

    /// Writes the 3 x K `m` at column `col0` (rows 0..3).
    pub fn set_block<const K: usize>(&mut self, col0: usize, m: &[[T; K]; 3]) {
        for (r, m_row) in m.iter().enumerate() {
            for (k, v) in m_row.iter().enumerate() {
                if let Some(d) = self.get_mut(r, col0 + k) {
                    *d = *v;
                }
            }
        }
    }

    /// Adds the 3 x K `m` at column `col0` (rows 0..3).
    pub fn add_block<const K: usize>(&mut self, col0: usize, m: &[[T; K]; 3]) {
        for (r, m_row) in m.iter().enumerate() {
            for (k, v) in m_row.iter().enumerate() {
                if let Some(d) = self.get_mut(r, col0 + k) {
                    *d += *v;
                }
            }
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
        let names: heapless::Vec<&str, 11> = EFFECT_BLOCKS.iter().map(|b| b.name()).collect();
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
                "imu_clock_drift",
                "gnss_position_gm",
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

    #[test]
    fn rows3_writes_like_set3_and_add3_and_ignores_outside_columns() {
        let m = [[1.0f32, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]];
        // blocks at 1 (inside) and at 3 (two of three columns outside a 4-column matrix)
        for col0 in [1usize, 3] {
            let mut a = [[0.5f32; 4]; 3];
            let mut b = a;
            set3(&mut a, 0, col0, &m);
            add3(&mut a, 0, col0, &m);
            let mut v = Rows3::new(&mut b);
            assert_eq!(v.cols(), 4);
            v.set_block(col0, &m);
            v.add_block(col0, &m);
            assert_eq!(a, b, "block at column {col0}");
        }
        let mut c = [[0.0f32; 4]; 3];
        let mut v = Rows3::new(&mut c);
        assert!(v.get_mut(3, 0).is_none());
        assert!(v.get_mut(0, 4).is_none());
        if let Some(x) = v.get_mut(2, 3) {
            *x = 7.0;
        }
        assert_eq!(c[2][3], 7.0);
        assert_eq!(c.iter().flatten().filter(|x| **x != 0.0).count(), 1);
    }
}
