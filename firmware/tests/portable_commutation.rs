#![cfg_attr(target_os = "none", no_std, no_main)]
//! The board-side library logic: the power-up commutation alignment around the motion
//! layer (`firmware::commutation`) against an ideal rotor that snaps onto the current
//! vector, and the touch-probe latches (`firmware::latch`) up to the drive's
//! 0x60B9/0x60BA-0x60BD. Runs on the host and under QEMU.
use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::od::{Dictionary, ObjectKey};
use firmware::cia402::{DriveCommand, EdgeLatch, SetpointKind};
use firmware::commutation::{
    align_config, CommutatedMotion, Commutation, Step, ALIGN_RAMP_S, ALIGN_SETTLE_S,
    ALIGN_SWEEP_SPEED, ALIGN_SWEEP_TURNS,
};
use firmware::drive::{AxisState, Drive};
use firmware::identity::Variant;
use firmware::latch::{units_at_count, Edges, ProbeInput, Seen};
use firmware::motion::{Feedback, Frame, MotionConfig, ECN57_20, SERVO_TS};
use firmware::params::Params;
use foc::angle::Angle;

fn cfg(closed: bool) -> MotionConfig {
    let p = Params::new(Variant::HybridServo);
    let mut c = MotionConfig::from_params(&p, Variant::HybridServo, &ECN57_20, SERVO_TS);
    c.closed_loop = closed;
    c
}

fn cmd(enabled: bool) -> DriveCommand {
    DriveCommand {
        power_stage: enabled,
        drive_enabled: enabled,
        kind: SetpointKind::Position,
        position: 0,
        torque_limit: 1000,
        current_limit: 1000,
        ..DriveCommand::default()
    }
}

/// An ideal rotor: its electrical angle jumps onto the commanded vector whenever a
/// current flows on a commanded angle; the encoder reads `rotor − offset` (`stuck`:
/// the encoder never moves).
struct Rotor {
    theta: Angle,
    offset: Angle,
    stuck: bool,
}

impl Rotor {
    fn raw(&self) -> Angle {
        if self.stuck {
            Angle(0x1234_5678)
        } else {
            self.theta.wrapping_sub(self.offset)
        }
    }
    fn apply(&mut self, s: &Step) {
        if let Frame::Command { angle, .. } = s.reference.frame {
            if s.reference.power && s.reference.id > 0.0 {
                self.theta = angle;
            }
        }
    }
}

fn fb() -> Feedback {
    Feedback::default()
}

/// Steps until the alignment is over (or `max` steps); returns the steps taken and
/// the last output.
fn run_alignment(m: &mut CommutatedMotion, r: &mut Rotor, max: u32) -> (u32, Step) {
    let mut n = 0;
    loop {
        let s = m.step(&fb(), r.raw());
        r.apply(&s);
        n += 1;
        if m.state() != Commutation::Aligning || n >= max {
            return (n, s);
        }
    }
}

fn expected_steps(wiggle: bool) -> u32 {
    let base = (ALIGN_RAMP_S + ALIGN_SETTLE_S) / SERVO_TS;
    let sweep = 2.0 * ALIGN_SWEEP_TURNS as f32 / ALIGN_SWEEP_SPEED / SERVO_TS;
    (base + if wiggle { sweep } else { 0.0 }) as u32
}

qemu_runner::tests! {
    fn closed_loop_enable_aligns_first_then_runs_the_servo() {
        for wiggle in [false, true] {
            let mut m = CommutatedMotion::new(cfg(true), wiggle);
            let mut r = Rotor { theta: Angle(0x4000_0000), offset: Angle(0x9ABC_0000), stuck: false };
            // Disabled: nothing happens.
            m.set_command(&cmd(false), 0.001);
            let s = m.step(&fb(), r.raw());
            assert!(!s.reference.power);
            assert_eq!(m.state(), Commutation::Unaligned);
            // Enable: the alignment drives a d current on a commanded angle, the motion
            // layer stays disabled.
            m.set_command(&cmd(true), 0.001);
            let s = m.step(&fb(), r.raw());
            r.apply(&s);
            assert_eq!(m.state(), Commutation::Aligning);
            assert!(s.reference.power && s.reference.reset);
            assert!(matches!(s.reference.frame, Frame::Command { .. }));
            assert!(s.reference.id > 0.0 && s.reference.iq == 0.0);
            assert!(!m.motion().enabled());
            let (n, last) = run_alignment(&mut m, &mut r, 20_000);
            let expect = expected_steps(wiggle);
            assert!(n + 1 >= expect && n <= expect + 10, "wiggle {wiggle}: {n} steps, expected {expect}");
            assert_eq!(m.state(), Commutation::Aligned);
            let off = last.offset.unwrap_or(Angle::ZERO);
            assert!(off.diff(r.offset).unsigned_abs() < 1 << 20, "offset {:#x} vs {:#x}", off.0, r.offset.0);
            // The finishing step still holds the rotor with the alignment current.
            assert!(last.reference.power && last.reference.id >= cfg(true).peak_current * 0.99);
            // Next step: the servo on the encoder frame, integrators cleared.
            let s = m.step(&fb(), r.raw());
            assert!(m.motion().enabled() && m.motion().closed_loop());
            assert_eq!(s.reference.frame, Frame::Encoder);
            assert!(s.reference.power && s.reference.reset);
            assert_eq!(s.offset, None);
            // Disable and enable again: no second alignment.
            m.set_command(&cmd(false), 0.001);
            assert!(!m.step(&fb(), r.raw()).reference.power);
            m.set_command(&cmd(true), 0.001);
            let s = m.step(&fb(), r.raw());
            assert_eq!(s.reference.frame, Frame::Encoder);
            assert_eq!(m.state(), Commutation::Aligned);
            assert_eq!(m.failures(), 0);
        }
    }

    fn encoder_that_does_not_follow_fails_once_and_retries_after_disable() {
        let mut m = CommutatedMotion::new(cfg(true), true);
        let mut r = Rotor { theta: Angle::ZERO, offset: Angle::ZERO, stuck: true };
        m.set_command(&cmd(true), 0.001);
        let (_, last) = run_alignment(&mut m, &mut r, 20_000);
        assert!(last.failed);
        assert!(!last.reference.power);
        assert_eq!(last.offset, None);
        assert_eq!(m.state(), Commutation::Failed);
        assert_eq!(m.failures(), 1);
        // Still enabled: bridges off, no second report, motion layer disabled.
        for _ in 0..100 {
            let s = m.step(&fb(), r.raw());
            assert!(!s.reference.power && !s.failed);
        }
        assert!(!m.motion().enabled());
        // Disabled (the fault did that), enabled again: a new attempt.
        m.set_command(&cmd(false), 0.001);
        m.step(&fb(), r.raw());
        assert_eq!(m.state(), Commutation::Unaligned);
        r.stuck = false;
        m.set_command(&cmd(true), 0.001);
        let (_, last) = run_alignment(&mut m, &mut r, 20_000);
        assert!(last.offset.is_some());
        assert_eq!(m.state(), Commutation::Aligned);
        assert_eq!(m.failures(), 1);
    }

    fn withdrawn_enable_abandons_the_alignment() {
        let mut m = CommutatedMotion::new(cfg(true), false);
        let mut r = Rotor { theta: Angle::ZERO, offset: Angle(0x1000_0000), stuck: false };
        m.set_command(&cmd(true), 0.001);
        for _ in 0..100 {
            let s = m.step(&fb(), r.raw());
            r.apply(&s);
        }
        assert_eq!(m.state(), Commutation::Aligning);
        m.set_command(&cmd(false), 0.001);
        let s = m.step(&fb(), r.raw());
        assert!(!s.reference.power && s.offset.is_none() && !s.failed);
        assert_eq!(m.state(), Commutation::Unaligned);
        // Closed loop deselected during an alignment: the open loop takes over at once.
        m.set_command(&cmd(true), 0.001);
        m.step(&fb(), r.raw());
        assert_eq!(m.state(), Commutation::Aligning);
        m.configure(cfg(false), false);
        let s = m.step(&fb(), r.raw());
        assert_eq!(m.state(), Commutation::Unaligned);
        assert!(s.reference.power && m.motion().enabled() && !m.motion().closed_loop());
    }

    fn open_loop_never_aligns_and_closed_loop_is_masked_until_aligned() {
        let mut m = CommutatedMotion::new(cfg(false), true);
        let r = Rotor { theta: Angle::ZERO, offset: Angle::ZERO, stuck: false };
        m.set_command(&cmd(true), 0.001);
        let s = m.step(&fb(), r.raw());
        assert!(s.reference.power && matches!(s.reference.frame, Frame::Command { .. }));
        assert_eq!(m.state(), Commutation::Unaligned);
        // Switched to closed loop while running open loop: stays open loop (masked).
        m.configure(cfg(true), true);
        m.step(&fb(), r.raw());
        assert!(m.motion().enabled() && !m.motion().closed_loop());
        assert!(m.config().closed_loop);
        assert_eq!(m.state(), Commutation::Unaligned);
        // The next enable aligns first.
        m.set_command(&cmd(false), 0.001);
        m.step(&fb(), r.raw());
        m.set_command(&cmd(true), 0.001);
        m.step(&fb(), r.raw());
        assert_eq!(m.state(), Commutation::Aligning);
        // No encoder: the closed loop cannot be asked for at all.
        let mut c = cfg(true);
        c.counts_per_rev = 0;
        let mut m = CommutatedMotion::new(c, true);
        m.set_command(&cmd(true), 0.001);
        let s = m.step(&fb(), r.raw());
        assert!(s.reference.power);
        assert_ne!(m.state(), Commutation::Aligning);
    }

    fn already_aligned_start_and_garbage_configuration() {
        let mut m = CommutatedMotion::new_aligned(cfg(true), false);
        m.set_command(&cmd(true), 0.001);
        let s = m.step(&fb(), Angle::ZERO);
        assert_eq!(s.reference.frame, Frame::Encoder);
        // Non-finite / zero values: no panic, a finite (zero) alignment current.
        let mut c = cfg(true);
        c.peak_current = f32::NAN;
        c.ts = f32::INFINITY;
        assert_eq!(align_config(&c, true).current, 0.0);
        let mut m = CommutatedMotion::new(c, true);
        m.set_command(&cmd(true), f32::NAN);
        let mut r = Rotor { theta: Angle::ZERO, offset: Angle::ZERO, stuck: false };
        let (n, s) = run_alignment(&mut m, &mut r, 50_000);
        assert!(n < 50_000);
        assert!(s.reference.id.is_finite());
        c.peak_current = -3.0;
        assert_eq!(align_config(&c, false).current, 0.0);
    }

    fn latched_counts_become_axis_positions() {
        let c = cfg(true); // 50 000 units, 4000 counts per revolution
        assert_eq!(units_at_count(&c, 100_000, 0), 100_000);
        assert_eq!(units_at_count(&c, 100_000, 4000), 50_000);
        assert_eq!(units_at_count(&c, 0, -4000), 50_000);
        // 1 count = 12.5 units: rounded.
        assert_eq!(units_at_count(&c, 0, 1), -13);
        let mut r = c;
        r.reverse = true;
        assert_eq!(units_at_count(&r, 0, 4000), 50_000);
        // Wrapping and extremes: no panic.
        // −12.5 units: halves round up.
        assert_eq!(units_at_count(&c, i32::MAX, -1), i32::MIN + 11);
        let _ = units_at_count(&c, 0, i32::MIN);
        let mut big = c;
        big.pulses_per_rev = u32::MAX;
        big.counts_per_rev = 1;
        let _ = units_at_count(&big, i32::MIN, i32::MAX);
        let mut none = c;
        none.counts_per_rev = 0;
        assert_eq!(units_at_count(&none, 77, 12345), 77);
    }

    fn edges_and_polarity_reach_the_touch_probe() {
        let mut e: Edges<i32> = Edges::default();
        let mut seen = Seen::default();
        assert_eq!(e.take_new(&mut seen), (None, None));
        e.record(true, 10);
        e.record(false, 20);
        assert_eq!(e.take_new(&mut seen), (Some(10), Some(20)));
        assert_eq!(e.take_new(&mut seen), (None, None));
        // Normal polarity: to active = rising.
        let mut e: Edges<i32> = Edges::default();
        let mut p = ProbeInput::default();
        e.record(true, 30);
        assert_eq!(p.update(&e, false), EdgeLatch { rising: Some(30), falling: None });
        // Pending until consumed; the first edge of a kind is kept.
        e.record(true, 40);
        e.record(false, 50);
        assert_eq!(p.update(&e, false), EdgeLatch { rising: Some(30), falling: Some(50) });
        assert_eq!(p.update(&e, false), p.pending());
        p.consumed();
        assert_eq!(p.update(&e, false), EdgeLatch::default());
        // Inverted (0x2154 bit set): to active = falling.
        let mut q = ProbeInput::default();
        assert_eq!(q.update(&e, true), EdgeLatch { rising: Some(50), falling: Some(40) });
        let _ = seen;
        // Sequence numbers wrap.
        let mut w: Edges<i32> = Edges { active_seq: u32::MAX, ..Edges::default() };
        let mut s2 = Seen::default();
        w.take_new(&mut s2);
        w.record(true, 1);
        assert_eq!(w.active_seq, 0);
        assert_eq!(w.take_new(&mut s2), (Some(1), None));
    }

    fn drive_feeds_probe_edges_into_60b9_and_60ba() {
        let mut d = Drive::new(Variant::HybridServo, 1);
        // 0x60B8: probe 1 enabled, rising + falling; probe 2 enabled, rising, continuous.
        let f: u16 = 0x0031 | (0x0013 << 8);
        assert!(d.write(ObjectKey::new(0x60B8, 0), &f.to_le_bytes(), EsmState::Op).is_ok());
        d.set_axis(AxisState { bus_mv: 48_000, ..AxisState::default() });
        d.run_cycle(0.001);
        d.set_axis(AxisState {
            bus_mv: 48_000,
            probe1: EdgeLatch { rising: Some(1234), falling: Some(-77) },
            probe2: EdgeLatch { rising: Some(999), falling: Some(5) },
            ..AxisState::default()
        });
        d.run_cycle(0.001);
        let mut b = [0u8; 4];
        let rd = |d: &mut Drive, i: u16, b: &mut [u8; 4]| {
            let n = d.read(ObjectKey::new(i, 0), b).unwrap_or(0);
            let mut v = [0u8; 4];
            v[..n].copy_from_slice(&b[..n]);
            i32::from_le_bytes(v)
        };
        let st = rd(&mut d, 0x60B9, &mut b) as u16;
        assert_eq!(st & 0x07, 0x07, "60B9 {st:#06x}");
        assert_eq!((st >> 8) & 0x03, 0x03, "60B9 {st:#06x}");
        assert_eq!(rd(&mut d, 0x60BA, &mut b), 1234);
        assert_eq!(rd(&mut d, 0x60BB, &mut b), -77);
        assert_eq!(rd(&mut d, 0x60BC, &mut b), 999);
        // Probe 2's falling edge is not enabled: 0x60BD keeps its value.
        assert_eq!(rd(&mut d, 0x60BD, &mut b), 0);
        // Continuous probe 2: a new rising edge toggles bit 6 of its half.
        d.set_axis(AxisState {
            bus_mv: 48_000,
            probe2: EdgeLatch { rising: Some(1001), falling: None },
            ..AxisState::default()
        });
        d.run_cycle(0.001);
        assert_eq!(rd(&mut d, 0x60BC, &mut b), 1001);
        let st2 = rd(&mut d, 0x60B9, &mut b) as u16;
        assert_ne!(st2 & 0x4000, st & 0x4000);
    }
}
