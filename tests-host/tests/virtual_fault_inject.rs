//! `virtual-drive --fault KIND@TIME` in process (no root, no network): the segment is
//! built as the binary builds it (`sim_drive::segment`, the plant axis for one
//! drive), the injection goes through `fault_inject::Schedule` as in the binary's
//! loop, and what an integrator sees is checked for every kind: 0x603F, the PDS state
//! Fault, the one emergency, the 0x10F3 message, the LED timeline, the fault history
//! 0x2401. Also: the history survives a restart from the `--flash` file, and a bad
//! `--fault` makes the binary exit with code 2.

use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::leds::Pattern;
use ecat_slave_stack::od::{Dictionary, ObjectKey};
use firmware::cia402::pds::PdsState;
use firmware::faults::Emergency;
use tests_host::esc_sim::Flavour;
use tests_host::fault_inject::{led_state, InjectedFault, Injection, LedLog, Schedule};
use tests_host::segment::Segment;
use tests_host::sim_drive::{self, Motor, SimDrive, SimDriveConfig};

struct Run {
    seg: Segment<SimDrive>,
    emcy: Vec<Emergency>,
    log: Vec<String>,
    leds: LedLog,
    schedule: Schedule,
}

impl Run {
    fn new(flash_file: Option<std::path::PathBuf>, injections: Vec<Injection>) -> Run {
        let cfg = SimDriveConfig {
            motor: Motor::Ecn57_20,
            flavour: Flavour::Lan9252,
            flash_file,
            dips: tests_host::sim_drive::DIPS_ALL_ON,
        };
        let seg = sim_drive::segment(&cfg, 1).expect("segment");
        let mut r = Run {
            seg,
            emcy: Vec::new(),
            log: Vec::new(),
            leds: LedLog::default(),
            schedule: Schedule::new(injections),
        };
        r.collect();
        r
    }

    /// The drive's emergencies (collected here, then sent as
    /// `sim_drive::forward_emergencies` does) and the LED timeline.
    fn collect(&mut self) {
        for d in self.seg.drives_mut() {
            while let Some(e) = d.app.drive.pop_emergency() {
                self.emcy.push(e);
                d.slave.emergency(e.code, e.register, e.data);
            }
        }
        // The history write and the rest of the housekeeping.
        sim_drive::forward_emergencies(&mut self.seg);
        let log = &mut self.log;
        self.leds.observe(&self.seg, &mut |l| log.push(l));
    }

    /// `ms` of simulated time, in 1 ms steps as the binary's loop (injections due are
    /// applied after each step).
    fn run_ms(&mut self, ms: u64) {
        for _ in 0..ms {
            self.seg.advance(1_000_000);
            let now_us = self.seg.now_ns() / 1000;
            for d in self.seg.drives_mut() {
                d.app.catch_up(now_us);
            }
            self.collect();
            let log = &mut self.log;
            self.schedule.apply_due(&mut self.seg, &mut |l| log.push(l));
        }
    }

    fn app(&mut self) -> &mut SimDrive {
        &mut self.seg.drive_mut(0).app
    }

    fn write(&mut self, index: u16, sub: u8, data: &[u8]) {
        Dictionary::write(
            self.app(),
            ObjectKey::new(index, sub),
            data,
            EsmState::PreOp,
        )
        .unwrap_or_else(|e| panic!("write {index:#06x}:{sub}: {e:?}"));
    }

    fn read(&mut self, index: u16, sub: u8) -> u32 {
        let mut buf = [0u8; 32];
        let n = Dictionary::read(self.app(), ObjectKey::new(index, sub), &mut buf)
            .unwrap_or_else(|e| panic!("read {index:#06x}:{sub}: {e:?}"));
        let mut v = [0u8; 4];
        v[..n.min(4)].copy_from_slice(&buf[..n.min(4)]);
        u32::from_le_bytes(v)
    }

    fn state(&mut self) -> PdsState {
        self.app().drive.cia402.state()
    }

    /// Operation enabled in `mode` (8 CSP: holding where it stands; 3 PV: at the
    /// target velocity 0x60FF).
    fn enable(&mut self, mode: u8) {
        self.write(0x6060, 0, &[mode]);
        let here = self.app().drive.cia402.position_actual();
        self.write(0x607A, 0, &here.to_le_bytes());
        for cw in [0x0006u16, 0x0007, 0x000F] {
            self.write(0x6040, 0, &cw.to_le_bytes());
            self.run_ms(30);
        }
        assert_eq!(self.state(), PdsState::OperationEnabled);
    }
}

fn at(fault: InjectedFault, ms: u64) -> Injection {
    Injection {
        fault,
        at_ns: ms * 1_000_000,
    }
}

/// How the drive runs when the fault comes.
#[derive(Clone, Copy, PartialEq)]
enum Motion {
    Disabled,
    /// CSP, holding its position.
    Holding,
    /// PV at 2 rev/s.
    Moving,
}

/// Injects `fault` at `at_ms` (0x2056 = `mask` from the start, the drive enabled at
/// 500 ms when `motion` says so) and checks the drive's report 300 ms after the
/// injection.
fn check_kind(fault: InjectedFault, at_ms: u64, mask: u16, motion: Motion, code: u16, flashes: u8) {
    let mut r = Run::new(None, vec![at(fault, at_ms)]);
    r.write(0x2056, 0, &mask.to_le_bytes());
    if at_ms > 500 {
        r.run_ms(500);
        match motion {
            Motion::Disabled => {}
            Motion::Holding => r.enable(8),
            Motion::Moving => {
                let v = 2 * r.read(0x2001, 0) as i32; // 2 rev/s in pulses (0x2001 per rev)
                r.write(0x60FF, 0, &v.to_le_bytes());
                r.enable(3);
            }
        }
        assert!(r.emcy.is_empty(), "{fault:?}: before: {:x?}", r.emcy);
        assert_eq!(r.read(0x603F, 0), 0);
    }
    r.run_ms(at_ms + 300 - r.seg.now_ns() / 1_000_000);
    assert!(
        r.log
            .iter()
            .any(|l| l.contains("fault injected: ") && l.contains(fault.name())),
        "{:#?}",
        r.log
    );
    assert_eq!(r.read(0x603F, 0), u32::from(code), "{fault:?}: 0x603F");
    assert_eq!(r.state(), PdsState::Fault, "{fault:?}");
    assert!(!r.app().drive.command().power_stage, "{fault:?}: power off");
    let codes: Vec<u16> = r.emcy.iter().map(|e| e.code).collect();
    assert_eq!(codes, vec![code], "{fault:?}: one emergency");
    // 0x10F3: the newest message is that emergency (DiagCode 0xE800, code in 16..31).
    let newest = r.read(0x10F3, 2) as u8;
    assert!(newest >= 6, "{fault:?}: a message");
    let mut msg = [0u8; 32];
    let n = Dictionary::read(r.app(), ObjectKey::new(0x10F3, newest), &mut msg).expect("message");
    assert!(n >= 16);
    assert_eq!(
        u32::from_le_bytes([msg[0], msg[1], msg[2], msg[3]]),
        0xE800 | (u32::from(code) << 16),
        "{fault:?}: diagnosis message"
    );
    // The fault history and the LEDs.
    assert_eq!(r.read(0x2401, 1), u32::from(code));
    assert!(
        r.read(0x2401, 7) >= at_ms as u32,
        "{fault:?}: time of the fault"
    );
    assert_eq!(led_state(&r.seg, 0).red, Some(flashes));
    let red = format!("red fault LED {flashes} flash(es)");
    let i_inj = r.log.iter().position(|l| l.contains("fault injected"));
    let i_led = r.log.iter().position(|l| l.contains(&red));
    assert!(
        i_inj.is_some() && i_led > i_inj,
        "{fault:?}: LED timeline after the injection: {:#?}",
        r.log
    );
}

#[test]
fn bus_overvoltage_is_0x3210_with_two_flashes() {
    check_kind(
        InjectedFault::BusOvervoltage,
        1000,
        0x00C3,
        Motion::Holding,
        0x3210,
        2,
    );
}

#[test]
fn bus_overvoltage_is_detected_while_disabled_too() {
    check_kind(
        InjectedFault::BusOvervoltage,
        1000,
        0x00C3,
        Motion::Disabled,
        0x3210,
        2,
    );
}

#[test]
fn bus_undervoltage_is_0x3220_with_three_flashes() {
    check_kind(
        InjectedFault::BusUndervoltage,
        1000,
        0x00C3,
        Motion::Holding,
        0x3220,
        3,
    );
}

#[test]
fn phase_short_is_0x2310_with_one_flash() {
    check_kind(
        InjectedFault::PhaseShort,
        1000,
        0x00C3,
        Motion::Holding,
        0x2310,
        1,
    );
}

/// An open phase at start-up with 0x2056 bit 2 on (saved in the flash, on a real
/// `virtual-drive` run): the power-up tune finds it, motor open 0x7120.
#[test]
fn open_phase_a_at_start_is_motor_open_0x7120_with_four_flashes() {
    check_kind(
        InjectedFault::OpenPhaseA,
        0,
        0x00C7,
        Motion::Disabled,
        0x7120,
        4,
    );
}

#[test]
fn open_phase_b_at_start_is_motor_open_0x7120_with_four_flashes() {
    check_kind(
        InjectedFault::OpenPhaseB,
        0,
        0x00C7,
        Motion::Disabled,
        0x7120,
        4,
    );
}

#[test]
fn encoder_loss_while_moving_is_a_following_error_with_seven_flashes() {
    check_kind(
        InjectedFault::EncoderLoss,
        1500,
        0x00C3,
        Motion::Moving,
        0x8611,
        7,
    );
}

#[test]
fn open_phase_with_the_default_mask_is_not_reported() {
    let mut r = Run::new(None, vec![at(InjectedFault::OpenPhaseA, 800)]);
    r.run_ms(500);
    r.enable(8);
    r.run_ms(1000);
    assert!(r.log.iter().any(|l| l.contains("open-phase-a")));
    assert_eq!(r.read(0x603F, 0), 0);
    assert!(r.emcy.is_empty(), "{:x?}", r.emcy);
}

#[test]
fn the_led_timeline_starts_with_the_power_up_state() {
    let r = Run::new(None, Vec::new());
    assert_eq!(r.log.len(), 1, "{:#?}", r.log);
    let s = led_state(&r.seg, 0);
    assert_eq!((s.run, s.err, s.red), (Pattern::Off, Pattern::Off, None));
    assert!(r.log[0].contains("RUN Off, ERR Off, red fault LED dark"));
}

/// `virtual-drive --flash FILE`: the fault history written after an injected fault
/// is there again when the drive starts from the same file.
#[test]
fn fault_history_survives_a_restart_from_the_flash_file() {
    let dir = std::env::temp_dir().join(format!("vd-history-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let file = dir.join("flash.bin");
    let _ = std::fs::remove_file(&file);
    let (code, bus, time) = {
        let mut r = Run::new(
            Some(file.clone()),
            vec![at(InjectedFault::BusOvervoltage, 600)],
        );
        r.run_ms(800);
        assert_eq!(r.read(0x603F, 0), 0x3210);
        (r.read(0x2401, 1), r.read(0x2401, 4), r.read(0x2401, 7))
    };
    assert_eq!(code, 0x3210);
    assert!(bus >= 590, "snapshot bus voltage {bus}");
    // Restart from the file: the history, no active fault (the bus is 48 V again).
    let mut r = Run::new(Some(file.clone()), Vec::new());
    r.run_ms(10);
    assert_eq!(r.read(0x603F, 0), 0);
    assert_eq!(
        (r.read(0x2401, 1), r.read(0x2401, 4), r.read(0x2401, 7)),
        (code, bus, time)
    );
    assert_eq!(r.read(0x2400, 2), 0x3210);
    assert_eq!(r.read(0x2400, 1), 0, "faults since this power-up");
    // 0x2093 = 1 clears it in the file too.
    r.write(0x2093, 0, &[1]);
    r.run_ms(5);
    drop(r);
    let mut r = Run::new(Some(file.clone()), Vec::new());
    assert_eq!(r.read(0x2401, 1), 0);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A bad `--fault` is a usage error: a message naming the problem, exit code 2
/// (before any network access, so no root needed).
#[test]
fn bad_fault_option_exits_with_code_2() {
    for (arg, want) in [
        ("nonsense@x", "unknown fault kind 'nonsense'"),
        ("bus-overvoltage@5", "needs a unit"),
        ("bus-overvoltage", "KIND@TIME"),
    ] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_virtual-drive"))
            .args(["--iface", "does-not-exist", "--fault", arg])
            .output()
            .expect("run virtual-drive");
        assert_eq!(out.status.code(), Some(2), "{arg}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(want), "{arg}: {err}");
    }
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_virtual-drive"))
        .arg("--help")
        .output()
        .expect("run virtual-drive");
    let err = String::from_utf8_lossy(&out.stderr);
    for k in InjectedFault::ALL {
        assert!(err.contains(k.name()), "--help lists {}", k.name());
        // What the drive reports comes from the fault table.
        assert!(err.contains(&k.effect()), "--help: {}", k.effect());
        let i = k.reported().info();
        let report = tests_host::fault_inject::report_text(k.reported());
        assert!(report.contains(&format!("{:#06x}", i.code)), "{report}");
        assert!(report.contains(i.name), "{report}");
        assert_eq!(report.contains("latched (0x2057)"), i.latched, "{report}");
        assert_eq!(
            report.contains("power off at once"),
            i.cuts_power,
            "{report}"
        );
    }
}
