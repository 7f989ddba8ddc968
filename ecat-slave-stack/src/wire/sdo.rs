//! The SDO wire format: a zero-copy [`Frame`] view with its [`field`] offsets and
//! [`cmd`] bits, the master's [`Request`] and this server's [`Response`].

use super::coe::{Header, Service, HEADER_LEN as COE_HEADER_LEN};
use super::mailbox::ErrorDetail;
use crate::od::{ObjectKey, SdoAbort};

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
    /// The index and sub-index fields.
    // Measured (cargo xtask size, LAN9252 image): out of line the image is 80 B larger.
    #[inline]
    pub fn key(&self) -> ObjectKey {
        let b = self.buffer.as_ref();
        let i = &b[field::INDEX];
        ObjectKey::new(u16::from_le_bytes([i[0], i[1]]), b[field::SUB])
    }
    /// Index, sub-index and the complete access flag of an initiate frame.
    pub fn address(&self) -> Address {
        let key = self.key();
        Address {
            index: key.index,
            sub: key.sub,
            complete_access: self.command() & cmd::COMPLETE_ACCESS != 0,
        }
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
    /// Sets the index and sub-index fields.
    pub fn set_key(&mut self, key: ObjectKey) {
        let b = self.buffer.as_mut();
        b[field::INDEX].copy_from_slice(&key.index.to_le_bytes());
        b[field::SUB] = key.sub;
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

/// The entry an SDO request addresses, or with complete access the object from this
/// sub-index on. Index and sub-index stay the two wire fields, so an address is four
/// bytes (an [`ObjectKey`] and the flag would take six, with its padding byte);
/// [`Address::key`] gives them as a key.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Address {
    /// Index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Complete access.
    pub complete_access: bool,
}

impl Address {
    /// The entry addressed (with complete access: the object's index and the first
    /// sub-index).
    pub const fn key(&self) -> ObjectKey {
        ObjectKey::new(self.index, self.sub)
    }
}

/// An initiate download request (expedited: `data` is the value; normal: `size` is the
/// complete size and `data` the part carried in this frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InitiateDownload<'a> {
    /// The entry or object written.
    pub address: Address,
    /// Expedited transfer.
    pub expedited: bool,
    /// Size indicated (expedited: `data.len()` is exact).
    pub size_indicated: bool,
    /// Complete size (normal transfer).
    pub size: u32,
    /// Data carried in this frame.
    pub data: &'a [u8],
}

/// A download segment request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DownloadSegment<'a> {
    /// Toggle bit.
    pub toggle: bool,
    /// Last segment.
    pub last: bool,
    /// Data of this segment.
    pub data: &'a [u8],
}

/// An SDO request from the master.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request<'a> {
    /// Initiate download.
    InitiateDownload(InitiateDownload<'a>),
    /// Download segment.
    DownloadSegment(DownloadSegment<'a>),
    /// Initiate upload of this entry or object.
    InitiateUpload(Address),
    /// Upload segment.
    UploadSegment {
        /// Toggle bit.
        toggle: bool,
    },
    /// Abort from the master.
    Abort {
        /// Index and sub-index.
        key: ObjectKey,
        /// Abort code.
        code: u32,
    },
    /// Block transfers and anything else.
    Unknown {
        /// The command byte.
        command: u8,
        /// Index (bytes 1–2) and sub-index (byte 3), as far as present (missing bytes
        /// as 0).
        key: ObjectKey,
    },
}

/// The data of a segment frame `b` with command `c`: a frame longer than the minimum
/// carries data up to its end; a minimum frame (7 data bytes) says in bits 3:1 how many
/// of them are unused.
fn segment_data(c: u8, b: &[u8]) -> &[u8] {
    let seg = b.get(field::SEGMENT_DATA).unwrap_or_default();
    let n = if seg.len() > 7 {
        seg.len()
    } else {
        7 - usize::from((c >> 1) & 7)
    };
    seg.get(..n).unwrap_or(seg)
}

/// The data of an expedited frame `b` with command `c`: 4 bytes, less the unused ones
/// bits 3:2 give when the size is indicated.
fn expedited_data(c: u8, b: &[u8]) -> &[u8] {
    let n = if c & cmd::SIZE_INDICATED != 0 {
        4 - usize::from((c >> 2) & 3)
    } else {
        4
    };
    b.get(field::DATA.start..field::DATA.start + n)
        .unwrap_or_default()
}

impl<'a> Request<'a> {
    /// Parses the SDO part of a request (after the CoE header). `Err` = too short for the
    /// command it carries.
    pub fn parse(b: &'a [u8]) -> Result<Self, ErrorDetail> {
        let f = Frame::new_checked(b)?;
        let c = f.command();
        match c >> 5 {
            0 => Ok(Request::DownloadSegment(DownloadSegment {
                toggle: c & cmd::TOGGLE != 0,
                last: c & cmd::LAST != 0,
                data: segment_data(c, b),
            })),
            1 => {
                let expedited = c & cmd::EXPEDITED != 0;
                let size_indicated = c & cmd::SIZE_INDICATED != 0;
                let data: &'a [u8] = if expedited {
                    expedited_data(c, b)
                } else {
                    &b[field::NORMAL_DATA]
                };
                Ok(Request::InitiateDownload(InitiateDownload {
                    address: f.address(),
                    expedited,
                    size_indicated,
                    size: f.data_u32(),
                    data,
                }))
            }
            2 => Ok(Request::InitiateUpload(f.address())),
            3 => Ok(Request::UploadSegment {
                toggle: c & cmd::TOGGLE != 0,
            }),
            4 => Ok(Request::Abort {
                key: f.key(),
                code: f.data_u32(),
            }),
            _ => {
                // Unknown commands need only the command byte: index and sub-index are
                // echoed in the abort as far as the request carries them (missing
                // bytes as 0).
                let at = |i: usize| b.get(i).copied().unwrap_or(0);
                let index =
                    u16::from_le_bytes([at(field::INDEX.start), at(field::INDEX.start + 1)]);
                Ok(Request::Unknown {
                    command: c,
                    key: ObjectKey::new(index, at(field::SUB)),
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
        /// Index and sub-index.
        key: ObjectKey,
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
        /// Index and sub-index.
        key: ObjectKey,
        /// The value, 1…4 bytes.
        data: &'a [u8],
    },
    /// Normal upload response (0x41, complete access 0x51): the complete size and the
    /// first part of the data.
    Upload {
        /// Index and sub-index.
        key: ObjectKey,
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
        /// Index and sub-index.
        key: ObjectKey,
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
    pub const fn abort(key: ObjectKey, abort: SdoAbort) -> Self {
        Response::Abort {
            key,
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
        let key = frame.key();
        let ca = c & cmd::COMPLETE_ACCESS != 0;
        Ok(match c >> 5 {
            0 => Response::UploadSegment {
                toggle: c & cmd::TOGGLE != 0,
                last: c & cmd::LAST != 0,
                data: segment_data(c, b),
            },
            1 => Response::DownloadSegment {
                toggle: c & cmd::TOGGLE != 0,
            },
            2 if c & cmd::EXPEDITED != 0 => Response::UploadExpedited {
                key,
                data: expedited_data(c, b),
            },
            2 => Response::Upload {
                key,
                complete_access: ca,
                size: frame.data_u32(),
                data: &b[field::NORMAL_DATA],
            },
            3 => Response::Download {
                key,
                complete_access: ca,
            },
            4 => Response::Abort {
                key,
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
        let (command, key, d4) = match *self {
            Response::Download {
                key,
                complete_access,
            } => (
                cmd::DOWNLOAD_RESPONSE | flag(complete_access, cmd::COMPLETE_ACCESS),
                key,
                [0; 4],
            ),
            Response::DownloadSegment { toggle } => (
                cmd::DOWNLOAD_SEGMENT_RESPONSE | flag(toggle, cmd::TOGGLE),
                ObjectKey::new(0, 0),
                [0; 4],
            ),
            Response::UploadExpedited { key, data } => {
                let len = data.len().min(4);
                let mut d = [0u8; 4];
                d[..len].copy_from_slice(&data[..len]);
                let c = cmd::UPLOAD_RESPONSE
                    | cmd::EXPEDITED
                    | cmd::SIZE_INDICATED
                    | ((u8::try_from(4 - len).unwrap_or(0) & 3) << 2);
                (c, key, d)
            }
            Response::Upload {
                key,
                complete_access,
                size,
                data,
            } => {
                frame.normal_data_mut()[..data.len()].copy_from_slice(data);
                let c = cmd::UPLOAD_RESPONSE
                    | cmd::SIZE_INDICATED
                    | flag(complete_access, cmd::COMPLETE_ACCESS);
                (c, key, size.to_le_bytes())
            }
            Response::Abort { key, code } => (cmd::ABORT, key, code.to_le_bytes()),
            Response::UploadSegment { toggle, last, data } => {
                // A segment has no index field: command and 7 or more data bytes.
                let pad = u8::try_from(7 - data.len().min(7)).unwrap_or(0);
                frame.set_command(flag(toggle, cmd::TOGGLE) | (pad << 1) | flag(last, cmd::LAST));
                let (d, rest) = frame.segment_data_mut()[..n - 1].split_at_mut(data.len());
                d.copy_from_slice(data);
                rest.fill(0);
                return n;
            }
        };
        frame.set_command(command);
        frame.set_key(key);
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
