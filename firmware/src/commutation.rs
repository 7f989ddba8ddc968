//! Commutation alignment around the motion layer: the closed loop needs the encoder's
//! electrical offset (where electrical angle 0 of the motor lies on the encoder), which
//! an incremental encoder cannot know at power-up. [`CommutatedMotion`] wraps
//! [`Motion`] and runs [`foc::servo::Alignment`] at the first closed-loop enable after
//! power-up, before the motion layer gets control. The board's servo interrupt and the
//! simulation's plant axis use the same code.
//!
//! # Sequence
//! * Closed loop requested (`MotionConfig::closed_loop`), not aligned yet, drive
//!   enabled (`DriveCommand::drive_enabled`) and the motion layer not already running:
//!   the motion layer is held disabled (it keeps tracking the actual position) and the
//!   alignment drives the current: a d current on a commanded angle ramps to the
//!   alignment current ([`align_config`]: the peak current 0x2000), the rotor settles,
//!   and with 0x2083 = 1 ("wiggle") the vector sweeps one electrical turn forward and
//!   back while the encoder is checked to follow. Durations: [`ALIGN_RAMP_S`] +
//!   [`ALIGN_SETTLE_S`] (+ 2 × [`ALIGN_SWEEP_TURNS`] / [`ALIGN_SWEEP_SPEED`] with the
//!   wiggle) = 0.25 s (0.65 s).
//! * Done: [`Step::offset`] carries the offset for
//!   `foc::encoder::Encoder::set_electrical_offset` (the caller sets it before the next
//!   step); the step that finishes still holds the alignment current, the next one
//!   enables the motion layer in closed loop at the actual position (no jump in the
//!   demand; the current loop's integrators are cleared by the enable). The offset is
//!   kept: later enables go straight to the closed loop.
//! * Failed (only detectable with the wiggle: the encoder did not follow the sweep —
//!   wrong direction, wrong line count 0x2029, no encoder, open phase): [`Step::failed`]
//!   is set once and [`CommutatedMotion::failures`] counts up; the caller raises the
//!   drive fault (the board: following error, 0x8611, see `hw::control`). The motion
//!   layer stays disabled, the bridges off; the next enable (after the drive was
//!   disabled, e.g. by the fault) tries again.
//! * The enable withdrawn or the closed loop deselected during the alignment: it is
//!   abandoned (no offset) and runs again at the next closed-loop enable.
//!
//! # Reported to CiA 402
//! [`CommutatedMotion::enable_pending`] (closed loop requested, offset not known) is
//! what the motor side reports as `motion::AxisState::commutation_pending`: the
//! PDS then stays in Switched on while the enable it passes down runs the alignment,
//! and enters Operation enabled once the motion layer holds the actual position in
//! closed loop (see `crate::cia402`, "transition 4 waits for the power stage"). A
//! failed alignment keeps it pending; the fault it raises ends the wait.
//!
//! Until the offset is known the motion layer is configured with the open loop (the
//! requested closed loop is masked), so a switch of 0x2024 to closed loop while
//! enabled in open loop takes effect at the next enable (with the alignment first).
//! Open loop and drives without encoder never align.

use crate::cia402::DriveCommand;
use crate::motion::{CurrentReference, Feedback, Frame, Motion, MotionConfig};
use foc::angle::Angle;
use foc::servo::{AlignConfig, AlignState, Alignment};

/// Ramp of the alignment current, s.
pub const ALIGN_RAMP_S: f32 = 0.05;
/// Time for the rotor to come to rest on the alignment vector, s.
pub const ALIGN_SETTLE_S: f32 = 0.2;
/// Electrical turns swept each way with the wiggle (0x2083 = 1).
pub const ALIGN_SWEEP_TURNS: u32 = 1;
/// Sweep speed, electrical turns per second.
pub const ALIGN_SWEEP_SPEED: f32 = 5.0;

/// The alignment configuration for a motion configuration: the servo period, the peak
/// current 0x2000 as alignment current, the wiggle from 0x2083.
pub fn align_config(cfg: &MotionConfig, wiggle: bool) -> AlignConfig {
    AlignConfig {
        ts: cfg.ts,
        current: if cfg.peak_current.is_finite() {
            cfg.peak_current.max(0.0)
        } else {
            0.0
        },
        ramp: ALIGN_RAMP_S,
        settle: ALIGN_SETTLE_S,
        wiggle,
        sweep_cycles: ALIGN_SWEEP_TURNS,
        sweep_speed: ALIGN_SWEEP_SPEED,
    }
}

/// Where the commutation stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Commutation {
    /// Offset unknown (power-up, or the last alignment was abandoned).
    Unaligned,
    /// The alignment is driving the current.
    Aligning,
    /// Offset known: closed loop available.
    Aligned,
    /// The last alignment failed; retried at the next enable.
    Failed,
}

/// What one servo step produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// The current loop's reference until the next step.
    pub reference: CurrentReference,
    /// The alignment finished in this step: the encoder's electrical offset.
    pub offset: Option<Angle>,
    /// The alignment failed in this step.
    pub failed: bool,
}

/// [`Motion`] with the power-up commutation alignment (see the module docs).
// In declaration order, the motion layer (with its smoothing windows at its end) last,
// for short field offsets (see `Motion`).
#[repr(C)]
pub struct CommutatedMotion {
    requested: MotionConfig,
    state: Commutation,
    align: Alignment,
    cmd: DriveCommand,
    cycle_s: f32,
    failures: u32,
    wiggle: bool,
    first: bool,
    motion: Motion,
}

impl CommutatedMotion {
    /// A disabled motion layer, not aligned; `wiggle` is 0x2083.
    pub fn new(cfg: MotionConfig, wiggle: bool) -> Self {
        let cfg = Self::checked(cfg);
        let masked = MotionConfig {
            closed_loop: false,
            ..cfg
        };
        CommutatedMotion {
            motion: Motion::new(masked),
            requested: cfg,
            wiggle,
            state: Commutation::Unaligned,
            align: Alignment::new(align_config(&cfg, wiggle)),
            first: false,
            cmd: DriveCommand::default(),
            cycle_s: cfg.ts,
            failures: 0,
        }
    }

    /// A disabled motion layer whose encoder offset is already known (the caller set
    /// it, e.g. a simulation that starts aligned).
    pub fn new_aligned(cfg: MotionConfig, wiggle: bool) -> Self {
        let mut m = Self::new(cfg, wiggle);
        m.state = Commutation::Aligned;
        m.motion.configure(cfg);
        m
    }

    /// The motion layer (position, following error, axis state).
    pub fn motion(&self) -> &Motion {
        &self.motion
    }

    /// The configuration as requested (closed loop unmasked).
    pub fn config(&self) -> &MotionConfig {
        &self.requested
    }

    /// Commutation state.
    pub fn state(&self) -> Commutation {
        self.state
    }

    /// Failed alignments since start (wrapping).
    pub fn failures(&self) -> u32 {
        self.failures
    }

    /// The closed loop is requested and the offset is not known: an enable first runs
    /// the alignment (0.25 s, 0.65 s with the wiggle) before the motion layer follows
    /// set-points. False in open loop, without encoder and once aligned.
    pub fn enable_pending(&self) -> bool {
        self.requested.closed_loop && self.state != Commutation::Aligned
    }

    /// No closed loop without an encoder (as [`Motion`] itself decides).
    fn checked(cfg: MotionConfig) -> MotionConfig {
        MotionConfig {
            closed_loop: cfg.closed_loop && cfg.counts_per_rev > 0,
            ..cfg
        }
    }

    fn masked(&self) -> MotionConfig {
        MotionConfig {
            closed_loop: self.requested.closed_loop && self.state == Commutation::Aligned,
            ..self.requested
        }
    }

    /// The motion layer is held disabled for (or after) an alignment.
    fn gated(&self) -> bool {
        self.state != Commutation::Aligned && self.requested.closed_loop && !self.motion.enabled()
    }

    fn pass_command(&mut self) {
        let mut c = self.cmd;
        if self.gated() {
            c.drive_enabled = false;
        }
        self.motion.set_command(&c, self.cycle_s);
    }

    /// New parameters ([`Motion::configure`]; the closed loop is masked until aligned).
    pub fn configure(&mut self, cfg: MotionConfig, wiggle: bool) {
        self.requested = Self::checked(cfg);
        self.wiggle = wiggle;
        self.motion.configure(self.masked());
    }

    /// The set-points of a drive cycle ([`Motion::set_command`]; the enable is held
    /// back while the commutation is being aligned).
    pub fn set_command(&mut self, cmd: &DriveCommand, cycle_s: f32) {
        self.cmd = *cmd;
        self.cycle_s = cycle_s;
        self.pass_command();
    }

    /// One servo period. `raw_elec`: the encoder's electrical angle without offset
    /// (`foc::encoder::Encoder::raw_electrical_angle`).
    pub fn step(&mut self, fb: &Feedback, raw_elec: Angle) -> Step {
        if self.state == Commutation::Aligned {
            // The running drive: the motion layer alone.
            return Step {
                reference: self.motion.step(fb),
                offset: None,
                failed: false,
            };
        }
        let enable = self.cmd.drive_enabled;
        let mut out = Step {
            reference: CurrentReference::OFF,
            offset: None,
            failed: false,
        };
        match self.state {
            Commutation::Aligning if !enable || !self.requested.closed_loop => {
                self.state = Commutation::Unaligned;
                self.pass_command();
            }
            Commutation::Failed if !enable => {
                self.state = Commutation::Unaligned;
            }
            Commutation::Unaligned if enable && self.gated() => {
                self.state = Commutation::Aligning;
                self.align = Alignment::new(align_config(&self.requested, self.wiggle));
                self.first = true;
            }
            _ => {}
        }
        // While aligning the motion layer only tracks the position (its enable is held
        // back).
        let r = self.motion.step(fb);
        if self.state != Commutation::Aligning {
            // Disabled (tracking), just aligned (its enable comes with the next
            // command), or running; OFF while a failed alignment waits.
            out.reference = if self.gated() {
                CurrentReference::OFF
            } else {
                r
            };
            return out;
        }
        let (angle, current) = self.align.step(raw_elec);
        out.reference = CurrentReference {
            power: true,
            reset: core::mem::take(&mut self.first),
            frame: Frame::Command {
                angle,
                omega_e: 0.0,
            },
            id: current,
            iq: 0.0,
        };
        match self.align.state {
            AlignState::Done(offset) => {
                // Hold the rotor for this step; the motion layer takes over next step.
                out.reference.id = self.align_current();
                out.offset = Some(offset);
                self.state = Commutation::Aligned;
                self.motion.configure(self.masked());
                self.pass_command();
            }
            AlignState::Failed => {
                out.reference = CurrentReference::OFF;
                out.failed = true;
                self.failures = self.failures.wrapping_add(1);
                self.state = Commutation::Failed;
            }
            _ => {}
        }
        out
    }

    /// One servo period while the current loop belongs to the power-up auto-tune
    /// ([`crate::current_supervisor::CurrentSupervisor::tuning`]): no current
    /// reference, the motion layer held ([`Motion::step_held`]); an alignment in
    /// progress starts again at the next enabled step.
    pub fn step_held(&mut self, fb: &Feedback) -> Step {
        if self.state == Commutation::Aligning {
            self.state = Commutation::Unaligned;
            self.pass_command();
        }
        self.motion.step_held(fb);
        Step {
            reference: CurrentReference::OFF,
            offset: None,
            failed: false,
        }
    }

    fn align_current(&self) -> f32 {
        align_config(&self.requested, self.wiggle).current
    }
}
