//! Analytic motions for the mechanization and alignment tests, integrated by the
//! workspace's one truth generator (`nav_sim::Integrator`).
//!
//! A motion is given by smooth analytic functions of time: NED velocity and its time
//! derivative, the attitude C_b^n and the body rate relative to NED omega_nb^b. `nav_sim`
//! integrates the geodetic position from the velocity and, over each IMU interval, the ideal
//! sensor outputs
//!
//! ```text
//! dtheta = integral of omega_ib^b dt,  omega_ib^b = omega_nb^b + C_n^b (omega_ie^n + omega_en^n)
//! dv     = integral of f^b dt,         f^b = C_n^b (dv^n/dt + (2 omega_ie^n + omega_en^n) x v^n - g^n)
//! ```
//!
//! (what a perfect rate-integrating IMU outputs), all with one classical fourth-order
//! Runge-Kutta pass over `n_sub` sub-steps per IMU interval (position is the ODE state, the two
//! integrals are quadratures along it). It uses `nav_core::earth`'s WGS84 formulas (tested on
//! their own), and nothing of the mechanization or of `nav_core::attitude`: Euler angles go
//! through nalgebra, Euler rates through the formula written out here.
#![allow(dead_code)]

use nalgebra::{UnitQuaternion, Vector3};
use nav_core::earth::Llh;
use nav_core::types::ImuSample;
use std::f64::consts::TAU;

/// The state of a motion at one instant.
#[derive(Debug, Clone, Copy)]
pub struct Kinematics {
    /// Velocity relative to the earth in NED, m/s.
    pub vel_ned_mps: Vector3<f64>,
    /// Time derivative of the NED velocity components, m/s^2.
    pub acc_ned_mps2: Vector3<f64>,
    /// Attitude C_b^n.
    pub q_nb: UnitQuaternion<f64>,
    /// Body rate relative to NED in body axes, rad/s.
    pub omega_nb_b_radps: Vector3<f64>,
}

/// A smooth motion, `t` in seconds since the start of the run.
pub trait Motion {
    /// The kinematics at time `t` (s).
    fn at(&self, t: f64) -> Kinematics;
}

/// `c0 + c1 t + sum a sin(2 pi t / period + phase)` with its derivative (C-infinity).
#[derive(Debug, Clone, Default)]
pub struct Sines {
    /// Constant term.
    pub c0: f64,
    /// Linear term, per second.
    pub c1: f64,
    /// (amplitude, period s, phase rad).
    pub terms: Vec<(f64, f64, f64)>,
}

impl Sines {
    /// A constant.
    pub fn constant(c0: f64) -> Self {
        Self {
            c0,
            ..Default::default()
        }
    }

    /// Value and first time derivative at `t` (s).
    pub fn eval(&self, t: f64) -> (f64, f64) {
        let mut v = self.c0 + self.c1 * t;
        let mut d = self.c1;
        for &(a, p, ph) in &self.terms {
            let w = TAU / p;
            let x = w * t + ph;
            v += a * x.sin();
            d += a * w * x.cos();
        }
        (v, d)
    }
}

/// A land vehicle: it moves along its body x axis with `speed` (m/s) in the direction given
/// by yaw and pitch; attitude from yaw, pitch, roll (rad, ZYX).
#[derive(Debug, Clone)]
pub struct CarMotion {
    /// Speed along the body x axis, m/s.
    pub speed_mps: Sines,
    /// Yaw (heading), rad.
    pub yaw_rad: Sines,
    /// Pitch (road slope), rad.
    pub pitch_rad: Sines,
    /// Roll, rad.
    pub roll_rad: Sines,
}

/// omega_nb^b from ZYX Euler angles and rates (written out independently of nav-core).
pub fn euler_body_rate(roll: f64, pitch: f64, rd: f64, pd: f64, yd: f64) -> Vector3<f64> {
    Vector3::new(
        rd - yd * pitch.sin(),
        pd * roll.cos() + yd * roll.sin() * pitch.cos(),
        -pd * roll.sin() + yd * roll.cos() * pitch.cos(),
    )
}

impl Motion for CarMotion {
    fn at(&self, t: f64) -> Kinematics {
        let (s, sd) = self.speed_mps.eval(t);
        let (y, yd) = self.yaw_rad.eval(t);
        let (p, pd) = self.pitch_rad.eval(t);
        let (r, rd) = self.roll_rad.eval(t);
        let (sy, cy) = y.sin_cos();
        let (sp, cp) = p.sin_cos();
        let u = Vector3::new(cp * cy, cp * sy, -sp);
        let du_dy = Vector3::new(-cp * sy, cp * cy, 0.0);
        let du_dp = Vector3::new(-sp * cy, -sp * sy, -cp);
        Kinematics {
            vel_ned_mps: u * s,
            acc_ned_mps2: u * sd + (du_dy * yd + du_dp * pd) * s,
            q_nb: UnitQuaternion::from_euler_angles(r, p, y),
            omega_nb_b_radps: euler_body_rate(r, p, rd, pd, yd),
        }
    }
}

/// At rest with a fixed attitude.
#[derive(Debug, Clone, Copy)]
pub struct Static {
    /// Attitude C_b^n.
    pub q_nb: UnitQuaternion<f64>,
}

impl Motion for Static {
    fn at(&self, _t: f64) -> Kinematics {
        Kinematics {
            vel_ned_mps: Vector3::zeros(),
            acc_ned_mps2: Vector3::zeros(),
            q_nb: self.q_nb,
            omega_nb_b_radps: Vector3::zeros(),
        }
    }
}

/// Classical coning at rest: C_b^n(t) = q0 * q_c(t) with
/// q_c = [cos(a/2), 0, sin(a/2) cos(W t), sin(a/2) sin(W t)] (scalar first): the body x axis
/// of q_c sweeps a cone of half-angle `a` at angular frequency `W`, and
/// omega_nb^b = (-2 sin^2(a/2) W, -W sin a sin Wt, W sin a cos Wt).
#[derive(Debug, Clone, Copy)]
pub struct Coning {
    /// Mean attitude C_b^n.
    pub q0: UnitQuaternion<f64>,
    /// Cone half-angle a, rad.
    pub half_angle_rad: f64,
    /// Coning angular frequency W, rad/s.
    pub freq_radps: f64,
}

impl Coning {
    /// The coning rotation q_c(t).
    pub fn q_c(&self, t: f64) -> UnitQuaternion<f64> {
        let (s, c) = (0.5 * self.half_angle_rad).sin_cos();
        let x = self.freq_radps * t;
        UnitQuaternion::new_normalize(nalgebra::Quaternion::new(c, 0.0, s * x.cos(), s * x.sin()))
    }
}

impl Motion for Coning {
    fn at(&self, t: f64) -> Kinematics {
        let a = self.half_angle_rad;
        let w = self.freq_radps;
        let s = (0.5 * a).sin();
        let x = w * t;
        Kinematics {
            vel_ned_mps: Vector3::zeros(),
            acc_ned_mps2: Vector3::zeros(),
            q_nb: self.q0 * self.q_c(t),
            omega_nb_b_radps: Vector3::new(
                -2.0 * s * s * w,
                -w * a.sin() * x.sin(),
                w * a.sin() * x.cos(),
            ),
        }
    }
}

/// The true navigation state at the end of an IMU interval.
#[derive(Debug, Clone, Copy)]
pub struct Truth {
    /// GPS seconds of week, s.
    pub t_s: f64,
    /// Geodetic position.
    pub pos: Llh,
    /// NED velocity, m/s.
    pub vel_ned_mps: Vector3<f64>,
    /// Attitude C_b^n.
    pub q_nb: UnitQuaternion<f64>,
}

/// An analytic [`Motion`] as a `nav_sim` motion (closed-form attitude; the integrator's
/// heading state is not used).
#[derive(Debug, Clone)]
pub struct Analytic<M>(pub M);

impl<M: Motion> nav_sim::Motion for Analytic<M> {
    fn at(&self, t_s: f64, _heading_rad: f64) -> nav_sim::BodyKinematics {
        let k = self.0.at(t_s);
        nav_sim::BodyKinematics {
            vel_ned_mps: k.vel_ned_mps,
            acc_ned_mps2: k.acc_ned_mps2,
            c_bn: k.q_nb.to_rotation_matrix().into_inner(),
            omega_nb_b_radps: k.omega_nb_b_radps,
            heading_rate_radps: 0.0,
        }
    }
}

/// Steps a motion through IMU intervals, producing ideal increments and the truth: the
/// workspace's one integrator ([`nav_sim::Integrator`]) with the truth attitude and velocity
/// taken from the motion's closed form.
pub struct Generator<M: Motion> {
    integ: nav_sim::Integrator<Analytic<M>>,
}

impl<M: Motion> Generator<M> {
    /// A generator starting at `pos` at GPS time `t0_s` (s), IMU interval `dt_s` (s), `n_sub`
    /// RK4 sub-steps per interval.
    pub fn new(motion: M, pos: Llh, t0_s: f64, dt_s: f64, n_sub: usize) -> Self {
        let n_sub = u32::try_from(n_sub).unwrap_or(u32::MAX);
        Self {
            integ: nav_sim::Integrator::new(Analytic(motion), pos, 0.0, t0_s, dt_s, n_sub),
        }
    }

    /// The motion.
    pub fn motion(&self) -> &M {
        &self.integ.motion().0
    }

    /// The current truth.
    pub fn truth(&self) -> Truth {
        let t = self.integ.t_rel_s();
        let kin = self.motion().at(t);
        Truth {
            t_s: self.integ.t0_s() + t,
            pos: self.integ.pos(),
            vel_ned_mps: kin.vel_ned_mps,
            q_nb: kin.q_nb,
        }
    }

    /// Integrates one IMU interval: the ideal sample for it and the truth at its end.
    pub fn step(&mut self) -> (ImuSample, Truth) {
        let imu = self.integ.step();
        (imu, self.truth())
    }
}

/// The vehicle profile of the dynamic tests: 8-22 m/s with accelerations up to about
/// 1.5 m/s^2, turns up to 0.25 rad/s (lateral acceleration up to about 5 m/s^2), hills of
/// +-2.5 deg, and body pitch/roll oscillations at 0.6 Hz and 2.2 Hz.
pub fn driving_profile() -> CarMotion {
    CarMotion {
        speed_mps: Sines {
            c0: 15.0,
            c1: 0.0,
            terms: vec![(5.0, 97.0, 0.3), (2.0, 23.0, 1.1), (0.3, 3.1, 0.0)],
        },
        yaw_rad: Sines {
            c0: 0.8,
            c1: 0.01,
            terms: vec![(0.9, 61.0, 0.0), (0.25, 17.0, 0.4), (0.02, 2.3, 0.0)],
        },
        pitch_rad: Sines {
            c0: 0.0,
            c1: 0.0,
            terms: vec![(0.03, 71.0, 0.2), (0.015, 13.0, 2.0), (0.004, 1.7, 0.5)],
        },
        roll_rad: Sines {
            c0: 0.0,
            c1: 0.0,
            terms: vec![(0.02, 29.0, 1.0), (0.005, 1.1, 0.0), (0.003, 0.45, 0.7)],
        },
    }
}
