//! A simulated drive: the plant plus the `foc` controllers wired as on the board
//! (current loop and encoder at the PWM rate, servo/open loop every
//! [`SERVO_DIV`]-th period), and a trapezoidal profile generator.

use super::motor::{Plant, PlantConfig};
use foc::angle::Angle;
use foc::current_loop::{AdcSample, CurrentLoop, CurrentLoopConfig};
use foc::encoder::{Encoder, EncoderConfig};
use foc::modulation::{Duties, Modulator};
use foc::servo::{Demand, Servo, ServoGains};
use std::f64::consts::PI;

/// PWM / current-loop period, s (40 kHz).
pub const TS: f32 = 25e-6;
/// Servo / open-loop steps happen every `SERVO_DIV` current-loop steps (10 kHz).
pub const SERVO_DIV: u64 = 4;
/// Servo period, s.
pub const TS_SERVO: f32 = TS * SERVO_DIV as f32;
/// Current-loop bandwidth used by the rigs: the drive's robust design
/// ([`foc::current_loop::robust_bandwidth`]), rad/s.
pub const WC: f32 = foc::current_loop::ROBUST_WC_TS / TS;
/// The current loop's latency, samples (sample to the middle of the PWM period that
/// applies its voltage: the plant's one sample of delay + 0.5).
pub const LATENCY: f32 = 1.5;
/// Encoder PLL natural frequency, rad/s.
pub const PLL_OMEGA: f32 = 8000.0;

/// Angle of `rad` (f64, any size) as a wrapping fixed-point angle.
pub fn angle_f64(rad: f64) -> Angle {
    let turns = rad / (2.0 * PI);
    let frac = turns - turns.floor();
    Angle(((frac * 4_294_967_296.0) as u64) as u32)
}

/// Plant + current loop + encoder.
pub struct Rig {
    /// The motor model.
    pub plant: Plant,
    /// The current controller.
    pub cl: CurrentLoop,
    /// The encoder.
    pub enc: Encoder,
    /// Current-loop steps done.
    pub k: u64,
}

impl Rig {
    /// Rig with current-loop gains from the true R and L, and the encoder offset set
    /// to the true value (use [`Rig::new_unaligned`] to test the alignment).
    pub fn new(cfg: PlantConfig) -> Rig {
        let mut r = Self::new_unaligned(cfg);
        let off = r.true_offset();
        r.enc.set_electrical_offset(off);
        r
    }

    /// Rig whose encoder electrical offset is 0 (unknown).
    pub fn new_unaligned(cfg: PlantConfig) -> Rig {
        let m = cfg.motor;
        let (kp, ki) = CurrentLoopConfig::gains_for(m.r as f32, m.l as f32, WC);
        let clc = CurrentLoopConfig {
            ts: TS,
            kp,
            ki,
            inductance: m.l as f32,
            ke: m.kt as f32,
            latency: LATENCY,
            sense: cfg.sense(),
            modulator: Modulator::new(cfg.pwm_period),
        };
        let plant = Plant::new(cfg);
        let enc = Encoder::new(
            EncoderConfig {
                lines: cfg.cpr / 4,
                ts: TS,
                pll_omega: PLL_OMEGA,
            },
            plant.encoder_raw(),
        );
        Rig {
            plant,
            cl: CurrentLoop::new(clc),
            enc,
            k: 0,
        }
    }

    /// The electrical offset that makes the encoder's electrical angle equal the
    /// rotor's (to half a count).
    pub fn true_offset(&self) -> Angle {
        let half_count = Angle(((25u64 << 32) / self.enc.cpr() as u64) as u32);
        angle_f64(self.plant.theta_e())
            .wrapping_sub(self.enc.raw_electrical_angle())
            .wrapping_add(half_count)
    }

    /// Error of an electrical offset against the truth, in encoder counts.
    pub fn offset_error_counts(&self, offset: Angle) -> f64 {
        let d = offset.diff(self.true_offset()) as f64 / 4_294_967_296.0;
        d * self.enc.cpr() as f64 / 50.0
    }

    /// One PWM period: sample, encoder update, `f` computes the duties, plant advances.
    pub fn tick_with(
        &mut self,
        f: impl FnOnce(&mut CurrentLoop, &mut Encoder, &AdcSample) -> Duties,
    ) {
        let adc = self.plant.sample();
        self.enc.update(self.plant.encoder_raw());
        let d = f(&mut self.cl, &mut self.enc, &adc);
        self.plant.advance(d);
        self.k += 1;
    }

    /// One PWM period of FOC on the encoder's commutation angle and speed
    /// (`foc::encoder`, "Angle and speed for the current loop") with the decoupling
    /// on the measured currents, as the board's closed loop.
    pub fn tick(&mut self) {
        self.cl.set_measured_decoupling(true);
        let adc = self.plant.sample();
        self.enc.update(self.plant.encoder_raw());
        let d = self.cl.step(
            &adc,
            self.enc.commutation_angle(),
            self.enc.commutation_omega_e(),
        );
        self.plant.advance(d);
        self.k += 1;
    }

    /// One PWM period of FOC on a given angle and electrical speed (open loop; the
    /// decoupling on the references).
    pub fn tick_at(&mut self, theta: Angle, omega_e: f32) {
        self.cl.set_measured_decoupling(false);
        self.tick_with(|cl, _, adc| cl.step(adc, theta, omega_e));
    }

    /// One servo period: servo step on the encoder, then [`SERVO_DIV`] FOC ticks.
    pub fn servo_period(&mut self, servo: &mut Servo, d: &Demand) {
        self.cl.id_ref = 0.0;
        self.cl.iq_ref = servo.step(d, self.enc.position(), self.enc.velocity());
        for _ in 0..SERVO_DIV {
            self.tick();
        }
    }

    /// Servo gains used by the scenarios for this motor: velocity bandwidth `bw_hz`,
    /// current limit √2·I_rated.
    pub fn servo_gains(&self, bw_hz: f32) -> ServoGains {
        let m = self.plant.cfg.motor;
        ServoGains::from_bandwidth(
            m.j as f32,
            m.kt as f32,
            self.enc.cpr(),
            bw_hz,
            (m.i_rated * std::f64::consts::SQRT_2) as f32,
        )
    }

    /// Applies an auto-tune's results as the drive does after its power-up tune:
    /// current-loop gains of the robust design, L and Ke for the feed-forward, the
    /// offsets and channel gains, and the dead-time compensation.
    pub fn apply_tune(&mut self, r: &foc::autotune::TuneResult) {
        let (kp, ki) = CurrentLoopConfig::gains_for(r.r, r.l, WC);
        self.cl.set_gains(kp, ki);
        let ke = self.cl.config().ke;
        self.cl.set_motor(r.l, ke);
        let s = self.cl.config().sense;
        self.cl.set_offsets(
            s.offset_a + r.offset[0] / s.amps_per_count,
            s.offset_b + r.offset[1] / s.amps_per_count,
        );
        self.cl.set_channel_gains(r.gain[0], r.gain[1]);
        let vbus = self.plant.cfg.vbus as f32;
        self.cl
            .set_dead_time(r.dead_time_v / vbus, foc::current_loop::DEAD_TIME_BAND);
    }

    /// Simulated time, s.
    pub fn time(&self) -> f64 {
        self.plant.time
    }
}

/// Trapezoidal (or triangular) move profile.
#[derive(Clone, Copy, Debug)]
pub struct Trapezoid {
    p0: f64,
    dir: f64,
    v: f64,
    a: f64,
    t_acc: f64,
    t_cruise: f64,
}

impl Trapezoid {
    /// From `p0` to `p1` with speed limit `vmax` and acceleration `amax` (units/s, /s²).
    pub fn new(p0: f64, p1: f64, vmax: f64, amax: f64) -> Self {
        let d = (p1 - p0).abs();
        let dir = if p1 >= p0 { 1.0 } else { -1.0 };
        let mut v = vmax;
        let mut t_acc = v / amax;
        let mut d_acc = 0.5 * amax * t_acc * t_acc;
        if 2.0 * d_acc > d {
            t_acc = (d / amax).sqrt();
            v = amax * t_acc;
            d_acc = 0.5 * d;
        }
        let t_cruise = (d - 2.0 * d_acc) / v;
        Trapezoid {
            p0,
            dir,
            v,
            a: amax,
            t_acc,
            t_cruise,
        }
    }

    /// Duration of acceleration (= deceleration), s.
    pub fn t_acc(&self) -> f64 {
        self.t_acc
    }

    /// Total duration, s.
    pub fn duration(&self) -> f64 {
        2.0 * self.t_acc + self.t_cruise
    }

    /// `(position, velocity, acceleration)` at time `t`.
    pub fn at(&self, t: f64) -> (f64, f64, f64) {
        let (a, v, ta, tc) = (self.a, self.v, self.t_acc, self.t_cruise);
        let (p, vel, acc) = if t <= 0.0 {
            (0.0, 0.0, 0.0)
        } else if t < ta {
            (0.5 * a * t * t, a * t, a)
        } else if t < ta + tc {
            (0.5 * a * ta * ta + v * (t - ta), v, 0.0)
        } else if t < 2.0 * ta + tc {
            let u = 2.0 * ta + tc - t;
            (
                2.0 * 0.5 * a * ta * ta + v * tc - 0.5 * a * u * u,
                a * u,
                -a,
            )
        } else {
            (a * ta * ta + v * tc, 0.0, 0.0)
        };
        (self.p0 + self.dir * p, self.dir * vel, self.dir * acc)
    }

    /// Servo demand at time `t` (positions in counts).
    pub fn demand(&self, t: f64) -> Demand {
        let (p, v, a) = self.at(t);
        let whole = p.floor();
        Demand {
            pos: whole as i64 as i32,
            frac: (p - whole) as f32,
            vel: v as f32,
            acc: a as f32,
        }
    }
}
