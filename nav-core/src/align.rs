//! Static coarse alignment: the initial attitude from a window of IMU samples taken at rest.
//!
//! * **Levelling**: roll and pitch from the mean specific force. At rest the accelerometers
//!   measure f^b = -C_n^b g^n = (g sin(pitch), -g sin(roll) cos(pitch), -g cos(roll) cos(pitch)),
//!   so roll = atan2(-f_y, -f_z), pitch = atan2(f_x, sqrt(f_y^2 + f_z^2)). An accelerometer bias
//!   b_a tilts the result by about b_a / g (1 mg -> 0.057 deg).
//! * **Heading**: given by the caller, or by **gyrocompassing**: the mean angular rate at rest is
//!   the earth rate, omega^b = C_n^b (W cos(lat), 0, -W sin(lat)); rotated into the levelled
//!   (heading-free) frame it is (W cos(lat) cos(yaw), -W cos(lat) sin(yaw), -W sin(lat)), so
//!   yaw = atan2(-omega_y, omega_x). A horizontal gyro bias b_g gives a heading error of about
//!   b_g / (W cos(lat)); W cos(lat) is only 15.04 deg/h * cos(lat) (10.06 deg/h at 48 deg).
//!   Gyrocompassing therefore needs a **navigation-grade gyro**: b_g << W cos(lat) times the
//!   wanted accuracy, i.e. below about 0.017 deg/h for 0.1 deg and 0.17 deg/h for 1 deg at
//!   48 deg latitude, and a window long enough to average the angle random walk
//!   (ARW / sqrt(T) below the same limit: 0.002 deg/sqrt(h) needs about 2 min for 0.1 deg).
//!   Tactical (1 deg/h) and MEMS gyros cannot gyrocompass: give the heading (magnetometer,
//!   GNSS course, a previous run) instead. The estimated heading uncertainty is checked
//!   against [`AlignConfig::max_gyrocompass_std_rad`] and a typed error returned above it.
//!
//! **Static detection.** The window (intervals between consecutive samples) is cut into
//! [`SEGMENTS`] consecutive segments; the mean specific force and angular rate of each segment
//! must stay within [`AlignConfig::max_segment_f_dev_mps2`] and
//! [`AlignConfig::max_segment_omega_dev_radps`] of the window means (averaging over a segment
//! removes white noise and vibration, so the test sees changes in acceleration or rotation
//! over seconds), the norm of the mean specific force must match normal gravity within
//! [`AlignConfig::max_gravity_mismatch_mps2`] (a sustained acceleration), and the mean rate
//! must stay below [`AlignConfig::max_mean_rate_radps`] (a steady turn). A motion at constant
//! velocity in a straight line is indistinguishable from rest for an IMU and is not detected.

use crate::config::FilterConfig;
use crate::earth::{self, Llh};
use crate::filter::InitialUncertainty;
use crate::strapdown::{NavState, MAX_DT_S};
use crate::types::ImuSample;
use libm::{atan2, cos, sin, sqrt};
use nalgebra::{UnitQuaternion, Vector3};

/// Number of segments the window is cut into for the static test.
pub const SEGMENTS: usize = 8;

/// Where the heading comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HeadingSource {
    /// Heading given by the caller: yaw (rad) and its standard deviation (rad).
    Given {
        /// Yaw (heading of the body x axis from north, ZYX convention), rad.
        yaw_rad: f64,
        /// One-sigma uncertainty of `yaw_rad`, rad.
        std_rad: f64,
    },
    /// Heading from the earth rate sensed by the gyros (navigation-grade gyros only, see the
    /// module documentation).
    Gyrocompass,
}

/// Thresholds of the static test and assumed sensor quality for the uncertainty.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AlignConfig {
    /// Shortest accepted window, s.
    pub min_duration_s: f64,
    /// Largest accepted | |mean f| - normal gravity |, m/s^2 (covers accelerometer bias and
    /// scale-factor error).
    pub max_gravity_mismatch_mps2: f64,
    /// Largest accepted deviation of a segment's mean specific force from the window mean,
    /// m/s^2.
    pub max_segment_f_dev_mps2: f64,
    /// Largest accepted deviation of a segment's mean angular rate from the window mean, rad/s.
    pub max_segment_omega_dev_radps: f64,
    /// Largest accepted norm of the mean angular rate, rad/s (earth rate plus gyro bias).
    pub max_mean_rate_radps: f64,
    /// Assumed one-sigma residual accelerometer bias, m/s^2 (for the attitude uncertainty).
    pub accel_bias_mps2: f64,
    /// Assumed one-sigma residual gyro bias, rad/s (for the heading uncertainty).
    pub gyro_bias_radps: f64,
    /// Largest accepted one-sigma gyrocompassing heading uncertainty, rad.
    pub max_gyrocompass_std_rad: f64,
}

impl Default for AlignConfig {
    /// Detection thresholds loose enough for MEMS noise and biases; uncertainty for a tactical
    /// IMU (100 ug accelerometer bias, 1 deg/h gyro bias). With these, gyrocompassing is
    /// refused (its uncertainty would be several degrees) unless `gyro_bias_radps` is set to a
    /// navigation-grade value.
    fn default() -> Self {
        Self {
            min_duration_s: 10.0,
            max_gravity_mismatch_mps2: 0.1,
            max_segment_f_dev_mps2: 0.05,
            max_segment_omega_dev_radps: 0.2 * DEG,
            max_mean_rate_radps: 1.0 * DEG,
            accel_bias_mps2: 1.0e-4 * earth::G0_MPS2,
            gyro_bias_radps: 1.0 * DEG / 3600.0,
            max_gyrocompass_std_rad: 5.0 * DEG,
        }
    }
}

const DEG: f64 = core::f64::consts::PI / 180.0;

/// Which static-test cue failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MotionCue {
    /// A segment's mean specific force deviates from the window mean (m/s^2).
    SpecificForceVariation,
    /// A segment's mean angular rate deviates from the window mean (rad/s).
    RateVariation,
    /// The norm of the mean angular rate is too large (rad/s).
    MeanRate,
    /// The norm of the mean specific force differs from normal gravity (m/s^2).
    GravityMismatch,
}

/// Why an alignment failed.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AlignError {
    /// The window is shorter than `min_s` seconds or has fewer than [`SEGMENTS`] + 1 samples.
    TooShort {
        /// Duration of the window (last minus first sample time), s.
        duration_s: f64,
        /// Number of samples in the window.
        samples: usize,
        /// Required duration, s.
        min_s: f64,
    },
    /// Sample `index` of the window has a non-finite time or increment.
    NonFinite {
        /// Index of the sample in the window.
        index: usize,
    },
    /// Sample `index` is not after the previous one, or the gap is longer than
    /// [`MAX_DT_S`].
    BadTimeStep {
        /// Index of the sample in the window.
        index: usize,
    },
    /// The window is not static: `cue` measured `value` over the limit `limit` (units of the
    /// cue).
    NotStatic {
        /// Which test failed.
        cue: MotionCue,
        /// Measured value (m/s^2 or rad/s).
        value: f64,
        /// Limit from the configuration (m/s^2 or rad/s).
        limit: f64,
    },
    /// In-motion alignment: the GNSS horizontal speed is too low for its course to give the
    /// heading.
    TooSlow {
        /// Horizontal speed, m/s.
        speed_mps: f64,
        /// Required speed, m/s.
        min_mps: f64,
    },
    /// Gyrocompassing would be worse than [`AlignConfig::max_gyrocompass_std_rad`] (gyro too
    /// poor for the latitude, or window too short).
    GyrocompassInaccurate {
        /// Estimated one-sigma heading uncertainty, rad.
        std_rad: f64,
        /// Configured limit, rad.
        limit_rad: f64,
    },
}

impl core::fmt::Display for MotionCue {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::SpecificForceVariation => "segment mean specific force variation (m/s^2)",
            Self::RateVariation => "segment mean angular rate variation (rad/s)",
            Self::MeanRate => "mean angular rate (rad/s)",
            Self::GravityMismatch => "mean specific force minus normal gravity (m/s^2)",
        })
    }
}

impl core::fmt::Display for AlignError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::TooShort {
                duration_s,
                samples,
                min_s,
            } => write!(
                f,
                "alignment window too short: {duration_s} s, {samples} samples \
                 (need {min_s} s and {} samples)",
                SEGMENTS + 1
            ),
            Self::NonFinite { index } => {
                write!(f, "alignment window sample {index} is not finite")
            }
            Self::BadTimeStep { index } => write!(
                f,
                "alignment window sample {index}: time not increasing or gap too long"
            ),
            Self::NotStatic { cue, value, limit } => write!(
                f,
                "alignment window is not static: {cue} = {value:e} exceeds {limit:e}"
            ),
            Self::TooSlow { speed_mps, min_mps } => write!(
                f,
                "in-motion alignment: GNSS horizontal speed {speed_mps:.3} m/s is below \
                 {min_mps} m/s, too slow for the course to give the heading"
            ),
            Self::GyrocompassInaccurate { std_rad, limit_rad } => write!(
                f,
                "gyrocompassing heading uncertainty {:.3} deg exceeds {:.3} deg: \
                 give the heading instead",
                std_rad / DEG,
                limit_rad / DEG
            ),
        }
    }
}

impl core::error::Error for AlignError {}

/// Result of a coarse alignment.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Alignment {
    /// Roll, pitch, yaw (ZYX Euler angles of the body relative to NED), rad.
    pub rpy_rad: [f64; 3],
    /// Rough one-sigma uncertainty of roll, pitch, yaw, rad (from the configured biases and the
    /// scatter of the segment means).
    pub att_std_rad: [f64; 3],
    /// Mean specific force over the window in body axes, m/s^2.
    pub mean_f_body_mps2: [f64; 3],
    /// Mean angular rate over the window in body axes, rad/s.
    pub mean_omega_body_radps: [f64; 3],
    /// Duration of the window, s.
    pub duration_s: f64,
    /// GPS seconds of week of the last sample of the window, s.
    pub t_end_s: f64,
}

impl Alignment {
    /// The attitude C_b^n.
    pub fn q_nb(&self) -> UnitQuaternion<f64> {
        crate::attitude::quat_from_euler_zyx(self.rpy_rad)
    }

    /// A navigation state at rest at `pos` at the end of the window, to start
    /// [`crate::strapdown::Strapdown`] from.
    pub fn nav_state(&self, pos: Llh) -> NavState {
        NavState::from_rpy(self.t_end_s, pos, Vector3::zeros(), self.rpy_rad)
    }
}

/// Per-segment sums.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Seg {
    dt_s: f64,
    dv: Vector3<f64>,
    dth: Vector3<f64>,
}

/// Static coarse alignment of `window` (consecutive IMU samples at rest, oldest first) at
/// position `pos`. The increments of samples 1..n are used (sample 0 only marks the start
/// time). See the module documentation for the method, the static test and the gyro grade
/// needed for gyrocompassing. [`StaticWindow`] is the same alignment on a stream.
pub fn coarse_align(
    window: &[ImuSample],
    pos: &Llh,
    heading: HeadingSource,
    cfg: &AlignConfig,
) -> Result<Alignment, AlignError> {
    let n = window.len();
    let (t_first, t_last) = match (window.first(), window.last()) {
        (Some(a), Some(b)) => (a.t_s, b.t_s),
        _ => {
            return Err(AlignError::TooShort {
                duration_s: 0.0,
                samples: 0,
                min_s: cfg.min_duration_s,
            })
        }
    };
    for (i, s) in window.iter().enumerate() {
        if !s.is_finite() {
            return Err(AlignError::NonFinite { index: i });
        }
    }
    let duration_s = t_last - t_first;
    if n < SEGMENTS + 1 || duration_s.is_nan() || duration_s < cfg.min_duration_s {
        return Err(AlignError::TooShort {
            duration_s,
            samples: n,
            min_s: cfg.min_duration_s,
        });
    }

    // Segment sums over the n - 1 intervals.
    let m = n - 1;
    let mut segs = [Seg::ZERO; SEGMENTS];
    let mut t_prev = t_first;
    for (i, s) in window.iter().enumerate().skip(1) {
        let dt = s.t_s - t_prev;
        if !(dt > 0.0 && dt <= MAX_DT_S) {
            return Err(AlignError::BadTimeStep { index: i });
        }
        t_prev = s.t_s;
        let j = (i - 1) * SEGMENTS / m;
        if let Some(seg) = segs.get_mut(j) {
            seg.add(dt, s);
        }
    }
    align_segments(&segs, n, t_first, t_last, pos, heading, cfg)
}

impl Seg {
    const ZERO: Self = Self {
        dt_s: 0.0,
        dv: Vector3::new(0.0, 0.0, 0.0),
        dth: Vector3::new(0.0, 0.0, 0.0),
    };

    fn add(&mut self, dt: f64, s: &ImuSample) {
        self.dt_s += dt;
        self.dv += Vector3::from(s.dv_mps);
        self.dth += Vector3::from(s.dtheta_rad);
    }
}

/// The alignment from the segment sums of a window of `n` samples from `t_first` to `t_last`
/// (the static test, levelling and heading of [`coarse_align`]).
fn align_segments(
    segs: &[Seg; SEGMENTS],
    n: usize,
    t_first: f64,
    t_last: f64,
    pos: &Llh,
    heading: HeadingSource,
    cfg: &AlignConfig,
) -> Result<Alignment, AlignError> {
    let duration_s = t_last - t_first;
    if n < SEGMENTS + 1
        || duration_s.is_nan()
        || duration_s < cfg.min_duration_s
        || segs.iter().any(|s| s.dt_s <= 0.0)
    {
        return Err(AlignError::TooShort {
            duration_s,
            samples: n,
            min_s: cfg.min_duration_s,
        });
    }
    let (mut dv, mut dth) = (Vector3::zeros(), Vector3::zeros());
    for seg in segs {
        dv += seg.dv;
        dth += seg.dth;
    }
    let f = dv / duration_s;
    let w = dth / duration_s;

    // Static test.
    let (mut f_dev, mut w_dev) = (0.0f64, 0.0f64);
    let (mut f_ss, mut w_ss) = (0.0, 0.0);
    for seg in segs {
        // Every segment holds at least one interval (checked above), so dt_s > 0.
        let df = seg.dv / seg.dt_s - f;
        let dw = seg.dth / seg.dt_s - w;
        f_dev = f_dev.max(df.norm());
        w_dev = w_dev.max(dw.norm());
        f_ss += df.norm_squared();
        w_ss += dw.norm_squared();
    }
    let g = earth::gravity_mps2(pos.lat_rad, pos.h_m);
    let checks = [
        (
            MotionCue::GravityMismatch,
            (f.norm() - g).abs(),
            cfg.max_gravity_mismatch_mps2,
        ),
        (
            MotionCue::SpecificForceVariation,
            f_dev,
            cfg.max_segment_f_dev_mps2,
        ),
        (
            MotionCue::RateVariation,
            w_dev,
            cfg.max_segment_omega_dev_radps,
        ),
        (MotionCue::MeanRate, w.norm(), cfg.max_mean_rate_radps),
    ];
    for (cue, value, limit) in checks {
        if value.is_nan() || value > limit {
            return Err(AlignError::NotStatic { cue, value, limit });
        }
    }

    // Levelling.
    let roll = atan2(-f.y, -f.z);
    let pitch = atan2(f.x, sqrt(f.y * f.y + f.z * f.z));

    // Standard errors of the window means per axis from the scatter of the segment means
    // (white noise: variance of the mean = variance of a segment mean / SEGMENTS).
    let k = 1.0 / (3.0 * (SEGMENTS * (SEGMENTS - 1)) as f64);
    let f_se = sqrt(f_ss * k);
    let w_se = sqrt(w_ss * k);
    let tilt_std = sqrt(cfg.accel_bias_mps2 * cfg.accel_bias_mps2 + f_se * f_se) / g;
    let cos_pitch = cos(pitch).max(1e-6);
    let roll_std = tilt_std / cos_pitch;

    let (yaw, yaw_std) = match heading {
        HeadingSource::Given { yaw_rad, std_rad } => (yaw_rad, std_rad),
        HeadingSource::Gyrocompass => {
            // Rate in the levelled frame: C_b^l = Ry(pitch) Rx(roll).
            let (sr, cr) = (sin(roll), cos(roll));
            let (sp, cp) = (sin(pitch), cos(pitch));
            let wy_r = cr * w.y - sr * w.z;
            let wz_r = sr * w.y + cr * w.z;
            let wx_l = cp * w.x + sp * wz_r;
            let wy_l = wy_r;
            let yaw = atan2(-wy_l, wx_l);
            let w_h = earth::OMEGA_IE_RADPS * cos(pos.lat_rad).abs();
            let tan_lat = sin(pos.lat_rad) / cos(pos.lat_rad).abs().max(1e-12);
            let gyro = sqrt(cfg.gyro_bias_radps * cfg.gyro_bias_radps + w_se * w_se);
            let from_gyro = if w_h > 0.0 { gyro / w_h } else { f64::INFINITY };
            let from_tilt = tan_lat * tilt_std;
            let std = sqrt(from_gyro * from_gyro + from_tilt * from_tilt);
            if std.is_nan() || std > cfg.max_gyrocompass_std_rad {
                return Err(AlignError::GyrocompassInaccurate {
                    std_rad: std,
                    limit_rad: cfg.max_gyrocompass_std_rad,
                });
            }
            (yaw, std)
        }
    };

    Ok(Alignment {
        rpy_rad: [roll, pitch, yaw],
        att_std_rad: [roll_std, tilt_std, yaw_std],
        mean_f_body_mps2: f.into(),
        mean_omega_body_radps: w.into(),
        duration_s,
        t_end_s: t_last,
    })
}

/// [`coarse_align`] on a stream: push the samples of a static window one by one (no buffer),
/// then [`StaticWindow::align`]. The window is the samples with `t_s <= t_first + length_s`
/// (the first sample only marks the start time, as in [`coarse_align`]). The intervals are
/// cut into the [`SEGMENTS`] of the static test by the time of their middle (the number of
/// samples is not known in advance), which equals [`coarse_align`]'s cut for evenly spaced
/// samples up to rounding at the segment borders.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticWindow {
    length_s: f64,
    t_first_s: f64,
    t_last_s: f64,
    samples: usize,
    segs: [Seg; SEGMENTS],
    fault: Option<AlignError>,
}

impl StaticWindow {
    /// An empty window of `length_s` seconds.
    pub fn new(length_s: f64) -> Self {
        Self {
            length_s,
            t_first_s: f64::NAN,
            t_last_s: f64::NAN,
            samples: 0,
            segs: [Seg::ZERO; SEGMENTS],
            fault: None,
        }
    }

    /// Empties the window (same length).
    pub fn clear(&mut self) {
        *self = Self::new(self.length_s);
    }

    /// Time of the first sample, s (NaN while empty).
    pub fn start_s(&self) -> f64 {
        self.t_first_s
    }

    /// Time of the last sample, s (NaN while empty).
    pub fn end_s(&self) -> f64 {
        self.t_last_s
    }

    /// Samples pushed.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Whether a sample at `t_s` belongs to the window (true while it is empty); a sample
    /// that does not closes the window.
    pub fn contains(&self, t_s: f64) -> bool {
        self.samples == 0 || t_s <= self.t_first_s + self.length_s
    }

    /// Adds a sample (the caller checks [`Self::contains`] first). A non-finite sample or a
    /// bad time step is remembered and returned by [`Self::align`].
    pub fn push(&mut self, s: &ImuSample) {
        let index = self.samples;
        self.samples = self.samples.saturating_add(1);
        if self.fault.is_some() {
            return;
        }
        if !s.is_finite() {
            self.fault = Some(AlignError::NonFinite { index });
            return;
        }
        if index == 0 {
            self.t_first_s = s.t_s;
            self.t_last_s = s.t_s;
            return;
        }
        let dt = s.t_s - self.t_last_s;
        if !(dt > 0.0 && dt <= MAX_DT_S) {
            self.fault = Some(AlignError::BadTimeStep { index });
            return;
        }
        let mid = 0.5 * (s.t_s + self.t_last_s) - self.t_first_s;
        let j = if self.length_s > 0.0 {
            libm::floor(mid / self.length_s * SEGMENTS as f64)
        } else {
            0.0
        };
        // j >= 0 (mid > 0); a sample past the window lands in the last segment
        let j = if j.is_finite() && j >= 0.0 {
            (j as usize).min(SEGMENTS - 1)
        } else {
            0
        };
        if let Some(seg) = self.segs.get_mut(j) {
            seg.add(dt, s);
        }
        self.t_last_s = s.t_s;
    }

    /// The alignment of the samples pushed so far at position `pos` (as [`coarse_align`]).
    pub fn align(
        &self,
        pos: &Llh,
        heading: HeadingSource,
        cfg: &AlignConfig,
    ) -> Result<Alignment, AlignError> {
        if let Some(e) = self.fault {
            return Err(e);
        }
        if self.samples == 0 {
            return Err(AlignError::TooShort {
                duration_s: 0.0,
                samples: 0,
                min_s: cfg.min_duration_s,
            });
        }
        align_segments(
            &self.segs,
            self.samples,
            self.t_first_s,
            self.t_last_s,
            pos,
            heading,
            cfg,
        )
    }
}

impl AlignConfig {
    /// These settings with the assumed sensor biases taken from a filter configuration's
    /// initial bias sigmas (largest axis) where those are set (> 0).
    pub fn with_filter_biases(mut self, cfg: &FilterConfig) -> Self {
        let max3 = |a: &[f64; 3]| a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let ab = max3(&cfg.accel.bias_init_sigma);
        if ab > 0.0 {
            self.accel_bias_mps2 = ab;
        }
        let gb = max3(&cfg.gyro.bias_init_sigma);
        if gb > 0.0 {
            self.gyro_bias_radps = gb;
        }
        self
    }
}

/// The filter's start after a static alignment ([`static_start`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticStart {
    /// Initial nominal state at the IMU reference point, at the end of the window (velocity
    /// zero).
    pub state: NavState,
    /// Initial uncertainty of the core states.
    pub unc: InitialUncertainty,
    /// Gyro bias: the window's mean angular rate minus the earth rate resolved in the aligned
    /// body axes, rad/s (the usual MEMS start-up calibration).
    pub gyro_bias_radps: [f64; 3],
    /// 1-sigma of that estimate from the angle random walk averaged over the window,
    /// `sqrt(S_N / T)`, rad/s: the filter must not believe it better.
    pub gyro_bias_sigma_floor_radps: [f64; 3],
}

/// The filter's start from an alignment `al`: the antenna position `antenna` (mean of the
/// fixes in the window, with the mean of their NED 1-sigma `antenna_std_ned_m`, m) moved to the
/// IMU point with the lever arm (body FRD, m), velocity zero with `vel_sigma_mps`, the
/// alignment's attitude sigmas (roll and pitch replaced by `tilt_std_rad` when given, rad),
/// the static gyro bias and its floor from the gyro white-noise PSD `gyro_s_n` (rad^2/s).
pub fn static_start(
    al: &Alignment,
    antenna: &Llh,
    antenna_std_ned_m: &[f64; 3],
    lever_arm_body_m: &[f64; 3],
    gyro_s_n: &[f64; 3],
    vel_sigma_mps: f64,
    tilt_std_rad: Option<f64>,
) -> StaticStart {
    let q = al.q_nb();
    let c = crate::filter::dcm_f64(&q);
    let pos = earth::displace(antenna, &(-(c * Vector3::from(*lever_arm_body_m))));
    let state = NavState {
        t_s: al.t_end_s,
        pos,
        vel_ned_mps: Vector3::zeros(),
        q_nb: q,
    };
    let w_ie_b = c.transpose() * earth::earth_rate_ned_radps(pos.lat_rad);
    let bias: [f64; 3] = (Vector3::from(al.mean_omega_body_radps) - w_ie_b).into();
    let floor = gyro_s_n.map(|s| sqrt(s / al.duration_s.max(1e-9)));
    let pos_sigma = antenna_std_ned_m.map(|s| s.max(0.005) + 0.01);
    let mut att_sigma = al.att_std_rad;
    if let Some(t) = tilt_std_rad {
        att_sigma[0] = t;
        att_sigma[1] = t;
    }
    StaticStart {
        state,
        unc: InitialUncertainty {
            att_sigma_rad: att_sigma,
            vel_sigma_mps: [vel_sigma_mps; 3],
            pos_sigma_m: pos_sigma,
        },
        gyro_bias_radps: bias,
        gyro_bias_sigma_floor_radps: floor,
    }
}

/// Settings of the in-motion alignment ([`motion_align`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotionAlignConfig {
    /// Lowest horizontal GNSS speed whose course is taken as the heading, m/s.
    pub min_speed_mps: f64,
    /// Assumed one-sigma angle between the body x axis and the velocity (side slip, crab,
    /// residual mounting yaw), rad; added to the course uncertainty for the yaw sigma.
    pub sideslip_std_rad: f64,
    /// Assumed one-sigma angle between the body x axis and the velocity in the vertical plane
    /// (angle of attack, residual mounting pitch), rad; added for the pitch sigma.
    pub attack_std_rad: f64,
    /// One-sigma roll when it cannot be levelled (no specific force given), rad.
    pub unlevelled_roll_std_rad: f64,
    /// Assumed one-sigma residual accelerometer bias, m/s^2 (for the roll sigma).
    pub accel_bias_mps2: f64,
}

impl Default for MotionAlignConfig {
    /// 3 m/s, 2 deg side slip, 2 deg angle of attack, 10 deg roll when not levelled,
    /// 10 mg accelerometer bias (consumer MEMS).
    fn default() -> Self {
        Self {
            min_speed_mps: 3.0,
            sideslip_std_rad: 2.0 * DEG,
            attack_std_rad: 2.0 * DEG,
            unlevelled_roll_std_rad: 10.0 * DEG,
            accel_bias_mps2: 0.01 * earth::G0_MPS2,
        }
    }
}

/// What [`motion_align`] measured the roll from.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotionLevelling {
    /// Mean specific force over a short interval, body axes, m/s^2.
    pub mean_f_body_mps2: [f64; 3],
    /// Mean kinematic acceleration over the same interval (from the GNSS velocity), NED,
    /// m/s^2.
    pub accel_ned_mps2: [f64; 3],
    /// One-sigma of `accel_ned_mps2` per axis, m/s^2.
    pub accel_std_mps2: f64,
    /// Magnitude of gravity at the position, m/s^2.
    pub gravity_mps2: f64,
}

/// In-motion coarse alignment from the GNSS velocity (a vehicle that moves from the first
/// sample, where the static levelling cannot work):
///
/// * yaw = the course `atan2(v_E, v_N)`, assuming the body x axis points along the velocity
///   (a land vehicle without side slip; the IMU mounting rotation already applied);
/// * pitch = the climb angle `atan2(-v_D, |v_H|)`;
/// * roll: levelled on the move when `level` is given: the specific force predicted from the
///   GNSS acceleration, `f^n = a^n - g^n`, rotated by the yaw and pitch above, is compared
///   with the measured mean specific force in the body y-z plane; roll is the angle between
///   them. Without `level` the roll is 0 with [`MotionAlignConfig::unlevelled_roll_std_rad`].
///
/// `vel_ned_mps` is the GNSS velocity (m/s) and `vel_std_mps` its one-sigma per axis (m/s).
/// The one-sigma attitude returned combines the course/climb noise (`vel_std / speed`) with
/// the configured side-slip and attack allowances, and for the roll the accelerometer bias
/// and the GNSS acceleration noise over gravity. The result's window fields
/// (`mean_omega_body_radps`, `duration_s`, `t_end_s`) are zero: the caller places the state.
pub fn motion_align(
    vel_ned_mps: [f64; 3],
    vel_std_mps: f64,
    level: Option<&MotionLevelling>,
    cfg: &MotionAlignConfig,
) -> Result<Alignment, AlignError> {
    let [vn, ve, vd] = vel_ned_mps;
    if !(vn.is_finite() && ve.is_finite() && vd.is_finite() && vel_std_mps.is_finite()) {
        return Err(AlignError::NonFinite { index: 0 });
    }
    let vh = sqrt(vn * vn + ve * ve);
    if vh.is_nan() || vh < cfg.min_speed_mps {
        return Err(AlignError::TooSlow {
            speed_mps: vh,
            min_mps: cfg.min_speed_mps,
        });
    }
    let yaw = atan2(ve, vn);
    let pitch = atan2(-vd, vh);
    let course_std = vel_std_mps.abs() / vh;
    let yaw_std = sqrt(course_std * course_std + cfg.sideslip_std_rad * cfg.sideslip_std_rad);
    let pitch_std = sqrt(course_std * course_std + cfg.attack_std_rad * cfg.attack_std_rad);
    let (roll, roll_std, mean_f) = match level {
        None => (0.0, cfg.unlevelled_roll_std_rad, [0.0; 3]),
        Some(l) => {
            let [an, ae, ad] = l.accel_ned_mps2;
            let [fx, fy, fz] = l.mean_f_body_mps2;
            let all = [an, ae, ad, fx, fy, fz, l.gravity_mps2, l.accel_std_mps2];
            if !all.iter().all(|v| v.is_finite()) {
                return Err(AlignError::NonFinite { index: 0 });
            }
            // f^n = a^n - g^n, g^n = (0, 0, g)
            let (n, e, d) = (an, ae, ad - l.gravity_mps2);
            // C_n^b without roll: R2(pitch) R3(yaw)
            let (sy, cy) = (sin(yaw), cos(yaw));
            let (sp, cp) = (sin(pitch), cos(pitch));
            let x1 = cy * n + sy * e;
            let y1 = -sy * n + cy * e;
            let z1 = d;
            let y2 = y1;
            let z2 = sp * x1 + cp * z1;
            // body = R1(roll) (y2, z2): the body vector is the predicted one turned by -roll
            let mut r = atan2(z2, y2) - atan2(fz, fy);
            while r > core::f64::consts::PI {
                r -= 2.0 * core::f64::consts::PI;
            }
            while r < -core::f64::consts::PI {
                r += 2.0 * core::f64::consts::PI;
            }
            let g = l.gravity_mps2.max(1.0);
            let tilt = sqrt(
                cfg.accel_bias_mps2 * cfg.accel_bias_mps2 + l.accel_std_mps2 * l.accel_std_mps2,
            ) / g;
            (r, tilt, l.mean_f_body_mps2)
        }
    };
    Ok(Alignment {
        rpy_rad: [roll, pitch, yaw],
        att_std_rad: [roll_std, pitch_std, yaw_std],
        mean_f_body_mps2: mean_f,
        mean_omega_body_radps: [0.0; 3],
        duration_s: 0.0,
        t_end_s: 0.0,
    })
}

/// When the direction of a GNSS displacement is taken as the heading ([`course_from_displacement`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CourseRule {
    /// Largest accepted one-sigma of the course from the position noise, rad: a displacement
    /// of horizontal length `d` between two positions with horizontal one-sigmas `s_a` and
    /// `s_b` (per axis) has a course one-sigma of about `hypot(s_a, s_b) / d` (the cross-track
    /// error over the length, small angles), so the course is accepted from
    /// `d >= hypot(s_a, s_b) / max_std_rad`.
    pub max_std_rad: f64,
    /// Length at which the course is accepted whatever the position noise, m (the longer the
    /// look-ahead, the likelier the track has turned: a cap for noisy single-point fixes).
    pub max_distance_m: f64,
}

impl Default for CourseRule {
    /// 1 deg, 5 m: RTK fixes (2 cm per axis) give the course after 1.6 m, single-point fixes
    /// (1.5 m) after 5 m (with a one-sigma of 24 deg, returned).
    fn default() -> Self {
        Self {
            max_std_rad: DEG,
            max_distance_m: 5.0,
        }
    }
}

/// A course over ground and its one-sigma ([`course_from_displacement`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Course {
    /// Course `atan2(east, north)`, rad.
    pub yaw_rad: f64,
    /// One-sigma of the course from the position noise, rad.
    pub std_rad: f64,
    /// Horizontal length of the displacement, m.
    pub distance_m: f64,
}

/// The heading from the GNSS course over a displacement `north_m`, `east_m` (m) between two
/// positions whose horizontal one-sigmas per axis combine to `sigma_m` (m,
/// `hypot(s_a, s_b)`), when the displacement is long enough ([`CourseRule`]): at least
/// `sigma_m / max_std_rad`, or at least `max_distance_m` whatever the noise. `None` when it is
/// shorter, or an input is not finite or `sigma_m` is negative.
///
/// Why a length from the position noise rather than a speed: a slow vehicle with precise
/// fixes has a well-defined course long before it reaches a speed at which a velocity course
/// is usable. A slow rover moving at 0.2 m/s with RTK fixes (2 cm) every 3 s: 0.6 m
/// between fixes, where a 1-deg course needs 1.6 m (the third fix after it starts); a speed
/// threshold (0.5 m/s by default) never triggers, and a fixed 5 m look-ahead takes the chord
/// across its first turn. [`TrackCourse`] then extends the course while the track stays
/// straight, so a car driving off straight still gets the course over 5 m.
pub fn course_from_displacement(
    north_m: f64,
    east_m: f64,
    sigma_m: f64,
    rule: &CourseRule,
) -> Option<Course> {
    if !(north_m.is_finite() && east_m.is_finite() && sigma_m.is_finite() && sigma_m >= 0.0) {
        return None;
    }
    let d = sqrt(north_m * north_m + east_m * east_m);
    let need = if rule.max_std_rad > 0.0 {
        (sigma_m / rule.max_std_rad).min(rule.max_distance_m)
    } else {
        rule.max_distance_m
    };
    if !(d > 0.0 && d >= need) {
        return None;
    }
    Some(Course {
        yaw_rad: atan2(east_m, north_m),
        std_rad: sigma_m / d,
        distance_m: d,
    })
}

/// The GNSS course over the first metres of a track ([`CourseRule`]), fix by fix, allocation
/// free: the displacement from the start to the first fix far enough away for the course
/// ([`course_from_displacement`]) gives a course, which is then extended to later fixes while
/// the track stays straight, up to [`CourseRule::max_distance_m`]: a segment between
/// consecutive fixes whose direction differs from the course by more than 3 sigma (the
/// segment's and the course's) is a turn, and the course found before it is kept.
///
/// On a straight start this is the course over [`CourseRule::max_distance_m`] (the longest
/// baseline); a vehicle that turns soon after it starts (a slow rover: 0.2 m/s, fixes
/// every 3 s, a turn after 2 m) keeps the course of its straight part instead of the chord
/// across the turn.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackCourse {
    rule: CourseRule,
    best: Option<Course>,
    last_ne_m: Option<[f64; 2]>,
    settled: bool,
}

impl TrackCourse {
    /// A course to be found with `rule`.
    pub fn new(rule: CourseRule) -> Self {
        Self {
            rule,
            best: None,
            last_ne_m: None,
            settled: false,
        }
    }

    /// Feeds the next fix: its horizontal displacement from the start position `north_m`,
    /// `east_m` (m), the combined one-sigma of start and fix `sigma_m` (m, as for
    /// [`course_from_displacement`]) and the fix's own horizontal one-sigma `fix_sigma_m`
    /// (m). Returns true once the course is settled (later fixes change nothing).
    pub fn push(&mut self, north_m: f64, east_m: f64, sigma_m: f64, fix_sigma_m: f64) -> bool {
        if self.settled || !(north_m.is_finite() && east_m.is_finite()) {
            return self.settled;
        }
        if let (Some(c), Some([ln, le])) = (self.best, self.last_ne_m) {
            let (sn, se) = (north_m - ln, east_m - le);
            let len = sqrt(sn * sn + se * se);
            if len > 0.0 && fix_sigma_m.is_finite() {
                let seg_std = core::f64::consts::SQRT_2 * fix_sigma_m.abs() / len;
                let mut dev = atan2(se, sn) - c.yaw_rad;
                while dev > core::f64::consts::PI {
                    dev -= 2.0 * core::f64::consts::PI;
                }
                while dev < -core::f64::consts::PI {
                    dev += 2.0 * core::f64::consts::PI;
                }
                if dev.abs() > 3.0 * sqrt(seg_std * seg_std + c.std_rad * c.std_rad) {
                    self.settled = true;
                    return true;
                }
            }
        }
        self.last_ne_m = Some([north_m, east_m]);
        if let Some(c) = course_from_displacement(north_m, east_m, sigma_m, &self.rule) {
            self.settled = c.distance_m >= self.rule.max_distance_m;
            self.best = Some(c);
        }
        self.settled
    }

    /// The course found so far (`None` before a fix far enough away).
    pub fn course(&self) -> Option<Course> {
        self.best
    }
}
