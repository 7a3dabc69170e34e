//! Opening serial ports (real UARTs or pseudo-terminals, by path).

use anyhow::Context;
use serialport::SerialPort;
use std::time::Duration;

/// Opens `path` at `baud` with a read/write timeout.
pub fn open(path: &str, baud: u32, timeout: Duration) -> anyhow::Result<Box<dyn SerialPort>> {
    serialport::new(path, baud)
        .timeout(timeout)
        .open()
        .with_context(|| format!("opening serial port {path} at {baud} baud"))
}

/// Serial ports the system reports (pseudo-terminals are not listed but open by path).
pub fn list() -> anyhow::Result<Vec<String>> {
    Ok(serialport::available_ports()
        .context("listing serial ports")?
        .into_iter()
        .map(|p| p.port_name)
        .collect())
}
