//! KF-GINS YAML configuration files (`kf-gins.yaml`, i2Nav-WHU/KF-GINS), read faithfully:
//! the keys and units are those of KF-GINS's `dataset/kf-gins.yaml` and of its `loadConfig`.
//!
//! | key | unit (file) | SI accessor |
//! |---|---|---|
//! | `imupath`, `gnsspath`, `outputpath` | path (KF-GINS: relative to the working directory) | [`KfGinsConfig::resolve_path`] |
//! | `imudatalen` | columns of the IMU file (only the first 7 used) | |
//! | `imudatarate` | Hz | [`KfGinsConfig::imu_dt_s`] |
//! | `starttime`, `endtime` | GPS seconds of week (`endtime: -1` = to the end) | [`KfGinsConfig::end_time_s`] |
//! | `initpos` | lat deg, lon deg, h m | [`KfGinsConfig::init_llh`] |
//! | `initvel` | m/s NED | |
//! | `initatt` | roll, pitch, yaw deg (ZYX) | [`KfGinsConfig::init_rpy_rad`] |
//! | `initgyrbias` / `initaccbias` | deg/h / mGal | [`KfGinsConfig::init_gyr_bias_radps`], [`KfGinsConfig::init_acc_bias_mps2`] |
//! | `initgyrscale` / `initaccscale` | ppm | [`KfGinsConfig::init_gyr_scale`], [`KfGinsConfig::init_acc_scale`] |
//! | `initposstd` | m (N, E, D) | |
//! | `initvelstd` | m/s (N, E, D) | |
//! | `initattstd` | deg (roll, pitch, yaw) | [`KfGinsConfig::init_att_std_rad`] |
//! | `initbgstd` / `initbastd` (optional) | deg/h / mGal; default `imunoise.gbstd` / `abstd` | [`KfGinsConfig::init_bg_std_radps`], [`KfGinsConfig::init_ba_std_mps2`] |
//! | `initsgstd` / `initsastd` (optional) | ppm; default `imunoise.gsstd` / `asstd` | [`KfGinsConfig::init_sg_std`], [`KfGinsConfig::init_sa_std`] |
//! | `imunoise.arw` | deg/sqrt(h) | [`KfGinsImuNoiseYaml::arw_rad_per_sqrt_s`] |
//! | `imunoise.vrw` | m/s/sqrt(h) | [`KfGinsImuNoiseYaml::vrw_mps_per_sqrt_s`] |
//! | `imunoise.gbstd` | deg/h (Gauss-Markov sigma) | [`KfGinsImuNoiseYaml::gbstd_radps`] |
//! | `imunoise.abstd` | mGal (Gauss-Markov sigma) | [`KfGinsImuNoiseYaml::abstd_mps2`] |
//! | `imunoise.gsstd`, `asstd` | ppm (Gauss-Markov sigma) | [`KfGinsImuNoiseYaml::gsstd`], [`KfGinsImuNoiseYaml::asstd`] |
//! | `imunoise.corrtime` | h (all Gauss-Markov states) | [`KfGinsImuNoiseYaml::corrtime_s`] |
//! | `antlever` | m, antenna phase centre in the IMU (body FRD) frame | |
//!
//! Differences from KF-GINS's own loader: the four `init*bias`/`init*scale` vectors default to
//! zero when absent (KF-GINS refuses the file), vectors must have exactly three elements
//! (KF-GINS reads the first three), and keys KF-GINS does not know are kept in
//! [`KfGinsConfig::unknown_keys`] rather than silently dropped. The mapping onto the filter is
//! [`KfGinsConfig::filter_config_feedback`] (what KF-GINS's code does: bias estimates that do
//! not decay between updates; `docs/kfgins-parity.md`), or with `--model kf-gins`
//! [`KfGinsConfig::filter_config_gauss_markov`] (the textbook Gauss-Markov reading,
//! [`nav_core::config::FilterConfig::from_kf_gins`] applied to [`KfGinsConfig::imu_noise`]).

mod quoted;

use super::text::write_with;
use super::IoError;
use nav_core::config::{FilterConfig, KfGinsImuNoise, ScaleFactorNoise};
use nav_core::earth::Llh;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

const DEG: f64 = std::f64::consts::PI / 180.0;

/// The `imunoise` section, in KF-GINS units.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KfGinsImuNoiseYaml {
    /// Angle random walk, deg/sqrt(h).
    #[serde(deserialize_with = "quoted::f64x3")]
    pub arw: [f64; 3],
    /// Velocity random walk, m/s/sqrt(h).
    #[serde(deserialize_with = "quoted::f64x3")]
    pub vrw: [f64; 3],
    /// Gyro bias Gauss-Markov sigma, deg/h.
    #[serde(deserialize_with = "quoted::f64x3")]
    pub gbstd: [f64; 3],
    /// Accelerometer bias Gauss-Markov sigma, mGal.
    #[serde(deserialize_with = "quoted::f64x3")]
    pub abstd: [f64; 3],
    /// Gyro scale-factor Gauss-Markov sigma, ppm.
    #[serde(deserialize_with = "quoted::f64x3")]
    pub gsstd: [f64; 3],
    /// Accelerometer scale-factor Gauss-Markov sigma, ppm.
    #[serde(deserialize_with = "quoted::f64x3")]
    pub asstd: [f64; 3],
    /// Correlation time of every Gauss-Markov state, h.
    #[serde(deserialize_with = "quoted::f64")]
    pub corrtime: f64,
}

impl KfGinsImuNoiseYaml {
    /// Angle random walk, rad/sqrt(s).
    pub fn arw_rad_per_sqrt_s(&self) -> [f64; 3] {
        self.arw.map(|v| v * DEG / 60.0)
    }
    /// Velocity random walk, m/s/sqrt(s).
    pub fn vrw_mps_per_sqrt_s(&self) -> [f64; 3] {
        self.vrw.map(|v| v / 60.0)
    }
    /// Gyro bias sigma, rad/s.
    pub fn gbstd_radps(&self) -> [f64; 3] {
        self.gbstd.map(|v| v * DEG / 3600.0)
    }
    /// Accelerometer bias sigma, m/s^2.
    pub fn abstd_mps2(&self) -> [f64; 3] {
        self.abstd.map(|v| v * 1e-5)
    }
    /// Gyro scale-factor sigma (dimensionless).
    pub fn gsstd(&self) -> [f64; 3] {
        self.gsstd.map(|v| v * 1e-6)
    }
    /// Accelerometer scale-factor sigma (dimensionless).
    pub fn asstd(&self) -> [f64; 3] {
        self.asstd.map(|v| v * 1e-6)
    }
    /// Correlation time, s.
    pub fn corrtime_s(&self) -> f64 {
        self.corrtime * 3600.0
    }
}

fn zero3() -> [f64; 3] {
    [0.0; 3]
}

/// A KF-GINS configuration file, field for field (units in the module table).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KfGinsConfig {
    /// IMU file (KF-GINS IMU text format, or its binary variant).
    pub imupath: String,
    /// GNSS file (7 columns, or KF-GINS's 13-column variant).
    pub gnsspath: String,
    /// Output folder.
    pub outputpath: String,
    /// Number of columns of the IMU file.
    #[serde(deserialize_with = "quoted::u32")]
    pub imudatalen: u32,
    /// IMU data rate, Hz.
    #[serde(deserialize_with = "quoted::u32")]
    pub imudatarate: u32,
    /// Processing start, GPS seconds of week.
    #[serde(deserialize_with = "quoted::f64")]
    pub starttime: f64,
    /// Processing end, GPS seconds of week (-1: to the end of the IMU file).
    #[serde(deserialize_with = "quoted::f64")]
    pub endtime: f64,
    /// Initial position: latitude deg, longitude deg, height m.
    #[serde(deserialize_with = "quoted::f64x3")]
    pub initpos: [f64; 3],
    /// Initial velocity north, east, down, m/s.
    #[serde(deserialize_with = "quoted::f64x3")]
    pub initvel: [f64; 3],
    /// Initial attitude roll, pitch, yaw, deg.
    #[serde(deserialize_with = "quoted::f64x3")]
    pub initatt: [f64; 3],
    /// Initial gyro bias, deg/h.
    #[serde(default = "zero3", deserialize_with = "quoted::f64x3")]
    pub initgyrbias: [f64; 3],
    /// Initial accelerometer bias, mGal.
    #[serde(default = "zero3", deserialize_with = "quoted::f64x3")]
    pub initaccbias: [f64; 3],
    /// Initial gyro scale factor, ppm.
    #[serde(default = "zero3", deserialize_with = "quoted::f64x3")]
    pub initgyrscale: [f64; 3],
    /// Initial accelerometer scale factor, ppm.
    #[serde(default = "zero3", deserialize_with = "quoted::f64x3")]
    pub initaccscale: [f64; 3],
    /// Initial position std north, east, down, m.
    #[serde(deserialize_with = "quoted::f64x3")]
    pub initposstd: [f64; 3],
    /// Initial velocity std north, east, down, m/s.
    #[serde(deserialize_with = "quoted::f64x3")]
    pub initvelstd: [f64; 3],
    /// Initial attitude std roll, pitch, yaw, deg.
    #[serde(deserialize_with = "quoted::f64x3")]
    pub initattstd: [f64; 3],
    /// Initial gyro bias std, deg/h (default `imunoise.gbstd`).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "quoted::opt_f64x3"
    )]
    pub initbgstd: Option<[f64; 3]>,
    /// Initial accelerometer bias std, mGal (default `imunoise.abstd`).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "quoted::opt_f64x3"
    )]
    pub initbastd: Option<[f64; 3]>,
    /// Initial gyro scale-factor std, ppm (default `imunoise.gsstd`).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "quoted::opt_f64x3"
    )]
    pub initsgstd: Option<[f64; 3]>,
    /// Initial accelerometer scale-factor std, ppm (default `imunoise.asstd`).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "quoted::opt_f64x3"
    )]
    pub initsastd: Option<[f64; 3]>,
    /// IMU noise.
    pub imunoise: KfGinsImuNoiseYaml,
    /// GNSS antenna phase centre in the IMU (body FRD) frame, m.
    #[serde(deserialize_with = "quoted::f64x3")]
    pub antlever: [f64; 3],
    /// Top-level keys KF-GINS does not read (kept so a caller can warn about them).
    #[serde(skip)]
    pub unknown_keys: BTreeMap<String, serde_norway::Value>,
}

impl KfGinsConfig {
    /// Initial position (rad, rad, m).
    pub fn init_llh(&self) -> Llh {
        Llh::from_deg(self.initpos[0], self.initpos[1], self.initpos[2])
    }
    /// Initial attitude roll, pitch, yaw, rad.
    pub fn init_rpy_rad(&self) -> [f64; 3] {
        self.initatt.map(|v| v * DEG)
    }
    /// Initial gyro bias, rad/s.
    pub fn init_gyr_bias_radps(&self) -> [f64; 3] {
        self.initgyrbias.map(|v| v * DEG / 3600.0)
    }
    /// Initial accelerometer bias, m/s^2.
    pub fn init_acc_bias_mps2(&self) -> [f64; 3] {
        self.initaccbias.map(|v| v * 1e-5)
    }
    /// Initial gyro scale factor (dimensionless).
    pub fn init_gyr_scale(&self) -> [f64; 3] {
        self.initgyrscale.map(|v| v * 1e-6)
    }
    /// Initial accelerometer scale factor (dimensionless).
    pub fn init_acc_scale(&self) -> [f64; 3] {
        self.initaccscale.map(|v| v * 1e-6)
    }
    /// Initial attitude std, rad.
    pub fn init_att_std_rad(&self) -> [f64; 3] {
        self.initattstd.map(|v| v * DEG)
    }
    /// Initial gyro bias std, rad/s (`initbgstd`, else `imunoise.gbstd`).
    pub fn init_bg_std_radps(&self) -> [f64; 3] {
        self.initbgstd
            .unwrap_or(self.imunoise.gbstd)
            .map(|v| v * DEG / 3600.0)
    }
    /// Initial accelerometer bias std, m/s^2 (`initbastd`, else `imunoise.abstd`).
    pub fn init_ba_std_mps2(&self) -> [f64; 3] {
        self.initbastd
            .unwrap_or(self.imunoise.abstd)
            .map(|v| v * 1e-5)
    }
    /// Initial gyro scale-factor std (`initsgstd`, else `imunoise.gsstd`).
    pub fn init_sg_std(&self) -> [f64; 3] {
        self.initsgstd
            .unwrap_or(self.imunoise.gsstd)
            .map(|v| v * 1e-6)
    }
    /// Initial accelerometer scale-factor std (`initsastd`, else `imunoise.asstd`).
    pub fn init_sa_std(&self) -> [f64; 3] {
        self.initsastd
            .unwrap_or(self.imunoise.asstd)
            .map(|v| v * 1e-6)
    }
    /// Nominal IMU interval 1 / imudatarate, s (KF-GINS uses it for the first sample and after
    /// intervals of 0.1 s or more).
    pub fn imu_dt_s(&self) -> f64 {
        1.0 / f64::from(self.imudatarate)
    }
    /// Processing end, s; `None` for "to the end of the IMU file" (a negative `endtime`).
    pub fn end_time_s(&self) -> Option<f64> {
        (self.endtime >= 0.0).then_some(self.endtime)
    }
    /// The `imunoise` section as nav-core's [`KfGinsImuNoise`] (same units), for
    /// [`nav_core::config::FilterConfig::from_kf_gins`].
    pub fn imu_noise(&self) -> KfGinsImuNoise {
        let n = &self.imunoise;
        KfGinsImuNoise {
            arw_deg_per_sqrt_h: n.arw,
            vrw_mps_per_sqrt_h: n.vrw,
            gbstd_deg_per_h: n.gbstd,
            abstd_mgal: n.abstd,
            gsstd_ppm: n.gsstd,
            asstd_ppm: n.asstd,
            corrtime_h: n.corrtime,
        }
    }

    /// The filter configuration of this file for the textbook Gauss-Markov reading of KF-GINS's
    /// model ([`nav_core::model::LAYOUT_KF_GINS`]): [`FilterConfig::from_kf_gins`] (`S_B = 2
    /// sigma^2 / T`), the initial bias variance `initbgstd^2` / `initbastd^2` split into the
    /// Gauss-Markov stationary part and `bias_init_sigma`, scale factors starting at
    /// `initsgstd` / `initsastd`. The bias estimates decay like a Gauss-Markov mean between
    /// updates, which KF-GINS's code does not do (see [`Self::filter_config_feedback`]).
    pub fn filter_config_gauss_markov(&self) -> FilterConfig {
        let mut filter = FilterConfig::from_kf_gins(&self.imu_noise());
        // KF-GINS's initial bias std: variance = stationary GM variance + bias_init_sigma^2
        let extra = |init: [f64; 3], stat: [f64; 3]| {
            [0, 1, 2].map(|i| (init[i] * init[i] - stat[i] * stat[i]).max(0.0).sqrt())
        };
        filter.gyro.bias_init_sigma = extra(self.init_bg_std_radps(), self.imunoise.gbstd_radps());
        filter.accel.bias_init_sigma = extra(self.init_ba_std_mps2(), self.imunoise.abstd_mps2());
        self.set_scale_factors(&mut filter);
        filter
    }

    /// The filter configuration that reproduces KF-GINS's code, for
    /// `LAYOUT_KF_GINS_FEEDBACK` (host-sim's default for a KF-GINS file): KF-GINS feeds the
    /// estimated bias error back into a bias estimate that it keeps constant between updates
    /// (`GIEngine::stateFeedback`; only the covariance uses `F = -1/T`), so a bias is a random
    /// constant plus a random walk with KF-GINS's `Qc = 2 sigma^2 / T` (`S_K`, no decay of
    /// the estimate) starting at `initbgstd` / `initbastd`. Not reproduced: KF-GINS's
    /// covariance decay `(1 - dt/T)^2` of the bias variance (it lowers KF-GINS's effective
    /// bias noise by `2 P / T`, a few per cent on `docs/kfgins-parity.md`'s drive) and the
    /// scale factors' non-decaying estimate (ours are Gauss-Markov with `initsgstd` /
    /// `initsastd` as stationary sigma, so their process noise follows the initial sigma).
    pub fn filter_config_feedback(&self) -> FilterConfig {
        let mut filter = FilterConfig::from_kf_gins(&self.imu_noise());
        for (n, init) in [
            (&mut filter.gyro, self.init_bg_std_radps()),
            (&mut filter.accel, self.init_ba_std_mps2()),
        ] {
            n.s_k = n.s_b;
            n.s_b = [0.0; 3];
            n.bias_init_sigma = init;
        }
        self.set_scale_factors(&mut filter);
        filter
    }

    fn set_scale_factors(&self, filter: &mut FilterConfig) {
        filter.gyro_scale = ScaleFactorNoise {
            sigma: self.init_sg_std(),
            t_s: filter.gyro_scale.t_s,
        };
        filter.accel_scale = ScaleFactorNoise {
            sigma: self.init_sa_std(),
            t_s: filter.accel_scale.t_s,
        };
    }

    /// Resolves a path of the file (`imupath`, ...): absolute paths as they are; a relative
    /// path relative to the configuration file's folder when that file exists, else as KF-GINS
    /// does, relative to the working directory.
    pub fn resolve_path(&self, p: &str, config_dir: &Path) -> PathBuf {
        let pb = PathBuf::from(p);
        if pb.is_absolute() {
            return pb;
        }
        let beside = config_dir.join(&pb);
        if beside.exists() {
            beside
        } else {
            pb
        }
    }

    /// Checks values a filter needs to be meaningful: finite numbers, non-negative standard
    /// deviations and noise, positive rate and correlation time, `imudatalen >= 7`,
    /// `|lat| <= 90`, `endtime < 0 or endtime > starttime`.
    pub fn validate(&self) -> Result<(), String> {
        let mut bad = Vec::new();
        let fin = |name: &str, v: &[f64], nonneg: bool, bad: &mut Vec<String>| {
            if v.iter().any(|x| !x.is_finite()) {
                bad.push(format!("{name} must be finite: {v:?}"));
            } else if nonneg && v.iter().any(|x| *x < 0.0) {
                bad.push(format!("{name} must not be negative: {v:?}"));
            }
        };
        fin("initpos", &self.initpos, false, &mut bad);
        fin("initvel", &self.initvel, false, &mut bad);
        fin("initatt", &self.initatt, false, &mut bad);
        fin("initgyrbias", &self.initgyrbias, false, &mut bad);
        fin("initaccbias", &self.initaccbias, false, &mut bad);
        fin("initgyrscale", &self.initgyrscale, false, &mut bad);
        fin("initaccscale", &self.initaccscale, false, &mut bad);
        fin("initposstd", &self.initposstd, true, &mut bad);
        fin("initvelstd", &self.initvelstd, true, &mut bad);
        fin("initattstd", &self.initattstd, true, &mut bad);
        for (n, v) in [
            ("initbgstd", &self.initbgstd),
            ("initbastd", &self.initbastd),
            ("initsgstd", &self.initsgstd),
            ("initsastd", &self.initsastd),
        ] {
            if let Some(v) = v {
                fin(n, v, true, &mut bad);
            }
        }
        let n = &self.imunoise;
        fin("imunoise.arw", &n.arw, true, &mut bad);
        fin("imunoise.vrw", &n.vrw, true, &mut bad);
        fin("imunoise.gbstd", &n.gbstd, true, &mut bad);
        fin("imunoise.abstd", &n.abstd, true, &mut bad);
        fin("imunoise.gsstd", &n.gsstd, true, &mut bad);
        fin("imunoise.asstd", &n.asstd, true, &mut bad);
        fin("antlever", &self.antlever, false, &mut bad);
        if !(n.corrtime.is_finite() && n.corrtime > 0.0) {
            bad.push(format!("imunoise.corrtime must be > 0 h: {}", n.corrtime));
        }
        if self.imudatarate == 0 {
            bad.push("imudatarate must be > 0 Hz".into());
        }
        if self.imudatalen < 7 {
            bad.push(format!("imudatalen must be >= 7: {}", self.imudatalen));
        }
        if self.initpos[0].abs() > 90.0 {
            bad.push(format!(
                "initpos latitude outside [-90, 90] deg: {}",
                self.initpos[0]
            ));
        }
        if !self.starttime.is_finite() || !self.endtime.is_finite() {
            bad.push("starttime and endtime must be finite".into());
        } else if self.endtime >= 0.0 && self.endtime <= self.starttime {
            bad.push(format!(
                "endtime {} must be after starttime {} (or -1)",
                self.endtime, self.starttime
            ));
        }
        if bad.is_empty() {
            Ok(())
        } else {
            Err(bad.join("; "))
        }
    }
}

/// Top-level keys KF-GINS reads.
const KNOWN_KEYS: [&str; 23] = [
    "imupath",
    "gnsspath",
    "outputpath",
    "imudatalen",
    "imudatarate",
    "starttime",
    "endtime",
    "initpos",
    "initvel",
    "initatt",
    "initgyrbias",
    "initaccbias",
    "initgyrscale",
    "initaccscale",
    "initposstd",
    "initvelstd",
    "initattstd",
    "initbgstd",
    "initbastd",
    "initsgstd",
    "initsastd",
    "imunoise",
    "antlever",
];

/// Parses KF-GINS YAML text (`name` is used in errors) and validates it.
pub fn parse_kf_gins_yaml(name: &Path, text: &str) -> Result<KfGinsConfig, IoError> {
    let err = |e: serde_norway::Error| IoError::Config {
        path: name.to_path_buf(),
        message: e.to_string(),
        source: Some(Box::new(e)),
    };
    // Typed parse first: its errors carry the line and column.
    let mut cfg: KfGinsConfig = serde_norway::from_str(text).map_err(err)?;
    if let serde_norway::Value::Mapping(m) =
        serde_norway::from_str::<serde_norway::Value>(text).map_err(err)?
    {
        for (k, v) in m {
            if let Some(k) = k.as_str() {
                if !KNOWN_KEYS.contains(&k) {
                    cfg.unknown_keys.insert(k.to_string(), v);
                }
            }
        }
    }
    cfg.validate().map_err(|message| IoError::Config {
        path: name.to_path_buf(),
        message,
        source: None,
    })?;
    Ok(cfg)
}

/// Reads and validates a KF-GINS YAML configuration file (at most
/// [`crate::runcfg::MAX_CONFIG_BYTES`]).
pub fn read_kf_gins_yaml(path: impl AsRef<Path>) -> Result<KfGinsConfig, IoError> {
    let path = path.as_ref();
    let text = crate::runcfg::read_config_text(path)?;
    // a UTF-8 byte-order mark (written by some Windows editors)
    parse_kf_gins_yaml(path, text.strip_prefix('\u{feff}').unwrap_or(&text))
}

/// Writes a KF-GINS YAML configuration (KF-GINS reads it; unknown keys are not written).
pub fn write_kf_gins_yaml(path: impl AsRef<Path>, cfg: &KfGinsConfig) -> Result<(), IoError> {
    let path = path.as_ref();
    let text = serde_norway::to_string(cfg).map_err(|e| IoError::Config {
        path: path.to_path_buf(),
        message: e.to_string(),
        source: Some(Box::new(e)),
    })?;
    write_with(path, |w| {
        w.write_all(b"# KF-GINS configuration file (written by host-sim)\n")?;
        w.write_all(text.as_bytes())
    })
}
