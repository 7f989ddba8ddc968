//! ESI (EtherCAT Slave Information, ETG.2000) XML from the device description and
//! the object dictionary.
//!
//! [`write()`] emits one `EtherCATInfo` document for one device:
//! `Vendor`, `Descriptions/Groups`, `Descriptions/Devices/Device` with `Type`
//! (ProductCode, RevisionNo), `Name`, `GroupType`, `Profile` (ProfileNo and the whole
//! `Dictionary`: `DataTypes` for every base type, string length, array and record
//! used, and one `Object` per entry of the object table passed in — index, name,
//! type, bit size, default data, access, PDO mapping), `Fmmu`, `Sm`, `RxPdo`/`TxPdo`
//! (default mappings, entry names and types looked up in the object table; `Sm` only
//! on the PDOs assigned by default, `Exclude` between PDOs that map a common object),
//! `Mailbox`
//! (CoE flags from the same [`CoeDetails`](crate::sii::CoeDetails) as the SII general
//! category), `Dc` op modes and `Eeprom` (ByteSize and ConfigData = SII words 0-6).
//!
//! No heap: the document is streamed into any [`core::fmt::Write`]. Every text is
//! XML-escaped. Before writing, the PDO maps are checked against the object table
//! (entry exists, is mappable in the PDO's direction, bit length matches), so the ESI
//! cannot promise a mapping the SDO server would refuse.
//!
//! Records and arrays are described as a `DataType` named `DT<index>` with one
//! `SubItem` per entry; sub-index 0 occupies bits 0-7, the next entry starts at bit 16
//! and the following ones are packed in order (the usual ETG layout).

use core::fmt::{self, Write};

use crate::diag::DiagText;
use crate::od::{
    Access, DataType, DefaultValue, Entry, Name, Object, ObjectCode, ObjectKey, PdoMappable,
};
use crate::sii::{DeviceDescription, SiiError, SmType};

mod dictionary;
use dictionary::{write_data_types, write_objects, Hex, TypeName};

/// One entry of a PDO mapping (index 0 = padding of `bits` bits), decoded from the
/// 32-bit value a mapping object holds (`index << 16 | sub << 8 | bits`, the
/// encoding of [`ObjectKey::mapping_word`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PdoEntry {
    /// The mapped entry (index 0 for a gap).
    pub key: ObjectKey,
    /// Length in bits.
    pub bits: u8,
}

impl PdoEntry {
    /// Decodes a mapping-object value.
    pub const fn decode(v: u32) -> Self {
        PdoEntry {
            key: ObjectKey::from_mapping_word(v),
            bits: v as u8,
        }
    }
    /// The mapping-object value.
    pub const fn encode(self) -> u32 {
        self.key.mapping_word(self.bits)
    }
}

/// A default PDO: mapping object index (0x1600-0x17FF RxPDO, 0x1A00-0x1BFF TxPDO),
/// its entries and the SyncManager it is assigned to by default.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PdoMap {
    /// Mapping object index.
    pub index: u16,
    /// Name.
    pub name: Name,
    /// SyncManager it is assigned to by default (None: selectable, not assigned).
    pub sm: Option<u8>,
    /// The mapping cannot be changed.
    pub fixed: bool,
    /// Must always be assigned.
    pub mandatory: bool,
    /// Entries in order, encoded as in the mapping objects (`index << 16 | sub << 8 |
    /// bits`, see [`ObjectKey::mapping_word`]).
    pub entries: &'static [u32],
}

impl PdoMap {
    /// True for an RxPDO (outputs of the master).
    pub const fn is_rx(&self) -> bool {
        self.index >= 0x1600 && self.index <= 0x17FF
    }
    /// True for a TxPDO (inputs of the master).
    pub const fn is_tx(&self) -> bool {
        self.index >= 0x1A00 && self.index <= 0x1BFF
    }
}

/// The default PDOs of the stack's PDO defaults (`crate::pdo::PdoDefaults`): every
/// non-empty or assigned mapping object 0x1600-0x1603 / 0x1A00-0x1A03, named after
/// its object in `objects`, assigned to the device's outputs / inputs SyncManager when
/// 0x1C12 / 0x1C13 list it. Mapping objects are configurable (not `Fixed`: the SDO
/// server takes a new mapping in Pre-Op) and none is `Mandatory` (a master may assign
/// an alternative instead of the default).
pub fn pdo_maps(
    desc: &DeviceDescription,
    objects: &[Object],
    defaults: &crate::pdo::PdoDefaults,
) -> heapless::Vec<PdoMap, { 2 * crate::pdo::MAPS }> {
    let mut out = heapless::Vec::new();
    let sm_of = |kind| desc.sync_manager(kind).map(|(n, _)| n);
    let dirs = [
        (
            crate::pdo::RX_MAP_BASE,
            &defaults.rx,
            defaults.rx_assign,
            sm_of(SmType::Outputs),
            "RxPDO",
        ),
        (
            crate::pdo::TX_MAP_BASE,
            &defaults.tx,
            defaults.tx_assign,
            sm_of(SmType::Inputs),
            "TxPDO",
        ),
    ];
    for (base, maps, assign, sm, fallback) in dirs {
        for (i, entries) in maps.iter().enumerate() {
            let index = base + i as u16;
            let assigned = assign.contains(&index);
            if entries.is_empty() && !assigned {
                continue;
            }
            let name = objects
                .binary_search_by_key(&index, |o| o.index)
                .map_or(Name::plain(fallback), |k| objects[k].name());
            let map = PdoMap {
                index,
                name,
                sm: if assigned { sm } else { None },
                fixed: false,
                mandatory: false,
                entries,
            };
            // Capacity is exactly 2 × MAPS.
            let _ = out.push(map);
        }
    }
    out
}

/// Why the ESI could not be written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EsiError {
    /// The writer failed (e.g. buffer full).
    Fmt,
    /// The device description is inconsistent.
    Description(SiiError),
    /// The object table is not sorted or has an object without entries.
    ObjectsNotWellFormed,
    /// A PDO index is outside 0x1600-0x17FF / 0x1A00-0x1BFF.
    PdoIndex(u16),
    /// A PDO's SyncManager does not exist or is not of its direction.
    PdoSyncManager(u16),
    /// A mapped entry does not exist in the object table.
    UnknownEntry {
        /// PDO.
        pdo: u16,
        /// Mapped entry.
        key: ObjectKey,
    },
    /// A mapped entry is not mappable in the PDO's direction.
    NotMappable {
        /// PDO.
        pdo: u16,
        /// Mapped entry.
        key: ObjectKey,
    },
    /// A mapped entry's bit length differs from the object table.
    BitLength {
        /// PDO.
        pdo: u16,
        /// Mapped entry.
        key: ObjectKey,
    },
}

impl From<fmt::Error> for EsiError {
    fn from(_: fmt::Error) -> Self {
        EsiError::Fmt
    }
}

fn find_entry(objects: &[Object], key: ObjectKey) -> Option<(&Object, &Entry)> {
    let i = objects.binary_search_by_key(&key.index, |o| o.index).ok()?;
    let o = &objects[i];
    o.entry(key.sub).map(|e| (o, e))
}

/// Checks the PDO maps against the object table and the SyncManagers.
pub fn validate(
    desc: &DeviceDescription,
    objects: &[Object],
    pdos: &[PdoMap],
) -> Result<(), EsiError> {
    desc.validate().map_err(EsiError::Description)?;
    if !crate::od::is_well_formed(objects) {
        return Err(EsiError::ObjectsNotWellFormed);
    }
    for p in pdos {
        if !p.is_rx() && !p.is_tx() {
            return Err(EsiError::PdoIndex(p.index));
        }
        if let Some(sm) = p.sm {
            let want = if p.is_rx() {
                SmType::Outputs
            } else {
                SmType::Inputs
            };
            match desc.sync_managers.get(sm as usize) {
                Some(s) if s.kind == want => {}
                _ => return Err(EsiError::PdoSyncManager(p.index)),
            }
        }
        for e in p.entries.iter().map(|v| PdoEntry::decode(*v)) {
            if e.key.index == 0 {
                continue;
            }
            let (pdo, key) = (p.index, e.key);
            let (_, entry) = find_entry(objects, key).ok_or(EsiError::UnknownEntry { pdo, key })?;
            let ok = if p.is_rx() {
                entry.pdo_mappable().rx()
            } else {
                entry.pdo_mappable().tx()
            };
            if !ok {
                return Err(EsiError::NotMappable { pdo, key });
            }
            if entry.bits() != e.bits as u16 {
                return Err(EsiError::BitLength { pdo, key });
            }
        }
    }
    Ok(())
}

/// Writes `s` XML-escaped.
pub fn escape<W: Write>(out: &mut W, s: &str) -> fmt::Result {
    let mut start = 0;
    for (i, c) in s.char_indices() {
        let rep = match c {
            '&' => "&amp;",
            '<' => "&lt;",
            '>' => "&gt;",
            '"' => "&quot;",
            '\'' => "&apos;",
            _ => continue,
        };
        out.write_str(&s[start..i])?;
        out.write_str(rep)?;
        start = i + c.len_utf8();
    }
    out.write_str(&s[start..])
}

/// Text wrapper that escapes on display (a `&str`, a [`crate::od::Name`], anything
/// displayable).
struct Esc<T>(T);

impl<T: fmt::Display> fmt::Display for Esc<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(Escaping(f), "{}", self.0)
    }
}

/// A writer that XML-escapes what goes through it.
struct Escaping<'a, W>(&'a mut W);

impl<W: Write> Write for Escaping<'_, W> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        escape(self.0, s)
    }
}

/// The PDOs of `pdos` that `p` excludes (ETG.2000 `Exclude`): the other PDOs of its
/// direction that map one of its objects (same index and sub-index, padding aside).
/// Assigned together they would carry one object twice in a frame — for an RxPDO,
/// two values for one object in one cycle — so a configurator offers them as
/// alternatives. Mapped entries are compared as written in the maps, in the order of
/// `pdos`.
pub fn excludes<'a>(pdos: &'a [PdoMap], p: &'a PdoMap) -> impl Iterator<Item = u16> + 'a {
    let objects = |m: &'a PdoMap| {
        m.entries
            .iter()
            .map(|v| PdoEntry::decode(*v))
            .filter(|e| e.key.index != 0)
            .map(|e| e.key)
    };
    pdos.iter()
        .filter(move |q| q.index != p.index && q.is_rx() == p.is_rx())
        .filter(move |q| objects(q).any(|o| objects(p).any(|x| x == o)))
        .map(|q| q.index)
}

/// A mapped entry as the ESI and the SII PDO categories name it: the object's name
/// for a variable, the entry's name for a record or array member; `None` for a gap
/// or an entry missing from the table.
pub fn pdo_entry_name(objects: &[Object], e: PdoEntry) -> Option<(Name, &Entry)> {
    if e.key.index == 0 {
        return None;
    }
    let (o, entry) = find_entry(objects, e.key)?;
    let name = if o.code() == ObjectCode::Var {
        o.name()
    } else {
        entry.name()
    };
    Some((name, entry))
}

/// One `RxPdo` / `TxPdo`. `Sm` only on a PDO assigned by default (ETG.2000: the
/// attribute is the default assignment; a configurator assigns every PDO that carries
/// it), so the ESI assigns exactly what 0x1C12 / 0x1C13 and the SII assign; the
/// alternatives carry none and name, with `Exclude`, the PDOs they cannot go with.
fn write_pdo<W: Write>(
    out: &mut W,
    objects: &[Object],
    pdos: &[PdoMap],
    p: &PdoMap,
) -> fmt::Result {
    let tag = if p.is_rx() { "RxPdo" } else { "TxPdo" };
    write!(out, "<{tag}")?;
    if p.fixed {
        out.write_str(" Fixed=\"1\"")?;
    }
    if p.mandatory {
        out.write_str(" Mandatory=\"1\"")?;
    }
    if let Some(sm) = p.sm {
        write!(out, " Sm=\"{sm}\"")?;
    }
    writeln!(
        out,
        "><Index>#x{:04X}</Index><Name>{}</Name>",
        p.index,
        Esc(p.name)
    )?;
    for x in excludes(pdos, p) {
        writeln!(out, "<Exclude>#x{x:04X}</Exclude>")?;
    }
    for e in p.entries.iter().map(|v| PdoEntry::decode(*v)) {
        match pdo_entry_name(objects, e) {
            Some((name, entry)) => {
                writeln!(
                    out,
                    "<Entry><Index>#x{:04X}</Index><SubIndex>{}</SubIndex><BitLen>{}</BitLen><Name>{}</Name><DataType>{}</DataType></Entry>",
                    e.key.index,
                    e.key.sub,
                    e.bits,
                    Esc(name),
                    TypeName(entry)
                )?;
            }
            _ => writeln!(
                out,
                "<Entry><Index>#x0</Index><BitLen>{}</BitLen></Entry>",
                e.bits
            )?,
        }
    }
    writeln!(out, "</{tag}>")
}

fn physics(ports: u16) -> [u8; 4] {
    let mut p = [0u8; 4];
    for (i, c) in p.iter_mut().enumerate() {
        *c = match (ports >> (4 * i)) & 0xF {
            1 => b'Y',
            3 => b'K',
            _ => 0,
        };
    }
    p
}

/// One device of an ESI document: its description, object table and default PDOs.
#[derive(Debug, Clone, Copy)]
pub struct EsiDevice<'a> {
    /// Identity, names, SyncManagers, mailbox, DC, EEPROM.
    pub desc: &'a DeviceDescription,
    /// The device's object table (sorted).
    pub objects: &'a [Object],
    /// The default PDOs.
    pub pdos: &'a [PdoMap],
    /// The texts of the 0x10F3 diagnosis messages (`<DiagMessages>`; empty: none).
    pub diag_texts: &'a [DiagText],
}

/// Writes the ESI document of one device.
pub fn write<W: Write>(
    desc: &DeviceDescription,
    objects: &[Object],
    pdos: &[PdoMap],
    out: &mut W,
) -> Result<(), EsiError> {
    write_devices(
        &[EsiDevice {
            desc,
            objects,
            pdos,
            diag_texts: &[],
        }],
        out,
    )
}

/// Writes one ESI document holding several devices of one vendor (e.g. the variants
/// of a product), each validated as in [`write()`]: one `Group` per distinct group type,
/// then the `Device` elements in the order given. An empty list, or devices of
/// different vendor ID or vendor name, is refused with
/// `EsiError::Description(SiiError::InvalidDescription)`.
pub fn write_devices<W: Write>(devices: &[EsiDevice<'_>], out: &mut W) -> Result<(), EsiError> {
    let first = devices
        .first()
        .ok_or(EsiError::Description(SiiError::InvalidDescription))?
        .desc;
    for d in devices {
        validate(d.desc, d.objects, d.pdos)?;
        if d.desc.vendor_id != first.vendor_id || d.desc.vendor_name != first.vendor_name {
            return Err(EsiError::Description(SiiError::InvalidDescription));
        }
    }
    out.write_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<EtherCATInfo Version=\"1.6\">\n")?;
    writeln!(
        out,
        "<Vendor><Id>#x{:08X}</Id><Name>{}</Name></Vendor>",
        first.vendor_id,
        Esc(first.vendor_name)
    )?;
    out.write_str("<Descriptions>\n<Groups>\n")?;
    for (i, d) in devices.iter().enumerate() {
        let g = d.desc.group_type;
        if devices[..i].iter().any(|p| p.desc.group_type == g) {
            continue;
        }
        writeln!(
            out,
            "<Group><Type>{}</Type><Name LcId=\"1033\">{}</Name></Group>",
            Esc(g),
            Esc(d.desc.group_name)
        )?;
    }
    out.write_str("</Groups>\n<Devices>\n")?;
    for d in devices {
        write_device(d, out)?;
    }
    out.write_str("</Devices>\n</Descriptions>\n</EtherCATInfo>\n")?;
    Ok(())
}

/// `<DiagMessages>` (ETG.2000, in `Profile` after `Dictionary`): one `DiagMessage`
/// per text, with its ID and the English text.
fn write_diag_messages<W: Write>(out: &mut W, texts: &[DiagText]) -> fmt::Result {
    if texts.is_empty() {
        return Ok(());
    }
    out.write_str("<DiagMessages>\n")?;
    for t in texts {
        writeln!(
            out,
            "<DiagMessage><TextId>#x{:04X}</TextId><MessageText LcId=\"1033\">{}</MessageText></DiagMessage>",
            t.id,
            Esc(t.text)
        )?;
    }
    out.write_str("</DiagMessages>\n")
}

/// One `Device` element.
fn write_device<W: Write>(d: &EsiDevice<'_>, out: &mut W) -> fmt::Result {
    let (desc, objects, pdos) = (d.desc, d.objects, d.pdos);
    out.write_str("<Device")?;
    let ph = physics(desc.physical_ports);
    let n = ph.iter().position(|c| *c == 0).unwrap_or(4);
    if n > 0 {
        out.write_str(" Physics=\"")?;
        for c in &ph[..n] {
            out.write_char(*c as char)?;
        }
        out.write_str("\"")?;
    }
    out.write_str(">\n")?;
    writeln!(
        out,
        "<Type ProductCode=\"#x{:08X}\" RevisionNo=\"#x{:08X}\">{}</Type>",
        desc.product_code,
        desc.revision,
        Esc(desc.type_name)
    )?;
    writeln!(out, "<Name LcId=\"1033\">{}</Name>", Esc(desc.name))?;
    writeln!(out, "<GroupType>{}</GroupType>", Esc(desc.group_type))?;
    writeln!(
        out,
        "<Profile><ProfileNo>{}</ProfileNo><AddInfo>0</AddInfo>",
        desc.profile_no
    )?;
    out.write_str("<Dictionary>\n")?;
    write_data_types(out, objects)?;
    write_objects(out, objects)?;
    out.write_str("</Dictionary>\n")?;
    write_diag_messages(out, d.diag_texts)?;
    out.write_str("</Profile>\n")?;
    for f in desc.fmmus.iter().filter(|f| !f.esi().is_empty()) {
        writeln!(out, "<Fmmu>{}</Fmmu>", f.esi())?;
    }
    write_sync_managers(out, desc)?;
    for p in pdos.iter().filter(|p| p.is_rx()) {
        write_pdo(out, objects, pdos, p)?;
    }
    for p in pdos.iter().filter(|p| p.is_tx()) {
        write_pdo(out, objects, pdos, p)?;
    }
    let c = desc.coe;
    writeln!(
        out,
        "<Mailbox DataLinkLayer=\"{}\"><CoE SdoInfo=\"{}\" PdoAssign=\"{}\" PdoConfig=\"{}\" PdoUpload=\"{}\" CompleteAccess=\"{}\"/>{}</Mailbox>",
        desc.mailbox_data_link_layer,
        c.sdo_info,
        c.pdo_assign,
        c.pdo_config,
        c.pdo_upload,
        c.complete_access,
        if desc.mailbox_protocols & crate::sii::MBOX_FOE != 0 {
            "<FoE/>"
        } else {
            ""
        }
    )?;
    write_dc(out, desc)?;
    let cfg = desc.config_area();
    write!(
        out,
        "<Eeprom><ByteSize>{}</ByteSize><ConfigData>{}</ConfigData>",
        desc.eeprom_bytes,
        Hex(&cfg[..14])
    )?;
    if let Some(boot) = &desc.bootstrap {
        let hex = boot.esi_hex();
        // ASCII hex digits: always UTF-8.
        let hex = core::str::from_utf8(&hex).unwrap_or("");
        write!(out, "<BootStrap>{hex}</BootStrap>")?;
    }
    out.write_str("</Eeprom>\n")?;
    out.write_str("</Device>\n")
}

/// The `<Sm>` elements.
fn write_sync_managers<W: Write>(out: &mut W, desc: &DeviceDescription) -> fmt::Result {
    for sm in desc.sync_managers {
        out.write_str("<Sm")?;
        if sm.min_size != 0 {
            write!(out, " MinSize=\"{}\"", sm.min_size)?;
        }
        if sm.max_size != 0 {
            write!(out, " MaxSize=\"{}\"", sm.max_size)?;
        }
        if sm.default_size != 0 {
            write!(out, " DefaultSize=\"{}\"", sm.default_size)?;
        }
        writeln!(
            out,
            " StartAddress=\"#x{:04X}\" ControlByte=\"#x{:02X}\" Enable=\"{}\">{}</Sm>",
            sm.start,
            sm.control,
            sm.enable as u8,
            sm.kind.esi()
        )?;
    }
    Ok(())
}

/// The `<Dc>` element with one `<OpMode>` per DC op mode (none without op modes).
fn write_dc<W: Write>(out: &mut W, desc: &DeviceDescription) -> fmt::Result {
    if !desc.dc_op_modes.is_empty() {
        out.write_str("<Dc>\n")?;
        for m in desc.dc_op_modes {
            write!(
                out,
                "<OpMode><Name>{}</Name><Desc>{}</Desc><AssignActivate>#x{:X}</AssignActivate>",
                Esc(m.name),
                Esc(m.description),
                m.assign_activate
            )?;
            // SYNC0 settings only for op modes that generate SYNC0 (0x0981 bit 1).
            if m.assign_activate & 0x0200 != 0 {
                write!(
                    out,
                    "<CycleTimeSync0 Factor=\"{}\">{}</CycleTimeSync0><ShiftTimeSync0>{}</ShiftTimeSync0>",
                    m.sync0_factor, m.cycle_time_sync0, m.shift_time_sync0
                )?;
            }
            if m.assign_activate & 0x0400 != 0 {
                write!(
                    out,
                    "<CycleTimeSync1 Factor=\"{}\">0</CycleTimeSync1><ShiftTimeSync1>{}</ShiftTimeSync1>",
                    m.sync1_factor, m.shift_time_sync1
                )?;
            }
            out.write_str("</OpMode>\n")?;
        }
        out.write_str("</Dc>\n")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests;
