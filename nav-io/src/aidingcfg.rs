//! The `[aiding]` section of the run configuration ([`super::RunConfig::aiding`]):
//! land-vehicle aiding of `nav_core::aiding`, every source off unless `enabled = true`.
//! Absent keys take `nav_core`'s defaults. Angles in degrees, everything else SI.
//!
//! ```toml
//! [aiding]
//! interval_s = 0.1                 # between aiding updates
//! [aiding.stationarity]            # detector of stops (ZUPT/ZARU)
//! window_s = 0.5
//! accel_std_max_mps2 = 0.1         # spread of the specific force
//! accel_mag_tol_mps2 = 0.3         # | |f| - g |
//! gyro_mean_max_deg_per_s = 1.0
//! gyro_std_max_deg_per_s = 0.5
//! gnss_speed_max_mps = 0.15        # when a GNSS velocity is at most gnss_max_age_s old
//! gnss_max_age_s = 1.0
//! filter_speed_max_mps = 1.0       # the filter's own speed estimate
//! learn = true                     # learn the idling vibration at GNSS-confirmed stops
//! learn_margin = 1.5               # spread thresholds: margin x the learned spreads
//! learn_tau_s = 5.0                # time constant of the learning
//! learn_accel_std_max_mps2 = 0.2   # bound of the learned specific-force threshold
//! learn_gyro_std_max_deg_per_s = 2.0  # bound of the learned rate threshold
//! learn_filter_speed_max_mps = 0.2 # learned thresholds only at filter speeds below this
//! [aiding.nhc]                     # non-holonomic constraint
//! enabled = true
//! sigma_lateral_mps = 0.1
//! sigma_vertical_mps = 0.05
//! min_speed_mps = 1.0
//! mount_rpy_deg = [0.0, 0.0, 0.0]  # vehicle -> body (body = vehicle when zero)
//! lever_arm_m = [0.0, 0.0, 0.0]    # constraint point (rear axle) from the IMU, body FRD
//! slip_sigma_deg_per_mps2 = 0.0    # side-slip sigma per m/s^2 of lateral acceleration
//! nis_gate = 18.42
//! [aiding.zupt]
//! enabled = true
//! sigma_mps = 0.02
//! nis_gate = 21.11
//! [aiding.zaru]
//! enabled = true
//! sigma_deg_per_s = 0.01
//! nis_gate = 21.11
//! [aiding.odometer]                # wheel speed (nav_io::odometer format: time speed)
//! enabled = true
//! file = "odometer.txt"            # relative to the configuration file's folder
//! sigma_mps = 0.05
//! lever_arm_m = [0.0, 0.0, 0.0]    # measured point (rear axle) from the IMU, body FRD
//! scale_factor = true              # estimate the scale-factor state (odometer_scale)
//! scale_sigma = 0.05               # its prior 1-sigma (fraction)
//! max_gap_s = 0.5                  # no interpolation across longer gaps
//! nis_gate = 15.14
//! [aiding.heading]                 # dual-antenna GNSS heading (nav_io::heading format)
//! enabled = true
//! file = "heading.txt"             # relative to the configuration file's folder
//! format = "text"                  # or "nmea" (HDT/THS, timed by RMC/GGA)
//! leap_seconds = 18                # GPS - UTC, for "nmea"
//! baseline_m = [1.0, 0.0, 0.0]     # primary -> secondary antenna, body FRD (direction only)
//! sigma_deg = 0.5                  # for samples without their own sigma
//! nis_gate = 15.14
//! ```
//!
//! The odometer's vehicle frame is `[aiding.nhc] mount_rpy_deg`. With a case directory
//! (`host-sim run --case`), the case's own `odometer.txt` / `heading.txt` replace the files
//! named here.

use nav_core::aiding::AidingConfig;

/// `[aiding]`.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AidingSection {
    /// Interval between aiding updates, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interval_s: Option<f64>,
    /// `[aiding.stationarity]`.
    #[serde(default)]
    pub stationarity: StationaritySection,
    /// `[aiding.nhc]`.
    #[serde(default)]
    pub nhc: NhcSection,
    /// `[aiding.zupt]`.
    #[serde(default)]
    pub zupt: ZuptSection,
    /// `[aiding.zaru]`.
    #[serde(default)]
    pub zaru: ZaruSection,
    /// `[aiding.odometer]`.
    #[serde(default)]
    pub odometer: OdometerSection,
    /// `[aiding.heading]`.
    #[serde(default)]
    pub heading: HeadingSection,
}

/// `[aiding.heading]`: dual-antenna GNSS heading.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeadingSection {
    /// Use the heading.
    #[serde(default)]
    pub enabled: bool,
    /// The heading file (`nav_io::heading` format), relative to the configuration's folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<std::path::PathBuf>,
    /// `"text"` (default) or `"nmea"` (`nav_io::heading::HeadingFormat`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub format: Option<String>,
    /// GPS - UTC of an NMEA log, s (default 18).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub leap_seconds: Option<i64>,
    /// Baseline from the primary to the secondary antenna, body FRD, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub baseline_m: Option<[f64; 3]>,
    /// Sigma of samples without their own, deg.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_deg: Option<f64>,
    /// Chi-square gate (1 dof).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nis_gate: Option<f64>,
}

/// `[aiding.odometer]`: the file and the host-side settings (`file`, `scale_factor`,
/// `scale_sigma`, `max_gap_s`) besides the filter's ([`AidingSection::to_config`]).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OdometerSection {
    /// Use the odometer.
    #[serde(default)]
    pub enabled: bool,
    /// The speed file (`nav_io::odometer` format), relative to the configuration's folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<std::path::PathBuf>,
    /// Speed sigma, m/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_mps: Option<f64>,
    /// Measured point from the IMU, body FRD, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lever_arm_m: Option<[f64; 3]>,
    /// Estimate the scale factor (adds the `odometer_scale` state); default true.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale_factor: Option<bool>,
    /// Prior 1-sigma of the scale factor (fraction, e.g. 0.05 = 5 %).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale_sigma: Option<f64>,
    /// Longest interval between samples interpolated across, s (default 0.5).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_gap_s: Option<f64>,
    /// Chi-square gate (1 dof).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nis_gate: Option<f64>,
}

impl OdometerSection {
    /// Default [`OdometerSection::max_gap_s`], s.
    pub const DEFAULT_MAX_GAP_S: f64 = 0.5;

    /// Whether the scale-factor state is estimated (on and `scale_factor` not false).
    pub fn estimates_scale(&self) -> bool {
        self.enabled && self.scale_factor.unwrap_or(true)
    }
}

impl HeadingSection {
    /// The file's kind (the error names the key).
    pub fn file_format(&self) -> Result<crate::heading::HeadingFormat, String> {
        use crate::heading::HeadingFormat;
        match self.format.as_deref().unwrap_or("text") {
            "text" => Ok(HeadingFormat::Text),
            "nmea" => {
                let leap_seconds = self.leap_seconds.unwrap_or(18);
                crate::runcfg::check_leap_seconds(leap_seconds)
                    .map_err(|e| format!("aiding: heading.leap_seconds {e}"))?;
                Ok(HeadingFormat::Nmea { leap_seconds })
            }
            other => Err(format!(
                "aiding: heading.format `{other}`: expected \"text\" or \"nmea\""
            )),
        }
    }
}

/// `[aiding.stationarity]`.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StationaritySection {
    /// Test window, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window_s: Option<f64>,
    /// Largest specific-force spread, m/s^2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub accel_std_max_mps2: Option<f64>,
    /// Largest | |f| - g |, m/s^2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub accel_mag_tol_mps2: Option<f64>,
    /// Largest mean rate, deg/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gyro_mean_max_deg_per_s: Option<f64>,
    /// Largest rate spread, deg/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gyro_std_max_deg_per_s: Option<f64>,
    /// Largest GNSS speed, m/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gnss_speed_max_mps: Option<f64>,
    /// Oldest GNSS velocity used, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gnss_max_age_s: Option<f64>,
    /// Largest speed of the filter's estimate, m/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub filter_speed_max_mps: Option<f64>,
    /// Learn the vibration at GNSS-confirmed stops (default on).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub learn: Option<bool>,
    /// Learned thresholds: factor on the learned spreads.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub learn_margin: Option<f64>,
    /// Time constant of the learning, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub learn_tau_s: Option<f64>,
    /// Bound of the learned specific-force spread threshold, m/s^2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub learn_accel_std_max_mps2: Option<f64>,
    /// Bound of the learned rate spread threshold, deg/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub learn_gyro_std_max_deg_per_s: Option<f64>,
    /// Largest filter speed at which the learned thresholds apply, m/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub learn_filter_speed_max_mps: Option<f64>,
}

/// `[aiding.nhc]`.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NhcSection {
    /// Use the non-holonomic constraint.
    #[serde(default)]
    pub enabled: bool,
    /// Lateral sigma, m/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_lateral_mps: Option<f64>,
    /// Vertical sigma, m/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_vertical_mps: Option<f64>,
    /// Lowest speed, m/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_speed_mps: Option<f64>,
    /// Vehicle-to-body rotation, ZYX Euler roll/pitch/yaw, deg.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mount_rpy_deg: Option<[f64; 3]>,
    /// Constraint point from the IMU, body FRD, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lever_arm_m: Option<[f64; 3]>,
    /// 1-sigma side slip per m/s^2 of lateral acceleration, deg per m/s^2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slip_sigma_deg_per_mps2: Option<f64>,
    /// Chi-square gate (2 dof).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nis_gate: Option<f64>,
}

/// `[aiding.zupt]`.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZuptSection {
    /// Use zero-velocity updates.
    #[serde(default)]
    pub enabled: bool,
    /// Velocity sigma at stops, m/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_mps: Option<f64>,
    /// Chi-square gate (3 dof).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nis_gate: Option<f64>,
}

/// `[aiding.zaru]`.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZaruSection {
    /// Use zero-rate updates.
    #[serde(default)]
    pub enabled: bool,
    /// Rate sigma at stops, deg/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_deg_per_s: Option<f64>,
    /// Chi-square gate (3 dof).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nis_gate: Option<f64>,
}

impl AidingSection {
    /// The filter-side configuration, validated (the error names the key).
    pub fn to_config(&self) -> Result<AidingConfig, String> {
        let mut c = AidingConfig::OFF;
        let set = |dst: &mut f64, v: Option<f64>| {
            if let Some(v) = v {
                *dst = v;
            }
        };
        let deg = |v: Option<f64>| v.map(f64::to_radians);
        set(&mut c.interval_s, self.interval_s);
        let s = &self.stationarity;
        let d = &mut c.stationarity;
        set(&mut d.window_s, s.window_s);
        set(&mut d.accel_std_max_mps2, s.accel_std_max_mps2);
        set(&mut d.accel_mag_tol_mps2, s.accel_mag_tol_mps2);
        set(&mut d.gyro_mean_max_radps, deg(s.gyro_mean_max_deg_per_s));
        set(&mut d.gyro_std_max_radps, deg(s.gyro_std_max_deg_per_s));
        set(&mut d.gnss_speed_max_mps, s.gnss_speed_max_mps);
        set(&mut d.gnss_max_age_s, s.gnss_max_age_s);
        set(&mut d.filter_speed_max_mps, s.filter_speed_max_mps);
        if let Some(v) = s.learn {
            d.learn = v;
        }
        set(&mut d.learn_margin, s.learn_margin);
        set(&mut d.learn_tau_s, s.learn_tau_s);
        set(&mut d.learn_accel_std_max_mps2, s.learn_accel_std_max_mps2);
        set(
            &mut d.learn_gyro_std_max_radps,
            deg(s.learn_gyro_std_max_deg_per_s),
        );
        set(
            &mut d.learn_filter_speed_max_mps,
            s.learn_filter_speed_max_mps,
        );
        let n = &self.nhc;
        c.nhc.enabled = n.enabled;
        set(&mut c.nhc.sigma_lateral_mps, n.sigma_lateral_mps);
        set(&mut c.nhc.sigma_vertical_mps, n.sigma_vertical_mps);
        set(&mut c.nhc.min_speed_mps, n.min_speed_mps);
        if let Some(r) = n.mount_rpy_deg {
            c.nhc.mount_rpy_rad = r.map(f64::to_radians);
        }
        if let Some(l) = n.lever_arm_m {
            c.nhc.lever_arm_m = l;
        }
        set(
            &mut c.nhc.slip_sigma_rad_per_mps2,
            deg(n.slip_sigma_deg_per_mps2),
        );
        set(&mut c.nhc.nis_gate, n.nis_gate);
        c.zupt.enabled = self.zupt.enabled;
        set(&mut c.zupt.sigma_mps, self.zupt.sigma_mps);
        set(&mut c.zupt.nis_gate, self.zupt.nis_gate);
        c.zaru.enabled = self.zaru.enabled;
        set(&mut c.zaru.sigma_radps, deg(self.zaru.sigma_deg_per_s));
        set(&mut c.zaru.nis_gate, self.zaru.nis_gate);
        let o = &self.odometer;
        c.odometer.enabled = o.enabled;
        set(&mut c.odometer.sigma_mps, o.sigma_mps);
        if let Some(l) = o.lever_arm_m {
            c.odometer.lever_arm_m = l;
        }
        set(&mut c.odometer.nis_gate, o.nis_gate);
        let h = &self.heading;
        c.heading.enabled = h.enabled;
        if let Some(b) = h.baseline_m {
            c.heading.baseline_m = b;
        }
        set(&mut c.heading.sigma_rad, deg(h.sigma_deg));
        set(&mut c.heading.nis_gate, h.nis_gate);
        c.validate().map_err(|e| e.to_string())?;
        if h.enabled && h.file.is_none() {
            return Err("aiding: heading.file is needed when the heading is enabled".into());
        }
        h.file_format()?;
        if o.enabled && o.file.is_none() {
            return Err("aiding: odometer.file is needed when the odometer is enabled".into());
        }
        for (v, n) in [(o.scale_sigma, "scale_sigma"), (o.max_gap_s, "max_gap_s")] {
            if v.is_some_and(|v| !(v.is_finite() && v > 0.0)) {
                return Err(format!("aiding: odometer.{n} must be finite and > 0"));
            }
        }
        Ok(c)
    }
}

/// 1-based line of `key` inside the table `[table]` (or its first line when the key is not
/// written there) of a TOML text, for error messages; None when the table is absent.
pub fn line_of_key(text: &str, table: &str, key: &str) -> Option<usize> {
    let mut current = String::new();
    let mut table_line = None;
    for (i, line) in text.lines().enumerate() {
        let t = line.trim();
        if let Some(h) = t.strip_prefix('[') {
            current = h.trim_end_matches(']').trim().to_string();
            if current == table && table_line.is_none() {
                table_line = Some(i + 1);
            }
            continue;
        }
        if current == table {
            if let Some((k, _)) = t.split_once('=') {
                if k.trim() == key {
                    return Some(i + 1);
                }
            }
        }
    }
    table_line
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn odometer_section_reaches_the_filter_config_and_checks_its_keys() {
        let a: AidingSection = toml::from_str(
            "[odometer]\nenabled = true\nfile = \"odo.txt\"\nsigma_mps = 0.03\n\
             lever_arm_m = [-1.2, 0.0, 0.8]\nscale_factor = false\n",
        )
        .unwrap();
        let c = a.to_config().unwrap();
        assert!(c.odometer.enabled && c.any_enabled());
        assert_eq!(c.odometer.sigma_mps, 0.03);
        assert_eq!(c.odometer.lever_arm_m, [-1.2, 0.0, 0.8]);
        assert!(!a.odometer.estimates_scale());
        let no_file: AidingSection = toml::from_str("[odometer]\nenabled = true\n").unwrap();
        let e = no_file.to_config().unwrap_err();
        assert!(e.starts_with("aiding: odometer.file"), "{e}");
        let bad: AidingSection =
            toml::from_str("[odometer]\nenabled = true\nfile = \"o\"\nsigma_mps = -1\n").unwrap();
        let e = bad.to_config().unwrap_err();
        assert!(e.contains("odometer.sigma_mps"), "{e}");
        assert!(toml::from_str::<AidingSection>("[odometer]\nspeed_file = \"o\"\n").is_err());
    }

    #[test]
    fn heading_section_reaches_the_filter_config_and_checks_its_keys() {
        let a: AidingSection = toml::from_str(
            "[heading]\nenabled = true\nfile = \"h.txt\"\nbaseline_m = [0.0, 1.5, 0.0]\n\
             sigma_deg = 0.2\nnis_gate = 10.83\n",
        )
        .unwrap();
        let c = a.to_config().unwrap();
        assert!(c.heading.enabled && c.any_enabled() && !c.imu_epoch_sources());
        assert_eq!(c.heading.baseline_m, [0.0, 1.5, 0.0]);
        assert!((c.heading.sigma_rad - 0.2f64.to_radians()).abs() < 1e-15);
        assert_eq!(c.heading.nis_gate, 10.83);
        let no_file: AidingSection = toml::from_str("[heading]\nenabled = true\n").unwrap();
        assert!(no_file
            .to_config()
            .unwrap_err()
            .starts_with("aiding: heading.file"));
        let vertical: AidingSection = toml::from_str(
            "[heading]\nenabled = true\nfile = \"h\"\nbaseline_m = [0.0, 0.0, 1.0]\n",
        )
        .unwrap();
        let e = vertical.to_config().unwrap_err();
        assert!(e.contains("heading.baseline_m"), "{e}");
        let bad: AidingSection =
            toml::from_str("[heading]\nenabled = true\nfile = \"h\"\nsigma_deg = 0\n").unwrap();
        assert!(bad.to_config().unwrap_err().contains("heading.sigma_deg"));
        let nmea: AidingSection = toml::from_str(
            "[heading]\nenabled = true\nfile = \"h\"\nformat = \"nmea\"\nleap_seconds = 17\n",
        )
        .unwrap();
        assert_eq!(
            nmea.heading.file_format(),
            Ok(crate::heading::HeadingFormat::Nmea { leap_seconds: 17 })
        );
        let fmt: AidingSection =
            toml::from_str("[heading]\nenabled = true\nfile = \"h\"\nformat = \"csv\"\n").unwrap();
        assert!(fmt.to_config().unwrap_err().contains("heading.format"));
    }
}
