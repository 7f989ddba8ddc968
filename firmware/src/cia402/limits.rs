//! Limits and supervision of a step: the software position limits 0x607D on the
//! demand, the following error (0x6065 / 0x6066) and the internal-limit flag.

use super::*;

impl Cia402 {
    pub(super) fn clamp_sw_limit(&mut self) -> bool {
        if let Some((lo, hi)) = self.params.sw_limits() {
            let pos = self.motion.position();
            let v = self.motion.velocity();
            if pos > hi || (pos == hi && v > 0.0) {
                self.motion.set(hi, 0.0);
                self.internal_limit = true;
                return true;
            }
            if pos < lo || (pos == lo && v < 0.0) {
                self.motion.set(lo, 0.0);
                self.internal_limit = true;
                return true;
            }
        }
        false
    }

    /// Step 5: following error supervision (0x6065 / 0x6066, fault 0x8611 after the
    /// time-out) and the internal limit of a limited current or torque.
    #[inline(always)]
    pub(super) fn supervise(&mut self, fb: &DriveFeedback, drive_enabled: bool, dt: f32) {
        self.following_error = self.motion.position().wrapping_sub(self.actual_position);
        let position_mode = self.mode.is_position();
        if drive_enabled && position_mode && self.params.following_error_window != u32::MAX {
            if self.following_error.unsigned_abs() > self.params.following_error_window {
                self.fe_time += dt;
                if self.fe_time * 1000.0 > self.params.following_error_timeout as f32 {
                    self.fe_flag = true;
                    if !matches!(
                        self.state,
                        crate::cia402::pds::PdsState::Fault
                            | crate::cia402::pds::PdsState::FaultReactionActive
                    ) {
                        self.fe_fault_news = true;
                    }
                    self.fault_detected(ERR_FOLLOWING);
                }
            } else {
                self.fe_time = 0.0;
            }
        } else {
            self.fe_time = 0.0;
        }
        if fb.current_limited
            || (self.params.max_torque > 0
                && fb.torque.unsigned_abs() >= self.params.torque_limit())
        {
            self.internal_limit = true;
        }
    }
}
