//! The drive's bootloader: [embassy-boot] on the STM32G474RE. At every reset it looks
//! at the boot state; if the firmware asked for an update it swaps the new image
//! (DFU partition) with the running one (active partition), or, if a swapped-in
//! image never confirmed itself (it did not call `mark_booted` before the next
//! reset), swaps the previous one back. Then it starts the firmware in the active
//! partition.
//!
//! It checks no signature: the firmware receives the update (FoE), verifies its
//! ed25519 signature and only then marks it for the swap, as embassy-boot's
//! `FirmwareUpdater::verify_and_mark_updated` does.
//!
//! ## Flash layout
//! (`layout.x`, `firmware::flash_layout`; 2 KiB pages, flash in dual-bank mode)
//!
//! | partition | address | size |
//! |---|---|---|
//! | bootloader (this program) | 0x0800_0000 | 32 KiB |
//! | boot state (embassy-boot's magic and swap progress) | 0x0800_8000 | 4 KiB |
//! | active (the firmware; last page its `.efw` header) | 0x0800_9000 | 228 KiB |
//! | DFU (the update; after a swap the previous image) | 0x0804_2000 | 230 KiB |
//! | spare | 0x0807_B800 | 2 KiB |
//! | records (parameters, fault history; never touched here) | 0x0807_C000 | 16 KiB |
//!
//! ## Power cuts
//! embassy-boot's swap is power-fail safe: it moves one page at a time and records
//! each step in the boot state before the next one, so after a power cut (or any
//! reset) in the middle of a swap or a revert the next start resumes where it
//! stopped. A swap of the whole active partition takes some seconds. The firmware
//! runs the independent watchdog, which keeps running through the reset into the
//! bootloader; every flash operation here feeds it first ([`Fed`]).
//!
//! If the flash fails (or the option bytes are not in dual-bank mode, DBANK = 1), it
//! panics and stops; a probe can look, a power cycle tries again.
//!
//! ## Flash ECC errors
//! A double word torn by a power cut may fail the flash's ECC check when read: the
//! chip raises an NMI (FLASH_ECCR.ECCD) and the read returns garbage. The NMI
//! handler here notes it and clears ECCD ([`NonMaskableInt`]), and the read that hit
//! it fails ([`Fed`]'s `read`, `FedError::Ecc`), as the firmware's record reads do
//! (`firmware::storage::ecc`): embassy-boot never acts on garbage. In the boot-state
//! page a torn double word reads as erased — the write it belonged to did not
//! complete — and a page found torn is erased once no swapped image awaits its
//! confirmation (`firmware::boot_state`, tested with the power-cut model in
//! `tests-host/tests/boot_power_cut.rs`): the last good image boots. A failed read
//! anywhere else (the images) makes the preparation fail and the bootloader panic: it
//! stops (the PWM is never configured here, so the bridges stay off), and the
//! watchdog, if the firmware started it, resets the chip to try again. Any other NMI
//! stops the same way. The default handler (an endless
//! loop with the NMI still pending) is never used.
//!
//! ## Flashing
//! Once per board, with a debug probe: the bootloader, then the first firmware image
//! (linked at 0x0800_9000). (`cargo xtask size` builds both too, into
//! `target/bootloader/` and `target/firmware/`.)
//!
//! ```text
//! cargo build -p bootloader --release --target thumbv7em-none-eabihf
//! probe-rs download --chip STM32G474RETx target/thumbv7em-none-eabihf/release/bootloader
//! cargo xtask flash
//! ```
//!
//! (`cargo xtask flash` builds the firmware, downloads it and runs it with its defmt
//! log; without the log: `probe-rs download --chip STM32G474RETx` of the firmware ELF,
//! then `probe-rs reset --chip STM32G474RETx`.) Each download erases only the pages
//! it writes, so the parameter records survive. An erased boot state, or one
//! left over from firmware that was linked at 0x0800_0000, reads as "boot": the
//! bootloader starts the active image. Later images come through FoE.
//!
//! [embassy-boot]: https://docs.embassy.dev/embassy-boot
#![cfg_attr(target_os = "none", no_std, no_main)]
#![deny(clippy::undocumented_unsafe_blocks)]

#[cfg(target_os = "none")]
mod boot {
    use core::cell::RefCell;

    use core::sync::atomic::{AtomicBool, Ordering};

    use cortex_m_rt::{entry, exception};
    use embassy_boot_stm32::{AlignedBuffer, BootLoader, BootLoaderConfig};
    use embassy_stm32::flash::{Flash, FLASH_BASE, MAX_ERASE_SIZE};
    use embassy_stm32::pac;
    use embassy_sync::blocking_mutex::raw::NoopRawMutex;
    use embassy_sync::blocking_mutex::Mutex;
    use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};

    #[entry]
    fn main() -> ! {
        // Reset clocks (HSI16): all the bootloader needs; the firmware sets its own.
        let p = embassy_stm32::init(Default::default());
        let flash: Mutex<NoopRawMutex, _> =
            Mutex::new(RefCell::new(Fed(Flash::new_blocking(p.FLASH))));
        // The partitions from layout.x's __bootloader_* symbols (offsets).
        let config = BootLoaderConfig::from_linkerfile_blocking(&flash, &flash, &flash);
        let active = config.active.offset();
        let mut state = config.state;
        // Swap or revert if the boot state says so (resumes an interrupted one), with
        // torn state words read as erased (`firmware::boot_state`); the copy buffer
        // is one erase page.
        let mut buf = AlignedBuffer([0; MAX_ERASE_SIZE]);
        let Ok(found) =
            firmware::boot_state::prepare_boot(config.active, config.dfu, &mut state, &mut buf.0)
        else {
            panic!("boot prepare error")
        };
        let loader = BootLoader { state: found };
        // SAFETY: the active partition holds a cortex-m-rt image linked at its start
        // (firmware/memory.x), beginning with its vector table; `load` points VTOR there, and
        // sets the stack pointer and jumps to the reset vector from it.
        unsafe { loader.load(FLASH_BASE as u32 + active) }
    }

    /// Set by [`NonMaskableInt`] for a double ECC error; cleared and checked around each
    /// read of [`Fed`].
    static ECC_ERROR: AtomicBool = AtomicBool::new(false);

    #[exception]
    unsafe fn NonMaskableInt() {
        if pac::FLASH.eccr().read().eccd() {
            ECC_ERROR.store(true, Ordering::Release);
            // Cleared by writing 1 (else the NMI comes again at once).
            pac::FLASH.eccr().modify(|w| w.set_eccd(true));
        } else {
            // Not a flash ECC error: stop, as a panic does.
            loop {
                core::hint::spin_loop();
            }
        }
    }

    /// Errors of [`Fed`]: the flash's, or a double ECC error during a read.
    #[derive(Debug)]
    pub enum FedError<E> {
        /// The read hit a double ECC error (its bytes are garbage).
        Ecc,
        /// The flash driver's error.
        Flash(E),
    }

    impl<E: embedded_storage::nor_flash::NorFlashError> embedded_storage::nor_flash::NorFlashError
        for FedError<E>
    {
        fn kind(&self) -> embedded_storage::nor_flash::NorFlashErrorKind {
            match self {
                FedError::Ecc => embedded_storage::nor_flash::NorFlashErrorKind::Other,
                FedError::Flash(e) => e.kind(),
            }
        }
    }

    /// The flash, feeding the independent watchdog before every erase page and every
    /// write (each well under the firmware's watchdog period). Feeding a watchdog
    /// that does not run changes nothing.
    pub struct Fed<F>(F);

    fn feed_watchdog() {
        pac::IWDG
            .kr()
            .write(|w| w.set_key(pac::iwdg::vals::Key::RESET));
    }

    impl<F: ErrorType> ErrorType for Fed<F> {
        type Error = FedError<F::Error>;
    }

    impl<F: ReadNorFlash> ReadNorFlash for Fed<F> {
        const READ_SIZE: usize = F::READ_SIZE;

        fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
            ECC_ERROR.store(false, Ordering::Release);
            self.0.read(offset, bytes).map_err(FedError::Flash)?;
            if ECC_ERROR.load(Ordering::Acquire) {
                return Err(FedError::Ecc);
            }
            Ok(())
        }

        fn capacity(&self) -> usize {
            self.0.capacity()
        }
    }

    impl<F: NorFlash> NorFlash for Fed<F> {
        const WRITE_SIZE: usize = F::WRITE_SIZE;
        const ERASE_SIZE: usize = F::ERASE_SIZE;

        fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
            for page in (from..to).step_by(Self::ERASE_SIZE) {
                feed_watchdog();
                self.0
                    .erase(page, (page + Self::ERASE_SIZE as u32).min(to))
                    .map_err(FedError::Flash)?;
            }
            Ok(())
        }

        fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
            feed_watchdog();
            self.0.write(offset, bytes).map_err(FedError::Flash)
        }
    }

    #[panic_handler]
    fn panic(_: &core::panic::PanicInfo) -> ! {
        // Stop without touching the flash again: a probe can attach, and the next
        // reset resumes whatever was under way.
        cortex_m::interrupt::disable();
        loop {
            core::hint::spin_loop();
        }
    }
}

/// On the host there is no bootloader: the crate builds for the board target only.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("the bootloader runs on the board: build it with --target thumbv7em-none-eabihf");
    std::process::exit(1);
}
