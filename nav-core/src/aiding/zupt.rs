//! Zero-velocity (ZUPT) and zero-angular-rate (ZARU) updates at stops, applied when the
//! stationarity detector ([`super::stationarity`]) declares the vehicle still. Derivation:
//! `docs/derivations/zupt_zaru.md`.
//!
//! * ZUPT: the NED velocity of the IMU is zero: `z = v_hat_n`, `H_dv = I`.
//! * ZARU: the body's rate is the earth's: `z = mean(w_hat_b) - C^T w_ie^n` over the
//!   detector's window, `H_bg = -I` on every gyro-bias group (`w_hat = w - db_g`); the
//!   attitude term `C^T [w_ie x] phi` is below 1e-8 rad/s per mrad and left out.

use super::nhc::put;
use crate::earth;
use crate::filter::dcm_f64;
use crate::model::{Block, Layout, IDX_VEL};
use crate::scalar::Scalar;
use crate::strapdown::NavState;
use nalgebra::Vector3;

/// Settings of the zero-velocity update (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ZuptConfig {
    /// Use it.
    pub enabled: bool,
    /// 1-sigma of the residual velocity at a stop (engine vibration, rocking), m/s.
    pub sigma_mps: f64,
    /// Chi-square gate on the 3-dof NIS (infinite: none).
    pub nis_gate: f64,
}

impl ZuptConfig {
    /// Off; when on: 0.02 m/s, gate chi-square(3) 0.9999 (21.11).
    pub const DEFAULT: Self = Self {
        enabled: false,
        sigma_mps: 0.02,
        nis_gate: 21.11,
    };
}

impl Default for ZuptConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Settings of the zero-angular-rate update (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ZaruConfig {
    /// Use it (needs a gyro-bias block in the layout).
    pub enabled: bool,
    /// 1-sigma of the window-mean rate at a stop, rad/s. [`super::Aiding`] makes the update
    /// only at a quiet stop: the window's rate spread within the detector's fixed
    /// `gyro_std_max_radps` (an idling engine's vibration shifts a MEMS gyro's mean rate).
    pub sigma_radps: f64,
    /// Chi-square gate on the 3-dof NIS (infinite: none).
    pub nis_gate: f64,
}

impl ZaruConfig {
    /// Off; when on: 0.01 deg/s, gate chi-square(3) 0.9999 (21.11).
    pub const DEFAULT: Self = Self {
        enabled: false,
        sigma_radps: 0.01 * core::f64::consts::PI / 180.0,
        nis_gate: 21.11,
    };
}

impl Default for ZaruConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// ZUPT residual (NED velocity, m/s), Jacobian and variances (m^2/s^2).
pub fn zupt_measurement<T: Scalar, const N: usize>(
    cfg: &ZuptConfig,
    nav: &NavState,
) -> ([f64; 3], [[T; N]; 3], [f64; 3]) {
    let mut h = [[T::ZERO; N]; 3];
    for (j, row) in h.iter_mut().enumerate() {
        put(row, IDX_VEL + j, 1.0);
    }
    let v = nav.vel_ned_mps;
    let r = cfg.sigma_mps * cfg.sigma_mps;
    ([v.x, v.y, v.z], h, [r; 3])
}

/// ZARU residual (body rate minus earth rate, rad/s) from the window-mean corrected rate,
/// Jacobian and variances (rad^2/s^2); None when the layout has no gyro bias.
#[allow(clippy::type_complexity)]
pub fn zaru_measurement<T: Scalar, const N: usize>(
    cfg: &ZaruConfig,
    layout: &Layout,
    nav: &NavState,
    w_mean_radps: &[f64; 3],
) -> Option<([f64; 3], [[T; N]; 3], [f64; 3])> {
    let mut h = [[T::ZERO; N]; 3];
    let mut any = false;
    for (off, b) in layout.iter() {
        if let Block::GyroBias(_) = b {
            any = true;
            for g in 0..b.dim() / 3 {
                for (j, row) in h.iter_mut().enumerate() {
                    put(row, off + 3 * g + j, -1.0);
                }
            }
        }
    }
    if !any {
        return None;
    }
    let c = dcm_f64(&nav.q_nb);
    let w_ie_b = c.transpose() * earth::earth_rate_ned_radps(nav.pos.lat_rad);
    let z = Vector3::from(*w_mean_radps) - w_ie_b;
    let r = cfg.sigma_radps * cfg.sigma_radps;
    Some(([z.x, z.y, z.z], h, [r; 3]))
}
