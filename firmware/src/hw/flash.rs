//! The parameter-record region of the internal flash: the last 16 KiB
//! ([`board::PARAM_FLASH_OFFSET`], [`board::PARAM_FLASH_SIZE`]), kept out of the
//! linker's FLASH region by `memory.x`.
//!
//! [`ParamFlash`] is embassy-stm32's blocking flash driver (`NorFlash`) seen through
//! `firmware::flash_region::FlashRegion`: offsets are relative to the region and every
//! access outside it is refused before it reaches the driver, so the record code can
//! never touch program flash.
//!
//! The STM32G474RE is run in dual-bank mode (option byte DBANK = 1, the factory
//! setting): 2 KiB pages, 8-byte (double-word) programming; the region lies in bank 2,
//! so erasing it does not stall code running from bank 1 (read-while-write), and the
//! whole-flash driver used here erases and programs without a critical section: the
//! current-loop interrupt keeps running during a save. embassy-stm32 panics when the
//! option byte disagrees with its `dual-bank` feature, so [`param_flash`] checks DBANK
//! first and returns `None` instead.
use embassy_stm32::flash::{Blocking, Flash};
use embassy_stm32::pac;
use embassy_stm32::peripherals::FLASH;
use embassy_stm32::Peri;
use firmware::flash_region::FlashRegion;

use crate::board;

/// The parameter region of the internal flash.
pub type ParamFlash = FlashRegion<Flash<'static, Blocking>>;

/// The region, or `None` when the flash is not in dual-bank mode (see the module docs).
pub fn param_flash(p: Peri<'static, FLASH>) -> Option<ParamFlash> {
    if !pac::FLASH.optr().read().dbank() {
        return None;
    }
    FlashRegion::new(
        Flash::new_blocking(p),
        board::PARAM_FLASH_OFFSET,
        board::PARAM_FLASH_SIZE,
    )
}

// ---------------------------------------------------------------------------------
// Staged saves
// ---------------------------------------------------------------------------------

/// Bytes of a record slot a save can stage in RAM: the 32-byte header plus the
/// largest payload the dictionary produces (225 saved entries, ≤ 1624 bytes with
/// their 4-byte tags when this was written), rounded up. A record that does not fit
/// is refused (the SDO 'save' answers "data cannot be stored"), never truncated.
pub const STAGE_LEN: usize = 2048;

/// Absolute address of the region's first byte in the memory map.
const REGION_ADDR: u32 = 0x0800_0000 + board::PARAM_FLASH_OFFSET;
/// Program granularity of the G4 (double word).
const WRITE_UNIT: usize = 8;

/// Error of the staging [`StagedFlash`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum StageError {
    /// Outside the region, or the record does not fit [`STAGE_LEN`].
    OutOfBounds,
    /// Not aligned to the write / erase unit.
    NotAligned,
    /// Parameter storage is off (DBANK = 0) or a staged record is still being
    /// committed.
    Unavailable,
}

impl embedded_storage::nor_flash::NorFlashError for StageError {
    fn kind(&self) -> embedded_storage::nor_flash::NorFlashErrorKind {
        use embedded_storage::nor_flash::NorFlashErrorKind as K;
        match self {
            StageError::OutOfBounds => K::OutOfBounds,
            StageError::NotAligned => K::NotAligned,
            StageError::Unavailable => K::Other,
        }
    }
}

/// A record image waiting for the flash: the erased range and the bytes programmed
/// into it, relative to the region.
pub struct Stage {
    /// Erased range `[from, to)`; writes must fall inside it.
    erase: Option<(u32, u32)>,
    /// Highest offset written + 1 (relative to `erase.0`).
    written: usize,
    /// Image of `[erase.0, erase.0 + STAGE_LEN)`, 0xFF = erased.
    bytes: [u8; STAGE_LEN],
}

impl Stage {
    /// An empty stage (all zeros, so a `static` of it lives in .bss; an erase fills
    /// the image with 0xFF before it is used).
    pub const fn new() -> Self {
        Stage {
            erase: None,
            written: 0,
            bytes: [0; STAGE_LEN],
        }
    }
}

/// The parameter store's view of the flash during a save (`drive::FlashStore<StagedFlash>`):
/// reads come straight from the memory-mapped region (what is committed), erases and
/// writes only fill a RAM image ([`Stage`]). The image is programmed into the real
/// flash afterwards by [`commit`], in thread mode and outside the drive's lock, so an
/// SDO 'save' answered inside `Slave::poll` costs the serialisation only (≈ 2 KiB of
/// dictionary reads), never a flash erase: the cyclic path keeps its timing.
///
/// The commit keeps the storage's power-loss order: erase, payload, header last.
pub struct StagedFlash {
    enabled: bool,
    stage: Option<&'static mut Stage>,
    ready: bool,
}

impl StagedFlash {
    /// Staging over the region; `enabled` false (DBANK = 0): reads see an erased
    /// region and every save is refused.
    pub fn new(stage: &'static mut Stage, enabled: bool) -> Self {
        StagedFlash {
            enabled,
            stage: Some(stage),
            ready: false,
        }
    }

    /// Takes a finished record image for [`commit`] (at most once per save).
    pub fn take_ready(&mut self) -> Option<&'static mut Stage> {
        if !self.ready {
            return None;
        }
        self.ready = false;
        self.stage.take()
    }

    /// Gives the image back after [`commit`].
    pub fn give_back(&mut self, stage: &'static mut Stage) {
        stage.erase = None;
        stage.written = 0;
        self.stage = Some(stage);
    }

    fn span(offset: u32, len: usize) -> Result<(), StageError> {
        let end = (offset as usize)
            .checked_add(len)
            .ok_or(StageError::OutOfBounds)?;
        if end > board::PARAM_FLASH_SIZE as usize {
            return Err(StageError::OutOfBounds);
        }
        Ok(())
    }
}

impl embedded_storage::nor_flash::ErrorType for StagedFlash {
    type Error = StageError;
}

impl embedded_storage::nor_flash::ReadNorFlash for StagedFlash {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), StageError> {
        Self::span(offset, bytes.len())?;
        if !self.enabled {
            bytes.fill(0xFF);
            return Ok(());
        }
        // SAFETY: the span lies inside the parameter region of the internal flash,
        // which is always mapped and readable.
        let src = unsafe {
            core::slice::from_raw_parts((REGION_ADDR + offset) as *const u8, bytes.len())
        };
        bytes.copy_from_slice(src);
        // A staged (not yet committed) image overrides what it covers.
        if let (true, Some(st)) = (self.ready, self.stage.as_deref()) {
            if let Some((from, to)) = st.erase {
                for (i, b) in bytes.iter_mut().enumerate() {
                    let a = offset + i as u32;
                    if a >= from && a < to {
                        *b = st.bytes.get((a - from) as usize).copied().unwrap_or(0xFF);
                    }
                }
            }
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        board::PARAM_FLASH_SIZE as usize
    }
}

impl embedded_storage::nor_flash::NorFlash for StagedFlash {
    const WRITE_SIZE: usize = WRITE_UNIT;
    const ERASE_SIZE: usize = 2048;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), StageError> {
        if !self.enabled || self.ready {
            return Err(StageError::Unavailable);
        }
        let st = self.stage.as_deref_mut().ok_or(StageError::Unavailable)?;
        if to < from {
            return Err(StageError::OutOfBounds);
        }
        Self::span(from, (to - from) as usize)?;
        let es = Self::ERASE_SIZE as u32;
        if !from.is_multiple_of(es) || !to.is_multiple_of(es) {
            return Err(StageError::NotAligned);
        }
        st.erase = Some((from, to));
        st.written = 0;
        st.bytes.fill(0xFF);
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), StageError> {
        if !self.enabled || self.ready {
            return Err(StageError::Unavailable);
        }
        let st = self.stage.as_deref_mut().ok_or(StageError::Unavailable)?;
        Self::span(offset, bytes.len())?;
        if !(offset as usize).is_multiple_of(WRITE_UNIT) || !bytes.len().is_multiple_of(WRITE_UNIT)
        {
            return Err(StageError::NotAligned);
        }
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
        // The storage writes the header (offset 0 of the slot) last: that is the
        // end of the record, so the image is complete.
        if rel == 0 {
            self.ready = true;
        }
        Ok(())
    }
}

/// Programs a staged record into the flash: erase the range, write the payload
/// (everything after the header), then the header. Blocking (erase ≈ 20 ms per
/// 2 KiB page, program ≈ 85 µs per double word); runs in thread mode without any
/// lock (bank 2, read-while-write: the interrupts keep running from bank 1).
pub fn commit(flash: &mut ParamFlash, st: &Stage) -> Result<(), RegionErrorOf> {
    use embedded_storage::nor_flash::NorFlash;
    let Some((from, to)) = st.erase else {
        return Ok(());
    };
    flash.erase(from, to)?;
    let head = HEADER.min(st.written);
    let body = &st.bytes[head..st.written.div_ceil(WRITE_UNIT) * WRITE_UNIT];
    for (i, chunk) in body.chunks(WRITE_UNIT).enumerate() {
        if chunk.iter().any(|&b| b != 0xFF) {
            flash.write(from + (head + i * WRITE_UNIT) as u32, chunk)?;
        }
    }
    if head > 0 {
        flash.write(from, &st.bytes[..head])?;
    }
    Ok(())
}

/// Header length of a record: written last by [`commit`].
const HEADER: usize = firmware::storage::HEADER_LEN;

/// Error of the real region.
pub type RegionErrorOf = firmware::flash_region::RegionError<embassy_stm32::flash::Error>;
