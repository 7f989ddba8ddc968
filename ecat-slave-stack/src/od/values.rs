//! [`Values`]: how an application module binds its entries to its state.

use super::{Entry, ObjectKey, SdoAbort};

/// The values behind one owner's objects: how an application module binds its entries
/// to its state. The dispatcher finds the entry in the dictionary, runs the generic
/// checks and the conversion between bytes and numbers once, and hands the owner the
/// entry's key and description; the owner reads or stores the number. `C` is what else
/// the owner's values are made of and it does not own (nothing for most owners).
pub trait Values<C: ?Sized = ()> {
    /// The value of the numeric entry `key` (described by `entry`), sign- or
    /// zero-extended as its data type says.
    fn get(&self, cx: &C, key: ObjectKey, entry: &Entry) -> Result<i64, SdoAbort>;
    /// Stores `value` for `key`; it has passed the access, length and range checks of
    /// `entry`. The default refuses: read-only values.
    fn set(
        &mut self,
        cx: &mut C,
        key: ObjectKey,
        entry: &Entry,
        value: i64,
    ) -> Result<(), SdoAbort> {
        let _ = (cx, key, entry, value);
        Err(SdoAbort::WriteReadOnly)
    }
    /// The bytes of an entry the owner answers as bytes (strings, octet strings, a
    /// record kept in its wire form), `None` for the numeric ones ([`Values::get`]).
    fn read_bytes(
        &self,
        cx: &C,
        key: ObjectKey,
        entry: &Entry,
        buf: &mut [u8],
    ) -> Option<Result<usize, SdoAbort>> {
        let _ = (cx, key, entry, buf);
        None
    }
}
