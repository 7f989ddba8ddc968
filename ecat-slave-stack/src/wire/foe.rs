//! The FoE header (ETG.1000.6 mailbox type 4), its opcodes and error codes. The
//! server that runs transfers is [`crate::foe`].
//!
//! Wire layout after the mailbox header (little-endian):
//!
//! | Byte | Field |
//! |---|---|
//! | 0 | opcode: 1 RRQ, 2 WRQ, 3 DATA, 4 ACK, 5 ERR, 6 BUSY |
//! | 1 | reserved (0) |
//! | 2–5 | u32: password (RRQ/WRQ, 0 = none), packet number (DATA/ACK), error code (ERR); BUSY: u16 done @2, u16 entire @4 |
//! | 6… | file name without NUL (RRQ/WRQ), file data (DATA), error text (ERR, BUSY), nothing (ACK) |

use super::mailbox::HEADER_LEN as MAILBOX_HEADER_LEN;

/// Size of the FoE header.
pub const HEADER_LEN: usize = 6;
/// Bytes of a mailbox that carry no file data (mailbox header + FoE header).
pub const OVERHEAD: usize = MAILBOX_HEADER_LEN + HEADER_LEN;

/// Byte ranges of the FoE header.
pub mod field {
    use core::ops::{Range, RangeFrom};
    /// Opcode.
    pub const OPCODE: usize = 0;
    /// Reserved byte.
    pub const RESERVED: usize = 1;
    /// Password, packet number or error code (u32).
    pub const ARG: Range<usize> = 2..6;
    /// BUSY: done (u16).
    pub const BUSY_DONE: Range<usize> = 2..4;
    /// BUSY: entire (u16).
    pub const BUSY_ENTIRE: Range<usize> = 4..6;
    /// File name, data or error text.
    pub const PAYLOAD: RangeFrom<usize> = 6..;
}

/// FoE opcodes (byte 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Opcode {
    /// Read request (master reads a file from the slave).
    Read,
    /// Write request (master writes a file to the slave).
    Write,
    /// File data.
    Data,
    /// Acknowledge of a DATA (or of a WRQ, number 0).
    Ack,
    /// Error, ends the transfer.
    Error,
    /// The receiver is busy; the sender repeats its last DATA.
    Busy,
    /// Any other code.
    Unknown(u8),
}

impl Opcode {
    /// Decodes byte 0.
    pub const fn from_u8(v: u8) -> Self {
        match v {
            1 => Self::Read,
            2 => Self::Write,
            3 => Self::Data,
            4 => Self::Ack,
            5 => Self::Error,
            6 => Self::Busy,
            x => Self::Unknown(x),
        }
    }
    /// The code.
    pub const fn code(self) -> u8 {
        match self {
            Self::Read => 1,
            Self::Write => 2,
            Self::Data => 3,
            Self::Ack => 4,
            Self::Error => 5,
            Self::Busy => 6,
            Self::Unknown(x) => x,
        }
    }
}

/// FoE error codes (ETG.1000.6; SSC `foeappl.h` texts).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum ErrorCode {
    /// Not defined.
    NotDefined = 0x8000,
    /// The requested file was not found.
    NotFound = 0x8001,
    /// Read or write access to this file is not allowed (e.g. local control).
    AccessDenied = 0x8002,
    /// The file does not fit (storage full, image larger than its partition).
    DiskFull = 0x8003,
    /// Illegal FoE operation (wrong opcode for the transfer state, oversized DATA).
    Illegal = 0x8004,
    /// Packet number invalid (repeated or out of order).
    PacketNumber = 0x8005,
    /// The file to be written exists already.
    AlreadyExists = 0x8006,
    /// No user.
    NoUser = 0x8007,
    /// FoE (this file) is only supported in Bootstrap.
    BootstrapOnly = 0x8008,
    /// This file may not be accessed in Bootstrap.
    NotInBootstrap = 0x8009,
    /// Password invalid.
    NoRights = 0x800A,
    /// Generic programming error (reason cannot be told apart).
    ProgramError = 0x800B,
    /// A checksum included in the file is invalid.
    InvalidChecksum = 0x800C,
    /// The hardware does not support the downloaded firmware.
    FirmwareNotForHardware = 0x800D,
    /// Do not use (identical to 0x8001).
    NoFile = 0x800F,
    /// File header missing or wrong.
    FileHeader = 0x8010,
    /// Flash cannot be accessed.
    FlashError = 0x8011,
}

impl ErrorCode {
    /// Every code, in numeric order.
    pub const ALL: &'static [ErrorCode] = &[
        Self::NotDefined,
        Self::NotFound,
        Self::AccessDenied,
        Self::DiskFull,
        Self::Illegal,
        Self::PacketNumber,
        Self::AlreadyExists,
        Self::NoUser,
        Self::BootstrapOnly,
        Self::NotInBootstrap,
        Self::NoRights,
        Self::ProgramError,
        Self::InvalidChecksum,
        Self::FirmwareNotForHardware,
        Self::NoFile,
        Self::FileHeader,
        Self::FlashError,
    ];
    /// The 32-bit code.
    pub const fn code(self) -> u32 {
        self as u32
    }
    /// Decodes a code (`None` for 0x800E and codes outside 0x8000–0x8011).
    pub fn from_code(v: u32) -> Option<Self> {
        Self::ALL.iter().copied().find(|c| c.code() == v)
    }
    /// A short English text.
    pub const fn text(self) -> &'static str {
        match self {
            Self::NotDefined => "not defined",
            Self::NotFound => "file not found",
            Self::AccessDenied => "access denied",
            Self::DiskFull => "disk full",
            Self::Illegal => "illegal",
            Self::PacketNumber => "packet number wrong",
            Self::AlreadyExists => "already exists",
            Self::NoUser => "no user",
            Self::BootstrapOnly => "bootstrap only",
            Self::NotInBootstrap => "not in bootstrap",
            Self::NoRights => "no rights",
            Self::ProgramError => "program error",
            Self::InvalidChecksum => "invalid checksum",
            Self::FirmwareNotForHardware => "firmware does not fit the hardware",
            Self::NoFile => "no file",
            Self::FileHeader => "file header wrong",
            Self::FlashError => "flash error",
        }
    }
}

/// Why a buffer could not be read as a FoE frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WireError {
    /// Shorter than the 6-byte header.
    Truncated,
    /// Opcode outside 1…6.
    UnknownOpcode(u8),
}

/// A zero-copy view of a FoE frame (the mailbox payload).
#[derive(Debug, Clone)]
pub struct Frame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Frame<T> {
    /// Wraps a buffer without checking it; accessors read missing bytes as 0.
    pub const fn new_unchecked(buffer: T) -> Self {
        Frame { buffer }
    }
    /// Wraps a buffer after [`Frame::check_len`].
    pub fn new_checked(buffer: T) -> Result<Self, WireError> {
        let f = Self::new_unchecked(buffer);
        f.check_len()?;
        Ok(f)
    }
    /// Checks that the 6-byte header fits.
    pub fn check_len(&self) -> Result<(), WireError> {
        if self.buffer.as_ref().len() < HEADER_LEN {
            Err(WireError::Truncated)
        } else {
            Ok(())
        }
    }
    /// Returns the buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }
    fn byte(&self, i: usize) -> u8 {
        self.buffer.as_ref().get(i).copied().unwrap_or(0)
    }
    /// The opcode.
    pub fn opcode(&self) -> Opcode {
        Opcode::from_u8(self.byte(field::OPCODE))
    }
    /// The reserved byte.
    pub fn reserved(&self) -> u8 {
        self.byte(field::RESERVED)
    }
    /// Bytes 2–5 as u32: password, packet number or error code.
    pub fn arg(&self) -> u32 {
        let s = field::ARG.start;
        u32::from_le_bytes([
            self.byte(s),
            self.byte(s + 1),
            self.byte(s + 2),
            self.byte(s + 3),
        ])
    }
    /// Password of RRQ / WRQ.
    pub fn password(&self) -> u32 {
        self.arg()
    }
    /// Packet number of DATA / ACK.
    pub fn packet_number(&self) -> u32 {
        self.arg()
    }
    /// Error code of ERR.
    pub fn error_code(&self) -> u32 {
        self.arg()
    }
    /// BUSY: done.
    pub fn busy_done(&self) -> u16 {
        let s = field::BUSY_DONE.start;
        u16::from_le_bytes([self.byte(s), self.byte(s + 1)])
    }
    /// BUSY: entire.
    pub fn busy_entire(&self) -> u16 {
        let s = field::BUSY_ENTIRE.start;
        u16::from_le_bytes([self.byte(s), self.byte(s + 1)])
    }
    /// Everything after the header (file name, data, error text).
    pub fn payload(&self) -> &[u8] {
        self.buffer.as_ref().get(field::PAYLOAD).unwrap_or(&[])
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Frame<T> {
    /// Sets the opcode and clears the reserved byte (no-op on an empty buffer).
    pub fn set_opcode(&mut self, op: Opcode) {
        let b = self.buffer.as_mut();
        if let Some(x) = b.get_mut(field::OPCODE) {
            *x = op.code();
        }
        if let Some(x) = b.get_mut(field::RESERVED) {
            *x = 0;
        }
    }
    /// Sets bytes 2–5 (no-op on a buffer shorter than the header).
    pub fn set_arg(&mut self, v: u32) {
        if let Some(b) = self.buffer.as_mut().get_mut(field::ARG) {
            b.copy_from_slice(&v.to_le_bytes());
        }
    }
    /// Sets the BUSY done / entire fields (no-op on a buffer shorter than the header).
    pub fn set_busy(&mut self, done: u16, entire: u16) {
        let [d0, d1] = done.to_le_bytes();
        let [e0, e1] = entire.to_le_bytes();
        if let Some(b) = self.buffer.as_mut().get_mut(field::ARG) {
            b.copy_from_slice(&[d0, d1, e0, e1]);
        }
    }
    /// The area after the header (empty for a buffer shorter than the header).
    pub fn payload_mut(&mut self) -> &mut [u8] {
        self.buffer
            .as_mut()
            .get_mut(field::PAYLOAD)
            .unwrap_or_default()
    }
}

/// A parsed FoE frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Repr<'a> {
    /// RRQ: read `name`.
    Read {
        /// Password (0 = none).
        password: u32,
        /// File name, without NUL.
        name: &'a [u8],
    },
    /// WRQ: write `name`.
    Write {
        /// Password (0 = none).
        password: u32,
        /// File name, without NUL.
        name: &'a [u8],
    },
    /// DATA.
    Data {
        /// Packet number, from 1.
        packet: u32,
        /// File bytes.
        data: &'a [u8],
    },
    /// ACK.
    Ack {
        /// Number of the DATA acknowledged (0 for the WRQ).
        packet: u32,
    },
    /// ERR.
    Error {
        /// Error code ([`ErrorCode`] for the standard ones).
        code: u32,
        /// Optional text.
        text: &'a [u8],
    },
    /// BUSY.
    Busy {
        /// Progress: done.
        done: u16,
        /// Progress: entire (0 = unknown).
        entire: u16,
        /// Optional text.
        text: &'a [u8],
    },
}

impl<'a> Repr<'a> {
    /// Parses a frame; the payload is the rest of the buffer (the caller passes exactly
    /// the mailbox data, `length` bytes).
    pub fn parse(frame: &Frame<&'a [u8]>) -> Result<Self, WireError> {
        frame.check_len()?;
        let payload: &'a [u8] = frame.buffer.get(field::PAYLOAD).unwrap_or(&[]);
        Ok(match frame.opcode() {
            Opcode::Read => Repr::Read {
                password: frame.password(),
                name: payload,
            },
            Opcode::Write => Repr::Write {
                password: frame.password(),
                name: payload,
            },
            Opcode::Data => Repr::Data {
                packet: frame.packet_number(),
                data: payload,
            },
            Opcode::Ack => Repr::Ack {
                packet: frame.packet_number(),
            },
            Opcode::Error => Repr::Error {
                code: frame.error_code(),
                text: payload,
            },
            Opcode::Busy => Repr::Busy {
                done: frame.busy_done(),
                entire: frame.busy_entire(),
                text: payload,
            },
            Opcode::Unknown(x) => return Err(WireError::UnknownOpcode(x)),
        })
    }

    /// The opcode.
    pub const fn opcode(&self) -> Opcode {
        match self {
            Repr::Read { .. } => Opcode::Read,
            Repr::Write { .. } => Opcode::Write,
            Repr::Data { .. } => Opcode::Data,
            Repr::Ack { .. } => Opcode::Ack,
            Repr::Error { .. } => Opcode::Error,
            Repr::Busy { .. } => Opcode::Busy,
        }
    }

    fn payload(&self) -> &'a [u8] {
        match *self {
            Repr::Read { name, .. } | Repr::Write { name, .. } => name,
            Repr::Data { data, .. } => data,
            Repr::Ack { .. } => &[],
            Repr::Error { text, .. } | Repr::Busy { text, .. } => text,
        }
    }

    /// Length of the emitted frame (the mailbox `length` field).
    pub fn buffer_len(&self) -> usize {
        HEADER_LEN + self.payload().len()
    }

    /// Writes the frame into the start of `frame`'s buffer; returns its length, or 0
    /// (buffer untouched) when the buffer is shorter than [`Repr::buffer_len`].
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, frame: &mut Frame<T>) -> usize {
        let n = self.buffer_len();
        if frame.buffer.as_ref().len() < n {
            return 0;
        }
        frame.set_opcode(self.opcode());
        match *self {
            Repr::Read { password, .. } | Repr::Write { password, .. } => frame.set_arg(password),
            Repr::Data { packet, .. } | Repr::Ack { packet } => frame.set_arg(packet),
            Repr::Error { code, .. } => frame.set_arg(code),
            Repr::Busy { done, entire, .. } => frame.set_busy(done, entire),
        }
        let p = self.payload();
        if let Some(dst) = frame.payload_mut().get_mut(..p.len()) {
            dst.copy_from_slice(p);
        }
        n
    }
}
