//! The bounded fuzz run (`cargo xtask fuzz`): every libFuzzer target of `fuzz/` (address
//! sanitizer, coverage instrumentation) for a fixed time, seeded with the committed corpus, into a scratch corpus
//! directory (so the committed one stays small). A crash fails the command; libFuzzer saves the
//! input under `fuzz/artifacts/<target>/` and it belongs in `fuzz/regressions/<target>/`,
//! which `hw-bridge/tests/it/fuzz_corpus.rs` replays in the ordinary test suite.
//!
//! The targets are built the way `cargo fuzz build` builds them (the same instrumentation
//! flags, for the host triple so build scripts and proc-macros stay uninstrumented, into
//! `fuzz/target/`), by cargo itself: nothing to install first, so a fresh machine does not
//! compile cargo-fuzz before it can fuzz. `cargo fuzz run <target>` works on the same tree for
//! a longer hand run. The sanitizer flag is a nightly compiler feature; the stable toolchain
//! accepts it with `RUSTC_BOOTSTRAP=1`.

use anyhow::{bail, Context, Result};
use std::process::{Command, Stdio};
use std::time::Instant;

/// The targets in `fuzz/fuzz_targets/`.
pub const TARGETS: [&str; 4] = ["wire_decoder", "nmea", "gnss_stream", "capture"];

/// The instrumentation of `cargo fuzz build` (coverage counters and comparisons for
/// libFuzzer, the `fuzzing` cfg, the address sanitizer, debug assertions and overflow checks).
const RUSTFLAGS: &str = "-Cpasses=sancov-module \
     -Cllvm-args=-sanitizer-coverage-level=4 \
     -Cllvm-args=-sanitizer-coverage-inline-8bit-counters \
     -Cllvm-args=-sanitizer-coverage-pc-table \
     -Cllvm-args=-sanitizer-coverage-trace-compares \
     -Cllvm-args=-sanitizer-coverage-stack-depth \
     --cfg fuzzing -Zsanitizer=address -Cdebug-assertions -Coverflow-checks";

fn cargo() -> Command {
    Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
}

/// The host's target triple (`rustc -vV`).
fn host_triple() -> Result<String> {
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    let out = Command::new(&rustc)
        .arg("-vV")
        .output()
        .with_context(|| format!("running {rustc} -vV"))?;
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .find_map(|l| l.strip_prefix("host: "))
        .map(|h| h.trim().to_string())
        .context("rustc -vV printed no host triple")
}

/// Runs every target for `seconds_each` seconds.
pub fn run(seconds_each: u32) -> Result<()> {
    let fuzz_dir = crate::root().join("fuzz");
    let triple = host_triple()?;
    let scratch = std::env::temp_dir().join(format!("navcore-fuzz-{}", std::process::id()));
    let mut build = cargo();
    build
        .args(["build", "--release", "--bins", "--target", &triple])
        .env(
            "RUSTFLAGS",
            RUSTFLAGS.split_whitespace().collect::<Vec<_>>().join(" "),
        )
        .env("RUSTC_BOOTSTRAP", "1")
        // opt-level 1: measured 383 CPU-s to build against 471 at the profile's 3 (the
        // instrumented dependency tree dominates); a bounded smoke run needs coverage, not
        // speed. A hand run (`cargo fuzz run`) keeps the profile's optimisation.
        .env("CARGO_PROFILE_RELEASE_OPT_LEVEL", "1")
        .env("CARGO_TARGET_DIR", fuzz_dir.join("target"))
        .current_dir(&fuzz_dir);
    eprintln!(
        "  $ (in fuzz/) RUSTC_BOOTSTRAP=1 CARGO_PROFILE_RELEASE_OPT_LEVEL=1 RUSTFLAGS=<cargo fuzz's instrumentation> {}",
        crate::show(&build)
    );
    if !build.status()?.success() {
        bail!("building the fuzz targets failed");
    }
    let bin_dir = fuzz_dir.join("target").join(&triple).join("release");
    for t in TARGETS {
        let work = scratch.join(t);
        std::fs::create_dir_all(&work)?;
        let artifacts = fuzz_dir.join("artifacts").join(t);
        std::fs::create_dir_all(&artifacts)?;
        let mut c = Command::new(bin_dir.join(t));
        c.arg(format!("-artifact_prefix={}/", artifacts.display()))
            .arg(format!("-max_total_time={seconds_each}"))
            .arg("-print_final_stats=1")
            .arg(&work)
            .arg(fuzz_dir.join("corpus").join(t))
            .current_dir(&fuzz_dir)
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        eprintln!("  $ (in fuzz/) {}", crate::show(&c));
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
    Ok(())
}
