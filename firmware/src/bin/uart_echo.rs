//! UART loopback check (emulated board): proves bytes flow both ways through the CMSDK UART
//! driver. Protocol: the firmware sends the banner `uart-echo ready\n`; the host sends a u32
//! little-endian count n and then n bytes; the firmware answers each byte b with `b ^ 0xA5`
//! (a transformed echo, so a link looping back on itself cannot pass), prints the count and
//! its peak stack over semihosting and exits 0.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use embedded_io::{Read, Write};
use firmware::{board, info, stack};

/// XOR applied to every echoed byte.
const ECHO_XOR: u8 = 0xA5;

#[entry]
fn main() -> ! {
    stack::paint();
    let mut b = board::init();
    let uart = &mut b.uart;
    let Ok(()) = uart.write_all(b"uart-echo ready\n");
    let mut hdr = [0u8; 4];
    if uart.read_exact(&mut hdr).is_err() {
        board::exit(false);
    }
    let n = u32::from_le_bytes(hdr);
    let mut done = 0u32;
    let mut buf = [0u8; 32];
    while done < n {
        let want = ((n - done) as usize).min(buf.len());
        let Ok(got) = uart.read(&mut buf[..want]);
        for x in &mut buf[..got] {
            *x ^= ECHO_XOR;
        }
        let Ok(()) = uart.write_all(&buf[..got]);
        done += got as u32;
    }
    let Ok(()) = uart.flush();
    info!(
        "uart-echo: {} bytes echoed, peak stack {} B",
        done,
        stack::peak_bytes()
    );
    board::exit(true)
}
