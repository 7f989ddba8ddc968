//! Sine and cosine of an [`Angle`].
//!
//! [`SinCos`] is the seam: the portable [`PolySinCos`] below, [`LibmSinCos`] as the
//! accurate reference, and a board may add one backed by the STM32G4 CORDIC.
//!
//! [`PolySinCos`] folds the angle into `[-¼, ¼]` turn with integer operations
//! (`sin(½ − x) = sin x`) and evaluates an odd polynomial of degree 11 in turns
//! (Taylor coefficients of `sin 2πx`, whose truncation error at ¼ turn is
//! `(π/2)^13/13! ≈ 6e-8`). Cosine is the sine of the angle plus ¼ turn. Measured
//! maximum error against `f64` sin/cos: 1.7e-7 over 2^24 angles (host sweep), bound
//! [`POLY_MAX_ERROR`] = 5e-7 asserted by the portable test `sincos_error_bound` on the
//! host and under QEMU, i.e. f32 rounding.
//! Cost on a Cortex-M4F: ~20 instructions per function, no table, no branch
//! misprediction concerns (one conditional fold).

use crate::angle::Angle;

/// Upper bound of `|PolySinCos − libm|` over all angles (asserted by the tests).
pub const POLY_MAX_ERROR: f32 = 5.0e-7;

/// A (sin, cos) provider.
pub trait SinCos {
    /// Returns `(sin θ, cos θ)`.
    fn sin_cos(&self, theta: Angle) -> (f32, f32);
}

/// Polynomial sine/cosine, see the module docs.
#[derive(Clone, Copy, Debug, Default)]
pub struct PolySinCos;

// sin(2πx) = Σ c_k x^k (digits as computed; f32 rounds them), c_k = (−1)^((k−1)/2) (2π)^k / k!
const C1: f32 = core::f32::consts::TAU;
const C3: f32 = -41.341_7;
const C5: f32 = 81.605_25;
const C7: f32 = -76.705_86;
const C9: f32 = 42.058_694;
const C11: f32 = -15.094_643;

/// Sine of an angle with the polynomial of the module docs.
#[inline]
pub fn sin(theta: Angle) -> f32 {
    let mut s = theta.0 as i32;
    // Fold |x| > ¼ turn: x → ½ − x (for x > 0) or −½ − x (x < 0); both are
    // `i32::MIN − x` in wrapping arithmetic.
    if s.unsigned_abs() > (1 << 30) {
        s = i32::MIN.wrapping_sub(s);
    }
    let x = s as f32 * (1.0 / 4_294_967_296.0);
    let x2 = x * x;
    x * (C1 + x2 * (C3 + x2 * (C5 + x2 * (C7 + x2 * (C9 + x2 * C11)))))
}

/// Cosine: `sin(θ + ¼ turn)`.
#[inline]
pub fn cos(theta: Angle) -> f32 {
    sin(theta.wrapping_add(Angle::QUARTER))
}

impl SinCos for PolySinCos {
    #[inline]
    fn sin_cos(&self, theta: Angle) -> (f32, f32) {
        (sin(theta), cos(theta))
    }
}

/// Reference implementation with `libm` (slow, accurate).
#[derive(Clone, Copy, Debug, Default)]
pub struct LibmSinCos;

impl SinCos for LibmSinCos {
    fn sin_cos(&self, theta: Angle) -> (f32, f32) {
        let r = theta.to_radians();
        (libm::sinf(r), libm::cosf(r))
    }
}
