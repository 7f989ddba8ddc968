//! The dictionary side of a parameter record: which entries a 'save' stores
//! ([`entries`]) and how a 'load' writes each back ([`apply`], with sub-index 0 of
//! mapping-like objects first written 0 and restored last, [`PendingCount`]).

use super::{LoadReport, SaveReport, Scope, StorageError, MAX_VALUE_LEN};
use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::od::{self, Dictionary, ObjectCode, ObjectKey, SdoAbort};

/// A restored sub-index 0 waiting for the other sub-indices of its object.
pub(super) struct PendingCount {
    pub(super) index: u16,
    pub(super) value: [u8; 8],
    pub(super) len: usize,
}

impl PendingCount {
    /// The value's bytes (`len` ≤ 8 by construction; `min` keeps the slice checked
    /// without a panic path).
    pub(super) fn bytes(&self) -> &[u8] {
        &self.value[..self.len.min(8)]
    }
}

/// Where [`entries`] hands each entry (its head, its value).
pub(super) type EmitEntry<'a> = dyn FnMut(&[u8], &[u8]) -> Result<(), StorageError> + 'a;

/// Every `saved` entry of `dict` inside `scope` (for mapping-like objects only the
/// sub-indices inside the count: the rest may hold values the rules refuse) to `emit`
/// as its entry head `index u16, sub u8, len u8` and value, counted in `report`;
/// unreadable ones are left out and counted.
pub(super) fn entries<D: Dictionary + ?Sized>(
    dict: &mut D,
    scope: Scope,
    report: &mut SaveReport,
    emit: &mut EmitEntry<'_>,
) -> Result<(), StorageError> {
    let mut value = [0u8; MAX_VALUE_LEN];
    for obj in dict.objects().iter().filter(|o| scope.contains(o.index)) {
        let limit = if has_count_first(obj) {
            match dict.read(ObjectKey::new(obj.index, 0), &mut value) {
                Ok(1) => Some(value[0]),
                _ => None,
            }
        } else {
            None
        };
        for e in obj
            .entries()
            .iter()
            .filter(|e| e.is_saved() && limit.is_none_or(|n| e.sub <= n))
        {
            match dict.read(ObjectKey::new(obj.index, e.sub), &mut value) {
                Ok(n) if n <= MAX_VALUE_LEN => {
                    let i = obj.index.to_le_bytes();
                    emit(&[i[0], i[1], e.sub, n as u8], &value[..n])?;
                    report.entries += 1;
                }
                _ => report.unreadable += 1,
            }
        }
    }
    Ok(())
}

/// True when `index` is an object whose saved, writable sub-index 0 must be written 0
/// before its other sub-indices (PDO mapping / assignment).
pub(super) fn count_first<D: Dictionary + ?Sized>(dict: &D, index: u16) -> bool {
    od::find(dict.objects(), index).is_some_and(has_count_first)
}

fn has_count_first(o: &od::Object) -> bool {
    o.code() != ObjectCode::Var
        && o.entries().len() > 1
        && o.entry(0)
            .is_some_and(|e| e.is_saved() && e.access.writable())
}

pub(super) fn apply<D: Dictionary + ?Sized>(
    dict: &mut D,
    key: ObjectKey,
    data: &[u8],
    report: &mut LoadReport,
) {
    let ok = match od::find_entry(dict.objects(), key) {
        Ok(e) if e.is_saved() => {
            let len_ok = if e.data_type.is_variable_length() {
                data.len() <= e.byte_len()
            } else {
                data.len() == e.byte_len()
            };
            let range_ok = match od::decode_int(e.data_type, data) {
                Some(v) => v >= e.min() && v <= e.max(),
                None => true,
            };
            len_ok
                && range_ok
                && match dict.write(key, data, EsmState::PreOp) {
                    Ok(()) => true,
                    // The device owns the value right now (e.g. current gains while
                    // auto-tune is on): not an error of the record.
                    Err(SdoAbort::LocalControl) => {
                        return;
                    }
                    Err(_) => false,
                }
        }
        _ => false,
    };
    if ok {
        report.applied = report.applied.saturating_add(1);
    } else {
        report.skipped = report.skipped.saturating_add(1);
    }
}
