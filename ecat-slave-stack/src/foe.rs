//! File access over EtherCAT (FoE, ETG.1000.6 mailbox type 4): the 6-byte FoE header,
//! the error codes, and the [`FoeServer`] that runs read and write transfers against
//! the application's files ([`FoeFiles`]), e.g. a firmware image writer in Bootstrap.
//!
//! Wire layout after the mailbox header (little-endian):
//!
//! | Byte | Field |
//! |---|---|
//! | 0 | opcode: 1 RRQ, 2 WRQ, 3 DATA, 4 ACK, 5 ERR, 6 BUSY |
//! | 1 | reserved (0) |
//! | 2–5 | u32: password (RRQ/WRQ, 0 = none), packet number (DATA/ACK), error code (ERR); BUSY: u16 done @2, u16 entire @4 |
//! | 6… | file name without NUL (RRQ/WRQ), file data (DATA), error text (ERR, BUSY), nothing (ACK) |
//!
//! A DATA frame carries at most the mailbox size − 12 bytes (mailbox header 6 + FoE
//! header 6): that is the *segment*. A file ends with the first DATA shorter than a
//! segment; a file whose size is a multiple of the segment ends with a 0-byte DATA.
//! SOEM and IgH both size segments by the SM0 (master → slave) length, in both
//! directions.
//!
//! # The server
//!
//! Write (master → slave): WRQ → [`FoeFiles::open_write`] → ACK 0; DATA 1, 2, 3… each
//! passed to [`FoeFiles::write`] at its file offset and answered with ACK of its
//! number, or BUSY while the backend is still erasing or writing (the master then
//! resends the same DATA, which is written again at the same offset); the last (short)
//! DATA is followed by [`FoeFiles::finish_write`] before its ACK, so an image that
//! fails verification is answered with ERR instead.
//!
//! Read (slave → master): RRQ → [`FoeFiles::open_read`] → DATA 1 with the first
//! segment; every ACK of the last DATA sent brings the next one; the ACK of the last
//! (short or 0-byte) DATA ends the transfer without an answer.
//!
//! Rules:
//! * A packet number other than the expected one (a repeated DATA, a DATA that skips
//!   one, an ACK of another DATA) → ERR 0x8005, the transfer is aborted. A repetition
//!   on the *mailbox* level (same mailbox counter) never reaches the server: the
//!   mailbox answers it again without executing it ([`crate::mailbox`]).
//! * A DATA longer than a segment, a DATA or ACK without an open transfer of its
//!   direction, a BUSY or an unknown opcode from the master → ERR 0x8004 (illegal);
//!   an open transfer is aborted.
//! * An ERR from the master aborts the transfer silently (no answer).
//! * A new WRQ or RRQ while a transfer is open aborts the old one and starts the new
//!   one.
//! * A transfer without a request for [`FoeServer::timeout_us`] (default
//!   [`DEFAULT_TIMEOUT_US`], 10 s) is aborted by [`FoeServer::tick`] without an
//!   answer: the master has given up long before (SOEM waits 0.7–2 s, IgH 3 s) and an
//!   unsolicited ERR would be taken as the answer to its next request.
//! * "Aborted" means [`FoeFiles::abort`] is called: exactly once for every transfer
//!   that was opened successfully and did not complete successfully (including the
//!   ones where the backend itself returned an error).
//! * A FoE payload shorter than the 6-byte header gets the mailbox error "size too
//!   short" and aborts an open transfer.
//! * The server does not decide which files may be written in which state: it passes
//!   `in_boot` to the backend. A file that may only be written in Bootstrap answers
//!   [`ErrorCode::BootstrapOnly`] (0x8008, SSC "FoE only supported in Bootstrap");
//!   one that may not be accessed in Bootstrap answers [`ErrorCode::NotInBootstrap`]
//!   (0x8009, SSC "this file may not be accessed in BOOTSTRAP state"). SOES uses
//!   0x8009 for the first case; this stack follows the SSC meaning of the codes.
//! * The server never answers BUSY to a WRQ (SOEM ends a write that sees BUSY before
//!   its first DATA), so slow preparation (erasing) belongs in [`FoeFiles::write`].
//!
//! No heap, no panics: all sizes are checked, the state is a few words.

use crate::mailbox::{ErrorDetail, HEADER_LEN as MAILBOX_HEADER_LEN};

/// Size of the FoE header.
pub const HEADER_LEN: usize = 6;
/// Bytes of a mailbox that carry no file data (mailbox header + FoE header).
pub const OVERHEAD: usize = MAILBOX_HEADER_LEN + HEADER_LEN;
/// Default transfer timeout: a transfer without a request for this long is aborted, µs.
pub const DEFAULT_TIMEOUT_US: u64 = 10_000_000;
/// BUSY "entire" value sent by the server: "done" is a percentage.
pub const BUSY_ENTIRE: u16 = 100;

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

/// What [`FoeFiles::write`] did with one DATA.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WriteStatus {
    /// The data is taken (stored or buffered): the DATA is acknowledged.
    Done,
    /// Not taken yet (e.g. the flash page is still being erased): the server answers
    /// BUSY with this progress, the master resends the same DATA and `write` is called
    /// again with the same offset and data.
    Busy {
        /// Progress of the whole transfer, 0–100 % (larger values are sent as 100).
        done_percent: u8,
    },
    /// The data cannot be written: the server answers ERR with this code and aborts
    /// the transfer.
    Err(ErrorCode),
}

/// The application's files, as the FoE server sees them. A firmware image writer
/// implements this for its image file(s); `abort` must leave the target in a state
/// the bootloader will not start (e.g. leave the update partition unmarked).
///
/// The server calls `open_*` once per request, then `write`/`read` with increasing
/// offsets, then `finish_write` (writes) or `finish_read` (reads) — or `abort` once if
/// the transfer ends any other way. At most one transfer is open at a time.
pub trait FoeFiles {
    /// WRQ for `name` (bytes as received, no NUL) with `password` (0 = none);
    /// `in_boot` is true in the Bootstrap state. `Err` is answered with ERR (e.g.
    /// [`ErrorCode::NotFound`], [`ErrorCode::NoRights`], [`ErrorCode::BootstrapOnly`]).
    fn open_write(&mut self, name: &[u8], password: u32, in_boot: bool) -> Result<(), ErrorCode>;
    /// The data of one DATA, at file offset `offset` (bytes from the start). Called
    /// again with the same arguments after [`WriteStatus::Busy`].
    fn write(&mut self, offset: u32, data: &[u8]) -> WriteStatus;
    /// The last DATA was written: complete the file (flush, verify the image, mark it
    /// for the bootloader). Runs before the ACK of the last DATA; `Err` is answered
    /// with ERR instead (e.g. [`ErrorCode::InvalidChecksum`]).
    fn finish_write(&mut self) -> Result<(), ErrorCode>;
    /// RRQ for `name`: returns the file length in bytes. `Err` is answered with ERR.
    fn open_read(&mut self, name: &[u8], password: u32, in_boot: bool) -> Result<u32, ErrorCode>;
    /// Copies file bytes from `offset` into `buf` (at most `buf.len()`, never past the
    /// length `open_read` returned) and returns how many. Fewer than asked ends the
    /// file early.
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> usize;
    /// The master acknowledged the last DATA of a read.
    fn finish_read(&mut self) {}
    /// The open transfer ended without success (master ERR, protocol error, timeout,
    /// replaced by a new request, mailbox stopped, or an error of the backend itself).
    fn abort(&mut self);
}

/// The conditions a request is served under.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Context {
    /// The slave is in Bootstrap (passed to `open_*`).
    pub in_boot: bool,
    /// Largest DATA the master may send: SM0 length − 12 bytes.
    pub write_segment: usize,
    /// DATA size of reads: SM0 length − 12 (what SOEM and IgH expect), or 0 when that
    /// does not fit SM1 (reads are then refused with ERR 0x8004).
    pub read_segment: usize,
    /// Time of the request, µs (for the timeout).
    pub now_us: u64,
}

/// What one request produced.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Answer {
    /// No answer (master ERR, ACK of the last DATA of a read).
    None,
    /// A FoE frame of this many bytes is in the output buffer.
    Frame(usize),
    /// The request is malformed on the mailbox level: answer this mailbox error.
    MailboxError(ErrorDetail),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Transfer {
    Idle,
    /// Receiving a file: `next` is the expected DATA number, `offset` its file offset.
    Writing {
        next: u32,
        offset: u32,
    },
    /// Sending a file: DATA `sent` is out, the next one starts at `offset`; `last` when
    /// DATA `sent` was the final (short) one.
    Reading {
        sent: u32,
        offset: u32,
        len: u32,
        last: bool,
    },
}

/// Direction of the open transfer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Master → slave (WRQ).
    Write,
    /// Slave → master (RRQ).
    Read,
}

/// The FoE state machine of the slave (see the module docs). A few words of state, no
/// buffers: answers are written into the caller's output buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FoeServer {
    transfer: Transfer,
    timeout_us: u64,
    last_us: u64,
}

impl Default for FoeServer {
    fn default() -> Self {
        Self::new()
    }
}

impl FoeServer {
    /// An idle server with the [`DEFAULT_TIMEOUT_US`] timeout.
    pub const fn new() -> Self {
        FoeServer {
            transfer: Transfer::Idle,
            timeout_us: DEFAULT_TIMEOUT_US,
            last_us: 0,
        }
    }

    /// The transfer timeout, µs.
    pub const fn timeout_us(&self) -> u64 {
        self.timeout_us
    }

    /// Sets the transfer timeout, µs.
    pub fn set_timeout_us(&mut self, us: u64) {
        self.timeout_us = us;
    }

    /// The open transfer's direction, if any.
    pub const fn active(&self) -> Option<Direction> {
        match self.transfer {
            Transfer::Idle => None,
            Transfer::Writing { .. } => Some(Direction::Write),
            Transfer::Reading { .. } => Some(Direction::Read),
        }
    }

    /// Bytes written so far in the open write transfer (0 otherwise).
    pub const fn write_offset(&self) -> u32 {
        match self.transfer {
            Transfer::Writing { offset, .. } => offset,
            _ => 0,
        }
    }

    /// Forgets the open transfer without telling the backend (call [`Self::abort`]
    /// first where the backend is at hand).
    pub fn reset(&mut self) {
        self.transfer = Transfer::Idle;
    }

    /// Aborts the open transfer: [`FoeFiles::abort`] if one is open. Returns whether
    /// one was.
    pub fn abort<F: FoeFiles + ?Sized>(&mut self, files: &mut F) -> bool {
        if self.transfer == Transfer::Idle {
            return false;
        }
        self.transfer = Transfer::Idle;
        files.abort();
        true
    }

    /// Timeout supervision: aborts a transfer idle for longer than the timeout (no
    /// answer, see the module docs). Returns whether it did.
    pub fn tick<F: FoeFiles + ?Sized>(&mut self, now_us: u64, files: &mut F) -> bool {
        if self.transfer != Transfer::Idle && now_us.saturating_sub(self.last_us) > self.timeout_us
        {
            return self.abort(files);
        }
        false
    }

    /// One FoE request (`payload` = the mailbox data). The answer, if any, is written
    /// into `out` (the mailbox data area of the answer, at least `ctx.read_segment` +
    /// 6 bytes for reads and 6 bytes otherwise).
    pub fn on_request<F: FoeFiles + ?Sized>(
        &mut self,
        payload: &[u8],
        files: &mut F,
        ctx: Context,
        out: &mut [u8],
    ) -> Answer {
        let frame = Frame::new_unchecked(payload);
        let req = match Repr::parse(&frame) {
            Ok(r) => r,
            Err(WireError::Truncated) => {
                self.abort(files);
                return Answer::MailboxError(ErrorDetail::SizeTooShort);
            }
            Err(WireError::UnknownOpcode(_)) => return self.fail(files, ErrorCode::Illegal, out),
        };
        self.last_us = ctx.now_us;
        match req {
            Repr::Write { password, name } => {
                self.abort(files);
                match files.open_write(name, password, ctx.in_boot) {
                    Ok(()) => {
                        self.transfer = Transfer::Writing { next: 1, offset: 0 };
                        emit(out, &Repr::Ack { packet: 0 })
                    }
                    Err(e) => emit_error(out, e),
                }
            }
            Repr::Read { password, name } => {
                self.abort(files);
                if ctx.read_segment == 0 {
                    return emit_error(out, ErrorCode::Illegal);
                }
                match files.open_read(name, password, ctx.in_boot) {
                    Ok(len) => self.send_data(files, 1, 0, len, ctx.read_segment, out),
                    Err(e) => emit_error(out, e),
                }
            }
            Repr::Data { packet, data } => self.on_data(files, packet, data, ctx, out),
            Repr::Ack { packet } => match self.transfer {
                Transfer::Reading {
                    sent,
                    offset,
                    len,
                    last,
                } if packet == sent => {
                    if last {
                        self.transfer = Transfer::Idle;
                        files.finish_read();
                        Answer::None
                    } else {
                        self.send_data(files, sent + 1, offset, len, ctx.read_segment, out)
                    }
                }
                Transfer::Reading { .. } => self.fail(files, ErrorCode::PacketNumber, out),
                _ => self.fail(files, ErrorCode::Illegal, out),
            },
            Repr::Error { .. } => {
                self.abort(files);
                Answer::None
            }
            Repr::Busy { .. } => self.fail(files, ErrorCode::Illegal, out),
        }
    }

    fn on_data<F: FoeFiles + ?Sized>(
        &mut self,
        files: &mut F,
        packet: u32,
        data: &[u8],
        ctx: Context,
        out: &mut [u8],
    ) -> Answer {
        let Transfer::Writing { next, offset } = self.transfer else {
            return self.fail(files, ErrorCode::Illegal, out);
        };
        if data.len() > ctx.write_segment {
            return self.fail(files, ErrorCode::Illegal, out);
        }
        if packet != next {
            return self.fail(files, ErrorCode::PacketNumber, out);
        }
        let Some(end) = u32::try_from(data.len())
            .ok()
            .and_then(|n| offset.checked_add(n))
        else {
            return self.fail(files, ErrorCode::DiskFull, out);
        };
        if !data.is_empty() {
            match files.write(offset, data) {
                WriteStatus::Done => {}
                WriteStatus::Busy { done_percent } => {
                    let done = u16::from(done_percent.min(100));
                    return emit(
                        out,
                        &Repr::Busy {
                            done,
                            entire: BUSY_ENTIRE,
                            text: &[],
                        },
                    );
                }
                WriteStatus::Err(e) => return self.fail(files, e, out),
            }
        }
        if data.len() < ctx.write_segment {
            // The last DATA: the file is complete once the backend accepts it.
            if let Err(e) = files.finish_write() {
                return self.fail(files, e, out);
            }
            self.transfer = Transfer::Idle;
        } else {
            self.transfer = Transfer::Writing {
                next: next.wrapping_add(1),
                offset: end,
            };
        }
        emit(out, &Repr::Ack { packet })
    }

    /// Reads the segment at `offset` and answers DATA `packet` with it.
    fn send_data<F: FoeFiles + ?Sized>(
        &mut self,
        files: &mut F,
        packet: u32,
        offset: u32,
        len: u32,
        segment: usize,
        out: &mut [u8],
    ) -> Answer {
        let left = len.saturating_sub(offset) as usize;
        let want = left.min(segment);
        let Some(buf) = out.get_mut(HEADER_LEN..HEADER_LEN + want) else {
            // The file is open (also for DATA 1, before the state says so).
            self.transfer = Transfer::Idle;
            files.abort();
            return emit_error(out, ErrorCode::ProgramError);
        };
        let n = files.read(offset, buf).min(want);
        self.transfer = Transfer::Reading {
            sent: packet,
            offset: offset.saturating_add(n as u32),
            len,
            last: n < segment,
        };
        let mut f = Frame::new_unchecked(&mut *out);
        f.set_opcode(Opcode::Data);
        f.set_arg(packet);
        Answer::Frame(HEADER_LEN + n)
    }

    /// Aborts the open transfer (backend told) and answers ERR `code`.
    fn fail<F: FoeFiles + ?Sized>(
        &mut self,
        files: &mut F,
        code: ErrorCode,
        out: &mut [u8],
    ) -> Answer {
        self.abort(files);
        emit_error(out, code)
    }
}

fn emit(out: &mut [u8], r: &Repr<'_>) -> Answer {
    match r.emit(&mut Frame::new_unchecked(out)) {
        0 => Answer::None,
        n => Answer::Frame(n),
    }
}

fn emit_error(out: &mut [u8], code: ErrorCode) -> Answer {
    emit(
        out,
        &Repr::Error {
            code: code.code(),
            text: &[],
        },
    )
}

#[cfg(test)]
mod tests;
