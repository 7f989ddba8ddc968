//! The internal flash: the parameter-record region, the last 16 KiB
//! ([`board::PARAM_FLASH_OFFSET`], [`board::PARAM_FLASH_SIZE`]; kept out of the
//! linker's FLASH region by `firmware/memory.x`), and the firmware update's partitions
//! (`firmware::flash_layout`).
//!
//! Both go through one embassy-stm32 blocking flash driver ([`ChipFlash`], a
//! thread-mode mutex). [`ParamFlash`] is a partition of it seen through
//! `firmware::flash_region::FlashRegion`: offsets are relative to the region and every
//! access outside it is refused before it reaches the driver, so the record code can
//! never touch program flash. [`BoardUpdate`] holds embassy-boot's partitions.
//!
//! The STM32G474RE is run in dual-bank mode (option byte DBANK = 1, the factory
//! setting): 2 KiB pages, 8-byte (double-word) programming; the region lies in bank 2,
//! so erasing it does not stall code running from bank 1 (read-while-write), and the
//! whole-flash driver used here erases and programs without a critical section: the
//! current-loop interrupt keeps running during a save. embassy-stm32 panics when the
//! option byte disagrees with its `dual-bank` feature, so [`chip_flash`] checks DBANK
//! first and returns `None` instead.
use core::cell::RefCell;
use core::mem::MaybeUninit;

use embassy_embedded_hal::flash::partition::BlockingPartition;
use embassy_stm32::flash::{Blocking, Flash};
use embassy_stm32::pac;
use embassy_stm32::peripherals::FLASH;
use embassy_stm32::Peri;
use embassy_sync::blocking_mutex::raw::ThreadModeRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use firmware::flash_layout::{self, Partition};
use firmware::flash_region::FlashRegion;
use firmware::update::{EmbassyUpdater, Update};

use crate::board;

/// The whole internal flash, shared by the parameter records and the firmware update.
/// Thread mode only: the mutex does not mask interrupts, so no flash operation ever
/// holds off the current loop (it panics if taken in an interrupt).
pub type ChipFlash = Mutex<ThreadModeRawMutex, RefCell<Flash<'static, Blocking>>>;

/// A partition of the chip's flash (`firmware::flash_layout`).
pub type Part = BlockingPartition<'static, ThreadModeRawMutex, Flash<'static, Blocking>>;

/// The parameter region of the internal flash.
pub type ParamFlash = FlashRegion<Part>;

/// The firmware update of the board: embassy-boot over the DFU, boot-state and
/// active partitions.
pub type BoardUpdate = Update<EmbassyUpdater<'static, Part, Part, Part>>;

/// The chip's flash in `slot`, or `None` when it is not in dual-bank mode (see the
/// module docs).
pub fn chip_flash(
    p: Peri<'static, FLASH>,
    slot: &'static mut MaybeUninit<ChipFlash>,
) -> Option<&'static ChipFlash> {
    if !pac::FLASH.optr().read().dbank() {
        return None;
    }
    Some(slot.write(Mutex::new(RefCell::new(Flash::new_blocking(p)))))
}

fn part(chip: &'static ChipFlash, p: Partition) -> Part {
    BlockingPartition::new(chip, p.offset, p.size)
}

/// The parameter region.
pub fn param_flash(chip: &'static ChipFlash) -> Option<ParamFlash> {
    FlashRegion::new(
        part(
            chip,
            Partition {
                offset: 0,
                size: flash_layout::FLASH_SIZE,
            },
        ),
        board::PARAM_FLASH_OFFSET,
        board::PARAM_FLASH_SIZE,
    )
}

/// The firmware update (`firmware::update`) of a board with ESC `esc`, written into
/// `slot`; reads the running image's header and embassy-boot's state.
pub fn board_update(
    chip: &'static ChipFlash,
    aligned: &'static mut embassy_boot::AlignedBuffer<8>,
    slot: &'static mut MaybeUninit<BoardUpdate>,
    esc: efw::Esc,
) -> &'static mut BoardUpdate {
    let updater = EmbassyUpdater::new(
        part(chip, flash_layout::DFU),
        part(chip, flash_layout::BOOT_STATE),
        part(chip, flash_layout::ACTIVE),
        &mut aligned.0,
    );
    slot.write(Update::new(
        updater,
        firmware::identity::VENDOR_ID,
        firmware::identity::BOARD_VARIANT.product_code(),
        esc,
    ))
}

// ---------------------------------------------------------------------------------
// Staged saves
// ---------------------------------------------------------------------------------

/// Bytes of a record slot a save can stage in RAM: the 32-byte header plus the
/// largest payload the dictionary produces (225 saved entries, ≤ 1624 bytes with
/// their 4-byte tags when this was written), rounded up. A record that does not fit
/// is refused (the SDO 'save' answers "data cannot be stored"), never truncated.
pub const STAGE_LEN: usize = 2048;

/// Erase unit of the region (dual-bank page).
const PAGE: usize = 2048;

/// Absolute address of the region's first byte in the memory map.
const REGION_ADDR: u32 = 0x0800_0000 + board::PARAM_FLASH_OFFSET;

/// The RAM image of a record being saved.
pub type Stage = firmware::staged_flash::Stage<STAGE_LEN>;

/// The parameter store's view of the flash (`firmware::staged_flash::StagedRecords`):
/// reads from the memory-mapped region (a read that hits a double ECC error fails:
/// [`BoardEcc`]); a save or history write only stages its payload in a [`Stage`],
/// written by [`commit`] in thread mode outside the drive's lock (see
/// `firmware::staged_flash` and main.rs, "Who owns what").
pub type StagedFlash = firmware::staged_flash::StagedFlash<'static, EccRegion, STAGE_LEN, PAGE>;

/// The drive's parameter store over [`StagedFlash`].
pub type BoardStore = firmware::staged_flash::StagedRecords<'static, EccRegion, STAGE_LEN, PAGE>;

/// The memory-mapped record region, its reads checked for double ECC errors
/// (`firmware::storage::ecc`).
pub type EccRegion = firmware::storage::ecc::EccChecked<MappedRegion, BoardEcc>;

/// The record region's reader for [`StagedFlash`].
pub const fn ecc_region() -> EccRegion {
    firmware::storage::ecc::EccChecked::new(MappedRegion, BoardEcc)
}

/// The NMI handler's note of a double ECC error in the record region
/// (`hw::safety::ECC_RECORD_ERROR`).
pub struct BoardEcc;

impl firmware::storage::ecc::EccMonitor for BoardEcc {
    fn clear(&mut self) {
        crate::hw::safety::ECC_RECORD_ERROR.store(false, core::sync::atomic::Ordering::Release);
    }
    fn double_error(&mut self) -> bool {
        // The NMI runs between the loads of the copy and this check.
        crate::hw::safety::ECC_RECORD_ERROR.load(core::sync::atomic::Ordering::Acquire)
    }
}

/// Read-only view of the parameter region through the memory map (no driver needed,
/// so the staged view can read while the driver is owned by the thread that
/// programs).
pub struct MappedRegion;

impl embedded_storage::nor_flash::ErrorType for MappedRegion {
    type Error = embedded_storage::nor_flash::NorFlashErrorKind;
}

impl embedded_storage::nor_flash::ReadNorFlash for MappedRegion {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let end = (offset as usize).checked_add(bytes.len());
        if end.is_none_or(|e| e > board::PARAM_FLASH_SIZE as usize) {
            return Err(embedded_storage::nor_flash::NorFlashErrorKind::OutOfBounds);
        }
        // SAFETY: the span lies inside the parameter region of the internal flash,
        // which is always mapped and readable.
        let src = unsafe {
            core::slice::from_raw_parts((REGION_ADDR + offset) as *const u8, bytes.len())
        };
        bytes.copy_from_slice(src);
        Ok(())
    }

    fn capacity(&self) -> usize {
        board::PARAM_FLASH_SIZE as usize
    }
}

/// Writes a staged record into the flash (`firmware::staged_flash::commit_staged`:
/// the newest record looked up through the ECC-checked reads, the kept entries, the
/// CRC and the header computed, then erase, payload, header last). Blocking (erase ≈
/// 20 ms per 2 KiB page, program ≈ 85 µs per double word); runs in thread mode without
/// any lock (bank 2, read-while-write: the interrupts keep running from bank 1).
pub fn commit(flash: &mut ParamFlash, st: &Stage) -> Result<(), firmware::storage::StorageError> {
    let mut via = firmware::staged_flash::ReadVia {
        read: ecc_region(),
        flash,
    };
    firmware::staged_flash::commit_staged(&mut via, st)
}
