//! `cargo xtask bench-replay`: the cost of the bridge on a long drive. `host-sim simulate`
//! writes the shipped one-hour 200 Hz drive (`scenarios/long.toml`, KF-GINS configuration),
//! `hw-bridge send --as-fast-as-possible` streams it over a socat pty pair into `hw-bridge
//! record`, then the capture is replayed three ways, each timed on the wall clock:
//!
//! 1. `hw-bridge replay --as-fast-as-possible` (decode only): bytes per second;
//! 2. `host-sim run --config kf-gins.yaml` on the case files;
//! 3. `hw-bridge replay --as-fast-as-possible --config kf-gins.yaml` on the capture.
//!
//! and (3)'s `nav.txt` must be byte-identical to (2)'s. It prints the times and the ratio
//! (3)/(2): the framing overhead, and the peak resident set of each command (its own
//! `VmHWM`, read while it runs: [`test_support::cli::try_run_bounded`]). `--hours H` drives
//! the generated drive of `cargo xtask bench-run` of H hours instead of the scenario, so that
//! the peaks of a short and a long capture can be held side by side (the replay's memory must
//! not grow with the capture). A benchmark, not a test: wall times depend on the machine.

use crate::benchrun::{measure_with_output, Meas};
use crate::hil::{host_bins, HostBins};
use anyhow::{bail, Context, Result};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

struct Kill(Child);
impl Drop for Kill {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// One command run to its end: its figures ([`Meas`]) and its standard output.
struct Timed {
    meas: Meas,
    stdout: String,
}

/// [`measure_with_output`] as a [`Timed`].
fn timed(cmd: &mut Command) -> Result<Timed> {
    let (meas, stdout) = measure_with_output(cmd)?;
    Ok(Timed { meas, stdout })
}

/// Runs the benchmark in `dir` (kept when `keep`) on `scenario`, or with `hours` on the
/// generated drive of that many hours; with `bins` the executables in that folder.
pub fn run(scenario: &str, hours: Option<f64>, bins: Option<&Path>, keep: bool) -> Result<()> {
    if let Some(h) = hours.filter(|h| !(*h > 0.0 && *h <= 24.0)) {
        bail!("--hours {h}: expected 0 < hours <= 24");
    }
    let bins = match bins {
        Some(d) => HostBins {
            host_sim: d.join("host-sim"),
            hw_bridge: d.join("hw-bridge"),
        },
        None => host_bins()?,
    };
    let dir = std::env::temp_dir().join(format!("navcore-bench-replay-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let r = match hours {
        Some(h) => {
            let sc = dir.join("scenario.toml");
            std::fs::write(&sc, crate::benchrun::scenario(h * 3600.0))?;
            run_in(&bins, &dir, &sc.to_string_lossy())
        }
        None => run_in(&bins, &dir, scenario),
    };
    if keep {
        eprintln!("  kept {}", dir.display());
    } else {
        let _ = std::fs::remove_dir_all(&dir);
    }
    r
}

fn run_in(bins: &HostBins, dir: &Path, scenario: &str) -> Result<()> {
    let case = dir.join("case");
    let sim = timed(
        Command::new(&bins.host_sim)
            .args(["simulate", "--scenario", scenario, "--errors", "tactical"])
            .args(["--seed", "1", "--kf-gins", "--out"])
            .arg(&case),
    )?;
    eprint!("  {}", sim.stdout);
    eprintln!("  simulate: {:.1} s", sim.meas.wall_s);
    let cap = capture(bins, dir, &case)?;
    let cap_bytes = std::fs::metadata(&cap)?.len();
    eprintln!("  capture {:.1} MB", cap_bytes as f64 / 1e6);

    let dec = timed(
        Command::new(&bins.hw_bridge)
            .args(["replay", "--as-fast-as-possible"])
            .arg(&cap),
    )?;
    let config = case.join("kf-gins.yaml");
    let out_sim = dir.join("out-sim");
    let sim_run = timed(
        Command::new(&bins.host_sim)
            .args(["run", "--quiet", "--config"])
            .arg(&config)
            .arg("--out")
            .arg(&out_sim),
    )?;
    let out_rep = dir.join("out-replay");
    let rep = timed(
        Command::new(&bins.hw_bridge)
            .args(["replay", "--as-fast-as-possible"])
            .arg(&cap)
            .arg("--config")
            .arg(&config)
            .arg("--out")
            .arg(&out_rep),
    )?;
    let same = std::fs::read(out_sim.join("nav.txt"))? == std::fs::read(out_rep.join("nav.txt"))?;
    let first = |s: &str| s.lines().next().unwrap_or("").to_string();
    let filter_line = rep
        .stdout
        .lines()
        .find(|l| l.starts_with("filter:"))
        .unwrap_or("")
        .to_string();
    eprintln!(
        "\n  replay, decode only: {} ({:.2} s wall incl. process start)",
        first(&dec.stdout),
        dec.meas.wall_s
    );
    eprintln!("  replay --config:    {} ", first(&rep.stdout));
    eprintln!("                      {filter_line}");
    for (what, t) in [
        ("hw-bridge replay (decode only)", &dec),
        ("host-sim run on the case files", &sim_run),
        ("hw-bridge replay --config on capture", &rep),
    ] {
        eprintln!(
            "  {what:<38} {:8.2} s wall, peak {:7.1} MiB",
            t.meas.wall_s, t.meas.rss_mib
        );
    }
    eprintln!(
        "  ratio replay / host-sim run: {:.3} (framing, decoding and capture reading {:+.2} s)",
        rep.meas.wall_s / sim_run.meas.wall_s,
        rep.meas.wall_s - sim_run.meas.wall_s
    );
    eprintln!(
        "  nav.txt of the replay is {} to host-sim run's",
        if same { "byte-identical" } else { "DIFFERENT" }
    );
    if !same {
        bail!("replay --config and host-sim run disagree on the same drive");
    }
    Ok(())
}

/// `hw-bridge send --as-fast-as-possible` of `case` over a socat pty pair into `hw-bridge
/// record`: the capture's path.
fn capture(bins: &HostBins, dir: &Path, case: &Path) -> Result<std::path::PathBuf> {
    // send -> pty pair -> record
    let a = dir.join("A");
    let b = dir.join("B");
    let socat = Kill(
        Command::new("socat")
            .arg(format!("pty,raw,echo=0,link={}", a.display()))
            .arg(format!("pty,raw,echo=0,link={}", b.display()))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .context("starting socat")?,
    );
    let t0 = Instant::now();
    while !(a.exists() && b.exists()) {
        if t0.elapsed() > Duration::from_secs(10) {
            bail!("socat made no pty pair");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let cap = dir.join("drive.cap");
    let mut rec = Command::new(&bins.hw_bridge);
    rec.args(["record", "--quiet", "--idle-exit", "3", "--port"])
        .arg(&b)
        .arg("--out")
        .arg(&cap)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    eprintln!("  $ {}", crate::show(&rec));
    let mut rec = rec.spawn().context("starting hw-bridge record")?;
    let mut err = std::io::BufReader::new(rec.stderr.take().context("record stderr")?);
    let mut line = String::new();
    std::io::BufRead::read_line(&mut err, &mut line)?;
    let send = timed(
        Command::new(&bins.hw_bridge)
            .args(["send", "--quiet", "--as-fast-as-possible", "--case"])
            .arg(case)
            .arg("--port")
            .arg(&a),
    )?;
    let st = rec.wait()?;
    drop(socat);
    if !st.success() {
        bail!("hw-bridge record failed ({st})");
    }
    eprintln!(
        "  send over the pty pair: {} in {:.1} s",
        send.stdout.trim(),
        send.meas.wall_s
    );
    Ok(cap)
}
