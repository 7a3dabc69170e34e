//! The options of the diagnosis and what it reports: the candidates' evidence per round, the
//! added effects, the steps and the diagnosis itself.
use super::*;

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
    /// Effect name (`Block::name` of one of `nav_core::model::EFFECT_BLOCKS`).
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
    /// Its held-out windows against the current model's, paired (None: not run).
    pub heldout: Option<HeldoutComparison>,
    /// The re-run's error in each held-out window, m, in the order of
    /// [`Diagnosis::heldout_windows`] (NaN: no fix to judge the window; empty: not run).
    pub window_errors_m: Vec<f64>,
    /// For a GNSS-side block ([`is_noise_like`]) whose evidence pays: its prediction of the
    /// fixes withheld one at a time ([`validate::interleaved_fixes`]) against the current
    /// model's, paired per fix (None: not judged so).
    pub heldout_fixes: Option<HeldoutComparison>,
    /// What the search decided.
    pub decision: Decision,
    /// Why, in words (evidence, significance, held-out gain).
    pub reason: String,
    /// Why it is not eligible (None: eligible or added).
    pub refused: Option<String>,
    /// Why it was not run (run error).
    pub note: Option<String>,
}

/// What the search decided on a candidate in one round.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Decision {
    /// Added to the model in this round.
    Added,
    /// Its evidence and held-out gain are significant, but another candidate was added.
    Eligible,
    /// Refused: its held-out errors are significantly higher than the current model's.
    Refused,
    /// Neither significant gain nor significant loss (evidence below its BIC penalty, an
    /// estimate within 2 sigma of zero, or a held-out change not significant either way).
    NotSignificant,
    /// Its run failed.
    Failed,
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
    /// closer than the margin, with the pick and the pair's joint fit in words.
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
    /// Log-likelihood gain when it was added, nats.
    pub delta_log_likelihood: f64,
    /// The held-out comparison that decided it, against the model before it, paired: its
    /// held-out windows, or for a GNSS-side block the fixes withheld one at a time
    /// ([`CandidateEvidence::heldout_fixes`]).
    pub heldout: HeldoutComparison,
    /// The strongest other paying candidate of that round and how many nats it trailed by.
    pub runner_up: Option<(String, f64)>,
    /// The other candidate when the choice was ambiguous (within the margin): this one was
    /// added for its lower held-out outage error.
    pub ambiguous_with: Option<String>,
    /// Whether it was a frozen block of the configuration, freed.
    pub freed: bool,
    /// The added block it took the place of (an IMU clock drift replaces a time offset, the
    /// model nested in it: [`prior::upgrades`]); its evidence and held-out comparison are then
    /// against the model with that block. None: appended.
    pub replaced: Option<String>,
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
    /// Why not (or, for an added effect, why).
    pub reason: Option<String>,
    /// Errors of the model with the change.
    pub errors: StepErrors,
    /// Its held-out windows against the model before the change, paired (None for the
    /// configuration).
    pub heldout: Option<HeldoutComparison>,
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
    /// The final model's GNSS error state prior (`gnss_position_gm`: per-axis sigma, m;
    /// correlation time, s) when the model carries the state with a prior other than the
    /// configuration's (the fitted one): `[gnss] error_state` of `augmented.toml`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_gnss_error_prior: Option<nav_io::GnssErrorPrior>,
    /// Every model change in order, with its errors (the first is the configuration).
    pub steps: Vec<Step>,
    /// Effects not added, with their detectability bounds on this drive.
    pub undetected: Vec<Undetected>,
    /// Misfit no effect of the vocabulary explains, and where in time it sits (None: none).
    pub unexplained: Option<stats::Unexplained>,
    /// Cautions about the diagnosis.
    pub warnings: Vec<String>,
    /// Candidates considered (frozen blocks of the configuration included).
    pub candidates_considered: Vec<String>,
    /// The held-out windows and how they were chosen.
    pub heldout_windows: HeldoutPlan,
    /// The configuration's error in each held-out window (search run), m; NaN when the
    /// window has no fix to judge it.
    pub window_errors_before_m: Vec<f64>,
    /// The final model's, m.
    pub window_errors_after_m: Vec<f64>,
    /// The final model against the configuration on the held-out windows (None when nothing
    /// changed).
    pub heldout_change: Option<HeldoutComparison>,
    /// Residual statistics of the base model.
    pub residuals_before: ResidualStats,
    /// Residual statistics of the final model.
    pub residuals_after: ResidualStats,
    /// The search, round by round.
    pub rounds: Vec<Round>,
    /// Time added to the IMU time stamps of the after solution in `nav_after.txt`, s: minus
    /// the time offset estimate (the output on the GNSS clock), else minus the clock drift's
    /// offset `dt_0` (its rate is not applied), 0 without either.
    pub output_clock_shift_s: f64,
    /// The time offset held at its estimate when it was added (s), when the final noise
    /// would have absorbed part of it (see the steps): the final model runs on the IMU data
    /// moved onto the GNSS clock by it, without the state (as `augmented.toml` runs).
    pub time_offset_held_s: Option<f64>,
    /// A bias step found in the data ([`changepoint`]) that passed the held-out rule (its
    /// held-out windows significantly lower than the recorded data's): removed from the data
    /// the search and the final model use.
    pub bias_step: Option<changepoint::BiasStep>,
    /// A bias step the change-point search found but the held-out rule did not keep (its
    /// windows not significantly lower, or significantly higher), with its comparison and the
    /// reason; the search runs on the recorded data.
    pub bias_step_not_kept: Option<changepoint::BiasStep>,
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

/// Result of [`diagnose`] with the two runs. Their navigation at every IMU epoch is in
/// temporary files ([`spill::NavFile`], removed when the output is dropped), not in the runs'
/// `nav` (empty), nor are their epoch records kept: memory proportional to the GNSS fixes.
pub struct DiagnoseOutput {
    /// The diagnosis (diagnosis.json).
    pub diagnosis: Diagnosis,
    /// The base run: innovations, snapshots, final estimates (`nav` and `epochs` empty).
    pub before: Arc<RunOutput>,
    /// Navigation records of the base run (`nav_before.txt`); their standard deviations are
    /// not recorded (NaN).
    pub before_nav: spill::NavFile,
    /// The run of the final model (the base run again when nothing changed), on the IMU
    /// clock (`nav_after.txt` adds [`Diagnosis::output_clock_shift_s`]); `nav` and `epochs`
    /// empty.
    pub after: Arc<RunOutput>,
    /// Navigation records of the final model's run: IMU clock, or the GNSS clock when the
    /// time offset was held ([`Diagnosis::time_offset_held_s`]); standard deviations NaN.
    pub after_nav: spill::NavFile,
    /// Time added to `after_nav`'s records when `nav_after.txt` is written, s:
    /// [`Diagnosis::output_clock_shift_s`], 0 when they are on the GNSS clock already.
    pub after_nav_shift_s: f64,
}

impl DiagnoseOutput {
    /// Time of the base run's first navigation record, s (the origin of the report's
    /// minutes; 0 without records).
    pub fn t0_s(&self) -> f64 {
        self.before_nav.first_t_s().unwrap_or(0.0)
    }
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
