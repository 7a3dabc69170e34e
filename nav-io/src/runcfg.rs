//! The project's own run configuration (TOML), [`RunConfig`]: which files to read and how,
//! the IMU mounting and antenna lever arm, the initial state or alignment, and the IMU noise
//! model in the source document's terms (S_N, S_B, T_B, S_K, initial sigmas).
//!
//! Paths: relative paths are relative to the folder of the configuration file
//! ([`RunConfig::resolve`]); `configs/drive0708.toml` therefore names the shared data as
//! `../../shared/data/...` (configs/ -> repository -> its parent, where `shared/` lives).
//!
//! The `[noise]` section and its keys (SI or datasheet units, one value or one per axis) are
//! documented in [`super::noisecfg`].

mod keys;

use super::gnsscsv::GnssCsvFormat;
use super::gnsslog::GnssLogOptions;
use super::imucsv::ImuCsvFormat;
use super::mount::Mounting;
pub use super::noisecfg::{
    AccelNoiseConfig, AxisValue, BiasModel, GyroNoiseConfig, NoiseConfig, ScaleNoiseConfig,
};
use super::pos::{read_rtklib_pos, PosOptions};
use super::text::{read_nav_text, ImuRecord};
use super::IoError;
use nav_core::config::GnssErrorNoise;
use nav_core::types::{GnssFix, NavSolution};
use std::path::{Path, PathBuf};

/// IMU file kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImuFileKind {
    /// The project's IMU text format (increments, KF-GINS layout).
    Text,
    /// A generic CSV log of rates and specific forces, mapped by `[imu.csv]`.
    Csv,
}

/// Where the IMU data come from and how to read them.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImuSource {
    /// IMU file (relative to the configuration file's folder).
    pub path: PathBuf,
    /// File kind.
    pub format: ImuFileKind,
    /// Column/unit mapping, required for `format = "csv"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub csv: Option<ImuCsvFormat>,
    /// Mounting rotation from IMU to body axes (default identity).
    #[serde(default)]
    pub mounting: Mounting,
    /// Constant added to the IMU time stamps after reading, s (for CSV logs in addition to
    /// the mapping's own `time_offset_s`).
    #[serde(default)]
    pub time_offset_s: f64,
    /// Physical plausibility limits and gap handling (default: consumer-MEMS ranges).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checks: Option<ImuChecksConfig>,
}

/// Sensor class names of `[imu.checks] class` (see `nav_core::imu_guard::ImuClass`); the same
/// kebab-case names in TOML, `FromStr`/`Display` and `strum::VariantNames::VARIANTS`.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    serde::Serialize,
    serde::Deserialize,
    strum::Display,
    strum::EnumString,
    strum::VariantNames,
)]
#[serde(rename_all = "kebab-case")]
#[strum(serialize_all = "kebab-case")]
pub enum ImuClassName {
    /// Consumer / automotive MEMS: 4000 deg/s, 32 g.
    ConsumerMems,
    /// Industrial MEMS: 2000 deg/s, 40 g.
    Industrial,
    /// Tactical grade: 1000 deg/s, 40 g.
    Tactical,
    /// Navigation grade: 500 deg/s, 30 g.
    Navigation,
}

impl ImuClassName {
    /// The nav-core class.
    pub fn class(self) -> nav_core::imu_guard::ImuClass {
        use nav_core::imu_guard::ImuClass;
        match self {
            Self::ConsumerMems => ImuClass::ConsumerMems,
            Self::Industrial => ImuClass::Industrial,
            Self::Tactical => ImuClass::Tactical,
            Self::Navigation => ImuClass::Navigation,
        }
    }
}

/// `[imu.checks]`: IMU plausibility limits and gap handling (`host-sim run`).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImuChecksConfig {
    /// Sensor class giving the default limits (its full-scale range + 10 %).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub class: Option<ImuClassName>,
    /// Largest plausible angular rate on any axis, deg/s (overrides the class).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_rate_deg_s: Option<f64>,
    /// Largest plausible specific force on any axis, g = 9.80665 m/s^2 (overrides the class).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_accel_g: Option<f64>,
    /// Longest time gap bridged, s (default 1; longer ends the run with an error).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_gap_s: Option<f64>,
    /// Stop the run at the first implausible sample instead of skipping it.
    #[serde(default)]
    pub stop_on_implausible: bool,
}

/// GNSS file kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GnssFileKind {
    /// The project's GNSS text format.
    Text,
    /// An RTKLIB `.pos` solution file.
    RtklibPos,
    /// A generic CSV/text log, mapped by `[gnss.csv]`.
    Csv,
    /// An NMEA 0183 log (GGA, RMC, GST, VTG), options in `[gnss.log]`.
    Nmea,
    /// A u-blox UBX log (NAV-PVT), options in `[gnss.log]`.
    Ubx,
}

fn default_max_q() -> u8 {
    6
}

/// Factors on a GNSS file's standard deviations (`[gnss] sigma_scale`): `horizontal` on the
/// north and east position and velocity sigmas, `vertical` on the down ones (dimensionless;
/// 1 = as given). In TOML either one number for both (`sigma_scale = 10.0`) or a table
/// (`sigma_scale = { horizontal = 10.0, vertical = 4.0 }`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(from = "SigmaScaleToml", into = "SigmaScaleToml")]
pub struct SigmaScale {
    /// Factor on the north and east standard deviations (position and velocity).
    pub horizontal: f64,
    /// Factor on the down standard deviations (position and velocity).
    pub vertical: f64,
}

/// The two ways to write [`SigmaScale`] in TOML.
#[derive(serde::Serialize, serde::Deserialize)]
#[serde(untagged)]
enum SigmaScaleToml {
    Both(f64),
    Split { horizontal: f64, vertical: f64 },
}

impl From<SigmaScaleToml> for SigmaScale {
    fn from(t: SigmaScaleToml) -> Self {
        match t {
            SigmaScaleToml::Both(k) => Self::both(k),
            SigmaScaleToml::Split {
                horizontal,
                vertical,
            } => Self {
                horizontal,
                vertical,
            },
        }
    }
}

impl From<SigmaScale> for SigmaScaleToml {
    fn from(s: SigmaScale) -> Self {
        if s.horizontal == s.vertical {
            Self::Both(s.horizontal)
        } else {
            Self::Split {
                horizontal: s.horizontal,
                vertical: s.vertical,
            }
        }
    }
}

impl Default for SigmaScale {
    /// The file's sigmas as given ([`Self::ONE`]).
    fn default() -> Self {
        Self::ONE
    }
}

impl SigmaScale {
    /// The file's sigmas as given.
    pub const ONE: Self = Self {
        horizontal: 1.0,
        vertical: 1.0,
    };

    /// The same factor on all three axes.
    pub const fn both(k: f64) -> Self {
        Self {
            horizontal: k,
            vertical: k,
        }
    }

    /// Whether both factors are finite and > 0.
    pub fn is_valid(&self) -> bool {
        [self.horizontal, self.vertical]
            .iter()
            .all(|k| k.is_finite() && *k > 0.0)
    }

    /// Multiplies a fix's position and velocity standard deviations: north and east by
    /// `horizontal`, down by `vertical`. The one place the configured scale is applied.
    pub fn apply(&self, g: &mut GnssFix) {
        let k = [self.horizontal, self.horizontal, self.vertical];
        for (s, k) in g.pos_std_ned_m.iter_mut().zip(k) {
            *s *= k;
        }
        for (s, k) in g.vel_std_ned_mps.iter_mut().zip(k) {
            *s *= k;
        }
    }
}

/// The prior of the GNSS error state (`[gnss] error_state`): the first-order Gauss-Markov
/// antenna-position error of the `gnss_position_gm` effect, used when that effect is in the
/// model. In TOML `error_state = { sigma_m = [0.08, 0.08, 0.16], correlation_time_s = 120.0 }`.
/// Absent: the filter's default (0.5, 0.5, 1.0 m; 300 s).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GnssErrorPrior {
    /// Stationary (and initial) 1-sigma per NED axis (north, east, down), m; each > 0.
    pub sigma_m: [f64; 3],
    /// Correlation time, s; > 0.
    pub correlation_time_s: f64,
}

impl GnssErrorPrior {
    /// Whether every sigma and the correlation time are finite and > 0.
    pub fn is_valid(&self) -> bool {
        self.sigma_m
            .iter()
            .chain(core::iter::once(&self.correlation_time_s))
            .all(|v| v.is_finite() && *v > 0.0)
    }

    /// The prior as the filter's effect configuration.
    pub fn noise(&self) -> GnssErrorNoise {
        GnssErrorNoise {
            sigma_m: self.sigma_m,
            t_s: self.correlation_time_s,
        }
    }
}

impl From<GnssErrorNoise> for GnssErrorPrior {
    fn from(n: GnssErrorNoise) -> Self {
        Self {
            sigma_m: n.sigma_m,
            correlation_time_s: n.t_s,
        }
    }
}

/// Where the GNSS fixes come from and how to use them.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GnssSource {
    /// GNSS file (relative to the configuration file's folder).
    pub path: PathBuf,
    /// File kind.
    pub format: GnssFileKind,
    /// Column/time/quality mapping, required for `format = "csv"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub csv: Option<GnssCsvFormat>,
    /// Options of `format = "nmea"` / `"ubx"` (sigmas when absent, leap seconds, strictness).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub log: Option<GnssLogOptions>,
    /// Keep RTKLIB records with quality 1 <= Q <= max_q (1 fixed .. 6 PPP); default 6.
    #[serde(default = "default_max_q")]
    pub max_q: u8,
    /// GNSS antenna phase centre relative to the IMU, body FRD axes, m (KF-GINS `antlever`).
    #[serde(default)]
    pub lever_arm_m: [f64; 3],
    /// Constant added to the GNSS time stamps, s.
    #[serde(default)]
    pub time_offset_s: f64,
    /// Use the GNSS velocities when the file has them.
    #[serde(default)]
    pub use_velocity: bool,
    /// Factors applied to the file's standard deviations (1 = as given): one number for all
    /// axes, or `{ horizontal = .., vertical = .. }` ([`SigmaScale`]).
    #[serde(default)]
    pub sigma_scale: SigmaScale,
    /// Prior of the GNSS error state of the `gnss_position_gm` effect ([`GnssErrorPrior`]:
    /// per-axis sigma in m, correlation time in s); absent: the filter's default.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error_state: Option<GnssErrorPrior>,
    /// Innovation gate of the filter: "off", or the acceptance probability "0.95", "0.99",
    /// "0.999", "0.9999" (default: the filter's, 0.9999).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gate: Option<String>,
    /// The GNSS velocity's own gate (with `use_velocity`): "joint" (default: position and
    /// velocity in one update under `gate`), or a separate velocity update gated "robust"
    /// (IGG-III down-weighting from the 0.99 chi-square quantile, rejection beyond 0.9999),
    /// "hard" (rejection beyond 0.9999, or a probability "0.95", "0.99", "0.999", "0.9999")
    /// or "off" (no gate).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity_gate: Option<String>,
}

/// Reference trajectory file kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TruthFileKind {
    /// The navigation text format (`week sow lat lon h vn ve vd roll pitch yaw`).
    NavText,
    /// An RTKLIB `.pos` file (positions only).
    RtklibPos,
}

/// An optional reference trajectory.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TruthSource {
    /// Truth file (relative to the configuration file's folder).
    pub path: PathBuf,
    /// File kind.
    pub format: TruthFileKind,
}

/// A given initial state (as in KF-GINS): `[init.given]`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GivenState {
    /// Latitude deg, longitude deg, ellipsoidal height m (of the IMU).
    pub pos_deg_deg_m: [f64; 3],
    /// NED velocity, m/s.
    pub vel_ned_mps: [f64; 3],
    /// Roll, pitch, yaw (ZYX, body FRD relative to NED), deg.
    pub rpy_deg: [f64; 3],
}

/// Alignment from the data: `[init.align]`. Position and velocity from the first usable GNSS
/// fix; roll and pitch by accelerometer levelling over the first `static_s` seconds (the
/// vehicle must be at rest); yaw given, or from the GNSS velocity once the speed exceeds
/// `yaw_from_gnss_min_speed_mps`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AlignSpec {
    /// Length of the static window at the start, s (default [`DEFAULT_STATIC_S`]; ignored
    /// when the GNSS speed at the start gives an in-motion alignment).
    #[serde(default = "default_static_s")]
    pub static_s: f64,
    /// Known initial yaw, deg (None: from the GNSS course over ground).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub yaw_deg: Option<f64>,
    /// Speed above which the GNSS course gives the yaw, m/s.
    #[serde(default = "half")]
    pub yaw_from_gnss_min_speed_mps: f64,
    /// Largest accepted | |mean f| - normal gravity | during the static window, m/s^2
    /// (accelerometer bias and scale-factor error; consumer MEMS need ~0.2).
    #[serde(default = "default_gravity_mismatch")]
    pub max_gravity_mismatch_mps2: f64,
}

fn default_gravity_mismatch() -> f64 {
    0.1
}

/// Static window of the default alignment, s (`[init.align] static_s` when not given).
pub const DEFAULT_STATIC_S: f64 = 5.0;

fn default_static_s() -> f64 {
    DEFAULT_STATIC_S
}

/// The alignment used when `[init]` names neither `[init.given]` nor `[init.align]`: levelling
/// over the first [`DEFAULT_STATIC_S`] s when the vehicle is at rest there, an in-motion
/// alignment when the GNSS speed at the start is high enough (the engine chooses from the
/// data); yaw from the GNSS course.
pub const DEFAULT_ALIGN: AlignSpec = AlignSpec {
    static_s: DEFAULT_STATIC_S,
    yaw_deg: None,
    yaw_from_gnss_min_speed_mps: 0.5,
    max_gravity_mismatch_mps2: 0.1,
};

impl Default for AlignSpec {
    /// [`DEFAULT_ALIGN`].
    fn default() -> Self {
        DEFAULT_ALIGN
    }
}

/// How the initial state is obtained.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InitMode<'a> {
    /// A given state.
    Given(&'a GivenState),
    /// Alignment from the data.
    Align(&'a AlignSpec),
}

fn half() -> f64 {
    0.5
}

/// Initial state and its uncertainty (`[init]`, optional: every key has a default, and
/// without `[init.given]` or `[init.align]` the run aligns from the data, [`DEFAULT_ALIGN`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitConfig {
    /// Initial position 1-sigma north, east, down, m (default 1, 1, 2).
    #[serde(default = "default_pos_std")]
    pub pos_std_m: [f64; 3],
    /// Initial velocity 1-sigma north, east, down, m/s (default 0.1 each).
    #[serde(default = "default_vel_std")]
    pub vel_std_mps: [f64; 3],
    /// Initial attitude 1-sigma roll, pitch, yaw, deg (default 2, 2, 10).
    #[serde(default = "default_att_std")]
    pub att_std_deg: [f64; 3],
    /// A given initial state (at most one of `given` and `align`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub given: Option<GivenState>,
    /// Alignment from the data (at most one of `given` and `align`; neither:
    /// [`DEFAULT_ALIGN`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub align: Option<AlignSpec>,
}

fn default_pos_std() -> [f64; 3] {
    [1.0, 1.0, 2.0]
}

fn default_vel_std() -> [f64; 3] {
    [0.1; 3]
}

fn default_att_std() -> [f64; 3] {
    [2.0, 2.0, 10.0]
}

impl Default for InitConfig {
    /// The defaults of every key: alignment from the data ([`DEFAULT_ALIGN`]).
    fn default() -> Self {
        Self {
            pos_std_m: default_pos_std(),
            vel_std_mps: default_vel_std(),
            att_std_deg: default_att_std(),
            given: None,
            align: None,
        }
    }
}

impl InitConfig {
    /// Which initialisation is configured: the given state, the configured alignment, or
    /// [`DEFAULT_ALIGN`] when neither is (an error when both are).
    pub fn mode(&self) -> Result<InitMode<'_>, String> {
        match (&self.given, &self.align) {
            (Some(g), None) => Ok(InitMode::Given(g)),
            (None, Some(a)) => Ok(InitMode::Align(a)),
            (None, None) => Ok(InitMode::Align(&DEFAULT_ALIGN)),
            (Some(_), Some(_)) => {
                Err("init: give at most one of [init.given] and [init.align]".into())
            }
        }
    }
}

/// A run of the navigation filter on recorded (or simulated) files.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunConfig {
    /// Short name of the case (used in reports).
    #[serde(default)]
    pub name: String,
    /// Free text: where the data come from, what is known about them.
    #[serde(default)]
    pub description: String,
    /// Processing start, s (same time scale as the files; None: first IMU sample).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_s: Option<f64>,
    /// Processing end, s (None: last IMU sample).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub end_s: Option<f64>,
    /// IMU input.
    pub imu: ImuSource,
    /// GNSS input.
    pub gnss: GnssSource,
    /// Optional reference trajectory.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truth: Option<TruthSource>,
    /// Initial state (optional: [`InitConfig::default`]).
    #[serde(default)]
    pub init: InitConfig,
    /// IMU noise model.
    pub noise: NoiseConfig,
    /// Effect blocks appended to the error-state model, by their vocabulary names
    /// (`accel_scale_factor`, `gyro_scale_factor`, `accel_misalignment`, `gyro_misalignment`,
    /// `lever_arm`, `time_offset`, `accel_temperature_bias`, `gyro_temperature_bias`,
    /// `gyro_g_sensitivity`, `imu_clock_drift`, `gnss_position_gm`), e.g. as written by `host-sim diagnose` into `augmented.toml`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub effects: Vec<String>,
    /// Land-vehicle aiding (`[aiding]`, see [`super::aidingcfg`]); absent: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aiding: Option<super::aidingcfg::AidingSection>,
}

impl RunConfig {
    /// A path of the configuration resolved against the configuration file's folder.
    pub fn resolve(config_dir: &Path, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            config_dir.join(p)
        }
    }

    /// Checks what serde cannot: CSV mapping present for CSV input, finite angles and
    /// offsets, non-negative sigmas, consistent noise keys, `1 <= max_q <= 6`.
    pub fn validate(&self) -> Result<(), String> {
        let bad: Vec<String> = self.problems().into_iter().map(|(_, _, msg)| msg).collect();
        if bad.is_empty() {
            Ok(())
        } else {
            Err(bad.join("; "))
        }
    }

    /// What [`RunConfig::validate`] finds, each with the table and key it is about (for the
    /// error to name their line; key "" for the table as a whole).
    pub fn problems(&self) -> Vec<(&'static str, &'static str, String)> {
        let mut bad: Vec<(&'static str, &'static str, String)> = self
            .located_problems()
            .into_iter()
            .map(|(table, key, msg)| (table, "", format!("{}{key}: {msg}", dotted(table))))
            .collect();
        let mut push = |table: &'static str, key: &'static str, msg: String| {
            bad.push((table, key, msg));
        };
        self.input_problems(&mut push);
        self.init_problems(&mut push);
        if let (Some(a), Some(b)) = (self.start_s, self.end_s) {
            if b.partial_cmp(&a) != Some(std::cmp::Ordering::Greater) {
                push("", "end_s", format!("end_s {b} must be after start_s {a}"));
            }
        }
        for p in self.noise.problems() {
            push("noise", "", p);
        }
        bad
    }

    /// The problems of the IMU and GNSS inputs' settings (formats and their mappings, the
    /// mounting, time offsets, fix quality, lever arm, sigma scale, GNSS error state prior), handed to `push` as
    /// (table, key, message).
    fn input_problems(&self, push: &mut impl FnMut(&'static str, &'static str, String)) {
        if self.imu.format == ImuFileKind::Csv && self.imu.csv.is_none() {
            push(
                "imu",
                "format",
                "imu.format = \"csv\" needs an [imu.csv] mapping".into(),
            );
        }
        if (self.gnss.format == GnssFileKind::Csv) != self.gnss.csv.is_some() {
            push(
                "gnss",
                "format",
                "gnss.format = \"csv\" and a [gnss.csv] mapping go together".into(),
            );
        }
        if self.gnss.log.is_some()
            && !matches!(self.gnss.format, GnssFileKind::Nmea | GnssFileKind::Ubx)
        {
            push(
                "gnss.log",
                "",
                "[gnss.log] goes with gnss.format = \"nmea\" or \"ubx\"".into(),
            );
        }
        if !self.imu.mounting.is_finite() {
            push(
                "imu.mounting",
                "",
                "imu.mounting angles must be finite".into(),
            );
        }
        if !self.imu.time_offset_s.is_finite() {
            push(
                "imu",
                "time_offset_s",
                "imu.time_offset_s must be finite".into(),
            );
        }
        if !self.gnss.time_offset_s.is_finite() {
            push(
                "gnss",
                "time_offset_s",
                "gnss.time_offset_s must be finite".into(),
            );
        }
        if !(1..=6).contains(&self.gnss.max_q) {
            push(
                "gnss",
                "max_q",
                format!("gnss.max_q must be in 1..=6, got {}", self.gnss.max_q),
            );
        }
        if !self.gnss.lever_arm_m.iter().all(|v| v.is_finite()) {
            push(
                "gnss",
                "lever_arm_m",
                "gnss.lever_arm_m must be finite".into(),
            );
        }
        if !self.gnss.sigma_scale.is_valid() {
            push(
                "gnss",
                "sigma_scale",
                "gnss.sigma_scale must be > 0 (horizontal and vertical)".into(),
            );
        }
        if self.gnss.error_state.is_some_and(|e| !e.is_valid()) {
            push(
                "gnss",
                "error_state",
                "gnss.error_state: sigma_m and correlation_time_s must be finite and > 0".into(),
            );
        }
    }

    /// The problems of the `[init]` table (the initial sigmas, the given state or the
    /// alignment settings), handed to `push` as (table, key, message).
    fn init_problems(&self, push: &mut impl FnMut(&'static str, &'static str, String)) {
        let sig_ok = |v: &[f64; 3]| v.iter().all(|x| x.is_finite() && *x >= 0.0);
        for (key, v) in [
            ("pos_std_m", &self.init.pos_std_m),
            ("vel_std_mps", &self.init.vel_std_mps),
            ("att_std_deg", &self.init.att_std_deg),
        ] {
            if !sig_ok(v) {
                push(
                    "init",
                    key,
                    format!("init.{key}: sigmas must be finite and >= 0"),
                );
            }
        }
        match self.init.mode() {
            Err(e) => push("init", "", e),
            Ok(InitMode::Given(g)) => {
                let mut all = g
                    .pos_deg_deg_m
                    .iter()
                    .chain(&g.vel_ned_mps)
                    .chain(&g.rpy_deg);
                if !all.all(|v| v.is_finite()) || g.pos_deg_deg_m[0].abs() > 90.0 {
                    push(
                        "init.given",
                        "",
                        "init.given: state must be finite with |lat| <= 90 deg".into(),
                    );
                }
            }
            Ok(InitMode::Align(a)) => {
                if !(a.static_s.is_finite() && a.static_s > 0.0) {
                    push(
                        "init.align",
                        "static_s",
                        "init.align.static_s must be > 0".into(),
                    );
                }
                if a.yaw_deg.is_some_and(|y| !y.is_finite())
                    || !a.yaw_from_gnss_min_speed_mps.is_finite()
                    || !(a.max_gravity_mismatch_mps2.is_finite()
                        && a.max_gravity_mismatch_mps2 > 0.0)
                {
                    push("init.align", "", "init.align: yaw_deg, yaw_from_gnss_min_speed_mps must be finite, max_gravity_mismatch_mps2 > 0".into());
                }
            }
        }
    }
}

fn dotted(table: &str) -> String {
    if table.is_empty() {
        String::new()
    } else {
        format!("{table}.")
    }
}

impl RunConfig {
    /// Problems tied to one key, as (table, key, message): noise values that are not finite,
    /// negative (the TOML keys are densities or sigmas that are squared: a sign would vanish
    /// silently), or zero where zero is meaningless (white noise, correlation time); effect
    /// names that are not effects.
    pub fn located_problems(&self) -> Vec<(&'static str, String, String)> {
        let mut out = self.noise.located_problems();
        let lever = self.gnss.lever_arm_m;
        let norm = lever.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm.is_nan() || norm > MAX_LEVER_ARM_M {
            out.push((
                "gnss",
                "lever_arm_m".to_string(),
                format!(
                    "{lever:?} is {norm} m long; a lever arm must be finite and at most {MAX_LEVER_ARM_M} m"
                ),
            ));
        }
        for (table, v) in [
            ("imu", self.imu.time_offset_s),
            ("gnss", self.gnss.time_offset_s),
        ] {
            if v.is_nan() || v.abs() > MAX_TIME_OFFSET_S {
                out.push((
                    table,
                    "time_offset_s".to_string(),
                    format!("{v} s is outside [-{MAX_TIME_OFFSET_S}, {MAX_TIME_OFFSET_S}] s"),
                ));
            }
        }
        if let Some(l) = self.gnss.log.as_ref().and_then(|l| l.leap_seconds) {
            if let Err(e) = check_leap_seconds(l) {
                out.push(("gnss.log", "leap_seconds".to_string(), e));
            }
        }
        for name in &self.effects {
            if nav_core::model::Block::effect_from_name(name.trim()).is_none() {
                let known: Vec<&str> = nav_core::model::EFFECT_BLOCKS
                    .iter()
                    .map(|b| b.name())
                    .collect();
                out.push((
                    "",
                    "effects".to_string(),
                    format!(
                        "{name:?} is not an effect name; known: {}",
                        known.join(", ")
                    ),
                ));
            }
        }
        out
    }
}

/// The 1-based line of `key` in the TOML table `table` ("" = top level) of `text`, when it is
/// written there as `key = ...` (dotted keys and inline tables are not followed).
pub fn key_line(text: &str, table: &str, key: &str) -> Option<usize> {
    let mut cur = String::new();
    for (i, raw) in text.lines().enumerate() {
        let l = raw.trim();
        if let Some(h) = l.strip_prefix('[') {
            let h = h.trim_start_matches('[');
            cur = h
                .split(']')
                .next()
                .unwrap_or("")
                .split('.')
                .map(|p| p.trim().trim_matches('"'))
                .collect::<Vec<_>>()
                .join(".");
            continue;
        }
        if cur == table {
            if let Some(rest) = l.strip_prefix(key) {
                if rest.trim_start().starts_with('=') {
                    return Some(i + 1);
                }
            }
        }
    }
    None
}

/// The 1-based line of the header `[table]` of `text` (None for the top level or a table
/// not written as a header).
pub fn table_line(text: &str, table: &str) -> Option<usize> {
    if table.is_empty() {
        return None;
    }
    text.lines()
        .position(|raw| {
            raw.trim()
                .strip_prefix('[')
                .map(|h| h.trim_start_matches('['))
                .and_then(|h| h.split(']').next())
                .is_some_and(|h| {
                    h.split('.')
                        .map(|p| p.trim().trim_matches('"'))
                        .collect::<Vec<_>>()
                        .join(".")
                        == table
                })
        })
        .map(|i| i + 1)
}

/// Longest GNSS lever arm accepted (`[gnss] lever_arm_m`), m: an antenna further than this from
/// the IMU is a unit or sign mistake.
pub const MAX_LEVER_ARM_M: f64 = 100.0;

/// Largest time offset accepted (`[imu] time_offset_s`, `[gnss] time_offset_s`, `host-sim run
/// --imu-time-offset`), s, either sign: a logging delay or a time-scale slip (GPS - UTC is
/// 18 s) is well inside it; beyond it the data do not overlap the way the offset means.
pub const MAX_TIME_OFFSET_S: f64 = 60.0;

/// Checks a GPS - UTC leap-second count against the leap-second table's range (0 before
/// 1981-07-01 up to the table's last value): `Err` names the range.
pub fn check_leap_seconds(l: i64) -> Result<(), String> {
    let max = i64::from(crate::gpstime::MAX_GPST_MINUS_UTC_S);
    if (0..=max).contains(&l) {
        Ok(())
    } else {
        Err(format!(
            "{l} s is outside the leap-second table's range [0, {max}] s (GPS - UTC)"
        ))
    }
}

/// For a TOML error about an unknown key or value (`unknown field `X`, expected one of `a`,
/// `b`` or `unknown variant ...`), "did you mean `a`?" naming the valid name nearest to `X` by
/// edit distance, when it is near enough to be a misspelling (at most a third of its length
/// edited, at least 2 edits allowed).
pub fn nearest_name_hint(message: &str) -> Option<String> {
    let (_, rest) = message
        .split_once("unknown field `")
        .or_else(|| message.split_once("unknown variant `"))?;
    let (bad, rest) = rest.split_once('`')?;
    let (_, list) = rest.split_once("expected")?;
    let list = list.lines().next().unwrap_or("");
    did_you_mean(bad, list.split('`').skip(1).step_by(2))
}

/// "did you mean `a`?" naming the candidate nearest to `bad` by edit distance, when it is
/// near enough to be a misspelling (at most a third of its length edited, at least 2 edits
/// allowed); `None` otherwise.
pub fn did_you_mean<'a>(
    bad: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> Option<String> {
    let best = candidates
        .into_iter()
        .map(|cand| (strsim::levenshtein(bad, cand), cand))
        .min()?;
    let allowed = (bad.chars().count() / 3).max(2);
    (best.0 <= allowed).then(|| format!("did you mean `{}`?", best.1))
}

/// The tables a run configuration must have, with what each holds.
const REQUIRED_TABLES: [(&str, &str); 3] = [
    ("imu", "the IMU input"),
    ("gnss", "the GNSS input"),
    ("noise", "the IMU noise model"),
];

/// The message of a required table absent from `text` when the parser's error (`message`,
/// without its position: the parser places a missing table at the start of the file) is
/// that; `None` otherwise.
fn missing_table(message: &str, text: &str) -> Option<String> {
    let field = message.strip_prefix("missing field `")?.split('`').next()?;
    if !REQUIRED_TABLES.iter().any(|(name, _)| *name == field) {
        return None;
    }
    let table: toml::Table = text.parse().ok()?;
    let missing: Vec<String> = REQUIRED_TABLES
        .iter()
        .filter(|(name, _)| !table.contains_key(*name))
        .map(|(name, what)| format!("[{name}] ({what})"))
        .collect();
    (!missing.is_empty()).then(|| {
        format!(
            "missing table{} {}: `host-sim init` writes a complete configuration, every key is \
             in docs/your-data.md",
            if missing.len() > 1 { "s" } else { "" },
            missing.join(", ")
        )
    })
}

/// Parses and validates a run configuration from TOML text (`name` is used in errors).
pub fn parse_run_config(name: &Path, text: &str) -> Result<RunConfig, IoError> {
    let cfg: RunConfig = toml::from_str(text).map_err(|e| {
        // a missing table: named, without the parser's message (its position is the file's
        // start, not where anything is wrong)
        if let Some(message) = missing_table(e.message(), text) {
            return IoError::Config {
                path: name.to_path_buf(),
                message,
                source: None,
            };
        }
        let mut message = e.to_string();
        // a key of another table: that table named (before any near misspelling)
        let at = e.span().map(|s| s.start);
        let hint =
            keys::wrong_table_hint(e.message(), text, at).or_else(|| nearest_name_hint(&message));
        if let Some(hint) = hint {
            message = format!("{}; {hint}", message.trim_end());
        }
        IoError::Config {
            path: name.to_path_buf(),
            message,
            source: Some(Box::new(e)),
        }
    })?;
    let located = cfg.located_problems();
    if !located.is_empty() {
        let message = located
            .iter()
            .map(|(table, key, msg)| match key_line(text, table, key) {
                Some(l) => format!("line {l}: {}{key}: {msg}", dotted(table)),
                None => format!("{}{key}: {msg}", dotted(table)),
            })
            .collect::<Vec<_>>()
            .join("; ");
        return Err(IoError::Config {
            path: name.to_path_buf(),
            message,
            source: None,
        });
    }
    let problems = cfg.problems();
    if !problems.is_empty() {
        let message = problems
            .iter()
            .map(|(table, key, msg)| {
                match key_line(text, table, key).or_else(|| table_line(text, table)) {
                    Some(l) => format!("line {l}: {msg}"),
                    None => msg.clone(),
                }
            })
            .collect::<Vec<_>>()
            .join("; ");
        return Err(IoError::Config {
            path: name.to_path_buf(),
            message,
            source: None,
        });
    }
    if let Some(a) = &cfg.aiding {
        if let Err(message) = a.to_config() {
            // name the line of the offending key (the error names `table.key`)
            let key = message
                .strip_prefix("aiding: ")
                .and_then(|m| m.split_whitespace().next())
                .unwrap_or("");
            let (table, k) = match key.rsplit_once('.') {
                Some((t, k)) => (format!("aiding.{t}"), k),
                None => ("aiding".to_string(), key),
            };
            let line = super::aidingcfg::line_of_key(text, &table, k)
                .or_else(|| super::aidingcfg::line_of_key(text, "aiding", ""));
            let at = line.map(|l| format!("line {l}: ")).unwrap_or_default();
            return Err(IoError::Config {
                path: name.to_path_buf(),
                message: format!("{at}[{table}] {message}"),
                source: None,
            });
        }
    }
    Ok(cfg)
}

/// Largest configuration file read (TOML or KF-GINS YAML), bytes: a configuration is a few
/// kB; a larger file (a data file or an image given as `--config`) is refused before it is
/// read, never held in memory nor echoed in a parse error.
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;

/// The text of the configuration file `path`: at most [`MAX_CONFIG_BYTES`], UTF-8, without
/// NUL bytes (else an error naming the file and the cause).
pub(crate) fn read_config_text(path: &Path) -> Result<String, IoError> {
    use std::io::Read as _;
    let open = |source| IoError::Open {
        path: path.to_path_buf(),
        source,
    };
    let f = std::fs::File::open(path).map_err(open)?;
    let format = |message: String| IoError::Format {
        path: path.to_path_buf(),
        line: 0,
        message,
    };
    let too_big = |n: u64| {
        format(format!(
            "{n} bytes or more: not a configuration (at most {MAX_CONFIG_BYTES} bytes are read); \
             is it a data file given as the configuration?"
        ))
    };
    let len = f.metadata().map_err(open)?.len();
    if len > MAX_CONFIG_BYTES {
        return Err(too_big(len));
    }
    let mut bytes = Vec::new();
    f.take(MAX_CONFIG_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|source| IoError::Read {
            path: path.to_path_buf(),
            line: 0,
            source,
        })?;
    if bytes.len() as u64 > MAX_CONFIG_BYTES {
        return Err(too_big(bytes.len() as u64));
    }
    if let Some(at) = bytes.iter().position(|b| *b == 0) {
        return Err(format(format!(
            "a NUL byte at byte {at}: not a text configuration"
        )));
    }
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let line = e.as_bytes()[..at].iter().filter(|b| **b == b'\n').count() + 1;
        IoError::NotText {
            path: path.to_path_buf(),
            line,
        }
    })
}

/// Reads and validates a run configuration file (at most [`MAX_CONFIG_BYTES`]).
pub fn read_run_config(path: impl AsRef<Path>) -> Result<RunConfig, IoError> {
    let path = path.as_ref();
    let text = read_config_text(path)?;
    // a UTF-8 byte-order mark (written by some Windows editors) is not TOML
    parse_run_config(path, text.strip_prefix('\u{feff}').unwrap_or(&text))
}

/// Writes a run configuration as TOML.
pub fn write_run_config(path: impl AsRef<Path>, cfg: &RunConfig) -> Result<(), IoError> {
    let path = path.as_ref();
    let text = toml::to_string_pretty(cfg).map_err(|e| IoError::Config {
        path: path.to_path_buf(),
        message: e.to_string(),
        source: Some(Box::new(e)),
    })?;
    super::text::write_with(path, |w| w.write_all(text.as_bytes()))
}

/// Reference trajectory as read.
#[derive(Debug, Clone, PartialEq)]
pub enum TruthData {
    /// Full navigation solutions (nav text).
    Nav(Vec<NavSolution>),
    /// Positions only (RTKLIB .pos, all qualities kept).
    Positions(Vec<GnssFix>),
}

/// The data a run needs, read as a [`RunConfig`] says.
#[derive(Debug, Clone, PartialEq)]
pub struct RunInputs {
    /// IMU increments in BODY axes (mounting applied), time offsets applied; the gap report
    /// of the file.
    pub imu: ImuRecord,
    /// GNSS fixes after the quality filter, time offset applied (standard deviations and
    /// velocities as in the file: `sigma_scale` and `use_velocity` are for the filter).
    pub gnss: Vec<GnssFix>,
    /// GPS week of the GNSS times when the file states it (RTKLIB .pos, CSV with a week or an
    /// absolute time, NMEA with its RMC date, UBX NAV-PVT with a valid UTC date).
    pub gnss_week: Option<i64>,
    /// GNSS records dropped by the quality filter.
    pub gnss_dropped_by_quality: usize,
    /// Things the readers want the user to know, each once (e.g. default GNSS sigmas used).
    pub warnings: Vec<String>,
    /// Reference trajectory, when configured.
    pub truth: Option<TruthData>,
}

/// The IMU file of a run configuration read one sample at a time ([`RunConfig::open_imu`]):
/// increments in BODY axes (the `[imu.mounting]` rotation applied), every time offset applied
/// (the CSV mapping's and `[imu] time_offset_s`), each with its 1-based file line. Memory is
/// that of the underlying reader ([`ImuTextReader`](super::text::ImuTextReader) or
/// [`ImuCsvIncrements`](super::imucsv::ImuCsvIncrements)): constant.
pub struct ImuFileReader {
    inner: ImuFileInner,
    path: PathBuf,
    c_imu_b: Option<nalgebra::Matrix3<f64>>,
    offset_s: f64,
}

// both readers boxed: each is large, and their sizes differ (clippy::large_enum_variant)
enum ImuFileInner {
    Text(Box<super::text::ImuTextReader>),
    Csv(Box<super::imucsv::ImuCsvIncrements>),
}

impl ImuFileReader {
    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// True when each increment covers the whole interval since the previous one even across
    /// a time gap (CSV rates converted over the true interval); false for increment files,
    /// where a gap may have lost increments (see `ImuOrigin::increments_span_gaps`).
    pub fn increments_span_gaps(&self) -> bool {
        matches!(self.inner, ImuFileInner::Csv(_))
    }
}

impl Iterator for ImuFileReader {
    type Item = Result<(nav_core::types::ImuSample, usize), IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        let r = match &mut self.inner {
            ImuFileInner::Text(rd) => rd.next()?,
            ImuFileInner::Csv(rd) => rd.next()?,
        };
        Some(r.map(|(mut s, line)| {
            if let Some(c) = &self.c_imu_b {
                let a = c * nalgebra::Vector3::from(s.dtheta_rad);
                let v = c * nalgebra::Vector3::from(s.dv_mps);
                s.dtheta_rad = [a.x, a.y, a.z];
                s.dv_mps = [v.x, v.y, v.z];
            }
            s.t_s += self.offset_s;
            (s, line)
        }))
    }
}

/// What a [`GnssFixReader`] learnt of its file besides the fixes: complete once the reader
/// has returned `None` (before that, what was seen so far).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GnssReadSummary {
    /// GPS week of the GNSS times when the file states it (RTKLIB .pos, CSV with a week or an
    /// absolute time, NMEA with its RMC date, UBX NAV-PVT with a valid UTC date).
    pub week: Option<i64>,
    /// Records dropped by the quality filter (`max_q`, no fix).
    pub dropped_by_quality: usize,
    /// Things the reader wants the user to know, each once (e.g. default GNSS sigmas used).
    pub warnings: Vec<String>,
}

/// The GNSS file of a run configuration read one fix at a time ([`RunConfig::open_gnss`]),
/// whatever its format: fixes after the quality filter, in time order, `[gnss]
/// time_offset_s` applied (standard deviations and velocities as in the file).
///
/// It holds the format's streaming reader ([`GnssTextReader`](super::text::GnssTextReader),
/// [`PosReader`](super::pos::PosReader), [`GnssCsvReader`](super::gnsscsv::GnssCsvReader),
/// [`NmeaLogReader`](super::gnsslog::NmeaLogReader) or
/// [`UbxLogReader`](super::gnsslog::UbxLogReader)), the one parser of each format, and fills
/// the summary as it goes: memory is constant whatever the file's length. Errors in the file
/// come with the fixes (those before it are returned first), naming the file and the line
/// (text formats) or the byte offset (UBX); after an error the reader ends. `Send`: it can be
/// read on another thread.
pub struct GnssFixReader {
    inner: GnssFileInner,
    path: PathBuf,
    offset_s: f64,
    summary: GnssReadSummary,
}

enum GnssFileInner {
    Text(super::text::GnssTextReader),
    Pos(super::pos::PosReader),
    // boxed: the CSV mapping, the NMEA epoch being assembled and the UBX parser's 4 KiB
    // packet buffer are large (clippy::large_enum_variant)
    Csv(Box<super::gnsscsv::GnssCsvReader>),
    Nmea(Box<super::gnsslog::NmeaLogReader>),
    Ubx(Box<super::gnsslog::UbxLogReader>),
}

impl GnssFixReader {
    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The week, drops and warnings seen so far (all of them once the reader is exhausted).
    pub fn summary(&self) -> &GnssReadSummary {
        &self.summary
    }

    /// Copies what the format's reader learnt so far into the summary.
    fn update_summary(&mut self) {
        let (week, dropped, warnings): (Option<i64>, usize, &[String]) = match &self.inner {
            GnssFileInner::Text(_) => (None, 0, &[]),
            GnssFileInner::Pos(rd) => (rd.week(), rd.dropped_by_quality(), &[]),
            GnssFileInner::Csv(rd) => (rd.week(), rd.dropped_by_quality(), rd.warnings()),
            GnssFileInner::Nmea(rd) => (rd.week(), rd.dropped_by_quality(), rd.warnings()),
            GnssFileInner::Ubx(rd) => (rd.week(), rd.dropped_by_quality(), rd.warnings()),
        };
        let s = &mut self.summary;
        s.week = week;
        s.dropped_by_quality = dropped;
        // warnings are only ever appended
        if let Some(new) = warnings.get(s.warnings.len()..) {
            s.warnings.extend_from_slice(new);
        }
    }
}

impl Iterator for GnssFixReader {
    type Item = Result<GnssFix, IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        let r = match &mut self.inner {
            GnssFileInner::Text(rd) => rd.next(),
            GnssFileInner::Pos(rd) => rd.next().map(|r| r.map(|(f, _)| f)),
            GnssFileInner::Csv(rd) => rd.next().map(|r| r.map(|(f, _)| f)),
            GnssFileInner::Nmea(rd) => rd.next().map(|r| r.map(|(f, _)| f)),
            GnssFileInner::Ubx(rd) => rd.next().map(|r| r.map(|(f, _)| f)),
        };
        self.update_summary();
        let offset_s = self.offset_s;
        r.map(|r| {
            r.map(|mut f| {
                f.t_s += offset_s;
                f
            })
        })
    }
}

impl RunConfig {
    /// Opens the IMU file named by the configuration as a stream ([`ImuFileReader`]); relative
    /// paths are resolved against `config_dir`. Errors in the file come with the samples.
    pub fn open_imu(&self, config_dir: &Path) -> Result<ImuFileReader, IoError> {
        let path = Self::resolve(config_dir, &self.imu.path);
        let inner = match self.imu.format {
            ImuFileKind::Text => {
                ImuFileInner::Text(Box::new(super::text::ImuTextReader::open(&path)?))
            }
            ImuFileKind::Csv => {
                let fmt = self.imu.csv.as_ref().ok_or_else(|| IoError::Config {
                    path: path.clone(),
                    message: "imu.format = \"csv\" needs an [imu.csv] mapping".into(),
                    source: None,
                })?;
                ImuFileInner::Csv(Box::new(super::imucsv::ImuCsvIncrements::open(&path, fmt)?))
            }
        };
        let m = &self.imu.mounting;
        Ok(ImuFileReader {
            inner,
            path,
            c_imu_b: (*m != Mounting::identity()).then(|| m.c_imu_b()),
            offset_s: self.imu.time_offset_s,
        })
    }

    /// Opens the GNSS file named by the configuration as a stream of fixes
    /// ([`GnssFixReader`]); relative paths are resolved against `config_dir`. Errors of the
    /// options and of opening come here (for NMEA also a log without an RMC date, found by a
    /// first pass that stops at the first RMC), errors in the file with the fixes.
    pub fn open_gnss(&self, config_dir: &Path) -> Result<GnssFixReader, IoError> {
        let path = Self::resolve(config_dir, &self.gnss.path);
        let inner = match self.gnss.format {
            GnssFileKind::Text => GnssFileInner::Text(super::text::GnssTextReader::open(&path)?),
            GnssFileKind::Csv => {
                let fmt = self.gnss.csv.as_ref().ok_or_else(|| IoError::Config {
                    path: path.clone(),
                    message: "gnss.format = \"csv\" needs a [gnss.csv] mapping".into(),
                    source: None,
                })?;
                GnssFileInner::Csv(Box::new(super::gnsscsv::GnssCsvReader::open(&path, fmt)?))
            }
            GnssFileKind::Nmea | GnssFileKind::Ubx => {
                let opts = self.gnss.log.clone().unwrap_or_default();
                if self.gnss.format == GnssFileKind::Nmea {
                    GnssFileInner::Nmea(Box::new(super::gnsslog::NmeaLogReader::open(
                        &path,
                        &opts,
                        self.gnss.max_q,
                    )?))
                } else {
                    GnssFileInner::Ubx(Box::new(super::gnsslog::UbxLogReader::open(
                        &path,
                        &opts,
                        self.gnss.max_q,
                    )?))
                }
            }
            GnssFileKind::RtklibPos => GnssFileInner::Pos(super::pos::PosReader::open(
                &path,
                &PosOptions {
                    max_q: self.gnss.max_q,
                },
            )?),
        };
        let mut rd = GnssFixReader {
            inner,
            path,
            offset_s: self.gnss.time_offset_s,
            summary: GnssReadSummary::default(),
        };
        rd.update_summary();
        Ok(rd)
    }
}

impl RunConfig {
    /// Reads the IMU (converted to increments in body axes), GNSS and truth files named by the
    /// configuration; relative paths are resolved against `config_dir`.
    pub fn load_inputs(&self, config_dir: &Path) -> Result<RunInputs, IoError> {
        let imu_rd = self.open_imu(config_dir)?;
        let imu_path = imu_rd.path().to_path_buf();
        let spans = imu_rd.increments_span_gaps();
        let mut samples = Vec::new();
        let mut lines = Vec::new();
        for r in imu_rd {
            let (s, line) = r?;
            samples.push(s);
            lines.push(line);
        }
        let t: Vec<f64> = samples.iter().map(|s| s.t_s).collect();
        let mut gaps = super::text::TimeGapReport::detect(&t, &lines);
        if spans {
            // increment i of a CSV log closes the interval ending at row i + 1
            for g in &mut gaps.gaps {
                g.index = g.index.saturating_sub(1);
            }
        }
        let imu = ImuRecord {
            samples,
            gaps,
            origin: Some(super::text::ImuOrigin {
                path: imu_path,
                lines,
                increments_span_gaps: spans,
            }),
        };
        let mut gnss_rd = self.open_gnss(config_dir)?;
        let mut gnss = Vec::new();
        for r in &mut gnss_rd {
            gnss.push(r?);
        }
        let GnssReadSummary {
            week: gnss_week,
            dropped_by_quality: dropped,
            warnings,
        } = gnss_rd.summary().clone();
        let truth = match &self.truth {
            None => None,
            Some(t) => {
                let p = Self::resolve(config_dir, &t.path);
                Some(match t.format {
                    TruthFileKind::NavText => TruthData::Nav(read_nav_text(&p)?),
                    TruthFileKind::RtklibPos => {
                        TruthData::Positions(read_rtklib_pos(&p, &PosOptions { max_q: 6 })?.fixes)
                    }
                })
            }
        };
        Ok(RunInputs {
            imu,
            gnss,
            gnss_week,
            gnss_dropped_by_quality: dropped,
            warnings,
            truth,
        })
    }
}
