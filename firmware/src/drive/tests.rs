use super::stack::{other_tx_entries, other_tx_entry, OTHER_TX_SLOT};
use super::*;
use crate::cia402::pds::PdsState;
use ecat_slave_stack::od::ObjectKey;

pub(super) fn sdo_write(d: &mut Drive, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoAbort> {
    let e = od::find_entry(dictionary::OBJECTS, ObjectKey::new(index, sub))?;
    od::check_write(e, data, EsmState::PreOp)?;
    d.write(ObjectKey::new(index, sub), data, EsmState::PreOp)
}

pub(super) fn sdo_read_u32(d: &mut Drive, index: u16, sub: u8) -> u32 {
    let mut b = [0u8; 8];
    let n = d.read(ObjectKey::new(index, sub), &mut b).expect("read");
    let mut v = [0u8; 4];
    v[..n.min(4)].copy_from_slice(&b[..n.min(4)]);
    u32::from_le_bytes(v)
}

#[test]
fn init_in_equals_with_store() {
    // Every readable value, the set-points and the ESM state agree.
    let mut a = Drive::new(Variant::HybridServo, 42);
    let mut slot = core::mem::MaybeUninit::uninit();
    let b = Drive::init_in(&mut slot, Variant::HybridServo, 42, NoStore);
    for o in dictionary::OBJECTS {
        for e in o.entries() {
            let (mut x, mut y) = ([0u8; 64], [0u8; 64]);
            let rx = a.read(ObjectKey::new(o.index, e.sub), &mut x);
            let ry = b.read(ObjectKey::new(o.index, e.sub), &mut y);
            assert_eq!(rx, ry, "{:#06x}:{}", o.index, e.sub);
            assert_eq!(x, y, "{:#06x}:{}", o.index, e.sub);
        }
    }
    assert_eq!(a.command(), b.command());
    assert_eq!(a.esm_state(), b.esm_state());
}

#[test]
fn other_tx_entry_is_the_chains_nth() {
    let n = other_tx_entries().count();
    for k in 0..n + 2 {
        assert_eq!(other_tx_entry(k), other_tx_entries().nth(k), "{k}");
    }
    let d = Drive::new(Variant::HybridServo, 7);
    assert_eq!(ProcessData::get_tx(&d, OTHER_TX_SLOT + n as u16), 0);
}

#[test]
fn every_product_entry_is_bound_to_its_owners_values() {
    // Each owner binds its entries through `od::Values`: every readable entry answers
    // with its length (a string with at most its length), and a writable numeric entry
    // given back its own value reaches a binding (no "does not exist", no
    // "read-only"); only the scope's blocks wait for a record.
    let mut d = Drive::new(Variant::HybridServo, 42);
    let unbound = [
        SdoAbort::ObjectDoesNotExist,
        SdoAbort::SubindexDoesNotExist,
        SdoAbort::WriteReadOnly,
    ];
    let mut n = 0;
    for o in dictionary::OBJECTS {
        if dictionary::owner_of(o.index) == Some(dictionary::Owner::SlaveRuntime) {
            continue;
        }
        for e in o.entries() {
            let mut b = [0u8; crate::scope::BLOCK_BYTES];
            let at = (o.index, e.sub);
            match d.read(ObjectKey::new(o.index, e.sub), &mut b) {
                Ok(len) if e.data_type.is_variable_length() => assert!(len <= e.byte_len()),
                Ok(len) => assert_eq!(len, e.byte_len(), "{at:x?}"),
                Err(SdoAbort::NoDataAvailable) => assert_eq!(o.index, crate::scope::DATA),
                Err(err) => panic!("{at:x?}: {err:?}"),
            }
            if e.access.writable() && !e.data_type.is_variable_length() {
                let len = e.byte_len();
                let r = d.write(ObjectKey::new(o.index, e.sub), &b[..len], EsmState::PreOp);
                assert!(
                    !r.is_err_and(|err| unbound.contains(&err)),
                    "{at:x?}: {r:?}"
                );
            }
            n += 1;
        }
    }
    assert!(n > 300, "{n} entries");
}

#[test]
fn dictionary_reads_reach_every_module() {
    let mut d = Drive::new(Variant::HybridServo, 42);
    assert_eq!(sdo_read_u32(&mut d, 0x1000, 0), 0x0002_0192);
    assert_eq!(sdo_read_u32(&mut d, 0x1018, 4), 42);
    assert_eq!(sdo_read_u32(&mut d, 0x2000, 0), 3200);
    assert_eq!(
        sdo_read_u32(&mut d, 0x6502, 0),
        crate::cia402::SUPPORTED_MODES
    );
    let mut b = [0u8; 8];
    assert_eq!(
        d.read(ObjectKey::new(0x5000, 0), &mut b),
        Err(SdoAbort::ObjectDoesNotExist)
    );
}

#[test]
fn out_of_range_vendor_write_is_refused_and_value_kept() {
    let mut d = Drive::new(Variant::HybridServo, 0);
    assert_eq!(
        sdo_write(&mut d, 0x2000, 0, &9000u16.to_le_bytes()),
        Err(SdoAbort::ValueTooHigh)
    );
    assert_eq!(
        sdo_write(&mut d, 0x2000, 0, &0u16.to_le_bytes()),
        Err(SdoAbort::ValueTooLow)
    );
    assert_eq!(sdo_read_u32(&mut d, 0x2000, 0), 3200);
    sdo_write(&mut d, 0x2000, 0, &2500u16.to_le_bytes()).expect("in range");
    assert_eq!(sdo_read_u32(&mut d, 0x2000, 0), 2500);
}

#[test]
fn mapped_peak_current_takes_the_sdo_range_check() {
    for (variant, max) in [(Variant::HybridServo, 8000u16), (Variant::OpenLoop, 8400)] {
        let mut d = Drive::new(variant, 0);
        let slot =
            ProcessData::rx_slot(&d, ObjectKey::new(0x2000, 0)).expect("0x2000 RxPDO-mappable");
        assert_eq!(
            ProcessData::rx_slot(&d, ObjectKey::new(0x2001, 0)),
            None,
            "0x2001 is not"
        );
        ProcessData::set_rx(&mut d, slot, 4000);
        assert_eq!(sdo_read_u32(&mut d, 0x2000, 0), 4000);
        // What the SDO write refuses (above the variant's maximum, below 1) is not
        // taken over: the value stays.
        for bad in [u64::from(max) + 1, 0, 0xFFFF] {
            assert!(
                sdo_write(&mut d, 0x2000, 0, &(bad as u16).to_le_bytes()).is_err(),
                "{variant:?}: SDO {bad}"
            );
            ProcessData::set_rx(&mut d, slot, bad);
            assert_eq!(
                sdo_read_u32(&mut d, 0x2000, 0),
                4000,
                "{variant:?}: PDO {bad}"
            );
        }
        ProcessData::set_rx(&mut d, slot, u64::from(max));
        assert_eq!(sdo_read_u32(&mut d, 0x2000, 0), u32::from(max));
        // Slots past the mappable entries change nothing.
        ProcessData::set_rx(&mut d, slot + 1, 1234);
        assert_eq!(sdo_read_u32(&mut d, 0x2000, 0), u32::from(max));
    }
}

#[test]
fn save_without_parameter_memory_is_refused() {
    let mut d = Drive::new(Variant::HybridServo, 0);
    let save = crate::comm::SAVE.to_le_bytes();
    assert_eq!(
        sdo_write(&mut d, 0x1010, 1, &save),
        Err(SdoAbort::DataCannotBeStored)
    );
    let other = 0x1234_5678u32.to_le_bytes();
    assert_eq!(
        sdo_write(&mut d, 0x1010, 1, &other),
        Err(SdoAbort::DataCannotBeStored)
    );
}

pub(super) fn enable(d: &mut Drive) {
    d.set_axis(AxisState {
        bus_mv: 48_000,
        ..AxisState::default()
    });
    for cw in [0x06u16, 0x07, 0x0F] {
        d.cia402.set_controlword(cw);
        for _ in 0..3 {
            d.run_cycle(0.001);
        }
    }
}

#[test]
fn cst_follows_the_loop_mode_and_torques_come_from_the_axis() {
    // The open-loop variant: no CST.
    let mut d = Drive::new(Variant::OpenLoop, 0);
    assert_eq!(sdo_read_u32(&mut d, 0x6502, 0), 0x1A5);
    assert_eq!(
        sdo_write(&mut d, 0x6060, 0, &[10]),
        Err(SdoAbort::ValueRangeExceeded)
    );
    // The hybrid servo in closed loop: CST; 0x2024 = 1 takes it away again and
    // leaves no mode.
    let mut d = Drive::new(Variant::HybridServo, 0);
    assert_eq!(sdo_read_u32(&mut d, 0x6502, 0), 0x3AD);
    sdo_write(&mut d, 0x6060, 0, &[10]).unwrap();
    sdo_write(&mut d, 0x2024, 0, &[1]).unwrap();
    assert_eq!(sdo_read_u32(&mut d, 0x6502, 0), 0x1A5);
    assert_eq!(sdo_read_u32(&mut d, 0x6060, 0), 0);
    assert_eq!(
        sdo_write(&mut d, 0x6060, 0, &[10]),
        Err(SdoAbort::ValueRangeExceeded)
    );
    sdo_write(&mut d, 0x2024, 0, &[2]).unwrap();
    sdo_write(&mut d, 0x6060, 0, &[10]).unwrap();
    // 0x6076: Kt of the ECN57-20 times 0x6075 (0x2000).
    assert_eq!(sdo_read_u32(&mut d, 0x6076, 0), 906);
    enable(&mut d);
    assert_eq!(d.cia402.mode_display(), 10);
    d.set_axis(AxisState {
        bus_mv: 48_000,
        torque_permille: -321,
        current_permille: 654,
        ..AxisState::default()
    });
    sdo_write(&mut d, 0x6071, 0, &250i16.to_le_bytes()).unwrap();
    let c = d.run_cycle(0.001);
    assert_eq!(
        (c.kind, c.torque),
        (crate::cia402::SetpointKind::Torque, 250)
    );
    assert_eq!(sdo_read_u32(&mut d, 0x6077, 0) as u16 as i16, -321);
    assert_eq!(sdo_read_u32(&mut d, 0x6078, 0) as u16 as i16, -321);
    assert_eq!(sdo_read_u32(&mut d, 0x6074, 0) as u16 as i16, 250);
    // Outside CST 0x6074 is the servo loops' demand.
    sdo_write(&mut d, 0x6060, 0, &[9]).unwrap();
    d.run_cycle(0.001);
    assert_eq!(sdo_read_u32(&mut d, 0x6074, 0) as u16 as i16, 654);
}

#[test]
fn enable_sequence_reaches_operation_enabled() {
    let mut d = Drive::new(Variant::HybridServo, 0);
    enable(&mut d);
    assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
    assert!(d.command().drive_enabled);
    let (_, brake_released) = d.outputs();
    assert!(brake_released);
}

#[test]
fn pending_commutation_holds_switched_on_and_leaving_op_then_is_no_fault() {
    for lost in [false, true] {
        let mut d = Drive::new(Variant::HybridServo, 0);
        d.on_state_change(EsmState::SafeOp, EsmState::Op);
        let pending = AxisState {
            bus_mv: 48_000,
            position: 777,
            commutation_pending: true,
            ..AxisState::default()
        };
        d.set_axis(pending);
        for cw in [0x06u16, 0x07, 0x0F] {
            d.cia402.set_controlword(cw);
            for _ in 0..3 {
                d.run_cycle(0.001);
            }
        }
        assert_eq!(d.cia402.state(), PdsState::SwitchedOn);
        // The motor side is enabled (and the brake released) at the actual
        // position; the drive function is not.
        assert!(d.command().drive_enabled && d.command().power_stage);
        assert_eq!(d.command().position, 777);
        assert!(d.outputs().1);
        assert!(!d.drive_function_enabled());
        if lost {
            d.on_outputs_lost(AlStatusCode::SmWatchdog);
        } else {
            d.on_state_change(EsmState::Op, EsmState::SafeOp);
        }
        d.run_cycle(0.001);
        assert_eq!(d.cia402.state(), PdsState::SwitchOnDisabled);
        assert!(!d.command().drive_enabled);
        assert!(!d.faults.any_active());
        assert!(d.pop_emergency().is_none());
    }
    // Ready: the next cycle enables the drive function.
    let mut d = Drive::new(Variant::HybridServo, 0);
    d.set_axis(AxisState {
        bus_mv: 48_000,
        commutation_pending: true,
        ..AxisState::default()
    });
    for cw in [0x06u16, 0x07, 0x0F] {
        d.cia402.set_controlword(cw);
        for _ in 0..3 {
            d.run_cycle(0.001);
        }
    }
    assert_eq!(d.cia402.state(), PdsState::SwitchedOn);
    d.set_axis(AxisState {
        bus_mv: 48_000,
        ..AxisState::default()
    });
    d.run_cycle(0.001);
    assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
    assert!(d.drive_function_enabled());
}

#[test]
fn leaving_op_while_enabled_faults_the_pds_and_sends_one_emergency() {
    let mut d = Drive::new(Variant::HybridServo, 0);
    d.on_state_change(EsmState::SafeOp, EsmState::Op);
    enable(&mut d);
    d.on_state_change(EsmState::Op, EsmState::SafeOp);
    for _ in 0..5 {
        d.run_cycle(0.001);
    }
    assert!(matches!(
        d.cia402.state(),
        PdsState::Fault | PdsState::FaultReactionActive
    ));
    let e = d.pop_emergency().expect("emergency");
    assert_eq!(e.code, 0xA001);
    assert!(d.pop_emergency().is_none());
    // Fault reset on the rising edge of bit 7 clears the non-latched EtherCAT fault.
    d.cia402.set_controlword(0x00);
    d.run_cycle(0.001);
    d.cia402.set_controlword(0x80);
    for _ in 0..3 {
        d.run_cycle(0.001);
    }
    assert_eq!(d.cia402.state(), PdsState::SwitchOnDisabled);
}

#[test]
fn following_error_fault_resets_once_the_drive_is_disabled() {
    let mut d = Drive::new(Variant::HybridServo, 0);
    enable(&mut d);
    d.set_axis(AxisState {
        bus_mv: 48_000,
        servo_following_error: 5000,
        ..AxisState::default()
    });
    d.run_cycle(0.001);
    assert_eq!(d.faults.error_code(), 0x8611);
    for _ in 0..20 {
        d.run_cycle(0.001);
    }
    assert_eq!(d.cia402.state(), PdsState::Fault);
    // The servo is off now; its stale error must not block the reset.
    d.cia402.set_controlword(0x00);
    d.run_cycle(0.001);
    d.cia402.set_controlword(0x80);
    for _ in 0..3 {
        d.run_cycle(0.001);
    }
    assert_eq!(d.cia402.state(), PdsState::SwitchOnDisabled);
    assert_eq!(d.faults.error_code(), 0);
}

#[test]
fn over_voltage_faults_latch_and_light_the_red_led() {
    let mut d = Drive::new(Variant::HybridServo, 0);
    enable(&mut d);
    d.set_axis(AxisState {
        bus_mv: 60_000,
        ..AxisState::default()
    });
    d.tick(1000, 0);
    d.run_cycle(0.001);
    assert_eq!(d.faults.error_code(), 0x3210);
    assert!(!d.command().drive_enabled || d.cia402.state() != PdsState::OperationEnabled);
    // Red LED: two 150 ms pulses from the start of the burst.
    let leds: [bool; 4] = [
        d.leds(1000).red,
        d.leds(1100).red,
        d.leds(1200).red,
        d.leds(1350).red,
    ];
    assert_eq!(leds, [true, true, false, true]);
}

#[test]
fn over_current_trip_clears_by_reset_once_re_armed_with_0x2057() {
    let mut d = Drive::new(Variant::HybridServo, 0);
    enable(&mut d);
    let trip = AxisState {
        bus_mv: 48_000,
        overcurrent_trip: true,
        ..AxisState::default()
    };
    d.set_axis(trip);
    d.tick(1000, 0);
    assert_eq!(d.faults.error_code(), 0x2310);
    assert!(d.pop_emergency().is_some());
    // Still tripped: no reset even with 0x2057 = 1.
    sdo_write(&mut d, 0x2057, 0, &[1]).expect("2057");
    assert!(!d.faults.fault_reset());
    // Re-armed, but a measured current above the limit is the condition too.
    d.set_axis(AxisState {
        bus_mv: 48_000,
        ia_ma: -11_000,
        ..AxisState::default()
    });
    d.tick(2000, 0);
    assert!(!d.faults.fault_reset());
    d.set_axis(AxisState {
        bus_mv: 48_000,
        ..AxisState::default()
    });
    d.tick(3000, 0);
    assert!(d.faults.fault_reset(), "gone and 0x2057 = 1");
    assert_eq!(d.faults.error_code(), 0);
}

#[test]
fn power_up_tune_keeps_the_pds_not_ready_to_switch_on() {
    use crate::current_supervisor::CurrentReport;
    let mut d = Drive::new(Variant::HybridServo, 0);
    d.set_axis(AxisState {
        bus_mv: 48_000,
        ..AxisState::default()
    });
    d.run_cycle(0.001);
    assert_eq!(d.cia402.state(), PdsState::SwitchOnDisabled);
    for tune in [TuneStatus::Pending, TuneStatus::Running] {
        d.current_report(&CurrentReport {
            tune,
            ..CurrentReport::default()
        });
        d.cia402.set_controlword(0x06);
        for _ in 0..3 {
            d.run_cycle(0.001);
        }
        assert_eq!(d.cia402.state(), PdsState::NotReadyToSwitchOn);
        assert_eq!(d.cia402.statusword() & 0x6F, 0);
    }
    d.current_report(&CurrentReport {
        tune: TuneStatus::Done,
        tune_seq: 1,
        ..CurrentReport::default()
    });
    d.cia402.set_controlword(0x00);
    d.run_cycle(0.001);
    assert_eq!(d.cia402.state(), PdsState::SwitchOnDisabled);
    // Once over, a later tune (retry after a fault) does not hold the PDS.
    d.current_report(&CurrentReport {
        tune: TuneStatus::Running,
        tune_seq: 1,
        ..CurrentReport::default()
    });
    d.cia402.set_controlword(0x06);
    for _ in 0..3 {
        d.run_cycle(0.001);
    }
    assert_eq!(d.cia402.state(), PdsState::ReadyToSwitchOn);
    // 0x2013 = 0: no hold at all.
    let mut d = Drive::new(Variant::HybridServo, 0);
    sdo_write(&mut d, 0x2013, 0, &[0]).expect("2013");
    d.current_report(&CurrentReport {
        tune: TuneStatus::Pending,
        ..CurrentReport::default()
    });
    d.run_cycle(0.001);
    assert_eq!(d.cia402.state(), PdsState::SwitchOnDisabled);
}

#[test]
fn current_report_writes_tune_results_and_raises_its_faults() {
    use crate::current_supervisor::{CurrentReport, TunedValues};
    use foc::autotune::{Phase, TuneError};
    let mut d = Drive::new(Variant::HybridServo, 0);
    d.set_axis(AxisState {
        bus_mv: 11_000,
        ..AxisState::default()
    });
    assert!(!d.tune_permitted(), "bus below the under-voltage window");
    d.set_axis(AxisState {
        bus_mv: 48_000,
        ..AxisState::default()
    });
    d.tick(1000, 0);
    assert!(d.tune_permitted());
    let done = CurrentReport {
        tune: TuneStatus::Done,
        tuned: TunedValues {
            r_mohm: 402,
            l_uh: 1795,
            kp: 2256,
            ki: 505,
            calibration: crate::current_supervisor::Calibration {
                gain_b_e4: 9709,
                offset_ma: [20, -21],
                dead_time_mv: 498,
                l_low_uh: 1801,
            },
        },
        tune_seq: 1,
        ..CurrentReport::default()
    };
    d.current_report(&done);
    assert_eq!(sdo_read_u32(&mut d, 0x2020, 0), 402);
    assert_eq!(sdo_read_u32(&mut d, 0x2021, 0), 1795);
    assert_eq!(sdo_read_u32(&mut d, 0x2015, 0), 2256);
    assert_eq!(sdo_read_u32(&mut d, 0x2016, 0), 505);
    // The current-sensing calibration, read-only.
    assert_eq!(sdo_read_u32(&mut d, 0x2022, 0), 5);
    assert_eq!(sdo_read_u32(&mut d, 0x2022, 1), 9709);
    assert_eq!(sdo_read_u32(&mut d, 0x2022, 2), 20);
    assert_eq!(sdo_read_u32(&mut d, 0x2022, 3) as u16 as i16, -21);
    assert_eq!(sdo_read_u32(&mut d, 0x2022, 4), 498);
    assert_eq!(sdo_read_u32(&mut d, 0x2022, 5), 1801);
    assert_eq!(
        sdo_write(&mut d, 0x2022, 1, &1u16.to_le_bytes()),
        Err(SdoAbort::WriteReadOnly)
    );
    assert_eq!(
        d.read(ObjectKey::new(0x2022, 6), &mut [0u8; 8]),
        Err(SdoAbort::SubindexDoesNotExist)
    );
    // Default mask 0x00C3: motor open and current sensing are off.
    let failed = CurrentReport {
        tune: TuneStatus::Failed(TuneError::OpenPhase(Phase::B)),
        tune_seq: 2,
        follow_seq: 1,
        follow_ref_ma: 2500,
        ..CurrentReport::default()
    };
    d.current_report(&failed);
    assert!(!d.faults.any_active());
    assert!(d.pop_emergency().is_none());
    sdo_write(&mut d, 0x2056, 0, &0x00CFu16.to_le_bytes()).expect("mask");
    let failed = CurrentReport {
        tune_seq: 3,
        follow_seq: 2,
        ..failed
    };
    d.current_report(&failed);
    d.current_report(&failed);
    let e = d.pop_emergency().expect("motor open");
    assert_eq!((e.code, e.data[0], e.data[3], e.data[4]), (0x7120, 3, 1, 1));
    let e = d.pop_emergency().expect("current does not follow");
    assert_eq!(e.code, 0x5210);
    assert_eq!(u16::from_le_bytes([e.data[3], e.data[4]]), 2500);
    assert!(d.pop_emergency().is_none(), "one each");
    assert!(!d.tune_permitted(), "a fault withdraws the permission");
    assert_eq!(d.faults.error_code(), 0x5210, "most severe");
    assert_eq!(d.faults.led_code(), Some(9));
    // Events: a fault reset clears both. The failed tune is not retried by itself:
    // a new 0x2013 write asks for it.
    assert!(d.faults.fault_reset());
    assert!(!d.tune_permitted());
    sdo_write(&mut d, 0x2013, 0, &[1]).expect("a new request");
    assert!(d.tune_permitted());
    // A calibration outside its band: the current-sensing fault, detail 2, with its
    // emergency; the last good calibration stays readable.
    let sensing = CurrentReport {
        tune: TuneStatus::Failed(TuneError::Sensing),
        tune_seq: 4,
        ..failed
    };
    while d.pop_emergency().is_some() {}
    d.current_report(&sensing);
    let e = d.pop_emergency().expect("sensing");
    assert_eq!((e.code, e.data[3], e.data[4]), (0x5210, 2, 0));
    assert_eq!(sdo_read_u32(&mut d, 0x2022, 1), 9709);
}

#[test]
fn save_then_power_cycle_restores_parameters_and_mapping() {
    use crate::storage::RamFlash;
    use ecat_slave_stack::pdo::PdoConfig;
    use ecat_slave_stack::slave::RuntimeObjects;
    use ecat_slave_stack::sync::SyncState;

    let storage = Storage::new(0, 4096);
    let mut pdo = PdoConfig::new(crate::pdo_defaults::PDO_DEFAULTS);
    let mut sync = SyncState::new((0, 0));
    let mut d = Drive::with_store(
        Variant::HybridServo,
        7,
        FlashStore {
            storage,
            history: None,
            flash: RamFlash::<8192>::new(),
        },
    );
    {
        let mut rt = RuntimeObjects {
            pdo: &mut pdo,
            sync: &mut sync,
            objects: dictionary::OBJECTS,
        };
        d.power_up(&mut rt);
    }
    sdo_write_any(&mut d, 0x2000, 0, &2100u16.to_le_bytes()).expect("peak current");
    // Re-assign RxPDO 0x1601 through the runtime objects, then 'save' through the
    // runtime path so the mapping is stored too.
    {
        let mut rt = RuntimeObjects {
            pdo: &mut pdo,
            sync: &mut sync,
            objects: dictionary::OBJECTS,
        };
        rt.write(ObjectKey::new(0x1C12, 0), &[0], EsmState::PreOp)
            .expect("sub 0 to 0");
        rt.write(
            ObjectKey::new(0x1C12, 1),
            &0x1601u16.to_le_bytes(),
            EsmState::PreOp,
        )
        .expect("assign");
        rt.write(ObjectKey::new(0x1C12, 0), &[1], EsmState::PreOp)
            .expect("count");
        let save = crate::comm::SAVE.to_le_bytes();
        d.write_with_runtime(ObjectKey::new(0x1010, 1), &save, EsmState::PreOp, &mut rt)
            .expect("save");
    }
    // Power cycle: a new drive and runtime over the same flash.
    let FlashStore { flash, .. } = d.store.take().expect("store");
    let mut d2 = Drive::with_store(
        Variant::HybridServo,
        7,
        FlashStore {
            storage,
            history: None,
            flash,
        },
    );
    let mut pdo2 = PdoConfig::new(crate::pdo_defaults::PDO_DEFAULTS);
    let mut sync2 = SyncState::new((0, 0));
    let report = {
        let mut rt = RuntimeObjects {
            pdo: &mut pdo2,
            sync: &mut sync2,
            objects: dictionary::OBJECTS,
        };
        d2.power_up(&mut rt)
    };
    assert!(report.source.is_some(), "{report:?}");
    assert_eq!(sdo_read_u32_any(&mut d2, 0x2000, 0), 2100);
    let mut b = [0u8; 4];
    pdo2.read(ObjectKey::new(0x1C12, 1), &mut b)
        .expect("read assign");
    assert_eq!(u16::from_le_bytes([b[0], b[1]]), 0x1601);
    assert!(
        d2.pop_emergency().is_none(),
        "clean load sends no emergency"
    );
}

/// A parameter record of a format this image does not know (written by a newer
/// image, then an older one runs: an update the other way, or a revert) is
/// refused as a whole: the defaults apply, nothing is half-read, and the next
/// 'save' writes a record of this image's format.
#[test]
fn a_record_of_an_unknown_format_is_refused_and_defaults_apply() {
    use crate::storage::{record::field, RamFlash, FORMAT_VERSION};
    let storage = Storage::new(0, 4096);
    let store = |flash| FlashStore {
        storage,
        history: None,
        flash,
    };
    let mut d = Drive::with_store(Variant::HybridServo, 0, store(RamFlash::<8192>::new()));
    d.power_up(&mut NoRuntime);
    sdo_write_any(&mut d, 0x2000, 0, &2100u16.to_le_bytes()).expect("peak current");
    let save = crate::comm::SAVE.to_le_bytes();
    sdo_write_any(&mut d, 0x1010, 1, &save).expect("save");
    let FlashStore { mut flash, .. } = d.store.take().expect("store");
    // The format version of every slot one higher.
    let newer = (FORMAT_VERSION + 1).to_le_bytes();
    for slot in 0..2 {
        let at = storage.slot_address(slot) as usize;
        flash.mem[at + field::FORMAT.start..at + field::FORMAT.end].copy_from_slice(&newer);
    }
    let mut d2 = Drive::with_store(Variant::HybridServo, 0, store(flash));
    let report = d2.power_up(&mut NoRuntime);
    assert!(report.source.is_none(), "{report:?}");
    assert_eq!(sdo_read_u32_any(&mut d2, 0x2000, 0), 3200, "defaults");
    // A save of this image's format works over it.
    sdo_write_any(&mut d2, 0x2000, 0, &1900u16.to_le_bytes()).expect("peak current");
    sdo_write_any(&mut d2, 0x1010, 1, &save).expect("save");
    let FlashStore { flash, .. } = d2.store.take().expect("store");
    let mut d3 = Drive::with_store(Variant::HybridServo, 0, store(flash));
    assert!(d3.power_up(&mut NoRuntime).source.is_some());
    assert_eq!(sdo_read_u32_any(&mut d3, 0x2000, 0), 1900);
}

#[test]
fn corrupt_flash_gives_defaults_and_an_emergency() {
    use crate::storage::RamFlash;
    let storage = Storage::new(0, 4096);
    let mut flash = RamFlash::<8192>::new();
    for (i, b) in flash.mem.iter_mut().enumerate() {
        *b = (i as u8).wrapping_mul(37) ^ 0x5A;
    }
    let mut d = Drive::with_store(
        Variant::HybridServo,
        0,
        FlashStore {
            storage,
            history: None,
            flash,
        },
    );
    let report = d.power_up(&mut NoRuntime);
    assert!(report.source.is_none());
    assert_eq!(sdo_read_u32_any(&mut d, 0x2000, 0), 3200);
    let e = d.pop_emergency().expect("emergency for lost parameters");
    assert_eq!(e.code, crate::storage::EMCY_PARAMETERS_LOST);
}

type HistoryFlash = crate::storage::RamFlash<{ crate::storage::region::SIZE as usize }>;

/// A drive over `flash` with the product's record layout (parameters and fault
/// history), powered up, all detections enabled.
fn history_drive(flash: HistoryFlash) -> Drive<FlashStore<HistoryFlash>> {
    use crate::storage::region;
    let mut d = Drive::with_store(
        Variant::HybridServo,
        1,
        FlashStore {
            storage: region::PARAMS,
            history: Some(region::HISTORY),
            flash,
        },
    );
    d.power_up(&mut NoRuntime);
    sdo_write_any(&mut d, 0x2056, 0, &0xFFFFu16.to_le_bytes()).expect("mask");
    d
}

#[test]
fn staged_store_programs_a_save_before_the_history() {
    use crate::staged_flash::{Stage, StagedFlash};
    use crate::storage::region;
    let mut ram = HistoryFlash::new();
    let mut stage = Stage::<4096>::new();
    {
        let staged: StagedFlash<'_, &mut HistoryFlash, 4096, 2048> =
            StagedFlash::new(&mut ram, &mut stage, true);
        let mut d = Drive::with_store(
            Variant::HybridServo,
            1,
            FlashStore {
                storage: region::PARAMS,
                history: Some(region::HISTORY),
                flash: staged,
            },
        );
        d.power_up(&mut NoRuntime);
        let (none, err) = d.next_staged_record();
        assert!(none.is_none() && err.is_none(), "nothing to program");
        // A fault marks the history dirty, and a 'save' stages its record: the
        // save's record comes first, the history stays dirty for the next call.
        d.faults
            .raise(FaultKind::OverVoltage, Snapshot::default(), 5);
        let save = u32::from_le_bytes(*b"save").to_le_bytes();
        d.write(ObjectKey::new(0x1010, 1), &save, EsmState::PreOp)
            .expect("save");
        let (first, err) = d.next_staged_record();
        assert!(err.is_none());
        let first = first.expect("the save's record");
        assert_eq!(
            first.erased_range().map(|(from, _)| from),
            Some(region::PARAMS.slot_address(0))
        );
        d.store_mut().expect("store").flash.give_back(first);
        let (second, err) = d.next_staged_record();
        assert!(err.is_none());
        let second = second.expect("the history's record");
        assert_eq!(
            second.erased_range().map(|(from, _)| from),
            Some(region::HISTORY.slot_address(0))
        );
        d.store_mut().expect("store").flash.give_back(second);
        let (none, _) = d.next_staged_record();
        assert!(none.is_none(), "the history was written once");
    }
}

/// The history as the SDO dictionary shows it: (0x240n:01 code, :04 bus voltage,
/// :07 time, :08 operating time) for n = 1..6.
fn history_by_sdo<S: ParameterStore>(d: &mut Drive<S>) -> [[u32; 4]; 6] {
    let mut h = [[0u32; 4]; 6];
    for (i, e) in h.iter_mut().enumerate() {
        let index = 0x2401 + i as u16;
        assert_eq!(sdo_read_u32_any(d, index, 0), 8);
        *e = [1, 4, 7, 8].map(|sub| sdo_read_u32_any(d, index, sub));
    }
    h
}

/// Raises and resets `kind` at `now_ms` with bus voltage `bus_dv`.
fn fault_at<S: ParameterStore>(d: &mut Drive<S>, kind: FaultKind, bus_dv: u16, now_ms: u32) {
    let snap = Snapshot {
        bus_dv,
        ..Snapshot::default()
    };
    assert!(d.faults.raise(kind, snap, now_ms));
    d.faults.condition_gone(kind);
    d.faults.fault_reset();
}

/// 0x10F3 by complete access through the SDO server (segmented upload in a
/// 128-byte mailbox): the header entries and every message at its 28 bytes, the
/// same bytes as sub by sub.
#[test]
fn diagnosis_history_by_complete_access() {
    use ecat_slave_stack::coe::sdo::SdoServer;
    let mut d = Drive::new(Variant::HybridServo, 42);
    fault_at(&mut d, FaultKind::UnderVoltage, 100, 10);
    let mut single = [([0u8; 32], 0usize); 22];
    for (sub, (b, n)) in single.iter_mut().enumerate() {
        *n = Dictionary::read(&mut d, ObjectKey::new(0x10F3, sub as u8), b).unwrap();
    }
    let single: [&[u8]; 22] = core::array::from_fn(|k| &single[k].0[..single[k].1]);
    let mut server = SdoServer::new();
    let mut out = [0u8; 128 - 6 - 2];
    let state = EsmState::PreOp;
    // Initiate upload, complete access from sub-index 0.
    let n = server
        .on_request(
            &[0x50, 0xF3, 0x10, 0, 0, 0, 0, 0],
            &mut out,
            &mut d,
            state,
            0,
            None,
        )
        .unwrap();
    // `out` starts with the CoE header (2 bytes).
    assert_eq!(
        out[2] & 0xE0,
        0x40,
        "initiate upload response: {:x?}",
        &out[..n]
    );
    let total = u32::from_le_bytes(out[6..10].try_into().unwrap()) as usize;
    let mut image = [0u8; 512];
    let mut len = n - 10;
    image[..len].copy_from_slice(&out[10..n]);
    let mut toggle = 0u8;
    while len < total {
        let n = server
            .on_request(
                &[0x60 | toggle << 4, 0, 0, 0, 0, 0, 0, 0],
                &mut out,
                &mut d,
                state,
                0,
                None,
            )
            .unwrap();
        assert_eq!(out[2] & 0xE0, 0x00, "upload segment response");
        let unused = usize::from((out[2] >> 1) & 7);
        let k = if n == 10 { 7 - unused } else { n - 3 };
        image[len..len + k].copy_from_slice(&out[3..3 + k]);
        len += k;
        if out[2] & 1 == 1 {
            break;
        }
        toggle ^= 1;
    }
    assert_eq!(len, 8 + 16 * 28);
    assert_eq!(total, len);
    assert_eq!(image[0], single[0][0], "SI0");
    for sub in 1..=3 {
        assert_eq!(image[1 + sub], single[sub][0], "SI{sub}");
    }
    // SI4 was 1 before the newest message was read sub by sub, 0 since.
    assert_eq!((single[4][0], image[5]), (1, 0), "SI4");
    assert_eq!(image[6..8], *single[5], "SI5");
    for k in 0..16 {
        let m = &image[8 + 28 * k..8 + 28 * (k + 1)];
        let s = single[6 + k];
        assert_eq!(m[..s.len()], s[..], "message {k}");
        assert!(
            m[s.len()..].iter().all(|&b| b == 0),
            "padding of message {k}"
        );
    }
    assert_eq!(
        u32::from_le_bytes(image[8..12].try_into().unwrap()),
        0x3220_E800
    );
}

fn take_flash(d: Drive<FlashStore<HistoryFlash>>) -> HistoryFlash {
    let mut d = d;
    d.store.take().expect("store").flash
}

#[test]
fn fault_history_survives_a_power_cycle_and_is_written_only_when_serviced() {
    let mut d = history_drive(HistoryFlash::new());
    assert_eq!(history_by_sdo(&mut d), [[0; 4]; 6], "blank flash: empty");
    assert_eq!(d.persist_history(), None, "nothing to write");
    // 100 s of running time, then an over-voltage detected by the tick.
    for t in 1..=100_000u64 {
        d.tick(t * 1000, 0);
    }
    let ops = d.store.as_ref().map(|s| s.flash.ops);
    d.set_axis(AxisState {
        bus_mv: 60_000,
        ..AxisState::default()
    });
    d.tick(100_001_000, 0);
    assert!(d.faults.is_active(FaultKind::OverVoltage));
    assert!(d.faults.history_dirty());
    assert_eq!(
        d.store.as_ref().map(|s| s.flash.ops),
        ops,
        "the fault path does not touch the flash"
    );
    assert_eq!(d.persist_history(), Some(Ok(())));
    assert_eq!(d.persist_history(), None, "written once");
    let before = history_by_sdo(&mut d);
    assert_eq!(before[0], [0x3210, 600, 100_001, 100]);
    // Power cycle: the same history, over the SDO dictionary, and the operating
    // time went on from the stored one (no 'save' of 0x2307 happened).
    let mut d2 = history_drive(take_flash(d));
    assert_eq!(history_by_sdo(&mut d2), before);
    assert_eq!(sdo_read_u32_any(&mut d2, 0x2400, 2), 0x3210);
    assert_eq!(sdo_read_u32_any(&mut d2, 0x2307, 0), 100);
    assert!(!d2.faults.history_dirty(), "loading is no change");
    // A new entry goes on top of the loaded ones and carries the operating time.
    for t in 1..=5_000u64 {
        d2.tick(t * 1000, 0);
    }
    fault_at(&mut d2, FaultKind::UnderVoltage, 110, 5_000);
    assert_eq!(d2.persist_history(), Some(Ok(())));
    let mut d3 = history_drive(take_flash(d2));
    let h = history_by_sdo(&mut d3);
    assert_eq!(h[0], [0x3220, 110, 5_000, 105]);
    assert_eq!(h[1], before[0]);
    // 0x2093 = 1 clears it, in flash too.
    sdo_write_any(&mut d3, 0x2093, 0, &[1]).expect("clear");
    d3.tick(1000, 0);
    assert_eq!(history_by_sdo(&mut d3), [[0; 4]; 6]);
    assert_eq!(d3.persist_history(), Some(Ok(())));
    let mut d4 = history_drive(take_flash(d3));
    assert_eq!(history_by_sdo(&mut d4), [[0; 4]; 6], "cleared in flash");
}

/// issue 33: a master that resets a recurring fault every second for 6 hours
/// writes at most `BURST + 6 / 2` history records (one per change before the rate
/// limit: 21 600, which wears the two slots out), the RAM history stays complete and
/// the last change reaches the flash within `MAX_DELAY_MS`.
#[test]
fn a_fault_reset_every_second_does_not_wear_out_the_history_pages() {
    use crate::storage::rate::{BURST, MAX_DELAY_MS};
    let mut d = history_drive(HistoryFlash::new());
    let (mut records, hours) = (0u32, 6u32);
    let mut now_us = 0u64;
    for s in 1..=hours * 3600 {
        now_us += 1_000_000;
        d.tick(now_us, 0);
        let kind = if s % 2 == 0 {
            FaultKind::UnderVoltage
        } else {
            FaultKind::FollowingError
        };
        let now_ms = d.now_ms;
        fault_at(&mut d, kind, s as u16, now_ms);
        if let Some(r) = d.persist_history() {
            r.expect("written");
            records += 1;
        }
    }
    assert!(
        records <= BURST + hours / 2,
        "{records} records in {hours} h"
    );
    let ram = history_by_sdo(&mut d);
    assert_eq!(ram[0][1], hours * 3600, "RAM history complete");
    // No new change: the pending one is written within the bound.
    let mut waited = 0u32;
    while d.faults.history_dirty() {
        now_us += 1_000_000;
        d.tick(now_us, 0);
        waited += 1000;
        if let Some(r) = d.persist_history() {
            r.expect("written");
        }
        assert!(
            waited <= MAX_DELAY_MS,
            "still not written after {waited} ms"
        );
    }
    assert_eq!(history_by_sdo(&mut history_drive(take_flash(d))), ram);
}

#[test]
fn power_cut_at_every_byte_of_a_history_write_keeps_old_or_new_history() {
    // Old history: two entries, written.
    let mut d = history_drive(HistoryFlash::new());
    fault_at(&mut d, FaultKind::UnderVoltage, 111, 10);
    fault_at(&mut d, FaultKind::FollowingError, 222, 20);
    assert_eq!(d.persist_history(), Some(Ok(())));
    let old_flash = take_flash(d);
    let old = history_by_sdo(&mut history_drive(old_flash.clone()));
    assert_eq!((old[0][0], old[1][0], old[2][0]), (0x8611, 0x3220, 0));
    // The new history: one more entry; how many byte operations its write takes.
    let raise_new = |d: &mut Drive<FlashStore<HistoryFlash>>| {
        fault_at(d, FaultKind::MotorOpen, 333, 30);
    };
    let mut d = history_drive(old_flash.clone());
    raise_new(&mut d);
    if let Some(s) = d.store.as_mut() {
        s.flash.power_on();
    }
    assert_eq!(d.persist_history(), Some(Ok(())));
    let total = d.store.as_ref().map_or(0, |s| s.flash.ops);
    let new = history_by_sdo(&mut history_drive(take_flash(d)));
    assert_eq!((new[0][0], new[1][0], new[2][0]), (0x7120, 0x8611, 0x3220));
    assert!(
        total > 2048,
        "erase of a 2 KiB slot and the record: {total}"
    );
    // Old history until the record's last write is done (the flash model fails reads
    // of torn double words, as the chip's ECC does), the new one from then on.
    let (mut saw_old, mut saw_new) = (0, 0);
    for cut in 0..=total {
        let mut d = history_drive(old_flash.clone());
        raise_new(&mut d);
        if let Some(s) = d.store.as_mut() {
            s.flash.power_on();
            s.flash.cut_power_after(cut);
        }
        let r = d.persist_history();
        assert_eq!(r.is_some_and(|r| r.is_ok()), cut == total, "cut {cut}");
        let mut flash = take_flash(d);
        flash.power_on();
        // Restart: the history read back over the SDO dictionary.
        let mut d2 = history_drive(flash);
        let h = history_by_sdo(&mut d2);
        if h == old {
            assert_eq!(saw_new, 0, "old history after the new one (cut {cut})");
            saw_old += 1;
        } else {
            assert_eq!(h, new, "cut after {cut} of {total} operations");
            saw_new += 1;
        }
        assert_eq!(d2.faults.active_mask(), 0);
    }
    assert_eq!(saw_old + saw_new, total + 1);
    // The record's last write is the magic's double word: a cut inside it tears
    // the word (an ECC error on the chip: the slot reads as corrupt), so the new
    // history exists only once the write is complete.
    assert_eq!(saw_new, 1, "new only once committed");
}

#[test]
fn garbage_flash_gives_an_empty_history_and_the_drive_runs_on() {
    use crate::storage::region;
    let mut flash = HistoryFlash::new();
    let mut x = 0x1234_5678u32;
    for b in flash.mem.iter_mut() {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        *b = x as u8;
    }
    let mut d = history_drive(flash);
    assert_eq!(history_by_sdo(&mut d), [[0; 4]; 6]);
    fault_at(&mut d, FaultKind::UnderVoltage, 1, 1);
    assert_eq!(d.persist_history(), Some(Ok(())), "writes over garbage");
    let mut d = history_drive(take_flash(d));
    assert_eq!(history_by_sdo(&mut d)[0][0], 0x3220);
    // A record with a valid CRC but a payload that is no history (unknown kind,
    // wrong length): an empty history.
    for bad in [
        &[0u8, 0, 0, 0, 1, 0, 0, 0][..],
        &[0u8; 34][..],
        &[9u8; 3][..],
    ] {
        let mut flash = HistoryFlash::new();
        let mut p = [0u8; 34];
        p[..bad.len()].copy_from_slice(bad);
        if bad.len() == 34 {
            p[4] = 1;
            p[8] = 200; // kind 200
        }
        region::HISTORY
            .write_bytes(&mut flash, &p[..bad.len()])
            .expect("record");
        let mut d = history_drive(flash);
        assert_eq!(history_by_sdo(&mut d), [[0; 4]; 6], "{bad:?}");
    }
}

fn sdo_write_any<S: ParameterStore>(
    d: &mut Drive<S>,
    index: u16,
    sub: u8,
    data: &[u8],
) -> Result<(), SdoAbort> {
    let e = od::find_entry(dictionary::OBJECTS, ObjectKey::new(index, sub))?;
    od::check_write(e, data, EsmState::PreOp)?;
    d.write(ObjectKey::new(index, sub), data, EsmState::PreOp)
}

fn sdo_read_u32_any<S: ParameterStore>(d: &mut Drive<S>, index: u16, sub: u8) -> u32 {
    let mut b = [0u8; 8];
    let n = d.read(ObjectKey::new(index, sub), &mut b).expect("read");
    let mut v = [0u8; 4];
    v[..n.min(4)].copy_from_slice(&b[..n.min(4)]);
    u32::from_le_bytes(v)
}

/// 0x6091 / 0x6092 / 0x6093 and 0x2001 are views of one value: a write that gives a
/// whole number in 0x2001's range sets 0x2001 (pending, effective after restart), the
/// other views follow; one that does not is stored and leaves 0x2001; 0 is refused.
#[test]
fn gear_feed_and_position_factor_follow_0x2001() {
    let mut d = Drive::new(Variant::HybridServo, 0);
    // 1000-line encoder: 4000 increments per revolution; 0x2001 = 50 000.
    assert_eq!(sdo_read_u32(&mut d, 0x608F, 1), 4000);
    let factor = |d: &mut Drive| (sdo_read_u32(d, 0x6093, 1), sdo_read_u32(d, 0x6093, 2));
    assert_eq!(factor(&mut d), (2, 25));
    assert_eq!(sdo_read_u32(&mut d, 0x6092, 1), 50_000);
    // Feed 20 000 per shaft revolution, gear 2 motor : 1 shaft → 10 000 per motor rev.
    sdo_write(&mut d, 0x6092, 1, &20_000u32.to_le_bytes()).unwrap();
    sdo_write(&mut d, 0x6091, 1, &2u32.to_le_bytes()).unwrap();
    assert_eq!(sdo_read_u32(&mut d, 0x2001, 0), 10_000);
    assert_eq!(factor(&mut d), (2, 5));
    // 20 000 / 3 is not whole: stored, 0x2001 keeps 10 000.
    sdo_write(&mut d, 0x6091, 1, &3u32.to_le_bytes()).unwrap();
    assert_eq!(sdo_read_u32(&mut d, 0x6091, 1), 3);
    assert_eq!(sdo_read_u32(&mut d, 0x2001, 0), 10_000);
    // 20 000 / 200 = 100: whole, but 0x2001's range (200-51 200) refuses it.
    sdo_write(&mut d, 0x6091, 1, &200u32.to_le_bytes()).unwrap();
    assert_eq!(
        sdo_read_u32(&mut d, 0x2001, 0),
        10_000,
        "100 < 0x2001's minimum"
    );
    assert_eq!(
        sdo_write(&mut d, 0x6091, 1, &0u32.to_le_bytes()),
        Err(SdoAbort::ValueTooLow)
    );
    // The factor: 4000 increments per 8000 units → 0x2001 = 8000, gear 1:1.
    sdo_write(&mut d, 0x6093, 1, &4000u32.to_le_bytes()).unwrap();
    sdo_write(&mut d, 0x6093, 2, &8000u32.to_le_bytes()).unwrap();
    assert_eq!(sdo_read_u32(&mut d, 0x2001, 0), 8000);
    assert_eq!(sdo_read_u32(&mut d, 0x6091, 1), 1);
    assert_eq!(sdo_read_u32(&mut d, 0x6092, 1), 8000);
    assert_eq!(factor(&mut d), (4000, 8000));
    // 0x2001 written: gear 1:1, feed (0x2001, 1), the factor derived.
    sdo_write(&mut d, 0x2001, 0, &12_800u32.to_le_bytes()).unwrap();
    assert_eq!(sdo_read_u32(&mut d, 0x6092, 1), 12_800);
    assert_eq!(factor(&mut d), (5, 16));
}
