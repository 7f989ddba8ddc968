//! The EtherCAT mailbox header (ETG.1000.4/.6), mailbox error replies and the counter
//! rule. The server that uses them is [`crate::mailbox`].
//!
//! Wire layout (little-endian):
//!
//! | Byte | Bits | Field |
//! |---|---|---|
//! | 0–1 | | length = bytes following the header |
//! | 2–3 | | address (originator station address; 0 = master) |
//! | 4 | 5:0 | channel (0) |
//! | 4 | 7:6 | priority |
//! | 5 | 3:0 | type (0 error, 1 AoE, 2 EoE, 3 CoE, 4 FoE, 5 SoE, 15 VoE) |
//! | 5 | 6:4 | counter 1…7 (0 = no counter) |

/// Byte ranges of the mailbox header.
pub mod field {
    use core::ops::{Range, RangeFrom};
    /// Length of the data after the header (u16).
    pub const LENGTH: Range<usize> = 0..2;
    /// Station address of the originator (u16).
    pub const ADDRESS: Range<usize> = 2..4;
    /// Channel (bits 5:0) and priority (bits 7:6).
    pub const CHANNEL_PRIORITY: usize = 4;
    /// Type (bits 3:0) and counter (bits 6:4).
    pub const TYPE_COUNTER: usize = 5;
    /// The mailbox data.
    pub const PAYLOAD: RangeFrom<usize> = 6..;
}

/// Size of the mailbox header.
pub const HEADER_LEN: usize = 6;

/// Mailbox types (protocols).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MailboxType {
    /// Mailbox error reply.
    Error,
    /// ADS over EtherCAT.
    Aoe,
    /// Ethernet over EtherCAT.
    Eoe,
    /// CANopen over EtherCAT.
    Coe,
    /// File access over EtherCAT.
    Foe,
    /// Servo profile over EtherCAT.
    Soe,
    /// Vendor specific.
    Voe,
    /// Any other code.
    Unknown(u8),
}

impl MailboxType {
    /// Decodes the 4-bit type.
    pub const fn from_bits(v: u8) -> Self {
        match v & 0x0F {
            0 => Self::Error,
            1 => Self::Aoe,
            2 => Self::Eoe,
            3 => Self::Coe,
            4 => Self::Foe,
            5 => Self::Soe,
            0x0F => Self::Voe,
            x => Self::Unknown(x),
        }
    }
    /// The 4-bit code.
    pub const fn bits(self) -> u8 {
        match self {
            Self::Error => 0,
            Self::Aoe => 1,
            Self::Eoe => 2,
            Self::Coe => 3,
            Self::Foe => 4,
            Self::Soe => 5,
            Self::Voe => 0x0F,
            Self::Unknown(x) => x & 0x0F,
        }
    }
}

/// Detail codes of a mailbox error reply (type 0, service word 0x0001).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u16)]
pub enum ErrorDetail {
    /// Syntax of the 6-byte header is wrong (buffer shorter than a header).
    Syntax = 0x0001,
    /// The mailbox protocol is not supported (no handler for it, see
    /// [`Handlers`](crate::mailbox::Handlers)).
    UnsupportedProtocol = 0x0002,
    /// Channel field is not 0.
    InvalidChannel = 0x0003,
    /// The service of the protocol is not supported (CoE services other than 2 and 8).
    ServiceNotSupported = 0x0004,
    /// Invalid header: length 0 or type 0 (error) received from the master.
    InvalidHeader = 0x0005,
    /// The data is too short for the service it names.
    SizeTooShort = 0x0006,
    /// No memory for the request.
    NoMoreMemory = 0x0007,
    /// The length field is inconsistent (larger than the mailbox).
    InvalidSize = 0x0008,
    /// A service is in work.
    ServiceInWork = 0x0009,
}

impl ErrorDetail {
    /// Decodes a detail code.
    pub const fn from_code(v: u16) -> Option<Self> {
        Some(match v {
            1 => Self::Syntax,
            2 => Self::UnsupportedProtocol,
            3 => Self::InvalidChannel,
            4 => Self::ServiceNotSupported,
            5 => Self::InvalidHeader,
            6 => Self::SizeTooShort,
            7 => Self::NoMoreMemory,
            8 => Self::InvalidSize,
            9 => Self::ServiceInWork,
            _ => return None,
        })
    }
}

/// Why a buffer could not be read as a mailbox frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WireError {
    /// Shorter than the header, or the length field exceeds the buffer.
    Truncated,
}

/// A zero-copy view of a mailbox frame.
#[derive(Debug, Clone)]
pub struct Frame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Frame<T> {
    /// Wraps a buffer without checking it.
    pub const fn new_unchecked(buffer: T) -> Self {
        Frame { buffer }
    }
    /// Wraps a buffer after [`Frame::check_len`].
    pub fn new_checked(buffer: T) -> Result<Self, WireError> {
        let f = Self::new_unchecked(buffer);
        f.check_len()?;
        Ok(f)
    }
    /// Checks that the header fits and that the length field does not exceed the buffer;
    /// after this the accessors cannot panic.
    pub fn check_len(&self) -> Result<(), WireError> {
        let b = self.buffer.as_ref();
        if b.len() < HEADER_LEN || b.len() - HEADER_LEN < usize::from(self.length()) {
            return Err(WireError::Truncated);
        }
        Ok(())
    }
    /// Returns the buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }
    fn byte(&self, i: usize) -> u8 {
        self.buffer.as_ref().get(i).copied().unwrap_or(0)
    }
    /// The length field (0 when the buffer is too short to hold it).
    pub fn length(&self) -> u16 {
        u16::from_le_bytes([
            self.byte(field::LENGTH.start),
            self.byte(field::LENGTH.start + 1),
        ])
    }
    /// The address field.
    pub fn address(&self) -> u16 {
        u16::from_le_bytes([
            self.byte(field::ADDRESS.start),
            self.byte(field::ADDRESS.start + 1),
        ])
    }
    /// The channel (bits 5:0 of byte 4).
    pub fn channel(&self) -> u8 {
        self.byte(field::CHANNEL_PRIORITY) & 0x3F
    }
    /// The priority (bits 7:6 of byte 4).
    pub fn priority(&self) -> u8 {
        self.byte(field::CHANNEL_PRIORITY) >> 6
    }
    /// The mailbox type.
    pub fn mailbox_type(&self) -> MailboxType {
        MailboxType::from_bits(self.byte(field::TYPE_COUNTER))
    }
    /// The counter (0…7).
    pub fn counter(&self) -> u8 {
        (self.byte(field::TYPE_COUNTER) >> 4) & 0x07
    }
    /// The mailbox data: `length` bytes after the header (clamped to the buffer).
    pub fn payload(&self) -> &[u8] {
        let b = self.buffer.as_ref();
        let end = (HEADER_LEN + usize::from(self.length())).min(b.len());
        b.get(HEADER_LEN..end).unwrap_or(&[])
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Frame<T> {
    /// Sets the length field. Panics if the buffer is shorter than a header.
    pub fn set_length(&mut self, v: u16) {
        self.buffer.as_mut()[field::LENGTH].copy_from_slice(&v.to_le_bytes());
    }
    /// Sets the address field.
    pub fn set_address(&mut self, v: u16) {
        self.buffer.as_mut()[field::ADDRESS].copy_from_slice(&v.to_le_bytes());
    }
    /// Sets channel and priority.
    pub fn set_channel_priority(&mut self, channel: u8, priority: u8) {
        self.buffer.as_mut()[field::CHANNEL_PRIORITY] = (channel & 0x3F) | ((priority & 3) << 6);
    }
    /// Sets type and counter.
    pub fn set_type_counter(&mut self, t: MailboxType, counter: u8) {
        self.buffer.as_mut()[field::TYPE_COUNTER] = t.bits() | ((counter & 7) << 4);
    }
    /// Sets only the counter, keeping the type.
    /// (No-op on a buffer shorter than a header.)
    pub fn set_counter(&mut self, counter: u8) {
        if let Some(b) = self.buffer.as_mut().get_mut(field::TYPE_COUNTER) {
            *b = (*b & 0x8F) | ((counter & 7) << 4);
        }
    }
    /// The mailbox data area (everything after the header).
    pub fn payload_mut(&mut self) -> &mut [u8] {
        &mut self.buffer.as_mut()[field::PAYLOAD]
    }
}

/// A parsed mailbox header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Repr {
    /// Length of the data after the header.
    pub length: u16,
    /// Station address of the originator.
    pub address: u16,
    /// Channel.
    pub channel: u8,
    /// Priority 0…3.
    pub priority: u8,
    /// Type.
    pub mailbox_type: MailboxType,
    /// Counter 0…7.
    pub counter: u8,
}

impl Repr {
    /// Parses a checked frame.
    pub fn parse<T: AsRef<[u8]>>(frame: &Frame<T>) -> Result<Self, WireError> {
        frame.check_len()?;
        Ok(Repr {
            length: frame.length(),
            address: frame.address(),
            channel: frame.channel(),
            priority: frame.priority(),
            mailbox_type: frame.mailbox_type(),
            counter: frame.counter(),
        })
    }
    /// Writes the header into a frame whose buffer holds at least [`HEADER_LEN`] bytes
    /// (a shorter buffer is left as it is).
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, frame: &mut Frame<T>) {
        let [l0, l1] = self.length.to_le_bytes();
        let [a0, a1] = self.address.to_le_bytes();
        let cp = (self.channel & 0x3F) | ((self.priority & 3) << 6);
        let tc = self.mailbox_type.bits() | ((self.counter & 7) << 4);
        if let Some(b) = frame.buffer.as_mut().get_mut(..HEADER_LEN) {
            b.copy_from_slice(&[l0, l1, a0, a1, cp, tc]);
        }
    }
}

/// Writes a complete mailbox error reply (10 bytes) into `out`; returns its length, or 0
/// when `out` is too short. The counter is left 0.
pub fn emit_error(out: &mut [u8], detail: ErrorDetail) -> usize {
    let Some(buf) = out.get_mut(..HEADER_LEN + 4) else {
        return 0;
    };
    let mut f = Frame::new_unchecked(&mut *buf);
    Repr {
        length: 4,
        address: 0,
        channel: 0,
        priority: 0,
        mailbox_type: MailboxType::Error,
        counter: 0,
    }
    .emit(&mut f);
    let p = f.payload_mut();
    p[0..2].copy_from_slice(&1u16.to_le_bytes());
    p[2..4].copy_from_slice(&(detail as u16).to_le_bytes());
    HEADER_LEN + 4
}

/// Next outgoing counter after `c`: 1…7, wrapping 7 → 1.
pub const fn next_counter(c: u8) -> u8 {
    if c >= 7 || c == 0 {
        1
    } else {
        c + 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_parse_and_emit() {
        let bytes = [0x0A, 0x00, 0x34, 0x12, 0x40, 0x53, 1, 2];
        let f = Frame::new_checked(&bytes[..]).unwrap_err();
        assert_eq!(f, WireError::Truncated);
        let mut buf = [0u8; 16];
        buf[..8].copy_from_slice(&bytes);
        let f = Frame::new_checked(&buf[..]).unwrap();
        let r = Repr::parse(&f).unwrap();
        assert_eq!(
            r,
            Repr {
                length: 10,
                address: 0x1234,
                channel: 0,
                priority: 1,
                mailbox_type: MailboxType::Coe,
                counter: 5
            }
        );
        assert_eq!(f.payload(), &buf[6..16]);
        let mut out = [0u8; 6];
        r.emit(&mut Frame::new_unchecked(&mut out[..]));
        assert_eq!(out, bytes[..6]);
        // Out-of-range fields are masked like the setters do; a short buffer is untouched.
        let wide = Repr {
            length: 0xBEEF,
            address: 0xCAFE,
            channel: 0xFF,
            priority: 0xFF,
            mailbox_type: MailboxType::Error,
            counter: 0xFF,
        };
        let mut by_setters = [0u8; 8];
        let mut f = Frame::new_unchecked(&mut by_setters[..]);
        f.set_length(wide.length);
        f.set_address(wide.address);
        f.set_channel_priority(wide.channel, wide.priority);
        f.set_type_counter(wide.mailbox_type, wide.counter);
        let mut by_emit = [0u8; 8];
        wide.emit(&mut Frame::new_unchecked(&mut by_emit[..]));
        assert_eq!(by_emit, by_setters);
        assert_eq!(by_emit[..6], [0xEF, 0xBE, 0xFE, 0xCA, 0xFF, 0x70]);
        let mut short = [0x55u8; 5];
        wide.emit(&mut Frame::new_unchecked(&mut short[..]));
        assert_eq!(short, [0x55; 5]);
        let mut f = Frame::new_unchecked(&mut out[..]);
        f.set_counter(7);
        assert_eq!(f.counter(), 7);
        assert_eq!(f.mailbox_type(), MailboxType::Coe);
        assert_eq!(out[5], 0x73);
        // Accessors never panic on short buffers.
        let short = Frame::new_unchecked(&[0x05u8][..]);
        assert_eq!(short.length(), 5);
        assert_eq!(short.counter(), 0);
        assert!(short.payload().is_empty());
        assert!(short.check_len().is_err());
        let r = Repr::parse(&Frame::new_unchecked(&[0xFFu8, 0xFF, 0, 0, 0, 3][..]));
        assert_eq!(r, Err(WireError::Truncated));
    }

    #[test]
    fn types_details_counters() {
        for t in 0..16u8 {
            assert_eq!(MailboxType::from_bits(t).bits(), t);
        }
        assert_eq!(MailboxType::from_bits(0x13), MailboxType::Coe);
        for d in 1..=9u16 {
            assert_eq!(ErrorDetail::from_code(d).map(|e| e as u16), Some(d));
        }
        assert_eq!(ErrorDetail::from_code(0), None);
        assert_eq!(ErrorDetail::from_code(10), None);
        let mut c = 0;
        let mut seen = [0u8; 14];
        for s in seen.iter_mut() {
            c = next_counter(c);
            *s = c;
        }
        assert_eq!(seen, [1, 2, 3, 4, 5, 6, 7, 1, 2, 3, 4, 5, 6, 7]);
        let mut b = [0u8; 12];
        assert_eq!(emit_error(&mut b, ErrorDetail::InvalidSize), 10);
        assert_eq!(b[..10], [4, 0, 0, 0, 0, 0, 1, 0, 8, 0]);
        assert_eq!(emit_error(&mut b[..9], ErrorDetail::InvalidSize), 0);
    }
}
