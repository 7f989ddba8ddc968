//! Small float helpers that never panic and compile to plain compares on a
//! Cortex-M4F (`f32::clamp` asserts its bounds, `f32::max` becomes a call to
//! `fmaxf` there).
//!
//! These helpers and [`crate::trig`] replace `micromath`, whose `sqrt` is coarse
//! (relative error up to 6.1 %, `sqrt(2)` = 1.5) and whose `sin` errs by up to 1.1e-3,
//! against the exact `vsqrt.f32` here and the 1.7e-7 of [`crate::trig`].

/// `x` limited to `[lo, hi]` by two compares; NaN passes through, bad bounds never
/// panic (the upper bound wins).
#[inline(always)]
pub fn clamp(x: f32, lo: f32, hi: f32) -> f32 {
    let y = if x < lo { lo } else { x };
    if y > hi {
        hi
    } else {
        y
    }
}

/// `x` if positive, else 0 (NaN → 0).
#[inline(always)]
pub fn pos(x: f32) -> f32 {
    if x > 0.0 {
        x
    } else {
        0.0
    }
}

/// Reciprocal square root `1/√x` for finite `x > 0`: bit-level first guess and three
/// Newton steps (relative error < 1e-6, ~16 FPU instructions, no division, no
/// library call; `libm::sqrtf` is a software routine on this target).
#[inline(always)]
pub fn rsqrt(x: f32) -> f32 {
    let mut y = f32::from_bits(0x5f37_59df_u32.wrapping_sub(x.to_bits() >> 1));
    let h = 0.5 * x;
    y *= 1.5 - h * y * y;
    y *= 1.5 - h * y * y;
    y *= 1.5 - h * y * y;
    y
}

/// Square root, correctly rounded (IEEE 754, bit-identical to `libm::sqrtf`): the
/// FPU's `vsqrt.f32` on hard-float Arm targets (one instruction instead of libm's
/// software routine and its 256-byte table in flash), `libm::sqrtf` elsewhere.
/// Negative input gives NaN, like libm.
#[inline(always)]
pub fn sqrtf(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        let r: u32;
        // SAFETY: moves the value into s0, takes its root there and moves it back;
        // s0 is declared clobbered; no memory, no stack.
        unsafe {
            core::arch::asm!(
                "vmov s0, {x}",
                "vsqrt.f32 s0, s0",
                "vmov {r}, s0",
                x = in(reg) x.to_bits(),
                r = lateout(reg) r,
                out("s0") _,
                options(pure, nomem, nostack)
            );
        }
        f32::from_bits(r)
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}
