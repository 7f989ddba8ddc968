use super::*;

static OBJS: &[Object] = crate::packed_dictionary!(&[SOURCE]);
const SOURCE: &[ObjectDesc] = &[
    ObjectDesc::var(
        0x1000,
        "Device type",
        &[EntryDesc::new(0, "Device type", DataType::Unsigned32, Access::RO).default(0x0002_0192)],
        "Profile | type",
    ),
    ObjectDesc::record(
        0x2000,
        "Gains",
        &[
            EntryDesc::new(0, "Count", DataType::Unsigned8, Access::RO),
            EntryDesc::new(1, "Kp", DataType::Unsigned16, Access::RW_PREOP)
                .unit("mA")
                .saved()
                .pdo(PdoMappable::Rx),
            EntryDesc::text(2, "Label", 8, "abc"),
        ],
        "",
    ),
];

#[test]
fn reference_lists_every_entry() {
    let mut s = std::string::String::new();
    write_reference(OBJS, &mut s).unwrap();
    assert!(s.contains("| 0x1000 | Device type | VAR | 1 |"));
    assert!(s.contains("## 0x2000 Gains (RECORD)"));
    // The description text is only kept with the `descriptions` feature.
    assert_eq!(
        s.contains("Profile \\| type"),
        cfg!(feature = "descriptions")
    );
    assert!(s.contains("| 1 | Kp | UINT | 16 | rPSO wP | Rx | 0 | 65535 | - | mA | yes |"));
    assert!(s.contains("| 2 | Label | STRING | 64 | rPSO | - | - | - | \"abc\" | - | no |"));
    assert!(s.contains(
        "| 0 | Device type | UDINT | 32 | rPSO | - | 0 | 4294967295 | 131474 (0x20192) | - | no |"
    ));
}

#[test]
fn od_lists_and_abort_table() {
    assert_eq!(OdListType::All.count(OBJS), 2);
    assert_eq!(OdListType::RxPdoMappable.count(OBJS), 1);
    assert_eq!(OdListType::TxPdoMappable.count(OBJS), 0);
    assert_eq!(OdListType::Settings.count(OBJS), 1);
    assert_eq!(OdListType::from_code(6), None);
    for a in SdoAbort::ALL {
        assert_eq!(SdoAbort::from_code(a.code()), Some(*a));
    }
    assert!(SdoAbort::ALL.windows(2).all(|w| w[0].code() < w[1].code()));
    assert_eq!(SdoAbort::from_code(0x0504_0002), None);
}

#[test]
fn constructors_fill_the_object_code_and_the_count_entry() {
    const E: &[EntryDesc] = &[EntryDesc::count(3)];
    static PACKED: &[Object] = crate::packed_dictionary!(&[&[
        ObjectDesc::var(0x1000, "V", E, "d"),
        ObjectDesc::array(0x1001, "A", E, "d"),
        ObjectDesc::record(0x1002, "R", E, "d"),
    ]]);
    let [v, a, r] = [0x1000, 0x1001, 0x1002].map(|i| find(PACKED, i).unwrap());
    assert_eq!(
        (v.code(), a.code(), r.code()),
        (ObjectCode::Var, ObjectCode::Array, ObjectCode::Record)
    );
    let d = if cfg!(feature = "descriptions") {
        "d"
    } else {
        ""
    };
    assert_eq!(
        (r.index, r.name().to_string(), r.description()),
        (0x1002, "R".to_string(), d)
    );
    let c = r.entries()[0];
    assert_eq!(
        (c.sub, c.name().to_string(), c.data_type, c.access),
        (
            0,
            "Number of entries".to_string(),
            DataType::Unsigned8,
            Access::RO
        )
    );
    assert_eq!(
        (c.bits(), c.min(), c.max(), c.default_value()),
        (8, 0, 255, DefaultValue::Int(3))
    );
    assert!(!c.is_saved() && c.pdo_mappable() == PdoMappable::No && c.unit_text().is_empty());
}

/// The packed layout reads back every field it was given (names, entries, code,
/// mapping, flags, range, default), whatever the order of the builder calls.
#[test]
fn every_unit_text_reads_back() {
    for (i, u) in UNITS.iter().enumerate() {
        let e = EntryDesc::new(1, "x", DataType::Unsigned16, Access::RO);
        let e = if i == 0 { e } else { e.unit(u) };
        assert_eq!(e.unit_text(), *u, "unit {i}");
    }
    // An index past the table (never set by `EntryDesc::unit`) reads as no unit.
    let mut e = find(OBJS, 0x2000).unwrap().entries()[1];
    assert_eq!(e.unit_text(), "mA");
    for i in [UNITS.len(), 200, 255] {
        e.unit = i as u8;
        assert_eq!(e.unit_text(), "");
    }
}

#[test]
fn packed_fields_read_back() {
    const LONGEST_OBJECT_NAME: &str =
        "abcdefghijklmnopqrstuvwxyzabcdefghijklmnopqrstuvwxyzabcdefghijk";
    const LONGEST_ENTRY_NAME: &str = concat!(
        "0123456789012345678901234567890123456789012345678901234567890123456789",
        "0123456789012345678901234567890123456789012345678901234567890123456789",
        "0123456789012345678901234567890123456789012345678901234567890123456789",
        "012345678901234567890123456789012345678901234"
    );
    const ENTRIES: &[EntryDesc] = &[
        EntryDesc::count(2),
        EntryDesc::new(1, LONGEST_ENTRY_NAME, DataType::Integer16, Access::RW)
            .pdo(PdoMappable::RxTx)
            .saved()
            .range(-5, 7)
            .default(-3)
            .unit("°C"),
        EntryDesc::new(2, "", DataType::Integer32, Access::RO)
            .default(-1)
            .pdo(PdoMappable::Tx)
            .range(i32::MIN as i64, -2),
    ];
    const D: ObjectDesc = ObjectDesc::record(0x2001, LONGEST_OBJECT_NAME, ENTRIES, "");
    static PACKED: &[Object] = crate::packed_dictionary!(&[&[D]]);
    let o0 = PACKED[0];
    assert_eq!(LONGEST_OBJECT_NAME.len(), MAX_OBJECT_NAME);
    assert_eq!(LONGEST_ENTRY_NAME.len(), 255);
    assert_eq!(o0.name(), LONGEST_OBJECT_NAME);
    assert_eq!(o0.code(), ObjectCode::Record);
    assert_eq!(o0.entries(), ENTRIES);
    assert_eq!(o0.entries().len(), 3);
    let e = o0.entries()[1];
    assert_eq!(e.name(), LONGEST_ENTRY_NAME);
    assert_eq!(
        (e.sub, e.data_type, e.bits(), e.access),
        (1, DataType::Integer16, 16, Access::RW)
    );
    assert_eq!(e.pdo_mappable(), PdoMappable::RxTx);
    assert!(e.is_saved());
    assert_eq!(
        (e.min(), e.max(), e.default_value()),
        (-5, 7, DefaultValue::Int(-3))
    );
    assert_eq!(e.unit_text(), "°C");
    assert_eq!(e.sdo_info_access(), 0x3F | 0xC0);
    let f = o0.entries()[2];
    assert_eq!(f.name(), "");
    assert_eq!(f.pdo_mappable(), PdoMappable::Tx);
    assert!(!f.is_saved());
    assert_eq!(
        (f.min(), f.max(), f.default_value()),
        (i32::MIN as i64, -2, DefaultValue::Int(-1))
    );
    for p in [
        PdoMappable::No,
        PdoMappable::Rx,
        PdoMappable::Tx,
        PdoMappable::RxTx,
    ] {
        let e = EntryDesc::new(0, "x", DataType::Unsigned8, Access::RO).pdo(p);
        assert_eq!(e.pdo_mappable(), p);
        assert_eq!(e.pdo(PdoMappable::No).pdo_mappable(), PdoMappable::No);
    }
    for code in [ObjectCode::Var, ObjectCode::Array, ObjectCode::Record] {
        let o = ObjectDesc::new(0x3000, "n", code, ENTRIES, "");
        assert_eq!((o.code(), o.name()), (code, "n"));
    }
    let o = D.with_entries(&ENTRIES[..1]);
    assert_eq!(
        (o.entries().len(), o.name(), o.code()),
        (1, D.name(), D.code())
    );
    assert_ne!(o, D);
    assert_eq!(D, D.with_entries(ENTRIES));
    assert_eq!(o0, D);
}

/// Replacing the default keeps the name, mapping, 'save' flag and unit, and moves
/// between a text and a numeric default as before the packing.
#[test]
fn replaced_defaults_keep_the_other_fields() {
    let n = EntryDesc::new(3, "Gain", DataType::Unsigned16, Access::RW)
        .range(1, 100)
        .pdo(PdoMappable::Rx)
        .saved()
        .unit("mA");
    assert_eq!(n.default_value(), DefaultValue::None);
    let d = n.with_default_value(DefaultValue::Int(42));
    assert_eq!(
        (d.min(), d.max(), d.default_value()),
        (1, 100, DefaultValue::Int(42))
    );
    let none = d.with_default_value(DefaultValue::None);
    assert_eq!(
        (none.min(), none.max(), none.default_value()),
        (1, 100, DefaultValue::None)
    );
    let t = d.with_default_value(DefaultValue::Text("seven"));
    assert_eq!(
        (t.min(), t.max(), t.default_value()),
        (0, 0, DefaultValue::Text("seven"))
    );
    for x in [d, none, t] {
        assert_eq!((x.name(), x.sub(), x.unit_text()), ("Gain", 3, "mA"));
        assert_eq!(x.pdo_mappable(), PdoMappable::Rx);
        assert!(x.is_saved());
    }
    // A text entry: range and numeric default do not apply; an Int default turns
    // it numeric with the natural range.
    let s = EntryDesc::text(0, "Label", 8, "abc");
    assert_eq!(s.range(1, 2).default(5), s);
    assert_eq!(
        s.with_default_value(DefaultValue::None).default_value(),
        DefaultValue::Text("abc")
    );
    let i = s.with_default_value(DefaultValue::Int(9));
    assert_eq!(
        (i.min(), i.max(), i.default_value()),
        (0, 0, DefaultValue::Int(9))
    );
    assert_eq!((i.bits(), i.name()), (64, "Label"));
    // Equality is by content, not by where the name is stored.
    let owned = std::string::String::from("Gain");
    let same = EntryDesc::new(
        3,
        std::boxed::Box::leak(owned.into_boxed_str()),
        DataType::Unsigned16,
        Access::RW,
    )
    .range(1, 100)
    .pdo(PdoMappable::Rx)
    .saved()
    .unit("mA");
    assert_eq!(same, n);
    assert_ne!(same.pdo(PdoMappable::Tx), n);
    assert!(std::format!("{n:?}").contains("\"Gain\""));
}

/// The natural range stored as 32-bit patterns (and the 64-bit types' flag) reads
/// back as the type's range, for every type, also after a text default is replaced.
#[test]
fn natural_range_of_every_type() {
    for t in DataType::ALL {
        let (bits, lo, hi) = type_range(t);
        let e = EntryDesc::new(1, "x", t, Access::RW);
        assert_eq!((e.bits(), e.min(), e.max()), (bits, lo, hi), "{t:?}");
        assert_eq!(e.default_value(), DefaultValue::None, "{t:?}");
        let d = e
            .with_default_value(DefaultValue::Text("t"))
            .with_default_value(DefaultValue::Int(0));
        assert_eq!((d.min(), d.max()), (lo, hi), "{t:?}");
        assert_eq!(d.default_value(), DefaultValue::Int(0), "{t:?}");
    }
    let l = EntryDesc::new(1, "x", DataType::Integer64, Access::RW).range(-7, 7);
    assert_eq!((l.min(), l.max()), (-7, 7));
}

#[test]
#[should_panic(expected = "longer than MAX_OBJECT_NAME")]
fn object_name_over_the_limit_is_refused() {
    let name = std::string::String::from_utf8(std::vec![b'a'; MAX_OBJECT_NAME + 1]).unwrap();
    let _ = ObjectDesc::var(
        0x2000,
        std::boxed::Box::leak(name.into_boxed_str()),
        &[],
        "",
    );
}

#[test]
#[should_panic(expected = "longer than 255 bytes")]
fn entry_name_over_the_limit_is_refused() {
    let name = std::string::String::from_utf8(std::vec![b'a'; 256]).unwrap();
    let _ = EntryDesc::new(
        0,
        std::boxed::Box::leak(name.into_boxed_str()),
        DataType::Unsigned8,
        Access::RO,
    );
}

#[test]
fn type_ranges_of_the_types() {
    assert_eq!(type_range(DataType::Boolean), (1, 0, 1));
    assert_eq!(type_range(DataType::Integer8), (8, -128, 127));
    assert_eq!(type_range(DataType::Integer16), (16, -32768, 32767));
    assert_eq!(type_range(DataType::Integer64), (64, i64::MIN, i64::MAX));
    assert_eq!(type_range(DataType::Unsigned32), (32, 0, u32::MAX as i64));
    assert_eq!(type_range(DataType::Unsigned64), (64, 0, i64::MAX));
    assert_eq!(type_range(DataType::Bit3), (3, 0, 7));
    assert_eq!(type_range(DataType::Bit8), (8, 0, 255));
    assert_eq!(type_range(DataType::Real32), (32, 0, 0));
    assert_eq!(type_range(DataType::OctetString), (0, 0, 0));
}
