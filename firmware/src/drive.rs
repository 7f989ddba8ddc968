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
use crate::scope::Scope;
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
    /// Torque-producing current reference (the servo loops' demand), per mille of the
    /// peak current 0x2000.
    pub current_permille: i16,
    /// Measured torque-producing current: the q current in the encoder frame, per
    /// mille of the peak current 0x2000 (= torque per mille of the rated torque 0x6076);
    /// 0 without an encoder.
    pub torque_permille: i16,
    /// Output of the position controller (0x60FA), command units/s
    /// ([`crate::motion::Motion::control_effort`]).
    pub control_effort: i32,
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
    /// Counts the open-loop stalls confirmed by the motion layer's detector (wrapping).
    pub stall_seq: u32,
    /// Command position where the last stall began (command units).
    pub stall_position: i32,
    /// Estimated load angle of the open loop, 0.1° electrical (0x2063).
    pub load_angle_ddeg: i16,
    /// The motion layer's servo tune runs ([`crate::servo_tune`]).
    pub servo_tune: crate::servo_tune::TuneReport,
}

/// LED levels of the drive (RUN/ERR come from the slave runtime's indicators).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DriveLeds {
    /// Green power LED.
    pub green: bool,
    /// Red fault LED (blink code of the most severe active fault).
    pub red: bool,
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
    /// The scope (trace buffer, 0x2500-0x2510), sampled by the tick.
    pub scope: Scope,
    /// Digital inputs (filtered, functions).
    pub inputs: Inputs,
    /// Positions latched by the edges of the input function "probe" at the ticks,
    /// for touch probe 1, until a drive step takes them.
    probe_tick: crate::cia402::EdgeLatch,
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
    /// `AxisState::stall_seq` of the last stall handled.
    stall_seen: u32,
    /// The servo tune (0x2162).
    servo_tune: crate::servo_tune::TuneControl,
    store: Option<S>,
    load_report: Option<LoadReport>,
    storage_emergency: Option<(u16, [u8; 5])>,
    /// The rate limit of the fault-history records (`crate::storage::rate`).
    history_rate: crate::storage::rate::HistoryRate,
    seen_tune_seq: u8,
    /// The last current auto-tune failed: no retry until 0x2013 is written again.
    tune_failed: bool,
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
            scope: Scope::new(),
            inputs: Inputs::default(),
            probe_tick: crate::cia402::EdgeLatch::default(),
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
            stall_seen: 0,
            servo_tune: crate::servo_tune::TuneControl::default(),
            store: Some($store),
            load_report: None,
            storage_emergency: None,
            history_rate: crate::storage::rate::HistoryRate::new(),
            seen_tune_seq: 0,
            tune_failed: false,
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
        let encoder_counts = if self.variant.has_encoder() {
            (self.params.get(Param::EncoderResolution) as u32).saturating_mul(4)
        } else {
            0
        };
        self.cia402.set_resolution(encoder_counts);
        self.cia402.set_has_index(self.variant.has_encoder());
        self.cia402
            .set_rated_current_ma(u32::from(self.params.settings().peak_current_ma));
        self.control_config_changed();
    }

    /// 0x2024 / 0x2060 / 0x2001 may have changed: CST's availability (closed loop)
    /// and stall homing's precondition (open loop with the stall detection 0x2060 on;
    /// the detection judges from 1 rev/s, so 0x6099:01 must reach 0x2001 units/s).
    pub(crate) fn control_config_changed(&mut self) {
        self.cia402.set_torque_control(self.torque_control());
        let stall = !self.torque_control() && self.params.get(Param::StallEnable) != 0;
        let ppr = match self.params.active().pulses_per_rev {
            0 => self.params.get(Param::PulsesPerRev),
            n => n as i32,
        };
        self.cia402
            .set_stall_homing(stall.then_some(ppr.max(1) as f32));
    }

    /// The closed loop is configured (an encoder and 0x2024 = 2): the motor side
    /// controls torque, CST is available.
    pub(crate) fn torque_control(&self) -> bool {
        self.variant.has_encoder() && self.params.get(Param::LoopMode) == 2
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
    /// Rate-limited ([`crate::storage::rate`]: ≥ 10 s between records, at most
    /// 8 + hours / 2 records): a change waits (still dirty) until the limit lets it
    /// through, at most 2 h; the history in RAM is complete meanwhile.
    ///
    /// `None`: nothing to do now (or no history memory); `Some(result)` of the write.
    /// The history counts as written either way (a failed write is reported once, not
    /// retried every tick; the next change writes again).
    pub fn persist_history(&mut self) -> Option<Result<(), StorageError>> {
        if !self.faults.history_dirty() || !self.history_rate.may_write(self.now_ms) {
            return None;
        }
        self.history_rate.wrote();
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
        self.params.set_load_angle(a.load_angle_ddeg);
    }

    /// The motor side's measurements last handed to the drive.
    pub fn axis_state(&self) -> &AxisState {
        &self.axis
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
        // Not while the current auto-tune may drive the bridges either.
        let due = self.startup_checks == Some(true)
            && !self.command.power_stage
            && self.power_up_tune_over;
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

    /// A stall the motion layer confirmed since the last step (where it began, command
    /// units).
    fn take_stall(&mut self) -> Option<i32> {
        let seq = self.axis.stall_seq;
        if seq == self.stall_seen {
            return None;
        }
        self.stall_seen = seq;
        Some(self.axis.stall_position)
    }

    /// Fault 0x7121 (motor blocked): an event, its condition gone at once, so a fault
    /// reset clears it; the emergency's detail is the load angle (0.1°).
    fn raise_motor_blocked(&mut self) {
        let snap = self.snapshot();
        let detail = self.axis.load_angle_ddeg.to_le_bytes();
        self.faults
            .raise_detail(FaultKind::MotorBlocked, detail, snap, self.now_ms);
        self.faults.condition_gone(FaultKind::MotorBlocked);
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
    /// starts its reaction in the same tick. Last, the scope's sample when it records
    /// ([`crate::scope`]). `raw_inputs`: bit n = level of IN n+1.
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
        // Input function "probe" (0x2152 bit 5): an edge latches the position at this
        // tick for touch probe 1, beside IN1's capture.
        if let Some(active) = self.inputs.probe_edge() {
            self.probe_tick = self.probe_tick.or(active, self.axis.position);
        }
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
        self.servo_tune_tick(dt_ms);
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
        if self.cia402.take_following_error_fault() {
            // The CiA 402 following-error supervision (0x6065 / 0x6066) faulted the
            // PDS: the fault module reports it like every other fault (emergency,
            // history, red LED 7, alarm output); an event, so a reset clears it.
            let snap = self.snapshot();
            self.faults
                .raise(FaultKind::FollowingError, snap, self.now_ms);
            self.faults.condition_gone(FaultKind::FollowingError);
        }
        if self.scope.running() {
            self.sample_scope();
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
    /// window and no fault is active; with 0x2013 = 1 also the power stage off and the
    /// brake engaged (`Drive::tune_state_allows`) and no failed tune since the last
    /// 0x2013 write. (With 0x2013 = 0 the permission only gates the first enable's
    /// phase check, which runs with the enable.) The control path also needs the
    /// current-sensor offsets to have passed their start-up check.
    pub fn tune_permitted(&self) -> bool {
        let c = self.faults.config();
        let bus = self.axis.bus_mv;
        bus >= c
            .under_voltage_mv
            .saturating_add(c.under_voltage_hysteresis_mv)
            && bus <= c.over_voltage_mv
            && !self.faults.any_active()
            && (self.params.get(Param::AutoTune) == 0
                || (!self.tune_failed && self.tune_state_allows()))
    }

    /// The PDS and ESM states in which the current auto-tune may energise the motor:
    /// the power-up self-test (Not ready to switch on), Switch on disabled, Ready to
    /// switch on or Fault (it then waits for the reset) — the power stage off and the
    /// brake engaged — and never in Bootstrap.
    pub(crate) fn tune_state_allows(&self) -> bool {
        use crate::cia402::pds::PdsState;
        matches!(
            self.cia402.state(),
            PdsState::NotReadyToSwitchOn
                | PdsState::SwitchOnDisabled
                | PdsState::ReadyToSwitchOn
                | PdsState::Fault
        ) && self.esm != EsmState::Bootstrap
            && !self.command.power_stage
            && !self.command.brake_release
    }

    /// A stop ramp runs (quick stop or fault reaction).
    #[cold]
    fn stopping(&self) -> bool {
        use crate::cia402::pds::PdsState;
        matches!(
            self.cia402.state(),
            PdsState::QuickStopActive | PdsState::FaultReactionActive
        )
    }

    /// Entering Bootstrap: the power stage goes off now unless a stop ramp runs (the
    /// 0x6007 reaction of the ESM change), in which case it goes off at its end.
    fn bootstrap_stop(&mut self) {
        if !self.stopping() {
            self.command.power_stage = false;
            self.command.drive_enabled = false;
            self.command.brake_release = false;
            // The PDS leaves the enabled states (disable voltage, as with 0x6007 = 2):
            // leaving Bootstrap re-energises nothing without a new enable.
            self.cia402.set_controlword(0);
            self.react_now = true;
        }
    }

    /// The current-loop supervisor's report (control path → drive; call every tick,
    /// before [`Drive::tick`]). A finished tune writes 0x2020 (mΩ), 0x2021 (µH), 0x2015
    /// and 0x2016 (the gains the loop now uses) and the calibration 0x2022; a failed one, or a phase without
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
                    self.params.set_calibration(t.calibration);
                }
                TuneStatus::Failed(e) => {
                    use foc::autotune::{Phase, TuneError};
                    // No retry of the auto-tune by itself: a new 0x2013 write asks
                    // for one. (With 0x2013 = 0 this was the first enable's phase
                    // check, which a fault reset re-arms.)
                    self.tune_failed = self.params.get(Param::AutoTune) == 1;
                    // A calibration outside its band is the current sensing's fault
                    // (0x5210, detail 2); the others are the motor's.
                    let (kind, detail) = match e {
                        TuneError::OpenPhase(Phase::A) => (FaultKind::MotorOpen, [1, 0]),
                        TuneError::OpenPhase(Phase::B) => (FaultKind::MotorOpen, [1, 1]),
                        TuneError::Unbalanced => (FaultKind::MotorOpen, [2, 0]),
                        TuneError::Implausible => (FaultKind::MotorOpen, [3, 0]),
                        TuneError::Sensing => (FaultKind::PhaseSensing, [2, 0]),
                    };
                    let snap = self.snapshot();
                    self.faults.raise_detail(kind, detail, snap, self.now_ms);
                    self.faults.condition_gone(kind);
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
                // The trip has already latched the bridges off: reported whatever
                // 0x2056 says (a masked detection would leave the drive enabled with
                // no torque and nothing to see).
                self.faults.raise_unmaskable(kind, snap, self.now_ms);
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

    /// Output pin levels (bit n = output n+1) and whether the drive wants the brake
    /// released (the runtime adds the power stage's confirmation:
    /// [`crate::runtime`]).
    pub fn outputs(&self) -> (u8, bool) {
        let op_enabled = self.command.drive_enabled;
        let master = (
            self.cia402.digital_outputs(),
            self.cia402.digital_outputs_mask(),
        );
        let brake = io::brake_released(op_enabled, self.faults.power_cut(), master);
        let status = OutputStatus {
            alarm: self.faults.alarm(),
            ready: !self.faults.any_active() && self.command.power_stage,
            in_position: self.cia402.statusword() & crate::cia402::sw::TARGET_REACHED != 0,
            brake_released: brake,
            enabled: op_enabled,
        };
        (io::output_levels(&self.params, status, master), brake)
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
        let stall = self.take_stall();
        // The 0x2062 reaction, unless stall homing searches its stop: 1 quick stop (as
        // the quick-stop input, for this step), 0 the motor-blocked fault below.
        let stall_fault = stall.is_some() && !self.cia402.seeking_stall();
        let stall_quick_stop = stall_fault && self.params.get(Param::StallReaction) == 1;
        let fb = DriveFeedback {
            position: self.axis.position,
            velocity: self.axis.velocity,
            control_effort: self.axis.control_effort,
            torque: self.axis.torque_permille,
            torque_demand: self.axis.current_permille,
            current: self.axis.torque_permille,
            digital_inputs: self.inputs.digital_inputs_60fd(),
            index: self.axis.index,
            probe1: self
                .axis
                .probe1
                .merge(core::mem::take(&mut self.probe_tick)),
            probe2: self.axis.probe2,
            fault: self.faults.error_code(),
            power_stage_tripped: power_cut,
            warning: false,
            current_limited: self.axis.current_limited,
            quick_stop_input: self.inputs.quick_stop() || stall_quick_stop,
            enable_pending: self.axis.commutation_pending,
            stall,
        };
        self.command = self.cia402.step(&fb, dt, setpoint);
        if stall_fault && !stall_quick_stop {
            self.raise_motor_blocked();
        }
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
        // the power stage stays off whatever the PDS says, once a running stop ended.
        if power_cut || (self.esm == EsmState::Bootstrap && !self.stopping()) {
            self.command.power_stage = false;
            self.command.drive_enabled = false;
            self.command.brake_release = false;
        }
        self.command
    }
}

mod stack;
mod store;
mod trace;
mod tune;

use stack::WholeDictionary;
pub use stack::{is_saved, NoRuntime};
pub use store::{FlashStore, NoStore, ParameterStore, StagedStore};

#[cfg(test)]
mod safety_tests;
#[cfg(test)]
mod stall_tests;
#[cfg(test)]
mod tests;
