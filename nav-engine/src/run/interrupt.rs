//! SIGINT (Ctrl-C) and SIGTERM: a run that is writing its outputs stops cleanly.
//!
//! [`install`] starts a thread that receives both signals (unix; elsewhere the system's
//! default stays). What a signal does depends on the phase:
//! - inside a [`Stoppable`] section (a streaming run and the moving of its outputs into
//!   place): the stop is recorded ([`requested`]); the run ends its data at the next IMU
//!   sample, writes what it processed as `*.partial` with `metrics.json.partial` saying
//!   `"complete": false` and the signal, and the command exits with `128 + signal`
//!   ([`exit_code`]). Moving files into place is never cut in the middle;
//! - outside (loading, an in-memory run, no output being moved): the process exits at once
//!   with `128 + signal`: nothing of `--out` has changed yet (the outputs are written in a
//!   stage folder, see [`super::outdir`]);
//! - a second signal while a stop is pending exits at once as well.
//!
//! What the message on stderr says is kept is the command's ([`say_on_stop`]): by default
//! the outputs so far as `*.partial` inside a section and nothing outside.

use std::sync::atomic::{AtomicI32, AtomicUsize, Ordering};
use std::sync::OnceLock;

/// The first signal received while a [`Stoppable`] section was open (0: none).
static SIGNAL: AtomicI32 = AtomicI32::new(0);
/// Open [`Stoppable`] sections.
static STOPPABLE: AtomicUsize = AtomicUsize::new(0);

/// While alive, SIGINT/SIGTERM request a stop ([`requested`]) instead of ending the process.
#[derive(Debug)]
pub struct Stoppable(());

impl Stoppable {
    /// Opens a section.
    pub fn enter() -> Self {
        STOPPABLE.fetch_add(1, Ordering::SeqCst);
        Self(())
    }
}

impl Drop for Stoppable {
    fn drop(&mut self) {
        STOPPABLE.fetch_sub(1, Ordering::SeqCst);
    }
}

/// The signal whose stop was requested, if any (its number).
pub fn requested() -> Option<i32> {
    match SIGNAL.load(Ordering::Relaxed) {
        0 => None,
        s => Some(s),
    }
}

/// The name of a signal number (`SIGINT`, `SIGTERM`, else `signal N`).
pub fn signal_name(sig: i32) -> String {
    match sig {
        2 => "SIGINT".into(),
        15 => "SIGTERM".into(),
        s => format!("signal {s}"),
    }
}

/// The process exit code after a requested stop: 128 + the signal (130 for SIGINT, 143 for
/// SIGTERM), as a shell reports a process the signal ended.
pub fn exit_code() -> Option<u8> {
    requested().and_then(|s| u8::try_from(128 + s).ok())
}

/// What a signal's message says is kept, set by the command ([`say_on_stop`]).
#[derive(Debug, Clone, Copy)]
struct StopWords {
    /// After "SIGINT: stopping; " inside a [`Stoppable`] section.
    stopping: &'static str,
    /// After "SIGINT: stopped; " when the process ends at once.
    ended: &'static str,
}

/// The command's [`StopWords`] (unset: [`DEFAULT_WORDS`]).
static WORDS: OnceLock<StopWords> = OnceLock::new();

/// What a run keeps: its outputs so far as `*.partial` once they are being written, nothing
/// before (`--out` unchanged).
const DEFAULT_WORDS: StopWords = StopWords {
    stopping: "the outputs so far are kept as *.partial",
    ended: "nothing kept, the output folder unchanged",
};

/// Sets what the message of a signal says the command keeps (once per process, before
/// [`install`]; later calls do nothing): `stopping` inside a [`Stoppable`] section (the
/// default: the outputs so far as `*.partial`), `ended` when the process ends at once (the
/// default: nothing, the output folder unchanged).
pub fn say_on_stop(stopping: &'static str, ended: &'static str) {
    let _ = WORDS.set(StopWords { stopping, ended });
}

/// The message of `sig` received: `stopping` true inside a [`Stoppable`] section (the stop
/// requested), false when the process ends at once.
pub fn stop_message(sig: i32, stopping: bool) -> String {
    let w = WORDS.get().copied().unwrap_or(DEFAULT_WORDS);
    if stopping {
        format!(
            "{}: stopping; {} (send it again to end at once)",
            signal_name(sig),
            w.stopping
        )
    } else {
        format!("{}: stopped; {}", signal_name(sig), w.ended)
    }
}

/// Handles a signal received: a stop request inside a section, else the end of the process.
fn on_signal(sig: i32) {
    let first = SIGNAL
        .compare_exchange(0, sig, Ordering::SeqCst, Ordering::SeqCst)
        .is_ok();
    if !first {
        eprintln!("\n{}: stopped at once", signal_name(sig));
        std::process::exit(128 + sig);
    }
    if STOPPABLE.load(Ordering::SeqCst) == 0 {
        eprintln!("\n{}", stop_message(sig, false));
        std::process::exit(128 + sig);
    }
    eprintln!("\n{}", stop_message(sig, true));
}

/// Starts the thread receiving SIGINT and SIGTERM (once per process; later calls do
/// nothing). An error (the thread or the handlers could not be set up) leaves the system's
/// default: the process ends at the signal, `--out` unchanged but the partial outputs lost.
pub fn install() -> std::io::Result<()> {
    #[cfg(unix)]
    {
        static INSTALLED: OnceLock<()> = OnceLock::new();
        if INSTALLED.get().is_some() {
            return Ok(());
        }
        let mut signals = signal_hook::iterator::Signals::new([
            signal_hook::consts::SIGINT,
            signal_hook::consts::SIGTERM,
        ])?;
        std::thread::Builder::new()
            .name("signals".into())
            .spawn(move || {
                for sig in signals.forever() {
                    on_signal(sig);
                }
            })?;
        let _ = INSTALLED.set(());
    }
    Ok(())
}
