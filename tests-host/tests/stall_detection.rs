//! Open-loop stall detection and stall homing on the plant (`tests_host::plant::stall`):
//! the goals of the report's "Stall detection (open loop)" table.

use tests_host::plant::motor::ECN57_20;
use tests_host::plant::stall::{detection_time, false_trip_runs, stall_homing, HOMING_GOAL_DEG};

#[test]
fn detects_a_hard_stop_within_two_electrical_periods() {
    for rev_s in [2.0, 5.0, 10.0] {
        let d = detection_time(ECN57_20, rev_s);
        eprintln!(
            "{rev_s} rev/s: {:.2} ms (goal {:.1} ms)",
            d.time_ms, d.goal_ms
        );
        assert!(d.time_ms <= d.goal_ms, "{d:?}");
    }
}

#[test]
fn no_false_trip_over_the_acceleration_range() {
    for r in false_trip_runs() {
        eprintln!("{r:?}");
        assert!(r.max_lag_deg < 180.0, "the rotor slipped: {r:?}");
        assert!(!r.tripped, "false trip: {r:?}");
    }
}

#[test]
fn stall_homing_within_one_full_step() {
    for seed in 1..=20 {
        let h = stall_homing(ECN57_20, seed);
        eprintln!("{seed}: {h:?}");
        assert!(h.found, "seed {seed}");
        assert!(h.error_deg.abs() <= HOMING_GOAL_DEG, "seed {seed}: {h:?}");
    }
}

use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::od::{Dictionary, ObjectKey};
use firmware::drive::Drive;
use firmware::identity::Variant;
use tests_host::plant::motor::HardStop;
use tests_host::sim_axis::PlantAxis;
use tests_host::sim_drive::{Axis, Motor};

/// The drive (`firmware::drive`) on the plant axis with the firmware's motion layer
/// (`tests_host::sim_axis::PlantAxis`): open loop, stall detection on, the objects
/// `extra`, a steel stop one revolution ahead of the rotor.
fn drive_on_plant(extra: &[(u16, u8, &[u8])]) -> (Drive, PlantAxis, f64) {
    let mut d: Drive = Drive::new(Variant::HybridServo, 0);
    let base: [(u16, u8, &[u8]); 3] = [(0x2013, 0, &[0]), (0x2024, 0, &[1]), (0x2060, 0, &[1])];
    for &(i, s, v) in base.iter().chain(extra) {
        Dictionary::write(&mut d, ObjectKey::new(i, s), v, EsmState::PreOp)
            .unwrap_or_else(|e| panic!("{i:x}: {e:?}"));
    }
    let mut ax = PlantAxis::new(Motor::Ecn57_20);
    let stop = ax.rig.plant.theta + 2.0 * std::f64::consts::PI;
    ax.rig.plant.hard_stop = Some(HardStop::steel(stop, 1.0, ECN57_20.j));
    ax.parameters(&d.params);
    (d, ax, stop)
}

/// Runs 1 ms cycles with each controlword for its number of cycles.
fn run(d: &mut Drive, ax: &mut PlantAxis, steps: &[(u16, u32)]) {
    for &(cw, n) in steps {
        d.cia402.set_controlword(cw);
        for _ in 0..n {
            d.set_axis(ax.state());
            let c = d.run_cycle(0.001);
            ax.command(&c, 0.001);
            ax.advance(0.001, &c);
        }
    }
}

/// End to end, CiA 402 homing method −1: the stall is the homing reference (no
/// fault); the home position is the stop to within one full step.
#[test]
fn drive_stall_homing_on_the_plant() {
    use firmware::cia402::homing::HomingStatus;
    let (mut d, mut ax, stop) = drive_on_plant(&[
        (0x6098, 0, &[-1i8 as u8]),
        (0x6099, 1, &100_000u32.to_le_bytes()),   // 2 rev/s
        (0x609A, 0, &5_000_000u32.to_le_bytes()), // 100 rev/s²
        (0x6060, 0, &[6]),
    ]);
    run(
        &mut d,
        &mut ax,
        &[(0x06, 5), (0x07, 5), (0x0F, 50), (0x1F, 3000)],
    );
    assert_eq!(
        d.faults.error_code(),
        0,
        "the stall is the reference, not a fault"
    );
    assert_eq!(d.cia402.homing_status(), HomingStatus::Attained);
    // Home (position 0) against the stop face, in full steps (250 units).
    let units_per_rad = 50_000.0 / (2.0 * std::f64::consts::PI);
    let rotor = (ax.rig.plant.theta - stop) * units_per_rad / 250.0;
    let reported = f64::from(d.cia402.position_actual()) / 250.0;
    eprintln!("rotor − stop {rotor:+.2} full steps, position actual {reported:+.2}");
    assert!(rotor.abs() <= 1.0 && reported.abs() <= 1.0);
}

/// End to end, a PP move through the stop with the default reaction (0x2062 = 0):
/// fault 0x7121 with its one emergency, the PDS in Fault, the rotor at the stop.
#[test]
fn drive_stall_fault_on_the_plant() {
    let (mut d, mut ax, stop) = drive_on_plant(&[
        (0x607A, 0, &100_000i32.to_le_bytes()), // 2 rev, the stop at 1
        (0x6081, 0, &150_000u32.to_le_bytes()), // 3 rev/s
        (0x6083, 0, &5_000_000u32.to_le_bytes()),
        (0x6084, 0, &5_000_000u32.to_le_bytes()),
        (0x6060, 0, &[1]),
    ]);
    run(
        &mut d,
        &mut ax,
        &[(0x06, 5), (0x07, 5), (0x0F, 20), (0x1F, 1000)],
    );
    let mut codes = Vec::new();
    while let Some(e) = d.pop_emergency() {
        codes.push(e.code);
    }
    assert_eq!(codes, [0x7121], "one emergency");
    assert_eq!(d.faults.error_code(), 0x7121);
    assert_eq!(d.cia402.state(), firmware::cia402::pds::PdsState::Fault);
    assert!((ax.rig.plant.theta - stop).abs() < 0.05, "at the stop");
}
