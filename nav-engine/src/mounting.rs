//! Checks of the configured IMU mounting, units, sample rate and GNSS time against the data.
//! The body frame is FRD (x forward, y right, z down); after the configured mounting rotation
//! the increments are in body axes. Two cues:
//!
//! * **turns**: while the vehicle moves (GNSS horizontal speed >= [`MIN_SPEED_MPS`]) the body z
//!   gyro must turn WITH the GNSS course: over GNSS intervals with a course rate of at least
//!   [`MIN_TURN_RATE_DEG_S`] the least-squares slope of the mean z rate against the course
//!   rate is close to +1 for a correct mounting (cos of the tilt), near -1 for an upside-down
//!   z axis and near 0 for a horizontal one;
//! * **gravity at rest**: while the GNSS speed stays below [`REST_SPEED_MPS`], the mean
//!   specific force points along body -z (about (0, 0, -g)).
//!
//! Either cue that contradicts the mounting gives a warning naming it and the way out. Course
//! rates from GNSS intervals whose velocity jumps by more than [`MAX_GNSS_ACCEL_MPS2`] (a
//! position outlier) are not used: one bad fix does not blame the mounting.
//!
//! The same cues name what is not the mounting, with the setting to change:
//!
//! * the SIZE of the specific force at rest: 1 m/s^2 is data in g read as m/s^2, 96 m/s^2 the
//!   reverse; for increments, any other multiple of g is the ratio of the interval the
//!   increments cover to the one their time stamps give (increments of 100 Hz stamped at
//!   200 Hz give 2 g); the turn checks are then not made;
//! * the turn slope: 57.3 is a gyro in deg/s read as rad/s, 1/57.3 the reverse;
//! * the GNSS time offset: the z gyro is binned at [`LAG_BIN_S`] and the turning intervals'
//!   course rates are fitted to it with the fixes shifted by up to +-[`MAX_LAG_S`]; an offset
//!   of at least [`MIN_REPORTED_LAG_S`] that halves the residual is reported with its estimate.
//!
//! # Estimating the mounting ([`estimate_mounting`], `host-sim mounting --config FILE`)
//!
//! From IMU increments in SENSOR axes (the configured mounting ignored) and the GNSS fixes:
//! 1. the data are reduced to pairs (measured mean specific force and z rate over an interval,
//!    expected body values): at rest the specific force is (0, 0, -g); while moving (GNSS
//!    speed >= [`MIN_SPEED_MPS`]) the GNSS acceleration between consecutive interval
//!    velocities, minus gravity, turned by the course and the climb angle into a level-roll
//!    vehicle frame, gives the expected (along-track, lateral, vertical) specific force, and
//!    the course rate the expected body z rate;
//! 2. each of the 24 axis layouts (signed permutations with determinant +1) is scored by the
//!    RMS of (layout x measured - expected) over all pairs (rates weighted by the speed, so
//!    that both are m/s^2); the best layout and the runner-up's residual are reported;
//! 3. the fine angles: the rotation that best maps the measured specific forces onto the
//!    expected ones (Wahba's problem, solved by SVD), started from the best layout: roll and
//!    pitch come mostly from gravity, yaw from the along-track vs lateral acceleration; the
//!    body's own roll in turns (lean, banked roads) is unknown, so in turns the expected
//!    cross-track/vertical direction is taken from the data and the solution repeated;
//! 4. one-sigma of the angles from the residual scatter: roll/pitch ~ rms / (g sqrt(n)),
//!    yaw ~ rms / (rms horizontal acceleration sqrt(n_moving)).

use nalgebra::{Matrix3, Vector3};
use nav_core::attitude::euler_zyx_from_dcm;
use nav_core::earth::{self, Llh};
use nav_core::types::{GnssFix, ImuSample};
use std::collections::VecDeque;

mod slow;
pub use slow::{
    MAX_WINDOW_S, MAX_WINDOW_TURN_DEG, MIN_REST_INTERVALS, MIN_SLOW_SPEED_MPS, MIN_STARTS_STOPS,
};

/// Lowest GNSS horizontal speed for the course to be used, m/s.
pub const MIN_SPEED_MPS: f64 = 3.0;
/// Lowest course rate of an interval used in the turn test, deg/s.
pub const MIN_TURN_RATE_DEG_S: f64 = 3.0;
/// Highest GNSS speed counted as rest, m/s.
pub const REST_SPEED_MPS: f64 = 0.1;
/// Fewest turning intervals for a verdict from the turns.
pub const MIN_TURN_INTERVALS: usize = 5;
/// Longest GNSS interval used by the check, s.
pub const MAX_INTERVAL_S: f64 = 5.0;
/// Largest horizontal acceleration between two consecutive GNSS interval velocities for a
/// course rate to be used, m/s^2 (about 1 g: more than a car brakes or turns). A position
/// outlier of a few metres in one fix makes the two intervals it closes and opens jump by
/// far more; their course rates are not used.
pub const MAX_GNSS_ACCEL_MPS2: f64 = 10.0;
/// Normal gravity used to tell units and sample rates at rest, m/s^2.
pub const G_MPS2: f64 = 9.806_65;
/// Bin of the z rate record used to estimate the GNSS time offset, s.
pub const LAG_BIN_S: f64 = 0.05;
/// Largest GNSS time offset looked for, s.
pub const MAX_LAG_S: f64 = 2.0;
/// Smallest GNSS time offset reported, s.
pub const MIN_REPORTED_LAG_S: f64 = 0.1;
/// Most seconds of z rate kept for the time offset estimate (from the first sample).
pub const LAG_RECORD_S: f64 = 3600.0;
/// Most turning intervals kept for the time offset estimate.
const MAX_TURNS: usize = 4096;

/// What the IMU file holds, for the warnings to name the setting to change.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ImuInput {
    /// Increments with their time stamps (the text format, binary, a KF-GINS file): the
    /// increments' size at rest tells the interval they cover.
    #[default]
    Increments,
    /// Rates and specific forces of an IMU CSV mapped by `[imu.csv]` (`gyro_unit`,
    /// `accel_unit`): converted to increments over the stamped intervals.
    CsvRates,
}

/// What the data say about the configured mounting.
#[derive(Debug, Clone, PartialEq)]
pub struct MountingCheck {
    /// Least-squares slope of the body z rate against the GNSS course rate (+1 expected), and
    /// the number of turning intervals it is from; None with too few turns.
    pub turn_slope: Option<(f64, usize)>,
    /// Mean specific force at rest, body axes, m/s^2, and the seconds of rest it is from.
    pub rest_f_body_mps2: Option<([f64; 3], f64)>,
    /// Mean IMU sample interval at rest (from the time stamps), s.
    pub rest_dt_s: Option<f64>,
    /// Estimated GNSS time offset, s: the z gyro follows the GNSS course best when the
    /// fixes are taken this much later (negative: the fixes are stamped late; add it to
    /// `[gnss] time_offset_s`); None with too few turns.
    pub gnss_lag_s: Option<f64>,
    /// Warnings (empty when the data agree with the configuration).
    pub warnings: Vec<String>,
}

fn llh(g: &GnssFix) -> Llh {
    Llh {
        lat_rad: g.lat_rad,
        lon_rad: g.lon_rad,
        h_m: g.h_m,
    }
}

/// Horizontal NED velocity of the interval a -> b: the fixes' own velocities averaged when
/// both have one, otherwise the position difference.
fn interval_velocity(a: &GnssFix, b: &GnssFix) -> [f64; 2] {
    if a.has_velocity && b.has_velocity {
        [
            0.5 * (a.vel_ned_mps[0] + b.vel_ned_mps[0]),
            0.5 * (a.vel_ned_mps[1] + b.vel_ned_mps[1]),
        ]
    } else {
        let d = earth::ned_offset_m(&llh(a), &llh(b));
        let dt = b.t_s - a.t_s;
        [d.x / dt, d.y / dt]
    }
}

fn wrap_pi(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

/// Sum of increments of `imu` (time order) with times in (t0, t1], and the time they span.
fn sums(imu: &[ImuSample], t0: f64, t1: f64) -> ([f64; 3], [f64; 3], f64) {
    let (th, dv, span, _) = sums_n(imu, t0, t1);
    (th, dv, span)
}

/// [`sums`] and the number of samples summed.
fn sums_n(imu: &[ImuSample], t0: f64, t1: f64) -> ([f64; 3], [f64; 3], f64, usize) {
    let i0 = imu.partition_point(|s| s.t_s <= t0);
    let i1 = imu.partition_point(|s| s.t_s <= t1);
    let (mut th, mut dv) = ([0.0; 3], [0.0; 3]);
    let mut prev = imu.get(i0.wrapping_sub(1)).map(|s| s.t_s);
    let mut span = 0.0;
    for s in imu.get(i0..i1).unwrap_or(&[]) {
        for k in 0..3 {
            th[k] += s.dtheta_rad[k];
            dv[k] += s.dv_mps[k];
        }
        if let Some(p) = prev {
            span += s.t_s - p;
        }
        prev = Some(s.t_s);
    }
    (th, dv, span, i1.saturating_sub(i0))
}

/// Checks body-axis increments `imu` against the GNSS fixes `gnss` (see the module notes):
/// [`MountingChecker`] over the two lists.
pub fn check_mounting(imu: &[ImuSample], gnss: &[GnssFix]) -> MountingCheck {
    check_mounting_of(ImuInput::Increments, imu, gnss)
}

/// [`check_mounting`] of an IMU file holding `input` (named in the warnings).
pub fn check_mounting_of(input: ImuInput, imu: &[ImuSample], gnss: &[GnssFix]) -> MountingCheck {
    let mut c = MountingChecker::for_input(input);
    let mut fixes = gnss.iter().peekable();
    for s in imu {
        // the fixes up to this sample's time first: at most a few are pending at a time
        while let Some(g) = fixes.next_if(|g| g.t_s <= s.t_s) {
            c.push_fix(g);
        }
        c.push_imu(s);
    }
    for g in fixes {
        c.push_fix(g);
    }
    c.finish()
}

/// [`check_mounting`] as a stream: IMU samples (time order) and GNSS fixes (time order) pushed
/// as they are read, each fix at the latest before the first IMU sample after it (fixes may
/// come any time earlier). Memory: the IMU samples of the current and the previous GNSS
/// interval (intervals longer than [`MAX_INTERVAL_S`] are not used, so at most about twice
/// that of data) and the fixes pushed ahead of the IMU. The result is bit-identical to
/// [`check_mounting`] on the whole lists: each GNSS interval is taken once the IMU has passed
/// its end, with the same sums in the same order.
#[derive(Debug, Clone, Default)]
pub struct MountingChecker {
    /// IMU samples from the last one at or before the earliest time a later interval needs.
    imu: VecDeque<ImuSample>,
    /// Valid fixes not yet taken (the IMU has not passed them).
    pending: VecDeque<GnssFix>,
    /// The previous valid fix taken.
    prev_fix: Option<GnssFix>,
    /// Course of the previous interval: (mid time, course rad).
    prev_course: Option<(f64, f64)>,
    /// Horizontal velocity of the previous interval: (mid time, north, east m/s).
    prev_vel: Option<(f64, [f64; 2])>,
    sxy: f64,
    sxx: f64,
    n_turn: usize,
    f_rest: [f64; 3],
    t_rest: f64,
    n_rest: usize,
    input: ImuInput,
    /// Time of the first IMU sample, s (start of `wz_bins`).
    t0: Option<f64>,
    /// Body z increments summed per [`LAG_BIN_S`] bin (by sample time), rad.
    wz_bins: Vec<f32>,
    /// Turning intervals: (start, end, GNSS course rate rad/s).
    turns: Vec<(f64, f64, f64)>,
}

impl MountingChecker {
    /// An empty check (an increments file).
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty check of an IMU file holding `input`.
    pub fn for_input(input: ImuInput) -> Self {
        Self {
            input,
            ..Self::default()
        }
    }

    /// A GNSS fix (invalid fixes are ignored, as [`check_mounting`] does).
    pub fn push_fix(&mut self, g: &GnssFix) {
        if g.is_valid() {
            self.pending.push_back(*g);
        }
    }

    /// An IMU sample (body axes, after the previous one in time; every fix before it already
    /// pushed).
    pub fn push_imu(&mut self, s: &ImuSample) {
        let t0 = *self.t0.get_or_insert(s.t_s);
        // binned by the middle of the interval the increment covers
        let mid = 0.5 * (s.t_s + self.imu.back().map_or(s.t_s, |p| p.t_s));
        let bin = ((mid - t0) / LAG_BIN_S).floor();
        if (0.0..LAG_RECORD_S / LAG_BIN_S).contains(&bin) {
            let bin = bin as usize;
            if self.wz_bins.len() <= bin {
                self.wz_bins.resize(bin + 1, 0.0);
            }
            if let Some(b) = self.wz_bins.get_mut(bin) {
                *b += s.dtheta_rad[2] as f32;
            }
        }
        self.imu.push_back(*s);
        // every sample up to a fix before this one is in: its interval can be taken
        while let Some(b) = self.pending.front().copied() {
            if b.t_s >= s.t_s {
                break;
            }
            self.pending.pop_front();
            self.interval_to(b);
        }
        // no fix ahead and none within MAX_INTERVAL_S before: the next fix (not before this
        // sample) closes an interval too long to be used; the one after it starts at that
        // fix, so only the last sample is still needed
        let far = self.prev_fix.is_none_or(|p| s.t_s - p.t_s > MAX_INTERVAL_S);
        if self.pending.is_empty() && far {
            while self.imu.len() > 1 {
                self.imu.pop_front();
            }
        }
    }

    /// The check over everything pushed.
    pub fn finish(mut self) -> MountingCheck {
        while let Some(b) = self.pending.pop_front() {
            self.interval_to(b);
        }
        let lag = if self.turns.len() >= 2 * MIN_TURN_INTERVALS {
            self.lag()
        } else {
            None
        };
        verdict(Evidence {
            turn_slope: (self.n_turn >= MIN_TURN_INTERVALS && self.sxx > 0.0)
                .then(|| (self.sxy / self.sxx, self.n_turn)),
            rest: (self.t_rest >= 1.0).then(|| (self.f_rest.map(|v| v / self.t_rest), self.t_rest)),
            rest_dt_s: (self.t_rest >= 1.0 && self.n_rest > 0)
                .then(|| self.t_rest / self.n_rest as f64),
            lag,
            input: self.input,
        })
    }

    /// The GNSS time offset that best lines the z gyro up with the GNSS course rates of the
    /// turning intervals (least-squares slope through the origin at each offset on a
    /// [`LAG_BIN_S`] grid within +-[`MAX_LAG_S`], the minimum refined by a parabola), with the
    /// residual there and at zero offset.
    fn lag(&self) -> Option<Lag> {
        let t0 = self.t0?;
        let mut cum = Vec::with_capacity(self.wz_bins.len() + 1);
        let mut acc = 0.0f64;
        cum.push(0.0);
        for b in &self.wz_bins {
            acc += f64::from(*b);
            cum.push(acc);
        }
        // the z angle turned from t0 to t: the bins' running sum, linear within a bin
        let angle = |t: f64| -> Option<f64> {
            let x = (t - t0) / LAG_BIN_S;
            if x.is_nan() || x < 0.0 {
                return None;
            }
            let i = x.floor();
            let (a, b) = (*cum.get(i as usize)?, *cum.get(i as usize + 1)?);
            Some(a + (x - i) * (b - a))
        };
        let sum = |a: f64, b: f64| -> Option<f64> { Some(angle(b)? - angle(a)?) };
        let steps = (MAX_LAG_S / LAG_BIN_S).round() as i64;
        // the turns whose window stays inside the record at every offset tried
        let t_end = t0 + self.wz_bins.len() as f64 * LAG_BIN_S;
        let margin = MAX_LAG_S + 2.0 * LAG_BIN_S;
        let turns: Vec<(f64, f64, f64)> = self
            .turns
            .iter()
            .copied()
            .filter(|&(a, b, _)| a - margin >= t0 && b + margin <= t_end)
            .collect();
        if turns.len() < 2 * MIN_TURN_INTERVALS {
            return None;
        }
        let rss_at = |k: i64| -> Option<f64> {
            let tau = k as f64 * LAG_BIN_S;
            let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
            for &(a, b, r) in &turns {
                let wz = sum(a + tau, b + tau)? / (b - a);
                sxy += wz * r;
                sxx += r * r;
                syy += wz * wz;
            }
            (sxx > 0.0).then(|| syy - sxy * sxy / sxx)
        };
        let rss: Vec<(i64, f64)> = (-steps..=steps)
            .filter_map(|k| rss_at(k).map(|r| (k, r)))
            .collect();
        let rss0 = rss.iter().find(|(k, _)| *k == 0)?.1;
        let &(kb, rb) = rss.iter().min_by(|a, b| a.1.total_cmp(&b.1))?;
        let at = |k: i64| rss.iter().find(|(j, _)| *j == k).map(|x| x.1);
        let frac = match (at(kb - 1), at(kb + 1)) {
            (Some(l), Some(r)) if l + r - 2.0 * rb > 0.0 => {
                (0.5 * (l - r) / (l + r - 2.0 * rb)).clamp(-0.5, 0.5)
            }
            _ => 0.0,
        };
        Some(Lag {
            lag_s: (kb as f64 + frac) * LAG_BIN_S,
            rss: rb,
            rss_zero: rss0,
            turns: turns.len(),
        })
    }

    /// The GNSS interval from the previous fix to `b` (every IMU sample up to `b` is in).
    fn interval_to(&mut self, b: GnssFix) {
        let Some(a) = self.prev_fix.replace(b) else {
            return;
        };
        self.interval(&a, &b);
        // a later interval needs samples after min(b, this interval's mid) and the one
        // before them (the span of a sum starts at the sample before its window)
        let keep_from = self.prev_course.map_or(b.t_s, |(tp, _)| tp.min(b.t_s));
        while self.imu.get(1).is_some_and(|s| s.t_s <= keep_from) {
            self.imu.pop_front();
        }
    }

    fn interval(&mut self, a: &GnssFix, b: &GnssFix) {
        let dt = b.t_s - a.t_s;
        if !(dt > 0.0 && dt <= MAX_INTERVAL_S) {
            self.prev_course = None;
            return;
        }
        let [vn, ve] = interval_velocity(a, b);
        let speed = vn.hypot(ve);
        let mid = 0.5 * (a.t_s + b.t_s);
        // a jump of the velocity no vehicle makes: a position outlier in one of the fixes
        let jump = self
            .prev_vel
            .replace((mid, [vn, ve]))
            .is_some_and(|(tp, [pn, pe])| {
                (vn - pn).hypot(ve - pe) > MAX_GNSS_ACCEL_MPS2 * (mid - tp)
            });
        if speed <= REST_SPEED_MPS {
            let (_, dv, span, n) = sums_n(self.imu.make_contiguous(), a.t_s, b.t_s);
            if span > 0.0 {
                for (f, d) in self.f_rest.iter_mut().zip(dv) {
                    *f += d;
                }
                self.t_rest += span;
                self.n_rest += n;
            }
        }
        if speed < MIN_SPEED_MPS {
            self.prev_course = None;
            return;
        }
        let course = ve.atan2(vn);
        if let Some((tp, cp)) = self.prev_course.filter(|_| !jump) {
            let rate = wrap_pi(course - cp) / (mid - tp);
            if rate.abs() >= MIN_TURN_RATE_DEG_S.to_radians() {
                let (th, _, span) = sums(self.imu.make_contiguous(), tp, mid);
                if span > 0.0 {
                    let wz = th[2] / span;
                    self.sxy += wz * rate;
                    self.sxx += rate * rate;
                    self.n_turn += 1;
                    if self.turns.len() < MAX_TURNS {
                        self.turns.push((tp, mid, rate));
                    }
                }
            }
        }
        self.prev_course = Some((mid, course));
    }
}

/// The time offset found by [`MountingChecker::lag`].
#[derive(Debug, Clone, Copy)]
struct Lag {
    lag_s: f64,
    rss: f64,
    rss_zero: f64,
    turns: usize,
}

/// What the check gathered, for [`verdict`].
struct Evidence {
    turn_slope: Option<(f64, usize)>,
    rest: Option<([f64; 3], f64)>,
    rest_dt_s: Option<f64>,
    lag: Option<Lag>,
    input: ImuInput,
}

/// Whether `x` is within 10 % of `want`.
fn near(x: f64, want: f64) -> bool {
    (x / want - 1.0).abs() <= 0.1
}

/// The warning about the size of the specific force at rest (units, or increments stamped at
/// another rate than they were taken), when it is not about 1 g; true when the time stamps
/// themselves are in doubt.
fn scale_warning(f: &[f64; 3], t: f64, dt: Option<f64>, input: ImuInput) -> Option<(String, bool)> {
    let norm = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
    let k = norm / G_MPS2;
    if near(k, 1.0) || !norm.is_finite() || norm <= 0.0 {
        return None;
    }
    let head = format!(
        "at rest ({t:.1} s) the specific force is {norm:.3} m/s^2 = {k:.3} g, where gravity \
         gives 9.81 m/s^2"
    );
    Some(match input {
        ImuInput::CsvRates if near(norm, 1.0) => (
            format!(
                "{head}: the accelerometer data are in g but read as m/s^2; set [imu.csv] \
                 accel_unit = \"g\""
            ),
            false,
        ),
        ImuInput::CsvRates if near(k, G_MPS2) => (
            format!(
                "{head}: the accelerometer data are in m/s^2 but read as g; set [imu.csv] \
                 accel_unit = \"m/s^2\""
            ),
            false,
        ),
        ImuInput::CsvRates => (
            format!(
                "{head}: neither g nor m/s^2 fits the accelerometer data; check [imu.csv] \
                 accel_unit and the accelerometer columns"
            ),
            false,
        ),
        ImuInput::Increments if near(norm, 1.0) => (
            format!(
                "{head}: the velocity increments are in g s, not m/s as the format wants; \
                 multiply them by 9.80665"
            ),
            false,
        ),
        ImuInput::Increments => match dt {
            Some(dt) => (
                format!(
                    "{head}: the increments are {k:.2}x what {dt:.4} s between time stamps \
                     gives; they cover {:.4} s each: increments of {:.0} Hz stamped at {:.0} Hz? \
                     Fix the time stamps (or [imu] time_offset_s / the tick clock); the \
                     mounting and time checks from turns are not made",
                    dt * k,
                    1.0 / (dt * k),
                    1.0 / dt
                ),
                true,
            ),
            None => (
                format!("{head}: check the time stamps and the increments' units"),
                true,
            ),
        },
    })
}

/// The warnings from the turn slope, the specific force at rest and the time offset.
fn verdict(ev: Evidence) -> MountingCheck {
    let Evidence {
        turn_slope,
        rest,
        rest_dt_s,
        lag,
        input,
    } = ev;
    let mut warnings = Vec::new();
    let mut stamps_in_doubt = false;
    if let Some((f, t)) = rest {
        if let Some((w, doubt)) = scale_warning(&f, t, rest_dt_s, input) {
            warnings.push(w);
            stamps_in_doubt = doubt;
        }
    }
    let gyro_units = turn_slope.and_then(|(s, n)| {
        let deg = 180.0 / std::f64::consts::PI;
        let fix = |unit: &str| match input {
            ImuInput::CsvRates => format!("set [imu.csv] gyro_unit = \"{unit}\""),
            ImuInput::Increments => {
                "convert the angle increments to rad (the format's unit)".into()
            }
        };
        if near(s, deg) {
            Some(format!(
                "the body z gyro turns {s:.1}x as fast as the GNSS course over {n} turning \
                 intervals: the gyro data are in deg (deg/s) but read as rad (rad/s); {}",
                fix("deg/s")
            ))
        } else if near(s, 1.0 / deg) {
            Some(format!(
                "the body z gyro turns {s:.4}x as fast as the GNSS course over {n} turning \
                 intervals: the gyro data are in rad (rad/s) but read as deg (deg/s); {}",
                fix("rad/s")
            ))
        } else {
            None
        }
    });
    let gyro_units_found = gyro_units.is_some();
    warnings.extend(gyro_units);
    if let Some((s, n)) = turn_slope.filter(|_| !stamps_in_doubt && !gyro_units_found) {
        if s < -0.5 {
            warnings.push(format!(
                "the body z gyro turns AGAINST the GNSS course (slope {s:.2} over {n} turning \
                 intervals, +1 expected): the IMU z axis points up in the configured mounting; \
                 fix [imu.mounting] rpy_deg (for example add 180 deg of roll)"
            ));
        } else if s < 0.5 {
            warnings.push(format!(
                "the body z gyro hardly follows the GNSS course (slope {s:.2} over {n} turning \
                 intervals, +1 expected): the configured [imu.mounting] does not put an IMU \
                 axis vertical"
            ));
        }
    }
    if let Some(l) = lag.filter(|l| {
        !stamps_in_doubt && l.lag_s.abs() >= MIN_REPORTED_LAG_S && l.rss < 0.5 * l.rss_zero
    }) {
        warnings.push(format!(
            "the GNSS time stamps are {:.2} s {} the IMU's: the z gyro follows the GNSS course \
             best with the fixes moved by {:+.2} s (over {} turning intervals; residual {:.0} % \
             of that at no offset); add {:+.2} s to [gnss] time_offset_s (or fix the logger's \
             time stamps)",
            l.lag_s.abs(),
            if l.lag_s < 0.0 { "late on" } else { "early on" },
            l.lag_s,
            l.turns,
            100.0 * l.rss / l.rss_zero,
            l.lag_s
        ));
    }
    if let Some((f, t)) = rest {
        let norm = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
        if norm > 0.0 && -f[2] / norm < 0.9 {
            warnings.push(format!(
                "at rest ({t:.1} s) the mean specific force in body axes is [{:.2}, {:.2}, \
                 {:.2}] m/s^2, not along -z: the configured [imu.mounting] tilts the body by \
                 {:.0} deg",
                f[0],
                f[1],
                f[2],
                (-f[2] / norm).clamp(-1.0, 1.0).acos().to_degrees()
            ));
        }
    }
    MountingCheck {
        turn_slope,
        rest_f_body_mps2: rest,
        rest_dt_s,
        gnss_lag_s: lag.map(|l| l.lag_s),
        warnings,
    }
}

/// The 24 axis layouts: signed permutation matrices with determinant +1 (x_body = L x_imu).
pub fn axis_layouts() -> Vec<Matrix3<f64>> {
    let perms = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut out = Vec::with_capacity(24);
    for p in perms {
        for signs in 0..8u8 {
            let mut m = Matrix3::zeros();
            for (row, &col) in p.iter().enumerate() {
                m[(row, col)] = if signs & (1 << row) != 0 { -1.0 } else { 1.0 };
            }
            if m.determinant() > 0.0 {
                out.push(m);
            }
        }
    }
    out
}

/// One reduced observation: measured (sensor axes) vs expected (body axes).
#[derive(Debug, Clone, Copy)]
struct Pair {
    f_meas: Vector3<f64>,
    f_exp: Vector3<f64>,
    w_meas: Vector3<f64>,
    /// Expected body z rate (course rate), rad/s; None at rest (rate expected 0 there too
    /// but not used).
    wz_exp: Option<f64>,
    speed: f64,
    moving: bool,
    /// Lateral (cross-track) acceleration of a moving pair, m/s^2 (0 at rest).
    lat_mps2: f64,
}

/// The `[imu.mounting]` estimated from the data.
#[derive(Debug, Clone, PartialEq)]
pub struct MountingEstimate {
    /// Roll, pitch, yaw to paste into `[imu.mounting] rpy_deg`, deg.
    pub rpy_deg: [f64; 3],
    /// One-sigma of the three angles, deg.
    pub sigma_deg: [f64; 3],
    /// Best axis layout (x_body = L x_imu).
    pub layout: Matrix3<f64>,
    /// RMS residual of the best layout (before the fine angles), m/s^2.
    pub best_residual_mps2: f64,
    /// RMS residual of the runner-up layout, m/s^2.
    pub runner_up_residual_mps2: f64,
    /// RMS residual after the fine angles, m/s^2.
    pub final_residual_mps2: f64,
    /// Intervals used at rest and while moving.
    pub rest_intervals: usize,
    /// Intervals used while moving (for a slow vehicle: the starts and stops used).
    pub moving_intervals: usize,
    /// What was determined from what, and what could not be (printed as comments).
    pub notes: Vec<String>,
}

fn pairs(imu: &[ImuSample], gnss: &[GnssFix]) -> Vec<Pair> {
    let fixes: Vec<&GnssFix> = gnss.iter().filter(|g| g.is_valid()).collect();
    let mut out = Vec::new();
    // previous moving interval: (mid time, NED velocity, mid height rate) for the acceleration
    let mut prev: Option<(f64, Vector3<f64>)> = None;
    for w in fixes.windows(2) {
        let (a, b) = (w[0], w[1]);
        let dt = b.t_s - a.t_s;
        if !(dt > 0.0 && dt <= 5.0) {
            prev = None;
            continue;
        }
        let v = if a.has_velocity && b.has_velocity {
            0.5 * (Vector3::from(a.vel_ned_mps) + Vector3::from(b.vel_ned_mps))
        } else {
            earth::ned_offset_m(&llh(a), &llh(b)) / dt
        };
        let speed = v.x.hypot(v.y);
        let mid = 0.5 * (a.t_s + b.t_s);
        let g = earth::gravity_mps2(a.lat_rad, a.h_m);
        if speed <= REST_SPEED_MPS {
            let (th, dv, span) = sums(imu, a.t_s, b.t_s);
            if span > 0.0 {
                out.push(Pair {
                    f_meas: Vector3::from(dv) / span,
                    f_exp: Vector3::new(0.0, 0.0, -g),
                    w_meas: Vector3::from(th) / span,
                    wz_exp: None,
                    speed,
                    moving: false,
                    lat_mps2: 0.0,
                });
            }
            prev = None;
            continue;
        }
        if speed < MIN_SPEED_MPS {
            prev = None;
            continue;
        }
        if let Some((tp, vp)) = prev {
            let dtm = mid - tp;
            let acc = (v - vp) / dtm;
            let vm = 0.5 * (v + vp);
            let course = vm.y.atan2(vm.x);
            let course_rate = wrap_pi(v.y.atan2(v.x) - vp.y.atan2(vp.x)) / dtm;
            let climb = (-vm.z).atan2(vm.x.hypot(vm.y));
            // f^n = a^n - g^n, turned by yaw = course and pitch = climb (roll 0)
            let (n, e, d) = (acc.x, acc.y, acc.z - g);
            let (sy, cy) = course.sin_cos();
            let (sp, cp) = climb.sin_cos();
            let x1 = cy * n + sy * e;
            let y1 = -sy * n + cy * e;
            let f_exp = Vector3::new(cp * x1 - sp * d, y1, sp * x1 + cp * d);
            let (th, dv, span) = sums(imu, tp, mid);
            if span > 0.0 {
                out.push(Pair {
                    f_meas: Vector3::from(dv) / span,
                    f_exp,
                    w_meas: Vector3::from(th) / span,
                    wz_exp: Some(course_rate),
                    speed: vm.x.hypot(vm.y),
                    moving: true,
                    lat_mps2: y1,
                });
            }
        }
        prev = Some((mid, v));
    }
    out
}

/// RMS residual (m/s^2) of the rotation `m` (x_body = m x_imu) over `ps`.
fn residual(m: &Matrix3<f64>, ps: &[Pair]) -> f64 {
    let mut ss = 0.0;
    let mut n = 0usize;
    for p in ps {
        ss += (m * p.f_meas - p.f_exp).norm_squared();
        n += 3;
        if let Some(wz) = p.wz_exp {
            let r = p.speed * ((m * p.w_meas).z - wz);
            ss += r * r;
            n += 1;
        }
    }
    if n == 0 {
        f64::INFINITY
    } else {
        (ss / n as f64).sqrt()
    }
}

/// Lateral acceleration from which a moving interval counts as a turn whose body roll is not
/// known (suspension lean, banked road), m/s^2.
pub const ROLL_FREE_LAT_MPS2: f64 = 0.3;
/// Passes of the fine-angle solution with the turns' body roll taken from the data.
const ROLL_PASSES: usize = 3;

/// Wahba's problem by SVD: the rotation `c` minimising sum |f_exp - c L f_meas|^2, returned
/// as `c L` (x_body = m x_imu); `None` when the SVD fails.
fn wahba(ps: &[Pair], layout: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let mut b = Matrix3::zeros();
    for p in ps {
        b += p.f_exp * (layout * p.f_meas).transpose();
    }
    let svd = b.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let d = (u.determinant() * vt.determinant()).signum();
    Some(u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * vt * layout)
}

/// In a turn the body rolls by an angle the GNSS does not see (leaning out on its springs,
/// into a banked curve): the expected specific force's cross-track/vertical part is turned
/// about the along-track axis onto the measured one's direction (its size and the
/// along-track part stay expected), so turns inform yaw and pitch but not the roll, which
/// comes from rest and straight driving. Pairs with less than [`ROLL_FREE_LAT_MPS2`] of
/// lateral acceleration are left as they are.
fn roll_to_data(p: &mut Pair, m: &Matrix3<f64>) {
    if !p.moving || p.lat_mps2.abs() < ROLL_FREE_LAT_MPS2 {
        return;
    }
    let f = m * p.f_meas;
    let e = p.f_exp;
    let size = e.y.hypot(e.z);
    let dir = f.y.hypot(f.z);
    if size > 0.0 && dir > 0.0 {
        p.f_exp = Vector3::new(e.x, size * f.y / dir, size * f.z / dir);
    }
}

/// Why the mounting could not be estimated ([`estimate_mounting`]): what the data lack.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum MountingError {
    /// Too few GNSS intervals while moving, and too few starts and stops of a slow vehicle.
    #[error(
        "only {moving} GNSS intervals while moving at >= {MIN_SPEED_MPS} m/s (10 needed), and \
         {starts_stops} starts or stops next to {rests} rests of >= {MIN_REST_INTERVALS} GNSS \
         intervals ({MIN_STARTS_STOPS} needed, with a rest for roll and pitch): the mounting \
         needs a drive with accelerations and turns (a few minutes), or for a slow vehicle a \
         few stops of some seconds between straight drives forwards"
    )]
    TooLittleMotion {
        /// GNSS intervals while moving at car speed (at least 10 are needed).
        moving: usize,
        /// Rests found (GNSS slower than [`REST_SPEED_MPS`] for >= [`MIN_REST_INTERVALS`]
        /// intervals).
        rests: usize,
        /// Starts and stops next to them whose velocity change gave a direction.
        starts_stops: usize,
    },
    /// The specific forces do not determine a rotation (the SVD failed).
    #[error("the specific forces do not determine a rotation")]
    NoRotation,
}

/// Estimates the IMU-to-body rotation from increments in SENSOR axes and GNSS fixes (see the
/// module notes). Errors say what the data lack.
pub fn estimate_mounting(
    imu: &[ImuSample],
    gnss: &[GnssFix],
) -> Result<MountingEstimate, MountingError> {
    let ps = pairs(imu, gnss);
    let rest = ps.iter().filter(|p| !p.moving).count();
    let moving = ps.len() - rest;
    if moving < 10 {
        return slow::estimate(imu, gnss, moving);
    }
    let mut scored: Vec<(f64, Matrix3<f64>)> = axis_layouts()
        .into_iter()
        .map(|l| (residual(&l, &ps), l))
        .collect();
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (best_res, layout) = scored[0];
    let runner_up = scored[1].0;
    // fine angles: Wahba on the specific forces, from the layout; then again with the body
    // roll of each turning pair taken from the data (a few passes)
    let mut m = wahba(&ps, &layout).ok_or(MountingError::NoRotation)?;
    let mut ps = ps;
    for _ in 0..ROLL_PASSES {
        for p in ps.iter_mut() {
            roll_to_data(p, &m);
        }
        m = wahba(&ps, &layout).ok_or(MountingError::NoRotation)?;
    }
    let final_res = residual(&m, &ps);
    let rpy = euler_zyx_from_dcm(&m.transpose());
    let g = 9.8;
    let h_acc: f64 = {
        let (s, n) = ps
            .iter()
            .filter(|p| p.moving)
            .fold((0.0, 0usize), |(s, n), p| {
                (s + p.f_exp.x.powi(2) + p.f_exp.y.powi(2), n + 1)
            });
        (s / n.max(1) as f64).sqrt()
    };
    let tilt = final_res / (g * (ps.len() as f64).sqrt());
    let yaw = final_res / (h_acc.max(1e-3) * (moving as f64).sqrt());
    Ok(MountingEstimate {
        rpy_deg: rpy.map(f64::to_degrees),
        sigma_deg: [tilt, tilt, yaw].map(f64::to_degrees),
        layout,
        best_residual_mps2: best_res,
        runner_up_residual_mps2: runner_up,
        final_residual_mps2: final_res,
        rest_intervals: rest,
        moving_intervals: moving,
        notes: vec![format!(
            "roll, pitch and yaw from gravity at {rest} rest intervals and the GNSS \
             accelerations and course of {moving} intervals at >= {MIN_SPEED_MPS} m/s"
        )],
    })
}

impl MountingEstimate {
    /// The `[imu.mounting]` section to paste, with the uncertainty, the runner-up and the
    /// notes as comments.
    pub fn toml_section(&self) -> String {
        let [r, p, y] = self.rpy_deg;
        let [sr, sp, sy] = self.sigma_deg;
        let notes: String = self.notes.iter().map(|n| format!("# {n}\n")).collect();
        notes
            + &format!(
                "# estimated by `host-sim mounting` from {} rest and {} moving GNSS intervals\n\
             # 1-sigma roll {sr:.2}, pitch {sp:.2}, yaw {sy:.2} deg; residual {:.3} m/s^2 \
             (best axis layout {:.3}, runner-up layout {:.3})\n\
             [imu.mounting]\nrpy_deg = [{r:.2}, {p:.2}, {y:.2}]\n",
                self.rest_intervals,
                self.moving_intervals,
                self.final_residual_mps2,
                self.best_residual_mps2,
                self.runner_up_residual_mps2
            )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nav_core::types::FixQuality;

    /// The check as it was written over whole lists (before [`MountingChecker`]): the
    /// reference the stream must equal bit for bit.
    type Reference = (Option<(f64, usize)>, Option<([f64; 3], f64)>);

    fn reference(imu: &[ImuSample], gnss: &[GnssFix]) -> Reference {
        let fixes: Vec<&GnssFix> = gnss.iter().filter(|g| g.is_valid()).collect();
        let (mut sxy, mut sxx, mut n_turn) = (0.0, 0.0, 0usize);
        let (mut f_rest, mut t_rest) = ([0.0; 3], 0.0);
        let mut prev_course: Option<(f64, f64)> = None;
        let mut prev_vel: Option<(f64, [f64; 2])> = None;
        for w in fixes.windows(2) {
            let (a, b) = (w[0], w[1]);
            let dt = b.t_s - a.t_s;
            if !(dt > 0.0 && dt <= 5.0) {
                prev_course = None;
                continue;
            }
            let [vn, ve] = interval_velocity(a, b);
            let speed = vn.hypot(ve);
            let mid = 0.5 * (a.t_s + b.t_s);
            let jump = prev_vel
                .replace((mid, [vn, ve]))
                .is_some_and(|(tp, [pn, pe])| {
                    (vn - pn).hypot(ve - pe) > MAX_GNSS_ACCEL_MPS2 * (mid - tp)
                });
            if speed <= REST_SPEED_MPS {
                let (_, dv, span) = sums(imu, a.t_s, b.t_s);
                if span > 0.0 {
                    for k in 0..3 {
                        f_rest[k] += dv[k];
                    }
                    t_rest += span;
                }
            }
            if speed < MIN_SPEED_MPS {
                prev_course = None;
                continue;
            }
            let course = ve.atan2(vn);
            if let Some((tp, cp)) = prev_course.filter(|_| !jump) {
                let rate = wrap_pi(course - cp) / (mid - tp);
                if rate.abs() >= MIN_TURN_RATE_DEG_S.to_radians() {
                    let (th, _, span) = sums(imu, tp, mid);
                    if span > 0.0 {
                        sxy += th[2] / span * rate;
                        sxx += rate * rate;
                        n_turn += 1;
                    }
                }
            }
            prev_course = Some((mid, course));
        }
        (
            (n_turn >= MIN_TURN_INTERVALS && sxx > 0.0).then(|| (sxy / sxx, n_turn)),
            (t_rest >= 1.0).then(|| (f_rest.map(|v| v / t_rest), t_rest)),
        )
    }

    fn part(c: &MountingCheck) -> Reference {
        (c.turn_slope, c.rest_f_body_mps2)
    }

    /// A car: 20 s at rest, then driving with turns of changing rate, a 10 s stop, a GNSS
    /// gap of 8 s, some fixes without velocity and some invalid; IMU at 100 Hz with a little
    /// deterministic wobble, GNSS at 4 Hz. `flip`: the IMU upside down (y and z negated).
    fn drive(flip: bool) -> (Vec<ImuSample>, Vec<GnssFix>) {
        let g = 9.8;
        let dt = 0.01;
        let t0 = 1000.0;
        let speed = |t: f64| -> f64 {
            let r = t - t0;
            if r < 20.0 || (150.0..160.0).contains(&r) {
                0.0
            } else {
                (12.0 * (1.0 - (-(r - 20.0) / 5.0).exp())).min(12.0)
            }
        };
        let yaw_rate = |t: f64| -> f64 {
            let r = t - t0;
            if speed(t) < 1.0 {
                0.0
            } else {
                0.15 * (r / 9.0).sin() + 0.05 * (r / 2.3).cos()
            }
        };
        let (mut yaw, mut n, mut e) = (0.3f64, 0.0f64, 0.0f64);
        let (mut imu, mut gnss) = (Vec::new(), Vec::new());
        let lat0 = 0.7f64;
        for k in 1..=30_000 {
            let t = t0 + k as f64 * dt;
            let w = yaw_rate(t);
            let v = speed(t);
            let a_long = (v - speed(t - dt)) / dt;
            yaw += w * dt;
            n += v * yaw.cos() * dt;
            e += v * yaw.sin() * dt;
            let wob = 1e-3 * (k as f64 * 0.37).sin();
            let mut th = [wob * dt, -wob * dt, w * dt];
            let mut dv = [a_long * dt, (v * w + wob) * dt, -g * dt];
            if flip {
                th[1] = -th[1];
                th[2] = -th[2];
                dv[1] = -dv[1];
                dv[2] = -dv[2];
            }
            imu.push(ImuSample {
                t_s: t,
                dtheta_rad: th,
                dv_mps: dv,
                temperature_c: f64::NAN,
            });
            // GNSS every 25th sample, off the IMU grid by 3 ms, not in the gap
            if k % 25 == 0 && !(200.0..208.0).contains(&(t - t0)) {
                let mut f = GnssFix {
                    t_s: t + 0.003,
                    lat_rad: lat0 + n / 6.4e6,
                    lon_rad: e / (6.4e6 * lat0.cos()),
                    h_m: 100.0,
                    pos_std_ned_m: [0.1, 0.1, 0.2],
                    vel_ned_mps: [v * yaw.cos(), v * yaw.sin(), 0.0],
                    vel_std_ned_mps: [0.05; 3],
                    has_velocity: k % 400 != 0,
                    quality: FixQuality::Single,
                    num_sats: 9,
                };
                if k % 1000 == 0 {
                    f.pos_std_ned_m[0] = f64::NAN;
                }
                gnss.push(f);
            }
        }
        (imu, gnss)
    }

    #[test]
    fn the_stream_is_the_whole_list_check_bit_for_bit_in_any_interleaving() {
        for flip in [false, true] {
            let (imu, gnss) = drive(flip);
            let whole = check_mounting(&imu, &gnss);
            assert_eq!(part(&whole), reference(&imu, &gnss));
            let want = whole;
            let (slope, n) = want.turn_slope.expect("turns");
            assert!(n > 100, "{n}");
            assert!(
                (slope - if flip { -1.0 } else { 1.0 }).abs() < 0.2,
                "{slope}"
            );
            assert!(want.rest_f_body_mps2.expect("rest").1 > 20.0);
            assert_eq!(
                want.warnings.len(),
                if flip { 2 } else { 0 },
                "{:?}",
                want.warnings
            );
            // all fixes first, then the IMU
            let mut c = MountingChecker::new();
            gnss.iter().for_each(|g| c.push_fix(g));
            imu.iter().for_each(|s| c.push_imu(s));
            assert_eq!(c.finish(), want);
            // fixes pushed one second ahead of the IMU: the buffer stays small
            let mut c = MountingChecker::new();
            let mut fixes = gnss.iter().peekable();
            let mut most = 0;
            for s in &imu {
                while let Some(g) = fixes.next_if(|g| g.t_s <= s.t_s + 1.0) {
                    c.push_fix(g);
                }
                c.push_imu(s);
                most = most.max(c.imu.len());
            }
            fixes.for_each(|g| c.push_fix(g));
            assert_eq!(c.finish(), want);
            // at most MAX_INTERVAL_S of samples (in the 8 s GNSS gap), one GNSS interval of
            // 0.25 s and the sample before
            assert!(most <= 500 + 25 + 1, "{most} IMU samples held");
            assert!(most >= 500, "{most} IMU samples held");
        }
    }
}
