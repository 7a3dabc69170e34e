//! `host-sim simulate`.

/// Arguments of `host-sim simulate`.
#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// Output directory.
    #[arg(long)]
    pub out: std::path::PathBuf,
}

/// Runs `host-sim simulate`.
pub fn run(args: SimulateArgs) -> anyhow::Result<()> {
    anyhow::bail!("simulate: not built yet ({})", args.out.display())
}
