//! Odometer (wheel speed): the measured forward speed of a point on the vehicle (the rear-axle
//! centre for a wheel-speed sensor on the rear wheels) against the filter's velocity of that
//! point in the vehicle frame, with an optional scale-factor state
//! ([`crate::model::Block::OdometerScale`]). Derivation: `docs/derivations/odometer.md`.
//!
//! Vehicle frame: `x_b = C_bv x_v` with the mounting of [`super::NhcConfig::c_vb`] (one
//! vehicle frame for every constraint). With `C = C_b^n`, `l` the point's lever arm (body
//! axes) and `k` the scale-factor error (measured = (1 + k) true):
//!
//! `s_hat = (1 + k_hat) e_x^T C_vb (C^T v_n + w_b x l)`, residual `z = s_hat - s_measured`,
//! Jacobian (dx = estimate - truth)
//! `H_phi = -(1 + k) e_x^T C_vb C^T [v_n x]`, `H_dv = (1 + k) e_x^T C_vb C^T`,
//! `H_bg = (1 + k) e_x^T C_vb [l x]` (every gyro-bias group), `H_k = v_x^v`.

use super::nhc::put;
use crate::filter::dcm_f64;
use crate::model::{Block, Layout, IDX_ATT, IDX_VEL};
use crate::scalar::Scalar;
use crate::strapdown::{NavState, StepInfo};
use nalgebra::{Matrix3, Vector3};

/// Settings of the odometer update (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OdometerConfig {
    /// Use it (needs a speed at the aiding epochs, [`super::AidingInputs::odometer_speed_mps`]).
    pub enabled: bool,
    /// 1-sigma of a speed sample (quantisation, tyre deformation), m/s.
    pub sigma_mps: f64,
    /// The measured point (rear-axle centre) relative to the IMU, body axes, m.
    pub lever_arm_m: [f64; 3],
    /// Chi-square gate on the 1-dof NIS (dimensionless; infinite: none).
    pub nis_gate: f64,
}

impl OdometerConfig {
    /// Off; when on: 0.05 m/s, no lever arm, gate at chi-square(1) 0.9999 (15.14).
    pub const DEFAULT: Self = Self {
        enabled: false,
        sigma_mps: 0.05,
        lever_arm_m: [0.0; 3],
        nis_gate: 15.14,
    };
}

impl Default for OdometerConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The odometer measurement: residual, Jacobian row and variance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometerMeasurement<T: Scalar, const N: usize> {
    /// Predicted minus measured forward speed, m/s.
    pub z_mps: [f64; 1],
    /// Jacobian row.
    pub h: [[T; N]; 1],
    /// Variance, m^2/s^2.
    pub r: [f64; 1],
}

/// Forward (vehicle x) velocity of the odometer point, m/s, without the scale factor.
pub fn point_speed(
    cfg: &OdometerConfig,
    c_vb: &Matrix3<f64>,
    nav: &NavState,
    step: &StepInfo,
) -> f64 {
    let c = dcm_f64(&nav.q_nb);
    let l = Vector3::from(cfg.lever_arm_m);
    (c_vb * (c.transpose() * nav.vel_ned_mps + step.omega_ib_body_radps.cross(&l))).x
}

/// The odometer measurement for the filter's state and a measured speed `speed_mps`;
/// `scale_est` is the estimated scale-factor error `k_hat` (0 without the block; the Jacobian
/// gets the block's column when `layout` has it).
pub fn odometer_measurement<T: Scalar, const N: usize>(
    cfg: &OdometerConfig,
    c_vb: &Matrix3<f64>,
    layout: &Layout,
    scale_est: f64,
    nav: &NavState,
    step: &StepInfo,
    speed_mps: f64,
) -> OdometerMeasurement<T, N> {
    let c = dcm_f64(&nav.q_nb);
    let a = c_vb * c.transpose();
    let v = nav.vel_ned_mps;
    let g = 1.0 + scale_est;
    let h_phi = -(a * v.cross_matrix());
    let l = Vector3::from(cfg.lever_arm_m);
    let h_bg = c_vb * l.cross_matrix();
    let vx = point_speed(cfg, c_vb, nav, step);
    let mut h = [[T::ZERO; N]; 1];
    for row in h.iter_mut() {
        for j in 0..3 {
            put(
                row,
                IDX_ATT + j,
                g * h_phi.get((0, j)).copied().unwrap_or(0.0),
            );
            put(row, IDX_VEL + j, g * a.get((0, j)).copied().unwrap_or(0.0));
        }
        for (off, b) in layout.iter() {
            match b {
                Block::GyroBias(_) => {
                    for grp in 0..b.dim() / 3 {
                        for j in 0..3 {
                            let v = g * h_bg.get((0, j)).copied().unwrap_or(0.0);
                            put(row, off + 3 * grp + j, v);
                        }
                    }
                }
                Block::OdometerScale => put(row, off, vx),
                _ => {}
            }
        }
    }
    OdometerMeasurement {
        z_mps: [g * vx - speed_mps],
        h,
        r: [cfg.sigma_mps * cfg.sigma_mps],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::attitude::{dcm_from_euler_zyx, quat_from_rotvec};
    use crate::earth::Llh;
    use crate::model::{BlockKind, LAYOUT_N};

    /// z(estimate) - z(truth) against H dx for small errors of attitude, velocity, gyro bias
    /// and the scale factor (dx = estimate - truth; C_hat = (I - [phi x]) C, w_hat = w - db_g,
    /// k_hat = k + dk).
    #[test]
    fn odometer_jacobian_matches_finite_differences() {
        const L: Layout = LAYOUT_N.with(Block::OdometerScale);
        const N: usize = L.dim();
        let cfg = OdometerConfig {
            lever_arm_m: [-1.5, 0.2, 1.3],
            ..OdometerConfig::DEFAULT
        };
        let c_vb = dcm_from_euler_zyx([0.02, -0.03, 0.05]).transpose();
        let truth = NavState::from_rpy(
            0.0,
            Llh::from_deg(48.2, 16.37, 220.0),
            Vector3::new(9.0, -11.0, 0.3),
            [0.05, -0.02, 2.3],
        );
        let step = StepInfo {
            dt_s: 0.01,
            f_body_mps2: Vector3::new(0.5, 2.0, -9.8),
            omega_ib_body_radps: Vector3::new(0.02, -0.01, 0.25),
            f_ned_mps2: Vector3::zeros(),
        };
        let k_true = 0.02;
        let s_meas = (1.0 + k_true) * point_speed(&cfg, &c_vb, &truth, &step);
        let m = odometer_measurement::<f64, N>(&cfg, &c_vb, &L, k_true, &truth, &step, s_meas);
        assert!(m.z_mps[0].abs() < 1e-12, "{:?}", m.z_mps);
        let (off_bg, _) = L.find(BlockKind::GyroBias).unwrap();
        let (off_k, _) = L.find(BlockKind::OdometerScale).unwrap();
        for k in 0..10 {
            let (idx, eps) = match k {
                0..=2 => (IDX_ATT + k, 1e-6),
                3..=5 => (IDX_VEL + k - 3, 1e-4),
                6..=8 => (off_bg + k - 6, 1e-6),
                _ => (off_k, 1e-5),
            };
            let mut dx = [0.0f64; N];
            dx[idx] = eps;
            let mut est = truth;
            let phi = Vector3::new(dx[0], dx[1], dx[2]);
            est.q_nb = quat_from_rotvec(&(-phi)) * truth.q_nb;
            est.vel_ned_mps += Vector3::new(dx[3], dx[4], dx[5]);
            let mut st = step;
            st.omega_ib_body_radps -= Vector3::new(dx[off_bg], dx[off_bg + 1], dx[off_bg + 2]);
            let m1 = odometer_measurement::<f64, N>(
                &cfg,
                &c_vb,
                &L,
                k_true + dx[off_k],
                &est,
                &st,
                s_meas,
            );
            let dz = m1.z_mps[0] - m.z_mps[0];
            let pred: f64 = m.h[0].iter().zip(dx.iter()).map(|(h, d)| h * d).sum();
            assert!(
                (pred - dz).abs() < 1e-3 * eps.max(dz.abs()) + 1e-12,
                "state {idx}: H dx {pred} vs dz {dz}"
            );
        }
        assert_eq!(m.r, [0.05 * 0.05]);
    }
}
