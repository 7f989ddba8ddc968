//! The motor-control path inside the current-loop interrupt (`ADC1_2`, `firmware::irq_priority::CURRENT_LOOP`)
//! and the lock-free exchange with the cyclic path.
//!
//! Every PWM period (40 kHz) [`on_sample`] publishes the raw sample ([`SAMPLES`]:
//! offset self-check, status line, watchdog sign of life) and runs
//! `firmware::control_core::ControlCore::period` with [`BoardHw`]: encoder update, at
//! the servo rate (10 kHz) the command, the motion layer, the latches and the
//! measurements for the drive ([`FEEDBACK`]), then the bridge decision and the
//! current loop. Every decision is the library's (host- and QEMU-tested); this
//! module holds the static cells and the register access of [`BoardHw`].
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
//! short: the rows "servo step (motion layer)", "motion set_command" and "current loop
//! step" of BENCHMARKS.md (QEMU instruction counts) add up to well under a thousand
//! instructions per servo period, a few µs at 170 MHz before memory wait states, to be
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
//! The brake pin (PB9) is this interrupt's alone (`firmware::power_gate::BrakeOut`,
//! [`BoardHw`] writes the register): released only while the command carries the
//! runtime's decision ([`ControlCommand::brake_released`]) and the bridges are on,
//! engaged in the PWM period in which the bridges go off — a lost power stage never
//! waits for the 1 ms tick.
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
use firmware::control_core::{ControlCore, ControlHw, LoopMotor, PowerStageConfig};
use firmware::current_supervisor::{CurrentReport, SupervisorConfig};
use firmware::latch::Edges;
use firmware::motion::MotionConfig;
use firmware::sampling::RawSample;
use firmware::scope::{PointRing, ServoPoint};
use foc::modulation::Duties;

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

/// `touch_probe2` task → interrupt: encoder counts (TIM2) latched at the IN2 edges.
/// One writer (that task, the cyclic level); the interrupt preempts it, never the reverse.
pub static PROBE2_RAW: Exchange<Edges<u32>> = Exchange::new(Edges {
    active_seq: 0,
    active: 0,
    inactive_seq: 0,
    inactive: 0,
});

/// Interrupt → supervision tick: the servo periods' points while the scope records
/// at the servo rate (32 = 3.2 ms, the tick takes them every 1 ms).
static TRACE: PointRing<32> = PointRing::new();

/// Hands the queued servo points to `f`, oldest first (the tick, before the drive's).
pub fn drain_trace(mut f: impl FnMut(&ServoPoint)) {
    while let Some(p) = TRACE.pop() {
        f(&p);
    }
}

/// The control path's view of the board: register access only.
pub struct BoardHw;

impl ControlHw for BoardHw {
    #[inline(always)]
    fn raw_count(&mut self) -> u32 {
        crate::hw::encoder::raw_count()
    }
    #[inline(always)]
    fn command(&mut self) -> Option<ControlCommand> {
        COMMAND.read().and_then(|(_, v)| v)
    }
    #[inline(always)]
    fn take_index_capture(&mut self) -> Option<u32> {
        crate::hw::encoder::take_index_capture()
    }
    #[inline(always)]
    fn take_probe1_capture(&mut self) -> Option<(u32, bool)> {
        crate::hw::encoder::take_probe1_capture()
    }
    #[inline(always)]
    fn probe2(&mut self) -> Option<Edges<u32>> {
        PROBE2_RAW.read().map(|(_, e)| e)
    }
    #[inline(always)]
    fn halted(&self) -> bool {
        crate::hw::safety::HALT.is_halted()
    }
    #[inline(always)]
    fn break_latched(&self) -> bool {
        pwm::break_latched() != 0
    }
    #[inline(always)]
    fn enable_outputs(&mut self) -> bool {
        pwm::enable_outputs()
    }
    #[inline(always)]
    fn disable_outputs(&mut self) {
        pwm::disable_outputs();
    }
    #[inline(always)]
    fn set_brake_released(&mut self, released: bool) {
        crate::hw::io::set_brake_released(released);
    }
    #[inline(always)]
    fn set_duties(&mut self, d: Duties) {
        pwm::set_compare(d.a1, d.a2, d.b1, d.b2);
    }
    #[inline(always)]
    fn trace(&mut self, p: &ServoPoint) {
        TRACE.push(p);
    }
}

struct IsrOwned(UnsafeCell<MaybeUninit<ControlCore>>);
// SAFETY: written once by `init` before the interrupt is enabled, then only touched
// by the interrupt (READY tells it the value is there).
unsafe impl Sync for IsrOwned {}
/// Uninitialised until `init` (kept in .bss, not .data: an `Option` would need an
/// initialised image of the whole state in flash).
static CONTROL: IsrOwned = IsrOwned(UnsafeCell::new(MaybeUninit::uninit()));
static READY: AtomicBool = AtomicBool::new(false);
/// Interrupt → runtime: the bridges as this PWM period left them
/// (`firmware::runtime::ControlPath::bridges_on_now`).
static BRIDGES_ON: AtomicBool = AtomicBool::new(false);

/// Builds the control state. Call once, before the current-loop interrupt is
/// enabled. `motor`: the current loop's motor constants (until an auto-tune
/// replaces them); `wiggle`: 0x2083.
#[inline(never)]
pub fn init(motion: MotionConfig, wiggle: bool, supervisor: SupervisorConfig, motor: LoopMotor) {
    if READY.load(Ordering::Acquire) {
        return;
    }
    // SAFETY: once (checked above), at start-up: the interrupt is not enabled yet and
    // main spawns the tasks that use the cells after `init`.
    unsafe {
        COMMAND.reset(None);
        FEEDBACK.reset_then(feedback_start);
    }
    // SAFETY: the interrupt does not read CONTROL before READY is set, and `init` runs
    // once (checked above), so nothing else references the cell.
    let slot = unsafe { &mut *CONTROL.0.get() };
    slot.write(ControlCore::new(
        PowerStageConfig {
            pwm_hz: board::PWM_HZ,
            pwm_arr: board::PWM_ARR,
            analog: board::ANALOG,
        },
        motor,
        motion,
        wiggle,
        supervisor,
        crate::hw::encoder::raw_count(),
    ));
    READY.store(true, Ordering::Release);
}

/// The control state is installed (the interrupt runs the loops).
pub fn ready() -> bool {
    READY.load(Ordering::Acquire)
}

/// The interrupt's latest measurements and their sequence number, for the thread-mode
/// and cyclic users (one copy of the volatile word-by-word read).
pub fn feedback() -> Option<(u32, Feedback)> {
    FEEDBACK.read_looped()
}

/// The newest current sample and its number (`None` before the first one).
pub fn latest_sample() -> Option<(u32, RawSample)> {
    SAMPLES.read().filter(|&(n, _)| n != 0)
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
    if let Some(fb) = c.period(&mut BoardHw, s) {
        // SAFETY: this interrupt is the one writer of FEEDBACK.
        unsafe { FEEDBACK.write(fb) };
    }
    BRIDGES_ON.store(c.bridges_on(), Ordering::Release);
}

/// The current-loop interrupt and the break latch as the runtime reaches them
/// ([`firmware::runtime::ControlPath`]): register and exchange access only.
pub struct BoardPath;

impl firmware::runtime::ControlPath for BoardPath {
    fn feedback(&mut self) -> Option<(u32, Feedback)> {
        feedback()
    }
    fn break_latched(&self) -> bool {
        crate::hw::pwm::break_latched() != 0
    }
    fn bridges_on_now(&self) -> bool {
        BRIDGES_ON.load(Ordering::Acquire)
    }
    fn send(&mut self, command: &ControlCommand) {
        send_command(command);
    }
    fn rearm_break(&mut self) -> bool {
        crate::hw::pwm::rearm()
    }
    fn drain_trace(&mut self, _wanted: bool, sink: &mut dyn FnMut(&ServoPoint)) {
        // The interrupt traces while the command says so (`ControlCommand::trace`).
        drain_trace(|p| sink(p));
    }
}

/// Publishes a command to the current-loop interrupt (not inlined: one copy of the
/// volatile write for every caller).
// Measured (cargo xtask size, LAN9252 image): dropped with the other hot-path attributes
// the image grew 1184 B (inlined into each caller).
#[inline(never)]
pub fn send_command(c: &ControlCommand) {
    // SAFETY: every caller holds the drive's lock (or runs at start-up before the
    // tasks exist): one writer at a time.
    unsafe { COMMAND.write(Some(*c)) };
}
