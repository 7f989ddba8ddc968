//! The motor-control path inside the current-loop interrupt (`ADC1_2`, priority 0)
//! and the lock-free exchange with the cyclic path.
//!
//! Every PWM period (40 kHz) [`on_sample`] runs, in this order:
//! 1. the raw sample is published ([`SAMPLES`]: offset self-check, status line,
//!    watchdog sign of life);
//! 2. the encoder counter (TIM2) → `foc::encoder::Encoder::update` (position, PLL
//!    velocity, electrical angle);
//! 3. every 4th period (10 kHz = `firmware::motion::SERVO_TS`): the newest
//!    [`ControlCommand`] is read (power permission, offsets; new cycle →
//!    `set_command`, new parameters → `configure`), the motion layer steps
//!    (`firmware::commutation::CommutatedMotion`: `Motion::step`, preceded at the first
//!    closed-loop enable after power-up by the commutation alignment, whose offset goes
//!    into the encoder) → current reference; the index and touch-probe latches are
//!    converted to axis positions (`firmware::latch`), and the measurements for the
//!    drive ([`Feedback`]) are published;
//! 4. the current loop through `firmware::current_supervisor::CurrentSupervisor`
//!    (`run_step`: `foc::current_loop::CurrentLoop::step` plus the "current does not
//!    follow" check, fault 0x5210) → duties → TIM1/TIM8 compare registers, or the
//!    bridges off. While the power-up auto-tune runs (0x2013 = 1, permitted by the
//!    drive: offsets passed, bus voltage in range, no fault) the supervisor drives the
//!    bridges in voltage mode instead (`tune_step`) and the motion layer is held
//!    (`step_held`); the results and a failure (motor open 0x7120) reach the drive in
//!    [`Feedback::current`].
//!
//! Touch probes: probe 1 (IN1) is latched by TIM2 CH4 on both edges in hardware
//! ([`crate::hw::encoder::take_probe1_capture`]: the pin level read with the capture
//! tells the edge); probe 2 (IN2) is latched in software by the `touch_probe2` task
//! (EXTI, both edges) and handed over in [`PROBE2_RAW`]. Both become
//! `firmware::latch::Edges` in command units in [`Feedback`]; the drive side maps them
//! to rising/falling with 0x2154 and feeds the CiA 402 touch probe.
//!
//! A failed alignment (0x2083 = 1: the encoder did not follow the sweep) is counted in
//! [`Feedback::align_failures`]; the drive side raises the following-error fault
//! (0x8611) for it. Until the alignment is done (closed loop) the published
//! `AxisState::commutation_pending` keeps CiA 402 in Switched on: the drive's enable
//! then only runs the alignment, and Operation enabled follows once the motion layer
//! holds the actual position (`firmware::cia402`, transition 4).
//!
//! Motion runs in the same interrupt (not a lower-priority one) because its step is
//! short — 255 instructions for `Motion::step`, 146 for `set_command` once per cycle,
//! 290 for the current step (QEMU instruction counts, BENCHMARKS.md), so a servo
//! period is ≈ 0.8 k instructions ≈ 5 µs at 170 MHz before memory wait states, to be
//! measured (`ISR max` in the status line is the worst period, which is a servo
//! period) — and the current reference must be in place before the next current
//! step; splitting would need another exchange cell and a fourth priority level.
//!
//! The bridges are on only while all of these hold (decided by
//! `firmware::power_gate::bridge_mode`): the drive is not halted by a panic or
//! HardFault (`hw::safety::HALT`, sticky until reset), the drive asks for the power
//! stage (`Drive::power_permission`: the PDS has the voltage enabled and no fault
//! that cuts the power is active, [`ControlCommand::power_allowed`]), the
//! current-sensor offsets passed the start-up check ([`ControlCommand::offsets`]), no
//! break (over-current) is latched, the fast protection has not tripped
//! (`CurrentSupervisor::protect`: a phase current above 10.5 A or a bus above 55 V in
//! any PWM period switches the bridges off in that period, until the drive has
//! withdrawn the permission), and the motion layer wants current
//! (`CurrentReference::power`).
//!
//! What the drive side does with [`Feedback`] and how it builds [`ControlCommand`]
//! (index and probe latches pending until a drive step, probe polarity, alignment
//! failures → fault, power permission) is the library's `firmware::board_glue`.
//!
//! # Exchange (no locks in the interrupt)
//! `firmware::board_glue::Exchange<T>` is a double buffer with a sequence number: the
//! writer fills the buffer the reader is not pointed at and then publishes it with
//! one atomic store. It is the one seqlock of the board:
//! * cyclic path → interrupt ([`COMMAND`]) and `touch_probe2` task → interrupt
//!   ([`PROBE2_RAW`]): the interrupt preempts the writer but is never preempted by
//!   it, so it always reads a complete buffer.
//! * interrupt → cyclic path ([`FEEDBACK`]) and interrupt → everyone ([`SAMPLES`]):
//!   a reader preempted by two publications could see a buffer being rewritten; it re-reads the sequence number afterwards
//!   and retries (a seqlock), so it never uses a torn value.
//!
//! Writers of [`COMMAND`] run under the drive's lock (thread mode and the cyclic
//! executor), so there is one writer at a time.
use core::cell::UnsafeCell;
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicBool, Ordering};

pub use firmware::board_glue::{ControlCommand, Exchange, Feedback};
use firmware::commutation::{CommutatedMotion, Commutation};
use firmware::current_supervisor::{CurrentReport, CurrentSupervisor, SupervisorConfig};
use firmware::latch::{units_at_count, Edges, Seen};
use firmware::motion::{CurrentReference, Frame, MotionConfig};
use firmware::power_gate::{bridge_mode, BridgeMode, GateInputs};
use firmware::sampling::RawSample;
use foc::current_loop::{AdcSample, CurrentLoop, CurrentLoopConfig, Sense};
use foc::encoder::{Encoder, EncoderConfig};
use foc::modulation::Modulator;

use crate::board;
use crate::hw::pwm;

/// Interrupt → everyone: the raw sample of every PWM period (offset self-check,
/// status line, watchdog sign of life: [`Exchange::sequence`] counts the samples).
pub static SAMPLES: Exchange<RawSample> = Exchange::new(RawSample {
    ia: 0,
    ib: 0,
    vbus: 0,
});

/// Cyclic path → interrupt (set-points, configuration, permission). `None` from
/// [`init`] on (zero bytes before: .bss, not an image in flash).
pub static COMMAND: Exchange<Option<ControlCommand>> = Exchange::zeroed();
/// Interrupt → cyclic path (measurements). [`feedback_start`] from [`init`] on (zero
/// bytes before: .bss, not an image in flash).
pub static FEEDBACK: Exchange<Feedback> = Exchange::zeroed();

/// What [`FEEDBACK`] holds until the interrupt publishes, set on the zero value (the
/// numbers 0, the flags `false`; see [`Exchange::reset_then`]): no latches, no tune
/// report, and the motor side not known to be ready.
fn feedback_start(f: &mut Feedback) {
    let no_latch = firmware::cia402::EdgeLatch {
        rising: None,
        falling: None,
    };
    f.axis.index = None;
    f.axis.probe1 = no_latch;
    f.axis.probe2 = no_latch;
    // Nothing published yet: the motor side is not known to be ready.
    f.axis.commutation_pending = true;
    f.current = CurrentReport::NONE;
}

const NO_EDGES: Edges<i32> = Edges {
    active_seq: 0,
    active: 0,
    inactive_seq: 0,
    inactive: 0,
};

/// `touch_probe2` task → interrupt: encoder counts (TIM2) latched at the IN2 edges.
/// One writer (that task, priority 2); the interrupt preempts it, never the reverse.
pub static PROBE2_RAW: Exchange<Edges<u32>> = Exchange::new(Edges {
    active_seq: 0,
    active: 0,
    inactive_seq: 0,
    inactive: 0,
});

/// Current-loop bandwidth, rad/s (2π·f_PWM/20, the design limit of `foc::current_loop`).
const WC: f32 = 2.0 * core::f32::consts::PI * board::PWM_HZ as f32 / 20.0;
/// Encoder PLL natural frequency, rad/s.
const PLL_OMEGA: f32 = 8000.0;
/// Current-loop periods per servo period.
const SERVO_DIVIDER: u8 = 4;

/// State owned by the interrupt.
struct Control {
    cl: CurrentLoop,
    enc: Encoder,
    motion: CommutatedMotion,
    sup: CurrentSupervisor,
    reference: CurrentReference,
    divider: u8,
    seen_cycle: u32,
    seen_config: u32,
    bridges_on: bool,
    /// Power permission of the last command (read at the servo rate).
    permitted: bool,
    /// TIM2 count at the last encoder update.
    raw: u32,
    index_seq: u32,
    index_units: i32,
    probe1: Edges<i32>,
    probe2: Edges<i32>,
    /// Probe-2 latches already converted.
    probe2_seen: Seen,
}

struct IsrOwned(UnsafeCell<MaybeUninit<Control>>);
// SAFETY: written once by `init` before the interrupt is enabled, then only touched
// by the interrupt (READY tells it the value is there).
unsafe impl Sync for IsrOwned {}
/// Uninitialised until `init` (kept in .bss, not .data: an `Option` would need an
/// initialised image of the whole state in flash).
static CONTROL: IsrOwned = IsrOwned(UnsafeCell::new(MaybeUninit::uninit()));
static READY: AtomicBool = AtomicBool::new(false);

/// Builds the control state. Call once, before the current-loop interrupt is
/// enabled. `r_ohm`, `l_h`, `ke`: motor constants for the current-loop gains and
/// feed-forward (until an auto-tune replaces them); `wiggle`: 0x2083.
#[inline(never)]
pub fn init(
    motion: MotionConfig,
    wiggle: bool,
    supervisor: SupervisorConfig,
    encoder_lines: u32,
    r_ohm: f32,
    l_h: f32,
    ke: f32,
) {
    let ts = 1.0 / board::PWM_HZ as f32;
    let (kp, ki) = CurrentLoopConfig::gains_for(r_ohm, l_h, WC);
    let cl = CurrentLoop::new(CurrentLoopConfig {
        ts,
        kp,
        ki,
        inductance: l_h,
        ke,
        latency: 1.5,
        sense: Sense {
            amps_per_count: board::ANALOG.amps_per_count,
            offset_a: f32::from(board::ANALOG.offset_nominal),
            offset_b: f32::from(board::ANALOG.offset_nominal),
            volts_per_count: board::ANALOG.volts_per_count,
        },
        modulator: Modulator::new(board::PWM_ARR),
    });
    let enc = Encoder::new(
        EncoderConfig {
            lines: encoder_lines.max(1),
            ts,
            pll_omega: PLL_OMEGA,
        },
        crate::hw::encoder::raw_count() as u16,
    );
    if READY.load(Ordering::Acquire) {
        return;
    }
    // SAFETY: once (checked above), at start-up: the interrupt is not enabled yet and
    // main spawns the tasks that use the cells after `init`.
    unsafe {
        COMMAND.reset(None);
        FEEDBACK.reset_then(feedback_start);
    }
    // One whole-struct write (a struct literal: a field added to `Control` and not
    // given a value here does not compile).
    // SAFETY: the interrupt does not read CONTROL before READY is set, and `init` runs
    // once (checked above), so nothing else references the cell.
    let slot = unsafe { &mut *CONTROL.0.get() };
    slot.write(Control {
        cl,
        enc,
        motion: CommutatedMotion::new(motion, wiggle),
        sup: CurrentSupervisor::new(supervisor),
        reference: CurrentReference::OFF,
        divider: 0,
        seen_cycle: 0,
        seen_config: 0,
        bridges_on: false,
        permitted: false,
        raw: crate::hw::encoder::raw_count(),
        index_seq: 0,
        index_units: 0,
        probe1: NO_EDGES,
        probe2: NO_EDGES,
        probe2_seen: Seen::default(),
    });
    READY.store(true, Ordering::Release);
}

/// The control state is installed (the interrupt runs the loops).
pub fn ready() -> bool {
    READY.load(Ordering::Acquire)
}

/// One PWM period (called by the `ADC1_2` interrupt with the fresh sample).
#[inline(always)]
pub fn on_sample(s: RawSample) {
    // SAFETY: this interrupt is the one writer of SAMPLES.
    unsafe { SAMPLES.write(s) };
    if !READY.load(Ordering::Acquire) {
        pwm::disable_outputs();
        return;
    }
    // SAFETY: initialised (READY), and only this interrupt touches it from then on.
    let c = unsafe { (*CONTROL.0.get()).assume_init_mut() };
    c.raw = crate::hw::encoder::raw_count();
    c.enc.update(c.raw as u16);

    c.divider += 1;
    if c.divider >= SERVO_DIVIDER {
        c.divider = 0;
        // The command is read at the servo rate: a withdrawn permission switches the
        // bridges off within 100 µs (an over-current does so in hardware at once).
        let cmd = COMMAND.read().and_then(|(_, v)| v);
        c.permitted = cmd.as_ref().is_some_and(ControlCommand::permits_power);
        if !c.permitted {
            // The drive has withdrawn the power (it took the trip's fault): re-armed.
            c.sup.rearm();
        }
        servo_step(c, cmd.as_ref());
    }

    // The bridge decision is the library's (`firmware::power_gate`): never on while
    // halted (panic / HardFault) or with a latched break.
    let mode = bridge_mode(GateInputs {
        halted: crate::hw::safety::HALT.is_halted(),
        break_latched: pwm::break_latched() != 0,
        tripped: c.sup.tripped(),
        tuning: c.sup.tuning(),
        permitted: c.permitted,
        power_wanted: c.reference.power,
    });
    let adc = AdcSample {
        ia: s.ia,
        ib: s.ib,
        vbus: s.vbus,
    };
    if mode != BridgeMode::Off {
        if !c.bridges_on {
            c.cl.reset();
            c.bridges_on = pwm::enable_outputs();
        }
        let d = if mode == BridgeMode::Tune {
            // Power-up auto-tune: voltage mode, the motion layer is held.
            c.sup.tune_step(&mut c.cl, &adc)
        } else {
            if c.reference.reset {
                c.cl.reset();
                c.reference.reset = false;
            }
            c.cl.id_ref = c.reference.id;
            c.cl.iq_ref = c.reference.iq;
            let (theta, omega) = match c.reference.frame {
                Frame::Encoder => (c.enc.electrical_angle(), c.enc.omega_e()),
                Frame::Command { angle, omega_e } => (angle, omega_e),
            };
            c.sup.run_step(&mut c.cl, &adc, theta, omega)
        };
        if c.sup.protect(&c.cl) {
            // The fast protection (`CurrentSupervisor::protect`): off in this period.
            pwm::disable_outputs();
            c.bridges_on = false;
        } else {
            pwm::set_compare(d.a1, d.a2, d.b1, d.b2);
        }
    } else {
        if c.bridges_on {
            pwm::disable_outputs();
            c.bridges_on = false;
        }
        c.sup.idle();
        // Keep the measurements fresh for the drive (and the protection watching).
        c.cl.voltage_step(&adc, 0.0, 0.0);
        c.sup.protect(&c.cl);
    }
}

fn servo_step(c: &mut Control, cmd: Option<&ControlCommand>) {
    c.sup.permit_tune(cmd.is_some_and(|k| k.tune_allowed));
    if let Some(k) = cmd {
        if k.config != c.seen_config {
            c.seen_config = k.config;
            c.motion.configure(k.motion, k.align_wiggle);
            if k.supervisor != *c.sup.config() {
                c.sup.configure(k.supervisor);
            }
        }
        if let Some((a, b)) = k.offsets {
            let cfg = c.cl.config().sense;
            if cfg.offset_a != a || cfg.offset_b != b {
                c.cl.set_offsets(a, b);
            }
        }
        if k.cycle != c.seen_cycle {
            c.seen_cycle = k.cycle;
            c.motion.set_command(&k.motion_command(), k.cycle_s);
        }
    }
    let fb = firmware::motion::Feedback {
        position: c.enc.position(),
        velocity: c.enc.velocity(),
        electrical_angle: c.enc.electrical_angle(),
        voltage_limited: c.cl.saturated,
    };
    let step = if c.sup.tuning() {
        c.motion.step_held(&fb)
    } else {
        c.motion.step(&fb, c.enc.raw_electrical_angle())
    };
    c.reference = step.reference;
    if let Some(offset) = step.offset {
        c.enc.set_electrical_offset(offset);
    }
    if let Some(z) = crate::hw::encoder::take_index_capture() {
        index_pulse(c, z);
    }
    probe_latches(c);
    let mut axis = firmware::drive::AxisState::default();
    c.motion.motion().fill_axis_state(&mut axis);
    // CiA 402 transition 4 waits while the closed loop still needs its alignment.
    axis.commutation_pending = c.motion.enable_pending();
    let ma = |a: f32| (a * 1000.0).clamp(-32000.0, 32000.0) as i16;
    axis.ia_ma = ma(c.cl.i_ab.alpha);
    axis.ib_ma = ma(c.cl.i_ab.beta);
    axis.bus_mv = (c.cl.vbus * 1000.0).clamp(0.0, 1.0e6) as u32;
    axis.electrical_angle = (c.enc.electrical_angle().0 >> 16) as u16;
    let fb = Feedback {
        axis,
        bridges_on: c.bridges_on,
        index_seq: c.index_seq,
        index_units: c.index_units,
        probe1: c.probe1,
        probe2: c.probe2,
        aligned: c.motion.state() == Commutation::Aligned,
        align_failures: c.motion.failures(),
        current: c.sup.report(),
    };
    // SAFETY: this interrupt is the one writer of FEEDBACK.
    unsafe { FEEDBACK.write(fb) };
}

/// Axis position (command units) at a latched TIM2 count.
fn units_at(c: &Control, latched: u32) -> i32 {
    let m = c.motion.motion();
    units_at_count(
        m.config(),
        m.position_units(),
        c.raw.wrapping_sub(latched) as i32,
    )
}

/// Touch-probe latches of this servo period → command units.
fn probe_latches(c: &mut Control) {
    if let Some((count, to_active)) = crate::hw::encoder::take_probe1_capture() {
        let u = units_at(c, count);
        c.probe1.record(to_active, u);
    }
    if let Some((_, raw)) = PROBE2_RAW.read() {
        let (to_active, to_inactive) = raw.take_new(&mut c.probe2_seen);
        if let Some(n) = to_active {
            let u = units_at(c, n);
            c.probe2.record(true, u);
        }
        if let Some(n) = to_inactive {
            let u = units_at(c, n);
            c.probe2.record(false, u);
        }
    }
}

/// An index pulse latched count `z` (TIM2 CH3): the axis position at that instant
/// is the present position minus the counts moved since, in command units.
fn index_pulse(c: &mut Control, z: u32) {
    c.enc.on_index(z as u16);
    if c.motion.motion().config().counts_per_rev == 0 {
        return;
    }
    c.index_units = units_at(c, z);
    c.index_seq = c.index_seq.wrapping_add(1);
}
