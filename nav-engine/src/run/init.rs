//! Initialisation of a run: from the truth (with injected errors), from a given state, or by
//! static coarse alignment on the first seconds of data.
//!
//! # Static alignment ([`StaticAlign`])
//!
//! Roll and pitch come from levelling the mean specific force of the window
//! (`nav_core::align::coarse_align`, which also checks that the window is static). Heading:
//! given, or (MEMS gyros cannot gyrocompass) from the GNSS **course of the first metres of
//! motion**: the direction from the mean static antenna position to the later fixes, from
//! the first one far enough away for a 1-deg course from the fixes' sigmas, extended while
//! the track stays straight up to `course_distance_m` (`nav_core::align::TrackCourse`).
//! That looks ahead in the data (post-processing), assumes the
//! vehicle drives off forward and roughly straight, and is given a generous uncertainty
//! (`heading_std_rad`) that the filter then reduces. Position: the mean antenna position of the
//! fixes inside the window, moved to the IMU point with the lever arm. Velocity zero. With
//! `gyro_bias_from_static`, the gyro bias estimate starts at the window's mean angular rate
//! minus the earth rate (resolved with the aligned attitude): the usual MEMS start-up
//! calibration. The filter starts at the last sample of the window.

use super::engine::ahead::{fixes_from, FixLookup};
use super::{RunError, RunOptions};
use nalgebra::Vector3;
use nav_core::align::{
    coarse_align, motion_align, static_start, AlignConfig, AlignError, Course, CourseRule,
    HeadingSource, MotionAlignConfig, MotionCue, MotionLevelling, TrackCourse,
};
use nav_core::attitude::quat_from_rotvec;
use nav_core::config::FilterConfig;
use nav_core::earth::{self, Llh};
use nav_core::filter::{dcm_f64, InitialUncertainty};
use nav_core::model::BlockKind;
use nav_core::strapdown::NavState;
use nav_core::types::{GnssFix, ImuSample, NavSolution};
use serde::Serialize;

/// How the filter's initial state is obtained.
#[derive(Debug, Clone, PartialEq)]
pub enum InitSpec {
    /// The truth at the first truth epoch (at or after the start time) with injected errors,
    /// each *estimate minus truth*: position NED offset (m), NED velocity (m/s) and phi angle
    /// (rad; `C_hat = (I - [phi x]) C`). `unc` is the initial 1-sigma the filter is told.
    FromTruth {
        /// Position error, N/E/D, m.
        pos_err_m: [f64; 3],
        /// Velocity error, N/E/D, m/s.
        vel_err_mps: [f64; 3],
        /// Attitude error phi, N/E/D axes, rad.
        att_err_rad: [f64; 3],
        /// Initial uncertainty given to the filter.
        unc: InitialUncertainty,
    },
    /// A given nominal state (its time is the initial epoch) and uncertainty.
    Given(NavState, InitialUncertainty),
    /// Static coarse alignment on the first seconds of data.
    StaticAlignment(StaticAlign),
}

/// Static alignment settings (see the module notes).
#[derive(Debug, Clone, PartialEq)]
pub struct StaticAlign {
    /// Length of the static window from the first IMU sample (or the start time), s.
    pub seconds: f64,
    /// Heading (yaw of the body x axis), rad; `None` = from the GNSS course.
    pub heading_rad: Option<f64>,
    /// 1-sigma of the heading, rad.
    pub heading_std_rad: f64,
    /// Distance at which the antenna's GNSS course is taken whatever the fixes' sigmas, m
    /// (precise fixes give it earlier).
    pub course_distance_m: f64,
    /// When set and the fixes carry velocities: the course is that of the first fix after the
    /// window whose horizontal speed reaches this, m/s (instead of the displacement rule).
    pub course_min_speed_mps: Option<f64>,
    /// Overrides the levelling's roll/pitch 1-sigma, rad (e.g. a configured floor).
    pub tilt_std_rad: Option<f64>,
    /// Start the gyro-bias estimate at the static mean rate minus the earth rate.
    pub gyro_bias_from_static: bool,
    /// Static-detection thresholds (the assumed sensor biases for the attitude uncertainty
    /// are taken from the filter configuration's initial bias sigmas when those are set).
    pub align: AlignConfig,
    /// Initial velocity 1-sigma, m/s.
    pub vel_sigma_mps: f64,
}

impl StaticAlign {
    /// `seconds` of static data, heading from the GNSS course (10 deg 1-sigma, 5 m), gyro bias
    /// from the static mean, default detection thresholds, 0.02 m/s velocity sigma.
    pub fn new(seconds: f64) -> Self {
        Self {
            seconds,
            heading_rad: None,
            heading_std_rad: 10f64.to_radians(),
            course_distance_m: 5.0,
            course_min_speed_mps: None,
            tilt_std_rad: None,
            gyro_bias_from_static: true,
            align: AlignConfig::default(),
            vel_sigma_mps: 0.02,
        }
    }
}

/// How a run was initialised.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InitReport {
    /// Initial epoch, GPS seconds of week.
    pub t_s: f64,
    /// `truth`, `given` or `static_alignment`.
    pub method: String,
    /// Initial roll, pitch, yaw, rad.
    pub rpy_rad: [f64; 3],
    /// Initial attitude 1-sigma (phi N/E/D), rad.
    pub att_sigma_rad: [f64; 3],
    /// Where the heading came from.
    pub heading_source: String,
    /// Static alignment: mean angular rate minus earth rate, body, rad/s.
    pub static_gyro_bias_radps: Option<[f64; 3]>,
    /// Static alignment: mean specific force, body, m/s^2.
    pub static_mean_f_mps2: Option<[f64; 3]>,
    /// Static alignment: window length, s.
    pub static_window_s: Option<f64>,
}

pub(crate) struct Start {
    /// Lower bound of the initial gyro-bias sigma (the static calibration's own noise).
    pub gyro_bias_sigma_floor: Option<[f64; 3]>,
    pub state: NavState,
    pub unc: InitialUncertainty,
    pub estimates: Vec<(BlockKind, [f64; 3])>,
    pub report: InitReport,
}

/// What the initialisation looks at: the first IMU samples (at least the static window), the
/// GNSS fixes and the truth when there is one.
#[derive(Clone, Copy)]
pub struct InitData<'a> {
    /// IMU samples from the start of the record (a bounded prefix is enough: the static
    /// window plus one sample).
    pub imu: &'a [ImuSample],
    /// GNSS fixes in time order (a slice, or the run's stream read as far ahead as the
    /// start-up looks).
    pub gnss: &'a dyn FixLookup,
    /// Truth, when known.
    pub truth: Option<&'a [NavSolution]>,
}

impl std::fmt::Debug for InitData<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("InitData")
            .field("imu", &self.imu.len())
            .field("gnss", &"(fixes read on demand)")
            .field("truth", &self.truth.map(<[NavSolution]>::len))
            .finish()
    }
}

fn max3(a: &[f64; 3]) -> f64 {
    a.iter().fold(0.0f64, |m, v| m.max(v.abs()))
}

pub(crate) fn initialise(
    case: &InitData<'_>,
    opts: &RunOptions,
    cfg: &FilterConfig,
) -> Result<Start, RunError> {
    let start_s = opts.start_s.unwrap_or(f64::NEG_INFINITY);
    match &opts.init {
        InitSpec::Given(state, unc) => Ok(Start {
            gyro_bias_sigma_floor: None,
            state: *state,
            unc: *unc,
            estimates: Vec::new(),
            report: InitReport {
                t_s: state.t_s,
                method: "given".into(),
                rpy_rad: state.rpy_rad(),
                att_sigma_rad: unc.att_sigma_rad,
                heading_source: "given".into(),
                static_gyro_bias_radps: None,
                static_mean_f_mps2: None,
                static_window_s: None,
            },
        }),
        InitSpec::FromTruth {
            pos_err_m,
            vel_err_mps,
            att_err_rad,
            unc,
        } => {
            let truth = case.truth.ok_or_else(|| {
                RunError::Init("initialisation from the truth needs a truth record".into())
            })?;
            let tr = truth
                .iter()
                .find(|s| s.t_s >= start_s && s.t_s.is_finite())
                .ok_or_else(|| RunError::Init("no truth record at or after the start".into()))?;
            let s = NavState::from_solution(tr);
            let pos = earth::displace(&s.pos, &Vector3::from(*pos_err_m));
            let vel = s.vel_ned_mps + Vector3::from(*vel_err_mps);
            // C_hat = (I - [phi x]) C  =>  q_hat = q(-phi) q
            let q = quat_from_rotvec(&(-Vector3::from(*att_err_rad))) * s.q_nb;
            let state = NavState {
                t_s: s.t_s,
                pos,
                vel_ned_mps: vel,
                q_nb: q,
            };
            Ok(Start {
                gyro_bias_sigma_floor: None,
                state,
                unc: *unc,
                estimates: Vec::new(),
                report: InitReport {
                    t_s: s.t_s,
                    method: "truth".into(),
                    rpy_rad: state.rpy_rad(),
                    att_sigma_rad: unc.att_sigma_rad,
                    heading_source: "truth".into(),
                    static_gyro_bias_radps: None,
                    static_mean_f_mps2: None,
                    static_window_s: None,
                },
            })
        }
        InitSpec::StaticAlignment(sa) => static_alignment(case, opts, cfg, sa, start_s),
    }
}

fn static_alignment(
    case: &InitData<'_>,
    opts: &RunOptions,
    cfg: &FilterConfig,
    sa: &StaticAlign,
    start_s: f64,
) -> Result<Start, RunError> {
    if !(sa.seconds.is_finite() && sa.seconds > 0.0) {
        return Err(RunError::Init(format!(
            "static window of {} s: must be positive",
            sa.seconds
        )));
    }
    let i0 = case.imu.partition_point(|s| s.t_s < start_s);
    let t_a = case
        .imu
        .get(i0)
        .map(|s| s.t_s)
        .ok_or_else(|| RunError::Init("no IMU samples at or after the start".into()))?;
    // a vehicle that moves at the start cannot be levelled at rest: align from the GNSS
    // velocity instead (and say so)
    if let Some((speed, t_fix)) = start_speed(case, t_a) {
        if speed >= MOVING_SPEED_MPS {
            return motion_alignment(
                case,
                opts,
                sa,
                t_a,
                format!(
                    "GNSS speed {speed:.2} m/s at {t_fix:.2} s: the vehicle moves at the start"
                ),
            );
        }
    }
    // the window covers `seconds`: it ends at the first sample at or after t_a + seconds (the
    // samples' times need not fall on t_a + seconds: "static_s = 10" at 125 Hz gave a
    // 9.9938 s window, refused as shorter than 10 s)
    let window = static_window(case.imu, i0, t_a, sa.seconds);
    let t_b = window.last().map_or(t_a, |s| s.t_s);

    let (ant, mean_std) = static_antenna(case, t_a, t_b)?;

    let heading = static_heading(case, sa, &ant, &mean_std, t_b)?;
    let mut acfg = sa.align.with_filter_biases(cfg);
    // the window length is the user's choice (static_s); float slack only
    acfg.min_duration_s = sa.seconds - 1e-6;
    let al = coarse_align(window, &ant, heading.0, &acfg)
        .map_err(|e| align_error(e, sa.seconds, t_a, t_b))?;
    let st = static_start(
        &al,
        &ant,
        &mean_std,
        &opts.lever_arm_m,
        &cfg.gyro.s_n,
        sa.vel_sigma_mps,
        sa.tilt_std_rad,
    );
    let (state, unc, bias) = (st.state, st.unc, st.gyro_bias_radps);
    let att_sigma = unc.att_sigma_rad;
    let mut estimates = Vec::new();
    let mut floor = None;
    if sa.gyro_bias_from_static {
        estimates.push((BlockKind::GyroBias, bias));
        floor = Some(st.gyro_bias_sigma_floor_radps);
    }
    Ok(Start {
        gyro_bias_sigma_floor: floor,
        state,
        unc,
        estimates,
        report: InitReport {
            t_s: al.t_end_s,
            method: "static_alignment".into(),
            rpy_rad: al.rpy_rad,
            att_sigma_rad: att_sigma,
            heading_source: heading.1,
            static_gyro_bias_radps: Some(bias),
            static_mean_f_mps2: Some(al.mean_f_body_mps2),
            static_window_s: Some(al.duration_s),
        },
    })
}

/// The static window from the sample `i0` at `t_a` s: it covers `seconds`, ending at the first
/// sample at or after `t_a + seconds` (the samples' times need not fall on `t_a + seconds`:
/// "static_s = 10" at 125 Hz gave a 9.9938 s window, refused as shorter than 10 s).
fn static_window(imu: &[ImuSample], i0: usize, t_a: f64, seconds: f64) -> &[ImuSample] {
    let mut i1 = imu.partition_point(|s| s.t_s <= t_a + seconds);
    if imu
        .get(i1.wrapping_sub(1))
        .is_some_and(|s| s.t_s < t_a + seconds - 1e-9)
        && i1 < imu.len()
    {
        i1 += 1;
    }
    imu.get(i0..i1).unwrap_or(&[])
}

/// The static antenna position: the mean of the valid fixes within 0.5 s of the window
/// `t_a .. t_b` s (as NED offsets from the first), and the mean of their reported position
/// sigmas N, E, D (m); an error when there is no fix.
fn static_antenna(case: &InitData<'_>, t_a: f64, t_b: f64) -> Result<(Llh, [f64; 3]), RunError> {
    let fixes: Vec<GnssFix> = fixes_from(case.gnss, 0)
        .take_while(|g| g.t_s <= t_b + 0.5)
        .filter(|g| g.t_s >= t_a - 0.5 && g.is_valid())
        .collect();
    if fixes.is_empty() {
        return Err(RunError::no_fix_to_align(t_a, t_b));
    }
    let n = fixes.len() as f64;
    let ref0 = Llh {
        lat_rad: fixes[0].lat_rad,
        lon_rad: fixes[0].lon_rad,
        h_m: fixes[0].h_m,
    };
    let mut mean_off = Vector3::zeros();
    let mut mean_std = [0.0; 3];
    for g in &fixes {
        let p = Llh {
            lat_rad: g.lat_rad,
            lon_rad: g.lon_rad,
            h_m: g.h_m,
        };
        mean_off += earth::ned_offset_m(&ref0, &p) / n;
        for (m, s) in mean_std.iter_mut().zip(g.pos_std_ned_m) {
            *m += s / n;
        }
    }
    Ok((earth::displace(&ref0, &mean_off), mean_std))
}

/// The heading of the static alignment and how it was found: the given yaw, else the GNSS
/// velocity course (above `course_min_speed_mps`), else the course over the first
/// `course_distance_m` of motion after the window's end `t_b` s (its sigma from the start
/// position's `mean_std`, m); rad.
fn static_heading(
    case: &InitData<'_>,
    sa: &StaticAlign,
    ant: &Llh,
    mean_std: &[f64; 3],
    t_b: f64,
) -> Result<(HeadingSource, String), RunError> {
    Ok(match sa.heading_rad {
        Some(y) => (
            HeadingSource::Given {
                yaw_rad: y,
                std_rad: sa.heading_std_rad,
            },
            "given".to_string(),
        ),
        None => {
            let mut course_std = 0.0f64;
            let by_speed = sa
                .course_min_speed_mps
                .and_then(|v| gnss_velocity_course(case, t_b, v));
            let (yaw, what) = match by_speed {
                Some((yaw, t, v)) => (
                    yaw,
                    format!("GNSS velocity course at {v:.2} m/s (fix at {t:.2} s)"),
                ),
                None => {
                    let start_sigma = mean_std[0].max(mean_std[1]);
                    let (c, t) = gnss_course(case, ant, start_sigma, t_b, sa.course_distance_m)?;
                    course_std = c.std_rad;
                    (
                        c.yaw_rad,
                        format!(
                            "GNSS course over the first {:.2} m of motion (fix at {t:.2} s, \
                             1-sigma {:.2} deg)",
                            c.distance_m,
                            c.std_rad.to_degrees()
                        ),
                    )
                }
            };
            (
                HeadingSource::Given {
                    yaw_rad: yaw,
                    std_rad: sa.heading_std_rad.max(course_std),
                },
                format!("{what}: {:.2} deg", yaw.to_degrees()),
            )
        }
    })
}

/// The error of a failed static alignment on `t_a .. t_b` s, with the way out for the user
/// (`static_s` the configured window, s).
fn align_error(e: AlignError, static_s: f64, t_a: f64, t_b: f64) -> RunError {
    let way_out = match e {
        AlignError::TooShort { .. } => format!(
            "the data after the start hold less than static_s = {} s: shorten \
             [init.align] static_s or move start_s earlier",
            static_s
        ),
        AlignError::NotStatic {
            cue: MotionCue::GravityMismatch,
            ..
        } => "the vehicle accelerates, or the accelerometer bias/scale error is larger \
              than max_gravity_mismatch_mps2 (raise it for consumer MEMS, e.g. 0.2)"
            .into(),
        AlignError::NotStatic { .. } => format!(
            "the vehicle is not at rest during the first {} s and the GNSS speed at the \
             start is below {MOVING_SPEED_MPS} m/s (so in-motion alignment was not used): \
             shorten static_s to the part at rest, move start_s to a stop or to where \
             the vehicle drives, or give [init.given]",
            static_s
        ),
        _ => "check the IMU time stamps of the window, or give [init.given]".into(),
    };
    RunError::Align {
        msg: format!("static alignment on {t_a:.3} .. {t_b:.3} s: {e}; {way_out}"),
        source: e,
    }
}

/// The GNSS course of the track from `from` (horizontal one-sigma `from_sigma_m`) over the
/// fixes after `t_after` (`nav_core::align::TrackCourse`: from the first fix far enough away
/// for a 1-deg course from the sigmas, extended while the track stays straight, up to
/// `dist_m`): (course, time of the fix it ends at).
fn gnss_course(
    case: &InitData<'_>,
    from: &Llh,
    from_sigma_m: f64,
    t_after: f64,
    dist_m: f64,
) -> Result<(Course, f64), RunError> {
    let mut track = TrackCourse::new(CourseRule {
        max_distance_m: dist_m,
        ..CourseRule::default()
    });
    let mut t_end = f64::NAN;
    for g in fixes_from(case.gnss, 0).filter(|g| g.t_s > t_after && g.is_valid()) {
        let d = earth::ned_offset_m(from, &llh_of(&g));
        let s_fix = g.pos_std_ned_m[0].max(g.pos_std_ned_m[1]);
        let before = track.course();
        let settled = track.push(d.x, d.y, from_sigma_m.hypot(s_fix), s_fix);
        if track.course() != before {
            t_end = g.t_s;
        }
        if settled {
            break;
        }
    }
    track.course().map(|c| (c, t_end)).ok_or_else(|| {
        RunError::Init(format!(
            "no heading given and the antenna never moves far enough after the static window \
             for the GNSS course (1 deg from the fixes' sigmas, or {dist_m} m)"
        ))
    })
}

/// The course of the first fix after `t_after` with a velocity of at least `min_speed_mps`
/// horizontally: (yaw rad, fix time, speed).
fn gnss_velocity_course(
    case: &InitData<'_>,
    t_after: f64,
    min_speed_mps: f64,
) -> Option<(f64, f64, f64)> {
    fixes_from(case.gnss, 0)
        .filter(|g| g.t_s > t_after && g.is_valid() && g.has_velocity)
        .find_map(|g| {
            let [vn, ve, _] = g.vel_ned_mps;
            let v = vn.hypot(ve);
            (v >= min_speed_mps).then(|| (ve.atan2(vn), g.t_s, v))
        })
}

/// GNSS horizontal speed at or above which the run is aligned in motion, m/s.
pub const MOVING_SPEED_MPS: f64 = 2.0;

fn llh_of(g: &GnssFix) -> Llh {
    Llh {
        lat_rad: g.lat_rad,
        lon_rad: g.lon_rad,
        h_m: g.h_m,
    }
}

/// The first two valid fixes at or after `t_a` (within 5 s of each other).
fn first_two_fixes(case: &InitData<'_>, t_a: f64) -> Option<(GnssFix, GnssFix)> {
    let mut it = fixes_from(case.gnss, 0)
        .take_while(|g| g.t_s <= t_a + 5.0)
        .filter(|g| g.t_s >= t_a - 1e-6 && g.is_valid());
    let a = it.next()?;
    let b = it.next()?;
    (b.t_s - a.t_s > 0.0 && b.t_s - a.t_s <= 5.0).then_some((a, b))
}

/// NED velocity at fix `a` (its own, or the mean over a -> b from the positions), m/s, and
/// its one-sigma per axis.
fn fix_velocity(a: &GnssFix, b: &GnssFix) -> (Vector3<f64>, f64) {
    if a.has_velocity {
        let s = max3(&a.vel_std_ned_mps);
        return (Vector3::from(a.vel_ned_mps), s);
    }
    let dt = b.t_s - a.t_s;
    let d = earth::ned_offset_m(&llh_of(a), &llh_of(b));
    let s = a.pos_std_ned_m[0]
        .max(a.pos_std_ned_m[1])
        .hypot(b.pos_std_ned_m[0].max(b.pos_std_ned_m[1]));
    (d / dt, s / dt)
}

/// Horizontal GNSS speed at the start and the time of the fix it is from.
fn start_speed(case: &InitData<'_>, t_a: f64) -> Option<(f64, f64)> {
    let (a, b) = first_two_fixes(case, t_a)?;
    let (v, _) = fix_velocity(&a, &b);
    Some((v.x.hypot(v.y), a.t_s))
}

/// In-motion alignment (`nav_core::align::motion_align`): yaw from the GNSS course, pitch
/// from the climb, roll levelled with the mean specific force between the first two fixes
/// against the GNSS acceleration; position and velocity from the first fix after the start.
fn motion_alignment(
    case: &InitData<'_>,
    opts: &RunOptions,
    sa: &StaticAlign,
    t_a: f64,
    why: String,
) -> Result<Start, RunError> {
    let (f0, f1) = first_two_fixes(case, t_a).ok_or_else(|| {
        RunError::Init(format!(
            "in-motion alignment ({why}) needs two valid GNSS fixes within 5 s after the start"
        ))
    })?;
    let dt = f1.t_s - f0.t_s;
    let (v0, v_std) = fix_velocity(&f0, &f1);
    // acceleration: from the two fixes' velocities, or (positions only) from a third fix
    let third = fixes_from(case.gnss, 0)
        .take_while(|g| g.t_s <= f1.t_s + 5.0)
        .filter(|g| g.t_s > f1.t_s && g.is_valid())
        .find(|_| !f0.has_velocity);
    let (acc, acc_std) = match (f0.has_velocity && f1.has_velocity, third) {
        (true, _) => (
            (Vector3::from(f1.vel_ned_mps) - v0) / dt,
            std::f64::consts::SQRT_2 * v_std / dt,
        ),
        (false, Some(f2)) => {
            let (v1, _) = fix_velocity(&f1, &f2);
            let dtm = 0.5 * (f2.t_s - f0.t_s);
            ((v1 - v0) / dtm, std::f64::consts::SQRT_2 * v_std / dtm)
        }
        (false, None) => (Vector3::zeros(), 1.0),
    };
    // mean specific force over (t0, t1]
    let (mut dv, mut tsum) = (Vector3::zeros(), 0.0);
    let mut prev: Option<f64> = None;
    for s in case
        .imu
        .iter()
        .filter(|s| s.t_s > f0.t_s - 0.02 && s.t_s <= f1.t_s)
    {
        if let Some(p) = prev {
            dv += Vector3::from(s.dv_mps);
            tsum += s.t_s - p;
        }
        prev = Some(s.t_s);
    }
    let p0 = llh_of(&f0);
    let level = (tsum > 0.0).then(|| MotionLevelling {
        mean_f_body_mps2: (dv / tsum).into(),
        accel_ned_mps2: acc.into(),
        accel_std_mps2: acc_std,
        gravity_mps2: earth::gravity_mps2(p0.lat_rad, p0.h_m),
    });
    let mcfg = MotionAlignConfig::default();
    let mut al =
        motion_align(v0.into(), v_std, level.as_ref(), &mcfg).map_err(|e| RunError::Align {
            msg: format!(
                "in-motion alignment ({why}): {e}; give [init.given] or start where the \
                 vehicle stands still or drives faster"
            ),
            source: e,
        })?;
    let heading = match sa.heading_rad {
        Some(y) => {
            al.rpy_rad[2] = y;
            al.att_std_rad[2] = sa.heading_std_rad;
            "given".to_string()
        }
        None => format!(
            "GNSS velocity course at {:.2} m/s (fix at {:.2} s): {:.2} deg",
            v0.x.hypot(v0.y),
            f0.t_s,
            al.rpy_rad[2].to_degrees()
        ),
    };
    // start at the first IMU sample at or after the fix
    let i = case.imu.partition_point(|s| s.t_s < f0.t_s);
    let t0 = case.imu.get(i).map(|s| s.t_s).ok_or_else(|| {
        RunError::Init(format!(
            "in-motion alignment ({why}): no IMU sample after the first fix"
        ))
    })?;
    let q = nav_core::attitude::quat_from_euler_zyx(al.rpy_rad);
    let c = dcm_f64(&q);
    let lag = t0 - f0.t_s;
    let ant = earth::displace(&p0, &(v0 * lag));
    let pos = earth::displace(&ant, &(-(c * Vector3::from(opts.lever_arm_m))));
    let state = NavState {
        t_s: t0,
        pos,
        vel_ned_mps: v0 + acc * lag,
        q_nb: q,
    };
    let unc = InitialUncertainty {
        att_sigma_rad: al.att_std_rad,
        vel_sigma_mps: [v_std.max(sa.vel_sigma_mps); 3],
        pos_sigma_m: f0.pos_std_ned_m.map(|s| s + 0.01),
    };
    Ok(Start {
        gyro_bias_sigma_floor: None,
        state,
        unc,
        estimates: Vec::new(),
        report: InitReport {
            t_s: t0,
            method: format!("in-motion alignment ({why})"),
            rpy_rad: al.rpy_rad,
            att_sigma_rad: al.att_std_rad,
            heading_source: format!(
                "{heading}; pitch from the climb, roll {}",
                if level.is_some() {
                    "levelled on the move"
                } else {
                    "0 (no IMU data between the first fixes)"
                }
            ),
            static_gyro_bias_radps: None,
            static_mean_f_mps2: level.map(|l| l.mean_f_body_mps2),
            static_window_s: None,
        },
    })
}
