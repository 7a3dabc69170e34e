//! `host-sim study`: the command line over the `nav-study` crate (the source document's
//! bias-model study): arguments, a progress bar, the printed table, and the outputs
//! `study.json`, the PNG plots ([`plots`]), `report.md` and the self-contained `report.html`.

mod html;
pub mod plots;

pub use html::base64;

use crate::cli_enum;
use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use nav_sim::Scenario;
use nav_study::report;
use nav_study::setup::Variant;
use nav_study::{run_study, Progress, StudyConfig, StudyResult, DEFAULT_OUTAGE_START_S};
use std::path::{Path, PathBuf};

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
    /// Models whose error budget is computed (comma-separated; the option with no value: no
    /// budget).
    #[arg(
        long,
        value_delimiter = ',',
        num_args = 0..=1,
        default_value = "nbk,n",
        value_parser = cli_enum::parser::<Variant>()
    )]
    pub budget_models: Vec<Variant>,
    /// A quick look: 6 runs per cell, 12 per budget source, the budget for NBK only, and the
    /// runs end 60 s after the outage.
    #[arg(long)]
    pub quick: bool,
    /// No progress bar.
    #[arg(long)]
    pub no_progress: bool,
}

/// The study's progress on the terminal (hidden with `--no-progress`).
struct Bar(ProgressBar);

impl Progress for Bar {
    fn begin(&self, total_runs: usize) {
        self.0.set_length(total_runs as u64);
    }
    fn phase(&self, name: &'static str) {
        self.0.set_message(name);
    }
    fn run_done(&self) {
        self.0.inc(1);
    }
    fn end(&self) {
        self.0.finish_and_clear();
    }
}

fn progress_bar(show: bool) -> Bar {
    if !show {
        return Bar(ProgressBar::hidden());
    }
    let pb = ProgressBar::new(0);
    pb.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} filter runs ({eta} left) {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    Bar(pb)
}

/// Writes `study.json`, the plots, `report.md` and `report.html` into `out`.
pub fn write_all(res: &StudyResult, out: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let p = out.join("study.json");
    std::fs::write(&p, serde_json::to_string(&report::study_json(res))?)
        .with_context(|| format!("writing {}", p.display()))?;
    let names = plots::write_all(res, out)?;
    let md = report::markdown(res, &names);
    let p = out.join("report.md");
    std::fs::write(&p, &md).with_context(|| format!("writing {}", p.display()))?;
    let html = html::html(&md, out, &names)?;
    let p = out.join("report.html");
    std::fs::write(&p, html).with_context(|| format!("writing {}", p.display()))?;
    Ok(())
}

/// Runs `host-sim study`.
pub fn run(args: StudyArgs) -> anyhow::Result<()> {
    let path = crate::sim::cli::resolve_scenario(&args.scenario)?;
    let scenario = Scenario::from_file(&path)?;
    let mut cfg = StudyConfig::new(scenario, args.runs, args.seed);
    cfg.outage_start_rel_s = args.outage_start;
    cfg.outage_duration_s = args.outage_duration;
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
    let res = run_study(&cfg, &progress_bar(!args.no_progress))?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let table = report::table(&res);
    println!("{table}");
    write_all(&res, &args.out)?;
    println!(
        "study: {} filter runs in {:.1} s; report: {}",
        res.filter_runs,
        res.elapsed_s,
        args.out.join("report.md").display()
    );
    Ok(())
}
