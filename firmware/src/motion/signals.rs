//! The motion layer's interface to the current loop: what the encoder and the loop
//! measured in a servo period ([`Feedback`]) and the current reference handed back
//! ([`CurrentReference`], in the [`Frame`] of the encoder or of a commanded angle), and
//! what the motor side reports to the drive each cycle ([`AxisState`]).

use foc::angle::Angle;
use foc::transforms::Dq;

/// What the encoder measured at the start of this servo period.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Feedback {
    /// Multi-turn position, motor counts (`foc::encoder::Encoder::position`).
    pub position: i32,
    /// Velocity estimate, motor counts/s.
    pub velocity: f32,
    /// Electrical angle of the rotor (alignment offset included).
    pub electrical_angle: Angle,
    /// The current loop limited its voltage vector in the last period.
    pub voltage_limited: bool,
    /// The current loop's commanded d/q voltages, mean over the last servo period, V.
    pub v_dq: Dq,
    /// The current loop's measured d/q currents, mean over the last servo period, A.
    pub i_dq: Dq,
}

/// Which angle the current loop works on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Frame {
    /// The encoder's electrical angle and velocity (closed loop).
    Encoder,
    /// A commanded angle and electrical velocity, rad/s (open loop).
    Command {
        /// Electrical angle of the d axis.
        angle: Angle,
        /// Electrical angular velocity (back-EMF / decoupling feed-forward), rad/s.
        omega_e: f32,
    },
}

/// The current loop's reference for the next servo period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurrentReference {
    /// Bridges on (false: all outputs off, current 0).
    pub power: bool,
    /// Clear the current loop's integrators (first period after enable).
    pub reset: bool,
    /// Frame of `id`/`iq`.
    pub frame: Frame,
    /// d current, A.
    pub id: f32,
    /// q current, A.
    pub iq: f32,
}

impl CurrentReference {
    /// No current, bridges off.
    pub const OFF: CurrentReference = CurrentReference {
        power: false,
        reset: false,
        frame: Frame::Encoder,
        id: 0.0,
        iq: 0.0,
    };
}

/// What the motor side measured, handed to the drive before each cycle (raw,
/// motor-side values in command units).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AxisState {
    /// Actual position, command units (0x2001 per revolution).
    pub position: i32,
    /// Actual velocity, command units/s.
    pub velocity: i32,
    /// Phase A current, mA.
    pub ia_ma: i16,
    /// Phase B current, mA.
    pub ib_ma: i16,
    /// Phase A set-point, mA.
    pub ia_set_ma: i16,
    /// Phase B set-point, mA.
    pub ib_set_ma: i16,
    /// Torque-producing current reference (the servo loops' demand), per mille of the
    /// peak current 0x2000.
    pub current_permille: i16,
    /// Measured torque-producing current: the q current in the encoder frame, per
    /// mille of the peak current 0x2000 (= torque per mille of the rated torque 0x6076);
    /// 0 without an encoder.
    pub torque_permille: i16,
    /// Output of the position controller (0x60FA), command units/s
    /// ([`super::Motion::control_effort`]).
    pub control_effort: i32,
    /// Electrical angle, 1/65536 turn.
    pub electrical_angle: u16,
    /// DC bus voltage, mV.
    pub bus_mv: u32,
    /// Position latched at an encoder index pulse since the previous cycle.
    pub index: Option<i32>,
    /// Positions latched at the edges of input 1 since the previous cycle (touch probe
    /// 1; logical edges, 0x2154 applied: see `latch`).
    pub probe1: crate::cia402::EdgeLatch,
    /// Positions latched at the edges of input 2 since the previous cycle (touch probe 2).
    pub probe2: crate::cia402::EdgeLatch,
    /// The power stage tripped (hardware over-current / break input).
    pub overcurrent_trip: bool,
    /// The servo is at its current limit.
    pub current_limited: bool,
    /// Following error between servo demand and encoder, encoder counts (closed loop;
    /// compared with 0x2030).
    pub servo_following_error: i32,
    /// The motor side cannot follow set-points at an enable yet: closed loop requested
    /// and the commutation alignment not done (`commutation::CommutatedMotion::
    /// enable_pending`). CiA 402 transition 4 waits for it to clear while the motor side
    /// aligns ([`crate::cia402::DriveFeedback::enable_pending`]). False (the default):
    /// open loop, no encoder, aligned — no wait.
    pub commutation_pending: bool,
    /// Counts the open-loop stalls confirmed by the motion layer's detector (wrapping).
    pub stall_seq: u32,
    /// Command position where the last stall began (command units).
    pub stall_position: i32,
    /// Estimated load angle of the open loop, 0.1° electrical (0x2063).
    pub load_angle_ddeg: i16,
    /// The motion layer's servo tune runs ([`crate::servo_tune`]).
    pub servo_tune: crate::servo_tune::TuneReport,
}
