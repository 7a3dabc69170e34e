//! A simulated case for the bridge's end-to-end tests, written from the workspace's truth
//! generator (`nav_sim::Trajectory`) with the project's writers (`nav_io`): the files
//! `host-sim simulate --kf-gins` writes and a run reads (`imu.txt`, `gnss.txt`, `truth.nav`,
//! the index of `case.toml` the run engine reads, `kf-gins.yaml`).
//!
//! The tests that use it check the link, the capture and the replay (frames sent equal frames
//! decoded, a replay's solution equal to the engine's on the files), not a sensor model, so
//! the errors are the simplest that make a realistic filter run: white noise at the
//! `tactical` preset's densities (accelerometer 50 ug/sqrt(Hz), gyro 0.1 deg/sqrt(h)), a
//! constant bias per axis drawn at the preset's turn-on sigmas (200 ug, 1 deg/h), and GNSS
//! positions of the antenna (lever arm below) with white noise 8/8/15 mm. The full error
//! model (Gauss-Markov, random walk, flicker, quantization, temperature, ...) is host-sim's
//! simulator; cross-crate tests that need it are in the `tests` crate.
use nalgebra::Vector3;
use nav_core::earth;
use nav_core::types::{FixQuality, GnssFix, ImuSample};
use nav_io::kfgins::{KfGinsConfig, KfGinsImuNoiseYaml};
use nav_sim::{Scenario, Trajectory};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::path::{Path, PathBuf};

/// Accelerometer white noise, m/s/sqrt(s) (50 ug/sqrt(Hz)).
const ACCEL_WHITE: f64 = 50e-6 * 9.80665;
/// Gyro white noise, rad/sqrt(s) (0.1 deg/sqrt(h)).
const GYRO_WHITE: f64 = 0.1 * std::f64::consts::PI / 180.0 / 60.0;
/// Accelerometer constant bias sigma, m/s^2 (200 ug).
const ACCEL_BIAS: f64 = 200e-6 * 9.80665;
/// Gyro constant bias sigma, rad/s (1 deg/h).
const GYRO_BIAS: f64 = std::f64::consts::PI / 180.0 / 3600.0;
/// GNSS white noise north, east, down, m.
const GNSS_WHITE: [f64; 3] = [0.008, 0.008, 0.015];
/// GNSS standard deviations the fixes report, m.
const GNSS_STD: [f64; 3] = [0.01, 0.01, 0.02];
/// Antenna lever arm, body FRD, m.
const LEVER: [f64; 3] = [0.3, -0.2, -0.8];

/// Simulates `scenario` with `seed` into `dir` (created); 1 Hz GNSS fixes, none whose time
/// after the first IMU epoch falls in an `outages` span `(start_s, duration_s)`. Returns the
/// case directory's `kf-gins.yaml`.
pub fn write_case(dir: &Path, scenario: &Scenario, seed: u64, outages: &[(f64, f64)]) -> PathBuf {
    let traj = Trajectory::generate(scenario).expect("the scenario integrates");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut randn = move || -> f64 { rng.sample(StandardNormal) };
    let dt = traj.dt_s;
    let ba: [f64; 3] = std::array::from_fn(|_| ACCEL_BIAS * randn());
    let bg: [f64; 3] = std::array::from_fn(|_| GYRO_BIAS * randn());
    let imu: Vec<ImuSample> = traj
        .imu
        .iter()
        .map(|s| ImuSample {
            t_s: s.t_s,
            dtheta_rad: std::array::from_fn(|i| {
                s.dtheta_rad[i] + bg[i] * dt + GYRO_WHITE * dt.sqrt() * randn()
            }),
            dv_mps: std::array::from_fn(|i| {
                s.dv_mps[i] + ba[i] * dt + ACCEL_WHITE * dt.sqrt() * randn()
            }),
            temperature_c: f64::NAN,
        })
        .collect();
    let n_fix = traj.duration_s().floor() as usize + 1;
    let gnss: Vec<GnssFix> = (0..n_fix)
        .filter_map(|k| {
            let t_rel = k as f64;
            // every epoch's noise is drawn, also in outages, as the simulator does
            let err = Vector3::from(std::array::from_fn(|i| GNSS_WHITE[i] * randn()));
            if outages.iter().any(|&(s, d)| t_rel >= s && t_rel < s + d) {
                return None;
            }
            let st = traj.truth_at(traj.t0_s + t_rel)?;
            let ant = earth::displace(&st.pos, &(st.q_nb * Vector3::from(LEVER)));
            let meas = earth::displace(&ant, &err);
            Some(GnssFix {
                t_s: traj.t0_s + t_rel,
                lat_rad: meas.lat_rad,
                lon_rad: meas.lon_rad,
                h_m: meas.h_m,
                pos_std_ned_m: GNSS_STD,
                quality: FixQuality::RtkFixed,
                num_sats: 12,
                ..GnssFix::default()
            })
        })
        .collect();
    std::fs::create_dir_all(dir).unwrap();
    let dir = std::path::absolute(dir).unwrap();
    nav_io::write_imu_text(dir.join("imu.txt"), &imu).unwrap();
    nav_io::write_gnss_text(dir.join("gnss.txt"), &gnss).unwrap();
    nav_io::write_nav_text(dir.join("truth.nav"), &traj.truth).unwrap();
    // the part of case.toml the run engine reads (nav_engine::run::prepare::CaseIndex)
    let mut index = format!(
        "[files]\nimu = \"imu.txt\"\ngnss = \"gnss.txt\"\ntruth = \"truth.nav\"\n\n\
         [summary]\ngps_week = {}\n",
        traj.week
    );
    for &(s, d) in outages {
        index.push_str(&format!(
            "\n[[outages]]\nstart_sow = {}\nduration_s = {d}\n",
            traj.t0_s + s
        ));
    }
    std::fs::write(dir.join("case.toml"), index).unwrap();
    let s0 = traj.truth[0];
    let config = KfGinsConfig {
        imupath: dir.join("imu.txt").display().to_string(),
        gnsspath: dir.join("gnss.txt").display().to_string(),
        outputpath: dir.display().to_string(),
        imudatalen: 7,
        imudatarate: scenario.imu.rate_hz.round() as u32,
        starttime: traj.t0_s,
        endtime: -1.0,
        initpos: [s0.lat_rad.to_degrees(), s0.lon_rad.to_degrees(), s0.h_m],
        initvel: s0.vel_ned_mps,
        initatt: [
            s0.rpy_rad[0].to_degrees(),
            s0.rpy_rad[1].to_degrees(),
            s0.rpy_rad[2].to_degrees().rem_euclid(360.0),
        ],
        initgyrbias: [0.0; 3],
        initaccbias: [0.0; 3],
        initgyrscale: [0.0; 3],
        initaccscale: [0.0; 3],
        initposstd: [0.01, 0.01, 0.02],
        initvelstd: [0.01, 0.01, 0.01],
        initattstd: [0.01, 0.01, 0.05],
        initbgstd: None,
        initbastd: None,
        initsgstd: None,
        initsastd: None,
        imunoise: KfGinsImuNoiseYaml {
            arw: [0.1; 3],
            vrw: [ACCEL_WHITE * 60.0; 3],
            gbstd: [1.0; 3],
            abstd: [ACCEL_BIAS / 1e-5; 3],
            gsstd: [1.0; 3],
            asstd: [1.0; 3],
            corrtime: 1.0,
        },
        antlever: LEVER,
        unknown_keys: Default::default(),
    };
    let path = dir.join("kf-gins.yaml");
    nav_io::write_kf_gins_yaml(&path, &config).unwrap();
    path
}
