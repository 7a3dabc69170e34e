//! `host-sim diagnose`: find the effects the error-state model lacks from a run's innovations,
//! add them, and report the errors before and after.
//!
//! 1. Residual statistics of the base run ([`stats::ResidualStats`]): NIS mean against its
//!    chi-square band; per innovation component the autocorrelation, Ljung-Box Q and the
//!    Allan variance of the normalised innovations over clusters of fixes (white: m AVAR(m) =
//!    1); and the correlation of the normalised innovations with each candidate effect's
//!    regressor (specific force, rate, their cross-axis products, temperature, velocity for a
//!    time offset, attitude columns for a lever arm).
//! 2. Candidates: every effect block of the vocabulary ([`EFFECT_BLOCKS`]) not already in the
//!    model; the temperature blocks only when the IMU data carry a temperature column.
//! 3. Selection, repeated while an effect pays: every remaining candidate is re-run with its
//!    block appended to the blocks added so far (in parallel, rayon); its innovation
//!    log-likelihood gain over the current model is compared with the BIC penalty
//!    `k/2 ln n` (k added states, n scalar measurements). The candidate with the largest
//!    `gain - penalty` is added when that is positive; when no candidate pays, the search stops
//!    ("no missing effect" when nothing was added at all).
//!
//! Cost: one filter run per candidate and round plus two full runs; a 40-minute 200 Hz drive
//! with all 9 candidates and one effect to find (2 rounds, 17 candidate runs) takes 12 s on
//! 2 threads (`cargo run --release -p host-sim --example diagnose_bench`, shared machine).
//! The filter's state count is a compile-time constant: [`crate::run::run_filter`] dispatches
//! layouts with extra blocks on their dimension (16 to [`MAX_EXTRA_DIM`] states).
//!
//! Units of the estimates ([`AddedEffect::estimate`], the blocks' states, SI):
//! `accel_scale_factor`, `gyro_scale_factor`: dimensionless (x, y, z; 1e-6 = 1 ppm);
//! `accel_misalignment`, `gyro_misalignment`: rad, `[m_xy, m_xz, m_yx, m_yz, m_zx, m_zy]`
//! (m_ij: fraction of the body-axis-j input sensed by sensor i); `lever_arm`: m, body FRD,
//! the correction to the configured antenna lever arm; `time_offset`: s, a fix tagged t is
//! the antenna at IMU time t + estimate; `accel_temperature_bias`: m/s^2/degC;
//! `gyro_temperature_bias`: rad/s/degC; `gyro_g_sensitivity`: rad/s per m/s^2 (diagonal).
pub mod report;
pub mod stats;

use std::path::PathBuf;

use anyhow::Context;
use nav_core::model::{Block, EFFECT_BLOCKS};
use rayon::prelude::*;
use serde::Serialize;

use crate::metrics::{self, Metrics};
use crate::run::cli::{execute, prepare, scale_white_noise, Prepared, RunArgs};
use crate::run::{output, run_filter, CaseData, RunOptions, RunOutput, MAX_EXTRA_DIM};
pub use stats::{regressor_correlation, residual_stats, ResidualStats, Whiteness};

/// Arguments of `host-sim diagnose`: the same as `run`, plus the search limits.
#[derive(clap::Args, Debug)]
pub struct DiagnoseArgs {
    /// Inputs as for `run`; `--out` receives diagnosis.json, nav_before.txt, nav_after.txt,
    /// report.md with its PNG plots, and the augmented configuration.
    #[command(flatten)]
    pub run: RunArgs,
    /// Largest number of effects to add.
    #[arg(long, default_value_t = 4)]
    pub max_effects: usize,
    /// Before the effect search, fit one factor on the IMU white-noise PSDs by maximum
    /// innovation likelihood (grid 1/4 .. 1024 in factors of 2; adopted when it pays its BIC
    /// penalty). For real drives whose base model is far from consistent (NIS far above its
    /// expectation): the effect evidence is then measured against a consistent base model.
    #[arg(long)]
    pub tune_noise: bool,
}

/// Options of [`diagnose`].
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    /// Largest number of effects to add.
    pub max_effects: usize,
    /// Candidates to consider (`None`: [`candidates`] of the case).
    pub candidates: Option<Vec<Block>>,
    /// Fit a white-noise PSD factor first (`--tune-noise`).
    pub tune_noise: bool,
}

/// The white-noise factor search of `--tune-noise`.
#[derive(Debug, Clone, Serialize)]
pub struct NoiseTuning {
    /// Factors tried on the accelerometer and gyro white-noise PSDs.
    pub scales: Vec<f64>,
    /// Innovation log-likelihood of each, nats (NaN: the run failed).
    pub log_likelihood: Vec<f64>,
    /// NIS mean of each.
    pub nis_mean: Vec<f64>,
    /// The factor adopted (1: the configuration's noise kept).
    pub chosen_scale: f64,
    /// Log-likelihood gain of the best factor over 1 minus the BIC penalty of one
    /// parameter, nats (adopted when positive).
    pub evidence: f64,
    /// The same search repeated with the added effects in the model (an unmodelled effect
    /// also inflates the innovations, so the first factor is an upper bound); its factor is
    /// the one of the final model. Absent when no effect was added.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub with_effects: Option<Box<NoiseTuning>>,
}

impl NoiseTuning {
    /// The factor of the final model (after the effects were added), 1 when not adopted.
    pub fn final_scale(&self) -> f64 {
        self.with_effects
            .as_ref()
            .map_or(self.chosen_scale, |t| t.chosen_scale)
    }
}

impl Default for DiagnoseOptions {
    /// At most 4 effects, all applicable candidates.
    fn default() -> Self {
        Self {
            max_effects: 4,
            candidates: None,
            tune_noise: false,
        }
    }
}

/// The evidence for one candidate effect in one round of the search.
#[derive(Debug, Clone, Serialize)]
pub struct CandidateEvidence {
    /// Effect name (the vocabulary of issue 7).
    pub name: String,
    /// Largest |correlation| of the current model's normalised position innovations with one
    /// of the candidate's regressors (screening statistic).
    pub regressor_correlation: f64,
    /// That correlation times sqrt(pairs) (about N(0,1) without the effect, for white
    /// innovations).
    pub correlation_z: f64,
    /// Log-likelihood gain of the re-run with the block added, nats (None: not run).
    pub delta_log_likelihood: Option<f64>,
    /// BIC penalty for its states, nats.
    pub bic_penalty: f64,
    /// delta_log_likelihood - bic_penalty: the evidence used for selection (> 0: pays).
    pub evidence: Option<f64>,
    /// Estimate of the block's states in the re-run (SI, see the module notes).
    pub estimate: Vec<f64>,
    /// Their 1-sigma.
    pub sigma: Vec<f64>,
    /// Outage position error of the re-run (see [`outage_error_m`]), m.
    pub outage_error_m: Option<f64>,
    /// Why it was not run (run error).
    pub note: Option<String>,
}

/// One round of the search: every remaining candidate against the current model.
#[derive(Debug, Clone, Serialize)]
pub struct Round {
    /// Effects in the model before this round (added by earlier rounds).
    pub model_effects: Vec<String>,
    /// Log-likelihood of the current model, nats.
    pub log_likelihood: f64,
    /// Every candidate's evidence, strongest first.
    pub candidates: Vec<CandidateEvidence>,
    /// The effect added in this round (None: no candidate paid, search stopped).
    pub added: Option<String>,
}

/// An effect the diagnosis added.
#[derive(Debug, Clone, Serialize)]
pub struct AddedEffect {
    /// Effect name (the vocabulary).
    pub name: String,
    /// Estimate of its states in the final model, SI (see the module notes).
    pub estimate: Vec<f64>,
    /// 1-sigma of the estimate, same units.
    pub sigma: Vec<f64>,
    /// SI unit of the states.
    pub unit: String,
    /// Log-likelihood gain minus BIC penalty when it was added, nats.
    pub evidence: f64,
    /// The strongest other candidate of that round and how many nats it trailed by (a small
    /// margin means the two are hard to tell apart on this drive, e.g. accelerometer and gyro
    /// misalignment, whose rotation parts are nearly equivalent).
    pub runner_up: Option<(String, f64)>,
}

/// Position errors of one run in the imposed outages (or overall without outages).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ErrorSummary {
    /// `truth` or `withheld_gnss`.
    pub reference: &'static str,
    /// Number of outages compared.
    pub outages: usize,
    /// RMS over outages of each outage's largest 3D position error, m (the headline figure;
    /// without outages the overall 3D RMS).
    pub outage_max_3d_rms_m: f64,
    /// RMS over outages of the horizontal error at the outage end, m.
    pub outage_end_horizontal_rms_m: f64,
    /// 3D position RMS over all comparison epochs, m.
    pub overall_3d_rms_m: f64,
    /// Horizontal RMS of the prior residuals of the used fixes, m.
    pub gnss_residual_horizontal_rms_m: f64,
}

/// The diagnosis (diagnosis.json).
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// Effects added, in the order they were added (empty: no missing effect).
    pub added_effects: Vec<AddedEffect>,
    /// "no missing effect" or the names added.
    pub verdict: String,
    /// The white-noise factor search (`--tune-noise`; absent otherwise). The added effects
    /// and the errors after are with the chosen factor.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_tuning: Option<NoiseTuning>,
    /// Cautions about the diagnosis (e.g. a base model whose NIS is far from its
    /// expectation: the likelihood comparison then also rewards states that absorb
    /// noise-model error).
    pub warnings: Vec<String>,
    /// Candidates considered.
    pub candidates_considered: Vec<String>,
    /// Residual statistics of the base model.
    pub residuals_before: ResidualStats,
    /// Residual statistics with the added effects (same as before when none).
    pub residuals_after: ResidualStats,
    /// The search, round by round.
    pub rounds: Vec<Round>,
    /// Position errors of the base model.
    pub error_before: ErrorSummary,
    /// Position errors with the added effects.
    pub error_after: ErrorSummary,
    /// Full error metrics of the base run (vs truth, else vs GNSS withheld in imposed
    /// outages).
    pub errors_before: Metrics,
    /// Full error metrics with the added effects.
    pub errors_after: Metrics,
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

/// The outage position error of a run: RMS over the outages of each outage's largest 3D
/// error (vs truth, or vs the withheld fixes), m; without outages the overall 3D RMS.
pub fn outage_error_m(m: &Metrics) -> f64 {
    if m.outage_summary.count > 0 {
        m.outage_summary.max_3d_m.rms
    } else {
        m.overall.pos_3d_m.rms
    }
}

fn error_summary(m: &Metrics) -> ErrorSummary {
    ErrorSummary {
        reference: if m.reference == "truth" {
            "truth"
        } else {
            "withheld_gnss"
        },
        outages: m.outage_summary.count,
        outage_max_3d_rms_m: outage_error_m(m),
        outage_end_horizontal_rms_m: m.outage_summary.end_horizontal_m.rms,
        overall_3d_rms_m: m.overall.pos_3d_m.rms,
        gnss_residual_horizontal_rms_m: m.gnss_residuals.horizontal_m.rms,
    }
}

/// The candidates for a case and base model: every effect block not in the model, the
/// temperature blocks only when some IMU sample carries a temperature.
pub fn candidates(case: &CaseData, opts: &RunOptions) -> Vec<Block> {
    let has_temp = case.imu.iter().any(|s| s.temperature_c.is_finite());
    let layout = opts.model.layout();
    EFFECT_BLOCKS
        .iter()
        .copied()
        .filter(|b| !layout.contains(b.kind()) && !opts.extra_blocks.contains(b))
        .filter(|b| {
            has_temp || !matches!(b, Block::AccelTemperatureBias | Block::GyroTemperatureBias)
        })
        .collect()
}

/// Options of a run with `blocks` appended: the time-offset block needs the filter to accept
/// fixes further from an IMU epoch (its 3-sigma prior).
pub fn options_with(base: &RunOptions, blocks: &[Block]) -> RunOptions {
    let mut o = base.clone();
    for &b in blocks {
        o.add_effect_block(b);
    }
    o
}

fn effect_values(out: &RunOutput, name: &str) -> (Vec<f64>, Vec<f64>) {
    out.final_effects
        .iter()
        .find(|e| e.name == name)
        .map_or((Vec::new(), Vec::new()), |e| {
            (e.value.clone(), e.std.clone())
        })
}

/// Diagnoses a prepared case (see the module notes).
pub fn diagnose(p: &Prepared, dopts: &DiagnoseOptions) -> anyhow::Result<DiagnoseOutput> {
    let (before, errors_before) = execute(p, &mut |_, _| {})?;
    let residuals_before = residual_stats(&before.innovations);
    let all = dopts
        .candidates
        .clone()
        .unwrap_or_else(|| candidates(&p.case, &p.opts));
    let base_dim =
        p.opts.model.layout().dim() + p.opts.extra_blocks.iter().map(|b| b.dim()).sum::<usize>();
    let truth = p.case.truth.as_deref();

    let mut base_opts = p.opts.clone();
    let mut current: (RunOutput, Metrics) = (before.clone(), errors_before.clone());
    let mut current_ll = residuals_before.log_likelihood;
    let mut noise_tuning = if dopts.tune_noise {
        let t = tune_white_noise(&p.case, &p.opts, &residuals_before);
        if t.chosen_scale != 1.0 {
            scale_white_noise(&mut base_opts.filter, t.chosen_scale);
            let pt = Prepared {
                case: p.case.clone(),
                opts: base_opts.clone(),
                week: p.week,
                description: p.description.clone(),
            };
            current = execute(&pt, &mut |_, _| {})?;
            current_ll = residual_stats(&current.0.innovations).log_likelihood;
        }
        Some(t)
    } else {
        None
    };
    let mut added: Vec<Block> = Vec::new();
    let mut added_ev: Vec<(f64, Option<(String, f64)>)> = Vec::new();
    let mut rounds = Vec::new();
    while added.len() < dopts.max_effects {
        let dim_now = base_dim + added.iter().map(|b| b.dim()).sum::<usize>();
        let remaining: Vec<Block> = all
            .iter()
            .copied()
            .filter(|b| !added.contains(b) && dim_now + b.dim() <= MAX_EXTRA_DIM)
            .collect();
        if remaining.is_empty() {
            break;
        }
        let cur_run = &current.0;
        let n_meas = residual_stats(&cur_run.innovations)
            .scalar_measurements
            .max(2) as f64;
        let results: Vec<(CandidateEvidence, Option<(RunOutput, Metrics)>)> = remaining
            .par_iter()
            .map(|&b| {
                let (rc, n) = regressor_correlation(b, &p.case.imu, cur_run);
                let penalty = 0.5 * b.dim() as f64 * n_meas.ln();
                let mut ev = CandidateEvidence {
                    name: b.name().to_string(),
                    regressor_correlation: rc,
                    correlation_z: rc * (n as f64).sqrt(),
                    delta_log_likelihood: None,
                    bic_penalty: penalty,
                    evidence: None,
                    estimate: Vec::new(),
                    sigma: Vec::new(),
                    outage_error_m: None,
                    note: None,
                };
                let mut blocks = added.clone();
                blocks.push(b);
                let opts = options_with(&base_opts, &blocks);
                match run_filter(&p.case, &opts) {
                    Ok(out) => {
                        let rs = residual_stats(&out.innovations);
                        let d = rs.log_likelihood - current_ll;
                        ev.delta_log_likelihood = Some(d);
                        ev.evidence = Some(d - penalty);
                        (ev.estimate, ev.sigma) = effect_values(&out, b.name());
                        let m = metrics::compute(&out, truth);
                        ev.outage_error_m = Some(outage_error_m(&m));
                        (ev, Some((out, m)))
                    }
                    Err(e) => {
                        ev.note = Some(e.to_string());
                        (ev, None)
                    }
                }
            })
            .collect();
        let best = results
            .iter()
            .enumerate()
            .filter(|(_, (ev, run))| run.is_some() && ev.evidence.is_some_and(|e| e > 0.0))
            .max_by(|a, b| {
                let ea = a.1 .0.evidence.unwrap_or(f64::NEG_INFINITY);
                let eb = b.1 .0.evidence.unwrap_or(f64::NEG_INFINITY);
                ea.total_cmp(&eb)
            })
            .map(|(i, _)| i);
        let mut cands: Vec<CandidateEvidence> = results.iter().map(|r| r.0.clone()).collect();
        cands.sort_by(|a, b| {
            let ka = a.evidence.unwrap_or(f64::NEG_INFINITY);
            let kb = b.evidence.unwrap_or(f64::NEG_INFINITY);
            kb.total_cmp(&ka)
        });
        let mut round = Round {
            model_effects: added.iter().map(|b| b.name().to_string()).collect(),
            log_likelihood: current_ll,
            candidates: cands,
            added: None,
        };
        let Some(i) = best else {
            rounds.push(round);
            break;
        };
        let Some((ev, Some(run))) = results.into_iter().nth(i) else {
            rounds.push(round);
            break;
        };
        let Some(b) = Block::effect_from_name(&ev.name) else {
            rounds.push(round);
            break;
        };
        let best_ev = ev.evidence.unwrap_or(0.0);
        let runner_up = round
            .candidates
            .iter()
            .find(|c| c.name != ev.name && c.evidence.is_some())
            .map(|c| (c.name.clone(), best_ev - c.evidence.unwrap_or(0.0)));
        round.added = Some(ev.name.clone());
        rounds.push(round);
        added.push(b);
        added_ev.push((best_ev, runner_up));
        current_ll += ev.delta_log_likelihood.unwrap_or(0.0);
        current = run;
    }

    let (after, errors_after) = current;
    let added_effects: Vec<AddedEffect> = added
        .iter()
        .zip(&added_ev)
        .map(|(b, (e, r))| {
            let (estimate, sigma) = effect_values(&after, b.name());
            AddedEffect {
                name: b.name().to_string(),
                estimate,
                sigma,
                unit: b.unit().to_string(),
                evidence: *e,
                runner_up: r.clone(),
            }
        })
        .collect();
    // the after run with the same recording as the before run (coasting baselines, epochs)
    let tuned = noise_tuning.as_ref().is_some_and(|t| t.chosen_scale != 1.0);
    let mut final_opts = options_with(&base_opts, &added);
    if let Some(t) = noise_tuning.as_mut().filter(|_| !added.is_empty()) {
        // re-fit the factor with the effects in the model, from the configuration's noise
        let with = options_with(&p.opts, &added);
        let base_stats = run_filter(&p.case, &with)
            .map(|o| residual_stats(&o.innovations))
            .unwrap_or_else(|_| residuals_before.clone());
        let t2 = tune_white_noise(&p.case, &with, &base_stats);
        final_opts = with;
        scale_white_noise(&mut final_opts.filter, t2.chosen_scale);
        t.with_effects = Some(Box::new(t2));
    }
    let (after, errors_after) = if added.is_empty() && !tuned {
        (after, errors_after)
    } else {
        let pa = Prepared {
            case: p.case.clone(),
            opts: final_opts,
            week: p.week,
            description: p.description.clone(),
        };
        execute(&pa, &mut |_, _| {}).unwrap_or((after, errors_after))
    };
    let residuals_after = residual_stats(&after.innovations);
    let verdict = if added_effects.is_empty() {
        "no missing effect".to_string()
    } else {
        added_effects
            .iter()
            .map(|e| e.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut warnings = Vec::new();
    let (nis, dim) = (residuals_before.nis_mean, residuals_before.nis_expected);
    if let Some(t) = noise_tuning.as_ref().filter(|_| tuned) {
        let tuned_nis = t
            .scales
            .iter()
            .zip(&t.nis_mean)
            .find(|(k, _)| **k == t.chosen_scale)
            .map_or(nis, |(_, n)| *n);
        let t = t.with_effects.as_deref().unwrap_or(t);
        if t.scales.last() == Some(&t.chosen_scale) {
            warnings.push(format!(
                "white-noise factor at the top of its grid ({}; NIS mean {tuned_nis:.1} for an \
                 expected {dim:.1}): the inconsistency is not only IMU white noise (GNSS \
                 sigmas, vibration, unmodelled effects)",
                t.chosen_scale
            ));
        }
    } else if dim > 0.0 && !(0.5 * dim..=2.0 * dim).contains(&residuals_after.nis_mean) {
        // judged on the final model: a missing effect alone also inflates the base NIS, and
        // is then explained by the effect added
        let after_nis = residuals_after.nis_mean;
        warnings.push(format!(
            "model inconsistent with the data even with the added effects: NIS mean \
             {after_nis:.1} (base {nis:.1}) for an expected {dim:.1}; the evidence values are \
             inflated and an added effect may partly absorb noise-model error (check the \
             noise model, e.g. run's --noise-scale, or diagnose --tune-noise)"
        ));
    }
    if residuals_before.updates < 30 {
        warnings.push(format!(
            "only {} GNSS updates: little evidence either way",
            residuals_before.updates
        ));
    }
    Ok(DiagnoseOutput {
        diagnosis: Diagnosis {
            added_effects,
            verdict,
            noise_tuning,
            warnings,
            candidates_considered: all.iter().map(|b| b.name().to_string()).collect(),
            residuals_before,
            residuals_after,
            rounds,
            error_before: error_summary(&errors_before),
            error_after: error_summary(&errors_after),
            errors_before,
            errors_after,
        },
        before,
        after,
    })
}

/// The `--tune-noise` search: the base model with its white-noise PSDs times 2^i,
/// i = -2..=10, in parallel; the best factor is adopted when its log-likelihood gain over the
/// configuration's noise exceeds the BIC penalty of one parameter.
fn tune_white_noise(case: &CaseData, opts: &RunOptions, before: &ResidualStats) -> NoiseTuning {
    let scales: Vec<f64> = (-2..=10).map(|i| 2f64.powi(i)).collect();
    let stats: Vec<(f64, f64)> = scales
        .par_iter()
        .map(|&k| {
            if k == 1.0 {
                return (before.log_likelihood, before.nis_mean);
            }
            let mut o = opts.clone();
            scale_white_noise(&mut o.filter, k);
            match run_filter(case, &o) {
                Ok(out) => {
                    let r = residual_stats(&out.innovations);
                    (r.log_likelihood, r.nis_mean)
                }
                Err(_) => (f64::NAN, f64::NAN),
            }
        })
        .collect();
    let penalty = 0.5 * (before.scalar_measurements.max(2) as f64).ln();
    let (best_k, best_ll) = scales
        .iter()
        .zip(&stats)
        .filter(|(_, (ll, _))| ll.is_finite())
        .max_by(|a, b| a.1 .0.total_cmp(&b.1 .0))
        .map_or((1.0, before.log_likelihood), |(k, (ll, _))| (*k, *ll));
    let evidence = best_ll - before.log_likelihood - penalty;
    NoiseTuning {
        scales,
        log_likelihood: stats.iter().map(|s| s.0).collect(),
        nis_mean: stats.iter().map(|s| s.1).collect(),
        chosen_scale: if evidence > 0.0 { best_k } else { 1.0 },
        evidence,
        with_effects: None,
    }
}

/// Writes diagnosis.json, nav_before.txt, nav_after.txt, the report and the augmented
/// configuration into `dir`.
pub fn write_outputs(
    dir: &std::path::Path,
    p: &Prepared,
    d: &DiagnoseOutput,
    config: Option<&std::path::Path>,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    output::write_nav(&dir.join("nav_before.txt"), &d.before.nav, p.week)?;
    output::write_nav(&dir.join("nav_after.txt"), &d.after.nav, p.week)?;
    let jp = dir.join("diagnosis.json");
    std::fs::write(&jp, serde_json::to_string_pretty(&d.diagnosis)?)
        .with_context(|| format!("writing {}", jp.display()))?;
    if let Some(c) = config {
        report::write_augmented_config(dir, c, &d.diagnosis)?;
    }
    report::write_report(dir, p, d)?;
    Ok(())
}

/// Runs `host-sim diagnose`.
pub fn run(args: DiagnoseArgs) -> anyhow::Result<()> {
    let p = prepare(&args.run)?;
    println!("{}", p.description);
    let dopts = DiagnoseOptions {
        max_effects: args.max_effects,
        candidates: None,
        tune_noise: args.tune_noise,
    };
    let d = diagnose(&p, &dopts)?;
    let dir: &PathBuf = &args.run.out;
    write_outputs(dir, &p, &d, Some(&args.run.config))?;
    let dg = &d.diagnosis;
    println!("{}", dg.verdict);
    for w in &dg.warnings {
        println!("warning: {w}");
    }
    for e in &dg.added_effects {
        println!(
            "added {}: estimate {:?} sigma {:?} [{}] evidence {:.1}",
            e.name, e.estimate, e.sigma, e.unit, e.evidence
        );
    }
    println!(
        "outage position error ({}): before {:.3} m, after {:.3} m",
        dg.error_before.reference,
        dg.error_before.outage_max_3d_rms_m,
        dg.error_after.outage_max_3d_rms_m
    );
    println!("wrote {}", dir.display());
    Ok(())
}
