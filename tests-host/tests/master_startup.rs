//! Start-up matrix: each master's documented start-up sequence, against the product
//! drive (the firmware's `Drive` behind the slave runtime and the ESC simulator), on
//! both ESC flavours, in every synchronisation mode:
//!
//! | row | how it is played | source of the sequence |
//! |---|---|---|
//! | ethercrab | the real ethercrab 0.7 in-process (`set_dc_sync`, `configure_dc_sync`) | ethercrab `src/subdevice_group/mod.rs` (`configure_dc_sync`, `into_safe_op`) |
//! | SOEM | the datagrams SOEM sends, replayed | SOEM `src/ec_config.c` (`ecx_config_init`, `ecx_config_map_group`; `ethercatconfig.c` in 1.4), `src/ec_dc.c` (`ecx_configdc`, `ecx_dcsync0`, `ecx_dcsync01`; `ethercatdc.c` in 1.4) |
//! | TwinCAT | its ESI-driven init commands, replayed | no public source: the start-up list TwinCAT builds from the ESI (ETG.2000 InitCmds) |
//! | IgH | the datagrams of its slave configuration state machine, replayed | IgH `master/fsm_slave_config.c` (state order), `master/fsm_pdo.c` (PDO SDOs), `master/slave_config.c` (`ecrt_slave_config_dc`) |
//!
//! Modes: free run, SM-synchronous, DC SYNC0 at 1 ms / 250 µs / 125 µs. Every row
//! checks: Op reached; 0x1C32 / 0x1C33 SI 1, 2 and 4; the application cycles (a
//! [`Counting`] wrapper around the product drive) against the SYNC0 pulses of the
//! simulator (DC: exactly one per SYNC0), the LRW frames (SM-synchronous: one per
//! frame) or the local 1 ms timer (free run). And per master and flavour: an
//! unsupported cycle time (300 µs) is refused with 0x0035, a sync type written
//! against 0x0981 (0x1C32:01 = 1 with SYNC0 armed) with 0x0028, SYNC0 + SYNC1
//! (0x0981 = 0x07, not supported) with 0x0030.
//!
//! Where the refusal comes: masters that arm SYNC0 in Pre-Op (ethercrab, TwinCAT,
//! IgH) get it at Pre-Op→Safe-Op; SOEM requests Safe-Op inside
//! `ecx_config_map_group`, before `ecx_dcsync0`, so the drive takes the DC
//! registers into account in Safe-Op and refuses Safe-Op→Op. Either way the drive
//! ends in Pre-Op with the error bit and the code (0x12 + code).

use std::cell::RefCell;
use std::rc::Rc;

use ethercrab::{MainDevice, PduStorage};
use tests_host::counting::{self, Counting};
use tests_host::esc_sim::Flavour;
use tests_host::ethercrab_seam::{sim_config, sim_now_ns, sim_timeouts, MasterHarness};
use tests_host::raw_master::RawMaster;
use tests_host::segment::Segment;
use tests_host::sim_drive::SimDrive;

type Seg = Segment<Counting<SimDrive>>;
type Master = RawMaster<Counting<SimDrive>>;

const STATION: u16 = 0x1001;
/// Bytes of the product's default mapping (0x1600 / 0x1A00).
const OUT_BYTES: usize = 12;
const IN_BYTES: usize = 19;
/// SYNC0 + SYNC1 requested by the master (not supported by the drive).
const SYNC01: u8 = 0x07;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    FreeRun,
    SmSync,
    Dc(u32),
}

const MODES: [Mode; 5] = [
    Mode::FreeRun,
    Mode::SmSync,
    Mode::Dc(1_000_000),
    Mode::Dc(250_000),
    Mode::Dc(125_000),
];

impl Mode {
    /// The master's cycle, ns.
    fn cycle_ns(self) -> u64 {
        match self {
            Mode::Dc(c) => c as u64,
            _ => 1_000_000,
        }
    }
    /// Expected 0x1C32:01 / 0x1C33:01.
    fn types(self) -> (u64, u64) {
        match self {
            Mode::FreeRun => (0, 0),
            Mode::SmSync => (1, 0x22),
            Mode::Dc(_) => (2, 2),
        }
    }
}

/// What a run asks the master to do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Plan {
    mode: Mode,
    /// 0x1C32:01 written by the application / init commands (None: not written).
    written: Option<u16>,
    /// 0x0981 value armed in DC modes (0x03 SYNC0, 0x07 SYNC0 + SYNC1).
    activation: u8,
}

impl Plan {
    fn normal(mode: Mode) -> Self {
        Plan {
            mode,
            // Free run can only be asked for by writing the sync type.
            written: (mode == Mode::FreeRun).then_some(0),
            activation: 0x03,
        }
    }
}

/// What a run saw.
#[derive(Debug, Default)]
struct Outcome {
    /// AL status and code after the start-up (Op expected, or the refusal).
    status: (u16, u16),
    /// 0x1C32 SI 1, 2, 4 and 0x1C33 SI 1, 2, 4 read in Op.
    si: [u64; 6],
    /// Application cycles / SYNC0 pulses / LRW frames / simulated ns over the
    /// measured window in Op.
    cycles: u64,
    dc_cycles: u64,
    pulses: u64,
    lrw: u64,
    elapsed_ns: u64,
}

fn counts(seg: &Seg) -> (u64, u64, u64) {
    let d = seg.drive(0);
    let pulses = seg.esc(0).stats().sync0_pulses;
    (d.app.counts.in_op, d.app.counts.dc_sync0, pulses)
}

/// The checks every successful row makes.
fn check_op(ctx: &str, plan: Plan, o: &Outcome) {
    assert_eq!(o.status, (0x08, 0), "{ctx}: Op");
    let (t2, t3) = plan.mode.types();
    let cycle = plan.mode.cycle_ns();
    assert_eq!((o.si[0], o.si[3]), (t2, t3), "{ctx}: 0x1C32:01 / 0x1C33:01");
    assert_eq!((o.si[2], o.si[5]), (7, 7), "{ctx}: 0x1C32:04 / 0x1C33:04");
    match plan.mode {
        // The measured master cycle: within 2 % of the master's.
        Mode::SmSync => {
            for si2 in [o.si[1], o.si[4]] {
                assert!(si2.abs_diff(cycle) * 50 <= cycle, "{ctx}: SI2 {si2}");
            }
        }
        _ => assert_eq!((o.si[1], o.si[4]), (cycle, cycle), "{ctx}: SI2"),
    }
    match plan.mode {
        Mode::Dc(_) => {
            assert!(o.pulses >= 40, "{ctx}: SYNC0 pulses {}", o.pulses);
            assert_eq!(o.cycles, o.pulses, "{ctx}: one cycle per SYNC0");
            assert_eq!(o.dc_cycles, o.pulses, "{ctx}: all cycles in DC mode");
        }
        Mode::SmSync => {
            assert_eq!(o.pulses, 0, "{ctx}: no SYNC0");
            assert!(o.lrw >= 40);
            assert_eq!(o.cycles, o.lrw, "{ctx}: one cycle per SM2 event");
        }
        Mode::FreeRun => {
            assert_eq!(o.pulses, 0, "{ctx}: no SYNC0");
            let want = o.elapsed_ns / 1_000_000;
            assert!(
                o.cycles.abs_diff(want) <= 1,
                "{ctx}: free run {} cycles in {} ns",
                o.cycles,
                o.elapsed_ns
            );
        }
    }
}

fn check_refused(ctx: &str, o: &Outcome, code: u16) {
    assert_eq!(o.status, (0x12, code), "{ctx}: refused");
}

// ---- raw-datagram masters --------------------------------------------------------

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Raw {
    Soem,
    TwinCat,
    Igh,
}

fn raw_master(flavour: Flavour) -> Master {
    let seg = counting::product_segment(flavour, 1).expect("segment");
    let mut m = RawMaster::new(seg);
    m.after = |seg: &mut Seg| {
        let now_us = seg.now_ns() / 1000;
        for d in seg.drives_mut() {
            d.app.inner.catch_up(now_us);
        }
    };
    m
}

/// Common to the three: ring scan, station address, SII identity and mailbox
/// words, mailbox SyncManagers, Init→Pre-Op.
fn init_to_preop(m: &mut Master, who: Raw) {
    // SOEM ecx_config_init: BWR AL control = Init + ack, then BRD 0x0000 counts.
    assert_eq!(m.bwr(0x0120, &0x0011u16.to_le_bytes()), 1);
    assert_eq!(m.brd(0x0000, 2).1, 1, "one slave");
    if who == Raw::Soem {
        // ecx_config_init also resets FMMUs, SMs and the DC activation by BWR.
        m.bwr(0x0600, &[0; 48]);
        m.bwr(0x0800, &[0; 32]);
        m.bwr(0x0981, &[0]);
    }
    assert_eq!(m.apwr(0, 0x0010, &STATION.to_le_bytes()), 1);
    // Identity (SII words 8..0x0F) and standard mailbox (0x18..0x1B).
    let vendor = m.sii_read(STATION, 0x08).expect("SII");
    assert_eq!(vendor, 0x0000_0E5C);
    let out = m.sii_read(STATION, 0x18).expect("SII");
    let inp = m.sii_read(STATION, 0x1A).expect("SII");
    m.mbx = (
        out as u16,
        (out >> 16) as u16,
        inp as u16,
        (inp >> 16) as u16,
    );
    // SOEM writes SM0 and SM1 in one 16-byte datagram; IgH and TwinCAT the same
    // area (IgH: fsm_slave_config "mailbox sync").
    let mbx = m.mbx;
    assert_eq!(m.configure_mailbox(STATION, mbx), 1);
    // EEPROM to the PDI before Pre-Op (SOEM ecx_eeprom2pdi).
    m.fpwr(STATION, 0x0500, &[0x01]);
    m.request_state(STATION, 0x02);
    let st = m.wait_state(STATION, 0x02, 50_000_000, 1_000_000, |_| {});
    assert_eq!(st, (0x02, 0), "{who:?}: Pre-Op");
}

fn sdo_w(m: &mut Master, index: u16, sub: u8, data: &[u8]) {
    m.sdo_download(STATION, index, sub, data)
        .unwrap_or_else(|e| panic!("SDO download {index:#06x}:{sub}: {e:?}"));
}

fn sdo_r(m: &mut Master, index: u16, sub: u8) -> u64 {
    m.sdo_upload(STATION, index, sub)
        .unwrap_or_else(|e| panic!("SDO upload {index:#06x}:{sub}: {e:?}"))
}

/// Writes the product's default mapping and assignment by SDO (TwinCAT's init
/// commands from the ESI; IgH's PDO configuration from the application's PDO list,
/// fsm_pdo.c: mapping of each PDO — count 0, entries, count — then the assignment).
fn write_pdos(m: &mut Master, assign_first: bool) {
    use firmware::pdo_defaults::PDO_DEFAULTS as D;
    for (assign, maps, base) in [(0x1C12u16, &D.rx, 0x1600u16), (0x1C13, &D.tx, 0x1A00)] {
        let list = if assign == 0x1C12 {
            D.rx_assign
        } else {
            D.tx_assign
        };
        if assign_first {
            sdo_w(m, assign, 0, &[0]);
        }
        for &pdo in list {
            let entries = maps[(pdo - base) as usize];
            sdo_w(m, pdo, 0, &[0]);
            for (i, e) in entries.iter().enumerate() {
                sdo_w(m, pdo, i as u8 + 1, &e.to_le_bytes());
            }
            sdo_w(m, pdo, 0, &[entries.len() as u8]);
        }
        if !assign_first {
            sdo_w(m, assign, 0, &[0]);
        }
        for (i, &pdo) in list.iter().enumerate() {
            sdo_w(m, assign, i as u8 + 1, &pdo.to_le_bytes());
        }
        sdo_w(m, assign, 0, &[list.len() as u8]);
    }
}

/// SOEM ecx_readPDOmap (ec_config.c / ec_coe.c): 0x1C00 SM types, then for SM2 and
/// SM3 the assignment and every assigned map; returns (output, input) bytes.
fn soem_read_pdo_map(m: &mut Master) -> (usize, usize) {
    let n = sdo_r(m, 0x1C00, 0);
    assert!(n >= 4, "0x1C00:00 = {n}");
    assert_eq!(sdo_r(m, 0x1C00, 3), 3);
    assert_eq!(sdo_r(m, 0x1C00, 4), 4);
    let mut bytes = [0usize; 2];
    for (k, assign) in [0x1C12u16, 0x1C13].into_iter().enumerate() {
        let mut bits = 0;
        for i in 1..=sdo_r(m, assign, 0) as u8 {
            let pdo = sdo_r(m, assign, i) as u16;
            for j in 1..=sdo_r(m, pdo, 0) as u8 {
                bits += sdo_r(m, pdo, j) & 0xFF;
            }
        }
        bytes[k] = bits.div_ceil(8) as usize;
    }
    (bytes[0], bytes[1])
}

/// DC as TwinCAT (start time, cycle, then 0x0980 = AssignActivate as one u16) and
/// IgH (fsm_slave_config dc_cycle: 0x09A0 with SYNC1 cycle, dc_sync_check: 0x092C,
/// dc_start: 0x0990, dc_assign: 0x0980 u16).
fn assign_activate_dc(m: &mut Master, who: Raw, cycle: u32, shift: u32, activation: u8) {
    let assign = (activation as u16) << 8;
    let now = m.fprd_u64(STATION, 0x0910);
    let start = (now + 100_000_000) / cycle as u64 * cycle as u64 + shift as u64;
    if who == Raw::Igh {
        let mut c = [0u8; 8];
        c[0..4].copy_from_slice(&cycle.to_le_bytes());
        m.fpwr(STATION, 0x09A0, &c);
        m.fprd(STATION, 0x092C, 4);
        m.fpwr(STATION, 0x0990, &start.to_le_bytes());
    } else {
        m.fpwr(STATION, 0x0990, &start.to_le_bytes());
        m.fpwr(STATION, 0x09A0, &cycle.to_le_bytes());
    }
    m.fpwr(STATION, 0x0980, &assign.to_le_bytes());
}

/// The cyclic exchange's LRWs with the right working counter so far.
fn good_lrws(m: &Master) -> u64 {
    m.cyclic.map_or(0, |c| c.good)
}

fn raw_run(who: Raw, flavour: Flavour, plan: Plan) -> Outcome {
    let mut m = raw_master(flavour);
    init_to_preop(&mut m, who);
    let dc_cycle = match plan.mode {
        Mode::Dc(c) => Some(c),
        _ => None,
    };
    let (out, inp) = match who {
        Raw::Soem => {
            // ecx_config_map_group: the PO2SO hook (the application's SDOs) runs
            // before the mapping is read.
            if let Some(t) = plan.written {
                sdo_w(&mut m, 0x1C32, 1, &t.to_le_bytes());
            }
            soem_read_pdo_map(&mut m)
        }
        Raw::TwinCat => {
            // Init commands P→S from the ESI: assignment cleared first, maps,
            // assignment; then the sync types of the chosen op mode; 0x1C32:05.
            write_pdos(&mut m, true);
            let (t2, t3) = match (plan.written, dc_cycle) {
                (Some(t), _) => (t, if t == 1 { 0x22 } else { t }),
                (None, Some(_)) => (2, 2),
                (None, None) => (1, 0x22),
            };
            sdo_w(&mut m, 0x1C32, 1, &t2.to_le_bytes());
            sdo_w(&mut m, 0x1C33, 1, &t3.to_le_bytes());
            if let Some(c) = dc_cycle {
                let min = sdo_r(&mut m, 0x1C32, 5);
                assert!(min <= c as u64 || c == 300_000, "0x1C32:05 = {min}");
            }
            (OUT_BYTES, IN_BYTES)
        }
        Raw::Igh => {
            // ecrt_slave_config_sdo*(): the application's SDOs first, then the
            // PDO configuration (fsm_pdo.c), then watchdog, SMs, FMMUs, DC.
            if let Some(t) = plan.written {
                sdo_w(&mut m, 0x1C32, 1, &t.to_le_bytes());
            }
            write_pdos(&mut m, false);
            m.fpwr(STATION, 0x0400, &2498u16.to_le_bytes());
            m.fpwr(STATION, 0x0420, &1000u16.to_le_bytes());
            (OUT_BYTES, IN_BYTES)
        }
    };
    assert_eq!((out, inp), (OUT_BYTES, IN_BYTES), "{who:?}: mapping sizes");
    assert_eq!(m.process_data_sms(STATION, 0, out, inp), 2);
    if let (Some(c), Raw::TwinCat | Raw::Igh) = (dc_cycle, who) {
        assign_activate_dc(&mut m, who, c, 0, plan.activation);
    }
    m.request_state(STATION, 0x04);
    if let (Some(c), Raw::Soem) = (dc_cycle, who) {
        // After ecx_config_map_group (Safe-Op already requested): ecx_configdc,
        // then the application's ecx_dcsync0 / ecx_dcsync01.
        m.soem_configdc(STATION, 789_000_000_000);
        m.soem_dcsync(STATION, c, 0, plan.activation);
    }
    let cycle = plan.mode.cycle_ns();
    let st = m.wait_state(STATION, 0x04, 50_000_000, 1_000_000, |_| {});
    if st != (0x04, 0) {
        return Outcome {
            status: st,
            ..Outcome::default()
        };
    }
    // The cyclic LRW from Safe-Op on (SOEM: ecx_send_processdata before the Op
    // request), then Op; the master polls AL status every ms.
    m.start_cyclic(cycle, OUT_BYTES + IN_BYTES, 3);
    m.wait(2 * cycle, cycle);
    m.request_state(STATION, 0x08);
    let st = m.wait_state(STATION, 0x08, 2_000_000_000, 1_000_000, |_| {});
    if st != (0x08, 0) {
        return Outcome {
            status: st,
            ..Outcome::default()
        };
    }
    m.wait(5 * cycle, cycle);
    let (c0, d0, p0) = counts(&m.seg);
    let (t0, l0) = (m.seg.now_ns(), good_lrws(&m));
    m.wait(60 * cycle, cycle);
    let (c1, d1, p1) = counts(&m.seg);
    let elapsed_ns = m.seg.now_ns() - t0;
    let lrw = good_lrws(&m) - l0;
    let mut si = [0u64; 6];
    for (k, (index, sub)) in [
        (0x1C32u16, 1u8),
        (0x1C32, 2),
        (0x1C32, 4),
        (0x1C33, 1),
        (0x1C33, 2),
        (0x1C33, 4),
    ]
    .into_iter()
    .enumerate()
    {
        si[k] = sdo_r(&mut m, index, sub);
    }
    Outcome {
        status: m.al_status(STATION),
        si,
        cycles: c1 - c0,
        dc_cycles: d1 - d0,
        pulses: p1 - p0,
        lrw,
        elapsed_ns,
    }
}

// ---- ethercrab ------------------------------------------------------------------

const MAX_SUBDEVICES: usize = 4;
const MAX_PDI: usize = 128;
static PDU_STORAGE: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

/// 0x1C32 / 0x1C33 SI 1, 2, 4 through ethercrab's SDO upload.
macro_rules! ethercrab_si {
    ($sd:expr) => {{
        let sd = $sd;
        [
            u64::from(sd.sdo_read::<u16>(0x1C32, 1).await?),
            u64::from(sd.sdo_read::<u32>(0x1C32, 2).await?),
            u64::from(sd.sdo_read::<u16>(0x1C32, 4).await?),
            u64::from(sd.sdo_read::<u16>(0x1C33, 1).await?),
            u64::from(sd.sdo_read::<u32>(0x1C33, 2).await?),
            u64::from(sd.sdo_read::<u16>(0x1C33, 4).await?),
        ]
    }};
}

/// The measuring window in Op: 5 cycles to settle, then 60 counted ones.
macro_rules! ethercrab_window {
    ($md:expr, $seg:expr, $cycle:expr, $exchange:expr) => {{
        for _ in 0..5 {
            $exchange;
            counting::advance(&mut $seg.borrow_mut(), $cycle);
        }
        let (c0, d0, p0) = counts(&$seg.borrow());
        let t0 = $seg.borrow().now_ns();
        let mut lrw = 0;
        for _ in 0..60 {
            if $exchange.working_counter == 3 {
                lrw += 1;
            }
            counting::advance(&mut $seg.borrow_mut(), $cycle);
        }
        let (c1, d1, p1) = counts(&$seg.borrow());
        Outcome {
            status: $seg.borrow().al_status(0),
            si: [0; 6],
            cycles: c1 - c0,
            dc_cycles: d1 - d0,
            pulses: p1 - p0,
            lrw,
            elapsed_ns: $seg.borrow().now_ns() - t0,
        }
    }};
}

/// ethercrab's own start-up (bringup.rs does the same with the test drive):
/// `init_single_group`, SDOs of the application in Pre-Op, `set_dc_sync`,
/// `into_pre_op_pdi`, static drift compensation, `configure_dc_sync` (0x0981 = 0,
/// start time, 0x09A0, [0x09A4], 0x0981 = 0x03 / 0x07), `into_safe_op`,
/// `request_into_op` with `tx_rx_dc` until all are in Op.
async fn ethercrab_run(
    md: Rc<MainDevice<'static>>,
    seg: Rc<RefCell<Seg>>,
    plan: Plan,
) -> Result<Outcome, ethercrab::error::Error> {
    use ethercrab::subdevice_group::DcConfiguration;
    use ethercrab::DcSync;
    use std::time::Duration;
    let refused = |seg: &Rc<RefCell<Seg>>| Outcome {
        status: seg.borrow().al_status(0),
        ..Outcome::default()
    };
    let mut group = md
        .init_single_group::<MAX_SUBDEVICES, MAX_PDI>(sim_now_ns)
        .await?;
    let dc = match plan.mode {
        Mode::Dc(c) => Some(c),
        _ => None,
    };
    for mut sd in group.iter_mut(&md) {
        if let Some(t) = plan.written {
            sd.sdo_write(0x1C32, 1, t).await?;
        }
        if dc.is_some() {
            sd.set_dc_sync(if plan.activation == SYNC01 {
                DcSync::Sync01 {
                    sync1_period: Duration::from_micros(0),
                }
            } else {
                DcSync::Sync0
            });
        }
    }
    let cycle = plan.mode.cycle_ns();
    let group = group.into_pre_op_pdi(&md).await?;
    let Some(c) = dc else {
        let Ok(group) = group.into_safe_op(&md).await else {
            return Ok(refused(&seg));
        };
        let group = group.into_op(&md).await?;
        let mut o = ethercrab_window!(md, seg, cycle, group.tx_rx(&md).await?);
        o.si = ethercrab_si!(group.subdevice(&md, 0)?);
        return Ok(o);
    };
    for _ in 0..20 {
        group.tx_rx_sync_system_time(&md).await?;
        counting::advance(&mut seg.borrow_mut(), 1_000_000);
    }
    let group = group
        .configure_dc_sync(
            &md,
            DcConfiguration {
                start_delay: Duration::from_millis(5),
                sync0_period: Duration::from_nanos(c as u64),
                sync0_shift: Duration::from_nanos(c as u64 / 2),
            },
        )
        .await?;
    let Ok(group) = group.into_safe_op(&md).await else {
        return Ok(refused(&seg));
    };
    let group = group.request_into_op(&md).await?;
    for _ in 0..3000 {
        let r = group.tx_rx_dc(&md).await?;
        counting::advance(&mut seg.borrow_mut(), cycle);
        if r.all_op() {
            break;
        }
    }
    if seg.borrow().al_status(0) != (0x08, 0) {
        return Ok(refused(&seg));
    }
    let mut o = ethercrab_window!(md, seg, cycle, group.tx_rx_dc(&md).await?);
    o.si = ethercrab_si!(group.subdevice(&md, 0)?);
    Ok(o)
}

// ---- the matrix -------------------------------------------------------------------

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Row {
    Ethercrab,
    Raw(Raw),
}

const ROWS: [Row; 4] = [
    Row::Ethercrab,
    Row::Raw(Raw::Soem),
    Row::Raw(Raw::TwinCat),
    Row::Raw(Raw::Igh),
];

fn run(h: &mut MasterHarness, row: Row, flavour: Flavour, plan: Plan) -> Outcome {
    match row {
        Row::Raw(who) => raw_run(who, flavour, plan),
        Row::Ethercrab => {
            let seg = Rc::new(RefCell::new(
                counting::product_segment(flavour, 1).expect("segment"),
            ));
            let s2 = seg.clone();
            let (res, stats) = h.run(seg.clone(), sim_timeouts(), sim_config(), |md| {
                ethercrab_run(md, s2, plan)
            });
            res.unwrap_or_else(|e| {
                let st = seg.borrow().al_status(0);
                panic!("ethercrab {flavour:?} {plan:?}: {e:?}; AL {st:04x?}; {stats:?}")
            })
        }
    }
}

/// One test for the whole matrix: ethercrab's `PduStorage` is split once per test
/// binary, so its rows must run in one test, and the raw rows go with them.
#[test]
fn every_master_reaches_op_in_every_mode_and_refuses_what_it_must() {
    let mut h = MasterHarness::new(&PDU_STORAGE).expect("storage split once");
    for flavour in [Flavour::Lan9252, Flavour::Et1100] {
        for row in ROWS {
            for mode in MODES {
                let plan = Plan::normal(mode);
                let o = run(&mut h, row, flavour, plan);
                let ctx = format!("{row:?} {flavour:?} {mode:?}");
                check_op(&ctx, plan, &o);
                eprintln!(
                    "{ctx}: Op, SI {:x?}, {} cycles / {} SYNC0 / {} LRW in {} µs",
                    o.si,
                    o.cycles,
                    o.pulses,
                    o.lrw,
                    o.elapsed_ns / 1000
                );
            }
            let refusals = [
                ("300 µs cycle", Plan::normal(Mode::Dc(300_000)), 0x0035),
                (
                    "0x1C32:01 = 1 with SYNC0",
                    Plan {
                        written: Some(1),
                        ..Plan::normal(Mode::Dc(1_000_000))
                    },
                    0x0028,
                ),
                (
                    "SYNC0 + SYNC1",
                    Plan {
                        activation: SYNC01,
                        ..Plan::normal(Mode::Dc(1_000_000))
                    },
                    0x0030,
                ),
            ];
            for (what, plan, code) in refusals {
                let o = run(&mut h, row, flavour, plan);
                let ctx = format!("{row:?} {flavour:?} {what}");
                check_refused(&ctx, &o, code);
                eprintln!("{ctx}: refused, AL {:04x?}", o.status);
            }
        }
    }
}
