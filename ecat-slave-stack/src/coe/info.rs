//! SDO information (CoE service 8): the master browses the object dictionary.
//!
//! After the CoE header: opcode (bits 6:0) with the "incomplete" flag (bit 7), a reserved
//! byte and a u16 "fragments left" ([`field`]), then the service data:
//!
//! | Opcode | Request | Response |
//! |---|---|---|
//! | 0x01 → 0x02 get OD list | u16 list type | u16 list type, u16 indices (list 0: five u16 counts of lists 1–5) |
//! | 0x03 → 0x04 get object description | u16 index | u16 index, u16 data type, u8 max sub-index, u8 object code, name |
//! | 0x05 → 0x06 get entry description | u16 index, u8 sub-index, u8 value-info request | u16 index, u8 sub-index, u8 value info, u16 data type, u16 bit length, u16 access, (default) (min) (max), name |
//! | — → 0x07 error | | u32 abort code |
//!
//! A response longer than the mailbox is sent as consecutive fragments: every fragment
//! but the last has the incomplete flag; "fragments left" counts down to 0. The list type
//! is only in the first fragment of an OD list.
//!
//! Choices of this implementation:
//! * OD lists 4 (backup) and 5 (settings) both hold the objects with at least one entry
//!   marked `saved` ([`od::OdListType`]).
//! * Entry description access word: bits 0–5 read/write per ESM state, bit 6 RxPDO, bit 7
//!   TxPDO mappable, bits 8 (backup) and 9 (setting) for `saved` entries.
//! * Value info: default (0x10), minimum (0x20) and maximum (0x40) are returned for
//!   numeric entries when requested, each at the entry's byte length; the response's
//!   value-info byte says which ones are present (bits 0–2 of the request are echoed).
//!   There are no ETG unit codes in the dictionary, so the unit-type flag (0x08) is never
//!   answered; instead a unit is appended to the entry name as `"name [unit]"`.
//! * Object description data type: the entry's type for VAR, the element type (sub-index
//!   1) for ARRAY, 0x002A (RECORD) for RECORD.
//! * Missing object → error 0x06020000, missing sub-index → 0x06090011, unknown list type
//!   → 0x06010000, unknown opcode → 0x05040001.

use crate::mailbox::ErrorDetail;
use crate::od::{
    self, DefaultValue, Dictionary, Entry, Name, Object, ObjectCode, ObjectKey, OdListType,
    SdoAbort,
};

pub use crate::wire::sdo_info::*;

/// The SDO information error for an abort.
const fn error(abort: SdoAbort) -> Repr {
    Repr::Error { code: abort.code() }
}

/// The answer to a request.
#[derive(Debug, Clone, Copy)]
pub enum Answer {
    /// A single frame of this length was written (an error).
    Frame(usize),
    /// A response sent as one or more fragments by [`InfoJob::next_fragment`].
    Series(InfoJob),
}

const HEAD_MAX: usize = 40;

#[derive(Debug, Clone, Copy)]
enum Body {
    OdList {
        list: OdListType,
        objects: &'static [Object],
    },
    /// `head`, then the name (expanded from its packed form while the fragments are
    /// written), then `tail`.
    Bytes {
        head: [u8; HEAD_MAX],
        head_len: u8,
        name: Name,
        tail: [&'static [u8]; 3],
    },
}

/// A response being sent fragment by fragment (no heap: OD lists are generated from the
/// static object table for each fragment).
#[derive(Debug, Clone, Copy)]
pub struct InfoJob {
    op: u8,
    body: Body,
    next: u16,
    fragments: u16,
    per_fragment: usize,
}

impl InfoJob {
    fn new(op: u8, body: Body, cap: usize) -> Self {
        let mut per = cap.saturating_sub(PREFIX_LEN).max(2);
        if matches!(body, Body::OdList { .. }) {
            per &= !1;
        }
        let mut job = InfoJob {
            op,
            body,
            next: 0,
            fragments: 1,
            per_fragment: per,
        };
        let total = job.payload_len();
        job.fragments = total.div_ceil(per).clamp(1, u16::MAX as usize) as u16;
        job
    }

    /// Length of the whole response data (all fragments).
    pub fn payload_len(&self) -> usize {
        match self.body {
            Body::OdList {
                list: OdListType::Counts,
                ..
            } => 2 + 2 * OdListType::LISTS.len(),
            Body::OdList { list, objects } => 2 + 2 * list.count(objects),
            Body::Bytes {
                head_len,
                name,
                tail,
                ..
            } => head_len as usize + name.len() + tail.iter().map(|t| t.len()).sum::<usize>(),
        }
    }

    /// Number of fragments of the response.
    pub fn fragments(&self) -> u16 {
        self.fragments
    }

    /// Writes the next fragment (CoE payload) into `out` (the mailbox data area, the
    /// size given to the request). Returns its length and whether it was the last.
    pub fn next_fragment(&mut self, out: &mut [u8]) -> (usize, bool) {
        if self.next >= self.fragments || out.len() < PREFIX_LEN + self.per_fragment {
            self.next = self.fragments;
            return (0, true);
        }
        let left = self.fragments - 1 - self.next;
        emit_prefix(out, self.op, left > 0, left);
        let start = self.next as usize * self.per_fragment;
        let end = (start + self.per_fragment).min(self.payload_len());
        let dst = &mut out[PREFIX_LEN..PREFIX_LEN + (end - start)];
        self.fill(start, dst);
        self.next += 1;
        (PREFIX_LEN + dst.len(), self.next >= self.fragments)
    }

    /// Copies the response data `[start, start + dst.len())` into `dst`.
    fn fill(&self, start: usize, dst: &mut [u8]) {
        match self.body {
            Body::OdList { list, objects } => {
                // Item 0 is the list type, items 1.. the indices (or the five counts).
                let first_item = start / 2;
                let n_items = dst.len() / 2;
                let mut put = |item: usize, v: u16| {
                    let o = (item - first_item) * 2;
                    if let Some(d) = dst.get_mut(o..o + 2) {
                        d.copy_from_slice(&v.to_le_bytes());
                    }
                };
                if n_items == 0 {
                    return;
                }
                let mut item = first_item;
                if item == 0 {
                    put(0, list.code());
                    item = 1;
                }
                let end_item = first_item + n_items;
                if list == OdListType::Counts {
                    for (i, l) in OdListType::LISTS.iter().enumerate() {
                        if (item..end_item).contains(&(i + 1)) {
                            put(i + 1, l.count(objects) as u16);
                        }
                    }
                } else {
                    let it = objects.iter().filter(|o| list.contains(o)).enumerate();
                    for (i, o) in it
                        .skip(item.saturating_sub(1))
                        .take(end_item.saturating_sub(item))
                    {
                        put(i + 1, o.index);
                    }
                }
            }
            Body::Bytes {
                head,
                head_len,
                name,
                tail,
            } => {
                // The payload is head, name, tail; `start` is where `dst` begins in it.
                let mut pos = 0usize;
                let mut put = |b: u8| {
                    if let Some(d) = pos.checked_sub(start).and_then(|i| dst.get_mut(i)) {
                        *d = b;
                    }
                    pos += 1;
                };
                let head = head.get(..head_len as usize).unwrap_or(&[]);
                head.iter().for_each(|&b| put(b));
                name.bytes().for_each(&mut put);
                tail.iter().copied().flatten().for_each(|&b| put(b));
            }
        }
    }
}

/// Data type code of an object for its description.
pub fn object_data_type(obj: &Object) -> u16 {
    match obj.code() {
        ObjectCode::Record => RECORD_TYPE,
        ObjectCode::Array => obj
            .entry(1)
            .or(obj.entries().first())
            .map_or(0, |e| e.data_type.code()),
        ObjectCode::Var => obj.entries().first().map_or(0, |e| e.data_type.code()),
    }
}

/// Access word of the entry description (bits 8 and 9 for saved entries).
pub const fn entry_access_word(e: &Entry) -> u16 {
    e.sdo_info_access() | if e.is_saved() { (1 << 8) | (1 << 9) } else { 0 }
}

/// Executes one SDO information request (`body` after the CoE header). `out` is the
/// mailbox data area; `cap` its size (fragment size).
pub fn on_request(
    body: &[u8],
    out: &mut [u8],
    dict: &mut impl Dictionary,
    cap: usize,
) -> Result<Answer, ErrorDetail> {
    let f = Frame::new(body);
    let req = match Repr::parse(&f) {
        Ok(r) => r,
        // An error frame from the master is no request, whatever its length: answered
        // like an unknown opcode.
        Err(_) if f.has_header() && f.opcode() == opcode::ERROR => Repr::Unknown {
            opcode: opcode::ERROR,
        },
        Err(WireError::Truncated) => return Err(ErrorDetail::SizeTooShort),
    };
    let objects = dict.objects();
    let err = |out: &mut [u8], a: SdoAbort| Answer::Frame(error(a).emit_coe(out));
    match req {
        Repr::OdList { list } => Ok(match OdListType::from_code(list) {
            Some(list) => Answer::Series(InfoJob::new(
                opcode::OD_LIST_RESPONSE,
                Body::OdList { list, objects },
                cap,
            )),
            None => err(out, SdoAbort::UnsupportedAccess),
        }),
        Repr::ObjectDescription { index } => {
            let Some(obj) = od::find(objects, index) else {
                return Ok(err(out, SdoAbort::ObjectDoesNotExist));
            };
            let mut head = [0u8; HEAD_MAX];
            let head_len = ObjectDescriptionHead {
                index,
                data_type: object_data_type(obj),
                max_sub: obj.max_sub(),
                object_code: obj.code() as u8,
            }
            .emit(&mut head);
            let body = Body::Bytes {
                head,
                head_len: head_len as u8,
                name: obj.name(),
                tail: [&[], &[], &[]],
            };
            Ok(Answer::Series(InfoJob::new(
                opcode::OBJECT_DESCRIPTION_RESPONSE,
                body,
                cap,
            )))
        }
        Repr::EntryDescription { key, value_info } => {
            let e = match od::find_entry(objects, key) {
                Ok(e) => e,
                Err(a) => return Ok(err(out, a)),
            };
            Ok(Answer::Series(InfoJob::new(
                opcode::ENTRY_DESCRIPTION_RESPONSE,
                entry_body(key, e, value_info),
                cap,
            )))
        }
        Repr::Error { .. } | Repr::Unknown { .. } => Ok(err(out, SdoAbort::InvalidCommand)),
    }
}

fn entry_body(key: ObjectKey, e: &'static Entry, request: u8) -> Body {
    let mut head = [0u8; HEAD_MAX];
    let mut len = EntryDescriptionHead::LEN;
    let mut vi = request & value_info::ECHOED;
    let n = e.byte_len();
    let numeric = od::has_numeric_range(e.data_type) && (1..=8).contains(&n);
    if numeric {
        let default = match e.default_value() {
            DefaultValue::Int(v) => Some(v),
            _ => None,
        };
        let fields = [
            (value_info::DEFAULT, default),
            (value_info::MINIMUM, Some(e.min())),
            (value_info::MAXIMUM, Some(e.max())),
        ];
        for (flag, v) in fields {
            if let (true, Some(v)) = (request & flag != 0, v) {
                head[len..len + n].copy_from_slice(&v.to_le_bytes()[..n]);
                len += n;
                vi |= flag;
            }
        }
    }
    EntryDescriptionHead {
        key,
        value_info: vi,
        data_type: e.data_type.code(),
        bit_length: e.bits(),
        access: entry_access_word(e),
    }
    .emit(&mut head);
    let tail: [&'static [u8]; 3] = if e.unit_text().is_empty() {
        [&[], &[], &[]]
    } else {
        [b" [", e.unit_text().as_bytes(), b"]"]
    };
    Body::Bytes {
        head,
        head_len: len as u8,
        name: e.name(),
        tail,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn description_heads_bytes() {
        let mut b = [0xEEu8; 12];
        let o = ObjectDescriptionHead {
            index: 0x1C12,
            data_type: 0x0006,
            max_sub: 4,
            object_code: 8,
        };
        assert_eq!(o.emit(&mut b), 6);
        assert_eq!(b[..7], [0x12, 0x1C, 0x06, 0x00, 4, 8, 0xEE]);
        assert_eq!(o.emit(&mut b[..5]), 0);
        let e = EntryDescriptionHead {
            key: ObjectKey::new(0x6040, 0),
            value_info: 0x70,
            data_type: 0x0006,
            bit_length: 16,
            access: 0x023F,
        };
        assert_eq!(e.emit(&mut b), 10);
        assert_eq!(
            b[..11],
            [0x40, 0x60, 0, 0x70, 6, 0, 16, 0, 0x3F, 0x02, 0xEE]
        );
        let mut short = [0u8; 9];
        assert_eq!(e.emit(&mut short), 0);
        assert_eq!(short, [0; 9]);
    }

    #[test]
    fn info_frame_view_and_error() {
        let f = Frame::new(&[0x86u8, 0x00, 0x03, 0x00, 0xAA][..]);
        assert!(f.has_header());
        assert_eq!(
            (f.opcode(), f.incomplete(), f.fragments_left(), f.data()),
            (6, true, 3, &[0xAA][..])
        );
        let s = Frame::new(&[0x01u8][..]);
        assert!(!s.has_header());
        assert_eq!(s.fragments_left(), 0);
        assert!(s.data().is_empty());
        let mut out = [0u8; 10];
        assert_eq!(error(SdoAbort::ObjectDoesNotExist).emit_coe(&mut out), 10);
        assert_eq!(
            out,
            [0x00, 0x80, 0x07, 0x00, 0x00, 0x00, 0x00, 0x00, 0x02, 0x06]
        );
        assert_eq!(
            error(SdoAbort::ObjectDoesNotExist).emit_coe(&mut out[..9]),
            0
        );
    }

    #[test]
    fn repr_round_trips() {
        let cases: [(&[u8], Repr); 4] = [
            (&[0x01, 0, 0, 0, 0x01, 0x00], Repr::OdList { list: 1 }),
            (
                &[0x03, 0, 0, 0, 0x00, 0x10],
                Repr::ObjectDescription { index: 0x1000 },
            ),
            (
                &[0x05, 0, 0, 0, 0x40, 0x60, 0x00, 0x70],
                Repr::EntryDescription {
                    key: ObjectKey::new(0x6040, 0),
                    value_info: 0x70,
                },
            ),
            (
                &[0x07, 0, 0, 0, 0x00, 0x00, 0x02, 0x06],
                Repr::Error { code: 0x0602_0000 },
            ),
        ];
        for (bytes, repr) in cases {
            let r = Repr::parse(&Frame::new(bytes)).unwrap();
            assert_eq!(r, repr);
            let mut out = [0xEEu8; 8];
            assert_eq!(r.emit(&mut Frame::new(&mut out[..])), bytes.len());
            assert_eq!(&out[..bytes.len()], bytes);
            assert_eq!(r.emit(&mut Frame::new(&mut out[..bytes.len() - 1])), 0);
        }
        assert_eq!(
            Repr::parse(&Frame::new(&[0x09u8, 0, 0, 0][..])),
            Ok(Repr::Unknown { opcode: 9 })
        );
        for short in [&[0x01u8, 0, 0][..], &[0x05, 0, 0, 0, 0x40, 0x60, 0x00][..]] {
            assert_eq!(Repr::parse(&Frame::new(short)), Err(WireError::Truncated));
        }
        assert_eq!(
            Frame::new_checked(&[0x01u8][..]).unwrap_err(),
            WireError::Truncated
        );
    }

    #[test]
    fn fragments_cover_the_payload_exactly() {
        static NAME: &str = "A rather long object name that needs several fragments";
        // The same kind of text packed: words of the vocabulary expand while the
        // fragments are written, also where a fragment ends inside one.
        static PACKED_TEXT: &str =
            "Touch probe 1 positive edge counts Mapping entry 12 of the Fault 3 snapshot";
        const WORDS: &[&str] = &[
            "Touch probe ",
            "positive edge",
            "counts ",
            "Mapping entry ",
            "Fault ",
            "snapshot",
        ];
        static VOCABULARY: [u8; od::words_len(WORDS)] = {
            let mut b = [0u8; od::words_len(WORDS)];
            od::words_into(WORDS, &mut b);
            b
        };
        static PACKED: [u8; od::packed_len(PACKED_TEXT, WORDS)] = {
            let mut b = [0u8; od::packed_len(PACKED_TEXT, WORDS)];
            od::pack_into(PACKED_TEXT, WORDS, &mut b, 0);
            b
        };
        assert!(PACKED.len() < PACKED_TEXT.len() / 2);
        let mut head = [0u8; HEAD_MAX];
        head[..6].copy_from_slice(&[1, 2, 3, 4, 5, 6]);
        for (name, text) in [
            (Name::plain(NAME), NAME),
            (Name::packed(&PACKED, &VOCABULARY), PACKED_TEXT),
        ] {
            for cap in 10..80 {
                let body = Body::Bytes {
                    head,
                    head_len: 6,
                    name,
                    tail: [b" [", b"mm", b"]"],
                };
                let mut job = InfoJob::new(opcode::OBJECT_DESCRIPTION_RESPONSE, body, cap);
                let total = 6 + text.len() + 5;
                assert_eq!(job.payload_len(), total);
                let mut all = [0u8; 128];
                let mut n = 0;
                let mut out = [0u8; 80];
                for k in 0..job.fragments() {
                    let (len, last) = job.next_fragment(&mut out[..cap]);
                    assert!(len <= cap && len > PREFIX_LEN);
                    assert_eq!(last, k + 1 == job.fragments());
                    assert_eq!(
                        u16::from_le_bytes([out[4], out[5]]),
                        job.fragments() - 1 - k
                    );
                    all[n..n + len - PREFIX_LEN].copy_from_slice(&out[PREFIX_LEN..len]);
                    n += len - PREFIX_LEN;
                }
                assert_eq!(job.next_fragment(&mut out[..cap]), (0, true));
                assert_eq!(n, total);
                assert_eq!(&all[..6], &[1, 2, 3, 4, 5, 6]);
                assert_eq!(&all[6..6 + text.len()], text.as_bytes());
                assert_eq!(&all[6 + text.len()..n], b" [mm]");
            }
        }
    }
}
