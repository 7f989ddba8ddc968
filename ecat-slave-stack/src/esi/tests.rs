//! Host-only: the generated document parsed by a real XML parser.
use super::*;
use crate::od::{EntryDesc, ObjectDesc};
use crate::sii::{self, EscFlavour};

const ID: [EntryDesc; 3] = [
    EntryDesc::new(0, "Number of entries", DataType::Unsigned8, Access::RO).default(2),
    EntryDesc::new(1, "Vendor <ID>", DataType::Unsigned32, Access::RO).default(0x0E5C),
    EntryDesc::new(2, "Product & code", DataType::Unsigned32, Access::RO).default(0x5840),
];
const CW: [EntryDesc; 1] =
    [EntryDesc::new(0, "Controlword", DataType::Unsigned16, Access::RW).pdo(PdoMappable::Rx)];
const SW: [EntryDesc; 1] =
    [EntryDesc::new(0, "Statusword", DataType::Unsigned16, Access::RO).pdo(PdoMappable::Tx)];
const NAME: [EntryDesc; 1] = [EntryDesc::text(0, "Device name", 12, "A \"quoted\" <name>")];
const FLAG: [EntryDesc; 1] = [EntryDesc::new(0, "Flag", DataType::Boolean, Access::RW).default(1)];
static OBJECTS: &[Object] = crate::packed_dictionary!(&[&SOURCE]);
const SOURCE: [ObjectDesc; 5] = [
    ObjectDesc::new(0x1008, "Device name", ObjectCode::Var, &NAME, ""),
    ObjectDesc::new(0x1018, "Identity", ObjectCode::Record, &ID, ""),
    ObjectDesc::new(0x2001, "Flag 'x'", ObjectCode::Var, &FLAG, ""),
    ObjectDesc::new(0x6040, "Controlword", ObjectCode::Var, &CW, ""),
    ObjectDesc::new(0x6041, "Statusword", ObjectCode::Var, &SW, ""),
];
/// The stack's PDO objects, packed.
static PDO_OBJECTS: &[Object] = crate::packed_dictionary!(&[crate::pdo::OBJECTS]);
static RX: [u32; 1] = [ObjectKey::new(0x6040, 0).mapping_word(16)];
static TX: [u32; 2] = [ObjectKey::new(0x6041, 0).mapping_word(16), 0x0000_0010];
static PDOS: [PdoMap; 2] = [
    PdoMap {
        index: 0x1600,
        name: Name::plain("Outputs"),
        sm: Some(2),
        fixed: false,
        mandatory: true,
        entries: &RX,
    },
    PdoMap {
        index: 0x1A00,
        name: Name::plain("Inputs"),
        sm: Some(3),
        fixed: true,
        mandatory: false,
        entries: &TX,
    },
];
const DESC: DeviceDescription = DeviceDescription {
    vendor_id: 0x0E5C,
    vendor_name: "Vendor & Sons <test>",
    product_code: 0x5841,
    revision: 0x0001_0000,
    serial: 0,
    type_name: "ECS-OL",
    name: "ECS-OL EtherCAT stepper",
    group_type: "Drives",
    group_name: "Drives",
    hardware_version: "1.0",
    software_version: "0.1.0",
    esc: EscFlavour::Et1100,
    sync_pulse_length: 1000,
    sync0_drive: sii::SyncDrive::PushPullActiveHigh,
    station_alias: 0,
    mailbox_protocols: sii::MBOX_COE,
    mailbox_data_link_layer: true,
    coe: sii::STANDARD_COE,
    fmmus: &sii::STANDARD_FMMUS,
    sync_managers: &sii::STANDARD_SYNC_MANAGERS,
    dc_op_modes: &sii::STANDARD_DC_OP_MODES,
    eeprom_bytes: 2048,
    physical_ports: 0x0011,
    profile_no: 402,
    ebus_current_ma: 0,
    bootstrap: None,
};

fn child<'a, 'i>(n: roxmltree::Node<'a, 'i>, tag: &str) -> roxmltree::Node<'a, 'i> {
    n.children()
        .find(|c| c.has_tag_name(tag))
        .unwrap_or_else(|| panic!("no <{tag}> in <{}>", n.tag_name().name()))
}

#[test]
fn parses_and_matches_description_and_dictionary() {
    let mut xml = String::new();
    write(&DESC, OBJECTS, &PDOS, &mut xml).unwrap();
    let doc = roxmltree::Document::parse(&xml).expect("well-formed XML");
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "EtherCATInfo");
    let vendor = child(root, "Vendor");
    assert_eq!(child(vendor, "Name").text(), Some("Vendor & Sons <test>"));
    assert_eq!(child(vendor, "Id").text(), Some("#x00000E5C"));
    let dev = child(child(child(root, "Descriptions"), "Devices"), "Device");
    let ty = child(dev, "Type");
    assert_eq!(ty.attribute("ProductCode"), Some("#x00005841"));
    assert_eq!(ty.attribute("RevisionNo"), Some("#x00010000"));
    assert_eq!(ty.text(), Some("ECS-OL"));
    assert_eq!(child(dev, "Name").text(), Some("ECS-OL EtherCAT stepper"));
    assert_eq!(child(dev, "GroupType").text(), Some("Drives"));
    // Element order of ETG.2000's DeviceType.
    let order: Vec<&str> = dev
        .children()
        .filter(|c| c.is_element())
        .map(|c| c.tag_name().name())
        .collect();
    let rank = |t: &str| {
        [
            "Type",
            "Name",
            "GroupType",
            "Profile",
            "Fmmu",
            "Sm",
            "RxPdo",
            "TxPdo",
            "Mailbox",
            "Dc",
            "Eeprom",
        ]
        .iter()
        .position(|x| *x == t)
        .unwrap()
    };
    assert!(
        order.windows(2).all(|w| rank(w[0]) <= rank(w[1])),
        "{order:?}"
    );
    let profile = child(dev, "Profile");
    assert_eq!(child(profile, "ProfileNo").text(), Some("402"));
    let dict = child(profile, "Dictionary");
    // Exactly the objects passed in, in order, with their names.
    let objs: Vec<_> = child(dict, "Objects")
        .children()
        .filter(|c| c.has_tag_name("Object"))
        .collect();
    assert_eq!(objs.len(), OBJECTS.len());
    for (o, x) in OBJECTS.iter().zip(&objs) {
        assert_eq!(
            child(*x, "Index").text().unwrap(),
            format!("#x{:04X}", o.index)
        );
        assert_eq!(
            child(*x, "Name").text().map(String::from),
            Some(o.name().to_string())
        );
        // every Type is defined in DataTypes
        let t = child(*x, "Type").text().unwrap();
        let dts = child(dict, "DataTypes");
        assert!(
            dts.children()
                .any(|d| d.has_tag_name("DataType") && child(d, "Name").text() == Some(t)),
            "type {t} not defined"
        );
    }
    let rec = objs[1];
    assert_eq!(child(rec, "BitSize").text(), Some("80"));
    let subs: Vec<_> = child(rec, "Info")
        .children()
        .filter(|c| c.has_tag_name("SubItem"))
        .collect();
    assert_eq!(subs.len(), 3);
    assert_eq!(child(subs[1], "Name").text(), Some("Vendor <ID>"));
    assert_eq!(
        child(child(subs[2], "Info"), "DefaultData").text(),
        Some("40580000")
    );
    assert_eq!(
        child(child(objs[0], "Info"), "DefaultString").text(),
        Some("A \"quoted\" <name>")
    );
    assert_eq!(child(objs[2], "Name").text(), Some("Flag 'x'"));
    assert_eq!(
        child(child(objs[2], "Info"), "DefaultData").text(),
        Some("01")
    );
    let cw_flags = child(objs[3], "Flags");
    assert_eq!(child(cw_flags, "Access").text(), Some("rw"));
    assert_eq!(child(cw_flags, "PdoMapping").text(), Some("R"));
    // Sm list = SII SyncManager list.
    let sms: Vec<_> = dev.children().filter(|c| c.has_tag_name("Sm")).collect();
    assert_eq!(sms.len(), DESC.sync_managers.len());
    for (s, x) in DESC.sync_managers.iter().zip(&sms) {
        assert_eq!(
            x.attribute("StartAddress").unwrap(),
            format!("#x{:04X}", s.start)
        );
        assert_eq!(
            x.attribute("ControlByte").unwrap(),
            format!("#x{:02X}", s.control)
        );
        assert_eq!(x.attribute("Enable"), Some("1"));
        assert_eq!(x.text(), Some(s.kind.esi()));
    }
    let fmmus: Vec<_> = dev
        .children()
        .filter(|c| c.has_tag_name("Fmmu"))
        .map(|c| c.text().unwrap())
        .collect();
    assert_eq!(fmmus, ["Outputs", "Inputs", "MBoxState"]);
    let rx = child(dev, "RxPdo");
    assert_eq!(rx.attribute("Sm"), Some("2"));
    assert_eq!(rx.attribute("Mandatory"), Some("1"));
    let tx = child(dev, "TxPdo");
    assert_eq!(tx.attribute("Fixed"), Some("1"));
    let entries: Vec<_> = tx.children().filter(|c| c.has_tag_name("Entry")).collect();
    assert_eq!(entries.len(), 2);
    assert_eq!(child(entries[0], "DataType").text(), Some("UINT"));
    assert_eq!(child(entries[1], "Index").text(), Some("#x0"));
    let coe = child(child(dev, "Mailbox"), "CoE");
    for a in ["SdoInfo", "PdoAssign", "PdoConfig", "CompleteAccess"] {
        assert_eq!(coe.attribute(a), Some("true"), "{a}");
    }
    assert_eq!(coe.attribute("PdoUpload"), Some("false"));
    let modes: Vec<_> = child(dev, "Dc")
        .children()
        .filter(|c| c.has_tag_name("OpMode"))
        .collect();
    assert_eq!(modes.len(), 2);
    assert_eq!(child(modes[1], "AssignActivate").text(), Some("#x300"));
    assert_eq!(
        child(modes[1], "CycleTimeSync0").attribute("Factor"),
        Some("1")
    );
    assert_eq!(child(modes[0], "AssignActivate").text(), Some("#x0"));
    assert!(!modes[0]
        .children()
        .any(|c| c.has_tag_name("CycleTimeSync0")));
    let ee = child(dev, "Eeprom");
    assert_eq!(child(ee, "ByteSize").text(), Some("2048"));
    // ConfigData = SII words 0-6 of the ET1100 flavour.
    assert_eq!(
        child(ee, "ConfigData").text(),
        Some("050C030EE8030000000000000000")
    );
    let mut img = vec![0u8; 2048];
    let n = sii::build(&DESC, &mut img).unwrap();
    let s = sii::Sii::new(&img[..n]);
    let g = s.general().unwrap();
    assert_eq!(g.coe_details & 0x2E, 0x2E);
    assert_eq!(
        g.coe_details & (1 << 5) != 0,
        coe.attribute("CompleteAccess") == Some("true")
    );
    assert_eq!(
        g.flags & 4 != 0,
        child(dev, "Mailbox").attribute("DataLinkLayer") == Some("true")
    );
}

#[test]
fn foe_is_announced_in_the_esi_and_the_sii() {
    let desc = DeviceDescription {
        mailbox_protocols: sii::MBOX_COE | sii::MBOX_FOE,
        ..DESC
    };
    for (d, foe) in [(&DESC, false), (&desc, true)] {
        let mut xml = String::new();
        write(d, PDO_OBJECTS, &[], &mut xml).unwrap();
        let doc = roxmltree::Document::parse(&xml).expect("well-formed XML");
        let mbx = doc
            .descendants()
            .find(|n| n.has_tag_name("Mailbox"))
            .unwrap();
        let kinds: Vec<_> = mbx
            .children()
            .filter(|c| c.is_element())
            .map(|c| c.tag_name().name())
            .collect();
        assert_eq!(
            kinds,
            if foe {
                &["CoE", "FoE"][..]
            } else {
                &["CoE"][..]
            }
        );
        let mut img = vec![0u8; 2048];
        let n = sii::build(d, &mut img).unwrap();
        let s = sii::Sii::new(&img[..n]);
        assert_eq!(s.general().unwrap().foe_details, foe as u8);
        assert_eq!(s.word(sii::word::MBX_PROTOCOLS), Some(d.mailbox_protocols));
        assert_eq!(s.bootstrap_mailbox(), None);
        let boot = crate::sm::BootMailbox::STANDARD;
        sii::set_bootstrap_mailbox(&mut img, &boot).unwrap();
        let s = sii::Sii::new(&img[..n]);
        assert_eq!(s.bootstrap_mailbox(), Some(boot));
        assert!(s.checksum_ok());
        assert_eq!(
            sii::set_bootstrap_mailbox(&mut img[..0x2F], &boot),
            Err(SiiError::BufferTooSmall)
        );
    }
}

#[test]
fn the_stacks_own_object_tables_give_a_valid_document() {
    let mut xml = String::new();
    write(&DESC, PDO_OBJECTS, &[], &mut xml).unwrap();
    let doc = roxmltree::Document::parse(&xml).expect("well-formed XML");
    let n = doc
        .descendants()
        .filter(|d| d.has_tag_name("Object"))
        .count();
    assert_eq!(n, crate::pdo::OBJECTS.len());
}

/// Alternatives: a PDO not assigned by default carries no `Sm` (the ESI assigns what
/// the defaults assign), and PDOs of one direction that map a common object exclude
/// each other, both ways; a PDO sharing nothing (or only padding) excludes none.
#[test]
fn alternatives_carry_no_sm_and_exclude_what_they_share() {
    static A: [u32; 2] = [ObjectKey::new(0x6040, 0).mapping_word(16), 0x0000_0010];
    static B: [u32; 1] = [ObjectKey::new(0x6040, 0).mapping_word(16)];
    static C: [u32; 1] = [0x0000_0010];
    static T: [u32; 1] = [ObjectKey::new(0x6041, 0).mapping_word(16)];
    let map = |index, sm, entries| PdoMap {
        index,
        name: Name::plain("P"),
        sm,
        fixed: false,
        mandatory: false,
        entries,
    };
    let pdos = [
        map(0x1600, Some(2), &A[..]),
        map(0x1601, None, &B[..]),
        map(0x1602, None, &C[..]),
        map(0x1A00, Some(3), &T[..]),
        map(0x1A01, None, &T[..]),
    ];
    let ex = |i: usize| excludes(&pdos, &pdos[i]).collect::<Vec<_>>();
    assert_eq!(ex(0), [0x1601]);
    assert_eq!(ex(1), [0x1600]);
    assert_eq!(ex(2), [] as [u16; 0], "padding alone shares nothing");
    assert_eq!(ex(3), [0x1A01]);
    assert_eq!(ex(4), [0x1A00]);
    let mut xml = String::new();
    write(&DESC, OBJECTS, &pdos, &mut xml).unwrap();
    let doc = roxmltree::Document::parse(&xml).unwrap();
    let dev = child(
        child(child(doc.root_element(), "Descriptions"), "Devices"),
        "Device",
    );
    for (x, p) in dev
        .children()
        .filter(|c| c.has_tag_name("RxPdo") || c.has_tag_name("TxPdo"))
        .zip(&pdos)
    {
        let sm = p.sm.map(|s| s.to_string());
        assert_eq!(x.attribute("Sm"), sm.as_deref(), "{:#06x}", p.index);
        // ETG.2000 PdoType order: Index, Name, Exclude*, Entry*.
        let tags: Vec<_> = x
            .children()
            .filter(|c| c.is_element())
            .map(|c| c.tag_name().name())
            .collect();
        let n_ex = tags.iter().filter(|t| **t == "Exclude").count();
        assert_eq!(&tags[..2], ["Index", "Name"]);
        assert!(tags[2..2 + n_ex].iter().all(|t| *t == "Exclude"));
        assert!(tags[2 + n_ex..].iter().all(|t| *t == "Entry"));
        let listed: Vec<_> = x
            .children()
            .filter(|c| c.has_tag_name("Exclude"))
            .map(|c| u16::from_str_radix(&c.text().unwrap()[2..], 16).unwrap())
            .collect();
        assert_eq!(listed, excludes(&pdos, p).collect::<Vec<_>>());
    }
}
