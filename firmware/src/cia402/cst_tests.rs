//! Cyclic synchronous torque (CST): mode dispatch, slope, limit, offset, the speed
//! limit in the command, the stops, availability (0x6502) and the SDO rules of the
//! torque objects; profile torque (PT); the enable without a mode.

extern crate std;
use super::*;
use crate::dictionary::Sdo;
use ecat_slave_stack::od::SdoAbort;

const DT: f32 = 0.001;

fn fb_at(velocity: i32, servo_torque: i16) -> DriveFeedback {
    DriveFeedback {
        velocity,
        torque: servo_torque,
        torque_demand: servo_torque,
        current: servo_torque,
        ..Default::default()
    }
}

/// A drive in Operation enabled in mode `m` (set before the enable).
fn enabled(m: i8) -> Cia402 {
    let mut d = Cia402::new();
    d.set_mode(m);
    for cw in [0x0000, 0x0006, 0x0007, 0x000F] {
        d.set_controlword(cw);
        d.cycle(&DriveFeedback::default(), DT);
    }
    assert_eq!(d.state(), PdsState::OperationEnabled);
    assert_eq!(d.mode_display(), m);
    d
}

fn sdo_i16(d: &mut Cia402, index: u16, v: i16) -> Result<(), SdoAbort> {
    d.write(index, 0, &v.to_le_bytes())
}

fn sdo_u32(d: &mut Cia402, index: u16, v: u32) -> Result<(), SdoAbort> {
    d.write(index, 0, &v.to_le_bytes())
}

#[test]
fn cst_commands_the_target_torque_with_the_speed_limit() {
    let mut d = enabled(mode::CST);
    sdo_i16(&mut d, 0x6071, 300).unwrap();
    sdo_u32(&mut d, 0x6080, 250_000).unwrap();
    let c = d.cycle(&fb_at(1234, 0), DT);
    assert_eq!(c.kind, SetpointKind::Torque);
    assert!(c.drive_enabled && c.power_stage);
    assert_eq!(c.torque, 300);
    assert_eq!(c.velocity, 250_000.0, "the speed limit 0x6080");
    // Target torque used: bit 12; no internal limit.
    assert_eq!(
        d.statusword() & (sw::DRIVE_FOLLOWS | sw::INTERNAL_LIMIT),
        sw::DRIVE_FOLLOWS
    );
    assert_eq!(d.value(0x6074, 0), Some(300));
    assert_eq!(d.value(0x6061, 0), Some(10));
    // The generator shows the actual speed (0x606B = 0x606C): a stop starts there.
    assert_eq!(d.velocity_demand(), 1234);
}

#[test]
fn cst_slope_limit_and_offset() {
    let mut d = enabled(mode::CST);
    // 0x6087 = 50 000 per mille/s: 50 per 1 ms step.
    sdo_u32(&mut d, 0x6087, 50_000).unwrap();
    sdo_i16(&mut d, 0x6071, 180).unwrap();
    let t: std::vec::Vec<i32> = (0..5).map(|_| d.cycle(&fb_at(0, 0), DT).torque).collect();
    assert_eq!(t, [50, 100, 150, 180, 180]);
    // Down again at the same rate, with the offset added to the target.
    sdo_i16(&mut d, 0x6071, -100).unwrap();
    sdo_i16(&mut d, 0x60B2, 30).unwrap();
    let t: std::vec::Vec<i32> = (0..6).map(|_| d.cycle(&fb_at(0, 0), DT).torque).collect();
    assert_eq!(t, [130, 80, 30, -20, -70, -70]);
    // 0 = no slope limit: the demand steps.
    sdo_u32(&mut d, 0x6087, 0).unwrap();
    sdo_i16(&mut d, 0x6071, 900).unwrap();
    assert_eq!(d.cycle(&fb_at(0, 0), DT).torque, 930);
    // Limited to ±0x6072, with the internal limit (bit 11).
    sdo_u32(&mut d, 0x6072, 0).unwrap_err();
    d.write(0x6072, 0, &500u16.to_le_bytes()).unwrap();
    assert_eq!(d.cycle(&fb_at(0, 0), DT).torque, 500);
    assert!(d.statusword() & sw::INTERNAL_LIMIT != 0);
    sdo_i16(&mut d, 0x6071, -3000).unwrap();
    assert_eq!(d.cycle(&fb_at(0, 0), DT).torque, -500);
    assert_eq!(d.value(0x6074, 0), Some(-500));
}

#[test]
fn torque_offset_is_the_feed_forward_of_csp_and_csv() {
    for m in [mode::CSP, mode::CSV] {
        let mut d = enabled(m);
        sdo_i16(&mut d, 0x60B2, -120).unwrap();
        let c = d.cycle(&fb_at(0, 0), DT);
        assert_eq!(
            (c.kind == SetpointKind::Torque, c.torque),
            (false, -120),
            "{m}"
        );
    }
    // Not in the profile modes.
    let mut d = enabled(mode::PV);
    sdo_i16(&mut d, 0x60B2, -120).unwrap();
    assert_eq!(d.cycle(&fb_at(0, 0), DT).torque, 0);
}

#[test]
fn cst_entry_starts_from_the_servo_torque_and_polarity_applies() {
    // CSP holding against a load: the servo demands 250 per mille. The switch to CST
    // with a slope starts there and moves to the target: no jump.
    let mut d = enabled(mode::CSP);
    d.cycle(&fb_at(0, 250), DT);
    sdo_u32(&mut d, 0x6087, 100_000).unwrap();
    sdo_i16(&mut d, 0x6071, 0).unwrap();
    d.set_mode(mode::CST);
    let c = d.cycle(&fb_at(0, 250), DT);
    assert_eq!((c.kind, c.torque), (SetpointKind::Torque, 150));
    // Velocity polarity (0x607E bit 6) turns torques round both ways.
    let mut d = enabled(mode::CST);
    d.set_controlword(0x0006);
    d.cycle(&fb_at(0, 0), DT);
    d.write(0x607E, 0, &[0x40]).unwrap();
    for cw in [0x0007, 0x000F] {
        d.set_controlword(cw);
        d.cycle(&fb_at(0, 0), DT);
    }
    sdo_i16(&mut d, 0x6071, 200).unwrap();
    let c = d.cycle(&fb_at(0, -77), DT);
    assert_eq!(c.torque, -200);
    assert_eq!(d.value(0x6077, 0), Some(77));
}

#[test]
fn cst_halt_and_quick_stop_ramp_from_the_actual_speed() {
    let mut d = enabled(mode::CST);
    sdo_i16(&mut d, 0x6071, 400).unwrap();
    sdo_u32(&mut d, 0x6085, 1_000_000).unwrap();
    d.cycle(&fb_at(100_000, 400), DT);
    // Halt (0x605D = 1: 0x6084 = 500 000): velocity control from the actual speed.
    d.set_controlword(0x010F);
    let c = d.cycle(&fb_at(100_000, 400), DT);
    assert_eq!(c.kind, SetpointKind::Velocity);
    assert!((c.velocity - 99_500.0).abs() < 1.0, "{}", c.velocity);
    assert_eq!(c.torque, 0);
    assert!(d.statusword() & sw::DRIVE_FOLLOWS == 0 && d.statusword() & sw::ABNORMAL_STOP != 0);
    // Released: torque control again, from the servo torque (no slope: the target).
    d.set_controlword(0x000F);
    let c = d.cycle(&fb_at(90_000, 400), DT);
    assert_eq!((c.kind, c.torque), (SetpointKind::Torque, 400));
    // Quick stop (0x605A = 2): position control on the 0x6085 ramp from the actual
    // speed, then Switch on disabled.
    d.set_controlword(0x000B);
    let c = d.cycle(&fb_at(90_000, 400), DT);
    assert_eq!(
        (d.state(), c.kind),
        (PdsState::QuickStopActive, SetpointKind::Position)
    );
    assert!((c.velocity - 89_000.0).abs() < 1.0, "{}", c.velocity);
    let mut n = 0;
    while d.state() == PdsState::QuickStopActive && n < 200 {
        d.cycle(&fb_at(0, 0), DT);
        n += 1;
    }
    assert_eq!(d.state(), PdsState::SwitchOnDisabled);
    assert!(
        (89..=91).contains(&n),
        "{n} ms for 89 000 inc/s at 1e6 inc/s²"
    );
}

#[test]
fn cst_stops_at_a_limit_switch_in_the_direction_of_the_torque() {
    let mut d = enabled(mode::CST);
    sdo_i16(&mut d, 0x6071, 300).unwrap();
    let pos_limit = DriveFeedback {
        digital_inputs: homing::DI_POS_LIMIT,
        ..fb_at(0, 300)
    };
    let c = d.cycle(&pos_limit, DT);
    assert_eq!(c.kind, SetpointKind::Velocity);
    assert!(d.statusword() & sw::ABNORMAL_STOP != 0);
    // Away from the switch: torque control.
    sdo_i16(&mut d, 0x6071, -300).unwrap();
    let c = d.cycle(&pos_limit, DT);
    assert_eq!((c.kind, c.torque), (SetpointKind::Torque, -300));
}

#[test]
fn cst_needs_the_closed_loop() {
    let mut d = Cia402::new();
    d.set_torque_control(false);
    assert_eq!(d.value(0x6502, 0), Some(0x1A5));
    assert_eq!(d.write(0x6060, 0, &[10]), Err(SdoAbort::ValueRangeExceeded));
    // An RxPDO value is not taken over.
    let slot = rx_slot_of(0x6060);
    d.set_rx(slot, &[10]);
    assert_eq!(d.mode_request(), 0);
    d.set_torque_control(true);
    assert_eq!(d.value(0x6502, 0), Some(0x3AD));
    d.write(0x6060, 0, &[10]).unwrap();
    // Losing the closed loop while CST is requested: no mode, the axis stops.
    let mut d = enabled(mode::CST);
    d.cycle(&fb_at(50_000, 0), DT);
    d.set_torque_control(false);
    assert_eq!(d.mode_request(), 0);
    let c = d.cycle(&fb_at(50_000, 0), DT);
    assert_eq!((d.mode_display(), c.kind), (0, SetpointKind::Position));
    assert!(c.velocity < 50_000.0 && c.velocity > 0.0, "{}", c.velocity);
}

fn rx_slot_of(index: u16) -> u8 {
    objects::rx_slot(index, 0).unwrap()
}

#[test]
fn torque_objects_refuse_bad_values() {
    let mut d = Cia402::new();
    for index in [0x6071, 0x60B2] {
        assert_eq!(sdo_i16(&mut d, index, 3001), Err(SdoAbort::ValueTooHigh));
        assert_eq!(sdo_i16(&mut d, index, -3001), Err(SdoAbort::ValueTooLow));
        assert_eq!(d.write(index, 0, &[1]), Err(SdoAbort::LengthTooLow));
        assert_eq!(d.value(index, 0), Some(0));
        sdo_i16(&mut d, index, -3000).unwrap();
        assert_eq!(d.value(index, 0), Some(-3000));
        // An RxPDO value beyond the range is clamped.
        d.set_rx(rx_slot_of(index), &4000i16.to_le_bytes());
        assert_eq!(d.value(index, 0), Some(3000));
    }
    assert_eq!(d.write(0x6087, 0, &[1, 2]), Err(SdoAbort::LengthTooLow));
    sdo_u32(&mut d, 0x6087, u32::MAX).unwrap();
    for index in [0x6074, 0x6076, 0x6077] {
        assert_eq!(d.write(index, 0, &[0, 0]), Err(SdoAbort::WriteReadOnly));
    }
    assert!(objects::tx_slot(0x6074, 0).is_some() && rx_slot_of(0x6071) < 255);
    assert!(objects::rx_slot(0x6087, 0).is_some() && objects::rx_slot(0x60B2, 0).is_some());
}

#[test]
fn rated_torque_is_kt_times_the_rated_current() {
    let mut d = Cia402::new();
    // ECN57-20: 0.283 N·m/A at 3.2 A (the power-up value is the motion layer's motor).
    assert_eq!(d.torque_constant, crate::motion::ECN57_20.kt);
    assert_eq!(d.value(0x6076, 0), Some(906));
    d.set_torque_constant(0.530);
    d.set_rated_current_ma(6000);
    assert_eq!(d.value(0x6076, 0), Some(3180));
    d.set_torque_constant(f32::NAN);
    assert_eq!(d.value(0x6076, 0), Some(0));
}

/// Profile torque (0x6060 = 4): the CST demand on the ramp 0x6087, statusword bit 10
/// when the demand has reached the limited target (not bit 12), closed loop only,
/// 0x6088 only linear (0).
#[test]
fn pt_ramps_to_the_target_torque_and_reports_target_reached() {
    let mut d = enabled(mode::PT);
    assert_eq!(d.value(0x6061, 0), Some(4));
    sdo_u32(&mut d, 0x6087, 100_000).unwrap();
    sdo_i16(&mut d, 0x6071, 250).unwrap();
    let mut t = std::vec::Vec::new();
    for _ in 0..4 {
        let c = d.cycle(&fb_at(0, 0), DT);
        assert_eq!(c.kind, SetpointKind::Torque);
        t.push((c.torque, d.statusword() & sw::TARGET_REACHED != 0));
    }
    assert_eq!(t, [(100, false), (200, false), (250, true), (250, true)]);
    assert_eq!(
        d.statusword() & sw::DRIVE_FOLLOWS,
        0,
        "bit 12 is reserved in PT"
    );
    assert_eq!(d.value(0x6074, 0), Some(250));
    // A new target: not reached until the ramp gets there; limited by 0x6072.
    d.write(0x6072, 0, &200u16.to_le_bytes()).unwrap();
    sdo_i16(&mut d, 0x6071, -900).unwrap();
    let c = d.cycle(&fb_at(0, 0), DT);
    assert_eq!(c.torque, 150);
    assert_eq!(d.statusword() & sw::TARGET_REACHED, 0);
    for _ in 0..4 {
        d.cycle(&fb_at(0, 0), DT);
    }
    assert_eq!(d.value(0x6074, 0), Some(-200));
    assert_ne!(d.statusword() & sw::TARGET_REACHED, 0);
    // Halt: velocity control to rest, then target reached.
    d.set_controlword(0x010F);
    let c = d.cycle(&fb_at(0, 0), DT);
    assert_eq!(c.kind, SetpointKind::Velocity);
    assert_ne!(d.statusword() & sw::TARGET_REACHED, 0, "halted at rest");
    // 0x6088: only the linear ramp.
    assert_eq!(sdo_i16(&mut d, 0x6088, 1), Err(SdoAbort::ValueTooHigh));
    assert_eq!(sdo_i16(&mut d, 0x6088, -1), Err(SdoAbort::ValueTooLow));
    sdo_i16(&mut d, 0x6088, 0).unwrap();
    assert_eq!(d.value(0x6088, 0), Some(0));
    // Open loop: PT refused like CST, and withdrawn while requested.
    d.set_torque_control(false);
    assert_eq!(d.mode_request(), 0);
    assert_eq!(d.write(0x6060, 0, &[4]), Err(SdoAbort::ValueRangeExceeded));
    d.set_rx(rx_slot_of(0x6060), &[4]);
    assert_eq!(d.mode_request(), 0);
}

/// 0x60C0: linear interpolation only; 0x605A, 0x6066, 0x6068 RxPDO-mappable, a PDO
/// value clamped to the SDO range.
#[test]
fn interpolation_sub_mode_and_the_mappable_option_objects() {
    let mut d = Cia402::new();
    assert_eq!(d.value(0x60C0, 0), Some(0));
    assert_eq!(sdo_i16(&mut d, 0x60C0, -1), Err(SdoAbort::ValueTooLow));
    assert_eq!(sdo_i16(&mut d, 0x60C0, 1), Err(SdoAbort::ValueTooHigh));
    sdo_i16(&mut d, 0x60C0, 0).unwrap();
    d.set_rx(rx_slot_of(0x605A), &9i16.to_le_bytes());
    assert_eq!(d.value(0x605A, 0), Some(8), "clamped to 0-8");
    d.set_rx(rx_slot_of(0x605A), &5i16.to_le_bytes());
    assert_eq!(d.value(0x605A, 0), Some(5));
    d.set_rx(rx_slot_of(0x6066), &250u16.to_le_bytes());
    assert_eq!(d.value(0x6066, 0), Some(250));
    d.set_rx(rx_slot_of(0x6068), &40u16.to_le_bytes());
    assert_eq!(d.value(0x6068, 0), Some(40));
}

/// Enabled with 0x6060 = 0: no fault, the axis holds where it is in position control
/// (a moving axis stops on the quick-stop ramp first), no mode bits.
#[test]
fn enabled_without_a_mode_holds_position() {
    let mut d = enabled(mode::NONE);
    let c = d.cycle(&fb_at(0, 0), DT);
    assert_eq!(d.state(), PdsState::OperationEnabled);
    assert_eq!((c.kind, c.velocity), (SetpointKind::Position, 0.0));
    assert!(c.drive_enabled);
    assert_eq!(
        d.statusword() & (sw::TARGET_REACHED | sw::DRIVE_FOLLOWS | sw::FOLLOWING_ERROR),
        0
    );
    assert_eq!(d.value(0x603F, 0), Some(0));
}
