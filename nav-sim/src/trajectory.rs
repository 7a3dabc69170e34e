//! A scenario integrated into its truth trajectory and ideal IMU increments.
//!
//! The compiled scenario ([`Profile`]: speed, pitch, roll, yaw rate, side slip and bounce as
//! closed-form functions of time) is the [`Motion`] [`ProfileMotion`]; the one integrator
//! ([`Integrator`]) carries position and the heading of the velocity (course) with RK4 at
//! `imu.rate_hz * imu.substeps` and integrates, in the same RK4 scheme,
//!
//! - `omega_ib^b = omega_nb^b + C_n^b (omega_ie^n + omega_en^n)` (omega_nb^b from the Euler
//!   angle rates), and
//! - `f^b = C_n^b (dv^n/dt + (2 omega_ie^n + omega_en^n) x v^n - g^n)`,
//!
//! so the increments `dtheta = int omega_ib^b dt` and `dv = int f^b dt` over each IMU interval
//! are those a real IMU outputs, exact to the RK4 truncation error (far below any sensor
//! noise, see host-sim's convergence test).

use crate::motion::{BodyKinematics, Integrator, Motion};
use crate::scenario::{Kinematics, Profile, Scenario, ScenarioError};
use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use nav_core::earth::{self, Llh};
use nav_core::strapdown::NavState;
use nav_core::types::{ImuSample, NavSolution};

/// The error-free result of a scenario: truth at every IMU epoch and the ideal increments.
#[derive(Debug, Clone)]
pub struct Trajectory {
    /// The scenario it came from.
    pub scenario: Scenario,
    /// GPS week of the start.
    pub week: u16,
    /// GPS seconds of week of the first epoch, s.
    pub t0_s: f64,
    /// IMU interval, s.
    pub dt_s: f64,
    /// Truth at the IMU reference point at every epoch `t0 + k dt`, k = 0..=n (n + 1 records;
    /// standard deviations NaN).
    pub truth: Vec<NavSolution>,
    /// Ideal increments, n records: `imu[k]` covers `(truth[k].t_s, truth[k+1].t_s]`;
    /// temperature NaN.
    pub imu: Vec<ImuSample>,
}

/// Body-to-NED rotation matrix C_b^n of ZYX Euler angles.
pub fn dcm_from_euler(roll: f64, pitch: f64, yaw: f64) -> Matrix3<f64> {
    let (sf, cf) = roll.sin_cos();
    let (st, ct) = pitch.sin_cos();
    let (sp, cp) = yaw.sin_cos();
    Matrix3::new(
        ct * cp,
        sf * st * cp - cf * sp,
        cf * st * cp + sf * sp,
        ct * sp,
        sf * st * sp + cf * cp,
        cf * st * sp - sf * cp,
        -st,
        sf * ct,
        cf * ct,
    )
}

/// Wraps an angle to (-pi, pi].
pub fn wrap_pi(a: f64) -> f64 {
    let mut x = a % std::f64::consts::TAU;
    if x > std::f64::consts::PI {
        x -= std::f64::consts::TAU;
    } else if x <= -std::f64::consts::PI {
        x += std::f64::consts::TAU;
    }
    x
}

/// A compiled scenario as a [`Motion`]: the integrator's heading state is the heading of the
/// velocity (course); the body yaw is the course minus the side slip.
#[derive(Debug, Clone, Copy)]
pub struct ProfileMotion<'a>(pub &'a Profile);

impl ProfileMotion<'_> {
    /// The profile's kinematics at `t` (s after the start) and the NED velocity (m/s) for
    /// course `course_rad` (rad).
    pub fn velocity(&self, t: f64, course_rad: f64) -> (Kinematics, Vector3<f64>) {
        let kin = self.0.eval(t);
        let (st, ct) = kin.pitch_rad.sin_cos();
        let (sp, cp) = course_rad.sin_cos();
        let u = Vector3::new(ct * cp, ct * sp, -st);
        let v = u * kin.speed_mps + Vector3::new(0.0, 0.0, kin.bounce_vel_mps);
        (kin, v)
    }
}

impl Motion for ProfileMotion<'_> {
    fn at(&self, t: f64, course_rad: f64) -> BodyKinematics {
        let kin = self.0.eval(t);
        let (st, ct) = kin.pitch_rad.sin_cos();
        let (sp, cp) = course_rad.sin_cos();
        let (sf, cf) = kin.roll_rad.sin_cos();
        let u = Vector3::new(ct * cp, ct * sp, -st);
        let s = kin.speed_mps;
        let v = u * s;
        let (qd, rd, pd) = (
            kin.pitch_rate_radps,
            kin.yaw_rate_radps,
            kin.roll_rate_radps,
        );
        let du = Vector3::new(
            -st * qd * cp - ct * sp * rd,
            -st * qd * sp + ct * cp * rd,
            -ct * qd,
        );
        let a_n = u * kin.speed_dot_mps2 + du * s + Vector3::new(0.0, 0.0, kin.bounce_acc_mps2);
        let v = v + Vector3::new(0.0, 0.0, kin.bounce_vel_mps);
        let yaw_b = course_rad - kin.slip_rad;
        let rd_b = rd - kin.slip_rate_radps;
        BodyKinematics {
            vel_ned_mps: v,
            acc_ned_mps2: a_n,
            c_bn: dcm_from_euler(kin.roll_rad, kin.pitch_rad, yaw_b),
            omega_nb_b_radps: Vector3::new(
                pd - rd_b * st,
                qd * cf + rd_b * sf * ct,
                -qd * sf + rd_b * cf * ct,
            ),
            heading_rate_radps: kin.yaw_rate_radps,
        }
    }
}

impl Trajectory {
    /// Integrates the scenario: truth at the IMU rate and ideal increments.
    pub fn generate(scenario: &Scenario) -> Result<Self, ScenarioError> {
        let prof = scenario.compile()?;
        let dt = scenario.dt_s();
        let n = (prof.duration_s / dt).round() as usize;
        let st = &scenario.start;
        let t0 = st.sow_s;
        let start = Llh {
            lat_rad: st.lat_deg.to_radians(),
            lon_rad: st.lon_deg.to_radians(),
            h_m: st.h_m,
        };
        let motion = ProfileMotion(&prof);
        let mut integ = Integrator::new(
            motion,
            start,
            st.heading_deg.to_radians(),
            t0,
            dt,
            scenario.imu.substeps,
        );
        let mut truth = Vec::with_capacity(n + 1);
        let mut imu = Vec::with_capacity(n);
        truth.push(Self::record(&integ, st.gps_week));
        for _ in 0..n {
            imu.push(integ.step());
            truth.push(Self::record(&integ, st.gps_week));
        }
        Ok(Self {
            scenario: scenario.clone(),
            week: st.gps_week,
            t0_s: t0,
            dt_s: dt,
            truth,
            imu,
        })
    }

    /// The truth record of the integrator's current epoch.
    fn record(integ: &Integrator<ProfileMotion<'_>>, week: u16) -> NavSolution {
        let t_rel = integ.t_rel_s();
        let course = integ.heading_rad();
        let (kin, v) = integ.motion().velocity(t_rel, course);
        let p = integ.pos();
        NavSolution {
            week,
            t_s: integ.t0_s() + t_rel,
            lat_rad: p.lat_rad,
            lon_rad: p.lon_rad,
            h_m: p.h_m,
            vel_ned_mps: [v.x, v.y, v.z],
            rpy_rad: [kin.roll_rad, kin.pitch_rad, wrap_pi(course - kin.slip_rad)],
            pos_std_ned_m: [f64::NAN; 3],
            vel_std_ned_mps: [f64::NAN; 3],
            att_std_rad: [f64::NAN; 3],
            status: 0,
        }
    }

    /// Number of IMU samples.
    pub fn len(&self) -> usize {
        self.imu.len()
    }

    /// True when there are no IMU samples.
    pub fn is_empty(&self) -> bool {
        self.imu.is_empty()
    }

    /// Duration, s.
    pub fn duration_s(&self) -> f64 {
        self.imu.len() as f64 * self.dt_s
    }

    /// The truth at epoch `k` as a mechanization state (IMU reference point).
    pub fn nav_state(&self, k: usize) -> Option<NavState> {
        self.truth.get(k).map(nav_state_of)
    }

    /// Truth interpolated at GPS time `t_s` (cubic Hermite in position with the velocity as
    /// derivative, linear in velocity, slerp in attitude); `None` outside the trajectory.
    pub fn truth_at(&self, t_s: f64) -> Option<NavState> {
        let x = (t_s - self.t0_s) / self.dt_s;
        let n = self.imu.len();
        if !(x >= -1e-9 && x <= n as f64 + 1e-9) {
            return None;
        }
        let k = (x.floor().max(0.0) as usize).min(n.saturating_sub(1));
        let a = nav_state_of(self.truth.get(k)?);
        let b = nav_state_of(self.truth.get(k + 1)?);
        let s = (x - k as f64).clamp(0.0, 1.0);
        let h = self.dt_s;
        let ra = earth::llh_rate(&a.pos, &a.vel_ned_mps) * h;
        let rb = earth::llh_rate(&b.pos, &b.vel_ned_mps) * h;
        let (h00, h10, h01, h11) = (
            2.0 * s * s * s - 3.0 * s * s + 1.0,
            s * s * s - 2.0 * s * s + s,
            -2.0 * s * s * s + 3.0 * s * s,
            s * s * s - s * s,
        );
        let pa = Vector3::new(a.pos.lat_rad, a.pos.lon_rad, a.pos.h_m);
        let pb = Vector3::new(b.pos.lat_rad, b.pos.lon_rad, b.pos.h_m);
        let p = pa * h00 + ra * h10 + pb * h01 + rb * h11;
        Some(NavState {
            t_s,
            pos: Llh {
                lat_rad: p.x,
                lon_rad: p.y,
                h_m: p.z,
            },
            vel_ned_mps: self.velocity_hermite(k, s),
            q_nb: a.q_nb.slerp(&b.q_nb, s),
        })
    }

    /// Velocity between epochs `k` and `k + 1` at fraction `s`: cubic Hermite with
    /// central-difference tangents (Catmull-Rom; one-sided at the ends), error O(dt^3).
    fn velocity_hermite(&self, k: usize, s: f64) -> Vector3<f64> {
        let v = |i: usize| -> Vector3<f64> {
            let i = i.min(self.truth.len().saturating_sub(1));
            self.truth
                .get(i)
                .map_or(Vector3::zeros(), |t| Vector3::from(t.vel_ned_mps))
        };
        let (va, vb) = (v(k), v(k + 1));
        let ma = if k == 0 {
            vb - va
        } else {
            (vb - v(k - 1)) * 0.5
        };
        let mb = if k + 2 >= self.truth.len() {
            vb - va
        } else {
            (v(k + 2) - va) * 0.5
        };
        let (s2, s3) = (s * s, s * s * s);
        va * (2.0 * s3 - 3.0 * s2 + 1.0)
            + ma * (s3 - 2.0 * s2 + s)
            + vb * (-2.0 * s3 + 3.0 * s2)
            + mb * (s3 - s2)
    }

    /// Mean angular rate of the body w.r.t. the navigation frame over IMU interval `k`, body
    /// axes, rad/s (from the ideal increments).
    fn omega_nb_b_interval(&self, k: usize) -> Vector3<f64> {
        let (Some(s), Some(tr)) = (self.imu.get(k), self.truth.get(k)) else {
            return Vector3::zeros();
        };
        let st = nav_state_of(tr);
        let w_in = earth::earth_rate_ned_radps(st.pos.lat_rad)
            + earth::transport_rate_ned_radps(st.pos.lat_rad, st.pos.h_m, &st.vel_ned_mps);
        Vector3::from(s.dtheta_rad) / self.dt_s - st.q_nb.inverse() * w_in
    }

    /// Angular rate of the body w.r.t. the navigation frame at GPS time `t_s`, body axes,
    /// rad/s: the interval means of the ideal increments, linearly interpolated between the
    /// interval midpoints (error O(dt^2)).
    pub fn omega_nb_b_at(&self, t_s: f64) -> Vector3<f64> {
        let n = self.imu.len();
        if n < 2 {
            return self.omega_nb_b_interval(0);
        }
        let x = (t_s - self.t0_s) / self.dt_s - 0.5;
        let k = (x.floor().max(0.0) as usize).min(n - 2);
        let s = (x - k as f64).clamp(0.0, 1.0);
        self.omega_nb_b_interval(k) * (1.0 - s) + self.omega_nb_b_interval(k + 1) * s
    }
}

/// A nav-format record as a mechanization state.
pub fn nav_state_of(s: &NavSolution) -> NavState {
    NavState {
        t_s: s.t_s,
        pos: Llh {
            lat_rad: s.lat_rad,
            lon_rad: s.lon_rad,
            h_m: s.h_m,
        },
        vel_ned_mps: Vector3::from(s.vel_ned_mps),
        q_nb: UnitQuaternion::from_euler_angles(s.rpy_rad[0], s.rpy_rad[1], s.rpy_rad[2]),
    }
}
