//! The solution against the truth (reference trajectory): one matching rule, applied record
//! by record ([`TruthMatcher`] over any iterator of truth records: a slice in memory, or a
//! file read as the solution advances) and over two slices ([`errors_vs_truth`], the matcher
//! over `truth.iter()`).
//!
//! The rule: at every truth epoch, the solution record with the same time stamp (within
//! 0.1 ms), or the two solution records around the truth epoch linearly interpolated when they
//! are at most 0.05 s apart (truth at a rate or phase other than the solution's); truth epochs
//! outside the solution are skipped.

use super::ErrSample;
use nav_core::earth::{self, Llh};
use nav_core::types::NavSolution;

/// Solution and truth time stamps within this are the same epoch, s.
const TOL_S: f64 = 1e-4;
/// Two solution records further apart than this are not interpolated, s.
const MAX_GAP_S: f64 = 0.05;

fn wrap_deg(a: f64) -> f64 {
    let r = (a + 180.0).rem_euclid(360.0) - 180.0;
    if r == -180.0 {
        180.0
    } else {
        r
    }
}

fn llh(s: &NavSolution) -> Llh {
    Llh {
        lat_rad: s.lat_rad,
        lon_rad: s.lon_rad,
        h_m: s.h_m,
    }
}

/// Error of `sol` against `truth` (same time assumed): position NED offset (m), velocity
/// (m/s) and attitude (deg, wrapped to +-180) differences, stamped with the truth's time.
pub fn error_vs_truth(sol: &NavSolution, truth: &NavSolution) -> ErrSample {
    let d = earth::ned_offset_m(&llh(truth), &llh(sol));
    let v = [0, 1, 2].map(|i| sol.vel_ned_mps[i] - truth.vel_ned_mps[i]);
    let a = [0, 1, 2].map(|i| wrap_deg((sol.rpy_rad[i] - truth.rpy_rad[i]).to_degrees()));
    ErrSample {
        t_s: truth.t_s,
        pos_ned_m: d.into(),
        vel_ned_mps: v,
        att_deg: a,
    }
}

/// Errors at every truth epoch (both records in time order), by the module's rule:
/// [`TruthMatcher`] over `truth.iter()`, fed every record of `nav`.
pub fn errors_vs_truth(nav: &[NavSolution], truth: &[NavSolution]) -> Vec<ErrSample> {
    let mut out = Vec::new();
    let mut m = TruthMatcher::new(truth.iter().copied());
    for s in nav {
        m.push(s, |e| out.push(e));
    }
    out
}

/// Linear interpolation of two solution records at `t_s` (s; angles along the short way).
pub fn interpolate(a: &NavSolution, b: &NavSolution, t_s: f64) -> NavSolution {
    let w = (t_s - a.t_s) / (b.t_s - a.t_s);
    let lin = |x: f64, y: f64| x + w * (y - x);
    let ang = |x: f64, y: f64| {
        let d = (y - x + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI)
            - std::f64::consts::PI;
        x + w * d
    };
    NavSolution {
        t_s,
        lat_rad: lin(a.lat_rad, b.lat_rad),
        lon_rad: lin(a.lon_rad, b.lon_rad),
        h_m: lin(a.h_m, b.h_m),
        vel_ned_mps: [0, 1, 2].map(|k| lin(a.vel_ned_mps[k], b.vel_ned_mps[k])),
        rpy_rad: [0, 1, 2].map(|k| ang(a.rpy_rad[k], b.rpy_rad[k])),
        ..*b
    }
}

/// The solution against the truth one solution record at a time: each new record decides
/// the truth epochs up to its time (plus 0.1 ms), which are compared as it arrives. The truth
/// is an iterator read as far as the solution has come (one record ahead): memory is one
/// truth record and one solution record whatever the length.
#[derive(Debug, Clone)]
pub struct TruthMatcher<I> {
    truth: I,
    /// The next truth record, read but beyond the last solution record.
    pending: Option<NavSolution>,
    prev: Option<NavSolution>,
}

impl<I: Iterator<Item = NavSolution>> TruthMatcher<I> {
    /// Against `truth` (time order).
    pub fn new(truth: I) -> Self {
        Self {
            truth,
            pending: None,
            prev: None,
        }
    }

    /// The next solution record (time order); `out` gets the samples it decides.
    pub fn push(&mut self, b: &NavSolution, mut out: impl FnMut(ErrSample)) {
        while let Some(t) = self.pending.take().or_else(|| self.truth.next()) {
            if t.t_s - TOL_S > b.t_s {
                self.pending = Some(t);
                break;
            }
            if (b.t_s - t.t_s).abs() <= TOL_S {
                out(error_vs_truth(b, &t));
                continue;
            }
            let Some(a) = &self.prev else {
                continue;
            };
            if b.t_s - a.t_s > MAX_GAP_S {
                continue;
            }
            out(error_vs_truth(&interpolate(a, b, t.t_s), &t));
        }
        self.prev = Some(*b);
    }

    /// The truth source (records not yet read by the matcher; one it read may be held).
    pub fn source(&self) -> &I {
        &self.truth
    }

    /// The truth source, mutable (reading from it skips those records for the matcher).
    pub fn source_mut(&mut self) -> &mut I {
        &mut self.truth
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap() {
        assert_eq!(wrap_deg(359.0), -1.0);
        assert_eq!(wrap_deg(-181.0), 179.0);
        assert_eq!(wrap_deg(-180.0), 180.0);
    }

    /// The matching rule as it was written over two slices (an index into the solution
    /// advanced per truth epoch), kept here as the reference of the record-by-record form.
    fn by_index(nav: &[NavSolution], truth: &[NavSolution]) -> Vec<ErrSample> {
        let mut out = Vec::new();
        let mut i = 0;
        for t in truth {
            while nav.get(i).is_some_and(|s| s.t_s < t.t_s - TOL_S) {
                i += 1;
            }
            let Some(b) = nav.get(i) else {
                break;
            };
            if (b.t_s - t.t_s).abs() <= TOL_S {
                out.push(error_vs_truth(b, t));
                continue;
            }
            let Some(a) = i.checked_sub(1).and_then(|j| nav.get(j)) else {
                continue;
            };
            if b.t_s - a.t_s > MAX_GAP_S {
                continue;
            }
            out.push(error_vs_truth(&interpolate(a, b, t.t_s), t));
        }
        out
    }

    fn rec(t_s: f64, k: f64) -> NavSolution {
        NavSolution {
            t_s,
            lat_rad: 0.5 + 1e-7 * k,
            lon_rad: 1.9 - 2e-7 * k,
            h_m: 20.0 + 0.01 * k,
            vel_ned_mps: [1.0 + 0.1 * k, -0.5, 0.02 * k],
            rpy_rad: [0.01 * k, -0.02, 3.1 + 0.01 * k],
            ..NavSolution::default()
        }
    }

    #[test]
    fn record_by_record_equals_the_index_form() {
        // solution at 200 Hz with a 0.2 s gap (not interpolated across) and a 0.03 s one
        // (interpolated); truth at 200 Hz (same epochs, 50 us off: within the tolerance),
        // at 30 Hz (interpolated) and starting before / ending after the solution
        let mut nav = Vec::new();
        let mut t = 100.0;
        for k in 0..2000 {
            nav.push(rec(t, k as f64));
            t += match k {
                500 => 0.2,
                900 => 0.03,
                _ => 0.005,
            };
        }
        let same: Vec<_> = (0..2100)
            .map(|k| rec(99.5 + 0.005 * k as f64 + 5e-5, 0.3 * k as f64))
            .collect();
        let slow: Vec<_> = (0..400)
            .map(|k| rec(99.0 + k as f64 / 30.0, -0.1 * k as f64))
            .collect();
        for truth in [&same, &slow] {
            let a = errors_vs_truth(&nav, truth);
            let b = by_index(&nav, truth);
            assert!(a.len() > 300, "{} samples", a.len());
            assert!(
                a.len() < truth.len(),
                "epochs outside the solution are skipped"
            );
            // bit for bit (NaN-free data: plain equality is bit equality here)
            assert_eq!(a, b);
        }
        // a truth epoch in the 0.2 s gap is skipped; one in the 0.03 s gap interpolated
        let gap_t = nav[500].t_s + 0.1;
        let e = errors_vs_truth(&nav, &[rec(gap_t, 0.0)]);
        assert!(e.is_empty());
        let mid_t = nav[900].t_s + 0.015;
        let e = errors_vs_truth(&nav, &[rec(mid_t, 0.0)]);
        assert_eq!(e.len(), 1);
        assert_eq!(e[0].t_s, mid_t);
    }
}
