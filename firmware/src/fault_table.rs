//! The fault table ([`TABLE`]): every fault kind's code, error-register bits, red-LED
//! flashes, reaction, latching, 0x2056 bit, protection class and text, stated once,
//! the [`FaultKind`] accessors derived from it at compile time, and the [`Emergency`]
//! a fault sends. The fault logic that uses them is `faults` (which re-exports them);
//! the diagnosis texts of `diagnosis` are made from the table, below the fault logic
//! that keeps their history.

/// The kinds of fault, most severe first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
#[repr(u8)]
pub enum FaultKind {
    /// Over-current or phase short circuit.
    OverCurrent = 0,
    /// Bus over-voltage.
    OverVoltage = 1,
    /// Phase fault or current-sensing fault (ADC offset, current does not follow).
    PhaseSensing = 2,
    /// Motor open or poor contact (no current response at power-up).
    MotorOpen = 3,
    /// Bus under-voltage.
    UnderVoltage = 4,
    /// Position following error.
    FollowingError = 5,
    /// EtherCAT communication fault (watchdog, sync, state transition, PDO length).
    Ecat = 6,
    /// Motor blocked: the open-loop stall detection saw the rotor lose synchronism.
    MotorBlocked = 7,
}

/// One row of the fault table ([`TABLE`]): what the drive states about a fault kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FaultInfo {
    /// Short name (docs, logs).
    pub name: &'static str,
    /// What detects it and when (docs).
    pub detection: &'static str,
    /// 0x603F and emergency code (EtherCAT faults carry the caller's code; this is
    /// the watchdog's).
    pub code: u16,
    /// Bits of 0x1001 (bit 0 generic included; bit 7, manufacturer-specific, marks a
    /// drive alarm: every fault but the EtherCAT one, which bit 4 reports).
    pub register: u8,
    /// Red LED flash count; 0: shown by the EtherCAT ERR LED instead.
    pub flashes: u8,
    /// Reaction: the power stage goes off at once (the bridges cannot, or must not,
    /// drive the motor any more); else the fault reaction 0x605E runs first.
    pub cuts_power: bool,
    /// Needs a power cycle (or 0x2057 = 1) to clear.
    pub latched: bool,
    /// Enable bit in 0x2056; [`NO_MASK`]: cannot be masked there.
    pub mask_bit: u8,
    /// Protects the hardware or the load: a detection of this kind whose cause has
    /// already taken the torque away (a latched hardware trip, a failed current-sensor
    /// check) is reported whatever 0x2056 says (`Faults::raise_unmaskable`), so it can
    /// never be masked into "enabled with no torque".
    pub protective: bool,
    /// The diagnosis text (0x10F3, the ESI's `<DiagMessages>`): the two parameters
    /// are the bus voltage (0.1 V) and the emergency's detail bytes.
    pub text: &'static str,
}

/// An emergency for `MailboxServer::emergency` (a fault's manufacturer data: see the
/// module docs of `faults`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Emergency {
    /// Error code.
    pub code: u16,
    /// Error register (0x1001) at the time.
    pub register: u8,
    /// Manufacturer-specific data.
    pub data: [u8; 5],
}

/// [`FaultInfo::mask_bit`] of a kind 0x2056 cannot switch off.
pub const NO_MASK: u8 = 0xFF;

/// The fault table, one row per [`FaultKind`] in its order (most severe first).
pub const TABLE: [FaultInfo; KINDS] = [
    FaultInfo {
        name: "over-current / phase short",
        detection: "phase current above the limit in the 1 ms tick; the break inputs \
                    and the current loop's fast trip switch the bridges off in hardware",
        code: 0x2310,
        register: 0x83,
        flashes: 1,
        cuts_power: true,
        latched: true,
        // The PWM must stop on a short whatever 0x2056 says (bit 0 is ignored).
        mask_bit: NO_MASK,
        protective: true,
        text: "Over-current or phase short (bus %d x 0.1 V, detail %d)",
    },
    FaultInfo {
        name: "over-voltage",
        detection: "bus voltage above 0x2054 (55 V by default); the current loop's \
                    fast trip latches the bridges off at 55 V",
        code: 0x3210,
        register: 0x85,
        flashes: 2,
        // Braking would pump the bus higher.
        cuts_power: true,
        latched: true,
        mask_bit: 1,
        protective: true,
        text: "Bus over-voltage (bus %d x 0.1 V, detail %d)",
    },
    FaultInfo {
        name: "phase / current sensing",
        detection: "start-up current-sensor offset check; current that does not follow \
                    its reference while running; a calibration outside its band",
        code: 0x5210,
        register: 0x83,
        flashes: 9,
        cuts_power: true,
        latched: false,
        mask_bit: 3,
        protective: true,
        text: "Phase or current-sensing fault (bus %d x 0.1 V, reference %d mA)",
    },
    FaultInfo {
        name: "motor open / poor contact",
        detection: "power-up current tune (open phase, unbalanced, implausible); no \
                    current in a phase while running",
        code: 0x7120,
        register: 0xA1,
        flashes: 4,
        cuts_power: true,
        latched: false,
        mask_bit: 2,
        protective: false,
        text: "Motor open or poor contact (bus %d x 0.1 V, reason and phase %X)",
    },
    FaultInfo {
        name: "under-voltage",
        detection: "bus voltage below 0x2055 (12 V by default; 0 = off) once it has \
                    been 0.5 V above it since power-up; clears 0.5 V above",
        code: 0x3220,
        register: 0x85,
        flashes: 3,
        cuts_power: false,
        latched: false,
        mask_bit: 6,
        protective: false,
        text: "Bus under-voltage (bus %d x 0.1 V, detail %d)",
    },
    FaultInfo {
        name: "position following error",
        detection: "following error above 0x2030; a failed commutation alignment",
        code: 0x8611,
        register: 0xA1,
        flashes: 7,
        cuts_power: false,
        latched: false,
        mask_bit: 7,
        protective: false,
        text: "Position following error (bus %d x 0.1 V, detail %d)",
    },
    FaultInfo {
        name: "EtherCAT communication",
        detection: "watchdog (0x8700), sync, ESM transition (0xA000, 0xA001), PDO \
                    length (0x8210, 0x8220): the caller's code; reaction 0x6007 = 1",
        code: 0x8700,
        register: 0x11,
        flashes: 0,
        cuts_power: false,
        latched: false,
        mask_bit: NO_MASK,
        protective: false,
        text: "EtherCAT communication fault (bus %d x 0.1 V, AL status / states %X)",
    },
    FaultInfo {
        name: "motor blocked",
        detection: "open-loop stall detection (0x2060-0x2062; switched by 0x2060); an \
                    event: a fault reset clears it",
        code: 0x7121,
        register: 0xA1,
        flashes: 5,
        cuts_power: false,
        latched: false,
        mask_bit: NO_MASK,
        protective: false,
        text: "Motor blocked, open-loop stall (bus %d x 0.1 V, load angle %d x 0.1 deg)",
    },
];

// The columns the drive uses at run time, taken out of [`TABLE`] at compile time: the
// board image holds these small arrays and masks, not the table's documentation
// strings.

/// One column of [`TABLE`] as an array indexed by the kind number.
macro_rules! column {
    ($field:ident: $t:ty) => {{
        let mut a: [$t; KINDS] = [0; KINDS];
        let mut i = 0;
        while i < KINDS {
            a[i] = TABLE[i].$field;
            i += 1;
        }
        a
    }};
}

/// A yes/no column of [`TABLE`] as a mask: bit n set for kind n.
macro_rules! kinds_where {
    ($field:ident) => {{
        let mut m = 0u8;
        let mut i = 0;
        while i < KINDS {
            if TABLE[i].$field {
                m |= 1 << i;
            }
            i += 1;
        }
        m
    }};
}

const CODES: [u16; KINDS] = column!(code: u16);
const REGISTERS: [u8; KINDS] = column!(register: u8);
const FLASHES: [u8; KINDS] = column!(flashes: u8);
const MASK_BITS: [u8; KINDS] = column!(mask_bit: u8);
/// Bit n set: [`FaultKind`] n cuts the power at once ([`FaultKind::cuts_power`]).
pub(crate) const POWER_CUT_MASK: u8 = kinds_where!(cuts_power);
const LATCHED_MASK: u8 = kinds_where!(latched);
const PROTECTIVE_MASK: u8 = kinds_where!(protective);

/// Number of fault kinds.
pub const KINDS: usize = 8;

impl FaultKind {
    /// The kind numbered `n` (its `repr(u8)` value), if any.
    pub fn from_number(n: u8) -> Option<FaultKind> {
        FaultKind::ALL.get(usize::from(n)).copied()
    }
    /// All kinds, most severe first.
    pub const ALL: [FaultKind; KINDS] = [
        FaultKind::OverCurrent,
        FaultKind::OverVoltage,
        FaultKind::PhaseSensing,
        FaultKind::MotorOpen,
        FaultKind::UnderVoltage,
        FaultKind::FollowingError,
        FaultKind::Ecat,
        FaultKind::MotorBlocked,
    ];
    /// Its row of [`TABLE`] (documentation and host tools; the drive's own code uses
    /// the accessors below).
    pub const fn info(self) -> &'static FaultInfo {
        &TABLE[self as usize]
    }
    /// 0x603F code (EtherCAT faults carry the caller's code instead).
    pub const fn code(self) -> u16 {
        CODES[self as usize]
    }
    /// Bits of 0x1001 (bit 0 generic always included). Bit 7 (manufacturer-specific)
    /// marks a drive alarm: every fault but the EtherCAT one, which bit 4 reports
    /// (the DP3CL's use of the two bits).
    pub const fn error_register(self) -> u8 {
        REGISTERS[self as usize]
    }
    /// Red LED flash count (`None`: shown by the EtherCAT ERR LED instead).
    pub const fn flashes(self) -> Option<u8> {
        match FLASHES[self as usize] {
            0 => None,
            n => Some(n),
        }
    }
    /// The power stage goes off at once ([`FaultInfo::cuts_power`]); the other
    /// faults stop the motor with the fault reaction 0x605E first.
    pub const fn cuts_power(self) -> bool {
        POWER_CUT_MASK & (1 << self as u8) != 0
    }
    /// Needs a power cycle (or 0x2057 = 1) to clear.
    pub const fn latched(self) -> bool {
        LATCHED_MASK & (1 << self as u8) != 0
    }
    /// Protects the hardware or the load ([`FaultInfo::protective`]).
    pub const fn protective(self) -> bool {
        PROTECTIVE_MASK & (1 << self as u8) != 0
    }
    /// Enable bit in 0x2056 (`None`: cannot be masked).
    pub const fn mask_bit(self) -> Option<u8> {
        match MASK_BITS[self as usize] {
            NO_MASK => None,
            b => Some(b),
        }
    }
}
