//! How the owners of the values write the dictionary: [`EntryDesc`] and
//! [`ObjectDesc`], constant tables with plain names and text defaults.
//!
//! They exist during compilation: [`crate::packed_dictionary!`] turns them into the
//! [`Entry`]s and [`Object`]s kept in flash, which read the names and texts in the
//! dictionary's [`Strings`]. Everything else an entry holds (type, access, range as
//! 32-bit patterns, default, unit, flags) is already in the packed form here, so
//! packing only adds the offsets.

use super::*;

/// The description of one entry as a table writes it: a name, and for a string its
/// default text; the rest is kept as the packed [`Entry`] will hold it.
#[derive(Clone, Copy)]
pub struct EntryDesc {
    name: &'static str,
    /// The default of a string ([`FLAG_TEXT`]).
    text: &'static str,
    /// Everything but the texts (its `strings` are [`Strings::NONE`] until packed).
    fields: Entry,
}

impl EntryDesc {
    /// A numeric entry with the natural range of its type, no default, not saved.
    pub const fn new(sub: u8, name: &'static str, data_type: DataType, access: Access) -> Self {
        assert!(
            name.len() <= u8::MAX as usize,
            "od name longer than 255 bytes"
        );
        EntryDesc {
            name,
            text: "",
            fields: Entry {
                strings: &Strings::NONE,
                spec: natural_patterns(data_type),
                name_at: 0,
                data_type,
                sub,
                access,
                unit: 0,
                name_len: 0,
                flags: natural_flag(data_type),
            },
        }
    }
    /// Sub-index 0 of an ARRAY or RECORD: "Number of entries", UINT8, read-only, with
    /// default `n` and the natural range of UINT8.
    pub const fn count(n: u8) -> Self {
        EntryDesc::new(0, "Number of entries", DataType::Unsigned8, Access::RO).default(n as i64)
    }
    /// A visible string of at most `max_len` bytes (read-only).
    pub const fn text(sub: u8, name: &'static str, max_len: u16, value: &'static str) -> Self {
        assert!(max_len <= u16::MAX / 8, "od string longer than 8191 bytes");
        let mut e = EntryDesc::new(sub, name, DataType::VisibleString, Access::RO);
        e.text = value;
        e.fields.spec[0] = max_len as i32;
        e.fields.flags = FLAG_TEXT;
        e
    }
    /// An octet string of `len` bytes (read-only) whose value the application
    /// supplies (e.g. an ETG.1020 diagnosis message, 0x10F3:06 and up).
    pub const fn octets(sub: u8, name: &'static str, len: u16) -> Self {
        let mut e = EntryDesc::text(sub, name, len, "");
        e.fields.data_type = DataType::OctetString;
        e
    }
    /// Sets the accepted range (must fit the 32-bit pattern of the type: checked at
    /// compile time for the constant tables).
    pub const fn range(mut self, min: i64, max: i64) -> Self {
        let f = &mut self.fields;
        if !f.has_no_range() {
            f.spec = [
                pattern(f.data_type, min),
                pattern(f.data_type, max),
                f.spec[2],
            ];
            f.flags &= !FLAG_NATURAL;
        }
        self
    }
    /// Sets the default value.
    pub const fn default(mut self, v: i64) -> Self {
        let f = &mut self.fields;
        if f.flags & FLAG_TEXT == 0 {
            f.spec[2] = pattern(f.data_type, v);
            f.flags |= FLAG_HAS_DEFAULT;
        }
        self
    }
    /// Replaces the default (documentation generators that describe a variant).
    pub const fn with_default_value(mut self, d: DefaultValue) -> Self {
        let keep = self.fields.flags & (FLAG_SAVED | FLAG_PDO);
        match d {
            DefaultValue::Int(v) => {
                let f = &mut self.fields;
                if f.flags & FLAG_TEXT != 0 {
                    self.text = "";
                    // A string keeps its length.
                    let len = f.spec[0];
                    f.spec = natural_patterns(f.data_type);
                    if f.data_type.is_variable_length() {
                        f.spec[0] = len;
                    }
                    f.flags = keep | natural_flag(f.data_type);
                }
                self.default(v)
            }
            DefaultValue::Text(t) => {
                self.text = t;
                self.fields.flags = keep | FLAG_TEXT;
                self
            }
            DefaultValue::None => {
                self.fields.flags &= !FLAG_HAS_DEFAULT;
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
                self.fields.unit = i as u8;
                return self;
            }
            i += 1;
        }
        panic!("unit not in od::UNITS");
    }
    /// Marks the entry as stored by 'save' (0x1010).
    pub const fn saved(mut self) -> Self {
        self.fields.flags |= FLAG_SAVED;
        self
    }
    /// Sets the access rights (e.g. a writable text).
    pub const fn with_access(mut self, access: Access) -> Self {
        self.fields.access = access;
        self
    }
    /// Sets PDO mappability.
    pub const fn pdo(mut self, pdo: PdoMappable) -> Self {
        self.fields.flags = (self.fields.flags & !FLAG_PDO) | ((pdo as u8) << PDO_SHIFT);
        self
    }
    /// Name.
    pub const fn name(&self) -> &'static str {
        self.name
    }
    /// Sub-index.
    pub const fn sub(&self) -> u8 {
        self.fields.sub
    }
    /// Data type.
    pub const fn data_type(&self) -> DataType {
        self.fields.data_type
    }
    /// Access per ESM state.
    pub const fn access(&self) -> Access {
        self.fields.access
    }
    /// Length in bits (for strings: the maximum length).
    pub const fn bits(&self) -> u16 {
        self.fields.bits()
    }
    /// Stored in flash by 'save' (0x1010).
    pub const fn is_saved(&self) -> bool {
        self.fields.is_saved()
    }
    /// PDO mappability.
    pub const fn pdo_mappable(&self) -> PdoMappable {
        self.fields.pdo_mappable()
    }
    /// Smallest accepted value on write (numeric types).
    pub const fn min(&self) -> i64 {
        self.fields.min()
    }
    /// Largest accepted value on write (numeric types).
    pub const fn max(&self) -> i64 {
        self.fields.max()
    }
    /// Default value.
    pub const fn default_value(&self) -> DefaultValue {
        if self.fields.flags & FLAG_TEXT != 0 {
            DefaultValue::Text(self.text)
        } else {
            self.fields.int_default()
        }
    }
    /// Unit text; empty when dimensionless.
    pub fn unit_text(&self) -> &'static str {
        unit_text(self.fields.unit)
    }
    /// The default text of a string (empty for a numeric entry).
    pub(crate) const fn text_value(&self) -> &'static str {
        self.text
    }
    /// The packed entry: this one reading its name (`name_len` bytes at `name_at`) and
    /// its default text (at `text_at`) in `strings`.
    pub(crate) const fn packed(
        &self,
        strings: &'static Strings,
        name_at: u16,
        name_len: usize,
        text_at: u16,
    ) -> Entry {
        assert!(
            name_len <= u8::MAX as usize,
            "packed od name over 255 bytes"
        );
        let mut e = self.fields;
        e.strings = strings;
        e.name_at = name_at;
        e.name_len = name_len as u8;
        if e.flags & FLAG_TEXT != 0 {
            assert!(self.text.len() <= u16::MAX as usize, "od text over 64 KiB");
            e.spec[1] = super::text_at(text_at, self.text.len() as u16);
        }
        e
    }
    /// [`PartialEq`] at compile time (the packer's test for equal entry tables).
    pub(crate) const fn same(&self, other: &EntryDesc) -> bool {
        str_eq(self.name, other.name)
            && str_eq(self.text, other.text)
            && self.fields.same_fields(&other.fields)
            && self.fields.flags == other.fields.flags
            && (self.fields.flags & (FLAG_TEXT | FLAG_HAS_DEFAULT) != FLAG_HAS_DEFAULT
                || self.fields.spec[2] == other.fields.spec[2])
    }
}

/// Two descriptions are equal when they describe the same thing.
impl PartialEq for EntryDesc {
    fn eq(&self, other: &Self) -> bool {
        self.same(other)
    }
}

impl Eq for EntryDesc {}

/// A packed entry equals the description it was packed from.
impl PartialEq<EntryDesc> for Entry {
    fn eq(&self, other: &EntryDesc) -> bool {
        self.name() == other.name
            && self.same_fields(&other.fields)
            && self.default_value() == other.default_value()
    }
}

impl core::fmt::Debug for EntryDesc {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        self.fields
            .debug(f, "EntryDesc", &self.name, self.default_value())
    }
}

/// The description of one object as a table writes it.
#[derive(Clone, Copy)]
pub struct ObjectDesc {
    /// Index.
    pub index: u16,
    name: &'static str,
    code: ObjectCode,
    entries: &'static [EntryDesc],
    description: &'static str,
}

impl ObjectDesc {
    /// An object with the given object code; a name longer than [`MAX_OBJECT_NAME`]
    /// or more than [`MAX_ENTRIES`] entries is a compile-time error for the constant
    /// tables.
    pub const fn new(
        index: u16,
        name: &'static str,
        code: ObjectCode,
        entries: &'static [EntryDesc],
        description: &'static str,
    ) -> Self {
        assert!(
            name.len() <= MAX_OBJECT_NAME,
            "od object name longer than MAX_OBJECT_NAME"
        );
        ObjectDesc {
            index,
            name,
            code,
            entries,
            description,
        }
        .with_entries(entries)
    }
    /// A VAR object (its single entry has sub-index 0).
    pub const fn var(
        index: u16,
        name: &'static str,
        entries: &'static [EntryDesc],
        description: &'static str,
    ) -> Self {
        Self::new(index, name, ObjectCode::Var, entries, description)
    }
    /// An ARRAY object (sub-index 0 is the count, see [`EntryDesc::count`]).
    pub const fn array(
        index: u16,
        name: &'static str,
        entries: &'static [EntryDesc],
        description: &'static str,
    ) -> Self {
        Self::new(index, name, ObjectCode::Array, entries, description)
    }
    /// A RECORD object (sub-index 0 is the count, see [`EntryDesc::count`]).
    pub const fn record(
        index: u16,
        name: &'static str,
        entries: &'static [EntryDesc],
        description: &'static str,
    ) -> Self {
        Self::new(index, name, ObjectCode::Record, entries, description)
    }
    /// The same object with other entries (documentation generators).
    pub const fn with_entries(mut self, entries: &'static [EntryDesc]) -> Self {
        assert!(
            entries.len() <= MAX_ENTRIES,
            "od object with more than MAX_ENTRIES entries"
        );
        self.entries = entries;
        self
    }
    /// Name.
    pub const fn name(&self) -> &'static str {
        self.name
    }
    /// VAR, ARRAY or RECORD.
    pub const fn code(&self) -> ObjectCode {
        self.code
    }
    /// Entries sorted by sub-index.
    pub const fn entries(&self) -> &'static [EntryDesc] {
        self.entries
    }
    /// What the object means.
    pub const fn description(&self) -> &'static str {
        self.description
    }
    /// The entry with sub-index `sub`.
    pub fn entry(&self, sub: u8) -> Option<&'static EntryDesc> {
        self.entries.iter().find(|e| e.sub() == sub)
    }
    /// The packed object: this one reading its name (`name_len` bytes at `name_at`) and
    /// its entries (at `entries_at`) in `tables`.
    pub(crate) const fn packed(
        &self,
        tables: &'static Tables,
        name_at: u16,
        name_len: usize,
        entries_at: u16,
    ) -> Object {
        assert!(
            name_len <= MAX_OBJECT_NAME,
            "packed od object name too long"
        );
        Object {
            tables,
            index: self.index,
            name_at,
            entries_at,
            name_code: name_len as u8 | ((self.code as u8 - ObjectCode::Var as u8) << CODE_SHIFT),
            entries_len: self.entries.len() as u8,
            #[cfg(feature = "descriptions")]
            description: self.description,
        }
    }
}

/// A packed object equals the description it was packed from (the description
/// text only with the `descriptions` feature, which keeps it).
impl PartialEq<ObjectDesc> for Object {
    fn eq(&self, other: &ObjectDesc) -> bool {
        self.index == other.index
            && self.name() == other.name
            && self.code() == other.code
            && self.entries() == other.entries
            && (cfg!(not(feature = "descriptions")) || self.description() == other.description)
    }
}

impl PartialEq for ObjectDesc {
    fn eq(&self, other: &Self) -> bool {
        self.index == other.index
            && str_eq(self.name, other.name)
            && self.code == other.code
            && self.entries == other.entries
            && str_eq(self.description, other.description)
    }
}

impl Eq for ObjectDesc {}

impl core::fmt::Debug for ObjectDesc {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("ObjectDesc")
            .field("index", &self.index)
            .field("name", &self.name)
            .field("code", &self.code)
            .field("entries", &self.entries)
            .finish()
    }
}

/// An entry to fill arrays with before they are written (compile-time table builders).
pub(crate) const PLACEHOLDER_ENTRY: EntryDesc =
    EntryDesc::new(0, "", DataType::Unsigned8, Access::RO);
/// A packed entry to fill arrays with before they are written.
pub(crate) const PLACEHOLDER_PACKED_ENTRY: Entry = PLACEHOLDER_ENTRY.fields;
/// A packed object to fill arrays with before they are written.
pub(crate) const PLACEHOLDER_PACKED_OBJECT: Object =
    ObjectDesc::var(0, "", &[], "").packed(&Tables::NONE, 0, 0, 0);
