//! The `hw-bridge` command line.
use clap::{Parser, Subcommand};

/// Serial bridge between a navigation board or GNSS receiver and nav-core.
#[derive(Parser, Debug)]
#[command(name = "hw-bridge", version, about)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// List serial ports (pseudo-terminals can always be opened by path).
    Ports,
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().cmd {
        Cmd::Ports => {
            for p in serialport::available_ports()? {
                println!("{}", p.port_name);
            }
            Ok(())
        }
    }
}
