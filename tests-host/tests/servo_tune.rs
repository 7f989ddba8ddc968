//! Servo auto-tuning on the plant (`tests_host::plant::servo_tune`): the load inertia
//! identified within ±10 % on 1×, 5× and 20× the rotor inertia, and the servo tuned
//! for it meets the control-quality goals on each load.

use tests_host::plant::motor::{ECN57_20, TC86_45};
use tests_host::plant::servo_tune::{csp_tuned, csp_voltage, identify, move_90_tuned, LOADS};

#[test]
fn inertia_identified_within_10_percent() {
    for m in [ECN57_20, TC86_45] {
        for load in LOADS {
            let id = identify(m, load);
            assert!(id.result.is_some(), "{} {load}×: {id:?}", m.name);
            assert!(id.error_percent.abs() <= 10.0, "{} {load}×: {id:?}", m.name);
            // The actual position stays within 15 % of the travel beyond it.
            assert!(id.overtravel_counts <= 150.0, "{} {load}×: {id:?}", m.name);
        }
    }
}

#[test]
fn tuned_servo_meets_the_goals_on_each_load() {
    for load in LOADS {
        let ratio = identify(ECN57_20, load).ratio_percent;
        let (mv, acc) = move_90_tuned(load, ratio);
        assert!(mv.settle_ms <= 20.0, "{load}× ({acc} rev/s²): {mv:?}");
        assert!(mv.overshoot_counts <= 2.0, "{load}×: {mv:?}");
        let ratio = identify(TC86_45, load).ratio_percent;
        let t = csp_tuned(load, ratio);
        if load <= 5.0 {
            assert!(csp_voltage(load).0 < 48.0);
            assert!(t.fe_accel <= 20.0, "{load}×: accel FE {}", t.fe_accel);
            assert!(
                t.fe_const <= 5.0,
                "{load}×: constant-speed FE {}",
                t.fe_const
            );
        } else {
            // 20×: the 200 rev/s² ramps at 600 rpm need more voltage than the 48 V
            // bus gives; the goals are not met (BENCHMARKS.md), the tracking stays
            // bounded.
            assert!(csp_voltage(load).0 > 48.0);
            assert!(t.fe_accel <= 200.0, "{load}×: accel FE {}", t.fe_accel);
            assert!(
                t.fe_const <= 200.0,
                "{load}×: constant-speed FE {}",
                t.fe_const
            );
        }
    }
}

/// The servo tune as the drive runs it (`tests_host::plant::drive_tune`).
mod on_the_drive {
    use ecat_slave_stack::od::{Dictionary, ObjectKey, SdoAbort};
    use firmware::cia402::pds::PdsState;
    use firmware::params::P;
    use firmware::servo_tune::StiffnessGains;
    use tests_host::plant::drive_tune::{tune_on_drive, DriveBench as Bench};
    use tests_host::sim_drive::Motor;

    /// Every load on both motors through the drive: done, 0x2164 within ±10 % of the
    /// true load, the axis back where it started and standing still.
    #[test]
    fn tune_on_the_drive_within_10_percent_on_every_load() {
        for motor in [Motor::Ecn57_20, Motor::Tc86_45] {
            for load in super::LOADS {
                let t = tune_on_drive(motor, load);
                eprintln!("{motor:?} {load}×: {t:?}");
                assert_eq!(t.state, 2, "{motor:?} {load}×: {t:?}");
                assert!(t.error_percent.abs() <= 10.0, "{motor:?} {load}×: {t:?}");
                assert!(t.standstill_after <= 2.0, "{motor:?} {load}×: {t:?}");
                assert!(t.end_counts.abs() <= 20.0, "{motor:?} {load}×: {t:?}");
            }
        }
    }

    /// 0x2162:01 = 1 in PP at rest runs the move; 0x2162:02 reads running, then done;
    /// 0x2164 is the identified ratio within ±10 % of the true 500 %, 0x2160 and the
    /// gains of the stiffness are set, the axis never leaves the travel by more than
    /// its following error and ends at the start, still enabled, without a fault.
    /// Before, with the gains for the rotor alone, the loaded axis hunts about its
    /// position; after, it stands.
    #[test]
    fn tune_on_the_drive_identifies_the_load_and_sets_the_gains() {
        let mut b = Bench::new(Motor::Ecn57_20, 5.0, &[]);
        b.enable();
        let start = b.counts();
        b.write(0x2162, 1, &[1]).unwrap();
        assert_eq!(b.read_u16(0x2162, 2), 1, "running");
        assert_eq!(b.read_u16(0x2162, 1), 1);
        let (ms, (lo, hi)) = b.until_tune_over(start);
        let ratio = b.read_u16(0x2164, 0);
        eprintln!(
            "tune {ms} ms, ratio {ratio} %, friction {} mN·m, travel {lo:.0}..{hi:.0} counts",
            b.read_u16(0x2165, 0)
        );
        assert_eq!(b.read_u16(0x2162, 2), 2, "done");
        assert_eq!(b.read_u16(0x2162, 1), 0);
        assert!((f64::from(ratio) / 500.0 - 1.0).abs() <= 0.10, "{ratio} %");
        assert_eq!(b.d.params.get(P::LoadInertiaRatio), i32::from(ratio));
        let g = StiffnessGains::for_level(12);
        assert_eq!(b.d.params.get(P::SpeedKp), i32::from(g.speed_kp));
        assert_eq!(b.d.params.get(P::PosKp), i32::from(g.pos_kp));
        // The default travel: 90° = 1000 counts; 20 % margin for the following error.
        assert!(lo >= -200.0 && (900.0..=1200.0).contains(&hi), "{lo}..{hi}");
        let (lo, hi) = b.range(200, start);
        // Back at the start (where the axis hunted about it before: ±20 counts), and
        // standing still with the tuned gains (it hunted by ±10 counts before).
        eprintln!("after the tune: {lo:.1}..{hi:.1} counts from the start");
        assert!(lo.abs() <= 20.0 && hi.abs() <= 20.0);
        assert!(hi - lo <= 2.0, "{lo}..{hi}");
        assert_eq!(b.d.cia402.state(), PdsState::OperationEnabled);
        assert_eq!(b.d.faults.error_code(), 0);
    }

    /// A quick stop in the middle of the move ends the tune (failed) and stops the axis
    /// on its ramp where it is: no return jump, inside the travel, no fault; the
    /// parameters keep their values.
    #[test]
    fn quick_stop_during_the_tune_fails_it_and_stops_in_place() {
        let mut b = Bench::new(Motor::Ecn57_20, 5.0, &[]);
        b.enable();
        let start = b.counts();
        b.write(0x2162, 1, &[1]).unwrap();
        // At the peak speed of the first stroke (probe: 50 rev/s², 90°).
        b.run(0x0F, 72, |_| {});
        assert_eq!(b.read_u16(0x2162, 2), 1);
        let speed = b.d.cia402.velocity_actual();
        let at_stop = b.counts() - start;
        let (mut lo, mut hi) = (at_stop, at_stop);
        b.run(0x0B, 300, |b| {
            let x = b.counts() - start;
            lo = lo.min(x);
            hi = hi.max(x);
        });
        eprintln!("quick stop at {at_stop:.0} counts, {speed} units/s, then {lo:.0}..{hi:.0}");
        assert_eq!(b.read_u16(0x2162, 2), 4, "failed");
        assert_eq!(b.d.params.get(P::LoadInertiaRatio), 0);
        assert_eq!(b.read_u16(0x2164, 0), 0);
        assert!(lo >= -200.0 && hi <= 1200.0, "{lo}..{hi}");
        // On the quick-stop ramp 0x6085 from that speed: v²/2a (units → counts).
        let mut buf = [0u8; 4];
        Dictionary::read(&mut b.d, ObjectKey::new(0x6085, 0), &mut buf).unwrap();
        let (v, a) = (f64::from(speed), f64::from(u32::from_le_bytes(buf)));
        let ramp = v * v / (2.0 * a) * 4000.0 / 50_000.0;
        assert!(
            lo >= at_stop - 20.0 && hi <= at_stop + 1.2 * ramp + 20.0,
            "ramp {ramp:.0}"
        );
        assert_eq!(b.d.faults.error_code(), 0);
        // Stopped: the rotor stands.
        let x = b.counts();
        b.run(0x0B, 50, |_| {});
        assert!((b.counts() - x).abs() <= 2.0);
    }

    /// The start is refused with the standard aborts: not Operation enabled or open
    /// loop (0x08000022), travel beyond the software limits (0x06090030), a value
    /// out of range (0x06090031), the read-only results (0x06010002). 0x2162:02
    /// reads 3 (refused) after a refusal.
    #[test]
    fn start_refusals_get_the_standard_aborts() {
        let mut b = Bench::new(Motor::Ecn57_20, 0.0, &[]);
        assert_eq!(b.write(0x2162, 1, &[1]), Err(SdoAbort::StateConflict));
        assert_eq!(b.read_u16(0x2162, 2), 3);
        assert_eq!(b.write(0x2162, 1, &[2]), Err(SdoAbort::ValueTooHigh));
        assert_eq!(b.write(0x2162, 2, &[1]), Err(SdoAbort::WriteReadOnly));
        assert_eq!(b.write(0x2164, 0, &[1, 0]), Err(SdoAbort::WriteReadOnly));
        assert_eq!(b.write(0x2165, 0, &[1, 0]), Err(SdoAbort::WriteReadOnly));
        assert_eq!(
            b.write(0x2163, 0, &99u16.to_le_bytes()),
            Err(SdoAbort::ValueTooLow)
        );
        assert_eq!(
            b.write(0x2163, 0, &36_001u16.to_le_bytes()),
            Err(SdoAbort::ValueTooHigh)
        );
        // Software limits ±5000 units (0.1 rev) against 90° (12 500 units).
        b.write(0x607D, 1, &(-5000i32).to_le_bytes()).unwrap();
        b.write(0x607D, 2, &5000i32.to_le_bytes()).unwrap();
        b.enable();
        assert_eq!(b.write(0x2162, 1, &[1]), Err(SdoAbort::ValueRangeExceeded));
        assert_eq!(b.read_u16(0x2162, 2), 3);
        // 18° fits.
        b.write(0x2163, 0, &180u16.to_le_bytes()).unwrap();
        assert_eq!(b.write(0x2162, 1, &[1]), Ok(()));
        assert_eq!(
            b.write(0x2162, 1, &[1]),
            Err(SdoAbort::StateConflict),
            "running"
        );
        b.write(0x2162, 1, &[0]).unwrap();
        assert_eq!(b.read_u16(0x2162, 2), 4, "stopped");
        // Open loop: refused.
        let mut open = Bench::new(Motor::Ecn57_20, 0.0, &[(0x2024, 0, &[1])]);
        open.enable();
        assert_eq!(open.write(0x2162, 1, &[1]), Err(SdoAbort::StateConflict));
    }
}
