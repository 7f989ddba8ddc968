//! Motor control for two-phase hybrid steppers and hybrid servos.
//!
//! `no_std`, no heap, `f32` arithmetic for the FPU of a Cortex-M4F, angles as
//! wrapping integers. The crate knows nothing of EtherCAT: parameters come in as
//! plain numbers in SI units (conversions for the drive's integer parameters are
//! documented where they are defined, e.g. [`autotune`]).
//!
//! | module | what |
//! |---|---|
//! | [`angle`] | wrapping fixed-point turns, θe = 50·θ, integer count → angle scaling |
//! | [`trig`] | sin/cos behind the [`trig::SinCos`] trait, polynomial implementation |
//! | [`transforms`] | Park / inverse Park for the two-phase machine |
//! | [`pi`] | PI with output limit and anti-windup |
//! | [`modulation`] | circular voltage limit, two H-bridges, bus compensation |
//! | [`current_loop`] | FOC current loop step: ADC counts → four duty cycles |
//! | [`encoder`] | quadrature count, electrical angle, PLL velocity, Z index |
//! | [`open_loop`] | microstepping, holding current, soft start, command filter |
//! | [`damping`] | anti-resonance damping of open loop (back-EMF speed estimate) |
//! | [`stall`] | open-loop stall detection from the back-EMF the current loop sees |
//! | [`servo`] | position/velocity cascade, CSP interpolation, following error, alignment |
//! | [`autotune`] | R/L measurement, current-loop gains, open/unbalanced phase |
//! | [`identify`] | load inertia and friction from a closed-loop move |
#![no_std]
#![warn(missing_docs)]
#![deny(clippy::undocumented_unsafe_blocks)]

pub mod angle;
pub mod autotune;
pub mod current_loop;
pub mod damping;
pub mod encoder;
pub mod identify;
pub mod modulation;
pub mod num;
pub mod open_loop;
pub mod pi;
pub mod servo;
pub mod stall;
pub mod transforms;
pub mod trig;

pub use angle::Angle;
