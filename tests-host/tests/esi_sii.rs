//! The ESI files and SII images `drive-docs` generates describe exactly the drive:
//! well-formed XML; every object of `firmware::dictionary::OBJECTS` with its index,
//! type, bit size, access and PDO mapping, nothing else; identity equal to the SII
//! words 8-15 and to 0x1018 read through the drive's dictionary; SyncManagers and
//! mailbox equal to the SII and to the project's standard layout; RxPdo/TxPdo equal to
//! the default maps read through the mapping objects; CoE details, FMMUs, DC op modes
//! and EEPROM config area equal in both; a correct SII checksum. The SII is parsed
//! here with a reader of its own (word map and category walk of the spec), not with
//! the builder's parser; its PDO categories (0x32 TxPDO, 0x33 RxPDO) equal the
//! ESI's TxPdo/RxPdo, and its order string the ESI type. A third-party parser
//! (`ethercat-esi` 0.2) reads both committed ESI files. Also: the committed
//! docs/object-dictionary.md, docs/faults.md and docs/esi/ are what the generators
//! produce today.

#[path = "../src/bin/drive-docs.rs"]
#[allow(dead_code)]
mod drive_docs;

use std::collections::BTreeMap;

use drive_docs::{FLAVOURS, VARIANTS};
use ecat_slave_stack::esi::{self, EsiDevice, EsiError};
use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::od::{
    Access, DataType, DefaultValue, Dictionary, Entry, Object, ObjectCode, ObjectKey, PdoMappable,
};
use ecat_slave_stack::pdo::PdoConfig;
use ecat_slave_stack::sii::{self, EscFlavour, SiiError};
use firmware::dictionary::OBJECTS;
use firmware::drive::Drive;
use firmware::identity::{self, Variant};
use firmware::pdo_defaults::PDO_DEFAULTS;
use roxmltree::{Document, Node};

// ---------------------------------------------------------------- XML helpers

fn children<'a, 'i>(n: Node<'a, 'i>, tag: &str) -> Vec<Node<'a, 'i>> {
    n.children().filter(|c| c.has_tag_name(tag)).collect()
}

fn child<'a, 'i>(n: Node<'a, 'i>, tag: &str) -> Node<'a, 'i> {
    let c = children(n, tag);
    assert_eq!(
        c.len(),
        1,
        "expected one <{tag}> in <{}>",
        n.tag_name().name()
    );
    c[0]
}

fn opt_child<'a, 'i>(n: Node<'a, 'i>, tag: &str) -> Option<Node<'a, 'i>> {
    let c = children(n, tag);
    assert!(c.len() <= 1, "several <{tag}> in <{}>", n.tag_name().name());
    c.first().copied()
}

fn text<'a>(n: Node<'a, '_>, tag: &str) -> &'a str {
    child(n, tag).text().unwrap_or("")
}

/// "#x1A2B" or decimal.
fn num(s: &str) -> u64 {
    match s.strip_prefix("#x") {
        Some(h) => u64::from_str_radix(h, 16).unwrap_or_else(|_| panic!("bad hex {s}")),
        None => s.parse().unwrap_or_else(|_| panic!("bad number {s}")),
    }
}

fn hex_bytes(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02X}")).collect()
}

fn devices<'a, 'i>(doc: &'a Document<'i>) -> Vec<Node<'a, 'i>> {
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "EtherCATInfo");
    children(child(child(root, "Descriptions"), "Devices"), "Device")
}

fn esi(esc: EscFlavour) -> String {
    drive_docs::esi_document(esc).expect("ESI generation")
}

/// The device of `variant` in a parsed ESI document (by product code).
fn device_of<'a, 'i>(doc: &'a Document<'i>, variant: Variant) -> Node<'a, 'i> {
    let found: Vec<_> = devices(doc)
        .into_iter()
        .filter(|d| {
            num(child(*d, "Type").attribute("ProductCode").unwrap_or(""))
                == u64::from(variant.product_code())
        })
        .collect();
    assert_eq!(
        found.len(),
        1,
        "one device with the product code of {variant:?}"
    );
    found[0]
}

// ---------------------------------------------------------------- SII reader

/// The SII checksum (ETG.1000.6 / ETG.2010): polynomial 0x07, init 0xFF, MSB first, no final XOR.
fn crc8(data: &[u8]) -> u8 {
    let mut crc = 0xFFu8;
    for b in data {
        crc ^= b;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                crc << 1 ^ 0x07
            } else {
                crc << 1
            };
        }
    }
    crc
}

struct Image {
    bytes: Vec<u8>,
}

impl Image {
    fn word(&self, i: usize) -> u16 {
        u16::from_le_bytes([self.bytes[2 * i], self.bytes[2 * i + 1]])
    }
    fn dword(&self, i: usize) -> u32 {
        u32::from(self.word(i)) | u32::from(self.word(i + 1)) << 16
    }
    /// Categories from word 0x40 up to the end marker: (type, data).
    fn categories(&self) -> Vec<(u16, &[u8])> {
        let mut out = Vec::new();
        let mut w = 0x40;
        loop {
            let kind = self.word(w);
            if kind == 0xFFFF {
                return out;
            }
            let len = usize::from(self.word(w + 1)) * 2;
            let start = 2 * (w + 2);
            out.push((kind, &self.bytes[start..start + len]));
            w += 2 + len / 2;
            assert!(out.len() < 64, "no end marker");
        }
    }
    fn category(&self, kind: u16) -> &[u8] {
        let c: Vec<_> = self
            .categories()
            .into_iter()
            .filter(|(k, _)| *k == kind)
            .collect();
        assert_eq!(c.len(), 1, "one category {kind}");
        c[0].1
    }
    fn strings(&self) -> Vec<String> {
        let d = self.category(10);
        let mut out = Vec::new();
        let mut at = 1;
        for _ in 0..d[0] {
            let n = usize::from(d[at]);
            out.push(String::from_utf8(d[at + 1..at + 1 + n].to_vec()).expect("ASCII string"));
            at += 1 + n;
        }
        out
    }
    /// 1-based string reference.
    fn string(&self, i: u8) -> String {
        assert!(i > 0, "string reference 0");
        self.strings()[usize::from(i) - 1].clone()
    }
}

fn image(v: Variant, esc: EscFlavour) -> Image {
    Image {
        bytes: drive_docs::sii_image(v, esc).expect("SII generation"),
    }
}

fn read(d: &mut impl Dictionary, index: u16, sub: u8) -> Vec<u8> {
    let mut buf = [0u8; 256];
    let n = d
        .read(ObjectKey::new(index, sub), &mut buf)
        .unwrap_or_else(|e| panic!("read {index:#06x}:{sub}: {e:?}"));
    buf[..n].to_vec()
}

fn read_u32(d: &mut impl Dictionary, index: u16, sub: u8) -> u32 {
    let b = read(d, index, sub);
    let mut w = [0u8; 4];
    w[..b.len()].copy_from_slice(&b);
    u32::from_le_bytes(w)
}

/// The mapping/assignment objects as the slave runtime serves them at power-up.
struct Runtime(PdoConfig);

impl Dictionary for Runtime {
    fn objects(&self) -> &'static [Object] {
        OBJECTS
    }
    fn read(
        &mut self,
        key: ObjectKey,
        buf: &mut [u8],
    ) -> Result<usize, ecat_slave_stack::od::SdoAbort> {
        self.0.read(key, buf)
    }
    fn write(
        &mut self,
        _: ObjectKey,
        _: &[u8],
        _: EsmState,
    ) -> Result<(), ecat_slave_stack::od::SdoAbort> {
        Err(ecat_slave_stack::od::SdoAbort::WriteReadOnly)
    }
}

fn runtime() -> Runtime {
    Runtime(PdoConfig::new(PDO_DEFAULTS))
}

/// The maps an assignment object (0x1C12 / 0x1C13) lists, read through the runtime.
fn assignment(rt: &mut Runtime, index: u16) -> Vec<u16> {
    (1..=read_u32(rt, index, 0) as u8)
        .map(|s| read_u32(rt, index, s) as u16)
        .collect()
}

// ---------------------------------------------------------------- expected values

/// ETG.2000 base type names, independent of the writer's table.
fn type_name(e: &Entry) -> String {
    let base = match e.data_type {
        DataType::Boolean => "BOOL",
        DataType::Integer8 => "SINT",
        DataType::Integer16 => "INT",
        DataType::Integer32 => "DINT",
        DataType::Integer64 => "LINT",
        DataType::Unsigned8 => "USINT",
        DataType::Unsigned16 => "UINT",
        DataType::Unsigned32 => "UDINT",
        DataType::Unsigned64 => "ULINT",
        DataType::Real32 => "REAL",
        DataType::VisibleString => return format!("STRING({})", e.bits() / 8),
        DataType::OctetString => return format!("OCTET_STRING({})", e.bits() / 8),
        t => return format!("BIT{}", t as u16 - 0x2F),
    };
    base.to_string()
}

/// (access text, write restriction) from the per-state rights.
fn access(a: Access) -> (&'static str, Option<&'static str>) {
    let r = [EsmState::PreOp, EsmState::SafeOp, EsmState::Op].map(|s| a.readable_in(s));
    let w = [EsmState::PreOp, EsmState::SafeOp, EsmState::Op].map(|s| a.writable_in(s));
    assert!(
        r.iter().all(|x| *x) || !r.iter().any(|x| *x),
        "partial read rights"
    );
    match w {
        [false, false, false] => ("ro", None),
        [true, true, true] if r[0] => ("rw", None),
        [true, true, true] => ("wo", None),
        [true, false, false] => ("rw", Some("PreOP")),
        [true, true, false] => ("rw", Some("PreOP_SafeOP")),
        other => panic!("access {other:?} has no ESI form"),
    }
}

fn check_flags(flags: Node, e: &Entry, what: &str) {
    let (acc, restr) = access(e.access);
    let a = child(flags, "Access");
    assert_eq!(a.text(), Some(acc), "{what}: access");
    assert_eq!(
        a.attribute("WriteRestrictions"),
        restr,
        "{what}: write restrictions"
    );
    let pdo = opt_child(flags, "PdoMapping").and_then(|p| p.text());
    let want = match e.pdo_mappable() {
        PdoMappable::No => None,
        PdoMappable::Rx => Some("R"),
        PdoMappable::Tx => Some("T"),
        PdoMappable::RxTx => Some("RT"),
    };
    assert_eq!(pdo, want, "{what}: PDO mapping");
}

/// The Info's default element against the variant's description and, for the entries
/// served by the variant-aware modules and the mapping objects, against the value
/// the powered-up drive returns.
fn check_default(info: Node, index: u16, e: &Entry, variant: Variant, what: &str) {
    let data = opt_child(info, "DefaultData").and_then(|n| n.text());
    let string = opt_child(info, "DefaultString").and_then(|n| n.text());
    match e.default_value() {
        DefaultValue::None => {
            assert_eq!((data, string), (None, None), "{what}: no default expected");
        }
        DefaultValue::Int(v) => {
            let n = e.bits().div_ceil(8).clamp(1, 8) as usize;
            assert_eq!(
                data,
                Some(hex_bytes(&v.to_le_bytes()[..n]).as_str()),
                "{what}: default"
            );
        }
        DefaultValue::Text(t) => assert_eq!(
            string,
            Some(t).filter(|t| !t.is_empty()),
            "{what}: default text"
        ),
    }
    if drive_docs::source_of(index).is_some() && (data.is_some() || string.is_some()) {
        let live = drive_docs::power_up_bytes(variant, index, e.sub)
            .unwrap_or_else(|| panic!("{what}: not readable at power-up"));
        match (data, string) {
            (Some(d), _) => assert_eq!(d, hex_bytes(&live), "{what}: default = power-up value"),
            (_, Some(s)) => assert_eq!(
                s.as_bytes(),
                live.as_slice(),
                "{what}: default = power-up text"
            ),
            _ => unreachable!(),
        }
    }
}

// ---------------------------------------------------------------- tests

#[test]
fn crc8_matches_the_spec_vectors() {
    let mut a = [0u8; 14];
    a[..4].copy_from_slice(&[0x08, 0x0E, 0x02, 0x88]);
    assert_eq!(crc8(&a), 0x2F);
    let mut b = [0u8; 14];
    b[..4].copy_from_slice(&[0x80, 0x06, 0x81, 0x06]);
    assert_eq!(crc8(&b), 0xCD);
    assert_eq!(sii::crc8(&a), 0x2F);
}

#[test]
fn esi_files_are_well_formed_and_hold_both_variants() {
    for (esc, _) in FLAVOURS {
        let xml = esi(esc);
        let doc = Document::parse(&xml).unwrap_or_else(|e| panic!("{esc:?}: not well-formed: {e}"));
        let root = doc.root_element();
        let vendor = child(root, "Vendor");
        assert_eq!(num(text(vendor, "Id")), u64::from(identity::VENDOR_ID));
        assert_eq!(text(vendor, "Name"), identity::VENDOR_NAME);
        let groups = children(child(child(root, "Descriptions"), "Groups"), "Group");
        assert_eq!(groups.len(), 1);
        assert_eq!(text(groups[0], "Type"), identity::GROUP);
        let devs = devices(&doc);
        assert_eq!(devs.len(), VARIANTS.len());
        for (v, _) in VARIANTS {
            let d = device_of(&doc, v);
            let ty = child(d, "Type");
            assert_eq!(ty.text(), Some(v.type_name()));
            assert_eq!(text(d, "Name"), v.device_name());
            assert_eq!(text(d, "GroupType"), identity::GROUP);
            assert_eq!(d.attribute("Physics"), Some("YY"));
        }
    }
}

#[test]
fn variant_descriptions_differ_from_the_table_only_in_defaults() {
    for (v, _) in VARIANTS {
        let objs = drive_docs::variant_objects(v);
        assert_eq!(objs.len(), OBJECTS.len());
        let mut changed = Vec::new();
        for (a, b) in OBJECTS.iter().zip(objs) {
            assert_eq!(
                (a.index, a.name(), a.code(), a.entries().len()),
                (b.index, b.name(), b.code(), b.entries().len())
            );
            for (x, y) in a.entries().iter().zip(b.entries()) {
                assert_eq!(
                    (
                        x.sub,
                        x.name(),
                        x.data_type,
                        x.bits(),
                        x.access,
                        x.pdo_mappable(),
                        x.min(),
                        x.max(),
                        x.unit_text(),
                        x.is_saved()
                    ),
                    (
                        y.sub,
                        y.name(),
                        y.data_type,
                        y.bits(),
                        y.access,
                        y.pdo_mappable(),
                        y.min(),
                        y.max(),
                        y.unit_text(),
                        y.is_saved()
                    ),
                    "{:#06x}:{}",
                    a.index,
                    x.sub
                );
                if !drive_docs::same_default(x.default_value(), y.default_value()) {
                    changed.push((a.index, x.sub));
                }
            }
        }
        // Mapping and assignment objects get the product's default mapping.
        let (pdo, other): (Vec<_>, Vec<_>) = changed
            .into_iter()
            .partition(|(i, _)| drive_docs::source_of(*i) == Some(drive_docs::Source::Pdo));
        assert!(pdo.contains(&(0x1600, 1)) && pdo.contains(&(0x1C13, 1)));
        // The table describes the hybrid servo; the open-loop drive reports its own
        // device type, name, product code, loop mode and modes (no CST).
        let want: &[(u16, u8)] = match v {
            Variant::HybridServo => &[],
            Variant::OpenLoop => &[
                (0x1000, 0),
                (0x1008, 0),
                (0x1018, 2),
                (0x2024, 0),
                (0x6502, 0),
            ],
        };
        assert_eq!(
            other, want,
            "{v:?}: entries whose default differs from the table"
        );
    }
}

#[test]
fn esi_dictionary_is_exactly_the_drive_dictionary() {
    for (esc, _) in FLAVOURS {
        let xml = esi(esc);
        let doc = Document::parse(&xml).unwrap();
        for (v, _) in VARIANTS {
            let objs = drive_docs::variant_objects(v);
            let dev = device_of(&doc, v);
            let profile = child(dev, "Profile");
            let mut drive = Drive::new(v, 0);
            assert_eq!(
                num(text(profile, "ProfileNo")),
                u64::from(read_u32(&mut drive, 0x1000, 0) & 0xFFFF)
            );
            let dict = child(profile, "Dictionary");
            let types: BTreeMap<&str, Node> = children(child(dict, "DataTypes"), "DataType")
                .into_iter()
                .map(|t| (text(t, "Name"), t))
                .collect();
            let xs = children(child(dict, "Objects"), "Object");
            assert_eq!(xs.len(), OBJECTS.len(), "{esc:?} {v:?}: object count");
            for (o, x) in objs.iter().zip(&xs) {
                let what = format!("{esc:?} {v:?} {:#06x}", o.index);
                assert_eq!(num(text(*x, "Index")), u64::from(o.index), "{what}");
                assert_eq!(text(*x, "Name"), o.name(), "{what}");
                let info = child(*x, "Info");
                if o.code() == ObjectCode::Var {
                    let e = &o.entries()[0];
                    assert_eq!(text(*x, "Type"), type_name(e), "{what}: type");
                    assert!(
                        types.contains_key(text(*x, "Type")),
                        "{what}: type not defined"
                    );
                    assert_eq!(
                        num(text(*x, "BitSize")),
                        u64::from(e.bits()),
                        "{what}: bits"
                    );
                    check_flags(child(*x, "Flags"), e, &what);
                    check_default(info, o.index, e, v, &what);
                    continue;
                }
                let dt_name = format!("DT{:04X}", o.index);
                assert_eq!(text(*x, "Type"), dt_name, "{what}");
                let dt = types[dt_name.as_str()];
                let subs = children(dt, "SubItem");
                assert_eq!(subs.len(), o.entries().len(), "{what}: sub-items");
                let mut off = 0u64;
                for (i, (e, s)) in o.entries().iter().zip(&subs).enumerate() {
                    let what = format!("{what}:{}", e.sub);
                    assert_eq!(num(text(*s, "SubIdx")), u64::from(e.sub), "{what}");
                    assert_eq!(text(*s, "Name"), e.name(), "{what}");
                    assert_eq!(text(*s, "Type"), type_name(e), "{what}: type");
                    assert_eq!(
                        num(text(*s, "BitSize")),
                        u64::from(e.bits()),
                        "{what}: bits"
                    );
                    // An entry of a byte or more starts on a byte (ETG.1020 DT10F3).
                    if e.bits() >= 8 {
                        off = off.next_multiple_of(8);
                    }
                    assert_eq!(num(text(*s, "BitOffs")), off, "{what}: offset");
                    check_flags(child(*s, "Flags"), e, &what);
                    off += u64::from(e.bits());
                    if i == 0 {
                        off = off.max(16);
                    }
                }
                assert_eq!(num(text(dt, "BitSize")), off, "{what}: record size");
                assert_eq!(num(text(*x, "BitSize")), off, "{what}: object size");
                let defaults = children(info, "SubItem");
                assert_eq!(
                    defaults.len(),
                    o.entries().len(),
                    "{what}: default sub-items"
                );
                for (e, s) in o.entries().iter().zip(&defaults) {
                    assert_eq!(text(*s, "Name"), e.name());
                    check_default(
                        child(*s, "Info"),
                        o.index,
                        e,
                        v,
                        &format!("{what}:{}", e.sub),
                    );
                }
            }
        }
    }
}

#[test]
fn identity_equals_sii_words_and_0x1018() {
    for (esc, _) in FLAVOURS {
        let xml = esi(esc);
        let doc = Document::parse(&xml).unwrap();
        let vendor = num(text(child(doc.root_element(), "Vendor"), "Id")) as u32;
        for (v, _) in VARIANTS {
            let dev = device_of(&doc, v);
            let ty = child(dev, "Type");
            let product = num(ty.attribute("ProductCode").unwrap()) as u32;
            let revision = num(ty.attribute("RevisionNo").unwrap()) as u32;
            let img = image(v, esc);
            assert_eq!(
                (
                    img.dword(8),
                    img.dword(0x0A),
                    img.dword(0x0C),
                    img.dword(0x0E)
                ),
                (vendor, product, revision, 0),
                "{esc:?} {v:?}: SII words 8-15"
            );
            let mut drive = Drive::new(v, 0);
            assert_eq!(read_u32(&mut drive, 0x1018, 0), 4);
            assert_eq!(
                [1, 2, 3, 4].map(|s| read_u32(&mut drive, 0x1018, s)),
                [vendor, product, revision, 0],
                "{esc:?} {v:?}: 0x1018 through the drive's dictionary"
            );
            assert_eq!(
                (vendor, product, revision),
                (identity::VENDOR_ID, v.product_code(), identity::REVISION)
            );
            // Names: SII general category strings = ESI = 0x1008.
            let g = img.category(30);
            assert_eq!(g.len(), 32, "general category is 32 bytes");
            assert_eq!(img.string(g[3]), text(dev, "Name"));
            assert_eq!(read(&mut drive, 0x1008, 0), text(dev, "Name").as_bytes());
            assert_eq!(img.string(g[0]), text(dev, "GroupType"));
            assert_eq!(g[0x0E], g[0]);
            assert_eq!(
                img.string(g[2]),
                text(dev, "Type"),
                "order string = ESI type"
            );
            assert_eq!(
                u16::from_le_bytes([g[0x10], g[0x11]]),
                0x0011,
                "two MII ports = Physics YY"
            );
        }
    }
}

/// The project's standard layout (common rules): start, mailbox size, control byte,
/// SII type; process data up to 64 bytes.
const LAYOUT: [(u16, u16, u8, u8, &str); 4] = [
    (0x1000, 128, 0x26, 1, "MBoxOut"),
    (0x1080, 128, 0x22, 2, "MBoxIn"),
    (0x1100, 0, 0x64, 3, "Outputs"),
    (0x1400, 0, 0x20, 4, "Inputs"),
];

#[test]
fn mailbox_and_sync_managers_equal_in_esi_sii_and_the_standard_layout() {
    for (esc, _) in FLAVOURS {
        let xml = esi(esc);
        let doc = Document::parse(&xml).unwrap();
        for (v, _) in VARIANTS {
            let what = format!("{esc:?} {v:?}");
            let dev = device_of(&doc, v);
            let img = image(v, esc);
            let sms = children(dev, "Sm");
            let cat = img.category(41);
            assert_eq!(sms.len(), LAYOUT.len(), "{what}");
            assert_eq!(cat.len(), 8 * LAYOUT.len(), "{what}");
            let mut rt = runtime();
            assert_eq!(read_u32(&mut rt, 0x1C00, 0), LAYOUT.len() as u32);
            for (i, (start, mbx, control, kind, tag)) in LAYOUT.iter().enumerate() {
                let x = sms[i];
                let r = &cat[8 * i..8 * i + 8];
                assert_eq!(
                    num(x.attribute("StartAddress").unwrap()),
                    u64::from(*start),
                    "{what} SM{i}"
                );
                assert_eq!(
                    num(x.attribute("ControlByte").unwrap()),
                    u64::from(*control),
                    "{what} SM{i}"
                );
                assert_eq!(x.attribute("Enable"), Some("1"), "{what} SM{i}");
                assert_eq!(x.text(), Some(*tag), "{what} SM{i}");
                assert_eq!(
                    u16::from_le_bytes([r[0], r[1]]),
                    *start,
                    "{what} SII SM{i} start"
                );
                assert_eq!(r[4], *control, "{what} SII SM{i} control");
                assert_eq!(r[6] & 1, 1, "{what} SII SM{i} enable");
                assert_eq!(r[7], *kind, "{what} SII SM{i} type");
                assert_eq!(
                    read_u32(&mut rt, 0x1C00, i as u8 + 1),
                    u32::from(*kind),
                    "{what} 0x1C00:{}",
                    i + 1
                );
                let sii_len = u16::from_le_bytes([r[2], r[3]]);
                if *mbx != 0 {
                    assert_eq!(sii_len, *mbx, "{what} SII SM{i} length");
                    assert_eq!(
                        x.attribute("DefaultSize").map(num),
                        Some(u64::from(*mbx)),
                        "{what} SM{i}"
                    );
                } else {
                    assert_eq!(
                        x.attribute("MaxSize").map(num),
                        Some(64),
                        "{what} SM{i} max size"
                    );
                    assert_eq!(sii_len, 0, "{what} SII SM{i}: length from the mapping");
                }
            }
            // Standard mailbox words = SM0/SM1; the bootstrap mailbox (FoE updates) is
            // the standard one too, in the SII and the ESI's Eeprom/BootStrap.
            assert_eq!(
                [0x18, 0x19, 0x1A, 0x1B].map(|w| img.word(w)),
                [0x1000, 128, 0x1080, 128],
                "{what}: SII standard mailbox"
            );
            assert_eq!(
                [0x14, 0x15, 0x16, 0x17].map(|w| img.word(w)),
                [0x1000, 128, 0x1080, 128],
                "{what}: bootstrap"
            );
            let boot = child(child(dev, "Eeprom"), "BootStrap")
                .text()
                .unwrap_or("");
            assert_eq!(
                boot, "0010800080108000",
                "{what}: ESI BootStrap = SII 0x14-0x17"
            );
            assert_eq!(img.word(0x1C), 0x000C, "{what}: CoE and FoE");
            let mbx = child(dev, "Mailbox");
            assert!(opt_child(mbx, "CoE").is_some());
            assert!(opt_child(mbx, "FoE").is_some(), "{what}: FoE");
            for p in ["EoE", "SoE", "AoE", "VoE"] {
                assert!(opt_child(mbx, p).is_none(), "{what}: {p} not implemented");
            }
        }
    }
}

#[test]
fn esi_pdos_equal_the_default_maps_read_through_the_mapping_objects() {
    for (esc, _) in FLAVOURS {
        let xml = esi(esc);
        let doc = Document::parse(&xml).unwrap();
        for (v, _) in VARIANTS {
            let what = format!("{esc:?} {v:?}");
            let dev = device_of(&doc, v);
            let objs = drive_docs::variant_objects(v);
            let mut rt = runtime();
            for (tag, base, assign, sm) in [
                ("RxPdo", 0x1600u16, 0x1C12u16, "2"),
                ("TxPdo", 0x1A00, 0x1C13, "3"),
            ] {
                let assigned = assignment(&mut rt, assign);
                let xs = children(dev, tag);
                let mut listed = Vec::new();
                let mut assigned_bits = 0;
                for map in base..base + 4 {
                    let n = read_u32(&mut rt, map, 0) as u8;
                    let entries: Vec<u32> = (1..=n).map(|s| read_u32(&mut rt, map, s)).collect();
                    let x = xs
                        .iter()
                        .find(|x| num(text(**x, "Index")) == u64::from(map));
                    let is_assigned = assigned.contains(&map);
                    let Some(x) = x else {
                        assert!(
                            entries.is_empty() && !is_assigned,
                            "{what}: {map:#06x} missing"
                        );
                        continue;
                    };
                    listed.push(map);
                    // `Sm` is the default assignment (ETG.2000): on the PDOs
                    // 0x1C12 / 0x1C13 list, on no other.
                    let want_sm = is_assigned.then_some(sm);
                    assert_eq!(x.attribute("Sm"), want_sm, "{what}: {map:#06x} Sm");
                    let es = children(*x, "Entry");
                    assert_eq!(es.len(), entries.len(), "{what}: {map:#06x} entries");
                    for (e, val) in es.iter().zip(&entries) {
                        let (index, sub, bits) =
                            ((val >> 16) as u16, (val >> 8) as u8, (val & 0xFF) as u8);
                        assert_eq!(num(text(*e, "Index")), u64::from(index));
                        assert_eq!(num(text(*e, "SubIndex")), u64::from(sub));
                        assert_eq!(num(text(*e, "BitLen")), u64::from(bits));
                        let o = objs
                            .iter()
                            .find(|o| o.index == index)
                            .expect("mapped object exists");
                        let entry = o.entry(sub).expect("mapped entry exists");
                        assert_eq!(
                            text(*e, "DataType"),
                            type_name(entry),
                            "{what}: {index:#06x}:{sub}"
                        );
                        assert_eq!(entry.bits(), u16::from(bits));
                        assert!(if tag == "RxPdo" {
                            entry.pdo_mappable().rx()
                        } else {
                            entry.pdo_mappable().tx()
                        });
                        if is_assigned {
                            assigned_bits += u32::from(bits);
                        }
                    }
                }
                assert_eq!(listed.len(), xs.len(), "{what}: {tag} nothing extra");
                assert!(!assigned.is_empty());
                assert!(assigned_bits.div_ceil(8) <= 64, "{what}: {tag} fits the SM");
            }
        }
    }
}

#[test]
fn coe_details_fmmus_dc_and_eeprom_agree() {
    for (esc, _) in FLAVOURS {
        let xml = esi(esc);
        let doc = Document::parse(&xml).unwrap();
        for (v, _) in VARIANTS {
            let what = format!("{esc:?} {v:?}");
            let dev = device_of(&doc, v);
            let img = image(v, esc);
            // CoE details byte: b0 SDO, b1 info, b2 assign, b3 config, b4 upload, b5 CA.
            let g = img.category(30);
            let coe = child(child(dev, "Mailbox"), "CoE");
            assert_eq!(g[5] & 1, 1, "{what}: SDO supported");
            assert_eq!(g[5] & 0xC0, 0);
            for (bit, attr) in [
                (1, "SdoInfo"),
                (2, "PdoAssign"),
                (3, "PdoConfig"),
                (4, "PdoUpload"),
                (5, "CompleteAccess"),
            ] {
                let esi_flag = coe.attribute(attr).unwrap_or("false");
                assert!(["true", "false", "1", "0"].contains(&esi_flag));
                let on = esi_flag == "true" || esi_flag == "1";
                assert_eq!(g[5] >> bit & 1 == 1, on, "{what}: {attr}");
            }
            assert_eq!((g[6], g[7]), (1, 0), "{what}: FoE, no EoE");
            let dll = child(dev, "Mailbox").attribute("DataLinkLayer") == Some("true");
            assert_eq!(
                g[0x0B] >> 2 & 1 == 1,
                dll,
                "{what}: mailbox data link layer"
            );
            // FMMUs.
            let fmmus: Vec<&str> = children(dev, "Fmmu")
                .iter()
                .map(|f| f.text().unwrap())
                .collect();
            let cat = img.category(40);
            let used: Vec<&str> = cat
                .iter()
                .filter(|b| !matches!(b, 0 | 0xFF))
                .map(|b| match b {
                    1 => "Outputs",
                    2 => "Inputs",
                    3 => "MBoxState",
                    other => panic!("{what}: FMMU usage {other}"),
                })
                .collect();
            assert_eq!(fmmus, used, "{what}: FMMUs");
            // DC op modes: 24 bytes each; AssignActivate at 14, SYNC0 factor at 16, name
            // and description strings at 18 and 19.
            let ops = children(child(dev, "Dc"), "OpMode");
            let dc = img.category(60);
            assert_eq!(dc.len(), 24 * ops.len(), "{what}: DC op modes");
            for (i, op) in ops.iter().enumerate() {
                let r = &dc[24 * i..24 * i + 24];
                assert_eq!(
                    num(text(*op, "AssignActivate")),
                    u64::from(u16::from_le_bytes([r[14], r[15]]))
                );
                assert_eq!(img.string(r[18]), text(*op, "Name"));
                assert_eq!(img.string(r[19]), text(*op, "Desc"));
                let sync0 = opt_child(*op, "CycleTimeSync0");
                assert_eq!(
                    sync0.is_some(),
                    r[15] & 0x02 != 0,
                    "{what}: SYNC0 only when generated"
                );
                if let Some(s) = sync0 {
                    let factor: i64 = s.attribute("Factor").unwrap().parse().unwrap();
                    assert_eq!(factor, i64::from(i16::from_le_bytes([r[16], r[17]])));
                    assert_eq!(
                        num(s.text().unwrap()),
                        u64::from(u32::from_le_bytes([r[0], r[1], r[2], r[3]]))
                    );
                }
            }
            // EEPROM: size word, version, config area and checksum.
            let ee = child(dev, "Eeprom");
            assert_eq!(
                num(text(ee, "ByteSize")) as usize,
                img.bytes.len(),
                "{what}"
            );
            assert_eq!(
                (usize::from(img.word(0x3E)) + 1) * 128,
                img.bytes.len(),
                "{what}: size word"
            );
            assert_eq!(img.word(0x3F), 1, "{what}: version");
            assert_eq!(
                text(ee, "ConfigData"),
                hex_bytes(&img.bytes[..14]),
                "{what}: ConfigData"
            );
            assert_eq!(img.bytes[14], crc8(&img.bytes[..14]), "{what}: checksum");
            assert_eq!(img.bytes[15], 0, "{what}: checksum high byte");
            assert!(sii::Sii::new(&img.bytes).checksum_ok());
            let d = identity::device_description(v, esc, 0);
            assert_eq!(
                [0, 1, 3].map(|w| img.word(w)),
                [
                    esc.pdi_control(),
                    esc.pdi_config(d.sync0_drive),
                    esc.pdi_config2()
                ]
            );
            assert_eq!(img.word(2), d.sync_pulse_length);
        }
    }
}

#[test]
fn corrupted_or_truncated_images_are_detected_without_panic() {
    let img = image(Variant::HybridServo, EscFlavour::Lan9252).bytes;
    for i in 0..16 {
        for bit in 0..8 {
            let mut bad = img.clone();
            bad[i] ^= 1 << bit;
            let ok = sii::Sii::new(&bad).checksum_ok();
            assert_eq!(ok, i == 15, "flip byte {i} bit {bit}");
            if i < 14 {
                assert_ne!(bad[14], crc8(&bad[..14]));
            }
        }
    }
    for n in [0, 1, 13, 14, 15, 16, 0x7F, 0x80, 0x81, 200] {
        let s = sii::Sii::new(&img[..n]);
        assert_eq!(s.checksum_ok(), n >= 16);
        let _ = (
            s.vendor_id(),
            s.general(),
            s.sync_manager(3),
            s.dc_op_mode(1),
        );
        let _ = s.categories().count();
        for k in 0..=255u8 {
            let _ = s.string(k);
        }
    }
}

#[test]
fn multi_device_writer_refuses_inconsistent_input() {
    let d = identity::device_description(Variant::HybridServo, EscFlavour::Lan9252, 0);
    let objs = drive_docs::variant_objects(Variant::HybridServo);
    let maps = drive_docs::pdo_maps(Variant::HybridServo, EscFlavour::Lan9252);
    let mut out = String::new();
    assert_eq!(
        esi::write_devices(&[], &mut out),
        Err(EsiError::Description(SiiError::InvalidDescription))
    );
    let other = sii::DeviceDescription {
        vendor_id: 0x1234,
        ..d
    };
    let dev = |desc| EsiDevice {
        desc,
        objects: objs,
        pdos: &maps,
        diag_texts: &[],
    };
    assert_eq!(
        esi::write_devices(&[dev(&d), dev(&other)], &mut out),
        Err(EsiError::Description(SiiError::InvalidDescription))
    );
    let mut one = String::new();
    esi::write(&d, objs, &maps, &mut one).unwrap();
    let mut many = String::new();
    esi::write_devices(&[dev(&d)], &mut many).unwrap();
    assert_eq!(one, many);
}

fn repo_path(rel: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(rel)
}

fn first_difference(a: &str, b: &str) -> String {
    for (i, (x, y)) in a.lines().zip(b.lines()).enumerate() {
        if x != y {
            return format!("line {}:\n  committed: {x}\n  generated: {y}", i + 1);
        }
    }
    format!(
        "lengths differ ({} vs {} lines)",
        a.lines().count(),
        b.lines().count()
    )
}

#[test]
fn committed_object_dictionary_md_is_up_to_date() {
    let path = repo_path("docs/object-dictionary.md");
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    let generated = drive_docs::od_reference();
    assert!(
        committed == generated,
        "docs/object-dictionary.md is out of date: run `cargo xtask od-doc` and commit it ({})",
        first_difference(&committed, &generated)
    );
    for o in OBJECTS {
        assert!(
            generated.contains(&format!("\n## 0x{:04X} ", o.index)),
            "{:#06x} missing",
            o.index
        );
    }
    assert!(generated.contains("| 0x1018 | 2 | Product code |"));
}

#[test]
fn committed_faults_md_is_up_to_date() {
    let committed = std::fs::read_to_string(repo_path("docs/faults.md")).unwrap_or_default();
    let generated = drive_docs::faults_reference();
    assert!(
        committed == generated,
        "docs/faults.md is out of date: run `cargo xtask faults-doc` and commit it ({})",
        first_difference(&committed, &generated)
    );
    // One row per kind, with the table's code.
    for k in firmware::faults::FaultKind::ALL {
        assert!(
            generated.contains(&format!(
                "\n| {} | {} | 0x{:04X} |",
                k as u8,
                k.info().name,
                k.code()
            )),
            "{k:?} missing"
        );
    }
}

#[test]
fn committed_esi_files_are_up_to_date() {
    let dir = repo_path("docs/esi");
    let files = drive_docs::esi_files().unwrap();
    let hint = "run `cargo run -p tests-host --release --bin drive-docs -- esi docs/esi` and commit docs/esi";
    for (name, data) in &files {
        let committed = std::fs::read(dir.join(name)).unwrap_or_default();
        assert!(&committed == data, "docs/esi/{name} is out of date: {hint}");
    }
    let mut present: Vec<String> = std::fs::read_dir(&dir)
        .map(|d| {
            d.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    present.sort();
    let want: Vec<String> = files.keys().cloned().collect();
    assert_eq!(
        present, want,
        "docs/esi holds exactly the generated files: {hint}"
    );
}

/// The drive's dictionary with the mapping objects the slave runtime serves.
struct WholeDrive {
    drive: Drive,
    pdo: PdoConfig,
}

impl Dictionary for WholeDrive {
    fn objects(&self) -> &'static [Object] {
        OBJECTS
    }
    fn read(
        &mut self,
        key: ObjectKey,
        buf: &mut [u8],
    ) -> Result<usize, ecat_slave_stack::od::SdoAbort> {
        let ObjectKey { index, .. } = key;
        match index {
            0x1600..=0x1C13 => self.pdo.read(key, buf),
            _ => self.drive.read(key, buf),
        }
    }
    fn write(
        &mut self,
        key: ObjectKey,
        data: &[u8],
        state: EsmState,
    ) -> Result<(), ecat_slave_stack::od::SdoAbort> {
        let ObjectKey { index, .. } = key;
        match index {
            0x1600..=0x1C13 => self.pdo.write(key, data, state, OBJECTS),
            _ => self.drive.write(key, data, state),
        }
    }
}

/// One mailbox exchange in Pre-Op: `body` after the 6-byte mailbox header (CoE).
fn exchange(
    srv: &mut ecat_slave_stack::mailbox::MailboxServer,
    d: &mut WholeDrive,
    counter: u8,
    body: &[u8],
) -> Vec<u8> {
    let mut f = vec![0u8; 6];
    f[0..2].copy_from_slice(&(body.len() as u16).to_le_bytes());
    f[5] = 0x03 | counter << 4;
    f.extend_from_slice(body);
    srv.on_request(&f, d, EsmState::PreOp, 0);
    let mut out = [0u8; 128];
    let n = srv.next_output(&mut out, 0);
    assert!(n >= 8, "no answer");
    out[..n].to_vec()
}

#[test]
fn coe_details_match_what_the_mailbox_server_implements() {
    let desc = identity::device_description(Variant::HybridServo, EscFlavour::Lan9252, 0);
    let c = desc.coe;
    let mut d = WholeDrive {
        drive: Drive::new(Variant::HybridServo, 0),
        pdo: PdoConfig::new(PDO_DEFAULTS),
    };
    let mut srv = ecat_slave_stack::mailbox::MailboxServer::new(128);
    let service = |out: &[u8]| u16::from_le_bytes([out[6], out[7]]) >> 12;
    // SDO information: get OD list (opcode 1), all objects (list type 1).
    let out = exchange(
        &mut srv,
        &mut d,
        1,
        &[0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00],
    );
    assert_eq!(service(&out), 8);
    assert_eq!(
        out[8] & 0x7F == 0x02,
        c.sdo_info,
        "SDO information answers an OD list"
    );
    // Complete access upload of 0x1018 from sub-index 0.
    let out = exchange(
        &mut srv,
        &mut d,
        2,
        &[0x00, 0x20, 0x50, 0x18, 0x10, 0x00, 0, 0, 0, 0],
    );
    assert_eq!(service(&out), 3, "SDO response, not an abort");
    assert_eq!(
        out[8] & 0xE0 == 0x40 && out[8] & 0x10 != 0,
        c.complete_access,
        "complete access upload answered as such ({:#04x})",
        out[8]
    );
    // PDO assignment and configuration writable in Pre-Op.
    let mut download = |counter: u8, index: u16, sub: u8, data: &[u8]| {
        let mut b = vec![0x00, 0x20, 0x23 | ((4 - data.len() as u8) << 2)];
        b.extend_from_slice(&index.to_le_bytes());
        b.push(sub);
        let mut v = [0u8; 4];
        v[..data.len()].copy_from_slice(data);
        b.extend_from_slice(&v);
        let out = exchange(&mut srv, &mut d, counter, &b);
        service(&out) == 3 && out[8] == 0x60
    };
    assert_eq!(download(3, 0x1C12, 0, &[0]), c.pdo_assign, "0x1C12:00 = 0");
    assert_eq!(
        download(4, 0x1C12, 1, &0x1601u16.to_le_bytes()),
        c.pdo_assign
    );
    assert_eq!(download(5, 0x1C12, 0, &[1]), c.pdo_assign);
    assert_eq!(download(6, 0x1601, 0, &[0]), c.pdo_config, "0x1601:00 = 0");
    assert_eq!(download(7, 0x1601, 0, &[6]), c.pdo_config);
}

/// The document without the PDOs that carry no `Sm` (the alternatives): the
/// `ethercat-esi` crate models a PDO with a mandatory SyncManager, where ETG.2000
/// makes `Sm` optional and means by it the default assignment. What is left is the
/// default configuration, which the crate can represent.
fn without_alternatives(xml: &str) -> String {
    let doc = Document::parse(xml).unwrap();
    let mut cut: Vec<_> = doc
        .descendants()
        .filter(|n| n.has_tag_name("RxPdo") || n.has_tag_name("TxPdo"))
        .filter(|n| n.attribute("Sm").is_none())
        .map(|n| n.range())
        .collect();
    assert!(!cut.is_empty(), "the ESI offers alternative PDOs");
    cut.sort_by_key(|r| std::cmp::Reverse(r.start));
    let mut out = xml.to_string();
    for r in cut {
        out.replace_range(r, "");
    }
    out
}

/// The ESI's default assignment (the PDOs with `Sm`, in document order) equals
/// 0x1C12 / 0x1C13 read through the dictionary and the SII PDO categories' SM bytes,
/// for both ESC flavours, both variants, generated and committed; the alternatives'
/// `Exclude` lists are symmetric, name only PDOs of the document, and no two PDOs of
/// the default assignment exclude each other.
#[test]
fn esi_default_assignment_equals_the_dictionary_and_the_sii() {
    for (esc, _) in FLAVOURS {
        let path = repo_path(&format!("docs/esi/{}", drive_docs::esi_file_name(esc)));
        let committed = std::fs::read_to_string(&path).expect("committed ESI file");
        for (which, xml) in [("committed", committed), ("generated", esi(esc))] {
            let doc = Document::parse(&xml).unwrap();
            for (v, _) in VARIANTS {
                let what = format!("{esc:?} {which} {v:?}");
                let dev = device_of(&doc, v);
                let img = image(v, esc);
                let mut rt = runtime();
                for (tag, kind, assign, sm) in
                    [("RxPdo", 51u16, 0x1C12u16, 2u8), ("TxPdo", 50, 0x1C13, 3)]
                {
                    let dictionary = assignment(&mut rt, assign);
                    let xs = children(dev, tag);
                    let in_esi: Vec<u16> = xs
                        .iter()
                        .filter(|x| x.attribute("Sm").is_some())
                        .inspect(|x| assert_eq!(x.attribute("Sm"), Some(sm.to_string().as_str())))
                        .map(|x| num(text(*x, "Index")) as u16)
                        .collect();
                    let in_sii: Vec<u16> = sii_pdos(&img, kind)
                        .iter()
                        .filter(|p| p.1 != 0xFF)
                        .inspect(|p| assert_eq!(p.1, sm, "{what}: SII SM byte"))
                        .map(|p| p.0)
                        .collect();
                    assert!(!dictionary.is_empty(), "{what}: {tag}");
                    assert_eq!(in_esi, dictionary, "{what}: {tag} ESI vs {assign:#06x}");
                    assert_eq!(in_sii, dictionary, "{what}: {tag} SII vs {assign:#06x}");
                    assert!(xs.len() > dictionary.len() || tag == "TxPdo", "{what}");
                    let index = |x: &Node| num(text(*x, "Index")) as u16;
                    let excl = |x: &Node| -> Vec<u16> {
                        children(*x, "Exclude")
                            .iter()
                            .map(|e| num(e.text().unwrap()) as u16)
                            .collect()
                    };
                    for x in &xs {
                        for e in excl(x) {
                            let other = xs
                                .iter()
                                .find(|y| index(y) == e)
                                .unwrap_or_else(|| panic!("{what}: excludes {e:#06x}"));
                            assert!(excl(other).contains(&index(x)), "{what}: symmetric");
                            assert!(
                                !(dictionary.contains(&e) && dictionary.contains(&index(x))),
                                "{what}: the default assignment excludes itself"
                            );
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn the_ethercat_esi_crate_parses_both_esi_files() {
    for (esc, _) in FLAVOURS {
        let path = repo_path(&format!("docs/esi/{}", drive_docs::esi_file_name(esc)));
        let committed = std::fs::read_to_string(&path).expect("committed ESI file");
        for (what, xml) in [("committed", committed), ("generated", esi(esc))] {
            let xml = without_alternatives(&xml);
            let info = ethercat_esi::EtherCatInfo::from_xml_str(&xml)
                .unwrap_or_else(|e| panic!("{esc:?} {what}: ethercat-esi: {e}"));
            assert_eq!(info.vendor.id, identity::VENDOR_ID, "{esc:?} {what}");
            let devs = &info.description.devices;
            assert_eq!(devs.len(), VARIANTS.len(), "{esc:?} {what}: devices");
            for (v, _) in VARIANTS {
                let d = devs
                    .iter()
                    .find(|d| d.product_code == v.product_code())
                    .unwrap_or_else(|| panic!("{esc:?} {what}: {v:?} missing"));
                assert_eq!(d.revision_no, identity::REVISION);
                assert_eq!(d.sm.len(), 4, "{esc:?} {what} {v:?}: SMs");
                let maps = drive_docs::pdo_maps(v, esc);
                for (list, rx, sm) in [(&d.rx_pdo, true, 2u8), (&d.tx_pdo, false, 3)] {
                    let want: Vec<_> = maps
                        .iter()
                        .filter(|m| m.is_rx() == rx && m.sm.is_some())
                        .collect();
                    assert_eq!(list.len(), want.len(), "{esc:?} {what} {v:?}: PDOs");
                    for (p, m) in list.iter().zip(want) {
                        assert_eq!(u16::from(p.idx), m.index);
                        assert_eq!(u8::from(p.sm), sm, "{:#06x}: Sm", m.index);
                        assert_eq!(p.entries.len(), m.entries.len());
                        for (e, raw) in p.entries.iter().zip(m.entries) {
                            let pe = esi::PdoEntry::decode(*raw);
                            assert_eq!(u16::from(e.entry_idx.idx), pe.key.index);
                            assert_eq!(u8::from(e.entry_idx.sub_idx), pe.key.sub);
                            assert_eq!(e.bit_len, usize::from(pe.bits));
                        }
                    }
                }
            }
        }
    }
}

/// One PDO of an SII PDO category: (index, SM byte, name, flags, entries as
/// (index, sub, name, data type code, bits)).
type SiiPdo = (u16, u8, String, u16, Vec<(u16, u8, String, u8, u8)>);

fn sii_pdos(img: &Image, kind: u16) -> Vec<SiiPdo> {
    let d = img.category(kind);
    let name = |i: u8| if i == 0 { String::new() } else { img.string(i) };
    let mut out = Vec::new();
    let mut at = 0;
    while at + 8 <= d.len() {
        let index = u16::from_le_bytes([d[at], d[at + 1]]);
        let n = usize::from(d[at + 2]);
        let (sm, pdo_name) = (d[at + 3], name(d[at + 5]));
        let flags = u16::from_le_bytes([d[at + 6], d[at + 7]]);
        at += 8;
        let mut entries = Vec::new();
        for _ in 0..n {
            let e = &d[at..at + 8];
            entries.push((
                u16::from_le_bytes([e[0], e[1]]),
                e[2],
                name(e[3]),
                e[4],
                e[5],
            ));
            at += 8;
        }
        out.push((index, sm, pdo_name, flags, entries));
    }
    assert_eq!(at, d.len(), "PDO category {kind}: no trailing bytes");
    out
}

#[test]
fn sii_pdo_categories_match_the_esi_pdos() {
    for (esc, _) in FLAVOURS {
        let xml = esi(esc);
        let doc = Document::parse(&xml).unwrap();
        for (v, _) in VARIANTS {
            let what = format!("{esc:?} {v:?}");
            let dev = device_of(&doc, v);
            let img = image(v, esc);
            let objs = drive_docs::variant_objects(v);
            let mut rt = runtime();
            for (tag, kind, assign, sm) in
                [("TxPdo", 50u16, 0x1C13u16, 3u8), ("RxPdo", 51, 0x1C12, 2)]
            {
                let assigned = assignment(&mut rt, assign);
                let xs = children(dev, tag);
                let pdos = sii_pdos(&img, kind);
                assert_eq!(pdos.len(), xs.len(), "{what}: {tag} count");
                for ((index, sm_byte, name, flags, entries), x) in pdos.iter().zip(&xs) {
                    assert_eq!(u64::from(*index), num(text(*x, "Index")), "{what}");
                    assert_eq!(name, text(*x, "Name"), "{what}: {index:#06x} name");
                    let want_sm = if assigned.contains(index) { sm } else { 0xFF };
                    assert_eq!(*sm_byte, want_sm, "{what}: {index:#06x} default SM");
                    assert_eq!(*flags, 0, "{what}: configurable, not mandatory");
                    let es = children(*x, "Entry");
                    assert_eq!(entries.len(), es.len(), "{what}: {index:#06x} entries");
                    for ((ei, sub, en, ty, bits), e) in entries.iter().zip(&es) {
                        assert_eq!(u64::from(*ei), num(text(*e, "Index")));
                        assert_eq!(u64::from(*sub), num(text(*e, "SubIndex")));
                        assert_eq!(u64::from(*bits), num(text(*e, "BitLen")));
                        assert_eq!(en, text(*e, "Name"), "{what}: {ei:#06x}:{sub} name");
                        let entry = objs
                            .iter()
                            .find(|o| o.index == *ei)
                            .and_then(|o| o.entry(*sub))
                            .expect("mapped entry exists");
                        assert_eq!(u16::from(*ty), entry.data_type.code(), "{what}: type code");
                        assert_eq!(text(*e, "DataType"), type_name(entry));
                    }
                }
            }
        }
    }
}

#[test]
fn esi_diag_messages_are_the_drive_texts() {
    // Every 0x10F3 message text of the drive (firmware::diagnosis::TEXTS) is in both
    // ESI files with its ID, and every message the drive makes names one of them.
    for name in ["ecs-lan9252.xml", "ecs-et1100.xml"] {
        let xml = std::fs::read_to_string(repo_path("docs/esi").join(name)).unwrap();
        for t in firmware::diagnosis::TEXTS {
            let mut text = String::new();
            ecat_slave_stack::esi::escape(&mut text, t.text).unwrap();
            let want = format!(
                "<DiagMessage><TextId>#x{:04X}</TextId><MessageText LcId=\"1033\">{text}</MessageText></DiagMessage>",
                t.id
            );
            // Once per device of the file (both variants).
            assert_eq!(xml.matches(&want).count(), 2, "{name}: {want}");
        }
    }
    for k in firmware::faults::FaultKind::ALL {
        let id = firmware::diagnosis::fault_text_id(k);
        assert!(firmware::diagnosis::text(id).is_some(), "{k:?}");
    }
}
