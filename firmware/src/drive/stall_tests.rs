//! The drive's side of the open-loop stall detection: the 0x2062 reactions, stall
//! homing (0x6098 = -1 / -2) and the SDO rules of 0x2060-0x2063.
use super::*;
use crate::cia402::homing::HomingStatus;
use crate::cia402::pds::PdsState;
use ecat_slave_stack::od::ObjectKey;

fn sdo_write(d: &mut Drive, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoAbort> {
    let e = od::find_entry(dictionary::OBJECTS, ObjectKey::new(index, sub))?;
    od::check_write(e, data, EsmState::PreOp)?;
    d.write(ObjectKey::new(index, sub), data, EsmState::PreOp)
}

fn axis(position: i32, stall_seq: u32, stall_position: i32) -> AxisState {
    AxisState {
        bus_mv: 48_000,
        position,
        stall_seq,
        stall_position,
        load_angle_ddeg: -1234,
        ..AxisState::default()
    }
}

fn enable(d: &mut Drive) {
    d.set_axis(axis(0, 0, 0));
    for cw in [0x06u16, 0x07, 0x0F] {
        d.cia402.set_controlword(cw);
        for _ in 0..3 {
            d.run_cycle(0.001);
        }
    }
    assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
}

fn open_loop_drive() -> Drive {
    let mut d = Drive::new(Variant::OpenLoop, 0);
    sdo_write(&mut d, 0x2060, 0, &[1]).expect("enable");
    d
}

#[test]
fn stall_objects_ranges_and_read_only_load_angle() {
    let mut d = open_loop_drive();
    assert_eq!(
        sdo_write(&mut d, 0x2060, 0, &[2]),
        Err(SdoAbort::ValueTooHigh)
    );
    assert_eq!(
        sdo_write(&mut d, 0x2061, 0, &[4]),
        Err(SdoAbort::ValueTooLow)
    );
    assert_eq!(
        sdo_write(&mut d, 0x2061, 0, &[91]),
        Err(SdoAbort::ValueTooHigh)
    );
    assert_eq!(
        sdo_write(&mut d, 0x2062, 0, &[2]),
        Err(SdoAbort::ValueTooHigh)
    );
    assert_eq!(
        sdo_write(&mut d, 0x2061, 0, &[40, 0]),
        Err(SdoAbort::LengthTooHigh)
    );
    assert_eq!(
        sdo_write(&mut d, 0x2063, 0, &[0, 0]),
        Err(SdoAbort::WriteReadOnly)
    );
    sdo_write(&mut d, 0x2061, 0, &[45]).expect("in range");
    assert_eq!(d.params.get(Param::StallSensitivity), 45);
    d.set_axis(axis(0, 0, 0));
    let mut b = [0u8; 2];
    assert_eq!(d.read(ObjectKey::new(0x2063, 0), &mut b), Ok(2));
    assert_eq!(i16::from_le_bytes(b), -1234);
    // The motion configuration takes the threshold and the motor model.
    let cfg = crate::motion::MotionConfig::from_params(
        &d.params,
        Variant::OpenLoop,
        &crate::motion::ECN57_20,
        1e-4,
    );
    let s = cfg.stall.expect("enabled");
    assert_eq!((s.threshold, s.r, s.l, s.ke), (0.45, 0.40, 1.8e-3, 0.283));
}

#[test]
fn stall_raises_motor_blocked_with_one_emergency_then_resets() {
    let mut d = open_loop_drive();
    enable(&mut d);
    while d.pop_emergency().is_some() {}
    d.set_axis(axis(100, 1, 90));
    d.run_cycle(0.001);
    assert_eq!(d.faults.error_code(), 0x7121);
    let e = d.pop_emergency().expect("emergency");
    assert_eq!(e.code, 0x7121);
    assert_eq!(e.data[0], FaultKind::MotorBlocked as u8);
    assert_eq!([e.data[3], e.data[4]], (-1234i16).to_le_bytes());
    // The same stall is one event.
    for _ in 0..50 {
        d.run_cycle(0.001);
    }
    assert!(d.pop_emergency().is_none());
    assert_eq!(d.cia402.state(), PdsState::Fault);
    assert_eq!(d.faults.led_code(), Some(5));
    d.cia402.set_controlword(0x80);
    for _ in 0..3 {
        d.run_cycle(0.001);
    }
    assert_eq!(d.cia402.state(), PdsState::SwitchOnDisabled);
    assert_eq!(d.faults.error_code(), 0);
}

#[test]
fn stall_with_reaction_1_is_a_quick_stop_without_fault() {
    let mut d = open_loop_drive();
    sdo_write(&mut d, 0x2062, 0, &[1]).expect("quick stop");
    enable(&mut d);
    d.set_axis(axis(0, 7, 0));
    d.run_cycle(0.001);
    assert_eq!(d.faults.error_code(), 0);
    assert_ne!(d.cia402.state(), PdsState::OperationEnabled);
    assert_ne!(d.cia402.state(), PdsState::Fault);
}

#[test]
fn stall_homing_without_its_preconditions_is_a_homing_error_with_no_motion() {
    // (0x2060, 0x6099:01): detection off; a search below its 1 rev/s (50 000 inc/s).
    for (detection, search) in [(0u8, 60_000u32), (1, 20_000)] {
        let mut d = Drive::new(Variant::OpenLoop, 0);
        sdo_write(&mut d, 0x2060, 0, &[detection]).unwrap();
        sdo_write(&mut d, 0x6099, 1, &search.to_le_bytes()).unwrap();
        sdo_write(&mut d, 0x6098, 0, &[-1i8 as u8]).unwrap();
        sdo_write(&mut d, 0x6060, 0, &[6]).unwrap();
        enable(&mut d);
        let start = d.command().position;
        d.cia402.set_controlword(0x1F);
        for _ in 0..200 {
            d.run_cycle(0.001);
            d.set_axis(axis(d.command().position, 0, 0));
        }
        let case = (detection, search);
        assert_eq!(d.cia402.homing_status(), HomingStatus::Error, "{case:?}");
        assert_ne!(
            d.cia402.statusword() & 1 << 13,
            0,
            "homing error bit {case:?}"
        );
        assert_eq!(d.command().position, start, "no motion {case:?}");
        assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
    }
    // A closed loop (hybrid servo, 0x2024 = 2) has no stall detection.
    let mut d = Drive::new(Variant::HybridServo, 0);
    sdo_write(&mut d, 0x2060, 0, &[1]).unwrap();
    sdo_write(&mut d, 0x6099, 1, &60_000u32.to_le_bytes()).unwrap();
    sdo_write(&mut d, 0x6098, 0, &[-2i8 as u8]).unwrap();
    sdo_write(&mut d, 0x6060, 0, &[6]).unwrap();
    enable(&mut d);
    d.cia402.set_controlword(0x1F);
    for _ in 0..20 {
        d.run_cycle(0.001);
    }
    assert_eq!(d.cia402.homing_status(), HomingStatus::Error);
}

#[test]
fn stall_homing_sets_home_at_the_stall_without_a_fault() {
    let mut d = open_loop_drive();
    sdo_write(&mut d, 0x6098, 0, &[-3i8 as u8]).expect_err("not a method");
    sdo_write(&mut d, 0x6098, 0, &[-1i8 as u8]).expect("stall homing +");
    sdo_write(&mut d, 0x607C, 0, &250i32.to_le_bytes()).expect("offset");
    // Search at 1.2 rev/s: above the detection's 1 rev/s.
    sdo_write(&mut d, 0x6099, 1, &60_000u32.to_le_bytes()).expect("search speed");
    sdo_write(&mut d, 0x6060, 0, &[6]).expect("HM");
    enable(&mut d);
    d.cia402.set_controlword(0x1F);
    let mut pos = 0;
    for _ in 0..200 {
        d.run_cycle(0.001);
        pos = d.command().position;
        d.set_axis(axis(pos, 0, 0));
    }
    assert!(pos > 2000, "searching in the positive direction: {pos}");
    assert!(d.cia402.seeking_stall());
    let at = pos - 40;
    d.set_axis(axis(pos, 1, at));
    d.run_cycle(0.001);
    assert_eq!(d.faults.error_code(), 0, "the reference, not a fault");
    for _ in 0..2000 {
        let p = d.command().position;
        d.set_axis(axis(p, 1, at));
        d.run_cycle(0.001);
    }
    assert_eq!(d.cia402.homing_status(), HomingStatus::Attained);
    assert_eq!(
        d.command().position,
        at,
        "the demand rests at the stall position"
    );
    assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
}
