//! Benchmark rows of the slave runtime (ESM poll, process-data cycle, unpack, pack).
//!
//! The ESC is a plain RAM array behind `EscAccess` (no SPI cost: the rows count the
//! stack's own instructions). The dictionary carries the CiA 402 objects of the
//! default maps (0x1600 / 0x1A00) and a few more for the 32-byte images.

use core::hint::black_box;

use ecat_slave_stack::al_status::AlStatusCode;
use ecat_slave_stack::esc::{EscAccess, EscError};
use ecat_slave_stack::esm::{EsmHooks, EsmState};
use ecat_slave_stack::od::{
    Access, DataType, Dictionary, EntryDesc, Object, ObjectDesc, ObjectKey, PdoMappable, SdoAbort,
};
use ecat_slave_stack::pdo::{self, PdoConfig, PdoDefaults, ProcessData};
use ecat_slave_stack::registers as reg;
use ecat_slave_stack::slave::{CycleInfo, Slave, SlaveApplication, SlaveConfig};

const MEM: usize = 0x2000;

struct RamEsc {
    m: [u8; MEM],
}

impl EscAccess for RamEsc {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EscError> {
        let a = addr as usize;
        let src = self.m.get(a..a + buf.len()).ok_or(EscError::OutOfRange)?;
        buf.copy_from_slice(src);
        // Reading AL control / SM activate / SYNC0 status / the SM2 buffer clears
        // the matching AL event bit, as on the chip.
        let end = a + buf.len();
        let mut clear = 0u32;
        if (a..end).contains(&(reg::AL_CONTROL.addr() as usize)) {
            clear |= 1;
        }
        if (a..end).contains(&0x110B) {
            clear |= 1 << 10;
        }
        if clear != 0 {
            let e = reg::AL_EVENT_REQUEST.addr() as usize;
            let v = u32::from_le_bytes([self.m[e], self.m[e + 1], self.m[e + 2], self.m[e + 3]])
                & !clear;
            self.m[e..e + 4].copy_from_slice(&v.to_le_bytes());
        }
        Ok(())
    }
    fn write(&mut self, addr: u16, data: &[u8]) -> Result<(), EscError> {
        let a = addr as usize;
        if a <= reg::AL_CONTROL.addr() as usize
            && (reg::AL_CONTROL.addr() as usize) < a + data.len()
        {
            return Ok(());
        }
        let dst = self
            .m
            .get_mut(a..a + data.len())
            .ok_or(EscError::OutOfRange)?;
        dst.copy_from_slice(data);
        Ok(())
    }
}

impl RamEsc {
    fn master_write(&mut self, addr: u16, data: &[u8], event: u32) {
        let a = addr as usize;
        self.m[a..a + data.len()].copy_from_slice(data);
        let e = reg::AL_EVENT_REQUEST.addr() as usize;
        let v =
            u32::from_le_bytes([self.m[e], self.m[e + 1], self.m[e + 2], self.m[e + 3]]) | event;
        self.m[e..e + 4].copy_from_slice(&v.to_le_bytes());
    }
    fn sm(&mut self, n: u8, start: u16, len: u16, control: u8) {
        let mut b = [0u8; 7];
        b[..2].copy_from_slice(&start.to_le_bytes());
        b[2..4].copy_from_slice(&len.to_le_bytes());
        b[4] = control;
        b[6] = 1;
        self.master_write(reg::sm_register(n), &b, 0);
    }
}

macro_rules! objects {
    ($( $idx:literal $t:ident $dir:ident ),* $(,)?) => {
        &[$(ObjectDesc::var($idx, "", &[EntryDesc::new(0, "", DataType::$t, Access::RW).pdo(PdoMappable::$dir)], "")),*]
    };
}

static OBJECTS: &[Object] = ecat_slave_stack::packed_dictionary!(&[SOURCE]);
const SOURCE: &[ObjectDesc] = objects![
    0x603F Unsigned16 Tx, 0x6040 Unsigned16 Rx, 0x6041 Unsigned16 Tx, 0x6060 Integer8 Rx,
    0x6061 Integer8 Tx, 0x6064 Integer32 Tx, 0x606C Integer32 Tx, 0x6077 Integer16 Tx,
    0x607A Integer32 Rx, 0x6081 Unsigned32 Rx, 0x6083 Unsigned32 Rx, 0x6098 Integer8 Rx,
    0x60B0 Integer32 Rx, 0x60B1 Integer32 Rx, 0x60B2 Integer16 Rx, 0x60B8 Unsigned16 Rx,
    0x60B9 Unsigned16 Tx, 0x60BA Integer32 Tx, 0x60BB Integer32 Tx, 0x60F4 Integer32 Tx,
    0x60FD Unsigned32 Tx, 0x60FF Integer32 Rx,
];

/// RxPDO1 / TxPDO1, the default maps.
const RX1: &[u32] = &[
    ObjectKey::new(0x6040, 0).mapping_word(16),
    ObjectKey::new(0x607A, 0).mapping_word(32),
    ObjectKey::new(0x60B0, 0).mapping_word(32),
    ObjectKey::new(0x60B8, 0).mapping_word(16),
];
const TX1: &[u32] = &[
    ObjectKey::new(0x603F, 0).mapping_word(16),
    ObjectKey::new(0x6041, 0).mapping_word(16),
    ObjectKey::new(0x6061, 0).mapping_word(8),
    ObjectKey::new(0x6064, 0).mapping_word(32),
    ObjectKey::new(0x60B9, 0).mapping_word(16),
    ObjectKey::new(0x60BA, 0).mapping_word(32),
    ObjectKey::new(0x60FD, 0).mapping_word(32),
];
/// 32-byte images.
const RX32: &[u32] = &[
    ObjectKey::new(0x6040, 0).mapping_word(16),
    ObjectKey::new(0x607A, 0).mapping_word(32),
    ObjectKey::new(0x60FF, 0).mapping_word(32),
    ObjectKey::new(0x60B0, 0).mapping_word(32),
    ObjectKey::new(0x60B1, 0).mapping_word(32),
    ObjectKey::new(0x6081, 0).mapping_word(32),
    ObjectKey::new(0x6083, 0).mapping_word(32),
    ObjectKey::new(0x60B2, 0).mapping_word(16),
    ObjectKey::new(0x6060, 0).mapping_word(8),
    ObjectKey::new(0x6098, 0).mapping_word(8),
    ObjectKey::new(0x60B8, 0).mapping_word(16),
];
const TX32: &[u32] = &[
    ObjectKey::new(0x603F, 0).mapping_word(16),
    ObjectKey::new(0x6041, 0).mapping_word(16),
    ObjectKey::new(0x6061, 0).mapping_word(8),
    ObjectKey::new(0, 0).mapping_word(8),
    ObjectKey::new(0x6064, 0).mapping_word(32),
    ObjectKey::new(0x606C, 0).mapping_word(32),
    ObjectKey::new(0x6077, 0).mapping_word(16),
    ObjectKey::new(0x60F4, 0).mapping_word(32),
    ObjectKey::new(0x60BA, 0).mapping_word(32),
    ObjectKey::new(0x60BB, 0).mapping_word(32),
    ObjectKey::new(0x60FD, 0).mapping_word(32),
];

struct App {
    v: [u64; 32],
}

fn slot_of(index: u16) -> Option<u16> {
    OBJECTS
        .iter()
        .position(|o| o.index == index)
        .map(|p| p as u16)
}

impl Dictionary for App {
    fn objects(&self) -> &'static [Object] {
        OBJECTS
    }
    fn read(&mut self, _key: ObjectKey, _buf: &mut [u8]) -> Result<usize, SdoAbort> {
        Err(SdoAbort::ObjectDoesNotExist)
    }
    fn write(&mut self, _key: ObjectKey, _data: &[u8], _state: EsmState) -> Result<(), SdoAbort> {
        Err(SdoAbort::ObjectDoesNotExist)
    }
}

impl ProcessData for App {
    fn rx_slot(&self, key: ObjectKey) -> Option<u16> {
        let ObjectKey { index, .. } = key;
        slot_of(index)
    }
    fn tx_slot(&self, key: ObjectKey) -> Option<u16> {
        let ObjectKey { index, .. } = key;
        slot_of(index)
    }
    fn set_rx(&mut self, slot: u16, raw: u64) {
        if let Some(v) = self.v.get_mut(slot as usize) {
            *v = raw;
        }
    }
    fn get_tx(&self, slot: u16) -> u64 {
        self.v.get(slot as usize).copied().unwrap_or(0)
    }
}

impl EsmHooks for App {
    fn on_state_change(&mut self, _from: EsmState, _to: EsmState) {}
}

impl SlaveApplication for App {
    fn cycle(&mut self, info: &CycleInfo) {
        black_box(info);
    }
    fn on_outputs_lost(&mut self, code: AlStatusCode) {
        black_box(code);
    }
}

/// A slave in Op with the default maps (12 B outputs, 19 B inputs), SM-synchronous.
fn slave_in_op<'a>(esc: &'a mut RamEsc, app: &mut App) -> Option<Slave<&'a mut RamEsc>> {
    esc.m[reg::RAM_SIZE.addr() as usize] = 4;
    esc.m[reg::WATCHDOG_STATUS_PD.addr() as usize] = 1;
    let defaults = PdoDefaults {
        rx: [RX1, &[], &[], &[]],
        tx: [TX1, &[], &[], &[]],
        rx_assign: &[0x1600],
        tx_assign: &[0x1A00],
    };
    let mut s = Slave::new(
        esc,
        SlaveConfig {
            pdo_defaults: defaults,
            ..SlaveConfig::default()
        },
    );
    s.init().ok()?;
    let e = s.esc_mut();
    e.sm(0, 0x1000, 128, 0x26);
    e.sm(1, 0x1080, 128, 0x22);
    e.sm(2, 0x1100, 12, 0x64);
    e.sm(3, 0x1400, 19, 0x20);
    e.master_write(reg::WATCHDOG_DIVIDER.addr(), &2498u16.to_le_bytes(), 0);
    e.master_write(reg::WATCHDOG_TIME_PD.addr(), &1000u16.to_le_bytes(), 0);
    for state in [2u16, 4, 8] {
        s.esc_mut()
            .master_write(reg::AL_CONTROL.addr(), &state.to_le_bytes(), 1);
        s.poll(app, 0).ok()?;
    }
    if s.state() == EsmState::Op {
        Some(s)
    } else {
        None
    }
}

pub fn run() {
    let mut esc = RamEsc { m: [0; MEM] };
    let mut app = App { v: [0; 32] };
    if let Some(mut s) = slave_in_op(&mut esc, &mut app) {
        let r = crate::bench("ESM poll (idle)", || s.poll(&mut app, black_box(1000)));
        black_box(r.is_ok());
        s.esc_mut()
            .master_write(0x1100, &[0x0F, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10], 1 << 10);
        let r = crate::bench("process data cycle (idle, default maps)", || {
            s.poll(&mut app, black_box(2000))
        });
        black_box(r.is_ok());
        // The cycle ran: the controlword reached the application.
        black_box(app.v[1] == 0x0F);
    }

    let defaults = PdoDefaults {
        rx: [RX32, &[], &[], &[]],
        tx: [TX32, &[], &[], &[]],
        rx_assign: &[0x1600],
        tx_assign: &[0x1A00],
    };
    let cfg = PdoConfig::new(defaults);
    let mut app = App {
        v: [0x5A5A_5A5A; 32],
    };
    if let Ok(plan) = cfg.compile(&app, OBJECTS) {
        let outputs = black_box([0xA5u8; 32]);
        let mut inputs = [0u8; 32];
        crate::bench("unpack 32 B outputs", || {
            pdo::unpack(&plan.rx, &outputs, &mut app)
        });
        crate::bench("pack 32 B inputs", || {
            pdo::pack(&plan.tx, &app, &mut inputs)
        });
        black_box(inputs);
    }
}
