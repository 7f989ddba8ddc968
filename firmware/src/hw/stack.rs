//! Painted-stack check: at start-up the free stack (between the end of static RAM,
//! `_stack_end` from cortex-m-rt's link.x, and a margin below the current stack
//! pointer) is filled with a pattern; [`high_water`] later finds how deep the stack
//! has ever reached by scanning for the first overwritten word. Interrupts share the
//! main stack (MSP), so this covers every interrupt nesting seen so far — run the
//! board through its worst case (all interrupts active, mailbox traffic) before
//! trusting the number.
const PAINT: u32 = 0x5A5A_A5A5;
/// Bytes below the stack pointer at paint time that are left alone (the frames of
/// `main` and `paint` itself).
const MARGIN: usize = 256;

extern "C" {
    static _stack_end: u32;
    static _stack_start: u32;
}

fn bounds() -> (usize, usize) {
    // Linker symbols: only their addresses are used.
    (
        core::ptr::addr_of!(_stack_end) as usize,
        core::ptr::addr_of!(_stack_start) as usize,
    )
}

/// Fills the unused stack with the pattern. Call once, early in `main`.
pub fn paint() {
    let (bottom, _) = bounds();
    let sp = cortex_m::register::msp::read() as usize;
    let top = sp.saturating_sub(MARGIN) & !3;
    let mut p = bottom;
    while p < top {
        // SAFETY: [bottom, sp - MARGIN) is RAM no one uses yet (below the live stack,
        // above all statics).
        unsafe { core::ptr::write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
}

/// (bytes of stack ever used, bytes of stack available).
pub fn high_water() -> (usize, usize) {
    let (bottom, top) = bounds();
    let mut p = bottom;
    while p < top {
        // SAFETY: `p` is word-aligned and inside the stack region [_stack_end,
        // _stack_start), which is RAM: always readable.
        if unsafe { core::ptr::read_volatile(p as *const u32) } != PAINT {
            break;
        }
        p += 4;
    }
    (top - p, top - bottom)
}
