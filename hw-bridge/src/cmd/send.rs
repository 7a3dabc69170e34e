//! `send`: a case streamed into a port as frames.

use super::*;
use crate::frames::case_payloads;
use crate::serial;
use crate::status::StatusLine;
use anyhow::{bail, Context};
use nav_core::wire::{Encoder, Payload, MAX_FRAME_LEN};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// `send` options (the command line's `hw-bridge send` arguments convert into them).
#[derive(Debug, Clone, PartialEq)]
pub struct SendOptions {
    /// Case directory with imu.txt and optionally gnss.txt (as `host-sim simulate` writes).
    pub case: PathBuf,
    /// Serial port to send to.
    pub port: String,
    /// Baud rate of `port`, bit/s.
    pub baud: u32,
    /// Speed-up over real time (sample times), in [[`MIN_SPEED`], [`MAX_SPEED`]].
    pub rate_x: f64,
    /// Send as fast as the port takes it (`rate_x` ignored).
    pub as_fast_as_possible: bool,
    /// Keep the port open this long after the last byte so the receiver drains it, s.
    pub linger_s: f64,
    /// Fail when the port takes no byte for this many seconds (nothing reads it), also while
    /// waiting at the end for the bytes written to drain.
    pub write_timeout_s: f64,
    /// No live status line.
    pub quiet: bool,
    /// Also write every byte sent, exactly as written to the port, to this file.
    pub copy_to: Option<PathBuf>,
    /// Open the port without the exclusive lock, so another program can use it too.
    pub shared: bool,
}

/// Default of `send --write-timeout`, s.
pub const DEFAULT_WRITE_TIMEOUT_S: f64 = 10.0;

/// Default of `send --linger-s`, s.
pub const DEFAULT_LINGER_S: f64 = 0.5;

impl SendOptions {
    /// Sending the case in `case` to `port` in real time at [`DEFAULT_BAUD`], quiet, with the
    /// default linger and write timeout.
    pub fn new(case: impl Into<PathBuf>, port: impl Into<String>) -> Self {
        Self {
            case: case.into(),
            port: port.into(),
            baud: DEFAULT_BAUD,
            rate_x: 1.0,
            as_fast_as_possible: false,
            linger_s: DEFAULT_LINGER_S,
            write_timeout_s: DEFAULT_WRITE_TIMEOUT_S,
            quiet: true,
            copy_to: None,
            shared: false,
        }
    }
}

/// Waits until the port's output queue is empty (the reader took every byte), at most
/// `timeout`. A port that cannot report its queue (the ioctl fails) is not waited for. Unlike
/// `flush` (POSIX `tcdrain`), this cannot block forever when nothing reads the port.
fn drain_output(port: &dyn serialport::SerialPort, timeout: Duration) -> anyhow::Result<()> {
    let t0 = Instant::now();
    loop {
        match port.bytes_to_write() {
            Ok(0) | Err(_) => return Ok(()),
            Ok(n) if t0.elapsed() >= timeout => bail!(
                "{n} bytes still not taken by the receiver after --write-timeout {} s (nothing reads the port?)",
                timeout.as_secs_f64()
            ),
            Ok(_) => std::thread::sleep(Duration::from_millis(5)),
        }
    }
}

/// What `send` sent.
#[derive(Debug, Default, Clone, Copy)]
pub struct SendOutcome {
    /// Frames sent.
    pub frames: u64,
    /// Bytes sent.
    pub bytes: u64,
    /// Wall time, s.
    pub wall_s: f64,
}

/// Reads a case directory's imu.txt and (when present) gnss.txt as the payloads to send.
pub fn read_case(dir: &Path) -> anyhow::Result<Vec<(f64, Payload)>> {
    let imu = nav_io::read_imu_text(dir.join("imu.txt"))?.samples;
    let gnss_path = dir.join("gnss.txt");
    let gnss = if gnss_path.exists() {
        nav_io::read_gnss_text(&gnss_path)?
    } else {
        Vec::new()
    };
    Ok(case_payloads(&imu, &gnss))
}

/// `send`: stream a simulated case into a port as frames, paced by the sample times.
pub fn send(a: &SendOptions) -> anyhow::Result<SendOutcome> {
    if !(MIN_SPEED..=MAX_SPEED).contains(&a.rate_x) {
        bail!(
            "--rate-x {} is outside [{MIN_SPEED}, {MAX_SPEED}]",
            a.rate_x
        );
    }
    if let Some(p) = &a.copy_to {
        // the copy never lands on the case it is read from (a link to it included)
        for input in ["imu.txt", "gnss.txt"] {
            nav_engine::run::outdir::check_not_input(p, &a.case.join(input))?;
        }
    }
    let payloads = read_case(&a.case)?;
    let write_timeout = secs(a.write_timeout_s);
    let mut port = serial::open_for_writing(&a.port, a.baud, write_timeout, a.shared)?;
    let timeout_s = write_timeout.as_secs_f64();
    let mut copy = match &a.copy_to {
        Some(p) => Some(BufWriter::new(
            // a file or link under the name is replaced, a link never written through
            nav_engine::run::outdir::create_new_file(p)
                .with_context(|| format!("creating {}", p.display()))?,
        )),
        None => None,
    };
    let mut put = |bytes: &[u8]| -> anyhow::Result<()> {
        serial::write_all_within(port.as_mut(), bytes, write_timeout).map_err(|e| {
            if e.kind() == std::io::ErrorKind::TimedOut {
                anyhow::anyhow!(
                    "writing frames to {}: the port took no byte within --write-timeout {timeout_s} s (nothing reads it?)",
                    a.port
                )
            } else {
                anyhow::Error::new(e).context(format!("writing frames to {}", a.port))
            }
        })?;
        if let Some(c) = copy.as_mut() {
            c.write_all(bytes).context("writing --copy-to")?;
        }
        Ok(())
    };
    let mut enc = Encoder::new();
    let mut status = StatusLine::new(Duration::from_millis(500), !a.quiet);
    let start = Instant::now();
    let t0 = payloads.first().map_or(0.0, |p| p.0);
    // A leading delimiter: the receiver's first frame is cleanly delimited whatever it had.
    let mut pending = vec![0u8];
    let mut out = SendOutcome::default();
    let mut buf = [0u8; MAX_FRAME_LEN];
    for (t, p) in &payloads {
        if !a.as_fast_as_possible {
            let due = secs((t - t0) / a.rate_x);
            if let Some(wait) = due.checked_sub(start.elapsed()) {
                if wait > Duration::from_millis(2) {
                    put(&pending)?;
                    out.bytes += pending.len() as u64;
                    pending.clear();
                    std::thread::sleep(wait);
                }
            }
        }
        let n = enc.encode(p, &mut buf)?;
        pending.extend_from_slice(&buf[..n]);
        out.frames += 1;
        if pending.len() >= 4096 {
            put(&pending)?;
            out.bytes += pending.len() as u64;
            pending.clear();
        }
        let (f, b) = (out.frames, out.bytes);
        status.update(f, false, || {
            format!("sent {f} frames, {b} bytes, t = {t:.3} s")
        });
    }
    put(&pending)?;
    out.bytes += pending.len() as u64;
    drain_output(port.as_ref(), write_timeout)?;
    if let Some(mut c) = copy {
        c.flush().context("writing --copy-to")?;
    }
    let (f, b) = (out.frames, out.bytes);
    status.update(f, true, || format!("sent {f} frames, {b} bytes"));
    status.finish();
    std::thread::sleep(secs(a.linger_s));
    out.wall_s = start.elapsed().as_secs_f64();
    Ok(out)
}
