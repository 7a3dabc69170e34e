//! The bounded fuzz run of CI: every cargo-fuzz target of `fuzz/` (libFuzzer, address
//! sanitizer) for a fixed time, seeded with the committed corpus, into a scratch corpus
//! directory (so the committed one stays small). A crash fails the step; libFuzzer saves the
//! input under `fuzz/artifacts/<target>/` and it belongs in `fuzz/regressions/<target>/`,
//! which `hw-bridge/tests/it/fuzz_corpus.rs` replays in the ordinary test suite.
//!
//! cargo-fuzz needs nightly compiler features (`-Zsanitizer`); the stable toolchain accepts
//! them with `RUSTC_BOOTSTRAP=1`. When `cargo fuzz` is missing it is installed from crates.io
//! (`cargo install cargo-fuzz --locked`); when that fails too, the step says so and skips
//! (the bounded random-input tests of `fuzz_corpus.rs` still run in the test suite).

use anyhow::{bail, Result};
use std::process::{Command, Stdio};
use std::time::Instant;

/// The targets in `fuzz/fuzz_targets/`.
pub const TARGETS: [&str; 4] = ["wire_decoder", "nmea", "gnss_stream", "capture"];

fn cargo() -> Command {
    Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
}

fn have_cargo_fuzz() -> bool {
    cargo()
        .args(["fuzz", "--version"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Runs every target for `seconds_each` seconds. Returns false when it had to skip.
pub fn run(seconds_each: u32) -> Result<bool> {
    if !have_cargo_fuzz() {
        eprintln!("  cargo-fuzz not found: installing it from crates.io");
        let ok = crate::run(cargo().args(["install", "cargo-fuzz", "--locked"])).is_ok();
        if !ok || !have_cargo_fuzz() {
            eprintln!(
                "  SKIPPED fuzz run: cargo-fuzz is not available and could not be installed \
                 (the corpus and bounded random-input tests ran in the test suite)"
            );
            return Ok(false);
        }
    }
    let fuzz_dir = crate::root().join("fuzz");
    let scratch = std::env::temp_dir().join(format!("navcore-fuzz-{}", std::process::id()));
    let mut build = cargo();
    build
        .args(["fuzz", "build"])
        .env("RUSTC_BOOTSTRAP", "1")
        .current_dir(&fuzz_dir);
    eprintln!("  $ (in fuzz/) RUSTC_BOOTSTRAP=1 {}", crate::show(&build));
    if !build.status()?.success() {
        bail!("cargo fuzz build failed");
    }
    for t in TARGETS {
        let work = scratch.join(t);
        std::fs::create_dir_all(&work)?;
        let mut c = cargo();
        c.args(["fuzz", "run", t])
            .arg(&work)
            .arg(fuzz_dir.join("corpus").join(t))
            .arg("--")
            .arg(format!("-max_total_time={seconds_each}"))
            .arg("-print_final_stats=1")
            .env("RUSTC_BOOTSTRAP", "1")
            .current_dir(&fuzz_dir)
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        eprintln!("  $ (in fuzz/) RUSTC_BOOTSTRAP=1 {}", crate::show(&c));
        let t0 = Instant::now();
        let out = c.output()?;
        let err = String::from_utf8_lossy(&out.stderr);
        let stat = |k: &str| {
            err.lines()
                .find_map(|l| l.strip_prefix(&format!("stat::{k}:")))
                .map(|v| v.trim().to_string())
                .unwrap_or_else(|| "?".into())
        };
        if !out.status.success() {
            let tail: Vec<&str> = err.lines().rev().take(40).collect();
            let tail: Vec<&str> = tail.into_iter().rev().collect();
            let _ = std::fs::remove_dir_all(&scratch);
            bail!(
                "fuzz target {t} failed ({}): a crash, saved under fuzz/artifacts/{t}/ (add it to fuzz/regressions/{t}/):\n{}",
                out.status,
                tail.join("\n")
            );
        }
        eprintln!(
            "  fuzz {t}: {} inputs in {:.0} s ({}/s), no crash; {} new corpus inputs",
            stat("number_of_executed_units"),
            t0.elapsed().as_secs_f64(),
            stat("average_exec_per_sec"),
            stat("new_units_added")
        );
    }
    let _ = std::fs::remove_dir_all(&scratch);
    Ok(true)
}
