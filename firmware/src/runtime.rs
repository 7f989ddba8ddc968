//! The drive runtime: every sequencing decision the board's tasks make, in one place
//! that the simulator runs too.
//!
//! The board's `main.rs` creates the peripherals and spawns tasks; each task calls one
//! function here and moves the result to the hardware. `tests-host`'s simulated drive
//! (and so `virtual-drive` and every master test) calls the same functions in the same
//! order over its models. What a test shows is therefore what the board does.
//!
//! | board task (clock) | runtime function | what it decides |
//! |---|---|---|
//! | start-up, once | [`Runtime::power_up`] | DIP banks → settings, stored parameters, station alias |
//! | supervisor, once | [`Runtime::offsets_checked`] | the current-sensor check → power permission or fault 9 |
//! | cyclic (SYNC0) | [`Runtime::before_step`] / [`Runtime::after_step`] | measurements in, set-points out around the master's cycle; the brake-close hold (the power stays on until the brake has held for 0x215A), the brake at once when the power stage is lost |
//! | 1 ms tick (the drive's own clock) | [`Runtime::tick`] | break latch ↔ fault 1, board faults, the drive's tick, counters, DIP station entry, configuration of the control path, outputs, brake, LEDs |
//! | EtherCAT poll (thread) | [`Runtime::before_poll`] / [`Runtime::after_poll`], [`Runtime::record_committed`] | emergencies to the mailbox, ESC loss, update confirmation, reset into the bootloader, a failed flash record |
//! | supervisor, 100 Hz | [`Runtime::feed_watchdog`] | whether the watchdog may be fed |
//!
//! The hardware is reached through [`ControlPath`] (the current-loop interrupt's
//! exchange, the break latch) and plain values in and out ([`Pins`], [`EsmView`]).
//! Nothing here touches a register.

use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::leds::{ErrCondition, StatusLeds};
use ecat_slave_stack::od::Dictionary;
use ecat_slave_stack::slave::SlaveApplication;

use crate::board_glue::{BoardGlue, ControlCommand, Feedback};
use crate::cia402::{DriveCommand, SetpointKind};
use crate::current_supervisor::SupervisorConfig;
use crate::dip::{self, AliasSource, SingleBank};
use crate::drive::{Drive, ParameterStore};
use crate::faults::Emergency;
use crate::motion::{MotionConfig, MotorConstants};
use crate::params::{DipReading, Param, Params};
use crate::scope::ServoPoint;
use crate::storage::LoadReport;

/// What distinguishes one board (or the simulator's model of it) from another: the
/// one place a board variant is chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoardSpec {
    /// The DIP layout ([`dip::Board`]).
    pub dip: dip::Board,
    /// The motor the loops are designed for until tuned.
    pub motor: MotorConstants,
    /// Servo period, s.
    pub servo_ts: f32,
    /// Current-loop (PWM) period, s.
    pub pwm_ts: f32,
    /// PWM timer period (auto-reload), counts.
    pub pwm_arr: u16,
}

/// The current-loop interrupt as the runtime sees it (the board: `hw::control`'s
/// exchange; the simulator: its axis model).
pub trait ControlPath {
    /// The latest measurements and their sequence number (`None`: nothing new could be
    /// read).
    fn feedback(&mut self) -> Option<(u32, Feedback)>;
    /// The power stage's over-current (break) latch is set.
    fn break_latched(&self) -> bool;
    /// The bridges are on now, as the control path last switched them (between its
    /// published measurements: a trip in the middle of a servo period shows here at
    /// once).
    fn bridges_on_now(&self) -> bool;
    /// Publishes a command to the control path.
    fn send(&mut self, command: &ControlCommand);
    /// Tries to re-arm the break after an over-current; true when it is re-armed.
    fn rearm_break(&mut self) -> bool;
    /// Hands the servo-rate scope points collected since the last call to `sink`;
    /// `wanted`: whether the next ones are wanted.
    fn drain_trace(&mut self, wanted: bool, sink: &mut dyn FnMut(&ServoPoint));
    /// The parameters changed (every 10 ms): a model that configures itself from them
    /// takes them here. The board's control path gets its configuration through the
    /// command instead (default: nothing).
    fn parameters(&mut self, params: &Params) {
        let _ = params;
    }
}

/// The EtherCAT state machine as the LEDs need it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EsmView {
    /// ESM state.
    pub state: EsmState,
    /// What the ERR indicator shows.
    pub err: ErrCondition,
}

impl EsmView {
    /// No slave runtime (the ESC did not answer at start-up): Init, booting error.
    pub const NO_ESC: EsmView = EsmView {
        state: EsmState::Init,
        err: ErrCondition::BootingError,
    };

    /// From the AL status register and AL status code.
    pub fn from_al_status(state: EsmState, al_status: u16, al_code: u16) -> Self {
        EsmView {
            state,
            err: ErrCondition::from_al_status(al_status, al_code),
        }
    }
}

/// The levels the board drives, after each tick (also 0x2157).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Pins {
    /// OUT1-OUT3 pin levels (bit n = output n+1 high).
    pub outputs: u8,
    /// Brake output energised (released).
    pub brake_released: bool,
    /// Green power LED.
    pub green: bool,
    /// Red fault LED.
    pub red: bool,
    /// EtherCAT RUN LED.
    pub run: bool,
    /// EtherCAT ERR LED.
    pub err: bool,
}

impl Pins {
    /// The 0x2157 word: bits 0-2 OUT1-OUT3, bit 8 brake released, bits 9-12 green,
    /// red, RUN, ERR.
    pub fn word(&self) -> u16 {
        u16::from(self.outputs & 0x7)
            | u16::from(self.brake_released) << 8
            | u16::from(self.green) << 9
            | u16::from(self.red) << 10
            | u16::from(self.run) << 11
            | u16::from(self.err) << 12
    }
}

/// The DIP banks as read at power-up (bit n = switch n+1 ON).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DipBanks {
    /// ID bank (two-bank boards).
    pub id: u8,
    /// Function bank, or the single bank.
    pub function: u8,
}

/// What [`Runtime::power_up`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PowerUp {
    /// The parameter load.
    pub report: LoadReport,
    /// The switches and what they select.
    pub dip: DipReading,
    /// The station alias to write to the ESC (`None`: keep what it loaded from SII
    /// word 4), and where it comes from.
    pub alias: Option<u16>,
    /// The alias source.
    pub alias_source: AliasSource,
}

/// What the board does after a mailbox poll.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AfterPoll {
    /// A new image on trial confirmed itself now.
    pub confirmed: bool,
    /// An accepted update waits: reset into the bootloader now.
    pub reset: bool,
}

/// The runtime's own state (see the module docs).
pub struct Runtime {
    spec: BoardSpec,
    glue: BoardGlue,
    status: StatusLeds,
    esm: EsmView,
    ticks: u32,
    ticks_at_feed: u32,
    samples_at_feed: u32,
    pins: Pins,
    single_bank: SingleBank,
    /// Last command position while enabled (0x2039/0x2040).
    last_command: Option<i32>,
    /// Last actual position in encoder counts (0x2041/0x2042).
    last_counts: Option<i64>,
    /// The control path has reported its bridges on since this tick (ms), `None`:
    /// off.
    bridges_on_since: Option<u32>,
    /// The bridges were on at the last measurement.
    bridges_on: bool,
    /// The ESC has not answered since (µs), and whether that was reported.
    esc_failing_since: Option<u64>,
    esc_loss_reported: bool,
    /// The last tick's time (ms).
    now_ms: u32,
    /// The brake output engaged at this tick (ms) after being released.
    brake_engaged_at: Option<u32>,
    /// The last command with which the drive held the motor (the brake-close hold's
    /// position).
    last_enabled: DriveCommand,
}

/// An ESC that does not answer for this long (µs) is the loss of the master: the
/// default process-data watchdog time (100 ms).
pub const ESC_LOSS_US: u64 = 100_000;

impl Runtime {
    /// The runtime of a drive on board `spec`, with the control path's first command
    /// (power not permitted, configuration from the drive's parameters).
    pub fn new<S: ParameterStore>(spec: BoardSpec, drive: &Drive<S>) -> Self {
        let ctl = ControlCommand {
            cycle: 0,
            command: *drive.command(),
            cycle_s: 1e-3,
            power_allowed: false,
            config: 0,
            motion: motion_config(&spec, drive),
            align_wiggle: align_wiggle(drive),
            offsets: None,
            supervisor: supervisor_config(&spec, drive),
            tune_allowed: false,
            trace: false,
            brake_released: false,
        };
        Runtime {
            spec,
            glue: BoardGlue::new(ctl),
            status: StatusLeds::new(),
            esm: EsmView::NO_ESC,
            ticks: 0,
            ticks_at_feed: 0,
            samples_at_feed: 0,
            pins: Pins::default(),
            single_bank: SingleBank::new(),
            last_command: None,
            last_counts: None,
            esc_failing_since: None,
            esc_loss_reported: false,
            bridges_on_since: None,
            bridges_on: false,
            now_ms: 0,
            brake_engaged_at: None,
            last_enabled: DriveCommand::default(),
        }
    }

    /// The board this runtime runs.
    pub fn spec(&self) -> &BoardSpec {
        &self.spec
    }

    /// The command last handed to the control path.
    pub fn command(&self) -> &ControlCommand {
        self.glue.command()
    }

    /// The levels of the last tick.
    pub fn pins(&self) -> Pins {
        self.pins
    }

    /// Power-up, before the ESC leaves Init: the stored parameters (and, through
    /// `runtime_objects`, the PDO mapping) are loaded, then the DIP banks are decoded
    /// for this board (a single bank's stored station number comes from 0x2156), the
    /// function switches latched into the parameters (they rule while 0x2025 = 0), and
    /// the station alias chosen.
    pub fn power_up<S: ParameterStore>(
        &mut self,
        drive: &mut Drive<S>,
        banks: DipBanks,
        runtime_objects: &mut dyn Dictionary,
    ) -> PowerUp {
        let report = drive.power_up(runtime_objects);
        let stored = drive.params.get(Param::DipStation) as u16;
        let cfg = dip::power_up(self.spec.dip, banks.id, banks.function, stored);
        let reading = DipReading {
            id_bits: if self.spec.dip == dip::Board::TwoBanks {
                banks.id
            } else {
                0
            },
            function_bits: banks.function,
            address: cfg.address,
            functions: cfg.functions,
        };
        drive.params.set_dip(reading);
        if matches!(self.spec.dip, dip::Board::SingleBank(_)) {
            // A bank switched on with SW8 ON is in station entry from the start.
            self.single_bank.update(banks.function);
        }
        drive.apply_parameters();
        let active = drive.params.active();
        let (alias, source) =
            dip::station_alias(active.alias_source, active.alias_value, cfg.address, 0);
        self.configure(drive);
        PowerUp {
            report,
            dip: reading,
            alias: (source != AliasSource::Sii).then_some(alias),
            alias_source: source,
        }
    }

    /// The start-up current-sensor check (bridges off): `Some((ia, ib))` offsets in
    /// counts when it passed — the control path may use the bridges and the auto-tune
    /// from the next command on; `None` when it failed — fault 9 at every tick until
    /// restart. Either way the start-up checks are over (a trial image confirms itself
    /// only after a pass).
    pub fn offsets_checked<S: ParameterStore>(
        &mut self,
        drive: &mut Drive<S>,
        ctl: &mut dyn ControlPath,
        offsets: Option<(f32, f32)>,
    ) {
        match offsets {
            Some((ia, ib)) => self.glue.offsets_passed(ia, ib),
            None => self.glue.offset_check_failed(),
        }
        drive.startup_checks_done(offsets.is_some());
        self.after_step(drive, ctl);
    }

    /// Before a drive step (the master's cycle): the control path's measurements to
    /// the drive.
    pub fn before_step<S: ParameterStore>(
        &mut self,
        drive: &mut Drive<S>,
        ctl: &mut dyn ControlPath,
    ) {
        if let Some((seq, fb)) = ctl.feedback() {
            self.bridges_on = fb.bridges_on;
            let latched = ctl.break_latched();
            self.glue.update_axis(drive, seq, &fb, latched);
            if !fb.bridges_on || latched {
                // The power stage is lost: the brake at once.
                self.engage_brake(drive);
            }
        }
        if !ctl.bridges_on_now() {
            // Switched off since its last measurements (a fast-protection trip).
            self.bridges_on = false;
            self.engage_brake(drive);
        }
    }

    /// The brake decision engages now, between ticks (0x2157 with it; the next command
    /// carries it to the control path, which engages the pin itself as soon as its
    /// bridges go off): the power stage is lost or the drive has stopped holding the
    /// motor.
    fn engage_brake<S: ParameterStore>(&mut self, drive: &mut Drive<S>) {
        if self.pins.brake_released {
            self.pins.brake_released = false;
            self.brake_engaged_at = Some(self.now_ms);
            drive.params.set_output_state(self.pins.word());
        }
    }

    /// After a drive step (or whenever the permissions may have changed): the command
    /// to the control path.
    pub fn after_step<S: ParameterStore>(
        &mut self,
        drive: &mut Drive<S>,
        ctl: &mut dyn ControlPath,
    ) {
        let hold = self.brake_hold(drive, ctl.break_latched());
        self.glue.set_hold(hold);
        let mut c = *self.glue.publish(drive);
        if hold.is_some() || !c.permits_power() {
            self.engage_brake(drive);
        }
        // The control path drives the pin from this decision, and engages it on its
        // own in the period its bridges go off (`crate::power_gate::BrakeOut`).
        self.glue.set_brake_released(self.pins.brake_released);
        c.brake_released = self.pins.brake_released;
        ctl.send(&c);
    }

    /// The power authority's brake-close sequence, decided before every command:
    /// when the drive stops holding the motor (shutdown, disable voltage, the end of a
    /// quick stop or of a fault reaction's ramp, Bootstrap) while the brake output is
    /// released or engaged less than the brake-close delay 0x215A ago, the motor keeps
    /// holding at standstill — the last enabled step's position, no speed, no torque
    /// feed-forward — with the power permitted, so the bridges go off only once the
    /// brake holds. No hold when the power stage is lost (bridges reported off, break
    /// latched, a fault that cuts the power): then the brake engages at once and the
    /// bridges stay off.
    fn brake_hold<S: ParameterStore>(
        &mut self,
        drive: &Drive<S>,
        latched: bool,
    ) -> Option<DriveCommand> {
        let cmd = drive.command();
        if cmd.drive_enabled && drive.power_permission() {
            self.last_enabled = *cmd;
            return None;
        }
        let lost = !self.bridges_on || latched || drive.faults.power_cut();
        let delay = drive.params.get(Param::BrakeCloseDelay) as u32;
        let closing = self.pins.brake_released
            || self
                .brake_engaged_at
                .is_some_and(|t| self.now_ms.wrapping_sub(t) < delay);
        (closing && !lost).then_some(DriveCommand {
            power_stage: true,
            drive_enabled: true,
            kind: SetpointKind::Position,
            velocity: 0.0,
            acceleration: 0.0,
            torque: 0,
            brake_release: false,
            ..self.last_enabled
        })
    }

    /// The 1 ms supervision tick on the drive's own clock, in every ESM state:
    /// break latch ↔ fault 1, measurements, the board's faults, the servo-rate scope
    /// points, [`Drive::tick`] with the raw input levels, the 0x2039-0x2042 counters,
    /// a single bank's station entry, every 10 ms the control path's configuration
    /// from the parameters, the command; then the pins: outputs, brake, LEDs (`esm`:
    /// the ESM as the slave runtime reports it; `None` keeps the last). `dip_bits`: the
    /// single bank's switches as they stand now (ignored on two-bank boards).
    pub fn tick<S: ParameterStore>(
        &mut self,
        drive: &mut Drive<S>,
        ctl: &mut dyn ControlPath,
        now_us: u64,
        raw_inputs: u8,
        dip_bits: u8,
        esm: Option<EsmView>,
    ) -> Pins {
        self.ticks = self.ticks.wrapping_add(1);
        let now_ms = (now_us / 1000) as u32;
        self.now_ms = now_ms;
        self.over_current(drive, ctl);
        self.before_step(drive, ctl);
        self.glue.raise_board_faults(drive, now_ms);
        ctl.drain_trace(drive.scope_wants_servo_points(), &mut |p| {
            drive.scope_servo_point(p)
        });
        drive.tick(now_us, raw_inputs);
        self.count(drive);
        if matches!(self.spec.dip, dip::Board::SingleBank(_)) {
            if let Some(station) = self.single_bank.update(dip_bits) {
                // Stored with the next save; the DIP address from the next power-up.
                drive
                    .params
                    .set_internal(Param::DipStation, i32::from(station));
            }
        }
        if self.ticks.is_multiple_of(10) {
            self.configure(drive);
            ctl.parameters(&drive.params);
        }
        let (outputs, brake) = drive.outputs();
        // The brake releases only once the control path has reported its bridges on
        // for the release delay 0x2159 (the motor holds the load before the brake
        // lets go), never while the power stage is latched off.
        let latched = ctl.break_latched();
        let on = self.bridges_on && ctl.bridges_on_now() && !latched;
        let on_since = match (on, self.bridges_on_since) {
            (true, Some(t)) => Some(t),
            (true, None) => Some(now_ms),
            (false, _) => None,
        };
        self.bridges_on_since = on_since;
        let delay = drive.params.get(Param::BrakeReleaseDelay) as u32;
        let held = on_since.is_some_and(|t| now_ms.wrapping_sub(t) >= delay);
        let released = brake && held;
        if self.pins.brake_released && !released {
            // The close delay 0x215A runs from here ([`Runtime::brake_hold`]).
            self.brake_engaged_at = Some(now_ms);
        }
        self.pins.brake_released = released;
        // The command carries the decision (and the brake-close hold).
        self.after_step(drive, ctl);
        if let Some(v) = esm {
            self.esm = v;
        }
        self.status.update(self.esm.state, self.esm.err, now_ms);
        let leds = drive.leds(now_ms);
        let (run, err) = self.status.levels(now_ms);
        self.pins = Pins {
            outputs,
            brake_released: self.pins.brake_released,
            green: leds.green,
            red: leds.red,
            run,
            err,
        };
        drive.params.set_output_state(self.pins.word());
        self.pins
    }

    /// Before a mailbox poll: the drive's emergencies to the mailbox (`send`).
    pub fn before_poll<S: ParameterStore>(
        &mut self,
        drive: &mut Drive<S>,
        send: &mut dyn FnMut(Emergency),
    ) {
        while let Some(e) = drive.pop_emergency() {
            send(e);
        }
    }

    /// After a mailbox poll, in thread mode (flash allowed): `poll_ok` tells whether
    /// the ESC answered; an ESC that has not answered for [`ESC_LOSS_US`] is the loss
    /// of the master (the 0x6007 reaction, as a process-data watchdog: the master's
    /// set-points can no longer arrive). Then the command (the poll may have changed
    /// the state), a new image on trial confirms itself, and whether an accepted update
    /// waits for the reset into the bootloader.
    pub fn after_poll<S: ParameterStore>(
        &mut self,
        drive: &mut Drive<S>,
        ctl: &mut dyn ControlPath,
        poll_ok: bool,
        now_us: u64,
    ) -> AfterPoll {
        if poll_ok {
            self.esc_failing_since = None;
            self.esc_loss_reported = false;
        } else {
            let since = *self.esc_failing_since.get_or_insert(now_us);
            if !self.esc_loss_reported && now_us.saturating_sub(since) >= ESC_LOSS_US {
                self.esc_loss_reported = true;
                drive.on_outputs_lost(ecat_slave_stack::al_status::AlStatusCode::SmWatchdog);
            }
        }
        self.after_step(drive, ctl);
        AfterPoll {
            confirmed: drive.confirm_update(),
            reset: drive.reset_requested(),
        }
    }

    /// A staged flash record (a 'save', the fault history) was programmed after the
    /// poll, outside the lock: a failed programming is reported as an emergency
    /// (0x5530, non-volatile memory) through `send`; the drive keeps its RAM copy.
    pub fn record_committed<S: ParameterStore>(
        &mut self,
        drive: &Drive<S>,
        ok: bool,
        send: &mut dyn FnMut(Emergency),
    ) {
        if !ok {
            send(Emergency {
                code: crate::storage::EMCY_RECORD_CORRUPT,
                register: drive.faults.error_register() | 1,
                data: [0; 5],
            });
        }
    }

    /// The supervisor's watchdog policy: feed only while the current-loop interrupt
    /// produced new samples (`samples`: its sample counter), its control state is
    /// installed (`control_ready`) and the 1 ms tick ran since the last feed.
    pub fn feed_watchdog(&mut self, samples: u32, control_ready: bool) -> bool {
        let feed =
            control_ready && samples != self.samples_at_feed && self.ticks != self.ticks_at_feed;
        if feed {
            self.samples_at_feed = samples;
            self.ticks_at_feed = self.ticks;
        }
        feed
    }

    /// Break latch (hardware over-current) ↔ fault 1 ([`BoardGlue::over_current`]):
    /// once the drive holds the fault, the command that withdraws the power permission
    /// is published before the latch is re-armed; a re-armed latch is the condition
    /// gone, so a fault reset clears the fault.
    fn over_current<S: ParameterStore>(&mut self, drive: &mut Drive<S>, ctl: &mut dyn ControlPath) {
        let latched = ctl.break_latched();
        if let Some(c) = self.glue.over_current(drive, latched).copied() {
            ctl.send(&c);
            if ctl.rearm_break() {
                self.glue.break_rearmed(drive);
            }
        }
    }

    /// The control path's configuration from the parameters (applied when it changed).
    fn configure<S: ParameterStore>(&mut self, drive: &Drive<S>) {
        self.glue.configure(
            motion_config(&self.spec, drive),
            align_wiggle(drive),
            supervisor_config(&self.spec, drive),
        );
    }

    /// 0x2039/0x2040: command units the enabled drive was told to move (the
    /// position set-point's change); 0x2041/0x2042: encoder counts the axis moved.
    /// Both are 32-bit two's complement sums of the signed changes.
    fn count<S: ParameterStore>(&mut self, drive: &mut Drive<S>) {
        let cmd = drive.command();
        if cmd.drive_enabled {
            let p = cmd.position;
            if let Some(last) = self.last_command {
                drive.params.add_command_pulses(p.wrapping_sub(last) as u32);
            }
            self.last_command = Some(p);
        } else {
            self.last_command = None;
        }
        if drive.variant.has_encoder() {
            let cpr = i64::from(drive.params.get(Param::EncoderResolution)) * 4;
            let ppr = i64::from(drive.params.active().pulses_per_rev.max(1));
            let counts = i64::from(drive.axis_state().position) * cpr / ppr;
            if let Some(last) = self.last_counts {
                drive.params.add_encoder_counts((counts - last) as u32);
            }
            self.last_counts = Some(counts);
        }
    }
}

/// The motion layer's configuration on board `spec` from the drive's parameters.
pub fn motion_config<S: ParameterStore>(spec: &BoardSpec, d: &Drive<S>) -> MotionConfig {
    MotionConfig::from_params(&d.params, d.variant, &spec.motor, spec.servo_ts)
}

/// The current-loop supervision (auto-tune 0x2013, its test current) on board `spec`.
pub fn supervisor_config<S: ParameterStore>(spec: &BoardSpec, d: &Drive<S>) -> SupervisorConfig {
    SupervisorConfig::from_params(&d.params, spec.pwm_ts, spec.pwm_arr)
}

/// 0x2083: the power-up alignment sweeps the field (wiggle) and checks the encoder.
pub fn align_wiggle<S: ParameterStore>(d: &Drive<S>) -> bool {
    d.params.get(Param::PowerUpWiggle) != 0
}

#[cfg(test)]
mod tests;
