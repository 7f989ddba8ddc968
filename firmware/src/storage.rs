//! Power-loss-safe parameter storage: two alternating flash records with a sequence
//! number and a CRC-32, behind the `embedded_storage` [`NorFlash`] trait.
//!
//! # Record format
//! A record lives in one of two equal *slots* (`slot_size` bytes each, a multiple of
//! the erase size): a [`HEADER_LEN`]-byte header ([`RecordHeader`], its layout in
//! [`record`]) and the payload. A parameter record's payload holds entries
//! `index u16, sub u8, len u8, value[len]` (little-endian).
//!
//! The payload holds one entry per `saved` entry of the *whole* dictionary, read
//! through [`Dictionary::read`] while iterating [`Dictionary::objects`]: the vendor
//! parameters and also the PDO mapping / assignment objects of the stack, or anything
//! another module marks `saved`. Restoring writes the values back through
//! [`Dictionary::write`] (in Pre-Op) after checking that the entry still exists, is
//! `saved`, has the same length and is in range; when an object's sub-index 0 is
//! saved and writable (mapping and assignment objects) it is first written 0, then the
//! other sub-indices, then its stored value — the order the PDO rules require. For such
//! objects only the sub-indices up to the count are stored.
//!
//! # Power-loss safety
//! A save always goes to the slot that does *not* hold the newest valid record: erase,
//! write the payload, and write the 32-byte header **last** (the header is the commit),
//! its first double word (the magic, [`COMMIT_WORD`]) after the other three.
//! A cut during the erase or the payload leaves that slot without a valid header; a cut
//! inside the header leaves no magic or a torn magic word. Either way the other slot is
//! untouched, so the old set survives.
//!
//! Reads are fallible: a double word torn by a cut may fail its ECC check (the
//! STM32G4's double ECC error, which the board turns into a failed read,
//! [`ecc`]), and any failed read of a slot makes that slot corrupt
//! ([`Storage::slot_status`]); the other slot is used. Load validates both slots and takes the valid
//! one with the newer sequence number; an erased slot is normal (first boot), a
//! non-erased invalid slot is reported ([`LoadReport::emergency`]).
//!
//! Restore defaults ('load' signature) writes a new record that keeps only what is
//! outside the restored scope (nothing for "all"), so the defaults apply at the next
//! power-up, as CiA 301 specifies for 0x1011.

use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::od::{Dictionary, ObjectKey, SdoAbort};
use embedded_storage::nor_flash::{NorFlash, NorFlashError, NorFlashErrorKind};

/// Largest value stored per entry (longer values are skipped).
pub const MAX_VALUE_LEN: usize = 64;
const CHUNK: usize = 64;

pub use crc::{crc32, Crc32};
use entries::{apply, count_first, entries, PendingCount};
use payload::{Reader, Writer};
pub use record::{
    RecordHeader, COMMIT_WORD, FORMAT_VERSION, HEADER_LEN, HISTORY_MAGIC, RECORD_MAGIC,
};

/// Which part of the dictionary a store / restore command covers (0x1010 / 0x1011
/// sub-index 1-4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scope {
    /// Sub-index 1 (all parameters) and 4 (E5: all parameters).
    All,
    /// Sub-index 2: communication parameters 0x1000-0x1FFF.
    Communication,
    /// Sub-index 3: application parameters 0x6000-0x9FFF.
    Application,
}

impl Scope {
    /// The scope of a 0x1010 / 0x1011 sub-index.
    pub fn from_sub(sub: u8) -> Option<Scope> {
        match sub {
            1 | 4 => Some(Scope::All),
            2 => Some(Scope::Communication),
            3 => Some(Scope::Application),
            _ => None,
        }
    }
    /// True when objects of `index` belong to this scope.
    pub fn contains(self, index: u16) -> bool {
        match self {
            Scope::All => true,
            Scope::Communication => (0x1000..=0x1FFF).contains(&index),
            Scope::Application => (0x6000..=0x9FFF).contains(&index),
        }
    }
}

/// What one slot holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlotStatus {
    /// Fully erased (never written).
    Erased,
    /// A complete record.
    Valid {
        /// Its sequence number.
        sequence: u32,
        /// Its payload length.
        payload_len: u32,
    },
    /// Written but not a valid record: torn save, interrupted erase, corruption, or a
    /// read error.
    Corrupt,
}

/// Why a save or restore failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StorageError {
    /// The flash driver failed (or power was lost).
    Flash(NorFlashErrorKind),
    /// The flash geometry does not fit the storage layout (alignment, capacity).
    Geometry,
    /// The record does not fit in a slot.
    RecordTooLarge,
}

impl StorageError {
    /// The SDO abort answering a failed 0x1010 / 0x1011 command.
    pub fn abort(self) -> SdoAbort {
        match self {
            StorageError::Flash(_) => SdoAbort::HardwareError,
            StorageError::Geometry | StorageError::RecordTooLarge => SdoAbort::DataCannotBeStored,
        }
    }
}

/// The storage error of a flash driver error (its kind).
pub(crate) fn flash_error<E: NorFlashError>(e: E) -> StorageError {
    StorageError::Flash(e.kind())
}

/// Result of a save.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SaveReport {
    /// Slot written.
    pub slot: usize,
    /// Sequence number of the new record.
    pub sequence: u32,
    /// Entries stored.
    pub entries: u16,
    /// Saved entries whose value could not be read (left out).
    pub unreadable: u16,
    /// Payload length.
    pub payload_len: u32,
}

/// Result of the power-up load.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoadReport {
    /// State of both slots.
    pub slots: [SlotStatus; 2],
    /// Slot and sequence of the record applied; `None`: defaults.
    pub source: Option<(usize, u32)>,
    /// Entries written to the dictionary.
    pub applied: u16,
    /// Stored entries refused (unknown object, not saved any more, wrong length, out of
    /// range, refused by the application).
    pub skipped: u16,
}

/// Emergency code for a corrupt record while the other one was used (non-volatile
/// memory, CiA 301 0x5530).
pub const EMCY_RECORD_CORRUPT: u16 = 0x5530;
/// Emergency code for "no valid record although flash was written": defaults in use
/// (loss of parameters, 0x6310).
pub const EMCY_PARAMETERS_LOST: u16 = 0x6310;
/// Emergency code for stored entries that were refused (parameter error, 0x6320).
pub const EMCY_PARAMETER_ERROR: u16 = 0x6320;

impl LoadReport {
    /// Bit n set: slot n is corrupt.
    pub fn corrupt_mask(&self) -> u8 {
        self.slots
            .iter()
            .enumerate()
            .filter(|(_, s)| **s == SlotStatus::Corrupt)
            .fold(0, |m, (i, _)| m | (1 << i))
    }
    /// The emergency the drive sends after loading (error code, manufacturer data), or
    /// `None` when the load was clean (including the blank flash of a first boot).
    /// Data byte 0: 1 record corrupt (other used), 2 defaults used, 3 entries refused;
    /// byte 1: corrupt slot mask; bytes 2-3: refused entry count.
    pub fn emergency(&self) -> Option<(u16, [u8; 5])> {
        let mask = self.corrupt_mask();
        let sk = self.skipped.to_le_bytes();
        if mask != 0 && self.source.is_none() {
            Some((EMCY_PARAMETERS_LOST, [2, mask, sk[0], sk[1], 0]))
        } else if mask != 0 {
            Some((EMCY_RECORD_CORRUPT, [1, mask, sk[0], sk[1], 0]))
        } else if self.skipped != 0 {
            Some((EMCY_PARAMETER_ERROR, [3, 0, sk[0], sk[1], 0]))
        } else {
            None
        }
    }
}

/// The two-slot record store at `base` in a [`NorFlash`].
///
/// The parameter records are its dictionary payload ([`Storage::save`],
/// [`Storage::load`]); other records (the fault history, `faults`) use the same
/// slots, header, CRC and slot selection with a payload of their own
/// ([`Storage::write_bytes`], [`Storage::read_newest`]) and their own magic, so one
/// piece of code carries the power-loss rules for every record in flash.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Storage {
    base: u32,
    slot_size: u32,
    magic: u32,
}

/// The newest valid record: slot, sequence number, payload length.
type Newest = (usize, u32, u32);

/// True when sequence `a` is newer than `b` (wrapping comparison).
pub fn newer(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) > 0
}

impl Storage {
    /// A store using two slots of `slot_size` bytes from `base` (checked against the
    /// flash geometry by [`Storage::check`] on every operation).
    pub const fn new(base: u32, slot_size: u32) -> Self {
        Self::with_magic(base, slot_size, RECORD_MAGIC)
    }

    /// [`Storage::new`] for records of another kind, told apart by `magic` (e.g.
    /// [`HISTORY_MAGIC`]).
    pub const fn with_magic(base: u32, slot_size: u32, magic: u32) -> Self {
        Storage {
            base,
            slot_size,
            magic,
        }
    }

    /// Start address of slot `n` (0 or 1).
    pub fn slot_address(&self, n: usize) -> u32 {
        self.base
            .saturating_add(self.slot_size.saturating_mul(n as u32))
    }

    /// Checks that the layout fits `F`'s geometry.
    pub fn check<F: NorFlash>(&self, flash: &F) -> Result<(), StorageError> {
        let ok = F::WRITE_SIZE > 0
            && F::READ_SIZE > 0
            && F::ERASE_SIZE > 0
            && HEADER_LEN.is_multiple_of(F::WRITE_SIZE)
            && HEADER_LEN.is_multiple_of(F::READ_SIZE)
            && (self.slot_size as usize).is_multiple_of(F::ERASE_SIZE)
            && (self.slot_size as usize).is_multiple_of(HEADER_LEN)
            && self.slot_size as usize >= 2 * HEADER_LEN
            && (self.base as usize).is_multiple_of(F::ERASE_SIZE)
            && (self.base as usize).saturating_add(2 * self.slot_size as usize) <= flash.capacity();
        if ok {
            Ok(())
        } else {
            Err(StorageError::Geometry)
        }
    }

    /// Slot `slot`'s header when it is one of this store's records (magic, format)
    /// with a payload length that fits the slot.
    fn read_header<F: NorFlash>(
        &self,
        flash: &mut F,
        slot: usize,
    ) -> Result<Option<RecordHeader<[u8; HEADER_LEN]>>, StorageError> {
        let mut h = [0u8; HEADER_LEN];
        flash
            .read(self.slot_address(slot), &mut h)
            .map_err(flash_error)?;
        let h = RecordHeader::new_unchecked(h);
        let ok = h.magic() == self.magic
            && h.format_version() == FORMAT_VERSION
            && h.payload_len() <= self.slot_size - HEADER_LEN as u32;
        Ok(ok.then_some(h))
    }

    fn payload_crc<F: NorFlash>(
        &self,
        flash: &mut F,
        slot: usize,
        payload_len: u32,
        checked: &[u8],
    ) -> Result<u32, StorageError> {
        let mut crc = Crc32::new();
        let mut buf = [0u8; CHUNK];
        let start = self.slot_address(slot) + HEADER_LEN as u32;
        let mut done = 0u32;
        while done < payload_len {
            let n = (payload_len - done).min(CHUNK as u32);
            // Reads stay aligned: whole 32-byte units, within the slot.
            // (n ≤ CHUNK, a multiple of HEADER_LEN: the `min` only lets the compiler
            // drop the bounds check.)
            let rn = ((n as usize).div_ceil(HEADER_LEN) * HEADER_LEN).min(CHUNK);
            flash
                .read(start + done, &mut buf[..rn])
                .map_err(flash_error)?;
            crc.update(&buf[..n as usize]);
            done += n;
        }
        crc.update(checked);
        Ok(crc.finish())
    }

    /// Classifies slot `n`.
    pub fn slot_status<F: NorFlash>(&self, flash: &mut F, slot: usize) -> SlotStatus {
        match self.try_slot_status(flash, slot) {
            Ok(s) => s,
            Err(_) => SlotStatus::Corrupt,
        }
    }

    fn try_slot_status<F: NorFlash>(
        &self,
        flash: &mut F,
        slot: usize,
    ) -> Result<SlotStatus, StorageError> {
        self.check(flash)?;
        if let Some(h) = self.read_header(flash, slot)? {
            if self.payload_crc(flash, slot, h.payload_len(), h.checked_part())? == h.crc() {
                return Ok(SlotStatus::Valid {
                    sequence: h.sequence(),
                    payload_len: h.payload_len(),
                });
            }
            return Ok(SlotStatus::Corrupt);
        }
        // No header: erased only if every byte of the slot is.
        let mut buf = [0u8; CHUNK];
        let mut at = 0u32;
        while at < self.slot_size {
            let n = (self.slot_size - at).min(CHUNK as u32) as usize;
            flash
                .read(self.slot_address(slot) + at, &mut buf[..n])
                .map_err(flash_error)?;
            if buf[..n].iter().any(|&b| b != 0xFF) {
                return Ok(SlotStatus::Corrupt);
            }
            at += n as u32;
        }
        Ok(SlotStatus::Erased)
    }

    /// The newest valid record (slot, sequence, payload length), as [`Storage::scan`]
    /// finds it, with less reading: both headers, then the check (payload CRC) of the
    /// newer record only, and of the other one only when the newer is not valid
    /// (a 'save' runs this under the drive's lock: one payload less to read and check).
    pub fn newest<F: NorFlash>(&self, flash: &mut F) -> Option<(usize, u32, u32)> {
        self.check(flash).ok()?;
        let seq = |flash: &mut F, i| Some(self.read_header(flash, i).ok()??.sequence());
        let (s0, s1) = (seq(flash, 0), seq(flash, 1));
        let first = usize::from(matches!((s0, s1), (Some(a), Some(b)) if newer(b, a)));
        [first, 1 - first]
            .into_iter()
            .filter(|&i| [s0, s1][i].is_some())
            .find_map(|i| match self.slot_status(flash, i) {
                SlotStatus::Valid {
                    sequence,
                    payload_len,
                } => Some((i, sequence, payload_len)),
                _ => None,
            })
    }

    /// Both slots' status and the slot holding the newest valid record.
    pub fn scan<F: NorFlash>(&self, flash: &mut F) -> ([SlotStatus; 2], Option<(usize, u32, u32)>) {
        let slots = [self.slot_status(flash, 0), self.slot_status(flash, 1)];
        let mut best: Option<(usize, u32, u32)> = None;
        for (i, s) in slots.iter().enumerate() {
            if let SlotStatus::Valid {
                sequence,
                payload_len,
            } = *s
            {
                if best.is_none_or(|(_, b, _)| newer(sequence, b)) {
                    best = Some((i, sequence, payload_len));
                }
            }
        }
        (slots, best)
    }

    /// Power-up load: applies the newest valid record to `dict` (or nothing: defaults)
    /// and reports what it found. Never panics on any flash content.
    pub fn load<F: NorFlash, D: Dictionary + ?Sized>(
        &self,
        flash: &mut F,
        dict: &mut D,
    ) -> LoadReport {
        let (slots, best) = self.scan(flash);
        let mut report = LoadReport {
            slots,
            source: None,
            applied: 0,
            skipped: 0,
        };
        let Some((slot, sequence, len)) = best else {
            return report;
        };
        report.source = Some((slot, sequence));
        let slot_end = self.slot_address(slot) + self.slot_size;
        let mut rd = Reader::new(self.slot_address(slot) + HEADER_LEN as u32, len);
        let mut pending: Option<PendingCount> = None;
        let mut value = [0u8; MAX_VALUE_LEN];
        loop {
            if rd.remaining() == 0 {
                break;
            }
            let mut tl = [0u8; 4];
            if !matches!(rd.read(flash, slot_end, &mut tl), Ok(true)) {
                // Trailing bytes that are not a whole entry, or a read error.
                report.skipped = report.skipped.saturating_add(1);
                break;
            }
            let index = u16::from_le_bytes([tl[0], tl[1]]);
            let sub = tl[2];
            let n = tl[3] as usize;
            if n > MAX_VALUE_LEN || n as u32 > rd.remaining() {
                report.skipped = report.skipped.saturating_add(1);
                break;
            }
            if !matches!(rd.read(flash, slot_end, &mut value[..n]), Ok(true)) {
                report.skipped = report.skipped.saturating_add(1);
                break;
            }
            if pending.as_ref().is_some_and(|p| p.index != index) {
                if let Some(p) = pending.take() {
                    apply(dict, ObjectKey::new(p.index, 0), p.bytes(), &mut report);
                }
            }
            if sub == 0 && n <= 8 && count_first(dict, index) {
                let zero = [0u8; 8];
                let _ = dict.write(ObjectKey::new(index, 0), &zero[..n], EsmState::PreOp);
                let mut v = [0u8; 8];
                v[..n].copy_from_slice(&value[..n]);
                pending = Some(PendingCount {
                    index,
                    value: v,
                    len: n,
                });
                continue;
            }
            apply(dict, ObjectKey::new(index, sub), &value[..n], &mut report);
        }
        if let Some(p) = pending.take() {
            apply(dict, ObjectKey::new(p.index, 0), p.bytes(), &mut report);
        }
        report
    }

    /// 'save': writes every `saved` entry of `dict` inside `scope` (plus, for a partial
    /// scope, the stored entries outside it) as a new record in the other slot.
    pub fn save<F: NorFlash, D: Dictionary + ?Sized>(
        &self,
        flash: &mut F,
        dict: &mut D,
        scope: Scope,
    ) -> Result<SaveReport, StorageError> {
        self.write_record(flash, Some(dict), scope)
    }

    /// 'load' (restore defaults): a new record without the entries of `scope`, so the
    /// defaults apply at the next power-up.
    pub fn restore_defaults<F: NorFlash>(
        &self,
        flash: &mut F,
        scope: Scope,
    ) -> Result<SaveReport, StorageError> {
        self.write_record::<F, dyn Dictionary>(flash, None, scope)
    }

    /// [`Storage::save`] (`dict` given) or [`Storage::restore_defaults`] (`None`): one
    /// code path for both commands.
    pub(crate) fn write_record<F: NorFlash, D: Dictionary + ?Sized>(
        &self,
        flash: &mut F,
        dict: Option<&mut D>,
        scope: Scope,
    ) -> Result<SaveReport, StorageError> {
        let (mut w, target, sequence, best) = self.begin(flash)?;
        let mut report = self.keep_outside(flash, &mut w, target, sequence, best, scope)?;
        if let Some(dict) = dict {
            entries(dict, scope, &mut report, &mut |head, value| {
                w.push(flash, head)?;
                w.push(flash, value)
            })?;
        }
        report.payload_len = self.finish(flash, w, target, sequence)?;
        Ok(report)
    }

    /// The dictionary part of a 'save' / 'load' command serialised into `out` with no
    /// flash access, no CRC and no look at the existing records (what a staged save
    /// does under the drive's lock, `staged_flash::StagedRecords`): the entries
    /// of `dict` inside `scope` (none for a restore, `dict` = `None`). The record is
    /// written later by [`Storage::write_serialised`]. Returns the report with the
    /// payload length so far (slot and sequence are decided when it is written).
    pub fn serialise<D: Dictionary + ?Sized>(
        &self,
        dict: Option<&mut D>,
        scope: Scope,
        out: &mut [u8],
    ) -> Result<SaveReport, StorageError> {
        let limit = out
            .len()
            .min((self.slot_size as usize).saturating_sub(HEADER_LEN));
        let mut report = SaveReport {
            slot: 0,
            sequence: 0,
            entries: 0,
            unreadable: 0,
            payload_len: 0,
        };
        let mut at = 0usize;
        if let Some(dict) = dict {
            entries(dict, scope, &mut report, &mut |head, value| {
                for part in [head, value] {
                    let end = at + part.len();
                    out.get_mut(at..end)
                        .filter(|_| end <= limit)
                        .ok_or(StorageError::RecordTooLarge)?
                        .copy_from_slice(part);
                    at = end;
                }
                Ok(())
            })?;
        }
        report.payload_len = at as u32;
        Ok(report)
    }

    /// Writes a record whose dictionary part [`Storage::serialise`] produced
    /// (`payload`), with the power-loss order of [`Storage::save`]: the newest record
    /// found (header, then its payload's CRC), its entries outside `scope` kept first
    /// (a partial command), then `payload`, the CRC and the header last.
    pub fn write_serialised<F: NorFlash>(
        &self,
        flash: &mut F,
        payload: &[u8],
        scope: Scope,
    ) -> Result<SaveReport, StorageError> {
        let (mut w, target, sequence, best) = self.begin(flash)?;
        let mut report = self.keep_outside(flash, &mut w, target, sequence, best, scope)?;
        w.push(flash, payload)?;
        report.payload_len = self.finish(flash, w, target, sequence)?;
        Ok(report)
    }

    /// A new record's report, with the entries of the previous record (`best`) outside
    /// `scope` pushed to `w` first: they survive a partial command.
    fn keep_outside<F: NorFlash>(
        &self,
        flash: &mut F,
        w: &mut Writer,
        target: usize,
        sequence: u32,
        best: Option<Newest>,
        scope: Scope,
    ) -> Result<SaveReport, StorageError> {
        let mut report = SaveReport {
            slot: target,
            sequence,
            entries: 0,
            unreadable: 0,
            payload_len: 0,
        };
        if let (Some((old, _, len)), true) = (best, scope != Scope::All) {
            let old_end = self.slot_address(old) + self.slot_size;
            let mut rd = Reader::new(self.slot_address(old) + HEADER_LEN as u32, len);
            let mut value = [0u8; MAX_VALUE_LEN];
            loop {
                let mut tl = [0u8; 4];
                if !rd.read(flash, old_end, &mut tl)? {
                    break;
                }
                let n = tl[3] as usize;
                if n > MAX_VALUE_LEN || !rd.read(flash, old_end, &mut value[..n])? {
                    break;
                }
                if !scope.contains(u16::from_le_bytes([tl[0], tl[1]])) {
                    w.push(flash, &tl)?;
                    w.push(flash, &value[..n])?;
                    report.entries += 1;
                }
            }
        }
        Ok(report)
    }

    /// Start of a new record: the layout checked, the target slot (the one *not*
    /// holding the newest valid record) erased, a writer for its payload. Returns the
    /// writer, the target slot, the new sequence number and the newest record found
    /// (slot, sequence, payload length).
    fn begin<F: NorFlash>(
        &self,
        flash: &mut F,
    ) -> Result<(Writer, usize, u32, Option<Newest>), StorageError> {
        self.check(flash)?;
        let best = self.newest(flash);
        let (target, sequence) = match best {
            Some((slot, seq, _)) => (1 - slot, seq.wrapping_add(1)),
            None => (0, 1),
        };
        let base = self.slot_address(target);
        flash
            .erase(base, base + self.slot_size)
            .map_err(flash_error)?;
        let w = Writer::new(base + HEADER_LEN as u32, self.slot_size - HEADER_LEN as u32);
        Ok((w, target, sequence, best))
    }

    /// End of a new record: the payload flushed, then the header written **last** —
    /// the commit (see the module docs). Returns the payload length.
    fn finish<F: NorFlash>(
        &self,
        flash: &mut F,
        mut w: Writer,
        target: usize,
        sequence: u32,
    ) -> Result<u32, StorageError> {
        let payload_len = w.len();
        w.flush(flash)?;
        let mut header = RecordHeader::new(self.magic, sequence, payload_len);
        let mut crc = w.crc;
        crc.update(header.checked_part());
        header.set_crc(crc.finish());
        let head = header.into_inner();
        // The magic's double word last: a cut in the header's other words leaves no
        // magic, a cut in the magic's word a torn word (an ECC error on the chip):
        // either way no record, until the very last write.
        // (A flash whose write unit is larger writes the header at once.)
        let at = self.slot_address(target);
        let commit = if COMMIT_WORD.is_multiple_of(F::WRITE_SIZE) {
            COMMIT_WORD
        } else {
            0
        };
        if commit > 0 {
            flash
                .write(at + commit as u32, &head[commit..])
                .map_err(flash_error)?;
        }
        flash
            .write(at, &head[..if commit > 0 { commit } else { HEADER_LEN }])
            .map_err(flash_error)?;
        Ok(payload_len)
    }

    /// Writes `payload` as a new record (a record kind of its own, see
    /// [`Storage::with_magic`]), with the power-loss order of [`Storage::save`]: a cut
    /// at any point leaves the previous record valid.
    pub fn write_bytes<F: NorFlash>(
        &self,
        flash: &mut F,
        payload: &[u8],
    ) -> Result<SaveReport, StorageError> {
        self.write_serialised(flash, payload, Scope::All)
    }

    /// The payload of the newest valid record, copied into `out`: its length, or
    /// `None` when there is no valid record (erased, torn or corrupt slots), it does
    /// not fit in `out`, or the flash cannot be read. Never panics on any content.
    pub fn read_newest<F: NorFlash>(&self, flash: &mut F, out: &mut [u8]) -> Option<usize> {
        let (slot, _, len) = self.newest(flash)?;
        let len = len as usize;
        let dst = out.get_mut(..len)?;
        let slot_end = self.slot_address(slot) + self.slot_size;
        let mut rd = Reader::new(self.slot_address(slot) + HEADER_LEN as u32, len as u32);
        match rd.read(flash, slot_end, dst) {
            Ok(true) => Some(len),
            _ => None,
        }
    }
}

/// The record layout of the drive's 16 KiB record region (the board's `PARAMS` region
/// in memory.x, the file of `virtual-drive --flash`; offsets relative to the region):
///
/// | offset | size | records |
/// |---|---|---|
/// | 0 | 2 × 4 KiB | parameters ([`region::PARAMS`], magic "ECSP") |
/// | 8 KiB | 2 × 4 KiB | fault history + operating time ([`region::HISTORY`], magic "ECSH") |
///
/// Every slot is a whole number of erase pages in either bank mode (2 KiB dual-bank,
/// 4 KiB single-bank pages), and erasing one (≤ 2 dual-bank pages) stays within what
/// the board's watchdog covers. A parameter record is at most the board's 2 KiB stage;
/// a history record is < 200 bytes.
/// A parameter record found at offset 8 KiB (a layout of two 8 KiB parameter slots)
/// is not a history record (other magic): the history starts empty and its first
/// write erases it, and the parameters load from the record at offset 0, if any.
pub mod region {
    use super::{Storage, HISTORY_MAGIC};
    /// Size of the region.
    pub const SIZE: u32 = 16 * 1024;
    const _: () = assert!(SIZE == crate::flash_layout::RECORDS.size);
    /// The parameter records.
    pub const PARAMS: Storage = Storage::new(0, 4 * 1024);
    /// The fault-history records.
    pub const HISTORY: Storage = Storage::with_magic(8 * 1024, 4 * 1024, HISTORY_MAGIC);
}

/// An empty dictionary (tests).
#[cfg(test)]
struct NoDict;

#[cfg(test)]
impl Dictionary for NoDict {
    fn objects(&self) -> &'static [ecat_slave_stack::od::Object] {
        &[]
    }
    fn read(&mut self, _: ObjectKey, _: &mut [u8]) -> Result<usize, SdoAbort> {
        Err(SdoAbort::ObjectDoesNotExist)
    }
    fn write(&mut self, _: ObjectKey, _: &[u8], _: EsmState) -> Result<(), SdoAbort> {
        Err(SdoAbort::ObjectDoesNotExist)
    }
}

mod crc;
pub mod ecc;
mod entries;
mod payload;
mod ram_flash;
pub mod rate;
pub mod record;

pub use ram_flash::{erase_range, read_range, write_range, PagedRamFlash, RamFlash};

#[cfg(test)]
mod tests;
