//! Sensor and GNSS error model: what a simulated case's IMU and GNSS get on top of the ideal
//! trajectory, seeded and reproducible.
//!
//! IMU, per axis, applied in the rate domain and integrated over each IMU interval `dt`:
//!
//! ```text
//! dtheta_meas = (I + diag(sf_g) + M_g) dtheta + G dv
//!             + (b_fixed + b_turn_on + b_GM + b_RW + b_flicker) dt + k_T int (T - T_ref) dt
//!             + white increment (variance S_N dt)          then quantization with carry
//! dv_meas     = (I + diag(sf_a) + M_a) dv + (same bias terms) + white, then quantization
//! ```
//!
//! with `dtheta`, `dv` the ideal increments, `sf` the scale factors (fixed, plus an optional
//! first-order Gauss-Markov part, [`SensorErrors::scale_factor_gm`]), `M` the off-diagonal
//! misalignment/non-orthogonality matrix (`meas_i += M_ij * true_j`, rad), `G` the gyro
//! g-sensitivity (rad/s per m/s^2, so `G dv` is in rad), `k_T` the temperature coefficient of
//! the bias and `T(t)` the simulated sensor temperature. GNSS: the antenna position (IMU
//! position + `C_b^n l^b`) at true time `t_tag - time_offset_s`, plus white and first-order
//! Gauss-Markov NED errors, tagged `t_tag` on a regular grid of the GNSS rate.
//!
//! Randomness: every (sensor, error source, axis) has its own ChaCha8 stream derived from the
//! one `u64` seed, so switching a source on or off leaves all other sources' realisations
//! unchanged (the study's error budget relies on that).

use crate::noise::{Flicker, GaussMarkov, Quantizer, RandomConstant, RandomWalk, White};
use crate::trajectory::{dcm_from_euler, Trajectory};
use nalgebra::{Matrix3, Vector3};
use nav_core::earth::{self, Llh};
use nav_core::types::{FixQuality, GnssFix, ImuSample};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Errors of the error-model description.
#[derive(Debug, thiserror::Error)]
pub enum ErrorModelError {
    /// File could not be read.
    #[error("error model {path}: {source}")]
    Io {
        /// File path.
        path: String,
        /// Underlying error.
        source: std::io::Error,
    },
    /// TOML could not be parsed or has unknown keys (message carries line and column).
    #[error("error model {path}: {source}")]
    Parse {
        /// File path or `<string>`.
        path: String,
        /// The TOML parser's (or, merging a preset, serializer's) error.
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
    /// Unknown preset name.
    #[error("unknown error preset `{0}` (known: none, seed-nbk, tactical, consumer-mems)")]
    UnknownPreset(String),
    /// A value is out of range.
    #[error("error model: {0}")]
    Invalid(String),
}

/// A per-axis value (x, y, z). In TOML either one number (same on all axes) or an array of 3.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
#[serde(transparent)]
pub struct Axes3(pub [f64; 3]);

impl<'de> Deserialize<'de> for Axes3 {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Either {
            One(f64),
            Three([f64; 3]),
        }
        Ok(match Either::deserialize(d)? {
            Either::One(x) => Axes3([x; 3]),
            Either::Three(a) => Axes3(a),
        })
    }
}

impl Axes3 {
    /// The same value on all axes.
    pub const fn splat(x: f64) -> Self {
        Self([x; 3])
    }
    fn all(&self, f: impl Fn(f64) -> bool) -> bool {
        self.0.iter().all(|&x| f(x))
    }
    fn is_zero(&self) -> bool {
        self.all(|x| x == 0.0)
    }
}

/// Error model of one sensor triad (accelerometers or gyros). Rate units: m/s^2 for
/// accelerometers, rad/s for gyros; PSDs two-sided (IEEE 952, see `docs/DESIGN.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorErrors {
    /// White noise PSD S_N: m^2/s^3 (accelerometer), rad^2/s (gyro).
    pub white_psd: Axes3,
    /// First-order Gauss-Markov driving PSD S_B: m^2/s^5, rad^2/s^3 (stationary variance
    /// S_B T_B / 2).
    pub gm_psd: Axes3,
    /// Gauss-Markov correlation time T_B, s.
    pub gm_tau_s: Axes3,
    /// Random-walk PSD S_K: m^2/s^5, rad^2/s^3.
    pub rw_psd: Axes3,
    /// Flicker coefficient B (IEEE 952; Allan floor 0.6643 B): m/s^2, rad/s.
    pub flicker_b: Axes3,
    /// Length of the independent flicker blocks, s (flicker is 1/f up to about a tenth of it).
    pub flicker_block_s: f64,
    /// Standard deviation of the random-constant turn-on bias (drawn per seed): m/s^2, rad/s.
    pub turn_on_bias_sigma: Axes3,
    /// Fixed (deterministic) bias: m/s^2, rad/s.
    pub bias: Axes3,
    /// A bias step (m/s^2, rad/s) added to every sample from `bias_step_at_s` on (an
    /// undeclared change of the bias: a shock, a mode switch); zero = none.
    pub bias_step: Axes3,
    /// Time of the bias step, s after the first IMU epoch.
    pub bias_step_at_s: f64,
    /// Quantum of the output increments: m/s, rad (0 = off).
    pub quantization_step: Axes3,
    /// Scale-factor error, ppm.
    pub scale_factor_ppm: Axes3,
    /// A time-varying scale-factor error on top of `scale_factor_ppm`: first-order
    /// Gauss-Markov (KF-GINS' scale-factor model), stationary start; none when absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale_factor_gm: Option<ScaleFactorGm>,
    /// Misalignment / non-orthogonality, rad: row i = sensor axis, column j = body axis;
    /// `meas_i += M_ij * true_j`. The diagonal must be zero (use `scale_factor_ppm`).
    pub misalignment_rad: [[f64; 3]; 3],
    /// Temperature coefficient of the bias: m/s^2/degC, rad/s/degC (needs `[temperature]`).
    pub temp_coeff_per_c: Axes3,
    /// Gyros only: g-sensitivity matrix, rad/s per m/s^2 of specific force (row = gyro axis,
    /// column = specific-force axis).
    pub g_sensitivity_radps_per_mps2: [[f64; 3]; 3],
}

impl Default for SensorErrors {
    /// No errors (flicker blocks of 600 s when flicker is switched on).
    fn default() -> Self {
        Self {
            white_psd: Axes3::default(),
            gm_psd: Axes3::default(),
            gm_tau_s: Axes3::default(),
            rw_psd: Axes3::default(),
            flicker_b: Axes3::default(),
            flicker_block_s: 600.0,
            turn_on_bias_sigma: Axes3::default(),
            bias: Axes3::default(),
            bias_step: Axes3::default(),
            bias_step_at_s: 0.0,
            quantization_step: Axes3::default(),
            scale_factor_ppm: Axes3::default(),
            scale_factor_gm: None,
            misalignment_rad: [[0.0; 3]; 3],
            temp_coeff_per_c: Axes3::default(),
            g_sensitivity_radps_per_mps2: [[0.0; 3]; 3],
        }
    }
}

/// A Gauss-Markov scale-factor error ([`SensorErrors::scale_factor_gm`]): per axis the
/// process `s' = -s / tau + w` with stationary standard deviation `sigma_ppm` (the driving
/// PSD `2 sigma^2 / tau`), drawn from the stationary distribution at the first sample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScaleFactorGm {
    /// Stationary standard deviation, ppm.
    pub sigma_ppm: Axes3,
    /// Correlation time, s.
    pub tau_s: f64,
}

/// Simulated sensor temperature: `T(t) = start_c + rise_c (1 - exp(-(t - t0) / tau_s))`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Temperature {
    /// Temperature at the first epoch, degC.
    pub start_c: f64,
    /// Warm-up rise, degC.
    pub rise_c: f64,
    /// Warm-up time constant, s.
    pub tau_s: f64,
    /// Reference temperature of the temperature-dependent biases, degC (default: `start_c`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_c: Option<f64>,
    /// White noise on the reported temperature column only, degC (the biases follow the true
    /// temperature).
    #[serde(default)]
    pub report_noise_c: f64,
}

impl Temperature {
    /// Reference temperature of the biases, degC.
    pub fn reference(&self) -> f64 {
        self.reference_c.unwrap_or(self.start_c)
    }
    /// True temperature at `t_rel` seconds after the start, degC.
    pub fn at(&self, t_rel: f64) -> f64 {
        self.start_c + self.rise_c * (1.0 - (-t_rel / self.tau_s).exp())
    }
    /// `int_a^b (T(t) - T_ref) dt` (relative times, s), degC s.
    pub fn integral_rel(&self, a: f64, b: f64) -> f64 {
        (self.start_c + self.rise_c - self.reference()) * (b - a)
            - self.rise_c * self.tau_s * ((-a / self.tau_s).exp() - (-b / self.tau_s).exp())
    }
}

/// One GNSS outage, relative to the first IMU epoch.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Outage {
    /// Start, s after the first IMU epoch.
    pub start_s: f64,
    /// Duration, s (fixes with tag in [start, start + duration) are removed).
    pub duration_s: f64,
}

/// Repeating outages: `duration_s` every `period_s`, the first one at `first_start_s`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PeriodicOutage {
    /// Start of the first outage, s after the first IMU epoch.
    pub first_start_s: f64,
    /// Duration of each outage, s.
    pub duration_s: f64,
    /// Period, s.
    pub period_s: f64,
}

/// GNSS model: rate, errors, antenna lever arm, time-tag offset, outages.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GnssErrors {
    /// Fix rate, Hz (fixes at `t0 + k / rate_hz`).
    pub rate_hz: f64,
    /// White position error standard deviation, north/east/down, m.
    pub white_sigma_ned_m: Axes3,
    /// Gauss-Markov (time-correlated) position error stationary std, north/east/down, m.
    pub gm_sigma_ned_m: Axes3,
    /// Its correlation time, s.
    pub gm_tau_s: f64,
    /// Standard deviations written to the file, m (default: root-sum-square of white and GM).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reported_std_ned_m: Option<Axes3>,
    /// Whether the fixes carry a velocity.
    pub velocity: bool,
    /// White velocity error standard deviation, m/s.
    pub vel_white_sigma_ned_mps: Axes3,
    /// Velocity standard deviations written to the file, m/s (default: the white sigma).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reported_vel_std_ned_mps: Option<Axes3>,
    /// Antenna position in the body frame (FRD) relative to the IMU, m.
    pub lever_arm_b_m: Axes3,
    /// Time-tag offset, s: a fix tagged `t` is the antenna position at IMU time
    /// `t - time_offset_s` (positive = GNSS tags late).
    pub time_offset_s: f64,
    /// Outages.
    pub outages: Vec<Outage>,
    /// Repeating outages (e.g. KF-GINS' 60 s every 180 s).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub periodic_outage: Option<PeriodicOutage>,
}

impl Default for GnssErrors {
    fn default() -> Self {
        Self {
            rate_hz: 1.0,
            white_sigma_ned_m: Axes3::default(),
            gm_sigma_ned_m: Axes3::default(),
            gm_tau_s: 60.0,
            reported_std_ned_m: None,
            velocity: false,
            vel_white_sigma_ned_mps: Axes3::default(),
            reported_vel_std_ned_mps: None,
            lever_arm_b_m: Axes3::default(),
            time_offset_s: 0.0,
            outages: Vec::new(),
            periodic_outage: None,
        }
    }
}

impl GnssErrors {
    /// Reported position standard deviations, m.
    pub fn reported_std(&self) -> [f64; 3] {
        match self.reported_std_ned_m {
            Some(a) => a.0,
            None => {
                let (w, g) = (self.white_sigma_ned_m.0, self.gm_sigma_ned_m.0);
                [0, 1, 2].map(|i| (w[i] * w[i] + g[i] * g[i]).sqrt())
            }
        }
    }

    /// Reported velocity standard deviations, m/s.
    pub fn reported_vel_std(&self) -> [f64; 3] {
        self.reported_vel_std_ned_mps
            .unwrap_or(self.vel_white_sigma_ned_mps)
            .0
    }

    /// All outages (explicit and periodic) as (start, duration), s after the first epoch,
    /// up to `duration_s`, sorted by start.
    pub fn all_outages(&self, duration_s: f64) -> Vec<Outage> {
        let mut v = self.outages.clone();
        if let Some(p) = self.periodic_outage {
            let mut s = p.first_start_s;
            while s < duration_s && p.period_s > 0.0 {
                v.push(Outage {
                    start_s: s,
                    duration_s: p.duration_s,
                });
                s += p.period_s;
            }
        }
        v.sort_by(|a, b| a.start_s.total_cmp(&b.start_s));
        v
    }
}

/// The complete error model of a simulated case.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ErrorModel {
    /// Name of the preset this model was built from (informative).
    #[serde(default)]
    pub name: String,
    /// Accelerometer errors.
    #[serde(default)]
    pub accel: SensorErrors,
    /// Gyro errors.
    #[serde(default)]
    pub gyro: SensorErrors,
    /// Sensor temperature profile; when present the IMU file gets the temperature column.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature: Option<Temperature>,
    /// GNSS errors.
    #[serde(default)]
    pub gnss: GnssErrors,
    /// IMU clock frequency error, ppm (positive: the IMU clock runs fast). The trajectory, the
    /// truth and the IMU samples are on the IMU clock; the GNSS fix tagged `t` (GNSS clock) is
    /// the antenna at IMU time `t + 1e-6 ppm (t - t_0)` (`t_0` the first IMU epoch): the
    /// GNSS-IMU time offset grows by `1e-6 ppm` s per s. Each IMU increment is integrated over
    /// the true interval, `1 / (1 + 1e-6 ppm)` of its stamped one (to first order in the
    /// drift: a `-ppm` common scale factor, `ppm * g` of apparent vertical bias).
    #[serde(default)]
    pub imu_clock_drift_ppm: f64,
}

/// An error-model file: the model plus an optional `base` preset it overrides.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ErrorModelFile {
    #[serde(default)]
    base: Option<String>,
    #[serde(default)]
    name: String,
    #[serde(default)]
    accel: SensorErrors,
    #[serde(default)]
    gyro: SensorErrors,
    #[serde(default)]
    temperature: Option<Temperature>,
    #[serde(default)]
    gnss: GnssErrors,
    #[serde(default)]
    imu_clock_drift_ppm: f64,
}

/// Micro-g in m/s^2.
pub const UG_MPS2: f64 = 1e-6 * nav_core::earth::G0_MPS2;
/// One degree per hour in rad/s.
pub const DEG_PER_H_RADPS: f64 = std::f64::consts::PI / 180.0 / 3600.0;

/// Names of the built-in presets.
pub const PRESETS: [&str; 4] = ["none", "seed-nbk", "tactical", "consumer-mems"];

fn rtk_gnss() -> GnssErrors {
    GnssErrors {
        white_sigma_ned_m: Axes3([0.008, 0.008, 0.015]),
        gm_sigma_ned_m: Axes3([0.006, 0.006, 0.012]),
        gm_tau_s: 60.0,
        vel_white_sigma_ned_mps: Axes3([0.02, 0.02, 0.03]),
        ..GnssErrors::default()
    }
}

impl ErrorModel {
    /// A built-in preset:
    ///
    /// - `none`: no IMU or GNSS errors (GNSS reports 0.01/0.01/0.02 m so files stay valid).
    /// - `seed-nbk`: the source document's identified tactical IMU (Appendix V): accelerometer
    ///   S_N = 6.2865e-9 m^2/s^3 (8.1 ug/sqrt(Hz)), FOGM S_B = 2.4360e-11 m^2/s^5 with
    ///   T_B = 45 s, random walk S_K = 2.6731e-12 m^2/s^5; gyro S_N = 5.3079e-10 rad^2/s
    ///   (0.079 deg/sqrt(h)); no quantization (as in the source's simulation). Turn-on biases
    ///   (the source gives none; assumed): 25 ug and 0.1 deg/h (the manufacturer's gyro bias
    ///   specification) 1-sigma. RTK GNSS: white 8/8/15 mm + GM 6/6/12 mm (60 s).
    /// - `tactical`: a generic tactical IMU: 50 ug/sqrt(Hz), GM 50 ug / 300 s, turn-on 200 ug;
    ///   gyro 0.1 deg/sqrt(h), GM 1 deg/h / 300 s, turn-on 1 deg/h. RTK GNSS.
    /// - `consumer-mems`: 150 ug/sqrt(Hz), flicker 40 ug, turn-on 5 mg, quantum 9e-6 m/s;
    ///   gyro 0.014 deg/s/sqrt(Hz), flicker 7.5 deg/h, turn-on 0.05 deg/s, quantum 5.3e-6 rad
    ///   (16-bit outputs at 200 Hz). RTK GNSS.
    pub fn preset(name: &str) -> Result<Self, ErrorModelError> {
        let mut m = ErrorModel {
            name: name.to_string(),
            accel: SensorErrors::default(),
            gyro: SensorErrors::default(),
            temperature: None,
            gnss: rtk_gnss(),
            imu_clock_drift_ppm: 0.0,
        };
        match name {
            "none" => {
                m.gnss = GnssErrors {
                    reported_std_ned_m: Some(Axes3([0.01, 0.01, 0.02])),
                    reported_vel_std_ned_mps: Some(Axes3([0.01, 0.01, 0.02])),
                    ..GnssErrors::default()
                };
            }
            "seed-nbk" => {
                m.accel.white_psd = Axes3::splat(6.2865e-9);
                m.accel.gm_psd = Axes3::splat(2.4360e-11);
                m.accel.gm_tau_s = Axes3::splat(45.0);
                m.accel.rw_psd = Axes3::splat(2.6731e-12);
                m.accel.turn_on_bias_sigma = Axes3::splat(25.0 * UG_MPS2);
                m.gyro.white_psd = Axes3::splat(5.3079e-10);
                m.gyro.turn_on_bias_sigma = Axes3::splat(0.1 * DEG_PER_H_RADPS);
            }
            "tactical" => {
                let n_a = 50.0 * UG_MPS2;
                let (sig_a, t_a) = (50.0 * UG_MPS2, 300.0);
                m.accel.white_psd = Axes3::splat(n_a * n_a);
                m.accel.gm_psd = Axes3::splat(2.0 * sig_a * sig_a / t_a);
                m.accel.gm_tau_s = Axes3::splat(t_a);
                m.accel.turn_on_bias_sigma = Axes3::splat(200.0 * UG_MPS2);
                let n_g = 0.1f64.to_radians() / 60.0;
                let (sig_g, t_g) = (1.0 * DEG_PER_H_RADPS, 300.0);
                m.gyro.white_psd = Axes3::splat(n_g * n_g);
                m.gyro.gm_psd = Axes3::splat(2.0 * sig_g * sig_g / t_g);
                m.gyro.gm_tau_s = Axes3::splat(t_g);
                m.gyro.turn_on_bias_sigma = Axes3::splat(1.0 * DEG_PER_H_RADPS);
            }
            "consumer-mems" => {
                let n_a = 150.0 * UG_MPS2;
                m.accel.white_psd = Axes3::splat(n_a * n_a);
                m.accel.flicker_b = Axes3::splat(40.0 * UG_MPS2);
                m.accel.turn_on_bias_sigma = Axes3::splat(5000.0 * UG_MPS2);
                m.accel.quantization_step = Axes3::splat(9e-6);
                let n_g = 0.014f64.to_radians();
                m.gyro.white_psd = Axes3::splat(n_g * n_g);
                m.gyro.flicker_b = Axes3::splat(7.5 * DEG_PER_H_RADPS);
                m.gyro.turn_on_bias_sigma = Axes3::splat(0.05f64.to_radians());
                m.gyro.quantization_step = Axes3::splat(5.3e-6);
            }
            other => return Err(ErrorModelError::UnknownPreset(other.to_string())),
        }
        Ok(m)
    }

    /// Parses an error model from TOML. A top-level `base = "<preset>"` starts from that
    /// preset and overrides only the keys given.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, ErrorModelError> {
        let perr = |e: Box<dyn std::error::Error + Send + Sync>| ErrorModelError::Parse {
            path: origin.to_string(),
            source: e,
        };
        // Typed parse first: unknown keys and wrong types are reported with line and column.
        let direct: ErrorModelFile = toml::from_str(text).map_err(|e| perr(Box::new(e)))?;
        let merged = match direct.base {
            None => {
                let m = ErrorModel {
                    name: direct.name,
                    accel: direct.accel,
                    gyro: direct.gyro,
                    temperature: direct.temperature,
                    gnss: direct.gnss,
                    imu_clock_drift_ppm: direct.imu_clock_drift_ppm,
                };
                m.validate()?;
                return Ok(m);
            }
            Some(name) => {
                let mut user: toml::Table = toml::from_str(text).map_err(|e| perr(Box::new(e)))?;
                user.remove("base");
                let preset = Self::preset(&name)?;
                let mut t = toml::Table::try_from(&preset).map_err(|e| perr(Box::new(e)))?;
                merge(&mut t, user);
                if !t.contains_key("name")
                    || t.get("name") == Some(&toml::Value::from(name.clone()))
                {
                    t.insert(
                        "name".into(),
                        toml::Value::from(format!("{name}+overrides")),
                    );
                }
                t
            }
        };
        let m: ErrorModel = merged
            .try_into()
            .map_err(|e: toml::de::Error| perr(Box::new(e)))?;
        m.validate()?;
        Ok(m)
    }

    /// A preset name or a TOML file path.
    pub fn load(spec: &str) -> Result<Self, ErrorModelError> {
        if PRESETS.contains(&spec) {
            return Self::preset(spec);
        }
        let p = Path::new(spec);
        if !p.exists() {
            return Err(ErrorModelError::UnknownPreset(spec.to_string()));
        }
        let text = std::fs::read_to_string(p).map_err(|e| ErrorModelError::Io {
            path: spec.to_string(),
            source: e,
        })?;
        Self::from_toml_str(&text, spec)
    }

    /// The model as TOML text (every value explicit).
    pub fn to_toml_string(&self) -> String {
        toml::to_string(self).unwrap_or_default()
    }

    /// Checks ranges and consistency.
    pub fn validate(&self) -> Result<(), ErrorModelError> {
        let bad = |m: String| Err(ErrorModelError::Invalid(m));
        for (name, s) in [("accel", &self.accel), ("gyro", &self.gyro)] {
            let nonneg = [
                ("white_psd", s.white_psd),
                ("gm_psd", s.gm_psd),
                ("rw_psd", s.rw_psd),
                ("flicker_b", s.flicker_b),
                ("turn_on_bias_sigma", s.turn_on_bias_sigma),
                ("quantization_step", s.quantization_step),
            ];
            for (k, v) in nonneg {
                if !v.all(|x| x.is_finite() && x >= 0.0) {
                    return bad(format!("{name}.{k} = {:?} must be finite and >= 0", v.0));
                }
            }
            for i in 0..3 {
                if s.gm_psd.0[i] > 0.0 && !(s.gm_tau_s.0[i] > 0.0 && s.gm_tau_s.0[i].is_finite()) {
                    return bad(format!("{name}.gm_tau_s must be > 0 where gm_psd > 0"));
                }
                if s.misalignment_rad[i][i] != 0.0 {
                    return bad(format!(
                        "{name}.misalignment_rad[{i}][{i}] must be 0 (use scale_factor_ppm)"
                    ));
                }
            }
            if !s.flicker_b.is_zero() && !pos(s.flicker_block_s) {
                return bad(format!("{name}.flicker_block_s must be > 0"));
            }
            if !(s.bias_step.all(f64::is_finite)
                && s.bias_step_at_s.is_finite()
                && s.bias_step_at_s >= 0.0)
            {
                return bad(format!(
                    "{name}: bias_step must be finite and bias_step_at_s finite and >= 0"
                ));
            }
            check_scale_gm(name, s.scale_factor_gm.as_ref())?;
            let finite = [s.bias, s.scale_factor_ppm, s.temp_coeff_per_c];
            if !finite.iter().all(|a| a.all(f64::is_finite))
                || !s.misalignment_rad.iter().flatten().all(|x| x.is_finite())
                || !s
                    .g_sensitivity_radps_per_mps2
                    .iter()
                    .flatten()
                    .all(|x| x.is_finite())
            {
                return bad(format!("{name}: non-finite value"));
            }
            if !s.temp_coeff_per_c.is_zero() && self.temperature.is_none() {
                return bad(format!(
                    "{name}.temp_coeff_per_c needs a [temperature] profile"
                ));
            }
        }
        if self
            .accel
            .g_sensitivity_radps_per_mps2
            .iter()
            .flatten()
            .any(|&x| x != 0.0)
        {
            return bad("accel.g_sensitivity_radps_per_mps2: g-sensitivity is a gyro error".into());
        }
        if let Some(t) = &self.temperature {
            if !pos(t.tau_s) || !t.start_c.is_finite() || !t.rise_c.is_finite() {
                return bad("temperature: tau_s must be > 0, start_c and rise_c finite".into());
            }
        }
        if !below(self.imu_clock_drift_ppm, 1000.0) {
            return bad(format!(
                "imu_clock_drift_ppm = {} must be finite and below 1000 in magnitude",
                self.imu_clock_drift_ppm
            ));
        }
        let g = &self.gnss;
        if !(g.rate_hz > 0.0 && g.rate_hz <= 100.0) {
            return bad(format!("gnss.rate_hz = {} outside (0, 100]", g.rate_hz));
        }
        if !g.gm_sigma_ned_m.is_zero() && !pos(g.gm_tau_s) {
            return bad("gnss.gm_tau_s must be > 0".into());
        }
        if !g.reported_std().iter().all(|&s| s > 0.0 && s.is_finite()) {
            return bad("gnss: reported position std must be > 0 (set gnss.reported_std_ned_m when the errors are zero)".into());
        }
        if g.velocity
            && !g
                .reported_vel_std()
                .iter()
                .all(|&s| s > 0.0 && s.is_finite())
        {
            return bad(
                "gnss: reported velocity std must be > 0 (set gnss.reported_vel_std_ned_mps)"
                    .into(),
            );
        }
        if !below(g.time_offset_s, 10.0) || !g.lever_arm_b_m.all(|x| x.abs() < 100.0) {
            return bad(
                "gnss: time_offset_s must be below 10 s and the lever arm below 100 m".into(),
            );
        }
        for o in &g.outages {
            if !(o.start_s.is_finite() && o.duration_s > 0.0) {
                return bad(format!("gnss outage {o:?}: start finite, duration > 0"));
            }
        }
        if let Some(p) = g.periodic_outage {
            if !(p.duration_s > 0.0 && p.period_s > p.duration_s && p.first_start_s.is_finite()) {
                return bad(format!(
                    "gnss.periodic_outage {p:?}: need 0 < duration < period"
                ));
            }
        }
        Ok(())
    }
}

/// Checks a sensor's Gauss-Markov scale factor (`name` the sensor, for the message).
fn check_scale_gm(name: &str, g: Option<&ScaleFactorGm>) -> Result<(), ErrorModelError> {
    match g {
        Some(g) if !(g.sigma_ppm.all(|x| x.is_finite() && x >= 0.0) && pos(g.tau_s)) => {
            Err(ErrorModelError::Invalid(format!(
                "{name}.scale_factor_gm: sigma_ppm must be finite and >= 0, tau_s > 0"
            )))
        }
        _ => Ok(()),
    }
}

/// True when `x` is finite and positive.
fn pos(x: f64) -> bool {
    x.is_finite() && x > 0.0
}

/// True when `|x| < lim` (false for NaN).
fn below(x: f64, lim: f64) -> bool {
    x.abs() < lim
}

fn merge(base: &mut toml::Table, over: toml::Table) {
    for (k, v) in over {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge(b, o),
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

/// Values drawn per seed (the random constants), the ground truth a diagnosis compares to.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Realized {
    /// Accelerometer turn-on bias, m/s^2 (drawn) plus the fixed bias.
    pub accel_bias_mps2: [f64; 3],
    /// Gyro turn-on bias, rad/s (drawn) plus the fixed bias.
    pub gyro_bias_radps: [f64; 3],
}

/// The sensor outputs of one seeded run.
#[derive(Debug, Clone)]
pub struct Measurements {
    /// IMU samples with errors (temperature column filled when the model has a profile).
    pub imu: Vec<ImuSample>,
    /// GNSS fixes (outages removed).
    pub gnss: Vec<GnssFix>,
    /// Realised random constants.
    pub realized: Realized,
}

/// Sensors and sources of the random streams.
const ACCEL: u64 = 1;
const GYRO: u64 = 2;
const GNSS: u64 = 3;
const TEMP: u64 = 4;
const SRC_WHITE: u64 = 1;
const SRC_GM: u64 = 2;
const SRC_RW: u64 = 3;
const SRC_FLICKER: u64 = 4;
const SRC_TURN_ON: u64 = 5;
const SRC_GNSS_VEL: u64 = 6;
const SRC_SCALE_GM: u64 = 7;

/// The random stream of (sensor, source, axis) for a seed: independent of every other
/// stream, so turning a source on or off never changes the others.
pub fn stream(seed: u64, sensor: u64, source: u64, axis: u64) -> ChaCha8Rng {
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    r.set_stream((sensor << 32) | (source << 16) | axis);
    r
}

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

fn transform(s: &SensorErrors) -> Matrix3<f64> {
    let mut m = Matrix3::identity();
    for i in 0..3 {
        m[(i, i)] += s.scale_factor_ppm.0[i] * 1e-6;
        for j in 0..3 {
            if i != j {
                m[(i, j)] += s.misalignment_rad[i][j];
            }
        }
    }
    m
}

impl ErrorModel {
    /// Applies the model to an error-free trajectory with `seed`: IMU and GNSS measurements.
    pub fn apply(&self, traj: &Trajectory, seed: u64) -> Measurements {
        let (imu, realized) = self.apply_imu(traj, seed);
        let gnss = self.apply_gnss(traj, seed);
        Measurements {
            imu,
            gnss,
            realized,
        }
    }

    /// IMU samples with errors and the realised random constants (the trajectory's samples
    /// through [`ImuErrors`] one by one).
    pub fn apply_imu(&self, traj: &Trajectory, seed: u64) -> (Vec<ImuSample>, Realized) {
        let mut e = ImuErrors::new(self, seed, traj.dt_s, traj.imu.len());
        let out = traj
            .imu
            .iter()
            .enumerate()
            .map(|(k, s)| e.apply(k, s))
            .collect();
        (out, e.realized())
    }

    /// GNSS fixes of the trajectory with errors, lever arm, time offset and outages.
    pub fn apply_gnss(&self, traj: &Trajectory, seed: u64) -> Vec<GnssFix> {
        let g = &self.gnss;
        let dur = traj.duration_s();
        let outages = g.all_outages(dur);
        let period = 1.0 / g.rate_hz;
        let n = (dur / period + 1e-9).floor() as usize + 1;
        let std = g.reported_std();
        let vstd = g.reported_vel_std();
        let lever = Vector3::from(g.lever_arm_b_m.0);
        let mut noise = GnssNoise::new(g, seed);
        let mut fixes = Vec::with_capacity(n);
        for k in 0..n {
            let t_rel = k as f64 * period;
            // Draw every epoch's errors (also in outages) so outages do not shift the streams.
            let (err, verr) = noise.next_epoch();
            if outages
                .iter()
                .any(|o| t_rel >= o.start_s && t_rel < o.start_s + o.duration_s)
            {
                continue;
            }
            let t_tag = traj.t0_s + t_rel;
            let drift = self.imu_clock_drift_ppm * 1e-6 * t_rel;
            let Some(st) = traj.truth_at(t_tag - g.time_offset_s + drift) else {
                continue;
            };
            let (r, p, y) = st.q_nb.euler_angles();
            let c_bn = dcm_from_euler(r, p, y);
            let ant = earth::displace(&st.pos, &(c_bn * lever));
            let meas: Llh = earth::displace(&ant, &err);
            let mut fix = GnssFix {
                t_s: t_tag,
                lat_rad: meas.lat_rad,
                lon_rad: meas.lon_rad,
                h_m: meas.h_m,
                pos_std_ned_m: std,
                quality: FixQuality::RtkFixed,
                num_sats: 12,
                ..GnssFix::default()
            };
            if g.velocity {
                let w_nb = traj.omega_nb_b_at(st.t_s);
                let v = st.vel_ned_mps + c_bn * w_nb.cross(&lever) + verr;
                fix.has_velocity = true;
                fix.vel_ned_mps = v.into();
                fix.vel_std_ned_mps = vstd;
            }
            fixes.push(fix);
        }
        fixes
    }
}

/// The sensor a stream of [`AxisErrors`] belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sensor {
    /// The accelerometer triad (increments dv, m/s).
    Accel,
    /// The gyro triad (increments dtheta, rad).
    Gyro,
}

impl Sensor {
    fn id(self) -> u64 {
        match self {
            Self::Accel => ACCEL,
            Self::Gyro => GYRO,
        }
    }
}

/// The bias and stochastic errors of one axis of one sensor ([`SensorErrors`]: fixed and
/// turn-on bias, bias step, white noise, Gauss-Markov, random walk, flicker, quantization)
/// applied sample by sample: the one definition behind [`ErrorModel::apply_imu`] (which runs
/// it over a whole trajectory) and the streaming generators of the tests. Each process draws
/// from its own stream of the seed ([`stream`]), so sample `k` gets the same value however the
/// samples are produced.
#[derive(Debug, Clone)]
pub struct AxisErrors {
    dt: f64,
    /// Fixed plus turn-on bias, rate units.
    bias: f64,
    step: f64,
    step_first: usize,
    white: Option<(White, ChaCha8Rng)>,
    gm: Option<(GaussMarkov, ChaCha8Rng)>,
    rw: Option<(RandomWalk, ChaCha8Rng)>,
    flicker: Option<(Flicker, ChaCha8Rng)>,
    quant: Option<Quantizer>,
    /// The slowly varying part at the last sample (bias, step, Gauss-Markov, random walk,
    /// flicker), rate units.
    last_bias: f64,
}

impl AxisErrors {
    /// The errors of `axis` (0..3) of `sensor` in `e` for `seed`, samples of `dt_s` s;
    /// `n_samples` sizes the flicker blocks (as [`ErrorModel::apply_imu`] does for a
    /// trajectory of that many samples).
    pub fn for_sensor(
        e: &SensorErrors,
        sensor: Sensor,
        axis: usize,
        seed: u64,
        dt_s: f64,
        n_samples: usize,
    ) -> Self {
        Self::new(e, sensor.id(), axis, seed, dt_s, n_samples)
    }

    fn new(e: &SensorErrors, sensor: u64, axis: usize, seed: u64, dt: f64, n: usize) -> Self {
        let a = axis as u64;
        let get = |v: &Axes3| v.0.get(axis).copied().unwrap_or(0.0);
        let mut bias = get(&e.bias);
        if get(&e.turn_on_bias_sigma) > 0.0 {
            let mut rng = stream(seed, sensor, SRC_TURN_ON, a);
            bias += RandomConstant::new(get(&e.turn_on_bias_sigma)).next(&mut rng);
        }
        let (s_n, s_b, s_k, b) = (
            get(&e.white_psd),
            get(&e.gm_psd),
            get(&e.rw_psd),
            get(&e.flicker_b),
        );
        let q = get(&e.quantization_step);
        Self {
            dt,
            bias,
            step: get(&e.bias_step),
            step_first: (e.bias_step_at_s / dt - 1e-9).ceil().max(0.0) as usize,
            white: (s_n > 0.0)
                .then(|| (White::from_psd(s_n, dt), stream(seed, sensor, SRC_WHITE, a))),
            gm: (s_b > 0.0).then(|| {
                (
                    GaussMarkov::new(s_b, get(&e.gm_tau_s), dt),
                    stream(seed, sensor, SRC_GM, a),
                )
            }),
            rw: (s_k > 0.0).then(|| (RandomWalk::new(s_k, dt), stream(seed, sensor, SRC_RW, a))),
            flicker: (b > 0.0).then(|| {
                let block = ((e.flicker_block_s / dt).round() as usize).clamp(16, n.max(16));
                (
                    Flicker::new(b, dt, block),
                    stream(seed, sensor, SRC_FLICKER, a),
                )
            }),
            quant: (q > 0.0).then(|| Quantizer::new(q)),
            last_bias: bias,
        }
    }

    /// The increment `x` of sample `k` (m/s or rad) with this axis's errors added (each
    /// process's value times the sample time), then quantized.
    pub fn apply(&mut self, k: usize, mut x: f64) -> f64 {
        let dt = self.dt;
        let mut slow = self.bias;
        if self.bias != 0.0 {
            x += self.bias * dt;
        }
        if self.step != 0.0 && k >= self.step_first {
            x += self.step * dt;
            slow += self.step;
        }
        if let Some((w, rng)) = self.white.as_mut() {
            x += w.next(rng) * dt;
        }
        if let Some((w, rng)) = self.gm.as_mut() {
            let v = w.next(rng);
            x += v * dt;
            slow += v;
        }
        if let Some((w, rng)) = self.rw.as_mut() {
            let v = w.next(rng);
            x += v * dt;
            slow += v;
        }
        if let Some((w, rng)) = self.flicker.as_mut() {
            let v = w.next(rng);
            x += v * dt;
            slow += v;
        }
        if let Some(qz) = self.quant.as_mut() {
            x = qz.quantize(x);
        }
        self.last_bias = slow;
        x
    }

    /// The constant bias of the axis (fixed plus turn-on), rate units (m/s^2, rad/s).
    pub fn constant_bias(&self) -> f64 {
        self.bias
    }

    /// The bias during the last sample given to [`AxisErrors::apply`]: constant, step,
    /// Gauss-Markov, random walk and flicker (everything but the white noise and the
    /// quantization), rate units (m/s^2, rad/s).
    pub fn bias_now(&self) -> f64 {
        self.last_bias
    }
}

/// The IMU errors of an [`ErrorModel`] applied sample by sample: the deterministic terms
/// (scale factor, misalignment, g-sensitivity, temperature bias, IMU clock drift; the
/// Gauss-Markov scale factor when the model has one) on the ideal increments, then each
/// axis's bias and stochastic errors ([`AxisErrors`]). [`ErrorModel::apply_imu`] runs it over
/// a trajectory; a streaming generator (the filter tests' `test_support::filter_sim`) runs it
/// on samples as they are made and gets the same values for the same seed.
#[derive(Debug, Clone)]
pub struct ImuErrors {
    dt: f64,
    ma: Matrix3<f64>,
    mg: Matrix3<f64>,
    gs: Matrix3<f64>,
    accel_temp: [f64; 3],
    gyro_temp: [f64; 3],
    temperature: Option<Temperature>,
    temp_rng: ChaCha8Rng,
    true_interval: f64,
    /// Accelerometer axes, then gyro axes.
    axes: [AxisErrors; 6],
    /// Gauss-Markov scale factors (accelerometer axes, then gyro axes), when on.
    scale_gm: Option<[(GaussMarkov, ChaCha8Rng); 6]>,
    /// The Gauss-Markov scale factors of the last sample (accelerometer, gyro).
    last_scale_gm: [f64; 6],
}

impl ImuErrors {
    /// The IMU errors of `model` for `seed`, samples of `dt_s` s; `n_samples` sizes the flicker
    /// blocks (as for a trajectory of that many samples).
    pub fn new(model: &ErrorModel, seed: u64, dt_s: f64, n_samples: usize) -> Self {
        let axes = std::array::from_fn(|k| {
            let (e, sensor) = if k < 3 {
                (&model.accel, Sensor::Accel)
            } else {
                (&model.gyro, Sensor::Gyro)
            };
            AxisErrors::for_sensor(e, sensor, k % 3, seed, dt_s, n_samples)
        });
        let scale_gm = (model.accel.scale_factor_gm.is_some()
            || model.gyro.scale_factor_gm.is_some())
        .then(|| {
            std::array::from_fn(|k| {
                let (e, sensor) = if k < 3 {
                    (&model.accel, ACCEL)
                } else {
                    (&model.gyro, GYRO)
                };
                let (sigma, tau) = e
                    .scale_factor_gm
                    .map(|g| (g.sigma_ppm.0[k % 3] * 1e-6, g.tau_s))
                    .unwrap_or((0.0, 1.0));
                (
                    GaussMarkov::new(2.0 * sigma * sigma / tau, tau, dt_s),
                    stream(seed, sensor, SRC_SCALE_GM, (k % 3) as u64),
                )
            })
        });
        Self {
            dt: dt_s,
            ma: transform(&model.accel),
            mg: transform(&model.gyro),
            gs: Matrix3::from_fn(|i, j| model.gyro.g_sensitivity_radps_per_mps2[i][j]),
            accel_temp: model.accel.temp_coeff_per_c.0,
            gyro_temp: model.gyro.temp_coeff_per_c.0,
            temperature: model.temperature.clone(),
            temp_rng: stream(seed, TEMP, SRC_WHITE, 0),
            // the increments over the true interval of a stamped one (IMU clock drift)
            true_interval: 1.0 / (1.0 + model.imu_clock_drift_ppm * 1e-6),
            axes,
            scale_gm,
            last_scale_gm: [0.0; 6],
        }
    }

    /// The measured sample `k` (0 = the first of the run) of the ideal sample `s`
    /// (increments in rad and m/s; the temperature column filled when the model has a
    /// profile).
    pub fn apply(&mut self, k: usize, s: &ImuSample) -> ImuSample {
        let dt = self.dt;
        let dth = Vector3::from(s.dtheta_rad);
        let dv = Vector3::from(s.dv_mps);
        let mut dth_m = (self.mg * dth + self.gs * dv) * self.true_interval;
        let mut dv_m = self.ma * dv * self.true_interval;
        if let Some(p) = self.scale_gm.as_mut() {
            for (j, (g, rng)) in p.iter_mut().enumerate() {
                self.last_scale_gm[j] = g.next(rng);
            }
            let sf = self.last_scale_gm;
            for i in 0..3 {
                dv_m[i] += sf[i] * dv[i] * self.true_interval;
                dth_m[i] += sf[3 + i] * dth[i] * self.true_interval;
            }
        }
        let mut temperature_c = f64::NAN;
        if let Some(t) = &self.temperature {
            let (a, b) = (k as f64 * dt, (k + 1) as f64 * dt);
            let integ = t.integral_rel(a, b);
            for i in 0..3 {
                dv_m[i] += self.accel_temp[i] * integ;
                dth_m[i] += self.gyro_temp[i] * integ;
            }
            temperature_c = t.at(b);
            if t.report_noise_c > 0.0 {
                temperature_c += t.report_noise_c * gauss(&mut self.temp_rng);
            }
        }
        let (acc, gyr) = self.axes.split_at_mut(3);
        ImuSample {
            t_s: s.t_s,
            dtheta_rad: std::array::from_fn(|i| match gyr.get_mut(i) {
                Some(a) => a.apply(k, dth_m[i]),
                None => dth_m[i],
            }),
            dv_mps: std::array::from_fn(|i| match acc.get_mut(i) {
                Some(a) => a.apply(k, dv_m[i]),
                None => dv_m[i],
            }),
            temperature_c,
        }
    }

    /// The accelerometer bias during the last sample given to [`ImuErrors::apply`]
    /// ([`AxisErrors::bias_now`]), m/s^2.
    pub fn accel_bias_now(&self) -> [f64; 3] {
        std::array::from_fn(|i| self.axes[i].bias_now())
    }

    /// The gyro bias during the last sample ([`AxisErrors::bias_now`]), rad/s.
    pub fn gyro_bias_now(&self) -> [f64; 3] {
        std::array::from_fn(|i| self.axes[3 + i].bias_now())
    }

    /// The Gauss-Markov scale factors during the last sample (accelerometer, gyro;
    /// dimensionless, zero without [`SensorErrors::scale_factor_gm`]).
    pub fn scale_gm_now(&self) -> ([f64; 3], [f64; 3]) {
        let s = self.last_scale_gm;
        ([s[0], s[1], s[2]], [s[3], s[4], s[5]])
    }

    /// The realised random constants (fixed plus turn-on bias per axis).
    pub fn realized(&self) -> Realized {
        Realized {
            accel_bias_mps2: std::array::from_fn(|i| self.axes[i].constant_bias()),
            gyro_bias_radps: std::array::from_fn(|i| self.axes[3 + i].constant_bias()),
        }
    }
}

/// The GNSS errors of [`GnssErrors`] fix epoch by fix epoch (white and Gauss-Markov position
/// errors, white velocity errors, NED), each axis and source from its own stream of the seed:
/// what [`ErrorModel::apply_gnss`] adds to the true antenna position and velocity, for a
/// generator that makes its fixes one at a time.
#[derive(Debug, Clone)]
pub struct GnssNoise {
    white_sigma_m: [f64; 3],
    gm_sigma_m: [f64; 3],
    vel_sigma_mps: [f64; 3],
    /// `exp(-period / tau)` of the Gauss-Markov part.
    phi: f64,
    gm: [f64; 3],
    first: bool,
    white: [ChaCha8Rng; 3],
    gm_rng: [ChaCha8Rng; 3],
    vel_rng: [ChaCha8Rng; 3],
}

impl GnssNoise {
    /// The errors of `g` for `seed`, epochs `1 / g.rate_hz` s apart.
    pub fn new(g: &GnssErrors, seed: u64) -> Self {
        let period = 1.0 / g.rate_hz;
        Self {
            white_sigma_m: g.white_sigma_ned_m.0,
            gm_sigma_m: g.gm_sigma_ned_m.0,
            vel_sigma_mps: g.vel_white_sigma_ned_mps.0,
            phi: if g.gm_tau_s > 0.0 {
                (-period / g.gm_tau_s).exp()
            } else {
                0.0
            },
            gm: [0.0; 3],
            first: true,
            white: std::array::from_fn(|a| stream(seed, GNSS, SRC_WHITE, a as u64)),
            gm_rng: std::array::from_fn(|a| stream(seed, GNSS, SRC_GM, a as u64)),
            vel_rng: std::array::from_fn(|a| stream(seed, GNSS, SRC_GNSS_VEL, a as u64)),
        }
    }

    /// The position error (m) and velocity error (m/s), NED, of the next fix epoch (the
    /// Gauss-Markov part from its stationary distribution at the first epoch).
    pub fn next_epoch(&mut self) -> (Vector3<f64>, Vector3<f64>) {
        let mut err = Vector3::zeros();
        let mut verr = Vector3::zeros();
        let phi = self.phi;
        for i in 0..3 {
            let sg = self.gm_sigma_m[i];
            self.gm[i] = if self.first {
                sg * gauss(&mut self.gm_rng[i])
            } else {
                phi * self.gm[i] + sg * (1.0 - phi * phi).sqrt() * gauss(&mut self.gm_rng[i])
            };
            err[i] = self.gm[i] + self.white_sigma_m[i] * gauss(&mut self.white[i]);
            verr[i] = self.vel_sigma_mps[i] * gauss(&mut self.vel_rng[i]);
        }
        self.first = false;
        (err, verr)
    }
}
