//! Synchronisation: free-run, SM2-synchronous and DC SYNC0 operation, the objects
//! 0x1C32 / 0x1C33, SYNC0 supervision and the timing diagnostics object (at the
//! index the product chooses in its range, [`SyncState::diag_index`]).
//!
//! # Modes
//! * **Free run** (0x1C32:01 = 0): the application cycle runs on a local timer with
//!   the period of 0x1C32:02 (1 ms when 0; SI2 then reads 1 000 000); process data
//!   are exchanged whenever the master updates them.
//! * **SM2-synchronous** (0x1C32:01 = 1, 0x1C33:01 = 0x22): one cycle per SM2 event
//!   (outputs written by the master); with no outputs mapped, per SM3 event
//!   (0x1C33:01 = 1). The default when DC is off.
//! * **DC SYNC0** (0x1C32:01 = 0x1C33:01 = 2): one cycle per SYNC0 event; the
//!   outputs of the last SM2 event are applied.
//!
//! # P→S checks ([`resolve_mode`])
//! DC activation 0x0981 bits 2:0 must be 000 (off) or 011 (SYNC0) → else 0x0030; a
//! sync type written by the master that is unsupported or disagrees with 0x0981 →
//! 0x0028; with SYNC0 the cycle time 0x09A0 must be a multiple of 125 µs from 125 µs
//! to 4 ms and not below the product's minimum (0x1C32:05) → else 0x0035. A product
//! whose minimum is 62.5 µs (`SlaveConfig::min_cycle_ns`) also accepts 62.5 µs.
//!
//! Without a sync type written in Pre-Op the mode follows 0x0981: SYNC0 active →
//! DC SYNC0 (0x1C32:01 = 0x1C33:01 = 2, SI2 = 0x09A0), else SM-synchronous. Masters
//! that arm SYNC0 only after requesting Safe-Op (SOEM: `ecx_config_map_group`
//! requests Safe-Op, `ecx_dcsync0` follows) are served by the runtime reading
//! 0x0981/0x09A0 again in Safe-Op (at most once per ms, and at the S→O request,
//! `Slave::poll`): a consistent change switches the mode at once, an inconsistent one
//! refuses S→O with the same codes (→ Pre-Op + error, as a refused P→S).
//!
//! # Supervision (DC SYNC0, [`Sync0Supervisor`])
//! Every SYNC0 event is time-stamped with the caller's clock. An interval within
//! ±50 % of the configured cycle is "good"; 4 good intervals in a row = **locked**.
//! Not locked within 1 s of the S→O request → 0x002D (Pre-Op). Once locked: no SYNC0
//! for max(2 × cycle, 1 ms) → 0x002C (Safe-Op); 4 bad intervals in a row → lock lost
//! 0x0032 (Safe-Op). SM-event-missed accounting (ETG.1020, 0x1C32:0B / 0x1C32:0C): at each SYNC0 in Op,
//! +3 if no SM2 event arrived since the previous SYNC0, −1 (down to 0) otherwise
//! (0x1C32:0B); above the limit 0x10F1:02 → 0x001A (Safe-Op). A cycle whose
//! computation outlasts the cycle time counts in 0x1C32:0C. 0x1C32:20 is set while
//! the missed counter is above the limit or 0x1C32:0C is non-zero.
//!
//! # Timing diagnostics (read-only, µs, reset on P→S and by writing 1 to 0x1C32:08)
//! The product lists [`timing_diag_object`] of its index in its dictionary and passes
//! the same index in `SlaveConfig::timing_diag_index`; without one the runtime serves
//! no diagnostics object.
//! | sub | name | meaning |
//! |---|---|---|
//! | 1 | PDI period | time between the last two process-data cycles |
//! | 2 | SYNC0 period | time between the last two SYNC0 events |
//! | 3 | SYNC0 period min | smallest SYNC0 period since reset |
//! | 4 | SYNC0 period max | largest SYNC0 period since reset |
//! | 5 | PDI-to-SYNC0 offset | time from the last SM2 event to the next SYNC0 |
//! | 6 | computation time | duration of the last application cycle (needs a clock from the application, else 0) |

use crate::al_status::AlStatusCode;
use crate::esm::EsmState;
use crate::od::{Access, DataType, EntryDesc, ObjectDesc, ObjectKey, SdoAbort};
use crate::pdo;
use crate::registers::DcActivation;

/// SM2 (outputs) sync parameters.
pub const SM2_SYNC: u16 = 0x1C32;
/// SM3 (inputs) sync parameters.
pub const SM3_SYNC: u16 = 0x1C33;
/// Supported sync types (0x1C32:04): free run, SM-synchronous, DC SYNC0.
pub const SUPPORTED_TYPES: u16 = 0x0007;
/// Smallest DC cycle accepted, ns.
pub const MIN_CYCLE_NS: u32 = 125_000;
/// Largest DC cycle accepted, ns.
pub const MAX_CYCLE_NS: u32 = 4_000_000;
/// Cycle granularity, ns.
pub const CYCLE_STEP_NS: u32 = 125_000;
/// Free-run period when 0x1C32:02 is 0, µs.
pub const DEFAULT_FREE_RUN_US: u32 = 1000;
/// Time allowed to lock to SYNC0 after the S→O request, µs.
pub const LOCK_TIMEOUT_US: u64 = 1_000_000;
/// Good intervals in a row that make a lock.
pub const LOCK_COUNT: u8 = 4;
/// Bad intervals in a row that lose it.
pub const LOST_COUNT: u8 = 4;

/// Synchronisation mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SyncMode {
    /// Local timer.
    FreeRun,
    /// SM2 event (or SM3 event without outputs).
    #[default]
    SmSync,
    /// DC SYNC0 event.
    DcSync0,
}

impl SyncMode {
    /// 0x1C32:01 value.
    pub const fn sm2_type(self) -> u16 {
        match self {
            Self::FreeRun => 0,
            Self::SmSync => 1,
            Self::DcSync0 => 2,
        }
    }
    /// 0x1C33:01 value (`outputs`: SM2 carries data).
    pub const fn sm3_type(self, outputs: bool) -> u16 {
        match self {
            Self::FreeRun => 0,
            Self::SmSync => {
                if outputs {
                    0x22
                } else {
                    1
                }
            }
            Self::DcSync0 => 2,
        }
    }
}

/// The 62.5 µs cycle (stretch goal), accepted only when the product allows it.
pub const HALF_STEP_CYCLE_NS: u32 = 62_500;

/// Checks a DC SYNC0 cycle time: every multiple of 125 µs from 125 µs to 4 ms.
pub const fn check_cycle(cycle_ns: u32) -> Result<(), AlStatusCode> {
    check_cycle_min(cycle_ns, MIN_CYCLE_NS)
}

/// Checks a DC SYNC0 cycle time against the product's shortest cycle `min_cycle_ns`
/// (0x1C32:05): every multiple of 125 µs from max(125 µs, minimum) to 4 ms, plus
/// 62.5 µs when the minimum allows it → else 0x0035.
pub const fn check_cycle_min(cycle_ns: u32, min_cycle_ns: u32) -> Result<(), AlStatusCode> {
    if cycle_ns == HALF_STEP_CYCLE_NS && min_cycle_ns <= HALF_STEP_CYCLE_NS {
        return Ok(());
    }
    if cycle_ns < MIN_CYCLE_NS
        || cycle_ns < min_cycle_ns
        || cycle_ns > MAX_CYCLE_NS
        || !cycle_ns.is_multiple_of(CYCLE_STEP_NS)
    {
        Err(AlStatusCode::DcInvalidCycleTime)
    } else {
        Ok(())
    }
}

/// The P→S sync decision (module docs): `written_sm2` / `written_sm3` are the sync
/// types the master wrote in this Pre-Op (None = not written), `dc_activation` is
/// 0x0981, `sync0_cycle_ns` 0x09A0, `outputs` whether SM2 carries data.
pub fn resolve_mode(
    written_sm2: Option<u16>,
    written_sm3: Option<u16>,
    dc_activation: u8,
    sync0_cycle_ns: u32,
    outputs: bool,
    min_cycle_ns: u32,
) -> Result<SyncMode, AlStatusCode> {
    let unsupported = Err(AlStatusCode::SyncModeNotSupported);
    let act = DcActivation::from_raw(dc_activation);
    if !act.off() && !act.sync0_only() {
        return Err(AlStatusCode::InvalidDcSync);
    }
    let mode = if act.sync0_only() {
        SyncMode::DcSync0
    } else {
        match written_sm2 {
            Some(0) => SyncMode::FreeRun,
            Some(1) => SyncMode::SmSync,
            Some(_) => return unsupported,
            None => match written_sm3 {
                Some(0) if !outputs => SyncMode::FreeRun,
                _ => SyncMode::SmSync,
            },
        }
    };
    if let Some(t) = written_sm2 {
        if t != mode.sm2_type() {
            return unsupported;
        }
    }
    if let Some(t) = written_sm3 {
        let ok = t == mode.sm3_type(outputs) || (mode == SyncMode::SmSync && t == 0x22);
        if !ok {
            return unsupported;
        }
    }
    if mode == SyncMode::DcSync0 {
        check_cycle_min(sync0_cycle_ns, min_cycle_ns)?;
    }
    Ok(mode)
}

/// What a SYNC0 or a supervision check reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SyncEvent {
    /// Nothing special.
    None,
    /// Lock obtained now.
    Locked,
    /// A supervision error.
    Error(AlStatusCode),
}

/// SYNC0 lock supervision (module docs). Times in µs of the caller's clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Sync0Supervisor {
    cycle_us: u32,
    last: Option<u64>,
    good: u8,
    bad: u8,
    locked: bool,
    active: bool,
}

impl Sync0Supervisor {
    /// Starts supervising a SYNC0 of `cycle_ns`.
    pub fn start(&mut self, cycle_ns: u32) {
        *self = Sync0Supervisor {
            cycle_us: (cycle_ns / 1000).max(1),
            active: true,
            ..Default::default()
        };
    }
    /// Stops supervising.
    pub fn stop(&mut self) {
        *self = Sync0Supervisor::default();
    }
    /// Supervising.
    pub const fn active(&self) -> bool {
        self.active
    }
    /// Locked to SYNC0.
    pub const fn locked(&self) -> bool {
        self.locked
    }
    /// Configured cycle, µs.
    pub const fn cycle_us(&self) -> u32 {
        self.cycle_us
    }
    /// No-SYNC0 time after which a locked slave reports 0x002C: max(2 × cycle, 1 ms).
    pub const fn watchdog_us(&self) -> u64 {
        let w = 2 * self.cycle_us as u64;
        if w < 1000 {
            1000
        } else {
            w
        }
    }
    /// One SYNC0 event at `now`; returns the interval to the previous one.
    pub fn on_sync0(&mut self, now: u64) -> (SyncEvent, Option<u64>) {
        if !self.active {
            return (SyncEvent::None, None);
        }
        let prev = self.last.replace(now);
        let Some(prev) = prev else {
            return (SyncEvent::None, None);
        };
        let interval = now.saturating_sub(prev);
        let c = self.cycle_us as u64;
        let tol = c / 2;
        if interval + tol >= c && interval <= c + tol {
            self.good = self.good.saturating_add(1);
            self.bad = 0;
            if !self.locked && self.good >= LOCK_COUNT {
                self.locked = true;
                return (SyncEvent::Locked, Some(interval));
            }
        } else {
            self.bad = self.bad.saturating_add(1);
            self.good = 0;
            if self.locked && self.bad >= LOST_COUNT {
                self.locked = false;
                return (SyncEvent::Error(AlStatusCode::PllError), Some(interval));
            }
        }
        (SyncEvent::None, Some(interval))
    }
    /// Checks for missing SYNC0 events at `now`.
    pub fn check(&mut self, now: u64) -> SyncEvent {
        if self.active && self.locked {
            if let Some(last) = self.last {
                if now.saturating_sub(last) > self.watchdog_us() {
                    self.locked = false;
                    return SyncEvent::Error(AlStatusCode::FatalSyncError);
                }
            }
        }
        SyncEvent::None
    }
}

/// Parameters of one of 0x1C32 / 0x1C33.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SyncParams {
    /// SI1 sync type.
    pub sync_type: u16,
    /// SI1 written by the master in this Pre-Op.
    pub written_type: Option<u16>,
    /// SI2 cycle time, ns.
    pub cycle_ns: u32,
    /// SI3 shift time, ns.
    pub shift_ns: u32,
    /// SI6 calc and copy time, ns.
    pub calc_copy_ns: u32,
    /// SI9 delay time, ns.
    pub delay_ns: u32,
    /// SI0A SYNC0 cycle time, ns.
    pub sync0_cycle_ns: u32,
    /// SI0B SM event missed counter.
    pub sm_event_missed: u16,
    /// SI0C cycle time too small counter.
    pub cycle_too_small: u16,
    /// SI20 sync error.
    pub sync_error: bool,
}

/// Timing diagnostics, µs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TimingDiag {
    /// :01 PDI period.
    pub pdi_period: u32,
    /// :02 SYNC0 period.
    pub sync0_period: u32,
    /// :03 SYNC0 period min (0 until measured).
    pub sync0_min: u32,
    /// :04 SYNC0 period max.
    pub sync0_max: u32,
    /// :05 SM2 event to next SYNC0.
    pub pdi_to_sync0: u32,
    /// :06 computation time of the last cycle.
    pub compute: u32,
}

impl TimingDiag {
    /// Records a SYNC0 period.
    pub fn sync0_period(&mut self, us: u64) {
        let v = us.min(u32::MAX as u64) as u32;
        self.sync0_period = v;
        if self.sync0_min == 0 || v < self.sync0_min {
            self.sync0_min = v;
        }
        if v > self.sync0_max {
            self.sync0_max = v;
        }
    }
}

/// The sync state of the slave: mode, both parameter objects, supervision,
/// diagnostics, missed-event accounting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SyncState {
    /// Mode chosen at P→S.
    pub mode: SyncMode,
    /// 0x1C32.
    pub sm2: SyncParams,
    /// 0x1C33.
    pub sm3: SyncParams,
    /// SYNC0 lock supervision.
    pub sup: Sync0Supervisor,
    /// The timing diagnostics object's values.
    pub diag: TimingDiag,
    /// Index of the timing diagnostics object (the product's choice); `None`: not
    /// served.
    pub diag_index: Option<u16>,
    /// Time of the last SM2 event (µs).
    pub last_sm2: Option<u64>,
    /// Time of the last process-data cycle (µs).
    pub last_cycle: Option<u64>,
    /// An SM2 event arrived since the last SYNC0.
    pub sm2_since_sync0: bool,
    /// Measurement running (0x1C32:08).
    pub measuring: bool,
    /// Shortest DC cycle accepted (0x1C32:05), ns.
    pub min_cycle_ns: u32,
}

fn put(buf: &mut [u8], v: &[u8]) -> Result<usize, SdoAbort> {
    let d = buf.get_mut(..v.len()).ok_or(SdoAbort::ExceedsMailbox)?;
    d.copy_from_slice(v);
    Ok(v.len())
}

impl SyncState {
    /// Init state; `calc_copy_ns` are the product's calc-and-copy times (outputs,
    /// inputs) reported in SI6.
    pub fn new(calc_copy_ns: (u32, u32)) -> Self {
        let mut s = SyncState::default();
        s.sm2.calc_copy_ns = calc_copy_ns.0;
        s.sm3.calc_copy_ns = calc_copy_ns.1;
        s.sm2.sync_type = 1;
        s.sm3.sync_type = 0x22;
        s.min_cycle_ns = MIN_CYCLE_NS;
        s
    }

    /// Leaving Pre-Op downwards: forget what the master wrote.
    pub fn reset_written(&mut self) {
        self.sm2.written_type = None;
        self.sm3.written_type = None;
    }

    /// Resets counters and diagnostics (P→S, 0x1C32:08 = 1).
    pub fn reset_counters(&mut self) {
        for p in [&mut self.sm2, &mut self.sm3] {
            p.sm_event_missed = 0;
            p.cycle_too_small = 0;
            p.sync_error = false;
        }
        self.diag = TimingDiag::default();
        self.last_sm2 = None;
        self.last_cycle = None;
        self.sm2_since_sync0 = false;
    }

    /// Applies the mode resolved at P→S and reports it in SI1/SI2/SI0A.
    pub fn enter(&mut self, mode: SyncMode, sync0_cycle_ns: u32, outputs: bool) {
        self.mode = mode;
        self.sm2.sync_type = mode.sm2_type();
        self.sm3.sync_type = mode.sm3_type(outputs);
        self.reset_counters();
        if mode == SyncMode::DcSync0 {
            for p in [&mut self.sm2, &mut self.sm3] {
                p.cycle_ns = sync0_cycle_ns;
                p.sync0_cycle_ns = sync0_cycle_ns;
            }
            self.sup.start(sync0_cycle_ns);
        } else {
            self.sup.stop();
        }
    }

    /// Leaving Safe-Op/Op.
    pub fn leave(&mut self) {
        self.sup.stop();
    }

    /// Free-run period, µs.
    pub fn free_run_period_us(&self) -> u32 {
        if self.sm2.cycle_ns == 0 {
            DEFAULT_FREE_RUN_US
        } else {
            (self.sm2.cycle_ns / 1000).max(1)
        }
    }

    /// The cycle time used for the watchdog check, ns (0 = unknown).
    pub fn cycle_ns(&self) -> u32 {
        self.sm2.cycle_ns
    }

    /// SM-event-missed accounting at a SYNC0 in Op; returns 0x001A when the counter
    /// exceeds `limit`.
    pub fn account_sm_event(&mut self, got_sm2: bool, limit: u16) -> Option<AlStatusCode> {
        let c = &mut self.sm2.sm_event_missed;
        if got_sm2 {
            *c = c.saturating_sub(1);
        } else {
            *c = c.saturating_add(3);
        }
        self.update_sync_error(limit);
        if self.sm2.sm_event_missed > limit {
            Some(AlStatusCode::SyncError)
        } else {
            None
        }
    }

    /// Records the computation time of one cycle; counts an overrun.
    pub fn computation(&mut self, us: u64, limit: u16) {
        self.diag.compute = us.min(u32::MAX as u64) as u32;
        let cycle = self.sm2.cycle_ns as u64;
        if cycle != 0 && us * 1000 > cycle {
            self.sm2.cycle_too_small = self.sm2.cycle_too_small.saturating_add(1);
        }
        self.update_sync_error(limit);
    }

    fn update_sync_error(&mut self, limit: u16) {
        let e = self.sm2.sm_event_missed > limit || self.sm2.cycle_too_small > 0;
        self.sm2.sync_error = e;
        self.sm3.sync_error = e;
        self.sm3.sm_event_missed = self.sm2.sm_event_missed;
        self.sm3.cycle_too_small = self.sm2.cycle_too_small;
    }

    /// True for the indices this state serves: 0x1C32, 0x1C33 and the timing
    /// diagnostics object.
    pub fn serves(&self, index: u16) -> bool {
        is_sync_index(index) || self.diag_index == Some(index)
    }

    /// Reads 0x1C32 / 0x1C33 / the timing diagnostics.
    pub fn read(&self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        let ObjectKey { index, sub } = key;
        if self.diag_index == Some(index) {
            let d = &self.diag;
            let v = match sub {
                0 => return put(buf, &[6]),
                1 => d.pdi_period,
                2 => d.sync0_period,
                3 => d.sync0_min,
                4 => d.sync0_max,
                5 => d.pdi_to_sync0,
                6 => d.compute,
                _ => return Err(SdoAbort::SubindexDoesNotExist),
            };
            return put(buf, &v.to_le_bytes());
        }
        let p = match index {
            SM2_SYNC => &self.sm2,
            SM3_SYNC => &self.sm3,
            _ => return Err(SdoAbort::ObjectDoesNotExist),
        };
        // (value, length in bytes): one `put` for every sub-index.
        let (v, n): (u32, usize) = match sub {
            0 => (0x20, 1),
            1 => (p.sync_type as u32, 2),
            2 => {
                // Without a written cycle: the measured master cycle (SM-synchronous)
                // or the local timer's period (free run).
                let v = match (self.mode, p.cycle_ns) {
                    (SyncMode::SmSync, 0) => self.diag.pdi_period.saturating_mul(1000),
                    (SyncMode::FreeRun, 0) => DEFAULT_FREE_RUN_US * 1000,
                    (_, c) => c,
                };
                (v, 4)
            }
            3 => (p.shift_ns, 4),
            4 => (SUPPORTED_TYPES as u32, 2),
            5 => (self.min_cycle_ns, 4),
            6 => (p.calc_copy_ns, 4),
            7 => (0, 4),
            8 => (self.measuring as u32, 2),
            9 => (p.delay_ns, 4),
            0x0A => (p.sync0_cycle_ns, 4),
            0x0B => (p.sm_event_missed as u32, 2),
            0x0C => (p.cycle_too_small as u32, 2),
            0x0D | 0x0E => (0, 2),
            0x20 => (p.sync_error as u32, 1),
            _ => return Err(SdoAbort::SubindexDoesNotExist),
        };
        put(buf, &v.to_le_bytes()[..n])
    }

    /// Writes 0x1C32 / 0x1C33 (SI1 and SI2 in Pre-Op, SI8 always) and refuses the
    /// rest as read-only.
    pub fn write(&mut self, key: ObjectKey, data: &[u8], state: EsmState) -> Result<(), SdoAbort> {
        let ObjectKey { index, sub } = key;
        if self.diag_index == Some(index) {
            return if sub <= 6 {
                Err(SdoAbort::WriteReadOnly)
            } else {
                Err(SdoAbort::SubindexDoesNotExist)
            };
        }
        let sm2 = match index {
            SM2_SYNC => true,
            SM3_SYNC => false,
            _ => return Err(SdoAbort::ObjectDoesNotExist),
        };
        match sub {
            1 => {
                let v = u16::from_le_bytes(pdo::exact(data)?);
                if state != EsmState::PreOp {
                    return Err(SdoAbort::StateConflict);
                }
                if !matches!(v, 0 | 1 | 2 | 3 | 0x22) {
                    return Err(SdoAbort::ValueRangeExceeded);
                }
                let p = if sm2 { &mut self.sm2 } else { &mut self.sm3 };
                p.sync_type = v;
                p.written_type = Some(v);
                Ok(())
            }
            2 => {
                let v = u32::from_le_bytes(pdo::exact(data)?);
                if state != EsmState::PreOp {
                    return Err(SdoAbort::StateConflict);
                }
                if sm2 {
                    self.sm2.cycle_ns = v;
                } else {
                    self.sm3.cycle_ns = v;
                }
                Ok(())
            }
            8 => {
                match u16::from_le_bytes(pdo::exact(data)?) {
                    0 => self.measuring = false,
                    1 => {
                        self.measuring = true;
                        self.reset_counters();
                    }
                    _ => return Err(SdoAbort::ValueRangeExceeded),
                }
                Ok(())
            }
            0 | 3..=7 | 9..=0x0E | 0x20 => Err(SdoAbort::WriteReadOnly),
            _ => Err(SdoAbort::SubindexDoesNotExist),
        }
    }
}

/// True for the sync parameter objects 0x1C32 / 0x1C33 (the timing diagnostics
/// object is at the product's index: [`SyncState::serves`]).
pub const fn is_sync_index(index: u16) -> bool {
    matches!(index, SM2_SYNC | SM3_SYNC)
}

macro_rules! sync_entries {
    ($dir:literal) => {
        &[
            EntryDesc::new(0, "Number of entries", DataType::Unsigned8, Access::RO).default(0x20),
            EntryDesc::new(
                1,
                "Synchronization type",
                DataType::Unsigned16,
                Access::RW_PREOP,
            )
            .range(0, 0x22),
            EntryDesc::new(2, "Cycle time", DataType::Unsigned32, Access::RW_PREOP).unit("ns"),
            EntryDesc::new(3, "Shift time", DataType::Unsigned32, Access::RO).unit("ns"),
            EntryDesc::new(4, "Sync types supported", DataType::Unsigned16, Access::RO)
                .default(SUPPORTED_TYPES as i64),
            EntryDesc::new(5, "Minimum cycle time", DataType::Unsigned32, Access::RO)
                .default(MIN_CYCLE_NS as i64)
                .unit("ns"),
            EntryDesc::new(
                6,
                concat!("Calc and copy time (", $dir, ")"),
                DataType::Unsigned32,
                Access::RO,
            )
            .unit("ns"),
            EntryDesc::new(7, "Minimum delay time", DataType::Unsigned32, Access::RO).unit("ns"),
            EntryDesc::new(8, "Get cycle time", DataType::Unsigned16, Access::RW).range(0, 1),
            EntryDesc::new(9, "Delay time", DataType::Unsigned32, Access::RO).unit("ns"),
            EntryDesc::new(0x0A, "SYNC0 cycle time", DataType::Unsigned32, Access::RO).unit("ns"),
            EntryDesc::new(0x0B, "SM event missed", DataType::Unsigned16, Access::RO),
            EntryDesc::new(
                0x0C,
                "Cycle time too small",
                DataType::Unsigned16,
                Access::RO,
            ),
            EntryDesc::new(
                0x0D,
                "Shift time too short",
                DataType::Unsigned16,
                Access::RO,
            ),
            EntryDesc::new(
                0x0E,
                "RxPDO toggle failed",
                DataType::Unsigned16,
                Access::RO,
            ),
            EntryDesc::new(0x20, "Sync error", DataType::Boolean, Access::RO),
        ]
    };
}

const SM2_SYNC_ENTRIES: &[EntryDesc] = sync_entries!("outputs");
const SM3_SYNC_ENTRIES: &[EntryDesc] = sync_entries!("inputs");

/// Description of 0x1C32.
pub const SM2_SYNC_OBJECT: ObjectDesc = ObjectDesc::record(
    SM2_SYNC,
    "SM output parameter",
    SM2_SYNC_ENTRIES,
    "Synchronisation of the outputs (SM2): sync type 0 free run, 1 SM2 event, 2 DC SYNC0",
);

/// Description of 0x1C33.
pub const SM3_SYNC_OBJECT: ObjectDesc = ObjectDesc::record(SM3_SYNC, "SM input parameter", SM3_SYNC_ENTRIES, "Synchronisation of the inputs (SM3): sync type 0 free run, 0x22 SM2 event, 1 SM3 event, 2 DC SYNC0");

const DIAG_ENTRIES: &[EntryDesc] = &[
    EntryDesc::new(0, "Number of entries", DataType::Unsigned8, Access::RO).default(6),
    EntryDesc::new(1, "PDI period", DataType::Unsigned32, Access::RO).unit("us"),
    EntryDesc::new(2, "SYNC0 period", DataType::Unsigned32, Access::RO).unit("us"),
    EntryDesc::new(3, "SYNC0 period min", DataType::Unsigned32, Access::RO).unit("us"),
    EntryDesc::new(4, "SYNC0 period max", DataType::Unsigned32, Access::RO).unit("us"),
    EntryDesc::new(5, "PDI to SYNC0 offset", DataType::Unsigned32, Access::RO).unit("us"),
    EntryDesc::new(6, "Computation time", DataType::Unsigned32, Access::RO).unit("us"),
];

/// The timing diagnostics object at `index` (the product's choice in its range; the
/// same index goes into `SlaveConfig::timing_diag_index`).
pub const fn timing_diag_object(index: u16) -> ObjectDesc {
    ObjectDesc::record(index, "Timing diagnostics", DIAG_ENTRIES, "Measured periods and times of the cyclic path in µs; reset on Pre-Op→Safe-Op and by 0x1C32:08 = 1")
}

#[cfg(test)]
mod tests;
