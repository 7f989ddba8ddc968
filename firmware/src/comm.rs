//! Product communication objects: 0x1000 device type, 0x1001 error register, 0x1003
//! pre-defined error field (the fault history in CiA 301 form), 0x1008-0x100A names
//! and versions, 0x1010 store, 0x1011 restore defaults, 0x1018 identity, 0x10F1 error
//! settings.
//!
//! Store / restore (CiA 301, 0x1010 / 0x1011):
//! * 'save' (0x65766173) written to 0x1010:01-04 → [`StoreCommand::Save`];
//! * 'load' (0x64616F6C) written to 0x1011:01-04 → [`StoreCommand::RestoreDefaults`];
//! * 'load' written to 0x1010:04 (E5 behaviour) → restore defaults of all parameters;
//! * any other value → abort 0x08000020.
//!
//! Sub-index 1 and 4 cover all parameters, 2 the communication area (0x1000-0x1FFF,
//! including the PDO mapping and assignment), 3 the application area (0x6000-0x9FFF).
//! A write of 0x1010 / 0x1011 only decodes the command
//! ([`Comm::take_store_command`]); the dictionary owner runs it with [`execute`] (it needs the whole dictionary and the flash) and answers the SDO with
//! its result. Restored defaults take effect at the next power-up (CiA 301).
//! Reading 0x1010 / 0x1011 sub 1-4 gives 1: "saves / restores on command".
//!
//! 0x1003: sub-index 0 = number of entries (writing 0 clears the history, anything
//! else is refused with 0x06090030); sub-index n = error code (bits 0-15) and fault
//! kind (bits 16-23) of the n-th newest fault.

use ecat_slave_stack::od::{
    Access, DataType, Dictionary, Entry, EntryDesc, ObjectKey, PdoMappable, SdoAbort,
};
use embedded_storage::nor_flash::NorFlash;

use crate::bind::bound_objects;
use crate::diagnosis::HISTORY_LEN;
use crate::faults::{Faults, HISTORY};
use crate::identity::{self, Identity};
use crate::storage::{SaveReport, Scope, Storage, StorageError};
use ecat_slave_stack::diag;

/// 'save' signature.
pub const SAVE: u32 = 0x6576_6173;
/// 'load' signature.
pub const LOAD: u32 = 0x6461_6F6C;

/// A store / restore command decoded from 0x1010 / 0x1011.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StoreCommand {
    /// Store the parameters of the scope.
    Save(Scope),
    /// Restore the defaults of the scope (effective after restart).
    RestoreDefaults(Scope),
}

/// Runs a store command against the flash and the whole dictionary.
pub fn execute<F: NorFlash, D: Dictionary + ?Sized>(
    cmd: StoreCommand,
    storage: &Storage,
    flash: &mut F,
    dict: &mut D,
) -> Result<SaveReport, StorageError> {
    // One instance of the record writer for both commands.
    match cmd {
        StoreCommand::Save(scope) => storage.write_record(flash, Some(dict), scope),
        StoreCommand::RestoreDefaults(scope) => storage.write_record::<F, D>(flash, None, scope),
    }
}

const fn cmd(sub: u8, name: &'static str) -> EntryDesc {
    EntryDesc::new(sub, name, DataType::Unsigned32, Access::RW).default(1)
}

const fn ro32(sub: u8, name: &'static str) -> EntryDesc {
    EntryDesc::new(sub, name, DataType::Unsigned32, Access::RO)
}

const NAME_BITS: u16 = identity::MAX_NAME_LEN as u16;

// The communication objects of the product and their values; the error register, the
// error field and the diagnosis history are the drive's [`Faults`].
bound_objects! {
    impl Values<Faults> for Comm, bytes by Comm::bytes;
    var 0x1000, "Device type", "CiA 402 drive: 0x00020192 hybrid servo, 0x00040192 stepper", {
        ro32(0, "Device type").default(0x0002_0192) => get |c| c.identity.variant.device_type();
    }
    var 0x1001, "Error register", "b0 generic, b1 current, b2 voltage, b4 communication (EtherCAT), b5 profile, b7 drive alarm (any fault but the EtherCAT one)", {
        EntryDesc::new(0, "Error register", DataType::Unsigned8, Access::RO)
            .pdo(PdoMappable::Tx)
            .default(0)
            => get |_, f| f.error_register();
    }
    array 0x1003, "Pre-defined error field", "Newest fault first: bits 0-15 error code, bits 16-23 fault kind; write 0 to sub 0 clears", {
        EntryDesc::new(0, "Number of errors", DataType::Unsigned8, Access::RW).default(0)
            => get |_, f| f.history_len() as u32, set |_, v, f| clear_history(f, v);
        ro32(1, "Standard error field 1") => get |_, f, key| error_field(f, key.sub);
        ro32(2, "Standard error field 2") => get |_, f, key| error_field(f, key.sub);
        ro32(3, "Standard error field 3") => get |_, f, key| error_field(f, key.sub);
        ro32(4, "Standard error field 4") => get |_, f, key| error_field(f, key.sub);
        ro32(5, "Standard error field 5") => get |_, f, key| error_field(f, key.sub);
        ro32(6, "Standard error field 6") => get |_, f, key| error_field(f, key.sub);
    }
    var 0x1008, "Device name", "Device name", {
        EntryDesc::text(0, "Device name", NAME_BITS, "ECS-HS EtherCAT hybrid servo") => bytes;
    }
    var 0x1009, "Hardware version", "Hardware version", {
        EntryDesc::text(0, "Hardware version", 8, identity::HARDWARE_VERSION) => bytes;
    }
    var 0x100A, "Software version", "Software version", {
        EntryDesc::text(0, "Software version", 16, identity::SOFTWARE_VERSION) => bytes;
    }
    array 0x1010, "Store parameters", "Write 'save' (0x65766173); 'load' to sub 4 restores defaults", {
        EntryDesc::count(4) => count;
        cmd(1, "Save all parameters") => get |_| 1, set |c, v| c.store(1, v);
        cmd(2, "Save communication parameters") => get |_| 1, set |c, v| c.store(2, v);
        cmd(3, "Save application parameters") => get |_| 1, set |c, v| c.store(3, v);
        cmd(4, "Save all parameters (E5)") => get |_| 1, set |c, v| c.store(4, v);
    }
    array 0x1011, "Restore default parameters", "Write 'load' (0x64616F6C); effective after restart", {
        EntryDesc::count(4) => count;
        cmd(1, "Restore all defaults") => get |_| 1, set |c, v| c.restore(1, v);
        cmd(2, "Restore communication defaults") => get |_| 1, set |c, v| c.restore(2, v);
        cmd(3, "Restore application defaults") => get |_| 1, set |c, v| c.restore(3, v);
        cmd(4, "Restore all defaults (E5)") => get |_| 1, set |c, v| c.restore(4, v);
    }
    record 0x1018, "Identity", "Identity (equals the SII)", {
        EntryDesc::count(4) => count;
        ro32(1, "Vendor ID").default(identity::VENDOR_ID as i64) => get |c| c.identity.vendor_id();
        ro32(2, "Product code").default(0x5840) => get |c| c.identity.product_code();
        ro32(3, "Revision").default(identity::REVISION as i64) => get |c| c.identity.revision();
        ro32(4, "Serial number") => get |c| c.identity.serial;
    }
    record 0x10F1, "Error settings", "Sync error counter limit used by the sync supervision", {
        EntryDesc::count(2) => count;
        EntryDesc::new(1, "Local error reaction", DataType::Unsigned32, Access::RW)
            .default(1)
            .saved()
            => get |c| c.local_error_reaction, set |c, v| c.local_error_reaction = v as u32;
        EntryDesc::new(2, "Sync error counter limit", DataType::Unsigned16, Access::RW)
            .default(4)
            .saved()
            => get |c| c.sync_error_limit, set |c, v| c.sync_error_limit = v as u16;
    }
    record 0x10F3, "Diagnosis history", "ETG.1020 diagnosis history: one message per fault, emergency and notable event (ring of 16; SI3 = 0 clears, SI3 = n acknowledges)", {
        EntryDesc::count(diag::FIRST_MESSAGE_SUB - 1 + HISTORY_LEN as u8) => count;
        EntryDesc::new(1, "Maximum messages", DataType::Unsigned8, Access::RO)
            .default(HISTORY_LEN as i64)
            => bytes;
        EntryDesc::new(2, "Newest message", DataType::Unsigned8, Access::RO).default(0) => bytes;
        EntryDesc::new(3, "Newest acknowledged message", DataType::Unsigned8, Access::RW)
            .default(0)
            => bytes, set |_, v, f, key, e| write_diagnosis(f, key.sub, e, v);
        EntryDesc::new(4, "New messages available", DataType::Boolean, Access::RO).default(0)
            => bytes;
        EntryDesc::new(5, "Flags", DataType::Unsigned16, Access::RW).default(0)
            => bytes, set |_, v, f, key, e| write_diagnosis(f, key.sub, e, v);
        msg(6, "Diagnosis message 001") => bytes;
        msg(7, "Diagnosis message 002") => bytes;
        msg(8, "Diagnosis message 003") => bytes;
        msg(9, "Diagnosis message 004") => bytes;
        msg(10, "Diagnosis message 005") => bytes;
        msg(11, "Diagnosis message 006") => bytes;
        msg(12, "Diagnosis message 007") => bytes;
        msg(13, "Diagnosis message 008") => bytes;
        msg(14, "Diagnosis message 009") => bytes;
        msg(15, "Diagnosis message 010") => bytes;
        msg(16, "Diagnosis message 011") => bytes;
        msg(17, "Diagnosis message 012") => bytes;
        msg(18, "Diagnosis message 013") => bytes;
        msg(19, "Diagnosis message 014") => bytes;
        msg(20, "Diagnosis message 015") => bytes;
        msg(21, "Diagnosis message 016") => bytes;
    }
}

const fn msg(sub: u8, name: &'static str) -> EntryDesc {
    EntryDesc::octets(sub, name, diag::MESSAGE_LEN as u16)
}

const _: () = assert!(HISTORY_LEN == 16, "one 0x10F3 entry per message");

/// State of the communication objects.
#[derive(Debug, Clone)]
pub struct Comm {
    identity: Identity,
    local_error_reaction: u32,
    sync_error_limit: u16,
    store: Option<StoreCommand>,
}

impl Comm {
    /// Defaults for `identity`.
    pub fn new(identity: Identity) -> Self {
        Comm {
            identity,
            local_error_reaction: 1,
            sync_error_limit: 4,
            store: None,
        }
    }

    /// The identity.
    pub fn identity(&self) -> Identity {
        self.identity
    }

    /// 0x10F1:02 (the sync supervision reads it).
    pub fn sync_error_limit(&self) -> u16 {
        self.sync_error_limit
    }

    /// 0x10F1:01.
    pub fn local_error_reaction(&self) -> u32 {
        self.local_error_reaction
    }

    /// The store / restore command the last write of 0x1010 / 0x1011 decoded, once:
    /// the dictionary owner runs it with [`execute`] and answers the SDO with its
    /// result.
    pub fn take_store_command(&mut self) -> Option<StoreCommand> {
        self.store.take()
    }
}

/// 0x1003:`sub` (the sub-th newest fault): error code and fault kind, 0 when empty.
fn error_field(faults: &Faults, sub: u8) -> u32 {
    faults
        .history(usize::from(sub) - 1)
        .map_or(0, |r| u32::from(r.code) | u32::from(r.kind as u8) << 16)
}

/// 0x1003:00 = `v`: 0 clears the history, anything else is refused.
fn clear_history(faults: &mut Faults, v: i64) -> Result<(), SdoAbort> {
    if v != 0 {
        return Err(SdoAbort::ValueRangeExceeded);
    }
    faults.clear_history();
    Ok(())
}

/// 0x10F3:`sub` = `v` (an entry of the history's own rules: acknowledge, flags).
fn write_diagnosis(faults: &mut Faults, sub: u8, entry: &Entry, v: i64) -> Result<(), SdoAbort> {
    let bytes = v.to_le_bytes();
    let len = entry.byte_len().min(bytes.len());
    faults.diagnosis_mut().write(sub, &bytes[..len])
}

impl Comm {
    /// 0x1010:`sub` = `v`: kept for [`Comm::take_store_command`].
    fn store(&mut self, sub: u8, v: i64) -> Result<(), SdoAbort> {
        let scope = Scope::from_sub(sub).ok_or(SdoAbort::SubindexDoesNotExist)?;
        self.store = Some(match v as u32 {
            SAVE => StoreCommand::Save(scope),
            LOAD if sub == 4 => StoreCommand::RestoreDefaults(Scope::All),
            _ => return Err(SdoAbort::DataCannotBeStored),
        });
        Ok(())
    }

    /// 0x1011:`sub` = `v`: kept for [`Comm::take_store_command`].
    fn restore(&mut self, sub: u8, v: i64) -> Result<(), SdoAbort> {
        let scope = Scope::from_sub(sub).ok_or(SdoAbort::SubindexDoesNotExist)?;
        self.store = Some(match v as u32 {
            LOAD => StoreCommand::RestoreDefaults(scope),
            _ => return Err(SdoAbort::DataCannotBeStored),
        });
        Ok(())
    }

    /// The names and versions, and the diagnosis history (kept in its wire form).
    fn bytes(
        &self,
        faults: &Faults,
        key: ObjectKey,
        buf: &mut [u8],
    ) -> Option<Result<usize, SdoAbort>> {
        let text = match key.index {
            0x1008 => self.identity.device_name(),
            0x1009 => identity::HARDWARE_VERSION,
            0x100A => identity::SOFTWARE_VERSION,
            0x10F3 => return Some(faults.diagnosis().peek(key.sub, buf)),
            _ => return None,
        };
        Some(match buf.get_mut(..text.len()) {
            Some(out) => {
                out.copy_from_slice(text.as_bytes());
                Ok(text.len())
            }
            None => Err(SdoAbort::ExceedsMailbox),
        })
    }
}

/// Room the longest entry of this table needs in a read buffer.
pub const MAX_READ_LEN: usize = identity::MAX_NAME_LEN;

/// Keeps `HISTORY` and the 0x1003 table in step.
const _: () = assert!(HISTORY == 6);

#[cfg(test)]
mod tests {
    /// The table as the product packs it (with the plain names of its words).
    static PACKED: &[ecat_slave_stack::od::Object] =
        ecat_slave_stack::packed_dictionary!(&[super::OBJECTS]);

    use super::*;
    use crate::faults::{FaultKind, Snapshot};
    use crate::identity::Variant;
    use ecat_slave_stack::esm::EsmState;
    use ecat_slave_stack::od::{self, ObjectKey};

    fn sdo_write(
        c: &mut Comm,
        f: &mut Faults,
        index: u16,
        sub: u8,
        v: u32,
    ) -> Result<Option<StoreCommand>, SdoAbort> {
        let e = od::find_entry(PACKED, ObjectKey::new(index, sub))?;
        let data = &v.to_le_bytes()[..e.byte_len()];
        od::check_write(e, data, EsmState::PreOp)?;
        write(c, f, index, sub, data)
    }

    fn write(
        c: &mut Comm,
        f: &mut Faults,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<Option<StoreCommand>, SdoAbort> {
        crate::dictionary::write_comm(c, f, ObjectKey::new(index, sub), data)
    }

    fn read(c: &Comm, f: &Faults, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        crate::dictionary::read(c, f, ObjectKey::new(index, sub), buf)
    }

    fn rd(c: &Comm, f: &Faults, index: u16, sub: u8) -> u32 {
        let mut buf = [0u8; 4];
        let n = read(c, f, index, sub, &mut buf).unwrap();
        let mut b = [0u8; 4];
        b[..n].copy_from_slice(&buf[..n]);
        u32::from_le_bytes(b)
    }

    #[test]
    fn identity_and_names() {
        assert!(od::is_well_formed(PACKED));
        let f = Faults::default();
        for (v, dt, pc) in [
            (Variant::HybridServo, 0x0002_0192, 0x5840),
            (Variant::OpenLoop, 0x0004_0192, 0x5841),
        ] {
            let c = Comm::new(Identity::new(v, 0xABCD));
            assert_eq!(rd(&c, &f, 0x1000, 0), dt);
            assert_eq!(rd(&c, &f, 0x1018, 0), 4);
            assert_eq!(rd(&c, &f, 0x1018, 1), 0x0E5C);
            assert_eq!(rd(&c, &f, 0x1018, 2), pc);
            assert_eq!(rd(&c, &f, 0x1018, 3), 0x0001_0000);
            assert_eq!(rd(&c, &f, 0x1018, 4), 0xABCD);
            let mut buf = [0u8; 64];
            let n = read(&c, &f, 0x1008, 0, &mut buf).unwrap();
            assert_eq!(&buf[..n], v.device_name().as_bytes());
            let n = read(&c, &f, 0x100A, 0, &mut buf).unwrap();
            assert_eq!(&buf[..n], env!("CARGO_PKG_VERSION").as_bytes());
            assert_eq!(
                read(&c, &f, 0x1008, 0, &mut buf[..4]),
                Err(SdoAbort::ExceedsMailbox)
            );
        }
        let mut c = Comm::new(Identity::new(Variant::HybridServo, 0));
        let mut f = Faults::default();
        assert_eq!(
            sdo_write(&mut c, &mut f, 0x1018, 1, 5),
            Err(SdoAbort::WriteReadOnly)
        );
        assert_eq!(
            sdo_write(&mut c, &mut f, 0x1000, 0, 5),
            Err(SdoAbort::WriteReadOnly)
        );
        assert_eq!(
            write(&mut c, &mut f, 0x1018, 1, &[0; 4]),
            Err(SdoAbort::WriteReadOnly)
        );
    }

    #[test]
    fn store_restore_signatures() {
        let mut c = Comm::new(Identity::new(Variant::HybridServo, 0));
        let mut f = Faults::default();
        for sub in 1..=4u8 {
            assert_eq!(rd(&c, &f, 0x1010, sub), 1);
            assert_eq!(rd(&c, &f, 0x1011, sub), 1);
            let scope = Scope::from_sub(sub).unwrap();
            assert_eq!(
                sdo_write(&mut c, &mut f, 0x1010, sub, SAVE),
                Ok(Some(StoreCommand::Save(scope)))
            );
            assert_eq!(
                sdo_write(&mut c, &mut f, 0x1011, sub, LOAD),
                Ok(Some(StoreCommand::RestoreDefaults(scope)))
            );
            assert_eq!(
                sdo_write(&mut c, &mut f, 0x1011, sub, SAVE),
                Err(SdoAbort::DataCannotBeStored)
            );
            for bad in [0, 1, 0xFFFF_FFFF, SAVE + 1, 0x7361_7665] {
                assert_eq!(
                    sdo_write(&mut c, &mut f, 0x1010, sub, bad),
                    Err(SdoAbort::DataCannotBeStored)
                );
                assert_eq!(
                    sdo_write(&mut c, &mut f, 0x1011, sub, bad),
                    Err(SdoAbort::DataCannotBeStored)
                );
            }
        }
        // E5: 'load' to 0x1010:04 restores every default; not on the other subs.
        assert_eq!(
            sdo_write(&mut c, &mut f, 0x1010, 4, LOAD),
            Ok(Some(StoreCommand::RestoreDefaults(Scope::All)))
        );
        assert_eq!(
            sdo_write(&mut c, &mut f, 0x1010, 1, LOAD),
            Err(SdoAbort::DataCannotBeStored)
        );
        assert_eq!(
            sdo_write(&mut c, &mut f, 0x1010, 0, 4),
            Err(SdoAbort::WriteReadOnly)
        );
        assert_eq!(
            sdo_write(&mut c, &mut f, 0x1010, 5, SAVE),
            Err(SdoAbort::SubindexDoesNotExist)
        );
        assert_eq!(
            write(&mut c, &mut f, 0x1010, 1, &[0x73, 0x61, 0x76]),
            Err(SdoAbort::LengthTooLow)
        );
        assert_eq!(
            write(&mut c, &mut f, 0x1010, 1, &[0; 5]),
            Err(SdoAbort::LengthTooHigh)
        );
    }

    #[test]
    fn error_register_and_predefined_error_field() {
        let mut c = Comm::new(Identity::new(Variant::HybridServo, 0));
        let mut f = Faults::default();
        assert_eq!(rd(&c, &f, 0x1001, 0), 0);
        assert_eq!(rd(&c, &f, 0x1003, 0), 0);
        f.raise(FaultKind::UnderVoltage, Snapshot::default(), 0);
        f.raise(FaultKind::OverCurrent, Snapshot::default(), 1);
        assert_eq!(
            rd(&c, &f, 0x1001, 0),
            0x87,
            "generic, current, voltage, drive alarm"
        );
        assert_eq!(rd(&c, &f, 0x1003, 0), 2);
        assert_eq!(rd(&c, &f, 0x1003, 1), 0x2310);
        assert_eq!(rd(&c, &f, 0x1003, 2), 0x3220 | 4 << 16);
        assert_eq!(rd(&c, &f, 0x1003, 3), 0);
        assert_eq!(
            sdo_write(&mut c, &mut f, 0x1003, 0, 1),
            Err(SdoAbort::ValueRangeExceeded)
        );
        assert_eq!(
            sdo_write(&mut c, &mut f, 0x1003, 1, 0),
            Err(SdoAbort::WriteReadOnly)
        );
        assert_eq!(sdo_write(&mut c, &mut f, 0x1003, 0, 0), Ok(None));
        assert_eq!(rd(&c, &f, 0x1003, 0), 0);
        assert_eq!(rd(&c, &f, 0x1001, 0), 0x87, "active faults stay");
    }

    #[test]
    fn error_settings() {
        let mut c = Comm::new(Identity::new(Variant::HybridServo, 0));
        let mut f = Faults::default();
        assert_eq!(
            (
                rd(&c, &f, 0x10F1, 0),
                rd(&c, &f, 0x10F1, 1),
                rd(&c, &f, 0x10F1, 2)
            ),
            (2, 1, 4)
        );
        assert_eq!(sdo_write(&mut c, &mut f, 0x10F1, 2, 9), Ok(None));
        assert_eq!(c.sync_error_limit(), 9);
        assert_eq!(sdo_write(&mut c, &mut f, 0x10F1, 1, 0), Ok(None));
        assert_eq!(c.local_error_reaction(), 0);
        assert_eq!(
            read(&c, &f, 0x10F2, 0, &mut [0; 4]),
            Err(SdoAbort::ObjectDoesNotExist)
        );
    }
}
