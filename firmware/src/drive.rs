//! The drive application: everything between the EtherCAT slave runtime and the
//! motor-control loops.
//!
//! [`Drive`] owns the values of the product dictionary (communication objects,
//! vendor parameters, fault history, monitoring, CiA 402) and implements the slave
//! runtime's [`SlaveApplication`]: the dictionary ([`Dictionary`]), the cyclic data
//! ([`ProcessData`]), the ESM hooks (CiA 402 coupling) and the application cycle.
//!
//! # Two clocks, one drive
//!
//! The drive steps on **its own clock**: [`Drive::tick`] runs every millisecond on
//! the board (in every ESM state and sync mode, with or without frames) and, unless
//! the master's cycle stepped the drive within the last [`TICK_STEP_AFTER_US`], runs
//! a control step ([`Drive::step`]): the CiA 402 power drive system, the fault
//! reactions and stop ramps, the profile and homing generators, the brake. The
//! master's cycle ([`SlaveApplication::cycle`]) only brings set-points and takes
//! actual values; it steps the drive too, so that its set-points take effect in the
//! cycle that brought them. When the master's commands stop (SM watchdog, Op left,
//! SYNC0 lost) 0x6007 decides the reaction, and the ticks carry it out.
//!
//! ```text
//! board / simulator ──set_axis(AxisState)──▶ Drive ──▶ faults, I/O functions
//!                                              │
//!              tick (local clock) / cycle ──▶ Cia402::step (PDS, modes, homing, probe)
//!                                              │
//! board / simulator ◀──command()── DriveCommand (position/velocity set-point, power)
//! ```
//!
//! Emergencies produced by faults are collected here and forwarded by the owner to
//! the mailbox with [`Drive::pop_emergency`].

use ecat_slave_stack::al_status::AlStatusCode;
use ecat_slave_stack::esm::{EsmHooks, EsmState};
use ecat_slave_stack::od::{self, Dictionary, Object, SdoAbort};
use ecat_slave_stack::pdo::ProcessData;
use ecat_slave_stack::slave::{CycleInfo, SlaveApplication};

use crate::cia402::{AbortConnection, Cia402, DriveCommand, DriveFeedback, SetpointArrival};
use crate::comm::{Comm, StoreCommand};
use crate::current_supervisor::{CurrentReport, TuneStatus};
use crate::dictionary;
use crate::fault_led;
use crate::faults::{Emergency, FaultKind, Faults, Snapshot};
use crate::identity::{Identity, Variant};
use crate::io::{self, Inputs, OutputStatus};
use crate::monitor::Monitor;
use crate::params::{Param, Params};
use crate::storage::{LoadReport, SaveReport, SlotStatus, Storage, StorageError};
use crate::update::FirmwareUpdate;
use ecat_slave_stack::foe::FoeFiles;
use embedded_storage::nor_flash::NorFlash;

/// What the motor side measured, handed to the drive before each cycle (raw,
/// motor-side values in command units).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AxisState {
    /// Actual position, command units (0x2001 per revolution).
    pub position: i32,
    /// Actual velocity, command units/s.
    pub velocity: i32,
    /// Phase A current, mA.
    pub ia_ma: i16,
    /// Phase B current, mA.
    pub ib_ma: i16,
    /// Phase A set-point, mA.
    pub ia_set_ma: i16,
    /// Phase B set-point, mA.
    pub ib_set_ma: i16,
    /// Torque-producing current, per mille of the peak current 0x2000.
    pub current_permille: i16,
    /// Electrical angle, 1/65536 turn.
    pub electrical_angle: u16,
    /// DC bus voltage, mV.
    pub bus_mv: u32,
    /// Position latched at an encoder index pulse since the previous cycle.
    pub index: Option<i32>,
    /// Positions latched at the edges of input 1 since the previous cycle (touch probe
    /// 1; logical edges, 0x2154 applied: see [`crate::latch`]).
    pub probe1: crate::cia402::EdgeLatch,
    /// Positions latched at the edges of input 2 since the previous cycle (touch probe 2).
    pub probe2: crate::cia402::EdgeLatch,
    /// The power stage tripped (hardware over-current / break input).
    pub overcurrent_trip: bool,
    /// The servo is at its current limit.
    pub current_limited: bool,
    /// Following error between servo demand and encoder, encoder counts (closed loop;
    /// compared with 0x2030).
    pub servo_following_error: i32,
    /// The motor side cannot follow set-points at an enable yet: closed loop requested
    /// and the commutation alignment not done (`crate::commutation::CommutatedMotion::
    /// enable_pending`). CiA 402 transition 4 waits for it to clear while the motor side
    /// aligns ([`crate::cia402::DriveFeedback::enable_pending`]). False (the default):
    /// open loop, no encoder, aligned — no wait.
    pub commutation_pending: bool,
}

/// LED levels of the drive (RUN/ERR come from the slave runtime's indicators).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DriveLeds {
    /// Green power LED.
    pub green: bool,
    /// Red fault LED (blink code of the most severe active fault).
    pub red: bool,
}

/// Where 'save' / 'load' (0x1010 / 0x1011) go and where the power-up load comes from.
pub trait ParameterStore {
    /// Runs a store or restore command over the whole dictionary.
    fn execute(
        &mut self,
        cmd: StoreCommand,
        dict: &mut dyn Dictionary,
    ) -> Result<SaveReport, StorageError>;
    /// Power-up: applies the newest valid record to `dict`.
    fn load(&mut self, dict: &mut dyn Dictionary) -> LoadReport;
    /// Power-up: copies the payload of the newest valid fault-history record into
    /// `out` and returns its length; `None`: no history memory or no valid record.
    fn load_history(&mut self, out: &mut [u8]) -> Option<usize> {
        let _ = out;
        None
    }
    /// Writes a fault-history record (`crate::faults::Faults::encode_history`):
    /// `Ok(true)` written (or, on the board, staged for programming), `Ok(false)` no
    /// history memory (the history lives in RAM only).
    fn write_history(&mut self, payload: &[u8]) -> Result<bool, StorageError> {
        let _ = payload;
        Ok(false)
    }
}

/// The two-record flash store ([`Storage`]) over a [`NorFlash`], with the fault
/// history's own record pair in the same flash.
pub struct FlashStore<F: NorFlash> {
    /// Layout of the two parameter records.
    pub storage: Storage,
    /// Layout of the two fault-history records (`None`: the history is not kept
    /// across power cycles). See [`crate::storage::region`].
    pub history: Option<Storage>,
    /// The flash region.
    pub flash: F,
}

/// A parameter store whose flash is staged in RAM ([`crate::staged_flash`]): the
/// board's, whose records are programmed outside the drive's lock.
pub trait StagedStore<'a, R, const N: usize, const E: usize> {
    /// The staged flash view.
    fn staged(&mut self) -> &mut crate::staged_flash::StagedFlash<'a, R, N, E>;
}

impl<'a, R, const N: usize, const E: usize> StagedStore<'a, R, N, E>
    for FlashStore<crate::staged_flash::StagedFlash<'a, R, N, E>>
where
    crate::staged_flash::StagedFlash<'a, R, N, E>: NorFlash,
{
    fn staged(&mut self) -> &mut crate::staged_flash::StagedFlash<'a, R, N, E> {
        &mut self.flash
    }
}

impl<F: NorFlash> ParameterStore for FlashStore<F> {
    fn execute(
        &mut self,
        cmd: StoreCommand,
        dict: &mut dyn Dictionary,
    ) -> Result<SaveReport, StorageError> {
        crate::comm::execute(cmd, &self.storage, &mut self.flash, dict)
    }
    fn load(&mut self, dict: &mut dyn Dictionary) -> LoadReport {
        self.storage.load(&mut self.flash, dict)
    }
    fn load_history(&mut self, out: &mut [u8]) -> Option<usize> {
        self.history?.read_newest(&mut self.flash, out)
    }
    fn write_history(&mut self, payload: &[u8]) -> Result<bool, StorageError> {
        match self.history {
            Some(h) => h.write_bytes(&mut self.flash, payload).map(|_| true),
            None => Ok(false),
        }
    }
}

/// No parameter memory (tests that do not care): 'save' is refused with 0x08000020.
#[derive(Debug, Default)]
pub struct NoStore;

impl ParameterStore for NoStore {
    fn execute(
        &mut self,
        _cmd: StoreCommand,
        _dict: &mut dyn Dictionary,
    ) -> Result<SaveReport, StorageError> {
        Err(StorageError::Geometry)
    }
    fn load(&mut self, _dict: &mut dyn Dictionary) -> LoadReport {
        LoadReport {
            slots: [SlotStatus::Erased; 2],
            source: None,
            applied: 0,
            skipped: 0,
        }
    }
}

/// The whole dictionary as 'save' sees it: the drive's objects plus those the slave
/// runtime serves (mapping, assignment, sync).
struct WholeDictionary<'a, S: ParameterStore> {
    drive: &'a mut Drive<S>,
    runtime: &'a mut dyn Dictionary,
}

fn is_runtime_index(index: u16) -> bool {
    ecat_slave_stack::pdo::is_pdo_index(index) || ecat_slave_stack::sync::is_sync_index(index)
}

impl<S: ParameterStore> Dictionary for WholeDictionary<'_, S> {
    fn objects(&self) -> &'static [Object] {
        dictionary::OBJECTS
    }
    fn read(&mut self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        if is_runtime_index(index) {
            self.runtime.read(index, sub, buf)
        } else {
            self.drive.read(index, sub, buf)
        }
    }
    fn write(&mut self, index: u16, sub: u8, data: &[u8], state: EsmState) -> Result<(), SdoAbort> {
        if is_runtime_index(index) {
            self.runtime.write(index, sub, data, state)
        } else {
            self.drive.write(index, sub, data, state)
        }
    }
}

/// The drive application state.
pub struct Drive<S: ParameterStore = NoStore> {
    /// Product variant.
    pub variant: Variant,
    /// Vendor parameters 0x2000-0x21FF.
    pub params: Params,
    /// Communication objects 0x1000-0x10FF.
    pub comm: Comm,
    /// CiA 402 profile 0x6000-0x6FFF.
    pub cia402: Cia402,
    /// Protections and fault history.
    pub faults: Faults,
    /// Monitoring objects.
    pub monitor: Monitor,
    /// Digital inputs (filtered, functions).
    pub inputs: Inputs,
    axis: AxisState,
    command: DriveCommand,
    esm: EsmState,
    /// Local clock of the last control step ([`Drive::step`]) and of the last tick, µs
    /// modulo 2^32 ([`Stamp`]).
    last_step_us: Option<Stamp>,
    last_tick_us: Option<Stamp>,
    /// Microseconds of the drive's clock since its last whole millisecond, at the last
    /// tick (the ticks count milliseconds from it).
    tick_phase_us: u32,
    /// Control steps so far (wrapping).
    steps: u32,
    /// Local clock of the last master cycle and the time between the last two, µs.
    last_cycle_us: Option<Stamp>,
    cycle_period_us: u32,
    /// The master's commands stopped: the next tick steps whatever the timing.
    react_now: bool,
    now_ms: u32,
    fault_led: fault_led::FaultLed,
    last_controlword: u16,
    store: Option<S>,
    load_report: Option<LoadReport>,
    storage_emergency: Option<(u16, [u8; 5])>,
    seen_tune_seq: u8,
    seen_follow_seq: u8,
    seen_open_seq: u8,
    seen_trip_seq: u8,
    power_up_tune_over: bool,
    /// Firmware update over FoE (the board's or the simulation's flash behind it).
    update: Option<&'static mut (dyn FirmwareUpdate + Send)>,
    /// The EtherCAT runtime has reached Pre-Op since power-up.
    reached_preop: bool,
    /// The start-up checks' outcome, once the board reported it.
    startup_checks: Option<bool>,
    /// Bootstrap → Init after an accepted update: the board resets.
    reset_request: bool,
}

/// Error code reported when the outputs stopped arriving (process-data watchdog,
/// sync loss) while the drive was enabled.
pub const ERR_COMMUNICATION_LOST: u16 = 0x8700;

/// Period of the supervision tick ([`Drive::tick`]) on the board, µs.
pub const TICK_US: u64 = 1000;

/// A tick runs a control step when none has run for this long (µs), or for 1.5
/// cycles while the master's cycles of 1 ms or less run: then the cycles do the
/// steps; with slower cycles or none at all the tick fills in, so the drive steps at
/// least every [`TICK_US`] (once the cycles stop, after at most two).
pub const TICK_STEP_AFTER_US: u64 = 900;

/// A time of the drive's clock kept modulo 2^32 µs (71.6 minutes): every interval the
/// drive measures between two stamps (a tick, a step, a master cycle) is far shorter,
/// so `now.wrapping_sub(then)` is exact, and the cyclic path does 32-bit arithmetic
/// instead of 64-bit. An interval of 2^31 µs or more reads as a clock that went back.
type Stamp = u32;

/// The time from `then` to `now`, µs; `None` when the clock went back (or stood still
/// for more than 35 minutes, which no running drive does).
#[inline]
fn elapsed_us(now: Stamp, then: Stamp) -> Option<u32> {
    let d = now.wrapping_sub(then);
    (d < 1 << 31).then_some(d)
}

impl Drive<NoStore> {
    /// A drive at power-up defaults without parameter memory; `serial` is 0x1018:04.
    pub fn new(variant: Variant, serial: u32) -> Self {
        Drive::with_store(variant, serial, NoStore)
    }
}

/// The drive's fields at power-up, before [`Drive::apply_parameters`]: one list for
/// [`Drive::with_store`] and [`Drive::init_in`], each building it where its value goes.
macro_rules! power_up_fields {
    ($variant:ident, $serial:ident, $store:ident, $params:ident) => {
        Drive {
            variant: $variant,
            comm: Comm::new(Identity::new($variant, $serial)),
            cia402: Cia402::new(),
            faults: Faults::default(),
            monitor: Monitor::new(),
            inputs: Inputs::default(),
            axis: AxisState::default(),
            command: DriveCommand::default(),
            esm: EsmState::Init,
            last_step_us: None,
            last_tick_us: None,
            tick_phase_us: 0,
            steps: 0,
            last_cycle_us: None,
            cycle_period_us: 0,
            react_now: false,
            now_ms: 0,
            fault_led: fault_led::FaultLed::new(),
            last_controlword: 0,
            store: Some($store),
            load_report: None,
            storage_emergency: None,
            seen_tune_seq: 0,
            seen_follow_seq: 0,
            seen_open_seq: 0,
            seen_trip_seq: 0,
            power_up_tune_over: false,
            update: None,
            reached_preop: false,
            startup_checks: None,
            reset_request: false,
            params: $params,
        }
    };
}

impl<S: ParameterStore> Drive<S> {
    /// A drive at power-up defaults (before the stored parameters are loaded) whose
    /// 'save' / 'load' go to `store`; `serial` is 0x1018:04.
    pub fn with_store(variant: Variant, serial: u32, store: S) -> Self {
        let params = Params::new(variant);
        let mut d = power_up_fields!(variant, serial, store, params);
        d.apply_parameters();
        d
    }

    /// [`Drive::with_store`] written into `slot` (the board's static): the fields go
    /// to their place instead of a whole value being built and then moved in, which
    /// the start-up code pays for in size.
    pub fn init_in(
        slot: &mut core::mem::MaybeUninit<Self>,
        variant: Variant,
        serial: u32,
        store: S,
    ) -> &mut Self {
        let params = Params::new(variant);
        let d = slot.write(power_up_fields!(variant, serial, store, params));
        d.apply_parameters();
        d
    }

    /// Applies the parameters that configure the other modules (call at power-up after
    /// loading the stored record, and after parameter changes that take effect at once).
    pub fn apply_parameters(&mut self) {
        self.faults.configure_from(&self.params);
        let active = self.params.active();
        let encoder_counts = if self.variant.has_encoder() {
            (self.params.get(Param::EncoderResolution) as u32).saturating_mul(4)
        } else {
            0
        };
        self.cia402
            .set_resolution(encoder_counts, active.pulses_per_rev);
        self.cia402.set_has_index(self.variant.has_encoder());
        self.cia402
            .set_rated_current_ma(self.params.get(Param::PeakCurrent) as u32);
    }

    /// Power-up: loads the stored parameters (drive objects and, through `runtime` —
    /// [`ecat_slave_stack::slave::Slave::runtime_objects`] — the PDO mapping), latches
    /// the "effective after restart" parameters and counts the power-up. A corrupt or
    /// lost record is reported as an emergency.
    pub fn power_up(&mut self, runtime: &mut dyn Dictionary) -> LoadReport {
        let report = match self.store.take() {
            Some(mut store) => {
                let r = store.load(&mut WholeDictionary {
                    drive: &mut *self,
                    runtime,
                });
                self.store = Some(store);
                r
            }
            None => NoStore.load(runtime),
        };
        if let Some((code, data)) = report.emergency() {
            self.storage_emergency = Some((code, data));
            self.faults
                .diagnosis_mut()
                .push(crate::diagnosis::parameter_message(
                    false,
                    code,
                    self.now_ms,
                ));
        }
        self.load_report = Some(report);
        self.params.latch_power_up();
        self.monitor.power_up();
        self.load_history();
        self.apply_parameters();
        report
    }

    /// Power-up: the fault history from its flash record (nothing, i.e. an empty
    /// history, for erased, torn or garbage records) and the operating time stored
    /// with it — the larger of that and the parameter record's 0x2307 counts, the
    /// history being written more often than the parameters.
    fn load_history(&mut self) {
        let mut buf = [0u8; crate::faults::HISTORY_PAYLOAD_MAX];
        let n = self.store.as_mut().and_then(|s| s.load_history(&mut buf));
        if let Some(op) = n.and_then(|n| self.faults.restore_history(&buf[..n.min(buf.len())])) {
            self.monitor.running_time_at_least(op);
        }
        self.faults
            .set_operating_base(self.monitor.running_time_s());
    }

    /// Deferred work for whoever services 'save' (the board's `ecat` task after
    /// `poll`, the simulator's housekeeping): when the fault history changed since
    /// the last call, writes it with the operating time 0x2307 as a new history record.
    /// The fault path only marks the history dirty; this is never called from it.
    ///
    /// The board's flash rule holds as for a parameter 'save': through the staged
    /// store this only serialises the record (≈ 170 bytes) into the RAM stage under
    /// the shared lock; the erase and programming run afterwards in thread mode
    /// outside the lock (bank 2 read-while-write: the current loop and the cyclic
    /// path keep running, also with the power stage on). Call it only while no staged
    /// parameter record waits for programming (the stage is shared).
    ///
    /// `None`: nothing to do (or no history memory); `Some(result)` of the write. The
    /// history counts as written either way (a failed write is reported once, not
    /// retried every tick; the next change writes again).
    pub fn persist_history(&mut self) -> Option<Result<(), StorageError>> {
        if !self.faults.history_dirty() {
            return None;
        }
        self.faults.history_written();
        let mut buf = [0u8; crate::faults::HISTORY_PAYLOAD_MAX];
        let n = self
            .faults
            .encode_history(self.monitor.running_time_s(), &mut buf);
        match self.store.as_mut()?.write_history(&buf[..n.min(buf.len())]) {
            Ok(true) => Some(Ok(())),
            Ok(false) => None,
            Err(e) => Some(Err(e)),
        }
    }

    /// The next record for the board to program outside its lock, from a staged
    /// store: a record a 'save' staged comes first; only when none waits is a changed
    /// fault history staged ([`Drive::persist_history`]: the stage is shared). Returns
    /// the stage to program (give it back with `StagedFlash::give_back` afterwards),
    /// and the error of a history that could not be staged.
    pub fn next_staged_record<'a, R, const N: usize, const E: usize>(
        &mut self,
    ) -> (
        Option<&'a mut crate::staged_flash::Stage<N>>,
        Option<StorageError>,
    )
    where
        S: StagedStore<'a, R, N, E>,
        R: embedded_storage::nor_flash::ReadNorFlash,
    {
        let take = |d: &mut Self| d.store.as_mut().and_then(|st| st.staged().take_ready());
        if let Some(stage) = take(self) {
            return (Some(stage), None);
        }
        let err = match self.persist_history() {
            Some(Err(e)) => Some(e),
            _ => None,
        };
        (take(self), err)
    }

    /// The parameter store (the board takes a finished staged record out of it to
    /// program the flash outside its lock).
    pub fn store_mut(&mut self) -> Option<&mut S> {
        self.store.as_mut()
    }

    /// What the power-up load found.
    pub fn load_report(&self) -> Option<LoadReport> {
        self.load_report
    }

    /// The motor side's measurements for the next cycle.
    pub fn set_axis(&mut self, a: AxisState) {
        self.axis = a;
        self.monitor.m.electrical_angle = a.electrical_angle;
        self.monitor.m.ia_ma = a.ia_ma;
        self.monitor.m.ib_ma = a.ib_ma;
        self.monitor.m.ia_set_ma = a.ia_set_ma;
        self.monitor.m.ib_set_ma = a.ib_set_ma;
        self.monitor.m.bus_10mv = (a.bus_mv / 10).min(u32::from(u16::MAX)) as u16;
    }

    /// The set-points produced by the last cycle.
    pub fn command(&self) -> &DriveCommand {
        &self.command
    }

    /// Gives the drive its firmware update ([`crate::update`]): FoE in Bootstrap, the
    /// boot state 0x2309, 0x100A from the running image's header, and the trial
    /// image's confirmation once [`Drive::startup_checks_done`] reported success and
    /// the runtime reached Pre-Op.
    pub fn attach_update(&mut self, update: &'static mut (dyn FirmwareUpdate + Send)) {
        self.monitor.set_boot_state(update.boot_state() as u8);
        self.update = Some(update);
    }

    /// The board's start-up checks (current-sensor offsets, the board self-test) are
    /// over: `passed` or not. A trial image is confirmed only after a pass.
    pub fn startup_checks_done(&mut self, passed: bool) {
        self.startup_checks = Some(passed);
    }

    /// An accepted update waits for the reset into the bootloader (set on Bootstrap →
    /// Init): the board resets; the simulation restarts the drive.
    pub fn reset_requested(&self) -> bool {
        self.reset_request
    }

    /// The update's housekeeping, every tick: its events as diagnosis messages, the
    /// boot state 0x2309. (No flash access here: the tick may run in an interrupt.)
    fn update_housekeeping(&mut self) {
        let Some(u) = self.update.as_deref_mut() else {
            return;
        };
        if let Some(e) = u.take_event() {
            self.faults
                .diagnosis_mut()
                .push(crate::diagnosis::update_message(e, self.now_ms));
        }
        self.monitor.set_boot_state(u.boot_state() as u8);
    }

    /// Confirms a new image on trial (embassy-boot's `mark_booted`) once its start-up
    /// checks passed and the runtime reached Pre-Op, and only while the power stage
    /// is off: the confirmation writes embassy-boot's state partition, in the flash
    /// bank the code runs from, which stalls the current-loop interrupt for the page
    /// erase. Call it from thread mode, where the flash is used (the board's `ecat`
    /// task after `poll`); returns true when it confirmed now.
    pub fn confirm_update(&mut self) -> bool {
        let due = self.startup_checks == Some(true) && !self.command.power_stage;
        let runtime_up = self.reached_preop;
        match self.update.as_deref_mut() {
            Some(u) => u.confirm(due, runtime_up),
            None => false,
        }
    }

    /// The last cycle enabled the drive function (Operation enabled and the stopping
    /// states) — not just the motor side while CiA 402 transition 4 waits for the
    /// commutation alignment ([`Cia402::enable_waiting`]).
    pub fn drive_function_enabled(&self) -> bool {
        self.command.drive_enabled && !self.cia402.enable_waiting()
    }

    /// ESM state last reported by the runtime.
    pub fn esm_state(&self) -> EsmState {
        self.esm
    }

    /// Next emergency to send (fault occurrences, fault reset, parameter memory).
    pub fn pop_emergency(&mut self) -> Option<Emergency> {
        if let Some((code, data)) = self.storage_emergency.take() {
            return Some(Emergency {
                code,
                register: self.faults.error_register() | 1,
                data,
            });
        }
        self.faults.pop_emergency()
    }

    /// Runs a store / restore command now over the whole dictionary.
    fn run_store(
        &mut self,
        cmd: StoreCommand,
        runtime: &mut dyn Dictionary,
    ) -> Result<(), SdoAbort> {
        let Some(mut store) = self.store.take() else {
            return Err(SdoAbort::DataCannotBeStored);
        };
        let r = store.execute(
            cmd,
            &mut WholeDictionary {
                drive: &mut *self,
                runtime,
            },
        );
        self.store = Some(store);
        if r.is_ok() && matches!(cmd, StoreCommand::RestoreDefaults(_)) {
            self.faults
                .diagnosis_mut()
                .push(crate::diagnosis::parameter_message(true, 0, self.now_ms));
        }
        r.map(|_| ()).map_err(StorageError::abort)
    }

    fn snapshot(&self) -> Snapshot {
        Snapshot {
            ia_ma: self.axis.ia_ma,
            ib_ma: self.axis.ib_ma,
            bus_dv: (self.axis.bus_mv / 100).min(u32::from(u16::MAX)) as u16,
            position_error: self.cia402.following_error(),
            speed: self.axis.velocity,
        }
    }

    /// The supervision tick, on the drive's own clock (`now_us`, µs; every
    /// [`TICK_US`] on the board, in every ESM state and sync mode): input filter and
    /// functions, protections from the measured values, fault reset by input,
    /// monitoring, then — unless the master's cycle did one within
    /// [`TICK_STEP_AFTER_US`] — a control step ([`Drive::step`]): the power drive
    /// system, the fault reactions and stop ramps, the profile and homing generators
    /// and the brake advance whether or not frames arrive. A fault this tick detects
    /// starts its reaction in the same tick. `raw_inputs`: bit n = level of IN n+1.
    pub fn tick(&mut self, now_us: u64, raw_inputs: u8) {
        let now = now_us as Stamp;
        // Whole milliseconds of the clock since the last tick (the clock's millisecond
        // boundaries, as `now_us / 1000` counts them).
        let dt_ms = match self.last_tick_us.map(|prev| elapsed_us(now, prev)) {
            Some(Some(d)) => {
                let us = self.tick_phase_us + d;
                self.tick_phase_us = us % 1000;
                us / 1000
            }
            Some(None) => 0,
            None => {
                self.tick_phase_us = (now_us % 1000) as u32;
                (TICK_US / 1000) as u32
            }
        };
        self.last_tick_us = Some(now);
        self.now_ms = self.now_ms.wrapping_add(dt_ms);
        self.faults.set_clock(self.now_ms);
        self.monitor.tick_ms(dt_ms);
        self.update_housekeeping();
        self.inputs
            .update(raw_inputs, dt_ms.saturating_mul(1000), &self.params);
        self.params.set_raw_inputs(self.inputs.raw());
        let snap = self.snapshot();
        let now_ms = self.now_ms;
        if self.axis.bus_mv > 0 {
            self.faults
                .check_bus_voltage(self.axis.bus_mv, snap, now_ms);
        }
        // Over-current: the measured phase currents against the limit (software check)
        // and the power stage's break latch. The condition is gone once the currents
        // are below the limit and the latch is re-armed; then a fault reset (with
        // 0x2057 = 1, the fault being latched) clears it.
        self.faults.check_phase_currents(
            i32::from(self.axis.ia_ma),
            i32::from(self.axis.ib_ma),
            snap,
            now_ms,
        );
        if self.axis.overcurrent_trip {
            self.faults.raise(FaultKind::OverCurrent, snap, now_ms);
        }
        if self.inputs.fault_clear_edge() {
            self.faults.fault_reset();
        }
        if self.params.take_fault_history_clear() {
            self.faults.clear_history();
        }
        let after = match self.cycles_running(now) {
            Some(p) => (TICK_STEP_AFTER_US as u32).max(p + p / 2),
            None => TICK_STEP_AFTER_US as u32,
        };
        let due = self
            .last_step_us
            .is_none_or(|t| elapsed_us(now, t).is_none_or(|d| d >= after));
        // A fault the PDS has not taken yet starts its reaction in this tick.
        let fault_news = self.faults.any_active()
            && !matches!(
                self.cia402.state(),
                crate::cia402::pds::PdsState::Fault
                    | crate::cia402::pds::PdsState::FaultReactionActive
            );
        if due || fault_news || core::mem::take(&mut self.react_now) {
            self.step_at(now, SetpointArrival::Stale);
        }
    }

    /// One control step at `now_us` on the drive's clock: [`Drive::run_cycle`] over the
    /// time since the previous step. Called by the supervision tick and by the
    /// master's cycle (`setpoint`: whether that cycle brought new outputs).
    pub fn step(&mut self, now_us: u64, setpoint: SetpointArrival) -> DriveCommand {
        self.step_at(now_us as Stamp, setpoint)
    }

    /// [`Drive::step`] at a [`Stamp`]: steps of at most 10 ms (a longer pause is not
    /// integrated), 1 µs when the clock stood still or went back.
    fn step_at(&mut self, now: Stamp, setpoint: SetpointArrival) -> DriveCommand {
        let dt = match self.last_step_us.map(|prev| elapsed_us(now, prev)) {
            Some(Some(d)) if d > 0 => d.min(10_000) as f32 * 1e-6,
            Some(_) => 1e-6,
            None => TICK_US as f32 * 1e-6,
        };
        self.last_step_us = Some(now);
        self.steps = self.steps.wrapping_add(1);
        self.control_step(dt, setpoint)
    }

    /// The period of the master's cycles (µs) while they run at 1 ms or faster (the
    /// last one less than two periods ago).
    fn cycles_running(&self, now: Stamp) -> Option<u32> {
        let p = self.cycle_period_us;
        let since = elapsed_us(now, self.last_cycle_us?)?;
        (p > 0 && p <= TICK_US as u32 && since < 2 * p).then_some(p)
    }

    /// How long the motion layer takes to reach a new step's set-points, s: the
    /// master's cycle while it runs at 1 ms or faster (the steps come with it), else
    /// the tick period. Not the length of the last step: the tick and the cycle may
    /// land close together, and the motion layer must not rush to the second one.
    pub fn segment_s(&self) -> f32 {
        let us = self
            .last_step_us
            .and_then(|t| self.cycles_running(t))
            .unwrap_or(TICK_US as u32);
        us as f32 * 1e-6
    }

    /// Control steps so far (wrapping): a new value means new set-points in
    /// [`Drive::command`], for the motion layer to start a new segment with.
    pub fn steps(&self) -> u32 {
        self.steps
    }

    /// The power stage may be on: the last step's command wants it, the PDS state has
    /// the voltage enabled, and no fault that cuts the power
    /// ([`FaultKind::cuts_power`]) is active. What the board's power
    /// stage and the simulated one obey.
    pub fn power_permission(&self) -> bool {
        // The PDS state as well as the last step's command: a disable voltage that
        // did not come from a step (0x6007 = 2) takes effect at once.
        self.command.power_stage
            && self.cia402.state().voltage_enabled()
            && !self.faults.power_cut()
    }

    /// Permission for the power-up current-loop auto-tune
    /// ([`crate::current_supervisor`]): the bus voltage is inside the under/over-voltage
    /// window and no fault is active. The control path also needs the current-sensor
    /// offsets to have passed their start-up check.
    pub fn tune_permitted(&self) -> bool {
        let c = self.faults.config();
        let bus = self.axis.bus_mv;
        bus >= c
            .under_voltage_mv
            .saturating_add(c.under_voltage_hysteresis_mv)
            && bus <= c.over_voltage_mv
            && !self.faults.any_active()
    }

    /// The current-loop supervisor's report (control path → drive; call every tick,
    /// before [`Drive::tick`]). A finished tune writes 0x2020 (mΩ), 0x2021 (µH), 0x2015
    /// and 0x2016 (the gains the loop now uses); a failed one, or a phase without
    /// current while running, raises motor open 0x7120; a "current does not follow" detection raises 0x5210; a trip of the fast
    /// protection raises over-current 0x2310 or over-voltage 0x3210. Both are events:
    /// the condition is reported gone at once, so a fault reset clears them (see the
    /// module docs of [`crate::current_supervisor`] for the retry).
    ///
    /// Until the first tune since power-up has finished (with 0x2013 = 1) the power-up
    /// self-test is running: the PDS stays in Not ready to switch on.
    pub fn current_report(&mut self, r: &CurrentReport) {
        if !self.power_up_tune_over {
            let running = self.params.get(Param::AutoTune) == 1
                && r.tune_seq == 0
                && matches!(r.tune, TuneStatus::Pending | TuneStatus::Running);
            self.power_up_tune_over = !running;
            self.cia402.set_self_test(running);
        }
        if r.tune_seq != self.seen_tune_seq {
            self.seen_tune_seq = r.tune_seq;
            match r.tune {
                TuneStatus::Done => {
                    let t = r.tuned;
                    self.params
                        .set_internal(Param::MotorResistance, i32::from(t.r_mohm));
                    self.params
                        .set_internal(Param::MotorInductance, i32::from(t.l_uh));
                    self.params.set_internal(Param::CurrentKp, i32::from(t.kp));
                    self.params.set_internal(Param::CurrentKi, i32::from(t.ki));
                }
                TuneStatus::Failed(e) => {
                    use foc::autotune::{Phase, TuneError};
                    let detail = match e {
                        TuneError::OpenPhase(Phase::A) => [1, 0],
                        TuneError::OpenPhase(Phase::B) => [1, 1],
                        TuneError::Unbalanced => [2, 0],
                        TuneError::Implausible => [3, 0],
                    };
                    let snap = self.snapshot();
                    self.faults
                        .raise_detail(FaultKind::MotorOpen, detail, snap, self.now_ms);
                    self.faults.condition_gone(FaultKind::MotorOpen);
                }
                _ => {}
            }
        }
        if r.trip_seq != self.seen_trip_seq {
            // The current loop's fast protection switched the bridges off: the fault
            // with the sample it tripped on (the tick's checks then follow the
            // condition until it is gone).
            self.seen_trip_seq = r.trip_seq;
            let kind = match r.trip {
                crate::current_supervisor::Trip::OverVoltage => Some(FaultKind::OverVoltage),
                crate::current_supervisor::Trip::OverCurrent => Some(FaultKind::OverCurrent),
                crate::current_supervisor::Trip::None => None,
            };
            if let Some(kind) = kind {
                let snap = Snapshot {
                    ia_ma: r.trip_ia_ma,
                    ib_ma: r.trip_ib_ma,
                    bus_dv: r.trip_bus_dv,
                    ..self.snapshot()
                };
                self.faults.raise(kind, snap, self.now_ms);
            }
        }
        if r.open_seq != self.seen_open_seq {
            // A phase without current while running: motor open, detail 4 and the
            // phase (0 = A, 1 = B).
            self.seen_open_seq = r.open_seq;
            let phase = u8::from(r.open_phase == foc::autotune::Phase::B);
            let snap = self.snapshot();
            self.faults
                .raise_detail(FaultKind::MotorOpen, [4, phase], snap, self.now_ms);
            self.faults.condition_gone(FaultKind::MotorOpen);
        }
        if r.follow_seq != self.seen_follow_seq {
            self.seen_follow_seq = r.follow_seq;
            let snap = self.snapshot();
            self.faults.raise_detail(
                FaultKind::PhaseSensing,
                r.follow_ref_ma.to_le_bytes(),
                snap,
                self.now_ms,
            );
            self.faults.condition_gone(FaultKind::PhaseSensing);
        }
    }

    /// The drive's LEDs at `now_ms`.
    pub fn leds(&mut self, now_ms: u32) -> DriveLeds {
        DriveLeds {
            green: true,
            red: self.fault_led.update(self.faults.led_code(), now_ms),
        }
    }

    /// Output pin levels (bit n = output n+1) and the brake.
    pub fn outputs(&self) -> (u8, bool) {
        let op_enabled = self.command.drive_enabled;
        let status = OutputStatus {
            alarm: self.faults.alarm(),
            ready: !self.faults.any_active() && self.command.power_stage,
            in_position: self.cia402.statusword() & crate::cia402::sw::TARGET_REACHED != 0,
        };
        (
            io::output_levels(&self.params, status),
            io::brake_released(op_enabled, self.faults.any_active()),
        )
    }

    /// One control step of `dt` seconds with set-points of unknown age
    /// ([`SetpointArrival::PerCycle`]), outside the drive's clock: for tests and
    /// benchmarks that step the drive once per simulated master cycle.
    pub fn run_cycle(&mut self, dt: f32) -> DriveCommand {
        self.control_step(dt, SetpointArrival::PerCycle)
    }

    fn control_step(&mut self, dt: f32, setpoint: SetpointArrival) -> DriveCommand {
        // Fault reset (controlword bit 7 rising edge) clears the protections first, so
        // the PDS sees no active fault and accepts the reset; latched faults stay.
        let cw = self.cia402.controlword();
        if cw & 0x80 != 0 && self.last_controlword & 0x80 == 0 {
            self.faults.fault_reset();
        }
        self.last_controlword = cw;
        let power_cut = self.faults.power_cut();
        let fb = DriveFeedback {
            position: self.axis.position,
            velocity: self.axis.velocity,
            torque: self.axis.current_permille,
            current: self.axis.current_permille,
            digital_inputs: self.inputs.digital_inputs_60fd(),
            index: self.axis.index,
            probe1: self.axis.probe1,
            probe2: self.axis.probe2,
            fault: self.faults.error_code(),
            power_stage_tripped: power_cut,
            warning: false,
            current_limited: self.axis.current_limited,
            quick_stop_input: self.inputs.quick_stop(),
            enable_pending: self.axis.commutation_pending,
        };
        self.command = self.cia402.step(&fb, dt, setpoint);
        // Following-error supervision of the closed loop (0x2030, encoder counts).
        if self.command.drive_enabled
            && self.variant.has_encoder()
            && self.params.get(Param::LoopMode) == 2
        {
            let err = self.axis.servo_following_error;
            let limit = self.params.get(Param::FollowingErrorLimit) as u16;
            if err.unsigned_abs() > u32::from(limit) {
                // The snapshot is only taken when there is something to record.
                let snap = self.snapshot();
                self.faults
                    .check_following_error(err, limit, snap, self.now_ms);
            } else {
                self.faults.condition_gone(FaultKind::FollowingError);
            }
        } else {
            // Not servoing: there is no following error, so a fault reset may clear it.
            self.faults.condition_gone(FaultKind::FollowingError);
        }
        // A fault reset accepted by the PDS (controlword bit 7) clears the faults.
        if self.faults.take_pds_fault_request() {
            self.cia402.raise_fault(self.faults.error_code());
        }
        // (No fault this step raises cuts the power: one reading serves.) In Bootstrap
        // the power stage stays off whatever the PDS says.
        if power_cut || self.esm == EsmState::Bootstrap {
            self.command.power_stage = false;
            self.command.drive_enabled = false;
            self.command.brake_release = false;
        }
        self.command
    }
}

impl<S: ParameterStore> Dictionary for Drive<S> {
    fn objects(&self) -> &'static [Object] {
        dictionary::OBJECTS
    }

    fn read(&mut self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        if index == 0x10F3 {
            // Reading the newest diagnosis message clears "new messages available".
            crate::dictionary::find_entry_in(crate::dictionary::COMM, index, sub)?;
            return self.faults.diagnosis_mut().read(sub, buf);
        }
        if let (0x100A, Some(v)) = (
            index,
            self.update.as_deref().and_then(|u| u.running_version()),
        ) {
            // The version of the running image's update header.
            crate::dictionary::find_entry_in(crate::dictionary::COMM, index, sub)?;
            let n = crate::update::format_version(v, buf);
            return if n == 0 {
                Err(SdoAbort::ExceedsMailbox)
            } else {
                Ok(n)
            };
        }
        self.read_entry(index, sub, buf)
    }

    fn write(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
        _state: EsmState,
    ) -> Result<(), SdoAbort> {
        match index {
            0x1000..=0x10FF => match self.comm.write(&mut self.faults, index, sub, data)? {
                // Without the runtime's objects a save would miss the PDO mapping.
                Some(cmd) => self.run_store(cmd, &mut NoRuntime),
                None => Ok(()),
            },
            0x2000..=0x21FF => {
                self.params.write(index, sub, data)?;
                self.faults.configure_from(&self.params);
                Ok(())
            }
            0x2300..=0x23FF => self.monitor.write(index, sub, data),
            0x6000..=0x6FFF => self.cia402.write(index, sub, data),
            _ => Err(SdoAbort::WriteReadOnly),
        }
    }

    fn write_with_runtime(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
        state: EsmState,
        runtime: &mut dyn Dictionary,
    ) -> Result<(), SdoAbort> {
        if (0x1000..=0x10FF).contains(&index) {
            if let Some(cmd) = self.comm.write(&mut self.faults, index, sub, data)? {
                return self.run_store(cmd, runtime);
            }
            return Ok(());
        }
        self.write(index, sub, data, state)
    }
}

/// Stand-in for the slave runtime's objects where there is no runtime (no ESC on the
/// board) or a write does not come through it: the product's objects, none of the
/// runtime's (a save through it keeps no PDO mapping).
pub struct NoRuntime;

impl Dictionary for NoRuntime {
    fn objects(&self) -> &'static [Object] {
        dictionary::OBJECTS
    }
    fn read(&mut self, _index: u16, _sub: u8, _buf: &mut [u8]) -> Result<usize, SdoAbort> {
        Err(SdoAbort::ObjectDoesNotExist)
    }
    fn write(
        &mut self,
        _index: u16,
        _sub: u8,
        _data: &[u8],
        _state: EsmState,
    ) -> Result<(), SdoAbort> {
        Err(SdoAbort::ObjectDoesNotExist)
    }
}

/// Slots of TxPDO-mappable entries outside the CiA 402 range start here; they are
/// served through the dictionary read (not a hot path: the default maps use none).
const OTHER_TX_SLOT: u16 = 0x8000;
/// Highest number of such entries.
const OTHER_TX_MAX: usize = 32;

fn other_tx_entries() -> impl Iterator<Item = (u16, u8)> {
    dictionary::OBJECTS
        .iter()
        .filter(|o| !(0x6000..=0x6FFF).contains(&o.index))
        .flat_map(|o| {
            o.entries()
                .iter()
                .filter(|e| e.pdo_mappable().tx())
                .map(move |e| (o.index, e.sub))
        })
        .take(OTHER_TX_MAX)
}

/// Entry number `n` of [`other_tx_entries`]: a plain walk (the chain's generic
/// `Iterator::nth` is three times as large).
#[inline(never)]
fn other_tx_entry(n: usize) -> Option<(u16, u8)> {
    for (k, e) in other_tx_entries().enumerate() {
        if k == n {
            return Some(e);
        }
    }
    None
}

impl<S: ParameterStore> ProcessData for Drive<S> {
    fn rx_slot(&self, index: u16, sub: u8) -> Option<u16> {
        ProcessData::rx_slot(&self.cia402, index, sub)
    }

    fn tx_slot(&self, index: u16, sub: u8) -> Option<u16> {
        if (0x6000..=0x6FFF).contains(&index) {
            return ProcessData::tx_slot(&self.cia402, index, sub);
        }
        other_tx_entries()
            .position(|k| k == (index, sub))
            .map(|n| OTHER_TX_SLOT + n as u16)
    }

    #[inline]
    fn set_rx(&mut self, slot: u16, raw: u64) {
        ProcessData::set_rx(&mut self.cia402, slot, raw);
    }

    #[inline]
    fn get_tx(&self, slot: u16) -> u64 {
        if slot < OTHER_TX_SLOT {
            return ProcessData::get_tx(&self.cia402, slot);
        }
        let Some((index, sub)) = other_tx_entry(usize::from(slot - OTHER_TX_SLOT)) else {
            return 0;
        };
        let mut buf = [0u8; 8];
        // (`other_tx_entry` never names a 0x6xxx entry.)
        match self.read_entry(index, sub, &mut buf) {
            Ok(_) => u64::from_le_bytes(buf),
            Err(_) => 0,
        }
    }
}

impl<S: ParameterStore> Drive<S> {
    /// SDO read of a product entry, dispatched on the index range (the dictionary
    /// read and the TxPDO entries outside 0x6xxx share it).
    #[inline(never)]
    fn read_entry(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        match index {
            0x1000..=0x10FF => self.comm.read(&self.faults, index, sub, buf),
            0x2000..=0x21FF => self.params.read(index, sub, buf),
            0x2300..=0x23FF => self.monitor.read(index, sub, buf),
            0x2400..=0x24FF => self.faults.read(index, sub, buf),
            0x6000..=0x6FFF => self.cia402.read(index, sub, buf),
            _ => Err(SdoAbort::ObjectDoesNotExist),
        }
    }

    /// The master's commands stopped: the ESM left Op (requested or forced), the
    /// outputs were lost (SM watchdog) or SYNC0 stopped. Applies 0x6007
    /// ([`Cia402::on_connection_lost`]); the reaction then runs on the drive's own
    /// clock (every [`Drive::tick`]). While the motor side aligns for transition 4 the
    /// PDS drops to Switch on disabled (no drive function yet: no fault). With the
    /// drive function enabled, 0x6007 = 1 raises the EtherCAT fault `code` with `diag`
    /// (emergency, history; an event, so a fault reset may clear it); 2 and 3 send the
    /// emergency `code` without a fault; 0 does nothing.
    #[inline(never)]
    fn left_op(&mut self, code: u16, diag: [u8; 2]) {
        use crate::cia402::pds::PdsState;
        let before = self.cia402.state();
        let had_function = matches!(
            before,
            PdsState::OperationEnabled | PdsState::QuickStopActive
        ) && !self.cia402.enable_waiting();
        let option = self.cia402.on_connection_lost();
        // The master's cycles are over: the reaction starts at the next tick. A PDS
        // that lost its voltage here (0x6007 = 2) shows it at once (statusword, power
        // off, brake engaged): a step of no length.
        self.last_cycle_us = None;
        self.react_now = option != AbortConnection::NoAction;
        if self.cia402.state() != before && !self.cia402.state().voltage_enabled() {
            self.control_step(1e-6, SetpointArrival::Stale);
        }
        // Reported once: a second report of the same loss (the outputs lost, then the
        // ESM change) finds the reaction already running.
        if !had_function || self.cia402.state() == before {
            return;
        }
        match option {
            AbortConnection::NoAction => {}
            AbortConnection::Fault => {
                self.faults.raise_ecat(code, diag, self.now_ms);
                self.faults.condition_gone(FaultKind::Ecat);
            }
            AbortConnection::DisableVoltage | AbortConnection::QuickStop => {
                self.faults.notify(code, diag);
            }
        }
    }
}

impl<S: ParameterStore> EsmHooks for Drive<S> {
    fn on_state_change(&mut self, from: EsmState, to: EsmState) {
        self.esm = to;
        if matches!(to, EsmState::PreOp | EsmState::SafeOp | EsmState::Op) {
            self.reached_preop = true;
        }
        if to == EsmState::Bootstrap {
            // Nothing of the motion survives the Bootstrap: the power stage is off.
            self.command.power_stage = false;
            self.command.drive_enabled = false;
            self.command.brake_release = false;
        }
        if from == EsmState::Op && to != EsmState::Op {
            let code = if to == EsmState::Init { 0xA000 } else { 0xA001 };
            self.left_op(code, [from.bits(), to.bits()]);
        }
        if to == EsmState::Init {
            self.cia402.on_esm_init();
        }
    }

    fn on_leave_bootstrap(&mut self) {
        if self.update.as_deref().is_some_and(|u| u.accepted()) {
            self.reset_request = true;
        }
    }
}

impl<S: ParameterStore> SlaveApplication for Drive<S> {
    /// The master's cycle: the set-points it brought take effect in a control step
    /// now (the supervision tick steps the drive as well, on its own clock).
    fn cycle(&mut self, info: &CycleInfo) {
        let now = info.now_us as Stamp;
        if let Some(t) = self.last_cycle_us {
            self.cycle_period_us = elapsed_us(now, t).unwrap_or(0);
        }
        self.last_cycle_us = Some(now);
        let arrival = if info.outputs_fresh {
            SetpointArrival::Fresh
        } else {
            SetpointArrival::Stale
        };
        self.step_at(now, arrival);
    }

    fn on_outputs_lost(&mut self, code: AlStatusCode) {
        self.left_op(ERR_COMMUNICATION_LOST, code.code().to_le_bytes());
    }

    fn sync_error_limit(&self) -> u16 {
        self.comm.sync_error_limit()
    }

    fn foe(&mut self) -> Option<&mut dyn FoeFiles> {
        match self.update.as_deref_mut() {
            Some(u) => Some(u),
            None => None,
        }
    }
}

/// True when `index` is stored by 'save' somewhere in the dictionary (for tests and
/// the storage layout documentation).
pub fn is_saved(index: u16, sub: u8) -> bool {
    od::find_entry(dictionary::OBJECTS, index, sub).is_ok_and(|e| e.is_saved())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cia402::pds::PdsState;

    fn sdo_write(d: &mut Drive, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoAbort> {
        let e = od::find_entry(dictionary::OBJECTS, index, sub)?;
        od::check_write(e, data, EsmState::PreOp)?;
        d.write(index, sub, data, EsmState::PreOp)
    }

    fn sdo_read_u32(d: &mut Drive, index: u16, sub: u8) -> u32 {
        let mut b = [0u8; 8];
        let n = d.read(index, sub, &mut b).expect("read");
        let mut v = [0u8; 4];
        v[..n.min(4)].copy_from_slice(&b[..n.min(4)]);
        u32::from_le_bytes(v)
    }

    #[test]
    fn init_in_equals_with_store() {
        // Every readable value, the set-points and the ESM state agree.
        let mut a = Drive::new(Variant::HybridServo, 42);
        let mut slot = core::mem::MaybeUninit::uninit();
        let b = Drive::init_in(&mut slot, Variant::HybridServo, 42, NoStore);
        for o in dictionary::OBJECTS {
            for e in o.entries() {
                let (mut x, mut y) = ([0u8; 64], [0u8; 64]);
                let rx = a.read(o.index, e.sub, &mut x);
                let ry = b.read(o.index, e.sub, &mut y);
                assert_eq!(rx, ry, "{:#06x}:{}", o.index, e.sub);
                assert_eq!(x, y, "{:#06x}:{}", o.index, e.sub);
            }
        }
        assert_eq!(a.command(), b.command());
        assert_eq!(a.esm_state(), b.esm_state());
    }

    #[test]
    fn other_tx_entry_is_the_chains_nth() {
        let n = other_tx_entries().count();
        for k in 0..n + 2 {
            assert_eq!(other_tx_entry(k), other_tx_entries().nth(k), "{k}");
        }
        let d = Drive::new(Variant::HybridServo, 7);
        assert_eq!(ProcessData::get_tx(&d, OTHER_TX_SLOT + n as u16), 0);
    }

    #[test]
    fn dictionary_reads_reach_every_module() {
        let mut d = Drive::new(Variant::HybridServo, 42);
        assert_eq!(sdo_read_u32(&mut d, 0x1000, 0), 0x0002_0192);
        assert_eq!(sdo_read_u32(&mut d, 0x1018, 4), 42);
        assert_eq!(sdo_read_u32(&mut d, 0x2000, 0), 3200);
        assert_eq!(
            sdo_read_u32(&mut d, 0x6502, 0),
            crate::cia402::SUPPORTED_MODES
        );
        let mut b = [0u8; 8];
        assert_eq!(d.read(0x5000, 0, &mut b), Err(SdoAbort::ObjectDoesNotExist));
    }

    #[test]
    fn out_of_range_vendor_write_is_refused_and_value_kept() {
        let mut d = Drive::new(Variant::HybridServo, 0);
        assert_eq!(
            sdo_write(&mut d, 0x2000, 0, &9000u16.to_le_bytes()),
            Err(SdoAbort::ValueTooHigh)
        );
        assert_eq!(
            sdo_write(&mut d, 0x2000, 0, &0u16.to_le_bytes()),
            Err(SdoAbort::ValueTooLow)
        );
        assert_eq!(sdo_read_u32(&mut d, 0x2000, 0), 3200);
        sdo_write(&mut d, 0x2000, 0, &2500u16.to_le_bytes()).expect("in range");
        assert_eq!(sdo_read_u32(&mut d, 0x2000, 0), 2500);
    }

    #[test]
    fn save_without_parameter_memory_is_refused() {
        let mut d = Drive::new(Variant::HybridServo, 0);
        let save = crate::comm::SAVE.to_le_bytes();
        assert_eq!(
            sdo_write(&mut d, 0x1010, 1, &save),
            Err(SdoAbort::DataCannotBeStored)
        );
        let other = 0x1234_5678u32.to_le_bytes();
        assert_eq!(
            sdo_write(&mut d, 0x1010, 1, &other),
            Err(SdoAbort::DataCannotBeStored)
        );
    }

    fn enable(d: &mut Drive) {
        d.set_axis(AxisState {
            bus_mv: 48_000,
            ..AxisState::default()
        });
        for cw in [0x06u16, 0x07, 0x0F] {
            d.cia402.set_controlword(cw);
            for _ in 0..3 {
                d.run_cycle(0.001);
            }
        }
    }

    #[test]
    fn enable_sequence_reaches_operation_enabled() {
        let mut d = Drive::new(Variant::HybridServo, 0);
        enable(&mut d);
        assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
        assert!(d.command().drive_enabled);
        let (_, brake_released) = d.outputs();
        assert!(brake_released);
    }

    #[test]
    fn pending_commutation_holds_switched_on_and_leaving_op_then_is_no_fault() {
        for lost in [false, true] {
            let mut d = Drive::new(Variant::HybridServo, 0);
            d.on_state_change(EsmState::SafeOp, EsmState::Op);
            let pending = AxisState {
                bus_mv: 48_000,
                position: 777,
                commutation_pending: true,
                ..AxisState::default()
            };
            d.set_axis(pending);
            for cw in [0x06u16, 0x07, 0x0F] {
                d.cia402.set_controlword(cw);
                for _ in 0..3 {
                    d.run_cycle(0.001);
                }
            }
            assert_eq!(d.cia402.state(), PdsState::SwitchedOn);
            // The motor side is enabled (and the brake released) at the actual
            // position; the drive function is not.
            assert!(d.command().drive_enabled && d.command().power_stage);
            assert_eq!(d.command().position, 777);
            assert!(d.outputs().1);
            assert!(!d.drive_function_enabled());
            if lost {
                d.on_outputs_lost(AlStatusCode::SmWatchdog);
            } else {
                d.on_state_change(EsmState::Op, EsmState::SafeOp);
            }
            d.run_cycle(0.001);
            assert_eq!(d.cia402.state(), PdsState::SwitchOnDisabled);
            assert!(!d.command().drive_enabled);
            assert!(!d.faults.any_active());
            assert!(d.pop_emergency().is_none());
        }
        // Ready: the next cycle enables the drive function.
        let mut d = Drive::new(Variant::HybridServo, 0);
        d.set_axis(AxisState {
            bus_mv: 48_000,
            commutation_pending: true,
            ..AxisState::default()
        });
        for cw in [0x06u16, 0x07, 0x0F] {
            d.cia402.set_controlword(cw);
            for _ in 0..3 {
                d.run_cycle(0.001);
            }
        }
        assert_eq!(d.cia402.state(), PdsState::SwitchedOn);
        d.set_axis(AxisState {
            bus_mv: 48_000,
            ..AxisState::default()
        });
        d.run_cycle(0.001);
        assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
        assert!(d.drive_function_enabled());
    }

    #[test]
    fn leaving_op_while_enabled_faults_the_pds_and_sends_one_emergency() {
        let mut d = Drive::new(Variant::HybridServo, 0);
        d.on_state_change(EsmState::SafeOp, EsmState::Op);
        enable(&mut d);
        d.on_state_change(EsmState::Op, EsmState::SafeOp);
        for _ in 0..5 {
            d.run_cycle(0.001);
        }
        assert!(matches!(
            d.cia402.state(),
            PdsState::Fault | PdsState::FaultReactionActive
        ));
        let e = d.pop_emergency().expect("emergency");
        assert_eq!(e.code, 0xA001);
        assert!(d.pop_emergency().is_none());
        // Fault reset on the rising edge of bit 7 clears the non-latched EtherCAT fault.
        d.cia402.set_controlword(0x00);
        d.run_cycle(0.001);
        d.cia402.set_controlword(0x80);
        for _ in 0..3 {
            d.run_cycle(0.001);
        }
        assert_eq!(d.cia402.state(), PdsState::SwitchOnDisabled);
    }

    #[test]
    fn following_error_fault_resets_once_the_drive_is_disabled() {
        let mut d = Drive::new(Variant::HybridServo, 0);
        enable(&mut d);
        d.set_axis(AxisState {
            bus_mv: 48_000,
            servo_following_error: 5000,
            ..AxisState::default()
        });
        d.run_cycle(0.001);
        assert_eq!(d.faults.error_code(), 0x8611);
        for _ in 0..20 {
            d.run_cycle(0.001);
        }
        assert_eq!(d.cia402.state(), PdsState::Fault);
        // The servo is off now; its stale error must not block the reset.
        d.cia402.set_controlword(0x00);
        d.run_cycle(0.001);
        d.cia402.set_controlword(0x80);
        for _ in 0..3 {
            d.run_cycle(0.001);
        }
        assert_eq!(d.cia402.state(), PdsState::SwitchOnDisabled);
        assert_eq!(d.faults.error_code(), 0);
    }

    #[test]
    fn over_voltage_faults_latch_and_light_the_red_led() {
        let mut d = Drive::new(Variant::HybridServo, 0);
        enable(&mut d);
        d.set_axis(AxisState {
            bus_mv: 60_000,
            ..AxisState::default()
        });
        d.tick(1000, 0);
        d.run_cycle(0.001);
        assert_eq!(d.faults.error_code(), 0x3210);
        assert!(!d.command().drive_enabled || d.cia402.state() != PdsState::OperationEnabled);
        // Red LED: two 150 ms pulses from the start of the burst.
        let leds: [bool; 4] = [
            d.leds(1000).red,
            d.leds(1100).red,
            d.leds(1200).red,
            d.leds(1350).red,
        ];
        assert_eq!(leds, [true, true, false, true]);
    }

    #[test]
    fn over_current_trip_clears_by_reset_once_re_armed_with_0x2057() {
        let mut d = Drive::new(Variant::HybridServo, 0);
        enable(&mut d);
        let trip = AxisState {
            bus_mv: 48_000,
            overcurrent_trip: true,
            ..AxisState::default()
        };
        d.set_axis(trip);
        d.tick(1000, 0);
        assert_eq!(d.faults.error_code(), 0x2310);
        assert!(d.pop_emergency().is_some());
        // Still tripped: no reset even with 0x2057 = 1.
        sdo_write(&mut d, 0x2057, 0, &[1]).expect("2057");
        assert!(!d.faults.fault_reset());
        // Re-armed, but a measured current above the limit is the condition too.
        d.set_axis(AxisState {
            bus_mv: 48_000,
            ia_ma: -11_000,
            ..AxisState::default()
        });
        d.tick(2000, 0);
        assert!(!d.faults.fault_reset());
        d.set_axis(AxisState {
            bus_mv: 48_000,
            ..AxisState::default()
        });
        d.tick(3000, 0);
        assert!(d.faults.fault_reset(), "gone and 0x2057 = 1");
        assert_eq!(d.faults.error_code(), 0);
    }

    #[test]
    fn power_up_tune_keeps_the_pds_not_ready_to_switch_on() {
        use crate::current_supervisor::CurrentReport;
        let mut d = Drive::new(Variant::HybridServo, 0);
        d.set_axis(AxisState {
            bus_mv: 48_000,
            ..AxisState::default()
        });
        d.run_cycle(0.001);
        assert_eq!(d.cia402.state(), PdsState::SwitchOnDisabled);
        for tune in [TuneStatus::Pending, TuneStatus::Running] {
            d.current_report(&CurrentReport {
                tune,
                ..CurrentReport::default()
            });
            d.cia402.set_controlword(0x06);
            for _ in 0..3 {
                d.run_cycle(0.001);
            }
            assert_eq!(d.cia402.state(), PdsState::NotReadyToSwitchOn);
            assert_eq!(d.cia402.statusword() & 0x6F, 0);
        }
        d.current_report(&CurrentReport {
            tune: TuneStatus::Done,
            tune_seq: 1,
            ..CurrentReport::default()
        });
        d.cia402.set_controlword(0x00);
        d.run_cycle(0.001);
        assert_eq!(d.cia402.state(), PdsState::SwitchOnDisabled);
        // Once over, a later tune (retry after a fault) does not hold the PDS.
        d.current_report(&CurrentReport {
            tune: TuneStatus::Running,
            tune_seq: 1,
            ..CurrentReport::default()
        });
        d.cia402.set_controlword(0x06);
        for _ in 0..3 {
            d.run_cycle(0.001);
        }
        assert_eq!(d.cia402.state(), PdsState::ReadyToSwitchOn);
        // 0x2013 = 0: no hold at all.
        let mut d = Drive::new(Variant::HybridServo, 0);
        sdo_write(&mut d, 0x2013, 0, &[0]).expect("2013");
        d.current_report(&CurrentReport {
            tune: TuneStatus::Pending,
            ..CurrentReport::default()
        });
        d.run_cycle(0.001);
        assert_eq!(d.cia402.state(), PdsState::SwitchOnDisabled);
    }

    #[test]
    fn current_report_writes_tune_results_and_raises_its_faults() {
        use crate::current_supervisor::{CurrentReport, TunedValues};
        use foc::autotune::{Phase, TuneError};
        let mut d = Drive::new(Variant::HybridServo, 0);
        d.set_axis(AxisState {
            bus_mv: 11_000,
            ..AxisState::default()
        });
        assert!(!d.tune_permitted(), "bus below the under-voltage window");
        d.set_axis(AxisState {
            bus_mv: 48_000,
            ..AxisState::default()
        });
        d.tick(1000, 0);
        assert!(d.tune_permitted());
        let done = CurrentReport {
            tune: TuneStatus::Done,
            tuned: TunedValues {
                r_mohm: 402,
                l_uh: 1795,
                kp: 2256,
                ki: 505,
            },
            tune_seq: 1,
            ..CurrentReport::default()
        };
        d.current_report(&done);
        assert_eq!(sdo_read_u32(&mut d, 0x2020, 0), 402);
        assert_eq!(sdo_read_u32(&mut d, 0x2021, 0), 1795);
        assert_eq!(sdo_read_u32(&mut d, 0x2015, 0), 2256);
        assert_eq!(sdo_read_u32(&mut d, 0x2016, 0), 505);
        // Default mask 0x00C3: motor open and current sensing are off.
        let failed = CurrentReport {
            tune: TuneStatus::Failed(TuneError::OpenPhase(Phase::B)),
            tune_seq: 2,
            follow_seq: 1,
            follow_ref_ma: 2500,
            ..CurrentReport::default()
        };
        d.current_report(&failed);
        assert!(!d.faults.any_active());
        assert!(d.pop_emergency().is_none());
        sdo_write(&mut d, 0x2056, 0, &0x00CFu16.to_le_bytes()).expect("mask");
        let failed = CurrentReport {
            tune_seq: 3,
            follow_seq: 2,
            ..failed
        };
        d.current_report(&failed);
        d.current_report(&failed);
        let e = d.pop_emergency().expect("motor open");
        assert_eq!((e.code, e.data[0], e.data[3], e.data[4]), (0x7120, 3, 1, 1));
        let e = d.pop_emergency().expect("current does not follow");
        assert_eq!(e.code, 0x5210);
        assert_eq!(u16::from_le_bytes([e.data[3], e.data[4]]), 2500);
        assert!(d.pop_emergency().is_none(), "one each");
        assert!(!d.tune_permitted(), "a fault withdraws the permission");
        assert_eq!(d.faults.error_code(), 0x5210, "most severe");
        assert_eq!(d.faults.led_code(), Some(9));
        // Events: a fault reset clears both.
        assert!(d.faults.fault_reset());
        assert!(d.tune_permitted());
    }

    #[test]
    fn save_then_power_cycle_restores_parameters_and_mapping() {
        use crate::storage::RamFlash;
        use ecat_slave_stack::pdo::PdoConfig;
        use ecat_slave_stack::slave::RuntimeObjects;
        use ecat_slave_stack::sync::SyncState;

        let storage = Storage::new(0, 4096);
        let mut pdo = PdoConfig::new(crate::pdo_defaults::PDO_DEFAULTS);
        let mut sync = SyncState::new((0, 0));
        let mut d = Drive::with_store(
            Variant::HybridServo,
            7,
            FlashStore {
                storage,
                history: None,
                flash: RamFlash::<8192>::new(),
            },
        );
        {
            let mut rt = RuntimeObjects {
                pdo: &mut pdo,
                sync: &mut sync,
                objects: dictionary::OBJECTS,
            };
            d.power_up(&mut rt);
        }
        sdo_write_any(&mut d, 0x2000, 0, &2100u16.to_le_bytes()).expect("peak current");
        // Re-assign RxPDO 0x1601 through the runtime objects, then 'save' through the
        // runtime path so the mapping is stored too.
        {
            let mut rt = RuntimeObjects {
                pdo: &mut pdo,
                sync: &mut sync,
                objects: dictionary::OBJECTS,
            };
            rt.write(0x1C12, 0, &[0], EsmState::PreOp)
                .expect("sub 0 to 0");
            rt.write(0x1C12, 1, &0x1601u16.to_le_bytes(), EsmState::PreOp)
                .expect("assign");
            rt.write(0x1C12, 0, &[1], EsmState::PreOp).expect("count");
            let save = crate::comm::SAVE.to_le_bytes();
            d.write_with_runtime(0x1010, 1, &save, EsmState::PreOp, &mut rt)
                .expect("save");
        }
        // Power cycle: a new drive and runtime over the same flash.
        let FlashStore { flash, .. } = d.store.take().expect("store");
        let mut d2 = Drive::with_store(
            Variant::HybridServo,
            7,
            FlashStore {
                storage,
                history: None,
                flash,
            },
        );
        let mut pdo2 = PdoConfig::new(crate::pdo_defaults::PDO_DEFAULTS);
        let mut sync2 = SyncState::new((0, 0));
        let report = {
            let mut rt = RuntimeObjects {
                pdo: &mut pdo2,
                sync: &mut sync2,
                objects: dictionary::OBJECTS,
            };
            d2.power_up(&mut rt)
        };
        assert!(report.source.is_some(), "{report:?}");
        assert_eq!(sdo_read_u32_any(&mut d2, 0x2000, 0), 2100);
        let mut b = [0u8; 4];
        pdo2.read(0x1C12, 1, &mut b).expect("read assign");
        assert_eq!(u16::from_le_bytes([b[0], b[1]]), 0x1601);
        assert!(
            d2.pop_emergency().is_none(),
            "clean load sends no emergency"
        );
    }

    /// A parameter record of a format this image does not know (written by a newer
    /// image, then an older one runs: an update the other way, or a revert) is
    /// refused as a whole: the defaults apply, nothing is half-read, and the next
    /// 'save' writes a record of this image's format.
    #[test]
    fn a_record_of_an_unknown_format_is_refused_and_defaults_apply() {
        use crate::storage::{RamFlash, FORMAT_VERSION};
        let storage = Storage::new(0, 4096);
        let store = |flash| FlashStore {
            storage,
            history: None,
            flash,
        };
        let mut d = Drive::with_store(Variant::HybridServo, 0, store(RamFlash::<8192>::new()));
        d.power_up(&mut NoRuntime);
        sdo_write_any(&mut d, 0x2000, 0, &2100u16.to_le_bytes()).expect("peak current");
        let save = crate::comm::SAVE.to_le_bytes();
        sdo_write_any(&mut d, 0x1010, 1, &save).expect("save");
        let FlashStore { mut flash, .. } = d.store.take().expect("store");
        // The format version (header bytes 4-5) of every slot one higher.
        let newer = (FORMAT_VERSION + 1).to_le_bytes();
        for slot in 0..2 {
            let at = storage.slot_address(slot) as usize + 4;
            flash.mem[at..at + 2].copy_from_slice(&newer);
        }
        let mut d2 = Drive::with_store(Variant::HybridServo, 0, store(flash));
        let report = d2.power_up(&mut NoRuntime);
        assert!(report.source.is_none(), "{report:?}");
        assert_eq!(sdo_read_u32_any(&mut d2, 0x2000, 0), 3200, "defaults");
        // A save of this image's format works over it.
        sdo_write_any(&mut d2, 0x2000, 0, &1900u16.to_le_bytes()).expect("peak current");
        sdo_write_any(&mut d2, 0x1010, 1, &save).expect("save");
        let FlashStore { flash, .. } = d2.store.take().expect("store");
        let mut d3 = Drive::with_store(Variant::HybridServo, 0, store(flash));
        assert!(d3.power_up(&mut NoRuntime).source.is_some());
        assert_eq!(sdo_read_u32_any(&mut d3, 0x2000, 0), 1900);
    }

    #[test]
    fn corrupt_flash_gives_defaults_and_an_emergency() {
        use crate::storage::RamFlash;
        let storage = Storage::new(0, 4096);
        let mut flash = RamFlash::<8192>::new();
        for (i, b) in flash.mem.iter_mut().enumerate() {
            *b = (i as u8).wrapping_mul(37) ^ 0x5A;
        }
        let mut d = Drive::with_store(
            Variant::HybridServo,
            0,
            FlashStore {
                storage,
                history: None,
                flash,
            },
        );
        let report = d.power_up(&mut NoRuntime);
        assert!(report.source.is_none());
        assert_eq!(sdo_read_u32_any(&mut d, 0x2000, 0), 3200);
        let e = d.pop_emergency().expect("emergency for lost parameters");
        assert_eq!(e.code, crate::storage::EMCY_PARAMETERS_LOST);
    }

    /// Bytes of the record header after its CRC (reserved, not checked).
    const HEADER_LEN_RESERVED: u32 = 12;

    type HistoryFlash = crate::storage::RamFlash<{ crate::storage::region::SIZE as usize }>;

    /// A drive over `flash` with the product's record layout (parameters and fault
    /// history), powered up, all detections enabled.
    fn history_drive(flash: HistoryFlash) -> Drive<FlashStore<HistoryFlash>> {
        use crate::storage::region;
        let mut d = Drive::with_store(
            Variant::HybridServo,
            1,
            FlashStore {
                storage: region::PARAMS,
                history: Some(region::HISTORY),
                flash,
            },
        );
        d.power_up(&mut NoRuntime);
        sdo_write_any(&mut d, 0x2056, 0, &0xFFFFu16.to_le_bytes()).expect("mask");
        d
    }

    #[test]
    fn staged_store_programs_a_save_before_the_history() {
        use crate::staged_flash::{Stage, StagedFlash};
        use crate::storage::region;
        let mut ram = HistoryFlash::new();
        let mut stage = Stage::<4096>::new();
        {
            let staged: StagedFlash<'_, &mut HistoryFlash, 4096, 2048> =
                StagedFlash::new(&mut ram, &mut stage, true);
            let mut d = Drive::with_store(
                Variant::HybridServo,
                1,
                FlashStore {
                    storage: region::PARAMS,
                    history: Some(region::HISTORY),
                    flash: staged,
                },
            );
            d.power_up(&mut NoRuntime);
            let (none, err) = d.next_staged_record();
            assert!(none.is_none() && err.is_none(), "nothing to program");
            // A fault marks the history dirty, and a 'save' stages its record: the
            // save's record comes first, the history stays dirty for the next call.
            d.faults
                .raise(FaultKind::OverVoltage, Snapshot::default(), 5);
            let save = u32::from_le_bytes(*b"save").to_le_bytes();
            d.write(0x1010, 1, &save, EsmState::PreOp).expect("save");
            let (first, err) = d.next_staged_record();
            assert!(err.is_none());
            let first = first.expect("the save's record");
            assert_eq!(
                first.erased_range().map(|(from, _)| from),
                Some(region::PARAMS.slot_address(0))
            );
            d.store_mut().expect("store").flash.give_back(first);
            let (second, err) = d.next_staged_record();
            assert!(err.is_none());
            let second = second.expect("the history's record");
            assert_eq!(
                second.erased_range().map(|(from, _)| from),
                Some(region::HISTORY.slot_address(0))
            );
            d.store_mut().expect("store").flash.give_back(second);
            let (none, _) = d.next_staged_record();
            assert!(none.is_none(), "the history was written once");
        }
    }

    /// The history as the SDO dictionary shows it: (0x240n:01 code, :04 bus voltage,
    /// :07 time, :08 operating time) for n = 1..6.
    fn history_by_sdo<S: ParameterStore>(d: &mut Drive<S>) -> [[u32; 4]; 6] {
        let mut h = [[0u32; 4]; 6];
        for (i, e) in h.iter_mut().enumerate() {
            let index = 0x2401 + i as u16;
            assert_eq!(sdo_read_u32_any(d, index, 0), 8);
            *e = [1, 4, 7, 8].map(|sub| sdo_read_u32_any(d, index, sub));
        }
        h
    }

    /// Raises and resets `kind` at `now_ms` with bus voltage `bus_dv`.
    fn fault_at<S: ParameterStore>(d: &mut Drive<S>, kind: FaultKind, bus_dv: u16, now_ms: u32) {
        let snap = Snapshot {
            bus_dv,
            ..Snapshot::default()
        };
        assert!(d.faults.raise(kind, snap, now_ms));
        d.faults.condition_gone(kind);
        d.faults.fault_reset();
    }

    /// 0x10F3 by complete access through the SDO server (segmented upload in a
    /// 128-byte mailbox): the header entries and every message at its 28 bytes, the
    /// same bytes as sub by sub.
    #[test]
    fn diagnosis_history_by_complete_access() {
        use ecat_slave_stack::coe::sdo::SdoServer;
        let mut d = Drive::new(Variant::HybridServo, 42);
        fault_at(&mut d, FaultKind::UnderVoltage, 100, 10);
        let mut single = [([0u8; 32], 0usize); 22];
        for (sub, (b, n)) in single.iter_mut().enumerate() {
            *n = Dictionary::read(&mut d, 0x10F3, sub as u8, b).unwrap();
        }
        let single: [&[u8]; 22] = core::array::from_fn(|k| &single[k].0[..single[k].1]);
        let mut server = SdoServer::new();
        let mut out = [0u8; 128 - 6 - 2];
        let state = EsmState::PreOp;
        // Initiate upload, complete access from sub-index 0.
        let n = server
            .on_request(
                &[0x50, 0xF3, 0x10, 0, 0, 0, 0, 0],
                &mut out,
                &mut d,
                state,
                0,
                None,
            )
            .unwrap();
        // `out` starts with the CoE header (2 bytes).
        assert_eq!(
            out[2] & 0xE0,
            0x40,
            "initiate upload response: {:x?}",
            &out[..n]
        );
        let total = u32::from_le_bytes(out[6..10].try_into().unwrap()) as usize;
        let mut image = [0u8; 512];
        let mut len = n - 10;
        image[..len].copy_from_slice(&out[10..n]);
        let mut toggle = 0u8;
        while len < total {
            let n = server
                .on_request(
                    &[0x60 | toggle << 4, 0, 0, 0, 0, 0, 0, 0],
                    &mut out,
                    &mut d,
                    state,
                    0,
                    None,
                )
                .unwrap();
            assert_eq!(out[2] & 0xE0, 0x00, "upload segment response");
            let unused = usize::from((out[2] >> 1) & 7);
            let k = if n == 10 { 7 - unused } else { n - 3 };
            image[len..len + k].copy_from_slice(&out[3..3 + k]);
            len += k;
            if out[2] & 1 == 1 {
                break;
            }
            toggle ^= 1;
        }
        assert_eq!(len, 8 + 16 * 28);
        assert_eq!(total, len);
        assert_eq!(image[0], single[0][0], "SI0");
        for sub in 1..=3 {
            assert_eq!(image[1 + sub], single[sub][0], "SI{sub}");
        }
        // SI4 was 1 before the newest message was read sub by sub, 0 since.
        assert_eq!((single[4][0], image[5]), (1, 0), "SI4");
        assert_eq!(image[6..8], *single[5], "SI5");
        for k in 0..16 {
            let m = &image[8 + 28 * k..8 + 28 * (k + 1)];
            let s = single[6 + k];
            assert_eq!(m[..s.len()], s[..], "message {k}");
            assert!(
                m[s.len()..].iter().all(|&b| b == 0),
                "padding of message {k}"
            );
        }
        assert_eq!(
            u32::from_le_bytes(image[8..12].try_into().unwrap()),
            0x3220_E800
        );
    }

    fn take_flash(d: Drive<FlashStore<HistoryFlash>>) -> HistoryFlash {
        let mut d = d;
        d.store.take().expect("store").flash
    }

    #[test]
    fn fault_history_survives_a_power_cycle_and_is_written_only_when_serviced() {
        let mut d = history_drive(HistoryFlash::new());
        assert_eq!(history_by_sdo(&mut d), [[0; 4]; 6], "blank flash: empty");
        assert_eq!(d.persist_history(), None, "nothing to write");
        // 100 s of running time, then an over-voltage detected by the tick.
        for t in 1..=100_000u64 {
            d.tick(t * 1000, 0);
        }
        let ops = d.store.as_ref().map(|s| s.flash.ops);
        d.set_axis(AxisState {
            bus_mv: 60_000,
            ..AxisState::default()
        });
        d.tick(100_001_000, 0);
        assert!(d.faults.is_active(FaultKind::OverVoltage));
        assert!(d.faults.history_dirty());
        assert_eq!(
            d.store.as_ref().map(|s| s.flash.ops),
            ops,
            "the fault path does not touch the flash"
        );
        assert_eq!(d.persist_history(), Some(Ok(())));
        assert_eq!(d.persist_history(), None, "written once");
        let before = history_by_sdo(&mut d);
        assert_eq!(before[0], [0x3210, 600, 100_001, 100]);
        // Power cycle: the same history, over the SDO dictionary, and the operating
        // time went on from the stored one (no 'save' of 0x2307 happened).
        let mut d2 = history_drive(take_flash(d));
        assert_eq!(history_by_sdo(&mut d2), before);
        assert_eq!(sdo_read_u32_any(&mut d2, 0x2400, 2), 0x3210);
        assert_eq!(sdo_read_u32_any(&mut d2, 0x2307, 0), 100);
        assert!(!d2.faults.history_dirty(), "loading is no change");
        // A new entry goes on top of the loaded ones and carries the operating time.
        for t in 1..=5_000u64 {
            d2.tick(t * 1000, 0);
        }
        fault_at(&mut d2, FaultKind::UnderVoltage, 110, 5_000);
        assert_eq!(d2.persist_history(), Some(Ok(())));
        let mut d3 = history_drive(take_flash(d2));
        let h = history_by_sdo(&mut d3);
        assert_eq!(h[0], [0x3220, 110, 5_000, 105]);
        assert_eq!(h[1], before[0]);
        // 0x2093 = 1 clears it, in flash too.
        sdo_write_any(&mut d3, 0x2093, 0, &[1]).expect("clear");
        d3.tick(1000, 0);
        assert_eq!(history_by_sdo(&mut d3), [[0; 4]; 6]);
        assert_eq!(d3.persist_history(), Some(Ok(())));
        let mut d4 = history_drive(take_flash(d3));
        assert_eq!(history_by_sdo(&mut d4), [[0; 4]; 6], "cleared in flash");
    }

    #[test]
    fn power_cut_at_every_byte_of_a_history_write_keeps_old_or_new_history() {
        // Old history: two entries, written.
        let mut d = history_drive(HistoryFlash::new());
        fault_at(&mut d, FaultKind::UnderVoltage, 111, 10);
        fault_at(&mut d, FaultKind::FollowingError, 222, 20);
        assert_eq!(d.persist_history(), Some(Ok(())));
        let old_flash = take_flash(d);
        let old = history_by_sdo(&mut history_drive(old_flash.clone()));
        assert_eq!((old[0][0], old[1][0], old[2][0]), (0x8611, 0x3220, 0));
        // The new history: one more entry; how many byte operations its write takes.
        let raise_new = |d: &mut Drive<FlashStore<HistoryFlash>>| {
            fault_at(d, FaultKind::MotorOpen, 333, 30);
        };
        let mut d = history_drive(old_flash.clone());
        raise_new(&mut d);
        if let Some(s) = d.store.as_mut() {
            s.flash.power_on();
        }
        assert_eq!(d.persist_history(), Some(Ok(())));
        let total = d.store.as_ref().map_or(0, |s| s.flash.ops);
        let new = history_by_sdo(&mut history_drive(take_flash(d)));
        assert_eq!((new[0][0], new[1][0], new[2][0]), (0x7120, 0x8611, 0x3220));
        assert!(
            total > 2048,
            "erase of a 2 KiB slot and the record: {total}"
        );
        // Old history until the header's CRC is in flash (its last 12 bytes are
        // reserved, not part of the record's check), the new one from then on.
        let (mut saw_old, mut saw_new) = (0, 0);
        for cut in 0..=total {
            let mut d = history_drive(old_flash.clone());
            raise_new(&mut d);
            if let Some(s) = d.store.as_mut() {
                s.flash.power_on();
                s.flash.cut_power_after(cut);
            }
            let r = d.persist_history();
            assert_eq!(r.is_some_and(|r| r.is_ok()), cut == total, "cut {cut}");
            let mut flash = take_flash(d);
            flash.power_on();
            // Restart: the history read back over the SDO dictionary.
            let mut d2 = history_drive(flash);
            let h = history_by_sdo(&mut d2);
            if h == old {
                assert_eq!(saw_new, 0, "old history after the new one (cut {cut})");
                saw_old += 1;
            } else {
                assert_eq!(h, new, "cut after {cut} of {total} operations");
                saw_new += 1;
            }
            assert_eq!(d2.faults.active_mask(), 0);
        }
        assert_eq!(saw_old + saw_new, total + 1);
        assert_eq!(
            saw_new,
            1 + (HEADER_LEN_RESERVED as usize),
            "new once committed"
        );
    }

    #[test]
    fn garbage_flash_gives_an_empty_history_and_the_drive_runs_on() {
        use crate::storage::region;
        let mut flash = HistoryFlash::new();
        let mut x = 0x1234_5678u32;
        for b in flash.mem.iter_mut() {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            *b = x as u8;
        }
        let mut d = history_drive(flash);
        assert_eq!(history_by_sdo(&mut d), [[0; 4]; 6]);
        fault_at(&mut d, FaultKind::UnderVoltage, 1, 1);
        assert_eq!(d.persist_history(), Some(Ok(())), "writes over garbage");
        let mut d = history_drive(take_flash(d));
        assert_eq!(history_by_sdo(&mut d)[0][0], 0x3220);
        // A record with a valid CRC but a payload that is no history (unknown kind,
        // wrong length): an empty history.
        for bad in [
            &[0u8, 0, 0, 0, 1, 0, 0, 0][..],
            &[0u8; 34][..],
            &[9u8; 3][..],
        ] {
            let mut flash = HistoryFlash::new();
            let mut p = [0u8; 34];
            p[..bad.len()].copy_from_slice(bad);
            if bad.len() == 34 {
                p[4] = 1;
                p[8] = 200; // kind 200
            }
            region::HISTORY
                .write_bytes(&mut flash, &p[..bad.len()])
                .expect("record");
            let mut d = history_drive(flash);
            assert_eq!(history_by_sdo(&mut d), [[0; 4]; 6], "{bad:?}");
        }
    }

    fn sdo_write_any<S: ParameterStore>(
        d: &mut Drive<S>,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), SdoAbort> {
        let e = od::find_entry(dictionary::OBJECTS, index, sub)?;
        od::check_write(e, data, EsmState::PreOp)?;
        d.write(index, sub, data, EsmState::PreOp)
    }

    fn sdo_read_u32_any<S: ParameterStore>(d: &mut Drive<S>, index: u16, sub: u8) -> u32 {
        let mut b = [0u8; 8];
        let n = d.read(index, sub, &mut b).expect("read");
        let mut v = [0u8; 4];
        v[..n.min(4)].copy_from_slice(&b[..n.min(4)]);
        u32::from_le_bytes(v)
    }
}
