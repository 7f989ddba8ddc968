//! Benchmarks of the `firmware` area. Each call to [`crate::bench`] is one row of BENCHMARKS.md.

use core::hint::black_box;
use ecat_slave_stack::od::ObjectKey;
use firmware::cia402::{mode, Cia402, DriveFeedback};
use firmware::dictionary::Sdo;

pub fn run() {
    cia402();
    cia402_pp();
    product();
    motion();
    csp_cycle();
    supervision_tick();
}

/// CiA 402 rows: one control cycle of the drive profile from "outputs unpacked" to
/// "inputs packed" — the RxPDO values of the default CSP map stored through their
/// slots, the PDS / mode / supervision cycle with CSP interpolation, and the TxPDO
/// values of the default map read back. The servo step is not included (the lead adds
/// it in the composed drive).
fn cia402() {
    let mut d = Cia402::new();
    d.set_mode(mode::CSP);
    let mut fb = DriveFeedback::default();
    for w in [0x0000u16, 0x0006, 0x0007, 0x000F, 0x000F] {
        d.set_controlword(w);
        d.cycle(&fb, 0.001);
    }
    // Running at a steady speed: the axis follows the previous demand.
    let mut target = 0i32;
    for _ in 0..10 {
        target += 50;
        d.set_rx_raw(0, 0x000F);
        d.set_rx_raw(5, target as u32);
        let c = d.cycle(&fb, 0.001);
        fb.position = c.position;
        fb.velocity = c.velocity as i32;
    }
    target += 50;
    let fb = black_box(fb);
    let target = black_box(target);
    let out = crate::bench("CSP cycle (CiA 402 + interpolation)", || {
        // RxPDO 0x1600: 6040, 607A, 60B0, 60B8.
        d.set_rx_raw(0, 0x000F);
        d.set_rx_raw(5, target as u32);
        d.set_rx_raw(17, 0);
        d.set_rx_raw(19, 0);
        let c = d.cycle(&fb, 0.001);
        // TxPDO 0x1A00: 603F, 6041, 6061, 6064, 60B9, 60BA, 60FD.
        let mut acc = 0u32;
        for slot in [0u8, 1, 2, 5, 10, 11, 17] {
            acc = acc.wrapping_add(d.get_tx_raw(slot));
        }
        (c.position, acc)
    });
    black_box(out);
    black_box(&d);
}

/// PP cycle in the middle of a move (the on-line trapezoid with its square root), for
/// comparison with the CSP row.
fn cia402_pp() {
    let mut d = Cia402::new();
    d.set_mode(mode::PP);
    let mut fb = DriveFeedback::default();
    for w in [0x0000u16, 0x0006, 0x0007, 0x000F] {
        d.set_controlword(w);
        d.cycle(&fb, 0.001);
    }
    d.params.target_position = 1_000_000;
    d.set_controlword(0x003F);
    for _ in 0..50 {
        let c = d.cycle(&fb, 0.001);
        fb.position = c.position;
        fb.velocity = c.velocity as i32;
        d.set_controlword(0x002F);
    }
    let fb = black_box(fb);
    let out = crate::bench("PP cycle (CiA 402 + trapezoid)", || d.cycle(&fb, 0.001));
    black_box(out);
    black_box(&d);
}

/// Product rows: the per-cycle I/O and protection work (input filter + functions +
/// 0x60FD, the three fault checks, the LED pattern and output levels), the CRC-32 of
/// a 1 KiB record, and one 'save' of the vendor parameters to a RAM flash.
fn product() {
    use firmware::fault_led::FaultLed;
    use firmware::faults::{Faults, Snapshot};
    use firmware::identity::Variant;
    use firmware::io::{self, Inputs, OutputStatus};
    use firmware::params::{Params, P};
    use firmware::storage::{crc32, RamFlash, Scope, Storage};

    let params = Params::new(Variant::HybridServo);
    let mut inputs = Inputs::new();
    let mut faults = Faults::default();
    let mut led = FaultLed::new();
    faults.configure_from(&params);
    let raw = black_box(0b0_0101u8);
    let bus_mv = black_box(24_000u32);
    let (ia, ib, fe) = black_box((1500i32, -1200i32, 40i32));
    let now = black_box(1234u32);
    let out = crate::bench("product I/O + fault checks + LED (1 cycle)", || {
        inputs.update(raw, 1000, &params);
        let snap = Snapshot::default();
        faults.check_bus_voltage(bus_mv, snap, now);
        let pwm_off = faults.check_phase_currents(ia, ib, snap, now);
        faults.check_following_error(fe, params.get(P::FollowingErrorLimit) as u16, snap, now);
        let red = led.update(faults.led_code(), now);
        let st = OutputStatus {
            alarm: faults.alarm(),
            ready: !faults.any_active(),
            in_position: true,
            ..OutputStatus::default()
        };
        (
            inputs.digital_inputs_60fd(),
            pwm_off,
            red,
            io::output_levels(&params, st, (0, 0)),
        )
    });
    black_box(out);

    let record = black_box([0x5Au8; 1024]);
    black_box(crate::bench("CRC-32 of 1 KiB (nibble table)", || {
        crc32(&record)
    }));

    struct ParamsDict(Params);
    impl ecat_slave_stack::od::Dictionary for ParamsDict {
        fn objects(&self) -> &'static [ecat_slave_stack::od::Object] {
            static PARAMS: &[ecat_slave_stack::od::Object] = ecat_slave_stack::packed_dictionary!(
                &[firmware::params::OBJECTS],
                firmware::dictionary::VOCABULARY
            );
            PARAMS
        }
        fn read(
            &mut self,
            key: ObjectKey,
            b: &mut [u8],
        ) -> Result<usize, ecat_slave_stack::od::SdoAbort> {
            let ObjectKey { index: i, sub: s } = key;
            self.0.read(i, s, b)
        }
        fn write(
            &mut self,
            key: ObjectKey,
            d: &[u8],
            _: ecat_slave_stack::esm::EsmState,
        ) -> Result<(), ecat_slave_stack::od::SdoAbort> {
            let ObjectKey { index: i, sub: s } = key;
            self.0.write(i, s, d)
        }
    }
    let mut dict = ParamsDict(params);
    let mut flash = RamFlash::<2048>::new();
    let store = Storage::new(0, 1024);
    let r = crate::bench(
        "save vendor parameters (2 x 1 KiB slots, RAM flash)",
        || store.save(&mut flash, &mut dict, Scope::All),
    );
    black_box(r.is_ok());
}

/// Motion layer rows (`firmware::motion`): one closed-loop servo step in the middle of
/// a CSP cycle's interpolation (interpolation + position/velocity cascade + limits),
/// and the once-per-cycle hand-over of the CiA 402 set-point (units → counts).
fn motion() {
    use firmware::identity::Variant;
    use firmware::motion::Motion;
    use firmware::params::Params;

    let p = Params::new(Variant::HybridServo);
    let cfg = crate::setup::servo_config(&p);
    let mut m = Motion::new(cfg);
    let mut cmd = crate::setup::moving_command();
    let mut fb = crate::setup::AT_REST;
    // Running at one revolution per second: 50 units (4 counts) per 1 ms cycle.
    for k in 0..20 {
        cmd.position = 50 * k;
        m.set_command(&cmd, 0.001);
        for _ in 0..10 {
            let (d, f) = m.demand_counts();
            fb.position = d;
            fb.velocity = 4000.0 + f;
            m.step(&fb);
        }
    }
    cmd.position += 50;
    let c = black_box(cmd);
    crate::bench("motion set_command (per cycle, units -> counts)", || {
        m.set_command(&c, 0.001)
    });
    for _ in 0..4 {
        m.step(&fb);
    }
    let fb = black_box(fb);
    let out = crate::bench("servo step (motion layer)", || m.step(&fb));
    black_box(out);
}

/// The composed CSP cycle of issue 7 with the product's default maps (0x1600 / 0x1A00):
/// the RxPDO image unpacked into the [`firmware::drive::Drive`] through the compiled
/// copy plan, the drive cycle (PDS, CSP mode, supervision), the per-cycle motion
/// hand-over (units → counts, interpolation start) and one closed-loop servo step of
/// `firmware::motion::Motion`, and the TxPDO image packed. Drive enabled in Op, CSP,
/// moving at one revolution per second.
fn csp_cycle() {
    use ecat_slave_stack::esm::EsmState;
    use ecat_slave_stack::pdo::{self, PdoConfig};
    use ecat_slave_stack::slave::{CycleInfo, SlaveApplication};
    use ecat_slave_stack::sync::SyncMode;
    use firmware::drive::{AxisState, Drive};
    use firmware::motion::{Feedback, Motion};

    let mut d = csp_drive_in_op();
    let cfg = PdoConfig::new(firmware::pdo_defaults::PDO_DEFAULTS);
    let Ok(plan) = cfg.compile(&d, firmware::dictionary::OBJECTS) else {
        return;
    };
    let mcfg = crate::setup::servo_config(&d.params);
    let mut m = Motion::new(mcfg);
    let image = csp_rx_image;
    let mut inputs = [0u8; 64];
    let tx_len = (plan.tx.bytes() as usize).min(inputs.len());
    let mut fb = crate::setup::AT_REST;
    let mut target = 0i32;
    let mut now_us = 0u64;
    let mut info = move || {
        now_us += 1000;
        CycleInfo {
            state: EsmState::Op,
            outputs_fresh: true,
            mode: SyncMode::DcSync0,
            now_us,
        }
    };
    let mut one_cycle = |d: &mut Drive, m: &mut Motion, fb: &mut Feedback, out: &[u8; 12]| {
        pdo::unpack(&plan.rx, out, d);
        d.cycle(&info());
        let cmd = *d.command();
        m.set_command(&cmd, 0.001);
        let r = m.step(fb);
        pdo::pack(&plan.tx, d, &mut inputs[..tx_len]);
        r
    };
    for cw in [0x0000u16, 0x0006, 0x0007, 0x000F, 0x000F] {
        one_cycle(&mut d, &mut m, &mut fb, &image(cw, target));
    }
    // Steady motion: the axis follows the demand (50 units per 1 ms cycle).
    for _ in 0..20 {
        target += 50;
        one_cycle(&mut d, &mut m, &mut fb, &image(0x000F, target));
        let (pos, vel) = m.demand_counts();
        fb.position = pos;
        fb.velocity = 4000.0 + vel;
        d.set_axis(AxisState {
            position: target,
            ..AxisState::default()
        });
    }
    target += 50;
    let out = black_box(image(0x000F, target));
    let fb = black_box(fb);
    let last = black_box(info());
    let r = crate::bench(
        "CSP cycle (unpack → Drive cycle → motion servo step → pack)",
        || {
            pdo::unpack(&plan.rx, &out, &mut d);
            d.cycle(&last);
            let cmd = *d.command();
            m.set_command(&cmd, 0.001);
            let r = m.step(&fb);
            pdo::pack(&plan.tx, &d, &mut inputs[..tx_len]);
            r
        },
    );
    black_box(r);
    black_box(inputs);
    // The drive is enabled (statusword "operation enabled") in the measured cycle.
    black_box(d.cia402.statusword() & 0x6F == 0x27);
}

/// The drive of [`csp_cycle`]: in Op (through Pre-Op and Safe-Op), mode CSP.
fn csp_drive_in_op() -> firmware::drive::Drive {
    use ecat_slave_stack::esm::{EsmHooks, EsmState};
    let mut d = firmware::drive::Drive::new(firmware::identity::Variant::HybridServo, 1);
    for (from, to) in [
        (EsmState::Init, EsmState::PreOp),
        (EsmState::PreOp, EsmState::SafeOp),
        (EsmState::SafeOp, EsmState::Op),
    ] {
        d.on_state_change(from, to);
    }
    d.cia402.set_mode(mode::CSP);
    d
}

/// The RxPDO image of the default map 0x1600: 6040 (2 B), 607A (4 B), 60B0 (4 B),
/// 60B8 (2 B).
fn csp_rx_image(cw: u16, target: i32) -> [u8; 12] {
    let mut b = [0u8; 12];
    b[0..2].copy_from_slice(&cw.to_le_bytes());
    b[2..6].copy_from_slice(&target.to_le_bytes());
    b
}

/// The supervision tick of the drive's own clock (`Drive::tick`: input filter,
/// protections, monitoring and, with no master cycle in the last 900 µs, the control
/// step: PDS, stop ramps, generators), in Op with the master silent: idle (Operation
/// enabled in PV at standstill) and during the fault reaction after the master's
/// commands stopped (0x6007 = 1: the quick-stop ramp from 1 rev/s).
fn supervision_tick() {
    use ecat_slave_stack::al_status::AlStatusCode;
    use ecat_slave_stack::esm::{EsmHooks, EsmState};
    use ecat_slave_stack::slave::SlaveApplication;
    use firmware::cia402::pds::PdsState;
    use firmware::drive::{AxisState, Drive};
    use firmware::identity::Variant;

    let mut d = Drive::new(Variant::HybridServo, 1);
    for (from, to) in [
        (EsmState::Init, EsmState::PreOp),
        (EsmState::PreOp, EsmState::SafeOp),
        (EsmState::SafeOp, EsmState::Op),
    ] {
        d.on_state_change(from, to);
    }
    let axis = AxisState {
        bus_mv: 48_000,
        ..AxisState::default()
    };
    d.set_axis(axis);
    d.cia402.set_mode(mode::PV);
    let mut now_us = 0u64;
    for cw in [0x0000u16, 0x0006, 0x0007, 0x000F, 0x000F] {
        d.cia402.set_controlword(cw);
        now_us += 1000;
        d.tick(now_us, 0);
    }
    now_us += 1000;
    let now = black_box(now_us);
    crate::bench("supervision tick (Op, enabled, idle, control step)", || {
        d.tick(now, 0)
    });
    black_box(d.cia402.state() == PdsState::OperationEnabled);
    // Moving at 1 rev/s (50 000 units/s), then the SM watchdog: the fault reaction.
    d.cia402.params.target_velocity = 50_000;
    for _ in 0..200 {
        now_us += 1000;
        d.set_axis(AxisState {
            velocity: d.command().velocity as i32,
            ..axis
        });
        d.tick(now_us, 0);
    }
    d.on_outputs_lost(AlStatusCode::SmWatchdog);
    for _ in 0..3 {
        now_us += 1000;
        d.tick(now_us, 0);
    }
    now_us += 1000;
    let now = black_box(now_us);
    crate::bench("supervision tick (fault reaction ramp)", || d.tick(now, 0));
    black_box(d.cia402.state() == PdsState::FaultReactionActive);
}
