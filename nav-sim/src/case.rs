//! A simulated case: trajectory + seeded measurements, in memory ([`simulate`]) and on disk
//! ([`Case::write`]: `imu.txt`, `gnss.txt`, `truth.nav`, `case.toml`, optionally
//! `kf-gins.yaml`).

use crate::errors::{ErrorModel, ErrorModelError, Measurements, Outage, Realized};
use crate::scenario::{Scenario, ScenarioError};
use crate::trajectory::Trajectory;
use nav_io::{write_gnss_text, write_imu_text, write_nav_text, IoError};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Errors of the simulation and of writing a case.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// Scenario problem.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// Error-model problem.
    #[error(transparent)]
    ErrorModel(#[from] ErrorModelError),
    /// Writing a data file failed.
    #[error(transparent)]
    Io(#[from] IoError),
    /// Writing another file failed.
    #[error("{path}: {source}")]
    File {
        /// File path.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
}

/// A simulated case in memory.
#[derive(Debug, Clone)]
pub struct Case {
    /// Seed of the error realisation.
    pub seed: u64,
    /// Error model applied.
    pub errors: ErrorModel,
    /// Error-free truth and ideal increments (holds the scenario).
    pub trajectory: Trajectory,
    /// Measured IMU and GNSS, and the realised random constants.
    pub meas: Measurements,
}

/// Simulates a scenario with an error model and a seed (trajectory + errors).
pub fn simulate(scenario: &Scenario, errors: &ErrorModel, seed: u64) -> Result<Case, SimError> {
    errors.validate()?;
    let trajectory = Trajectory::generate(scenario)?;
    let meas = errors.apply(&trajectory, seed);
    Ok(Case {
        seed,
        errors: errors.clone(),
        trajectory,
        meas,
    })
}

/// One outage in absolute and relative time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OutageRecord {
    /// Start, s after the first IMU epoch.
    pub start_s: f64,
    /// Duration, s.
    pub duration_s: f64,
    /// Start, GPS seconds of week.
    pub start_sow: f64,
    /// End (exclusive), GPS seconds of week.
    pub end_sow: f64,
}

/// Files of a case, relative to the case directory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaseFiles {
    /// IMU text file.
    pub imu: String,
    /// GNSS text file.
    pub gnss: String,
    /// Truth in the nav format at the IMU rate.
    pub truth: String,
    /// KF-GINS configuration, when written.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kf_gins: Option<String>,
    /// Wheel speed (`nav_io::odometer` format), when the scenario's vehicle has an odometer.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub odometer: Option<String>,
    /// Dual-antenna heading (`nav_io::heading` format), when the scenario's vehicle has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heading: Option<String>,
}

/// Summary numbers of a case.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaseSummary {
    /// GPS week.
    pub gps_week: u16,
    /// First IMU epoch (truth record 0), GPS seconds of week.
    pub t0_sow: f64,
    /// Last IMU epoch, GPS seconds of week.
    pub t_end_sow: f64,
    /// Duration, s.
    pub duration_s: f64,
    /// IMU rate, Hz.
    pub imu_rate_hz: f64,
    /// IMU samples in the file.
    pub imu_samples: usize,
    /// GNSS fixes in the file.
    pub gnss_fixes: usize,
    /// Whether the IMU file has the temperature column.
    pub temperature_column: bool,
}

/// `case.toml`: what was simulated, machine-readable (the ground truth of every effect).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaseFile {
    /// Format tag.
    pub format: String,
    /// Seed of the error realisation.
    pub seed: u64,
    /// Data files.
    pub files: CaseFiles,
    /// Summary.
    pub summary: CaseSummary,
    /// Realised random constants (turn-on biases incl. fixed biases).
    pub realized: Realized,
    /// All GNSS outages (explicit and periodic).
    #[serde(default)]
    pub outages: Vec<OutageRecord>,
    /// The scenario.
    pub scenario: Scenario,
    /// The complete error model (every value explicit).
    pub errors: ErrorModel,
}

impl CaseFile {
    /// Reads a `case.toml`.
    pub fn from_file(path: &Path) -> Result<Self, SimError> {
        let text = std::fs::read_to_string(path).map_err(|source| SimError::File {
            path: path.to_path_buf(),
            source,
        })?;
        toml::from_str(&text).map_err(|e| {
            SimError::ErrorModel(ErrorModelError::Parse {
                path: path.display().to_string(),
                source: Box::new(e),
            })
        })
    }
}

const CASE_HEADER: &str = "\
# host-sim simulated case: what was simulated, with every value explicit.
# Conventions: body frame FRD (= vehicle frame), navigation frame NED, time GPS seconds of week.
# IMU file: t dtheta_xyz[rad] dv_xyz[m/s] [temperature_C], increments over (t_prev, t].
# Truth (nav format) is at the IMU reference point at every IMU epoch.
# Errors (see nav-sim/src/errors.rs): measured increment = (I + diag(scale_factor_ppm*1e-6)
#   + misalignment_rad) * ideal + g_sensitivity * dv (gyros) + bias terms * dt
#   + temp_coeff_per_c * int(T - T_ref) dt + white noise, then quantization with carry.
# PSDs are two-sided (IEEE 952): white_psd S_N, gm_psd S_B (stationary var S_B*T_B/2), rw_psd S_K.
# GNSS: a fix tagged t is the antenna (IMU + C_b^n lever_arm_b_m) position at IMU time
#   t - time_offset_s, plus white and Gauss-Markov NED errors; outages remove fixes with tag in
#   [start, start + duration).
# realized.*_bias = fixed bias + drawn turn-on bias (constant over the run).
";

impl Case {
    /// All outages of the case in absolute and relative time.
    pub fn outages(&self) -> Vec<OutageRecord> {
        let t0 = self.trajectory.t0_s;
        self.errors
            .gnss
            .all_outages(self.trajectory.duration_s())
            .iter()
            .map(|o: &Outage| OutageRecord {
                start_s: o.start_s,
                duration_s: o.duration_s,
                start_sow: t0 + o.start_s,
                end_sow: t0 + o.start_s + o.duration_s,
            })
            .collect()
    }

    /// The `case.toml` content.
    pub fn case_file(&self, kf_gins: bool) -> CaseFile {
        let tr = &self.trajectory;
        CaseFile {
            format: "host-sim case 1".into(),
            seed: self.seed,
            files: CaseFiles {
                imu: "imu.txt".into(),
                gnss: "gnss.txt".into(),
                truth: "truth.nav".into(),
                kf_gins: kf_gins.then(|| "kf-gins.yaml".into()),
                odometer: tr
                    .scenario
                    .vehicle
                    .odometer
                    .is_some()
                    .then(|| "odometer.txt".into()),
                heading: tr
                    .scenario
                    .vehicle
                    .heading
                    .is_some()
                    .then(|| "heading.txt".into()),
            },
            summary: CaseSummary {
                gps_week: tr.week,
                t0_sow: tr.t0_s,
                t_end_sow: tr.truth.last().map_or(tr.t0_s, |s| s.t_s),
                duration_s: tr.duration_s(),
                imu_rate_hz: tr.scenario.imu.rate_hz,
                imu_samples: self.meas.imu.len(),
                gnss_fixes: self.meas.gnss.len(),
                temperature_column: self.errors.temperature.is_some(),
            },
            realized: self.meas.realized.clone(),
            outages: self.outages(),
            scenario: tr.scenario.clone(),
            errors: self.errors.clone(),
        }
    }

    /// Writes the case into `dir` (created if needed): `imu.txt`, `gnss.txt`, `truth.nav`,
    /// `case.toml`, and with `kf_gins` also `kf-gins.yaml`.
    pub fn write(&self, dir: &Path, kf_gins: bool) -> Result<(), SimError> {
        let ferr = |path: &Path| {
            let path = path.to_path_buf();
            move |source| SimError::File { path, source }
        };
        std::fs::create_dir_all(dir).map_err(ferr(dir))?;
        write_imu_text(dir.join("imu.txt"), &self.meas.imu)?;
        write_gnss_text(dir.join("gnss.txt"), &self.meas.gnss)?;
        write_nav_text(dir.join("truth.nav"), &self.trajectory.truth)?;
        let cf = self.case_file(kf_gins);
        let body = toml::to_string(&cf).map_err(|e| {
            SimError::ErrorModel(ErrorModelError::Invalid(format!("case.toml: {e}")))
        })?;
        let p = dir.join("case.toml");
        std::fs::write(&p, format!("{CASE_HEADER}{body}")).map_err(ferr(&p))?;
        if let Some(spec) = &self.trajectory.scenario.vehicle.odometer {
            let odo = crate::odometer::wheel_speed(&self.trajectory, spec, self.seed);
            nav_io::write_odometer(dir.join("odometer.txt"), &odo)?;
        }
        if let Some(spec) = &self.trajectory.scenario.vehicle.heading {
            let h = crate::heading::dual_antenna_heading(&self.trajectory, spec, self.seed);
            nav_io::write_heading(dir.join("heading.txt"), &h)?;
        }
        if kf_gins {
            let p = dir.join("kf-gins.yaml");
            let abs = std::path::absolute(dir).map_err(ferr(dir))?;
            std::fs::write(&p, self.kf_gins_yaml(&abs)).map_err(ferr(&p))?;
        }
        Ok(())
    }

    /// A KF-GINS configuration (its own keys and units) for this case, paths under `dir`.
    ///
    /// Mapping: `arw = sqrt(S_N,g)` in deg/sqrt(h), `vrw = sqrt(S_N,a)` in m/s/sqrt(h);
    /// KF-GINS has one first-order Gauss-Markov bias per axis, so `gbstd`/`abstd` are the
    /// root-sum-square of the turn-on sigma, the fixed bias, the Gauss-Markov stationary std
    /// and the flicker coefficient (largest axis), and `corrtime` is the Gauss-Markov T_B when
    /// that process dominates a sensor's bias variance, else 1 h (random constants dominate).
    /// The random walk is not representable and is left out. Scale-factor stds are the true
    /// scale factors (at least 1 ppm, KF-GINS always carries the states). The initial state is
    /// the truth at the first epoch.
    pub fn kf_gins_yaml(&self, dir: &Path) -> String {
        let tr = &self.trajectory;
        let e = &self.errors;
        let s0 = tr.truth.first().copied().unwrap_or_default();
        let rpy = s0.rpy_rad.map(f64::to_degrees);
        let yaw = rpy[2].rem_euclid(360.0);
        let max3 = |a: [f64; 3]| a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let mgal = 1e-5;
        let dph = crate::errors::DEG_PER_H_RADPS;
        let bias_std = |s: &crate::errors::SensorErrors| -> (f64, f64) {
            let mut var_max = 0.0f64;
            let mut tau = 3600.0;
            for i in 0..3 {
                let gm_var = if s.gm_psd.0[i] > 0.0 {
                    0.5 * s.gm_psd.0[i] * s.gm_tau_s.0[i]
                } else {
                    0.0
                };
                let rc_var = s.turn_on_bias_sigma.0[i].powi(2)
                    + s.bias.0[i].powi(2)
                    + s.flicker_b.0[i].powi(2);
                if gm_var > rc_var {
                    tau = s.gm_tau_s.0[i];
                }
                var_max = var_max.max(gm_var + rc_var);
            }
            (var_max.sqrt(), tau)
        };
        let (gb, tau_g) = bias_std(&e.gyro);
        let (ab, tau_a) = bias_std(&e.accel);
        let corr_h = tau_g.min(tau_a) / 3600.0;
        let arw = max3(e.gyro.white_psd.0).sqrt().to_degrees() * 60.0;
        let vrw = max3(e.accel.white_psd.0).sqrt() * 60.0;
        let gs = max3(e.gyro.scale_factor_ppm.0).max(1.0);
        let as_ = max3(e.accel.scale_factor_ppm.0).max(1.0);
        let imudatalen = if e.temperature.is_some() { 8 } else { 7 };
        let l = e.gnss.lever_arm_b_m.0;
        let p = |f: &str| dir.join(f).display().to_string();
        format!(
            "# KF-GINS configuration written by `host-sim simulate` (seed {seed}).\n\
             # Initial state = truth at the first IMU epoch. Noise mapped from the case's error\n\
             # model (see case.toml); KF-GINS cannot represent the random walk, the separate\n\
             # FOGM/turn-on processes nor the undeclared effects (temperature, misalignment,\n\
             # g-sensitivity, time offset): those are in case.toml only.\n\
             imupath: \"{imu}\"\n\
             gnsspath: \"{gnss}\"\n\
             outputpath: \"{out}\"\n\
             imudatalen: {imudatalen}\n\
             imudatarate: {rate}\n\
             starttime: {t0}\n\
             endtime: -1\n\
             initpos: [ {lat:.10}, {lon:.10}, {h:.4} ]\n\
             initvel: [ {vn}, {ve}, {vd} ]\n\
             initatt: [ {r:.8}, {pi:.8}, {y:.8} ]\n\
             initgyrbias: [ 0, 0, 0 ]    # [deg/h]\n\
             initaccbias: [ 0, 0, 0 ]    # [mGal]\n\
             initgyrscale: [ 0, 0, 0 ]   # [ppm]\n\
             initaccscale: [ 0, 0, 0 ]   # [ppm]\n\
             initposstd: [ 0.01, 0.01, 0.02 ]   # [m]\n\
             initvelstd: [ 0.01, 0.01, 0.01 ]   # [m/s]\n\
             initattstd: [ 0.01, 0.01, 0.05 ]   # [deg]\n\
             initbgstd: [ {gbd}, {gbd}, {gbd} ]   # [deg/h]\n\
             initbastd: [ {abm}, {abm}, {abm} ]   # [mGal]\n\
             initsgstd: [ {gs}, {gs}, {gs} ]   # [ppm]\n\
             initsastd: [ {as_}, {as_}, {as_} ]   # [ppm]\n\
             imunoise:\n\
             \x20 arw: [ {arw:e}, {arw:e}, {arw:e} ]   # [deg/sqrt(hr)]\n\
             \x20 vrw: [ {vrw:e}, {vrw:e}, {vrw:e} ]   # [m/s/sqrt(hr)]\n\
             \x20 gbstd: [ {gbd}, {gbd}, {gbd} ]   # [deg/hr]\n\
             \x20 abstd: [ {abm}, {abm}, {abm} ]   # [mGal]\n\
             \x20 gsstd: [ {gs}, {gs}, {gs} ]   # [ppm]\n\
             \x20 asstd: [ {as_}, {as_}, {as_} ]   # [ppm]\n\
             \x20 corrtime: {corr_h}   # [hr]\n\
             antlever: [ {l0}, {l1}, {l2} ]   # [m] forward, right, down\n",
            seed = self.seed,
            imu = p("imu.txt"),
            gnss = p("gnss.txt"),
            out = dir.display(),
            rate = tr.scenario.imu.rate_hz,
            t0 = tr.t0_s,
            lat = s0.lat_rad.to_degrees(),
            lon = s0.lon_rad.to_degrees(),
            h = s0.h_m,
            vn = s0.vel_ned_mps[0],
            ve = s0.vel_ned_mps[1],
            vd = s0.vel_ned_mps[2],
            r = rpy[0],
            pi = rpy[1],
            y = yaw,
            gbd = gb / dph,
            abm = ab / mgal,
            l0 = l[0],
            l1 = l[1],
            l2 = l[2],
        )
    }
}
