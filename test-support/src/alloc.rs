//! A process-wide counting global allocator for the tests that bound a run's memory
//! (`host-sim/tests/run_stream_memory.rs`, `run_stream_gnss_memory.rs`). Each such test is its
//! own test binary (the counters are process-wide) and installs it with
//!
//! ```ignore
//! #[global_allocator]
//! static A: test_support::alloc::Counting = test_support::alloc::Counting;
//! ```
//!
//! then measures with [`reset_peak`] before and [`peak_bytes`] after the run.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Forwards to the system allocator and counts the live bytes and their peak.
pub struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator; only counts (atomics, no allocation).
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        // SAFETY: same layout contract as the caller's.
        let p = unsafe { System.alloc(l) };
        if !p.is_null() {
            let now = LIVE.fetch_add(l.size(), Ordering::Relaxed) + l.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        // SAFETY: p was allocated by System with l.
        unsafe { System.dealloc(p, l) };
        LIVE.fetch_sub(l.size(), Ordering::Relaxed);
    }
}

/// Sets the peak to the bytes live now and returns them (the base of a measurement), bytes.
pub fn reset_peak() -> usize {
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    base
}

/// Peak live bytes since the last [`reset_peak`], bytes (subtract its base for the growth).
pub fn peak_bytes() -> usize {
    PEAK.load(Ordering::Relaxed)
}
