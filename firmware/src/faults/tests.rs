use super::*;
use crate::dictionary::fault_history::{read, OBJECTS};
use crate::dictionary::Sdo;
use ecat_slave_stack::od::{self, ObjectKey, SdoAbort};

/// The table as the product packs it.
static PACKED: &[od::Object] = ecat_slave_stack::packed_dictionary!(&[OBJECTS]);

const S: Snapshot = Snapshot {
    ia_ma: 0,
    ib_ma: 0,
    bus_dv: 240,
    position_error: 0,
    speed: 0,
};

fn all_enabled() -> Faults {
    let mut f = Faults::default();
    f.configure(0xFFFF, false);
    f
}

#[test]
fn table_well_formed() {
    assert!(od::is_well_formed(PACKED));
}

#[test]
fn each_fault_code_register_emcy_led_pds_alarm() {
    let cases: &[(FaultKind, u16, u8, Option<u8>, bool)] = &[
        (FaultKind::OverCurrent, 0x2310, 0x83, Some(1), true),
        (FaultKind::OverVoltage, 0x3210, 0x85, Some(2), true),
        (FaultKind::UnderVoltage, 0x3220, 0x85, Some(3), false),
        (FaultKind::MotorOpen, 0x7120, 0xA1, Some(4), false),
        (FaultKind::FollowingError, 0x8611, 0xA1, Some(7), false),
        (FaultKind::PhaseSensing, 0x5210, 0x83, Some(9), false),
    ];
    for &(k, code, reg, led, latched) in cases {
        let mut f = all_enabled();
        assert!(f.raise(k, S, 1000));
        assert!(!f.raise(k, S, 1001), "same occurrence");
        assert_eq!(f.error_code(), code);
        assert_eq!(f.error_register(), reg);
        assert_eq!(f.led_code(), led);
        assert!(f.alarm());
        assert!(f.take_pds_fault_request());
        assert!(!f.take_pds_fault_request());
        let e = f.pop_emergency().unwrap();
        assert_eq!(
            (e.code, e.register, e.data[0], e.data[1]),
            (code, reg, k as u8, 240)
        );
        assert_eq!(f.pop_emergency(), None, "exactly one emergency");
        // Condition still present: reset does nothing.
        assert!(!f.fault_reset());
        assert!(f.is_active(k));
        f.condition_gone(k);
        assert_eq!(f.fault_reset(), !latched);
        assert_eq!(f.is_active(k), latched);
        if latched {
            assert_eq!(f.pop_emergency(), None);
            // 0x2057 = 1 allows clearing.
            f.configure(0xFFFF, true);
            assert!(f.fault_reset());
        }
        assert_eq!(
            f.pop_emergency().map(|e| e.code),
            Some(0),
            "error reset emergency"
        );
        assert_eq!(
            (f.error_code(), f.error_register(), f.led_code(), f.alarm()),
            (0, 0, None, false)
        );
        // A new occurrence after clearing sends again.
        assert!(f.raise(k, S, 2000));
        assert_eq!(f.pop_emergency().map(|e| e.code), Some(code));
        assert_eq!(f.count(), 2);
    }
}

#[test]
fn under_voltage_armed_after_bus_came_up() {
    let mut f = Faults::default();
    for mv in [0, 5_000, 11_999, 12_400] {
        f.check_bus_voltage(mv, S, 0);
    }
    assert!(!f.any_active(), "rising supply at switch-on");
    f.check_bus_voltage(12_500, S, 0);
    f.check_bus_voltage(11_999, S, 0);
    assert!(f.is_active(FaultKind::UnderVoltage));
}

#[test]
fn thresholds() {
    let mut f = Faults::default(); // 0x00C3: OC, OV, UV, FE
    f.check_bus_voltage(55_000, S, 0);
    assert!(!f.any_active());
    f.check_bus_voltage(55_001, S, 0);
    assert!(f.is_active(FaultKind::OverVoltage));
    f.check_bus_voltage(24_000, S, 0);
    f.check_bus_voltage(12_000, S, 0);
    assert!(!f.is_active(FaultKind::UnderVoltage));
    f.check_bus_voltage(11_999, S, 0);
    assert!(f.is_active(FaultKind::UnderVoltage));
    f.check_bus_voltage(12_400, S, 0);
    assert!(!f.fault_reset(), "inside hysteresis, OV latched");
    assert!(f.is_active(FaultKind::UnderVoltage));
    f.check_bus_voltage(12_500, S, 0);
    f.fault_reset();
    assert!(!f.is_active(FaultKind::UnderVoltage));
    assert!(
        f.is_active(FaultKind::OverVoltage),
        "latched until power cycle"
    );
    assert_eq!(f.led_code(), Some(2));
    assert!(!f.check_phase_currents(10_500, -10_500, S, 0));
    assert!(f.check_phase_currents(0, -10_501, S, 0));
    assert_eq!(f.history(0).map(|r| r.snapshot.ib_ma), Some(-10_501));
    assert_eq!(f.led_code(), Some(1), "most severe shown");
    f.check_following_error(-1000, 1000, S, 0);
    assert!(!f.is_active(FaultKind::FollowingError));
    f.check_following_error(-1001, 1000, S, 0);
    assert!(f.is_active(FaultKind::FollowingError));
    assert_eq!(f.history(0).map(|r| r.snapshot.position_error), Some(-1001));
    assert_eq!(f.error_code(), 0x2310);
}

#[test]
fn masking() {
    let mut f = Faults::default();
    assert!(!f.raise(FaultKind::MotorOpen, S, 0), "off by default");
    assert!(!f.raise(FaultKind::PhaseSensing, S, 0));
    f.configure(0, false);
    assert!(!f.raise(FaultKind::OverVoltage, S, 0));
    assert!(!f.raise(FaultKind::UnderVoltage, S, 0));
    assert!(!f.raise(FaultKind::FollowingError, S, 0));
    assert!(
        f.raise(FaultKind::OverCurrent, S, 0),
        "over-current cannot be masked"
    );
    assert!(
        f.raise_ecat(0xA001, [4, 0], 0),
        "EtherCAT faults cannot be masked"
    );
    assert_eq!(f.pop_emergency().map(|e| e.code), Some(0x2310));
    assert_eq!(
        f.pop_emergency().map(|e| (e.code, e.register, e.data[3])),
        Some((0xA001, 0x93, 4))
    );
}

#[test]
fn ecat_fault_has_no_red_led() {
    let mut f = Faults::default();
    assert!(f.raise_ecat(0x8700, [0, 0], 5));
    assert_eq!(f.error_code(), 0x8700);
    assert_eq!(f.error_register(), 0x11);
    assert_eq!(f.led_code(), None);
    assert!(f.take_pds_fault_request());
    f.condition_gone(FaultKind::Ecat);
    assert!(f.fault_reset());
}

#[test]
fn history_order_after_wrapping_and_clearing() {
    let mut f = all_enabled();
    let raise = |f: &mut Faults, t: u32| {
        assert!(f.raise(FaultKind::FollowingError, Snapshot::default(), t));
        f.condition_gone(FaultKind::FollowingError);
        f.fault_reset();
    };
    for t in 0..(HISTORY as u32 * 2 + 3) {
        raise(&mut f, t);
        let newest = t;
        for n in 0..HISTORY {
            let want = newest.checked_sub(n as u32);
            assert_eq!(
                f.history(n).map(|r| r.time_ms),
                want,
                "after {t}, entry {n}"
            );
        }
        assert_eq!(f.history(HISTORY), None);
        assert_eq!(f.history(usize::MAX), None);
    }
    f.clear_history();
    assert_eq!(f.history_len(), 0);
    raise(&mut f, 100);
    raise(&mut f, 101);
    assert_eq!(f.history_len(), 2);
    assert_eq!(f.history(0).map(|r| r.time_ms), Some(101));
    assert_eq!(f.history(1).map(|r| r.time_ms), Some(100));
    assert_eq!(f.history(2), None);
}

#[test]
fn history_keeps_six_newest_readable_by_sdo() {
    let mut f = all_enabled();
    let kinds = [
        FaultKind::UnderVoltage,
        FaultKind::MotorOpen,
        FaultKind::FollowingError,
        FaultKind::PhaseSensing,
        FaultKind::UnderVoltage,
        FaultKind::MotorOpen,
        FaultKind::FollowingError,
    ];
    for (i, &k) in kinds.iter().enumerate() {
        let snap = Snapshot {
            ia_ma: -(i as i16),
            ib_ma: 100,
            bus_dv: 123,
            position_error: -7,
            speed: 99,
        };
        assert!(f.raise(k, snap, 10 * i as u32));
        f.condition_gone(k);
        f.fault_reset();
    }
    assert_eq!(f.history_len(), 6);
    let mut buf = [0u8; 4];
    let rd = |f: &Faults, i, s, buf: &mut [u8; 4]| {
        let n = read(f, i, s, buf).unwrap();
        let e = od::find_entry(PACKED, ObjectKey::new(i, s)).unwrap();
        od::decode_int(e.data_type, &buf[..n]).unwrap()
    };
    assert_eq!(rd(&f, 0x2400, 0, &mut buf), 8);
    assert_eq!(rd(&f, 0x2400, 1, &mut buf), 7);
    assert_eq!(rd(&f, 0x2400, 2, &mut buf), 0x8611);
    assert_eq!(rd(&f, 0x2400, 3, &mut buf), 0x7120);
    assert_eq!(
        rd(&f, 0x2400, 7, &mut buf),
        0x7120,
        "second fault (oldest kept)"
    );
    assert_eq!(rd(&f, 0x2401, 1, &mut buf), 0x8611);
    assert_eq!(rd(&f, 0x2401, 2, &mut buf), -6);
    assert_eq!(rd(&f, 0x2401, 3, &mut buf), 100);
    assert_eq!(rd(&f, 0x2401, 4, &mut buf), 123);
    assert_eq!(rd(&f, 0x2401, 5, &mut buf), -7);
    assert_eq!(rd(&f, 0x2401, 6, &mut buf), 99);
    assert_eq!(rd(&f, 0x2401, 7, &mut buf), 60);
    assert_eq!(rd(&f, 0x2406, 7, &mut buf), 10);
    f.clear_history();
    assert_eq!(rd(&f, 0x2401, 1, &mut buf), 0);
    assert_eq!(rd(&f, 0x2400, 2, &mut buf), 0);
    assert_eq!(
        read(&f, 0x2407, 0, &mut buf),
        Err(SdoAbort::ObjectDoesNotExist)
    );
    assert_eq!(
        read(&f, 0x2401, 9, &mut buf),
        Err(SdoAbort::SubindexDoesNotExist)
    );
    assert_eq!(
        read(&f, 0x2401, 5, &mut [0u8; 2]),
        Err(SdoAbort::ExceedsMailbox)
    );
}

#[test]
fn emergency_queue_never_overflows() {
    let mut f = all_enabled();
    for i in 0..50u32 {
        f.raise(FaultKind::UnderVoltage, S, i);
        f.condition_gone(FaultKind::UnderVoltage);
        f.fault_reset();
    }
    let mut n = 0;
    while f.pop_emergency().is_some() {
        n += 1;
    }
    assert_eq!(n, 8);
    assert_eq!(f.count(), 50);
}

/// 0x2054 / 0x2055 set the bus-voltage thresholds; 0x2055 = 0 switches the
/// under-voltage detection off; out-of-range values are refused and change nothing.
#[test]
fn voltage_thresholds_from_the_parameters() {
    use crate::identity::Variant;
    use crate::params::Params;
    let mut p = Params::new(Variant::OpenLoop);
    let mut f = Faults::default();
    f.configure_from(&p);
    assert_eq!(f.config(), FaultConfig::DEFAULT, "the defaults agree");
    assert_eq!(
        p.write(0x2054, 0, &56u16.to_le_bytes()),
        Err(od::SdoAbort::ValueTooHigh)
    );
    assert_eq!(
        p.write(0x2055, 0, &21u16.to_le_bytes()),
        Err(od::SdoAbort::ValueTooHigh)
    );
    p.write(0x2054, 0, &36u16.to_le_bytes()).unwrap();
    p.write(0x2055, 0, &18u16.to_le_bytes()).unwrap();
    f.configure_from(&p);
    f.check_bus_voltage(24_000, S, 0);
    assert!(!f.any_active());
    f.check_bus_voltage(17_999, S, 0);
    assert!(f.is_active(FaultKind::UnderVoltage));
    f.check_bus_voltage(36_001, S, 0);
    assert!(f.is_active(FaultKind::OverVoltage));
    // Under-voltage off: a sagging bus raises nothing, an active one is gone.
    let mut f = Faults::default();
    p.write(0x2055, 0, &0u16.to_le_bytes()).unwrap();
    f.configure_from(&p);
    for mv in [24_000, 5_000, 0] {
        f.check_bus_voltage(mv, S, 0);
    }
    assert!(!f.any_active());
}

#[test]
fn the_fault_table_is_consistent() {
    for (i, r) in TABLE.iter().enumerate() {
        let k = FaultKind::ALL[i];
        assert_eq!(k as usize, i, "rows in kind order");
        assert_eq!(k.info(), r);
        assert_eq!(r.register & 0x01, 0x01, "{}: generic bit", r.name);
        // A protective fault takes the power away at once.
        assert!(!r.protective || r.cuts_power, "{}", r.name);
        // Latched faults are the protective ones that a hardware trip latches.
        assert!(!r.latched || r.protective, "{}", r.name);
        assert_eq!(POWER_CUT_MASK & (1 << i) != 0, r.cuts_power);
        // The run-time columns are the table's.
        assert_eq!(
            (k.code(), k.error_register(), k.flashes().unwrap_or(0)),
            (r.code, r.register, r.flashes)
        );
        assert_eq!(
            (k.cuts_power(), k.latched(), k.protective()),
            (r.cuts_power, r.latched, r.protective)
        );
        assert_eq!(k.mask_bit().unwrap_or(NO_MASK), r.mask_bit);
        for (j, o) in TABLE.iter().enumerate().skip(i + 1) {
            assert_ne!(r.code, o.code, "{} / {}", r.name, o.name);
            assert!(
                r.flashes == 0 || r.flashes != o.flashes,
                "{} / {}",
                r.name,
                o.name
            );
            assert!(
                r.mask_bit == NO_MASK || r.mask_bit != o.mask_bit,
                "{} / {} ({j})",
                r.name,
                o.name
            );
        }
        assert!(r.mask_bit == NO_MASK || r.mask_bit < 16);
        // The diagnosis text is the table's.
        let t = crate::diagnosis::text(crate::diagnosis::fault_text_id(k)).expect("text");
        assert_eq!(t.text, r.text);
    }
}

#[test]
fn a_protective_detection_cannot_be_masked_into_no_torque() {
    for k in FaultKind::ALL {
        let mut f = Faults::default();
        f.configure(0, false);
        let raised = f.raise_unmaskable(k, S, 0);
        assert_eq!(
            raised,
            k.info().protective || k.mask_bit().is_none(),
            "{:?}: protective detections report whatever 0x2056 says",
            k
        );
        if raised {
            assert!(f.power_cut() || !k.cuts_power());
            assert_eq!(f.pop_emergency().map(|e| e.code), Some(k.code()));
        }
    }
    // The over-current, over-voltage and current-sensing rows are protective.
    for k in [
        FaultKind::OverCurrent,
        FaultKind::OverVoltage,
        FaultKind::PhaseSensing,
    ] {
        assert!(k.info().protective, "{k:?}");
    }
}
