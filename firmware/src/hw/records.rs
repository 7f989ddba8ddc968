//! Programming the staged flash records (a parameter 'save', the fault history)
//! outside the drive's lock: which record is next is the drive's
//! (`Drive::next_staged_record`); this module moves it into the flash and logs.

use core::sync::atomic::Ordering;

use crate::hw;
use crate::hw::boot::BoardDrive;
use crate::hw::flash::{ParamFlash, Stage};

/// The next record to program, taken under the lock (a staged 'save' first, else a
/// changed fault history); a history that could not be staged is logged.
pub fn next_staged(drive: &mut BoardDrive) -> Option<&'static mut Stage> {
    let (staged, history_error) = drive.next_staged_record();
    if let Some(e) = history_error {
        hw::log::FLASH_ERRORS.fetch_add(1, Ordering::Relaxed);
        defmt::error!(
            "fault history: not staged: {=istr}",
            hw::log::storage_error(e)
        );
    }
    staged
}

/// Programs `stage` (erase, payload, header last: the storage's power-loss order) and
/// logs the result; true when it failed (no flash counts as done).
pub fn commit_logged(flash: Option<&mut ParamFlash>, stage: &Stage) -> bool {
    let result = match flash {
        Some(f) => hw::flash::commit(f, stage),
        None => Ok(()),
    };
    match result {
        Ok(()) => {
            defmt::info!("flash record programmed (parameters or fault history)");
            false
        }
        Err(e) => {
            hw::log::FLASH_ERRORS.fetch_add(1, Ordering::Relaxed);
            defmt::error!(
                "flash record: programming failed: {=istr}",
                hw::log::storage_error(e)
            );
            true
        }
    }
}
