//! Dual-antenna GNSS heading: a receiver with two antennas measures the azimuth (from north,
//! clockwise) of the baseline between them. The baseline is fixed in the body frame
//! (`baseline_m`, primary to secondary antenna, body FRD), so its azimuth is a function of the
//! attitude alone. Derivation: `docs/derivations/heading.md`.
//!
//! With `C = C_b^n` and `b_n = C b = [n, e, d]`: `psi_hat = atan2(e, n)`, residual
//! `z = wrap(psi_hat - psi_measured)` in `(-pi, pi]`, Jacobian (dx = estimate - truth,
//! `C_hat = (I - [phi x]) C`)
//!
//! `H_phi = [n d, e d, -(n^2 + e^2)] / (n^2 + e^2)`, every other state 0.
//!
//! A baseline along the body x axis on a level vehicle gives `H_phi = [0, 0, -1]`: the
//! heading observes the yaw error directly, whatever the motion (at rest, straight at
//! constant speed) where GNSS positions alone observe it poorly.

use crate::filter::dcm_f64;
use crate::model::IDX_ATT;
use crate::scalar::Scalar;
use crate::strapdown::NavState;
use nalgebra::Vector3;

/// Settings of the dual-antenna heading update (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HeadingConfig {
    /// Use it (needs heading samples, [`super::Aiding::on_heading`]).
    pub enabled: bool,
    /// The baseline from the primary to the secondary antenna, body FRD axes, m (only its
    /// direction matters; its horizontal part must not vanish).
    pub baseline_m: [f64; 3],
    /// 1-sigma of a heading sample when the sample has none, rad.
    pub sigma_rad: f64,
    /// Chi-square gate on the 1-dof NIS (dimensionless; infinite: none).
    pub nis_gate: f64,
}

impl HeadingConfig {
    /// Off; when on: baseline along the body x axis (1 m), 0.5 deg, gate at chi-square(1)
    /// 0.9999 (15.14).
    pub const DEFAULT: Self = Self {
        enabled: false,
        baseline_m: [1.0, 0.0, 0.0],
        sigma_rad: 0.5 * core::f64::consts::PI / 180.0,
        nis_gate: 15.14,
    };
}

impl Default for HeadingConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Smallest horizontal fraction `sqrt(n^2 + e^2) / |b|` of the baseline in the navigation
/// frame at which the heading is used (below it the azimuth is ill-defined: the vehicle
/// stands on its end).
pub const MIN_HORIZONTAL_FRACTION: f64 = 0.1;

/// The heading measurement: residual, Jacobian row and variance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingMeasurement<T: Scalar, const N: usize> {
    /// Predicted minus measured azimuth of the baseline, wrapped to (-pi, pi], rad.
    pub z_rad: [f64; 1],
    /// Jacobian row.
    pub h: [[T; N]; 1],
    /// Variance, rad^2.
    pub r: [f64; 1],
}

/// Azimuth of the baseline in the navigation frame for the attitude of `nav`, rad in
/// (-pi, pi], with its horizontal fraction (see [`MIN_HORIZONTAL_FRACTION`]).
pub fn baseline_azimuth(cfg: &HeadingConfig, nav: &NavState) -> (f64, f64) {
    let b = Vector3::from(cfg.baseline_m);
    let bn = dcm_f64(&nav.q_nb) * b;
    let h = libm::hypot(bn.x, bn.y);
    let len = b.norm();
    let frac = if len > 0.0 { h / len } else { 0.0 };
    (libm::atan2(bn.y, bn.x), frac)
}

/// `a - b` wrapped to [-pi, pi], rad.
pub fn wrap_angle_diff(a: f64, b: f64) -> f64 {
    libm::remainder(a - b, 2.0 * core::f64::consts::PI)
}

/// The heading measurement for the filter's attitude and a measured azimuth `heading_rad`
/// with its 1-sigma `sigma_rad` (the configured sigma when `None`). `None` when the baseline
/// is nearly vertical in the navigation frame, or the heading or sigma is not finite (or the
/// sigma not positive).
pub fn heading_measurement<T: Scalar, const N: usize>(
    cfg: &HeadingConfig,
    nav: &NavState,
    heading_rad: f64,
    sigma_rad: Option<f64>,
) -> Option<HeadingMeasurement<T, N>> {
    let sigma = sigma_rad.unwrap_or(cfg.sigma_rad);
    if !(heading_rad.is_finite() && sigma.is_finite() && sigma > 0.0) {
        return None;
    }
    let bn = dcm_f64(&nav.q_nb) * Vector3::from(cfg.baseline_m);
    let (psi_hat, frac) = baseline_azimuth(cfg, nav);
    // NaN (a non-finite attitude) fails too
    if frac.is_nan() || frac < MIN_HORIZONTAL_FRACTION {
        return None;
    }
    let (n, e, d) = (bn.x, bn.y, bn.z);
    let h2 = n * n + e * e;
    let mut h = [[T::ZERO; N]; 1];
    for row in h.iter_mut() {
        for (j, v) in [n * d / h2, e * d / h2, -1.0].into_iter().enumerate() {
            if let Some(x) = row.get_mut(IDX_ATT + j) {
                *x = T::of_f64(v);
            }
        }
    }
    Some(HeadingMeasurement {
        z_rad: [wrap_angle_diff(psi_hat, heading_rad)],
        h,
        r: [sigma * sigma],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::attitude::quat_from_rotvec;
    use crate::earth::Llh;

    fn nav(rpy: [f64; 3]) -> NavState {
        NavState::from_rpy(
            0.0,
            Llh::from_deg(48.2, 16.37, 220.0),
            Vector3::new(9.0, -11.0, 0.3),
            rpy,
        )
    }

    /// z(estimate) - z(truth) against H phi for small attitude errors (C_hat = (I - [phi x]) C),
    /// on a tilted vehicle with a baseline that is not along an axis.
    #[test]
    fn heading_jacobian_matches_finite_differences() {
        let cfg = HeadingConfig {
            enabled: true,
            baseline_m: [1.2, -0.4, 0.3],
            ..HeadingConfig::DEFAULT
        };
        let truth = nav([0.15, -0.2, 2.9]);
        let (psi, _) = baseline_azimuth(&cfg, &truth);
        let m = heading_measurement::<f64, 15>(&cfg, &truth, psi, None).unwrap();
        assert!(m.z_rad[0].abs() < 1e-12);
        assert!((m.r[0] - cfg.sigma_rad * cfg.sigma_rad).abs() < 1e-18);
        for k in 0..3 {
            let eps = 1e-6;
            let mut phi = Vector3::zeros();
            phi[k] = eps;
            let mut est = truth;
            est.q_nb = quat_from_rotvec(&(-phi)) * truth.q_nb;
            let m1 = heading_measurement::<f64, 15>(&cfg, &est, psi, None).unwrap();
            let dz = m1.z_rad[0] - m.z_rad[0];
            let pred = m.h[0][IDX_ATT + k] * eps;
            assert!(
                (pred - dz).abs() < 1e-4 * eps,
                "phi {k}: H phi {pred} vs dz {dz}"
            );
        }
        for v in &m.h[0][IDX_ATT + 3..] {
            assert_eq!(*v, 0.0);
        }
    }

    /// Level, baseline along x: the residual is the yaw difference, wrapped across +-180 deg;
    /// a vertical baseline and a bad sigma give no measurement.
    #[test]
    fn heading_residual_wraps_and_degenerate_cases_are_refused() {
        let cfg = HeadingConfig {
            enabled: true,
            ..HeadingConfig::DEFAULT
        };
        let yaw = 179.0f64.to_radians();
        let m =
            heading_measurement::<f64, 15>(&cfg, &nav([0.0, 0.0, yaw]), -179f64.to_radians(), None)
                .unwrap();
        assert!(
            (m.z_rad[0] + 2f64.to_radians()).abs() < 1e-12,
            "{}",
            m.z_rad[0]
        );
        assert!((m.h[0][IDX_ATT + 2] + 1.0).abs() < 1e-12);
        assert!(m.h[0][IDX_ATT].abs() < 1e-12 && m.h[0][IDX_ATT + 1].abs() < 1e-12);
        let up = HeadingConfig {
            baseline_m: [0.0, 0.0, -1.0],
            ..cfg
        };
        assert!(heading_measurement::<f64, 15>(&up, &nav([0.0; 3]), 0.0, None).is_none());
        assert!(heading_measurement::<f64, 15>(&cfg, &nav([0.0; 3]), 0.0, Some(0.0)).is_none());
        assert!(heading_measurement::<f64, 15>(&cfg, &nav([0.0; 3]), f64::NAN, None).is_none());
        let with_sigma =
            heading_measurement::<f32, 15>(&cfg, &nav([0.0; 3]), 0.1, Some(0.02)).unwrap();
        assert!((with_sigma.r[0] - 4e-4).abs() < 1e-15);
        assert!((with_sigma.z_rad[0] + 0.1).abs() < 1e-12);
    }
}
