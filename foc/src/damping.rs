//! Anti-resonance damping of open-loop (microstepping) operation.
//!
//! # Why an open-loop stepper rings
//! In open loop the current vector of magnitude `I` sits on the command angle θc
//! and the rotor follows at a load angle `δ = θc − θr` (electrical). The torque
//! `T = Kt·I·sin δ` is a spring of stiffness `k = p·Kt·I` N·m/rad (mechanical, `p`
//! = 50 pole pairs) on the rotor inertia `J`: natural frequency
//! `ωn = √(k/J)` (about 190 Hz for a NEMA 23 at rated current). The current loop
//! imposes the current against the back-EMF, which would otherwise damp the rotor,
//! so the only damping left is the viscous friction `B`: `ζ = B/(2·√(k·J))`, a few
//! tenths of a percent. The detent torque (`Td·sin 4θe`, at `4·p·n` Hz at `n` rev/s)
//! excites the spring at about 1 rev/s; near the voltage limit, where the current
//! lags, the rotor-current interaction turns the damping negative (mid-band
//! instability, 9-14 rev/s on a NEMA 34 at 48 V). `tests-host`'s resonance sweep
//! (BENCHMARKS.md, "Open-loop resonance") shows both.
//!
//! # The damping term
//! The rotor speed is estimated from what the current loop already has, and the
//! command angle is advanced by the speed error:
//!
//! `θout = θc + Kd·(ωc − ω̂r)` (electrical rad, `Kd` in s)
//!
//! so the effective load angle is `δ + Kd·δ̇` and the torque gains the term
//! `k·Kd·δ̇`: a damper of `c = k·Kd` N·m·s/rad. `Kd = 2ζ/ωn` gives the damping ratio
//! ζ; [`DEFAULT_GAIN`] (1 ms) gives ζ ≈ 0.6 on the rotor alone and ≈ 0.25 with five
//! times the rotor's inertia on the shaft.
//!
//! # Speed from the current loop (back-EMF magnitude)
//! Each phase obeys `v = R·i + L·di/dt + e`, and the two phases' back-EMFs form a
//! vector of magnitude `|e| = Ke·|ωr|` (mechanical speed, `Ke` V·s/rad) whatever the
//! rotor angle. Over one update period `T` (the open-loop step, [`Damping::update`])
//! the mean back-EMF is, per phase,
//!
//! `ē = v̄ − R·(i₀ + i₁)/2 − L·(i₁ − i₀)/T`
//!
//! with `v̄` the mean of the voltages the bridges applied over the period (collected
//! by [`Damping::tick`] after each current-loop step, `delay_ticks` steps late: the
//! PWM applies a step's voltage from the next update event on) and `i₀`, `i₁` the
//! phase currents measured at its start and end. The `L·di/dt` term matters: the
//! correction itself moves the current vector, and without it the current loop's
//! answer would read as back-EMF (a fast loop of its own, unstable). The estimate is
//! in the stationary frame, so it needs no angle; the magnitude is filtered
//! (first order, `fc` Hz): `|ω̂r,e| = p·|ē|/Ke`. Its sign is the command's: the
//! estimate only matters while the rotor follows the command. Averaging a vector
//! that turns by `ωe·T` over the period shortens it by `sinc(ωe·T/2)`, under 2 % at
//! 20 rev/s and a 10 kHz update.
//!
//! # Numeric behaviour
//! At low speed `|ē|` is small against the dead-time and resistance errors (tenths
//! of a volt), so the term fades in linearly between `min_speed` and twice that
//! (electrical rad/s) and is zero below. The correction is clamped to
//! `±max_correction` rad (electrical): a stalled rotor (ω̂r = 0) gets at most that
//! advance, never a runaway angle. All `f32`; one `vsqrt` per update; [`Damping::tick`]
//! is a copy and two additions.

use crate::angle::Angle;
use crate::num;
use crate::transforms::AlphaBeta;
use core::f32::consts::PI;

/// Default damping gain `Kd`, s.
pub const DEFAULT_GAIN: f32 = 1.0e-3;
/// Default cut-off of the back-EMF filter, Hz.
pub const DEFAULT_CUTOFF_HZ: f32 = 1000.0;
/// Default lower speed of the fade-in, electrical rad/s (0.25 rev/s at 50 pole pairs).
pub const DEFAULT_MIN_SPEED: f32 = 2.0 * PI * 50.0 * 0.25;
/// Default largest angle correction, electrical rad (30°).
pub const DEFAULT_MAX_CORRECTION: f32 = PI / 6.0;

/// Configuration of [`Damping`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DampingConfig {
    /// Update period, s (the open-loop step's: [`Damping::update`]'s period).
    pub ts: f32,
    /// Damping gain `Kd`, s (0 = off).
    pub gain: f32,
    /// Phase resistance, Ω.
    pub r: f32,
    /// Phase inductance, H.
    pub l: f32,
    /// Back-EMF constant, V·s/rad (mechanical).
    pub ke: f32,
    /// Cut-off of the back-EMF filter, Hz.
    pub cutoff_hz: f32,
    /// Speed below which the term is off, electrical rad/s (full above twice this).
    pub min_speed: f32,
    /// Largest correction, electrical rad.
    pub max_correction: f32,
    /// Current-loop steps from a step's voltage to the sampling interval it drives:
    /// `latency + 0.5` with the current loop's `latency` (sample to the middle of the
    /// PWM period that applies the voltage, [`crate::current_loop::CurrentLoopConfig`]),
    /// i.e. 1 + the update delay `D` (2 when the duties load one period after the
    /// sample). Fractions interpolate between steps; `0..=MAX_DELAY`. The estimate
    /// depends on it: one step off and the `L·di/dt` term no longer matches its
    /// voltage (the sweep loses steps with the plant's delay mis-stated by a step).
    pub delay_ticks: f32,
}

/// Largest [`DampingConfig::delay_ticks`].
pub const MAX_DELAY: usize = 3;

impl DampingConfig {
    /// The defaults above for a motor with `r`, `l`, `ke`, updated every `ts` s, with
    /// a current loop of `latency` samples (see [`DampingConfig::delay_ticks`]).
    pub fn new(ts: f32, r: f32, l: f32, ke: f32, latency: f32) -> Self {
        DampingConfig {
            ts,
            gain: DEFAULT_GAIN,
            r,
            l,
            ke,
            cutoff_hz: DEFAULT_CUTOFF_HZ,
            min_speed: DEFAULT_MIN_SPEED,
            max_correction: DEFAULT_MAX_CORRECTION,
            delay_ticks: latency + 0.5,
        }
    }
}

/// Rotor-speed estimate and angle correction, see the module docs.
#[derive(Clone, Debug)]
pub struct Damping {
    cfg: DampingConfig,
    /// Filter coefficient `1 − e^(−2π·fc·ts)`.
    alpha: f32,
    /// `p / Ke`: electrical rad/s per volt of back-EMF.
    per_volt: f32,
    /// Whole and fractional part of the delay.
    delay_whole: usize,
    delay_frac: f32,
    /// Voltages of the last current-loop steps, newest first.
    v_hist: [AlphaBeta; MAX_DELAY + 2],
    /// Sum of the applied voltages since the last update, and their number.
    v_sum: AlphaBeta,
    n: u32,
    /// Phase currents at the last update.
    i_prev: AlphaBeta,
    /// Filtered `|ω̂r,e|`.
    omega_r: f32,
    correction: f32,
    /// `i_prev` and the voltage history hold measurements (an update has run since the
    /// last reset).
    primed: bool,
}

impl Damping {
    /// A damper with nothing measured yet.
    pub fn new(cfg: DampingConfig) -> Self {
        let x = 2.0 * PI * cfg.cutoff_hz.max(0.0) * cfg.ts.max(0.0);
        // x/(1 + x/2 + x²/6) is 1 − e^(−x) to within 3 % for x ≤ 1 (no `exp` in
        // `no_std`): the cut-off is a few percent off, which does not matter here.
        let alpha = num::clamp(x / (1.0 + 0.5 * x + x * x / 6.0), 0.0, 1.0);
        let per_volt = if cfg.ke > 0.0 {
            crate::angle::POLE_PAIRS as f32 / cfg.ke
        } else {
            0.0
        };
        let delay = if cfg.delay_ticks.is_finite() {
            num::clamp(cfg.delay_ticks, 0.0, MAX_DELAY as f32)
        } else {
            0.0
        };
        let delay_whole = (delay as usize).min(MAX_DELAY);
        Damping {
            cfg,
            alpha,
            per_volt,
            delay_whole,
            delay_frac: delay - delay_whole as f32,
            v_hist: [AlphaBeta::default(); MAX_DELAY + 2],
            v_sum: AlphaBeta::default(),
            n: 0,
            i_prev: AlphaBeta::default(),
            omega_r: 0.0,
            correction: 0.0,
            primed: false,
        }
    }

    /// Configuration in use.
    pub fn config(&self) -> &DampingConfig {
        &self.cfg
    }

    /// Forgets the estimate (the bridges were off, or the frame was not the command
    /// angle): the next [`Damping::update`] only takes its currents as the start of a
    /// period. Cheap when there is nothing to forget.
    #[inline]
    pub fn reset(&mut self) {
        if self.primed {
            self.primed = false;
            self.omega_r = 0.0;
            self.correction = 0.0;
        }
    }

    /// Last rotor-speed estimate, electrical rad/s (its magnitude: the sign is the
    /// command's).
    pub fn rotor_speed(&self) -> f32 {
        self.omega_r
    }

    /// Last correction, electrical rad.
    pub fn correction(&self) -> f32 {
        self.correction
    }

    /// After each current-loop step: `v_ab`, the phase voltages it commanded (V).
    #[inline]
    pub fn tick(&mut self, v_ab: AlphaBeta) {
        // Shifted element by element: `copy_within` is a `memmove` call (the only one
        // in the board image, 1.5 KiB of flash) for these four moves.
        for k in (1..self.v_hist.len()).rev() {
            self.v_hist[k] = self.v_hist[k - 1];
        }
        self.v_hist[0] = v_ab;
        let (a, b) = (
            self.v_hist[self.delay_whole],
            self.v_hist[self.delay_whole + 1],
        );
        let f = self.delay_frac;
        self.v_sum.alpha += a.alpha + f * (b.alpha - a.alpha);
        self.v_sum.beta += a.beta + f * (b.beta - a.beta);
        self.n += 1;
    }

    /// Sets the damping gain `Kd` (s; negative or not finite: 0, off).
    pub fn set_gain(&mut self, gain: f32) {
        self.cfg.gain = if gain.is_finite() { gain.max(0.0) } else { 0.0 };
    }

    /// Sets the motor's resistance (Ω) and inductance (H), e.g. after an auto-tune.
    pub fn set_motor(&mut self, r: f32, l: f32) {
        if r.is_finite() && l.is_finite() {
            self.cfg.r = r.max(0.0);
            self.cfg.l = l.max(0.0);
        }
    }

    /// One update per open-loop step: `i_ab` the phase currents last measured (A),
    /// `omega_c` the commanded electrical speed (rad/s). Returns the angle to add to
    /// the command angle.
    pub fn update(&mut self, i_ab: AlphaBeta, omega_c: f32) -> Angle {
        let c = &self.cfg;
        let i0 = self.i_prev;
        self.i_prev = i_ab;
        let n = self.n;
        let sum = self.v_sum;
        self.v_sum = AlphaBeta::default();
        self.n = 0;
        if !self.primed || n == 0 {
            // The period's start, or no voltage since: nothing to estimate from yet; the
            // rotor is taken to follow the command.
            self.primed = true;
            self.omega_r = omega_c.abs();
            return Angle::from_radians(self.correction);
        }
        let inv_n = 1.0 / n as f32;
        let l_t = c.l / c.ts;
        let emf = |v: f32, i0: f32, i1: f32| v * inv_n - c.r * 0.5 * (i0 + i1) - l_t * (i1 - i0);
        let ea = emf(sum.alpha, i0.alpha, i_ab.alpha);
        let eb = emf(sum.beta, i0.beta, i_ab.beta);
        let mag = num::sqrtf(ea * ea + eb * eb) * self.per_volt;
        self.omega_r += self.alpha * (mag - self.omega_r);
        let speed = omega_c.abs();
        let fade = num::clamp((speed - c.min_speed) / c.min_speed.max(1e-3), 0.0, 1.0);
        let raw = c.gain * (speed - self.omega_r) * fade;
        // (`gain` = 0 switches it off: no correction, the estimate still runs.)
        let corr = num::clamp(raw, -c.max_correction, c.max_correction);
        self.correction = if omega_c < 0.0 { -corr } else { corr };
        Angle::from_radians(self.correction)
    }
}
