//! Motor and power-stage simulation for the control-quality tests and the
//! `control-report` binary.
//!
//! * [`motor`]: the two-phase hybrid stepper model of `motor.rs` (both motors), H-bridge
//!   average model, ADC and encoder quantisation, seeded noise, one sample of delay;
//! * [`rig`]: the plant wired to the `foc` controllers as on the board;
//! * [`scenarios`]: the control-quality scenarios, shared by the tests and the report;
//! * [`robustness`]: the current loop under the non-idealities of a real motor;
//! * [`resonance`]: the open-loop speed sweep, with and without the damping;
//! * [`stall`]: open-loop stall detection and stall homing;
//! * [`torque`]: cyclic synchronous torque (CST) through the firmware's profile and
//!   motion layer;
//! * [`servo_tune`]: the closed-loop load identification and the tuned servo figures;
//! * [`drive_tune`]: the same identification as the drive runs it (0x2162).

pub mod drive_tune;
pub mod motor;
pub mod resonance;
pub mod rig;
pub mod rng;
pub mod robustness;
pub mod scenarios;
pub mod servo_tune;
pub mod stall;
pub mod torque;
