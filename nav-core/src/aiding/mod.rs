//! Land-vehicle aiding: constraints and auxiliary measurements fused by the error-state filter
//! through [`crate::filter::Filter::update_aiding`]. One file per source, measurement checks
//! apart from the fusion maths (PX4 EKF2 style):
//!
//! * [`stationarity`]: the stationarity detector (window of IMU specific force and rate, GNSS
//!   speed when present);
//! * [`nhc`]: the non-holonomic constraint (lateral and vertical vehicle velocity ~ 0);
//! * [`zupt`]: zero-velocity and zero-angular-rate updates at stops;
//! * [`odometer`]: wheel speed, with an optional scale-factor state;
//! * [`heading`]: dual-antenna GNSS heading (azimuth of a baseline fixed in the body frame).
//!
//! [`Aiding`] runs them at IMU epochs: call [`Aiding::on_imu_with`] (or [`Aiding::on_imu`]
//! without an odometer) after every successful [`crate::filter::Filter::propagate`], and
//! [`Aiding::on_heading`] at the IMU epoch nearest each heading sample. Every source is off by
//! default ([`AidingConfig`]);
//! what each did is counted in [`AidingCounters`]. No allocation, no panics, fixed sizes.

pub mod heading;
pub mod nhc;
pub mod odometer;
pub mod stationarity;
pub mod zupt;

use crate::earth;
use crate::filter::{AidingOutcome, Filter, FilterError};
use crate::model::BlockKind;
use crate::scalar::Scalar;
pub use heading::HeadingConfig;
pub use nhc::NhcConfig;
pub use odometer::OdometerConfig;
pub use stationarity::{
    RestLevel, StationarityConfig, StationarityDetector, Thresholds, WindowStats,
};
pub use zupt::{ZaruConfig, ZuptConfig};

/// Configuration of every aiding source.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AidingConfig {
    /// Interval between aiding updates, s (0: every IMU epoch).
    pub interval_s: f64,
    /// Stationarity detector thresholds.
    pub stationarity: StationarityConfig,
    /// Non-holonomic constraint.
    pub nhc: NhcConfig,
    /// Zero-velocity update.
    pub zupt: ZuptConfig,
    /// Zero-angular-rate update.
    pub zaru: ZaruConfig,
    /// Odometer (wheel speed).
    pub odometer: OdometerConfig,
    /// Dual-antenna GNSS heading.
    pub heading: HeadingConfig,
}

/// What the caller knows at an IMU epoch besides the IMU ([`Aiding::on_imu_with`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AidingInputs {
    /// `(fix time s, speed m/s)` of the latest GNSS velocity, if any.
    pub gnss_speed: Option<(f64, f64)>,
    /// The odometer's speed at this epoch (interpolated to it by the caller), m/s, if any.
    pub odometer_speed_mps: Option<f64>,
}

/// An invalid aiding setting (names the field).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AidingConfigError {
    /// The field must be finite and >= 0.
    NotNonNegative(&'static str),
    /// The field must be finite and > 0.
    NotPositive(&'static str),
    /// The field must be finite.
    NotFinite(&'static str),
}

impl core::fmt::Display for AidingConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NotNonNegative(n) => write!(f, "aiding: {n} must be finite and >= 0"),
            Self::NotPositive(n) => write!(f, "aiding: {n} must be finite and > 0"),
            Self::NotFinite(n) => write!(f, "aiding: {n} must be finite"),
        }
    }
}

impl core::error::Error for AidingConfigError {}

impl AidingConfig {
    /// Everything off (the filter's behaviour without aiding).
    pub const OFF: Self = Self {
        interval_s: 0.1,
        stationarity: StationarityConfig::DEFAULT,
        nhc: NhcConfig::DEFAULT,
        zupt: ZuptConfig::DEFAULT,
        zaru: ZaruConfig::DEFAULT,
        odometer: OdometerConfig::DEFAULT,
        heading: HeadingConfig::DEFAULT,
    };

    /// Land-vehicle aiding with the default settings: the non-holonomic constraint and the
    /// zero-velocity and zero-rate updates on, the odometer off (the firmware's
    /// `wire::CONFIG_LAND_AIDING`).
    pub const LAND: Self = Self {
        nhc: NhcConfig {
            enabled: true,
            ..NhcConfig::DEFAULT
        },
        zupt: ZuptConfig {
            enabled: true,
            ..ZuptConfig::DEFAULT
        },
        zaru: ZaruConfig {
            enabled: true,
            ..ZaruConfig::DEFAULT
        },
        ..Self::OFF
    };

    /// Whether any source is on.
    pub fn any_enabled(&self) -> bool {
        self.imu_epoch_sources() || self.heading.enabled
    }

    /// Whether any source that runs at the IMU epochs ([`Aiding::on_imu_with`]) is on.
    pub fn imu_epoch_sources(&self) -> bool {
        self.nhc.enabled || self.zupt.enabled || self.zaru.enabled || self.odometer.enabled
    }

    /// Checks every threshold and sigma; the error names the first bad field.
    pub fn validate(&self) -> Result<(), AidingConfigError> {
        use AidingConfigError::{NotFinite, NotNonNegative, NotPositive};
        let nonneg = |v: f64, n| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(NotNonNegative(n))
            }
        };
        let pos = |v: f64, n| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(NotPositive(n))
            }
        };
        let gate = |v: f64, n| {
            if v > 0.0 {
                Ok(())
            } else {
                Err(NotPositive(n))
            }
        };
        let s = &self.stationarity;
        nonneg(self.interval_s, "interval_s")?;
        pos(s.window_s, "stationarity.window_s")?;
        nonneg(s.accel_std_max_mps2, "stationarity.accel_std_max_mps2")?;
        nonneg(s.accel_mag_tol_mps2, "stationarity.accel_mag_tol_mps2")?;
        nonneg(s.gyro_mean_max_radps, "stationarity.gyro_mean_max")?;
        nonneg(s.gyro_std_max_radps, "stationarity.gyro_std_max")?;
        nonneg(s.gnss_speed_max_mps, "stationarity.gnss_speed_max_mps")?;
        nonneg(s.gnss_max_age_s, "stationarity.gnss_max_age_s")?;
        nonneg(s.filter_speed_max_mps, "stationarity.filter_speed_max_mps")?;
        pos(s.learn_margin, "stationarity.learn_margin")?;
        nonneg(s.learn_tau_s, "stationarity.learn_tau_s")?;
        nonneg(
            s.learn_accel_std_max_mps2,
            "stationarity.learn_accel_std_max_mps2",
        )?;
        nonneg(
            s.learn_gyro_std_max_radps,
            "stationarity.learn_gyro_std_max",
        )?;
        nonneg(
            s.learn_filter_speed_max_mps,
            "stationarity.learn_filter_speed_max_mps",
        )?;
        nonneg(
            self.nhc.slip_sigma_rad_per_mps2,
            "nhc.slip_sigma_deg_per_mps2",
        )?;
        pos(self.nhc.sigma_lateral_mps, "nhc.sigma_lateral_mps")?;
        pos(self.nhc.sigma_vertical_mps, "nhc.sigma_vertical_mps")?;
        nonneg(self.nhc.min_speed_mps, "nhc.min_speed_mps")?;
        if !self
            .nhc
            .mount_rpy_rad
            .iter()
            .chain(&self.nhc.lever_arm_m)
            .all(|v| v.is_finite())
        {
            return Err(NotFinite("nhc.mount_rpy / nhc.lever_arm_m"));
        }
        gate(self.nhc.nis_gate, "nhc.nis_gate")?;
        pos(self.zupt.sigma_mps, "zupt.sigma_mps")?;
        gate(self.zupt.nis_gate, "zupt.nis_gate")?;
        pos(self.zaru.sigma_radps, "zaru.sigma")?;
        gate(self.zaru.nis_gate, "zaru.nis_gate")?;
        pos(self.odometer.sigma_mps, "odometer.sigma_mps")?;
        if !self.odometer.lever_arm_m.iter().all(|v| v.is_finite()) {
            return Err(NotFinite("odometer.lever_arm_m"));
        }
        gate(self.odometer.nis_gate, "odometer.nis_gate")?;
        pos(self.heading.sigma_rad, "heading.sigma_deg")?;
        let b = self.heading.baseline_m;
        if !(b.iter().all(|v| v.is_finite()) && libm::hypot(b[0], b[1]) > 0.0) {
            return Err(NotFinite(
                "heading.baseline_m (finite, with a horizontal part)",
            ));
        }
        gate(self.heading.nis_gate, "heading.nis_gate")?;
        Ok(())
    }
}

/// Counts of one aiding source.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SourceCounters {
    /// Updates used.
    pub used: u32,
    /// Updates rejected by the source's chi-square gate.
    pub rejected: u32,
    /// Updates skipped by a numerical failure (innovation covariance not positive definite).
    pub failed: u32,
}

/// What the aiding did over a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AidingCounters {
    /// Aiding epochs at which the detector had a full window.
    pub epochs: u32,
    /// Of those, epochs declared stationary.
    pub stationary_epochs: u32,
    /// Non-holonomic constraint.
    pub nhc: SourceCounters,
    /// Zero-velocity update.
    pub zupt: SourceCounters,
    /// Zero-angular-rate update.
    pub zaru: SourceCounters,
    /// Odometer.
    pub odometer: SourceCounters,
    /// Dual-antenna heading (`failed` also counts samples refused for a nearly vertical
    /// baseline or a bad sigma).
    pub heading: SourceCounters,
}

/// The aiding runner: the stationarity detector (window of at most `W` IMU samples and the
/// vibration level learned at stops), the update timer and the counters.
#[derive(Debug, Clone)]
pub struct Aiding<T: Scalar, const W: usize> {
    cfg: AidingConfig,
    det: StationarityDetector<T, W>,
    rest: RestLevel<T>,
    last_t_s: f64,
    stationary: bool,
    counters: AidingCounters,
}

impl<T: Scalar, const W: usize> Aiding<T, W> {
    /// A runner for a validated configuration.
    pub fn new(cfg: &AidingConfig) -> Result<Self, AidingConfigError> {
        cfg.validate()?;
        Ok(Self {
            cfg: *cfg,
            det: StationarityDetector::new(),
            rest: RestLevel::new(),
            last_t_s: f64::NEG_INFINITY,
            stationary: false,
            counters: AidingCounters::default(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &AidingConfig {
        &self.cfg
    }

    /// The counters.
    pub fn counters(&self) -> &AidingCounters {
        &self.counters
    }

    /// The detector's last decision.
    pub fn is_stationary(&self) -> bool {
        self.stationary
    }

    /// The vibration level learned at stops (`[specific-force spread m/s^2, rate spread
    /// rad/s]`), once one was learned.
    pub fn rest_level(&self) -> Option<[f64; 2]> {
        self.rest.level()
    }

    /// Runs the aiding after a successful [`Filter::propagate`]: feeds the detector with the
    /// epoch's corrected specific force and rate and, every `interval_s`, decides stationarity
    /// and applies the enabled updates (ZUPT and ZARU when still, else the NHC when fast
    /// enough). `gnss_speed` is `(fix time s, speed m/s)` of the latest GNSS velocity, if any.
    /// A numerical failure of one update is counted (`failed`) and the others go on; the
    /// filter stays usable, so this never fails for a numerical reason.
    pub fn on_imu<const N: usize>(&mut self, f: &mut Filter<T, N>, gnss_speed: Option<(f64, f64)>) {
        self.on_imu_with(
            f,
            &AidingInputs {
                gnss_speed,
                odometer_speed_mps: None,
            },
        );
    }

    /// [`Self::on_imu`] with every input: also applies the odometer update at the aiding
    /// epochs when a speed is given (moving or still).
    pub fn on_imu_with<const N: usize>(&mut self, f: &mut Filter<T, N>, inputs: &AidingInputs) {
        let gnss_speed = inputs.gnss_speed;
        if !self.cfg.imu_epoch_sources() {
            return;
        }
        let step = *f.last_step();
        self.det
            .push(&step.f_body_mps2.into(), &step.omega_ib_body_radps.into());
        let nav = *f.nav_state();
        let t = nav.t_s;
        if t - self.last_t_s < self.cfg.interval_s - 0.5 * step.dt_s {
            return;
        }
        let since_last_s = t - self.last_t_s;
        self.last_t_s = t;
        let n = if step.dt_s > 0.0 {
            libm::round(self.cfg.stationarity.window_s / step.dt_s) as usize
        } else {
            0
        }
        .clamp(2, W.max(2));
        let Some(stats) = self.det.stats(n) else {
            self.stationary = false;
            return;
        };
        self.counters.epochs = self.counters.epochs.saturating_add(1);
        let speed = gnss_speed.and_then(|(ts, v)| {
            (t - ts <= self.cfg.stationarity.gnss_max_age_s && t - ts >= -1.0).then_some(v)
        });
        let g = earth::gravity_mps2(nav.pos.lat_rad, nav.pos.h_m);
        let (cfg_s, filter_speed) = (&self.cfg.stationarity, nav.vel_ned_mps.norm());
        self.rest
            .learn(cfg_s, &stats, g, speed, filter_speed, since_last_s);
        self.stationary = self
            .rest
            .is_stationary(cfg_s, &stats, g, speed, filter_speed);
        let layout = *f.layout();
        if let (true, Some(speed)) = (self.cfg.odometer.enabled, inputs.odometer_speed_mps) {
            let k = f
                .block_estimate(BlockKind::OdometerScale)
                .and_then(|e| e.first().copied())
                .unwrap_or(0.0);
            let m = odometer::odometer_measurement::<T, N>(
                &self.cfg.odometer,
                &self.cfg.nhc.c_vb(),
                &layout,
                k,
                f.nav_state(),
                &step,
                speed,
            );
            let res = f.update_aiding(&m.z_mps, &m.h, &m.r, self.cfg.odometer.nis_gate);
            count(&mut self.counters.odometer, res);
        }
        if self.stationary {
            self.counters.stationary_epochs = self.counters.stationary_epochs.saturating_add(1);
            if self.cfg.zupt.enabled {
                let (z, h, r) = zupt::zupt_measurement::<T, N>(&self.cfg.zupt, f.nav_state());
                let res = f.update_aiding(&z, &h, &r, self.cfg.zupt.nis_gate);
                count(&mut self.counters.zupt, res);
            }
            // the zero-rate update only at a quiet stop (rate spread within the fixed
            // threshold): an idling engine's vibration shifts the window-mean rate of a MEMS
            // gyro (vibration rectification), which a ZARU would take for gyro bias; the
            // zero-velocity update holds at every stop
            let quiet = stats.w_std_radps <= self.cfg.stationarity.gyro_std_max_radps;
            if self.cfg.zaru.enabled && quiet {
                if let Some((z, h, r)) = zupt::zaru_measurement::<T, N>(
                    &self.cfg.zaru,
                    &layout,
                    f.nav_state(),
                    &stats.w_mean_radps,
                ) {
                    let res = f.update_aiding(&z, &h, &r, self.cfg.zaru.nis_gate);
                    count(&mut self.counters.zaru, res);
                }
            }
        } else if nhc::nhc_applies(&self.cfg.nhc, f.nav_state(), false) {
            let m = nhc::nhc_measurement::<T, N>(&self.cfg.nhc, &layout, f.nav_state(), &step);
            let res = f.update_aiding(&m.z_mps, &m.h, &m.r, self.cfg.nhc.nis_gate);
            count(&mut self.counters.nhc, res);
        }
    }
}

impl<T: Scalar, const W: usize> Aiding<T, W> {
    /// Applies a dual-antenna heading sample (azimuth of the configured baseline from north,
    /// clockwise, rad; its 1-sigma, rad, or the configured one): call it at the IMU epoch
    /// nearest the sample's time, after [`Filter::propagate`]. Gated by the source's
    /// chi-square gate (an outlier is rejected and counted). `None` (and nothing done) when
    /// the source is off; a refused sample (nearly vertical baseline, bad sigma) or a
    /// numerical failure is counted as `failed` and also gives `None`.
    pub fn on_heading<const N: usize>(
        &mut self,
        f: &mut Filter<T, N>,
        heading_rad: f64,
        sigma_rad: Option<f64>,
    ) -> Option<AidingOutcome> {
        if !self.cfg.heading.enabled {
            return None;
        }
        let c = &mut self.counters.heading;
        let Some(m) = heading::heading_measurement::<T, N>(
            &self.cfg.heading,
            f.nav_state(),
            heading_rad,
            sigma_rad,
        ) else {
            c.failed = c.failed.saturating_add(1);
            return None;
        };
        let res = f.update_aiding(&m.z_rad, &m.h, &m.r, self.cfg.heading.nis_gate);
        let out = res.as_ref().ok().copied();
        count(c, res);
        out
    }
}

fn count(c: &mut SourceCounters, res: Result<crate::filter::AidingOutcome, FilterError>) {
    match res {
        Ok(o) if o.accepted => c.used = c.used.saturating_add(1),
        Ok(_) => c.rejected = c.rejected.saturating_add(1),
        Err(_) => c.failed = c.failed.saturating_add(1),
    }
}
