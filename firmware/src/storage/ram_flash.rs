//! RAM models of the NOR flash (simulation and tests) and the range checks of a
//! flash operation they share with the board driver.

use super::*;

/// The bytes a read of `len` bytes at `offset` covers in a flash of `capacity` bytes
/// (the range check shared by the NOR flashes held in memory: [`RamFlash`] and the
/// host's file-backed flash).
pub fn read_range(
    capacity: usize,
    offset: u32,
    len: usize,
) -> Result<core::ops::Range<usize>, NorFlashErrorKind> {
    let start = offset as usize;
    match start.checked_add(len) {
        Some(end) if end <= capacity => Ok(start..end),
        _ => Err(NorFlashErrorKind::OutOfBounds),
    }
}

/// The bytes an erase of `from..to` covers: within `capacity`, on `erase_size`
/// boundaries.
pub fn erase_range(
    capacity: usize,
    erase_size: usize,
    from: u32,
    to: u32,
) -> Result<core::ops::Range<usize>, NorFlashErrorKind> {
    let (from, to) = (from as usize, to as usize);
    if from > to || to > capacity {
        return Err(NorFlashErrorKind::OutOfBounds);
    }
    if !from.is_multiple_of(erase_size) || !to.is_multiple_of(erase_size) {
        return Err(NorFlashErrorKind::NotAligned);
    }
    Ok(from..to)
}

/// The bytes a write of `len` bytes at `offset` into `mem` covers: offset and length
/// multiples of `write_size`, within `mem`, and every byte still erased (0xFF) —
/// programming a double word twice is an error on the STM32G4 (`Other`).
pub fn write_range(
    mem: &[u8],
    write_size: usize,
    offset: u32,
    len: usize,
) -> Result<core::ops::Range<usize>, NorFlashErrorKind> {
    if !(offset as usize).is_multiple_of(write_size) || !len.is_multiple_of(write_size) {
        return Err(NorFlashErrorKind::NotAligned);
    }
    let range = read_range(mem.len(), offset, len)?;
    if mem[range.clone()].iter().any(|&b| b != 0xFF) {
        return Err(NorFlashErrorKind::Other);
    }
    Ok(range)
}

/// A RAM [`NorFlash`] for simulation and tests: `N` bytes, 32-byte pages, 8-byte write
/// units (like the STM32G4's double words). Writing a byte that is not erased fails,
/// as on the chip. It can lose power after a given number of byte operations (erase or
/// write): the operation in progress stops there and every later one fails until
/// [`RamFlash::power_on`].
///
/// ECC, as the STM32G4's per double word: a cut that leaves a double word partly
/// programmed or partly erased ("torn") leaves its ECC wrong, and every later read
/// that touches it fails (`Other`, the chip's double ECC error) until it is erased
/// (the board turns the NMI into the same failed read: [`crate::storage::ecc`]).
#[derive(Clone)]
pub struct RamFlash<const N: usize> {
    /// The memory.
    pub mem: [u8; N],
    budget: Option<usize>,
    dead: bool,
    /// Byte operations done since the last [`RamFlash::power_on`].
    pub ops: usize,
    /// Bytes read so far (the work a reader did: tests that bound it per call).
    pub reads: usize,
    /// Torn double words (offsets; the oldest is forgotten when more are torn).
    torn: [Option<u32>; TORN_MAX],
}

/// Torn double words a [`RamFlash`] remembers.
const TORN_MAX: usize = 8;

/// Its double word of byte offset `i`.
const fn word_of(i: usize) -> u32 {
    (i & !7) as u32
}

impl<const N: usize> Default for RamFlash<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> RamFlash<N> {
    /// Erased flash.
    pub const fn new() -> Self {
        RamFlash {
            mem: [0xFF; N],
            budget: None,
            dead: false,
            ops: 0,
            reads: 0,
            torn: [None; TORN_MAX],
        }
    }
    /// True when the double word at `offset` (a multiple of 8) is torn.
    pub fn is_torn(&self, offset: u32) -> bool {
        self.torn.contains(&Some(offset))
    }
    /// Marks the double word of byte `i` torn when the cut at `i` left it half done.
    fn tear(&mut self, i: usize) {
        if i.is_multiple_of(8) || self.is_torn(word_of(i)) {
            return;
        }
        self.torn.rotate_right(1);
        self.torn[0] = Some(word_of(i));
    }
    /// The double words of `range` have a good ECC again (erased or programmed).
    fn mend(&mut self, range: core::ops::Range<usize>) {
        for t in self.torn.iter_mut() {
            if t.is_some_and(|w| range.contains(&(w as usize))) {
                *t = None;
            }
        }
    }
    /// Power is lost after `ops` more byte operations.
    pub fn cut_power_after(&mut self, ops: usize) {
        self.budget = Some(ops);
    }
    /// Power back, no cut scheduled.
    pub fn power_on(&mut self) {
        self.budget = None;
        self.dead = false;
        self.ops = 0;
    }
    /// True once power was cut.
    pub fn power_lost(&self) -> bool {
        self.dead
    }
    fn step(&mut self) -> Result<(), NorFlashErrorKind> {
        if self.dead {
            return Err(NorFlashErrorKind::Other);
        }
        if let Some(b) = self.budget {
            if b == 0 {
                self.dead = true;
                return Err(NorFlashErrorKind::Other);
            }
            self.budget = Some(b - 1);
        }
        self.ops += 1;
        Ok(())
    }
}

impl<const N: usize> embedded_storage::nor_flash::ErrorType for RamFlash<N> {
    type Error = NorFlashErrorKind;
}

impl<const N: usize> embedded_storage::nor_flash::ReadNorFlash for RamFlash<N> {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        if self.dead {
            return Err(NorFlashErrorKind::Other);
        }
        let range = read_range(N, offset, bytes.len())?;
        let (first, end) = (word_of(range.start), range.end as u32);
        if self.torn.iter().flatten().any(|&w| w >= first && w < end) {
            // The double ECC error: the chip's NMI, a failed read here.
            return Err(NorFlashErrorKind::Other);
        }
        bytes.copy_from_slice(&self.mem[range]);
        self.reads += bytes.len();
        Ok(())
    }
    fn capacity(&self) -> usize {
        N
    }
}

impl<const N: usize> NorFlash for RamFlash<N> {
    const WRITE_SIZE: usize = 8;
    const ERASE_SIZE: usize = 32;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let range = erase_range(N, Self::ERASE_SIZE, from, to)?;
        for i in range.clone() {
            if let Err(e) = self.step() {
                self.mend(range.start..word_of(i) as usize);
                self.tear(i);
                return Err(e);
            }
            self.mem[i] = 0xFF;
        }
        self.mend(range);
        Ok(())
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let range = write_range(&self.mem, Self::WRITE_SIZE, offset, bytes.len())?;
        for (i, &b) in range.clone().zip(bytes) {
            if let Err(e) = self.step() {
                self.tear(i);
                return Err(e);
            }
            self.mem[i] = b;
        }
        self.mend(range);
        Ok(())
    }
}

/// A [`RamFlash`] erased in the STM32G4's 2 KiB pages (dual-bank mode) with its 8-byte
/// writes: the flash model of the firmware update's tests (embassy-boot sizes its
/// state by the page count, so the page size must be the chip's).
#[derive(Clone, Default)]
pub struct PagedRamFlash<const N: usize>(pub RamFlash<N>);

impl<const N: usize> PagedRamFlash<N> {
    /// Erased flash.
    pub const fn new() -> Self {
        PagedRamFlash(RamFlash::new())
    }
}

impl<const N: usize> embedded_storage::nor_flash::ErrorType for PagedRamFlash<N> {
    type Error = NorFlashErrorKind;
}

impl<const N: usize> embedded_storage::nor_flash::ReadNorFlash for PagedRamFlash<N> {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.0.read(offset, bytes)
    }
    fn capacity(&self) -> usize {
        N
    }
}

impl<const N: usize> NorFlash for PagedRamFlash<N> {
    const WRITE_SIZE: usize = 8;
    const ERASE_SIZE: usize = crate::flash_layout::PAGE as usize;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        erase_range(N, Self::ERASE_SIZE, from, to)?;
        self.0.erase(from, to)
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.0.write(offset, bytes)
    }
}
