//! Motor and power-stage simulation for the control-quality tests and the
//! `control-report` binary.
//!
//! * [`motor`]: the model of `shared/spec/motor-model.md` (both motors), H-bridge
//!   average model, ADC and encoder quantisation, seeded noise, one sample of delay;
//! * [`rig`]: the plant wired to the `foc` controllers as on the board;
//! * [`scenarios`]: the control-quality scenarios, shared by the tests and the report;
//! * [`robustness`]: the current loop under the non-idealities of a real motor;
//! * [`servo_tune`]: the closed-loop load identification and the tuned servo figures.

pub mod motor;
pub mod rig;
pub mod rng;
pub mod robustness;
pub mod scenarios;
pub mod servo_tune;
