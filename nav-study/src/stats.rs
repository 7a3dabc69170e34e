//! Monte Carlo statistics of the study: true errors of each run against the truth, their mean
//! and RMS over the runs, the filter's standard deviations, and the NEES.
//!
//! Errors are *estimate minus truth* (the filter's convention): position in metres along north,
//! east and down, NED velocity in m/s, attitude as the phi angle in rad
//! (`C_hat = (I - [phi x]) C`).

use nav_core::attitude::rotvec_from_quat;
use nav_core::earth::ned_offset_m;
use nav_engine::run::RunOutput;
use nav_sim::trajectory::{nav_state_of, Trajectory};
use serde::Serialize;

/// Names of the 9 core error components, in state order.
pub const COMPONENTS: [&str; 9] = [
    "att_n", "att_e", "att_d", "vel_n", "vel_e", "vel_d", "pos_n", "pos_e", "pos_d",
];
/// The three NEES groups: attitude (0..3), velocity (3..6), position (6..9).
pub const GROUPS: [&str; 3] = ["attitude", "velocity", "position"];

/// One run's errors and standard deviations at the recorded epochs.
#[derive(Debug, Clone, Default)]
pub struct Trace {
    /// Time since the first IMU epoch, s.
    pub t_rel_s: Vec<f64>,
    /// True error of the 9 core states (see [`COMPONENTS`]).
    pub err: Vec<[f64; 9]>,
    /// The filter's 1-sigma of the 9 core states.
    pub std: Vec<[f64; 9]>,
}

/// The errors of a run against the trajectory's truth at every recorded epoch.
pub fn trace_of(out: &RunOutput, traj: &Trajectory) -> Trace {
    let mut tr = Trace::default();
    for ep in &out.epochs {
        let x = (ep.t_s - traj.t0_s) / traj.dt_s;
        let k = x.round();
        if !(k >= 0.0 && (x - k).abs() < 1e-3) {
            continue;
        }
        let Some(truth) = traj.truth.get(k as usize) else {
            continue;
        };
        let t = nav_state_of(truth);
        let e = nav_state_of(&ep.nav);
        let dp = ned_offset_m(&t.pos, &e.pos);
        let dv = e.vel_ned_mps - t.vel_ned_mps;
        // q_hat = q(-phi) q  =>  phi = -rotvec(q_hat q^-1)
        let phi = -rotvec_from_quat(&(e.q_nb * t.q_nb.inverse()));
        let mut err = [0.0; 9];
        let mut std = [f64::NAN; 9];
        for i in 0..3 {
            err[i] = phi[i];
            err[3 + i] = dv[i];
            err[6 + i] = dp[i];
        }
        for (s, v) in std.iter_mut().zip(&ep.state_std) {
            *s = *v;
        }
        tr.t_rel_s.push(ep.t_s - traj.t0_s);
        tr.err.push(err);
        tr.std.push(std);
    }
    tr
}

/// Normalised estimation error squared of group `g` at epoch `k` of a trace, from the
/// diagonal of the covariance: `sum_i e_i^2 / P_ii` over the group's three components. Its
/// expectation is 3 for a consistent filter exactly as for the full-matrix NEES
/// (`E[e^T D^-1 e] = tr(D^-1 P) = 3`); the off-diagonal terms only change its spread.
pub fn nees_diag(err: &[f64; 9], std: &[f64; 9], g: usize) -> f64 {
    (3 * g..3 * g + 3)
        .map(|i| {
            let (e, s) = (err[i], std[i]);
            e * e / (s * s)
        })
        .sum()
}

/// Monte Carlo statistics of one cell (a model on a case) at every recorded epoch.
#[derive(Debug, Clone, Default, Serialize)]
pub struct CellStats {
    /// Number of runs.
    pub runs: usize,
    /// Time since the first IMU epoch, s.
    pub t_rel_s: Vec<f64>,
    /// Mean true error over the runs (the bias of the estimator).
    pub mean_err: Vec<[f64; 9]>,
    /// RMS true error over the runs.
    pub rms_err: Vec<[f64; 9]>,
    /// The filter's standard deviation (RMS over the runs; the runs differ very little).
    pub std: Vec<[f64; 9]>,
    /// Average NEES over the runs per group (attitude, velocity, position).
    pub nees: Vec<[f64; 3]>,
}

/// Statistics over runs whose epochs coincide (the common prefix of the traces).
pub fn cell_stats(traces: &[Trace]) -> CellStats {
    let r = traces.len();
    let n = traces.iter().map(|t| t.err.len()).min().unwrap_or(0);
    let mut cs = CellStats {
        runs: r,
        ..Default::default()
    };
    if r == 0 {
        return cs;
    }
    let rf = r as f64;
    for k in 0..n {
        let mut m = [0.0; 9];
        let mut ms = [0.0; 9];
        let mut vs = [0.0; 9];
        let mut ne = [0.0; 3];
        for t in traces {
            let (e, s) = (&t.err[k], &t.std[k]);
            for i in 0..9 {
                m[i] += e[i] / rf;
                ms[i] += e[i] * e[i] / rf;
                vs[i] += s[i] * s[i] / rf;
            }
            for (g, x) in ne.iter_mut().enumerate() {
                *x += nees_diag(e, s, g) / rf;
            }
        }
        cs.t_rel_s.push(traces[0].t_rel_s[k]);
        cs.mean_err.push(m);
        cs.rms_err.push(ms.map(f64::sqrt));
        cs.std.push(vs.map(f64::sqrt));
        cs.nees.push(ne);
    }
    cs
}

impl CellStats {
    /// Index of the recorded epoch nearest to `t_rel_s`.
    pub fn index_at(&self, t_rel_s: f64) -> Option<usize> {
        let i = self.t_rel_s.partition_point(|t| *t < t_rel_s);
        let cand = [i.checked_sub(1), Some(i)];
        cand.into_iter()
            .flatten()
            .filter(|&j| j < self.t_rel_s.len())
            .min_by(|&a, &b| {
                (self.t_rel_s[a] - t_rel_s)
                    .abs()
                    .total_cmp(&(self.t_rel_s[b] - t_rel_s).abs())
            })
    }

    /// Fraction of the epochs in `[t0, t1]` whose average NEES of group `g` lies inside
    /// `band`, and the fractions below and above it.
    pub fn nees_fractions(&self, g: usize, band: (f64, f64), t0: f64, t1: f64) -> [f64; 3] {
        let mut c = [0usize; 3];
        for (t, n) in self.t_rel_s.iter().zip(&self.nees) {
            if *t < t0 || *t > t1 {
                continue;
            }
            let x = n[g];
            let j = if x < band.0 {
                1
            } else if x > band.1 {
                2
            } else {
                0
            };
            c[j] += 1;
        }
        let tot = (c[0] + c[1] + c[2]).max(1) as f64;
        c.map(|x| x as f64 / tot)
    }

    /// Time average of the average NEES of group `g` over `[t0, t1]`.
    pub fn nees_mean(&self, g: usize, t0: f64, t1: f64) -> f64 {
        let v: Vec<f64> = self
            .t_rel_s
            .iter()
            .zip(&self.nees)
            .filter(|(t, _)| **t >= t0 && **t <= t1)
            .map(|(_, n)| n[g])
            .collect();
        v.iter().sum::<f64>() / v.len().max(1) as f64
    }

    /// Time average of the RMS error and of the standard deviation of component `i` over
    /// `[t0, t1]` (both as RMS over time).
    pub fn rms_over(&self, i: usize, t0: f64, t1: f64) -> (f64, f64) {
        let (mut a, mut b, mut n) = (0.0, 0.0, 0usize);
        for ((t, e), s) in self.t_rel_s.iter().zip(&self.rms_err).zip(&self.std) {
            if *t >= t0 && *t <= t1 {
                a += e[i] * e[i];
                b += s[i] * s[i];
                n += 1;
            }
        }
        let n = n.max(1) as f64;
        ((a / n).sqrt(), (b / n).sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_stats_of_known_traces() {
        let mk = |e: f64, s: f64| Trace {
            t_rel_s: vec![0.0, 1.0],
            err: vec![[e; 9], [2.0 * e; 9]],
            std: vec![[s; 9], [s; 9]],
        };
        let cs = cell_stats(&[mk(1.0, 1.0), mk(-3.0, 1.0)]);
        assert_eq!(cs.runs, 2);
        assert_eq!(cs.mean_err[0][0], -1.0);
        assert!((cs.rms_err[0][4] - 5f64.sqrt()).abs() < 1e-12);
        // NEES: (1 + 9) / 2 per component, x 3 components
        assert!((cs.nees[0][2] - 15.0).abs() < 1e-12);
        assert!((cs.nees[1][1] - 60.0).abs() < 1e-12);
        assert_eq!(cs.index_at(0.7), Some(1));
        let f = cs.nees_fractions(0, (1.0, 20.0), 0.0, 1.0);
        assert_eq!(f, [0.5, 0.0, 0.5]);
    }
}
