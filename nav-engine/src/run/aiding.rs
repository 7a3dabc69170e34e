//! Land-vehicle aiding in host runs: wraps `nav_core::aiding::Aiding` (stationarity detector,
//! non-holonomic constraint, zero-velocity and zero-rate updates, odometer, dual-antenna
//! heading) for the run loop, which calls [`RunAiding::note_fix`] for every GNSS fix given to
//! the filter and [`RunAiding::after_imu`] after every integrated IMU sample. The odometer and
//! heading files ([`RunAidingConfig`]) are read as the run goes (two odometer samples and one
//! heading sample in memory): the wheel speed is interpolated to the aiding epochs, a heading
//! sample is applied at the IMU epoch nearest it. What it did is in [`AidingReport`] (run
//! summary and `metrics.json`).

use nav_core::aiding::{Aiding, AidingConfig, AidingCounters, AidingInputs, SourceCounters};
use nav_core::filter::Filter;
use nav_core::model::BlockKind;
use nav_core::scalar::Scalar;
use nav_core::types::GnssFix;
use nav_io::heading::HeadingFormat;
use nav_io::{HeadingStream, OdometerStream};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// The aiding of a run: the filter-side settings and the input files of the sources that
/// need one.
#[derive(Debug, Clone, PartialEq)]
pub struct RunAidingConfig {
    /// The filter-side settings (`nav_core`).
    pub filter: AidingConfig,
    /// Wheel-speed file (`nav_io::odometer` format), needed when the odometer is on.
    pub odometer_file: Option<PathBuf>,
    /// Longest interval between wheel-speed samples interpolated across, s.
    pub odometer_max_gap_s: f64,
    /// Heading file (`nav_io::heading` text, or an NMEA log), needed when the heading is on.
    pub heading_file: Option<PathBuf>,
    /// Its kind.
    pub heading_format: HeadingFormat,
}

impl RunAidingConfig {
    /// Everything off.
    pub const OFF: Self = Self {
        filter: AidingConfig::OFF,
        odometer_file: None,
        odometer_max_gap_s: nav_io::aidingcfg::OdometerSection::DEFAULT_MAX_GAP_S,
        heading_file: None,
        heading_format: HeadingFormat::Text,
    };
}

impl Default for RunAidingConfig {
    fn default() -> Self {
        Self::OFF
    }
}

impl From<AidingConfig> for RunAidingConfig {
    /// Filter-side settings without input files (the odometer and heading need files).
    fn from(filter: AidingConfig) -> Self {
        Self {
            filter,
            ..Self::OFF
        }
    }
}

/// Largest stationarity-detector window of host runs, IMU samples (1.28 s at 200 Hz).
pub const HOST_WINDOW: usize = 256;

/// Updates of one aiding source.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct SourceReport {
    /// Whether the source was on.
    pub enabled: bool,
    /// Updates used.
    pub used: u32,
    /// Updates rejected by the source's chi-square gate.
    pub rejected: u32,
    /// Updates skipped by a numerical failure.
    pub failed: u32,
}

impl SourceReport {
    fn of(enabled: bool, c: &SourceCounters) -> Self {
        Self {
            enabled,
            used: c.used,
            rejected: c.rejected,
            failed: c.failed,
        }
    }
}

/// What the aiding did over a run.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct AidingReport {
    /// Aiding epochs with a full detector window.
    pub epochs: u32,
    /// Of those, declared stationary.
    pub stationary_epochs: u32,
    /// Runs of consecutive stationary decisions: `[first, last]` decision time, s (GPS
    /// seconds of week), in time order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub stationary_intervals: Vec<[f64; 2]>,
    /// The vibration learned at GNSS-confirmed stops at the end of the run: specific-force
    /// spread m/s^2, rate spread deg/s (none learned: absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rest_level: Option<[f64; 2]>,
    /// Non-holonomic constraint.
    pub nhc: SourceReport,
    /// Zero-velocity update.
    pub zupt: SourceReport,
    /// Zero-angular-rate update.
    pub zaru: SourceReport,
    /// Odometer (wheel speed).
    #[serde(default)]
    pub odometer: SourceReport,
    /// Estimated odometer scale-factor error at the end of the run (measured = (1 + k) true,
    /// dimensionless) and its 1-sigma, when the run estimates it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub odometer_scale: Option<[f64; 2]>,
    /// Dual-antenna heading.
    #[serde(default)]
    pub heading: SourceReport,
    /// Heading samples not used because no IMU epoch was near them (before the run's start,
    /// in an IMU gap).
    #[serde(default)]
    pub heading_skipped: u64,
    /// An input file that could not be read to its end (the source stopped there).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub input_error: Option<String>,
}

impl AidingReport {
    /// The report of a configuration and its counters.
    pub fn new(cfg: &AidingConfig, c: &AidingCounters) -> Self {
        Self {
            epochs: c.epochs,
            stationary_epochs: c.stationary_epochs,
            stationary_intervals: Vec::new(),
            rest_level: None,
            nhc: SourceReport::of(cfg.nhc.enabled, &c.nhc),
            zupt: SourceReport::of(cfg.zupt.enabled, &c.zupt),
            zaru: SourceReport::of(cfg.zaru.enabled, &c.zaru),
            odometer: SourceReport::of(cfg.odometer.enabled, &c.odometer),
            odometer_scale: None,
            heading: SourceReport::of(cfg.heading.enabled, &c.heading),
            heading_skipped: 0,
            input_error: None,
        }
    }

    /// One line for the run summary (empty when every source is off).
    pub fn summary_line(&self) -> String {
        let mut parts = Vec::new();
        for (name, s) in [
            ("nhc", &self.nhc),
            ("zupt", &self.zupt),
            ("zaru", &self.zaru),
            ("odometer", &self.odometer),
            ("heading", &self.heading),
        ] {
            if s.enabled {
                parts.push(format!(
                    "{name} {} used / {} rejected{}",
                    s.used,
                    s.rejected,
                    if s.failed > 0 {
                        format!(" / {} failed", s.failed)
                    } else {
                        String::new()
                    }
                ));
            }
        }
        if parts.is_empty() {
            return String::new();
        }
        let mut line = format!(
            "aiding: {}; stationary {} of {} aiding epochs",
            parts.join(", "),
            self.stationary_epochs,
            self.epochs
        );
        if let Some([a, w]) = self.rest_level {
            line.push_str(&format!(
                " ({} stops; vibration learned at stops {a:.3} m/s^2, {w:.2} deg/s)",
                self.stationary_intervals.len()
            ));
        }
        if let Some([k, s]) = self.odometer_scale {
            line.push_str(&format!(
                "; odometer scale factor {:+.3} % +- {:.3} %",
                100.0 * k,
                100.0 * s
            ));
        }
        if self.heading_skipped > 0 {
            line.push_str(&format!(
                "; {} heading sample(s) before the run's first epoch or in IMU gaps (not used)",
                self.heading_skipped
            ));
        }
        if let Some(e) = &self.input_error {
            line.push_str(&format!("; INPUT ERROR (the source stopped there): {e}"));
        }
        line
    }
}

/// The run loop's aiding state.
#[derive(Debug)]
pub struct RunAiding<T: Scalar> {
    inner: Aiding<T, HOST_WINDOW>,
    gnss_speed: Option<(f64, f64)>,
    /// The aiding's decision time as `Aiding::on_imu` keeps it (for the smoother's recorder).
    last_decision_s: f64,
    odometer: Option<OdometerStream>,
    heading: Option<HeadingStream>,
    odometer_scale: Option<[f64; 2]>,
    input_error: Option<String>,
    stationary_intervals: Vec<[f64; 2]>,
    last_stationary: bool,
}

impl<T: Scalar> RunAiding<T> {
    /// For a configuration (validated here; the error names the field). Opens the odometer
    /// and heading files of the sources that are on (an error names the file).
    pub fn new(cfg: &RunAidingConfig) -> Result<Self, String> {
        let f = &cfg.filter;
        let odometer = if f.odometer.enabled {
            let p = cfg
                .odometer_file
                .as_ref()
                .ok_or("aiding: the odometer is on but no odometer file is given")?;
            Some(OdometerStream::open(p, cfg.odometer_max_gap_s).map_err(|e| e.to_string())?)
        } else {
            None
        };
        let heading = if f.heading.enabled {
            let p = cfg
                .heading_file
                .as_ref()
                .ok_or("aiding: the heading is on but no heading file is given")?;
            Some(HeadingStream::open_format(p, cfg.heading_format).map_err(|e| e.to_string())?)
        } else {
            None
        };
        Ok(Self {
            inner: Aiding::new(f).map_err(|e| e.to_string())?,
            gnss_speed: None,
            last_decision_s: f64::NEG_INFINITY,
            odometer,
            heading,
            odometer_scale: None,
            input_error: None,
            stationary_intervals: Vec::new(),
            last_stationary: false,
        })
    }

    /// A GNSS fix given to the filter: its speed feeds the stationarity detector.
    pub fn note_fix(&mut self, fix: &GnssFix) {
        if fix.has_velocity && fix.vel_ned_mps.iter().all(|v| v.is_finite()) {
            let [n, e, d] = fix.vel_ned_mps;
            self.gnss_speed = Some((fix.t_s, (n * n + e * e + d * d).sqrt()));
        }
    }

    /// After an integrated IMU sample.
    /// With the smoother's recorder enabled, the covariance is predicted (and recorded) first
    /// at every aiding decision epoch (the rule of `Aiding::on_imu`) and before a heading
    /// update, so that the prediction an aiding update makes is seen. A read error of an input
    /// file stops that source and is kept for the report ([`AidingReport::input_error`]).
    pub fn after_imu<const N: usize>(
        &mut self,
        f: &mut Filter<T, N>,
        rec: &mut crate::smooth::Recorder,
    ) {
        let cfg = self.inner.config();
        let (t, dt) = (f.nav_state().t_s, f.last_step().dt_s);
        if rec.is_enabled()
            && cfg.imu_epoch_sources()
            && t - self.last_decision_s >= cfg.interval_s - 0.5 * dt
        {
            self.last_decision_s = t;
            // a failure is counted by the update that follows
            let _ = f.predict_covariance_observed(rec);
        }
        let odometer_speed_mps = match self.odometer.as_mut().map(|o| o.speed_at(t)) {
            Some(Ok(v)) => v,
            Some(Err(e)) => {
                self.input_error.get_or_insert(e.to_string());
                self.odometer = None;
                None
            }
            None => None,
        };
        let stationary_before = self.inner.counters().stationary_epochs;
        self.inner.on_imu_with(
            f,
            &AidingInputs {
                gnss_speed: self.gnss_speed,
                odometer_speed_mps,
            },
        );
        if self.inner.counters().stationary_epochs != stationary_before {
            match self.stationary_intervals.last_mut() {
                Some(last) if self.last_stationary => last[1] = t,
                _ => self.stationary_intervals.push([t, t]),
            }
        }
        self.last_stationary = self.inner.is_stationary();
        if odometer_speed_mps.is_some() {
            if let Some(v) = f.block_value(BlockKind::OdometerScale) {
                self.odometer_scale = Some([v.estimate[0], v.sigma[0]]);
            }
        }
        while let Some(h) = self.heading.as_mut() {
            match h.due(t, dt) {
                Ok(Some(s)) => {
                    if rec.is_enabled() {
                        let _ = f.predict_covariance_observed(rec);
                    }
                    self.inner.on_heading(
                        f,
                        s.heading_deg.to_radians(),
                        s.sigma_deg.map(f64::to_radians),
                    );
                }
                Ok(None) => break,
                Err(e) => {
                    self.input_error.get_or_insert(e.to_string());
                    self.heading = None;
                }
            }
        }
    }

    /// What it did.
    pub fn report(&self) -> AidingReport {
        let mut r = AidingReport::new(self.inner.config(), self.inner.counters());
        r.odometer_scale = self.odometer_scale;
        r.heading_skipped = self.heading.as_ref().map_or(0, |h| h.skipped() as u64);
        r.input_error = self.input_error.clone();
        r.stationary_intervals = self.stationary_intervals.clone();
        r.rest_level = self.inner.rest_level().map(|[a, w]| [a, w.to_degrees()]);
        r
    }
}
