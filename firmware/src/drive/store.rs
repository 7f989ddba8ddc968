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

impl<S: ParameterStore> Drive<S> {
    /// Power-up: loads the stored parameters (drive objects and, through `runtime` —
    /// [`ecat_slave_stack::slave::Slave::runtime_objects`] — the PDO mapping), latches
    /// the "effective after restart" parameters and counts the power-up. A corrupt or
    /// lost record is reported as an emergency.
    pub fn power_up(&mut self, runtime: &mut dyn Dictionary) -> LoadReport {
        let report = match self.store.take() {
            Some(mut store) => {
                let r = store.load(&mut WholeDictionary {
                    drive: &mut *self,
                    runtime,
                });
                self.store = Some(store);
                r
            }
            None => NoStore.load(runtime),
        };
        if let Some((code, data)) = report.emergency() {
            self.storage_emergency = Some((code, data));
            self.faults
                .diagnosis_mut()
                .push(crate::diagnosis::parameter_message(
                    false,
                    code,
                    self.now_ms,
                ));
        }
        self.load_report = Some(report);
        self.params.latch_power_up();
        self.monitor.power_up();
        self.load_history();
        self.apply_parameters();
        report
    }

    /// Power-up: the fault history from its flash record (nothing, i.e. an empty
    /// history, for erased, torn or garbage records) and the operating time stored
    /// with it — the larger of that and the parameter record's 0x2307 counts, the
    /// history being written more often than the parameters.
    pub(super) fn load_history(&mut self) {
        let mut buf = [0u8; crate::faults::HISTORY_PAYLOAD_MAX];
        let n = self.store.as_mut().and_then(|s| s.load_history(&mut buf));
        if let Some(op) = n.and_then(|n| self.faults.restore_history(&buf[..n.min(buf.len())])) {
            self.monitor.running_time_at_least(op);
        }
        self.faults
            .set_operating_base(self.monitor.running_time_s());
    }

    /// Deferred work for whoever services 'save' (the board's `ecat` task after
    /// `poll`, the simulator's housekeeping): when the fault history changed since
    /// the last call, writes it with the operating time 0x2307 as a new history record.
    /// The fault path only marks the history dirty; this is never called from it.
    ///
    /// The board's flash rule holds as for a parameter 'save': through the staged
    /// store this only serialises the record (≈ 170 bytes) into the RAM stage under
    /// the shared lock; the erase and programming run afterwards in thread mode
    /// outside the lock (bank 2 read-while-write: the current loop and the cyclic
    /// path keep running, also with the power stage on). Call it only while no staged
    /// parameter record waits for programming (the stage is shared).
    ///
    /// Rate-limited ([`crate::storage::rate`]: ≥ 10 s between records, at most
    /// 8 + hours / 2 records): a change waits (still dirty) until the limit lets it
    /// through, at most 2 h; the history in RAM is complete meanwhile.
    ///
    /// `None`: nothing to do now (or no history memory); `Some(result)` of the write.
    /// The history counts as written either way (a failed write is reported once, not
    /// retried every tick; the next change writes again).
    pub fn persist_history(&mut self) -> Option<Result<(), StorageError>> {
        if !self.faults.history_dirty() || !self.history_rate.may_write(self.now_ms) {
            return None;
        }
        self.history_rate.wrote();
        self.faults.history_written();
        let mut buf = [0u8; crate::faults::HISTORY_PAYLOAD_MAX];
        let n = self
            .faults
            .encode_history(self.monitor.running_time_s(), &mut buf);
        match self.store.as_mut()?.write_history(&buf[..n.min(buf.len())]) {
            Ok(true) => Some(Ok(())),
            Ok(false) => None,
            Err(e) => Some(Err(e)),
        }
    }

    /// The next record for the board to program outside its lock, from a staged
    /// store: a record a 'save' staged comes first; only when none waits is a changed
    /// fault history staged ([`Drive::persist_history`]: the stage is shared). Returns
    /// the stage to program (give it back with `StagedFlash::give_back` afterwards),
    /// and the error of a history that could not be staged.
    pub fn next_staged_record<'a, R, const N: usize, const E: usize>(
        &mut self,
    ) -> (
        Option<&'a mut crate::staged_flash::Stage<N>>,
        Option<StorageError>,
    )
    where
        S: StagedStore<'a, R, N, E>,
        R: embedded_storage::nor_flash::ReadNorFlash,
    {
        let take = |d: &mut Self| d.store.as_mut().and_then(|st| st.staged().take_ready());
        if let Some(stage) = take(self) {
            return (Some(stage), None);
        }
        let err = match self.persist_history() {
            Some(Err(e)) => Some(e),
            _ => None,
        };
        (take(self), err)
    }

    /// The parameter store (the board takes a finished staged record out of it to
    /// program the flash outside its lock).
    pub fn store_mut(&mut self) -> Option<&mut S> {
        self.store.as_mut()
    }

    /// What the power-up load found.
    pub fn load_report(&self) -> Option<LoadReport> {
        self.load_report
    }

    /// Runs a store / restore command now over the whole dictionary.
    pub(super) fn run_store(
        &mut self,
        cmd: StoreCommand,
        runtime: &mut dyn Dictionary,
    ) -> Result<(), SdoAbort> {
        let Some(mut store) = self.store.take() else {
            return Err(SdoAbort::DataCannotBeStored);
        };
        let r = store.execute(
            cmd,
            &mut WholeDictionary {
                drive: &mut *self,
                runtime,
            },
        );
        self.store = Some(store);
        if r.is_ok() && matches!(cmd, StoreCommand::RestoreDefaults(_)) {
            self.faults
                .diagnosis_mut()
                .push(crate::diagnosis::parameter_message(true, 0, self.now_ms));
        }
        r.map(|_| ()).map_err(StorageError::abort)
    }
}

/// The board's staged records ([`crate::staged_flash::StagedRecords`]) as the drive's store.
impl<R: embedded_storage::nor_flash::ReadNorFlash, const N: usize, const E: usize> ParameterStore
    for crate::staged_flash::StagedRecords<'_, R, N, E>
{
    fn execute(
        &mut self,
        cmd: StoreCommand,
        dict: &mut dyn Dictionary,
    ) -> Result<SaveReport, StorageError> {
        let (scope, dict) = match cmd {
            StoreCommand::Save(scope) => (scope, Some(dict)),
            StoreCommand::RestoreDefaults(scope) => (scope, None),
        };
        let storage = self.storage;
        let mut report = None;
        self.flash.stage_record(storage, scope, |out| {
            let r = storage.serialise(dict, scope, out)?;
            report = Some(r);
            Ok(r.payload_len as usize)
        })?;
        report.ok_or(StorageError::Geometry)
    }
    fn load(&mut self, dict: &mut dyn Dictionary) -> LoadReport {
        self.storage.load(&mut self.flash, dict)
    }
    fn load_history(&mut self, out: &mut [u8]) -> Option<usize> {
        self.history?.read_newest(&mut self.flash, out)
    }
    fn write_history(&mut self, payload: &[u8]) -> Result<bool, StorageError> {
        let Some(h) = self.history else {
            return Ok(false);
        };
        self.flash
            .stage_record(h, crate::storage::Scope::All, |out| {
                out.get_mut(..payload.len())
                    .ok_or(StorageError::RecordTooLarge)?
                    .copy_from_slice(payload);
                Ok(payload.len())
            })?;
        Ok(true)
    }
}

impl<'a, R: embedded_storage::nor_flash::ReadNorFlash, const N: usize, const E: usize>
    StagedStore<'a, R, N, E> for crate::staged_flash::StagedRecords<'a, R, N, E>
{
    fn staged(&mut self) -> &mut crate::staged_flash::StagedFlash<'a, R, N, E> {
        &mut self.flash
    }
}
