//! The SDO server (CoE services 2 and 3): expedited, normal and segmented upload and
//! download, complete access, and aborts.
//!
//! Frame layout after the CoE header ([`field`]): command byte, u16 index, u8 sub-index,
//! 4 bytes of data (expedited data or the u32 complete size), then the data of a normal
//! transfer. Segments carry the command byte followed by at least 7 data bytes.
//!
//! Command bytes:
//!
//! | Request (master) | Response (this server) |
//! |---|---|
//! | initiate download `001 ca n n e s` (0x23/27/2B/2F expedited 4/3/2/1 bytes, 0x21 normal) | 0x60 (complete access 0x70) |
//! | download segment `000 t n n n c` | 0x20 \| toggle |
//! | initiate upload 0x40 (complete access 0x50) | 0x43/47/4B/4F expedited, 0x41 normal (+ 0x10 CA) with u32 size and as much data as fits |
//! | upload segment 0x60 \| toggle | `000 t n n n c` + data (padded to 7) |
//! | abort 0x80 (no response) | — |
//!
//! An abort is sent as an SDO **request** (CoE service 2) with command 0x80, index,
//! sub-index and the u32 code: SOEM misreads service 3 aborts.
//!
//! Rules of this server:
//! * Every access goes through [`od::check_read`] / [`od::check_write`] and then the
//!   [`Dictionary`]; missing object → 0x06020000, missing sub-index → 0x06090011.
//! * A transfer that does not fit the mailbox in one frame is segmented; its data is
//!   held in a buffer of [`TRANSFER_MAX`] bytes (larger objects abort with 0x05040005).
//! * The toggle bit starts at 0 and must alternate; otherwise the transfer is aborted
//!   with 0x05030000.
//! * A segmented transfer with no segment request for [`TRANSFER_TIMEOUT_US`] (1 s) is
//!   aborted with 0x05040000. A segment request without a transfer aborts with 0x05040001
//!   (0x05040000 if its transfer has just timed out). A new initiate request silently
//!   replaces a stale transfer; an abort from the master ends it without an answer.
//! * Complete access (bit 4) works on ARRAY and RECORD objects from sub-index 0 (sub-index
//!   0 transferred as 16 bits) or 1; entries follow at their bit length, byte types
//!   byte-aligned. Upload: the entries up to the current value of sub-index 0; write-only
//!   entries read as zeros. Download from sub-index 0: the first byte gives the number of
//!   entries; from sub-index 1: the data length decides. Read-only entries are skipped
//!   (not an error). All entries are validated before the first write (all-or-nothing
//!   unless the application itself refuses a write half-way); when sub-index 0 is
//!   writable it is first set to 0, then the entries are written, then sub-index 0 is set
//!   to the new count (the PDO-mapping edit order). A data length that does not match the
//!   entries → 0x06070010; strings → 0x06010004; VAR objects or a start sub-index > 1 →
//!   0x06010000.

use super::{Header, Service, HEADER_LEN as COE_HEADER_LEN};
use crate::esm::EsmState;
use crate::mailbox::ErrorDetail;
use crate::od::{self, Dictionary, Entry, Object, ObjectCode, SdoAbort};

/// Largest object (or complete-access image) a segmented transfer can carry.
pub const TRANSFER_MAX: usize = 512;
/// A segmented transfer idle for longer than this is aborted (0x05040000).
pub const TRANSFER_TIMEOUT_US: u64 = 1_000_000;
/// Length of an initiate / abort frame after the mailbox header (CoE header + 8).
pub const INITIATE_LEN: usize = COE_HEADER_LEN + 8;

/// Byte offsets of the SDO frame after the CoE header.
pub mod field {
    use core::ops::{Range, RangeFrom};
    /// Command specifier.
    pub const COMMAND: usize = 0;
    /// Index (u16).
    pub const INDEX: Range<usize> = 1..3;
    /// Sub-index.
    pub const SUB: usize = 3;
    /// Expedited data, complete size or abort code.
    pub const DATA: Range<usize> = 4..8;
    /// Data of a normal transfer (after the complete size).
    pub const NORMAL_DATA: RangeFrom<usize> = 8..;
    /// Data of a segment.
    pub const SEGMENT_DATA: RangeFrom<usize> = 1..;
}

/// Command byte bits.
pub mod cmd {
    /// Complete access flag of initiate requests and responses.
    pub const COMPLETE_ACCESS: u8 = 0x10;
    /// Toggle bit of segments.
    pub const TOGGLE: u8 = 0x10;
    /// Expedited flag.
    pub const EXPEDITED: u8 = 0x02;
    /// Size indicated flag.
    pub const SIZE_INDICATED: u8 = 0x01;
    /// Last segment flag.
    pub const LAST: u8 = 0x01;
    /// Download response.
    pub const DOWNLOAD_RESPONSE: u8 = 0x60;
    /// Download segment response.
    pub const DOWNLOAD_SEGMENT_RESPONSE: u8 = 0x20;
    /// Upload response (normal: 0x41; expedited adds 0x02 and `(4 − n) << 2`).
    pub const UPLOAD_RESPONSE: u8 = 0x40;
    /// Abort.
    pub const ABORT: u8 = 0x80;
}

/// Length of the fixed part of an initiate, abort or segment frame after the CoE header:
/// command byte, index, sub-index and 4 data bytes (a segment: command and 7 data bytes).
pub const BODY_LEN: usize = 8;

/// Why a buffer could not be read as an SDO frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WireError {
    /// Shorter than the fields its command byte carries.
    Truncated,
    /// A server command specifier (bits 7:5) outside 0…4 ([`Response::parse`]).
    UnknownCommand(u8),
}

impl From<WireError> for ErrorDetail {
    /// A truncated SDO request is answered with the mailbox error "size too short"
    /// (requests never give [`WireError::UnknownCommand`]: those are aborted).
    fn from(e: WireError) -> Self {
        match e {
            WireError::Truncated => ErrorDetail::SizeTooShort,
            WireError::UnknownCommand(_) => ErrorDetail::InvalidHeader,
        }
    }
}

/// A zero-copy view of an SDO frame (after the CoE header).
///
/// Invariant of the accessors: they index the buffer directly and panic on bytes beyond
/// its end. [`Frame::check_len`] guarantees the command byte, and for every request that
/// carries index, sub-index and data (initiate, abort, download segment) all
/// [`BODY_LEN`] bytes; a frame built with [`Frame::new_unchecked`] must be long enough
/// for the fields read.
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
    /// Checks that the buffer holds the command byte and the fields that command carries
    /// as a request: [`BODY_LEN`] bytes for initiate download / upload, download segment
    /// and abort; the command byte alone for upload segment and unknown commands.
    pub fn check_len(&self) -> Result<(), WireError> {
        let b = self.buffer.as_ref();
        let need = match b.first() {
            None => 1,
            Some(c) if Self::carries_body(*c) => BODY_LEN,
            Some(_) => 1,
        };
        if b.len() < need {
            Err(WireError::Truncated)
        } else {
            Ok(())
        }
    }
    /// True for request commands with index, sub-index and data (specifier 0, 1, 2, 4).
    const fn carries_body(command: u8) -> bool {
        matches!(command >> 5, 0 | 1 | 2 | 4)
    }
    /// Returns the buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }
    /// Length of the buffer.
    pub fn len(&self) -> usize {
        self.buffer.as_ref().len()
    }
    /// True when the buffer is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The command byte.
    pub fn command(&self) -> u8 {
        self.buffer.as_ref()[field::COMMAND]
    }
    /// The index.
    pub fn index(&self) -> u16 {
        let b = &self.buffer.as_ref()[field::INDEX];
        u16::from_le_bytes([b[0], b[1]])
    }
    /// The sub-index.
    pub fn sub(&self) -> u8 {
        self.buffer.as_ref()[field::SUB]
    }
    /// The 4 data bytes of an initiate or abort frame.
    pub fn data4(&self) -> [u8; 4] {
        let b = &self.buffer.as_ref()[field::DATA];
        [b[0], b[1], b[2], b[3]]
    }
    /// The 4 data bytes as u32 (complete size, abort code).
    pub fn data_u32(&self) -> u32 {
        u32::from_le_bytes(self.data4())
    }
    /// The data after the complete size of a normal transfer.
    pub fn normal_data(&self) -> &[u8] {
        &self.buffer.as_ref()[field::NORMAL_DATA]
    }
    /// The data area of a segment.
    pub fn segment_data(&self) -> &[u8] {
        &self.buffer.as_ref()[field::SEGMENT_DATA]
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Frame<T> {
    /// Sets the command byte.
    pub fn set_command(&mut self, v: u8) {
        self.buffer.as_mut()[field::COMMAND] = v;
    }
    /// Sets the index.
    pub fn set_index(&mut self, v: u16) {
        self.buffer.as_mut()[field::INDEX].copy_from_slice(&v.to_le_bytes());
    }
    /// Sets the sub-index.
    pub fn set_sub(&mut self, v: u8) {
        self.buffer.as_mut()[field::SUB] = v;
    }
    /// Sets the 4 data bytes.
    pub fn set_data4(&mut self, v: [u8; 4]) {
        self.buffer.as_mut()[field::DATA].copy_from_slice(&v);
    }
    /// The data area of a normal transfer, writable.
    pub fn normal_data_mut(&mut self) -> &mut [u8] {
        &mut self.buffer.as_mut()[field::NORMAL_DATA]
    }
    /// The data area of a segment, writable.
    pub fn segment_data_mut(&mut self) -> &mut [u8] {
        &mut self.buffer.as_mut()[field::SEGMENT_DATA]
    }
}

/// An SDO request from the master.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request<'a> {
    /// Initiate download (expedited: `data` is the value; normal: `size` is the complete
    /// size and `data` the part carried in this frame).
    InitiateDownload {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Complete access.
        complete_access: bool,
        /// Expedited transfer.
        expedited: bool,
        /// Size indicated (expedited: `data.len()` is exact).
        size_indicated: bool,
        /// Complete size (normal transfer).
        size: u32,
        /// Data carried in this frame.
        data: &'a [u8],
    },
    /// Download segment.
    DownloadSegment {
        /// Toggle bit.
        toggle: bool,
        /// Last segment.
        last: bool,
        /// Data of this segment.
        data: &'a [u8],
    },
    /// Initiate upload.
    InitiateUpload {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Complete access.
        complete_access: bool,
    },
    /// Upload segment.
    UploadSegment {
        /// Toggle bit.
        toggle: bool,
    },
    /// Abort from the master.
    Abort {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Abort code.
        code: u32,
    },
    /// Block transfers and anything else.
    Unknown {
        /// The command byte.
        command: u8,
        /// Index (bytes 1–2, if present).
        index: u16,
        /// Sub-index (byte 3, if present).
        sub: u8,
    },
}

impl<'a> Request<'a> {
    /// Parses the SDO part of a request (after the CoE header). `Err` = too short for the
    /// command it carries.
    pub fn parse(b: &'a [u8]) -> Result<Self, ErrorDetail> {
        let f = Frame::new_checked(b)?;
        let c = f.command();
        match c >> 5 {
            0 => {
                let seg: &'a [u8] = &b[field::SEGMENT_DATA];
                let n = if seg.len() > 7 {
                    seg.len()
                } else {
                    7 - ((c >> 1) & 7) as usize
                };
                Ok(Request::DownloadSegment {
                    toggle: c & cmd::TOGGLE != 0,
                    last: c & cmd::LAST != 0,
                    data: &seg[..n],
                })
            }
            1 => {
                let expedited = c & cmd::EXPEDITED != 0;
                let size_indicated = c & cmd::SIZE_INDICATED != 0;
                let data: &'a [u8] = if expedited {
                    let n = if size_indicated {
                        4 - ((c >> 2) & 3) as usize
                    } else {
                        4
                    };
                    &b[field::DATA.start..field::DATA.start + n]
                } else {
                    &b[field::NORMAL_DATA]
                };
                Ok(Request::InitiateDownload {
                    index: f.index(),
                    sub: f.sub(),
                    complete_access: c & cmd::COMPLETE_ACCESS != 0,
                    expedited,
                    size_indicated,
                    size: f.data_u32(),
                    data,
                })
            }
            2 => Ok(Request::InitiateUpload {
                index: f.index(),
                sub: f.sub(),
                complete_access: c & cmd::COMPLETE_ACCESS != 0,
            }),
            3 => Ok(Request::UploadSegment {
                toggle: c & cmd::TOGGLE != 0,
            }),
            4 => Ok(Request::Abort {
                index: f.index(),
                sub: f.sub(),
                code: f.data_u32(),
            }),
            _ => {
                // Unknown commands need only the command byte: index and sub-index are
                // echoed in the abort as far as the request carries them (missing
                // bytes as 0).
                let at = |i: usize| b.get(i).copied().unwrap_or(0);
                Ok(Request::Unknown {
                    command: c,
                    index: u16::from_le_bytes([at(field::INDEX.start), at(field::INDEX.start + 1)]),
                    sub: at(field::SUB),
                })
            }
        }
    }
}

/// An SDO frame sent by this server: a response, or an abort (which travels as a CoE
/// SDO request, see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Response<'a> {
    /// Initiate download response (0x60, complete access 0x70).
    Download {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Complete access.
        complete_access: bool,
    },
    /// Download segment response (0x20 | toggle, 7 reserved bytes).
    DownloadSegment {
        /// Toggle bit.
        toggle: bool,
    },
    /// Expedited upload response (0x43/47/4B/4F): 1…4 bytes of data in the data field.
    UploadExpedited {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The value, 1…4 bytes.
        data: &'a [u8],
    },
    /// Normal upload response (0x41, complete access 0x51): the complete size and the
    /// first part of the data.
    Upload {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Complete access.
        complete_access: bool,
        /// Complete size, bytes.
        size: u32,
        /// Data carried in this frame.
        data: &'a [u8],
    },
    /// Upload segment response (`000 t n n n c`), data padded to 7 bytes.
    UploadSegment {
        /// Toggle bit.
        toggle: bool,
        /// Last segment.
        last: bool,
        /// Data of this segment.
        data: &'a [u8],
    },
    /// Abort (0x80) with the u32 abort code.
    Abort {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Abort code.
        code: u32,
    },
}

const fn flag(on: bool, bit: u8) -> u8 {
    if on {
        bit
    } else {
        0
    }
}

impl<'a> Response<'a> {
    /// An abort with a standard code.
    pub const fn abort(index: u16, sub: u8, abort: SdoAbort) -> Self {
        Response::Abort {
            index,
            sub,
            code: abort.code(),
        }
    }

    /// The CoE service the frame travels in: aborts as SDO request, the rest as SDO
    /// response.
    pub const fn service(&self) -> Service {
        match self {
            Response::Abort { .. } => Service::SdoRequest,
            _ => Service::SdoResponse,
        }
    }

    /// Parses a frame sent by an SDO server (the counterpart of [`Response::emit`], for
    /// masters and tests).
    pub fn parse(frame: &Frame<&'a [u8]>) -> Result<Self, WireError> {
        let b: &'a [u8] = frame.buffer;
        if b.len() < BODY_LEN {
            return Err(WireError::Truncated);
        }
        let c = frame.command();
        let (index, sub) = (frame.index(), frame.sub());
        let ca = c & cmd::COMPLETE_ACCESS != 0;
        Ok(match c >> 5 {
            0 => {
                let seg: &'a [u8] = &b[field::SEGMENT_DATA];
                let n = if seg.len() > 7 {
                    seg.len()
                } else {
                    7 - ((c >> 1) & 7) as usize
                };
                Response::UploadSegment {
                    toggle: c & cmd::TOGGLE != 0,
                    last: c & cmd::LAST != 0,
                    data: &seg[..n],
                }
            }
            1 => Response::DownloadSegment {
                toggle: c & cmd::TOGGLE != 0,
            },
            2 if c & cmd::EXPEDITED != 0 => {
                let n = if c & cmd::SIZE_INDICATED != 0 {
                    4 - ((c >> 2) & 3) as usize
                } else {
                    4
                };
                Response::UploadExpedited {
                    index,
                    sub,
                    data: &b[field::DATA.start..field::DATA.start + n],
                }
            }
            2 => Response::Upload {
                index,
                sub,
                complete_access: ca,
                size: frame.data_u32(),
                data: &b[field::NORMAL_DATA],
            },
            3 => Response::Download {
                index,
                sub,
                complete_access: ca,
            },
            4 => Response::Abort {
                index,
                sub,
                code: frame.data_u32(),
            },
            _ => return Err(WireError::UnknownCommand(c)),
        })
    }

    /// Length of the emitted frame after the CoE header.
    pub fn buffer_len(&self) -> usize {
        match *self {
            Response::Upload { data, .. } => BODY_LEN + data.len(),
            Response::UploadSegment { data, .. } => 1 + data.len().max(7),
            _ => BODY_LEN,
        }
    }

    /// Writes the frame (after the CoE header) into the start of `frame`'s buffer;
    /// returns its length, or 0 (buffer untouched) when the buffer is shorter than
    /// [`Response::buffer_len`].
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, frame: &mut Frame<T>) -> usize {
        let n = self.buffer_len();
        if frame.len() < n {
            return 0;
        }
        let (command, index, sub, d4) = match *self {
            Response::Download {
                index,
                sub,
                complete_access,
            } => (
                cmd::DOWNLOAD_RESPONSE | flag(complete_access, cmd::COMPLETE_ACCESS),
                index,
                sub,
                [0; 4],
            ),
            Response::DownloadSegment { toggle } => (
                cmd::DOWNLOAD_SEGMENT_RESPONSE | flag(toggle, cmd::TOGGLE),
                0,
                0,
                [0; 4],
            ),
            Response::UploadExpedited { index, sub, data } => {
                let len = data.len().min(4);
                let mut d = [0u8; 4];
                d[..len].copy_from_slice(&data[..len]);
                let c = cmd::UPLOAD_RESPONSE
                    | cmd::EXPEDITED
                    | cmd::SIZE_INDICATED
                    | (((4 - len) as u8 & 3) << 2);
                (c, index, sub, d)
            }
            Response::Upload {
                index,
                sub,
                complete_access,
                size,
                data,
            } => {
                frame.normal_data_mut()[..data.len()].copy_from_slice(data);
                let c = cmd::UPLOAD_RESPONSE
                    | cmd::SIZE_INDICATED
                    | flag(complete_access, cmd::COMPLETE_ACCESS);
                (c, index, sub, size.to_le_bytes())
            }
            Response::Abort { index, sub, code } => (cmd::ABORT, index, sub, code.to_le_bytes()),
            Response::UploadSegment { toggle, last, data } => {
                // A segment has no index field: command and 7 or more data bytes.
                let pad = (7 - data.len().min(7)) as u8;
                frame.set_command(flag(toggle, cmd::TOGGLE) | (pad << 1) | flag(last, cmd::LAST));
                let (d, rest) = frame.segment_data_mut()[..n - 1].split_at_mut(data.len());
                d.copy_from_slice(data);
                rest.fill(0);
                return n;
            }
        };
        frame.set_command(command);
        frame.set_index(index);
        frame.set_sub(sub);
        frame.set_data4(d4);
        n
    }

    /// Writes the CoE header of [`Response::service`] and the frame into `out`; returns
    /// the length of both, or 0 (nothing written) when `out` is too short.
    pub fn emit_coe(&self, out: &mut [u8]) -> usize {
        if out.len() < COE_HEADER_LEN + self.buffer_len() {
            return 0;
        }
        let (head, body) = out.split_at_mut(COE_HEADER_LEN);
        Header::of(self.service()).emit(head);
        COE_HEADER_LEN + self.emit(&mut Frame::new_unchecked(body))
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Transfer {
    Idle,
    Download {
        index: u16,
        sub: u8,
        ca: bool,
        total: usize,
        toggle: bool,
    },
    Upload {
        index: u16,
        sub: u8,
        pos: usize,
        toggle: bool,
    },
}

/// The state of the SDO server: at most one segmented transfer.
pub struct SdoServer {
    t: Transfer,
    buf: [u8; TRANSFER_MAX],
    len: usize,
    last_us: u64,
}

impl Default for SdoServer {
    fn default() -> Self {
        Self::new()
    }
}

impl SdoServer {
    /// An idle server.
    pub const fn new() -> Self {
        SdoServer {
            t: Transfer::Idle,
            buf: [0; TRANSFER_MAX],
            len: 0,
            last_us: 0,
        }
    }

    /// Back to idle, in place: the state of [`Self::new`] without building a new
    /// server (and its transfer buffer) on the stack. The buffer keeps stale bytes,
    /// which no idle server reads.
    pub fn reset(&mut self) {
        self.t = Transfer::Idle;
        self.len = 0;
        self.last_us = 0;
    }

    /// True while a segmented transfer is in progress.
    pub fn active(&self) -> bool {
        self.t != Transfer::Idle
    }

    fn target(&self) -> Option<(u16, u8)> {
        match self.t {
            Transfer::Idle => None,
            Transfer::Download { index, sub, .. } | Transfer::Upload { index, sub, .. } => {
                Some((index, sub))
            }
        }
    }

    /// Ends a transfer idle for longer than [`TRANSFER_TIMEOUT_US`]; returns its
    /// index and sub-index.
    pub fn expire(&mut self, now_us: u64) -> Option<(u16, u8)> {
        let target = self.target()?;
        if now_us.saturating_sub(self.last_us) > TRANSFER_TIMEOUT_US {
            self.t = Transfer::Idle;
            Some(target)
        } else {
            None
        }
    }

    /// Executes one SDO request (`body` = after the CoE header) and writes the answer's
    /// CoE payload into `out` (the mailbox data area, ≥ 10 bytes). Returns the answer
    /// length (0 = no answer, after an abort from the master), or the mailbox error to
    /// send for a frame too short for its command. `expired` is what [`Self::expire`]
    /// returned just before (to answer a late segment with 0x05040000).
    pub fn on_request(
        &mut self,
        body: &[u8],
        out: &mut [u8],
        dict: &mut impl Dictionary,
        state: EsmState,
        now_us: u64,
        expired: Option<(u16, u8)>,
    ) -> Result<usize, ErrorDetail> {
        if out.len() < INITIATE_LEN {
            return Err(ErrorDetail::NoMoreMemory);
        }
        let req = Request::parse(body)?;
        let n = match req {
            Request::InitiateDownload {
                index,
                sub,
                complete_access,
                expedited,
                size_indicated,
                size,
                data,
            } => {
                self.t = Transfer::Idle;
                let r = if expedited {
                    self.expedited_download(
                        index,
                        sub,
                        complete_access,
                        size_indicated,
                        data,
                        dict,
                        state,
                    )
                } else {
                    self.initiate_normal_download(
                        index,
                        sub,
                        complete_access,
                        size as usize,
                        data,
                        dict,
                        state,
                        now_us,
                    )
                };
                match r {
                    Ok(()) => Response::Download {
                        index,
                        sub,
                        complete_access,
                    }
                    .emit_coe(out),
                    Err(a) => Response::abort(index, sub, a).emit_coe(out),
                }
            }
            Request::DownloadSegment { toggle, last, data } => match self.t {
                Transfer::Download {
                    index,
                    sub,
                    ca,
                    total,
                    toggle: expected,
                } => {
                    match self.download_segment(
                        index, sub, ca, total, expected, toggle, last, data, dict, state,
                    ) {
                        Ok(()) => {
                            self.last_us = now_us;
                            Response::DownloadSegment { toggle }.emit_coe(out)
                        }
                        Err(a) => {
                            self.t = Transfer::Idle;
                            Response::abort(index, sub, a).emit_coe(out)
                        }
                    }
                }
                _ => self.no_transfer(out, expired),
            },
            Request::InitiateUpload {
                index,
                sub,
                complete_access,
            } => {
                self.t = Transfer::Idle;
                self.initiate_upload(out, index, sub, complete_access, dict, state, now_us)
            }
            Request::UploadSegment { toggle } => match self.t {
                Transfer::Upload {
                    index,
                    sub,
                    pos,
                    toggle: expected,
                } => {
                    if toggle != expected {
                        self.t = Transfer::Idle;
                        Response::abort(index, sub, SdoAbort::ToggleBit).emit_coe(out)
                    } else {
                        self.last_us = now_us;
                        self.upload_segment(out, index, sub, pos, toggle)
                    }
                }
                _ => self.no_transfer(out, expired),
            },
            Request::Abort { .. } => {
                self.t = Transfer::Idle;
                0
            }
            Request::Unknown { index, sub, .. } => {
                self.t = Transfer::Idle;
                Response::abort(index, sub, SdoAbort::InvalidCommand).emit_coe(out)
            }
        };
        Ok(n)
    }

    /// A segment request that does not belong to the current transfer.
    fn no_transfer(&mut self, out: &mut [u8], expired: Option<(u16, u8)>) -> usize {
        if let Some((index, sub)) = expired {
            return Response::abort(index, sub, SdoAbort::Timeout).emit_coe(out);
        }
        let (index, sub) = self.target().unwrap_or((0, 0));
        self.t = Transfer::Idle;
        Response::abort(index, sub, SdoAbort::InvalidCommand).emit_coe(out)
    }

    #[allow(clippy::too_many_arguments)]
    fn expedited_download(
        &mut self,
        index: u16,
        sub: u8,
        ca: bool,
        size_indicated: bool,
        data: &[u8],
        dict: &mut impl Dictionary,
        state: EsmState,
    ) -> Result<(), SdoAbort> {
        let mut data = data;
        if !size_indicated && !ca {
            // Size not indicated: the entry's own length (at most the 4 bytes carried).
            let e = od::find_entry(dict.objects(), index, sub)?;
            data = data.get(..e.byte_len().clamp(1, 4)).unwrap_or(data);
        }
        download(dict, state, index, sub, ca, data)
    }

    #[allow(clippy::too_many_arguments)]
    fn initiate_normal_download(
        &mut self,
        index: u16,
        sub: u8,
        ca: bool,
        total: usize,
        data: &[u8],
        dict: &mut impl Dictionary,
        state: EsmState,
        now_us: u64,
    ) -> Result<(), SdoAbort> {
        let objects = dict.objects();
        // Refuse early what can never succeed, before a segmented transfer starts.
        if ca {
            let obj = od::find(objects, index).ok_or(SdoAbort::ObjectDoesNotExist)?;
            if obj.code() == ObjectCode::Var || sub > 1 {
                return Err(SdoAbort::UnsupportedAccess);
            }
            if total > TRANSFER_MAX {
                return Err(SdoAbort::OutOfMemory);
            }
        } else {
            let e = od::find_entry(objects, index, sub)?;
            if !e.access.writable() {
                return Err(SdoAbort::WriteReadOnly);
            }
            if !e.access.writable_in(state) {
                return Err(SdoAbort::StateConflict);
            }
            if total > e.byte_len() {
                return Err(SdoAbort::LengthTooHigh);
            }
            if !e.data_type.is_variable_length() && total < e.byte_len() {
                return Err(SdoAbort::LengthTooLow);
            }
            if total > TRANSFER_MAX {
                return Err(SdoAbort::OutOfMemory);
            }
        }
        if data.len() >= total {
            return download(dict, state, index, sub, ca, &data[..total]);
        }
        self.buf[..data.len()].copy_from_slice(data);
        self.len = data.len();
        self.t = Transfer::Download {
            index,
            sub,
            ca,
            total,
            toggle: false,
        };
        self.last_us = now_us;
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    fn download_segment(
        &mut self,
        index: u16,
        sub: u8,
        ca: bool,
        total: usize,
        expected: bool,
        toggle: bool,
        last: bool,
        data: &[u8],
        dict: &mut impl Dictionary,
        state: EsmState,
    ) -> Result<(), SdoAbort> {
        if toggle != expected {
            return Err(SdoAbort::ToggleBit);
        }
        let end = self.len + data.len();
        if end > total {
            return Err(SdoAbort::TypeMismatch);
        }
        self.buf[self.len..end].copy_from_slice(data);
        self.len = end;
        if !last {
            self.t = Transfer::Download {
                index,
                sub,
                ca,
                total,
                toggle: !toggle,
            };
            return Ok(());
        }
        self.t = Transfer::Idle;
        if end != total {
            return Err(SdoAbort::TypeMismatch);
        }
        download(dict, state, index, sub, ca, &self.buf[..end])
    }

    #[allow(clippy::too_many_arguments)]
    fn initiate_upload(
        &mut self,
        out: &mut [u8],
        index: u16,
        sub: u8,
        ca: bool,
        dict: &mut impl Dictionary,
        state: EsmState,
        now_us: u64,
    ) -> usize {
        let len = match upload(dict, state, index, sub, ca, &mut self.buf) {
            Ok(n) => n,
            Err(a) => return Response::abort(index, sub, a).emit_coe(out),
        };
        if !ca && (1..=4).contains(&len) {
            let data = &self.buf[..len];
            return Response::UploadExpedited { index, sub, data }.emit_coe(out);
        }
        let room = out.len() - INITIATE_LEN;
        let first = len.min(room);
        Response::Upload {
            index,
            sub,
            complete_access: ca,
            size: len as u32,
            data: &self.buf[..first],
        }
        .emit_coe(out);
        if first < len {
            self.len = len;
            self.t = Transfer::Upload {
                index,
                sub,
                pos: first,
                toggle: false,
            };
            self.last_us = now_us;
        }
        INITIATE_LEN + first
    }

    fn upload_segment(
        &mut self,
        out: &mut [u8],
        index: u16,
        sub: u8,
        pos: usize,
        toggle: bool,
    ) -> usize {
        let room = out.len() - COE_HEADER_LEN - 1;
        let end = (pos + room).min(self.len);
        let last = end == self.len;
        let data = self.buf.get(pos.min(end)..end).unwrap_or_default();
        let n = Response::UploadSegment { toggle, last, data }.emit_coe(out);
        self.t = if last {
            Transfer::Idle
        } else {
            Transfer::Upload {
                index,
                sub,
                pos: end,
                toggle: !toggle,
            }
        };
        n
    }
}

/// Reads one entry (or a complete-access image) into `buf`; returns its length.
fn upload(
    dict: &mut impl Dictionary,
    state: EsmState,
    index: u16,
    sub: u8,
    ca: bool,
    buf: &mut [u8],
) -> Result<usize, SdoAbort> {
    let obj = od::find(dict.objects(), index).ok_or(SdoAbort::ObjectDoesNotExist)?;
    if ca {
        return ca_upload(obj, dict, state, sub, buf);
    }
    let e = obj.entry(sub).ok_or(SdoAbort::SubindexDoesNotExist)?;
    od::check_read(e, state)?;
    let n = dict.read(index, sub, buf)?;
    Ok(n.min(buf.len()))
}

/// Checks and writes one entry or a complete-access image.
fn download(
    dict: &mut impl Dictionary,
    state: EsmState,
    index: u16,
    sub: u8,
    ca: bool,
    data: &[u8],
) -> Result<(), SdoAbort> {
    let objects = dict.objects();
    if ca {
        let obj = od::find(objects, index).ok_or(SdoAbort::ObjectDoesNotExist)?;
        return ca_download(obj, dict, state, sub, data);
    }
    let e = od::find_entry(objects, index, sub)?;
    od::check_write(e, data, state)?;
    dict.write(index, sub, data, state)
}

/// Writes `nbits` (≤ 64) of `v` at bit position `pos` of `buf` (LSB first).
fn put_bits(buf: &mut [u8], pos: usize, v: u64, nbits: usize) {
    for i in 0..nbits.min(64) {
        let p = pos + i;
        if let Some(b) = buf.get_mut(p / 8) {
            if (v >> i) & 1 != 0 {
                *b |= 1 << (p % 8);
            } else {
                *b &= !(1 << (p % 8));
            }
        }
    }
}

/// Reads `nbits` (≤ 64) at bit position `pos` of `buf` (LSB first).
fn get_bits(buf: &[u8], pos: usize, nbits: usize) -> u64 {
    let mut v = 0u64;
    for i in 0..nbits.min(64) {
        let p = pos + i;
        if buf.get(p / 8).is_some_and(|b| (b >> (p % 8)) & 1 != 0) {
            v |= 1 << i;
        }
    }
    v
}

/// Where an entry starts in a complete-access image: byte types are byte-aligned.
fn ca_start(e: &Entry, bit: usize) -> usize {
    if e.bits.is_multiple_of(8) {
        bit.div_ceil(8) * 8
    } else {
        bit
    }
}

fn ca_checks(obj: &Object, sub: u8) -> Result<&'static Entry, SdoAbort> {
    if obj.code() == ObjectCode::Var || sub > 1 {
        return Err(SdoAbort::UnsupportedAccess);
    }
    obj.entry(0).ok_or(SdoAbort::SubindexDoesNotExist)
}

fn ca_entries(obj: &Object, count: u8) -> impl Iterator<Item = &'static Entry> {
    let entries: &'static [Entry] = obj.entries();
    entries.iter().filter(move |e| e.sub >= 1 && e.sub <= count)
}

fn ca_upload(
    obj: &Object,
    dict: &mut impl Dictionary,
    state: EsmState,
    sub: u8,
    buf: &mut [u8],
) -> Result<usize, SdoAbort> {
    let e0 = ca_checks(obj, sub)?;
    od::check_read(e0, state)?;
    let mut tmp = [0u8; 8];
    dict.read(obj.index, 0, &mut tmp)?;
    let raw_count = tmp[0];
    let count = raw_count.min(obj.max_sub());
    // A VISIBLE_STRING's length is its content's; an OCTET_STRING keeps its declared
    // length (an upload pads a shorter value with zeros), so it has a fixed place.
    if ca_entries(obj, count).any(|e| e.data_type == od::DataType::VisibleString) {
        return Err(SdoAbort::CompleteAccessVariableLength);
    }
    let mut bit = 0usize;
    if sub == 0 {
        let b = buf.get_mut(..2).ok_or(SdoAbort::OutOfMemory)?;
        b[0] = raw_count;
        b[1] = 0;
        bit = 16;
    }
    for e in ca_entries(obj, count) {
        let nbits = e.bits as usize;
        if e.data_type == od::DataType::OctetString {
            let start = bit.div_ceil(8);
            let end = start + nbits / 8;
            let out = buf.get_mut(start..end).ok_or(SdoAbort::OutOfMemory)?;
            od::check_read(e, state)?;
            let n = dict.read(obj.index, e.sub, out)?.min(out.len());
            out[n..].fill(0);
            bit = end * 8;
            continue;
        }
        if nbits > 64 {
            return Err(SdoAbort::UnsupportedAccess);
        }
        let mut val = [0u8; 8];
        match od::check_read(e, state) {
            Ok(()) => {
                dict.read(obj.index, e.sub, &mut val)?;
            }
            // Write-only entries read as zeros in a complete access.
            Err(SdoAbort::ReadWriteOnly) => {}
            Err(a) => return Err(a),
        }
        let start = ca_start(e, bit);
        let end = start + nbits;
        if end.div_ceil(8) > buf.len() {
            return Err(SdoAbort::OutOfMemory);
        }
        if nbits.is_multiple_of(8) {
            buf[start / 8..end / 8].copy_from_slice(&val[..nbits / 8]);
        } else {
            if bit.is_multiple_of(8) {
                if let Some(b) = buf.get_mut(bit / 8) {
                    *b = 0;
                }
            }
            put_bits(buf, start, u64::from_le_bytes(val), nbits);
        }
        bit = end;
    }
    // Clear the unused high bits of a last partial byte.
    if !bit.is_multiple_of(8) {
        if let Some(b) = buf.get_mut(bit / 8) {
            *b &= (1u8 << (bit % 8)) - 1;
        }
    }
    Ok(bit.div_ceil(8))
}

/// The value of entry `e` at bit position `start` of a complete-access image.
fn ca_value(data: &[u8], e: &Entry, start: usize) -> [u8; 8] {
    let nbits = e.bits as usize;
    if nbits.is_multiple_of(8) {
        let mut v = [0u8; 8];
        if let Some(src) = data.get(start / 8..start / 8 + nbits / 8) {
            v[..src.len()].copy_from_slice(src);
        }
        v
    } else {
        get_bits(data, start, nbits).to_le_bytes()
    }
}

/// Walks the entries of a complete-access download image and returns the end bit:
/// checks every writable entry's value (`write` false) or writes it (`write` true).
/// One walk for both passes of [`ca_download`].
#[allow(clippy::too_many_arguments)]
fn ca_walk(
    obj: &Object,
    dict: &mut impl Dictionary,
    state: EsmState,
    data: &[u8],
    count: u8,
    first_bit: usize,
    stop_at_data_end: Option<usize>,
    write: bool,
) -> Result<usize, SdoAbort> {
    let mut bit = first_bit;
    for e in ca_entries(obj, count) {
        let nbits = e.bits as usize;
        if e.data_type.is_variable_length() {
            return Err(SdoAbort::CompleteAccessVariableLength);
        }
        if nbits > 64 {
            return Err(SdoAbort::UnsupportedAccess);
        }
        let start = ca_start(e, bit);
        if let Some(data_bits) = stop_at_data_end {
            if start + nbits > data_bits {
                break;
            }
        }
        if e.access.writable() {
            let v = ca_value(data, e, start);
            let v = &v[..e.byte_len().min(8)];
            if write {
                dict.write(obj.index, e.sub, v, state)?;
            } else {
                od::check_write(e, v, state)?;
            }
        }
        bit = start + nbits;
    }
    Ok(bit)
}

fn ca_download(
    obj: &Object,
    dict: &mut impl Dictionary,
    state: EsmState,
    sub: u8,
    data: &[u8],
) -> Result<(), SdoAbort> {
    let e0 = ca_checks(obj, sub)?;
    let data_bits = data.len() * 8;
    let (count, first_bit, stop) = if sub == 0 {
        let n = *data.first().ok_or(SdoAbort::TypeMismatch)?;
        if data.len() < 2 {
            return Err(SdoAbort::TypeMismatch);
        }
        if n > obj.max_sub() {
            return Err(SdoAbort::ValueTooHigh);
        }
        if e0.access.writable() {
            od::check_write(e0, &[n], state)?;
        }
        (n, 16, None)
    } else {
        (obj.max_sub(), 0, Some(data_bits))
    };
    // Pass 1: layout and checks, nothing written.
    let end = ca_walk(obj, dict, state, data, count, first_bit, stop, false)?;
    if end.div_ceil(8) != data.len() {
        return Err(SdoAbort::TypeMismatch);
    }
    // Pass 2: the writes, in the PDO-mapping edit order.
    let index = obj.index;
    let si0_written = sub == 0 && e0.access.writable_in(state);
    if si0_written && e0.min() <= 0 {
        dict.write(index, 0, &[0], state)?;
    }
    ca_walk(obj, dict, state, data, count, first_bit, stop, true)?;
    if si0_written {
        dict.write(index, 0, &[count], state)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn request_parse() {
        assert_eq!(
            Request::parse(&[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]),
            Ok(Request::InitiateUpload {
                index: 0x1000,
                sub: 0,
                complete_access: false
            })
        );
        assert_eq!(
            Request::parse(&[0x50, 0x12, 0x1C, 0x01, 0, 0, 0, 0]),
            Ok(Request::InitiateUpload {
                index: 0x1C12,
                sub: 1,
                complete_access: true
            })
        );
        assert_eq!(
            Request::parse(&[0x2B, 0x40, 0x60, 0x00, 0x0F, 0x00, 0xAA, 0xBB]),
            Ok(Request::InitiateDownload {
                index: 0x6040,
                sub: 0,
                complete_access: false,
                expedited: true,
                size_indicated: true,
                size: 0xBBAA_000F,
                data: &[0x0F, 0x00],
            })
        );
        let b = [0x21, 0x02, 0x20, 0x00, 5, 0, 0, 0, 1, 2, 3];
        assert_eq!(
            Request::parse(&b),
            Ok(Request::InitiateDownload {
                index: 0x2002,
                sub: 0,
                complete_access: false,
                expedited: false,
                size_indicated: true,
                size: 5,
                data: &[1, 2, 3],
            })
        );
        assert_eq!(
            Request::parse(&[0x0B, 1, 2, 3, 4, 5, 6, 7]),
            Ok(Request::DownloadSegment {
                toggle: false,
                last: true,
                data: &[1, 2]
            })
        );
        assert_eq!(
            Request::parse(&[0x10, 1, 2, 3, 4, 5, 6, 7, 8]),
            Ok(Request::DownloadSegment {
                toggle: true,
                last: false,
                data: &[1, 2, 3, 4, 5, 6, 7, 8]
            })
        );
        assert_eq!(
            Request::parse(&[0x0E, 1, 2, 3, 4, 5, 6, 7]),
            Ok(Request::DownloadSegment {
                toggle: false,
                last: false,
                data: &[]
            })
        );
        assert_eq!(
            Request::parse(&[0x70]),
            Ok(Request::UploadSegment { toggle: true })
        );
        assert_eq!(
            Request::parse(&[0x80, 0x00, 0x10, 0x02, 0x00, 0x00, 0x04, 0x05]),
            Ok(Request::Abort {
                index: 0x1000,
                sub: 2,
                code: 0x0504_0000
            })
        );
        assert_eq!(
            Request::parse(&[0xC0]),
            Ok(Request::Unknown {
                command: 0xC0,
                index: 0,
                sub: 0
            })
        );
        assert_eq!(Request::parse(&[]), Err(ErrorDetail::SizeTooShort));
        assert_eq!(
            Request::parse(&[0x40, 0, 0x10]),
            Err(ErrorDetail::SizeTooShort)
        );
        assert_eq!(
            Request::parse(&[0x00, 1, 2]),
            Err(ErrorDetail::SizeTooShort)
        );
        assert_eq!(
            Request::parse(&[0x80, 0, 0x10, 0, 0]),
            Err(ErrorDetail::SizeTooShort)
        );
    }

    #[test]
    fn frame_view_and_emitters() {
        let f = Frame::new_unchecked(&[0x41u8, 0x08, 0x10, 0x00, 3, 0, 0, 0, b'a', b'b', b'c'][..]);
        assert_eq!(
            (f.command(), f.index(), f.sub(), f.data_u32()),
            (0x41, 0x1008, 0, 3)
        );
        assert_eq!(f.normal_data(), b"abc");
        let e = Frame::new_unchecked(&[][..] as &[u8]);
        assert!(e.is_empty());
        assert_eq!(e.check_len(), Err(WireError::Truncated));
        assert!(Frame::new_checked(&[0x40u8, 0, 0x10][..]).is_err());
        assert!(Frame::new_checked(&[0x60u8][..]).is_ok());
        let mut out = [0u8; 16];
        assert_eq!(
            Response::abort(0x6040, 0, SdoAbort::ValueTooHigh).emit_coe(&mut out),
            10
        );
        assert_eq!(
            out[..10],
            [0x00, 0x20, 0x80, 0x40, 0x60, 0x00, 0x31, 0x00, 0x09, 0x06]
        );
        assert_eq!(
            Response::abort(0, 0, SdoAbort::Timeout).emit_coe(&mut out[..9]),
            0
        );
        let seg = |toggle, last, data| Response::UploadSegment { toggle, last, data };
        assert_eq!(seg(true, true, &[9, 8]).emit_coe(&mut out), 10);
        assert_eq!(out[..10], [0x00, 0x30, 0x1B, 9, 8, 0, 0, 0, 0, 0]);
        assert_eq!(seg(false, false, &[1]).emit_coe(&mut out[..9]), 0);
        let download = Response::Download {
            index: 0x1C12,
            sub: 2,
            complete_access: true,
        };
        assert_eq!(download.emit_coe(&mut out), 10);
        assert_eq!(out[..10], [0x00, 0x30, 0x70, 0x12, 0x1C, 2, 0, 0, 0, 0]);
        assert_eq!(
            Response::DownloadSegment { toggle: true }.emit_coe(&mut out),
            10
        );
        assert_eq!(out[..10], [0x00, 0x30, 0x30, 0, 0, 0, 0, 0, 0, 0]);
    }

    #[test]
    fn response_round_trips() {
        let cases: [&[u8]; 7] = [
            &[0x60, 0x40, 0x60, 0x00, 0, 0, 0, 0],
            &[0x70, 0x12, 0x1C, 0x02, 0, 0, 0, 0],
            &[0x30, 0, 0, 0, 0, 0, 0, 0],
            &[0x4B, 0x41, 0x60, 0x00, 0x37, 0x02, 0, 0],
            &[0x51, 0x00, 0x1C, 0x00, 5, 0, 0, 0, 4, 1, 2],
            &[0x1B, 9, 8, 0, 0, 0, 0, 0],
            &[0x80, 0x40, 0x60, 0x00, 0x31, 0x00, 0x09, 0x06],
        ];
        for bytes in cases {
            let r = Response::parse(&Frame::new_unchecked(bytes)).unwrap();
            assert_eq!(r.buffer_len(), bytes.len());
            let mut out = [0xEEu8; 16];
            assert_eq!(r.emit(&mut Frame::new_unchecked(&mut out[..])), bytes.len());
            assert_eq!(&out[..bytes.len()], bytes);
            assert_eq!(
                r.emit(&mut Frame::new_unchecked(&mut out[..bytes.len() - 1])),
                0
            );
        }
        assert_eq!(
            Response::parse(&Frame::new_unchecked(&[
                0x4B, 0x41, 0x60, 0x00, 0x37, 0x02, 0, 0
            ])),
            Ok(Response::UploadExpedited {
                index: 0x6041,
                sub: 0,
                data: &[0x37, 0x02]
            })
        );
        assert_eq!(
            Response::parse(&Frame::new_unchecked(&[0x60, 0x40, 0x60][..])),
            Err(WireError::Truncated)
        );
        assert_eq!(
            Response::parse(&Frame::new_unchecked(&[0xA0, 0, 0, 0, 0, 0, 0, 0][..])),
            Err(WireError::UnknownCommand(0xA0))
        );
        assert_eq!(
            Response::abort(0x1000, 0, SdoAbort::Timeout).service(),
            Service::SdoRequest
        );
        assert_eq!(
            Response::DownloadSegment { toggle: false }.service(),
            Service::SdoResponse
        );
    }

    #[test]
    fn request_frame_checks() {
        for short in [
            &[][..],
            &[0x40, 0, 0x10][..],
            &[0x23, 0, 0x60, 0, 1, 2, 3][..],
        ] {
            assert_eq!(Frame::new_checked(short).unwrap_err(), WireError::Truncated);
            assert_eq!(Request::parse(short), Err(ErrorDetail::SizeTooShort));
        }
        assert!(Frame::new_checked(&[0x60u8][..]).is_ok());
        assert_eq!(
            Request::parse(&[0xC0, 0x34]),
            Ok(Request::Unknown {
                command: 0xC0,
                index: 0x34,
                sub: 0
            })
        );
    }

    #[test]
    fn bit_helpers() {
        let mut b = [0xFFu8; 3];
        put_bits(&mut b, 3, 0b1010, 4);
        assert_eq!(b[0], 0b1101_0111);
        assert_eq!(get_bits(&b, 3, 4), 0b1010);
        put_bits(&mut b, 6, 0, 6);
        assert_eq!(b[..2], [0b0001_0111, 0b1111_0000]);
        assert_eq!(get_bits(&b, 20, 8), 0x0F); // bits past the end read 0
        put_bits(&mut b, 22, 0xFF, 8); // writes past the end are dropped
        assert_eq!(b[2], 0xFF);
    }
}
