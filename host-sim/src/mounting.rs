//! `host-sim mounting`: the IMU mounting estimated from the data (the estimator and the
//! check live in `nav_engine::mounting`).

use nav_engine::mounting::estimate_mounting;

/// `host-sim mounting` arguments.
#[derive(clap::Args, Debug)]
pub struct MountingArgs {
    /// Run configuration (TOML); its `[imu.mounting]` is ignored.
    #[arg(long)]
    pub config: std::path::PathBuf,
}

/// `host-sim mounting --config FILE`: prints the `[imu.mounting]` section estimated from the
/// data.
pub fn run(a: MountingArgs) -> anyhow::Result<()> {
    let mut cfg = nav_io::read_run_config(&a.config)?;
    cfg.imu.mounting = nav_io::Mounting::identity();
    let dir = a.config.parent().map_or_else(
        || std::path::PathBuf::from("."),
        std::path::Path::to_path_buf,
    );
    let inp = cfg.load_inputs(&dir)?;
    for w in &inp.warnings {
        eprintln!("warning: {w}");
    }
    let est = estimate_mounting(&inp.imu.samples, &inp.gnss).map_err(|e| anyhow::anyhow!(e))?;
    print!("{}", est.toml_section());
    Ok(())
}
