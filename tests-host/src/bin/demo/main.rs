//! The commissioning demo (`cargo xtask demo`): an in-process ethercrab master
//! commissions one simulated drive — the complete firmware library behind the ESC
//! simulator, with a simulated axis — without any hardware.
//!
//! Steps: scan, identity and names from the SII, SDO reads of key objects, the PDO
//! configuration, Pre-Op → Safe-Op → Op, enable (CiA 402 state machine), homing, a
//! profile-position move, a CSP S-curve at 1 ms cycle, a following-error fault with
//! its emergency and the fault reset. Prints a report of tables and writes PNG plots
//! (current step response of the FOC current loop on the motor plant, CSP tracking
//! error, homing trace) into `target/demo/` (or `--out DIR`).
#![deny(clippy::undocumented_unsafe_blocks)]

use std::cell::RefCell;
use std::path::PathBuf;
use std::rc::Rc;

use ethercrab::{MainDevice, PduStorage, SubDeviceGroup};
use plotters::style::RGBColor;
use tests_host::esc_sim::frame::{datagrams, FrameOutcome, Wire};
use tests_host::esc_sim::Flavour;
use tests_host::ethercrab_seam::{sim_config, sim_now_ns, sim_timeouts, MasterHarness};
use tests_host::plot::{load_font, plot, Series};
use tests_host::segment::Segment;
use tests_host::sim_drive::{self, Motor, SimDrive, SimDriveConfig};

mod report;
mod steps;

use report::*;
use steps::*;

static PDU_STORAGE: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

/// Units: command units per revolution (0x2001 default) and encoder counts.
const UNITS_PER_REV: f64 = 50_000.0;
const COUNTS_PER_REV: f64 = 4_000.0;
const CYCLE_NS: u64 = 1_000_000;

/// The simulated segment as ethercrab's wire, with a sniffer for emergencies read from
/// the mailbox (SM1 at 0x1080).
struct SimWire {
    seg: Segment<SimDrive>,
    emergencies: Vec<(u64, u16, u8, [u8; 5])>,
}

impl Wire for SimWire {
    fn transfer(&mut self, frame: &mut [u8]) -> FrameOutcome {
        let out = sim_drive::process(&mut self.seg, frame);
        for d in datagrams(frame).unwrap_or_default() {
            // FPRD (0x04) of the SM1 buffer: a CoE emergency is mailbox type 3, CoE service 1.
            let ado = (d.addr >> 16) as u16;
            if d.cmd == 0x04
                && ado == 0x1080
                && d.wkc == 1
                && d.data.len() >= 16
                && d.data[5] & 0x0F == 3
            {
                let coe = u16::from_le_bytes([d.data[6], d.data[7]]);
                if coe >> 12 == 1 {
                    let code = u16::from_le_bytes([d.data[8], d.data[9]]);
                    let mut m = [0u8; 5];
                    m.copy_from_slice(&d.data[11..16]);
                    self.emergencies
                        .push((self.seg.now_ns(), code, d.data[10], m));
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
type PreOpGroup = SubDeviceGroup<4, 128>;
type OpGroup = SubDeviceGroup<4, 128, ethercrab::DefaultLock, ethercrab::subdevice_group::Op>;

/// Inputs of the default TxPDO 0x1A00.
#[derive(Debug, Clone, Copy, Default)]
struct Tx {
    error: u16,
    status: u16,
    mode: i8,
    position: i32,
    inputs: u32,
}

fn decode(inputs: &[u8]) -> Tx {
    let g = |r: std::ops::Range<usize>| inputs.get(r).map(|b| b.to_vec()).unwrap_or_default();
    let u16_at = |o: usize| g(o..o + 2).try_into().map(u16::from_le_bytes).unwrap_or(0);
    Tx {
        error: u16_at(0),
        status: u16_at(2),
        mode: inputs.get(4).map_or(0, |&b| b as i8),
        position: g(5..9).try_into().map(i32::from_le_bytes).unwrap_or(0),
        inputs: g(15..19).try_into().map(u32::from_le_bytes).unwrap_or(0),
    }
}

/// Names of the CiA 402 states from the statusword.
fn pds_state(sw: u16) -> &'static str {
    match sw & 0x6F {
        0x00 | 0x20 => "Not ready to switch on",
        0x40 | 0x60 => "Switch on disabled",
        0x21 => "Ready to switch on",
        0x23 => "Switched on",
        0x27 => "Operation enabled",
        0x07 => "Quick stop active",
        0x0F | 0x2F => "Fault reaction active",
        0x08 | 0x28 => "Fault",
        _ => "?",
    }
}

struct Op<'a> {
    md: &'a MainDevice<'static>,
    group: &'a OpGroup,
    wire: Wired,
    t0: u64,
}

impl Op<'_> {
    /// One 1 ms cycle: outputs (controlword, target position) out, inputs back.
    async fn cycle(&self, cw: u16, target: i32) -> Result<Tx, ethercrab::error::Error> {
        {
            let sd = self.group.subdevice(self.md, 0)?;
            let mut o = sd.outputs_raw_mut();
            o[0..2].copy_from_slice(&cw.to_le_bytes());
            o[2..6].copy_from_slice(&target.to_le_bytes());
        }
        self.group.tx_rx(self.md).await?;
        // The master's cycle: simulated time moves on to the next millisecond.
        {
            let mut w = self.wire.borrow_mut();
            let now = w.seg.now_ns();
            let next = (now / CYCLE_NS + 1) * CYCLE_NS;
            sim_drive::advance(&mut w.seg, next - now);
        }
        let sd = self.group.subdevice(self.md, 0)?;
        let tx = decode(&sd.inputs_raw());
        Ok(tx)
    }
    fn t_ms(&self) -> f64 {
        (sim_now_ns() - self.t0) as f64 * 1e-6
    }
    /// Runs cycles with controlword `cw` (target `hold`, then the actual position) until the
    /// statusword shows `state` (`statusword & 0x6F`), as a master's CiA 402 state
    /// machine does, at most `max_ms` cycles. Returns the last inputs and the cycles.
    async fn until_state(
        &self,
        cw: u16,
        state: u16,
        max_ms: u32,
        hold: i32,
    ) -> Result<(Tx, u32), ethercrab::error::Error> {
        let mut tx = self.cycle(cw, hold).await?;
        let mut n = 1;
        while tx.status & 0x6F != state && n < max_ms {
            tx = self.cycle(cw, tx.position).await?;
            n += 1;
        }
        Ok((tx, n))
    }
    /// Writes 0x6060 and runs cycles (controlword 0x000F, holding `hold`) until 0x6061
    /// shows the new mode.
    async fn set_mode(&self, mode: i8, hold: i32) -> Result<Tx, ethercrab::error::Error> {
        self.sdo_w(0x6060, 0, mode).await?;
        let mut tx = self.cycle(0x000F, hold).await?;
        for _ in 0..200 {
            if tx.mode == mode {
                break;
            }
            tx = self.cycle(0x000F, hold).await?;
        }
        Ok(tx)
    }
    async fn sdo_w<T: ethercrab::EtherCrabWireWrite>(
        &self,
        i: u16,
        s: u8,
        v: T,
    ) -> Result<(), ethercrab::error::Error> {
        self.group.subdevice(self.md, 0)?.sdo_write(i, s, v).await
    }
}

struct Traces {
    /// What did not go as a commissioning engineer expects (the demo then fails).
    problems: Vec<String>,
    homing: Vec<(f64, f64)>,
    homing_switch: Vec<(f64, f64)>,
    csp_error: Vec<(f64, f64)>,
    /// The drive's own following error 0x60F4 (read by SDO after each cycle).
    csp_following: Vec<(f64, f64)>,
    csp_target: Vec<(f64, f64)>,
}

async fn commission(
    md: Rc<MainDevice<'static>>,
    wire: Wired,
) -> Result<Traces, ethercrab::error::Error> {
    let group = md.init_single_group::<4, 128>(sim_now_ns).await?;
    scan_report(&md, &group).await?;
    sdo_report(&md, &group).await?;
    pdo_report(&md, &group).await?;

    // --- Op -----------------------------------------------------------------------
    let group = group.into_op(&md).await?;
    let op = Op {
        md: &md,
        group: &group,
        wire: wire.clone(),
        t0: sim_now_ns(),
    };
    let (seg_in, seg_out) = {
        let sd = group.subdevice(&md, 0)?;
        let i = sd.inputs_raw().len();
        let o = sd.outputs_raw_mut().len();
        (i, o)
    };
    println!("\n4. Operational: {seg_out} bytes of outputs and {seg_in} bytes of inputs exchanged every 1 ms (LRW).");

    let mut problems = Problems::default();
    let tx = enable_after_self_test(&op, &mut problems).await?;
    let (tx, homing, homing_switch) = home(&op, tx, &mut problems).await?;
    let tx = profile_position(&op, tx, &mut problems).await?;
    let (tx, csp) = csp_s_curve(&op, tx, &mut problems).await?;
    fault_and_reset(&op, tx, &mut problems).await?;
    emergency_report(&wire.borrow(), op.t0);
    let group = group.into_safe_op(&md).await?;
    let group = group.into_pre_op(&md).await?;
    let _ = group.into_init(&md).await?;
    println!("\nBack to Init.");
    Ok(Traces {
        problems: problems.0,
        homing,
        homing_switch,
        csp_error: csp.error,
        csp_following: csp.following,
        csp_target: csp.target,
    })
}

/// What did not go as the demo expects (it fails with these).
#[derive(Default)]
struct Problems(Vec<String>);

impl Problems {
    /// Notes `what` unless `ok`.
    fn expect(&mut self, ok: bool, what: &str) {
        if !ok {
            self.0.push(what.to_string());
        }
    }
}

fn main() {
    let mut out = PathBuf::from("target/demo");
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--out" {
            if let Some(p) = args.next() {
                out = PathBuf::from(p);
            }
        }
    }
    println!("ECS drive firmware — commissioning demo on a simulated drive (no hardware)");
    println!("Firmware library + ESC simulator (LAN9252) + simulated axis; master: ethercrab 0.7, in-process.");
    let cfg = SimDriveConfig {
        motor: Motor::Ecn57_20,
        flavour: Flavour::Lan9252,
        flash_file: None,
        dips: tests_host::sim_drive::DIPS_ALL_ON,
    };
    let seg = match sim_drive::segment(&cfg, 1) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("demo: cannot start the simulated drive: {e}");
            std::process::exit(1);
        }
    };
    let wire = Rc::new(RefCell::new(SimWire {
        seg,
        emergencies: Vec::new(),
    }));
    let mut h = MasterHarness::new(&PDU_STORAGE).expect("PDU storage split once");
    let w2 = wire.clone();
    let (res, stats) = h.run(wire.clone(), sim_timeouts(), sim_config(), |md| {
        commission(md, w2)
    });
    let traces = match res {
        Ok(t) => t,
        Err(e) => {
            eprintln!("demo: the master reported an error: {e:?}");
            std::process::exit(1);
        }
    };
    println!(
        "\nFrames: {} sent, {} received; simulated time {:.2} s.",
        stats.sent,
        stats.received,
        sim_now_ns() as f64 * 1e-9
    );
    if !traces.problems.is_empty() {
        eprintln!("demo: not as expected: {}", traces.problems.join("; "));
        std::process::exit(1);
    }

    write_plots(&out, &traces);
    let _ = traces.csp_target;
}

/// The demo's PNG plots into `out`: the current step on the motor plant, the CSP
/// tracking error, the homing trace. Exits the process on an I/O error.
fn write_plots(out: &std::path::Path, traces: &Traces) {
    if let Err(e) = std::fs::create_dir_all(out) {
        eprintln!("demo: cannot create {}: {e}", out.display());
        std::process::exit(1);
    }
    let text = load_font();
    let step = tests_host::plant::scenarios::current_step(tests_host::plant::motor::ECN57_20, 8);
    let plots = [
        (
            "current_step.png",
            format!("FOC current loop on the ECN57-20 plant: 0.5 A step, rise {:.0} µs, overshoot {:.1} %", step.rise_us, step.overshoot_pct),
            "time (µs)",
            "i_q (A)",
            vec![("reference", step.reference.clone(), RGBColor(120, 120, 120)), ("measured i_q", step.trace.clone(), RGBColor(200, 30, 30))],
        ),
        (
            "csp_tracking_error.png",
            "CSP S-curve, 5 revolutions in 1.5 s: tracking error".to_string(),
            "cycle (1 ms)",
            "error (encoder counts)",
            vec![
                (
                    "target − actual as the master sees it (previous cycle's target; includes the 1-cycle transport delay)",
                    traces.csp_error.clone(),
                    RGBColor(30, 60, 200),
                ),
                (
                    "0x60F4 following error: the drive's demand − actual at its own cycle",
                    traces.csp_following.clone(),
                    RGBColor(200, 30, 30),
                ),
            ],
        ),
        (
            "homing_trace.png",
            "Homing method 19: position and home switch".to_string(),
            "time (ms)",
            "position (revolutions)",
            vec![("position", traces.homing.clone(), RGBColor(30, 140, 60)), ("home switch (0.5 = active)", traces.homing_switch.clone(), RGBColor(200, 120, 0))],
        ),
    ];
    println!();
    for (file, title, x, y, series) in plots {
        let path = out.join(file);
        let s: Vec<Series> = series
            .iter()
            .map(|(n, d, c)| (*n, d.as_slice(), *c))
            .collect();
        match plot(&path, &title, x, y, &s, text) {
            Ok(()) => println!("plot: {}", path.display()),
            Err(e) => {
                eprintln!("demo: plot {file}: {e}");
                std::process::exit(1);
            }
        }
    }
}
