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

use super::HEADER_LEN as COE_HEADER_LEN;
use crate::esm::EsmState;
use crate::mailbox::ErrorDetail;
use crate::od::{self, Dictionary, Entry, Object, ObjectCode, ObjectKey, SdoAbort};

/// Largest object (or complete-access image) a segmented transfer can carry.
pub const TRANSFER_MAX: usize = 512;
/// A segmented transfer idle for longer than this is aborted (0x05040000).
pub const TRANSFER_TIMEOUT_US: u64 = 1_000_000;
/// Length of an initiate / abort frame after the mailbox header (CoE header + 8).
pub const INITIATE_LEN: usize = COE_HEADER_LEN + 8;

pub use crate::wire::sdo::*;

/// A segmented download in progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Download {
    to: Address,
    /// Complete size announced by the initiate request.
    total: usize,
    /// Toggle bit the next segment must carry.
    toggle: bool,
}

/// A segmented upload in progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Upload {
    to: Address,
    /// Bytes of the buffer already sent.
    pos: usize,
    /// Toggle bit the next segment request must carry.
    toggle: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Transfer {
    Idle,
    Download(Download),
    Upload(Upload),
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

    fn target(&self) -> Option<ObjectKey> {
        match self.t {
            Transfer::Idle => None,
            Transfer::Download(Download { to, .. }) | Transfer::Upload(Upload { to, .. }) => {
                Some(to.key())
            }
        }
    }

    /// Ends a transfer idle for longer than [`TRANSFER_TIMEOUT_US`]; returns the entry
    /// (or object) it addressed.
    pub fn expire(&mut self, now_us: u64) -> Option<ObjectKey> {
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
        expired: Option<ObjectKey>,
    ) -> Result<usize, ErrorDetail> {
        if out.len() < INITIATE_LEN {
            return Err(ErrorDetail::NoMoreMemory);
        }
        let req = Request::parse(body)?;
        let n = match req {
            Request::InitiateDownload(r) => {
                self.t = Transfer::Idle;
                let to = r.address;
                let done = if r.expedited {
                    expedited_download(&r, dict, state)
                } else {
                    self.initiate_normal_download(&r, dict, state, now_us)
                };
                match done {
                    Ok(()) => Response::Download {
                        key: to.key(),
                        complete_access: to.complete_access,
                    }
                    .emit_coe(out),
                    Err(a) => Response::abort(to.key(), a).emit_coe(out),
                }
            }
            Request::DownloadSegment(seg) => match self.t {
                Transfer::Download(d) => match self.download_segment(d, &seg, dict, state) {
                    Ok(()) => {
                        self.last_us = now_us;
                        Response::DownloadSegment { toggle: seg.toggle }.emit_coe(out)
                    }
                    Err(a) => {
                        self.t = Transfer::Idle;
                        Response::abort(d.to.key(), a).emit_coe(out)
                    }
                },
                _ => self.no_transfer(out, expired),
            },
            Request::InitiateUpload(to) => {
                self.t = Transfer::Idle;
                self.initiate_upload(out, to, dict, state, now_us)
            }
            Request::UploadSegment { toggle } => match self.t {
                Transfer::Upload(u) if toggle != u.toggle => {
                    self.t = Transfer::Idle;
                    Response::abort(u.to.key(), SdoAbort::ToggleBit).emit_coe(out)
                }
                Transfer::Upload(u) => {
                    self.last_us = now_us;
                    self.upload_segment(out, u)
                }
                _ => self.no_transfer(out, expired),
            },
            Request::Abort { .. } => {
                self.t = Transfer::Idle;
                0
            }
            Request::Unknown { key, .. } => {
                self.t = Transfer::Idle;
                Response::abort(key, SdoAbort::InvalidCommand).emit_coe(out)
            }
        };
        Ok(n)
    }

    /// A segment request that does not belong to the current transfer.
    fn no_transfer(&mut self, out: &mut [u8], expired: Option<ObjectKey>) -> usize {
        if let Some(key) = expired {
            return Response::abort(key, SdoAbort::Timeout).emit_coe(out);
        }
        let key = self.target().unwrap_or(ObjectKey::new(0, 0));
        self.t = Transfer::Idle;
        Response::abort(key, SdoAbort::InvalidCommand).emit_coe(out)
    }

    fn initiate_normal_download(
        &mut self,
        r: &InitiateDownload<'_>,
        dict: &mut impl Dictionary,
        state: EsmState,
        now_us: u64,
    ) -> Result<(), SdoAbort> {
        let to = r.address;
        let total = r.size as usize;
        check_normal_download(dict.objects(), to, total, state)?;
        let data = r.data;
        if data.len() >= total {
            return download(dict, state, to, &data[..total]);
        }
        self.buf[..data.len()].copy_from_slice(data);
        self.len = data.len();
        self.t = Transfer::Download(Download {
            to,
            total,
            toggle: false,
        });
        self.last_us = now_us;
        Ok(())
    }

    fn download_segment(
        &mut self,
        d: Download,
        seg: &DownloadSegment<'_>,
        dict: &mut impl Dictionary,
        state: EsmState,
    ) -> Result<(), SdoAbort> {
        if seg.toggle != d.toggle {
            return Err(SdoAbort::ToggleBit);
        }
        let end = self.len + seg.data.len();
        if end > d.total {
            return Err(SdoAbort::TypeMismatch);
        }
        self.buf[self.len..end].copy_from_slice(seg.data);
        self.len = end;
        if !seg.last {
            self.t = Transfer::Download(Download {
                toggle: !seg.toggle,
                ..d
            });
            return Ok(());
        }
        self.t = Transfer::Idle;
        if end != d.total {
            return Err(SdoAbort::TypeMismatch);
        }
        download(dict, state, d.to, &self.buf[..end])
    }

    fn initiate_upload(
        &mut self,
        out: &mut [u8],
        to: Address,
        dict: &mut impl Dictionary,
        state: EsmState,
        now_us: u64,
    ) -> usize {
        let key = to.key();
        let len = match upload(dict, state, to, &mut self.buf) {
            Ok(n) => n,
            Err(a) => return Response::abort(key, a).emit_coe(out),
        };
        if !to.complete_access && (1..=4).contains(&len) {
            let data = &self.buf[..len];
            return Response::UploadExpedited { key, data }.emit_coe(out);
        }
        let room = out.len() - INITIATE_LEN;
        let first = len.min(room);
        Response::Upload {
            key,
            complete_access: to.complete_access,
            size: len as u32,
            data: &self.buf[..first],
        }
        .emit_coe(out);
        if first < len {
            self.len = len;
            self.t = Transfer::Upload(Upload {
                to,
                pos: first,
                toggle: false,
            });
            self.last_us = now_us;
        }
        INITIATE_LEN + first
    }

    fn upload_segment(&mut self, out: &mut [u8], u: Upload) -> usize {
        let room = out.len() - COE_HEADER_LEN - 1;
        let end = (u.pos + room).min(self.len);
        let last = end == self.len;
        let data = self.buf.get(u.pos.min(end)..end).unwrap_or_default();
        let toggle = u.toggle;
        let n = Response::UploadSegment { toggle, last, data }.emit_coe(out);
        self.t = if last {
            Transfer::Idle
        } else {
            Transfer::Upload(Upload {
                pos: end,
                toggle: !toggle,
                ..u
            })
        };
        n
    }
}

/// An expedited download: the value is in the request.
fn expedited_download(
    r: &InitiateDownload<'_>,
    dict: &mut impl Dictionary,
    state: EsmState,
) -> Result<(), SdoAbort> {
    let to = r.address;
    let mut data = r.data;
    if !r.size_indicated && !to.complete_access {
        // Size not indicated: the entry's own length (at most the 4 bytes carried).
        let e = od::find_entry(dict.objects(), to.key())?;
        data = data.get(..e.byte_len().clamp(1, 4)).unwrap_or(data);
    }
    download(dict, state, to, data)
}

/// Refuses early what can never succeed, before a segmented transfer starts.
fn check_normal_download(
    objects: &'static [Object],
    to: Address,
    total: usize,
    state: EsmState,
) -> Result<(), SdoAbort> {
    if to.complete_access {
        let obj = od::find(objects, to.index).ok_or(SdoAbort::ObjectDoesNotExist)?;
        if obj.code() == ObjectCode::Var || to.sub > 1 {
            return Err(SdoAbort::UnsupportedAccess);
        }
    } else {
        let e = od::find_entry(objects, to.key())?;
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
    }
    if total > TRANSFER_MAX {
        return Err(SdoAbort::OutOfMemory);
    }
    Ok(())
}

/// Reads one entry (or a complete-access image) into `buf`; returns its length.
fn upload(
    dict: &mut impl Dictionary,
    state: EsmState,
    to: Address,
    buf: &mut [u8],
) -> Result<usize, SdoAbort> {
    let obj = od::find(dict.objects(), to.index).ok_or(SdoAbort::ObjectDoesNotExist)?;
    if to.complete_access {
        return ca_upload(obj, dict, state, to.sub, buf);
    }
    let e = obj.entry(to.sub).ok_or(SdoAbort::SubindexDoesNotExist)?;
    od::check_read(e, state)?;
    let n = dict.read(to.key(), buf)?;
    Ok(n.min(buf.len()))
}

/// Checks and writes one entry or a complete-access image.
fn download(
    dict: &mut impl Dictionary,
    state: EsmState,
    to: Address,
    data: &[u8],
) -> Result<(), SdoAbort> {
    let objects = dict.objects();
    if to.complete_access {
        let obj = od::find(objects, to.index).ok_or(SdoAbort::ObjectDoesNotExist)?;
        return ca_download(obj, dict, state, to.sub, data);
    }
    let e = od::find_entry(objects, to.key())?;
    od::check_write(e, data, state)?;
    dict.write(to.key(), data, state)
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
    if e.bits().is_multiple_of(8) {
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
    dict.read(ObjectKey::new(obj.index, 0), &mut tmp)?;
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
        let nbits = e.bits() as usize;
        if e.data_type == od::DataType::OctetString {
            let start = bit.div_ceil(8);
            let end = start + nbits / 8;
            let out = buf.get_mut(start..end).ok_or(SdoAbort::OutOfMemory)?;
            od::check_read(e, state)?;
            let n = dict
                .read(ObjectKey::new(obj.index, e.sub), out)?
                .min(out.len());
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
                dict.read(ObjectKey::new(obj.index, e.sub), &mut val)?;
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
    let nbits = e.bits() as usize;
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

/// Where the entries of a complete-access download image are.
#[derive(Debug, Clone, Copy)]
struct CaLayout {
    /// Entries 1..=count.
    count: u8,
    /// Bit position of the first entry.
    first_bit: usize,
    /// Stop before the entry that would end after this bit (the data length).
    stop_at_data_end: Option<usize>,
}

/// Walks the entries of a complete-access download image and returns the end bit:
/// checks every writable entry's value (`write` false) or writes it (`write` true).
/// One walk for both passes of [`ca_download`].
fn ca_walk(
    obj: &Object,
    dict: &mut impl Dictionary,
    state: EsmState,
    data: &[u8],
    layout: CaLayout,
    write: bool,
) -> Result<usize, SdoAbort> {
    let CaLayout {
        count,
        first_bit,
        stop_at_data_end,
    } = layout;
    let mut bit = first_bit;
    for e in ca_entries(obj, count) {
        let nbits = e.bits() as usize;
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
                dict.write(ObjectKey::new(obj.index, e.sub), v, state)?;
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
    let layout = CaLayout {
        count,
        first_bit,
        stop_at_data_end: stop,
    };
    let end = ca_walk(obj, dict, state, data, layout, false)?;
    if end.div_ceil(8) != data.len() {
        return Err(SdoAbort::TypeMismatch);
    }
    // Pass 2: the writes, in the PDO-mapping edit order.
    let count_key = ObjectKey::new(obj.index, 0);
    let si0_written = sub == 0 && e0.access.writable_in(state);
    if si0_written && e0.min() <= 0 {
        dict.write(count_key, &[0], state)?;
    }
    ca_walk(obj, dict, state, data, layout, true)?;
    if si0_written {
        dict.write(count_key, &[count], state)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests;
