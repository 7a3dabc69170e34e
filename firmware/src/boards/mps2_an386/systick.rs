//! SysTick as the time base of the MPS2-AN386 (25 MHz processor clock).
//!
//! The 24-bit down-counter runs from the processor clock with reload 0xFF_FFFF; the
//! `SysTick` exception counts wraps, so [`SysTickClock::now_ticks`] is a monotonic u64.
//! Under `qemu -icount shift=S` qemu's virtual clock advances 2^S ns per executed instruction;
//! one tick is 40 ns, so instructions = ticks * 40 / 2^S (the `bench` binary checks this
//! against a loop of known length).

use crate::time::TimeBase;
use core::sync::atomic::{AtomicU32, Ordering};
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;

/// The board's processor clock, Hz.
pub const CLOCK_HZ: u32 = 25_000_000;
const RELOAD: u32 = 0x00FF_FFFF;

static WRAPS: AtomicU32 = AtomicU32::new(0);

#[cortex_m_rt::exception]
fn SysTick() {
    WRAPS.fetch_add(1, Ordering::Relaxed);
}

/// SysTick running from the processor clock, extended to 64 bits by its wrap exception.
pub struct SysTickClock {
    _syst: SYST,
}

impl SysTickClock {
    /// Starts SysTick (processor clock, full 24-bit reload, wrap exception enabled).
    pub fn new(mut syst: SYST) -> Self {
        syst.disable_counter();
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(RELOAD);
        syst.clear_current();
        WRAPS.store(0, Ordering::Relaxed);
        syst.enable_interrupt();
        syst.enable_counter();
        Self { _syst: syst }
    }
}

impl TimeBase for SysTickClock {
    const HZ: u32 = CLOCK_HZ;
    fn now_ticks(&mut self) -> u64 {
        loop {
            let w1 = WRAPS.load(Ordering::Relaxed);
            let cvr = SYST::get_current();
            let w2 = WRAPS.load(Ordering::Relaxed);
            if w1 == w2 {
                return u64::from(w1) * u64::from(RELOAD + 1) + u64::from(RELOAD - cvr);
            }
        }
    }
}
