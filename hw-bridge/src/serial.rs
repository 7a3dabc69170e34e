//! Opening serial ports (real UARTs or pseudo-terminals, by path).

use anyhow::Context;
use serialport::SerialPort;
use std::time::Duration;

/// Opens `path` at `baud` with a read/write timeout, exclusively (no other program can open
/// it while this one holds it).
pub fn open(path: &str, baud: u32, timeout: Duration) -> anyhow::Result<Box<dyn SerialPort>> {
    open_with(path, baud, timeout, false)
}

/// Opens `path` at `baud` with a read/write timeout; `shared` leaves out the exclusive lock
/// (POSIX `TIOCEXCL` and `flock`), so that e.g. `hw-bridge send` and `hw-bridge record` can
/// hold the two directions of one port (a pty in front of an emulated board).
pub fn open_with(
    path: &str,
    baud: u32,
    timeout: Duration,
    shared: bool,
) -> anyhow::Result<Box<dyn SerialPort>> {
    let b = serialport::new(path, baud).timeout(timeout);
    #[cfg(unix)]
    let b = b.exclusive(!shared);
    b.open().with_context(|| {
        format!(
            "opening serial port {path} at {baud} baud{}",
            if shared { " (shared)" } else { "" }
        )
    })
}

/// Serial ports the system reports (pseudo-terminals are not listed but open by path).
pub fn list() -> anyhow::Result<Vec<String>> {
    Ok(serialport::available_ports()
        .context("listing serial ports")?
        .into_iter()
        .map(|p| p.port_name)
        .collect())
}

/// Opens `path` for writing with `timeout` as the longest wait for the port to take a byte
/// (see [`write_all_within`]). On Unix the descriptor is made non-blocking: a blocking tty
/// `write()` sleeps until the whole buffer fits, whatever timeout serialport polled with, so
/// a port nobody reads would block forever.
pub fn open_for_writing(
    path: &str,
    baud: u32,
    timeout: Duration,
    shared: bool,
) -> anyhow::Result<Box<dyn SerialPort>> {
    #[cfg(unix)]
    {
        use std::os::fd::AsRawFd;
        let port = serialport::new(path, baud)
            .timeout(timeout)
            .exclusive(!shared)
            .open_native()
            .with_context(|| {
                format!(
                    "opening serial port {path} at {baud} baud{}",
                    if shared { " (shared)" } else { "" }
                )
            })?;
        let fd = port.as_raw_fd();
        // SAFETY: fcntl on a descriptor the port owns and keeps open; no memory is passed.
        let ok = unsafe {
            let flags = libc::fcntl(fd, libc::F_GETFL);
            flags >= 0 && libc::fcntl(fd, libc::F_SETFL, flags | libc::O_NONBLOCK) >= 0
        };
        if !ok {
            return Err(std::io::Error::last_os_error())
                .with_context(|| format!("making {path} non-blocking"));
        }
        Ok(Box::new(port))
    }
    #[cfg(not(unix))]
    {
        open_with(path, baud, timeout, shared)
    }
}

/// Writes all of `bytes`, failing with `ErrorKind::TimedOut` when the port takes no byte for
/// `timeout` (serialport polls for writability with the port's timeout before each write; a
/// non-blocking write that would block is retried until `timeout` passes without progress).
pub fn write_all_within(
    port: &mut dyn SerialPort,
    mut bytes: &[u8],
    timeout: Duration,
) -> std::io::Result<()> {
    use std::io::ErrorKind;
    let mut last_progress = std::time::Instant::now();
    while !bytes.is_empty() {
        match port.write(bytes) {
            Ok(0) => return Err(ErrorKind::WriteZero.into()),
            Ok(n) => {
                bytes = bytes.get(n..).unwrap_or_default();
                last_progress = std::time::Instant::now();
            }
            Err(e) if matches!(e.kind(), ErrorKind::Interrupted) => {}
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                if last_progress.elapsed() >= timeout {
                    return Err(ErrorKind::TimedOut.into());
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            Err(e) => return Err(e),
        }
    }
    Ok(())
}
