//! Building an SII image from a [`DeviceDescription`]: the string table, the fixed
//! words and the categories.

use super::*;
use crate::esi::{self, PdoEntry, PdoMap};
use crate::od::{Name, Object};

/// Up to this many distinct strings.
const MAX_STRINGS: usize = 80;

/// The string table: distinct non-empty strings in order of first use.
struct Strings {
    list: [Name; MAX_STRINGS],
    n: usize,
}

impl Strings {
    fn new() -> Self {
        Strings {
            list: [Name::plain(""); MAX_STRINGS],
            n: 0,
        }
    }
    fn add(&mut self, s: Name) -> Result<(), SiiError> {
        if s.is_empty() || self.list[..self.n].contains(&s) {
            return Ok(());
        }
        if s.len() > 255 || self.n >= MAX_STRINGS {
            return Err(SiiError::StringTable);
        }
        self.list[self.n] = s;
        self.n += 1;
        Ok(())
    }
    /// 1-based index, 0 for the empty string.
    fn index(&self, s: Name) -> u8 {
        self.list[..self.n]
            .iter()
            .position(|x| *x == s)
            .map_or(0, |i| i as u8 + 1)
    }
    fn of(desc: &DeviceDescription, objects: &[Object], pdos: &[PdoMap]) -> Result<Self, SiiError> {
        let mut t = Strings::new();
        for s in [
            desc.name,
            desc.type_name,
            desc.group_type,
            desc.hardware_version,
            desc.software_version,
        ] {
            t.add(Name::plain(s))?;
        }
        for m in desc.dc_op_modes {
            t.add(Name::plain(m.name))?;
            t.add(Name::plain(m.description))?;
        }
        for p in pdos {
            t.add(p.name)?;
            for e in p.entries.iter().map(|v| PdoEntry::decode(*v)) {
                if let Some((name, _)) = esi::pdo_entry_name(objects, e) {
                    t.add(name)?;
                }
            }
        }
        Ok(t)
    }
}

/// Writes categories into a buffer, word-aligned, with bounds checks.
struct Writer<'a> {
    out: &'a mut [u8],
    pos: usize,
}

impl Writer<'_> {
    fn bytes(&mut self, b: &[u8]) -> Result<(), SiiError> {
        let end = self.pos + b.len();
        self.out
            .get_mut(self.pos..end)
            .ok_or(SiiError::BufferTooSmall)?
            .copy_from_slice(b);
        self.pos = end;
        Ok(())
    }
    fn u16(&mut self, v: u16) -> Result<(), SiiError> {
        self.bytes(&v.to_le_bytes())
    }
    fn u32(&mut self, v: u32) -> Result<(), SiiError> {
        self.bytes(&v.to_le_bytes())
    }
    fn pad(&mut self) -> Result<(), SiiError> {
        if self.pos % 2 == 1 {
            self.bytes(&[0])?;
        }
        Ok(())
    }
    /// Starts a category; returns the position of its size word.
    fn begin(&mut self, kind: u16) -> Result<usize, SiiError> {
        self.u16(kind)?;
        let at = self.pos;
        self.u16(0)?;
        Ok(at)
    }
    /// Pads the category to a word and fills in its size.
    fn end(&mut self, size_at: usize) -> Result<(), SiiError> {
        self.pad()?;
        let words = ((self.pos - size_at - 2) / 2) as u16;
        self.out[size_at..size_at + 2].copy_from_slice(&words.to_le_bytes());
        Ok(())
    }
}

/// Builds the SII image of `desc` into `out` without PDO categories (see
/// [`build_with_pdos`]) and returns its length in bytes (the end marker included).
/// The rest of the EEPROM should read 0xFF.
pub fn build(desc: &DeviceDescription, out: &mut [u8]) -> Result<usize, SiiError> {
    build_with_pdos(desc, &[], &[], out)
}

/// Writes one PDO category (TxPDO or RxPDO): per PDO an 8-byte header (index, entry
/// count, SyncManager of the default assignment or 0xFF, DC sync 0, name string,
/// flags: 0x0001 mandatory, 0x0010 fixed content), then 8 bytes per entry (index,
/// sub-index, name string, CoE data type, bit length, flags 0).
fn pdo_category(
    w: &mut Writer<'_>,
    kind: u16,
    strings: &Strings,
    objects: &[Object],
    pdos: &[PdoMap],
) -> Result<(), SiiError> {
    let rx = kind == category::RXPDO;
    let mut list = pdos
        .iter()
        .filter(|p| p.is_rx() == rx && p.is_rx() != p.is_tx());
    if list.clone().next().is_none() {
        return Ok(());
    }
    let at = w.begin(kind)?;
    for p in list.by_ref() {
        let n = u8::try_from(p.entries.len()).map_err(|_| SiiError::InvalidDescription)?;
        w.u16(p.index)?;
        let flags = (p.mandatory as u16) | (p.fixed as u16) << 4;
        w.bytes(&[n, p.sm.unwrap_or(0xFF), 0, strings.index(p.name)])?;
        w.u16(flags)?;
        for e in p.entries.iter().map(|v| PdoEntry::decode(*v)) {
            let (name, ty) = match esi::pdo_entry_name(objects, e) {
                Some((name, entry)) => (strings.index(name), entry.data_type.code() as u8),
                None => (0, 0),
            };
            w.u16(e.key.index)?;
            w.bytes(&[e.key.sub, name, ty, e.bits])?;
            w.u16(0)?;
        }
    }
    w.end(at)
}

/// Builds the SII image of `desc` into `out`, with the PDO categories (TxPDO 0x32,
/// RxPDO 0x33) of `pdos` — the list the ESI's `RxPdo`/`TxPdo` are written from
/// ([`esi::pdo_maps`]), entry names and data types from `objects` as in the ESI —
/// and returns its length in bytes (the end marker included). The rest of the
/// EEPROM should read 0xFF.
pub fn build_with_pdos(
    desc: &DeviceDescription,
    objects: &[Object],
    pdos: &[PdoMap],
    out: &mut [u8],
) -> Result<usize, SiiError> {
    desc.validate()?;
    let strings = Strings::of(desc, objects, pdos)?;
    let header_len = word::CATEGORIES * 2;
    out.get_mut(..header_len)
        .ok_or(SiiError::BufferTooSmall)?
        .fill(0);
    let mut w = Writer { out, pos: 0 };
    fixed_area(&mut w, desc)?;
    strings_category(&mut w, &strings)?;
    general_category(&mut w, desc, &strings)?;
    layout_categories(&mut w, desc, &strings)?;
    pdo_category(&mut w, category::TXPDO, &strings, objects, pdos)?;
    pdo_category(&mut w, category::RXPDO, &strings, objects, pdos)?;

    w.u16(category::END)?;
    if w.pos > desc.eeprom_bytes as usize {
        return Err(SiiError::EepromTooSmall);
    }
    let len = w.pos;
    if let Some(boot) = &desc.bootstrap {
        set_bootstrap_mailbox(out, boot)?;
    }
    Ok(len)
}

/// Words 0x00–0x3F: ESC configuration area, identity, mailbox offsets and sizes,
/// protocols, EEPROM size and version (the bootstrap words stay 0 here).
fn fixed_area(w: &mut Writer<'_>, desc: &DeviceDescription) -> Result<(), SiiError> {
    w.bytes(&desc.config_area())?;
    for v in [
        desc.vendor_id,
        desc.product_code,
        desc.revision,
        desc.serial,
    ] {
        w.u32(v)?;
    }
    // 0x10-0x13 reserved and 0x14-0x17 bootstrap mailbox: zero (no Bootstrap).
    w.pos = word::MBX_RX_OFFSET * 2;
    let (_, rx) = desc
        .sync_manager(SmType::MailboxOut)
        .ok_or(SiiError::MissingMailbox)?;
    let (_, tx) = desc
        .sync_manager(SmType::MailboxIn)
        .ok_or(SiiError::MissingMailbox)?;
    for v in [
        rx.start,
        rx.default_size,
        tx.start,
        tx.default_size,
        desc.mailbox_protocols,
    ] {
        w.u16(v)?;
    }
    w.pos = word::SIZE * 2;
    w.u16(desc.eeprom_bytes / 128 - 1)?;
    w.u16(1)?;
    Ok(())
}

/// The STRINGS category: count, then each string with its length byte.
fn strings_category(w: &mut Writer<'_>, strings: &Strings) -> Result<(), SiiError> {
    let at = w.begin(category::STRINGS)?;
    w.bytes(&[strings.n as u8])?;
    for s in &strings.list[..strings.n] {
        w.bytes(&[s.len() as u8])?;
        for b in s.bytes() {
            w.bytes(&[b])?;
        }
    }
    w.end(at)?;
    Ok(())
}

/// The GENERAL category, exactly 32 bytes.
fn general_category(
    w: &mut Writer<'_>,
    desc: &DeviceDescription,
    strings: &Strings,
) -> Result<(), SiiError> {
    let at = w.begin(category::GENERAL)?;
    let group = strings.index(Name::plain(desc.group_type));
    let mut g = [0u8; 32];
    g[0] = group;
    g[1] = 0; // image
    g[2] = strings.index(Name::plain(desc.type_name));
    g[3] = strings.index(Name::plain(desc.name));
    g[5] = desc.coe.bits();
    g[6] = (desc.mailbox_protocols & MBOX_FOE != 0) as u8;
    g[0x0B] = (desc.mailbox_data_link_layer as u8) << 2;
    g[0x0C..0x0E].copy_from_slice(&desc.ebus_current_ma.to_le_bytes());
    g[0x0E] = group;
    g[0x10..0x12].copy_from_slice(&desc.physical_ports.to_le_bytes());
    w.bytes(&g)?;
    w.end(at)?;
    Ok(())
}

/// The FMMU, SYNC_MANAGER and (with DC op modes) DC categories.
fn layout_categories(
    w: &mut Writer<'_>,
    desc: &DeviceDescription,
    strings: &Strings,
) -> Result<(), SiiError> {
    // FMMU usage.
    let at = w.begin(category::FMMU)?;
    for f in desc.fmmus {
        w.bytes(&[*f as u8])?;
    }
    w.end(at)?;

    // SyncManagers.
    let at = w.begin(category::SYNC_MANAGER)?;
    for sm in desc.sync_managers {
        w.u16(sm.start)?;
        w.u16(sm.default_size)?;
        w.bytes(&[sm.control, 0, sm.enable as u8, sm.kind as u8])?;
    }
    w.end(at)?;

    // Distributed clocks.
    if !desc.dc_op_modes.is_empty() {
        let at = w.begin(category::DC)?;
        for m in desc.dc_op_modes {
            w.u32(m.cycle_time_sync0)?;
            w.u32(m.shift_time_sync0)?;
            w.u32(m.shift_time_sync1)?;
            w.bytes(&m.sync1_factor.to_le_bytes())?;
            w.u16(m.assign_activate)?;
            w.bytes(&m.sync0_factor.to_le_bytes())?;
            w.bytes(&[
                strings.index(Name::plain(m.name)),
                strings.index(Name::plain(m.description)),
                0,
                0,
                0,
                0,
            ])?;
        }
        w.end(at)?;
    }
    Ok(())
}

/// Writes the bootstrap mailbox (words 0x14–0x17, outside the checksummed area) into
/// a built image; `image` must hold at least the fixed part (0x40 words).
pub fn set_bootstrap_mailbox(
    image: &mut [u8],
    boot: &crate::sm::BootMailbox,
) -> Result<(), SiiError> {
    let at = word::BOOT_RX_OFFSET * 2;
    let dst = image.get_mut(at..at + 8).ok_or(SiiError::BufferTooSmall)?;
    for (d, w) in dst.chunks_exact_mut(2).zip(boot.sii_words()) {
        d.copy_from_slice(&w.to_le_bytes());
    }
    Ok(())
}
