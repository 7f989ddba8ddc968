//! Dynamic PDO mapping on the real drive (issue 5 "How to test"): the simulated drive
//! of `sim_drive` (firmware `Drive` + slave runtime + ESC simulator) is re-mapped by
//! ethercrab 0.7 in Pre-Op — 0x1C12 = {0x1601} (RxPDO2, PP), 0x1C13 = {0x1A00, 0x1A01}
//! with 0x1A01 filled by SDO (0x606C velocity actual, 0x60F4 following error) — and
//! exchanges the new image in Op with the right working counter. Invalid maps are
//! refused with the standard SDO aborts; what SDO cannot refuse is refused at P→S with
//! the AL codes (raw datagrams): SM2/SM3 length ≠ mapping → 0x001D / 0x001E, a mapped
//! entry the application cannot serve → 0x0025 (outputs) / 0x0024 (inputs).

use std::cell::RefCell;
use std::rc::Rc;

use ecat_slave_stack::al_status::AlStatusCode;
use ecat_slave_stack::esm::{EsmHooks, EsmState};
use ecat_slave_stack::od::{Dictionary, Object, ObjectKey, SdoAbort};
use ecat_slave_stack::pdo::ProcessData;
use ecat_slave_stack::slave::{CycleInfo, SlaveApplication};
use ethercrab::error::{Error, MailboxError};
use ethercrab::{MainDevice, PduStorage, SubDeviceState};
use firmware::identity::{self, Variant};
use tests_host::esc_sim::frame::{Command, FrameBuilder, FrameOutcome, Wire};
use tests_host::esc_sim::Flavour;
use tests_host::ethercrab_seam::{sim_config, sim_now_ns, sim_timeouts, MasterHarness};
use tests_host::file_flash::FileFlash;
use tests_host::segment::{sii_image, Segment, SegmentConfig};
use tests_host::sim_drive::{self, AxisModel, Motor, SimDrive, SimDriveConfig};

static PDU_STORAGE: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

/// The drive segment as ethercrab's wire (frames through `sim_drive::process`).
struct DriveWire(Segment<SimDrive>);

impl Wire for DriveWire {
    fn transfer(&mut self, frame: &mut [u8]) -> FrameOutcome {
        sim_drive::process(&mut self.0, frame)
    }
    fn now_ns(&self) -> u64 {
        self.0.now_ns()
    }
}

fn abort(e: Result<(), Error>) -> Option<u32> {
    match e {
        Err(Error::Mailbox(MailboxError::Aborted { code, .. })) => Some(u32::from(code)),
        _ => None,
    }
}

#[derive(Debug, Default)]
struct Report {
    /// (what, abort code) of every refused write.
    aborts: Vec<(&'static str, Option<u32>)>,
    sizes: (usize, usize),
    wkc: Vec<u16>,
    mode_display: Vec<u8>,
    max_velocity: i32,
    final_position_image: i32,
    final_position_sdo: i32,
    following_error_seen: bool,
    statusword_end: u16,
    states_ok: bool,
    safeop_aborts: Vec<(&'static str, Option<u32>)>,
}

async fn remap(md: Rc<MainDevice<'static>>, wire: Rc<RefCell<DriveWire>>) -> Result<Report, Error> {
    let mut r = Report::default();
    let group = md.init_single_group::<4, 256>(sim_now_ns).await?;
    {
        let sd = group.subdevice(&md, 0)?;
        // 0x1A01 by SDO: sub 0 to 0 first, entries, then the count.
        sd.sdo_write(0x1A01, 0, 0u8).await?;
        r.aborts.push((
            "Rx-only object into a TxPDO map",
            abort(
                sd.sdo_write(0x1A01, 1, ObjectKey::new(0x6040, 0).mapping_word(16))
                    .await,
            ),
        ));
        r.aborts.push((
            "object that does not exist",
            abort(
                sd.sdo_write(0x1A01, 1, ObjectKey::new(0x5FF0, 0).mapping_word(32))
                    .await,
            ),
        ));
        sd.sdo_write(0x1A01, 1, ObjectKey::new(0x606C, 0).mapping_word(32))
            .await?;
        sd.sdo_write(0x1A01, 2, ObjectKey::new(0x60F4, 0).mapping_word(32))
            .await?;
        sd.sdo_write(0x1A01, 0, 2u8).await?;
        r.aborts.push((
            "entry written while sub 0 != 0",
            abort(
                sd.sdo_write(0x1A01, 1, ObjectKey::new(0x6064, 0).mapping_word(32))
                    .await,
            ),
        ));
        // 0x1A02: 10 × 32 bit = 40 bytes; assigned with 0x1A00 (19) + 0x1A01 (8) = 67.
        sd.sdo_write(0x1A02, 0, 0u8).await?;
        for k in 1..=10u8 {
            sd.sdo_write(0x1A02, k, ObjectKey::new(0x6064, 0).mapping_word(32))
                .await?;
        }
        sd.sdo_write(0x1A02, 0, 10u8).await?;
        sd.sdo_write(0x1C13, 0, 0u8).await?;
        sd.sdo_write(0x1C13, 1, 0x1A00u16).await?;
        sd.sdo_write(0x1C13, 2, 0x1A01u16).await?;
        sd.sdo_write(0x1C13, 3, 0x1A02u16).await?;
        r.aborts.push((
            "assignment above 64 bytes",
            abort(sd.sdo_write(0x1C13, 0, 3u8).await),
        ));
        sd.sdo_write(0x1C13, 0, 2u8).await?;
        // An assigned map growing beyond 64 bytes in total.
        sd.sdo_write(0x1A01, 0, 0u8).await?;
        for k in 1..=12u8 {
            sd.sdo_write(0x1A01, k, ObjectKey::new(0x6064, 0).mapping_word(32))
                .await?;
        }
        r.aborts.push((
            "assigned map above 64 bytes in total",
            abort(sd.sdo_write(0x1A01, 0, 12u8).await),
        ));
        sd.sdo_write(0x1A01, 0, 0u8).await?;
        sd.sdo_write(0x1A01, 1, ObjectKey::new(0x606C, 0).mapping_word(32))
            .await?;
        sd.sdo_write(0x1A01, 2, ObjectKey::new(0x60F4, 0).mapping_word(32))
            .await?;
        sd.sdo_write(0x1A01, 0, 2u8).await?;
        // 0x1C12 = {0x1601}.
        sd.sdo_write(0x1C12, 0, 0u8).await?;
        r.aborts.push((
            "TxPDO map in the RxPDO assignment",
            abort(sd.sdo_write(0x1C12, 1, 0x1A00u16).await),
        ));
        sd.sdo_write(0x1C12, 1, 0x1601u16).await?;
        sd.sdo_write(0x1C12, 0, 1u8).await?;
        // Profile position parameters by SDO, mode by PDO (0x6060 is in RxPDO2).
    }
    let group = group.into_op(&md).await?;
    let sd = group.subdevice(&md, 0)?;
    // (One guard at a time: inputs and outputs share ethercrab's PDI lock.)
    let out_len = sd.outputs_raw_mut().len();
    let in_len = sd.inputs_raw().len();
    r.sizes = (out_len, in_len);
    r.states_ok = true;
    let target = 20_000i32;
    for k in 0..1500u32 {
        let cw: u16 = match k {
            0..=2 => 0x0006,
            3..=5 => 0x0007,
            6..=9 => 0x000F,
            10..=12 => 0x001F, // new set-point
            _ => 0x000F,
        };
        {
            let mut o = sd.outputs_raw_mut();
            if o.len() >= 19 {
                o[0..2].copy_from_slice(&cw.to_le_bytes());
                o[2..6].copy_from_slice(&target.to_le_bytes());
                o[6..10].copy_from_slice(&50_000u32.to_le_bytes());
                o[10..14].copy_from_slice(&500_000u32.to_le_bytes());
                o[14..18].copy_from_slice(&500_000u32.to_le_bytes());
                o[18] = 1; // profile position
            }
        }
        let res = group.tx_rx(&md).await?;
        r.wkc.push(res.working_counter);
        if res
            .subdevice_states
            .iter()
            .any(|s| *s != SubDeviceState::Op)
        {
            r.states_ok = false;
        }
        {
            let i = sd.inputs_raw();
            if i.len() >= 27 {
                r.mode_display.push(i[4]);
                let v = i32::from_le_bytes([i[19], i[20], i[21], i[22]]);
                r.max_velocity = r.max_velocity.max(v);
                let fe = i32::from_le_bytes([i[23], i[24], i[25], i[26]]);
                r.following_error_seen |= fe != 0;
                r.final_position_image = i32::from_le_bytes([i[5], i[6], i[7], i[8]]);
                r.statusword_end = u16::from_le_bytes([i[2], i[3]]);
            }
        }
        wire.borrow_mut().advance_cycle();
    }
    r.final_position_sdo = sd.sdo_read::<i32>(0x6064, 0).await?;
    let group = group.into_safe_op(&md).await?;
    {
        let sd = group.subdevice(&md, 0)?;
        r.safeop_aborts.push((
            "0x1C12:00 in Safe-Op",
            abort(sd.sdo_write(0x1C12, 0, 0u8).await),
        ));
        r.safeop_aborts.push((
            "0x1A01:00 in Safe-Op",
            abort(sd.sdo_write(0x1A01, 0, 0u8).await),
        ));
    }
    let _ = group.into_pre_op(&md).await?.into_init(&md).await?;
    Ok(r)
}

impl DriveWire {
    fn advance_cycle(&mut self) {
        let left = 1_000_000 - self.0.now_ns() % 1_000_000;
        sim_drive::advance(&mut self.0, left);
    }
}

#[test]
fn ethercrab_remaps_in_preop_and_exchanges_the_new_image() {
    let mut h = MasterHarness::new(&PDU_STORAGE).expect("storage split once");
    for flavour in [Flavour::Lan9252, Flavour::Et1100] {
        let cfg = SimDriveConfig {
            motor: Motor::Ecn57_20,
            flavour,
            flash_file: None,
            dips: tests_host::sim_drive::DIPS_ALL_ON,
        };
        let seg = sim_drive::segment_with(&cfg, 1, AxisModel::Kinematic).expect("segment");
        let wire = Rc::new(RefCell::new(DriveWire(seg)));
        let w2 = wire.clone();
        let (res, stats) = h.run(wire.clone(), sim_timeouts(), sim_config(), |md| {
            remap(md, w2)
        });
        let r = res.unwrap_or_else(|e| panic!("{flavour:?}: ethercrab error {e:?}; {stats:?}"));
        let expect = [
            ("Rx-only object into a TxPDO map", 0x0604_0041),
            ("object that does not exist", 0x0604_0041),
            ("entry written while sub 0 != 0", 0x0601_0003),
            ("assignment above 64 bytes", 0x0604_0042),
            ("assigned map above 64 bytes in total", 0x0604_0042),
            // 0x1C12 entries range over 0x1600-0x1603: value too high.
            ("TxPDO map in the RxPDO assignment", 0x0609_0031),
        ];
        for ((what, got), (w, code)) in r.aborts.iter().zip(expect) {
            assert_eq!((*what, *got), (w, Some(code)), "{flavour:?}");
        }
        assert_eq!(r.aborts.len(), expect.len());
        // RxPDO2 = 19 bytes out; 0x1A00 (19) + 0x1A01 (8) = 27 bytes in.
        assert_eq!(r.sizes, (19, 27), "{flavour:?}: image sizes");
        assert!(r.states_ok, "{flavour:?}: stayed in Op");
        // One LRW: outputs written (+2) and inputs read (+1).
        assert!(
            r.wkc.iter().all(|w| *w == 3),
            "{flavour:?}: {:?}",
            &r.wkc[..5]
        );
        // Mode display 1 (PP) through the new image once the drive took the mode.
        assert_eq!(r.mode_display.last(), Some(&1), "{flavour:?}");
        // 0x606C from 0x1A01 shows the move at the profile velocity (50 000 units/s,
        // within the kinematic axis's few per cent of overshoot).
        assert!(
            r.max_velocity > 40_000 && r.max_velocity <= 52_500,
            "{flavour:?}: velocity actual {}",
            r.max_velocity
        );
        // At the end: target reached (statusword bit 10), the image and SDO agree.
        assert_ne!(
            r.statusword_end & 0x0400,
            0,
            "{flavour:?}: {:#06x}",
            r.statusword_end
        );
        assert!(
            (r.final_position_image - 20_000).abs() <= 20,
            "{flavour:?}: position {}",
            r.final_position_image
        );
        assert_eq!(r.final_position_image, r.final_position_sdo, "{flavour:?}");
        let _ = r.following_error_seen;
        for (what, got) in &r.safeop_aborts {
            assert_eq!(*got, Some(0x0800_0022), "{flavour:?}: {what}");
        }
        assert_eq!(r.safeop_aborts.len(), 2);
        assert_eq!(wire.borrow().0.al_status(0), (0x01, 0), "{flavour:?}");
    }
}

// ---- P→S checks with raw datagrams ---------------------------------------------------

/// The drive, except that it cannot serve one object in process data (it refuses the
/// slot although its dictionary calls the object mappable).
struct NoSlot {
    inner: SimDrive,
    index: u16,
}

impl Dictionary for NoSlot {
    fn objects(&self) -> &'static [Object] {
        self.inner.objects()
    }
    fn read(&mut self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        self.inner.read(key, buf)
    }
    fn write(&mut self, key: ObjectKey, data: &[u8], state: EsmState) -> Result<(), SdoAbort> {
        self.inner.write(key, data, state)
    }
    fn write_with_runtime(
        &mut self,
        key: ObjectKey,
        data: &[u8],
        state: EsmState,
        runtime: &mut dyn Dictionary,
    ) -> Result<(), SdoAbort> {
        self.inner.write_with_runtime(key, data, state, runtime)
    }
}

impl ProcessData for NoSlot {
    fn rx_slot(&self, key: ObjectKey) -> Option<u16> {
        let ObjectKey { index, .. } = key;
        (index != self.index)
            .then(|| self.inner.rx_slot(key))
            .flatten()
    }
    fn tx_slot(&self, key: ObjectKey) -> Option<u16> {
        let ObjectKey { index, .. } = key;
        (index != self.index)
            .then(|| self.inner.tx_slot(key))
            .flatten()
    }
    fn set_rx(&mut self, slot: u16, raw: u64) {
        self.inner.set_rx(slot, raw)
    }
    fn get_tx(&self, slot: u16) -> u64 {
        self.inner.get_tx(slot)
    }
}

impl EsmHooks for NoSlot {
    fn on_state_change(&mut self, from: EsmState, to: EsmState) {
        self.inner.on_state_change(from, to)
    }
}

impl SlaveApplication for NoSlot {
    fn cycle(&mut self, info: &CycleInfo) {
        self.inner.cycle(info)
    }
    fn on_outputs_lost(&mut self, code: AlStatusCode) {
        self.inner.on_outputs_lost(code)
    }
    fn sync_error_limit(&self) -> u16 {
        self.inner.sync_error_limit()
    }
}

/// One drive on raw datagrams (station address 0x1000).
struct Raw<A: SlaveApplication> {
    seg: Segment<A>,
}

impl<A: SlaveApplication> Raw<A> {
    fn new(mut seg: Segment<A>) -> Self {
        let d = seg.raw(FrameBuilder::new().physical(
            Command::Apwr,
            0,
            0x0010,
            &0x1000u16.to_le_bytes(),
        ));
        assert_eq!(d[0].wkc, 1);
        let mut r = Raw { seg };
        r.sm(0, 0x1000, 128, 0x26);
        r.sm(1, 0x1080, 128, 0x22);
        assert_eq!(r.request(0x02), (0x02, 0), "Pre-Op");
        r
    }
    fn wr(&mut self, ado: u16, data: &[u8]) -> u16 {
        self.seg
            .raw(FrameBuilder::new().physical(Command::Fpwr, 0x1000, ado, data))[0]
            .wkc
    }
    fn request(&mut self, ctl: u16) -> (u16, u16) {
        assert_eq!(self.wr(0x0120, &ctl.to_le_bytes()), 1);
        self.seg.advance(1000);
        self.seg.al_status(0)
    }
    fn sm(&mut self, n: u16, start: u16, len: u16, control: u8) {
        let mut b = [0u8; 8];
        b[0..2].copy_from_slice(&start.to_le_bytes());
        b[2..4].copy_from_slice(&len.to_le_bytes());
        b[4] = control;
        b[6] = 1;
        self.wr(0x0806 + 8 * n, &[0]);
        assert_eq!(self.wr(0x0800 + 8 * n, &b), 1);
    }
}

fn drive_segment(flavour: Flavour) -> Segment<SimDrive> {
    let cfg = SimDriveConfig {
        motor: Motor::Ecn57_20,
        flavour,
        flash_file: None,
        dips: tests_host::sim_drive::DIPS_ALL_ON,
    };
    sim_drive::segment_with(&cfg, 1, AxisModel::Kinematic).expect("segment")
}

#[test]
fn sync_manager_length_mismatch_is_0x001d_or_0x001e() {
    for flavour in [Flavour::Lan9252, Flavour::Et1100] {
        let mut r = Raw::new(drive_segment(flavour));
        // Default maps: 12 bytes out (0x1600), 19 bytes in (0x1A00). A master that
        // configured SM2 for RxPDO2 (19 bytes) without re-assigning 0x1C12:
        r.sm(2, 0x1100, 19, 0x64);
        r.sm(3, 0x1400, 19, 0x20);
        assert_eq!(r.request(0x04), (0x12, 0x001D), "{flavour:?}");
        assert_eq!(r.request(0x12).0, 0x02);
        // Outputs right, inputs as if 0x1A01 (8 bytes) were assigned too:
        r.sm(2, 0x1100, 12, 0x64);
        r.sm(3, 0x1400, 27, 0x20);
        assert_eq!(r.request(0x04), (0x12, 0x001E), "{flavour:?}");
        assert_eq!(r.request(0x12).0, 0x02);
        // Both right: Safe-Op.
        r.sm(3, 0x1400, 19, 0x20);
        assert_eq!(r.request(0x04), (0x04, 0), "{flavour:?}");
    }
}

#[test]
fn sync_manager_length_follows_the_remapped_image() {
    // Re-mapped through the runtime's objects (what the SDO server writes): 0x1C12 =
    // {0x1601} → 19 bytes; an SM2 still sized for 0x1600 is refused, 19 bytes pass.
    let mut r = Raw::new(drive_segment(Flavour::Lan9252));
    {
        let d = r.seg.drive_mut(0);
        let mut rt = d.slave.runtime_objects(firmware::dictionary::OBJECTS);
        rt.write(ObjectKey::new(0x1C12, 0), &[0], EsmState::PreOp)
            .unwrap();
        rt.write(
            ObjectKey::new(0x1C12, 1),
            &0x1601u16.to_le_bytes(),
            EsmState::PreOp,
        )
        .unwrap();
        rt.write(ObjectKey::new(0x1C12, 0), &[1], EsmState::PreOp)
            .unwrap();
    }
    r.sm(2, 0x1100, 12, 0x64);
    r.sm(3, 0x1400, 19, 0x20);
    assert_eq!(r.request(0x04), (0x12, 0x001D));
    assert_eq!(r.request(0x12).0, 0x02);
    r.sm(2, 0x1100, 19, 0x64);
    assert_eq!(r.request(0x04), (0x04, 0));
}

/// A segment whose drive cannot serve `index` in process data.
fn no_slot_segment(index: u16) -> Segment<NoSlot> {
    let desc = identity::device_description(
        Variant::HybridServo,
        sim_drive::esc_flavour(Flavour::Et1100),
        0,
    );
    let sii = sii_image(&desc).expect("SII");
    let axis = tests_host::sim_axis::boxed_model(Motor::Ecn57_20, AxisModel::Kinematic, 1);
    let app = NoSlot {
        inner: SimDrive::new(0x1000, FileFlash::in_memory(), axis),
        index,
    };
    let mut seg = Segment::new(
        SegmentConfig::new(Flavour::Et1100),
        &sii,
        vec![app],
        sim_drive::slave_config(),
        None,
    )
    .expect("segment");
    for d in seg.drives_mut() {
        let mut runtime = d.slave.runtime_objects(firmware::dictionary::OBJECTS);
        d.app.inner.drive.power_up(&mut runtime);
    }
    seg
}

#[test]
fn a_map_the_application_cannot_serve_is_refused_at_p_to_s() {
    // Inputs: 0x1A01 = {0x606C} assigned; the application has no slot for 0x606C.
    let mut r = Raw::new(no_slot_segment(0x606C));
    {
        let d = r.seg.drive_mut(0);
        let mut rt = d.slave.runtime_objects(firmware::dictionary::OBJECTS);
        let w = |rt: &mut dyn Dictionary, i: u16, s: u8, v: &[u8]| {
            rt.write(ObjectKey::new(i, s), v, EsmState::PreOp)
        };
        // The dictionary says mappable: the SDO layer accepts it.
        assert_eq!(w(&mut rt, 0x1A01, 0, &[0]), Ok(()));
        assert_eq!(
            w(
                &mut rt,
                0x1A01,
                1,
                &ObjectKey::new(0x606C, 0).mapping_word(32).to_le_bytes()
            ),
            Ok(())
        );
        assert_eq!(w(&mut rt, 0x1A01, 0, &[1]), Ok(()));
        assert_eq!(w(&mut rt, 0x1C13, 0, &[0]), Ok(()));
        assert_eq!(w(&mut rt, 0x1C13, 1, &0x1A00u16.to_le_bytes()), Ok(()));
        assert_eq!(w(&mut rt, 0x1C13, 2, &0x1A01u16.to_le_bytes()), Ok(()));
        assert_eq!(w(&mut rt, 0x1C13, 0, &[2]), Ok(()));
    }
    r.sm(2, 0x1100, 12, 0x64);
    r.sm(3, 0x1400, 23, 0x20);
    assert_eq!(r.request(0x04), (0x12, 0x0024), "invalid input mapping");

    // Outputs: 0x1C12 = {0x1601}; the application has no slot for 0x6081.
    let mut r = Raw::new(no_slot_segment(0x6081));
    {
        let d = r.seg.drive_mut(0);
        let mut rt = d.slave.runtime_objects(firmware::dictionary::OBJECTS);
        rt.write(ObjectKey::new(0x1C12, 0), &[0], EsmState::PreOp)
            .unwrap();
        rt.write(
            ObjectKey::new(0x1C12, 1),
            &0x1601u16.to_le_bytes(),
            EsmState::PreOp,
        )
        .unwrap();
        rt.write(ObjectKey::new(0x1C12, 0), &[1], EsmState::PreOp)
            .unwrap();
    }
    r.sm(2, 0x1100, 19, 0x64);
    r.sm(3, 0x1400, 19, 0x20);
    assert_eq!(r.request(0x04), (0x12, 0x0025), "invalid output mapping");
    // Back to the default assignment: Safe-Op.
    assert_eq!(r.request(0x12).0, 0x02);
    {
        let d = r.seg.drive_mut(0);
        let mut rt = d.slave.runtime_objects(firmware::dictionary::OBJECTS);
        rt.write(
            ObjectKey::new(0x1C12, 1),
            &0x1600u16.to_le_bytes(),
            EsmState::PreOp,
        )
        .unwrap_err();
        rt.write(ObjectKey::new(0x1C12, 0), &[0], EsmState::PreOp)
            .unwrap();
        rt.write(
            ObjectKey::new(0x1C12, 1),
            &0x1600u16.to_le_bytes(),
            EsmState::PreOp,
        )
        .unwrap();
        rt.write(ObjectKey::new(0x1C12, 0), &[1], EsmState::PreOp)
            .unwrap();
    }
    r.sm(2, 0x1100, 12, 0x64);
    assert_eq!(r.request(0x04), (0x04, 0));
}

#[test]
fn every_mappable_entry_of_the_product_has_a_slot() {
    // Why 0x0024/0x0025 need the test application above: the product drive serves
    // every entry its dictionary calls mappable, so SDO-accepted maps always compile.
    let d = firmware::drive::Drive::new(Variant::HybridServo, 1);
    let mut missing = Vec::new();
    for o in firmware::dictionary::OBJECTS {
        for e in o.entries() {
            if e.pdo_mappable().rx() && d.rx_slot(ObjectKey::new(o.index, e.sub)).is_none() {
                missing.push(("rx", o.index, e.sub));
            }
            if e.pdo_mappable().tx() && d.tx_slot(ObjectKey::new(o.index, e.sub)).is_none() {
                missing.push(("tx", o.index, e.sub));
            }
        }
    }
    assert!(missing.is_empty(), "{missing:x?}");
}
