//! Initialisation of a run: from the truth (with injected errors), from a given state, or by
//! static coarse alignment on the first seconds of data.
//!
//! # Static alignment ([`StaticAlign`])
//!
//! Roll and pitch come from levelling the mean specific force of the window
//! (`nav_core::align::coarse_align`, which also checks that the window is static). Heading:
//! given, or (MEMS gyros cannot gyrocompass) from the GNSS **course of the first metres of
//! motion**: the direction from the mean static antenna position to the first later fix at
//! least `course_distance_m` away. That looks ahead in the data (post-processing), assumes the
//! vehicle drives off forward and roughly straight, and is given a generous uncertainty
//! (`heading_std_rad`) that the filter then reduces. Position: the mean antenna position of the
//! fixes inside the window, moved to the IMU point with the lever arm. Velocity zero. With
//! `gyro_bias_from_static`, the gyro bias estimate starts at the window's mean angular rate
//! minus the earth rate (resolved with the aligned attitude): the usual MEMS start-up
//! calibration. The filter starts at the last sample of the window.

use super::{RunError, RunOptions};
use nalgebra::Vector3;
use nav_core::align::{coarse_align, static_start, AlignConfig, HeadingSource};
use nav_core::attitude::quat_from_rotvec;
use nav_core::config::FilterConfig;
use nav_core::earth::{self, Llh};
use nav_core::filter::InitialUncertainty;
use nav_core::model::BlockKind;
use nav_core::nav::NavState;
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
    /// Distance the antenna must move for the GNSS course, m.
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
#[derive(Debug, Clone, Copy)]
pub struct InitData<'a> {
    /// IMU samples from the start of the record (a bounded prefix is enough: the static
    /// window plus one sample).
    pub imu: &'a [ImuSample],
    /// GNSS fixes in time order.
    pub gnss: &'a [GnssFix],
    /// Truth, when known.
    pub truth: Option<&'a [NavSolution]>,
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
    let i1 = case.imu.partition_point(|s| s.t_s <= t_a + sa.seconds);
    let window = case.imu.get(i0..i1).unwrap_or(&[]);
    let t_b = window.last().map_or(t_a, |s| s.t_s);

    // static antenna position: mean of the fixes in the window
    let fixes: Vec<_> = case
        .gnss
        .iter()
        .filter(|g| g.t_s >= t_a - 0.5 && g.t_s <= t_b + 0.5 && g.is_valid())
        .collect();
    if fixes.is_empty() {
        return Err(RunError::Init(format!(
            "no valid GNSS fix during the static window {t_a:.3} .. {t_b:.3} s"
        )));
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
    let ant = earth::displace(&ref0, &mean_off);

    let heading = match sa.heading_rad {
        Some(y) => (
            HeadingSource::Given {
                yaw_rad: y,
                std_rad: sa.heading_std_rad,
            },
            "given".to_string(),
        ),
        None => {
            let by_speed = sa
                .course_min_speed_mps
                .and_then(|v| gnss_velocity_course(case, t_b, v));
            let (yaw, what) = match by_speed {
                Some((yaw, t, v)) => (
                    yaw,
                    format!("GNSS velocity course at {v:.2} m/s (fix at {t:.2} s)"),
                ),
                None => {
                    let (yaw, t, d) = gnss_course(case, &ant, t_b, sa.course_distance_m)?;
                    (
                        yaw,
                        format!("GNSS course over the first {d:.1} m of motion (fix at {t:.2} s)"),
                    )
                }
            };
            (
                HeadingSource::Given {
                    yaw_rad: yaw,
                    std_rad: sa.heading_std_rad,
                },
                format!("{what}: {:.2} deg", yaw.to_degrees()),
            )
        }
    };
    let acfg = sa.align.with_filter_biases(cfg);
    let al = coarse_align(window, &ant, heading.0, &acfg)
        .map_err(|e| RunError::Init(format!("static alignment on {t_a:.3} .. {t_b:.3} s: {e}")))?;
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

/// The course from `from` to the first fix after `t_after` at least `dist_m` away
/// horizontally: (yaw rad, fix time, distance).
fn gnss_course(
    case: &InitData<'_>,
    from: &Llh,
    t_after: f64,
    dist_m: f64,
) -> Result<(f64, f64, f64), RunError> {
    for g in case.gnss.iter().filter(|g| g.t_s > t_after && g.is_valid()) {
        let p = Llh {
            lat_rad: g.lat_rad,
            lon_rad: g.lon_rad,
            h_m: g.h_m,
        };
        let d = earth::ned_offset_m(from, &p);
        let hd = d.x.hypot(d.y);
        if hd >= dist_m {
            return Ok((d.y.atan2(d.x), g.t_s, hd));
        }
    }
    Err(RunError::Init(format!(
        "no heading given and the antenna never moves {dist_m} m after the static window \
         (GNSS course unavailable)"
    )))
}

/// The course of the first fix after `t_after` with a velocity of at least `min_speed_mps`
/// horizontally: (yaw rad, fix time, speed).
fn gnss_velocity_course(
    case: &InitData<'_>,
    t_after: f64,
    min_speed_mps: f64,
) -> Option<(f64, f64, f64)> {
    case.gnss
        .iter()
        .filter(|g| g.t_s > t_after && g.is_valid() && g.has_velocity)
        .find_map(|g| {
            let [vn, ve, _] = g.vel_ned_mps;
            let v = vn.hypot(ve);
            (v >= min_speed_mps).then(|| (ve.atan2(vn), g.t_s, v))
        })
}
