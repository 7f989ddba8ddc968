//! The drive application: everything between the EtherCAT slave runtime and the
//! motor-control loops.
//!
//! [`Drive`] owns the values of the product dictionary (communication objects,
//! vendor parameters, fault history, monitoring, CiA 402) and implements the slave
//! runtime's [`SlaveApplication`]: the dictionary ([`Dictionary`]), the cyclic data
//! ([`ProcessData`]), the ESM hooks (CiA 402 coupling) and the application cycle.
//!
//! Data flow of one cycle (called by the runtime between unpacking the outputs and
//! packing the inputs):
//!
//! ```text
//! board / simulator ──set_axis(AxisState)──▶ Drive ──▶ faults, I/O functions
//!                                              │
//!                                      Cia402::cycle (PDS, modes, homing, probe)
//!                                              │
//! board / simulator ◀──command()── DriveCommand (position/velocity set-point, power)
//! ```
//!
//! Slow work (input filtering, LED timing, monitoring, fault reactions that do not
//! need the cycle) runs in [`Drive::tick`], called every millisecond by the main loop.
//! Emergencies produced by faults are collected here and forwarded by the owner to
//! the mailbox with [`Drive::pop_emergency`].

use ecat_slave_stack::al_status::AlStatusCode;
use ecat_slave_stack::esm::{EsmHooks, EsmState};
use ecat_slave_stack::od::{self, Dictionary, Object, SdoAbort};
use ecat_slave_stack::pdo::ProcessData;
use ecat_slave_stack::slave::{CycleInfo, SlaveApplication};

use crate::cia402::{Cia402, DriveCommand, DriveFeedback};
use crate::comm::{Comm, StoreCommand};
use crate::dictionary;
use crate::fault_led;
use crate::faults::{Emergency, FaultKind, Faults, Snapshot};
use crate::identity::{Identity, Variant};
use crate::io::{self, Inputs, OutputStatus};
use crate::monitor::Monitor;
use crate::params::{Params, P};

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
    /// The power stage tripped (hardware over-current / break input).
    pub overcurrent_trip: bool,
    /// The servo is at its current limit.
    pub current_limited: bool,
    /// Following error between servo demand and encoder, command units (closed loop).
    pub servo_following_error: i32,
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
pub struct Drive {
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
    last_cycle_us: Option<u64>,
    now_ms: u32,
    pending_store: Option<StoreCommand>,
    fault_led: fault_led::FaultLed,
    last_controlword: u16,
}

/// Error code reported when the outputs stopped arriving (process-data watchdog,
/// sync loss) while the drive was enabled.
pub const ERR_COMMUNICATION_LOST: u16 = 0x8700;

impl Drive {
    /// A drive at power-up defaults (before the stored parameters are loaded);
    /// `serial` is 0x1018:04.
    pub fn new(variant: Variant, serial: u32) -> Self {
        let params = Params::new(variant);
        let mut d = Drive {
            variant,
            comm: Comm::new(Identity::new(variant, serial)),
            cia402: Cia402::new(),
            faults: Faults::default(),
            monitor: Monitor::new(),
            inputs: Inputs::default(),
            axis: AxisState::default(),
            command: DriveCommand::default(),
            esm: EsmState::Init,
            last_cycle_us: None,
            now_ms: 0,
            pending_store: None,
            fault_led: fault_led::FaultLed::new(),
            last_controlword: 0,
            params,
        };
        d.apply_parameters();
        d
    }

    /// Applies the parameters that configure the other modules (call at power-up after
    /// loading the stored record, and after parameter changes that take effect at once).
    pub fn apply_parameters(&mut self) {
        self.faults.configure_from(&self.params);
        let active = self.params.active();
        let encoder_counts = if self.variant.has_encoder() {
            (self.params.get(P::EncoderResolution) as u32).saturating_mul(4)
        } else {
            0
        };
        self.cia402
            .set_resolution(encoder_counts, active.pulses_per_rev);
        self.cia402.set_has_index(self.variant.has_encoder());
        self.cia402
            .set_rated_current_ma(self.params.get(P::PeakCurrent) as u32);
    }

    /// Call once at power-up after the stored record was loaded: latches the
    /// "effective after restart" parameters and counts the power-up.
    pub fn power_up(&mut self) {
        self.params.latch_power_up();
        self.monitor.power_up();
        self.apply_parameters();
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

    /// ESM state last reported by the runtime.
    pub fn esm_state(&self) -> EsmState {
        self.esm
    }

    /// A store/restore command (0x1010/0x1011) accepted by SDO and not yet executed.
    pub fn take_store_request(&mut self) -> Option<StoreCommand> {
        self.pending_store.take()
    }

    /// Next emergency to send (fault occurrences, fault reset).
    pub fn pop_emergency(&mut self) -> Option<Emergency> {
        self.faults.pop_emergency()
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

    /// Slow housekeeping, every `dt_ms` (1 ms on the board): input filter and
    /// functions, protections from measured values, fault reset by input, monitoring,
    /// LEDs. `raw_inputs`: bit n = level of IN n+1.
    pub fn tick(&mut self, dt_ms: u32, raw_inputs: u8) {
        self.now_ms = self.now_ms.wrapping_add(dt_ms);
        self.monitor.tick_ms(dt_ms);
        self.inputs
            .update(raw_inputs, dt_ms.saturating_mul(1000), &self.params);
        self.params.set_raw_inputs(self.inputs.raw());
        let snap = self.snapshot();
        let now = self.now_ms;
        if self.axis.bus_mv > 0 {
            self.faults.check_bus_voltage(self.axis.bus_mv, snap, now);
        }
        if self.axis.overcurrent_trip {
            self.faults.raise(FaultKind::OverCurrent, snap, now);
        }
        if self.inputs.fault_clear_edge() {
            self.faults.fault_reset();
        }
        if self.params.take_fault_history_clear() {
            self.faults.clear_history();
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

    /// Runs one application cycle with the latest axis state (also used directly by
    /// tests and by the board's SYNC0 path through the runtime).
    pub fn run_cycle(&mut self, dt: f32) -> DriveCommand {
        // Fault reset (controlword bit 7 rising edge) clears the protections first, so
        // the PDS sees no active fault and accepts the reset; latched faults stay.
        let cw = self.cia402.controlword();
        if cw & 0x80 != 0 && self.last_controlword & 0x80 == 0 {
            self.faults.fault_reset();
        }
        self.last_controlword = cw;
        let fb = DriveFeedback {
            position: self.axis.position,
            velocity: self.axis.velocity,
            torque: self.axis.current_permille,
            current: self.axis.current_permille,
            digital_inputs: self.inputs.digital_inputs_60fd(),
            index: self.axis.index,
            fault: self.faults.error_code(),
            power_stage_tripped: self.faults.is_active(FaultKind::OverCurrent),
            warning: false,
            current_limited: self.axis.current_limited,
            quick_stop_input: self.inputs.quick_stop(),
            ..DriveFeedback::default()
        };
        self.command = self.cia402.cycle(&fb, dt);
        // Following-error supervision of the closed loop (0x2030, encoder counts).
        if self.command.drive_enabled
            && self.variant.has_encoder()
            && self.params.get(P::LoopMode) == 2
        {
            let snap = self.snapshot();
            self.faults.check_following_error(
                self.axis.servo_following_error,
                self.params.get(P::FollowingErrorLimit) as u16,
                snap,
                self.now_ms,
            );
        }
        // A fault reset accepted by the PDS (controlword bit 7) clears the faults.
        if self.faults.take_pds_fault_request() {
            self.cia402.raise_fault(self.faults.error_code());
        }
        self.command
    }
}

impl Dictionary for Drive {
    fn objects(&self) -> &'static [Object] {
        dictionary::OBJECTS
    }

    fn read(&mut self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        match index {
            0x1000..=0x10FF => self.comm.read(&self.faults, index, sub, buf),
            0x2000..=0x21FF => self.params.read(index, sub, buf),
            0x2300..=0x23FF => self.monitor.read(index, sub, buf),
            0x2400..=0x24FF => self.faults.read(index, sub, buf),
            0x6000..=0x6FFF => self.cia402.read(index, sub, buf),
            _ => Err(SdoAbort::ObjectDoesNotExist),
        }
    }

    fn write(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
        _state: EsmState,
    ) -> Result<(), SdoAbort> {
        match index {
            0x1000..=0x10FF => {
                if let Some(cmd) = self.comm.write(&mut self.faults, index, sub, data)? {
                    self.pending_store = Some(cmd);
                }
                Ok(())
            }
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
            o.entries
                .iter()
                .filter(|e| e.pdo.tx())
                .map(move |e| (o.index, e.sub))
        })
        .take(OTHER_TX_MAX)
}

impl ProcessData for Drive {
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
        let Some((index, sub)) = other_tx_entries().nth(usize::from(slot - OTHER_TX_SLOT)) else {
            return 0;
        };
        let mut buf = [0u8; 8];
        let n = match index {
            0x1000..=0x10FF => self.comm.read(&self.faults, index, sub, &mut buf),
            0x2000..=0x21FF => self.params.read(index, sub, &mut buf),
            0x2300..=0x23FF => self.monitor.read(index, sub, &mut buf),
            0x2400..=0x24FF => self.faults.read(index, sub, &mut buf),
            _ => Err(SdoAbort::ObjectDoesNotExist),
        };
        match n {
            Ok(_) => u64::from_le_bytes(buf),
            Err(_) => 0,
        }
    }
}

impl EsmHooks for Drive {
    fn on_state_change(&mut self, from: EsmState, to: EsmState) {
        self.esm = to;
        if from == EsmState::Op && to != EsmState::Op && self.command.drive_enabled {
            // Leaving Op while enabled: the PDS goes to Fault and the motor follows the
            // fault reaction (drive-requirements §2.1); a PDS change never moves the ESM.
            self.cia402.on_esm_left_op_while_enabled();
            let code = if to == EsmState::Init { 0xA000 } else { 0xA001 };
            self.faults
                .raise_ecat(code, [from.bits(), to.bits()], self.now_ms);
            // An event, not a lasting condition: a fault reset may clear it.
            self.faults.condition_gone(FaultKind::Ecat);
        }
        if to == EsmState::Init {
            self.cia402.on_esm_init();
        }
    }
}

impl SlaveApplication for Drive {
    fn cycle(&mut self, info: &CycleInfo) {
        let dt = match self.last_cycle_us {
            Some(prev) if info.now_us > prev => {
                ((info.now_us - prev) as f32 * 1e-6).clamp(62.5e-6, 0.01)
            }
            _ => self
                .cia402
                .params
                .interpolation_period_s()
                .clamp(62.5e-6, 0.01),
        };
        self.last_cycle_us = Some(info.now_us);
        if info.state == EsmState::Op && !info.outputs_fresh && self.command.drive_enabled {
            // No fresh outputs in Op: keep the last set-points (SM-synchronous cycles
            // without a frame) — the watchdog catches a stopped master.
        }
        self.run_cycle(dt);
    }

    fn on_outputs_lost(&mut self, code: AlStatusCode) {
        if self.command.drive_enabled {
            self.cia402.on_esm_left_op_while_enabled();
            self.faults.raise_ecat(
                ERR_COMMUNICATION_LOST,
                code.code().to_le_bytes(),
                self.now_ms,
            );
            self.faults.condition_gone(FaultKind::Ecat);
        }
    }

    fn sync_error_limit(&self) -> u16 {
        self.comm.sync_error_limit()
    }
}

/// True when `index` is stored by 'save' somewhere in the dictionary (for tests and
/// the storage layout documentation).
pub fn is_saved(index: u16, sub: u8) -> bool {
    od::find_entry(dictionary::OBJECTS, index, sub).is_ok_and(|e| e.saved)
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
    fn save_command_is_queued_for_the_owner() {
        let mut d = Drive::new(Variant::HybridServo, 0);
        sdo_write(&mut d, 0x1010, 1, &crate::comm::SAVE.to_le_bytes()).expect("save");
        assert!(matches!(
            d.take_store_request(),
            Some(StoreCommand::Save(_))
        ));
        assert_eq!(
            sdo_write(&mut d, 0x1010, 1, &0x1234_5678u32.to_le_bytes()),
            Err(SdoAbort::DataCannotBeStored)
        );
        assert!(d.take_store_request().is_none());
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
    fn over_voltage_faults_latch_and_light_the_red_led() {
        let mut d = Drive::new(Variant::HybridServo, 0);
        enable(&mut d);
        d.set_axis(AxisState {
            bus_mv: 60_000,
            ..AxisState::default()
        });
        d.tick(1, 0);
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
}
