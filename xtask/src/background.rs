//! Commands run in the background while CI's host steps use the cores: one after the other,
//! each with its output in a log file (printed when a command fails), each timed.
//!
//! CI starts the firmware builds (both boards, their own cargo target directory) this way
//! right after set-up, at a lower scheduling priority (`nice`), so they use the cores the host
//! build and test run leave idle; the firmware steps then wait for them by name.

use anyhow::{anyhow, bail, Context, Result};
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc::{channel, Receiver};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

/// Niceness of the background commands: the host steps (CI's longer chain) keep priority.
pub const NICENESS: &str = "10";

/// One background command and what to do once it succeeded.
pub struct Job<T> {
    /// Name the waiting step asks for.
    pub label: String,
    /// The command (run in the workspace root).
    pub command: Command,
    /// Runs after the command succeeded, in the background thread; its value is the job's.
    pub then: Box<dyn FnOnce() -> Result<T> + Send>,
}

/// A finished job: its label, its result and how long the command and `then` took, seconds.
struct Done<T> {
    label: String,
    result: Result<T>,
    secs: f64,
}

/// The process id of the command running now, and whether the jobs were abandoned.
#[derive(Default)]
struct Running {
    pid: Option<u32>,
    cancelled: bool,
}

/// Jobs running one after the other in a background thread (see the module documentation).
/// Dropping it before every job was waited for stops the running command (with every process
/// it started) and the jobs not yet started. The commands stay in CI's process group, so an
/// interrupt (Ctrl-C) reaches them too.
pub struct Background<T> {
    rx: Receiver<Done<T>>,
    log: PathBuf,
    running: Arc<Mutex<Running>>,
    thread: Option<JoinHandle<()>>,
    started: Instant,
    finished: Vec<(String, f64)>,
}

impl<T: Send + 'static> Background<T> {
    /// Starts `jobs` in order in a background thread, their output appended to `log` (created
    /// or emptied first). A failed job stops the ones after it.
    pub fn start(jobs: Vec<Job<T>>, log: &Path) -> Result<Self> {
        if let Some(dir) = log.parent() {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        let file = File::create(log).with_context(|| format!("creating {}", log.display()))?;
        let (tx, rx) = channel();
        let running = Arc::new(Mutex::new(Running::default()));
        let shared = Arc::clone(&running);
        let thread = std::thread::spawn(move || {
            for job in jobs {
                let t = Instant::now();
                let label = job.label.clone();
                let result = run_job(job, &file, &shared);
                let failed = result.is_err();
                let secs = t.elapsed().as_secs_f64();
                if tx
                    .send(Done {
                        label,
                        result,
                        secs,
                    })
                    .is_err()
                    || failed
                {
                    break;
                }
            }
        });
        Ok(Self {
            rx,
            log: log.to_path_buf(),
            running,
            thread: Some(thread),
            started: Instant::now(),
            finished: Vec::new(),
        })
    }

    /// Waits for the job `label` (the next one in order): its value, or its failure with the
    /// log printed.
    pub fn wait(&mut self, label: &str) -> Result<T> {
        let waited = Instant::now();
        let done = self.rx.recv().map_err(|_| {
            anyhow!(
                "background job `{label}` never finished: an earlier one failed (log {})",
                self.log.display()
            )
        })?;
        if done.label != label {
            bail!(
                "waited for background job `{label}`, the next one is `{}`",
                done.label
            );
        }
        eprintln!(
            "  `{label}`: {:.1} s in the background (started {:.1} s ago, waited {:.1} s here; log {})",
            done.secs,
            self.started.elapsed().as_secs_f64(),
            waited.elapsed().as_secs_f64(),
            self.log.display()
        );
        self.finished.push((done.label, done.secs));
        done.result.map_err(|e| {
            let text = std::fs::read_to_string(&self.log).unwrap_or_default();
            eprintln!(
                "  ---- {} ----\n{text}  ---- end of log ----",
                self.log.display()
            );
            e.context(format!(
                "background job `{label}` failed (its output above, also in {})",
                self.log.display()
            ))
        })
    }

    /// Every job waited for so far with its time in the background, seconds.
    pub fn finished(&self) -> &[(String, f64)] {
        &self.finished
    }
}

impl<T> Drop for Background<T> {
    fn drop(&mut self) {
        let pid = {
            let mut r = self.running.lock().unwrap_or_else(|p| p.into_inner());
            r.cancelled = true;
            r.pid
        };
        if let Some(pid) = pid {
            let mut pids = vec![pid];
            let mut i = 0;
            while let Some(&p) = pids.get(i) {
                pids.extend(children(p));
                i += 1;
            }
            eprintln!("  stopping the background job (processes {pids:?})");
            let _ = Command::new("kill")
                .arg("-TERM")
                .args(pids.iter().map(u32::to_string))
                .stderr(Stdio::null())
                .status();
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The child processes of `pid` (Linux's `/proc/PID/task/PID/children`; none where it cannot
/// be read).
fn children(pid: u32) -> Vec<u32> {
    std::fs::read_to_string(format!("/proc/{pid}/task/{pid}/children"))
        .unwrap_or_default()
        .split_whitespace()
        .filter_map(|s| s.parse().ok())
        .collect()
}

/// Runs one job's command with its output in `log` (its process id recorded in `running`
/// while it runs), then the job's `then`.
fn run_job<T>(job: Job<T>, log: &File, running: &Mutex<Running>) -> Result<T> {
    let Job {
        label,
        mut command,
        then,
    } = job;
    let shown = crate::show(&command);
    let mut out = log.try_clone().context("duplicating the log file")?;
    writeln!(out, "==> {label}\n  $ {shown}").context("writing the log")?;
    command
        .current_dir(crate::root())
        .stdin(Stdio::null())
        .stdout(out.try_clone().context("duplicating the log file")?)
        .stderr(out);
    let mut child = {
        let mut r = running.lock().unwrap_or_else(|p| p.into_inner());
        if r.cancelled {
            bail!("`{label}` not started: the background jobs were stopped");
        }
        let child = command
            .spawn()
            .with_context(|| format!("cannot start {shown}"))?;
        r.pid = Some(child.id());
        child
    };
    let status = child.wait();
    running.lock().unwrap_or_else(|p| p.into_inner()).pid = None;
    let status = status.with_context(|| format!("waiting for {shown}"))?;
    if !status.success() {
        bail!("`{shown}` failed ({status})");
    }
    then()
}

/// `cmd` run through `nice -n` [`NICENESS`] (same program, arguments and environment), or
/// `cmd` itself where there is no `nice`.
pub fn niced(cmd: Command) -> Command {
    if crate::embedded::which("nice").is_none() {
        return cmd;
    }
    let mut n = Command::new("nice");
    n.args(["-n", NICENESS])
        .arg(cmd.get_program())
        .args(cmd.get_args());
    for (k, v) in cmd.get_envs() {
        match v {
            Some(v) => n.env(k, v),
            None => n.env_remove(k),
        };
    }
    n
}

#[cfg(test)]
mod tests {
    use super::{niced, Background, Job};
    use std::process::Command;

    fn sh(label: &str, script: &str, value: u32) -> Job<u32> {
        let mut command = Command::new("sh");
        command.args(["-c", script]);
        Job {
            label: label.into(),
            command,
            then: Box::new(move || Ok(value)),
        }
    }

    fn log(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!(
            "xtask-background-{}-{name}.log",
            std::process::id()
        ))
    }

    #[test]
    fn jobs_finish_in_order_with_their_values_and_output_in_the_log() {
        let path = log("ok");
        let mut bg = Background::start(
            vec![sh("one", "echo first", 1), sh("two", "echo second >&2", 2)],
            &path,
        )
        .unwrap();
        assert_eq!(bg.wait("one").unwrap(), 1);
        assert_eq!(bg.wait("two").unwrap(), 2);
        let names: Vec<&str> = bg.finished().iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["one", "two"]);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.contains("first\n") && text.contains("second\n"),
            "{text}"
        );
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn a_failed_job_names_itself_and_stops_the_ones_after_it() {
        let path = log("fail");
        let mut bg = Background::start(
            vec![sh("one", "echo broken; exit 3", 1), sh("two", "true", 2)],
            &path,
        )
        .unwrap();
        let e = format!("{:#}", bg.wait("one").unwrap_err());
        assert!(e.contains("background job `one` failed"), "{e}");
        assert!(e.contains("exit status: 3"), "{e}");
        let e = format!("{:#}", bg.wait("two").unwrap_err());
        assert!(e.contains("`two` never finished"), "{e}");
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn waiting_out_of_order_is_refused_by_name() {
        let path = log("order");
        let mut bg = Background::start(vec![sh("one", "true", 1)], &path).unwrap();
        let e = format!("{:#}", bg.wait("two").unwrap_err());
        assert!(e.contains("the next one is `one`"), "{e}");
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn dropping_stops_a_running_job_and_what_it_started() {
        let path = log("drop");
        let pid_file = log("drop-pid");
        let script = format!("sleep 30 & echo $! > {}; wait", pid_file.display());
        let t = std::time::Instant::now();
        let bg = Background::start(vec![sh("slow", &script, 1)], &path).unwrap();
        let mut sleep_pid = None;
        while sleep_pid.is_none() && t.elapsed().as_secs() < 10 {
            std::thread::sleep(std::time::Duration::from_millis(50));
            sleep_pid = std::fs::read_to_string(&pid_file)
                .ok()
                .and_then(|s| s.trim().parse::<u32>().ok());
        }
        let sleep_pid = sleep_pid.expect("the job wrote its child's pid");
        drop(bg);
        assert!(t.elapsed().as_secs() < 10, "{:?}", t.elapsed());
        // the grandchild is gone (or a zombie waiting to be reaped), not sleeping on
        let alive = || {
            std::fs::read_to_string(format!("/proc/{sleep_pid}/stat"))
                .is_ok_and(|s| !s.rsplit(") ").next().unwrap_or("").starts_with('Z'))
        };
        let t = std::time::Instant::now();
        while alive() && t.elapsed().as_secs() < 5 {
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        assert!(!alive(), "sleep {sleep_pid} still running");
        let _ = std::fs::remove_file(path);
        let _ = std::fs::remove_file(pid_file);
    }

    #[test]
    fn niced_keeps_program_arguments_and_environment() {
        let mut c = Command::new("cargo");
        c.args(["build", "--release"]).env("A", "1").env_remove("B");
        let n = niced(c);
        let args: Vec<String> = n
            .get_args()
            .map(|a| a.to_string_lossy().into_owned())
            .collect();
        if n.get_program() == "nice" {
            assert_eq!(args, ["-n", "10", "cargo", "build", "--release"]);
        }
        let envs: Vec<_> = n.get_envs().collect();
        assert!(envs.contains(&("A".as_ref(), Some("1".as_ref()))));
        assert!(envs.contains(&("B".as_ref(), None)));
    }
}
