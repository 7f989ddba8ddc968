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

#[test]
#[ignore]
fn debug_ratio_trace() {
    use tests_host::plant::rig::{Trapezoid, TS_SERVO};
    use tests_host::plant::stall::{StallRig, PPR};
    let mut r = StallRig::new(ECN57_20, 7, 0.0123);
    let ppr = f64::from(PPR);
    let (v, a) = (10.0 * ppr, 100.0 * ppr);
    let prof = Trapezoid::new(0.0, v * v / a + v * 0.1, v, a);
    for _ in 0..100 {
        r.period(0);
    }
    let n = (prof.duration() / TS_SERVO as f64).ceil() as usize + 300;
    for k in 0..n {
        let t = (k + 1) as f64 * TS_SERVO as f64;
        let (p, vel, _) = prof.at(t);
        let s = r.period(p.round() as i32);
        if k % 20 == 0 {
            let e = r.det.back_emf();
            eprintln!(
                "t {:.4} v {:.2} ratio {:.3} ed {:.2} eq {:.2} vd {:.2} vq {:.2} id {:.2} iq {:.2} sat {} {:?}",
                t, vel / ppr, r.det.ratio(), e.d, e.q, r.rig.cl.v_dq.d, r.rig.cl.v_dq.q,
                r.rig.cl.i_dq.d, r.rig.cl.i_dq.q, r.rig.cl.saturated, s
            );
        }
    }
}

#[test]
#[ignore]
fn debug_homing_trace() {
    use tests_host::plant::motor::HardStop;
    use tests_host::plant::rig::{Trapezoid, TS_SERVO};
    use tests_host::plant::stall::{StallRig, PPR};
    let mut r = StallRig::new(ECN57_20, 1, 0.3);
    let ppr = f64::from(PPR);
    let stop_p = 0.22 * ppr;
    r.rig.plant.hard_stop = Some(HardStop::steel(r.shaft_at(stop_p), 1.0, ECN57_20.j));
    for _ in 0..100 {
        r.period(0);
    }
    let prof = Trapezoid::new(0.0, 10.0 * ppr, 2.0 * ppr, 100.0 * ppr);
    for k in 0..4000 {
        let (p, _, _) = prof.at((k + 1) as f64 * TS_SERVO as f64);
        let s = r.period(p.round() as i32);
        let rot = r.rotor_pulses();
        if rot > stop_p - 60.0 {
            eprintln!(
                "k {k} cmd {} rotor {:.1} stop {stop_p} ratio {:.3} onset {} {:?}",
                r.cmd,
                rot,
                r.det.ratio(),
                r.onset,
                s
            );
        }
        if s == foc::stall::StallState::Stalled {
            break;
        }
    }
}
