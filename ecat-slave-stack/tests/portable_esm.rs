//! The slave runtime against an in-memory fake ESC: the test writes AL control, SM
//! registers, mailbox and process data bytes the way a master would and checks AL
//! status / status code, the SyncManager hand-over and the application's view.
//! Runs on the host and under QEMU.
#![cfg_attr(target_os = "none", no_std, no_main)]

use ecat_slave_stack::al_status::AlStatusCode;
use ecat_slave_stack::esc::{EscAccess, EscError};
use ecat_slave_stack::esm::{self, Decision, EsmHooks, EsmState};
use ecat_slave_stack::foe::{ErrorCode, FoeFiles, WriteStatus};
use ecat_slave_stack::leds::{ErrCondition, Pattern, StatusLeds};
use ecat_slave_stack::od::{
    Access, DataType, Dictionary, EntryDesc, Object, ObjectDesc, ObjectKey, PdoMappable, SdoAbort,
};
use ecat_slave_stack::pdo::{self, PdoDefaults, ProcessData};
use ecat_slave_stack::registers as reg;
use ecat_slave_stack::slave::{CycleInfo, Slave, SlaveApplication, SlaveConfig};
use ecat_slave_stack::sm::BootMailbox;
use ecat_slave_stack::sync;

// ---- fake ESC -----------------------------------------------------------------

const MEM: usize = 0x2000;

struct FakeEsc {
    m: [u8; MEM],
}

impl FakeEsc {
    fn new() -> Self {
        let mut m = [0u8; MEM];
        m[reg::RAM_SIZE.addr() as usize] = 4;
        m[reg::SM_COUNT.addr() as usize] = 4;
        m[reg::FMMU_COUNT.addr() as usize] = 3;
        m[reg::STATION_ALIAS.addr() as usize] = 0x34;
        m[reg::STATION_ALIAS.addr() as usize + 1] = 0x12;
        m[reg::WATCHDOG_STATUS_PD.addr() as usize] = 1;
        FakeEsc { m }
    }
    fn u16(&self, a: u16) -> u16 {
        u16::from_le_bytes([self.m[a as usize], self.m[a as usize + 1]])
    }
    fn event(&self) -> u32 {
        let a = reg::AL_EVENT_REQUEST.addr() as usize;
        u32::from_le_bytes([self.m[a], self.m[a + 1], self.m[a + 2], self.m[a + 3]])
    }
    fn set_event(&mut self, bits: u32, on: bool) {
        let v = if on {
            self.event() | bits
        } else {
            self.event() & !bits
        };
        let a = reg::AL_EVENT_REQUEST.addr() as usize;
        self.m[a..a + 4].copy_from_slice(&v.to_le_bytes());
    }
    fn sm(&self, n: u16) -> (u16, u16) {
        let b = reg::sm_register(n as u8);
        (self.u16(b), self.u16(b + 2))
    }
    /// A master write, with the ESC's side effects.
    fn ecat_write(&mut self, addr: u16, data: &[u8]) {
        let a = addr as usize;
        self.m[a..a + data.len()].copy_from_slice(data);
        let end = addr + data.len() as u16;
        let touches = |x: u16| addr <= x && x < end;
        if touches(reg::AL_CONTROL.addr()) {
            self.set_event(1, true);
        }
        for n in 0..4 {
            if touches(reg::sm_register(n) + reg::sm::ACTIVATE) {
                self.set_event(1 << 4, true);
            }
        }
        let (s0, l0) = self.sm(0);
        if l0 > 0 && touches(s0 + l0 - 1) {
            self.m[(reg::sm_register(0) + 5) as usize] |= 0x08;
            self.set_event(1 << 8, true);
        }
        let (s2, l2) = self.sm(2);
        if l2 > 0 && touches(s2 + l2 - 1) {
            self.set_event(1 << 10, true);
            self.m[reg::WATCHDOG_STATUS_PD.addr() as usize] = 1;
        }
    }
    fn al_control(&mut self, v: u16) {
        self.ecat_write(reg::AL_CONTROL.addr(), &v.to_le_bytes());
    }
    fn al_status(&self) -> (u16, u16) {
        (
            self.u16(reg::AL_STATUS.addr()),
            self.u16(reg::AL_STATUS_CODE.addr()),
        )
    }
    fn write_sm(&mut self, n: u8, start: u16, len: u16, control: u8, enable: bool) {
        let mut b = [0u8; 8];
        b[..2].copy_from_slice(&start.to_le_bytes());
        b[2..4].copy_from_slice(&len.to_le_bytes());
        b[4] = control;
        b[6] = enable as u8;
        self.ecat_write(reg::sm_register(n), &b[..7]);
    }
    /// Master reads SM1 (mailbox in): returns the bytes, frees the mailbox.
    fn read_sm1(&mut self, out: &mut [u8]) -> bool {
        let st = reg::sm_register(1) + 5;
        if self.m[st as usize] & 0x08 == 0 {
            return false;
        }
        let (s, l) = self.sm(1);
        let n = out.len().min(l as usize);
        out[..n].copy_from_slice(&self.m[s as usize..s as usize + n]);
        self.m[st as usize] &= !0x08;
        true
    }
}

impl EscAccess for FakeEsc {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EscError> {
        let a = addr as usize;
        let end = a + buf.len();
        if end > MEM {
            return Err(EscError::OutOfRange);
        }
        buf.copy_from_slice(&self.m[a..end]);
        let touches = |x: u16| (a..end).contains(&(x as usize));
        if touches(reg::AL_CONTROL.addr()) {
            self.set_event(1, false);
        }
        if (0..4).any(|n| touches(reg::sm_register(n) + reg::sm::ACTIVATE)) {
            self.set_event(1 << 4, false);
        }
        if touches(reg::DC_SYNC0_STATUS.addr()) {
            self.set_event(1 << 2, false);
        }
        let (s0, l0) = self.sm(0);
        if l0 > 0 && touches(s0 + l0 - 1) {
            self.m[(reg::sm_register(0) + 5) as usize] &= !0x08;
            self.set_event(1 << 8, false);
        }
        let (s2, l2) = self.sm(2);
        if l2 > 0 && touches(s2 + l2 - 1) {
            self.set_event(1 << 10, false);
        }
        Ok(())
    }
    fn write(&mut self, addr: u16, data: &[u8]) -> Result<(), EscError> {
        let a = addr as usize;
        let end = a + data.len();
        if end > MEM {
            return Err(EscError::OutOfRange);
        }
        // The PDI cannot write the master's AL control or SM configuration.
        if a <= reg::AL_CONTROL.addr() as usize && (reg::AL_CONTROL.addr() as usize) < end {
            return Ok(());
        }
        self.m[a..end].copy_from_slice(data);
        let (s1, l1) = self.sm(1);
        if l1 > 0 && (a..end).contains(&((s1 + l1 - 1) as usize)) {
            self.m[(reg::sm_register(1) + 5) as usize] |= 0x08;
        }
        Ok(())
    }
}

// ---- fake application -----------------------------------------------------------

const fn var(
    index: u16,
    name: &'static str,
    t: DataType,
    pdo: PdoMappable,
    entries: &'static [EntryDesc],
) -> ObjectDesc {
    let _ = (t, pdo);
    ObjectDesc::var(index, name, entries, "")
}
const E_6040: &[EntryDesc] =
    &[EntryDesc::new(0, "cw", DataType::Unsigned16, Access::RW).pdo(PdoMappable::Rx)];
const E_6041: &[EntryDesc] =
    &[EntryDesc::new(0, "sw", DataType::Unsigned16, Access::RO).pdo(PdoMappable::Tx)];
const E_6060: &[EntryDesc] =
    &[EntryDesc::new(0, "mode", DataType::Integer8, Access::RW).pdo(PdoMappable::Rx)];
const E_6064: &[EntryDesc] =
    &[EntryDesc::new(0, "pos", DataType::Integer32, Access::RO).pdo(PdoMappable::Tx)];
const E_607A: &[EntryDesc] =
    &[EntryDesc::new(0, "target", DataType::Integer32, Access::RW).pdo(PdoMappable::Rx)];
const E_60FE: &[EntryDesc] = &[
    EntryDesc::new(0, "n", DataType::Unsigned8, Access::RO),
    EntryDesc::new(1, "outputs", DataType::Unsigned32, Access::RW).pdo(PdoMappable::Rx),
];
const E_2100: &[EntryDesc] =
    &[EntryDesc::new(0, "flag", DataType::Boolean, Access::RW).pdo(PdoMappable::RxTx)];
const E_2101: &[EntryDesc] = &[EntryDesc::new(
    0,
    "not mappable",
    DataType::Unsigned16,
    Access::RW,
)];
const E_2102: &[EntryDesc] =
    &[EntryDesc::new(0, "big", DataType::Unsigned64, Access::RW).pdo(PdoMappable::RxTx)];

static OBJECTS: &[Object] = ecat_slave_stack::packed_dictionary!(&[
    pdo::OBJECTS,
    LOCAL,
    &[sync::timing_diag_object(0x2200)]
]);
const LOCAL: &[ObjectDesc] = &[
    var(0x2100, "flag", DataType::Boolean, PdoMappable::RxTx, E_2100),
    var(0x2101, "nm", DataType::Unsigned16, PdoMappable::No, E_2101),
    var(
        0x2102,
        "big",
        DataType::Unsigned64,
        PdoMappable::RxTx,
        E_2102,
    ),
    var(0x6040, "cw", DataType::Unsigned16, PdoMappable::Rx, E_6040),
    var(0x6041, "sw", DataType::Unsigned16, PdoMappable::Tx, E_6041),
    var(0x6060, "mode", DataType::Integer8, PdoMappable::Rx, E_6060),
    var(0x6064, "pos", DataType::Integer32, PdoMappable::Tx, E_6064),
    var(
        0x607A,
        "target",
        DataType::Integer32,
        PdoMappable::Rx,
        E_607A,
    ),
    ObjectDesc::array(0x60FE, "outputs", E_60FE, ""),
];

const RX1: &[u32] = &[
    ObjectKey::new(0x6040, 0).mapping_word(16),
    ObjectKey::new(0x607A, 0).mapping_word(32),
];
const RX2: &[u32] = &[
    ObjectKey::new(0x6040, 0).mapping_word(16),
    ObjectKey::new(0x6060, 0).mapping_word(8),
    ObjectKey::new(0x2100, 0).mapping_word(1),
    ObjectKey::new(0, 0).mapping_word(7),
];
const TX1: &[u32] = &[
    ObjectKey::new(0x6041, 0).mapping_word(16),
    ObjectKey::new(0x6064, 0).mapping_word(32),
];
const DEFAULTS: PdoDefaults = PdoDefaults {
    rx: [RX1, RX2, &[], &[]],
    tx: [TX1, &[], &[], &[]],
    rx_assign: &[0x1600],
    tx_assign: &[0x1A00],
};

/// A firmware file "fw.bin" (Bootstrap only): counts the bytes, completions, aborts.
struct FwFile {
    bytes: u32,
    finished: u32,
    aborted: u32,
    open: bool,
}

impl FoeFiles for FwFile {
    fn open_write(&mut self, name: &[u8], _password: u32, in_boot: bool) -> Result<(), ErrorCode> {
        match name {
            b"fw.bin" if in_boot => {
                self.open = true;
                self.bytes = 0;
                Ok(())
            }
            b"fw.bin" => Err(ErrorCode::BootstrapOnly),
            _ => Err(ErrorCode::NotFound),
        }
    }
    fn write(&mut self, offset: u32, data: &[u8]) -> WriteStatus {
        assert_eq!(offset, self.bytes);
        self.bytes += data.len() as u32;
        WriteStatus::Done
    }
    fn finish_write(&mut self) -> Result<(), ErrorCode> {
        self.open = false;
        self.finished += 1;
        Ok(())
    }
    fn open_read(
        &mut self,
        _name: &[u8],
        _password: u32,
        _in_boot: bool,
    ) -> Result<u32, ErrorCode> {
        Err(ErrorCode::NotFound)
    }
    fn read(&mut self, _offset: u32, _buf: &mut [u8]) -> usize {
        0
    }
    fn abort(&mut self) {
        assert!(self.open);
        self.open = false;
        self.aborted += 1;
    }
}

// Slots: 0 cw, 1 target, 2 mode, 3 flag, 4 sw, 5 pos, 6 big, 7 outputs
struct App {
    v: [u64; 8],
    changes: [(EsmState, EsmState); 16],
    n_changes: usize,
    lost: Option<AlStatusCode>,
    cycles: u32,
    fresh_cycles: u32,
    refuse_tx: bool,
    local: Option<AlStatusCode>,
    /// FoE backend (None: the application serves no files).
    files: Option<FwFile>,
    /// Bootstrap hooks called: (entered, left).
    boot_hooks: (u32, u32),
}

impl App {
    fn new() -> Self {
        App {
            v: [0; 8],
            changes: [(EsmState::Init, EsmState::Init); 16],
            n_changes: 0,
            lost: None,
            cycles: 0,
            fresh_cycles: 0,
            refuse_tx: false,
            local: None,
            files: None,
            boot_hooks: (0, 0),
        }
    }
    fn last_change(&self) -> Option<(EsmState, EsmState)> {
        self.n_changes.checked_sub(1).map(|i| self.changes[i % 16])
    }
}

impl Dictionary for App {
    fn objects(&self) -> &'static [Object] {
        OBJECTS
    }
    fn read(&mut self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        let ObjectKey { index, .. } = key;
        if index == 0x6041 {
            buf[..2].copy_from_slice(&(self.v[4] as u16).to_le_bytes());
            return Ok(2);
        }
        Err(SdoAbort::ObjectDoesNotExist)
    }
    fn write(&mut self, _key: ObjectKey, _data: &[u8], _state: EsmState) -> Result<(), SdoAbort> {
        Err(SdoAbort::WriteReadOnly)
    }
}

impl ProcessData for App {
    fn rx_slot(&self, key: ObjectKey) -> Option<u16> {
        let ObjectKey { index, sub } = key;
        match (index, sub) {
            (0x6040, 0) => Some(0),
            (0x607A, 0) => Some(1),
            (0x6060, 0) => Some(2),
            (0x2100, 0) => Some(3),
            (0x2102, 0) => Some(6),
            (0x60FE, 1) => None,
            _ => None,
        }
    }
    fn tx_slot(&self, key: ObjectKey) -> Option<u16> {
        let ObjectKey { index, .. } = key;
        if self.refuse_tx {
            return None;
        }
        match index {
            0x6041 => Some(4),
            0x6064 => Some(5),
            0x2100 => Some(3),
            0x2102 => Some(6),
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
        self.changes[self.n_changes % 16] = (from, to);
        self.n_changes += 1;
    }
    fn on_enter_bootstrap(&mut self) {
        assert_eq!(
            self.last_change(),
            Some((EsmState::Init, EsmState::Bootstrap))
        );
        self.boot_hooks.0 += 1;
    }
    fn on_leave_bootstrap(&mut self) {
        assert_eq!(
            self.last_change(),
            Some((EsmState::Bootstrap, EsmState::Init))
        );
        self.boot_hooks.1 += 1;
    }
}

impl SlaveApplication for App {
    fn cycle(&mut self, info: &CycleInfo) {
        self.cycles += 1;
        if info.outputs_fresh {
            self.fresh_cycles += 1;
        }
        // Echo: statusword = controlword + 1, position = target.
        self.v[4] = (self.v[0] + 1) & 0xFFFF;
        self.v[5] = self.v[1];
    }
    fn on_outputs_lost(&mut self, code: AlStatusCode) {
        self.lost = Some(code);
    }
    fn local_error(&mut self) -> Option<AlStatusCode> {
        self.local
    }
    fn foe(&mut self) -> Option<&mut dyn FoeFiles> {
        self.files.as_mut().map(|f| f as &mut dyn FoeFiles)
    }
}

// ---- helpers ----------------------------------------------------------------------

fn cfg() -> SlaveConfig {
    SlaveConfig {
        station_alias: None,
        pdo_defaults: DEFAULTS,
        timing_diag_index: Some(0x2200),
        ..SlaveConfig::default()
    }
}

fn new_slave() -> (Slave<FakeEsc>, App) {
    let mut s = Slave::new(FakeEsc::new(), cfg());
    s.init().unwrap();
    (s, App::new())
}

/// Bootstrap mailbox: SM0 at 0x1000, SM1 at 0x1100, 192 bytes each.
const BOOT: BootMailbox = BootMailbox {
    rx_start: 0x1000,
    rx_len: 192,
    tx_start: 0x1100,
    tx_len: 192,
};

/// A slave with Bootstrap support and an application with the firmware file.
fn new_boot_slave() -> (Slave<FakeEsc>, App) {
    let mut s = Slave::new(
        FakeEsc::new(),
        SlaveConfig {
            bootstrap: Some(BOOT),
            ..cfg()
        },
    );
    s.init().unwrap();
    let mut app = App::new();
    app.files = Some(FwFile {
        bytes: 0,
        finished: 0,
        aborted: 0,
        open: false,
    });
    (s, app)
}

fn boot_mailbox(esc: &mut FakeEsc) {
    esc.write_sm(0, BOOT.rx_start, BOOT.rx_len, 0x26, true);
    esc.write_sm(1, BOOT.tx_start, BOOT.tx_len, 0x22, true);
}

fn to_boot(s: &mut Slave<FakeEsc>, app: &mut App) {
    boot_mailbox(s.esc_mut());
    assert_eq!(request(s, app, 3, 0), (0x03, 0));
}

/// Writes one mailbox request of type `t` (SM0 of `size` bytes) with `counter`,
/// polls, and returns the answer read from SM1 (None if there is none).
fn mailbox_exchange(
    s: &mut Slave<FakeEsc>,
    app: &mut App,
    size: usize,
    t: u8,
    counter: u8,
    payload: &[u8],
    now: u64,
) -> Option<([u8; 256], usize)> {
    let (sm0, _) = s.esc_mut().sm(0);
    let mut req = [0u8; 256];
    req[..2].copy_from_slice(&(payload.len() as u16).to_le_bytes());
    req[5] = t | (counter << 4);
    req[6..6 + payload.len()].copy_from_slice(payload);
    s.esc_mut().ecat_write(sm0, &req[..size]);
    s.poll(app, now).unwrap();
    let mut out = [0u8; 256];
    if !s.esc_mut().read_sm1(&mut out[..size]) {
        return None;
    }
    let len = 6 + u16::from_le_bytes([out[0], out[1]]) as usize;
    Some((out, len))
}

fn standard_mailbox(esc: &mut FakeEsc) {
    esc.write_sm(0, 0x1000, 128, 0x26, true);
    esc.write_sm(1, 0x1080, 128, 0x22, true);
}

fn request(s: &mut Slave<FakeEsc>, app: &mut App, ctl: u16, now: u64) -> (u16, u16) {
    s.esc_mut().al_control(ctl);
    s.poll(app, now).unwrap();
    s.esc_mut().al_status()
}

fn to_preop(s: &mut Slave<FakeEsc>, app: &mut App) {
    standard_mailbox(s.esc_mut());
    assert_eq!(request(s, app, 2, 0), (0x02, 0));
}

/// SM2/SM3 for the default maps (6 bytes each), watchdog 100 ms.
fn pd_sms(esc: &mut FakeEsc, rx: u16, tx: u16) {
    esc.write_sm(2, 0x1100, rx, 0x64, rx > 0);
    esc.write_sm(3, 0x1400, tx, 0x20, tx > 0);
    esc.ecat_write(reg::WATCHDOG_DIVIDER.addr(), &2498u16.to_le_bytes());
    esc.ecat_write(reg::WATCHDOG_TIME_PD.addr(), &1000u16.to_le_bytes());
}

fn to_safeop(s: &mut Slave<FakeEsc>, app: &mut App) {
    to_preop(s, app);
    pd_sms(s.esc_mut(), 6, 6);
    assert_eq!(request(s, app, 4, 0), (0x04, 0));
}

fn to_op(s: &mut Slave<FakeEsc>, app: &mut App) {
    to_safeop(s, app);
    assert_eq!(request(s, app, 8, 0), (0x08, 0));
}

fn sdo_write(
    s: &mut Slave<FakeEsc>,
    app: &mut App,
    index: u16,
    sub: u8,
    data: &[u8],
) -> Result<(), SdoAbort> {
    let state = s.state();
    s.dictionary(app)
        .write(ObjectKey::new(index, sub), data, state)
}

fn sdo_read_u32(s: &mut Slave<FakeEsc>, app: &mut App, index: u16, sub: u8) -> u32 {
    let mut b = [0u8; 8];
    let n = s
        .dictionary(app)
        .read(ObjectKey::new(index, sub), &mut b)
        .unwrap();
    let mut w = [0u8; 4];
    w[..n.min(4)].copy_from_slice(&b[..n.min(4)]);
    u32::from_le_bytes(w)
}

/// DC SYNC0 active with `cycle_ns`.
fn dc_on(esc: &mut FakeEsc, activation: u8, cycle_ns: u32) {
    esc.ecat_write(reg::DC_ACTIVATION.addr(), &[activation]);
    esc.ecat_write(reg::DC_SYNC0_CYCLE.addr(), &cycle_ns.to_le_bytes());
}

fn sync0(s: &mut Slave<FakeEsc>, app: &mut App, now: u64, with_outputs: bool) {
    if with_outputs {
        let (st, len) = s.esc_mut().sm(2);
        let data = [0x11u8; 6];
        s.esc_mut().ecat_write(st, &data[..len as usize]);
    }
    s.esc_mut().set_event(1 << 2, true);
    s.poll(app, now).unwrap();
}

/// (start, length, control, enable) of one SyncManager.
type SmCfg = (u16, u16, u8, bool);

fn lcg(x: &mut u32) -> u32 {
    *x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
    *x >> 8
}

qemu_runner::tests! {
    fn test_dictionary_is_well_formed() {
        assert!(ecat_slave_stack::od::is_well_formed(OBJECTS));
        assert_eq!(pdo::OBJECTS.len(), 13);
    }

    fn transition_table_matches_the_standard() {
        use EsmState::*;
        let states = [Init, PreOp, Bootstrap, SafeOp, Op];
        let allowed = [
            (Init, PreOp), (PreOp, Init), (PreOp, SafeOp), (SafeOp, Init), (SafeOp, PreOp),
            (SafeOp, Op), (Op, Init), (Op, PreOp), (Op, SafeOp), (Bootstrap, Init),
        ];
        for from in states {
            for to in states {
                let d = esm::decide(from, false, to.bits() as u16);
                let expect = if from == to {
                    Decision::None
                } else if allowed.contains(&(from, to)) {
                    Decision::Transition { from, to }
                } else {
                    let code = if (from, to) == (Init, Bootstrap) {
                        AlStatusCode::BootstrapNotSupported
                    } else {
                        AlStatusCode::InvalidStateChange
                    };
                    let state = match from {
                        Op => SafeOp,
                        Bootstrap => Init,
                        s => s,
                    };
                    Decision::Refuse { code, state }
                };
                assert_eq!(d, expect, "{:?} → {:?}", from, to);
                // With an error pending: ignored unless acknowledged or Init.
                let d = esm::decide(from, true, to.bits() as u16);
                if to == Init {
                    assert_eq!(d, esm::decide(from, false, 1));
                } else {
                    assert_eq!(d, Decision::None);
                }
                assert_eq!(esm::decide(from, true, to.bits() as u16 | 0x10), expect);
            }
        }
    }

    fn oversized_default_maps_are_refused_at_preop_to_safeop() {
        const BIG: &[u32] = &[
            ObjectKey::new(0x2102, 0).mapping_word(64), ObjectKey::new(0x2102, 0).mapping_word(64), ObjectKey::new(0x2102, 0).mapping_word(64), ObjectKey::new(0x2102, 0).mapping_word(64),
            ObjectKey::new(0x2102, 0).mapping_word(64), ObjectKey::new(0x2102, 0).mapping_word(64), ObjectKey::new(0x2102, 0).mapping_word(64), ObjectKey::new(0x2102, 0).mapping_word(64),
            ObjectKey::new(0x2100, 0).mapping_word(1),
        ];
        for (rx, tx, code) in [(BIG, TX1, 0x0025u16), (RX1, BIG, 0x0024)] {
            let d = PdoDefaults { rx: [rx, &[], &[], &[]], tx: [tx, &[], &[], &[]], ..DEFAULTS };
            let mut s = Slave::new(FakeEsc::new(), SlaveConfig { pdo_defaults: d, ..cfg() });
            s.init().unwrap();
            let mut app = App::new();
            to_preop(&mut s, &mut app);
            pd_sms(s.esc_mut(), 6, 6);
            assert_eq!(request(&mut s, &mut app, 4, 0), (0x12, code));
        }
    }

    fn input_only_device_cycles_on_the_sm3_event() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        sdo_write(&mut s, &mut app, 0x1C12, 0, &[0]).unwrap();
        pd_sms(s.esc_mut(), 0, 6);
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x04, 0));
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C33, 1), 1);
        assert_eq!(request(&mut s, &mut app, 8, 0), (0x08, 0));
        let c = app.cycles;
        s.poll(&mut app, 10).unwrap();
        assert_eq!(app.cycles, c);
        s.esc_mut().set_event(1 << 11, true);
        s.poll(&mut app, 20).unwrap();
        assert_eq!(app.cycles, c + 1);
        // Enabling SM2 with data while nothing is mapped is refused.
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        sdo_write(&mut s, &mut app, 0x1C12, 0, &[0]).unwrap();
        pd_sms(s.esc_mut(), 6, 6);
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x12, 0x001D));
    }

    fn sync0_interrupt_entry_runs_the_cycle() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        pd_sms(s.esc_mut(), 6, 6);
        dc_on(s.esc_mut(), 3, 500_000);
        request(&mut s, &mut app, 4, 0);
        request(&mut s, &mut app, 8, 0);
        let mut t = 0;
        for _ in 0..8 {
            t += 500;
            s.esc_mut().ecat_write(0x1100, &[3, 0, 9, 0, 0, 0]);
            s.cycle(&mut app, t).unwrap();
            s.poll(&mut app, t + 1).unwrap();
        }
        assert_eq!(s.esc_mut().al_status(), (0x08, 0));
        assert_eq!(app.v[1], 9);
        assert_eq!(&s.esc_mut().m[0x1400..0x1402], &[4, 0]);
        // cycle() outside Safe-Op/Op does nothing.
        request(&mut s, &mut app, 2, t + 2);
        let c = app.cycles;
        s.cycle(&mut app, t + 3).unwrap();
        assert_eq!(app.cycles, c);
    }

    fn pending_safeop_to_op_can_be_cancelled() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        pd_sms(s.esc_mut(), 6, 6);
        dc_on(s.esc_mut(), 3, 1_000_000);
        request(&mut s, &mut app, 4, 0);
        assert_eq!(request(&mut s, &mut app, 8, 0), (0x04, 0));
        assert_eq!(s.esm().pending(), Some(EsmState::Op));
        // Asking for Op again keeps the original deadline.
        assert_eq!(request(&mut s, &mut app, 8, 600_000), (0x04, 0));
        assert_eq!(request(&mut s, &mut app, 4, 700_000), (0x04, 0));
        assert_eq!(s.esm().pending(), None);
        s.poll(&mut app, 2_000_000).unwrap();
        assert_eq!(s.esc_mut().al_status(), (0x04, 0));
    }

    fn local_error_refuses_op_and_takes_the_slave_out_of_op() {
        let (mut s, mut app) = new_slave();
        to_safeop(&mut s, &mut app);
        app.local = Some(AlStatusCode::SupplyVoltageTooLow);
        assert_eq!(request(&mut s, &mut app, 8, 0), (0x14, 0x0080));
        app.local = None;
        assert_eq!(request(&mut s, &mut app, 0x18, 0), (0x08, 0));
        app.local = Some(AlStatusCode::ExternalHardwareNotReady);
        s.poll(&mut app, 10).unwrap();
        assert_eq!(s.esc_mut().al_status(), (0x14, 0x0052));
        assert_eq!(app.last_change(), Some((EsmState::Op, EsmState::SafeOp)));
    }

    fn device_id_is_not_loaded_while_an_error_is_pending() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        assert_eq!(request(&mut s, &mut app, 8, 0), (0x12, 0x0011));
        assert_eq!(request(&mut s, &mut app, 0x22, 0), (0x12, 0x0011));
        assert_eq!(request(&mut s, &mut app, 0x32, 0), (0x22, 0x1234));
    }

    fn init_reports_init_and_sets_event_mask() {
        let mut s = Slave::new(FakeEsc::new(), SlaveConfig { station_alias: Some(0x0042), ..cfg() });
        let info = s.init().unwrap();
        assert_eq!(info.ram_kib, 4);
        let esc = s.esc_mut();
        assert_eq!(esc.al_status(), (0x01, 0));
        assert_eq!(esc.u16(reg::STATION_ALIAS.addr()), 0x0042);
        assert_ne!(esc.u16(reg::AL_EVENT_MASK.addr()) & 0x11, 0);
    }

    fn init_to_preop_and_back() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        assert_eq!(app.last_change(), Some((EsmState::Init, EsmState::PreOp)));
        assert_eq!(request(&mut s, &mut app, 1, 0), (0x01, 0));
        assert_eq!(app.last_change(), Some((EsmState::PreOp, EsmState::Init)));
    }

    fn every_invalid_mailbox_config_gives_0x0016_in_init() {
        // (SM0 start, len, control, enable), (SM1 ...)
        let cases: &[(SmCfg, SmCfg)] = &[
            ((0x1000, 14, 0x26, true), (0x1080, 128, 0x22, true)),   // SM0 too short
            ((0x1000, 258, 0x26, true), (0x1200, 128, 0x22, true)),  // SM0 too long
            ((0x1000, 128, 0x26, true), (0x1080, 14, 0x22, true)),   // SM1 too short
            ((0x1000, 128, 0x26, true), (0x1080, 258, 0x22, true)),  // SM1 too long
            ((0x1001, 128, 0x26, true), (0x1100, 128, 0x22, true)),  // odd SM0 start
            ((0x1000, 128, 0x26, true), (0x1081, 128, 0x22, true)),  // odd SM1 start
            ((0x1000, 128, 0x26, true), (0x1040, 128, 0x22, true)),  // overlap
            ((0x1000, 128, 0x22, true), (0x1080, 128, 0x22, true)),  // SM0 wrong direction
            ((0x1000, 128, 0x26, true), (0x1080, 128, 0x20, true)),  // SM1 buffered mode
            ((0x1000, 128, 0x06, true), (0x1080, 128, 0x22, true)),  // no AL event IRQ
            ((0x1000, 128, 0x26, false), (0x1080, 128, 0x22, true)), // SM0 disabled
            ((0x1000, 128, 0x26, true), (0x1080, 128, 0x22, false)), // SM1 disabled
            ((0x0F00, 128, 0x26, true), (0x1080, 128, 0x22, true)),  // below process RAM
            ((0x1000, 128, 0x26, true), (0x1FC0, 128, 0x22, true)),  // past the end of RAM
        ];
        for (a, b) in cases {
            let (mut s, mut app) = new_slave();
            s.esc_mut().write_sm(0, a.0, a.1, a.2, a.3);
            s.esc_mut().write_sm(1, b.0, b.1, b.2, b.3);
            assert_eq!(request(&mut s, &mut app, 2, 0), (0x11, 0x0016), "{:?} {:?}", a, b);
            assert_eq!(app.n_changes, 0);
        }
        // Overlap with a process-data SM the master already configured.
        let (mut s, mut app) = new_slave();
        standard_mailbox(s.esc_mut());
        s.esc_mut().write_sm(2, 0x1060, 8, 0x64, false);
        assert_eq!(request(&mut s, &mut app, 2, 0), (0x11, 0x0016));
    }

    fn refused_transitions_keep_the_state_with_0x0011() {
        let (mut s, mut app) = new_slave();
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x11, 0x0011)); // I→S
        assert_eq!(request(&mut s, &mut app, 0x18, 0), (0x11, 0x0011)); // I→O (with ack)
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        assert_eq!(request(&mut s, &mut app, 8, 0), (0x12, 0x0011)); // P→O
        assert_eq!(request(&mut s, &mut app, 0x13, 0), (0x12, 0x0011)); // P→B
        let (mut s, mut app) = new_slave();
        to_safeop(&mut s, &mut app);
        assert_eq!(request(&mut s, &mut app, 3, 0), (0x14, 0x0011)); // S→B
        let (mut s, mut app) = new_slave();
        to_op(&mut s, &mut app);
        assert_eq!(request(&mut s, &mut app, 3, 0), (0x14, 0x0011)); // O→B falls to Safe-Op
        assert_eq!(app.last_change(), Some((EsmState::Op, EsmState::SafeOp)));
    }

    fn unknown_state_gives_0x0012_and_op_falls_to_safeop() {
        for bits in [0u16, 5, 6, 7, 9, 0x0A, 0x0B, 0x0C, 0x0D, 0x0E, 0x0F] {
            let (mut s, mut app) = new_slave();
            assert_eq!(request(&mut s, &mut app, bits, 0), (0x11, 0x0012));
            let (mut s, mut app) = new_slave();
            to_preop(&mut s, &mut app);
            assert_eq!(request(&mut s, &mut app, bits, 0), (0x12, 0x0012));
            let (mut s, mut app) = new_slave();
            to_op(&mut s, &mut app);
            assert_eq!(request(&mut s, &mut app, bits, 0), (0x14, 0x0012));
        }
    }

    fn bootstrap_is_refused_with_0x0013() {
        let (mut s, mut app) = new_slave();
        assert_eq!(request(&mut s, &mut app, 3, 0), (0x11, 0x0013));
        standard_mailbox(s.esc_mut());
        // Error pending: a request without acknowledge is ignored …
        assert_eq!(request(&mut s, &mut app, 2, 0), (0x11, 0x0013));
        // … with acknowledge it is carried out and the code cleared.
        assert_eq!(request(&mut s, &mut app, 0x12, 0), (0x02, 0));
    }

    fn bootstrap_transition_table() {
        use EsmState::*;
        let states = [Init, PreOp, Bootstrap, SafeOp, Op];
        for from in states {
            for to in states {
                let with = esm::decide_with(from, false, to.bits() as u16, true);
                let without = esm::decide(from, false, to.bits() as u16);
                match (from, to) {
                    (Init, Bootstrap) => {
                        assert_eq!(with, Decision::Transition { from, to });
                        assert_eq!(without, Decision::Refuse {
                            code: AlStatusCode::BootstrapNotSupported,
                            state: Init,
                        });
                    }
                    (Bootstrap, Init) => assert_eq!(with, Decision::Transition { from, to }),
                    (Bootstrap, Bootstrap) => assert_eq!(with, Decision::None),
                    // Every other way out of Boot: 0x0011, staying in Boot.
                    (Bootstrap, _) => assert_eq!(with, Decision::Refuse {
                        code: AlStatusCode::InvalidStateChange,
                        state: Bootstrap,
                    }),
                    (_, Bootstrap) => {
                        assert_eq!(with, without);
                        assert!(matches!(with, Decision::Refuse {
                            code: AlStatusCode::InvalidStateChange, ..
                        }));
                    }
                    _ => assert_eq!(with, without),
                }
            }
        }
        assert!(!esm::Esm::new().bootstrap_supported());
        assert!(esm::Esm::with_bootstrap(true).bootstrap_supported());
    }

    fn bootstrap_disabled_still_answers_0x0013() {
        // The default configuration, even with the boot mailbox configured by the master.
        let (mut s, mut app) = new_slave();
        boot_mailbox(s.esc_mut());
        assert_eq!(request(&mut s, &mut app, 3, 0), (0x11, 0x0013));
        assert_eq!(app.n_changes, 0);
        assert_eq!(app.boot_hooks, (0, 0));
    }

    fn init_to_boot_with_the_boot_mailbox_and_back() {
        let (mut s, mut app) = new_boot_slave();
        to_boot(&mut s, &mut app);
        assert_eq!(app.last_change(), Some((EsmState::Init, EsmState::Bootstrap)));
        assert_eq!(app.boot_hooks, (1, 0));
        // Mailbox events on, no process data.
        let mask = s.esc_mut().u16(reg::AL_EVENT_MASK.addr()) as u32;
        assert_ne!(mask & (1 << 8), 0);
        assert_eq!(mask & (1 << 10), 0);
        // RUN flickers (50 ms on / 50 ms off), ERR off.
        let mut leds = StatusLeds::new();
        let (st, code) = s.esc_mut().al_status();
        leds.update(s.state(), ErrCondition::from_al_status(st, code), 0);
        assert_eq!(leds.run.pattern(), Pattern::Flickering);
        assert_eq!(leds.err.pattern(), Pattern::Off);
        assert_eq!(leds.levels(10), (true, false));
        assert_eq!(leds.levels(60), (false, false));
        assert_eq!(leds.levels(110), (true, false));
        // Boot → Init.
        assert_eq!(request(&mut s, &mut app, 1, 0), (0x01, 0));
        assert_eq!(app.last_change(), Some((EsmState::Bootstrap, EsmState::Init)));
        assert_eq!(app.boot_hooks, (1, 1));
        // And again, then the normal way up still works.
        to_boot(&mut s, &mut app);
        assert_eq!(request(&mut s, &mut app, 1, 0), (0x01, 0));
        assert_eq!(app.boot_hooks, (2, 2));
        to_preop(&mut s, &mut app);
        assert_eq!(app.boot_hooks, (2, 2));
    }

    fn init_to_boot_with_a_wrong_mailbox_gives_0x0015() {
        let cases: &[(SmCfg, SmCfg)] = &[
            ((0x1000, 128, 0x26, true), (0x1080, 128, 0x22, true)),  // the standard mailbox
            ((0x1000, 192, 0x26, true), (0x1100, 190, 0x22, true)),  // SM1 length
            ((0x1002, 192, 0x26, true), (0x1100, 192, 0x22, true)),  // SM0 start
            ((0x1000, 192, 0x26, true), (0x1100, 192, 0x22, false)), // SM1 disabled
            ((0x1000, 192, 0x22, true), (0x1100, 192, 0x22, true)),  // SM0 direction
            ((0x1000, 192, 0x26, true), (0x1100, 192, 0x20, true)),  // SM1 buffered
        ];
        for (a, b) in cases {
            let (mut s, mut app) = new_boot_slave();
            s.esc_mut().write_sm(0, a.0, a.1, a.2, a.3);
            s.esc_mut().write_sm(1, b.0, b.1, b.2, b.3);
            assert_eq!(request(&mut s, &mut app, 3, 0), (0x11, 0x0015), "{:?} {:?}", a, b);
            assert_eq!(app.n_changes, 0);
            assert_eq!(app.boot_hooks, (0, 0));
            // Acknowledge, fix the configuration, enter Boot.
            boot_mailbox(s.esc_mut());
            assert_eq!(request(&mut s, &mut app, 0x13, 0), (0x03, 0));
        }
    }

    fn other_transitions_into_and_out_of_boot_give_0x0011() {
        let (mut s, mut app) = new_boot_slave();
        to_preop(&mut s, &mut app);
        assert_eq!(request(&mut s, &mut app, 3, 0), (0x12, 0x0011)); // P→B
        let (mut s, mut app) = new_boot_slave();
        to_safeop(&mut s, &mut app);
        assert_eq!(request(&mut s, &mut app, 3, 0), (0x14, 0x0011)); // S→B
        let (mut s, mut app) = new_boot_slave();
        to_op(&mut s, &mut app);
        assert_eq!(request(&mut s, &mut app, 3, 0), (0x14, 0x0011)); // O→B falls to Safe-Op
        for ctl in [2u16, 4, 8] {
            let (mut s, mut app) = new_boot_slave();
            to_boot(&mut s, &mut app);
            pd_sms(s.esc_mut(), 6, 6);
            let n = app.n_changes;
            // B→P/S/O: refused, Boot + ERR.
            assert_eq!(request(&mut s, &mut app, ctl, 0), (0x13, 0x0011), "B → {ctl}");
            assert_eq!(app.n_changes, n);
            // Ignored without acknowledge; acknowledged in Boot.
            assert_eq!(request(&mut s, &mut app, ctl, 0), (0x13, 0x0011));
            assert_eq!(request(&mut s, &mut app, 0x13, 0), (0x03, 0));
            // With acknowledge still refused.
            assert_eq!(request(&mut s, &mut app, ctl | 0x10, 0), (0x13, 0x0011));
            // Init is an implicit acknowledge.
            assert_eq!(request(&mut s, &mut app, 1, 0), (0x01, 0));
            assert_eq!(app.boot_hooks, (1, 1));
        }
    }

    fn firmware_download_over_foe_in_boot() {
        let (mut s, mut app) = new_boot_slave();
        to_boot(&mut s, &mut app);
        let seg = 192 - 12;
        // CoE in Boot: mailbox error "protocol not supported".
        let sdo = [0x00, 0x20, 0x40, 0x12, 0x1C, 0x01, 0, 0, 0, 0];
        let (out, len) = mailbox_exchange(&mut s, &mut app, 192, 3, 1, &sdo, 0).unwrap();
        assert_eq!(&out[5..len], &[0x10, 0x01, 0x00, 0x02, 0x00]);
        // WRQ "fw.bin" → ACK 0.
        let mut wrq = [0u8; 12];
        wrq[0] = 2;
        wrq[6..].copy_from_slice(b"fw.bin");
        let (out, len) = mailbox_exchange(&mut s, &mut app, 192, 4, 2, &wrq, 0).unwrap();
        assert_eq!(out[5] & 0x0F, 4);
        assert_eq!(&out[6..len], &[4, 0, 0, 0, 0, 0]);
        // Two whole segments and a short one.
        let mut cnt = 2;
        for (packet, n) in [(1u32, seg), (2, seg), (3, 10)] {
            cnt = cnt % 7 + 1;
            let mut d = [0u8; 256];
            d[0] = 3;
            d[2..6].copy_from_slice(&packet.to_le_bytes());
            let (out, len) = mailbox_exchange(&mut s, &mut app, 192, 4, cnt, &d[..6 + n], 0).unwrap();
            assert_eq!(&out[6..len], &[4, 0, packet as u8, 0, 0, 0]);
        }
        let f = app.files.as_ref().unwrap();
        assert_eq!((f.bytes, f.finished, f.aborted), (2 * seg as u32 + 10, 1, 0));
        // A transfer left open is aborted when the master goes back to Init.
        let (out, len) = mailbox_exchange(&mut s, &mut app, 192, 4, cnt % 7 + 1, &wrq, 0).unwrap();
        assert_eq!(&out[6..len], &[4, 0, 0, 0, 0, 0]);
        assert_eq!(request(&mut s, &mut app, 1, 0), (0x01, 0));
        assert_eq!(app.files.as_ref().unwrap().aborted, 1);
        assert_eq!(app.boot_hooks, (1, 1));
    }

    fn foe_outside_boot_and_its_timeout() {
        let (mut s, mut app) = new_boot_slave();
        to_preop(&mut s, &mut app);
        let mut wrq = [0u8; 12];
        wrq[0] = 2;
        wrq[6..].copy_from_slice(b"fw.bin");
        // The firmware file is Bootstrap only: 0x8008.
        let (out, len) = mailbox_exchange(&mut s, &mut app, 128, 4, 1, &wrq, 0).unwrap();
        assert_eq!(&out[6..len], &[5, 0, 0x08, 0x80, 0, 0]);
        // In Boot: a stalled transfer is aborted after 10 s without a request.
        let (mut s, mut app) = new_boot_slave();
        to_boot(&mut s, &mut app);
        mailbox_exchange(&mut s, &mut app, 192, 4, 1, &wrq, 1_000).unwrap();
        s.poll(&mut app, 1_000 + 10_000_000).unwrap();
        assert_eq!(app.files.as_ref().unwrap().aborted, 0);
        s.poll(&mut app, 1_001 + 10_000_000).unwrap();
        assert_eq!(app.files.as_ref().unwrap().aborted, 1);
        let d = [3u8, 0, 1, 0, 0, 0];
        let (out, len) = mailbox_exchange(&mut s, &mut app, 192, 4, 2, &d, 10_002_000).unwrap();
        assert_eq!(&out[6..len], &[5, 0, 0x04, 0x80, 0, 0]);
    }

    fn foe_without_files_answers_unsupported_protocol() {
        // An application without FoE, in Pre-Op and (with Bootstrap on) in Boot.
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        let wrq = [2u8, 0, 0, 0, 0, 0, b'x'];
        let (out, len) = mailbox_exchange(&mut s, &mut app, 128, 4, 1, &wrq, 0).unwrap();
        assert_eq!(&out[5..len], &[0x10, 0x01, 0x00, 0x02, 0x00]);
        let (mut s, mut app) = new_boot_slave();
        app.files = None;
        to_boot(&mut s, &mut app);
        let (out, len) = mailbox_exchange(&mut s, &mut app, 192, 4, 1, &wrq, 0).unwrap();
        assert_eq!(&out[5..len], &[0x10, 0x01, 0x00, 0x02, 0x00]);
        // Emergencies are not sent in Boot.
        s.emergency(0x1234, 1, [0; 5]);
        s.poll(&mut app, 10).unwrap();
        let mut o = [0u8; 192];
        assert!(!s.esc_mut().read_sm1(&mut o));
    }

    fn init_request_is_an_implicit_acknowledge() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        assert_eq!(request(&mut s, &mut app, 8, 0), (0x12, 0x0011));
        assert_eq!(request(&mut s, &mut app, 1, 0), (0x01, 0));
        // Acknowledge without a state change clears the indication only.
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        assert_eq!(request(&mut s, &mut app, 8, 0), (0x12, 0x0011));
        assert_eq!(request(&mut s, &mut app, 0x12, 0), (0x02, 0));
    }

    fn every_allowed_transition_works() {
        use EsmState::*;
        // (path up to the start state, request, expected state)
        let cases: &[(EsmState, u16, EsmState)] = &[
            (PreOp, 1, Init), (PreOp, 4, SafeOp),
            (SafeOp, 1, Init), (SafeOp, 2, PreOp), (SafeOp, 8, Op),
            (Op, 1, Init), (Op, 2, PreOp), (Op, 4, SafeOp),
            (PreOp, 2, PreOp), (SafeOp, 4, SafeOp), (Op, 8, Op), (Init, 1, Init),
        ];
        for (start, ctl, end) in cases {
            let (mut s, mut app) = new_slave();
            match start {
                PreOp => {
                    to_preop(&mut s, &mut app);
                    pd_sms(s.esc_mut(), 6, 6);
                }
                SafeOp => to_safeop(&mut s, &mut app),
                Op => to_op(&mut s, &mut app),
                _ => {}
            }
            let n = app.n_changes;
            let (st, code) = request(&mut s, &mut app, *ctl, 0);
            assert_eq!((st, code), (end.bits() as u16, 0), "{:?} → {}", start, ctl);
            if start != end {
                assert_eq!(app.last_change(), Some((*start, *end)));
                assert_eq!(app.n_changes, n + 1);
            } else {
                assert_eq!(app.n_changes, n);
            }
        }
    }

    fn device_id_request_loads_the_id() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        assert_eq!(request(&mut s, &mut app, 0x22, 0), (0x22, 0x1234));
        assert_eq!(request(&mut s, &mut app, 0x02, 0), (0x02, 0));
    }

    fn process_data_flows_only_in_op() {
        let (mut s, mut app) = new_slave();
        to_safeop(&mut s, &mut app);
        // Outputs: controlword 0x000F, target 0x12345678.
        let out = [0x0F, 0x00, 0x78, 0x56, 0x34, 0x12];
        s.esc_mut().ecat_write(0x1100, &out);
        s.poll(&mut app, 1000).unwrap();
        assert_eq!(app.v[0], 0, "Safe-Op must not apply outputs");
        assert_eq!(app.cycles, 1);
        assert_eq!(request(&mut s, &mut app, 8, 2000), (0x08, 0));
        s.esc_mut().ecat_write(0x1100, &out);
        s.poll(&mut app, 3000).unwrap();
        assert_eq!(app.v[0], 0x0F);
        assert_eq!(app.v[1], 0x1234_5678);
        assert_eq!(app.fresh_cycles, 1);
        let m = &s.esc_mut().m;
        assert_eq!(&m[0x1400..0x1406], &[0x10, 0x00, 0x78, 0x56, 0x34, 0x12]);
        // No new SM2 event: no cycle in SM-synchronous mode.
        s.poll(&mut app, 4000).unwrap();
        assert_eq!(app.cycles, 2);
    }

    fn sm2_and_sm3_checks_give_0x001d_0x001e_in_preop() {
        // (SM2 len, SM2 control, SM2 enable, SM3 len, SM3 control, SM3 enable, code)
        let cases: &[(u16, u8, bool, u16, u8, bool, u16)] = &[
            (5, 0x64, true, 6, 0x20, true, 0x001D),  // length ≠ mapping
            (6, 0x66, true, 6, 0x20, true, 0x001D),  // mailbox mode
            (6, 0x60, true, 6, 0x20, true, 0x001D),  // wrong direction
            (6, 0x44, true, 6, 0x20, true, 0x001D),  // no AL event interrupt
            (6, 0x64, false, 6, 0x20, true, 0x001D), // disabled
            (6, 0x64, true, 7, 0x20, true, 0x001E),
            (6, 0x64, true, 6, 0x24, true, 0x001E),
            (6, 0x64, true, 6, 0x22, true, 0x001E),
            (6, 0x64, true, 6, 0x20, false, 0x001E),
        ];
        for c in cases {
            let (mut s, mut app) = new_slave();
            to_preop(&mut s, &mut app);
            pd_sms(s.esc_mut(), 6, 6);
            s.esc_mut().write_sm(2, 0x1100, c.0, c.1, c.2);
            s.esc_mut().write_sm(3, 0x1400, c.3, c.4, c.5);
            assert_eq!(request(&mut s, &mut app, 4, 0), (0x12, c.6), "{:?}", c);
        }
        // Overlap of SM2 (3 × 6 bytes) with SM3: SM2 is checked first.
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        pd_sms(s.esc_mut(), 6, 6);
        s.esc_mut().write_sm(3, 0x110C, 6, 0x20, true);
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x12, 0x001D));
        // SM3 overlapping the mailbox.
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        pd_sms(s.esc_mut(), 6, 6);
        s.esc_mut().write_sm(3, 0x1060, 6, 0x20, true);
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x12, 0x001E));
        // SM3 three buffers past the end of process RAM.
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        pd_sms(s.esc_mut(), 6, 6);
        s.esc_mut().write_sm(3, 0x1FF0, 6, 0x20, true);
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x12, 0x001E));
        // SM2 overlapping the mailbox.
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        pd_sms(s.esc_mut(), 6, 6);
        s.esc_mut().write_sm(2, 0x1070, 6, 0x64, true);
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x12, 0x001D));
    }

    fn watchdog_configuration_gives_0x001f() {
        // Watchdog enabled but SM2 without trigger bit.
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        pd_sms(s.esc_mut(), 6, 6);
        s.esc_mut().write_sm(2, 0x1100, 6, 0x24, true);
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x12, 0x001F));
        // Watchdog 1 ms with a 1 ms DC cycle (< 2 × cycle).
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        pd_sms(s.esc_mut(), 6, 6);
        s.esc_mut().ecat_write(reg::WATCHDOG_TIME_PD.addr(), &10u16.to_le_bytes());
        dc_on(s.esc_mut(), 3, 1_000_000);
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x12, 0x001F));
        // Watchdog time exactly 2 × cycle is fine.
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        pd_sms(s.esc_mut(), 6, 6);
        s.esc_mut().ecat_write(reg::WATCHDOG_TIME_PD.addr(), &20u16.to_le_bytes());
        dc_on(s.esc_mut(), 3, 1_000_000);
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x04, 0));
    }

    fn invalid_mappings_give_0x0025_and_0x0024() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        // Map an entry the application has no slot for: 0x60FE:01 (mappable, no slot).
        sdo_write(&mut s, &mut app, 0x1C12, 0, &[0]).unwrap();
        sdo_write(&mut s, &mut app, 0x1602, 0, &[0]).unwrap();
        sdo_write(&mut s, &mut app, 0x1602, 1, &ObjectKey::new(0x60FE, 1).mapping_word(32).to_le_bytes()).unwrap();
        sdo_write(&mut s, &mut app, 0x1602, 0, &[1]).unwrap();
        sdo_write(&mut s, &mut app, 0x1C12, 1, &0x1602u16.to_le_bytes()).unwrap();
        sdo_write(&mut s, &mut app, 0x1C12, 0, &[1]).unwrap();
        pd_sms(s.esc_mut(), 4, 6);
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x12, 0x0025));
        // Inputs the application refuses.
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        app.refuse_tx = true;
        pd_sms(s.esc_mut(), 6, 6);
        assert_eq!(request(&mut s, &mut app, 0x14, 0), (0x12, 0x0024));
    }

    fn sync_configuration_errors() {
        // 0x0030: DC activation other than off / SYNC0.
        for act in [0x01u8, 0x02, 0x05, 0x07] {
            let (mut s, mut app) = new_slave();
            to_preop(&mut s, &mut app);
            pd_sms(s.esc_mut(), 6, 6);
            dc_on(s.esc_mut(), act, 1_000_000);
            assert_eq!(request(&mut s, &mut app, 4, 0), (0x12, 0x0030), "{act:#x}");
        }
        // 0x0035: cycle times that are not a multiple of 125 µs in 125 µs … 4 ms.
        for cyc in [0u32, 100_000, 130_000, 4_125_000, 62_500] {
            let (mut s, mut app) = new_slave();
            to_preop(&mut s, &mut app);
            pd_sms(s.esc_mut(), 6, 6);
            s.esc_mut().ecat_write(reg::WATCHDOG_TIME_PD.addr(), &0u16.to_le_bytes());
            s.esc_mut().write_sm(2, 0x1100, 6, 0x24, true);
            dc_on(s.esc_mut(), 3, cyc);
            assert_eq!(request(&mut s, &mut app, 4, 0), (0x12, 0x0035), "{cyc}");
        }
        // 0x0028: sync type DC written without DC; SYNC1 type; SM-sync with DC on.
        for (sm2_type, act) in [(2u16, 0u8), (3, 0), (1, 3), (0, 3)] {
            let (mut s, mut app) = new_slave();
            to_preop(&mut s, &mut app);
            sdo_write(&mut s, &mut app, 0x1C32, 1, &sm2_type.to_le_bytes()).unwrap();
            pd_sms(s.esc_mut(), 6, 6);
            dc_on(s.esc_mut(), act, 1_000_000);
            assert_eq!(request(&mut s, &mut app, 4, 0), (0x12, 0x0028), "{sm2_type} {act}");
        }
        // 0x1C33 inconsistent with 0x1C32.
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        sdo_write(&mut s, &mut app, 0x1C32, 1, &1u16.to_le_bytes()).unwrap();
        sdo_write(&mut s, &mut app, 0x1C33, 1, &2u16.to_le_bytes()).unwrap();
        pd_sms(s.esc_mut(), 6, 6);
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x12, 0x0028));
    }

    fn every_multiple_of_125us_is_accepted_for_dc() {
        for k in 1..=32u32 {
            let (mut s, mut app) = new_slave();
            to_preop(&mut s, &mut app);
            pd_sms(s.esc_mut(), 6, 6);
            dc_on(s.esc_mut(), 3, k * 125_000);
            assert_eq!(request(&mut s, &mut app, 4, 0), (0x04, 0), "{k}");
            assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C32, 1), 2);
            assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C33, 1), 2);
            assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C32, 0x0A), k * 125_000);
        }
    }

    fn product_minimum_cycle_is_enforced_and_62_5us_allowed() {
        for (min, cycle, ok) in [
            (62_500u32, 62_500u32, true),
            (62_500, 125_000, true),
            (62_500, 93_750, false),
            (250_000, 125_000, false),
            (250_000, 250_000, true),
        ] {
            let mut s = Slave::new(FakeEsc::new(), SlaveConfig { min_cycle_ns: min, ..cfg() });
            s.init().unwrap();
            let mut app = App::new();
            to_preop(&mut s, &mut app);
            pd_sms(s.esc_mut(), 6, 6);
            dc_on(s.esc_mut(), 3, cycle);
            let expect = if ok { (0x04, 0) } else { (0x12, 0x0035) };
            assert_eq!(request(&mut s, &mut app, 4, 0), expect, "{min} {cycle}");
            assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C32, 5), min);
        }
    }

    fn dc_lock_then_op_then_sync0_missing_gives_0x002c() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        pd_sms(s.esc_mut(), 6, 6);
        dc_on(s.esc_mut(), 3, 250_000);
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x04, 0));
        // S→O waits for the lock.
        assert_eq!(request(&mut s, &mut app, 8, 0), (0x04, 0));
        let mut t = 0;
        for _ in 0..8 {
            t += 250;
            sync0(&mut s, &mut app, t, true);
        }
        assert_eq!(s.esc_mut().al_status(), (0x08, 0));
        assert!(app.fresh_cycles >= 1);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x2200, 2), 250);
        // SYNC0 stops: after 1 ms without it → Safe-Op + 0x002C.
        s.poll(&mut app, t + 900).unwrap();
        assert_eq!(s.esc_mut().al_status(), (0x08, 0));
        s.poll(&mut app, t + 1100).unwrap();
        assert_eq!(s.esc_mut().al_status(), (0x14, 0x002C));
        assert_eq!(app.lost, Some(AlStatusCode::FatalSyncError));
        assert_eq!(app.last_change(), Some((EsmState::Op, EsmState::SafeOp)));
    }

    fn no_lock_within_1s_gives_0x002d_in_preop() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        pd_sms(s.esc_mut(), 6, 6);
        dc_on(s.esc_mut(), 3, 1_000_000);
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x04, 0));
        assert_eq!(request(&mut s, &mut app, 8, 10), (0x04, 0));
        // SYNC0 events at an irregular pace never lock.
        let mut t = 10;
        while t + 3_100 < 1_000_000 {
            t += 3_100;
            sync0(&mut s, &mut app, t, true);
        }
        assert_eq!(s.esc_mut().al_status().0, 0x04);
        s.poll(&mut app, 1_000_020).unwrap();
        assert_eq!(s.esc_mut().al_status(), (0x12, 0x002D));
    }

    fn lock_lost_gives_0x0032() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        pd_sms(s.esc_mut(), 6, 6);
        dc_on(s.esc_mut(), 3, 1_000_000);
        request(&mut s, &mut app, 4, 0);
        request(&mut s, &mut app, 8, 0);
        let mut t = 0;
        for _ in 0..6 {
            t += 1000;
            sync0(&mut s, &mut app, t, true);
        }
        assert_eq!(s.esc_mut().al_status(), (0x08, 0));
        for _ in 0..4 {
            t += 300;
            sync0(&mut s, &mut app, t, true);
        }
        assert_eq!(s.esc_mut().al_status(), (0x14, 0x0032));
        assert_eq!(app.lost, Some(AlStatusCode::PllError));
    }

    fn missed_sm_events_give_0x001a() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        pd_sms(s.esc_mut(), 6, 6);
        dc_on(s.esc_mut(), 3, 1_000_000);
        request(&mut s, &mut app, 4, 0);
        request(&mut s, &mut app, 8, 0);
        let mut t = 0;
        for _ in 0..6 {
            t += 1000;
            sync0(&mut s, &mut app, t, true);
        }
        assert_eq!(s.esc_mut().al_status(), (0x08, 0));
        // One miss: +3 (limit 4) → still Op; a good one −1; two more misses → 8 > 4.
        t += 1000;
        sync0(&mut s, &mut app, t, false);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C32, 0x0B), 3);
        t += 1000;
        sync0(&mut s, &mut app, t, true);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C32, 0x0B), 2);
        assert_eq!(s.esc_mut().al_status(), (0x08, 0));
        t += 1000;
        sync0(&mut s, &mut app, t, false);
        assert_eq!(s.esc_mut().al_status(), (0x14, 0x001A));
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C32, 0x20), 1);
    }

    fn process_data_watchdog_gives_0x001b_and_stops_outputs() {
        let (mut s, mut app) = new_slave();
        to_op(&mut s, &mut app);
        s.esc_mut().ecat_write(0x1100, &[1, 0, 2, 0, 0, 0]);
        s.poll(&mut app, 100).unwrap();
        assert_eq!(app.v[0], 1);
        // The ESC reports the watchdog expired.
        s.esc_mut().m[reg::WATCHDOG_STATUS_PD.addr() as usize] = 0;
        s.poll(&mut app, 200_000).unwrap();
        assert_eq!(s.esc_mut().al_status(), (0x14, 0x001B));
        assert_eq!(app.lost, Some(AlStatusCode::SmWatchdog));
        assert_eq!(app.last_change(), Some((EsmState::Op, EsmState::SafeOp)));
        // Safe-Op: new outputs are not applied.
        s.esc_mut().ecat_write(0x1100, &[7, 0, 2, 0, 0, 0]);
        s.poll(&mut app, 200_100).unwrap();
        assert_eq!(app.v[0], 1);
        // Watchdog in Safe-Op after outputs were flowing: also 0x001B.
        let (mut s, mut app) = new_slave();
        to_safeop(&mut s, &mut app);
        s.esc_mut().ecat_write(0x1100, &[1, 0, 2, 0, 0, 0]);
        s.poll(&mut app, 100).unwrap();
        s.esc_mut().m[reg::WATCHDOG_STATUS_PD.addr() as usize] = 0;
        s.poll(&mut app, 200_000).unwrap();
        assert_eq!(s.esc_mut().al_status(), (0x14, 0x001B));
    }

    fn watchdog_status_is_read_at_least_every_millisecond() {
        let (mut s, mut app) = new_slave();
        to_op(&mut s, &mut app);
        s.poll(&mut app, 10_000).unwrap();
        s.esc_mut().m[reg::WATCHDOG_STATUS_PD.addr() as usize] = 0;
        s.poll(&mut app, 10_500).unwrap();
        assert_eq!(s.esc_mut().al_status(), (0x08, 0));
        s.poll(&mut app, 11_000).unwrap();
        assert_eq!(s.esc_mut().al_status(), (0x14, 0x001B));
        // The ESC's watchdog event is acted on at once.
        let (mut s, mut app) = new_slave();
        to_op(&mut s, &mut app);
        s.poll(&mut app, 10_000).unwrap();
        s.esc_mut().m[reg::WATCHDOG_STATUS_PD.addr() as usize] = 0;
        s.esc_mut().set_event(1 << 6, true);
        s.poll(&mut app, 10_001).unwrap();
        assert_eq!(s.esc_mut().al_status(), (0x14, 0x001B));
    }

    fn mailbox_buffer_is_released_and_bad_lengths_are_answered() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        let sm0_status = (reg::sm_register(0) + reg::sm::STATUS) as usize;
        for announced in [0u16, 2, 10, 122, 123, 500, 0xFFFF] {
            let mut req = [0u8; 128];
            req[..2].copy_from_slice(&announced.to_le_bytes());
            req[5] = 0x03;
            s.esc_mut().ecat_write(0x1000, &req);
            assert_ne!(s.esc_mut().m[sm0_status] & 0x08, 0);
            s.poll(&mut app, 0).unwrap();
            assert_eq!(s.esc_mut().m[sm0_status] & 0x08, 0, "released ({announced})");
            let mut out = [0u8; 128];
            assert!(s.esc_mut().read_sm1(&mut out), "answered ({announced})");
        }
    }

    fn mailbox_answer_uses_handover_and_repeat() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        // A VoE request (type 0xF): answered with a mailbox error, "protocol not supported".
        let mut req = [0u8; 128];
        req[..6].copy_from_slice(&[4, 0, 0, 0, 0, 0x1F]);
        s.esc_mut().ecat_write(0x1000, &req);
        s.poll(&mut app, 0).unwrap();
        let mut out = [0u8; 128];
        assert!(s.esc_mut().read_sm1(&mut out));
        assert_eq!(out[5] & 0x0F, 0, "mailbox type error");
        assert_eq!(&out[6..10], &[0x01, 0x00, 0x02, 0x00]);
        let first = out;
        // Nothing more to send.
        s.poll(&mut app, 10).unwrap();
        assert!(!s.esc_mut().read_sm1(&mut out));
        // Repeat request: toggle SM1 activate bit 1 → same frame again, ack in 0x080F.
        s.esc_mut().ecat_write(reg::sm_register(1) + reg::sm::ACTIVATE, &[0x03]);
        s.poll(&mut app, 20).unwrap();
        let mut again = [0u8; 128];
        assert!(s.esc_mut().read_sm1(&mut again));
        assert_eq!(&again[..10], &first[..10]);
        assert_eq!(s.esc_mut().m[(reg::sm_register(1) + reg::sm::PDI_CONTROL) as usize] & 0x02, 0x02);
    }

    fn sdo_through_the_mailbox_reaches_the_communication_objects() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        // Expedited upload of 0x1C12:01, counter 1.
        let mut req = [0u8; 128];
        req[..16].copy_from_slice(&[10, 0, 0, 0, 0, 0x13, 0x00, 0x20, 0x40, 0x12, 0x1C, 0x01, 0, 0, 0, 0]);
        s.esc_mut().ecat_write(0x1000, &req);
        s.poll(&mut app, 0).unwrap();
        let mut out = [0u8; 128];
        assert!(s.esc_mut().read_sm1(&mut out));
        assert_eq!(out[5] & 0x0F, 3, "CoE");
        assert_eq!(out[7] >> 4, 3, "SDO response");
        assert_eq!(&out[9..12], &[0x12, 0x1C, 0x01]);
        assert_eq!(&out[12..14], &[0x00, 0x16]);
        // Download 0x1C12:00 = 0 in Safe-Op: abort 0x08000022.
        pd_sms(s.esc_mut(), 6, 6);
        assert_eq!(request(&mut s, &mut app, 4, 10), (0x04, 0));
        req[..16].copy_from_slice(&[10, 0, 0, 0, 0, 0x23, 0x00, 0x20, 0x2F, 0x12, 0x1C, 0x00, 0, 0, 0, 0]);
        s.esc_mut().ecat_write(0x1000, &req);
        s.poll(&mut app, 20).unwrap();
        assert!(s.esc_mut().read_sm1(&mut out));
        assert_eq!(out[8], 0x80, "abort");
        assert_eq!(u32::from_le_bytes([out[12], out[13], out[14], out[15]]), 0x0800_0022);
    }

    fn pdo_sdo_rules() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        let e = |i, sub, b| ObjectKey::new(i, sub).mapping_word(b).to_le_bytes();
        // Sub-index 0 first.
        assert_eq!(sdo_write(&mut s, &mut app, 0x1600, 1, &e(0x6040, 0, 16)), Err(SdoAbort::SubindexZeroFirst));
        sdo_write(&mut s, &mut app, 0x1600, 0, &[0]).unwrap();
        // Not mappable / wrong direction / missing object / missing sub-index.
        assert_eq!(sdo_write(&mut s, &mut app, 0x1600, 1, &e(0x2101, 0, 16)), Err(SdoAbort::NotMappable));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1600, 1, &e(0x6041, 0, 16)), Err(SdoAbort::NotMappable));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1600, 1, &e(0x5000, 0, 16)), Err(SdoAbort::NotMappable));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1600, 1, &e(0x6040, 3, 16)), Err(SdoAbort::NotMappable));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1600, 1, &e(0x6040, 0, 8)), Err(SdoAbort::ParameterIncompatibility));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1600, 1, &e(0, 0, 0)), Err(SdoAbort::NotMappable));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1600, 1, &[1, 2]), Err(SdoAbort::LengthTooLow));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1600, 17, &e(0x6040, 0, 16)), Err(SdoAbort::SubindexDoesNotExist));
        // Nine 64-bit entries = 72 bytes > 64.
        for k in 1..=9u8 {
            sdo_write(&mut s, &mut app, 0x1600, k, &e(0x2102, 0, 64)).unwrap();
        }
        assert_eq!(sdo_write(&mut s, &mut app, 0x1600, 0, &[9]), Err(SdoAbort::PdoLengthExceeded));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1600, 0, &[17]), Err(SdoAbort::ValueTooHigh));
        sdo_write(&mut s, &mut app, 0x1600, 0, &[8]).unwrap();
        // Assigned 0x1600 (64 bytes) + 0x1601 (4 bytes) > 64 → refused.
        sdo_write(&mut s, &mut app, 0x1C12, 0, &[0]).unwrap();
        sdo_write(&mut s, &mut app, 0x1C12, 1, &0x1600u16.to_le_bytes()).unwrap();
        sdo_write(&mut s, &mut app, 0x1C12, 2, &0x1601u16.to_le_bytes()).unwrap();
        assert_eq!(sdo_write(&mut s, &mut app, 0x1C12, 0, &[2]), Err(SdoAbort::PdoLengthExceeded));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1C12, 2, &0x1600u16.to_le_bytes()), Ok(()));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1C12, 0, &[2]), Err(SdoAbort::ParameterIncompatibility));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1C12, 1, &0x1A00u16.to_le_bytes()), Err(SdoAbort::ValueRangeExceeded));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1C13, 1, &0x1A00u16.to_le_bytes()), Err(SdoAbort::SubindexZeroFirst));
        sdo_write(&mut s, &mut app, 0x1C13, 0, &[0]).unwrap();
        assert_eq!(sdo_write(&mut s, &mut app, 0x1C13, 1, &0x1600u16.to_le_bytes()), Err(SdoAbort::ValueRangeExceeded));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1C13, 1, &0x1A04u16.to_le_bytes()), Err(SdoAbort::ValueRangeExceeded));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1C13, 1, &[0]), Err(SdoAbort::LengthTooLow));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1C12, 0, &[5]), Err(SdoAbort::ValueTooHigh));
        sdo_write(&mut s, &mut app, 0x1C12, 0, &[1]).unwrap();
        assert_eq!(s.pdo().assigned_bytes(pdo::Dir::Rx), 64);
        // 0x1C00 is read-only.
        assert_eq!(sdo_write(&mut s, &mut app, 0x1C00, 1, &[1]), Err(SdoAbort::WriteReadOnly));
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C00, 3), 3);
        // Outside Pre-Op: state conflict.
        let (mut s, mut app) = new_slave();
        to_safeop(&mut s, &mut app);
        assert_eq!(sdo_write(&mut s, &mut app, 0x1600, 0, &[0]), Err(SdoAbort::StateConflict));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1C13, 0, &[0]), Err(SdoAbort::StateConflict));
        assert_eq!(sdo_write(&mut s, &mut app, 0x1C32, 1, &[0, 0]), Err(SdoAbort::StateConflict));
        // Default maps read back.
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1600, 0), 2);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1600, 2), 0x607A_0020);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C13, 1), 0x1A00);
        // Other indices reach the application.
        app.v[4] = 0x0237;
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x6041, 0), 0x0237);
    }

    fn remapped_bits_and_padding_flow_in_op() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        // Rx: 0x1601 = cw 16, mode 8, flag 1, pad 7 (4 bytes). Tx: 0x1A01 = flag 1, pad 7, sw 16.
        sdo_write(&mut s, &mut app, 0x1C12, 0, &[0]).unwrap();
        sdo_write(&mut s, &mut app, 0x1C12, 1, &0x1601u16.to_le_bytes()).unwrap();
        sdo_write(&mut s, &mut app, 0x1C12, 0, &[1]).unwrap();
        sdo_write(&mut s, &mut app, 0x1A01, 1, &ObjectKey::new(0x2100, 0).mapping_word(1).to_le_bytes()).unwrap();
        sdo_write(&mut s, &mut app, 0x1A01, 2, &ObjectKey::new(0, 0).mapping_word(7).to_le_bytes()).unwrap();
        sdo_write(&mut s, &mut app, 0x1A01, 3, &ObjectKey::new(0x6041, 0).mapping_word(16).to_le_bytes()).unwrap();
        sdo_write(&mut s, &mut app, 0x1A01, 0, &[3]).unwrap();
        sdo_write(&mut s, &mut app, 0x1C13, 0, &[0]).unwrap();
        sdo_write(&mut s, &mut app, 0x1C13, 1, &0x1A01u16.to_le_bytes()).unwrap();
        sdo_write(&mut s, &mut app, 0x1C13, 0, &[1]).unwrap();
        pd_sms(s.esc_mut(), 4, 3);
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x04, 0));
        assert_eq!(request(&mut s, &mut app, 8, 0), (0x08, 0));
        s.esc_mut().ecat_write(0x1100, &[0x06, 0x00, 0xFE, 0xFF]);
        s.poll(&mut app, 10).unwrap();
        assert_eq!((app.v[0], app.v[2], app.v[3]), (6, 0xFE, 1));
        assert_eq!(&s.esc_mut().m[0x1400..0x1403], &[0x01, 0x07, 0x00]);
    }

    fn free_run_cycles_on_the_local_period() {
        let (mut s, mut app) = new_slave();
        to_preop(&mut s, &mut app);
        sdo_write(&mut s, &mut app, 0x1C32, 1, &0u16.to_le_bytes()).unwrap();
        sdo_write(&mut s, &mut app, 0x1C32, 2, &500_000u32.to_le_bytes()).unwrap();
        pd_sms(s.esc_mut(), 6, 6);
        assert_eq!(request(&mut s, &mut app, 4, 0), (0x04, 0));
        let c0 = app.cycles;
        for t in (100..=2000).step_by(100) {
            s.poll(&mut app, t).unwrap();
        }
        assert_eq!(app.cycles - c0, 4);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x2200, 1), 500);
    }

    fn disabling_sm2_in_op_gives_0x001d() {
        let (mut s, mut app) = new_slave();
        to_op(&mut s, &mut app);
        s.esc_mut().write_sm(2, 0x1100, 6, 0x64, false);
        s.poll(&mut app, 10).unwrap();
        assert_eq!(s.esc_mut().al_status(), (0x12, 0x001D));
    }

    fn garbage_never_panics() {
        let mut x = 12345u32;
        for _ in 0..40 {
            let (mut s, mut app) = new_slave();
            for _ in 0..40 {
                let r = lcg(&mut x);
                match r % 6 {
                    0 => s.esc_mut().al_control((lcg(&mut x) & 0xFFFF) as u16),
                    1 => {
                        let n = (lcg(&mut x) % 4) as u8;
                        let v = lcg(&mut x);
                        s.esc_mut().write_sm(n, 0x0F00 + (v & 0x1FFF) as u16, (lcg(&mut x) % 400) as u16, v as u8, v & 0x100 != 0);
                    }
                    2 => {
                        let a = 0x1000 + (lcg(&mut x) % 0x0F00) as u16;
                        let b = [lcg(&mut x) as u8; 16];
                        s.esc_mut().ecat_write(a, &b);
                    }
                    3 => s.esc_mut().set_event(lcg(&mut x), true),
                    4 => dc_on(s.esc_mut(), lcg(&mut x) as u8, lcg(&mut x)),
                    _ => {
                        let idx = [0x1600u16, 0x1A01, 0x1C12, 0x1C13, 0x1C32, 0x1C33, 0x2200, 0x1C00][(r % 8) as usize];
                        let d = lcg(&mut x).to_le_bytes();
                        let st = s.state();
                        let _ = s.dictionary(&mut app).write(ObjectKey::new(idx, (lcg(&mut x) % 40) as u8), &d[..(r as usize % 5)], st);
                        let mut b = [0u8; 8];
                        let _ = s.dictionary(&mut app).read(ObjectKey::new(idx, (lcg(&mut x) % 40) as u8), &mut b);
                    }
                }
                s.poll(&mut app, lcg(&mut x) as u64).unwrap();
                let _ = s.cycle(&mut app, lcg(&mut x) as u64);
            }
        }
    }

    fn dc_armed_in_safeop_as_soem_does_switches_to_sync0() {
        // SOEM: ecx_config_map_group requests Safe-Op, ecx_dcsync0 arms SYNC0 after
        // it (0x0981 = 0, 0x0980 = 0, start time, 0x09A0, 0x0981 = 3); 0x1C32:01 is
        // never written.
        let (mut s, mut app) = new_slave();
        to_safeop(&mut s, &mut app);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C32, 1), 1);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C33, 1), 0x22);
        let esc = s.esc_mut();
        esc.ecat_write(reg::DC_ACTIVATION.addr(), &[0]);
        esc.ecat_write(reg::DC_CYCLIC_UNIT_CONTROL.addr(), &[0]);
        esc.ecat_write(reg::DC_START_TIME.addr(), &100_000_000u64.to_le_bytes());
        esc.ecat_write(reg::DC_SYNC0_CYCLE.addr(), &1_000_000u32.to_le_bytes());
        esc.ecat_write(reg::DC_ACTIVATION.addr(), &[3]);
        // A SYNC0 event raised before (SM-synchronous mode ignores it) runs no cycle.
        esc.set_event(1 << 2, true);
        let c = app.cycles;
        s.poll(&mut app, 1_500).unwrap();
        assert_eq!(app.cycles, c, "stale SYNC0 event");
        assert_eq!(s.sync().mode, sync::SyncMode::DcSync0);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C32, 1), 2);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C32, 2), 1_000_000);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C32, 0x0A), 1_000_000);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C33, 1), 2);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C33, 2), 1_000_000);
        let m = reg::AL_EVENT_MASK.addr() as usize;
        let mask = u32::from_le_bytes(s.esc_mut().m[m..m + 4].try_into().unwrap());
        assert_ne!(mask & 1 << 2, 0, "SYNC0 in the event mask");
        // S→O waits for the lock, then exactly one cycle per SYNC0.
        assert_eq!(request(&mut s, &mut app, 8, 1_600), (0x04, 0));
        let mut t = 1_600;
        for _ in 0..6 {
            t += 1000;
            sync0(&mut s, &mut app, t, true);
        }
        assert_eq!(s.esc_mut().al_status(), (0x08, 0));
        let c = app.cycles;
        for _ in 0..20 {
            t += 1000;
            sync0(&mut s, &mut app, t, true);
            // Polls between SYNC0 events (SM2 events included) run no cycle.
            s.poll(&mut app, t + 300).unwrap();
            s.esc_mut().ecat_write(0x1100, &[1, 2, 3, 4, 5, 6]);
            s.poll(&mut app, t + 600).unwrap();
        }
        assert_eq!(app.cycles - c, 20);
    }

    fn dc_change_in_safeop_is_picked_up_within_1ms_and_can_be_undone() {
        let (mut s, mut app) = new_slave();
        to_safeop(&mut s, &mut app);
        s.poll(&mut app, 5_000).unwrap();
        dc_on(s.esc_mut(), 3, 250_000);
        // Read at most once per ms: not yet at 5.5 ms, at 6 ms.
        s.poll(&mut app, 5_500).unwrap();
        assert_eq!(s.sync().mode, sync::SyncMode::SmSync);
        s.poll(&mut app, 6_000).unwrap();
        assert_eq!(s.sync().mode, sync::SyncMode::DcSync0);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C32, 2), 250_000);
        // The master switches SYNC0 off again: SM-synchronous, nothing refused.
        s.esc_mut().ecat_write(reg::DC_ACTIVATION.addr(), &[0]);
        s.poll(&mut app, 7_000).unwrap();
        assert_eq!(s.sync().mode, sync::SyncMode::SmSync);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C32, 1), 1);
        assert_eq!(sdo_read_u32(&mut s, &mut app, 0x1C33, 1), 0x22);
        assert_eq!(request(&mut s, &mut app, 8, 7_100), (0x08, 0));
    }

    fn dc_armed_in_safeop_against_the_written_type_refuses_op() {
        // (0x1C32:01 written in Pre-Op, 0x0981, 0x09A0, S→O answer)
        type Case = (Option<u16>, u8, u32, (u16, u16));
        let cases: [Case; 6] = [
            (Some(1), 3, 1_000_000, (0x12, 0x0028)),
            (Some(0), 3, 1_000_000, (0x12, 0x0028)),
            (None, 7, 1_000_000, (0x12, 0x0030)),
            (None, 1, 1_000_000, (0x12, 0x0030)),
            (None, 3, 300_000, (0x12, 0x0035)),
            (Some(2), 3, 1_000_000, (0x04, 0)),
        ];
        for (i, (written, act, cycle, answer)) in cases.into_iter().enumerate() {
            let (mut s, mut app) = new_slave();
            to_preop(&mut s, &mut app);
            pd_sms(s.esc_mut(), 6, 6);
            if let Some(t) = written {
                sdo_write(&mut s, &mut app, 0x1C32, 1, &t.to_le_bytes()).unwrap();
            }
            // Type 2 needs SYNC0 armed at P→S; the others go to Safe-Op without DC.
            if written == Some(2) {
                dc_on(s.esc_mut(), 3, 500_000);
            }
            assert_eq!(request(&mut s, &mut app, 4, 0), (0x04, 0), "case {i}");
            let before = s.sync().mode;
            dc_on(s.esc_mut(), act, cycle);
            s.poll(&mut app, 2_000).unwrap();
            if answer.1 != 0 {
                assert_eq!(s.sync().mode, before, "case {i}: mode kept");
            }
            // The S→O request reads the registers again (no 1 ms wait).
            assert_eq!(request(&mut s, &mut app, 8, 2_001), answer, "case {i}");
            if answer.1 != 0 {
                // Like a refused P→S: back in Pre-Op with the error. Acknowledged,
                // corrected (SYNC0 off), Safe-Op and Op are reached.
                assert_eq!(request(&mut s, &mut app, 0x12, 2_002), (0x02, 0));
                s.esc_mut().ecat_write(reg::DC_ACTIVATION.addr(), &[0]);
                assert_eq!(request(&mut s, &mut app, 4, 2_003), (0x04, 0), "case {i}");
                assert_eq!(request(&mut s, &mut app, 8, 2_004), (0x08, 0), "case {i}");
            }
        }
    }
}
