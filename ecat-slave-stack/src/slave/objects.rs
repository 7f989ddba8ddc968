//! The dictionary the mailbox serves: the runtime's own communication objects
//! (mapping, assignment, sync) in front of the application's dictionary.

use super::*;

/// The dictionary seen by the mailbox: the runtime's communication objects in front
/// of the application's dictionary.
pub struct CommDictionary<'a, A: Dictionary + ?Sized> {
    /// Mapping and assignment.
    pub pdo: &'a mut PdoConfig,
    /// Sync objects and timing diagnostics.
    pub sync: &'a mut SyncState,
    /// Everything else.
    pub app: &'a mut A,
}

impl<A: Dictionary + ?Sized> Dictionary for CommDictionary<'_, A> {
    fn objects(&self) -> &'static [Object] {
        self.app.objects()
    }
    fn read(&mut self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        if is_runtime_index(self.sync, key.index) {
            self.runtime().read(key, buf)
        } else {
            self.app.read(key, buf)
        }
    }
    fn write(&mut self, key: ObjectKey, data: &[u8], state: EsmState) -> Result<(), SdoAbort> {
        if is_runtime_index(self.sync, key.index) {
            self.runtime().write(key, data, state)
        } else {
            let mut runtime = RuntimeObjects {
                pdo: self.pdo,
                sync: self.sync,
                objects: self.app.objects(),
            };
            self.app.write_with_runtime(key, data, state, &mut runtime)
        }
    }
}

impl<A: Dictionary + ?Sized> CommDictionary<'_, A> {
    /// The runtime's own objects, with the application's table for the mappability
    /// rules.
    fn runtime(&mut self) -> RuntimeObjects<'_> {
        RuntimeObjects {
            pdo: self.pdo,
            sync: self.sync,
            objects: self.app.objects(),
        }
    }
}

/// True for the indices the runtime serves itself (mapping, assignment, sync, timing
/// diagnostics).
fn is_runtime_index(sync: &SyncState, index: u16) -> bool {
    pdo::is_pdo_index(index) || sync.serves(index)
}

/// The objects the runtime serves itself (mapping, assignment, sync parameters,
/// timing diagnostics), as a dictionary of their own; every other index answers
/// "object does not exist". Handed to [`Dictionary::write_with_runtime`] and, at
/// power-up, to the parameter store ([`Slave::runtime_objects`]).
pub struct RuntimeObjects<'a> {
    /// Mapping and assignment.
    pub pdo: &'a mut PdoConfig,
    /// Sync objects and timing diagnostics.
    pub sync: &'a mut SyncState,
    /// The whole product table (for the mappability rules).
    pub objects: &'static [Object],
}

impl Dictionary for RuntimeObjects<'_> {
    fn objects(&self) -> &'static [Object] {
        self.objects
    }
    fn read(&mut self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        if pdo::is_pdo_index(key.index) {
            self.pdo.read(key, buf)
        } else if self.sync.serves(key.index) {
            self.sync.read(key, buf)
        } else {
            Err(SdoAbort::ObjectDoesNotExist)
        }
    }
    fn write(&mut self, key: ObjectKey, data: &[u8], state: EsmState) -> Result<(), SdoAbort> {
        if pdo::is_pdo_index(key.index) {
            self.pdo.write(key, data, state, self.objects)
        } else if self.sync.serves(key.index) {
            self.sync.write(key, data, state)
        } else {
            Err(SdoAbort::ObjectDoesNotExist)
        }
    }
}
