//! The CiA 402 words as types: the mode of operation ([`OperationMode`], 0x6060 /
//! 0x6061, an `i8` on the wire), the controlword 0x6040 ([`Controlword`]) and the
//! statusword 0x6041 ([`Statusword`]) with their bits named, the mode-specific bits
//! 4-6, 9 and 10, 12, 13 once per mode (IEC 61800-7-201). The raw values stay what
//! the objects, the PDOs and the masters see: [`mode`] and [`sw`] give them as
//! constants.

use super::pds::{Command, PdsState};

/// A mode of operation the drive implements (0x6060 / 0x6061 value, 0x6502 bit
/// `value − 1`). Velocity mode (2) and interpolated position (7) are not
/// implemented: [`OperationMode::try_from`] refuses them like any other value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(i8)]
pub enum OperationMode {
    /// 0: no mode (the axis holds its position).
    #[default]
    None = 0,
    /// 1: profile position (PP).
    Pp = 1,
    /// 3: profile velocity (PV).
    Pv = 3,
    /// 4: profile torque (PT, closed loop only).
    Pt = 4,
    /// 6: homing (HM).
    Hm = 6,
    /// 8: cyclic synchronous position (CSP).
    Csp = 8,
    /// 9: cyclic synchronous velocity (CSV).
    Csv = 9,
    /// 10: cyclic synchronous torque (CST, closed loop only).
    Cst = 10,
}

impl OperationMode {
    /// The wire value (0x6060 / 0x6061).
    pub const fn code(self) -> i8 {
        self as i8
    }

    /// Every mode, in the order of their values.
    pub const ALL: [OperationMode; 8] = [
        OperationMode::None,
        OperationMode::Pp,
        OperationMode::Pv,
        OperationMode::Pt,
        OperationMode::Hm,
        OperationMode::Csp,
        OperationMode::Csv,
        OperationMode::Cst,
    ];

    /// The mode of a wire value, `None` for a value the drive does not implement.
    pub const fn from_code(code: i8) -> Option<OperationMode> {
        let mut i = 0;
        while i < Self::ALL.len() {
            if Self::ALL[i].code() == code {
                return Some(Self::ALL[i]);
            }
            i += 1;
        }
        None
    }

    /// The mode's bit in 0x6502 (supported drive modes): bit `value − 1`; 0 for
    /// [`OperationMode::None`].
    pub const fn supported_bit(self) -> u32 {
        match self {
            OperationMode::None => 0,
            m => 1 << (m.code() - 1),
        }
    }

    /// True for the torque modes, PT and CST (closed loop only).
    pub const fn is_torque(self) -> bool {
        matches!(self, OperationMode::Pt | OperationMode::Cst)
    }

    /// True for the modes whose demand is a position the following error is
    /// supervised on (PP, HM, CSP).
    pub const fn is_position(self) -> bool {
        matches!(
            self,
            OperationMode::Pp | OperationMode::Hm | OperationMode::Csp
        )
    }

    /// True for the cyclic synchronous modes (CSP, CSV, CST).
    pub const fn is_cyclic(self) -> bool {
        matches!(
            self,
            OperationMode::Csp | OperationMode::Csv | OperationMode::Cst
        )
    }
}

impl TryFrom<i8> for OperationMode {
    /// The refused wire value.
    type Error = i8;

    fn try_from(code: i8) -> Result<Self, i8> {
        OperationMode::from_code(code).ok_or(code)
    }
}

impl From<OperationMode> for i8 {
    fn from(m: OperationMode) -> i8 {
        m.code()
    }
}

/// Mode of operation values (0x6060 / 0x6061) as the wire's `i8`.
pub mod mode {
    use super::OperationMode;
    /// No mode.
    pub const NONE: i8 = OperationMode::None.code();
    /// Profile position.
    pub const PP: i8 = OperationMode::Pp.code();
    /// Profile velocity.
    pub const PV: i8 = OperationMode::Pv.code();
    /// Profile torque (closed loop only).
    pub const PT: i8 = OperationMode::Pt.code();
    /// Homing.
    pub const HM: i8 = OperationMode::Hm.code();
    /// Cyclic synchronous position.
    pub const CSP: i8 = OperationMode::Csp.code();
    /// Cyclic synchronous velocity.
    pub const CSV: i8 = OperationMode::Csv.code();
    /// Cyclic synchronous torque (closed loop only).
    pub const CST: i8 = OperationMode::Cst.code();
}

/// True if `m` may be written to 0x6060 with the modes `supported` (a 0x6502 value):
/// 0 or a mode whose bit is set.
pub const fn mode_supported(m: i8, supported: u32) -> bool {
    m == 0 || (m >= 1 && m <= 32 && supported & (1 << (m - 1)) != 0)
}

/// Statusword bits (masks of the raw 0x6041; [`Statusword`] reads them by name).
pub mod sw {
    /// Voltage enabled.
    pub const VOLTAGE_ENABLED: u16 = 1 << 4;
    /// Warning.
    pub const WARNING: u16 = 1 << 7;
    /// Manufacturer (E5): abnormal stop (limit switch, quick stop, halt).
    pub const ABNORMAL_STOP: u16 = 1 << 8;
    /// Remote: the controlword is processed.
    pub const REMOTE: u16 = 1 << 9;
    /// Target reached.
    pub const TARGET_REACHED: u16 = 1 << 10;
    /// Internal limit active.
    pub const INTERNAL_LIMIT: u16 = 1 << 11;
    /// Bit 12 in PP: set-point acknowledge.
    pub const SETPOINT_ACKNOWLEDGE: u16 = 1 << 12;
    /// Bit 12 in PV: speed zero (|0x606C| ≤ 0x606F).
    pub const SPEED_ZERO: u16 = 1 << 12;
    /// Bit 12 in HM: homing attained.
    pub const HOMING_ATTAINED: u16 = 1 << 12;
    /// Bit 12 in CSP, CSV, CST: the drive follows the command value.
    pub const DRIVE_FOLLOWS: u16 = 1 << 12;
    /// Bit 13 in PP and CSP: following error.
    pub const FOLLOWING_ERROR: u16 = 1 << 13;
    /// Bit 13 in HM: homing error.
    pub const HOMING_ERROR: u16 = 1 << 13;
    /// Manufacturer (E5): a motion parameter (0x6081 / 0x6083 / 0x6084) is zero.
    pub const PARAM_ZERO: u16 = 1 << 14;
    /// Manufacturer (E5): a new set-point can be accepted (PP).
    pub const SETPOINT_FREE: u16 = 1 << 15;
}

/// The statusword 0x6041.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(transparent)]
pub struct Statusword(u16);

impl Statusword {
    /// The word of a raw value.
    pub const fn from_raw(raw: u16) -> Statusword {
        Statusword(raw)
    }
    /// The raw value.
    pub const fn raw(self) -> u16 {
        self.0
    }
    /// The state bits (0-3, 5, 6) of `state`, nothing else set.
    pub const fn of_state(state: PdsState) -> Statusword {
        Statusword(state.statusword_bits())
    }
    /// This word with the bits of `mask` set when `on`.
    #[inline(always)]
    pub const fn with(self, mask: u16, on: bool) -> Statusword {
        Statusword(if on { self.0 | mask } else { self.0 })
    }
    const fn bit(self, mask: u16) -> bool {
        self.0 & mask != 0
    }
    /// The PDS state the word shows (the standard masks).
    pub const fn state(self) -> Option<PdsState> {
        PdsState::from_statusword(self.0)
    }
    /// Bit 4: voltage enabled.
    pub const fn voltage_enabled(self) -> bool {
        self.bit(sw::VOLTAGE_ENABLED)
    }
    /// Bit 7: warning.
    pub const fn warning(self) -> bool {
        self.bit(sw::WARNING)
    }
    /// Bit 8 (E5): abnormal stop.
    pub const fn abnormal_stop(self) -> bool {
        self.bit(sw::ABNORMAL_STOP)
    }
    /// Bit 9: remote.
    pub const fn remote(self) -> bool {
        self.bit(sw::REMOTE)
    }
    /// Bit 10: target reached.
    pub const fn target_reached(self) -> bool {
        self.bit(sw::TARGET_REACHED)
    }
    /// Bit 11: internal limit active.
    pub const fn internal_limit(self) -> bool {
        self.bit(sw::INTERNAL_LIMIT)
    }
    /// Bit 12 in PP: set-point acknowledge.
    pub const fn setpoint_acknowledge(self) -> bool {
        self.bit(sw::SETPOINT_ACKNOWLEDGE)
    }
    /// Bit 12 in PV: speed zero.
    pub const fn speed_zero(self) -> bool {
        self.bit(sw::SPEED_ZERO)
    }
    /// Bit 12 in HM: homing attained.
    pub const fn homing_attained(self) -> bool {
        self.bit(sw::HOMING_ATTAINED)
    }
    /// Bit 12 in CSP, CSV, CST: the drive follows the command value.
    pub const fn drive_follows(self) -> bool {
        self.bit(sw::DRIVE_FOLLOWS)
    }
    /// Bit 13 in PP and CSP: following error.
    pub const fn following_error(self) -> bool {
        self.bit(sw::FOLLOWING_ERROR)
    }
    /// Bit 13 in HM: homing error.
    pub const fn homing_error(self) -> bool {
        self.bit(sw::HOMING_ERROR)
    }
    /// Bit 14 (E5): a motion parameter is zero.
    pub const fn param_zero(self) -> bool {
        self.bit(sw::PARAM_ZERO)
    }
    /// Bit 15 (E5): a new set-point can be accepted (PP).
    pub const fn setpoint_free(self) -> bool {
        self.bit(sw::SETPOINT_FREE)
    }
}

/// The controlword 0x6040.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(transparent)]
pub struct Controlword(u16);

impl Controlword {
    const NEW_SETPOINT: u16 = 1 << 4;
    const CHANGE_IMMEDIATELY: u16 = 1 << 5;
    const RELATIVE: u16 = 1 << 6;
    const FAULT_RESET: u16 = 1 << 7;
    const HALT: u16 = 1 << 8;
    const CHANGE_ON_SETPOINT: u16 = 1 << 9;

    /// The word of a raw value.
    pub const fn from_raw(raw: u16) -> Controlword {
        Controlword(raw)
    }
    /// The raw value.
    pub const fn raw(self) -> u16 {
        self.0
    }
    const fn bit(self, mask: u16) -> bool {
        self.0 & mask != 0
    }
    /// The PDS command of bits 0-3 and 7 (the standard masks).
    pub const fn command(self) -> Command {
        Command::decode(self.0)
    }
    /// Bit 7: fault reset.
    pub const fn fault_reset(self) -> bool {
        self.bit(Self::FAULT_RESET)
    }
    /// Bit 8: halt.
    pub const fn halt(self) -> bool {
        self.bit(Self::HALT)
    }
    /// Bit 4 in PP: new set-point.
    pub const fn new_setpoint(self) -> bool {
        self.bit(Self::NEW_SETPOINT)
    }
    /// Bit 4 in HM: homing operation start.
    pub const fn homing_start(self) -> bool {
        self.bit(Self::NEW_SETPOINT)
    }
    /// Bit 5 in PP: change set immediately.
    pub const fn change_immediately(self) -> bool {
        self.bit(Self::CHANGE_IMMEDIATELY)
    }
    /// Bit 6 in PP: the target is relative.
    pub const fn relative(self) -> bool {
        self.bit(Self::RELATIVE)
    }
    /// Bit 9 in PP: change on set-point (pass through the current target).
    pub const fn change_on_setpoint(self) -> bool {
        self.bit(Self::CHANGE_ON_SETPOINT)
    }
    /// Bit 7 rose since `prev`: a fault reset edge.
    pub const fn fault_reset_edge(self, prev: Controlword) -> bool {
        self.fault_reset() && !prev.fault_reset()
    }
    /// Bit 4 rose since `prev` (PP new set-point, HM start).
    pub const fn new_setpoint_edge(self, prev: Controlword) -> bool {
        self.new_setpoint() && !prev.new_setpoint()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_wire_mode_value_round_trips_or_is_refused() {
        for code in i8::MIN..=i8::MAX {
            match OperationMode::try_from(code) {
                Ok(m) => assert_eq!(i8::from(m), code),
                Err(e) => {
                    assert_eq!(e, code);
                    assert!(!matches!(code, 0 | 1 | 3 | 4 | 6 | 8 | 9 | 10));
                }
            }
        }
        assert_eq!(OperationMode::try_from(2), Err(2), "vl is not implemented");
        assert_eq!(OperationMode::try_from(7), Err(7), "ip is not implemented");
        assert!(OperationMode::Pt.is_torque() && OperationMode::Cst.is_torque());
        assert!(!OperationMode::Csp.is_torque() && OperationMode::Csp.is_position());
        assert_eq!(OperationMode::Cst.supported_bit(), 1 << 9);
        assert_eq!(OperationMode::None.supported_bit(), 0);
    }

    #[test]
    fn the_named_bits_are_the_standard_ones() {
        let s = Statusword::from_raw(1 << 12);
        assert!(s.setpoint_acknowledge() && s.speed_zero() && s.homing_attained());
        assert!(s.drive_follows() && !s.following_error() && !s.target_reached());
        let s = Statusword::of_state(PdsState::OperationEnabled)
            .with(sw::HOMING_ERROR, true)
            .with(sw::REMOTE, false);
        assert_eq!(s.raw(), 0x2027);
        assert_eq!(s.state(), Some(PdsState::OperationEnabled));
        assert!(s.homing_error() && !s.remote());
        let c = Controlword::from_raw(0x011F);
        assert!(c.new_setpoint() && c.homing_start() && c.halt() && !c.relative());
        assert_eq!(c.command(), Command::EnableOperation);
        assert!(c.new_setpoint_edge(Controlword::from_raw(0x000F)));
        assert!(!c.new_setpoint_edge(c));
        let r = Controlword::from_raw(0x0080);
        assert!(r.fault_reset_edge(Controlword::default()) && !r.fault_reset_edge(r));
        assert_eq!(r.command(), Command::FaultReset);
    }
}
