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
//!
//! # Angle and speed for the current loop
//! A count is 4.5° electrical at 4000 counts/rev. Commutating on the count itself
//! makes the voltage vector jump by that much at every edge, and the PLL speed,
//! which follows each edge within its bandwidth (≈ 3 kHz), ripples at the edge
//! pattern: both reach the current as steps at non-integer speeds, where the count
//! pattern does not repeat. The current loop therefore takes angle and speed from
//! a second, slower **commutation tracker** (type 3, all three poles at −ω):
//!
//! ```text
//! p̂⁻ = p̂ + Ts·v̂      e = n − p̂⁻      p̂ = p̂⁻ + 3ωTs·e      v̂ ← v̂ + Ts·â + 3ω²Ts·e      â ← â + ω³Ts·e
//! ```
//!
//! `p̂/n = (3ωs² + 3ω²s + ω³)/(s + ω)³`. Being of type 3 it has no lag at constant
//! speed nor at constant acceleration; a jerk `J` leaves a position lag of `J/ω³`.
//!
//! ## Two bandwidths: the count's quantisation against the motion
//! The count is the shaft's position floored to a whole count: `n − (θ − ½)` is a
//! sawtooth of 1 count peak-to-peak whose frequency is the *beat* of the speed
//! against the sampling, `f_s·|v·Ts − round(v·Ts)|` for speed `v` in counts/s (and,
//! with amplitude 1/q, its distance to every fraction p/q). At 10.013 rev/s (1.0013
//! counts per sample) it is 52 Hz; near 10 rev/s it goes down to 0. A linear
//! tracker passes the sawtooth below its bandwidth and attenuates it only as
//! `3ω/(2πf)` above (relative degree 1). On the plant (i_q* = 0.5 A, 10 rev/s,
//! angle error `a·sin 2πft` injected): 0.5 count at 30-300 Hz gives 16-31 mA of i_q
//! ripple, at 3 Hz and below it is lost in the 4 mA of the ADC quantisation. The
//! quantisation must therefore reach the angle only below a few hertz, while the
//! motion (accelerations, shocks) needs tens of hertz.
//!
//! The tracker separates the two by the size of the innovation. Its own error seen
//! through the quantisation is at most ½ count (plus the estimate's error), so an
//! innovation beyond [`FINE_BAND`] (1 count) is motion the estimate missed. The
//! correction is
//!
//! ```text
//! g·e + g′·(e − clamp(e, −1, 1))       g = (3ω, 3ω², ω³)·Ts at ω = COMMUTATION_OMEGA
//!                                      g′ = (3ω′, 3ω′², ω′³)·Ts at ω′ = ACQUISITION_OMEGA
//! ```
//!
//! a linear tracker at [`COMMUTATION_OMEGA`] (80 rad/s, −3 dB ≈ 25 Hz) inside the
//! band, to which a tracker at [`ACQUISITION_OMEGA`] (250 rad/s) is added on the
//! part of the error beyond it: a step of acceleration or a speed the tracker does
//! not know yet is followed as fast as by the 250 rad/s tracker, to within a count,
//! and the last count is closed at 80 rad/s. Within the band the loop is linear
//! and stable (the slow tracker alone), so the nonlinearity cannot sustain a limit
//! cycle; it acts only while the error exceeds a count. At 10.013 rev/s (52 Hz
//! beat) the angle error is 0.34 count peak (0.53 with the 250 rad/s tracker
//! alone); where the beat is slower than the tracker's 25 Hz it passes. With the
//! current loop's decoupling on the measured currents
//! (`crate::current_loop`, "Decoupling") the i_q ripple stays ≤ 8.1 mA from
//! 0.0013 to 10.13 rev/s, including speeds within 0.0005 rev/s of 10 (BENCHMARKS.md,
//! "Robustness", and `tests-host/tests/robustness.rs`).
//!
//! Beyond [`TRACKER_LIMIT`] (8 counts) the tracker is re-started on the count at the
//! PLL's speed: from a stand-still state against a shaft already turning, the PLL
//! (≈ 3 kHz) has the speed within a millisecond, the tracker would need tens.
//!
//! Its angle ([`Encoder::commutation_angle`]) is the count's angle moved by
//! `p̂ − n`, bounded to ±[`MAX_INTERPOLATION`] counts: whatever the motion (a
//! shock, an acceleration step), the commutation stays within 9° electrical of the
//! count, the PLL and the servo loops are not affected. `p̂` is kept relative to the
//! count, so it keeps its resolution over any number of turns.
//!
//! Cost: the band adds a clamp, a subtraction and three multiply-adds to the
//! tracker's step; the acquisition gains are the fine gains times the constant
//! ratios `(ω′/ω)ⁱ`, so no state is added.

use crate::angle::{Angle, CountScale, POLE_PAIRS};
use core::f32::consts::PI;

/// `n` reduced into `[0, cpr)` (`n.rem_euclid(cpr as i32)`; `cpr` is 4..=2^24 here,
/// the checked form only keeps the impossible zero / overflow cases off the panic
/// path: they give 0).
#[inline(always)]
fn wrap(n: i32, cpr: u32) -> i32 {
    n.checked_rem_euclid(cpr as i32).unwrap_or(0)
}

/// Largest correction of the commutation angle against the count, counts.
pub const MAX_INTERPOLATION: f32 = 2.0;

/// Pole of the commutation tracker inside [`FINE_BAND`], rad/s (triple; −3 dB
/// ≈ 2·ω = 25 Hz).
///
/// Chosen on the plant (i_q* = 0.5 A, shaft at constant speed, i_q peak-to-peak
/// over 0.013-10.013 rev/s in steps of 0.25 and at 20 speeds near 0, 5 and 10
/// rev/s, both motors, worst of the two, the current loop decoupling on the
/// measured currents): 50 rad/s gives 7.7 mA, 80 rad/s 8.1 mA, 120 rad/s 8.5 mA;
/// the linear tracker at 250 rad/s alone 12.1 mA (at 10.013 rev/s). 80 keeps the
/// lag of a jerk inside the band (`J/ω³`) four times smaller than 50 would.
pub const COMMUTATION_OMEGA: f32 = 80.0;

/// Pole of the tracker added on the error beyond [`FINE_BAND`], rad/s (triple).
pub const ACQUISITION_OMEGA: f32 = 250.0;

/// Half-width of the band within which the innovation is taken as the count's
/// quantisation, counts.
pub const FINE_BAND: f32 = 1.0;

/// The acquisition gains over the fine gains: `(ω′/ω)`, `(ω′/ω)²`, `(ω′/ω)³`.
const ACQUISITION_RATIO: [f32; 3] = {
    let r = ACQUISITION_OMEGA / COMMUTATION_OMEGA;
    [r, r * r, r * r * r]
};

/// Bound of the commutation tracker's state against the count, counts (beyond it the
/// tracker is re-started on the count at the PLL's speed: a start, a stall, a shock).
pub const TRACKER_LIMIT: f32 = 8.0;

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
    /// Electrical angle of one count, in [`Angle`] units (2³² per turn).
    elec_per_count: f32,
    ts: f32,
    k1: f32,
    k2: f32,
    pll_pos: i32,
    pll_frac: f32,
    pll_vel: f32,
    /// Commutation tracker: `p̂ − n` (counts), `v̂` (counts/s), `â` (counts/s²).
    trk_pos: f32,
    trk_vel: f32,
    trk_acc: f32,
    /// Its fine gains times Ts: 3ω·Ts, 3ω²·Ts, ω³·Ts (ω = [`COMMUTATION_OMEGA`]).
    trk_k: [f32; 3],
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
            elec_per_count: 4_294_967_296.0 * POLE_PAIRS as f32 / cpr as f32,
            ts: cfg.ts,
            k1: 2.0 * w,
            k2: w * w,
            pll_pos: 0,
            pll_frac: 0.0,
            pll_vel: 0.0,
            trk_pos: 0.0,
            trk_vel: 0.0,
            trk_acc: 0.0,
            trk_k: {
                let (w, ts) = (COMMUTATION_OMEGA, cfg.ts);
                [3.0 * w * ts, 3.0 * w * w * ts, w * w * w * ts]
            },
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
        self.track(delta);
        delta
    }

    /// The commutation tracker's step (module doc) for a count that moved by `delta`:
    /// the prediction from the last estimate, then its correction by the new count
    /// (fine gains, plus the acquisition gains on the error beyond [`FINE_BAND`]), so
    /// the estimate is the shaft's at this sample.
    #[inline]
    fn track(&mut self, delta: i32) {
        let p = self.trk_pos + self.ts * self.trk_vel - delta as f32;
        if !(-TRACKER_LIMIT..=TRACKER_LIMIT).contains(&p) {
            // Far off the count (or not finite): restart on it at the PLL's speed.
            self.trk_pos = 0.0;
            self.trk_vel = if self.pll_vel.is_finite() {
                self.pll_vel
            } else {
                0.0
            };
            self.trk_acc = 0.0;
            return;
        }
        let [k1, k2, k3] = self.trk_k;
        let [r1, r2, r3] = ACQUISITION_RATIO;
        let e = -p;
        // The part of the innovation beyond the count's quantisation (module doc).
        let o = e - crate::num::clamp(e, -FINE_BAND, FINE_BAND);
        self.trk_pos = p + k1 * (e + r1 * o);
        self.trk_vel += self.ts * self.trk_acc + k2 * (e + r2 * o);
        self.trk_acc += k3 * (e + r3 * o);
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

    /// Commutation angle for the current loop (alignment offset included): the
    /// count's angle moved by the commutation tracker's `p̂ − n`, at most
    /// ±[`MAX_INTERPOLATION`] counts (module doc).
    #[inline]
    pub fn commutation_angle(&self) -> Angle {
        let d = crate::num::clamp(self.trk_pos, -MAX_INTERPOLATION, MAX_INTERPOLATION);
        self.electrical_angle()
            .wrapping_add(Angle((d * self.elec_per_count) as i32 as u32))
    }

    /// Electrical speed of the commutation tracker, rad/s (the current loop's
    /// feed-forward speed, module doc).
    #[inline]
    pub fn commutation_omega_e(&self) -> f32 {
        self.trk_vel * self.elec_per_count * (2.0 * PI / 4_294_967_296.0)
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
