//! `embedded_io` 0.7 over any `embedded-hal-nb` serial pair (the STM32 HALs implement those
//! traits; their own `embedded-io` implementations are for 0.6).

use embedded_hal_nb::serial::{Error as _, ErrorKind, Read, Write};

/// A serial error as `embedded_io` wants it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SerialError(pub ErrorKind);

impl core::fmt::Display for SerialError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "serial error: {:?}", self.0)
    }
}

impl core::error::Error for SerialError {}

impl embedded_io::Error for SerialError {
    fn kind(&self) -> embedded_io::ErrorKind {
        embedded_io::ErrorKind::Other
    }
}

/// A transmitter and a receiver as one `embedded_io` link.
pub struct NbSerial<TX, RX> {
    tx: TX,
    rx: RX,
    pending: Option<u8>,
}

impl<TX, RX> NbSerial<TX, RX> {
    /// Joins the two halves.
    pub fn new(tx: TX, rx: RX) -> Self {
        Self {
            tx,
            rx,
            pending: None,
        }
    }
}

impl<TX, RX> embedded_io::ErrorType for NbSerial<TX, RX> {
    type Error = SerialError;
}

impl<TX, RX: Read<u8>> embedded_io::ReadReady for NbSerial<TX, RX> {
    fn read_ready(&mut self) -> Result<bool, SerialError> {
        if self.pending.is_some() {
            return Ok(true);
        }
        match self.rx.read() {
            Ok(b) => {
                self.pending = Some(b);
                Ok(true)
            }
            Err(nb::Error::WouldBlock) => Ok(false),
            Err(nb::Error::Other(e)) => Err(SerialError(e.kind())),
        }
    }
}

impl<TX, RX: Read<u8>> embedded_io::Read for NbSerial<TX, RX> {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, SerialError> {
        let Some(first) = buf.first_mut() else {
            return Ok(0);
        };
        *first = match self.pending.take() {
            Some(b) => b,
            None => nb::block!(self.rx.read()).map_err(|e| SerialError(e.kind()))?,
        };
        Ok(1)
    }
}

impl<TX: Write<u8>, RX> embedded_io::Write for NbSerial<TX, RX> {
    fn write(&mut self, buf: &[u8]) -> Result<usize, SerialError> {
        let Some(&b) = buf.first() else {
            return Ok(0);
        };
        nb::block!(self.tx.write(b)).map_err(|e| SerialError(e.kind()))?;
        Ok(1)
    }
    fn flush(&mut self) -> Result<(), SerialError> {
        nb::block!(self.tx.flush()).map_err(|e| SerialError(e.kind()))
    }
}
