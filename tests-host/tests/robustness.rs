//! Current-loop robustness (issues 22 and 37) on the plant with a real motor's and
//! board's non-idealities (`tests_host::plant::robustness`): the same figures as the
//! "Robustness" table of BENCHMARKS.md, with the goals asserted, every one with the
//! power-up auto-tune in the loop as on the board. Each test also checks that the
//! condition really disturbs the loop it is compensated in (the "before" figure), so
//! that a plant option that stopped working cannot pass unnoticed.

use tests_host::plant::motor::{ECN57_20, TC86_45};
use tests_host::plant::robustness::*;

const MOTORS: [tests_host::plant::motor::MotorParams; 2] = [ECN57_20, TC86_45];

#[test]
fn step_overshoot_within_5_percent_over_inductance_and_delay() {
    for m in MOTORS {
        for delay in DELAYS {
            for l in L_SCALES {
                let o = step_overshoot(m, &Conditions::delayed(delay, l), Calibration::Tuned);
                assert!(o <= 5.0, "{}: L × {l}, delay {delay}: {o} %", m.name);
            }
        }
        // The baseline design overshoots there: the conditions are real.
        let before = step_overshoot_of(m, &Conditions::delayed(1.0, 0.7), Design::Baseline);
        assert!(before > 10.0, "{}: baseline at L × 0.7: {before} %", m.name);
    }
}

#[test]
fn tuned_inductance_does_not_depend_on_the_delay() {
    // The goal is ±10 %; the slope method gives ±0.5 % on the plant (`foc::autotune`
    // module docs state ±2 %, asserted here), and the delay within 0.1 sample.
    for m in MOTORS {
        for delay in L_DELAYS {
            for l in L_SCALES {
                let (e, d) = tuned_l_error(m, &Conditions::delayed(delay, l));
                assert!(e.abs() <= 2.0, "{}: L × {l}, delay {delay}: {e} %", m.name);
                assert!(
                    (d - delay).abs() <= 0.1,
                    "{}: L × {l}, delay {delay}: measured {d}",
                    m.name
                );
            }
        }
    }
}

#[test]
fn encoder_commutation_ripple() {
    for m in MOTORS {
        for v in [1.0, 5.07] {
            let r = 1e3 * iq_ripple(m, &Conditions::IDEAL, Calibration::Tuned, v);
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
            let r = 1e3 * iq_ripple(m, &Conditions::IDEAL, Calibration::Tuned, v);
            assert!(r <= 10.0, "{} at {v} rev/s: {r} mA", m.name);
        }
    }
}

#[test]
fn encoder_commutation_ripple_over_the_speed_range() {
    // The tuning guide's plot's sweep, 0.013-10.013 rev/s in steps of 0.25: every speed meets
    // the goal (the "worst" rows of BENCHMARKS.md).
    for m in MOTORS {
        let sweep = ripple_sweep(m, &Conditions::IDEAL, Design::Robust(Calibration::Tuned));
        assert_eq!(sweep.len(), 41);
        for (v, r) in sweep {
            assert!(r <= 10.0, "{} at {v} rev/s: {r} mA", m.name);
        }
    }
}

#[test]
fn calibration_removes_gain_offset_and_dead_time_ripple() {
    let sensors = SENSORS;
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
        // Steady error: both channels referred to their mean (≤ 1 %); B scaled to A
        // only leaves A's +3 %, read as −3 % of true current.
        let s = spin(m, &sensors, Design::Robust(Calibration::Tuned), 5.0);
        let b_to_a = b_to_a_error(m);
        assert!(
            s.iq_error_pct().abs() <= 1.0 && b_to_a < -2.0,
            "{}: {} % (B to A only {b_to_a} %)",
            m.name,
            s.iq_error_pct()
        );
        // The base: the loop on the true motor constants without dead time.
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
        // Each channel to the mean: A × 1.03 and B × 0.97 both read ≈ 1.0 × the current.
        assert!(
            (t.gain[0] * 1.03 - 1.0).abs() < 0.01 && (t.gain[1] * 0.97 - 1.0).abs() < 0.01,
            "{}: {t:?}",
            m.name
        );
        assert!(
            (t.offset[0] - 0.02).abs() < 0.004 && (t.offset[1] + 0.02 * 0.97).abs() < 0.004,
            "{t:?}"
        );
        let t = tune(m, &bridge);
        assert!((t.dead_time_v - 0.5).abs() < 0.05, "{}: {t:?}", m.name);
    }
}

#[test]
fn d_current_ripple_at_the_beat_makes_no_torque_ripple() {
    // Near 10 rev/s the commutation angle's count error turns the back-EMF into a
    // d-axis voltage; the measured decoupling keeps the d current it drives out of the
    // q axis (`foc::current_loop`, "Decoupling"): i_q stays quiet, i_d carries it.
    for m in MOTORS {
        let s = spin(
            m,
            &Conditions::IDEAL,
            Design::Robust(Calibration::Tuned),
            10.013,
        );
        assert!(
            s.iq_pp <= 0.010 && s.id_pp <= 0.1,
            "{}: i_d {} A, i_q {} A p-p",
            m.name,
            s.id_pp,
            s.iq_pp
        );
    }
}

#[test]
fn all_conditions_combined() {
    for m in MOTORS {
        let o = step_overshoot(m, &Conditions::ALL, Calibration::Tuned);
        let s = spin(
            m,
            &Conditions::ALL,
            Design::Robust(Calibration::Tuned),
            5.07,
        );
        let (l_err, _) = tuned_l_error(m, &Conditions::ALL);
        assert!(
            combined_met(o, s, l_err),
            "{}: {o} % / {s:?} / L {l_err} %",
            m.name
        );
        let t = 1e3 * torque_ripple(m, &Conditions::ALL, Calibration::Tuned, 5.0);
        assert!(
            t > 0.0 && t < 0.01 * m.t_hold * 1e3,
            "{}: torque ripple {t} mN·m",
            m.name
        );
    }
}
