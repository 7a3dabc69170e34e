//! What a diagnosis stopped by SIGINT/SIGTERM keeps: the search's rounds decided before the
//! signal ([`PartialDiagnosis`]), written as `report.md.partial`, `diagnosis.json.partial`
//! and `nav_before.txt.partial` ([`write_partial_files`]), the naming `host-sim run` gives the
//! outputs of a run it could not finish.
//!
//! A round is decided when every run of its candidates (and of the search steps before it)
//! ended before the signal: the state of the search is recorded after a round only when no
//! stop was requested by then ([`Checkpoint::after_round`]), so a round whose runs the signal
//! cut is never listed. No after-run is made: no `nav_after.txt` and no `augmented.toml` (the
//! effects decided so far are not a final model: the noise is not re-tuned with them, their
//! estimates are those of the search runs that added them, the diagnosis's windows withheld).
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::*;

/// Suffix of the files of a diagnosis stopped before its end (as `host-sim run`'s
/// [`nav_engine::run::output::PARTIAL_SUFFIX`]).
pub const PARTIAL_SUFFIX: &str = nav_engine::run::output::PARTIAL_SUFFIX;

/// The diagnosis of the rounds decided before a signal stopped the search
/// (`diagnosis.json.partial`): incomplete, never a finished diagnosis.
#[derive(Debug, Clone, Serialize)]
pub struct PartialDiagnosis {
    /// Always false: the search did not finish.
    pub complete: bool,
    /// The signal that stopped it (`SIGINT`, `SIGTERM`).
    pub interrupted: String,
    /// The number of search rounds decided (listed in [`Self::rounds`]); the round in
    /// progress at the signal is not listed.
    pub after_round: usize,
    /// What the diagnosis is and is not, in words.
    pub note: String,
    /// The effects the decided rounds added, in order; estimate and sigma are those of the
    /// search run that added each (the diagnosis's windows withheld), not of a final model.
    pub added_effects: Vec<AddedEffect>,
    /// The noise tuning before the search (absent with `--no-tune-noise`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_tuning: Option<NoiseTuning>,
    /// Every model change of the decided rounds, in order (the first is the configuration).
    pub steps: Vec<Step>,
    /// The decided rounds.
    pub rounds: Vec<Round>,
    /// Cautions so far.
    pub warnings: Vec<String>,
    /// Candidates considered.
    pub candidates_considered: Vec<String>,
    /// The held-out windows and how they were chosen.
    pub heldout_windows: HeldoutPlan,
    /// The configuration's error in each held-out window (search run), m.
    pub window_errors_before_m: Vec<f64>,
    /// The current model's error in each held-out window after the last decided round, m.
    pub window_errors_so_far_m: Vec<f64>,
    /// Residual statistics of the base model.
    pub residuals_before: ResidualStats,
    /// Position errors of the base model.
    pub error_before: ErrorSummary,
    /// A bias step kept before or during the decided rounds.
    pub bias_step: Option<changepoint::BiasStep>,
    /// A bias step found but not kept.
    pub bias_step_not_kept: Option<changepoint::BiasStep>,
}

/// A diagnosis stopped by SIGINT/SIGTERM: what it decided before the signal.
#[derive(Debug)]
pub struct Interrupted {
    /// The signal (`SIGINT`, `SIGTERM`).
    pub signal: String,
    /// The rounds decided and the base run's navigation (`nav_before.txt`); None when the
    /// signal came before the first round was decided (nothing to keep).
    pub kept: Option<(PartialDiagnosis, spill::NavFile)>,
}

/// How a diagnosis ended: complete, or stopped by a signal.
pub enum Outcome {
    /// Every round, the final run and the figures.
    Complete(Box<DiagnoseOutput>),
    /// Stopped by SIGINT/SIGTERM.
    Interrupted(Box<Interrupted>),
}

/// What does not change during the search: the base run's figures, recorded once.
pub(crate) struct BeforeSearch {
    pub(crate) plan: HeldoutPlan,
    pub(crate) candidates: Vec<String>,
    pub(crate) windows: Vec<f64>,
    pub(crate) residuals: ResidualStats,
    pub(crate) errors: ErrorSummary,
    pub(crate) nav: spill::NavFile,
}

/// The search's state after its last decided round, and who is told of each decided round.
pub(crate) struct Checkpoint<'a> {
    pub(crate) before: Option<BeforeSearch>,
    kept: Option<PartialDiagnosis>,
    on_round: &'a mut dyn FnMut(usize, &Round),
}

impl<'a> Checkpoint<'a> {
    /// Nothing kept yet; `on_round` is called with each decided round (1-based number).
    pub(crate) fn new(on_round: &'a mut dyn FnMut(usize, &Round)) -> Self {
        Self {
            before: None,
            kept: None,
            on_round,
        }
    }

    /// Records the search `s` after a round: only when no stop is requested (every run so
    /// far ended before the signal) and a round was added since the last record.
    pub(crate) fn after_round(&mut self, s: &Search) {
        if nav_engine::run::interrupt::requested().is_some() {
            return;
        }
        let Some(b) = &self.before else {
            return;
        };
        let done = self.kept.as_ref().map_or(0, |k| k.after_round);
        if s.rounds.len() <= done {
            return;
        }
        for (i, r) in s.rounds.iter().enumerate().skip(done) {
            (self.on_round)(i + 1, r);
        }
        self.kept = Some(PartialDiagnosis {
            complete: false,
            interrupted: String::new(),
            after_round: s.rounds.len(),
            note: String::new(),
            added_effects: s.added_info.clone(),
            noise_tuning: s.noise_tuning.clone(),
            steps: s.steps.clone(),
            rounds: s.rounds.clone(),
            warnings: s.warnings.clone(),
            candidates_considered: b.candidates.clone(),
            heldout_windows: b.plan.clone(),
            window_errors_before_m: b.windows.clone(),
            window_errors_so_far_m: s.cur.windows.clone(),
            residuals_before: b.residuals.clone(),
            error_before: b.errors,
            bias_step: s.bias_step.clone(),
            bias_step_not_kept: s.bias_step_not_kept.clone(),
        });
    }

    /// What the diagnosis keeps when `signal` stopped it.
    pub(crate) fn interrupted(self, signal: String) -> Interrupted {
        let kept = self.kept.zip(self.before).map(|(mut d, b)| {
            d.interrupted.clone_from(&signal);
            d.note = format!(
                "interrupted by {signal} after round {} of the search: the rounds listed are \
                 complete (every candidate run and decided), the search did not finish (the \
                 round in progress dropped, no later round, no noise re-tuning, no final run: \
                 no nav_after.txt, no augmented.toml)",
                d.after_round
            );
            (d, b.nav)
        });
        Interrupted { signal, kept }
    }
}

/// The text of `report.md.partial` for the stopped diagnosis `d` of the case `description`.
pub fn partial_markdown(description: &str, d: &PartialDiagnosis) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Diagnosis: INTERRUPTED, INCOMPLETE\n\n**Interrupted by {} after round {} of the \
         search.** The rounds listed below are complete: every candidate of theirs was run and \
         decided. The search did not finish: the round in progress at the signal was dropped, \
         and no later round, no noise re-tuning with the effects and no final run with every \
         fix were made. So there is no nav_after.txt and no augmented.toml: the effects added \
         so far are not a final model (their estimates are those of the search runs that \
         added them, the held-out windows withheld). Run the diagnosis again for the complete \
         one.\n\n{description}\n",
        d.interrupted, d.after_round
    );
    let added: Vec<&str> = d.added_effects.iter().map(|e| e.name.as_str()).collect();
    let _ = writeln!(
        s,
        "Effects added by the decided rounds: **{}**\n",
        if added.is_empty() {
            "none".to_string()
        } else {
            added.join(", ")
        }
    );
    if let Some(t) = &d.noise_tuning {
        report::noise_section(&mut s, t);
    }
    report::steps_table(&mut s, &d.steps);
    for w in &d.warnings {
        let _ = writeln!(s, "Warning: {w}\n");
    }
    let _ = writeln!(
        s,
        "Candidates considered: {}\n",
        d.candidates_considered.join(", ")
    );
    if !d.added_effects.is_empty() {
        let _ = writeln!(
            s,
            "## Effects added by the decided rounds (estimates of the search runs that added \
             them)\n"
        );
        report::added_table(&mut s, &d.added_effects);
    }
    let _ = writeln!(s, "## Evidence (the decided rounds)\n");
    report::rounds_tables(&mut s, &d.rounds);
    s
}

/// Writes the stopped diagnosis's files into `dir`: `diagnosis.json.partial`,
/// `report.md.partial` ([`partial_markdown`]) and `nav_before.txt.partial` (the base run's
/// solution, `week` its GPS week). Returns the paths written.
pub fn write_partial_files(
    dir: &Path,
    description: &str,
    week: u16,
    (d, before_nav): &(PartialDiagnosis, spill::NavFile),
) -> Result<Vec<PathBuf>, DiagnoseError> {
    std::fs::create_dir_all(dir).map_err(|source| DiagnoseError::CreateDir {
        path: dir.to_path_buf(),
        source,
    })?;
    let name = |n: &str| dir.join(format!("{n}{PARTIAL_SUFFIX}"));
    let write = |path: PathBuf, text: String| {
        std::fs::write(&path, text)
            .map(|()| path.clone())
            .map_err(|source| DiagnoseError::Write { path, source })
    };
    let report = write(name("report.md"), partial_markdown(description, d))?;
    let json = write(name("diagnosis.json"), serde_json::to_string_pretty(d)?)?;
    let nav = name("nav_before.txt");
    output::write_nav_records(&nav, before_nav.records()?, week, 0.0)?;
    Ok(vec![report, json, nav])
}
