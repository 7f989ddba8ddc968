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

/// A zero-copy view of an SDO frame (after the CoE header).
#[derive(Debug, Clone)]
pub struct Frame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Frame<T> {
    /// Wraps a buffer; accessors return 0 / empty for bytes beyond its end.
    pub const fn new(buffer: T) -> Self {
        Frame { buffer }
    }
    fn byte(&self, i: usize) -> u8 {
        self.buffer.as_ref().get(i).copied().unwrap_or(0)
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
        self.byte(field::COMMAND)
    }
    /// The index.
    pub fn index(&self) -> u16 {
        u16::from_le_bytes([
            self.byte(field::INDEX.start),
            self.byte(field::INDEX.start + 1),
        ])
    }
    /// The sub-index.
    pub fn sub(&self) -> u8 {
        self.byte(field::SUB)
    }
    /// The 4 data bytes of an initiate or abort frame.
    pub fn data4(&self) -> [u8; 4] {
        let s = field::DATA.start;
        [
            self.byte(s),
            self.byte(s + 1),
            self.byte(s + 2),
            self.byte(s + 3),
        ]
    }
    /// The 4 data bytes as u32 (complete size, abort code).
    pub fn data_u32(&self) -> u32 {
        u32::from_le_bytes(self.data4())
    }
    /// The data after the complete size of a normal transfer.
    pub fn normal_data(&self) -> &[u8] {
        self.buffer.as_ref().get(field::NORMAL_DATA).unwrap_or(&[])
    }
    /// The data area of a segment.
    pub fn segment_data(&self) -> &[u8] {
        self.buffer.as_ref().get(field::SEGMENT_DATA).unwrap_or(&[])
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
        let f = Frame::new(b);
        if f.is_empty() {
            return Err(ErrorDetail::SizeTooShort);
        }
        let c = f.command();
        let need_full = |r: Self| {
            if f.len() >= 8 {
                Ok(r)
            } else {
                Err(ErrorDetail::SizeTooShort)
            }
        };
        match c >> 5 {
            0 => {
                if f.len() < 8 {
                    return Err(ErrorDetail::SizeTooShort);
                }
                let seg: &'a [u8] = b.get(field::SEGMENT_DATA).unwrap_or(&[]);
                let n = if seg.len() > 7 {
                    seg.len()
                } else {
                    7 - ((c >> 1) & 7) as usize
                };
                Ok(Request::DownloadSegment {
                    toggle: c & cmd::TOGGLE != 0,
                    last: c & cmd::LAST != 0,
                    data: seg.get(..n).unwrap_or(seg),
                })
            }
            1 => {
                let expedited = c & cmd::EXPEDITED != 0;
                let size_indicated = c & cmd::SIZE_INDICATED != 0;
                let data = if expedited {
                    let n = if size_indicated {
                        4 - ((c >> 2) & 3) as usize
                    } else {
                        4
                    };
                    b.get(field::DATA.start..field::DATA.start + n)
                        .unwrap_or(&[])
                } else {
                    b.get(field::NORMAL_DATA).unwrap_or(&[])
                };
                need_full(Request::InitiateDownload {
                    index: f.index(),
                    sub: f.sub(),
                    complete_access: c & cmd::COMPLETE_ACCESS != 0,
                    expedited,
                    size_indicated,
                    size: f.data_u32(),
                    data,
                })
            }
            2 => need_full(Request::InitiateUpload {
                index: f.index(),
                sub: f.sub(),
                complete_access: c & cmd::COMPLETE_ACCESS != 0,
            }),
            3 => Ok(Request::UploadSegment {
                toggle: c & cmd::TOGGLE != 0,
            }),
            4 => need_full(Request::Abort {
                index: f.index(),
                sub: f.sub(),
                code: f.data_u32(),
            }),
            _ => Ok(Request::Unknown {
                command: c,
                index: f.index(),
                sub: f.sub(),
            }),
        }
    }
}

/// Writes a 10-byte initiate-style frame (CoE header, command, index, sub-index, 4 data
/// bytes) into `out`; returns 10, or 0 if `out` is too short. Every 10-byte answer is
/// built here.
#[inline(never)]
fn emit_initiate(
    out: &mut [u8],
    service: Service,
    command: u8,
    index: u16,
    sub: u8,
    data: [u8; 4],
) -> usize {
    let Some(b) = out.get_mut(..INITIATE_LEN) else {
        return 0;
    };
    let [h0, h1] = Header::of(service).to_u16().to_le_bytes();
    let [i0, i1] = index.to_le_bytes();
    let [d0, d1, d2, d3] = data;
    b.copy_from_slice(&[h0, h1, command, i0, i1, sub, d0, d1, d2, d3]);
    INITIATE_LEN
}

/// Writes an abort (CoE service 2, command 0x80) into `out` (the CoE payload area, at
/// least 10 bytes); returns 10, or 0 if `out` is too short.
pub fn emit_abort(out: &mut [u8], index: u16, sub: u8, abort: SdoAbort) -> usize {
    emit_initiate(
        out,
        Service::SdoRequest,
        cmd::ABORT,
        index,
        sub,
        abort.code().to_le_bytes(),
    )
}

/// Download response (0x60, complete access 0x70).
fn emit_download_response(out: &mut [u8], index: u16, sub: u8, ca: bool) -> usize {
    let c = cmd::DOWNLOAD_RESPONSE | if ca { cmd::COMPLETE_ACCESS } else { 0 };
    emit_initiate(out, Service::SdoResponse, c, index, sub, [0; 4])
}

/// Download segment response (0x20 | toggle, 7 reserved bytes).
fn emit_download_segment_response(out: &mut [u8], toggle: bool) -> usize {
    let c = cmd::DOWNLOAD_SEGMENT_RESPONSE | if toggle { cmd::TOGGLE } else { 0 };
    emit_initiate(out, Service::SdoResponse, c, 0, 0, [0; 4])
}

/// Segment frame (upload segment response): command, data padded to 7 bytes.
fn emit_segment(out: &mut [u8], toggle: bool, last: bool, data: &[u8]) -> usize {
    let len = data.len().max(7);
    let Some(b) = out.get_mut(..COE_HEADER_LEN + 1 + len) else {
        return 0;
    };
    let (head, rest) = b.split_at_mut(COE_HEADER_LEN + 1);
    Header::of(Service::SdoResponse).emit(head);
    let n = (7 - data.len().min(7)) as u8;
    head[COE_HEADER_LEN] =
        (if toggle { cmd::TOGGLE } else { 0 }) | (n << 1) | if last { cmd::LAST } else { 0 };
    let (d, pad) = rest.split_at_mut(data.len());
    d.copy_from_slice(data);
    pad.fill(0);
    COE_HEADER_LEN + 1 + len
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
                    Ok(()) => emit_download_response(out, index, sub, complete_access),
                    Err(a) => emit_abort(out, index, sub, a),
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
                            emit_download_segment_response(out, toggle)
                        }
                        Err(a) => {
                            self.t = Transfer::Idle;
                            emit_abort(out, index, sub, a)
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
                        emit_abort(out, index, sub, SdoAbort::ToggleBit)
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
                emit_abort(out, index, sub, SdoAbort::InvalidCommand)
            }
        };
        Ok(n)
    }

    /// A segment request that does not belong to the current transfer.
    fn no_transfer(&mut self, out: &mut [u8], expired: Option<(u16, u8)>) -> usize {
        if let Some((index, sub)) = expired {
            return emit_abort(out, index, sub, SdoAbort::Timeout);
        }
        let (index, sub) = self.target().unwrap_or((0, 0));
        self.t = Transfer::Idle;
        emit_abort(out, index, sub, SdoAbort::InvalidCommand)
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
            Err(a) => return emit_abort(out, index, sub, a),
        };
        let ca_bit = if ca { cmd::COMPLETE_ACCESS } else { 0 };
        if !ca && (1..=4).contains(&len) {
            let c = cmd::UPLOAD_RESPONSE
                | cmd::EXPEDITED
                | cmd::SIZE_INDICATED
                | (((4 - len) as u8) << 2);
            let mut d = [0u8; 4];
            d[..len].copy_from_slice(&self.buf[..len]);
            return emit_initiate(out, Service::SdoResponse, c, index, sub, d);
        }
        let room = out.len() - INITIATE_LEN;
        let first = len.min(room);
        emit_initiate(
            out,
            Service::SdoResponse,
            cmd::UPLOAD_RESPONSE | cmd::SIZE_INDICATED | ca_bit,
            index,
            sub,
            (len as u32).to_le_bytes(),
        );
        out[INITIATE_LEN..INITIATE_LEN + first].copy_from_slice(&self.buf[..first]);
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
        let n = emit_segment(out, toggle, last, data);
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
        let f = Frame::new(&[0x41u8, 0x08, 0x10, 0x00, 3, 0, 0, 0, b'a', b'b', b'c'][..]);
        assert_eq!(
            (f.command(), f.index(), f.sub(), f.data_u32()),
            (0x41, 0x1008, 0, 3)
        );
        assert_eq!(f.normal_data(), b"abc");
        let e = Frame::new(&[][..] as &[u8]);
        assert!(e.is_empty());
        assert_eq!((e.command(), e.index(), e.data4()), (0, 0, [0; 4]));
        let mut out = [0u8; 16];
        assert_eq!(emit_abort(&mut out, 0x6040, 0, SdoAbort::ValueTooHigh), 10);
        assert_eq!(
            out[..10],
            [0x00, 0x20, 0x80, 0x40, 0x60, 0x00, 0x31, 0x00, 0x09, 0x06]
        );
        assert_eq!(emit_abort(&mut out[..9], 0, 0, SdoAbort::Timeout), 0);
        assert_eq!(emit_segment(&mut out, true, true, &[9, 8]), 10);
        assert_eq!(out[..10], [0x00, 0x30, 0x1B, 9, 8, 0, 0, 0, 0, 0]);
        assert_eq!(emit_segment(&mut out[..9], false, false, &[1]), 0);
        assert_eq!(emit_download_response(&mut out, 0x1C12, 2, true), 10);
        assert_eq!(out[..10], [0x00, 0x30, 0x70, 0x12, 0x1C, 2, 0, 0, 0, 0]);
        assert_eq!(emit_download_segment_response(&mut out, true), 10);
        assert_eq!(out[..10], [0x00, 0x30, 0x30, 0, 0, 0, 0, 0, 0, 0]);
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
