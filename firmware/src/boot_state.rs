//! What the bootloader does at reset (`bootloader/src/main.rs`), here so that the
//! power-cut tests (`tests-host/tests/boot_power_cut.rs`) run the same code:
//! embassy-boot's `prepare_boot`, with the boot-state page read through torn double
//! words ([`prepare_boot`]).
//!
//! A power cut inside the programming or the erase of one of embassy-boot's state
//! words (a magic, a progress word, the "progress invalid" word) may leave that
//! double word failing its ECC check: every read of it is a double ECC error (a
//! failed read, `bootloader`'s `NonMaskableInt`). embassy-boot reads every progress
//! word, so without more it would fail at every reset and the drive would never start
//! again. Here a state double word that cannot be read reads as *erased*
//! ([`TornAsErased`]): the write it belonged to did not complete, which is what it
//! means for embassy-boot too —
//! - a torn progress word: the step it recorded is done again (as after a cut just
//!   before that word), and its write, zeros over the torn word, completes it;
//! - a torn magic: "no update asked for" (SWAP_MAGIC cut while the firmware marked an
//!   update: the old image boots, the update is lost) or "boot" (the REVERT_MAGIC
//!   cut at the end of a revert: the reverted image boots);
//! - a torn word left by a cut state erase: erased, as the erase meant.
//!
//! When a torn word was seen (during the work or in a look at the whole page after
//! it) and no swapped image waits for its confirmation afterwards, the state page is
//! erased (an erased state reads "boot"), so the
//! firmware, which reads the magic, never meets the torn word. Whether a real torn
//! double word fails its ECC, and that a completed programming of zeros mends it, is
//! for a board to show.

use core::cell::Cell;

use embassy_boot::{BlockingFirmwareState, BootError, BootLoader, BootLoaderConfig, State};
use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// The ECC unit of the STM32G4's flash and embassy-boot's state write unit.
const DOUBLE_WORD: usize = 8;

/// The state page seen through torn double words: a double word that cannot be read
/// reads as erased, and `torn` is set (see the module docs). Writes and erases pass
/// through.
pub struct TornAsErased<'a, F> {
    inner: F,
    torn: &'a Cell<bool>,
}

impl<'a, F> TornAsErased<'a, F> {
    /// `inner` (the state partition), noting torn double words in `torn`.
    pub fn new(inner: F, torn: &'a Cell<bool>) -> Self {
        TornAsErased { inner, torn }
    }
}

impl<F: ErrorType> ErrorType for TornAsErased<'_, F> {
    type Error = F::Error;
}

impl<F: ReadNorFlash> ReadNorFlash for TornAsErased<'_, F> {
    const READ_SIZE: usize = F::READ_SIZE;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), F::Error> {
        let first = self.inner.read(offset, bytes);
        let end = offset as usize + bytes.len();
        if first.is_ok() || end > self.inner.capacity() {
            return first;
        }
        // Double word by double word: the ones that fail read as erased.
        let mut at = 0;
        while at < bytes.len() {
            let addr = offset as usize + at;
            let next = (addr - addr % DOUBLE_WORD + DOUBLE_WORD).min(end) - offset as usize;
            let chunk = &mut bytes[at..next];
            if self.inner.read(addr as u32, chunk).is_err() {
                chunk.fill(0xFF);
                self.torn.set(true);
            }
            at = next;
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.inner.capacity()
    }
}

impl<F: NorFlash> NorFlash for TornAsErased<'_, F> {
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), F::Error> {
        self.inner.erase(from, to)
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), F::Error> {
        self.inner.write(offset, bytes)
    }
}

/// The bootloader's work at reset: embassy-boot's `prepare_boot` (swap, revert or
/// nothing; returns the state it found) with `state` read through torn double words;
/// then, when one was seen and the state is not "swapped, awaiting confirmation",
/// the state page erased (see the module docs). `buf`: embassy-boot's copy buffer.
pub fn prepare_boot<A: NorFlash, D: NorFlash, S: NorFlash>(
    active: A,
    dfu: D,
    state: &mut S,
    buf: &mut [u8],
) -> Result<State, BootError> {
    let torn = Cell::new(false);
    let found = BootLoader::new(BootLoaderConfig {
        active,
        dfu,
        state: TornAsErased::new(&mut *state, &torn),
    })
    .prepare_boot(buf)?;
    // embassy-boot reads only the magic when there is nothing to do: look at the
    // whole page (a cut state erase may have torn a word behind an erased magic).
    let mut reader = TornAsErased::new(&mut *state, &torn);
    let mut chunk = [0u8; 64];
    let size = reader.capacity() as u32;
    for at in (0..size).step_by(chunk.len()) {
        let n = chunk.len().min((size - at) as usize);
        reader
            .read(at, &mut chunk[..n])
            .map_err(|e| BootError::Flash(e.kind()))?;
    }
    if torn.get() {
        let mut word = [0u8; DOUBLE_WORD];
        let now = BlockingFirmwareState::new(TornAsErased::new(&mut *state, &torn), &mut word)
            .get_state()
            .map_err(|_| BootError::Flash(NorFlashErrorKind::Other))?;
        if now != State::Swap {
            let size = state.capacity() as u32;
            state
                .erase(0, size)
                .map_err(|e| BootError::Flash(e.kind()))?;
        }
    }
    Ok(found)
}
