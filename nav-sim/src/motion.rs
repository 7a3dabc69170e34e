//! The integrator: a vehicle motion integrated into truth position and heading and the ideal
//! IMU increments by inverse mechanization.
//!
//! A [`Motion`] gives, at relative time `t` and for the heading the integrator carries, the
//! vehicle's [`BodyKinematics`]: NED velocity and its time derivative, the attitude C_b^n, the
//! body rate relative to NED and the heading rate. [`Integrator`] integrates the ODE
//!
//! ```text
//! d(lat, lon, h)/dt = llh_rate(v^n)          (WGS84 radii)
//! d(heading)/dt     = heading rate           (the motion's own state; 0 for closed-form motions)
//! d(theta)/dt       = omega_ib^b = omega_nb^b + C_n^b (omega_ie^n + omega_en^n)
//! d(v)/dt           = f^b        = C_n^b (dv^n/dt + (2 omega_ie^n + omega_en^n) x v^n - g^n)
//! ```
//!
//! with one classical fourth-order Runge-Kutta pass over `n_sub` sub-steps per IMU interval;
//! `theta` and `v` restart at zero at every IMU epoch, so they are the increments a perfect
//! rate-integrating IMU outputs over the interval, exact to the RK4 truncation error. The
//! earth terms are `nav_core::earth`'s formulas (the test `earth_terms_match_nav_core`); the
//! mechanization itself (`nav_core::strapdown`) is not used, so the truth is independent of it.

use nalgebra::{Matrix3, Vector3};
use nav_core::earth::{self, Llh};
use nav_core::types::ImuSample;

/// The kinematics of the vehicle at one instant (IMU reference point).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyKinematics {
    /// Velocity relative to the earth in NED, m/s.
    pub vel_ned_mps: Vector3<f64>,
    /// Time derivative of the NED velocity components, m/s^2.
    pub acc_ned_mps2: Vector3<f64>,
    /// Attitude: the body-to-NED rotation matrix C_b^n.
    pub c_bn: Matrix3<f64>,
    /// Angular rate of the body relative to NED in body axes, rad/s.
    pub omega_nb_b_radps: Vector3<f64>,
    /// Rate of the heading state the integrator carries, rad/s (0 when the motion does not
    /// use it).
    pub heading_rate_radps: f64,
}

/// A vehicle motion: its kinematics as a function of time.
pub trait Motion {
    /// The kinematics at `t_s` seconds after the start, given the integrated heading
    /// `heading_rad` (rad; a motion whose heading is closed-form ignores it).
    fn at(&self, t_s: f64, heading_rad: f64) -> BodyKinematics;
}

impl<M: Motion + ?Sized> Motion for &M {
    fn at(&self, t_s: f64, heading_rad: f64) -> BodyKinematics {
        (**self).at(t_s, heading_rad)
    }
}

/// Earth terms at one position and velocity: the formulas of `nav_core::earth` (earth rate,
/// transport rate, llh rate from the same WGS84 radii; gravity by `earth::gravity_ned_mps2`)
/// evaluated with one sine/cosine of latitude.
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

/// ODE state: lat (rad), lon (rad), h (m), heading (rad), int omega_ib^b (rad), int f^b (m/s).
type State = [f64; 10];

fn deriv<M: Motion>(motion: &M, t: f64, y: &State) -> State {
    let k = motion.at(t, y[3]);
    let v = k.vel_ned_mps;
    let e = EarthTerms::new(y[0], y[2], &v);
    let f_n = k.acc_ned_mps2 + (2.0 * e.w_ie + e.w_en).cross(&v) - e.g;
    let c_nb = k.c_bn.transpose();
    let w_ib = k.omega_nb_b_radps + c_nb * (e.w_ie + e.w_en);
    let f_b = c_nb * f_n;
    [
        e.llh_rate.x,
        e.llh_rate.y,
        e.llh_rate.z,
        k.heading_rate_radps,
        w_ib.x,
        w_ib.y,
        w_ib.z,
        f_b.x,
        f_b.y,
        f_b.z,
    ]
}

fn axpy(y: &State, a: f64, k: &State) -> State {
    let mut o = *y;
    for (oi, ki) in o.iter_mut().zip(k) {
        *oi += a * ki;
    }
    o
}

/// Steps a [`Motion`] through IMU intervals: the ideal increments of each interval and the
/// position and heading at its end.
#[derive(Debug, Clone)]
pub struct Integrator<M> {
    motion: M,
    t0_s: f64,
    dt_s: f64,
    n_sub: u32,
    k: u64,
    y: State,
}

impl<M: Motion> Integrator<M> {
    /// An integrator starting at `pos` with heading `heading_rad` (rad) at GPS time `t0_s`
    /// (s), IMU interval `dt_s` (s), `n_sub` RK4 sub-steps per interval (at least 1).
    pub fn new(motion: M, pos: Llh, heading_rad: f64, t0_s: f64, dt_s: f64, n_sub: u32) -> Self {
        let mut y = [0.0; 10];
        y[0] = pos.lat_rad;
        y[1] = pos.lon_rad;
        y[2] = pos.h_m;
        y[3] = heading_rad;
        Self {
            motion,
            t0_s,
            dt_s,
            n_sub: n_sub.max(1),
            k: 0,
            y,
        }
    }

    /// The motion.
    pub fn motion(&self) -> &M {
        &self.motion
    }

    /// GPS time of the start, s.
    pub fn t0_s(&self) -> f64 {
        self.t0_s
    }

    /// IMU interval, s.
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// Number of IMU intervals integrated so far.
    pub fn epochs(&self) -> u64 {
        self.k
    }

    /// Seconds since the start now (`epochs() * dt_s`), s.
    pub fn t_rel_s(&self) -> f64 {
        self.k as f64 * self.dt_s
    }

    /// Geodetic position now.
    pub fn pos(&self) -> Llh {
        Llh {
            lat_rad: self.y[0],
            lon_rad: self.y[1],
            h_m: self.y[2],
        }
    }

    /// The integrated heading now, rad (not wrapped).
    pub fn heading_rad(&self) -> f64 {
        self.y[3]
    }

    /// The motion's kinematics now.
    pub fn kinematics(&self) -> BodyKinematics {
        self.motion.at(self.t_rel_s(), self.y[3])
    }

    /// Integrates one IMU interval and returns its ideal sample, tagged with the GPS time of
    /// the interval's end (temperature NaN).
    pub fn step(&mut self) -> ImuSample {
        let dt = self.dt_s;
        let h = dt / self.n_sub as f64;
        let tk = self.k as f64 * dt;
        let mut y = self.y;
        for j in 0..self.n_sub {
            let t = tk + j as f64 * h;
            let k1 = deriv(&self.motion, t, &y);
            let k2 = deriv(&self.motion, t + 0.5 * h, &axpy(&y, 0.5 * h, &k1));
            let k3 = deriv(&self.motion, t + 0.5 * h, &axpy(&y, 0.5 * h, &k2));
            let k4 = deriv(&self.motion, t + h, &axpy(&y, h, &k3));
            for (i, yi) in y.iter_mut().enumerate() {
                *yi += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
        }
        self.k += 1;
        let imu = ImuSample {
            t_s: self.t0_s + self.k as f64 * dt,
            dtheta_rad: [y[4], y[5], y[6]],
            dv_mps: [y[7], y[8], y[9]],
            temperature_c: f64::NAN,
        };
        for v in &mut y[4..10] {
            *v = 0.0;
        }
        self.y = y;
        imu
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

    /// At rest and level the increments are the earth rate and minus gravity, rotated into
    /// the body, times the interval, and the position does not move.
    #[test]
    fn at_rest_the_increments_are_earth_rate_and_gravity() {
        struct Rest(Matrix3<f64>);
        impl Motion for Rest {
            fn at(&self, _t: f64, _h: f64) -> BodyKinematics {
                BodyKinematics {
                    vel_ned_mps: Vector3::zeros(),
                    acc_ned_mps2: Vector3::zeros(),
                    c_bn: self.0,
                    omega_nb_b_radps: Vector3::zeros(),
                    heading_rate_radps: 0.0,
                }
            }
        }
        let yaw = 0.7f64;
        let c_bn = *nalgebra::Rotation3::from_euler_angles(0.0, 0.0, yaw).matrix();
        let pos = Llh::from_deg(47.0, 8.0, 500.0);
        let mut it = Integrator::new(Rest(c_bn), pos, 0.0, 100.0, 0.01, 4);
        let s = it.step();
        let w = c_bn.transpose() * earth::earth_rate_ned_radps(pos.lat_rad) * 0.01;
        let f = -(c_bn.transpose() * earth::gravity_ned_mps2(pos.lat_rad, pos.h_m)) * 0.01;
        for i in 0..3 {
            assert!((s.dtheta_rad[i] - w[i]).abs() < 1e-18, "{s:?} {w:?}");
            assert!((s.dv_mps[i] - f[i]).abs() < 1e-15, "{s:?} {f:?}");
        }
        assert_eq!(s.t_s, 100.01);
        assert_eq!(it.pos(), pos);
        assert_eq!(it.epochs(), 1);
    }
}
