//! Robust gating state: IGG-III weights, the windowed NIS monitor that tells a persistent
//! model mismatch from isolated outliers, and what is needed to re-initialise the filter from
//! the fixes after consecutive rejections (see `docs/robust-gating.md`).
//!
//! The monitor keeps the NIS normalised by the measurement dimension (NIS/dof, 1 = consistent
//! on average) of the last [`RobustGating::window`] fixes, accepted or not. While the window
//! median exceeds [`RobustGating::mismatch_ratio_on`] a model mismatch is declared: per fix the
//! process noise Q and the rejection threshold are multiplied by
//! [`RobustGating::inflation_step`] (capped); while the median is below
//! [`RobustGating::mismatch_ratio_off`] both are divided by it again down to 1. A single
//! outlier moves the median by one rank and cannot trigger it.

use super::sigma_scale::{median_of, ScaleInput, SigmaScale};
use super::{HEADING_RESET_SIDESLIP_VAR_RAD2, RESET_MAX_FIX_INTERVAL_S};
use crate::config::{Gating, RobustGating, MAX_NIS_WINDOW};
use crate::model::{IDX_ATT, IDX_POS, IDX_VEL};
use nalgebra::UnitQuaternion;

/// IGG-III weight of a fix with normalised innovation squared `nis` between the
/// down-weighting threshold `k0_sq` and the rejection threshold `k1_sq` (both NIS values):
/// with `s = sqrt(nis)`, `w = 1` for `s <= k0`, `w = (k0 / s) ((k1 - s) / (k1 - k0))^2` for
/// `k0 < s <= k1`, and 0 beyond (rejection). R is divided by the weight.
pub fn igg3_weight(nis: f64, k0_sq: f64, k1_sq: f64) -> f64 {
    if nis.is_nan() || nis <= k0_sq {
        return 1.0;
    }
    if k1_sq.is_nan() || nis > k1_sq || k1_sq <= k0_sq {
        return 0.0;
    }
    let s = libm::sqrt(nis);
    let k0 = libm::sqrt(k0_sq);
    let k1 = libm::sqrt(k1_sq);
    let r = (k1 - s) / (k1 - k0);
    (k0 / s) * r * r
}

/// Smallest weight used for an update (a smaller one rejects): R is inflated at most 1e4
/// times, which keeps S well conditioned in f32.
pub const MIN_WEIGHT: f64 = 1e-4;

/// Bound of the gate widening while a persistent mismatch is followed (keeps the widened
/// thresholds finite).
pub const UNCAPPED_WIDENING: f64 = 1e9;

/// Per-fix factor by which the remembered level of a persistent mismatch eases off.
const LEVEL_EASING: f64 = 0.99;

/// What the robust gating and the monitor did over the run, and their current state. Times
/// are GNSS fix times, s; ratios are NIS/dof.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RobustStats {
    /// Fixes used with an inflated R (IGG-III weight below 1).
    pub downweighted: u32,
    /// Re-initialisations from the fixes after consecutive rejections.
    pub resets: u32,
    /// Of which also re-initialised the heading from the GNSS course.
    pub heading_resets: u32,
    /// Times a model mismatch was declared (episodes).
    pub mismatch_episodes: u32,
    /// Fixes processed while a mismatch was declared.
    pub mismatch_fixes: u32,
    /// Total time with a mismatch declared, s.
    pub mismatch_time_s: f64,
    /// Longest single mismatch episode, s.
    pub longest_mismatch_s: f64,
    /// Fix time when the first mismatch was declared, s (NaN: never).
    pub first_mismatch_t_s: f64,
    /// Largest window median of NIS/dof seen (NaN before the window has 3 entries).
    pub max_median_ratio: f64,
    /// Largest process-noise inflation factor applied.
    pub max_q_inflation: f64,
    /// Largest gate widening factor applied.
    pub max_gate_widening: f64,
    /// Current window median of NIS/dof (NaN before the window has 3 entries).
    pub median_ratio: f64,
    /// Current process-noise inflation factor (1 = none).
    pub q_inflation: f64,
    /// Current gate widening factor (1 = none).
    pub gate_widening: f64,
    /// Whether a mismatch is declared now.
    pub mismatch: bool,
    /// First fixes after an outage that were used on probation and taken back because the
    /// next fix disagreed with them (outliers; see `Filter::update_gnss`).
    pub reacquisitions_undone: u32,
    /// Current R multiplier of the learned GNSS sigma scale (variance ratio; 1 = none).
    pub sigma_scale: f64,
    /// Largest R multiplier applied.
    pub max_sigma_scale: f64,
    /// Mean R multiplier over the fixes processed with one (1 when none was).
    pub mean_sigma_scale: f64,
    /// Fixes processed with R multiplied by the learned scale.
    pub sigma_scaled_fixes: u32,
    /// Fix time when R was first multiplied, s (NaN: never).
    pub first_sigma_scale_t_s: f64,
}

impl Default for RobustStats {
    fn default() -> Self {
        Self {
            downweighted: 0,
            resets: 0,
            heading_resets: 0,
            mismatch_episodes: 0,
            mismatch_fixes: 0,
            mismatch_time_s: 0.0,
            longest_mismatch_s: 0.0,
            first_mismatch_t_s: f64::NAN,
            max_median_ratio: f64::NAN,
            max_q_inflation: 1.0,
            max_gate_widening: 1.0,
            median_ratio: f64::NAN,
            q_inflation: 1.0,
            gate_widening: 1.0,
            mismatch: false,
            reacquisitions_undone: 0,
            sigma_scale: 1.0,
            max_sigma_scale: 1.0,
            mean_sigma_scale: 1.0,
            sigma_scaled_fixes: 0,
            first_sigma_scale_t_s: f64::NAN,
        }
    }
}

/// A rejected fix remembered for the velocity of a re-initialisation: its time and its
/// position innovation (predicted minus measured antenna position, NED m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct RejectedFix {
    pub t_s: f64,
    pub z_pos_m: [f64; 3],
    pub var_pos_m2: [f64; 3],
}

/// Runtime state of the gate and the monitor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct GateState {
    window: [f64; MAX_NIS_WINDOW],
    len: usize,
    next: usize,
    /// The last rejected fix of the current run of rejections.
    pub last_rejected: Option<RejectedFix>,
    /// Whether the last fix's NIS was within the gate without the re-acquisition widening.
    pub last_within_normal_gate: bool,
    /// The one rejected before it.
    pub earlier_rejected: Option<RejectedFix>,
    rejection_run: u32,
    last_fix_t_s: f64,
    last_seen_t_s: f64,
    last_used_t_s: f64,
    nominal_interval_s: f64,
    episode_start_t_s: f64,
    /// Remembered NIS/dof level of a persistent mismatch (floor of the widening, >= 1).
    level: f64,
    /// Fixes fed to the monitor since the start or the last re-initialisation.
    warm: u32,
    /// The learned GNSS sigma scale.
    pub scale: SigmaScale,
    pub stats: RobustStats,
}

impl Default for GateState {
    fn default() -> Self {
        Self {
            window: [0.0; MAX_NIS_WINDOW],
            len: 0,
            next: 0,
            last_rejected: None,
            last_within_normal_gate: false,
            earlier_rejected: None,
            rejection_run: 0,
            last_fix_t_s: f64::NAN,
            last_seen_t_s: f64::NAN,
            last_used_t_s: f64::NAN,
            nominal_interval_s: f64::NAN,
            episode_start_t_s: f64::NAN,
            level: 1.0,
            warm: 0,
            scale: SigmaScale::default(),
            stats: RobustStats::default(),
        }
    }
}

/// What a re-initialisation from the fixes needs to know (see [`GateState::reset_plan`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ResetInput {
    /// Fix time, s.
    pub t_s: f64,
    /// Position innovation of this fix (predicted minus measured antenna), NED m.
    pub z_pos_m: [f64; 3],
    /// Its variances, m^2.
    pub var_pos_m2: [f64; 3],
    /// Velocity innovation and variances (m/s, m^2/s^2) when the fix's velocity is used.
    pub vel: Option<([f64; 3], [f64; 3])>,
    /// The filter's velocity, NED m/s.
    pub vel_ned_mps: [f64; 3],
    /// The filter's attitude.
    pub q_nb: UnitQuaternion<f64>,
    /// The filter's heading variance, rad^2.
    pub var_yaw_rad2: f64,
    /// Heading reset only at this horizontal speed or more, m/s.
    pub heading_min_speed_mps: f64,
}

/// The states a reset sets: error-state indices (`usize::MAX` = unused), the error to feed
/// back (estimate minus truth) and the new variance of each.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ResetPlan {
    pub idx: [usize; 7],
    pub dx: [f64; 7],
    pub var: [f64; 7],
}

/// The thresholds that apply to one fix (NIS values).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Thresholds {
    /// Above: down-weighted (robust) — equals `reject` for the hard gate.
    pub downweight: f64,
    /// Above: rejected.
    pub reject: f64,
    /// The rejection threshold without the re-acquisition widening.
    pub normal_reject: f64,
    /// The fix is the first after an outage (no fix at all for longer than the
    /// re-acquisition gap) and gets the re-acquisition widening.
    pub after_outage: bool,
}

impl GateState {
    /// The thresholds for a measurement of dimension `dim` (3 or 6).
    /// With robust gating the rejection threshold is widened by the monitor's factor, and by
    /// [`RobustGating::max_gate_widening`] for a fix that ends a gap (see
    /// [`Self::is_reacquisition`]). `t_s` is the fix time.
    pub fn thresholds(&self, g: &Gating, dim: usize, t_s: f64) -> Thresholds {
        let base = if dim == 3 {
            g.nis_threshold_pos
        } else {
            g.nis_threshold_pos_vel
        };
        match &g.robust {
            None => Thresholds {
                downweight: base,
                reject: base,
                normal_reject: base,
                after_outage: false,
            },
            Some(r) => {
                let dw = if dim == 3 {
                    r.downweight_nis_pos
                } else {
                    r.downweight_nis_pos_vel
                };
                let gap = self.is_reacquisition(r, t_s);
                let after_outage = gap && t_s - self.last_seen_t_s > r.reacquisition_min_gap_s;
                let reacq = gap || self.warm < r.warmup_fixes;
                let widening = if reacq {
                    // after an outage (no fix at all, not a run of rejections) times the
                    // remembered level of a persistent mismatch: unaided, what the model
                    // leaves out grows beyond the level seen at the fix rate
                    let lvl = if after_outage { self.level } else { 1.0 };
                    (r.max_gate_widening * lvl).max(self.stats.gate_widening)
                } else {
                    self.stats.gate_widening
                };
                let reject = base * widening;
                Thresholds {
                    downweight: (dw * widening).min(reject),
                    reject,
                    normal_reject: base * self.stats.gate_widening,
                    after_outage,
                }
            }
        }
    }

    /// Whether a fix at `t_s` ends a gap: no fix used for longer than
    /// [`RobustGating::reacquisition_gap_intervals`] nominal fix intervals (and at least
    /// [`RobustGating::reacquisition_min_gap_s`]). After a gap the unaided error has grown
    /// with whatever the model leaves out, so the predicted innovation covariance is least
    /// trustworthy exactly there (an outage, or a run of rejections).
    pub fn is_reacquisition(&self, r: &RobustGating, t_s: f64) -> bool {
        let gap = t_s - self.last_used_t_s;
        let nominal = if self.nominal_interval_s.is_finite() {
            self.nominal_interval_s
        } else {
            0.0
        };
        gap.is_finite()
            && gap > r.reacquisition_min_gap_s
            && gap > r.reacquisition_gap_intervals * nominal
    }

    /// Notes a fix (robust gating only): its time, for the nominal fix interval, and whether it
    /// ended a gap (used within the gate without the re-acquisition widening, or a reset).
    pub fn note_fix(&mut self, t_s: f64, used: bool) {
        let dt = t_s - self.last_seen_t_s;
        if dt.is_finite() && dt > 0.0 {
            if !self.nominal_interval_s.is_finite() {
                self.nominal_interval_s = dt;
            } else if dt < 2.0 * self.nominal_interval_s {
                self.nominal_interval_s = 0.9 * self.nominal_interval_s + 0.1 * dt;
            } else {
                // a gap, or a slower fix rate: adapt slowly
                self.nominal_interval_s *= 1.1;
            }
        }
        if t_s.is_finite() {
            self.last_seen_t_s = t_s;
            if used {
                self.last_used_t_s = t_s;
            }
        }
    }

    /// The process-noise inflation factor to apply at the next prediction.
    pub fn q_inflation(&self) -> f64 {
        self.stats.q_inflation
    }

    /// Feeds one fix's NIS/dof into the monitor and updates the inflation (robust gating
    /// only). `t_s` is the fix time; `rejected` whether the gate rejected the fix. Two
    /// rejections in a row are not an isolated outlier: they inflate at once, without waiting
    /// for the median to cross [`RobustGating::mismatch_ratio_on`]. `accepted_widening` is the
    /// widening that the fix's own NIS times [`RobustGating::growth_per_fix`] asks for when it
    /// was used (0 otherwise): innovations that grow steadily from fix to fix (a mismatch
    /// building up in a manoeuvre) stay inside the gate.
    pub fn monitor(
        &mut self,
        r: &RobustGating,
        t_s: f64,
        nis_ratio: f64,
        rejected: bool,
        accepted_widening: f64,
    ) {
        let dt = t_s - self.last_fix_t_s;
        self.last_fix_t_s = t_s;
        self.warm = self.warm.saturating_add(1);
        if self.stats.mismatch && dt.is_finite() && dt > 0.0 {
            self.stats.mismatch_time_s += dt;
            self.stats.mismatch_fixes = self.stats.mismatch_fixes.saturating_add(1);
        }
        let w = r.window.clamp(1, MAX_NIS_WINDOW);
        if let Some(slot) = self.window.get_mut(self.next) {
            *slot = if nis_ratio.is_finite() {
                nis_ratio
            } else {
                f64::MAX
            };
        }
        self.next = if self.next + 1 >= w { 0 } else { self.next + 1 };
        self.len = (self.len + 1).min(w);
        let run = if rejected {
            self.rejection_run = self.rejection_run.saturating_add(1);
            self.rejection_run
        } else {
            self.rejection_run = 0;
            0
        };
        // a median needs a few values: below 3 one outlier would be half the window
        let med = if self.len < 3.min(w) {
            f64::NAN
        } else {
            self.median()
        };
        let s = &mut self.stats;
        s.median_ratio = med;
        if s.max_median_ratio.is_nan() || med > s.max_median_ratio {
            s.max_median_ratio = med;
        }
        if med > r.mismatch_ratio_on || run >= 2 {
            if !s.mismatch {
                s.mismatch = true;
                s.mismatch_episodes = s.mismatch_episodes.saturating_add(1);
                self.episode_start_t_s = t_s;
                if s.first_mismatch_t_s.is_nan() {
                    s.first_mismatch_t_s = t_s;
                }
            }
            s.q_inflation = (s.q_inflation * r.inflation_step).min(r.max_q_inflation);
        } else if med < r.mismatch_ratio_off {
            s.mismatch = false;
            s.q_inflation = (s.q_inflation / r.easing_step).max(1.0);
        }
        // the gate follows the innovations actually seen (covariance matching): widened by
        // the window median of NIS/dof, faster on a run of rejections, easing off slowly
        let mut g = s.gate_widening / r.easing_step;
        if med.is_finite() {
            g = g.max(if s.mismatch {
                med * r.mismatch_median_factor
            } else {
                med
            });
        }
        if run >= 2 {
            g = g.max(s.gate_widening * r.inflation_step);
        }
        if accepted_widening.is_finite() {
            g = g.max(accepted_widening);
        }
        // A declared mismatch whose last fix was used is persistent, not an outlier: the gate
        // follows the innovations without the cap (a 1.5 m lever arm in a turn against 2 cm
        // fixes is ~1e4 in NIS/dof). Otherwise (a run of rejections: a jump, or clean data)
        // the cap holds, and a widening already beyond it is kept, not grown.
        // The level of such a mismatch is remembered (easing off by 1 % per fix) as a floor
        // of the widening: its signature comes back (each turn for a lever arm) and must not
        // be rejected at its onset. Only fixes used by an update teach it, not rejected ones
        // (a jump of all fixes) nor a reset.
        let used = accepted_widening > 0.0;
        let cap = if s.mismatch && used {
            if med.is_finite() && med > self.level {
                self.level = med.min(UNCAPPED_WIDENING);
            }
            UNCAPPED_WIDENING
        } else {
            r.max_gate_widening.max(s.gate_widening)
        };
        self.level = (self.level * LEVEL_EASING).max(1.0);
        // (not f64::clamp: its NaN/order assertion would link float formatting on the MCU)
        s.gate_widening = g.min(cap).max(self.level);
        if s.mismatch {
            let d = t_s - self.episode_start_t_s;
            if d > s.longest_mismatch_s {
                s.longest_mismatch_s = d;
            }
        }
        s.max_q_inflation = s.max_q_inflation.max(s.q_inflation);
        s.max_gate_widening = s.max_gate_widening.max(s.gate_widening);
    }

    /// What a re-initialisation from the fixes sets (and counts it; empties the window):
    /// the position from this fix; the velocity from the fix's velocity when used, else from
    /// the rate of the position error through this fix's and the two previous rejected fixes'
    /// innovations (a quadratic: v = sum z_i L_i'(t3) of the Lagrange basis, variance
    /// sum r_i L_i'(t3)^2, the error's third derivative neglected; with one previous fix the
    /// mean over the interval, with a variance that allows for the change of the error over
    /// it); the heading from the GNSS course when the horizontal speed is at least
    /// `heading_min_speed_mps`, the course is within 90 deg of the heading and differs from it
    /// by more than 3 sigma (forward motion without sideslip).
    pub fn reset_plan(&mut self, inp: &ResetInput) -> ResetPlan {
        let t_s = inp.t_s;
        let zp = &inp.z_pos_m;
        let rp = &inp.var_pos_m2;
        let mut plan = ResetPlan {
            idx: [usize::MAX; 7],
            dx: [0.0; 7],
            var: [0.0; 7],
        };
        let mut put = |slot: usize, idx: usize, dx: f64, var: f64| {
            if let Some(x) = plan.idx.get_mut(slot) {
                *x = idx;
            }
            if let Some(x) = plan.dx.get_mut(slot) {
                *x = dx;
            }
            if let Some(x) = plan.var.get_mut(slot) {
                *x = var.max(0.0);
            }
        };
        for (i, (z, r)) in zp.iter().zip(rp.iter()).enumerate() {
            put(i, IDX_POS + i, *z, *r);
        }
        let recent =
            |p: &RejectedFix, t: f64| (t - p.t_s) > 0.0 && (t - p.t_s) <= RESET_MAX_FIX_INTERVAL_S;
        let prev = self.last_rejected.filter(|p| recent(p, t_s));
        let earlier = match prev {
            Some(p) => self.earlier_rejected.filter(|e| recent(e, p.t_s)),
            None => None,
        };
        let vel_reset = match (inp.vel, prev, earlier) {
            (Some((z, r)), _, _) => Some((z, r)),
            (None, Some(p2), Some(p1)) => {
                let (t1, t2, t3) = (p1.t_s, p2.t_s, t_s);
                let l1 = (t3 - t2) / ((t1 - t2) * (t1 - t3));
                let l2 = (t3 - t1) / ((t2 - t1) * (t2 - t3));
                let l3 = 1.0 / (t3 - t1) + 1.0 / (t3 - t2);
                let mut dv = [0.0; 3];
                let mut var = [0.0; 3];
                for (i, (d, v)) in dv.iter_mut().zip(var.iter_mut()).enumerate() {
                    let z = |a: &[f64; 3]| a.get(i).copied().unwrap_or(0.0);
                    *d = l1 * z(&p1.z_pos_m) + l2 * z(&p2.z_pos_m) + l3 * z(zp);
                    *v =
                        l1 * l1 * z(&p1.var_pos_m2) + l2 * l2 * z(&p2.var_pos_m2) + l3 * l3 * z(rp);
                }
                Some((dv, var))
            }
            (None, Some(p), None) => {
                let dt = t_s - p.t_s;
                let mut dv = [0.0; 3];
                let mut var = [0.0; 3];
                for (i, (d, v)) in dv.iter_mut().zip(var.iter_mut()).enumerate() {
                    let z = |a: &[f64; 3]| a.get(i).copied().unwrap_or(0.0);
                    *d = (z(zp) - z(&p.z_pos_m)) / dt;
                    // the fixes' noise, and the velocity error's change over the interval
                    // (unknown; bounded by half the mean error when it grew from zero)
                    *v = (z(rp) + z(&p.var_pos_m2)) / (dt * dt) + 0.25 * *d * *d;
                }
                Some((dv, var))
            }
            (None, None, _) => None,
        };
        if let Some((dv, var_v)) = vel_reset {
            for (i, (d, v)) in dv.iter().zip(var_v.iter()).enumerate() {
                put(3 + i, IDX_VEL + i, *d, *v);
            }
            let [dvn, dve, _] = dv;
            let [v_n, v_e, _] = inp.vel_ned_mps;
            let (vn, ve) = (v_n - dvn, v_e - dve);
            let speed2 = vn * vn + ve * ve;
            let min_speed = inp.heading_min_speed_mps;
            if speed2 >= min_speed * min_speed && speed2 > 0.0 {
                let course = libm::atan2(ve, vn);
                // yaw of the ZYX Euler angles: atan2(C_21, C_11)
                let q = inp.q_nb.quaternion();
                let yaw = libm::atan2(
                    2.0 * (q.w * q.k + q.i * q.j),
                    1.0 - 2.0 * (q.j * q.j + q.k * q.k),
                );
                let mut dpsi = course - yaw;
                if dpsi > core::f64::consts::PI {
                    dpsi -= 2.0 * core::f64::consts::PI;
                } else if dpsi < -core::f64::consts::PI {
                    dpsi += 2.0 * core::f64::consts::PI;
                }
                let [vv0, vv1, _] = var_v;
                let var_course = vv0.max(vv1) / speed2;
                let var_new = var_course + HEADING_RESET_SIDESLIP_VAR_RAD2;
                if dpsi.abs() < core::f64::consts::FRAC_PI_2
                    && dpsi * dpsi > 9.0 * (inp.var_yaw_rad2 + var_new)
                {
                    put(6, IDX_ATT + 2, dpsi, var_new);
                    self.stats.heading_resets = self.stats.heading_resets.saturating_add(1);
                }
            }
        }
        self.stats.resets = self.stats.resets.saturating_add(1);
        self.warm = 0;
        self.clear_window();
        self.scale.clear();
        plan
    }

    /// Empties the NIS window (after a re-initialisation the old innovations say nothing about
    /// the new state); the inflation factors stay and ease off with the next fixes.
    pub fn clear_window(&mut self) {
        self.len = 0;
        self.next = 0;
        self.last_rejected = None;
        self.earlier_rejected = None;
    }

    /// Median of the window.
    fn median(&self) -> f64 {
        median_of(&self.window, self.len)
    }

    /// The R multiplier of the learned GNSS sigma scale for the next fix (1 = none).
    pub fn sigma_scale(&self) -> f64 {
        self.scale.factor()
    }

    /// Feeds one GNSS fix (accepted or not) into the sigma-scale estimator; `t_s` the fix
    /// time, `factor` the R multiplier the fix was processed with.
    pub fn learn_scale(&mut self, r: &RobustGating, t_s: f64, factor: f64, inp: &ScaleInput<'_>) {
        let s = &mut self.stats;
        if factor > 1.0 {
            let n = f64::from(s.sigma_scaled_fixes);
            s.mean_sigma_scale = if s.sigma_scaled_fixes == 0 {
                factor
            } else {
                (s.mean_sigma_scale * n + factor) / (n + 1.0)
            };
            s.sigma_scaled_fixes = s.sigma_scaled_fixes.saturating_add(1);
            s.max_sigma_scale = s.max_sigma_scale.max(factor);
            if s.first_sigma_scale_t_s.is_nan() {
                s.first_sigma_scale_t_s = t_s;
            }
        }
        self.scale.learn(r, inp);
        self.stats.sigma_scale = self.scale.factor();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::chi2;

    #[test]
    fn igg3_weight_is_one_below_k0_zero_beyond_k1_and_decreasing_between() {
        let (k0, k1) = (chi2::DIM3_P99, chi2::DIM3_P9999);
        assert_eq!(igg3_weight(1.0, k0, k1), 1.0);
        assert_eq!(igg3_weight(k0, k0, k1), 1.0);
        assert_eq!(igg3_weight(k1 * 1.0001, k0, k1), 0.0);
        assert_eq!(igg3_weight(f64::NAN, k0, k1), 1.0);
        let mut last = 1.0;
        for i in 1..100 {
            let nis = k0 + (k1 - k0) * i as f64 / 100.0;
            let w = igg3_weight(nis, k0, k1);
            assert!(w < last && w > 0.0, "{nis} {w}");
            last = w;
        }
        // continuous at k0: w -> 1
        assert!((igg3_weight(k0 * 1.000_001, k0, k1) - 1.0).abs() < 1e-5);
    }

    #[test]
    fn monitor_ignores_one_outlier_and_declares_a_persistent_mismatch() {
        // the default (gate follows the innovations, no process-noise inflation) and the
        // optional Q inflation
        for max_q in [1.0, 100.0] {
            let r = RobustGating {
                max_q_inflation: max_q,
                ..RobustGating::default()
            };
            let mut g = GateState::default();
            for k in 0..30 {
                let ratio = if k == 15 { 1e6 } else { 1.0 };
                g.monitor(&r, k as f64, ratio, k == 15, 0.0);
                assert!(!g.stats.mismatch);
                assert_eq!(g.stats.gate_widening, 1.0);
            }
            assert_eq!(g.stats.q_inflation, 1.0);
            for k in 30..60 {
                g.monitor(&r, k as f64, 9.0, false, 0.0);
            }
            assert!(g.stats.mismatch);
            assert_eq!(g.stats.mismatch_episodes, 1);
            // declared when 5 of the 10 are 9: median (1 + 9) / 2 = 5 > 4
            assert_eq!(g.stats.first_mismatch_t_s, 34.0);
            assert_eq!(g.stats.q_inflation, max_q);
            // the gate follows twice the median of NIS/dof while the mismatch is declared
            assert_eq!(g.stats.gate_widening, 18.0);
            // a used fix asks for room to grow: 2 x its own NIS over the base gate
            g.monitor(&r, 60.0, 9.0, false, 30.0);
            assert_eq!(g.stats.gate_widening, 30.0);
            for k in 61..200 {
                g.monitor(&r, k as f64, 1.0, false, 0.0);
                // the level of the mismatch seen on a used fix (median 9) stays the floor of
                // the widening, easing off by 1 % per fix
                let floor = 9.0 * libm::pow(0.99, (k - 59) as f64);
                assert!(g.stats.gate_widening >= floor.max(1.0) * (1.0 - 1e-12));
            }
            // held until 6 of the 10 are consistent again (median 1 < 1.5) at t = 66
            assert!((g.stats.mismatch_time_s - 32.0).abs() < 1e-9);
            assert!((g.stats.longest_mismatch_s - 31.0).abs() < 1e-9);
            assert!(!g.stats.mismatch);
            assert_eq!(g.stats.q_inflation, 1.0);
            for k in 200..450 {
                g.monitor(&r, k as f64, 1.0, false, 0.0);
            }
            assert_eq!(g.stats.gate_widening, 1.0);
            assert_eq!(g.stats.max_q_inflation, max_q);
            assert_eq!(g.stats.max_gate_widening, 30.0);
            assert_eq!(g.stats.max_median_ratio, 9.0);
        }
    }

    #[test]
    fn the_first_fixes_after_the_start_and_after_a_reset_get_the_widest_gate() {
        let r = RobustGating::default();
        let gating = Gating::robust();
        let wide = gating.nis_threshold_pos * r.max_gate_widening;
        let mut g = GateState::default();
        for k in 0..30u32 {
            let t = f64::from(k);
            let th = g.thresholds(&gating, 3, t);
            let want = if k < r.warmup_fixes {
                wide
            } else {
                gating.nis_threshold_pos
            };
            assert_eq!(th.reject, want, "fix {k}");
            // the normal gate stays the reference of the re-acquisition bookkeeping
            assert_eq!(th.normal_reject, gating.nis_threshold_pos);
            assert!(!th.after_outage);
            g.note_fix(t, true);
            g.monitor(&r, t, 1.0, false, 0.0);
        }
        // a re-initialisation from the fixes starts the warm-up again
        let inp = ResetInput {
            t_s: 30.0,
            z_pos_m: [0.0; 3],
            var_pos_m2: [1e-4; 3],
            vel: None,
            vel_ned_mps: [0.0; 3],
            q_nb: UnitQuaternion::identity(),
            var_yaw_rad2: 1e-4,
            heading_min_speed_mps: 5.0,
        };
        g.reset_plan(&inp);
        g.note_fix(30.0, true);
        assert_eq!(g.thresholds(&gating, 3, 31.0).reject, wide);
        // none with `warmup_fixes` 0
        let gating0 = Gating {
            robust: Some(RobustGating {
                warmup_fixes: 0,
                ..r
            }),
            ..gating
        };
        let g0 = GateState::default();
        assert_eq!(
            g0.thresholds(&gating0, 3, 0.0).reject,
            gating.nis_threshold_pos
        );
    }

    #[test]
    fn a_fix_after_a_gap_gets_the_widest_gate() {
        let r = RobustGating::default();
        let gating = Gating::robust();
        let mut g = GateState::default();
        for k in 0..20 {
            g.note_fix(k as f64, true);
        }
        // past the warm-up
        g.warm = r.warmup_fixes;
        let normal = g.thresholds(&gating, 3, 20.0);
        assert_eq!(normal.reject, gating.nis_threshold_pos);
        assert_eq!(normal.downweight, r.downweight_nis_pos);
        // 2 s after the last used fix at 1 Hz: not yet a gap (needs > 2.5 intervals and > 2 s)
        assert!(!g.is_reacquisition(&r, 21.0));
        assert!(!g.is_reacquisition(&r, 21.5));
        assert!(g.is_reacquisition(&r, 79.0));
        let wide = g.thresholds(&gating, 3, 79.0);
        assert_eq!(wide.reject, gating.nis_threshold_pos * r.max_gate_widening);
        assert_eq!(wide.normal_reject, gating.nis_threshold_pos);
        // a fix beyond the normal gate does not end the gap
        g.note_fix(79.0, false);
        assert!(g.is_reacquisition(&r, 80.0));
        g.note_fix(80.0, true);
        assert!(!g.is_reacquisition(&r, 81.0));
    }
}
