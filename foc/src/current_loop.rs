//! Field-oriented current loop for the two-phase machine.
//!
//! One [`CurrentLoop::step`] per PWM period (40 kHz nominal): raw ADC counts in, four
//! compare values out.
//!
//! ```text
//! i_X = (raw − offset_X)·A_per_count·g_X     V_bus = raw·V_per_count
//! (i_d, i_q) = Park(i_A, i_B, θe)
//! v_d = PI_d(i_d* − i_d) − ωe·L·i_q                  (decoupling feed-forward)
//! v_q = PI_q(i_q* − i_q) + ωe·L·i_d + Ke·ωe/50       (+ back-EMF feed-forward)
//!                     (i_d, i_q: measured, or the references i_d*, i_q*)
//! |v| ≤ m_max·V_bus                                  (circle, anti-windup)
//! (v_A, v_B) = Park⁻¹(v_d, v_q, θe + 1.5·ωe·Ts)      (latency compensation)
//! v_X += V_dt·clamp(i_X/I_dt, −1, 1)                 (dead-time compensation)
//! duties = ½ ± v/(2·V_bus)                           (two H-bridges)
//! ```
//!
//! The decoupling uses the *measured* currents on the encoder's angle, the
//! references on a commanded angle (module section "Decoupling").
//! Latency: the voltage computed from the sample at `t` is applied from `t + Ts` to
//! `t + 2Ts` (one period of computation delay, PWM shadow registers), so on average
//! it acts `1.5·Ts` later; the inverse Park angle is advanced by `ωe·1.5·Ts`
//! ([`CurrentLoopConfig::latency`]) with [`rotate_small2`] instead of a second
//! sin/cos.
//!
//! # Design: robust to the inductance and to the delay
//! With `Kp = L̂·ωc`, `Ki = R̂·ωc` the PI zero cancels the coil pole and, without
//! delay, the loop is `ωc/(s + ωc)`. Two things move it on a real drive:
//! * **the inductance**: a hybrid stepper's incremental inductance falls with the
//!   current (typically 25-30 % at rated current), and the tune measures it at one
//!   current. With `L = 0.7·L̂` the loop gain is 1.43 times the design's.
//! * **the delay** `D` from the sample to the update event that loads the duties:
//!   on the board 0.5 sample when the current-loop interrupt ends before the PWM
//!   underflow (sample at the counter peak, `ADC1_2` at +2.3 µs, underflow at
//!   +12.5 µs; the loaded duties then form the pulse centred on the next sample),
//!   1.0 when the interrupt ends after it (the duties load at the next peak). The
//!   design takes the worse, `D = 1`.
//!
//! Simulating the loop `i[k+1] = e^{−RTs/L}·i[k] + …` with the duties acting from
//! `k + D` (ECN57-20; overshoot of a step, % — the TC86-45 gives the same within
//! 0.5 %, the figures depend on `ωc·Ts` and `L̂/L` only):
//!
//! | `ωc·Ts` | D = 1: L × 0.7 / 1.0 / 1.3 | D = 1.5, L × 1 | D = 1.5, L × 0.7 | −3 dB, D = 1 |
//! |---|---|---|---|---|
//! | 0.314 (`2π·f_s/20`) | 18.3 / 2.1 / 0.5 | 14.0 | 38.2 | 4.5 kHz |
//! | 0.24 | 4.2 / 0.0 / 0.6 | 3.1 | 18.6 | 2.7 kHz |
//! | 0.22 | 1.5 / 0.0 / 0.6 | 1.2 | 13.2 | 2.3 kHz |
//!
//! The drive uses `ωc = 0.23/Ts` ([`ROBUST_WC_TS`], 9.2·10³ rad/s at 40 kHz), between
//! the last two rows: ≤ 5 % overshoot from 0.7 to 1.3 × the tuned L and with 1.5
//! samples of delay, a 10-90 % rise of ≈ 170 µs and a bandwidth above 2 kHz (the
//! figures on the plant, with its ADC noise and quantisation, are in BENCHMARKS.md:
//! "Control quality" and "Robustness"). The gains are **not scheduled** on |i|:
//! the margin the delay needs already covers the L(i) drop to rated current, and a
//! schedule would add work to every step and depend on the fit of L(i). A Smith
//! predictor of the delay (tried: `i + Σ` of the voltages not yet applied) bought
//! no more than this lower gain: 0.0 / 0.4 % instead of 1.5 / 1.2 %, 14 % combined.
//! [`CurrentLoopConfig::gains_for`] computes the gains, [`robust_bandwidth`] ωc.
//!
//! # Decoupling
//! In the rotor frame the motor is `L·di_d/dt = v_d − R·i_d + ωe·L·i_q` and
//! `L·di_q/dt = v_q − R·i_q − ωe·L·i_d − Ke·ωe/50`. Subtracting `ωe·L̂` times the
//! measured currents leaves two independent `R`-`L` axes; with the references
//! instead, the motor's own `ωe·L` still couples the current *errors*: at 10 rev/s
//! (500 Hz electrical) `ωe·L` is 9.4 Ω on the TC86-45 (5.7 Ω on the ECN57-20)
//! against `R` = 0.33 Ω. The commutation angle's error `δ` (quantisation of the
//! count, `foc::encoder`) turns the back-EMF (33 V at 10 rev/s on the TC86-45) by
//! `δ` into a d-axis voltage error `E·δ`, the d current the PI leaves of it
//! (`E·δ/|Kp + Ki/jω + jωL|` ≈ 40 mA for `δ` = 0.5 count at 30 Hz) then drove
//! `ωe·L·i_d` into the q axis: on the plant 26-31 mA of i_q ripple at 10.013 rev/s
//! with the references, 8-12 mA with the measured currents (same commutation
//! tracker). The price is the ADC noise times `ωe·L`: 1 LSB (4.9 mA) gives 46 mV at
//! 10 rev/s, a third of what the proportional term already passes (`Kp` × 1 LSB =
//! 135 mV). The measured currents are the sample's, used with the voltage that acts
//! 1.5 samples later: a phase error of `1.5·ωe·Ts` (0.12 rad at 500 Hz electrical)
//! in the cancelled term, i.e. 12 % of the coupling is left at 10 rev/s.
//!
//! **Where the angle error goes: i_d.** The back-EMF error `E·δ` is a d-axis
//! voltage whatever the decoupling does; the decoupling only decides whether the
//! d current it drives also reaches q. With the measured currents it does not, so
//! near the speeds where the count pattern beats slowly against the sampling
//! (10.013 rev/s, 1 count per sample) i_d carries it: 57 mA p-p on the ECN57-20 and
//! 70 mA on the TC86-45 on the plant after the tune, against 5-7 mA of i_q
//! (BENCHMARKS.md, "Robustness"). This is the intended place: i_d makes no torque
//! (the torque is `Kt·i_q`; a hybrid stepper's d and q inductances are nearly equal,
//! so i_d adds next to no reluctance torque), the copper loss of 60 mA p-p on a 0.5 A reference is
//! 1 % of it, and the alternative, decoupling on the references, puts 26-31 mA of
//! it back into i_q and the torque. Only a better angle would shrink it (a finer
//! encoder: `δ` is half a count).
//!
//! On a **commanded** angle (open loop, alignment) the decoupling stays on the
//! references ([`CurrentLoop::set_measured_decoupling`], off by default): there
//! the rotor lags the frame by its load angle, the coupling of the current errors
//! is part of the electrical damping of the rotor's resonance that
//! `crate::damping` builds on, and on the plant the measured decoupling took the
//! damped open-loop speed ripple from 1-5 % to 15-27 % of the speed above 3 rev/s.
//!
//! # Dead-time compensation
//! The bridge loses `V_dt·sgn(i)` of each phase voltage to its dead time (during it
//! the current's own direction decides which diode conducts). The step adds it back
//! by the sign of the **measured** phase current, through a linear band `±I_dt`
//! ([`CurrentLoop::set_dead_time`]) so the correction is continuous at the zero
//! crossing, where the ripple current makes the loss itself a ramp. `V_dt` is
//! stated as a fraction of the bus voltage (the loss is `Vbus·t_dead·f_pwm` per
//! leg pair, less the switching times); the auto-tune measures it
//! ([`crate::autotune::TuneResult::dead_time_v`]).
//!
//! Cost on a Cortex-M4F: 319 executed instructions per step (QEMU instruction count,
//! `current loop step` benchmark, unsaturated path; the voltage limit adds ~25 when
//! active), of which about 29 are the dead-time compensation and the channel gains
//! (each channel's gain is folded into its amperes per count, [`CurrentLoop::set_channel_gains`]):
//! over the 300 of the budget, for the ripple they remove (BENCHMARKS.md). Everything is `f32` on the FPU; no library calls, one division (by V_bus).

use crate::angle::Angle;
use crate::modulation::{limit_circle, Duties, Modulator};
use crate::num;
use crate::pi::Pi;
use crate::transforms::{inverse_park, park, rotate_small2, AlphaBeta, Dq};
use crate::trig;

/// Default current band of the dead-time compensation, A (the plant's and a typical
/// bridge's: the PWM ripple current at which the loss has fully changed sign).
pub const DEAD_TIME_BAND: f32 = 0.05;

/// One set of ADC conversions taken at the PWM centre (raw 12-bit counts).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AdcSample {
    /// Phase A current channel.
    pub ia: u16,
    /// Phase B current channel.
    pub ib: u16,
    /// DC bus voltage channel.
    pub vbus: u16,
}

/// ADC scaling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sense {
    /// Amperes per count of the phase current channels (sign included).
    pub amps_per_count: f32,
    /// Zero-current offset of phase A (counts, calibrated at start-up).
    pub offset_a: f32,
    /// Zero-current offset of phase B (counts).
    pub offset_b: f32,
    /// Volts per count of the bus voltage channel.
    pub volts_per_count: f32,
}

impl Sense {
    /// Phase currents (A) of a sample.
    #[inline]
    pub fn currents(&self, s: &AdcSample) -> AlphaBeta {
        AlphaBeta {
            alpha: (s.ia as f32 - self.offset_a) * self.amps_per_count,
            beta: (s.ib as f32 - self.offset_b) * self.amps_per_count,
        }
    }

    /// Bus voltage (V) of a sample.
    #[inline]
    pub fn vbus(&self, s: &AdcSample) -> f32 {
        s.vbus as f32 * self.volts_per_count
    }
}

/// `ωc·Ts` of the robust design (module doc).
pub const ROBUST_WC_TS: f32 = 0.23;

/// Current-loop bandwidth ωc (rad/s) of the robust design for sample period `ts`.
pub fn robust_bandwidth(ts: f32) -> f32 {
    ROBUST_WC_TS / ts
}

/// Static configuration of the current loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurrentLoopConfig {
    /// Sample (PWM) period, s.
    pub ts: f32,
    /// Proportional gain, V/A.
    pub kp: f32,
    /// Integral gain, V/(A·s).
    pub ki: f32,
    /// Phase inductance used for decoupling, H.
    pub inductance: f32,
    /// Back-EMF constant Ke, V·s/rad (mechanical), peak per phase.
    pub ke: f32,
    /// Angle advance of the inverse Park in samples (1.5 for one sample of delay).
    pub latency: f32,
    /// ADC scaling.
    pub sense: Sense,
    /// PWM modulator (timer period, m_max).
    pub modulator: Modulator,
}

impl CurrentLoopConfig {
    /// Gains `(Kp, Ki)` for a first-order closed loop of bandwidth `wc` (rad/s):
    /// `Kp = L·ωc` (V/A), `Ki = R·ωc` (V/(A·s)).
    pub fn gains_for(r: f32, l: f32, wc: f32) -> (f32, f32) {
        (l * wc, r * wc)
    }
}

/// The current controller and its last measurements.
#[derive(Clone, Debug)]
pub struct CurrentLoop {
    cfg: CurrentLoopConfig,
    // Precomputed: Ke per electrical rad/s (Ke/50) and Ts·latency.
    ke_e: f32,
    advance: f32,
    /// Calibrated gain of each current channel (A, B; 1 = as the sensing says).
    gain: [f32; 2],
    /// Amperes per count of each channel with its gain (precomputed for the step).
    amps: [f32; 2],
    /// Dead-time loss as a fraction of the bus voltage.
    dead_time: f32,
    /// 1 / the current band of the dead-time compensation, 1/A.
    dead_time_slope: f32,
    /// Decouple d and q with the measured currents (else with the references).
    measured_decoupling: bool,
    pi_d: Pi,
    pi_q: Pi,
    /// Current reference on d (A).
    pub id_ref: f32,
    /// Current reference on q (A).
    pub iq_ref: f32,
    /// Last measured phase currents (A).
    pub i_ab: AlphaBeta,
    /// Last measured rotor-frame currents (A).
    pub i_dq: Dq,
    /// Last commanded rotor-frame voltages (V, after limiting).
    pub v_dq: Dq,
    /// Last commanded phase voltages (V).
    pub v_ab: AlphaBeta,
    /// Last bus voltage (V).
    pub vbus: f32,
    /// The voltage vector was limited in the last step.
    pub saturated: bool,
}

impl CurrentLoop {
    /// New loop with zero references.
    pub fn new(cfg: CurrentLoopConfig) -> Self {
        CurrentLoop {
            cfg,
            ke_e: cfg.ke * (1.0 / crate::angle::POLE_PAIRS as f32),
            advance: cfg.ts * cfg.latency,
            gain: [1.0; 2],
            amps: [cfg.sense.amps_per_count; 2],
            dead_time: 0.0,
            dead_time_slope: 1.0 / DEAD_TIME_BAND,
            measured_decoupling: false,
            pi_d: Pi::new(cfg.kp, cfg.ki, cfg.ts, 0.0),
            pi_q: Pi::new(cfg.kp, cfg.ki, cfg.ts, 0.0),
            id_ref: 0.0,
            iq_ref: 0.0,
            i_ab: AlphaBeta::default(),
            i_dq: Dq::default(),
            v_dq: Dq::default(),
            v_ab: AlphaBeta::default(),
            vbus: 0.0,
            saturated: false,
        }
    }

    /// Configuration in use.
    pub fn config(&self) -> &CurrentLoopConfig {
        &self.cfg
    }

    /// Changes gains (integrators kept).
    pub fn set_gains(&mut self, kp: f32, ki: f32) {
        self.cfg.kp = kp;
        self.cfg.ki = ki;
        self.pi_d.set_gains(kp, ki, self.cfg.ts);
        self.pi_q.set_gains(kp, ki, self.cfg.ts);
    }

    /// Changes the motor constants used by the feed-forward.
    pub fn set_motor(&mut self, inductance: f32, ke: f32) {
        self.cfg.inductance = inductance;
        self.cfg.ke = ke;
        self.ke_e = ke * (1.0 / crate::angle::POLE_PAIRS as f32);
    }

    /// Changes the ADC offsets (counts).
    pub fn set_offsets(&mut self, offset_a: f32, offset_b: f32) {
        self.cfg.sense.offset_a = offset_a;
        self.cfg.sense.offset_b = offset_b;
    }

    /// Phase-B channel gain relative to phase A (the calibration's `1/ratio`), phase
    /// A's gain kept; values outside 0.5..2 or not finite are ignored.
    pub fn set_gain_b(&mut self, gain_b: f32) {
        self.set_channel_gains(self.gain[0], self.gain[0] * gain_b);
    }

    /// The calibrated gain of each current channel (`foc::autotune`, "Channel
    /// gains"): the channel's reading is multiplied by it. A pair with a value outside
    /// 0.5..2 or not finite is ignored. [`Sense`] (and [`Self::voltage_step`]) stays
    /// uncalibrated.
    pub fn set_channel_gains(&mut self, a: f32, b: f32) {
        let ok = |g: f32| g.is_finite() && (0.5..=2.0).contains(&g);
        if ok(a) && ok(b) {
            self.gain = [a, b];
            let apc = self.cfg.sense.amps_per_count;
            self.amps = [apc * a, apc * b];
        }
    }

    /// The calibrated channel gains (A, B).
    pub fn channel_gains(&self) -> [f32; 2] {
        self.gain
    }

    /// Dead-time compensation: the loss as a fraction of the bus voltage (0 = off;
    /// clamped to 0..0.1) and the current band `band` (A, > 0) of its linear part.
    pub fn set_dead_time(&mut self, fraction: f32, band: f32) {
        self.dead_time = if fraction.is_finite() {
            num::clamp(fraction, 0.0, 0.1)
        } else {
            0.0
        };
        if band.is_finite() && band > 1e-4 {
            self.dead_time_slope = 1.0 / band;
        }
    }

    /// Decoupling of d and q (module doc, "Decoupling"): `true` with the measured
    /// currents, for the encoder's commutation angle; `false` (the default) with the
    /// references, for a commanded angle (open loop, alignment).
    pub fn set_measured_decoupling(&mut self, on: bool) {
        self.measured_decoupling = on;
    }

    /// Clears both integrators (use when the bridges were off).
    pub fn reset(&mut self) {
        self.pi_d.reset();
        self.pi_q.reset();
    }

    /// One current-loop step. `theta_e`: electrical angle at the sampling instant;
    /// `omega_e`: electrical angular velocity (rad/s). Uses [`Self::id_ref`] and
    /// [`Self::iq_ref`]. Returns the compare values for the next PWM period.
    #[inline]
    pub fn step(&mut self, adc: &AdcSample, theta_e: Angle, omega_e: f32) -> Duties {
        let cfg = &self.cfg;
        // The sensing with each channel's calibrated gain.
        let i_ab = AlphaBeta {
            alpha: (adc.ia as f32 - cfg.sense.offset_a) * self.amps[0],
            beta: (adc.ib as f32 - cfg.sense.offset_b) * self.amps[1],
        };
        let vbus = cfg.sense.vbus(adc);
        let (s, c) = (trig::sin(theta_e), trig::cos(theta_e));
        let i_dq = park(i_ab, s, c);

        let vmax = cfg.modulator.vmax(vbus);
        let wl = omega_e * cfg.inductance;
        // Decoupling (module doc, "Decoupling").
        let (xd, xq) = if self.measured_decoupling {
            (i_dq.d, i_dq.q)
        } else {
            (self.id_ref, self.iq_ref)
        };
        let ff_d = -wl * xq;
        let ff_q = wl * xd + self.ke_e * omega_e;

        let ed = self.id_ref - i_dq.d;
        let eq = self.iq_ref - i_dq.q;
        let ud = self.pi_d.output_unlimited(ed) + ff_d;
        let uq = self.pi_q.output_unlimited(eq) + ff_q;
        let (vd, vq, sat) = limit_circle(ud, uq, vmax);
        // Conditional integration (`Pi::integrate`): while the circle limits the
        // vector, each axis only integrates towards the inside.
        self.pi_d.integrate(ed, ud, sat, -vmax, vmax);
        self.pi_q.integrate(eq, uq, sat, -vmax, vmax);

        let (s2, c2) = rotate_small2(s, c, omega_e * self.advance);
        let v_dq = Dq { d: vd, q: vq };
        let v_ab = inverse_park(v_dq, s2, c2);
        let v_dt = vbus * self.dead_time;
        let k = self.dead_time_slope;
        let duties = cfg.modulator.duties(
            v_ab.alpha + v_dt * num::clamp(i_ab.alpha * k, -1.0, 1.0),
            v_ab.beta + v_dt * num::clamp(i_ab.beta * k, -1.0, 1.0),
            vbus,
        );

        self.i_ab = i_ab;
        self.i_dq = i_dq;
        self.v_dq = v_dq;
        self.v_ab = v_ab;
        self.vbus = vbus;
        self.saturated = sat;
        duties
    }

    /// Voltage mode (auto-tune, diagnostics): measures the sample and applies the
    /// phase voltages `va`, `vb` (V, limited to the circle) without the PI
    /// controllers. The integrators are cleared.
    pub fn voltage_step(&mut self, adc: &AdcSample, va: f32, vb: f32) -> Duties {
        let cfg = &self.cfg;
        let i_ab = cfg.sense.currents(adc);
        let vbus = cfg.sense.vbus(adc);
        let (a, b, sat) = limit_circle(va, vb, cfg.modulator.vmax(vbus));
        let duties = cfg.modulator.duties(a, b, vbus);
        self.pi_d.reset();
        self.pi_q.reset();
        self.i_ab = i_ab;
        self.v_ab = AlphaBeta { alpha: a, beta: b };
        self.vbus = vbus;
        self.saturated = sat;
        duties
    }

    /// The last measured phase currents expressed in another frame (e.g. the encoder
    /// frame while the loop runs on the open-loop command angle).
    pub fn currents_in_frame(&self, theta_e: Angle) -> Dq {
        park(self.i_ab, trig::sin(theta_e), trig::cos(theta_e))
    }
}
