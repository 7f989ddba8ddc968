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
