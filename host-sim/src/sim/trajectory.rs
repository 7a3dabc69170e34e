//! Truth trajectory and ideal IMU increments by inverse mechanization.
//!
//! The vehicle's position (latitude, longitude, height) and heading are integrated with RK4
//! at `imu.rate_hz * imu.substeps` from the smooth scenario kinematics; speed, pitch and roll
//! are closed-form. At every internal stage the simulator evaluates, with `nav_core::earth`,
//!
//! - `omega_ib^b = omega_nb^b + C_n^b (omega_ie^n + omega_en^n)` (omega_nb^b from the Euler
//!   angle rates), and
//! - `f^b = C_n^b (dv^n/dt + (2 omega_ie^n + omega_en^n) x v^n - g^n)`,
//!
//! and integrates them in the same RK4 scheme, so the increments `dtheta = int omega_ib^b dt`
//! and `dv = int f^b dt` over each IMU interval are those a real IMU outputs, exact to the
//! RK4 truncation error (far below any sensor noise, see the convergence test).

use super::scenario::{Kinematics, Profile, Scenario, ScenarioError};
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

/// ODE state: lat, lon, h, yaw, int omega_ib^b, int f^b.
type State = [f64; 10];

/// Everything the inverse mechanization computes at one instant.
#[derive(Debug, Clone, Copy)]
pub struct Instant {
    /// Kinematics from the profile.
    pub kin: Kinematics,
    /// Yaw, rad.
    pub yaw_rad: f64,
    /// NED velocity, m/s.
    pub vel_ned_mps: Vector3<f64>,
    /// Angular rate of the body w.r.t. inertial space in body axes, rad/s.
    pub omega_ib_b_radps: Vector3<f64>,
    /// Specific force in body axes, m/s^2.
    pub f_b_mps2: Vector3<f64>,
    /// Rate of (lat rad/s, lon rad/s, height m/s).
    pub llh_rate: Vector3<f64>,
}

/// Earth terms at one position and velocity: the formulas of `nav_core::earth` (earth rate,
/// transport rate, llh rate from the same WGS84 radii; gravity by `earth::gravity_ned_mps2`)
/// evaluated with one sine/cosine of latitude (the test `earth_terms_match_nav_core` checks
/// them against `nav_core::earth` to 1e-15 relative).
struct EarthTerms {
    w_ie: Vector3<f64>,
    w_en: Vector3<f64>,
    g: Vector3<f64>,
    llh_rate: Vector3<f64>,
}

impl EarthTerms {
    fn new(lat: f64, h: f64, v: &Vector3<f64>) -> Self {
        let (sl, cl) = lat.sin_cos();
        let d = 1.0 - earth::E2 * sl * sl;
        let sd = d.sqrt();
        let rn = earth::A_M / sd + h;
        let rm = earth::A_M * (1.0 - earth::E2) / (d * sd) + h;
        Self {
            w_ie: Vector3::new(earth::OMEGA_IE_RADPS * cl, 0.0, -earth::OMEGA_IE_RADPS * sl),
            w_en: Vector3::new(v.y / rn, -v.x / rm, -v.y * sl / (cl * rn)),
            g: earth::gravity_ned_mps2(lat, h),
            llh_rate: Vector3::new(v.x / rm, v.y / (rn * cl), -v.z),
        }
    }
}

/// The inverse mechanization at relative time `t` for position/yaw `y`.
fn instant(prof: &Profile, t: f64, y: &State) -> Instant {
    let kin = prof.eval(t);
    // y[3] is the heading of the velocity (course); the body yaw is the course minus the side
    // slip (zero without slip)
    let (lat, h, yaw) = (y[0], y[2], y[3]);
    let (st, ct) = kin.pitch_rad.sin_cos();
    let (sp, cp) = yaw.sin_cos();
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
    let e = EarthTerms::new(lat, h, &v);
    let (w_ie, w_en, g) = (e.w_ie, e.w_en, e.g);
    let f_n = a_n + (2.0 * w_ie + w_en).cross(&v) - g;
    let yaw_b = yaw - kin.slip_rad;
    let rd = rd - kin.slip_rate_radps;
    let c_bn = dcm_from_euler(kin.roll_rad, kin.pitch_rad, yaw_b);
    let c_nb = c_bn.transpose();
    let w_nb_b = Vector3::new(
        pd - rd * st,
        qd * cf + rd * sf * ct,
        -qd * sf + rd * cf * ct,
    );
    Instant {
        kin,
        yaw_rad: yaw,
        vel_ned_mps: v,
        omega_ib_b_radps: w_nb_b + c_nb * (w_ie + w_en),
        f_b_mps2: c_nb * f_n,
        llh_rate: e.llh_rate,
    }
}

fn deriv(prof: &Profile, t: f64, y: &State) -> State {
    let i = instant(prof, t, y);
    [
        i.llh_rate.x,
        i.llh_rate.y,
        i.llh_rate.z,
        i.kin.yaw_rate_radps,
        i.omega_ib_b_radps.x,
        i.omega_ib_b_radps.y,
        i.omega_ib_b_radps.z,
        i.f_b_mps2.x,
        i.f_b_mps2.y,
        i.f_b_mps2.z,
    ]
}

fn axpy(y: &State, a: f64, k: &State) -> State {
    let mut o = *y;
    for (oi, ki) in o.iter_mut().zip(k) {
        *oi += a * ki;
    }
    o
}

impl Trajectory {
    /// Integrates the scenario: truth at the IMU rate and ideal increments.
    pub fn generate(scenario: &Scenario) -> Result<Self, ScenarioError> {
        let prof = scenario.compile()?;
        let dt = scenario.dt_s();
        let n = (prof.duration_s / dt).round() as usize;
        let sub = scenario.imu.substeps as usize;
        let h = dt / sub as f64;
        let st = &scenario.start;
        let t0 = st.sow_s;
        let mut y: State = [0.0; 10];
        y[0] = st.lat_deg.to_radians();
        y[1] = st.lon_deg.to_radians();
        y[2] = st.h_m;
        y[3] = st.heading_deg.to_radians();
        let mut truth = Vec::with_capacity(n + 1);
        let mut imu = Vec::with_capacity(n);
        truth.push(Self::record(&prof, st.gps_week, t0, 0.0, &y));
        for k in 0..n {
            let tk = k as f64 * dt;
            for j in 0..sub {
                let t = tk + j as f64 * h;
                let k1 = deriv(&prof, t, &y);
                let k2 = deriv(&prof, t + 0.5 * h, &axpy(&y, 0.5 * h, &k1));
                let k3 = deriv(&prof, t + 0.5 * h, &axpy(&y, 0.5 * h, &k2));
                let k4 = deriv(&prof, t + h, &axpy(&y, h, &k3));
                for i in 0..10 {
                    y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
                }
            }
            let t_rel = (k + 1) as f64 * dt;
            imu.push(ImuSample {
                t_s: t0 + t_rel,
                dtheta_rad: [y[4], y[5], y[6]],
                dv_mps: [y[7], y[8], y[9]],
                temperature_c: f64::NAN,
            });
            for v in &mut y[4..10] {
                *v = 0.0;
            }
            truth.push(Self::record(&prof, st.gps_week, t0, t_rel, &y));
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

    fn record(prof: &Profile, week: u16, t0: f64, t_rel: f64, y: &State) -> NavSolution {
        let i = instant(prof, t_rel, y);
        NavSolution {
            week,
            t_s: t0 + t_rel,
            lat_rad: y[0],
            lon_rad: y[1],
            h_m: y[2],
            vel_ned_mps: [i.vel_ned_mps.x, i.vel_ned_mps.y, i.vel_ned_mps.z],
            rpy_rad: [
                i.kin.roll_rad,
                i.kin.pitch_rad,
                wrap_pi(y[3] - i.kin.slip_rad),
            ],
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn earth_terms_match_nav_core() {
        for &(lat_deg, h, vn, ve, vd) in &[
            (48.2, 220.0, 10.0, -3.0, 0.5),
            (-33.9, -20.0, -25.0, 12.0, -1.0),
            (70.0, 3000.0, 0.0, 30.0, 0.0),
        ] {
            let lat = f64::to_radians(lat_deg);
            let v = Vector3::new(vn, ve, vd);
            let e = EarthTerms::new(lat, h, &v);
            let pos = Llh {
                lat_rad: lat,
                lon_rad: 0.3,
                h_m: h,
            };
            let close = |a: Vector3<f64>, b: Vector3<f64>| {
                assert!(
                    (a - b).norm() <= 1e-15 * b.norm().max(1e-300),
                    "{a:?} {b:?}"
                )
            };
            close(e.w_ie, earth::earth_rate_ned_radps(lat));
            close(e.w_en, earth::transport_rate_ned_radps(lat, h, &v));
            close(e.g, earth::gravity_ned_mps2(lat, h));
            close(e.llh_rate, earth::llh_rate(&pos, &v));
        }
    }
}
