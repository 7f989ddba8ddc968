//! The CoE mailbox through the simulated ESC and the slave runtime.
//!
//! * ethercrab 0.7 in-process: expedited and normal upload, expedited download, aborts
//!   (ethercrab's segmented upload and non-expedited download are broken, see
//!   the masters' sources, so those are not exercised with it).
//! * Master-side mailbox frames written into SM0 and read from SM1 with raw datagrams:
//!   segmented download and upload, complete access (including the runtime's own
//!   0x1C12), SDO information with fragments, emergencies, repeated requests.
//!
//! The drive application wraps `coe::example::ExampleDictionary` together with the
//! runtime's communication objects (PDO mapping/assignment and timing diagnostics).

use ecat_slave_stack::coe::example::{self, ExampleDictionary, DEVICE_NAME};
use ecat_slave_stack::esm::{EsmHooks, EsmState};
use ecat_slave_stack::od::{
    self, Access, DataType, Dictionary, EntryDesc, Object, ObjectDesc, ObjectKey, PdoMappable,
    SdoAbort,
};
use ecat_slave_stack::pdo::{self, ProcessData};
use ecat_slave_stack::slave::SlaveApplication;
use ecat_slave_stack::sync;
use ethercrab::error::{Error, MailboxError};
use ethercrab::PduStorage;
use std::cell::RefCell;
use std::rc::Rc;
use tests_host::esc_sim::frame::{Command, FrameBuilder};
use tests_host::esc_sim::Flavour;
use tests_host::ethercrab_seam::{sim_config, sim_now_ns, sim_timeouts, MasterHarness};
use tests_host::segment::{
    sii_image, test_description, test_slave_config, PdiPath, Segment, SegmentConfig,
};

const E_6064: &[EntryDesc] =
    &[
        EntryDesc::new(0, "Position actual value", DataType::Integer32, Access::RO)
            .pdo(PdoMappable::Tx),
    ];

/// The example objects, the runtime's PDO objects and the timing diagnostics, sorted.
static OBJECTS: &[Object] = ecat_slave_stack::packed_dictionary!(&[
    pdo::OBJECTS,
    OBJECTS_LOCAL,
    &[sync::timing_diag_object(0x2200)]
]);
const OBJECTS_LOCAL: &[ObjectDesc] = &[
    example::SOURCE[0],  // 0x1000
    example::SOURCE[1],  // 0x1001
    example::SOURCE[2],  // 0x1008
    example::SOURCE[3],  // 0x1018
    example::SOURCE[6],  // 0x2000
    example::SOURCE[7],  // 0x2001
    example::SOURCE[8],  // 0x2002
    example::SOURCE[9],  // 0x2003
    example::SOURCE[10], // 0x2004
    example::SOURCE[11], // 0x2005
    example::SOURCE[12], // 0x2FFF
    example::SOURCE[13], // 0x6040
    example::SOURCE[14], // 0x6041
    ObjectDesc::var(0x6064, "Position actual value", E_6064, ""),
    example::SOURCE[15], // 0x607A
];

#[derive(Default)]
struct CoeDrive {
    ex: ExampleDictionary,
    position: i32,
    states: Vec<(EsmState, EsmState)>,
}

impl Dictionary for CoeDrive {
    fn objects(&self) -> &'static [Object] {
        OBJECTS
    }
    fn read(&mut self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        let ObjectKey { index, .. } = key;
        if index == 0x6064 {
            let b = buf.get_mut(..4).ok_or(SdoAbort::GeneralError)?;
            b.copy_from_slice(&self.position.to_le_bytes());
            return Ok(4);
        }
        self.ex.read(key, buf)
    }
    fn write(&mut self, key: ObjectKey, data: &[u8], state: EsmState) -> Result<(), SdoAbort> {
        self.ex.write(key, data, state)
    }
}

impl ProcessData for CoeDrive {
    fn rx_slot(&self, key: ObjectKey) -> Option<u16> {
        let ObjectKey { index, sub } = key;
        match (index, sub) {
            (0x6040, 0) => Some(0),
            (0x607A, 0) => Some(1),
            _ => None,
        }
    }
    fn tx_slot(&self, key: ObjectKey) -> Option<u16> {
        let ObjectKey { index, sub } = key;
        match (index, sub) {
            (0x6041, 0) => Some(2),
            (0x6064, 0) => Some(3),
            _ => None,
        }
    }
    fn set_rx(&mut self, slot: u16, raw: u64) {
        match slot {
            0 => self.ex.set_value(ObjectKey::new(0x6040, 0), raw),
            _ => self.ex.set_value(ObjectKey::new(0x607A, 0), raw),
        }
    }
    fn get_tx(&self, slot: u16) -> u64 {
        match slot {
            2 => self.ex.value(ObjectKey::new(0x6041, 0)),
            _ => self.position as u32 as u64,
        }
    }
}

impl EsmHooks for CoeDrive {
    fn on_state_change(&mut self, from: EsmState, to: EsmState) {
        self.states.push((from, to));
    }
}

impl SlaveApplication for CoeDrive {}

fn segment(flavour: Flavour, pdi: PdiPath) -> Segment<CoeDrive> {
    let cfg = SegmentConfig::new(flavour).with_pdi(pdi);
    let image = sii_image(&test_description(flavour)).expect("SII image");
    Segment::new(
        cfg,
        &image,
        vec![CoeDrive::default()],
        test_slave_config(),
        None,
    )
    .expect("segment")
}

#[test]
fn object_table_is_sorted() {
    assert_eq!(pdo::OBJECTS.len(), 13);
    assert!(od::is_well_formed(OBJECTS));
}

// ---- ethercrab ---------------------------------------------------------------------

static PDU_STORAGE: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

fn abort_code(e: &Error) -> Option<String> {
    match e {
        Error::Mailbox(MailboxError::Aborted { code, .. }) => Some(format!("{code}")),
        _ => None,
    }
}

#[derive(Debug, Default)]
struct SdoReport {
    device_type: u32,
    name: String,
    vendor: u32,
    assign_count: u8,
    assign_1: u16,
    mapping_1: u32,
    written: i32,
    controlword: u16,
    too_high: Option<String>,
    write_only: Option<String>,
    read_only: Option<String>,
    missing: Option<String>,
    missing_sub: Option<String>,
    state_conflict: Option<String>,
}

async fn sdo_scenario(md: Rc<ethercrab::MainDevice<'static>>) -> Result<SdoReport, Error> {
    let group = md.init_single_group::<4, 64>(sim_now_ns).await?;
    let mut r = SdoReport::default();
    {
        let sd = group.subdevice(&md, 0)?;
        r.device_type = sd.sdo_read::<u32>(0x1000, 0).await?;
        r.name = sd
            .sdo_read::<heapless::String<32>>(0x1008, 0)
            .await?
            .to_string();
        r.vendor = sd.sdo_read::<u32>(0x1018, 1).await?;
        r.assign_count = sd.sdo_read::<u8>(0x1C12, 0).await?;
        r.assign_1 = sd.sdo_read::<u16>(0x1C12, 1).await?;
        r.mapping_1 = sd.sdo_read::<u32>(0x1600, 1).await?;
        sd.sdo_write(0x2000, 0, -250i32).await?;
        r.written = sd.sdo_read::<i32>(0x2000, 0).await?;
        sd.sdo_write(0x6040, 0, 0x000Fu16).await?;
        r.controlword = sd.sdo_read::<u16>(0x6040, 0).await?;
        r.too_high = sd
            .sdo_write(0x2000, 0, 5000i32)
            .await
            .err()
            .as_ref()
            .and_then(abort_code);
        r.write_only = sd
            .sdo_read::<u16>(0x2001, 0)
            .await
            .err()
            .as_ref()
            .and_then(abort_code);
        r.read_only = sd
            .sdo_write(0x1000, 0, 1u32)
            .await
            .err()
            .as_ref()
            .and_then(abort_code);
        r.missing = sd
            .sdo_read::<u32>(0x5555, 0)
            .await
            .err()
            .as_ref()
            .and_then(abort_code);
        r.missing_sub = sd
            .sdo_read::<u32>(0x1018, 9)
            .await
            .err()
            .as_ref()
            .and_then(abort_code);
    }
    let group = group.into_safe_op(&md).await?;
    {
        let sd = group.subdevice(&md, 0)?;
        // Mapping objects are writable in Pre-Op only.
        r.state_conflict = sd
            .sdo_write(0x1C12, 0, 0u8)
            .await
            .err()
            .as_ref()
            .and_then(abort_code);
    }
    let _ = group.into_pre_op(&md).await?.into_init(&md).await?;
    Ok(r)
}

#[test]
fn ethercrab_sdo_through_the_simulated_esc() {
    let mut h = MasterHarness::new(&PDU_STORAGE).expect("storage split once");
    for (flavour, pdi) in [
        (Flavour::Lan9252, PdiPath::Direct),
        (Flavour::Et1100, PdiPath::Direct),
        (Flavour::Lan9252, PdiPath::Spi),
        (Flavour::Et1100, PdiPath::Spi),
    ] {
        let seg = Rc::new(RefCell::new(segment(flavour, pdi)));
        let (res, stats) = h.run(seg.clone(), sim_timeouts(), sim_config(), sdo_scenario);
        let ctx = format!("{flavour:?} {pdi:?}");
        let r = res.unwrap_or_else(|e| panic!("{ctx}: ethercrab error {e:?}; {stats:?}"));
        assert_eq!(r.device_type, 0x0002_0192, "{ctx}");
        assert_eq!(r.name, DEVICE_NAME, "{ctx}: normal upload");
        assert_eq!(r.vendor, 0x0E5C, "{ctx}");
        assert_eq!(
            (r.assign_count, r.assign_1),
            (1, 0x1600),
            "{ctx}: runtime's 0x1C12"
        );
        assert_eq!(r.mapping_1, 0x6040_0010, "{ctx}: runtime's 0x1600");
        assert_eq!(r.written, -250, "{ctx}: expedited download");
        assert_eq!(r.controlword, 0x000F, "{ctx}");
        let starts =
            |s: &Option<String>, code: &str| s.as_deref().is_some_and(|s| s.starts_with(code));
        assert!(starts(&r.too_high, "0x06090031"), "{ctx}: {:?}", r.too_high);
        assert!(
            starts(&r.write_only, "0x06010001"),
            "{ctx}: {:?}",
            r.write_only
        );
        assert!(
            starts(&r.read_only, "0x06010002"),
            "{ctx}: {:?}",
            r.read_only
        );
        assert!(starts(&r.missing, "0x06020000"), "{ctx}: {:?}", r.missing);
        assert!(
            starts(&r.missing_sub, "0x06090011"),
            "{ctx}: {:?}",
            r.missing_sub
        );
        assert!(
            starts(&r.state_conflict, "0x08000022"),
            "{ctx}: {:?}",
            r.state_conflict
        );
        let s = seg.borrow();
        assert_eq!(
            s.al_status(0),
            (0x01, 0),
            "{ctx}: back in Init without error"
        );
        assert_eq!(s.drive(0).poll_errors, 0, "{ctx}");
        assert_eq!(
            s.drive(0).app.ex.value(ObjectKey::new(0x2000, 0)) as u32 as i32,
            -250,
            "{ctx}"
        );
    }
}

// ---- raw master-side mailbox frames ------------------------------------------------

const SM0: [u8; 8] = [0x00, 0x10, 0x80, 0x00, 0x26, 0x00, 0x01, 0x00];
const SM1: [u8; 8] = [0x80, 0x10, 0x80, 0x00, 0x22, 0x00, 0x01, 0x00];

struct Raw {
    seg: Segment<CoeDrive>,
    counter: u8,
}

impl Raw {
    fn new(flavour: Flavour) -> Self {
        let mut seg = segment(flavour, PdiPath::Direct);
        let d = seg.raw(FrameBuilder::new().physical(
            Command::Apwr,
            0,
            0x0010,
            &0x1000u16.to_le_bytes(),
        ));
        assert_eq!(d[0].wkc, 1);
        let mut r = Raw { seg, counter: 0 };
        assert_eq!(r.wr(0x0800, &SM0), 1);
        assert_eq!(r.wr(0x0808, &SM1), 1);
        assert_eq!(r.wr(0x0120, &2u16.to_le_bytes()), 1);
        r.seg.advance(1000);
        let s = r.rd_once(0x0130, 6).expect("AL status");
        assert_eq!((s[0], s[4]), (0x02, 0), "Pre-Op");
        r
    }
    fn wr(&mut self, ado: u16, data: &[u8]) -> u16 {
        self.seg
            .raw(FrameBuilder::new().physical(Command::Fpwr, 0x1000, ado, data))[0]
            .wkc
    }
    fn rd_once(&mut self, ado: u16, len: usize) -> Option<Vec<u8>> {
        let d =
            self.seg
                .raw(FrameBuilder::new().physical(Command::Fprd, 0x1000, ado, &vec![0; len]));
        (d[0].wkc == 1).then(|| d[0].data.clone())
    }
    /// Writes one mailbox (CoE payload) into SM0 with the next counter.
    fn send(&mut self, coe: &[u8]) {
        self.counter = if self.counter >= 7 {
            1
        } else {
            self.counter + 1
        };
        let c = self.counter;
        self.send_with(c, coe);
    }
    fn send_with(&mut self, counter: u8, coe: &[u8]) {
        let mut m = vec![0u8; 128];
        m[0..2].copy_from_slice(&(coe.len() as u16).to_le_bytes());
        m[5] = 0x03 | (counter << 4);
        m[6..6 + coe.len()].copy_from_slice(coe);
        for _ in 0..20 {
            if self.wr(0x1000, &m) == 1 {
                return;
            }
            self.seg.advance(100_000);
        }
        panic!("SM0 never free");
    }
    /// Reads the next mailbox from SM1; returns its mailbox payload.
    fn recv(&mut self) -> Vec<u8> {
        for _ in 0..20 {
            self.seg.advance(100_000);
            if let Some(a) = self.rd_once(0x1080, 128) {
                let len = u16::from_le_bytes([a[0], a[1]]) as usize;
                assert!(len + 6 <= 128);
                assert!(a[5] & 0x0F == 0x03 || a[5] & 0x0F == 0, "mailbox type");
                return a[6..6 + len].to_vec();
            }
        }
        panic!("no mailbox in SM1");
    }
    fn nothing(&mut self) {
        self.seg.advance(300_000);
        assert!(self.rd_once(0x1080, 128).is_none(), "unexpected mailbox");
    }
    fn coe(&mut self, coe: &[u8]) -> Vec<u8> {
        self.send(coe);
        self.recv()
    }
}

fn pattern(i: usize) -> u8 {
    (i * 13 + 1) as u8
}

#[test]
fn segmented_transfers_through_the_sync_managers() {
    for flavour in [Flavour::Lan9252, Flavour::Et1100] {
        let mut r = Raw::new(flavour);
        // Segmented download of 250 bytes into 0x2002: 112 + 119 + 19.
        let mut f = vec![0x00, 0x20, 0x21, 0x02, 0x20, 0x00, 250, 0, 0, 0];
        f.extend((0..112).map(pattern));
        assert_eq!(r.coe(&f), [0x00, 0x30, 0x60, 0x02, 0x20, 0x00, 0, 0, 0, 0]);
        let mut s = vec![0x00, 0x20, 0x00];
        s.extend((112..231).map(pattern));
        assert_eq!(r.coe(&s), [0x00, 0x30, 0x20, 0, 0, 0, 0, 0, 0, 0]);
        let mut s = vec![0x00, 0x20, 0x11];
        s.extend((231..250).map(pattern));
        assert_eq!(r.coe(&s), [0x00, 0x30, 0x30, 0, 0, 0, 0, 0, 0, 0]);
        let text = r.seg.drive(0).app.ex.long_text().to_vec();
        assert_eq!(text, (0..250).map(pattern).collect::<Vec<_>>());
        // Segmented upload of the same bytes.
        let a = r.coe(&[0x00, 0x20, 0x40, 0x02, 0x20, 0x00, 0, 0, 0, 0]);
        assert_eq!(
            &a[..10],
            &[0x00, 0x30, 0x41, 0x02, 0x20, 0x00, 250, 0, 0, 0]
        );
        let mut got = a[10..].to_vec();
        let mut toggle = 0;
        loop {
            let a = r.coe(&[0x00, 0x20, 0x60 | toggle, 0, 0, 0, 0, 0, 0, 0]);
            assert_eq!(a[2] & 0x10, toggle);
            got.extend_from_slice(&a[3..]);
            if a[2] & 1 != 0 {
                break;
            }
            toggle ^= 0x10;
        }
        assert_eq!(got, text, "{flavour:?}");
        // Wrong toggle: abort with service 2.
        let _ = r.coe(&[0x00, 0x20, 0x40, 0x02, 0x20, 0x00, 0, 0, 0, 0]);
        let a = r.coe(&[0x00, 0x20, 0x70, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(
            a,
            [0x00, 0x20, 0x80, 0x02, 0x20, 0x00, 0x00, 0x00, 0x03, 0x05]
        );
    }
}

#[test]
fn complete_access_through_the_sync_managers() {
    let mut r = Raw::new(Flavour::Lan9252);
    // The runtime's RxPDO assignment, complete access from sub-index 0 (as SOEM reads it).
    let a = r.coe(&[0x00, 0x20, 0x50, 0x12, 0x1C, 0x00, 0, 0, 0, 0]);
    assert_eq!(
        &a[..12],
        &[0x00, 0x30, 0x51, 0x12, 0x1C, 0x00, 4, 0, 0, 0, 1, 0]
    );
    assert_eq!(&a[12..], &[0x00, 0x16]);
    // The runtime's mapping 0x1600: two entries.
    let a = r.coe(&[0x00, 0x20, 0x50, 0x00, 0x16, 0x00, 0, 0, 0, 0]);
    assert_eq!(
        &a[10..],
        &[2, 0, 0x10, 0x00, 0x40, 0x60, 0x20, 0x00, 0x7A, 0x60]
    );
    // Rewrite 0x1600 with complete access (sub-index 0 cleared first by the server).
    let a = r.coe(&[
        0x00, 0x20, 0x31, 0x00, 0x16, 0x00, 10, 0, 0, 0, 2, 0, 0x20, 0x00, 0x7A, 0x60, 0x10, 0x00,
        0x40, 0x60,
    ]);
    assert_eq!(a, [0x00, 0x30, 0x70, 0x00, 0x16, 0x00, 0, 0, 0, 0]);
    let a = r.coe(&[0x00, 0x20, 0x50, 0x00, 0x16, 0x01, 0, 0, 0, 0]);
    assert_eq!(&a[10..], &[0x20, 0x00, 0x7A, 0x60, 0x10, 0x00, 0x40, 0x60]);
    // Identity record from sub-index 1.
    let a = r.coe(&[0x00, 0x20, 0x50, 0x18, 0x10, 0x01, 0, 0, 0, 0]);
    assert_eq!(&a[6..14], &[16, 0, 0, 0, 0x5C, 0x0E, 0, 0]);
}

#[test]
fn sdo_information_emergencies_and_repeats_through_the_sync_managers() {
    let mut r = Raw::new(Flavour::Et1100);
    // OD list, all objects: 2 + 2 * 29 bytes, one frame.
    let a = r.coe(&[0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00]);
    assert_eq!(&a[..8], &[0x00, 0x80, 0x02, 0x00, 0x00, 0x00, 0x01, 0x00]);
    let idx: Vec<u16> = a[8..]
        .chunks(2)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect();
    assert_eq!(idx, OBJECTS.iter().map(|o| o.index).collect::<Vec<_>>());
    // Entry description with values and unit.
    let a = r.coe(&[0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x00, 0x20, 0x00, 0x70]);
    assert_eq!(
        &a[6..16],
        &[0x00, 0x20, 0x00, 0x70, 0x04, 0x00, 0x20, 0x00, 0xFF, 0x03]
    );
    assert!(a.ends_with(b"Current limit [mA]"));
    // Object description of a runtime object.
    let a = r.coe(&[0x00, 0x80, 0x03, 0x00, 0x00, 0x00, 0x12, 0x1C]);
    assert_eq!(&a[6..10], &[0x12, 0x1C, 0x06, 0x00]);
    // Emergencies go out when SM1 is free.
    r.seg
        .drive_mut(0)
        .slave
        .emergency(0xFF01, 0x80, [1, 2, 3, 4, 5]);
    let a = r.recv();
    assert_eq!(a, [0x00, 0x10, 0x01, 0xFF, 0x80, 1, 2, 3, 4, 5]);
    r.nothing();
    // A burst larger than the queue: 8 sent, 2 counted as overruns.
    for i in 0..10u8 {
        r.seg
            .drive_mut(0)
            .slave
            .emergency(0xFF00 | i as u16, 0x80, [i; 5]);
    }
    assert_eq!(r.seg.drive(0).slave.emergency_overruns(), 2);
    for i in 0..8u8 {
        assert_eq!(r.recv(), [0x00, 0x10, i, 0xFF, 0x80, i, i, i, i, i]);
    }
    r.nothing();
    // A repeated request (same counter) is answered again but executed once.
    let req = [0x00, 0x20, 0x23, 0xFF, 0x2F, 0x00, 0, 0, 0, 0];
    r.send(&req);
    let a = r.recv();
    assert_eq!(a[2], 0x60);
    let writes = r.seg.drive(0).app.ex.writes;
    let c = r.counter;
    r.send_with(c, &req);
    assert_eq!(r.recv(), a);
    assert_eq!(r.seg.drive(0).app.ex.writes, writes);
    // Not CoE: mailbox error "protocol not supported".
    let mut m = vec![0u8; 128];
    m[0] = 10;
    m[5] = 0x04 | (5 << 4);
    assert_eq!(r.wr(0x1000, &m), 1);
    r.counter = 5;
    assert_eq!(r.recv(), [0x01, 0x00, 0x02, 0x00]);
}
