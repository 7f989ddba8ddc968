//! Sequential reading and writing of a slot's payload in whole flash units: a
//! buffered [`Reader`] and a buffered, CRC-computing [`Writer`].

use super::{flash_error, Crc32, StorageError, CHUNK, HEADER_LEN};
use embedded_storage::nor_flash::NorFlash;

/// Sequential reader of a slot's payload.
pub(super) struct Reader {
    start: u32,
    end: u32,
    pos: u32,
    buf: [u8; CHUNK],
    buf_at: u32,
    buf_len: u32,
}

impl Reader {
    pub(super) fn new(start: u32, len: u32) -> Self {
        Reader {
            start,
            end: len,
            pos: 0,
            buf: [0; CHUNK],
            buf_at: 0,
            buf_len: 0,
        }
    }
    pub(super) fn remaining(&self) -> u32 {
        self.end - self.pos
    }
    /// Reads `out.len()` bytes; `Ok(false)` when the payload ends first.
    pub(super) fn read<F: NorFlash>(
        &mut self,
        flash: &mut F,
        slot_end: u32,
        out: &mut [u8],
    ) -> Result<bool, StorageError> {
        if (out.len() as u32) > self.remaining() {
            self.pos = self.end;
            return Ok(false);
        }
        for b in out.iter_mut() {
            if self.pos < self.buf_at || self.pos >= self.buf_at + self.buf_len {
                let at = self.pos - self.pos % CHUNK as u32;
                let abs = self.start + at;
                let n = (slot_end.saturating_sub(abs)).min(CHUNK as u32);
                if n == 0 {
                    return Ok(false);
                }
                flash
                    .read(abs, &mut self.buf[..n as usize])
                    .map_err(flash_error)?;
                self.buf_at = at;
                self.buf_len = n;
            }
            // pos - buf_at < buf_len ≤ CHUNK here: `get` only drops the bounds check.
            let Some(&v) = self.buf.get((self.pos - self.buf_at) as usize) else {
                return Ok(false);
            };
            *b = v;
            self.pos += 1;
        }
        Ok(true)
    }
}

/// Buffered, CRC-computing writer of a slot's payload.
pub(super) struct Writer {
    start: u32,
    limit: u32,
    flushed: u32,
    buf: [u8; CHUNK],
    fill: usize,
    pub(super) crc: Crc32,
}

impl Writer {
    /// A writer of a payload starting at `start`, at most `limit` bytes.
    pub(super) fn new(start: u32, limit: u32) -> Self {
        Writer {
            start,
            limit,
            flushed: 0,
            buf: [0; CHUNK],
            fill: 0,
            crc: Crc32::new(),
        }
    }
    pub(super) fn push<F: NorFlash>(
        &mut self,
        flash: &mut F,
        bytes: &[u8],
    ) -> Result<(), StorageError> {
        for &b in bytes {
            if self.flushed + self.fill as u32 >= self.limit {
                return Err(StorageError::RecordTooLarge);
            }
            // fill < CHUNK (flushed when full): `get_mut` only drops the bounds check.
            let Some(slot) = self.buf.get_mut(self.fill) else {
                return Err(StorageError::RecordTooLarge);
            };
            *slot = b;
            self.fill += 1;
            if self.fill == CHUNK {
                self.flush(flash)?;
            }
        }
        self.crc.update(bytes);
        Ok(())
    }
    pub(super) fn flush<F: NorFlash>(&mut self, flash: &mut F) -> Result<(), StorageError> {
        if self.fill == 0 {
            return Ok(());
        }
        // fill ≤ CHUNK, a multiple of HEADER_LEN: the `min` and `skip` only let the
        // compiler drop the bounds checks.
        let padded = (self.fill.div_ceil(HEADER_LEN) * HEADER_LEN).min(CHUNK);
        let data = &mut self.buf[..padded];
        for b in data.iter_mut().skip(self.fill) {
            *b = 0xFF;
        }
        flash
            .write(self.start + self.flushed, data)
            .map_err(flash_error)?;
        self.flushed += self.fill as u32;
        self.fill = 0;
        Ok(())
    }
    pub(super) fn len(&self) -> u32 {
        self.flushed + self.fill as u32
    }
}
