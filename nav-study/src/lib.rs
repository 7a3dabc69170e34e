//! The source document's simulation study as a library (`host-sim study` is its command line):
//! the source's N and NBK accelerometer bias models compared on a simulated drive, extended
//! with true errors, Monte Carlo statistics, NEES consistency and an error budget.
//!
//! # What runs
//!
//! - **Truth**: the scenario's trajectory is generated once ([`Trajectory::generate`]); per run
//!   (seed) the simulated IMU gets the source's identified stochastic errors (Appendix V:
//!   accelerometer white noise, first-order Gauss-Markov and random-walk bias; gyro white
//!   noise; turn-on biases, see [`setup`]) and the GNSS RTK-level errors
//!   ([`setup::truth_errors`]). The filter starts from the truth plus initial errors drawn with
//!   the uncertainty it is told ([`setup::init_spec`]).
//! - **Models**: N (manufacturer white noise, constant biases), NBK (identified parameters,
//!   separate Gauss-Markov and random-walk accelerometer bias states) and the source's
//!   single-state NBK variant, each on **case 1** (continuous 1 Hz GNSS) and **case 2** (one
//!   5-minute outage). Every filter run goes through [`nav_engine::run::run_filter`].
//! - **Statistics** ([`stats`]): per epoch (1 Hz) the mean and RMS of the true errors over the
//!   runs, the filter's standard deviations, and the average NEES of attitude, velocity and
//!   position against the two-sided 95 % chi-square band of `runs x 3` degrees of freedom.
//! - **Error budget** ([`budget`]): each error source alone (same seeds, same random streams)
//!   on case 2, the position error at the end of the outage; the contributions are compared
//!   in variance with the all-sources total.
//!
//! Results: [`StudyResult`]; [`report`] turns it into the table, the verdicts, the
//! `study.json` document and the Markdown report (the command line adds the plots and the
//! HTML page).
//!
//! ```no_run
//! use nav_study::{run_study, NoProgress, StudyConfig};
//! let scenario = nav_sim::Scenario::from_file("scenarios/default.toml".as_ref()).unwrap();
//! let mut cfg = StudyConfig::new(scenario, 6, 1);
//! cfg.budget_models.clear();
//! let res = run_study(&cfg, &NoProgress).unwrap();
//! println!("{}", nav_study::report::table(&res));
//! ```
#![deny(missing_docs)]

pub mod budget;
pub mod report;
pub mod setup;
pub mod stats;

use nav_engine::run::{self, CaseData, RecordOptions, RunOptions};
use nav_sim::{Scenario, Trajectory};
use rayon::prelude::*;
use serde::Serialize;
use setup::Variant;
use setup::{Source, Sources};
use stats::{CellStats, Trace};

/// Default start of the outage, s after the first IMU epoch: 9.5 minutes of GNSS (3 min static,
/// 6.5 min driving) before it; in the default scenario the outage then holds a braking, a
/// 180 degree turn, an acceleration from 12 to 25 m/s, a 45 degree turn and cruising.
pub const DEFAULT_OUTAGE_START_S: f64 = 570.0;

/// Everything the study needs.
#[derive(Debug, Clone)]
pub struct StudyConfig {
    /// The motion scenario.
    pub scenario: Scenario,
    /// Runs per cell.
    pub runs: usize,
    /// Seed of the first run.
    pub seed: u64,
    /// Outage start, s after the first IMU epoch.
    pub outage_start_rel_s: f64,
    /// Outage duration, s.
    pub outage_duration_s: f64,
    /// Models compared (each on both cases).
    pub models: Vec<Variant>,
    /// Models whose error budget is computed.
    pub budget_models: Vec<Variant>,
    /// Runs per source in the budget (seeds `seed .. seed + budget_runs`).
    pub budget_runs: usize,
    /// End the runs this long after the first IMU epoch (`None` = the whole scenario).
    pub end_rel_s: Option<f64>,
}

impl StudyConfig {
    /// The default study on a scenario: `runs` runs from `seed`, N, NBK and NBK-single, the
    /// budget for NBK and N with 60 runs per source, the whole scenario.
    pub fn new(scenario: Scenario, runs: usize, seed: u64) -> Self {
        Self {
            scenario,
            runs,
            seed,
            outage_start_rel_s: DEFAULT_OUTAGE_START_S,
            outage_duration_s: 300.0,
            models: Variant::ALL.to_vec(),
            budget_models: vec![Variant::Nbk, Variant::N],
            budget_runs: 60,
            end_rel_s: None,
        }
    }

    /// The epoch at which "the end of the outage" is evaluated, s after the first IMU epoch:
    /// the last withheld fix's time, i.e. exactly `outage_duration_s` after the last fix used
    /// before the outage (fixes at 1 Hz; the fix at `start + duration` is used again).
    pub fn outage_eval_rel_s(&self) -> f64 {
        self.outage_start_rel_s + self.outage_duration_s - 1.0
    }

    /// End of the outage (first fix used again), s after the first IMU epoch.
    pub fn outage_end_rel_s(&self) -> f64 {
        self.outage_start_rel_s + self.outage_duration_s
    }
}

/// Why the study could not run.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    /// Fewer than two runs per cell: no spread to estimate.
    #[error("the study needs at least 2 runs per cell (got {0})")]
    TooFewRuns(usize),
    /// The outage does not end before the data do.
    #[error("the outage ({start_s} s + {duration_s} s) must end before the data ({data_s:.0} s)")]
    OutageBeyondData {
        /// Outage start, s after the first IMU epoch.
        start_s: f64,
        /// Outage duration, s.
        duration_s: f64,
        /// Length of the data, s.
        data_s: f64,
    },
    /// The scenario does not compile into a trajectory.
    #[error(transparent)]
    Scenario(#[from] nav_sim::ScenarioError),
    /// A filter run failed.
    #[error("{what}: {source}")]
    Run {
        /// Which run: model, case and seed.
        what: String,
        /// The run engine's error.
        source: Box<run::RunError>,
    },
    /// A run's record has no epoch at the outage evaluation time.
    #[error("{0}: no epoch at the outage end")]
    NoEpochAtOutageEnd(String),
    /// The error budget of a model got different numbers of runs per source.
    #[error("budget of {0}: run counts differ")]
    BudgetRunCounts(&'static str),
}

/// Progress of a study, reported from the worker threads (filter runs run in parallel).
pub trait Progress: Sync {
    /// The study starts `total_runs` filter runs.
    fn begin(&self, total_runs: usize) {
        let _ = total_runs;
    }
    /// A phase starts (`"models x cases"`, `"error budget"`).
    fn phase(&self, name: &'static str) {
        let _ = name;
    }
    /// One filter run is done.
    fn run_done(&self) {}
    /// Every run is done.
    fn end(&self) {}
}

/// No progress reporting.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoProgress;

impl Progress for NoProgress {}

/// The two cases of the source.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Case {
    /// Continuous 1 Hz GNSS.
    Continuous,
    /// One GNSS outage.
    Outage,
}

impl Case {
    /// Both cases.
    pub const ALL: [Case; 2] = [Case::Continuous, Case::Outage];

    /// Label for tables.
    pub fn label(self) -> &'static str {
        match self {
            Self::Continuous => "case 1 (continuous GNSS)",
            Self::Outage => "case 2 (5-min outage)",
        }
    }

    /// Short name for file names.
    pub fn short(self) -> &'static str {
        match self {
            Self::Continuous => "case1",
            Self::Outage => "case2",
        }
    }
}

/// One model on one case: its Monte Carlo statistics and the per-run errors at the
/// evaluation epoch (the end of the outage).
#[derive(Debug, Clone)]
pub struct Cell {
    /// Variant.
    pub model: Variant,
    /// Case.
    pub case: Case,
    /// Per-epoch statistics.
    pub stats: CellStats,
    /// Per-run position error (N, E, D, m) at the outage evaluation epoch.
    pub pos_err_at_eval: Vec<[f64; 3]>,
    /// A few runs' full traces (for the plots).
    pub sample_traces: Vec<Trace>,
}

/// Everything the study produced.
#[derive(Debug, Clone)]
pub struct StudyResult {
    /// The configuration.
    pub config: StudyConfig,
    /// Duration of the runs, s.
    pub duration_s: f64,
    /// Variant x case cells.
    pub cells: Vec<Cell>,
    /// Error budgets (one per budget model).
    pub budgets: Vec<budget::Budget>,
    /// Wall-clock time of the study, s.
    pub elapsed_s: f64,
    /// Filter runs made.
    pub filter_runs: usize,
}

impl StudyResult {
    /// The cell of a model and case.
    pub fn cell(&self, model: Variant, case: Case) -> Option<&Cell> {
        self.cells
            .iter()
            .find(|c| c.model == model && c.case == case)
    }
}

/// Number of full traces kept per cell for the plots.
const SAMPLE_TRACES: usize = 5;

fn record_options() -> RecordOptions {
    RecordOptions {
        nav_rate_hz: Some(0.0),
        epoch_rate_hz: Some(1.0),
    }
}

/// What one filter run is: model, case, seed, sources switched on, optional end.
#[derive(Debug, Clone, Copy)]
struct RunSpec {
    model: Variant,
    case: Case,
    seed: u64,
    on: Sources,
    end_rel_s: Option<f64>,
}

/// One filter run on the measurements of `data`, with or without the outage.
fn run_one(
    cfg: &StudyConfig,
    traj: &Trajectory,
    data: &CaseData,
    r: RunSpec,
) -> Result<Trace, StudyError> {
    let mut opts = RunOptions::new(
        r.model.model(),
        r.model.config(),
        setup::init_spec(r.seed, r.on),
    );
    opts.record = record_options();
    if r.case == Case::Outage {
        opts.outages = vec![run::Outage {
            start_s: traj.t0_s + cfg.outage_start_rel_s,
            duration_s: cfg.outage_duration_s,
        }];
    }
    opts.end_s = r.end_rel_s.map(|e| traj.t0_s + e);
    let out = run::run_filter(data, &opts).map_err(|source| StudyError::Run {
        what: format!(
            "{} on {} (seed {})",
            r.model.label(),
            r.case.short(),
            r.seed
        ),
        source: Box::new(source),
    })?;
    Ok(stats::trace_of(&out, traj))
}

/// The measurements of seed `seed` with the sources `on`, as the runner's case data (the truth
/// record holds only the first epoch: the runner needs it for the initial state).
fn case_data(traj: &Trajectory, seed: u64, on: Sources) -> CaseData {
    let m = setup::errors_with(on).apply(traj, seed);
    CaseData {
        imu: m.imu,
        gnss: m.gnss,
        truth: Some(traj.truth.iter().take(1).copied().collect()),
        imu_origin: None,
    }
}

/// The trajectory of the study (truncated to `end_rel_s` plus a second when set).
pub fn trajectory(cfg: &StudyConfig) -> Result<Trajectory, nav_sim::ScenarioError> {
    let mut traj = Trajectory::generate(&cfg.scenario)?;
    if let Some(e) = cfg.end_rel_s {
        let n = ((e + 1.0) / traj.dt_s).ceil() as usize;
        traj.imu.truncate(n);
        traj.truth.truncate(n + 1);
    }
    Ok(traj)
}

/// Runs the study, reporting its progress to `progress`.
pub fn run_study(cfg: &StudyConfig, progress: &dyn Progress) -> Result<StudyResult, StudyError> {
    let t_start = std::time::Instant::now();
    if cfg.runs < 2 {
        return Err(StudyError::TooFewRuns(cfg.runs));
    }
    let traj = trajectory(cfg)?;
    let dur = traj.duration_s();
    if cfg.outage_end_rel_s() >= dur {
        return Err(StudyError::OutageBeyondData {
            start_s: cfg.outage_start_rel_s,
            duration_s: cfg.outage_duration_s,
            data_s: dur,
        });
    }
    let n_main = cfg.runs * cfg.models.len() * Case::ALL.len();
    let n_budget: usize = cfg
        .budget_models
        .iter()
        .map(|m| {
            let have = if cfg.models.contains(m) { cfg.runs } else { 0 };
            cfg.budget_runs * Source::ALL.len() + cfg.budget_runs.saturating_sub(have)
        })
        .sum();
    progress.begin(n_main + n_budget);
    let cells = main_cells(cfg, &traj, progress)?;
    let budgets = error_budgets(cfg, &traj, &cells, progress)?;
    progress.end();
    Ok(StudyResult {
        config: cfg.clone(),
        duration_s: dur,
        cells,
        budgets,
        elapsed_s: t_start.elapsed().as_secs_f64(),
        filter_runs: n_main + n_budget,
    })
}

/// The main grid: per seed one measurement set, every model on both cases; the cells'
/// statistics over the seeds and each run's position error at the outage evaluation epoch.
fn main_cells(
    cfg: &StudyConfig,
    traj: &Trajectory,
    progress: &dyn Progress,
) -> Result<Vec<Cell>, StudyError> {
    let seeds: Vec<u64> = (0..cfg.runs as u64).map(|i| cfg.seed + i).collect();

    // main grid: per seed one measurement set, every model on both cases
    progress.phase("models x cases");
    let per_seed: Vec<Vec<(Variant, Case, Trace)>> = seeds
        .par_iter()
        .map(|&seed| -> Result<Vec<(Variant, Case, Trace)>, StudyError> {
            let data = case_data(traj, seed, Sources::All);
            let mut v = Vec::new();
            for &model in &cfg.models {
                for case in Case::ALL {
                    let spec = RunSpec {
                        model,
                        case,
                        seed,
                        on: Sources::All,
                        end_rel_s: None,
                    };
                    let tr = run_one(cfg, traj, &data, spec)?;
                    progress.run_done();
                    v.push((model, case, tr));
                }
            }
            Ok(v)
        })
        .collect::<Result<_, StudyError>>()?;
    let eval = cfg.outage_eval_rel_s();
    let mut cells = Vec::new();
    for &model in &cfg.models {
        for case in Case::ALL {
            let traces: Vec<Trace> = per_seed
                .iter()
                .filter_map(|v| {
                    v.iter()
                        .find(|(m, c, _)| *m == model && *c == case)
                        .map(|x| x.2.clone())
                })
                .collect();
            let st = stats::cell_stats(&traces);
            let k = st.index_at(eval).ok_or_else(|| {
                StudyError::NoEpochAtOutageEnd(format!("{} on {}", model.label(), case.short()))
            })?;
            let pos_err_at_eval = traces
                .iter()
                .map(|t| [t.err[k][6], t.err[k][7], t.err[k][8]])
                .collect();
            cells.push(Cell {
                model,
                case,
                stats: st,
                pos_err_at_eval,
                sample_traces: traces.into_iter().take(SAMPLE_TRACES).collect(),
            });
        }
    }
    Ok(cells)
}

/// The error budget: each source alone, case 2, up to the outage evaluation epoch, for every
/// budget model; the all-sources errors of seeds beyond the main runs computed the same way.
fn error_budgets(
    cfg: &StudyConfig,
    traj: &Trajectory,
    cells: &[Cell],
    progress: &dyn Progress,
) -> Result<Vec<budget::Budget>, StudyError> {
    let eval = cfg.outage_eval_rel_s();
    // error budget: each source alone, case 2, up to the outage evaluation epoch; the
    // all-sources errors of seeds beyond the main runs are computed the same way
    progress.phase("error budget");
    let budget_seeds: Vec<u64> = (0..cfg.budget_runs as u64).map(|i| cfg.seed + i).collect();
    let mut jobs: Vec<(Variant, Sources, u64)> = Vec::new();
    for &m in &cfg.budget_models {
        for s in Source::ALL {
            for &seed in &budget_seeds {
                jobs.push((m, Sources::Only(s), seed));
            }
        }
        let have = if cfg.models.contains(&m) { cfg.runs } else { 0 };
        for &seed in budget_seeds.iter().skip(have) {
            jobs.push((m, Sources::All, seed));
        }
    }
    let stop = Some(eval + 0.5);
    let results: Vec<(Variant, Sources, u64, [f64; 3])> = jobs
        .par_iter()
        .map(|&(model, on, seed)| -> Result<_, StudyError> {
            let data = case_data(traj, seed, on);
            let spec = RunSpec {
                model,
                case: Case::Outage,
                seed,
                on,
                end_rel_s: stop,
            };
            let tr = run_one(cfg, traj, &data, spec)?;
            progress.run_done();
            let k = tr
                .t_rel_s
                .iter()
                .position(|t| (t - eval).abs() < 0.25)
                .ok_or_else(|| {
                    StudyError::NoEpochAtOutageEnd(format!(
                        "budget run of {} (seed {seed})",
                        model.label()
                    ))
                })?;
            Ok((model, on, seed, [tr.err[k][6], tr.err[k][7], tr.err[k][8]]))
        })
        .collect::<Result<_, StudyError>>()?;
    let collect = |model: Variant, on: Sources| -> Vec<[f64; 3]> {
        let mut v: Vec<(u64, [f64; 3])> = results
            .iter()
            .filter(|a| a.0 == model && a.1 == on)
            .map(|a| (a.2, a.3))
            .collect();
        v.sort_by_key(|x| x.0);
        v.into_iter().map(|x| x.1).collect()
    };
    let mut budgets = Vec::new();
    for &model in &cfg.budget_models {
        let mut total: Vec<[f64; 3]> = cells
            .iter()
            .find(|c| c.model == model && c.case == Case::Outage)
            .map(|c| c.pos_err_at_eval.clone())
            .unwrap_or_default();
        total.truncate(cfg.budget_runs);
        total.extend(collect(model, Sources::All));
        let per_source: Vec<(Source, Vec<[f64; 3]>)> = Source::ALL
            .iter()
            .map(|&s| (s, collect(model, Sources::Only(s))))
            .collect();
        if !per_source.iter().all(|p| p.1.len() == total.len()) {
            return Err(StudyError::BudgetRunCounts(model.label()));
        }
        let pos_std = cells
            .iter()
            .find(|c| c.model == model && c.case == Case::Outage)
            .and_then(|c| c.stats.index_at(eval).map(|k| c.stats.std[k]))
            .map(|s| [s[6], s[7], s[8]]);
        budgets.push(budget::Budget::compute(
            model,
            eval,
            &total,
            &per_source,
            pos_std,
        ));
    }
    Ok(budgets)
}
