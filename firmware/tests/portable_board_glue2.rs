#![cfg_attr(target_os = "none", no_std, no_main)]
//! The board glue of `firmware::board_glue` (what `firmware/src/main.rs` and the
//! simulator run between the drive and the control path): index and probe latches
//! kept until a drive step, probe polarity 0x2154, failed alignments → 0x8611 once,
//! the failed offset check → fault 9 at every tick, break latch ↔ fault 1 with the
//! re-arm only after the power permission was withdrawn, a new interpolation segment
//! only per drive step; and the seqlock [`Exchange`] (single-threaded protocol).
//! Host and QEMU.
use ecat_slave_stack::esm::{EsmHooks, EsmState};
use ecat_slave_stack::slave::{CycleInfo, SlaveApplication};
use ecat_slave_stack::sync::SyncMode;
use firmware::board_glue::{BoardGlue, ControlCommand, Exchange, Feedback};
use firmware::cia402::pds::PdsState;
use firmware::cia402::EdgeLatch;
use firmware::current_supervisor::SupervisorConfig;
use firmware::drive::{AxisState, Drive};
use firmware::faults::FaultKind;
use firmware::identity::Variant;
use firmware::latch::Edges;
use firmware::motion::{MotionConfig, ECN57_20, SERVO_TS};
use firmware::params::P;

const BUS_MV: u32 = 48_000;

/// A drive with the glue in front of it, as the board wires them.
struct Rig {
    d: Drive,
    g: BoardGlue,
    fb: Feedback,
    seq: u32,
    now_us: u64,
}

fn start_command(d: &Drive) -> ControlCommand {
    ControlCommand {
        cycle: 0,
        command: *d.command(),
        cycle_s: 1e-3,
        power_allowed: false,
        config: 0,
        motion: MotionConfig::from_params(&d.params, d.variant, &ECN57_20, SERVO_TS),
        align_wiggle: false,
        offsets: None,
        supervisor: SupervisorConfig::from_params(&d.params, 25e-6, 2125),
        tune_allowed: false,
        trace: false,
        brake_released: false,
    }
}

impl Rig {
    fn new() -> Rig {
        let d = Drive::new(Variant::HybridServo, 3);
        let g = BoardGlue::new(start_command(&d));
        let mut fb = Feedback::default();
        fb.axis.bus_mv = BUS_MV;
        Rig {
            d,
            g,
            fb,
            seq: 0,
            now_us: 0,
        }
    }

    /// Powered up, in Op, enabled (Operation enabled) through master cycles.
    fn enabled() -> Rig {
        let mut r = Rig::new();
        for (from, to) in [
            (EsmState::Init, EsmState::PreOp),
            (EsmState::PreOp, EsmState::SafeOp),
            (EsmState::SafeOp, EsmState::Op),
        ] {
            r.d.on_state_change(from, to);
        }
        r.g.offsets_passed(2048.0, 2048.0);
        for cw in [0x0000u16, 0x0006, 0x0007, 0x000F, 0x000F] {
            r.d.cia402.set_controlword(cw);
            r.cycle(false);
        }
        assert_eq!(r.d.cia402.state(), PdsState::OperationEnabled);
        r
    }

    /// The control path publishes `fb` once more.
    fn publish_feedback(&mut self) {
        self.seq = self.seq.wrapping_add(1);
    }

    fn update(&mut self, break_latched: bool) -> AxisState {
        self.g
            .update_axis(&mut self.d, self.seq, &self.fb, break_latched)
    }

    /// One master cycle as the board's `cyclic` task runs it.
    fn cycle(&mut self, break_latched: bool) -> ControlCommand {
        self.now_us += 1000;
        self.update(break_latched);
        self.d.cycle(&CycleInfo {
            state: EsmState::Op,
            outputs_fresh: true,
            mode: SyncMode::DcSync0,
            now_us: self.now_us,
        });
        *self.g.publish(&self.d)
    }

    /// One 1 ms tick as the board's `tick` task runs it (without the break part).
    fn tick(&mut self, break_latched: bool) -> ControlCommand {
        self.now_us += 1000;
        self.update(break_latched);
        self.g
            .raise_board_faults(&mut self.d, (self.now_us / 1000) as u32);
        self.d.tick(self.now_us, 0);
        *self.g.publish(&self.d)
    }

    fn emergencies_with(&mut self, code: u16) -> usize {
        let mut n = 0;
        while let Some(e) = self.d.pop_emergency() {
            n += usize::from(e.code == code);
        }
        n
    }
}

qemu_runner::tests! {
    fn index_is_kept_until_a_drive_step_consumed_it() {
        let mut r = Rig::new();
        r.publish_feedback();
        assert_eq!(r.update(false).index, None);
        r.fb.index_seq = 1;
        r.fb.index_units = 1234;
        r.publish_feedback();
        // Seen by several updates without a step in between (the interrupt keeps
        // publishing the same latch): still pending.
        for _ in 0..3 {
            assert_eq!(r.update(false).index, Some(1234));
            let steps = r.d.steps();
            r.g.publish(&r.d);
            assert_eq!(r.d.steps(), steps);
        }
        // A step consumes it: the next update no longer reports it.
        let steps = r.d.steps();
        r.tick(false);
        assert_ne!(r.d.steps(), steps);
        assert_eq!(r.update(false).index, None);
        // A newer pulse replaces it.
        r.fb.index_seq = 2;
        r.fb.index_units = -7;
        assert_eq!(r.update(false).index, Some(-7));
        r.fb.index_seq = 3;
        r.fb.index_units = 99;
        assert_eq!(r.update(false).index, Some(99));
    }

    fn probe_edges_follow_the_polarity_of_0x2154() {
        for (inverted, in1_inv, in2_inv) in [(0, false, false), (1, true, false), (2, false, true), (3, true, true)] {
            let mut r = Rig::new();
            r.d.params.set_internal(P::InputPolarity, inverted);
            let mut e1 = Edges::default();
            let mut e2 = Edges::default();
            e1.record(true, 100);
            e2.record(false, -200);
            r.fb.probe1 = e1;
            r.fb.probe2 = e2;
            let a = r.update(false);
            let (want1, want2) = (
                if in1_inv {
                    EdgeLatch { rising: None, falling: Some(100) }
                } else {
                    EdgeLatch { rising: Some(100), falling: None }
                },
                if in2_inv {
                    EdgeLatch { rising: Some(-200), falling: None }
                } else {
                    EdgeLatch { rising: None, falling: Some(-200) }
                },
            );
            assert_eq!(a.probe1, want1, "0x2154 = {inverted}");
            assert_eq!(a.probe2, want2, "0x2154 = {inverted}");
            // Pending until a step, then gone (the same edges are not new again).
            assert_eq!(r.update(false).probe1, want1);
            r.tick(false);
            let b = r.update(false);
            assert_eq!(b.probe1, EdgeLatch::default());
            assert_eq!(b.probe2, EdgeLatch::default());
        }
    }

    fn a_failed_alignment_is_exactly_one_following_error() {
        let mut r = Rig::new();
        r.publish_feedback();
        for _ in 0..5 {
            r.tick(false);
        }
        assert!(!r.d.faults.is_active(FaultKind::FollowingError));
        assert_eq!(r.emergencies_with(0x8611), 0);
        r.fb.align_failures = 1;
        r.publish_feedback();
        // Seen by a cycle's update first, raised by the next tick.
        r.update(false);
        assert!(!r.d.faults.is_active(FaultKind::FollowingError));
        for _ in 0..20 {
            r.tick(false);
        }
        assert!(r.d.faults.is_active(FaultKind::FollowingError));
        assert_eq!(r.emergencies_with(0x8611), 1);
        // Reset: no second fault from the same failure.
        assert!(r.d.faults.fault_reset());
        for _ in 0..20 {
            r.tick(false);
        }
        assert!(!r.d.faults.is_active(FaultKind::FollowingError));
        assert_eq!(r.emergencies_with(0x8611), 0);
        // A second failed alignment is a new fault.
        r.fb.align_failures = 2;
        r.tick(false);
        assert!(r.d.faults.is_active(FaultKind::FollowingError));
        assert_eq!(r.emergencies_with(0x8611), 1);
    }

    fn a_failed_offset_check_is_fault_9_at_every_tick() {
        let mut r = Rig::new();
        // 0x2056 bit 3: phase-sensing detection enabled (not in the default mask).
        r.d.params.set_internal(P::FaultMask, 0x00CB);
        r.d.faults.configure_from(&r.d.params);
        r.tick(false);
        assert!(!r.d.faults.is_active(FaultKind::PhaseSensing));
        r.g.offset_check_failed();
        r.tick(false);
        assert!(r.d.faults.is_active(FaultKind::PhaseSensing));
        assert_eq!(r.d.faults.led_code(), Some(9));
        for _ in 0..10 {
            // A fault reset does not clear it: the condition is raised again at once.
            r.d.faults.fault_reset();
            r.tick(false);
            assert!(r.d.faults.is_active(FaultKind::PhaseSensing));
            assert!(!r.d.power_permission());
            assert!(!r.g.command().power_allowed);
        }
    }

    fn the_break_is_rearmed_only_after_the_permission_was_withdrawn() {
        let mut r = Rig::enabled();
        // 0x2057 = 1: the latched over-current may be cleared by a fault reset.
        r.d.params.set_internal(P::FaultClearAllowed, 1);
        r.d.faults.configure_from(&r.d.params);
        let c = r.cycle(false);
        assert!(c.power_allowed);
        assert!(c.command.drive_enabled);
        // No latch: nothing to do.
        assert!(r.g.over_current(&mut r.d, false).is_none());
        // The break latches: first noted, no re-arm while the drive has no fault yet.
        assert!(r.g.over_current(&mut r.d, true).is_none());
        assert!(r.g.over_current(&mut r.d, true).is_none());
        assert!(!r.d.faults.is_active(FaultKind::OverCurrent));
        // The drive sees the trip and latches fault 1.
        let a = r.update(true);
        assert!(a.overcurrent_trip);
        r.tick(true);
        assert!(r.d.faults.is_active(FaultKind::OverCurrent));
        // Now the glue asks for a re-arm, with the command that withdraws the power.
        let cmd = *r.g.over_current(&mut r.d, true).expect("re-arm requested");
        assert!(!cmd.power_allowed);
        assert!(!cmd.command.drive_enabled);
        assert!(!r.d.power_permission());
        // The re-arm failed (break inputs still active): the fault stays, asked again.
        assert!(!r.d.faults.fault_reset());
        assert!(r.g.over_current(&mut r.d, true).is_some());
        // Re-armed: the condition is gone, a fault reset clears fault 1.
        r.g.break_rearmed(&mut r.d);
        r.update(false);
        assert!(r.g.over_current(&mut r.d, false).is_none());
        assert!(r.d.faults.fault_reset());
        assert!(!r.d.faults.is_active(FaultKind::OverCurrent));
        // A second re-arm report without a latch changes nothing.
        r.g.break_rearmed(&mut r.d);
        assert!(!r.d.faults.is_active(FaultKind::OverCurrent));
    }

    fn a_new_segment_only_at_a_new_drive_step() {
        let mut r = Rig::enabled();
        let c0 = *r.g.publish(&r.d);
        // Publishing again without a step: the same segment.
        for _ in 0..3 {
            let c = *r.g.publish(&r.d);
            assert_eq!(c.cycle, c0.cycle);
            assert_eq!(c.command, c0.command);
        }
        // Each step (cycle or tick) is one new segment with the drive's set-points.
        let c1 = r.cycle(false);
        assert_eq!(c1.cycle, c0.cycle.wrapping_add(1));
        assert_eq!(c1.command, *r.d.command());
        assert_eq!(c1.cycle_s, r.d.segment_s());
        assert!(c1.power_allowed && c1.command.drive_enabled);
        // The tune permission needs the passed offsets.
        assert_eq!(c1.tune_allowed, r.d.tune_permitted());
        // The tick right after a cycle of the same millisecond does not step again.
        let steps = r.d.steps();
        let c2 = *r.g.publish(&r.d);
        assert_eq!(r.d.steps(), steps);
        assert_eq!(c2.cycle, c1.cycle);
        // Permission withdrawn (disable voltage) without a step: drive_enabled masked.
        r.d.cia402.set_controlword(0x0000);
        r.cycle(false);
        let c3 = *r.g.publish(&r.d);
        assert!(!c3.power_allowed);
        assert!(!c3.command.drive_enabled);
        assert!(!c3.permits_power());
        assert!(!c3.motion_command().drive_enabled);
    }

    fn the_control_path_needs_permission_and_offsets() {
        let r = Rig::enabled();
        let mut c = *r.g.command();
        assert!(c.power_allowed && c.offsets.is_some());
        assert!(c.permits_power());
        assert!(c.motion_command().drive_enabled);
        c.offsets = None;
        assert!(!c.permits_power());
        c.offsets = Some((2048.0, 2048.0));
        c.power_allowed = false;
        assert!(!c.permits_power());
        // The set-points other than the enable pass unchanged.
        let m = c.motion_command();
        assert!(!m.drive_enabled);
        assert_eq!(m.position, c.command.position);
    }

    fn configuration_number_moves_only_on_a_change() {
        let mut r = Rig::new();
        let c0 = *r.g.command();
        r.g.configure(c0.motion, c0.align_wiggle, c0.supervisor);
        assert_eq!(r.g.command().config, c0.config);
        r.g.configure(c0.motion, !c0.align_wiggle, c0.supervisor);
        assert_eq!(r.g.command().config, c0.config.wrapping_add(1));
        assert_eq!(r.g.command().align_wiggle, !c0.align_wiggle);
    }

    fn exchange_write_read_sequence() {
        let x: Exchange<[u32; 3]> = Exchange::new([1, 2, 3]);
        assert_eq!(x.sequence(), 0);
        assert_eq!(x.read(), Some((0, [1, 2, 3])));
        assert_eq!(x.read_looped(), Some((0, [1, 2, 3])));
        for i in 1..=5u32 {
            // SAFETY: the only writer (single-threaded test).
            unsafe { x.write([i, i * 10, i * 100]) };
            assert_eq!(x.sequence(), i);
            assert_eq!(x.read(), Some((i, [i, i * 10, i * 100])));
            assert_eq!(x.read_looped(), Some((i, [i, i * 10, i * 100])));
        }
        // SAFETY: nothing else uses the cell.
        unsafe { x.reset([7, 8, 9]) };
        assert_eq!(x.sequence(), 0);
        assert_eq!(x.read(), Some((0, [7, 8, 9])));
        // After a reset the next write goes to the other buffer as before.
        // SAFETY: the only writer.
        unsafe { x.write([4, 5, 6]) };
        assert_eq!(x.read(), Some((1, [4, 5, 6])));
    }

    fn exchange_zeroed_and_reset_then() {
        let x: Exchange<Option<u32>> = Exchange::zeroed();
        assert_eq!(x.read(), Some((0, None)));
        // SAFETY: the only writer.
        unsafe { x.write(Some(5)) };
        assert_eq!(x.read(), Some((1, Some(5))));
        let f: Exchange<Feedback> = Exchange::zeroed();
        let (s, v) = f.read_looped().expect("no writer");
        assert_eq!(s, 0);
        assert_eq!(v.index_seq, 0);
        assert!(!v.axis.commutation_pending);
        // SAFETY: nothing else uses the cell.
        unsafe {
            f.reset_then(|v| {
                v.axis.commutation_pending = true;
                v.index_units = -3;
            })
        };
        let (s, v) = f.read_looped().expect("no writer");
        assert_eq!(s, 0);
        assert!(v.axis.commutation_pending);
        assert_eq!(v.index_units, -3);
        // Both buffers were set: the value survives the first publication's swap.
        let mut w = v;
        w.index_seq = 9;
        // SAFETY: the only writer.
        unsafe { f.write(w) };
        let (s, v) = f.read_looped().expect("no writer");
        assert_eq!((s, v.index_seq, v.index_units), (1, 9, -3));
    }

    fn exchange_keeps_the_latest_of_many() {
        let x: Exchange<u32> = Exchange::new(0);
        // SAFETY: the only writer.
        unsafe { x.write(1) };
        let (s, _) = x.read().expect("no writer");
        assert_eq!(s, 1);
        // Many writes: the latest always reads back whole.
        for i in 0..1000u32 {
            // SAFETY: the only writer.
            unsafe { x.write(i) };
        }
        assert_eq!(x.read(), Some((1001, 999)));
    }
}
