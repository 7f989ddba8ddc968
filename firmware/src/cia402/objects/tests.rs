extern crate std;
use super::*;
use crate::dictionary::Sdo;
use ecat_slave_stack::od;
use ecat_slave_stack::od::{DefaultValue, Entry, Object, ObjectKey};

/// The table as the product packs it.
static PACKED: &[Object] = ecat_slave_stack::packed_dictionary!(&[OBJECTS]);

#[test]
fn table_is_well_formed_and_in_range() {
    assert!(od::is_well_formed(PACKED));
    assert!(PACKED.iter().all(|o| (0x6000..=0x6FFF).contains(&o.index)));
}

#[test]
fn every_entry_has_a_value_and_defaults_match() {
    let d = Cia402::new();
    for o in PACKED {
        for e in o.entries() {
            let v = d.value(o.index, e.sub);
            assert!(v.is_some(), "{:#06x}:{}", o.index, e.sub);
            if let DefaultValue::Int(def) = e.default_value() {
                assert_eq!(v, Some(def), "default of {:#06x}:{}", o.index, e.sub);
                assert!(
                    def >= e.min() && def <= e.max(),
                    "default range {:#06x}:{}",
                    o.index,
                    e.sub
                );
            }
        }
    }
}

#[test]
fn slots_match_the_table() {
    for (i, &(idx, sub)) in RX_SLOTS.iter().enumerate() {
        let e = od::find_entry(PACKED, ObjectKey::new(idx, sub)).unwrap();
        assert!(e.pdo_mappable().rx(), "{idx:#06x}");
        assert_eq!(rx_slot(idx, sub), Some(i as u8));
    }
    for (i, &(idx, sub)) in TX_SLOTS.iter().enumerate() {
        let e = od::find_entry(PACKED, ObjectKey::new(idx, sub)).unwrap();
        assert!(e.pdo_mappable().tx(), "{idx:#06x}");
        assert_eq!(tx_slot(idx, sub), Some(i as u8));
    }
    // Every mappable entry has a slot.
    for o in PACKED {
        for e in o.entries() {
            assert_eq!(
                e.pdo_mappable().rx(),
                rx_slot(o.index, e.sub).is_some(),
                "{:#06x}:{}",
                o.index,
                e.sub
            );
            assert_eq!(
                e.pdo_mappable().tx(),
                tx_slot(o.index, e.sub).is_some(),
                "{:#06x}:{}",
                o.index,
                e.sub
            );
        }
    }
}

#[test]
fn fields_cover_exactly_the_entries() {
    // Every entry of OBJECTS has one ENTRY_KEYS row and every row is an entry.
    let mut n = 0;
    for o in PACKED {
        for e in o.entries() {
            let rows = ENTRY_KEYS
                .iter()
                .filter(|&&(index, sub)| index == o.index && sub == e.sub)
                .count();
            assert_eq!(rows, 1, "{:#06x}:{}", o.index, e.sub);
            n += 1;
        }
    }
    assert_eq!(n, ENTRY_KEYS.len());
    let d = Cia402::new();
    assert_eq!(d.value(0x6040, 1), None);
    assert_eq!(d.value(0x607D, 3), None);
    assert_eq!(d.value(0x6000, 0), None);
    assert_eq!(d.value(0x6FFF, 0), None);
}

#[test]
fn sdo_write_changes_only_its_entry() {
    // Each writable entry at its most negative (or largest) value: the value reads
    // back sign-extended and no other entry changes (the field widths are right).
    let all = |d: &Cia402| -> std::vec::Vec<(u16, u8, Option<i64>)> {
        PACKED
            .iter()
            .flat_map(|o| o.entries().iter().map(move |e| (o.index, e.sub)))
            .map(|(i, s)| (i, s, d.value(i, s)))
            .collect()
    };
    for o in PACKED {
        for e in o.entries().iter().filter(|e| e.access.writable()) {
            let (idx, sub) = (o.index, e.sub);
            let val: i64 = match (idx, sub) {
                (0x6060, 0) => 6,
                (0x6098, 0) => 1,
                (0x60B8, 0) => 0x0011,
                (0x6086, 0) => 3,
                (0x607E, 0) => 0xC0,
                _ if e.min() < 0 => e.min(),
                _ => e.max(),
            };
            let before = all(&Cia402::new());
            let d = written_and_read_back(e, idx, sub, val);
            for ((i, s, v0), (_, _, v1)) in before.iter().zip(all(&d).iter()) {
                // The probe function also sets the probe status (enabled bits).
                if (*i, *s) != (idx, sub) && !(idx == 0x60B8 && *i == 0x60B9) {
                    assert_eq!(v0, v1, "{idx:#06x}:{sub} changed {i:#06x}:{s}");
                }
            }
        }
    }
}

#[test]
fn every_writable_entry_reads_back_what_sdo_wrote() {
    for o in PACKED {
        for e in o.entries().iter().filter(|e| e.access.writable()) {
            let (idx, sub) = (o.index, e.sub);
            let val: i64 = match (idx, sub) {
                (0x6060, 0) => 3,
                (0x6098, 0) => 17,
                (0x60B8, 0) => 0x0011,
                (0x6086, 0) => 3,
                (0x607E, 0) => 0x80,
                _ => e.max().min(12_345),
            };
            written_and_read_back(e, idx, sub, val);
        }
    }
}

/// A new `Cia402` after an SDO write of `val` to `idx:sub`, checked to accept it and
/// to read it back.
fn written_and_read_back(e: &Entry, idx: u16, sub: u8, val: i64) -> Cia402 {
    let mut d = Cia402::new();
    let bytes = (val as u64).to_le_bytes();
    assert_eq!(
        d.write(idx, sub, &bytes[..e.byte_len()]),
        Ok(()),
        "{idx:#06x}:{sub}"
    );
    assert_eq!(d.value(idx, sub), Some(val), "{idx:#06x}:{sub}");
    d
}

#[test]
fn rx_slots_and_sdo_write_agree() {
    // Writing each Rx slot and reading the entry back by SDO gives the same value.
    for (i, &(idx, sub)) in RX_SLOTS.iter().enumerate() {
        let e = od::find_entry(PACKED, ObjectKey::new(idx, sub)).unwrap();
        let val: i64 = match (idx, sub) {
            (0x6060, 0) => 3,
            (0x6098, 0) => 17,
            (0x60B8, 0) => 0x0011,
            (0x6072, 0) => 800,
            _ => e.max().min(12_345),
        };
        let mut d = Cia402::new();
        d.set_rx(i as u8, &(val as u32).to_le_bytes()[..e.byte_len()]);
        assert_eq!(d.value(idx, sub), Some(val), "{idx:#06x}:{sub}");
    }
}

#[test]
fn tx_slots_and_sdo_read_agree() {
    let mut d = Cia402::new();
    let fb = crate::cia402::DriveFeedback {
        position: -1234,
        velocity: 777,
        torque: -55,
        current: 66,
        digital_inputs: 0x5,
        ..Default::default()
    };
    d.cycle(&fb, 0.001);
    for (i, &(idx, sub)) in TX_SLOTS.iter().enumerate() {
        let mut a = [0u8; 8];
        let n = d.read(idx, sub, &mut a).unwrap();
        let mut b = [0u8; 4];
        d.get_tx(i as u8, &mut b[..n]);
        assert_eq!(&a[..n], &b[..n], "{idx:#06x}:{sub}");
    }
}

#[test]
fn control_effort_follows_the_feedback_and_the_position_polarity() {
    let mut d = Cia402::new();
    let fb = crate::cia402::DriveFeedback {
        control_effort: 12_345,
        ..Default::default()
    };
    d.cycle(&fb, 0.001);
    assert_eq!(d.value(0x60FA, 0), Some(12_345));
    let slot = tx_slot(0x60FA, 0).expect("0x60FA is TxPDO-mappable");
    assert_eq!(d.get_tx_raw(slot) as i32, 12_345);
    assert_eq!(d.write(0x60FA, 0, &[0; 4]), Err(SdoAbort::WriteReadOnly));
    // Position polarity (0x607E bit 7) turns the controller's output with the position.
    d.write(0x607E, 0, &[0x80]).unwrap();
    d.cycle(&fb, 0.001);
    assert_eq!(d.value(0x60FA, 0), Some(-12_345));
}

#[test]
fn stack_process_data_trait() {
    use ecat_slave_stack::pdo::ProcessData;
    let mut d = Cia402::new();
    let cw = ProcessData::rx_slot(&d, ObjectKey::new(0x6040, 0)).unwrap();
    let m = ProcessData::rx_slot(&d, ObjectKey::new(0x6060, 0)).unwrap();
    let t = ProcessData::rx_slot(&d, ObjectKey::new(0x607A, 0)).unwrap();
    assert_eq!(ProcessData::rx_slot(&d, ObjectKey::new(0x6041, 0)), None);
    assert_eq!(ProcessData::tx_slot(&d, ObjectKey::new(0x6040, 0)), None);
    ProcessData::set_rx(&mut d, cw, 0x0006);
    ProcessData::set_rx(&mut d, m, 0xF8); // -8: not a mode, ignored
    ProcessData::set_rx(&mut d, m, 0x08);
    ProcessData::set_rx(&mut d, t, 0xFFFF_FFFE);
    ProcessData::set_rx(&mut d, 0x1234, 5); // unknown slot: ignored
    assert_eq!(d.value(0x6040, 0), Some(6));
    assert_eq!(d.value(0x6060, 0), Some(8));
    assert_eq!(d.value(0x607A, 0), Some(-2));
    d.cycle(
        &crate::cia402::DriveFeedback {
            position: -5,
            ..Default::default()
        },
        0.001,
    );
    let sw = ProcessData::tx_slot(&d, ObjectKey::new(0x6041, 0)).unwrap();
    let pos = ProcessData::tx_slot(&d, ObjectKey::new(0x6064, 0)).unwrap();
    assert_eq!(ProcessData::get_tx(&d, sw) as u16 & 0x6F, 0x21);
    assert_eq!(ProcessData::get_tx(&d, pos) as u32 as i32, -5);
    assert_eq!(ProcessData::get_tx(&d, 0x1234), 0);
}

#[test]
fn sdo_errors() {
    let mut d = Cia402::new();
    let mut buf = [0u8; 4];
    assert_eq!(
        d.read(0x6000, 0, &mut buf),
        Err(SdoAbort::ObjectDoesNotExist)
    );
    assert_eq!(
        d.read(0x6040, 1, &mut buf),
        Err(SdoAbort::SubindexDoesNotExist)
    );
    assert_eq!(
        d.read(0x6064, 0, &mut buf[..2]),
        Err(SdoAbort::ExceedsMailbox)
    );
    assert_eq!(d.write(0x6041, 0, &[0, 0]), Err(SdoAbort::WriteReadOnly));
    assert_eq!(d.write(0x6040, 0, &[0]), Err(SdoAbort::LengthTooLow));
    assert_eq!(d.write(0x6040, 0, &[0, 0, 0]), Err(SdoAbort::LengthTooHigh));
    assert_eq!(d.write(0x6060, 0, &[2]), Err(SdoAbort::ValueRangeExceeded));
    assert_eq!(d.write(0x6060, 0, &[0xFF]), Err(SdoAbort::ValueTooLow));
    assert_eq!(d.write(0x6060, 0, &[11]), Err(SdoAbort::ValueTooHigh));
    assert_eq!(d.write(0x6098, 0, &[15]), Err(SdoAbort::ValueRangeExceeded));
    assert_eq!(d.write(0x6098, 0, &[36]), Err(SdoAbort::ValueRangeExceeded));
    assert_eq!(d.write(0x605A, 0, &[9, 0]), Err(SdoAbort::ValueTooHigh));
    assert_eq!(
        d.write(0x607E, 0, &[0x01]),
        Err(SdoAbort::ValueRangeExceeded)
    );
    assert_eq!(
        d.write(0x60B8, 0, &[0x08, 0]),
        Err(SdoAbort::ValueRangeExceeded)
    );
    assert_eq!(d.write(0x60C2, 2, &[0xF9]), Err(SdoAbort::ValueTooLow));
    assert_eq!(d.write(0x607D, 0, &[2]), Err(SdoAbort::WriteReadOnly));
    assert_eq!(
        d.write(0x6502, 0, &[0, 0, 0, 0]),
        Err(SdoAbort::WriteReadOnly)
    );
    // Rejected writes change nothing.
    assert_eq!(d.value(0x6060, 0), Some(0));
    assert_eq!(d.value(0x6098, 0), Some(37));
    // Good writes.
    d.write(0x6060, 0, &[8]).unwrap();
    d.write(0x607D, 1, &(-1000i32).to_le_bytes()).unwrap();
    assert_eq!(d.value(0x607D, 1), Some(-1000));
    assert_eq!(d.read(0x6502, 0, &mut buf), Ok(4));
    assert_eq!(u32::from_le_bytes(buf), 0x3AD);
}

#[test]
fn garbage_writes_never_panic() {
    let mut d = Cia402::new();
    let mut x: u32 = 0x1234_5678;
    for o in PACKED {
        for e in o.entries() {
            for len in 0..6 {
                for _ in 0..20 {
                    x ^= x << 13;
                    x ^= x >> 17;
                    x ^= x << 5;
                    let data = x.to_le_bytes();
                    let mut buf = [0u8; 8];
                    let d5 = [data[0], data[1], data[2], data[3], 0xAA];
                    let _ = d.write(o.index, e.sub, &d5[..len.min(5)]);
                    let _ = d.read(o.index, e.sub, &mut buf);
                }
            }
        }
    }
    for slot in 0..=255u8 {
        d.set_rx(slot, &[0xFF, 0xFF, 0xFF, 0xFF]);
        d.set_rx(slot, &[]);
        let mut b = [0u8; 2];
        d.get_tx(slot, &mut b);
    }
    for _ in 0..100 {
        d.cycle(&crate::cia402::DriveFeedback::default(), 0.001);
    }
}
