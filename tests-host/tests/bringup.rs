//! ethercrab 0.7 brings simulated drives from INIT to OP and back, in-process.
//!
//! One `PduStorage` per test binary: every ethercrab scenario runs sequentially inside
//! the single test `ethercrab_bringup`. Segments of 1 and 8 drives, LAN9252 and ET1100
//! flavours, PDI direct and through the chip driver + SPI model.

use ecat_slave_stack::od::ObjectKey;
use ethercrab::{MainDevice, PduStorage, SubDeviceState};
use std::cell::RefCell;
use std::rc::Rc;
use tests_host::esc_sim::Flavour;
use tests_host::ethercrab_seam::{sim_config, sim_now_ns, sim_timeouts, MasterHarness, NetStats};
use tests_host::segment::{
    test_segment, PdiPath, Segment, SegmentConfig, TestDrive, TEST_PD_BYTES,
};

const MAX_SUBDEVICES: usize = 16;
const MAX_PDI: usize = 256;
const MAX_FRAMES: usize = 16;

static PDU_STORAGE: PduStorage<MAX_FRAMES, { PduStorage::element_size(1100) }> = PduStorage::new();

#[derive(Debug, Default)]
struct Report {
    names: Vec<String>,
    identities: Vec<(u32, u32, u32)>,
    addresses: Vec<u16>,
    op_wkc: Vec<u16>,
    echo_ok: bool,
    states_after_op: Vec<u16>,
    device_types: Vec<u32>,
    targets: Vec<i32>,
    sdo_abort: Option<bool>,
}

async fn bring_up(
    md: Rc<MainDevice<'static>>,
    seg: Rc<RefCell<Segment<TestDrive>>>,
    cycles: usize,
) -> Result<Report, ethercrab::error::Error> {
    let mut rep = Report::default();
    let group = md
        .init_single_group::<MAX_SUBDEVICES, MAX_PDI>(sim_now_ns)
        .await?;
    for sd in group.iter(&md) {
        let long = sd
            .description()
            .await?
            .map(|s| s.to_string())
            .unwrap_or_default();
        rep.names.push(format!("{}|{}", sd.name(), long));
        let id = sd.identity();
        rep.identities
            .push((id.vendor_id, id.product_id, id.revision));
        rep.addresses.push(sd.configured_address());
    }
    // Expedited SDO traffic through the mailbox SyncManagers.
    for (i, sd) in group.iter(&md).enumerate() {
        rep.device_types.push(sd.sdo_read::<u32>(0x1000, 0).await?);
        sd.sdo_write(0x607A, 0, 0x1234_0000i32 + i as i32).await?;
        rep.targets.push(sd.sdo_read::<i32>(0x607A, 0).await?);
        rep.sdo_abort = Some(sd.sdo_read::<u32>(0x5555, 0).await.is_err());
    }
    let group = group.into_op(&md).await?;
    {
        let s = seg.borrow();
        rep.states_after_op = (0..s.len()).map(|i| s.al_status(i).0).collect();
    }
    let mut echo_ok = true;
    for k in 0..cycles {
        for (i, sd) in group.iter(&md).enumerate() {
            let mut o = sd.outputs_raw_mut();
            let cw = 0x0006u16 + k as u16 + i as u16;
            let target = 1000 * k as i32 - i as i32;
            o[0..2].copy_from_slice(&cw.to_le_bytes());
            o[2..6].copy_from_slice(&target.to_le_bytes());
        }
        let r = group.tx_rx(&md).await?;
        rep.op_wkc.push(r.working_counter);
        if r.subdevice_states.iter().any(|s| *s != SubDeviceState::Op) {
            echo_ok = false;
        }
        // The drive answered the outputs of this cycle: the next LRW carries them
        // back, so check the inputs of the previous cycle.
        if k >= 2 {
            for (i, sd) in group.iter(&md).enumerate() {
                let inp = sd.inputs_raw();
                let sw = u16::from_le_bytes([inp[0], inp[1]]);
                let pos = i32::from_le_bytes([inp[2], inp[3], inp[4], inp[5]]);
                let prev = k - 1;
                if sw != 0x0007 + prev as u16 + i as u16 || pos != 1000 * prev as i32 - i as i32 {
                    echo_ok = false;
                }
            }
        }
        seg.borrow_mut().advance(1_000_000);
    }
    rep.echo_ok = echo_ok;
    let group = group.into_safe_op(&md).await?;
    let group = group.into_pre_op(&md).await?;
    let _group = group.into_init(&md).await?;
    Ok(rep)
}

/// DC-synchronous bring-up: SYNC0 at 1 ms, the drives lock to it before entering Op.
async fn bring_up_dc(
    md: Rc<MainDevice<'static>>,
    seg: Rc<RefCell<Segment<TestDrive>>>,
) -> Result<(Vec<u16>, u64, usize), ethercrab::error::Error> {
    use ethercrab::subdevice_group::DcConfiguration;
    use ethercrab::DcSync;
    use std::time::Duration;
    let mut group = md
        .init_single_group::<MAX_SUBDEVICES, MAX_PDI>(sim_now_ns)
        .await?;
    for mut sd in group.iter_mut(&md) {
        sd.set_dc_sync(DcSync::Sync0);
    }
    let group = group.into_pre_op_pdi(&md).await?;
    for _ in 0..20 {
        group.tx_rx_sync_system_time(&md).await?;
        seg.borrow_mut().advance(1_000_000);
    }
    let group = group
        .configure_dc_sync(
            &md,
            DcConfiguration {
                start_delay: Duration::from_millis(5),
                sync0_period: Duration::from_millis(1),
                sync0_shift: Duration::from_micros(500),
            },
        )
        .await?;
    let group = group.into_safe_op(&md).await?;
    let group = group.request_into_op(&md).await?;
    let mut cycles_to_op = 0;
    loop {
        let r = group.tx_rx_dc(&md).await?;
        seg.borrow_mut().advance(1_000_000);
        cycles_to_op += 1;
        if r.all_op() || cycles_to_op > 2000 {
            break;
        }
    }
    let mut wkcs = Vec::new();
    for _ in 0..20 {
        wkcs.push(group.tx_rx_dc(&md).await?.working_counter);
        seg.borrow_mut().advance(1_000_000);
    }
    let pulses = seg.borrow().esc(0).stats().sync0_pulses;
    let group = group.into_safe_op(&md).await?;
    let _ = group.into_pre_op(&md).await?.into_init(&md).await?;
    Ok((wkcs, pulses, cycles_to_op))
}

/// ethercrab writes a new station alias into the SII (word 4 + checksum word 7).
async fn write_alias(md: Rc<MainDevice<'static>>) -> Result<Vec<u16>, ethercrab::error::Error> {
    let mut group = md
        .init_single_group::<MAX_SUBDEVICES, MAX_PDI>(sim_now_ns)
        .await?;
    let mut aliases = Vec::new();
    for (i, mut sd) in group.iter_mut(&md).enumerate() {
        sd.set_alias_address(0x0770 + i as u16).await?;
        aliases.push(sd.alias_address());
    }
    Ok(aliases)
}

fn scenario(
    h: &mut MasterHarness,
    cfg: SegmentConfig,
    n: usize,
) -> (Report, NetStats, Rc<RefCell<Segment<TestDrive>>>) {
    let seg = Rc::new(RefCell::new(test_segment(cfg, n).expect("segment")));
    let s2 = seg.clone();
    let (res, stats) = h.run(seg.clone(), sim_timeouts(), sim_config(), |md| {
        bring_up(md, s2, 12)
    });
    let rep = res.unwrap_or_else(|e| {
        let s = seg.borrow();
        let st: Vec<_> = (0..s.len()).map(|i| s.al_status(i)).collect();
        panic!("{cfg:?} x{n}: ethercrab error {e:?}; AL status/code per drive {st:04x?}; {stats:?}")
    });
    (rep, stats, seg)
}

#[test]
fn ethercrab_bringup() {
    let mut h = MasterHarness::new(&PDU_STORAGE).expect("storage split once");
    let cases = [
        (SegmentConfig::new(Flavour::Lan9252), 1),
        (SegmentConfig::new(Flavour::Et1100), 1),
        (SegmentConfig::new(Flavour::Lan9252), 8),
        (SegmentConfig::new(Flavour::Et1100), 8),
        (
            SegmentConfig::new(Flavour::Lan9252).with_pdi(PdiPath::Spi),
            1,
        ),
        (
            SegmentConfig::new(Flavour::Et1100).with_pdi(PdiPath::Spi),
            1,
        ),
        (
            SegmentConfig::new(Flavour::Lan9252).with_pdi(PdiPath::Spi),
            8,
        ),
        (
            SegmentConfig::new(Flavour::Et1100).with_pdi(PdiPath::Spi),
            8,
        ),
    ];
    for (cfg, n) in cases {
        let (rep, stats, seg) = scenario(&mut h, cfg, n);
        let ctx = format!("{cfg:?} x{n}");
        assert_eq!(rep.names.len(), n, "{ctx}: discovered drives");
        for (i, name) in rep.names.iter().enumerate() {
            // ethercrab's name() is the SII order string, description() the name string.
            assert_eq!(
                name, "ECS-HS|ECS-HS EtherCAT hybrid servo",
                "{ctx}: names from SII strings"
            );
            assert_eq!(
                rep.identities[i],
                (0x0000_0E5C, 0x0000_5840, 0x0001_0000),
                "{ctx}: identity from SII"
            );
            assert_eq!(
                rep.addresses[i],
                0x1000 + i as u16,
                "{ctx}: configured address"
            );
        }
        assert!(
            rep.states_after_op.iter().all(|&s| s == 0x08),
            "{ctx}: all in OP: {:x?}",
            rep.states_after_op
        );
        // LRW over [inputs][outputs]: read + write in every drive = 3 each.
        assert!(
            rep.op_wkc.iter().all(|&w| w == 3 * n as u16),
            "{ctx}: LRW WKC {:?}",
            rep.op_wkc
        );
        assert!(rep.echo_ok, "{ctx}: process data echoed by every drive");
        assert_eq!(
            rep.device_types,
            vec![0x0002_0192; n],
            "{ctx}: SDO upload 0x1000"
        );
        let want: Vec<i32> = (0..n as i32).map(|i| 0x1234_0000 + i).collect();
        assert_eq!(rep.targets, want, "{ctx}: SDO download + upload 0x607A");
        assert_eq!(
            rep.sdo_abort,
            Some(true),
            "{ctx}: missing object answered with an abort"
        );
        let mut s = seg.borrow_mut();
        for i in 0..n {
            assert_eq!(
                s.al_status(i),
                (0x0001, 0),
                "{ctx}: drive {i} back in INIT without error"
            );
            let d = s.drive_mut(i);
            assert_eq!(d.poll_errors, 0, "{ctx}: no ESC access error");
            assert!(
                d.app.cycles.1 >= 10,
                "{ctx}: fresh outputs reached the application"
            );
            assert_eq!(
                d.slave.esc_mut().spi_violations(),
                Vec::<String>::new(),
                "{ctx}: SPI protocol"
            );
        }
        assert_eq!(stats.malformed, 0);
        assert_eq!(
            stats.sent, stats.received,
            "{ctx}: every frame came back: {stats:?}"
        );
        assert_eq!(TEST_PD_BYTES, 6);
        eprintln!("{ctx}: {} frames, {stats:?}", s.frames());
    }
    // Station alias written into the EEPROM by the master, loaded after a reload.
    for flavour in [Flavour::Lan9252, Flavour::Et1100] {
        let seg = Rc::new(RefCell::new(
            test_segment(SegmentConfig::new(flavour), 2).expect("segment"),
        ));
        let (res, _) = h.run(seg.clone(), sim_timeouts(), sim_config(), write_alias);
        assert_eq!(res.expect("alias write"), vec![0x0770, 0x0771]);
        let s = seg.borrow();
        for i in 0..2 {
            let mut e = s.esc(i);
            let sii = e.sii().to_vec();
            assert_eq!(
                &sii[8..10],
                &(0x0770 + i as u16).to_le_bytes(),
                "{flavour:?}: SII word 4"
            );
            assert_eq!(
                sii[14],
                tests_host::esc_sim::sii_crc8(&sii[..14]),
                "{flavour:?}: checksum word 7"
            );
            // A reload command makes the ESC take the new alias into 0x0012.
            assert!(e.side_write(tests_host::esc_sim::Side::Ecat, 0x0500, &[0x02]));
            assert!(e.side_write(tests_host::esc_sim::Side::Ecat, 0x0502, &[0x00, 0x04]));
            assert_eq!(e.peek(0x0012, 2), &(0x0770 + i as u16).to_le_bytes());
        }
    }
    // DC SYNC0 mode, both chips, 3 drives.
    for flavour in [Flavour::Lan9252, Flavour::Et1100] {
        let cfg = SegmentConfig::new(flavour);
        let seg = Rc::new(RefCell::new(test_segment(cfg, 3).expect("segment")));
        let s2 = seg.clone();
        let (res, stats) = h.run(seg.clone(), sim_timeouts(), sim_config(), |md| {
            bring_up_dc(md, s2)
        });
        let (wkcs, pulses, cycles_to_op) = res.unwrap_or_else(|e| {
            let s = seg.borrow();
            let st: Vec<_> = (0..s.len()).map(|i| s.al_status(i)).collect();
            panic!("DC {flavour:?}: ethercrab error {e:?}; AL status/code {st:04x?}; {stats:?}")
        });
        assert!(
            cycles_to_op < 100,
            "DC {flavour:?}: Op after {cycles_to_op} cycles"
        );
        assert!(
            wkcs.iter().all(|&w| w == 9),
            "DC {flavour:?}: LRW WKC {wkcs:?}"
        );
        assert!(pulses >= 20, "DC {flavour:?}: SYNC0 pulses {pulses}");
        let s = seg.borrow();
        for i in 0..3 {
            assert_eq!(
                s.al_status(i),
                (0x01, 0),
                "DC {flavour:?}: drive {i} back in INIT"
            );
            assert!(
                s.drive(i).app.cycles.1 >= 20,
                "DC {flavour:?}: cycles ran on SYNC0"
            );
        }
        eprintln!(
            "DC {flavour:?}: Op after {cycles_to_op} cycles, {pulses} SYNC0 pulses, {stats:?}"
        );
    }
}

// ---- refused transitions and invalid configurations, with raw datagrams ----------------
//
// ethercrab cannot be made to request a forbidden transition or write a bad SM layout,
// so these tests play the master with raw datagrams through the same segment.

use tests_host::esc_sim::frame::{Command, FrameBuilder};

const SM0: [u8; 8] = [0x00, 0x10, 0x80, 0x00, 0x26, 0x00, 0x01, 0x00];
const SM1: [u8; 8] = [0x80, 0x10, 0x80, 0x00, 0x22, 0x00, 0x01, 0x00];

struct Raw {
    seg: Segment<TestDrive>,
}

impl Raw {
    fn new(flavour: Flavour, n: usize) -> Self {
        let mut seg = test_segment(SegmentConfig::new(flavour), n).unwrap();
        for i in 0..n {
            let d = seg.raw(FrameBuilder::new().physical(
                Command::Apwr,
                0u16.wrapping_sub(i as u16),
                0x0010,
                &(0x1000 + i as u16).to_le_bytes(),
            ));
            assert_eq!(d[0].wkc, 1);
        }
        Raw { seg }
    }
    fn wr(&mut self, i: usize, ado: u16, data: &[u8]) -> u16 {
        self.seg
            .raw(FrameBuilder::new().physical(Command::Fpwr, 0x1000 + i as u16, ado, data))[0]
            .wkc
    }
    fn rd(&mut self, i: usize, ado: u16, len: usize) -> Vec<u8> {
        let d = self.seg.raw(FrameBuilder::new().physical(
            Command::Fprd,
            0x1000 + i as u16,
            ado,
            &vec![0; len],
        ));
        assert_eq!(d[0].wkc, 1);
        d[0].data.clone()
    }
    /// Writes AL control, lets the slave answer, reads AL status + code as a master.
    fn request(&mut self, i: usize, ctl: u16) -> (u16, u16) {
        assert_eq!(self.wr(i, 0x0120, &ctl.to_le_bytes()), 1);
        self.seg.advance(1000);
        let s = self.rd(i, 0x0130, 6);
        (
            u16::from_le_bytes([s[0], s[1]]),
            u16::from_le_bytes([s[4], s[5]]),
        )
    }
    fn sm(&mut self, i: usize, n: u8, start: u16, len: u16, control: u8, enable: bool) {
        let mut b = [0u8; 8];
        b[0..2].copy_from_slice(&start.to_le_bytes());
        b[2..4].copy_from_slice(&len.to_le_bytes());
        b[4] = control;
        b[6] = enable as u8;
        // Disable first (the ESC locks the configuration of an enabled SM).
        self.wr(i, 0x0806 + 8 * n as u16, &[0]);
        assert_eq!(self.wr(i, 0x0800 + 8 * n as u16, &b), 1);
    }
    fn mailbox(&mut self, i: usize) {
        self.wr(i, 0x0800, &SM0);
        self.wr(i, 0x0808, &SM1);
    }
    fn enter_preop(&mut self, i: usize) {
        self.mailbox(i);
        assert_eq!(self.request(i, 0x02), (0x02, 0));
    }
    /// SM2/SM3 for the default 6-byte maps, watchdog 100 ms.
    fn pd(&mut self, i: usize) {
        self.sm(i, 2, 0x1100, TEST_PD_BYTES as u16, 0x64, true);
        self.sm(i, 3, 0x1400, TEST_PD_BYTES as u16, 0x20, true);
    }
    fn enter_safeop(&mut self, i: usize) {
        self.enter_preop(i);
        self.pd(i);
        assert_eq!(self.request(i, 0x04), (0x04, 0));
    }
    fn outputs(&mut self, i: usize) {
        assert_eq!(self.wr(i, 0x1100, &[1, 2, 3, 4, 5, 6]), 1);
    }
    fn enter_op(&mut self, i: usize) {
        self.enter_safeop(i);
        self.outputs(i);
        assert_eq!(self.request(i, 0x08), (0x08, 0));
    }
    /// Clears an error indication by acknowledging into `state`.
    fn ack(&mut self, i: usize, state: u16) {
        let (st, _) = self.request(i, state | 0x10);
        assert_eq!(st, state, "acknowledged");
    }
}

#[test]
fn refused_transitions_answer_0x0011_and_keep_the_state() {
    for flavour in [Flavour::Lan9252, Flavour::Et1100] {
        let mut r = Raw::new(flavour, 2);
        // From Init: Safe-Op and Op are two steps away.
        assert_eq!(r.request(0, 0x04), (0x11, 0x0011));
        // While the error is pending, a request without acknowledge is ignored.
        r.mailbox(0);
        assert_eq!(r.request(0, 0x02), (0x11, 0x0011));
        r.ack(0, 0x01);
        assert_eq!(r.request(0, 0x08), (0x11, 0x0011));
        r.ack(0, 0x01);
        // Pre-Op → Op.
        r.enter_preop(0);
        assert_eq!(r.request(0, 0x08), (0x12, 0x0011));
        r.ack(0, 0x02);
        // Pre-Op → Boot, Safe-Op → Boot.
        assert_eq!(r.request(0, 0x03), (0x12, 0x0011));
        r.ack(0, 0x02);
        r.pd(0);
        assert_eq!(r.request(0, 0x04), (0x04, 0));
        assert_eq!(r.request(0, 0x03), (0x14, 0x0011));
        r.ack(0, 0x04);
        // Op → Boot: refused, falls back to Safe-Op with the error.
        r.outputs(0);
        assert_eq!(r.request(0, 0x08), (0x08, 0));
        assert_eq!(r.request(0, 0x03), (0x14, 0x0011));
        // Init as an implicit acknowledge, downward skipping allowed.
        assert_eq!(r.request(0, 0x01), (0x01, 0));
        // The other drive never moved.
        assert_eq!(r.seg.al_status(1), (0x01, 0));
    }
}

#[test]
fn unknown_state_0x0012_and_bootstrap_0x0013() {
    let mut r = Raw::new(Flavour::Et1100, 1);
    for bad in [0x00u16, 0x05, 0x06, 0x07, 0x09, 0x0A, 0x0F] {
        assert_eq!(r.request(0, bad), (0x11, 0x0012), "state code {bad:#x}");
        r.ack(0, 0x01);
    }
    assert_eq!(r.request(0, 0x03), (0x11, 0x0013));
    r.ack(0, 0x01);
    // In Op an unknown state falls back to Safe-Op.
    r.enter_op(0);
    assert_eq!(r.request(0, 0x0F), (0x14, 0x0012));
}

#[test]
fn invalid_mailbox_configuration_0x0016() {
    for flavour in [Flavour::Lan9252, Flavour::Et1100] {
        let ram_end = 0x1000 + flavour.ram_bytes() as u16;
        let cases: [(&str, [u8; 8], [u8; 8]); 8] = [
            ("SM0 disabled", [0x00, 0x10, 0x80, 0, 0x26, 0, 0, 0], SM1),
            (
                "SM0 wrong direction",
                [0x00, 0x10, 0x80, 0, 0x22, 0, 1, 0],
                SM1,
            ),
            (
                "SM1 buffered mode",
                SM0,
                [0x80, 0x10, 0x80, 0, 0x20, 0, 1, 0],
            ),
            ("SM0 odd start", [0x01, 0x10, 0x80, 0, 0x26, 0, 1, 0], SM1),
            ("SM0 too short", [0x00, 0x10, 14, 0, 0x26, 0, 1, 0], SM1),
            ("SM1 too short", SM0, [0x80, 0x10, 14, 0, 0x22, 0, 1, 0]),
            ("overlap", SM0, [0x40, 0x10, 0x80, 0, 0x22, 0, 1, 0]),
            (
                "beyond process RAM",
                SM0,
                [
                    (ram_end - 0x40) as u8,
                    ((ram_end - 0x40) >> 8) as u8,
                    0x80,
                    0,
                    0x22,
                    0,
                    1,
                    0,
                ],
            ),
        ];
        for (what, s0, s1) in cases {
            let mut r = Raw::new(flavour, 1);
            r.wr(0, 0x0800, &s0);
            r.wr(0, 0x0808, &s1);
            assert_eq!(r.request(0, 0x02), (0x11, 0x0016), "{flavour:?}: {what}");
            // Fixing the layout and acknowledging works.
            r.ack(0, 0x01);
            r.sm(0, 0, 0x1000, 128, 0x26, true);
            r.sm(0, 1, 0x1080, 128, 0x22, true);
            assert_eq!(r.request(0, 0x02), (0x02, 0), "{flavour:?}: {what} fixed");
        }
    }
}

#[test]
fn invalid_process_data_sync_managers_0x001d_0x001e() {
    type Setup = fn(&mut Raw);
    let cases: [(&str, Setup, u16); 7] = [
        (
            "SM2 length != mapping",
            |r| r.sm(0, 2, 0x1100, 4, 0x64, true),
            0x001D,
        ),
        (
            "SM2 wrong direction",
            |r| r.sm(0, 2, 0x1100, 6, 0x60, true),
            0x001D,
        ),
        (
            "SM2 disabled with outputs mapped",
            |r| r.sm(0, 2, 0x1100, 6, 0x64, false),
            0x001D,
        ),
        (
            "SM2 overlaps the mailbox",
            |r| r.sm(0, 2, 0x1040, 6, 0x64, true),
            0x001D,
        ),
        (
            "SM3 length != mapping",
            |r| r.sm(0, 3, 0x1400, 8, 0x20, true),
            0x001E,
        ),
        (
            "SM3 wrong direction",
            |r| r.sm(0, 3, 0x1400, 6, 0x24, true),
            0x001E,
        ),
        (
            "SM3 mailbox mode",
            |r| r.sm(0, 3, 0x1400, 6, 0x22, true),
            0x001E,
        ),
    ];
    for (what, setup, code) in cases {
        let mut r = Raw::new(Flavour::Lan9252, 1);
        r.enter_preop(0);
        r.pd(0);
        setup(&mut r);
        assert_eq!(r.request(0, 0x04), (0x12, code), "{what}");
        r.ack(0, 0x02);
        r.pd(0);
        assert_eq!(r.request(0, 0x04), (0x04, 0), "{what}: fixed");
    }
}

#[test]
fn invalid_watchdog_configuration_0x001f() {
    let mut r = Raw::new(Flavour::Et1100, 1);
    r.enter_preop(0);
    r.pd(0);
    // Watchdog time set but SM2 does not trigger it.
    r.sm(0, 2, 0x1100, 6, 0x24, true);
    assert_eq!(r.request(0, 0x04), (0x12, 0x001F));
    r.ack(0, 0x02);
    // SM2 triggers it but the time is 0.
    r.sm(0, 2, 0x1100, 6, 0x64, true);
    r.wr(0, 0x0420, &[0, 0]);
    assert_eq!(r.request(0, 0x04), (0x12, 0x001F));
    r.ack(0, 0x02);
    // DC at 1 ms with a 1.5 ms watchdog (15 × 100 µs, < 2 cycles).
    r.wr(0, 0x0420, &15u16.to_le_bytes());
    r.wr(0, 0x09A0, &1_000_000u32.to_le_bytes());
    r.wr(0, 0x0980, &[0x00, 0x03]);
    assert_eq!(r.request(0, 0x04), (0x12, 0x001F));
}

#[test]
fn dc_configuration_errors_0x0030_0x0035() {
    let mut r = Raw::new(Flavour::Et1100, 1);
    r.enter_preop(0);
    r.pd(0);
    // SYNC1 as well: not supported.
    r.wr(0, 0x09A0, &1_000_000u32.to_le_bytes());
    r.wr(0, 0x0980, &[0x00, 0x07]);
    assert_eq!(r.request(0, 0x04), (0x12, 0x0030));
    r.ack(0, 0x02);
    // 300 µs is not a multiple of 125 µs; 5 ms is above the limit.
    for cycle in [300_000u32, 5_000_000, 62_500] {
        r.wr(0, 0x0981, &[0]);
        r.wr(0, 0x09A0, &cycle.to_le_bytes());
        r.wr(0, 0x0981, &[0x03]);
        assert_eq!(r.request(0, 0x04), (0x12, 0x0035), "cycle {cycle}");
        r.ack(0, 0x02);
    }
}

#[test]
fn process_data_watchdog_in_op_0x001b() {
    let mut r = Raw::new(Flavour::Lan9252, 2);
    r.enter_op(0);
    r.enter_op(1);
    // Drive 1 keeps getting outputs every ms; drive 0 gets nothing for 150 ms.
    for _ in 0..150 {
        r.outputs(1);
        r.seg.advance(1_000_000);
    }
    assert_eq!(r.seg.al_status(0), (0x14, 0x001B));
    assert_eq!(r.seg.al_status(1), (0x08, 0));
    assert!(r
        .seg
        .drive(0)
        .app
        .outputs_lost
        .contains(&ecat_slave_stack::AlStatusCode::SmWatchdog));
    // Outputs again, acknowledge, back to Op.
    r.outputs(0);
    r.ack(0, 0x04);
    r.outputs(0);
    assert_eq!(r.request(0, 0x08), (0x08, 0));
}

fn system_time(r: &mut Raw, i: usize) -> u64 {
    let b = r.rd(i, 0x0910, 8);
    u64::from_le_bytes(b.try_into().unwrap())
}

/// DC SYNC0 at 1 ms starting `delay_ns` after the drive's current system time.
fn start_sync0(r: &mut Raw, i: usize, delay_ns: i64) {
    let now = system_time(r, i);
    r.wr(i, 0x09A0, &1_000_000u32.to_le_bytes());
    r.wr(i, 0x0990, &(now as i64 + delay_ns).max(1).to_le_bytes());
    r.wr(i, 0x0980, &[0x00, 0x03]);
}

#[test]
fn dc_sync0_lock_missing_0x002d_and_lost_0x002c() {
    // SYNC0 never comes (start time in the past): S→O waits for the lock, then 0x002D.
    let mut r = Raw::new(Flavour::Et1100, 1);
    r.enter_preop(0);
    r.pd(0);
    start_sync0(&mut r, 0, -5_000_000);
    assert_eq!(r.request(0, 0x04), (0x04, 0));
    r.outputs(0);
    r.wr(0, 0x0120, &8u16.to_le_bytes());
    let mut last = (0, 0);
    for _ in 0..1200 {
        r.outputs(0);
        r.seg.advance(1_000_000);
        last = r.seg.al_status(0);
        if last.0 & 0x10 != 0 {
            break;
        }
    }
    assert_eq!(last.1, 0x002D, "status {last:x?}");
    assert_eq!(last.0 & 0x10, 0x10);

    // SYNC0 running: Op is reached; SYNC0 stops (master switches the unit off): 0x002C.
    let mut r = Raw::new(Flavour::Et1100, 1);
    r.enter_preop(0);
    r.pd(0);
    start_sync0(&mut r, 0, 2_000_000);
    assert_eq!(r.request(0, 0x04), (0x04, 0));
    r.wr(0, 0x0120, &8u16.to_le_bytes());
    for _ in 0..50 {
        r.outputs(0);
        r.seg.advance(1_000_000);
        if r.seg.al_status(0).0 == 0x08 {
            break;
        }
    }
    assert_eq!(r.seg.al_status(0), (0x08, 0), "locked to SYNC0");
    assert!(r.seg.esc(0).stats().sync0_pulses >= 4);
    r.wr(0, 0x0981, &[0]);
    for _ in 0..50 {
        r.outputs(0);
        r.seg.advance(1_000_000);
    }
    assert_eq!(r.seg.al_status(0), (0x14, 0x002C));
}

#[test]
fn dc_sync0_phase_jumps_0x0032() {
    // Locked at 1 ms, then the master restarts SYNC0 at 400 µs: the intervals no longer
    // match the cycle the slave accepted → lock lost.
    let mut r = Raw::new(Flavour::Lan9252, 1);
    r.enter_preop(0);
    r.pd(0);
    start_sync0(&mut r, 0, 2_000_000);
    assert_eq!(r.request(0, 0x04), (0x04, 0));
    r.wr(0, 0x0120, &8u16.to_le_bytes());
    for _ in 0..50 {
        r.outputs(0);
        r.seg.advance(1_000_000);
    }
    assert_eq!(r.seg.al_status(0), (0x08, 0));
    r.wr(0, 0x0981, &[0]);
    let now = system_time(&mut r, 0);
    r.wr(0, 0x09A0, &400_000u32.to_le_bytes());
    r.wr(0, 0x0990, &(now + 100_000).to_le_bytes());
    r.wr(0, 0x0981, &[0x03]);
    for _ in 0..40 {
        r.outputs(0);
        r.seg.advance(400_000);
    }
    assert_eq!(r.seg.al_status(0), (0x14, 0x0032));
}

/// Expedited SDO download through the mailbox SyncManagers (raw CoE frames).
fn sdo_download(
    r: &mut Raw,
    i: usize,
    counter: u8,
    index: u16,
    sub: u8,
    data: &[u8],
) -> Result<(), u32> {
    assert!(!data.is_empty() && data.len() <= 4);
    let mut m = vec![0u8; 128];
    m[0..2].copy_from_slice(&10u16.to_le_bytes()); // length: CoE header + SDO
    m[5] = 0x03 | (counter & 7) << 4; // CoE, counter
    m[6..8].copy_from_slice(&(2u16 << 12).to_le_bytes()); // SDO request
    m[8] = 0x23 | ((4 - data.len() as u8) << 2);
    m[9..11].copy_from_slice(&index.to_le_bytes());
    m[11] = sub;
    m[12..12 + data.len()].copy_from_slice(data);
    assert_eq!(r.wr(i, 0x1000, &m), 1, "SM0 free");
    for _ in 0..10 {
        r.seg.advance(100_000);
        let d = r.seg.raw(FrameBuilder::new().physical(
            Command::Fprd,
            0x1000 + i as u16,
            0x1080,
            &[0; 128],
        ));
        if d[0].wkc == 1 {
            let a = &d[0].data;
            assert_eq!(a[5] & 0x0F, 0x03, "CoE reply");
            return match a[8] {
                0x60 => Ok(()),
                0x80 => Err(u32::from_le_bytes([a[12], a[13], a[14], a[15]])),
                other => panic!("unexpected SDO command {other:#x}"),
            };
        }
    }
    panic!("no SDO answer");
}

#[test]
fn unsupported_sync_type_0x0028_via_sdo() {
    let mut r = Raw::new(Flavour::Et1100, 1);
    r.enter_preop(0);
    r.pd(0);
    // 0x1C32:01 = 2 (DC SYNC0) while the DC unit is off: inconsistent with 0x0981.
    sdo_download(&mut r, 0, 1, 0x1C32, 1, &2u16.to_le_bytes()).expect("SDO download accepted");
    assert_eq!(r.request(0, 0x04), (0x12, 0x0028));
    r.ack(0, 0x02);
    // SM-synchronous (1) is consistent.
    sdo_download(&mut r, 0, 2, 0x1C32, 1, &1u16.to_le_bytes()).expect("SDO download accepted");
    assert_eq!(r.request(0, 0x04), (0x04, 0));
}

#[test]
fn invalid_default_mappings_0x0024_0x0025() {
    use ecat_slave_stack::pdo::PdoDefaults;
    use tests_host::segment::{sii_image, test_description, test_slave_config};
    // RxPDO mapping an object the application cannot receive (0x6041 is input-only).
    const RX_BAD: &[u32] = &[ObjectKey::new(0x6041, 0).mapping_word(16)];
    const TX_OK: &[u32] = &[ObjectKey::new(0x6041, 0).mapping_word(16)];
    // TxPDO mapping an object the application cannot send.
    const TX_BAD: &[u32] = &[ObjectKey::new(0x6040, 0).mapping_word(16)];
    const RX_OK: &[u32] = &[ObjectKey::new(0x6040, 0).mapping_word(16)];
    let cases: [(PdoDefaults, u16); 2] = [
        (
            PdoDefaults {
                rx: [RX_BAD, &[], &[], &[]],
                tx: [TX_OK, &[], &[], &[]],
                rx_assign: &[0x1600],
                tx_assign: &[0x1A00],
            },
            0x0025,
        ),
        (
            PdoDefaults {
                rx: [RX_OK, &[], &[], &[]],
                tx: [TX_BAD, &[], &[], &[]],
                rx_assign: &[0x1600],
                tx_assign: &[0x1A00],
            },
            0x0024,
        ),
    ];
    for (defaults, code) in cases {
        let cfg = SegmentConfig::new(Flavour::Lan9252);
        let image = sii_image(&test_description(cfg.flavour)).unwrap();
        let mut slave_cfg = test_slave_config();
        slave_cfg.pdo_defaults = defaults;
        let seg = Segment::new(cfg, &image, vec![TestDrive::default()], slave_cfg, None).unwrap();
        let mut r = Raw { seg };
        assert_eq!(
            r.wr(0, 0x0010, &0x1000u16.to_le_bytes()),
            0,
            "not addressed yet"
        );
        let d = r.seg.raw(FrameBuilder::new().physical(
            Command::Apwr,
            0,
            0x0010,
            &0x1000u16.to_le_bytes(),
        ));
        assert_eq!(d[0].wkc, 1);
        r.enter_preop(0);
        r.sm(0, 2, 0x1100, 2, 0x64, true);
        r.sm(0, 3, 0x1400, 2, 0x20, true);
        assert_eq!(r.request(0, 0x04), (0x12, code));
    }
}

#[test]
fn station_alias_from_sii_and_garbage_frames_through_a_live_segment() {
    let cfg = SegmentConfig::new(Flavour::Et1100);
    let image = tests_host::segment::sii_image(&tests_host::segment::test_description(cfg.flavour))
        .unwrap();
    let apps = (0..3).map(|_| TestDrive::default()).collect();
    let mut seg = Segment::new(
        cfg,
        &image,
        apps,
        tests_host::segment::test_slave_config(),
        Some(0x0200),
    )
    .unwrap();
    for i in 0..3u16 {
        let d = seg.raw(FrameBuilder::new().physical(
            Command::Aprd,
            0u16.wrapping_sub(i),
            0x0012,
            &[0, 0],
        ));
        assert_eq!(
            d[0].data,
            (0x0200 + i).to_le_bytes(),
            "alias from SII word 4"
        );
    }
    // Garbage in the mailbox and in AL control never stops the drives.
    let mut r = Raw { seg };
    for i in 0..3 {
        let d = r.seg.raw(FrameBuilder::new().physical(
            Command::Apwr,
            0u16.wrapping_sub(i as u16),
            0x0010,
            &(0x1000 + i as u16).to_le_bytes(),
        ));
        assert_eq!(d[0].wkc, 1);
        r.enter_preop(i);
    }
    let mut x = 0x1234_5678u32;
    for k in 0..300 {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        let i = (x % 3) as usize;
        let junk: Vec<u8> = (0..128).map(|j| (x >> (j % 24)) as u8).collect();
        r.wr(i, 0x1000, &junk);
        if k % 7 == 0 {
            r.wr(i, 0x0120, &((x as u16) & 0x3F).to_le_bytes());
        }
        r.seg.advance(50_000);
        r.seg.raw(FrameBuilder::new().physical(
            Command::Fprd,
            0x1000 + i as u16,
            0x1080,
            &[0; 128],
        ));
    }
    for i in 0..3 {
        assert_eq!(r.seg.drive(i).poll_errors, 0);
        r.request(i, 0x11);
        assert_eq!(r.request(i, 0x11).0, 0x01, "drive {i} still answers");
    }
}

#[test]
fn mailbox_repeat_request_resends_the_last_reply() {
    let mut r = Raw::new(Flavour::Lan9252, 1);
    r.enter_preop(0);
    sdo_download(&mut r, 0, 1, 0x607A, 0, &7i32.to_le_bytes()).expect("download");
    // The reply was consumed by sdo_download; the master lost it and asks again by
    // toggling the repeat request bit (SM1 activate bit 1).
    let act = r.rd(0, 0x080E, 2);
    assert_eq!(act[1] & 0x02, 0, "no repeat acknowledged yet");
    r.wr(0, 0x080E, &[act[0] ^ 0x02]);
    r.seg.advance(100_000);
    let st = r.rd(0, 0x0808, 8);
    assert_eq!(st[5] & 0x08, 0x08, "SM1 full again");
    assert_eq!(
        st[7] & 0x02,
        0x02,
        "repeat acknowledged in PDI control bit 1"
    );
    let d = r
        .seg
        .raw(FrameBuilder::new().physical(Command::Fprd, 0x1000, 0x1080, &[0; 128]));
    assert_eq!(d[0].wkc, 1);
    assert_eq!(d[0].data[5] & 0x0F, 0x03, "CoE");
    assert_eq!(d[0].data[8], 0x60, "the download response again");
}

#[test]
fn random_datagrams_against_live_drives_never_panic() {
    for flavour in [Flavour::Lan9252, Flavour::Et1100] {
        let mut r = Raw::new(flavour, 3);
        for i in 0..3 {
            r.enter_op(i);
        }
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        // Registers the stack reacts to, plus anything.
        let hot: [u16; 12] = [
            0x0120, 0x0800, 0x0806, 0x0808, 0x080E, 0x0810, 0x0818, 0x0600, 0x0981, 0x09A0, 0x1000,
            0x1100,
        ];
        for k in 0..4000 {
            let mut fb = FrameBuilder::new();
            for _ in 0..1 + next() % 3 {
                let cmd = (next() % 15) as u8;
                let ado = if next() % 2 == 0 {
                    hot[(next() % hot.len() as u64) as usize].wrapping_add((next() % 16) as u16)
                } else {
                    (next() % 0x3000) as u16
                };
                let adp = match next() % 3 {
                    0 => 0x1000 + (next() % 3) as u16,
                    1 => 0u16.wrapping_sub((next() % 3) as u16),
                    _ => next() as u16,
                };
                let len = (next() % 140) as usize;
                let data: Vec<u8> = (0..len).map(|_| next() as u8).collect();
                fb = fb.raw(cmd, adp as u32 | (ado as u32) << 16, &data);
            }
            r.seg.raw(fb);
            if k % 10 == 0 {
                r.seg.advance(next() % 3_000_000);
            }
        }
        // Every drive still answers a plain Init request.
        for i in 0..3 {
            r.wr(i, 0x0010, &(0x1000 + i as u16).to_le_bytes());
            let d = r.seg.raw(FrameBuilder::new().physical(
                Command::Apwr,
                0u16.wrapping_sub(i as u16),
                0x0010,
                &(0x1000 + i as u16).to_le_bytes(),
            ));
            assert_eq!(d[0].wkc, 1);
            let _ = r.rd(i, 0x0120, 2);
            r.seg.advance(1000);
            r.request(i, 0x11);
            assert_eq!(
                r.request(i, 0x11).0 & 0x0F,
                0x01,
                "{flavour:?}: drive {i} back in Init"
            );
        }
    }
}
