#![doc = include_str!("../README.md")]
//!
//! # How the diagnosis works
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
//! 4. Held-out windows ([`validate::plan_windows`]): the imposed outages, the gaps of the GNSS
//!    file, and, when those number fewer than [`validate::TARGET_WINDOWS`], windows of up to
//!    20 s the diagnosis withholds itself, spread over the drive. Every search run withholds
//!    them all (one fold: every candidate is judged on every window); the final run uses every
//!    fix. A window's error is the RMS 3D distance of the predicted antenna position from
//!    its withheld fixes and the first fix after it.
//! 5. Selection, repeated while an effect pays: every remaining candidate is re-run with its
//!    block put into the current model (in parallel, rayon) and decided ([`decide`]):
//!    ADDED (or eligible) when (a) its innovation log-likelihood gain exceeds the BIC penalty
//!    `k/2 ln n`, (b) some state of its estimate is at least [`validate::MIN_Z`] = 2 sigma
//!    from zero, and (c) its held-out window errors are significantly lower than the current
//!    model's, paired per window ([`validate::compare_windows`]: Wilcoxon signed-rank test of
//!    the log error ratios, one-sided 5 %); REFUSED when they are significantly higher;
//!    NOT SIGNIFICANT otherwise. The eligible candidate with the largest `gain - penalty` is
//!    added; when the next eligible one trails by less than
//!    [`DiagnoseOptions::ambiguity_margin`] (3 nats: a likelihood ratio of 20, "strong" on the
//!    Kass-Raftery scale) the two are reported as "ambiguous between A and B" and the one
//!    with the larger held-out gain is added; the note gives the pair's joint fit (each
//!    block's significance beside the other: "the same signal" when neither keeps a state
//!    2 sigma from zero). The noise steps (tuned, re-tuned) are kept
//!    unless their held-out errors are significantly higher. A paying candidate left out is
//!    unexplained gain; with it (or a NIS mean above its band) the diagnosis says where in
//!    time the misfit sits ([`stats::misfit_spans`]). A GNSS-side block (`gnss_position_gm`,
//!    [`is_noise_like`]) has its prior (sigma, correlation time) fitted by likelihood jointly
//!    with a factor on the GNSS sigma scale; when its evidence pays it is eligible on
//!    significantly lower windows, or, when those do not tell, on fixes withheld one at a
//!    time ([`validate::interleaved_fixes`]), and never when either is significantly higher;
//!    a model with the block predicts a withheld fix as the antenna position plus the
//!    block's estimate ([`spill::predict_withheld_fixes`]).
//! 6. Every model change (tuned noise, each effect, the re-tuned noise) is a [`Step`] with its
//!    errors and its paired held-out comparison with the model before it.
//! 7. Effects not added get a detectability bound ([`validate::detectability_bound`]): the
//!    magnitude per state that would have been found on this drive; "none detectable" when
//!    nothing was added.
//! 8. A time offset moves the output onto the GNSS clock: `nav_after.txt` is stamped
//!    `IMU time - estimate` ([`Diagnosis::output_clock_shift_s`]) and `augmented.toml` carries
//!    the correction as `imu.time_offset_s`. The metrics against a simulated truth (which is on
//!    the IMU clock) are computed before the shift.
//!
//! Cost: per round one filter run per candidate, plus the noise tuning (about 30 runs before
//! and 30 with the effects), the search's base run when the diagnosis withholds windows, and
//! the final run (on a clean 40-minute 200 Hz drive 47 runs: the base, its search run, 38
//! noise trials, 7 candidates; see `docs/benchmarks.md`). A run asked for again (the same
//! model on the same data: a refined noise factor on a trial already run, a candidate whose
//! options equal an earlier round's) is answered from a memo of the last runs instead of run
//! again (on the real drive's default command 12 of its 265 runs repeat an earlier one; the
//! memo answers 9: a scored search run needs its navigation, which a run kept for its
//! innovations has not). Runs whose navigation is not
//! read record none, and no run computes its navigation records' standard deviations
//! (nothing the diagnosis writes reads them).
//! Memory: the IMU record is decoded once into a temporary file ([`imu_cache`], 72 bytes a
//! sample on disk) and every run streams from it, a bias step removed and a held time offset
//! applied as the samples are read; in memory stay the fixes and the truth when given (a
//! simulated case's, at its own rate); `--smooth` reads each search run's samples into memory
//! for the smoother. The runs' navigation
//! records go to temporary files ([`spill`], removed at the end, also on error); what the
//! diagnosis keeps of a run grows with the GNSS fixes only: its innovation records and, for a
//! search run, its navigation record nearest each fix (about 320 bytes a fix for each run
//! kept: the base and final runs, the current model's and each candidate's of a round, and
//! the memo's last runs, at most 32 of them and 2^17 innovation records in all).
//! The filter's state count is a compile-time constant: [`nav_engine::run::run_filter`] dispatches
//! layouts with extra blocks on their dimension (16 to [`MAX_EXTRA_DIM`] states).
//!
//! Units of the estimates ([`AddedEffect::estimate`], the blocks' states, SI):
//! `accel_scale_factor`, `gyro_scale_factor`: dimensionless (x, y, z; 1e-6 = 1 ppm);
//! `accel_misalignment`, `gyro_misalignment`: rad, `[m_xy, m_xz, m_yx, m_yz, m_zx, m_zy]`
//! (m_ij: fraction of the body-axis-j input sensed by sensor i); `lever_arm`: m, body FRD,
//! the correction to the configured antenna lever arm; `time_offset`: s, a fix tagged t is
//! the antenna at IMU time t + estimate; `accel_temperature_bias`: m/s^2/degC;
//! `gyro_temperature_bias`: rad/s/degC; `gyro_g_sensitivity`: rad/s per m/s^2 (diagonal);
//! `imu_clock_drift`: `[dt_0 s, rate s/s]`, the fix tagged t is the antenna at IMU time
//! `t + dt_0 + rate (t - t_0)`; `gnss_position_gm`: m, NED, the GNSS position error at the
//! end. A bias step ([`changepoint`]) is reported apart ([`Diagnosis::bias_step`]).
#![deny(missing_docs)]

pub mod changepoint;
mod error;
pub mod imu_cache;
mod memo;
pub mod noise;
mod partial;
pub mod prior;
pub mod report;
pub mod spill;
pub mod stats;
pub mod validate;

mod finish;
mod gnss_error;
mod round;
mod search;
mod types;

use nav_core::model::Block;
use nav_core::types::ImuSample;
use rayon::prelude::*;
use serde::Serialize;
use std::sync::Arc;

pub use error::DiagnoseError;
use finish::*;
use imu_cache::{Adjust, Case, Data, ImuCache};
use nav_engine::metrics::{self, Metrics};
use nav_engine::run::prepare::Prepared;
use nav_engine::run::{output, run_filter, Outage, RunOptions, RunOutput, MAX_EXTRA_DIM};
pub use noise::{NoiseFactors, NoiseTrial, NoiseTuning};
pub use partial::{
    partial_markdown, write_partial_files, Interrupted, Outcome, PartialDiagnosis, PARTIAL_SUFFIX,
};
use partial::{BeforeSearch, Checkpoint};
pub use prior::{candidates, options_with};
pub use round::*;
pub use search::*;
pub use stats::{regressor_correlation, residual_stats, ResidualStats, Whiteness};
pub use types::*;
pub use validate::{
    HeldoutComparison, HeldoutPlan, HeldoutVerdict, HeldoutWindow, StepErrors, WindowKind,
};

/// Diagnoses a prepared case (see the module notes): its IMU samples are written into the
/// diagnosis's record file first ([`imu_cache`]), then [`diagnose_cached`]. A diagnosis
/// stopped by SIGINT/SIGTERM is the error [`DiagnoseError::Interrupted`].
pub fn diagnose(p: &Prepared, dopts: &DiagnoseOptions) -> Result<DiagnoseOutput, DiagnoseError> {
    let folder = spill::temp_folder()?;
    let imu = ImuCache::from_case(&folder, &p.case)?;
    let case = nav_engine::run::CaseData {
        imu: Vec::new(),
        gnss: p.case.gnss.clone(),
        truth: p.case.truth.clone(),
        imu_origin: None,
    };
    match diagnose_cached(case, &p.opts, imu, dopts, &mut |_, _| {})? {
        Outcome::Complete(d) => Ok(*d),
        Outcome::Interrupted(i) => Err(DiagnoseError::Interrupted { signal: i.signal }),
    }
}

/// Diagnoses the fixes and truth of `case` (its IMU list unused) with the IMU record `imu`
/// and the configuration's options `opts` (see the module notes); the diagnosis's files go
/// into the record's temporary folder. `on_round` is told of each search round once it is
/// decided (its number from 1, the round).
///
/// Stopped by SIGINT/SIGTERM (inside a [`nav_engine::run::interrupt::Stoppable`] section:
/// the runs end at their next IMU read), it returns [`Outcome::Interrupted`] with the rounds
/// decided before the signal ([`PartialDiagnosis`]; none when the first round was not
/// decided): a round whose runs the signal cut is never among them.
pub fn diagnose_cached(
    case: nav_engine::run::CaseData,
    opts: &RunOptions,
    imu: ImuCache,
    dopts: &DiagnoseOptions,
    on_round: &mut dyn FnMut(usize, &Round),
) -> Result<Outcome, DiagnoseError> {
    let mut cp = Checkpoint::new(on_round);
    let res = search_and_finish(case, opts, imu, dopts, &mut cp);
    // a stop requested at any point: the runs since the last decided round may be cut (an
    // error, or a result of cut runs), whatever `res` is
    match nav_engine::run::interrupt::requested() {
        Some(sig) => Ok(Outcome::Interrupted(Box::new(
            cp.interrupted(nav_engine::run::interrupt::signal_name(sig)),
        ))),
        None => res.map(|d| Outcome::Complete(Box::new(d))),
    }
}

/// The error [`DiagnoseError::Interrupted`] once SIGINT/SIGTERM asked for a stop.
fn stop_requested() -> Result<(), DiagnoseError> {
    match nav_engine::run::interrupt::requested() {
        Some(sig) => Err(DiagnoseError::Interrupted {
            signal: nav_engine::run::interrupt::signal_name(sig),
        }),
        None => Ok(()),
    }
}

/// The diagnosis of [`diagnose_cached`]: the base run, the search (the decided rounds
/// recorded in `cp`), the final steps.
fn search_and_finish(
    case: nav_engine::run::CaseData,
    opts: &RunOptions,
    imu: ImuCache,
    dopts: &DiagnoseOptions,
    cp: &mut Checkpoint<'_>,
) -> Result<DiagnoseOutput, DiagnoseError> {
    let folder = imu.folder().clone();
    // the data with a step found after an added effect removed, when it is kept
    let late_data = std::cell::OnceCell::new();
    // the data with the kept step refitted beside an effect removed ([`refit_step_with_effect`])
    let refit_data = std::cell::OnceCell::new();
    let data = Data {
        case: Case::new(case, Arc::new(imu)),
        opts: opts.clone(),
    };
    let p = &data;
    let (before, before_nav, errors_before) =
        spill::run_to_file(&p.case, &p.opts, &folder, "before")?;
    stop_requested()?;
    let before = Arc::new(before);
    let fix_times: Vec<f64> = if p.case.gnss.is_empty() {
        before.innovations.iter().map(|r| r.t_s).collect()
    } else {
        p.case.gnss.iter().map(|f| f.t_s).collect()
    };
    let plan = validate::plan_windows(&fix_times, &p.opts.outages);
    let withheld = plan.withheld_outages();
    let interleaved = validate::interleaved_fixes(&fix_times, &plan.windows);
    let base_ctx = Ctx {
        p,
        dopts,
        plan,
        withheld,
        interleaved,
        folder,
        runs: Default::default(),
    };
    let all = dopts
        .candidates
        .clone()
        .unwrap_or_else(|| prior::candidates_with(p.case.imu.has_temperature(), &p.opts));
    let base = base_eval(&base_ctx, &before, &before_nav, &errors_before)?;
    let error_before = error_summary(
        &errors_before,
        validate::written_solution_vs_fixes_file(&before, &before_nav, &p.case.gnss)?,
    );
    cp.before = Some(BeforeSearch {
        plan: base_ctx.plan.clone(),
        candidates: validate::names(&all),
        windows: base.windows.clone(),
        residuals: residual_stats(&before.innovations),
        errors: error_before,
        nav: before_nav.clone(),
    });
    let found = find_bias_step(p, &before);
    // the search and the final model run on the data with the step removed when it is kept
    let (ctx, step) = judge_bias_step(base_ctx, &base, found.as_ref(), &all)?;
    let mut s = start_search(&ctx, &base, step)?;
    // a step the base model's misfit hid: looked for again after each added effect
    let mut ctx = ctx;
    let mut searched_with = 0;
    loop {
        let more = search_rounds(&ctx, &mut s, &all, true, &mut |s| cp.after_round(s));
        stop_requested()?;
        if s.added.len() > searched_with {
            searched_with = s.added.len();
            if let Some(stepped) = late_bias_step(&ctx, &mut s)? {
                ctx = Ctx {
                    p: late_data.get_or_init(|| stepped),
                    ..ctx
                };
            }
        }
        if !more {
            // no effect eligible beside a kept step: the step refitted with the strongest
            // paying candidate, judged together (once)
            match refit_step_with_effect(&ctx, &mut s)? {
                Some(stepped) => {
                    ctx = Ctx {
                        p: refit_data.get_or_init(|| stepped),
                        ..ctx
                    };
                }
                None => break,
            }
        }
    }
    if let Some(st) = s
        .last_noise_refusal
        .take()
        .filter(|_| s.pending_noise.is_some())
    {
        s.steps.push(st);
    }
    let final_opts = retune_noise(&ctx, &mut s);
    let held = hold_time_offset(&ctx, &mut s);
    let (ctx, final_opts) = match &held {
        Some((moved, o)) => (Ctx { p: moved, ..ctx }, o.clone()),
        None => (ctx, final_opts),
    };
    stop_requested()?;
    finish(
        &ctx,
        s,
        &all,
        &base,
        (before, before_nav, errors_before),
        (final_opts, error_before),
    )
}

/// Writes the diagnosis's files into `dir`: `diagnosis.json`, `nav_before.txt`,
/// `nav_after.txt`, `report.md` and, given the run configuration `config` (a project TOML),
/// `augmented.toml`. The plots `report.md` links are the caller's (`host-sim diagnose` draws
/// them).
pub fn write_files(
    dir: &std::path::Path,
    p: &Prepared,
    d: &DiagnoseOutput,
    config: Option<&std::path::Path>,
) -> Result<(), DiagnoseError> {
    std::fs::create_dir_all(dir).map_err(|source| DiagnoseError::CreateDir {
        path: dir.to_path_buf(),
        source,
    })?;
    output::write_nav_records(
        &dir.join("nav_before.txt"),
        d.before_nav.records()?,
        p.week,
        0.0,
    )?;
    // the after solution on the GNSS clock when a time offset was added (written record by
    // record from the file: no copy of the solution in memory); the base run's own records
    // unshifted (nothing changed) are nav_before.txt's bytes, copied instead of formatted
    let shift = d.after_nav_shift_s;
    let after = dir.join("nav_after.txt");
    if shift == 0.0 && d.after_nav.path() == d.before_nav.path() {
        let before = dir.join("nav_before.txt");
        std::fs::copy(&before, &after).map_err(|source| DiagnoseError::Write {
            path: after,
            source,
        })?;
    } else {
        output::write_nav_records(&after, d.after_nav.records()?, p.week, shift)?;
    }
    let jp = dir.join("diagnosis.json");
    std::fs::write(&jp, serde_json::to_string_pretty(&d.diagnosis)?)
        .map_err(|source| DiagnoseError::Write { path: jp, source })?;
    if let Some(c) = config {
        report::write_augmented_config(dir, c, &d.diagnosis)?;
    }
    report::write_report(dir, p, d)?;
    Ok(())
}
