//! End to end through the simulated ESC, the slave runtime, the firmware's drive
//! application and a simulated axis, with ethercrab as the master (in-process, default
//! PDO maps 0x1600 / 0x1A00, `sim_drive::segment_with`).
//!
//! One `PduStorage` per test binary: the ethercrab scenarios run one after another
//! inside the single test `ethercrab_drive_e2e`:
//!
//! 1. plant axis (ECN57-20, FOC current loop, `firmware::motion`): Op, enable with the
//!    statusword checked cycle by cycle, a CSP trapezoid of one revolution, quick stop;
//! 2. kinematic axis: PP move with the set-point handshake, homing methods 35, 19 and
//!    34, quick stop from PP, Op → Safe-Op while enabled (PDS fault, emergency 0xA001),
//!    back to Op and fault reset.
//!
//! Outputs (0x1600): controlword [0..2], target position [2..6], 0x60B0 [6..10],
//! 0x60B8 [10..12]. Inputs (0x1A00): 0x603F [0..2], statusword [2..4], 0x6061 [4],
//! position actual [5..9], 0x60B9 [9..11], 0x60BA [11..15], 0x60FD [15..19]. The
//! inputs of a `tx_rx` are those the drive packed in the cycle before.

use ethercrab::{MainDevice, PduStorage};
use firmware::cia402::DriveCommand;
use firmware::dictionary::Sdo;
use std::cell::RefCell;
use std::rc::Rc;
use tests_host::esc_sim::frame::{datagrams, FrameOutcome, Wire};
use tests_host::esc_sim::Flavour;
use tests_host::ethercrab_seam::{sim_config, sim_now_ns, sim_timeouts, MasterHarness};
use tests_host::segment::Segment;
use tests_host::sim_axis::{AxisModel, PlantAxis};
use tests_host::sim_drive::{self, Axis, Motor, SimDrive, SimDriveConfig};

static PDU_STORAGE: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

const CYCLE_NS: u64 = 1_000_000;
/// Command units per revolution (0x2001 default) and units per encoder count.
const UPR: i32 = 50_000;
const UNITS_PER_COUNT: f64 = 12.5;

/// The segment as ethercrab's wire: frames through `sim_drive::process` (which also
/// forwards the drive's emergencies to its mailbox), with a sniffer for CoE
/// emergencies read from SM1 (0x1080).
struct SimWire {
    seg: Segment<SimDrive>,
    emergencies: Vec<(u16, u8, [u8; 5])>,
}

impl Wire for SimWire {
    fn transfer(&mut self, frame: &mut [u8]) -> FrameOutcome {
        let out = sim_drive::process(&mut self.seg, frame);
        for d in datagrams(frame).unwrap_or_default() {
            let ado = (d.addr >> 16) as u16;
            // FPRD of the SM1 buffer; mailbox type 3 (CoE), CoE service 1 (emergency).
            if d.cmd == 0x04 && ado == 0x1080 && d.wkc == 1 && d.data.len() >= 16 {
                let coe = u16::from_le_bytes([d.data[6], d.data[7]]);
                if d.data[5] & 0x0F == 3 && coe >> 12 == 1 {
                    let mut m = [0u8; 5];
                    m.copy_from_slice(&d.data[11..16]);
                    self.emergencies.push((
                        u16::from_le_bytes([d.data[8], d.data[9]]),
                        d.data[10],
                        m,
                    ));
                }
            }
        }
        out
    }
    fn now_ns(&self) -> u64 {
        self.seg.now_ns()
    }
}

type Wired = Rc<RefCell<SimWire>>;
type Err = ethercrab::error::Error;

/// Inputs of 0x1A00.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Tx {
    error: u16,
    sw: u16,
    mode: i8,
    pos: i32,
    di: u32,
}

fn decode(i: &[u8]) -> Tx {
    Tx {
        error: u16::from_le_bytes([i[0], i[1]]),
        sw: u16::from_le_bytes([i[2], i[3]]),
        mode: i[4] as i8,
        pos: i32::from_le_bytes([i[5], i[6], i[7], i[8]]),
        di: u32::from_le_bytes([i[15], i[16], i[17], i[18]]),
    }
}

/// PDS state from the statusword (mask 0x6F as in CiA 402).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum St {
    NotReady,
    SwitchOnDisabled,
    Ready,
    SwitchedOn,
    Enabled,
    QuickStop,
    FaultReaction,
    Fault,
    Other(u16),
}

fn st(sw: u16) -> St {
    match sw & 0x6F {
        0x00 | 0x20 => St::NotReady,
        0x40 | 0x60 => St::SwitchOnDisabled,
        0x21 => St::Ready,
        0x23 => St::SwitchedOn,
        0x27 => St::Enabled,
        0x07 => St::QuickStop,
        0x0F | 0x2F => St::FaultReaction,
        0x08 | 0x28 => St::Fault,
        x => St::Other(x),
    }
}

/// The true shaft position of drive 0 (command units).
fn true_pos(w: &Wired) -> f64 {
    w.borrow()
        .seg
        .drive(0)
        .app
        .axis
        .true_position()
        .expect("modelled")
}

/// One master cycle: outputs out, inputs back, then simulated time to the next ms.
async fn cycle<G>(
    md: &MainDevice<'static>,
    g: &G,
    w: &Wired,
    cw: u16,
    target: i32,
) -> Result<Tx, Err>
where
    G: OpGroup,
{
    g.write_outputs(md, cw, target)?;
    g.exchange(md).await?;
    {
        let mut s = w.borrow_mut();
        let now = s.seg.now_ns();
        let next = (now / CYCLE_NS + 1) * CYCLE_NS;
        sim_drive::advance(&mut s.seg, next - now);
    }
    g.read_inputs(md)
}

/// The few group operations the scenarios need (keeps the typestate generic out of
/// the helpers).
trait OpGroup {
    fn write_outputs(&self, md: &MainDevice<'static>, cw: u16, target: i32) -> Result<(), Err>;
    fn read_inputs(&self, md: &MainDevice<'static>) -> Result<Tx, Err>;
    async fn exchange(&self, md: &MainDevice<'static>) -> Result<(), Err>;
    async fn sdo_write<T: ethercrab::EtherCrabWireWrite>(
        &self,
        md: &MainDevice<'static>,
        i: u16,
        s: u8,
        v: T,
    ) -> Result<(), Err>;
    async fn sdo_read<T: ethercrab::EtherCrabWireReadSized>(
        &self,
        md: &MainDevice<'static>,
        i: u16,
        s: u8,
    ) -> Result<T, Err>;
}

type Group =
    ethercrab::SubDeviceGroup<4, 128, ethercrab::DefaultLock, ethercrab::subdevice_group::Op>;

impl OpGroup for Group {
    fn write_outputs(&self, md: &MainDevice<'static>, cw: u16, target: i32) -> Result<(), Err> {
        let sd = self.subdevice(md, 0)?;
        let mut o = sd.outputs_raw_mut();
        o[0..2].copy_from_slice(&cw.to_le_bytes());
        o[2..6].copy_from_slice(&target.to_le_bytes());
        Ok(())
    }
    fn read_inputs(&self, md: &MainDevice<'static>) -> Result<Tx, Err> {
        Ok(decode(&self.subdevice(md, 0)?.inputs_raw()))
    }
    async fn exchange(&self, md: &MainDevice<'static>) -> Result<(), Err> {
        self.tx_rx(md).await.map(|_| ())
    }
    async fn sdo_write<T: ethercrab::EtherCrabWireWrite>(
        &self,
        md: &MainDevice<'static>,
        i: u16,
        s: u8,
        v: T,
    ) -> Result<(), Err> {
        self.subdevice(md, 0)?.sdo_write(i, s, v).await
    }
    async fn sdo_read<T: ethercrab::EtherCrabWireReadSized>(
        &self,
        md: &MainDevice<'static>,
        i: u16,
        s: u8,
    ) -> Result<T, Err> {
        self.subdevice(md, 0)?.sdo_read(i, s).await
    }
}

/// Runs cycles with `cw`/`target` until `done(tx)` or `max` cycles; returns the inputs
/// of every cycle.
async fn run_until(
    md: &MainDevice<'static>,
    g: &Group,
    w: &Wired,
    cw: u16,
    target: i32,
    max: usize,
    done: impl Fn(&Tx) -> bool,
) -> Result<Vec<Tx>, Err> {
    let mut seen = Vec::new();
    for _ in 0..max {
        let tx = cycle(md, g, w, cw, target).await?;
        seen.push(tx);
        if done(&tx) {
            break;
        }
    }
    Ok(seen)
}

/// Writes 0x6060 and waits until 0x6061 shows it (holding `cw`, `hold`).
async fn set_mode(
    md: &MainDevice<'static>,
    g: &Group,
    w: &Wired,
    mode: i8,
    cw: u16,
    hold: i32,
) -> Result<(), Err> {
    g.sdo_write(md, 0x6060, 0, mode).await?;
    let seen = run_until(md, g, w, cw, hold, 50, |t| t.mode == mode).await?;
    assert_eq!(
        seen.last().map(|t| t.mode),
        Some(mode),
        "0x6061 never showed {mode}"
    );
    Ok(())
}

/// Enable through controlwords 6, 7, 15 holding `hold`, checking the statusword cycle
/// by cycle: each controlword moves the PDS by exactly one state (the old state until
/// the drive processed it, then the new one) within 3 cycles.
async fn enable(
    md: &MainDevice<'static>,
    g: &Group,
    w: &Wired,
    hold: i32,
) -> Result<Vec<(u16, u16)>, Err> {
    let mut log = Vec::new();
    let steps = [
        (0x0006u16, [St::SwitchOnDisabled, St::Ready]),
        (0x0007, [St::Ready, St::SwitchedOn]),
        (0x000F, [St::SwitchedOn, St::Enabled]),
    ];
    for (cw, [from, to]) in steps {
        let mut reached = false;
        for _ in 0..3 {
            let tx = cycle(md, g, w, cw, hold).await?;
            log.push((cw, tx.sw));
            let s = st(tx.sw);
            assert!(
                s == from || s == to,
                "cw {cw:#06x}: statusword {:#06x} ({s:?}), log {log:04x?}",
                tx.sw
            );
            if s == to {
                reached = true;
                // Voltage enabled from Switched on; remote always.
                assert!(tx.sw & 0x0200 != 0, "remote bit");
                if to != St::Ready {
                    assert!(tx.sw & 0x0010 != 0, "voltage enabled");
                }
                break;
            }
        }
        assert!(reached, "cw {cw:#06x} did not reach {to:?}: {log:04x?}");
    }
    // Stays enabled.
    for _ in 0..5 {
        let tx = cycle(md, g, w, 0x000F, hold).await?;
        assert_eq!(st(tx.sw), St::Enabled, "{:#06x}", tx.sw);
    }
    Ok(log)
}

/// Trapezoid of `dist` units: accelerate `ta` s, total `tt` s; position at `t`.
fn trapezoid(dist: f64, ta: f64, tt: f64, t: f64) -> f64 {
    let v = dist / (tt - ta);
    let a = v / ta;
    if t <= 0.0 {
        0.0
    } else if t < ta {
        0.5 * a * t * t
    } else if t < tt - ta {
        0.5 * a * ta * ta + v * (t - ta)
    } else if t < tt {
        dist - 0.5 * a * (tt - t) * (tt - t)
    } else {
        dist
    }
}

async fn to_op(md: &MainDevice<'static>) -> Result<Group, Err> {
    let group = md.init_single_group::<4, 128>(sim_now_ns).await?;
    group.into_op(md).await
}

/// Scenario 1 on the plant axis: enable, CSP one revolution, quick stop.
async fn plant_csp(md: Rc<MainDevice<'static>>, w: Wired) -> Result<Vec<String>, Err> {
    let md = &*md;
    let mut notes = Vec::new();
    let g = to_op(md).await?;
    // The power-up self-test (current-loop auto-tune, 0x2013 = 1) keeps the drive in
    // Not ready to switch on for ≈ 0.3 s after power-up: wait for Switch on disabled,
    // as a master does before the enable sequence.
    let mut tx = cycle(md, &g, &w, 0, 0).await?;
    let mut waited = 0;
    while st(tx.sw) == St::NotReady && waited < 1000 {
        tx = cycle(md, &g, &w, 0, 0).await?;
        waited += 1;
    }
    assert_eq!(st(tx.sw), St::SwitchOnDisabled, "{:#06x}", tx.sw);
    notes.push(format!(
        "power-up self-test (auto-tune): Not ready to switch on for {waited} more cycles in Op"
    ));
    let home = tx.pos;
    set_mode(md, &g, &w, 8, 0, home).await?;
    enable(md, &g, &w, home).await?;
    let start_true = true_pos(&w);
    // One revolution in 300 ms (100 ms acceleration), then 150 ms to settle.
    let mut worst_fe = 0i32;
    for k in 1..=450 {
        let t = k as f64 * 1e-3;
        let target = home + trapezoid(UPR as f64, 0.1, 0.3, t).round() as i32;
        let tx = cycle(md, &g, &w, 0x000F, target).await?;
        assert_eq!(
            st(tx.sw),
            St::Enabled,
            "k {k}: {:#06x} error {:#06x}",
            tx.sw,
            tx.error
        );
        if k > 5 {
            // CSP: statusword bit 12 "drive follows the command value".
            assert!(tx.sw & 0x1000 != 0, "k {k}: {:#06x}", tx.sw);
        }
        worst_fe = worst_fe.max(
            (tx.pos - (home + trapezoid(UPR as f64, 0.1, 0.3, t - 2e-3).round() as i32)).abs(),
        );
    }
    let tx = cycle(md, &g, &w, 0x000F, home + UPR).await?;
    let fe: i32 = g.sdo_read(md, 0x60F4, 0).await?;
    let moved_true = true_pos(&w) - start_true;
    notes.push(format!(
        "CSP on the plant: end position {} (target {}), true shaft {:.1} units, 0x60F4 {fe}, worst lag during the move {worst_fe} units",
        tx.pos - home,
        UPR,
        moved_true
    ));
    assert!(
        (tx.pos - home - UPR).abs() as f64 <= 3.0 * UNITS_PER_COUNT,
        "{}",
        notes[0]
    );
    assert!(
        (moved_true - UPR as f64).abs() <= 3.0 * UNITS_PER_COUNT,
        "{}",
        notes[0]
    );
    assert!(fe.abs() as f64 <= 3.0 * UNITS_PER_COUNT, "{}", notes[0]);
    // Quick stop (bit 2 = 0) during a second move: Quick stop active, then with 0x605A =
    // 2 (default) Switch on disabled once at rest.
    let qso: i16 = g.sdo_read(md, 0x605A, 0).await?;
    assert_eq!(qso, 2);
    // PV on the plant (velocity set-point to the motion layer's velocity loop): 0x60FF
    // over SDO, velocity reached (bit 10) at 2 rev/s, then speed zero (bit 12) at 0.
    set_mode(md, &g, &w, 3, 0x000F, home + UPR).await?;
    g.sdo_write(md, 0x6083, 0, 1_000_000u32).await?;
    g.sdo_write(md, 0x6084, 0, 1_000_000u32).await?;
    // Velocity window 2 % (one count is 12.5 units: the default 100 units/s is finer
    // than a 4000-count encoder resolves in a few ms).
    g.sdo_write(md, 0x606D, 0, 2_000u16).await?;
    g.sdo_write(md, 0x60FF, 0, 100_000i32).await?;
    let seen = run_until(md, &g, &w, 0x000F, 0, 1000, |t| {
        t.sw & 0x0400 != 0 && t.sw & 0x1000 == 0
    })
    .await?;
    let n_up = seen.len();
    assert!(n_up < 1000, "velocity never reached");
    for _ in 0..50 {
        cycle(md, &g, &w, 0x000F, 0).await?;
    }
    let v: i32 = g.sdo_read(md, 0x606C, 0).await?;
    assert!((v - 100_000).abs() <= 2_000, "PV actual velocity {v}");
    g.sdo_write(md, 0x60FF, 0, 0i32).await?;
    let seen = run_until(md, &g, &w, 0x000F, 0, 1000, |t| t.sw & 0x1400 == 0x1400).await?;
    assert_eq!(
        seen.last().map(|t| t.sw & 0x1400),
        Some(0x1400),
        "PV did not stop"
    );
    assert!(seen.iter().all(|t| st(t.sw) == St::Enabled));
    let v0: i32 = g.sdo_read(md, 0x606C, 0).await?;
    notes.push(format!(
        "PV on the plant: 2 rev/s reached after {n_up} cycles, 0x606C {v} at speed, {v0} after the stop ({} cycles)",
        seen.len()
    ));
    // Back to CSP at the actual position (bumpless).
    let here = seen.last().map_or(0, |t| t.pos);
    set_mode(md, &g, &w, 8, 0x000F, here).await?;
    let base = cycle(md, &g, &w, 0x000F, here).await?.pos;
    let p_csp = true_pos(&w);
    for _ in 0..20 {
        cycle(md, &g, &w, 0x000F, base).await?;
    }
    assert!(
        (true_pos(&w) - p_csp).abs() <= 2.0 * UNITS_PER_COUNT,
        "PV -> CSP jumped"
    );
    let mut last = base;
    for k in 1..=100 {
        last = base + (k as f64 * 1e-3 * 100_000.0) as i32; // 2 rev/s
        cycle(md, &g, &w, 0x000F, last).await?;
    }
    let seen = run_until(md, &g, &w, 0x000B, last, 500, |t| {
        st(t.sw) == St::SwitchOnDisabled
    })
    .await?;
    let states: Vec<St> = seen.iter().map(|t| st(t.sw)).collect();
    assert!(states.contains(&St::QuickStop), "{states:?}");
    assert_eq!(states.last(), Some(&St::SwitchOnDisabled), "{states:?}");
    assert!(
        states
            .iter()
            .all(|s| matches!(s, St::Enabled | St::QuickStop | St::SwitchOnDisabled)),
        "{states:?}"
    );
    let p0 = true_pos(&w);
    for _ in 0..20 {
        cycle(md, &g, &w, 0x0000, last).await?;
    }
    notes.push(format!(
        "quick stop from CSP at 2 rev/s: {} cycles to Switch on disabled, drift afterwards {:.1} units",
        seen.len(),
        true_pos(&w) - p0
    ));
    Ok(notes)
}

/// PP move with the set-point handshake to `target` (absolute); checks the handshake
/// cycle by cycle and returns the cycles to target reached.
async fn pp_move(
    md: &MainDevice<'static>,
    g: &Group,
    w: &Wired,
    target: i32,
) -> Result<usize, Err> {
    // Bit 4 rising: the drive acknowledges with bit 12 (and clears bit 15, E5).
    let seen = run_until(md, g, w, 0x001F, target, 10, |t| t.sw & 0x1000 != 0).await?;
    let ack = seen.last().copied().unwrap_or_default();
    assert!(
        ack.sw & 0x1000 != 0,
        "no set-point acknowledge: {seen:04x?}"
    );
    // Bit 4 low: bit 12 clears.
    let seen2 = run_until(md, g, w, 0x000F, target, 10, |t| t.sw & 0x1000 == 0).await?;
    assert!(
        seen2.last().is_some_and(|t| t.sw & 0x1000 == 0),
        "{seen2:04x?}"
    );
    // Target reached (bit 10) at the target.
    let seen3 = run_until(md, g, w, 0x000F, target, 5000, |t| {
        t.sw & 0x0400 != 0 && (t.pos - target).abs() <= 13
    })
    .await?;
    let last = seen3.last().copied().unwrap_or_default();
    assert!(
        last.sw & 0x0400 != 0,
        "target {target} not reached: {last:?}"
    );
    assert!(seen3.iter().all(|t| st(t.sw) == St::Enabled));
    Ok(seen.len() + seen2.len() + seen3.len())
}

/// Homing with `method`; returns the final user position and true shaft position.
async fn home(
    md: &MainDevice<'static>,
    g: &Group,
    w: &Wired,
    method: i8,
    offset: i32,
) -> Result<(Tx, f64), Err> {
    g.sdo_write(md, 0x6098, 0, method).await?;
    g.sdo_write(md, 0x607C, 0, offset).await?;
    let hold = g.read_inputs(md)?.pos;
    set_mode(md, g, w, 6, 0x000F, hold).await?;
    // Start (bit 4); attained = bit 12 and bit 10, error = bit 13. The inputs lag one
    // cycle: the first two after the start may still show the previous homing's bits.
    cycle(md, g, w, 0x001F, hold).await?;
    cycle(md, g, w, 0x001F, hold).await?;
    let seen = run_until(md, g, w, 0x001F, hold, 20_000, |t| {
        t.sw & 0x1400 == 0x1400 || t.sw & 0x2000 != 0
    })
    .await?;
    let last = seen.last().copied().unwrap_or_default();
    assert!(
        last.sw & 0x2000 == 0,
        "method {method}: homing error {last:?}"
    );
    assert_eq!(
        last.sw & 0x1400,
        0x1400,
        "method {method}: not attained after {} cycles",
        seen.len()
    );
    // Attained is reported inside the position window (0x6067); let the axis settle.
    let mut tx = last;
    for _ in 0..150 {
        tx = cycle(md, g, w, 0x000F, hold).await?;
    }
    assert_eq!(tx.sw & 0x1400, 0x1400, "method {method}: {tx:?}");
    Ok((tx, true_pos(w)))
}

/// Scenario 2 on the kinematic axis: PP, homing, quick stop, Op → Safe-Op, reset.
async fn kinematic(md: Rc<MainDevice<'static>>, w: Wired) -> Result<Vec<String>, Err> {
    let md = &*md;
    let mut notes = Vec::new();
    let g = to_op(md).await?;
    let tx = cycle(md, &g, &w, 0, 0).await?;
    set_mode(md, &g, &w, 1, 0, tx.pos).await?;
    g.sdo_write(md, 0x6081, 0, 100_000u32).await?;
    g.sdo_write(md, 0x6083, 0, 1_000_000u32).await?;
    g.sdo_write(md, 0x6084, 0, 1_000_000u32).await?;
    enable(md, &g, &w, tx.pos).await?;
    // PP: 60 000 units, then back to 5 000.
    let n1 = pp_move(md, &g, &w, 60_000).await?;
    let n2 = pp_move(md, &g, &w, 5_000).await?;
    notes.push(format!("PP moves: {n1} and {n2} cycles to target reached"));
    assert!((true_pos(&w) - 5_000.0).abs() <= UNITS_PER_COUNT);

    // Homing 35: the present position is the home position (0x607C).
    let before = true_pos(&w);
    let (tx, t35) = home(md, &g, &w, 35, 777).await?;
    assert!((tx.pos - 777).abs() <= 13, "35: {tx:?}");
    assert!((t35 - before).abs() <= UNITS_PER_COUNT, "35 moved the axis");
    // Homing 19 (home switch active at 20 000..30 000 raw; from below: the rising edge at
    // the lower end of the switch), home offset 0.
    // Input filter of IN1 (home) to its minimum (50 µs), fast switch search, steep
    // homing acceleration (short overshoot into the switch).
    g.sdo_write(md, 0x2153, 1, 1u16).await?;
    g.sdo_write(md, 0x6099, 1, 50_000u32).await?;
    g.sdo_write(md, 0x609A, 0, 2_000_000u32).await?;
    let (tx, t19) = home(md, &g, &w, 19, 0).await?;
    assert!(tx.pos.abs() <= 13, "19: {tx:?}");
    // In encoder counts: the switch changes between count 1599 (inactive) and 1600
    // (active); the shaft ends within one count of that edge.
    let c19 = (t19 / UNITS_PER_COUNT).floor();
    assert!(
        (1598.0..=1600.0).contains(&c19),
        "19: true {t19} (count {c19})"
    );
    notes.push(format!(
        "homing 19: position {} reads, shaft at {t19:.2} (switch edge 20000)",
        tx.pos
    ));
    // Homing 34 (index, positive direction): the next index pulse after the present
    // position (1 250 + k·50 000 raw), home offset 100.
    g.sdo_write(md, 0x6099, 2, 40_000u32).await?;
    let (tx, t34) = home(md, &g, &w, 34, 100).await?;
    let idx = 1_250.0 + ((t19 - 1_250.0) / 50_000.0).ceil() * 50_000.0;
    assert!((tx.pos - 100).abs() <= 13, "34: {tx:?}");
    // The index latches at count 100 + k·4000 (1 250 units): the shaft ends in that
    // count or a neighbour.
    let c34 = (t34 / UNITS_PER_COUNT).floor() - idx / UNITS_PER_COUNT;
    assert!(c34.abs() <= 1.0, "34: true {t34}, index {idx}");
    notes.push(format!(
        "homing 34: position {} reads, shaft at {t34:.2} (index {idx})",
        tx.pos
    ));
    // Homing 33 (index, negative direction).
    let (tx, t33) = home(md, &g, &w, 33, -50).await?;
    let idx33 = 1_250.0 + ((t34 - 1.0 - 1_250.0) / 50_000.0).floor() * 50_000.0;
    assert!((tx.pos + 50).abs() <= 13, "33: {tx:?}");
    let c33 = (t33 / UNITS_PER_COUNT).floor() - idx33 / UNITS_PER_COUNT;
    assert!(c33.abs() <= 1.0, "33: true {t33}, index {idx33}");
    notes.push(format!(
        "homing 33: position {} reads, shaft at {t33:.2} (index {idx33})",
        tx.pos
    ));

    // Quick stop from PP during a move.
    set_mode(md, &g, &w, 1, 0x000F, tx.pos).await?;
    let user = tx.pos;
    run_until(md, &g, &w, 0x001F, user + 200_000, 5, |t| {
        t.sw & 0x1000 != 0
    })
    .await?;
    run_until(md, &g, &w, 0x000F, user + 200_000, 200, |_| false).await?;
    let seen = run_until(md, &g, &w, 0x000B, user + 200_000, 500, |t| {
        st(t.sw) == St::SwitchOnDisabled
    })
    .await?;
    let states: Vec<St> = seen.iter().map(|t| st(t.sw)).collect();
    assert!(states.contains(&St::QuickStop), "{states:?}");
    assert_eq!(states.last(), Some(&St::SwitchOnDisabled), "{states:?}");
    notes.push(format!(
        "quick stop from PP: {} cycles to Switch on disabled",
        seen.len()
    ));

    // Op → Safe-Op while enabled.
    let hold = g.read_inputs(md)?.pos;
    enable(md, &g, &w, hold).await?;
    w.borrow_mut().emergencies.clear();
    let g = g.into_safe_op(md).await?;
    // The master keeps exchanging process data in Safe-Op (inputs only).
    for _ in 0..5 {
        g.tx_rx(md).await?;
        let mut s = w.borrow_mut();
        sim_drive::advance(&mut s.seg, CYCLE_NS);
    }
    let sw: u16 = g.subdevice(md, 0)?.sdo_read(0x6041, 0).await?;
    assert_eq!(st(sw), St::Fault, "statusword {sw:#06x}");
    let err: u16 = g.subdevice(md, 0)?.sdo_read(0x603F, 0).await?;
    // Let ethercrab read the mailbox again (the emergency may follow the reply).
    let _: u16 = g.subdevice(md, 0)?.sdo_read(0x6041, 0).await?;
    let emcy = w.borrow().emergencies.clone();
    assert!(
        emcy.iter().any(|e| e.0 == 0xA001),
        "emergencies {emcy:04x?}"
    );
    notes.push(format!("Op -> Safe-Op while enabled: statusword {sw:#06x}, 0x603F {err:#06x}, emergencies {emcy:04x?}"));
    // Back to Op, fault reset on the rising edge of bit 7.
    let g = g.into_op(md).await?;
    let hold = g.read_inputs(md)?.pos;
    cycle(md, &g, &w, 0x0000, hold).await?;
    let seen = run_until(md, &g, &w, 0x0080, hold, 10, |t| {
        st(t.sw) == St::SwitchOnDisabled
    })
    .await?;
    assert_eq!(
        seen.last().map(|t| st(t.sw)),
        Some(St::SwitchOnDisabled),
        "{seen:04x?}"
    );
    let hold = seen.last().map_or(0, |t| t.pos);
    enable(md, &g, &w, hold).await?;
    notes.push("fault reset: Switch on disabled, enabled again".into());
    Ok(notes)
}

fn wired(model: AxisModel) -> Wired {
    let cfg = SimDriveConfig {
        motor: Motor::Ecn57_20,
        flavour: Flavour::Lan9252,
        flash_file: None,
        dips: tests_host::sim_drive::DIPS_ALL_ON,
    };
    let seg = sim_drive::segment_with(&cfg, 1, model).expect("segment");
    Rc::new(RefCell::new(SimWire {
        seg,
        emergencies: Vec::new(),
    }))
}

#[test]
fn ethercrab_drive_e2e() {
    let mut h = MasterHarness::new(&PDU_STORAGE).expect("storage split once");
    let w = wired(AxisModel::Plant);
    let w2 = w.clone();
    let (r, stats) = h.run(w.clone(), sim_timeouts(), sim_config(), |md| {
        plant_csp(md, w2)
    });
    let notes = r.unwrap_or_else(|e| panic!("plant scenario: ethercrab error {e:?}; {stats:?}"));
    for n in notes {
        println!("{n}");
    }
    let w = wired(AxisModel::Kinematic);
    let w2 = w.clone();
    let (r, stats) = h.run(w.clone(), sim_timeouts(), sim_config(), |md| {
        kinematic(md, w2)
    });
    let notes =
        r.unwrap_or_else(|e| panic!("kinematic scenario: ethercrab error {e:?}; {stats:?}"));
    for n in notes {
        println!("{n}");
    }
}

/// Speed of the plant axis (printed; the figure behind `sim_axis::PLANT_MAX_DRIVES`),
/// and the axis holds its position while enabled.
#[test]
fn plant_axis_real_time_factor() {
    let mut ax = PlantAxis::new(Motor::Ecn57_20);
    let c = DriveCommand {
        power_stage: true,
        drive_enabled: true,
        torque_limit: 1000,
        current_limit: 1000,
        ..DriveCommand::default()
    };
    let t = std::time::Instant::now();
    let n = 200;
    for _ in 0..n {
        ax.command(&c, 1e-3);
        ax.advance(1e-3, &c);
    }
    let wall = t.elapsed().as_secs_f64();
    let sim = n as f64 * 1e-3;
    println!(
        "PlantAxis: {sim} s simulated in {wall:.4} s wall: real-time factor {:.1}",
        sim / wall
    );
    let s = ax.state();
    assert!(s.position.abs() <= 13, "{s:?}");
    assert!(ax.true_position().abs() <= UNITS_PER_COUNT);
}

/// The plant axis under load torque holds its position (velocity integrator) and
/// reports a torque current; with the drive disabled it carries no current.
#[test]
fn plant_axis_holds_against_load_and_is_dead_when_disabled() {
    let mut ax = PlantAxis::new(Motor::Ecn57_20);
    let mut c = DriveCommand {
        power_stage: true,
        drive_enabled: true,
        torque_limit: 1000,
        current_limit: 1000,
        ..DriveCommand::default()
    };
    ax.set_load(0.3);
    for _ in 0..300 {
        ax.command(&c, 1e-3);
        ax.advance(1e-3, &c);
    }
    let s = ax.state();
    assert!(s.position.abs() <= 13, "{s:?}");
    // 0.3 N·m / 0.283 N·m/A ≈ 1.06 A of 3.2 A ≈ 331 ‰.
    // (plus friction 0.015 N·m and the detent torque at this angle)
    assert!((300..=420).contains(&s.current_permille), "{s:?}");
    c.drive_enabled = false;
    c.power_stage = false;
    ax.set_load(0.0);
    for _ in 0..20 {
        ax.command(&c, 1e-3);
        ax.advance(1e-3, &c);
    }
    let s = ax.state();
    assert!(s.ia_ma.abs() < 100 && s.ib_ma.abs() < 100, "{s:?}");
    assert_eq!((s.ia_set_ma, s.ib_set_ma), (0, 0));
}

/// On the plant: closed loop → open loop (0x2024 = 1 through the parameter hook) while
/// enabled and holding, an open-loop move of a quarter revolution, back to closed loop;
/// the shaft never jumps and every phase current stays bounded.
#[test]
fn plant_axis_open_closed_switching_and_open_loop_move() {
    use firmware::identity::Variant;
    use firmware::params::Params;
    let mut ax = PlantAxis::new(Motor::Ecn57_20);
    let mut p = Params::new(Variant::HybridServo);
    ax.parameters(&p);
    let mut c = DriveCommand {
        power_stage: true,
        drive_enabled: true,
        torque_limit: 1000,
        current_limit: 1000,
        ..DriveCommand::default()
    };
    let run = |ax: &mut PlantAxis, c: &DriveCommand, ms: usize| -> (f64, i16) {
        let mut worst = 0.0f64;
        let mut imax = 0i16;
        let p0 = ax.true_position();
        for _ in 0..ms {
            ax.command(c, 1e-3);
            ax.advance(1e-3, c);
            let s = ax.state();
            imax = imax.max(s.ia_ma.abs()).max(s.ib_ma.abs());
            worst = worst.max((ax.true_position() - p0).abs());
        }
        (worst, imax)
    };
    let (w, _) = run(&mut ax, &c, 50);
    assert!(w <= UNITS_PER_COUNT, "closed-loop hold moved {w}");
    // To open loop: the vector goes onto the rotor, the shaft stays.
    p.write(0x2024, 0, &[1]).unwrap();
    ax.parameters(&p);
    assert!(!ax.motion.motion().closed_loop());
    let (w, imax) = run(&mut ax, &c, 100);
    assert!(
        w <= 3.0 * UNITS_PER_COUNT,
        "switch to open loop moved the shaft {w}"
    );
    assert!(imax <= 3400, "{imax} mA");
    // Open-loop move: a quarter revolution in 250 ms.
    let start = ax.state().position;
    for k in 1..=250 {
        c.position = start + k * 50;
        ax.command(&c, 1e-3);
        ax.advance(1e-3, &c);
    }
    let (_, imax) = run(&mut ax, &c, 100);
    assert!(imax <= 3400, "{imax} mA");
    let moved = ax.state().position - start;
    // The rotor follows the vector (load angle of a few counts, detent).
    assert!((moved - 12_500).abs() <= 40, "open loop moved {moved}");
    // Back to closed loop: bumpless, and the axis then holds the commanded position.
    p.write(0x2024, 0, &[2]).unwrap();
    ax.parameters(&p);
    assert!(ax.motion.motion().closed_loop());
    let (w, imax) = run(&mut ax, &c, 200);
    assert!(
        w <= 3.0 * UNITS_PER_COUNT,
        "switch to closed loop moved the shaft {w}"
    );
    assert!(imax <= 3400, "{imax} mA");
    let s = ax.state();
    assert!(
        (s.position - c.position).abs() <= 13,
        "{s:?} vs {}",
        c.position
    );
    println!(
        "plant open/closed: open-loop move {moved} units (12 500 commanded), after closing \
         the loop {} (target {}), largest shaft motion at the switch {w:.1} units",
        s.position, c.position
    );
}
