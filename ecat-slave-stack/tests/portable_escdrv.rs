//! Portable tests (host and QEMU) of the ESC drivers' bounded start-up, the SII image,
//! the ESI writer and the ETG.1300 indicators. Byte-exact driver tests against the
//! SPI chip models live in `tests-host/tests/spi_drivers.rs`.
#![cfg_attr(target_os = "none", no_std, no_main)]

use core::fmt::Write;

use ecat_slave_stack::esi::{self, EsiError, PdoEntry, PdoMap};
use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::et1100::{self, Et1100, Et1100Config};
use ecat_slave_stack::lan9252::{self, Lan9252, Lan9252Config};
use ecat_slave_stack::leds::{self, ErrCondition, Indicator, Pattern, StatusLeds};
use ecat_slave_stack::od::{
    Access, DataType, EntryDesc, Name, Object, ObjectCode, ObjectDesc, ObjectKey, PdoMappable,
};
use ecat_slave_stack::pdo;
use ecat_slave_stack::sii::{self, DeviceDescription, EscFlavour, Sii, SiiError, SmType};
use ecat_slave_stack::{EscAccess, EscError};
use embedded_hal::delay::DelayNs;
use embedded_hal::spi::{ErrorKind, ErrorType, Operation, SpiDevice};

// ---------------------------------------------------------------------------------
// A tiny no-alloc SPI responder for the start-up / fault tests.

#[derive(Debug)]
struct BusErr;
impl embedded_hal::spi::Error for BusErr {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Other
    }
}

/// Answers LAN9252 register reads from a fixed table (fast read framing), or floats
/// MISO high when `absent`.
struct FakeLan {
    absent: bool,
    byte_test: u32,
    hw_cfg: u32,
    csr_cmd: u32,
    transactions: u32,
    fail: bool,
}

impl FakeLan {
    fn new() -> Self {
        FakeLan {
            absent: false,
            byte_test: lan9252::BYTE_TEST_VALUE,
            hw_cfg: lan9252::HW_CFG_READY,
            csr_cmd: 0,
            transactions: 0,
            fail: false,
        }
    }
}

impl ErrorType for FakeLan {
    type Error = BusErr;
}

impl SpiDevice for FakeLan {
    fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), BusErr> {
        self.transactions += 1;
        if self.fail {
            return Err(BusErr);
        }
        let mut addr = 0u16;
        for op in ops.iter_mut() {
            match op {
                Operation::Write(w) if w.len() >= 3 && w[0] != lan9252::cmd::SERIAL_WRITE => {
                    addr = (w[1] as u16) << 8 | w[2] as u16;
                }
                Operation::Read(r) => {
                    let v = match addr {
                        lan9252::reg::BYTE_TEST => self.byte_test,
                        lan9252::reg::HW_CFG => self.hw_cfg,
                        lan9252::reg::ECAT_CSR_CMD => self.csr_cmd,
                        lan9252::reg::PRAM_RD_CMD | lan9252::reg::PRAM_WR_CMD => 0,
                        _ => 0,
                    };
                    for (i, b) in r.iter_mut().enumerate() {
                        *b = if self.absent {
                            0xFF
                        } else {
                            v.to_le_bytes()[i % 4]
                        };
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }
}

/// An ET1100 whose MISO is stuck at one value (no chip: 0xFF or 0x00).
struct StuckSpi {
    miso: u8,
    transactions: u32,
}

impl ErrorType for StuckSpi {
    type Error = BusErr;
}

impl SpiDevice for StuckSpi {
    fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), BusErr> {
        self.transactions += 1;
        for op in ops.iter_mut() {
            match op {
                Operation::Read(r) | Operation::TransferInPlace(r) => r.fill(self.miso),
                Operation::Transfer(r, _) => r.fill(self.miso),
                _ => {}
            }
        }
        Ok(())
    }
}

/// MISO is pseudo-random noise: whatever the chip answers, the drivers must end every
/// call with a result, bounded, without panicking.
struct NoiseSpi {
    seed: u32,
    transactions: u32,
}

impl ErrorType for NoiseSpi {
    type Error = BusErr;
}

impl SpiDevice for NoiseSpi {
    fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), BusErr> {
        self.transactions += 1;
        for op in ops.iter_mut() {
            let buf: &mut [u8] = match op {
                Operation::Read(r) | Operation::TransferInPlace(r) => r,
                Operation::Transfer(r, _) => r,
                _ => continue,
            };
            for b in buf.iter_mut() {
                *b = lcg(&mut self.seed) as u8;
            }
        }
        if lcg(&mut self.seed).is_multiple_of(50) {
            return Err(BusErr);
        }
        Ok(())
    }
}

struct CountDelay(u32);
impl DelayNs for CountDelay {
    fn delay_ns(&mut self, _ns: u32) {
        self.0 += 1;
    }
}

// ---------------------------------------------------------------------------------
// Device description and a small dictionary for SII / ESI.

const RECORD_1018: [EntryDesc; 5] = [
    EntryDesc::new(0, "Number of entries", DataType::Unsigned8, Access::RO).default(4),
    EntryDesc::new(1, "Vendor ID", DataType::Unsigned32, Access::RO).default(0x0E5C),
    EntryDesc::new(2, "Product code", DataType::Unsigned32, Access::RO).default(0x5840),
    EntryDesc::new(3, "Revision", DataType::Unsigned32, Access::RO).default(0x0001_0000),
    EntryDesc::new(
        4,
        "Serial \"number\" <sn> & co",
        DataType::Unsigned32,
        Access::RO,
    ),
];
const MAP_1600: [EntryDesc; 3] = [
    EntryDesc::new(
        0,
        "Number of entries",
        DataType::Unsigned8,
        Access::RW_PREOP,
    )
    .default(2),
    EntryDesc::new(1, "Entry 1", DataType::Unsigned32, Access::RW_PREOP).default(0x6040_0010),
    EntryDesc::new(2, "Entry 2", DataType::Unsigned32, Access::RW_PREOP).default(0x607A_0020),
];
const MAP_1A00: [EntryDesc; 2] = [
    EntryDesc::new(
        0,
        "Number of entries",
        DataType::Unsigned8,
        Access::RW_PREOP,
    )
    .default(1),
    EntryDesc::new(1, "Entry 1", DataType::Unsigned32, Access::RW_PREOP).default(0x6041_0010),
];
const ARR_1C12: [EntryDesc; 2] = [
    EntryDesc::new(
        0,
        "Number of assigned PDOs",
        DataType::Unsigned8,
        Access::RW_PREOP,
    )
    .default(1),
    EntryDesc::new(1, "PDO 1", DataType::Unsigned16, Access::RW_PREOP).default(0x1600),
];
const V1000: [EntryDesc; 1] =
    [EntryDesc::new(0, "Device type", DataType::Unsigned32, Access::RO).default(0x0002_0192)];
const V1008: [EntryDesc; 1] = [EntryDesc::text(
    0,
    "Device name",
    28,
    "ECS-HS EtherCAT hybrid servo",
)];
const V2000: [EntryDesc; 1] =
    [
        EntryDesc::new(0, "Limit <min> & \"max\"", DataType::Integer16, Access::RW)
            .default(-2)
            .range(-100, 100),
    ];
const V6040: [EntryDesc; 1] = [
    EntryDesc::new(0, "Controlword", DataType::Unsigned16, Access::RW)
        .pdo(PdoMappable::Rx)
        .default(0),
];
const V6041: [EntryDesc; 1] =
    [EntryDesc::new(0, "Statusword", DataType::Unsigned16, Access::RO).pdo(PdoMappable::Tx)];
const V607A: [EntryDesc; 1] =
    [EntryDesc::new(0, "Target position", DataType::Integer32, Access::RW).pdo(PdoMappable::Rx)];

const fn obj(
    index: u16,
    name: &'static str,
    code: ObjectCode,
    entries: &'static [EntryDesc],
) -> ObjectDesc {
    ObjectDesc::new(index, name, code, entries, "")
}

static OBJECTS: &[Object] = ecat_slave_stack::packed_dictionary!(&[&SOURCE]);
const SOURCE: [ObjectDesc; 10] = [
    obj(0x1000, "Device type", ObjectCode::Var, &V1000),
    obj(0x1008, "Device name", ObjectCode::Var, &V1008),
    obj(0x1018, "Identity", ObjectCode::Record, &RECORD_1018),
    obj(0x1600, "RxPDO 1", ObjectCode::Record, &MAP_1600),
    obj(0x1A00, "TxPDO 1", ObjectCode::Record, &MAP_1A00),
    obj(0x1C12, "RxPDO assign", ObjectCode::Array, &ARR_1C12),
    obj(0x2000, "Vendor & <test>", ObjectCode::Var, &V2000),
    obj(0x6040, "Controlword", ObjectCode::Var, &V6040),
    obj(0x6041, "Statusword", ObjectCode::Var, &V6041),
    obj(0x607A, "Target position", ObjectCode::Var, &V607A),
];

static RX1: [u32; 2] = [
    ObjectKey::new(0x6040, 0).mapping_word(16),
    ObjectKey::new(0, 0).mapping_word(16),
];
static TX1: [u32; 1] = [ObjectKey::new(0x6041, 0).mapping_word(16)];
static PDOS: [PdoMap; 2] = [
    PdoMap {
        index: 0x1600,
        name: Name::plain("RxPDO 1"),
        sm: Some(2),
        fixed: false,
        mandatory: false,
        entries: &RX1,
    },
    PdoMap {
        index: 0x1A00,
        name: Name::plain("TxPDO 1"),
        sm: Some(3),
        fixed: false,
        mandatory: false,
        entries: &TX1,
    },
];

const DESC: DeviceDescription = DeviceDescription {
    vendor_id: 0x0000_0E5C,
    vendor_name: "Open drives & co",
    product_code: 0x0000_5840,
    revision: 0x0001_0000,
    serial: 0x1234_5678,
    type_name: "ECS-HS",
    name: "ECS-HS EtherCAT hybrid servo",
    group_type: "Drives",
    group_name: "Drives",
    hardware_version: "1.0",
    software_version: "0.1.0",
    esc: EscFlavour::Lan9252,
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
};

struct Buf<const N: usize> {
    b: [u8; N],
    n: usize,
}

impl<const N: usize> Buf<N> {
    fn new() -> Self {
        Buf { b: [0; N], n: 0 }
    }
    fn as_str(&self) -> &str {
        core::str::from_utf8(&self.b[..self.n]).unwrap()
    }
}

impl<const N: usize> Write for Buf<N> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        let end = self.n + s.len();
        if end > N {
            return Err(core::fmt::Error);
        }
        self.b[self.n..end].copy_from_slice(s.as_bytes());
        self.n = end;
        Ok(())
    }
}

/// Checks that tags nest, names match, and every `&` starts one of the 5 entities.
fn xml_well_formed(s: &str) -> bool {
    let mut stack: [&str; 32] = [""; 32];
    let mut depth = 0usize;
    let bytes = s.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'&' => {
                let rest = &s[i..];
                if !["&amp;", "&lt;", "&gt;", "&quot;", "&apos;"]
                    .iter()
                    .any(|e| rest.starts_with(e))
                {
                    return false;
                }
                i += 1;
            }
            b'>' => return false,
            b'<' => {
                let Some(len) = s[i..].find('>') else {
                    return false;
                };
                let tag = &s[i + 1..i + len];
                i += len + 1;
                if tag.starts_with('?') {
                    continue;
                }
                if let Some(name) = tag.strip_prefix('/') {
                    if depth == 0 || stack[depth - 1] != name {
                        return false;
                    }
                    depth -= 1;
                } else if !tag.ends_with('/') {
                    let name = tag.split(' ').next().unwrap_or("");
                    if depth == stack.len() || name.is_empty() {
                        return false;
                    }
                    stack[depth] = name;
                    depth += 1;
                }
            }
            _ => i += 1,
        }
    }
    depth == 0
}

fn lcg(seed: &mut u32) -> u32 {
    *seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
    *seed >> 8
}

qemu_runner::tests! {
    // ------------------------------------------------------------- drivers

    fn lan9252_absent_chip_is_not_detected_after_bounded_polls() {
        let mut spi = FakeLan::new();
        spi.absent = true;
        let cfg = Lan9252Config { startup_polls: 7, ..Lan9252Config::default() };
        let mut d = Lan9252::new(spi, cfg);
        let mut delay = CountDelay(0);
        assert_eq!(d.init(&mut delay), Err(EscError::NotDetected));
        assert_eq!(d.spi_mut().transactions, 7);
        assert_eq!(delay.0, 6);
    }

    fn lan9252_wrong_byte_test_is_not_detected() {
        let mut spi = FakeLan::new();
        spi.byte_test = 0x2143_6587; // byte-swapped bus
        let mut d = Lan9252::new(spi, Lan9252Config { startup_polls: 3, ..Lan9252Config::default() });
        assert_eq!(d.init(&mut CountDelay(0)), Err(EscError::NotDetected));
        assert_eq!(d.spi_mut().transactions, 3);
    }

    fn lan9252_never_ready_times_out() {
        let mut spi = FakeLan::new();
        spi.hw_cfg = 0;
        let mut d = Lan9252::new(spi, Lan9252Config { startup_polls: 5, ..Lan9252Config::default() });
        assert_eq!(d.init(&mut CountDelay(0)), Err(EscError::Timeout));
        assert_eq!(d.spi_mut().transactions, 1 + 5);
    }

    fn lan9252_stuck_csr_busy_times_out_bounded() {
        let mut spi = FakeLan::new();
        spi.csr_cmd = lan9252::CSR_BUSY;
        let cfg = Lan9252Config { max_polls: 9, reset: lan9252::ResetKind::None, ..Lan9252Config::default() };
        let mut d = Lan9252::new(spi, cfg);
        d.init(&mut CountDelay(0)).unwrap();
        let before = d.spi_mut().transactions;
        assert_eq!(d.read_u16(0x0130), Err(EscError::Timeout));
        // one command write + 9 polls
        assert_eq!(d.spi_mut().transactions - before, 1 + 9);
        assert_eq!(d.write_u8(0x0120, 1), Err(EscError::Timeout));
    }

    fn lan9252_fifo_never_ready_times_out_bounded() {
        let spi = FakeLan::new();
        let cfg = Lan9252Config { max_polls: 4, reset: lan9252::ResetKind::None, ..Lan9252Config::default() };
        let mut d = Lan9252::new(spi, cfg);
        d.init(&mut CountDelay(0)).unwrap();
        let before = d.spi_mut().transactions;
        let mut b = [0u8; 8];
        assert_eq!(d.read(0x1100, &mut b), Err(EscError::Timeout));
        // abort + abort poll, addr/len, start, 4 polls
        assert_eq!(d.spi_mut().transactions - before, 2 + 2 + 4);
        assert_eq!(d.write(0x1100, &b), Err(EscError::Timeout));
    }

    fn lan9252_bus_error_and_out_of_range() {
        let mut spi = FakeLan::new();
        spi.fail = true;
        let mut d = Lan9252::new(spi, Lan9252Config::default());
        assert_eq!(d.init(&mut CountDelay(0)), Err(EscError::Bus));
        let mut b = [0u8; 2];
        let before = d.spi_mut().transactions;
        assert_eq!(d.read(0x1FFF, &mut b), Err(EscError::OutOfRange));
        assert_eq!(d.write(0xFFFF, &b), Err(EscError::OutOfRange));
        assert_eq!(d.spi_mut().transactions, before);
        assert_eq!(d.read(0x0000, &mut []), Ok(()));
    }

    fn et1100_absent_chip_is_not_detected() {
        for miso in [0xFF, 0x00] {
            let spi = StuckSpi { miso, transactions: 0 };
            let cfg = Et1100Config { startup_polls: 4, expected_type: None, ..Et1100Config::default() };
            let mut d = Et1100::new(spi, cfg);
            assert_eq!(d.init(&mut CountDelay(0)), Err(EscError::NotDetected));
            assert_eq!(d.spi_mut().transactions, 4);
        }
    }

    fn et1100_pdi_never_operational_times_out() {
        // Every byte reads 0x11: ESC type OK, but DL status 0x1111 has bit 0 set, so use 0x10.
        let spi = StuckSpi { miso: 0x10, transactions: 0 };
        let cfg = Et1100Config { startup_polls: 3, expected_type: Some(0x10), ..Et1100Config::default() };
        let mut d = Et1100::new(spi, cfg);
        assert_eq!(d.init(&mut CountDelay(0)), Err(EscError::Timeout));
        assert_eq!(d.spi_mut().transactions, 1 + 3);
        let spi = StuckSpi { miso: 0x11, transactions: 0 };
        let mut d = Et1100::new(spi, Et1100Config::default());
        assert_eq!(d.init(&mut CountDelay(0)), Ok(()));
    }

    fn et1100_address_phase_encoding() {
        assert_eq!(et1100::address_phase(0x0130, et1100::cmd::READ_WAIT, false), ([0x09, 0x83, 0], 2));
        assert_eq!(et1100::address_phase(0x1FFF, et1100::cmd::WRITE, false), ([0xFF, 0xFC, 0], 2));
        assert_eq!(et1100::address_phase(0x0000, et1100::cmd::NOP, false), ([0, 0, 0], 2));
        // 0x2F00: A12..A5 = 0x78, A4..A0 = 0, A15..A13 = 1
        assert_eq!(et1100::address_phase(0x2F00, et1100::cmd::READ, false), ([0x78, 0x06, 0x28], 3));
        assert_eq!(et1100::address_phase(0x0130, et1100::cmd::WRITE, true), ([0x09, 0x86, 0x10], 3));
        assert_eq!(et1100::address_phase(0xFFFF, et1100::cmd::READ_WAIT, true), ([0xFF, 0xFE, 0xEC], 3));
    }

    fn et1100_out_of_range_never_touches_the_bus() {
        let mut d = Et1100::new(StuckSpi { miso: 0, transactions: 0 }, Et1100Config::default());
        let mut b = [0u8; 4];
        assert_eq!(d.read(0x2FFE, &mut b), Err(EscError::OutOfRange));
        assert_eq!(d.write(0xFFFF, &b), Err(EscError::OutOfRange));
        assert_eq!(d.spi_mut().transactions, 0);
    }

    fn drivers_survive_noise_on_miso() {
        let mut buf = [0u8; 80];
        let cfg = Lan9252Config { max_polls: 8, startup_polls: 3, ..Lan9252Config::default() };
        let mut lan = Lan9252::new(NoiseSpi { seed: 1, transactions: 0 }, cfg);
        let _ = lan.init(&mut CountDelay(0));
        let mut et = Et1100::new(NoiseSpi { seed: 2, transactions: 0 }, Et1100Config::default());
        let _ = et.init(&mut CountDelay(0));
        let mut seed = 3u32;
        for _ in 0..200 {
            let addr = (lcg(&mut seed) % 0x3100) as u16;
            let len = (lcg(&mut seed) % 80) as usize;
            let before = lan.spi_mut().transactions;
            let _ = lan.read(addr, &mut buf[..len]);
            let _ = lan.write(addr, &buf[..len]);
            let _ = lan.al_event();
            // Worst case per call: every FIFO word costs a poll budget and a burst.
            assert!(lan.spi_mut().transactions - before < 3 * (4 + 80 * 9));
            let _ = et.read(addr, &mut buf[..len]);
            let _ = et.write(addr, &buf[..len]);
            let _ = et.al_event();
        }
    }

    // ------------------------------------------------------------- SII

    fn crc8_matches_reference_vectors() {
        let mut a = [0u8; 14];
        a[..4].copy_from_slice(&[0x08, 0x0E, 0x02, 0x88]);
        assert_eq!(sii::crc8(&a), 0x2F);
        let mut b = [0u8; 14];
        b[..4].copy_from_slice(&[0x80, 0x06, 0x81, 0x06]);
        assert_eq!(sii::crc8(&b), 0xCD);
    }

    fn sii_image_parses_back_field_by_field() {
        let mut img = [0xFFu8; 2048];
        let n = sii::build(&DESC, &mut img).unwrap();
        assert!(n.is_multiple_of(2) && n <= 2048 && n > 0x80);
        let s = Sii::new(&img[..n]);
        assert!(s.checksum_ok());
        assert_eq!(s.word(0), Some(0x0C80));
        assert_eq!(s.word(1), Some(0x0E00));
        assert_eq!(s.word(2), Some(1000));
        assert_eq!(s.word(3), Some(0));
        assert_eq!(s.word(4), Some(0));
        assert_eq!(s.word(7).map(|w| w >> 8), Some(0));
        assert_eq!(s.vendor_id(), Some(0x0E5C));
        assert_eq!(s.product_code(), Some(0x5840));
        assert_eq!(s.revision(), Some(0x0001_0000));
        assert_eq!(s.serial(), Some(0x1234_5678));
        for w in 0x10..0x18 {
            assert_eq!(s.word(w), Some(0), "word {w:#x}");
        }
        assert_eq!(s.word(0x18), Some(0x1000));
        assert_eq!(s.word(0x19), Some(128));
        assert_eq!(s.word(0x1A), Some(0x1080));
        assert_eq!(s.word(0x1B), Some(128));
        assert_eq!(s.word(0x1C), Some(0x0004));
        for w in 0x1D..0x3E {
            assert_eq!(s.word(w), Some(0), "word {w:#x}");
        }
        assert_eq!(s.word(0x3E), Some(15));
        assert_eq!(s.word(0x3F), Some(1));
        // categories, in order, then the end marker right at the end of the image
        let mut kinds = [0u16; 8];
        let mut k = 0;
        for c in s.categories() {
            kinds[k] = c.kind;
            k += 1;
        }
        assert_eq!(&kinds[..k], &[10, 30, 40, 41, 60]);
        assert_eq!(s.word(n / 2 - 1), Some(0xFFFF));
        // general
        let g = s.general().unwrap();
        assert_eq!(s.string(g.name), Some(DESC.name));
        assert_eq!(s.string(g.order), Some("ECS-HS"));
        assert_eq!(s.string(g.group), Some("Drives"));
        assert_eq!(g.group2, g.group);
        assert_eq!(g.image, 0);
        assert_eq!(g.coe_details, 0x2F);
        assert_eq!(g.foe_details, 0);
        assert_eq!(g.eoe_details, 0);
        assert_eq!(g.flags, 0x04);
        assert_eq!(g.ebus_current_ma, 0);
        assert_eq!(g.physical_ports, 0x0011);
        assert_eq!(s.string(0), None);
        assert_eq!(s.string(s.string_count() + 1), None);
        // FMMU: outputs, inputs, mailbox state, pad
        assert_eq!(s.fmmus(), &[1, 2, 3, 0]);
        // SyncManagers
        assert_eq!(s.sync_manager_count(), 4);
        for (i, sm) in DESC.sync_managers.iter().enumerate() {
            let r = s.sync_manager(i).unwrap();
            assert_eq!((r.start, r.length, r.control, r.status, r.enable, r.kind),
                (sm.start, sm.default_size, sm.control, 0, 1, sm.kind as u8));
        }
        assert_eq!(s.sync_manager(0).unwrap().kind, SmType::MailboxOut as u8);
        assert_eq!(s.sync_manager(4), None);
        // DC
        assert_eq!(s.dc_op_mode_count(), 2);
        let dc = s.dc_op_mode(1).unwrap();
        assert_eq!(dc.assign_activate, 0x0300);
        assert_eq!(dc.sync0_factor, 1);
        assert_eq!((dc.cycle_time_sync0, dc.shift_time_sync0, dc.shift_time_sync1, dc.sync1_factor), (0, 0, 0, 0));
        assert_eq!(s.string(dc.name), Some("DC"));
        assert_eq!(s.string(dc.description), Some("DC-Synchron"));
        assert_eq!(s.dc_op_mode(0).unwrap().assign_activate, 0);
        assert_eq!(s.dc_op_mode(2), None);
        // versions are in the string table
        let mut found = 0;
        for i in 1..=s.string_count() {
            if matches!(s.string(i), Some("1.0") | Some("0.1.0")) {
                found += 1;
            }
        }
        assert_eq!(found, 2);
    }

    fn sii_et1100_flavour_config_words() {
        let d = DeviceDescription { esc: EscFlavour::Et1100, station_alias: 0x1234, ..DESC };
        let mut img = [0u8; 2048];
        let n = sii::build(&d, &mut img).unwrap();
        let s = Sii::new(&img[..n]);
        assert!(s.checksum_ok());
        assert_eq!(s.word(0), Some(0x0C05));
        assert_eq!(s.word(1), Some(0x0E03));
        assert_eq!(s.word(4), Some(0x1234));
        assert_eq!(&img[..16], &d.config_area());
    }

    fn sii_checksum_detects_any_config_byte_change() {
        let mut img = [0u8; 2048];
        let n = sii::build(&DESC, &mut img).unwrap();
        for i in 0..14 {
            let mut c = img;
            c[i] ^= 0x01;
            assert!(!Sii::new(&c[..n]).checksum_ok(), "byte {i}");
        }
    }

    fn sii_build_rejects_bad_descriptions_and_small_buffers() {
        let mut img = [0u8; 2048];
        let n = sii::build(&DESC, &mut img).unwrap();
        for len in 0..n {
            let mut small = [0u8; 2048];
            assert_eq!(sii::build(&DESC, &mut small[..len]), Err(SiiError::BufferTooSmall), "len {len}");
        }
        let d = DeviceDescription { eeprom_bytes: 256, ..DESC };
        assert_eq!(sii::build(&d, &mut img), Err(SiiError::EepromTooSmall));
        let d = DeviceDescription { eeprom_bytes: 1000, ..DESC };
        assert_eq!(sii::build(&d, &mut img), Err(SiiError::InvalidDescription));
        let d = DeviceDescription { sync_managers: &sii::STANDARD_SYNC_MANAGERS[1..], ..DESC };
        assert_eq!(sii::build(&d, &mut img), Err(SiiError::MissingMailbox));
        let d = DeviceDescription { mailbox_protocols: 0x0040 | sii::MBOX_COE, ..DESC };
        assert_eq!(sii::build(&d, &mut img), Err(SiiError::InvalidDescription));
        let long = "this name is much longer than two hundred and fifty-five bytes ..........................................................................................................................................................................................................";
        assert!(long.len() > 255);
        let d = DeviceDescription { name: long, ..DESC };
        assert_eq!(sii::build(&d, &mut img), Err(SiiError::StringTable));
    }

    fn sii_view_survives_garbage() {
        let mut seed = 7u32;
        let mut buf = [0u8; 512];
        for round in 0..200 {
            for b in buf.iter_mut() {
                *b = lcg(&mut seed) as u8;
            }
            // sometimes a plausible category header with a huge size
            if round % 3 == 0 {
                buf[0x80..0x84].copy_from_slice(&[10, 0, 0xFF, 0x7F]);
            }
            let len = (lcg(&mut seed) as usize) % buf.len();
            let s = Sii::new(&buf[..len]);
            let _ = s.checksum_ok();
            let _ = (s.vendor_id(), s.product_code(), s.general(), s.fmmus(), s.string_count());
            for i in 0..=255u8 {
                let _ = s.string(i);
            }
            assert!(s.categories().count() <= len / 4 + 1);
            let _ = (s.sync_manager(usize::MAX), s.dc_op_mode(usize::MAX / 8), s.word(usize::MAX));
        }
        assert_eq!(Sii::new(&[]).vendor_id(), None);
        assert!(!Sii::new(&[1, 2, 3]).checksum_ok());
    }

    // ------------------------------------------------------------- ESI

    fn esi_is_well_formed_and_lists_every_object() {
        let mut out = Buf::<32768>::new();
        esi::write(&DESC, OBJECTS, &PDOS, &mut out).unwrap();
        let x = out.as_str();
        assert!(xml_well_formed(x), "{x}");
        assert_eq!(x.matches("<Object>").count(), OBJECTS.len());
        for o in OBJECTS.iter() {
            let mut tag = Buf::<32>::new();
            write!(tag, "<Index>#x{:04X}</Index>", o.index).unwrap();
            assert!(x.contains(tag.as_str()), "object {:04X}", o.index);
        }
        assert!(x.contains("<Name>Vendor &amp; &lt;test&gt;</Name>"));
        assert!(x.contains("<Name>Serial &quot;number&quot; &lt;sn&gt; &amp; co</Name>"));
        assert!(x.contains("<Id>#x00000E5C</Id>"));
        assert!(x.contains("ProductCode=\"#x00005840\" RevisionNo=\"#x00010000\""));
        assert!(x.contains("<ProfileNo>402</ProfileNo>"));
        assert!(x.contains("<CoE SdoInfo=\"true\" PdoAssign=\"true\" PdoConfig=\"true\" PdoUpload=\"false\" CompleteAccess=\"true\"/>"));
        assert!(x.contains("<AssignActivate>#x300</AssignActivate>"));
        assert!(x.contains("<ConfigData>800C000EE8030000000000000000</ConfigData>"));
        assert!(x.contains("<ByteSize>2048</ByteSize>"));
        assert!(x.contains("StartAddress=\"#x1000\" ControlByte=\"#x26\" Enable=\"1\">MBoxOut</Sm>"));
        assert!(x.contains("<RxPdo Sm=\"2\"><Index>#x1600</Index>"));
        assert!(x.contains("<Entry><Index>#x6040</Index><SubIndex>0</SubIndex><BitLen>16</BitLen><Name>Controlword</Name><DataType>UINT</DataType></Entry>"));
        assert!(x.contains("<DefaultData>FEFF</DefaultData>")); // INT16 -2
        assert!(x.contains("<DefaultData>92010200</DefaultData>"));
        assert!(x.contains("<DefaultString>ECS-HS EtherCAT hybrid servo</DefaultString>"));
        assert!(x.contains("<Name>DT1018</Name><BitSize>144</BitSize>"));
        assert!(x.contains("<Access WriteRestrictions=\"PreOP\">rw</Access>"));
        assert!(x.contains("<PdoMapping>R</PdoMapping>"));
        assert!(x.contains("Physics=\"YY\""));
    }

    fn esi_rejects_inconsistent_pdo_maps() {
        let mut out = Buf::<32768>::new();
        static BAD_ENTRY: [u32; 1] = [PdoEntry { key: ObjectKey::new(0x6099, 0), bits: 16 }.encode()];
        static WRONG_DIR: [u32; 1] = [ObjectKey::new(0x6041, 0).mapping_word(16)];
        static WRONG_BITS: [u32; 1] = [ObjectKey::new(0x6040, 0).mapping_word(32)];
        let p = |index, sm, entries| [PdoMap { index, name: Name::plain("x"), sm, fixed: false, mandatory: false, entries }];
        assert_eq!(esi::write(&DESC, OBJECTS, &p(0x1600, Some(2), &BAD_ENTRY), &mut out),
            Err(EsiError::UnknownEntry { pdo: 0x1600, key: ObjectKey::new(0x6099, 0) }));
        assert_eq!(esi::write(&DESC, OBJECTS, &p(0x1600, Some(2), &WRONG_DIR), &mut out),
            Err(EsiError::NotMappable { pdo: 0x1600, key: ObjectKey::new(0x6041, 0) }));
        assert_eq!(esi::write(&DESC, OBJECTS, &p(0x1600, Some(2), &WRONG_BITS), &mut out),
            Err(EsiError::BitLength { pdo: 0x1600, key: ObjectKey::new(0x6040, 0) }));
        assert_eq!(esi::write(&DESC, OBJECTS, &p(0x1600, Some(3), &RX1), &mut out),
            Err(EsiError::PdoSyncManager(0x1600)));
        assert_eq!(esi::write(&DESC, OBJECTS, &p(0x1234, None, &RX1), &mut out), Err(EsiError::PdoIndex(0x1234)));
        let unsorted = [OBJECTS[1], OBJECTS[0]];
        assert_eq!(esi::write(&DESC, &unsorted, &[], &mut out), Err(EsiError::ObjectsNotWellFormed));
        let mut small = Buf::<512>::new();
        assert_eq!(esi::write(&DESC, OBJECTS, &PDOS, &mut small), Err(EsiError::Fmt));
        assert_eq!(out.n, 0, "nothing written before validation failed");
    }

    fn esi_config_data_is_the_sii_config_area() {
        let mut img = [0u8; 2048];
        sii::build(&DESC, &mut img).unwrap();
        let mut out = Buf::<32768>::new();
        esi::write(&DESC, OBJECTS, &PDOS, &mut out).unwrap();
        let x = out.as_str();
        let start = x.find("<ConfigData>").unwrap() + "<ConfigData>".len();
        let hex = &x[start..start + 28];
        for i in 0..14 {
            let b = u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).unwrap();
            assert_eq!(b, img[i], "byte {i}");
        }
        assert_eq!(&x[start + 28..start + 41], "</ConfigData>");
    }

    fn esi_pdo_maps_from_the_stack_defaults() {
        static RXD: [u32; 1] = [ObjectKey::new(0x6040, 0).mapping_word(16)];
        static TXD: [u32; 1] = [ObjectKey::new(0x6041, 0).mapping_word(16)];
        static RXA: [u16; 1] = [0x1600];
        static TXA: [u16; 1] = [0x1A00];
        let defaults = pdo::PdoDefaults {
            rx: [&RXD, &[], &RXD, &[]],
            tx: [&TXD, &[], &[], &[]],
            rx_assign: &RXA,
            tx_assign: &TXA,
        };
        let maps = esi::pdo_maps(&DESC, OBJECTS, &defaults);
        assert_eq!(maps.len(), 3);
        assert_eq!((maps[0].index, maps[0].sm), (0x1600, Some(2)));
        assert_eq!(maps[0].name, "RxPDO 1");
        assert_eq!((maps[1].index, maps[1].sm), (0x1602, None));
        assert_eq!(maps[1].name, "RxPDO");
        assert_eq!((maps[2].index, maps[2].sm), (0x1A00, Some(3)));
        assert_eq!(maps[2].name, "TxPDO 1");
        assert_eq!(PdoEntry::decode(maps[2].entries[0]), PdoEntry { key: ObjectKey::new(0x6041, 0), bits: 16 });
        let mut out = Buf::<32768>::new();
        esi::write(&DESC, OBJECTS, &maps, &mut out).unwrap();
        let x = out.as_str();
        // Not assigned by default: no Sm (ETG.2000: Sm is the default assignment), and
        // it maps 0x6040 as 0x1600 does, so the two exclude each other.
        assert!(x.contains("<RxPdo Sm=\"2\"><Index>#x1600</Index><Name>RxPDO 1</Name>\n<Exclude>#x1602</Exclude>"));
        assert!(x.contains("<RxPdo><Index>#x1602</Index><Name>RxPDO</Name>\n<Exclude>#x1600</Exclude>"));
        assert!(x.contains("<TxPdo Sm=\"3\"><Index>#x1A00</Index>"));
    }

    fn sii_pdo_categories_byte_by_byte() {
        static RX2: [u32; 1] = [ObjectKey::new(0x607A, 0).mapping_word(32)];
        let mut maps = [PDOS[0], PDOS[1], PDOS[0]];
        maps[2] = PdoMap { index: 0x1601, name: Name::plain("RxPDO 2"), sm: None, fixed: true, mandatory: true, entries: &RX2 };
        let mut img = [0xFFu8; 2048];
        let n = sii::build_with_pdos(&DESC, OBJECTS, &maps, &mut img).unwrap();
        let view = sii::Sii::new(&img[..n]);
        let cat = |kind: u16| view.categories().find(|c| c.kind == kind).map(|c| c.data);
        let st = |s: &str| (1..=view.string_count()).find(|i| view.string(*i) == Some(s)).unwrap();
        // TxPDO (0x32): 0x1A00, 1 entry, SM 3, name; 6041:00 "Statusword" UINT 16.
        let tx = cat(sii::category::TXPDO).unwrap();
        assert_eq!(tx.len(), 16);
        assert_eq!(tx[..8], [0x00, 0x1A, 1, 3, 0, st("TxPDO 1"), 0, 0]);
        assert_eq!(tx[8..], [0x41, 0x60, 0, st("Statusword"), 0x06, 16, 0, 0]);
        // RxPDO (0x33): 0x1600 (SM 2; a 16-bit gap without name or type), then
        // 0x1601 not assigned (SM 0xFF), mandatory and fixed (flags 0x0011).
        let rx = cat(sii::category::RXPDO).unwrap();
        assert_eq!(rx.len(), 8 + 16 + 8 + 8);
        assert_eq!(rx[..8], [0x00, 0x16, 2, 2, 0, st("RxPDO 1"), 0, 0]);
        assert_eq!(rx[8..16], [0x40, 0x60, 0, st("Controlword"), 0x06, 16, 0, 0]);
        assert_eq!(rx[16..24], [0, 0, 0, 0, 0, 16, 0, 0]);
        assert_eq!(rx[24..32], [0x01, 0x16, 1, 0xFF, 0, st("RxPDO 2"), 0x11, 0]);
        assert_eq!(rx[32..], [0x7A, 0x60, 0, st("Target position"), 0x04, 32, 0, 0]);
        // Order string = type name; without PDOs no PDO category.
        let g = cat(sii::category::GENERAL).unwrap();
        assert_eq!(view.string(g[2]), Some(DESC.type_name));
        let n = sii::build(&DESC, &mut img).unwrap();
        let view = sii::Sii::new(&img[..n]);
        assert!(view.categories().all(|c| c.kind != sii::category::TXPDO && c.kind != sii::category::RXPDO));
    }

    // ------------------------------------------------------------- LEDs

    fn led_patterns_follow_exact_timelines() {
        // (pattern, period, on-intervals within the period)
        type Case = (Pattern, u32, &'static [(u32, u32)]);
        let cases: [Case; 4] = [
            (Pattern::Flickering, 100, &[(0, 50)]),
            (Pattern::Blinking, 400, &[(0, 200)]),
            (Pattern::SingleFlash, 1200, &[(0, 200)]),
            (Pattern::DoubleFlash, 1600, &[(0, 200), (400, 600)]),
        ];
        for (p, period, on) in cases {
            assert_eq!(p.period_ms(), period);
            let start = 12_345;
            let mut ind = Indicator::new();
            ind.set(p, start);
            for t in 0..3 * period {
                let phase = t % period;
                let want = on.iter().any(|&(a, b)| phase >= a && phase < b);
                assert_eq!(ind.level(start + t), want, "{p:?} at {t} ms");
            }
        }
        for t in [0, 1, 999, 1_000_000] {
            assert!(!Pattern::Off.level_at(t));
            assert!(Pattern::On.level_at(t));
        }
    }

    fn led_double_flash_edges() {
        let mut ind = Indicator::new();
        ind.set(Pattern::DoubleFlash, 0);
        // transitions: on at 0, off at 200, on at 400, off at 600, on at 1600
        let mut edges = [0u32; 8];
        let mut n = 0;
        let mut last = ind.level(0);
        for t in 1..3200 {
            let l = ind.level(t);
            if l != last {
                edges[n] = t;
                n += 1;
                last = l;
            }
        }
        assert_eq!(&edges[..n], &[200, 400, 600, 1600, 1800, 2000, 2200]);
    }

    fn led_phase_restarts_only_on_change_and_survives_wrap() {
        let mut ind = Indicator::new();
        ind.set(Pattern::Blinking, 1000);
        assert!(ind.level(1000));
        assert!(!ind.level(1250));
        ind.set(Pattern::Blinking, 1250); // same pattern: keeps its phase
        assert!(!ind.level(1250));
        ind.set(Pattern::SingleFlash, 1250); // new pattern starts "on"
        assert!(ind.level(1250));
        assert!(ind.level(1449));
        assert!(!ind.level(1450));
        let mut w = Indicator::new();
        w.set(Pattern::Blinking, u32::MAX - 100);
        assert!(w.level(50)); // 151 ms after start
        assert!(!w.level(150)); // 251 ms
    }

    fn led_run_and_err_mapping() {
        assert_eq!(leds::run_pattern(EsmState::Init), Pattern::Off);
        assert_eq!(leds::run_pattern(EsmState::PreOp), Pattern::Blinking);
        assert_eq!(leds::run_pattern(EsmState::SafeOp), Pattern::SingleFlash);
        assert_eq!(leds::run_pattern(EsmState::Op), Pattern::On);
        assert_eq!(leds::run_pattern(EsmState::Bootstrap), Pattern::Flickering);
        assert_eq!(ErrCondition::None.pattern(), Pattern::Off);
        assert_eq!(ErrCondition::InvalidConfiguration.pattern(), Pattern::Blinking);
        assert_eq!(ErrCondition::LocalError.pattern(), Pattern::SingleFlash);
        assert_eq!(ErrCondition::WatchdogTimeout.pattern(), Pattern::DoubleFlash);
        assert_eq!(ErrCondition::BootingError.pattern(), Pattern::Flickering);
        assert_eq!(ErrCondition::PdiWatchdog.pattern(), Pattern::On);
        assert_eq!(ErrCondition::from_al_status(0x04, 0x001B), ErrCondition::None);
        assert_eq!(ErrCondition::from_al_status(0x14, 0x0000), ErrCondition::None);
        assert_eq!(ErrCondition::from_al_status(0x14, 0x001B), ErrCondition::WatchdogTimeout);
        assert_eq!(ErrCondition::from_al_status(0x14, 0x001A), ErrCondition::LocalError);
        assert_eq!(ErrCondition::from_al_status(0x14, 0x002D), ErrCondition::LocalError);
        assert_eq!(ErrCondition::from_al_status(0x14, 0x0032), ErrCondition::LocalError);
        // Every other state change the slave makes by itself is a local error too.
        for code in [0x002A, 0x0033, 0x0034, 0x0052, 0x0060, 0x0080, 0x0081] {
            assert_eq!(ErrCondition::from_al_status(0x12, code), ErrCondition::LocalError, "{code:#06x}");
        }
        // Refused requests: invalid configuration (blinking).
        for code in [0x0011, 0x0017, 0x001D, 0x001E, 0x0024, 0x0025, 0x0028, 0x0030, 0x0035] {
            assert_eq!(ErrCondition::from_al_status(0x12, code), ErrCondition::InvalidConfiguration, "{code:#06x}");
            assert_eq!(ErrCondition::from_al_status(0x12, code).pattern(), Pattern::Blinking);
        }
        assert_eq!(ErrCondition::from_al_status(0x11, 0x0051), ErrCondition::BootingError);
        assert_eq!(ErrCondition::from_al_status(0x12, 0x0011), ErrCondition::InvalidConfiguration);
        assert_eq!(ErrCondition::from_al_status(0x12, 0xFFFF), ErrCondition::InvalidConfiguration);
        assert_eq!(Pattern::Off.override_code(), 0x10);
        assert_eq!(Pattern::SingleFlash.override_code(), 0x11);
        assert_eq!(Pattern::DoubleFlash.override_code(), 0x12);
        assert_eq!(Pattern::Blinking.override_code(), 0x1D);
        assert_eq!(Pattern::Flickering.override_code(), 0x1E);
        assert_eq!(Pattern::On.override_code(), 0x1F);
        let mut s = StatusLeds::new();
        s.update(EsmState::SafeOp, ErrCondition::WatchdogTimeout, 500);
        assert_eq!(s.levels(500), (true, true));
        assert_eq!(s.levels(700), (false, false));
        assert_eq!(s.levels(900), (false, true));
        assert_eq!(s.levels(1700), (true, false));
        assert_eq!(s.levels(2100), (false, true));
    }
}
