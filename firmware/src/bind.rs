//! One row per entry: its description and its binding to the owner's state, for the
//! owners of plain object tables (`monitor`, `comm`, `scope`, the fault history).
//!
//! [`bound_objects!`] takes the owner's objects, each a list of
//! rows `description => binding;`, and writes both the owner's `OBJECTS` table and its
//! `impl Values` (`get` / `set`), so an entry is described and bound in one place:
//!
//! ```text
//! bound_objects! {
//!     impl Values<()> for Monitor;
//!     var 0x2300, "Electrical angle", "Electrical angle used by the current loop", {
//!         tx("Electrical angle", DataType::Unsigned16, "1/65536 turn") => get |m| m.m.electrical_angle;
//!     }
//!     record 0x2500, "Scope configuration", "…", {
//!         EntryDesc::count(8) => count;
//!         rw(1, "Sample divisor", U16, 1, 1, 1000) => get |s| s.divisor, set |s, v| s.divisor = v as u16;
//!     }
//! }
//! ```
//!
//! A binding is one of
//! - `get |s, cx, key, entry| value` — the value (any integer or `bool`; it becomes
//!   the `i64` of [`Values::get`]); `s` is the owner, the context `cx`, the
//!   `ObjectKey` `key` and the packed `Entry` may be left out from the right;
//! - `bytes` — the owner answers the entry as bytes, in the function the header names
//!   (`impl Values<C> for T, bytes by T::f;`, `f(&self, &C, ObjectKey, &mut [u8])`
//!   being `Values::read_bytes`);
//! - `count` — the read-only count of an array or record, answered by the dictionary
//!   from the description;
//! - `elsewhere` — another owner's `Values` answers it (the scope's internal signals
//!   0x2510 are the drive's);
//!
//! optionally followed by `, set |s, v, cx, key, entry| store` (`v` the checked `i64`; the
//! store is `()` or a `Result<(), SdoAbort>`, and may use `?`). Every entry has one row,
//! so every entry has a binding; a read of an entry without a `get` (a `bytes` or
//! `count` row the dispatcher did not answer) is "object does not exist", a write
//! without a `set` "write a read-only object". Arms match on the entry's
//! `(index, sub-index)` as the description states it.
//!
//! [`Values::get`]: ecat_slave_stack::od::Values::get

use ecat_slave_stack::od::{EntryDesc, SdoAbort};

/// The `(index, sub-index)` of an entry as one number (what the arms compare).
pub const fn key(index: u16, entry: &EntryDesc) -> u32 {
    (index as u32) << 8 | entry.sub() as u32
}

/// The result of a `set` binding: a plain store or one that can refuse.
pub trait Stored {
    /// As the `Values::set` result.
    fn stored(self) -> Result<(), SdoAbort>;
}

impl Stored for () {
    #[inline(always)]
    fn stored(self) -> Result<(), SdoAbort> {
        Ok(())
    }
}

impl Stored for Result<(), SdoAbort> {
    #[inline(always)]
    fn stored(self) -> Result<(), SdoAbort> {
        self
    }
}

/// Writes `OBJECTS` and `impl Values` from rows `description => binding;` (see the
/// module documentation).
macro_rules! bound_objects {
    (
        impl Values<$cx_ty:ty> for $owner:ty $(, bytes by $bytes:path)?;
        $(
            $code:ident $index:expr, $name:literal, $text:expr, {
                $(
                    $entry:expr => $kind:ident $(|$($gp:tt),+| $get:expr)?
                        $(, set |$($sp:tt),+| $set:expr)?;
                )*
            }
        )*
    ) => {
        /// The objects of this owner, sorted; their values are bound in the same rows.
        pub const OBJECTS: &[::ecat_slave_stack::od::ObjectDesc] = &[
            $(::ecat_slave_stack::od::ObjectDesc::$code($index, $name, &[$($entry),*], $text),)*
        ];

        impl ::ecat_slave_stack::od::Values<$cx_ty> for $owner {
            #[allow(unused_variables, clippy::unnecessary_cast, clippy::useless_conversion)]
            fn get(
                &self,
                cx: &$cx_ty,
                key: ::ecat_slave_stack::od::ObjectKey,
                entry: &::ecat_slave_stack::od::Entry,
            ) -> Result<i64, ::ecat_slave_stack::od::SdoAbort> {
                let k = u32::from(key.index) << 8 | u32::from(key.sub);
                $($(
                    $crate::bind::bound_objects!(@get self, cx, key, entry, k, $index, $entry, $kind
                        $([$($gp),+] $get)?);
                )*)*
                Err(::ecat_slave_stack::od::SdoAbort::ObjectDoesNotExist)
            }

            #[allow(unused_variables, clippy::unnecessary_cast, clippy::useless_conversion)]
            fn set(
                &mut self,
                cx: &mut $cx_ty,
                key: ::ecat_slave_stack::od::ObjectKey,
                entry: &::ecat_slave_stack::od::Entry,
                value: i64,
            ) -> Result<(), ::ecat_slave_stack::od::SdoAbort> {
                let k = u32::from(key.index) << 8 | u32::from(key.sub);
                $($($(
                    if k == { const K: u32 = $crate::bind::key($index, &$entry); K } {
                        $crate::bind::bound_objects!(@let [$($sp),+] [self, value, cx, key, entry]);
                        return $crate::bind::Stored::stored($set);
                    }
                )?)*)*
                Err(::ecat_slave_stack::od::SdoAbort::WriteReadOnly)
            }

            $(
                fn read_bytes(
                    &self,
                    cx: &$cx_ty,
                    key: ::ecat_slave_stack::od::ObjectKey,
                    _: &::ecat_slave_stack::od::Entry,
                    buf: &mut [u8],
                ) -> Option<Result<usize, ::ecat_slave_stack::od::SdoAbort>> {
                    $bytes(self, cx, key, buf)
                }
            )?
        }
    };
    (@get $s:ident, $cx:ident, $key:ident, $e:ident, $k:ident, $index:expr, $entry:expr, get
        [$($gp:tt),+] $get:expr) => {
        if $k == { const K: u32 = $crate::bind::key($index, &$entry); K } {
            $crate::bind::bound_objects!(@let [$($gp),+] [$s, $cx, $key, $e]);
            return Ok(i64::from($get));
        }
    };
    (@get $s:ident, $cx:ident, $key:ident, $e:ident, $k:ident, $index:expr, $entry:expr, bytes) => {};
    (@get $s:ident, $cx:ident, $key:ident, $e:ident, $k:ident, $index:expr, $entry:expr, count) => {};
    (@get $s:ident, $cx:ident, $key:ident, $e:ident, $k:ident, $index:expr, $entry:expr, elsewhere) => {};
    // The binding's parameters, from the left, as the owner's arguments.
    (@let [$p:tt $(, $ps:tt)*] [$a:ident $(, $as:ident)*]) => {
        let $p = $a;
        $crate::bind::bound_objects!(@let [$($ps),*] [$($as),*]);
    };
    (@let [] [$($as:ident),*]) => {};
}

pub(crate) use bound_objects;
