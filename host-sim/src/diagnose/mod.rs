//! `host-sim diagnose`: find the effect the error-state model lacks from a run's innovations.
//!
//! 1. Residual statistics of the base run ([`ResidualStats`]): NIS mean against its
//!    chi-square band, lag autocorrelation and Ljung-Box Q per innovation component, and the
//!    correlation of the innovations with each candidate effect's regressor.
//! 2. Every candidate of [`DIAGNOSE_CANDIDATES`] not already in the model is confirmed by a
//!    re-run with its block appended (in parallel); the innovation log-likelihood gain is
//!    compared with a BIC penalty `k/2 ln n` (k added states, n scalar measurements). The best
//!    candidate is added only when its gain exceeds the penalty; otherwise "no missing effect".
//!
//! Limitation of this slice: [`crate::run::RunOptions::extra_block`] holds one block, so at
//! most one effect is added (the search loop stops after the first).
use std::path::PathBuf;

use anyhow::Context;
use nav_core::model::Block;
use nav_core::types::{ImuSample, NavSolution};
use rayon::prelude::*;
use serde::Serialize;

use crate::metrics::{self, Metrics};
use crate::run::cli::{execute, prepare, Prepared, RunArgs};
use crate::run::{output, run_filter, FixUse, InnovationRecord, RunOutput, DIAGNOSE_CANDIDATES};

/// Arguments of `host-sim diagnose`: the same as `run`.
#[derive(clap::Args, Debug)]
pub struct DiagnoseArgs {
    /// Inputs as for `run`; `--out` receives diagnosis.json, nav_before.txt, nav_after.txt.
    #[command(flatten)]
    pub run: RunArgs,
}

/// Whiteness statistics of one innovation component.
#[derive(Debug, Clone, Serialize)]
pub struct Whiteness {
    /// Component index (0-2 position N/E/D, 3-5 velocity N/E/D).
    pub component: usize,
    /// Number of normalized innovations.
    pub n: usize,
    /// Autocorrelation of the normalized innovations at lags 1..=LAGS.
    pub autocorr: Vec<f64>,
    /// Ljung-Box Q over lags 1..=LAGS (chi-square with LAGS degrees of freedom when white).
    pub ljung_box_q: f64,
    /// 95 % point of chi-square(LAGS).
    pub ljung_box_q95: f64,
}

/// Residual statistics of one run.
#[derive(Debug, Clone, Serialize)]
pub struct ResidualStats {
    /// Updates used (accepted or forced).
    pub updates: usize,
    /// Mean NIS.
    pub nis_mean: f64,
    /// Mean measurement dimension (the NIS mean's expectation).
    pub nis_expected: f64,
    /// Two-sided 95 % band of the NIS mean (normal approximation of chi-square / n).
    pub nis_band: [f64; 2],
    /// Per-component whiteness.
    pub whiteness: Vec<Whiteness>,
    /// Innovation log-likelihood (diagonal innovation variances), nats.
    pub log_likelihood: f64,
    /// Number of scalar measurements in the log-likelihood.
    pub scalar_measurements: usize,
}

/// The evidence for one candidate effect.
#[derive(Debug, Clone, Serialize)]
pub struct CandidateEvidence {
    /// Effect name (the vocabulary of issue 7).
    pub name: String,
    /// Largest |correlation| of normalized innovations with one of its regressors.
    pub regressor_correlation: f64,
    /// That correlation times sqrt(n) (about N(0,1) without the effect).
    pub correlation_z: f64,
    /// Log-likelihood gain of the re-run with the block added, nats (None: not re-run).
    pub delta_log_likelihood: Option<f64>,
    /// BIC penalty for its states, nats.
    pub bic_penalty: f64,
    /// delta_log_likelihood - bic_penalty: the evidence used for selection.
    pub evidence: Option<f64>,
    /// Why it was not re-run (already in the model, run error).
    pub note: Option<String>,
}

/// An effect the diagnosis added.
#[derive(Debug, Clone, Serialize)]
pub struct AddedEffect {
    /// Effect name.
    pub name: String,
    /// Final estimate of its states, SI (scale factor: dimensionless; lever arm: m, body FRD;
    /// time offset: s).
    pub estimate: Vec<f64>,
    /// 1-sigma of the estimate, same units.
    pub sigma: Vec<f64>,
    /// Log-likelihood gain minus BIC penalty, nats.
    pub evidence: f64,
}

/// The diagnosis.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// Effects added, in order (empty: no missing effect).
    pub added_effects: Vec<AddedEffect>,
    /// Residual statistics of the base model.
    pub residuals_before: ResidualStats,
    /// Residual statistics with the added effects (same as before when none).
    pub residuals_after: ResidualStats,
    /// Every candidate's evidence, strongest first.
    pub candidates: Vec<CandidateEvidence>,
    /// Errors of the base run (vs truth, else vs GNSS withheld in imposed outages).
    pub errors_before: Metrics,
    /// Errors with the added effects.
    pub errors_after: Metrics,
}

/// Number of autocorrelation lags of the whiteness test.
pub const LAGS: usize = 10;

fn used(r: &InnovationRecord) -> bool {
    matches!(r.used, FixUse::Accepted | FixUse::Forced)
}

/// Residual statistics of a run's innovations.
pub fn residual_stats(innov: &[InnovationRecord]) -> ResidualStats {
    let recs: Vec<&InnovationRecord> = innov.iter().filter(|r| used(r)).collect();
    let n = recs.len();
    let nis_mean = recs.iter().map(|r| r.nis).sum::<f64>() / n.max(1) as f64;
    let dim_mean = recs.iter().map(|r| r.dim as f64).sum::<f64>() / n.max(1) as f64;
    let half = 1.96 * (2.0 * dim_mean / n.max(1) as f64).sqrt();
    let mut ll = 0.0;
    let mut m = 0;
    for r in &recs {
        for (v, &s) in r.innovation.iter().zip(&r.innovation_var).take(r.dim) {
            if s > 0.0 {
                ll -= 0.5 * ((2.0 * std::f64::consts::PI * s).ln() + v * v / s);
                m += 1;
            }
        }
    }
    let max_dim = recs.iter().map(|r| r.dim.min(6)).max().unwrap_or(0);
    let whiteness = (0..max_dim)
        .map(|c| {
            let z: Vec<f64> = recs
                .iter()
                .filter(|r| r.dim > c && r.innovation_var[c] > 0.0)
                .map(|r| r.innovation[c] / r.innovation_var[c].sqrt())
                .collect();
            whiteness(c, &z)
        })
        .collect();
    ResidualStats {
        updates: n,
        nis_mean,
        nis_expected: dim_mean,
        nis_band: [dim_mean - half, dim_mean + half],
        whiteness,
        log_likelihood: ll,
        scalar_measurements: m,
    }
}

fn whiteness(component: usize, z: &[f64]) -> Whiteness {
    let n = z.len();
    let mean = z.iter().sum::<f64>() / n.max(1) as f64;
    let c0: f64 = z.iter().map(|v| (v - mean).powi(2)).sum();
    let mut autocorr = Vec::with_capacity(LAGS);
    let mut q = 0.0;
    for k in 1..=LAGS {
        let ck: f64 = z
            .iter()
            .zip(z.iter().skip(k))
            .map(|(a, b)| (a - mean) * (b - mean))
            .sum();
        let r = if c0 > 0.0 { ck / c0 } else { 0.0 };
        autocorr.push(r);
        if n > k {
            q += r * r / (n - k) as f64;
        }
    }
    Whiteness {
        component,
        n,
        autocorr,
        ljung_box_q: n as f64 * (n as f64 + 2.0) * q,
        // chi-square(10) 95 % point
        ljung_box_q95: 18.307,
    }
}

/// Pearson correlation.
fn corr(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len());
    if n < 3 {
        return 0.0;
    }
    let mx = x.iter().take(n).sum::<f64>() / n as f64;
    let my = y.iter().take(n).sum::<f64>() / n as f64;
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y.iter()).take(n) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx).powi(2);
        syy += (b - my).powi(2);
    }
    if sxx > 0.0 && syy > 0.0 {
        sxy / (sxx * syy).sqrt()
    } else {
        0.0
    }
}

fn c_bn(rpy: [f64; 3]) -> [[f64; 3]; 3] {
    let (sr, cr) = rpy[0].sin_cos();
    let (sp, cp) = rpy[1].sin_cos();
    let (sy, cy) = rpy[2].sin_cos();
    [
        [cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
        [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
        [-sp, sr * cp, cr * cp],
    ]
}

fn nearest<T>(v: &[T], t: f64, key: impl Fn(&T) -> f64) -> Option<usize> {
    if v.is_empty() {
        return None;
    }
    let i = v.partition_point(|x| key(x) < t);
    let i = i.min(v.len() - 1);
    if i > 0 && (t - key(&v[i - 1])).abs() < (key(&v[i]) - t).abs() {
        Some(i - 1)
    } else {
        Some(i)
    }
}

/// NED regressor vectors (one per state of the block) of a candidate at one fix.
fn regressors(b: Block, imu: &[ImuSample], i: usize, nav: &NavSolution) -> Vec<[f64; 3]> {
    let c = c_bn(nav.rpy_rad);
    let dt = if i > 0 {
        imu[i].t_s - imu[i - 1].t_s
    } else {
        imu.get(1).map_or(0.0, |s| s.t_s - imu[0].t_s)
    };
    let rate = |v: [f64; 3]| {
        if dt > 0.0 {
            [v[0] / dt, v[1] / dt, v[2] / dt]
        } else {
            [0.0; 3]
        }
    };
    let col = |j: usize, s: f64| [c[0][j] * s, c[1][j] * s, c[2][j] * s];
    match b {
        Block::AccelScaleFactor => {
            let f = rate(imu[i].dv_mps);
            (0..3).map(|j| col(j, f[j])).collect()
        }
        Block::GyroScaleFactor => {
            let w = rate(imu[i].dtheta_rad);
            (0..3).map(|j| col(j, w[j])).collect()
        }
        Block::LeverArm => (0..3).map(|j| col(j, 1.0)).collect(),
        Block::TimeOffset => vec![nav.vel_ned_mps],
        _ => Vec::new(),
    }
}

/// Largest |correlation| of the normalized position innovations with the candidate's
/// regressors (pooled over N/E/D), and the number of pairs.
pub fn regressor_correlation(b: Block, imu: &[ImuSample], run: &RunOutput) -> (f64, usize) {
    let mut best = (0.0f64, 0);
    let recs: Vec<&InnovationRecord> = run.innovations.iter().filter(|r| used(r)).collect();
    let nstates = match b {
        Block::TimeOffset => 1,
        _ => 3,
    };
    for j in 0..nstates {
        let mut x = Vec::new();
        let mut y = Vec::new();
        for r in &recs {
            let (Some(ii), Some(ni)) = (
                nearest(imu, r.t_s, |s| s.t_s),
                nearest(&run.nav, r.t_s, |s| s.t_s),
            ) else {
                continue;
            };
            let reg = regressors(b, imu, ii, &run.nav[ni]);
            let Some(rv) = reg.get(j) else { continue };
            let comps = r.innovation.iter().zip(&r.innovation_var).zip(rv);
            for ((v, &s), reg) in comps.take(r.dim.min(3)) {
                if s > 0.0 {
                    x.push(v / s.sqrt());
                    y.push(*reg);
                }
            }
        }
        let c = corr(&x, &y).abs();
        if c > best.0 {
            best = (c, x.len());
        }
    }
    best
}

/// Result of [`diagnose`] with the two runs.
pub struct DiagnoseOutput {
    /// The diagnosis (diagnosis.json).
    pub diagnosis: Diagnosis,
    /// The base run.
    pub before: RunOutput,
    /// The run with the added effects (the base run again when none).
    pub after: RunOutput,
}

/// Diagnoses a prepared case (see the module notes).
pub fn diagnose(p: &Prepared) -> anyhow::Result<DiagnoseOutput> {
    let (before, errors_before) = execute(p, &mut |_, _| {})?;
    let residuals_before = residual_stats(&before.innovations);
    let base_layout = p.opts.model.layout();
    let n_meas = residuals_before.scalar_measurements.max(1) as f64;
    let results: Vec<(CandidateEvidence, Option<(RunOutput, Metrics)>)> = DIAGNOSE_CANDIDATES
        .par_iter()
        .map(|&b| {
            let (rc, n) = regressor_correlation(b, &p.case.imu, &before);
            let penalty = 0.5 * b.dim() as f64 * n_meas.ln();
            let mut ev = CandidateEvidence {
                name: b.name().to_string(),
                regressor_correlation: rc,
                correlation_z: rc * (n as f64).sqrt(),
                delta_log_likelihood: None,
                bic_penalty: penalty,
                evidence: None,
                note: None,
            };
            if base_layout.find(b.kind()).is_some() {
                ev.note = Some("already in the model".into());
                return (ev, None);
            }
            let mut opts = p.opts.clone();
            opts.extra_block = Some(b);
            match run_filter(&p.case, &opts) {
                Ok(out) => {
                    let rs = residual_stats(&out.innovations);
                    let d = rs.log_likelihood - residuals_before.log_likelihood;
                    ev.delta_log_likelihood = Some(d);
                    ev.evidence = Some(d - penalty);
                    let m = metrics::compute(&out, p.case.truth.as_deref());
                    (ev, Some((out, m)))
                }
                Err(e) => {
                    ev.note = Some(e.to_string());
                    (ev, None)
                }
            }
        })
        .collect();
    let mut best: Option<usize> = None;
    for (i, (ev, run)) in results.iter().enumerate() {
        if let (Some(e), Some(_)) = (ev.evidence, run) {
            if e > 0.0 && best.is_none_or(|j| results[j].0.evidence.unwrap_or(f64::MIN) < e) {
                best = Some(i);
            }
        }
    }
    let mut candidates: Vec<CandidateEvidence> = results.iter().map(|r| r.0.clone()).collect();
    candidates.sort_by(|a, b| {
        let ka = a.evidence.unwrap_or(f64::NEG_INFINITY);
        let kb = b.evidence.unwrap_or(f64::NEG_INFINITY);
        kb.total_cmp(&ka)
    });
    let mut added_effects = Vec::new();
    let (after, errors_after) = match best.and_then(|i| results.into_iter().nth(i)) {
        Some((ev, Some((out, m)))) => {
            let dim = Block::effect_from_name(&ev.name)
                .map_or(3, |b| b.dim())
                .min(3);
            let fb = out.final_blocks.iter().find(|f| f.name == ev.name);
            added_effects.push(AddedEffect {
                name: ev.name.clone(),
                estimate: fb.map_or(Vec::new(), |f| f.value[..dim].to_vec()),
                sigma: fb.map_or(Vec::new(), |f| f.std[..dim].to_vec()),
                evidence: ev.evidence.unwrap_or(0.0),
            });
            (out, m)
        }
        _ => (before.clone(), errors_before.clone()),
    };
    let residuals_after = residual_stats(&after.innovations);
    Ok(DiagnoseOutput {
        diagnosis: Diagnosis {
            added_effects,
            residuals_before,
            residuals_after,
            candidates,
            errors_before,
            errors_after,
        },
        before,
        after,
    })
}

/// Runs `host-sim diagnose`.
pub fn run(args: DiagnoseArgs) -> anyhow::Result<()> {
    let p = prepare(&args.run)?;
    println!("{}", p.description);
    let d = diagnose(&p)?;
    let dir: &PathBuf = &args.run.out;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    output::write_nav(&dir.join("nav_before.txt"), &d.before.nav, p.week)?;
    output::write_nav(&dir.join("nav_after.txt"), &d.after.nav, p.week)?;
    let jp = dir.join("diagnosis.json");
    std::fs::write(&jp, serde_json::to_string_pretty(&d.diagnosis)?)
        .with_context(|| format!("writing {}", jp.display()))?;
    if d.diagnosis.added_effects.is_empty() {
        println!("no missing effect");
    }
    for e in &d.diagnosis.added_effects {
        println!(
            "added {}: estimate {:?} sigma {:?} evidence {:.1}",
            e.name, e.estimate, e.sigma, e.evidence
        );
    }
    Ok(())
}
