//! The object dictionary framework.
//!
//! One description per object and per entry — index, sub-index, name, data type, bit
//! length, access per ESM state, PDO mappability, range, default, unit, saved-or-not.
//! The modules that own the values write it as constant tables of [`ObjectDesc`] and
//! [`EntryDesc`]; [`crate::packed_dictionary!`] merges them at compile time into the
//! table of [`Object`]s and [`Entry`]s kept in flash, whose names and texts are in one
//! packed blob ([`Strings`]). That single description feeds the SDO server (access,
//! length and range checks), the PDO mapping rules, SDO information, the SII image,
//! the ESI XML and the generated dictionary reference. The *values* are owned by the
//! application, which implements [`Dictionary`].
//!
//! The generic checks done by the stack before a write reaches the application are
//! in [`check_write`]; lookups are binary searches over the sorted object table.

use crate::esm::EsmState;

mod abort;
mod desc;
mod key;
mod name;
pub mod pack;
mod reference;
mod types;
mod values;

pub use abort::SdoAbort;
pub use desc::{EntryDesc, ObjectDesc};
pub use key::ObjectKey;
pub use reference::write_reference;
pub use types::*;
pub use values::Values;

pub use name::{pack_into, packed_len, words_into, words_len, Name, NameBytes, COE_WORDS};

/// The texts of a packed dictionary: the names packed ([`pack_into`]), each distinct
/// one once, the vocabulary they were packed with ([`words_into`]), and the text
/// defaults, each distinct one once. Every [`Entry`] and, through [`Tables`], every
/// [`Object`] of the dictionary reads its name and text default here at an offset it
/// keeps.
pub struct Strings {
    names: &'static [u8],
    words: &'static [u8],
    texts: &'static str,
}

impl Strings {
    /// The packed names `names` of a dictionary, packed with the vocabulary `words`,
    /// and its text defaults `texts` (made by [`crate::packed_dictionary!`] or
    /// `pack::leak`).
    pub const fn new(names: &'static [u8], words: &'static [u8], texts: &'static str) -> Self {
        Strings {
            names,
            words,
            texts,
        }
    }
    /// No texts: what an [`EntryDesc`] holds until it is packed.
    const NONE: Strings = Strings::new(&[], &[], "");
    /// The packed name of `len` bytes at `at` (empty when out of range: never for a
    /// packed dictionary).
    fn name(&self, at: u16, len: usize) -> Name {
        let at = at as usize;
        Name::packed(self.names.get(at..at + len).unwrap_or(&[]), self.words)
    }
    /// The text default located by `spec[1]` of an entry ([`text_at`]).
    fn text(&self, located: i32) -> &'static str {
        let (at, len) = (located as u32 & 0xFFFF, located as u32 >> 16);
        let texts: &'static str = self.texts;
        texts.get(at as usize..(at + len) as usize).unwrap_or("")
    }
}

/// The tables of a packed dictionary: its texts and its entry table, which each
/// [`Object`] reads at an offset it keeps.
pub struct Tables {
    strings: &'static Strings,
    entries: &'static [Entry],
}

impl Tables {
    /// The entry table `entries` of a dictionary whose texts are `strings`.
    pub const fn new(strings: &'static Strings, entries: &'static [Entry]) -> Self {
        Tables { strings, entries }
    }
    /// No tables: what the placeholder objects of the packer hold.
    const NONE: Tables = Tables::new(&Strings::NONE, &[]);
}

/// One entry (sub-index) of an object, as the packed dictionary keeps it.
///
/// Kept compact (24 bytes on the target: the dictionary has several hundred entries):
/// the name is an offset into the dictionary's [`Strings`] and a one-byte length (read
/// it with [`Entry::name`]), limits and the default are stored as 32-bit patterns read
/// back through the data type, a text default as its offset and length in the same
/// [`Strings`], the unit as an index into [`UNITS`], the flags in one byte. Use
/// [`Entry::bits`], [`Entry::min`], [`Entry::max`], [`Entry::default_value`],
/// [`Entry::unit_text`] and [`Entry::is_saved`] to read them. Tables are written as
/// [`EntryDesc`]s.
#[derive(Clone, Copy)]
pub struct Entry {
    /// The dictionary's texts: the name and a text default are read here.
    strings: &'static Strings,
    /// `[lo, hi, def]`: 32-bit patterns read through the data type. A string type
    /// has no range: `lo` is its maximum length in bytes. With a text default
    /// ([`FLAG_TEXT`]) `hi` locates the text in `strings` (see [`text_at`]).
    spec: [i32; 3],
    /// Offset of the packed name in `strings`.
    name_at: u16,
    /// Data type.
    pub data_type: DataType,
    /// Sub-index.
    pub sub: u8,
    /// Access per ESM state.
    pub access: Access,
    unit: u8,
    /// Length of the packed name in bytes.
    name_len: u8,
    /// [`FLAG_SAVED`], [`FLAG_TEXT`], [`FLAG_NATURAL`], [`FLAG_HAS_DEFAULT`] and the
    /// [`PdoMappable`] code at [`PDO_SHIFT`].
    flags: u8,
}

#[cfg(target_pointer_width = "32")]
const _: () = assert!(core::mem::size_of::<Entry>() == 24);

/// Stored in flash by 'save' (0x1010).
const FLAG_SAVED: u8 = 1 << 0;
/// The default is a text, located by `spec[1]` (otherwise `spec[2]` holds a numeric
/// default).
const FLAG_TEXT: u8 = 1 << 1;
/// The range is the data type's own and does not fit 32-bit patterns (64-bit types
/// without a range of their own); the natural range of the other types is stored in
/// `spec` like any other, so [`Entry::min`]/[`Entry::max`] need no table of types.
const FLAG_NATURAL: u8 = 1 << 2;
/// The numeric default in `spec` is meaningful.
const FLAG_HAS_DEFAULT: u8 = 1 << 3;
/// Position of the two [`PdoMappable`] bits in the flags.
const PDO_SHIFT: u32 = 4;
/// The two [`PdoMappable`] bits.
const FLAG_PDO: u8 = 3 << PDO_SHIFT;

/// Unit texts an entry can carry ([`EntryDesc::unit`]); index 0 is "no unit".
pub const UNITS: &[&str] = &[
    "",
    "inc",
    "inc/s",
    "inc/s²",
    "inc/rev",
    "lines/rev",
    "1/65536 turn",
    "ns",
    "us",
    "ms",
    "s",
    "h",
    "min",
    "50us",
    "mA",
    "A",
    "mV",
    "10mV",
    "0.1V",
    "V",
    "mOhm",
    "uH",
    "%",
    "0.1 %",
    "rpm",
    "Hz",
    "kHz",
    "°C",
    "mN·m",
    "0.1 %/s",
    "0.1°",
];

/// The texts of [`UNITS`] one after the other, and where each one ends: what
/// [`Entry::unit_text`] reads (one byte per unit instead of a pointer and a length).
static UNIT_TEXT: &str = pack::utf8(&unit_bytes::<{ units_len() }>());
static UNIT_END: [u8; UNITS.len()] = unit_ends();

/// Bytes of all [`UNITS`] (at most 255: one byte locates each end).
const fn units_len() -> usize {
    let mut n = 0;
    let mut k = 0;
    while k < UNITS.len() {
        n += UNITS[k].len();
        k += 1;
    }
    assert!(n <= u8::MAX as usize, "od::UNITS over 255 bytes");
    n
}

const fn unit_bytes<const N: usize>() -> [u8; N] {
    let mut out = [0; N];
    let mut at = 0;
    let mut k = 0;
    while k < UNITS.len() {
        let u = UNITS[k].as_bytes();
        let mut j = 0;
        while j < u.len() {
            out[at] = u[j];
            at += 1;
            j += 1;
        }
        k += 1;
    }
    out
}

const fn unit_ends() -> [u8; UNITS.len()] {
    let mut out = [0; UNITS.len()];
    let mut end = 0;
    let mut k = 0;
    while k < UNITS.len() {
        end += UNITS[k].len();
        out[k] = end as u8;
        k += 1;
    }
    out
}

const fn str_eq(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// Whether 32-bit patterns of `t` are read as unsigned (`u32`) rather than signed.
const fn unsigned_pattern(t: DataType) -> bool {
    !matches!(
        t,
        DataType::Integer8 | DataType::Integer16 | DataType::Integer32 | DataType::Integer64
    )
}

/// A value of `t` as a 32-bit pattern; a compile-time error for a table value that
/// does not fit (64-bit objects take their natural range and small defaults only).
const fn pattern(t: DataType, v: i64) -> i32 {
    if unsigned_pattern(t) {
        assert!(
            v >= 0 && v <= u32::MAX as i64,
            "unsigned entry value outside 0..=u32::MAX"
        );
        v as u32 as i32
    } else {
        assert!(
            v >= i32::MIN as i64 && v <= i32::MAX as i64,
            "signed entry value outside i32"
        );
        v as i32
    }
}

const fn unpattern(t: DataType, p: i32) -> i64 {
    if unsigned_pattern(t) {
        p as u32 as i64
    } else {
        p as i64
    }
}

/// [`FLAG_NATURAL`] for the types whose range does not fit 32-bit patterns, else 0.
const fn natural_flag(t: DataType) -> u8 {
    if type_range(t).0 == 64 {
        FLAG_NATURAL
    } else {
        0
    }
}

/// `[lo, hi, def]` of an entry of `t` with the natural range and no default (zeros for
/// the 64-bit types, see [`natural_flag`]).
const fn natural_patterns(t: DataType) -> [i32; 3] {
    let (bits, lo, hi) = type_range(t);
    if bits == 64 {
        [0; 3]
    } else {
        [pattern(t, lo), pattern(t, hi), 0]
    }
}

/// The pattern of `spec[1]` for a text default of `len` bytes at `at` in the
/// dictionary's [`Strings`].
const fn text_at(at: u16, len: u16) -> i32 {
    (at as u32 | (len as u32) << 16) as i32
}

impl Entry {
    /// Name (SDO information, ESI, documentation).
    pub fn name(&self) -> Name {
        self.strings.name(self.name_at, self.name_len as usize)
    }
    /// Length in bits (for strings: the maximum length).
    // Measured (cargo xtask size, LAN9252 image): without it, `Object::entries`'s and
    // `pdo::map_slot`'s, ≈ +620 B flash over the SDO and mapping paths.
    #[inline(never)]
    pub const fn bits(&self) -> u16 {
        if self.data_type.is_variable_length() {
            self.spec[0] as u16 * 8
        } else {
            type_bits(self.data_type)
        }
    }
    /// No range: a string, or an entry with a text default.
    const fn has_no_range(&self) -> bool {
        self.flags & FLAG_TEXT != 0 || self.data_type.is_variable_length()
    }
    /// Stored in flash by 'save' (0x1010).
    pub const fn is_saved(&self) -> bool {
        self.flags & FLAG_SAVED != 0
    }
    /// PDO mappability.
    pub const fn pdo_mappable(&self) -> PdoMappable {
        match (self.flags & FLAG_PDO) >> PDO_SHIFT {
            0 => PdoMappable::No,
            1 => PdoMappable::Rx,
            2 => PdoMappable::Tx,
            _ => PdoMappable::RxTx,
        }
    }
    /// The text default, if the entry is a string.
    fn text_default(&self) -> Option<&'static str> {
        if self.flags & FLAG_TEXT == 0 {
            return None;
        }
        Some(self.strings.text(self.spec[1]))
    }
    /// Smallest accepted value on write (numeric types).
    pub const fn min(&self) -> i64 {
        if self.has_no_range() {
            0
        } else if self.flags & FLAG_NATURAL != 0 {
            // 64-bit types only (see `natural_flag`).
            if self.data_type.is_signed() {
                i64::MIN
            } else {
                0
            }
        } else {
            unpattern(self.data_type, self.spec[0])
        }
    }
    /// Largest accepted value on write (numeric types).
    pub const fn max(&self) -> i64 {
        if self.has_no_range() {
            0
        } else if self.flags & FLAG_NATURAL != 0 {
            // 64-bit types only; u64 values above i64::MAX are not range-checked.
            i64::MAX
        } else {
            unpattern(self.data_type, self.spec[1])
        }
    }
    /// The numeric default (not for a string).
    const fn int_default(&self) -> DefaultValue {
        if self.flags & (FLAG_TEXT | FLAG_HAS_DEFAULT) == FLAG_HAS_DEFAULT {
            DefaultValue::Int(unpattern(self.data_type, self.spec[2]))
        } else {
            DefaultValue::None
        }
    }
    /// Default value (also the ESI `DefaultData`).
    pub fn default_value(&self) -> DefaultValue {
        match self.text_default() {
            Some(t) => DefaultValue::Text(t),
            None => self.int_default(),
        }
    }
    /// Unit text ("mA", "ms", "inc", …); empty when dimensionless.
    pub fn unit_text(&self) -> &'static str {
        unit_text(self.unit)
    }
    /// Size in bytes on the wire (rounded up).
    pub const fn byte_len(&self) -> usize {
        (self.bits() as usize).div_ceil(8)
    }
    /// The access word of SDO information's entry description: bits 0-5 from
    /// [`Access::bits`], bit 6 RxPDO mappable, bit 7 TxPDO mappable.
    pub const fn sdo_info_access(&self) -> u16 {
        self.access.bits()
            | if self.pdo_mappable().rx() { 1 << 6 } else { 0 }
            | if self.pdo_mappable().tx() { 1 << 7 } else { 0 }
    }
    /// The fields other than the name and the default, compared (same type, length,
    /// sub-index, access, mapping, range, unit and 'save' flag).
    const fn same_fields(&self, other: &Entry) -> bool {
        self.data_type as u8 == other.data_type as u8
            && self.bits() == other.bits()
            && self.sub == other.sub
            && self.access.0 == other.access.0
            && self.flags & (FLAG_SAVED | FLAG_PDO) == other.flags & (FLAG_SAVED | FLAG_PDO)
            && self.unit == other.unit
            && self.min() == other.min()
            && self.max() == other.max()
    }
}

/// Text `unit` of [`UNITS`].
fn unit_text(unit: u8) -> &'static str {
    let k = unit as usize;
    let start = match k.checked_sub(1) {
        Some(before) => UNIT_END.get(before),
        None => Some(&0),
    };
    match (start, UNIT_END.get(k)) {
        (Some(&a), Some(&b)) => UNIT_TEXT.get(a as usize..b as usize).unwrap_or(""),
        _ => "",
    }
}

/// Two entries are equal when they describe the same thing (same name, type, length,
/// sub-index, access, mapping, range, default, unit and 'save' flag).
impl PartialEq for Entry {
    fn eq(&self, other: &Self) -> bool {
        self.name() == other.name()
            && self.same_fields(other)
            && self.default_value() == other.default_value()
    }
}

impl Eq for Entry {}

impl core::fmt::Debug for Entry {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        self.debug(f, "Entry", &self.name(), self.default_value())
    }
}

impl Entry {
    /// The [`core::fmt::Debug`] form of an entry named `name` with the default
    /// `default` (the packed entry and its description print alike).
    fn debug(
        &self,
        f: &mut core::fmt::Formatter<'_>,
        kind: &str,
        name: &dyn core::fmt::Debug,
        default: DefaultValue,
    ) -> core::fmt::Result {
        f.debug_struct(kind)
            .field("sub", &self.sub)
            .field("name", name)
            .field("data_type", &self.data_type)
            .field("bits", &self.bits())
            .field("access", &self.access)
            .field("pdo", &self.pdo_mappable())
            .field("saved", &self.is_saved())
            .field("min", &self.min())
            .field("max", &self.max())
            .field("default", &default)
            .field("unit", &self.unit_text())
            .finish()
    }
}

/// Bit length and value range of a numeric type.
pub const fn type_range(t: DataType) -> (u16, i64, i64) {
    let bits = type_bits(t);
    let (lo, hi) = match t {
        DataType::Integer8 | DataType::Integer16 | DataType::Integer32 | DataType::Integer64 => {
            (i64::MIN >> (64 - bits), i64::MAX >> (64 - bits))
        }
        // u64 values above i64::MAX are not range-checked.
        DataType::Unsigned64 => (0, i64::MAX),
        DataType::Real32 | DataType::VisibleString | DataType::OctetString => (0, 0),
        _ => (0, (1 << bits) - 1),
    };
    (bits, lo, hi)
}

/// Bit length of a value of `t` (0 for the strings: their length is the entry's).
pub const fn type_bits(t: DataType) -> u16 {
    match t {
        DataType::Boolean | DataType::Bit1 => 1,
        DataType::Bit2 => 2,
        DataType::Bit3 => 3,
        DataType::Bit4 => 4,
        DataType::Bit5 => 5,
        DataType::Bit6 => 6,
        DataType::Bit7 => 7,
        DataType::Integer8 | DataType::Unsigned8 | DataType::Bit8 => 8,
        DataType::Integer16 | DataType::Unsigned16 => 16,
        DataType::Integer32 | DataType::Unsigned32 | DataType::Real32 => 32,
        DataType::Integer64 | DataType::Unsigned64 => 64,
        DataType::VisibleString | DataType::OctetString => 0,
    }
}

/// One object, as the packed dictionary keeps it.
///
/// Kept compact (12 bytes on the target): the name and the entries are offsets into
/// the dictionary's [`Tables`] with one-byte lengths, the object code shares a byte
/// with the name length; read them with [`Object::name`], [`Object::entries`] and
/// [`Object::code`]. Tables are written as [`ObjectDesc`]s.
#[derive(Clone, Copy)]
pub struct Object {
    /// The dictionary's texts and entry table.
    tables: &'static Tables,
    /// Index.
    pub index: u16,
    /// Offset of the packed name in the dictionary's [`Strings`].
    name_at: u16,
    /// Offset of the first entry in the dictionary's entry table.
    entries_at: u16,
    /// Bits 0-5: length of the packed name (at most [`MAX_OBJECT_NAME`]); bits 6-7: the
    /// object code minus 7 (VAR 0, ARRAY 1, RECORD 2).
    name_code: u8,
    /// Number of entries (at most [`MAX_ENTRIES`]).
    entries_len: u8,
    /// What the object means (dictionary reference). Only kept with the
    /// `descriptions` feature (documentation generators); the target build leaves the
    /// texts out of flash.
    #[cfg(feature = "descriptions")]
    description: &'static str,
}

#[cfg(all(target_pointer_width = "32", not(feature = "descriptions")))]
const _: () = assert!(core::mem::size_of::<Object>() == 12);

/// Longest object name in bytes (6 bits of [`Object`]; entry names may have 255).
pub const MAX_OBJECT_NAME: usize = 63;
/// Most entries of one object (one byte of [`Object`]).
pub const MAX_ENTRIES: usize = 255;
/// The bits of `Object::name_code` that hold the name length.
const NAME_LEN_MASK: u8 = MAX_OBJECT_NAME as u8;
/// Position of the object code in `Object::name_code`.
const CODE_SHIFT: u32 = 6;

impl Object {
    /// Name.
    pub fn name(&self) -> Name {
        let len = (self.name_code & NAME_LEN_MASK) as usize;
        self.tables.strings.name(self.name_at, len)
    }
    /// VAR, ARRAY or RECORD.
    pub const fn code(&self) -> ObjectCode {
        code_of(self.name_code >> CODE_SHIFT)
    }
    /// Entries sorted by sub-index. A VAR has exactly one entry (sub-index 0); an
    /// ARRAY or RECORD has its sub-index 0 (UINT8 count) first.
    // Measured (cargo xtask size, LAN9252 image): see `Entry::bits`.
    #[inline(never)]
    pub fn entries(&self) -> &'static [Entry] {
        let at = self.entries_at as usize;
        let entries: &'static [Entry] = self.tables.entries;
        entries
            .get(at..at + self.entries_len as usize)
            .unwrap_or(&[])
    }
    /// What the object means; empty without the `descriptions` feature.
    pub const fn description(&self) -> &'static str {
        #[cfg(feature = "descriptions")]
        return self.description;
        #[cfg(not(feature = "descriptions"))]
        return "";
    }
    /// The entry with sub-index `sub`.
    pub fn entry(&self, sub: u8) -> Option<&'static Entry> {
        self.entries().iter().find(|e| e.sub == sub)
    }
    /// Highest sub-index described.
    pub fn max_sub(&self) -> u8 {
        self.entries().last().map_or(0, |e| e.sub)
    }
}

/// The object code of the two bits [`Object`] keeps (VAR 0, ARRAY 1, RECORD 2).
const fn code_of(bits: u8) -> ObjectCode {
    match bits {
        0 => ObjectCode::Var,
        1 => ObjectCode::Array,
        _ => ObjectCode::Record,
    }
}

/// Two objects are equal when they describe the same thing (same index, name, object
/// code, entries and description).
impl PartialEq for Object {
    fn eq(&self, other: &Self) -> bool {
        self.index == other.index
            && self.name() == other.name()
            && self.code() == other.code()
            && self.entries() == other.entries()
            && self.description() == other.description()
    }
}

impl Eq for Object {}

impl core::fmt::Debug for Object {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Object")
            .field("index", &self.index)
            .field("name", &self.name())
            .field("code", &self.code())
            .field("entries", &self.entries())
            .finish()
    }
}

/// Finds an object in a table sorted by index (binary search).
pub fn find(objects: &'static [Object], index: u16) -> Option<&'static Object> {
    objects
        .binary_search_by_key(&index, |o| o.index)
        .ok()
        .map(|i| &objects[i])
}

/// Finds an entry, distinguishing "no object" from "no sub-index".
pub fn find_entry(objects: &'static [Object], key: ObjectKey) -> Result<&'static Entry, SdoAbort> {
    let obj = find(objects, key.index).ok_or(SdoAbort::ObjectDoesNotExist)?;
    obj.entry(key.sub).ok_or(SdoAbort::SubindexDoesNotExist)
}

/// True when `objects` is strictly sorted by index and every object's entries are
/// strictly sorted by sub-index (checked by tests of every dictionary).
pub fn is_well_formed(objects: &[Object]) -> bool {
    objects.windows(2).all(|w| w[0].index < w[1].index)
        && objects
            .iter()
            .all(|o| !o.entries().is_empty() && o.entries().windows(2).all(|w| w[0].sub < w[1].sub))
}

/// Decodes a little-endian numeric value of `t` from `data` (sign-extended).
pub fn decode_int(t: DataType, data: &[u8]) -> Option<i64> {
    let mut b = [0u8; 8];
    let n = data.len().min(8);
    b[..n].copy_from_slice(&data[..n]);
    let raw = u64::from_le_bytes(b);
    Some(match t {
        DataType::Integer8 => raw as u8 as i8 as i64,
        DataType::Integer16 => raw as u16 as i16 as i64,
        DataType::Integer32 => raw as u32 as i32 as i64,
        DataType::Integer64 => raw as i64,
        DataType::Unsigned64 => raw.min(i64::MAX as u64) as i64,
        DataType::Real32 | DataType::VisibleString | DataType::OctetString => return None,
        _ => raw as i64,
    })
}

/// The checks every SDO write goes through before the application sees it:
/// access in this ESM state, length, and range.
pub fn check_write(entry: &Entry, data: &[u8], state: EsmState) -> Result<(), SdoAbort> {
    if !entry.access.writable() {
        return Err(SdoAbort::WriteReadOnly);
    }
    if !entry.access.writable_in(state) {
        return Err(SdoAbort::StateConflict);
    }
    let len = entry.byte_len();
    if entry.data_type.is_variable_length() {
        if data.len() > len {
            return Err(SdoAbort::LengthTooHigh);
        }
        return Ok(());
    }
    if data.len() > len {
        return Err(SdoAbort::LengthTooHigh);
    }
    if data.len() < len {
        return Err(SdoAbort::LengthTooLow);
    }
    if let Some(v) = decode_int(entry.data_type, data) {
        if v > entry.max() {
            return Err(SdoAbort::ValueTooHigh);
        }
        if v < entry.min() {
            return Err(SdoAbort::ValueTooLow);
        }
    }
    Ok(())
}

/// The checks every SDO read goes through.
pub fn check_read(entry: &Entry, state: EsmState) -> Result<(), SdoAbort> {
    if !entry.access.readable() {
        return Err(SdoAbort::ReadWriteOnly);
    }
    if !entry.access.readable_in(state) {
        return Err(SdoAbort::StateConflict);
    }
    Ok(())
}

/// What the application provides: the static description and the values.
///
/// The stack calls [`Dictionary::read`] / [`Dictionary::write`] only for entries that
/// exist and have passed [`check_read`] / [`check_write`]; the application adds its own
/// rules (e.g. sub-index 0 of a mapping object must be 0 first, 'save' signatures,
/// read-only-while-auto-tune) and returns the matching abort.
pub trait Dictionary {
    /// The objects, sorted by index.
    fn objects(&self) -> &'static [Object];
    /// Writes the entry's current value into `buf` (little-endian) and returns its length.
    fn read(&mut self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort>;
    /// Stores a new value (already checked for access, length and range).
    fn write(&mut self, key: ObjectKey, data: &[u8], state: EsmState) -> Result<(), SdoAbort>;
    /// A write arriving through the slave runtime, which passes the objects it serves
    /// itself (PDO mapping/assignment, sync parameters) as `runtime`. Needed where one
    /// write acts on the whole dictionary — 0x1010 'save' must store the mapping too.
    /// The default is a plain [`Dictionary::write`].
    fn write_with_runtime(
        &mut self,
        key: ObjectKey,
        data: &[u8],
        state: EsmState,
        runtime: &mut dyn Dictionary,
    ) -> Result<(), SdoAbort> {
        let _ = runtime;
        self.write(key, data, state)
    }
}

/// The OD lists of SDO information's "get OD list" service (ETG.1000.6).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u16)]
pub enum OdListType {
    /// Not a list: the answer is the number of objects of lists 1 to 5.
    Counts = 0,
    /// All objects.
    All = 1,
    /// Objects with at least one RxPDO-mappable entry.
    RxPdoMappable = 2,
    /// Objects with at least one TxPDO-mappable entry.
    TxPdoMappable = 3,
    /// Objects to store for a device replacement (backup): in this stack, objects with
    /// at least one entry marked [`Entry::is_saved`].
    Backup = 4,
    /// Start-up parameters ("settings"): in this stack, also the objects with at least one
    /// [`Entry::is_saved`] entry — the parameters a master may write at start-up are exactly
    /// the ones the drive stores.
    Settings = 5,
}

impl OdListType {
    /// Lists 1 to 5, in the order of the counts answer of list type 0.
    pub const LISTS: [OdListType; 5] = [
        Self::All,
        Self::RxPdoMappable,
        Self::TxPdoMappable,
        Self::Backup,
        Self::Settings,
    ];

    /// Decodes the list type of a request.
    pub const fn from_code(code: u16) -> Option<Self> {
        match code {
            0 => Some(Self::Counts),
            1 => Some(Self::All),
            2 => Some(Self::RxPdoMappable),
            3 => Some(Self::TxPdoMappable),
            4 => Some(Self::Backup),
            5 => Some(Self::Settings),
            _ => None,
        }
    }

    /// The raw code.
    pub const fn code(self) -> u16 {
        self as u16
    }

    /// True when `obj` belongs to this list ([`OdListType::Counts`] contains nothing).
    pub fn contains(self, obj: &Object) -> bool {
        match self {
            Self::Counts => false,
            Self::All => true,
            Self::RxPdoMappable => obj.entries().iter().any(|e| e.pdo_mappable().rx()),
            Self::TxPdoMappable => obj.entries().iter().any(|e| e.pdo_mappable().tx()),
            Self::Backup | Self::Settings => obj.entries().iter().any(|e| e.is_saved()),
        }
    }

    /// Number of objects of `objects` in this list.
    pub fn count(self, objects: &[Object]) -> usize {
        objects.iter().filter(|o| self.contains(o)).count()
    }
}

#[cfg(test)]
mod reference_tests;
