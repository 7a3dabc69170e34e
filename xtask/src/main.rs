#![doc = include_str!("../README.md")]
//!
//! ## Commands
//!
//! - `setup`: installs what the embedded half needs (Debian `rustc-web`, `rust-web-src`,
//!   `rust-web-clippy`, `qemu-system-arm`, `socat`) when it is missing;
//! - `gen-vectors [--check]`: the firmware self-test's expected values from the host build;
//! - `fw build | run | size [--board B]`: cross-build the firmware, run its self-test on qemu
//!   (mps2-an386), report sizes;
//! - `fw test`: the on-target unit tests (covariance SPD in f32 over a long run, gating,
//!   reset) on qemu;
//! - `fw clippy`: clippy on nav-core for the thumb target with core only (the embedded
//!   toolchain's clippy);
//! - `fw bench`: instruction counts, sizes, stack and budgets on qemu `-icount shift=5`;
//! - `fw hil`: UART loopback, the navigation application's frame link, and `hw-bridge send`
//!   / `hw-bridge record` of a simulated drive through the `nav` firmware, over qemu's UART
//!   on a socket and a socat pty, compared with the host;
//! - `bench-replay [--hours H]`: `hw-bridge replay --config` of a 1-hour (or H-hour) 200 Hz
//!   capture against `host-sim run` on the same case (wall times, peak memory, ratio,
//!   identical output);
//! - `fuzz [--seconds S]`: every libFuzzer target of `fuzz/` for S seconds (default 60; not a CI
//!   step: the test suite replays the corpus and the regressions and runs each property on
//!   random inputs);
//! - `soak [--seconds S]`: `hw-bridge send` -> faulty pty link -> `hw-bridge record` for S
//!   seconds (default 600), counters balancing exactly at the end;
//! - `hostile [--keep]`: careless and hostile inputs of `host-sim run` and `hw-bridge
//!   replay` / `record` by family, each run of the release binaries bounded in time, and the
//!   table of tries, panics, hangs, silent wrong results, lost or clobbered files and
//!   messages without file and line;
//! - `lint [--update-allowlist]`: wording (no ticket references or work-log words in code and
//!   docs), no `clap` in the library crates, no clap argument struct taken by a `pub fn` of
//!   host-sim's or hw-bridge's library, function bodies of at most 120 lines (existing
//!   longer ones listed in `xtask/long-functions.txt`, which may only shrink);
//! - `test-host`: the host test suite only (no root, no embedded toolchain, no qemu);
//! - `ci`: everything CI checks, each step named and timed.

mod background;
mod benchrun;
mod budget;
mod embedded;
mod fuzz;
mod hil;
mod hostile;
mod lint;
mod replaybench;
mod soak;
mod vectors;

use embedded::Board;

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
    /// The project's own rules: wording of code and docs, no clap in library crates, no clap
    /// argument struct taken by a library function, function length (120 lines; the listed
    /// longer functions may only shrink).
    Lint {
        /// Lower the entries of xtask/long-functions.txt to the functions' current lengths and
        /// remove those within the limit (never adds or raises an entry).
        #[arg(long)]
        update_allowlist: bool,
    },
    /// The host test suite (`cargo test --workspace --profile ci`: release optimisation
    /// without LTO): no root, no embedded toolchain, no qemu needed.
    TestHost,
    /// Run every libFuzzer target of `fuzz/` for a bounded time (coverage-guided, address
    /// sanitizer; builds the instrumented targets first, about 2.5 CPU-minutes).
    Fuzz {
        /// Seconds per target.
        #[arg(long, default_value_t = 60)]
        seconds: u32,
    },
    /// The 10-minute soak: `hw-bridge send` and `record` over a pty link with random faults;
    /// per stream, frames sent = delivered + lost at the end.
    Soak {
        /// Seconds of sending.
        #[arg(long, default_value_t = 600)]
        seconds: u32,
    },
    /// Benchmark: wall time, CPU time and peak RSS of `host-sim run` and `diagnose` on a
    /// generated 200 Hz drive against a baseline `host-sim` built from git.
    BenchRun {
        /// Length of the generated drive, hours (0.6667 = the 40-minute case; 4 for the long
        /// case).
        #[arg(long, default_value_t = 40.0 / 60.0)]
        hours: f64,
        /// Git revision of the baseline `host-sim`.
        #[arg(long, default_value = "e9a1122")]
        baseline: String,
        /// Measurements per binary (median reported).
        #[arg(long, default_value_t = 1)]
        repeat: usize,
        /// Keep the case and outputs (the directory is printed).
        #[arg(long)]
        keep: bool,
        /// Skip `diagnose`.
        #[arg(long)]
        no_diagnose: bool,
        /// Skip `run --smooth`.
        #[arg(long)]
        no_smooth: bool,
        /// A prebuilt baseline `host-sim` (instead of building `--baseline` from git).
        #[arg(long)]
        baseline_bin: Option<std::path::PathBuf>,
        /// KF-GINS executable: run it on the same files in the same invocation and report the
        /// ratios (see docs/benchmarks.md for building it outside the repository).
        #[arg(long)]
        peer_kfgins: Option<std::path::PathBuf>,
        /// Also the rows of `run --smooth` and `diagnose` on a drive of this many hours (4:
        /// the long rows of docs/benchmarks.md), each binary measured once.
        #[arg(long)]
        long_hours: Option<f64>,
    },
    /// Careless and hostile inputs of `host-sim run` and `hw-bridge replay` / `record` by
    /// family (release binaries, each run bounded in time): a table of tries, panics, hangs,
    /// silent wrong results, lost or clobbered files, messages without file and line.
    Hostile {
        /// Keep the generated inputs and outputs (the folder is printed).
        #[arg(long)]
        keep: bool,
    },
    /// Benchmark: `hw-bridge replay --as-fast-as-possible --config` of a 1-hour 200 Hz
    /// capture (sent and recorded over a pty pair) against `host-sim run` on the same case.
    BenchReplay {
        /// Scenario to simulate (a shipped name or a TOML file).
        #[arg(long, default_value = "long")]
        scenario: String,
        /// Instead of the scenario, the generated drive of `bench-run` of this many hours
        /// (0 < hours <= 24).
        #[arg(long)]
        hours: Option<f64>,
        /// Run the `host-sim` and `hw-bridge` executables in this folder (e.g.
        /// `target/release`) instead of building the binaries of the host test suite (profile
        /// `ci`).
        #[arg(long)]
        bins: Option<PathBuf>,
        /// Keep the case, capture and outputs (the directory is printed).
        #[arg(long)]
        keep: bool,
    },
}

#[derive(Subcommand)]
enum FwCmd {
    /// Cross-build the firmware for thumbv7em-none-eabihf (release).
    Build {
        /// Board to build for.
        #[arg(long, value_enum, default_value = "mps2-an386")]
        board: Board,
    },
    /// Build, then run the self-test on qemu-system-arm -machine mps2-an386.
    Run,
    /// `cargo clippy -D warnings` on nav-core for thumbv7em-none-eabihf with core only (the
    /// embedded toolchain's clippy; CI's firmware build already proves nav-core core-only).
    Clippy,
    /// Build, then run the on-target unit tests (covariance SPD, gating, reset) on qemu.
    Test,
    /// Flash (text + rodata + data) and static RAM (data + bss) of the firmware ELFs.
    Size {
        /// Board to build for.
        #[arg(long, value_enum, default_value = "mps2-an386")]
        board: Board,
    },
    /// Instructions per call, sizes, peak stack and budget check (qemu -icount shift=5).
    Bench,
    /// UART loopback, the nav application's frame link, and `hw-bridge send`/`record` of a
    /// simulated drive through the nav firmware, via a socket + socat pty.
    Hil,
    /// The firmware steps of `ci` only (build, self-test, sizes, HIL, real board, budgets).
    Ci,
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let res = match cli.cmd {
        Cmd::Setup => embedded::setup(),
        Cmd::GenVectors { check } => vectors::generate(check),
        Cmd::Fw { cmd } => match cmd {
            FwCmd::Build { board } => embedded::fw_build(board).map(|_| ()),
            FwCmd::Clippy => embedded::clippy_nav_core_thumb(),
            FwCmd::Run => embedded::fw_build(Board::Mps2An386)
                .and_then(|b| embedded::fw_run(&b.elf("firmware"))),
            FwCmd::Test => embedded::fw_build(Board::Mps2An386)
                .and_then(|b| embedded::fw_run(&b.elf("ontarget"))),
            FwCmd::Size { board } => {
                embedded::fw_build(board).and_then(|b| embedded::fw_size(&b).map(|_| ()))
            }
            FwCmd::Bench => embedded::fw_build(Board::Mps2An386).and_then(|b| {
                let sizes = embedded::fw_size(&b)?;
                let bench = budget::run_bench(&b.elf("bench"))?;
                budget::report(&bench, &sizes, &[])
            }),
            FwCmd::Ci => fw_ci(),
            FwCmd::Hil => embedded::fw_build(Board::Mps2An386).and_then(|b| {
                hil::uart_echo(&b.elf("uart-echo"))?;
                hil::frame_link(&b.elf("nav"))?;
                let bins = hil::host_bins()?;
                hil::bridge_drive(&b.elf("nav"), &bins).map(|_| ())
            }),
        },
        Cmd::Ci => ci(),
        Cmd::Lint { update_allowlist } => lint::run(update_allowlist),
        Cmd::TestHost => test_host(),
        Cmd::Fuzz { seconds } => fuzz::run(seconds),
        Cmd::Soak { seconds } => soak::run(seconds),
        Cmd::BenchReplay {
            scenario,
            hours,
            bins,
            keep,
        } => replaybench::run(&scenario, hours, bins.as_deref(), keep),
        Cmd::Hostile { keep } => hostile::run(keep),
        Cmd::BenchRun {
            hours,
            baseline,
            repeat,
            keep,
            no_diagnose,
            no_smooth,
            baseline_bin,
            peer_kfgins,
            long_hours,
        } => benchrun::run(&benchrun::Opts {
            hours,
            baseline,
            baseline_bin,
            repeat,
            keep,
            no_diagnose,
            no_smooth,
            peer_kfgins,
            long_hours,
        }),
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

/// The command line of `cmd` as one string.
pub fn show(cmd: &Command) -> String {
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
    // Both boards' firmware builds (their own cargo target directory) run from here on in the
    // background, niced: they take the cores the host build and the test run leave idle.
    let mut fw_bg = start_firmware_builds()?;
    step(
        "cargo fmt --check (host workspace and firmware)",
        &mut || {
            run(cargo().args(["fmt", "--all", "--check"]))?;
            run(cargo().args(["fmt", "--manifest-path", "firmware/Cargo.toml", "--check"]))
        },
    )?;
    step(
        "lint: wording, no clap in library crates or library functions, function length ratchet",
        &mut || lint::run(false),
    )?;
    step(
        "cargo clippy -D warnings (host crates, all targets)",
        &mut || {
            run(cargo().args([
                "clippy",
                "--workspace",
                "--all-targets",
                "--profile",
                "ci",
                "--",
                "-D",
                "warnings",
            ]))
        },
    )?;
    step(
        "cargo doc -D warnings (host crates: every doc link resolves, none to a private item)",
        &mut || {
            run(cargo().env("RUSTDOCFLAGS", "-D warnings").args([
                "doc",
                "--workspace",
                "--no-deps",
                "--profile",
                "ci",
            ]))
        },
    )?;
    step(
        "self-test vector is what the host computes now",
        &mut || vectors::generate(true),
    )?;
    step(
        "host test suite (cargo test --workspace --profile ci)",
        &mut test_host,
    )?;
    firmware_steps(&mut step, &mut fw_bg)?;
    eprintln!("\n[ci] summary");
    for (name, dt) in &steps {
        eprintln!("  {dt:7.1} s  {name}");
    }
    for (name, dt) in fw_bg.finished() {
        eprintln!("  {dt:7.1} s  (in the background, overlapping the steps above) {name}");
    }
    eprintln!(
        "[ci] all {} steps passed in {:.1} s",
        steps.len(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The host test suite: every host crate's tests in the `ci` profile (release optimisation
/// without LTO; see the workspace's Cargo.toml), as CI builds them.
fn test_host() -> Result<()> {
    run(cargo().args(["test", "--workspace", "--profile", "ci"]))
}

/// The firmware builds CI runs in the background: each board's ELFs, labelled by board name.
type FwBackground = background::Background<embedded::FwBuild>;

/// Starts both boards' firmware builds (emulated board first) in the background, niced, their
/// output in `target/embedded/ci-firmware-build.log`.
fn start_firmware_builds() -> Result<FwBackground> {
    let mut jobs = Vec::new();
    for board in [Board::Mps2An386, Board::Stm32f407] {
        jobs.push(background::Job {
            label: board.name().to_string(),
            command: background::niced(embedded::fw_build_command(board)?),
            then: Box::new(move || embedded::fw_collect(board)),
        });
    }
    let log = root().join("target/embedded/ci-firmware-build.log");
    eprintln!(
        "  firmware builds (boards {}, {}) started in the background, log {}",
        Board::Mps2An386.name(),
        Board::Stm32f407.name(),
        log.display()
    );
    background::Background::start(jobs, &log)
}

/// A step runner: runs the closure under the step's name, timing it.
type StepFn<'a> = dyn FnMut(&'static str, &mut dyn FnMut() -> Result<()>) -> Result<()> + 'a;

/// The firmware half of CI, in order: build (emulated board), self-test, sizes, the two HIL
/// tests, the real board's build and size, and the budget check (last, so everything else has
/// been checked when a budget fails). `step` names, times and runs each. The two build steps
/// wait for the builds `bg` runs in the background (see [`start_firmware_builds`]); their own
/// build times are printed.
fn firmware_steps(step: &mut StepFn, bg: &mut FwBackground) -> Result<()> {
    let mut fw: Option<embedded::FwBuild> = None;
    step(
        "firmware build (thumbv7em-none-eabihf, release, board mps2-an386)",
        &mut || {
            fw = Some(bg.wait(Board::Mps2An386.name())?);
            Ok(())
        },
    )?;
    let fw = fw.context("firmware build produced nothing")?;
    step(
        "firmware self-test on qemu mps2-an386 (Cortex-M4F)",
        &mut || embedded::fw_run(&fw.elf("firmware")),
    )?;
    step(
        "firmware on-target unit tests on qemu (covariance SPD over a long f32 run, gating, reset)",
        &mut || embedded::fw_run(&fw.elf("ontarget")),
    )?;
    let mut sizes = Vec::new();
    step("firmware size report", &mut || {
        sizes = embedded::fw_size(&fw)?;
        Ok(())
    })?;
    step(
        "HIL: UART loopback through qemu UART0 socket + socat pty",
        &mut || hil::uart_echo(&fw.elf("uart-echo")),
    )?;
    let mut nav_stack = 0u64;
    step(
        "HIL: nav application frame link (IMU/GNSS/config in, solutions/health out) vs host",
        &mut || {
            nav_stack = hil::frame_link(&fw.elf("nav"))?;
            Ok(())
        },
    )?;
    step(
        "HIL: hw-bridge send/record of a simulated drive (GNSS outages, stops, missing IMU samples and an implausible sample, land aiding on) through the nav firmware vs host, bit-exact",
        &mut || {
            let bins = hil::host_bins()?;
            nav_stack = nav_stack.max(hil::bridge_drive(&fw.elf("nav"), &bins)?);
            Ok(())
        },
    )?;
    let mut real_sizes = Vec::new();
    step(
        "real board firmware build (stm32f407) and size",
        &mut || {
            let b = bg.wait(Board::Stm32f407.name())?;
            for (bin, s) in embedded::fw_size(&b)? {
                real_sizes.push((format!("{}:{bin}", b.board.name()), s));
            }
            Ok(())
        },
    )?;
    step(
        "firmware budgets: bench on qemu -icount shift=5 (instructions, flash, RAM + stack)",
        &mut || {
            let bench = budget::run_bench(&fw.elf("bench"))?;
            if let Some((_, s)) = sizes.iter().find(|(n, _)| *n == "nav") {
                let total = s.ram() + nav_stack;
                eprintln!(
                    "  nav app (HIL run): static RAM {} B + peak stack {} B = {} B (budget {} B)",
                    s.ram(),
                    nav_stack,
                    total,
                    budget::RAM_STACK_BUDGET
                );
                if total >= budget::RAM_STACK_BUDGET {
                    bail!("nav app static RAM + peak stack {total} B over budget");
                }
            }
            budget::report(&bench, &sizes, &real_sizes)
        },
    )?;
    Ok(())
}

/// `cargo xtask fw ci`: set-up and the firmware steps of `ci` only.
fn fw_ci() -> Result<()> {
    let t0 = Instant::now();
    let mut n = 0usize;
    let mut step = |name: &'static str, f: &mut dyn FnMut() -> Result<()>| -> Result<()> {
        eprintln!("\n==> [fw ci] {name}");
        let t = Instant::now();
        let r = f();
        let dt = t.elapsed().as_secs_f64();
        match &r {
            Ok(()) => eprintln!("<== [fw ci] {name}: ok in {dt:.1} s"),
            Err(e) => eprintln!("<== [fw ci] {name}: FAILED after {dt:.1} s: {e:#}"),
        }
        n += 1;
        r
    };
    step("setup: embedded toolchain and emulator", &mut || {
        embedded::setup()
    })?;
    let mut bg = start_firmware_builds()?;
    firmware_steps(&mut step, &mut bg)?;
    eprintln!(
        "[fw ci] all {n} steps passed in {:.1} s",
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}
