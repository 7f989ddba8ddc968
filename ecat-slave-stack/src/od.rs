//! The object dictionary framework.
//!
//! One static description per object ([`Object`]) and per entry ([`Entry`]) — index,
//! sub-index, name, data type, bit length, access per ESM state, PDO mappability,
//! range, default, unit, saved-or-not. That single description feeds the SDO server
//! (access, length and range checks), the PDO mapping rules, SDO information, the
//! SII image, the ESI XML and the generated dictionary reference. The *values* are
//! owned by the application, which implements [`Dictionary`].
//!
//! The generic checks done by the stack before a write reaches the application are
//! in [`check_write`]; lookups are binary searches over the sorted object table.

use crate::esm::EsmState;

mod abort;
mod name;
pub mod pack;
mod reference;
mod types;

pub use abort::SdoAbort;
pub use reference::write_reference;
pub use types::*;

pub use name::{pack_into, packed_len, Name, NameBytes};

/// The static description of one entry (sub-index) of an object.
///
/// Kept compact (24 bytes on the target: the dictionary has several hundred entries):
/// the name is a thin pointer and a one-byte length (read it with [`Entry::name`]),
/// limits and the default are stored as 32-bit patterns read back through the data
/// type, the unit as an index into [`UNITS`], the flags in one byte. Use
/// [`Entry::min`], [`Entry::max`], [`Entry::default_value`], [`Entry::unit_text`] and
/// [`Entry::is_saved`] to read them.
#[derive(Clone, Copy)]
pub struct Entry {
    /// First byte of the name (see [`Entry::name`]).
    name_ptr: *const u8,
    spec: Spec,
    /// Data type.
    pub data_type: DataType,
    /// Length in bits (for strings: the maximum length).
    pub bits: u16,
    /// Sub-index.
    pub sub: u8,
    /// Access per ESM state.
    pub access: Access,
    unit: u8,
    name_len: u8,
    /// [`FLAG_SAVED`], [`FLAG_TEXT`], [`FLAG_NATURAL`], [`FLAG_HAS_DEFAULT`] and the
    /// [`PdoMappable`] code at [`PDO_SHIFT`].
    flags: u8,
}

#[cfg(target_pointer_width = "32")]
const _: () = assert!(core::mem::size_of::<Entry>() == 24);

// SAFETY: the only non-`Sync`/`Send` field is `name_ptr`, which always points into the
// bytes of a `&'static str` (immutable, never freed): sharing or sending an `Entry` is
// sharing that `&'static str`, which is `Sync` and `Send`.
unsafe impl Sync for Entry {}
// SAFETY: see the `Sync` impl above.
unsafe impl Send for Entry {}

/// Stored in flash by 'save' (0x1010).
const FLAG_SAVED: u8 = 1 << 0;
/// [`Spec::text`] holds the default (otherwise [`Spec::num`]).
const FLAG_TEXT: u8 = 1 << 1;
/// The range is the data type's own and does not fit 32-bit patterns (64-bit types
/// without [`Entry::range`]); the natural range of the other types is stored in
/// [`Spec::num`] like any other, so [`Entry::min`]/[`Entry::max`] need no table of types.
const FLAG_NATURAL: u8 = 1 << 2;
/// [`Spec::num`]'s default is meaningful.
const FLAG_HAS_DEFAULT: u8 = 1 << 3;
/// Position of the two [`PdoMappable`] bits in the flags.
const PDO_SHIFT: u32 = 4;
/// The two [`PdoMappable`] bits.
const FLAG_PDO: u8 = 3 << PDO_SHIFT;
/// The name is packed ([`Name`]; set by [`pack`]).
const FLAG_PACKED: u8 = 1 << 6;

/// Value part of an [`Entry`]: a numeric range and default (32-bit patterns `[lo, hi,
/// def]`, read through the data type) or a text default; which one is written is
/// [`FLAG_TEXT`] of the entry's flags (no tag of its own: that keeps `Entry` at 24
/// bytes).
#[derive(Clone, Copy)]
union Spec {
    num: [i32; 3],
    text: &'static str,
}

/// Splits a name into the thin pointer and the one-byte length [`Entry`] and [`Object`]
/// keep; a name longer than 255 bytes is a compile-time error for the constant tables.
const fn short_name(name: &'static str) -> (*const u8, u8) {
    assert!(
        name.len() <= u8::MAX as usize,
        "od name longer than 255 bytes"
    );
    (name.as_ptr(), name.len() as u8)
}

/// The name [`short_name`] split.
///
/// # Safety
/// `ptr` and `len` must come from one [`short_name`] call.
const unsafe fn long_name(ptr: *const u8, len: u8) -> &'static str {
    // SAFETY: `short_name` took both from one `&'static str` whose length fits `u8`
    // (checked there), so they describe `len` bytes of valid UTF-8 that live for
    // `'static` and are never mutated.
    unsafe { core::str::from_utf8_unchecked(core::slice::from_raw_parts(ptr, len as usize)) }
}

/// Unit texts an entry can carry ([`Entry::unit`]); index 0 is "no unit".
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
    "0.1°",
];

/// [`UNITS`] as length-prefixed texts: what [`Entry::unit_text`] reads (one byte per
/// unit instead of a pointer and a length).
static UNIT_TEXT: [u8; name::prefixed_len(UNITS)] = name::prefixed_list(UNITS);

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

impl Entry {
    /// A numeric entry with the natural range of its type, no default, not saved.
    pub const fn new(sub: u8, name: &'static str, data_type: DataType, access: Access) -> Self {
        let (bits, _, _) = type_range(data_type);
        let (name_ptr, name_len) = short_name(name);
        Entry {
            sub,
            name_ptr,
            name_len,
            data_type,
            bits,
            access,
            spec: Spec {
                num: natural_patterns(data_type),
            },
            unit: 0,
            flags: natural_flag(data_type),
        }
    }
    /// Sub-index 0 of an ARRAY or RECORD: "Number of entries", UINT8, read-only, with
    /// default `n` and the natural range of UINT8.
    pub const fn count(n: u8) -> Self {
        Entry::new(0, "Number of entries", DataType::Unsigned8, Access::RO).default(n as i64)
    }
    /// A visible string of at most `max_len` bytes (read-only).
    pub const fn text(sub: u8, name: &'static str, max_len: u16, value: &'static str) -> Self {
        let (name_ptr, name_len) = short_name(name);
        Entry {
            sub,
            name_ptr,
            name_len,
            data_type: DataType::VisibleString,
            bits: max_len * 8,
            access: Access::RO,
            spec: Spec { text: value },
            unit: 0,
            flags: FLAG_TEXT,
        }
    }
    /// An octet string of `len` bytes (read-only) whose value the application
    /// supplies (e.g. an ETG.1020 diagnosis message, 0x10F3:06 and up).
    pub const fn octets(sub: u8, name: &'static str, len: u16) -> Self {
        let mut e = Entry::text(sub, name, len, "");
        e.data_type = DataType::OctetString;
        e
    }
    /// Name (SDO information, ESI, documentation).
    pub const fn name(&self) -> Name {
        if self.flags & FLAG_PACKED != 0 {
            // SAFETY: with the flag set, `name_ptr` and `name_len` were set together by
            // `with_packed_name` from one `&'static [u8]`.
            Name::packed(unsafe {
                core::slice::from_raw_parts(self.name_ptr, self.name_len as usize)
            })
        } else {
            // SAFETY: `name_ptr` and `name_len` are private and only set by `new`/`text`,
            // from one `short_name` call.
            Name::plain(unsafe { long_name(self.name_ptr, self.name_len) })
        }
    }
    /// The same entry with its name replaced by packed bytes ([`pack`]); longer than
    /// 255 bytes is a compile-time error for the constant tables.
    pub(crate) const fn with_packed_name(mut self, packed: &'static [u8]) -> Self {
        assert!(
            packed.len() <= u8::MAX as usize,
            "packed od name over 255 bytes"
        );
        self.name_ptr = packed.as_ptr();
        self.name_len = packed.len() as u8;
        self.flags |= FLAG_PACKED;
        self
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
    /// The numeric patterns `[lo, hi, def]` (zeros for a text entry).
    const fn num(&self) -> [i32; 3] {
        if self.flags & FLAG_TEXT != 0 {
            return [0; 3];
        }
        // SAFETY: every writer of `spec` sets or clears `FLAG_TEXT` with it: the flag
        // is clear, so `num` is the field last written.
        unsafe { self.spec.num }
    }
    /// The text default, if the entry has one.
    const fn text_default(&self) -> Option<&'static str> {
        if self.flags & FLAG_TEXT == 0 {
            return None;
        }
        // SAFETY: as in `num`: the flag is set, so `text` is the field last written.
        Some(unsafe { self.spec.text })
    }
    /// Sets the accepted range (must fit the 32-bit pattern of the type: checked at
    /// compile time for the constant tables).
    pub const fn range(mut self, min: i64, max: i64) -> Self {
        if self.flags & FLAG_TEXT == 0 {
            let [_, _, def] = self.num();
            let t = self.data_type;
            self.spec = Spec {
                num: [pattern(t, min), pattern(t, max), def],
            };
            self.flags &= !FLAG_NATURAL;
        }
        self
    }
    /// Sets the default value.
    pub const fn default(mut self, v: i64) -> Self {
        if self.flags & FLAG_TEXT == 0 {
            let [lo, hi, _] = self.num();
            self.spec = Spec {
                num: [lo, hi, pattern(self.data_type, v)],
            };
            self.flags |= FLAG_HAS_DEFAULT;
        }
        self
    }
    /// Replaces the default (documentation generators that describe a variant).
    pub const fn with_default_value(mut self, d: DefaultValue) -> Self {
        match d {
            DefaultValue::Int(v) => {
                if self.flags & FLAG_TEXT != 0 {
                    self.spec = Spec {
                        num: natural_patterns(self.data_type),
                    };
                    self.flags = (self.flags & (FLAG_SAVED | FLAG_PDO | FLAG_PACKED))
                        | natural_flag(self.data_type);
                }
                self.default(v)
            }
            DefaultValue::Text(t) => {
                self.spec = Spec { text: t };
                self.flags = (self.flags & (FLAG_SAVED | FLAG_PDO | FLAG_PACKED)) | FLAG_TEXT;
                self
            }
            DefaultValue::None => {
                self.flags &= !FLAG_HAS_DEFAULT;
                self
            }
        }
    }
    /// Sets the unit (one of [`UNITS`]; an unknown unit is a compile-time error for
    /// the constant tables).
    pub const fn unit(mut self, unit: &'static str) -> Self {
        let mut i = 0;
        while i < UNITS.len() {
            if str_eq(UNITS[i], unit) {
                self.unit = i as u8;
                return self;
            }
            i += 1;
        }
        panic!("unit not in od::UNITS");
    }
    /// Marks the entry as stored by 'save' (read back with [`Entry::is_saved`]).
    pub const fn saved(mut self) -> Self {
        self.flags |= FLAG_SAVED;
        self
    }
    /// Sets the access rights (e.g. a writable text).
    pub const fn with_access(mut self, access: Access) -> Self {
        self.access = access;
        self
    }
    /// Sets PDO mappability (read back with [`Entry::pdo_mappable`]).
    pub const fn pdo(mut self, pdo: PdoMappable) -> Self {
        self.flags = (self.flags & !FLAG_PDO) | ((pdo as u8) << PDO_SHIFT);
        self
    }
    /// Smallest accepted value on write (numeric types).
    pub const fn min(&self) -> i64 {
        if self.flags & FLAG_TEXT != 0 {
            0
        } else if self.flags & FLAG_NATURAL != 0 {
            // 64-bit types only (see `natural_flag`).
            if self.data_type.is_signed() {
                i64::MIN
            } else {
                0
            }
        } else {
            unpattern(self.data_type, self.num()[0])
        }
    }
    /// Largest accepted value on write (numeric types).
    pub const fn max(&self) -> i64 {
        if self.flags & FLAG_TEXT != 0 {
            0
        } else if self.flags & FLAG_NATURAL != 0 {
            // 64-bit types only; u64 values above i64::MAX are not range-checked.
            i64::MAX
        } else {
            unpattern(self.data_type, self.num()[1])
        }
    }
    /// Default value (also the ESI `DefaultData`).
    pub const fn default_value(&self) -> DefaultValue {
        if let Some(t) = self.text_default() {
            DefaultValue::Text(t)
        } else if self.flags & FLAG_HAS_DEFAULT != 0 {
            DefaultValue::Int(unpattern(self.data_type, self.num()[2]))
        } else {
            DefaultValue::None
        }
    }
    /// Unit text ("mA", "ms", "inc", …); empty when dimensionless.
    pub fn unit_text(&self) -> &'static str {
        let text = name::prefixed(&UNIT_TEXT, self.unit);
        // SAFETY: `UNIT_TEXT` holds the whole texts of `UNITS`, each after its length
        // byte; `prefixed` returns one of them (or nothing): valid UTF-8.
        unsafe { core::str::from_utf8_unchecked(text) }
    }
    /// Size in bytes on the wire (rounded up).
    pub const fn byte_len(&self) -> usize {
        (self.bits as usize).div_ceil(8)
    }
    /// The access word of SDO information's entry description: bits 0-5 from
    /// [`Access::bits`], bit 6 RxPDO mappable, bit 7 TxPDO mappable.
    pub const fn sdo_info_access(&self) -> u16 {
        self.access.bits()
            | if self.pdo_mappable().rx() { 1 << 6 } else { 0 }
            | if self.pdo_mappable().tx() { 1 << 7 } else { 0 }
    }
}

/// An entry to fill arrays with before they are written (compile-time table builders).
pub(crate) const PLACEHOLDER_ENTRY: Entry = Entry::new(0, "", DataType::Unsigned8, Access::RO);
/// An object to fill arrays with before they are written.
pub(crate) const PLACEHOLDER_OBJECT: Object = Object::var(0, "", &[PLACEHOLDER_ENTRY], "");

/// [`PartialEq`] for entries at compile time: the same text of the name, the same
/// fields, flags and value part.
pub(crate) const fn same_entry(a: &Entry, b: &Entry) -> bool {
    let names = match (a.name().as_plain(), b.name().as_plain()) {
        (Some(x), Some(y)) => str_eq(x, y),
        _ => false,
    };
    let values = match (a.text_default(), b.text_default()) {
        (Some(x), Some(y)) => str_eq(x, y),
        (None, None) => {
            let (x, y) = (a.num(), b.num());
            x[0] == y[0] && x[1] == y[1] && x[2] == y[2]
        }
        _ => false,
    };
    names
        && values
        && a.data_type as u8 == b.data_type as u8
        && a.bits == b.bits
        && a.sub == b.sub
        && a.access.0 == b.access.0
        && a.unit == b.unit
        && a.flags == b.flags
}

/// Two entries are equal when they describe the same thing (same name, type, length,
/// sub-index, access, mapping, range, default, unit and 'save' flag).
impl PartialEq for Entry {
    fn eq(&self, other: &Self) -> bool {
        self.name() == other.name()
            && self.data_type == other.data_type
            && self.bits == other.bits
            && self.sub == other.sub
            && self.access == other.access
            && self.pdo_mappable() == other.pdo_mappable()
            && self.unit == other.unit
            && self.is_saved() == other.is_saved()
            && self.min() == other.min()
            && self.max() == other.max()
            && self.default_value() == other.default_value()
    }
}

impl Eq for Entry {}

impl core::fmt::Debug for Entry {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Entry")
            .field("sub", &self.sub)
            .field("name", &self.name())
            .field("data_type", &self.data_type)
            .field("bits", &self.bits)
            .field("access", &self.access)
            .field("pdo", &self.pdo_mappable())
            .field("saved", &self.is_saved())
            .field("min", &self.min())
            .field("max", &self.max())
            .field("default", &self.default_value())
            .field("unit", &self.unit_text())
            .finish()
    }
}

/// Bit length and value range of a numeric type.
pub const fn type_range(t: DataType) -> (u16, i64, i64) {
    match t {
        DataType::Boolean => (1, 0, 1),
        DataType::Integer8 => (8, i8::MIN as i64, i8::MAX as i64),
        DataType::Integer16 => (16, i16::MIN as i64, i16::MAX as i64),
        DataType::Integer32 => (32, i32::MIN as i64, i32::MAX as i64),
        DataType::Integer64 => (64, i64::MIN, i64::MAX),
        DataType::Unsigned8 => (8, 0, u8::MAX as i64),
        DataType::Unsigned16 => (16, 0, u16::MAX as i64),
        DataType::Unsigned32 => (32, 0, u32::MAX as i64),
        // u64 values above i64::MAX are not range-checked.
        DataType::Unsigned64 => (64, 0, i64::MAX),
        DataType::Real32 => (32, 0, 0),
        DataType::VisibleString | DataType::OctetString => (0, 0, 0),
        DataType::Bit1 => (1, 0, 1),
        DataType::Bit2 => (2, 0, 3),
        DataType::Bit3 => (3, 0, 7),
        DataType::Bit4 => (4, 0, 15),
        DataType::Bit5 => (5, 0, 31),
        DataType::Bit6 => (6, 0, 63),
        DataType::Bit7 => (7, 0, 127),
        DataType::Bit8 => (8, 0, 255),
    }
}

/// The static description of one object.
///
/// Kept compact (12 bytes on the target): the name and the entries are thin pointers
/// with one-byte lengths, the object code shares a byte with the name length; read
/// them with [`Object::name`], [`Object::entries`] and [`Object::code`].
#[derive(Clone, Copy)]
pub struct Object {
    /// Index.
    pub index: u16,
    /// Bits 0-5: length of the name (at most [`MAX_OBJECT_NAME`]); bits 6-7: the
    /// object code minus 7 (VAR 0, ARRAY 1, RECORD 2).
    name_code: u8,
    /// First byte of the name (see [`Object::name`]).
    name_ptr: *const u8,
    /// First entry (see [`Object::entries`]).
    entries_ptr: *const Entry,
    /// Bits 0-6: number of entries (at most [`MAX_ENTRIES`]); bit 7: the name is packed
    /// ([`Name`]; set by [`pack`]).
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
/// Most entries of one object (7 bits of [`Object`]).
pub const MAX_ENTRIES: usize = 127;
/// `Object::entries_len`: the name is packed.
const OBJECT_NAME_PACKED: u8 = 1 << 7;
/// The bits of `Object::name_code` that hold the name length.
const NAME_LEN_MASK: u8 = MAX_OBJECT_NAME as u8;
/// Position of the object code in `Object::name_code`.
const CODE_SHIFT: u32 = 6;

// SAFETY: the only non-`Sync`/`Send` fields are `name_ptr` and `entries_ptr`, which
// always point into a `&'static str` and a `&'static [Entry]` (immutable, never freed;
// `Entry` is `Sync`): sharing or sending an `Object` is sharing those references.
unsafe impl Sync for Object {}
// SAFETY: see the `Sync` impl above.
unsafe impl Send for Object {}

/// Splits an entry table into the thin pointer and the one-byte count [`Object`]
/// keeps; more than [`MAX_ENTRIES`] is a compile-time error for the constant tables.
const fn short_entries(entries: &'static [Entry]) -> (*const Entry, u8) {
    assert!(
        entries.len() <= MAX_ENTRIES,
        "od object with more than MAX_ENTRIES entries"
    );
    (entries.as_ptr(), entries.len() as u8)
}

impl Object {
    /// An object with the given object code.
    pub const fn new(
        index: u16,
        name: &'static str,
        code: ObjectCode,
        entries: &'static [Entry],
        description: &'static str,
    ) -> Self {
        #[cfg(not(feature = "descriptions"))]
        let _ = description;
        assert!(
            name.len() <= MAX_OBJECT_NAME,
            "od object name longer than MAX_OBJECT_NAME"
        );
        let (name_ptr, name_len) = short_name(name);
        let (entries_ptr, entries_len) = short_entries(entries);
        Object {
            index,
            name_ptr,
            name_code: name_len | ((code as u8 - ObjectCode::Var as u8) << CODE_SHIFT),
            entries_ptr,
            entries_len,
            #[cfg(feature = "descriptions")]
            description,
        }
    }
    /// Name.
    pub const fn name(&self) -> Name {
        let len = self.name_code & NAME_LEN_MASK;
        if self.entries_len & OBJECT_NAME_PACKED != 0 {
            // SAFETY: with the flag set, `name_ptr` and the length bits were set
            // together by `with_packed_name` from one `&'static [u8]`.
            Name::packed(unsafe { core::slice::from_raw_parts(self.name_ptr, len as usize) })
        } else {
            // SAFETY: `name_ptr` and the length bits of `name_code` are private and
            // only set by `new`, from one `short_name` call (the length fits the bits:
            // checked there).
            Name::plain(unsafe { long_name(self.name_ptr, len) })
        }
    }
    /// The same object with its name replaced by packed bytes ([`pack`]); longer than
    /// [`MAX_OBJECT_NAME`] is a compile-time error for the constant tables.
    pub(crate) const fn with_packed_name(mut self, packed: &'static [u8]) -> Self {
        assert!(
            packed.len() <= MAX_OBJECT_NAME,
            "packed od object name too long"
        );
        self.name_ptr = packed.as_ptr();
        self.name_code = (self.name_code & !NAME_LEN_MASK) | packed.len() as u8;
        self.entries_len |= OBJECT_NAME_PACKED;
        self
    }
    /// VAR, ARRAY or RECORD.
    pub const fn code(&self) -> ObjectCode {
        match self.name_code >> CODE_SHIFT {
            0 => ObjectCode::Var,
            1 => ObjectCode::Array,
            _ => ObjectCode::Record,
        }
    }
    /// Entries sorted by sub-index. A VAR has exactly one entry (sub-index 0); an
    /// ARRAY or RECORD has its sub-index 0 (UINT8 count) first.
    pub const fn entries(&self) -> &'static [Entry] {
        // SAFETY: `entries_ptr` and `entries_len` are private and only set by `new` and
        // `with_entries`, from one `short_entries` call: they are the start and the
        // length of one `&'static [Entry]`, immutable and never freed.
        unsafe {
            core::slice::from_raw_parts(
                self.entries_ptr,
                (self.entries_len & !OBJECT_NAME_PACKED) as usize,
            )
        }
    }
    /// The same object with other entries (documentation generators).
    pub const fn with_entries(mut self, entries: &'static [Entry]) -> Self {
        let (entries_ptr, entries_len) = short_entries(entries);
        self.entries_ptr = entries_ptr;
        self.entries_len = (self.entries_len & OBJECT_NAME_PACKED) | entries_len;
        self
    }
    /// What the object means; empty without the `descriptions` feature.
    pub const fn description(&self) -> &'static str {
        #[cfg(feature = "descriptions")]
        return self.description;
        #[cfg(not(feature = "descriptions"))]
        return "";
    }
    /// A VAR object (its single entry has sub-index 0).
    pub const fn var(
        index: u16,
        name: &'static str,
        entries: &'static [Entry],
        description: &'static str,
    ) -> Self {
        Self::new(index, name, ObjectCode::Var, entries, description)
    }
    /// An ARRAY object (sub-index 0 is the count, see [`Entry::count`]).
    pub const fn array(
        index: u16,
        name: &'static str,
        entries: &'static [Entry],
        description: &'static str,
    ) -> Self {
        Self::new(index, name, ObjectCode::Array, entries, description)
    }
    /// A RECORD object (sub-index 0 is the count, see [`Entry::count`]).
    pub const fn record(
        index: u16,
        name: &'static str,
        entries: &'static [Entry],
        description: &'static str,
    ) -> Self {
        Self::new(index, name, ObjectCode::Record, entries, description)
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
pub fn find_entry(
    objects: &'static [Object],
    index: u16,
    sub: u8,
) -> Result<&'static Entry, SdoAbort> {
    let obj = find(objects, index).ok_or(SdoAbort::ObjectDoesNotExist)?;
    obj.entry(sub).ok_or(SdoAbort::SubindexDoesNotExist)
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
    fn read(&mut self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, SdoAbort>;
    /// Stores a new value (already checked for access, length and range).
    fn write(&mut self, index: u16, sub: u8, data: &[u8], state: EsmState) -> Result<(), SdoAbort>;
    /// A write arriving through the slave runtime, which passes the objects it serves
    /// itself (PDO mapping/assignment, sync parameters) as `runtime`. Needed where one
    /// write acts on the whole dictionary — 0x1010 'save' must store the mapping too.
    /// The default is a plain [`Dictionary::write`].
    fn write_with_runtime(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
        state: EsmState,
        runtime: &mut dyn Dictionary,
    ) -> Result<(), SdoAbort> {
        let _ = runtime;
        self.write(index, sub, data, state)
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
    /// at least one entry marked [`Entry::saved`].
    Backup = 4,
    /// Start-up parameters ("settings"): in this stack, also the objects with at least one
    /// [`Entry::saved`] entry — the parameters a master may write at start-up are exactly
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
