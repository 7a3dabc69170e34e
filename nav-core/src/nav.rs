//! The nominal navigation state and the strapdown mechanization on IMU increments (NED,
//! quaternion attitude). Everything here is `f64`.
//!
//! The interface is fixed (the filter and the tools use it); the integration algorithm inside
//! [`Strapdown::update`] is free to improve.

use crate::attitude;
use crate::earth::{self, Llh};
use crate::types::ImuSample;
use libm::{cos, sin, sqrt};
use nalgebra::{UnitQuaternion, Vector3};

/// Nominal navigation state at the IMU reference point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavState {
    /// GPS seconds of week of this state, s.
    pub t_s: f64,
    /// Geodetic position.
    pub pos: Llh,
    /// Velocity relative to the earth in NED, m/s.
    pub vel_ned_mps: Vector3<f64>,
    /// Attitude: rotates body (FRD) vectors into NED, `v_ned = q_nb * v_body` (C_b^n).
    pub q_nb: UnitQuaternion<f64>,
}

impl NavState {
    /// Roll, pitch, yaw (ZYX Euler angles of the body relative to NED), rad; roll and yaw in
    /// (-pi, pi], pitch in [-pi/2, pi/2] (see [`attitude::euler_zyx_from_quat`] for gimbal lock).
    pub fn rpy_rad(&self) -> [f64; 3] {
        attitude::euler_zyx_from_quat(&self.q_nb)
    }

    /// A state from position, NED velocity and roll/pitch/yaw in radians.
    pub fn from_rpy(t_s: f64, pos: Llh, vel_ned_mps: Vector3<f64>, rpy_rad: [f64; 3]) -> Self {
        Self {
            t_s,
            pos,
            vel_ned_mps,
            q_nb: attitude::quat_from_euler_zyx(rpy_rad),
        }
    }
}

/// Errors of the mechanization (the state is left unchanged when one is returned).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MechError {
    /// An increment or the time is NaN or infinite.
    NonFinite,
    /// The sample's time is not after the current state's time, or the step is longer than
    /// [`MAX_DT_S`].
    BadTimeStep,
}

impl core::fmt::Display for MechError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NonFinite => f.write_str("IMU sample has a non-finite time or increment"),
            Self::BadTimeStep => {
                f.write_str("IMU sample time is not increasing or the gap is too long")
            }
        }
    }
}

/// Longest IMU interval the mechanization accepts, s.
pub const MAX_DT_S: f64 = 1.0;

/// What one mechanization step saw, for the error-state model (F and G matrices) and for
/// regressors of effect blocks.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepInfo {
    /// Length of the interval, s.
    pub dt_s: f64,
    /// Mean specific force over the interval in body axes, m/s^2 (dv / dt).
    pub f_body_mps2: Vector3<f64>,
    /// Mean angular rate (inertial) over the interval in body axes, rad/s (dtheta / dt).
    pub omega_ib_body_radps: Vector3<f64>,
    /// Mean specific force over the interval in NED, m/s^2.
    pub f_ned_mps2: Vector3<f64>,
}

/// Strapdown inertial navigation on IMU increments in the local-level NED frame, quaternion
/// attitude, `f64` throughout.
///
/// # Algorithm (one [`update`](Strapdown::update), interval (t_{k-1}, t_k], length dt)
///
/// The formulation is Savage's / Groves' single-speed increment form, as in KF-GINS:
///
/// 1. **Body frame.** Rotation vector of the body over the interval with the two-sample coning
///    correction from the previous increment, `phi = dtheta + dtheta_prev x dtheta / 12`, and
///    the velocity increment in the body frame at t_{k-1} with rotation compensation (to
///    second order) and two-sample sculling: `dv_b = dv + dtheta x dv / 2 +
///    dtheta x (dtheta x dv) / 6 + (dtheta_prev x dv + dv_prev x dtheta) / 12` (see
///    [`attitude::sculled_dv`]). The two-sample terms are exact for rates and specific forces
///    varying linearly over the two intervals; the residual coning drift for a coning motion of half-angle `alpha` and frequency `W` is
///    `alpha^2 W (W dt)^4 / 60` (rad/s). The previous increments are used only when the
///    previous interval was between half and twice the current one (otherwise, and on the
///    first sample after [`new`](Strapdown::new), the two-sample terms are zero).
/// 2. **Mid-interval extrapolation.** Velocity, height and latitude at t_{k-1/2} are
///    extrapolated from the start values, the body increment rotated into NED and the gravity /
///    Coriolis acceleration of the previous step (an error in that cached value, e.g. after a
///    large reset through [`state_mut`](Strapdown::state_mut), only affects one step at second
///    order). At the mid-interval position: radii of curvature, Somigliana gravity, earth rate
///    omega_ie^n and transport rate omega_en^n (one `sin`, one `cos`, one `sqrt`).
/// 3. **Velocity.** `dv_n = (I - [zeta x] / 2) C_b^n(t_{k-1}) dv_b` with
///    `zeta = (omega_ie^n + omega_en^n) dt` (rotation of the navigation frame over the
///    interval), then `v_k = v_{k-1} + dv_n + (g^n - (2 omega_ie^n + omega_en^n) x v_mid) dt`.
/// 4. **Position**, with the trapezoid velocity `v_bar = (v_{k-1} + v_k) / 2`: height first
///    (`h_k = h_{k-1} - v_bar_D dt`), then latitude with the meridian radius at the mid height,
///    then longitude with the transverse radius and `cos` of the mid latitude.
/// 5. **Attitude**: `q_nb,k = q(-zeta') * q_nb,k-1 * q(phi)` where `zeta'` uses the transport
///    rate of `v_bar`; the quaternion is renormalised to first order every step.
///
/// Cost per step: about 400 `f64` operations (of which about 12 divisions), one `sin`, one
/// `cos`, one `sqrt`, no allocation. On a Cortex-M4F `f64` is emulated in software (its FPU
/// is single precision), so expect roughly 20-30 thousand cycles per step there. The local-level NED frame is singular at the poles (|latitude| -> 90 deg):
/// longitude rate and transport rate diverge there.
#[derive(Debug, Clone, Copy)]
pub struct Strapdown {
    state: NavState,
    prev_dtheta_rad: Vector3<f64>,
    prev_dv_mps: Vector3<f64>,
    prev_dt_s: f64,
    have_prev: bool,
    /// Gravity minus Coriolis/centripetal acceleration in NED of the last step, m/s^2 (only for
    /// the mid-interval extrapolation).
    accel_ng_mps2: Vector3<f64>,
    /// Meridian radius of curvature of the last step, m (only for the extrapolation).
    meridian_m: f64,
}

/// Earth quantities at one latitude and height, computed from one `sin` / `cos` / `sqrt`.
#[derive(Debug, Clone, Copy)]
struct EarthAt {
    sin_lat: f64,
    cos_lat: f64,
    /// Meridian radius of curvature R_M, m.
    meridian_m: f64,
    /// Transverse radius of curvature R_N, m.
    transverse_m: f64,
    /// Normal gravity magnitude, m/s^2.
    gravity_mps2: f64,
}

impl EarthAt {
    /// The same formulas as [`earth::radii`] and [`earth::gravity_mps2`] (checked against them
    /// in the tests), sharing the trigonometry and the square root.
    fn new(lat_rad: f64, h_m: f64) -> Self {
        let sin_lat = sin(lat_rad);
        let cos_lat = cos(lat_rad);
        let s2 = sin_lat * sin_lat;
        let d = 1.0 - earth::E2 * s2;
        let sd = sqrt(d);
        let transverse_m = earth::A_M / sd;
        let meridian_m = earth::A_M * (1.0 - earth::E2) / (d * sd);
        let g0 = earth::GAMMA_E_MPS2 * (1.0 + earth::SOMIGLIANA_K * s2) / sd;
        let gravity_mps2 = g0
            * (1.0
                - 2.0 / earth::A_M * (1.0 + earth::F + earth::M_RATIO - 2.0 * earth::F * s2) * h_m
                + 3.0 * h_m * h_m / (earth::A_M * earth::A_M));
        Self {
            sin_lat,
            cos_lat,
            meridian_m,
            transverse_m,
            gravity_mps2,
        }
    }

    /// Earth rate in NED, rad/s.
    fn earth_rate(&self) -> Vector3<f64> {
        Vector3::new(
            earth::OMEGA_IE_RADPS * self.cos_lat,
            0.0,
            -earth::OMEGA_IE_RADPS * self.sin_lat,
        )
    }

    /// Transport rate in NED (rad/s) for velocity `v` (m/s) at height `h_m`.
    fn transport_rate(&self, h_m: f64, v: &Vector3<f64>) -> Vector3<f64> {
        let inv_rn = 1.0 / (self.transverse_m + h_m);
        let inv_rm = 1.0 / (self.meridian_m + h_m);
        Vector3::new(
            v.y * inv_rn,
            -v.x * inv_rm,
            -v.y * inv_rn * self.sin_lat / self.cos_lat,
        )
    }
}

/// Gravity minus Coriolis and centripetal acceleration in NED, m/s^2.
fn accel_ng(
    g_mps2: f64,
    w_ie: &Vector3<f64>,
    w_en: &Vector3<f64>,
    v: &Vector3<f64>,
) -> Vector3<f64> {
    Vector3::new(0.0, 0.0, g_mps2) - (w_ie * 2.0 + w_en).cross(v)
}

impl Strapdown {
    /// Starts the mechanization from `state`.
    pub fn new(state: NavState) -> Self {
        let e = EarthAt::new(state.pos.lat_rad, state.pos.h_m);
        let w_ie = e.earth_rate();
        let w_en = e.transport_rate(state.pos.h_m, &state.vel_ned_mps);
        Self {
            state,
            prev_dtheta_rad: Vector3::zeros(),
            prev_dv_mps: Vector3::zeros(),
            prev_dt_s: 0.0,
            have_prev: false,
            accel_ng_mps2: accel_ng(e.gravity_mps2, &w_ie, &w_en, &state.vel_ned_mps),
            meridian_m: e.meridian_m,
        }
    }

    /// The current nominal state.
    pub fn state(&self) -> &NavState {
        &self.state
    }

    /// Mutable access to the nominal state (closed-loop error feedback).
    pub fn state_mut(&mut self) -> &mut NavState {
        &mut self.state
    }

    /// Forgets the previous increments, so the next step uses no coning / sculling terms
    /// (call after a data gap or when the sensor-error corrections change abruptly).
    pub fn reset_history(&mut self) {
        self.have_prev = false;
    }

    /// Integrates one IMU sample (already corrected for the estimated sensor errors) over
    /// (state.t_s, imu.t_s]. On error the state is unchanged.
    pub fn update(&mut self, imu: &ImuSample) -> Result<StepInfo, MechError> {
        if !imu.is_finite() {
            return Err(MechError::NonFinite);
        }
        let dt = imu.t_s - self.state.t_s;
        if !(dt > 0.0 && dt <= MAX_DT_S) {
            return Err(MechError::BadTimeStep);
        }
        let dth = Vector3::from(imu.dtheta_rad);
        let dv = Vector3::from(imu.dv_mps);

        // 1. Body frame: coning, rotation compensation and sculling (two-sample, previous
        //    interval). Without a usable previous sample the two-sample terms are dropped.
        let use_prev = self.have_prev && dt <= 2.0 * self.prev_dt_s && self.prev_dt_s <= 2.0 * dt;
        let (phi_b, dv_b) = if use_prev {
            (
                dth + attitude::coning_correction(&self.prev_dtheta_rad, &dth),
                attitude::sculled_dv(&self.prev_dtheta_rad, &self.prev_dv_mps, &dth, &dv),
            )
        } else {
            (
                dth,
                attitude::sculled_dv(&Vector3::zeros(), &Vector3::zeros(), &dth, &dv),
            )
        };

        let s = self.state;
        let (lat0, lon0, h0) = (s.pos.lat_rad, s.pos.lon_rad, s.pos.h_m);
        let v0 = s.vel_ned_mps;

        // 2. Body increment in n(t_{k-1}); mid-interval extrapolation of v, h, lat.
        let dv_n0 = s.q_nb * dv_b;
        let v_mid = v0 + (dv_n0 + self.accel_ng_mps2 * dt) * 0.5;
        let h_mid = h0 - 0.5 * v_mid.z * dt;
        let lat_mid = lat0 + 0.5 * dt * v_mid.x / (self.meridian_m + h_mid);
        let e = EarthAt::new(lat_mid, h_mid);
        let w_ie = e.earth_rate();
        let w_en = e.transport_rate(h_mid, &v_mid);

        // 3. Velocity: navigation-frame rotation over the interval, gravity, Coriolis.
        let zeta = (w_ie + w_en) * dt;
        let dv_n = dv_n0 - zeta.cross(&dv_n0) * 0.5;
        let a_ng = accel_ng(e.gravity_mps2, &w_ie, &w_en, &v_mid);
        let v1 = v0 + dv_n + a_ng * dt;

        // 4. Position: height, then latitude, then longitude (trapezoid velocity, mid radii).
        let v_bar = (v0 + v1) * 0.5;
        let h1 = h0 - v_bar.z * dt;
        let h_bar = 0.5 * (h0 + h1);
        let lat1 = lat0 + v_bar.x * dt / (e.meridian_m + h_bar);
        // cos of the true mid latitude, to first order around the extrapolated one.
        let cos_bar = e.cos_lat - e.sin_lat * (0.5 * (lat0 + lat1) - lat_mid);
        let lon1 = lon0 + v_bar.y * dt / ((e.transverse_m + h_bar) * cos_bar);

        // 5. Attitude: body rotation, then the navigation frame's rotation (with v_bar).
        let zeta_att = (w_ie + e.transport_rate(h_bar, &v_bar)) * dt;
        let q_bb = attitude::quat_from_rotvec(&phi_b);
        let q_nn = attitude::quat_from_rotvec(&(-zeta_att));
        let q = q_nn.quaternion() * s.q_nb.quaternion() * q_bb.quaternion();
        let q_nb = UnitQuaternion::new_unchecked(attitude::renormalized(q));

        self.state = NavState {
            t_s: imu.t_s,
            pos: Llh {
                lat_rad: lat1,
                lon_rad: lon1,
                h_m: h1,
            },
            vel_ned_mps: v1,
            q_nb,
        };
        self.prev_dtheta_rad = dth;
        self.prev_dv_mps = dv;
        self.prev_dt_s = dt;
        self.have_prev = true;
        self.accel_ng_mps2 = a_ng;
        self.meridian_m = e.meridian_m;
        Ok(StepInfo {
            dt_s: dt,
            f_body_mps2: dv / dt,
            omega_ib_body_radps: dth / dt,
            f_ned_mps2: dv_n / dt,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn earth_at_matches_the_earth_module() {
        for &lat_deg in &[-89.0, -45.0, 0.0, 12.3, 48.0, 80.0] {
            for &h in &[-100.0, 0.0, 300.0, 10_000.0] {
                let lat = f64::to_radians(lat_deg);
                let e = EarthAt::new(lat, h);
                let r = earth::radii(lat);
                assert!((e.meridian_m - r.meridian_m).abs() < 1e-8);
                assert!((e.transverse_m - r.transverse_m).abs() < 1e-8);
                assert!((e.gravity_mps2 - earth::gravity_mps2(lat, h)).abs() < 1e-14);
                assert!((e.earth_rate() - earth::earth_rate_ned_radps(lat)).norm() < 1e-20);
                let v = Vector3::new(12.0, -7.0, 0.5);
                let w_ref = earth::transport_rate_ned_radps(lat, h, &v);
                let w = e.transport_rate(h, &v) - w_ref;
                assert!(w.norm() < 1e-14 * w_ref.norm());
            }
        }
    }

    #[test]
    fn rejects_bad_samples_and_keeps_the_state() {
        let s0 = NavState::from_rpy(
            10.0,
            Llh::from_deg(48.0, 11.0, 300.0),
            Vector3::zeros(),
            [0.0; 3],
        );
        let mut m = Strapdown::new(s0);
        let mut imu = ImuSample {
            t_s: 10.005,
            dtheta_rad: [f64::NAN, 0.0, 0.0],
            ..Default::default()
        };
        assert_eq!(m.update(&imu), Err(MechError::NonFinite));
        imu.dtheta_rad = [0.0; 3];
        imu.t_s = 10.0;
        assert_eq!(m.update(&imu), Err(MechError::BadTimeStep));
        imu.t_s = 11.5;
        assert_eq!(m.update(&imu), Err(MechError::BadTimeStep));
        assert_eq!(*m.state(), s0);
    }
}
