//! Open-loop microstepping.
//!
//! The command position (pulses, `pulses_per_rev` per motor revolution) passes the
//! command-smoothing filter, is turned into an electrical angle
//! `θe = 50·pos/ppr` turn (integer reciprocal, exact to a few LSB) and a current
//! vector of magnitude `I` is placed on that angle (`i_d* = I`, `i_q* = 0` in the
//! frame of the command angle). The rotor follows with a load angle
//! `asin(T_load / (Kt·I))`.
//!
//! Current magnitude:
//! * soft start: after [`OpenLoop::enable`] the current ramps linearly from 0 to the
//!   running current over `soft_start` seconds;
//! * stand-by: when the filtered command has not changed for `standby` seconds the
//!   current ramps down (over [`HOLD_RAMP`] s) to `holding_percent` % of the running
//!   current; it returns to the running current at once when motion resumes;
//! * voltage headroom: while the current loop reports voltage limiting the current
//!   is derated (down to 50 %) and recovers afterwards ([`OpenLoop::voltage_limited`]).
//!
//! Command smoothing: a moving average over `N = filter_time/ts` steps,
//! `H(z) = (1/N)·Σ_{k<N} z^{−k}` (delay `(N−1)·ts/2`, first zero at `1/(N·ts)` Hz),
//! computed exactly on the integer increments (no drift, the output reaches the
//! command exactly). `N` is limited to [`MAX_TAPS`].

use crate::angle::{Angle, CountScale, POLE_PAIRS};
use core::f32::consts::PI;

/// Longest moving average (steps): 25.6 ms at a 10 kHz step rate, the longest
/// smoothing time the drive's parameters (0x2010:2) and DIP tables ask for. Each
/// window holds this many words, so it sets the filter's RAM (1 KiB).
pub const MAX_TAPS: usize = 256;
/// Current reduction per step while the current loop is voltage-limited.
pub const DERATE_DOWN: f32 = 0.005;
/// Current recovery per step without voltage limiting.
pub const DERATE_UP: f32 = 0.0001;
/// Smallest current factor of the voltage-headroom management.
pub const DERATE_MIN: f32 = 0.5;
/// Ramp time from running to holding current, s.
///
/// (The derating constants above are per step and were chosen on the plant
/// simulation at a 10 kHz step rate: ECN57-20, 48 V, 7.07 A, 1 N·m at 600 rpm.)
pub const HOLD_RAMP: f32 = 0.01;

/// Exact integer moving average of a position command, see the module docs.
#[derive(Clone, Debug)]
#[repr(C)]
pub struct MovingAverage {
    n: usize,
    head: usize,
    last_in: i32,
    out: i32,
    sum: i64,
    rem: i64,
    taps: [i32; MAX_TAPS],
}

impl MovingAverage {
    /// `n` taps (clamped to `1..=MAX_TAPS`), starting at position `start`.
    pub fn new(n: usize, start: i32) -> Self {
        MovingAverage {
            taps: [0; MAX_TAPS],
            n: n.clamp(1, MAX_TAPS),
            head: 0,
            sum: 0,
            rem: 0,
            last_in: start,
            out: start,
        }
    }

    /// Re-initialises in place: the same state as `new(n, start)`, without a
    /// `MAX_TAPS`-word value on the stack (for reconfiguration inside an interrupt).
    pub fn reinit(&mut self, n: usize, start: i32) {
        self.n = n.clamp(1, MAX_TAPS);
        self.head = 0;
        self.reset(start);
    }

    /// Number of taps.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Always false (there is at least one tap).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Restarts at `pos` with no motion in the window.
    pub fn reset(&mut self, pos: i32) {
        self.taps[..self.n].fill(0);
        self.sum = 0;
        self.rem = 0;
        self.last_in = pos;
        self.out = pos;
    }

    /// Feeds the command `x`; returns the filtered position.
    #[inline]
    pub fn step(&mut self, x: i32) -> i32 {
        let d = x.wrapping_sub(self.last_in);
        self.last_in = x;
        if self.n == 1 {
            self.out = x;
            return x;
        }
        // head < n ≤ MAX_TAPS (a power of two): the mask changes nothing and drops
        // the bounds check.
        let slot = &mut self.taps[self.head % MAX_TAPS];
        let old = *slot;
        *slot = d;
        self.head += 1;
        if self.head >= self.n {
            self.head = 0;
        }
        self.sum += d as i64 - old as i64;
        // Advance by sum/N, carrying the remainder exactly.
        let acc = self.rem + self.sum;
        // The hardware divider handles 32 bits; 64-bit division only for huge input.
        let q = match i32::try_from(acc) {
            Ok(a) => a.div_euclid(self.n as i32) as i64,
            Err(_) => acc.div_euclid(self.n as i64),
        };
        self.rem = acc - q * self.n as i64;
        self.out = self.out.wrapping_add(q as i32);
        self.out
    }

    /// Last output.
    pub fn output(&self) -> i32 {
        self.out
    }

    /// True while the window still holds motion (output not yet at the input).
    pub fn busy(&self) -> bool {
        self.sum != 0 || self.rem != 0 || self.out != self.last_in
    }
}

/// Open-loop configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpenLoopConfig {
    /// Command pulses per motor revolution (200..=51200 typical).
    pub pulses_per_rev: u32,
    /// Step period, s.
    pub ts: f32,
    /// Running current (peak vector magnitude), A.
    pub running_current: f32,
    /// Holding current, % of the running current (0..=100).
    pub holding_percent: u8,
    /// Stand-still time before holding current, s.
    pub standby: f32,
    /// Soft-start ramp after enable, s (0 = immediate).
    pub soft_start: f32,
    /// Command smoothing time constant (moving-average length), s (0 = off).
    pub filter_time: f32,
}

/// What the current loop should do this step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OpenLoopOutput {
    /// Electrical angle of the current vector.
    pub angle: Angle,
    /// Current magnitude on that angle (i_d*), A.
    pub current: f32,
    /// Commanded electrical velocity, rad/s (for the back-EMF feed-forward).
    pub omega_e: f32,
    /// Filtered command position, pulses.
    pub position: i32,
    /// The holding current is active.
    pub holding: bool,
}

/// Open-loop microstepping state.
#[derive(Clone, Debug)]
// In declaration order, the smoothing window last: the per-step fields stay within
// the short load/store offsets of Thumb-2 and the FPU (VLDR reaches 1020 bytes).
#[repr(C)]
pub struct OpenLoop {
    cfg: OpenLoopConfig,
    scale: CountScale,
    still_steps: u32,
    standby_steps: u32,
    current: f32,
    soft_rate: f32,
    hold_rate: f32,
    rad_per_pulse_e: f32,
    angle_offset: Angle,
    derate: f32,
    soft_starting: bool,
    enabled: bool,
    filter: MovingAverage,
}

impl OpenLoop {
    /// New (disabled) open loop at command position `start`. Out-of-range values are
    /// clamped (ppr ≥ 1, currents ≥ 0, percent ≤ 100, times ≥ 0).
    pub fn new(cfg: OpenLoopConfig, start: i32) -> Self {
        let mut o = OpenLoop {
            cfg,
            scale: CountScale::new(1, POLE_PAIRS),
            filter: MovingAverage::new(1, start),
            still_steps: 0,
            standby_steps: 0,
            current: 0.0,
            soft_rate: 0.0,
            hold_rate: 0.0,
            soft_starting: false,
            enabled: false,
            rad_per_pulse_e: 0.0,
            angle_offset: Angle::ZERO,
            derate: 1.0,
        };
        o.reconfigure(cfg, start);
        o
    }

    /// Starts over with a new configuration, in place: the same state as
    /// `new(cfg, start)` (disabled, no angle offset), without building a whole
    /// `OpenLoop` — with its smoothing window — on the stack.
    pub fn reconfigure(&mut self, cfg: OpenLoopConfig, start: i32) {
        let mut cfg = cfg;
        cfg.pulses_per_rev = cfg.pulses_per_rev.max(1);
        cfg.holding_percent = cfg.holding_percent.min(100);
        let pos = |x: f32| if x.is_finite() { x.max(0.0) } else { 0.0 };
        cfg.running_current = pos(cfg.running_current);
        cfg.standby = pos(cfg.standby);
        cfg.soft_start = pos(cfg.soft_start);
        cfg.filter_time = pos(cfg.filter_time);
        cfg.ts = if cfg.ts.is_finite() && cfg.ts > 0.0 {
            cfg.ts
        } else {
            1e-4
        };
        let taps = (cfg.filter_time / cfg.ts + 0.5) as usize;
        let per = |t: f32| cfg.running_current * cfg.ts / t.max(cfg.ts);
        self.cfg = cfg;
        self.scale = CountScale::new(cfg.pulses_per_rev, POLE_PAIRS);
        self.filter.reinit(taps, start);
        self.still_steps = 0;
        self.standby_steps = (cfg.standby / cfg.ts + 0.5) as u32;
        self.current = 0.0;
        self.soft_rate = per(cfg.soft_start);
        self.hold_rate = per(HOLD_RAMP);
        self.soft_starting = false;
        self.enabled = false;
        self.rad_per_pulse_e = 2.0 * PI * POLE_PAIRS as f32 / cfg.pulses_per_rev as f32;
        self.angle_offset = Angle::ZERO;
        self.derate = 1.0;
    }

    /// Configuration in use.
    pub fn config(&self) -> &OpenLoopConfig {
        &self.cfg
    }

    /// Electrical angle added to the command angle (set it so that the command
    /// position maps onto the rotor's present angle, e.g. after closed loop).
    pub fn set_angle_offset(&mut self, offset: Angle) {
        self.angle_offset = offset;
    }

    /// Starts driving (soft start from zero current) at command position `pos`.
    pub fn enable(&mut self, pos: i32) {
        self.filter.reset(pos);
        self.current = 0.0;
        self.still_steps = 0;
        self.soft_starting = true;
        self.enabled = true;
    }

    /// Stops driving (current 0).
    pub fn disable(&mut self) {
        self.enabled = false;
        self.current = 0.0;
    }

    /// Electrical angle of a (filtered) command position.
    #[inline]
    pub fn angle_of(&self, pos: i32) -> Angle {
        // Equal to `rem_euclid` for every divisor but 0 (impossible: clamped to ≥ 1) and
        // for the one overflow (pulses_per_rev = u32::MAX at i32::MIN, whose exact
        // remainder is 0): neither panics.
        let n = pos
            .checked_rem_euclid(self.cfg.pulses_per_rev as i32)
            .unwrap_or(0) as u32;
        self.scale.angle(n).wrapping_add(self.angle_offset)
    }

    /// Voltage-headroom management: call once per step with the current loop's
    /// "voltage vector limited" flag. While the loop is voltage-limited (at speed the
    /// back-EMF and `ωe·L·i` leave no headroom) the current reference is reduced by
    /// [`DERATE_DOWN`] per step, down to [`DERATE_MIN`] of the set value; without
    /// limiting it recovers by [`DERATE_UP`] per step. A saturated current loop with
    /// a too-large d-current (the rotor lags the vector) delivers less torque than a
    /// smaller current it can actually impose, so this keeps the motor in step at
    /// speeds where the set current is not reachable. Returns the present factor.
    pub fn voltage_limited(&mut self, limited: bool) -> f32 {
        self.derate = if limited {
            crate::num::clamp(self.derate - DERATE_DOWN, DERATE_MIN, 1.0)
        } else {
            crate::num::clamp(self.derate + DERATE_UP, DERATE_MIN, 1.0)
        };
        self.derate
    }

    /// One step with the raw command position (pulses).
    #[inline]
    pub fn step(&mut self, command: i32) -> OpenLoopOutput {
        let prev = self.filter.output();
        let pos = self.filter.step(command);
        let moved = pos.wrapping_sub(prev);
        if moved != 0 {
            self.still_steps = 0;
        } else {
            self.still_steps = self.still_steps.saturating_add(1);
            if self.still_steps > 10 {
                // No speed, no back-EMF: the full current is available again.
                self.derate = 1.0;
            }
        }
        let holding = self.still_steps >= self.standby_steps;
        let run = self.cfg.running_current;
        let target = if !self.enabled {
            0.0
        } else if holding {
            run * self.cfg.holding_percent as f32 * 0.01
        } else {
            run
        };
        if self.soft_starting {
            let up = self.current + self.soft_rate;
            self.current = if up < target { up } else { target };
            if self.current >= target {
                self.soft_starting = false;
            }
        } else if target >= self.current {
            self.current = target;
        } else {
            let down = self.current - self.hold_rate;
            self.current = if down > target { down } else { target };
        }
        OpenLoopOutput {
            angle: self.angle_of(pos),
            current: self.current * self.derate,
            omega_e: moved as f32 * self.rad_per_pulse_e / self.cfg.ts,
            position: pos,
            holding,
        }
    }
}
