//! CiA 402 (IEC 61800-7-201/-301) drive profile: power drive system, operating modes
//! (PP, PV, HM, CSP, CSV, CST), homing, touch probe, limits and supervision, and the
//! 0x6000-0x6FFF part of the object dictionary.
//!
//! The application calls [`Cia402::cycle`] once per control cycle with the measured
//! state of the axis ([`DriveFeedback`]) and gets the set-points for the servo loops
//! ([`DriveCommand`]). The module knows nothing of the motor control crate: positions are
//! `i32` command units (0x2001 per motor revolution), velocities command units/s.
//!
//! Coordinates: *raw* values are motor-side (what [`DriveFeedback`] reports and
//! [`DriveCommand`] takes); *user* values are what the objects show:
//! `user = polarity · raw + home shift` (0x607E bit 7 for positions, bit 6 for
//! velocities; the home shift is set by homing so that the home position reads 0x607C).
//!
//! Submodules: [`pds`] (states and the transition table), [`profile`] (trajectory
//! generator), [`homing`], [`probe`] (touch probe), [`objects`] (dictionary entries,
//! SDO read/write, PDO slots), `words` (the mode of operation, controlword and
//! statusword as types), `access` (the values read by objects and the application).
//! The step itself: `cycle` (its order), `power` (the
//! power drive system in a step), `modes` (the mode dispatch and generators),
//! `limits` (software limits, following error), `statusword`.
//!
//! # Behaviour decided here (where the sources leave a choice)
//! * The drive steps the profile on its own clock ([`Cia402::step`] from its
//!   supervision tick, in every ESM state) and in the master's cycles. Transition 1
//!   happens in the first step; [`Cia402::on_esm_init`] puts the PDS in Switch on
//!   disabled unless a stop is running or a fault is latched (those finish / stay).
//! * Option codes 3 and 4 ("current limit", "voltage limit") of 0x605A/0x605D/0x605E
//!   stop with the maximum deceleration 0x60C6: the drive is position controlled.
//!   0x605A = 0 / 0x605E = 0 disable the drive function at once (transitions 11 + 12
//!   in one cycle for 0x605A = 0).
//! * Transitions 5 and 8 with option code 1 stay in Operation enabled while the axis
//!   slows down (0x6084), then change state.
//! * PP: a set-point is refused (no acknowledge, statusword bit 14 set) while 0x6081,
//!   0x6083 or 0x6084 is 0. Halt voids the running and the buffered set-point. Bit 9
//!   passes through the current target at min(its, the next) profile velocity only
//!   when the buffered target continues in the same direction. Bit 15 (E5) is the
//!   inverse of bit 12. Relative targets follow 0x60F2 bits 0-1.
//! * Hardware limit switches (0x60FD bits 0/1, outside homing) stop motion towards
//!   them with 0x6085 and set bits 8 and 11; motion away from them is allowed.
//!   Software limits 0x607D apply when min < max and not both at the type limits.
//! * Homing: at the home position the position actual value reads 0x607C (the axis
//!   returns to the reference point found, so the final position is that point);
//!   homing runs in user coordinates (after 0x607E).
//! * A following error (|0x60F4| > 0x6065 for longer than 0x6066 ms in PP, HM, CSP)
//!   sets bit 13 and raises fault 0x8611; 0x6065 = 0xFFFFFFFF switches it off.
//! * The master's commands stop (SM watchdog, Op left, SYNC0 lost): 0x6007
//!   ([`AbortConnection`], [`Cia402::on_connection_lost`]); with 1, the default,
//!   a fault whose 0x603F is the loss's own code, the one its emergency carries
//!   (0x8700 process-data watchdog, 0xA000 / 0xA001 Op left to Init / Safe-Op or
//!   Pre-Op, ...), and the reaction 0x605E.
//! * Fault reaction: the ramp starts at the demand position with the lower of the
//!   demand and the actual speed (a jump of the target or a dragged shaft is not
//!   ramped down from an absurd demand speed).
//! * Transition 4 waits for the power stage ([`DriveFeedback::enable_pending`]; guard
//!   [`pds::Guard::ReadyToFollow`]). A hybrid servo in closed loop cannot follow
//!   set-points before its commutation alignment has run (the encoder's electrical
//!   offset is unknown after power-up; `commutation`), and the alignment needs
//!   current in the motor. So while "enable operation" is commanded in Switched on and
//!   the feedback reports the enable pending, the PDS stays in Switched on (statusword
//!   0x0233 with voltage) but the command asks the motor side to get ready:
//!   [`DriveCommand::drive_enabled`] (and the brake release) is set with the position
//!   demand at the actual position and no velocity — the motion layer holds it back
//!   while it aligns, then holds the actual position in closed loop. The first cycle
//!   whose feedback no longer reports it pending performs transition 4, which starts
//!   the internal set-points at the actual position: 0x6064 = 0x6062 at the moment
//!   the statusword first shows Operation enabled, so a CSP master that copies 0x6064
//!   into 0x607A then gets no jump. [`Cia402::enable_waiting`] tells the application
//!   that the enable of this cycle is such a request (no drive function yet: leaving
//!   Op is not a fault). The wait has no time-out of its own: a failed alignment is a
//!   fault of the motor side (following error 0x8611), which ends it in Fault; any
//!   other command (shutdown, disable voltage, quick stop) ends it at once. Open loop
//!   and drives without encoder never report it (no wait).
//! * CST (0x6060 = 10) and PT (0x6060 = 4) need the closed loop (an encoder and
//!   0x2024 = 2, [`Cia402::set_torque_control`]): 0x6502 shows bits 3 and 9 only then,
//!   and 0x6060 = 4 / 10 is refused otherwise like any unsupported mode (SDO abort
//!   0x06090030; an RxPDO value is not taken over). Losing the closed loop while in a
//!   torque mode sets 0x6060 to 0 (no mode): the axis stops on the 0x6085 ramp in
//!   position control and holds.
//! * Operation enabled with 0x6060 = 0 (no mode) is accepted: the axis holds its
//!   position in position control (a stop on the 0x6085 ramp first if it was moving)
//!   until a mode is chosen, and statusword bits 10, 12 and 13 stay clear. This is
//!   deliberate, where some drives raise an alarm: CiA 402 leaves the behaviour
//!   without a mode to the manufacturer, and masters that enable before they write
//!   0x6060, or pass through 0 while switching modes, keep working; the axis is
//!   never left without a set-point.
//! * PT runs the CST demand below (0x6071 set by SDO or PDO, the ramp 0x6087, the
//!   profile type 0x6088 = 0 linear); statusword bit 10 (target reached) is set when
//!   the demand has reached the limited target, or, halted, once the axis is at rest.
//! * CST demand: 0x6071 + 0x60B2, limited to ±0x6072, approached at 0x6087 per mille
//!   per second (0 = no slope limit: the demand steps). On entering CST while enabled,
//!   and at transitions 4 and 16, the demand starts from the torque the servo loops
//!   were demanding (0x6074), so with a slope the switch is bumpless; without one
//!   the master writes 0x6071 = 0x6077 for that (as it copies 0x6064 into 0x607A for
//!   CSP). Speed: the motion layer limits |v| to 0x6080 in the direction of the
//!   torque (`foc::servo::Servo::step_torque`: torque is taken off past the limit,
//!   statusword bit 11). Halt, hardware limit switches and software position limits
//!   in the direction of the torque or of the motion, the stop ramps of quick stop,
//!   fault reaction and transitions 5 / 8 leave torque control: the axis stops from
//!   its actual position and speed in velocity (halt, limits) or position control
//!   (the PDS stops) on the ramps of the option codes, as in the other modes.
//!   0x60B2 is also the torque feed-forward of CSP and CSV.

mod access;
#[cfg(test)]
mod cst_tests;
mod cycle;
pub mod homing;
mod limits;
mod modes;
pub mod objects;
mod params;
pub mod pds;
mod power;
pub mod probe;
pub mod profile;
pub mod scaling;
mod statusword;
mod words;

use homing::{Homing, HomingInputs, HomingParams, HomingStatus};
pub use params::{Params, PEAK_PERMILLE};
use pds::{Command, Event, Guard, PdsState};
pub use probe::EdgeLatch;
use probe::TouchProbe;
use profile::{Motion, MoveStatus, Smoother};
pub use words::{mode, mode_supported, sw, Controlword, OperationMode, Statusword};

/// 0x6502 in closed loop: PP (bit 0), PV (bit 2), PT (bit 3), HM (bit 5), CSP (bit 7),
/// CSV (bit 8), CST (bit 9).
pub const SUPPORTED_MODES: u32 = SUPPORTED_MODES_OPEN_LOOP
    | OperationMode::Pt.supported_bit()
    | OperationMode::Cst.supported_bit();

/// 0x6502 without torque control (open loop, no encoder): no PT, no CST.
pub const SUPPORTED_MODES_OPEN_LOOP: u32 = OperationMode::Pp.supported_bit()
    | OperationMode::Pv.supported_bit()
    | OperationMode::Hm.supported_bit()
    | OperationMode::Csp.supported_bit()
    | OperationMode::Csv.supported_bit();

/// 0x6007 abort connection option code: what the drive does when the master's
/// commands stop ([`Cia402::on_connection_lost`]). Stored by 'save'.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(i16)]
pub enum AbortConnection {
    /// 0: no action; the drive keeps its state and its last set-points.
    NoAction = 0,
    /// 1 (default): fault with the code of the loss (0x603F = the emergency's code:
    /// 0x8700, 0xA000, 0xA001, ...), the fault reaction 0x605E, then Fault.
    Fault = 1,
    /// 2: disable voltage (power off at once, brake engaged).
    DisableVoltage = 2,
    /// 3: quick stop on the 0x605A ramp.
    QuickStop = 3,
}

impl AbortConnection {
    /// The option of a 0x6007 value (the object's range is 0-3; anything else is
    /// taken as the default, fault).
    pub const fn from_code(code: i16) -> AbortConnection {
        match code {
            0 => AbortConnection::NoAction,
            2 => AbortConnection::DisableVoltage,
            3 => AbortConnection::QuickStop,
            _ => AbortConnection::Fault,
        }
    }
}

/// Error code (0x603F) of a following error.
pub const ERR_FOLLOWING: u16 = 0x8611;

/// What the drive measured this cycle (raw, motor-side values).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DriveFeedback {
    /// Actual position (command units).
    pub position: i32,
    /// Actual velocity (command units/s).
    pub velocity: i32,
    /// Output of the position controller, command units/s, motor side (0x60FA).
    pub control_effort: i32,
    /// Actual torque, per mille of rated torque (0x6077): the measured q current
    /// (encoder frame) per mille of the rated current.
    pub torque: i16,
    /// Torque the servo loops demand (their q-current reference), per mille of rated
    /// torque (0x6074 outside CST).
    pub torque_demand: i16,
    /// Actual current, per mille of rated current (0x6078).
    pub current: i16,
    /// Digital inputs in 0x60FD layout (bit 0 negative limit, 1 positive limit, 2 home),
    /// already mapped through the input functions 0x2152.
    pub digital_inputs: u32,
    /// Position latched at an encoder index pulse during this cycle.
    pub index: Option<i32>,
    /// Positions latched at the edges of input 1 (touch probe 1) during this cycle.
    pub probe1: EdgeLatch,
    /// Positions latched at the edges of input 2 (touch probe 2) during this cycle.
    pub probe2: EdgeLatch,
    /// Active fault condition as a CiA 402 error code (0 = none). While non-zero the
    /// drive goes to / stays in Fault and a fault reset is refused.
    pub fault: u16,
    /// The power stage is already off because of the fault (over-current, …): the fault
    /// reaction cannot ramp.
    pub power_stage_tripped: bool,
    /// A warning condition (statusword bit 7).
    pub warning: bool,
    /// The servo is at its current / torque limit (statusword bit 11).
    pub current_limited: bool,
    /// A quick-stop input function is active (acts like controlword bit 2 = 0).
    pub quick_stop_input: bool,
    /// The power stage cannot follow set-points yet (the closed loop's commutation
    /// alignment has not run): transition 4 waits (see the module docs).
    pub enable_pending: bool,
    /// The open loop confirmed a stall during this cycle: the position where it began
    /// (the reference of stall homing, [`homing`]).
    pub stall: Option<i32>,
}

/// Which set-point the servo loops should follow.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SetpointKind {
    /// Follow `position`, with `velocity` as feed-forward.
    #[default]
    Position,
    /// Follow `velocity` (PV, CSV); `position` is the actual position plus one cycle of
    /// that velocity (for a loop that can only follow positions, e.g. open loop).
    Velocity,
    /// Follow `torque` (CST, closed loop); `velocity` is the speed limit (0x6080,
    /// magnitude), `position` the actual position (a loop that cannot control torque
    /// holds it).
    Torque,
    /// The servo tune's identification move (`servo_tune`), generated by the
    /// motion layer; `position` and `velocity` are the actual ones (where set-points
    /// of another kind start).
    Tune,
}

/// Set-points for the servo loops (raw, motor-side values).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DriveCommand {
    /// Power stage on (high voltage applied): Switched on, Operation enabled, Quick stop
    /// active, Fault reaction active.
    pub power_stage: bool,
    /// Drive function enabled: the loops must control the motor. Also set in Switched
    /// on while transition 4 waits for [`DriveFeedback::enable_pending`] (position =
    /// actual position, velocity 0: the motor side aligns, then holds; see
    /// [`Cia402::enable_waiting`] and the module docs).
    pub drive_enabled: bool,
    /// Which set-point is primary.
    pub kind: SetpointKind,
    /// Position demand (command units).
    pub position: i32,
    /// Velocity demand / feed-forward (command units/s).
    pub velocity: f32,
    /// Acceleration feed-forward (command units/s²): change of the velocity demand over
    /// this cycle (0 while disabled).
    pub acceleration: f32,
    /// Torque limit, per mille of rated torque (0x6072).
    pub torque_limit: u16,
    /// Current limit, per mille of rated current (0x6073).
    pub current_limit: u16,
    /// Torque demand (CST, whole per mille) or torque feed-forward (CSP, CSV: 0x60B2),
    /// per mille of rated torque; 0 in the other modes and states. (An `i32`: the
    /// command then has no padding and is copied whole, word by word.)
    pub torque: i32,
    /// Release the holding brake.
    pub brake_release: bool,
}

/// One PP set-point.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Setpoint {
    target: i32,
    vel: f32,
    acc: f32,
    dec: f32,
}

/// Profile position state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Pp {
    active: Option<Setpoint>,
    buffered: Option<Setpoint>,
    ack: bool,
    last_target: i32,
    /// The running target was clamped by the software limits.
    clamped: bool,
    /// Trapezoid generator when the jerk-limiting filter is on (0x6086 = 3); the
    /// filtered output is the drive's demand.
    gen: Motion,
    smooth: Smoother,
}

/// CSP set-point segment: the demand goes from `from` towards `to` (see
/// [`Cia402::step`] for the timing rules).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Cyclic {
    from: i32,
    to: i32,
    /// Time since the segment started, s.
    elapsed: f32,
    /// Time since the last set-point, s, and that time at the last set-point.
    since_fresh: f32,
    last_gap: f32,
    /// Set-point period of the segment, s.
    period: f32,
    /// The segment interpolates over its period (several steps per set-point) instead
    /// of reaching `to` at once.
    interpolate: bool,
    /// The caller tells which steps bring set-points ([`SetpointArrival::Fresh`] /
    /// [`SetpointArrival::Stale`]): the demand may run on for one period past `to`.
    extrapolate: bool,
    started: bool,
    /// Velocity of the current segment (position change over its period, no 0x60B1),
    /// and the target it was built for: the acceleration limits' state.
    v: f32,
    last_target: i32,
}

impl Cyclic {
    /// The segment's demand at its `elapsed` time and the velocity feed-forward
    /// (`offset` is 0x60B1). In periods from the segment's start, an interpolated
    /// segment reaches `to` after one, a direct one at once; with run-on the demand
    /// goes on for one more period, then holds with velocity 0.
    fn demand(&self, offset: f32) -> (i32, f32) {
        let period = if self.period > 0.0 {
            self.period
        } else {
            1.0e-3
        };
        let seg = self.to.wrapping_sub(self.from);
        if !self.interpolate && (!self.extrapolate || self.elapsed == 0.0) {
            // Direct, at the set-point's step (or one step per set-point): the target,
            // at the segment's velocity.
            return (self.to, seg as f32 / period + offset);
        }
        let start = if self.interpolate { 0.0 } else { 1.0 };
        let end = if self.extrapolate { 2.0 } else { 1.0 };
        let mut frac = start + self.elapsed / period;
        if (0.999..=1.001).contains(&frac) {
            frac = 1.0;
        }
        let held = self.extrapolate && frac >= end;
        let pos = self.from.wrapping_add((seg as f32 * frac.min(end)) as i32);
        let vel = if held {
            0.0
        } else {
            seg as f32 / period + offset
        };
        (pos, vel)
    }
}

/// Whether a step brings new cyclic set-points (CSP's 0x607A, CSV's 0x60FF).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SetpointArrival {
    /// The caller does not tell: every step is a cycle of the master, and when the
    /// steps are shorter than 0x60C2 a new set-point is taken every 0x60C2 period.
    PerCycle,
    /// The master's cycle delivered new outputs for this step.
    Fresh,
    /// No new outputs since the last step (the drive's own supervision tick, or a
    /// cycle without a frame).
    Stale,
}

/// The drive steps at least this often (its supervision tick): a set-point period of
/// 1.5 steps or more is interpolated over several steps.
pub const STEP_PERIOD_S: f32 = 1.0e-3;

/// The acceleration feed-forward is the change of the velocity demand over at least
/// this time, so that a short step (the supervision tick and the master's cycle
/// landing close together) does not make a spike of it.
pub const ACCELERATION_MIN_DT_S: f32 = 250.0e-6;

/// A stop in Operation enabled that is not a PDS state of its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Pending {
    None,
    /// Transition 5 or 8 waits for the slow-down ramp.
    Transition(Command),
}

/// The CiA 402 drive profile.
#[derive(Debug, Clone)]
pub struct Cia402 {
    /// The writable parameters.
    pub params: Params,
    state: PdsState,
    controlword: Controlword,
    prev_cw: Controlword,
    prev_demand_vel: f32,
    mode_request: OperationMode,
    mode: OperationMode,
    motion: Motion,
    pp: Pp,
    hm: Homing,
    /// The stall of this cycle's feedback (raw position where it began).
    stall: Option<i32>,
    cyc: Cyclic,
    probe: TouchProbe,
    pending: Pending,
    error_code: u16,
    init_done: bool,
    self_test: bool,
    shift: i32,
    // Measured / derived values.
    raw_position: i32,
    actual_position: i32,
    actual_velocity: i32,
    control_effort: i32,
    actual_torque: i16,
    actual_current: i16,
    /// The servo loops' torque demand (last feedback, raw sign).
    servo_torque: i16,
    /// CST: the torque demand after the slope and 0x6072, per mille (user sign).
    torque_demand: f32,
    /// Torque command of this step for the motor side ([`DriveCommand::torque`],
    /// user sign).
    torque_cmd: i16,
    digital_inputs: u32,
    following_error: i32,
    statusword: Statusword,
    // Supervision.
    fe_time: f32,
    fe_flag: bool,
    /// A following-error fault (0x6065 / 0x6066) not yet taken by the drive's fault
    /// module ([`Cia402::take_following_error_fault`]).
    fe_fault_news: bool,
    window_time: f32,
    vel_window_time: f32,
    target_reached: bool,
    internal_limit: bool,
    abnormal_stop: bool,
    halted: bool,
    /// The motor side reported the enable pending (last feedback).
    enable_pending: bool,
    /// Transition 4 is waiting for it (the command enables the motor side).
    enable_waiting: bool,
    // Configuration from the application.
    has_index: bool,
    assigned_inputs: u32,
    /// Stall homing's precondition ([`Cia402::set_stall_homing`]).
    stall_homing: Option<f32>,
    rated_current_ma: u32,
    /// Torque constant of the motor, N·m/A (0x6076 = this · 0x6075).
    torque_constant: f32,
    /// The closed loop can control torque: CST available.
    torque_control: bool,
    /// The servo tune runs its move ([`Cia402::set_servo_tune`]).
    servo_tune: bool,
    encoder_increments: u32,
    /// 0x6091-0x6093, the views of the command units per revolution (0x2001).
    pub(crate) scaling: scaling::Scaling,
}

impl Default for Cia402 {
    fn default() -> Self {
        Self::new()
    }
}

fn pol16(neg: bool, v: i16) -> i16 {
    if neg {
        v.wrapping_neg()
    } else {
        v
    }
}

fn pol(neg: bool, v: i32) -> i32 {
    if neg {
        v.wrapping_neg()
    } else {
        v
    }
}

impl Cia402 {
    /// Power-on (transition 0): Not ready to switch on, default parameters.
    pub fn new() -> Self {
        Cia402 {
            params: Params::DEFAULT,
            state: PdsState::NotReadyToSwitchOn,
            controlword: Controlword::from_raw(0),
            prev_cw: Controlword::from_raw(0),
            prev_demand_vel: 0.0,
            mode_request: OperationMode::None,
            mode: OperationMode::None,
            motion: Motion::at(0),
            pp: Pp::default(),
            hm: Homing::new(),
            cyc: Cyclic::default(),
            probe: TouchProbe::default(),
            pending: Pending::None,
            error_code: 0,
            init_done: false,
            self_test: false,
            shift: 0,
            raw_position: 0,
            actual_position: 0,
            actual_velocity: 0,
            control_effort: 0,
            actual_torque: 0,
            actual_current: 0,
            servo_torque: 0,
            torque_demand: 0.0,
            torque_cmd: 0,
            digital_inputs: 0,
            following_error: 0,
            statusword: Statusword::from_raw(0),
            fe_time: 0.0,
            fe_flag: false,
            fe_fault_news: false,
            window_time: 0.0,
            vel_window_time: 0.0,
            target_reached: false,
            internal_limit: false,
            abnormal_stop: false,
            halted: false,
            enable_pending: false,
            enable_waiting: false,
            stall: None,
            has_index: true,
            assigned_inputs: homing::DI_NEG_LIMIT | homing::DI_POS_LIMIT | homing::DI_HOME,
            stall_homing: None,
            rated_current_ma: 3200,
            // ECN57-20, the motion layer's `ECN57_20.kt` (equal: `cst_tests`).
            torque_constant: 0.283,
            torque_control: true,
            servo_tune: false,
            encoder_increments: 4000,
            scaling: scaling::Scaling::new(50_000),
        }
    }

    // ----- configuration from the application -----

    /// Whether an encoder index pulse exists (hybrid servo with Z). Without it the
    /// index homing methods end in homing error and index touch probes never trigger.
    pub fn set_has_index(&mut self, yes: bool) {
        self.has_index = yes;
    }
    /// Stall homing (0x6098 = -1 / -2) is possible — open loop with the stall
    /// detection on — and its search speed 0x6099:01 must be at least this (command
    /// units/s: the detection's minimum speed); `None`: not possible. Otherwise the
    /// start is a homing error at once (statusword bit 13), with no motion.
    pub fn set_stall_homing(&mut self, min_speed: Option<f32>) {
        self.stall_homing = min_speed;
    }
    /// Which 0x60FD bits (limit and home switches) are assigned to inputs (0x2152).
    pub fn set_assigned_inputs(&mut self, mask: u32) {
        self.assigned_inputs = mask;
    }
    /// Rated motor current shown in 0x6075 (mA).
    pub fn set_rated_current_ma(&mut self, milliamps: u32) {
        self.rated_current_ma = milliamps;
    }
    /// Torque constant of the motor, N·m/A (peak q current; `motion::
    /// MotorConstants::kt`): the rated torque 0x6076 is it times the rated current
    /// 0x6075. Torque values in per mille are per mille of the rated current on q.
    pub fn set_torque_constant(&mut self, kt: f32) {
        self.torque_constant = if kt.is_finite() && kt > 0.0 { kt } else { 0.0 };
    }
    /// Whether the motor side can control torque (closed loop: an encoder and 0x2024 =
    /// 2): CST is available (0x6502 bit 9). Withdrawn while 0x6060 = 10, 0x6060 falls
    /// to 0 (see the module docs).
    pub fn set_torque_control(&mut self, available: bool) {
        self.torque_control = available;
        if !available && self.mode_request.is_torque() {
            self.mode_request = OperationMode::None;
        }
    }
    /// The servo tune's move (`servo_tune`) takes over the set-points (`on`):
    /// in Operation enabled, PP or CSP, without halt, the step hands the motion layer
    /// [`SetpointKind::Tune`] and the generator follows the actual position. It ends
    /// (false) at the first step where any of that does not hold, or with `false`.
    pub fn set_servo_tune(&mut self, on: bool) {
        self.servo_tune = on;
    }
    /// The servo tune's move finished where it began, at rest: the set-points go back
    /// to the mode, its generator at the actual position and at rest (the velocity it
    /// followed during the move is stale by then).
    pub fn end_servo_tune_at_rest(&mut self) {
        if self.servo_tune {
            self.servo_tune = false;
            self.motion.set(self.actual_position, 0.0);
        }
    }
    /// The software position limits 0x607D in effect, in the motor side's command
    /// units (polarity and home offset undone), low end first.
    pub fn raw_position_limits(&self) -> Option<(i32, i32)> {
        let (lo, hi) = self.params.sw_limits()?;
        let (a, b) = (self.user_to_raw(lo), self.user_to_raw(hi));
        Some((a.min(b), a.max(b)))
    }
    /// Whether the servo tune's move has the set-points ([`Cia402::set_servo_tune`]).
    pub fn servo_tune(&self) -> bool {
        self.servo_tune
    }
    /// 0x6502: the modes available now.
    pub fn supported_modes(&self) -> u32 {
        if self.torque_control {
            SUPPORTED_MODES
        } else {
            SUPPORTED_MODES_OPEN_LOOP
        }
    }
    /// 0x6076 motor rated torque, mN·m.
    pub fn rated_torque_mnm(&self) -> u32 {
        (self.torque_constant * self.rated_current_ma as f32 + 0.5) as u32
    }
    /// Encoder increments per motor revolution (0x608F:01, the position factor's
    /// reference).
    pub fn set_resolution(&mut self, encoder_increments: u32) {
        self.encoder_increments = encoder_increments;
    }
    /// 0x2001 (command units per revolution, as written) changed: 0x6091-0x6093 show
    /// it ([`scaling`]).
    pub fn set_scaling_units(&mut self, units: u32) {
        self.scaling.set_units(units);
    }
    /// The whole number of command units per revolution the last write of 0x6091-0x6093
    /// gave, for 0x2001; [`Cia402::settle_scaling`] once 0x2001 took it.
    pub fn scaling_candidate(&self) -> Option<u32> {
        self.scaling.candidate()
    }
    /// 0x2001 took [`Cia402::scaling_candidate`].
    pub fn settle_scaling(&mut self) {
        self.scaling.settle();
    }

    // ----- ESM coupling -----

    /// The master's commands stopped: the process-data watchdog, the SYNC0 or sync
    /// supervision, or the ESM leaving Op (requested or forced). Applies 0x6007
    /// ([`AbortConnection`]) and returns it. Except with 0x6007 = 0 the controlword is
    /// replaced by the command the reaction needs (no master commands arrive any more;
    /// a master that comes back must enable again):
    /// * 1 fault: Operation enabled / Quick stop active → Fault reaction active
    ///   (0x603F = `code`, the code of the loss the emergency carries, reaction
    ///   0x605E, then Fault);
    /// * 2 disable voltage: → Switch on disabled at once (power off, brake engaged);
    /// * 3 quick stop: Operation enabled → Quick stop active (ramp 0x605A); the
    ///   controlword holds "quick stop", so the stop runs to its end;
    /// * with 1-3, Switched on / Ready to switch on fall to Switch on disabled.
    ///
    /// The reaction then runs on the drive's own clock ([`Cia402::step`] from the
    /// supervision tick): no frame is needed to finish it.
    pub fn on_connection_lost(&mut self, code: u16) -> AbortConnection {
        let option = AbortConnection::from_code(self.params.abort_connection_option);
        let cmd = match option {
            AbortConnection::NoAction => return option,
            AbortConnection::Fault | AbortConnection::DisableVoltage => 0,
            AbortConnection::QuickStop => pds::QUICK_STOP_COMMAND,
        };
        self.controlword = Controlword::from_raw(cmd);
        self.prev_cw = self.controlword;
        match (self.state, option) {
            (PdsState::OperationEnabled | PdsState::QuickStopActive, AbortConnection::Fault) => {
                self.fault_detected(code)
            }
            (PdsState::OperationEnabled, AbortConnection::QuickStop) => {
                self.enter(PdsState::QuickStopActive)
            }
            (PdsState::QuickStopActive, AbortConnection::QuickStop) => {}
            (
                PdsState::OperationEnabled
                | PdsState::QuickStopActive
                | PdsState::SwitchedOn
                | PdsState::ReadyToSwitchOn,
                _,
            ) => self.enter(PdsState::SwitchOnDisabled),
            _ => {}
        }
        option
    }

    /// The ESM went to Init. A stop that is running (fault reaction, quick stop) and,
    /// with 0x6007 = 0, Operation enabled are left alone: they go on on the drive's own
    /// clock. A fault stays until a fault reset (0x603F keeps telling what happened).
    /// Every other state goes to Switch on disabled (Not ready to switch on while the
    /// power-up self-test runs) with the controlword cleared.
    pub fn on_esm_init(&mut self) {
        if matches!(
            self.state,
            PdsState::OperationEnabled
                | PdsState::QuickStopActive
                | PdsState::FaultReactionActive
                | PdsState::Fault
        ) {
            return;
        }
        self.controlword = Controlword::from_raw(0);
        self.prev_cw = self.controlword;
        self.init_done = !self.self_test;
        self.enter(if self.self_test {
            PdsState::NotReadyToSwitchOn
        } else {
            PdsState::SwitchOnDisabled
        });
    }

    /// The power-up self-test (the current-loop auto-tune, `Drive::current_report`) is
    /// running: the PDS stays in (or, from Switch on disabled, returns to) Not ready to
    /// switch on, and transition 1 waits until it is over (IEC 61800-7-201: "drive
    /// initialisation or self-test running").
    pub fn set_self_test(&mut self, running: bool) {
        self.self_test = running;
        if running && self.state == PdsState::SwitchOnDisabled {
            self.init_done = false;
            self.enter(PdsState::NotReadyToSwitchOn);
        }
    }

    /// Raises a fault detected elsewhere (transition 13, 0x603F = `code`); a fault
    /// reset clears it unless [`DriveFeedback::fault`] still reports a condition.
    pub fn raise_fault(&mut self, code: u16) {
        self.fault_detected(code);
    }
}
