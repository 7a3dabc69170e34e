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
//! (3)/(2): the framing overhead. A benchmark, not a test: wall times depend on the machine.

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

fn timed(cmd: &mut Command) -> Result<(f64, String)> {
    eprintln!("  $ {}", crate::show(cmd));
    let t = Instant::now();
    let out = cmd
        .stdin(Stdio::null())
        .output()
        .with_context(|| format!("starting {}", crate::show(cmd)))?;
    let dt = t.elapsed().as_secs_f64();
    let so = String::from_utf8_lossy(&out.stdout).into_owned();
    if !out.status.success() {
        bail!(
            "`{}` failed ({}): {so}{}",
            crate::show(cmd),
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
    }
    Ok((dt, so))
}

/// Runs the benchmark in `dir` (kept when `keep`).
pub fn run(scenario: &str, keep: bool) -> Result<()> {
    let bins = host_bins()?;
    let dir = std::env::temp_dir().join(format!("navcore-bench-replay-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let r = run_in(&bins, &dir, scenario);
    if keep {
        eprintln!("  kept {}", dir.display());
    } else {
        let _ = std::fs::remove_dir_all(&dir);
    }
    r
}

fn run_in(bins: &HostBins, dir: &Path, scenario: &str) -> Result<()> {
    let case = dir.join("case");
    let (t_sim, so) = timed(
        Command::new(&bins.host_sim)
            .args(["simulate", "--scenario", scenario, "--errors", "tactical"])
            .args(["--seed", "1", "--kf-gins", "--out"])
            .arg(&case),
    )?;
    eprint!("  {so}");
    eprintln!("  simulate: {t_sim:.1} s");
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
    let (t_send, so) = timed(
        Command::new(&bins.hw_bridge)
            .args(["send", "--quiet", "--as-fast-as-possible", "--case"])
            .arg(&case)
            .arg("--port")
            .arg(&a),
    )?;
    let st = rec.wait()?;
    drop(socat);
    if !st.success() {
        bail!("hw-bridge record failed ({st})");
    }
    let cap_bytes = std::fs::metadata(&cap)?.len();
    eprintln!(
        "  send over the pty pair: {} in {t_send:.1} s; capture {:.1} MB",
        so.trim(),
        cap_bytes as f64 / 1e6
    );

    let (t_dec, so_dec) = timed(
        Command::new(&bins.hw_bridge)
            .args(["replay", "--as-fast-as-possible"])
            .arg(&cap),
    )?;
    let config = case.join("kf-gins.yaml");
    let out_sim = dir.join("out-sim");
    let (t_sim_run, _) = timed(
        Command::new(&bins.host_sim)
            .args(["run", "--quiet", "--config"])
            .arg(&config)
            .arg("--out")
            .arg(&out_sim),
    )?;
    let out_rep = dir.join("out-replay");
    let (t_rep, so_rep) = timed(
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
    let filter_line = so_rep
        .lines()
        .find(|l| l.starts_with("filter:"))
        .unwrap_or("")
        .to_string();
    eprintln!(
        "\n  replay, decode only: {} ({t_dec:.2} s wall incl. process start)",
        first(&so_dec)
    );
    eprintln!("  replay --config:    {} ", first(&so_rep));
    eprintln!("                      {filter_line}");
    eprintln!("  host-sim run on the case files:         {t_sim_run:7.2} s wall");
    eprintln!("  hw-bridge replay --config on capture:   {t_rep:7.2} s wall");
    eprintln!(
        "  ratio replay / host-sim run: {:.3} (framing, decoding and capture reading {:+.2} s)",
        t_rep / t_sim_run,
        t_rep - t_sim_run
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
