//! The `host-sim` command line.
use clap::{Parser, Subcommand};

/// Exit status of `host-sim`, shown under `--help`.
const EXIT_CODES: &str = "\
Exit status:
  0        done (--help and --version too)
  1        error: a bad option or value, an input or configuration error, an output that
           could not be written (the message names the cause, with file and line)
  2        not a navigation solution: no GNSS fix (or too few) used; the outputs, when
           written, are a dead-reckoning track
  130/143  stopped by SIGINT/SIGTERM (128 + the signal): run keeps its outputs so far as
           *.partial; diagnose keeps the search rounds decided before the signal as
           report.md.partial, diagnosis.json.partial and nav_before.txt.partial (no
           nav_after.txt or augmented.toml; nothing before its first round is decided)";

/// INS/GNSS navigation core on the host: simulate, identify noise, run, study, diagnose.
#[derive(Parser, Debug)]
#[command(name = "host-sim", version, about, long_about = None, after_help = EXIT_CODES)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Allan/modified/Hadamard deviation of an IMU record, noise-model fit, plots, config.
    Allan(host_sim::allan::cli::AllanArgs),
    /// Simulate a case (trajectory, IMU with errors, GNSS, truth) into the project's formats.
    Simulate(host_sim::sim::cli::SimulateArgs),
    /// The source's simulation study: N vs NBK models, continuous GNSS vs a 5-minute outage,
    /// Monte Carlo true errors, NEES and an error budget; writes a report.
    Study(host_sim::study::StudyArgs),
    /// Run the filter on a case (simulated or real): nav.txt, std.txt, bias.txt,
    /// innovations.txt and metrics.json, with imposed GNSS outages.
    Run(host_sim::run::cli::RunArgs),
    /// Find the effects the model lacks from the innovations, add each one whose held-out
    /// prediction is significantly better, and write report.md, diagnosis.json,
    /// augmented.toml, nav_before.txt, nav_after.txt and plots.
    ///
    /// Each search round says `round N decided: ...` on stderr (not with --quiet). Ctrl-C
    /// (SIGINT) or SIGTERM ends the runs and keeps the rounds decided before the signal as
    /// report.md.partial, diagnosis.json.partial ("complete": false) and
    /// nav_before.txt.partial, exit 130/143: the round in progress is dropped, there is no
    /// nav_after.txt or augmented.toml, and nothing is kept before the first round is
    /// decided. A second signal ends it at once.
    Diagnose(host_sim::diagnose::DiagnoseArgs),
    /// Estimate the IMU-to-body rotation from the data (the configured [imu.mounting] is
    /// ignored) and print the [imu.mounting] section to paste.
    Mounting(host_sim::mounting::MountingArgs),
    /// Write a run configuration from the IMU and GNSS files (formats, columns, units, time
    /// kind, rest, mounting, initial sigmas), each guess commented with its evidence.
    Init(host_sim::init::InitArgs),
}

fn main() -> std::process::ExitCode {
    // clap's usage errors exit 2, which means "not a navigation solution" here: they exit 1
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() {
                std::process::ExitCode::FAILURE
            } else {
                std::process::ExitCode::SUCCESS
            };
        }
    };
    if matches!(cli.cmd, Cmd::Run(_) | Cmd::Diagnose(_)) {
        // SIGINT/SIGTERM: a run keeps what it processed as *.partial, a diagnosis ends its
        // runs and keeps the rounds it decided as *.partial (else the system's default)
        if matches!(cli.cmd, Cmd::Diagnose(_)) {
            nav_engine::run::interrupt::say_on_stop(
                host_sim::diagnose::KEPT_ON_STOP,
                host_sim::diagnose::KEPT_ON_EXIT,
            );
        }
        if let Err(e) = nav_engine::run::interrupt::install() {
            eprintln!("warning: SIGINT/SIGTERM handling not installed: {e}");
        }
    }
    let res = match cli.cmd {
        Cmd::Allan(a) => host_sim::allan::cli::run(a),
        Cmd::Simulate(a) => host_sim::sim::cli::run(a),
        Cmd::Study(a) => host_sim::study::run(a),
        Cmd::Run(a) => host_sim::run::cli::run(a),
        Cmd::Diagnose(a) => host_sim::diagnose::run(a),
        Cmd::Mounting(a) => host_sim::mounting::run(a),
        Cmd::Init(a) => host_sim::init::run(a),
    };
    match res {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_chain(&e));
            // stopped by a signal: 128 + its number, as a shell reports it; outputs written
            // but a dead-reckoning track ("incomplete"): 2
            if let Some(code) = nav_engine::run::interrupt::exit_code() {
                std::process::ExitCode::from(code)
            } else if e
                .downcast_ref::<nav_engine::run::gnss_use::NotANavigationSolution>()
                .is_some()
            {
                std::process::ExitCode::from(2)
            } else {
                std::process::ExitCode::FAILURE
            }
        }
    }
}

/// The error and its causes on one line, each said once: `nav_io::IoError` prints its
/// source in its own message, so a cause the line already contains is not repeated (compared
/// without its trailing line end: a message that adds a hint after its cause trims it).
fn error_chain(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for text in e.chain().map(ToString::to_string) {
        let text = text.trim_end();
        if !text.is_empty() && !out.contains(text) {
            if !out.is_empty() {
                out.push_str(": ");
            }
            out.push_str(text);
        }
    }
    out
}
