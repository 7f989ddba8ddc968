//! The slave runtime (`ecat_slave_stack::slave`) against the ESC simulator, with the
//! test acting as the master through ECAT-side register and RAM accesses: mailbox
//! hand-over through real 1-buffer SyncManagers, 3-buffer process data, the
//! process-data watchdog and DC SYNC0 in simulated time.

use ecat_slave_stack::al_status::AlStatusCode;
use ecat_slave_stack::esm::{EsmHooks, EsmState};
use ecat_slave_stack::od::{
    Access, DataType, Dictionary, EntryDesc, Object, ObjectDesc, ObjectKey, PdoMappable, SdoAbort,
};
use ecat_slave_stack::pdo::{self, PdoDefaults, ProcessData};
use ecat_slave_stack::registers as reg;
use ecat_slave_stack::slave::{CycleInfo, Slave, SlaveApplication, SlaveConfig};
use tests_host::esc_sim::{EscSim, Flavour, SharedEsc, Side};

const E_6040: &[EntryDesc] =
    &[EntryDesc::new(0, "cw", DataType::Unsigned16, Access::RW).pdo(PdoMappable::Rx)];
const E_6041: &[EntryDesc] =
    &[EntryDesc::new(0, "sw", DataType::Unsigned16, Access::RO).pdo(PdoMappable::Tx)];
const E_6064: &[EntryDesc] =
    &[EntryDesc::new(0, "pos", DataType::Integer32, Access::RO).pdo(PdoMappable::Tx)];
const E_607A: &[EntryDesc] =
    &[EntryDesc::new(0, "target", DataType::Integer32, Access::RW).pdo(PdoMappable::Rx)];

const fn var(index: u16, entries: &'static [EntryDesc]) -> ObjectDesc {
    ObjectDesc::var(index, "", entries, "")
}

static OBJECTS: &[Object] = ecat_slave_stack::packed_dictionary!(&[pdo::OBJECTS, OBJECTS_LOCAL]);
const OBJECTS_LOCAL: &[ObjectDesc] = &[
    var(0x6040, E_6040),
    var(0x6041, E_6041),
    var(0x6064, E_6064),
    var(0x607A, E_607A),
];

const RX1: &[u32] = &[
    ObjectKey::new(0x6040, 0).mapping_word(16),
    ObjectKey::new(0x607A, 0).mapping_word(32),
];
const TX1: &[u32] = &[
    ObjectKey::new(0x6041, 0).mapping_word(16),
    ObjectKey::new(0x6064, 0).mapping_word(32),
];
const DEFAULTS: PdoDefaults = PdoDefaults {
    rx: [RX1, &[], &[], &[]],
    tx: [TX1, &[], &[], &[]],
    rx_assign: &[0x1600],
    tx_assign: &[0x1A00],
};

#[derive(Default)]
struct App {
    v: [u64; 4],
    lost: Option<AlStatusCode>,
    changes: Vec<(EsmState, EsmState)>,
}

impl Dictionary for App {
    fn objects(&self) -> &'static [Object] {
        OBJECTS
    }
    fn read(&mut self, _key: ObjectKey, _b: &mut [u8]) -> Result<usize, SdoAbort> {
        Err(SdoAbort::ObjectDoesNotExist)
    }
    fn write(&mut self, _key: ObjectKey, _d: &[u8], _st: EsmState) -> Result<(), SdoAbort> {
        Err(SdoAbort::ObjectDoesNotExist)
    }
}

impl ProcessData for App {
    fn rx_slot(&self, key: ObjectKey) -> Option<u16> {
        let ObjectKey { index, .. } = key;
        match index {
            0x6040 => Some(0),
            0x607A => Some(1),
            _ => None,
        }
    }
    fn tx_slot(&self, key: ObjectKey) -> Option<u16> {
        let ObjectKey { index, .. } = key;
        match index {
            0x6041 => Some(2),
            0x6064 => Some(3),
            _ => None,
        }
    }
    fn set_rx(&mut self, slot: u16, raw: u64) {
        self.v[slot as usize] = raw;
    }
    fn get_tx(&self, slot: u16) -> u64 {
        self.v[slot as usize]
    }
}

impl EsmHooks for App {
    fn on_state_change(&mut self, from: EsmState, to: EsmState) {
        self.changes.push((from, to));
    }
}

impl SlaveApplication for App {
    fn cycle(&mut self, _info: &CycleInfo) {
        self.v[2] = self.v[0] + 1;
        self.v[3] = self.v[1];
    }
    fn on_outputs_lost(&mut self, code: AlStatusCode) {
        self.lost = Some(code);
    }
}

struct Bench {
    sim: SharedEsc,
    slave: Slave<SharedEsc>,
    app: App,
    now_us: u64,
}

impl Bench {
    fn new(flavour: Flavour) -> Self {
        let sim = SharedEsc::new(EscSim::new(flavour, vec![0; 256]));
        let cfg = SlaveConfig {
            pdo_defaults: DEFAULTS,
            timing_diag_index: Some(0x2200),
            ..SlaveConfig::default()
        };
        let mut slave = Slave::new(SharedEsc(sim.0.clone()), cfg);
        slave.init().unwrap();
        Bench {
            sim,
            slave,
            app: App::default(),
            now_us: 0,
        }
    }
    fn ecat_write(&self, addr: u16, data: &[u8]) -> bool {
        self.sim.borrow_mut().side_write(Side::Ecat, addr, data)
    }
    fn ecat_read(&self, addr: u16, buf: &mut [u8]) -> bool {
        self.sim.borrow_mut().side_read(Side::Ecat, addr, buf)
    }
    fn ecat_u16(&self, addr: u16) -> u16 {
        let mut b = [0u8; 2];
        self.ecat_read(addr, &mut b);
        u16::from_le_bytes(b)
    }
    /// Advances simulated time by `us` and polls the slave once.
    fn step(&mut self, us: u64) {
        self.now_us += us;
        self.sim.borrow_mut().advance_to(self.now_us * 1000);
        self.slave.poll(&mut self.app, self.now_us).unwrap();
    }
    fn request(&mut self, state: u16) -> (u16, u16) {
        self.ecat_write(reg::AL_CONTROL.addr(), &state.to_le_bytes());
        self.step(10);
        (
            self.ecat_u16(reg::AL_STATUS.addr()),
            self.ecat_u16(reg::AL_STATUS_CODE.addr()),
        )
    }
    fn mailboxes(&self) {
        // SOEM style: SM0 and SM1 in one 16-byte write.
        let mut b = [0u8; 16];
        b[..8].copy_from_slice(&[0x00, 0x10, 0x80, 0x00, 0x26, 0x00, 0x01, 0x00]);
        b[8..].copy_from_slice(&[0x80, 0x10, 0x80, 0x00, 0x22, 0x00, 0x01, 0x00]);
        self.ecat_write(reg::sm_register(0), &b);
    }
    fn process_data_sms(&self) {
        self.process_data_sms_with(0x64);
    }
    fn process_data_sms_with(&self, sm2_control: u8) {
        self.ecat_write(
            reg::sm_register(2),
            &[0x00, 0x11, 6, 0, sm2_control, 0, 1, 0],
        );
        self.ecat_write(reg::sm_register(3), &[0x00, 0x14, 6, 0, 0x20, 0, 1, 0]);
    }
    /// One mailbox exchange: the whole SM0 buffer out, then SM1 read when full.
    fn mailbox(&mut self, request: &[u8]) -> Vec<u8> {
        let mut buf = [0u8; 128];
        buf[..request.len()].copy_from_slice(request);
        assert!(self.ecat_write(0x1000, &buf), "SM0 accepts the request");
        for _ in 0..10 {
            self.step(100);
            let mut st = [0u8; 1];
            self.ecat_read(reg::sm_register(1) + reg::sm::STATUS, &mut st);
            if st[0] & 0x08 != 0 {
                let mut out = vec![0u8; 128];
                assert!(self.ecat_read(0x1080, &mut out));
                return out;
            }
        }
        panic!("no mailbox answer");
    }
}

#[test]
fn bring_up_sdo_and_cyclic_exchange_on_both_chips() {
    for flavour in [Flavour::Lan9252, Flavour::Et1100] {
        let mut b = Bench::new(flavour);
        assert_eq!(b.ecat_u16(reg::AL_STATUS.addr()), 0x01);
        b.mailboxes();
        assert_eq!(b.request(2), (0x02, 0));
        // SDO upload 0x1A00:02 (expedited).
        let out = b.mailbox(&[
            10, 0, 0, 0, 0, 0x13, 0x00, 0x20, 0x40, 0x00, 0x1A, 0x02, 0, 0, 0, 0,
        ]);
        assert_eq!(out[5] & 0x0F, 3);
        assert_eq!(out[8], 0x43);
        assert_eq!(
            u32::from_le_bytes([out[12], out[13], out[14], out[15]]),
            0x6064_0020
        );
        b.process_data_sms();
        assert_eq!(b.request(4), (0x04, 0));
        // First inputs are in SM3 before any cycle.
        let mut inp = [0xFFu8; 6];
        assert!(b.ecat_read(0x1400, &mut inp));
        assert_eq!(inp, [0; 6]);
        assert_eq!(b.request(8), (0x08, 0));
        for k in 1..20u32 {
            let mut out = [0u8; 6];
            out[..2].copy_from_slice(&(k as u16).to_le_bytes());
            out[2..].copy_from_slice(&(k * 1000).to_le_bytes());
            assert!(b.ecat_write(0x1100, &out));
            b.step(1000);
            assert!(b.ecat_read(0x1400, &mut inp));
            assert_eq!(
                u16::from_le_bytes([inp[0], inp[1]]),
                k as u16 + 1,
                "{flavour:?}"
            );
            assert_eq!(
                u32::from_le_bytes([inp[2], inp[3], inp[4], inp[5]]),
                k * 1000
            );
        }
        assert_eq!(b.request(1), (0x01, 0));
        assert_eq!(
            b.app.changes,
            [
                (EsmState::Init, EsmState::PreOp),
                (EsmState::PreOp, EsmState::SafeOp),
                (EsmState::SafeOp, EsmState::Op),
                (EsmState::Op, EsmState::Init)
            ]
        );
    }
}

#[test]
fn stopped_master_trips_the_process_data_watchdog() {
    let mut b = Bench::new(Flavour::Lan9252);
    b.mailboxes();
    b.request(2);
    b.process_data_sms();
    b.request(4);
    b.request(8);
    for k in 0..5u8 {
        b.ecat_write(0x1100, &[k, 0, 0, 0, 0, 0]);
        b.step(1000);
    }
    assert_eq!(b.ecat_u16(reg::AL_STATUS.addr()), 0x08);
    // No more outputs: the default watchdog (100 ms) expires.
    for _ in 0..150 {
        b.step(1000);
    }
    assert_eq!(b.ecat_u16(reg::AL_STATUS.addr()), 0x14);
    assert_eq!(b.ecat_u16(reg::AL_STATUS_CODE.addr()), 0x001B);
    assert_eq!(b.app.lost, Some(AlStatusCode::SmWatchdog));
}

#[test]
fn dc_sync0_locks_and_missing_sync0_is_reported() {
    for cycle_us in [1000u64, 250, 125] {
        let mut b = Bench::new(Flavour::Et1100);
        b.mailboxes();
        b.request(2);
        // Watchdog off (SM2 without trigger) for this test.
        b.process_data_sms_with(0x24);
        b.ecat_write(reg::WATCHDOG_TIME_PD.addr(), &[0, 0]);
        b.ecat_write(
            reg::DC_SYNC0_CYCLE.addr(),
            &((cycle_us * 1000) as u32).to_le_bytes(),
        );
        let start = (b.now_us + 2000) * 1000;
        b.ecat_write(reg::DC_START_TIME.addr(), &start.to_le_bytes());
        b.ecat_write(reg::DC_ACTIVATION.addr(), &[0x03]);
        assert_eq!(b.request(4), (0x04, 0));
        b.ecat_write(reg::AL_CONTROL.addr(), &8u16.to_le_bytes());
        // Poll once per SYNC0 period; SYNC0 starts 2 ms from now.
        for _ in 0..(2000 / cycle_us + 12) {
            b.ecat_write(0x1100, &[1, 0, 0, 0, 0, 0]);
            b.step(cycle_us);
        }
        assert_eq!(b.ecat_u16(reg::AL_STATUS.addr()), 0x08, "{cycle_us} µs");
        let mut buf = [0u8; 4];
        let mut d = b.slave.dictionary(&mut b.app);
        d.read(ObjectKey::new(0x2200, 2), &mut buf).unwrap();
        assert_eq!(u32::from_le_bytes(buf) as u64, cycle_us);
        // SYNC0 stops.
        b.ecat_write(reg::DC_ACTIVATION.addr(), &[0x00]);
        for _ in 0..20 {
            b.step(cycle_us);
        }
        assert_eq!(b.ecat_u16(reg::AL_STATUS.addr()), 0x14);
        assert_eq!(b.ecat_u16(reg::AL_STATUS_CODE.addr()), 0x002C);
    }
}
