//! Faults and protections (`docs/safety.md`): detection from measured values,
//! the 0x603F error code, the 0x1001 error register, one emergency per occurrence,
//! the PDS fault request, the alarm output, latching (0x2057), masking (0x2056), and
//! the history of the last six faults with a snapshot (objects 0x2400-0x2406), kept
//! in flash across power cycles.
//!
//! Every fault kind's code, error-register bits, red-LED flashes, reaction, latching,
//! 0x2056 bit, protection class and text are stated once, in [`TABLE`]; everything
//! else (the [`FaultKind`] accessors, the diagnosis texts of [`crate::diagnosis`],
//! the board's status line, `virtual-drive --help`, `docs/faults.md` by
//! `cargo xtask faults-doc`) is derived from it.
//!
//! **Reaction** ([`FaultKind::cuts_power`]): "power off at once" withdraws the power
//! stage in the same supervision tick (the motor coasts, the brake engages); the
//! others run the CiA 402 fault reaction 0x605E on the drive's clock, with the power
//! stage on until the motor stands, then Fault.
//!
//! The rows are in order of severity (the red LED shows the most severe active fault;
//! 0x603F reports the most severe active fault's code, 0 when none). Motor blocked
//! comes last: its kind number (7) follows the older kinds, so the stored histories
//! keep their meaning. It is an event of the stall detector (`motion`); its
//! condition is gone at once, so a fault reset clears it.
//!
//! **0x2056** (default 0x00C3): a set bit *enables* the detection of the kind whose
//! row names it; a kind without a bit cannot be masked there. A protective kind
//! ([`FaultInfo::protective`]) is reported whatever the mask says when its cause has
//! already taken the torque away.
//!
//! **Latching**: a latched fault survives fault reset until power is cycled, unless
//! 0x2057 = 1. Every fault also stays until its condition is gone. Fault reset
//! comes from the controlword bit 7 edge (CiA 402 helper) or a fault-clear input edge
//! (I/O): both call [`Faults::fault_reset`].
//!
//! **Emergencies**: one per occurrence (a fault that is already active does not send
//! again). Manufacturer data: byte 0 the [`FaultKind`] number, bytes 1-2 the bus
//! voltage in 0.1 V, bytes 3-4 a detail: the caller's EtherCAT diagnosis; for motor
//! open the reason (failed power-up tune: 1 open phase, 2 unbalanced phases,
//! 3 implausible result; 4 no current in a phase while running) and the phase
//! (0 A, 1 B); for "current does not follow"
//! (0x5210 while running) the reference current magnitude in mA (u16); 0 otherwise.
//! When a fault reset clears the last active fault, the CiA 301 "error reset"
//! emergency (code 0x0000) is sent.
//!
//! **Over-current recovery**: `Drive::tick` checks the measured phase currents
//! ([`Faults::check_phase_currents`]) and the power stage's break latch
//! (`AxisState::overcurrent_trip`); the condition is gone once both are clear (latch
//! re-armed), so a fault reset with 0x2057 = 1 clears the fault. Motor open (failed
//! power-up tune) and "current does not follow" are events (`Drive::current_report`,
//! `current_supervisor`): a fault reset clears them.
//!
//! **Persistent history**: the six history entries (and the operating-time counter
//! 0x2307 at the time of writing) survive power cycles in a record pair of their own
//! (`crate::storage::region::HISTORY`, the parameter storage's record code with its own
//! magic: erase, payload, header last, the newer valid record wins). Raising a fault
//! only marks the history dirty ([`Faults::history_dirty`]); the write is deferred
//! work of whoever services the parameter 'save' (`Drive::persist_history`: the
//! board's `ecat` task, the simulator's housekeeping), never the fault path. Each
//! entry carries the operating time (s since the drive was first powered, 0x2307)
//! when it happened, besides the time since that power-up. At power-up the stored
//! history is loaded ([`Faults::restore_history`]); anything that is not a valid
//! record (erased, torn by a power cut, garbage) gives the previous record or an empty
//! history. Clearing (0x2093 = 1, 0x1003:00 = 0) is written to the flash the same way.
//!
//! The table, the [`FaultKind`] accessors and [`Emergency`] are in `fault_table.rs`
//! (a layer below the diagnosis texts made from it); the objects 0x2400-0x2406 that
//! show the history are described and read in `dictionary/fault_history.rs` (the
//! dictionary reads the fault state; the fault logic does not look into the
//! dictionary).

use heapless::Deque;

use crate::fault_table::POWER_CUT_MASK;
pub use crate::fault_table::{Emergency, FaultInfo, FaultKind, KINDS, NO_MASK, TABLE};

/// Values captured when a fault occurs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Snapshot {
    /// Phase A current, mA.
    pub ia_ma: i16,
    /// Phase B current, mA.
    pub ib_ma: i16,
    /// Bus voltage, 0.1 V.
    pub bus_dv: u16,
    /// Position following error, command units.
    pub position_error: i32,
    /// Speed, command units/s.
    pub speed: i32,
}

/// One history entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FaultRecord {
    /// The kind.
    pub kind: FaultKind,
    /// Its 0x603F code.
    pub code: u16,
    /// Values at the time.
    pub snapshot: Snapshot,
    /// Milliseconds since power-up.
    pub time_ms: u32,
    /// Operating time (0x2307, s of powered time since the first power-up) when it
    /// happened.
    pub operating_s: u32,
}

/// Bytes of one history entry in the flash record: kind u8, 0, code u16, phase A and
/// B current i16, bus voltage u16, position error i32, speed i32, time since power-up
/// u32, operating time u32 (little-endian).
const RECORD_BYTES: usize = 26;

/// Bytes of the history record's payload: operating time u32 (0x2307 when written),
/// entry count u8, 3 × 0, then the entries newest first ([`Faults::encode_history`]).
pub const HISTORY_PAYLOAD_MAX: usize = 8 + HISTORY * RECORD_BYTES;

/// Thresholds of the protections.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FaultConfig {
    /// Over-voltage above this bus voltage, mV (55 V for the 50 V class).
    pub over_voltage_mv: u32,
    /// Under-voltage below this bus voltage, mV.
    pub under_voltage_mv: u32,
    /// Under-voltage clears above threshold + this, mV.
    pub under_voltage_hysteresis_mv: u32,
    /// Over-current above this phase current magnitude, mA.
    pub over_current_ma: u32,
}

impl FaultConfig {
    /// The product's thresholds.
    pub const DEFAULT: FaultConfig = FaultConfig {
        over_voltage_mv: 55_000,
        under_voltage_mv: 12_000,
        under_voltage_hysteresis_mv: 500,
        over_current_ma: 10_500,
    };
}

impl Default for FaultConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// History depth.
pub const HISTORY: usize = 6;

/// Fault state of the drive.
#[derive(Debug, Clone)]
pub struct Faults {
    cfg: FaultConfig,
    mask: u16,
    clear_allowed: bool,
    /// Bit n: [`FaultKind`] n active (one word: the drive cycle reads it every time).
    active: u8,
    present: [bool; KINDS],
    ecat_code: u16,
    /// A ring: `history[newest]` is the newest entry, older ones follow (a new fault
    /// moves `newest` back one slot instead of shifting the records).
    history: [Option<FaultRecord>; HISTORY],
    newest: u8,
    count: u16,
    pds_request: bool,
    emcy: Deque<Emergency, 8>,
    bus_dv: u16,
    uv_armed: bool,
    diag: crate::diagnosis::History,
    clock_ms: u32,
    /// The history changed since it was last written to flash.
    history_dirty: bool,
    /// Operating time at this power-up, s (0x2307 as restored).
    operating_base_s: u32,
}

impl Default for Faults {
    fn default() -> Self {
        Self::new(FaultConfig::default())
    }
}

impl Faults {
    /// Power-up state: nothing active, empty history, mask 0x00C3, no clearing of
    /// latched faults.
    pub fn new(cfg: FaultConfig) -> Self {
        Faults {
            cfg,
            mask: 0x00C3,
            clear_allowed: false,
            active: 0,
            present: [false; KINDS],
            ecat_code: 0,
            history: [None; HISTORY],
            newest: 0,
            count: 0,
            pds_request: false,
            emcy: Deque::new(),
            bus_dv: 0,
            uv_armed: false,
            diag: crate::diagnosis::History::new(),
            clock_ms: 0,
            history_dirty: false,
            operating_base_s: 0,
        }
    }

    /// Takes 0x2056 and 0x2057 (call when they change or every cycle).
    pub fn configure(&mut self, mask: u16, clear_allowed: bool) {
        self.mask = mask;
        self.clear_allowed = clear_allowed;
    }

    /// Applies 0x2054-0x2057 from the parameters: the bus-voltage thresholds (0x2055
    /// = 0: no under-voltage detection) and the mask and clear permission.
    pub fn configure_from(&mut self, p: &crate::params::Params) {
        use crate::params::Param;
        self.cfg.over_voltage_mv = p.get(Param::OverVoltageThreshold).max(0) as u32 * 1000;
        self.cfg.under_voltage_mv = p.get(Param::UnderVoltageThreshold).max(0) as u32 * 1000;
        self.configure(
            p.get(Param::FaultMask) as u16,
            p.get(Param::FaultClearAllowed) == 1,
        );
    }

    /// The thresholds.
    pub fn config(&self) -> FaultConfig {
        self.cfg
    }

    /// True when detection of `kind` is enabled by 0x2056.
    pub fn enabled(&self, kind: FaultKind) -> bool {
        kind.mask_bit().is_none_or(|b| self.mask & (1 << b) != 0)
    }

    /// Reports that the condition of `kind` is present. Returns true when this is a
    /// new occurrence (then one emergency is queued, the history gets an entry and the
    /// PDS fault request is set).
    pub fn raise(&mut self, kind: FaultKind, snap: Snapshot, now_ms: u32) -> bool {
        self.raise_with(kind, kind.code(), [0, 0], snap, now_ms)
    }

    /// [`Faults::raise`] with the two detail bytes of the emergency (bytes 3-4 of the
    /// manufacturer data).
    pub fn raise_detail(
        &mut self,
        kind: FaultKind,
        detail: [u8; 2],
        snap: Snapshot,
        now_ms: u32,
    ) -> bool {
        self.raise_with(kind, kind.code(), detail, snap, now_ms)
    }

    /// An EtherCAT fault with its code (0x8700 sync, 0xA000/0xA001 ESM transition,
    /// 0x8210/0x8220 PDO length, ...) and two diagnosis bytes for the emergency.
    pub fn raise_ecat(&mut self, code: u16, diag: [u8; 2], now_ms: u32) -> bool {
        let snap = Snapshot {
            bus_dv: self.bus_dv,
            ..Snapshot::default()
        };
        self.raise_with(FaultKind::Ecat, code, diag, snap, now_ms)
    }

    fn raise_with(
        &mut self,
        kind: FaultKind,
        code: u16,
        detail: [u8; 2],
        snap: Snapshot,
        now_ms: u32,
    ) -> bool {
        if !self.enabled(kind) {
            return false;
        }
        self.raise_always(kind, code, detail, snap, now_ms)
    }

    /// [`Faults::raise`] for a detection whose cause has already taken the torque away
    /// (a failed start-up current-sensor check, a latched trip of the current loop's
    /// fast protection): for a kind the table marks protective
    /// ([`FaultInfo::protective`]) it is reported whatever 0x2056 says — masking it
    /// would leave the drive enabled with no torque and nothing reported; any other
    /// kind follows 0x2056 as [`Faults::raise`] does.
    pub fn raise_unmaskable(&mut self, kind: FaultKind, snap: Snapshot, now_ms: u32) -> bool {
        if !kind.protective() {
            return self.raise(kind, snap, now_ms);
        }
        self.raise_always(kind, kind.code(), [0, 0], snap, now_ms)
    }

    fn raise_always(
        &mut self,
        kind: FaultKind,
        code: u16,
        detail: [u8; 2],
        snap: Snapshot,
        now_ms: u32,
    ) -> bool {
        let k = kind as usize;
        self.present[k] = true;
        if self.active & (1 << k) != 0 {
            return false;
        }
        self.active |= 1 << k;
        if kind == FaultKind::Ecat {
            self.ecat_code = code;
        }
        let slot = (usize::from(self.newest) + HISTORY - 1) % HISTORY;
        self.newest = slot as u8;
        self.history[slot] = Some(FaultRecord {
            kind,
            code,
            snapshot: snap,
            time_ms: now_ms,
            operating_s: self.operating_base_s.saturating_add(now_ms / 1000),
        });
        self.history_dirty = true;
        self.count = self.count.saturating_add(1);
        self.pds_request = true;
        let v = snap.bus_dv.to_le_bytes();
        let e = Emergency {
            code,
            register: self.error_register(),
            data: [kind as u8, v[0], v[1], detail[0], detail[1]],
        };
        self.send(e, true, now_ms);
        true
    }

    /// Queues an emergency and records it in the diagnosis history (0x10F3).
    fn send(&mut self, e: Emergency, fault: bool, now_ms: u32) {
        self.clock_ms = now_ms;
        self.diag
            .push(crate::diagnosis::message_for_emergency(&e, fault, now_ms));
        if self.emcy.is_full() {
            self.emcy.pop_front();
        }
        let _ = self.emcy.push_back(e);
    }

    /// The drive's clock for the messages that come without a time (ms since
    /// power-up; `Drive::tick` sets it).
    pub fn set_clock(&mut self, now_ms: u32) {
        self.clock_ms = now_ms;
    }

    /// The diagnosis history 0x10F3.
    pub fn diagnosis(&self) -> &crate::diagnosis::History {
        &self.diag
    }

    /// The diagnosis history 0x10F3, for SDO access and events of the drive.
    pub fn diagnosis_mut(&mut self) -> &mut crate::diagnosis::History {
        &mut self.diag
    }

    /// Reports that the condition of `kind` is gone (the fault itself stays until a
    /// fault reset).
    pub fn condition_gone(&mut self, kind: FaultKind) {
        self.present[kind as usize] = false;
    }

    /// Checks the bus voltage (mV): over- and under-voltage. Under-voltage is armed
    /// once the bus has reached threshold + hysteresis after power-up, so the rising
    /// supply at switch-on is not a fault.
    pub fn check_bus_voltage(&mut self, mv: u32, snap: Snapshot, now_ms: u32) {
        self.bus_dv = (mv / 100).min(u32::from(u16::MAX)) as u16;
        let snap = Snapshot {
            bus_dv: self.bus_dv,
            ..snap
        };
        if mv > self.cfg.over_voltage_mv {
            self.raise(FaultKind::OverVoltage, snap, now_ms);
        } else {
            self.condition_gone(FaultKind::OverVoltage);
        }
        if self.cfg.under_voltage_mv == 0 {
            // Switched off by 0x2055 = 0.
            self.uv_armed = false;
            self.condition_gone(FaultKind::UnderVoltage);
        } else if mv < self.cfg.under_voltage_mv {
            if self.uv_armed {
                self.raise(FaultKind::UnderVoltage, snap, now_ms);
            }
        } else if mv >= self.cfg.under_voltage_mv + self.cfg.under_voltage_hysteresis_mv {
            self.uv_armed = true;
            self.condition_gone(FaultKind::UnderVoltage);
        }
    }

    /// Checks the phase currents (mA) against the over-current limit. Returns true when
    /// the PWM must be switched off now.
    pub fn check_phase_currents(
        &mut self,
        ia_ma: i32,
        ib_ma: i32,
        snap: Snapshot,
        now_ms: u32,
    ) -> bool {
        let m = ia_ma.unsigned_abs().max(ib_ma.unsigned_abs());
        if m > self.cfg.over_current_ma {
            let snap = Snapshot {
                ia_ma: sat16(ia_ma),
                ib_ma: sat16(ib_ma),
                bus_dv: self.bus_dv,
                ..snap
            };
            self.raise(FaultKind::OverCurrent, snap, now_ms);
            true
        } else {
            self.condition_gone(FaultKind::OverCurrent);
            false
        }
    }

    /// Checks the following error (counts) against 0x2030.
    pub fn check_following_error(&mut self, error: i32, limit: u16, snap: Snapshot, now_ms: u32) {
        if error.unsigned_abs() > u32::from(limit) {
            let snap = Snapshot {
                position_error: error,
                bus_dv: self.bus_dv,
                ..snap
            };
            self.raise(FaultKind::FollowingError, snap, now_ms);
        } else {
            self.condition_gone(FaultKind::FollowingError);
        }
    }

    /// Fault reset (controlword bit 7 edge, fault-clear input, 0x2093): clears every
    /// active fault whose condition is gone and that is not latched (or 0x2057 = 1).
    /// Returns true when no fault is active afterwards.
    pub fn fault_reset(&mut self) -> bool {
        let had = self.any_active();
        for k in FaultKind::ALL {
            let i = k as usize;
            if self.active & (1 << i) != 0
                && !self.present[i]
                && (!k.latched() || self.clear_allowed)
            {
                self.active &= !(1 << i);
            }
        }
        let clear = !self.any_active();
        if had && clear {
            let e = Emergency {
                code: 0,
                register: 0,
                data: [0; 5],
            };
            self.send(e, false, self.clock_ms);
        }
        clear
    }

    /// True while `kind` is active.
    pub fn is_active(&self, kind: FaultKind) -> bool {
        self.active & (1 << kind as u8) != 0
    }

    /// True while a fault is active whose reaction is "power stage off at once"
    /// ([`FaultKind::cuts_power`]).
    pub fn power_cut(&self) -> bool {
        self.active & POWER_CUT_MASK != 0
    }

    /// Queues an emergency that reports an event without a fault (0x6007 = 2 or 3: the
    /// drive stopped on its own when the master's commands stopped): `code`, the
    /// error register of the active faults plus the communication bit, the diagnosis
    /// bytes as for [`Faults::raise_ecat`]. No history entry, no PDS fault.
    pub fn notify(&mut self, code: u16, diag: [u8; 2]) {
        let v = self.bus_dv.to_le_bytes();
        let e = Emergency {
            code,
            register: self.error_register() | FaultKind::Ecat.error_register(),
            data: [FaultKind::Ecat as u8, v[0], v[1], diag[0], diag[1]],
        };
        self.send(e, false, self.clock_ms);
    }

    /// True while any fault is active (alarm output, PDS stays in Fault).
    pub fn any_active(&self) -> bool {
        self.active != 0
    }

    /// Alarm output function (0x2005 bit 0).
    pub fn alarm(&self) -> bool {
        self.any_active()
    }

    /// The most severe active fault.
    pub fn most_severe(&self) -> Option<FaultKind> {
        if self.active == 0 {
            return None;
        }
        FaultKind::ALL.into_iter().find(|&k| self.is_active(k))
    }

    /// 0x603F: code of the most severe active fault, 0 when none. Out of line (several
    /// callers; the code size stays down).
    // Measured (cargo xtask size, LAN9252 image): without it, `history`'s and
    // `Cia402::probe_position`'s, +104 B flash (inlined into the control step and the SDO
    // read).
    #[inline(never)]
    pub fn error_code(&self) -> u16 {
        match self.most_severe() {
            Some(FaultKind::Ecat) => self.ecat_code,
            Some(k) => k.code(),
            None => 0,
        }
    }

    /// 0x1001: OR of the active faults' bits.
    pub fn error_register(&self) -> u8 {
        FaultKind::ALL
            .iter()
            .filter(|&&k| self.is_active(k))
            .fold(0, |r, &k| r | k.error_register())
    }

    /// Bit n set: [`FaultKind`] n active (0x2400:08).
    pub fn active_mask(&self) -> u16 {
        u16::from(self.active)
    }

    /// Flash count of the most severe active fault with a red LED code.
    pub fn led_code(&self) -> Option<u8> {
        FaultKind::ALL
            .into_iter()
            .filter(|&k| self.is_active(k))
            .find_map(|k| k.flashes())
    }

    /// True once per new fault: the CiA 402 state machine must go to Fault reaction
    /// active (605E reaction).
    pub fn take_pds_fault_request(&mut self) -> bool {
        core::mem::take(&mut self.pds_request)
    }

    /// Next emergency for the mailbox.
    pub fn pop_emergency(&mut self) -> Option<Emergency> {
        self.emcy.pop_front()
    }

    /// History entry `n` (0 = newest). Out of line: the SDO reads of 0x1003 and
    /// 0x2400-0x2406 call it from several places.
    // Measured (cargo xtask size, LAN9252 image): see `error_code`.
    #[inline(never)]
    pub fn history(&self, n: usize) -> Option<&FaultRecord> {
        if n >= HISTORY {
            return None;
        }
        self.history[(usize::from(self.newest) + n) % HISTORY].as_ref()
    }

    /// Faults since power-up.
    pub fn count(&self) -> u16 {
        self.count
    }

    /// Number of history entries present.
    pub fn history_len(&self) -> usize {
        self.history.iter().filter(|r| r.is_some()).count()
    }

    /// Empties the history (0x2093 = 1, 0x1003:00 = 0), in flash too at the next
    /// history write. Active faults stay.
    pub fn clear_history(&mut self) {
        self.history = [None; HISTORY];
        self.history_dirty = true;
    }

    /// The operating time (0x2307, s) at this power-up: entries raised from now on
    /// carry it plus their time since power-up.
    pub fn set_operating_base(&mut self, seconds: u32) {
        self.operating_base_s = seconds;
    }

    /// The history changed since the last [`Faults::history_written`]: a history write
    /// is due (deferred work, see the module docs).
    pub fn history_dirty(&self) -> bool {
        self.history_dirty
    }

    /// The history as it is now has been handed to the flash.
    pub fn history_written(&mut self) {
        self.history_dirty = false;
    }

    /// The history record's payload (see [`HISTORY_PAYLOAD_MAX`]) with `operating_s`
    /// (0x2307 now): its length.
    pub fn encode_history(&self, operating_s: u32, out: &mut [u8; HISTORY_PAYLOAD_MAX]) -> usize {
        out.fill(0);
        out[0..4].copy_from_slice(&operating_s.to_le_bytes());
        let mut n = 0usize;
        for (i, r) in (0..HISTORY).filter_map(|i| self.history(i)).enumerate() {
            let at = 8 + i * RECORD_BYTES;
            let Some(b) = out.get_mut(at..at + RECORD_BYTES) else {
                break;
            };
            let s = &r.snapshot;
            b[0] = r.kind as u8;
            b[2..4].copy_from_slice(&r.code.to_le_bytes());
            b[4..6].copy_from_slice(&s.ia_ma.to_le_bytes());
            b[6..8].copy_from_slice(&s.ib_ma.to_le_bytes());
            b[8..10].copy_from_slice(&s.bus_dv.to_le_bytes());
            b[10..14].copy_from_slice(&s.position_error.to_le_bytes());
            b[14..18].copy_from_slice(&s.speed.to_le_bytes());
            b[18..22].copy_from_slice(&r.time_ms.to_le_bytes());
            b[22..26].copy_from_slice(&r.operating_s.to_le_bytes());
            n = i + 1;
        }
        out[4] = n as u8;
        8 + n * RECORD_BYTES
    }

    /// Power-up: takes the history from a record payload ([`Faults::encode_history`]).
    /// Returns the operating time stored with it, or `None` (history left empty) when
    /// the payload is not a well-formed history: wrong length, too many entries, an
    /// unknown kind. Does not mark the history dirty.
    pub fn restore_history(&mut self, payload: &[u8]) -> Option<u32> {
        let head = payload.get(..8)?;
        let n = usize::from(head[4]);
        if n > HISTORY || payload.len() != 8 + n * RECORD_BYTES {
            return None;
        }
        let mut h: [Option<FaultRecord>; HISTORY] = [None; HISTORY];
        for (i, slot) in h.iter_mut().enumerate().take(n) {
            let b = payload.get(8 + i * RECORD_BYTES..8 + (i + 1) * RECORD_BYTES)?;
            let u16_at = |k: usize| u16::from_le_bytes([b[k], b[k + 1]]);
            let u32_at = |k: usize| u32::from_le_bytes([b[k], b[k + 1], b[k + 2], b[k + 3]]);
            *slot = Some(FaultRecord {
                kind: FaultKind::from_number(b[0])?,
                code: u16_at(2),
                snapshot: Snapshot {
                    ia_ma: u16_at(4) as i16,
                    ib_ma: u16_at(6) as i16,
                    bus_dv: u16_at(8),
                    position_error: u32_at(10) as i32,
                    speed: u32_at(14) as i32,
                },
                time_ms: u32_at(18),
                operating_s: u32_at(22),
            });
        }
        self.history = h;
        self.newest = 0;
        Some(u32::from_le_bytes([head[0], head[1], head[2], head[3]]))
    }
}

fn sat16(v: i32) -> i16 {
    v.clamp(i32::from(i16::MIN), i32::from(i16::MAX)) as i16
}
#[cfg(test)]
mod tests;
