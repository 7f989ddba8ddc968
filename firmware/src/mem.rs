//! Small `memcpy` / `memset` for the board image (Cortex-M4, Thumb-2).
//!
//! The compiler calls `memcpy`, `memset` and the ARM EABI helpers `__aeabi_memcpy*`,
//! `__aeabi_memset*`, `__aeabi_memclr*` for every struct copy and clear. The versions
//! in `compiler_builtins` are fast for every alignment and take about 1.7 KiB of flash;
//! these two routines take about 0.1 KiB:
//!
//! * [`copy`]: when destination and source are both word-aligned, 16 bytes per
//!   `ldmia`/`stmia` pair, then words, then bytes; otherwise byte by byte (the
//!   compiler's struct copies, including the current-loop interrupt's, are aligned);
//! * [`fill`]: bytes up to word alignment, then words, then bytes.
//!
//! With the `board` feature (the board binary) they are exported under the C and EABI
//! names, which override the weak `compiler_builtins` symbols. The routines themselves are
//! built for every bare-metal Arm image, so the portable tests check them under QEMU
//! for every alignment and length (`tests/portable_mem.rs`); on the host [`copy`] and
//! [`fill`] are `core::ptr` copies.

#[cfg(all(target_arch = "arm", target_os = "none"))]
core::arch::global_asm!(
    ".section .text.ecs_memcpy,\"ax\",%progbits",
    ".global ecs_memcpy",
    ".p2align 2",
    ".type ecs_memcpy,%function",
    ".thumb_func",
    // r0 destination, r1 source, r2 length; returns the destination in r0.
    "ecs_memcpy:",
    "push {{r0, r4, r5, lr}}",
    "orr r12, r0, r1",
    "lsls r12, r12, #30",
    "bne 5f",
    "1:",
    "subs r2, r2, #16",
    "bcc 2f",
    "ldmia r1!, {{r3, r4, r5, r12}}",
    "stmia r0!, {{r3, r4, r5, r12}}",
    "b 1b",
    "2:",
    "adds r2, r2, #16",
    "3:",
    "subs r2, r2, #4",
    "bcc 4f",
    "ldr r3, [r1], #4",
    "str r3, [r0], #4",
    "b 3b",
    "4:",
    "adds r2, r2, #4",
    "5:",
    "cbz r2, 6f",
    "ldrb r3, [r1], #1",
    "strb r3, [r0], #1",
    "subs r2, r2, #1",
    "b 5b",
    "6:",
    "pop {{r0, r4, r5, pc}}",
    ".size ecs_memcpy, . - ecs_memcpy",
    "",
    ".section .text.ecs_memset,\"ax\",%progbits",
    ".global ecs_memset",
    ".p2align 2",
    ".type ecs_memset,%function",
    ".thumb_func",
    // r0 destination, r1 byte value (low 8 bits), r2 length; returns the destination.
    "ecs_memset:",
    "push {{r0, lr}}",
    "and r1, r1, #255",
    "orr r1, r1, r1, lsl #8",
    "orr r1, r1, r1, lsl #16",
    "1:",
    "tst r0, #3",
    "beq 2f",
    "cbz r2, 5f",
    "strb r1, [r0], #1",
    "subs r2, r2, #1",
    "b 1b",
    "2:",
    "subs r2, r2, #4",
    "bcc 3f",
    "str r1, [r0], #4",
    "b 2b",
    "3:",
    "adds r2, r2, #4",
    "4:",
    "cbz r2, 5f",
    "strb r1, [r0], #1",
    "subs r2, r2, #1",
    "b 4b",
    "5:",
    "pop {{r0, pc}}",
    ".size ecs_memset, . - ecs_memset",
);

#[cfg(all(target_arch = "arm", target_os = "none"))]
extern "C" {
    fn ecs_memcpy(dst: *mut u8, src: *const u8, n: usize) -> *mut u8;
    fn ecs_memset(dst: *mut u8, c: i32, n: usize) -> *mut u8;
}

/// Copies `n` bytes from `src` to `dst` (the board's `memcpy`).
///
/// # Safety
/// As for `core::ptr::copy_nonoverlapping`: `src` valid for `n` reads, `dst` for `n`
/// writes, the two ranges do not overlap.
pub unsafe fn copy(dst: *mut u8, src: *const u8, n: usize) {
    #[cfg(all(target_arch = "arm", target_os = "none"))]
    // SAFETY: the caller's guarantees are the routine's requirements.
    unsafe {
        ecs_memcpy(dst, src, n);
    }
    #[cfg(not(all(target_arch = "arm", target_os = "none")))]
    // SAFETY: as above.
    unsafe {
        core::ptr::copy_nonoverlapping(src, dst, n);
    }
}

/// Sets `n` bytes at `dst` to `value` (the board's `memset`).
///
/// # Safety
/// As for `core::ptr::write_bytes`: `dst` valid for `n` writes.
pub unsafe fn fill(dst: *mut u8, value: u8, n: usize) {
    #[cfg(all(target_arch = "arm", target_os = "none"))]
    // SAFETY: the caller's guarantee is the routine's requirement.
    unsafe {
        ecs_memset(dst, value as i32, n);
    }
    #[cfg(not(all(target_arch = "arm", target_os = "none")))]
    // SAFETY: as above.
    unsafe {
        core::ptr::write_bytes(dst, value, n);
    }
}

// The routines under the names the compiler and the ARM EABI use; only the board
// binary has them (feature `board`), so the QEMU test and benchmark images keep
// `compiler_builtins`' versions. `__aeabi_memset*` take (destination, length, value),
// `__aeabi_memclr*` (destination, length).
#[cfg(all(target_arch = "arm", target_os = "none", feature = "board"))]
core::arch::global_asm!(
    ".section .text.ecs_mem_names,\"ax\",%progbits",
    ".p2align 2",
    ".global memcpy",
    ".global __aeabi_memcpy",
    ".global __aeabi_memcpy4",
    ".global __aeabi_memcpy8",
    ".global memset",
    ".global __aeabi_memset",
    ".global __aeabi_memset4",
    ".global __aeabi_memset8",
    ".global __aeabi_memclr",
    ".global __aeabi_memclr4",
    ".global __aeabi_memclr8",
    ".thumb_func",
    "memcpy:",
    ".thumb_func",
    "__aeabi_memcpy:",
    ".thumb_func",
    "__aeabi_memcpy4:",
    ".thumb_func",
    "__aeabi_memcpy8:",
    "b.w ecs_memcpy",
    ".thumb_func",
    "memset:",
    "b.w ecs_memset",
    ".thumb_func",
    "__aeabi_memset:",
    ".thumb_func",
    "__aeabi_memset4:",
    ".thumb_func",
    "__aeabi_memset8:",
    "mov r3, r1",
    "mov r1, r2",
    "mov r2, r3",
    "b.w ecs_memset",
    ".thumb_func",
    "__aeabi_memclr:",
    ".thumb_func",
    "__aeabi_memclr4:",
    ".thumb_func",
    "__aeabi_memclr8:",
    "mov r2, r1",
    "movs r1, #0",
    "b.w ecs_memset",
);
