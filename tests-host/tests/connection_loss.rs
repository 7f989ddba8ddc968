//! Connection loss and faults without frames (issue 15), through the real slave
//! runtime and the simulated ESC, with the product drive (`sim_drive::segment_with`,
//! one drive on the electrical plant [`PlantAxis`]).
//!
//! The test is the master: it acts through ECAT-side register and RAM accesses of the
//! ESC simulator (as `slave_runtime_sim.rs` does): mailbox SyncManagers for SDO,
//! 3-buffer process data (0x1600 remapped to controlword, 0x607A, 0x60FF; 0x1A00 as
//! delivered), AL control, the SM2 watchdog and DC SYNC0. Until the loss it writes the
//! outputs every millisecond; from the loss on it does nothing at all — simulated time
//! moves on only through [`sim_drive::advance`], which runs the drive's 1 ms tick
//! (the board's main loop). Every reaction asserted below therefore runs on the drive's
//! own clock; the segment's frame counter stays 0 throughout (no frame is ever sent).
//!
//! **Matrix** (one `#[test]` per mode, so that they run in parallel): every mode (PP,
//! PV, HM, CSP, CSV, CST) × every 0x6007 option (0-3) × every loss (the master stops → SM2
//! watchdog 0x001B; the master requests Safe-Op; the master requests Init; SYNC0 stops
//! in DC mode → 0x002C). The axis moves when the loss happens. Checked per case: the
//! reaction starts within one tick of the detection; the stop takes |v|/0x6085 (the
//! default 0x605A / 0x605E = 2 use 0x6085, configured to 1 500 000 inc/s²) within one
//! tick, or the power goes off within one tick (0x6007 = 2), or the drive keeps its
//! last set-points (0x6007 = 0); power stage, power permission and brake; position
//! drift over 2 s (0x6064 and the true shaft position, ≤ 1 encoder count); in CST the
//! axis runs at its speed limit (0x6080 = the matrix speed, 0x6071 = 20 % of the rated
//! torque on the free shaft), the stops are the same ramps; 0x6041 and
//! 0x603F read over SDO as the master would (after Init: back to Pre-Op first); the
//! emergencies (read from SM1; for Init, where the mailbox is off, taken from the drive
//! directly, see [`Master::lose`]).
//!
//! **Faults without frames**: bus over-voltage, a phase short (over-current), a load
//! the servo cannot hold (following error), injected into the plant while the drive is
//! enabled, the ESM in Op with the SM2 watchdog switched off (0x0420 = 0) and the
//! master silent.
//!
//! Distances in command units (50 000 per revolution); one encoder count is 12.5.

use std::cell::RefCell;
use std::rc::Rc;

use ecat_slave_stack::diag::DiagMessage;
use ecat_slave_stack::leds::Pattern;
use ecat_slave_stack::od::{Dictionary, ObjectKey};
use ecat_slave_stack::registers as reg;
use firmware::cia402::pds::PdsState;
use tests_host::esc_sim::{Flavour, Side};
use tests_host::segment::Segment;
use tests_host::sim_axis::{PlantAxis, SharedPlant};
use tests_host::sim_drive::{self, AxisModel, Motor, SimDrive, SimDriveConfig};

/// 1 ms in ns.
const MS: u64 = 1_000_000;
/// Observation step after the loss, ns (the drive's tick is 1 ms).
const STEP: u64 = 100_000;
/// One encoder count in command units (4000 counts, 50 000 units per revolution).
const COUNT: f64 = 12.5;
/// 0x6085 quick-stop deceleration configured for the matrix, inc/s².
const QS_DEC: u32 = 1_500_000;
/// Speed of the axis at the loss (PP, PV, CSP, CSV), inc/s.
const SPEED: i32 = 100_000;
/// Homing search speed 0x6099:01, inc/s.
const HOMING_SPEED: i32 = 50_000;

// ---- the master ------------------------------------------------------------------

/// One CoE emergency.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Emcy {
    code: u16,
    register: u8,
    data: [u8; 5],
}

/// The process inputs of 0x1A00.
#[derive(Debug, Clone, Copy, Default)]
struct Inputs {
    error_code: u16,
    statusword: u16,
    position: i32,
}

/// What the master writes each cycle: a set-point generator.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Gen {
    /// Fixed outputs.
    Fixed,
    /// CSP: the target moves with a velocity that ramps to `goal` at `acc`.
    Position { goal: f64, acc: f64 },
    /// CSV: 0x60FF ramps to `goal` at `acc`.
    Velocity { goal: f64, acc: f64 },
}

/// The test as the EtherCAT master of one simulated product drive.
struct Master {
    seg: Segment<SimDrive>,
    plant: Rc<RefCell<PlantAxis>>,
    /// Mailbox counter of the next request (1..=7).
    counter: u8,
    /// Emergencies received from SM1 (and, for Init, taken from the drive).
    emcy: Vec<Emcy>,
    /// The master writes the outputs every millisecond.
    cyclic: bool,
    next_cycle_ns: u64,
    cw: u16,
    target: i32,
    velocity: i32,
    gen: Gen,
    gen_pos: f64,
    gen_vel: f64,
    inputs: Inputs,
    /// Bytes of the outputs (SM2).
    out_len: usize,
    /// SM2 control byte (0x64: 3-buffer, watchdog trigger; 0x24: without).
    sm2_control: u8,
}

impl Master {
    /// A powered-up drive on the electrical plant (the test shares the plant to inject
    /// faults and read the true shaft).
    fn new() -> Master {
        let cfg = SimDriveConfig {
            motor: Motor::Ecn57_20,
            flavour: Flavour::Lan9252,
            flash_file: None,
            dips: tests_host::sim_drive::DIPS_ALL_ON,
        };
        let mut seg = sim_drive::segment_with(&cfg, 1, AxisModel::Plant).expect("segment");
        let plant = Rc::new(RefCell::new(PlantAxis::new(Motor::Ecn57_20)));
        // Limit switches out of the way of the long runs (the home switch stays at
        // 20 000..30 000 for homing).
        plant.borrow_mut().switches.limit_neg = -1.0e9;
        plant.borrow_mut().switches.limit_pos = 1.0e9;
        {
            let d = &mut seg.drive_mut(0).app;
            d.axis = Box::new(SharedPlant(plant.clone()));
            d.axis.parameters(&d.drive.params);
        }
        Master {
            seg,
            plant,
            counter: 1,
            emcy: Vec::new(),
            cyclic: false,
            next_cycle_ns: 0,
            cw: 0,
            target: 0,
            velocity: 0,
            gen: Gen::Fixed,
            gen_pos: 0.0,
            gen_vel: 0.0,
            inputs: Inputs::default(),
            out_len: 10,
            sm2_control: 0x64,
        }
    }

    fn app(&mut self) -> &mut SimDrive {
        &mut self.seg.drive_mut(0).app
    }
    fn now_ns(&self) -> u64 {
        self.seg.now_ns()
    }
    fn ecat_write(&self, addr: u16, data: &[u8]) -> bool {
        self.seg.esc(0).side_write(Side::Ecat, addr, data)
    }
    fn ecat_read(&self, addr: u16, buf: &mut [u8]) -> bool {
        self.seg.esc(0).side_read(Side::Ecat, addr, buf)
    }
    fn al(&self) -> (u16, u16) {
        self.seg.al_status(0)
    }

    /// One master cycle: outputs to SM2, inputs from SM3.
    fn exchange(&mut self) {
        match self.gen {
            Gen::Fixed => {}
            Gen::Position { goal, acc } => {
                self.gen_vel = approach(self.gen_vel, goal, acc * 1e-3);
                self.gen_pos += self.gen_vel * 1e-3;
                self.target = self.gen_pos.round() as i32;
            }
            Gen::Velocity { goal, acc } => {
                self.gen_vel = approach(self.gen_vel, goal, acc * 1e-3);
                self.velocity = self.gen_vel.round() as i32;
            }
        }
        let mut out = [0u8; 10];
        out[..2].copy_from_slice(&self.cw.to_le_bytes());
        out[2..6].copy_from_slice(&self.target.to_le_bytes());
        out[6..10].copy_from_slice(&self.velocity.to_le_bytes());
        assert!(self.ecat_write(0x1100, &out[..self.out_len]), "SM2 write");
        let mut inp = [0u8; 19];
        if self.ecat_read(0x1400, &mut inp) {
            self.inputs = Inputs {
                error_code: u16::from_le_bytes([inp[0], inp[1]]),
                statusword: u16::from_le_bytes([inp[2], inp[3]]),
                position: i32::from_le_bytes([inp[5], inp[6], inp[7], inp[8]]),
            };
        }
    }

    /// Simulated time moves on by `ns`; while cyclic, the master exchanges process
    /// data every millisecond.
    fn wait(&mut self, ns: u64) {
        let end = self.now_ns() + ns;
        while self.now_ns() < end {
            if self.cyclic && self.now_ns() >= self.next_cycle_ns {
                self.exchange();
                self.next_cycle_ns = self.now_ns() + MS;
            }
            let dt = STEP.min(end - self.now_ns());
            sim_drive::advance(&mut self.seg, dt);
        }
    }

    fn start_cyclic(&mut self) {
        self.cyclic = true;
        self.next_cycle_ns = self.now_ns();
    }

    /// AL control `state`; waits (≤ `timeout_ms`) until the AL status shows it or an
    /// error. Returns (AL status, AL status code).
    fn request(&mut self, state: u16, timeout_ms: u64) -> (u16, u16) {
        self.ecat_write(reg::AL_CONTROL.addr(), &state.to_le_bytes());
        for _ in 0..timeout_ms * 10 {
            self.wait(STEP);
            let (s, c) = self.al();
            if s & 0x0F == state || s & 0x10 != 0 {
                return (s, c);
            }
        }
        self.al()
    }

    /// SM0 / SM1 as the standard mailbox (SOEM style, one write).
    fn mailboxes(&self) {
        let mut b = [0u8; 16];
        b[..8].copy_from_slice(&[0x00, 0x10, 0x80, 0x00, 0x26, 0x00, 0x01, 0x00]);
        b[8..].copy_from_slice(&[0x80, 0x10, 0x80, 0x00, 0x22, 0x00, 0x01, 0x00]);
        self.ecat_write(reg::sm_register(0), &b);
    }

    /// SM2 (outputs) and SM3 (inputs of 0x1A00, 19 bytes).
    fn process_data_sms(&self) {
        let len = self.out_len as u8;
        let c = self.sm2_control;
        self.ecat_write(reg::sm_register(2), &[0x00, 0x11, len, 0, c, 0, 1, 0]);
        self.ecat_write(reg::sm_register(3), &[0x00, 0x14, 19, 0, 0x20, 0, 1, 0]);
    }

    /// One CoE SDO request; returns the SDO response bytes (from the command
    /// specifier on). Emergencies that arrive meanwhile are collected.
    fn sdo(&mut self, sdo: [u8; 8]) -> [u8; 8] {
        let mut buf = [0u8; 128];
        buf[..6].copy_from_slice(&[10, 0, 0, 0, 0, (self.counter << 4) | 3]);
        buf[6..8].copy_from_slice(&[0x00, 0x20]);
        buf[8..16].copy_from_slice(&sdo);
        self.counter = if self.counter >= 7 {
            1
        } else {
            self.counter + 1
        };
        assert!(self.ecat_write(0x1000, &buf), "SM0 accepts the request");
        for _ in 0..500 {
            self.wait(STEP);
            let mut st = [0u8; 1];
            self.ecat_read(reg::sm_register(1) + reg::sm::STATUS, &mut st);
            if st[0] & 0x08 == 0 {
                continue;
            }
            let mut out = [0u8; 128];
            assert!(self.ecat_read(0x1080, &mut out));
            let service = u16::from_le_bytes([out[6], out[7]]) >> 12;
            if out[5] & 0x0F == 3 && service == 1 {
                let mut data = [0u8; 5];
                data.copy_from_slice(&out[11..16]);
                self.emcy.push(Emcy {
                    code: u16::from_le_bytes([out[8], out[9]]),
                    register: out[10],
                    data,
                });
                continue;
            }
            let mut r = [0u8; 8];
            r.copy_from_slice(&out[8..16]);
            return r;
        }
        panic!(
            "no SDO answer for {sdo:02x?} within 50 ms (AL {:x?})",
            self.al()
        );
    }

    /// Expedited SDO upload (≤ 4 bytes), value zero-extended; Err = abort code.
    fn sdo_read(&mut self, index: u16, sub: u8) -> Result<u32, u32> {
        let i = index.to_le_bytes();
        let r = self.sdo([0x40, i[0], i[1], sub, 0, 0, 0, 0]);
        let v = u32::from_le_bytes([r[4], r[5], r[6], r[7]]);
        match r[0] {
            0x80 => Err(v),
            c if c & 0x43 == 0x43 => {
                let n = 4 - usize::from((c >> 2) & 3);
                Ok(if n == 4 { v } else { v & ((1 << (8 * n)) - 1) })
            }
            c => panic!("{index:04x}:{sub}: unexpected SDO answer {c:#04x}"),
        }
    }

    /// Expedited SDO download (1, 2 or 4 bytes); Err = abort code.
    fn sdo_write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), u32> {
        let i = index.to_le_bytes();
        let cmd = 0x23 | (((4 - data.len()) as u8) << 2);
        let mut req = [cmd, i[0], i[1], sub, 0, 0, 0, 0];
        req[4..4 + data.len()].copy_from_slice(data);
        let r = self.sdo(req);
        match r[0] {
            0x60 => Ok(()),
            0x80 => Err(u32::from_le_bytes([r[4], r[5], r[6], r[7]])),
            c => panic!("{index:04x}:{sub}: unexpected SDO answer {c:#04x}"),
        }
    }

    fn sdo_set(&mut self, index: u16, sub: u8, data: &[u8]) {
        if let Err(a) = self.sdo_write(index, sub, data) {
            panic!("SDO write {index:04x}:{sub} = {data:02x?}: abort {a:#010x}");
        }
    }

    /// Init → Pre-Op with the mailbox; waits for the power-up self-test (auto-tune).
    fn go_pre_op(&mut self) {
        self.mailboxes();
        assert_eq!(self.request(2, 20), (0x02, 0), "Init → Pre-Op");
        for _ in 0..1000 {
            if self.app().drive.cia402.state() == PdsState::SwitchOnDisabled {
                return;
            }
            self.wait(MS);
        }
        panic!("power-up self-test not over after 1 s");
    }

    /// Outputs mapping 0x1600 = controlword, target position, target velocity.
    fn map_outputs(&mut self) {
        self.sdo_set(0x1600, 0, &[0]);
        self.sdo_set(0x1600, 1, &0x6040_0010u32.to_le_bytes());
        self.sdo_set(0x1600, 2, &0x607A_0020u32.to_le_bytes());
        self.sdo_set(0x1600, 3, &0x60FF_0020u32.to_le_bytes());
        self.sdo_set(0x1600, 0, &[3]);
        self.out_len = 10;
    }

    /// Pre-Op → Safe-Op → Op with cyclic exchange (DC SYNC0 at 1 ms if `dc`).
    fn go_op(&mut self, dc: bool) {
        self.process_data_sms();
        if dc {
            self.ecat_write(reg::DC_SYNC0_CYCLE.addr(), &(MS as u32).to_le_bytes());
            let start = self.seg.esc(0).system_time() + 2 * MS;
            self.ecat_write(reg::DC_START_TIME.addr(), &start.to_le_bytes());
            self.ecat_write(reg::DC_ACTIVATION.addr(), &[0x03]);
        }
        assert_eq!(self.request(4, 20), (0x04, 0), "Pre-Op → Safe-Op");
        self.cw = 0;
        self.target = self.app().drive.cia402.position_actual();
        self.start_cyclic();
        self.wait(5 * MS);
        assert_eq!(self.request(8, 100), (0x08, 0), "Safe-Op → Op (dc {dc})");
        self.wait(5 * MS);
    }

    /// Shutdown, switch on, enable operation (process data), holding the position.
    fn enable(&mut self) {
        let here = self.app().drive.cia402.position_actual();
        self.target = here;
        self.gen_pos = f64::from(here);
        for cw in [0x0006, 0x0007, 0x000F] {
            self.cw = cw;
            self.wait(10 * MS);
        }
        assert_eq!(
            self.app().drive.cia402.state(),
            PdsState::OperationEnabled,
            "enable: statusword {:#06x}",
            self.inputs.statusword
        );
    }

    /// Reads the drive's state directly (not a master access).
    fn snap(&mut self) -> Snap {
        let plant_vel = self.plant.borrow().rig.plant.omega / (2.0 * std::f64::consts::PI)
            * 50_000.0
            * if self.plant.borrow().motion.config().reverse {
                -1.0
            } else {
                1.0
            };
        let true_pos = self.plant.borrow().true_position();
        let d = &mut self.app().drive;
        Snap {
            t_ns: 0,
            state: d.cia402.state(),
            statusword: d.cia402.statusword(),
            error_code: d.cia402.error_code(),
            v_demand: d.cia402.velocity_demand(),
            position: d.cia402.position_actual(),
            power_stage: d.command().power_stage,
            power_permission: d.power_permission(),
            brake_released: d.outputs().1,
            true_pos,
            true_vel: plant_vel,
        }
        .at(self.now_ns())
    }
}

fn approach(v: f64, goal: f64, dv: f64) -> f64 {
    if (goal - v).abs() <= dv {
        goal
    } else {
        v + dv * (goal - v).signum()
    }
}

/// The drive as seen at one instant.
#[derive(Debug, Clone, Copy)]
struct Snap {
    t_ns: u64,
    state: PdsState,
    statusword: u16,
    error_code: u16,
    v_demand: i32,
    position: i32,
    power_stage: bool,
    power_permission: bool,
    brake_released: bool,
    true_pos: f64,
    true_vel: f64,
}

impl Snap {
    fn at(mut self, t: u64) -> Snap {
        self.t_ns = t;
        self
    }
}

/// Fault (0x4F mask = 0x08), Switch on disabled (0x40), Operation enabled (0x6F = 0x27).
fn sw_fault(sw: u16) -> bool {
    sw & 0x4F == 0x08
}
fn sw_disabled(sw: u16) -> bool {
    sw & 0x4F == 0x40
}
fn sw_enabled(sw: u16) -> bool {
    sw & 0x6F == 0x27
}

// ---- the matrix -------------------------------------------------------------------

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Pp,
    Pv,
    Hm,
    Csp,
    Csv,
    Cst,
}

impl Mode {
    fn code(self) -> i8 {
        match self {
            Mode::Pp => 1,
            Mode::Pv => 3,
            Mode::Hm => 6,
            Mode::Csp => 8,
            Mode::Csv => 9,
            Mode::Cst => 10,
        }
    }
    fn speed(self) -> i32 {
        if self == Mode::Hm {
            HOMING_SPEED
        } else {
            SPEED
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Loss {
    /// The master stops sending: the SM2 watchdog (100 ms) trips, 0x001B.
    MasterStops,
    /// The master requests Safe-Op.
    SafeOp,
    /// The master requests Init.
    Init,
    /// DC mode; SYNC0 is switched off and the master falls silent: 0x002C.
    Sync0Stops,
}

const LOSSES: [Loss; 4] = [
    Loss::MasterStops,
    Loss::SafeOp,
    Loss::Init,
    Loss::Sync0Stops,
];

impl Loss {
    /// The emergency code of the loss (0x6007 = 1..3).
    fn emergency(self) -> u16 {
        match self {
            Loss::MasterStops | Loss::Sync0Stops => 0x8700,
            Loss::SafeOp => 0xA001,
            Loss::Init => 0xA000,
        }
    }
}

impl Master {
    /// A drive in Op, Operation enabled in `mode`, moving; 0x6007 = `option`.
    fn moving(mode: Mode, option: i16, dc: bool) -> Master {
        let mut m = Master::new();
        m.go_pre_op();
        m.map_outputs();
        m.sdo_set(0x6007, 0, &option.to_le_bytes());
        m.sdo_set(0x6085, 0, &QS_DEC.to_le_bytes());
        m.sdo_set(0x6060, 0, &[mode.code() as u8]);
        match mode {
            Mode::Pp => {
                m.sdo_set(0x6081, 0, &(SPEED as u32).to_le_bytes());
                m.sdo_set(0x6083, 0, &2_000_000u32.to_le_bytes());
                m.sdo_set(0x6084, 0, &2_000_000u32.to_le_bytes());
            }
            Mode::Pv => m.sdo_set(0x6083, 0, &2_000_000u32.to_le_bytes()),
            Mode::Hm => {
                // Home switch (IN1, 20 000..30 000): method 19 searches in the positive
                // direction from 0 at 0x6099:01.
                m.sdo_set(0x6098, 0, &[19]);
                m.sdo_set(0x6099, 1, &(HOMING_SPEED as u32).to_le_bytes());
                m.sdo_set(0x609A, 0, &2_000_000u32.to_le_bytes());
            }
            Mode::Csp | Mode::Csv => {}
            Mode::Cst => {
                // The free shaft runs up to the speed limit and is held there.
                m.sdo_set(0x6080, 0, &(SPEED as u32).to_le_bytes());
                m.sdo_set(0x6071, 0, &200i16.to_le_bytes());
            }
        }
        m.go_op(dc);
        m.enable();
        let v = f64::from(SPEED);
        match mode {
            Mode::Pp => {
                m.target = m.target.wrapping_add(2_000_000);
                m.cw = 0x001F;
                m.wait(5 * MS);
                assert!(
                    m.inputs.statusword & 0x1000 != 0,
                    "PP set-point acknowledged"
                );
                m.cw = 0x000F;
            }
            Mode::Pv => m.velocity = SPEED,
            Mode::Hm => m.cw = 0x001F,
            Mode::Csp => {
                m.gen = Gen::Position {
                    goal: v,
                    acc: 2_000_000.0,
                }
            }
            Mode::Csv => {
                m.gen = Gen::Velocity {
                    goal: v,
                    acc: 2_000_000.0,
                }
            }
            Mode::Cst => {}
        }
        m.wait(140 * MS);
        let before = m.snap();
        m.wait(10 * MS);
        let s = m.snap();
        let want = f64::from(mode.speed());
        let shaft_speed = (s.true_pos - before.true_pos) / 0.01;
        assert!(
            (f64::from(s.v_demand) - want).abs() < 0.01 * want
                && (shaft_speed - want).abs() < 0.05 * want,
            "{mode:?}: moving at {want} before the loss: shaft at {shaft_speed:.0} inc/s, {s:?}"
        );
        // What the master sees in its inputs (0x1A00) just before the loss.
        let i = m.inputs;
        assert!(
            sw_enabled(i.statusword)
                && i.error_code == 0
                && (i.position - s.position).unsigned_abs() < 1000,
            "{mode:?}: inputs before the loss {i:?} (drive at {})",
            s.position
        );
        m
    }

    /// The loss happens now. From here on the master does nothing. Returns the
    /// instant the drive's runtime detected it (ns).
    ///
    /// Safe-Op / Init: the AL control request is written and the runtime polled once
    /// at this instant (the PDI interrupt of the request): detection = now. For Init
    /// the emergency is taken from the drive right there — in Init the mailbox is off
    /// and the runtime drops its queue when the mailbox restarts, so no master can
    /// receive it; the drive must still have produced it.
    fn lose(&mut self, loss: Loss) -> u64 {
        self.cyclic = false;
        match loss {
            Loss::MasterStops | Loss::Sync0Stops => {
                if loss == Loss::Sync0Stops {
                    self.ecat_write(reg::DC_ACTIVATION.addr(), &[0x00]);
                }
                let code = if loss == Loss::MasterStops {
                    0x001B
                } else {
                    0x002C
                };
                for _ in 0..2000 {
                    sim_drive::advance(&mut self.seg, STEP);
                    if self.al() == (0x14, code) {
                        return self.now_ns();
                    }
                }
                panic!("{loss:?}: AL status {:x?} after 200 ms", self.al());
            }
            Loss::SafeOp | Loss::Init => {
                let state = if loss == Loss::SafeOp { 4u16 } else { 1 };
                self.ecat_write(reg::AL_CONTROL.addr(), &state.to_le_bytes());
                self.seg.poll_all();
                assert_eq!(self.al(), (state, 0), "{loss:?} request");
                if loss == Loss::Init {
                    while let Some(e) = self.app().drive.pop_emergency() {
                        self.emcy.push(Emcy {
                            code: e.code,
                            register: e.register,
                            data: e.data,
                        });
                    }
                }
                self.now_ns()
            }
        }
    }

    /// Advances (only `sim_drive::advance`) until `done` holds, at most `max_ns`.
    fn advance_until(&mut self, max_ns: u64, done: impl Fn(&Snap) -> bool) -> Option<Snap> {
        let end = self.now_ns() + max_ns;
        while self.now_ns() < end {
            sim_drive::advance(&mut self.seg, STEP);
            let s = self.snap();
            if done(&s) {
                return Some(s);
            }
        }
        None
    }

    fn advance_ns(&mut self, ns: u64) {
        let end = self.now_ns() + ns;
        while self.now_ns() < end {
            let dt = STEP.min(end - self.now_ns());
            sim_drive::advance(&mut self.seg, dt);
        }
    }
}

/// What a case found (for the summary line).
struct Outcome {
    stop_ms: Option<f64>,
    drift_counts: f64,
}

fn run_case(mode: Mode, option: i16, loss: Loss) -> Outcome {
    let case = format!(
        "{mode:?} (0x6060 = {}) × 0x6007 = {option} × {loss:?}",
        mode.code()
    );
    let mut m = Master::moving(mode, option, loss == Loss::Sync0Stops);
    let frames_before = m.seg.frames();
    let before_loss = m.snap();
    let t_detect = m.lose(loss);
    let at_detect = m.snap();
    // The first tick after the detection (the drive ticks on whole milliseconds; an
    // AL request handled at a whole millisecond comes after that millisecond's tick,
    // a watchdog or SYNC0 loss found by the poll of `advance` before it).
    let t_tick = match loss {
        Loss::SafeOp | Loss::Init => (t_detect / MS + 1) * MS,
        _ => t_detect.div_ceil(MS) * MS,
    };
    let v0 = f64::from(at_detect.v_demand.unsigned_abs());
    let moving = |s: &Snap| matches!(s.state, PdsState::OperationEnabled);
    let mut outcome = Outcome {
        stop_ms: None,
        drift_counts: 0.0,
    };

    match option {
        0 => {
            // No action: the drive keeps its state and last set-points.
            m.advance_ns(2 * MS);
            let s = m.snap();
            assert!(
                moving(&s) && s.power_permission && s.brake_released,
                "{case}: 0x6007 = 0 keeps Operation enabled, power on, brake released: {s:?}"
            );
            if mode == Mode::Csp {
                // CSP runs on for at most one period after its last set-point, then
                // holds: at rest by now, holding in closed loop.
                assert_eq!(s.v_demand, 0, "{case}: CSP holds after one period: {s:?}");
            }
        }
        1 | 3 => {
            let stopping = if option == 1 {
                PdsState::FaultReactionActive
            } else {
                PdsState::QuickStopActive
            };
            if v0 > 0.0 {
                assert_eq!(
                    at_detect.state, stopping,
                    "{case}: reaction state at the detection"
                );
            }
            let end = if option == 1 {
                PdsState::Fault
            } else {
                PdsState::SwitchOnDisabled
            };
            // The ramp starts at the first tick after the detection.
            let first = m
                .advance_until(2 * MS, |s| s.t_ns >= t_tick)
                .expect("first tick");
            // A loss found on a whole millisecond is reacted to in that very tick
            // (the snapshot at the detection already shows the first ramp step): then
            // the ramp must have left the speed before the loss.
            let v_first = f64::from(first.v_demand.unsigned_abs());
            let same_tick =
                t_tick == t_detect && v_first < f64::from(before_loss.v_demand.unsigned_abs());
            assert!(
                v0 == 0.0 || first.state == end || v_first < v0 || same_tick,
                "{case}: the stop ramp starts at the first tick after the detection ({} µs \
                 later): velocity demand still {} at the tick, {first:?}",
                (t_tick - t_detect) / 1000,
                first.v_demand
            );
            let done = m
                .advance_until(2000 * MS, |s| s.state == end)
                .unwrap_or_else(|| panic!("{case}: no {end:?} within 2 s: {:?}", m.snap()));
            let took = (done.t_ns - t_detect) as f64 * 1e-6;
            let expected = v0 / f64::from(QS_DEC) * 1e3;
            assert!(
                (took - expected).abs() <= 1.0,
                "{case}: stop on the 0x6085 ramp from {v0} inc/s at {QS_DEC} inc/s² takes \
                 {expected:.1} ms, took {took:.1} ms from the detection (state {:?} at {} ms)",
                done.state,
                done.t_ns / 1000 / 1000
            );
            outcome.stop_ms = Some(took);
            assert!(
                !done.power_stage && !done.power_permission && !done.brake_released,
                "{case}: after the stop power off and brake engaged: {done:?}"
            );
        }
        2 => {
            // Already off in the snapshot at the detection, or at a later step.
            let off = Some(at_detect)
                .filter(|s| !s.power_permission)
                .or_else(|| m.advance_until(2 * MS, |s| !s.power_permission))
                .unwrap_or_else(|| panic!("{case}: power still on 2 ms after the detection"));
            assert!(
                off.t_ns <= t_tick && off.t_ns - t_detect <= MS,
                "{case}: 0x6007 = 2 cuts the power at the first tick ({} µs after the \
                 detection)",
                (off.t_ns - t_detect) / 1000
            );
            assert!(
                off.state == PdsState::SwitchOnDisabled && !off.power_stage && !off.brake_released,
                "{case}: disable voltage: Switch on disabled, power off, brake engaged: {off:?}"
            );
            outcome.stop_ms = Some((off.t_ns - t_detect) as f64 * 1e-6);
        }
        _ => unreachable!(),
    }

    // Settle, then 2 s of drift (closed loop holding, or power off at rest).
    let keeps_moving = option == 0 && matches!(mode, Mode::Pp | Mode::Pv | Mode::Csv | Mode::Cst);
    if option == 0 && mode == Mode::Hm {
        // No action: the homing search goes on on the drive's clock and finishes
        // (attained: bits 12 and 10) at the home switch, 20 000 inc ahead.
        let attained = m.advance_until(3000 * MS, |s| s.statusword & 0x1400 == 0x1400);
        assert!(
            attained.is_some_and(|s| s.statusword & 0x2000 == 0),
            "{case}: with 0x6007 = 0 the homing goes on to the end without frames: {:?}",
            m.snap()
        );
    }
    let settle = if option == 2 { 150 * MS } else { 50 * MS };
    m.advance_ns(settle);
    let a = m.snap();
    m.advance_ns(2000 * MS);
    let b = m.snap();
    let drift_units = f64::from(b.position.wrapping_sub(a.position));
    let drift_true = b.true_pos - a.true_pos;
    outcome.drift_counts = drift_true.abs() / COUNT;
    if keeps_moving {
        let want = 2.0 * f64::from(mode.speed());
        assert!(
            drift_true > 0.9 * want && moving(&b),
            "{case}: with 0x6007 = 0 the drive keeps its last set-points, so the axis keeps \
             moving ({want} expected over 2 s): moved {drift_true:.0}, {b:?}"
        );
    } else {
        assert!(
            drift_units.abs() <= COUNT.ceil() && drift_true.abs() <= COUNT,
            "{case}: drift over 2 s ≤ 1 count: 0x6064 {drift_units}, shaft {drift_true:.2} \
             ({a:?} → {b:?})"
        );
    }
    let end_state = b;
    let expect_power = option == 0;
    assert_eq!(
        (end_state.power_permission, end_state.brake_released),
        (expect_power, expect_power),
        "{case}: power permission / brake released 2 s later: {end_state:?}"
    );
    assert_eq!(
        m.seg.frames(),
        frames_before,
        "{case}: no frame after the loss"
    );

    // The master comes back and reads 0x6041 / 0x603F over SDO.
    let al = m.al();
    // (In Safe-Op the runtime keeps supervising the SM2 watchdog once outputs were
    // seen: the silent master's Safe-Op ends as Safe-Op + error 0x001B 100 ms later.)
    let expected_al = match loss {
        Loss::MasterStops | Loss::SafeOp => (0x14, 0x001B),
        Loss::Init => (0x01, 0),
        Loss::Sync0Stops => (0x14, 0x002C),
    };
    assert_eq!(al, expected_al, "{case}: AL status / code");
    if loss == Loss::Init {
        m.mailboxes();
        assert_eq!(m.request(2, 20), (0x02, 0), "{case}: Init → Pre-Op to read");
    }
    let sw = m.sdo_read(0x6041, 0).expect("0x6041") as u16;
    let err = m.sdo_read(0x603F, 0).expect("0x603F") as u16;
    let mut dict = [0u8; 2];
    m.app()
        .read(ObjectKey::new(0x6041, 0), &mut dict)
        .expect("0x6041 direct");
    assert_eq!(
        sw,
        u16::from_le_bytes(dict),
        "{case}: SDO and dictionary agree"
    );
    let (sw_ok, want_err) = match option {
        0 => (sw_enabled(sw), 0),
        1 => (sw_fault(sw), loss.emergency()),
        _ => (sw_disabled(sw), 0),
    };
    assert!(
        sw_ok,
        "{case}: statusword {sw:#06x} over SDO (Operation enabled for 0x6007 = 0, Fault for \
         1, Switch on disabled for 2 and 3)"
    );
    assert_eq!(err, want_err, "{case}: 0x603F over SDO");
    // Emergencies: those read from SM1 so far (and, for Init, taken from the drive).
    let codes: Vec<u16> = m.emcy.iter().map(|e| e.code).collect();
    let want: Vec<u16> = if option == 0 {
        Vec::new()
    } else {
        vec![loss.emergency()]
    };
    assert_eq!(codes, want, "{case}: emergencies {:x?}", m.emcy);
    // The ERR LED shows the final AL status code (ETG.1300: double flash for the
    // watchdog, single flash for the sync error, off without an error).
    let want_led = match expected_al.1 {
        0x001B => Pattern::DoubleFlash,
        0x002C => Pattern::SingleFlash,
        _ => Pattern::Off,
    };
    assert_eq!(
        tests_host::fault_inject::led_state(&m.seg, 0).err,
        want_led,
        "{case}: ERR LED"
    );
    // The emergency is also the newest 0x10F3 message (diagnosis code 0xE800 with the
    // emergency code in bits 16-31).
    if let Some(&code) = want.first() {
        let mut b = [0u8; 64];
        Dictionary::read(m.app(), ObjectKey::new(0x10F3, 2), &mut b).expect("0x10F3:02");
        let newest = b[0];
        let n = Dictionary::read(m.app(), ObjectKey::new(0x10F3, newest), &mut b)
            .expect("0x10F3 message");
        let msg = DiagMessage::parse(&b[..n]).expect("a diagnosis message");
        assert_eq!(
            msg.code,
            0xE800 | (u32::from(code) << 16),
            "{case}: 0x10F3 message {newest}"
        );
    }
    if option == 1 {
        assert!(
            m.emcy[0].register != 0,
            "{case}: fault emergency sets the error register: {:x?}",
            m.emcy
        );
    }
    outcome
}

/// Every option × every loss for `mode`; a failing case does not hide the others: all
/// failures are listed at the end.
fn matrix(mode: Mode) {
    let mut failed = Vec::new();
    for option in 0..=3i16 {
        for loss in LOSSES {
            match std::panic::catch_unwind(|| run_case(mode, option, loss)) {
                Ok(o) => eprintln!(
                    "{mode:?} 0x6007={option} {loss:?}: ok, stop {:?} ms, shaft drift {:.2} \
                     counts",
                    o.stop_ms, o.drift_counts
                ),
                Err(e) => {
                    let msg = e
                        .downcast_ref::<String>()
                        .cloned()
                        .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                        .unwrap_or_default();
                    failed.push(msg);
                }
            }
        }
    }
    assert!(
        failed.is_empty(),
        "{} of 16 {mode:?} cases failed:\n{}",
        failed.len(),
        failed.join("\n")
    );
}

#[test]
fn connection_loss_pp() {
    matrix(Mode::Pp);
}

#[test]
fn connection_loss_pv() {
    matrix(Mode::Pv);
}

#[test]
fn connection_loss_hm() {
    matrix(Mode::Hm);
}

#[test]
fn connection_loss_csp() {
    matrix(Mode::Csp);
}

#[test]
fn connection_loss_csv() {
    matrix(Mode::Csv);
}

#[test]
fn connection_loss_cst() {
    matrix(Mode::Cst);
}

// ---- nothing waits on the master ----------------------------------------------------

/// The reaction needs no frame: PV at speed, 0x6007 = 1, the master stops. With the
/// drive's tick (`sim_drive::advance`) and zero frames after the loss the fault
/// reaction runs to Fault with the power off. The control run shows that this check
/// has teeth: the same segment moved on with `Segment::advance` only (ESC time and the
/// runtime's polls, i.e. a drive stepped only by what the master's frames trigger)
/// leaves the drive in Fault reaction active with the power on, 0.5 s after the
/// watchdog — exactly the behaviour of issue 15.
#[test]
fn nothing_waits_on_the_master() {
    for ticked in [true, false] {
        let mut m = Master::moving(Mode::Pv, 1, false);
        let frames = m.seg.frames();
        let t = m.lose(Loss::MasterStops);
        let after = m.snap();
        assert_eq!(
            after.state,
            PdsState::FaultReactionActive,
            "at the watchdog"
        );
        let end = t + 500 * MS;
        while m.now_ns() < end {
            if ticked {
                sim_drive::advance(&mut m.seg, STEP);
            } else {
                m.seg.advance(STEP);
            }
        }
        let s = m.snap();
        assert_eq!(m.seg.frames(), frames, "no frame after the loss");
        if ticked {
            assert!(
                s.state == PdsState::Fault && !s.power_permission && !s.brake_released,
                "on the drive's clock the fault reaction ends in Fault, power off: {s:?}"
            );
            assert!(s.true_vel.abs() < 1000.0, "shaft at rest: {s:?}");
        } else {
            assert!(
                s.state == PdsState::FaultReactionActive && s.power_permission,
                "control run (no drive tick): a drive stepped only through frames would \
                 still be reacting with the power on: {s:?}"
            );
        }
    }
}

// ---- faults in the plant, no master frames ------------------------------------------

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum PlantFault {
    OverVoltage,
    PhaseShort,
    LoadFollowingError,
}

/// Drive enabled in CSP holding its position, ESM in Op with the SM2 watchdog off
/// (0x0420 = 0), the master silent; a fault injected into the plant must react on the
/// drive's clock alone: Fault, power off, brake engaged, 0x603F and one emergency.
#[test]
fn plant_faults_react_without_master_frames() {
    let cases = [
        // (fault, 0x603F)
        (PlantFault::OverVoltage, 0x3210u16),
        (PlantFault::PhaseShort, 0x2310),
        (PlantFault::LoadFollowingError, 0x8611),
    ];
    for (fault, code) in cases {
        let mut m = Master::new();
        m.go_pre_op();
        m.map_outputs();
        m.sdo_set(0x6060, 0, &[8]);
        // SM2 watchdog off (no trigger, 0x0420 = 0): the silent master leaves the ESM
        // in Op.
        m.sm2_control = 0x24;
        m.ecat_write(reg::WATCHDOG_TIME_PD.addr(), &[0, 0]);
        m.go_op(false);
        m.enable();
        m.wait(20 * MS);
        m.cyclic = false;
        let frames = m.seg.frames();
        // Silent for 200 ms first: still Op, still enabled, holding.
        m.advance_ns(200 * MS);
        let s = m.snap();
        assert_eq!(m.al(), (0x08, 0), "{fault:?}: Op with the watchdog off");
        assert_eq!(s.state, PdsState::OperationEnabled, "{fault:?}: {s:?}");
        let t_inject = m.now_ns();
        match fault {
            PlantFault::OverVoltage => m.plant.borrow_mut().set_bus_voltage(56.0),
            PlantFault::PhaseShort => m.plant.borrow_mut().inject_phase_short(0, true),
            PlantFault::LoadFollowingError => m.plant.borrow_mut().set_load(1.2),
        }
        let done = m
            .advance_until(1000 * MS, |s| s.state == PdsState::Fault)
            .unwrap_or_else(|| panic!("{fault:?}: no Fault within 1 s: {:?}", m.snap()));
        m.plant.borrow_mut().set_load(0.0);
        let ms = (done.t_ns - t_inject) / MS;
        assert!(
            !done.power_permission && !done.power_stage && !done.brake_released,
            "{fault:?}: power off, brake engaged {ms} ms after the injection: {done:?}"
        );
        assert_eq!(done.error_code, code, "{fault:?}: 0x603F (direct)");
        m.advance_ns(100 * MS);
        assert_eq!(m.seg.frames(), frames, "{fault:?}: no frame");
        // The master reads it back over SDO (Op: the mailbox runs).
        assert_eq!(m.al(), (0x08, 0), "{fault:?}: the ESM stays in Op");
        let sw = m.sdo_read(0x6041, 0).expect("0x6041") as u16;
        let err = m.sdo_read(0x603F, 0).expect("0x603F") as u16;
        assert!(sw_fault(sw), "{fault:?}: statusword {sw:#06x}");
        assert_eq!(err, code, "{fault:?}: 0x603F over SDO");
        let codes: Vec<u16> = m.emcy.iter().map(|e| e.code).collect();
        assert_eq!(codes, vec![code], "{fault:?}: emergencies {:x?}", m.emcy);
        eprintln!("{fault:?}: Fault {ms} ms after the injection, 0x603F {err:#06x}");
    }
}
