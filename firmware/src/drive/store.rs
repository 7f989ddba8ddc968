//! Where the drive's parameters are saved: the [`ParameterStore`] seam, the flash
//! records ([`FlashStore`]) and the store-less stand-in ([`NoStore`]).

use super::*;

/// Where 'save' / 'load' (0x1010 / 0x1011) go and where the power-up load comes from.
pub trait ParameterStore {
    /// Runs a store or restore command over the whole dictionary.
    fn execute(
        &mut self,
        cmd: StoreCommand,
        dict: &mut dyn Dictionary,
    ) -> Result<SaveReport, StorageError>;
    /// Power-up: applies the newest valid record to `dict`.
    fn load(&mut self, dict: &mut dyn Dictionary) -> LoadReport;
    /// Power-up: copies the payload of the newest valid fault-history record into
    /// `out` and returns its length; `None`: no history memory or no valid record.
    fn load_history(&mut self, out: &mut [u8]) -> Option<usize> {
        let _ = out;
        None
    }
    /// Writes a fault-history record (`crate::faults::Faults::encode_history`):
    /// `Ok(true)` written (or, on the board, staged for programming), `Ok(false)` no
    /// history memory (the history lives in RAM only).
    fn write_history(&mut self, payload: &[u8]) -> Result<bool, StorageError> {
        let _ = payload;
        Ok(false)
    }
}

/// The two-record flash store ([`Storage`]) over a [`NorFlash`], with the fault
/// history's own record pair in the same flash.
pub struct FlashStore<F: NorFlash> {
    /// Layout of the two parameter records.
    pub storage: Storage,
    /// Layout of the two fault-history records (`None`: the history is not kept
    /// across power cycles). See [`crate::storage::region`].
    pub history: Option<Storage>,
    /// The flash region.
    pub flash: F,
}

/// A parameter store whose flash is staged in RAM ([`crate::staged_flash`]): the
/// board's, whose records are programmed outside the drive's lock.
pub trait StagedStore<'a, R, const N: usize, const E: usize> {
    /// The staged flash view.
    fn staged(&mut self) -> &mut crate::staged_flash::StagedFlash<'a, R, N, E>;
}

impl<'a, R, const N: usize, const E: usize> StagedStore<'a, R, N, E>
    for FlashStore<crate::staged_flash::StagedFlash<'a, R, N, E>>
where
    crate::staged_flash::StagedFlash<'a, R, N, E>: NorFlash,
{
    fn staged(&mut self) -> &mut crate::staged_flash::StagedFlash<'a, R, N, E> {
        &mut self.flash
    }
}

impl<F: NorFlash> ParameterStore for FlashStore<F> {
    fn execute(
        &mut self,
        cmd: StoreCommand,
        dict: &mut dyn Dictionary,
    ) -> Result<SaveReport, StorageError> {
        crate::comm::execute(cmd, &self.storage, &mut self.flash, dict)
    }
    fn load(&mut self, dict: &mut dyn Dictionary) -> LoadReport {
        self.storage.load(&mut self.flash, dict)
    }
    fn load_history(&mut self, out: &mut [u8]) -> Option<usize> {
        self.history?.read_newest(&mut self.flash, out)
    }
    fn write_history(&mut self, payload: &[u8]) -> Result<bool, StorageError> {
        match self.history {
            Some(h) => h.write_bytes(&mut self.flash, payload).map(|_| true),
            None => Ok(false),
        }
    }
}

/// No parameter memory (tests that do not care): 'save' is refused with 0x08000020.
#[derive(Debug, Default)]
pub struct NoStore;

impl ParameterStore for NoStore {
    fn execute(
        &mut self,
        _cmd: StoreCommand,
        _dict: &mut dyn Dictionary,
    ) -> Result<SaveReport, StorageError> {
        Err(StorageError::Geometry)
    }
    fn load(&mut self, _dict: &mut dyn Dictionary) -> LoadReport {
        LoadReport {
            slots: [SlotStatus::Erased; 2],
            source: None,
            applied: 0,
            skipped: 0,
        }
    }
}
