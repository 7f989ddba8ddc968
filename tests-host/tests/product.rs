//! Product features end to end on the host: vendor parameters through real SDO frames
//! (the stack's `MailboxServer`), store / restore with the real PDO mapping objects
//! and a simulated power cycle, flash failures, and every fault from detection to
//! emergency frame, LED timeline, PDS request, alarm output and recovery.

use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::mailbox::MailboxServer;
use ecat_slave_stack::od::{self, Dictionary, Object, ObjectDesc, ObjectKey, SdoAbort};
use ecat_slave_stack::pdo::{self, PdoConfig, PdoDefaults};
use firmware::comm::{self, Comm, LOAD, SAVE};
use firmware::dictionary::Sdo;
use firmware::fault_led::FaultLed;
use firmware::faults::{FaultKind, Faults, Snapshot};
use firmware::identity::{Identity, Variant};
use firmware::io::{self, Inputs, OutputStatus};
use firmware::monitor::{self, Monitor};
use firmware::params::{self, Params, P};
use firmware::storage::{RamFlash, Storage, StorageError};

// ---- the drive under test ---------------------------------------------------------

const PARTS: &[&[ObjectDesc]] = &[
    comm::OBJECTS,
    pdo::OBJECTS,
    params::OBJECTS,
    monitor::OBJECTS,
    firmware::dictionary::fault_history::OBJECTS,
];

fn all_objects() -> &'static [Object] {
    static ALL: &[Object] =
        ecat_slave_stack::packed_dictionary!(PARTS, firmware::dictionary::VOCABULARY);
    ALL
}

const TX1: &[u32] = &[
    ObjectKey::new(0x1001, 0).mapping_word(8),
    ObjectKey::new(0x2155, 0).mapping_word(8),
];
const DEFAULTS: PdoDefaults = PdoDefaults {
    rx: [&[], &[], &[], &[]],
    tx: [TX1, &[], &[], &[]],
    rx_assign: &[],
    tx_assign: &[0x1A00],
};

type Flash = RamFlash<4096>;
const STORE: Storage = Storage::new(0, 2048);

struct Drive {
    comm: Comm,
    pdo: PdoConfig,
    params: Params,
    faults: Faults,
    monitor: Monitor,
    inputs: Inputs,
    led: FaultLed,
    flash: Flash,
    mbx: MailboxServer,
    pds_fault: bool,
    now_ms: u32,
    /// Mailbox counter of the last request (1..7).
    counter: u8,
}

impl Drive {
    /// Power-up: defaults, then the stored record, then the power-up latches.
    fn power_up(flash: Flash) -> (Drive, firmware::storage::LoadReport) {
        let mut d = Drive {
            comm: Comm::new(Identity::new(Variant::HybridServo, 1)),
            pdo: PdoConfig::new(DEFAULTS),
            params: Params::new(Variant::HybridServo),
            faults: Faults::default(),
            monitor: Monitor::new(),
            inputs: Inputs::new(),
            led: FaultLed::new(),
            flash,
            mbx: MailboxServer::new(128),
            pds_fault: false,
            now_ms: 0,
            counter: 0,
        };
        let mut flash = std::mem::take(&mut d.flash);
        let report = STORE.load(&mut flash, &mut d);
        d.flash = flash;
        d.params.latch_power_up();
        d.monitor.power_up();
        d.faults.configure_from(&d.params);
        if let Some((code, data)) = report.emergency() {
            d.mbx.emergency(code, 0x01, data);
        }
        (d, report)
    }

    fn power_cycle(self) -> Drive {
        let mut flash = self.flash;
        flash.power_on();
        Drive::power_up(flash).0
    }

    /// One 1 ms application step: inputs, faults, emergencies, PDS request, LED, outputs.
    /// Returns (red LED, output pins).
    fn step(
        &mut self,
        raw_inputs: u8,
        bus_mv: u32,
        ia_ma: i32,
        ib_ma: i32,
        following_error: i32,
    ) -> (bool, u8) {
        self.now_ms += 1;
        self.monitor.tick_ms(1);
        self.inputs.update(raw_inputs, 1000, &self.params);
        self.params.set_raw_inputs(self.inputs.raw());
        self.faults.configure_from(&self.params);
        let snap = Snapshot {
            bus_dv: (bus_mv / 100) as u16,
            ..Snapshot::default()
        };
        self.faults.check_bus_voltage(bus_mv, snap, self.now_ms);
        self.faults
            .check_phase_currents(ia_ma, ib_ma, snap, self.now_ms);
        self.faults.check_following_error(
            following_error,
            self.params.get(P::FollowingErrorLimit) as u16,
            snap,
            self.now_ms,
        );
        if self.inputs.fault_clear_edge() {
            self.faults.fault_reset();
        }
        if self.params.take_fault_history_clear() {
            self.faults.clear_history();
        }
        while let Some(e) = self.faults.pop_emergency() {
            self.mbx.emergency(e.code, e.register, e.data);
        }
        if self.faults.take_pds_fault_request() {
            self.pds_fault = true;
        }
        let led = self.led.update(self.faults.led_code(), self.now_ms);
        let status = OutputStatus {
            alarm: self.faults.alarm(),
            ready: !self.faults.any_active(),
            in_position: false,
            ..OutputStatus::default()
        };
        (led, io::output_levels(&self.params, status, (0, 0)))
    }

    fn sdo_download(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), u32> {
        let mut f = [0u8; 16];
        f[0..2].copy_from_slice(&10u16.to_le_bytes());
        f[5] = 0x03; // CoE, counter set below
        f[6..8].copy_from_slice(&(2u16 << 12).to_le_bytes()); // SDO request
        f[8] = 0x23 | ((4 - data.len() as u8) << 2);
        f[9..11].copy_from_slice(&index.to_le_bytes());
        f[11] = sub;
        f[12..12 + data.len()].copy_from_slice(data);
        self.transfer(&mut f).map(|_| ())
    }

    fn sdo_upload(&mut self, index: u16, sub: u8) -> Result<u32, u32> {
        let mut f = [0u8; 16];
        f[0..2].copy_from_slice(&10u16.to_le_bytes());
        f[5] = 0x03;
        f[6..8].copy_from_slice(&(2u16 << 12).to_le_bytes());
        f[8] = 0x40;
        f[9..11].copy_from_slice(&index.to_le_bytes());
        f[11] = sub;
        self.transfer(&mut f)
    }

    /// Sends a request, returns the expedited value or the abort code.
    fn transfer(&mut self, f: &mut [u8; 16]) -> Result<u32, u32> {
        self.counter = self.counter % 7 + 1;
        let c = self.counter;
        f[5] = 0x03 | c << 4;
        let mut mbx = std::mem::replace(&mut self.mbx, MailboxServer::new(128));
        mbx.on_request(&f[..], self, EsmState::PreOp, u64::from(self.now_ms) * 1000);
        let mut out = [0u8; 128];
        let n = mbx.next_output(&mut out, 0);
        self.mbx = mbx;
        assert!(n >= 16, "no SDO answer");
        // SDO response (3); an abort travels as an SDO request (2), as in ETG.1000.6.
        let service = u16::from_le_bytes([out[6], out[7]]) >> 12;
        assert!(
            service == 3 || (service == 2 && out[8] == 0x80),
            "SDO answer service {service}"
        );
        let cmd = out[8];
        let v = u32::from_le_bytes([out[12], out[13], out[14], out[15]]);
        match cmd {
            0x80 => Err(v),
            0x60 => Ok(0),
            c if c & 0xE3 == 0x43 => {
                let len = 4 - ((c >> 2) & 3) as usize;
                Ok(v & (u32::MAX >> (32 - 8 * len)))
            }
            c => panic!("unexpected SDO response {c:#x}"),
        }
    }

    /// Emergency frames queued in the mailbox: (code, register, data).
    fn emergencies(&mut self) -> Vec<(u16, u8, [u8; 5])> {
        let mut v = Vec::new();
        loop {
            let mut out = [0u8; 128];
            let n = self.mbx.next_output(&mut out, 0);
            if n == 0 {
                return v;
            }
            assert_eq!(
                u16::from_le_bytes([out[6], out[7]]) >> 12,
                1,
                "emergency service"
            );
            let mut data = [0u8; 5];
            data.copy_from_slice(&out[11..16]);
            v.push((u16::from_le_bytes([out[8], out[9]]), out[10], data));
        }
    }
}

impl Dictionary for Drive {
    fn objects(&self) -> &'static [Object] {
        all_objects()
    }
    fn read(&mut self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        let ObjectKey { index, sub } = key;
        match index {
            0x1000..=0x10FF => firmware::dictionary::read(&self.comm, &self.faults, key, buf),
            0x1600..=0x1C13 => self.pdo.read(key, buf),
            0x2000..=0x21FF => self.params.read(index, sub, buf),
            0x2300..=0x23FF => self.monitor.read(index, sub, buf),
            0x2400..=0x24FF => {
                firmware::dictionary::fault_history::read(&self.faults, index, sub, buf)
            }
            _ => Err(SdoAbort::ObjectDoesNotExist),
        }
    }
    fn write(&mut self, key: ObjectKey, data: &[u8], state: EsmState) -> Result<(), SdoAbort> {
        let ObjectKey { index, sub } = key;
        match index {
            0x1000..=0x10FF => {
                if let Some(cmd) = firmware::dictionary::write_comm(
                    &mut self.comm,
                    &mut self.faults,
                    ObjectKey::new(index, sub),
                    data,
                )? {
                    let mut flash = std::mem::take(&mut self.flash);
                    let r = comm::execute(cmd, &STORE, &mut flash, self);
                    self.flash = flash;
                    r.map_err(StorageError::abort)?;
                }
                Ok(())
            }
            0x1600..=0x1C13 => self.pdo.write(key, data, state, all_objects()),
            0x2000..=0x21FF => self.params.write(index, sub, data),
            0x2300..=0x23FF => self.monitor.write(index, sub, data),
            _ => Err(SdoAbort::ObjectDoesNotExist),
        }
    }
}

fn new_drive() -> Drive {
    Drive::power_up(Flash::new()).0
}

/// The `len` low bytes of `v`, little-endian (an SDO download's data).
fn le_bytes(v: i64, len: usize) -> Vec<u8> {
    (v as u64).to_le_bytes()[..len].to_vec()
}

// ---- parameters ---------------------------------------------------------------------

#[test]
fn every_vendor_parameter_default_and_range_edges_over_sdo() {
    let mut d = new_drive();
    d.sdo_download(0x2013, 0, &[0]).unwrap(); // unlock 0x2015/0x2016
    for o in all_objects()
        .iter()
        .filter(|o| (0x2000..=0x21FF).contains(&o.index))
    {
        for e in o.entries() {
            let len = e.byte_len();
            if let od::DefaultValue::Int(def) = e.default_value() {
                let expect = if (o.index, e.sub) == (0x2013, 0) {
                    0
                } else {
                    def
                };
                assert_eq!(
                    d.sdo_upload(o.index, e.sub),
                    Ok(expect as u32),
                    "{:#x}:{} default",
                    o.index,
                    e.sub
                );
            }
            if !e.access.writable() {
                assert_eq!(
                    d.sdo_download(o.index, e.sub, &le_bytes(0, len)),
                    Err(SdoAbort::WriteReadOnly.code())
                );
                continue;
            }
            if matches!((o.index, e.sub), (0x2040 | 0x2042 | 0x2093, 0)) {
                continue; // commands, covered below
            }
            if (o.index, e.sub) == (0x2162, 1) {
                // The servo tune's start: a command of the drive (`servo_tune` tests);
                // its range is checked here like any entry's.
                assert_eq!(d.sdo_download(0x2162, 1, &[0]), Ok(()));
                assert_eq!(
                    d.sdo_download(0x2162, 1, &[2]),
                    Err(SdoAbort::ValueTooHigh.code())
                );
                continue;
            }
            // 0x2000's upper edge is the variant's (the table holds the largest).
            let max = match (o.index, e.sub) {
                (0x2000, 0) => i64::from(Variant::HybridServo.max_peak_current_ma()),
                _ => e.max(),
            };
            for v in [e.min(), max] {
                assert_eq!(
                    d.sdo_download(o.index, e.sub, &le_bytes(v, len)),
                    Ok(()),
                    "{:#x}:{} = {v}",
                    o.index,
                    e.sub
                );
                assert_eq!(d.sdo_upload(o.index, e.sub), Ok(v as u32));
            }
            let (_, tmin, tmax) = od::type_range(e.data_type);
            if max < tmax {
                assert_eq!(
                    d.sdo_download(o.index, e.sub, &le_bytes(max + 1, len)),
                    Err(0x0609_0031),
                    "{:#x}",
                    o.index
                );
                assert_eq!(d.sdo_upload(o.index, e.sub), Ok(max as u32), "unchanged");
            }
            if e.min() > tmin {
                assert_eq!(
                    d.sdo_download(o.index, e.sub, &le_bytes(e.min() - 1, len)),
                    Err(0x0609_0032),
                    "{:#x}",
                    o.index
                );
                assert_eq!(d.sdo_upload(o.index, e.sub), Ok(max as u32), "unchanged");
            }
            // One byte too many.
            if len < 4 {
                assert_eq!(
                    d.sdo_download(o.index, e.sub, &vec![0u8; len + 1]),
                    Err(0x0607_0012)
                );
            }
            if (o.index, e.sub) == (0x2013, 0) {
                d.sdo_download(0x2013, 0, &[0]).unwrap(); // keep 0x2015/0x2016 writable
            }
        }
    }
}

#[test]
fn auto_tune_lock_and_counters_over_sdo() {
    let mut d = new_drive();
    assert_eq!(
        d.sdo_download(0x2015, 0, &le_bytes(3000, 2)),
        Err(0x0800_0021)
    );
    assert_eq!(
        d.sdo_download(0x2016, 0, &le_bytes(300, 2)),
        Err(0x0800_0021)
    );
    assert_eq!(d.sdo_upload(0x2015, 0), Ok(1000));
    d.params.add_command_pulses(70_000);
    assert_eq!(d.sdo_upload(0x2039, 0), Ok(1));
    assert_eq!(d.sdo_upload(0x2040, 0), Ok(70_000 - 65_536));
    assert_eq!(d.sdo_download(0x2040, 0, &le_bytes(1, 2)), Ok(()));
    assert_eq!(
        (d.sdo_upload(0x2039, 0), d.sdo_upload(0x2040, 0)),
        (Ok(0), Ok(0))
    );
    assert_eq!(d.sdo_download(0x2039, 0, &le_bytes(1, 2)), Err(0x0601_0002));
    assert_eq!(d.sdo_upload(0x2155, 0), Ok(0));
    d.step(0b1_0101, 24_000, 0, 0, 0);
    assert_eq!(d.sdo_upload(0x2155, 0), Ok(0b1_0101));
}

// ---- store / restore ----------------------------------------------------------------

#[test]
fn save_power_cycle_restores_parameters_and_pdo_mapping() {
    let mut d = new_drive();
    d.sdo_download(0x2000, 0, &le_bytes(4200, 2)).unwrap();
    d.sdo_download(0x2001, 0, &le_bytes(12_800, 4)).unwrap();
    d.sdo_download(0x2152, 5, &le_bytes(16, 2)).unwrap();
    d.sdo_download(0x10F1, 2, &le_bytes(8, 2)).unwrap();
    // New TxPDO1 mapping and TxPDO2 assigned as well.
    d.sdo_download(0x1A00, 0, &[0]).unwrap();
    d.sdo_download(
        0x1A00,
        1,
        &le_bytes(ObjectKey::new(0x2303, 0).mapping_word(16) as i64, 4),
    )
    .unwrap();
    d.sdo_download(
        0x1A00,
        2,
        &le_bytes(ObjectKey::new(0x2039, 0).mapping_word(16) as i64, 4),
    )
    .unwrap();
    d.sdo_download(0x1A00, 0, &[2]).unwrap();
    d.sdo_download(0x1A01, 0, &[0]).unwrap();
    d.sdo_download(
        0x1A01,
        1,
        &le_bytes(ObjectKey::new(0x1001, 0).mapping_word(8) as i64, 4),
    )
    .unwrap();
    d.sdo_download(0x1A01, 0, &[1]).unwrap();
    d.sdo_download(0x1C13, 0, &[0]).unwrap();
    d.sdo_download(0x1C13, 1, &le_bytes(0x1A00, 2)).unwrap();
    d.sdo_download(0x1C13, 2, &le_bytes(0x1A01, 2)).unwrap();
    d.sdo_download(0x1C13, 0, &[2]).unwrap();
    assert_eq!(
        d.params.active().pulses_per_rev,
        50_000,
        "0x2001 after restart only"
    );
    assert_eq!(d.sdo_download(0x1010, 1, &SAVE.to_le_bytes()), Ok(()));

    let mut d = d.power_cycle();
    assert_eq!(d.emergencies(), vec![], "clean load");
    assert_eq!(d.sdo_upload(0x2000, 0), Ok(4200));
    assert_eq!(d.sdo_upload(0x2001, 0), Ok(12_800));
    assert_eq!(d.params.active().pulses_per_rev, 12_800);
    assert_eq!(d.sdo_upload(0x2152, 5), Ok(16));
    assert_eq!(d.sdo_upload(0x10F1, 2), Ok(8));
    assert_eq!(d.sdo_upload(0x1A00, 0), Ok(2));
    assert_eq!(
        d.sdo_upload(0x1A00, 1),
        Ok(ObjectKey::new(0x2303, 0).mapping_word(16))
    );
    assert_eq!(
        d.sdo_upload(0x1A00, 2),
        Ok(ObjectKey::new(0x2039, 0).mapping_word(16))
    );
    assert_eq!(d.sdo_upload(0x1A01, 0), Ok(1));
    assert_eq!(d.sdo_upload(0x1C13, 0), Ok(2));
    assert_eq!(d.sdo_upload(0x1C13, 2), Ok(0x1A01));
    assert_eq!(d.pdo.assigned_bytes(pdo::Dir::Tx), 5);
    assert_eq!(d.sdo_upload(0x2306, 0), Ok(2), "second power-up counted");

    // E5: 'load' to 0x1010:04 → defaults after the next power cycle.
    assert_eq!(d.sdo_download(0x1010, 4, &LOAD.to_le_bytes()), Ok(()));
    assert_eq!(d.sdo_upload(0x2000, 0), Ok(4200), "effective after restart");
    let mut d = d.power_cycle();
    assert_eq!(d.sdo_upload(0x2000, 0), Ok(3200));
    assert_eq!(d.sdo_upload(0x1A00, 0), Ok(2));
    assert_eq!(
        d.sdo_upload(0x1A00, 1),
        Ok(ObjectKey::new(0x1001, 0).mapping_word(8))
    );
    assert_eq!(d.sdo_upload(0x1C13, 0), Ok(1));
}

#[test]
fn store_signatures_and_flash_failure() {
    let mut d = new_drive();
    for sub in 1..=4u8 {
        assert_eq!(
            d.sdo_download(0x1010, sub, &0x1234_5678u32.to_le_bytes()),
            Err(0x0800_0020)
        );
        assert_eq!(
            d.sdo_download(0x1011, sub, &SAVE.to_le_bytes()),
            Err(0x0800_0020)
        );
        assert_eq!(d.sdo_upload(0x1010, sub), Ok(1));
    }
    assert_eq!(
        d.sdo_download(0x1010, 1, &LOAD.to_le_bytes()),
        Err(0x0800_0020)
    );
    assert_eq!(
        d.sdo_download(0x1010, 5, &SAVE.to_le_bytes()),
        Err(0x0609_0011)
    );
    // Power to the flash lost in the middle of a save: hardware error, drive keeps running.
    d.flash.cut_power_after(2100);
    assert_eq!(
        d.sdo_download(0x1010, 1, &SAVE.to_le_bytes()),
        Err(0x0606_0000)
    );
    assert_eq!(d.sdo_upload(0x2000, 0), Ok(3200));
    // After the power cycle: the torn record is reported, defaults (nothing else stored).
    let mut d = d.power_cycle();
    let e = d.emergencies();
    assert_eq!(e.len(), 1);
    assert_eq!(e[0].0, firmware::storage::EMCY_PARAMETERS_LOST);
    // A save now works and the report goes away.
    assert_eq!(d.sdo_download(0x1010, 1, &SAVE.to_le_bytes()), Ok(()));
    let mut d = d.power_cycle();
    assert_eq!(d.emergencies(), vec![]);
}

// ---- faults -------------------------------------------------------------------------

/// On/off intervals of the red LED from `from` for `ms` milliseconds of `step`s.
fn led_timeline(
    d: &mut Drive,
    ms: u32,
    mut inputs: impl FnMut(u32) -> (u8, u32, i32, i32, i32),
) -> (Vec<(bool, u32, u32)>, u8) {
    let mut tl: Vec<(bool, u32, u32)> = Vec::new();
    let mut pins = 0;
    for k in 0..ms {
        let (raw, mv, ia, ib, fe) = inputs(k);
        let (led, p) = d.step(raw, mv, ia, ib, fe);
        pins = p;
        let t = d.now_ms;
        match tl.last_mut() {
            Some(last) if last.0 == led => last.2 = t + 1,
            _ => tl.push((led, t, t + 1)),
        }
    }
    (tl, pins)
}

fn pulses(tl: &[(bool, u32, u32)]) -> usize {
    tl.iter().filter(|i| i.0).count()
}

struct Case {
    kind: FaultKind,
    code: u16,
    register: u8,
    flashes: usize,
    latched: bool,
    /// Inputs that produce the fault: (raw inputs, bus mV, ia, ib, following error).
    bad: (u8, u32, i32, i32, i32),
}

const GOOD: (u8, u32, i32, i32, i32) = (0, 24_000, 500, -500, 10);

#[test]
fn every_fault_code_emergency_led_pds_output_and_recovery() {
    let cases = [
        Case {
            kind: FaultKind::OverCurrent,
            code: 0x2310,
            register: 0x83,
            flashes: 1,
            latched: true,
            bad: (0, 24_000, 12_000, 0, 0),
        },
        Case {
            kind: FaultKind::OverVoltage,
            code: 0x3210,
            register: 0x85,
            flashes: 2,
            latched: true,
            bad: (0, 56_000, 0, 0, 0),
        },
        Case {
            kind: FaultKind::UnderVoltage,
            code: 0x3220,
            register: 0x85,
            flashes: 3,
            latched: false,
            bad: (0, 10_000, 0, 0, 0),
        },
        Case {
            kind: FaultKind::FollowingError,
            code: 0x8611,
            register: 0xA1,
            flashes: 7,
            latched: false,
            bad: (0, 24_000, 0, 0, 5000),
        },
    ];
    for c in &cases {
        let mut d = new_drive();
        let (tl, pins) = led_timeline(&mut d, 100, |_| GOOD);
        assert_eq!(pulses(&tl), 0);
        assert_eq!(pins, 0b11, "alarm outputs (active-low) inactive → high");
        assert!(!d.pds_fault);
        // The fault for 3 s: one emergency, N pulses, alarm output active (low).
        let start = d.now_ms + 1;
        let (tl, pins) = led_timeline(&mut d, 3000, |_| c.bad);
        assert_eq!(tl[0], (true, start, start + 150), "{:?}", c.kind);
        assert_eq!(pulses(&tl), c.flashes, "{:?}", c.kind);
        assert_eq!(pins, 0b00);
        assert!(d.pds_fault);
        let e = d.emergencies();
        assert_eq!(e.len(), 1, "exactly one emergency for {:?}", c.kind);
        assert_eq!(
            (e[0].0, e[0].1, e[0].2[0]),
            (c.code, c.register, c.kind as u8)
        );
        assert_eq!(d.sdo_upload(0x1001, 0), Ok(u32::from(c.register)));
        assert_eq!(d.sdo_upload(0x2400, 2), Ok(u32::from(c.code)), "history");
        assert_eq!(
            d.sdo_upload(0x1003, 1),
            Ok(u32::from(c.code) | (c.kind as u32) << 16)
        );
        // Condition gone, fault-clear input (IN4, function 8) pulsed.
        led_timeline(&mut d, 10, |_| GOOD);
        let (_, pins) = led_timeline(&mut d, 10, |_| (0b1000, 24_000, 0, 0, 0));
        led_timeline(&mut d, 10, |_| GOOD);
        if c.latched {
            assert!(d.faults.is_active(c.kind), "{:?} latched", c.kind);
            assert_eq!(pins, 0b00);
            assert_eq!(d.emergencies(), vec![]);
            // 0x2057 = 1 allows clearing without a power cycle.
            d.sdo_download(0x2057, 0, &[1]).unwrap();
            led_timeline(&mut d, 10, |_| (0b1000, 24_000, 0, 0, 0));
            led_timeline(&mut d, 10, |_| GOOD);
        }
        assert!(!d.faults.any_active(), "{:?} cleared", c.kind);
        assert_eq!(
            d.emergencies().iter().map(|e| e.0).collect::<Vec<_>>(),
            vec![0x0000],
            "error reset emergency"
        );
        let (tl, pins) = led_timeline(&mut d, 3000, |_| GOOD);
        assert_eq!(pulses(&tl), 0);
        assert_eq!(pins, 0b11);
        assert_eq!(d.sdo_upload(0x1001, 0), Ok(0));
    }
}

#[test]
fn latched_fault_needs_power_cycle_and_most_severe_is_shown() {
    let mut d = new_drive();
    led_timeline(&mut d, 10, |_| GOOD);
    // Under-voltage first, then over-current: LED shows 1 flash from the next burst.
    led_timeline(&mut d, 990, |_| (0, 10_000, 0, 0, 0));
    let (tl, _) = led_timeline(&mut d, 6000, |k| {
        if k < 10 {
            (0, 10_000, 20_000, 0, 0)
        } else {
            (0, 10_000, 0, 0, 0)
        }
    });
    let later: Vec<_> = tl.iter().filter(|i| i.0 && i.1 > 3000).collect();
    assert_eq!(later.len(), 2, "one pulse per burst, two bursts: {tl:?}");
    assert_eq!(d.sdo_upload(0x2400, 1), Ok(2), "two faults counted");
    assert_eq!(d.emergencies().len(), 2);
    // Fault clear: under-voltage still present, over-current latched.
    led_timeline(&mut d, 5, |_| (0b1000, 10_000, 0, 0, 0));
    assert!(d.faults.is_active(FaultKind::OverCurrent));
    assert!(d.faults.is_active(FaultKind::UnderVoltage));
    // Voltage back, clear again: only the latched one stays.
    led_timeline(&mut d, 5, |_| GOOD);
    led_timeline(&mut d, 5, |_| (0b1000, 24_000, 0, 0, 0));
    assert!(d.faults.is_active(FaultKind::OverCurrent));
    assert!(!d.faults.is_active(FaultKind::UnderVoltage));
    // Power cycle clears it.
    let mut d = d.power_cycle();
    let (tl, pins) = led_timeline(&mut d, 3000, |_| GOOD);
    assert_eq!(pulses(&tl), 0);
    assert_eq!(pins, 0b11);
}

#[test]
fn masked_faults_are_not_reported() {
    let mut d = new_drive();
    d.sdo_download(0x2056, 0, &le_bytes(0x0001, 2)).unwrap(); // only over-current
    let (tl, pins) = led_timeline(&mut d, 3000, |_| (0, 60_000, 0, 0, 99_999));
    assert_eq!(pulses(&tl), 0);
    assert_eq!(pins, 0b11);
    assert!(d.emergencies().is_empty());
    assert!(!d.pds_fault);
    // Fault history clear record 0x2093.
    d.sdo_download(0x2056, 0, &le_bytes(0x00C3, 2)).unwrap();
    led_timeline(&mut d, 10, |_| (0, 60_000, 0, 0, 0));
    assert_eq!(d.sdo_upload(0x2400, 2), Ok(0x3210));
    d.sdo_download(0x2093, 0, &[1]).unwrap();
    led_timeline(&mut d, 1, |_| GOOD);
    assert_eq!(d.sdo_upload(0x2400, 2), Ok(0));
    assert!(
        d.faults.is_active(FaultKind::OverVoltage),
        "history clear is not a fault reset"
    );
}

#[test]
fn ecat_and_power_up_faults() {
    let mut d = new_drive();
    d.sdo_download(0x2056, 0, &le_bytes(0xFFFF, 2)).unwrap();
    d.step(0, 24_000, 0, 0, 0);
    for (kind, code, flashes) in [
        (FaultKind::MotorOpen, 0x7120u16, 4usize),
        (FaultKind::PhaseSensing, 0x5210, 9),
    ] {
        assert!(d.faults.raise(kind, Snapshot::default(), d.now_ms));
        let (tl, pins) = led_timeline(&mut d, 3000, |_| GOOD);
        assert_eq!(pulses(&tl), flashes);
        assert_eq!(pins, 0);
        assert_eq!(d.emergencies()[0].0, code);
        d.faults.condition_gone(kind);
        led_timeline(&mut d, 2, |_| (0b1000, 24_000, 0, 0, 0));
        led_timeline(&mut d, 2, |_| GOOD);
        assert!(!d.faults.any_active());
        d.emergencies();
    }
    // EtherCAT: emergency and PDS fault, no red LED (the ERR LED shows it).
    d.pds_fault = false;
    assert!(d.faults.raise_ecat(0xA001, [4, 0x1B], d.now_ms));
    let (tl, pins) = led_timeline(&mut d, 3000, |_| GOOD);
    assert_eq!(pulses(&tl), 0);
    assert_eq!(pins, 0);
    assert!(d.pds_fault);
    assert_eq!(d.emergencies(), vec![(0xA001, 0x11, [6, 240, 0, 4, 0x1B])]);
    assert_eq!(d.sdo_upload(0x1001, 0), Ok(0x11));
}

// ---- the composed drive (firmware::drive) -------------------------------------------

#[test]
fn composed_drive_fault_reaches_pds_emergency_led_outputs_and_0x603f() {
    use firmware::drive::{AxisState, Drive as AppDrive};
    let mut d = AppDrive::new(Variant::HybridServo, 1);
    let ok = AxisState {
        bus_mv: 24_000,
        ..AxisState::default()
    };
    let mut now = 0u32;
    let mut run = |d: &mut AppDrive, a: AxisState, raw: u8, ms: u32| -> Vec<(bool, u32, u32)> {
        let mut tl: Vec<(bool, u32, u32)> = Vec::new();
        for _ in 0..ms {
            now += 1;
            d.set_axis(a);
            d.tick(u64::from(now) * 1000, raw);
            d.run_cycle(0.001);
            let red = d.leds(now).red;
            match tl.last_mut() {
                Some(l) if l.0 == red => l.2 = now + 1,
                _ => tl.push((red, now, now + 1)),
            }
        }
        tl
    };
    run(&mut d, ok, 0, 20);
    assert!(d.pop_emergency().is_none());
    assert_eq!(d.outputs().0, 0b11);
    // Over-voltage for 3 s: one emergency, PDS Fault, 603F, 2 flashes, alarm output.
    let tl = run(
        &mut d,
        AxisState {
            bus_mv: 56_000,
            ..ok
        },
        0,
        3000,
    );
    assert_eq!(tl.iter().filter(|i| i.0).count(), 2);
    assert_eq!(tl[0].2 - tl[0].1, 150);
    let e = d.pop_emergency().expect("emergency");
    assert_eq!((e.code, e.register & 0x05), (0x3210, 0x05));
    assert!(d.pop_emergency().is_none(), "one emergency per occurrence");
    assert_eq!(d.cia402.statusword() & 0x0008, 0x0008, "PDS in Fault");
    let mut b = [0u8; 4];
    assert_eq!(d.read(ObjectKey::new(0x603F, 0), &mut b), Ok(2));
    assert_eq!(u16::from_le_bytes([b[0], b[1]]), 0x3210);
    assert_eq!(d.outputs().0, 0b00, "alarm outputs active (low)");
    // Voltage back, fault-clear input: latched (0x2057 = 0), stays.
    run(&mut d, ok, 0, 5);
    run(&mut d, ok, 0b1000, 5);
    run(&mut d, ok, 0, 5);
    assert!(d.faults.is_active(FaultKind::OverVoltage));
    // 0x2057 = 1 and the input again: cleared, error-reset emergency, LED dark.
    assert_eq!(
        d.write(ObjectKey::new(0x2057, 0), &[1], EsmState::PreOp),
        Ok(())
    );
    run(&mut d, ok, 0b1000, 5);
    let tl = run(&mut d, ok, 0, 3000);
    assert!(!d.faults.any_active());
    assert_eq!(tl.iter().filter(|i| i.0).count(), 0);
    assert_eq!(d.pop_emergency().map(|e| e.code), Some(0x0000));
    assert_eq!(d.outputs().0, 0b11);
}
