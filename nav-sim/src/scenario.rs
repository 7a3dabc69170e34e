//! Motion scenarios: a small TOML description (start, IMU rate, a list of manoeuvre segments)
//! and its compilation into smooth kinematic profiles of time.
//!
//! Every profile is built from one C-infinity transition function `S(x)` (0 for x <= 0, 1 for
//! x >= 1, all derivatives zero at both ends; see [`smooth_step`]), so speed, yaw rate, pitch
//! and roll have no discontinuity in any derivative: the specific force and angular rate of the
//! vehicle are smooth functions of time.
//!
//! Vehicle model: a non-holonomic land vehicle. The velocity is along the body x axis (FRD
//! body = vehicle frame); pitch equals the road grade; roll is a small outward lean in turns
//! proportional to the lateral acceleration (`roll_per_g_deg`).

use serde::{Deserialize, Serialize};
use std::path::Path;

/// Standard gravity used to express lateral acceleration in g (roll model), m/s^2.
const G0: f64 = nav_core::earth::G0_MPS2;

/// Errors in a scenario description.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file could not be read.
    #[error("scenario {path}: {source}")]
    Io {
        /// File path.
        path: String,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The TOML could not be parsed (message carries line and column).
    #[error("scenario {path}: {source}")]
    Parse {
        /// File path (or `<string>`).
        path: String,
        /// The TOML parser's error.
        source: toml::de::Error,
    },
    /// A value is out of range or inconsistent.
    #[error("scenario: {0}")]
    Invalid(String),
    /// A segment is inconsistent with the vehicle state when it starts.
    #[error("scenario segment {index} ({kind}): {msg}")]
    Segment {
        /// Zero-based index of the segment in the file.
        index: usize,
        /// Segment kind.
        kind: &'static str,
        /// What is wrong.
        msg: String,
    },
}

/// Start of the scenario: position, heading and GPS time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Start {
    /// Geodetic latitude, degrees.
    pub lat_deg: f64,
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// Ellipsoidal height, m.
    pub h_m: f64,
    /// Initial heading (yaw of the body x axis from north, clockwise), degrees.
    pub heading_deg: f64,
    /// GPS week number.
    pub gps_week: u16,
    /// GPS seconds of week of the first IMU epoch, s.
    pub sow_s: f64,
}

/// IMU sampling and the simulator's internal integration rate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImuRate {
    /// IMU output rate, Hz.
    #[serde(default = "default_rate_hz")]
    pub rate_hz: f64,
    /// Internal RK4 sub-steps per IMU interval (the increments are integrated at
    /// `rate_hz * substeps`).
    #[serde(default = "default_substeps")]
    pub substeps: u32,
}

fn default_rate_hz() -> f64 {
    200.0
}
fn default_substeps() -> u32 {
    4
}

impl Default for ImuRate {
    fn default() -> Self {
        Self {
            rate_hz: default_rate_hz(),
            substeps: default_substeps(),
        }
    }
}

/// Vehicle parameters of the motion model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Vehicle {
    /// Outward body roll per g of lateral (centripetal) acceleration, degrees per g.
    #[serde(default = "default_roll_per_g")]
    pub roll_per_g_deg: f64,
    /// Default duration of the yaw-rate ramps at the start and end of a turn, s.
    #[serde(default = "default_turn_ramp")]
    pub turn_ramp_s: f64,
    /// Side slip of the body (constraint point) per m/s^2 of lateral acceleration, degrees per
    /// m/s^2: the velocity points `slip` to the outside of the body x axis, so the
    /// non-holonomic constraint is violated by `speed * sin(slip)` in turns (0: none; a
    /// passenger car: about 0.2 to 0.5).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub slip_deg_per_mps2: f64,
    /// Bounce: amplitude of a vertical velocity oscillation of the body while it moves, m/s
    /// (sum of three incommensurate sines 1.1 / 1.9 / 3.3 Hz of relative amplitudes
    /// 1 / 0.6 / 0.3, faded in with speed up to 5 m/s; 0: none; a car on a normal road: about
    /// 0.02 to 0.05).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub bounce_mps: f64,
    /// A wheel-speed odometer (`[vehicle.odometer]`): a case simulated by `host-sim` gets
    /// `odometer.txt` (`nav_sim::odometer`); none when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub odometer: Option<WheelSpeedSpec>,
    /// A dual-antenna GNSS heading (`[vehicle.heading]`): a case simulated by `host-sim` gets
    /// `heading.txt` (`nav_sim::heading`); none when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heading: Option<HeadingSpec>,
}

/// What the simulated dual-antenna heading measures (`[vehicle.heading]` of a scenario): the
/// azimuth of the antenna baseline (fixed in the body frame) from the true attitude, plus
/// white noise, at its own rate, with the sigma written in each line.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeadingSpec {
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// White-noise 1-sigma, deg (also written as the sample's sigma).
    pub sigma_deg: f64,
    /// Baseline from the primary to the secondary antenna, body FRD, m.
    #[serde(default = "default_baseline")]
    pub baseline_m: [f64; 3],
}

fn default_baseline() -> [f64; 3] {
    [1.0, 0.0, 0.0]
}

/// What the simulated odometer measures (`[vehicle.odometer]` of a scenario).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WheelSpeedSpec {
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Scale-factor error: measured = (1 + scale) true.
    pub scale: f64,
    /// White-noise 1-sigma, m/s.
    pub sigma_mps: f64,
    /// The measured point (rear-axle centre) from the IMU, body FRD, m.
    #[serde(default)]
    pub lever_arm_m: [f64; 3],
}

fn default_roll_per_g() -> f64 {
    4.0
}
fn default_turn_ramp() -> f64 {
    2.0
}

impl Default for Vehicle {
    fn default() -> Self {
        Self {
            roll_per_g_deg: default_roll_per_g(),
            turn_ramp_s: default_turn_ramp(),
            slip_deg_per_mps2: 0.0,
            bounce_mps: 0.0,
            odometer: None,
            heading: None,
        }
    }
}

/// One manoeuvre. Speeds in m/s, durations in s, angles in degrees (positive = right turn,
/// clockwise seen from above), lengths and heights in m.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Segment {
    /// Standing still (speed must be zero).
    Static {
        /// Duration, s.
        duration_s: f64,
    },
    /// Speed increase (smooth, zero jerk at both ends).
    Accelerate {
        /// Speed change, m/s (positive); alternative to `to_speed_mps`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        delta_speed_mps: Option<f64>,
        /// Target speed, m/s; alternative to `delta_speed_mps`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        to_speed_mps: Option<f64>,
        /// Duration, s.
        duration_s: f64,
    },
    /// Speed decrease.
    Brake {
        /// Speed decrease, m/s (positive); alternative to `to_speed_mps`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        delta_speed_mps: Option<f64>,
        /// Target speed, m/s; alternative to `delta_speed_mps`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        to_speed_mps: Option<f64>,
        /// Duration, s.
        duration_s: f64,
    },
    /// Constant speed, straight and level.
    Cruise {
        /// Duration, s.
        duration_s: f64,
    },
    /// Heading change at constant speed: the yaw rate ramps up, holds, and ramps down.
    Turn {
        /// Heading change, degrees (positive = right).
        angle_deg: f64,
        /// Yaw rate on the hold part, deg/s (magnitude); alternative to `radius_m`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        rate_deg_s: Option<f64>,
        /// Turn radius on the hold part, m; alternative to `rate_deg_s`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        radius_m: Option<f64>,
        /// Yaw-rate ramp duration, s (default: the vehicle's `turn_ramp_s`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        ramp_s: Option<f64>,
    },
    /// Height change over a path length at constant speed: the grade (pitch) ramps to a
    /// plateau and back to level.
    Hill {
        /// Height change, m (positive = up).
        height_m: f64,
        /// Path length travelled in the segment, m.
        length_m: f64,
        /// Grade ramp duration, s (default: a quarter of the segment).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        ramp_s: Option<f64>,
    },
    /// Brake to standstill.
    Stop {
        /// Duration, s (default: speed / 1.5 m/s^2).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        duration_s: Option<f64>,
    },
}

impl Segment {
    /// The segment kind as written in the file.
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Static { .. } => "static",
            Self::Accelerate { .. } => "accelerate",
            Self::Brake { .. } => "brake",
            Self::Cruise { .. } => "cruise",
            Self::Turn { .. } => "turn",
            Self::Hill { .. } => "hill",
            Self::Stop { .. } => "stop",
        }
    }
}

/// A motion scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Short name.
    #[serde(default)]
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Start position, heading and time.
    pub start: Start,
    /// IMU rate and internal integration rate.
    #[serde(default)]
    pub imu: ImuRate,
    /// Vehicle model parameters.
    #[serde(default)]
    pub vehicle: Vehicle,
    /// The manoeuvres, in order.
    #[serde(rename = "segment", default)]
    pub segments: Vec<Segment>,
}

impl Scenario {
    /// Parses a scenario from TOML text; `origin` names the source in errors.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, ScenarioError> {
        let s: Scenario = toml::from_str(text).map_err(|source| ScenarioError::Parse {
            path: origin.to_string(),
            source,
        })?;
        s.compile()?;
        Ok(s)
    }

    /// Reads and validates a scenario file.
    pub fn from_file(path: &Path) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|e| ScenarioError::Io {
            path: path.display().to_string(),
            source: e,
        })?;
        Self::from_toml_str(&text, &path.display().to_string())
    }

    /// The scenario as TOML text.
    pub fn to_toml_string(&self) -> String {
        toml::to_string(self).unwrap_or_default()
    }

    /// IMU sampling interval, s.
    pub fn dt_s(&self) -> f64 {
        1.0 / self.imu.rate_hz
    }

    /// Total duration, s (a whole number of IMU intervals, rounded down).
    pub fn duration_s(&self) -> Result<f64, ScenarioError> {
        Ok(self.compile()?.duration_s)
    }

    /// Validates the scenario and builds its time profile.
    pub fn compile(&self) -> Result<Profile, ScenarioError> {
        self.check_start_and_vehicle()?;
        let st = &self.start;
        let v = &self.vehicle;
        if self.segments.is_empty() {
            return Err(ScenarioError::Invalid("no [[segment]]".into()));
        }
        let mut pieces = Vec::with_capacity(self.segments.len());
        let mut t = 0.0;
        let mut speed = 0.0f64;
        for (index, seg) in self.segments.iter().enumerate() {
            let (dur, shape) = segment_shape(seg, index, &mut speed, v.turn_ramp_s)?;
            pieces.push(Piece {
                t0_s: t,
                t1_s: t + dur,
                speed0_mps: match shape {
                    Shape::Speed { delta_mps } => speed - delta_mps,
                    _ => speed,
                },
                shape,
            });
            t += dur;
        }
        let dt = self.dt_s();
        let n = (t / dt + 1e-9).floor();
        let duration_s = n * dt;
        if st.sow_s + duration_s >= 604_800.0 {
            return Err(ScenarioError::Invalid(format!(
                "scenario ({duration_s} s from sow {}) crosses the end of the GPS week",
                st.sow_s
            )));
        }
        Ok(Profile {
            pieces,
            duration_s,
            roll_rad_per_mps2: v.roll_per_g_deg.to_radians() / G0,
            slip_rad_per_mps2: v.slip_deg_per_mps2.to_radians(),
            bounce_mps: v.bounce_mps,
        })
    }

    /// Checks the start (position, heading, time), the IMU rate and sub-steps and the
    /// vehicle's settings (roll, turn ramp, odometer, heading sensor).
    fn check_start_and_vehicle(&self) -> Result<(), ScenarioError> {
        let st = &self.start;
        if !(st.lat_deg.abs() < 89.0 && st.lon_deg.is_finite() && st.h_m.is_finite()) {
            return Err(ScenarioError::Invalid(format!(
                "start position ({}, {}, {}) is not a valid position below 89 degrees latitude",
                st.lat_deg, st.lon_deg, st.h_m
            )));
        }
        if !(st.heading_deg.is_finite() && st.sow_s >= 0.0 && st.sow_s < 604_800.0) {
            return Err(ScenarioError::Invalid(format!(
                "start heading {} deg or sow {} s out of range",
                st.heading_deg, st.sow_s
            )));
        }
        if !(self.imu.rate_hz >= 1.0 && self.imu.rate_hz <= 10_000.0) {
            return Err(ScenarioError::Invalid(format!(
                "imu.rate_hz = {} outside [1, 10000]",
                self.imu.rate_hz
            )));
        }
        if !(1..=100).contains(&self.imu.substeps) {
            return Err(ScenarioError::Invalid(format!(
                "imu.substeps = {} outside [1, 100]",
                self.imu.substeps
            )));
        }
        let v = &self.vehicle;
        if !(v.roll_per_g_deg.abs() <= 30.0 && v.turn_ramp_s > 0.0) {
            return Err(ScenarioError::Invalid(format!(
                "vehicle.roll_per_g_deg = {} or turn_ramp_s = {} out of range",
                v.roll_per_g_deg, v.turn_ramp_s
            )));
        }
        if let Some(o) = &v.odometer {
            if !(o.rate_hz.is_finite()
                && o.rate_hz > 0.0
                && o.scale.is_finite()
                && o.sigma_mps.is_finite()
                && o.sigma_mps >= 0.0
                && o.lever_arm_m.iter().all(|x| x.is_finite()))
            {
                return Err(ScenarioError::Invalid(format!(
                    "vehicle.odometer: rate_hz = {} (> 0), scale = {}, sigma_mps = {} (>= 0) \
                     or lever_arm_m out of range",
                    o.rate_hz, o.scale, o.sigma_mps
                )));
            }
        }
        if let Some(h) = &v.heading {
            let b = h.baseline_m;
            if !(h.rate_hz.is_finite()
                && h.rate_hz > 0.0
                && h.sigma_deg.is_finite()
                && h.sigma_deg > 0.0
                && b.iter().all(|x| x.is_finite())
                && b[0].hypot(b[1]) > 0.0)
            {
                return Err(ScenarioError::Invalid(format!(
                    "vehicle.heading: rate_hz = {} (> 0), sigma_deg = {} (> 0) or baseline_m \
                     {b:?} (finite, with a horizontal part) out of range",
                    h.rate_hz, h.sigma_deg
                )));
            }
        }
        Ok(())
    }
}

/// Finds the plateau grade (rad) so that a hill of duration `dur` s at `speed` m/s with grade
/// ramps of `ramp` s climbs `height` m; `None` when it needs more than 25 degrees.
fn solve_hill_grade(height: f64, speed: f64, dur: f64, ramp: f64) -> Option<f64> {
    let climb = |g: f64| -> f64 {
        // Simpson on the ramp (C-infinity integrand, 400 panels is exact to ~1e-12 relative).
        let n = 400;
        let h = 1.0 / n as f64;
        let mut acc = 0.0;
        for i in 0..=n {
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            acc += w * (g * smooth_step(i as f64 * h)).sin();
        }
        let ramp_int = acc * h / 3.0;
        speed * ((dur - 2.0 * ramp) * g.sin() + 2.0 * ramp * ramp_int)
    };
    let (mut lo, mut hi) = (-25f64.to_radians(), 25f64.to_radians());
    if height < climb(lo) || height > climb(hi) {
        return None;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if climb(mid) < height {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi))
}

/// C-infinity transition from 0 (x <= 0) to 1 (x >= 1): `S(x) = 1 / (1 + e^(1/x - 1/(1-x)))`.
/// All derivatives vanish at both ends, `S(x) + S(1-x) = 1`, the integral over [0, 1] is 1/2
/// and the largest slope is `S'(1/2) = 2`.
pub fn smooth_step(x: f64) -> f64 {
    smooth_step_d(x).0
}

/// `S(x)`, `S'(x)` and `S''(x)` of [`smooth_step`].
pub fn smooth_step_d(x: f64) -> (f64, f64, f64) {
    if x <= 0.0 {
        return (0.0, 0.0, 0.0);
    }
    if x >= 1.0 {
        return (1.0, 0.0, 0.0);
    }
    let y = 1.0 - x;
    let z = 1.0 / x - 1.0 / y;
    // S = logistic(-z), written to avoid overflow of e^z.
    let s = if z > 0.0 {
        let e = (-z).exp();
        e / (1.0 + e)
    } else {
        1.0 / (1.0 + z.exp())
    };
    let p = s * (1.0 - s);
    let g = 1.0 / (x * x) + 1.0 / (y * y);
    let dg = -2.0 / (x * x * x) + 2.0 / (y * y * y);
    let ds = p * g;
    let dp = ds * (1.0 - 2.0 * s);
    (s, ds, dp * g + p * dg)
}

/// Shape of one compiled segment.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Shape {
    /// Constant speed, level, straight.
    Constant,
    /// Speed change by `delta_mps` over the whole piece.
    Speed { delta_mps: f64 },
    /// Yaw-rate plateau `rate_radps` with ramps of `ramp_s`.
    Turn { rate_radps: f64, ramp_s: f64 },
    /// Grade plateau `grade_rad` with ramps of `ramp_s`.
    Hill { grade_rad: f64, ramp_s: f64 },
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Piece {
    t0_s: f64,
    t1_s: f64,
    speed0_mps: f64,
    shape: Shape,
}

/// The kinematic quantities of the vehicle at one time that do not need integration.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Kinematics {
    /// Speed along the body x axis, m/s.
    pub speed_mps: f64,
    /// Its time derivative, m/s^2.
    pub speed_dot_mps2: f64,
    /// Yaw (heading) rate, rad/s.
    pub yaw_rate_radps: f64,
    /// Pitch (= road grade), rad.
    pub pitch_rad: f64,
    /// Pitch rate, rad/s.
    pub pitch_rate_radps: f64,
    /// Roll, rad.
    pub roll_rad: f64,
    /// Roll rate, rad/s.
    pub roll_rate_radps: f64,
    /// Side-slip angle: velocity heading minus body heading, rad (0 without slip).
    pub slip_rad: f64,
    /// Its rate, rad/s.
    pub slip_rate_radps: f64,
    /// Vertical (down) velocity of the bounce added to the NED velocity, m/s.
    pub bounce_vel_mps: f64,
    /// Its time derivative, m/s^2.
    pub bounce_acc_mps2: f64,
}

/// A compiled scenario: smooth kinematics as functions of time since the start.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    pieces: Vec<Piece>,
    /// Total duration, s (whole IMU intervals).
    pub duration_s: f64,
    roll_rad_per_mps2: f64,
    slip_rad_per_mps2: f64,
    bounce_mps: f64,
}

/// Plateau function on [0, len] with C-infinity ramps of `ramp` s: value and derivative.
fn plateau(tau: f64, len: f64, ramp: f64) -> (f64, f64) {
    if tau < ramp {
        let (s, ds, _) = smooth_step_d(tau / ramp);
        (s, ds / ramp)
    } else if tau > len - ramp {
        let (s, ds, _) = smooth_step_d((len - tau) / ramp);
        (s, -ds / ramp)
    } else {
        (1.0, 0.0)
    }
}

/// Plateau value, first and second derivative.
fn plateau2(tau: f64, len: f64, ramp: f64) -> (f64, f64, f64) {
    if tau < ramp {
        let (s, ds, dds) = smooth_step_d(tau / ramp);
        (s, ds / ramp, dds / (ramp * ramp))
    } else if tau > len - ramp {
        let (s, ds, dds) = smooth_step_d((len - tau) / ramp);
        (s, -ds / ramp, dds / (ramp * ramp))
    } else {
        (1.0, 0.0, 0.0)
    }
}

impl Profile {
    /// Kinematics at `t_s` seconds after the start (clamped to the scenario).
    pub fn eval(&self, t_s: f64) -> Kinematics {
        let i = self
            .pieces
            .partition_point(|p| p.t1_s <= t_s)
            .min(self.pieces.len().saturating_sub(1));
        let Some(p) = self.pieces.get(i) else {
            return Kinematics::default();
        };
        let tau = (t_s - p.t0_s).clamp(0.0, p.t1_s - p.t0_s);
        let len = p.t1_s - p.t0_s;
        let mut k = Kinematics {
            speed_mps: p.speed0_mps,
            ..Default::default()
        };
        let mut yaw_acc = 0.0;
        match p.shape {
            Shape::Constant => {}
            Shape::Speed { delta_mps } => {
                let (s, ds, _) = smooth_step_d(tau / len);
                k.speed_mps = p.speed0_mps + delta_mps * s;
                k.speed_dot_mps2 = delta_mps * ds / len;
            }
            Shape::Turn { rate_radps, ramp_s } => {
                let (s, ds, _) = plateau2(tau, len, ramp_s);
                k.yaw_rate_radps = rate_radps * s;
                yaw_acc = rate_radps * ds;
            }
            Shape::Hill { grade_rad, ramp_s } => {
                let (s, ds) = plateau(tau, len, ramp_s);
                k.pitch_rad = grade_rad * s;
                k.pitch_rate_radps = grade_rad * ds;
            }
        }
        // Outward lean: a right turn (positive yaw rate) accelerates the vehicle to the right,
        // the body rolls left (negative roll).
        let lat_acc = k.speed_mps * k.yaw_rate_radps;
        let lat_acc_dot = k.speed_dot_mps2 * k.yaw_rate_radps + k.speed_mps * yaw_acc;
        k.roll_rad = -self.roll_rad_per_mps2 * lat_acc;
        k.roll_rate_radps = -self.roll_rad_per_mps2 * lat_acc_dot;
        // side slip: the velocity turns outward of the body x axis (a right turn: the body's
        // nose points right of the velocity, i.e. the velocity is to the left in the body)
        k.slip_rad = self.slip_rad_per_mps2 * lat_acc;
        k.slip_rate_radps = self.slip_rad_per_mps2 * lat_acc_dot;
        if self.bounce_mps != 0.0 {
            // faded in with speed: smooth_step of speed / 5 m/s
            // (below 0.01 m/s the step is exp(-500) = 0; its derivative formula would be 0 * inf)
            let x = k.speed_mps / 5.0;
            let (fade, dfade, _) = if x > 2e-3 {
                smooth_step_d(x)
            } else {
                (0.0, 0.0, 0.0)
            };
            let dfade_dt = dfade / 5.0 * k.speed_dot_mps2;
            let mut b = 0.0;
            let mut db = 0.0;
            for (f_hz, a, ph) in [(1.1, 1.0, 0.0), (1.9, 0.6, 1.3), (3.3, 0.3, 2.1)] {
                let w = 2.0 * std::f64::consts::PI * f_hz;
                b += a * (w * t_s + ph).sin();
                db += a * w * (w * t_s + ph).cos();
            }
            k.bounce_vel_mps = self.bounce_mps * fade * b;
            k.bounce_acc_mps2 = self.bounce_mps * (fade * db + dfade_dt * b);
        }
        k
    }

    /// Number of segments.
    pub fn num_segments(&self) -> usize {
        self.pieces.len()
    }

    /// Start and end time of segment `i` (seconds after the start).
    pub fn segment_span_s(&self, i: usize) -> Option<(f64, f64)> {
        self.pieces.get(i).map(|p| (p.t0_s, p.t1_s))
    }
}

/// Whether a value is exactly zero (a vehicle effect that is off is not written, so a
/// scenario without it reads in earlier versions of the tools).
fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// The duration (s) and kinematic shape of segment `index`, entered at `speed_io` (m/s), which
/// it updates to the segment's exit speed; `turn_ramp_s` is the vehicle's default turn ramp.
fn segment_shape(
    seg: &Segment,
    index: usize,
    speed_io: &mut f64,
    turn_ramp_s: f64,
) -> Result<(f64, Shape), ScenarioError> {
    let mut speed = *speed_io;
    let c = SegCheck {
        index,
        kind: seg.kind(),
    };
    let shaped = match seg {
        Segment::Static { duration_s } => {
            if speed != 0.0 {
                return Err(c.err(format!(
                    "vehicle moves at {speed} m/s: add a `stop` segment first"
                )));
            }
            (c.positive("duration_s", *duration_s)?, Shape::Constant)
        }
        Segment::Cruise { duration_s } => (c.positive("duration_s", *duration_s)?, Shape::Constant),
        Segment::Accelerate {
            delta_speed_mps,
            to_speed_mps,
            duration_s,
        }
        | Segment::Brake {
            delta_speed_mps,
            to_speed_mps,
            duration_s,
        } => {
            let sign = if matches!(seg, Segment::Accelerate { .. }) {
                1.0
            } else {
                -1.0
            };
            let target = match (delta_speed_mps, to_speed_mps) {
                (Some(d), None) => speed + sign * c.positive("delta_speed_mps", *d)?,
                (None, Some(v)) => *v,
                _ => {
                    return Err(c.err("give exactly one of delta_speed_mps and to_speed_mps".into()))
                }
            };
            if !(target.is_finite() && (0.0..=100.0).contains(&target))
                || sign * (target - speed) <= 0.0
            {
                return Err(c.err(format!(
                    "target speed {target} m/s from {speed} m/s is not a valid {}",
                    c.kind
                )));
            }
            let d = c.positive("duration_s", *duration_s)?;
            let delta = target - speed;
            speed = target;
            (d, Shape::Speed { delta_mps: delta })
        }
        Segment::Stop { duration_s } => {
            if speed <= 0.0 {
                return Err(c.err("vehicle is already at rest".into()));
            }
            let d = match duration_s {
                Some(d) => c.positive("duration_s", *d)?,
                None => speed / 1.5,
            };
            let delta = -speed;
            speed = 0.0;
            (d, Shape::Speed { delta_mps: delta })
        }
        Segment::Turn {
            angle_deg,
            rate_deg_s,
            radius_m,
            ramp_s,
        } => turn_shape(
            &c,
            *angle_deg,
            *rate_deg_s,
            *radius_m,
            *ramp_s,
            speed,
            turn_ramp_s,
        )?,
        Segment::Hill {
            height_m,
            length_m,
            ramp_s,
        } => hill_shape(&c, *height_m, *length_m, *ramp_s, speed)?,
    };
    *speed_io = speed;
    Ok(shaped)
}

/// The segment being compiled, for its error messages.
struct SegCheck {
    index: usize,
    kind: &'static str,
}

impl SegCheck {
    /// An error about this segment.
    fn err(&self, msg: String) -> ScenarioError {
        ScenarioError::Segment {
            index: self.index,
            kind: self.kind,
            msg,
        }
    }

    /// `x` when positive, finite and below 1e6; else an error naming `name`.
    fn positive(&self, name: &str, x: f64) -> Result<f64, ScenarioError> {
        if x.is_finite() && x > 0.0 && x < 1e6 {
            Ok(x)
        } else {
            Err(self.err(format!("{name} = {x} must be positive and finite")))
        }
    }
}

/// A turn's duration (s) and shape: by `angle_deg` at `rate_deg_s` or on `radius_m` at the
/// entry `speed` (m/s), with ramps of `ramp_s` (default `turn_ramp_s`).
fn turn_shape(
    c: &SegCheck,
    angle_deg: f64,
    rate_deg_s: Option<f64>,
    radius_m: Option<f64>,
    ramp_s: Option<f64>,
    speed: f64,
    turn_ramp_s: f64,
) -> Result<(f64, Shape), ScenarioError> {
    if !(angle_deg.is_finite() && angle_deg != 0.0 && angle_deg.abs() <= 3600.0) {
        return Err(c.err(format!("angle_deg = {angle_deg} out of range")));
    }
    let rate = match (rate_deg_s, radius_m) {
        (Some(r), None) => c.positive("rate_deg_s", r)?.to_radians(),
        (None, Some(rad)) => {
            if speed < 0.5 {
                return Err(c.err(format!(
                    "a turn by radius needs speed >= 0.5 m/s (is {speed})"
                )));
            }
            speed / c.positive("radius_m", rad)?
        }
        _ => return Err(c.err("give exactly one of rate_deg_s and radius_m".into())),
    };
    let angle = angle_deg.to_radians();
    let ramp = match ramp_s {
        Some(r) => c.positive("ramp_s", r)?,
        None => turn_ramp_s,
    };
    // Heading change = rate * (hold + ramp); if the angle is too small for a
    // full ramp, shorten the ramps (no hold).
    let ramp = ramp.min(angle.abs() / rate);
    let dur = angle.abs() / rate + ramp;
    Ok((
        dur,
        Shape::Turn {
            rate_radps: rate * angle.signum(),
            ramp_s: ramp,
        },
    ))
}

/// A hill's duration (s) and shape: `height_m` over `length_m` at the entry `speed` (m/s),
/// with grade ramps of `ramp_s` (default a quarter of the hill).
fn hill_shape(
    c: &SegCheck,
    height_m: f64,
    length_m: f64,
    ramp_s: Option<f64>,
    speed: f64,
) -> Result<(f64, Shape), ScenarioError> {
    if speed < 0.5 {
        return Err(c.err(format!("a hill needs speed >= 0.5 m/s (is {speed})")));
    }
    let len = c.positive("length_m", length_m)?;
    if !height_m.is_finite() || height_m.abs() >= 0.3 * len {
        return Err(c.err(format!(
            "height_m = {height_m} must be finite and below 30% of length_m"
        )));
    }
    let dur = len / speed;
    let ramp = match ramp_s {
        Some(r) => c.positive("ramp_s", r)?.min(dur / 2.0),
        None => dur / 4.0,
    };
    let grade = solve_hill_grade(height_m, speed, dur, ramp).ok_or_else(|| {
        c.err(format!(
            "no grade below 25 degrees climbs {height_m} m in {len} m"
        ))
    })?;
    Ok((
        dur,
        Shape::Hill {
            grade_rad: grade,
            ramp_s: ramp,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smooth_step_derivatives_match_finite_differences() {
        for &x in &[0.05, 0.2, 0.5, 0.7, 0.93] {
            let h = 1e-6;
            let (s, ds, dds) = smooth_step_d(x);
            let (sp, dsp, _) = smooth_step_d(x + h);
            let (sm, dsm, _) = smooth_step_d(x - h);
            assert!(((sp - sm) / (2.0 * h) - ds).abs() < 1e-6, "{x}");
            assert!(((dsp - dsm) / (2.0 * h) - dds).abs() < 1e-4, "{x}");
            assert!((s + smooth_step(1.0 - x) - 1.0).abs() < 1e-15);
        }
        assert!((smooth_step_d(0.5).1 - 2.0).abs() < 1e-12);
    }

    #[test]
    fn hill_grade_solution_climbs_the_requested_height() {
        let g = solve_hill_grade(10.0, 15.0, 20.0, 5.0).unwrap();
        // Numerically integrate the climb.
        let n = 200_000;
        let mut h = 0.0;
        for i in 0..n {
            let t = (i as f64 + 0.5) * 20.0 / n as f64;
            h += 15.0 * (g * plateau(t, 20.0, 5.0).0).sin() * 20.0 / n as f64;
        }
        assert!((h - 10.0).abs() < 1e-6, "{h}");
    }
}
