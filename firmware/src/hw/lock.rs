//! The lock of the drive state shared by the cyclic path (interrupt executor,
//! priority [`CYCLIC_PRIORITY`]) and the thread-mode tasks (EtherCAT poll, 1 ms tick,
//! supervisor): a priority-ceiling lock.
//!
//! Locking raises BASEPRI to the cyclic path's priority: the cyclic executor and
//! everything less urgent (EXTI wakers, the time driver) wait, while the break
//! interrupts, the current-loop interrupt and the SPI-DMA interrupts (the levels above
//! [`firmware::irq_priority::CYCLIC`]) keep running — unlike a critical section, which
//! would delay the current loop. The
//! cyclic path itself runs at the ceiling, so nothing that takes this lock can
//! preempt it: the lock never blocks, it only defers. Nested use restores the outer
//! BASEPRI.
//!
//! Nothing above the cyclic level may take this lock (it would not exclude the others).
use embassy_stm32::interrupt::Priority;
use embassy_sync::blocking_mutex::raw::RawMutex;

/// Priority of the cyclic interrupt executor (and of the ESC IRQ / SYNC0 EXTI lines).
pub const CYCLIC_PRIORITY: Priority = priority(firmware::irq_priority::CYCLIC);

/// The embassy priority of a level of [`firmware::irq_priority`].
pub const fn priority(level: u8) -> Priority {
    match level {
        0 => Priority::P0,
        1 => Priority::P1,
        2 => Priority::P2,
        3 => Priority::P3,
        4 => Priority::P4,
        _ => Priority::P15,
    }
}

// Every level of the table maps to its own register value.
const _: () = {
    let all = firmware::irq_priority::ALL;
    let mut i = 0;
    while i < all.len() {
        assert!(priority(all[i].1) as u8 == firmware::irq_priority::register(all[i].1));
        i += 1;
    }
};

/// Priority-ceiling raw mutex (see the module docs).
pub struct CyclicCeiling(());

// SAFETY: mutual exclusion between every context at or below CYCLIC_PRIORITY on a
// single core: while BASEPRI masks that priority, none of them can start running.
unsafe impl RawMutex for CyclicCeiling {
    const INIT: Self = CyclicCeiling(());

    fn lock<R>(&self, f: impl FnOnce() -> R) -> R {
        let old = cortex_m::register::basepri::read();
        // basepri_max only ever raises the masking level.
        cortex_m::register::basepri_max::write(CYCLIC_PRIORITY as u8);
        // Keep the protected accesses between the two BASEPRI writes.
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
        let r = f();
        core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
        // SAFETY: restores the level found on entry (0 = no masking in thread mode).
        unsafe { cortex_m::register::basepri::write(old) };
        r
    }
}
