//! [`ObjectKey`]: the address of one dictionary entry.

/// The address of one entry of the dictionary: object index and sub-index
/// (ETG.1000.6 / CiA 301). Ordered by index, then sub-index, as the dictionary is.
///
/// ```
/// use ecat_slave_stack::od::ObjectKey;
/// let key = ObjectKey::new(0x6040, 0);
/// assert!(key < ObjectKey::new(0x6040, 1));
/// assert_eq!(key.index, 0x6040);
/// // As a PDO mapping entry of 16 bits, and back.
/// assert_eq!(key.mapping_word(16), 0x6040_0010);
/// assert_eq!(ObjectKey::from_mapping_word(0x6099_0220), ObjectKey::new(0x6099, 2));
/// assert_eq!(ObjectKey::new(0x6099, 2).to_string(), "0x6099:02");
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ObjectKey {
    /// Object index.
    pub index: u16,
    /// Sub-index (0 for a variable).
    pub sub: u8,
}

impl ObjectKey {
    /// `index:sub`.
    pub const fn new(index: u16, sub: u8) -> Self {
        Self { index, sub }
    }

    /// The mapping-entry form of ETG.1000.6 (index << 16 | sub << 8 | bit length),
    /// as PDO mapping objects and the scope's channel list hold it.
    pub const fn mapping_word(self, bits: u8) -> u32 {
        (self.index as u32) << 16 | (self.sub as u32) << 8 | bits as u32
    }

    /// The key of a mapping word (its low byte, the bit length, is dropped).
    pub const fn from_mapping_word(word: u32) -> Self {
        Self::new((word >> 16) as u16, (word >> 8) as u8)
    }
}

impl core::fmt::Display for ObjectKey {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "0x{:04X}:{:02X}", self.index, self.sub)
    }
}
