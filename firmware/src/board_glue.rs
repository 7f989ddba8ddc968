//! The glue between the drive application ([`Drive`]) and the motor-control path: what
//! the board's tasks (`firmware/src/main.rs`) and the simulator
//! (`tests-host/src/sim_drive.rs`) do with the control path's measurements before a
//! drive step, and what they hand back to it after one.
//!
//! Chip-independent: the hardware readings come in as plain values (the published
//! [`Feedback`], the break latch), and what the hardware must do goes out as return
//! values (publish this [`ControlCommand`], re-arm the break). The board's `hw` modules
//! only move those values to and from the registers.
//!
//! * [`BoardGlue::update_axis`] — measurements → [`Drive::set_axis`]: an index pulse
//!   is kept pending until a drive step has consumed it; touch-probe edges become
//!   rising/falling edges per 0x2154 (bit 0: IN1, bit 1: IN2, [`ProbeInput`]) and are
//!   kept the same way; a newly counted failed commutation alignment is noted for
//!   [`BoardGlue::raise_board_faults`]; the current-loop supervisor's report (auto-tune,
//!   "current does not follow") is forwarded once the control path has published.
//! * [`BoardGlue::publish`] — the drive's step → the [`ControlCommand`]: a new
//!   interpolation segment per change of [`Drive::steps`], the power permission
//!   ([`Drive::power_permission`]), the auto-tune permission (only with passed
//!   current-sensor offsets), the scope's servo-rate trace, `drive_enabled` masked by
//!   the power permission.
//! * [`BoardGlue::over_current`] / [`BoardGlue::break_rearmed`] — break latch ↔ fault
//!   1 (over-current): the latch is reported through `AxisState::overcurrent_trip`;
//!   the break is re-armed only once the drive holds the fault and the command that
//!   withdraws the power permission has been published.
//! * [`BoardGlue::raise_board_faults`] — a failed start-up offset check is the current-sensing fault
//!   (phase sensing, 0x5210) at every tick until restart; each failed commutation
//!   alignment is one following-error fault (0x8611).
//!
//! [`Exchange`] is the one lock-free latest-value cell between the control interrupt
//! and the rest (a double buffer with a sequence number: a seqlock).
use core::cell::UnsafeCell;
use core::mem::MaybeUninit;
use core::sync::atomic::{compiler_fence, AtomicU32, Ordering};

use crate::cia402::DriveCommand;
use crate::current_supervisor::{CurrentReport, SupervisorConfig};
use crate::drive::{AxisState, Drive, ParameterStore};
use crate::faults::{FaultKind, Snapshot};
use crate::latch::{Edges, ProbeInput};
use crate::motion::MotionConfig;
use crate::params::P;

/// What the drive side tells the control path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlCommand {
    /// Incremented once per drive step (a new set-point for the interpolation).
    pub cycle: u32,
    /// The drive's set-points of that step (`drive_enabled` cleared while the power
    /// is not permitted).
    pub command: DriveCommand,
    /// Length of the interpolation segment, s ([`Drive::segment_s`]).
    pub cycle_s: f32,
    /// Power stage requested and no power-cutting fault active
    /// ([`Drive::power_permission`]).
    pub power_allowed: bool,
    /// Incremented when [`Self::motion`], [`Self::align_wiggle`] or
    /// [`Self::supervisor`] changed (parameter write, power-up load).
    pub config: u32,
    /// Motion configuration from the parameters.
    pub motion: MotionConfig,
    /// Alignment with the wiggle (0x2083 = 1); applied with [`Self::motion`].
    pub align_wiggle: bool,
    /// Current-sensor offsets (counts) once the start-up check passed.
    pub offsets: Option<(f32, f32)>,
    /// Current-loop supervision (auto-tune 0x2013, test current); applied with
    /// [`Self::motion`].
    pub supervisor: SupervisorConfig,
    /// The drive permits the power-up auto-tune ([`Drive::tune_permitted`]) and the
    /// offsets passed.
    pub tune_allowed: bool,
    /// The scope records at the servo rate ([`Drive::scope_wants_servo_points`]): hand
    /// over a [`crate::scope::ServoPoint`] every servo period.
    pub trace: bool,
    /// The runtime's brake decision (0x2157 bit 8, [`BoardGlue::set_brake_released`]):
    /// the control path releases the pin only with it and its bridges on, and engages
    /// it in the period its bridges go off (`crate::power_gate::BrakeOut`).
    pub brake_released: bool,
}

impl ControlCommand {
    /// The control path may switch the bridges on for the drive: the drive permits the
    /// power stage and the current-sensor offsets passed their start-up check (one
    /// input of `crate::power_gate::bridge_mode`).
    pub fn permits_power(&self) -> bool {
        self.power_allowed && self.offsets.is_some()
    }

    /// The set-points for the motion layer: `drive_enabled` only with the power
    /// permitted.
    pub fn motion_command(&self) -> DriveCommand {
        let mut c = self.command;
        c.drive_enabled &= self.power_allowed;
        c
    }
}

/// What the control path measured (published at the servo rate).
#[derive(Debug, Clone, Copy, Default)]
pub struct Feedback {
    /// Position / velocity / following error / current limit / torque current, as
    /// `Motion::fill_axis_state` writes them. The index, probe and over-current fields
    /// are filled in by [`BoardGlue::update_axis`].
    pub axis: AxisState,
    /// The bridges are switched on.
    pub bridges_on: bool,
    /// Incremented at each encoder index pulse.
    pub index_seq: u32,
    /// Axis position at the last index pulse, command units.
    pub index_units: i32,
    /// Touch probe 1 (IN1): positions at the electrical edges, command units.
    pub probe1: Edges<i32>,
    /// Touch probe 2 (IN2): positions at the electrical edges, command units.
    pub probe2: Edges<i32>,
    /// The commutation offset is known (closed loop available).
    pub aligned: bool,
    /// Failed commutation alignments since start (wrapping).
    pub align_failures: u32,
    /// The current-loop supervisor's report for [`Drive::current_report`].
    pub current: CurrentReport,
}

/// The drive side's glue state (see the module docs).
#[derive(Debug, Clone, Copy)]
pub struct BoardGlue {
    /// The last command handed to the control path.
    ctl: ControlCommand,
    /// [`Drive::steps`] when the last command was built.
    seen_steps: u32,
    /// The break latch was reported to the drive as an over-current fault.
    oc_reported: bool,
    /// The start-up offset self-check failed (the current-sensing fault, kept until restart).
    offset_fault: bool,
    /// Index pulses seen (`Feedback::index_seq`) and one not yet given to a step.
    index_seen: u32,
    pending_index: Option<i32>,
    /// Touch-probe edges not yet given to a step.
    probe1: ProbeInput,
    probe2: ProbeInput,
    /// Failed commutation alignments already seen, and one not yet raised as a fault.
    align_failures: u32,
    align_fault: bool,
    /// The runtime's brake-close hold ([`BoardGlue::set_hold`]).
    hold: Option<DriveCommand>,
}

impl BoardGlue {
    /// Glue whose first command is `ctl` (the control path's start configuration); no
    /// step seen yet, no latch pending, no board fault.
    pub fn new(ctl: ControlCommand) -> Self {
        BoardGlue {
            ctl,
            seen_steps: 0,
            oc_reported: false,
            offset_fault: false,
            index_seen: 0,
            pending_index: None,
            probe1: ProbeInput::default(),
            probe2: ProbeInput::default(),
            align_failures: 0,
            align_fault: false,
            hold: None,
        }
    }

    /// The command as last built by [`BoardGlue::publish`] (or given to `new`).
    pub fn command(&self) -> &ControlCommand {
        &self.ctl
    }

    /// The start-up current-sensor check passed with these offsets (counts): the
    /// control path may use the bridges (and the auto-tune) from the next command on.
    pub fn offsets_passed(&mut self, ia: f32, ib: f32) {
        self.ctl.offsets = Some((ia, ib));
    }

    /// The start-up current-sensor check failed: the current-sensing fault at every
    /// [`BoardGlue::raise_board_faults`] until restart.
    pub fn offset_check_failed(&mut self) {
        self.offset_fault = true;
    }

    /// New motion / alignment / supervision configuration from the parameters; the
    /// control path applies it when it changed (the configuration number moves).
    pub fn configure(&mut self, motion: MotionConfig, wiggle: bool, sup: SupervisorConfig) {
        let c = &mut self.ctl;
        if motion != c.motion || wiggle != c.align_wiggle || sup != c.supervisor {
            c.motion = motion;
            c.align_wiggle = wiggle;
            c.supervisor = sup;
            c.config = c.config.wrapping_add(1);
        }
    }

    /// Hands the control path's measurements to the drive (before a step). `seq`: the
    /// publication's sequence number (0: nothing published yet, so the initial report
    /// is not forwarded: it would end the drive's power-up self-test before the tune
    /// could start); `break_latched`: the power stage's over-current latch. Returns the
    /// axis state given to [`Drive::set_axis`].
    pub fn update_axis<S: ParameterStore>(
        &mut self,
        drive: &mut Drive<S>,
        seq: u32,
        fb: &Feedback,
        break_latched: bool,
    ) -> AxisState {
        if seq != 0 {
            drive.current_report(&fb.current);
        }
        let mut axis = fb.axis;
        axis.overcurrent_trip = break_latched;
        if fb.index_seq != self.index_seen {
            self.index_seen = fb.index_seq;
            self.pending_index = Some(fb.index_units);
        }
        // Kept until a drive step has seen it (cleared in `publish`).
        axis.index = self.pending_index;
        let inverted = drive.params.get(P::InputPolarity);
        axis.probe1 = self.probe1.update(&fb.probe1, inverted & 1 != 0);
        axis.probe2 = self.probe2.update(&fb.probe2, inverted & 2 != 0);
        if fb.align_failures != self.align_failures {
            self.align_failures = fb.align_failures;
            self.align_fault = true;
        }
        drive.set_axis(axis);
        axis
    }

    /// While `Some`, the power authority (`runtime`) keeps the motor holding
    /// through the brake-close delay: every [`BoardGlue::publish`] sends these
    /// set-points with the power permitted, whatever the drive's step says, and no
    /// auto-tune.
    pub fn set_hold(&mut self, hold: Option<DriveCommand>) {
        self.hold = hold;
    }

    /// The runtime's brake decision, carried by every command from now on
    /// ([`ControlCommand::brake_released`]).
    pub fn set_brake_released(&mut self, released: bool) {
        self.ctl.brake_released = released;
    }

    /// The command for the control path after the drive may have stepped: a new
    /// step ([`Drive::steps`] moved) starts a new interpolation segment of
    /// [`Drive::segment_s`] and ends the pending index and probe latches; the power and
    /// tune permissions are refreshed every time.
    pub fn publish<S: ParameterStore>(&mut self, drive: &Drive<S>) -> &ControlCommand {
        if drive.steps() != self.seen_steps {
            self.seen_steps = drive.steps();
            self.pending_index = None;
            self.probe1.consumed();
            self.probe2.consumed();
            self.ctl.cycle = self.ctl.cycle.wrapping_add(1);
            self.ctl.command = *drive.command();
            self.ctl.cycle_s = drive.segment_s();
        }
        self.ctl.power_allowed = drive.power_permission();
        self.ctl.tune_allowed = drive.tune_permitted() && self.ctl.offsets.is_some();
        self.ctl.trace = drive.scope_wants_servo_points();
        if let Some(hold) = self.hold {
            self.ctl.command = hold;
            self.ctl.power_allowed = true;
            self.ctl.tune_allowed = false;
        } else if !self.ctl.power_allowed {
            self.ctl.command.drive_enabled = false;
        }
        &self.ctl
    }

    /// The break latch (hardware over-current) against the drive's over-current fault. A new
    /// latch is noted (the drive sees it as `AxisState::overcurrent_trip` through
    /// [`BoardGlue::update_axis`] and latches the fault). Once the drive holds the
    /// fault, returns the command to publish before the break may be re-armed: it
    /// withdraws the power permission. The caller publishes it, tries to re-arm and
    /// reports success with [`BoardGlue::break_rearmed`]. `None`: do not re-arm.
    pub fn over_current<S: ParameterStore>(
        &mut self,
        drive: &mut Drive<S>,
        break_latched: bool,
    ) -> Option<&ControlCommand> {
        if !break_latched {
            return None;
        }
        if !self.oc_reported {
            self.oc_reported = true;
            return None;
        }
        if !drive.faults.is_active(FaultKind::OverCurrent) {
            return None;
        }
        let cmd = self.publish(drive);
        // The fault cuts the power; re-arm only with the permission withdrawn.
        (!cmd.power_allowed && !cmd.command.drive_enabled).then_some(&self.ctl)
    }

    /// The break was re-armed (its inputs are inactive again): the over-current
    /// condition is gone, so a fault reset clears the drive's over-current fault.
    pub fn break_rearmed<S: ParameterStore>(&mut self, drive: &mut Drive<S>) {
        if self.oc_reported {
            self.oc_reported = false;
            drive.faults.condition_gone(FaultKind::OverCurrent);
        }
    }

    /// The board's own faults, once per 1 ms tick (`now_ms`: the drive's clock): the
    /// failed start-up offset check (the current-sensing fault, at every tick: it cannot be reset), and
    /// a following-error fault (0x8611) once per newly failed commutation alignment.
    pub fn raise_board_faults<S: ParameterStore>(&mut self, drive: &mut Drive<S>, now_ms: u32) {
        if self.offset_fault {
            // Not maskable: the bridges stay blocked without a passed check.
            drive
                .faults
                .raise_unmaskable(FaultKind::PhaseSensing, Snapshot::default(), now_ms);
        }
        if core::mem::take(&mut self.align_fault) {
            drive
                .faults
                .raise(FaultKind::FollowingError, Snapshot::default(), now_ms);
        }
    }
}

/// Latest-value double buffer with a sequence number (a seqlock), for a single core
/// where the writer and the readers are interrupt levels of one another.
///
/// The writer fills the buffer the readers are not pointed at and publishes it with
/// one atomic store of the sequence number. A reader that the writer cannot preempt
/// always reads a complete buffer; a reader that the writer can preempt re-reads the
/// sequence number after the copy and retries when two publications went by (its
/// buffer may have been rewritten), so it never returns a torn value.
pub struct Exchange<T: Copy> {
    seq: AtomicU32,
    bufs: [UnsafeCell<T>; 2],
}

// SAFETY: the cells are shared between execution contexts of one core; the protocol
// (one writer at a time — `write` is `unsafe` for that; readers validate the sequence)
// keeps every returned value whole.
unsafe impl<T: Copy + Send> Sync for Exchange<T> {}

/// Read attempts before a reader gives up on a writer that keeps publishing.
const READ_ATTEMPTS: u32 = 4;

impl<T: Copy> Exchange<T> {
    /// A cell holding `v` in both buffers (sequence 0).
    pub const fn new(v: T) -> Self {
        Exchange {
            seq: AtomicU32::new(0),
            bufs: [UnsafeCell::new(v), UnsafeCell::new(v)],
        }
    }

    /// A cell of zero bytes (sequence 0): a static of it lives in .bss instead of
    /// holding an initialised image in flash. The compiler rejects a `T` for which
    /// zero bytes are not a valid value (const evaluation), so an early read sees
    /// zeros, never an invalid value; [`Exchange::reset`] gives the cell its start value.
    pub const fn zeroed() -> Self {
        // The inline `const` block is evaluated at compile time for every `T` this is
        // instantiated with, also when `zeroed` itself is called at run time; there a
        // zero `T` that is not a valid value fails the build.
        // SAFETY: compile-time evaluation rejects an invalid zero value (above).
        let v: T = const { unsafe { core::mem::zeroed() } };
        Self::new(v)
    }

    /// Sets both buffers to `v` and the sequence to 0 (as [`Exchange::new`]).
    ///
    /// # Safety
    /// Nothing may read or write the cell meanwhile (start-up, before the interrupt
    /// and the tasks that use it run).
    pub unsafe fn reset(&self, v: T) {
        // SAFETY: exclusive access (the caller's contract).
        unsafe {
            *self.bufs[0].get() = v;
            *self.bufs[1].get() = v;
        }
        self.seq.store(0, Ordering::Release);
    }

    /// As [`Exchange::reset`] with `v` = the zero value changed by `set`, written in
    /// place (a large constant `v` would be an image in flash, copied twice). As for
    /// [`Exchange::zeroed`], a `T` for which zero bytes are not a valid value does not
    /// compile.
    ///
    /// # Safety
    /// As [`Exchange::reset`].
    pub unsafe fn reset_then(&self, set: impl Fn(&mut T)) {
        for b in &self.bufs {
            // SAFETY: exclusive access (the caller's contract); a zero `T` that is not
            // a valid value is a compile-time error (const evaluation).
            unsafe {
                b.get().write(const { core::mem::zeroed() });
                set(&mut *b.get());
            }
        }
        self.seq.store(0, Ordering::Release);
    }

    /// Publishes `v`.
    ///
    /// # Safety
    /// One writer at a time: no other `write`, `reset` or `reset_then` of this cell
    /// may run meanwhile (on the board: a single writing context, or writers that
    /// exclude one another by a lock).
    pub unsafe fn write(&self, v: T) {
        let next = self.seq.load(Ordering::Relaxed).wrapping_add(1);
        // SAFETY: buffer `next & 1` is not the published one and no other writer
        // touches it (the caller's contract); a reader that still holds it validates
        // the sequence afterwards.
        unsafe { core::ptr::write_volatile(self.bufs[(next & 1) as usize].get(), v) };
        compiler_fence(Ordering::Release);
        self.seq.store(next, Ordering::Release);
    }

    /// Publications so far (wrapping; 0: none since `new` / `reset`).
    pub fn sequence(&self) -> u32 {
        self.seq.load(Ordering::Acquire)
    }

    /// The latest value and its sequence number; `None` only when the writer kept
    /// publishing during four attempts.
    pub fn read(&self) -> Option<(u32, T)> {
        for _ in 0..READ_ATTEMPTS {
            let s = self.seq.load(Ordering::Acquire);
            compiler_fence(Ordering::Acquire);
            // SAFETY: a `T` is always there (initialised by the constructor); whether
            // it was being rewritten is checked below.
            let v = unsafe { core::ptr::read_volatile(self.bufs[(s & 1) as usize].get()) };
            compiler_fence(Ordering::Acquire);
            // At most one more publication, into the other buffer: ours is intact.
            if self.seq.load(Ordering::Acquire).wrapping_sub(s) < 2 {
                return Some((s, v));
            }
        }
        None
    }

    /// As [`Exchange::read`], but the copy is a loop over 32-bit words instead of an
    /// unrolled copy of the whole value: a few instructions of flash for readers of a
    /// large `T` where the speed does not matter.
    pub fn read_looped(&self) -> Option<(u32, T)> {
        const {
            assert!(size_of::<T>().is_multiple_of(4) && align_of::<T>() >= 4);
        }
        for _ in 0..READ_ATTEMPTS {
            let s = self.seq.load(Ordering::Acquire);
            compiler_fence(Ordering::Acquire);
            let mut v = MaybeUninit::<T>::uninit();
            let src = self.bufs[(s & 1) as usize].get() as *const MaybeUninit<u32>;
            let dst = v.as_mut_ptr() as *mut MaybeUninit<u32>;
            for i in 0..size_of::<T>() / 4 {
                // SAFETY: both point to a `T`, whose size is a multiple of 4 and whose
                // alignment is at least 4 (checked above); words of `MaybeUninit` may
                // hold the padding bytes.
                unsafe { dst.add(i).write(src.add(i).read_volatile()) };
            }
            compiler_fence(Ordering::Acquire);
            if self.seq.load(Ordering::Acquire).wrapping_sub(s) < 2 {
                // SAFETY: every byte of a `T` that was not being rewritten (see `read`).
                return Some((s, unsafe { v.assume_init() }));
            }
        }
        None
    }
}
