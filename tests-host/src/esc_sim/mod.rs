//! A simulated EtherCAT slave controller (ESC): the register space and process RAM of a
//! LAN9252 or ET1100, seen from both sides.
//!
//! * **ECAT side** (the wire): [`frame::process_frame`] runs an Ethernet frame through a
//!   chain of simulators, executing every datagram command with the working-counter
//!   rules, auto-increment addressing and FMMU logical mapping.
//! * **PDI side** (the microcontroller): [`EscSim`] implements
//!   [`ecat_slave_stack::EscAccess`], so the firmware talks to it exactly as to a chip
//!   (the SPI chip models can also wrap it).
//!
//! What is modelled (ETG.1000.4): access rights per side (e.g. AL control is written by
//! the master, AL status by the PDI; SM start/length/control only while the SM is
//! disabled), SyncManager mailbox (1-buffer) and 3-buffer semantics with their status
//! bits and AL/ECAT events, AL control → AL event bit 0 with the "mailbox" behaviour
//! of AL control (device emulation off), the SII EEPROM interface at 0x0500-0x050F
//! backed by an SII image, the process-data watchdog, the PDI watchdog, and distributed
//! clocks (local time, receive-time latching, offset/delay, a drift compensation that
//! settles on the first system-time write, SYNC0 generation). Time is simulated
//! nanoseconds; it only moves through [`EscSim::advance_to`] (or the segment), never
//! with the wall clock.
//!
//! Choices where the real chips' behaviour is not in our sources are marked
//! *simulation choice* in the docs below.

mod dc;
pub mod frame;
mod registers;
mod sii;
mod sm;

pub use sii::sii_crc8;

use crate::pi_mutex::{PiGuard, PiMutex};
use ecat_slave_stack::registers as reg;
use ecat_slave_stack::{EscAccess, EscError};
use sm::SmRuntime;
use std::sync::Arc;

/// Which chip is simulated. Decides the ESC information registers, the number of
/// FMMUs/SyncManagers, the process RAM size and the SII read size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flavour {
    /// Microchip LAN9252: 3 FMMUs, 4 SyncManagers, 4 KiB process RAM, 2 MII ports.
    Lan9252,
    /// Beckhoff ET1100: 8 FMMUs, 8 SyncManagers, 8 KiB process RAM.
    Et1100,
}

impl Flavour {
    /// ESC type (0x0000). *Simulation choice* for the LAN9252 value.
    pub const fn esc_type(self) -> u8 {
        match self {
            Flavour::Lan9252 => ecat_slave_stack::lan9252::LAN9252_TYPE,
            Flavour::Et1100 => ecat_slave_stack::et1100::ET1100_TYPE,
        }
    }
    /// ESC revision (0x0001).
    pub const fn revision(self) -> u8 {
        match self {
            Flavour::Lan9252 => 0x02,
            Flavour::Et1100 => 0x00,
        }
    }
    /// ESC build (0x0002).
    pub const fn build(self) -> u16 {
        match self {
            Flavour::Lan9252 => 0x0001,
            Flavour::Et1100 => 0x0003,
        }
    }
    /// Number of FMMUs (0x0004).
    pub const fn fmmu_count(self) -> u8 {
        match self {
            Flavour::Lan9252 => 3,
            Flavour::Et1100 => 8,
        }
    }
    /// Number of SyncManagers (0x0005).
    pub const fn sm_count(self) -> u8 {
        match self {
            Flavour::Lan9252 => 4,
            Flavour::Et1100 => 8,
        }
    }
    /// Process RAM in bytes (0x0006 holds it in KiB).
    pub const fn ram_bytes(self) -> usize {
        match self {
            Flavour::Lan9252 => 4 * 1024,
            Flavour::Et1100 => 8 * 1024,
        }
    }
    /// Port descriptor (0x0007): ports 0 and 1 MII (ET1100: ports 2/3 not configured).
    pub const fn port_descriptor(self) -> u8 {
        match self {
            Flavour::Lan9252 => 0x0F,
            Flavour::Et1100 => 0x5F,
        }
    }
    /// Features (0x0008): DC, 64-bit DC, MII enhanced link detection, separate FCS
    /// handling, enhanced DC SYNC activation (+ EBUS bits on the ET1100).
    pub const fn features(self) -> u16 {
        match self {
            Flavour::Lan9252 => 0x01CC,
            Flavour::Et1100 => 0x01FC,
        }
    }
    /// The SII interface delivers 8 bytes per read (0x0502 bit 6), else 4.
    /// *Simulation choice*: the ET1100 flavour reads 8, the LAN9252 flavour 4, so that
    /// both master code paths are exercised.
    pub const fn sii_reads_8_bytes(self) -> bool {
        matches!(self, Flavour::Et1100)
    }
    /// Size of the whole address space (registers + process RAM).
    pub const fn address_space(self) -> usize {
        0x1000 + self.ram_bytes()
    }
}

/// Which side of the ESC performs an access.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// The EtherCAT master, through datagrams.
    Ecat,
    /// The local microcontroller (process data interface).
    Pdi,
}

/// Counters a test can inspect.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SimStats {
    /// SYNC0 pulses generated.
    pub sync0_pulses: u64,
    /// Process-data watchdog expiries.
    pub pd_watchdog_expiries: u64,
    /// PDI watchdog expiries.
    pub pdi_watchdog_expiries: u64,
    /// SII commands executed (read, write, reload).
    pub sii_commands: u64,
    /// ECAT writes to AL control ignored because the PDI had not read the previous one.
    pub al_control_writes_ignored: u64,
}

/// Timing of the current frame at this ESC, set by the frame processor.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct FrameTiming {
    /// Simulated time the frame entered port 0.
    pub(crate) port0_ns: u64,
    /// Simulated time the frame came back into port 1 (none at the end of the line).
    pub(crate) port1_ns: Option<u64>,
}

#[derive(Debug, Clone, Copy, Default)]
struct Sync0 {
    active: bool,
    next: u64,
    cycle: u32,
    /// Simulated time of the latest pulse, ns.
    last_ns: u64,
}

/// One simulated ESC.
pub struct EscSim {
    flavour: Flavour,
    mem: Vec<u8>,
    sms: Vec<SmRuntime>,
    sii: Vec<u8>,
    sii_busy_reads: u8,
    al_control_unread: bool,
    now_ns: u64,
    clock_base_ns: u64,
    pll_correction: i64,
    sync0: Sync0,
    pd_wd_armed: bool,
    pd_wd_last_ns: u64,
    pdi_last_ns: u64,
    timing: FrameTiming,
    stats: SimStats,
    port0_closed: bool,
}

fn get_u16(m: &[u8], a: usize) -> u16 {
    u16::from_le_bytes([m[a], m[a + 1]])
}
fn get_u32(m: &[u8], a: usize) -> u32 {
    u32::from_le_bytes([m[a], m[a + 1], m[a + 2], m[a + 3]])
}
fn get_u64(m: &[u8], a: usize) -> u64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&m[a..a + 8]);
    u64::from_le_bytes(b)
}
fn put_u16(m: &mut [u8], a: usize, v: u16) {
    m[a..a + 2].copy_from_slice(&v.to_le_bytes());
}
fn put_u32(m: &mut [u8], a: usize, v: u32) {
    m[a..a + 4].copy_from_slice(&v.to_le_bytes());
}
fn put_u64(m: &mut [u8], a: usize, v: u64) {
    m[a..a + 8].copy_from_slice(&v.to_le_bytes());
}

/// ECAT event request bit: AL status changed.
pub(super) const ECAT_EVENT_AL_STATUS: u16 = 1 << 3;

impl EscSim {
    /// A freshly powered ESC that has loaded `sii` (the EEPROM image). A too short
    /// image or a wrong checksum leaves the ESC with "EEPROM not loaded" (DL status
    /// bit 0 clear, 0x0502 bits 11/12 set), as a chip with a blank EEPROM.
    pub fn new(flavour: Flavour, sii: Vec<u8>) -> Self {
        let sms = (0..flavour.sm_count())
            .map(|_| SmRuntime::default())
            .collect();
        let mut esc = EscSim {
            flavour,
            mem: vec![0; flavour.address_space()],
            sms,
            sii,
            sii_busy_reads: 0,
            al_control_unread: false,
            now_ns: 0,
            clock_base_ns: 0,
            pll_correction: 0,
            sync0: Sync0::default(),
            pd_wd_armed: false,
            pd_wd_last_ns: 0,
            pdi_last_ns: 0,
            timing: FrameTiming::default(),
            stats: SimStats::default(),
            port0_closed: false,
        };
        esc.power_on();
        esc
    }

    fn power_on(&mut self) {
        let f = self.flavour;
        let m = &mut self.mem;
        m[reg::ESC_TYPE.addr() as usize] = f.esc_type();
        m[reg::ESC_REVISION.addr() as usize] = f.revision();
        put_u16(m, reg::ESC_BUILD.addr() as usize, f.build());
        m[reg::FMMU_COUNT.addr() as usize] = f.fmmu_count();
        m[reg::SM_COUNT.addr() as usize] = f.sm_count();
        m[reg::RAM_SIZE.addr() as usize] = (f.ram_bytes() / 1024) as u8;
        m[reg::PORT_DESCRIPTOR.addr() as usize] = f.port_descriptor();
        put_u16(m, reg::FEATURES.addr() as usize, f.features());
        put_u16(m, reg::AL_CONTROL.addr() as usize, 0x0001);
        put_u16(m, reg::AL_STATUS.addr() as usize, 0x0001);
        put_u16(m, reg::WATCHDOG_DIVIDER.addr() as usize, 2498);
        put_u16(m, reg::WATCHDOG_TIME_PDI.addr() as usize, 1000);
        put_u16(m, reg::WATCHDOG_TIME_PD.addr() as usize, 1000);
        put_u16(m, reg::WATCHDOG_STATUS_PD.addr() as usize, 0x0001);
        self.set_ports(false);
        self.load_sii_config();
    }

    /// Sets the link state of the ports: port 0 always has a link (towards the
    /// master); port 1 has one when another ESC follows, otherwise its loop is closed.
    pub fn set_ports(&mut self, downstream: bool) {
        // bit 1 PDI watchdog OK is kept; bit 0 (PDI operational) is kept.
        let keep = get_u16(&self.mem, reg::DL_STATUS.addr() as usize) & 0x0003;
        let mut v = keep | (1 << 4) | (1 << 9); // link + communication on port 0
        if downstream {
            v |= (1 << 5) | (1 << 11); // link + communication on port 1
        } else {
            v |= 1 << 10; // port 1 loop closed
        }
        v |= (1 << 12) | (1 << 14); // ports 2/3 closed
        put_u16(&mut self.mem, reg::DL_STATUS.addr() as usize, v | 0x0002);
    }

    /// Closes (or reopens) the loop at port 0, as when the cable towards the master
    /// is broken: frames then reach the processing unit through the closed port 0,
    /// which marks them as circulating (see [`frame::process_frame`]).
    pub fn set_port0_loop_closed(&mut self, closed: bool) {
        self.port0_closed = closed;
        let a = reg::DL_STATUS.addr() as usize;
        let mut v = get_u16(&self.mem, a);
        if closed {
            v = (v & !((1 << 4) | (1 << 9))) | (1 << 8);
        } else {
            v = (v & !(1 << 8)) | (1 << 4) | (1 << 9);
        }
        put_u16(&mut self.mem, a, v);
    }

    /// True while port 0's loop is closed.
    pub fn port0_loop_closed(&self) -> bool {
        self.port0_closed
    }

    /// Gives this ESC's local clock a different power-up instant (ns added to the
    /// simulated time), so that DC offsets are not trivially zero.
    pub fn set_clock_base(&mut self, ns: u64) {
        self.clock_base_ns = ns;
    }

    /// The simulated chip.
    pub fn flavour(&self) -> Flavour {
        self.flavour
    }

    /// Current simulated time (ns).
    pub fn now_ns(&self) -> u64 {
        self.now_ns
    }

    /// Counters for tests.
    pub fn stats(&self) -> SimStats {
        self.stats
    }

    /// The SII image (after any master writes through 0x0502).
    pub fn sii(&self) -> &[u8] {
        &self.sii
    }

    /// Raw view of the address space without side effects (for tests and tools).
    pub fn peek(&self, addr: u16, len: usize) -> &[u8] {
        let a = (addr as usize).min(self.mem.len());
        let e = (a + len).min(self.mem.len());
        &self.mem[a..e]
    }

    /// The PDI interrupt line: AL event request & AL event mask ≠ 0.
    pub fn pdi_irq(&self) -> bool {
        let req = get_u32(&self.mem, reg::AL_EVENT_REQUEST.addr() as usize);
        let mask = get_u32(&self.mem, reg::AL_EVENT_MASK.addr() as usize);
        req & mask != 0
    }

    /// AL status (0x0130) as the master would read it.
    pub fn al_status(&self) -> u16 {
        get_u16(&self.mem, reg::AL_STATUS.addr() as usize)
    }

    /// AL status code (0x0134).
    pub fn al_status_code(&self) -> u16 {
        get_u16(&self.mem, reg::AL_STATUS_CODE.addr() as usize)
    }

    // ---------------------------------------------------------------- events

    fn al_event_set(&mut self, bits: u32) {
        let a = reg::AL_EVENT_REQUEST.addr() as usize;
        let v = get_u32(&self.mem, a) | bits;
        put_u32(&mut self.mem, a, v);
    }
    fn al_event_clear(&mut self, bits: u32) {
        let a = reg::AL_EVENT_REQUEST.addr() as usize;
        let v = get_u32(&self.mem, a) & !bits;
        put_u32(&mut self.mem, a, v);
    }
    fn ecat_event_set(&mut self, bits: u16) {
        let a = reg::ECAT_EVENT_REQUEST.addr() as usize;
        let v = get_u16(&self.mem, a) | bits;
        put_u16(&mut self.mem, a, v);
    }
    fn ecat_event_clear(&mut self, bits: u16) {
        let a = reg::ECAT_EVENT_REQUEST.addr() as usize;
        let v = get_u16(&self.mem, a) & !bits;
        put_u16(&mut self.mem, a, v);
    }
    /// ECAT event request & ECAT event mask, ORed into each datagram's IRQ field.
    pub(crate) fn ecat_irq(&self) -> u16 {
        get_u16(&self.mem, reg::ECAT_EVENT_REQUEST.addr() as usize)
            & get_u16(&self.mem, reg::ECAT_EVENT_MASK.addr() as usize)
    }

    // ---------------------------------------------------------------- addressing

    /// Configured station address (0x0010).
    pub fn station_address(&self) -> u16 {
        get_u16(&self.mem, reg::STATION_ADDRESS.addr() as usize)
    }

    /// True when a configured-address datagram with `adp` addresses this ESC
    /// (station address, or the alias when DL control bit 24 enables it).
    pub(crate) fn matches_configured(&self, adp: u16) -> bool {
        if adp == self.station_address() {
            return true;
        }
        let alias_enabled = self.mem[reg::DL_CONTROL.addr() as usize + 3] & 0x01 != 0;
        alias_enabled && adp == get_u16(&self.mem, reg::STATION_ALIAS.addr() as usize)
    }

    // ---------------------------------------------------------------- access

    /// Reads `buf.len()` bytes at `addr` from `side`. Bytes outside the implemented
    /// address space are left unchanged in `buf`. Returns whether the access was
    /// accepted (counts for the working counter): a read of an empty mailbox, of a
    /// SyncManager buffer in the wrong direction or entirely outside the address space
    /// is not accepted.
    pub fn side_read(&mut self, side: Side, addr: u16, buf: &mut [u8]) -> bool {
        if side == Side::Pdi {
            self.pdi_touch();
        }
        let start = addr as usize;
        let end = (start + buf.len()).min(self.mem.len());
        if start >= end {
            return false;
        }
        let mut accepted = false;
        if start < 0x1000 {
            let rend = end.min(0x1000);
            self.read_registers(side, start, &mut buf[..rend - start]);
            accepted = true;
        }
        if end > 0x1000 {
            let rstart = start.max(0x1000);
            let off = rstart - start;
            accepted |= self.ram_read(side, rstart, &mut buf[off..off + (end - rstart)]);
        }
        accepted
    }

    /// Writes `data` at `addr` from `side`, applying the access rights and side
    /// effects. Returns whether the access was accepted (see [`EscSim::side_read`]); writes
    /// to read-only registers are ignored but accepted, as on the chips.
    pub fn side_write(&mut self, side: Side, addr: u16, data: &[u8]) -> bool {
        if side == Side::Pdi {
            self.pdi_touch();
        }
        let start = addr as usize;
        let end = (start + data.len()).min(self.mem.len());
        if start >= end {
            return false;
        }
        let mut accepted = false;
        if start < 0x1000 {
            let rend = end.min(0x1000);
            self.write_registers(side, start, &data[..rend - start]);
            accepted = true;
        }
        if end > 0x1000 {
            let rstart = start.max(0x1000);
            let off = rstart - start;
            accepted |= self.ram_write(side, rstart, &data[off..off + (end - rstart)]);
        }
        accepted
    }

    fn pdi_touch(&mut self) {
        self.pdi_last_ns = self.now_ns;
        self.mem[reg::DL_STATUS.addr() as usize] |= 0x02;
    }

    /// Side-effect-free view of a byte range as the next consumer would see it
    /// (used for read-modify-write of partial bytes by bit-granular FMMUs).
    pub(crate) fn peek_for_rmw(&self, addr: usize, out: &mut [u8]) {
        for (i, o) in out.iter_mut().enumerate() {
            let a = addr + i;
            *o = match self.sm_window_at(a) {
                Some((n, off)) => self.sms[n].peek(&self.mem, self.sm_start(n), off),
                None => self.mem.get(a).copied().unwrap_or(0),
            };
        }
    }

    // ---------------------------------------------------------------- registers

    fn system_time_at(&self, t: u64) -> u64 {
        let offset = get_u64(&self.mem, reg::DC_SYSTEM_TIME_OFFSET.addr() as usize);
        t.wrapping_add(self.clock_base_ns)
            .wrapping_add(offset)
            .wrapping_add(self.pll_correction as u64)
    }

    /// The DC system time (0x0910) at the current simulated time.
    pub fn system_time(&self) -> u64 {
        self.system_time_at(self.now_ns)
    }

    fn access_time(&self, side: Side) -> u64 {
        match side {
            Side::Ecat => self.timing.port0_ns,
            Side::Pdi => self.now_ns,
        }
    }

    fn fmmu_end(&self) -> usize {
        reg::FMMU_BASE as usize + 16 * self.flavour.fmmu_count() as usize
    }
    fn sm_end(&self) -> usize {
        reg::SM_BASE as usize + 8 * self.flavour.sm_count() as usize
    }

    // ---------------------------------------------------------------- SyncManagers

    fn sm_start(&self, n: usize) -> usize {
        get_u16(&self.mem, reg::sm_register(n as u8) as usize) as usize
    }
    fn sm_len(&self, n: usize) -> usize {
        get_u16(&self.mem, reg::sm_register(n as u8) as usize + 2) as usize
    }
    fn sm_control(&self, n: usize) -> u8 {
        self.mem[reg::sm_register(n as u8) as usize + 4]
    }

    fn sm_effective_enable(&self, n: usize) -> bool {
        let base = reg::sm_register(n as u8) as usize;
        self.mem[base + 6] & 0x01 != 0 && self.mem[base + 7] & 0x01 == 0
    }

    #[allow(clippy::collapsible_match)]
    fn sm_reg_write_ecat(&mut self, a: usize, v: u8) {
        let n = (a - 0x0800) / 8;
        let off = (a - 0x0800) % 8;
        let base = reg::sm_register(n as u8) as usize;
        match off {
            0..=4 => {
                // Start, length and control are locked while the SM is enabled.
                if self.mem[base + 6] & 0x01 == 0 {
                    self.mem[a] = v;
                }
            }
            6 => {
                let old = self.mem[a];
                let was = self.sm_effective_enable(n);
                self.mem[a] = v & 0xC3;
                if old != self.mem[a] {
                    self.al_event_set(reg::al_event::SM_CHANGE);
                }
                if was != self.sm_effective_enable(n) {
                    self.sm_reset(n);
                }
            }
            _ => {}
        }
    }

    fn sm_pdi_control_write(&mut self, a: usize, v: u8) {
        let n = (a - 0x0800) / 8;
        let was = self.sm_effective_enable(n);
        self.mem[a] = v & 0x03;
        if was != self.sm_effective_enable(n) {
            self.sm_reset(n);
        }
    }

    fn sm_reset(&mut self, n: usize) {
        let enabled = self.sm_effective_enable(n);
        let len = self.sm_len(n);
        let mailbox = self.sm_control(n) & 0x03 == 0x02;
        self.sms[n].reset(enabled, if mailbox { 0 } else { len });
        self.al_event_clear(reg::al_event::sm(n as u8));
        self.sm_update_status(n);
    }

    fn sm_update_status(&mut self, n: usize) {
        let st = self.sms[n].status_byte(self.sm_control(n) & 0x03 == 0x02);
        self.mem[reg::sm_register(n as u8) as usize + 5] = st;
    }

    /// The enabled SyncManager whose buffer window contains `a`, with the offset.
    fn sm_window_at(&self, a: usize) -> Option<(usize, usize)> {
        (0..self.sms.len()).find_map(|n| {
            if !self.sms[n].enabled || !self.sm_valid_mode(n) {
                return None;
            }
            let (s, l) = (self.sm_start(n), self.sm_len(n));
            (l > 0 && a >= s && a < s + l).then(|| (n, a - s))
        })
    }

    fn sm_valid_mode(&self, n: usize) -> bool {
        let c = self.sm_control(n);
        matches!(c & 0x03, 0x00 | 0x02) && matches!(c & 0x0C, 0x00 | 0x04)
    }

    fn ram_read(&mut self, side: Side, start: usize, buf: &mut [u8]) -> bool {
        self.ram_access(side, start, RamOp::Read(buf))
    }
    fn ram_write(&mut self, side: Side, start: usize, data: &[u8]) -> bool {
        self.ram_access(side, start, RamOp::Write(data))
    }

    fn ram_access(&mut self, side: Side, start: usize, mut op: RamOp<'_>) -> bool {
        let len = op.len();
        let mut accepted = false;
        let mut i = 0;
        while i < len {
            let a = start + i;
            match self.sm_window_at(a) {
                None => {
                    // Plain memory up to the next SM window.
                    let mut j = i + 1;
                    while j < len && self.sm_window_at(start + j).is_none() {
                        j += 1;
                    }
                    match &mut op {
                        RamOp::Read(b) => b[i..j].copy_from_slice(&self.mem[a..start + j]),
                        RamOp::Write(d) => self.mem[a..start + j].copy_from_slice(&d[i..j]),
                    }
                    accepted = true;
                    i = j;
                }
                Some((n, off)) => {
                    let win = self.sm_len(n);
                    let take = (win - off).min(len - i);
                    let ok = match &mut op {
                        RamOp::Read(b) => {
                            self.sm_access(n, side, off, SmOp::Read(&mut b[i..i + take]))
                        }
                        RamOp::Write(d) => {
                            self.sm_access(n, side, off, SmOp::Write(&d[i..i + take]))
                        }
                    };
                    accepted |= ok;
                    i += take;
                }
            }
        }
        accepted
    }

    fn sm_access(&mut self, n: usize, side: Side, off: usize, op: SmOp<'_>) -> bool {
        let ctl = self.sm_control(n);
        let ecat_writes = ctl & 0x0C == 0x04;
        // The master produces for a write-direction SM, the PDI for a read-direction one.
        let producer = if ecat_writes { Side::Ecat } else { Side::Pdi };
        let is_write = matches!(op, SmOp::Write(_));
        if is_write != (side == producer) {
            return false;
        }
        match side {
            Side::Pdi => self.al_event_clear(reg::al_event::sm(n as u8)),
            Side::Ecat if n < 8 => self.ecat_event_clear(1 << (4 + n)),
            Side::Ecat => {}
        }
        let start = self.sm_start(n);
        let win = self.sm_len(n);
        let mailbox = ctl & 0x03 == 0x02;
        let outcome = self.sms[n].access(&mut self.mem, start, win, mailbox, off, op);
        if let Some(ev) = outcome.event {
            // The event goes to the other side of the SM.
            let to = if ev == sm::Event::Written {
                other(producer)
            } else {
                producer
            };
            match to {
                Side::Pdi => {
                    if ctl & 0x20 != 0 {
                        self.al_event_set(reg::al_event::sm(n as u8));
                    }
                }
                Side::Ecat => {
                    if ctl & 0x10 != 0 && n < 8 {
                        self.ecat_event_set(1 << (4 + n));
                    }
                }
            }
            if ev == sm::Event::Written && side == Side::Ecat && ctl & 0x40 != 0 {
                self.pd_watchdog_trigger();
            }
        }
        self.sm_update_status(n);
        outcome.accepted
    }

    pub(crate) fn set_frame_timing(&mut self, timing: FrameTiming) {
        self.timing = timing;
    }
}

fn other(side: Side) -> Side {
    match side {
        Side::Ecat => Side::Pdi,
        Side::Pdi => Side::Ecat,
    }
}

enum RamOp<'a> {
    Read(&'a mut [u8]),
    Write(&'a [u8]),
}
impl RamOp<'_> {
    fn len(&self) -> usize {
        match self {
            RamOp::Read(b) => b.len(),
            RamOp::Write(d) => d.len(),
        }
    }
}

pub(crate) use sm::SmOp;

/// A simulator shared between the wire side (the segment, or `virtual-drive`'s frame
/// thread) and the PDI side (the firmware, directly or through an SPI chip model).
///
/// Each side holds the lock for one access only (one frame on the wire side, one
/// register or RAM access on the PDI side), as the chip serialises its ECAT and PDI
/// accesses: so the wire side never waits for the application, only for the access
/// in progress (the lock has priority inheritance, [`PiMutex`]). One thread holds at
/// most one simulator's lock at a time, except the wire side, which takes a line's in
/// order.
#[derive(Clone)]
pub struct SharedEsc(pub Arc<PiMutex<EscSim>>);

impl SharedEsc {
    /// Wraps a simulator.
    pub fn new(esc: EscSim) -> Self {
        SharedEsc(Arc::new(PiMutex::new(esc)))
    }
    /// The simulator, for reading.
    pub fn borrow(&self) -> PiGuard<'_, EscSim> {
        self.0.lock()
    }
    /// The simulator, for changing.
    pub fn borrow_mut(&self) -> PiGuard<'_, EscSim> {
        self.0.lock()
    }
}

impl EscAccess for SharedEsc {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EscError> {
        EscAccess::read(&mut *self.borrow_mut(), addr, buf)
    }
    fn write(&mut self, addr: u16, data: &[u8]) -> Result<(), EscError> {
        EscAccess::write(&mut *self.borrow_mut(), addr, data)
    }
}

impl EscAccess for EscSim {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EscError> {
        if addr as usize + buf.len() > self.mem.len() {
            return Err(EscError::OutOfRange);
        }
        self.side_read(Side::Pdi, addr, buf);
        Ok(())
    }
    fn write(&mut self, addr: u16, data: &[u8]) -> Result<(), EscError> {
        if addr as usize + data.len() > self.mem.len() {
            return Err(EscError::OutOfRange);
        }
        self.side_write(Side::Pdi, addr, data);
        Ok(())
    }
}
