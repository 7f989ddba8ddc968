//! A dictionary packed for flash at compile time ([`packed_dictionary!`]).
//!
//! The object tables of an application are written where their values live (one
//! table per module, plain names, one entry table per object). For the image, one
//! constant evaluation merges them into the table the SDO server, SDO information and
//! the PDO rules read:
//!
//! * objects sorted by index (two tables describing one index are a compile-time
//!   error);
//! * every name packed ([`super::Name`], about 45 % of the text) and stored once, however
//!   many objects or entries carry it;
//! * an entry table identical to an earlier object's stored once (the four RxPDO and
//!   four TxPDO mapping objects share one).
//!
//! Only the packed statics are referenced at run time; the source tables, their plain
//! names and the helper arrays below exist during compilation only. The packed table
//! describes exactly what the source tables describe (tested for the product
//! dictionary entry by entry).
//!
//! [`packed_dictionary!`]: crate::packed_dictionary

use super::{packed_len, Entry, Object};

/// Builds the packed dictionary of a list of object tables and evaluates to a
/// `&'static [Object]` sorted by index:
///
/// ```ignore
/// pub static OBJECTS: &[Object] = ecat_slave_stack::packed_dictionary!(&[comm::OBJECTS, app::OBJECTS]);
/// ```
#[macro_export]
macro_rules! packed_dictionary {
    ($parts:expr) => {{
        use $crate::od::{pack as p, Entry, Object};
        const OD_PACK_PARTS: &[&[Object]] = $parts;
        const O: usize = p::object_count(OD_PACK_PARTS);
        const NE: usize = p::entry_count::<O>(OD_PACK_PARTS);
        const S: usize = O + NE;
        const LIST: [&str; S] = p::name_list::<O, NE, S>(OD_PACK_PARTS);
        const NAME_AT: [u16; S] = p::name_offsets(&LIST);
        const B: usize = p::name_bytes(&LIST, &NAME_AT);
        const SRC: [Entry; NE] = p::entry_list::<O, NE>(OD_PACK_PARTS);
        const RUN_AT: [u16; O] = p::run_offsets(OD_PACK_PARTS, &SRC);
        const E: usize = p::run_total(OD_PACK_PARTS, &RUN_AT);
        static NAMES: [u8; B] = p::names(&LIST, &NAME_AT);
        static ENTRIES: [Entry; E] =
            p::entries(&SRC, OD_PACK_PARTS, &RUN_AT, &LIST, &NAME_AT, &NAMES);
        static OBJECTS: [Object; O] =
            p::objects(OD_PACK_PARTS, &RUN_AT, &ENTRIES, &LIST, &NAME_AT, &NAMES);
        &OBJECTS
    }};
}

/// Number of objects of all parts.
pub const fn object_count(parts: &[&[Object]]) -> usize {
    let mut n = 0;
    let mut p = 0;
    while p < parts.len() {
        n += parts[p].len();
        p += 1;
    }
    n
}

/// Number of entries of all parts (before identical tables are merged).
pub const fn entry_count<const O: usize>(parts: &[&[Object]]) -> usize {
    let objs = flat::<O>(parts);
    let mut n = 0;
    let mut i = 0;
    while i < O {
        n += objs[i].entries().len();
        i += 1;
    }
    n
}

const fn plain(o: super::Name) -> &'static str {
    match o.as_plain() {
        Some(s) => s,
        None => panic!("od::pack: the source tables have plain names"),
    }
}

/// Every name: first the objects' (in the order of the parts), then the entries'.
pub const fn name_list<const O: usize, const NE: usize, const S: usize>(
    parts: &[&[Object]],
) -> [&'static str; S] {
    assert!(O + NE == S, "od::pack: name count");
    let objs = flat::<O>(parts);
    let entries = entry_list::<O, NE>(parts);
    let mut out = [""; S];
    let mut k = 0;
    while k < O {
        out[k] = plain(objs[k].name());
        k += 1;
    }
    while k < S {
        out[k] = plain(entries[k - O].name());
        k += 1;
    }
    out
}

/// FNV-1a hash of a name: the search for equal texts compares these first.
const fn name_hash(s: &str) -> u32 {
    let b = s.as_bytes();
    let mut h = 0x811C_9DC5u32;
    let mut i = 0;
    while i < b.len() {
        h = (h ^ b[i] as u32).wrapping_mul(0x0100_0193);
        i += 1;
    }
    h
}

/// The first slot of `list` holding the same text as slot `k` (`hashes`: the
/// [`name_hash`] of each slot; texts are compared only where the hashes agree, which
/// keeps the quadratic search within the constant evaluation's budget).
const fn first_with_name<const S: usize>(list: &[&str; S], hashes: &[u32; S], k: usize) -> usize {
    let h = hashes[k];
    let mut j = 0;
    while j < k {
        if hashes[j] == h && super::str_eq(list[j], list[k]) {
            return j;
        }
        j += 1;
    }
    k
}

/// Offset of each name's packed bytes in the name area (equal texts share one).
pub const fn name_offsets<const S: usize>(list: &[&'static str; S]) -> [u16; S] {
    let mut hashes = [0u32; S];
    let mut k = 0;
    while k < S {
        hashes[k] = name_hash(list[k]);
        k += 1;
    }
    let mut out = [0u16; S];
    let mut at = 0usize;
    let mut k = 0;
    while k < S {
        let first = first_with_name(list, &hashes, k);
        if first == k {
            assert!(at <= u16::MAX as usize, "od::pack: names over 64 KiB");
            out[k] = at as u16;
            at += packed_len(list[k]);
        } else {
            out[k] = out[first];
        }
        k += 1;
    }
    out
}

/// Size of the name area.
pub const fn name_bytes<const S: usize>(list: &[&'static str; S], at: &[u16; S]) -> usize {
    let mut end = 0;
    let mut k = 0;
    while k < S {
        let e = at[k] as usize + packed_len(list[k]);
        if e > end {
            end = e;
        }
        k += 1;
    }
    end
}

/// The name area: each distinct name packed once. [`name_offsets`] places each
/// first occurrence at the end of the area so far and a repeat before it, so the
/// first occurrences are the slots whose offset reaches that end (no second search
/// for equal texts: the constant evaluation stays linear here).
pub const fn names<const S: usize, const B: usize>(
    list: &[&'static str; S],
    at: &[u16; S],
) -> [u8; B] {
    let mut out = [0u8; B];
    let mut end = 0usize;
    let mut k = 0;
    while k < S {
        let a = at[k] as usize;
        if a >= end {
            super::pack_into(list[k], &mut out, a);
            end = a + packed_len(list[k]);
        }
        k += 1;
    }
    out
}

/// Every entry of the parts, object after object.
pub const fn entry_list<const O: usize, const NE: usize>(parts: &[&[Object]]) -> [Entry; NE] {
    let objs = flat::<O>(parts);
    let mut out = [super::PLACEHOLDER_ENTRY; NE];
    let mut k = 0;
    let mut i = 0;
    while i < O {
        let entries = objs[i].entries();
        let mut j = 0;
        while j < entries.len() {
            out[k] = entries[j];
            k += 1;
            j += 1;
        }
        i += 1;
    }
    out
}

/// Every object of the parts, in their order.
const fn flat<const O: usize>(parts: &[&[Object]]) -> [Object; O] {
    let mut out = [super::PLACEHOLDER_OBJECT; O];
    let mut k = 0;
    let mut p = 0;
    while p < parts.len() {
        let mut i = 0;
        while i < parts[p].len() {
            out[k] = parts[p][i];
            k += 1;
            i += 1;
        }
        p += 1;
    }
    out
}

/// Per object of [`flat`]: the index of its first entry in [`entry_list`] and its
/// number of entries.
const fn spans<const O: usize>(objs: &[Object; O]) -> [(usize, usize); O] {
    let mut out = [(0, 0); O];
    let mut first = 0;
    let mut n = 0;
    while n < O {
        let len = objs[n].entries().len();
        out[n] = (first, len);
        first += len;
        n += 1;
    }
    out
}

/// Where each object's entries start in the packed entry table: an entry table equal
/// to an earlier object's is that one.
pub const fn run_offsets<const O: usize, const NE: usize>(
    parts: &[&[Object]],
    src: &[Entry; NE],
) -> [u16; O] {
    let sp = spans(&flat::<O>(parts));
    let mut out = [0u16; O];
    let mut next = 0usize;
    let mut n = 0;
    while n < O {
        let (first, len) = sp[n];
        let mut found = None;
        let mut m = 0;
        while m < n && found.is_none() {
            let (ofirst, olen) = sp[m];
            if olen == len {
                let mut j = 0;
                while j < len && super::same_entry(&src[first + j], &src[ofirst + j]) {
                    j += 1;
                }
                if j == len {
                    found = Some(out[m]);
                }
            }
            m += 1;
        }
        out[n] = match found {
            Some(at) => at,
            None => {
                assert!(next <= u16::MAX as usize, "od::pack: entries over u16");
                let at = next as u16;
                next += len;
                at
            }
        };
        n += 1;
    }
    out
}

/// Size of the packed entry table.
pub const fn run_total<const O: usize>(parts: &[&[Object]], at: &[u16; O]) -> usize {
    let sp = spans(&flat::<O>(parts));
    let mut end = 0;
    let mut n = 0;
    while n < O {
        let e = at[n] as usize + sp[n].1;
        if e > end {
            end = e;
        }
        n += 1;
    }
    end
}

/// `len` bytes of the name area at `at`.
const fn name_slice(names: &'static [u8], at: u16, len: usize) -> &'static [u8] {
    names.split_at(at as usize).1.split_at(len).0
}

/// The packed entry table: each distinct entry table once, names packed.
pub const fn entries<
    const NE: usize,
    const O: usize,
    const S: usize,
    const B: usize,
    const E: usize,
>(
    src: &[Entry; NE],
    parts: &[&[Object]],
    run_at: &[u16; O],
    list: &[&'static str; S],
    name_at: &[u16; S],
    names: &'static [u8; B],
) -> [Entry; E] {
    let sp = spans(&flat::<O>(parts));
    let mut out = [super::PLACEHOLDER_ENTRY; E];
    let mut n = 0;
    while n < O {
        let (first, len) = sp[n];
        let mut j = 0;
        while j < len {
            let slot = O + first + j;
            let packed = name_slice(names, name_at[slot], packed_len(list[slot]));
            out[run_at[n] as usize + j] = src[first + j].with_packed_name(packed);
            j += 1;
        }
        n += 1;
    }
    out
}

/// The packed objects, sorted by index.
pub const fn objects<const O: usize, const E: usize, const S: usize, const B: usize>(
    parts: &[&[Object]],
    run_at: &[u16; O],
    entries: &'static [Entry; E],
    list: &[&'static str; S],
    name_at: &[u16; S],
    names: &'static [u8; B],
) -> [Object; O] {
    let mut out = flat::<O>(parts);
    let mut n = 0;
    while n < O {
        let obj = out[n];
        let len = obj.entries().len();
        let own = entries.split_at(run_at[n] as usize).1.split_at(len).0;
        let packed = name_slice(names, name_at[n], packed_len(list[n]));
        out[n] = obj.with_entries(own).with_packed_name(packed);
        n += 1;
    }
    // Insertion sort by index.
    let mut i = 1;
    while i < O {
        let mut j = i;
        while j > 0 && out[j - 1].index > out[j].index {
            let t = out[j - 1];
            out[j - 1] = out[j];
            out[j] = t;
            j -= 1;
        }
        i += 1;
    }
    let mut i = 1;
    while i < O {
        assert!(
            out[i - 1].index < out[i].index,
            "od::pack: two tables describe the same index"
        );
        i += 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use crate::od::{self, Access, DataType, Entry, Object};

    const TWIN: &[Entry] = &[
        Entry::count(2),
        Entry::new(1, "Fault code 1", DataType::Unsigned16, Access::RO),
        Entry::new(2, "Fault code 2", DataType::Unsigned16, Access::RO).default(7),
    ];
    const LOCAL: &[Object] = &[
        Object::record(0x3001, "Fault history copy", TWIN, ""),
        Object::var(
            0x3000,
            "Position actual value",
            &[Entry::new(
                0,
                "Position actual value",
                DataType::Integer32,
                Access::RO,
            )],
            "",
        ),
        Object::record(0x3002, "Fault history copy", TWIN, ""),
        Object::var(
            0x3003,
            "Device name",
            &[Entry::text(0, "Device name", 16, "ECS drive")],
            "",
        ),
    ];
    const PARTS: &[&[Object]] = &[crate::pdo::OBJECTS, LOCAL, crate::sync::DIAG_OBJECTS];
    static PACKED: &[Object] = crate::packed_dictionary!(PARTS);

    #[test]
    fn packed_table_describes_the_sources() {
        assert!(od::is_well_formed(PACKED));
        let n: usize = PARTS.iter().map(|p| p.len()).sum();
        assert_eq!(PACKED.len(), n);
        for part in PARTS {
            for src in part.iter() {
                let p = od::find(PACKED, src.index).expect("packed object");
                assert_eq!(p, src, "{:#06x}", src.index);
                assert!(p.name().as_plain().is_none());
                assert_eq!(p.name(), src.name().as_plain().unwrap());
                for (pe, se) in p.entries().iter().zip(src.entries()) {
                    assert_eq!(pe, se, "{:#06x}:{}", src.index, se.sub);
                    assert_eq!(pe.name(), se.name().as_plain().unwrap());
                    assert_eq!(pe.default_value(), se.default_value());
                    assert_eq!((pe.min(), pe.max()), (se.min(), se.max()));
                }
            }
        }
    }

    #[test]
    fn equal_tables_and_names_are_stored_once() {
        let a = od::find(PACKED, 0x3001).unwrap();
        let b = od::find(PACKED, 0x3002).unwrap();
        assert_eq!(a.entries().as_ptr(), b.entries().as_ptr());
        // A VAR's entry carries its object's name (packed once, read by both).
        let v = od::find(PACKED, 0x3000).unwrap();
        assert_eq!(v.name().bytes().count(), v.entries()[0].name().len());
        assert_eq!(v.name(), v.entries()[0].name());
        // Tables that differ stay apart.
        let t = od::find(PACKED, 0x3003).unwrap();
        assert_ne!(t.entries().as_ptr(), v.entries().as_ptr());
        assert_eq!(
            t.entries()[0].default_value(),
            od::DefaultValue::Text("ECS drive")
        );
    }
}
