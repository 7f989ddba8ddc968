//! Flash ECC errors: what a double ECC error means, decided here (and tested) for
//! the board's NMI handler (`firmware/src/hw/safety.rs`, `NonMaskableInt`) and its
//! record reads (`firmware/src/hw/flash.rs`, `MappedRegion`).
//!
//! The STM32G4 keeps an 8-bit ECC per 64-bit double word. A double word whose
//! programming or erase was cut by a power loss ("torn") may read with a double
//! error (FLASH_ECCR.ECCD), which the chip signals as an NMI; the data read is then
//! garbage. The rules:
//! - an ECC error inside the record region (parameters, fault history) is a failed
//!   read of that record: the NMI handler notes it and returns, the read returns an
//!   error ([`EccChecked`]), and the storage takes the record for corrupt and uses
//!   the other one ([`crate::storage::Storage::slot_status`]) — what it does for a
//!   torn record anyway, now also when the tear is in the ECC;
//! - anywhere else (program flash, the update partitions, an NMI without ECCD) the
//!   drive cannot trust what it runs: [`NmiAction::Stop`], the bridges off, the
//!   brake engaged, the watchdog resets the chip (`hw::safety`'s fatal path).

use core::ops::Range;
use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// What the NMI handler does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NmiAction {
    /// A double ECC error while reading a record: note it for the read in progress
    /// ([`EccMonitor::double_error`]), clear ECCD and return.
    RecordReadError,
    /// Anything else: bridges off, halt, watchdog reset.
    Stop,
}

/// The decision for an NMI: `eccd` (FLASH_ECCR.ECCD set), `offset` (the failing
/// double word's offset from the start of the flash, [`ecc_offset`]) and the record
/// region `records` (offsets).
pub fn nmi_action(eccd: bool, offset: u32, records: Range<u32>) -> NmiAction {
    if eccd && records.contains(&offset) {
        NmiAction::RecordReadError
    } else {
        NmiAction::Stop
    }
}

/// The flash offset of FLASH_ECCR's failing address: `addr` (ADDR_ECC, the byte
/// address inside the bank), `bank2` (BK_ECC), `bank_size` (dual-bank mode: half the
/// flash).
pub fn ecc_offset(bank2: bool, addr: u32, bank_size: u32) -> u32 {
    if bank2 {
        bank_size.saturating_add(addr)
    } else {
        addr
    }
}

/// Where the board's NMI handler leaves a double ECC error for the read in progress.
pub trait EccMonitor {
    /// Forgets an earlier error (before a read).
    fn clear(&mut self);
    /// True when a double ECC error was noted since [`EccMonitor::clear`].
    fn double_error(&mut self) -> bool;
}

/// Errors of an [`EccChecked`] flash.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EccError<E> {
    /// The read hit a double ECC error: its bytes are garbage.
    DoubleError,
    /// The flash's own error.
    Flash(E),
}

impl<E: NorFlashError> NorFlashError for EccError<E> {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            EccError::DoubleError => NorFlashErrorKind::Other,
            EccError::Flash(e) => e.kind(),
        }
    }
}

/// A flash whose reads fail when a double ECC error was noted during them (the
/// fallible read the storage reads records through).
pub struct EccChecked<F, M> {
    flash: F,
    monitor: M,
}

impl<F, M> EccChecked<F, M> {
    /// `flash`, checked with `monitor`.
    pub const fn new(flash: F, monitor: M) -> Self {
        EccChecked { flash, monitor }
    }
    /// The flash.
    pub fn inner_mut(&mut self) -> &mut F {
        &mut self.flash
    }
}

impl<F: ErrorType, M> ErrorType for EccChecked<F, M> {
    type Error = EccError<F::Error>;
}

impl<F: ReadNorFlash, M: EccMonitor> ReadNorFlash for EccChecked<F, M> {
    const READ_SIZE: usize = F::READ_SIZE;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.monitor.clear();
        self.flash.read(offset, bytes).map_err(EccError::Flash)?;
        if self.monitor.double_error() {
            bytes.fill(0xFF);
            return Err(EccError::DoubleError);
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.flash.capacity()
    }
}

impl<F: NorFlash, M: EccMonitor> NorFlash for EccChecked<F, M> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.flash.erase(from, to).map_err(EccError::Flash)
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.flash.write(offset, bytes).map_err(EccError::Flash)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::storage::{region, RamFlash, SlotStatus};

    #[test]
    fn only_a_double_error_in_the_records_is_a_read_error() {
        let records = 0x7C000..0x80000;
        assert_eq!(
            nmi_action(true, 0x7C000, records.clone()),
            NmiAction::RecordReadError
        );
        assert_eq!(
            nmi_action(true, 0x7FFF8, records.clone()),
            NmiAction::RecordReadError
        );
        assert_eq!(
            nmi_action(true, 0x7BFF8, records.clone()),
            NmiAction::Stop,
            "program"
        );
        assert_eq!(
            nmi_action(false, 0x7C000, records.clone()),
            NmiAction::Stop,
            "no ECCD"
        );
        assert_eq!(ecc_offset(true, 0x3C000, 0x40000), 0x7C000);
        assert_eq!(ecc_offset(false, 0x3C000, 0x40000), 0x3C000);
    }

    /// The NMI handler's note, as a test double: set while reading `bad`.
    struct Nmi<'a> {
        flag: &'a core::cell::Cell<bool>,
    }
    impl EccMonitor for Nmi<'_> {
        fn clear(&mut self) {
            self.flag.set(false);
        }
        fn double_error(&mut self) -> bool {
            self.flag.get()
        }
    }

    /// A flash whose double word at `bad` raises the (simulated) NMI when read.
    struct Torn<'a> {
        flash: RamFlash<{ region::SIZE as usize }>,
        bad: u32,
        flag: &'a core::cell::Cell<bool>,
    }
    impl embedded_storage::nor_flash::ErrorType for Torn<'_> {
        type Error = NorFlashErrorKind;
    }
    impl ReadNorFlash for Torn<'_> {
        const READ_SIZE: usize = 1;
        fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
            self.flash.read(offset, bytes)?;
            let end = offset + bytes.len() as u32;
            if offset < self.bad + 8 && self.bad < end {
                // Garbage, as the chip returns, and the NMI.
                bytes.fill(0x5A);
                self.flag.set(true);
            }
            Ok(())
        }
        fn capacity(&self) -> usize {
            self.flash.capacity()
        }
    }
    impl NorFlash for Torn<'_> {
        const WRITE_SIZE: usize = 8;
        const ERASE_SIZE: usize = 32;
        fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
            self.flash.erase(from, to)
        }
        fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
            self.flash.write(offset, bytes)
        }
    }

    #[test]
    fn a_record_read_with_a_double_error_is_corrupt_and_the_other_is_used() {
        let flag = core::cell::Cell::new(false);
        let h = region::HISTORY;
        let mut f = EccChecked::new(
            Torn {
                flash: RamFlash::new(),
                bad: u32::MAX - 8,
                flag: &flag,
            },
            Nmi { flag: &flag },
        );
        h.write_bytes(&mut f, &[1; 40]).unwrap();
        h.write_bytes(&mut f, &[2; 40]).unwrap();
        // The newer record (slot 1) gets a double error in its payload.
        f.inner_mut().bad = h.slot_address(1) + 40;
        let mut out = [0u8; 64];
        assert_eq!(h.slot_status(&mut f, 1), SlotStatus::Corrupt);
        assert_eq!(h.read_newest(&mut f, &mut out), Some(40));
        assert_eq!(out[..40], [1; 40], "the older record");
        // Without the check the garbage would have passed the read (and only the CRC
        // would stand between it and the drive).
        let mut raw = [0u8; 8];
        f.inner_mut()
            .read(h.slot_address(1) + 40, &mut raw)
            .unwrap();
        assert_eq!(raw, [0x5A; 8]);
        // The next write goes over the corrupt slot, and reads well again.
        h.write_bytes(&mut f, &[3; 40]).unwrap();
        f.inner_mut().bad = u32::MAX - 8;
        assert_eq!(h.read_newest(&mut f, &mut out), Some(40));
        assert_eq!(out[..40], [3; 40]);
    }
}
