//! Peak stack measurement by painting: [`paint`] fills the free stack below the current stack
//! pointer with a pattern; [`peak_bytes`] later finds the lowest word that no longer holds it.
//! The peak counts from the top of the stack (`_stack_start`), so it includes the frames that
//! existed before painting. Interrupt frames count too (they use the same stack).

const PATTERN: u32 = 0xACE0_BA5E;
/// Largest region painted, bytes: far above every budget, and quick to paint and scan.
pub const PAINT_MAX_BYTES: usize = 128 * 1024;
/// Bytes just below the stack pointer left alone (the painting function's own callees).
const GUARD_BYTES: usize = 64;

extern "C" {
    static _stack_start: u32;
    static _stack_end: u32;
}

fn stack_top() -> usize {
    // linker symbol from cortex-m-rt's link.x; only its address is used
    core::ptr::addr_of!(_stack_start) as usize
}

fn paint_bottom() -> usize {
    // `_stack_end` is the end of static RAM (start of the free region)
    let end = core::ptr::addr_of!(_stack_end) as usize;
    end.max(stack_top().saturating_sub(PAINT_MAX_BYTES))
}

/// Paints the free stack. Call first thing in `main`, before interrupts are enabled.
#[inline(never)]
pub fn paint() {
    let sp = cortex_m::register::msp::read() as usize;
    let mut a = paint_bottom();
    let end = sp.saturating_sub(GUARD_BYTES);
    while a < end {
        // SAFETY: free RAM between the end of the static data and below the live stack.
        unsafe { core::ptr::write_volatile(a as *mut u32, PATTERN) };
        a += 4;
    }
}

/// Peak stack use since [`paint`], bytes. When the whole painted region was used the result
/// is the region's size (a lower bound).
pub fn peak_bytes() -> usize {
    let top = stack_top();
    let mut a = paint_bottom();
    while a < top {
        // SAFETY: reads RAM inside the stack region.
        if unsafe { core::ptr::read_volatile(a as *const u32) } != PATTERN {
            break;
        }
        a += 4;
    }
    top - a
}
