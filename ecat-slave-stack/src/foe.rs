//! File access over EtherCAT (FoE, ETG.1000.6 mailbox type 4): the 6-byte FoE header,
//! the error codes, and the [`FoeServer`] that runs read and write transfers against
//! the application's files ([`FoeFiles`]), e.g. a firmware image writer in Bootstrap.
//!
//! The frame format (header, opcodes, error codes) is [`crate::wire::foe`]; its items
//! are re-exported here.
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

use crate::mailbox::ErrorDetail;
pub use crate::wire::foe::*;

/// Default transfer timeout: a transfer without a request for this long is aborted, µs.
pub const DEFAULT_TIMEOUT_US: u64 = 10_000_000;
/// BUSY "entire" value sent by the server: "done" is a percentage.
pub const BUSY_ENTIRE: u16 = 100;

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
