//! Vendor parameters 0x2000-0x2165 (`docs/object-dictionary.md`; 0x2156, the
//! anti-resonance damping 0x2059, the stall detection 0x2060-0x2063, and
//! 0x2160-0x2165 of the servo tune, `servo_tune`): the one table of their
//! access, default, range, unit and saved flag, and the values.
//!
//! The generic SDO checks (`od::check_write`) refuse out-of-range writes from this
//! table with 0x06090031 / 0x06090032; the dictionary's write repeats them (the
//! storage restore path also comes there) and the `Values` binding adds the product rules:
//!
//! * 0x2015 / 0x2016 (current Kp / Ki) are read-only while 0x2013 (auto-tune at
//!   power-up) is 1: a write is refused with **0x08000021** ("cannot be stored because
//!   of local control": the auto-tune owns the value). The entries stay `rw` in the
//!   static description because the lock depends on another value.
//! * 0x2040 / 0x2042: writing 1 clears the 32-bit received-pulse / encoder counter
//!   (0x2039/0x2040 and 0x2041/0x2042 are its high and low 16 bits); 0 does nothing.
//! * 0x2093 (fault clear record): writing 1 requests clearing the fault history
//!   (0x2400-0x2406); it reads 1 until the application took the request
//!   ([`Params::take_fault_history_clear`]), then 0.
//! * 0x2001, 0x2150, 0x2151 take effect after a restart: SDO reads and writes see the
//!   *pending* value, the drive uses the *active* copy latched by
//!   [`Params::latch_power_up`] ([`ActiveConfig`]).
//! * 0x2024 = 2 (closed loop) is refused with 0x06090031 on the open-loop variant.
//! * 0x2022 (current-sensing calibration) is filled by the drive from the power-up
//!   auto-tune's report ([`Params::set_calibration`]); read-only, not saved.
//! * 0x2155 (raw input levels) is filled by the I/O module ([`Params::set_raw_inputs`]).
//! * 0x2063 (estimated load angle) is filled by the drive from the motion layer's
//!   stall detector ([`Params::set_load_angle`]).
//! * 0x2162:01 (servo tune start/stop) is a command the drive carries out at once
//!   after the write ([`Params::take_servo_tune_request`], `Drive::write`,
//!   `servo_tune::TuneControl`: a refusal is the write's abort); it reads 1
//!   while a tune runs. 0x2162:02, 0x2164 and 0x2165 are the tune's state and result
//!   ([`Params::set_servo_tune`]).
//! * 0x2156 (ours) keeps the station number entered on a single-bank DIP board (SW8
//!   ON → SW1-SW7 → SW8 OFF, see [`crate::dip::SingleBank`]); the application sets it
//!   with [`Params::set_internal`] and stores it with a save. It is the DIP address from
//!   the next power-up.

use ecat_slave_stack::od::{
    Access, DataType, DefaultValue, Entry, EntryDesc, ObjectDesc, ObjectKey, PdoMappable, SdoAbort,
    Values,
};

use crate::identity::Variant;

/// A saved read-write entry: range `min..=max`, default `def`, unit `unit`.
const fn rws(
    sub: u8,
    name: &'static str,
    t: DataType,
    def: i64,
    min: i64,
    max: i64,
    unit: &'static str,
) -> EntryDesc {
    EntryDesc::new(sub, name, t, Access::RW)
        .range(min, max)
        .default(def)
        .unit(unit)
        .saved()
}

use DataType::{Integer16 as I16, Unsigned16 as U16, Unsigned32 as U32, Unsigned8 as U8};

/// Generates [`OBJECTS`], [`Param`] and [`KEYS`] from the table below: per object
/// `index code "name", "description" { slot = entry, .. }`, where `slot` is the
/// [`Param`] variant holding the entry's value in [`Params`], or `_` for entries
/// without a stored value (counts and the run-time values of the `Values` binding).
macro_rules! vendor_params {
    ($($index:literal $code:ident $name:literal, $description:literal {
        $($slot:tt = $entry:expr,)*
    })*) => {
        /// The vendor parameter objects, sorted by index.
        pub const OBJECTS: &[ObjectDesc] = &[
            $(ObjectDesc::$code($index, $name, &[$($entry),*], $description),)*
        ];
        param_slots!([] [] [] $($(($index, $slot, $entry))*)*);
    };
}

/// Collects the entries with a value slot into [`Param`], [`KEYS`] and `LIMITS` (same
/// order).
macro_rules! param_slots {
    ([$($variant:ident)*] [$($key:expr,)*] [$($limit:expr,)*]) => {
        /// One stored vendor parameter (the ones with a value slot in [`Params`]),
        /// named after its object; the order is that of [`KEYS`].
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        #[repr(u8)]
        #[allow(missing_docs)]
        pub enum Param {
            $($variant,)*
        }

        /// (index, sub-index) of each [`Param`], in the same order.
        pub const KEYS: [(u16, u8); [$(Param::$variant),*].len()] = [$($key,)*];

        /// `[min, max, default]` of each [`Param`] from its entry, for the values set
        /// inside the drive (made at compile time; a `static`, so that the defaults are
        /// copied in a loop rather than written one by one).
        static LIMITS: [[u16; 3]; KEYS.len()] = [$($limit,)*];
    };
    ([$($variant:ident)*] [$($key:expr,)*] [$($limit:expr,)*] ($index:literal, _, $entry:expr)
        $($rest:tt)*) => {
        param_slots!([$($variant)*] [$($key,)*] [$($limit,)*] $($rest)*);
    };
    ([$($variant:ident)*] [$($key:expr,)*] [$($limit:expr,)*] ($index:literal, $slot:ident,
        $entry:expr) $($rest:tt)*) => {
        param_slots!([$($variant)* $slot] [$($key,)* ($index, $entry.sub()),]
            [$($limit,)* limits(&$entry),] $($rest)*);
    };
}

/// `[min, max, default]` of a stored parameter's entry; every one fits 16 bits
/// (checked at compile time).
const fn limits(e: &EntryDesc) -> [u16; 3] {
    let def = match e.default_value() {
        DefaultValue::Int(v) => v,
        _ => 0,
    };
    assert!(
        fits16(e.min()) && fits16(e.max()) && fits16(def),
        "vendor parameter outside 0..=65535"
    );
    [e.min() as u16, e.max() as u16, def as u16]
}

const fn fits16(v: i64) -> bool {
    v >= 0 && v <= u16::MAX as i64
}

vendor_params! {
    0x2000 var "Peak current",
        "Peak phase current while running (at most 8400 mA on ECS-OL, 8000 mA on ECS-HS); RxPDO-mappable: a mapped value the SDO write would refuse is not taken over" {
        PeakCurrent = rws(0, "Peak current", U16, 3200, 1, 8400, "mA").pdo(PdoMappable::Rx),
    }
    0x2001 var "Pulses per revolution",
        "Command units per motor revolution; effective after restart" {
        PulsesPerRev = rws(0, "Pulses per revolution", U32, 50000, 200, 51200, "inc/rev"),
    }
    0x2002 var "Stand-by time",
        "Time without motion before the holding current applies" {
        StandbyTime = rws(0, "Stand-by time", U16, 500, 100, 10000, "ms"),
    }
    0x2005 array "Output function",
        "bit0 alarm, bit1 ready, bit2 in-position, bit3 brake released, bit4 operation enabled; 0 = driven by 0x60FE only" {
        _ = EntryDesc::count(3),
        Out1Function = rws(1, "Output 1 function", U16, 1, 0, 31, ""),
        Out2Function = rws(2, "Output 2 function", U16, 1, 0, 31, ""),
        Out3Function = rws(3, "Output 3 function", U16, 0, 0, 31, ""),
    }
    0x2008 var "Output level",
        "bit n = 1: output n+1 is active-high" {
        OutputLevel = rws(0, "Output level", U8, 4, 0, 7, ""),
    }
    0x2009 var "Command filter enable",
        "Command smoothing filter on/off" {
        CmdFilterEnable = rws(0, "Command filter enable", U8, 0, 0, 1, ""),
    }
    0x2010 record "Command filter",
        "Command smoothing filter time (sub-index 1 is not used)" {
        _ = EntryDesc::count(2),
        CmdFilterTime = rws(2, "Command filter time", U16, 1000, 50, 25600, "us"),
    }
    0x2013 var "Current loop auto-tune",
        "Measure R and L and compute the current gains at power-up" {
        AutoTune = rws(0, "Current loop auto-tune", U8, 1, 0, 1, ""),
    }
    0x2015 var "Current Kp",
        "Current loop proportional gain; read-only while 0x2013 = 1" {
        CurrentKp = rws(0, "Current Kp", U16, 1000, 200, 32767, ""),
    }
    0x2016 var "Current Ki",
        "Current loop integral gain; read-only while 0x2013 = 1" {
        CurrentKi = rws(0, "Current Ki", U16, 200, 0, 32767, ""),
    }
    0x2017 var "Current Kc",
        "Current loop anti-windup gain (read-only)" {
        CurrentKc = EntryDesc::new(0, "Current Kc", U16, Access::RO).range(80, 300).default(100),
    }
    0x2020 var "Motor resistance",
        "Phase resistance (auto-tune fills it)" {
        MotorResistance = rws(0, "Motor resistance", U16, 1000, 1, 20000, "mOhm"),
    }
    0x2021 var "Motor inductance",
        "Phase inductance (auto-tune fills it)" {
        MotorInductance = rws(0, "Motor inductance", U16, 1, 1, 6000, "uH"),
    }
    0x2022 record "Current sensing calibration",
        "Measured by the power-up auto-tune: channel B gain in 1/10000 of A's, offsets, dead-time loss, L at half the test current (0 until a tune has finished)" {
        _ = EntryDesc::count(5),
        _ = EntryDesc::new(1, "Channel B gain", U16, Access::RO).default(0),
        _ = EntryDesc::new(2, "Offset A", I16, Access::RO).unit("mA").default(0),
        _ = EntryDesc::new(3, "Offset B", I16, Access::RO).unit("mA").default(0),
        _ = EntryDesc::new(4, "Dead-time loss", U16, Access::RO).unit("mV").default(0),
        _ = EntryDesc::new(5, "Inductance at half test current", U16, Access::RO).unit("uH").default(0),
    }
    0x2024 var "Loop mode",
        "1 open loop, 2 closed loop" {
        LoopMode = rws(0, "Loop mode", U8, 2, 1, 2, ""),
    }
    0x2025 var "Control mode",
        "0 DIP, 1 lead, 2 PM, 3 FOC, 4 self-test, 5 closed loop" {
        ControlMode = rws(0, "Control mode", U8, 5, 0, 5, ""),
    }
    0x2026 var "Holding current",
        "Stand-still current in % of peak (open loop)" {
        HoldingCurrent = rws(0, "Holding current", U8, 50, 0, 100, "%"),
    }
    0x2029 var "Encoder resolution",
        "Encoder lines per revolution" {
        EncoderResolution = rws(0, "Encoder resolution", U16, 1000, 200, 60000, "lines/rev"),
    }
    0x2030 var "Following error limit",
        "Position following error limit in encoder counts (fault, 7 flashes)" {
        FollowingErrorLimit = rws(0, "Following error limit", U16, 1000, 1, 60000, "inc"),
    }
    0x2039 var "Command pulses high",
        "Received command pulses, bits 16-31" {
        _ = EntryDesc::new(0, "Command pulses high", U16, Access::RO).pdo(PdoMappable::Tx).default(0),
    }
    0x2040 var "Command pulses low",
        "Received command pulses, bits 0-15; write 1 clears the counter" {
        _ = EntryDesc::new(0, "Command pulses low", U16, Access::RW).range(0, 1).pdo(PdoMappable::Tx).default(0),
    }
    0x2041 var "Encoder counts high",
        "Encoder feedback counts, bits 16-31" {
        _ = EntryDesc::new(0, "Encoder counts high", U16, Access::RO).pdo(PdoMappable::Tx).default(0),
    }
    0x2042 var "Encoder counts low",
        "Encoder feedback counts, bits 0-15; write 1 clears the counter" {
        _ = EntryDesc::new(0, "Encoder counts low", U16, Access::RW).range(0, 1).pdo(PdoMappable::Tx).default(0),
    }
    0x2051 var "Direction reversal",
        "1 reverses the motor direction" {
        DirectionReversal = rws(0, "Direction reversal", U8, 0, 0, 1, ""),
    }
    0x2053 var "In-position output level",
        "1: an in-position output is active-high" {
        InPositionLevel = rws(0, "In-position output level", U8, 0, 0, 1, ""),
    }
    0x2054 var "Over-voltage threshold",
        "Bus voltage above which the over-voltage fault 0x3210 is raised (the power stage's own trip stays at 55 V)" {
        OverVoltageThreshold = rws(0, "Over-voltage threshold", U16, 55, 20, 55, "V"),
    }
    0x2055 var "Under-voltage threshold",
        "Bus voltage below which the under-voltage fault 0x3220 is raised once the bus has been above it; 0 switches the detection off (as does 0x2056 bit 6)" {
        UnderVoltageThreshold = rws(0, "Under-voltage threshold", U16, 12, 0, 20, "V"),
    }
    0x2056 var "Fault detection mask",
        "bit = 1 enables the detection (see faults module)" {
        FaultMask = rws(0, "Fault detection mask", U16, 0x00C3, 0, 0xFFFF, ""),
    }
    0x2057 var "Fault clear allowed",
        "1: latched faults may be cleared without a power cycle" {
        FaultClearAllowed = rws(0, "Fault clear allowed", U8, 0, 0, 1, ""),
    }
    0x2058 var "Current soft-start",
        "Current ramp on enable" {
        SoftStart = rws(0, "Current soft-start", U16, 1, 0, 10000, "50us"),
    }
    0x2059 var "Anti-resonance damping",
        "Open-loop damping gain Kd (foc::damping): the command angle advances by Kd times the speed error estimated from the back-EMF; 0 off" {
        ResonanceDamping = rws(0, "Anti-resonance damping", U16, 1000, 0, 5000, "us"),
    }
    0x2060 var "Stall detection enable",
        "Open loop: 1 detects the loss of synchronism from the back-EMF the current loop sees (inactive below 1 rev/s, where the back-EMF is of the order of the model's errors)" {
        StallEnable = rws(0, "Stall detection enable", U8, 0, 0, 1, ""),
    }
    0x2061 var "Stall detection sensitivity",
        "Trip when the in-phase back-EMF stays below this % of Ke times the command speed for a quarter of an electrical period; higher values trip at a smaller load angle, acos(x/100)" {
        StallSensitivity = rws(0, "Stall detection sensitivity", U8, 30, 5, 90, "%"),
    }
    0x2062 var "Stall reaction",
        "0 fault 0x7121 motor blocked (emergency, fault reaction 0x605E), 1 quick stop (0x605A); during stall homing (0x6098 = -1, -2) the stall sets the home position instead" {
        StallReaction = rws(0, "Stall reaction", U8, 0, 0, 1, ""),
    }
    0x2063 var "Estimated load angle",
        "Open loop: load angle estimated from the back-EMF, in the direction of motion (positive: the rotor lags); 0 while the stall detection is inactive" {
        _ = EntryDesc::new(0, "Estimated load angle", I16, Access::RO).pdo(PdoMappable::Tx).unit("0.1°").default(0),
    }
    0x2083 var "Power-up wiggle",
        "Angle alignment by a small shaft movement at power-up" {
        PowerUpWiggle = rws(0, "Power-up wiggle", U8, 0, 0, 1, ""),
    }
    0x2093 var "Fault clear record",
        "Write 1: clear the fault history" {
        _ = EntryDesc::new(0, "Fault clear record", U8, Access::RW).range(0, 1).default(0),
    }
    0x2137 var "Position loop Kp",
        "Position loop proportional gain" {
        PosKp = rws(0, "Position loop Kp", U16, 120, 0, 150, ""),
    }
    0x2138 var "Position loop Ki",
        "Position loop integral gain" {
        PosKi = rws(0, "Position loop Ki", U16, 50, 0, 150, ""),
    }
    0x2139 var "Velocity feed-forward",
        "Velocity feed-forward gain" {
        VelFf = rws(0, "Velocity feed-forward", U16, 70, 0, 150, ""),
    }
    0x2140 var "Speed loop Kp",
        "Speed loop proportional gain" {
        SpeedKp = rws(0, "Speed loop Kp", U16, 60, 0, 150, ""),
    }
    0x2150 var "Station alias",
        "Station alias used when 0x2151 = 1; effective after restart" {
        AliasValue = rws(0, "Station alias", U16, 1, 1, 65535, ""),
    }
    0x2151 var "Alias source",
        "0 DIP (DIP 0: SII word 4), 1 object 0x2150; effective after restart" {
        AliasSource = rws(0, "Alias source", U8, 0, 0, 1, ""),
    }
    0x2152 array "Input function",
        "1 home, 2 limit-, 4 limit+, 8 fault clear, 16 quick stop, 32 probe" {
        _ = EntryDesc::count(5),
        In1Function = rws(1, "Input 1 function", U16, 1, 0, 0xFFFF, ""),
        In2Function = rws(2, "Input 2 function", U16, 2, 0, 0xFFFF, ""),
        In3Function = rws(3, "Input 3 function", U16, 4, 0, 0xFFFF, ""),
        In4Function = rws(4, "Input 4 function", U16, 8, 0, 0xFFFF, ""),
        In5Function = rws(5, "Input 5 function", U16, 0, 0, 0xFFFF, ""),
    }
    0x2153 array "Input filter",
        "Digital input filter time" {
        _ = EntryDesc::count(5),
        In1Filter = rws(1, "Input 1 filter", U16, 20, 1, 60000, "50us"),
        In2Filter = rws(2, "Input 2 filter", U16, 20, 1, 60000, "50us"),
        In3Filter = rws(3, "Input 3 filter", U16, 20, 1, 60000, "50us"),
        In4Filter = rws(4, "Input 4 filter", U16, 20, 1, 60000, "50us"),
        In5Filter = rws(5, "Input 5 filter", U16, 20, 1, 60000, "50us"),
    }
    0x2154 var "Input polarity",
        "bit n inverts input n+1" {
        InputPolarity = rws(0, "Input polarity", U8, 0, 0, 0x1F, ""),
    }
    0x2155 var "Input raw levels",
        "bit n = electrical level of input n+1" {
        _ = EntryDesc::new(0, "Input raw levels", U8, Access::RO).pdo(PdoMappable::Tx),
    }
    0x2156 var "Stored DIP station number",
        "Station number entered with SW8 on single-bank boards (0 = none); effective after restart" {
        DipStation = rws(0, "Stored DIP station number", U16, 0, 0, 127, ""),
    }
    0x2157 var "Output state",
        "Pin levels as driven: bit0-2 OUT1-OUT3, bit 8 brake released, bit 9 green LED, bit 10 red LED, bit 11 RUN LED, bit 12 ERR LED" {
        _ = EntryDesc::new(0, "Output state", U16, Access::RO).pdo(PdoMappable::Tx),
    }
    0x2158 record "DIP switches",
        "Switch positions read at power-up (bit n = switch n+1 ON) and the motor settings in effect (from the function switches when 0x2025 = 0)" {
        _ = EntryDesc::count(7),
        _ = EntryDesc::new(1, "ID bank", U8, Access::RO),
        _ = EntryDesc::new(2, "Function bank", U8, Access::RO),
        _ = EntryDesc::new(3, "Station address from the switches", U16, Access::RO),
        _ = EntryDesc::new(4, "Peak current in effect", U16, Access::RO).unit("mA"),
        _ = EntryDesc::new(5, "Holding current in effect", U8, Access::RO).unit("%"),
        _ = EntryDesc::new(6, "Direction reversed in effect", U8, Access::RO),
        _ = EntryDesc::new(7, "Command smoothing in effect", U32, Access::RO).unit("us"),
    }
    0x2159 var "Brake release delay",
        "Time the power stage must have been on before the brake output releases" {
        BrakeReleaseDelay = rws(0, "Brake release delay", U16, 0, 0, 2000, "ms"),
    }
    0x215A var "Brake close delay",
        "Time the motor keeps holding at standstill after the brake output engages, before the power stage goes off" {
        BrakeCloseDelay = rws(0, "Brake close delay", U16, 0, 0, 2000, "ms"),
    }
    0x2160 var "Load inertia ratio",
        "Load inertia in % of the rotor inertia; the servo base gains use J·(1 + ratio)" {
        LoadInertiaRatio = rws(0, "Load inertia ratio", U16, 0, 0, 5000, "%"),
    }
    0x2161 var "Stiffness",
        "Velocity-loop bandwidth level the servo tune sets 0x2137-0x2140 for (1 = 20 Hz .. 16 = 400 Hz)" {
        Stiffness = rws(0, "Stiffness", U8, 12, 1, 16, ""),
    }
    0x2162 record "Servo tune",
        "Identification move in closed loop (Operation enabled, PP or CSP, at rest): 1 starts, 0 stops; state 0 idle, 1 running, 2 done, 3 refused, 4 failed" {
        _ = EntryDesc::count(2),
        _ = EntryDesc::new(1, "Start", U8, Access::RW).range(0, 1).default(0),
        _ = EntryDesc::new(2, "State", U8, Access::RO).default(0),
    }
    0x2163 var "Servo tune travel",
        "Stroke of the identification move from the start position in the positive direction, 0.1° of the motor shaft" {
        TuneTravel = rws(0, "Servo tune travel", U16, 900, 100, 36000, "0.1°"),
    }
    0x2164 var "Identified inertia ratio",
        "Load inertia the last servo tune found, % of the rotor inertia (also written to 0x2160)" {
        _ = EntryDesc::new(0, "Identified inertia ratio", U16, Access::RO).unit("%").default(0),
    }
    0x2165 var "Identified friction",
        "Coulomb friction torque the last servo tune found" {
        _ = EntryDesc::new(0, "Identified friction", U16, Access::RO).unit("mN·m").default(0),
    }
}

/// Short alias of [`Param`], used by the board glue and the integration tests.
pub use Param as P;

const N: usize = KEYS.len();

pub(crate) fn slot_of(index: u16, sub: u8) -> Option<usize> {
    KEYS.binary_search(&(index, sub)).ok()
}

/// Values that only take effect at power-up (latched by [`Params::latch_power_up`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ActiveConfig {
    /// 0x2001 in effect.
    pub pulses_per_rev: u32,
    /// 0x2150 in effect.
    pub alias_value: u16,
    /// 0x2151 in effect.
    pub alias_source: u8,
}

/// The DIP switches as read at power-up and what they select (0x2158).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DipReading {
    /// ID bank, bit n = switch n+1 ON (0 on a single-bank board).
    pub id_bits: u8,
    /// Function (or single) bank, bit n = switch n+1 ON.
    pub function_bits: u8,
    /// Station address the switches give (0 = none).
    pub address: u16,
    /// The function switches' selection (`None`: the board has none in this position).
    pub functions: Option<crate::dip::DipFunctions>,
}

/// The vendor parameter values plus the few run-time values of the vendor range.
#[derive(Debug, Clone)]
pub struct Params {
    variant: Variant,
    values: [i32; N],
    active: ActiveConfig,
    raw_inputs: u8,
    output_state: u16,
    dip: DipReading,
    load_angle_ddeg: i16,
    command_pulses: u32,
    encoder_counts: u32,
    fault_history_clear: bool,
    calibration: Calibration,
    servo_tune: ServoTuneValues,
    servo_tune_request: Option<bool>,
}

/// The run-time values of 0x2162-0x2165.
#[derive(Debug, Clone, Copy, Default)]
struct ServoTuneValues {
    state: u8,
    ratio_percent: u16,
    friction_mnm: u16,
}

impl Params {
    /// All parameters at their defaults for `variant` (0x2024 follows the variant);
    /// the active copy equals the defaults.
    pub fn new(variant: Variant) -> Self {
        let mut values = [0i32; N];
        for (v, [_, _, def]) in values.iter_mut().zip(&LIMITS) {
            *v = i32::from(*def);
        }
        values[Param::LoopMode as usize] = i32::from(variant.default_loop_mode());
        let mut p = Params {
            variant,
            values,
            active: ActiveConfig {
                pulses_per_rev: 0,
                alias_value: 0,
                alias_source: 0,
            },
            raw_inputs: 0,
            output_state: 0,
            dip: DipReading::default(),
            load_angle_ddeg: 0,
            command_pulses: 0,
            encoder_counts: 0,
            fault_history_clear: false,
            calibration: Calibration::default(),
            servo_tune: ServoTuneValues::default(),
            servo_tune_request: None,
        };
        p.latch_power_up();
        p
    }

    /// The variant these parameters belong to.
    pub fn variant(&self) -> Variant {
        self.variant
    }

    /// Puts every stored parameter back to its default (RAM only; the flash record is
    /// handled by the storage module).
    pub fn restore_defaults(&mut self) {
        let fresh = Params::new(self.variant);
        self.values = fresh.values;
    }

    /// Copies the "effective after restart" parameters into the active set. Call once
    /// at power-up, after the stored record was loaded.
    pub fn latch_power_up(&mut self) {
        self.active = ActiveConfig {
            pulses_per_rev: self.get(Param::PulsesPerRev) as u32,
            alias_value: self.get(Param::AliasValue) as u16,
            alias_source: self.get(Param::AliasSource) as u8,
        };
    }

    /// The values in effect for the "after restart" parameters.
    pub fn active(&self) -> ActiveConfig {
        self.active
    }

    /// Current (pending) value of a parameter.
    pub fn get(&self, p: Param) -> i32 {
        self.values[p as usize]
    }

    /// Sets a parameter from inside the drive (auto-tune results, DIP values), clamped
    /// to the table range. Not subject to the SDO rules (auto-tune lock).
    pub fn set_internal(&mut self, p: Param, value: i32) {
        let [min, max, _] = LIMITS[p as usize];
        // max/min rather than clamp: clamp's min > max panic would bring core::fmt's
        // integer formatting into the image (the table keeps min ≤ max).
        self.values[p as usize] = value.max(i32::from(min)).min(i32::from(max));
    }

    /// Input function bits of input `n` (0-based, 0..5).
    pub fn input_function(&self, n: usize) -> u16 {
        const F: [Param; 5] = [
            Param::In1Function,
            Param::In2Function,
            Param::In3Function,
            Param::In4Function,
            Param::In5Function,
        ];
        F.get(n).map_or(0, |&p| self.get(p) as u16)
    }

    /// Input filter of input `n` in 50 µs units.
    pub fn input_filter(&self, n: usize) -> u16 {
        const F: [Param; 5] = [
            Param::In1Filter,
            Param::In2Filter,
            Param::In3Filter,
            Param::In4Filter,
            Param::In5Filter,
        ];
        F.get(n).map_or(1, |&p| self.get(p) as u16)
    }

    /// Sets the raw input levels reported by 0x2155.
    pub fn set_raw_inputs(&mut self, levels: u8) {
        self.raw_inputs = levels & 0x1F;
    }

    /// Sets the pin levels reported by 0x2157 (bit 0-2 OUT1-OUT3, bit 8 brake
    /// released, bits 9-12 the green, red, RUN and ERR LEDs).
    pub fn set_output_state(&mut self, state: u16) {
        self.output_state = state;
    }

    /// The pin levels reported by 0x2157.
    pub fn output_state(&self) -> u16 {
        self.output_state
    }

    /// Latches the DIP switches read at power-up (0x2158): from now on
    /// [`Params::settings`] takes the motor settings from the function switches while
    /// 0x2025 = 0.
    pub fn set_dip(&mut self, dip: DipReading) {
        self.dip = dip;
    }

    /// The DIP switches latched at power-up.
    pub fn dip(&self) -> DipReading {
        self.dip
    }

    /// The motor settings in effect (peak and holding current, direction, command
    /// smoothing): the function switches' when 0x2025 = 0 and the board has function
    /// switches in that position, otherwise the objects' ([`Params::settings_with`]).
    /// Everything that uses these settings reads them here.
    pub fn settings(&self) -> crate::dip::Settings {
        self.settings_with(self.dip.functions)
    }

    /// Chooses between the parameters and the DIP functions (`dip`: what
    /// `dip::power_up` read; `None` when the board has none or is in station entry).
    pub fn settings_with(&self, dip: Option<crate::dip::DipFunctions>) -> crate::dip::Settings {
        use crate::dip::{Settings, Standstill};
        let p = self;
        match dip {
            Some(f) if p.get(Param::ControlMode) == 0 => Settings {
                peak_current_ma: f.peak_current_ma,
                holding_percent: match f.standstill {
                    Standstill::Software => p.get(Param::HoldingCurrent) as u8,
                    Standstill::Full => 100,
                    Standstill::Half => 50,
                },
                direction_reversed: f.direction_cw,
                smoothing_us: f.smoothing_us,
            },
            _ => Settings {
                peak_current_ma: p.get(Param::PeakCurrent) as u16,
                holding_percent: p.get(Param::HoldingCurrent) as u8,
                direction_reversed: p.get(Param::DirectionReversal) == 1,
                smoothing_us: if p.get(Param::CmdFilterEnable) == 1 {
                    p.get(Param::CmdFilterTime) as u32
                } else {
                    0
                },
            },
        }
    }

    /// Sets the estimated load angle reported by 0x2063, 0.1° electrical.
    pub fn set_load_angle(&mut self, ddeg: i16) {
        self.load_angle_ddeg = ddeg;
    }

    /// Adds received command pulses (0x2039/0x2040).
    pub fn add_command_pulses(&mut self, delta: u32) {
        self.command_pulses = self.command_pulses.wrapping_add(delta);
    }

    /// Adds encoder feedback counts (0x2041/0x2042).
    pub fn add_encoder_counts(&mut self, delta: u32) {
        self.encoder_counts = self.encoder_counts.wrapping_add(delta);
    }

    /// Sets the current-sensing calibration reported by 0x2022.
    pub fn set_calibration(&mut self, c: Calibration) {
        self.calibration = c;
    }

    /// Sets the servo tune's state (0x2162:02) and, with a result, the identified
    /// inertia ratio (0x2164, %) and friction (0x2165, mN·m).
    pub fn set_servo_tune(&mut self, state: u8, result: Option<(u16, u16)>) {
        self.servo_tune.state = state;
        if let Some((ratio, friction)) = result {
            self.servo_tune.ratio_percent = ratio;
            self.servo_tune.friction_mnm = friction;
        }
    }

    /// The last write of 0x2162:01 (`true`: start, `false`: stop) not yet taken.
    pub fn take_servo_tune_request(&mut self) -> Option<bool> {
        self.servo_tune_request.take()
    }

    /// True once after 1 was written to 0x2093.
    pub fn take_fault_history_clear(&mut self) -> bool {
        core::mem::take(&mut self.fault_history_clear)
    }
}

/// The values of 0x2000-0x21FF: the stored parameters by their slot and the run-time
/// values (the counts of the arrays and records are their descriptions'). A write
/// has passed the entry's access, length and range checks; the rules of the module
/// docs follow.
impl Values for Params {
    fn get(&self, _: &(), key: ObjectKey, _: &Entry) -> Result<i64, SdoAbort> {
        let value: i64 = match (key.index, key.sub) {
            (0x2039, 0) => (self.command_pulses >> 16).into(),
            (0x2040, 0) => (self.command_pulses & 0xFFFF).into(),
            (0x2041, 0) => (self.encoder_counts >> 16).into(),
            (0x2042, 0) => (self.encoder_counts & 0xFFFF).into(),
            (0x2093, 0) => self.fault_history_clear.into(),
            (0x2155, 0) => self.raw_inputs.into(),
            (0x2157, 0) => self.output_state.into(),
            (0x2158, 1) => self.dip.id_bits.into(),
            (0x2158, 2) => self.dip.function_bits.into(),
            (0x2158, 3) => self.dip.address.into(),
            (0x2158, 4) => self.settings().peak_current_ma.into(),
            (0x2158, 5) => self.settings().holding_percent.into(),
            (0x2158, 6) => self.settings().direction_reversed.into(),
            (0x2158, 7) => self.settings().smoothing_us.into(),
            (0x2063, 0) => self.load_angle_ddeg.into(),
            (0x2162, 1) => (self.servo_tune.state == 1).into(),
            (0x2162, 2) => self.servo_tune.state.into(),
            (0x2164, 0) => self.servo_tune.ratio_percent.into(),
            (0x2165, 0) => self.servo_tune.friction_mnm.into(),
            (0x2022, 1) => self.calibration.gain_b_e4.into(),
            (0x2022, 2) => self.calibration.offset_ma[0].into(),
            (0x2022, 3) => self.calibration.offset_ma[1].into(),
            (0x2022, 4) => self.calibration.dead_time_mv.into(),
            (0x2022, 5) => self.calibration.l_low_uh.into(),
            (index, sub) => match slot_of(index, sub).and_then(|slot| self.values.get(slot)) {
                Some(&v) => v.into(),
                None => return Err(SdoAbort::SubindexDoesNotExist),
            },
        };
        Ok(value)
    }

    fn set(&mut self, _: &mut (), key: ObjectKey, _: &Entry, v: i64) -> Result<(), SdoAbort> {
        match (key.index, key.sub) {
            (0x2162, 1) => {
                self.servo_tune_request = Some(v == 1);
                return Ok(());
            }
            (0x2040, 0) => {
                if v == 1 {
                    self.command_pulses = 0;
                }
                return Ok(());
            }
            (0x2042, 0) => {
                if v == 1 {
                    self.encoder_counts = 0;
                }
                return Ok(());
            }
            (0x2093, 0) => {
                if v == 1 {
                    self.fault_history_clear = true;
                }
                return Ok(());
            }
            (0x2015, 0) | (0x2016, 0) if self.get(Param::AutoTune) == 1 => {
                return Err(SdoAbort::LocalControl);
            }
            (0x2024, 0) if v > i64::from(self.variant.max_loop_mode()) => {
                return Err(SdoAbort::ValueTooHigh);
            }
            (0x2000, 0) if v > i64::from(self.variant.max_peak_current_ma()) => {
                return Err(SdoAbort::ValueTooHigh);
            }
            _ => {}
        }
        let slot = slot_of(key.index, key.sub)
            .and_then(|slot| self.values.get_mut(slot))
            .ok_or(SdoAbort::SubindexDoesNotExist)?;
        *slot = v as i32;
        Ok(())
    }
}

/// The auto-tune's current-sensing calibration in the integer units of 0x2022.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Calibration {
    /// Channel B gain relative to channel A, 1/10000 (10000 = equal).
    pub gain_b_e4: u16,
    /// Channel offsets with the bridges switching (A, B), mA.
    pub offset_ma: [i16; 2],
    /// Dead-time voltage loss of the bridges, mV.
    pub dead_time_mv: u16,
    /// Inductance at half the test current (mean of both phases), µH.
    pub l_low_uh: u16,
}

impl Calibration {
    /// The offsets the loop adds to the start-up offsets, counts of `amps_per_count`
    /// (A per count; 0 without a scale).
    pub fn offset_trim(&self, amps_per_count: f32) -> [f32; 2] {
        if amps_per_count > 0.0 {
            self.offset_ma
                .map(|ma| f32::from(ma) * 1e-3 / amps_per_count)
        } else {
            [0.0; 2]
        }
    }

    /// Each channel's gain (A, B) from channel B's relative gain: both referred to
    /// their geometric mean (`foc::autotune`, "Channel gains"). `[1, 1]` before a tune.
    pub fn channel_gains(&self) -> [f32; 2] {
        if self.gain_b_e4 == 0 {
            return [1.0; 2];
        }
        let g = foc::num::sqrtf(f32::from(self.gain_b_e4) * 1e-4);
        [1.0 / g, g]
    }

    /// The integer form of a tune's results.
    pub fn from_tune(r: &foc::autotune::TuneResult) -> Self {
        let round = |x: f32, lo: f32, hi: f32| {
            if x.is_finite() {
                (x + 0.5 * x.signum()).clamp(lo, hi)
            } else {
                0.0
            }
        };
        let ma = |a: f32| round(a * 1e3, -32768.0, 32767.0) as i16;
        Calibration {
            gain_b_e4: round(r.gain_b * 1e4, 0.0, 65535.0) as u16,
            offset_ma: [ma(r.offset[0]), ma(r.offset[1])],
            dead_time_mv: round(r.dead_time_v * 1e3, 0.0, 65535.0) as u16,
            l_low_uh: round(0.5 * (r.l_low[0] + r.l_low[1]) * 1e6, 0.0, 65535.0) as u16,
        }
    }
}

#[cfg(test)]
mod tests;
