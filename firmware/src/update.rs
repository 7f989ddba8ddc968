//! Firmware update over EtherCAT: the FoE files of the Bootstrap state, the checks of
//! a signed `.efw` image ([`efw`]) and embassy-boot's trial boot.
//!
//! # The path of an update
//! 1. The master takes the drive Init → Bootstrap (the power stage stays off there) and
//!    writes a `*.efw` file over FoE ([`Update`] is the drive's [`FoeFiles`]).
//! 2. The first [`efw::HEADER_LEN`] bytes are the header: format, header signature
//!    with the key the build trusts ([`TRUST`]), vendor and product code, ESC
//!    flavour, an image length that fits [`flash_layout::IMAGE_MAX`], and a security
//!    version not below the running image's (anti-rollback, see below). Anything
//!    else is refused with an FoE error before a byte of the DFU partition is erased.
//! 3. The image goes to the DFU partition through embassy-boot's
//!    `write_firmware`, in writes of [`WRITE_CHUNK`] bytes (the FoE data of a packet
//!    is not a multiple of the flash's 8-byte unit).
//! 4. The DATA that completes the image starts its check, answered FoE BUSY until it
//!    is done, one bounded step per answer (`Update::verify_step`): the last chunk
//!    written, the header to the DFU partition's header page
//!    ([`flash_layout::HEADER_OFFSET`]), SHA-512 over the DFU partition
//!    [`VERIFY_STEP`] bytes at a time, and the image signature (ed25519, the same check
//!    as embassy-boot's `verify_and_mark_updated`). Then the transfer's end marks the
//!    partition for the swap (embassy-boot's `mark_updated`, one state-page erase),
//!    before the last packet is acknowledged. No step runs longer than one page erase
//!    or one signature check (≈ 25 ms), so the thread that polls the slave feeds the
//!    300 ms watchdog in between, whatever the image length (at once: ≈ 1.4 ms per
//!    KiB, ≈ 230 ms for the largest image).
//! 5. Bootstrap → Init: the drive resets; embassy-boot swaps (power-fail safe) and
//!    starts the new image on trial ([`BootState::Trial`]).
//! 6. The new image confirms itself (`mark_booted`, [`Update::confirm`]) once its
//!    start-up checks have passed and the EtherCAT runtime reached Pre-Op. A reset
//!    before that (a crash, the watchdog) makes embassy-boot revert to the old image,
//!    which then reports [`BootState::Reverted`] and confirms itself.
//!
//! While an image is on trial no update is taken (embassy-boot's rule: the running
//! image must be confirmed first), and neither is a second one in the Bootstrap that
//! accepted one (it would rewrite the partition marked for the swap); the refusal
//! says so (FoE "access denied").
//!
//! # Anti-rollback
//! The update header carries a security version (`efw`). The lowest one the drive
//! accepts is the running image's, read from the header page of the active
//! partition: the swap installs that page with the image, and only an image that
//! confirmed itself stays there (an unconfirmed one is reverted with its page). So
//! the floor is the highest security version the drive accepted and kept, persisted
//! in flash with the image itself. A file below it is refused with FoE "access
//! denied" (0x8002) before anything is erased. The bootloader (embassy-boot) checks
//! no signature or version: it only swaps what the firmware marked.
//!
//! # The trusted key
//! [`TRUST`]: a build with `ECS_UPDATE_PUBLIC_KEY` (64 hex digits) trusts that key
//! ("production"). Without it, a debug build trusts the repository's development key
//! (`keys/`, its secret half is public); a **release** build trusts no key and refuses
//! every update file (FoE "access denied"), unless the development key is asked for
//! explicitly: the cargo feature `dev-key` or `ECS_UPDATE_ALLOW_DEV_KEY=1` at build
//! time. The same holds when `ECS_UPDATE_PUBLIC_KEY` is the development key itself.
//!
//! # The information file
//! Reading [`INFO_FILE`] over FoE returns a few `key=value` lines about the running
//! image: vendor and product, ESC, version, build (the first 8 bytes of its image
//! signature, in hex: unique to the signed image), image length, whether its header
//! carries a valid signature of [`PUBLIC_KEY`] (an image flashed by probe-rs has no
//! header: its version is then the build's own, `build=none`, `signature=none`), the
//! security version the drive accepts at least, the key it trusts (`key=development`,
//! `production` or `none`, and `key-fingerprint=`, the first 8 bytes of the SHA-512 of
//! the public key in hex), and the boot state, so a tool can check an update.

use crate::flash_layout;
use ecat_slave_stack::foe::{ErrorCode, FoeFiles, WriteStatus};
use efw::{Esc, Expected, Header, ImageError, HEADER_LEN};

mod info;
mod trust;
mod updater;

pub use info::format_version;
pub use trust::{trust, Trust, DEV_PUBLIC_KEY_HEX, PUBLIC_KEY, TRUST};
pub use updater::{BootState, EmbassyUpdater, Updater, UpdaterError};

/// File name read over FoE for the running image's information.
pub const INFO_FILE: &[u8] = b"firmware.info";
/// Image bytes collected before a write to the DFU partition (a multiple of the
/// STM32G4's 8-byte write unit).
pub const WRITE_CHUNK: usize = 256;
/// Image bytes hashed per FoE BUSY answer while the image is checked (≈ 6 ms of
/// SHA-512 at 170 MHz).
pub const VERIFY_STEP: u32 = 4096;

/// What happened, for the diagnosis history (the drive turns it into a 0x10F3
/// message).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    /// An image was received, verified and marked: it starts after Bootstrap → Init.
    Accepted {
        /// Its version.
        version: u32,
    },
    /// An image was refused with this FoE error; the running image is untouched.
    Refused(ErrorCode),
    /// This start: a new image on trial confirmed itself.
    Confirmed {
        /// Its version.
        version: u32,
    },
    /// This start: the bootloader had reverted an unconfirmed image.
    Reverted,
}

/// The running image, from its header page.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Running {
    /// The header, when the page holds one signed with the trusted key for this product
    /// (`None`: an image flashed without an update file, e.g. by probe-rs).
    pub header: Option<Header>,
    /// Boot state at start-up.
    pub boot: BootState,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Rx {
    Idle,
    /// Receiving: `head_len` header bytes so far, then the image.
    Receiving,
    /// A refused or failed transfer: everything until the next request is refused.
    Failed(ErrorCode),
}

/// The step of the image check that the next BUSY answer runs
/// ([`Update::verify_step`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Check {
    /// The last, short chunk to the DFU partition.
    Flush,
    /// The header page: erased (one step), then the header written.
    Header,
    /// SHA-512 of the image, this many bytes done.
    Hash(u32),
    /// The image signature over the digest.
    Signature([u8; 64]),
    /// Checked: [`FoeFiles::finish_write`] marks it for the swap.
    Done,
}

/// The check of a complete image, run while the DATA that completed it is answered
/// BUSY (that DATA: `offset`, `len`; its repeats only carry the check on).
#[derive(Clone)]
struct Verifying {
    offset: u32,
    len: usize,
    check: Check,
    digest: efw::ImageDigest,
}

/// The drive's FoE files and update state over an [`Updater`].
pub struct Update<U> {
    updater: U,
    trust: Trust,
    expected: Expected,
    running: Running,
    confirmed: bool,
    rx: Rx,
    head: [u8; HEADER_LEN],
    head_len: usize,
    header: Option<Header>,
    /// Image bytes received.
    received: u32,
    chunk: [u8; WRITE_CHUNK],
    chunk_len: usize,
    /// Image bytes written to the DFU partition.
    written: u32,
    /// The DFU partition is erased (in this transfer) up to here.
    erased_end: u32,
    /// The header page is erased (in this transfer).
    header_page_erased: bool,
    /// The header bytes that passed their checks (kept while the DATA that completes
    /// them is answered BUSY: a resend with other bytes is checked again).
    header_ok: Option<[u8; HEADER_LEN]>,
    verifying: Option<Verifying>,
    accepted: Option<Header>,
    event: Option<Event>,
    info: [u8; INFO_LEN],
    info_len: usize,
}

const INFO_LEN: usize = 320;

/// The update as the drive holds it (object-safe: the drive keeps a
/// `&'static mut dyn FirmwareUpdate`, whatever flash is behind it).
pub trait FirmwareUpdate: FoeFiles {
    /// An image was received and marked in this Bootstrap.
    fn accepted(&self) -> bool;
    /// Boot state now.
    fn boot_state(&self) -> BootState;
    /// The running image's version from its header.
    fn running_version(&self) -> Option<u32>;
    /// [`Update::confirm`].
    fn confirm(&mut self, checks_passed: bool, runtime_up: bool) -> bool;
    /// The last event, once.
    fn take_event(&mut self) -> Option<Event>;
}

impl<U: Updater> FirmwareUpdate for Update<U> {
    fn accepted(&self) -> bool {
        self.accepted.is_some()
    }
    fn boot_state(&self) -> BootState {
        Update::boot_state(self)
    }
    fn running_version(&self) -> Option<u32> {
        Update::running_version(self)
    }
    fn confirm(&mut self, checks_passed: bool, runtime_up: bool) -> bool {
        Update::confirm(self, checks_passed, runtime_up)
    }
    fn take_event(&mut self) -> Option<Event> {
        Update::take_event(self)
    }
}

/// FoE answer of a refused image.
pub const fn foe_error(e: ImageError) -> ErrorCode {
    match e {
        ImageError::WrongProduct | ImageError::WrongEsc | ImageError::BadMagic => {
            ErrorCode::FirmwareNotForHardware
        }
        ImageError::UnknownFormat => ErrorCode::FirmwareNotForHardware,
        ImageError::BadHeaderSignature | ImageError::BadImageSignature => {
            ErrorCode::InvalidChecksum
        }
        ImageError::TooLong => ErrorCode::DiskFull,
        ImageError::Truncated => ErrorCode::ProgramError,
        ImageError::Rollback => ErrorCode::AccessDenied,
    }
}

impl<U: Updater> Update<U> {
    /// The update of a drive with this identity (`vendor_id`, `product_code`, `esc`)
    /// over `updater`, trusting the build's key ([`TRUST`]); reads the running
    /// image's header and the boot state. An image the bootloader reverted to
    /// confirms itself at once (it ran before).
    pub fn new(updater: U, vendor_id: u32, product_code: u32, esc: Esc) -> Self {
        Self::with_trust(updater, vendor_id, product_code, esc, TRUST)
    }

    /// [`Update::new`] trusting `trust` (tests, tools).
    pub fn with_trust(
        mut updater: U,
        vendor_id: u32,
        product_code: u32,
        esc: Esc,
        trust: Trust,
    ) -> Self {
        let mut expected = Expected {
            vendor_id,
            product_code,
            esc,
            capacity: flash_layout::IMAGE_MAX.min(updater.capacity()),
            public_key: trust.key().unwrap_or([0; 32]),
            min_security_version: 0,
        };
        let mut page = [0xFFu8; HEADER_LEN];
        let header = match (trust.key(), updater.read_running_header(&mut page)) {
            (Some(_), Ok(())) => efw::check_header(&page, &expected).ok(),
            _ => None,
        };
        // Anti-rollback: never below the running image (see the module docs).
        expected.min_security_version = header.map_or(0, |h| h.security_version);
        let boot = updater.boot_state().unwrap_or(BootState::Confirmed);
        let mut u = Update {
            updater,
            trust,
            expected,
            running: Running { header, boot },
            confirmed: boot == BootState::Confirmed,
            rx: Rx::Idle,
            head: [0; HEADER_LEN],
            head_len: 0,
            header: None,
            received: 0,
            chunk: [0xFF; WRITE_CHUNK],
            chunk_len: 0,
            written: 0,
            erased_end: 0,
            header_page_erased: false,
            header_ok: None,
            verifying: None,
            accepted: None,
            event: None,
            info: [0; INFO_LEN],
            info_len: 0,
        };
        if boot == BootState::Reverted && u.updater.mark_booted().is_ok() {
            u.confirmed = true;
            u.event = Some(Event::Reverted);
        }
        u
    }

    /// The running image.
    pub fn running(&self) -> &Running {
        &self.running
    }

    /// The version to report in 0x100A: the running image's header, if it has one.
    pub fn running_version(&self) -> Option<u32> {
        self.running.header.map(|h| h.version)
    }

    /// Boot state now (a trial image is [`BootState::Confirmed`] once confirmed).
    pub fn boot_state(&self) -> BootState {
        if self.confirmed {
            if self.running.boot == BootState::Reverted {
                BootState::Reverted
            } else {
                BootState::Confirmed
            }
        } else {
            self.running.boot
        }
    }

    /// Confirms a trial image (`mark_booted`) once `checks_passed` (the start-up
    /// checks) and `runtime_up` (the EtherCAT runtime reached Pre-Op); does nothing
    /// otherwise or when there is nothing to confirm. Returns true when it confirmed.
    pub fn confirm(&mut self, checks_passed: bool, runtime_up: bool) -> bool {
        if self.confirmed || !checks_passed || !runtime_up {
            return false;
        }
        if self.updater.mark_booted().is_err() {
            return false;
        }
        self.confirmed = true;
        self.event = Some(Event::Confirmed {
            version: self.running_version().unwrap_or(0),
        });
        true
    }

    /// The header of an image received and marked in this Bootstrap (the drive
    /// resets into the bootloader on Bootstrap → Init).
    pub fn accepted(&self) -> Option<&Header> {
        self.accepted.as_ref()
    }

    /// The last event, once.
    pub fn take_event(&mut self) -> Option<Event> {
        self.event.take()
    }

    fn fail(&mut self, code: ErrorCode) -> ErrorCode {
        self.rx = Rx::Failed(code);
        self.event = Some(Event::Refused(code));
        code
    }

    /// Erases the DFU partition up to `end` (whole pages).
    fn erase_to(&mut self, end: u32) -> Result<(), UpdaterError> {
        while self.erased_end < end {
            self.updater.erase_page(self.erased_end)?;
            self.erased_end += flash_layout::PAGE;
        }
        Ok(())
    }

    /// The page this DATA of `n` bytes needs erased before it is taken, if any: the
    /// header page once the header is known good, then the pages the chunks it
    /// completes go to.
    fn page_to_erase(&self, n: usize) -> Option<u32> {
        let header_part = if self.header.is_some() {
            0
        } else {
            HEADER_LEN - self.head_len
        };
        if n < header_part {
            // The header is not complete yet: nothing to write.
            return None;
        }
        if !self.header_page_erased {
            return Some(flash_layout::HEADER_OFFSET);
        }
        let image_part = n - header_part;
        let full = (self.chunk_len + image_part) / WRITE_CHUNK * WRITE_CHUNK;
        let end = self.written + full as u32;
        (end > self.erased_end).then_some(self.erased_end)
    }

    /// Writes the collected chunk (padded with erased bytes to the write unit) into
    /// erased flash.
    fn flush(&mut self) -> Result<(), UpdaterError> {
        if self.chunk_len == 0 {
            return Ok(());
        }
        let n = self.chunk_len.next_multiple_of(8);
        self.chunk[self.chunk_len..n].fill(0xFF);
        self.erase_to(self.written + n as u32)?;
        let r = self.updater.write(self.written, &self.chunk[..n]);
        self.written += self.chunk_len as u32;
        self.chunk_len = 0;
        self.chunk.fill(0xFF);
        r
    }

    fn take_image_bytes(&mut self, mut data: &[u8]) -> Result<(), ErrorCode> {
        let Some(h) = self.header else {
            return Err(ErrorCode::ProgramError);
        };
        if u64::from(self.received) + data.len() as u64 > u64::from(h.image_len) {
            return Err(ErrorCode::DiskFull);
        }
        self.received += data.len() as u32;
        while !data.is_empty() {
            let n = (WRITE_CHUNK - self.chunk_len).min(data.len());
            self.chunk[self.chunk_len..self.chunk_len + n].copy_from_slice(&data[..n]);
            self.chunk_len += n;
            data = &data[n..];
            if self.chunk_len == WRITE_CHUNK {
                self.flush().map_err(|_| ErrorCode::ProgramError)?;
            }
        }
        Ok(())
    }

    fn take(&mut self, mut data: &[u8]) -> Result<(), ErrorCode> {
        if self.header.is_none() {
            let n = (HEADER_LEN - self.head_len).min(data.len());
            self.head[self.head_len..self.head_len + n].copy_from_slice(&data[..n]);
            self.head_len += n;
            data = &data[n..];
            if self.head_len < HEADER_LEN {
                return Ok(());
            }
            // Checked when this DATA arrived (`check_completed_header`): these very
            // bytes, or nothing is taken.
            if self.header_ok != Some(self.head) {
                return Err(ErrorCode::InvalidChecksum);
            }
            let h = Header::parse(&efw::Frame::new_unchecked(&self.head[..])).map_err(foe_error)?;
            self.header = Some(h);
        }
        self.take_image_bytes(data)
    }

    /// The lowest security version this drive accepts (the running image's).
    pub fn min_security_version(&self) -> u32 {
        self.expected.min_security_version
    }

    /// One bounded step of the check of a complete image (see the module docs):
    /// at most one page erase plus one chunk write, [`VERIFY_STEP`] bytes read and
    /// hashed, or one ed25519 check. `Busy` until the last step, which answers `Done`.
    fn verify_step(&mut self) -> WriteStatus {
        let Some(v) = self.verifying.as_mut() else {
            return WriteStatus::Err(ErrorCode::Illegal);
        };
        let Some(h) = self.header else {
            return WriteStatus::Err(ErrorCode::ProgramError);
        };
        let check = v.check;
        let next = match check {
            Check::Flush => self.flush().map(|()| Check::Header).map_err(flash_code),
            Check::Header if !self.header_page_erased => self
                .updater
                .erase_page(flash_layout::HEADER_OFFSET)
                .map(|()| {
                    self.header_page_erased = true;
                    Check::Header
                })
                .map_err(flash_code),
            Check::Header => self
                .updater
                .write(flash_layout::HEADER_OFFSET, &self.head)
                .map(|()| Check::Hash(0))
                .map_err(flash_code),
            Check::Hash(at) => self.hash_step(at, h.image_len),
            Check::Signature(d) => efw::verify_digest(&h, &d, &self.expected.public_key)
                .map(|()| Check::Done)
                .map_err(foe_error),
            Check::Done => Ok(Check::Done),
        };
        match next {
            Ok(c) => {
                if let Some(v) = self.verifying.as_mut() {
                    v.check = c;
                }
                if c == Check::Done {
                    WriteStatus::Done
                } else {
                    WriteStatus::Busy {
                        done_percent: self.done_percent(),
                    }
                }
            }
            Err(code) => {
                self.verifying = None;
                WriteStatus::Err(self.fail(code))
            }
        }
    }

    /// Hashes the image from `at`, [`VERIFY_STEP`] bytes at most, read through the
    /// write chunk (free once the last chunk is written).
    fn hash_step(&mut self, at: u32, len: u32) -> Result<Check, ErrorCode> {
        let end = at.saturating_add(VERIFY_STEP).min(len);
        let mut pos = at;
        while pos < end {
            let n = ((end - pos) as usize).min(WRITE_CHUNK);
            let buf = &mut self.chunk[..n];
            self.updater.read(pos, buf).map_err(flash_code)?;
            if let Some(v) = self.verifying.as_mut() {
                v.digest.update(buf);
            }
            pos += n as u32;
        }
        self.chunk.fill(0xFF);
        if pos < len {
            return Ok(Check::Hash(pos));
        }
        let digest = self
            .verifying
            .as_ref()
            .map(|v| v.digest.clone().finish())
            .ok_or(ErrorCode::ProgramError)?;
        Ok(Check::Signature(digest))
    }

    /// The end of a transfer: the image, checked by the DATA that completed it, is
    /// marked for the swap (embassy-boot's `mark_updated`: one state-page erase and
    /// a write). Only a finished transfer marks: one aborted after its check leaves
    /// the running image as it was.
    fn finish(&mut self) -> Result<Header, ErrorCode> {
        let h = self.header.ok_or(ErrorCode::ProgramError)?;
        match self.verifying.take() {
            Some(v) if v.check == Check::Done => {}
            _ => return Err(ErrorCode::ProgramError),
        }
        self.updater.mark_updated().map_err(|e| match e {
            UpdaterError::NotConfirmed => ErrorCode::AccessDenied,
            UpdaterError::Signature => ErrorCode::InvalidChecksum,
            UpdaterError::Flash => ErrorCode::ProgramError,
        })?;
        Ok(h)
    }

    fn reset_transfer(&mut self) {
        self.rx = Rx::Idle;
        self.head_len = 0;
        self.header = None;
        self.received = 0;
        self.chunk_len = 0;
        self.written = 0;
        self.erased_end = 0;
        self.header_page_erased = false;
        self.header_ok = None;
        self.verifying = None;
    }

    /// Checks the header before anything is erased, when this DATA completes it. The
    /// same DATA comes again after BUSY: the check is not repeated for the same bytes,
    /// but other bytes are checked again.
    fn check_completed_header(&mut self, data: &[u8]) -> Result<(), ErrorCode> {
        if self.header.is_some() || self.head_len + data.len() < HEADER_LEN {
            return Ok(());
        }
        let mut h = self.head;
        h[self.head_len..].copy_from_slice(&data[..HEADER_LEN - self.head_len]);
        if self.header_ok == Some(h) {
            return Ok(());
        }
        self.header_ok = None;
        efw::check_header(&h, &self.expected).map_err(foe_error)?;
        self.header_ok = Some(h);
        Ok(())
    }

    fn done_percent(&self) -> u8 {
        match self.header {
            Some(h) if h.image_len > 0 => {
                (u64::from(self.received) * 100 / u64::from(h.image_len)).min(100) as u8
            }
            _ => 0,
        }
    }
}

/// The FoE answer of a failed flash step of the check.
fn flash_code(_: UpdaterError) -> ErrorCode {
    ErrorCode::ProgramError
}

/// `name` ends in `.efw` (any case, after any path).
fn is_update_file(name: &[u8]) -> bool {
    name.len() > 4 && name[name.len() - 4..].eq_ignore_ascii_case(b".efw")
}

impl<U: Updater> FoeFiles for Update<U> {
    fn open_write(&mut self, name: &[u8], password: u32, in_boot: bool) -> Result<(), ErrorCode> {
        self.reset_transfer();
        if !is_update_file(name) {
            return Err(ErrorCode::NotFound);
        }
        if password != 0 {
            return Err(ErrorCode::NoRights);
        }
        if !in_boot {
            return Err(ErrorCode::BootstrapOnly);
        }
        if self.trust.key().is_none() {
            // A release build given no key (module docs, "The trusted key").
            return Err(self.fail(ErrorCode::AccessDenied));
        }
        if !self.confirmed {
            return Err(self.fail(ErrorCode::AccessDenied));
        }
        if self.accepted.is_some() {
            // An image is marked for the swap: a second download in this Bootstrap
            // would rewrite the DFU partition under it. Leave Bootstrap first.
            return Err(self.fail(ErrorCode::AccessDenied));
        }
        self.rx = Rx::Receiving;
        Ok(())
    }

    fn write(&mut self, offset: u32, data: &[u8]) -> WriteStatus {
        match self.rx {
            Rx::Receiving => {}
            Rx::Failed(code) => return WriteStatus::Err(code),
            Rx::Idle => return WriteStatus::Err(ErrorCode::Illegal),
        }
        if let Some(v) = &self.verifying {
            // The repeats of the DATA that completed the image carry its check on.
            if offset != v.offset || data.len() != v.len {
                self.verifying = None;
                return WriteStatus::Err(self.fail(ErrorCode::Illegal));
            }
            return self.verify_step();
        }
        if let Err(code) = self.check_completed_header(data) {
            return WriteStatus::Err(self.fail(code));
        }
        if let Some(page) = self.page_to_erase(data.len()) {
            // One page erase per call; the server asks again with the same data.
            return match self.updater.erase_page(page) {
                Ok(()) => {
                    if page == flash_layout::HEADER_OFFSET {
                        self.header_page_erased = true;
                    } else {
                        self.erased_end += flash_layout::PAGE;
                    }
                    WriteStatus::Busy {
                        done_percent: self.done_percent(),
                    }
                }
                Err(_) => WriteStatus::Err(self.fail(ErrorCode::ProgramError)),
            };
        }
        if let Err(code) = self.take(data) {
            return WriteStatus::Err(self.fail(code));
        }
        match self.header {
            Some(h) if self.received == h.image_len => {
                // The image is complete: its check starts, in steps (BUSY meanwhile).
                self.verifying = Some(Verifying {
                    offset,
                    len: data.len(),
                    check: Check::Flush,
                    digest: efw::ImageDigest::new(),
                });
                WriteStatus::Busy {
                    done_percent: self.done_percent(),
                }
            }
            _ => WriteStatus::Done,
        }
    }

    fn finish_write(&mut self) -> Result<(), ErrorCode> {
        if self.rx != Rx::Receiving {
            return Err(ErrorCode::Illegal);
        }
        let r = self.finish();
        self.reset_transfer();
        match r {
            Ok(h) => {
                self.accepted = Some(h);
                self.event = Some(Event::Accepted { version: h.version });
                Ok(())
            }
            Err(code) => Err(self.fail(code)),
        }
    }

    fn open_read(&mut self, name: &[u8], password: u32, _in_boot: bool) -> Result<u32, ErrorCode> {
        if name != INFO_FILE {
            return Err(ErrorCode::NotFound);
        }
        if password != 0 {
            return Err(ErrorCode::NoRights);
        }
        self.info_len = self.build_info();
        Ok(self.info_len as u32)
    }

    fn read(&mut self, offset: u32, buf: &mut [u8]) -> usize {
        let rest = self.info.get(offset as usize..self.info_len).unwrap_or(&[]);
        let n = rest.len().min(buf.len());
        buf[..n].copy_from_slice(&rest[..n]);
        n
    }

    fn abort(&mut self) {
        if self.rx == Rx::Receiving {
            self.event = Some(Event::Refused(ErrorCode::NotDefined));
        }
        self.reset_transfer();
    }
}

#[cfg(test)]
mod tests;
