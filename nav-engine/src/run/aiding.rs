//! Land-vehicle aiding in host runs: wraps `nav_core::aiding::Aiding` (stationarity detector,
//! non-holonomic constraint, zero-velocity and zero-rate updates) for the run loop, which calls
//! [`RunAiding::note_fix`] for every GNSS fix given to the filter and [`RunAiding::after_imu`]
//! after every integrated IMU sample. What it did is in [`AidingReport`] (run summary and
//! `metrics.json`).

use nav_core::aiding::{Aiding, AidingConfig, AidingCounters, SourceCounters};
use nav_core::filter::Filter;
use nav_core::scalar::Scalar;
use nav_core::types::GnssFix;
use serde::{Deserialize, Serialize};

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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct AidingReport {
    /// Aiding epochs with a full detector window.
    pub epochs: u32,
    /// Of those, declared stationary.
    pub stationary_epochs: u32,
    /// Non-holonomic constraint.
    pub nhc: SourceReport,
    /// Zero-velocity update.
    pub zupt: SourceReport,
    /// Zero-angular-rate update.
    pub zaru: SourceReport,
}

impl AidingReport {
    /// The report of a configuration and its counters.
    pub fn new(cfg: &AidingConfig, c: &AidingCounters) -> Self {
        Self {
            epochs: c.epochs,
            stationary_epochs: c.stationary_epochs,
            nhc: SourceReport::of(cfg.nhc.enabled, &c.nhc),
            zupt: SourceReport::of(cfg.zupt.enabled, &c.zupt),
            zaru: SourceReport::of(cfg.zaru.enabled, &c.zaru),
        }
    }

    /// One line for the run summary (empty when every source is off).
    pub fn summary_line(&self) -> String {
        let mut parts = Vec::new();
        for (name, s) in [
            ("nhc", &self.nhc),
            ("zupt", &self.zupt),
            ("zaru", &self.zaru),
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
        format!(
            "aiding: {}; stationary {} of {} aiding epochs",
            parts.join(", "),
            self.stationary_epochs,
            self.epochs
        )
    }
}

/// The run loop's aiding state.
#[derive(Debug, Clone)]
pub struct RunAiding<T: Scalar> {
    inner: Aiding<T, HOST_WINDOW>,
    gnss_speed: Option<(f64, f64)>,
    /// The aiding's decision time as `Aiding::on_imu` keeps it (for the smoother's recorder).
    last_decision_s: f64,
}

impl<T: Scalar> RunAiding<T> {
    /// For a configuration (validated here; the error names the field).
    pub fn new(cfg: &AidingConfig) -> Result<Self, String> {
        Ok(Self {
            inner: Aiding::new(cfg).map_err(|e| e.to_string())?,
            gnss_speed: None,
            last_decision_s: f64::NEG_INFINITY,
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
    /// at every aiding decision epoch (the rule of `Aiding::on_imu`), so that the prediction
    /// an aiding update makes is seen.
    pub fn after_imu<const N: usize>(
        &mut self,
        f: &mut Filter<T, N>,
        rec: &mut crate::smooth::Recorder,
    ) {
        let cfg = self.inner.config();
        if rec.is_enabled() && cfg.any_enabled() {
            let (t, dt) = (f.nav_state().t_s, f.last_step().dt_s);
            if t - self.last_decision_s >= cfg.interval_s - 0.5 * dt {
                self.last_decision_s = t;
                // a failure is counted by the update that follows
                let _ = f.predict_covariance_observed(rec);
            }
        }
        self.inner.on_imu(f, self.gnss_speed);
    }

    /// What it did.
    pub fn report(&self) -> AidingReport {
        AidingReport::new(self.inner.config(), self.inner.counters())
    }
}
