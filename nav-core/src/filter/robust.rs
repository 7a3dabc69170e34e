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

use crate::config::{Gating, RobustGating, MAX_NIS_WINDOW};

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
    /// The one rejected before it.
    pub earlier_rejected: Option<RejectedFix>,
    rejection_run: u32,
    last_fix_t_s: f64,
    last_seen_t_s: f64,
    last_used_t_s: f64,
    nominal_interval_s: f64,
    episode_start_t_s: f64,
    pub stats: RobustStats,
}

impl Default for GateState {
    fn default() -> Self {
        Self {
            window: [0.0; MAX_NIS_WINDOW],
            len: 0,
            next: 0,
            last_rejected: None,
            earlier_rejected: None,
            rejection_run: 0,
            last_fix_t_s: f64::NAN,
            last_seen_t_s: f64::NAN,
            last_used_t_s: f64::NAN,
            nominal_interval_s: f64::NAN,
            episode_start_t_s: f64::NAN,
            stats: RobustStats::default(),
        }
    }
}

/// The thresholds that apply to one fix (NIS values).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Thresholds {
    /// Above: down-weighted (robust) — equals `reject` for the hard gate.
    pub downweight: f64,
    /// Above: rejected.
    pub reject: f64,
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
            },
            Some(r) => {
                let dw = if dim == 3 {
                    r.downweight_nis_pos
                } else {
                    r.downweight_nis_pos_vel
                };
                let widening = if self.is_reacquisition(r, t_s) {
                    r.max_gate_widening.max(self.stats.gate_widening)
                } else {
                    self.stats.gate_widening
                };
                let reject = base * widening;
                Thresholds {
                    downweight: dw.min(reject),
                    reject,
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
    /// was used (accepted or reset), for the gap.
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
    /// for the median to cross [`RobustGating::mismatch_ratio_on`].
    pub fn monitor(&mut self, r: &RobustGating, t_s: f64, nis_ratio: f64, rejected: bool) {
        let dt = t_s - self.last_fix_t_s;
        self.last_fix_t_s = t_s;
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
        self.next = (self.next + 1) % w;
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
            s.gate_widening = (s.gate_widening * r.inflation_step).min(r.max_gate_widening);
        } else if med < r.mismatch_ratio_off {
            s.mismatch = false;
            s.q_inflation = (s.q_inflation / r.easing_step).max(1.0);
            s.gate_widening = (s.gate_widening / r.easing_step).max(1.0);
        }
        if s.mismatch {
            let d = t_s - self.episode_start_t_s;
            if d > s.longest_mismatch_s {
                s.longest_mismatch_s = d;
            }
        }
        s.max_q_inflation = s.max_q_inflation.max(s.q_inflation);
        s.max_gate_widening = s.max_gate_widening.max(s.gate_widening);
    }

    /// Empties the NIS window (after a re-initialisation the old innovations say nothing about
    /// the new state); the inflation factors stay and ease off with the next fixes.
    pub fn clear_window(&mut self) {
        self.len = 0;
        self.next = 0;
        self.last_rejected = None;
        self.earlier_rejected = None;
    }

    /// Median of the window (insertion sort of at most [`MAX_NIS_WINDOW`] values).
    fn median(&self) -> f64 {
        let mut a = [0.0f64; MAX_NIS_WINDOW];
        let n = self.len.min(MAX_NIS_WINDOW);
        for (i, v) in self.window.iter().take(n).enumerate() {
            let mut j = i;
            while j > 0 && a.get(j - 1).is_some_and(|p| *p > *v) {
                if let Some(p) = a.get(j - 1).copied() {
                    if let Some(x) = a.get_mut(j) {
                        *x = p;
                    }
                }
                j -= 1;
            }
            if let Some(x) = a.get_mut(j) {
                *x = *v;
            }
        }
        let mid = n / 2;
        let hi = a.get(mid).copied().unwrap_or(f64::NAN);
        if n % 2 == 1 {
            hi
        } else {
            0.5 * (a.get(mid.wrapping_sub(1)).copied().unwrap_or(hi) + hi)
        }
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
        let r = RobustGating::default();
        let mut g = GateState::default();
        for k in 0..30 {
            let ratio = if k == 15 { 1e6 } else { 1.0 };
            g.monitor(&r, k as f64, ratio, k == 15);
            assert!(!g.stats.mismatch);
        }
        assert_eq!(g.stats.q_inflation, 1.0);
        for k in 30..60 {
            g.monitor(&r, k as f64, 9.0, false);
        }
        assert!(g.stats.mismatch);
        assert_eq!(g.stats.mismatch_episodes, 1);
        // declared when 5 of the 10 are 9: median (1 + 9) / 2 = 5 > 4
        assert_eq!(g.stats.first_mismatch_t_s, 34.0);
        assert_eq!(g.stats.q_inflation, 100.0);
        assert_eq!(g.stats.gate_widening, 100.0);
        for k in 60..200 {
            g.monitor(&r, k as f64, 1.0, false);
        }
        // held until 6 of the 10 are consistent again (median 1 < 1.5) at t = 65
        assert!((g.stats.mismatch_time_s - 31.0).abs() < 1e-9);
        assert!((g.stats.longest_mismatch_s - 30.0).abs() < 1e-9);
        assert!(!g.stats.mismatch);
        assert_eq!(g.stats.q_inflation, 1.0);
        assert_eq!(g.stats.max_q_inflation, 100.0);
        assert_eq!(g.stats.max_median_ratio, 9.0);
    }
}
