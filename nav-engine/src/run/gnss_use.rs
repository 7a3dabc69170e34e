//! Whether a run is a navigation solution: where every GNSS fix of the data went, and the
//! error a front end returns when (almost) none was used.
//!
//! A run whose fixes were all unusable integrates the IMU alone: a dead-reckoning track that
//! drifts without bound. It is not reported as a solution: [`check`] returns a
//! [`NotANavigationSolution`] naming each cause (no fix in the data, every record filtered by
//! the quality filter, every fix before or after the IMU data or a GPS week away from it,
//! standard deviations zero or otherwise invalid, mistimed, rejected by the gate, withheld).

use super::RunCounters;

/// Smallest fraction of the fixes offered to the filter (inside the IMU data, not withheld
/// by an imposed outage) that a run must use to be a navigation solution.
pub const MIN_USED_FRACTION: f64 = 0.1;

/// Seconds in a GPS week.
const WEEK_S: f64 = 604_800.0;

/// `span` (first and last time, s) widened to hold `t_s`.
pub fn widen_span(span: Option<(f64, f64)>, t_s: f64) -> Option<(f64, f64)> {
    Some(span.map_or((t_s, t_s), |(a, b)| (a.min(t_s), b.max(t_s))))
}

/// First and last of a sequence of times, s (None when empty): the spans of
/// [`GnssAccount`].
pub fn time_span(t_s: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    t_s.fold(None, widen_span)
}

/// Where the fixes of a run went, from the reader to the filter.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GnssAccount {
    /// The run's counters.
    pub counters: RunCounters,
    /// Records the GNSS reader dropped by the quality filter (`[gnss] max_q`, no fix).
    pub dropped_by_quality: u64,
    /// Time of the first and last fix of the data, GPS seconds of week (when known).
    pub fix_span_s: Option<(f64, f64)>,
    /// Time of the first and last IMU sample, GPS seconds of week (when known).
    pub imu_span_s: Option<(f64, f64)>,
}

impl GnssAccount {
    /// Fixes offered to the filter: inside the IMU data and not withheld.
    pub fn offered(&self) -> u64 {
        let c = &self.counters;
        c.gnss_total
            .saturating_sub(c.gnss_outside_run)
            .saturating_sub(c.gnss_withheld)
    }

    /// One line: where every fix went (`in the data = before + after + used + rejected +
    /// withheld + invalid`).
    pub fn summary_line(&self) -> String {
        let c = &self.counters;
        let mut s = format!("GNSS fixes: {} in the data", c.gnss_total);
        if self.dropped_by_quality > 0 {
            s.push_str(&format!(
                " ({} more record(s) dropped by the quality filter)",
                self.dropped_by_quality
            ));
        }
        s.push_str(&format!(
            ": {} before the IMU data, {} after it, {} used, {} rejected, {} withheld, {} invalid ({} mistimed)",
            c.gnss_before_run,
            c.gnss_outside_run.saturating_sub(c.gnss_before_run),
            c.gnss_accepted,
            c.gnss_rejected,
            c.gnss_withheld,
            c.gnss_invalid,
            c.gnss_mistimed
        ));
        s
    }

    /// The causes of the fixes not used, largest first, in words.
    pub fn causes(&self) -> Vec<String> {
        let c = &self.counters;
        let mut out = Vec::new();
        if c.gnss_total == 0 {
            out.push(if self.dropped_by_quality > 0 {
                format!(
                    "every one of the {} GNSS record(s) was filtered out by the quality filter ([gnss] max_q, no-fix records)",
                    self.dropped_by_quality
                )
            } else {
                "the GNSS data hold no fix (an empty file?)".to_string()
            });
            return out;
        }
        let after = c.gnss_outside_run.saturating_sub(c.gnss_before_run);
        let week_off = match (self.fix_span_s, self.imu_span_s) {
            (Some((f0, f1)), Some((i0, i1))) => [-WEEK_S, WEEK_S]
                .into_iter()
                .find(|w| f1 - w >= i0 - 1.0 && f0 - w <= i1 + 1.0),
            _ => None,
        };
        let spans = match (self.fix_span_s, self.imu_span_s) {
            (Some((f0, f1)), Some((i0, i1))) => {
                format!(" (fixes {f0:.3} to {f1:.3} s, IMU data {i0:.3} to {i1:.3} s of week)")
            }
            _ => String::new(),
        };
        if c.gnss_outside_run > 0 {
            if let (Some(w), true) = (week_off, c.gnss_outside_run == c.gnss_total) {
                out.push(format!(
                    "every fix is one GPS week ({}{} s) {} the IMU data{spans}: the GNSS and IMU time tags are a week apart (week number or time scale)",
                    if w > 0.0 { "+" } else { "-" },
                    WEEK_S,
                    if w > 0.0 { "after" } else { "before" }
                ));
            } else {
                if c.gnss_before_run > 0 {
                    out.push(format!(
                        "{} of {} fix(es) are before the IMU data{spans}",
                        c.gnss_before_run, c.gnss_total
                    ));
                }
                if after > 0 {
                    out.push(format!(
                        "{after} of {} fix(es) are after the IMU data{spans}",
                        c.gnss_total
                    ));
                }
            }
        }
        let bad_values = c.gnss_invalid.saturating_sub(c.gnss_mistimed);
        if bad_values > 0 {
            out.push(format!(
                "{bad_values} fix(es) invalid: a position standard deviation zero or not finite (e.g. UBX hAcc 0), a non-finite position or velocity, or no-fix quality"
            ));
        }
        if c.gnss_mistimed > 0 {
            out.push(format!(
                "{} fix(es) mistimed: too far from the IMU epoch they were due at",
                c.gnss_mistimed
            ));
        }
        if c.gnss_rejected > 0 {
            out.push(format!(
                "{} fix(es) rejected by the innovation gate",
                c.gnss_rejected
            ));
        }
        if c.gnss_withheld > 0 {
            out.push(format!(
                "{} fix(es) withheld by the imposed outages",
                c.gnss_withheld
            ));
        }
        out
    }
}

/// A run that used no GNSS fix, or fewer than [`MIN_USED_FRACTION`] of those offered: the
/// outputs are a dead-reckoning track, not a navigation solution.
#[derive(Debug, Clone, PartialEq)]
pub struct NotANavigationSolution {
    /// Fixes used.
    pub used: u64,
    /// Fixes in the data.
    pub total: u64,
    /// Fixes offered to the filter (inside the IMU data, not withheld).
    pub offered: u64,
    /// Why the others were not used ([`GnssAccount::causes`]).
    pub causes: Vec<String>,
    /// Why the run did not start, when it did not (then no output was written; `None`: the
    /// outputs are a dead-reckoning track).
    pub not_started: Option<String>,
}

impl std::fmt::Display for NotANavigationSolution {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "not a navigation solution ({}): {} of {} GNSS fix(es) used, {} offered to the filter (at least {} % of them needed): {}",
            match &self.not_started {
                Some(why) => format!("nothing run, no output written: {why}"),
                None => "dead reckoning only".to_string(),
            },
            self.used,
            self.total,
            self.offered,
            MIN_USED_FRACTION * 100.0,
            if self.causes.is_empty() {
                "no cause counted".to_string()
            } else {
                self.causes.join("; ")
            }
        )
    }
}

impl std::error::Error for NotANavigationSolution {}

/// `Err` when the run used no fix, or fewer than [`MIN_USED_FRACTION`] of the fixes offered
/// to the filter.
pub fn check(a: &GnssAccount) -> Result<(), NotANavigationSolution> {
    let c = &a.counters;
    let offered = a.offered();
    let used = c.gnss_accepted;
    if used > 0 && used as f64 >= MIN_USED_FRACTION * offered as f64 {
        return Ok(());
    }
    Err(NotANavigationSolution {
        used,
        total: c.gnss_total,
        offered,
        causes: a.causes(),
        not_started: None,
    })
}

/// A run that could not start for want of a GNSS fix (`why`, e.g. the static alignment found
/// none in its window), `a` counting the data's fixes (none used): a
/// [`NotANavigationSolution`] naming where every fix went when none of them was usable (none in
/// the data, all before or after the IMU data, all invalid), else `None` (a usable fix exists
/// elsewhere in the data: the start-up error says more).
pub fn not_started(a: &GnssAccount, why: &str) -> Option<NotANavigationSolution> {
    let c = &a.counters;
    let usable = a.offered().saturating_sub(c.gnss_invalid);
    if usable > 0 {
        return None;
    }
    check(a).err().map(|mut e| {
        e.not_started = Some(why.to_string());
        e
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn account(f: impl FnOnce(&mut RunCounters)) -> GnssAccount {
        let mut c = RunCounters {
            gnss_total: 100,
            ..RunCounters::default()
        };
        f(&mut c);
        GnssAccount {
            counters: c,
            ..GnssAccount::default()
        }
    }

    #[test]
    fn each_cause_is_named_and_enough_fixes_pass() {
        let ok = account(|c| {
            c.gnss_accepted = 90;
            c.gnss_rejected = 10;
        });
        assert!(check(&ok).is_ok());
        let few = account(|c| {
            c.gnss_accepted = 9;
            c.gnss_rejected = 91;
        });
        let e = check(&few).unwrap_err().to_string();
        assert!(
            e.contains("9 of 100") && e.contains("91 fix(es) rejected"),
            "{e}"
        );
        let empty = GnssAccount::default();
        assert!(check(&empty).unwrap_err().to_string().contains("no fix"));
        let q = GnssAccount {
            dropped_by_quality: 7,
            ..GnssAccount::default()
        };
        assert!(check(&q).unwrap_err().to_string().contains("max_q"));
        let mut week = account(|c| {
            c.gnss_outside_run = 100;
        });
        week.fix_span_s = Some((1000.0 + WEEK_S, 1100.0 + WEEK_S));
        week.imu_span_s = Some((990.0, 1110.0));
        let e = check(&week).unwrap_err().to_string();
        assert!(e.contains("one GPS week"), "{e}");
        let before = account(|c| {
            c.gnss_outside_run = 100;
            c.gnss_before_run = 100;
        });
        assert!(check(&before)
            .unwrap_err()
            .to_string()
            .contains("100 of 100 fix(es) are before"));
        let sig = account(|c| c.gnss_invalid = 100);
        assert!(check(&sig)
            .unwrap_err()
            .to_string()
            .contains("standard deviation zero"));
    }

    #[test]
    fn a_run_not_started_is_explained_only_when_no_fix_was_usable() {
        let why = "the static alignment found no fix";
        let after = account(|c| {
            c.gnss_outside_run = 100;
        });
        let e = not_started(&after, why).expect("every fix after the IMU data");
        let text = e.to_string();
        assert!(
            text.contains("nothing run, no output written: the static alignment")
                && text.contains("100 of 100 fix(es) are after the IMU data")
                && !text.contains("dead reckoning"),
            "{text}"
        );
        assert!(not_started(&GnssAccount::default(), why)
            .expect("no fix")
            .to_string()
            .contains("hold no fix"));
        let invalid = account(|c| c.gnss_invalid = 100);
        assert!(not_started(&invalid, why).is_some());
        // one usable fix in the data (outside the static window): not this error
        let one = account(|c| {
            c.gnss_outside_run = 50;
            c.gnss_invalid = 49;
        });
        assert_eq!(not_started(&one, why), None);
    }
}
