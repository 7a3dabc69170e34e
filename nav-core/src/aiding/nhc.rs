//! Non-holonomic constraint (NHC): a land vehicle neither slides sideways nor leaves the road,
//! so the lateral and vertical velocity of a point on its rear axle, in the vehicle frame, are
//! near zero. Derivation: `docs/derivations/nhc.md`.
//!
//! Vehicle frame: `x_b = C_bv x_v` with `C_bv` the configured mounting rotation (ZYX Euler
//! angles, vehicle to body; zero when the body frame already is the vehicle frame). The
//! constraint point is `lever_arm_m` from the IMU, body axes. With `C = C_b^n`:
//!
//! `v_p^v = C_vb (C^T v_n + w_b x l)`, residual `z = [v_p^v_y, v_p^v_z]` (predicted minus the
//! measured zero), Jacobian
//! `H_phi = -C_vb C^T [v_n x]`, `H_dv = C_vb C^T`, `H_bg = C_vb [l x]` (every gyro-bias group).

use crate::attitude::dcm_from_euler_zyx;
use crate::filter::dcm_f64;
use crate::model::{Block, Layout, IDX_ATT, IDX_VEL};
use crate::scalar::Scalar;
use crate::strapdown::{NavState, StepInfo};
use nalgebra::{Matrix3, Vector3};

/// Settings of the non-holonomic constraint (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NhcConfig {
    /// Use the constraint.
    pub enabled: bool,
    /// 1-sigma of the lateral velocity of the constraint point (side slip), m/s.
    pub sigma_lateral_mps: f64,
    /// 1-sigma of the vertical velocity (bounce), m/s.
    pub sigma_vertical_mps: f64,
    /// Lowest speed at which the constraint is applied, m/s (below it the heading is poorly
    /// defined by the motion; the zero-velocity update takes over at stops).
    pub min_speed_mps: f64,
    /// Mounting rotation vehicle to body, ZYX Euler `[roll, pitch, yaw]`, rad
    /// (`x_body = C_bv x_vehicle`).
    pub mount_rpy_rad: [f64; 3],
    /// The constraint point (rear-axle centre) relative to the IMU, body axes, m.
    pub lever_arm_m: [f64; 3],
    /// 1-sigma of the side-slip angle per m/s^2 of lateral acceleration, rad per m/s^2: the
    /// lateral variance grows by `(speed * slip_sigma * a_lat)^2` with `a_lat = speed * yaw
    /// rate` (tyres slip in turns; 0: a fixed sigma).
    pub slip_sigma_rad_per_mps2: f64,
    /// Chi-square gate on the 2-dof NIS (dimensionless; infinite: none).
    pub nis_gate: f64,
}

impl NhcConfig {
    /// Off; when switched on: 0.1 m/s lateral, 0.05 m/s vertical, from 1 m/s, no mounting
    /// rotation or lever arm, gate at chi-square(2) 0.9999 (18.42).
    pub const DEFAULT: Self = Self {
        enabled: false,
        sigma_lateral_mps: 0.1,
        sigma_vertical_mps: 0.05,
        min_speed_mps: 1.0,
        mount_rpy_rad: [0.0; 3],
        lever_arm_m: [0.0; 3],
        slip_sigma_rad_per_mps2: 0.0,
        nis_gate: 18.42,
    };

    /// `C_vb` (body to vehicle), row-major.
    pub fn c_vb(&self) -> Matrix3<f64> {
        dcm_from_euler_zyx(self.mount_rpy_rad).transpose()
    }
}

impl Default for NhcConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The NHC measurement: residual, Jacobian rows and variances.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NhcMeasurement<T: Scalar, const N: usize> {
    /// Predicted minus measured (zero) lateral and vertical velocity of the point, m/s.
    pub z_mps: [f64; 2],
    /// Jacobian rows (lateral, vertical).
    pub h: [[T; N]; 2],
    /// Variances, m^2/s^2.
    pub r: [f64; 2],
}

/// Measurement check: the constraint applies when on and the vehicle moves at least
/// `min_speed_mps` (and is not declared stationary).
pub fn nhc_applies(cfg: &NhcConfig, nav: &NavState, stationary: bool) -> bool {
    cfg.enabled && !stationary && nav.vel_ned_mps.norm() >= cfg.min_speed_mps
}

/// Velocity of the constraint point in the vehicle frame, m/s.
pub fn point_velocity_vehicle(cfg: &NhcConfig, nav: &NavState, step: &StepInfo) -> Vector3<f64> {
    let c = dcm_f64(&nav.q_nb);
    let l = Vector3::from(cfg.lever_arm_m);
    cfg.c_vb() * (c.transpose() * nav.vel_ned_mps + step.omega_ib_body_radps.cross(&l))
}

/// The NHC measurement for the filter's state (fusion maths; no checks).
pub fn nhc_measurement<T: Scalar, const N: usize>(
    cfg: &NhcConfig,
    layout: &Layout,
    nav: &NavState,
    step: &StepInfo,
) -> NhcMeasurement<T, N> {
    let c = dcm_f64(&nav.q_nb);
    let cvb = cfg.c_vb();
    let a = cvb * c.transpose();
    let v = nav.vel_ned_mps;
    let h_phi = -(a * v.cross_matrix());
    let l = Vector3::from(cfg.lever_arm_m);
    let h_bg = cvb * l.cross_matrix();
    let vp = point_velocity_vehicle(cfg, nav, step);
    let mut h = [[T::ZERO; N]; 2];
    for (k, row) in h.iter_mut().enumerate() {
        let r = k + 1; // vehicle y (lateral), z (vertical)
        for j in 0..3 {
            put(row, IDX_ATT + j, m3(&h_phi, r, j));
            put(row, IDX_VEL + j, m3(&a, r, j));
        }
        for (off, b) in layout.iter() {
            if let Block::GyroBias(_) = b {
                for g in 0..b.dim() / 3 {
                    for j in 0..3 {
                        put(row, off + 3 * g + j, m3(&h_bg, r, j));
                    }
                }
            }
        }
    }
    // side slip: a_lat = speed * yaw rate (body z), slip sigma proportional to it
    let speed = v.norm();
    let a_lat = speed * step.omega_ib_body_radps.z;
    let slip_v = speed * cfg.slip_sigma_rad_per_mps2 * a_lat;
    NhcMeasurement {
        z_mps: [vp.y, vp.z],
        h,
        r: [
            cfg.sigma_lateral_mps * cfg.sigma_lateral_mps + slip_v * slip_v,
            cfg.sigma_vertical_mps * cfg.sigma_vertical_mps,
        ],
    }
}

/// Element (r, c) of a 3x3 matrix (0 outside).
fn m3(m: &Matrix3<f64>, r: usize, c: usize) -> f64 {
    m.get((r, c)).copied().unwrap_or(0.0)
}

pub(crate) fn put<T: Scalar, const N: usize>(row: &mut [T; N], i: usize, v: f64) {
    if let Some(x) = row.get_mut(i) {
        *x = T::of_f64(v);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::attitude::quat_from_rotvec;
    use crate::earth::Llh;
    use crate::model::LAYOUT_N;

    /// z(estimate) - z(truth) against H dx for small errors of attitude, velocity and gyro bias
    /// (dx = estimate - truth; C_hat = (I - [phi x]) C, w_hat = w - db_g).
    #[test]
    fn nhc_jacobian_matches_finite_differences() {
        let mut cfg = NhcConfig::DEFAULT;
        cfg.mount_rpy_rad = [0.02, -0.03, 0.05];
        cfg.lever_arm_m = [-1.2, 0.1, 1.4];
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
        let z0 = point_velocity_vehicle(&cfg, &truth, &step);
        let m = nhc_measurement::<f64, 15>(&cfg, &LAYOUT_N, &truth, &step);
        assert!((m.z_mps[0] - z0.y).abs() < 1e-12 && (m.z_mps[1] - z0.z).abs() < 1e-12);
        let (off_bg, _) = LAYOUT_N.find(crate::model::BlockKind::GyroBias).unwrap();
        for k in 0..9 {
            let eps = if k < 3 {
                1e-6
            } else if k < 6 {
                1e-4
            } else {
                1e-6
            };
            let mut dx = [0.0f64; 15];
            let idx = match k {
                0..=2 => IDX_ATT + k,
                3..=5 => IDX_VEL + k - 3,
                _ => off_bg + k - 6,
            };
            dx[idx] = eps;
            let mut est = truth;
            let phi = Vector3::new(dx[0], dx[1], dx[2]);
            est.q_nb = quat_from_rotvec(&(-phi)) * truth.q_nb;
            est.vel_ned_mps += Vector3::new(dx[3], dx[4], dx[5]);
            let mut st = step;
            st.omega_ib_body_radps -= Vector3::new(dx[off_bg], dx[off_bg + 1], dx[off_bg + 2]);
            let z1 = point_velocity_vehicle(&cfg, &est, &st);
            for (row, dz) in m.h.iter().zip([z1.y - z0.y, z1.z - z0.z]) {
                let pred: f64 = row.iter().zip(dx.iter()).map(|(h, d)| h * d).sum();
                assert!(
                    (pred - dz).abs() < 1e-3 * eps.max(dz.abs()) + 1e-12,
                    "state {idx}: H dx {pred} vs dz {dz}"
                );
            }
        }
        // variances: the lateral one grows with the side slip
        let mut c2 = cfg;
        c2.slip_sigma_rad_per_mps2 = 0.3f64.to_radians();
        let m2 = nhc_measurement::<f64, 15>(&c2, &LAYOUT_N, &truth, &step);
        assert!(m2.r[0] > m.r[0] && m2.r[1] == m.r[1]);
    }
}
