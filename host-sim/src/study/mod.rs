//! `host-sim study`: the source document's simulation study, runnable with one command and
//! extended with true errors, Monte Carlo statistics, NEES consistency and an error budget.
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
//! Results: a printed table, `study.json`, PNG plots and `report.md` / `report.html`
//! ([`report`], [`plots`]).

pub mod budget;
pub mod plots;
pub mod report;
pub mod setup;
pub mod stats;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use nav_engine::run::{self, CaseData, RecordOptions, RunOptions};
use nav_sim::{Scenario, Trajectory};
use rayon::prelude::*;
use serde::Serialize;
use setup::Variant;
use setup::{Source, Sources};
use stats::{CellStats, Trace};
use std::path::PathBuf;

/// Arguments of `host-sim study`.
#[derive(clap::Args, Debug, Clone)]
pub struct StudyArgs {
    /// Monte Carlo runs per model and case (each run is one seed).
    #[arg(long, default_value_t = 20)]
    pub runs: usize,
    /// Seed of the first run (run i uses seed + i).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory.
    #[arg(long, default_value = "out/study")]
    pub out: PathBuf,
    /// Scenario TOML file, or the name of a shipped scenario.
    #[arg(long, default_value = "default")]
    pub scenario: String,
    /// Start of the 5-minute outage of case 2, s after the first IMU epoch.
    #[arg(long, default_value_t = DEFAULT_OUTAGE_START_S)]
    pub outage_start: f64,
    /// Duration of the outage, s.
    #[arg(long, default_value_t = 300.0)]
    pub outage_duration: f64,
    /// Runs per error source in the error budget (the sampling noise of the variance
    /// decomposition falls as 1/sqrt(runs): about 0.3/sqrt(runs) here).
    #[arg(long, default_value_t = 60)]
    pub budget_runs: usize,
    /// Models whose error budget is computed (comma-separated: n, nbk, nbk-single; empty =
    /// none).
    #[arg(long, value_delimiter = ',', default_value = "nbk,n")]
    pub budget_models: Vec<Variant>,
    /// A quick look: 6 runs per cell, 12 per budget source, the budget for NBK only, and the
    /// runs end 60 s after the outage.
    #[arg(long)]
    pub quick: bool,
    /// No progress bar.
    #[arg(long)]
    pub no_progress: bool,
}

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
    /// Show a progress bar.
    pub progress: bool,
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
            progress: false,
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
) -> anyhow::Result<Trace> {
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
    let out = run::run_filter(data, &opts).with_context(|| {
        format!(
            "{} on {} (seed {})",
            r.model.label(),
            r.case.short(),
            r.seed
        )
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
pub fn trajectory(cfg: &StudyConfig) -> anyhow::Result<Trajectory> {
    let mut traj = Trajectory::generate(&cfg.scenario)?;
    if let Some(e) = cfg.end_rel_s {
        let n = ((e + 1.0) / traj.dt_s).ceil() as usize;
        traj.imu.truncate(n);
        traj.truth.truncate(n + 1);
    }
    Ok(traj)
}

fn progress_bar(cfg: &StudyConfig, total: usize) -> ProgressBar {
    if !cfg.progress {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(total as u64);
    pb.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} filter runs ({eta} left) {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb
}

/// Runs the study.
pub fn run_study(cfg: &StudyConfig) -> anyhow::Result<StudyResult> {
    let t_start = std::time::Instant::now();
    anyhow::ensure!(cfg.runs >= 2, "the study needs at least 2 runs per cell");
    let traj = trajectory(cfg)?;
    let dur = traj.duration_s();
    anyhow::ensure!(
        cfg.outage_end_rel_s() < dur,
        "the outage ({} s + {} s) must end before the data ({dur:.0} s)",
        cfg.outage_start_rel_s,
        cfg.outage_duration_s
    );
    let n_main = cfg.runs * cfg.models.len() * Case::ALL.len();
    let n_budget: usize = cfg
        .budget_models
        .iter()
        .map(|m| {
            let have = if cfg.models.contains(m) { cfg.runs } else { 0 };
            cfg.budget_runs * Source::ALL.len() + cfg.budget_runs.saturating_sub(have)
        })
        .sum();
    let pb = progress_bar(cfg, n_main + n_budget);
    let cells = main_cells(cfg, &traj, &pb)?;

    let budgets = error_budgets(cfg, &traj, &cells, &pb)?;
    pb.finish_and_clear();
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
fn main_cells(cfg: &StudyConfig, traj: &Trajectory, pb: &ProgressBar) -> anyhow::Result<Vec<Cell>> {
    let seeds: Vec<u64> = (0..cfg.runs as u64).map(|i| cfg.seed + i).collect();

    // main grid: per seed one measurement set, every model on both cases
    pb.set_message("models x cases");
    let per_seed: Vec<Vec<(Variant, Case, Trace)>> = seeds
        .par_iter()
        .map(|&seed| -> anyhow::Result<Vec<(Variant, Case, Trace)>> {
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
                    pb.inc(1);
                    v.push((model, case, tr));
                }
            }
            Ok(v)
        })
        .collect::<anyhow::Result<_>>()?;
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
            let k = st.index_at(eval).context("no epoch at the outage end")?;
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
    pb: &ProgressBar,
) -> anyhow::Result<Vec<budget::Budget>> {
    let eval = cfg.outage_eval_rel_s();
    // error budget: each source alone, case 2, up to the outage evaluation epoch; the
    // all-sources errors of seeds beyond the main runs are computed the same way
    pb.set_message("error budget");
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
        .map(|&(model, on, seed)| -> anyhow::Result<_> {
            let data = case_data(traj, seed, on);
            let spec = RunSpec {
                model,
                case: Case::Outage,
                seed,
                on,
                end_rel_s: stop,
            };
            let tr = run_one(cfg, traj, &data, spec)?;
            pb.inc(1);
            let k = tr
                .t_rel_s
                .iter()
                .position(|t| (t - eval).abs() < 0.25)
                .context("budget run has no epoch at the outage end")?;
            Ok((model, on, seed, [tr.err[k][6], tr.err[k][7], tr.err[k][8]]))
        })
        .collect::<anyhow::Result<_>>()?;
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
        anyhow::ensure!(
            per_source.iter().all(|p| p.1.len() == total.len()),
            "budget of {}: run counts differ",
            model.label()
        );
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

/// Runs `host-sim study`.
pub fn run(args: StudyArgs) -> anyhow::Result<()> {
    let path = crate::sim::cli::resolve_scenario(&args.scenario)?;
    let scenario = Scenario::from_file(&path)?;
    let mut cfg = StudyConfig::new(scenario, args.runs, args.seed);
    cfg.outage_start_rel_s = args.outage_start;
    cfg.outage_duration_s = args.outage_duration;
    cfg.progress = !args.no_progress;
    cfg.budget_runs = args.budget_runs;
    cfg.budget_models = args.budget_models.clone();
    if args.quick {
        cfg.runs = cfg.runs.min(6);
        cfg.budget_runs = cfg.budget_runs.min(12);
        cfg.budget_models.retain(|m| *m == Variant::Nbk);
        cfg.end_rel_s = Some(cfg.outage_end_rel_s() + 60.0);
    }
    println!(
        "study: scenario `{}`, {} runs per cell, seeds {}..{}, outage {:.0} s + {:.0} s, {} threads",
        cfg.scenario.name,
        cfg.runs,
        cfg.seed,
        cfg.seed + cfg.runs as u64 - 1,
        cfg.outage_start_rel_s,
        cfg.outage_duration_s,
        rayon::current_num_threads()
    );
    let res = run_study(&cfg)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let table = report::table(&res);
    println!("{table}");
    report::write_all(&res, &args.out)?;
    println!(
        "study: {} filter runs in {:.1} s; report: {}",
        res.filter_runs,
        res.elapsed_s,
        args.out.join("report.md").display()
    );
    Ok(())
}
