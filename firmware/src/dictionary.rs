//! The product's object dictionary: one sorted table made at compile time from the
//! tables of the modules that own the values.
//!
//! Which module owns which index range is stated once, in [`OWNERS`]; the SDO and PDO
//! dispatch ([`owner_of`]) uses it. Every owner binds its entries to its state the one
//! way, by implementing `ecat_slave_stack::od::Values`; the dispatcher (`Drive`) finds
//! the entry here once and runs the generic checks and the byte conversion ([`read()`],
//! [`write()`]).
//! The objects the slave runtime serves itself (mapping, assignment, sync manager
//! parameters) are the stack's to name (`ecat_slave_stack::pdo::is_pdo_index`,
//! `ecat_slave_stack::sync::is_sync_index`); it also serves the timing diagnostics at
//! the index the product gives it ([`crate::identity::TIMING_DIAG`]).
//!
//! The same table feeds the SDO server, PDO mapping rules, SDO information, the ESI,
//! the SII and the generated reference (`cargo xtask od-doc`), so they cannot disagree.

use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::od::{
    self, DefaultValue, Entry, Object, ObjectCode, ObjectDesc, ObjectKey, SdoAbort, Values,
};

pub mod fault_history;
mod vocabulary;

pub use vocabulary::VOCABULARY;

/// The owners' tables, as written (compile-time descriptions; documentation
/// generators describe variants of the dictionary from them).
pub const PARTS: &[&[ObjectDesc]] = &[
    crate::comm::OBJECTS,
    ecat_slave_stack::pdo::OBJECTS,
    crate::params::OBJECTS,
    &[ecat_slave_stack::sync::timing_diag_object(
        crate::identity::TIMING_DIAG,
    )],
    fault_history::OBJECTS,
    crate::monitor::OBJECTS,
    crate::scope::OBJECTS,
    crate::cia402::objects::OBJECTS,
];

/// Every object of the drive, sorted by index: the module tables merged at compile
/// time, names packed with [`VOCABULARY`] and stored once, identical entry tables once
/// (`ecat_slave_stack::od::pack`; two modules describing one index do not compile).
// Packing the whole product dictionary at compile time runs past rustc's default
// const-evaluation lint; it terminates (bounded loops over the tables).
#[allow(long_running_const_eval)]
pub static OBJECTS: &[Object] = ecat_slave_stack::packed_dictionary!(PARTS, VOCABULARY);

/// True when the table is well formed (sorted objects, sorted sub-indices).
pub fn is_well_formed() -> bool {
    od::is_well_formed(OBJECTS)
}

/// The module that serves an object's SDO and PDO access.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Owner {
    /// [`crate::comm`]: device type, names, store / restore, identity, error settings.
    Comm,
    /// The slave runtime (`ecat_slave_stack`): PDO mapping and assignment, sync manager
    /// parameters, timing diagnostics.
    SlaveRuntime,
    /// [`crate::params`]: the vendor parameters.
    Params,
    /// [`crate::monitor`]: monitoring values.
    Monitor,
    /// [`fault_history`]: the fault history of [`crate::faults`].
    Faults,
    /// [`crate::scope`]: scope and trace buffer.
    Scope,
    /// [`crate::cia402`]: the drive profile.
    Cia402,
}

/// The product modules' index ranges, in ascending order: the one owner table. Every
/// object of [`OBJECTS`] inside a range is one of that module's (tested below).
pub const OWNERS: &[(u16, u16, Owner)] = &[
    (0x1000, 0x10FF, Owner::Comm),
    (0x2000, 0x21FF, Owner::Params),
    (0x2300, 0x23FF, Owner::Monitor),
    (0x2400, 0x24FF, Owner::Faults),
    (0x2500, 0x25FF, Owner::Scope),
    (0x6000, 0x6FFF, Owner::Cia402),
];

/// The owner of `index`: the slave runtime's objects first, then [`OWNERS`].
pub fn owner_of(index: u16) -> Option<Owner> {
    if ecat_slave_stack::pdo::is_pdo_index(index)
        || ecat_slave_stack::sync::is_sync_index(index)
        || index == crate::identity::TIMING_DIAG
    {
        return Some(Owner::SlaveRuntime);
    }
    OWNERS
        .iter()
        .find(|&&(lo, hi, _)| (lo..=hi).contains(&index))
        .map(|&(_, _, owner)| owner)
}

/// The answer of a read: the low `entry.byte_len()` bytes of `v` (little-endian) into
/// `buf`; "exceeds mailbox" when they do not fit.
pub(crate) fn put_le(entry: &Entry, v: u64, buf: &mut [u8]) -> Result<usize, SdoAbort> {
    let len = entry.byte_len();
    let out = buf.get_mut(..len).ok_or(SdoAbort::ExceedsMailbox)?;
    let n = len.min(8);
    out[..n].copy_from_slice(&v.to_le_bytes()[..n]);
    Ok(len)
}

/// The checks of a write to `entry` and its value: access, length and range as the
/// stack's `check_write` in Pre-Op (a write may come from the storage restore or a
/// PDO as well as from the SDO server), except that a read-only entry marked saved
/// (the monitoring counters) takes the value the restore brings.
pub(crate) fn checked_value(entry: &Entry, data: &[u8]) -> Result<i64, SdoAbort> {
    let mut e = *entry;
    if e.is_saved() && !e.access.writable() {
        e.access = od::Access::RW;
    }
    od::check_write(&e, data, EsmState::PreOp)?;
    od::decode_int(e.data_type, data).ok_or(SdoAbort::TypeMismatch)
}

/// The dispatcher's read of entry `key` of an owner's values (`cx`: what else they
/// are made of): the entry of [`OBJECTS`] (no object / no sub-index), readable, the
/// owner's bytes, else its number in little-endian. The read-only sub-index 0 of an
/// array or record (its count) is bound to its description: it reads as its default.
pub fn read<C: ?Sized>(
    owner: &dyn Values<C>,
    cx: &C,
    key: ObjectKey,
    buf: &mut [u8],
) -> Result<usize, SdoAbort> {
    let obj = od::find(OBJECTS, key.index).ok_or(SdoAbort::ObjectDoesNotExist)?;
    let entry = obj.entry(key.sub).ok_or(SdoAbort::SubindexDoesNotExist)?;
    if !entry.access.readable() {
        return Err(SdoAbort::ReadWriteOnly);
    }
    if let Some(r) = owner.read_bytes(cx, key, entry, buf) {
        return r;
    }
    let v = match (key.sub, obj.code(), entry.default_value()) {
        (0, ObjectCode::Array | ObjectCode::Record, DefaultValue::Int(n))
            if !entry.access.writable() =>
        {
            n
        }
        _ => owner.get(cx, key, entry)?,
    };
    put_le(entry, v as u64, buf)
}

/// The dispatcher's write of entry `key` of an owner's values: the entry of
/// [`OBJECTS`], `checked_value`, then the owner stores the number.
pub fn write<C: ?Sized>(
    owner: &mut dyn Values<C>,
    cx: &mut C,
    key: ObjectKey,
    data: &[u8],
) -> Result<(), SdoAbort> {
    let entry = od::find_entry(OBJECTS, key)?;
    let v = checked_value(entry, data)?;
    owner.set(cx, key, entry, v)
}

/// [`write()`] of a communication object, then the store / restore command it decoded
/// (0x1010 / 0x1011), for the caller to run with `comm::execute`.
pub fn write_comm(
    comm: &mut crate::comm::Comm,
    faults: &mut crate::faults::Faults,
    key: ObjectKey,
    data: &[u8],
) -> Result<Option<crate::comm::StoreCommand>, SdoAbort> {
    write(comm, faults, key, data)?;
    Ok(comm.take_store_command())
}

/// SDO-style access to one owner's values without the drive (tests, tools): [`read()`]
/// and [`write()`] by index and sub-index.
pub trait Sdo {
    /// [`read()`] of `index:sub`.
    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, SdoAbort>;
    /// [`write()`] of `index:sub`.
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoAbort>;
}

impl<V: Values> Sdo for V {
    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        read(self, &(), ObjectKey::new(index, sub), buf)
    }
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoAbort> {
        write(self, &mut (), ObjectKey::new(index, sub), data)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::string::ToString;

    #[test]
    fn module_ranges_hold_exactly_the_module_tables() {
        let modules: [(&[ObjectDesc], Owner); 6] = [
            (crate::comm::OBJECTS, Owner::Comm),
            (crate::params::OBJECTS, Owner::Params),
            (crate::monitor::OBJECTS, Owner::Monitor),
            (fault_history::OBJECTS, Owner::Faults),
            (crate::scope::OBJECTS, Owner::Scope),
            (crate::cia402::objects::OBJECTS, Owner::Cia402),
        ];
        for (own, owner) in modules {
            for o in own {
                assert_eq!(owner_of(o.index), Some(owner), "{:#06x}", o.index);
            }
            for o in OBJECTS.iter().filter(|o| owner_of(o.index) == Some(owner)) {
                let mine = own.iter().find(|d| d.index == o.index);
                assert_eq!(
                    mine.map(|d| d.name().to_string()),
                    Some(o.name().to_string())
                );
            }
        }
    }

    #[test]
    fn only_the_saved_counters_are_restored_into_read_only_entries() {
        let mut restored = std::vec::Vec::new();
        for o in OBJECTS
            .iter()
            .filter(|o| owner_of(o.index) != Some(Owner::SlaveRuntime))
        {
            for e in o.entries() {
                if e.is_saved() && !e.access.writable() {
                    restored.push((o.index, e.sub));
                }
            }
        }
        assert_eq!(restored, [(0x2306, 0), (0x2307, 0)]);
        let e = od::find_entry(OBJECTS, ObjectKey::new(0x2306, 0)).unwrap();
        assert_eq!(checked_value(e, &7u32.to_le_bytes()), Ok(7));
        assert_eq!(checked_value(e, &[7]), Err(SdoAbort::LengthTooLow));
        let e = od::find_entry(OBJECTS, ObjectKey::new(0x2300, 0)).unwrap();
        assert_eq!(checked_value(e, &[7, 0]), Err(SdoAbort::WriteReadOnly));
    }

    #[test]
    fn every_object_has_one_owner_and_the_table_is_ordered() {
        for w in OWNERS.windows(2) {
            assert!(w[0].1 < w[1].0, "{:#06x}", w[1].0);
        }
        for part in [
            ecat_slave_stack::pdo::OBJECTS,
            &[ecat_slave_stack::sync::timing_diag_object(
                crate::identity::TIMING_DIAG,
            )],
        ] {
            for o in part {
                assert_eq!(
                    owner_of(o.index),
                    Some(Owner::SlaveRuntime),
                    "{:#06x}",
                    o.index
                );
                assert!(!OWNERS.iter().any(|r| (r.0..=r.1).contains(&o.index)));
            }
        }
        for o in OBJECTS {
            assert!(owner_of(o.index).is_some(), "{:#06x} has no owner", o.index);
        }
    }

    #[test]
    fn packed_table_describes_the_module_tables() {
        let mut n = 0;
        for part in PARTS {
            for src in part.iter() {
                let packed = od::find(OBJECTS, src.index).expect("object in the table");
                assert_eq!(packed, src, "{:#06x}", src.index);
                assert_eq!(packed.name().to_string(), src.name().to_string());
                for (p, s) in packed.entries().iter().zip(src.entries()) {
                    assert_eq!(p, s, "{:#06x}:{}", src.index, s.sub());
                    assert_eq!(p.name().to_string(), s.name().to_string());
                    assert_eq!(p.name().len(), s.name().len());
                    assert!(p.name().stored_len() <= s.name().len(), "packed");
                }
                n += 1;
            }
        }
        assert_eq!(n, OBJECTS.len());
    }

    #[test]
    fn table_is_sorted_and_complete() {
        assert!(is_well_formed());
        let total: usize = PARTS.iter().map(|p| p.len()).sum();
        assert_eq!(OBJECTS.len(), total);
        for index in [
            0x1000, 0x1018, 0x1600, 0x1A00, 0x1C12, 0x1C32, 0x2000, 0x2152, 0x2200, 0x2500, 0x2503,
            0x6040, 0x6041, 0x607A, 0x6502,
        ] {
            assert!(od::find(OBJECTS, index).is_some(), "{index:#06x} missing");
        }
    }
}
