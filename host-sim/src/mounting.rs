//! Checks of the configured IMU mounting against the data (issue 15). The body frame is FRD
//! (x forward, y right, z down); after the configured mounting rotation the increments are in
//! body axes. Two cues:
//!
//! * **turns**: while the vehicle moves (GNSS horizontal speed >= [`MIN_SPEED_MPS`]) the body z
//!   gyro must turn WITH the GNSS course: over GNSS intervals with a course rate of at least
//!   [`MIN_TURN_RATE_DEG_S`] the least-squares slope of the mean z rate against the course
//!   rate is close to +1 for a correct mounting (cos of the tilt), near -1 for an upside-down
//!   z axis and near 0 for a horizontal one;
//! * **gravity at rest**: while the GNSS speed stays below [`REST_SPEED_MPS`], the mean
//!   specific force points along body -z (about (0, 0, -g)).
//!
//! Either cue that contradicts the mounting gives a warning naming it and the way out.
//! (Estimating the mounting itself, `host-sim mounting`, is not implemented yet.)

use nav_core::earth::{self, Llh};
use nav_core::types::{GnssFix, ImuSample};

/// Lowest GNSS horizontal speed for the course to be used, m/s.
pub const MIN_SPEED_MPS: f64 = 3.0;
/// Lowest course rate of an interval used in the turn test, deg/s.
pub const MIN_TURN_RATE_DEG_S: f64 = 3.0;
/// Highest GNSS speed counted as rest, m/s.
pub const REST_SPEED_MPS: f64 = 0.1;
/// Fewest turning intervals for a verdict from the turns.
pub const MIN_TURN_INTERVALS: usize = 5;

/// What the data say about the configured mounting.
#[derive(Debug, Clone, PartialEq)]
pub struct MountingCheck {
    /// Least-squares slope of the body z rate against the GNSS course rate (+1 expected), and
    /// the number of turning intervals it is from; None with too few turns.
    pub turn_slope: Option<(f64, usize)>,
    /// Mean specific force at rest, body axes, m/s^2, and the seconds of rest it is from.
    pub rest_f_body_mps2: Option<([f64; 3], f64)>,
    /// Warnings (empty when the data agree with the mounting).
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
    (th, dv, span)
}

/// Checks body-axis increments `imu` against the GNSS fixes `gnss` (see the module notes).
pub fn check_mounting(imu: &[ImuSample], gnss: &[GnssFix]) -> MountingCheck {
    let fixes: Vec<&GnssFix> = gnss.iter().filter(|g| g.is_valid()).collect();
    let (mut sxy, mut sxx, mut n_turn) = (0.0, 0.0, 0usize);
    let (mut f_rest, mut t_rest) = ([0.0; 3], 0.0);
    // course of the previous interval: (mid time, course rad)
    let mut prev_course: Option<(f64, f64)> = None;
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
        if let Some((tp, cp)) = prev_course {
            let rate = wrap_pi(course - cp) / (mid - tp);
            if rate.abs() >= MIN_TURN_RATE_DEG_S.to_radians() {
                let (th, _, span) = sums(imu, tp, mid);
                if span > 0.0 {
                    let wz = th[2] / span;
                    sxy += wz * rate;
                    sxx += rate * rate;
                    n_turn += 1;
                }
            }
        }
        prev_course = Some((mid, course));
    }
    let turn_slope = (n_turn >= MIN_TURN_INTERVALS && sxx > 0.0).then(|| (sxy / sxx, n_turn));
    let rest = (t_rest >= 1.0).then(|| (f_rest.map(|v| v / t_rest), t_rest));
    let mut warnings = Vec::new();
    if let Some((s, n)) = turn_slope {
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
        warnings,
    }
}
