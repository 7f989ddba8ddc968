//! The drive on its own clock (drive-requirements "two clocks"): after the master's
//! commands stop, only [`Drive::tick`] runs — no cycle, no frame — and the reaction of
//! 0x6007, the stop ramps and the protections must still run to their end. Host and
//! QEMU.
//!
//! The axis is ideal: it follows the drive's position demand (and its velocity) at
//! each tick, so the stopping distance and time are the drive's own.
#![cfg_attr(target_os = "none", no_std, no_main)]

use ecat_slave_stack::al_status::AlStatusCode;
use ecat_slave_stack::diag::{DiagMessage, Param};
use ecat_slave_stack::esm::{EsmHooks, EsmState};
use ecat_slave_stack::od::{Dictionary, ObjectKey, SdoAbort};
use ecat_slave_stack::slave::{CycleInfo, SlaveApplication};
use ecat_slave_stack::sync::SyncMode;
use firmware::cia402::mode;
use firmware::cia402::pds::PdsState;
use firmware::current_supervisor::{CurrentReport, Trip};
use firmware::drive::{AxisState, Drive, ERR_COMMUNICATION_LOST};
use firmware::faults::Emergency;
use firmware::identity::Variant;

const BUS_MV: u32 = 48_000;
/// 0x6085 of these tests (units/s²) and the speed the loss finds the axis at.
const QS_DEC: u32 = 1_000_000;
const SPEED: i32 = 100_000;

/// A drive with an ideal axis and its local clock.
struct Rig {
    d: Drive,
    now_us: u64,
    pos: i32,
    vel: i32,
    /// Extra input to the axis state (faults injected "in the plant").
    extra: AxisState,
}

impl Rig {
    /// Powered up, in Op, mode `m`, enabled through master cycles (1 ms).
    fn enabled(m: i8, abort_option: i16) -> Rig {
        let mut d = Drive::new(Variant::HybridServo, 7);
        for (from, to) in [
            (EsmState::Init, EsmState::PreOp),
            (EsmState::PreOp, EsmState::SafeOp),
            (EsmState::SafeOp, EsmState::Op),
        ] {
            d.on_state_change(from, to);
        }
        d.cia402.params.abort_connection_option = abort_option;
        d.cia402.params.quick_stop_deceleration = QS_DEC;
        d.cia402.params.profile_acceleration = 10_000_000;
        d.cia402.params.max_acceleration = 100_000_000;
        d.cia402.set_mode(m);
        let mut r = Rig {
            d,
            now_us: 0,
            pos: 0,
            vel: 0,
            extra: AxisState::default(),
        };
        for cw in [0x0000u16, 0x0006, 0x0007, 0x000F, 0x000F] {
            r.d.cia402.set_controlword(cw);
            r.cycle();
        }
        assert_eq!(r.d.cia402.state(), PdsState::OperationEnabled);
        r
    }

    fn axis(&mut self) {
        let c = *self.d.command();
        if c.drive_enabled && self.d.power_permission() {
            self.pos = c.position;
            self.vel = c.velocity as i32;
        } else {
            self.vel = 0;
        }
        self.d.set_axis(AxisState {
            position: self.pos,
            velocity: self.vel,
            bus_mv: BUS_MV,
            ..self.extra
        });
    }

    /// One master cycle with fresh outputs, then the tick of the same millisecond.
    fn cycle(&mut self) {
        self.now_us += 1000;
        self.d.cycle(&CycleInfo {
            state: EsmState::Op,
            outputs_fresh: true,
            mode: SyncMode::DcSync0,
            now_us: self.now_us,
        });
        self.axis();
        self.d.tick(self.now_us, 0);
        self.axis();
    }

    /// One millisecond of the drive's own clock, no master.
    fn tick(&mut self) {
        self.now_us += 1000;
        self.d.tick(self.now_us, 0);
        self.axis();
    }

    fn emergencies(&mut self) -> heapless::Vec<Emergency, 8> {
        let mut v = heapless::Vec::new();
        while let Some(e) = self.d.pop_emergency() {
            let _ = v.push(e);
        }
        v
    }
}

/// The losses of the master's commands, as the slave runtime reports them.
#[derive(Clone, Copy, Debug)]
enum Loss {
    Watchdog,
    SafeOp,
    Init,
    Sync0,
}

fn lose(r: &mut Rig, loss: Loss) -> u16 {
    match loss {
        // As the slave runtime reports them: the outputs lost, then the ESM change.
        Loss::Watchdog => {
            r.d.on_outputs_lost(AlStatusCode::SmWatchdog);
            r.d.on_state_change(EsmState::Op, EsmState::SafeOp);
            ERR_COMMUNICATION_LOST
        }
        Loss::Sync0 => {
            r.d.on_outputs_lost(AlStatusCode::SyncError);
            r.d.on_state_change(EsmState::Op, EsmState::SafeOp);
            ERR_COMMUNICATION_LOST
        }
        Loss::SafeOp => {
            r.d.on_state_change(EsmState::Op, EsmState::SafeOp);
            0xA001
        }
        Loss::Init => {
            r.d.on_state_change(EsmState::Op, EsmState::Init);
            0xA000
        }
    }
}

qemu_runner::tests! {
    fn every_abort_option_and_loss_in_pv_finishes_on_the_local_clock() {
        for option in 0..=3i16 {
            for loss in [Loss::Watchdog, Loss::SafeOp, Loss::Init, Loss::Sync0] {
                let mut r = Rig::enabled(mode::PV, option);
                r.d.cia402.params.target_velocity = SPEED;
                for _ in 0..50 {
                    r.cycle();
                }
                assert_eq!(r.vel, SPEED, "{loss:?}/{option}: moving");
                let _ = r.emergencies();
                let first = lose(&mut r, loss);
                // Only the drive's own clock from here on: 2.5 s of ticks.
                let mut stop_ms = None;
                for k in 1..=2500u32 {
                    r.tick();
                    if stop_ms.is_none() && r.vel == 0 {
                        stop_ms = Some(k);
                    }
                }
                let e = r.emergencies();
                let st = r.d.cia402.state();
                let case = (loss, option);
                match option {
                    0 => {
                        // No action: the drive keeps its state and its last set-points.
                        assert_eq!(st, PdsState::OperationEnabled, "{case:?}");
                        assert_eq!(r.vel, SPEED, "{case:?} keeps moving");
                        assert!(e.is_empty(), "{case:?}: {e:?}");
                        continue;
                    }
                    1 => {
                        assert_eq!(st, PdsState::Fault, "{case:?}");
                        assert_eq!(r.d.cia402.error_code(), first, "{case:?}: 0x603F = the emergency");
                        assert_eq!(e.len(), 1, "{case:?}: {e:?}");
                        assert_eq!(e[0].code, first, "{case:?}");
                        assert_eq!(e[0].register & 0x11, 0x11, "{case:?}: generic + communication");
                    }
                    2 => {
                        assert_eq!(st, PdsState::SwitchOnDisabled, "{case:?}");
                        assert_eq!(r.d.cia402.error_code(), 0, "{case:?}");
                        assert_eq!(e.len(), 1, "{case:?}: {e:?}");
                        assert_eq!(e[0].code, first, "{case:?}");
                    }
                    _ => {
                        assert_eq!(st, PdsState::SwitchOnDisabled, "{case:?}");
                        assert_eq!(r.d.cia402.error_code(), 0, "{case:?}");
                        assert_eq!(e.len(), 1, "{case:?}: {e:?}");
                    }
                }
                // Time to standstill against the ramp, within one tick.
                let t = stop_ms.expect("stands still");
                let expected = if option == 2 { 1 } else { (SPEED as u32 * 1000).div_ceil(QS_DEC) };
                assert!(t.abs_diff(expected) <= 1, "{case:?}: standstill after {t} ms, ramp {expected} ms");
                // Power stage off, brake engaged, statusword shows it; nothing moves.
                let c = *r.d.command();
                assert!(!c.power_stage && !c.drive_enabled, "{case:?}");
                assert!(!r.d.power_permission(), "{case:?}");
                assert!(!r.d.outputs().1, "{case:?}: brake engaged");
                let sw = r.d.cia402.statusword();
                assert_eq!(sw & 0x10, 0, "{case:?}: voltage not enabled ({sw:#06x})");
                let at = r.pos;
                for _ in 0..2000 {
                    r.tick();
                }
                assert_eq!(r.pos, at, "{case:?}: no drift after the stop");
            }
        }
    }

    fn csp_holds_after_one_period_of_run_on_and_faults_on_watchdog() {
        let mut r = Rig::enabled(mode::CSP, 1);
        let mut target = 0;
        for _ in 0..50 {
            target += 100;
            r.d.cia402.params.target_position = target;
            r.cycle();
        }
        assert_eq!(r.pos, target);
        // Frames stop; the watchdog needs 100 ms to notice. Meanwhile: one period of
        // run-on (100 units), then hold.
        for _ in 0..100 {
            r.tick();
        }
        assert_eq!(r.pos, target + 100, "run-on for one period, then hold");
        assert_eq!(r.vel, 0);
        assert_eq!(r.d.cia402.state(), PdsState::OperationEnabled);
        lose(&mut r, Loss::Watchdog);
        for _ in 0..10 {
            r.tick();
        }
        assert_eq!(r.d.cia402.state(), PdsState::Fault);
        assert_eq!(r.pos, target + 100, "no motion in the reaction from standstill");
    }

    fn quick_stop_option_that_stays_holds_with_power_on_the_local_clock() {
        let mut r = Rig::enabled(mode::PV, 3);
        r.d.cia402.params.quick_stop_option = 6;
        r.d.cia402.params.target_velocity = SPEED;
        for _ in 0..50 {
            r.cycle();
        }
        lose(&mut r, Loss::Watchdog);
        for _ in 0..500 {
            r.tick();
        }
        assert_eq!(r.d.cia402.state(), PdsState::QuickStopActive);
        let at = r.pos;
        for _ in 0..2000 {
            r.tick();
            assert!(r.d.power_permission() && r.d.command().drive_enabled, "holding");
        }
        assert_eq!(r.pos, at);
    }

    fn faults_without_frames_react_on_the_tick() {
        // Over-voltage: power off at once (no ramp: braking would pump the bus).
        let mut r = Rig::enabled(mode::PV, 1);
        r.d.cia402.params.target_velocity = SPEED;
        for _ in 0..50 {
            r.cycle();
        }
        let _ = r.emergencies();
        r.d.set_axis(AxisState { bus_mv: 60_000, position: r.pos, velocity: r.vel, ..AxisState::default() });
        r.now_us += 1000;
        r.d.tick(r.now_us, 0);
        assert!(!r.d.power_permission(), "over-voltage: power off in the same tick");
        assert_eq!(r.d.faults.error_code(), 0x3210);
        r.axis();
        r.tick();
        assert_eq!(r.vel, 0);
        assert_eq!(r.d.cia402.state(), PdsState::Fault);
        assert_eq!(r.emergencies()[0].code, 0x3210);
        // The same fault in the ETG.1020 diagnosis history, as a master reads it.
        let mut b = [0u8; 32];
        assert_eq!(r.d.read(ObjectKey::new(0x10F3, 2), &mut b), Ok(1));
        let newest = b[0];
        assert_eq!(newest, 6, "first message in SI6");
        assert_eq!(r.d.read(ObjectKey::new(0x10F3, 4), &mut b).map(|_| b[0]), Ok(1), "new message");
        assert_eq!(r.d.read(ObjectKey::new(0x10F3, newest), &mut b), Ok(28));
        let m = DiagMessage::parse(&b).expect("a message");
        assert_eq!(m.code, 0x3210_E800);
        assert_eq!(m.text_id, firmware::diagnosis::fault_text_id(firmware::faults::FaultKind::OverVoltage));
        assert_eq!(m.params[0], Param::U16(600), "bus 60.0 V");
        assert_eq!(r.d.read(ObjectKey::new(0x10F3, 4), &mut b).map(|_| b[0]), Ok(0), "read: no new message");
        assert_eq!(r.d.write(ObjectKey::new(0x10F3, 3), &[7], EsmState::PreOp), Err(SdoAbort::ValueRangeExceeded));
        assert_eq!(r.d.write(ObjectKey::new(0x10F3, 3), &[0], EsmState::PreOp), Ok(()));
        assert_eq!(r.d.read(ObjectKey::new(0x10F3, 2), &mut b).map(|_| b[0]), Ok(0), "cleared");

        // Phase short (the break latch): power off at once.
        let mut r = Rig::enabled(mode::PV, 1);
        r.d.cia402.params.target_velocity = SPEED;
        for _ in 0..50 {
            r.cycle();
        }
        r.extra.overcurrent_trip = true;
        r.tick();
        r.tick();
        assert!(!r.d.power_permission());
        assert_eq!(r.vel, 0);
        assert_eq!(r.d.cia402.state(), PdsState::Fault);
        assert_eq!(r.d.cia402.error_code(), 0x2310);

        // The current loop's fast protection tripped (the bridges are already off):
        // the drive raises the fault with the sample from the report.
        let mut r = Rig::enabled(mode::PV, 1);
        r.d.cia402.params.target_velocity = SPEED;
        for _ in 0..50 {
            r.cycle();
        }
        let _ = r.emergencies();
        r.d.current_report(&CurrentReport {
            trip_seq: 1,
            trip: Trip::OverCurrent,
            trip_ia_ma: 11_200,
            trip_bus_dv: 480,
            ..CurrentReport::NONE
        });
        r.tick();
        assert!(!r.d.power_permission());
        assert_eq!(r.d.cia402.state(), PdsState::Fault);
        assert_eq!(r.d.faults.history(0).map(|h| h.snapshot.ia_ma), Some(11_200));
        assert_eq!(r.emergencies()[0].code, 0x2310);

        // Following error while holding (closed loop): the 0x605E ramp, then Fault.
        let mut r = Rig::enabled(mode::CSP, 1);
        r.d.cia402.params.target_position = 0;
        for _ in 0..20 {
            r.cycle();
        }
        r.extra.servo_following_error = 5_000;
        for _ in 0..5 {
            r.tick();
        }
        assert_eq!(r.d.cia402.state(), PdsState::Fault);
        assert_eq!(r.d.cia402.error_code(), 0x8611);
        assert!(!r.d.power_permission());
        assert!(!r.d.outputs().1, "brake engaged");
    }
}
