//! Current-loop robustness (issue 22) on the plant with a real motor's and board's
//! non-idealities (`tests_host::plant::robustness`): the same figures as the
//! "Robustness" table of BENCHMARKS.md, with the goals asserted. Each test also checks
//! that the condition really disturbs the loop it is compensated in (the "before"
//! figure), so that a plant option that stopped working cannot pass unnoticed.

use tests_host::plant::motor::{ECN57_20, TC86_45};
use tests_host::plant::robustness::*;

const MOTORS: [tests_host::plant::motor::MotorParams; 2] = [ECN57_20, TC86_45];

#[test]
fn step_overshoot_within_5_percent_over_inductance_and_delay() {
    for m in MOTORS {
        for (l, delay) in [(0.7, 1.0), (1.3, 1.0), (1.0, 1.5)] {
            let c = Conditions {
                l_scale: l,
                delay,
                ..Conditions::IDEAL
            };
            let o = step_overshoot(m, &c, Calibration::Off);
            assert!(o <= 5.0, "{}: L × {l}, delay {delay}: {o} %", m.name);
        }
        // The baseline design overshoots there: the conditions are real.
        let c = Conditions {
            l_scale: 0.7,
            ..Conditions::IDEAL
        };
        let before = step_overshoot_of(m, &c, Design::Baseline);
        assert!(before > 10.0, "{}: baseline at L × 0.7: {before} %", m.name);
    }
}

#[test]
fn encoder_commutation_ripple() {
    for m in MOTORS {
        for v in [1.0, 5.07] {
            let r = 1e3 * iq_ripple(m, &Conditions::IDEAL, Calibration::Off, v);
            assert!(r <= 10.0, "{} at {v} rev/s: {r} mA", m.name);
            let before = 1e3 * ripple_of(m, &Conditions::IDEAL, Design::Baseline, v);
            assert!(
                before > 20.0,
                "{} baseline at {v} rev/s: {before} mA",
                m.name
            );
        }
        // Near 10 rev/s (1 count per sample) the count pattern beats slowly against
        // the sampling: 520 Hz at 10.13, 52 Hz at 10.013, 20 Hz at 10.005, 2 Hz at
        // 10.0005 rev/s, each a sawtooth of a whole count.
        for v in [10.13, 10.013, 10.005, 10.0005] {
            let r = 1e3 * iq_ripple(m, &Conditions::IDEAL, Calibration::Off, v);
            assert!(r <= 10.0, "{} at {v} rev/s: {r} mA", m.name);
        }
    }
}

#[test]
fn encoder_commutation_ripple_over_the_speed_range() {
    // The README plot's sweep, 0.013-10.013 rev/s in steps of 0.25: every speed meets
    // the goal (the "worst" rows of BENCHMARKS.md).
    for m in MOTORS {
        let sweep = ripple_sweep(m, &Conditions::IDEAL, Design::Robust(Calibration::Off));
        assert_eq!(sweep.len(), 41);
        for (v, r) in sweep {
            assert!(r <= 10.0, "{} at {v} rev/s: {r} mA", m.name);
        }
    }
}

#[test]
fn calibration_removes_gain_offset_and_dead_time_ripple() {
    let sensors = Conditions {
        adc_gain: [1.03, 0.97],
        offset_a: [0.02, -0.02],
        ..Conditions::IDEAL
    };
    let bridge = Conditions {
        dead_time_v: 0.5,
        ..Conditions::IDEAL
    };
    for m in MOTORS {
        let r = 1e3 * iq_ripple(m, &sensors, Calibration::Tuned, 5.0);
        let before = 1e3 * iq_ripple(m, &sensors, Calibration::Off, 5.0);
        assert!(
            r <= 10.0 && before > 50.0,
            "{}: {r} mA (before {before})",
            m.name
        );
        let base = 1e3 * iq_ripple(m, &Conditions::IDEAL, Calibration::Off, 5.0);
        let added = 1e3 * iq_ripple(m, &bridge, Calibration::Tuned, 5.0) - base;
        let before = 1e3 * iq_ripple(m, &bridge, Calibration::Off, 5.0) - base;
        // Uncompensated, the dead time misses the goal (4 mA on the TC86-45 with the
        // decoupling on the measured currents, 7 mA with it on the references).
        assert!(
            added <= 3.0 && before > 3.0,
            "{}: dead time {added} mA (before {before})",
            m.name
        );
        // What the tune measured: channel B's gain relative to A, the offsets, the loss.
        let t = tune(m, &sensors);
        assert!((t.gain_b - 1.03 / 0.97).abs() < 0.01, "{}: {t:?}", m.name);
        assert!(
            (t.offset[0] - 0.02).abs() < 0.004 && (t.offset[1] + 0.02 * 0.97).abs() < 0.004,
            "{t:?}"
        );
        let t = tune(m, &bridge);
        assert!((t.dead_time_v - 0.5).abs() < 0.05, "{}: {t:?}", m.name);
    }
}

#[test]
fn all_conditions_combined() {
    for m in MOTORS {
        let o = step_overshoot(m, &Conditions::ALL, Calibration::Tuned);
        let r = 1e3 * iq_ripple(m, &Conditions::ALL, Calibration::Tuned, 5.07);
        assert!(o <= 5.0 && r <= 10.0, "{}: {o} % / {r} mA", m.name);
        let t = 1e3 * torque_ripple(m, &Conditions::ALL, Calibration::Tuned, 5.0);
        assert!(
            t > 0.0 && t < 0.01 * m.t_hold * 1e3,
            "{}: torque ripple {t} mN·m",
            m.name
        );
    }
}
