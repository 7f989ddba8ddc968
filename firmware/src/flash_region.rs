//! A window onto part of a NOR flash: `FlashRegion<F>` implements
//! `embedded_storage::nor_flash::NorFlash` with offsets relative to the window and
//! refuses every access that leaves it, before the underlying driver sees it.
//!
//! The board gives the parameter-record code (`storage`) only this window over
//! the chip's flash, so no record offset — whatever a corrupt header or a bug says —
//! can erase or program the firmware itself. Alignment is checked here too, so the
//! driver's own error paths are never the only guard.
use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// Errors of a [`FlashRegion`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RegionError<E> {
    /// The access leaves the window (or overflows).
    OutOfBounds,
    /// Offset or length not a multiple of the write / erase granularity.
    NotAligned,
    /// The underlying flash reported an error.
    Flash(E),
}

impl<E: NorFlashError> NorFlashError for RegionError<E> {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            RegionError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            RegionError::NotAligned => NorFlashErrorKind::NotAligned,
            RegionError::Flash(e) => e.kind(),
        }
    }
}

/// The window `[base, base + size)` of `F`.
#[derive(Debug)]
pub struct FlashRegion<F> {
    flash: F,
    base: u32,
    size: u32,
}

impl<F: NorFlash> FlashRegion<F> {
    /// The window, or `None` when it does not lie inside `flash` or is not made of
    /// whole erase units.
    pub fn new(flash: F, base: u32, size: u32) -> Option<Self> {
        let end = base.checked_add(size)?;
        let es = F::ERASE_SIZE as u32;
        let fits = end as usize <= flash.capacity();
        let aligned = es > 0 && base.is_multiple_of(es) && size.is_multiple_of(es);
        if fits && aligned {
            Some(FlashRegion { flash, base, size })
        } else {
            None
        }
    }

    /// Start of the window in the underlying flash.
    pub fn base(&self) -> u32 {
        self.base
    }

    /// Gives the underlying flash back.
    pub fn release(self) -> F {
        self.flash
    }

    fn span(&self, offset: u32, len: usize) -> Result<u32, RegionError<F::Error>> {
        let len = u32::try_from(len).map_err(|_| RegionError::OutOfBounds)?;
        let end = offset.checked_add(len).ok_or(RegionError::OutOfBounds)?;
        if end > self.size {
            return Err(RegionError::OutOfBounds);
        }
        Ok(self.base + offset)
    }
}

impl<F: NorFlash> ErrorType for FlashRegion<F> {
    type Error = RegionError<F::Error>;
}

impl<F: NorFlash> ReadNorFlash for FlashRegion<F> {
    const READ_SIZE: usize = F::READ_SIZE;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let abs = self.span(offset, bytes.len())?;
        let rs = F::READ_SIZE.max(1);
        if !(offset as usize).is_multiple_of(rs) || !bytes.len().is_multiple_of(rs) {
            return Err(RegionError::NotAligned);
        }
        self.flash.read(abs, bytes).map_err(RegionError::Flash)
    }

    fn capacity(&self) -> usize {
        self.size as usize
    }
}

impl<F: NorFlash> NorFlash for FlashRegion<F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if to < from {
            return Err(RegionError::OutOfBounds);
        }
        let abs = self.span(from, (to - from) as usize)?;
        let es = F::ERASE_SIZE.max(1) as u32;
        if !from.is_multiple_of(es) || !to.is_multiple_of(es) {
            return Err(RegionError::NotAligned);
        }
        self.flash
            .erase(abs, abs + (to - from))
            .map_err(RegionError::Flash)
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let abs = self.span(offset, bytes.len())?;
        let ws = F::WRITE_SIZE.max(1);
        if !(offset as usize).is_multiple_of(ws) || !bytes.len().is_multiple_of(ws) {
            return Err(RegionError::NotAligned);
        }
        self.flash.write(abs, bytes).map_err(RegionError::Flash)
    }
}
