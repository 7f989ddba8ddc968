//! The values of [`Cia402`] the objects and the application read (and the few they
//! write directly): state, words, positions, velocities, torques.

use super::*;

impl Cia402 {
    /// PDS state.
    pub fn state(&self) -> PdsState {
        self.state
    }
    /// The last cycle's command enables the motor side only so that it can get ready
    /// (Switched on, "enable operation" commanded, [`DriveFeedback::enable_pending`]):
    /// the drive function is not enabled yet.
    pub fn enable_waiting(&self) -> bool {
        self.enable_waiting
    }
    /// 0x6041 as computed in the last cycle.
    pub fn statusword(&self) -> u16 {
        self.statusword.raw()
    }
    /// 0x6041 as computed in the last cycle, its bits by name.
    pub fn status(&self) -> Statusword {
        self.statusword
    }
    /// 0x6040.
    pub fn controlword(&self) -> u16 {
        self.controlword.raw()
    }
    /// Writes 0x6040 (acts in the next cycle).
    pub fn set_controlword(&mut self, cw: u16) {
        self.controlword = Controlword::from_raw(cw);
    }
    /// 0x6060.
    pub fn mode_request(&self) -> i8 {
        self.mode_request.code()
    }
    /// Writes 0x6060; unsupported values are ignored (the SDO path refuses them).
    pub fn set_mode(&mut self, m: i8) {
        if let (true, Some(mode)) = (
            mode_supported(m, self.supported_modes()),
            OperationMode::from_code(m),
        ) {
            self.mode_request = mode;
        }
    }
    /// 0x6061.
    pub fn mode_display(&self) -> i8 {
        self.mode.code()
    }
    /// The mode that runs (0x6061).
    pub fn operation_mode(&self) -> OperationMode {
        self.mode
    }
    /// 0x603F.
    pub fn error_code(&self) -> u16 {
        self.error_code
    }
    /// Touch probe value `k` (0x60BA + k), in the position range 0x607B when one is set.
    // Measured (cargo xtask size, LAN9252 image): see `Faults::error_code`.
    #[inline(never)]
    pub(crate) fn probe_position(&self, k: usize) -> i32 {
        self.params.wrap_position(self.probe.value(k))
    }
    /// 0x6064 (in the position range 0x607B when one is set).
    pub fn position_actual(&self) -> i32 {
        self.params.wrap_position(self.actual_position)
    }
    /// 0x6062 position demand value (user units, in the position range 0x607B when one
    /// is set).
    pub fn position_demand(&self) -> i32 {
        self.params.wrap_position(self.motion.position())
    }
    /// 0x60FC position demand internal value (raw).
    pub fn position_demand_internal(&self) -> i32 {
        self.user_to_raw(self.motion.position())
    }
    /// 0x606B velocity demand value.
    pub fn velocity_demand(&self) -> i32 {
        self.motion.velocity() as i32
    }
    /// 0x6074 torque demand: in CST the demand after the slope and 0x6072, else the
    /// servo loops' demand (per mille, user sign).
    pub fn torque_demand(&self) -> i16 {
        if self.mode.is_torque() && self.state == PdsState::OperationEnabled {
            modes::round_i16(self.torque_demand)
        } else {
            self.servo_torque_user()
        }
    }
    /// 0x6077 (user sign: 0x607E bit 6 turns torques round with velocities).
    pub fn torque_actual(&self) -> i16 {
        pol16(self.vel_neg(), self.actual_torque)
    }
    /// The servo loops' torque demand, user sign.
    pub(super) fn servo_torque_user(&self) -> i16 {
        pol16(self.vel_neg(), self.servo_torque)
    }
    /// 0x606C.
    pub fn velocity_actual(&self) -> i32 {
        self.actual_velocity
    }
    /// 0x60F4.
    pub fn following_error(&self) -> i32 {
        self.following_error
    }
    /// 0x60FD.
    pub fn digital_inputs(&self) -> u32 {
        self.digital_inputs
    }
    /// 0x60FE:01 masked by 0x60FE:02: the outputs the master drives.
    pub fn digital_outputs(&self) -> u32 {
        self.params.digital_outputs & self.params.digital_outputs_mask
    }
    /// True once after the 0x6065 / 0x6066 supervision raised fault 0x8611: the drive
    /// reports it through its fault module (emergency, history, LED, alarm output).
    pub fn take_following_error_fault(&mut self) -> bool {
        core::mem::take(&mut self.fe_fault_news)
    }
    /// 0x60FE:02: which outputs the master drives.
    pub fn digital_outputs_mask(&self) -> u32 {
        self.params.digital_outputs_mask
    }
    /// Touch probe state.
    pub fn touch_probe(&self) -> &TouchProbe {
        &self.probe
    }
    /// Homing status.
    pub fn homing_status(&self) -> HomingStatus {
        self.hm.status()
    }
    /// A stall homing method searches its hard stop: a stall is its reference, not a
    /// fault (the drive skips the 0x2062 reaction).
    pub fn seeking_stall(&self) -> bool {
        self.mode == OperationMode::Hm && self.hm.seeking_stall()
    }

    pub(super) fn pos_neg(&self) -> bool {
        self.params.polarity & 0x80 != 0
    }
    pub(super) fn vel_neg(&self) -> bool {
        self.params.polarity & 0x40 != 0
    }
    pub(super) fn raw_to_user(&self, raw: i32) -> i32 {
        pol(self.pos_neg(), raw).wrapping_add(self.shift)
    }
    pub(super) fn user_to_raw(&self, user: i32) -> i32 {
        pol(self.pos_neg(), user.wrapping_sub(self.shift))
    }
}
