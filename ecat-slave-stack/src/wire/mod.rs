//! Frame formats, smoltcp style: a `Frame`/`Packet` view over a byte buffer with checked
//! accessors, and a `Repr` that parses from and emits into such a view. No state and no
//! server logic: the servers ([`crate::mailbox`], [`crate::coe::sdo`], [`crate::foe`])
//! sit beside this module and use only these types for the bytes they read and write.
//!
//! * [`mailbox`]: the 6-byte mailbox header, mailbox error replies, the counter rule
//!   (ETG.1000.4 / ETG.1000.6).
//! * [`coe`]: the CoE header and its services.
//! * [`sdo`]: SDO requests and responses (expedited, normal, segmented, abort).
//! * [`sdo_info`]: SDO information requests and fragment headers.
//! * [`emcy`]: the emergency message.
//! * [`foe`]: the FoE header, opcodes and error codes.

#![deny(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap,
    clippy::cast_lossless
)]

pub mod coe;
pub mod emcy;
pub mod foe;
pub mod mailbox;
pub mod sdo;
pub mod sdo_info;
