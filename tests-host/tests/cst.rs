//! Cyclic synchronous torque (CST) on the plant (`tests_host::plant::torque`): the
//! goals of the figures in BENCHMARKS.md, and the speed limit 0x6080 holding the
//! free shaft.

use firmware::cia402::SetpointKind;
use tests_host::plant::torque::*;
use tests_host::sim_drive::Motor;

#[test]
fn cst_torque_step_rises_within_a_millisecond_without_overshoot() {
    for m in [Motor::Ecn57_20, Motor::Tc86_45] {
        let s = torque_step(m, 2);
        println!(
            "{m:?}: {s:.3?}",
            s = (s.rise_us, s.overshoot_pct, s.target_nm)
        );
        assert!(s.rise_us <= RISE_GOAL_US, "{m:?}: rise {} µs", s.rise_us);
        assert!(
            s.overshoot_pct <= OVERSHOOT_GOAL_PCT,
            "{m:?}: {} %",
            s.overshoot_pct
        );
        // The step really happened: the end of the trace is at the target.
        let last = s.trace.last().map_or(0.0, |p| p.1);
        assert!(
            (last - s.target_nm).abs() < 0.03 * s.target_nm,
            "{m:?}: {last}"
        );
        // Before the demand reached the current loop nothing moved.
        assert!(
            s.trace[0].1.abs() < 0.05 * s.target_nm,
            "{m:?}: {:?}",
            s.trace[0]
        );
    }
}

#[test]
fn cst_torque_ripple_at_constant_speed() {
    for m in [Motor::Ecn57_20, Motor::Tc86_45] {
        let r = torque_ripple(m, RIPPLE_REV_S);
        println!("{m:?}: {r:?}");
        assert!(r.pp_pct <= RIPPLE_GOAL_PCT, "{m:?}: {r:?}");
        // The demanded torque is produced at speed.
        assert!(
            (r.mean_nm - r.target_nm).abs() < 0.02 * r.target_nm,
            "{m:?}: {r:?}"
        );
    }
}

#[test]
fn cst_speed_limit_holds_the_free_shaft() {
    // 50 % rated torque on the free rotor, 0x6080 = 2 rev/s (100 000 inc/s).
    let mut a = CstAxis::enabled(Motor::Ecn57_20, 3);
    a.cia.params.max_motor_speed = 100_000;
    a.cia.params.target_torque = TORQUE_PM;
    let mut fastest = 0.0f64;
    for _ in 0..200 {
        a.cycle(|ax| fastest = fastest.max(ax.rig.plant.omega));
    }
    // The mean speed over 100 ms (the detent torque modulates the instantaneous one
    // by about ±0.07 rev/s at 400 Hz).
    let p0 = a.axis.true_position();
    for _ in 0..100 {
        a.cycle(|_| {});
    }
    let rev_s = (a.axis.true_position() - p0) / 50_000.0 / 0.1;
    assert!((rev_s - 2.0).abs() < 0.01, "{rev_s} rev/s");
    // Past the limit the velocity loop's proportional gain takes the torque off: the
    // whole demand (1.6 A) needs i/Kv = 1.6 A / 4.0e-4 A per count/s = 4000 counts/s
    // = 1 rev/s of overshoot (0x2140 = 60: Kv of 240 Hz on the ECN57-20).
    let peak = fastest / (2.0 * std::f64::consts::PI);
    assert!(peak < 3.2, "overshoot to {peak} rev/s");
    // Statusword bit 11 (internal limit) while the limit takes torque off.
    assert!(
        a.cia.statusword() & 0x0800 != 0,
        "{:#06x}",
        a.cia.statusword()
    );
    // The torque left is what friction takes (0.015 N·m + B·ω), far below the demand.
    assert!(a.torque_nm().abs() < 0.1, "{}", a.torque_nm());
    // A quick stop from the limited speed: position control on the 0x6085 ramp.
    a.cia.params.quick_stop_deceleration = 1_000_000;
    a.cia.set_controlword(0x000B);
    let mut kinds = Vec::new();
    for _ in 0..150 {
        a.cycle(|_| {});
        kinds.push(a.cia.state());
    }
    let rev_s = a.axis.rig.plant.omega / (2.0 * std::f64::consts::PI);
    assert!(
        rev_s.abs() < 0.05,
        "stopped: {rev_s} rev/s, {:?}",
        kinds.last()
    );
    let _ = SetpointKind::Torque;
}
