//! The motor and power-stage model: a two-phase hybrid stepper in the stationary frame.
//!
//! State `(i_A, i_B, θ, ω)`, per phase `L·di/dt = v − R·i − e`,
//! `e_A = −Ke·ω·sin θe`, `e_B = +Ke·ω·cos θe`, torque
//! `T = Kt·(−i_A·sin θe + i_B·cos θe) − Td·sin 4θe`,
//! `J·dω/dt = T − B·ω − Tc·sgn ω − T_load` with a stick band, integrated with RK4 at
//! PWM period / 8. The H-bridges are an average model: the bridge voltage is
//! `(duty₁ − duty₂)·Vbus` minus a dead-time loss `V_dt·sat(i/0.05 A)`. Duties written
//! by the controller after the sample at `t` act from `t + D·Ts`
//! ([`PlantConfig::delay`], D = 1 by default: one sample of delay).
//! Current sampling: 12-bit ADC, offset 2048, seeded Gaussian noise; bus voltage
//! 12-bit; encoder: floor of the angle in counts plus a mounting offset, as the
//! 16-bit counter of a timer in encoder mode.
//!
//! # Non-idealities (all off by default)
//! The robustness figures switch them on one at a time, then all together:
//! * **L(i)**, [`PlantConfig::saturation`]: the incremental inductance of each phase
//!   falls with its own current, `L(i) = L₀·(1 − s·min((i/I_rated)², 2))`. The curves
//!   used are [`SATURATION_ECN57_20`] (s = 0.30: 30 % lower at rated current) and
//!   [`SATURATION_TC86_45`] (s = 0.25), the typical drop of a hybrid stepper's
//!   phase inductance at rated current. [`PlantConfig::l_scale`] multiplies L₀ (a
//!   tune made at another operating point).
//! * **Delay**, [`PlantConfig::delay`]: 0.5 is the board when the current-loop
//!   interrupt ends before the PWM underflow (the duties load half a period after the
//!   sample), 1.0 when it ends after it, 1.5 the robustness case.
//! * **Current sensing**, [`PlantConfig::adc_gain`] (per channel) and
//!   [`Plant::adc_offset_error`] (counts).
//! * **Dead time**, [`PlantConfig::dead_time_v`].
//! * **Encoder at any speed**, [`Plant::forced_speed`]: a dynamometer holds the shaft
//!   at a constant speed, so the count pattern need not repeat.
//! * **Hard stop**, [`Plant::hard_stop`]: beyond a shaft angle a stiff spring with a
//!   damper pushes back, `T = −k·x − c·ω` while `x > 0` (`x`: penetration, rad) — the
//!   mechanical end stop of an axis (stall detection, stall homing).

use super::rng::Rng;
use foc::current_loop::{AdcSample, Sense};
use foc::modulation::Duties;
use std::f64::consts::PI;

/// A phase-resistance multiplier at or above this value models an open coil.
pub const OPEN_SCALE: f64 = 1e3;
/// Resistance of a short across a phase's motor terminals (wiring + contact), Ω.
pub const SHORT_OHMS: f64 = 0.02;
/// Inductance of that short (the motor leads), H.
pub const SHORT_HENRY: f64 = 2e-6;
/// Relative inductance drop of the ECN57-20 at rated current (the L(i) curve).
pub const SATURATION_ECN57_20: f64 = 0.30;
/// Relative inductance drop of the TC86-45 at rated current.
pub const SATURATION_TC86_45: f64 = 0.25;

/// Motor constants (SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorParams {
    /// Name.
    pub name: &'static str,
    /// Holding torque (both phases at rated current), N·m.
    pub t_hold: f64,
    /// Rated phase current, A.
    pub i_rated: f64,
    /// Phase resistance, Ω.
    pub r: f64,
    /// Phase inductance, H.
    pub l: f64,
    /// Rotor inertia, kg·m².
    pub j: f64,
    /// Torque constant = back-EMF constant, N·m/A = V·s/rad.
    pub kt: f64,
    /// Detent torque amplitude, N·m.
    pub td: f64,
    /// Coulomb friction, N·m.
    pub tc: f64,
    /// Viscous friction, N·m·s.
    pub b: f64,
}

/// ECN57-20 (NEMA 23).
pub const ECN57_20: MotorParams = MotorParams {
    name: "ECN57-20",
    t_hold: 2.0,
    i_rated: 5.0,
    r: 0.40,
    l: 1.8e-3,
    j: 480e-7,
    kt: 0.283,
    td: 0.05,
    tc: 0.015,
    b: 2e-4,
};

/// TC86-45 (NEMA 34, 1000-line encoder).
pub const TC86_45: MotorParams = MotorParams {
    name: "TC86-45",
    t_hold: 4.5,
    i_rated: 6.0,
    r: 0.325,
    l: 3.0e-3,
    j: 1400e-7,
    kt: 0.530,
    td: 0.15,
    tc: 0.04,
    b: 5e-4,
};

/// Power stage, sensing and simulation settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantConfig {
    /// Motor.
    pub motor: MotorParams,
    /// Bus voltage, V.
    pub vbus: f64,
    /// PWM period, s.
    pub ts: f64,
    /// PWM timer period, counts.
    pub pwm_period: u16,
    /// Dead-time voltage loss, V.
    pub dead_time_v: f64,
    /// Current ADC full scale ±, A.
    pub adc_full_scale: f64,
    /// Current ADC noise, LSB (σ).
    pub adc_noise_lsb: f64,
    /// Bus ADC full scale, V.
    pub vbus_full_scale: f64,
    /// Encoder counts per revolution.
    pub cpr: u32,
    /// Encoder count at rotor angle 0 (mounting offset).
    pub encoder_offset: i32,
    /// Integration sub-steps per PWM period (RK4).
    pub substeps: u32,
    /// Rotor locked (current-loop tests).
    pub locked: bool,
    /// Speed below which the rotor may stick, rad/s.
    pub stick_band: f64,
    /// Noise seed.
    pub seed: u64,
    /// Initial rotor angle, rad.
    pub theta0: f64,
    /// Phase resistance multipliers (A, B) for fault studies (1.0 = healthy; a huge
    /// value = open coil).
    pub r_scale: [f64; 2],
    /// Samples from the current sample to the update event that loads the duties
    /// computed from it (0.5, 1.0 or 1.5; see the module doc).
    pub delay: f64,
    /// Multiplier of the motor's inductance L₀ (the tuned value is `motor.l`).
    pub l_scale: f64,
    /// Relative drop of the incremental inductance at rated current (0 = constant L).
    pub saturation: f64,
    /// Gain of the current sensors (A, B), 1.0 = nominal.
    pub adc_gain: [f64; 2],
}

impl PlantConfig {
    /// Defaults: 48 V, 40 kHz, period 2125 counts (170 MHz centre-aligned), ±10 A ADC,
    /// 1 LSB noise, 4000 counts/rev, offset 37 counts.
    pub fn new(motor: MotorParams) -> Self {
        PlantConfig {
            motor,
            vbus: 48.0,
            ts: 25e-6,
            pwm_period: 2125,
            dead_time_v: 0.2,
            adc_full_scale: 10.0,
            adc_noise_lsb: 1.0,
            vbus_full_scale: 60.0,
            cpr: 4000,
            encoder_offset: 37,
            substeps: 8,
            locked: false,
            stick_band: 1e-3,
            seed: 1,
            r_scale: [1.0, 1.0],
            theta0: 0.0123,
            delay: 1.0,
            l_scale: 1.0,
            saturation: 0.0,
            adc_gain: [1.0, 1.0],
        }
    }

    /// Incremental inductance of a phase carrying `i` amperes, H.
    pub fn inductance(&self, i: f64) -> f64 {
        let x = i / self.motor.i_rated;
        self.motor.l * self.l_scale * (1.0 - self.saturation * (x * x).min(2.0))
    }

    /// The controller's ADC scaling matching this plant.
    pub fn sense(&self) -> Sense {
        Sense {
            amps_per_count: (2.0 * self.adc_full_scale / 4096.0) as f32,
            offset_a: 2048.0,
            offset_b: 2048.0,
            volts_per_count: (self.vbus_full_scale / 4096.0) as f32,
        }
    }
}

/// The simulated motor + power stage.
#[derive(Clone, Debug)]
pub struct Plant {
    /// Configuration.
    pub cfg: PlantConfig,
    /// Phase A current, A.
    pub ia: f64,
    /// Phase B current, A.
    pub ib: f64,
    /// Mechanical angle, rad (unwrapped).
    pub theta: f64,
    /// Mechanical speed, rad/s.
    pub omega: f64,
    /// Load torque (opposing positive rotation when positive), N·m.
    pub load: f64,
    /// Simulated time, s.
    pub time: f64,
    /// Fault injection: phase (A, B) short-circuited at the motor terminals. The
    /// bridge then drives the short ([`SHORT_OHMS`], [`SHORT_HENRY`]) instead of the
    /// winding: no back-EMF, no torque from that phase.
    pub short: [bool; 2],
    /// Break input: every bridge switch off. A phase current then freewheels through
    /// the diodes against the bus (`v = −Vbus·sgn i`) until it reaches zero and stays
    /// there (the back-EMF of these motors stays below the bus).
    pub bridges_off: bool,
    /// Fault injection: zero-current error of the current sensors (A, B), ADC counts.
    pub adc_offset_error: [f64; 2],
    /// Fault injection: the encoder signals are lost (cable cut). The counter then
    /// holds this value whatever the shaft does.
    pub encoder_frozen: Option<u16>,
    /// Fault injection: a current sensor (A, B) whose output stays at this ADC value
    /// whatever the current (a broken amplifier or an open sense resistor path).
    pub adc_stuck: [Option<u16>; 2],
    /// A dynamometer holds the shaft at this speed, rad/s (the motor's torque then
    /// does not change it).
    pub forced_speed: Option<f64>,
    /// A mechanical end stop on the shaft (none by default).
    pub hard_stop: Option<HardStop>,
    stuck: bool,
    /// Duties computed from the last three samples, newest first.
    duties: [Duties; 3],
    rng: Rng,
}

/// A mechanical end stop: a stiff spring with a damper beyond an angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HardStop {
    /// Shaft angle of the stop face, rad.
    pub at: f64,
    /// +1: blocks rotation beyond `at` in the positive direction; −1: below `at`.
    pub side: f64,
    /// Stiffness, N·m/rad.
    pub stiffness: f64,
    /// Damping, N·m·s/rad.
    pub damping: f64,
}

impl HardStop {
    /// A steel stop at `at` on `side` for a rotor of inertia `j`: 2000 N·m/rad (0.1°
    /// under 3.5 N·m), damping of half the critical value (a short bounce).
    pub fn steel(at: f64, side: f64, j: f64) -> Self {
        let k = 2000.0;
        HardStop {
            at,
            side,
            stiffness: k,
            damping: (k * j).sqrt(),
        }
    }

    /// Torque of the stop on the shaft at angle `th`, speed `w`, N·m.
    pub fn torque(&self, th: f64, w: f64) -> f64 {
        let x = (th - self.at) * self.side;
        if x > 0.0 {
            -self.side * (self.stiffness * x + self.damping * w * self.side).max(0.0)
        } else {
            0.0
        }
    }
}

#[derive(Clone, Copy)]
struct Inputs {
    va: f64,
    vb: f64,
    /// Bridges off: sign of each phase current at the start of the sub-step (the
    /// diodes that conduct; 0 = none).
    free: [f64; 2],
}

impl Plant {
    /// New plant at rest, angle 0, bridges at 50 %.
    pub fn new(cfg: PlantConfig) -> Self {
        let z = Duties::zero(cfg.pwm_period);
        Plant {
            cfg,
            ia: 0.0,
            ib: 0.0,
            theta: cfg.theta0,
            omega: 0.0,
            load: 0.0,
            time: 0.0,
            short: [false; 2],
            bridges_off: false,
            adc_offset_error: [0.0; 2],
            encoder_frozen: None,
            adc_stuck: [None; 2],
            forced_speed: None,
            hard_stop: None,
            stuck: true,
            duties: [z; 3],
            rng: Rng::new(cfg.seed),
        }
    }

    fn adc_current(&mut self, i: f64, offset_error: f64, gain: f64) -> u16 {
        let lsb = 2.0 * self.cfg.adc_full_scale / 4096.0;
        let x = 2048.0 + offset_error + gain * i / lsb + self.cfg.adc_noise_lsb * self.rng.normal();
        x.round().clamp(0.0, 4095.0) as u16
    }

    /// ADC conversion at the PWM centre (now).
    pub fn sample(&mut self) -> AdcSample {
        let (ia, ib) = (self.ia, self.ib);
        let v = (self.cfg.vbus / self.cfg.vbus_full_scale * 4096.0).round();
        let (sa, sb) = (
            self.adc_current(ia, self.adc_offset_error[0], self.cfg.adc_gain[0]),
            self.adc_current(ib, self.adc_offset_error[1], self.cfg.adc_gain[1]),
        );
        AdcSample {
            ia: self.adc_stuck[0].unwrap_or(sa),
            ib: self.adc_stuck[1].unwrap_or(sb),
            vbus: v.clamp(0.0, 4095.0) as u16,
        }
    }

    /// Encoder count (unwrapped, i64).
    pub fn encoder_count(&self) -> i64 {
        ((self.theta * self.cfg.cpr as f64 / (2.0 * PI)).floor() as i64)
            .wrapping_add(self.cfg.encoder_offset as i64)
    }

    /// Encoder timer counter value (16 bits).
    pub fn encoder_raw(&self) -> u16 {
        self.encoder_frozen.unwrap_or(self.encoder_count() as u16)
    }

    /// Electrical angle, rad.
    pub fn theta_e(&self) -> f64 {
        50.0 * self.theta
    }

    /// Rotor-frame currents `(i_d, i_q)` from the true state.
    pub fn i_dq(&self) -> (f64, f64) {
        let (s, c) = self.theta_e().sin_cos();
        (self.ia * c + self.ib * s, self.ib * c - self.ia * s)
    }

    /// Motor torque (electromagnetic + detent), N·m.
    pub fn torque(&self) -> f64 {
        let m = &self.cfg.motor;
        let (s, c) = self.theta_e().sin_cos();
        let s2 = 2.0 * s * c;
        let c2 = c * c - s * s;
        let ia = if self.short[0] { 0.0 } else { self.ia };
        let ib = if self.short[1] { 0.0 } else { self.ib };
        m.kt * (-ia * s + ib * c) - m.td * 2.0 * s2 * c2
    }

    fn deriv(&self, x: [f64; 4], u: Inputs) -> [f64; 4] {
        let m = &self.cfg.motor;
        let [ia, ib, th, w] = x;
        let (s, c) = (50.0 * th).sin_cos();
        let dt = self.cfg.dead_time_v;
        let sat = |i: f64| (i / 0.05).clamp(-1.0, 1.0);
        let ea = -m.kt * w * s;
        let eb = m.kt * w * c;
        let (la, lb) = (self.cfg.inductance(ia), self.cfg.inductance(ib));
        let mut dia = (u.va - dt * sat(ia) - m.r * self.cfg.r_scale[0] * ia - ea) / la;
        let mut dib = (u.vb - dt * sat(ib) - m.r * self.cfg.r_scale[1] * ib - eb) / lb;
        if self.short != [false; 2] || self.bridges_off {
            let vbus = self.cfg.vbus;
            let phase = |p: usize, i: f64, v: f64, e: f64, d: f64| -> f64 {
                let (v, e) = if self.bridges_off {
                    // Diodes: the current returns to the bus, none starts.
                    if u.free[p] == 0.0 {
                        return 0.0;
                    }
                    (-vbus * u.free[p], e)
                } else {
                    (v - dt * sat(i), e)
                };
                if self.short[p] {
                    (v - SHORT_OHMS * i) / SHORT_HENRY
                } else if self.bridges_off {
                    (v - m.r * self.cfg.r_scale[p] * i - e) / self.cfg.inductance(i)
                } else {
                    d
                }
            };
            dia = phase(0, ia, u.va, ea, dia);
            dib = phase(1, ib, u.vb, eb, dib);
        }
        // An open coil (resistance scale ≥ OPEN_SCALE) carries no current.
        if self.cfg.r_scale[0] >= OPEN_SCALE {
            dia = 0.0;
        }
        if self.cfg.r_scale[1] >= OPEN_SCALE {
            dib = 0.0;
        }
        if self.stuck || self.cfg.locked {
            return [dia, dib, 0.0, 0.0];
        }
        if self.forced_speed.is_some() {
            return [dia, dib, w, 0.0];
        }
        let s2 = 2.0 * s * c;
        let c2 = c * c - s * s;
        let (ta, tb) = (
            if self.short[0] { 0.0 } else { ia },
            if self.short[1] { 0.0 } else { ib },
        );
        let t = m.kt * (-ta * s + tb * c) - m.td * 2.0 * s2 * c2;
        let net = t - self.load + self.stop_torque(th, w);
        let fr = if w > 0.0 {
            m.tc
        } else if w < 0.0 {
            -m.tc
        } else {
            m.tc * net.signum()
        };
        [dia, dib, w, (net - m.b * w - fr) / m.j]
    }

    /// Advances one PWM period. `next` is what the controller computed from the
    /// sample just taken; it acts from [`PlantConfig::delay`] samples after it.
    pub fn advance(&mut self, next: Duties) {
        self.duties = [next, self.duties[0], self.duties[1]];
        let p = self.cfg.pwm_period.max(1) as f64;
        let vbus = self.cfg.vbus;
        let bridge = |d: &Duties| {
            (
                (d.a1 as f64 - d.a2 as f64) / p * vbus,
                (d.b1 as f64 - d.b2 as f64) / p * vbus,
            )
        };
        let mut u = Inputs {
            va: 0.0,
            vb: 0.0,
            free: [0.0; 2],
        };
        let n = self.cfg.substeps.max(1);
        let h = self.cfg.ts / n as f64;
        if let Some(w) = self.forced_speed {
            self.omega = w;
            self.stuck = false;
        }
        if self.at_rest() {
            // Nothing moves in this period (see `at_rest`): every sub-step below
            // would leave the state as it is.
            (self.ia, self.ib) = (0.0, 0.0);
            self.time += self.cfg.ts;
            return;
        }
        for s in 0..n {
            // The duties computed `age` samples ago are active at this sub-step.
            let tau = s as f64 / n as f64;
            let age = ((self.cfg.delay - tau).ceil().max(0.0) as usize).min(2);
            (u.va, u.vb) = bridge(&self.duties[age]);
            let x = [self.ia, self.ib, self.theta, self.omega];
            let sgn = |i: f64| if i == 0.0 { 0.0 } else { i.signum() };
            u.free = [sgn(x[0]), sgn(x[1])];
            let k1 = self.deriv(x, u);
            let add = |a: [f64; 4], k: [f64; 4], f: f64| {
                [
                    a[0] + f * k[0],
                    a[1] + f * k[1],
                    a[2] + f * k[2],
                    a[3] + f * k[3],
                ]
            };
            let k2 = self.deriv(add(x, k1, h / 2.0), u);
            let k3 = self.deriv(add(x, k2, h / 2.0), u);
            let k4 = self.deriv(add(x, k3, h), u);
            let mut y = [0.0; 4];
            for i in 0..4 {
                y[i] = x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
            if self.bridges_off {
                // The freewheeling current stops at zero.
                if y[0] * x[0] <= 0.0 {
                    y[0] = 0.0;
                }
                if y[1] * x[1] <= 0.0 {
                    y[1] = 0.0;
                }
            }
            self.ia = y[0];
            self.ib = y[1];
            if !self.cfg.locked {
                self.update_mechanics(x[3], y[2], y[3]);
            }
        }
        self.time += self.cfg.ts;
    }

    /// True when a period changes nothing: no current (a subnormal one counts as
    /// none: a decaying current ends on a subnormal fixed point of the integration,
    /// 1e-322 A, whose arithmetic is slow; FPUs with flush-to-zero, the board's
    /// included, see 0), no voltage across either coil from any of the duties that
    /// act in it (both legs of each bridge equal), and the rotor held (stiction holds
    /// against the net torque, or locked). Then every derivative of the currents is
    /// zero, and the mechanics keep their state (`update_mechanics` returns at once
    /// for a stuck rotor that stays stuck): [`Plant::advance`] skips the integration
    /// — what keeps an idle virtual drive cheap — with the same result.
    pub fn at_rest(&self) -> bool {
        let quiet = |d: &Duties| d.a1 == d.a2 && d.b1 == d.b2;
        if self.forced_speed.is_some()
            || self.ia.abs() >= f64::MIN_POSITIVE
            || self.ib.abs() >= f64::MIN_POSITIVE
            || !self.duties.iter().all(quiet)
        {
            return false;
        }
        if self.cfg.locked {
            return true;
        }
        let net = self.torque() - self.load + self.stop_torque(self.theta, self.omega);
        self.stuck && self.omega == 0.0 && net.abs() <= self.cfg.motor.tc
    }

    fn update_mechanics(&mut self, w_old: f64, th: f64, w: f64) {
        let m = self.cfg.motor;
        if let Some(w) = self.forced_speed {
            self.theta = th;
            self.omega = w;
            return;
        }
        let net = self.torque() - self.load + self.stop_torque(self.theta, self.omega);
        if self.stuck {
            if net.abs() > m.tc {
                self.stuck = false;
            }
            return;
        }
        self.theta = th;
        self.omega = w;
        let net = self.torque() - self.load + self.stop_torque(th, w);
        let crossed = w_old * w <= 0.0 || w.abs() < self.cfg.stick_band;
        if crossed && net.abs() <= m.tc {
            self.stuck = true;
            self.omega = 0.0;
        }
    }

    fn stop_torque(&self, th: f64, w: f64) -> f64 {
        self.hard_stop.map_or(0.0, |h| h.torque(th, w))
    }

    /// Rotor is held by static friction.
    pub fn is_stuck(&self) -> bool {
        self.stuck
    }
}
