//! The motor-control path of the current-loop interrupt, chip-independent: what the
//! board's `ADC1_2` interrupt (`firmware/src/hw/control.rs`) does every PWM period,
//! behind the [`ControlHw`] trait, so that host and QEMU tests run the same decisions
//! the board runs.
//!
//! Every PWM period [`ControlCore::period`] does, in this order:
//! 1. the encoder counter → `foc::encoder::Encoder::update` (position, PLL velocity,
//!    electrical angle);
//! 2. every [`SERVO_DIVIDER`]th period (10 kHz = [`crate::motion::SERVO_TS`]): the
//!    newest [`ControlCommand`] is read (power permission, offsets; a new cycle →
//!    `set_command`, new parameters → `configure`), the motion layer steps
//!    ([`CommutatedMotion`], held while the power-up auto-tune runs) → current
//!    reference (in open loop its angle gets the anti-resonance correction,
//!    `foc::damping`, 0x2059); the index and touch-probe latches become axis positions
//!    ([`crate::latch`]), the measurements for the drive ([`Feedback`]) are
//!    returned for publication, and, while the scope records at the servo rate, this
//!    period's [`ServoPoint`] goes to [`ControlHw::trace`];
//! 3. the bridges: [`bridge_mode`] decides (halted, break latched, fast protection
//!    tripped, auto-tune, the drive's permission, the motion layer's wish); on, the
//!    current loop through [`CurrentSupervisor`] (`run_step`, or `tune_step` in
//!    voltage mode while tuning) → duties → compare registers (in open loop the
//!    applied voltage also goes to the damping's back-EMF estimate), unless the fast
//!    protection trips in this very period; off, the loop keeps measuring (the
//!    protection keeps watching) with zero volts. The loop's `v_dq` / `i_dq` are
//!    summed for their servo-period means (the open-loop stall detection,
//!    `foc::stall`: the open-loop angle steps once per servo period, so a single
//!    period's voltage carries the current loop's response to that step).
//!
//! A withdrawn permission re-arms the fast protection (the drive has taken the trip's
//! fault); the current loop's integrators restart at every enable and at a
//! reference's reset.
use crate::board_glue::{ControlCommand, Feedback};
use crate::commutation::{CommutatedMotion, Commutation};
use crate::current_supervisor::{CurrentSupervisor, SupervisorConfig};
use crate::latch::{units_at_count, Edges, Seen};
use crate::motion::{CurrentReference, Frame, MotionConfig};
use crate::power_gate::{bridge_mode, BrakeOut, BridgeMode, GateInputs};
use crate::sampling::{AnalogScale, RawSample};
use crate::scope::ServoPoint;
use foc::current_loop::{robust_bandwidth, AdcSample, CurrentLoop, CurrentLoopConfig, Sense};
use foc::damping::{Damping, DampingConfig};
use foc::encoder::{Encoder, EncoderConfig};
use foc::modulation::{Duties, Modulator};
use foc::transforms::Dq;

/// Current-loop periods per servo period.
pub const SERVO_DIVIDER: u8 = 4;
/// Encoder PLL natural frequency, rad/s.
const PLL_OMEGA: f32 = 8000.0;
/// The current loop's latency, samples: sample to the middle of the PWM period that
/// applies the voltage (the duties load at the update event after the sample).
const LATENCY: f32 = 1.5;

/// What the control path needs of the hardware: the board maps each call onto its
/// registers (TIM2, TIM1/TIM8, the capture flags, the halted state); tests onto a
/// model.
pub trait ControlHw {
    /// The encoder counter (wrapping).
    fn raw_count(&mut self) -> u32;
    /// The newest command of the drive side (read at the servo rate).
    fn command(&mut self) -> Option<ControlCommand>;
    /// The counter latched by an index pulse since the last call.
    fn take_index_capture(&mut self) -> Option<u32>;
    /// The counter latched by a touch-probe 1 edge since the last call, and whether
    /// the edge went to the active level.
    fn take_probe1_capture(&mut self) -> Option<(u32, bool)>;
    /// The counters latched at the touch-probe 2 edges (sequence-numbered).
    fn probe2(&mut self) -> Option<Edges<u32>>;
    /// A panic or HardFault halted the drive (sticky until reset).
    fn halted(&self) -> bool;
    /// A break (over-current) is latched.
    fn break_latched(&self) -> bool;
    /// Switches both bridges on at zero volts; false when the hardware refused.
    fn enable_outputs(&mut self) -> bool;
    /// Switches both bridges off.
    fn disable_outputs(&mut self);
    /// Loads the compare registers.
    fn set_duties(&mut self, d: Duties);
    /// Drives the brake output (true: released). Called only when the level changes.
    fn set_brake_released(&mut self, released: bool);
    /// Hands the drive this servo period's point for the scope at the servo rate
    /// (only while the command asks for it, [`ControlCommand::trace`]; the board
    /// queues it in a [`crate::scope::PointRing`]). Without a scope: nothing.
    fn trace(&mut self, _p: &ServoPoint) {}
}

/// The board's fixed quantities the control path is built from.
#[derive(Debug, Clone, Copy)]
pub struct PowerStageConfig {
    /// PWM frequency, Hz (one [`ControlCore::period`] per PWM period).
    pub pwm_hz: u32,
    /// PWM auto-reload value (centre-aligned).
    pub pwm_arr: u16,
    /// ADC scaling and nominal offsets.
    pub analog: AnalogScale,
}

/// The motor data the current loop's gains and feed-forward start from (until an
/// auto-tune replaces them).
#[derive(Debug, Clone, Copy)]
pub struct LoopMotor {
    /// Phase resistance, Ω.
    pub r_ohm: f32,
    /// Phase inductance, H.
    pub l_h: f32,
    /// Back-EMF constant, V·s/rad (mechanical; the current loop divides by the pole
    /// pairs).
    pub ke: f32,
    /// Encoder lines per revolution.
    pub encoder_lines: u32,
}

impl LoopMotor {
    /// The current loop's resistance and inductance from the parameters 0x2020 (mΩ) /
    /// 0x2021 (µH) once 0x2021 holds a plausible inductance (≥ 100 µH, as an auto-tune
    /// or the user writes it), else `fallback` (the board's motor, Ω and H).
    pub fn from_params(
        p: &crate::params::Params,
        fallback: (f32, f32),
        ke: f32,
        encoder_lines: u32,
    ) -> Self {
        use crate::params::Param;
        let l_uh = p.get(Param::MotorInductance);
        let (r_ohm, l_h) = if l_uh >= 100 {
            (
                p.get(Param::MotorResistance).max(1) as f32 * 1e-3,
                l_uh as f32 * 1e-6,
            )
        } else {
            fallback
        };
        LoopMotor {
            r_ohm,
            l_h,
            ke,
            encoder_lines,
        }
    }
}

/// The state of the control path (owned by the current-loop interrupt on the board).
pub struct ControlCore {
    cl: CurrentLoop,
    enc: Encoder,
    motion: CommutatedMotion,
    sup: CurrentSupervisor,
    reference: CurrentReference,
    /// Open-loop anti-resonance damping (`foc::damping`).
    damping: Damping,
    /// Phase resistance before a tune measured it, Ω.
    motor_r: f32,
    divider: u8,
    seen_cycle: u32,
    seen_config: u32,
    bridges_on: bool,
    /// Power permission of the last command (read at the servo rate).
    permitted: bool,
    /// The last command's brake decision and the brake output ([`BrakeOut`]).
    brake_wanted: bool,
    brake: BrakeOut,
    /// Encoder counter at the last update.
    raw: u32,
    index_seq: u32,
    index_units: i32,
    probe1: Edges<i32>,
    probe2: Edges<i32>,
    /// Probe-2 latches already converted.
    probe2_seen: Seen,
    /// Sums of the current loop's `v_dq` / `i_dq` over the periods since the last
    /// servo period (their means feed the open loop's stall detection).
    v_sum: Dq,
    i_sum: Dq,
}

const NO_EDGES: Edges<i32> = Edges {
    active_seq: 0,
    active: 0,
    inactive_seq: 0,
    inactive: 0,
};

impl ControlCore {
    /// The control path at power-up: bridges off, no command seen, the current loop's
    /// gains for the robust bandwidth `foc::current_loop::robust_bandwidth` (0.23/Ts,
    /// ≤ 5 % overshoot over 0.7-1.3 × L and 1.5 samples of delay), the encoder
    /// starting at `raw_count`.
    pub fn new(
        stage: PowerStageConfig,
        motor: LoopMotor,
        motion: MotionConfig,
        wiggle: bool,
        supervisor: SupervisorConfig,
        raw_count: u32,
    ) -> Self {
        let ts = 1.0 / stage.pwm_hz as f32;
        let wc = robust_bandwidth(ts);
        let (kp, ki) = CurrentLoopConfig::gains_for(motor.r_ohm, motor.l_h, wc);
        let cl = CurrentLoop::new(CurrentLoopConfig {
            ts,
            kp,
            ki,
            inductance: motor.l_h,
            ke: motor.ke,
            latency: LATENCY,
            sense: Sense {
                amps_per_count: stage.analog.amps_per_count,
                offset_a: f32::from(stage.analog.offset_nominal),
                offset_b: f32::from(stage.analog.offset_nominal),
                volts_per_count: stage.analog.volts_per_count,
            },
            modulator: Modulator::new(stage.pwm_arr),
        });
        let enc = Encoder::new(
            EncoderConfig {
                lines: motor.encoder_lines.max(1),
                ts,
                pll_omega: PLL_OMEGA,
            },
            raw_count as u16,
        );
        ControlCore {
            cl,
            enc,
            motion: CommutatedMotion::new(motion, wiggle),
            sup: CurrentSupervisor::new(supervisor),
            reference: CurrentReference::OFF,
            damping: Damping::new(DampingConfig::new(
                ts * f32::from(SERVO_DIVIDER),
                motor.r_ohm,
                motor.l_h,
                motor.ke,
                LATENCY,
            )),
            motor_r: motor.r_ohm,
            divider: 0,
            seen_cycle: 0,
            seen_config: 0,
            bridges_on: false,
            permitted: false,
            brake_wanted: false,
            brake: BrakeOut::default(),
            raw: raw_count,
            index_seq: 0,
            index_units: 0,
            probe1: NO_EDGES,
            probe2: NO_EDGES,
            probe2_seen: Seen::default(),
            v_sum: Dq::default(),
            i_sum: Dq::default(),
        }
    }

    /// The bridges are on.
    pub fn bridges_on(&self) -> bool {
        self.bridges_on
    }

    /// One PWM period with the fresh sample `s` (module docs). Returns the
    /// measurements for the drive at the servo rate.
    #[inline(always)]
    pub fn period<H: ControlHw>(&mut self, hw: &mut H, s: RawSample) -> Option<Feedback> {
        self.raw = hw.raw_count();
        self.enc.update(self.raw as u16);

        let mut feedback = None;
        self.divider += 1;
        if self.divider >= SERVO_DIVIDER {
            self.divider = 0;
            // The command is read at the servo rate: a withdrawn permission switches
            // the bridges off within one servo period (an over-current does so in
            // hardware at once).
            let cmd = hw.command();
            self.permitted = cmd.as_ref().is_some_and(ControlCommand::permits_power);
            self.brake_wanted = cmd.as_ref().is_some_and(|k| k.brake_released);
            if !self.permitted {
                // The drive has withdrawn the power (it took the trip's fault): re-armed.
                self.sup.rearm();
            }
            feedback = Some(self.servo_step(hw, cmd.as_ref()));
        }

        // The bridge decision (`power_gate`): never on while halted (panic /
        // HardFault) or with a latched break.
        let mode = bridge_mode(GateInputs {
            halted: hw.halted(),
            break_latched: hw.break_latched(),
            tripped: self.sup.tripped(),
            tuning: self.sup.tuning(),
            permitted: self.permitted,
            power_wanted: self.reference.power,
        });
        let adc = AdcSample {
            ia: s.ia,
            ib: s.ib,
            vbus: s.vbus,
        };
        self.bridges(hw, mode, &adc);
        // The brake follows the bridges in this very period: engaged as they go off
        // (the power stage lost), released only with them on and the runtime's
        // decision. The measurements report the bridges after this decision.
        if let Some(released) = self.brake.update(self.brake_wanted, self.bridges_on) {
            hw.set_brake_released(released);
        }
        if let Some(f) = feedback.as_mut() {
            f.bridges_on = self.bridges_on;
        }
        feedback
    }

    /// The bridges for `mode` in this period: on, the current loop (or the tune) and
    /// the duties unless the fast protection trips; off, zero volts and the
    /// protection watching.
    #[inline(always)]
    fn bridges<H: ControlHw>(&mut self, hw: &mut H, mode: BridgeMode, adc: &AdcSample) {
        let adc = *adc;
        if mode != BridgeMode::Off {
            if !self.bridges_on {
                self.cl.reset();
                self.bridges_on = hw.enable_outputs();
            }
            let d = if mode == BridgeMode::Tune {
                // Power-up auto-tune: voltage mode, the motion layer is held.
                self.sup.tune_step(&mut self.cl, &adc)
            } else {
                if self.reference.reset {
                    self.cl.reset();
                    self.reference.reset = false;
                }
                self.cl.id_ref = self.reference.id;
                self.cl.iq_ref = self.reference.iq;
                match self.reference.frame {
                    Frame::Encoder => {
                        let (theta, omega) =
                            (self.enc.commutation_angle(), self.enc.commutation_omega_e());
                        // The measured currents decouple d and q on the rotor's angle
                        // (`foc::current_loop`, "Decoupling").
                        self.cl.set_measured_decoupling(true);
                        self.sup.run_step(&mut self.cl, &adc, theta, omega)
                    }
                    Frame::Command { angle, omega_e } => {
                        self.cl.set_measured_decoupling(false);
                        let d = self.sup.run_step(&mut self.cl, &adc, angle, omega_e);
                        self.damping.tick(self.cl.v_ab);
                        d
                    }
                }
            };
            if self.sup.protect(&self.cl) {
                // The fast protection (`CurrentSupervisor::protect`): off in this period.
                hw.disable_outputs();
                self.bridges_on = false;
            } else {
                hw.set_duties(d);
            }
            // For the stall detection's servo-period means (four additions, outside
            // `CurrentLoop::step`).
            self.v_sum.d += self.cl.v_dq.d;
            self.v_sum.q += self.cl.v_dq.q;
            self.i_sum.d += self.cl.i_dq.d;
            self.i_sum.q += self.cl.i_dq.q;
        } else {
            if self.bridges_on {
                hw.disable_outputs();
                self.bridges_on = false;
            }
            self.sup.idle();
            // Keep the measurements fresh for the drive (and the protection watching).
            self.cl.voltage_step(&adc, 0.0, 0.0);
            self.sup.protect(&self.cl);
        }
    }

    /// The brake output is released (as last written to [`ControlHw::set_brake_released`]).
    pub fn brake_released(&self) -> bool {
        self.brake.released()
    }

    /// The servo period: the command's news, the motion layer's step, the latches and
    /// the measurements for the drive.
    fn servo_step<H: ControlHw>(&mut self, hw: &mut H, cmd: Option<&ControlCommand>) -> Feedback {
        self.sup.permit_tune(cmd.is_some_and(|k| k.tune_allowed));
        if let Some(k) = cmd {
            self.take_command(k);
        }
        let k = 1.0 / f32::from(SERVO_DIVIDER);
        let fb = crate::motion::Feedback {
            position: self.enc.position(),
            velocity: self.enc.velocity(),
            electrical_angle: self.enc.electrical_angle(),
            voltage_limited: self.cl.saturated,
            v_dq: Dq {
                d: self.v_sum.d * k,
                q: self.v_sum.q * k,
            },
            i_dq: Dq {
                d: self.i_sum.d * k,
                q: self.i_sum.q * k,
            },
        };
        self.v_sum = Dq::default();
        self.i_sum = Dq::default();
        let step = if self.sup.tuning() {
            self.motion.step_held(&fb)
        } else {
            self.motion.step(&fb, self.enc.raw_electrical_angle())
        };
        self.reference = step.reference;
        self.damp_open_loop();
        // The first power request with 0x2013 = 0 starts the phase check.
        self.sup.request_power(self.reference.power);
        if let Some(offset) = step.offset {
            self.enc.set_electrical_offset(offset);
        }
        if let Some(z) = hw.take_index_capture() {
            self.index_pulse(z);
        }
        self.probe_latches(hw);
        let mut axis = crate::motion::AxisState::default();
        self.motion.motion().fill_axis_state(&mut axis);
        // CiA 402 transition 4 waits while the closed loop still needs its alignment.
        axis.commutation_pending = self.motion.enable_pending();
        let milliamps = |a: f32| (a * 1000.0).clamp(-32000.0, 32000.0) as i16;
        axis.ia_ma = milliamps(self.cl.i_ab.alpha);
        axis.ib_ma = milliamps(self.cl.i_ab.beta);
        self.motion.motion().fill_measured_torque(&mut axis);
        axis.bus_mv = (self.cl.vbus * 1000.0).clamp(0.0, 1.0e6) as u32;
        axis.electrical_angle = (self.enc.electrical_angle().0 >> 16) as u16;
        if cmd.is_some_and(|k| k.trace) {
            hw.trace(&ServoPoint::of(&axis));
        }
        Feedback {
            axis,
            bridges_on: self.bridges_on,
            index_seq: self.index_seq,
            index_units: self.index_units,
            probe1: self.probe1,
            probe2: self.probe2,
            aligned: self.motion.state() == Commutation::Aligned,
            align_failures: self.motion.failures(),
            current: self.sup.report(),
        }
    }

    /// A command's news: a new configuration, the offsets, a new cycle's set-points.
    fn take_command(&mut self, k: &ControlCommand) {
        if k.config != self.seen_config {
            self.seen_config = k.config;
            self.motion.configure(k.motion, k.align_wiggle);
            self.damping.set_gain(k.motion.damping_s);
            if k.supervisor != *self.sup.config() {
                self.sup.configure(k.supervisor);
            }
        }
        if let Some((a, b)) = k.offsets {
            // One owner of the offsets: the start-up calibration plus the tune's
            // trim, the one 0x2022 reports (`crate::current_supervisor`).
            let cfg = self.cl.config().sense;
            let t = self.sup.offset_trim(cfg.amps_per_count);
            let (a, b) = (a + t[0], b + t[1]);
            if cfg.offset_a != a || cfg.offset_b != b {
                self.cl.set_offsets(a, b);
            }
        }
        if k.cycle != self.seen_cycle {
            self.seen_cycle = k.cycle;
            self.motion.set_command(&k.motion_command(), k.cycle_s);
        }
    }

    /// Open loop: the anti-resonance correction of the command angle (`foc::damping`),
    /// from the currents and voltages of the last servo period. Otherwise, and with
    /// the bridges off, the estimate restarts.
    fn damp_open_loop(&mut self) {
        match &mut self.reference.frame {
            Frame::Command { angle, omega_e } if self.bridges_on => {
                let r = self.sup.tuned_resistance().unwrap_or(self.motor_r);
                self.damping.set_motor(r, self.cl.config().inductance);
                *angle = angle.wrapping_add(self.damping.update(self.cl.i_ab, *omega_e));
            }
            _ => self.damping.reset(),
        }
    }

    /// Axis position (command units) at a latched encoder count.
    fn units_at(&self, latched: u32) -> i32 {
        let m = self.motion.motion();
        units_at_count(
            m.config(),
            m.position_units(),
            self.raw.wrapping_sub(latched) as i32,
        )
    }

    /// Touch-probe latches of this servo period → command units.
    fn probe_latches<H: ControlHw>(&mut self, hw: &mut H) {
        if let Some((count, to_active)) = hw.take_probe1_capture() {
            let u = self.units_at(count);
            self.probe1.record(to_active, u);
        }
        if let Some(raw) = hw.probe2() {
            let (to_active, to_inactive) = raw.take_new(&mut self.probe2_seen);
            if let Some(n) = to_active {
                let u = self.units_at(n);
                self.probe2.record(true, u);
            }
            if let Some(n) = to_inactive {
                let u = self.units_at(n);
                self.probe2.record(false, u);
            }
        }
    }

    /// An index pulse latched count `z`: the axis position at that instant is the
    /// present position minus the counts moved since, in command units.
    fn index_pulse(&mut self, z: u32) {
        self.enc.on_index(z as u16);
        if self.motion.motion().config().counts_per_rev == 0 {
            return;
        }
        self.index_units = self.units_at(z);
        self.index_seq = self.index_seq.wrapping_add(1);
    }
}

#[cfg(test)]
mod tests;
