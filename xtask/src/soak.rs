//! `cargo xtask soak [--seconds S]`: the long soak of `hw-bridge send` and `hw-bridge record`
//! over a pty pair with random link faults (bit flips, dropped byte runs, garbage, stalls, the
//! port vanishing and coming back), the ignored test `soak_10_minutes` of
//! `hw-bridge/tests/it/link.rs`. It passes when, per stream, frames sent = delivered + lost
//! exactly at the end; it prints the counts. The normal test suite runs a 20-second one.

use anyhow::Result;
use std::process::Command;
use std::time::Instant;

fn cargo() -> Command {
    Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
}

/// Runs the soak for `seconds` of sending (default 600).
pub fn run(seconds: u32) -> Result<()> {
    let t = Instant::now();
    let mut c = cargo();
    c.current_dir(crate::root())
        .args([
            "test",
            "--profile",
            "ci",
            "-p",
            "hw-bridge",
            "--test",
            "link",
            "--",
            "--ignored",
            "--exact",
            "soak_10_minutes",
            "--nocapture",
        ])
        .env("HW_BRIDGE_SOAK_S", seconds.to_string());
    crate::run(&mut c)?;
    eprintln!(
        "  soak of {seconds} s passed in {:.1} s",
        t.elapsed().as_secs_f64()
    );
    Ok(())
}
