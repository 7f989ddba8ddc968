//! The statusword 0x6041 of a step.

use super::*;

impl Cia402 {
    pub(super) fn build_statusword(&self, fb: &DriveFeedback) -> u16 {
        let st = self.state;
        let mut s = st.statusword_bits();
        if st == PdsState::NotReadyToSwitchOn {
            return s;
        }
        s |= sw::REMOTE;
        if st.voltage_enabled() {
            s |= sw::VOLTAGE_ENABLED;
        }
        if fb.warning {
            s |= sw::WARNING;
        }
        if self.internal_limit {
            s |= sw::INTERNAL_LIMIT;
        }
        if self.abnormal_stop {
            s |= sw::ABNORMAL_STOP;
        }
        let p = &self.params;
        let param_zero = match self.mode {
            mode::PP => {
                p.profile_velocity == 0
                    || p.profile_acceleration == 0
                    || p.profile_deceleration == 0
            }
            mode::PV => p.profile_acceleration == 0 || p.profile_deceleration == 0,
            _ => false,
        };
        if param_zero {
            s |= sw::PARAM_ZERO;
        }
        match st {
            PdsState::OperationEnabled => match self.mode {
                mode::PP => {
                    if self.target_reached {
                        s |= sw::TARGET_REACHED;
                    }
                    if self.pp.ack {
                        s |= sw::BIT12;
                    } else {
                        s |= sw::SETPOINT_FREE;
                    }
                    if self.fe_flag {
                        s |= sw::BIT13;
                    }
                }
                mode::PV => {
                    if self.target_reached {
                        s |= sw::TARGET_REACHED;
                    }
                    if self.actual_velocity.unsigned_abs() <= p.velocity_threshold as u32 {
                        s |= sw::BIT12;
                    }
                }
                mode::HM => match self.hm.status() {
                    HomingStatus::Idle => {
                        if self.motion.velocity() == 0.0 {
                            s |= sw::TARGET_REACHED;
                        }
                    }
                    HomingStatus::InProgress => {}
                    HomingStatus::Attained => {
                        s |= sw::BIT12;
                        if self.target_reached {
                            s |= sw::TARGET_REACHED;
                        }
                    }
                    HomingStatus::Error => {
                        s |= sw::BIT13;
                        if self.motion.velocity() == 0.0 {
                            s |= sw::TARGET_REACHED;
                        }
                    }
                },
                mode::PT if self.target_reached => s |= sw::TARGET_REACHED,
                mode::CSP | mode::CSV | mode::CST => {
                    if !self.halted && !self.abnormal_stop && self.pending == Pending::None {
                        s |= sw::BIT12;
                    }
                    if self.mode == mode::CSP && self.fe_flag {
                        s |= sw::BIT13;
                    }
                }
                _ => {}
            },
            PdsState::QuickStopActive if self.target_reached && self.motion.velocity() == 0.0 => {
                s |= sw::TARGET_REACHED;
            }
            _ => {}
        }
        s
    }
}
