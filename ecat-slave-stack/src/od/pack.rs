//! A dictionary packed for flash at compile time ([`packed_dictionary!`]).
//!
//! The object tables of an application are written where their values live (one
//! table of [`ObjectDesc`]s per module, plain names, one entry table per object). For
//! the image, one constant evaluation merges them into the table the SDO server, SDO
//! information and the PDO rules read:
//!
//! * objects sorted by index (two tables describing one index are a compile-time
//!   error);
//! * every name packed with the application's vocabulary ([`super::Name`], about 45 %
//!   of the text for this project's drive) and stored once, however many objects or
//!   entries carry it; the text defaults after the names, each distinct one once; all
//!   of it in one [`Strings`] that entries and objects read at 16-bit offsets;
//! * an entry table identical to an earlier object's stored once (the four RxPDO and
//!   four TxPDO mapping objects share one).
//!
//! Only the packed statics are referenced at run time; the source tables, their plain
//! names and the helper arrays below exist during compilation only. The packed table
//! describes exactly what the source tables describe (tested for the product
//! dictionary entry by entry). The same steps run on the host with `leak` (feature
//! `alloc`) for documentation generators that describe variants of a dictionary.
//!
//! [`packed_dictionary!`]: crate::packed_dictionary

use super::desc::{PLACEHOLDER_ENTRY, PLACEHOLDER_PACKED_ENTRY, PLACEHOLDER_PACKED_OBJECT};
use super::{packed_len, str_eq, Entry, EntryDesc, Object, ObjectDesc, Strings, Tables};

/// Builds the packed dictionary of a list of object tables and evaluates to a
/// `&'static [Object]` sorted by index. The second argument is the vocabulary the
/// names are packed with (words that repeat in the application's names, at most 128;
/// [`super::COE_WORDS`] when left out):
///
/// ```ignore
/// pub static OBJECTS: &[Object] =
///     ecat_slave_stack::packed_dictionary!(&[comm::OBJECTS, app::OBJECTS], VOCABULARY);
/// ```
#[macro_export]
macro_rules! packed_dictionary {
    ($parts:expr) => {
        $crate::packed_dictionary!($parts, $crate::od::COE_WORDS)
    };
    ($parts:expr, $words:expr) => {{
        use $crate::od::{pack as p, Entry, EntryDesc, Object, ObjectDesc, Strings, Tables};
        const OD_PACK_PARTS: &[&[ObjectDesc]] = $parts;
        const OD_PACK_WORDS: &[&str] = $words;
        const OD_PACK_O: usize = p::object_count(OD_PACK_PARTS);
        const OD_PACK_NE: usize = p::entry_count(OD_PACK_PARTS);
        const OD_PACK_LIST: [&str; OD_PACK_O + OD_PACK_NE] = {
            let mut a = [""; OD_PACK_O + OD_PACK_NE];
            p::name_list(OD_PACK_PARTS, &mut a);
            a
        };
        const OD_PACK_NAME_AT: [u16; OD_PACK_O + OD_PACK_NE] = {
            let mut a = [0; OD_PACK_O + OD_PACK_NE];
            p::name_offsets(&OD_PACK_LIST, OD_PACK_WORDS, &mut a);
            a
        };
        const OD_PACK_SRC: [EntryDesc; OD_PACK_NE] = {
            let mut a = [p::PLACEHOLDER; OD_PACK_NE];
            p::entry_list(OD_PACK_PARTS, &mut a);
            a
        };
        const OD_PACK_TEXT_AT: [u16; OD_PACK_NE] = {
            let mut a = [0; OD_PACK_NE];
            p::text_offsets(&OD_PACK_SRC, &mut a);
            a
        };
        const OD_PACK_RUN_AT: [u16; OD_PACK_O] = {
            let mut a = [0; OD_PACK_O];
            p::run_offsets(OD_PACK_PARTS, &OD_PACK_SRC, &mut a);
            a
        };
        const OD_PACK_L: p::Layout<'static> = p::Layout {
            parts: OD_PACK_PARTS,
            words: OD_PACK_WORDS,
            names: &OD_PACK_LIST,
            name_at: &OD_PACK_NAME_AT,
            entries: &OD_PACK_SRC,
            text_at: &OD_PACK_TEXT_AT,
            run_at: &OD_PACK_RUN_AT,
        };
        static OD_PACK_NAMES: [u8; OD_PACK_L.name_bytes()] = {
            let mut a = [0; OD_PACK_L.name_bytes()];
            OD_PACK_L.write_names(&mut a);
            a
        };
        const OD_PACK_TEXTS: [u8; OD_PACK_L.text_bytes()] = {
            let mut a = [0; OD_PACK_L.text_bytes()];
            OD_PACK_L.write_texts(&mut a);
            a
        };
        static OD_PACK_VOCABULARY: [u8; $crate::od::words_len(OD_PACK_WORDS)] = {
            let mut a = [0; $crate::od::words_len(OD_PACK_WORDS)];
            $crate::od::words_into(OD_PACK_WORDS, &mut a);
            a
        };
        static OD_PACK_STRINGS: Strings =
            Strings::new(&OD_PACK_NAMES, &OD_PACK_VOCABULARY, p::utf8(&OD_PACK_TEXTS));
        static OD_PACK_ENTRIES: [Entry; OD_PACK_L.entry_total()] = {
            let mut a = [p::PLACEHOLDER_PACKED; OD_PACK_L.entry_total()];
            OD_PACK_L.write_entries(&OD_PACK_STRINGS, &mut a);
            a
        };
        static OD_PACK_TABLES: Tables = Tables::new(&OD_PACK_STRINGS, &OD_PACK_ENTRIES);
        static OD_PACK_OBJECTS: [Object; OD_PACK_O] = {
            let mut a = [p::PLACEHOLDER_OBJECT; OD_PACK_O];
            OD_PACK_L.write_objects(&OD_PACK_TABLES, &mut a);
            a
        };
        &OD_PACK_OBJECTS
    }};
}

/// A description to fill arrays with before they are written.
pub const PLACEHOLDER: EntryDesc = PLACEHOLDER_ENTRY;
/// A packed entry to fill arrays with before they are written.
pub const PLACEHOLDER_PACKED: Entry = PLACEHOLDER_PACKED_ENTRY;
/// A packed object to fill arrays with before they are written.
pub const PLACEHOLDER_OBJECT: Object = PLACEHOLDER_PACKED_OBJECT;

/// Number of objects of all parts.
pub const fn object_count(parts: &[&[ObjectDesc]]) -> usize {
    let mut n = 0;
    let mut p = 0;
    while p < parts.len() {
        n += parts[p].len();
        p += 1;
    }
    n
}

/// Object `n` of the parts, counted across them in their order.
const fn object_at<'a>(parts: &[&'a [ObjectDesc]], mut n: usize) -> &'a ObjectDesc {
    let mut p = 0;
    while n >= parts[p].len() {
        n -= parts[p].len();
        p += 1;
    }
    &parts[p][n]
}

/// Number of entries of all parts (before identical tables are merged).
pub const fn entry_count(parts: &[&[ObjectDesc]]) -> usize {
    let mut n = 0;
    let mut i = 0;
    while i < object_count(parts) {
        n += object_at(parts, i).entries().len();
        i += 1;
    }
    n
}

/// Every entry of the parts, object after object, into `out` ([`entry_count`]).
pub const fn entry_list(parts: &[&[ObjectDesc]], out: &mut [EntryDesc]) {
    let mut k = 0;
    let mut i = 0;
    while i < object_count(parts) {
        let entries = object_at(parts, i).entries();
        let mut j = 0;
        while j < entries.len() {
            out[k] = entries[j];
            k += 1;
            j += 1;
        }
        i += 1;
    }
}

/// Every name into `out`: first the objects' (in the order of the parts), then the
/// entries' (as [`entry_list`]).
pub const fn name_list(parts: &[&[ObjectDesc]], out: &mut [&'static str]) {
    let o = object_count(parts);
    let mut k = 0;
    let mut i = 0;
    while i < o {
        let obj = object_at(parts, i);
        out[i] = obj.name();
        let entries = obj.entries();
        let mut j = 0;
        while j < entries.len() {
            out[o + k] = entries[j].name();
            k += 1;
            j += 1;
        }
        i += 1;
    }
}

/// The first slot of `list` holding the same text as slot `k`.
const fn first_with_name(list: &[&str], k: usize) -> usize {
    let mut j = 0;
    while j < k {
        if str_eq(list[j], list[k]) {
            return j;
        }
        j += 1;
    }
    k
}

/// Offset of each name's packed bytes in the text area into `out` (equal texts share
/// one).
pub const fn name_offsets(list: &[&str], words: &[&str], out: &mut [u16]) {
    let mut at = 0usize;
    let mut k = 0;
    while k < list.len() {
        let first = first_with_name(list, k);
        if first == k {
            assert!(at <= u16::MAX as usize, "od::pack: names over 64 KiB");
            out[k] = at as u16;
            at += packed_len(list[k], words);
        } else {
            out[k] = out[first];
        }
        k += 1;
    }
}

/// Size of the names' part of the text area.
pub const fn name_bytes(list: &[&str], at: &[u16], words: &[&str]) -> usize {
    let mut end = 0;
    let mut k = 0;
    while k < list.len() {
        let e = at[k] as usize + packed_len(list[k], words);
        if e > end {
            end = e;
        }
        k += 1;
    }
    end
}

/// Offset of each entry's default text in the text area into `out`; equal texts share
/// one, a numeric entry gets 0.
pub const fn text_offsets(src: &[EntryDesc], out: &mut [u16]) {
    let mut at = 0;
    let mut k = 0;
    while k < src.len() {
        let t = src[k].text_value();
        let mut j = 0;
        while j < k && !str_eq(src[j].text_value(), t) {
            j += 1;
        }
        if t.is_empty() {
            out[k] = 0;
        } else if j < k {
            out[k] = out[j];
        } else {
            assert!(at <= u16::MAX as usize, "od::pack: texts over 64 KiB");
            out[k] = at as u16;
            at += t.len();
        }
        k += 1;
    }
}

/// Where each object's entries start in the packed entry table, into `out`: an entry
/// table equal to an earlier object's is that one.
pub const fn run_offsets(parts: &[&[ObjectDesc]], src: &[EntryDesc], out: &mut [u16]) {
    let mut next = 0usize;
    let mut first = 0;
    let mut n = 0;
    while n < object_count(parts) {
        let len = object_at(parts, n).entries().len();
        let mut found = None;
        let mut ofirst = 0;
        let mut m = 0;
        while m < n && found.is_none() {
            let olen = object_at(parts, m).entries().len();
            if olen == len {
                let mut j = 0;
                while j < len && src[first + j].same(&src[ofirst + j]) {
                    j += 1;
                }
                if j == len {
                    found = Some(out[m]);
                }
            }
            ofirst += olen;
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
        first += len;
        n += 1;
    }
}

/// Everything the packed statics are made of: the source tables and the offsets
/// computed from them (arrays of the sizes [`object_count`] and [`entry_count`]).
pub struct Layout<'a> {
    /// The source tables.
    pub parts: &'a [&'a [ObjectDesc]],
    /// The vocabulary.
    pub words: &'a [&'a str],
    /// [`name_list`].
    pub names: &'a [&'static str],
    /// [`name_offsets`].
    pub name_at: &'a [u16],
    /// [`entry_list`].
    pub entries: &'a [EntryDesc],
    /// [`text_offsets`].
    pub text_at: &'a [u16],
    /// [`run_offsets`].
    pub run_at: &'a [u16],
}

impl Layout<'_> {
    /// Size of the name area.
    pub const fn name_bytes(&self) -> usize {
        name_bytes(self.names, self.name_at, self.words)
    }
    /// The name area ([`Layout::name_bytes`]): each distinct name packed once.
    pub const fn write_names(&self, out: &mut [u8]) {
        let mut k = 0;
        while k < self.names.len() {
            if first_with_name(self.names, k) == k {
                super::pack_into(self.names[k], self.words, out, self.name_at[k] as usize);
            }
            k += 1;
        }
    }
    /// Size of the area of the default texts.
    pub const fn text_bytes(&self) -> usize {
        let mut end = 0;
        let mut k = 0;
        while k < self.entries.len() {
            let e = self.text_at[k] as usize + self.entries[k].text_value().len();
            if e > end {
                end = e;
            }
            k += 1;
        }
        end
    }
    /// The default texts ([`Layout::text_bytes`]), each distinct one once: whole
    /// `&str`s one after the other, so the area is UTF-8.
    pub const fn write_texts(&self, out: &mut [u8]) {
        let mut k = 0;
        while k < self.entries.len() {
            let t = self.entries[k].text_value().as_bytes();
            let at = self.text_at[k] as usize;
            let mut j = 0;
            while j < t.len() {
                out[at + j] = t[j];
                j += 1;
            }
            k += 1;
        }
    }
    /// Size of the packed entry table.
    pub const fn entry_total(&self) -> usize {
        let mut end = 0;
        let mut n = 0;
        while n < self.run_at.len() {
            let e = self.run_at[n] as usize + object_at(self.parts, n).entries().len();
            if e > end {
                end = e;
            }
            n += 1;
        }
        end
    }
    /// The packed entry table ([`Layout::entry_total`]): each distinct entry table
    /// once, reading their texts in `strings`.
    pub const fn write_entries(&self, strings: &'static Strings, out: &mut [Entry]) {
        let o = self.run_at.len();
        let mut first = 0;
        let mut n = 0;
        while n < o {
            let len = object_at(self.parts, n).entries().len();
            let mut j = 0;
            while j < len {
                let k = first + j;
                let name = self.names[o + k];
                out[self.run_at[n] as usize + j] = self.entries[k].packed(
                    strings,
                    self.name_at[o + k],
                    packed_len(name, self.words),
                    self.text_at[k],
                );
                j += 1;
            }
            first += len;
            n += 1;
        }
    }
    /// The packed objects ([`object_count`]), sorted by index, reading their names and
    /// entries in `tables`.
    pub const fn write_objects(&self, tables: &'static Tables, out: &mut [Object]) {
        let mut n = 0;
        while n < out.len() {
            let name = self.names[n];
            out[n] = object_at(self.parts, n).packed(
                tables,
                self.name_at[n],
                packed_len(name, self.words),
                self.run_at[n],
            );
            n += 1;
        }
        // Insertion sort by index.
        let mut i = 1;
        while i < out.len() {
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
        while i < out.len() {
            assert!(
                out[i - 1].index < out[i].index,
                "od::pack: two tables describe the same index"
            );
            i += 1;
        }
    }
}

/// The text area written by [`Layout::write_texts`] as text (checked when the
/// dictionary is built).
pub const fn utf8(bytes: &'static [u8]) -> &'static str {
    match core::str::from_utf8(bytes) {
        Ok(s) => s,
        Err(_) => panic!("od::pack: default texts are not UTF-8"),
    }
}

/// [`crate::packed_dictionary!`] at run time: the packed dictionary of `parts` with
/// the vocabulary `words`, in memory that is never freed (documentation generators on
/// the host, which describe variants of a dictionary made at run time).
#[cfg(any(test, feature = "alloc"))]
pub fn leak(parts: &[&[ObjectDesc]], words: &[&str]) -> &'static [Object] {
    use alloc::{boxed::Box, vec};
    let (o, ne) = (object_count(parts), entry_count(parts));
    let mut names = vec![""; o + ne];
    name_list(parts, &mut names);
    let mut name_at = vec![0; o + ne];
    name_offsets(&names, words, &mut name_at);
    let mut entries = vec![PLACEHOLDER; ne];
    entry_list(parts, &mut entries);
    let mut text_at = vec![0; ne];
    text_offsets(&entries, &mut text_at);
    let mut run_at = vec![0; o];
    run_offsets(parts, &entries, &mut run_at);
    let l = Layout {
        parts,
        words,
        names: &names,
        name_at: &name_at,
        entries: &entries,
        text_at: &text_at,
        run_at: &run_at,
    };
    let mut name_area = vec![0; l.name_bytes()];
    l.write_names(&mut name_area);
    let mut texts = vec![0; l.text_bytes()];
    l.write_texts(&mut texts);
    let mut vocabulary = vec![0; super::words_len(words)];
    super::words_into(words, &mut vocabulary);
    let strings: &'static Strings = Box::leak(Box::new(Strings::new(
        name_area.leak(),
        vocabulary.leak(),
        utf8(texts.leak()),
    )));
    let mut packed = vec![PLACEHOLDER_PACKED; l.entry_total()];
    l.write_entries(strings, &mut packed);
    let tables: &'static Tables = Box::leak(Box::new(Tables::new(strings, packed.leak())));
    let mut objects = vec![PLACEHOLDER_OBJECT; o];
    l.write_objects(tables, &mut objects);
    objects.leak()
}

#[cfg(test)]
mod tests {
    use crate::od::{self, Access, DataType, DefaultValue, EntryDesc, Object, ObjectDesc};

    const TWIN: &[EntryDesc] = &[
        EntryDesc::count(2),
        EntryDesc::new(1, "Fault code 1", DataType::Unsigned16, Access::RO),
        EntryDesc::new(2, "Fault code 2", DataType::Unsigned16, Access::RO).default(7),
    ];
    const LOCAL: &[ObjectDesc] = &[
        ObjectDesc::record(0x3001, "Fault history copy", TWIN, ""),
        ObjectDesc::var(
            0x3000,
            "Position actual value",
            &[EntryDesc::new(
                0,
                "Position actual value",
                DataType::Integer32,
                Access::RO,
            )],
            "",
        ),
        ObjectDesc::record(0x3002, "Fault history copy", TWIN, ""),
        ObjectDesc::var(
            0x3003,
            "Device name",
            &[EntryDesc::text(0, "Device name", 16, "ECS drive")],
            "",
        ),
        ObjectDesc::var(
            0x3004,
            "Device name copy",
            &[EntryDesc::text(0, "Device name", 16, "ECS drive").saved()],
            "",
        ),
    ];
    const PARTS: &[&[ObjectDesc]] = &[
        crate::pdo::OBJECTS,
        LOCAL,
        &[crate::sync::timing_diag_object(0x2200)],
    ];
    const WORDS: &[&str] = &["Fault ", "Position ", "actual value", "Device "];
    static PACKED: &[Object] = crate::packed_dictionary!(PARTS, WORDS);

    fn describes_the_sources(packed: &'static [Object]) {
        assert!(od::is_well_formed(packed));
        let n: usize = PARTS.iter().map(|p| p.len()).sum();
        assert_eq!(packed.len(), n);
        for part in PARTS {
            for src in part.iter() {
                let p = od::find(packed, src.index).expect("packed object");
                assert_eq!(p, src, "{:#06x}", src.index);
                assert_eq!(p.name(), src.name());
                for (pe, se) in p.entries().iter().zip(src.entries()) {
                    assert_eq!(pe, se, "{:#06x}:{}", src.index, se.sub());
                    assert_eq!(pe.name(), se.name());
                    assert!(pe.name().stored_len() <= se.name().len());
                    assert_eq!(pe.default_value(), se.default_value());
                    assert_eq!((pe.min(), pe.max()), (se.min(), se.max()));
                    assert_eq!(pe.bits(), se.bits());
                }
            }
        }
    }

    #[test]
    fn packed_table_describes_the_sources() {
        describes_the_sources(PACKED);
        // Names with words of the vocabulary take fewer bytes than their text.
        let v = od::find(PACKED, 0x3000).unwrap();
        assert_eq!(v.name().stored_len(), 2);
        assert_eq!(v.name().len(), "Position actual value".len());
    }

    #[test]
    fn equal_tables_and_texts_are_stored_once() {
        let a = od::find(PACKED, 0x3001).unwrap();
        let b = od::find(PACKED, 0x3002).unwrap();
        assert_eq!(a.entries().as_ptr(), b.entries().as_ptr());
        // A VAR's entry carries its object's name (packed once, read by both).
        let v = od::find(PACKED, 0x3000).unwrap();
        assert_eq!(v.name().bytes().count(), v.entries()[0].name().len());
        assert_eq!(v.name(), v.entries()[0].name());
        // Tables that differ stay apart.
        let t = od::find(PACKED, 0x3003).unwrap();
        let u = od::find(PACKED, 0x3004).unwrap();
        assert_ne!(t.entries().as_ptr(), v.entries().as_ptr());
        assert_ne!(t.entries().as_ptr(), u.entries().as_ptr());
        let (DefaultValue::Text(x), DefaultValue::Text(y)) = (
            t.entries()[0].default_value(),
            u.entries()[0].default_value(),
        ) else {
            panic!("text defaults");
        };
        assert_eq!(x, "ECS drive");
        assert_eq!(x.as_ptr(), y.as_ptr());
    }

    #[test]
    fn run_time_packing_gives_the_same_table() {
        let leaked = super::leak(PARTS, WORDS);
        describes_the_sources(leaked);
        assert_eq!(leaked, PACKED);
        // Another vocabulary: the same texts, other bytes.
        let plain = super::leak(PARTS, &[]);
        assert_eq!(plain, PACKED);
        let v = od::find(plain, 0x3000).unwrap();
        assert_eq!(v.name().stored_len(), "Position actual value".len());
    }

    #[test]
    #[should_panic(expected = "two tables describe the same index")]
    fn two_tables_of_one_index_are_refused() {
        let _ = super::leak(&[LOCAL, LOCAL], WORDS);
    }
}
