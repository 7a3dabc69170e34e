//! `host-sim simulate`.

use anyhow::Context;
use nav_engine::run::outdir::OutDir;
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
    /// Output directory. A folder already holding a case (imu.txt, gnss.txt, truth.nav,
    /// case.toml, ...) is refused unless --force; so is one holding the scenario or
    /// error-model file, one another process is writing into, or a file in its place.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace the case already in --out (its files that this case does not write are
    /// removed too, so the folder holds one case).
    #[arg(long)]
    pub force: bool,
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

/// The files `simulate` writes into its output folder (which of them depends on the scenario
/// and the options); any of them in `--out` means the folder already holds a case.
pub const CASE_FILES: [&str; 8] = [
    "imu.txt",
    "gnss.txt",
    "truth.nav",
    "case.toml",
    "odometer.txt",
    "heading.txt",
    "kf-gins.yaml",
    "trajectory.png",
];

/// Why `simulate` does not write its case.
#[derive(Debug, thiserror::Error)]
pub enum SimulateError {
    /// The output folder already holds a case and `--force` was not given.
    #[error(
        "--out {} already holds a case ({}): pass --force to replace it, or choose another \
         output folder (nothing was written)",
        out.display(),
        names.join(", ")
    )]
    CaseExists {
        /// The output folder.
        out: PathBuf,
        /// The case files found in it.
        names: Vec<&'static str>,
    },
}

/// The [`CASE_FILES`] present in `out` (a link counts: it is not written through either).
fn case_files_in(out: &Path) -> Vec<&'static str> {
    CASE_FILES
        .into_iter()
        .filter(|n| std::fs::symlink_metadata(out.join(n)).is_ok())
        .collect()
}

/// Refuses `out` when it holds a case and `force` is not set.
fn check_no_case(out: &Path, force: bool) -> Result<(), SimulateError> {
    let names = case_files_in(out);
    if names.is_empty() || force {
        return Ok(());
    }
    Err(SimulateError::CaseExists {
        out: out.to_path_buf(),
        names,
    })
}

/// Writes `case` through the output folder `od`: into its stage folder (the KF-GINS YAML
/// naming the files at their final place), then moved into `OUT`; with `force`, the case
/// files of an earlier case that this one does not write are removed.
fn write_case(od: OutDir, case: &nav_sim::case::Case, args: &SimulateArgs) -> anyhow::Result<()> {
    let stage = od.stage().to_path_buf();
    case.write(&stage, args.kf_gins)
        .with_context(|| format!("writing the case to {}", args.out.display()))?;
    if args.kf_gins {
        let abs = std::path::absolute(&args.out)
            .with_context(|| format!("resolving {}", args.out.display()))?;
        let p = stage.join("kf-gins.yaml");
        std::fs::write(&p, case.kf_gins_yaml(&abs))
            .with_context(|| format!("writing {}", p.display()))?;
    }
    if args.plot {
        super::plot::plot_trajectory(&case.trajectory, &stage.join("trajectory.png"))?;
    }
    let written = od.commit()?;
    for n in case_files_in(&args.out) {
        if !written
            .iter()
            .any(|w| w.file_name().is_some_and(|f| f == n))
        {
            let p = args.out.join(n);
            std::fs::remove_file(&p)
                .with_context(|| format!("removing {} of the earlier case", p.display()))?;
        }
    }
    Ok(())
}

/// Runs `host-sim simulate`: the case is written as `run` writes its outputs (staged in
/// `--out`, moved into place at the end; see [`OutDir`]), over an earlier case only with
/// `--force`.
pub fn run(args: SimulateArgs) -> anyhow::Result<()> {
    let path = resolve_scenario(&args.scenario)?;
    let scenario = Scenario::from_file(&path)?;
    let mut errors = ErrorModel::load(&args.errors)?;
    errors.gnss.outages.extend(args.outages.iter().copied());
    if let Some(r) = args.gnss_rate_hz {
        errors.gnss.rate_hz = r;
    }
    errors.validate()?;
    // the folder checked before anything is created in it, and again under its lock
    let inputs = [path.clone(), PathBuf::from(&args.errors)];
    nav_engine::run::outdir::check_inputs(&args.out, &inputs)?;
    check_no_case(&args.out, args.force)?;
    let t = std::time::Instant::now();
    let case = simulate(&scenario, &errors, args.seed)?;
    let t_sim = t.elapsed().as_secs_f64();
    let od = OutDir::open(&args.out, &inputs)?;
    check_no_case(&args.out, args.force)?;
    write_case(od, &case, &args)?;
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
