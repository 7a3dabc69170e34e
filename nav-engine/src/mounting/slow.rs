//! The mounting of a slow or stop-and-go vehicle ([`super::estimate_mounting`] when the
//! GNSS shows too little driving at car speeds): a rover at 0.2 m/s with RTK fixes every
//! few seconds gives GNSS accelerations of a few mm/s^2, far below what the car method
//! needs, but it stops and starts. So:
//!
//! * **roll, pitch** from gravity at rest: the mean specific force over the runs of at least
//!   [`MIN_REST_INTERVALS`] GNSS intervals slower than [`REST_SPEED_MPS`] points along body
//!   -z;
//! * **yaw** from the starts and stops: from the last fix of a rest (forwards) or its first
//!   (backwards), the specific force less the rest's mean (gravity and the accelerometer
//!   bias), turned into the rest's sensor axes by the gyro, is integrated into the velocity
//!   change, and turned back into the sensor axes of its time; over the next GNSS intervals
//!   (at most [`MAX_WINDOW_S`], before the vehicle has turned by [`MAX_WINDOW_TURN_DEG`]:
//!   the bias turns with the sensor and no longer cancels) its mean points along body +x for
//!   a vehicle that drives forwards, whatever the speed was at the anchor fix; its
//!   horizontal direction gives the yaw;
//! * **check** of the z axis: the body z rate against the GNSS course rate of consecutive
//!   moving intervals (slope +1 expected).
use super::{
    axis_layouts, earth, llh, residual, sums, wrap_pi, GnssFix, ImuSample, Matrix3, MountingError,
    MountingEstimate, Pair, Vector3, MAX_INTERVAL_S, REST_SPEED_MPS,
};
use nalgebra::Rotation3;

/// Fewest consecutive GNSS intervals at rest for a rest (its first and last may hold the end
/// of a stop or the start of a drive).
pub const MIN_REST_INTERVALS: usize = 2;
/// Lowest GNSS speed of an interval used for the yaw after a start or before a stop, m/s.
pub const MIN_SLOW_SPEED_MPS: f64 = 0.05;
/// Longest integration from a rest's anchor fix, s.
pub const MAX_WINDOW_S: f64 = 12.0;
/// Largest turn of the sensor since the anchor fix for the velocity to be used, deg (the
/// body's forward axis must not have moved).
pub const MAX_WINDOW_TURN_DEG: f64 = 1.0;
/// Fewest starts and stops for a yaw.
pub const MIN_STARTS_STOPS: usize = 2;

/// One GNSS interval between consecutive valid fixes.
#[derive(Debug, Clone, Copy)]
struct Interval {
    t0: f64,
    t1: f64,
    v: Vector3<f64>,
    speed: f64,
    /// Starts where the previous interval ended (no gap, no invalid fix between).
    joined: bool,
}

fn intervals(gnss: &[GnssFix]) -> Vec<Interval> {
    let fixes: Vec<&GnssFix> = gnss.iter().filter(|g| g.is_valid()).collect();
    let mut out: Vec<Interval> = Vec::new();
    let mut joined = false;
    for w in fixes.windows(2) {
        let (a, b) = (w[0], w[1]);
        let dt = b.t_s - a.t_s;
        if !(dt > 0.0 && dt <= MAX_INTERVAL_S) {
            joined = false;
            continue;
        }
        let v = if a.has_velocity && b.has_velocity {
            0.5 * (Vector3::from(a.vel_ned_mps) + Vector3::from(b.vel_ned_mps))
        } else {
            earth::ned_offset_m(&llh(a), &llh(b)) / dt
        };
        out.push(Interval {
            t0: a.t_s,
            t1: b.t_s,
            v,
            speed: v.x.hypot(v.y),
            joined,
        });
        joined = true;
    }
    out
}

/// A rest: intervals `first..=last` (indices), the mean specific force (sensor axes, m/s^2)
/// over its inner part, and the seconds and samples it is from.
#[derive(Debug, Clone, Copy)]
struct Rest {
    first: usize,
    last: usize,
    f: Vector3<f64>,
    span_s: f64,
    samples: usize,
    /// Standard deviation of the per-sample specific force about the mean, m/s^2 (rms of the
    /// three axes).
    sd: f64,
}

fn rests(imu: &[ImuSample], iv: &[Interval]) -> Vec<Rest> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < iv.len() {
        if iv[i].speed > REST_SPEED_MPS {
            i += 1;
            continue;
        }
        let mut j = i;
        while j + 1 < iv.len() && iv[j + 1].joined && iv[j + 1].speed <= REST_SPEED_MPS {
            j += 1;
        }
        if j + 1 - i >= MIN_REST_INTERVALS {
            // the inner intervals, when there are any, hold no part of a stop or a start
            let (t0, t1) = if j - i >= 2 {
                (iv[i].t1, iv[j].t0)
            } else {
                (iv[i].t0, iv[j].t1)
            };
            let (_, dv, span, n) = super::sums_n(imu, t0, t1);
            if span > 0.0 {
                let f = Vector3::from(dv) / span;
                let k0 = imu.partition_point(|s| s.t_s <= t0).max(1);
                let (mut ss, mut m) = (0.0, 0usize);
                for k in k0..imu.len() {
                    let dt = imu[k].t_s - imu[k - 1].t_s;
                    if imu[k].t_s > t1 {
                        break;
                    }
                    if dt > 0.0 {
                        ss += (Vector3::from(imu[k].dv_mps) / dt - f).norm_squared();
                        m += 1;
                    }
                }
                out.push(Rest {
                    first: i,
                    last: j,
                    f,
                    span_s: span,
                    samples: n,
                    sd: (ss / (3 * m.max(1)) as f64).sqrt(),
                });
            }
        }
        i = j + 1;
    }
    out
}

/// The velocity change since the anchor time `t_a` (m/s; integrated in the rest's sensor
/// axes, each value turned into the sensor axes of its time), averaged over `[t0, t1]`, integrating forwards (`t0 >= t_a`) or backwards (`t1 <= t_a`); `None` when the
/// sensor turned by more than [`MAX_WINDOW_TURN_DEG`] before the end of the span or no sample
/// lies in it.
fn mean_dv(
    imu: &[ImuSample],
    f_rest: &Vector3<f64>,
    t_a: f64,
    t0: f64,
    t1: f64,
) -> Option<Vector3<f64>> {
    let forward = t0 >= t_a;
    let max_turn = MAX_WINDOW_TURN_DEG.to_radians();
    let (mut c, mut v) = (Rotation3::identity(), Vector3::zeros());
    let (mut sum, mut n) = (Vector3::zeros(), 0usize);
    // one sample: forwards v(t_k) = v(t_k-1) + C dv - f dt, then C to the sample's end;
    // backwards C to the sample's start after v(t_k-1) = v(t_k) - (C dv - f dt)
    let step = |c: &mut Rotation3<f64>, v: &mut Vector3<f64>, prev: &ImuSample, s: &ImuSample| {
        let dv = *c * Vector3::from(s.dv_mps) - f_rest * (s.t_s - prev.t_s);
        let rot = Rotation3::new(Vector3::from(s.dtheta_rad));
        if forward {
            *v += dv;
            *c *= rot;
        } else {
            *v -= dv;
            *c *= rot.inverse();
        }
    };
    if forward {
        let k0 = imu.partition_point(|s| s.t_s <= t_a).max(1);
        for k in k0..imu.len() {
            let s = &imu[k];
            if s.t_s > t1 {
                break;
            }
            step(&mut c, &mut v, &imu[k - 1], s);
            if c.angle() > max_turn {
                return None;
            }
            if s.t_s >= t0 {
                sum += c.inverse() * v;
                n += 1;
            }
        }
    } else {
        let k0 = imu.partition_point(|s| s.t_s <= t_a);
        for k in (1..k0).rev() {
            let s = &imu[k];
            if s.t_s <= t0 {
                break;
            }
            if s.t_s <= t1 {
                sum += c.inverse() * v;
                n += 1;
            }
            step(&mut c, &mut v, &imu[k - 1], s);
            if c.angle() > max_turn {
                return None;
            }
        }
    }
    (n > 0).then(|| sum / n as f64)
}

/// The velocity directions (sensor axes, unit vectors along body +x) after the starts and
/// before the stops next to the rests.
fn start_stop_directions(imu: &[ImuSample], iv: &[Interval], rs: &[Rest]) -> Vec<Vector3<f64>> {
    let mut out = Vec::new();
    for r in rs {
        // forwards from the start of the rest's last interval, backwards from the end of its
        // first: the joined moving intervals within MAX_WINDOW_S
        let starts = (r.last + 1..iv.len()).take_while(|&k| iv[k].joined);
        let stops = (0..r.first).rev().take_while(|&k| iv[k + 1].joined);
        for (anchor, ks) in [
            (iv[r.last].t0, starts.collect::<Vec<_>>()),
            (iv[r.first].t1, stops.collect::<Vec<_>>()),
        ] {
            let mut best: Option<Vector3<f64>> = None;
            for k in ks {
                let it = &iv[k];
                if (it.t1 - anchor).abs().max((it.t0 - anchor).abs()) > MAX_WINDOW_S {
                    break;
                }
                if it.speed < MIN_SLOW_SPEED_MPS {
                    continue;
                }
                let Some(dv) = mean_dv(imu, &r.f, anchor, it.t0, it.t1) else {
                    break;
                };
                // the change is at most the speed reached (and not much more: drift)
                let size = dv.norm();
                if size < 0.3 * it.speed || size > 2.0 * it.speed + 0.05 {
                    continue;
                }
                // the nearest: the shortest integration
                best = Some(dv / size);
                break;
            }
            if let Some(u) = best {
                out.push(u);
            }
        }
    }
    out
}

/// Slope of the body z rate against the GNSS course rate over consecutive moving intervals
/// turning at 1 deg/s or more, and their number.
fn turn_slope(imu: &[ImuSample], iv: &[Interval], m: &Matrix3<f64>) -> Option<(f64, usize)> {
    let (mut sxy, mut sxx, mut n) = (0.0, 0.0, 0usize);
    for w in iv.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        if !b.joined || a.speed < MIN_SLOW_SPEED_MPS || b.speed < MIN_SLOW_SPEED_MPS {
            continue;
        }
        let (ma, mb) = (0.5 * (a.t0 + a.t1), 0.5 * (b.t0 + b.t1));
        let rate = wrap_pi(b.v.y.atan2(b.v.x) - a.v.y.atan2(a.v.x)) / (mb - ma);
        if rate.abs() < 1f64.to_radians() {
            continue;
        }
        let (th, _, span) = sums(imu, ma, mb);
        if span > 0.0 {
            sxy += (m * Vector3::from(th)).z / span * rate;
            sxx += rate * rate;
            n += 1;
        }
    }
    (n >= 3 && sxx > 0.0).then(|| (sxy / sxx, n))
}

/// The slow-vehicle estimate (see the module notes); `moving` is the number of car-speed
/// intervals the other method found, for the error.
pub(super) fn estimate(
    imu: &[ImuSample],
    gnss: &[GnssFix],
    moving: usize,
) -> Result<MountingEstimate, MountingError> {
    let iv = intervals(gnss);
    let rs = rests(imu, &iv);
    let dirs = start_stop_directions(imu, &iv, &rs);
    if rs.is_empty() || dirs.len() < MIN_STARTS_STOPS {
        return Err(MountingError::TooLittleMotion {
            moving,
            rests: rs.len(),
            starts_stops: dirs.len(),
        });
    }
    // body z (down) in sensor axes: against the mean specific force at rest
    let f_sum: Vector3<f64> = rs.iter().map(|r| r.f * r.span_s).sum();
    let z = -f_sum.normalize();
    // body x: the horizontal part of the start/stop directions
    let hs: Vec<Vector3<f64>> = dirs
        .iter()
        .map(|u| u - z * u.dot(&z))
        .filter(|h| h.norm() > 1e-6)
        .map(|h| h.normalize())
        .collect();
    let x_sum: Vector3<f64> = hs.iter().sum();
    if x_sum.norm() < 1e-6 {
        return Err(MountingError::NoRotation);
    }
    let x = x_sum.normalize();
    let y = z.cross(&x);
    let m = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    // pairs for the layout scores and the residuals: gravity at each rest, g along body +x
    // for each start/stop direction
    let g = rs.iter().map(|r| r.f.norm()).sum::<f64>() / rs.len() as f64;
    let mut ps: Vec<Pair> = rs
        .iter()
        .map(|r| pair(r.f, Vector3::new(0.0, 0.0, -g)))
        .collect();
    ps.extend(dirs.iter().map(|u| pair(u * g, Vector3::new(g, 0.0, 0.0))));
    let mut scored: Vec<(f64, Matrix3<f64>)> = axis_layouts()
        .into_iter()
        .map(|l| (residual(&l, &ps), l))
        .collect();
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (best_res, layout) = scored[0];
    // one-sigma: yaw from the scatter of the directions, tilt from the rests' noise
    let yaw_sd = {
        let a: Vec<f64> = hs.iter().map(|h| h.dot(&y).atan2(h.dot(&x))).collect();
        let n = a.len() as f64;
        (a.iter().map(|v| v * v).sum::<f64>() / (n - 1.0).max(1.0) / n).sqrt()
    };
    // tilt: the scatter of the rests' gravity directions (two or more rests), or the
    // sample noise of the one
    let tilt_sd = {
        let n = rs.len() as f64;
        let scatter = rs
            .iter()
            .map(|r| (r.f.normalize() + z).norm_squared())
            .sum::<f64>()
            / (n - 1.0).max(1.0)
            / n;
        let noise = rs
            .iter()
            .map(|r| (r.sd / g).powi(2) / r.samples.max(1) as f64)
            .sum::<f64>()
            / (n * n);
        if rs.len() >= 2 {
            scatter.sqrt()
        } else {
            noise.sqrt()
        }
    };
    let rpy = nav_core::attitude::euler_zyx_from_dcm(&m.transpose());
    let slope = turn_slope(imu, &iv, &m);
    let mut notes = vec![
        format!(
            "slow vehicle: roll and pitch from gravity at {} rests ({:.0} s, {} samples), yaw \
             from the velocity change of {} starts and stops (the vehicle drives forwards)",
            rs.len(),
            rs.iter().map(|r| r.span_s).sum::<f64>(),
            rs.iter().map(|r| r.samples).sum::<usize>(),
            dirs.len()
        ),
        format!(
            "not determined from GNSS accelerations: only {moving} GNSS intervals at >= {} m/s",
            super::MIN_SPEED_MPS
        ),
    ];
    notes.push(match slope {
        Some((s, n)) => format!(
            "z axis check: the body z gyro follows the GNSS course over {n} turning intervals \
             with slope {s:.2} (1 expected)"
        ),
        None => "z axis check: no turns resolved by the fixes, the z gyro not compared".into(),
    });
    Ok(MountingEstimate {
        rpy_deg: rpy.map(f64::to_degrees),
        sigma_deg: [tilt_sd, tilt_sd, yaw_sd].map(f64::to_degrees),
        layout,
        best_residual_mps2: best_res,
        runner_up_residual_mps2: scored[1].0,
        final_residual_mps2: residual(&m, &ps),
        rest_intervals: rs.iter().map(|r| r.last + 1 - r.first).sum(),
        moving_intervals: dirs.len(),
        notes,
    })
}

fn pair(f_meas: Vector3<f64>, f_exp: Vector3<f64>) -> Pair {
    Pair {
        f_meas,
        f_exp,
        w_meas: Vector3::zeros(),
        wz_exp: None,
        speed: 0.0,
        moving: false,
        lat_mps2: 0.0,
    }
}
