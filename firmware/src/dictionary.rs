//! The product's object dictionary: one sorted table made at compile time from the
//! tables of the modules that own the values.
//!
//! Which module owns which index range is stated once, in [`OWNERS`]; the SDO and PDO
//! dispatch ([`owner_of`]) and the modules' own look-ups (`find_entry_in`) use it.
//! The objects the slave runtime serves itself (mapping, assignment, sync manager
//! parameters) are the stack's to name (`ecat_slave_stack::pdo::is_pdo_index`,
//! `ecat_slave_stack::sync::is_sync_index`); it also serves the timing diagnostics at
//! the index the product gives it ([`crate::identity::TIMING_DIAG`]).
//!
//! The same table feeds the SDO server, PDO mapping rules, SDO information, the ESI,
//! the SII and the generated reference (`cargo xtask od-doc`), so they cannot disagree.

use ecat_slave_stack::od::{self, Entry, Object, ObjectDesc, SdoAbort};

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

// The owners as the modules name themselves in their look-ups.
pub(crate) const COMM: Owner = Owner::Comm;
pub(crate) const PARAMS: Owner = Owner::Params;
pub(crate) const MONITOR: Owner = Owner::Monitor;
pub(crate) const FAULTS: Owner = Owner::Faults;
pub(crate) const SCOPE: Owner = Owner::Scope;
pub(crate) const CIA402: Owner = Owner::Cia402;

/// Object `index` of the module `owner`: the same answer as
/// `od::find(module::OBJECTS, index)`, without a second copy of the module's table in
/// flash (a module's `const OBJECTS` used at run time is its own array beside
/// [`OBJECTS`]).
pub(crate) fn find_in(owner: Owner, index: u16) -> Option<&'static Object> {
    if owner_of(index) != Some(owner) {
        return None;
    }
    od::find(OBJECTS, index)
}

/// The answer of a module's SDO read: the low `entry.byte_len()` bytes of `v`
/// (little-endian) into `buf`; "exceeds mailbox" when they do not fit. Shared by
/// every module's read.
pub(crate) fn put_le(entry: &Entry, v: u64, buf: &mut [u8]) -> Result<usize, SdoAbort> {
    let len = entry.byte_len();
    let out = buf.get_mut(..len).ok_or(SdoAbort::ExceedsMailbox)?;
    let n = len.min(8);
    out[..n].copy_from_slice(&v.to_le_bytes()[..n]);
    Ok(len)
}

/// Entry `index:sub` of the module `owner` (as `od::find_entry(module::OBJECTS,
/// ..)`: no object → `ObjectDoesNotExist`, no sub-index → `SubindexDoesNotExist`).
pub(crate) fn find_entry_in(owner: Owner, index: u16, sub: u8) -> Result<&'static Entry, SdoAbort> {
    let obj = find_in(owner, index).ok_or(SdoAbort::ObjectDoesNotExist)?;
    obj.entry(sub).ok_or(SdoAbort::SubindexDoesNotExist)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::string::ToString;

    #[test]
    fn module_ranges_hold_exactly_the_module_tables() {
        let modules: [(&[ObjectDesc], Owner); 6] = [
            (crate::comm::OBJECTS, COMM),
            (crate::params::OBJECTS, PARAMS),
            (crate::monitor::OBJECTS, MONITOR),
            (fault_history::OBJECTS, FAULTS),
            (crate::scope::OBJECTS, SCOPE),
            (crate::cia402::objects::OBJECTS, CIA402),
        ];
        for (own, owner) in modules {
            for o in own {
                assert_eq!(owner_of(o.index), Some(owner), "{:#06x}", o.index);
            }
            for index in 0..=u16::MAX {
                let mine = own.iter().find(|o| o.index == index);
                let found = find_in(owner, index);
                assert_eq!(mine.is_some(), found.is_some(), "{index:#06x}");
                if let (Some(a), Some(b)) = (mine, found) {
                    assert_eq!(a.name(), b.name());
                    assert_eq!(a.entries().len(), b.entries().len());
                    for sub in 0..=u8::MAX {
                        assert_eq!(
                            a.entry(sub)
                                .map(|e| (e.sub(), e.name().to_string()))
                                .ok_or(SdoAbort::SubindexDoesNotExist),
                            find_entry_in(owner, index, sub).map(|e| (e.sub, e.name().to_string())),
                            "{index:#06x}:{sub}"
                        );
                    }
                }
                if mine.is_none() {
                    for sub in [0, 1, 255] {
                        assert_eq!(
                            find_entry_in(owner, index, sub).err(),
                            Some(SdoAbort::ObjectDoesNotExist)
                        );
                    }
                }
            }
        }
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
