//! Noise tuning by maximum innovation likelihood (the default of `diagnose`): effects must
//! not absorb noise-model error, so the base model's noise levels are fitted first (and again
//! with the added effects). The noise model is the IMU's (white noise and bias driving PSDs)
//! and the GNSS fixes' (a factor on their declared standard deviations, horizontal and
//! vertical: declared sigmas that are too small are the commonest real-world mismatch).
//!
//! Stages, each adopted only when its log-likelihood gain pays the BIC penalty `1/2 ln n` per
//! parameter it changes (n scalar measurements):
//! 0. GNSS: one factor on the fixes' sigmas (horizontal and vertical together), grid
//!    2^(i/2), i = 0 .. 10 (1 .. 32; never below 1: time-correlated fix errors make smaller
//!    sigmas look likelier although nothing is wrong with the declared ones) with the IMU
//!    noise as configured,
//!    in parallel with stage 1 at the configured GNSS sigmas. Whichever gains more is kept and
//!    the other grid is searched again on top of it (both sources inflate the innovations; the
//!    first fit must not absorb the other's error);
//! 1. one factor on both sensors' white-noise PSDs, grid 2^-2 .. 2^10;
//!    Then the GNSS factor refined: the joint factor at the log-parabola vertex through the best grid point
//!    and its neighbours (one run), then horizontal and vertical each on the grid 2^(+-1/4),
//!    2^(+-1/2) and their own vertex, each at least 1 (a second parameter, its own penalty);
//! 2. per sensor (accelerometer, gyro) a factor on the grid 1/4, 1/2, 2, 4 on top of stage 1's;
//! 3. per sensor a factor on the grid 1/16, 1/4, 4, 16 on the bias driving PSDs (Gauss-Markov
//!    S_B and random walk S_K together; skipped for a sensor whose bias is a random constant).
//!
//! Stages 2 and 3 pick each sensor's best factor with the other sensor at the previous stage's
//! value and confirm the combination with one more run.
//!
//! Every grid is climbed, not run whole: from the point the stage starts at (factor 1) its two
//! neighbours, then onwards in the direction that gains while the log-likelihood rises. On a
//! log-likelihood unimodal along the grid (as the factor's curves are: one maximum, the
//! innovations' fit falling off on both sides) that is the whole grid's best point with its
//! two neighbours (the vertex's three points) in 2 to 4 runs where the grid has 4 to 12;
//! the trials reported are the runs made.
use rayon::prelude::*;
use serde::Serialize;

use super::stats::{residual_stats, ResidualStats};
use nav_engine::run::RunOptions;

use super::imu_cache::Case;

/// Multipliers on the IMU noise PSDs of a configuration and on its GNSS sigmas.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NoiseFactors {
    /// On the accelerometer white-noise PSD S_N.
    pub accel_white: f64,
    /// On the gyro white-noise PSD S_N.
    pub gyro_white: f64,
    /// On the accelerometer bias driving PSDs S_B and S_K.
    pub accel_bias: f64,
    /// On the gyro bias driving PSDs S_B and S_K.
    pub gyro_bias: f64,
    /// On the fixes' north and east standard deviations (position and velocity; a factor on
    /// the sigma, not the variance), on top of the configuration's `[gnss] sigma_scale`.
    pub gnss_horizontal: f64,
    /// On the fixes' down standard deviations (position and velocity).
    pub gnss_vertical: f64,
}

impl NoiseFactors {
    /// The configuration's noise.
    pub const ONE: Self = Self {
        accel_white: 1.0,
        gyro_white: 1.0,
        accel_bias: 1.0,
        gyro_bias: 1.0,
        gnss_horizontal: 1.0,
        gnss_vertical: 1.0,
    };

    /// Multiplies the IMU noise PSDs of `o`'s filter and its GNSS sigma scale
    /// ([`RunOptions::gnss_sigma_scale`]).
    pub fn apply(&self, o: &mut RunOptions) {
        o.gnss_sigma_scale.horizontal *= self.gnss_horizontal;
        o.gnss_sigma_scale.vertical *= self.gnss_vertical;
        let f = &mut o.filter;
        f.accel.s_n.iter_mut().for_each(|s| *s *= self.accel_white);
        f.gyro.s_n.iter_mut().for_each(|s| *s *= self.gyro_white);
        for s in f.accel.s_b.iter_mut().chain(f.accel.s_k.iter_mut()) {
            *s *= self.accel_bias;
        }
        for s in f.gyro.s_b.iter_mut().chain(f.gyro.s_k.iter_mut()) {
            *s *= self.gyro_bias;
        }
    }

    fn as_array(&self) -> [f64; 6] {
        [
            self.accel_white,
            self.gyro_white,
            self.accel_bias,
            self.gyro_bias,
            self.gnss_horizontal,
            self.gnss_vertical,
        ]
    }

    /// Whether every factor is 1.
    pub fn is_one(&self) -> bool {
        self.as_array().iter().all(|k| *k == 1.0)
    }

    /// Whether only the GNSS factors differ from 1 (the IMU noise is the configuration's).
    pub fn is_gnss_only(&self) -> bool {
        self.as_array()[..4].iter().all(|k| *k == 1.0) && !self.is_one()
    }

    /// Number of free parameters these factors change (for the BIC penalty): one per IMU
    /// factor that is not 1; the GNSS factors count one when equal (one scale), two when not.
    pub fn params(&self) -> usize {
        let imu = self.as_array()[..4].iter().filter(|k| **k != 1.0).count();
        let gnss = if self.gnss_horizontal != self.gnss_vertical {
            2
        } else if self.gnss_horizontal != 1.0 {
            1
        } else {
            0
        };
        imu + gnss
    }

    /// The GNSS factors as a sigma scale (horizontal, vertical).
    pub fn gnss(&self) -> nav_io::SigmaScale {
        nav_io::SigmaScale {
            horizontal: self.gnss_horizontal,
            vertical: self.gnss_vertical,
        }
    }

    /// What differs from the configuration, in words ("unchanged" when nothing).
    pub fn describe(&self) -> String {
        let names = [
            "accelerometer white-noise PSD",
            "gyro white-noise PSD",
            "accelerometer bias PSDs (S_B, S_K)",
            "gyro bias PSDs (S_B, S_K)",
            "GNSS sigmas horizontal",
            "GNSS sigmas vertical",
        ];
        let v: Vec<String> = names
            .iter()
            .zip(self.as_array())
            .filter(|(_, k)| *k != 1.0)
            .map(|(n, k)| {
                if n.starts_with("GNSS") {
                    format!("{n} x{k:.3}")
                } else {
                    format!("{n} x{k}")
                }
            })
            .collect();
        if v.is_empty() {
            "unchanged".into()
        } else {
            v.join(", ")
        }
    }
}

/// One tried noise setting.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NoiseTrial {
    /// The factors tried.
    pub factors: NoiseFactors,
    /// Innovation log-likelihood, nats (NaN: the run failed).
    pub log_likelihood: f64,
    /// NIS mean.
    pub nis_mean: f64,
}

/// The noise tuning of a diagnosis.
#[derive(Debug, Clone, Serialize)]
pub struct NoiseTuning {
    /// Stage 0: factors tried on the GNSS sigmas (horizontal and vertical together), ascending
    /// (the grid points the climb reached, 1 among them).
    pub gnss_scales: Vec<f64>,
    /// Their innovation log-likelihoods, nats (NaN: the run failed).
    pub gnss_log_likelihood: Vec<f64>,
    /// Their NIS means.
    pub gnss_nis_mean: Vec<f64>,
    /// Stage 0's log-likelihood gain over the model it started from minus one BIC penalty,
    /// nats (> 0: the GNSS sigmas were rescaled).
    pub gnss_evidence: f64,
    /// Stage 1: factors tried on both white-noise PSDs, ascending (the grid points the climb
    /// reached, 1 among them).
    pub scales: Vec<f64>,
    /// Their innovation log-likelihoods, nats (NaN: the run failed).
    pub log_likelihood: Vec<f64>,
    /// Their NIS means.
    pub nis_mean: Vec<f64>,
    /// Stage 1's factor (1: the configuration's white noise kept).
    pub chosen_scale: f64,
    /// Stage 1's log-likelihood gain over the model it started from minus one BIC penalty,
    /// nats.
    pub evidence: f64,
    /// Stages 2 and 3: every setting tried.
    pub refinement: Vec<NoiseTrial>,
    /// The factors of all stages (what the tuned model uses).
    pub chosen: NoiseFactors,
    /// Log-likelihood gain of [`Self::chosen`] over the configuration minus the BIC penalty of
    /// the parameters it changes, nats.
    pub total_evidence: f64,
    /// NIS mean with the configuration's noise.
    pub nis_before: f64,
    /// NIS mean with the chosen factors.
    pub nis_after: f64,
    /// Expected NIS mean (mean measurement dimension).
    pub nis_expected: f64,
    /// Whether the diagnosis used the tuned noise (it must also not worsen the held-out
    /// outage error or the GNSS residuals; see [`super::Step`]).
    pub adopted: bool,
    /// The same tuning repeated with the added effects in the model (an unmodelled effect also
    /// inflates the innovations, so the first tuning is an upper bound); its factors are the
    /// final model's when adopted. Absent when no effect was added.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub with_effects: Option<Box<NoiseTuning>>,
}

impl NoiseTuning {
    /// Stage 1's factor of the final model (after the effects were added).
    pub fn final_scale(&self) -> f64 {
        self.with_effects
            .as_ref()
            .map_or(self.chosen_scale, |t| t.chosen_scale)
    }

    /// The GNSS noise scale of the final model (after the effects were added): the factors
    /// on the configuration's GNSS sigmas (1, 1: the declared sigmas kept).
    pub fn final_gnss_scale(&self) -> nav_io::SigmaScale {
        self.with_effects
            .as_ref()
            .map_or(self.chosen.gnss(), |t| t.chosen.gnss())
    }
}

fn trial(case: &Case, opts: &RunOptions, k: NoiseFactors) -> NoiseTrial {
    let mut o = super::search_recording(opts);
    k.apply(&mut o);
    match super::spill::run_innovations(case, &o) {
        Ok(out) => {
            let r = residual_stats(&out.innovations);
            NoiseTrial {
                factors: k,
                log_likelihood: r.log_likelihood,
                nis_mean: r.nis_mean,
            }
        }
        Err(_) => NoiseTrial {
            factors: k,
            log_likelihood: f64::NAN,
            nis_mean: f64::NAN,
        },
    }
}

/// The abscissa `x(t)` of the maximum of the parabola through the best trial of `trials`
/// (sorted by `x`) and its two neighbours, kept within their span; None when the best is at
/// an end or a neighbour failed.
fn vertex(trials: &[NoiseTrial], x: impl Fn(&NoiseTrial) -> f64) -> Option<f64> {
    let b = best(trials)?;
    let i = trials.iter().position(|t| std::ptr::eq(t, b))?;
    let (l, r) = (trials.get(i.checked_sub(1)?)?, trials.get(i + 1)?);
    let (x0, x1, x2) = (x(l), x(b), x(r));
    let (y0, y1, y2) = (l.log_likelihood, b.log_likelihood, r.log_likelihood);
    if !(y0.is_finite() && y2.is_finite()) {
        return None;
    }
    // Lagrange parabola's vertex
    let d = (x1 - x0) * (y1 - y2) - (x1 - x2) * (y1 - y0);
    let n = (x1 - x0).powi(2) * (y1 - y2) - (x1 - x2).powi(2) * (y1 - y0);
    if d == 0.0 || !n.is_finite() {
        return None;
    }
    let v = x1 - 0.5 * n / d;
    v.is_finite().then(|| v.clamp(x0, x2))
}

fn best(trials: &[NoiseTrial]) -> Option<&NoiseTrial> {
    trials
        .iter()
        .filter(|t| t.log_likelihood.is_finite())
        .max_by(|a, b| a.log_likelihood.total_cmp(&b.log_likelihood))
}

/// The trials of a climb on the factors `ks` (ascending) from `centre`, the trial at
/// `ks[at]`: both neighbours of the centre first (in parallel), then onwards from the one that
/// gains, one grid point at a time while the log-likelihood rises, stopping at the first point
/// that does not gain (or failed) or at an end of the grid. Returns the trials run and the
/// centre, ordered as `ks`. When the log-likelihood is unimodal on the grid this finds the same
/// best point as the whole grid, with the best point's two grid neighbours among the trials
/// (what [`vertex`] needs); on the usual curve (best at or next to the centre) it runs 2 to 3
/// trials instead of the grid's length minus one.
fn climb(
    centre: NoiseTrial,
    ks: &[f64],
    at: usize,
    run: &(impl Fn(f64) -> NoiseTrial + Sync),
) -> Vec<NoiseTrial> {
    let probe = |i: Option<usize>| i.and_then(|i| ks.get(i)).map(|&k| (k, run(k)));
    let (lo, hi) = rayon::join(|| probe(at.checked_sub(1)), || probe(at.checked_add(1)));
    let gains = |t: &Option<(f64, NoiseTrial)>, than: f64| {
        t.as_ref()
            .is_some_and(|(_, t)| t.log_likelihood.is_finite() && t.log_likelihood > than)
    };
    let ll = |t: &Option<(f64, NoiseTrial)>| {
        t.as_ref().map_or(f64::NEG_INFINITY, |t| t.1.log_likelihood)
    };
    let mut below: Vec<NoiseTrial> = Vec::new();
    let mut above: Vec<NoiseTrial> = Vec::new();
    // the direction of the neighbour that gains more (both gain only off a unimodal curve)
    let up = gains(&hi, centre.log_likelihood)
        && !(gains(&lo, centre.log_likelihood) && ll(&lo) > ll(&hi));
    let down = !up && gains(&lo, centre.log_likelihood);
    let (mut last, side, step): (f64, &mut Vec<NoiseTrial>, isize) = if up {
        (ll(&hi), &mut above, 1)
    } else {
        (ll(&lo), &mut below, -1)
    };
    if up || down {
        let mut i = at as isize + 2 * step;
        while let Some(&k) = usize::try_from(i).ok().and_then(|i| ks.get(i)) {
            let t = run(k);
            side.push(t);
            if !(t.log_likelihood.is_finite() && t.log_likelihood > last) {
                break;
            }
            last = t.log_likelihood;
            i += step;
        }
    }
    let mut out: Vec<NoiseTrial> = below.into_iter().rev().collect();
    out.extend(lo.map(|t| t.1));
    out.push(centre);
    out.extend(hi.map(|t| t.1));
    out.extend(above);
    out
}

/// Stage 1's change: both white-noise PSD factors set to `k`.
fn imu_f(f: NoiseFactors, k: f64) -> NoiseFactors {
    NoiseFactors {
        accel_white: k,
        gyro_white: k,
        ..f
    }
}

/// Stage 0's change: both GNSS sigma factors set to `k`.
fn gnss_f(f: NoiseFactors, k: f64) -> NoiseFactors {
    NoiseFactors {
        gnss_horizontal: k,
        gnss_vertical: k,
        ..f
    }
}

type Make = fn(NoiseFactors, f64) -> NoiseFactors;

/// Stages 0 and 1 from the configuration's trial `one` (the grids `gnss_scales` and `scales`
/// in parallel), the stronger source first and the other's grid again on top of it: the
/// stage 1 and stage 0 trials, their evidences (nats) and the trial chosen.
fn coarse(
    case: &Case,
    opts: &RunOptions,
    penalty: f64,
    one: NoiseTrial,
    scales: &[f64],
    gnss_scales: &[f64],
) -> (Vec<NoiseTrial>, Vec<NoiseTrial>, f64, f64, NoiseTrial) {
    // a climb from the grid point that is `from` itself (the whole grid when none is)
    let grid = |from: NoiseTrial, ks: &[f64], make: Make| -> Vec<NoiseTrial> {
        let run = |k: f64| trial(case, opts, make(from.factors, k));
        match ks
            .iter()
            .position(|&k| make(from.factors, k) == from.factors)
        {
            Some(at) => climb(from, ks, at, &run),
            None => ks.par_iter().map(|&k| run(k)).collect(),
        }
    };
    let (s1_first, s0_first) = rayon::join(
        || grid(one, scales, imu_f),
        || grid(one, gnss_scales, gnss_f),
    );
    let gain = |t: &[NoiseTrial], from: &NoiseTrial| {
        best(t).map_or(f64::NEG_INFINITY, |b| {
            b.log_likelihood - from.log_likelihood
        })
    };
    let mut cur = one;
    // the stronger source first, the other's grid again on top of it
    let gnss_first = gain(&s0_first, &one) > gain(&s1_first, &one);
    let (s1, s0, evidence, gnss_evidence) = if gnss_first {
        let e0 = gain(&s0_first, &one) - penalty;
        if e0 > 0.0 {
            cur = best(&s0_first).copied().unwrap_or(one);
        }
        let s1 = if cur == one {
            s1_first
        } else {
            grid(cur, scales, imu_f)
        };
        let e1 = gain(&s1, &cur) - penalty;
        if e1 > 0.0 {
            cur = best(&s1).copied().unwrap_or(cur);
        }
        (s1, s0_first, e1, e0)
    } else {
        let e1 = gain(&s1_first, &one) - penalty;
        if e1 > 0.0 {
            cur = best(&s1_first).copied().unwrap_or(one);
        }
        let s0 = if cur == one {
            s0_first
        } else {
            grid(cur, gnss_scales, gnss_f)
        };
        let e0 = gain(&s0, &cur) - penalty;
        if e0 > 0.0 {
            cur = best(&s0).copied().unwrap_or(cur);
        }
        (s1_first, s0, e1, e0)
    };
    (s1, s0, evidence, gnss_evidence, cur)
}

/// Stage 1b from the trial `cur`: the GNSS factor refined on the stage 0 trials `s0` (vertex
/// of the log-parabola), then split into horizontal and vertical; every trial run is added to
/// `refinement`. Returns the trial chosen.
fn refine_gnss(
    case: &Case,
    opts: &RunOptions,
    penalty: f64,
    mut cur: NoiseTrial,
    s0: &[NoiseTrial],
    refinement: &mut Vec<NoiseTrial>,
) -> NoiseTrial {
    let log2 = |k: f64| k.log2();
    if let Some(x) = vertex(s0, |t| log2(t.factors.gnss_horizontal)) {
        let t = trial(case, opts, gnss_f(cur.factors, 2f64.powf(x).max(1.0)));
        refinement.push(t);
        if t.log_likelihood > cur.log_likelihood {
            cur = t;
        }
    }
    let steps = [-0.5, -0.25, 0.0, 0.25, 0.5].map(|e: f64| 2f64.powf(e));
    let base_f = cur.factors;
    let split: [fn(&mut NoiseFactors, f64); 2] =
        [|f, k| f.gnss_horizontal *= k, |f, k| f.gnss_vertical *= k];
    let (h, v) = rayon::join(
        || per_factor(case, opts, cur, &steps, split[0]),
        || per_factor(case, opts, cur, &steps, split[1]),
    );
    let per: Vec<(usize, NoiseTrial)> = h
        .into_iter()
        .map(|t| (0, t))
        .chain(v.into_iter().map(|t| (1, t)))
        .collect();
    refinement.extend(per.iter().map(|t| t.1));
    let mut combined = base_f;
    for (c, set) in split.iter().enumerate() {
        let get = |f: &NoiseFactors| {
            if c == 0 {
                f.gnss_horizontal
            } else {
                f.gnss_vertical
            }
        };
        let mut pts: Vec<NoiseTrial> = per.iter().filter(|t| t.0 == c).map(|t| t.1).collect();
        pts.push(cur);
        pts.sort_by(|a, b| get(&a.factors).total_cmp(&get(&b.factors)));
        let Some(x) = vertex(&pts, |t| log2(get(&t.factors))) else {
            continue;
        };
        let mut f = base_f;
        set(&mut f, 2f64.powf(x).max(1.0) / get(&base_f));
        let t = trial(case, opts, f);
        refinement.push(t);
        pts.push(t);
        if let Some(b) = best(&pts) {
            set(&mut combined, get(&b.factors).max(1.0) / get(&base_f));
        }
    }
    if combined != base_f {
        let t = trial(case, opts, combined);
        refinement.push(t);
        // a second GNSS parameter when horizontal and vertical differ
        if t.log_likelihood.is_finite() && t.log_likelihood - cur.log_likelihood > penalty {
            cur = t;
        }
    }
    cur
}

/// The trials of a climb from `cur` on one factor multiplied by `grid` (ascending, with 1,
/// which is `cur` itself) through `set`; `cur` not among them.
fn per_factor(
    case: &Case,
    opts: &RunOptions,
    cur: NoiseTrial,
    grid: &[f64],
    set: fn(&mut NoiseFactors, f64),
) -> Vec<NoiseTrial> {
    let run = |k: f64| {
        let mut f = cur.factors;
        set(&mut f, k);
        trial(case, opts, f)
    };
    let at = grid.iter().position(|&k| k == 1.0);
    let all = match at {
        Some(at) => climb(cur, grid, at, &run),
        None => grid.par_iter().map(|&k| run(k)).collect(),
    };
    all.into_iter()
        .filter(|t| t.factors != cur.factors)
        .collect()
}

/// Stages 2 and 3 from the trial `cur`: per sensor the white-noise and then the bias PSD
/// factors, the combination confirmed; every trial run is added to `refinement`. Returns the
/// trial chosen.
fn per_sensor(
    case: &Case,
    opts: &RunOptions,
    penalty: f64,
    mut cur: NoiseTrial,
    refinement: &mut Vec<NoiseTrial>,
) -> NoiseTrial {
    type Set = fn(&mut NoiseFactors, f64);
    let stages: [(&[f64], [Set; 2]); 2] = [
        (
            &[0.25, 0.5, 1.0, 2.0, 4.0],
            [|f, k| f.accel_white *= k, |f, k| f.gyro_white *= k],
        ),
        (
            &[1.0 / 16.0, 0.25, 1.0, 4.0, 16.0],
            [|f, k| f.accel_bias *= k, |f, k| f.gyro_bias *= k],
        ),
    ];
    for (si, (grid, setters)) in stages.iter().enumerate() {
        let has_bias = [
            opts.filter
                .accel
                .s_b
                .iter()
                .chain(&opts.filter.accel.s_k)
                .any(|s| *s > 0.0),
            opts.filter
                .gyro
                .s_b
                .iter()
                .chain(&opts.filter.gyro.s_k)
                .any(|s| *s > 0.0),
        ];
        if si == 1 && !has_bias.contains(&true) {
            continue;
        }
        let base_f = cur.factors;
        let sensors: Vec<usize> = (0..2).filter(|&s| si == 0 || has_bias[s]).collect();
        let trials: Vec<(usize, NoiseTrial)> = sensors
            .par_iter()
            .map(|&s| (s, per_factor(case, opts, cur, grid, setters[s])))
            .collect::<Vec<_>>()
            .into_iter()
            .flat_map(|(s, ts)| ts.into_iter().map(move |t| (s, t)))
            .collect();
        refinement.extend(trials.iter().map(|t| t.1));
        let mut combined = base_f;
        let mut changed = 0usize;
        for (s, setter) in setters.iter().enumerate() {
            let per: Vec<NoiseTrial> = trials.iter().filter(|t| t.0 == s).map(|t| t.1).collect();
            if let Some(b) = best(&per) {
                if b.log_likelihood - cur.log_likelihood > penalty {
                    let k = grid
                        .iter()
                        .copied()
                        .find(|&k| {
                            let mut f = base_f;
                            setter(&mut f, k);
                            f == b.factors
                        })
                        .unwrap_or(1.0);
                    setter(&mut combined, k);
                    changed += 1;
                }
            }
        }
        if changed == 0 {
            continue;
        }
        let t = if changed == 1 {
            trials
                .iter()
                .map(|t| t.1)
                .find(|t| t.factors == combined)
                .unwrap_or_else(|| trial(case, opts, combined))
        } else {
            let t = trial(case, opts, combined);
            refinement.push(t);
            t
        };
        if t.log_likelihood.is_finite()
            && t.log_likelihood - cur.log_likelihood > penalty * changed as f64
        {
            cur = t;
        }
    }
    cur
}

/// Tunes the noise of `opts` (see the module notes); `base` are the residual statistics of
/// `opts` as given.
pub fn tune(case: &Case, opts: &RunOptions, base: &ResidualStats) -> NoiseTuning {
    let penalty = 0.5 * (base.scalar_measurements.max(2) as f64).ln();
    let one = NoiseTrial {
        factors: NoiseFactors::ONE,
        log_likelihood: base.log_likelihood,
        nis_mean: base.nis_mean,
    };
    // stages 0 and 1 from the configuration, in parallel: the GNSS factor and the IMU
    // white-noise factor
    let scales: Vec<f64> = (-2..=10).map(|i| 2f64.powi(i)).collect();
    // at least 1: with time-correlated GNSS errors (declared as their total sigma) the
    // likelihood of white-noise fixes prefers smaller sigmas (0.79 on a clean simulated
    // drive) although nothing is wrong with them
    let gnss_scales: Vec<f64> = (0..=10).map(|i| 2f64.powf(f64::from(i) / 2.0)).collect();
    let (s1, s0, evidence, gnss_evidence, cur) =
        coarse(case, opts, penalty, one, &scales, &gnss_scales);
    let chosen_scale = cur.factors.accel_white;
    let mut refinement = Vec::new();
    // stage 1b: the GNSS factor refined (vertex of the log-parabola), then split
    let cur = if cur.factors.gnss_horizontal != 1.0 {
        refine_gnss(case, opts, penalty, cur, &s0, &mut refinement)
    } else {
        cur
    };
    // stages 2 and 3: per sensor, then confirm the combination
    let cur = per_sensor(case, opts, penalty, cur, &mut refinement);
    let params = cur.factors.params();
    NoiseTuning {
        gnss_scales: s0.iter().map(|t| t.factors.gnss_horizontal).collect(),
        gnss_log_likelihood: s0.iter().map(|t| t.log_likelihood).collect(),
        gnss_nis_mean: s0.iter().map(|t| t.nis_mean).collect(),
        gnss_evidence,
        scales: s1.iter().map(|t| t.factors.accel_white).collect(),
        log_likelihood: s1.iter().map(|t| t.log_likelihood).collect(),
        nis_mean: s1.iter().map(|t| t.nis_mean).collect(),
        chosen_scale,
        evidence,
        refinement,
        chosen: cur.factors,
        total_evidence: cur.log_likelihood - base.log_likelihood - penalty * params as f64,
        nis_before: base.nis_mean,
        nis_after: cur.nis_mean,
        nis_expected: base.nis_expected,
        adopted: false,
        with_effects: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A trial at white-noise factor `k` with the log-likelihood `ll(log2 k)`.
    fn at(k: f64, ll: &dyn Fn(f64) -> f64) -> NoiseTrial {
        NoiseTrial {
            factors: imu_f(NoiseFactors::ONE, k),
            log_likelihood: ll(k.log2()),
            nis_mean: 1.0,
        }
    }

    #[test]
    fn climb_finds_the_whole_grids_best_point_and_its_neighbours_on_a_unimodal_curve() {
        let ks: Vec<f64> = (-2..=10).map(|i| 2f64.powi(i)).collect();
        let centre = 2; // factor 1
        for peak in [-3.0, -2.0, -1.4, -0.2, 0.0, 0.3, 1.0, 2.6, 7.0, 10.0, 14.0] {
            // concave in log2(k), as the innovation log-likelihood of a noise factor
            let ll = move |x: f64| {
                let d = x - peak;
                if d < 0.0 {
                    -3.0 * d * d
                } else {
                    -d * d
                }
            };
            let runs = std::sync::atomic::AtomicUsize::new(0);
            let run = |k: f64| {
                runs.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                at(k, &ll)
            };
            let got = climb(at(1.0, &ll), &ks, centre, &run);
            let whole: Vec<NoiseTrial> = ks.iter().map(|&k| at(k, &ll)).collect();
            let want = best(&whole).unwrap().factors.accel_white;
            assert_eq!(best(&got).unwrap().factors.accel_white, want, "peak {peak}");
            // ascending, the centre among them, every trial run once
            assert!(got
                .windows(2)
                .all(|w| w[0].factors.accel_white < w[1].factors.accel_white));
            assert_eq!(runs.into_inner(), got.len() - 1, "peak {peak}");
            // the parabola's three points are there: the same vertex as on the whole grid
            let x = |t: &NoiseTrial| t.factors.accel_white.log2();
            assert_eq!(vertex(&got, x), vertex(&whole, x), "peak {peak}");
            // the run count: the neighbours and one past the best (none past a grid end)
            let i = ks.iter().position(|&k| k == want).unwrap();
            let far = i.abs_diff(centre);
            let past = (i < centre && i > 0) || (i > centre && i + 1 < ks.len());
            let want_runs = if far == 0 {
                2
            } else {
                2 + far - 1 + usize::from(past)
            };
            assert_eq!(got.len() - 1, want_runs, "peak {peak}");
        }
    }

    #[test]
    fn climb_stops_at_a_failed_run_and_starts_at_the_grids_end() {
        let ks = [1.0, 2.0, 4.0, 8.0];
        let ll = |x: f64| if x >= 2.0 { f64::NAN } else { x };
        let got = climb(at(1.0, &ll), &ks, 0, &|k| at(k, &ll));
        let lls: Vec<f64> = got.iter().map(|t| t.factors.accel_white).collect();
        assert_eq!(lls, [1.0, 2.0, 4.0]);
        assert_eq!(best(&got).unwrap().factors.accel_white, 2.0);
    }
}
