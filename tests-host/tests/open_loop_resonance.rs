//! The open-loop resonance and its damping (`foc::damping`, 0x2059) on the plant:
//! the speeds of the sweep where the undamped drive rings or loses steps.
//! BENCHMARKS.md, "Open-loop resonance", has the whole sweep.

use tests_host::plant::motor::{ECN57_20, TC86_45};
use tests_host::plant::resonance::run_at;

#[test]
fn damping_calms_the_low_speed_resonance() {
    // The rotor spring (k = p·Kt·I) on the rotor's inertia rings near 1 rev/s, where
    // the detent torque's 4th electrical harmonic meets it.
    for (m, speed) in [(ECN57_20, 1.0), (TC86_45, 0.875)] {
        let off = run_at(m, speed, false);
        let on = run_at(m, speed, true);
        assert!(
            !off.lost_steps() && !on.lost_steps(),
            "{}: {off:?} {on:?}",
            m.name
        );
        assert!(off.ripple_rel() > 1.0, "{}: undamped {off:?}", m.name);
        assert!(
            on.ripple_rel() <= 0.5 * off.ripple_rel(),
            "{}: damped {on:?} undamped {off:?}",
            m.name
        );
    }
}

#[test]
fn damping_keeps_the_nema34_in_step_in_the_mid_band() {
    // TC86-45 at 48 V: undamped, the rotor oscillates from about 9 rev/s and falls
    // out of step from about 13 rev/s; damped, it runs smoothly to 20 rev/s.
    let off = run_at(TC86_45, 14.0, false);
    assert!(off.lost_steps(), "undamped {off:?}");
    for speed in [10.0, 14.0, 20.0] {
        let on = run_at(TC86_45, speed, true);
        assert!(!on.lost_steps(), "{speed} rev/s: {on:?}");
        assert!(on.ripple_rel() <= 0.02, "{speed} rev/s: {on:?}");
    }
}

#[test]
fn damping_changes_little_where_nothing_rings() {
    // 5 rev/s on the NEMA 23: no resonance; the damped drive stays within 10 %.
    let on = run_at(ECN57_20, 5.0, true);
    assert!(!on.lost_steps() && on.ripple_rel() <= 0.10, "{on:?}");
}
