//! `host-sim simulate`.

use anyhow::Context;
use nav_sim::case::simulate;
use nav_sim::errors::{ErrorModel, Outage};
use nav_sim::scenario::Scenario;
use std::path::{Path, PathBuf};

/// Arguments of `host-sim simulate`.
#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// Scenario TOML file, or the name of a shipped scenario (default, static, turns, long,
    /// figure8).
    #[arg(long, default_value = "default")]
    pub scenario: String,
    /// Error model: a preset (none, seed-nbk, tactical, consumer-mems) or a TOML file
    /// (`base = "<preset>"` in it overrides a preset).
    #[arg(long, default_value = "seed-nbk")]
    pub errors: String,
    /// Seed of the error realisation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// GNSS outage START:DURATION in seconds after the first IMU epoch (repeatable).
    #[arg(long = "outage", value_parser = parse_outage)]
    pub outages: Vec<Outage>,
    /// GNSS fix rate, Hz (overrides the error model).
    #[arg(long)]
    pub gnss_rate_hz: Option<f64>,
    /// Also write `kf-gins.yaml` (KF-GINS configuration of the case).
    #[arg(long)]
    pub kf_gins: bool,
    /// Also write `trajectory.png` (ground track, speed, height, attitude, specific force).
    #[arg(long)]
    pub plot: bool,
}

/// Parses `START:DURATION` (seconds): the run's parser ([`nav_engine::run::parse_outage`]),
/// as the simulator's outage.
pub fn parse_outage(s: &str) -> Result<Outage, String> {
    nav_engine::run::parse_outage(s).map(|o| Outage {
        start_s: o.start_s,
        duration_s: o.duration_s,
    })
}

/// Directory of the shipped scenarios (`scenarios/` at the repository root).
pub fn scenarios_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios")
}

/// Resolves a scenario argument: an existing path, or a shipped scenario's name.
pub fn resolve_scenario(arg: &str) -> anyhow::Result<PathBuf> {
    let p = PathBuf::from(arg);
    if p.exists() {
        return Ok(p);
    }
    for dir in [PathBuf::from("scenarios"), scenarios_dir()] {
        let c = dir.join(format!("{arg}.toml"));
        if c.exists() {
            return Ok(c);
        }
    }
    let mut names: Vec<String> = [PathBuf::from("scenarios"), scenarios_dir()]
        .iter()
        .filter_map(|d| std::fs::read_dir(d).ok())
        .flat_map(|d| d.flatten())
        .filter_map(|e| {
            let p = e.path();
            (p.extension()? == "toml").then(|| p.file_stem()?.to_str().map(str::to_string))?
        })
        .collect();
    names.sort();
    names.dedup();
    let hint = nav_io::did_you_mean(arg, names.iter().map(String::as_str))
        .map(|h| format!("; {h}"))
        .unwrap_or_default();
    anyhow::bail!(
        "scenario `{arg}`: no such file and no shipped scenario of that name (shipped: {}){hint}",
        names.join(", ")
    )
}

/// Runs `host-sim simulate`.
pub fn run(args: SimulateArgs) -> anyhow::Result<()> {
    let path = resolve_scenario(&args.scenario)?;
    let scenario = Scenario::from_file(&path)?;
    let mut errors = ErrorModel::load(&args.errors)?;
    errors.gnss.outages.extend(args.outages.iter().copied());
    if let Some(r) = args.gnss_rate_hz {
        errors.gnss.rate_hz = r;
    }
    errors.validate()?;
    let t = std::time::Instant::now();
    let case = simulate(&scenario, &errors, args.seed)?;
    let t_sim = t.elapsed().as_secs_f64();
    case.write(&args.out, args.kf_gins)
        .with_context(|| format!("writing the case to {}", args.out.display()))?;
    if args.plot {
        super::plot::plot_trajectory(&case.trajectory, &args.out.join("trajectory.png"))?;
    }
    let cf = case.case_file(args.kf_gins);
    println!(
        "simulated `{}` ({:.1} min, {} IMU samples at {} Hz, {} GNSS fixes, {} outage(s)) with \
         errors `{}`, seed {} in {:.2} s",
        scenario.name,
        cf.summary.duration_s / 60.0,
        cf.summary.imu_samples,
        cf.summary.imu_rate_hz,
        cf.summary.gnss_fixes,
        cf.outages.len(),
        errors.name,
        args.seed,
        t_sim
    );
    println!(
        "wrote {}/{{imu.txt, gnss.txt, truth.nav, case.toml{}{}}}",
        args.out.display(),
        if args.kf_gins { ", kf-gins.yaml" } else { "" },
        if args.plot { ", trajectory.png" } else { "" }
    );
    Ok(())
}
