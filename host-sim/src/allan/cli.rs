//! `host-sim allan`.

/// Arguments of `host-sim allan`.
#[derive(clap::Args, Debug)]
pub struct AllanArgs {
    /// IMU file to analyse.
    pub input: std::path::PathBuf,
}

/// Runs `host-sim allan`.
pub fn run(args: AllanArgs) -> anyhow::Result<()> {
    anyhow::bail!("allan: not built yet ({})", args.input.display())
}
