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
    /// Erased flash, not mirrored.
    pub fn in_memory() -> Self {
        FileFlash {
            mem: vec![0xFF; SIZE],
            file: None,
            file_errors: 0,
        }
    }

    /// Flash mirrored to `path`: loads it when it exists (a file of another size is
    /// treated as erased flash), creates it on the first write.
    pub fn open(path: PathBuf) -> Self {
        let mut mem = vec![0xFF; SIZE];
        if let Ok(bytes) = std::fs::read(&path) {
            if bytes.len() == SIZE {
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

    fn persist(&mut self) {
        if let Some(path) = &self.file {
            let tmp = path.with_extension("tmp");
            let ok = std::fs::write(&tmp, &self.mem).is_ok() && std::fs::rename(&tmp, path).is_ok();
            if !ok {
                self.file_errors += 1;
            }
        }
    }
}

impl ErrorType for FileFlash {
    type Error = NorFlashErrorKind;
}

impl ReadNorFlash for FileFlash {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let range = storage::read_range(SIZE, offset, bytes.len())?;
        bytes.copy_from_slice(&self.mem[range]);
        Ok(())
    }
    fn capacity(&self) -> usize {
        SIZE
    }
}

impl NorFlash for FileFlash {
    const WRITE_SIZE: usize = 8;
    const ERASE_SIZE: usize = 2048;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let range = storage::erase_range(SIZE, Self::ERASE_SIZE, from, to)?;
        self.mem[range].fill(0xFF);
        self.persist();
        Ok(())
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let range = storage::write_range(&self.mem, Self::WRITE_SIZE, offset, bytes.len())?;
        self.mem[range].copy_from_slice(bytes);
        self.persist();
        Ok(())
    }
}
