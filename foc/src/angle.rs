//! Wrapping fixed-point angles.
//!
//! An [`Angle`] is a `u32` where `2^32` is one full turn, so one LSB is
//! `2π / 2^32 ≈ 1.46e-9 rad`. Addition and subtraction wrap modulo one turn for free
//! (two's complement), which is exactly the behaviour of a rotor angle. The signed
//! view (`as i32`) is the angle in `[-½, ½)` turn.
//!
//! The two-phase hybrid stepper has [`POLE_PAIRS`] = 50 rotor teeth: the electrical
//! angle is `θe = 50·θ`. In fixed point this is a wrapping multiplication by 50, exact
//! to the LSB (the lost high bits are whole electrical turns).
//!
//! The `fixed` crate's `U0F32` / `I0F32` would express the wrapping sum, difference
//! and integer multiply with the same code (identical Thumb-2 output), but its float
//! conversions are correctly rounded software routines where the casts here are one
//! `vcvt`: built with `fixed` 1.31 for `thumbv7em-none-eabihf` at opt-level 3,
//! `to_radians` is 55 instructions against 9, `add_radians` 124 against 9 and
//! `from_turns` 98 against 51 (function bodies, prologue included). So `Angle` stays a
//! plain `u32`, and `foc` depends on `libm` only.

use core::f32::consts::PI;

/// Rotor teeth (pole pairs) of a 1.8° two-phase hybrid stepper: θe = 50·θ.
pub const POLE_PAIRS: u32 = 50;

/// Radians per LSB of an [`Angle`] (`2π / 2^32`).
pub const RAD_PER_LSB: f32 = 2.0 * PI / 4_294_967_296.0;

/// A wrapping angle, `u32::MAX + 1` = one turn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Angle(pub u32);

impl Angle {
    /// Zero angle.
    pub const ZERO: Angle = Angle(0);
    /// A quarter turn (90°).
    pub const QUARTER: Angle = Angle(1 << 30);
    /// A half turn (180°).
    pub const HALF: Angle = Angle(1 << 31);

    /// From a fraction of a turn (any value, wraps). Saturates non-finite input to 0.
    pub fn from_turns(turns: f32) -> Self {
        if !turns.is_finite() {
            return Angle::ZERO;
        }
        let frac = turns - libm::floorf(turns);
        // frac in [0, 1]; ×2^32 is exact in f32 (a power of two) and the cast one
        // `vcvt` (a detour through f64 and u64 cost soft-float routines: 1.3 KiB of
        // flash and their cycles). 1.0 (a tiny negative `turns` rounds to it) is a
        // whole turn: 0.
        let lsb = frac * 4_294_967_296.0;
        Angle(if lsb < 4_294_967_296.0 { lsb as u32 } else { 0 })
    }

    /// From radians (any value, wraps).
    pub fn from_radians(rad: f32) -> Self {
        Self::from_turns(rad * (0.5 / PI))
    }

    /// Signed angle in turns, `[-0.5, 0.5)`.
    #[inline]
    pub fn to_turns(self) -> f32 {
        self.0 as i32 as f32 * (1.0 / 4_294_967_296.0)
    }

    /// Signed angle in radians, `[-π, π)`.
    #[inline]
    pub fn to_radians(self) -> f32 {
        self.0 as i32 as f32 * RAD_PER_LSB
    }

    /// Electrical angle of this mechanical angle: `50·θ` (wrapping, exact).
    #[inline]
    pub fn electrical(self) -> Angle {
        Angle(self.0.wrapping_mul(POLE_PAIRS))
    }

    /// Wrapping sum.
    #[inline]
    pub fn wrapping_add(self, other: Angle) -> Angle {
        Angle(self.0.wrapping_add(other.0))
    }

    /// Wrapping difference.
    #[inline]
    pub fn wrapping_sub(self, other: Angle) -> Angle {
        Angle(self.0.wrapping_sub(other.0))
    }

    /// Signed shortest difference `self − other` in LSB (`[-2^31, 2^31)`).
    #[inline]
    pub fn diff(self, other: Angle) -> i32 {
        self.0.wrapping_sub(other.0) as i32
    }

    /// Adds a (small, any sign) angle given in radians: the increment is converted to
    /// LSB with saturation at ±½ turn.
    #[inline]
    pub fn add_radians(self, rad: f32) -> Angle {
        let lsb = rad * (1.0 / RAD_PER_LSB);
        // `as i32` saturates (and maps NaN to 0).
        Angle(self.0.wrapping_add(lsb as i32 as u32))
    }
}

/// Integer-to-angle scaling for a position counter with `period` counts per turn:
/// `angle = count · 2^32 / period` computed as `(count · k) >> 16` with the reciprocal
/// `k = round(2^48 · mult / period)` (precomputed; no division at run time).
///
/// Exact to ≤ 2 LSB of the `u32` angle for `count < period < 2^24` and
/// `mult ≤ 256`. With `mult = 50` a mechanical count gives the electrical angle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CountScale {
    k: u64,
    period: u32,
}

impl CountScale {
    /// `period` counts per turn (clamped to ≥ 1), angle multiplied by `mult` (≥ 1).
    pub fn new(period: u32, mult: u32) -> Self {
        let period = period.max(1);
        let mult = mult.clamp(1, 256) as u128;
        let k = (((mult << 48) + (period as u128 / 2)) / period as u128) as u64;
        CountScale { k, period }
    }

    /// Counts per turn.
    pub fn period(&self) -> u32 {
        self.period
    }

    /// Angle of `count` (must be in `[0, period)`; larger values still wrap correctly
    /// as long as `count · k < 2^64`).
    #[inline]
    pub fn angle(&self, count: u32) -> Angle {
        Angle(((count as u64).wrapping_mul(self.k) >> 16) as u32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn electrical_is_fifty_times() {
        let a = Angle::from_turns(1.0 / 200.0); // one full step = ¼ electrical turn
        let e = a.electrical();
        assert!((e.to_turns() - 0.25).abs() < 1e-6);
    }

    #[test]
    fn from_turns_is_the_exact_fraction() {
        // The f32 fraction of a turn ×2^32, truncated, computed in f64 (exact there)
        // and wrapped.
        let exact = |t: f32| {
            let frac = t - libm::floorf(t);
            ((frac as f64) * 4_294_967_296.0) as u64 as u32
        };
        let mut x = 0x1234_5678u32;
        for i in 0..20_000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            let t = f32::from_bits(x);
            let t = if t.is_finite() {
                t
            } else {
                i as f32 * 0.37 - 3000.0
            };
            assert_eq!(Angle::from_turns(t).0, exact(t), "{t}");
        }
        assert_eq!(Angle::from_turns(0.25), Angle::QUARTER);
        assert_eq!(Angle::from_turns(-0.5), Angle::HALF);
        assert_eq!(Angle::from_turns(3.0), Angle::ZERO);
        assert_eq!(
            Angle::from_turns(1.0 - f32::EPSILON / 2.0).0,
            u32::MAX - 255
        );
        // A tiny negative turn rounds to a whole turn in f32: 0, not a saturated cast.
        assert_eq!(Angle::from_turns(-1e-10), Angle::ZERO);
        assert_eq!(Angle::from_turns(f32::NAN), Angle::ZERO);
        assert_eq!(Angle::from_turns(f32::INFINITY), Angle::ZERO);
    }

    #[test]
    fn count_scale_matches_exact() {
        let s = CountScale::new(4000, 50);
        for c in 0..4000u32 {
            let exact = ((c as u64 * 50) << 32) / 4000;
            let got = s.angle(c).0 as u64;
            let d = (got as i64 - (exact as u32) as i64).unsigned_abs();
            assert!(d <= 2 || d >= (1u64 << 32) - 2, "{c}: {d}");
        }
    }
}
