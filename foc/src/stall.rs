//! Sensorless stall detection in open loop: the back-EMF seen by the current loop.
//!
//! # Model
//! In open loop the current loop works in the frame of the command angle `θc`
//! (`i_d* = I`, `i_q* = 0`, [`crate::open_loop`]); the rotor's electrical angle is
//! `θr = θc − δ` (δ: load angle, positive when the rotor lags, torque `Kt·I·sin δ`).
//! The back-EMF vector of the rotor, `Ke·ω·(−sin θr, cos θr)` in the phases
//! (`ω` mechanical, rad/s), lies at `θr + 90°`; in the command frame it is
//!
//! ```text
//! E = (e_d, e_q) = Ke·ω·(sin δ, cos δ)
//! ```
//!
//! and the coil equations in that frame (rotating at the command's `ωc`, electrical)
//! leave it as the voltage residual
//!
//! ```text
//! e_d = v_d − R·i_d + ωc·L·i_q
//! e_q = v_q − R·i_q − ωc·L·i_d
//! ```
//!
//! (`L·di/dt` left out: zero in the steady state of the rotating frame, a transient of
//! the current loop's rise time, ≈ 0.2 ms, otherwise). `v_dq` is the current loop's
//! last commanded voltage (after the circle limit; the latency advance makes it act
//! in the command frame), `i_dq` its last measurement ([`crate::current_loop`]).
//!
//! # Decision
//! In step, `ω = ωc/50` and `|δ| < 90°`: the in-phase part of the back-EMF against
//! the expected one,
//!
//! ```text
//! s = e_q / (Ke·ωc/50) = (ω/ωc·50)·cos δ
//! ```
//!
//! is `cos δ` (1 unloaded, 0 at the pull-out load angle of 90°). When the rotor loses
//! synchronism it stops or oscillates about a pole while the field turns on: `E`
//! collapses or spins in the command frame and `s` falls to about 0 on average. The
//! drive trips when `s` stays below the threshold (the sensitivity, 0x2061: a higher
//! value trips at a smaller load angle, `δ = acos(threshold)` for a rotor still in
//! step) for a quarter of an electrical turn of the command ([`CONFIRM_RAD`]). The
//! confirmation is this short so that the stall is known before the load angle of a
//! blocked rotor passes 180°, beyond which the field pulls the rotor back (a stall
//! homing that stops the field then still finds the rotor at the stop).
//!
//! # Filters and rates
//! [`StallDetector::step`] runs at the servo rate (10 kHz), outside the current loop's
//! step, on the values the loop keeps. `e_d`, `e_q` and the expected `Ke·ωc/50` pass
//! the same first-order low-pass, `y += α·(x − y)`, whose time constant is half an
//! electrical radian of the command ([`FILTER_RAD`]), `α = min(2·|ω̄c|·Ts, ½)` (ω̄c:
//! the command speed through a 1 ms low-pass, [`SPEED_TAU`], which also smooths the
//! pulse quantisation of the command). So the detection takes about the same part of
//! an electrical period at every speed: the filtered `s` falls to the default
//! threshold 0.3 about `0.5·ln(1/0.3)` = 0.6 rad after the rotor stops, the
//! confirmation adds π/2: ≈ 0.35 electrical periods, plus the current loop's
//! settling; the detent ripple at `4·ωc` is attenuated to 45 %.
//! Filtering the expected value with the same filter takes the filter's lag out of
//! the ratio during acceleration.
//!
//! Below [`MIN_SPEED_E`] (1 rev/s) the detection is inactive: there `Ke·ω` is of the
//! order of the errors of the model (R off by 20 % with the winding's temperature is
//! `0.2·R·I`, 0.4 V on the ECN57-20 at 5 A, against `Ke·ω` = 1.8 V at 1 rev/s; the
//! dead-time loss left by its compensation). An error `ΔL` of the inductance shifts
//! `s` by `50·ΔL·I/Ke` at every speed (0.16 for 10 % on the ECN57-20 at 5 A): the
//! tuned L (auto-tune) matters.
//!
//! # Numeric behaviour
//! `f32`, no division in [`StallDetector::step`] (the ratio is compared as
//! `e_q·sgn(ωc) < threshold·|Ke·ωc/50|`), ≈ 30 FPU operations at the servo rate; the
//! inputs are the means of the current loop's `v_dq`, `i_dq` over the servo period
//! (the open-loop angle steps once per servo period: a single current-loop period's
//! voltage carries the loop's response to that step, not the motor's steady
//! voltage); their sums cost four additions per current-loop period outside
//! `CurrentLoop::step`. The load angle
//! ([`StallDetector::load_angle`]) takes one `atan2f` and is meant for the
//! monitoring rate. Non-finite inputs leave the state unchanged.

use crate::num;
use crate::transforms::Dq;
use core::f32::consts::PI;

/// Command speed below which the detection is inactive, electrical rad/s (1 rev/s).
pub const MIN_SPEED_E: f32 = 2.0 * PI * crate::angle::POLE_PAIRS as f32;
/// Electrical angle the command turns while `s` stays below the threshold before the
/// stall is declared, rad (a quarter of an electrical period).
pub const CONFIRM_RAD: f32 = 0.5 * PI;
/// Time constant of the command-speed filter, s.
pub const SPEED_TAU: f32 = 1e-3;
/// Time constant of the back-EMF filter, electrical radians of the command.
pub const FILTER_RAD: f32 = 0.5;
/// Largest filter weight per step.
const ALPHA_MAX: f32 = 0.5;

/// Motor constants and settings of the detector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StallConfig {
    /// Step period of [`StallDetector::step`], s.
    pub ts: f32,
    /// Phase resistance, Ω.
    pub r: f32,
    /// Phase inductance, H.
    pub l: f32,
    /// Back-EMF constant, V·s/rad (mechanical), peak per phase.
    pub ke: f32,
    /// Trip when `s` stays below this (0..1; the sensitivity).
    pub threshold: f32,
}

/// The detector's verdict of a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StallState {
    /// Below [`MIN_SPEED_E`] (or never stepped): no judgement.
    Inactive,
    /// The rotor follows the command.
    InStep,
    /// `s` below the threshold, not yet for [`CONFIRM_RAD`].
    Suspect,
    /// Loss of synchronism confirmed (sticky until [`StallDetector::reset`]).
    Stalled,
}

/// Back-EMF stall detector (module docs).
#[derive(Clone, Debug)]
pub struct StallDetector {
    cfg: StallConfig,
    ke_e: f32,
    speed_k: f32,
    omega_f: f32,
    ed: f32,
    eq: f32,
    expected: f32,
    below: f32,
    /// Command angle turned in step since the last suspect verdict, rad.
    steady: f32,
    onset: bool,
    state: StallState,
}

impl StallDetector {
    /// A detector in the state of [`StallDetector::reset`]. Non-finite or negative
    /// constants are taken as 0; the threshold is clamped to 0..1.
    pub fn new(cfg: StallConfig) -> Self {
        let mut d = StallDetector {
            cfg,
            ke_e: 0.0,
            speed_k: 0.0,
            omega_f: 0.0,
            ed: 0.0,
            eq: 0.0,
            expected: 0.0,
            below: 0.0,
            steady: 0.0,
            onset: false,
            state: StallState::Inactive,
        };
        d.configure(cfg);
        d
    }

    /// New constants and threshold; the filters keep their state.
    pub fn configure(&mut self, cfg: StallConfig) {
        let pos = |x: f32| if x.is_finite() { num::pos(x) } else { 0.0 };
        let ts = if cfg.ts.is_finite() && cfg.ts > 0.0 {
            cfg.ts
        } else {
            1e-4
        };
        self.cfg = StallConfig {
            ts,
            r: pos(cfg.r),
            l: pos(cfg.l),
            ke: pos(cfg.ke),
            threshold: num::clamp(pos(cfg.threshold), 0.0, 1.0),
        };
        self.ke_e = self.cfg.ke * (1.0 / crate::angle::POLE_PAIRS as f32);
        self.speed_k = ts / (SPEED_TAU + ts);
    }

    /// Configuration in use.
    pub fn config(&self) -> &StallConfig {
        &self.cfg
    }

    /// Forgets everything (use at enable and after a fault reset).
    pub fn reset(&mut self) {
        self.omega_f = 0.0;
        self.ed = 0.0;
        self.eq = 0.0;
        self.expected = 0.0;
        self.below = 0.0;
        self.steady = 0.0;
        self.onset = false;
        self.state = StallState::Inactive;
    }

    /// One step with the current loop's last voltages `v` and currents `i` (command
    /// frame, V and A) and the command's electrical speed `omega_e` (rad/s).
    pub fn step(&mut self, v: Dq, i: Dq, omega_e: f32) -> StallState {
        let finite = v.d.is_finite()
            && v.q.is_finite()
            && i.d.is_finite()
            && i.q.is_finite()
            && omega_e.is_finite();
        if !finite {
            return self.state;
        }
        self.omega_f += self.speed_k * (omega_e - self.omega_f);
        let w = self.omega_f.abs();
        let a = num::clamp(w * self.cfg.ts * (1.0 / FILTER_RAD), 0.0, ALPHA_MAX);
        let wl = omega_e * self.cfg.l;
        let ed = v.d - self.cfg.r * i.d + wl * i.q;
        let eq = v.q - self.cfg.r * i.q - wl * i.d;
        self.ed += a * (ed - self.ed);
        self.eq += a * (eq - self.eq);
        self.expected += a * (self.ke_e * omega_e - self.expected);
        self.onset = false;
        if self.state == StallState::Stalled {
            return self.state;
        }
        if w < MIN_SPEED_E {
            self.below = 0.0;
            self.steady = 0.0;
            self.state = StallState::Inactive;
            return self.state;
        }
        let sign = if self.expected < 0.0 { -1.0 } else { 1.0 };
        if self.eq * sign < self.cfg.threshold * self.expected.abs() {
            self.onset = self.steady >= CONFIRM_RAD;
            self.steady = 0.0;
            self.below += w * self.cfg.ts;
            self.state = if self.below >= CONFIRM_RAD {
                StallState::Stalled
            } else {
                StallState::Suspect
            };
        } else {
            self.below = 0.0;
            self.steady += w * self.cfg.ts;
            self.state = StallState::InStep;
        }
        self.state
    }

    /// True in the step where `s` fell below the threshold after at least
    /// [`CONFIRM_RAD`] in step: the command position of this step is where the rotor
    /// met the obstacle (a short recovery while it bounces there does not move it).
    pub fn onset(&self) -> bool {
        self.onset
    }

    /// The last verdict.
    pub fn state(&self) -> StallState {
        self.state
    }

    /// Filtered back-EMF in the command frame, V.
    pub fn back_emf(&self) -> Dq {
        Dq {
            d: self.ed,
            q: self.eq,
        }
    }

    /// `s`: the in-phase back-EMF over the expected one (1 unloaded, ≈ 0 stalled; 0
    /// while the expected value is below 1 mV).
    pub fn ratio(&self) -> f32 {
        if self.expected.abs() < 1e-3 {
            0.0
        } else {
            self.eq / self.expected
        }
    }

    /// Estimated load angle in the direction of motion, rad (−π..π; positive: the
    /// rotor lags the command): `δ = atan2(e_d·σ, e_q·σ)` with `σ = sgn ωc` is the
    /// angle of `θc − θr`, `σ·δ` its lag along the motion.
    pub fn load_angle(&self) -> f32 {
        let sign = if self.expected < 0.0 { -1.0 } else { 1.0 };
        sign * libm::atan2f(self.ed * sign, self.eq * sign)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CFG: StallConfig = StallConfig {
        ts: 1e-4,
        r: 0.4,
        l: 1.8e-3,
        ke: 0.283,
        threshold: 0.5,
    };

    /// Steady-state voltages of the model with rotor speed `w_r` (mechanical) and
    /// load angle `delta`, command speed `w_c` (electrical), current `i` on d.
    fn voltages(w_c: f32, w_r: f32, delta: f32, i: f32) -> (Dq, Dq) {
        let e = CFG.ke * w_r;
        let v = Dq {
            d: CFG.r * i + e * libm::sinf(delta),
            q: w_c * CFG.l * i + e * libm::cosf(delta),
        };
        (v, Dq { d: i, q: 0.0 })
    }

    fn run(d: &mut StallDetector, w_c: f32, w_r: f32, delta: f32, steps: u32) -> StallState {
        let (v, i) = voltages(w_c, w_r, delta, 5.0);
        let mut s = d.state();
        for _ in 0..steps {
            s = d.step(v, i, w_c);
        }
        s
    }

    #[test]
    fn in_step_gives_cos_delta_and_the_load_angle() {
        for (rev_s, delta) in [(2.0f32, 0.3f32), (10.0, 1.0), (-5.0, -0.6)] {
            let w_c = rev_s * 2.0 * PI * 50.0;
            let mut d = StallDetector::new(CFG);
            assert_eq!(
                run(&mut d, w_c, w_c / 50.0, delta, 2000),
                StallState::InStep
            );
            assert!(
                (d.ratio() - libm::cosf(delta)).abs() < 1e-3,
                "{}",
                d.ratio()
            );
            // In reverse a lagging rotor is at θc − δ with δ < 0: lag |δ| along the
            // motion.
            assert!(
                (d.load_angle() - delta.abs()).abs() < 1e-3,
                "{}",
                d.load_angle()
            );
        }
    }

    #[test]
    fn stopped_rotor_trips_within_an_electrical_period() {
        for rev_s in [2.0f32, 5.0, 10.0, -10.0] {
            let w_c = rev_s * 2.0 * PI * 50.0;
            let mut d = StallDetector::new(CFG);
            run(&mut d, w_c, w_c / 50.0, 0.2, 2000);
            let period = 1.0 / (rev_s.abs() * 50.0);
            let mut n = 0;
            while run(&mut d, w_c, 0.0, 0.0, 1) != StallState::Stalled {
                n += 1;
                assert!(n < 100_000);
            }
            let t = n as f32 * CFG.ts;
            assert!(t > 0.2 * period && t < 0.6 * period, "{rev_s}: {t} s");
        }
    }

    #[test]
    fn threshold_is_the_load_angle_of_the_trip() {
        let w_c = 5.0 * 2.0 * PI * 50.0;
        let mut d = StallDetector::new(CFG);
        // cos 55° = 0.57 > 0.5: in step; cos 65° = 0.42: tripped.
        assert_eq!(
            run(&mut d, w_c, w_c / 50.0, 55f32.to_radians(), 5000),
            StallState::InStep
        );
        assert_eq!(
            run(&mut d, w_c, w_c / 50.0, 65f32.to_radians(), 5000),
            StallState::Stalled
        );
        assert_eq!(run(&mut d, w_c, w_c / 50.0, 0.0, 5000), StallState::Stalled);
        d.reset();
        assert_eq!(run(&mut d, w_c, w_c / 50.0, 0.0, 5000), StallState::InStep);
    }

    #[test]
    fn inactive_below_the_minimum_speed_and_robust_to_bad_input() {
        let w_c = 0.8 * MIN_SPEED_E;
        let mut d = StallDetector::new(CFG);
        assert_eq!(run(&mut d, w_c, 0.0, 0.0, 20_000), StallState::Inactive);
        let nan = Dq {
            d: f32::NAN,
            q: 0.0,
        };
        assert_eq!(d.step(nan, nan, 1000.0), StallState::Inactive);
        assert_eq!(
            d.step(Dq::default(), Dq::default(), f32::INFINITY),
            StallState::Inactive
        );
        let mut bad = StallDetector::new(StallConfig {
            ts: -1.0,
            r: f32::NAN,
            l: -1.0,
            ke: f32::INFINITY,
            threshold: 7.0,
        });
        let c = *bad.config();
        assert_eq!(
            (c.ts, c.r, c.l, c.ke, c.threshold),
            (1e-4, 0.0, 0.0, 0.0, 1.0)
        );
        assert!(bad.step(Dq::default(), Dq::default(), 3000.0) != StallState::Stalled);
        assert!(bad.ratio().is_finite() && bad.load_angle().is_finite());
    }
}
