//! The SDO information frame (CoE service 8, ETG.1000.6): opcode with the incomplete
//! flag, a reserved byte and a u16 "fragments left", then the service data. The
//! server that answers requests is [`crate::coe::info`].

use super::coe::{Header, Service, HEADER_LEN as COE_HEADER_LEN};
use crate::od::ObjectKey;

/// Size of the SDO information header (opcode, reserved, fragments left).
pub const INFO_HEADER_LEN: usize = 4;
/// CoE header + SDO information header.
pub const PREFIX_LEN: usize = COE_HEADER_LEN + INFO_HEADER_LEN;
/// Data type code reported for RECORD objects.
pub const RECORD_TYPE: u16 = 0x002A;

/// Byte offsets after the CoE header.
pub mod field {
    use core::ops::{Range, RangeFrom};
    /// Opcode (bits 6:0) and incomplete flag (bit 7).
    pub const OPCODE: usize = 0;
    /// Fragments left (u16).
    pub const FRAGMENTS_LEFT: Range<usize> = 2..4;
    /// Service data.
    pub const DATA: RangeFrom<usize> = 4..;
}

/// Opcodes.
pub mod opcode {
    /// Get OD list request.
    pub const OD_LIST_REQUEST: u8 = 0x01;
    /// Get OD list response.
    pub const OD_LIST_RESPONSE: u8 = 0x02;
    /// Get object description request.
    pub const OBJECT_DESCRIPTION_REQUEST: u8 = 0x03;
    /// Get object description response.
    pub const OBJECT_DESCRIPTION_RESPONSE: u8 = 0x04;
    /// Get entry description request.
    pub const ENTRY_DESCRIPTION_REQUEST: u8 = 0x05;
    /// Get entry description response.
    pub const ENTRY_DESCRIPTION_RESPONSE: u8 = 0x06;
    /// SDO information error.
    pub const ERROR: u8 = 0x07;
    /// Incomplete flag (more fragments follow).
    pub const INCOMPLETE: u8 = 0x80;
}

/// Value-info flags of the entry description.
pub mod value_info {
    /// Unit type (never answered by this server, see the module docs).
    pub const UNIT_TYPE: u8 = 0x08;
    /// Default value.
    pub const DEFAULT: u8 = 0x10;
    /// Minimum value.
    pub const MINIMUM: u8 = 0x20;
    /// Maximum value.
    pub const MAXIMUM: u8 = 0x40;
    /// The flags that carry no data and are echoed.
    pub const ECHOED: u8 = 0x07;
}

/// A zero-copy view of an SDO information frame (after the CoE header).
#[derive(Debug, Clone)]
pub struct Frame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Frame<T> {
    /// Wraps a buffer; accessors read 0 / empty beyond its end.
    pub const fn new(buffer: T) -> Self {
        Frame { buffer }
    }
    fn byte(&self, i: usize) -> u8 {
        self.buffer.as_ref().get(i).copied().unwrap_or(0)
    }
    /// True when the buffer holds the 4-byte header.
    pub fn has_header(&self) -> bool {
        self.buffer.as_ref().len() >= INFO_HEADER_LEN
    }
    /// Opcode without the incomplete flag.
    pub fn opcode(&self) -> u8 {
        self.byte(field::OPCODE) & 0x7F
    }
    /// Incomplete flag.
    pub fn incomplete(&self) -> bool {
        self.byte(field::OPCODE) & opcode::INCOMPLETE != 0
    }
    /// Fragments left.
    pub fn fragments_left(&self) -> u16 {
        u16::from_le_bytes([
            self.byte(field::FRAGMENTS_LEFT.start),
            self.byte(field::FRAGMENTS_LEFT.end - 1),
        ])
    }
    /// Service data.
    pub fn data(&self) -> &[u8] {
        self.buffer.as_ref().get(field::DATA).unwrap_or(&[])
    }
}

impl<T: AsRef<[u8]>> Frame<T> {
    /// Wraps a buffer after [`Frame::check_len`].
    pub fn new_checked(buffer: T) -> Result<Self, WireError> {
        let f = Self::new(buffer);
        f.check_len()?;
        Ok(f)
    }
    /// Checks that the 4-byte header fits.
    pub fn check_len(&self) -> Result<(), WireError> {
        if self.has_header() {
            Ok(())
        } else {
            Err(WireError::Truncated)
        }
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Frame<T> {
    /// Sets opcode, incomplete flag and fragments left (a buffer shorter than the header
    /// is left as it is).
    pub fn set_header(&mut self, op: u8, incomplete: bool, fragments_left: u16) {
        let op = (op & 0x7F) | if incomplete { opcode::INCOMPLETE } else { 0 };
        let [f0, f1] = fragments_left.to_le_bytes();
        if let Some(b) = self.buffer.as_mut().get_mut(..INFO_HEADER_LEN) {
            b.copy_from_slice(&[op, 0, f0, f1]);
        }
    }
    /// Service data, writable (empty for a buffer shorter than the header).
    pub fn data_mut(&mut self) -> &mut [u8] {
        self.buffer
            .as_mut()
            .get_mut(field::DATA)
            .unwrap_or_default()
    }
}

/// The fixed part of a get-object-description response, before the object's name:
/// u16 index, u16 data type, u8 maximum sub-index, u8 object code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ObjectDescriptionHead {
    /// Index.
    pub index: u16,
    /// Data type code.
    pub data_type: u16,
    /// Maximum sub-index.
    pub max_sub: u8,
    /// Object code (7 VAR, 8 ARRAY, 9 RECORD).
    pub object_code: u8,
}

impl ObjectDescriptionHead {
    /// Length of the emitted head.
    pub const LEN: usize = 6;
    /// Writes the head into the start of `out`; returns [`Self::LEN`], or 0 (nothing
    /// written) when `out` is shorter.
    pub fn emit(&self, out: &mut [u8]) -> usize {
        let Some(b) = out.get_mut(..Self::LEN) else {
            return 0;
        };
        let [i0, i1] = self.index.to_le_bytes();
        let [t0, t1] = self.data_type.to_le_bytes();
        b.copy_from_slice(&[i0, i1, t0, t1, self.max_sub, self.object_code]);
        Self::LEN
    }
}

/// The fixed part of a get-entry-description response, before the value fields
/// (default, minimum, maximum as `value_info` says) and the entry's name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EntryDescriptionHead {
    /// Index and sub-index.
    pub key: ObjectKey,
    /// Value info: which value fields follow ([`value_info`] flags).
    pub value_info: u8,
    /// Data type code.
    pub data_type: u16,
    /// Length in bits.
    pub bit_length: u16,
    /// Access word (read/write per state, PDO mappable, backup, setting).
    pub access: u16,
}

impl EntryDescriptionHead {
    /// Length of the emitted head.
    pub const LEN: usize = 10;
    /// Writes the head into the start of `out`; returns [`Self::LEN`], or 0 (nothing
    /// written) when `out` is shorter.
    pub fn emit(&self, out: &mut [u8]) -> usize {
        let Some(b) = out.get_mut(..Self::LEN) else {
            return 0;
        };
        let [i0, i1] = self.key.index.to_le_bytes();
        let [t0, t1] = self.data_type.to_le_bytes();
        let [l0, l1] = self.bit_length.to_le_bytes();
        let [a0, a1] = self.access.to_le_bytes();
        let sub = self.key.sub;
        b.copy_from_slice(&[i0, i1, sub, self.value_info, t0, t1, l0, l1, a0, a1]);
        Self::LEN
    }
}

/// Why a buffer could not be read as an SDO information frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WireError {
    /// Shorter than the header, or than the service data its opcode carries.
    Truncated,
}

/// An SDO information request, or the error response (the frames of a whole message;
/// responses other than the error are written fragment by fragment by
/// [`InfoJob`](crate::coe::info::InfoJob)).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Repr {
    /// Get OD list request (0x01).
    OdList {
        /// List type (0 = counts, 1 = all, 2 = RxPDO, 3 = TxPDO, 4 = backup, 5 = settings).
        list: u16,
    },
    /// Get object description request (0x03).
    ObjectDescription {
        /// Index.
        index: u16,
    },
    /// Get entry description request (0x05).
    EntryDescription {
        /// Index and sub-index.
        key: ObjectKey,
        /// Value-info request ([`value_info`] flags).
        value_info: u8,
    },
    /// SDO information error (0x07).
    Error {
        /// Abort code.
        code: u32,
    },
    /// Any other opcode (its service data is not read).
    Unknown {
        /// Opcode without the incomplete flag.
        opcode: u8,
    },
}

impl Repr {
    /// Parses a frame (header fragments-left and incomplete flag not checked).
    pub fn parse<T: AsRef<[u8]>>(frame: &Frame<T>) -> Result<Self, WireError> {
        frame.check_len()?;
        let d = frame.data();
        let need = |n: usize| {
            if d.len() < n {
                Err(WireError::Truncated)
            } else {
                Ok(())
            }
        };
        let u16_at = |i: usize| u16::from_le_bytes([d[i], d[i + 1]]);
        Ok(match frame.opcode() {
            opcode::OD_LIST_REQUEST => {
                need(2)?;
                Repr::OdList { list: u16_at(0) }
            }
            opcode::OBJECT_DESCRIPTION_REQUEST => {
                need(2)?;
                Repr::ObjectDescription { index: u16_at(0) }
            }
            opcode::ENTRY_DESCRIPTION_REQUEST => {
                need(4)?;
                Repr::EntryDescription {
                    key: ObjectKey::new(u16_at(0), d[2]),
                    value_info: d[3],
                }
            }
            opcode::ERROR => {
                need(4)?;
                Repr::Error {
                    code: u32::from_le_bytes([d[0], d[1], d[2], d[3]]),
                }
            }
            op => Repr::Unknown { opcode: op },
        })
    }

    /// Length of the emitted frame after the CoE header.
    pub const fn buffer_len(&self) -> usize {
        INFO_HEADER_LEN
            + match self {
                Repr::OdList { .. } | Repr::ObjectDescription { .. } => 2,
                Repr::EntryDescription { .. } | Repr::Error { .. } => 4,
                Repr::Unknown { .. } => 0,
            }
    }

    /// Writes the frame (after the CoE header, as one complete fragment) into the start
    /// of `frame`'s buffer; returns its length, or 0 (buffer untouched) when the buffer
    /// is shorter than [`Repr::buffer_len`].
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, frame: &mut Frame<T>) -> usize {
        let n = self.buffer_len();
        if frame.buffer.as_ref().len() < n {
            return 0;
        }
        let (op, data): (u8, [u8; 4]) = match *self {
            Repr::OdList { list } => {
                let [a, b] = list.to_le_bytes();
                (opcode::OD_LIST_REQUEST, [a, b, 0, 0])
            }
            Repr::ObjectDescription { index } => {
                let [a, b] = index.to_le_bytes();
                (opcode::OBJECT_DESCRIPTION_REQUEST, [a, b, 0, 0])
            }
            Repr::EntryDescription { key, value_info } => {
                let [a, b] = key.index.to_le_bytes();
                (
                    opcode::ENTRY_DESCRIPTION_REQUEST,
                    [a, b, key.sub, value_info],
                )
            }
            Repr::Error { code } => (opcode::ERROR, code.to_le_bytes()),
            Repr::Unknown { opcode } => (opcode, [0; 4]),
        };
        frame.set_header(op, false, 0);
        let len = n - INFO_HEADER_LEN;
        frame.data_mut()[..len].copy_from_slice(&data[..len]);
        n
    }

    /// Writes the CoE header (service 8) and the frame into `out`; returns the length of
    /// both, or 0 (nothing written) when `out` is too short.
    pub fn emit_coe(&self, out: &mut [u8]) -> usize {
        if out.len() < COE_HEADER_LEN + self.buffer_len() {
            return 0;
        }
        let (head, body) = out.split_at_mut(COE_HEADER_LEN);
        Header::of(Service::SdoInformation).emit(head);
        COE_HEADER_LEN + self.emit(&mut Frame::new(body))
    }
}

/// Writes the CoE header and the information header of a response fragment into
/// `out[..6]` (a shorter `out` is left as it is).
pub fn emit_prefix(out: &mut [u8], op: u8, incomplete: bool, fragments_left: u16) {
    if let Some((head, body)) = out
        .get_mut(..PREFIX_LEN)
        .map(|b| b.split_at_mut(COE_HEADER_LEN))
    {
        Header::of(Service::SdoInformation).emit(head);
        Frame::new(body).set_header(op, incomplete, fragments_left);
    }
}
