//! The parameter-record region of the internal flash: the last 16 KiB
//! ([`board::PARAM_FLASH_OFFSET`], [`board::PARAM_FLASH_SIZE`]), kept out of the
//! linker's FLASH region by `memory.x`.
//!
//! [`ParamFlash`] wraps embassy-stm32's blocking flash driver and implements
//! `embedded_storage::nor_flash::NorFlash` with offsets *relative to the region*, so
//! the library's record code can never reach program flash: every access outside the
//! region is refused with `OutOfBounds` before it reaches the driver.
//!
//! The STM32G474RE is run in dual-bank mode (option byte DBANK = 1, the factory
//! setting): 2 KiB pages, 8-byte (double-word) programming. embassy-stm32 panics when
//! the option byte disagrees with its `dual-bank` feature, so [`ParamFlash::new`]
//! checks DBANK first and returns `None` instead.
use embassy_stm32::flash::{Blocking, Flash};
use embassy_stm32::pac;
use embassy_stm32::peripherals::FLASH;
use embassy_stm32::Peri;
use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

use crate::board;

/// Errors of [`ParamFlash`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum ParamFlashError {
    /// Outside the parameter region.
    OutOfBounds,
    /// Offset or length not aligned to the write / erase granularity.
    NotAligned,
    /// The flash controller reported an error.
    Driver,
}

impl NorFlashError for ParamFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            ParamFlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            ParamFlashError::NotAligned => NorFlashErrorKind::NotAligned,
            ParamFlashError::Driver => NorFlashErrorKind::Other,
        }
    }
}

/// NorFlash over the parameter region only.
pub struct ParamFlash {
    flash: Flash<'static, Blocking>,
}

impl ParamFlash {
    /// The region, or `None` when the flash is not in dual-bank mode (see the module
    /// docs).
    pub fn new(p: Peri<'static, FLASH>) -> Option<Self> {
        if !pac::FLASH.optr().read().dbank() {
            return None;
        }
        Some(ParamFlash {
            flash: Flash::new_blocking(p),
        })
    }

    fn span(offset: u32, len: usize) -> Result<u32, ParamFlashError> {
        let len = u32::try_from(len).map_err(|_| ParamFlashError::OutOfBounds)?;
        let end = offset
            .checked_add(len)
            .ok_or(ParamFlashError::OutOfBounds)?;
        if end > board::PARAM_FLASH_SIZE {
            return Err(ParamFlashError::OutOfBounds);
        }
        Ok(board::PARAM_FLASH_OFFSET + offset)
    }
}

impl ErrorType for ParamFlash {
    type Error = ParamFlashError;
}

impl ReadNorFlash for ParamFlash {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), ParamFlashError> {
        let abs = Self::span(offset, bytes.len())?;
        self.flash
            .blocking_read(abs, bytes)
            .map_err(|_| ParamFlashError::Driver)
    }

    fn capacity(&self) -> usize {
        board::PARAM_FLASH_SIZE as usize
    }
}

impl NorFlash for ParamFlash {
    const WRITE_SIZE: usize = embassy_stm32::flash::WRITE_SIZE;
    const ERASE_SIZE: usize = embassy_stm32::flash::MAX_ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), ParamFlashError> {
        if to < from {
            return Err(ParamFlashError::OutOfBounds);
        }
        let abs = Self::span(from, (to - from) as usize)?;
        let es = Self::ERASE_SIZE as u32;
        if !from.is_multiple_of(es) || !to.is_multiple_of(es) {
            return Err(ParamFlashError::NotAligned);
        }
        self.flash
            .blocking_erase(abs, abs + (to - from))
            .map_err(|_| ParamFlashError::Driver)
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), ParamFlashError> {
        let abs = Self::span(offset, bytes.len())?;
        let ws = Self::WRITE_SIZE as u32;
        if !offset.is_multiple_of(ws) || !bytes.len().is_multiple_of(Self::WRITE_SIZE) {
            return Err(ParamFlashError::NotAligned);
        }
        self.flash
            .blocking_write(abs, bytes)
            .map_err(|_| ParamFlashError::Driver)
    }
}
