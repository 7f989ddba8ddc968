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
//!
//! # Example
//!
//! A PI current controller (V per A) driving a 1 Ω, 1 mH winding, sampled at
//! 40 kHz, settles on its 1 A reference and never asks for more than its 24 V:
//!
//! ```
//! use foc::pi::Pi;
//!
//! let (r, l, ts) = (1.0_f32, 1.0e-3_f32, 25.0e-6_f32);
//! let mut pi = Pi::new(2.0, 2000.0, ts, 24.0);
//! let mut i = 0.0_f32;
//! for _ in 0..4000 {
//!     let v = pi.update(1.0 - i, 0.0);
//!     assert!(v.abs() <= 24.0);
//!     i += ts * (v - r * i) / l;
//! }
//! assert!((i - 1.0).abs() < 1e-3);
//! ```
//!
//! Angles wrap as integers: the electrical angle of a 50-pole-pair rotor is 50 times
//! the mechanical one, exact.
//!
//! ```
//! use foc::angle::Angle;
//!
//! let quarter = Angle::from_turns(0.25);
//! assert_eq!(Angle::from_turns(0.5).diff(quarter), quarter.0 as i32);
//! assert_eq!(Angle::from_turns(1.0 / 50.0).electrical().0, Angle::from_turns(1.0 / 50.0).0.wrapping_mul(50));
//! ```
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
