//! A complete simulated drive: the firmware's drive application
//! ([`firmware::drive::Drive`]) with its parameter flash, behind the slave runtime and
//! the ESC simulator of a [`Segment`], driving a simulated axis.
//!
//! [`SimDrive`] is the [`SlaveApplication`] of each segment position: in every
//! application cycle it advances its [`Axis`] to the cycle's time, hands the measured
//! state to the drive, runs the drive cycle and gives the drive's set-points back to
//! the axis. The helpers [`advance`] / [`process`] move the segment on and also do
//! what the board's main loop does: the 1 ms supervision tick on the drive's own
//! clock, which steps the drive whether or not frames arrive, and forwarding the
//! drive's emergencies to the mailbox.
//!
//! Between the drive and the axis sits the board's runtime,
//! [`firmware::runtime::Runtime`] (what `firmware/src/main.rs`'s tasks call, called
//! here in the same order: the tick in [`SimDrive::catch_up`], the cycle in
//! [`SlaveApplication::cycle`], the mailbox work in [`forward_emergencies`]), and
//! through it the board's glue [`firmware::board_glue::BoardGlue`]: the
//! axis's measurements become a [`Feedback`] for [`BoardGlue::update_axis`] (index
//! kept until a drive step consumed it, a failed commutation alignment,
//! [`Axis::commutation_failures`], → following-error fault 0x8611 at the next tick,
//! the current-loop report), and the axis takes its set-points from
//! [`BoardGlue::publish`] (a new segment per drive step, `drive_enabled` masked by the
//! power permission, the auto-tune permission).

use std::path::PathBuf;

use ecat_slave_stack::al_status::AlStatusCode;
use ecat_slave_stack::esm::{EsmHooks, EsmState};
use ecat_slave_stack::od::{Dictionary, Object, ObjectKey, SdoAbort};
use ecat_slave_stack::pdo::ProcessData;
use ecat_slave_stack::sii::EscFlavour;
use ecat_slave_stack::slave::{CycleInfo, SlaveApplication, SlaveConfig};
use firmware::board_glue::{ControlCommand, Feedback};
use firmware::cia402::DriveCommand;
use firmware::drive::{AxisState, Drive, FlashStore};
use firmware::identity::{self, Variant};
use firmware::runtime::{BoardSpec, ControlPath, DipBanks, EsmView, Runtime};
use firmware::storage::region;

use crate::esc_sim::frame::FrameOutcome;
use crate::esc_sim::Flavour;
use crate::file_flash::FileFlash;
use crate::segment::{Segment, SegmentConfig};
pub use crate::sim_axis::AxisModel;

/// The motor model of the simulated axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Motor {
    /// NEMA 23, 2.0 N·m, 5 A.
    Ecn57_20,
    /// NEMA 34, 4.5 N·m, 6 A, 1000-line encoder.
    Tc86_45,
}

/// What the drive's motor side looks like to the application.
pub trait Axis {
    /// Moves simulated time on by `dt_s` with the drive's latest set-points.
    fn advance(&mut self, dt_s: f64, cmd: &DriveCommand);
    /// Measurements for the next cycle.
    fn state(&mut self) -> AxisState;
    /// Input pin levels (bit n = IN n+1).
    fn raw_inputs(&self) -> u8;
    /// A new set-point from this cycle (`cycle_s` = the cycle period), before
    /// [`Axis::advance`] runs with it. Default: nothing to do.
    fn command(&mut self, cmd: &DriveCommand, cycle_s: f64) {
        let _ = (cmd, cycle_s);
    }
    /// The drive's parameters (gains, resolution, currents). Default: not used.
    fn parameters(&mut self, p: &firmware::params::Params) {
        let _ = p;
    }
    /// The current-loop supervisor: takes the drive's permission for the power-up
    /// auto-tune and returns its report (as the board's control interrupt does through
    /// its exchange). Default: no supervisor, nothing to report.
    fn current_control(
        &mut self,
        tune_permitted: bool,
    ) -> firmware::current_supervisor::CurrentReport {
        let _ = tune_permitted;
        firmware::current_supervisor::CurrentReport::default()
    }
    /// True shaft position in command units, for tests (None: not modelled).
    fn true_position(&self) -> Option<f64> {
        None
    }
    /// Failed commutation alignments since start (wrapping; the board's
    /// `Feedback::align_failures`). Default: the model has no alignment.
    fn commutation_failures(&self) -> u32 {
        0
    }
    /// The plant develops `fault` from now on (`virtual-drive --fault`); false when the
    /// model cannot (default: nothing is modelled).
    fn inject(&mut self, fault: crate::fault_inject::InjectedFault) -> bool {
        let _ = fault;
        false
    }
    /// The scope at the servo rate (`firmware::scope::ServoPoint`, the board's
    /// `ControlHw::trace`): with `on`, the model keeps one point per servo period
    /// from now on; the points kept since the last call go to `out`. Default: a model
    /// without a servo period keeps none.
    fn servo_points(&mut self, on: bool, out: &mut Vec<firmware::scope::ServoPoint>) {
        let _ = (on, out);
    }
    /// With `on`, the model may skip work while the axis rests (e.g.
    /// [`crate::sim_axis::PlantAxis::set_rest_skip`]; `virtual-drive` turns it on).
    /// Default: nothing to skip.
    fn skip_rest(&mut self, on: bool) {
        let _ = on;
    }
    /// The axis rests and stays so until a new command: not controlled, still
    /// (`virtual-drive` then wakes less often, [`crate::realtime::IDLE_TICKS`]).
    /// Default: never claimed.
    fn resting(&self) -> bool {
        false
    }
}

/// The servo periods' points of `axis` to the scope of `drive`, and whether the next
/// ones are wanted (the board's `hw::control::drain_trace` before the drive's tick).
pub fn hand_servo_points<S: firmware::drive::ParameterStore>(
    axis: &mut dyn Axis,
    drive: &mut firmware::drive::Drive<S>,
) {
    let mut points = Vec::new();
    axis.servo_points(drive.scope_wants_servo_points(), &mut points);
    for p in &points {
        drive.scope_servo_point(p);
    }
}

/// Settings of the simulated drives.
#[derive(Debug, Clone)]
pub struct SimDriveConfig {
    /// Motor model.
    pub motor: Motor,
    /// ESC chip.
    pub flavour: Flavour,
    /// Parameter flash mirrored to this file (one file per drive: `FILE`, `FILE.2`, …).
    pub flash_file: Option<PathBuf>,
    /// The DIP banks as they stand at power-up (`virtual-drive --dip-id` /
    /// `--dip-function`; bit n = switch n+1 ON).
    pub dips: DipBanks,
}

impl SimDriveConfig {
    /// `motor` on `flavour`, no flash file, the DIP switches all ON (no DIP address;
    /// the function bank's smallest current, used only with 0x2025 = 0).
    pub fn new(motor: Motor, flavour: Flavour) -> Self {
        SimDriveConfig {
            motor,
            flavour,
            flash_file: None,
            dips: DIPS_ALL_ON,
        }
    }
}

/// Every DIP switch ON: no DIP station address; the function bank selects the
/// smallest current (used only with 0x2025 = 0).
pub const DIPS_ALL_ON: DipBanks = DipBanks {
    id: 0xFF,
    function: 0xFF,
};

/// The simulated board: the reference board's DIP layout, the ECN57-20, the plant
/// rig's loop periods.
pub const SIM_BOARD: BoardSpec = BoardSpec {
    dip: firmware::dip::Board::TwoBanks,
    motor: firmware::motion::ECN57_20,
    servo_ts: firmware::motion::SERVO_TS,
    pwm_ts: crate::plant::rig::TS,
    pwm_arr: 2125,
};

/// The drive's parameter flash.
pub type SimStore = FlashStore<FileFlash>;

/// One simulated drive: firmware drive application + axis, sequenced by the board's
/// runtime ([`Runtime`]).
pub struct SimDrive {
    /// The firmware's drive application.
    pub drive: Drive<SimStore>,
    /// The motor side.
    pub axis: Box<dyn Axis>,
    /// The board's runtime: what the board's tasks call, called here in the same order.
    pub rt: Runtime,
    /// The runtime's view of the axis (the board's current-loop exchange).
    path: PathState,
    /// Simulated time the axis has reached, µs.
    axis_us: u64,
    /// Simulated time of the last 1 ms tick, µs.
    tick_us: u64,
    /// The DIP banks at power-up.
    pub dips: DipBanks,
    /// The ESM as the LEDs show it (from the slave runtime, when the segment saw it).
    esm: Option<EsmView>,
    /// The segment's count of failed polls when last looked at.
    poll_errors_seen: u64,
    /// 0x1018:04.
    serial: u32,
    /// Inputs held at a level from outside the axis model (`virtual-drive --input`).
    pub inputs: crate::sim_inputs::ForcedInputs,
    /// The boot flash and ESC of the firmware update, when attached.
    boot: Option<(&'static crate::sim_update::SharedFlash, Flavour)>,
    /// What the bootloader did at this start.
    boot_state: Option<Result<embassy_boot::State, String>>,
}

/// What the simulated control path keeps between calls (the board's exchange
/// sequence numbers and latches).
#[derive(Debug, Clone, Copy, Default)]
struct PathState {
    /// Publications of the axis's measurements ([`Feedback`] sequence number).
    fb_seq: u32,
    /// Index pulses the axis has reported (`Feedback::index_seq`) and the last one.
    index_seq: u32,
    index_units: i32,
    /// The command's segment number the axis has taken the set-points of.
    seen_cycle: u32,
    /// The last command's auto-tune permission.
    tune_allowed: bool,
    /// The axis reports a tripped power stage (the board's break latch).
    tripped: bool,
    /// The last command switches the model's bridges on.
    powered: bool,
    /// The last command's brake decision and the brake pin, driven as the board's
    /// current-loop interrupt drives it (`firmware::power_gate::BrakeOut`).
    brake_wanted: bool,
    brake: firmware::power_gate::BrakeOut,
}

impl PathState {
    /// The model's bridges are on; the brake pin follows them at once.
    fn bridges(&mut self) -> bool {
        let on = self.powered && !self.tripped;
        self.brake.update(self.brake_wanted, on);
        on
    }
}

/// The axis as the runtime's [`ControlPath`] (what `hw::control::BoardPath` is on
/// the board).
struct SimPath<'a> {
    axis: &'a mut dyn Axis,
    st: &'a mut PathState,
}

impl ControlPath for SimPath<'_> {
    fn feedback(&mut self) -> Option<(u32, Feedback)> {
        let axis = self.axis.state();
        let st = &mut *self.st;
        if let Some(u) = axis.index {
            st.index_seq = st.index_seq.wrapping_add(1);
            st.index_units = u;
        }
        st.tripped = axis.overcurrent_trip;
        let bridges_on = st.bridges();
        let current = self.axis.current_control(st.tune_allowed);
        st.fb_seq = st.fb_seq.wrapping_add(1).max(1);
        Some((
            st.fb_seq,
            Feedback {
                axis,
                index_seq: st.index_seq,
                index_units: st.index_units,
                align_failures: self.axis.commutation_failures(),
                current,
                // The model's bridges follow the command at once.
                bridges_on,
                ..Feedback::default()
            },
        ))
    }
    fn break_latched(&self) -> bool {
        self.st.tripped
    }
    fn bridges_on_now(&self) -> bool {
        self.st.powered && !self.st.tripped
    }
    fn send(&mut self, c: &ControlCommand) {
        self.st.tune_allowed = c.tune_allowed;
        self.st.powered = c.permits_power() && c.command.power_stage;
        self.st.brake_wanted = c.brake_released;
        self.st.bridges();
        if c.cycle != self.st.seen_cycle {
            self.st.seen_cycle = c.cycle;
            self.axis.command(&c.command, f64::from(c.cycle_s));
        }
    }
    fn rearm_break(&mut self) -> bool {
        // The model's trip is its condition: re-armed once the model no longer
        // reports it.
        self.st.tripped = self.axis.state().overcurrent_trip;
        self.st.bridges();
        !self.st.tripped
    }
    fn drain_trace(&mut self, wanted: bool, sink: &mut dyn FnMut(&firmware::scope::ServoPoint)) {
        let mut points = Vec::new();
        self.axis.servo_points(wanted, &mut points);
        for p in &points {
            sink(p);
        }
    }
    fn parameters(&mut self, params: &firmware::params::Params) {
        self.axis.parameters(params);
    }
}

impl SimDrive {
    /// A drive with parameter flash `flash` and motor side `axis`.
    pub fn new(serial: u32, flash: FileFlash, axis: Box<dyn Axis>) -> Self {
        let store = FlashStore {
            storage: region::PARAMS,
            history: Some(region::HISTORY),
            flash,
        };
        let drive = Drive::with_store(Variant::HybridServo, serial, store);
        let rt = Runtime::new(SIM_BOARD, &drive);
        let mut d = SimDrive {
            drive,
            axis,
            rt,
            path: PathState::default(),
            axis_us: 0,
            tick_us: 0,
            dips: DIPS_ALL_ON,
            esm: None,
            poll_errors_seen: 0,
            serial,
            inputs: Default::default(),
            boot: None,
            boot_state: None,
        };
        // The simulated current sensors have no start-up check: passed at nominal.
        let (drive, rt, mut path) = d.parts();
        rt.offsets_checked(drive, &mut path, Some((0.0, 0.0)));
        d
    }

    /// The drive, the runtime and the axis as the runtime's control path.
    fn parts(&mut self) -> (&mut Drive<SimStore>, &mut Runtime, SimPath<'_>) {
        (
            &mut self.drive,
            &mut self.rt,
            SimPath {
                axis: &mut *self.axis,
                st: &mut self.path,
            },
        )
    }

    /// Gives the drive its firmware update over the boot flash `shared` (see
    /// [`crate::sim_update`]): the bootloader runs first, as at a power-up.
    pub fn attach_update(&mut self, shared: &'static crate::sim_update::SharedFlash, esc: Flavour) {
        let (update, state) = crate::sim_update::boot(
            shared,
            identity::VENDOR_ID,
            Variant::HybridServo.product_code(),
            match esc {
                Flavour::Lan9252 => efw::Esc::Lan9252,
                Flavour::Et1100 => efw::Esc::Et1100,
            },
        );
        self.drive.attach_update(Box::leak(Box::new(update)));
        self.boot = Some((shared, esc));
        self.boot_state = Some(state);
    }

    /// What the bootloader did at this start (`None`: no update attached).
    pub fn boot_state(&self) -> Option<&Result<embassy_boot::State, String>> {
        self.boot_state.as_ref()
    }

    /// A reset of the drive's processor (after an accepted update, as the board does
    /// on Bootstrap → Init): a new drive over the same parameter flash, boot flash
    /// (the bootloader swaps or reverts first), motor and switches. Call
    /// [`restart_requested`] rather, which also restarts the slave runtime.
    fn reset(&mut self) {
        let flash = self
            .drive
            .store_mut()
            .map(|s| std::mem::replace(&mut s.flash, FileFlash::in_memory()))
            .unwrap_or_else(FileFlash::in_memory);
        let parked =
            crate::sim_axis::boxed_model(Motor::Ecn57_20, crate::sim_axis::AxisModel::Kinematic, 1);
        let axis = std::mem::replace(&mut self.axis, parked);
        let (boot, dips, inputs) = (self.boot, self.dips, std::mem::take(&mut self.inputs));
        *self = SimDrive::new(self.serial, flash, axis);
        (self.dips, self.inputs) = (dips, inputs);
        if let Some((shared, esc)) = boot {
            self.attach_update(shared, esc);
        }
    }

    /// Power-up through the runtime (as the board's start-up): stored parameters and
    /// PDO mapping through `runtime_objects`, the DIP banks, the alias; returns the
    /// alias for the ESC (`None`: keep SII word 4's).
    pub fn power_up(&mut self, runtime_objects: &mut dyn Dictionary) -> Option<u16> {
        let dips = self.dips;
        let up = self.rt.power_up(&mut self.drive, dips, runtime_objects);
        self.axis.parameters(&self.drive.params);
        up.alias
    }

    /// The ESM as the LEDs show it, seen by the segment (kept until the next one).
    pub fn set_esm(&mut self, esm: EsmView) {
        self.esm = Some(esm);
    }

    /// The board's pins: the levels the last tick drove (outputs, LEDs) and the brake
    /// pin as the control path drives it.
    pub fn pins(&self) -> firmware::runtime::Pins {
        firmware::runtime::Pins {
            brake_released: self.path.brake.released(),
            ..self.rt.pins()
        }
    }

    /// The model's bridges are on (the last command permits the power stage and no
    /// trip is latched): what `Feedback::bridges_on` reports.
    pub fn bridges_on(&self) -> bool {
        self.path.powered && !self.path.tripped
    }

    /// True when a 1 ms tick is due by `now_us` (what [`SimDrive::catch_up`] would run).
    pub fn tick_due(&self, now_us: u64) -> bool {
        self.tick_us + 1000 <= now_us
    }

    /// Brings the axis and the 1 ms housekeeping up to `now_us`, in time order as on
    /// the board: the axis moves to each tick due, under the command of the step
    /// before it, and the tick runs there (however late this is called); then the
    /// axis moves on to `now_us`.
    pub fn catch_up(&mut self, now_us: u64) {
        while self.tick_us + 1000 <= now_us {
            self.tick_us += 1000;
            let t = self.tick_us;
            self.advance_axis(t);
            // The board's `tick` task: the runtime's tick with the raw inputs.
            let (raw, esm) = (self.inputs.apply(self.axis.raw_inputs(), t), self.esm);
            let dip_bits = self.dips.function;
            let (drive, rt, mut path) = self.parts();
            rt.tick(drive, &mut path, t, raw, dip_bits, esm);
        }
        self.advance_axis(now_us);
    }

    /// The axis model moved on to `t_us` under the last step's command.
    fn advance_axis(&mut self, t_us: u64) {
        if t_us > self.axis_us {
            let dt = (t_us - self.axis_us) as f64 * 1e-6;
            let cmd = self.rt.command().command;
            self.axis.advance(dt, &cmd);
            self.axis_us = t_us;
        }
    }

    /// The board's `ecat` task around a mailbox poll: emergencies before (`send`),
    /// then the command, the update confirmation and whether a reset is due.
    fn mailbox_work(&mut self, send: &mut dyn FnMut(firmware::faults::Emergency), poll_ok: bool) {
        self.rt.before_poll(&mut self.drive, send);
        let now = self.tick_us;
        let (drive, rt, mut path) = self.parts();
        rt.after_poll(drive, &mut path, poll_ok, now);
        if let Some(Err(e)) = self.drive.persist_history() {
            eprintln!("simulated drive: fault history not written: {e:?}");
        }
    }
}

impl Dictionary for SimDrive {
    fn objects(&self) -> &'static [Object] {
        self.drive.objects()
    }
    fn read(&mut self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        self.drive.read(key, buf)
    }
    fn write(&mut self, key: ObjectKey, data: &[u8], state: EsmState) -> Result<(), SdoAbort> {
        self.drive.write(key, data, state)?;
        self.axis.parameters(&self.drive.params);
        Ok(())
    }
    fn write_with_runtime(
        &mut self,
        key: ObjectKey,
        data: &[u8],
        state: EsmState,
        runtime: &mut dyn Dictionary,
    ) -> Result<(), SdoAbort> {
        self.drive.write_with_runtime(key, data, state, runtime)?;
        self.axis.parameters(&self.drive.params);
        Ok(())
    }
}

impl ProcessData for SimDrive {
    fn rx_slot(&self, key: ObjectKey) -> Option<u16> {
        self.drive.rx_slot(key)
    }
    fn tx_slot(&self, key: ObjectKey) -> Option<u16> {
        self.drive.tx_slot(key)
    }
    fn set_rx(&mut self, slot: u16, raw: u64) {
        self.drive.set_rx(slot, raw)
    }
    fn get_tx(&self, slot: u16) -> u64 {
        self.drive.get_tx(slot)
    }
}

impl EsmHooks for SimDrive {
    fn on_state_change(&mut self, from: EsmState, to: EsmState) {
        self.drive.on_state_change(from, to)
    }
    fn on_enter_bootstrap(&mut self) {
        self.drive.on_enter_bootstrap()
    }
    fn on_leave_bootstrap(&mut self) {
        self.drive.on_leave_bootstrap()
    }
}

impl SlaveApplication for SimDrive {
    fn cycle(&mut self, info: &CycleInfo) {
        // The board's `cyclic` task: measurements in, the drive's cycle, command out.
        self.catch_up(info.now_us);
        let (drive, rt, mut path) = self.parts();
        rt.before_step(drive, &mut path);
        drive.cycle(info);
        rt.after_step(drive, &mut path);
    }
    fn on_outputs_lost(&mut self, code: AlStatusCode) {
        self.drive.on_outputs_lost(code)
    }
    fn sync_error_limit(&self) -> u16 {
        self.drive.sync_error_limit()
    }
    fn foe(&mut self) -> Option<&mut dyn ecat_slave_stack::foe::FoeFiles> {
        self.drive.foe()
    }
}

/// The ESC flavour of the SII for a simulator flavour.
pub fn esc_flavour(f: Flavour) -> EscFlavour {
    match f {
        Flavour::Lan9252 => EscFlavour::Lan9252,
        Flavour::Et1100 => EscFlavour::Et1100,
    }
}

/// The runtime configuration of the product.
pub fn slave_config() -> SlaveConfig {
    firmware::identity::slave_config()
}

/// The axis model used for `motor` (see [`crate::sim_axis`]).
pub fn make_axis(motor: Motor) -> Box<dyn Axis> {
    crate::sim_axis::boxed(motor)
}

/// A powered-up segment of `n` simulated drives: SII from the product identity, the
/// product's default PDO maps, parameters loaded from each drive's flash. The axes
/// follow [`AxisModel::Auto`]: the electrical plant ([`crate::sim_axis::PlantAxis`])
/// for up to [`crate::sim_axis::PLANT_MAX_DRIVES`] drives, the kinematic model beyond.
pub fn segment(cfg: &SimDriveConfig, n: usize) -> Result<Segment<SimDrive>, String> {
    segment_with(cfg, n, AxisModel::Auto)
}

/// [`segment`] with an explicit axis model.
pub fn segment_with(
    cfg: &SimDriveConfig,
    n: usize,
    model: AxisModel,
) -> Result<Segment<SimDrive>, String> {
    let desc = identity::device_description(Variant::HybridServo, esc_flavour(cfg.flavour), 0);
    let sii = crate::segment::sii_image_with_pdos(
        &desc,
        firmware::dictionary::OBJECTS,
        &firmware::pdo_defaults::PDO_DEFAULTS,
    )
    .map_err(|e| format!("SII image: {e:?}"))?;
    let apps: Vec<SimDrive> = (0..n)
        .map(|i| {
            let flash = match &cfg.flash_file {
                Some(p) if i == 0 => FileFlash::open(p.clone()),
                Some(p) => FileFlash::open(PathBuf::from(format!("{}.{}", p.display(), i + 1))),
                None => FileFlash::in_memory(),
            };
            let axis = crate::sim_axis::boxed_model(cfg.motor, model, n);
            let mut d = SimDrive::new(0x1000 + i as u32, flash, axis);
            d.dips = cfg.dips;
            if let Some(p) = &cfg.flash_file {
                let file = if i == 0 {
                    p.clone()
                } else {
                    PathBuf::from(format!("{}.{}", p.display(), i + 1))
                };
                let shared = crate::sim_update::share(crate::sim_update::boot_flash(Some(
                    crate::sim_update::boot_file(&file),
                )));
                d.attach_update(shared, cfg.flavour);
            }
            d
        })
        .collect();
    let mut seg = Segment::new(
        SegmentConfig::new(cfg.flavour),
        &sii,
        apps,
        slave_config(),
        None,
    )
    .map_err(|e| format!("ESC start-up: {e:?}"))?;
    power_up_drives(&mut seg);
    forward_emergencies(&mut seg);
    Ok(seg)
}

/// Gives every drive of the segment a firmware update over a boot flash in memory
/// (the drives of [`segment`] with a flash file have one in the file already).
pub fn attach_updates_in_memory(seg: &mut Segment<SimDrive>, flavour: Flavour) {
    for d in seg.drives_mut() {
        if d.app.boot.is_none() {
            let shared = crate::sim_update::share(crate::sim_update::boot_flash(None));
            d.app.attach_update(shared, flavour);
        }
    }
}

/// Restarts every drive that asks for a reset (an update accepted, Bootstrap →
/// Init): the processor's reset ([`SimDrive`]'s bootloader and power-up), the slave
/// runtime's start (AL status Init). Returns the drives restarted.
pub fn restart_requested(seg: &mut Segment<SimDrive>) -> Vec<usize> {
    let due: Vec<usize> = (0..seg.len())
        .filter(|&i| seg.drive(i).app.drive.reset_requested())
        .collect();
    for &i in &due {
        restart(seg, i);
    }
    due
}

/// Resets drive `i`'s processor now (a power cycle of the drive's logic, a watchdog
/// reset): the bootloader runs, the drive powers up, the slave runtime starts in Init.
pub fn restart(seg: &mut Segment<SimDrive>, i: usize) {
    let d = seg.drive_mut(i);
    d.app.reset();
    power_up_one(d, i);
}

/// One drive's power-up (the board's start-up order): parameters, DIP banks and
/// alias through the runtime, then the slave runtime's start with that alias.
fn power_up_one(d: &mut crate::segment::Drive<SimDrive>, i: usize) {
    let mut runtime = d.slave.runtime_objects(firmware::dictionary::OBJECTS);
    let alias = d.app.power_up(&mut runtime);
    d.slave.set_station_alias(alias);
    if let Err(e) = d.slave.init() {
        eprintln!("simulated drive {}: ESC start-up: {e:?}", i + 1);
    }
}

/// Every drive's power-up: the stored parameters (and PDO mapping) loaded through its
/// slave runtime, then the axis model set from the parameters.
pub fn power_up_drives(seg: &mut Segment<SimDrive>) {
    for (i, d) in seg.drives_mut().iter_mut().enumerate() {
        power_up_one(d, i);
    }
}

/// Sends every drive's pending emergencies through its mailbox, writes a changed
/// fault history to the drive's flash ([`Drive::persist_history`]) and lets a new
/// image on trial confirm itself ([`Drive::confirm_update`]): the board's `ecat` task
/// does these after each `poll`, in thread mode, outside the fault path.
pub fn forward_emergencies(seg: &mut Segment<SimDrive>) {
    forward_emergencies_where(seg, |_| true);
}

/// [`forward_emergencies`] for the drives (positions) `which` selects (the board's
/// `ecat` task does this work around each of its polls: `crate::realtime::step` does
/// it for the drives it polled).
pub fn forward_emergencies_where(seg: &mut Segment<SimDrive>, which: impl Fn(usize) -> bool) {
    let drives = seg.drives_mut().iter_mut().enumerate();
    for (_, d) in drives.filter(|(i, _)| which(*i)) {
        let slave = &mut d.slave;
        // The segment's polls count their ESC errors (`Drive::poll_errors`).
        let ok = d.poll_errors == d.app.poll_errors_seen;
        d.app.poll_errors_seen = d.poll_errors;
        d.app
            .mailbox_work(&mut |e| slave.emergency(e.code, e.register, e.data), ok);
        let esm = slave.esm();
        d.app.set_esm(EsmView::from_al_status(
            slave.state(),
            esm.status_word(),
            esm.code(),
        ));
    }
}

/// Advances the segment by `dt_ns` of simulated time (in ≤ 100 µs steps so the
/// housekeeping and axis stay close to the ESC time).
pub fn advance(seg: &mut Segment<SimDrive>, dt_ns: u64) {
    let mut left = dt_ns;
    while left > 0 {
        let step = left.min(100_000);
        seg.advance(step);
        let now_us = seg.now_ns() / 1000;
        for d in seg.drives_mut() {
            d.app.catch_up(now_us);
        }
        forward_emergencies(seg);
        left -= step;
    }
}

/// Frame in → frame out through the segment.
pub fn process(seg: &mut Segment<SimDrive>, frame: &mut [u8]) -> FrameOutcome {
    let out = seg.process(frame);
    forward_emergencies(seg);
    out
}

/// Orderly stop: disables every drive's power stage (nothing else to flush: the
/// parameter flash is written through on every change).
pub fn shutdown(seg: &mut Segment<SimDrive>) {
    for d in seg.drives_mut() {
        d.app.axis.advance(0.0, &DriveCommand::default());
    }
}

/// A runtime dictionary without objects: for tests that power up a [`SimDrive`]'s
/// drive without the slave runtime's PDO objects (`Drive::power_up(&mut NoRuntime)`).
pub struct NoRuntime;

impl Dictionary for NoRuntime {
    fn objects(&self) -> &'static [Object] {
        &[]
    }
    fn read(&mut self, _: ObjectKey, _: &mut [u8]) -> Result<usize, SdoAbort> {
        Err(SdoAbort::ObjectDoesNotExist)
    }
    fn write(&mut self, _: ObjectKey, _: &[u8], _: EsmState) -> Result<(), SdoAbort> {
        Err(SdoAbort::ObjectDoesNotExist)
    }
}
