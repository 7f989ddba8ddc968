//! The drive application: everything the EtherCAT CiA 402 stepper / hybrid-servo drive
//! decides, with no chip in it.
//!
//! The board binary (`src/main.rs`, feature `board`) and the simulator in `tests-host`
//! both call [`runtime::Runtime`], which owns the sequencing (start-up, the cycle, the
//! 1 ms tick, the mailbox work, the watchdog policy, outputs, brake and LEDs) over the
//! application in [`drive`] (object dictionary, [`cia402`] power drive system and
//! modes, [`motion`], [`faults`], [`params`], [`storage`], [`update`]). Hardware is
//! reached through small traits ([`runtime::ControlPath`], [`runtime::Pins`],
//! `ecat_slave_stack::esc::EscAccess`, the flash). ARCHITECTURE.md at the repository
//! root shows the layers and one cycle's path.
//!
//! # Example
//!
//! The DIP switches as a board reads them at power-up: on the EST-584 two-bank board
//! the ID bank gives the station alias (switches OFF add their weight) and the function
//! bank the peak current, which the drive uses while 0x2025 = 0.
//!
//! ```
//! use firmware::dip::{power_up, Board, EST584_CURRENT_MA};
//!
//! // ID bank: S1 OFF, the others ON → station 1. Function bank: all ON.
//! let dip = power_up(Board::TwoBanks, 0b1111_1110, 0xFF, 0);
//! assert_eq!(dip.address, 1);
//! let f = dip.functions.expect("a two-bank board always has function switches");
//! assert_eq!(f.peak_current_ma, EST584_CURRENT_MA[0]);
//! ```
#![no_std]
#![warn(missing_docs)]
#![deny(clippy::undocumented_unsafe_blocks)]
pub mod bind;
pub mod board_glue;
pub mod boot_state;
pub mod cia402;
pub mod comm;
pub mod commutation;
pub mod control_core;
pub mod current_supervisor;
pub mod diagnosis;
pub mod dictionary;
pub mod dip;
pub mod drive;
pub mod fault_led;
pub mod fault_table;
pub mod faults;
pub mod flash_layout;
pub mod flash_region;
pub mod identity;
pub mod io;
pub mod irq_priority;
pub mod latch;
pub mod mem;
pub mod monitor;
pub mod motion;
pub mod params;
pub mod pdo_defaults;
pub mod power_gate;
pub mod runtime;
pub mod sampling;
pub mod scope;
pub mod selftest;
pub mod servo_tune;
pub mod staged_flash;
pub mod storage;
pub mod update;
