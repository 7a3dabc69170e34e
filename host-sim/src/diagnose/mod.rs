//! `host-sim diagnose`: find the effects the error-state model lacks from a run's innovations,
//! add them when the data support them, and report the errors before and after.
//!
//! 1. Residual statistics of the base run ([`stats::ResidualStats`]): NIS mean against its
//!    chi-square band; per innovation component the autocorrelation, Ljung-Box Q and the
//!    Allan variance of the normalised innovations over clusters of fixes; and the correlation
//!    of the normalised innovations with each candidate effect's regressor.
//! 2. Noise model in the loop ([`noise`], default on): the IMU white-noise and bias PSDs are
//!    fitted per sensor by maximum innovation likelihood before the effect search (so an
//!    effect cannot absorb noise-model error), and re-fitted with the added effects.
//! 3. Candidates ([`prior`]): every effect block of the vocabulary ([`nav_core::model::EFFECT_BLOCKS`]) the
//!    model does not carry, or carries frozen (zero sigmas: a KF-GINS YAML with
//!    `gsstd = asstd = 0` declares no scale factor); the temperature blocks only when the IMU
//!    data carry a temperature column.
//! 4. Selection, repeated while an effect pays: every remaining candidate is re-run with its
//!    block put into the current model (in parallel, rayon). A candidate is ELIGIBLE when
//!    (a) its innovation log-likelihood gain exceeds the BIC penalty `k/2 ln n`; (b) its own
//!    estimate is significant: some state at least [`validate::MIN_Z`] = 2 sigma from zero
//!    (else its gain is reported as unexplained); (c) it passes the held-out check
//!    ([`validate`]): a lower outage error against the withheld fixes and no higher GNSS
//!    prior residual. The eligible candidate with the largest `gain - penalty` is added;
//!    when the next eligible one trails by less than [`DiagnoseOptions::ambiguity_margin`]
//!    (3 nats: a likelihood ratio of 20, "strong" on the Kass-Raftery scale) the two are
//!    reported as "ambiguous between A and B" and the one with the lower held-out outage error
//!    is added.
//! 5. Every model change (tuned noise, each effect, the re-tuned noise) is a [`Step`] with its
//!    errors; a change that would make the held-out outage error or the error with GNSS worse
//!    is not made, so after is never worse than before on the fixes.
//! 6. Effects not added get a detectability bound ([`validate::detectability_bound`]): the
//!    magnitude per state that would have been found on this drive; "none detectable" when
//!    nothing was added.
//! 7. A time offset moves the output onto the GNSS clock: `nav_after.txt` is stamped
//!    `IMU time - estimate` ([`Diagnosis::output_clock_shift_s`]) and `augmented.toml` carries
//!    the correction as `imu.time_offset_s`. The metrics against a simulated truth (which is on
//!    the IMU clock) are computed before the shift.
//!
//! Cost: per round one filter run per candidate, plus the noise tuning (about 30 runs before
//! and 30 with the effects) and the final run; see the README for a 40-minute 200 Hz drive.
//! The filter's state count is a compile-time constant: [`nav_engine::run::run_filter`] dispatches
//! layouts with extra blocks on their dimension (16 to [`MAX_EXTRA_DIM`] states).
//!
//! Units of the estimates ([`AddedEffect::estimate`], the blocks' states, SI):
//! `accel_scale_factor`, `gyro_scale_factor`: dimensionless (x, y, z; 1e-6 = 1 ppm);
//! `accel_misalignment`, `gyro_misalignment`: rad, `[m_xy, m_xz, m_yx, m_yz, m_zx, m_zy]`
//! (m_ij: fraction of the body-axis-j input sensed by sensor i); `lever_arm`: m, body FRD,
//! the correction to the configured antenna lever arm; `time_offset`: s, a fix tagged t is
//! the antenna at IMU time t + estimate; `accel_temperature_bias`: m/s^2/degC;
//! `gyro_temperature_bias`: rad/s/degC; `gyro_g_sensitivity`: rad/s per m/s^2 (diagonal).
pub mod noise;
pub mod prior;
pub mod report;
pub mod stats;
pub mod validate;

use std::path::PathBuf;

use anyhow::Context;
use nav_core::model::Block;
use rayon::prelude::*;
use serde::Serialize;
use std::sync::Arc;

use crate::run::cli::{execute, execute_case, prepare, Prepared, RunArgs};
use nav_engine::metrics::{self, Metrics};
use nav_engine::run::{output, run_filter, RunOptions, RunOutput, MAX_EXTRA_DIM};
pub use noise::{NoiseFactors, NoiseTrial, NoiseTuning};
pub use prior::{candidates, options_with};
pub use stats::{regressor_correlation, residual_stats, ResidualStats, Whiteness};
pub use validate::StepErrors;
/// Arguments of `host-sim diagnose`: the same as `run`, plus the search limits.
#[derive(clap::Args, Debug)]
pub struct DiagnoseArgs {
    /// Inputs as for `run`; `--out` receives diagnosis.json, nav_before.txt, nav_after.txt,
    /// report.md with its PNG plots, and the augmented configuration. `--smooth` scores the
    /// held-out check on the Rauch-Tung-Striebel smoothed solution of every candidate run (the
    /// outage fixes stay withheld from the filter and so from the smoother) instead of the
    /// forward one; the evidence stays the forward innovations' ([`DiagnoseOptions::smooth`]).
    #[command(flatten)]
    pub run: RunArgs,
    /// Largest number of effects to add.
    #[arg(long, default_value_t = 4)]
    pub max_effects: usize,
    /// Keep the configuration's IMU noise (by default the white-noise and bias PSDs are
    /// fitted per sensor by maximum innovation likelihood before and after the effect search).
    #[arg(long)]
    pub no_tune_noise: bool,
    /// Accepted for compatibility: noise tuning is the default.
    #[arg(long, hide = true)]
    pub tune_noise: bool,
    /// Evidence margin, nats, below which two eligible candidates are reported as ambiguous.
    #[arg(long, default_value_t = 3.0)]
    pub ambiguity_margin: f64,
}

/// Options of [`diagnose`].
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    /// Largest number of effects to add.
    pub max_effects: usize,
    /// Candidates to consider (`None`: [`candidates`] of the case).
    pub candidates: Option<Vec<Block>>,
    /// Fit the IMU noise levels ([`noise`]) before and after the effect search.
    pub tune_noise: bool,
    /// Evidence margin below which two eligible candidates are ambiguous, nats.
    pub ambiguity_margin: f64,
    /// Score the held-out check on the smoothed solutions (`--smooth`).
    pub smooth: bool,
}

impl Default for DiagnoseOptions {
    /// At most 4 effects, all applicable candidates, noise tuning on, margin 3 nats, scored
    /// on the forward solution.
    fn default() -> Self {
        Self {
            max_effects: 4,
            candidates: None,
            tune_noise: true,
            ambiguity_margin: 3.0,
            smooth: false,
        }
    }
}

/// The evidence for one candidate effect in one round of the search.
#[derive(Debug, Clone, Serialize)]
pub struct CandidateEvidence {
    /// Effect name (the vocabulary of issue 7).
    pub name: String,
    /// Whether the model carried the block frozen (zero sigmas) and the candidate frees it.
    pub freed: bool,
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
    /// Largest |estimate| / sigma over the states.
    pub max_z: f64,
    /// Detectability bound per state on this drive (see [`validate::detectability_bound`]).
    pub detectability_bound: Vec<f64>,
    /// Outage position error of the re-run (see [`outage_error_m`]), m.
    pub outage_error_m: Option<f64>,
    /// Errors of the re-run.
    pub errors: Option<StepErrors>,
    /// Why it is not eligible (None: eligible).
    pub refused: Option<String>,
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
    /// The effect added in this round (None: no candidate was eligible, search stopped).
    pub added: Option<String>,
    /// "ambiguous between A and B (margin nats)" when the two best eligible candidates were
    /// closer than the margin.
    pub ambiguous: Option<String>,
    /// Likelihood gain no eligible effect explains: the best paying candidate that was
    /// refused, with its gain minus penalty, nats, and the reason.
    pub unexplained: Option<String>,
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
    /// The strongest other paying candidate of that round and how many nats it trailed by.
    pub runner_up: Option<(String, f64)>,
    /// The other candidate when the choice was ambiguous (within the margin): this one was
    /// added for its lower held-out outage error.
    pub ambiguous_with: Option<String>,
    /// Whether it was a frozen block of the configuration, freed.
    pub freed: bool,
    /// Errors of the model before it was added.
    pub before: StepErrors,
    /// Errors with it added.
    pub after: StepErrors,
}

/// One model change of the diagnosis and its errors.
#[derive(Debug, Clone, Serialize)]
pub struct Step {
    /// What changed (`configuration` for the base model).
    pub label: String,
    /// Whether the change was kept.
    pub accepted: bool,
    /// Why not.
    pub reason: Option<String>,
    /// Errors of the model with the change.
    pub errors: StepErrors,
}

/// An effect that was not added, with what could have been seen.
#[derive(Debug, Clone, Serialize)]
pub struct Undetected {
    /// Effect name.
    pub name: String,
    /// SI unit.
    pub unit: String,
    /// Detectability bound per state ([`validate::detectability_bound`]).
    pub bound: Vec<f64>,
    /// The smallest of them: the smallest magnitude that would have been found.
    pub min_bound: f64,
    /// Its estimate when last tried, and why it was not added.
    pub estimate: Vec<f64>,
    /// Why it was not added.
    pub reason: String,
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
    /// Horizontal RMS of the written solution (nav_before.txt / nav_after.txt, on their
    /// clocks), moved to the antenna as the model places it (configured lever arm plus any
    /// estimate, [`validate::written_solution_vs_fixes_m`]), against the GNSS fixes outside
    /// the outages, m.
    pub output_vs_fixes_horizontal_rms_m: f64,
}

/// The diagnosis (diagnosis.json).
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// Effects added, in the order they were added (empty: none detectable).
    pub added_effects: Vec<AddedEffect>,
    /// "none detectable" or the names added (with "ambiguous between" notes).
    pub verdict: String,
    /// The noise tuning (absent with `--no-tune-noise`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_tuning: Option<NoiseTuning>,
    /// The final model's IMU noise PSDs (SI) when the tuning changed them:
    /// `[accel S_N, S_B, S_K, gyro S_N, S_B, S_K]`, x axis.
    pub final_noise_psd: Option<[f64; 6]>,
    /// The final model's GNSS `sigma_scale` (the configuration's times the tuned GNSS noise
    /// scale) when the tuning changed it.
    pub final_gnss_sigma_scale: Option<nav_io::SigmaScale>,
    /// Every model change in order, with its errors (the first is the configuration).
    pub steps: Vec<Step>,
    /// Effects not added, with their detectability bounds on this drive.
    pub undetected: Vec<Undetected>,
    /// Cautions about the diagnosis.
    pub warnings: Vec<String>,
    /// Candidates considered (frozen blocks of the configuration included).
    pub candidates_considered: Vec<String>,
    /// Residual statistics of the base model.
    pub residuals_before: ResidualStats,
    /// Residual statistics of the final model.
    pub residuals_after: ResidualStats,
    /// The search, round by round.
    pub rounds: Vec<Round>,
    /// Time added to the IMU time stamps of the after solution in `nav_after.txt`, s: minus
    /// the time offset estimate (the output on the GNSS clock), 0 without one.
    pub output_clock_shift_s: f64,
    /// Position errors of the base model.
    pub error_before: ErrorSummary,
    /// Position errors of the final model.
    pub error_after: ErrorSummary,
    /// Full error metrics of the base run (vs truth, else vs GNSS withheld in imposed
    /// outages).
    pub errors_before: Metrics,
    /// Full error metrics of the final model.
    pub errors_after: Metrics,
}

/// Result of [`diagnose`] with the two runs.
pub struct DiagnoseOutput {
    /// The diagnosis (diagnosis.json).
    pub diagnosis: Diagnosis,
    /// The base run (shared: the search starts from it without a copy).
    pub before: Arc<RunOutput>,
    /// The run of the final model (the base run again when nothing changed), on the IMU
    /// clock (`nav_after.txt` adds [`Diagnosis::output_clock_shift_s`]).
    pub after: Arc<RunOutput>,
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

fn error_summary(m: &Metrics, output_vs_fixes: f64) -> ErrorSummary {
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
        output_vs_fixes_horizontal_rms_m: output_vs_fixes,
    }
}

fn effect_values(out: &RunOutput, name: &str) -> (Vec<f64>, Vec<f64>) {
    out.final_effects
        .iter()
        .find(|e| e.name == name)
        .map_or((Vec::new(), Vec::new()), |e| {
            (e.value.clone(), e.std.clone())
        })
}

fn dim_of(o: &RunOptions) -> usize {
    o.model.layout().dim() + o.extra_blocks.iter().map(|b| b.dim()).sum::<usize>()
}

/// A run with its metrics and errors.
type Eval = (Arc<RunOutput>, Metrics, StepErrors);

/// Navigation record rate of the search's runs, Hz: enough for the metrics' interpolation
/// (records at most 0.05 s apart), an eighth of the memory of every epoch at 200 Hz.
pub const SEARCH_NAV_RATE_HZ: f64 = 25.0;

/// Options of a search run: navigation recorded at [`SEARCH_NAV_RATE_HZ`] (when the IMU is
/// faster), no epoch records (the estimates come from the final state).
pub fn search_recording(o: &RunOptions) -> RunOptions {
    let mut o = o.clone();
    o.record.nav_rate_hz = Some(
        o.record
            .nav_rate_hz
            .map_or(SEARCH_NAV_RATE_HZ, |r| r.min(SEARCH_NAV_RATE_HZ)),
    );
    o.record.epoch_rate_hz = Some(0.0);
    o
}

fn evaluate(p: &Prepared, o: &RunOptions, smooth: bool) -> Result<Eval, nav_engine::run::RunError> {
    let mut ro = search_recording(o);
    ro.smoother_history |= smooth;
    let mut out = run_filter(&p.case, &ro)?;
    let m = metrics::compute(&out, p.case.truth.as_deref());
    let mut e = validate::step_errors(&out, &m);
    e.written_vs_fixes_m = validate::written_solution_vs_fixes_m(&out, &p.case.gnss);
    if smooth {
        // a run the smoother refuses keeps None: scored on the forward solution
        if let Ok((so, _, _)) = nav_engine::smooth::apply::smooth_run(&p.case, &out) {
            e.heldout_outage_smoothed_m = validate::heldout_outage_error_m(&so);
        }
        out.history = None;
    }
    Ok((Arc::new(out), m, e))
}

/// Diagnoses a prepared case (see the module notes).
pub fn diagnose(p: &Prepared, dopts: &DiagnoseOptions) -> anyhow::Result<DiagnoseOutput> {
    let (before, errors_before) = execute(p, &mut |_, _| {})?;
    let before = Arc::new(before);
    let residuals_before = residual_stats(&before.innovations);
    let mut se_before = validate::step_errors(&before, &errors_before);
    se_before.written_vs_fixes_m = validate::written_solution_vs_fixes_m(&before, &p.case.gnss);
    if dopts.smooth {
        // the base model's smoothed held-out error (one more run with the smoother's history)
        se_before.heldout_outage_smoothed_m =
            evaluate(p, &p.opts, true)?.2.heldout_outage_smoothed_m;
    }
    let all = dopts
        .candidates
        .clone()
        .unwrap_or_else(|| candidates(&p.case, &p.opts));
    let mut steps = vec![Step {
        label: "configuration".into(),
        accepted: true,
        reason: None,
        errors: se_before,
    }];
    let mut warnings = Vec::new();
    if se_before.heldout_outage_m.is_none() {
        warnings.push(
            "no imposed outages: the held-out check uses only the GNSS prior residuals; impose \
             outages (--outage, --periodic-outage) for a prediction check on withheld fixes"
                .to_string(),
        );
    }

    // the noise model: fitted first, then put into the model in competition with the
    // effects (it is adopted in the round where its evidence beats the best eligible effect's,
    // so neither absorbs the other)
    let mut base_opts = p.opts.clone();
    let mut cur: Eval = (before.clone(), errors_before.clone(), se_before);
    let mut noise_tuning = if dopts.tune_noise {
        Some(noise::tune(&p.case, &p.opts, &residuals_before))
    } else {
        None
    };
    let mut pending_noise = noise_tuning
        .as_ref()
        .map(|t| t.chosen)
        .filter(|k| !k.is_one());
    let mut last_noise_refusal: Option<Step> = None;
    let mut added: Vec<Block> = Vec::new();
    let mut added_info: Vec<AddedEffect> = Vec::new();
    let mut rounds: Vec<Round> = Vec::new();
    while added.len() < dopts.max_effects {
        let cur_opts = options_with(&base_opts, &added);
        let dim_now = dim_of(&cur_opts);
        let remaining: Vec<Block> = all
            .iter()
            .copied()
            .filter(|b| {
                !added.contains(b) && dim_now + prior::added_dim(&cur_opts, *b) <= MAX_EXTRA_DIM
            })
            .collect();
        if remaining.is_empty() {
            break;
        }
        let cur_ll = cur.2.log_likelihood;
        let cur_se = cur.2;
        let n_meas = residual_stats(&cur.0.innovations)
            .scalar_measurements
            .max(2) as f64;
        let cur_run = &cur.0;
        let results: Vec<(CandidateEvidence, Option<Eval>)> = remaining
            .par_iter()
            .map(|&b| {
                let (rc, n) = regressor_correlation(b, &p.case.imu, cur_run);
                let penalty = 0.5 * b.dim() as f64 * n_meas.ln();
                let mut ev = CandidateEvidence {
                    name: b.name().to_string(),
                    freed: prior::is_frozen(&cur_opts, b),
                    regressor_correlation: rc,
                    correlation_z: rc * (n as f64).sqrt(),
                    delta_log_likelihood: None,
                    bic_penalty: penalty,
                    evidence: None,
                    estimate: Vec::new(),
                    sigma: Vec::new(),
                    max_z: 0.0,
                    detectability_bound: Vec::new(),
                    outage_error_m: None,
                    errors: None,
                    refused: None,
                    note: None,
                };
                let opts = options_with(&cur_opts, &[b]);
                match evaluate(p, &opts, dopts.smooth) {
                    Ok(r) => {
                        let d = r.2.log_likelihood - cur_ll;
                        ev.delta_log_likelihood = Some(d);
                        ev.evidence = Some(d - penalty);
                        (ev.estimate, ev.sigma) = effect_values(&r.0, b.name());
                        ev.max_z = validate::max_z(&ev.estimate, &ev.sigma);
                        ev.detectability_bound = validate::detectability_bound(&ev.sigma, penalty);
                        ev.outage_error_m = Some(outage_error_m(&r.1));
                        ev.errors = Some(r.2);
                        ev.refused = if d - penalty <= 0.0 {
                            Some("likelihood gain below the BIC penalty".into())
                        } else if ev.max_z < validate::MIN_Z {
                            Some(format!(
                                "estimate not significant (largest |estimate|/sigma {:.2} < {})",
                                ev.max_z,
                                validate::MIN_Z
                            ))
                        } else {
                            validate::check_heldout(&r.2, &cur_se).err()
                        };
                        (ev, Some(r))
                    }
                    Err(e) => {
                        ev.note = Some(e.to_string());
                        ev.refused = Some(format!("run failed: {e}"));
                        (ev, None)
                    }
                }
            })
            .collect();
        let mut order: Vec<usize> = (0..results.len()).collect();
        let key = |i: &usize| results[*i].0.evidence.unwrap_or(f64::NEG_INFINITY);
        order.sort_by(|a, b| key(b).total_cmp(&key(a)));
        let eligible: Vec<usize> = order
            .iter()
            .copied()
            .filter(|&i| results[i].0.refused.is_none() && results[i].1.is_some())
            .collect();
        let mut round = Round {
            model_effects: validate::names(&added),
            log_likelihood: cur_ll,
            candidates: order.iter().map(|&i| results[i].0.clone()).collect(),
            added: None,
            ambiguous: None,
            unexplained: None,
        };
        // the strongest paying candidate that was refused: gain no effect explains
        if let Some(&i) = order.iter().find(|&&i| {
            results[i].0.refused.is_some() && results[i].0.evidence.is_some_and(|e| e > 0.0)
        }) {
            let c = &results[i].0;
            if eligible.first().is_none_or(|&j| key(&j) < key(&i)) {
                round.unexplained = Some(format!(
                    "{} ({:.1} nats): {}",
                    c.name,
                    c.evidence.unwrap_or(0.0),
                    c.refused.as_deref().unwrap_or("")
                ));
            }
        }
        if let Some(k) = pending_noise {
            let mut o = cur_opts.clone();
            k.apply(&mut o);
            let params = k.params();
            let label = format!("noise tuned: {}", k.describe());
            match evaluate(p, &o, dopts.smooth) {
                Ok(ev) => {
                    let pen = 0.5 * params as f64 * n_meas.ln();
                    let evidence = ev.2.log_likelihood - cur_ll - pen;
                    let check = if evidence > 0.0 {
                        validate::check_heldout(&ev.2, &cur_se)
                    } else {
                        Err("likelihood gain below the BIC penalty".into())
                    };
                    let beats = eligible.first().is_none_or(|&j| evidence > key(&j));
                    match check {
                        Ok(()) if beats => {
                            steps.push(Step {
                                label,
                                accepted: true,
                                reason: None,
                                errors: ev.2,
                            });
                            round.added = Some(format!("noise ({evidence:.1} nats)"));
                            rounds.push(round);
                            if let Some(t) = noise_tuning.as_mut() {
                                t.adopted = true;
                            }
                            k.apply(&mut base_opts);
                            pending_noise = None;
                            last_noise_refusal = None;
                            cur = ev;
                            continue;
                        }
                        Ok(()) => {}
                        Err(why) => {
                            last_noise_refusal = Some(Step {
                                label,
                                accepted: false,
                                reason: Some(why),
                                errors: ev.2,
                            })
                        }
                    }
                }
                Err(e) => {
                    warnings.push(format!("tuned noise run failed: {e}"));
                    pending_noise = None;
                }
            }
        }
        let Some(&top) = eligible.first() else {
            rounds.push(round);
            break;
        };
        let mut pick = top;
        let mut ambiguous_with = None;
        if let Some(&second) = eligible.get(1) {
            let margin = key(&top) - key(&second);
            if margin < dopts.ambiguity_margin {
                let h = |i: usize| {
                    results[i]
                        .1
                        .as_ref()
                        .and_then(|r| r.2.scored_heldout_m())
                        .unwrap_or(f64::INFINITY)
                };
                if h(second) < h(top) {
                    pick = second;
                }
                let other = if pick == top { second } else { top };
                ambiguous_with = Some(results[other].0.name.clone());
                round.ambiguous = Some(format!(
                    "ambiguous between {} and {} ({margin:.1} nats); added {} (lower held-out \
                     outage error)",
                    results[top].0.name, results[second].0.name, results[pick].0.name
                ));
            }
        }
        let c = results[pick].0.clone();
        let Some(b) = Block::effect_from_name(&c.name) else {
            rounds.push(round);
            break;
        };
        let Some(run) = results.into_iter().nth(pick).and_then(|r| r.1) else {
            rounds.push(round);
            break;
        };
        let runner_up = round
            .candidates
            .iter()
            .find(|x| x.name != c.name && x.evidence.is_some_and(|e| e > 0.0))
            .map(|x| {
                (
                    x.name.clone(),
                    c.evidence.unwrap_or(0.0) - x.evidence.unwrap_or(0.0),
                )
            });
        round.added = Some(c.name.clone());
        rounds.push(round);
        steps.push(Step {
            label: format!("+ {}", c.name),
            accepted: true,
            reason: None,
            errors: run.2,
        });
        added_info.push(AddedEffect {
            name: c.name.clone(),
            estimate: c.estimate.clone(),
            sigma: c.sigma.clone(),
            unit: b.unit().to_string(),
            evidence: c.evidence.unwrap_or(0.0),
            runner_up,
            ambiguous_with,
            freed: c.freed,
            before: cur_se,
            after: run.2,
        });
        added.push(b);
        cur = run;
    }

    if let Some(st) = last_noise_refusal.filter(|_| pending_noise.is_some()) {
        steps.push(st);
    }
    // the noise re-fitted with the effects in the model, from the configuration's noise
    let mut final_opts = options_with(&base_opts, &added);
    if let Some(t) = noise_tuning.as_mut().filter(|_| !added.is_empty()) {
        let with = options_with(&p.opts, &added);
        if let Ok(base_with) = run_filter(&p.case, &search_recording(&with)) {
            let mut t2 = noise::tune(&p.case, &with, &residual_stats(&base_with.innovations));
            let mut o = with.clone();
            t2.chosen.apply(&mut o);
            let label = format!("noise re-tuned with the effects: {}", t2.chosen.describe());
            let same =
                o.filter == final_opts.filter && o.gnss_sigma_scale == final_opts.gnss_sigma_scale;
            if !same {
                match evaluate(p, &o, dopts.smooth) {
                    Ok(ev) => match validate::check_heldout(&ev.2, &cur.2) {
                        Ok(()) => {
                            steps.push(Step {
                                label,
                                accepted: true,
                                reason: None,
                                errors: ev.2,
                            });
                            t2.adopted = true;
                            final_opts = o;
                            cur = ev;
                        }
                        Err(why) => steps.push(Step {
                            label,
                            accepted: false,
                            reason: Some(why),
                            errors: ev.2,
                        }),
                    },
                    Err(e) => warnings.push(format!("re-tuned noise run failed: {e}")),
                }
            } else {
                t2.adopted = t.adopted;
            }
            t.with_effects = Some(Box::new(t2));
        }
    }
    let final_gnss_sigma_scale = (final_opts.gnss_sigma_scale != p.opts.gnss_sigma_scale)
        .then_some(final_opts.gnss_sigma_scale);
    let changed =
        final_opts.filter != p.opts.filter || final_gnss_sigma_scale.is_some() || !added.is_empty();
    let (after, errors_after) = if changed {
        execute_case(&p.case, &final_opts, &mut |_, _| {})
            .map(|(r, m)| (Arc::new(r), m))
            .unwrap_or((cur.0, cur.1))
    } else {
        (before.clone(), errors_before.clone())
    };
    // the added effects' estimates in the final model
    for e in &mut added_info {
        let (est, sig) = effect_values(&after, &e.name);
        if !est.is_empty() {
            e.estimate = est;
            e.sigma = sig;
        }
    }
    let residuals_after = residual_stats(&after.innovations);
    let output_clock_shift_s = added_info
        .iter()
        .find(|e| e.name == Block::TimeOffset.name())
        .and_then(|e| e.estimate.first())
        .map_or(0.0, |dt| -dt);
    let ovf = |run: &RunOutput| validate::written_solution_vs_fixes_m(run, &p.case.gnss);
    let error_before = error_summary(&errors_before, ovf(&before));
    let error_after = error_summary(&errors_after, ovf(&after));

    // what was not added, and what could have been seen
    let mut undetected = Vec::new();
    for b in &all {
        if added.contains(b) {
            continue;
        }
        let last = rounds
            .iter()
            .rev()
            .flat_map(|r| r.candidates.iter())
            .find(|c| c.name == b.name() && !c.sigma.is_empty());
        if let Some(c) = last {
            undetected.push(Undetected {
                name: c.name.clone(),
                unit: b.unit().to_string(),
                bound: c.detectability_bound.clone(),
                min_bound: validate::min_bound(&c.detectability_bound),
                estimate: c.estimate.clone(),
                reason: c.refused.clone().unwrap_or_else(|| "not reached".into()),
            });
        }
    }
    let mut verdict = if added_info.is_empty() {
        "none detectable".to_string()
    } else {
        added_info
            .iter()
            .map(|e| e.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    };
    if let Some(g) = final_gnss_sigma_scale {
        let k = g.horizontal / p.opts.gnss_sigma_scale.horizontal;
        let kv = g.vertical / p.opts.gnss_sigma_scale.vertical;
        let s = format!("GNSS noise scale x{k:.2} horizontal, x{kv:.2} vertical");
        verdict = if added_info.is_empty() {
            s
        } else {
            format!("{verdict}; {s}")
        };
    }
    for r in &rounds {
        if let Some(a) = &r.ambiguous {
            verdict.push_str(&format!("; {a}"));
        }
    }
    if let Some(u) = rounds.last().and_then(|r| r.unexplained.as_ref()) {
        warnings.push(format!("likelihood gain no effect explains: {u}"));
    }
    let (nis, dim) = (residuals_before.nis_mean, residuals_before.nis_expected);
    if dim > 0.0 && !(0.5 * dim..=2.0 * dim).contains(&residuals_after.nis_mean) {
        let after_nis = residuals_after.nis_mean;
        warnings.push(format!(
            "model inconsistent with the data even after the diagnosis: NIS mean {after_nis:.1} \
             (base {nis:.1}) for an expected {dim:.1}; the inconsistency is not only the IMU \
             noise levels (GNSS sigmas, vibration, unmodelled effects)"
        ));
    }
    if residuals_before.updates < 30 {
        warnings.push(format!(
            "only {} GNSS updates: little evidence either way",
            residuals_before.updates
        ));
    }
    let final_noise_psd = (final_opts.filter != options_with(&p.opts, &added).filter).then(|| {
        let f = &final_opts.filter;
        [
            f.accel.s_n[0],
            f.accel.s_b[0],
            f.accel.s_k[0],
            f.gyro.s_n[0],
            f.gyro.s_b[0],
            f.gyro.s_k[0],
        ]
    });
    Ok(DiagnoseOutput {
        diagnosis: Diagnosis {
            added_effects: added_info,
            verdict,
            noise_tuning,
            final_noise_psd,
            final_gnss_sigma_scale,
            steps,
            undetected,
            warnings,
            candidates_considered: validate::names(&all),
            residuals_before,
            residuals_after,
            rounds,
            output_clock_shift_s,
            error_before,
            error_after,
            errors_before,
            errors_after,
        },
        before,
        after,
    })
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
    // the after solution on the GNSS clock when a time offset was added (written record by
    // record: no second copy of the solution)
    let shift = d.diagnosis.output_clock_shift_s;
    output::write_nav_with(&dir.join("nav_after.txt"), &d.after.nav, p.week, shift)?;
    let jp = dir.join("diagnosis.json");
    std::fs::write(&jp, serde_json::to_string_pretty(&d.diagnosis)?)
        .with_context(|| format!("writing {}", jp.display()))?;
    if let Some(c) = config {
        report::write_augmented_config(dir, c, &d.diagnosis)?;
    }
    report::write_report(dir, p, d)?;
    Ok(())
}

/// `[a, b, c]` with 4 significant digits (the console summary; `diagnosis.json` keeps full
/// precision).
fn short_list(v: &[f64]) -> String {
    let items: Vec<String> = v
        .iter()
        .map(|x| {
            let a = x.abs();
            if a == 0.0 || (1e-3..1e4).contains(&a) {
                format!(
                    "{:.*}",
                    (3 - a.log10().floor().max(-3.0) as i32).max(0) as usize,
                    x
                )
            } else {
                format!("{x:.3e}")
            }
        })
        .collect();
    format!("[{}]", items.join(", "))
}

/// Runs `host-sim diagnose`.
pub fn run(args: DiagnoseArgs) -> anyhow::Result<()> {
    let p = prepare(&args.run)?;
    println!("{}", p.description);
    let dopts = DiagnoseOptions {
        max_effects: args.max_effects,
        candidates: None,
        tune_noise: !args.no_tune_noise,
        ambiguity_margin: args.ambiguity_margin,
        smooth: args.run.smooth,
    };
    let d = diagnose(&p, &dopts)?;
    let dir: &PathBuf = &args.run.out;
    write_outputs(dir, &p, &d, Some(&args.run.config))?;
    let dg = &d.diagnosis;
    println!("effects the model lacks: {}", dg.verdict);
    for w in &dg.warnings {
        println!("warning: {w}");
    }
    for e in &dg.added_effects {
        println!(
            "added {}: estimate {} sigma {} [{}] evidence {:.1}",
            e.name,
            short_list(&e.estimate),
            short_list(&e.sigma),
            e.unit,
            e.evidence
        );
    }
    for u in &dg.undetected {
        println!(
            "not added {}: detectability bound {:.3e} [{}] ({})",
            u.name, u.min_bound, u.unit, u.reason
        );
    }
    for st in &dg.steps {
        let e = &st.errors;
        println!(
            "step {}{}: held-out outage error {} m, GNSS prior residual {:.3} m, written solution vs fixes {:.3} m, NIS {:.2}{}",
            st.label,
            if st.accepted { "" } else { " (refused)" },
            e.heldout_outage_m.map_or("-".into(), |x| format!("{x:.3}")),
            e.gnss_prior_horizontal_rms_m,
            e.written_vs_fixes_m,
            e.nis_mean,
            st.reason
                .as_ref()
                .map_or(String::new(), |r| format!(": {r}"))
        );
    }
    println!(
        "outage position error ({}): before {:.3} m, after {:.3} m; GNSS prior residual (horizontal): before {:.3} m, after {:.3} m; written solution vs the used fixes (horizontal, posterior: favours no time offset): before {:.3} m, after {:.3} m{}",
        dg.error_before.reference,
        dg.error_before.outage_max_3d_rms_m,
        dg.error_after.outage_max_3d_rms_m,
        dg.error_before.gnss_residual_horizontal_rms_m,
        dg.error_after.gnss_residual_horizontal_rms_m,
        dg.error_before.output_vs_fixes_horizontal_rms_m,
        dg.error_after.output_vs_fixes_horizontal_rms_m,
        if dg.output_clock_shift_s != 0.0 {
            format!(" (nav_after.txt on the GNSS clock: IMU time {:+.4} s)", dg.output_clock_shift_s)
        } else {
            String::new()
        }
    );
    println!("wrote {}", dir.display());
    Ok(())
}
