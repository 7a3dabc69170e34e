//! The `hw-bridge` command line.
use clap::{Parser, Subcommand};
use hw_bridge::cmd;
use std::process::ExitCode;

mod cli;

/// Exit status of `hw-bridge`, shown under `--help`.
const EXIT_CODES: &str = "\
Exit status:
  0        done, outputs complete (--help and --version too)
  1        error: a bad option or value, an unreadable or damaged input, an output that
           could not be written (the message names the cause once)
  2        finished but incomplete: the outputs hold everything up to the fault and say so
           (e.g. replay --config whose filter run is not a navigation solution)
  130/143  stopped by SIGINT/SIGTERM (128 + the signal): a replay's outputs kept as *.partial
           (record: SIGINT/SIGTERM end the recording normally, exit 0, the capture complete)";

/// Serial bridge between a navigation board or GNSS receiver and nav-core.
#[derive(Parser, Debug)]
#[command(name = "hw-bridge", version, about, after_help = EXIT_CODES)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// List serial ports (pseudo-terminals can always be opened by path).
    Ports,
    /// Record raw bytes with receive timestamps into a capture file.
    Record(cli::RecordArgs),
    /// Decode a capture (its chunking and, with --speed, its timing) into text files, or
    /// stream it back out to a port.
    Replay(cli::ReplayArgs),
    /// Stream a simulated case (imu.txt, gnss.txt) into a port as frames.
    Send(cli::SendArgs),
    /// Live decode of a board's frames and a GNSS receiver, with health.
    Stream(cli::StreamArgs),
}

/// Exit status: 0 complete, 2 finished but incomplete (outputs hold everything up to the
/// fault and say so), 1 error (the message names the cause once), 128 + the signal when
/// SIGINT/SIGTERM stopped a replay (130, 143: its outputs kept as `*.partial`).
fn main() -> ExitCode {
    // clap's own usage errors exit 2, which means "incomplete" here: they exit 1.
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() {
                ExitCode::FAILURE
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    if matches!(cli.cmd, Cmd::Record(_) | Cmd::Replay(_)) {
        // SIGINT/SIGTERM: a recording ends with its capture complete, a replay keeps what it
        // decoded as *.partial (else the system's default)
        if matches!(cli.cmd, Cmd::Record(_)) {
            nav_engine::run::interrupt::say_on_stop(
                cmd::RECORD_KEPT_ON_STOP,
                "the capture is left as OUT.partial",
            );
        }
        if let Err(e) = nav_engine::run::interrupt::install() {
            eprintln!("warning: SIGINT/SIGTERM handling not installed: {e}");
        }
    }
    match run(cli.cmd) {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::from(2),
        Err(e) => {
            eprintln!("error: {}", hw_bridge::status::error_chain(&e));
            match nav_engine::run::interrupt::exit_code() {
                Some(code) => ExitCode::from(code),
                None => ExitCode::FAILURE,
            }
        }
    }
}

/// Runs a command: `Ok(true)` when its outputs are complete.
fn run(cmd: Cmd) -> anyhow::Result<bool> {
    let mut complete = true;
    match cmd {
        Cmd::Ports => {
            let ports = hw_bridge::serial::list()?;
            if ports.is_empty() {
                println!("(no serial ports reported; pseudo-terminals open by path)");
            }
            for p in ports {
                println!("{p}");
            }
        }
        Cmd::Record(a) => {
            let o = cmd::record(&(&a).into())?;
            println!(
                "recorded {} records, {} bytes, {} link resets",
                o.records, o.bytes, o.link_resets
            );
            println!("{}", hw_bridge::status::decoder_report(&o.stats));
            if let Some(sig) = &o.stopped_by {
                println!("stopped by {sig}; capture {} complete", a.out.display());
            }
            if let Some(why) = &o.incomplete {
                eprintln!("incomplete: {why}");
                complete = false;
            }
        }
        Cmd::Replay(a) => {
            let o = cmd::replay(&(&a).into())?;
            let mb = o.bytes as f64 / 1e6;
            println!(
                "replayed {} records, {} bytes ({:.3} s recorded) in {:.3} s wall ({:.1} MB/s)",
                o.records,
                o.bytes,
                o.recorded_s,
                o.wall_s,
                mb / o.wall_s.max(1e-9)
            );
            match a.input {
                cmd::InputKind::Frames => print!("{}", hw_bridge::status::decoder_report(&o.stats)),
                cmd::InputKind::Gnss => println!("{} GNSS fixes", o.gnss_fixes.len()),
            }
            if let Some(why) = &o.incomplete {
                println!("incomplete: {why}");
                complete = false;
            }
            if let Some(f) = &o.filter {
                let c = &f.output.counters;
                println!(
                    "filter: model {} ({} states), {} IMU epochs, GNSS {} used, {} rejected, {} withheld in {} outage(s); {:.3} s",
                    f.output.model.name(),
                    f.output.state_names.len(),
                    c.imu_epochs,
                    c.gnss_accepted,
                    c.gnss_rejected,
                    c.gnss_withheld,
                    f.output.outages.len(),
                    f.wall_s
                );
                print!("{}", nav_engine::metrics::summary_table(&f.metrics));
            }
        }
        Cmd::Send(a) => {
            let o = cmd::send(&(&a).into())?;
            println!(
                "sent {} frames, {} bytes in {:.3} s",
                o.frames, o.bytes, o.wall_s
            );
        }
        Cmd::Stream(a) => {
            let s = cmd::stream(&(&a).into())?;
            print!("{}", hw_bridge::status::decoder_report(&s.stats));
            if let Some(n) = s.host_solution {
                println!(
                    "host filter: {} IMU epochs, {} GNSS updates; last solution t {:.3} lat {:.8} lon {:.8} h {:.3}",
                    s.host_imu_epochs,
                    s.host_gnss_updates,
                    n.t_s,
                    n.lat_rad.to_degrees(),
                    n.lon_rad.to_degrees(),
                    n.h_m
                );
            }
        }
    }
    Ok(complete)
}
