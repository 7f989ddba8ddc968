//! A firmware update survives a power cut at any instant: embassy-boot 0.7 (the blocking
//! `BootLoader` and `BlockingFirmwareUpdater`, as the drive's bootloader and FoE update
//! use them) over a RAM flash that loses power after N byte operations, for every N.
//!
//! # The flash
//!
//! [`CutFlash`] behaves like the STM32G474RE's flash in dual-bank mode: 2 KiB erase
//! pages, 8-byte (double-word) programming, erased bytes read 0xFF, and a double word
//! that is not erased can only be programmed with zeros (RM0440, FLASH_SR.PROGERR: "a
//! double word to be programmed contains a value different from 0xFFFF_FFFF, except
//! if the data to write is 0x0000_0000"). Each erased or programmed byte is one
//! operation; when power is cut after N of them the erase or write in progress stops
//! there (a page partly erased from its start, a double word partly programmed) and
//! every later access fails until [`CutFlash::power_on`]. The firmware crate's
//! `storage::RamFlash` has the same cut model but does not fit here: its 32-byte erase
//! unit would become embassy-boot's swap page (the page is the largest erase size of
//! the partitions), and it refuses the zero overwrite that embassy-boot needs (see
//! "Findings").
//!
//! # The partitions
//!
//! Smaller than the real ones (`firmware::flash_layout`) to keep the cut loops short,
//! with the real page and write sizes: boot state 2 pages (4 KiB, as on the board),
//! active 8 pages (16 KiB), DFU 9 pages (one more, as embassy-boot's swap needs), in
//! that order in one flash shared through `Mutex<NoopRawMutex, RefCell<_>>`.
//! [`real_layout_update_and_revert`] runs the same update once, without cuts, on the
//! real layout. The bootloader's buffer is one page (2 KiB).
//!
//! Images: A (old, running, confirmed) is 15 000 bytes, B (new) 16 284 bytes, distinct
//! pseudo-random bytes in every page; the rest of the active partition is erased. B
//! reaches into the last page of the partition, so its transfer rewrites every DFU
//! page the swap moves and the DFU's stale contents (a third pattern) never show.
//! B travels as a `.efw` file signed by `efw::sign::update_file` (as `cargo xtask
//! update-image` signs): FoE pieces of 116 bytes, the 160-byte header checked with
//! `efw::check_header`, the image staged into 8-byte multiples for `write_firmware`
//! (the last one padded with 0xFF), then `verify_and_mark_updated` with the header's
//! image signature and length.
//!
//! # Cut points
//!
//! Each case first runs its operation without a cut and logs its erases and writes,
//! then runs it again from the same flash contents with power cut after N = 0, 1, 2, …
//! byte operations, until the run where it completes (N = its byte count), powers on
//! and checks what the next boot does. Every byte is a cut point, so every operation
//! boundary is one too. A failure names the cut point (the operation and the byte in
//! it) and the first page of the active partition that differs. Cut points per case
//! (debug build, about 1-2 s each):
//!
//! | case | operation cut | cut points |
//! |---|---|---|
//! | 1 | receive + `verify_and_mark_updated` | 36 784 |
//! | 2 | `prepare_boot` swapping | 65 664, and 8 982 second cuts |
//! | 3 | `prepare_boot` reverting | 69 776, and 10 056 second cuts |
//! | 4 | `mark_booted` | 4 112 |
//!
//! Second cuts (cases 2, 3): after a first cut at every operation boundary and at
//! every [`SECOND_CUT_STRIDE`]th byte, the recovering boot is cut too, before each of
//! its operations and at its middle byte.
//!
//! # Findings (embassy-boot 0.7.0, this cut model)
//!
//! - No cut point leaves a mixed ACTIVE once `prepare_boot` returns `Ok`: a cut
//!   transfer boots A; a cut swap ends with B at the next boot; a cut revert with A.
//! - `prepare_boot` returns the state it *found*: the boot that reverts returns
//!   `State::Swap` like the boot that swaps; only `get_state` afterwards tells
//!   `Revert`. After a cut in the last step of a revert (the state erase or the
//!   REVERT_MAGIC write) the state is `Boot`, not `Revert`; the image is A either way.
//! - A cut in `mark_booted` before its state erase has begun (its first step writes
//!   the "progress invalid" word) leaves SWAP_MAGIC with invalid progress. The next
//!   boot takes that for "swapped, not confirmed", runs the revert, whose every page
//!   copy is skipped because invalid progress reads as "all done", and writes
//!   REVERT_MAGIC: the drive runs B, confirmed by the application, but `get_state`
//!   says `Revert`. The images are never mixed.
//! - That boot rewrites the "progress invalid" word that the cut `mark_booted` had
//!   already (partly) programmed, and a swap or revert step cut inside its progress
//!   word write rewrites that word: both only work because the STM32G4 lets a
//!   programmed double word be programmed again with zeros. On a flash that refuses
//!   it, such a cut leaves `prepare_boot` failing at every boot
//!   ([`a_flash_without_zero_overwrite_would_not_boot`]).
//! - The safety of a cut state erase rests on the magic word reading "not SWAP" as
//!   soon as the progress words read erased
//!   ([`a_state_erase_sparing_only_the_magic_would_mix_the_images`]).
//! - `verify_and_mark_updated` panics (an `assert!`, not an `Err`) when the length is
//!   larger than the DFU partition; the drive must bound it first. An image longer
//!   than the *active* partition is accepted, and the swap installs only the active
//!   partition's size of it.
//!
//! - ECC (issue 33): [`CutFlash`] can model the STM32G4's ECC on torn double words
//!   (a cut inside a double word's programming or erase leaves it failing every read,
//!   the chip's double ECC error, which the bootloader turns into a failed read:
//!   `bootloader/src/main.rs`, `NonMaskableInt`). With it, a cut inside one of
//!   embassy-boot's state words (a progress word, the "progress invalid" word, a
//!   magic) makes every later `prepare_boot` fail: the bootloader stops (bridges
//!   off, never configured there) until the state page is erased by a probe
//!   ([`a_torn_state_word_stops_the_bootloader`]). The drive's bootloader therefore
//!   reads a torn state word as erased and erases a state page it found torn
//!   (`firmware::boot_state`): a cut inside any state write or erase of a swap, a
//!   revert, the confirmation or the marking of an update boots a whole image, and
//!   the state is readable afterwards ([`a_torn_state_word_boots_a_whole_image`]).
//!   Cases 1-5 run without the ECC model; whether a real torn double word fails its
//!   ECC is for a board to show.

use std::cell::RefCell;
use std::collections::HashSet;
use std::fmt;

use efw::{Esc, Expected, Header, HEADER_LEN};
use embassy_boot::{
    AlignedBuffer, BlockingFirmwareState, BlockingFirmwareUpdater, BootError, BootLoader,
    BootLoaderConfig, FirmwareUpdaterConfig, FirmwareUpdaterError, State,
};
use embassy_embedded_hal::flash::partition::BlockingPartition;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash};
use firmware::flash_layout::{self, Partition, PAGE};
use firmware::identity::{Variant, VENDOR_ID};
use firmware::storage::{erase_range, read_range};

/// Erase page, bytes.
const PAGE_SIZE: usize = PAGE as usize;
/// Programming unit (a double word).
const WRITE_SIZE: usize = 8;
/// The bootloader's copy buffer.
const BOOT_BUF: usize = PAGE_SIZE;
/// FoE data bytes per piece.
const FOE_PIECE: usize = 116;
/// First cut points with second cuts: every operation boundary and every this many
/// bytes (a prime: the points fall at every position within pages and double words).
const SECOND_CUT_STRIDE: usize = 509;
/// Signing key of the test images.
const SEED: [u8; 32] = [0x5A; 32];
/// Some other key.
const OTHER_SEED: [u8; 32] = [0xA5; 32];

/// Where the partitions are in the flash.
#[derive(Clone, Copy)]
struct Geometry {
    state: Partition,
    active: Partition,
    dfu: Partition,
    flash: usize,
}

/// The layout of these tests: the real page size, fewer pages.
const SMALL: Geometry = Geometry {
    state: Partition {
        offset: 0,
        size: 2 * PAGE,
    },
    active: Partition {
        offset: 2 * PAGE,
        size: 8 * PAGE,
    },
    dfu: Partition {
        offset: 10 * PAGE,
        size: 9 * PAGE,
    },
    flash: 19 * PAGE_SIZE,
};

/// The board's layout (`firmware::flash_layout`).
const REAL: Geometry = Geometry {
    state: flash_layout::BOOT_STATE,
    active: flash_layout::ACTIVE,
    dfu: flash_layout::DFU,
    flash: flash_layout::FLASH_SIZE as usize,
};

/// An erased page.
const ERASED: [u8; PAGE_SIZE] = [0xFF; PAGE_SIZE];

/// One erase or write, as logged by a run without a cut.
#[derive(Debug, Clone, Copy)]
struct Op {
    erase: bool,
    addr: u32,
    len: usize,
    /// Byte operations before it since power-on.
    first: usize,
}

/// The STM32G4-like RAM flash with a power cut (module doc).
struct CutFlash {
    mem: Vec<u8>,
    /// Byte operations left before power is lost (`None`: no cut scheduled).
    budget: Option<usize>,
    dead: bool,
    /// Byte operations since power-on.
    ops: usize,
    /// Erases and writes since power-on, when logging.
    log: Option<Vec<Op>>,
    /// A programmed double word may be programmed again with zeros (STM32G4).
    zero_overwrite: bool,
    /// Torn double words (offsets): a cut left them partly programmed or partly
    /// erased, their ECC is wrong and every read that touches them fails (the
    /// STM32G4's double ECC error), until an erase or a completed programming.
    torn: Vec<u32>,
    /// Model the ECC of torn double words (off in cases 1-5, which check embassy-boot's
    /// swap logic: see "Findings" and [`a_torn_state_word_stops_the_bootloader`]).
    ecc: bool,
}

/// The state of a [`CutFlash`]: contents and torn double words.
type Snapshot = (Vec<u8>, Vec<u32>);

impl CutFlash {
    fn new(size: usize) -> Self {
        CutFlash {
            mem: vec![0xFF; size],
            budget: None,
            dead: false,
            ops: 0,
            log: None,
            zero_overwrite: true,
            torn: Vec::new(),
            ecc: false,
        }
    }

    /// An operation from `addr` was cut after `done` bytes: the double word it
    /// stopped in is torn (unless it stopped on a double-word boundary).
    fn tear(&mut self, addr: u32, done: usize) {
        let at = addr as usize + done;
        if self.ecc && !at.is_multiple_of(WRITE_SIZE) {
            let w = (at - at % WRITE_SIZE) as u32;
            if !self.torn.contains(&w) {
                self.torn.push(w);
                self.torn.sort_unstable();
            }
        }
    }

    /// The double words in `from..to` were erased or programmed completely.
    fn mend(&mut self, from: usize, to: usize) {
        self.torn.retain(|&w| !(from..to).contains(&(w as usize)));
    }

    /// Power is lost after `n` more byte operations.
    fn cut_power_after(&mut self, n: usize) {
        self.budget = Some(n);
    }

    /// Power back, no cut scheduled.
    fn power_on(&mut self) {
        self.budget = None;
        self.dead = false;
        self.ops = 0;
    }

    /// Starts an operation of `len` bytes: how many of them happen before power is lost.
    fn start(&mut self, erase: bool, addr: u32, len: usize) -> usize {
        if let Some(log) = &mut self.log {
            log.push(Op {
                erase,
                addr,
                len,
                first: self.ops,
            });
        }
        let done = self.budget.map_or(len, |b| b.min(len));
        if let Some(b) = &mut self.budget {
            *b -= done;
        }
        self.ops += done;
        if done < len {
            self.dead = true;
        }
        done
    }

    fn alive(&self) -> Result<(), NorFlashErrorKind> {
        if self.dead {
            Err(NorFlashErrorKind::Other)
        } else {
            Ok(())
        }
    }
}

impl ErrorType for CutFlash {
    type Error = NorFlashErrorKind;
}

impl ReadNorFlash for CutFlash {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.alive()?;
        let r = read_range(self.mem.len(), offset, bytes.len())?;
        let first = r.start - r.start % WRITE_SIZE;
        if self
            .torn
            .iter()
            .any(|&w| (first..r.end).contains(&(w as usize)))
        {
            // The double ECC error (an NMI on the chip, a failed read for the
            // bootloader and the firmware).
            return Err(NorFlashErrorKind::Other);
        }
        bytes.copy_from_slice(&self.mem[r]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.mem.len()
    }
}

impl NorFlash for CutFlash {
    const WRITE_SIZE: usize = WRITE_SIZE;
    const ERASE_SIZE: usize = PAGE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.alive()?;
        let r = erase_range(self.mem.len(), PAGE_SIZE, from, to)?;
        let done = self.start(true, from, r.len());
        self.mem[r.start..r.start + done].fill(0xFF);
        self.mend(r.start, r.start + done - done % WRITE_SIZE);
        if done < r.len() {
            self.tear(from, done);
            return Err(NorFlashErrorKind::Other);
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.alive()?;
        if !(offset as usize).is_multiple_of(WRITE_SIZE) || !bytes.len().is_multiple_of(WRITE_SIZE)
        {
            return Err(NorFlashErrorKind::NotAligned);
        }
        let r = read_range(self.mem.len(), offset, bytes.len())?;
        // Slice comparisons and copies (memcmp, memcpy): the cut loops run this a
        // few million times in a debug build.
        let erased = self.mem[r.clone()]
            .chunks(PAGE_SIZE)
            .all(|c| c == &ERASED[..c.len()]);
        if !erased {
            // PROGERR: the whole write is refused before anything is programmed.
            for (old, new) in self.mem[r.clone()]
                .chunks_exact(WRITE_SIZE)
                .zip(bytes.chunks_exact(WRITE_SIZE))
            {
                let erased = old == &ERASED[..WRITE_SIZE];
                let zeros = self.zero_overwrite && new == &[0u8; WRITE_SIZE][..];
                if !erased && !zeros {
                    return Err(NorFlashErrorKind::Other);
                }
            }
        }
        let done = self.start(false, offset, bytes.len());
        let target = &mut self.mem[r.start..r.start + done];
        if erased {
            target.copy_from_slice(&bytes[..done]);
        } else {
            // Programming only clears bits: exact for erased bytes and for zeros.
            for (m, &b) in target.iter_mut().zip(bytes) {
                *m &= b;
            }
        }
        self.mend(r.start, r.start + done - done % WRITE_SIZE);
        if done < bytes.len() {
            self.tear(offset, done);
            return Err(NorFlashErrorKind::Other);
        }
        Ok(())
    }
}

type Part<'a> = BlockingPartition<'a, NoopRawMutex, CutFlash>;

/// The flash and its partitions.
struct Rig {
    g: Geometry,
    flash: Mutex<NoopRawMutex, RefCell<CutFlash>>,
}

impl Rig {
    fn new(g: Geometry) -> Self {
        Rig {
            g,
            flash: Mutex::new(RefCell::new(CutFlash::new(g.flash))),
        }
    }

    fn with<R>(&self, f: impl FnOnce(&mut CutFlash) -> R) -> R {
        self.flash.lock(|c| f(&mut c.borrow_mut()))
    }

    fn part(&self, p: Partition) -> Part<'_> {
        BlockingPartition::new(&self.flash, p.offset, p.size)
    }

    /// What the bootloader does at reset.
    fn prepare_boot(&self) -> Result<State, BootError> {
        let mut boot = BootLoader::new(BootLoaderConfig {
            active: self.part(self.g.active),
            dfu: self.part(self.g.dfu),
            state: self.part(self.g.state),
        });
        let mut buf = AlignedBuffer([0u8; BOOT_BUF]);
        boot.prepare_boot(&mut buf.0)
    }

    /// What the drive's bootloader does at reset: the same call
    /// (`firmware::boot_state::prepare_boot`, torn state words read as erased).
    fn bootloader(&self) -> Result<State, BootError> {
        let mut buf = AlignedBuffer([0u8; BOOT_BUF]);
        firmware::boot_state::prepare_boot(
            self.part(self.g.active),
            self.part(self.g.dfu),
            &mut self.part(self.g.state),
            &mut buf.0,
        )
    }

    /// The state the application reads (`get_state`).
    fn state(&self) -> State {
        let mut aligned = [0u8; WRITE_SIZE];
        BlockingFirmwareState::new(self.part(self.g.state), &mut aligned)
            .get_state()
            .expect("state readable")
    }

    /// The application confirms its boot.
    fn mark_booted(&self) -> Result<(), FirmwareUpdaterError> {
        let mut aligned = [0u8; WRITE_SIZE];
        BlockingFirmwareState::new(self.part(self.g.state), &mut aligned).mark_booted()
    }

    fn read(&self, p: Partition) -> Vec<u8> {
        self.with(|f| f.mem[p.offset as usize..(p.offset + p.size) as usize].to_vec())
    }

    fn snapshot(&self) -> Snapshot {
        self.with(|f| (f.mem.clone(), f.torn.clone()))
    }

    /// Back to the contents of `snapshot`, power on.
    fn restore(&self, snapshot: &Snapshot) {
        self.with(|f| {
            f.mem.copy_from_slice(&snapshot.0);
            f.torn.clone_from(&snapshot.1);
            f.power_on();
        });
    }

    fn power_on(&self) {
        self.with(|f| f.power_on());
    }

    fn power_lost(&self) -> bool {
        self.with(|f| f.dead)
    }

    /// The name of the partition and page at flash offset `addr`.
    fn place(&self, addr: u32) -> String {
        for (name, p) in [
            ("state", self.g.state),
            ("active", self.g.active),
            ("DFU", self.g.dfu),
        ] {
            if in_partition(addr, p) {
                let at = addr - p.offset;
                return format!("{name} page {} +{}", at / PAGE, at % PAGE);
            }
        }
        format!("0x{addr:X}")
    }
}

/// `addr` (a flash offset) is in `p`.
fn in_partition(addr: u32, p: Partition) -> bool {
    (p.offset..p.offset + p.size).contains(&addr)
}

/// A firmware image and what the active partition holds when it is installed.
struct Image {
    name: &'static str,
    bytes: Vec<u8>,
    /// The active partition: the image, then erased bytes.
    partition: Vec<u8>,
}

impl Image {
    fn new(name: &'static str, seed: u32, len: usize, g: &Geometry) -> Self {
        let mut x = seed;
        let bytes: Vec<u8> = (0..len)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                (x >> 11) as u8
            })
            .collect();
        let mut partition = bytes.clone();
        partition.resize(g.active.size as usize, 0xFF);
        Image {
            name,
            bytes,
            partition,
        }
    }

    fn page(&self, i: usize) -> &[u8] {
        &self.partition[i * PAGE_SIZE..(i + 1) * PAGE_SIZE]
    }
}

/// A and B of the small layout.
fn images(g: &Geometry) -> (Image, Image) {
    let a = Image::new("A", 0x1234_5678, 15_000, g);
    let b = Image::new("B", 0x0BAD_F00D, 16_284, g);
    assert!(b.bytes.len() > (g.active.size - PAGE) as usize);
    for i in 0..(g.active.size / PAGE) as usize {
        assert_ne!(a.page(i), b.page(i), "A and B share page {i}");
    }
    (a, b)
}

/// What the drive accepts.
fn expected(g: &Geometry) -> Expected {
    Expected {
        vendor_id: VENDOR_ID,
        product_code: Variant::HybridServo.product_code(),
        esc: Esc::Lan9252,
        capacity: g.active.size,
        public_key: efw::sign::public_key(&SEED),
        min_security_version: 0,
    }
}

/// A `.efw` file and its header.
struct Update {
    file: Vec<u8>,
    header: Header,
}

/// The `.efw` file of `image` signed with `seed`, as `cargo xtask update-image` makes it.
fn signed(seed: &[u8; 32], image: &Image) -> Vec<u8> {
    efw::sign::update_file(
        seed,
        VENDOR_ID,
        Variant::HybridServo.product_code(),
        Esc::Lan9252,
        0x0001_0000,
        &image.bytes,
    )
}

/// The update of `image` for the drive of layout `g`, its header checked as the drive
/// checks it when the header has arrived (once here: it reads no flash, so it adds no
/// cut point, and its signature check would only slow the cut loops down).
fn update(g: &Geometry, image: &Image) -> Update {
    let file = signed(&SEED, image);
    let header = efw::check_header(&file, &expected(g)).expect("header accepted");
    assert_eq!(header.image_len as usize, image.bytes.len());
    Update { file, header }
}

/// The drive as it was flashed and confirmed with `a`; the DFU holds older bytes.
fn install(rig: &Rig, a: &Image) {
    let (active, dfu) = (rig.g.active, rig.g.dfu);
    rig.with(|f| {
        let at = active.offset as usize;
        f.mem[at..at + a.partition.len()].copy_from_slice(&a.partition);
        let stale = Image::new("stale", 0x7777_0001, dfu.size as usize, &rig.g);
        let at = dfu.offset as usize;
        f.mem[at..at + dfu.size as usize].copy_from_slice(&stale.bytes);
    });
    rig.mark_booted().expect("mark_booted");
    assert_eq!(rig.state(), State::Boot);
}

/// The FoE receive of `u`: the file in 116-byte pieces; after the header, the image
/// staged into 8-byte multiples for `write_firmware`, the last one padded with 0xFF.
fn receive(rig: &Rig, u: &Update) -> Result<(), FirmwareUpdaterError> {
    let mut aligned = [0u8; WRITE_SIZE];
    let mut updater = BlockingFirmwareUpdater::new(
        FirmwareUpdaterConfig {
            dfu: rig.part(rig.g.dfu),
            state: rig.part(rig.g.state),
        },
        &mut aligned,
    );
    let mut header_left = HEADER_LEN;
    let mut staged: Vec<u8> = Vec::with_capacity(FOE_PIECE + WRITE_SIZE);
    let mut offset = 0;
    for piece in u.file.chunks(FOE_PIECE) {
        let skip = header_left.min(piece.len());
        header_left -= skip;
        staged.extend_from_slice(&piece[skip..]);
        let whole = staged.len() - staged.len() % WRITE_SIZE;
        if whole > 0 {
            updater.write_firmware(offset, &staged[..whole])?;
            offset += whole;
            staged.drain(..whole);
        }
    }
    if !staged.is_empty() {
        staged.resize(WRITE_SIZE, 0xFF);
        updater.write_firmware(offset, &staged)?;
    }
    Ok(())
}

/// `verify_and_mark_updated` of the drive's key.
fn verify(rig: &Rig, signature: &[u8; 64], len: u32) -> Result<(), FirmwareUpdaterError> {
    let mut aligned = [0u8; WRITE_SIZE];
    let mut updater = BlockingFirmwareUpdater::new(
        FirmwareUpdaterConfig {
            dfu: rig.part(rig.g.dfu),
            state: rig.part(rig.g.state),
        },
        &mut aligned,
    );
    updater.verify_and_mark_updated(&efw::sign::public_key(&SEED), signature, len)
}

/// A whole update: receive, then verify and mark.
fn transfer(rig: &Rig, u: &Update) -> Result<(), FirmwareUpdaterError> {
    receive(rig, u)?;
    verify(rig, &u.header.image_signature, u.header.image_len)
}

/// A cut point of an operation whose run without a cut is `log`.
struct Cut<'a> {
    /// Byte operations done before the cut.
    n: usize,
    /// Byte operations of the whole run.
    total: usize,
    log: &'a [Op],
    rig: &'a Rig,
}

impl Cut<'_> {
    /// The operation that the cut stops (`None`: a cut before an operation starts).
    fn inside(&self) -> Option<(usize, &Op)> {
        self.log
            .iter()
            .enumerate()
            .find(|(_, o)| o.first < self.n && self.n < o.first + o.len)
    }

    /// The number of the operation that starts at the cut, or `log.len()` at the end.
    fn boundary(&self) -> Option<usize> {
        if self.n == self.total {
            return Some(self.log.len());
        }
        self.log.iter().position(|o| o.first == self.n)
    }
}

impl fmt::Display for Cut<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "cut after {} of {} byte operations", self.n, self.total)?;
        let what = |o: &Op| {
            format!(
                "{} of {} bytes at {}",
                if o.erase { "erase" } else { "write" },
                o.len,
                self.rig.place(o.addr)
            )
        };
        if let Some((i, o)) = self.inside() {
            write!(
                f,
                ", byte {} of operation {i} ({})",
                self.n - o.first,
                what(o)
            )
        } else if let Some(i) = self.boundary() {
            match self.log.get(i) {
                Some(o) => write!(f, ", before operation {i} ({})", what(o)),
                None => write!(f, " (no cut)"),
            }
        } else {
            Ok(())
        }
    }
}

/// Runs `op` from the flash contents it finds, once without a cut (logging its
/// erases and writes), then once per cut point N = 0, 1, 2, … until it completes
/// without a cut; after each cut, power on and `check`. Returns the cut points run.
fn every_cut(rig: &Rig, op: impl Fn(&Rig) -> bool, check: impl FnMut(&Rig, &Cut)) -> usize {
    cut_loop(rig, false, op, check)
}

/// [`every_cut`] at fewer cut points: before each operation and at its middle byte.
fn boundary_cuts(rig: &Rig, op: impl Fn(&Rig) -> bool, check: impl FnMut(&Rig, &Cut)) -> usize {
    cut_loop(rig, true, op, check)
}

fn cut_loop(
    rig: &Rig,
    sparse: bool,
    op: impl Fn(&Rig) -> bool,
    mut check: impl FnMut(&Rig, &Cut),
) -> usize {
    let start = rig.snapshot();
    rig.with(|f| {
        f.power_on();
        f.log = Some(Vec::new());
    });
    assert!(op(rig), "the operation fails without a power cut");
    let (log, total) = rig.with(|f| (f.log.take().unwrap_or_default(), f.ops));
    let mut runs = 0;
    for n in 0.. {
        let cut = Cut {
            n,
            total,
            log: &log,
            rig,
        };
        let middle = || cut.inside().is_some_and(|(_, o)| n == o.first + o.len / 2);
        if sparse && n < total && cut.boundary().is_none() && !middle() {
            continue;
        }
        rig.restore(&start);
        rig.with(|f| f.cut_power_after(n));
        let ok = op(rig);
        if !rig.power_lost() {
            assert!(ok, "{cut}: fails without a cut");
            assert_eq!(n, total, "{cut}: completes early");
            break;
        }
        assert!(!ok, "{cut}: reports success");
        rig.power_on();
        check(rig, &cut);
        runs += 1;
    }
    rig.restore(&start);
    runs
}

/// The whole active partition is `image`; else panics with `when` and the first page
/// that differs (and whose page it holds).
fn assert_active_is(rig: &Rig, image: &Image, others: &[&Image], when: &dyn fmt::Display) {
    let active = rig.read(rig.g.active);
    if active == image.partition {
        return;
    }
    let pages = active.len() / PAGE_SIZE;
    let differ: Vec<usize> = (0..pages)
        .filter(|&i| active[i * PAGE_SIZE..(i + 1) * PAGE_SIZE] != *image.page(i))
        .collect();
    let p = differ[0];
    let got = &active[p * PAGE_SIZE..(p + 1) * PAGE_SIZE];
    let holds = others
        .iter()
        .flat_map(|o| (0..pages).map(move |i| (o, i)))
        .find(|(o, i)| o.page(*i) == got)
        .map_or_else(
            || {
                let b = got.iter().zip(image.page(p)).position(|(x, y)| x != y);
                format!(
                    "neither image's page (first differing byte +{})",
                    b.unwrap_or(0)
                )
            },
            |(o, i)| format!("{}'s page {i}", o.name),
        );
    panic!(
        "{when}: ACTIVE is not {}: first differing page {p} of {pages} (it holds {holds}), \
         {} pages differ: {differ:?}",
        image.name,
        differ.len()
    );
}

/// The DFU pages 1..=N hold the active image the swap took out (the revert's source).
fn assert_backup_is(rig: &Rig, image: &Image, when: &dyn fmt::Display) {
    let dfu = rig.read(rig.g.dfu);
    let n = image.partition.len();
    if dfu[PAGE_SIZE..PAGE_SIZE + n] != image.partition[..] {
        let p = (0..n / PAGE_SIZE)
            .find(|&i| dfu[(i + 1) * PAGE_SIZE..(i + 2) * PAGE_SIZE] != *image.page(i))
            .unwrap_or(0);
        panic!(
            "{when}: DFU page {} is not {}'s page {p}",
            p + 1,
            image.name
        );
    }
}

/// The drive after a complete, marked transfer of B; A still active.
fn marked_update(rig: &Rig, a: &Image, b: &Image) {
    install(rig, a);
    transfer(rig, &update(&SMALL, b)).expect("transfer");
    assert_eq!(rig.state(), State::Swap);
}

/// Case 1: a cut anywhere in the transfer (the DFU erases and writes, the signature
/// check and `mark_updated`) leaves A booting, confirmed; a new transfer then works.
///
/// The boot check runs at every cut point. The new transfer (which ends with the swap
/// to B) runs at every operation boundary; inside a state-partition operation at every
/// cut point that leaves flash contents not seen before (past its first words the
/// state erase clears bytes that are erased already); inside a DFU erase or write at
/// every 97th byte (a prime stride: every position within a double word): such a cut
/// only changes DFU bytes that the new transfer erases before it writes them.
#[test]
fn transfer_cut_keeps_the_old_image() {
    let rig = Rig::new(SMALL);
    let (a, b) = images(&SMALL);
    install(&rig, &a);
    let u = update(&SMALL, &b);
    let mut seen = HashSet::new();
    let mut retried = 0;
    let cuts = every_cut(
        &rig,
        |r| transfer(r, &u).is_ok(),
        |r, cut| {
            let inside = cut.inside().map(|(_, o)| *o);
            let retry = match inside {
                None => true,
                Some(o) if in_partition(o.addr, SMALL.state) => seen.insert(r.snapshot()),
                Some(o) => (cut.n - o.first) % 97 == 0,
            };
            assert_eq!(r.prepare_boot(), Ok(State::Boot), "{cut}");
            assert_active_is(r, &a, &[&b], cut);
            assert_eq!(r.state(), State::Boot, "{cut}");
            if retry {
                retried += 1;
                transfer(r, &u).unwrap_or_else(|e| panic!("{cut}: new transfer: {e:?}"));
                assert_eq!(r.state(), State::Swap, "{cut}: new transfer");
                assert_eq!(r.prepare_boot(), Ok(State::Swap), "{cut}: new transfer");
                assert_active_is(r, &b, &[&a], &format_args!("{cut}, new transfer"));
            }
        },
    );
    println!("transfer: {cuts} cut points, a new transfer after {retried} of them");
}

/// Case 2: a cut anywhere in the swap; the next boot (no cut) completes it: B active
/// exactly, trial state `Swap`, A's backup in the DFU pages 1..=8 for a revert. (One
/// boot: a second one without `mark_booted` reverts, by design — case 3.)
///
/// Second cuts: after a first cut at every operation boundary and every 509th byte, the
/// recovering boot is cut too, before each of its operations and at its middle byte;
/// the boot after that ends with B all the same.
#[test]
fn swap_cut_completes_on_the_next_boot() {
    let rig = Rig::new(SMALL);
    let (a, b) = images(&SMALL);
    marked_update(&rig, &a, &b);
    let boot_is_b = |r: &Rig, when: &dyn fmt::Display| {
        assert_eq!(r.prepare_boot(), Ok(State::Swap), "{when}");
        assert_active_is(r, &b, &[&a], when);
        assert_backup_is(r, &a, when);
        assert_eq!(r.state(), State::Swap, "{when}");
    };
    let mut second = 0;
    let cuts = every_cut(
        &rig,
        |r| r.prepare_boot() == Ok(State::Swap),
        |r, cut| {
            if cut.boundary().is_some() || cut.n % SECOND_CUT_STRIDE == 0 {
                second += boundary_cuts(
                    r,
                    |r| r.prepare_boot() == Ok(State::Swap),
                    |r, cut2| boot_is_b(r, &format_args!("{cut}; then {cut2}")),
                );
            }
            boot_is_b(r, cut);
        },
    );
    // The run without a cut: the same.
    assert_eq!(rig.prepare_boot(), Ok(State::Swap));
    assert_active_is(&rig, &b, &[&a], &"swap without a cut");
    println!("swap: {cuts} cut points, {second} second cuts");
}

/// Case 3: the trial boot of B is not confirmed; the next boot reverts to A. With a cut
/// at every byte of that revert, the boot after it ends with A too: state Revert, or
/// Boot when the cut hit the revert's last step (the state erase or the REVERT_MAGIC
/// write); `mark_booted` then gives Boot. Second cuts as in case 2.
#[test]
fn unconfirmed_trial_reverts() {
    let rig = Rig::new(SMALL);
    let (a, b) = images(&SMALL);
    marked_update(&rig, &a, &b);
    assert_eq!(rig.prepare_boot(), Ok(State::Swap));
    assert_active_is(&rig, &b, &[&a], &"swap");
    let trial = rig.snapshot();

    // No cut. prepare_boot reports the state it found (Swap), not Revert.
    assert_eq!(rig.prepare_boot(), Ok(State::Swap));
    assert_active_is(&rig, &a, &[&b], &"revert without a cut");
    assert_eq!(rig.state(), State::Revert);
    rig.mark_booted().expect("mark_booted");
    assert_eq!(rig.state(), State::Boot);
    assert_eq!(rig.prepare_boot(), Ok(State::Boot));
    assert_active_is(&rig, &a, &[&b], &"boot after the revert");

    rig.restore(&trial);
    let (mut revert, mut boot, mut second) = (0, 0, 0);
    let cuts = every_cut(
        &rig,
        |r| r.prepare_boot() == Ok(State::Swap),
        |r, cut| {
            if cut.boundary().is_some() || cut.n % SECOND_CUT_STRIDE == 0 {
                second += boundary_cuts(
                    r,
                    |r| r.prepare_boot().is_ok(),
                    |r, cut2| {
                        let when = format_args!("{cut}; then {cut2}");
                        assert!(r.prepare_boot().is_ok(), "{when}");
                        assert_active_is(r, &a, &[&b], &when);
                        let s = r.state();
                        assert!(s == State::Revert || s == State::Boot, "{when}: {s:?}");
                    },
                );
            }
            // The revert's last three operations: "progress invalid", state erase,
            // REVERT_MAGIC. A cut from the erase's first byte on has erased the
            // magic: the state reads Boot and the boot after it does nothing.
            let erase = &cut.log[cut.log.len() - 2];
            assert!(erase.erase && erase.addr == SMALL.state.offset);
            let magic_gone = cut.n > erase.first;
            let s = r.prepare_boot();
            assert_active_is(r, &a, &[&b], cut);
            if magic_gone {
                assert_eq!(s, Ok(State::Boot), "{cut}");
                assert_eq!(r.state(), State::Boot, "{cut}");
                boot += 1;
            } else {
                assert_eq!(s, Ok(State::Swap), "{cut}");
                assert_eq!(r.state(), State::Revert, "{cut}");
                revert += 1;
            }
            r.mark_booted()
                .unwrap_or_else(|e| panic!("{cut}: mark_booted: {e:?}"));
            assert_eq!(r.prepare_boot(), Ok(State::Boot), "{cut}");
            assert_active_is(r, &a, &[&b], cut);
        },
    );
    println!(
        "revert: {cuts} cut points: A with state Revert after {revert}, A with state Boot \
         after {boot}; {second} second cuts"
    );
}

/// Case 4: the trial boot of B is confirmed; B stays. With a cut at every byte of
/// `mark_booted`: observed, the next boot
/// - N = 0 (nothing written): reverts to A, state Revert (case 3);
/// - N = 1..=8 (the "progress invalid" word partly or wholly written, state erase not
///   begun): runs the revert with every page copy skipped, so B stays, but the state
///   becomes Revert — B runs, labelled as reverted;
/// - N > 8 (the state erase or the BOOT_MAGIC write cut): B, state Boot.
///
/// Never another image or a mixed one.
#[test]
fn confirmed_trial_keeps_the_new_image() {
    let rig = Rig::new(SMALL);
    let (a, b) = images(&SMALL);
    marked_update(&rig, &a, &b);
    assert_eq!(rig.prepare_boot(), Ok(State::Swap));
    let trial = rig.snapshot();

    rig.mark_booted().expect("mark_booted");
    assert_eq!(rig.state(), State::Boot);
    assert_eq!(rig.prepare_boot(), Ok(State::Boot));
    assert_active_is(&rig, &b, &[&a], &"boot after mark_booted");
    assert_eq!(rig.prepare_boot(), Ok(State::Boot));
    assert_active_is(&rig, &b, &[&a], &"second boot after mark_booted");

    rig.restore(&trial);
    let mut outcomes = [0usize; 3];
    let cuts = every_cut(
        &rig,
        |r| r.mark_booted().is_ok(),
        |r, cut| {
            // mark_booted: "progress invalid" word, state erase, BOOT_MAGIC.
            let (word, erase) = (&cut.log[0], &cut.log[1]);
            assert!(!word.erase && word.addr == SMALL.state.offset + WRITE_SIZE as u32);
            assert!(erase.erase && cut.log.len() == 3);
            let s = r.prepare_boot();
            let outcome = if cut.n == 0 {
                assert_eq!(s, Ok(State::Swap), "{cut}");
                assert_active_is(r, &a, &[&b], cut);
                assert_eq!(r.state(), State::Revert, "{cut}");
                0
            } else if cut.n <= erase.first {
                assert_eq!(s, Ok(State::Swap), "{cut}");
                assert_active_is(r, &b, &[&a], cut);
                assert_eq!(r.state(), State::Revert, "{cut}");
                1
            } else {
                assert_eq!(s, Ok(State::Boot), "{cut}");
                assert_active_is(r, &b, &[&a], cut);
                assert_eq!(r.state(), State::Boot, "{cut}");
                2
            };
            outcomes[outcome] += 1;
            // Whatever runs confirms itself and keeps running.
            let running = rig.read(SMALL.active);
            r.mark_booted()
                .unwrap_or_else(|e| panic!("{cut}: mark_booted: {e:?}"));
            assert_eq!(r.prepare_boot(), Ok(State::Boot), "{cut}");
            assert_eq!(
                rig.read(SMALL.active),
                running,
                "{cut}: the next boot changed ACTIVE"
            );
        },
    );
    println!(
        "mark_booted: {cuts} cut points: A reverted after {}, B labelled Revert after {}, \
         B confirmed after {}",
        outcomes[0], outcomes[1], outcomes[2]
    );
}

/// Case 5: `verify_and_mark_updated` refuses a changed DFU byte, another key's
/// signature, a length beyond the written image (within the DFU partition) and one
/// short of it; it panics on a length beyond the DFU partition. Each time the state
/// stays Boot and A boots. It accepts an image longer than the active partition.
#[test]
fn verify_refuses_bad_images() {
    let rig = Rig::new(SMALL);
    let (a, b) = images(&SMALL);
    install(&rig, &a);
    let u = update(&SMALL, &b);
    receive(&rig, &u).expect("receive");
    let received = rig.snapshot();
    let foreign = signed(&OTHER_SEED, &b);
    assert!(efw::check_header(&foreign, &expected(&SMALL)).is_err());
    let other = Header::parse(&efw::Frame::new_unchecked(&foreign[..])).expect("other key's");
    let h = u.header;
    let len = h.image_len;

    let refused = |what: &str, r: Result<(), FirmwareUpdaterError>| {
        assert!(
            matches!(r, Err(FirmwareUpdaterError::Signature(_))),
            "{what}: {r:?}"
        );
        assert_eq!(rig.state(), State::Boot, "{what}");
        assert_eq!(rig.prepare_boot(), Ok(State::Boot), "{what}");
        assert_active_is(&rig, &a, &[&b], &what);
        rig.restore(&received);
    };

    let mut tampered = 0;
    for at in [0, 1, 4_000, len as usize / 2, len as usize - 1] {
        rig.with(|f| f.mem[SMALL.dfu.offset as usize + at] ^= 0x10);
        refused(
            &format!("DFU byte {at} changed"),
            verify(&rig, &h.image_signature, len),
        );
        tampered += 1;
    }
    refused(
        "another key's signature",
        verify(&rig, &other.image_signature, len),
    );
    refused("length + 1", verify(&rig, &h.image_signature, len + 1));
    refused("length + 8", verify(&rig, &h.image_signature, len + 8));
    refused(
        "length + 1 page",
        verify(&rig, &h.image_signature, len + PAGE),
    );
    refused("length - 1", verify(&rig, &h.image_signature, len - 1));
    refused(
        "the whole DFU partition",
        verify(&rig, &h.image_signature, SMALL.dfu.size),
    );

    // Longer than the DFU partition: an assert! in embassy-boot, not an Err.
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        verify(&rig, &h.image_signature, SMALL.dfu.size + 1)
    }));
    assert!(r.is_err(), "a length beyond the DFU partition: {r:?}");
    rig.power_on();
    assert_eq!(rig.state(), State::Boot);
    assert_eq!(rig.prepare_boot(), Ok(State::Boot));
    assert_active_is(&rig, &a, &[&b], &"length beyond the DFU partition");

    // The control: the received image with its own signature and length.
    verify(&rig, &h.image_signature, len).expect("the right signature");
    assert_eq!(rig.state(), State::Swap);
    println!("verify: {tampered} changed bytes and 6 other refusals, 1 panic");

    // embassy-boot bounds the length by the DFU partition only: an image 1000 bytes
    // longer than the active partition verifies and is marked, and the swap installs
    // its first 16 KiB. The drive must refuse it before (efw::check_header does, with
    // the active partition's size as its capacity).
    let rig = Rig::new(SMALL);
    install(&rig, &a);
    let long = Image::new(
        "long",
        0x0C0F_FEE0,
        SMALL.active.size as usize + 1000,
        &SMALL,
    );
    let file = signed(&SEED, &long);
    assert_eq!(
        efw::check_header(&file, &expected(&SMALL)).map(|h| h.image_len),
        Err(efw::ImageError::TooLong)
    );
    let header = Header::parse(&efw::Frame::new_unchecked(&file[..])).expect("header");
    let u = Update { file, header };
    receive(&rig, &u).expect("receive");
    verify(&rig, &header.image_signature, header.image_len).expect("accepted");
    assert_eq!(rig.prepare_boot(), Ok(State::Swap));
    assert_eq!(
        rig.read(SMALL.active),
        long.partition,
        "truncated to the partition"
    );
}

/// The board's layout (`firmware::flash_layout`): embassy-boot accepts its partitions,
/// and an update of an image of the largest size swaps and then reverts, without cuts.
#[test]
fn real_layout_update_and_revert() {
    let rig = Rig::new(REAL);
    let max = flash_layout::IMAGE_MAX as usize;
    let a = Image::new("A", 0x1234_5678, max - 5_000, &REAL);
    let b = Image::new("B", 0x0BAD_F00D, max - 4, &REAL);
    // A fresh drive: DFU erased, A flashed and confirmed.
    rig.with(|f| {
        let at = REAL.active.offset as usize;
        f.mem[at..at + a.partition.len()].copy_from_slice(&a.partition);
    });
    rig.mark_booted().expect("mark_booted");
    transfer(&rig, &update(&REAL, &b)).expect("transfer");
    assert_eq!(rig.prepare_boot(), Ok(State::Swap));
    assert_active_is(&rig, &b, &[&a], &"swap");
    assert_eq!(rig.prepare_boot(), Ok(State::Swap));
    assert_active_is(&rig, &a, &[&b], &"revert");
    assert_eq!(rig.state(), State::Revert);
    rig.mark_booted().expect("mark_booted");
    transfer(&rig, &update(&REAL, &b)).expect("second transfer");
    assert_eq!(rig.prepare_boot(), Ok(State::Swap));
    rig.mark_booted().expect("mark_booted");
    assert_eq!(rig.prepare_boot(), Ok(State::Boot));
    assert_active_is(&rig, &b, &[&a], &"confirmed");
}

/// The first progress word that the swap from the rig's contents writes (a run
/// without a cut, logged; the rig is left as it was).
fn first_progress_word(rig: &Rig) -> Op {
    let start = rig.snapshot();
    rig.with(|f| {
        f.power_on();
        f.log = Some(Vec::new());
    });
    assert_eq!(rig.prepare_boot(), Ok(State::Swap));
    let log = rig.with(|f| f.log.take().unwrap_or_default());
    let progress = *log
        .iter()
        .find(|o| !o.erase && o.len == WRITE_SIZE)
        .expect("progress");
    assert!(in_partition(progress.addr, SMALL.state));
    rig.restore(&start);
    progress
}

/// Why [`CutFlash`] lets a programmed double word be programmed again with zeros, as
/// the STM32G4 does: on a flash that refuses it (as `firmware::storage::RamFlash`
/// does), a cut inside a progress-word write of the swap, or inside `mark_booted`'s
/// first write, leaves embassy-boot unable to boot — `prepare_boot` fails every time.
#[test]
fn a_flash_without_zero_overwrite_would_not_boot() {
    let rig = Rig::new(SMALL);
    let (a, b) = images(&SMALL);
    marked_update(&rig, &a, &b);
    rig.with(|f| f.zero_overwrite = false);
    let trial = rig.snapshot();

    // The swap, cut after 3 bytes of its first progress word.
    let progress = first_progress_word(&rig);
    rig.with(|f| f.cut_power_after(progress.first + 3));
    assert!(rig.prepare_boot().is_err());
    for _ in 0..3 {
        rig.power_on();
        assert_eq!(
            rig.prepare_boot(),
            Err(BootError::Flash(NorFlashErrorKind::Other))
        );
    }

    // mark_booted after the swap, cut after 3 bytes of its first write.
    rig.restore(&trial);
    assert_eq!(rig.prepare_boot(), Ok(State::Swap));
    rig.with(|f| f.cut_power_after(3));
    assert!(rig.mark_booted().is_err());
    rig.power_on();
    assert_eq!(
        rig.prepare_boot(),
        Err(BootError::Flash(NorFlashErrorKind::Other))
    );
}

/// A state that [`CutFlash`] never produces, for the record: its interrupted erase
/// clears a page from its start, so the magic word goes first. If an interrupted state
/// erase (`mark_booted`'s, or the end of a revert) left the magic word intact and the
/// rest erased, the next boot would read SWAP_MAGIC with valid progress 0 and run the
/// swap again over the swapped images: a mixed ACTIVE. On the chip a page erase is not
/// ordered; that outcome needs every bit of the "progress invalid" word erased and no
/// zero bit of the magic word, and such half-erased double words are ECC errors.
#[test]
fn a_state_erase_sparing_only_the_magic_would_mix_the_images() {
    let rig = Rig::new(SMALL);
    let (a, b) = images(&SMALL);
    marked_update(&rig, &a, &b);
    assert_eq!(rig.prepare_boot(), Ok(State::Swap));
    let state = SMALL.state.offset as usize;
    rig.with(|f| f.mem[state + WRITE_SIZE..state + SMALL.state.size as usize].fill(0xFF));
    assert_eq!(rig.prepare_boot(), Ok(State::Swap));
    let active = rig.read(SMALL.active);
    assert_ne!(active, a.partition);
    assert_ne!(active, b.partition);
}

/// Finding (issue 33): with the ECC of torn double words modelled, a cut inside a
/// progress word of the swap leaves that word unreadable, and embassy-boot 0.7's
/// `prepare_boot` fails at every later boot (it reads every progress word); the
/// bootloader then stops with the bridges off (`bootloader/src/main.rs`). A cut
/// between two double words leaves nothing torn, and that boot completes the swap.
#[test]
fn a_torn_state_word_stops_the_bootloader() {
    let rig = Rig::new(SMALL);
    let (a, b) = images(&SMALL);
    marked_update(&rig, &a, &b);
    rig.with(|f| f.ecc = true);
    let trial = rig.snapshot();
    let progress = first_progress_word(&rig);
    // Inside the word: torn, every read of it fails, the bootloader cannot go on.
    rig.restore(&trial);
    rig.with(|f| f.cut_power_after(progress.first + 3));
    assert!(rig.prepare_boot().is_err());
    rig.power_on();
    assert!(rig.with(|f| f.torn.contains(&progress.addr)));
    for _ in 0..3 {
        assert_eq!(
            rig.prepare_boot(),
            Err(BootError::Flash(NorFlashErrorKind::Other))
        );
        rig.power_on();
    }
    // Before the word: nothing torn, the next boot completes the swap.
    rig.restore(&trial);
    rig.with(|f| f.cut_power_after(progress.first));
    assert!(rig.prepare_boot().is_err());
    rig.power_on();
    assert!(rig.with(|f| f.torn.is_empty()));
    assert_eq!(rig.prepare_boot(), Ok(State::Swap));
    assert_active_is(&rig, &b, &[&a], &"swap after a cut between words");
}

/// Issue 33, the fix of [`a_torn_state_word_stops_the_bootloader`]: with the ECC of
/// torn double words modelled, a cut inside any state-partition write or erase of the
/// swap, of the confirmation after it (`mark_booted`), of the revert, or of the
/// marking of an update (`mark_updated`) leaves a torn word in the state page. The
/// drive's bootloader (`firmware::boot_state::prepare_boot`) reads it as erased and
/// boots a whole image — B after a cut swap, A after a cut revert or marking, one of
/// the two after a cut confirmation — and no torn word stays in the state page: the
/// firmware reads its state.
#[test]
fn a_torn_state_word_boots_a_whole_image() {
    let rig = Rig::new(SMALL);
    let (a, b) = images(&SMALL);
    marked_update(&rig, &a, &b);
    rig.with(|f| f.ecc = true);
    let marked = rig.snapshot();
    assert_eq!(rig.bootloader(), Ok(State::Swap));
    let swapped = rig.snapshot();
    // B in ACTIVE, A in the DFU pages, the state erased ("boot"): the marking of a
    // second update.
    rig.with(|f| {
        let st = SMALL.state.offset as usize;
        f.mem[st..st + SMALL.state.size as usize].fill(0xFF);
    });
    let unmarked = rig.snapshot();
    let mark_updated = |r: &Rig| {
        let mut aligned = [0u8; WRITE_SIZE];
        BlockingFirmwareState::new(r.part(r.g.state), &mut aligned)
            .mark_updated()
            .is_ok()
    };
    type Scenario<'a> = (
        &'a str,
        &'a Snapshot,
        &'a dyn Fn(&Rig) -> bool,
        Option<&'a Image>,
    );
    let scenarios: [Scenario; 4] = [
        ("swap", &marked, &|r: &Rig| r.bootloader().is_ok(), Some(&b)),
        (
            "confirmation",
            &swapped,
            &|r: &Rig| r.mark_booted().is_ok(),
            None,
        ),
        (
            "revert",
            &swapped,
            &|r: &Rig| r.bootloader().is_ok(),
            Some(&a),
        ),
        ("marking", &unmarked, &mark_updated, Some(&b)),
    ];
    let mut torn_runs = 0;
    for (name, start, op, expect) in scenarios {
        // The state-partition operations of an uncut run.
        rig.restore(start);
        rig.with(|f| f.log = Some(Vec::new()));
        assert!(op(&rig), "{name} without a cut");
        let ops: Vec<Op> = rig
            .with(|f| f.log.take().unwrap_or_default())
            .into_iter()
            .filter(|o| in_partition(o.addr, SMALL.state))
            .collect();
        assert!(!ops.is_empty(), "{name}: no state operation");
        for o in ops {
            // Inside its first, second and last double word, and its middle.
            let mut at = vec![3, 11, o.len / 2 + 5, o.len - 3];
            at.retain(|&k| k < o.len && k % WRITE_SIZE != 0);
            for k in at {
                let when = format!("{name}: cut {k} bytes into {}", rig.place(o.addr));
                rig.restore(start);
                rig.with(|f| f.cut_power_after(o.first + k));
                assert!(!op(&rig), "{when}: reports success");
                rig.power_on();
                let torn = rig.with(|f| f.torn.iter().any(|&w| in_partition(w, SMALL.state)));
                torn_runs += usize::from(torn);
                assert!(rig.bootloader().is_ok(), "{when}: the bootloader fails");
                assert!(
                    rig.with(|f| f.torn.iter().all(|&w| !in_partition(w, SMALL.state))),
                    "{when}: a torn word stays in the state page"
                );
                let _ = rig.state();
                // Which image runs: the expected one, or (a cut confirmation) one of
                // the two, whole.
                let active = rig.read(SMALL.active);
                let (image, others) = if active == a.partition {
                    (&a, &b)
                } else {
                    (&b, &a)
                };
                if let Some(e) = expect {
                    assert_active_is(&rig, e, &[others], &when);
                } else {
                    assert_active_is(&rig, image, &[others], &when);
                }
            }
        }
    }
    // The cuts did tear state words (the model is on).
    assert!(torn_runs > 10, "{torn_runs} torn runs");
}
