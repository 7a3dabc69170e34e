//! `cargo xtask`: the project's automation, written in Rust so it runs wherever cargo does.
//!
//! - `setup`: installs what the embedded half needs (Debian `rustc-web`, `rust-web-src`,
//!   `rust-web-clippy`, `qemu-system-arm`, `socat`) when it is missing;
//! - `gen-vectors [--check]`: the firmware self-test's expected values from the host build;
//! - `fw build | run | size`: cross-build the firmware, run it on qemu (mps2-an386), report size;
//! - `ci`: everything CI checks, each step named and timed.

mod embedded;
mod vectors;

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

#[derive(Parser)]
#[command(
    name = "cargo xtask",
    about = "Project automation: setup, ci, firmware, vectors"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Install the embedded toolchain and emulator when missing (apt-get, as root only).
    Setup,
    /// Write (or with --check, verify) firmware/src/expected.rs from the host build of nav-core.
    GenVectors {
        /// Fail if the checked-in vector differs from what the host computes now.
        #[arg(long)]
        check: bool,
    },
    /// Firmware: build, run on qemu, or report its size.
    Fw {
        #[command(subcommand)]
        cmd: FwCmd,
    },
    /// Everything CI checks, in order, each step named and timed.
    Ci,
}

#[derive(Subcommand)]
enum FwCmd {
    /// Cross-build the firmware for thumbv7em-none-eabihf (release).
    Build,
    /// Build, then run the firmware on qemu-system-arm -machine mps2-an386.
    Run,
    /// Flash (text + rodata + data) and static RAM (data + bss) of the firmware ELF.
    Size,
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let res = match cli.cmd {
        Cmd::Setup => embedded::setup(),
        Cmd::GenVectors { check } => vectors::generate(check),
        Cmd::Fw { cmd } => match cmd {
            FwCmd::Build => embedded::fw_build().map(|_| ()),
            FwCmd::Run => embedded::fw_build().and_then(|elf| embedded::fw_run(&elf)),
            FwCmd::Size => embedded::fw_build().and_then(|elf| embedded::fw_size(&elf)),
        },
        Cmd::Ci => ci(),
    };
    match res {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// The workspace root (parent of this crate's manifest directory).
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// Runs a command in the workspace root, echoing it; fails on a non-zero exit.
pub fn run(cmd: &mut Command) -> Result<()> {
    eprintln!("  $ {}", show(cmd));
    let status = cmd
        .current_dir(root())
        .status()
        .with_context(|| format!("cannot start {}", show(cmd)))?;
    if !status.success() {
        bail!("`{}` failed ({status})", show(cmd));
    }
    Ok(())
}

fn show(cmd: &Command) -> String {
    let mut s = cmd.get_program().to_string_lossy().into_owned();
    for a in cmd.get_args() {
        s.push(' ');
        s.push_str(&a.to_string_lossy());
    }
    s
}

fn cargo() -> Command {
    Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
}

fn ci() -> Result<()> {
    let t0 = Instant::now();
    let mut steps: Vec<(&str, f64)> = Vec::new();
    let mut step = |name: &'static str, f: &mut dyn FnMut() -> Result<()>| -> Result<()> {
        eprintln!("\n==> [ci] {name}");
        let t = Instant::now();
        let r = f();
        let dt = t.elapsed().as_secs_f64();
        match &r {
            Ok(()) => eprintln!("<== [ci] {name}: ok in {dt:.1} s"),
            Err(e) => eprintln!("<== [ci] {name}: FAILED after {dt:.1} s: {e:#}"),
        }
        steps.push((name, dt));
        r
    };
    step("setup: embedded toolchain and emulator", &mut || {
        embedded::setup()
    })?;
    step(
        "cargo fmt --check (host workspace and firmware)",
        &mut || {
            run(cargo().args(["fmt", "--all", "--check"]))?;
            run(cargo().args(["fmt", "--manifest-path", "firmware/Cargo.toml", "--check"]))
        },
    )?;
    step(
        "cargo clippy -D warnings (host crates, all targets)",
        &mut || {
            run(cargo().args([
                "clippy",
                "--workspace",
                "--all-targets",
                "--release",
                "--",
                "-D",
                "warnings",
            ]))
        },
    )?;
    step(
        "cargo clippy -D warnings (nav-core for thumbv7em-none-eabihf)",
        &mut || embedded::clippy_nav_core_thumb(),
    )?;
    step(
        "self-test vector is what the host computes now",
        &mut || vectors::generate(true),
    )?;
    step(
        "host test suite (cargo test --workspace --release)",
        &mut || run(cargo().args(["test", "--workspace", "--release"])),
    )?;
    step(
        "nav-core builds for thumbv7em-none-eabihf with core only (no alloc, no std)",
        &mut || embedded::nav_core_thumb_build(),
    )?;
    let mut elf = PathBuf::new();
    step(
        "firmware build (thumbv7em-none-eabihf, release)",
        &mut || {
            elf = embedded::fw_build()?;
            Ok(())
        },
    )?;
    step(
        "firmware self-test on qemu mps2-an386 (Cortex-M4F)",
        &mut || embedded::fw_run(&elf),
    )?;
    step("firmware size report", &mut || embedded::fw_size(&elf))?;
    eprintln!("\n[ci] summary");
    for (name, dt) in &steps {
        eprintln!("  {dt:7.1} s  {name}");
    }
    eprintln!(
        "[ci] all {} steps passed in {:.1} s",
        steps.len(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}
