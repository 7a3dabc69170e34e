//! The nominal navigation state and the strapdown mechanization on IMU increments (NED,
//! quaternion attitude). Everything here is `f64`.
//!
//! The interface is fixed (the filter and the tools use it); the integration algorithm inside
//! [`Strapdown::update`] is free to improve.

use crate::earth::{self, Llh};
use crate::types::ImuSample;
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
    /// Roll, pitch, yaw (ZYX Euler angles of the body relative to NED), rad.
    pub fn rpy_rad(&self) -> [f64; 3] {
        let (r, p, y) = self.q_nb.euler_angles();
        [r, p, y]
    }

    /// A state from position, NED velocity and roll/pitch/yaw in radians.
    pub fn from_rpy(t_s: f64, pos: Llh, vel_ned_mps: Vector3<f64>, rpy_rad: [f64; 3]) -> Self {
        Self {
            t_s,
            pos,
            vel_ned_mps,
            q_nb: UnitQuaternion::from_euler_angles(rpy_rad[0], rpy_rad[1], rpy_rad[2]),
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

/// Strapdown inertial navigation on increments.
#[derive(Debug, Clone, Copy)]
pub struct Strapdown {
    state: NavState,
    prev_dtheta_rad: Vector3<f64>,
    prev_dv_mps: Vector3<f64>,
    have_prev: bool,
}

impl Strapdown {
    /// Starts the mechanization from `state`.
    pub fn new(state: NavState) -> Self {
        Self {
            state,
            prev_dtheta_rad: Vector3::zeros(),
            prev_dv_mps: Vector3::zeros(),
            have_prev: false,
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
        let s = &self.state;
        let lat = s.pos.lat_rad;
        let h = s.pos.h_m;
        let w_ie = earth::earth_rate_ned_radps(lat);
        let w_en = earth::transport_rate_ned_radps(lat, h, &s.vel_ned_mps);
        let w_in = w_ie + w_en;

        // Velocity: rotation (sculling-free first order) of the body increment into NED with
        // the attitude at mid-interval, Coriolis and gravity at the start.
        let q_mid = s.q_nb * UnitQuaternion::from_scaled_axis(dth * 0.5);
        let q_mid = UnitQuaternion::from_scaled_axis(-w_in * (0.5 * dt)) * q_mid;
        let dv_n = q_mid * dv;
        let g = earth::gravity_ned_mps2(lat, h);
        let cor = (2.0 * w_ie + w_en).cross(&s.vel_ned_mps);
        let v_new = s.vel_ned_mps + dv_n + (g - cor) * dt;

        // Position: trapezoidal velocity with the start-of-interval curvature.
        let v_mid = (s.vel_ned_mps + v_new) * 0.5;
        let rate = earth::llh_rate(&s.pos, &v_mid);
        let pos = Llh {
            lat_rad: lat + rate.x * dt,
            lon_rad: s.pos.lon_rad + rate.y * dt,
            h_m: h + rate.z * dt,
        };

        // Attitude: body rotation, then the navigation frame's rotation.
        let q_b = UnitQuaternion::from_scaled_axis(dth);
        let q_n = UnitQuaternion::from_scaled_axis(-w_in * dt);
        let q_nb = q_n * s.q_nb * q_b;

        self.state = NavState {
            t_s: imu.t_s,
            pos,
            vel_ned_mps: v_new,
            q_nb,
        };
        self.prev_dtheta_rad = dth;
        self.prev_dv_mps = dv;
        self.have_prev = true;
        Ok(StepInfo {
            dt_s: dt,
            f_body_mps2: dv / dt,
            omega_ib_body_radps: dth / dt,
            f_ned_mps2: dv_n / dt,
        })
    }
}
