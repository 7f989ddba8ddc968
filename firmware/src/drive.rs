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
//!
//! # Where it is
//! This file holds the drive's state, its construction and the control step; the
//! submodules add one concern each to [`Drive`]: `clock` (the supervision tick and
//! the steps on the drive's clock), `stack` (the slave runtime's view: dictionary,
//! process data, ESM hooks, cycle), `store` (parameter and fault-history
//! persistence), `report` (the current-loop supervisor's report), `boot` (firmware
//! update and Bootstrap), `tune` (the servo tune), `trace` (the scope's samples).

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

pub use crate::motion::AxisState;

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
            scope: Scope::new(dictionary::OBJECTS),
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

    /// The drive's LEDs at `now_ms`.
    pub fn leds(&mut self, now_ms: u32) -> DriveLeds {
        DriveLeds {
            green: true,
            red: self.fault_led.update(self.faults.led_code(), now_ms),
        }
    }

    /// Output pin levels (bit n = output n+1) and whether the drive wants the brake
    /// released (the runtime adds the power stage's confirmation:
    /// `runtime`).
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

mod boot;
mod clock;
mod report;
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
