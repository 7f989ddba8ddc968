//! Exact scaling between command units and encoder counts (0x2001 / encoder
//! resolution, 0x2029 direction): integer ratios, floor division without checks.

use core::num::{NonZeroU32, NonZeroU64};

/// Exact scaling between command units and encoder counts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Scale {
    // Both ≥ 1 (no division checks) and below 2^24.
    pub(super) units: NonZeroU32,
    pub(super) counts: NonZeroU32,
    // Precomputed ratios (i64 → f32 conversions are library calls on the M4).
    cpu: f32,
    upc: f32,
}

/// `x.div_euclid(d)` for `d > 0` by one unsigned division: for `x < 0`,
/// `floor(x / d) = !((!x) / d)` with `!x = −x − 1 ≥ 0` (no overflow or zero checks).
#[inline]
pub(super) fn floor_div_i32(x: i32, d: NonZeroU32) -> i32 {
    let m = x >> 31;
    (((x ^ m) as u32) / d) as i32 ^ m
}

/// [`floor_div_i32`] in 64 bits.
#[inline]
pub(crate) fn floor_div_i64(x: i64, d: NonZeroU64) -> i64 {
    let m = x >> 63;
    (((x ^ m) as u64) / d) as i64 ^ m
}

impl Scale {
    pub(super) fn new(units: u32, counts: u32) -> Self {
        let (u, c) = (units.max(1), counts.max(1));
        Scale {
            units: NonZeroU32::new(u).unwrap_or(NonZeroU32::MIN),
            counts: NonZeroU32::new(c).unwrap_or(NonZeroU32::MIN),
            // Both are below 2^24 (pulses per revolution ≤ 51 200, encoder counts per
            // revolution ≤ 240 000), so they are exact in f32 and the quotient is
            // correctly rounded without pulling f64 soft-float into the image.
            cpu: c as f32 / u as f32,
            upc: u as f32 / c as f32,
        }
    }
    /// Command units → counts: integer part and fraction in [0, 1).
    pub(super) fn to_counts(self, p: i32) -> (i32, f32) {
        let (u, c) = (self.units.get(), self.counts.get());
        if u64::from(u) * u64::from(c) < (1 << 31) {
            // p = a·U + b, 0 ≤ b < U: counts = a·C + (b·C)/U with 32-bit hardware
            // divisions only (b·C < U·C < 2^31).
            let a = floor_div_i32(p, self.units);
            let b = p.wrapping_sub(a.wrapping_mul(u as i32)) as u32;
            let t = b * c;
            let q = t / self.units;
            let r = t - q * u;
            return (
                a.wrapping_mul(c as i32).wrapping_add(q as i32),
                r as f32 / u as f32,
            );
        }
        self.to_counts_wide(p)
    }
    /// [`Scale::to_counts`] in 64 bits (any U·C).
    pub(super) fn to_counts_wide(self, p: i32) -> (i32, f32) {
        let units = i64::from(self.units.get());
        let n = i64::from(p) * i64::from(self.counts.get());
        // One 64-bit division (a library call on the M4); the remainder from it.
        let q = floor_div_i64(n, NonZeroU64::from(self.units));
        let r = n - q * units;
        (q as i32, r as f32 / units as f32)
    }
    /// Counts → command units, rounded to nearest.
    // Measured (cargo xtask size, LAN9252 image): dropped with the other hot-path
    // attributes the image grew 1184 B; see `hw::pwm::enable_outputs`.
    #[inline(never)]
    pub(super) fn to_units(self, n: i32) -> i32 {
        let c = u64::from(self.counts.get());
        let x = 2 * i64::from(n) * i64::from(self.units.get()) + c as i64;
        // 2·C ≥ 2.
        floor_div_i64(x, NonZeroU64::new(2 * c).unwrap_or(NonZeroU64::MIN)) as i32
    }
    pub(super) fn counts_per_unit(self) -> f32 {
        self.cpu
    }
    pub(super) fn units_per_count(self) -> f32 {
        self.upc
    }
}
