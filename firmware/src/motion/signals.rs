//! The motion layer's interface to the current loop: what the encoder and the loop
//! measured in a servo period ([`Feedback`]) and the current reference handed back
//! ([`CurrentReference`], in the [`Frame`] of the encoder or of a commanded angle).

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
