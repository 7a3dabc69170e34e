//! The smoothed solution of a run: corrected navigation records, smoothed standard
//! deviations, GNSS errors recomputed against the smoothed trajectory.

use super::{smooth, History, SmoothError, Smoothed, SmoothedPoint};
use crate::run::{position_innovation, CaseData, EpochRecord, FixUse, InnovationRecord, RunOutput};
use nalgebra::{Matrix3, Vector3};
use nav_core::attitude;
use nav_core::earth::{self, Llh};
use nav_core::model::{CORE_DIM, IDX_ATT, IDX_POS, IDX_VEL};
use nav_core::strapdown::NavState;
use nav_core::types::{GnssFix, NavSolution};
use serde::Serialize;

/// Sizes and times of the smoother.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SmootherReport {
    /// Error-state dimension.
    pub states: usize,
    /// Nodes (covariance-prediction epochs) stored.
    pub nodes: usize,
    /// Nodes with an update (posterior and/or correction stored).
    pub update_nodes: usize,
    /// Size of the forward history (its temporary file), bytes.
    pub history_bytes: u64,
    /// History bytes per node.
    pub history_bytes_per_node: f64,
    /// Size of the smoothed node data (their temporary file), bytes.
    pub smoothed_bytes: u64,
    /// Time of the backward pass, s.
    pub backward_s: f64,
    /// Time to apply it to the records (in a streamed run: the second pass over the data
    /// that writes the smoothed outputs), s.
    pub apply_s: f64,
    /// Backward steps that needed the pseudo-inverse of the prior covariance.
    pub pinv_fallbacks: usize,
}

/// The nav record of the stored forward nominal corrected by the smoothed error, as the
/// filter's feedback does (`C <- (I + [phi x]) C`, `v <- v - dv`, `r <- r - dr`), with the
/// smoothed standard deviations.
pub fn correct(nav: &NavSolution, p: &SmoothedPoint) -> NavSolution {
    let g = |i: usize| p.dx.get(i).copied().unwrap_or(0.0);
    let v3 = |o: usize| Vector3::new(g(o), g(o + 1), g(o + 2));
    let q = attitude::quat_from_euler_zyx(nav.rpy_rad);
    let q_s = attitude::quat_from_rotvec(&v3(IDX_ATT)) * q;
    let pos = earth::displace(
        &Llh {
            lat_rad: nav.lat_rad,
            lon_rad: nav.lon_rad,
            h_m: nav.h_m,
        },
        &(-v3(IDX_POS)),
    );
    let dv = v3(IDX_VEL);
    let sd = |i: usize| p.var.get(i).copied().unwrap_or(0.0).max(0.0).sqrt();
    let rpy = attitude::euler_zyx_from_quat(&q_s);
    NavSolution {
        lat_rad: pos.lat_rad,
        lon_rad: pos.lon_rad,
        h_m: pos.h_m,
        vel_ned_mps: [0, 1, 2].map(|i| nav.vel_ned_mps[i] - dv[i]),
        rpy_rad: rpy,
        pos_std_ned_m: [0, 1, 2].map(|i| sd(IDX_POS + i)),
        vel_std_ned_mps: [0, 1, 2].map(|i| sd(IDX_VEL + i)),
        att_std_rad: euler_std(&rpy, &p.cov_core),
        ..*nav
    }
}

/// Roll/pitch/yaw 1-sigma from the phi covariance (as `nav_core::filter`'s solution does).
fn euler_std(rpy: &[f64; 3], cov: &[f64; 81]) -> [f64; 3] {
    let [_, th, ps] = *rpy;
    let a = Matrix3::new(
        ps.cos() * th.cos(),
        -ps.sin(),
        0.0,
        ps.sin() * th.cos(),
        ps.cos(),
        0.0,
        -th.sin(),
        0.0,
        1.0,
    );
    let Some(ai) = a.try_inverse() else {
        return [f64::NAN; 3];
    };
    let s = Matrix3::from_fn(|i, j| cov[(IDX_ATT + i) * 9 + IDX_ATT + j]);
    let e = ai * s * ai.transpose();
    [
        e.m11.max(0.0).sqrt(),
        e.m22.max(0.0).sqrt(),
        e.m33.max(0.0).sqrt(),
    ]
}

/// The record of `nav` nearest to `t_s` (records in time order).
pub(crate) fn nearest(nav: &[NavSolution], t_s: f64) -> Option<&NavSolution> {
    let i = nav.partition_point(|s| s.t_s < t_s);
    let after = nav.get(i);
    let before = i.checked_sub(1).and_then(|j| nav.get(j));
    match (before, after) {
        (Some(b), Some(a)) => Some(if t_s - b.t_s <= a.t_s - t_s { b } else { a }),
        (b, a) => b.or(a),
    }
}

/// Fix outcomes whose innovation is recomputed against the smoothed trajectory.
pub(crate) fn recomputed(u: FixUse) -> bool {
    matches!(
        u,
        FixUse::Accepted | FixUse::Forced | FixUse::Withheld | FixUse::Rejected
    )
}

/// The antenna lever arm (m, body) and GNSS time offset (s) of the forward run's final
/// estimates, for the innovations against the smoothed trajectory.
pub(crate) fn antenna(fwd: &RunOutput) -> ([f64; 3], f64) {
    let effect = |name: &str| {
        fwd.final_effects
            .iter()
            .find(|e| e.name == name)
            .map(|e| e.value.clone())
    };
    let mut lever = fwd.lever_arm_m;
    if let Some(v) = effect("lever_arm") {
        for (l, d) in lever.iter_mut().zip(v) {
            *l += d;
        }
    }
    let dt_off = effect("time_offset")
        .and_then(|v| v.first().copied())
        .unwrap_or(0.0);
    (lever, dt_off)
}

/// The innovation of `fix` recomputed against the smoothed record `s` (the innovation
/// variances and NIS become NaN).
pub(crate) fn reinnovate(
    r: &mut InnovationRecord,
    fix: &GnssFix,
    s: &NavSolution,
    lever: &[f64; 3],
    dt_off: f64,
) {
    let shifted = GnssFix {
        t_s: fix.t_s + dt_off,
        ..*fix
    };
    let inn = position_innovation(&NavState::from_solution(s), lever, &shifted);
    r.innovation[..3].copy_from_slice(&inn);
    r.innovation_var = [f64::NAN; 6];
    r.nis = f64::NAN;
}

/// An epoch record with the smoothed solution `p`: nav corrected, standard deviations and
/// sensor-error estimates smoothed (the `blocks` stay the forward ones).
pub(crate) fn smooth_epoch(e: &mut EpochRecord, p: &SmoothedPoint) {
    e.nav = correct(&e.nav, p);
    for (sd, v) in e.state_std.iter_mut().zip(&p.var) {
        *sd = v.max(0.0).sqrt();
    }
    for (i, (est, d)) in e.estimates.iter_mut().zip(&p.dx).enumerate() {
        if i >= CORE_DIM {
            *est -= d;
        }
    }
}

/// The run's outputs with the smoothed solution: nav records corrected, `epochs`' standard
/// deviations and sensor-error estimates smoothed (their `blocks`, i.e. `bias.txt`, stay
/// the forward ones), and the position innovation of every GNSS fix (used and withheld)
/// recomputed against the smoothed trajectory (the antenna from the smoothed nav record
/// nearest the fix, with the forward run's final lever-arm and time-offset estimates).
/// For a run held in memory; `host-sim run --smooth` streams ([`super::run`]).
pub fn smoothed_output(
    case: &CaseData,
    fwd: &RunOutput,
    sm: &Smoothed,
) -> Result<RunOutput, SmoothError> {
    let mut out = fwd.clone();
    out.history = None;
    let mut cur = sm.cursor();
    for s in &mut out.nav {
        if let Some(p) = cur.at(s.t_s)? {
            *s = correct(s, &p);
        }
    }
    let mut cur = sm.cursor();
    for e in &mut out.epochs {
        if let Some(p) = cur.at(e.t_s)? {
            smooth_epoch(e, &p);
        }
    }
    let (lever, dt_off) = antenna(fwd);
    for r in &mut out.innovations {
        if !recomputed(r.used) {
            continue;
        }
        let i = case.gnss.partition_point(|g| g.t_s < r.t_s);
        let Some(fix) = case.gnss.get(i).filter(|g| g.t_s == r.t_s) else {
            continue;
        };
        let Some(s) = nearest(&out.nav, fix.t_s) else {
            continue;
        };
        reinnovate(r, fix, s, &lever, dt_off);
    }
    Ok(out)
}

/// Smooths a run held in memory that recorded its history
/// (`RunOptions::smoother_history`): the smoothed outputs and the smoother's memory and time.
pub fn smooth_run(
    case: &CaseData,
    fwd: &RunOutput,
) -> Result<(RunOutput, Smoothed, SmootherReport), SmoothError> {
    let h = fwd.history.as_ref().ok_or(SmoothError::Empty)?;
    let t = std::time::Instant::now();
    let sm = smooth(h)?;
    let backward_s = t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let out = smoothed_output(case, fwd, &sm)?;
    let apply_s = t.elapsed().as_secs_f64();
    let rep = SmootherReport::new(h, &sm, backward_s, apply_s);
    Ok((out, sm, rep))
}

impl SmootherReport {
    /// The report of a backward pass `sm` over `h` and its times.
    pub fn new(h: &History, sm: &Smoothed, backward_s: f64, apply_s: f64) -> Self {
        let hb = h.file_bytes();
        Self {
            states: h.n,
            nodes: h.len(),
            update_nodes: h.update_nodes(),
            history_bytes: hb,
            history_bytes_per_node: hb as f64 / h.len().max(1) as f64,
            smoothed_bytes: sm.file_bytes(),
            backward_s,
            apply_s,
            pinv_fallbacks: sm.pinv_fallbacks,
        }
    }
}
