//! Unit tests of the homing state machine.

use super::*;

#[test]
fn packed_table_is_the_spec_for_every_method_value() {
    let mut n = 0;
    for m in i8::MIN..=i8::MAX {
        let spec = Method::spec(m);
        assert_eq!(Method::describe(m), spec, "method {m}");
        assert_eq!(supported(m), spec.is_some(), "method {m}");
        n += usize::from(spec.is_some());
    }
    // 1-14, 17-30, 33, 34, 35, 37, and -1, -2.
    assert_eq!(n, 34);
    assert_eq!(Method::unpack(0), None);
}

fn run(h: &mut Homing, m: &mut Motion, di: u32, stall: Option<i32>) -> Option<i32> {
    let inp = HomingInputs {
        digital_inputs: di,
        actual: m.position(),
        index: None,
        stall,
    };
    h.cycle(m, &inp, 0.001)
}

#[test]
fn stall_homing_without_its_preconditions_is_an_error_at_once() {
    let inp = HomingInputs {
        digital_inputs: 0,
        actual: 0,
        index: None,
        stall: None,
    };
    for (min, fast) in [(None, 100_000.0), (Some(50_000.0), 40_000.0)] {
        let p = HomingParams {
            method: -1,
            fast,
            slow: 10_000.0,
            acc: 1.0e7,
            offset: 0,
            has_index: false,
            assigned: 0,
            stall_min_speed: min,
        };
        let mut h = Homing::new();
        assert_eq!(h.start(p, &inp), None);
        assert_eq!(h.status(), HomingStatus::Error, "{min:?}, {fast}");
        assert!(!h.seeking_stall());
    }
}

#[test]
fn stall_homing_takes_the_stall_position_as_home() {
    for (method, dir) in [(-1i8, 1i32), (-2, -1)] {
        let p = HomingParams {
            method,
            fast: 100_000.0,
            slow: 10_000.0,
            acc: 1.0e7,
            offset: 500,
            has_index: false,
            assigned: 0,
            stall_min_speed: Some(50_000.0),
        };
        let mut m = Motion::default();
        let mut h = Homing::new();
        let inp = HomingInputs {
            digital_inputs: 0,
            actual: 0,
            index: None,
            stall: None,
        };
        assert_eq!(h.start(p, &inp), None);
        assert!(h.seeking_stall());
        for _ in 0..50 {
            assert_eq!(run(&mut h, &mut m, 0, None), None);
        }
        assert!(
            m.position() * dir > 4000,
            "searching in {dir}: {}",
            m.position()
        );
        let at = m.position() - dir * 300;
        assert_eq!(run(&mut h, &mut m, 0, Some(at)), None);
        assert!(!h.seeking_stall() && m.velocity() == 0.0, "stopped at once");
        let mut shift = None;
        for _ in 0..1000 {
            shift = shift.or(run(&mut h, &mut m, 0, None));
        }
        assert_eq!(shift, Some(500 - at), "home = stall position, reads 0x607C");
        assert_eq!(m.position(), at);
        assert_eq!(h.status(), HomingStatus::Attained);
    }
}

#[test]
fn stall_homing_errors_on_a_limit_switch_ahead() {
    let p = HomingParams {
        method: -2,
        fast: 100_000.0,
        slow: 10_000.0,
        acc: 1.0e7,
        offset: 0,
        has_index: false,
        assigned: DI_NEG_LIMIT,
        stall_min_speed: Some(50_000.0),
    };
    let mut m = Motion::default();
    let mut h = Homing::new();
    let inp = HomingInputs {
        digital_inputs: 0,
        actual: 0,
        index: None,
        stall: None,
    };
    h.start(p, &inp);
    for _ in 0..10 {
        run(&mut h, &mut m, 0, None);
    }
    for _ in 0..1000 {
        run(&mut h, &mut m, DI_NEG_LIMIT, None);
    }
    assert_eq!(h.status(), HomingStatus::Error);
    // A positive method number outside the table stays unsupported.
    assert!(!supported(-3) && !supported(36) && supported(-1));
}
