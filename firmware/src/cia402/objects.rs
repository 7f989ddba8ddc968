//! The CiA 402 objects (0x6000-0x6FFF) of the dictionary: static descriptions
//! ([`OBJECTS`]), SDO read/write on [`Cia402`], and the fast accessors of the cyclic
//! path by compact slot ids ([`RX_SLOTS`], [`TX_SLOTS`]).
//!
//! Units: positions in command units ("inc", 0x2001 per motor revolution), velocities
//! in command units/s, accelerations in command units/s², torque and current in per
//! mille of the rated value, times in ms.

use super::{homing, mode_supported, probe, Cia402, SUPPORTED_MODES};
use ecat_slave_stack::od::{self, Access, DataType, Entry, Object, PdoMappable, SdoAbort};

const U8: DataType = DataType::Unsigned8;
const U16: DataType = DataType::Unsigned16;
const U32: DataType = DataType::Unsigned32;
const I8: DataType = DataType::Integer8;
const I16: DataType = DataType::Integer16;
const I32: DataType = DataType::Integer32;
const RO: Access = Access::RO;
const RW: Access = Access::RW;
const RX: PdoMappable = PdoMappable::Rx;
const TX: PdoMappable = PdoMappable::Tx;

/// The CiA 402 objects, sorted by index.
pub const OBJECTS: &[Object] = &[
    Object::var(0x6007, "Abort connection option code", &[Entry::new(0, "Abort connection option code", I16, RW).range(0, 3).default(1).saved()],
        "Reaction when the master's commands stop (SM watchdog, Op left, SYNC0 missing): 0 none (the last set-points stay), 1 fault (reaction 0x605E), 2 disable voltage, 3 quick stop (0x605A)."),
    Object::var(0x603F, "Error code", &[Entry::new(0, "Error code", U16, RO).pdo(TX).default(0)],
        "Code of the last fault (CiA 402 / CiA 301 error codes); 0 after a fault reset."),
    Object::var(0x6040, "Controlword", &[Entry::new(0, "Controlword", U16, RW).pdo(RX).default(0)],
        "PDS commands (bits 0-3, 7 fault reset), mode-specific bits 4-6 and 9, bit 8 halt."),
    Object::var(0x6041, "Statusword", &[Entry::new(0, "Statusword", U16, RO).pdo(TX)],
        "PDS state, voltage enabled, warning, remote, target reached, internal limit, mode bits, E5 bits 8/14/15."),
    Object::var(0x605A, "Quick stop option code", &[Entry::new(0, "Quick stop option code", I16, RW).range(0, 8).default(2).saved()],
        "0 disable drive function; 1/2/3/4 slow-down / quick-stop / max-deceleration ramp then switch on disabled; 5-8 the same and stay in quick stop active."),
    Object::var(0x605B, "Shutdown option code", &[Entry::new(0, "Shutdown option code", I16, RW).range(0, 1).default(0).saved()],
        "Transition 8: 0 disable drive function; 1 slow down with 0x6084, then disable."),
    Object::var(0x605C, "Disable operation option code", &[Entry::new(0, "Disable operation option code", I16, RW).range(0, 1).default(1).saved()],
        "Transition 5: 0 disable drive function; 1 slow down with 0x6084, then disable."),
    Object::var(0x605D, "Halt option code", &[Entry::new(0, "Halt option code", I16, RW).range(1, 4).default(1).saved()],
        "Controlword bit 8: 1 slow-down ramp, 2 quick-stop ramp, 3/4 max-deceleration ramp; stays in operation enabled."),
    Object::var(0x605E, "Fault reaction option code", &[Entry::new(0, "Fault reaction option code", I16, RW).range(0, 4).default(2).saved()],
        "0 disable drive function; 1 slow-down ramp; 2 quick-stop ramp; 3/4 max-deceleration ramp."),
    Object::var(0x6060, "Modes of operation", &[Entry::new(0, "Modes of operation", I8, RW).pdo(RX).range(0, 9).default(0)],
        "Requested mode: 0 none, 1 PP, 3 PV, 6 HM, 8 CSP, 9 CSV."),
    Object::var(0x6061, "Modes of operation display", &[Entry::new(0, "Modes of operation display", I8, RO).pdo(TX).default(0)],
        "Mode that is running (changes when the switch is done)."),
    Object::var(0x6062, "Position demand value", &[Entry::new(0, "Position demand value", I32, RO).pdo(TX).unit("inc")],
        "Output of the trajectory generator / CSP interpolation."),
    Object::var(0x6063, "Position actual internal value", &[Entry::new(0, "Position actual internal value", I32, RO).pdo(TX).unit("inc")],
        "Actual position, motor side, before polarity and home offset."),
    Object::var(0x6064, "Position actual value", &[Entry::new(0, "Position actual value", I32, RO).pdo(TX).unit("inc")],
        "Actual position in command units."),
    Object::var(0x6065, "Following error window", &[Entry::new(0, "Following error window", U32, RW).pdo(RX).default(50_000).unit("inc").saved()],
        "Allowed |0x60F4|; 0xFFFFFFFF switches the supervision off."),
    Object::var(0x6066, "Following error time out", &[Entry::new(0, "Following error time out", U16, RW).default(100).unit("ms").saved()],
        "Time the following error may exceed 0x6065 before statusword bit 13 and fault 0x8611."),
    Object::var(0x6067, "Position window", &[Entry::new(0, "Position window", U32, RW).pdo(RX).default(100).unit("inc").saved()],
        "Target reached window."),
    Object::var(0x6068, "Position window time", &[Entry::new(0, "Position window time", U16, RW).default(0).unit("ms").saved()],
        "Time in the window before target reached."),
    Object::var(0x606B, "Velocity demand value", &[Entry::new(0, "Velocity demand value", I32, RO).pdo(TX).unit("inc/s")],
        "Velocity of the trajectory generator."),
    Object::var(0x606C, "Velocity actual value", &[Entry::new(0, "Velocity actual value", I32, RO).pdo(TX).unit("inc/s")],
        "Measured velocity."),
    Object::var(0x606D, "Velocity window", &[Entry::new(0, "Velocity window", U16, RW).default(100).unit("inc/s").saved()],
        "PV target reached window."),
    Object::var(0x606E, "Velocity window time", &[Entry::new(0, "Velocity window time", U16, RW).default(0).unit("ms").saved()],
        "PV time in the window before target reached."),
    Object::var(0x606F, "Velocity threshold", &[Entry::new(0, "Velocity threshold", U16, RW).default(100).unit("inc/s").saved()],
        "PV speed-zero threshold (statusword bit 12)."),
    Object::var(0x6072, "Max torque", &[Entry::new(0, "Max torque", U16, RW).pdo(RX).range(0, 3000).default(1000).unit("0.1 %").saved()],
        "Torque limit for the servo loops (closed loop), per mille of rated torque."),
    Object::var(0x6073, "Max current", &[Entry::new(0, "Max current", U16, RW).range(0, 3000).default(1000).unit("0.1 %").saved()],
        "Current limit, per mille of the rated current 0x6075."),
    Object::var(0x6075, "Motor rated current", &[Entry::new(0, "Motor rated current", U32, RO).unit("mA")],
        "Rated current (follows the peak current setting 0x2000)."),
    Object::var(0x6077, "Torque actual value", &[Entry::new(0, "Torque actual value", I16, RO).pdo(TX).unit("0.1 %")],
        "Measured torque, per mille of rated torque."),
    Object::var(0x6078, "Current actual value", &[Entry::new(0, "Current actual value", I16, RO).pdo(TX).unit("0.1 %")],
        "Measured current, per mille of rated current."),
    Object::var(0x607A, "Target position", &[Entry::new(0, "Target position", I32, RW).pdo(RX).default(0).unit("inc")],
        "PP target (absolute or relative), CSP target every cycle."),
    Object::var(0x607C, "Home offset", &[Entry::new(0, "Home offset", I32, RW).pdo(RX).default(0).unit("inc").saved()],
        "Position actual value given to the home position when homing ends."),
    Object::array(0x607D, "Software position limit", &[
        Entry::count(2).range(2, 2),
        Entry::new(1, "Min position limit", I32, RW).default(i32::MIN as i64).unit("inc").saved(),
        Entry::new(2, "Max position limit", I32, RW).default(i32::MAX as i64).unit("inc").saved(),
    ], "Demand positions are limited to [min, max] when min < max (the type limits mean off)."),
    Object::var(0x607E, "Polarity", &[Entry::new(0, "Polarity", U8, RW).default(0).saved()],
        "Bit 7 inverts positions, bit 6 velocities (other bits refused); writable outside operation enabled."),
    Object::var(0x607F, "Max profile velocity", &[Entry::new(0, "Max profile velocity", U32, RW).pdo(RX).range(1, u32::MAX as i64).default(5_000_000).unit("inc/s").saved()],
        "Upper limit of every profile / target velocity."),
    Object::var(0x6080, "Max motor speed", &[Entry::new(0, "Max motor speed", U32, RW).range(1, u32::MAX as i64).default(5_000_000).unit("inc/s").saved()],
        "Upper limit of every velocity demand."),
    Object::var(0x6081, "Profile velocity", &[Entry::new(0, "Profile velocity", U32, RW).pdo(RX).default(50_000).unit("inc/s").saved()],
        "PP travel speed, limited by min(0x607F, 0x6080)."),
    Object::var(0x6082, "End velocity", &[Entry::new(0, "Start/stop velocity", U32, RW).pdo(RX).default(0).unit("inc/s").saved()],
        "E5: speed the PP profile may start from / stop at without a ramp."),
    Object::var(0x6083, "Profile acceleration", &[Entry::new(0, "Profile acceleration", U32, RW).pdo(RX).default(500_000).unit("inc/s²").saved()],
        "PP / PV acceleration, limited by 0x60C5."),
    Object::var(0x6084, "Profile deceleration", &[Entry::new(0, "Profile deceleration", U32, RW).pdo(RX).default(500_000).unit("inc/s²").saved()],
        "PP / PV deceleration and slow-down ramp, limited by 0x60C6."),
    Object::var(0x6085, "Quick stop deceleration", &[Entry::new(0, "Quick stop deceleration", U32, RW).pdo(RX).default(2_000_000).unit("inc/s²").saved()],
        "Quick-stop ramp; also the stop ramp at a hardware limit switch."),
    Object::var(0x6086, "Motion profile type", &[Entry::new(0, "Motion profile type", I16, RW).range(0, 3).default(0).saved()],
        "PP profile: 0 linear ramp (trapezoid); 3 jerk-limited ramp (trapezoid through a moving average as long as one acceleration, at most 64 cycles); 1 and 2 are refused."),
    Object::array(0x608F, "Position encoder resolution", &[
        Entry::count(2).range(2, 2),
        Entry::new(1, "Encoder increments", U32, RO).default(4000),
        Entry::new(2, "Motor revolutions", U32, RO).default(1),
    ], "Encoder increments per motor revolution."),
    Object::array(0x6091, "Gear ratio", &[
        Entry::count(2).range(2, 2),
        Entry::new(1, "Motor revolutions", U32, RO).default(1),
        Entry::new(2, "Shaft revolutions", U32, RO).default(1),
    ], "Fixed 1:1 (scaling is set by 0x2001)."),
    Object::array(0x6092, "Feed constant", &[
        Entry::count(2).range(2, 2),
        Entry::new(1, "Feed", U32, RO).default(50_000).unit("inc"),
        Entry::new(2, "Shaft revolutions", U32, RO).default(1),
    ], "Command units per revolution (0x2001)."),
    Object::var(0x6098, "Homing method", &[Entry::new(0, "Homing method", I8, RW).pdo(RX).range(1, 37).default(37).saved()],
        "1-14, 17-30, 33, 34, 35, 37."),
    Object::array(0x6099, "Homing speeds", &[
        Entry::count(2).range(2, 2),
        Entry::new(1, "Speed during search for switch", U32, RW).pdo(RX).default(20_000).unit("inc/s").saved(),
        Entry::new(2, "Speed during search for zero", U32, RW).pdo(RX).default(2_000).unit("inc/s").saved(),
    ], "Homing speeds."),
    Object::var(0x609A, "Homing acceleration", &[Entry::new(0, "Homing acceleration", U32, RW).pdo(RX).default(200_000).unit("inc/s²").saved()],
        "Acceleration and deceleration of every homing move."),
    Object::var(0x60B0, "Position offset", &[Entry::new(0, "Position offset", I32, RW).pdo(RX).default(0).unit("inc")],
        "Added to the CSP target position."),
    Object::var(0x60B1, "Velocity offset", &[Entry::new(0, "Velocity offset", I32, RW).pdo(RX).default(0).unit("inc/s")],
        "Velocity feed-forward (CSP) / added to the CSV target."),
    Object::var(0x60B8, "Touch probe function", &[Entry::new(0, "Touch probe function", U16, RW).pdo(RX).default(0)],
        "Per probe (2: bits 8-13): bit 0 enable, 1 continuous, 2 index pulse as trigger, 4 rising edge, 5 falling edge."),
    Object::var(0x60B9, "Touch probe status", &[Entry::new(0, "Touch probe status", U16, RO).pdo(TX)],
        "Per probe: bit 0 enabled, 1 rising value stored, 2 falling value stored, 6/7 toggles in continuous mode."),
    Object::var(0x60BA, "Touch probe 1 positive edge", &[Entry::new(0, "Touch probe 1 positive edge", I32, RO).pdo(TX).unit("inc")],
        "Position latched at the rising edge of probe 1."),
    Object::var(0x60BB, "Touch probe 1 negative edge", &[Entry::new(0, "Touch probe 1 negative edge", I32, RO).pdo(TX).unit("inc")],
        "Position latched at the falling edge of probe 1."),
    Object::var(0x60BC, "Touch probe 2 positive edge", &[Entry::new(0, "Touch probe 2 positive edge", I32, RO).pdo(TX).unit("inc")],
        "Position latched at the rising edge of probe 2."),
    Object::var(0x60BD, "Touch probe 2 negative edge", &[Entry::new(0, "Touch probe 2 negative edge", I32, RO).pdo(TX).unit("inc")],
        "Position latched at the falling edge of probe 2."),
    Object::record(0x60C2, "Interpolation time period", &[
        Entry::count(2).range(2, 2),
        Entry::new(1, "Interpolation time period value", U8, RW).range(1, 255).default(1),
        Entry::new(2, "Interpolation time index", I8, RW).range(-6, -3).default(-3),
    ], "Period = value · 10^index s; must equal the sync cycle."),
    Object::var(0x60C5, "Max acceleration", &[Entry::new(0, "Max acceleration", U32, RW).range(1, u32::MAX as i64).default(100_000_000).unit("inc/s²").saved()],
        "Limit of 0x6083 and 0x609A."),
    Object::var(0x60C6, "Max deceleration", &[Entry::new(0, "Max deceleration", U32, RW).range(1, u32::MAX as i64).default(100_000_000).unit("inc/s²").saved()],
        "Limit of 0x6084 and 0x609A; ramp of the option codes 3 and 4."),
    Object::var(0x60F2, "Positioning option code", &[Entry::new(0, "Positioning option code", U16, RW).range(0, 2).default(0).saved()],
        "Bits 0-1, PP relative moves: 0 from the previous target, 1 from the position demand value, 2 from the position actual value."),
    Object::var(0x60F4, "Following error actual value", &[Entry::new(0, "Following error actual value", I32, RO).pdo(TX).unit("inc")],
        "0x6062 − 0x6064."),
    Object::var(0x60FC, "Position demand internal value", &[Entry::new(0, "Position demand internal value", I32, RO).pdo(TX).unit("inc")],
        "Position demand, motor side."),
    Object::var(0x60FD, "Digital inputs", &[Entry::new(0, "Digital inputs", U32, RO).pdo(TX)],
        "Bit 0 negative limit, 1 positive limit, 2 home switch (after the input functions 0x2152)."),
    Object::array(0x60FE, "Digital outputs", &[
        Entry::count(2).range(2, 2),
        Entry::new(1, "Physical outputs", U32, RW).pdo(RX).default(0),
        Entry::new(2, "Bit mask", U32, RW).default(0),
    ], "Outputs driven by the master where the mask bit is set."),
    Object::var(0x60FF, "Target velocity", &[Entry::new(0, "Target velocity", I32, RW).pdo(RX).default(0).unit("inc/s")],
        "PV and CSV target."),
    Object::var(0x6502, "Supported drive modes", &[Entry::new(0, "Supported drive modes", U32, RO).default(SUPPORTED_MODES as i64)],
        "Bit 0 PP, 2 PV, 5 HM, 7 CSP, 8 CSV."),
];

/// RxPDO-mappable entries; the position in this table is the slot id.
pub const RX_SLOTS: &[(u16, u8)] = &[
    (0x6040, 0),
    (0x6060, 0),
    (0x6065, 0),
    (0x6067, 0),
    (0x6072, 0),
    (0x607A, 0),
    (0x607C, 0),
    (0x607F, 0),
    (0x6081, 0),
    (0x6082, 0),
    (0x6083, 0),
    (0x6084, 0),
    (0x6085, 0),
    (0x6098, 0),
    (0x6099, 1),
    (0x6099, 2),
    (0x609A, 0),
    (0x60B0, 0),
    (0x60B1, 0),
    (0x60B8, 0),
    (0x60FE, 1),
    (0x60FF, 0),
];

/// TxPDO-mappable entries; the position in this table is the slot id.
pub const TX_SLOTS: &[(u16, u8)] = &[
    (0x603F, 0),
    (0x6041, 0),
    (0x6061, 0),
    (0x6062, 0),
    (0x6063, 0),
    (0x6064, 0),
    (0x606B, 0),
    (0x606C, 0),
    (0x6077, 0),
    (0x6078, 0),
    (0x60B9, 0),
    (0x60BA, 0),
    (0x60BB, 0),
    (0x60BC, 0),
    (0x60BD, 0),
    (0x60F4, 0),
    (0x60FC, 0),
    (0x60FD, 0),
];

fn slot_of(table: &[(u16, u8)], index: u16, sub: u8) -> Option<u8> {
    table
        .iter()
        .position(|&e| e == (index, sub))
        .map(|i| i as u8)
}

/// Slot id of an RxPDO-mappable entry.
pub fn rx_slot(index: u16, sub: u8) -> Option<u8> {
    slot_of(RX_SLOTS, index, sub)
}

/// Slot id of a TxPDO-mappable entry.
pub fn tx_slot(index: u16, sub: u8) -> Option<u8> {
    slot_of(TX_SLOTS, index, sub)
}

/// Reads `n` little-endian bytes (1..=4) as a u32.
fn le(data: &[u8]) -> u32 {
    let mut b = [0u8; 4];
    let n = data.len().min(4);
    b[..n].copy_from_slice(&data[..n]);
    u32::from_le_bytes(b)
}

/// Integer type of a field of [`Cia402`] served straight from memory.
#[derive(Debug, Clone, Copy)]
enum Int {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
}

impl Int {
    /// Reads the field at byte offset `off` of `base`, sign- or zero-extended.
    ///
    /// # Safety
    /// `base + off` must be an initialised, aligned field of this type.
    unsafe fn load(self, base: *const u8, off: u16) -> i64 {
        // SAFETY: the caller's contract.
        unsafe {
            let p = base.add(usize::from(off));
            match self {
                Int::I8 => i64::from(p.cast::<i8>().read()),
                Int::U8 => i64::from(p.read()),
                Int::I16 => i64::from(p.cast::<i16>().read()),
                Int::U16 => i64::from(p.cast::<u16>().read()),
                Int::I32 => i64::from(p.cast::<i32>().read()),
                Int::U32 => i64::from(p.cast::<u32>().read()),
            }
        }
    }

    /// Writes `v` (truncated to the type, as `as` does) to the field at byte offset
    /// `off` of `base`.
    ///
    /// # Safety
    /// `base + off` must be an aligned field of this type that nothing else borrows.
    unsafe fn store(self, base: *mut u8, off: u16, v: i64) {
        // SAFETY: the caller's contract.
        unsafe {
            let p = base.add(usize::from(off));
            match self {
                Int::I8 | Int::U8 => p.write(v as u8),
                Int::I16 | Int::U16 => p.cast::<u16>().write(v as u16),
                Int::I32 | Int::U32 => p.cast::<u32>().write(v as u32),
            }
        }
    }
}

/// How the value of an entry is found.
#[derive(Debug, Clone, Copy)]
enum Kind {
    /// A field of [`Cia402`] of this type at byte offset `arg`.
    Int(Int),
    /// The constant `arg` (counts, fixed ratios, supported modes).
    Const,
    PositionDemand,
    VelocityDemand,
    PositionDemandInternal,
    ProbeFunction,
    ProbeStatus,
    /// Latched probe value number `arg`.
    ProbeValue,
}

/// One entry of [`FIELDS`].
#[derive(Debug, Clone, Copy)]
struct Field {
    index: u16,
    sub: u8,
    kind: Kind,
    arg: u16,
}

/// An entry held in a field of [`Cia402`]: the field's type is checked against `$t`
/// (a mismatch does not compile), its offset is taken by `offset_of!`.
macro_rules! field {
    ($index:expr, $sub:expr, $t:ident, $($f:ident).+) => {{
        const _: fn(&Cia402) -> &$t = |c| &c.$($f).+;
        Field {
            index: $index,
            sub: $sub,
            kind: Kind::Int(int_of!($t)),
            arg: core::mem::offset_of!(Cia402, $($f).+) as u16,
        }
    }};
}

macro_rules! int_of {
    (i8) => {
        Int::I8
    };
    (u8) => {
        Int::U8
    };
    (i16) => {
        Int::I16
    };
    (u16) => {
        Int::U16
    };
    (i32) => {
        Int::I32
    };
    (u32) => {
        Int::U32
    };
}

const fn computed(index: u16, sub: u8, kind: Kind, arg: u16) -> Field {
    Field {
        index,
        sub,
        kind,
        arg,
    }
}

/// Where every entry of [`OBJECTS`] gets its value (one table instead of a read and a
/// write dispatch; `tests::every_entry_has_a_field` keeps it complete).
const FIELDS: &[Field] = &[
    field!(0x6007, 0, i16, params.abort_connection_option),
    field!(0x603F, 0, u16, error_code),
    field!(0x6040, 0, u16, controlword),
    field!(0x6041, 0, u16, statusword),
    field!(0x605A, 0, i16, params.quick_stop_option),
    field!(0x605B, 0, i16, params.shutdown_option),
    field!(0x605C, 0, i16, params.disable_op_option),
    field!(0x605D, 0, i16, params.halt_option),
    field!(0x605E, 0, i16, params.fault_reaction_option),
    field!(0x6060, 0, i8, mode_request),
    field!(0x6061, 0, i8, mode),
    computed(0x6062, 0, Kind::PositionDemand, 0),
    field!(0x6063, 0, i32, raw_position),
    field!(0x6064, 0, i32, actual_position),
    field!(0x6065, 0, u32, params.following_error_window),
    field!(0x6066, 0, u16, params.following_error_timeout),
    field!(0x6067, 0, u32, params.position_window),
    field!(0x6068, 0, u16, params.position_window_time),
    computed(0x606B, 0, Kind::VelocityDemand, 0),
    field!(0x606C, 0, i32, actual_velocity),
    field!(0x606D, 0, u16, params.velocity_window),
    field!(0x606E, 0, u16, params.velocity_window_time),
    field!(0x606F, 0, u16, params.velocity_threshold),
    field!(0x6072, 0, u16, params.max_torque),
    field!(0x6073, 0, u16, params.max_current),
    field!(0x6075, 0, u32, rated_current_ma),
    field!(0x6077, 0, i16, actual_torque),
    field!(0x6078, 0, i16, actual_current),
    field!(0x607A, 0, i32, params.target_position),
    field!(0x607C, 0, i32, params.home_offset),
    computed(0x607D, 0, Kind::Const, 2),
    field!(0x607D, 1, i32, params.sw_limit_min),
    field!(0x607D, 2, i32, params.sw_limit_max),
    field!(0x607E, 0, u8, params.polarity),
    field!(0x607F, 0, u32, params.max_profile_velocity),
    field!(0x6080, 0, u32, params.max_motor_speed),
    field!(0x6081, 0, u32, params.profile_velocity),
    field!(0x6082, 0, u32, params.start_stop_speed),
    field!(0x6083, 0, u32, params.profile_acceleration),
    field!(0x6084, 0, u32, params.profile_deceleration),
    field!(0x6085, 0, u32, params.quick_stop_deceleration),
    field!(0x6086, 0, i16, params.motion_profile_type),
    computed(0x608F, 0, Kind::Const, 2),
    field!(0x608F, 1, u32, encoder_increments),
    computed(0x608F, 2, Kind::Const, 1),
    computed(0x6091, 0, Kind::Const, 2),
    computed(0x6091, 1, Kind::Const, 1),
    computed(0x6091, 2, Kind::Const, 1),
    computed(0x6092, 0, Kind::Const, 2),
    field!(0x6092, 1, u32, units_per_rev),
    computed(0x6092, 2, Kind::Const, 1),
    field!(0x6098, 0, i8, params.homing_method),
    computed(0x6099, 0, Kind::Const, 2),
    field!(0x6099, 1, u32, params.homing_speed_switch),
    field!(0x6099, 2, u32, params.homing_speed_zero),
    field!(0x609A, 0, u32, params.homing_acceleration),
    field!(0x60B0, 0, i32, params.position_offset),
    field!(0x60B1, 0, i32, params.velocity_offset),
    computed(0x60B8, 0, Kind::ProbeFunction, 0),
    computed(0x60B9, 0, Kind::ProbeStatus, 0),
    computed(0x60BA, 0, Kind::ProbeValue, 0),
    computed(0x60BB, 0, Kind::ProbeValue, 1),
    computed(0x60BC, 0, Kind::ProbeValue, 2),
    computed(0x60BD, 0, Kind::ProbeValue, 3),
    computed(0x60C2, 0, Kind::Const, 2),
    field!(0x60C2, 1, u8, params.interpolation_period),
    field!(0x60C2, 2, i8, params.interpolation_index),
    field!(0x60C5, 0, u32, params.max_acceleration),
    field!(0x60C6, 0, u32, params.max_deceleration),
    field!(0x60F2, 0, u16, params.positioning_option),
    field!(0x60F4, 0, i32, following_error),
    computed(0x60FC, 0, Kind::PositionDemandInternal, 0),
    field!(0x60FD, 0, u32, digital_inputs),
    computed(0x60FE, 0, Kind::Const, 2),
    field!(0x60FE, 1, u32, params.digital_outputs),
    field!(0x60FE, 2, u32, params.digital_outputs_mask),
    field!(0x60FF, 0, i32, params.target_velocity),
    computed(0x6502, 0, Kind::Const, SUPPORTED_MODES as u16),
];

const _: () = assert!(SUPPORTED_MODES <= u16::MAX as u32);
const _: () = assert!(core::mem::size_of::<Cia402>() <= u16::MAX as usize);

/// The [`FIELDS`] entry of `(index, sub)`.
fn field(index: u16, sub: u8) -> Option<Field> {
    FIELDS
        .iter()
        .find(|f| f.index == index && f.sub == sub)
        .copied()
}

impl Cia402 {
    /// Current value of an entry (sign-extended), `None` if the object/sub-index is
    /// not one of [`OBJECTS`].
    pub fn value(&self, index: u16, sub: u8) -> Option<i64> {
        let f = field(index, sub)?;
        Some(match f.kind {
            Kind::Int(t) => {
                // SAFETY: `f` comes from `FIELDS`, whose `field!` entries hold the
                // offset of an integer field of `Cia402` of type `t` (checked there).
                unsafe { t.load(core::ptr::from_ref(self).cast::<u8>(), f.arg) }
            }
            Kind::Const => i64::from(f.arg),
            Kind::PositionDemand => i64::from(self.position_demand()),
            Kind::VelocityDemand => i64::from(self.velocity_demand()),
            Kind::PositionDemandInternal => i64::from(self.position_demand_internal()),
            Kind::ProbeFunction => i64::from(self.probe.function()),
            Kind::ProbeStatus => i64::from(self.probe.status()),
            Kind::ProbeValue => i64::from(self.probe.value(usize::from(f.arg))),
        })
    }

    /// SDO read of a 0x6xxx entry: little-endian value into `buf`, returns its length.
    pub fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        let e = crate::dictionary::find_entry_in(crate::dictionary::CIA402, index, sub)?;
        if !e.access.readable() {
            return Err(SdoAbort::ReadWriteOnly);
        }
        let v = self
            .value(index, sub)
            .ok_or(SdoAbort::SubindexDoesNotExist)?;
        crate::dictionary::put_le(e, v as u64, buf)
    }

    /// SDO write of a 0x6xxx entry: checks access, length and range (the same checks
    /// as the stack's `check_write`, so a direct call is safe too) and the object's own
    /// rules, then stores the value.
    pub fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoAbort> {
        let e = crate::dictionary::find_entry_in(crate::dictionary::CIA402, index, sub)?;
        od::check_write(e, data, ecat_slave_stack::esm::EsmState::PreOp)?;
        let v = od::decode_int(e.data_type, data).ok_or(SdoAbort::TypeMismatch)?;
        match (index, sub) {
            (0x6060, 0) if !mode_supported(v as i8) => return Err(SdoAbort::ValueRangeExceeded),
            (0x6098, 0) if !homing::supported(v as i8) => return Err(SdoAbort::ValueRangeExceeded),
            (0x6086, 0) if v != 0 && v != 3 => return Err(SdoAbort::ValueRangeExceeded),
            (0x60B8, 0) if !probe::function_valid(v as u16) => {
                return Err(SdoAbort::ValueRangeExceeded)
            }
            (0x607E, 0) => {
                if v as u8 & 0x3F != 0 {
                    return Err(SdoAbort::ValueRangeExceeded);
                }
                if self.state.voltage_enabled() {
                    return Err(SdoAbort::StateConflict);
                }
            }
            _ => {}
        }
        self.store(index, sub, v);
        Ok(())
    }

    /// Stores an already validated value (SDO path; the PDO path is
    /// [`Cia402::set_rx_raw`]).
    fn store(&mut self, index: u16, sub: u8, v: i64) {
        match (index, sub) {
            (0x6060, 0) => self.set_mode(v as i8),
            (0x607E, 0) => self.params.polarity = v as u8 & 0xC0,
            (0x60B8, 0) => self.probe.set_function(v as u16),
            _ => {
                if let Some(Field {
                    kind: Kind::Int(t),
                    arg,
                    ..
                }) = field(index, sub)
                {
                    // SAFETY: as in `value`: `arg` is the offset of an integer field of
                    // type `t`; `&mut self` makes the write exclusive.
                    unsafe { t.store(core::ptr::from_mut(self).cast::<u8>(), arg, v) }
                }
            }
        }
    }

    /// Cyclic path: stores an RxPDO entry by slot id from its little-endian bytes.
    /// Unknown slots are ignored; out-of-range values are made harmless by the users
    /// (an unsupported mode or homing method is not taken over).
    #[inline]
    pub fn set_rx(&mut self, slot: u8, data: &[u8]) {
        self.set_rx_raw(slot, le(data));
    }

    /// Cyclic path: stores an RxPDO entry by slot id from its raw value.
    pub fn set_rx_raw(&mut self, slot: u8, raw: u32) {
        let p = &mut self.params;
        match slot {
            0 => self.controlword = raw as u16,
            1 => self.set_mode(raw as u8 as i8),
            2 => p.following_error_window = raw,
            3 => p.position_window = raw,
            4 => p.max_torque = (raw as u16).min(3000),
            5 => p.target_position = raw as i32,
            6 => p.home_offset = raw as i32,
            7 => p.max_profile_velocity = raw.max(1),
            8 => p.profile_velocity = raw,
            9 => p.start_stop_speed = raw,
            10 => p.profile_acceleration = raw,
            11 => p.profile_deceleration = raw,
            12 => p.quick_stop_deceleration = raw,
            13 if homing::supported(raw as u8 as i8) => p.homing_method = raw as u8 as i8,
            14 => p.homing_speed_switch = raw,
            15 => p.homing_speed_zero = raw,
            16 => p.homing_acceleration = raw,
            17 => p.position_offset = raw as i32,
            18 => p.velocity_offset = raw as i32,
            19 => self.probe.set_function(raw as u16),
            20 => p.digital_outputs = raw,
            21 => p.target_velocity = raw as i32,
            _ => {}
        }
    }

    /// Cyclic path: the raw value of a TxPDO entry by slot id (0 for unknown slots).
    pub fn get_tx_raw(&self, slot: u8) -> u32 {
        match slot {
            0 => self.error_code as u32,
            1 => self.statusword as u32,
            2 => self.mode as u8 as u32,
            3 => self.motion.position() as u32,
            4 => self.raw_position as u32,
            5 => self.actual_position as u32,
            6 => self.motion.velocity() as i32 as u32,
            7 => self.actual_velocity as u32,
            8 => self.actual_torque as u16 as u32,
            9 => self.actual_current as u16 as u32,
            10 => self.probe.status() as u32,
            11 => self.probe.value(0) as u32,
            12 => self.probe.value(1) as u32,
            13 => self.probe.value(2) as u32,
            14 => self.probe.value(3) as u32,
            15 => self.following_error as u32,
            16 => self.position_demand_internal() as u32,
            17 => self.digital_inputs,
            _ => 0,
        }
    }

    /// Cyclic path: writes a TxPDO entry by slot id (little-endian, as many bytes as
    /// fit in `buf`, at most 4) and returns the number written.
    #[inline]
    pub fn get_tx(&self, slot: u8, buf: &mut [u8]) -> usize {
        let b = self.get_tx_raw(slot).to_le_bytes();
        let n = buf.len().min(4);
        buf[..n].copy_from_slice(&b[..n]);
        n
    }
}

/// The cyclic path of the stack: slots are the indices of [`RX_SLOTS`] / [`TX_SLOTS`].
/// (The drive's own `ProcessData` dispatches to these when it combines several
/// modules' objects.)
impl ecat_slave_stack::pdo::ProcessData for Cia402 {
    fn rx_slot(&self, index: u16, sub: u8) -> Option<u16> {
        rx_slot(index, sub).map(u16::from)
    }
    fn tx_slot(&self, index: u16, sub: u8) -> Option<u16> {
        tx_slot(index, sub).map(u16::from)
    }
    #[inline]
    fn set_rx(&mut self, slot: u16, raw: u64) {
        if let Ok(s) = u8::try_from(slot) {
            self.set_rx_raw(s, raw as u32);
        }
    }
    #[inline]
    fn get_tx(&self, slot: u16) -> u64 {
        u8::try_from(slot).map_or(0, |s| self.get_tx_raw(s) as u64)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use ecat_slave_stack::od::DefaultValue;

    #[test]
    fn table_is_well_formed_and_in_range() {
        assert!(od::is_well_formed(OBJECTS));
        assert!(OBJECTS.iter().all(|o| (0x6000..=0x6FFF).contains(&o.index)));
    }

    #[test]
    fn every_entry_has_a_value_and_defaults_match() {
        let d = Cia402::new();
        for o in OBJECTS {
            for e in o.entries() {
                let v = d.value(o.index, e.sub);
                assert!(v.is_some(), "{:#06x}:{}", o.index, e.sub);
                if let DefaultValue::Int(def) = e.default_value() {
                    assert_eq!(v, Some(def), "default of {:#06x}:{}", o.index, e.sub);
                    assert!(
                        def >= e.min() && def <= e.max(),
                        "default range {:#06x}:{}",
                        o.index,
                        e.sub
                    );
                }
            }
        }
    }

    #[test]
    fn slots_match_the_table() {
        for (i, &(idx, sub)) in RX_SLOTS.iter().enumerate() {
            let e = od::find_entry(OBJECTS, idx, sub).unwrap();
            assert!(e.pdo_mappable().rx(), "{idx:#06x}");
            assert_eq!(rx_slot(idx, sub), Some(i as u8));
        }
        for (i, &(idx, sub)) in TX_SLOTS.iter().enumerate() {
            let e = od::find_entry(OBJECTS, idx, sub).unwrap();
            assert!(e.pdo_mappable().tx(), "{idx:#06x}");
            assert_eq!(tx_slot(idx, sub), Some(i as u8));
        }
        // Every mappable entry has a slot.
        for o in OBJECTS {
            for e in o.entries() {
                assert_eq!(
                    e.pdo_mappable().rx(),
                    rx_slot(o.index, e.sub).is_some(),
                    "{:#06x}:{}",
                    o.index,
                    e.sub
                );
                assert_eq!(
                    e.pdo_mappable().tx(),
                    tx_slot(o.index, e.sub).is_some(),
                    "{:#06x}:{}",
                    o.index,
                    e.sub
                );
            }
        }
    }

    #[test]
    fn fields_cover_exactly_the_entries() {
        // Every entry of OBJECTS has one FIELDS row and every row is an entry.
        let mut n = 0;
        for o in OBJECTS {
            for e in o.entries() {
                let rows = FIELDS
                    .iter()
                    .filter(|f| f.index == o.index && f.sub == e.sub)
                    .count();
                assert_eq!(rows, 1, "{:#06x}:{}", o.index, e.sub);
                n += 1;
            }
        }
        assert_eq!(n, FIELDS.len());
        let d = Cia402::new();
        assert_eq!(d.value(0x6040, 1), None);
        assert_eq!(d.value(0x607D, 3), None);
        assert_eq!(d.value(0x6000, 0), None);
        assert_eq!(d.value(0x6FFF, 0), None);
    }

    #[test]
    fn sdo_write_changes_only_its_entry() {
        // Each writable entry at its most negative (or largest) value: the value reads
        // back sign-extended and no other entry changes (the field widths are right).
        let all = |d: &Cia402| -> std::vec::Vec<(u16, u8, Option<i64>)> {
            OBJECTS
                .iter()
                .flat_map(|o| o.entries().iter().map(move |e| (o.index, e.sub)))
                .map(|(i, s)| (i, s, d.value(i, s)))
                .collect()
        };
        for o in OBJECTS {
            for e in o.entries().iter().filter(|e| e.access.writable()) {
                let (idx, sub) = (o.index, e.sub);
                let val: i64 = match (idx, sub) {
                    (0x6060, 0) => 6,
                    (0x6098, 0) => 1,
                    (0x60B8, 0) => 0x0011,
                    (0x6086, 0) => 3,
                    (0x607E, 0) => 0xC0,
                    _ if e.min() < 0 => e.min(),
                    _ => e.max(),
                };
                let before = all(&Cia402::new());
                let d = written_and_read_back(e, idx, sub, val);
                for ((i, s, v0), (_, _, v1)) in before.iter().zip(all(&d).iter()) {
                    // The probe function also sets the probe status (enabled bits).
                    if (*i, *s) != (idx, sub) && !(idx == 0x60B8 && *i == 0x60B9) {
                        assert_eq!(v0, v1, "{idx:#06x}:{sub} changed {i:#06x}:{s}");
                    }
                }
            }
        }
    }

    #[test]
    fn every_writable_entry_reads_back_what_sdo_wrote() {
        for o in OBJECTS {
            for e in o.entries().iter().filter(|e| e.access.writable()) {
                let (idx, sub) = (o.index, e.sub);
                let val: i64 = match (idx, sub) {
                    (0x6060, 0) => 3,
                    (0x6098, 0) => 17,
                    (0x60B8, 0) => 0x0011,
                    (0x6086, 0) => 3,
                    (0x607E, 0) => 0x80,
                    _ => e.max().min(12_345),
                };
                written_and_read_back(e, idx, sub, val);
            }
        }
    }

    /// A new `Cia402` after an SDO write of `val` to `idx:sub`, checked to accept it and
    /// to read it back.
    fn written_and_read_back(e: &Entry, idx: u16, sub: u8, val: i64) -> Cia402 {
        let mut d = Cia402::new();
        let bytes = (val as u64).to_le_bytes();
        assert_eq!(
            d.write(idx, sub, &bytes[..e.byte_len()]),
            Ok(()),
            "{idx:#06x}:{sub}"
        );
        assert_eq!(d.value(idx, sub), Some(val), "{idx:#06x}:{sub}");
        d
    }

    #[test]
    fn rx_slots_and_sdo_write_agree() {
        // Writing each Rx slot and reading the entry back by SDO gives the same value.
        for (i, &(idx, sub)) in RX_SLOTS.iter().enumerate() {
            let e = od::find_entry(OBJECTS, idx, sub).unwrap();
            let val: i64 = match (idx, sub) {
                (0x6060, 0) => 3,
                (0x6098, 0) => 17,
                (0x60B8, 0) => 0x0011,
                (0x6072, 0) => 800,
                _ => e.max().min(12_345),
            };
            let mut d = Cia402::new();
            d.set_rx(i as u8, &(val as u32).to_le_bytes()[..e.byte_len()]);
            assert_eq!(d.value(idx, sub), Some(val), "{idx:#06x}:{sub}");
        }
    }

    #[test]
    fn tx_slots_and_sdo_read_agree() {
        let mut d = Cia402::new();
        let fb = crate::cia402::DriveFeedback {
            position: -1234,
            velocity: 777,
            torque: -55,
            current: 66,
            digital_inputs: 0x5,
            ..Default::default()
        };
        d.cycle(&fb, 0.001);
        for (i, &(idx, sub)) in TX_SLOTS.iter().enumerate() {
            let mut a = [0u8; 8];
            let n = d.read(idx, sub, &mut a).unwrap();
            let mut b = [0u8; 4];
            d.get_tx(i as u8, &mut b[..n]);
            assert_eq!(&a[..n], &b[..n], "{idx:#06x}:{sub}");
        }
    }

    #[test]
    fn stack_process_data_trait() {
        use ecat_slave_stack::pdo::ProcessData;
        let mut d = Cia402::new();
        let cw = ProcessData::rx_slot(&d, 0x6040, 0).unwrap();
        let m = ProcessData::rx_slot(&d, 0x6060, 0).unwrap();
        let t = ProcessData::rx_slot(&d, 0x607A, 0).unwrap();
        assert_eq!(ProcessData::rx_slot(&d, 0x6041, 0), None);
        assert_eq!(ProcessData::tx_slot(&d, 0x6040, 0), None);
        ProcessData::set_rx(&mut d, cw, 0x0006);
        ProcessData::set_rx(&mut d, m, 0xF8); // -8: not a mode, ignored
        ProcessData::set_rx(&mut d, m, 0x08);
        ProcessData::set_rx(&mut d, t, 0xFFFF_FFFE);
        ProcessData::set_rx(&mut d, 0x1234, 5); // unknown slot: ignored
        assert_eq!(d.value(0x6040, 0), Some(6));
        assert_eq!(d.value(0x6060, 0), Some(8));
        assert_eq!(d.value(0x607A, 0), Some(-2));
        d.cycle(
            &crate::cia402::DriveFeedback {
                position: -5,
                ..Default::default()
            },
            0.001,
        );
        let sw = ProcessData::tx_slot(&d, 0x6041, 0).unwrap();
        let pos = ProcessData::tx_slot(&d, 0x6064, 0).unwrap();
        assert_eq!(ProcessData::get_tx(&d, sw) as u16 & 0x6F, 0x21);
        assert_eq!(ProcessData::get_tx(&d, pos) as u32 as i32, -5);
        assert_eq!(ProcessData::get_tx(&d, 0x1234), 0);
    }

    #[test]
    fn sdo_errors() {
        let mut d = Cia402::new();
        let mut buf = [0u8; 4];
        assert_eq!(
            d.read(0x6000, 0, &mut buf),
            Err(SdoAbort::ObjectDoesNotExist)
        );
        assert_eq!(
            d.read(0x6040, 1, &mut buf),
            Err(SdoAbort::SubindexDoesNotExist)
        );
        assert_eq!(
            d.read(0x6064, 0, &mut buf[..2]),
            Err(SdoAbort::ExceedsMailbox)
        );
        assert_eq!(d.write(0x6041, 0, &[0, 0]), Err(SdoAbort::WriteReadOnly));
        assert_eq!(d.write(0x6040, 0, &[0]), Err(SdoAbort::LengthTooLow));
        assert_eq!(d.write(0x6040, 0, &[0, 0, 0]), Err(SdoAbort::LengthTooHigh));
        assert_eq!(d.write(0x6060, 0, &[2]), Err(SdoAbort::ValueRangeExceeded));
        assert_eq!(d.write(0x6060, 0, &[0xFF]), Err(SdoAbort::ValueTooLow));
        assert_eq!(d.write(0x6060, 0, &[10]), Err(SdoAbort::ValueTooHigh));
        assert_eq!(d.write(0x6098, 0, &[15]), Err(SdoAbort::ValueRangeExceeded));
        assert_eq!(d.write(0x6098, 0, &[36]), Err(SdoAbort::ValueRangeExceeded));
        assert_eq!(d.write(0x605A, 0, &[9, 0]), Err(SdoAbort::ValueTooHigh));
        assert_eq!(
            d.write(0x607E, 0, &[0x01]),
            Err(SdoAbort::ValueRangeExceeded)
        );
        assert_eq!(
            d.write(0x60B8, 0, &[0x08, 0]),
            Err(SdoAbort::ValueRangeExceeded)
        );
        assert_eq!(d.write(0x60C2, 2, &[0xF9]), Err(SdoAbort::ValueTooLow));
        assert_eq!(d.write(0x607D, 0, &[2]), Err(SdoAbort::WriteReadOnly));
        assert_eq!(
            d.write(0x6502, 0, &[0, 0, 0, 0]),
            Err(SdoAbort::WriteReadOnly)
        );
        // Rejected writes change nothing.
        assert_eq!(d.value(0x6060, 0), Some(0));
        assert_eq!(d.value(0x6098, 0), Some(37));
        // Good writes.
        d.write(0x6060, 0, &[8]).unwrap();
        d.write(0x607D, 1, &(-1000i32).to_le_bytes()).unwrap();
        assert_eq!(d.value(0x607D, 1), Some(-1000));
        assert_eq!(d.read(0x6502, 0, &mut buf), Ok(4));
        assert_eq!(u32::from_le_bytes(buf), 0x1A5);
    }

    #[test]
    fn garbage_writes_never_panic() {
        let mut d = Cia402::new();
        let mut x: u32 = 0x1234_5678;
        for o in OBJECTS {
            for e in o.entries() {
                for len in 0..6 {
                    for _ in 0..20 {
                        x ^= x << 13;
                        x ^= x >> 17;
                        x ^= x << 5;
                        let data = x.to_le_bytes();
                        let mut buf = [0u8; 8];
                        let d5 = [data[0], data[1], data[2], data[3], 0xAA];
                        let _ = d.write(o.index, e.sub, &d5[..len.min(5)]);
                        let _ = d.read(o.index, e.sub, &mut buf);
                    }
                }
            }
        }
        for slot in 0..=255u8 {
            d.set_rx(slot, &[0xFF, 0xFF, 0xFF, 0xFF]);
            d.set_rx(slot, &[]);
            let mut b = [0u8; 2];
            d.get_tx(slot, &mut b);
        }
        for _ in 0..100 {
            d.cycle(&crate::cia402::DriveFeedback::default(), 0.001);
        }
    }
}
