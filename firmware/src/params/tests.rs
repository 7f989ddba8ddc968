/// The table as the product packs it (with the plain names of its words).
static PACKED: &[ecat_slave_stack::od::Object] =
    ecat_slave_stack::packed_dictionary!(&[super::OBJECTS]);

extern crate std;
use super::*;
use crate::dictionary::Sdo;
use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::od;
use ecat_slave_stack::od::ObjectKey;

fn w(p: &mut Params, index: u16, sub: u8, v: i64) -> Result<(), SdoAbort> {
    let e = od::find_entry(PACKED, ObjectKey::new(index, sub))?;
    let bytes = (v as u64).to_le_bytes();
    let data = &bytes[..e.byte_len()];
    od::check_write(e, data, EsmState::Op)?;
    p.write(index, sub, data)
}

fn r(p: &Params, index: u16, sub: u8) -> i64 {
    let mut buf = [0u8; 8];
    let n = p.read(index, sub, &mut buf).unwrap();
    let e = od::find_entry(PACKED, ObjectKey::new(index, sub)).unwrap();
    od::decode_int(e.data_type, &buf[..n]).unwrap()
}

#[test]
fn table_is_well_formed_and_keys_match_saved_entries() {
    assert!(od::is_well_formed(PACKED));
    let mut keys = KEYS.to_vec();
    keys.sort();
    assert_eq!(keys, KEYS.to_vec(), "KEYS sorted");
    let saved: std::vec::Vec<(u16, u8)> = PACKED
        .iter()
        .flat_map(|o| {
            o.entries()
                .iter()
                .filter(|e| e.is_saved())
                .map(move |e| (o.index, e.sub))
        })
        .collect();
    // Every saved entry has a slot; the only unsaved slot is Kc (read-only).
    for k in &saved {
        assert!(KEYS.contains(k), "{k:x?} has no slot");
    }
    assert_eq!(saved.len() + 1, KEYS.len());
    for o in PACKED {
        assert!((0x2000..=0x2FFF).contains(&o.index));
    }
}

#[test]
fn every_parameter_default_and_range_edges() {
    for &(index, sub) in KEYS.iter() {
        let e = od::find_entry(PACKED, ObjectKey::new(index, sub)).unwrap();
        // The table's 0x2000 range is the widest of the variants' (the open-loop
        // drive's 8.4 A; the hybrid servo's 8.0 A: `peak_current_limit_per_variant`).
        let variant = if index == 0x2000 {
            Variant::OpenLoop
        } else {
            Variant::HybridServo
        };
        let mut p = Params::new(variant);
        p.set_internal(Param::AutoTune, 0);
        let DefaultValue::Int(def) = e.default_value() else {
            panic!("{index:x} no default")
        };
        if index != 0x2013 {
            assert_eq!(r(&p, index, sub), def, "{index:x}:{sub} default");
        }
        if !e.access.writable() {
            assert_eq!(w(&mut p, index, sub, def), Err(SdoAbort::WriteReadOnly));
            continue;
        }
        assert_eq!(w(&mut p, index, sub, e.min()), Ok(()), "{index:x} min");
        assert_eq!(r(&p, index, sub), e.min());
        assert_eq!(w(&mut p, index, sub, e.max()), Ok(()), "{index:x} max");
        assert_eq!(r(&p, index, sub), e.max());
        let (_, tmin, tmax) = od::type_range(e.data_type);
        if e.max() < tmax {
            assert_eq!(
                w(&mut p, index, sub, e.max() + 1),
                Err(SdoAbort::ValueTooHigh)
            );
            assert_eq!(
                p.write(
                    index,
                    sub,
                    &((e.max() + 1) as u64).to_le_bytes()[..e.byte_len()]
                ),
                Err(SdoAbort::ValueTooHigh)
            );
            assert_eq!(r(&p, index, sub), e.max(), "unchanged");
        }
        if e.min() > tmin {
            assert_eq!(
                w(&mut p, index, sub, e.min() - 1),
                Err(SdoAbort::ValueTooLow)
            );
            assert_eq!(
                p.write(
                    index,
                    sub,
                    &((e.min() - 1) as u64).to_le_bytes()[..e.byte_len()]
                ),
                Err(SdoAbort::ValueTooLow)
            );
            assert_eq!(r(&p, index, sub), e.max(), "unchanged");
        }
    }
}

#[test]
fn peak_current_limit_per_variant() {
    for (v, max) in [(Variant::HybridServo, 8000u16), (Variant::OpenLoop, 8400)] {
        let mut p = Params::new(v);
        assert_eq!(
            p.write(0x2000, 0, &(max + 1).to_le_bytes()),
            Err(SdoAbort::ValueTooHigh),
            "{v:?}"
        );
        assert_eq!(p.get(Param::PeakCurrent), 3200, "{v:?}: unchanged");
        p.write(0x2000, 0, &max.to_le_bytes()).unwrap();
        assert_eq!(p.get(Param::PeakCurrent), i32::from(max));
    }
}

#[test]
fn spec_table_values() {
    let p = Params::new(Variant::HybridServo);
    let expect: &[(u16, u8, i64, i64, i64)] = &[
        (0x2000, 0, 3200, 1, 8400),
        (0x2001, 0, 50000, 200, 51200),
        (0x2002, 0, 500, 100, 10000),
        (0x2005, 1, 1, 0, 31),
        (0x2005, 2, 1, 0, 31),
        (0x2005, 3, 0, 0, 31),
        (0x2008, 0, 4, 0, 7),
        (0x2010, 2, 1000, 50, 25600),
        (0x2013, 0, 1, 0, 1),
        (0x2015, 0, 1000, 200, 32767),
        (0x2016, 0, 200, 0, 32767),
        (0x2017, 0, 100, 80, 300),
        (0x2020, 0, 1000, 1, 20000),
        (0x2021, 0, 1, 1, 6000),
        (0x2024, 0, 2, 1, 2),
        (0x2025, 0, 5, 0, 5),
        (0x2026, 0, 50, 0, 100),
        (0x2029, 0, 1000, 200, 60000),
        (0x2030, 0, 1000, 1, 60000),
        (0x2054, 0, 55, 20, 55),
        (0x2055, 0, 12, 0, 20),
        (0x2056, 0, 0xC3, 0, 0xFFFF),
        (0x2058, 0, 1, 0, 10000),
        (0x2060, 0, 0, 0, 1),
        (0x2061, 0, 30, 5, 90),
        (0x2062, 0, 0, 0, 1),
        (0x2137, 0, 120, 0, 150),
        (0x2138, 0, 50, 0, 150),
        (0x2139, 0, 70, 0, 150),
        (0x2140, 0, 60, 0, 150),
        (0x2150, 0, 1, 1, 65535),
        (0x2151, 0, 0, 0, 1),
        (0x2152, 1, 1, 0, 0xFFFF),
        (0x2152, 2, 2, 0, 0xFFFF),
        (0x2152, 3, 4, 0, 0xFFFF),
        (0x2152, 4, 8, 0, 0xFFFF),
        (0x2152, 5, 0, 0, 0xFFFF),
        (0x2153, 3, 20, 1, 60000),
        (0x2154, 0, 0, 0, 0x1F),
        (0x2160, 0, 0, 0, 5000),
        (0x2161, 0, 12, 1, 16),
    ];
    for &(i, s, d, lo, hi) in expect {
        let e = od::find_entry(PACKED, ObjectKey::new(i, s)).unwrap();
        assert_eq!(
            (e.default_value(), e.min(), e.max()),
            (DefaultValue::Int(d), lo, hi),
            "{i:x}:{s}"
        );
        assert_eq!(r(&p, i, s), d);
    }
    assert_eq!(r(&p, 0x2005, 0), 3);
    assert_eq!(r(&p, 0x2152, 0), 5);
    assert_eq!(r(&p, 0x2010, 0), 2);
    let mut buf = [0u8; 4];
    assert_eq!(
        p.read(0x2010, 1, &mut buf),
        Err(SdoAbort::SubindexDoesNotExist)
    );
    assert_eq!(
        p.read(0x2011, 0, &mut buf),
        Err(SdoAbort::ObjectDoesNotExist)
    );
    assert_eq!(
        p.read(0x2152, 6, &mut buf),
        Err(SdoAbort::SubindexDoesNotExist)
    );
}

#[test]
fn current_gains_locked_while_auto_tune() {
    let mut p = Params::new(Variant::HybridServo);
    assert_eq!(p.get(Param::AutoTune), 1);
    assert_eq!(w(&mut p, 0x2015, 0, 2000), Err(SdoAbort::LocalControl));
    assert_eq!(w(&mut p, 0x2016, 0, 300), Err(SdoAbort::LocalControl));
    assert_eq!(p.get(Param::CurrentKp), 1000);
    p.set_internal(Param::CurrentKp, 1500); // auto-tune result
    assert_eq!(r(&p, 0x2015, 0), 1500);
    p.set_internal(Param::CurrentKp, 100_000);
    assert_eq!(r(&p, 0x2015, 0), 32767, "clamped");
    assert_eq!(w(&mut p, 0x2013, 0, 0), Ok(()));
    assert_eq!(w(&mut p, 0x2015, 0, 2000), Ok(()));
    assert_eq!(w(&mut p, 0x2016, 0, 300), Ok(()));
    assert_eq!(
        (p.get(Param::CurrentKp), p.get(Param::CurrentKi)),
        (2000, 300)
    );
}

#[test]
fn counters_clear_on_write_one() {
    let mut p = Params::new(Variant::HybridServo);
    p.add_command_pulses(0x0001_2345);
    p.add_encoder_counts(0xFFFF_FFFF);
    assert_eq!((r(&p, 0x2039, 0), r(&p, 0x2040, 0)), (1, 0x2345));
    assert_eq!((r(&p, 0x2041, 0), r(&p, 0x2042, 0)), (0xFFFF, 0xFFFF));
    assert_eq!(w(&mut p, 0x2039, 0, 1), Err(SdoAbort::WriteReadOnly));
    assert_eq!(w(&mut p, 0x2040, 0, 2), Err(SdoAbort::ValueTooHigh));
    assert_eq!(w(&mut p, 0x2040, 0, 0), Ok(()));
    assert_eq!(r(&p, 0x2040, 0), 0x2345, "0 does nothing");
    assert_eq!(w(&mut p, 0x2040, 0, 1), Ok(()));
    assert_eq!((r(&p, 0x2039, 0), r(&p, 0x2040, 0)), (0, 0));
    assert_eq!(r(&p, 0x2042, 0), 0xFFFF, "encoder untouched");
    assert_eq!(w(&mut p, 0x2042, 0, 1), Ok(()));
    assert_eq!((r(&p, 0x2041, 0), r(&p, 0x2042, 0)), (0, 0));
}

#[test]
fn after_restart_parameters_need_power_up() {
    let mut p = Params::new(Variant::HybridServo);
    assert_eq!(
        p.active(),
        ActiveConfig {
            pulses_per_rev: 50000,
            alias_value: 1,
            alias_source: 0
        }
    );
    w(&mut p, 0x2001, 0, 10000).unwrap();
    w(&mut p, 0x2150, 0, 77).unwrap();
    w(&mut p, 0x2151, 0, 1).unwrap();
    assert_eq!(r(&p, 0x2001, 0), 10000, "SDO sees the pending value");
    assert_eq!(p.active().pulses_per_rev, 50000, "drive keeps the old one");
    assert_eq!(p.active().alias_source, 0);
    p.latch_power_up();
    assert_eq!(
        p.active(),
        ActiveConfig {
            pulses_per_rev: 10000,
            alias_value: 77,
            alias_source: 1
        }
    );
}

#[test]
fn open_loop_variant_refuses_closed_loop() {
    let mut p = Params::new(Variant::OpenLoop);
    assert_eq!(r(&p, 0x2024, 0), 1);
    assert_eq!(w(&mut p, 0x2024, 0, 2), Err(SdoAbort::ValueTooHigh));
    assert_eq!(r(&p, 0x2024, 0), 1);
}

#[test]
fn garbage_writes_never_panic() {
    let mut p = Params::new(Variant::HybridServo);
    let before = p.values;
    for o in PACKED {
        for e in o.entries() {
            for len in 0..6 {
                let data = [0xFFu8; 6];
                let res = p.write(o.index, e.sub, &data[..len]);
                if len != e.byte_len() {
                    assert!(res.is_err());
                }
            }
        }
    }
    let mut buf = [0u8; 1];
    assert_eq!(p.read(0x2001, 0, &mut buf), Err(SdoAbort::ExceedsMailbox));
    assert_eq!(p.write(0x2FFF, 0, &[0]), Err(SdoAbort::ObjectDoesNotExist));
    // Every all-ones value is above the range of entries that have a limit; the
    // unlimited ones (functions, mask, alias) took 0xFFFF.
    assert_eq!(
        p.get(Param::PeakCurrent),
        before[Param::PeakCurrent as usize]
    );
    assert_eq!(
        p.get(Param::PulsesPerRev),
        before[Param::PulsesPerRev as usize]
    );
    assert!(!p.take_fault_history_clear());
}

#[test]
fn fault_clear_record() {
    let mut p = Params::new(Variant::HybridServo);
    assert_eq!(r(&p, 0x2093, 0), 0);
    w(&mut p, 0x2093, 0, 1).unwrap();
    assert_eq!(r(&p, 0x2093, 0), 1);
    assert!(p.take_fault_history_clear());
    assert!(!p.take_fault_history_clear());
    assert_eq!(r(&p, 0x2093, 0), 0);
}
