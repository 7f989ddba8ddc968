//! The drive's own safety decisions at its edges: when the current auto-tune may
//! energise the motor, and what leaving Pre-Op for Init or Bootstrap does to an axis
//! enabled outside Op.

use super::tests::{enable, sdo_read_u32, sdo_write};
use super::*;
use crate::cia402::pds::PdsState;
use crate::current_supervisor::{CurrentReport, TuneStatus};
use ecat_slave_stack::esm::EsmHooks;

fn steps(d: &mut Drive, n: usize) {
    for _ in 0..n {
        d.run_cycle(0.001);
    }
}

fn powered_up(esm: EsmState) -> Drive {
    let mut d = Drive::new(Variant::HybridServo, 0);
    d.on_state_change(EsmState::Init, EsmState::PreOp);
    if esm != EsmState::PreOp {
        d.on_state_change(EsmState::PreOp, esm);
    }
    d.set_axis(AxisState {
        bus_mv: 48_000,
        ..AxisState::default()
    });
    steps(&mut d, 2);
    d
}

#[test]
fn auto_tune_refused_while_enabled_and_in_bootstrap() {
    let mut d = powered_up(EsmState::PreOp);
    // 0x2013 = 1 (the default): the tune may run while the power stage is off.
    assert_eq!(d.params.get(Param::AutoTune), 1);
    assert!(d.tune_permitted());
    enable(&mut d);
    assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
    assert!(!d.tune_permitted(), "no tune while the power stage is on");
    // 0 is always accepted (it stops a tune); 1 is refused while enabled.
    assert_eq!(sdo_write(&mut d, 0x2013, 0, &[0]), Ok(()));
    assert_eq!(
        sdo_write(&mut d, 0x2013, 0, &[1]),
        Err(SdoAbort::StateConflict)
    );
    assert_eq!(
        d.params.get(Param::AutoTune),
        0,
        "the refused write changed nothing"
    );
    // Switched off again: the tune may be asked for.
    d.cia402.set_controlword(0x06);
    steps(&mut d, 3);
    assert_eq!(d.cia402.state(), PdsState::ReadyToSwitchOn);
    assert_eq!(sdo_write(&mut d, 0x2013, 0, &[1]), Ok(()));
    assert!(d.tune_permitted());
    // Bootstrap: never.
    let mut d = powered_up(EsmState::PreOp);
    d.on_state_change(EsmState::PreOp, EsmState::Init);
    d.on_state_change(EsmState::Init, EsmState::Bootstrap);
    steps(&mut d, 2);
    assert!(!d.tune_permitted());
    assert_eq!(
        sdo_write(&mut d, 0x2013, 0, &[1]),
        Err(SdoAbort::StateConflict)
    );
}

#[test]
fn a_failed_tune_does_not_rearm_itself() {
    let mut d = powered_up(EsmState::PreOp);
    sdo_write(&mut d, 0x2013, 0, &[1]).unwrap();
    assert!(d.tune_permitted());
    let failed = CurrentReport {
        tune: TuneStatus::Failed(foc::autotune::TuneError::Implausible),
        tune_seq: 1,
        ..CurrentReport::default()
    };
    d.current_report(&failed);
    // Whatever the fault mask made of it, once reset the permission does not return
    // by itself.
    d.faults.fault_reset();
    steps(&mut d, 2);
    assert!(!d.faults.any_active());
    assert!(!d.tune_permitted(), "no retry without a new request");
    // A new 0x2013 write asks again.
    sdo_write(&mut d, 0x2013, 0, &[1]).unwrap();
    assert!(d.tune_permitted());
}

#[test]
fn init_from_an_enabled_pre_op_runs_the_0x6007_reaction() {
    // Enabled by SDO in Pre-Op, moving in PV; the master takes the ESM to Init.
    let mut d = powered_up(EsmState::PreOp);
    sdo_write(&mut d, 0x6060, 0, &[3]).unwrap();
    sdo_write(&mut d, 0x60FF, 0, &50_000i32.to_le_bytes()).unwrap();
    enable(&mut d);
    steps(&mut d, 100);
    assert!(d.command().velocity > 0.0);
    d.on_state_change(EsmState::PreOp, EsmState::Init);
    // 0x6007 = 1 (default): fault reaction on the 0x605E ramp, then Fault.
    steps(&mut d, 500);
    assert_eq!(d.cia402.state(), PdsState::Fault);
    assert!(!d.command().drive_enabled && !d.command().power_stage);
    assert_eq!(d.command().velocity, 0.0);
}

#[test]
fn bootstrap_stops_first_and_never_reenables() {
    for option in [0i16, 1, 2, 3] {
        let mut d = powered_up(EsmState::PreOp);
        sdo_write(&mut d, 0x6007, 0, &option.to_le_bytes()).unwrap();
        sdo_write(&mut d, 0x6060, 0, &[3]).unwrap();
        sdo_write(&mut d, 0x60FF, 0, &50_000i32.to_le_bytes()).unwrap();
        enable(&mut d);
        steps(&mut d, 100);
        d.on_state_change(EsmState::PreOp, EsmState::Init);
        d.on_state_change(EsmState::Init, EsmState::Bootstrap);
        steps(&mut d, 500);
        assert!(
            !d.command().power_stage && !d.command().drive_enabled,
            "0x6007 = {option}: power off in Bootstrap"
        );
        // Back to Init: nothing re-energises, whatever the old controlword was.
        d.on_state_change(EsmState::Bootstrap, EsmState::Init);
        d.on_state_change(EsmState::Init, EsmState::PreOp);
        steps(&mut d, 50);
        assert!(
            !d.command().power_stage && !d.command().drive_enabled,
            "0x6007 = {option}: re-energised after Bootstrap ({:?})",
            d.cia402.state()
        );
        assert!(!d.cia402.state().voltage_enabled(), "0x6007 = {option}");
    }
}

/// A drive in Op with CSP (0x6060 = 8) selected, not enabled yet.
fn csp_in_op() -> Drive {
    let mut d = powered_up(EsmState::PreOp);
    d.on_state_change(EsmState::PreOp, EsmState::SafeOp);
    d.on_state_change(EsmState::SafeOp, EsmState::Op);
    sdo_write(&mut d, 0x6060, 0, &[8]).unwrap();
    d
}

#[test]
fn a_csp_target_jump_is_followed_no_faster_than_0x6080() {
    let mut d = csp_in_op();
    // 10 rev/s at 50 000 inc/rev.
    sdo_write(&mut d, 0x6080, 0, &500_000u32.to_le_bytes()).unwrap();
    enable(&mut d);
    assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
    let start = d.command().position;
    // A jump of 100 revolutions in one set-point.
    let target = start.wrapping_add(5_000_000);
    sdo_write(&mut d, 0x607A, 0, &target.to_le_bytes()).unwrap();
    let mut last = start;
    let mut fastest = 0u32;
    for _ in 0..12_000 {
        let c = d.run_cycle(0.001);
        fastest = fastest.max(c.position.wrapping_sub(last).unsigned_abs());
        last = c.position;
        assert!(
            c.velocity.abs() <= 500_000.0 * 1.001,
            "demand speed {}",
            c.velocity
        );
        // An axis that follows its demand.
        d.set_axis(AxisState {
            bus_mv: 48_000,
            position: c.position,
            ..AxisState::default()
        });
    }
    assert!(
        fastest <= 500,
        "fastest step {fastest} inc per 1 ms (limit 500)"
    );
    assert_eq!(last, target, "reached the target at the limited speed");
    assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
}

/// A drive in CSP with the limits of [`limited`], enabled, its target 100 revolutions
/// ahead; returns it and the target.
fn limited_jump() -> (Drive, i32) {
    let mut d = csp_in_op();
    limited(&mut d);
    enable(&mut d);
    let target = d.command().position.wrapping_add(5_000_000);
    sdo_write(&mut d, 0x607A, 0, &target.to_le_bytes()).unwrap();
    (d, target)
}

#[test]
fn a_csp_jump_is_no_faster_than_0x6080_on_the_drives_clock_when_set_points_jitter() {
    let (mut d, _) = limited_jump();
    // Set-points 1 ms apart on average, on the drive's clock alternately early and
    // late (a master's jitter); the demand after each, with its time.
    const GAPS_US: [u64; 5] = [400, 1600, 700, 1300, 1000];
    let mut seen = [(0u64, 0i32); 1500];
    let mut now = 1_000_000u64;
    for (k, s) in seen.iter_mut().enumerate() {
        now += GAPS_US[k % GAPS_US.len()];
        let c = d.step(now, SetpointArrival::Fresh);
        *s = (now, c.position);
        d.set_axis(AxisState {
            bus_mv: 48_000,
            position: c.position,
            ..AxisState::default()
        });
    }
    // Every 200 ms of the drive's time after the 50 ms acceleration: no more than
    // 0x6080 allows, give or take the whole increments (½ inc per segment, 1 at the
    // ends); and at least 95 % of it.
    for (k, &(t0, p0)) in seen.iter().enumerate().skip(50) {
        let Some((n, &(t1, p1))) = seen[k..]
            .iter()
            .enumerate()
            .find(|(_, (t, _))| t - t0 >= 200_000)
        else {
            break;
        };
        let most = 500_000.0 * (t1 - t0) as f32 * 1e-6;
        let moved = p1.wrapping_sub(p0) as f32;
        assert!(
            moved <= most + 0.5 * n as f32 + 1.0,
            "{moved} inc in {} µs from {k}: faster than 0x6080",
            t1 - t0
        );
        assert!(
            moved >= 0.95 * most,
            "{moved} inc in {} µs from {k}",
            t1 - t0
        );
    }
    assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
}

#[test]
fn the_0x6065_following_error_goes_through_the_fault_module() {
    let mut d = csp_in_op();
    sdo_write(&mut d, 0x6065, 0, &500u32.to_le_bytes()).unwrap();
    sdo_write(&mut d, 0x6066, 0, &5u16.to_le_bytes()).unwrap();
    enable(&mut d);
    while d.pop_emergency().is_some() {}
    // The target runs away from an axis that stands still.
    let target = d.command().position.wrapping_add(50_000);
    sdo_write(&mut d, 0x607A, 0, &target.to_le_bytes()).unwrap();
    let mut t = 100_000u64;
    for _ in 0..50 {
        d.run_cycle(0.001);
        t += 1000;
        d.tick(t, 0);
    }
    assert_eq!(d.cia402.error_code(), 0x8611);
    let e = d
        .pop_emergency()
        .expect("an emergency for the 0x6065 fault");
    assert_eq!(e.code, 0x8611);
    assert!(d.pop_emergency().is_none(), "one emergency");
    assert_eq!(d.faults.led_code(), Some(7));
    assert!(d.faults.alarm());
    assert_eq!(sdo_read_u32(&mut d, 0x2400, 2), 0x8611, "history");
}

#[test]
fn masked_trips_are_still_reported() {
    use crate::board_glue::{BoardGlue, ControlCommand};
    use crate::current_supervisor::Trip;
    // Every maskable detection off.
    let mut d = powered_up(EsmState::PreOp);
    sdo_write(&mut d, 0x2056, 0, &0u16.to_le_bytes()).unwrap();
    // A fast over-voltage trip of the current loop.
    let trip = CurrentReport {
        trip: Trip::OverVoltage,
        trip_seq: 1,
        ..CurrentReport::default()
    };
    d.current_report(&trip);
    assert!(d.faults.is_active(crate::faults::FaultKind::OverVoltage));
    assert_eq!(d.pop_emergency().map(|e| e.code), Some(0x3210));
    // A failed start-up offset check.
    let mut d = powered_up(EsmState::PreOp);
    sdo_write(&mut d, 0x2056, 0, &0u16.to_le_bytes()).unwrap();
    let mut glue = BoardGlue::new(ControlCommand {
        cycle: 0,
        command: *d.command(),
        cycle_s: 1e-3,
        power_allowed: false,
        config: 0,
        motion: crate::motion::MotionConfig::from_params(
            &d.params,
            d.variant,
            &crate::motion::ECN57_20,
            crate::motion::SERVO_TS,
        ),
        align_wiggle: false,
        offsets: None,
        supervisor: crate::current_supervisor::SupervisorConfig::from_params(
            &d.params, 25e-6, 2125,
        ),
        tune_allowed: false,
        trace: false,
        brake_released: false,
    });
    glue.offset_check_failed();
    glue.raise_board_faults(&mut d, 5);
    assert!(d.faults.is_active(crate::faults::FaultKind::PhaseSensing));
    assert_eq!(d.pop_emergency().map(|e| e.code), Some(0x5210));
}

/// An axis that follows its demand exactly (position and speed).
fn follow(d: &mut Drive, c: &DriveCommand) {
    d.set_axis(AxisState {
        bus_mv: 48_000,
        position: c.position,
        velocity: c.velocity as i32,
        ..AxisState::default()
    });
}

/// 0x6080 = 10 rev/s, 0x60C5 = 200 rev/s², 0x60C6 = 400 rev/s² (50 000 inc/rev).
fn limited(d: &mut Drive) {
    sdo_write(d, 0x6080, 0, &500_000u32.to_le_bytes()).unwrap();
    sdo_write(d, 0x60C5, 0, &10_000_000u32.to_le_bytes()).unwrap();
    sdo_write(d, 0x60C6, 0, &20_000_000u32.to_le_bytes()).unwrap();
}

/// Runs `n` 1 ms cycles of a following axis; checks every step against the limits of
/// [`limited`] and returns the last command.
fn run_limited(d: &mut Drive, n: usize) -> DriveCommand {
    let mut last = *d.command();
    for k in 0..n {
        let c = d.run_cycle(0.001);
        let dv = c.velocity - last.velocity;
        assert!(
            c.velocity.abs() <= 500_000.0 * 1.001,
            "speed {} ({k})",
            c.velocity
        );
        // Away from standstill 0x60C5, towards it 0x60C6 (1 ms steps), give or take
        // one whole increment per step (1000 inc/s).
        let speeding_up =
            c.velocity.abs() > last.velocity.abs() && c.velocity * last.velocity >= 0.0;
        let a = if speeding_up { 10_000.0 } else { 20_000.0 };
        assert!(dv.abs() <= a + 1_000.0, "speed step {dv} at {k}");
        let dp = c.position.wrapping_sub(last.position).unsigned_abs();
        assert!(dp <= 500, "position step {dp} at {k}");
        follow(d, &c);
        last = c;
    }
    last
}

#[test]
fn torque_and_current_limits_never_exceed_the_peak_current() {
    let mut d = powered_up(EsmState::PreOp);
    // 0x6072 / 0x6073 accept up to 3000 ‰; the peak current 0x2000 is 1000 ‰.
    sdo_write(&mut d, 0x6072, 0, &3000u16.to_le_bytes()).unwrap();
    sdo_write(&mut d, 0x6073, 0, &2500u16.to_le_bytes()).unwrap();
    enable(&mut d);
    let c = d.run_cycle(0.001);
    assert_eq!((c.torque_limit, c.current_limit), (1000, 1000));
    // Below the peak current they apply as written.
    sdo_write(&mut d, 0x6072, 0, &400u16.to_le_bytes()).unwrap();
    sdo_write(&mut d, 0x6073, 0, &700u16.to_le_bytes()).unwrap();
    let c = d.run_cycle(0.001);
    assert_eq!((c.torque_limit, c.current_limit), (400, 700));
}

#[test]
fn a_csv_setpoint_jump_is_limited_by_0x6080_and_the_acceleration_limits() {
    let mut d = csp_in_op();
    sdo_write(&mut d, 0x6060, 0, &[9]).unwrap();
    limited(&mut d);
    enable(&mut d);
    assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
    // 100 rev/s asked at once: 10 rev/s reached at 200 rev/s² (50 ms).
    sdo_write(&mut d, 0x60FF, 0, &5_000_000i32.to_le_bytes()).unwrap();
    let c = run_limited(&mut d, 30);
    assert!(
        c.velocity > 250_000.0 && c.velocity < 350_000.0,
        "{}",
        c.velocity
    );
    assert_ne!(d.cia402.statusword() & 1 << 11, 0, "internal limit");
    let c = run_limited(&mut d, 40);
    assert!((c.velocity - 500_000.0).abs() < 1.0, "{}", c.velocity);
    // Stop asked at once: down at 400 rev/s² (25 ms).
    sdo_write(&mut d, 0x60FF, 0, &0i32.to_le_bytes()).unwrap();
    let c = run_limited(&mut d, 20);
    assert!(c.velocity > 50_000.0, "{}", c.velocity);
    let c = run_limited(&mut d, 10);
    assert_eq!(c.velocity, 0.0);
    assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
}

#[test]
fn a_csp_target_jump_respects_the_acceleration_limits_and_lands_on_it() {
    // A jump of 100 revolutions, then of 1 revolution back.
    let (mut d, target) = limited_jump();
    let start = target.wrapping_sub(5_000_000);
    let mut max_pos = start;
    for _ in 0..11_000 {
        let c = run_limited(&mut d, 1);
        max_pos = max_pos.max(c.position);
    }
    assert_eq!(d.command().position, target, "reached");
    // At most one deceleration step past it: 0x60C6 × (1 ms)² = 20 inc.
    assert!(max_pos.wrapping_sub(target) <= 20, "overshoot to {max_pos}");
    let back = target.wrapping_sub(50_000);
    sdo_write(&mut d, 0x607A, 0, &back.to_le_bytes()).unwrap();
    let c = run_limited(&mut d, 500);
    assert_eq!((c.position, c.velocity), (back, 0.0));
    // Set-points inside the limits are followed exactly: 5 rev/s reached in 50 ms.
    let mut p = back;
    for k in 0..200i32 {
        let v = 250_000.0f32.min(5_000.0 * k as f32);
        p = p.wrapping_add((v * 0.001) as i32);
        sdo_write(&mut d, 0x607A, 0, &p.to_le_bytes()).unwrap();
        let c = run_limited(&mut d, 1);
        assert_eq!(c.position, p, "followed at {k}");
    }
    assert_eq!(d.cia402.statusword() & 1 << 11, 0, "no internal limit");
}

#[test]
fn the_fault_ramp_starts_from_the_limited_motion_not_the_jumped_target() {
    let mut d = csp_in_op();
    limited(&mut d);
    // Fault reaction: quick-stop ramp, 0x6085 = 40 rev/s².
    sdo_write(&mut d, 0x6085, 0, &2_000_000u32.to_le_bytes()).unwrap();
    enable(&mut d);
    let start = d.command().position;
    let target = start.wrapping_add(5_000_000);
    sdo_write(&mut d, 0x607A, 0, &target.to_le_bytes()).unwrap();
    let c = run_limited(&mut d, 1_000);
    let v = c.velocity;
    assert!((v - 500_000.0).abs() < 1.0, "at the speed limit: {v}");
    // The master is lost: fault, 0x605E = 2.
    d.on_outputs_lost(ecat_slave_stack::al_status::AlStatusCode::SmWatchdog);
    let at = c.position;
    let c = run_limited(&mut d, 1_000);
    assert_eq!(d.cia402.state(), PdsState::Fault);
    // Stopped within v² / 2a of where the axis was (not at the jumped target).
    let travel = c.position.wrapping_sub(at);
    let bound = (v * v / (2.0 * 2_000_000.0)) as i32 + 1_000;
    assert!(travel > 0 && travel <= bound, "{travel} > {bound}");
}

#[test]
fn the_servo_tune_refuses_a_limit_switch_and_ends_at_one() {
    let mut d = powered_up(EsmState::PreOp);
    assert_eq!(d.params.get(Param::LoopMode), 2, "closed loop");
    sdo_write(&mut d, 0x6060, 0, &[1]).unwrap();
    enable(&mut d);
    assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
    let mut t = 100_000u64;
    let mut ticks = |d: &mut Drive, raw: u8, n: u32| {
        for _ in 0..n {
            t += 1000;
            d.tick(t, raw);
        }
    };
    // IN3 (positive limit switch, 0x60FD bit 1) active: the start is refused.
    ticks(&mut d, 0b100, 5);
    assert_ne!(d.inputs.digital_inputs_60fd() & 0b10, 0);
    assert_eq!(
        sdo_write(&mut d, 0x2162, 1, &[1]),
        Err(SdoAbort::StateConflict)
    );
    assert_eq!(sdo_read_u32(&mut d, 0x2162, 2), 3, "refused");
    // Released: the tune starts; the switch again ends the move (failed).
    ticks(&mut d, 0, 5);
    assert_eq!(sdo_write(&mut d, 0x2162, 1, &[1]), Ok(()));
    ticks(&mut d, 0, 2);
    assert!(d.cia402.servo_tune(), "the move has the set-points");
    ticks(&mut d, 0b100, 5);
    assert!(!d.cia402.servo_tune(), "the limit switch ended the move");
    assert_eq!(sdo_read_u32(&mut d, 0x2162, 2), 4, "failed");
    assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
}

#[test]
fn the_servo_tune_move_is_limited_to_0x6080() {
    let mut d = powered_up(EsmState::PreOp);
    sdo_write(&mut d, 0x6060, 0, &[1]).unwrap();
    // 2 rev/s (50 000 inc/rev), below the move's own 10 rev/s.
    sdo_write(&mut d, 0x6080, 0, &100_000u32.to_le_bytes()).unwrap();
    enable(&mut d);
    assert_eq!(sdo_write(&mut d, 0x2162, 1, &[1]), Ok(()));
    let c = d.run_cycle(0.001);
    assert_eq!(c.kind, crate::cia402::SetpointKind::Tune);
    // The move's speed limit to the motion layer, command units/s.
    assert_eq!(c.velocity, 100_000.0);
}
