//! Parameter saves staged in RAM: a [`NorFlash`] view for [`crate::storage::Storage`]
//! whose reads come from the real flash (or its memory-mapped image) and whose
//! erases and writes only fill a RAM image ([`Stage`]); [`commit`] programs the image
//! into the flash later, in the storage's power-loss order (erase, payload, header
//! last).
//!
//! Why: on the board a 'save' (SDO 0x1010) is executed inside the slave runtime's
//! `poll`, under the lock the EtherCAT cycle needs. Erasing a record slot takes tens
//! of milliseconds; staging keeps only the serialisation under the lock and moves
//! the erase/program out of it.
//!
//! The board's store, [`StagedRecords`], goes further: under the lock a 'save' only
//! reads the dictionary into the stage ([`Storage::serialise`]: no flash read, no
//! CRC); finding the newest record (its headers and its payload's CRC), keeping its
//! entries outside a partial command's scope, the CRC, the header, the erase and the
//! programming all run in [`commit_staged`], after the lock is released. A fault
//! history record is staged the same way (its payload copied).
//!
//! Geometry: write unit [`WRITE_UNIT`] bytes (double word, STM32G4), erase unit
//! `ERASE` bytes (a const parameter), image of `N` bytes from the start of the erased
//! range (a record that does not fit is refused, never truncated).
use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

use crate::storage::{Scope, Storage, StorageError};

/// Program granularity handled by [`StagedFlash`] (and [`commit`]).
pub const WRITE_UNIT: usize = 8;

/// Errors of a [`StagedFlash`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StageError {
    /// Outside the flash, outside the erased range, or beyond the image.
    OutOfBounds,
    /// Not aligned to the write / erase unit.
    NotAligned,
    /// Storage is off, or a finished image waits for [`commit`].
    Unavailable,
    /// The underlying flash refused a read.
    Read,
}

impl NorFlashError for StageError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            StageError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            StageError::NotAligned => NorFlashErrorKind::NotAligned,
            StageError::Unavailable | StageError::Read => NorFlashErrorKind::Other,
        }
    }
}

/// A record image waiting for the flash.
pub struct Stage<const N: usize> {
    /// Erased range `[from, to)`; writes must fall inside it.
    erase: Option<(u32, u32)>,
    /// Bytes of the image written (from `erase.0`).
    written: usize,
    /// An image, or instead a record's serialised payload.
    content: Content,
    bytes: [u8; N],
}

/// What a [`Stage`] holds. `repr(u8)` with [`Content::Image`] first: its tag is 0, so
/// an empty stage is all zeros and a `static` of it is `.bss`, not a 2 KiB `.data`
/// image in flash (an `Option` would put its `None` in `Scope`'s unused values).
#[repr(u8)]
#[derive(Clone, Copy)]
enum Content {
    /// A flash image (`erase`, `written`).
    Image,
    /// A record's serialised payload (`bytes[..len]`), the records it goes to and the
    /// command's scope ([`StagedFlash::stage_record`]).
    Record(Storage, Scope, usize),
}

impl<const N: usize> Stage<N> {
    /// An empty image (all zeros, so a `static` of it needs no flash image; an erase
    /// fills it with 0xFF first).
    pub const fn new() -> Self {
        Stage {
            erase: None,
            written: 0,
            content: Content::Image,
            bytes: [0; N],
        }
    }

    /// The erased range of the image, if any.
    pub fn erased_range(&self) -> Option<(u32, u32)> {
        self.erase
    }
}

impl<const N: usize> Default for Stage<N> {
    fn default() -> Self {
        Self::new()
    }
}

/// The staging view (see the module docs). `R` reads the committed flash.
pub struct StagedFlash<'a, R, const N: usize, const ERASE: usize> {
    reader: R,
    enabled: bool,
    stage: Option<&'a mut Stage<N>>,
    ready: bool,
}

impl<'a, R: ReadNorFlash, const N: usize, const ERASE: usize> StagedFlash<'a, R, N, ERASE> {
    /// Staging over `reader` with `stage` as the image; `enabled` false: reads see an
    /// erased flash and every save is refused (no parameter memory).
    pub fn new(reader: R, stage: &'a mut Stage<N>, enabled: bool) -> Self {
        StagedFlash {
            reader,
            enabled,
            stage: Some(stage),
            ready: false,
        }
    }

    /// A finished image for [`commit`] (the storage wrote the record header, offset 0
    /// of the erased range, which it writes last). Once per save.
    pub fn take_ready(&mut self) -> Option<&'a mut Stage<N>> {
        if !self.ready {
            return None;
        }
        self.ready = false;
        self.stage.take()
    }

    /// Gives the image back after [`commit`] (cleared).
    pub fn give_back(&mut self, stage: &'a mut Stage<N>) {
        stage.erase = None;
        stage.written = 0;
        stage.content = Content::Image;
        self.stage = Some(stage);
    }

    /// Stages a record of `storage` for [`commit_staged`]: `fill` writes its payload
    /// into the stage and returns the length (no flash access). Refused like a write
    /// while storage is off or a staged record waits.
    pub fn stage_record(
        &mut self,
        storage: Storage,
        scope: Scope,
        fill: impl FnOnce(&mut [u8]) -> Result<usize, StorageError>,
    ) -> Result<(), StorageError> {
        let st = self.writable().map_err(crate::storage::flash_error)?;
        let len = fill(&mut st.bytes)?;
        st.erase = None;
        st.written = 0;
        st.content = Content::Record(storage, scope, len.min(N));
        self.ready = true;
        Ok(())
    }

    fn span(&self, offset: u32, len: usize) -> Result<(), StageError> {
        let end = (offset as usize)
            .checked_add(len)
            .ok_or(StageError::OutOfBounds)?;
        if end > self.reader.capacity() {
            return Err(StageError::OutOfBounds);
        }
        Ok(())
    }

    fn writable(&mut self) -> Result<&mut Stage<N>, StageError> {
        if !self.enabled || self.ready {
            return Err(StageError::Unavailable);
        }
        self.stage.as_deref_mut().ok_or(StageError::Unavailable)
    }
}

impl<R: ReadNorFlash, const N: usize, const ERASE: usize> ErrorType
    for StagedFlash<'_, R, N, ERASE>
{
    type Error = StageError;
}

impl<R: ReadNorFlash, const N: usize, const ERASE: usize> ReadNorFlash
    for StagedFlash<'_, R, N, ERASE>
{
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), StageError> {
        self.span(offset, bytes.len())?;
        if !self.enabled {
            bytes.fill(0xFF);
            return Ok(());
        }
        self.reader
            .read(offset, bytes)
            .map_err(|_| StageError::Read)?;
        // A finished image not yet committed overrides what it covers.
        if let (true, Some(st)) = (self.ready, self.stage.as_deref()) {
            if let Some((from, to)) = st.erase {
                for (i, b) in bytes.iter_mut().enumerate() {
                    let a = offset as usize + i;
                    if a >= from as usize && a < to as usize {
                        *b = st.bytes.get(a - from as usize).copied().unwrap_or(0xFF);
                    }
                }
            }
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.reader.capacity()
    }
}

impl<R: ReadNorFlash, const N: usize, const ERASE: usize> NorFlash
    for StagedFlash<'_, R, N, ERASE>
{
    const WRITE_SIZE: usize = WRITE_UNIT;
    const ERASE_SIZE: usize = ERASE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), StageError> {
        if to < from {
            return Err(StageError::OutOfBounds);
        }
        self.span(from, (to - from) as usize)?;
        let es = ERASE.max(1) as u32;
        if !from.is_multiple_of(es) || !to.is_multiple_of(es) {
            return Err(StageError::NotAligned);
        }
        let st = self.writable()?;
        st.erase = Some((from, to));
        st.written = 0;
        st.bytes.fill(0xFF);
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), StageError> {
        self.span(offset, bytes.len())?;
        if !(offset as usize).is_multiple_of(WRITE_UNIT) || !bytes.len().is_multiple_of(WRITE_UNIT)
        {
            return Err(StageError::NotAligned);
        }
        let st = self.writable()?;
        let (from, to) = st.erase.ok_or(StageError::OutOfBounds)?;
        let end = offset as usize + bytes.len();
        if offset < from || end > to as usize {
            return Err(StageError::OutOfBounds);
        }
        let rel = (offset - from) as usize;
        let dst = st
            .bytes
            .get_mut(rel..rel + bytes.len())
            .ok_or(StageError::OutOfBounds)?;
        dst.copy_from_slice(bytes);
        st.written = st.written.max(rel + bytes.len());
        // The record header (offset 0 of the slot) is written last: image complete.
        if rel == 0 {
            self.ready = true;
        }
        Ok(())
    }
}

/// Programs a finished image into `flash`: erase the range, write everything after
/// the first `header_len` bytes (skipping units that are still erased), then the
/// header, its first double word last — the record becomes valid only with its last
/// write, as when the storage writes the flash itself. Blocking; nothing to do for an empty image.
pub fn commit<F: NorFlash, const N: usize>(
    flash: &mut F,
    st: &Stage<N>,
    header_len: usize,
) -> Result<(), F::Error> {
    let Some((from, to)) = st.erase else {
        return Ok(());
    };
    flash.erase(from, to)?;
    let written = st.written.min(N);
    let head = header_len.min(written);
    for (i, chunk) in st.bytes[head..written].chunks(WRITE_UNIT).enumerate() {
        if chunk.iter().any(|&b| b != 0xFF) {
            flash.write(from + (head + i * WRITE_UNIT) as u32, chunk)?;
        }
    }
    // The header's first double word (the magic) last, as the storage writes it
    // (`crate::storage::COMMIT_WORD`).
    let commit = crate::storage::COMMIT_WORD.min(head);
    if head > commit {
        flash.write(from + commit as u32, &st.bytes[commit..head])?;
    }
    if commit > 0 {
        flash.write(from, &st.bytes[..commit])?;
    }
    Ok(())
}

/// Programs a staged record: a serialised payload ([`StagedFlash::stage_record`]) is
/// written by [`Storage::write_serialised`] (the newest record looked up, the CRC and
/// the header computed here, outside the drive's lock); an image by [`commit`].
pub fn commit_staged<F: NorFlash, const N: usize>(
    flash: &mut F,
    st: &Stage<N>,
) -> Result<(), StorageError> {
    match st.content {
        Content::Record(storage, scope, len) => storage
            .write_serialised(flash, &st.bytes[..len.min(N)], scope)
            .map(|_| ()),
        Content::Image => {
            commit(flash, st, crate::storage::HEADER_LEN).map_err(crate::storage::flash_error)
        }
    }
}

/// The board's parameter store: the parameter and fault-history records of
/// [`Storage`] over a [`StagedFlash`], whose 'save', 'load' (restore) and history
/// writes only stage the payload ([`StagedFlash::stage_record`]; see the module docs).
/// Reads (the power-up load, the history) go to the flash as in the drive's
/// `FlashStore`; the drive implements its store traits for it (`drive/store.rs`).
pub struct StagedRecords<'a, R, const N: usize, const E: usize> {
    /// Layout of the two parameter records.
    pub storage: Storage,
    /// Layout of the two fault-history records (`None`: RAM only).
    pub history: Option<Storage>,
    /// The staged view of the record region.
    pub flash: StagedFlash<'a, R, N, E>,
}

/// A flash whose reads go through `read` and whose erases and writes go to `flash`:
/// on the board, [`commit_staged`] reads the records through the ECC-checked view
/// (`crate::storage::ecc`) and programs the region's driver.
pub struct ReadVia<R, F> {
    /// The reader.
    pub read: R,
    /// The programmer (its geometry is the flash's).
    pub flash: F,
}

/// An error of [`ReadVia`]: the kind of the reader's or the programmer's error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ViaError(pub NorFlashErrorKind);

impl NorFlashError for ViaError {
    fn kind(&self) -> NorFlashErrorKind {
        self.0
    }
}

impl<R, F> ErrorType for ReadVia<R, F> {
    type Error = ViaError;
}

impl<R: ReadNorFlash, F: NorFlash> ReadNorFlash for ReadVia<R, F> {
    const READ_SIZE: usize = R::READ_SIZE;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), ViaError> {
        self.read
            .read(offset, bytes)
            .map_err(|e| ViaError(e.kind()))
    }

    fn capacity(&self) -> usize {
        self.flash.capacity()
    }
}

impl<R: ReadNorFlash, F: NorFlash> NorFlash for ReadVia<R, F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), ViaError> {
        self.flash.erase(from, to).map_err(|e| ViaError(e.kind()))
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), ViaError> {
        self.flash
            .write(offset, bytes)
            .map_err(|e| ViaError(e.kind()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::comm::StoreCommand;
    use crate::drive::{Drive, ParameterStore};
    use crate::identity::Variant;
    use crate::storage::{region, RamFlash};
    use ecat_slave_stack::esm::EsmState;
    use ecat_slave_stack::od::{Dictionary, ObjectKey};

    type Ram = RamFlash<{ region::SIZE as usize }>;
    type Records<'a, 'r> = StagedRecords<'a, &'r mut Ram, 4096, 2048>;

    fn read_u32(d: &mut Drive, index: u16) -> u32 {
        let mut b = [0u8; 4];
        let n = d.read(ObjectKey::new(index, 0), &mut b).unwrap();
        u32::from_le_bytes(b) & (u32::MAX >> (32 - 8 * n))
    }

    fn set(d: &mut Drive, index: u16, v: &[u8]) {
        d.write(ObjectKey::new(index, 0), v, EsmState::PreOp)
            .unwrap();
    }

    /// Stages `cmd` through the board's store ("under the lock") and returns the flash
    /// reads and byte operations it did, then writes the record ("after the lock").
    fn stage_then_commit(ram: &mut Ram, d: &mut Drive, cmd: StoreCommand) -> (usize, usize) {
        let mut stage = Stage::<4096>::new();
        let (reads, ops) = (ram.reads, ram.ops);
        let staged = {
            let mut store: Records = StagedRecords {
                storage: region::PARAMS,
                history: Some(region::HISTORY),
                flash: StagedFlash::new(&mut *ram, &mut stage, true),
            };
            store.execute(cmd, d).unwrap();
            // A second command while one waits is refused; nothing is lost.
            assert!(store.execute(cmd, d).is_err());
            store.flash.take_ready().expect("staged")
        };
        let done = (ram.reads - reads, ram.ops - ops);
        commit_staged(ram, staged).unwrap();
        // The erase and the programming happen here.
        assert!(ram.ops > ops + done.1);
        done
    }

    #[test]
    fn a_staged_save_only_reads_the_dictionary_under_the_lock() {
        let mut ram = Ram::new();
        let mut d = Drive::new(Variant::HybridServo, 7);
        set(&mut d, 0x2000, &3100u16.to_le_bytes());
        set(&mut d, 0x6065, &7000u32.to_le_bytes());
        // Under the lock: no flash read (no header, no CRC check of the newest record),
        // no erase, no write — on a blank flash and over an existing record.
        assert_eq!(
            stage_then_commit(&mut ram, &mut d, StoreCommand::Save(Scope::All)),
            (0, 0)
        );
        set(&mut d, 0x2000, &2500u16.to_le_bytes());
        set(&mut d, 0x6065, &9000u32.to_le_bytes());
        let app = StoreCommand::Save(Scope::Application);
        assert_eq!(stage_then_commit(&mut ram, &mut d, app), (0, 0));
        // The record written after the lock: the application scope new, the entries
        // outside it kept from the previous record.
        let mut fresh = Drive::new(Variant::HybridServo, 7);
        let rep = region::PARAMS.load(&mut ram, &mut fresh);
        assert_eq!(rep.source.map(|(_, seq)| seq), Some(2));
        assert_eq!(read_u32(&mut fresh, 0x6065), 9000);
        assert_eq!(read_u32(&mut fresh, 0x2000), 3100);
        // Restoring the defaults stages nothing from the flash either.
        let restore = StoreCommand::RestoreDefaults(Scope::All);
        assert_eq!(stage_then_commit(&mut ram, &mut d, restore), (0, 0));
        let mut fresh = Drive::new(Variant::HybridServo, 7);
        region::PARAMS.load(&mut ram, &mut fresh);
        assert_eq!(
            read_u32(&mut fresh, 0x2000),
            read_u32(&mut Drive::new(Variant::HybridServo, 7), 0x2000)
        );
    }

    #[test]
    fn a_staged_history_record_is_written_after_the_lock() {
        let mut ram = Ram::new();
        let mut stage = Stage::<4096>::new();
        let staged = {
            let mut store: Records = StagedRecords {
                storage: region::PARAMS,
                history: Some(region::HISTORY),
                flash: StagedFlash::new(&mut ram, &mut stage, true),
            };
            assert_eq!(store.write_history(&[5; 100]), Ok(true));
            store.flash.take_ready().expect("staged")
        };
        assert_eq!((ram.reads, ram.ops), (0, 0));
        commit_staged(&mut ram, staged).unwrap();
        let mut out = [0u8; 200];
        assert_eq!(region::HISTORY.read_newest(&mut ram, &mut out), Some(100));
        assert_eq!(out[..100], [5; 100]);
    }
}
