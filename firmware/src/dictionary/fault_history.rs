//! The fault history objects 0x2400-0x2406 (owner `Owner::Faults`): their
//! descriptions and their values from the drive's [`Faults`]. They live with the
//! dictionary (which reads the fault state) rather than in [`crate::faults`], so the
//! fault logic does not depend on the dictionary.

use ecat_slave_stack::od::{
    Access, DataType, Entry, EntryDesc, ObjectDesc, ObjectKey, PdoMappable, SdoAbort, Values,
};

use crate::faults::Faults;

const fn ro(sub: u8, name: &'static str, t: DataType, unit: &'static str) -> EntryDesc {
    EntryDesc::new(sub, name, t, Access::RO).unit(unit)
}

const SNAPSHOT: &[EntryDesc] = &[
    EntryDesc::count(8),
    ro(1, "Error code", DataType::Unsigned16, ""),
    ro(2, "Phase A current", DataType::Integer16, "mA"),
    ro(3, "Phase B current", DataType::Integer16, "mA"),
    ro(4, "Bus voltage", DataType::Unsigned16, "0.1V"),
    ro(5, "Position error", DataType::Integer32, "inc"),
    ro(6, "Speed", DataType::Integer32, "inc/s"),
    ro(7, "Time since power-up", DataType::Unsigned32, "ms"),
    ro(8, "Operating time", DataType::Unsigned32, "s"),
];

const fn snap_obj(index: u16, name: &'static str) -> ObjectDesc {
    ObjectDesc::record(
        index,
        name,
        SNAPSHOT,
        "Values captured when the fault occurred (zeros when empty); kept in flash \
         across power cycles; sub 8: operating time 0x2307 at the fault",
    )
}

/// Fault history objects (the Xinje U1 group): 0x2400 summary, 0x2401 newest fault's
/// snapshot … 0x2406 sixth newest.
pub const OBJECTS: &[ObjectDesc] = &[
    ObjectDesc::record(
        0x2400,
        "Fault history",
        &[
            EntryDesc::count(8),
            ro(1, "Faults since power-up", DataType::Unsigned16, ""),
            ro(2, "Fault code 1 (newest)", DataType::Unsigned16, ""),
            ro(3, "Fault code 2", DataType::Unsigned16, ""),
            ro(4, "Fault code 3", DataType::Unsigned16, ""),
            ro(5, "Fault code 4", DataType::Unsigned16, ""),
            ro(6, "Fault code 5", DataType::Unsigned16, ""),
            ro(7, "Fault code 6 (oldest)", DataType::Unsigned16, ""),
            EntryDesc::new(8, "Active faults", DataType::Unsigned16, Access::RO)
                .pdo(PdoMappable::Tx),
        ],
        "Last six faults, newest first; sub 8: bit n = fault kind n active",
    ),
    snap_obj(0x2401, "Fault 1 snapshot"),
    snap_obj(0x2402, "Fault 2 snapshot"),
    snap_obj(0x2403, "Fault 3 snapshot"),
    snap_obj(0x2404, "Fault 4 snapshot"),
    snap_obj(0x2405, "Fault 5 snapshot"),
    snap_obj(0x2406, "Fault 6 snapshot"),
];

/// The values of 0x2400-0x2406: the drive's [`Faults`] as its history reports them
/// (read-only).
pub struct FaultHistory<'a>(pub &'a Faults);

impl Values for FaultHistory<'_> {
    fn get(&self, _: &(), key: ObjectKey, _: &Entry) -> Result<i64, SdoAbort> {
        let faults = self.0;
        let (index, sub) = (key.index, key.sub);
        let v: u32 = match (index, sub) {
            (0x2400, 1) => u32::from(faults.count()),
            (0x2400, 2..=7) => faults
                .history(usize::from(sub) - 2)
                .map_or(0, |r| u32::from(r.code)),
            (0x2400, 8) => u32::from(faults.active_mask()),
            (0x2401..=0x2406, _) => match faults.history(usize::from(index - 0x2401)) {
                None => 0,
                Some(r) => match sub {
                    1 => u32::from(r.code),
                    2 => r.snapshot.ia_ma as u16 as u32,
                    3 => r.snapshot.ib_ma as u16 as u32,
                    4 => u32::from(r.snapshot.bus_dv),
                    5 => r.snapshot.position_error as u32,
                    6 => r.snapshot.speed as u32,
                    7 => r.time_ms,
                    _ => r.operating_s,
                },
            },
            _ => return Err(SdoAbort::ObjectDoesNotExist),
        };
        Ok(i64::from(v))
    }
}

/// SDO read of 0x2400-0x2406 from `faults` (the dispatcher's read of [`FaultHistory`]).
pub fn read(faults: &Faults, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, SdoAbort> {
    super::read(&FaultHistory(faults), &(), ObjectKey::new(index, sub), buf)
}
