//! A small, self-contained INS/GNSS data generator for the filter tests (the full simulator
//! lives in host-sim). The truth trajectory is *defined* by integrating error-free increments
//! with the same strapdown algorithm at the IMU rate, so mechanisation error is exactly zero
//! and everything the filter sees comes from the sensor and GNSS errors drawn here:
//!
//! * accelerometer bias = b_GM (first-order Gauss-Markov, stationary start) + b_RW (random
//!   walk starting at N(0, bias_init_sigma^2)); gyro bias likewise (GM part only when the
//!   gyro S_B > 0); optional Gauss-Markov scale factors;
//! * white noise on the increments with variance S_N dt;
//! * GNSS antenna positions (and velocities) with white noise of the stated sigma, at integer
//!   seconds aligned with IMU epochs.
//!
//! The trajectory is a repeating 100 s drive: accelerations, decelerations, left and right
//! turns (heading and horizontal accelerometer biases become observable) and gentle vertical
//! undulation.
#![allow(dead_code, clippy::needless_range_loop)]

use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use nav_core::attitude;
use nav_core::config::FilterConfig;
use nav_core::earth::{self, Llh};
use nav_core::filter::{Filter, InitialUncertainty};
use nav_core::nav::{NavState, Strapdown};
use nav_core::scalar::Scalar;
use nav_core::types::{FixQuality, GnssFix, ImuSample};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// The motion of the test vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Motion {
    /// At rest.
    Static,
    /// The repeating 100 s drive.
    Drive,
}

/// Generator settings.
#[derive(Debug, Clone, Copy)]
pub struct SimConfig {
    /// IMU rate, Hz.
    pub imu_hz: f64,
    /// Sensor-error parameters of the truth (same meaning as the filter's).
    pub truth: FilterConfig,
    /// Whether the truth has Gauss-Markov scale-factor errors (sigma/time from `truth`).
    pub scale_factors: bool,
    /// GNSS position sigma N, E, D, m.
    pub gnss_pos_sigma_m: [f64; 3],
    /// GNSS velocity sigma (when `gnss_velocity`), m/s.
    pub gnss_vel_sigma_mps: [f64; 3],
    /// Whether fixes carry velocity.
    pub gnss_velocity: bool,
    /// Antenna lever arm, body FRD, m.
    pub lever_arm_body_m: [f64; 3],
    /// Motion profile.
    pub motion: Motion,
    /// Initial speed, m/s (drive).
    pub speed0_mps: f64,
}

impl SimConfig {
    /// NBK truth (the source's identified parameters), 100 Hz, RTK-grade GNSS.
    pub fn nbk(imu_hz: f64) -> Self {
        Self {
            imu_hz,
            truth: FilterConfig::source_nbk_model(),
            scale_factors: false,
            gnss_pos_sigma_m: [0.02, 0.02, 0.04],
            gnss_vel_sigma_mps: [0.02, 0.02, 0.04],
            gnss_velocity: false,
            lever_arm_body_m: [0.5, -0.3, -1.2],
            motion: Motion::Drive,
            speed0_mps: 10.0,
        }
    }
}

/// One generated IMU epoch.
#[derive(Debug, Clone, Copy)]
pub struct Epoch {
    /// The raw (erroneous) IMU sample.
    pub imu: ImuSample,
    /// The true state at the end of the sample.
    pub truth: NavState,
    /// A GNSS fix at this epoch, if one is due.
    pub gnss: Option<GnssFix>,
    /// True accelerometer bias (b_GM + b_RW), m/s^2, during the sample.
    pub accel_bias_mps2: [f64; 3],
    /// True gyro bias, rad/s.
    pub gyro_bias_radps: [f64; 3],
    /// True accelerometer scale-factor errors.
    pub accel_sf: [f64; 3],
    /// True gyro scale-factor errors.
    pub gyro_sf: [f64; 3],
}

/// Gauss-Markov + random-walk triad.
#[derive(Debug, Clone, Copy, Default)]
struct Bias {
    gm: [f64; 3],
    rw: [f64; 3],
}

/// The generator.
pub struct Sim {
    pub cfg: SimConfig,
    rng: ChaCha8Rng,
    truth: Strapdown,
    k: u64,
    t0_s: f64,
    dt_s: f64,
    accel: Bias,
    gyro: Bias,
    accel_sf: [f64; 3],
    gyro_sf: [f64; 3],
    heading_rad: f64,
    /// Inertial body rate of the last generated interval, rad/s.
    last_w_ib: Vector3<f64>,
}

/// Standard normal draw.
pub fn randn(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample(StandardNormal)
}

/// The start of every generated run: 1000 s of week, 47.1 N 15.4 E, 350 m, heading 30 deg.
pub fn initial_truth(speed_mps: f64) -> NavState {
    let yaw = 30f64.to_radians();
    NavState::from_rpy(
        1000.0,
        Llh::from_deg(47.1, 15.4, 350.0),
        Vector3::new(speed_mps * yaw.cos(), speed_mps * yaw.sin(), 0.0),
        [0.0, 0.0, yaw],
    )
}

impl Sim {
    /// A generator with the given settings and seed.
    pub fn new(cfg: SimConfig, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let speed = if cfg.motion == Motion::Static {
            0.0
        } else {
            cfg.speed0_mps
        };
        let init = initial_truth(speed);
        let draw_bias = |n: &nav_core::config::SensorNoise, rng: &mut ChaCha8Rng| {
            let mut b = Bias::default();
            for i in 0..3 {
                b.gm[i] = (0.5 * n.s_b[i] * n.t_b_s).sqrt() * randn(rng);
                b.rw[i] = n.bias_init_sigma[i] * randn(rng);
            }
            b
        };
        let accel = draw_bias(&cfg.truth.accel, &mut rng);
        let gyro = draw_bias(&cfg.truth.gyro, &mut rng);
        let mut accel_sf = [0.0; 3];
        let mut gyro_sf = [0.0; 3];
        if cfg.scale_factors {
            for i in 0..3 {
                accel_sf[i] = cfg.truth.accel_scale.sigma[i] * randn(&mut rng);
                gyro_sf[i] = cfg.truth.gyro_scale.sigma[i] * randn(&mut rng);
            }
        }
        Self {
            cfg,
            rng,
            truth: Strapdown::new(init),
            k: 0,
            t0_s: init.t_s,
            dt_s: 1.0 / cfg.imu_hz,
            accel,
            gyro,
            accel_sf,
            gyro_sf,
            heading_rad: 30f64.to_radians(),
            last_w_ib: Vector3::zeros(),
        }
    }

    /// The true state now.
    pub fn truth(&self) -> &NavState {
        self.truth.state()
    }

    /// Desired NED acceleration (m/s^2) and yaw rate (rad/s) at time `tau` into the run.
    fn profile(&self, tau: f64, v: &Vector3<f64>) -> (Vector3<f64>, f64) {
        if self.cfg.motion == Motion::Static {
            return (Vector3::zeros(), 0.0);
        }
        let ph = tau % 100.0;
        let (along, yaw_rate) = match ph {
            p if p < 10.0 => (1.0, 0.0),
            p if p < 20.0 => (0.0, 0.0),
            p if p < 35.0 => (0.0, 0.12),
            p if p < 45.0 => (-1.0, 0.0),
            p if p < 55.0 => (0.0, 0.0),
            p if p < 70.0 => (0.0, -0.12),
            p if p < 80.0 => (0.5, 0.0),
            p if p < 90.0 => (-0.5, 0.0),
            p => (
                0.0,
                0.06 * (2.0 * std::f64::consts::PI * (p - 90.0) / 10.0).sin(),
            ),
        };
        let hdg = Vector3::new(self.heading_rad.cos(), self.heading_rad.sin(), 0.0);
        let centripetal = Vector3::new(-yaw_rate * v.y, yaw_rate * v.x, 0.0);
        let vertical = 0.15 * (2.0 * std::f64::consts::PI * tau / 37.0).sin();
        (
            hdg * along + centripetal + Vector3::new(0.0, 0.0, vertical),
            yaw_rate,
        )
    }

    /// Generates the next IMU epoch.
    pub fn step(&mut self) -> Epoch {
        let dt = self.dt_s;
        let s = *self.truth.state();
        let tau = self.k as f64 * dt;
        let (a_n, yaw_rate) = self.profile(tau + 0.5 * dt, &s.vel_ned_mps);
        let lat = s.pos.lat_rad;
        let w_ie = earth::earth_rate_ned_radps(lat);
        let w_en = earth::transport_rate_ned_radps(lat, s.pos.h_m, &s.vel_ned_mps);
        let c = s.q_nb.to_rotation_matrix().into_inner();
        let w_ib = Vector3::new(0.0, 0.0, yaw_rate) + c.transpose() * (w_ie + w_en);
        let dtheta = w_ib * dt;
        self.last_w_ib = w_ib;
        let g = earth::gravity_ned_mps2(lat, s.pos.h_m);
        let f_n = a_n - g + (2.0 * w_ie + w_en).cross(&s.vel_ned_mps);
        let c_mid = c * attitude::dcm_from_rotvec(&(dtheta * 0.5));
        let dv = c_mid.transpose() * f_n * dt;
        self.k += 1;
        let t = self.t0_s + self.k as f64 * dt;
        let clean = ImuSample {
            t_s: t,
            dtheta_rad: dtheta.into(),
            dv_mps: dv.into(),
            temperature_c: f64::NAN,
        };
        let st = self.truth.update(&clean).expect("truth mechanisation");
        let _ = st;
        self.heading_rad += yaw_rate * dt;

        // sensor errors during this sample
        let ab = self.bias_total(true);
        let gb = self.bias_total(false);
        let tr = &self.cfg.truth;
        let mut imu = clean;
        for i in 0..3 {
            imu.dtheta_rad[i] = (1.0 + self.gyro_sf[i]) * dtheta[i]
                + gb[i] * dt
                + (tr.gyro.s_n[i] * dt).sqrt() * randn(&mut self.rng);
            imu.dv_mps[i] = (1.0 + self.accel_sf[i]) * dv[i]
                + ab[i] * dt
                + (tr.accel.s_n[i] * dt).sqrt() * randn(&mut self.rng);
        }
        let epoch_accel_sf = self.accel_sf;
        let epoch_gyro_sf = self.gyro_sf;
        self.advance_errors(dt);

        let truth = *self.truth.state();
        let gnss = if self.k.is_multiple_of(self.cfg.imu_hz.round() as u64) {
            Some(self.fix(&truth))
        } else {
            None
        };
        Epoch {
            imu,
            truth,
            gnss,
            accel_bias_mps2: ab,
            gyro_bias_radps: gb,
            accel_sf: epoch_accel_sf,
            gyro_sf: epoch_gyro_sf,
        }
    }

    fn bias_total(&self, accel: bool) -> [f64; 3] {
        let b = if accel { &self.accel } else { &self.gyro };
        [b.gm[0] + b.rw[0], b.gm[1] + b.rw[1], b.gm[2] + b.rw[2]]
    }

    fn advance_errors(&mut self, dt: f64) {
        let tr = self.cfg.truth;
        for (b, n) in [(&mut self.accel, &tr.accel), (&mut self.gyro, &tr.gyro)] {
            let phi = (-dt / n.t_b_s).exp();
            for i in 0..3 {
                let q = 0.5 * n.s_b[i] * n.t_b_s * (1.0 - phi * phi);
                b.gm[i] = phi * b.gm[i] + q.sqrt() * randn(&mut self.rng);
                b.rw[i] += (n.s_k[i] * dt).sqrt() * randn(&mut self.rng);
            }
        }
        if self.cfg.scale_factors {
            for (s, p) in [
                (&mut self.accel_sf, &tr.accel_scale),
                (&mut self.gyro_sf, &tr.gyro_scale),
            ] {
                let phi = (-dt / p.t_s).exp();
                for i in 0..3 {
                    let q = p.sigma[i] * p.sigma[i] * (1.0 - phi * phi);
                    s[i] = phi * s[i] + q.sqrt() * randn(&mut self.rng);
                }
            }
        }
    }

    fn fix(&mut self, truth: &NavState) -> GnssFix {
        let c = truth.q_nb.to_rotation_matrix().into_inner();
        let l = Vector3::from(self.cfg.lever_arm_body_m);
        let mut n = Vector3::zeros();
        for i in 0..3 {
            n[i] = self.cfg.gnss_pos_sigma_m[i] * randn(&mut self.rng);
        }
        let ant = earth::displace(&truth.pos, &(c * l));
        let p = earth::displace(&ant, &n);
        let mut vel = [0.0; 3];
        if self.cfg.gnss_velocity {
            let w = self.truth_omega_b();
            let lat = truth.pos.lat_rad;
            let w_in = earth::earth_rate_ned_radps(lat)
                + earth::transport_rate_ned_radps(lat, truth.pos.h_m, &truth.vel_ned_mps);
            let v = truth.vel_ned_mps + c * w.cross(&l) - w_in.cross(&(c * l));
            for i in 0..3 {
                vel[i] = v[i] + self.cfg.gnss_vel_sigma_mps[i] * randn(&mut self.rng);
            }
        }
        GnssFix {
            t_s: truth.t_s,
            lat_rad: p.lat_rad,
            lon_rad: p.lon_rad,
            h_m: p.h_m,
            pos_std_ned_m: self.cfg.gnss_pos_sigma_m,
            vel_ned_mps: vel,
            vel_std_ned_mps: self.cfg.gnss_vel_sigma_mps,
            has_velocity: self.cfg.gnss_velocity,
            quality: FixQuality::RtkFixed,
            num_sats: 20,
        }
    }

    /// Body angular rate (inertial) of the truth: the mean over the last interval (the
    /// rate is piecewise constant, so this is also the rate at the fix time except at a
    /// segment switch, where the filter sees the same mean), rad/s.
    fn truth_omega_b(&self) -> Vector3<f64> {
        self.last_w_ib
    }

    /// A filter initial state: the truth perturbed by draws from `unc` (seeded by `rng`).
    pub fn perturbed_initial(&mut self, unc: &InitialUncertainty) -> NavState {
        let mut s = *self.truth.state();
        let mut phi = Vector3::zeros();
        for i in 0..3 {
            phi[i] = unc.att_sigma_rad[i] * randn(&mut self.rng);
            s.vel_ned_mps[i] += unc.vel_sigma_mps[i] * randn(&mut self.rng);
        }
        let mut dr = Vector3::zeros();
        for i in 0..3 {
            dr[i] = unc.pos_sigma_m[i] * randn(&mut self.rng);
        }
        // C_hat = (I - [phi x]) C  =>  q_hat = q(-phi) q
        s.q_nb = attitude::quat_from_rotvec(&(-phi)) * s.q_nb;
        s.pos = earth::displace(&s.pos, &dr);
        s
    }
}

/// Errors (estimate minus truth) of a state: attitude phi (NED, rad), velocity (m/s),
/// position (NED, m).
pub fn nav_errors(est: &NavState, truth: &NavState) -> ([f64; 3], [f64; 3], [f64; 3]) {
    // C = (I + [phi x]) C_hat  =>  q(phi) = q q_hat^-1
    let q_err: UnitQuaternion<f64> = truth.q_nb * est.q_nb.inverse();
    let phi = attitude::rotvec_from_quat(&q_err);
    let dv = est.vel_ned_mps - truth.vel_ned_mps;
    let dr = earth::ned_offset_m(&truth.pos, &est.pos);
    (phi.into(), dv.into(), dr.into())
}

/// `e^T P^-1 e` for the 3x3 block of `p` starting at `i0` (as f64).
pub fn nees3<T: Scalar, const N: usize>(p: &[[T; N]; N], i0: usize, e: &[f64; 3]) -> f64 {
    let m = Matrix3::from_fn(|i, j| p[i0 + i][i0 + j].to_f64());
    let inv = m.try_inverse().expect("3x3 block invertible");
    let v = Vector3::from(*e);
    (v.transpose() * inv * v)[0]
}

/// A default initial uncertainty for the tests: 0.05/0.05/0.3 deg, 0.05 m/s, 0.3 m.
pub fn test_uncertainty() -> InitialUncertainty {
    InitialUncertainty {
        att_sigma_rad: [
            0.05f64.to_radians(),
            0.05f64.to_radians(),
            0.3f64.to_radians(),
        ],
        vel_sigma_mps: [0.05; 3],
        pos_sigma_m: [0.3; 3],
    }
}

/// Builds a filter started from a perturbed truth.
pub fn start_filter<T: Scalar, const N: usize>(
    sim: &mut Sim,
    layout: nav_core::model::Layout,
    cfg: &FilterConfig,
    unc: &InitialUncertainty,
) -> Filter<T, N> {
    let init = sim.perturbed_initial(unc);
    Filter::new(layout, cfg, init, unc).expect("filter construction")
}

/// ln Gamma(x) (Lanczos, g = 7, n = 9), for x > 0.
fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised lower incomplete gamma P(a, x) by its series (fine for the moderate
/// arguments used here).
fn gamma_p(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    let mut sum = 1.0 / a;
    let mut term = sum;
    let mut n = 1.0;
    while term > sum * 1e-16 && n < 10_000.0 {
        term *= x / (a + n);
        sum += term;
        n += 1.0;
    }
    (sum.ln() - x + a * x.ln() - ln_gamma(a)).exp()
}

/// Chi-square CDF with `dof` degrees of freedom.
pub fn chi2_cdf(x: f64, dof: f64) -> f64 {
    gamma_p(0.5 * dof, 0.5 * x)
}

/// Chi-square quantile by bisection.
pub fn chi2_quantile(p: f64, dof: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, dof * 10.0 + 100.0);
    for _ in 0..200 {
        let m = 0.5 * (lo + hi);
        if chi2_cdf(m, dof) < p {
            lo = m;
        } else {
            hi = m;
        }
    }
    0.5 * (lo + hi)
}
