//! The product's object dictionary: one sorted table made at compile time from the
//! tables of the modules that own the values.
//!
//! | range | owner |
//! |---|---|
//! | 0x1000-0x10FF | [`crate::comm`] (device type, names, store/restore, identity, error settings) |
//! | 0x1600-0x1C33 | `ecat_slave_stack::pdo` (mapping, assignment, sync manager parameters; served by the slave runtime) |
//! | 0x2000-0x21FF | [`crate::params`] (vendor parameters) |
//! | 0x2200 | `ecat_slave_stack::sync` (timing diagnostics; served by the slave runtime) |
//! | 0x2400 | [`crate::faults`] (fault history) |
//! | 0x2500 | [`crate::monitor`] (monitoring) |
//! | 0x6000-0x6FFF | [`crate::cia402`] (drive profile) |
//!
//! The same table feeds the SDO server, PDO mapping rules, SDO information, the ESI,
//! the SII and the generated reference (`cargo xtask od-doc`), so they cannot disagree.

use ecat_slave_stack::od::{self, Access, DataType, Entry, Object, SdoAbort};

const PLACEHOLDER_ENTRY: Entry = Entry::new(0, "", DataType::Unsigned8, Access::RO);
const PLACEHOLDER: Object = Object::var(0, "", &[PLACEHOLDER_ENTRY], "");

const PARTS: &[&[Object]] = &[
    crate::comm::OBJECTS,
    ecat_slave_stack::pdo::OBJECTS,
    crate::params::OBJECTS,
    ecat_slave_stack::sync::DIAG_OBJECTS,
    crate::faults::OBJECTS,
    crate::monitor::OBJECTS,
    crate::cia402::objects::OBJECTS,
];

const fn total(parts: &[&[Object]]) -> usize {
    let mut n = 0;
    let mut i = 0;
    while i < parts.len() {
        n += parts[i].len();
        i += 1;
    }
    n
}

/// Concatenates the parts and sorts by index (insertion sort, at compile time).
const fn merge<const N: usize>(parts: &[&[Object]]) -> [Object; N] {
    let mut out = [PLACEHOLDER; N];
    let mut n = 0;
    let mut p = 0;
    while p < parts.len() {
        let mut i = 0;
        while i < parts[p].len() {
            out[n] = parts[p][i];
            n += 1;
            i += 1;
        }
        p += 1;
    }
    let mut i = 1;
    while i < N {
        let mut j = i;
        while j > 0 && out[j - 1].index > out[j].index {
            let t = out[j - 1];
            out[j - 1] = out[j];
            out[j] = t;
            j -= 1;
        }
        i += 1;
    }
    out
}

const fn strictly_sorted(objects: &[Object]) -> bool {
    let mut i = 1;
    while i < objects.len() {
        if objects[i - 1].index >= objects[i].index {
            return false;
        }
        i += 1;
    }
    true
}

const COUNT: usize = total(PARTS);
static TABLE: [Object; COUNT] = merge::<COUNT>(PARTS);
const _: () = assert!(
    strictly_sorted(&merge::<COUNT>(PARTS)),
    "two modules describe the same index"
);

/// Every object of the drive, sorted by index.
pub static OBJECTS: &[Object] = &TABLE;

/// True when the table is well formed (sorted objects, sorted sub-indices).
pub fn is_well_formed() -> bool {
    od::is_well_formed(OBJECTS)
}

/// Index ranges of the modules that look their entries up here: every object of
/// [`OBJECTS`] inside a range is one of that module's (tested below).
pub(crate) const COMM: (u16, u16) = (0x1000, 0x10FF);
pub(crate) const PARAMS: (u16, u16) = (0x2000, 0x21FF);
pub(crate) const MONITOR: (u16, u16) = (0x2300, 0x23FF);
pub(crate) const FAULTS: (u16, u16) = (0x2400, 0x24FF);
pub(crate) const CIA402: (u16, u16) = (0x6000, 0x6FFF);

/// Object `index` of a module owning `range`: the same answer as
/// `od::find(module::OBJECTS, index)`, without a second copy of the module's table in
/// flash (a module's `const OBJECTS` used at run time is its own array beside
/// [`TABLE`]).
pub(crate) fn find_in(range: (u16, u16), index: u16) -> Option<&'static Object> {
    if index < range.0 || index > range.1 {
        return None;
    }
    od::find(OBJECTS, index)
}

/// The answer of a module's SDO read: the low `entry.byte_len()` bytes of `v`
/// (little-endian) into `buf`; "exceeds mailbox" when they do not fit. One copy for
/// every module's read instead of one inlined per module.
#[inline(never)]
pub(crate) fn put_le(entry: &Entry, v: u64, buf: &mut [u8]) -> Result<usize, SdoAbort> {
    let len = entry.byte_len();
    let out = buf.get_mut(..len).ok_or(SdoAbort::ExceedsMailbox)?;
    let n = len.min(8);
    out[..n].copy_from_slice(&v.to_le_bytes()[..n]);
    Ok(len)
}

/// Entry `index:sub` of a module owning `range` (as `od::find_entry(module::OBJECTS,
/// ..)`: no object → `ObjectDoesNotExist`, no sub-index → `SubindexDoesNotExist`).
pub(crate) fn find_entry_in(
    range: (u16, u16),
    index: u16,
    sub: u8,
) -> Result<&'static Entry, SdoAbort> {
    let obj = find_in(range, index).ok_or(SdoAbort::ObjectDoesNotExist)?;
    obj.entry(sub).ok_or(SdoAbort::SubindexDoesNotExist)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn module_ranges_hold_exactly_the_module_tables() {
        let modules: [(&[Object], (u16, u16)); 5] = [
            (crate::comm::OBJECTS, COMM),
            (crate::params::OBJECTS, PARAMS),
            (crate::monitor::OBJECTS, MONITOR),
            (crate::faults::OBJECTS, FAULTS),
            (crate::cia402::objects::OBJECTS, CIA402),
        ];
        for (own, range) in modules {
            for o in own {
                assert!((range.0..=range.1).contains(&o.index), "{:#06x}", o.index);
            }
            for index in 0..=u16::MAX {
                let mine = od::find(own, index);
                let found = find_in(range, index);
                assert_eq!(mine.is_some(), found.is_some(), "{index:#06x}");
                if let (Some(a), Some(b)) = (mine, found) {
                    assert_eq!(a.name(), b.name());
                    assert_eq!(a.entries().len(), b.entries().len());
                    for sub in 0..=u8::MAX {
                        assert_eq!(
                            od::find_entry(own, index, sub).map(|e| (e.sub, e.name())),
                            find_entry_in(range, index, sub).map(|e| (e.sub, e.name())),
                            "{index:#06x}:{sub}"
                        );
                    }
                }
                if mine.is_none() {
                    for sub in [0, 1, 255] {
                        assert_eq!(
                            find_entry_in(range, index, sub).err(),
                            Some(SdoAbort::ObjectDoesNotExist)
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn table_is_sorted_and_complete() {
        assert!(is_well_formed());
        let total: usize = PARTS.iter().map(|p| p.len()).sum();
        assert_eq!(OBJECTS.len(), total);
        for index in [
            0x1000, 0x1018, 0x1600, 0x1A00, 0x1C12, 0x1C32, 0x2000, 0x2152, 0x2200, 0x6040, 0x6041,
            0x607A, 0x6502,
        ] {
            assert!(od::find(OBJECTS, index).is_some(), "{index:#06x} missing");
        }
    }
}
