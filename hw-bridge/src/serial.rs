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
