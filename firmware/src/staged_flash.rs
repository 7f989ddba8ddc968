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
//! Geometry: write unit [`WRITE_UNIT`] bytes (double word, STM32G4), erase unit
//! `ERASE` bytes (a const parameter), image of `N` bytes from the start of the erased
//! range (a record that does not fit is refused, never truncated).
use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

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
    bytes: [u8; N],
}

impl<const N: usize> Stage<N> {
    /// An empty image (all zeros, so a `static` of it needs no flash image; an erase
    /// fills it with 0xFF first).
    pub const fn new() -> Self {
        Stage {
            erase: None,
            written: 0,
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
        self.stage = Some(stage);
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
