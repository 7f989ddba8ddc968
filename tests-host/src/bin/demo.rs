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

fn table(title: &str, headers: &[&str], rows: &[Vec<String>]) {
    let mut w: Vec<usize> = headers.iter().map(|h| h.chars().count()).collect();
    for r in rows {
        for (i, c) in r.iter().enumerate() {
            w[i] = w[i].max(c.chars().count());
        }
    }
    println!("\n{title}");
    let line = |cells: Vec<String>| {
        let s: Vec<String> = cells
            .iter()
            .enumerate()
            .map(|(i, c)| format!("{c:<width$}", width = w[i]))
            .collect();
        println!("  | {} |", s.join(" | "));
    };
    line(headers.iter().map(|s| s.to_string()).collect());
    println!(
        "  |{}|",
        w.iter()
            .map(|n| "-".repeat(n + 2))
            .collect::<Vec<_>>()
            .join("|")
    );
    for r in rows {
        line(r.clone());
    }
}

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

/// Table 1: the drives found on the segment, identity and names from the SII.
async fn scan_report(
    md: &MainDevice<'static>,
    group: &PreOpGroup,
) -> Result<(), ethercrab::error::Error> {
    let mut rows = Vec::new();
    for sd in group.iter(md) {
        let id = sd.identity();
        rows.push(vec![
            format!("{:#06x}", sd.configured_address()),
            sd.name().to_string(),
            sd.description()
                .await?
                .map(|s| s.to_string())
                .unwrap_or_default(),
            format!("{:#010x}", id.vendor_id),
            format!("{:#010x}", id.product_id),
            format!("{:#010x}", id.revision),
            format!("{}", id.serial),
        ]);
    }
    table(
        "1. Scan: drives found on the segment (identity and names from the SII EEPROM)",
        &[
            "address", "order", "name", "vendor", "product", "revision", "serial",
        ],
        &rows,
    );
    Ok(())
}

/// Table 2: SDO reads of key objects, and the abort for a missing one.
async fn sdo_report(
    md: &MainDevice<'static>,
    group: &PreOpGroup,
) -> Result<(), ethercrab::error::Error> {
    let sd = group.subdevice(md, 0)?;
    let mut rows = Vec::new();
    let u32s: [(u16, u8, &str); 6] = [
        (0x1000, 0, "device type (CiA 402 servo)"),
        (0x1018, 2, "product code"),
        (
            0x6502,
            0,
            "supported drive modes (bit 0 PP, 2 PV, 5 HM, 7 CSP, 8 CSV)",
        ),
        (0x2001, 0, "pulses per revolution (command units)"),
        (0x2029, 0, "encoder lines"),
        (0x2030, 0, "following error limit (counts)"),
    ];
    for (i, s, what) in u32s {
        let v: u32 = if i == 0x2001 || i == 0x2029 || i == 0x2030 {
            sd.sdo_read::<u16>(i, s)
                .await
                .map(u32::from)
                .or(sd.sdo_read::<u32>(i, s).await)?
        } else {
            sd.sdo_read::<u32>(i, s).await?
        };
        rows.push(vec![
            format!("{i:#06x}:{s:02}"),
            what.into(),
            format!("{v} ({v:#x})"),
        ]);
    }
    let peak: u16 = sd.sdo_read(0x2000, 0).await?;
    rows.push(vec![
        "0x2000:00".into(),
        "peak current (mA)".into(),
        peak.to_string(),
    ]);
    let mode_loop: u8 = sd.sdo_read(0x2024, 0).await?;
    rows.push(vec![
        "0x2024:00".into(),
        "open/closed loop (2 = closed)".into(),
        mode_loop.to_string(),
    ]);
    // A missing object is answered with an abort, the drive keeps running.
    let missing = sd.sdo_read::<u32>(0x5FFF, 0).await;
    rows.push(vec![
        "0x5FFF:00".into(),
        "object that does not exist".into(),
        match missing {
            Err(e) => format!("refused: {e:?}"),
            Ok(v) => format!("unexpected value {v}"),
        },
    ]);
    table(
        "2. SDO reads through the CoE mailbox",
        &["object", "meaning", "value"],
        &rows,
    );
    Ok(())
}

/// Table 3: the default PDO mapping, read back by SDO.
async fn pdo_report(
    md: &MainDevice<'static>,
    group: &PreOpGroup,
) -> Result<(), ethercrab::error::Error> {
    let sd = group.subdevice(md, 0)?;
    let mut rows = Vec::new();
    for (assign, dir) in [(0x1C12u16, "RxPDO (outputs)"), (0x1C13, "TxPDO (inputs)")] {
        let n: u8 = sd.sdo_read(assign, 0).await?;
        for k in 1..=n {
            let map: u16 = sd.sdo_read(assign, k).await?;
            let entries: u8 = sd.sdo_read(map, 0).await?;
            let mut list = Vec::new();
            let mut bits = 0u32;
            for e in 1..=entries {
                let raw: u32 = sd.sdo_read(map, e).await?;
                bits += raw & 0xFF;
                list.push(format!(
                    "{:04X}:{:02X}/{}",
                    raw >> 16,
                    (raw >> 8) & 0xFF,
                    raw & 0xFF
                ));
            }
            rows.push(vec![
                dir.into(),
                format!("{map:#06x}"),
                list.join(" "),
                format!("{}", bits.div_ceil(8)),
            ]);
        }
    }
    table(
        "3. Process data mapping (default maps, read back by SDO)",
        &["direction", "map", "entries (index:sub/bits)", "bytes"],
        &rows,
    );
    Ok(())
}

/// Table 5: the power-up self-test, then the CiA 402 enable sequence; the auto-tune's
/// results. Returns the inputs in Operation enabled.
async fn enable_after_self_test(
    op: &Op<'_>,
    problems: &mut Problems,
) -> Result<Tx, ethercrab::error::Error> {
    // The drive stays in Not ready to switch on while it auto-tunes its current loop
    // (0x2013 = 1); like a real master, wait for Switch on disabled first, then step
    // through the states, each until the statusword shows it.
    let mut rows = Vec::new();
    let (mut tx, waited) = op.until_state(0x0000, 0x40, 3000, 0).await?;
    problems.expect(
        tx.status & 0x6F == 0x40,
        "Switch on disabled after the power-up self-test",
    );
    rows.push(vec![
        format!("0x0000 (power-up self-test: {waited} ms)"),
        format!("{:#06x}", tx.status),
        pds_state(tx.status).into(),
    ]);
    for (cw, what, state) in [
        (0x0006u16, "shutdown", 0x21u16),
        (0x0007, "switch on", 0x23),
        (0x000F, "enable operation", 0x27),
    ] {
        let (t, n) = op.until_state(cw, state, 2000, tx.position).await?;
        tx = t;
        problems.expect(tx.status & 0x6F == state, what);
        rows.push(vec![
            format!("{cw:#06x} {what} ({n} cycles)"),
            format!("{:#06x}", tx.status),
            pds_state(tx.status).into(),
        ]);
    }
    table(
        "5. Enable through the CiA 402 power drive system",
        &["controlword", "statusword", "state"],
        &rows,
    );
    let mut tuned = Vec::new();
    for (i, what) in [
        (0x2020u16, "phase resistance (mΩ)"),
        (0x2021, "phase inductance (µH)"),
        (0x2015, "current Kp (0.01 V/A)"),
        (0x2016, "current Ki (10 V/(A·s))"),
    ] {
        let v: u16 = op.group.subdevice(op.md, 0)?.sdo_read(i, 0).await?;
        tuned.push(vec![format!("{i:#06X}:00"), what.into(), v.to_string()]);
    }
    table(
        "   The power-up auto-tune's results (0x2013 = 1), read by SDO",
        &["object", "meaning", "value"],
        &tuned,
    );
    Ok(tx)
}

/// Table 6: homing, method 19; the position and home-switch traces of the plot.
async fn home(
    op: &Op<'_>,
    mut tx: Tx,
    problems: &mut Problems,
) -> Result<(Tx, Vec<(f64, f64)>, Vec<(f64, f64)>), ethercrab::error::Error> {
    let hold = tx.position;
    op.sdo_w(0x6098, 0, 19i8).await?;
    op.sdo_w(0x6099, 1, 40_000u32).await?;
    op.sdo_w(0x6099, 2, 4_000u32).await?;
    op.sdo_w(0x609A, 0, 400_000u32).await?;
    op.sdo_w(0x607C, 0, 0i32).await?;
    op.set_mode(6, hold).await?;
    let mut homing = Vec::new();
    let mut homing_switch = Vec::new();
    let start_ms = op.t_ms();
    let mut attained = None;
    for k in 0..6000 {
        tx = op.cycle(0x001F, 0).await?;
        let t = op.t_ms() - start_ms;
        homing.push((t, tx.position as f64 / UNITS_PER_REV));
        // 0x60FD bit 2: home switch, as the drive reports it.
        homing_switch.push((t, if tx.inputs & 0b100 != 0 { 0.5 } else { 0.0 }));
        if tx.status & (1 << 13) != 0 {
            break;
        }
        if tx.status & (1 << 12) != 0 && tx.status & (1 << 10) != 0 && k > 5 {
            attained = Some(t);
            break;
        }
    }
    tx = op.cycle(0x000F, 0).await?;
    problems.expect(attained.is_some(), "homing attained");
    table(
        "6. Homing, method 19 (home switch, positive side) on the simulated axis",
        &["0x6061", "result", "time", "position (units)", "statusword"],
        &[vec![
            tx.mode.to_string(),
            match attained {
                Some(_) => "homing attained".into(),
                None => "did not finish".into(),
            },
            attained.map_or("—".into(), |t| format!("{t:.0} ms")),
            tx.position.to_string(),
            format!("{:#06x}", tx.status),
        ]],
    );
    Ok((tx, homing, homing_switch))
}

/// Table 7: a profile-position move with the set-point handshake.
async fn profile_position(
    op: &Op<'_>,
    mut tx: Tx,
    problems: &mut Problems,
) -> Result<Tx, ethercrab::error::Error> {
    tx = op.set_mode(1, tx.position).await?;
    let pp_start = tx.position;
    op.sdo_w(0x6081, 0, 100_000u32).await?;
    op.sdo_w(0x6083, 0, 500_000u32).await?;
    op.sdo_w(0x6084, 0, 500_000u32).await?;
    let target = pp_start + 100_000;
    let t_start = op.t_ms();
    let mut ack_at = None;
    let mut reached_at = None;
    for _ in 0..4000 {
        let cw = if ack_at.is_none() { 0x001F } else { 0x000F };
        tx = op.cycle(cw, target).await?;
        if ack_at.is_none() && tx.status & (1 << 12) != 0 {
            ack_at = Some(op.t_ms() - t_start);
        }
        if ack_at.is_some() && tx.status & (1 << 10) != 0 {
            reached_at = Some(op.t_ms() - t_start);
            break;
        }
    }
    problems.expect(reached_at.is_some(), "PP target reached");
    table(
        "7. Profile position move: 2 revolutions at 2 rev/s, 10 rev/s² (PP, set-point handshake)",
        &[
            "0x6061",
            "target",
            "set-point acknowledged",
            "target reached",
            "final position",
            "error (counts)",
        ],
        &[vec![
            tx.mode.to_string(),
            target.to_string(),
            ack_at.map_or("no".into(), |t| format!("after {t:.0} ms")),
            reached_at.map_or("no".into(), |t| format!("after {t:.0} ms")),
            tx.position.to_string(),
            format!(
                "{:.1}",
                (tx.position - target) as f64 / UNITS_PER_REV * COUNTS_PER_REV
            ),
        ]],
    );
    Ok(tx)
}

/// The CSP run's traces (cycle number, counts or revolutions).
struct CspTraces {
    error: Vec<(f64, f64)>,
    following: Vec<(f64, f64)>,
    target: Vec<(f64, f64)>,
}

/// Table 8: a CSP S-curve at 1 ms cycle with its tracking error.
async fn csp_s_curve(
    op: &Op<'_>,
    mut tx: Tx,
    problems: &mut Problems,
) -> Result<(Tx, CspTraces), ethercrab::error::Error> {
    tx = op.set_mode(8, tx.position).await?;
    let p0 = tx.position as f64;
    // Backwards: the simulated positive limit switch sits at +4 revolutions.
    let dist = -5.0 * UNITS_PER_REV;
    let t_move = 1.5;
    let cycles = (t_move * 1000.0) as usize + 300;
    let (mut csp_error, mut csp_target) = (Vec::new(), Vec::new());
    let mut csp_following = Vec::new();
    let mut prev_target = p0 as i32;
    let mut max_err: f64 = 0.0;
    let mut max_following: f64 = 0.0;
    for k in 0..cycles {
        let t = (k as f64 / 1000.0).min(t_move);
        let s = t / t_move;
        let p =
            p0 + dist * (s - (2.0 * std::f64::consts::PI * s).sin() / (2.0 * std::f64::consts::PI));
        let target = p.round() as i32;
        tx = op.cycle(0x000F, target).await?;
        // The drive answers with the position at the cycle's start: compare with the
        // target of the previous cycle.
        let err = (prev_target - tx.position) as f64 / UNITS_PER_REV * COUNTS_PER_REV;
        prev_target = target;
        // The drive's own following error (position demand − actual at its cycle),
        // without the master's one-cycle transport delay.
        let fe = op
            .group
            .subdevice(op.md, 0)?
            .sdo_read::<i32>(0x60F4, 0)
            .await?;
        let fe = fe as f64 / UNITS_PER_REV * COUNTS_PER_REV;
        if k > 2 {
            max_err = max_err.max(err.abs());
            max_following = max_following.max(fe.abs());
            csp_error.push((k as f64, err));
            csp_following.push((k as f64, fe));
            csp_target.push((k as f64, target as f64 / UNITS_PER_REV));
        }
    }
    problems.expect(max_err < 500.0, "CSP tracking error below 500 counts");
    table(
        "8. CSP: 5 revolutions as an S-curve (cycloidal) in 1.5 s, target every 1 ms cycle",
        &[
            "peak speed",
            "max target − actual (master view)",
            "max 0x60F4 (drive)",
            "final position",
            "final error",
        ],
        &[vec![
            format!("{:.0} rpm", 2.0 * 5.0 / t_move * 60.0),
            format!("{max_err:.1} counts"),
            format!("{max_following:.1} counts"),
            tx.position.to_string(),
            format!(
                "{:.1} counts",
                (prev_target - tx.position) as f64 / UNITS_PER_REV * COUNTS_PER_REV
            ),
        ]],
    );
    Ok((
        tx,
        CspTraces {
            error: csp_error,
            following: csp_following,
            target: csp_target,
        },
    ))
}

/// Table 9: a following-error fault, its reset and a new enable.
async fn fault_and_reset(
    op: &Op<'_>,
    mut tx: Tx,
    problems: &mut Problems,
) -> Result<(), ethercrab::error::Error> {
    op.sdo_w(0x6065, 0, 500u32).await?;
    op.sdo_w(0x6066, 0, 5u16).await?;
    let jump = tx.position + 50_000;
    let mut rows = Vec::new();
    // The demand follows the jump no faster than 0x6080; the axis lags, the fault
    // reaction ramps down from the actual speed, then the drive is in Fault.
    for _ in 0..2000 {
        tx = op.cycle(0x000F, jump).await?;
        if tx.status & 0x4F == 0x08 {
            break;
        }
    }
    problems.expect(tx.error == 0x8611, "following-error fault 0x8611");
    rows.push(vec![
        "target jumps by one revolution (following error window 500 units, 5 ms)".into(),
        format!("{:#06x}", tx.status),
        pds_state(tx.status).into(),
        format!("{:#06x}", tx.error),
    ]);
    let hold = tx.position;
    tx = op.cycle(0x0000, hold).await?;
    for _ in 0..3 {
        tx = op.cycle(0x0080, hold).await?;
    }
    rows.push(vec![
        "fault reset (controlword bit 7 rising edge)".into(),
        format!("{:#06x}", tx.status),
        pds_state(tx.status).into(),
        format!("{:#06x}", tx.error),
    ]);
    for (cw, state) in [(0x0006u16, 0x21u16), (0x0007, 0x23), (0x000F, 0x27)] {
        tx = op.until_state(cw, state, 2000, tx.position).await?.0;
    }
    problems.expect(
        tx.status & 0x6F == 0x27,
        "Operation enabled again after the reset",
    );
    rows.push(vec![
        "enable again".into(),
        format!("{:#06x}", tx.status),
        pds_state(tx.status).into(),
        format!("{:#06x}", tx.error),
    ]);
    op.sdo_w(0x6065, 0, 50_000u32).await?;
    table(
        "9. A fault and its reset",
        &["event", "statusword", "state", "0x603F"],
        &rows,
    );
    Ok(())
}

/// Table 10: the emergencies the master read from the mailbox (times from `t0`).
fn emergency_report(w: &SimWire, t0: u64) {
    let rows: Vec<Vec<String>> = w
        .emergencies
        .iter()
        .map(|(t, code, reg, m)| {
            vec![
                format!("{:.0} ms", (*t - t0) as f64 * 1e-6),
                format!("{code:#06x}"),
                format!("{reg:#04x}"),
                m.iter()
                    .map(|b| format!("{b:02x}"))
                    .collect::<Vec<_>>()
                    .join(" "),
            ]
        })
        .collect();
    table(
        "10. Emergency messages the master read from the mailbox",
        &[
            "read by the master at",
            "error code",
            "error register",
            "manufacturer bytes",
        ],
        &rows,
    );
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

    // --- plots ------------------------------------------------------------------------
    if let Err(e) = std::fs::create_dir_all(&out) {
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
    let _ = traces.csp_target;
}
