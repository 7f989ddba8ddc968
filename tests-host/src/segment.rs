//! A virtual EtherCAT segment: N simulated drives in a line.
//!
//! Each [`Drive`] is an [`EscSim`] (wire side), the slave runtime
//! [`ecat_slave_stack::slave::Slave`] talking to the same simulator through a PDI
//! path, and an application. The PDI path is either direct ([`PdiPath::Direct`]: the
//! runtime calls the simulator's [`EscAccess`]) or the real chip driver over the
//! SPI-level chip model ([`PdiPath::Spi`]: `Lan9252`/`Et1100` driver → SPI model →
//! simulator), so the same bytes as on the board cross the SPI bus.
//!
//! [`Segment::process`] is "frame in → frame out": the frame passes every ESC in
//! order, then every slave's `poll()` runs, then simulated time moves on by
//! [`SegmentConfig::frame_ns`]. [`Segment::advance`] moves simulated time explicitly
//! (cyclic operation, watchdogs, SYNC0), polling the slaves afterwards. Nothing here
//! reads the wall clock, so a test behaves the same on any machine.
//!
//! [`TestDrive`] is a minimal application (dictionary with the PDO objects and a few
//! CiA 402 objects, an echo cycle) for tests until the real drive application is
//! plugged in; any [`SlaveApplication`] works.

use crate::esc_sim::frame::{
    datagrams, process_frame, DatagramView, FrameBuilder, FrameOutcome, Wire,
};
use crate::esc_sim::{EscSim, Flavour, SharedEsc};
use crate::pi_mutex::PiGuard;
use crate::spi_models::{Et1100Model, Lan9252Model};
use ecat_slave_stack::al_status::AlStatusCode;
use ecat_slave_stack::esm::{EsmHooks, EsmState};
use ecat_slave_stack::et1100::{Et1100, Et1100Config};
use ecat_slave_stack::lan9252::{Lan9252, Lan9252Config};
use ecat_slave_stack::od::{
    Access, DataType, Dictionary, EntryDesc, Object, ObjectDesc, ObjectKey, PdoMappable, SdoAbort,
};
use ecat_slave_stack::pdo::{self, PdoDefaults, ProcessData};
use ecat_slave_stack::sii::{self, DeviceDescription};
use ecat_slave_stack::slave::{CycleInfo, Slave, SlaveApplication, SlaveConfig};
use ecat_slave_stack::{sync, EscAccess, EscError};

/// How the slave runtime reaches the ESC.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PdiPath {
    /// The runtime calls the simulator directly.
    Direct,
    /// Chip driver (LAN9252 or ET1100, per flavour) → SPI chip model → simulator.
    Spi,
}

/// The PDI side of one drive.
pub enum Pdi {
    /// Direct access.
    Direct(SharedEsc),
    /// LAN9252 driver over the LAN9252 SPI model.
    Lan9252(Box<Lan9252<Lan9252Model<SharedEsc>>>),
    /// ET1100 driver over the ET1100 SPI model.
    Et1100(Box<Et1100<Et1100Model<SharedEsc>>>),
}

impl Pdi {
    /// Protocol violations the SPI model recorded (always empty for the direct path).
    pub fn spi_violations(&mut self) -> Vec<String> {
        match self {
            Pdi::Direct(_) => Vec::new(),
            Pdi::Lan9252(d) => d.spi_mut().violations.clone(),
            Pdi::Et1100(d) => d.spi_mut().violations.clone(),
        }
    }
    fn trim_logs(&mut self) {
        match self {
            Pdi::Direct(_) => {}
            Pdi::Lan9252(d) => d.spi_mut().log.clear(),
            Pdi::Et1100(d) => d.spi_mut().log.clear(),
        }
    }
}

impl EscAccess for Pdi {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EscError> {
        match self {
            Pdi::Direct(e) => e.read(addr, buf),
            Pdi::Lan9252(d) => d.read(addr, buf),
            Pdi::Et1100(d) => d.read(addr, buf),
        }
    }
    fn write(&mut self, addr: u16, data: &[u8]) -> Result<(), EscError> {
        match self {
            Pdi::Direct(e) => e.write(addr, data),
            Pdi::Lan9252(d) => d.write(addr, data),
            Pdi::Et1100(d) => d.write(addr, data),
        }
    }
    fn al_event(&mut self) -> Result<u32, EscError> {
        match self {
            Pdi::Direct(e) => e.al_event(),
            Pdi::Lan9252(d) => d.al_event(),
            Pdi::Et1100(d) => d.al_event(),
        }
    }
}

/// A delay that does not wait (simulated chips are ready at once).
struct NoDelay;
impl embedded_hal::delay::DelayNs for NoDelay {
    fn delay_ns(&mut self, _ns: u32) {}
}

/// One simulated drive.
pub struct Drive<A> {
    /// The ESC simulator (wire side; also reachable for inspection).
    pub esc: SharedEsc,
    /// The slave runtime.
    pub slave: Slave<Pdi>,
    /// The application.
    pub app: A,
    /// ESC access errors returned by `poll()` (should stay 0).
    pub poll_errors: u64,
    /// Simulated time of the last `poll()`, ns.
    pub polled_ns: u64,
    /// `poll()` calls so far.
    pub polls: u64,
}

impl<A: SlaveApplication> Drive<A> {
    fn poll_at(&mut self, t_ns: u64) {
        let t_ns = t_ns.max(self.polled_ns);
        self.polled_ns = t_ns;
        self.polls += 1;
        if self.slave.poll(&mut self.app, t_ns / 1000).is_err() {
            self.poll_errors += 1;
        }
        self.slave.esc_mut().trim_logs();
    }
}

/// Longest time between two polls of a slave by [`Segment::poll_pending`] when its
/// ESC raises no interrupt, ns: the board's `ecat` task polls on each IRQ edge and at
/// least every millisecond.
pub const POLL_EVERY_NS: u64 = 1_000_000;

/// Segment settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SegmentConfig {
    /// Simulated chip.
    pub flavour: Flavour,
    /// PDI path.
    pub pdi: PdiPath,
    /// Cable + forwarding delay from one ESC to the next, ns.
    pub hop_ns: u64,
    /// Simulated time a frame takes (added after each frame), ns.
    pub frame_ns: u64,
}

impl SegmentConfig {
    /// Direct PDI, 600 ns per hop, 10 µs per frame.
    pub const fn new(flavour: Flavour) -> Self {
        SegmentConfig {
            flavour,
            pdi: PdiPath::Direct,
            hop_ns: 600,
            frame_ns: 10_000,
        }
    }
    /// The same with another PDI path.
    pub const fn with_pdi(mut self, pdi: PdiPath) -> Self {
        self.pdi = pdi;
        self
    }
}

/// N drives in a line.
pub struct Segment<A: SlaveApplication> {
    cfg: SegmentConfig,
    drives: Vec<Drive<A>>,
    now_ns: u64,
    frames: u64,
}

impl<A: SlaveApplication> Segment<A> {
    /// Powers up one drive per application: each ESC loads `sii` (alias word 4 is
    /// replaced by `alias_base + position` when `alias_base` is given), the PDI path is
    /// initialised (chip start-up over SPI for [`PdiPath::Spi`]) and the runtime's
    /// `init()` runs.
    pub fn new(
        cfg: SegmentConfig,
        sii: &[u8],
        apps: Vec<A>,
        slave_cfg: SlaveConfig,
        alias_base: Option<u16>,
    ) -> Result<Self, EscError> {
        let n = apps.len();
        let mut drives = Vec::with_capacity(n);
        for (i, app) in apps.into_iter().enumerate() {
            let mut image = sii.to_vec();
            if let (Some(base), true) = (alias_base, image.len() >= 16) {
                image[8..10].copy_from_slice(&base.wrapping_add(i as u16).to_le_bytes());
                image[14] = sii::crc8(&image[..14]);
            }
            let mut esc = EscSim::new(cfg.flavour, image);
            esc.set_ports(i + 1 < n);
            // Different power-up instants: local clocks differ by a few ms.
            esc.set_clock_base(3_000_000 * i as u64 + 1_234);
            let shared = SharedEsc::new(esc);
            let mut pdi = match (cfg.pdi, cfg.flavour) {
                (PdiPath::Direct, _) => Pdi::Direct(shared.clone()),
                (PdiPath::Spi, Flavour::Lan9252) => {
                    let mut d =
                        Lan9252::new(Lan9252Model::new(shared.clone()), Lan9252Config::default());
                    d.init(&mut NoDelay)?;
                    Pdi::Lan9252(Box::new(d))
                }
                (PdiPath::Spi, Flavour::Et1100) => {
                    let mut d =
                        Et1100::new(Et1100Model::new(shared.clone()), Et1100Config::default());
                    d.init(&mut NoDelay)?;
                    Pdi::Et1100(Box::new(d))
                }
            };
            pdi.trim_logs();
            let mut slave = Slave::new(pdi, slave_cfg);
            slave.init()?;
            drives.push(Drive {
                esc: shared,
                slave,
                app,
                poll_errors: 0,
                polled_ns: 0,
                polls: 0,
            });
        }
        Ok(Segment {
            cfg,
            drives,
            now_ns: 0,
            frames: 0,
        })
    }

    /// Number of drives.
    pub fn len(&self) -> usize {
        self.drives.len()
    }
    /// True for a segment without drives.
    pub fn is_empty(&self) -> bool {
        self.drives.is_empty()
    }
    /// The settings.
    pub fn config(&self) -> SegmentConfig {
        self.cfg
    }
    /// Simulated time, ns.
    pub fn now_ns(&self) -> u64 {
        self.now_ns
    }
    /// Frames processed.
    pub fn frames(&self) -> u64 {
        self.frames
    }
    /// Drive `i`.
    pub fn drive(&self, i: usize) -> &Drive<A> {
        &self.drives[i]
    }
    /// Drive `i`, mutable.
    pub fn drive_mut(&mut self, i: usize) -> &mut Drive<A> {
        &mut self.drives[i]
    }
    /// All drives.
    pub fn drives_mut(&mut self) -> &mut [Drive<A>] {
        &mut self.drives
    }
    /// The simulator of drive `i`.
    pub fn esc(&self, i: usize) -> PiGuard<'_, EscSim> {
        self.drives[i].esc.borrow_mut()
    }

    /// The ESC simulators in line order, shared: what a thread that answers frames
    /// on its own (`virtual-drive`'s frame thread, [`crate::realtime`]) runs the
    /// frames through while this segment's slaves keep using them.
    pub fn escs(&self) -> Vec<SharedEsc> {
        self.drives.iter().map(|d| d.esc.clone()).collect()
    }

    /// Frame in → frame out: runs `frame` through every ESC (in place), then polls
    /// every slave and advances simulated time by one frame time.
    pub fn process(&mut self, frame: &mut [u8]) -> FrameOutcome {
        let outcome = {
            let mut escs: Vec<PiGuard<'_, EscSim>> =
                self.drives.iter().map(|d| d.esc.borrow_mut()).collect();
            process_frame(&mut escs, frame, self.now_ns, self.cfg.hop_ns)
        };
        self.frames += 1;
        self.poll_all();
        self.advance(self.cfg.frame_ns);
        outcome
    }

    /// Builds, processes and decodes a frame (for raw-datagram tests).
    pub fn raw(&mut self, fb: FrameBuilder) -> Vec<DatagramView> {
        let mut f = fb.build();
        self.process(&mut f);
        datagrams(&f).unwrap_or_default()
    }

    /// Runs every slave's `poll()` once at the current simulated time.
    pub fn poll_all(&mut self) {
        self.poll_where(|_, _| true);
    }

    /// Runs `poll()` at the current simulated time for every slave whose ESC raises its
    /// interrupt line (an AL event it has not masked) or that was last polled
    /// [`POLL_EVERY_NS`] ago or more: what the board's `ecat` task does (a poll on each
    /// IRQ edge, at least one per millisecond). A segment of many drives then spends
    /// its time on the drives a frame concerned.
    pub fn poll_pending(&mut self) {
        let now = self.now_ns;
        self.poll_where(|d, esc_irq| esc_irq || now.saturating_sub(d.polled_ns) >= POLL_EVERY_NS);
    }

    fn poll_where(&mut self, due: impl Fn(&Drive<A>, bool) -> bool) {
        let now = self.now_ns;
        for d in &mut self.drives {
            let irq = d.esc.borrow().pdi_irq();
            if due(d, irq) {
                d.poll_at(now);
            }
        }
    }

    /// Runs drive `i`'s `poll()` at `t_ns` (not before its previous poll) without
    /// moving the segment's time: the microcontroller of one drive answering its own
    /// interrupt, e.g. a SYNC0 pulse at the pulse's time (`crate::realtime::step`).
    pub fn poll_at(&mut self, i: usize, t_ns: u64) {
        self.drives[i].poll_at(t_ns);
    }

    /// Moves simulated time to `t_ns` (nothing if that is not ahead) and runs
    /// [`Segment::poll_pending`].
    pub fn advance_pending(&mut self, t_ns: u64) {
        if t_ns > self.now_ns {
            self.now_ns = t_ns;
            for d in &self.drives {
                d.esc.borrow_mut().advance_to(t_ns);
            }
        }
        self.poll_pending();
    }

    /// Advances simulated time by `dt_ns` (ESC timers, SYNC0, watchdogs), then polls
    /// every slave.
    pub fn advance(&mut self, dt_ns: u64) {
        self.now_ns += dt_ns;
        for d in &self.drives {
            d.esc.borrow_mut().advance_to(self.now_ns);
        }
        self.poll_all();
    }

    /// Advances simulated time to `t_ns` (nothing if that is not ahead), e.g. to follow
    /// the wall clock in a real-time loop.
    pub fn advance_to(&mut self, t_ns: u64) {
        if t_ns > self.now_ns {
            self.advance(t_ns - self.now_ns);
        }
    }

    /// AL status and status code of drive `i` as the master reads them.
    pub fn al_status(&self, i: usize) -> (u16, u16) {
        let e = self.drives[i].esc.borrow();
        (e.al_status(), e.al_status_code())
    }
}

impl<A: SlaveApplication> Wire for Segment<A> {
    fn transfer(&mut self, frame: &mut [u8]) -> FrameOutcome {
        self.process(frame)
    }
    fn now_ns(&self) -> u64 {
        self.now_ns
    }
}

// ---- a minimal test application ------------------------------------------------------

const fn var(index: u16, name: &'static str, entries: &'static [EntryDesc]) -> ObjectDesc {
    ObjectDesc::var(index, name, entries, "")
}

const E_1000: &[EntryDesc] = &[EntryDesc::new(
    0,
    "Device type",
    DataType::Unsigned32,
    Access::RO,
)];
const E_6040: &[EntryDesc] =
    &[EntryDesc::new(0, "Controlword", DataType::Unsigned16, Access::RW).pdo(PdoMappable::Rx)];
const E_6041: &[EntryDesc] =
    &[EntryDesc::new(0, "Statusword", DataType::Unsigned16, Access::RO).pdo(PdoMappable::Tx)];
const E_6064: &[EntryDesc] =
    &[
        EntryDesc::new(0, "Position actual value", DataType::Integer32, Access::RO)
            .pdo(PdoMappable::Tx),
    ];
const E_607A: &[EntryDesc] =
    &[EntryDesc::new(0, "Target position", DataType::Integer32, Access::RW).pdo(PdoMappable::Rx)];

/// The test application's dictionary: 0x1000, the PDO objects, the timing
/// diagnostics and four CiA 402 objects.
pub static TEST_OBJECTS: &[Object] = ecat_slave_stack::packed_dictionary!(&[
    pdo::OBJECTS,
    TEST_OBJECTS_LOCAL,
    &[sync::timing_diag_object(0x2200)]
]);
const TEST_OBJECTS_LOCAL: &[ObjectDesc] = &[
    var(0x1000, "Device type", E_1000),
    var(0x6040, "Controlword", E_6040),
    var(0x6041, "Statusword", E_6041),
    var(0x6064, "Position actual value", E_6064),
    var(0x607A, "Target position", E_607A),
];

const RX: &[u32] = &[
    ObjectKey::new(0x6040, 0).mapping_word(16),
    ObjectKey::new(0x607A, 0).mapping_word(32),
];
const TX: &[u32] = &[
    ObjectKey::new(0x6041, 0).mapping_word(16),
    ObjectKey::new(0x6064, 0).mapping_word(32),
];

/// Default mapping of [`TestDrive`]: 6 bytes each way.
pub const TEST_PDO_DEFAULTS: PdoDefaults = PdoDefaults {
    rx: [RX, &[], &[], &[]],
    tx: [TX, &[], &[], &[]],
    rx_assign: &[0x1600],
    tx_assign: &[0x1A00],
};

/// Bytes of outputs / inputs with the default mapping.
pub const TEST_PD_BYTES: usize = 6;

/// A minimal drive application: statusword = controlword + 1, position = target.
#[derive(Debug, Clone, Default)]
pub struct TestDrive {
    /// Controlword, target, statusword, position.
    pub values: [u64; 4],
    /// ESM changes seen.
    pub state_changes: Vec<(EsmState, EsmState)>,
    /// Cycles run / cycles with fresh outputs.
    pub cycles: (u64, u64),
    /// Communication-loss reactions.
    pub outputs_lost: Vec<AlStatusCode>,
}

impl Dictionary for TestDrive {
    fn objects(&self) -> &'static [Object] {
        TEST_OBJECTS
    }
    fn read(&mut self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        let ObjectKey { index, .. } = key;
        let (v, n) = match index {
            0x1000 => (0x0002_0192u64, 4),
            0x6040 => (self.values[0], 2),
            0x607A => (self.values[1], 4),
            0x6041 => (self.values[2], 2),
            0x6064 => (self.values[3], 4),
            _ => return Err(SdoAbort::ObjectDoesNotExist),
        };
        let out = buf.get_mut(..n).ok_or(SdoAbort::GeneralError)?;
        out.copy_from_slice(&v.to_le_bytes()[..n]);
        Ok(n)
    }
    fn write(&mut self, key: ObjectKey, data: &[u8], _state: EsmState) -> Result<(), SdoAbort> {
        let ObjectKey { index, .. } = key;
        let mut b = [0u8; 8];
        let n = data.len().min(8);
        b[..n].copy_from_slice(&data[..n]);
        let v = u64::from_le_bytes(b);
        match index {
            0x6040 => self.values[0] = v,
            0x607A => self.values[1] = v,
            _ => return Err(SdoAbort::WriteReadOnly),
        }
        Ok(())
    }
}

impl ProcessData for TestDrive {
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
        if let Some(v) = self.values.get_mut(slot as usize) {
            *v = raw;
        }
    }
    fn get_tx(&self, slot: u16) -> u64 {
        self.values.get(slot as usize).copied().unwrap_or(0)
    }
}

impl EsmHooks for TestDrive {
    fn on_state_change(&mut self, from: EsmState, to: EsmState) {
        self.state_changes.push((from, to));
    }
}

impl SlaveApplication for TestDrive {
    fn cycle(&mut self, info: &CycleInfo) {
        self.cycles.0 += 1;
        if info.outputs_fresh {
            self.cycles.1 += 1;
        }
        self.values[2] = (self.values[0] + 1) & 0xFFFF;
        self.values[3] = self.values[1];
    }
    fn on_outputs_lost(&mut self, code: AlStatusCode) {
        self.outputs_lost.push(code);
    }
}

/// The runtime configuration for [`TestDrive`].
pub fn test_slave_config() -> SlaveConfig {
    SlaveConfig {
        pdo_defaults: TEST_PDO_DEFAULTS,
        timing_diag_index: Some(0x2200),
        ..SlaveConfig::default()
    }
}

/// A device description for tests: the project's identity and standard SM/FMMU
/// layout, on the given chip.
pub fn test_description(flavour: Flavour) -> DeviceDescription {
    DeviceDescription {
        vendor_id: 0x0000_0E5C,
        vendor_name: "ECS project",
        product_code: 0x0000_5840,
        revision: 0x0001_0000,
        serial: 0,
        type_name: "ECS-HS",
        name: "ECS-HS EtherCAT hybrid servo",
        group_type: "Drives",
        group_name: "Drives",
        hardware_version: "1.0",
        software_version: env!("CARGO_PKG_VERSION"),
        esc: match flavour {
            Flavour::Lan9252 => sii::EscFlavour::Lan9252,
            Flavour::Et1100 => sii::EscFlavour::Et1100,
        },
        sync_pulse_length: 1000,
        sync0_drive: sii::SyncDrive::PushPullActiveHigh,
        station_alias: 0,
        mailbox_protocols: sii::MBOX_COE,
        mailbox_data_link_layer: true,
        coe: sii::STANDARD_COE,
        fmmus: &sii::STANDARD_FMMUS,
        sync_managers: &sii::STANDARD_SYNC_MANAGERS,
        dc_op_modes: &sii::STANDARD_DC_OP_MODES,
        eeprom_bytes: 2048,
        physical_ports: 0x0011,
        profile_no: 402,
        ebus_current_ma: 0,
        bootstrap: None,
    }
}

/// The SII image of `desc` (EEPROM size, rest 0xFF).
pub fn sii_image(desc: &DeviceDescription) -> Result<Vec<u8>, sii::SiiError> {
    let mut buf = vec![0xFFu8; (desc.eeprom_bytes as usize).max(128)];
    let n = sii::build(desc, &mut buf)?;
    buf.truncate(buf.len().max(n));
    Ok(buf)
}

/// The SII image of `desc` with the PDO categories of the default PDOs of
/// `defaults` (the same list the ESI is written from), names from `objects`.
pub fn sii_image_with_pdos(
    desc: &DeviceDescription,
    objects: &'static [Object],
    defaults: &PdoDefaults,
) -> Result<Vec<u8>, sii::SiiError> {
    let pdos = ecat_slave_stack::esi::pdo_maps(desc, objects, defaults);
    let mut buf = vec![0xFFu8; (desc.eeprom_bytes as usize).max(128)];
    let n = sii::build_with_pdos(desc, objects, &pdos, &mut buf)?;
    buf.truncate(buf.len().max(n));
    Ok(buf)
}

/// A segment of `n` [`TestDrive`]s with the test description's SII.
pub fn test_segment(cfg: SegmentConfig, n: usize) -> Result<Segment<TestDrive>, EscError> {
    let image = sii_image(&test_description(cfg.flavour)).map_err(|_| EscError::NotDetected)?;
    let apps = (0..n).map(|_| TestDrive::default()).collect();
    Segment::new(cfg, &image, apps, test_slave_config(), None)
}
