//! A small INS/GNSS data generator for the filter tests (the full simulator is
//! `host-sim simulate`). The truth and the error-free increments come from the workspace's one
//! truth generator (`nav_sim::Integrator`, RK4 with 4 sub-steps per IMU interval) driven by the
//! test vehicle ([`Motion`]); what the filter sees beyond the sensor and GNSS errors is the
//! mechanization's own (second-order) error on these increments: over 300 s at
//! 100 Hz 0.43 mm, 3e-6 m/s and 1.1e-10 rad on the drive, 3.6 cm, 2.6e-4 m/s and 1.5e-7 rad
//! on the drive with wobble (test-support's test `filter_sim_truth`
//! measures it; a truth taken from the strapdown's own output would make this error zero by
//! construction).
//!
//! The errors are not drawn here: the generator's settings become a `nav_sim` error model
//! ([`error_model`]) and every sample goes through `nav_sim::errors::ImuErrors`, every fix's
//! noise comes from `nav_sim::errors::GnssNoise` (the simulator's model and per-seed streams,
//! the ones `host-sim simulate` applies; sample by sample they give `ErrorModel::apply_imu`'s
//! values, the test at the end of this file):
//!
//! * accelerometer bias = Gauss-Markov (S_B, T_B, stationary start) + random walk (S_K,
//!   from 0) + a turn-on constant of sigma `bias_init_sigma` (together the filter's random
//!   walk starting at `N(0, bias_init_sigma^2)`); gyro bias likewise;
//! * white noise on the increments with variance S_N dt;
//! * optional Gauss-Markov scale factors (stationary sigma and correlation time from
//!   `truth`; `nav_sim::errors::ScaleFactorGm`);
//! * GNSS antenna positions (and velocities) with white noise of the stated sigma, at integer
//!   seconds aligned with IMU epochs.
//!
//! The trajectory is a repeating 100 s drive: accelerations, decelerations, left and right
//! turns (heading and horizontal accelerometer biases become observable) and gentle vertical
//! undulation; optionally ([`SimConfig::wobble`]) with roll and pitch oscillations of the
//! body (+-2 deg at 7 s, +-1.5 deg at 11 s) so the x and y gyros see rates too. The
//! along-track acceleration and the yaw rate are held over each IMU interval (the profile at
//! the interval's midpoint), so every change of manoeuvre falls on an IMU epoch.
//!
//! Effects ([`TruthEffects`], all zero by default, the effect blocks' vocabulary): fixed scale
//! factors, axis misalignments, temperature-driven biases along a warm-up temperature profile
//! (the samples then carry the temperature), diagonal gyro g-sensitivity, and a GNSS time
//! offset (a fix tagged `t` is the antenna at `t + offset`). The sensor model is `nav_sim`'s
//! and the filter's (`docs/derivations/error_state.md`, section 5.1), on the increments:
//!
//! ```text
//! dtheta_meas = (I + diag(s_g) + M_g) dtheta + diag(g_s) dv + (b_g + k_g dT) dt + noise
//! dv_meas     = (I + diag(s_a) + M_a) dv                    + (b_a + k_a dT) dt + noise
//! ```
//!
//! with `dT dt` the integral of the temperature difference over the sample.
#![allow(dead_code, clippy::needless_range_loop)]

use crate::trajectory::euler_body_rate;
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use nav_core::attitude;
use nav_core::config::FilterConfig;
use nav_core::earth::{self, Llh};
use nav_core::filter::{Filter, InitialUncertainty};
use nav_core::scalar::Scalar;
use nav_core::strapdown::NavState;
use nav_core::types::{FixQuality, GnssFix, ImuSample};
use nav_sim::errors::{
    Axes3, GnssErrors, GnssNoise, ImuErrors, ScaleFactorGm, SensorErrors, Temperature,
};
use nav_sim::ErrorModel;
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
    /// Laps of an oval track, always turning left: 20 s straights (accelerating at
    /// 0.5 m/s^2, then braking) and half circles at 0.12 rad/s (26.2 s); heading errors
    /// proportional to the turned angle (gyro scale factor) accumulate instead of cancelling.
    Track,
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
    /// Roll/pitch oscillation of the body during the drive.
    pub wobble: bool,
    /// Undeclared effects in the data.
    pub effects: TruthEffects,
}

/// A warm-up temperature profile `T(t) = start + rise (1 - e^(-t/tau))`, degC.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TempProfile {
    /// Temperature at the start, degC.
    pub start_c: f64,
    /// Total rise, degC.
    pub rise_c: f64,
    /// Time constant, s.
    pub tau_s: f64,
}

impl TempProfile {
    /// Temperature `tau` seconds into the run, degC.
    pub fn at(&self, tau: f64) -> f64 {
        self.start_c + self.rise_c * (1.0 - (-tau / self.tau_s).exp())
    }
}

/// The effects in the simulated data (SI units; misalignment order
/// `[m_xy, m_xz, m_yx, m_yz, m_zx, m_zy]`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TruthEffects {
    /// Fixed accelerometer scale-factor errors (added to any Gauss-Markov ones).
    pub accel_sf: [f64; 3],
    /// Fixed gyro scale-factor errors.
    pub gyro_sf: [f64; 3],
    /// Accelerometer misalignment, rad.
    pub accel_mis_rad: [f64; 6],
    /// Gyro misalignment, rad.
    pub gyro_mis_rad: [f64; 6],
    /// Accelerometer bias temperature coefficient, m/s^2/degC.
    pub accel_temp_coeff: [f64; 3],
    /// Gyro bias temperature coefficient, rad/s/degC.
    pub gyro_temp_coeff: [f64; 3],
    /// Temperature of the IMU (None: samples carry no temperature); the reference of the
    /// coefficients is the start temperature.
    pub temperature: Option<TempProfile>,
    /// Diagonal gyro g-sensitivity, rad/s per m/s^2.
    pub gyro_g_sens: [f64; 3],
    /// GNSS time offset, s: a fix tagged t is the antenna at t + offset.
    pub gnss_time_offset_s: f64,
}

impl TruthEffects {
    fn imu_active(&self) -> bool {
        let nz = |a: &[f64]| a.iter().any(|v| *v != 0.0);
        nz(&self.accel_sf)
            || nz(&self.gyro_sf)
            || nz(&self.accel_mis_rad)
            || nz(&self.gyro_mis_rad)
            || nz(&self.accel_temp_coeff)
            || nz(&self.gyro_temp_coeff)
            || nz(&self.gyro_g_sens)
    }
}

/// `M v` for a misalignment vector `[m_xy, m_xz, m_yx, m_yz, m_zx, m_zy]`.
pub fn mis_times(m: &[f64; 6], v: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(
        m[0] * v.y + m[1] * v.z,
        m[2] * v.x + m[3] * v.z,
        m[4] * v.x + m[5] * v.y,
    )
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
            wobble: false,
            effects: TruthEffects::default(),
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
    /// True accelerometer bias (turn-on constant + Gauss-Markov + random walk, the filter's
    /// b_GM + b_RW), m/s^2, during the sample.
    pub accel_bias_mps2: [f64; 3],
    /// True gyro bias, rad/s.
    pub gyro_bias_radps: [f64; 3],
    /// True Gauss-Markov accelerometer scale-factor errors during the sample (zero unless
    /// [`SimConfig::scale_factors`]; the fixed [`TruthEffects::accel_sf`] not included).
    pub accel_sf: [f64; 3],
    /// True Gauss-Markov gyro scale-factor errors (as `accel_sf`).
    pub gyro_sf: [f64; 3],
}

/// The sensor-error model of a sensor triad's noise parameters (`nav_sim`'s): white noise
/// S_N, Gauss-Markov S_B/T_B (stationary start), random walk S_K (from 0) and the random
/// walk's start as a turn-on bias of sigma `bias_init_sigma` (the sum has the filter's
/// `N(0, bias_init_sigma^2)` start).
fn sensor_errors(n: &nav_core::config::SensorNoise) -> SensorErrors {
    SensorErrors {
        white_psd: Axes3(n.s_n),
        gm_psd: Axes3(n.s_b),
        gm_tau_s: Axes3::splat(n.t_b_s),
        rw_psd: Axes3(n.s_k),
        turn_on_bias_sigma: Axes3(n.bias_init_sigma),
        ..SensorErrors::default()
    }
}

/// `nav_sim`'s misalignment matrix (row = sensor axis, column = body axis) of a misalignment
/// vector `[m_xy, m_xz, m_yx, m_yz, m_zx, m_zy]`, rad.
fn mis_matrix(m: &[f64; 6]) -> [[f64; 3]; 3] {
    [[0.0, m[0], m[1]], [m[2], 0.0, m[3]], [m[4], m[5], 0.0]]
}

/// The `nav_sim` error model of the generator's settings: the truth's sensor noise
/// ([`SimConfig::truth`]), its Gauss-Markov scale factors when [`SimConfig::scale_factors`],
/// the effects ([`TruthEffects`]: fixed scale factors, misalignment, diagonal gyro
/// g-sensitivity, temperature coefficients along the warm-up profile) and the GNSS white
/// noise (the generator makes the fixes itself: lever arm, time offset, 1 Hz).
pub fn error_model(cfg: &SimConfig) -> ErrorModel {
    let fx = &cfg.effects;
    let tr = &cfg.truth;
    let gm = |p: &nav_core::config::ScaleFactorNoise| {
        cfg.scale_factors.then(|| ScaleFactorGm {
            sigma_ppm: Axes3(p.sigma.map(|v| v * 1e6)),
            tau_s: p.t_s,
        })
    };
    let mut accel = sensor_errors(&tr.accel);
    accel.scale_factor_ppm = Axes3(fx.accel_sf.map(|v| v * 1e6));
    accel.scale_factor_gm = gm(&tr.accel_scale);
    accel.misalignment_rad = mis_matrix(&fx.accel_mis_rad);
    accel.temp_coeff_per_c = Axes3(fx.accel_temp_coeff);
    let mut gyro = sensor_errors(&tr.gyro);
    gyro.scale_factor_ppm = Axes3(fx.gyro_sf.map(|v| v * 1e6));
    gyro.scale_factor_gm = gm(&tr.gyro_scale);
    gyro.misalignment_rad = mis_matrix(&fx.gyro_mis_rad);
    gyro.temp_coeff_per_c = Axes3(fx.gyro_temp_coeff);
    for i in 0..3 {
        gyro.g_sensitivity_radps_per_mps2[i][i] = fx.gyro_g_sens[i];
    }
    ErrorModel {
        name: "filter_sim".into(),
        accel,
        gyro,
        temperature: fx.temperature.map(|t| Temperature {
            start_c: t.start_c,
            rise_c: t.rise_c,
            tau_s: t.tau_s,
            reference_c: None,
            report_noise_c: 0.0,
        }),
        gnss: GnssErrors {
            rate_hz: 1.0,
            white_sigma_ned_m: Axes3(cfg.gnss_pos_sigma_m),
            gm_sigma_ned_m: Axes3::default(),
            vel_white_sigma_ned_mps: Axes3(cfg.gnss_vel_sigma_mps),
            ..GnssErrors::default()
        },
        imu_clock_drift_ppm: 0.0,
    }
}

/// The test vehicle as a `nav_sim` motion: along-track acceleration and yaw rate held over
/// each IMU interval, the speed from them, the heading integrated by `nav_sim`, the vertical
/// velocity and the wobble closed-form.
#[derive(Debug, Clone)]
struct DriveMotion {
    motion: Motion,
    wobble: bool,
    /// Start of the current IMU interval, s from the run start.
    t_start_s: f64,
    /// Speed at `t_start_s`, m/s.
    speed0_mps: f64,
    /// Along-track acceleration held over the interval, m/s^2.
    along_mps2: f64,
    /// Yaw rate held over the interval, rad/s.
    yaw_rate_radps: f64,
}

/// Vertical (down) acceleration amplitude of the drive's undulation, m/s^2, and its period, s.
const UNDULATION: (f64, f64) = (0.15, 37.0);

impl DriveMotion {
    /// Along-track acceleration (m/s^2) and yaw rate (rad/s) at `tau` s into the run.
    fn profile(&self, tau: f64) -> (f64, f64) {
        if self.motion == Motion::Static {
            return (0.0, 0.0);
        }
        let half_circle_s = std::f64::consts::PI / 0.12;
        let lap_s = 40.0 + 2.0 * half_circle_s;
        let ph = tau % 100.0;
        match ph {
            _ if self.motion == Motion::Track => match (tau % lap_s) % (lap_s / 2.0) {
                p if p < 10.0 => (0.5, 0.0),
                p if p < 20.0 => (-0.5, 0.0),
                _ => (0.0, 0.12),
            },
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
        }
    }
}

impl nav_sim::Motion for DriveMotion {
    fn begin_interval(&mut self, t0_s: f64, t1_s: f64) {
        self.speed0_mps += self.along_mps2 * (t0_s - self.t_start_s);
        self.t_start_s = t0_s;
        (self.along_mps2, self.yaw_rate_radps) = self.profile(0.5 * (t0_s + t1_s));
    }

    fn at(&self, t: f64, heading_rad: f64) -> nav_sim::BodyKinematics {
        let moving = self.motion != Motion::Static;
        let speed = self.speed0_mps + self.along_mps2 * (t - self.t_start_s);
        let (s, c) = heading_rad.sin_cos();
        let hdg = Vector3::new(c, s, 0.0);
        let left = Vector3::new(-s, c, 0.0);
        let (mut vd, mut ad) = (0.0, 0.0);
        if moving {
            let (a, period) = UNDULATION;
            let w = std::f64::consts::TAU / period;
            vd = a / w * (1.0 - (w * t).cos());
            ad = a * (w * t).sin();
        }
        let (mut r, mut rd, mut p, mut pd) = (0.0, 0.0, 0.0, 0.0);
        if self.wobble && moving {
            let (a_r, w_r) = (2f64.to_radians(), std::f64::consts::TAU / 7.0);
            let (a_p, w_p) = (1.5f64.to_radians(), std::f64::consts::TAU / 11.0);
            (r, rd) = (a_r * (w_r * t).sin(), a_r * w_r * (w_r * t).cos());
            (p, pd) = (a_p * (w_p * t).sin(), a_p * w_p * (w_p * t).cos());
        }
        nav_sim::BodyKinematics {
            vel_ned_mps: hdg * speed + Vector3::new(0.0, 0.0, vd),
            acc_ned_mps2: hdg * self.along_mps2
                + left * (speed * self.yaw_rate_radps)
                + Vector3::new(0.0, 0.0, ad),
            c_bn: Rotation3::from_euler_angles(r, p, heading_rad).into_inner(),
            omega_nb_b_radps: euler_body_rate(r, p, rd, pd, self.yaw_rate_radps),
            heading_rate_radps: self.yaw_rate_radps,
        }
    }
}

/// The generator.
pub struct Sim {
    pub cfg: SimConfig,
    /// The draws of the initial state's errors ([`Sim::perturbed_initial`]).
    rng: ChaCha8Rng,
    integ: nav_sim::Integrator<DriveMotion>,
    truth: NavState,
    k: u64,
    t0_s: f64,
    dt_s: f64,
    /// `nav_sim`'s IMU errors of [`error_model`], sample by sample.
    imu_errors: ImuErrors,
    /// `nav_sim`'s GNSS errors, fix by fix.
    gnss_noise: GnssNoise,
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
    /// A generator with the given settings and seed (the truth integrated with 4 RK4
    /// sub-steps per IMU interval).
    pub fn new(cfg: SimConfig, seed: u64) -> Self {
        Self::with_substeps(cfg, seed, 4)
    }

    /// A generator whose truth is integrated with `n_sub` RK4 sub-steps per IMU interval.
    pub fn with_substeps(cfg: SimConfig, seed: u64, n_sub: u32) -> Self {
        let rng = ChaCha8Rng::seed_from_u64(seed);
        let speed = if cfg.motion == Motion::Static {
            0.0
        } else {
            cfg.speed0_mps
        };
        let init = initial_truth(speed);
        let drive = DriveMotion {
            motion: cfg.motion,
            wobble: cfg.wobble,
            t_start_s: 0.0,
            speed0_mps: speed,
            along_mps2: 0.0,
            yaw_rate_radps: 0.0,
        };
        let dt_s = 1.0 / cfg.imu_hz;
        let yaw0 = 30f64.to_radians();
        let model = error_model(&cfg);
        let imu_errors = ImuErrors::new(&model, seed, dt_s, 0);
        let gnss_noise = GnssNoise::new(&model.gnss, seed);
        Self {
            cfg,
            rng,
            integ: nav_sim::Integrator::new(drive, init.pos, yaw0, init.t_s, dt_s, n_sub),
            truth: init,
            k: 0,
            t0_s: init.t_s,
            dt_s,
            imu_errors,
            gnss_noise,
            last_w_ib: Vector3::zeros(),
        }
    }

    /// The true state now.
    pub fn truth(&self) -> &NavState {
        &self.truth
    }

    /// Generates the next IMU epoch.
    pub fn step(&mut self) -> Epoch {
        let dt = self.dt_s;
        let clean = self.integ.step();
        self.last_w_ib = Vector3::from(clean.dtheta_rad) / dt;
        self.k += 1;
        let kin = self.integ.kinematics();
        self.truth = NavState {
            t_s: clean.t_s,
            pos: self.integ.pos(),
            vel_ned_mps: kin.vel_ned_mps,
            q_nb: UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(kin.c_bn)),
        };

        // the sample through nav_sim's error model (sample k = 0 is the first)
        let e = &mut self.imu_errors;
        let imu = e.apply(self.k as usize - 1, &clean);
        let (accel_sf, gyro_sf) = e.scale_gm_now();
        let (ab, gb) = (e.accel_bias_now(), e.gyro_bias_now());
        let truth = self.truth;
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
            accel_sf,
            gyro_sf,
        }
    }

    fn fix(&mut self, truth: &NavState) -> GnssFix {
        let c = truth.q_nb.to_rotation_matrix().into_inner();
        let l = Vector3::from(self.cfg.lever_arm_body_m);
        // nav_sim's GNSS white-noise streams (position, velocity), one draw per fix
        // nav_sim's GNSS noise of this fix (position, velocity; NED)
        let (n, vel_noise) = self.gnss_noise.next_epoch();
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
                vel[i] = v[i] + vel_noise[i];
            }
        }
        GnssFix {
            t_s: truth.t_s - self.cfg.effects.gnss_time_offset_s,
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
        let mut s = self.truth;
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

/// A filter of any dimension, for running several layouts on the same data.
pub trait AnyFilter {
    /// Integrates one IMU sample.
    fn propagate_imu(&mut self, imu: &ImuSample);
    /// Uses one GNSS fix (returns whether it was accepted).
    fn use_fix(&mut self, fix: &GnssFix) -> bool;
    /// The nominal state.
    fn nav(&self) -> NavState;
}

impl<T: Scalar, const N: usize> AnyFilter for Filter<T, N> {
    fn propagate_imu(&mut self, imu: &ImuSample) {
        self.propagate(imu).expect("propagate");
    }
    fn use_fix(&mut self, fix: &GnssFix) -> bool {
        self.update_gnss(fix).map(|o| o.accepted).unwrap_or(false)
    }
    fn nav(&self) -> NavState {
        *self.nav_state()
    }
}

/// NBK-18 with every effect block of the vocabulary (`nav_core::model::EFFECT_BLOCKS`), each
/// kind once: `imu_clock_drift` (offset and rate) is the same kind as `time_offset`, which is
/// kept, so it is left out (52 states). [`nbk_with_all_effects_clock_drift`] has it instead.
pub const fn nbk_with_all_effects() -> nav_core::model::Layout {
    all_effects_of(false, true)
}

/// [`nbk_with_all_effects`] with `imu_clock_drift` in place of `time_offset` (53 states).
pub const fn nbk_with_all_effects_clock_drift() -> nav_core::model::Layout {
    all_effects_of(true, true)
}

/// [`nbk_with_all_effects`] without the GNSS-side `gnss_position_gm` block (49 states): the
/// IMU effects, the lever arm and the time offset.
pub const fn nbk_with_all_imu_side_effects() -> nav_core::model::Layout {
    all_effects_of(false, false)
}

/// NBK-18 with every effect block, the time offset as `imu_clock_drift` (`drift`) or as
/// `time_offset`.
/// With `gnss_gm` the GNSS position Gauss-Markov block too.
const fn all_effects_of(drift: bool, gnss_gm: bool) -> nav_core::model::Layout {
    use nav_core::model::Block;
    let mut l = nav_core::model::LAYOUT_NBK;
    let mut i = 0;
    while i < nav_core::model::EFFECT_BLOCKS.len() {
        let b = nav_core::model::EFFECT_BLOCKS[i];
        let skip = if drift {
            matches!(b, Block::TimeOffset)
        } else {
            matches!(b, Block::ImuClockDrift)
        } || (!gnss_gm && matches!(b, Block::GnssPositionGm));
        if !skip {
            l = l.with(b);
        }
        i += 1;
    }
    l
}

/// GNSS outages `[start, end)` in seconds from the run start: `count` outages of `len_s`
/// starting at `first_s`, every `every_s`.
pub fn outage_plan(first_s: f64, every_s: f64, len_s: f64, count: usize) -> Vec<(f64, f64)> {
    (0..count)
        .map(|k| {
            let a = first_s + k as f64 * every_s;
            (a, a + len_s)
        })
        .collect()
}

/// What one filter did during a run: the largest horizontal position error (IMU point vs
/// truth, m) inside each outage, and the GNSS fixes it accepted / was offered.
#[derive(Debug, Clone, Default)]
pub struct RunStats {
    /// Largest horizontal error during each outage, m.
    pub outage_max_horiz_m: Vec<f64>,
    /// Horizontal error at the last epoch before each outage started, m.
    pub outage_start_horiz_m: Vec<f64>,
    /// Fixes accepted.
    pub accepted: usize,
    /// Fixes offered.
    pub offered: usize,
}

impl RunStats {
    /// Mean over the outages of the largest horizontal error, m.
    pub fn mean_outage_max_m(&self) -> f64 {
        self.outage_max_horiz_m.iter().sum::<f64>() / self.outage_max_horiz_m.len().max(1) as f64
    }
}

/// Runs every filter on `duration_s` seconds of the simulator's data with the GNSS fixes
/// withheld inside `outages` (seconds from the start). Each fix is used at the IMU epoch
/// nearest its time tag (as a real-time or file-based run would: with a GNSS time offset the
/// fix's position belongs to a later epoch than its tag). `on_epoch` sees each epoch after
/// the filters used it.
pub fn run_filters(
    sim: &mut Sim,
    filters: &mut [&mut dyn AnyFilter],
    duration_s: f64,
    outages: &[(f64, f64)],
    mut on_epoch: impl FnMut(&Epoch),
) -> Vec<RunStats> {
    let t0 = sim.truth().t_s;
    let dt = 1.0 / sim.cfg.imu_hz;
    let n_ep = (duration_s * sim.cfg.imu_hz).round() as usize;
    let epochs: Vec<Epoch> = (0..n_ep).map(|_| sim.step()).collect();
    // fix -> index of the epoch nearest its tag
    let mut due: Vec<Vec<GnssFix>> = vec![Vec::new(); n_ep];
    for e in &epochs {
        if let Some(fix) = e.gnss {
            let k = ((fix.t_s - t0) / dt).round() as i64 - 1;
            if k >= 0 && (k as usize) < n_ep {
                due[k as usize].push(fix);
            }
        }
    }
    let mut stats = vec![RunStats::default(); filters.len()];
    for st in stats.iter_mut() {
        st.outage_max_horiz_m = vec![0.0; outages.len()];
        st.outage_start_horiz_m = vec![f64::NAN; outages.len()];
    }
    for (e, fixes) in epochs.iter().zip(&due) {
        let tau = e.truth.t_s - t0;
        let in_outage = outages.iter().position(|(a, b)| tau >= *a && tau < *b);
        for (f, st) in filters.iter_mut().zip(stats.iter_mut()) {
            f.propagate_imu(&e.imu);
            if in_outage.is_none() {
                for fix in fixes {
                    st.offered += 1;
                    if f.use_fix(fix) {
                        st.accepted += 1;
                    }
                }
            }
            let (_, _, dr) = nav_errors(&f.nav(), &e.truth);
            let h = (dr[0] * dr[0] + dr[1] * dr[1]).sqrt();
            if let Some(k) = in_outage {
                if st.outage_start_horiz_m[k].is_nan() {
                    st.outage_start_horiz_m[k] = h;
                }
                st.outage_max_horiz_m[k] = st.outage_max_horiz_m[k].max(h);
            }
        }
        on_epoch(e);
    }
    stats
}

/// The result of running a base filter and the same filter with effect blocks on one drive.
pub struct EffectRun<const NB: usize> {
    /// The filter with the effect blocks, at the end of the run.
    pub with: Filter<f64, NB>,
    /// Its outage statistics.
    pub with_stats: RunStats,
    /// Outage statistics of the base filter (NBK-18 without the blocks).
    pub without_stats: RunStats,
}

/// Runs the NBK-18 base filter and `layout` (NBK-18 + effect blocks, dimension NB) with the
/// same configuration `cfg` from the same perturbed initial state on `duration_s` seconds of
/// `sc`'s drive (seed `seed`) with the GNSS fixes withheld inside `outages`.
pub fn effect_run<const NB: usize>(
    sc: SimConfig,
    seed: u64,
    cfg: &FilterConfig,
    layout: nav_core::model::Layout,
    duration_s: f64,
    outages: &[(f64, f64)],
) -> EffectRun<NB> {
    const N18: usize = nav_core::model::LAYOUT_NBK.dim();
    let mut sim = Sim::new(sc, seed);
    let unc = test_uncertainty();
    let init = sim.perturbed_initial(&unc);
    let mut with: Filter<f64, NB> = Filter::new(layout, cfg, init, &unc).expect("with blocks");
    let mut without: Filter<f64, N18> =
        Filter::new(nav_core::model::LAYOUT_NBK, cfg, init, &unc).expect("base");
    let stats = run_filters(
        &mut sim,
        &mut [&mut with, &mut without],
        duration_s,
        outages,
        |_| {},
    );
    let mut it = stats.into_iter();
    let with_stats = it.next().unwrap_or_default();
    let without_stats = it.next().unwrap_or_default();
    EffectRun {
        with,
        with_stats,
        without_stats,
    }
}

/// Checks a block's estimate against the truth and prints the comparison: every component
/// within 3 sigma (the sigma is honest); the components in `accurate` within 20 % of the
/// truth with a sigma below 20 % of it; the components in `detected` with a sigma below half
/// the truth (the effect is seen at 2 sigma or more, not just left at its prior).
pub fn check_block_estimate<const N: usize>(
    f: &Filter<f64, N>,
    kind: nav_core::model::BlockKind,
    truth: &[f64],
    scale: f64,
    unit: &str,
    accurate: &[usize],
    detected: &[usize],
) {
    let v = f.block_value(kind).expect("block in layout");
    let name = v.block.name();
    for i in 0..v.dim {
        let (e, s, t) = (v.estimate[i], v.sigma[i], truth[i]);
        println!(
            "{name}[{i}]: estimate {:10.4} truth {:10.4} sigma {:8.4} {unit}  (error {:6.2} sigma, {:6.1} % of truth){}",
            e / scale,
            t / scale,
            s / scale,
            (e - t) / s,
            100.0 * (e - t) / t,
            if accurate.contains(&i) {
                " [accurate]"
            } else if detected.contains(&i) {
                " [detected]"
            } else {
                ""
            }
        );
    }
    for i in 0..v.dim {
        let (e, s, t) = (v.estimate[i], v.sigma[i], truth[i]);
        assert!(
            (e - t).abs() < 3.0 * s,
            "{name}[{i}]: estimate {e:e} truth {t:e} is {:.1} sigma off (sigma {s:e})",
            (e - t).abs() / s
        );
        if accurate.contains(&i) {
            assert!(
                (e - t).abs() < 0.2 * t.abs(),
                "{name}[{i}]: estimate {e:e} not within 20 % of the truth {t:e}"
            );
            assert!(
                s < 0.2 * t.abs(),
                "{name}[{i}]: sigma {s:e} not below 20 % of the truth {t:e}"
            );
        }
        if detected.contains(&i) {
            assert!(
                s < 0.5 * t.abs(),
                "{name}[{i}]: sigma {s:e} not below half the truth {t:e}"
            );
        }
    }
}

/// Estimate and 1-sigma of the linear combination `coeffs . x` of a block's states (from the
/// filter's covariance).
pub fn block_combination<const N: usize>(
    f: &Filter<f64, N>,
    kind: nav_core::model::BlockKind,
    coeffs: &[f64],
) -> (f64, f64) {
    let (off, _) = f.layout().find(kind).expect("block in layout");
    let est = f.block_estimate(kind).expect("block in layout");
    let p = f.covariance();
    let mut e = 0.0;
    let mut var = 0.0;
    for (i, ci) in coeffs.iter().enumerate() {
        e += ci * est[i];
        for (j, cj) in coeffs.iter().enumerate() {
            var += ci * cj * p[off + i][off + j];
        }
    }
    (e, var.sqrt())
}

/// Estimate and 1-sigma of a linear combination of states of several blocks:
/// `sum coeff * x[block][index]`.
pub fn state_combination<const N: usize>(
    f: &Filter<f64, N>,
    terms: &[(nav_core::model::BlockKind, usize, f64)],
) -> (f64, f64) {
    let p = f.covariance();
    let idx: Vec<(usize, f64, f64)> = terms
        .iter()
        .map(|(k, i, c)| {
            let (off, _) = f.layout().find(*k).expect("block in layout");
            (off + i, *c, f.block_estimate(*k).expect("block")[*i])
        })
        .collect();
    let e: f64 = idx.iter().map(|(_, c, x)| c * x).sum();
    let mut var = 0.0;
    for (i, ci, _) in &idx {
        for (j, cj, _) in &idx {
            var += ci * cj * p[*i][*j];
        }
    }
    (e, var.sqrt())
}

/// Checks a linear combination of a block's states like an `accurate` component of
/// [`check_block_estimate`]: within 3 sigma and 20 % of the truth, sigma below 20 %.
pub fn check_combination<const N: usize>(
    f: &Filter<f64, N>,
    kind: nav_core::model::BlockKind,
    label: &str,
    coeffs: &[f64],
    truth: f64,
    scale: f64,
    unit: &str,
) {
    let terms: Vec<_> = coeffs
        .iter()
        .enumerate()
        .map(|(i, c)| (kind, i, *c))
        .collect();
    check_terms(f, &terms, label, truth, scale, unit);
}

/// Checks a linear combination of states of several blocks ([`state_combination`]) like an
/// `accurate` component of [`check_block_estimate`].
pub fn check_terms<const N: usize>(
    f: &Filter<f64, N>,
    terms: &[(nav_core::model::BlockKind, usize, f64)],
    label: &str,
    truth: f64,
    scale: f64,
    unit: &str,
) {
    let (e, s) = state_combination(f, terms);
    println!(
        "{label}: estimate {:10.4} truth {:10.4} sigma {:8.4} {unit}  (error {:6.2} sigma, {:6.1} % of truth) [accurate]",
        e / scale,
        truth / scale,
        s / scale,
        (e - truth) / s,
        100.0 * (e - truth) / truth
    );
    assert!(
        (e - truth).abs() < 3.0 * s,
        "{label}: {e:e} vs {truth:e}, sigma {s:e}"
    );
    assert!(
        (e - truth).abs() < 0.2 * truth.abs(),
        "{label}: {e:e} vs {truth:e}"
    );
    assert!(s < 0.2 * truth.abs(), "{label}: sigma {s:e} vs {truth:e}");
}

/// Prints and checks that the block lowers the mean (over the outages) of the largest
/// horizontal position error during an outage; returns (with, without) in m.
pub fn check_outage_improvement(name: &str, with: &RunStats, without: &RunStats) -> (f64, f64) {
    let (a, b) = (with.mean_outage_max_m(), without.mean_outage_max_m());
    println!(
        "{name}: mean max horizontal error in {} outages: with the block {a:.3} m, without {b:.3} m ({:.0} % lower); per outage with {:?} without {:?}; fixes accepted {}/{} vs {}/{}",
        with.outage_max_horiz_m.len(),
        100.0 * (1.0 - a / b),
        with.outage_max_horiz_m.iter().map(|v| format!("{v:.2}")).collect::<Vec<_>>(),
        without.outage_max_horiz_m.iter().map(|v| format!("{v:.2}")).collect::<Vec<_>>(),
        with.accepted,
        with.offered,
        without.accepted,
        without.offered,
    );
    (a, b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nav_sim::errors::{AxisErrors, Sensor};
    use nav_sim::{Scenario, Trajectory};

    /// A generator of the NBK drive (with wobble: every gyro and accelerometer axis sees
    /// motion) whose truth has no sensor noise, with `effects`.
    fn noise_free(effects: TruthEffects) -> Sim {
        use nav_core::config::SensorNoise;
        let quiet = SensorNoise::isotropic(0.0, 0.0, 45.0, 0.0, 0.0);
        let mut sc = SimConfig::nbk(100.0);
        sc.truth = FilterConfig::with_noise(quiet, quiet);
        sc.wobble = true;
        sc.effects = effects;
        Sim::new(sc, 5)
    }

    /// The effects enter as the filter's sensor model says (`docs/derivations/error_state.md`
    /// 5.1): `dtheta_meas = (I + diag(s_g) + M_g) dtheta + diag(g_s) dv`,
    /// `dv_meas = (I + diag(s_a) + M_a) dv`, `M` with `m_ij` the fraction of body axis j that
    /// sensor i sees, `[m_xy, m_xz, m_yx, m_yz, m_zx, m_zy]`, on the ideal increments. Pins the
    /// convention of the generator's translation into `nav_sim`'s error model.
    #[test]
    fn effects_follow_the_filters_sensor_model() {
        let fx = TruthEffects {
            accel_sf: [1500e-6, -800e-6, 1200e-6],
            gyro_sf: [700e-6, -1200e-6, 1500e-6],
            accel_mis_rad: [0.45e-3, -0.2e-3, 0.35e-3, 0.25e-3, -0.35e-3, 0.3e-3],
            gyro_mis_rad: [0.25e-3, 0.4e-3, -0.3e-3, -0.35e-3, 0.2e-3, 0.45e-3],
            gyro_g_sens: [2e-5, -3e-5, 4e-6],
            ..TruthEffects::default()
        };
        let (mut plain, mut with) = (noise_free(TruthEffects::default()), noise_free(fx));
        let mut worst = 0.0f64;
        for _ in 0..2000 {
            let (a, b) = (plain.step().imu, with.step().imu);
            let (th, dv) = (Vector3::from(a.dtheta_rad), Vector3::from(a.dv_mps));
            let mg = mis_times(&fx.gyro_mis_rad, &th);
            let ma = mis_times(&fx.accel_mis_rad, &dv);
            for i in 0..3 {
                let want_th = th[i] + fx.gyro_sf[i] * th[i] + mg[i] + fx.gyro_g_sens[i] * dv[i];
                let want_dv = dv[i] + fx.accel_sf[i] * dv[i] + ma[i];
                worst = worst
                    .max((b.dtheta_rad[i] - want_th).abs() / th.norm().max(1e-6))
                    .max((b.dv_mps[i] - want_dv).abs() / dv.norm());
            }
        }
        assert!(worst < 1e-12, "largest relative difference {worst:e}");
    }

    /// Sample variance of `x` about zero over its mean square expectation `var`.
    fn var_ratio(x: &[f64], var: f64) -> f64 {
        x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64 / var
    }

    /// The drawn errors have the statistics of the filter's model of them: over 400 seeds
    /// the accelerometer bias at the first sample has the variance `S_B T_B / 2 +
    /// bias_init_sigma^2` (stationary Gauss-Markov plus the random walk's start), the gyro
    /// bias `bias_init_sigma^2`, the Gauss-Markov scale factors `sigma^2`; the GNSS position
    /// noise of 900 fixes has the stated sigma. Each ratio within 0.75..1.25 (the standard
    /// deviation of a ratio of 1,200 squares is 0.04, of 900 squares 0.05).
    #[test]
    fn drawn_errors_have_the_filters_statistics() {
        let mut sc = SimConfig::nbk(100.0);
        sc.motion = Motion::Static;
        sc.scale_factors = true;
        sc.truth.accel_scale = nav_core::config::ScaleFactorNoise::from_ppm(300.0, 3600.0);
        sc.truth.gyro_scale = nav_core::config::ScaleFactorNoise::from_ppm(200.0, 3600.0);
        let (a, g) = (sc.truth.accel, sc.truth.gyro);
        let (mut ab, mut gb, mut asf, mut gsf) = (vec![], vec![], vec![], vec![]);
        for seed in 0..400 {
            let e = Sim::new(sc, seed).step();
            ab.extend(e.accel_bias_mps2);
            gb.extend(e.gyro_bias_radps);
            asf.extend(e.accel_sf);
            gsf.extend(e.gyro_sf);
        }
        let ratios = [
            (
                "accel bias",
                var_ratio(&ab, 0.5 * a.s_b[0] * a.t_b_s + a.bias_init_sigma[0].powi(2)),
            ),
            ("gyro bias", var_ratio(&gb, g.bias_init_sigma[0].powi(2))),
            ("accel scale factor", var_ratio(&asf, 300e-6f64.powi(2))),
            ("gyro scale factor", var_ratio(&gsf, 200e-6f64.powi(2))),
        ];
        let mut sim = Sim::new(sc, 1);
        let (mut n, mut d) = (vec![], vec![]);
        while n.len() < 900 {
            let e = sim.step();
            let Some(fix) = e.gnss else { continue };
            let c = e.truth.q_nb.to_rotation_matrix().into_inner();
            let ant = earth::displace(&e.truth.pos, &(c * Vector3::from(sc.lever_arm_body_m)));
            let p = Llh {
                lat_rad: fix.lat_rad,
                lon_rad: fix.lon_rad,
                h_m: fix.h_m,
            };
            let r = earth::ned_offset_m(&ant, &p);
            n.push(r[0] / sc.gnss_pos_sigma_m[0]);
            d.push(r[2] / sc.gnss_pos_sigma_m[2]);
        }
        for (name, r) in ratios.into_iter().chain([
            ("gnss north", var_ratio(&n, 1.0)),
            ("gnss down", var_ratio(&d, 1.0)),
        ]) {
            println!("{name}: variance / model {r:.3}");
            assert!((0.75..1.25).contains(&r), "{name}: {r}");
        }
    }

    /// The generator's way of drawing the sensor errors (sample by sample, one
    /// `AxisErrors` per axis) gives the simulator's measurements bit for bit: the same
    /// model and seed through `ErrorModel::apply_imu` over a 20 s drive, with every stochastic
    /// source on (turn-on bias, bias step, white, Gauss-Markov, random walk, flicker,
    /// quantization).
    #[test]
    fn sample_by_sample_errors_are_the_simulators() {
        let text = r#"
[start]
lat_deg = 47.1
lon_deg = 15.4
h_m = 350.0
heading_deg = 30.0
gps_week = 2300
sow_s = 1000.0

[imu]
rate_hz = 100.0

[[segment]]
kind = "accelerate"
to_speed_mps = 8.0
duration_s = 10.0

[[segment]]
kind = "turn"
angle_deg = 90.0
rate_deg_s = 10.0
"#;
        let traj = Trajectory::generate(&Scenario::from_toml_str(text, "<test>").unwrap()).unwrap();
        let mut m = ErrorModel::preset("consumer-mems").unwrap();
        for e in [&mut m.accel, &mut m.gyro] {
            e.gm_psd = Axes3::splat(1e-10);
            e.gm_tau_s = Axes3::splat(30.0);
            e.rw_psd = Axes3::splat(1e-12);
            e.bias_step = Axes3([1e-4, 0.0, -2e-4]);
            e.bias_step_at_s = 7.0;
        }
        let seed = 17;
        let (batch, realized) = m.apply_imu(&traj, seed);
        let n = traj.imu.len();
        assert!(n > 1000);
        let mut axes: Vec<AxisErrors> = (0..6)
            .map(|k| {
                let (e, sensor) = if k < 3 {
                    (&m.accel, Sensor::Accel)
                } else {
                    (&m.gyro, Sensor::Gyro)
                };
                AxisErrors::for_sensor(e, sensor, k % 3, seed, traj.dt_s, n)
            })
            .collect();
        for (k, (clean, meas)) in traj.imu.iter().zip(&batch).enumerate() {
            for i in 0..3 {
                let dv = axes[i].apply(k, clean.dv_mps[i]);
                let dth = axes[3 + i].apply(k, clean.dtheta_rad[i]);
                assert_eq!(
                    dv.to_bits(),
                    meas.dv_mps[i].to_bits(),
                    "dv sample {k} axis {i}"
                );
                assert_eq!(
                    dth.to_bits(),
                    meas.dtheta_rad[i].to_bits(),
                    "dtheta {k} {i}"
                );
            }
        }
        for i in 0..3 {
            assert_eq!(axes[i].constant_bias(), realized.accel_bias_mps2[i]);
            assert_eq!(axes[3 + i].constant_bias(), realized.gyro_bias_radps[i]);
            assert!(realized.accel_bias_mps2[i] != 0.0);
        }
    }
}
