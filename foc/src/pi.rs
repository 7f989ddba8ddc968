//! PI controller with output limit and anti-windup by conditional integration.
//!
//! Continuous form `C(s) = Kp + Ki/s`. Discrete (forward Euler integrator, sample
//! time `Ts`):
//!
//! ```text
//! u[n]   = clamp(Kp·e[n] + x[n] + ff, lo, hi)
//! x[n+1] = clamp(x[n] + Ki·Ts·e[n], lo, hi)   unless u is saturated and e pushes further
//! ```
//!
//! Anti-windup: when the output is at a limit and the error would drive it further
//! into the limit, the integrator is frozen (clamping / conditional integration). The
//! integrator itself is also kept inside the output range, so leaving saturation is
//! immediate (the rule is [`Pi::integrate`], shared by every PI of the crate).
//! Transfer function while unsaturated:
//! `U(z)/E(z) = Kp + Ki·Ts / (z − 1)`.
//!
//! Units are the caller's: for the current loop `e` in A, `u` in V, `Kp` in V/A and
//! `Ki` in V/(A·s).

use crate::num;

/// PI controller state and gains.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pi {
    /// Proportional gain (output unit per input unit).
    pub kp: f32,
    /// Integral gain times sample time, `Ki·Ts` (output unit per input unit and sample).
    pub ki_ts: f32,
    /// Lower output limit.
    pub lo: f32,
    /// Upper output limit.
    pub hi: f32,
    /// Integrator state (output unit).
    pub x: f32,
}

impl Pi {
    /// New controller from `kp`, `ki` (per second), sample time `ts` (s) and a
    /// symmetric output limit `±limit`.
    pub fn new(kp: f32, ki: f32, ts: f32, limit: f32) -> Self {
        let limit = if limit.is_finite() { limit.abs() } else { 0.0 };
        Pi {
            kp,
            ki_ts: ki * ts,
            lo: -limit,
            hi: limit,
            x: 0.0,
        }
    }

    /// Sets gains (the integrator state is kept: bumpless).
    pub fn set_gains(&mut self, kp: f32, ki: f32, ts: f32) {
        self.kp = kp;
        self.ki_ts = ki * ts;
    }

    /// Sets a symmetric output limit and pulls the integrator inside it.
    #[inline]
    pub fn set_limit(&mut self, limit: f32) {
        self.hi = limit;
        self.lo = -limit;
        self.x = num::clamp(self.x, self.lo, self.hi);
    }

    /// Clears the integrator.
    pub fn reset(&mut self) {
        self.x = 0.0;
    }

    /// Presets the integrator so the next output (with zero error) is `u` (bumpless
    /// transfer).
    pub fn preset(&mut self, u: f32) {
        self.x = num::clamp(u, self.lo, self.hi);
    }

    /// One update with error `e` and feed-forward `ff`; returns the limited output.
    #[inline]
    pub fn update(&mut self, e: f32, ff: f32) -> f32 {
        let (lo, hi) = (self.lo, self.hi);
        self.step_in(e, ff, lo, hi)
    }

    /// [`Pi::update`] (no feed-forward) with the output range narrowed to `[lo, hi]`
    /// for this step (`lo ≤ hi`, both inside the controller's own limits): the
    /// integrator is first pulled inside the range, then the same conditional
    /// integration runs against it. A range that moves from step to step (a speed
    /// limit whose bound is the torque demand, `crate::servo::Servo::step_torque`)
    /// never leaves the integrator outside the output it may produce.
    #[inline]
    pub fn update_within(&mut self, e: f32, lo: f32, hi: f32) -> f32 {
        let lo = num::clamp(lo, self.lo, self.hi);
        let hi = num::clamp(hi, lo, self.hi);
        self.x = num::clamp(self.x, lo, hi);
        self.step_in(e, 0.0, lo, hi)
    }

    /// The PI step with conditional integration against the output range `[lo, hi]`:
    /// while the output is limited, the integrator only moves back towards the range.
    #[inline(always)]
    fn step_in(&mut self, e: f32, ff: f32, lo: f32, hi: f32) -> f32 {
        let u = self.kp * e + self.x + ff;
        let (y, limited) = if u > hi {
            (hi, true)
        } else if u < lo {
            (lo, true)
        } else {
            (u, false)
        };
        self.integrate(e, u, limited, lo, hi);
        y
    }

    /// The anti-windup rule every PI of the crate uses (this one, the current loop's
    /// d/q pair under its voltage circle, the auto-tune's DC regulator): the
    /// integrator takes its step `Ki·Ts·e` while the output `u` (unlimited, with its
    /// feed-forward) is not `limited`, or, while it is, when the step points against
    /// `u` (back towards the inside of a limit centred on zero); it is kept inside
    /// `[lo, hi]`. For a caller that forms the output itself (a vector limit, a range
    /// that changes every step).
    #[inline(always)]
    pub fn integrate(&mut self, e: f32, u: f32, limited: bool, lo: f32, hi: f32) {
        let dx = self.ki_ts * e;
        if !limited || dx * u < 0.0 {
            self.x = num::clamp(self.x + dx, lo, hi);
        }
    }

    /// Output without limiting and without touching the integrator: `Kp·e + x`.
    #[inline]
    pub fn output_unlimited(&self, e: f32) -> f32 {
        self.kp * e + self.x
    }
}
