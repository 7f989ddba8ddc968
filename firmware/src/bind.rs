//! One row per entry: its description and its binding to the owner's state, for the
//! owners of plain object tables (`monitor`, `comm`, `scope`, the fault history).
//!
//! `bound_objects!` takes the owner's objects, each a list of
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
//! without a `set` "write a read-only object". Arms match on `index << 8 | sub-index`, the
//! sub-index as the entry's description states it.
//!
//! [`Values::get`]: ecat_slave_stack::od::Values::get

use ecat_slave_stack::od::SdoAbort;

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
                let v: i64 = 'bound: {
                    $($(
                        $crate::bind::bound_objects!(@get 'bound, self, cx, key, entry, k,
                            $index, $entry, $kind $([$($gp),+] $get)?);
                    )*)*
                    return Err(::ecat_slave_stack::od::SdoAbort::ObjectDoesNotExist);
                };
                Ok(v)
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
                    if k == $crate::bind::bound_objects!(@key $index, $entry) {
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
    // `index << 8 | sub-index` of a row, the sub-index from its description (compile
    // time).
    (@key $index:expr, $entry:expr) => {{
        const KEY: u32 =
            ($index as u32) << 8 | ::ecat_slave_stack::od::EntryDesc::sub(&$entry) as u32;
        KEY
    }};
    (@get $l:lifetime, $s:ident, $cx:ident, $key:ident, $e:ident, $k:ident, $index:expr,
        $entry:expr, get [$($gp:tt),+] $get:expr) => {
        if $k == $crate::bind::bound_objects!(@key $index, $entry) {
            $crate::bind::bound_objects!(@let [$($gp),+] [$s, $cx, $key, $e]);
            break $l i64::from($get);
        }
    };
    (@get $l:lifetime, $s:ident, $cx:ident, $key:ident, $e:ident, $k:ident, $index:expr, $entry:expr, bytes) => {};
    (@get $l:lifetime, $s:ident, $cx:ident, $key:ident, $e:ident, $k:ident, $index:expr, $entry:expr, count) => {};
    (@get $l:lifetime, $s:ident, $cx:ident, $key:ident, $e:ident, $k:ident, $index:expr, $entry:expr, elsewhere) => {};
    // The binding's parameters, from the left, as the owner's arguments.
    (@let [$p:tt $(, $ps:tt)*] [$a:ident $(, $as:ident)*]) => {
        let $p = $a;
        $crate::bind::bound_objects!(@let [$($ps),*] [$($as),*]);
    };
    (@let [] [$($as:ident),*]) => {};
}

pub(crate) use bound_objects;

#[cfg(test)]
mod tests {
    use ecat_slave_stack::od::{
        self, Access, DataType, EntryDesc, ObjectKey, PdoMappable, SdoAbort, Values,
    };

    /// An owner with every kind of row.
    #[derive(Default)]
    struct Toy {
        a: i16,
        b: u8,
    }

    impl Toy {
        fn bytes(&self, _: &(), key: ObjectKey, buf: &mut [u8]) -> Option<Result<usize, SdoAbort>> {
            (key == ObjectKey::new(0x2001, 2)).then(|| {
                buf[0] = 7;
                Ok(1)
            })
        }
    }

    super::bound_objects! {
        impl Values<()> for Toy, bytes by Toy::bytes;
        var 0x2000, "A", "a", {
            EntryDesc::new(0, "A", DataType::Integer16, Access::RW).pdo(PdoMappable::Tx)
                => get |t| t.a, set |t, v| t.a = v as i16;
        }
        record 0x2001, "B", "b", {
            EntryDesc::count(3) => count;
            EntryDesc::new(1, "B", DataType::Unsigned8, Access::RW)
                => get |t, _, key| t.b + key.sub, set |t, v| {
                    if v > 100 {
                        return Err(SdoAbort::ValueRangeExceeded);
                    }
                    t.b = v as u8
                };
            EntryDesc::octets(2, "Block", 1) => bytes;
            EntryDesc::new(3, "Other", DataType::Unsigned8, Access::RO) => elsewhere;
        }
    }

    #[test]
    fn rows_describe_and_bind() {
        static PACKED: &[od::Object] = ecat_slave_stack::packed_dictionary!(&[OBJECTS]);
        assert!(od::is_well_formed(PACKED));
        let e = |i, s| *od::find_entry(PACKED, ObjectKey::new(i, s)).unwrap();
        let mut t = Toy::default();
        let k = ObjectKey::new;
        assert_eq!(t.set(&mut (), k(0x2000, 0), &e(0x2000, 0), -5), Ok(()));
        assert_eq!(t.get(&(), k(0x2000, 0), &e(0x2000, 0)), Ok(-5));
        assert_eq!(t.set(&mut (), k(0x2001, 1), &e(0x2001, 1), 40), Ok(()));
        assert_eq!(t.get(&(), k(0x2001, 1), &e(0x2001, 1)), Ok(41));
        // A refused store keeps the value.
        assert_eq!(
            t.set(&mut (), k(0x2001, 1), &e(0x2001, 1), 101),
            Err(SdoAbort::ValueRangeExceeded)
        );
        assert_eq!(t.b, 40);
        // Rows without a `get` / `set`, and keys without a row.
        for s in [0, 2, 3] {
            assert_eq!(
                t.get(&(), k(0x2001, s), &e(0x2001, s)),
                Err(SdoAbort::ObjectDoesNotExist)
            );
            assert_eq!(
                t.set(&mut (), k(0x2001, s), &e(0x2001, s), 1),
                Err(SdoAbort::WriteReadOnly)
            );
        }
        assert_eq!(
            t.get(&(), k(0x2002, 0), &e(0x2000, 0)),
            Err(SdoAbort::ObjectDoesNotExist)
        );
        let mut buf = [0u8; 1];
        assert_eq!(
            t.read_bytes(&(), k(0x2001, 2), &e(0x2001, 2), &mut buf),
            Some(Ok(1))
        );
        assert_eq!(buf[0], 7);
        assert_eq!(
            t.read_bytes(&(), k(0x2000, 0), &e(0x2000, 0), &mut buf),
            None
        );
    }
}
