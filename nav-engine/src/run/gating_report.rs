//! What the innovation gate and its model-mismatch monitor did in a run, in numbers and in
//! words (run summary and `metrics.json`; see `docs/robust-gating.md`).

use nav_core::config::Gating;
use nav_core::filter::robust::RobustStats;
use nav_core::filter::{
    Counters, STATUS_LAST_FIX_DOWNWEIGHTED, STATUS_MODEL_MISMATCH, STATUS_RESET,
};
use serde::Serialize;

/// The gate's report of a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GatingReport {
    /// `robust` (default), `hard` (chi-square gate only) or `off`.
    pub mode: String,
    /// Fixes used with an inflated R (IGG-III down-weighting).
    pub downweighted: u64,
    /// Re-initialisations of position and velocity from the fixes after consecutive
    /// rejections.
    pub resets: u64,
    /// Of which also re-initialised the heading from the GNSS course.
    pub heading_resets: u64,
    /// Times the monitor declared a model mismatch.
    pub mismatch_episodes: u64,
    /// Total time with a mismatch declared, s.
    pub mismatch_time_s: f64,
    /// Longest mismatch episode, s.
    pub longest_mismatch_s: f64,
    /// Fix time of the first declared mismatch, s of week.
    pub first_mismatch_t_s: Option<f64>,
    /// Largest windowed median of the innovations relative to their predicted sigma
    /// (sqrt of the median NIS per degree of freedom; 1 = as predicted).
    pub max_innovation_ratio: Option<f64>,
    /// Largest process-noise inflation factor applied.
    pub max_q_inflation: f64,
    /// Largest gate widening factor applied.
    pub max_gate_widening: f64,
    /// Fixes processed with R multiplied by the learned GNSS sigma scale (the declared sigmas
    /// looked understated: a persistent, white excess of the innovations).
    pub sigma_scaled_fixes: u64,
    /// Mean R multiplier over those fixes (variance ratio; its square root is the sigma
    /// factor); 1 when none.
    pub mean_sigma_scale: f64,
    /// Largest R multiplier applied (variance ratio).
    pub max_sigma_scale: f64,
    /// Fix time when R was first multiplied, s of week.
    pub first_sigma_scale_t_s: Option<f64>,
    /// Status bits (`nav_core::filter::STATUS_*`) seen after any fix, OR-ed.
    pub status_bits_seen: u32,
    /// What happened, in words.
    pub message: String,
}

impl GatingReport {
    /// The report from the filter's counters and robust statistics at the end of a run.
    pub fn new(g: &Gating, c: &Counters, st: &RobustStats, status_bits_seen: u32) -> Self {
        let mode = if g.robust.is_some() {
            "robust"
        } else if g.nis_threshold_pos.is_finite() || g.nis_threshold_pos_vel.is_finite() {
            "hard"
        } else {
            "off"
        };
        let ratio = st
            .max_median_ratio
            .is_finite()
            .then(|| st.max_median_ratio.sqrt());
        let mut r = Self {
            mode: mode.to_string(),
            downweighted: u64::from(st.downweighted),
            resets: u64::from(c.gnss_forced),
            heading_resets: u64::from(st.heading_resets),
            mismatch_episodes: u64::from(st.mismatch_episodes),
            mismatch_time_s: st.mismatch_time_s,
            longest_mismatch_s: st.longest_mismatch_s,
            first_mismatch_t_s: st
                .first_mismatch_t_s
                .is_finite()
                .then_some(st.first_mismatch_t_s),
            max_innovation_ratio: ratio,
            max_q_inflation: st.max_q_inflation,
            max_gate_widening: st.max_gate_widening,
            sigma_scaled_fixes: u64::from(st.sigma_scaled_fixes),
            mean_sigma_scale: st.mean_sigma_scale,
            max_sigma_scale: st.max_sigma_scale,
            first_sigma_scale_t_s: st
                .first_sigma_scale_t_s
                .is_finite()
                .then_some(st.first_sigma_scale_t_s),
            status_bits_seen,
            message: String::new(),
        };
        r.message = r.words(g, c);
        r
    }

    fn words(&self, g: &Gating, c: &Counters) -> String {
        let mut parts = Vec::new();
        if self.sigma_scaled_fixes > 0 {
            parts.push(format!(
                "GNSS sigmas look understated by about {:.1}x: the innovations were persistently \
                 {:.0}x their predicted variance, white from fix to fix (noise, not a model \
                 mismatch); the gate used them inflated (R x{:.0} on average, up to x{:.0}) for \
                 {} fix(es) from t = {:.1} s; declare larger sigmas or a GNSS noise scale \
                 (`host-sim diagnose` fits one)",
                self.mean_sigma_scale.sqrt(),
                self.mean_sigma_scale,
                self.mean_sigma_scale,
                self.max_sigma_scale,
                self.sigma_scaled_fixes,
                self.first_sigma_scale_t_s.unwrap_or(f64::NAN)
            ));
        }
        if self.mismatch_episodes > 0 {
            let ratio = self.max_innovation_ratio.unwrap_or(f64::NAN);
            let q = if self.max_q_inflation > 1.0 {
                format!(
                    ", process noise inflated up to x{:.1}",
                    self.max_q_inflation
                )
            } else {
                String::new()
            };
            parts.push(format!(
                "innovations up to {ratio:.1}x larger than predicted for {:.0} s in {} episode(s) \
                 (first at t = {:.1} s, longest {:.0} s): model mismatch, gate widened up to \
                 x{:.1}{q} so the fixes are still used; run `host-sim diagnose` to find the \
                 missing effect",
                self.mismatch_time_s,
                self.mismatch_episodes,
                self.first_mismatch_t_s.unwrap_or(f64::NAN),
                self.longest_mismatch_s,
                self.max_gate_widening
            ));
        }
        if self.downweighted > 0 {
            parts.push(format!(
                "{} fix(es) down-weighted (IGG-III) instead of rejected",
                self.downweighted
            ));
        }
        if c.gnss_rejected > 0 {
            parts.push(format!("{} fix(es) rejected as outliers", c.gnss_rejected));
        }
        if self.resets > 0 {
            parts.push(format!(
                "{} reset(s) of position and velocity from the fixes after {} consecutive \
                 rejections ({} with the heading from the GNSS course)",
                self.resets, g.max_consecutive_rejections, self.heading_resets
            ));
        }
        if parts.is_empty() {
            return match self.mode.as_str() {
                "off" => "every valid fix used".to_string(),
                _ => "innovations consistent with the model: no fix down-weighted, rejected or \
                      reset"
                    .to_string(),
            };
        }
        parts.join("; ")
    }

    /// Names of the status bits in [`Self::status_bits_seen`] that concern the gate.
    pub fn status_names(&self) -> Vec<&'static str> {
        [
            (STATUS_MODEL_MISMATCH, "MODEL_MISMATCH"),
            (STATUS_LAST_FIX_DOWNWEIGHTED, "LAST_FIX_DOWNWEIGHTED"),
            (STATUS_RESET, "RESET"),
        ]
        .iter()
        .filter(|(b, _)| self.status_bits_seen & b != 0)
        .map(|(_, n)| *n)
        .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_declared_mismatch_is_told_in_words_with_its_numbers() {
        let st = RobustStats {
            mismatch_episodes: 2,
            mismatch_time_s: 120.0,
            longest_mismatch_s: 80.0,
            first_mismatch_t_s: 1234.5,
            max_median_ratio: 64.0,
            max_q_inflation: 4.0,
            max_gate_widening: 4.0,
            downweighted: 7,
            ..RobustStats::default()
        };
        let c = Counters {
            gnss_rejected: 3,
            gnss_forced: 1,
            ..Counters::default()
        };
        let r = GatingReport::new(
            &Gating::robust(),
            &c,
            &st,
            STATUS_MODEL_MISMATCH | STATUS_RESET,
        );
        assert_eq!(r.mode, "robust");
        assert_eq!(r.max_innovation_ratio, Some(8.0));
        for needle in [
            "innovations up to 8.0x larger than predicted for 120 s",
            "model mismatch, gate widened up to x4.0, process noise inflated up to x4.0",
            "host-sim diagnose",
            "7 fix(es) down-weighted",
            "3 fix(es) rejected",
            "1 reset(s) of position and velocity",
        ] {
            assert!(
                r.message.contains(needle),
                "{needle:?} not in {:?}",
                r.message
            );
        }
        assert_eq!(r.status_names(), vec!["MODEL_MISMATCH", "RESET"]);
        let quiet = GatingReport::new(
            &Gating::robust(),
            &Counters::default(),
            &RobustStats::default(),
            0,
        );
        assert!(
            quiet.message.starts_with("innovations consistent"),
            "{}",
            quiet.message
        );
        assert_eq!(quiet.first_mismatch_t_s, None);
        let off = GatingReport::new(
            &Gating::disabled(),
            &Counters::default(),
            &RobustStats::default(),
            0,
        );
        assert_eq!(off.mode, "off");
        assert_eq!(off.sigma_scaled_fixes, 0);
        assert!(!off.message.contains("understated"));
    }

    #[test]
    fn understated_sigmas_are_told_with_their_factor() {
        let st = RobustStats {
            sigma_scaled_fixes: 90,
            mean_sigma_scale: 100.0,
            max_sigma_scale: 180.0,
            sigma_scale: 95.0,
            first_sigma_scale_t_s: 118_826.0,
            ..RobustStats::default()
        };
        let c = Counters {
            gnss_rejected: 2,
            ..Counters::default()
        };
        let r = GatingReport::new(&Gating::robust(), &c, &st, 0);
        assert_eq!(r.sigma_scaled_fixes, 90);
        assert_eq!(r.first_sigma_scale_t_s, Some(118_826.0));
        for needle in [
            "GNSS sigmas look understated by about 10.0x",
            "persistently 100x their predicted variance",
            "R x100 on average, up to x180",
            "for 90 fix(es) from t = 118826.0 s",
            "2 fix(es) rejected",
        ] {
            assert!(
                r.message.contains(needle),
                "{needle:?} not in {:?}",
                r.message
            );
        }
        let json = serde_json::to_value(&r).unwrap();
        assert_eq!(json["mean_sigma_scale"], 100.0);
    }
}
