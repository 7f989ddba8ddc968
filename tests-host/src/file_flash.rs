//! A NOR flash in host memory with the STM32G4's geometry (8-byte double-word writes,
//! 2 KiB pages), optionally mirrored to a file so a 'save' survives a restart of the
//! program — as on a real drive (`virtual-drive --flash FILE`).

use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash};
use firmware::storage;
use std::path::PathBuf;

/// Size of the record region (as in `memory.x`; laid out as
/// `firmware::storage::region`: parameters, then the fault history).
pub const SIZE: usize = firmware::storage::region::SIZE as usize;

/// Flash contents in memory, mirrored to `file` after every change when set.
pub struct FileFlash {
    mem: Vec<u8>,
    file: Option<PathBuf>,
    /// Errors writing the mirror file (the in-memory copy stays valid).
    pub file_errors: u32,
}

impl FileFlash {
    /// Erased record region ([`SIZE`]), not mirrored.
    pub fn in_memory() -> Self {
        Self::in_memory_sized(SIZE)
    }

    /// Erased flash of `size` bytes, not mirrored.
    pub fn in_memory_sized(size: usize) -> Self {
        FileFlash {
            mem: vec![0xFF; size],
            file: None,
            file_errors: 0,
        }
    }

    /// The record region ([`SIZE`]) mirrored to `path` (see [`FileFlash::open_sized`]).
    pub fn open(path: PathBuf) -> Self {
        Self::open_sized(path, SIZE)
    }

    /// Flash of `size` bytes mirrored to `path`: loads it when it exists (a file of
    /// another size is treated as erased flash), creates it on the first write.
    pub fn open_sized(path: PathBuf, size: usize) -> Self {
        let mut mem = vec![0xFF; size];
        if let Ok(bytes) = std::fs::read(&path) {
            if bytes.len() == size {
                mem.copy_from_slice(&bytes);
            }
        }
        FileFlash {
            mem,
            file: Some(path),
            file_errors: 0,
        }
    }

    /// The contents.
    pub fn bytes(&self) -> &[u8] {
        &self.mem
    }

    /// Mirrors the bytes `range` to the file: in place when the file has the flash's
    /// size (a process killed mid-write is then a power cut at that byte, which the
    /// record and boot layers survive), else the whole flash, written beside the file
    /// and renamed over it.
    fn persist(&mut self, range: std::ops::Range<usize>) {
        use std::os::unix::fs::FileExt;
        let Some(path) = &self.file else {
            return;
        };
        let in_place = std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .ok()
            .filter(|f| f.metadata().is_ok_and(|m| m.len() == self.mem.len() as u64))
            .map(|f| {
                f.write_all_at(&self.mem[range.clone()], range.start as u64)
                    .is_ok()
            });
        let ok = match in_place {
            Some(ok) => ok,
            None => {
                let tmp = path.with_extension("tmp");
                std::fs::write(&tmp, &self.mem).is_ok() && std::fs::rename(&tmp, path).is_ok()
            }
        };
        if !ok {
            self.file_errors += 1;
        }
    }
}

impl ErrorType for FileFlash {
    type Error = NorFlashErrorKind;
}

impl ReadNorFlash for FileFlash {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let range = storage::read_range(self.mem.len(), offset, bytes.len())?;
        bytes.copy_from_slice(&self.mem[range]);
        Ok(())
    }
    fn capacity(&self) -> usize {
        self.mem.len()
    }
}

impl NorFlash for FileFlash {
    const WRITE_SIZE: usize = 8;
    const ERASE_SIZE: usize = 2048;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let range = storage::erase_range(self.mem.len(), Self::ERASE_SIZE, from, to)?;
        self.mem[range.clone()].fill(0xFF);
        self.persist(range);
        Ok(())
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let range = storage::write_range(&self.mem, Self::WRITE_SIZE, offset, bytes.len())?;
        self.mem[range.clone()].copy_from_slice(bytes);
        self.persist(range);
        Ok(())
    }
}
