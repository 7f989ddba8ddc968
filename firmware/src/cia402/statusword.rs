//! The statusword 0x6041 of a step.

use super::*;

impl Cia402 {
    pub(super) fn build_statusword(&self, fb: &DriveFeedback) -> Statusword {
        let st = self.state;
        let s = Statusword::of_state(st);
        if st == PdsState::NotReadyToSwitchOn {
            return s;
        }
        let p = &self.params;
        let param_zero = match self.mode {
            OperationMode::Pp => {
                p.profile_velocity == 0
                    || p.profile_acceleration == 0
                    || p.profile_deceleration == 0
            }
            OperationMode::Pv => p.profile_acceleration == 0 || p.profile_deceleration == 0,
            _ => false,
        };
        let s = s
            .with(sw::REMOTE, true)
            .with(sw::VOLTAGE_ENABLED, st.voltage_enabled())
            .with(sw::WARNING, fb.warning)
            .with(sw::INTERNAL_LIMIT, self.internal_limit)
            .with(sw::ABNORMAL_STOP, self.abnormal_stop)
            .with(sw::PARAM_ZERO, param_zero);
        match st {
            PdsState::OperationEnabled => self.mode_bits(s),
            PdsState::QuickStopActive => s.with(
                sw::TARGET_REACHED,
                self.target_reached && self.motion.velocity() == 0.0,
            ),
            _ => s,
        }
    }

    /// The mode-specific bits (10, 12, 13, 15) in Operation enabled; none without a
    /// mode.
    fn mode_bits(&self, s: Statusword) -> Statusword {
        let at_rest = || self.motion.velocity() == 0.0;
        match self.mode {
            OperationMode::Pp => s
                .with(sw::TARGET_REACHED, self.target_reached)
                .with(sw::SETPOINT_ACKNOWLEDGE, self.pp.ack)
                .with(sw::SETPOINT_FREE, !self.pp.ack)
                .with(sw::FOLLOWING_ERROR, self.fe_flag),
            OperationMode::Pv => s.with(sw::TARGET_REACHED, self.target_reached).with(
                sw::SPEED_ZERO,
                self.actual_velocity.unsigned_abs() <= self.params.velocity_threshold as u32,
            ),
            OperationMode::Hm => match self.hm.status() {
                HomingStatus::Idle => s.with(sw::TARGET_REACHED, at_rest()),
                HomingStatus::InProgress => s,
                HomingStatus::Attained => s
                    .with(sw::HOMING_ATTAINED, true)
                    .with(sw::TARGET_REACHED, self.target_reached),
                HomingStatus::Error => s
                    .with(sw::HOMING_ERROR, true)
                    .with(sw::TARGET_REACHED, at_rest()),
            },
            OperationMode::Pt => s.with(sw::TARGET_REACHED, self.target_reached),
            OperationMode::Csp | OperationMode::Csv | OperationMode::Cst => s
                .with(
                    sw::DRIVE_FOLLOWS,
                    !self.halted && !self.abnormal_stop && self.pending == Pending::None,
                )
                .with(
                    sw::FOLLOWING_ERROR,
                    self.mode == OperationMode::Csp && self.fe_flag,
                ),
            OperationMode::None => s,
        }
    }
}
