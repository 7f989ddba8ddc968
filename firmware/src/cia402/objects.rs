//! The CiA 402 objects (0x6000-0x6FFF) of the dictionary, described once in the table
//! at the end of this file. From it come the static descriptions ([`OBJECTS`]), the
//! `Values` binding of [`Cia402`] (SDO read and write), and the cyclic accessors by compact slot ids
//! ([`RX_SLOTS`], [`TX_SLOTS`]).
//!
//! Units: positions in command units ("inc", 0x2001 per motor revolution), velocities
//! in command units/s, accelerations in command units/s², torque and current in per
//! mille of the rated value, times in ms.
//!
//! # The table
//! One block per object: `code index "name", "description", { entries }`, each entry
//! in braces, either `count(n) range(lo, hi)` (sub-index 0 of an array or record) or
//!
//! ```text
//! sub "name": type access pdo [range(lo, hi)] [further Entry builders] binding
//! ```
//!
//! * `type` is the Rust integer type the value is held in; it gives the CANopen data
//!   type, and a field of another type does not compile.
//! * `pdo` is `RX`, `TX` or `NO`. RxPDO and TxPDO entries get consecutive slot ids in
//!   table order.
//! * `range` is the accepted SDO range; an RxPDO value stored straight into a `field`
//!   is clamped to it (a PDO write cannot be refused).
//! * The binding says where the value lives: `field(path)` (a field of [`Cia402`]),
//!   `get(|d| ..)` (computed, read-only unless a setter follows) or `constant(v)`;
//!   then optionally `set(|d, v| ..)` (replaces the plain store, for SDO and PDO) and
//!   `check(|d, v| ..)` (the object's own SDO rule after the range check, returning the
//!   abort code).

use super::{homing, mode_supported, probe, Cia402, Controlword, SUPPORTED_MODES};
use ecat_slave_stack::od::{
    Access, DataType, Entry, EntryDesc, ObjectDesc, ObjectKey, PdoMappable, SdoAbort, Values,
};

const RO: Access = Access::RO;
const RW: Access = Access::RW;
const RX: PdoMappable = PdoMappable::Rx;
const TX: PdoMappable = PdoMappable::Tx;
const NO: PdoMappable = PdoMappable::No;

/// An integer type a CiA 402 value is held in.
trait EntryInt: Copy + Ord {
    /// The CANopen data type of the entry.
    const DATA_TYPE: DataType;
    /// The value, sign- or zero-extended.
    fn to_i64(self) -> i64;
    /// The low bits of `v` (as `as` truncates).
    fn from_i64(v: i64) -> Self;
    /// The PDO image: the value's bytes, zero-extended to 32 bits.
    fn to_raw(self) -> u32;
    /// The low bits of a PDO raw value.
    fn from_raw(raw: u32) -> Self;
}

macro_rules! entry_int {
    ($($t:ty: $data_type:ident, $unsigned:ty;)*) => {$(
        #[allow(clippy::unnecessary_cast)]
        impl EntryInt for $t {
            const DATA_TYPE: DataType = DataType::$data_type;
            #[inline]
            fn to_i64(self) -> i64 {
                i64::from(self)
            }
            #[inline]
            fn from_i64(v: i64) -> Self {
                v as $t
            }
            #[inline]
            fn to_raw(self) -> u32 {
                u32::from(self as $unsigned)
            }
            #[inline]
            fn from_raw(raw: u32) -> Self {
                raw as $t
            }
        }
    )*};
}

entry_int! {
    i8: Integer8, u8;
    u8: Unsigned8, u8;
    i16: Integer16, u16;
    u16: Unsigned16, u16;
    i32: Integer32, u32;
    u32: Unsigned32, u32;
}

/// Calls a table getter (the bound gives the closure its argument type).
#[inline(always)]
fn call_get<T>(get: impl FnOnce(&Cia402) -> T, d: &Cia402) -> T {
    get(d)
}

/// Calls a table setter.
#[inline(always)]
fn call_set<T>(set: impl FnOnce(&mut Cia402, T), d: &mut Cia402, v: T) {
    set(d, v)
}

/// Calls a table check.
#[inline(always)]
fn call_check<T>(
    check: impl FnOnce(&Cia402, T) -> Result<(), SdoAbort>,
    d: &Cia402,
    v: T,
) -> Result<(), SdoAbort> {
    check(d, v)
}

/// `Ok` when `ok`, else "value range exceeded" (a value inside the type range that the
/// object does not accept).
fn valid_if(ok: bool) -> Result<(), SdoAbort> {
    if ok {
        Ok(())
    } else {
        Err(SdoAbort::ValueRangeExceeded)
    }
}

/// The [`EntryDesc`] of one table entry.
macro_rules! entry_description {
    (count($n:literal) $(range($lo:expr, $hi:expr))?) => {
        EntryDesc::count($n) $(.range($lo, $hi))?
    };
    ($sub:literal $name:literal: $t:ident $access:ident $pdo:ident
        $(range($lo:expr, $hi:expr))? [$($build:tt)*] $($binding:tt)*) => {
        EntryDesc::new($sub, $name, <$t as EntryInt>::DATA_TYPE, $access)
            .pdo($pdo)
            $(.range($lo as i64, $hi as i64))?
            $($build)*
    };
}

/// The sub-index of one table entry.
macro_rules! entry_sub {
    (count $($rest:tt)*) => {
        0
    };
    ($sub:literal $($rest:tt)*) => {
        $sub
    };
}

/// The value of one table entry, as its type.
macro_rules! entry_get {
    ($d:ident, count($n:literal) $($rest:tt)*) => {{
        let v: u8 = $n;
        v
    }};
    ($d:ident, $sub:literal $name:literal: $t:ident $access:ident $pdo:ident
        $(range($lo:expr, $hi:expr))? [$($build:tt)*] $($binding:tt)*) => {
        binding_get!($d, $t, $($binding)*)
    };
}

macro_rules! binding_get {
    ($d:ident, $t:ident, field($($field:ident).+) $($rest:tt)*) => {{
        let v: $t = $d.$($field).+;
        v
    }};
    ($d:ident, $t:ident, get($get:expr) $($rest:tt)*) => {{
        let v: $t = call_get($get, $d);
        v
    }};
    ($d:ident, $t:ident, constant($c:expr)) => {{
        let v: $t = $c;
        v
    }};
}

/// SDO write of one table entry: the entry's own check, then the store.
macro_rules! entry_write {
    ($d:ident, $v:ident, count $($rest:tt)*) => {
        Ok(())
    };
    ($d:ident, $v:ident, $sub:literal $name:literal: $t:ident $access:ident $pdo:ident
        $(range($lo:expr, $hi:expr))? [$($build:tt)*] $($binding:tt)*) => {{
        let v = <$t as EntryInt>::from_i64($v);
        binding_check!($d, v, $($binding)*)?;
        binding_set!($d, v, $($binding)*);
        Ok(())
    }};
}

macro_rules! binding_check {
    ($d:ident, $v:ident, $kind:ident($($arg:tt)*) $(set($set:expr))? check($check:expr)) => {
        call_check($check, $d, $v)
    };
    ($d:ident, $v:ident, $($rest:tt)*) => {
        Ok::<(), SdoAbort>(())
    };
}

/// Stores a value of the entry's type (SDO after the checks, PDO after the clamp).
macro_rules! binding_set {
    ($d:ident, $v:ident, $kind:ident($($arg:tt)*) set($set:expr) $($rest:tt)*) => {
        call_set($set, $d, $v)
    };
    ($d:ident, $v:ident, field($($field:ident).+) $($rest:tt)*) => {
        $d.$($field).+ = $v
    };
    ($d:ident, $v:ident, $($rest:tt)*) => {{
        let _ = $v;
    }};
}

/// One arm of the RxPDO store: slot `$i` if the entry is RxPDO-mappable.
macro_rules! entry_rx {
    ($d:ident, $slot:ident, $i:ident, $raw:ident, $sub:literal $name:literal: $t:ident
        $access:ident RX $(range($lo:expr, $hi:expr))? [$($build:tt)*] $($binding:tt)*) => {
        if $slot == $i {
            let v = <$t as EntryInt>::from_raw($raw);
            rx_value!(v, $t, [$($lo, $hi)?], $($binding)*);
            binding_set!($d, v, $($binding)*);
            return;
        }
        $i += 1;
    };
    ($d:ident, $slot:ident, $i:ident, $raw:ident, $($rest:tt)*) => {};
}

/// A PDO value stored into a plain field is clamped to the entry's range.
macro_rules! rx_value {
    ($v:ident, $t:ident, [$lo:expr, $hi:expr], field($($field:ident).+)) => {
        let $v = $v.clamp(
            <$t as EntryInt>::from_i64(i64::from($lo)),
            <$t as EntryInt>::from_i64(i64::from($hi)),
        );
    };
    ($v:ident, $t:ident, [$($range:tt)*], $($binding:tt)*) => {};
}

/// One arm of the TxPDO read: slot `$i` if the entry is TxPDO-mappable.
macro_rules! entry_tx {
    ($d:ident, $slot:ident, $i:ident, $sub:literal $name:literal: $t:ident
        $access:ident TX $(range($lo:expr, $hi:expr))? [$($build:tt)*] $($binding:tt)*) => {
        if $slot == $i {
            return EntryInt::to_raw(binding_get!($d, $t, $($binding)*));
        }
        $i += 1;
    };
    ($d:ident, $slot:ident, $i:ident, $($rest:tt)*) => {};
}

/// Generates [`OBJECTS`], [`ENTRY_KEYS`] and the accessors of [`Cia402`] from the table.
macro_rules! cia402_objects {
    ($($code:ident $index:literal $name:literal, $description:literal,
        { $({ $($entry:tt)* })* })*) => {
        /// The CiA 402 objects, sorted by index.
        // `range(lo, hi)` converts its bounds with `as i64` (`From` is not const).
        #[allow(clippy::unnecessary_cast)]
        pub const OBJECTS: &[ObjectDesc] = &[
            $(ObjectDesc::$code(
                $index,
                $name,
                &[$(entry_description!($($entry)*)),*],
                $description,
            ),)*
        ];

        /// `(index, sub-index)` of every entry of [`OBJECTS`], in table order: the
        /// position of an entry here selects its arm in the SDO accessors.
        const ENTRY_KEYS: &[(u16, u8)] = &[$($(($index, entry_sub!($($entry)*)),)*)*];

        impl Cia402 {
            /// Current value of an entry (sign-extended), `None` if the object/sub-index
            /// is not one of [`OBJECTS`].
            pub fn value(&self, index: u16, sub: u8) -> Option<i64> {
                let at = entry_position(index, sub)?;
                let d = self;
                let mut i = 0usize;
                $($(
                    if at == i {
                        return Some(EntryInt::to_i64(entry_get!(d, $($entry)*)));
                    }
                    i += 1;
                )*)*
                let _ = i;
                None
            }

            /// Checks an SDO value (already in the entry's type range) against the
            /// object's own rules and stores it.
            fn write_value(&mut self, index: u16, sub: u8, value: i64) -> Result<(), SdoAbort> {
                let Some(at) = entry_position(index, sub) else {
                    return Err(SdoAbort::SubindexDoesNotExist);
                };
                let d = self;
                let mut i = 0usize;
                $($(
                    if at == i {
                        return entry_write!(d, value, $($entry)*);
                    }
                    i += 1;
                )*)*
                let _ = i;
                Err(SdoAbort::SubindexDoesNotExist)
            }

            /// Cyclic path: stores an RxPDO entry by slot id (its position in
            /// [`RX_SLOTS`]) from its raw value. Unknown slots are ignored; values a
            /// field cannot take are clamped to the entry's range, and an unsupported
            /// mode or homing method is not taken over.
            pub fn set_rx_raw(&mut self, slot: u8, raw: u32) {
                let d = self;
                let mut i = 0u8;
                $($(entry_rx!(d, slot, i, raw, $($entry)*);)*)*
                let _ = (d, i);
            }

            /// Cyclic path: the raw value of a TxPDO entry by slot id (its position in
            /// [`TX_SLOTS`]); 0 for unknown slots.
            pub fn get_tx_raw(&self, slot: u8) -> u32 {
                let d = self;
                let mut i = 0u8;
                $($(entry_tx!(d, slot, i, $($entry)*);)*)*
                let _ = (d, i);
                0
            }
        }
    };
}

/// Position of `(index, sub)` in [`ENTRY_KEYS`].
fn entry_position(index: u16, sub: u8) -> Option<usize> {
    ENTRY_KEYS.iter().position(|&key| key == (index, sub))
}

/// A write of 0x6091-0x6093 (see [`super::scaling`]).
fn scale(d: &mut Cia402, index: u16, sub: u8, v: u32) {
    let increments = d.encoder_increments;
    d.scaling.set(index, sub, v, increments);
}

/// The little-endian value of the first (up to 4) bytes of `data`, zero-extended.
fn u32_from_le_prefix(data: &[u8]) -> u32 {
    let mut b = [0u8; 4];
    let n = data.len().min(4);
    b[..n].copy_from_slice(&data[..n]);
    u32::from_le_bytes(b)
}

/// The values of 0x6000-0x6FFF, bound by the table below: the dictionary's read and
/// write hand over the entry after the generic checks; the object's own rules follow.
impl Values for Cia402 {
    fn get(&self, _: &(), key: ObjectKey, _: &Entry) -> Result<i64, SdoAbort> {
        self.value(key.index, key.sub)
            .ok_or(SdoAbort::SubindexDoesNotExist)
    }

    fn set(&mut self, _: &mut (), key: ObjectKey, _: &Entry, v: i64) -> Result<(), SdoAbort> {
        self.write_value(key.index, key.sub, v)
    }
}

// The table. Sorted by index; see the module documentation for the columns.
cia402_objects! {
    var 0x6007 "Abort connection option code", "Reaction when the master's commands stop (SM watchdog, Op left, SYNC0 missing): 0 none (the last set-points stay), 1 fault (reaction 0x605E), 2 disable voltage, 3 quick stop (0x605A).",
    {
        { 0 "Abort connection option code": i16 RW NO range(0, 3) [.default(1).saved()] field(params.abort_connection_option) }
    }
    var 0x603F "Error code", "Code of the last fault (CiA 402 / CiA 301 error codes); 0 after a fault reset.",
    {
        { 0 "Error code": u16 RO TX [.default(0)] field(error_code) }
    }
    var 0x6040 "Controlword", "PDS commands (bits 0-3, 7 fault reset), mode-specific bits 4-6 and 9, bit 8 halt.",
    {
        { 0 "Controlword": u16 RW RX [.default(0)] get(|d| d.controlword.raw()) set(|d, v| d.controlword = Controlword::from_raw(v)) }
    }
    var 0x6041 "Statusword", "PDS state, voltage enabled, warning, remote, target reached, internal limit, mode bits, E5 bits 8/14/15.",
    {
        { 0 "Statusword": u16 RO TX [] get(|d| d.statusword.raw()) }
    }
    var 0x605A "Quick stop option code", "0 disable drive function; 1/2/3/4 slow-down / quick-stop / max-deceleration ramp then switch on disabled; 5-8 the same and stay in quick stop active.",
    {
        { 0 "Quick stop option code": i16 RW RX range(0, 8) [.default(2).saved()] field(params.quick_stop_option) }
    }
    var 0x605B "Shutdown option code", "Transition 8: 0 disable drive function; 1 slow down with 0x6084, then disable.",
    {
        { 0 "Shutdown option code": i16 RW NO range(0, 1) [.default(0).saved()] field(params.shutdown_option) }
    }
    var 0x605C "Disable operation option code", "Transition 5: 0 disable drive function; 1 slow down with 0x6084, then disable.",
    {
        { 0 "Disable operation option code": i16 RW NO range(0, 1) [.default(1).saved()] field(params.disable_op_option) }
    }
    var 0x605D "Halt option code", "Controlword bit 8: 1 slow-down ramp, 2 quick-stop ramp, 3/4 max-deceleration ramp; stays in operation enabled.",
    {
        { 0 "Halt option code": i16 RW NO range(1, 4) [.default(1).saved()] field(params.halt_option) }
    }
    var 0x605E "Fault reaction option code", "0 disable drive function; 1 slow-down ramp; 2 quick-stop ramp; 3/4 max-deceleration ramp.",
    {
        { 0 "Fault reaction option code": i16 RW NO range(0, 4) [.default(2).saved()] field(params.fault_reaction_option) }
    }
    var 0x6060 "Modes of operation", "Requested mode: 0 none, 1 PP, 3 PV, 4 PT, 6 HM, 8 CSP, 9 CSV, 10 CST (PT and CST closed loop only: refused with 0x06090030 while 0x6502 bit 9 is clear; an RxPDO value is not taken over).",
    {
        { 0 "Modes of operation": i8 RW RX range(0, 10) [.default(0)] get(|d| d.mode_request.code())
            set(|d, m| d.set_mode(m))
            check(|d, m| valid_if(mode_supported(m, d.supported_modes()))) }
    }
    var 0x6061 "Modes of operation display", "Mode that is running (changes when the switch is done).",
    {
        { 0 "Modes of operation display": i8 RO TX [.default(0)] get(|d| d.mode.code()) }
    }
    var 0x6062 "Position demand value", "Output of the trajectory generator / CSP interpolation.",
    {
        { 0 "Position demand value": i32 RO TX [.unit("inc")] get(|d| d.position_demand()) }
    }
    var 0x6063 "Position actual internal value", "Actual position, motor side, before polarity and home offset.",
    {
        { 0 "Position actual internal value": i32 RO TX [.unit("inc")] field(raw_position) }
    }
    var 0x6064 "Position actual value", "Actual position in command units.",
    {
        { 0 "Position actual value": i32 RO TX [.unit("inc")] get(|d| d.position_actual()) }
    }
    var 0x6065 "Following error window", "Allowed |0x60F4|; 0xFFFFFFFF switches the supervision off.",
    {
        { 0 "Following error window": u32 RW RX [.default(50_000).unit("inc").saved()] field(params.following_error_window) }
    }
    var 0x6066 "Following error time out", "Time the following error may exceed 0x6065 before statusword bit 13 and fault 0x8611.",
    {
        { 0 "Following error time out": u16 RW RX [.default(100).unit("ms").saved()] field(params.following_error_timeout) }
    }
    var 0x6067 "Position window", "Target reached window.",
    {
        { 0 "Position window": u32 RW RX [.default(100).unit("inc").saved()] field(params.position_window) }
    }
    var 0x6068 "Position window time", "Time in the window before target reached.",
    {
        { 0 "Position window time": u16 RW RX [.default(0).unit("ms").saved()] field(params.position_window_time) }
    }
    var 0x606B "Velocity demand value", "Velocity of the trajectory generator.",
    {
        { 0 "Velocity demand value": i32 RO TX [.unit("inc/s")] get(|d| d.velocity_demand()) }
    }
    var 0x606C "Velocity actual value", "Measured velocity.",
    {
        { 0 "Velocity actual value": i32 RO TX [.unit("inc/s")] field(actual_velocity) }
    }
    var 0x606D "Velocity window", "PV target reached window.",
    {
        { 0 "Velocity window": u16 RW NO [.default(100).unit("inc/s").saved()] field(params.velocity_window) }
    }
    var 0x606E "Velocity window time", "PV time in the window before target reached.",
    {
        { 0 "Velocity window time": u16 RW NO [.default(0).unit("ms").saved()] field(params.velocity_window_time) }
    }
    var 0x606F "Velocity threshold", "PV speed-zero threshold (statusword bit 12).",
    {
        { 0 "Velocity threshold": u16 RW NO [.default(100).unit("inc/s").saved()] field(params.velocity_threshold) }
    }
    var 0x6071 "Target torque", "CST target, per mille of the rated torque 0x6076; 0x60B2 is added, the sum is limited to ±0x6072 and approached at 0x6087.",
    {
        { 0 "Target torque": i16 RW RX range(-3000, 3000) [.default(0).unit("0.1 %")] field(params.target_torque) }
    }
    var 0x6072 "Max torque", "Torque limit for the servo loops (closed loop) and of the CST demand, per mille of rated torque; values above 1000 (the peak current 0x2000) act as 1000.",
    {
        { 0 "Max torque": u16 RW RX range(0, 3000) [.default(1000).unit("0.1 %").saved()] field(params.max_torque) }
    }
    var 0x6073 "Max current", "Current limit, per mille of the rated current 0x6075; values above 1000 (the peak current 0x2000) act as 1000.",
    {
        { 0 "Max current": u16 RW NO range(0, 3000) [.default(1000).unit("0.1 %").saved()] field(params.max_current) }
    }
    var 0x6074 "Torque demand", "CST: the demand after the slope 0x6087 and the limit 0x6072; other modes: the servo loops' q-current reference; per mille of rated torque.",
    {
        { 0 "Torque demand": i16 RO TX [.unit("0.1 %")] get(|d| d.torque_demand()) }
    }
    var 0x6075 "Motor rated current", "Rated current (follows the peak current setting 0x2000).",
    {
        { 0 "Motor rated current": u32 RO NO [.unit("mA")] field(rated_current_ma) }
    }
    var 0x6076 "Motor rated torque", "Torque constant of the motor (q current) times the rated current 0x6075; the reference of every torque in per mille.",
    {
        { 0 "Motor rated torque": u32 RO NO [.unit("mN·m")] get(|d| d.rated_torque_mnm()) }
    }
    var 0x6077 "Torque actual value", "Measured torque Kt·i_q (q current measured in the encoder frame, detent torque not included), per mille of rated torque; 0 without an encoder.",
    {
        { 0 "Torque actual value": i16 RO TX [.unit("0.1 %")] get(|d| d.torque_actual()) }
    }
    var 0x6078 "Current actual value", "Measured q current (encoder frame), per mille of rated current; 0 without an encoder.",
    {
        { 0 "Current actual value": i16 RO TX [.unit("0.1 %")] field(actual_current) }
    }
    var 0x607A "Target position", "PP target (absolute or relative), CSP target every cycle.",
    {
        { 0 "Target position": i32 RW RX [.default(0).unit("inc")] field(params.target_position) }
    }
    array 0x607B "Position range limit", "When min < max (and the range is narrower than the type's), positions wrap in [min, max]: 0x6062, 0x6064 and the touch probe values are shown in it; a CSP target moves the shortest way, a PP absolute target as 0x60F2 bits 6-7 choose; 0x607D is not applied then.",
    {
        { count(2) range(2, 2) }
        { 1 "Min position range limit": i32 RW NO [.default(i32::MIN as i64).unit("inc").saved()] field(params.range_min) }
        { 2 "Max position range limit": i32 RW NO [.default(i32::MAX as i64).unit("inc").saved()] field(params.range_max) }
    }
    var 0x607C "Home offset", "Position actual value given to the home position when homing ends.",
    {
        { 0 "Home offset": i32 RW RX [.default(0).unit("inc").saved()] field(params.home_offset) }
    }
    array 0x607D "Software position limit", "Demand positions are limited to [min, max] when min < max (the type limits mean off) and no position range 0x607B is in effect.",
    {
        { count(2) range(2, 2) }
        { 1 "Min position limit": i32 RW NO [.default(i32::MIN as i64).unit("inc").saved()] field(params.sw_limit_min) }
        { 2 "Max position limit": i32 RW NO [.default(i32::MAX as i64).unit("inc").saved()] field(params.sw_limit_max) }
    }
    var 0x607E "Polarity", "Bit 7 inverts positions, bit 6 velocities (other bits refused); writable outside operation enabled.",
    {
        { 0 "Polarity": u8 RW NO [.default(0).saved()] field(params.polarity)
            set(|d, p| d.params.polarity = p & 0xC0)
            check(|d, p| {
                if p & 0x3F != 0 {
                    Err(SdoAbort::ValueRangeExceeded)
                } else if d.state.voltage_enabled() {
                    Err(SdoAbort::StateConflict)
                } else {
                    Ok(())
                }
            }) }
    }
    var 0x607F "Max profile velocity", "Upper limit of every profile / target velocity.",
    {
        { 0 "Max profile velocity": u32 RW RX range(1, u32::MAX) [.default(5_000_000).unit("inc/s").saved()] field(params.max_profile_velocity) }
    }
    var 0x6080 "Max motor speed", "Upper limit of every velocity demand; in CST the speed limit (torque is taken off beyond it, statusword bit 11).",
    {
        { 0 "Max motor speed": u32 RW NO range(1, u32::MAX) [.default(5_000_000).unit("inc/s").saved()] field(params.max_motor_speed) }
    }
    var 0x6081 "Profile velocity", "PP travel speed, limited by min(0x607F, 0x6080).",
    {
        { 0 "Profile velocity": u32 RW RX [.default(50_000).unit("inc/s").saved()] field(params.profile_velocity) }
    }
    var 0x6082 "End velocity", "E5: speed the PP profile may start from / stop at without a ramp.",
    {
        { 0 "Start/stop velocity": u32 RW RX [.default(0).unit("inc/s").saved()] field(params.start_stop_speed) }
    }
    var 0x6083 "Profile acceleration", "PP / PV acceleration, limited by 0x60C5.",
    {
        { 0 "Profile acceleration": u32 RW RX [.default(500_000).unit("inc/s²").saved()] field(params.profile_acceleration) }
    }
    var 0x6084 "Profile deceleration", "PP / PV deceleration and slow-down ramp, limited by 0x60C6.",
    {
        { 0 "Profile deceleration": u32 RW RX [.default(500_000).unit("inc/s²").saved()] field(params.profile_deceleration) }
    }
    var 0x6085 "Quick stop deceleration", "Quick-stop ramp; also the stop ramp at a hardware limit switch.",
    {
        { 0 "Quick stop deceleration": u32 RW RX [.default(2_000_000).unit("inc/s²").saved()] field(params.quick_stop_deceleration) }
    }
    var 0x6086 "Motion profile type", "PP profile: 0 linear ramp (trapezoid); 3 jerk-limited ramp (trapezoid through a moving average as long as one acceleration, at most 64 cycles); 1 and 2 are refused.",
    {
        { 0 "Motion profile type": i16 RW NO range(0, 3) [.default(0).saved()] field(params.motion_profile_type)
            check(|_, t| valid_if(t == 0 || t == 3)) }
    }
    var 0x6087 "Torque slope", "Rate at which the PT / CST demand approaches its target, per mille of rated torque per second; 0 = no slope limit (the demand steps).",
    {
        { 0 "Torque slope": u32 RW RX [.default(0).unit("0.1 %/s").saved()] field(params.torque_slope) }
    }
    var 0x6088 "Torque profile type", "Shape of the PT / CST demand's approach to its target: 0 linear ramp at 0x6087 (the only type; others refused).",
    {
        { 0 "Torque profile type": i16 RW NO range(0, 0) [.default(0).saved()] field(params.torque_profile_type) }
    }
    array 0x608F "Position encoder resolution", "Encoder increments per motor revolution.",
    {
        { count(2) range(2, 2) }
        { 1 "Encoder increments": u32 RO NO [.default(4000)] field(encoder_increments) }
        { 2 "Motor revolutions": u32 RO NO [.default(1)] constant(1) }
    }
    array 0x6091 "Gear ratio", "Motor revolutions per shaft revolutions; with 0x6092 it sets 0x2001 = feed · shaft revolutions (0x6091:02) / (0x6092:02 · motor revolutions) once that is a whole number 0x2001 takes (effective after restart).",
    {
        { count(2) range(2, 2) }
        { 1 "Motor revolutions": u32 RW NO range(1, u32::MAX) [.default(1).saved()] get(|d| d.scaling.gear[0]) set(|d, v| scale(d, 0x6091, 1, v)) }
        { 2 "Shaft revolutions": u32 RW NO range(1, u32::MAX) [.default(1).saved()] get(|d| d.scaling.gear[1]) set(|d, v| scale(d, 0x6091, 2, v)) }
    }
    array 0x6092 "Feed constant", "Command units per shaft revolutions (see 0x6091); a write of 0x2001 sets it to (0x2001, 1) and the gear ratio to 1:1.",
    {
        { count(2) range(2, 2) }
        { 1 "Feed": u32 RW NO range(1, u32::MAX) [.default(50_000).unit("inc").saved()] get(|d| d.scaling.feed[0]) set(|d, v| scale(d, 0x6092, 1, v)) }
        { 2 "Shaft revolutions": u32 RW NO range(1, u32::MAX) [.default(1).saved()] get(|d| d.scaling.feed[1]) set(|d, v| scale(d, 0x6092, 2, v)) }
    }
    array 0x6093 "Position factor", "Encoder increments (0x608F:01) per command unit as numerator / divisor; derived from 0x2001, or as written: a write sets 0x2001 = 0x608F:01 · divisor / numerator once that is a whole number 0x2001 takes (gear 1:1, feed (0x2001, 1)).",
    {
        { count(2) range(2, 2) }
        { 1 "Numerator": u32 RW NO range(1, u32::MAX) [] get(|d| d.scaling.factor(d.encoder_increments)[0]) set(|d, v| scale(d, 0x6093, 1, v)) }
        { 2 "Divisor": u32 RW NO range(1, u32::MAX) [] get(|d| d.scaling.factor(d.encoder_increments)[1]) set(|d, v| scale(d, 0x6093, 2, v)) }
    }
    var 0x6098 "Homing method", "1-14, 17-30, 33, 34, 35, 37; manufacturer-specific stall homing (open loop, 0x2060 = 1): -1 positive, -2 negative direction at 0x6099:01 onto a hard stop, home = where the stall began (+ 0x607C).",
    {
        { 0 "Homing method": i8 RW RX range(-2, 37) [.default(37).saved()] field(params.homing_method)
            set(|d, m| {
                if homing::supported(m) {
                    d.params.homing_method = m;
                }
            })
            check(|_, m| valid_if(homing::supported(m))) }
    }
    array 0x6099 "Homing speeds", "Homing speeds.",
    {
        { count(2) range(2, 2) }
        { 1 "Speed during search for switch": u32 RW RX [.default(20_000).unit("inc/s").saved()] field(params.homing_speed_switch) }
        { 2 "Speed during search for zero": u32 RW RX [.default(2_000).unit("inc/s").saved()] field(params.homing_speed_zero) }
    }
    var 0x609A "Homing acceleration", "Acceleration and deceleration of every homing move.",
    {
        { 0 "Homing acceleration": u32 RW RX [.default(200_000).unit("inc/s²").saved()] field(params.homing_acceleration) }
    }
    var 0x60B0 "Position offset", "Added to the CSP target position.",
    {
        { 0 "Position offset": i32 RW RX [.default(0).unit("inc")] field(params.position_offset) }
    }
    var 0x60B1 "Velocity offset", "Velocity feed-forward (CSP) / added to the CSV target.",
    {
        { 0 "Velocity offset": i32 RW RX [.default(0).unit("inc/s")] field(params.velocity_offset) }
    }
    var 0x60B2 "Torque offset", "Added to the CST target; torque feed-forward of the servo loops in CSP and CSV; per mille of rated torque.",
    {
        { 0 "Torque offset": i16 RW RX range(-3000, 3000) [.default(0).unit("0.1 %")] field(params.torque_offset) }
    }
    var 0x60B8 "Touch probe function", "Per probe (2: bits 8-13): bit 0 enable, 1 continuous, 2 index pulse as trigger, 4 rising edge, 5 falling edge.",
    {
        { 0 "Touch probe function": u16 RW RX [.default(0)] get(|d| d.probe.function())
            set(|d, f| d.probe.set_function(f))
            check(|_, f| valid_if(probe::function_valid(f))) }
    }
    var 0x60B9 "Touch probe status", "Per probe: bit 0 enabled, 1 rising value stored, 2 falling value stored, 6/7 toggles in continuous mode.",
    {
        { 0 "Touch probe status": u16 RO TX [] get(|d| d.probe.status()) }
    }
    var 0x60BA "Touch probe 1 positive edge", "Position latched at the rising edge of probe 1.",
    {
        { 0 "Touch probe 1 positive edge": i32 RO TX [.unit("inc")] get(|d| d.probe_position(0)) }
    }
    var 0x60BB "Touch probe 1 negative edge", "Position latched at the falling edge of probe 1.",
    {
        { 0 "Touch probe 1 negative edge": i32 RO TX [.unit("inc")] get(|d| d.probe_position(1)) }
    }
    var 0x60BC "Touch probe 2 positive edge", "Position latched at the rising edge of probe 2.",
    {
        { 0 "Touch probe 2 positive edge": i32 RO TX [.unit("inc")] get(|d| d.probe_position(2)) }
    }
    var 0x60BD "Touch probe 2 negative edge", "Position latched at the falling edge of probe 2.",
    {
        { 0 "Touch probe 2 negative edge": i32 RO TX [.unit("inc")] get(|d| d.probe_position(3)) }
    }
    var 0x60C0 "Interpolation sub mode select", "CSP set-points are interpolated linearly between cycles (0 = linear interpolation, the only sub mode; others refused).",
    {
        { 0 "Interpolation sub mode select": i16 RW NO range(0, 0) [.default(0).saved()] field(params.interpolation_submode) }
    }
    record 0x60C2 "Interpolation time period", "Period = value · 10^index s; must equal the sync cycle.",
    {
        { count(2) range(2, 2) }
        { 1 "Interpolation time period value": u8 RW NO range(1, 255) [.default(1)] field(params.interpolation_period) }
        { 2 "Interpolation time index": i8 RW NO range(-6, -3) [.default(-3)] field(params.interpolation_index) }
    }
    var 0x60C5 "Max acceleration", "Limit of 0x6083 and 0x609A.",
    {
        { 0 "Max acceleration": u32 RW NO range(1, u32::MAX) [.default(100_000_000).unit("inc/s²").saved()] field(params.max_acceleration) }
    }
    var 0x60C6 "Max deceleration", "Limit of 0x6084 and 0x609A; ramp of the option codes 3 and 4.",
    {
        { 0 "Max deceleration": u32 RW NO range(1, u32::MAX) [.default(100_000_000).unit("inc/s²").saved()] field(params.max_deceleration) }
    }
    var 0x60F2 "Positioning option code", "Bits 0-1, PP relative moves: 0 from the previous target, 1 from the position demand value, 2 from the position actual value; bits 6-7, PP absolute targets with a position range 0x607B: 0 inside the range, 1 negative direction only, 2 positive direction only, 3 the shortest way. Other bits refused.",
    {
        { 0 "Positioning option code": u16 RW NO range(0, 0xC2) [.default(0).saved()] field(params.positioning_option)
            check(|_, v| valid_if(v & !0xC3 == 0 && v & 3 != 3)) }
    }
    var 0x60F4 "Following error actual value", "0x6062 − 0x6064.",
    {
        { 0 "Following error actual value": i32 RO TX [.unit("inc")] field(following_error) }
    }
    var 0x60FA "Control effort", "Output of the position controller, command units/s: closed loop, the position loop's velocity command (feed-forward, proportional and integral parts) in the position modes, 0 in the velocity and torque modes; open loop, the commanded velocity; 0 while disabled.",
    {
        { 0 "Control effort": i32 RO TX [.unit("inc/s")] field(control_effort) }
    }
    var 0x60FC "Position demand internal value", "Position demand, motor side.",
    {
        { 0 "Position demand internal value": i32 RO TX [.unit("inc")] get(|d| d.position_demand_internal()) }
    }
    var 0x60FD "Digital inputs", "Bit 0 negative limit, 1 positive limit, 2 home switch (after the input functions 0x2152).",
    {
        { 0 "Digital inputs": u32 RO TX [] field(digital_inputs) }
    }
    array 0x60FE "Digital outputs", "Outputs driven by the master where the mask bit is set.",
    {
        { count(2) range(2, 2) }
        { 1 "Physical outputs": u32 RW RX [.default(0)] field(params.digital_outputs) }
        { 2 "Bit mask": u32 RW NO [.default(0)] field(params.digital_outputs_mask) }
    }
    var 0x60FF "Target velocity", "PV and CSV target.",
    {
        { 0 "Target velocity": i32 RW RX [.default(0).unit("inc/s")] field(params.target_velocity) }
    }
    var 0x6502 "Supported drive modes", "Bit 0 PP, 2 PV, 5 HM, 7 CSP, 8 CSV; bits 3 PT and 9 CST only in closed loop (an encoder and 0x2024 = 2).",
    {
        { 0 "Supported drive modes": u32 RO NO [.default(SUPPORTED_MODES as i64)] get(|d| d.supported_modes()) }
    }
}

mod slots;
pub use slots::{rx_slot, tx_slot, RX_SLOTS, TX_SLOTS};

#[cfg(test)]
mod tests;
