//! IMU noise tuning by maximum innovation likelihood (the default of `diagnose`):
//! effects must not absorb noise-model error, so the base model's noise levels are
//! fitted first (and again with the added effects).
//!
//! Three stages, each adopted only when its log-likelihood gain pays the BIC penalty
//! `1/2 ln n` per parameter it changes (n scalar measurements):
//! 1. one factor on both sensors' white-noise PSDs, grid 2^-2 .. 2^10 (13 runs);
//! 2. per sensor (accelerometer, gyro) a factor 1/4, 1/2, 2, 4 on top of stage 1's;
//! 3. per sensor a factor 1/16, 1/4, 4, 16 on the bias driving PSDs (Gauss-Markov S_B and
//!    random walk S_K together; skipped for a sensor whose bias is a random constant).
//!
//! Stages 2 and 3 pick each sensor's best factor with the other sensor at the previous stage's
//! value and confirm the combination with one more run.
use nav_core::config::FilterConfig;
use rayon::prelude::*;
use serde::Serialize;

use super::stats::{residual_stats, ResidualStats};
use nav_engine::run::{run_filter, CaseData, RunOptions};

/// Multipliers on the IMU noise PSDs of a configuration.
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
}

impl NoiseFactors {
    /// The configuration's noise.
    pub const ONE: Self = Self {
        accel_white: 1.0,
        gyro_white: 1.0,
        accel_bias: 1.0,
        gyro_bias: 1.0,
    };

    /// Multiplies the PSDs of `f`.
    pub fn apply(&self, f: &mut FilterConfig) {
        f.accel.s_n.iter_mut().for_each(|s| *s *= self.accel_white);
        f.gyro.s_n.iter_mut().for_each(|s| *s *= self.gyro_white);
        for s in f.accel.s_b.iter_mut().chain(f.accel.s_k.iter_mut()) {
            *s *= self.accel_bias;
        }
        for s in f.gyro.s_b.iter_mut().chain(f.gyro.s_k.iter_mut()) {
            *s *= self.gyro_bias;
        }
    }

    fn as_array(&self) -> [f64; 4] {
        [
            self.accel_white,
            self.gyro_white,
            self.accel_bias,
            self.gyro_bias,
        ]
    }

    /// Whether every factor is 1.
    pub fn is_one(&self) -> bool {
        self.as_array().iter().all(|k| *k == 1.0)
    }

    /// What differs from the configuration, in words ("unchanged" when nothing).
    pub fn describe(&self) -> String {
        let names = [
            "accelerometer white-noise PSD",
            "gyro white-noise PSD",
            "accelerometer bias PSDs (S_B, S_K)",
            "gyro bias PSDs (S_B, S_K)",
        ];
        let v: Vec<String> = names
            .iter()
            .zip(self.as_array())
            .filter(|(_, k)| *k != 1.0)
            .map(|(n, k)| format!("{n} x{k}"))
            .collect();
        if v.is_empty() {
            "unchanged".into()
        } else {
            v.join(", ")
        }
    }
}

/// One tried noise setting.
#[derive(Debug, Clone, Copy, Serialize)]
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
    /// Stage 1: factors tried on both white-noise PSDs.
    pub scales: Vec<f64>,
    /// Their innovation log-likelihoods, nats (NaN: the run failed).
    pub log_likelihood: Vec<f64>,
    /// Their NIS means.
    pub nis_mean: Vec<f64>,
    /// Stage 1's factor (1: the configuration's white noise kept).
    pub chosen_scale: f64,
    /// Stage 1's log-likelihood gain over the configuration minus one BIC penalty, nats.
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
}

fn trial(case: &CaseData, opts: &RunOptions, k: NoiseFactors) -> NoiseTrial {
    let mut o = super::search_recording(opts);
    k.apply(&mut o.filter);
    match run_filter(case, &o) {
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

fn best(trials: &[NoiseTrial]) -> Option<&NoiseTrial> {
    trials
        .iter()
        .filter(|t| t.log_likelihood.is_finite())
        .max_by(|a, b| a.log_likelihood.total_cmp(&b.log_likelihood))
}

/// Tunes the noise of `opts` (see the module notes); `base` are the residual statistics of
/// `opts` as given.
pub fn tune(case: &CaseData, opts: &RunOptions, base: &ResidualStats) -> NoiseTuning {
    let penalty = 0.5 * (base.scalar_measurements.max(2) as f64).ln();
    let one = NoiseTrial {
        factors: NoiseFactors::ONE,
        log_likelihood: base.log_likelihood,
        nis_mean: base.nis_mean,
    };
    // stage 1
    let scales: Vec<f64> = (-2..=10).map(|i| 2f64.powi(i)).collect();
    let s1: Vec<NoiseTrial> = scales
        .par_iter()
        .map(|&k| {
            if k == 1.0 {
                return one;
            }
            let f = NoiseFactors {
                accel_white: k,
                gyro_white: k,
                ..NoiseFactors::ONE
            };
            trial(case, opts, f)
        })
        .collect();
    let b1 = best(&s1).copied().unwrap_or(one);
    let evidence = b1.log_likelihood - base.log_likelihood - penalty;
    let mut cur = if evidence > 0.0 { b1 } else { one };
    let chosen_scale = cur.factors.accel_white;
    let mut refinement = Vec::new();
    // stages 2 and 3: per sensor, then confirm the combination
    type Set = fn(&mut NoiseFactors, f64);
    let stages: [(&[f64], [Set; 2]); 2] = [
        (
            &[0.25, 0.5, 2.0, 4.0],
            [|f, k| f.accel_white *= k, |f, k| f.gyro_white *= k],
        ),
        (
            &[1.0 / 16.0, 0.25, 4.0, 16.0],
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
        let jobs: Vec<(usize, f64)> = (0..2)
            .filter(|&s| si == 0 || has_bias[s])
            .flat_map(|s| grid.iter().map(move |&k| (s, k)))
            .collect();
        if jobs.is_empty() {
            continue;
        }
        let base_f = cur.factors;
        let trials: Vec<(usize, NoiseTrial)> = jobs
            .par_iter()
            .map(|&(s, k)| {
                let mut f = base_f;
                setters[s](&mut f, k);
                (s, trial(case, opts, f))
            })
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
    let params = cur.factors.as_array().iter().filter(|k| **k != 1.0).count();
    NoiseTuning {
        scales,
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
