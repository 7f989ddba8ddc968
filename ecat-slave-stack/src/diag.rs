//! ETG.1020 diagnosis history (object 0x10F3): a ring of diagnosis messages that a
//! master reads over SDO (TwinCAT's "Diag History" tab), beside the emergencies.
//!
//! ```text
//! 0x10F3:00  u8    highest sub-index (5 + N)
//!        :01  u8    maximum messages (N)
//!        :02  u8    newest message (its sub-index, 6..5+N; 0 = none)
//!        :03  u8    newest acknowledged (RW: 0 clears the history; 6..5+N acknowledges)
//!        :04  BOOL  new messages available (TxPDO-mappable)
//!        :05  u16   flags (RW: bit 0 send as emergency, bits 1-3 suppress info /
//!                   warning / error messages, bit 4 acknowledge mode; bit 5 a message
//!                   was lost, read-only)
//!        :06..      diagnosis messages, OCTET STRING of MESSAGE_LEN bytes
//! ```
//!
//! A message ([`DiagMessage`], [`DiagMessage::emit`] / [`DiagMessage::parse`]):
//!
//! ```text
//! 0   u32  diagnosis code (0xE800 | emergency code << 16 for an emergency, 0xE000-0xE7FF
//!          manufacturer)
//! 4   u16  flags: bits 0-3 type (0 info, 1 warning, 2 error), bit 4 the time stamp is
//!          local (time since power-up, not the DC system time), bits 8-15 parameters
//! 6   u16  text ID (the ESI's <DiagMessages> text with %d / %X placeholders)
//! 8   u64  time stamp, ns
//! 16  per parameter: u16 flags (bits 12-15 = 0: a value of the CoE type in bits 0-11)
//!     then the value (little endian)
//! ```
//!
//! **Overwrite mode** (flags bit 4 = 0, the default): a new message takes the next
//! slot of the ring, overwriting the oldest; overwriting the newest acknowledged one
//! resets SI3 to 0 and sets the "lost" flag. SI4 is set by a new message and cleared
//! when the master reads the newest message. **Acknowledge mode** (bit 4 = 1): a full
//! ring (every slot unacknowledged) drops new messages (the "lost" flag is set);
//! SI4 is set while the newest is not acknowledged.
//!
//! Writes: SI3 = 0 clears the ring; SI3 = the sub-index of a stored message
//! acknowledges it and every older one; other values are refused (value range); SI5
//! takes bits 0-4 (bit 5 is read-only). A complete-access read gets every entry,
//! each message at its declared 28 bytes (a shorter message padded with zeros), in
//! one image (`coe::sdo`); complete-access writes are refused.

use crate::od::SdoAbort;

/// Bytes of one message in the ring: the 16-byte header and two parameters of at
/// most 4 bytes each (2 + 4 bytes per parameter).
pub const MESSAGE_LEN: usize = 28;
/// Parameters a message can carry.
pub const MAX_PARAMS: usize = 2;
/// Sub-index of the first message.
pub const FIRST_MESSAGE_SUB: u8 = 6;

/// Flag bits of SI5.
pub mod flags {
    /// Send each new message as an emergency too (stored; the product sends its
    /// emergencies anyway).
    pub const SEND_AS_EMERGENCY: u16 = 1 << 0;
    /// Do not store info messages.
    pub const DISABLE_INFO: u16 = 1 << 1;
    /// Do not store warning messages.
    pub const DISABLE_WARNING: u16 = 1 << 2;
    /// Do not store error messages.
    pub const DISABLE_ERROR: u16 = 1 << 3;
    /// Acknowledge mode instead of overwrite mode.
    pub const ACK_MODE: u16 = 1 << 4;
    /// A message was lost (overwritten unacknowledged, or dropped), read-only.
    pub const LOST: u16 = 1 << 5;
    /// The bits a master may write.
    pub const WRITABLE: u16 = 0x001F;
}

/// The diagnosis code of an emergency with error code `emcy`.
pub const fn emergency_code(emcy: u16) -> u32 {
    0xE800 | (emcy as u32) << 16
}

/// Message type (flags bits 0-3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Severity {
    /// Information.
    Info = 0,
    /// Warning.
    Warning = 1,
    /// Error.
    Error = 2,
}

impl Severity {
    const fn disable_bit(self) -> u16 {
        match self {
            Severity::Info => flags::DISABLE_INFO,
            Severity::Warning => flags::DISABLE_WARNING,
            Severity::Error => flags::DISABLE_ERROR,
        }
    }
}

/// The text of a message, for the ESI's `<DiagMessages>` (the device's one table of
/// texts: its messages carry the `id`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DiagText {
    /// Text ID (message bytes 6-7).
    pub id: u16,
    /// Type.
    pub severity: Severity,
    /// English text; `%d` / `%X` are the parameters in order.
    pub text: &'static str,
}

/// A parameter of a message: a value of a CoE basic type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Param {
    /// UINT8.
    U8(u8),
    /// UINT16.
    U16(u16),
    /// UINT32.
    U32(u32),
    /// INT16.
    I16(i16),
    /// INT32.
    I32(i32),
}

impl Param {
    /// The CoE data type (parameter flags bits 0-11) and the value's bytes.
    fn split(self) -> (u16, [u8; 4], usize) {
        let mut b = [0u8; 4];
        let (t, n) = match self {
            Param::U8(v) => {
                b[0] = v;
                (0x0005, 1)
            }
            Param::U16(v) => {
                b[..2].copy_from_slice(&v.to_le_bytes());
                (0x0006, 2)
            }
            Param::U32(v) => {
                b.copy_from_slice(&v.to_le_bytes());
                (0x0007, 4)
            }
            Param::I16(v) => {
                b[..2].copy_from_slice(&v.to_le_bytes());
                (0x0003, 2)
            }
            Param::I32(v) => {
                b.copy_from_slice(&v.to_le_bytes());
                (0x0004, 4)
            }
        };
        (t, b, n)
    }

    fn from_wire(flags: u16, v: &[u8]) -> Option<(Param, usize)> {
        if flags >> 12 != 0 {
            return None;
        }
        let u16_at = |v: &[u8]| Some(u16::from_le_bytes([*v.first()?, *v.get(1)?]));
        let u32_at = |v: &[u8]| Some(u32::from_le_bytes(v.get(..4)?.try_into().ok()?));
        Some(match flags & 0x0FFF {
            0x0005 => (Param::U8(*v.first()?), 1),
            0x0006 => (Param::U16(u16_at(v)?), 2),
            0x0007 => (Param::U32(u32_at(v)?), 4),
            0x0003 => (Param::I16(u16_at(v)? as i16), 2),
            0x0004 => (Param::I32(u32_at(v)? as i32), 4),
            _ => return None,
        })
    }
}

/// One diagnosis message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DiagMessage {
    /// Diagnosis code.
    pub code: u32,
    /// Type.
    pub severity: Severity,
    /// Text ID of the ESI's message text.
    pub text_id: u16,
    /// Time stamp, ns.
    pub time_ns: u64,
    /// The time stamp is local (since power-up), not the DC system time.
    pub local_time: bool,
    /// Parameters (the first `n_params` are used).
    pub params: [Param; MAX_PARAMS],
    /// Number of parameters.
    pub n_params: u8,
}

impl DiagMessage {
    /// A message without parameters.
    pub const fn new(code: u32, severity: Severity, text_id: u16, time_ns: u64) -> Self {
        DiagMessage {
            code,
            severity,
            text_id,
            time_ns,
            local_time: true,
            params: [Param::U8(0); MAX_PARAMS],
            n_params: 0,
        }
    }

    /// The message with one more parameter (ignored beyond [`MAX_PARAMS`]).
    pub const fn with(mut self, p: Param) -> Self {
        if (self.n_params as usize) < MAX_PARAMS {
            self.params[self.n_params as usize] = p;
            self.n_params += 1;
        }
        self
    }

    /// Writes the message into `buf` (at least [`MESSAGE_LEN`] bytes; the rest of the
    /// slot is zero); returns its length.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        let out = buf.get_mut(..MESSAGE_LEN).ok_or(SdoAbort::ExceedsMailbox)?;
        out.fill(0);
        let n = (self.n_params as usize).min(MAX_PARAMS);
        let f = self.severity as u16 | u16::from(self.local_time) << 4 | (n as u16) << 8;
        out[0..4].copy_from_slice(&self.code.to_le_bytes());
        out[4..6].copy_from_slice(&f.to_le_bytes());
        out[6..8].copy_from_slice(&self.text_id.to_le_bytes());
        out[8..16].copy_from_slice(&self.time_ns.to_le_bytes());
        let mut at = 16;
        for p in &self.params[..n] {
            let (t, b, len) = p.split();
            out[at..at + 2].copy_from_slice(&t.to_le_bytes());
            out[at + 2..at + 2 + len].copy_from_slice(&b[..len]);
            at += 2 + len;
        }
        Ok(MESSAGE_LEN)
    }

    /// Reads a message written by [`DiagMessage::emit`] (a master's view; tests).
    /// `None` for a buffer too short, an unknown type or parameter.
    pub fn parse(b: &[u8]) -> Option<DiagMessage> {
        let h = b.get(..16)?;
        let code = u32::from_le_bytes(h[0..4].try_into().ok()?);
        let f = u16::from_le_bytes([h[4], h[5]]);
        let severity = match f & 0x0F {
            0 => Severity::Info,
            1 => Severity::Warning,
            2 => Severity::Error,
            _ => return None,
        };
        let n = usize::from(f >> 8);
        if n > MAX_PARAMS {
            return None;
        }
        let mut m = DiagMessage::new(
            code,
            severity,
            u16::from_le_bytes([h[6], h[7]]),
            u64::from_le_bytes(h[8..16].try_into().ok()?),
        );
        m.local_time = f & 0x10 != 0;
        let mut at = 16;
        for _ in 0..n {
            let pf = u16::from_le_bytes([*b.get(at)?, *b.get(at + 1)?]);
            let (p, len) = Param::from_wire(pf, b.get(at + 2..)?)?;
            m = m.with(p);
            at += 2 + len;
        }
        Some(m)
    }
}

/// The 0x10F3 state: a ring of `N` messages (1 ≤ N ≤ 250).
#[derive(Debug, Clone)]
pub struct DiagHistory<const N: usize> {
    ring: [Option<DiagMessage>; N],
    /// Ring index of the newest message (valid when `count > 0`).
    newest: usize,
    /// Messages stored (≤ N).
    count: usize,
    /// Ring index of the newest acknowledged message.
    acked: Option<usize>,
    new_available: bool,
    flags: u16,
}

impl<const N: usize> Default for DiagHistory<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> DiagHistory<N> {
    const CHECK: () = assert!(N >= 1 && N <= 250, "0x10F3 holds 1 to 250 messages");

    /// An empty history in overwrite mode.
    pub const fn new() -> Self {
        let () = Self::CHECK;
        DiagHistory {
            ring: [None; N],
            newest: 0,
            count: 0,
            acked: None,
            new_available: false,
            flags: 0,
        }
    }

    /// Sub-index of ring slot `i`.
    fn sub_of(i: usize) -> u8 {
        FIRST_MESSAGE_SUB + i as u8
    }

    /// Adds a message (unless its type is suppressed by SI5). Returns true when it was
    /// stored.
    pub fn push(&mut self, m: DiagMessage) -> bool {
        if self.flags & m.severity.disable_bit() != 0 {
            return false;
        }
        let ack_mode = self.flags & flags::ACK_MODE != 0;
        let next = if self.count == 0 {
            0
        } else {
            (self.newest + 1) % N
        };
        if self.count == N {
            // `next` holds the oldest message; it counts as acknowledged when any
            // message is (an acknowledgement covers every older one).
            if ack_mode && self.acked.is_none() {
                self.flags |= flags::LOST;
                return false;
            }
            if self.acked == Some(next) {
                // The acknowledged message itself goes: nothing stored is
                // acknowledged any more. In overwrite mode that is a lost message.
                self.acked = None;
                if !ack_mode {
                    self.flags |= flags::LOST;
                }
            }
        }
        self.ring[next] = Some(m);
        self.newest = next;
        self.count = (self.count + 1).min(N);
        self.new_available = true;
        true
    }

    /// Number of messages stored.
    pub fn len(&self) -> usize {
        self.count
    }

    /// True when no message is stored.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The message `age` steps older than the newest (0 = newest).
    pub fn get(&self, age: usize) -> Option<&DiagMessage> {
        if age >= self.count {
            return None;
        }
        self.ring[(self.newest + N - age) % N].as_ref()
    }

    /// SI4.
    pub fn new_messages_available(&self) -> bool {
        if self.flags & flags::ACK_MODE != 0 {
            self.count > 0 && self.acked != Some(self.newest)
        } else {
            self.new_available
        }
    }

    /// SI5.
    pub fn flags(&self) -> u16 {
        self.flags
    }

    /// Highest sub-index (SI0).
    pub const fn highest_sub() -> u8 {
        FIRST_MESSAGE_SUB - 1 + N as u8
    }

    /// SDO upload of `sub` into `buf`; returns the length. Reading the newest
    /// message clears SI4 (overwrite mode).
    pub fn read(&mut self, sub: u8, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        let n = self.peek(sub, buf)?;
        if self.count > 0 && sub == self.newest_sub() {
            self.new_available = false;
        }
        Ok(n)
    }

    /// [`Self::read`] without its side effect (process data, diagnostics).
    pub fn peek(&self, sub: u8, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        let put = |buf: &mut [u8], b: &[u8]| -> Result<usize, SdoAbort> {
            buf.get_mut(..b.len())
                .ok_or(SdoAbort::ExceedsMailbox)?
                .copy_from_slice(b);
            Ok(b.len())
        };
        match sub {
            0 => put(buf, &[Self::highest_sub()]),
            1 => put(buf, &[N as u8]),
            2 => put(buf, &[self.newest_sub()]),
            3 => put(buf, &[self.acked.map_or(0, Self::sub_of)]),
            4 => put(buf, &[u8::from(self.new_messages_available())]),
            5 => put(buf, &self.flags.to_le_bytes()),
            s if s >= FIRST_MESSAGE_SUB && s <= Self::highest_sub() => {
                let i = usize::from(s - FIRST_MESSAGE_SUB);
                match self.ring[i] {
                    Some(m) if self.holds(i) => m.emit(buf),
                    _ => {
                        // An empty slot reads as zeros.
                        let out = buf.get_mut(..MESSAGE_LEN).ok_or(SdoAbort::ExceedsMailbox)?;
                        out.fill(0);
                        Ok(MESSAGE_LEN)
                    }
                }
            }
            _ => Err(SdoAbort::SubindexDoesNotExist),
        }
    }

    fn newest_sub(&self) -> u8 {
        if self.count == 0 {
            0
        } else {
            Self::sub_of(self.newest)
        }
    }

    /// SDO download of `data` into `sub` (SI3, SI5; everything else is read-only).
    pub fn write(&mut self, sub: u8, data: &[u8]) -> Result<(), SdoAbort> {
        match (sub, data) {
            (3, &[v]) => {
                if v == 0 {
                    if self.flags & flags::ACK_MODE != 0 {
                        self.clear_acknowledged();
                    } else {
                        self.clear();
                    }
                    return Ok(());
                }
                if v < FIRST_MESSAGE_SUB || v > Self::highest_sub() {
                    return Err(SdoAbort::ValueRangeExceeded);
                }
                let i = usize::from(v - FIRST_MESSAGE_SUB);
                if !self.holds(i) {
                    return Err(SdoAbort::ValueRangeExceeded);
                }
                self.acked = Some(i);
                Ok(())
            }
            (5, &[lo, hi]) => {
                let v = u16::from_le_bytes([lo, hi]);
                self.flags = (self.flags & flags::LOST) | (v & flags::WRITABLE);
                Ok(())
            }
            (3, d) | (5, d) if d.len() > if sub == 3 { 1 } else { 2 } => {
                Err(SdoAbort::LengthTooHigh)
            }
            (3 | 5, _) => Err(SdoAbort::LengthTooLow),
            (0..=2 | 4, _) => Err(SdoAbort::WriteReadOnly),
            _ if sub <= Self::highest_sub() => Err(SdoAbort::WriteReadOnly),
            _ => Err(SdoAbort::SubindexDoesNotExist),
        }
    }

    /// Age of ring slot `i` (0 = the newest message).
    fn age_of(&self, i: usize) -> usize {
        (self.newest + N - i) % N
    }

    /// True when ring slot `i` holds one of the stored messages.
    fn holds(&self, i: usize) -> bool {
        i < N && self.age_of(i) < self.count
    }

    /// SI3 = 0 in acknowledge mode: removes the acknowledged message and every older
    /// one (the unacknowledged ones stay where they are), and the "lost" flag.
    pub fn clear_acknowledged(&mut self) {
        if let Some(a) = self.acked.take() {
            self.count = self.age_of(a);
            for i in 0..N {
                if !self.holds(i) {
                    self.ring[i] = None;
                }
            }
        }
        self.flags &= !flags::LOST;
    }

    /// Clears every message and the "lost" flag (SI3 = 0 in overwrite mode).
    pub fn clear(&mut self) {
        self.ring = [None; N];
        self.count = 0;
        self.newest = 0;
        self.acked = None;
        self.new_available = false;
        self.flags &= !flags::LOST;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn msg(k: u16) -> DiagMessage {
        DiagMessage::new(
            emergency_code(0x2310),
            Severity::Error,
            k,
            u64::from(k) * 1000,
        )
        .with(Param::I16(-1200))
        .with(Param::U16(480))
    }

    #[test]
    fn message_bytes_round_trip() {
        let m = msg(7);
        let mut b = [0xAAu8; 32];
        assert_eq!(m.emit(&mut b), Ok(MESSAGE_LEN));
        assert_eq!(
            &b[..MESSAGE_LEN],
            &[
                0x00, 0xE8, 0x10, 0x23, // code 0xE800 | 0x2310 << 16
                0x12, 0x02, // error, local time, 2 parameters
                0x07, 0x00, // text ID
                0x58, 0x1B, 0, 0, 0, 0, 0, 0, // 7000 ns
                0x03, 0x00, 0x50, 0xFB, // INT16 -1200
                0x06, 0x00, 0xE0, 0x01, // UINT16 480
                0, 0, 0, 0,
            ]
        );
        assert_eq!(b[MESSAGE_LEN], 0xAA, "nothing past the slot");
        assert_eq!(DiagMessage::parse(&b), Some(m));
        assert_eq!(m.emit(&mut [0u8; 27]), Err(SdoAbort::ExceedsMailbox));
        // Garbage from outside: unknown type, too many parameters, short buffers.
        assert_eq!(DiagMessage::parse(&b[..15]), None);
        let mut bad = b;
        bad[4] = 0x05;
        assert_eq!(DiagMessage::parse(&bad), None);
        bad = b;
        bad[5] = 9;
        assert_eq!(DiagMessage::parse(&bad), None);
        bad = b;
        bad[17] = 0x40;
        assert_eq!(DiagMessage::parse(&bad), None);
    }

    fn rd(h: &mut DiagHistory<4>, sub: u8) -> u16 {
        let mut b = [0u8; 32];
        let n = h.read(sub, &mut b).unwrap();
        match n {
            1 => u16::from(b[0]),
            2 => u16::from_le_bytes([b[0], b[1]]),
            _ => u16::from_le_bytes([b[6], b[7]]),
        }
    }

    #[test]
    fn overwrite_mode_ring_newest_and_new_flag() {
        let mut h = DiagHistory::<4>::new();
        assert_eq!((rd(&mut h, 0), rd(&mut h, 1), rd(&mut h, 2)), (9, 4, 0));
        assert_eq!(rd(&mut h, 4), 0);
        assert_eq!(rd(&mut h, 6), 0, "empty slot reads zeros");
        for k in 1..=3 {
            assert!(h.push(msg(k)));
        }
        assert_eq!(rd(&mut h, 2), 8, "newest in SI8");
        assert_eq!(rd(&mut h, 4), 1);
        assert_eq!(rd(&mut h, 7), 2);
        assert_eq!(rd(&mut h, 4), 1, "reading an older one keeps SI4");
        assert_eq!(rd(&mut h, 8), 3);
        assert_eq!(rd(&mut h, 4), 0, "reading the newest clears SI4");
        // Acknowledge SI7, then wrap: 4 fills SI9, 5 overwrites SI6, 6 overwrites the
        // acknowledged SI7 → SI3 = 0, lost.
        h.write(3, &[7]).unwrap();
        assert_eq!(rd(&mut h, 3), 7);
        h.push(msg(4));
        h.push(msg(5));
        assert_eq!(rd(&mut h, 2), 6);
        assert_eq!(rd(&mut h, 6), 5);
        assert_eq!(
            rd(&mut h, 5) & flags::LOST,
            0,
            "the overwritten one was acknowledged"
        );
        h.push(msg(6));
        assert_eq!(rd(&mut h, 3), 0);
        assert_ne!(rd(&mut h, 5) & flags::LOST, 0);
        assert_eq!(h.get(0).map(|m| m.text_id), Some(6));
        assert_eq!(h.get(3).map(|m| m.text_id), Some(3));
        assert_eq!(h.get(4), None);
        // Clear.
        h.write(3, &[0]).unwrap();
        assert_eq!((h.len(), rd(&mut h, 2), rd(&mut h, 5)), (0, 0, 0));
    }

    #[test]
    fn acknowledge_mode_drops_when_full_of_unacknowledged() {
        let mut h = DiagHistory::<4>::new();
        h.write(5, &flags::ACK_MODE.to_le_bytes()).unwrap();
        for k in 1..=4 {
            assert!(h.push(msg(k)));
        }
        assert_eq!(rd(&mut h, 4), 1);
        assert!(!h.push(msg(5)), "full, nothing acknowledged: dropped");
        assert_ne!(rd(&mut h, 5) & flags::LOST, 0);
        assert_eq!(h.get(0).map(|m| m.text_id), Some(4));
        // Acknowledge the second (and so the first): the oldest slot may be reused.
        h.write(3, &[7]).unwrap();
        assert!(h.push(msg(5)));
        assert_eq!(rd(&mut h, 6), 5);
        assert_eq!(rd(&mut h, 3), 7);
        // The acknowledged one itself is the oldest now: reused, nothing acknowledged.
        assert!(h.push(msg(6)));
        assert_eq!(rd(&mut h, 3), 0);
        assert!(!h.push(msg(7)), "full of unacknowledged messages");
        assert_eq!(rd(&mut h, 4), 1);
        h.write(3, &[7]).unwrap();
        assert_eq!(rd(&mut h, 4), 0, "newest acknowledged");
    }

    #[test]
    fn acknowledge_mode_clear_removes_only_the_acknowledged() {
        let mut h = DiagHistory::<4>::new();
        h.write(5, &flags::ACK_MODE.to_le_bytes()).unwrap();
        h.write(3, &[0]).unwrap();
        assert!(h.is_empty(), "nothing acknowledged, nothing stored");
        for k in 1..=4 {
            assert!(h.push(msg(k)));
        }
        assert!(!h.push(msg(5)), "full: dropped, lost flag");
        // Acknowledge the second (sub 7): SI3 = 0 removes it and the first.
        h.write(3, &[7]).unwrap();
        h.write(3, &[0]).unwrap();
        assert_eq!(h.len(), 2);
        assert_eq!((rd(&mut h, 2), rd(&mut h, 3), rd(&mut h, 4)), (9, 0, 1));
        assert_eq!(rd(&mut h, 5) & flags::LOST, 0, "lost flag cleared");
        let text = |h: &mut DiagHistory<4>, sub: u8| {
            let mut b = [0u8; MESSAGE_LEN];
            h.read(sub, &mut b).unwrap();
            DiagMessage::parse(&b).map(|m| m.text_id)
        };
        assert_eq!((text(&mut h, 8), text(&mut h, 9)), (Some(3), Some(4)));
        let mut b = [0xFFu8; MESSAGE_LEN];
        h.read(6, &mut b).unwrap();
        assert_eq!(b, [0; MESSAGE_LEN], "removed: reads as zeros");
        assert_eq!(h.write(3, &[6]), Err(SdoAbort::ValueRangeExceeded));
        // The freed slots take the next messages, in order.
        assert!(h.push(msg(5)) && h.push(msg(6)));
        assert_eq!((text(&mut h, 6), text(&mut h, 7)), (Some(5), Some(6)));
        assert_eq!(rd(&mut h, 2), 7);
        assert!(!h.push(msg(7)), "full of unacknowledged again");
        // Acknowledging the newest and clearing empties it.
        h.write(3, &[7]).unwrap();
        h.write(3, &[0]).unwrap();
        assert!(h.is_empty());
        assert_eq!((rd(&mut h, 2), rd(&mut h, 4)), (0, 0));
        assert!(h.push(msg(8)));
        assert_eq!(rd(&mut h, 2), 6);
    }

    #[test]
    fn bad_writes_get_the_standard_answers_and_change_nothing() {
        let mut h = DiagHistory::<4>::new();
        h.push(msg(1));
        assert_eq!(
            h.write(3, &[7]),
            Err(SdoAbort::ValueRangeExceeded),
            "empty slot"
        );
        assert_eq!(h.write(3, &[5]), Err(SdoAbort::ValueRangeExceeded));
        assert_eq!(h.write(3, &[10]), Err(SdoAbort::ValueRangeExceeded));
        assert_eq!(h.write(3, &[6, 0]), Err(SdoAbort::LengthTooHigh));
        assert_eq!(h.write(3, &[]), Err(SdoAbort::LengthTooLow));
        assert_eq!(h.write(5, &[1]), Err(SdoAbort::LengthTooLow));
        assert_eq!(h.write(5, &[1, 2, 3]), Err(SdoAbort::LengthTooHigh));
        for sub in [0, 1, 2, 4, 6, 9] {
            assert_eq!(h.write(sub, &[0]), Err(SdoAbort::WriteReadOnly), "SI{sub}");
        }
        assert_eq!(h.write(10, &[0]), Err(SdoAbort::SubindexDoesNotExist));
        assert_eq!(
            h.read(10, &mut [0u8; 32]),
            Err(SdoAbort::SubindexDoesNotExist)
        );
        assert_eq!(h.read(6, &mut [0u8; 8]), Err(SdoAbort::ExceedsMailbox));
        // The lost bit is read-only; bits 6-15 are ignored.
        h.write(5, &0xFFFFu16.to_le_bytes()).unwrap();
        assert_eq!(h.flags(), flags::WRITABLE);
        assert_eq!(h.len(), 1);
        // Suppressed types are not stored.
        assert!(!h.push(msg(2)), "errors disabled");
    }
}
