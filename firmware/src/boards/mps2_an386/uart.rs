//! Register-level driver of the CMSDK APB UART (ARM DDI 0479) as found on the MPS2 boards
//! (UART0 at 0x4000_4000), implementing `embedded_io::{Read, Write, ReadReady, WriteReady}`.
//! Registers: DATA +0x0, STATE +0x4 (bit 0 TX buffer full, bit 1 RX buffer full), CTRL +0x8
//! (bit 0 TX enable, bit 1 RX enable), BAUDDIV +0x10 (>= 16). One byte of buffering each way:
//! reads and writes poll STATE. It never fails, so the error type is `Infallible`.

use core::convert::Infallible;
use core::ptr::{read_volatile, write_volatile};

const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
const BAUDDIV: usize = 0x10;
const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const CTRL_TX_EN: u32 = 1 << 0;
const CTRL_RX_EN: u32 = 1 << 1;

/// Base address of UART0 on MPS2-AN386.
pub const UART0_BASE: usize = 0x4000_4000;

/// A CMSDK APB UART.
pub struct CmsdkUart {
    base: usize,
}

impl CmsdkUart {
    /// Takes the UART at `base`, sets the baud divider (`clock_hz / baud`, at least 16) and
    /// enables transmitter and receiver.
    ///
    /// # Safety
    /// `base` must be a CMSDK APB UART that nothing else uses.
    pub unsafe fn new(base: usize, clock_hz: u32, baud: u32) -> Self {
        let u = Self { base };
        u.wr(BAUDDIV, (clock_hz / baud.max(1)).max(16));
        u.wr(CTRL, CTRL_TX_EN | CTRL_RX_EN);
        u
    }
    fn rd(&self, off: usize) -> u32 {
        // SAFETY: a register of the UART this value owns (see `new`).
        unsafe { read_volatile((self.base + off) as *const u32) }
    }
    fn wr(&self, off: usize, v: u32) {
        // SAFETY: as in `rd`.
        unsafe { write_volatile((self.base + off) as *mut u32, v) }
    }
    fn rx_full(&self) -> bool {
        self.rd(STATE) & STATE_RX_FULL != 0
    }
    fn tx_full(&self) -> bool {
        self.rd(STATE) & STATE_TX_FULL != 0
    }
}

impl embedded_io::ErrorType for CmsdkUart {
    type Error = Infallible;
}

impl embedded_io::Read for CmsdkUart {
    /// Blocks until at least one byte has arrived, then returns what is available.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        let mut n = 0;
        for b in buf.iter_mut() {
            if n > 0 && !self.rx_full() {
                break;
            }
            while !self.rx_full() {}
            *b = self.rd(DATA) as u8;
            n += 1;
        }
        Ok(n)
    }
}

impl embedded_io::ReadReady for CmsdkUart {
    fn read_ready(&mut self) -> Result<bool, Infallible> {
        Ok(self.rx_full())
    }
}

impl embedded_io::Write for CmsdkUart {
    /// Blocks until the transmitter takes the first byte, then writes what fits without waiting.
    fn write(&mut self, buf: &[u8]) -> Result<usize, Infallible> {
        let mut n = 0;
        for &b in buf {
            if n > 0 && self.tx_full() {
                break;
            }
            while self.tx_full() {}
            self.wr(DATA, u32::from(b));
            n += 1;
        }
        Ok(n)
    }
    fn flush(&mut self) -> Result<(), Infallible> {
        while self.tx_full() {}
        Ok(())
    }
}

impl embedded_io::WriteReady for CmsdkUart {
    fn write_ready(&mut self) -> Result<bool, Infallible> {
        Ok(!self.tx_full())
    }
}
