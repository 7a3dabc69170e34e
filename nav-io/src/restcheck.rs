//! What the IMU shows while the vehicle stands still at the start of a record, and the check of
//! the configured initial bias sigmas against it.
//!
//! The rest window starts at the first IMU sample and ends at the first sign of motion: a GNSS
//! speed above [`REST_SPEED_MPS`] (from the fixes' velocities, or a horizontal displacement
//! from the first fix beyond three times its sigma and 0.3 m), or an IMU block of 0.25 s
//! whose mean rate or specific force leaves the first second's by more than six standard
//! errors (plus a floor of 0.001 rad/s and 0.03 m/s^2). Its last 0.5 s are dropped (the
//! motion starts before it is seen). A window shorter than [`MIN_REST_S`] is no rest.
//!
//! At rest the mean angular rate is the gyro bias plus the earth rate (at most 7.3e-5 rad/s,
//! 15 deg/h), and the length of the mean specific force minus normal gravity is the
//! accelerometer bias along the vertical after levelling (the horizontal biases tilt the
//! levelling and are not seen). [`bias_warnings`] compares both with the configured initial
//! bias sigmas.

use super::runcfg::RunConfig;
use nav_core::earth::{gravity_mps2, ned_offset_m, Llh, OMEGA_IE_RADPS};
use nav_core::types::{GnssFix, ImuSample};
use std::path::Path;

/// GNSS speed above which the vehicle moves, m/s.
pub const REST_SPEED_MPS: f64 = 0.2;
/// Shortest rest window that counts, s.
pub const MIN_REST_S: f64 = 2.0;
/// Longest span of the record examined, s.
pub const REST_PREFIX_S: f64 = 120.0;
/// A configured bias sigma exceeded this many times by the bias seen at rest is warned about.
pub const BIAS_SIGMA_FACTOR: f64 = 5.0;

/// How far the local gravity may differ from the normal gravity model the accelerometer check
/// compares with (gravity anomalies reach a few hundred mGal), m/s^2: a smaller mismatch says
/// nothing about the accelerometer bias (0.5 mg).
pub const GRAVITY_MODEL_TOLERANCE_MPS2: f64 = 0.5e-3 * 9.806_65;

const BLOCK_S: f64 = 0.25;
const MARGIN_S: f64 = 0.5;
const REF_S: f64 = 1.0;

/// The IMU at rest at the start of a record (means and standard deviations per sample, body or
/// sensor axes as the samples are given).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RestStats {
    /// Start of the rest window (first IMU sample), s.
    pub t0_s: f64,
    /// Length of the rest window, s.
    pub duration_s: f64,
    /// Samples in the window.
    pub samples: usize,
    /// Mean sample interval, s.
    pub dt_s: f64,
    /// Mean angular rate per axis, rad/s.
    pub mean_rate_radps: [f64; 3],
    /// Standard deviation of the angular rate per axis, rad/s.
    pub std_rate_radps: [f64; 3],
    /// Mean specific force per axis, m/s^2.
    pub mean_f_mps2: [f64; 3],
    /// Standard deviation of the specific force per axis, m/s^2.
    pub std_f_mps2: [f64; 3],
    /// Normal gravity at the first fix (9.80665 without one), m/s^2.
    pub gravity_mps2: f64,
    /// What ended the window ("GNSS motion at ... s", "IMU motion at ... s", "end of the
    /// examined span").
    pub ended_by: &'static str,
}

impl RestStats {
    /// Length of the mean specific force minus normal gravity, m/s^2 (the vertical
    /// accelerometer bias after levelling, or a unit/scale error).
    pub fn gravity_mismatch_mps2(&self) -> f64 {
        norm(self.mean_f_mps2) - self.gravity_mps2
    }
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Time of the first GNSS sign of motion (see the module notes); `None` when the fixes never
/// show motion, `Some(first fix time)` when the first fix already moves.
pub fn gnss_motion_start(fixes: &[GnssFix]) -> Option<f64> {
    let valid: Vec<&GnssFix> = fixes.iter().filter(|g| g.is_valid()).collect();
    let first = valid.first()?;
    let p0 = Llh {
        lat_rad: first.lat_rad,
        lon_rad: first.lon_rad,
        h_m: first.h_m,
    };
    for g in &valid {
        if g.has_velocity && g.vel_ned_mps[0].hypot(g.vel_ned_mps[1]) > REST_SPEED_MPS {
            return Some(g.t_s);
        }
        let p = Llh {
            lat_rad: g.lat_rad,
            lon_rad: g.lon_rad,
            h_m: g.h_m,
        };
        let d = ned_offset_m(&p0, &p);
        let sig = first.pos_std_ned_m[0].hypot(first.pos_std_ned_m[1]) + 1e-3;
        if d.x.hypot(d.y) > (3.0 * sig).max(0.3) {
            return Some(g.t_s);
        }
    }
    None
}

/// Sums of one block of samples.
#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    n: usize,
    dt: f64,
    w: [f64; 3],
    w2: [f64; 3],
    f: [f64; 3],
    f2: [f64; 3],
}

impl Sums {
    fn add(&mut self, w: [f64; 3], f: [f64; 3], dt: f64) {
        self.n += 1;
        self.dt += dt;
        for k in 0..3 {
            self.w[k] += w[k];
            self.w2[k] += w[k] * w[k];
            self.f[k] += f[k];
            self.f2[k] += f[k] * f[k];
        }
    }

    fn merge(&mut self, o: &Sums) {
        self.n += o.n;
        self.dt += o.dt;
        for k in 0..3 {
            self.w[k] += o.w[k];
            self.w2[k] += o.w2[k];
            self.f[k] += o.f[k];
            self.f2[k] += o.f2[k];
        }
    }

    fn mean_std(s: [f64; 3], s2: [f64; 3], n: usize) -> ([f64; 3], [f64; 3]) {
        let n = n.max(1) as f64;
        let m = s.map(|v| v / n);
        let sd = [0, 1, 2].map(|k| (s2[k] / n - m[k] * m[k]).max(0.0).sqrt());
        (m, sd)
    }

    /// Whether this block's means leave the reference's by more than six standard errors
    /// (plus the floors).
    fn leaves(&self, rf: &Sums) -> bool {
        let (wm, _) = Self::mean_std(self.w, self.w2, self.n);
        let (fm, _) = Self::mean_std(self.f, self.f2, self.n);
        let (rwm, rws) = Self::mean_std(rf.w, rf.w2, rf.n);
        let (rfm, rfs) = Self::mean_std(rf.f, rf.f2, rf.n);
        let se = 1.0 / (self.n.max(1) as f64).sqrt();
        (0..3).any(|k| {
            (wm[k] - rwm[k]).abs() > 6.0 * rws[k] * se + 1e-3
                || (fm[k] - rfm[k]).abs() > 6.0 * rfs[k] * se + 0.03
        })
    }
}

/// The rest window at the start of `imu` (increments, time order) and its statistics, the
/// window ended by the GNSS motion start `gnss_motion_s` when given (see the module notes).
/// Reads at most [`REST_PREFIX_S`] of samples; memory is bounded by its blocks. `None` when the
/// window is shorter than [`MIN_REST_S`].
pub fn rest_stats(
    imu: impl IntoIterator<Item = ImuSample>,
    gnss_motion_s: Option<f64>,
    gravity_mps2: f64,
) -> Option<RestStats> {
    let mut prev_t: Option<f64> = None;
    let mut t0 = None;
    let mut reference = Sums::default();
    let mut blocks: Vec<Sums> = Vec::new();
    let mut cur = Sums::default();
    let mut block_end = 0.0;
    let mut ended_by = "end of the examined span";
    for s in imu {
        let Some(p) = prev_t.replace(s.t_s) else {
            t0 = Some(s.t_s);
            continue;
        };
        let dt = s.t_s - p;
        let t_start = t0.unwrap_or(p);
        if gnss_motion_s.is_some_and(|m| s.t_s >= m) {
            ended_by = "GNSS motion";
            break;
        }
        if s.t_s - t_start > REST_PREFIX_S {
            break;
        }
        if !(dt > 0.0 && dt < 0.5) {
            continue;
        }
        let w = s.dtheta_rad.map(|v| v / dt);
        let f = s.dv_mps.map(|v| v / dt);
        if s.t_s - t_start <= REF_S {
            reference.add(w, f, dt);
            continue;
        }
        if cur.n == 0 {
            block_end = s.t_s + BLOCK_S;
        }
        cur.add(w, f, dt);
        if s.t_s >= block_end {
            if cur.leaves(&reference) {
                ended_by = "IMU motion";
                break;
            }
            blocks.push(std::mem::take(&mut cur));
        }
    }
    let t0 = t0?;
    let margin_blocks = (MARGIN_S / BLOCK_S).round() as usize;
    if ended_by != "end of the examined span" {
        blocks.truncate(blocks.len().saturating_sub(margin_blocks));
    }
    let mut all = reference;
    for b in &blocks {
        all.merge(b);
    }
    let duration = all.dt;
    if duration.is_nan() || duration < MIN_REST_S || all.n < 10 {
        return None;
    }
    let (mw, sw) = Sums::mean_std(all.w, all.w2, all.n);
    let (mf, sf) = Sums::mean_std(all.f, all.f2, all.n);
    Some(RestStats {
        t0_s: t0,
        duration_s: duration,
        samples: all.n,
        dt_s: all.dt / all.n as f64,
        mean_rate_radps: mw,
        std_rate_radps: sw,
        mean_f_mps2: mf,
        std_f_mps2: sf,
        gravity_mps2,
        ended_by,
    })
}

/// The warnings when the biases seen at rest exceed [`BIAS_SIGMA_FACTOR`] times the configured
/// initial bias sigmas: the gyro's mean rate per axis (less the earth rate, which it may hold,
/// and three standard errors of its mean) against `gyro_sigma_radps`, the accelerometer's
/// gravity mismatch beyond [`GRAVITY_MODEL_TOLERANCE_MPS2`] against the largest of
/// `accel_sigma_mps2` (its vertical axis is not known before levelling).
pub fn bias_warnings(
    st: &RestStats,
    gyro_sigma_radps: [f64; 3],
    accel_sigma_mps2: [f64; 3],
) -> Vec<String> {
    let mut out = Vec::new();
    let axes = ["x", "y", "z"];
    let worst = (0..3)
        .map(|k| {
            // less the earth rate and three standard errors of the mean: what the data show
            let sem = 3.0 * st.std_rate_radps[k] / (st.samples.max(1) as f64).sqrt();
            let seen = (st.mean_rate_radps[k].abs() - OMEGA_IE_RADPS - sem).max(0.0);
            (seen / gyro_sigma_radps[k].max(1e-12), k)
        })
        .max_by(|a, b| a.0.total_cmp(&b.0));
    if let Some((ratio, k)) = worst {
        if ratio > BIAS_SIGMA_FACTOR {
            out.push(format!(
                "gyro bias: the mean rate at rest over the first {:.1} s is {:+.4} deg/s on \
                 the {} axis ({:.0} x the configured initial bias sigma {:.4} deg/s; mean \
                 rates {}); raise [noise.gyro] bias_init_deg_per_s to about {:.3}",
                st.duration_s,
                st.mean_rate_radps[k].to_degrees(),
                axes[k],
                ratio,
                gyro_sigma_radps[k].to_degrees(),
                fmt3(st.mean_rate_radps.map(f64::to_degrees), 4),
                (2.0 * st.mean_rate_radps[k].abs()).to_degrees()
            ));
        }
    }
    let mis = st.gravity_mismatch_mps2();
    let sig = accel_sigma_mps2.iter().fold(0.0f64, |m, v| m.max(*v));
    if mis.abs() > BIAS_SIGMA_FACTOR * sig && mis.abs() > GRAVITY_MODEL_TOLERANCE_MPS2 {
        out.push(format!(
            "accelerometer bias: |mean specific force| at rest over the first {:.1} s is \
             {:.4} m/s^2 against normal gravity {:.4} ({:+.4} m/s^2 = {:+.1} mg, {:.0} x the \
             configured initial bias sigma {:.4} m/s^2); raise [noise.accel] bias_init_sigma \
             to about {:.3}",
            st.duration_s,
            norm(st.mean_f_mps2),
            st.gravity_mps2,
            mis,
            mis / 9.806_65 * 1e3,
            mis.abs() / sig.max(1e-12),
            sig,
            2.0 * mis.abs()
        ));
    }
    out
}

fn fmt3(v: [f64; 3], prec: usize) -> String {
    format!("[{:+.p$}, {:+.p$}, {:+.p$}]", v[0], v[1], v[2], p = prec)
}

/// The start-up check of a run configuration: reads the first [`REST_PREFIX_S`] of its GNSS
/// and IMU files (memory bounded by that span's fixes and the IMU blocks), finds the rest at
/// the start and returns [`bias_warnings`] against the configured `[noise]` initial bias
/// sigmas. Nothing when the start is not at rest, and nothing on a read error (the run
/// itself reports those).
pub fn check_config_biases(cfg: &RunConfig, config_dir: &Path) -> Vec<String> {
    let (Ok(gyro), Ok(accel)) = (
        cfg.noise.gyro.to_sensor_noise(),
        cfg.noise.accel.to_sensor_noise(),
    ) else {
        return Vec::new();
    };
    let Ok(imu) = cfg.open_imu(config_dir) else {
        return Vec::new();
    };
    let mut imu = imu.map_while(Result::ok).map(|(s, _)| s).peekable();
    let Some(t0) = imu.peek().map(|s| s.t_s) else {
        return Vec::new();
    };
    let fixes: Vec<GnssFix> = match cfg.open_gnss(config_dir) {
        Ok(rd) => rd
            .map_while(Result::ok)
            .take_while(|g| g.t_s <= t0 + REST_PREFIX_S)
            .collect(),
        Err(_) => Vec::new(),
    };
    let g = fixes
        .iter()
        .find(|f| f.is_valid())
        .map_or(9.806_65, |f| gravity_mps2(f.lat_rad, f.h_m));
    match rest_stats(imu, gnss_motion_start(&fixes), g) {
        Some(st) => bias_warnings(&st, gyro.bias_init_sigma, accel.bias_init_sigma),
        None => Vec::new(),
    }
}
