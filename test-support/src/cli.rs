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
/// The signals [`interrupt_when_ready`] sends in the workspace's tests.
#[cfg(unix)]
pub use libc::{SIGINT, SIGTERM};
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

/// What a run of a binary under a time limit did ([`run_bounded`]).
#[derive(Debug, Clone)]
pub struct Bounded {
    /// The exit status (None: killed at the time limit).
    pub status: Option<ExitStatus>,
    /// Standard output (lossy UTF-8).
    pub stdout: String,
    /// Standard error (lossy UTF-8).
    pub stderr: String,
    /// Wall time to the end (or to the kill), s.
    pub wall_s: f64,
    /// Peak resident set of the process's own image, KiB: its `VmHWM` (Linux
    /// `/proc/PID/status`) read every 5 ms while it runs, so a peak in its last 5 ms may be
    /// missed; 0 when it ended before the first reading or elsewhere than on Linux. Not
    /// `wait4`'s `ru_maxrss`: that one keeps the high-water mark of the address space the
    /// child left at `exec`, the test process's own (hundreds of MiB while other tests run).
    pub max_rss_kib: u64,
    /// CPU time of the process (user + system), s.
    pub cpu_s: f64,
}

impl Bounded {
    /// The exit code (None: killed, by the limit or a signal).
    pub fn code(&self) -> Option<i32> {
        self.status.and_then(|s| s.code())
    }

    /// Whether it was killed at the time limit.
    pub fn timed_out(&self) -> bool {
        self.status.is_none()
    }

    /// Whether it panicked (exit code 101 or a panic message on stderr).
    pub fn panicked(&self) -> bool {
        self.code() == Some(101) || self.stderr.contains("panicked at")
    }

    /// Asserts that it was stopped by `signal` the way the workspace's binaries report it:
    /// exit code 128 + the signal and `interrupted by SIGINT` (or `SIGTERM`) on stderr.
    #[cfg(unix)]
    pub fn assert_interrupted_by(&self, signal: i32) {
        let name = match signal {
            libc::SIGINT => "SIGINT",
            libc::SIGTERM => "SIGTERM",
            _ => "",
        };
        assert_eq!(self.code(), Some(128 + signal), "{self:?}");
        assert!(
            !name.is_empty() && self.stderr.contains(&format!("interrupted by {name}")),
            "no \"interrupted by {name}\": {self:?}"
        );
    }
}

/// Runs `cmd` (its standard input empty, in a process group of its own) for at most `limit`:
/// killed (SIGKILL, with the processes it started) past it.
/// Measures its own CPU time with `wait4` (that child only, not the other children of the
/// test) and its peak resident set from `/proc` ([`Bounded::max_rss_kib`]). Panics when it
/// cannot be started ([`try_run_bounded`] returns that as an error).
#[cfg(unix)]
pub fn run_bounded(cmd: &mut Command, limit: std::time::Duration) -> Bounded {
    try_run_bounded(cmd, limit).unwrap_or_else(|e| panic!("{cmd:?}: {e}"))
}

/// [`run_bounded`], with an error instead of a panic when `cmd` cannot be started or waited
/// for (for tools measuring other programs, e.g. `cargo xtask bench-run`).
#[cfg(unix)]
// the child is reaped by `wait4` (std's `wait` would lose its resource usage)
#[allow(clippy::zombie_processes)]
pub fn try_run_bounded(cmd: &mut Command, limit: std::time::Duration) -> std::io::Result<Bounded> {
    use std::os::unix::process::ExitStatusExt;
    let t = std::time::Instant::now();
    // a process group of its own: killed at the limit with whatever it started
    let (child, out, err) = spawn_drained(cmd)
        .map_err(|e| std::io::Error::new(e.kind(), format!("could not be started: {e}")))?;
    let pid = libc::pid_t::try_from(child.id()).map_err(std::io::Error::other)?;
    let mut killed = false;
    let mut max_rss_kib = 0u64;
    let (status, ru) = loop {
        max_rss_kib = max_rss_kib.max(vm_hwm_kib(pid).unwrap_or(0));
        let mut st = 0;
        // SAFETY: an all-zero rusage is a valid value; wait4 fills it for our own child.
        let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
        let flags = if killed { 0 } else { libc::WNOHANG };
        // SAFETY: `pid` is our child, not reaped yet (std's `Child` never waits here).
        let r = unsafe { libc::wait4(pid, &mut st, flags, &mut ru) };
        if r == pid {
            break (st, ru);
        }
        if r < 0 {
            let e = std::io::Error::last_os_error();
            if e.kind() == std::io::ErrorKind::Interrupted {
                continue;
            }
            // SAFETY: signalling the process group of our own child, not reaped yet.
            unsafe { libc::kill(-pid, libc::SIGKILL) };
            return Err(std::io::Error::new(e.kind(), format!("wait4: {e}")));
        }
        if t.elapsed() > limit {
            // SAFETY: signalling the process group of our own child, not reaped yet.
            unsafe { libc::kill(-pid, libc::SIGKILL) };
            killed = true;
        } else {
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
    };
    let secs = |v: libc::timeval| v.tv_sec as f64 + v.tv_usec as f64 * 1e-6;
    Ok(Bounded {
        status: (!killed).then(|| ExitStatus::from_raw(status)),
        stdout: out.join(),
        stderr: err.join(),
        wall_s: t.elapsed().as_secs_f64(),
        max_rss_kib,
        cpu_s: secs(ru.ru_utime) + secs(ru.ru_stime),
    })
}

/// Starts `cmd` (its standard input empty, in a process group of its own, its output read),
/// waits until `ready()` says it has started its work (polled every 2 ms, at most
/// `start_limit`), sends it `signal` (e.g. `libc::SIGINT`, `libc::SIGTERM`) and waits at most
/// `end_limit` for its end (killed with its process group past it: then
/// [`Bounded::timed_out`]). `wall_s` is the time from the signal to the end. `Err` naming what
/// happened when it ended, or was still not ready at `start_limit` (then killed), before the
/// signal.
#[cfg(unix)]
pub fn interrupt_when_ready(
    cmd: &mut Command,
    ready: &mut dyn FnMut() -> bool,
    signal: i32,
    start_limit: std::time::Duration,
    end_limit: std::time::Duration,
) -> Result<Bounded, String> {
    interrupt_at_stderr(cmd, &mut |_| ready(), signal, start_limit, end_limit)
}

/// [`interrupt_when_ready`] with `ready` given the child's standard error so far (e.g. a
/// progress line it waits for).
#[cfg(unix)]
pub fn interrupt_at_stderr(
    cmd: &mut Command,
    ready: &mut dyn FnMut(&str) -> bool,
    signal: i32,
    start_limit: std::time::Duration,
    end_limit: std::time::Duration,
) -> Result<Bounded, String> {
    let t = std::time::Instant::now();
    let (mut child, out, err) =
        spawn_drained(cmd).map_err(|e| format!("{cmd:?} could not be started: {e}"))?;
    let pid = libc::pid_t::try_from(child.id()).map_err(|e| e.to_string())?;
    let kill_group = || {
        // SAFETY: signalling the process group of our own child, not reaped yet.
        unsafe { libc::kill(-pid, libc::SIGKILL) };
    };
    while !ready(&err.so_far()) {
        let ended = child.try_wait().map_err(|e| e.to_string())?;
        if ended.is_some() || t.elapsed() > start_limit {
            if ended.is_none() {
                kill_group();
            }
            let status = child.wait().map_err(|e| e.to_string())?;
            return Err(format!(
                "{cmd:?} {} before it was ready ({:.1} s): {status}\nstdout:\n{}\nstderr:\n{}",
                if ended.is_some() {
                    "ended"
                } else {
                    "was killed at the start limit"
                },
                t.elapsed().as_secs_f64(),
                out.join(),
                err.join()
            ));
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    let t_sig = std::time::Instant::now();
    // SAFETY: signalling our own child, not reaped yet (`try_wait` saw it running).
    unsafe { libc::kill(pid, signal) };
    let mut killed = false;
    let status = loop {
        if let Some(st) = child.try_wait().map_err(|e| e.to_string())? {
            break st;
        }
        if !killed && t_sig.elapsed() > end_limit {
            kill_group();
            killed = true;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    };
    Ok(Bounded {
        status: (!killed).then_some(status),
        stdout: out.join(),
        stderr: err.join(),
        wall_s: t_sig.elapsed().as_secs_f64(),
        max_rss_kib: 0,
        cpu_s: 0.0,
    })
}

/// A thread reading one of a child's outputs to its end, with what it has read so far.
#[cfg(unix)]
struct Drain {
    thread: std::thread::JoinHandle<()>,
    read: std::sync::Arc<std::sync::Mutex<Vec<u8>>>,
}

#[cfg(unix)]
impl Drain {
    /// Reads `r` (none: nothing) to its end in a thread of its own.
    fn start(r: Option<Box<dyn std::io::Read + Send>>) -> Self {
        let read = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let into = read.clone();
        let thread = std::thread::spawn(move || {
            let Some(mut r) = r else { return };
            let mut b = [0u8; 4096];
            loop {
                match r.read(&mut b) {
                    Ok(0) => break,
                    Ok(n) => into
                        .lock()
                        .unwrap_or_else(std::sync::PoisonError::into_inner)
                        .extend_from_slice(&b[..n]),
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(_) => break,
                }
            }
        });
        Self { thread, read }
    }

    /// The text read so far.
    fn so_far(&self) -> String {
        let b = self
            .read
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        String::from_utf8_lossy(&b).into_owned()
    }

    /// The whole text, once the output has ended.
    fn join(self) -> String {
        let Self { thread, read } = self;
        let _ = thread.join();
        let b = read
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        String::from_utf8_lossy(&b).into_owned()
    }
}

/// Starts `cmd` with its standard input empty, in a process group of its own (so that killing
/// the group also ends whatever it started, which would hold the output pipes open), and its
/// standard output and error each read to the end by a thread.
#[cfg(unix)]
fn spawn_drained(cmd: &mut Command) -> std::io::Result<(std::process::Child, Drain, Drain)> {
    use std::os::unix::process::CommandExt;
    use std::process::Stdio;
    let mut child = cmd
        .process_group(0)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()?;
    let out = Drain::start(child.stdout.take().map(|r| Box::new(r) as _));
    let err = Drain::start(child.stderr.take().map(|r| Box::new(r) as _));
    Ok((child, out, err))
}

/// The high-water mark of a running process's resident set (`VmHWM` of `/proc/PID/status`),
/// KiB; None once it has ended (a zombie has no address space) or without `/proc`.
#[cfg(unix)]
fn vm_hwm_kib(pid: libc::pid_t) -> Option<u64> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(unix)]
    #[test]
    fn a_bounded_run_is_killed_at_its_limit_and_measured() {
        let limit = std::time::Duration::from_millis(300);
        let r = run_bounded(Command::new("/bin/sh").args(["-c", "sleep 20"]), limit);
        assert!(r.timed_out() && r.wall_s < 10.0, "{r:?}");
        let r = run_bounded(
            // the sleep: alive at the first readings of its resident set
            Command::new("/bin/sh").args(["-c", "sleep 0.1; echo out; echo err >&2; exit 3"]),
            std::time::Duration::from_secs(20),
        );
        assert_eq!(
            (r.code(), r.stdout.as_str(), r.stderr.as_str()),
            (Some(3), "out\n", "err\n")
        );
        assert!(r.max_rss_kib > 0 && !r.panicked(), "{r:?}");
    }

    #[cfg(unix)]
    #[test]
    fn a_child_is_signalled_once_ready_and_its_end_reported() {
        use std::time::Duration;
        let d = std::env::temp_dir().join(format!("ts-interrupt-{}", std::process::id()));
        let _ = std::fs::remove_file(&d);
        let script = format!(
            "trap 'echo interrupted by SIGTERM >&2; exit 143' TERM; touch {}; \
             while :; do sleep 0.01; done",
            d.display()
        );
        let mut ready = || d.exists();
        let r = interrupt_when_ready(
            Command::new("/bin/sh").args(["-c", &script]),
            &mut ready,
            libc::SIGTERM,
            Duration::from_secs(20),
            Duration::from_secs(20),
        )
        .unwrap();
        r.assert_interrupted_by(libc::SIGTERM);
        let _ = std::fs::remove_file(&d);
        // ended before it was ready: an error with its output
        let e = interrupt_when_ready(
            Command::new("/bin/sh").args(["-c", "echo gone >&2; exit 4"]),
            &mut || false,
            libc::SIGINT,
            Duration::from_secs(20),
            Duration::from_secs(20),
        )
        .unwrap_err();
        assert!(
            e.contains("ended before it was ready") && e.contains("gone"),
            "{e}"
        );
        // a child that ignores the signal: killed at the end limit
        let mut ready = || d.exists();
        let script = format!("trap '' INT; touch {}; sleep 20", d.display());
        let r = interrupt_when_ready(
            Command::new("/bin/sh").args(["-c", &script]),
            &mut ready,
            libc::SIGINT,
            Duration::from_secs(20),
            Duration::from_millis(300),
        )
        .unwrap();
        assert!(r.timed_out() && r.wall_s < 10.0, "{r:?}");
        let _ = std::fs::remove_file(&d);
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn the_peak_resident_set_is_the_childs_own_not_the_test_processs() {
        // the test process holds 256 MiB, touched; the child (a shell sleeping) a few MiB
        let big = vec![1u8; 256 << 20];
        let r = run_bounded(
            Command::new("/bin/sh").args(["-c", "sleep 0.2"]),
            std::time::Duration::from_secs(20),
        );
        assert!(big.iter().step_by(4096).all(|&b| b == 1));
        assert!(r.max_rss_kib > 0 && r.max_rss_kib < 64 << 10, "{r:?}");
    }

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
