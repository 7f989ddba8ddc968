//! Reading an SII image: the fixed words and the categories.

use super::*;

/// A panic-free view of an SII image (any bytes: missing parts read as `None`).
#[derive(Debug, Clone, Copy)]
pub struct Sii<'a> {
    data: &'a [u8],
}

/// One category: its type and data (size × 2 bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Category<'a> {
    /// Category type.
    pub kind: u16,
    /// Data.
    pub data: &'a [u8],
}

/// Iterator over the categories from word 0x40 to the end marker; stops at the end
/// marker, at a truncated header and at a category running past the image.
#[derive(Debug, Clone)]
pub struct Categories<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Iterator for Categories<'a> {
    type Item = Category<'a>;
    fn next(&mut self) -> Option<Category<'a>> {
        let h = self.data.get(self.pos..self.pos.checked_add(4)?)?;
        let kind = u16::from_le_bytes([h[0], h[1]]);
        if kind == category::END {
            return None;
        }
        let len = u16::from_le_bytes([h[2], h[3]]) as usize * 2;
        let start = self.pos + 4;
        let data = self.data.get(start..start + len)?;
        self.pos = start + len;
        Some(Category { kind, data })
    }
}

/// The general category, decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct General {
    /// Group string index.
    pub group: u8,
    /// Image string index.
    pub image: u8,
    /// Order string index.
    pub order: u8,
    /// Name string index.
    pub name: u8,
    /// CoE details.
    pub coe_details: u8,
    /// FoE details.
    pub foe_details: u8,
    /// EoE details.
    pub eoe_details: u8,
    /// Flags byte (b2 mailbox data-link layer).
    pub flags: u8,
    /// E-bus current, mA.
    pub ebus_current_ma: i16,
    /// Group index duplicate.
    pub group2: u8,
    /// Physical ports.
    pub physical_ports: u16,
}

/// One SyncManager record of category 41.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SmRecord {
    /// Start address.
    pub start: u16,
    /// Length.
    pub length: u16,
    /// Control byte.
    pub control: u8,
    /// Status byte (0).
    pub status: u8,
    /// Enable flags (b0 enable).
    pub enable: u8,
    /// Type (1-4).
    pub kind: u8,
}

/// One op-mode record of category 60.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DcRecord {
    /// SYNC0 cycle time, ns.
    pub cycle_time_sync0: u32,
    /// SYNC0 shift, ns.
    pub shift_time_sync0: u32,
    /// SYNC1 shift, ns.
    pub shift_time_sync1: u32,
    /// SYNC1 cycle factor.
    pub sync1_factor: i16,
    /// AssignActivate.
    pub assign_activate: u16,
    /// SYNC0 cycle factor.
    pub sync0_factor: i16,
    /// Name string index.
    pub name: u8,
    /// Description string index.
    pub description: u8,
}

impl<'a> Sii<'a> {
    /// Views `data` as an SII image.
    pub const fn new(data: &'a [u8]) -> Self {
        Sii { data }
    }
    /// Word `i`.
    pub fn word(&self, i: usize) -> Option<u16> {
        let at = i.checked_mul(2)?;
        let b = self.data.get(at..at.checked_add(2)?)?;
        Some(u16::from_le_bytes([b[0], b[1]]))
    }
    /// Two words starting at `i` as a u32.
    pub fn dword(&self, i: usize) -> Option<u32> {
        Some(self.word(i)? as u32 | (self.word(i + 1)? as u32) << 16)
    }
    /// True when word 7's low byte is the CRC-8 of bytes 0-13.
    pub fn checksum_ok(&self) -> bool {
        match (self.data.get(..14), self.word(word::CHECKSUM)) {
            (Some(b), Some(w)) => w & 0xFF == crc8(b) as u16,
            _ => false,
        }
    }
    /// Vendor ID.
    pub fn vendor_id(&self) -> Option<u32> {
        self.dword(word::VENDOR_ID)
    }
    /// Product code.
    pub fn product_code(&self) -> Option<u32> {
        self.dword(word::PRODUCT_CODE)
    }
    /// Revision.
    pub fn revision(&self) -> Option<u32> {
        self.dword(word::REVISION)
    }
    /// Serial number.
    pub fn serial(&self) -> Option<u32> {
        self.dword(word::SERIAL)
    }
    /// The bootstrap mailbox of words 0x14–0x17 (`None`: all zero, Bootstrap not
    /// supported, or the image is too short).
    pub fn bootstrap_mailbox(&self) -> Option<crate::sm::BootMailbox> {
        let w = |i| self.word(word::BOOT_RX_OFFSET + i);
        let b = crate::sm::BootMailbox {
            rx_start: w(0)?,
            rx_len: w(1)?,
            tx_start: w(2)?,
            tx_len: w(3)?,
        };
        (b.sii_words() != [0; 4]).then_some(b)
    }
    /// The categories.
    pub fn categories(&self) -> Categories<'a> {
        Categories {
            data: self.data,
            pos: word::CATEGORIES * 2,
        }
    }
    /// The first category of `kind`.
    pub fn find(&self, kind: u16) -> Option<&'a [u8]> {
        self.categories().find(|c| c.kind == kind).map(|c| c.data)
    }
    /// String `index` (1-based) of the strings category; `None` for 0, a missing
    /// string or one that is not UTF-8.
    pub fn string(&self, index: u8) -> Option<&'a str> {
        let d = self.find(category::STRINGS)?;
        let count = *d.first()?;
        if index == 0 || index > count {
            return None;
        }
        let mut pos = 1usize;
        for i in 1..=count {
            let len = *d.get(pos)? as usize;
            let s = d.get(pos + 1..pos + 1 + len)?;
            if i == index {
                return core::str::from_utf8(s).ok();
            }
            pos += 1 + len;
        }
        None
    }
    /// Number of strings.
    pub fn string_count(&self) -> u8 {
        self.find(category::STRINGS)
            .and_then(|d| d.first().copied())
            .unwrap_or(0)
    }
    /// The general category (must be 32 bytes).
    pub fn general(&self) -> Option<General> {
        let g = self.find(category::GENERAL)?;
        if g.len() != 32 {
            return None;
        }
        Some(General {
            group: g[0],
            image: g[1],
            order: g[2],
            name: g[3],
            coe_details: g[5],
            foe_details: g[6],
            eoe_details: g[7],
            flags: g[0x0B],
            ebus_current_ma: i16::from_le_bytes([g[0x0C], g[0x0D]]),
            group2: g[0x0E],
            physical_ports: u16::from_le_bytes([g[0x10], g[0x11]]),
        })
    }
    /// FMMU usage bytes (including a pad byte, if any).
    pub fn fmmus(&self) -> &'a [u8] {
        self.find(category::FMMU).unwrap_or(&[])
    }
    /// SyncManager record `n`.
    pub fn sync_manager(&self, n: usize) -> Option<SmRecord> {
        let d = self.find(category::SYNC_MANAGER)?;
        let at = n.checked_mul(8)?;
        let r = d.get(at..at.checked_add(8)?)?;
        Some(SmRecord {
            start: u16::from_le_bytes([r[0], r[1]]),
            length: u16::from_le_bytes([r[2], r[3]]),
            control: r[4],
            status: r[5],
            enable: r[6],
            kind: r[7],
        })
    }
    /// Number of SyncManager records.
    pub fn sync_manager_count(&self) -> usize {
        self.find(category::SYNC_MANAGER).map_or(0, |d| d.len() / 8)
    }
    /// DC op-mode record `n`.
    pub fn dc_op_mode(&self, n: usize) -> Option<DcRecord> {
        let d = self.find(category::DC)?;
        let at = n.checked_mul(24)?;
        let r = d.get(at..at.checked_add(24)?)?;
        let u32_at = |i: usize| u32::from_le_bytes([r[i], r[i + 1], r[i + 2], r[i + 3]]);
        Some(DcRecord {
            cycle_time_sync0: u32_at(0),
            shift_time_sync0: u32_at(4),
            shift_time_sync1: u32_at(8),
            sync1_factor: i16::from_le_bytes([r[12], r[13]]),
            assign_activate: u16::from_le_bytes([r[14], r[15]]),
            sync0_factor: i16::from_le_bytes([r[16], r[17]]),
            name: r[18],
            description: r[19],
        })
    }
    /// Number of DC op-mode records.
    pub fn dc_op_mode_count(&self) -> usize {
        self.find(category::DC).map_or(0, |d| d.len() / 24)
    }
}
