//! Incremental quadrature encoder: multi-turn count, integer electrical angle,
//! velocity from a phase-locked loop, index (Z) handling.
//!
//! The hardware counter (a 16-bit timer in encoder mode) is read once per control
//! step; the signed 16-bit difference to the previous reading is accumulated, so any
//! speed below 32767 counts per step is tracked (at 40 kHz and 4000 counts/rev:
//! 19 600 rev/s).
//!
//! Angles are integers: the count within one revolution `n ∈ [0, cpr)` is scaled by
//! a precomputed reciprocal ([`CountScale`]) to the mechanical angle `n/cpr` turn and
//! to the electrical angle `50·n/cpr` turn (4000 counts/rev = 80 counts per electrical
//! turn). An electrical offset (from the alignment procedure) is added.
//!
//! Velocity: second-order tracking loop (PLL) on the count,
//!
//! ```text
//! e = n − p̂          p̂ ← p̂ + Ts·(v̂ + 2ζω·e)          v̂ ← v̂ + Ts·ω²·e
//! ```
//!
//! i.e. `v̂/n = (2ζωs + ω²)/(s² + 2ζωs + ω²)·s` (ζ = 1): zero steady-state error for a
//! constant speed, −3 dB bandwidth ≈ 2.5·ω. `p̂` is kept as an integer plus an `f32`
//! fraction so it never loses resolution over many turns.

use crate::angle::{Angle, CountScale, POLE_PAIRS};
use core::f32::consts::PI;

/// `n` reduced into `[0, cpr)` (`n.rem_euclid(cpr as i32)`; `cpr` is 4..=2^24 here,
/// the checked form only keeps the impossible zero / overflow cases off the panic
/// path: they give 0).
#[inline(always)]
fn wrap(n: i32, cpr: u32) -> i32 {
    n.checked_rem_euclid(cpr as i32).unwrap_or(0)
}

/// Encoder configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EncoderConfig {
    /// Lines per revolution (counts per revolution = 4 × lines).
    pub lines: u32,
    /// Update period, s.
    pub ts: f32,
    /// PLL natural frequency ω, rad/s.
    pub pll_omega: f32,
}

impl Default for EncoderConfig {
    fn default() -> Self {
        EncoderConfig {
            lines: 1000,
            ts: 25e-6,
            pll_omega: 8000.0,
        }
    }
}

/// Z-index bookkeeping.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IndexState {
    /// An index pulse has been seen since reset.
    pub seen: bool,
    /// Count within the revolution at the first index pulse.
    pub reference: u32,
    /// Multi-turn position at the last index pulse.
    pub last_position: i32,
    /// Deviation (counts) found at the last index pulse (0 = no lost counts).
    pub last_error: i32,
    /// Number of index pulses whose position deviated by more than one count.
    pub error_count: u32,
}

/// Quadrature encoder state.
#[derive(Clone, Debug)]
pub struct Encoder {
    cpr: u32,
    last_raw: u16,
    position: i32,
    in_rev: u32,
    mech: CountScale,
    elec: CountScale,
    elec_offset: Angle,
    ts: f32,
    k1: f32,
    k2: f32,
    pll_pos: i32,
    pll_frac: f32,
    pll_vel: f32,
    /// Z-index state.
    pub index: IndexState,
}

impl Encoder {
    /// New encoder; `raw` is the present hardware counter value. Lines are clamped to
    /// `1..=2^22`.
    pub fn new(cfg: EncoderConfig, raw: u16) -> Self {
        let cpr = cfg.lines.clamp(1, 1 << 22) * 4;
        let w = if cfg.pll_omega.is_finite() {
            cfg.pll_omega.max(0.0)
        } else {
            0.0
        };
        Encoder {
            cpr,
            last_raw: raw,
            position: 0,
            in_rev: 0,
            mech: CountScale::new(cpr, 1),
            elec: CountScale::new(cpr, POLE_PAIRS),
            elec_offset: Angle::ZERO,
            ts: cfg.ts,
            k1: 2.0 * w,
            k2: w * w,
            pll_pos: 0,
            pll_frac: 0.0,
            pll_vel: 0.0,
            index: IndexState::default(),
        }
    }

    /// Counts per revolution.
    pub fn cpr(&self) -> u32 {
        self.cpr
    }

    /// Reads a new hardware counter value; returns the counts moved since the last call.
    #[inline]
    pub fn update(&mut self, raw: u16) -> i32 {
        let delta = raw.wrapping_sub(self.last_raw) as i16 as i32;
        self.last_raw = raw;
        self.position = self.position.wrapping_add(delta);
        // Keep the count within the revolution in [0, cpr).
        let mut n = self.in_rev as i32 + delta;
        if n < 0 || n >= self.cpr as i32 {
            n = wrap(n, self.cpr);
        }
        self.in_rev = n as u32;
        // PLL.
        let e = self.position.wrapping_sub(self.pll_pos) as f32 - self.pll_frac;
        self.pll_frac += self.ts * (self.pll_vel + self.k1 * e);
        self.pll_vel += self.ts * self.k2 * e;
        let whole = self.pll_frac as i32;
        self.pll_pos = self.pll_pos.wrapping_add(whole);
        self.pll_frac -= whole as f32;
        delta
    }

    /// Index pulse: `raw_at_index` is the counter value latched by the hardware at the
    /// pulse (it must belong to the interval of the last [`Encoder::update`]). The first
    /// pulse records the reference; later ones check it and correct lost counts.
    pub fn on_index(&mut self, raw_at_index: u16) {
        let back = self.last_raw.wrapping_sub(raw_at_index) as i16 as i32;
        let pos = self.position.wrapping_sub(back);
        let n = wrap(self.in_rev as i32 - back, self.cpr) as u32;
        if !self.index.seen {
            self.index.seen = true;
            self.index.reference = n;
            self.index.last_error = 0;
        } else {
            let half = (self.cpr / 2) as i32;
            let mut dev = n as i32 - self.index.reference as i32;
            if dev >= half {
                dev -= self.cpr as i32;
            } else if dev < -half {
                dev += self.cpr as i32;
            }
            self.index.last_error = dev;
            if dev.abs() > 1 {
                self.index.error_count = self.index.error_count.saturating_add(1);
                // Correct the revolution count (the multi-turn position keeps its
                // history, the angle is resynchronised).
                self.in_rev = wrap(self.in_rev as i32 - dev, self.cpr) as u32;
            }
        }
        self.index.last_position = pos;
    }

    /// Multi-turn position, counts (wraps at ±2^31).
    #[inline]
    pub fn position(&self) -> i32 {
        self.position
    }

    /// Sets the multi-turn position (the angle is unaffected).
    pub fn set_position(&mut self, pos: i32) {
        let d = pos.wrapping_sub(self.position);
        self.position = pos;
        self.pll_pos = self.pll_pos.wrapping_add(d);
    }

    /// Count within the revolution, `[0, cpr)`.
    pub fn count_in_rev(&self) -> u32 {
        self.in_rev
    }

    /// Mechanical angle.
    #[inline]
    pub fn mechanical_angle(&self) -> Angle {
        self.mech.angle(self.in_rev)
    }

    /// Electrical angle without the alignment offset.
    #[inline]
    pub fn raw_electrical_angle(&self) -> Angle {
        self.elec.angle(self.in_rev)
    }

    /// Electrical angle (alignment offset included).
    #[inline]
    pub fn electrical_angle(&self) -> Angle {
        self.elec.angle(self.in_rev).wrapping_add(self.elec_offset)
    }

    /// Sets the electrical offset found by the alignment.
    pub fn set_electrical_offset(&mut self, offset: Angle) {
        self.elec_offset = offset;
    }

    /// Electrical offset in use.
    pub fn electrical_offset(&self) -> Angle {
        self.elec_offset
    }

    /// PLL velocity estimate, counts/s.
    #[inline]
    pub fn velocity(&self) -> f32 {
        self.pll_vel
    }

    /// PLL position estimate: integer part and fraction (counts).
    #[inline]
    pub fn position_estimate(&self) -> (i32, f32) {
        (self.pll_pos, self.pll_frac)
    }

    /// Electrical angular velocity, rad/s.
    #[inline]
    pub fn omega_e(&self) -> f32 {
        self.pll_vel * (2.0 * PI * POLE_PAIRS as f32) / self.cpr as f32
    }

    /// Mechanical angular velocity, rad/s.
    #[inline]
    pub fn omega(&self) -> f32 {
        self.pll_vel * (2.0 * PI) / self.cpr as f32
    }
}
