//! Firmware update of the simulated drives, as on the board: the firmware's own
//! [`firmware::update::Update`] over embassy-boot's updater, and embassy-boot's
//! `BootLoader` run at every start ("power-up") over the same partitions, here in a
//! file beside the parameter flash (`FILE.boot` for `--flash FILE`) or in memory.
//!
//! The boot file holds the chip's boot state, active and DFU partitions in the
//! chip's order ([`firmware::flash_layout`]), so an update that the simulation takes
//! is the same sequence of erases and writes as on the board. The simulation runs no
//! image: the active partition's header page ([`firmware::flash_layout::HEADER_OFFSET`])
//! says which version "runs", and 0x100A reports it.
//!
//! Each attached update lives as long as the process (`Box::leak`: the drive holds a
//! `&'static mut dyn FirmwareUpdate`, as the board's static does). Only drives that
//! ask for one get it: `virtual-drive`, and the tests that update.

use std::cell::RefCell;
use std::path::{Path, PathBuf};

use embassy_boot::{BootLoader, BootLoaderConfig, State};
use embassy_embedded_hal::flash::partition::BlockingPartition;
use embassy_sync::blocking_mutex::{raw::CriticalSectionRawMutex, Mutex};
use firmware::flash_layout::{self, Partition, ACTIVE, BOOT_STATE, DFU};
use firmware::update::{EmbassyUpdater, Update};

use crate::file_flash::FileFlash;

/// Size of the boot file: boot state, active and DFU partitions.
pub const BOOT_FILE_SIZE: usize = (BOOT_STATE.size + ACTIVE.size + DFU.size) as usize;

/// The boot file beside the parameter flash file `flash`.
pub fn boot_file(flash: &Path) -> PathBuf {
    PathBuf::from(format!("{}.boot", flash.display()))
}

/// The boot flash of a drive: mirrored to `file`, or in memory.
pub fn boot_flash(file: Option<PathBuf>) -> FileFlash {
    match file {
        Some(p) => FileFlash::open_sized(p, BOOT_FILE_SIZE),
        None => FileFlash::in_memory_sized(BOOT_FILE_SIZE),
    }
}

/// A drive's boot flash, shared by the bootloader and the firmware's updater (and
/// kept across the drive's restarts).
pub type SharedFlash = Mutex<CriticalSectionRawMutex, RefCell<FileFlash>>;
type Part = BlockingPartition<'static, CriticalSectionRawMutex, FileFlash>;

/// The boot flash `flash`, shared for the process's life.
pub fn share(flash: FileFlash) -> &'static SharedFlash {
    Box::leak(Box::new(Mutex::new(RefCell::new(flash))))
}

fn part(flash: &'static SharedFlash, p: Partition) -> Part {
    BlockingPartition::new(flash, p.offset - BOOT_STATE.offset, p.size)
}

/// One start of a drive's boot flash: embassy-boot's `prepare_boot` (the swap of a
/// marked update, or the revert of an unconfirmed one), then the firmware's update
/// over the same partitions. Returns the update and the bootloader's state.
pub fn boot(
    shared: &'static SharedFlash,
    vendor_id: u32,
    product_code: u32,
    esc: efw::Esc,
) -> (
    Update<impl firmware::update::Updater>,
    Result<State, String>,
) {
    let mut page = vec![0u8; flash_layout::PAGE as usize];
    let state = BootLoader::new(BootLoaderConfig {
        active: part(shared, ACTIVE),
        dfu: part(shared, DFU),
        state: part(shared, BOOT_STATE),
    })
    .prepare_boot(&mut page)
    .map_err(|e| format!("{e:?}"));
    let aligned: &'static mut [u8] = Box::leak(Box::new([0u8; 8]));
    let updater = EmbassyUpdater::new(
        part(shared, DFU),
        part(shared, BOOT_STATE),
        part(shared, ACTIVE),
        aligned,
    );
    (Update::new(updater, vendor_id, product_code, esc), state)
}
