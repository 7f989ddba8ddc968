//! The record header: a field view over the first [`HEADER_LEN`] bytes of a slot,
//! the one place that knows where each field lies (`field`).
//!
//! # Record format (version 1)
//! Little-endian throughout:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic ([`RECORD_MAGIC`] "ECSP", [`HISTORY_MAGIC`] "ECSH") |
//! | 4 | 2 | format version ([`FORMAT_VERSION`]) |
//! | 6 | 2 | flags (0) |
//! | 8 | 4 | sequence number (wrapping; the newer record wins) |
//! | 12 | 4 | payload length in bytes |
//! | 16 | 4 | CRC-32 (IEEE) of the payload followed by bytes 0..16 |
//! | 20 | 12 | reserved (0) |
//! | 32 | n | payload |

/// Record magic of the parameter records ("ECSP" little-endian).
pub const RECORD_MAGIC: u32 = 0x5053_4345;
/// Record magic of the fault-history records ("ECSH" little-endian): a store of
/// another kind (or a slot of an older layout) never passes for one of these.
pub const HISTORY_MAGIC: u32 = 0x4853_4345;
/// Record format version.
pub const FORMAT_VERSION: u16 = 1;
/// Header length; also the write/read granularity the storage needs (WRITE_SIZE and
/// READ_SIZE must divide it).
pub const HEADER_LEN: usize = 32;
/// The header's first double word (magic, format, flags): written last, it commits a
/// record (when the flash's write unit divides it; else the header is one write).
pub const COMMIT_WORD: usize = 8;

/// Byte ranges of the header fields.
pub mod field {
    use core::ops::Range;
    /// Record magic, `u32`.
    pub const MAGIC: Range<usize> = 0..4;
    /// Format version, `u16`.
    pub const FORMAT: Range<usize> = 4..6;
    /// Flags, `u16` (0).
    pub const FLAGS: Range<usize> = 6..8;
    /// Sequence number, `u32`.
    pub const SEQUENCE: Range<usize> = 8..12;
    /// Payload length, `u32`.
    pub const PAYLOAD_LEN: Range<usize> = 12..16;
    /// CRC-32 of the payload and [`CHECKED`], `u32`.
    pub const CRC: Range<usize> = 16..20;
    /// The header bytes the CRC covers (after the payload).
    pub const CHECKED: Range<usize> = 0..16;
}

/// A record header over a buffer of at least [`HEADER_LEN`] bytes (shorter buffers
/// read as zeros and ignore writes: no panic path).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RecordHeader<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> RecordHeader<T> {
    /// The view over `buffer`, whatever its length.
    pub const fn new_unchecked(buffer: T) -> Self {
        RecordHeader { buffer }
    }

    /// The view over `buffer` when it holds a whole header.
    pub fn new_checked(buffer: T) -> Option<Self> {
        (buffer.as_ref().len() >= HEADER_LEN).then_some(RecordHeader { buffer })
    }

    /// The buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    fn get<const N: usize>(&self, r: core::ops::Range<usize>) -> [u8; N] {
        self.buffer
            .as_ref()
            .get(r)
            .and_then(|b| b.try_into().ok())
            .unwrap_or([0; N])
    }

    /// Record magic.
    pub fn magic(&self) -> u32 {
        u32::from_le_bytes(self.get(field::MAGIC))
    }
    /// Format version.
    pub fn format_version(&self) -> u16 {
        u16::from_le_bytes(self.get(field::FORMAT))
    }
    /// Flags.
    pub fn flags(&self) -> u16 {
        u16::from_le_bytes(self.get(field::FLAGS))
    }
    /// Sequence number.
    pub fn sequence(&self) -> u32 {
        u32::from_le_bytes(self.get(field::SEQUENCE))
    }
    /// Payload length in bytes.
    pub fn payload_len(&self) -> u32 {
        u32::from_le_bytes(self.get(field::PAYLOAD_LEN))
    }
    /// Stored CRC-32.
    pub fn crc(&self) -> u32 {
        u32::from_le_bytes(self.get(field::CRC))
    }
    /// The header bytes the CRC covers after the payload ([`field::CHECKED`]).
    pub fn checked_part(&self) -> &[u8] {
        self.buffer.as_ref().get(field::CHECKED).unwrap_or(&[])
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> RecordHeader<T> {
    fn set(&mut self, r: core::ops::Range<usize>, v: &[u8]) {
        if let Some(b) = self.buffer.as_mut().get_mut(r) {
            if b.len() == v.len() {
                b.copy_from_slice(v);
            }
        }
    }

    /// Sets the record magic.
    pub fn set_magic(&mut self, v: u32) {
        self.set(field::MAGIC, &v.to_le_bytes());
    }
    /// Sets the format version.
    pub fn set_format_version(&mut self, v: u16) {
        self.set(field::FORMAT, &v.to_le_bytes());
    }
    /// Sets the flags.
    pub fn set_flags(&mut self, v: u16) {
        self.set(field::FLAGS, &v.to_le_bytes());
    }
    /// Sets the sequence number.
    pub fn set_sequence(&mut self, v: u32) {
        self.set(field::SEQUENCE, &v.to_le_bytes());
    }
    /// Sets the payload length.
    pub fn set_payload_len(&mut self, v: u32) {
        self.set(field::PAYLOAD_LEN, &v.to_le_bytes());
    }
    /// Sets the CRC-32.
    pub fn set_crc(&mut self, v: u32) {
        self.set(field::CRC, &v.to_le_bytes());
    }
}

impl RecordHeader<[u8; HEADER_LEN]> {
    /// A header of this format: `magic`, [`FORMAT_VERSION`], flags 0, `sequence`,
    /// `payload_len`; CRC and reserved bytes 0 (the CRC is set when the payload is
    /// known, [`RecordHeader::set_crc`]).
    pub fn new(magic: u32, sequence: u32, payload_len: u32) -> Self {
        let mut h = RecordHeader::new_unchecked([0; HEADER_LEN]);
        h.set_magic(magic);
        h.set_format_version(FORMAT_VERSION);
        h.set_sequence(sequence);
        h.set_payload_len(payload_len);
        h
    }
}
