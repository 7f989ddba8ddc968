//! "Operation enabled" only once the drive can follow set-points: the power-up
//! commutation alignment of the closed loop runs while the PDS stays in Switched on.
//!
//! A [`SimDrive`] (the firmware's drive application) drives a [`PlantAxis`] built
//! like a board just after power-up ([`PlantAxis::new_unaligned`]: the encoder's
//! electrical offset unknown, the board's `CommutatedMotion` in front of the motion
//! layer). The test plays a CSP master as TwinCAT / SOEM do: shutdown, switch on,
//! enable operation, and until the statusword shows Operation enabled it copies the
//! position actual value 0x6064 into the target 0x607A every cycle; from then on it
//! commands a move. Checked: the statusword stays Switched on (0x0233) for the 0.25 s
//! (0.65 s with the wiggle 0x2083 = 1) of the alignment while the motor side already
//! has the power stage; Operation enabled then arrives with 0x6062 = 0x6064 and the
//! shaft does not jump; the CSP move follows with a small following error. A locked
//! rotor with the wiggle fails the alignment: fault 0x8611, never Operation enabled.
//! Open loop and an aligned axis do not wait.

use std::cell::RefCell;
use std::rc::Rc;

use ecat_slave_stack::esm::{EsmHooks, EsmState};
use ecat_slave_stack::od::{Dictionary, ObjectKey};
use ecat_slave_stack::slave::{CycleInfo, SlaveApplication};
use ecat_slave_stack::sync::SyncMode;
use firmware::cia402::pds::PdsState;
use firmware::commutation::Commutation;
use firmware::current_supervisor::TuneStatus;
use firmware::faults::Emergency;
use tests_host::file_flash::FileFlash;
use tests_host::sim_axis::{PlantAxis, SharedPlant};
use tests_host::sim_drive::{Axis, Motor, NoRuntime, SimDrive};

/// Command units per encoder count (50 000 units, 4 000 counts per revolution).
const UNITS_PER_COUNT: f64 = 12.5;

/// One millisecond as the master sees it.
#[derive(Debug, Clone, Copy)]
struct Sample {
    ms: u32,
    statusword: u16,
    actual: i32,
    demand: i32,
    target: i32,
    commutation: Commutation,
    ia: f64,
    ib: f64,
}

struct Bench {
    d: SimDrive,
    axis: Rc<RefCell<PlantAxis>>,
    now_us: u64,
    emcy: Vec<Emergency>,
    /// The master copies 0x6064 into 0x607A before each cycle while the statusword
    /// does not show Operation enabled (what CSP masters do).
    track: bool,
    log: Vec<Sample>,
}

impl Bench {
    /// A drive powered up on `axis` (48 V), mode CSP, `wiggle` written to 0x2083, after
    /// the power-up auto-tune.
    fn new(axis: PlantAxis, wiggle: bool) -> Self {
        let axis = Rc::new(RefCell::new(axis));
        let mut d = SimDrive::new(
            0x1234,
            FileFlash::in_memory(),
            Box::new(SharedPlant(axis.clone())),
        );
        d.drive.power_up(&mut NoRuntime);
        d.axis.parameters(&d.drive.params);
        let mut b = Bench {
            d,
            axis,
            now_us: 0,
            emcy: Vec::new(),
            track: true,
            log: Vec::new(),
        };
        b.sdo_write(0x6060, 0, &[8]);
        b.sdo_write(0x2083, 0, &[u8::from(wiggle)]);
        for _ in 0..1000 {
            let t = b.axis.borrow().supervisor.report().tune;
            if !matches!(t, TuneStatus::Pending | TuneStatus::Running) {
                break;
            }
            b.run_ms(1);
        }
        assert_eq!(b.axis.borrow().supervisor.report().tune, TuneStatus::Done);
        b.run_ms(20);
        assert_eq!(b.state(), PdsState::SwitchOnDisabled);
        b
    }

    fn sdo_write(&mut self, index: u16, sub: u8, data: &[u8]) {
        Dictionary::write(&mut self.d, ObjectKey::new(index, sub), data, EsmState::Op)
            .unwrap_or_else(|e| panic!("write {index:#06x}:{sub}: {e:?}"));
    }

    fn now_ms(&self) -> u32 {
        (self.now_us / 1000) as u32
    }

    fn state(&self) -> PdsState {
        self.d.drive.cia402.state()
    }

    fn statusword(&self) -> u16 {
        self.d.drive.cia402.statusword()
    }

    fn true_position(&self) -> f64 {
        self.axis.borrow().true_position()
    }

    /// `ms` drive cycles of 1 ms (DC mode, fresh outputs), the master's tracking of
    /// 0x607A before each, a log sample after each.
    fn run_ms(&mut self, ms: u64) {
        for _ in 0..ms {
            let sw = self.statusword();
            if self.track && sw & 0x6F != 0x27 {
                let here = self.d.drive.cia402.position_actual();
                Dictionary::write(
                    &mut self.d,
                    ObjectKey::new(0x607A, 0),
                    &here.to_le_bytes(),
                    EsmState::Op,
                )
                .unwrap();
            }
            self.now_us += 1000;
            self.d.catch_up(self.now_us);
            self.d.cycle(&CycleInfo {
                state: EsmState::Op,
                outputs_fresh: true,
                mode: SyncMode::DcSync0,
                now_us: self.now_us,
            });
            while let Some(e) = self.d.drive.pop_emergency() {
                self.emcy.push(e);
            }
            let c = &self.d.drive.cia402;
            let ax = self.axis.borrow();
            let s = Sample {
                ms: self.now_ms(),
                statusword: c.statusword(),
                actual: c.position_actual(),
                demand: c.position_demand(),
                target: c.params.target_position,
                commutation: ax.commutation(),
                ia: ax.rig.plant.ia,
                ib: ax.rig.plant.ib,
            };
            drop(ax);
            self.log.push(s);
        }
    }

    fn controlword(&mut self, cw: u16, ms: u64) {
        self.sdo_write(0x6040, 0, &cw.to_le_bytes());
        self.run_ms(ms);
    }

    /// Shutdown, switch on, then enable operation; runs until the statusword shows
    /// Operation enabled or the PDS is in Fault (at most `max_ms`). Returns the log
    /// index of the first cycle after "enable operation" was written.
    fn enable(&mut self, max_ms: u32) -> usize {
        self.controlword(0x0006, 5);
        self.controlword(0x0007, 5);
        assert_eq!(self.state(), PdsState::SwitchedOn);
        self.sdo_write(0x6040, 0, &0x000Fu16.to_le_bytes());
        let from = self.log.len();
        for _ in 0..max_ms {
            self.run_ms(1);
            if matches!(self.state(), PdsState::OperationEnabled | PdsState::Fault) {
                break;
            }
        }
        from
    }
}

/// Enables an unaligned axis and checks the wait; returns the bench just after
/// Operation enabled and the length of the wait in ms.
fn enable_unaligned(wiggle: bool, theta0: f64) -> (Bench, u32) {
    let axis = PlantAxis::with_plant(Motor::Ecn57_20, false, |p| p.theta0 = theta0);
    let mut b = Bench::new(axis, wiggle);
    assert_eq!(b.axis.borrow().commutation(), Commutation::Unaligned);
    let from = b.enable(2000);
    assert_eq!(b.state(), PdsState::OperationEnabled, "wiggle {wiggle}");
    assert!(b.emcy.is_empty(), "{:x?}", b.emcy);
    let log = &b.log[from..];
    let (last, waiting) = log.split_last().unwrap();
    // Every cycle before: Switched on with voltage (0x0233), the alignment running.
    for s in waiting {
        assert_eq!(
            s.statusword & 0x027F,
            0x0233,
            "{} ms: {:#06x}",
            s.ms,
            s.statusword
        );
        assert_eq!(
            s.demand, s.actual,
            "{} ms: demand at the actual position",
            s.ms
        );
    }
    // The motor side had the power stage: current flowed and the rotor was pulled.
    let peak = waiting
        .iter()
        .map(|s| s.ia.abs().max(s.ib.abs()))
        .fold(0.0, f64::max);
    assert!(peak > 1.0, "alignment current {peak:.2} A");
    assert!(waiting
        .iter()
        .any(|s| s.commutation == Commutation::Aligning));
    let wait = waiting.len() as u32;
    let expect = if wiggle { 650..=670 } else { 250..=270 };
    assert!(expect.contains(&wait), "wiggle {wiggle}: waited {wait} ms");
    // The first Operation enabled cycle: aligned, 0x6062 = 0x6064, and the target the
    // master copied is the actual position to a count.
    assert_eq!(last.commutation, Commutation::Aligned);
    assert_eq!(last.statusword & 0x6F, 0x27);
    assert!(
        (last.demand - last.actual).abs() as f64 <= UNITS_PER_COUNT,
        "demand {} actual {}",
        last.demand,
        last.actual
    );
    assert!((last.target - last.actual).abs() as f64 <= UNITS_PER_COUNT);
    let ax = b.axis.borrow();
    let err = ax.rig.offset_error_counts(ax.rig.enc.electrical_offset());
    assert!(err.abs() <= 3.0, "offset error {err:.2} counts");
    drop(ax);
    (b, wait)
}

/// A CSP move of `dist` units in 400 ms (smooth velocity profile) from the actual
/// position, then 200 ms hold; returns the largest |0x60F4| and the final error of the
/// shaft against the target, units.
fn csp_move(b: &mut Bench, dist: i32) -> (i32, f64) {
    b.track = false;
    let p0 = b.d.drive.cia402.position_actual();
    let true0 = b.true_position();
    let mut worst = 0;
    for k in 1..=600 {
        let x = (f64::from(k) / 400.0).min(1.0);
        // 0 → 1 with zero velocity at both ends.
        let s = x - (2.0 * std::f64::consts::PI * x).sin() / (2.0 * std::f64::consts::PI);
        let t = p0 + (f64::from(dist) * s).round() as i32;
        b.sdo_write(0x607A, 0, &t.to_le_bytes());
        b.run_ms(1);
        assert_eq!(b.state(), PdsState::OperationEnabled, "{} ms", b.now_ms());
        worst = worst.max(b.d.drive.cia402.following_error().abs());
    }
    let moved = b.true_position() - true0;
    (worst, moved - f64::from(dist))
}

#[test]
fn unaligned_enable_waits_in_switched_on_then_csp_follows() {
    for (wiggle, theta0) in [(false, 0.4), (true, -1.3)] {
        let (mut b, _) = enable_unaligned(wiggle, theta0);
        // No jump at the enable: the shaft holds where the alignment left it.
        let at_enable = b.true_position();
        b.run_ms(50);
        let drift = (b.true_position() - at_enable).abs();
        assert!(drift <= 2.0 * UNITS_PER_COUNT, "moved {drift:.1} units");
        // Half a revolution and back.
        for dist in [25_000, -25_000] {
            let (fe, miss) = csp_move(&mut b, dist);
            assert!(
                fe <= 250,
                "wiggle {wiggle}: following error up to {fe} units"
            );
            assert!(
                miss.abs() <= 2.0 * UNITS_PER_COUNT,
                "wiggle {wiggle}: ended {miss:.1} units off"
            );
        }
        assert!(b.emcy.is_empty(), "{:x?}", b.emcy);
        assert_eq!(b.d.drive.cia402.error_code(), 0);
        // Disabled and enabled again: the offset is kept, no second wait.
        b.track = true;
        b.controlword(0x0007, 5);
        assert_eq!(b.state(), PdsState::SwitchedOn);
        let from = b.log.len();
        b.controlword(0x000F, 3);
        assert_eq!(b.state(), PdsState::OperationEnabled);
        assert_eq!(
            b.log[from].statusword & 0x6F,
            0x27,
            "enabled in the first cycle"
        );
    }
}

#[test]
fn locked_rotor_fails_the_alignment_with_a_fault_and_never_reports_operation_enabled() {
    let axis = PlantAxis::with_plant(Motor::Ecn57_20, false, |p| p.locked = true);
    let mut b = Bench::new(axis, true);
    let from = b.enable(2000);
    assert_eq!(b.state(), PdsState::Fault);
    let ms = b.log.len() - from;
    assert!((640..=680).contains(&ms), "fault after {ms} ms");
    b.run_ms(500);
    for s in &b.log[from..] {
        assert_ne!(s.statusword & 0x6F, 0x27, "{} ms: Operation enabled", s.ms);
    }
    assert_eq!(b.d.drive.cia402.error_code(), 0x8611);
    assert_eq!(b.axis.borrow().commutation(), Commutation::Unaligned);
    assert_eq!(b.axis.borrow().commutation_failures(), 1);
    let codes: Vec<u16> = b.emcy.iter().map(|e| e.code).collect();
    assert_eq!(codes, vec![0x8611]);
    // Nothing driven after the fault.
    let last = b.log.last().copied().unwrap();
    assert!(last.ia.abs() < 0.05 && last.ib.abs() < 0.05, "{last:?}");
    // Fault reset and a new enable: the alignment runs again and fails again.
    b.controlword(0x0000, 2);
    b.controlword(0x0080, 5);
    b.controlword(0x0000, 5);
    assert_eq!(b.state(), PdsState::SwitchOnDisabled);
    let from = b.enable(2000);
    assert_eq!(b.state(), PdsState::Fault);
    assert!(b.log[from..].iter().all(|s| s.statusword & 0x6F != 0x27));
    assert_eq!(b.axis.borrow().commutation_failures(), 2);
}

#[test]
fn shutdown_during_the_alignment_abandons_it_and_leaving_op_is_no_fault() {
    let axis = PlantAxis::new_unaligned(Motor::Ecn57_20);
    let mut b = Bench::new(axis, false);
    b.controlword(0x0006, 5);
    b.controlword(0x0007, 5);
    b.controlword(0x000F, 100);
    assert_eq!(b.state(), PdsState::SwitchedOn);
    assert_eq!(b.axis.borrow().commutation(), Commutation::Aligning);
    assert!(b.d.drive.command().drive_enabled);
    assert!(!b.d.drive.drive_function_enabled());
    // Shutdown: Ready to switch on, the alignment abandoned, the bridges without current.
    b.controlword(0x0006, 20);
    assert_eq!(b.state(), PdsState::ReadyToSwitchOn);
    assert_eq!(b.axis.borrow().commutation(), Commutation::Unaligned);
    let last = b.log.last().copied().unwrap();
    assert!(last.ia.abs() < 0.05 && last.ib.abs() < 0.05, "{last:?}");
    // Enabled again: the whole alignment, then Operation enabled.
    let from = b.enable(2000);
    assert_eq!(b.state(), PdsState::OperationEnabled);
    let wait = b.log.len() - from - 1;
    assert!((250..=270).contains(&wait), "waited {wait} ms");
    // Disabled, re-enabled is immediate; a master leaving Op while the drive waits for
    // an alignment is not a fault (fresh axis).
    let axis = PlantAxis::new_unaligned(Motor::Ecn57_20);
    let mut b = Bench::new(axis, false);
    b.controlword(0x0006, 5);
    b.controlword(0x0007, 5);
    b.controlword(0x000F, 50);
    assert_eq!(b.state(), PdsState::SwitchedOn);
    b.d.on_state_change(EsmState::Op, EsmState::SafeOp);
    b.run_ms(20);
    assert_eq!(b.state(), PdsState::SwitchOnDisabled);
    assert!(b.emcy.is_empty(), "{:x?}", b.emcy);
    assert!(!b.d.drive.faults.any_active());
}

#[test]
fn open_loop_and_an_aligned_axis_do_not_wait() {
    // Open loop (0x2024 = 1) on an unaligned axis: no alignment, no wait.
    let axis = PlantAxis::new_unaligned(Motor::Ecn57_20);
    let mut b = Bench::new(axis, false);
    b.sdo_write(0x2024, 0, &[1]);
    b.run_ms(5);
    let from = b.enable(50);
    assert_eq!(b.state(), PdsState::OperationEnabled);
    assert_eq!(b.log.len() - from, 1, "enabled in the first cycle");
    assert_eq!(b.axis.borrow().commutation(), Commutation::Unaligned);
    // The aligned axis of the other tests (PlantAxis::new).
    let mut b = Bench::new(PlantAxis::new(Motor::Ecn57_20), false);
    let from = b.enable(50);
    assert_eq!(b.state(), PdsState::OperationEnabled);
    assert_eq!(b.log.len() - from, 1, "enabled in the first cycle");
    let (fe, miss) = csp_move(&mut b, 12_500);
    assert!(
        fe <= 250 && miss.abs() <= 2.0 * UNITS_PER_COUNT,
        "{fe} {miss}"
    );
}
