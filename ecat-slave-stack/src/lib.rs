//! EtherCAT SubDevice protocol stack for a microcontroller behind an ESC.
//!
//! `no_std`, no heap, no panics on input from the wire. Layers:
//! [`esc`] (access to the ESC address space, drivers for LAN9252 and ET1100),
//! [`registers`] and [`al_status`] (the one register map and AL status code table),
//! [`esm`] (state machine), [`od`] (object dictionary description and checks),
//! [`mailbox`] with [`coe`] (SDO, SDO information, emergency) and [`foe`] (file
//! access, firmware download in Bootstrap).
//!
//! # Example
//!
//! The state machine's transition rules as ETG.1000.6 states them: Init → Pre-Op is
//! allowed, Init → Op is refused with AL status 0x0011, and Bootstrap is only
//! reachable from Init on a slave that offers it.
//!
//! ```
//! use ecat_slave_stack::al_status::AlStatusCode;
//! use ecat_slave_stack::esm::{rule, rule_with, EsmState, Rule};
//!
//! assert_eq!(rule(EsmState::Init, EsmState::PreOp), Rule::Allowed);
//! assert_eq!(
//!     rule(EsmState::Init, EsmState::Op),
//!     Rule::Refused(AlStatusCode::InvalidStateChange)
//! );
//! assert_eq!(rule_with(EsmState::Init, EsmState::Bootstrap, true), Rule::Allowed);
//! assert_eq!(rule_with(EsmState::PreOp, EsmState::Bootstrap, true),
//!     Rule::Refused(AlStatusCode::InvalidStateChange));
//! ```
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_op_in_unsafe_fn)]
#![deny(clippy::undocumented_unsafe_blocks)]
#![warn(missing_docs)]

#[cfg(any(test, feature = "alloc"))]
extern crate alloc;

pub mod al_status;
pub mod coe;
pub mod diag;
pub mod esc;
pub mod esi;
pub mod esm;
pub mod et1100;
pub mod foe;
pub mod lan9252;
pub mod leds;
pub mod mailbox;
pub mod od;
pub mod pdo;
pub mod registers;
pub mod sii;
pub mod slave;
pub mod sm;
pub mod sync;
pub mod wire;

pub use al_status::AlStatusCode;
pub use esc::{EscAccess, EscError};
