//! Drives with one undeclared effect, written in the KF-GINS formats with a `kf-gins.yaml` that
//! declares only KF-GINS's 21-state model (the robust-gating drives, reused by the
//! diagnosis tests).
//!
//! What a drive is:
//!
//! - a land-vehicle scenario of `minutes` at `rate_hz` ([`drive_scenario`]): static start,
//!   accelerations, braking to stops, left and right turns at 10-25 deg/s with a net rotation
//!   of several full circles (so a gyro scale factor shows in the heading), hills; the truth is
//!   integrated with RK4 at `rate_hz * substeps` (default 8 substeps, 1.6 kHz at 200 Hz);
//! - the declared sensor: the source's tactical IMU (accelerometer white 8.1 ug/sqrt(Hz),
//!   Gauss-Markov 2.4 ug / 45 s, random walk 10 ug/sqrt(h), turn-on 50 ug; gyro white
//!   0.079 deg/sqrt(h), Gauss-Markov 0.05 deg/h / 1 h, turn-on 0.1 deg/h), quantized
//!   (1e-6 m/s, 1e-8 rad), with RTK-like GNSS (white 1/1/2 cm plus a 5 mm / 60 s Gauss-Markov
//!   error the YAML does not declare), fixes at 1 Hz and 60 s outages every 120 s
//!   ([`drive_outages`]);
//! - one undeclared effect ([`Effect`]) drawn per seed inside realistic ranges
//!   (random signs per axis), optionally a second one ([`DriveSpec::second`]) and one outside
//!   the diagnosis vocabulary ([`OutsideEffect`]: GNSS multipath jumps);
//! - a `kf-gins.yaml` ([`kf_gins_config`]) as a KF-GINS user writes it: the
//!   noise of the declared sensor in KF-GINS's keys, scale-factor sigmas of zero, the lever arm
//!   the user believes (zero for the lever-arm drive while the antenna is 1.5 m away), and an
//!   initial state drawn around the truth with the declared initial standard deviations.
//!
//! The generator does not share the filter's assumptions where it can avoid it: the truth is
//! integrated at a higher rate than the filter's mechanization, the GNSS error has a
//! correlated part the configuration does not declare, the accelerometer bias has a random
//! walk KF-GINS's single Gauss-Markov state does not represent, the outputs are quantized, and
//! the effect itself is outside the declared model.

use crate::case::{simulate, Case, SimError};
use crate::errors::{
    stream, Axes3, ErrorModel, GnssErrors, Outage, SensorErrors, Temperature, DEG_PER_H_RADPS,
    UG_MPS2,
};
use crate::scenario::{ImuRate, Scenario, Segment, Start, Vehicle};
use nav_io::{write_kf_gins_yaml, KfGinsConfig, KfGinsImuNoiseYaml};
use rand::Rng;
use std::collections::BTreeMap;
use std::path::Path;

/// An effect that the KF-GINS configuration of a drive does not declare.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Effect {
    /// Gyro scale factor, 300-1000 ppm per axis.
    GyroScaleFactor,
    /// Accelerometer scale factor, 500-1500 ppm per axis.
    AccelScaleFactor,
    /// Accelerometer misalignment / non-orthogonality, 100-400 urad per off-diagonal element.
    AccelMisalignment,
    /// Accelerometer bias temperature coefficient, 25-60 ug/degC per axis, over a 20 degC
    /// warm-up (time constant a third of the drive).
    AccelTemperature,
    /// GNSS antenna 1.5 m from the IMU while the configuration says 0.
    LeverArm,
    /// GNSS time tags 50-100 ms late.
    TimeOffset,
    /// IMU clock running 30-80 ppm fast or slow: the GNSS-IMU time offset grows by
    /// 30-80 us per s (0.07-0.19 s over 40 minutes).
    ImuClockDrift,
    /// GNSS position errors larger than declared: the white noise 2-4 times the reported
    /// standard deviations and a time-correlated (Gauss-Markov) error of 5-15 cm per axis with
    /// a 100-300 s correlation time (the declared drive has 5 mm / 60 s).
    GnssCorrelatedError,
    /// Accelerometer bias step of 2-4 mg along a random horizontal body axis (random sign) at
    /// [`bias_step_time_s`].
    AccelBiasStep,
    /// Gyro bias step of 20-50 deg/h about a random body axis (random sign) at
    /// [`bias_step_time_s`].
    GyroBiasStep,
    /// Gyro bias temperature coefficient, 0.3-0.6 deg/h/degC per axis, over a 20 degC warm-up
    /// (time constant a third of the drive): 6-12 deg/h by the end.
    GyroTemperature,
    /// Gyro g-sensitivity, 10-30 deg/h/g per axis on the diagonal (each gyro sensing the
    /// specific force along its own axis): on the vertical gyro a constant bias (f_z = -g),
    /// on the horizontal ones a bias while the car accelerates, brakes and turns.
    GyroGSensitivity,
    /// GNSS standard deviations understated: the fixes' white noise 3-8 times the reported
    /// sigmas (the same factor on every axis), nothing else changed.
    GnssWhiteNoise,
}

impl Effect {
    /// Every effect: the sensor and installation effects first, then the clock, GNSS and
    /// bias-step effects.
    pub const ALL: [Effect; 13] = [
        Effect::GyroScaleFactor,
        Effect::AccelScaleFactor,
        Effect::AccelMisalignment,
        Effect::AccelTemperature,
        Effect::LeverArm,
        Effect::TimeOffset,
        Effect::ImuClockDrift,
        Effect::GnssCorrelatedError,
        Effect::AccelBiasStep,
        Effect::GyroBiasStep,
        Effect::GyroTemperature,
        Effect::GyroGSensitivity,
        Effect::GnssWhiteNoise,
    ];

    /// The name of the effect in the diagnosis vocabulary: the effect block that models it
    /// (`nav_core::model::Block::effect_from_name`; the scale factors are KF-GINS's own
    /// states, declared with a sigma of zero in the YAML), for a bias step, which is not a
    /// state, the change point the diagnosis reports
    /// (`nav_diagnose::changepoint::BiasStepSensor::name`), and for understated GNSS sigmas
    /// the noise model's GNSS sigma scale ([`GNSS_SIGMA_SCALE`]).
    pub const fn block_name(self) -> &'static str {
        match self {
            Effect::GyroScaleFactor => "gyro_scale_factor",
            Effect::AccelScaleFactor => "accel_scale_factor",
            Effect::AccelMisalignment => "accel_misalignment",
            Effect::AccelTemperature => "accel_temperature_bias",
            Effect::LeverArm => "lever_arm",
            Effect::TimeOffset => "time_offset",
            Effect::ImuClockDrift => "imu_clock_drift",
            Effect::GnssCorrelatedError => "gnss_position_gm",
            Effect::AccelBiasStep => "accel_bias_step",
            Effect::GyroBiasStep => "gyro_bias_step",
            Effect::GyroTemperature => "gyro_temperature_bias",
            Effect::GyroGSensitivity => "gyro_g_sensitivity",
            Effect::GnssWhiteNoise => GNSS_SIGMA_SCALE,
        }
    }

    /// A short description of the magnitude range, for reports.
    pub const fn range(self) -> &'static str {
        match self {
            Effect::GyroScaleFactor => "gyro scale factor 300-1000 ppm",
            Effect::AccelScaleFactor => "accel scale factor 500-1500 ppm",
            Effect::AccelMisalignment => "accel misalignment 100-400 urad",
            Effect::AccelTemperature => {
                "accel temperature coefficient 25-60 ug/degC, 20 degC warm-up"
            }
            Effect::LeverArm => "undeclared lever arm 1.5 m",
            Effect::TimeOffset => "GNSS-IMU time offset 50-100 ms",
            Effect::ImuClockDrift => "IMU clock drift 30-80 ppm",
            Effect::GnssCorrelatedError => {
                "GNSS white noise 2-4x declared, Gauss-Markov 5-15 cm / 100-300 s"
            }
            Effect::AccelBiasStep => "accelerometer bias step 2-4 mg",
            Effect::GyroBiasStep => "gyro bias step 20-50 deg/h",
            Effect::GyroTemperature => {
                "gyro temperature coefficient 0.3-0.6 deg/h/degC, 20 degC warm-up"
            }
            Effect::GyroGSensitivity => "gyro g-sensitivity 10-30 deg/h/g",
            Effect::GnssWhiteNoise => "GNSS white noise 3-8x the reported sigmas",
        }
    }
}

/// The name of the GNSS noise scale, the noise-model parameter that models understated GNSS
/// sigmas ([`Effect::GnssWhiteNoise`]): the `[gnss] sigma_scale` of a run configuration.
pub const GNSS_SIGMA_SCALE: &str = "gnss_sigma_scale";

impl core::fmt::Display for Effect {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.block_name())
    }
}

/// An undeclared effect OUTSIDE the diagnosis vocabulary: no effect block of the error-state
/// model and no change point models it, so a diagnosis should name nothing for it (or only
/// what its own estimate supports) and must not make the held-out predictions worse.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum OutsideEffect {
    /// GNSS multipath: position jumps of 0.3-1 m (a random 3D direction) lasting 20-60 s
    /// each, one per started 3 minutes of the drive (at least two), at random times after the
    /// static start, the fixes' reported standard deviations unchanged ([`multipath_jumps`]).
    GnssMultipath,
}

impl OutsideEffect {
    /// A short name for reports: `gnss_multipath` (not a block of the vocabulary).
    pub const fn name(self) -> &'static str {
        match self {
            OutsideEffect::GnssMultipath => "gnss_multipath",
        }
    }

    /// A short description of the magnitude range, for reports.
    pub const fn range(self) -> &'static str {
        match self {
            OutsideEffect::GnssMultipath => "GNSS multipath jumps 0.3-1 m lasting 20-60 s",
        }
    }
}

impl core::fmt::Display for OutsideEffect {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// One GNSS multipath jump of a drive ([`OutsideEffect::GnssMultipath`]): every fix in
/// `[start_s, start_s + duration_s)` is displaced by `offset_ned_m`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultipathJump {
    /// Start, s after the first IMU epoch.
    pub start_s: f64,
    /// Duration, s.
    pub duration_s: f64,
    /// Position error added to the fixes, north/east/down, m.
    pub offset_ned_m: [f64; 3],
}

/// The multipath jumps of a drive of `duration_s` for `seed`: one per started 180 s (at
/// least two), each 20-60 s long, starting uniformly between the end of the static start and
/// 60 s before the end, 0.3-1 m in a direction uniform on the sphere (jumps may overlap: their
/// offsets add).
pub fn multipath_jumps(duration_s: f64, seed: u64) -> Vec<MultipathJump> {
    let mut rng = stream(seed, DRIVE_STREAMS, 3, 0);
    let n = ((duration_s / 180.0).ceil() as usize).max(2);
    let lo = STATIC_START_S;
    let hi = (duration_s - 60.0).max(lo + 1.0);
    (0..n)
        .map(|_| {
            let start_s = lo + (hi - lo) * rng.random::<f64>();
            let duration_s = 20.0 + 40.0 * rng.random::<f64>();
            let m = 0.3 + 0.7 * rng.random::<f64>();
            let z: f64 = 2.0 * rng.random::<f64>() - 1.0;
            let az = std::f64::consts::TAU * rng.random::<f64>();
            let r = (1.0 - z * z).max(0.0).sqrt();
            MultipathJump {
                start_s,
                duration_s,
                offset_ned_m: [m * r * az.cos(), m * r * az.sin(), m * z],
            }
        })
        .collect()
}

/// Adds the jumps to the fixes of `case` (their times relative to its first IMU epoch).
fn apply_multipath(case: &mut Case, jumps: &[MultipathJump]) {
    let t0 = case.trajectory.t0_s;
    for f in &mut case.meas.gnss {
        let t = f.t_s - t0;
        let mut d = [0.0; 3];
        for j in jumps
            .iter()
            .filter(|j| j.start_s <= t && t < j.start_s + j.duration_s)
        {
            for (a, b) in d.iter_mut().zip(&j.offset_ned_m) {
                *a += b;
            }
        }
        if d != [0.0; 3] {
            let p = nav_core::earth::displace(
                &nav_core::earth::Llh {
                    lat_rad: f.lat_rad,
                    lon_rad: f.lon_rad,
                    h_m: f.h_m,
                },
                &nalgebra::Vector3::from(d),
            );
            f.lat_rad = p.lat_rad;
            f.lon_rad = p.lon_rad;
            f.h_m = p.h_m;
        }
    }
}

/// Parameters of a drive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveSpec {
    /// The undeclared effect (`None`: the declared model is complete).
    pub effect: Option<Effect>,
    /// A second undeclared effect of the vocabulary (`None`: one effect at most). Its
    /// magnitudes come from their own random stream, so `effect` is drawn as without it.
    pub second: Option<Effect>,
    /// An undeclared effect outside the diagnosis vocabulary ([`OutsideEffect`]).
    pub outside: Option<OutsideEffect>,
    /// Duration, minutes (at least 4).
    pub minutes: f64,
    /// IMU rate, Hz.
    pub rate_hz: f64,
    /// RK4 substeps per IMU interval of the truth integration.
    pub substeps: u32,
    /// Seed of the effect magnitudes, the sensor errors and the initial-state errors.
    pub seed: u64,
    /// The GNSS file's gaps: `None` the periodic outages of [`drive_outages`]; `Some(n)`: `n`
    /// gaps of [`OUTAGE_S`] spread over the drive ([`spread_gaps`], not on fix epochs).
    pub file_gaps: Option<usize>,
    /// The size of the GNSS correlated error when [`Effect::GnssCorrelatedError`] is one of
    /// the drive's effects (`None`: the effect's own ranges, 5-15 cm with white noise 2-4x).
    pub gnss_error_size: Option<GnssErrorSize>,
}

/// The size of a drive's GNSS correlated error ([`Effect::GnssCorrelatedError`]) other than
/// the effect's own: the per-axis Gauss-Markov sigmas and the white-noise factor drawn for the
/// seed as for the effect, then rescaled, so that one seed keeps its realisation (its draws,
/// its correlation time of 100-300 s) across sizes. A single-point or SBAS receiver has errors
/// of 0.3-1 m correlated over minutes; the effect's own size (5-15 cm) is an RTK float's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssErrorSize {
    /// Centre of the Gauss-Markov sigma, m: each axis gets `[0.5, 1.5]` times it (0.1 m is
    /// the effect's own 5-15 cm).
    pub gm_sigma_m: f64,
    /// The white noise as a multiple of the reported standard deviations, the same on every
    /// axis (`None`: the effect's own draw, 2-4).
    pub white_factor: Option<f64>,
}

impl GnssErrorSize {
    /// Centre of the Gauss-Markov sigma of [`Effect::GnssCorrelatedError`]'s own range, m.
    pub const OWN_GM_SIGMA_M: f64 = 0.1;

    /// Rescales the GNSS correlated error drawn by [`add_effect`] in `m` to this size.
    pub fn apply(&self, m: &mut ErrorModel) {
        let k = self.gm_sigma_m / Self::OWN_GM_SIGMA_M;
        m.gnss.gm_sigma_ned_m = Axes3(m.gnss.gm_sigma_ned_m.0.map(|s| s * k));
        if let Some(w) = self.white_factor {
            m.gnss.white_sigma_ned_m = Axes3(m.gnss.reported_std().map(|s| s * w));
        }
    }
}

impl DriveSpec {
    /// A 10-minute 200 Hz drive (4 outages) with `effect`, 8 substeps, seed 13, no second
    /// effect and none outside the vocabulary.
    pub fn new(effect: Option<Effect>) -> Self {
        Self {
            effect,
            second: None,
            outside: None,
            minutes: 10.0,
            rate_hz: 200.0,
            substeps: 8,
            seed: 13,
            file_gaps: None,
            gnss_error_size: None,
        }
    }
}

/// GPS week of the drives.
pub const GPS_WEEK: u16 = 2200;
/// GPS seconds of week of the first IMU epoch.
pub const START_SOW: f64 = 300_000.0;
/// Static time at the start, s (the vehicle stands while the filter settles).
pub const STATIC_START_S: f64 = 30.0;
/// Duration of each GNSS outage, s.
pub const OUTAGE_S: f64 = 60.0;
/// True antenna position of the lever-arm drive, body FRD, m (1.49 m from the IMU; the
/// configuration says zero).
pub const LEVER_ARM_TRUE_M: [f64; 3] = [1.2, -0.6, -0.65];

/// The motion of a drive of `minutes` at `rate_hz` (RK4 `substeps` per IMU interval): 30 s
/// static, then a repeated block of accelerations, turns both ways (net +360 deg per block),
/// a hill, braking to a stop with a 5 s halt; ends with a stop and 10 s static.
pub fn drive_scenario(minutes: f64, rate_hz: f64, substeps: u32) -> Scenario {
    let target_s = minutes * 60.0;
    let turn = |angle_deg: f64, rate_deg_s: f64| Segment::Turn {
        angle_deg,
        rate_deg_s: Some(rate_deg_s),
        radius_m: None,
        ramp_s: Some(1.5),
    };
    let block: Vec<Segment> = vec![
        Segment::Accelerate {
            delta_speed_mps: None,
            to_speed_mps: Some(12.0),
            duration_s: 8.0,
        },
        Segment::Cruise { duration_s: 10.0 },
        turn(180.0, 18.0),
        Segment::Cruise { duration_s: 8.0 },
        Segment::Hill {
            height_m: 6.0,
            length_m: 150.0,
            ramp_s: None,
        },
        turn(-90.0, 12.0),
        Segment::Accelerate {
            delta_speed_mps: None,
            to_speed_mps: Some(16.0),
            duration_s: 6.0,
        },
        Segment::Cruise { duration_s: 8.0 },
        turn(270.0, 22.0),
        Segment::Brake {
            delta_speed_mps: None,
            to_speed_mps: Some(8.0),
            duration_s: 5.0,
        },
        turn(-120.0, 25.0),
        Segment::Cruise { duration_s: 6.0 },
        turn(200.0, 20.0),
        Segment::Hill {
            height_m: -6.0,
            length_m: 120.0,
            ramp_s: None,
        },
        turn(-60.0, 10.0),
        Segment::Stop {
            duration_s: Some(6.0),
        },
        Segment::Static { duration_s: 5.0 },
    ];
    let mut segments = vec![Segment::Static {
        duration_s: STATIC_START_S,
    }];
    let mut sc = Scenario {
        name: "undeclared-drive".into(),
        description: format!("{minutes} min land-vehicle drive for the undeclared-effect tests"),
        start: Start {
            lat_deg: 48.2,
            lon_deg: 16.37,
            h_m: 180.0,
            heading_deg: 30.0,
            gps_week: GPS_WEEK,
            sow_s: START_SOW,
        },
        imu: ImuRate { rate_hz, substeps },
        vehicle: Vehicle::default(),
        segments: Vec::new(),
    };
    // append whole segments of the block (cycling) until the target length minus the tail
    let mut i = 0usize;
    loop {
        sc.segments.clone_from(&segments);
        let d = sc.compile().map(|p| p.duration_s).unwrap_or(0.0);
        if d + 20.0 >= target_s || i > 10_000 {
            break;
        }
        segments.push(block[i % block.len()].clone());
        i += 1;
    }
    // finish: stop when moving, then stand still
    let moving = !matches!(
        segments.last(),
        Some(Segment::Static { .. }) | Some(Segment::Stop { .. })
    );
    if moving {
        segments.push(Segment::Stop {
            duration_s: Some(6.0),
        });
    }
    if !matches!(segments.last(), Some(Segment::Static { .. })) {
        segments.push(Segment::Static { duration_s: 10.0 });
    }
    sc.segments = segments;
    sc
}

/// Period of the GNSS outages, s (60 s of GNSS between two outages).
pub const OUTAGE_PERIOD_S: f64 = 120.0;

/// The GNSS outages of a drive of `duration_s`: 60 s each, the first at 120 s, then every
/// 120 s while an outage ends at least 30 s before the end (4 outages in 10 minutes).
pub fn drive_outages(duration_s: f64) -> Vec<Outage> {
    let mut v = Vec::new();
    let mut s = OUTAGE_PERIOD_S;
    while s + OUTAGE_S + 30.0 <= duration_s {
        v.push(Outage {
            start_s: s,
            duration_s: OUTAGE_S,
        });
        s += OUTAGE_PERIOD_S;
    }
    v
}

/// `n` GNSS gaps of [`OUTAGE_S`] for a drive of `duration_s`: centred at `k / (n + 1)` of the
/// drive (k = 1..n), each starting 0.37 s after a whole second (between the 1 Hz fix epochs).
pub fn spread_gaps(duration_s: f64, n: usize) -> Vec<Outage> {
    (1..=n)
        .map(|k| Outage {
            start_s: (duration_s * k as f64 / (n + 1) as f64 - 0.5 * OUTAGE_S).floor() + 0.37,
            duration_s: OUTAGE_S,
        })
        .collect()
}

/// The declared sensor and GNSS (no undeclared effect): see the module documentation.
pub fn declared_error_model(duration_s: f64) -> ErrorModel {
    let accel = SensorErrors {
        white_psd: Axes3::splat(6.2865e-9),
        gm_psd: Axes3::splat(2.4360e-11),
        gm_tau_s: Axes3::splat(45.0),
        rw_psd: Axes3::splat(2.6731e-12),
        turn_on_bias_sigma: Axes3::splat(50.0 * UG_MPS2),
        quantization_step: Axes3::splat(1e-6),
        ..SensorErrors::default()
    };
    let gyro_gm_sigma = 0.05 * DEG_PER_H_RADPS;
    let gyro = SensorErrors {
        white_psd: Axes3::splat(5.3079e-10),
        gm_psd: Axes3::splat(2.0 * gyro_gm_sigma * gyro_gm_sigma / 3600.0),
        gm_tau_s: Axes3::splat(3600.0),
        turn_on_bias_sigma: Axes3::splat(0.1 * DEG_PER_H_RADPS),
        quantization_step: Axes3::splat(1e-8),
        ..SensorErrors::default()
    };
    ErrorModel {
        name: "undeclared-drive declared sensor".into(),
        accel,
        gyro,
        temperature: None,
        imu_clock_drift_ppm: 0.0,
        gnss: GnssErrors {
            rate_hz: 1.0,
            white_sigma_ned_m: Axes3([0.01, 0.01, 0.02]),
            gm_sigma_ned_m: Axes3::splat(0.005),
            gm_tau_s: 60.0,
            reported_std_ned_m: Some(Axes3([0.01, 0.01, 0.02])),
            outages: drive_outages(duration_s),
            ..GnssErrors::default()
        },
    }
}

/// Time of the bias step of a drive of `duration_s`: 15 s into the GNSS window (between two
/// outages, [`drive_outages`]) that follows the middle of the drive.
pub fn bias_step_time_s(duration_s: f64) -> f64 {
    let k = (0.5 * duration_s / OUTAGE_PERIOD_S).floor();
    k * OUTAGE_PERIOD_S + OUTAGE_S + 15.0
}

/// Sensor/source id of the drive's own random streams (effect magnitudes, initial errors),
/// distinct from those of [`ErrorModel::apply`].
const DRIVE_STREAMS: u64 = 13;

/// A uniform draw in `[lo, hi]` with a random sign.
fn signed(rng: &mut impl Rng, lo: f64, hi: f64) -> f64 {
    let m = lo + (hi - lo) * rng.random::<f64>();
    if rng.random::<bool>() {
        m
    } else {
        -m
    }
}

/// Adds `effect` to `m` with magnitudes drawn from `seed` inside the realistic ranges.
pub fn add_effect(m: &mut ErrorModel, effect: Effect, seed: u64, duration_s: f64) {
    let mut rng = stream(seed, DRIVE_STREAMS, 1, effect as u64);
    match effect {
        Effect::GyroScaleFactor => {
            m.gyro.scale_factor_ppm = Axes3([0; 3].map(|_| signed(&mut rng, 300.0, 1000.0)));
        }
        Effect::AccelScaleFactor => {
            m.accel.scale_factor_ppm = Axes3([0; 3].map(|_| signed(&mut rng, 500.0, 1500.0)));
        }
        Effect::AccelMisalignment => {
            for i in 0..3 {
                for j in 0..3 {
                    if i != j {
                        m.accel.misalignment_rad[i][j] = signed(&mut rng, 100e-6, 400e-6);
                    }
                }
            }
        }
        Effect::AccelTemperature => {
            m.accel.temp_coeff_per_c =
                Axes3([0; 3].map(|_| signed(&mut rng, 25.0, 60.0) * UG_MPS2));
            m.temperature = Some(warm_up(duration_s));
        }
        Effect::LeverArm => m.gnss.lever_arm_b_m = Axes3(LEVER_ARM_TRUE_M),
        Effect::TimeOffset => m.gnss.time_offset_s = 0.05 + 0.05 * rng.random::<f64>(),
        Effect::ImuClockDrift => m.imu_clock_drift_ppm = signed(&mut rng, 30.0, 80.0),
        Effect::GnssCorrelatedError => {
            let white = 2.0 + 2.0 * rng.random::<f64>();
            let reported = m.gnss.reported_std();
            m.gnss.reported_std_ned_m = Some(Axes3(reported));
            m.gnss.white_sigma_ned_m = Axes3(reported.map(|s| s * white));
            m.gnss.gm_sigma_ned_m = Axes3([0; 3].map(|_| 0.05 + 0.1 * rng.random::<f64>()));
            m.gnss.gm_tau_s = 100.0 + 200.0 * rng.random::<f64>();
        }
        Effect::AccelBiasStep => {
            let mut step = [0.0; 3];
            let axis = usize::from(rng.random::<bool>());
            step[axis] = signed(&mut rng, 2000.0, 4000.0) * UG_MPS2;
            m.accel.bias_step = Axes3(step);
            m.accel.bias_step_at_s = bias_step_time_s(duration_s);
        }
        Effect::GyroBiasStep => {
            let mut step = [0.0; 3];
            let axis = rng.random_range(0..3usize);
            step[axis] = signed(&mut rng, 20.0, 50.0) * DEG_PER_H_RADPS;
            m.gyro.bias_step = Axes3(step);
            m.gyro.bias_step_at_s = bias_step_time_s(duration_s);
        }
        Effect::GyroTemperature => {
            m.gyro.temp_coeff_per_c =
                Axes3([0; 3].map(|_| signed(&mut rng, 0.3, 0.6) * DEG_PER_H_RADPS));
            m.temperature = Some(warm_up(duration_s));
        }
        Effect::GyroGSensitivity => {
            let per_g = DEG_PER_H_RADPS / nav_core::earth::G0_MPS2;
            for i in 0..3 {
                m.gyro.g_sensitivity_radps_per_mps2[i][i] = signed(&mut rng, 10.0, 30.0) * per_g;
            }
        }
        Effect::GnssWhiteNoise => {
            let white = 3.0 + 5.0 * rng.random::<f64>();
            let reported = m.gnss.reported_std();
            m.gnss.reported_std_ned_m = Some(Axes3(reported));
            m.gnss.white_sigma_ned_m = Axes3(reported.map(|s| s * white));
        }
    }
}

/// The temperature profile of the temperature effects: 20 degC rising by 20 degC with a time
/// constant of a third of the drive.
fn warm_up(duration_s: f64) -> Temperature {
    Temperature {
        start_c: 20.0,
        rise_c: 20.0,
        tau_s: duration_s / 3.0,
        reference_c: None,
        report_noise_c: 0.01,
    }
}

/// A generated drive: the simulated case and what its configuration declares.
#[derive(Debug, Clone)]
pub struct UndeclaredDrive {
    /// The drive's parameters.
    pub spec: DriveSpec,
    /// Truth, measurements and the complete error model (with the effect).
    pub case: Case,
    /// The KF-GINS configuration (paths relative to the drive's folder).
    pub config: KfGinsConfig,
    /// The multipath jumps added to the fixes ([`OutsideEffect::GnssMultipath`]; empty
    /// otherwise). They are not part of the error model (`case.errors`) nor of `case.toml`.
    pub multipath: Vec<MultipathJump>,
}

/// Generates a drive (truth, IMU, GNSS, configuration) in memory.
pub fn generate(spec: &DriveSpec) -> Result<UndeclaredDrive, SimError> {
    let scenario = drive_scenario(spec.minutes, spec.rate_hz, spec.substeps);
    let duration_s = scenario.duration_s()?;
    let mut errors = declared_error_model(duration_s);
    if let Some(n) = spec.file_gaps {
        errors.gnss.outages = spread_gaps(duration_s, n);
    }
    for e in spec.effect.iter().chain(&spec.second) {
        add_effect(&mut errors, *e, spec.seed, duration_s);
        if let (Effect::GnssCorrelatedError, Some(size)) = (e, spec.gnss_error_size) {
            size.apply(&mut errors);
        }
    }
    let mut what: Vec<&str> = spec
        .effect
        .iter()
        .chain(&spec.second)
        .map(|e| e.range())
        .collect();
    what.extend(spec.outside.map(|o| o.range()));
    errors.name = if what.is_empty() {
        "declared model only".into()
    } else {
        format!("undeclared {}", what.join(" and "))
    };
    let mut case = simulate(&scenario, &errors, spec.seed)?;
    let multipath = match spec.outside {
        Some(OutsideEffect::GnssMultipath) => multipath_jumps(duration_s, spec.seed),
        None => Vec::new(),
    };
    apply_multipath(&mut case, &multipath);
    let config = kf_gins_config(&case, spec.seed);
    Ok(UndeclaredDrive {
        spec: *spec,
        case,
        config,
        multipath,
    })
}

/// The configuration a KF-GINS user writes for the declared sensor of `case`: 21 states,
/// scale-factor sigmas of zero, lever arm zero (the antenna is not declared), the initial
/// state = truth plus errors drawn from the declared initial standard deviations.
pub fn kf_gins_config(case: &Case, seed: u64) -> KfGinsConfig {
    let tr = &case.trajectory;
    let s0 = tr.truth.first().copied().unwrap_or_default();
    let mut rng = stream(seed, DRIVE_STREAMS, 2, 0);
    let mut g =
        || -> f64 { rand_distr::Distribution::sample(&rand_distr::StandardNormal, &mut rng) };
    let pos_std = [0.02, 0.02, 0.03];
    let vel_std = [0.01, 0.01, 0.01];
    let att_std_deg = [0.02, 0.02, 0.3];
    let dn = [
        g() * pos_std[0] * 0.5,
        g() * pos_std[1] * 0.5,
        g() * pos_std[2] * 0.5,
    ];
    let p0 = nav_core::earth::displace(
        &nav_core::earth::Llh {
            lat_rad: s0.lat_rad,
            lon_rad: s0.lon_rad,
            h_m: s0.h_m,
        },
        &nalgebra::Vector3::from(dn),
    );
    let v0 = [0, 1, 2].map(|i| s0.vel_ned_mps[i] + 0.5 * vel_std[i] * g());
    let rpy = [0, 1, 2].map(|i| s0.rpy_rad[i].to_degrees() + 0.5 * att_std_deg[i] * g());
    // the declared sensor in KF-GINS's keys: one Gauss-Markov bias per axis with a 1 h
    // correlation time; the accelerometer's 45 s Gauss-Markov and random walk (grown over
    // the correlation time) folded into abstd; the turn-on biases in the initial stds
    let acc_gm_var: f64 = 0.5 * 2.4360e-11 * 45.0 + 2.6731e-12 * 3600.0;
    let abstd_mgal = acc_gm_var.sqrt() / 1e-5;
    let gbstd_dph = 0.05;
    let init_ba = ((50.0 * UG_MPS2).powi(2) + acc_gm_var).sqrt() / 1e-5;
    let init_bg = (0.1f64.powi(2) + gbstd_dph * gbstd_dph).sqrt();
    let imudatalen = if case.errors.temperature.is_some() {
        8
    } else {
        7
    };
    KfGinsConfig {
        imupath: "imu.txt".into(),
        gnsspath: "gnss.txt".into(),
        outputpath: "kf-gins-out".into(),
        imudatalen,
        imudatarate: tr.scenario.imu.rate_hz.round() as u32,
        starttime: tr.t0_s,
        endtime: -1.0,
        initpos: [p0.lat_rad.to_degrees(), p0.lon_rad.to_degrees(), p0.h_m],
        initvel: v0,
        initatt: [rpy[0], rpy[1], rpy[2].rem_euclid(360.0)],
        initgyrbias: [0.0; 3],
        initaccbias: [0.0; 3],
        initgyrscale: [0.0; 3],
        initaccscale: [0.0; 3],
        initposstd: pos_std,
        initvelstd: vel_std,
        initattstd: att_std_deg,
        initbgstd: Some([init_bg; 3]),
        initbastd: Some([init_ba; 3]),
        initsgstd: Some([0.0; 3]),
        initsastd: Some([0.0; 3]),
        imunoise: KfGinsImuNoiseYaml {
            arw: [5.3079e-10f64.sqrt().to_degrees() * 60.0; 3],
            vrw: [6.2865e-9f64.sqrt() * 60.0; 3],
            gbstd: [gbstd_dph; 3],
            abstd: [abstd_mgal; 3],
            gsstd: [0.0; 3],
            asstd: [0.0; 3],
            corrtime: 1.0,
        },
        antlever: [0.0; 3],
        unknown_keys: BTreeMap::new(),
    }
}

impl UndeclaredDrive {
    /// Writes the drive into `dir` (created if needed): `imu.txt`, `gnss.txt`, `truth.nav`,
    /// `case.toml` (the complete model, with the effect and the outages) and `kf-gins.yaml`
    /// (the declared model). `host-sim run --config DIR/kf-gins.yaml` picks up the truth and
    /// the outages from `case.toml`.
    pub fn write(&self, dir: &Path) -> Result<(), SimError> {
        self.case.write(dir, false)?;
        write_kf_gins_yaml(dir.join("kf-gins.yaml"), &self.config)?;
        Ok(())
    }

    /// What the drive holds, in one line (effect and realised magnitudes).
    pub fn describe(&self) -> String {
        let mut what: Vec<String> = self
            .spec
            .effect
            .iter()
            .chain(&self.spec.second)
            .map(|e| self.describe_effect(*e))
            .collect();
        if !self.multipath.is_empty() {
            let j: Vec<String> = self
                .multipath
                .iter()
                .map(|j| {
                    let m = j.offset_ned_m.iter().map(|x| x * x).sum::<f64>().sqrt();
                    format!(
                        "{m:.2} m at {:.0}-{:.0} s",
                        j.start_s,
                        j.start_s + j.duration_s
                    )
                })
                .collect();
            what.push(format!("GNSS multipath jumps {}", j.join(", ")));
        }
        let what = if what.is_empty() {
            "no undeclared effect".to_string()
        } else {
            what.join("; ")
        };
        format!(
            "{:.1} min at {} Hz (truth RK4 x{}), seed {}: {what}",
            self.case.trajectory.duration_s() / 60.0,
            self.spec.rate_hz,
            self.spec.substeps,
            self.spec.seed
        )
    }

    /// One effect of the drive with its realised magnitudes.
    fn describe_effect(&self, effect: Effect) -> String {
        let e = &self.case.errors;
        match effect {
            Effect::GyroScaleFactor => {
                format!(
                    "gyro scale factor {:?} ppm",
                    e.gyro.scale_factor_ppm.0.map(r1)
                )
            }
            Effect::AccelScaleFactor => {
                format!(
                    "accel scale factor {:?} ppm",
                    e.accel.scale_factor_ppm.0.map(r1)
                )
            }
            Effect::AccelMisalignment => format!(
                "accel misalignment {:?} urad",
                e.accel.misalignment_rad.map(|r| r.map(|x| r1(x * 1e6)))
            ),
            Effect::AccelTemperature => format!(
                "accel temperature coefficient {:?} ug/degC over a 20 degC warm-up",
                e.accel.temp_coeff_per_c.0.map(|x| r1(x / UG_MPS2))
            ),
            Effect::LeverArm => {
                format!(
                    "antenna at {:?} m, declared [0, 0, 0]",
                    e.gnss.lever_arm_b_m.0
                )
            }
            Effect::TimeOffset => {
                format!("GNSS tags {:.1} ms late", e.gnss.time_offset_s * 1e3)
            }
            Effect::ImuClockDrift => {
                format!("IMU clock {:+.1} ppm", e.imu_clock_drift_ppm)
            }
            Effect::GnssCorrelatedError => format!(
                "GNSS white {:?} m, Gauss-Markov {:?} cm / {:.0} s (reported {:?} m)",
                e.gnss.white_sigma_ned_m.0,
                e.gnss.gm_sigma_ned_m.0.map(|x| r1(x * 100.0)),
                e.gnss.gm_tau_s,
                e.gnss.reported_std()
            ),
            Effect::AccelBiasStep => format!(
                "accelerometer bias step {:?} ug at {:.0} s",
                e.accel.bias_step.0.map(|x| r1(x / UG_MPS2)),
                e.accel.bias_step_at_s
            ),
            Effect::GyroBiasStep => format!(
                "gyro bias step {:?} deg/h at {:.0} s",
                e.gyro.bias_step.0.map(|x| r1(x / DEG_PER_H_RADPS)),
                e.gyro.bias_step_at_s
            ),
            Effect::GyroTemperature => format!(
                "gyro temperature coefficient {:?} deg/h/degC over a 20 degC warm-up",
                e.gyro
                    .temp_coeff_per_c
                    .0
                    .map(|x| (x / DEG_PER_H_RADPS * 100.0).round() / 100.0)
            ),
            Effect::GyroGSensitivity => {
                let per_g = DEG_PER_H_RADPS / nav_core::earth::G0_MPS2;
                let g = e.gyro.g_sensitivity_radps_per_mps2;
                format!(
                    "gyro g-sensitivity (diagonal) {:?} deg/h/g",
                    [0, 1, 2].map(|i| r1(g[i][i] / per_g))
                )
            }
            Effect::GnssWhiteNoise => format!(
                "GNSS white {:?} m (x{:.2} the reported {:?} m)",
                e.gnss.white_sigma_ned_m.0,
                e.gnss.white_sigma_ned_m.0[0] / e.gnss.reported_std()[0],
                e.gnss.reported_std()
            ),
        }
    }
}

fn r1(x: f64) -> f64 {
    (x * 10.0).round() / 10.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenario_length_and_outages() {
        let sc = drive_scenario(8.0, 100.0, 2);
        let d = sc.duration_s().unwrap();
        assert!((460.0..=520.0).contains(&d), "{d}");
        let o = drive_outages(d);
        assert_eq!(o.len(), 3, "{o:?}");
        let d10 = drive_scenario(10.0, 100.0, 2).duration_s().unwrap();
        assert_eq!(drive_outages(d10).len(), 4);
        assert!(o.iter().all(|o| o.start_s + o.duration_s + 30.0 <= d));
    }

    #[test]
    fn multipath_jumps_are_in_range_and_displace_only_their_fixes() {
        for seed in 0..20 {
            let j = multipath_jumps(600.0, seed);
            assert_eq!(j.len(), 4);
            for j in &j {
                let m = j.offset_ned_m.iter().map(|x| x * x).sum::<f64>().sqrt();
                assert!((0.3..=1.0).contains(&m), "{m}");
                assert!((20.0..=60.0).contains(&j.duration_s), "{j:?}");
                assert!((STATIC_START_S..=540.0).contains(&j.start_s), "{j:?}");
            }
        }
        let spec = DriveSpec {
            minutes: 4.0,
            rate_hz: 20.0,
            substeps: 1,
            file_gaps: Some(1),
            ..DriveSpec::new(None)
        };
        let clean = generate(&spec).unwrap();
        let mp = generate(&DriveSpec {
            outside: Some(OutsideEffect::GnssMultipath),
            ..spec
        })
        .unwrap();
        assert!(clean.multipath.is_empty() && mp.multipath.len() == 2);
        assert!(clean
            .case
            .meas
            .imu
            .iter()
            .zip(&mp.case.meas.imu)
            .all(|(a, b)| a.dv_mps == b.dv_mps && a.dtheta_rad == b.dtheta_rad));
        assert_eq!(clean.case.meas.gnss.len(), mp.case.meas.gnss.len());
        let t0 = mp.case.trajectory.t0_s;
        let mut moved = 0;
        for (c, m) in clean.case.meas.gnss.iter().zip(&mp.case.meas.gnss) {
            let t = c.t_s - t0;
            let want: [f64; 3] = [0, 1, 2].map(|i| {
                mp.multipath
                    .iter()
                    .filter(|j| j.start_s <= t && t < j.start_s + j.duration_s)
                    .map(|j| j.offset_ned_m[i])
                    .sum()
            });
            // metres north, east, down from the displaced position
            let r = nav_core::earth::radii(c.lat_rad);
            let got = [
                (m.lat_rad - c.lat_rad) * (r.meridian_m + c.h_m),
                (m.lon_rad - c.lon_rad) * (r.transverse_m + c.h_m) * c.lat_rad.cos(),
                c.h_m - m.h_m,
            ];
            for (g, w) in got.iter().zip(&want) {
                assert!((g - w).abs() < 1e-6, "{got:?} {want:?}");
            }
            moved += usize::from(want != [0.0; 3]);
            assert_eq!(c.pos_std_ned_m, m.pos_std_ned_m);
        }
        assert!(moved >= 20, "{moved}");
        assert!(
            mp.describe().contains("GNSS multipath jumps"),
            "{}",
            mp.describe()
        );
    }

    #[test]
    fn a_gnss_error_size_rescales_the_drawn_error_and_keeps_its_correlation_time() {
        let spec = DriveSpec {
            minutes: 4.0,
            rate_hz: 20.0,
            substeps: 1,
            file_gaps: Some(1),
            ..DriveSpec::new(Some(Effect::GnssCorrelatedError))
        };
        let own = generate(&spec).unwrap().case.errors.gnss;
        let sized = generate(&DriveSpec {
            gnss_error_size: Some(GnssErrorSize {
                gm_sigma_m: 0.6,
                white_factor: Some(1.0),
            }),
            ..spec
        })
        .unwrap()
        .case
        .errors
        .gnss;
        assert_eq!(own.gm_tau_s, sized.gm_tau_s);
        assert_eq!(own.reported_std(), sized.reported_std());
        for i in 0..3 {
            let g = sized.gm_sigma_ned_m.0[i];
            assert!((g - 6.0 * own.gm_sigma_ned_m.0[i]).abs() < 1e-12);
            assert!((0.3..=0.9).contains(&g), "{g}");
            assert!((sized.white_sigma_ned_m.0[i] - sized.reported_std()[i]).abs() < 1e-12);
        }
    }

    #[test]
    fn a_second_effect_leaves_the_first_as_drawn_alone() {
        for (a, b) in [
            (Effect::GyroScaleFactor, Effect::ImuClockDrift),
            (Effect::LeverArm, Effect::AccelBiasStep),
            (Effect::AccelScaleFactor, Effect::GyroBiasStep),
        ] {
            // disjoint fields and separate random streams: the order does not matter
            let mut ab = declared_error_model(600.0);
            add_effect(&mut ab, a, 7, 600.0);
            let alone = ab.clone();
            add_effect(&mut ab, b, 7, 600.0);
            let mut ba = declared_error_model(600.0);
            add_effect(&mut ba, b, 7, 600.0);
            add_effect(&mut ba, a, 7, 600.0);
            assert_eq!(ab, ba);
            assert_ne!(ab, alone);
        }
    }

    #[test]
    fn effect_magnitudes_are_in_range() {
        for seed in 0..20 {
            for e in Effect::ALL {
                let mut m = declared_error_model(480.0);
                add_effect(&mut m, e, seed, 480.0);
                m.validate().unwrap();
                match e {
                    Effect::GyroScaleFactor => assert!(m
                        .gyro
                        .scale_factor_ppm
                        .0
                        .iter()
                        .all(|x| (300.0..=1000.0).contains(&x.abs()))),
                    Effect::AccelScaleFactor => assert!(m
                        .accel
                        .scale_factor_ppm
                        .0
                        .iter()
                        .all(|x| (500.0..=1500.0).contains(&x.abs()))),
                    Effect::AccelMisalignment => {
                        for i in 0..3 {
                            for j in 0..3 {
                                let x = m.accel.misalignment_rad[i][j].abs();
                                if i == j {
                                    assert_eq!(x, 0.0);
                                } else {
                                    assert!((100e-6..=400e-6).contains(&x), "{x}");
                                }
                            }
                        }
                    }
                    Effect::AccelTemperature => {
                        assert!(m
                            .accel
                            .temp_coeff_per_c
                            .0
                            .iter()
                            .all(|x| (25.0..=60.0).contains(&(x.abs() / UG_MPS2))));
                        assert_eq!(m.temperature.as_ref().unwrap().rise_c, 20.0);
                    }
                    Effect::LeverArm => {
                        let n = LEVER_ARM_TRUE_M.iter().map(|x| x * x).sum::<f64>().sqrt();
                        assert!((n - 1.5).abs() < 0.05, "{n}");
                        assert_eq!(m.gnss.lever_arm_b_m.0, LEVER_ARM_TRUE_M);
                    }
                    Effect::TimeOffset => {
                        assert!((0.05..=0.1).contains(&m.gnss.time_offset_s))
                    }
                    Effect::ImuClockDrift => {
                        assert!((30.0..=80.0).contains(&m.imu_clock_drift_ppm.abs()))
                    }
                    Effect::GnssCorrelatedError => {
                        let (w, r) = (m.gnss.white_sigma_ned_m.0, m.gnss.reported_std());
                        for ((w, r), g) in w.iter().zip(&r).zip(&m.gnss.gm_sigma_ned_m.0) {
                            assert!((2.0..=4.0).contains(&(w / r)), "{w} {r}");
                            assert!((0.05..=0.15).contains(g), "{g}");
                        }
                        assert!((100.0..=300.0).contains(&m.gnss.gm_tau_s));
                    }
                    Effect::AccelBiasStep => {
                        let s = m.accel.bias_step.0;
                        assert_eq!(s[2], 0.0);
                        let mg = s.iter().map(|x| x.abs()).sum::<f64>() / UG_MPS2 / 1e3;
                        assert!((2.0..=4.0).contains(&mg), "{mg}");
                        assert!(s.iter().filter(|x| **x != 0.0).count() == 1);
                        assert_eq!(m.accel.bias_step_at_s, bias_step_time_s(480.0));
                    }
                    Effect::GyroBiasStep => {
                        let s = m.gyro.bias_step.0;
                        let dph = s.iter().map(|x| x.abs()).sum::<f64>() / DEG_PER_H_RADPS;
                        assert!((20.0..=50.0).contains(&dph), "{dph}");
                        assert!(s.iter().filter(|x| **x != 0.0).count() == 1);
                    }
                    Effect::GyroTemperature => {
                        assert!(m
                            .gyro
                            .temp_coeff_per_c
                            .0
                            .iter()
                            .all(|x| (0.3..=0.6).contains(&(x.abs() / DEG_PER_H_RADPS))));
                        assert_eq!(m.temperature.as_ref().unwrap().rise_c, 20.0);
                        assert_eq!(m.accel.temp_coeff_per_c.0, [0.0; 3]);
                    }
                    Effect::GyroGSensitivity => {
                        let per_g = DEG_PER_H_RADPS / nav_core::earth::G0_MPS2;
                        let g = m.gyro.g_sensitivity_radps_per_mps2;
                        for (i, row) in g.iter().enumerate() {
                            for (j, x) in row.iter().enumerate() {
                                if i == j {
                                    assert!((10.0..=30.0).contains(&(x.abs() / per_g)), "{x}");
                                } else {
                                    assert_eq!(*x, 0.0);
                                }
                            }
                        }
                    }
                    Effect::GnssWhiteNoise => {
                        let (w, r) = (m.gnss.white_sigma_ned_m.0, m.gnss.reported_std());
                        let k = w[0] / r[0];
                        assert!((3.0..=8.0).contains(&k), "{k}");
                        for (w, r) in w.iter().zip(&r) {
                            assert!((w / r - k).abs() < 1e-12);
                        }
                        assert_eq!(m.gnss.gm_sigma_ned_m.0, [0.005; 3]);
                    }
                }
            }
        }
    }
}
