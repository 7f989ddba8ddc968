//! The servo tune on the drive's side (0x2162-0x2165, [`crate::servo_tune`]): the
//! start and stop commands, the hand-over of the set-points to the motion layer's
//! move (`Cia402::set_servo_tune`), and the result into the parameters.

use super::*;
use crate::cia402::pds::PdsState;
use crate::servo_tune::{StartConditions, TuneState};

/// CiA 402 modes in which a tune may start: profile position and cyclic synchronous
/// position (0x6061).
const TUNE_MODES: [i8; 2] = [1, 8];

impl<S: ParameterStore> Drive<S> {
    /// 0x2162:01 written: `start` (1) checks the conditions ([`StartConditions`]) and
    /// hands the set-points to the move; 0 stops a running tune.
    pub(super) fn servo_tune_command(&mut self, start: bool) -> Result<(), SdoAbort> {
        if !start {
            self.servo_tune.stop();
            self.servo_tune_publish(None);
            return Ok(());
        }
        let ppr = match self.params.active().pulses_per_rev {
            0 => self.params.get(Param::PulsesPerRev),
            n => n as i32,
        }
        .max(1) as u32;
        let tenths = self.params.get(Param::TuneTravel).max(0) as u64;
        let travel = (tenths * u64::from(ppr) / 3600).min(u64::from(u32::MAX)) as u32;
        let c = StartConditions {
            closed_loop: self.variant.has_encoder() && self.params.get(Param::LoopMode) == 2,
            operation_enabled: self.cia402.state() == PdsState::OperationEnabled
                && TUNE_MODES.contains(&self.cia402.mode_display())
                && self.cia402.controlword() & 0x100 == 0,
            velocity: self.cia402.velocity_demand() as f32,
            units_per_rev: ppr,
            position: self.axis.position,
            travel,
            limits: self.cia402.raw_position_limits(),
            limit_switch: self.inputs.digital_inputs_60fd()
                & (crate::cia402::homing::DI_POS_LIMIT | crate::cia402::homing::DI_NEG_LIMIT)
                != 0,
        };
        let r = self.servo_tune.start(&c, &self.axis.servo_tune);
        self.servo_tune_publish(None);
        r
    }

    /// Once per tick: follows the motion layer's run (the axis state) and the CiA 402
    /// layer; a finished run's inertia ratio and the stiffness's gains go to the
    /// parameters ([`crate::servo_tune::apply`]; not saved), and 0x2164 / 0x2165 show
    /// the result.
    pub(super) fn servo_tune_tick(&mut self, dt_ms: u32) {
        if !self.servo_tune.running() {
            return;
        }
        let done = self
            .servo_tune
            .update(&self.axis.servo_tune, self.cia402.servo_tune(), dt_ms);
        if let Some(r) = done {
            crate::servo_tune::apply(&mut self.params, f32::from(r.ratio_percent));
            self.faults.configure_from(&self.params);
            self.cia402.end_servo_tune_at_rest();
        }
        self.servo_tune_publish(done.map(|r| (r.ratio_percent, r.friction_mnm)));
    }

    /// The tune's state to the CiA 402 layer and to 0x2162:02 (with a `result`, to
    /// 0x2164 / 0x2165).
    fn servo_tune_publish(&mut self, result: Option<(u16, u16)>) {
        let state = self.servo_tune.state();
        self.cia402.set_servo_tune(state == TuneState::Running);
        self.params.set_servo_tune(state as u8, result);
    }
}
