//! The time base a board supplies: a free-running monotonic tick counter.

/// A monotonic tick counter (SysTick on the emulated board, the DWT cycle counter on a real
/// Cortex-M4F, the wall clock on the host).
pub trait TimeBase {
    /// Tick rate, Hz.
    const HZ: u32;
    /// Ticks since the time base started.
    fn now_ticks(&mut self) -> u64;
    /// Milliseconds since the time base started (wraps after 49 days).
    fn now_ms(&mut self) -> u32 {
        (self.now_ticks() / u64::from(Self::HZ / 1000).max(1)) as u32
    }
}
