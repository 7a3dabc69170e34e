//! A real navigation board: STM32F407 (Cortex-M4F, 168 MHz from an 8 MHz crystal, e.g. the
//! STM32F4-Discovery or a custom board with the same pin-out), with
//!
//! - USART2 (PA2 TX, PA3 RX, 921600 baud 8N1): wire frames: GNSS fixes and configuration in,
//!   navigation solutions and health out (`hw-bridge` on the host side);
//! - SPI1 (PA5 SCK, PA6 MISO, PA7 MOSI, PA4 chip select, mode 3, 8 MHz): a TDK ICM-42688-P
//!   at 200 Hz behind an `embedded-hal` `SpiDevice` ([`crate::icm42688`]);
//! - the DWT cycle counter (168 MHz) as the time base ([`DwtClock`]).
//!
//! Memory layout: `firmware/boards/stm32f407/memory.x` (1 MiB flash, 128 KiB SRAM).

mod serial;

pub use serial::{NbSerial, SerialError};

use crate::app::NavApp;
use crate::icm42688::{self, Icm42688};
use crate::time::TimeBase;
use embedded_hal_bus::spi::ExclusiveDevice;
use embedded_io::ReadReady;
use stm32f4xx_hal::{pac, prelude::*, rcc::Config, serial::config::Config as SerialConfig};

/// The board's name as `cargo xtask fw --board` spells it.
pub const NAME: &str = "stm32f407";
/// Core clock, Hz.
pub const SYSCLK_HZ: u32 = 168_000_000;
/// Frame link baud rate.
pub const BAUD: u32 = 921_600;

/// The DWT cycle counter extended to 64 bits (poll it at least every 25 s).
pub struct DwtClock {
    last: u32,
    high: u64,
}

impl DwtClock {
    /// Enables trace and the cycle counter.
    pub fn new(mut dcb: cortex_m::peripheral::DCB, mut dwt: cortex_m::peripheral::DWT) -> Self {
        dcb.enable_trace();
        dwt.enable_cycle_counter();
        Self {
            last: cortex_m::peripheral::DWT::cycle_count(),
            high: 0,
        }
    }
}

impl TimeBase for DwtClock {
    const HZ: u32 = SYSCLK_HZ;
    fn now_ticks(&mut self) -> u64 {
        let now = cortex_m::peripheral::DWT::cycle_count();
        if now < self.last {
            self.high += 1 << 32;
        }
        self.last = now;
        self.high | u64::from(now)
    }
}

/// Ends the program (a real board has no host to report to): halts in a breakpoint when a
/// debugger is attached, else spins.
pub fn exit(_ok: bool) -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}

#[cfg(feature = "defmt")]
#[defmt::panic_handler]
fn defmt_panic() -> ! {
    exit(false)
}

#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    crate::error!("firmware panic");
    cortex_m::peripheral::SCB::sys_reset()
}

/// The navigation application on this board: the ICM-42688-P paces the epochs (polled
/// data-ready), GNSS and configuration frames arrive on USART2, solutions and health leave on
/// it. Never returns; on a fatal set-up error it resets after logging.
pub fn run_nav<const N: usize>(app: &mut NavApp<N>) -> ! {
    let (Some(dp), Some(cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        cortex_m::peripheral::SCB::sys_reset()
    };
    let mut rcc = dp.RCC.freeze(Config::hse(8.MHz()).sysclk(SYSCLK_HZ.Hz()));
    let mut clock = DwtClock::new(cp.DCB, cp.DWT);
    let gpioa = dp.GPIOA.split(&mut rcc);

    let Ok(serial) = dp.USART2.serial(
        (gpioa.pa2, gpioa.pa3),
        SerialConfig::default().baudrate(BAUD.bps()),
        &mut rcc,
    ) else {
        crate::error!("nav: USART2 configuration refused");
        cortex_m::peripheral::SCB::sys_reset()
    };
    let (tx, rx) = serial.split();
    let mut link = NbSerial::new(tx, rx);

    let spi = dp.SPI1.spi(
        (Some(gpioa.pa5), Some(gpioa.pa6), Some(gpioa.pa7)),
        embedded_hal::spi::MODE_3,
        8.MHz(),
        &mut rcc,
    );
    let cs = gpioa.pa4.into_push_pull_output();
    let Ok(dev) = ExclusiveDevice::new_no_delay(spi, cs);
    // power-up, then gyro start-up time after configuration
    cortex_m::asm::delay(SYSCLK_HZ / 100);
    let cfg = icm42688::Config::default();
    let mut imu = match Icm42688::new(dev, cfg) {
        Ok(imu) => imu,
        Err(_) => {
            crate::error!("nav: no ICM-42688-P on SPI1");
            cortex_m::peripheral::SCB::sys_reset()
        }
    };
    cortex_m::asm::delay(SYSCLK_HZ / 20);

    app.set_stack_probe(crate::stack::peak_bytes);
    app.set_time_from_gnss(true);
    app.set_link_imu(false);
    let dt_s = 1.0 / cfg.odr.hz();
    let hz = f64::from(DwtClock::HZ);
    loop {
        if let Ok(true) = imu.data_ready() {
            let t_s = clock.now_ticks() as f64 / hz + app.time_offset_s();
            if let Ok(s) = imu.read_sample(t_s, dt_s) {
                let _ = app.on_imu(&s, &mut link, &mut clock);
            }
        }
        while let Ok(true) = link.read_ready() {
            let mut b = [0u8; 1];
            if let Ok(1) = embedded_io::Read::read(&mut link, &mut b) {
                let _ = app.feed(&b, &mut link, &mut clock);
            }
        }
    }
}
