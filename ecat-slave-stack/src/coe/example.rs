//! A small example object dictionary: the reference for implementing [`Dictionary`],
//! and the dictionary of the CoE tests, the mailbox fuzz test and the benchmarks.
//!
//! It holds one object of every kind the SDO server has to handle: read-only and
//! write-only entries, Pre-Op-only entries, visible strings (one longer than a 128-byte
//! mailbox), a RECORD with bit-sized entries, an ARRAY, a PDO-mapping-like object that
//! needs sub-index 0 set to 0 before its entries are written, and an "abort injector"
//! (0x2FFF) whose write answers with the abort code written (to test that every
//! application abort reaches the master unchanged).

use crate::esm::EsmState;
use crate::od::{
    self, Access, DataType, DefaultValue, Dictionary, EntryDesc, Object, ObjectDesc, ObjectKey,
    PdoMappable, SdoAbort,
};

const U8: DataType = DataType::Unsigned8;
const U16: DataType = DataType::Unsigned16;
const U32: DataType = DataType::Unsigned32;

/// Maximum length of the long string 0x2002.
pub const LONG_TEXT_MAX: usize = 300;
/// Initial value of 0x1008.
pub const DEVICE_NAME: &str = "CoE example device";

/// The objects, sorted: [`SOURCE`] packed as an application's dictionary is
/// (`od::pack`), so every CoE test and the mailbox fuzz read packed names.
pub static OBJECTS: &[Object] = crate::packed_dictionary!(&[SOURCE]);

/// The objects as written (plain names, one entry table per object).
pub const SOURCE: &[ObjectDesc] = &[
    ObjectDesc::var(
        0x1000,
        "Device type",
        &[EntryDesc::new(0, "Device type", U32, Access::RO).default(0x0002_0192)],
        "CiA 402 servo drive.",
    ),
    ObjectDesc::var(
        0x1001,
        "Error register",
        &[EntryDesc::new(0, "Error register", U8, Access::RO).pdo(PdoMappable::Tx)],
        "",
    ),
    ObjectDesc::var(
        0x1008,
        "Manufacturer device name",
        &[EntryDesc::text(
            0,
            "Manufacturer device name",
            32,
            DEVICE_NAME,
        )],
        "",
    ),
    ObjectDesc::record(
        0x1018,
        "Identity",
        &[
            EntryDesc::new(0, "Number of entries", U8, Access::RO).default(4),
            EntryDesc::new(1, "Vendor ID", U32, Access::RO).default(0x0E5C),
            EntryDesc::new(2, "Product code", U32, Access::RO).default(0x5840),
            EntryDesc::new(3, "Revision", U32, Access::RO).default(0x0001_0000),
            EntryDesc::new(4, "Serial number", U32, Access::RO).default(0x1234_5678),
        ],
        "",
    ),
    ObjectDesc::array(
        0x1600,
        "RxPDO mapping",
        &[
            EntryDesc::new(0, "Number of entries", U8, Access::RW_PREOP)
                .range(0, 4)
                .default(2),
            EntryDesc::new(1, "Entry 1", U32, Access::RW_PREOP).default(0x6040_0010),
            EntryDesc::new(2, "Entry 2", U32, Access::RW_PREOP).default(0x607A_0020),
            EntryDesc::new(3, "Entry 3", U32, Access::RW_PREOP),
            EntryDesc::new(4, "Entry 4", U32, Access::RW_PREOP),
        ],
        "Sub-index 0 must be 0 while entries are written.",
    ),
    ObjectDesc::array(
        0x1C12,
        "RxPDO assign",
        &[
            EntryDesc::new(0, "Number of entries", U8, Access::RW_PREOP)
                .range(0, 2)
                .default(1),
            EntryDesc::new(1, "PDO 1", U16, Access::RW_PREOP).default(0x1600),
            EntryDesc::new(2, "PDO 2", U16, Access::RW_PREOP),
        ],
        "",
    ),
    ObjectDesc::var(
        0x2000,
        "Current limit",
        &[
            EntryDesc::new(0, "Current limit", DataType::Integer32, Access::RW)
                .range(-1000, 1000)
                .default(100)
                .unit("mA")
                .saved()
                .pdo(PdoMappable::RxTx),
        ],
        "",
    ),
    ObjectDesc::var(
        0x2001,
        "Command",
        &[EntryDesc::new(0, "Command", U16, Access::WO)],
        "Write-only.",
    ),
    ObjectDesc::var(
        0x2002,
        "Long text",
        &[EntryDesc::text(0, "Long text", LONG_TEXT_MAX as u16, "").with_access(Access::RW)],
        "",
    ),
    ObjectDesc::record(
        0x2003,
        "Mixed record",
        &[
            EntryDesc::new(0, "Number of entries", U8, Access::RO).default(5),
            EntryDesc::new(1, "Flag A", DataType::Boolean, Access::RW),
            EntryDesc::new(2, "Field B", DataType::Bit2, Access::RW),
            EntryDesc::new(3, "Byte C", U8, Access::RW_PREOP)
                .range(0, 200)
                .saved(),
            EntryDesc::new(4, "Word D", DataType::Integer16, Access::RO).default(-2),
            EntryDesc::new(5, "Secret E", U32, Access::WO),
        ],
        "Bit-sized, read-only, write-only and Pre-Op-only entries.",
    ),
    ObjectDesc::array(
        0x2004,
        "Byte table",
        &[
            EntryDesc::new(0, "Number of entries", U8, Access::RO).default(40),
            EntryDesc::new(1, "B1", U8, Access::RW),
            EntryDesc::new(2, "B2", U8, Access::RW),
            EntryDesc::new(3, "B3", U8, Access::RW),
            EntryDesc::new(4, "B4", U8, Access::RW),
            EntryDesc::new(5, "B5", U8, Access::RW),
            EntryDesc::new(6, "B6", U8, Access::RW),
            EntryDesc::new(7, "B7", U8, Access::RW),
            EntryDesc::new(8, "B8", U8, Access::RW),
            EntryDesc::new(9, "B9", U8, Access::RW),
            EntryDesc::new(10, "B10", U8, Access::RW),
            EntryDesc::new(11, "B11", U8, Access::RW),
            EntryDesc::new(12, "B12", U8, Access::RW),
            EntryDesc::new(13, "B13", U8, Access::RW),
            EntryDesc::new(14, "B14", U8, Access::RW),
            EntryDesc::new(15, "B15", U8, Access::RW),
            EntryDesc::new(16, "B16", U8, Access::RW),
            EntryDesc::new(17, "B17", U8, Access::RW),
            EntryDesc::new(18, "B18", U8, Access::RW),
            EntryDesc::new(19, "B19", U8, Access::RW),
            EntryDesc::new(20, "B20", U8, Access::RW),
            EntryDesc::new(21, "B21", U8, Access::RW),
            EntryDesc::new(22, "B22", U8, Access::RW),
            EntryDesc::new(23, "B23", U8, Access::RW),
            EntryDesc::new(24, "B24", U8, Access::RW),
            EntryDesc::new(25, "B25", U8, Access::RW),
            EntryDesc::new(26, "B26", U8, Access::RW),
            EntryDesc::new(27, "B27", U8, Access::RW),
            EntryDesc::new(28, "B28", U8, Access::RW),
            EntryDesc::new(29, "B29", U8, Access::RW),
            EntryDesc::new(30, "B30", U8, Access::RW),
            EntryDesc::new(31, "B31", U8, Access::RW),
            EntryDesc::new(32, "B32", U8, Access::RW),
            EntryDesc::new(33, "B33", U8, Access::RW),
            EntryDesc::new(34, "B34", U8, Access::RW),
            EntryDesc::new(35, "B35", U8, Access::RW),
            EntryDesc::new(36, "B36", U8, Access::RW),
            EntryDesc::new(37, "B37", U8, Access::RW),
            EntryDesc::new(38, "B38", U8, Access::RW),
            EntryDesc::new(39, "B39", U8, Access::RW),
            EntryDesc::new(40, "B40", U8, Access::RW),
        ],
        "",
    ),
    ObjectDesc::record(
        0x2005,
        "Record with text",
        &[
            EntryDesc::new(0, "Number of entries", U8, Access::RO).default(2),
            EntryDesc::new(1, "Value", U16, Access::RW),
            EntryDesc::text(2, "Label", 8, "label"),
        ],
        "Complete access is refused (variable length).",
    ),
    ObjectDesc::var(
        0x2FFF,
        "Abort injector",
        &[EntryDesc::new(0, "Abort injector", U32, Access::RW)],
        "A write answers with the abort code written (0: accepted).",
    ),
    ObjectDesc::var(
        0x6040,
        "Controlword",
        &[EntryDesc::new(0, "Controlword", U16, Access::RW).pdo(PdoMappable::Rx)],
        "",
    ),
    ObjectDesc::var(
        0x6041,
        "Statusword",
        &[EntryDesc::new(0, "Statusword", U16, Access::RO).pdo(PdoMappable::Tx)],
        "",
    ),
    ObjectDesc::var(
        0x607A,
        "Target position",
        &[
            EntryDesc::new(0, "Target position", DataType::Integer32, Access::RW)
                .unit("inc")
                .pdo(PdoMappable::Rx)
                .saved(),
        ],
        "",
    ),
];

const SLOTS: usize = 80;

/// The values of [`OBJECTS`].
pub struct ExampleDictionary {
    values: [u64; SLOTS],
    text: [u8; LONG_TEXT_MAX],
    text_len: usize,
    /// Number of successful writes (tests check all-or-nothing behaviour with it).
    pub writes: u32,
}

impl Default for ExampleDictionary {
    fn default() -> Self {
        Self::new()
    }
}

fn slot(key: ObjectKey) -> Option<usize> {
    let mut n = 0;
    for o in OBJECTS {
        for e in o.entries() {
            if ObjectKey::new(o.index, e.sub) == key {
                return (n < SLOTS).then_some(n);
            }
            n += 1;
        }
    }
    None
}

impl ExampleDictionary {
    /// All values at their defaults.
    pub fn new() -> Self {
        let mut d = ExampleDictionary {
            values: [0; SLOTS],
            text: [0; LONG_TEXT_MAX],
            text_len: 0,
            writes: 0,
        };
        for o in OBJECTS {
            for e in o.entries() {
                if let (DefaultValue::Int(v), Some(s)) =
                    (e.default_value(), slot(ObjectKey::new(o.index, e.sub)))
                {
                    d.values[s] = v as u64;
                }
            }
        }
        d
    }

    /// The raw value of a numeric entry (0 for unknown entries).
    pub fn value(&self, key: ObjectKey) -> u64 {
        slot(key).map_or(0, |s| self.values[s])
    }

    /// Sets a numeric value directly (as the application would).
    pub fn set_value(&mut self, key: ObjectKey, v: u64) {
        if let Some(s) = slot(key) {
            self.values[s] = v;
        }
    }

    /// The long text 0x2002.
    pub fn long_text(&self) -> &[u8] {
        &self.text[..self.text_len]
    }
}

impl Dictionary for ExampleDictionary {
    fn objects(&self) -> &'static [Object] {
        OBJECTS
    }

    fn read(&mut self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        let e = od::find_entry(OBJECTS, key)?;
        let src: &[u8] = match (key.index, e.default_value()) {
            (0x2002, _) => &self.text[..self.text_len],
            (_, DefaultValue::Text(t)) => t.as_bytes(),
            _ => {
                let s = slot(key).ok_or(SdoAbort::GeneralError)?;
                let bytes = self.values[s].to_le_bytes();
                let n = e.byte_len().min(8);
                let dst = buf.get_mut(..n).ok_or(SdoAbort::OutOfMemory)?;
                dst.copy_from_slice(&bytes[..n]);
                return Ok(n);
            }
        };
        let dst = buf.get_mut(..src.len()).ok_or(SdoAbort::OutOfMemory)?;
        dst.copy_from_slice(src);
        Ok(src.len())
    }

    fn write(&mut self, key: ObjectKey, data: &[u8], _state: EsmState) -> Result<(), SdoAbort> {
        match key.index {
            0x2002 => {
                let dst = self
                    .text
                    .get_mut(..data.len())
                    .ok_or(SdoAbort::LengthTooHigh)?;
                dst.copy_from_slice(data);
                self.text_len = data.len();
            }
            0x2FFF => {
                let mut b = [0u8; 4];
                let n = data.len().min(4);
                b[..n].copy_from_slice(&data[..n]);
                let code = u32::from_le_bytes(b);
                if code != 0 {
                    return Err(SdoAbort::from_code(code).unwrap_or(SdoAbort::GeneralError));
                }
            }
            _ => {
                // PDO mapping rule: entries only while sub-index 0 is 0.
                if key.index == 0x1600 && key.sub != 0 && self.value(ObjectKey::new(0x1600, 0)) != 0
                {
                    return Err(SdoAbort::SubindexZeroFirst);
                }
                let s = slot(key).ok_or(SdoAbort::SubindexDoesNotExist)?;
                let mut b = [0u8; 8];
                let n = data.len().min(8);
                b[..n].copy_from_slice(&data[..n]);
                self.values[s] = u64::from_le_bytes(b);
            }
        }
        self.writes += 1;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn example_dictionary_is_well_formed() {
        assert!(od::is_well_formed(OBJECTS));
        let n: usize = OBJECTS.iter().map(|o| o.entries().len()).sum();
        assert!(n <= SLOTS);
        let mut d = ExampleDictionary::new();
        let mut b = [0u8; 64];
        assert_eq!(
            d.read(ObjectKey::new(0x1008, 0), &mut b),
            Ok(DEVICE_NAME.len())
        );
        assert_eq!(d.read(ObjectKey::new(0x2003, 4), &mut b), Ok(2));
        assert_eq!(i16::from_le_bytes([b[0], b[1]]), -2);
        assert_eq!(
            d.read(ObjectKey::new(0x1600, 9), &mut b),
            Err(SdoAbort::SubindexDoesNotExist)
        );
    }
}
