//! CANopen over EtherCAT (ETG.1000.6): the CoE header and its services — the SDO server
//! ([`sdo`]), SDO information ([`info`]) and emergency messages ([`emcy`]). [`example`]
//! is a small dictionary used by the tests and benchmarks, and a reference for
//! implementing [`crate::od::Dictionary`].
//!
//! The CoE header is the u16 after the mailbox header: bits 8:0 number (PDO number, 0
//! for SDO), bits 11:9 reserved, bits 15:12 service.

pub mod emcy;
pub mod example;
pub mod info;
pub mod sdo;

pub use crate::wire::coe::{Header, Service, HEADER_LEN};
