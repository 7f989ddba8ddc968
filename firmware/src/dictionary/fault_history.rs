//! The fault history objects 0x2400-0x2406 (owner `Owner::Faults`): their
//! descriptions and their values from the drive's [`Faults`]. They live with the
//! dictionary (which reads the fault state) rather than in [`crate::faults`], so the
//! fault logic does not depend on the dictionary.

use ecat_slave_stack::od::{Access, DataType, EntryDesc, ObjectKey, PdoMappable, SdoAbort};

use crate::bind::bound_objects;
use crate::faults::{FaultRecord, Faults};

const fn ro(sub: u8, name: &'static str, t: DataType, unit: &'static str) -> EntryDesc {
    EntryDesc::new(sub, name, t, Access::RO).unit(unit)
}

/// The values of 0x2400-0x2406: the drive's [`Faults`] as its history reports them
/// (read-only).
pub struct FaultHistory<'a>(pub &'a Faults);

/// The fault whose snapshot is object `key.index` (0x2401 the newest); one call for
/// the 48 snapshot entries.
#[inline(never)]
fn fault<'a>(h: &FaultHistory<'a>, key: ObjectKey) -> Option<&'a FaultRecord> {
    h.0.history(usize::from(key.index - 0x2401))
}

const SNAPSHOT_TEXT: &str =
    "Values captured when the fault occurred (zeros when empty); kept in flash \
                             across power cycles; sub 8: operating time 0x2307 at the fault";

/// The table: 0x2400 and, from one description, the snapshot records 0x2401-0x2406
/// (`$index`: 0x2401 the newest fault).
macro_rules! fault_history_objects {
    ($($index:literal $name:literal;)*) => {
        bound_objects! {
            impl Values<()> for FaultHistory<'_>;
            record 0x2400, "Fault history", "Last six faults, newest first; sub 8: bit n = fault kind n active", {
                EntryDesc::count(8) => count;
                ro(1, "Faults since power-up", DataType::Unsigned16, "") => get |h| h.0.count();
                ro(2, "Fault code 1 (newest)", DataType::Unsigned16, "") => get |h, _, key| code(h, key.sub - 2);
                ro(3, "Fault code 2", DataType::Unsigned16, "") => get |h, _, key| code(h, key.sub - 2);
                ro(4, "Fault code 3", DataType::Unsigned16, "") => get |h, _, key| code(h, key.sub - 2);
                ro(5, "Fault code 4", DataType::Unsigned16, "") => get |h, _, key| code(h, key.sub - 2);
                ro(6, "Fault code 5", DataType::Unsigned16, "") => get |h, _, key| code(h, key.sub - 2);
                ro(7, "Fault code 6 (oldest)", DataType::Unsigned16, "") => get |h, _, key| code(h, key.sub - 2);
                EntryDesc::new(8, "Active faults", DataType::Unsigned16, Access::RO)
                    .pdo(PdoMappable::Tx)
                    => get |h| h.0.active_mask();
            }
            $(record $index, $name, SNAPSHOT_TEXT, {
                EntryDesc::count(8) => count;
                ro(1, "Error code", DataType::Unsigned16, "") => get |h, _, key| fault(h, key).map_or(0, |r| r.code);
                ro(2, "Phase A current", DataType::Integer16, "mA")
                    => get |h, _, key| fault(h, key).map_or(0, |r| r.snapshot.ia_ma as u16);
                ro(3, "Phase B current", DataType::Integer16, "mA")
                    => get |h, _, key| fault(h, key).map_or(0, |r| r.snapshot.ib_ma as u16);
                ro(4, "Bus voltage", DataType::Unsigned16, "0.1V")
                    => get |h, _, key| fault(h, key).map_or(0, |r| r.snapshot.bus_dv);
                ro(5, "Position error", DataType::Integer32, "inc")
                    => get |h, _, key| fault(h, key).map_or(0, |r| r.snapshot.position_error as u32);
                ro(6, "Speed", DataType::Integer32, "inc/s")
                    => get |h, _, key| fault(h, key).map_or(0, |r| r.snapshot.speed as u32);
                ro(7, "Time since power-up", DataType::Unsigned32, "ms")
                    => get |h, _, key| fault(h, key).map_or(0, |r| r.time_ms);
                ro(8, "Operating time", DataType::Unsigned32, "s")
                    => get |h, _, key| fault(h, key).map_or(0, |r| r.operating_s);
            })*
        }
    };
}

// Fault history objects (the Xinje U1 group): 0x2400 summary, 0x2401 newest fault's
// snapshot … 0x2406 sixth newest.
fault_history_objects! {
    0x2401 "Fault 1 snapshot";
    0x2402 "Fault 2 snapshot";
    0x2403 "Fault 3 snapshot";
    0x2404 "Fault 4 snapshot";
    0x2405 "Fault 5 snapshot";
    0x2406 "Fault 6 snapshot";
}

/// The code of fault `n` of the history (0 the newest), 0 when empty.
fn code(h: &FaultHistory<'_>, n: u8) -> u16 {
    h.0.history(usize::from(n)).map_or(0, |r| r.code)
}

/// SDO read of 0x2400-0x2406 from `faults` (the dispatcher's read of [`FaultHistory`]).
pub fn read(faults: &Faults, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, SdoAbort> {
    super::read(&FaultHistory(faults), &(), ObjectKey::new(index, sub), buf)
}
