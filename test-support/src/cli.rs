//! Running a workspace binary from a test: the binary's path, run with arguments, the output
//! and the exit status captured.
//!
//! The path comes from the test crate (`env!("CARGO_BIN_EXE_<name>")` is set only there):
//!
//! ```no_run
//! use test_support::cli::Bin;
//! const HOST_SIM: Bin = Bin::new("target/release/host-sim"); // env!("CARGO_BIN_EXE_host-sim")
//! let stdout = HOST_SIM.run_ok(["--version"]);
//! assert!(stdout.contains("host-sim"));
//! let ran = HOST_SIM.run(["run", "--config", "missing.yaml"]);
//! assert!(!ran.ok && ran.stderr.contains("missing.yaml"));
//! ```
use std::ffi::OsStr;
use std::process::{Command, ExitStatus};

/// A binary to run.
#[derive(Debug, Clone, Copy)]
pub struct Bin {
    path: &'static str,
}

/// What a run of a binary did.
#[derive(Debug, Clone)]
pub struct Ran {
    /// Whether the binary exited with status 0.
    pub ok: bool,
    /// The exit status.
    pub status: ExitStatus,
    /// Standard output (lossy UTF-8).
    pub stdout: String,
    /// Standard error (lossy UTF-8).
    pub stderr: String,
}

impl Bin {
    /// The binary at `path`.
    pub const fn new(path: &'static str) -> Self {
        Self { path }
    }

    /// A command for the binary, for arguments or settings `run` does not cover.
    pub fn command(&self) -> Command {
        Command::new(self.path)
    }

    /// Runs the binary with `args` and captures what it did (panics only when it cannot be
    /// started).
    pub fn run<I, S>(&self, args: I) -> Ran
    where
        I: IntoIterator<Item = S>,
        S: AsRef<OsStr>,
    {
        run(self.command().args(args))
    }

    /// Runs the binary with `args`; panics, with the command line and both outputs, unless it
    /// exits with status 0; returns its standard output.
    pub fn run_ok<I, S>(&self, args: I) -> String
    where
        I: IntoIterator<Item = S>,
        S: AsRef<OsStr>,
    {
        run_ok(self.command().args(args))
    }

    /// As [`Bin::run_ok`], returning the standard output followed by the standard error (for
    /// checks on notes and warnings as well as results).
    pub fn run_ok_both<I, S>(&self, args: I) -> String
    where
        I: IntoIterator<Item = S>,
        S: AsRef<OsStr>,
    {
        let mut cmd = self.command();
        cmd.args(args);
        let ran = run(&mut cmd);
        assert!(
            ran.ok,
            "{cmd:?} exited with {}\nstdout:\n{}\nstderr:\n{}",
            ran.status, ran.stdout, ran.stderr
        );
        ran.stdout + &ran.stderr
    }
}

/// Runs `cmd` and captures what it did (panics only when it cannot be started).
pub fn run(cmd: &mut Command) -> Ran {
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("{cmd:?} could not be started: {e}"));
    Ran {
        ok: out.status.success(),
        status: out.status,
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// Runs `cmd`; panics, with the command line and both outputs, unless it exits with status 0;
/// returns its standard output.
pub fn run_ok(cmd: &mut Command) -> String {
    let ran = run(cmd);
    assert!(
        ran.ok,
        "{cmd:?} exited with {}\nstdout:\n{}\nstderr:\n{}",
        ran.status, ran.stdout, ran.stderr
    );
    ran.stdout
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(unix)]
    #[test]
    fn a_run_captures_output_and_exit_status() {
        let sh = Bin::new("/bin/sh");
        let ran = sh.run(["-c", "echo out; echo err >&2; exit 3"]);
        assert_eq!(ran.stdout, "out\n");
        assert_eq!(ran.stderr, "err\n");
        assert_eq!(ran.status.code(), Some(3));
        assert!(!ran.ok);
        assert_eq!(sh.run_ok(["-c", "echo fine"]), "fine\n");
        assert_eq!(sh.run_ok_both(["-c", "echo a; echo b >&2"]), "a\nb\n");
        let failed = std::panic::catch_unwind(|| sh.run_ok(["-c", "echo why >&2; exit 1"]));
        let msg = failed.expect_err("a failing run panics");
        let msg = msg.downcast_ref::<String>().expect("a formatted message");
        assert!(
            msg.contains("why") && msg.contains("exit status: 1"),
            "{msg}"
        );
    }
}
