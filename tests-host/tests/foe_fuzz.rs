//! Property test of the FoE path, as `coe_fuzz.rs` is for CoE: random and mutated FoE
//! mailbox frames (300 000 per run over five mailbox sizes) go through the
//! stack's [`MailboxServer`] into the product's firmware update
//! ([`firmware::update::Update`] over [`EmbassyUpdater`] on RAM partitions in the
//! STM32G4's 2 KiB pages), called exactly as the slave runtime calls them
//! (`ecat-slave-stack/src/slave.rs`: `receive_mailbox`, the `poll` ticks, `next_output`
//! when SM1 is free, `foe_abort` + `reset` when the mailbox stops, the mailbox sizes
//! set when it starts, the drive's reset on Bootstrap → Init after an accepted
//! update and its confirmation in Pre-Op).
//!
//! The frames: WRQ / RRQ with random names (`*.efw` in several spellings,
//! `firmware.info`, others) and passwords; DATA with the right, a repeated, a skipped
//! or a random packet number and random, zero, full, short or oversized lengths
//! (random bytes, or slices of a real signed file so the header passes and the
//! erase / BUSY / write / verification paths run); ACK, ERR and BUSY from the master;
//! truncated FoE headers; unknown opcodes; zero-length mailboxes; other mailbox
//! types, wrong channels, bad length fields, repeated counters; the master sometimes
//! not reading SM1 or asking for a repeat. In between: time steps and jumps past the
//! FoE timeout (the runtime's ticks abort the transfer), ESM changes between
//! Bootstrap, Init and Pre-Op (aborts), power cycles (embassy-boot's `prepare_boot`),
//! and now and then a real signed file in correct packets with BUSY handling
//! ("injections": valid, or tampered, truncated, for the other ESC), sometimes broken
//! by an interleaved frame or a timeout.
//!
//! Invariants, checked after every frame:
//! * nothing panics;
//! * every frame the server hands to SM1 is a well-formed mailbox frame no longer
//!   than SM1, with the next counter: a mailbox error (service 1, a known detail) or
//!   FoE with opcode DATA (at most a read segment, printable text of the information
//!   file), ACK, BUSY (done ≤ 100 of 100) or ERR with a code of
//!   [`ErrorCode`]; CoE only in Pre-Op (where CoE goes to a dictionary);
//! * every request that is not a repetition, not an ERR from the master, not the ACK
//!   of a read's last DATA (and not CoE in Pre-Op, `coe_fuzz.rs`'s domain) gets an
//!   answer at once when SM1 is free;
//! * the backend sees the [`FoeFiles`] contract: one transfer at a time, `abort` only
//!   for an open one;
//! * an update is accepted only when the backend received, byte for byte, one of
//!   the validly signed files (and then the finished transfer is an injection of it):
//!   no other [`Update::accepted`], no `Event::Accepted`, and embassy-boot's state
//!   stays `Boot` except between such an acceptance and the confirmation of the new
//!   image (the model follows swap, trial, confirmation and revert, and checks the
//!   running version and the active partition after each power cycle);
//! * every valid injection that is not broken is accepted (the fuzzer reaches the
//!   deep states), every tampered / truncated / foreign one gets its FoE error.
//!
//! After the fuzzing of each mailbox size, a clean transfer of a valid file still
//! succeeds, swaps and confirms. The counts of answers by kind are printed.
//!
//! Two directed tests follow from what the fuzzer's invariants catch: a header
//! changed in the DATA resent after BUSY must be refused; and a second download
//! after an accepted one must not leave an unverified image to be swapped in (both
//! were product bugs this fuzzer found; the backend now refuses them).
//!
//! Own small PRNG (xorshift64*), fixed seeds: runs are repeatable.

use std::cell::RefCell;
use std::collections::BTreeMap;

use ecat_slave_stack::coe::example::ExampleDictionary;
use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::foe::{self, ErrorCode, FoeFiles, WriteStatus};
use ecat_slave_stack::mailbox::{ErrorDetail, Handlers, MailboxServer, MAX_MAILBOX_SIZE};
use embassy_boot::{BlockingFirmwareState, BootLoader, BootLoaderConfig, State};
use embassy_embedded_hal::flash::partition::BlockingPartition;
use embassy_sync::blocking_mutex::{raw::NoopRawMutex, Mutex};
use firmware::flash_layout;
use firmware::identity::{Variant, VENDOR_ID};
use firmware::storage::RamFlash;
use firmware::update::{EmbassyUpdater, Event, FirmwareUpdate, Update, Updater, INFO_FILE};

// ---- PRNG ------------------------------------------------------------------------

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    fn byte(&mut self) -> u8 {
        self.next() as u8
    }
    /// True with `per_mille` / 1000.
    fn chance(&mut self, per_mille: usize) -> bool {
        self.below(1000) < per_mille
    }
    fn pick<'a, T>(&mut self, v: &'a [T]) -> &'a T {
        &v[self.below(v.len())]
    }
}

// ---- RAM partitions ----------------------------------------------------------------

const ACTIVE_SIZE: usize = flash_layout::ACTIVE.size as usize;
const DFU_SIZE: usize = flash_layout::DFU.size as usize;
const STATE_SIZE: usize = flash_layout::BOOT_STATE.size as usize;
const PRODUCT: u32 = Variant::HybridServo.product_code();

/// A [`RamFlash`] erased in whole 2 KiB pages, like the STM32G4 (embassy-boot sizes
/// its swap by the page count).
struct Paged<const N: usize>(RamFlash<N>);

impl<const N: usize> embedded_storage::nor_flash::ErrorType for Paged<N> {
    type Error = embedded_storage::nor_flash::NorFlashErrorKind;
}

impl<const N: usize> embedded_storage::nor_flash::ReadNorFlash for Paged<N> {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        self.0.read(offset, bytes)
    }
    fn capacity(&self) -> usize {
        N
    }
}

impl<const N: usize> embedded_storage::nor_flash::NorFlash for Paged<N> {
    const WRITE_SIZE: usize = 8;
    const ERASE_SIZE: usize = flash_layout::PAGE as usize;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let page = flash_layout::PAGE;
        if !from.is_multiple_of(page) || !to.is_multiple_of(page) {
            return Err(embedded_storage::nor_flash::NorFlashErrorKind::NotAligned);
        }
        self.0.erase(from, to)
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        self.0.write(offset, bytes)
    }
}

type Part<const N: usize> = Mutex<NoopRawMutex, RefCell<Paged<N>>>;

fn part<const N: usize>() -> Part<N> {
    Mutex::new(RefCell::new(Paged(RamFlash::new())))
}

/// The chip's boot state, active and DFU partitions, each its own RAM flash.
struct Flashes {
    active: Part<ACTIVE_SIZE>,
    dfu: Part<DFU_SIZE>,
    state: Part<STATE_SIZE>,
}

impl Flashes {
    fn new() -> Box<Self> {
        Box::new(Flashes {
            active: part(),
            dfu: part(),
            state: part(),
        })
    }

    /// The firmware's update over the partitions, as the drive builds it at start.
    fn update(&self) -> Update<impl Updater + '_> {
        // The updater keeps a buffer aligned to the state partition's write size for
        // the life of the drive (a static on the board).
        let aligned: &'static mut [u8] = Box::leak(Box::new([0u8; 8]));
        let u = EmbassyUpdater::new(
            BlockingPartition::new(&self.dfu, 0, DFU_SIZE as u32),
            BlockingPartition::new(&self.state, 0, STATE_SIZE as u32),
            BlockingPartition::new(&self.active, 0, ACTIVE_SIZE as u32),
            aligned,
        );
        Update::new(u, VENDOR_ID, PRODUCT, efw::Esc::Lan9252)
    }

    /// A power-up: embassy-boot's `prepare_boot` (swap or revert).
    fn boot(&self) -> State {
        let mut bl = BootLoader::new(BootLoaderConfig {
            active: BlockingPartition::new(&self.active, 0, ACTIVE_SIZE as u32),
            dfu: BlockingPartition::new(&self.dfu, 0, DFU_SIZE as u32),
            state: BlockingPartition::new(&self.state, 0, STATE_SIZE as u32),
        });
        let mut page = vec![0u8; flash_layout::PAGE as usize];
        bl.prepare_boot(&mut page).expect("prepare_boot")
    }

    /// embassy-boot's state as its partition holds it now.
    fn state(&self) -> State {
        let mut aligned = [0u8; 8];
        BlockingFirmwareState::new(
            BlockingPartition::new(&self.state, 0, STATE_SIZE as u32),
            &mut aligned,
        )
        .get_state()
        .expect("boot state")
    }

    fn active_starts_with(&self, image: &[u8]) -> bool {
        self.active
            .lock(|f| f.borrow().0.mem[..image.len()] == *image)
    }
}

// ---- files -----------------------------------------------------------------------

fn seed() -> [u8; 32] {
    efw::sign::dev_key()
}

fn image(len: usize, salt: u8) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u8).wrapping_mul(29).wrapping_add(salt) ^ (i >> 8) as u8)
        .collect()
}

/// The signed files of one run: valid ones (sizes around the page and segment
/// boundaries) and their images.
struct Files {
    valid: Vec<(u32, Vec<u8>)>,
    images: BTreeMap<u32, Vec<u8>>,
    /// Built for the ET1100 variant.
    foreign: Vec<u8>,
}

impl Files {
    fn new(segment: usize, salt: u8) -> Files {
        let hl = efw::HEADER_LEN;
        // Image lengths: tiny, one write chunk, across pages, and one that makes the
        // file a multiple of the segment (the transfer ends with an empty DATA).
        let mut lens = vec![1, 256, 700, 2048, 2049, 4100];
        let k = (hl + 3000).div_ceil(segment);
        lens.push(k * segment - hl);
        let mut valid = Vec::new();
        let mut images = BTreeMap::new();
        for (i, len) in lens.into_iter().enumerate() {
            let version = 0x0002_0000 | (u32::from(salt) << 8) | i as u32;
            let img = image(len, salt.wrapping_add(i as u8));
            let f = efw::sign::update_file(
                &seed(),
                VENDOR_ID,
                PRODUCT,
                efw::Esc::Lan9252,
                version,
                &img,
            );
            valid.push((version, f));
            images.insert(version, img);
        }
        let foreign = efw::sign::update_file(
            &seed(),
            VENDOR_ID,
            PRODUCT,
            efw::Esc::Et1100,
            0x0009_0000,
            &image(900, salt),
        );
        Files {
            valid,
            images,
            foreign,
        }
    }
}

// ---- the backend, as the server sees it --------------------------------------------

/// The product's update behind a recorder of the [`FoeFiles`] calls: it checks the
/// contract and keeps the bytes the backend took, to tell what was accepted.
struct Recorder<'a> {
    upd: Box<dyn FirmwareUpdate + 'a>,
    open: Option<foe::Direction>,
    /// The bytes taken in the open (or last) write transfer.
    taken: Vec<u8>,
    /// A `finish_write` returned Ok: the file it completed.
    finished: Option<Vec<u8>>,
    aborts: u64,
    busy: u64,
}

impl FoeFiles for Recorder<'_> {
    fn open_write(&mut self, name: &[u8], password: u32, in_boot: bool) -> Result<(), ErrorCode> {
        assert_eq!(self.open, None, "open_write with a transfer open");
        let r = self.upd.open_write(name, password, in_boot);
        if r.is_ok() {
            self.open = Some(foe::Direction::Write);
            self.taken.clear();
        }
        r
    }
    fn write(&mut self, offset: u32, data: &[u8]) -> WriteStatus {
        assert_eq!(
            self.open,
            Some(foe::Direction::Write),
            "write without a write open"
        );
        assert_eq!(offset as usize, self.taken.len(), "write offset");
        let r = self.upd.write(offset, data);
        match r {
            WriteStatus::Done => self.taken.extend_from_slice(data),
            WriteStatus::Busy { done_percent } => {
                assert!(done_percent <= 100);
                self.busy += 1;
            }
            WriteStatus::Err(_) => {}
        }
        r
    }
    fn finish_write(&mut self) -> Result<(), ErrorCode> {
        assert_eq!(
            self.open,
            Some(foe::Direction::Write),
            "finish without a write open"
        );
        let r = self.upd.finish_write();
        if r.is_ok() {
            self.open = None;
            self.finished = Some(self.taken.clone());
        }
        r
    }
    fn open_read(&mut self, name: &[u8], password: u32, in_boot: bool) -> Result<u32, ErrorCode> {
        assert_eq!(self.open, None, "open_read with a transfer open");
        let r = self.upd.open_read(name, password, in_boot);
        if r.is_ok() {
            self.open = Some(foe::Direction::Read);
        }
        r
    }
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> usize {
        assert_eq!(
            self.open,
            Some(foe::Direction::Read),
            "read without a read open"
        );
        self.upd.read(offset, buf)
    }
    fn finish_read(&mut self) {
        assert_eq!(
            self.open,
            Some(foe::Direction::Read),
            "finish_read without a read"
        );
        self.open = None;
        self.upd.finish_read();
    }
    fn abort(&mut self) {
        assert!(self.open.is_some(), "abort without an open transfer");
        self.open = None;
        self.aborts += 1;
        self.upd.abort();
    }
}

// ---- the model of the drive's boot flash -------------------------------------------

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Boot {
    /// The running image is confirmed: embassy-boot's state is Boot.
    Confirmed,
    /// An update was accepted (marked for the swap) in this Bootstrap.
    Marked { version: u32 },
    /// The new image runs on trial until Pre-Op; `prev` ran before.
    Trial { version: u32, prev: Option<u32> },
}

// ---- the answers -------------------------------------------------------------------

const K_MBX_ERROR: usize = 0;
const K_ACK: usize = 1;
const K_DATA: usize = 2;
const K_ERR: usize = 3;
const K_BUSY: usize = 4;
const K_COE: usize = 5;
const KIND_NAMES: [&str; 6] = ["mailbox error", "ACK", "DATA", "ERR", "BUSY", "CoE"];

/// An answer, decoded.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Answer {
    MailboxError(u16),
    Ack(u32),
    Data(u32, Vec<u8>),
    Err(u32),
    Busy,
    Coe,
}

#[derive(Default)]
struct Stats {
    random_frames: u64,
    injection_frames: u64,
    answers: [u64; 6],
    details: BTreeMap<u16, u64>,
    codes: BTreeMap<u32, u64>,
    checked_answers: u64,
    repeats: u64,
    timeouts: u64,
    state_changes: u64,
    power_cycles: u64,
    swaps: u64,
    reverts: u64,
    injections: BTreeMap<String, u64>,
    accepted: u64,
    accepted_from_stream: u64,
    reads_completed: u64,
    backend_busy: u64,
    backend_aborts: u64,
}

impl Stats {
    fn add(&mut self, o: &Stats) {
        self.random_frames += o.random_frames;
        self.injection_frames += o.injection_frames;
        for (a, b) in self.answers.iter_mut().zip(o.answers) {
            *a += b;
        }
        for (k, v) in &o.details {
            *self.details.entry(*k).or_default() += v;
        }
        for (k, v) in &o.codes {
            *self.codes.entry(*k).or_default() += v;
        }
        for (k, v) in &o.injections {
            *self.injections.entry(k.clone()).or_default() += v;
        }
        self.checked_answers += o.checked_answers;
        self.repeats += o.repeats;
        self.timeouts += o.timeouts;
        self.state_changes += o.state_changes;
        self.power_cycles += o.power_cycles;
        self.swaps += o.swaps;
        self.reverts += o.reverts;
        self.accepted += o.accepted;
        self.accepted_from_stream += o.accepted_from_stream;
        self.reads_completed += o.reads_completed;
        self.backend_busy += o.backend_busy;
        self.backend_aborts += o.backend_aborts;
    }
}

/// Checks one frame from `next_output` (the server's answer in SM1) and decodes it.
fn check_frame(o: &[u8], sm1: usize, counter: u8, state: EsmState, read_segment: usize) -> Answer {
    assert!(
        o.len() >= 6 && o.len() <= sm1,
        "frame length {} for SM1 {sm1}",
        o.len()
    );
    let len = u16::from_le_bytes([o[0], o[1]]) as usize;
    assert_eq!(len, o.len() - 6, "length field of {o:02x?}");
    assert_eq!((o[5] >> 4) & 7, counter, "counter sequence");
    assert_eq!(o[2..5], [0, 0, 0], "address / channel / priority");
    let p = &o[6..];
    match o[5] & 0x0F {
        0 => {
            assert_eq!(p.len(), 4, "mailbox error {p:02x?}");
            assert_eq!(u16::from_le_bytes([p[0], p[1]]), 1, "service");
            let d = u16::from_le_bytes([p[2], p[3]]);
            assert!(ErrorDetail::from_code(d).is_some(), "detail {d}");
            Answer::MailboxError(d)
        }
        4 => {
            assert!(p.len() >= foe::HEADER_LEN, "FoE answer {p:02x?}");
            assert_eq!(p[1], 0, "reserved byte");
            let arg = u32::from_le_bytes([p[2], p[3], p[4], p[5]]);
            match p[0] {
                3 => {
                    let data = &p[6..];
                    assert!(
                        read_segment > 0 && data.len() <= read_segment,
                        "DATA of {} bytes, read segment {read_segment}",
                        data.len()
                    );
                    assert!(arg >= 1, "DATA number {arg}");
                    assert!(
                        data.iter()
                            .all(|&c| c == b'\n' || (0x20..0x7F).contains(&c)),
                        "information file text {data:02x?}"
                    );
                    Answer::Data(arg, data.to_vec())
                }
                4 => {
                    assert_eq!(p.len(), 6, "ACK {p:02x?}");
                    Answer::Ack(arg)
                }
                5 => {
                    assert_eq!(p.len(), 6, "ERR {p:02x?}");
                    assert!(ErrorCode::from_code(arg).is_some(), "ERR code {arg:#x}");
                    Answer::Err(arg)
                }
                6 => {
                    assert_eq!(p.len(), 6, "BUSY {p:02x?}");
                    let (done, entire) = (
                        u16::from_le_bytes([p[2], p[3]]),
                        u16::from_le_bytes([p[4], p[5]]),
                    );
                    assert!(
                        done <= 100 && entire == foe::BUSY_ENTIRE,
                        "BUSY {done}/{entire}"
                    );
                    Answer::Busy
                }
                op => panic!("FoE opcode {op} sent by the slave: {p:02x?}"),
            }
        }
        3 => {
            assert_eq!(state, EsmState::PreOp, "CoE answer outside Pre-Op");
            Answer::Coe
        }
        t => panic!("mailbox type {t} sent by the slave"),
    }
}

// ---- the world: runtime + backend + master -----------------------------------------

/// A file name for a WRQ.
fn name(r: &mut Rng, out: &mut Vec<u8>) {
    let names: [&[u8]; 14] = [
        b"ecs-lan9252.efw",
        b"ecs-et1100.efw",
        b"x/Y.EFW",
        b"a.Efw",
        b".efw",
        b"efw",
        b"firmware.info",
        b"firmware.bin",
        b"ecs-lan9252.efw\0",
        b"",
        b"FIRMWARE.INFO",
        b"/firmware.info",
        b"update.efw.bak",
        b"\xff\xfe.efw",
    ];
    match r.below(10) {
        0 => out.extend((0..r.below(40)).map(|_| r.byte())),
        1 => {
            out.extend((0..r.below(150)).map(|_| b'a' + (r.byte() % 26)));
            out.extend_from_slice(b".efw");
        }
        _ => {
            let n: &&[u8] = r.pick(&names);
            out.extend_from_slice(n);
        }
    }
}

/// What the fuzzer's master believes about the transfer in progress.
#[derive(Default, Clone, Copy)]
struct Belief {
    /// A write is open: the next DATA number.
    write_next: Option<u32>,
    /// A read is open: the last DATA number received.
    read_last: Option<u32>,
    /// The valid file (index) the DATA of the write are mostly slices of.
    file: usize,
}

struct World<'a> {
    fl: &'a Flashes,
    files: &'a Files,
    rec: Recorder<'a>,
    dict: ExampleDictionary,
    mbx: MailboxServer,
    sm0: usize,
    sm1: usize,
    state: EsmState,
    now_us: u64,
    foe_timeout_us: u64,
    /// The SM0 buffer as the master last wrote it.
    sm0_buf: Vec<u8>,
    /// A frame in SM1 the master has not read yet.
    sm1_frame: Option<Vec<u8>>,
    /// The last frame the server handed out (what a repeat request brings).
    last_handed: Option<Vec<u8>>,
    /// Counter of the master's last request.
    counter: u8,
    /// Counter of the last request the server saw (for its repetition rule).
    last_in: Option<u8>,
    /// Counter of the last frame the master read (the sequence to check).
    out_counter: u8,
    boot: Boot,
    running: Option<u32>,
    belief: Belief,
    read_bytes: Vec<u8>,
    read_next: Option<u32>,
    stats: Stats,
}

impl<'a> World<'a> {
    fn new(fl: &'a Flashes, files: &'a Files, sm0: usize, sm1: usize) -> Self {
        let foe_timeout_us = firmware::identity::slave_config().foe_timeout_us;
        let mut mbx = MailboxServer::new(sm1);
        mbx.set_foe_timeout_us(foe_timeout_us);
        World {
            fl,
            files,
            rec: Recorder {
                upd: Box::new(fl.update()),
                open: None,
                taken: Vec::new(),
                finished: None,
                aborts: 0,
                busy: 0,
            },
            dict: ExampleDictionary::new(),
            mbx,
            sm0,
            sm1,
            state: EsmState::Init,
            now_us: 0,
            foe_timeout_us,
            sm0_buf: vec![0; sm0],
            sm1_frame: None,
            last_handed: None,
            counter: 0,
            last_in: None,
            out_counter: 0,
            boot: Boot::Confirmed,
            running: None,
            belief: Belief::default(),
            read_bytes: Vec::new(),
            read_next: None,
            stats: Stats::default(),
        }
    }

    fn segment(&self) -> usize {
        self.sm0.min(MAX_MAILBOX_SIZE) - foe::OVERHEAD
    }

    fn read_segment(&self) -> usize {
        if self.sm0 <= self.sm1 {
            self.segment()
        } else {
            0
        }
    }

    fn next_counter(&mut self) -> u8 {
        self.counter = self.counter % 7 + 1;
        self.counter
    }

    /// The runtime's mailbox part of `poll` (SM0 served before): ticks, then SM1
    /// filled when it is free.
    fn poll(&mut self) {
        if !self.state.mailbox_running() {
            return;
        }
        self.mbx.tick(self.now_us);
        if self.mbx.foe_active().is_some() {
            self.mbx.foe_tick(self.now_us, &mut self.rec);
        }
        if self.sm1_frame.is_none() {
            let mut out = vec![0x5Au8; self.sm1];
            let n = self.mbx.next_output(&mut out, self.now_us);
            if n > 0 {
                out.truncate(n);
                self.last_handed = Some(out.clone());
                self.sm1_frame = Some(out);
            }
        }
    }

    /// The master writes `frame` into SM0 (the whole buffer, or only its first bytes
    /// over the previous contents); the runtime reads the header and the bytes it
    /// announces (`receive_mailbox`), serves the request with the handler of its
    /// protocol, then polls. Returns whether the documented rules demand an answer.
    fn send(&mut self, frame: &[u8], whole: bool) -> bool {
        let n = frame.len().min(self.sm0);
        if whole {
            self.sm0_buf.fill(0);
        }
        self.sm0_buf[..n].copy_from_slice(&frame[..n]);
        let cap = self.sm0.min(MAX_MAILBOX_SIZE);
        let announced = u16::from_le_bytes([self.sm0_buf[0], self.sm0_buf[1]]) as usize;
        let req = self.sm0_buf[..(6 + announced).clamp(6, cap)].to_vec();
        let must = self.expects_answer(&req, cap);
        let (state, now) = (self.state, self.now_us);
        if req[5] & 0x0F == 4 {
            let files: &mut dyn FoeFiles = &mut self.rec;
            let h = Handlers::<ExampleDictionary>::foe(Some(files));
            self.mbx.on_request_with(&req, h, state, now);
        } else if state == EsmState::Bootstrap {
            let h = Handlers::<ExampleDictionary>::foe(None);
            self.mbx.on_request_with(&req, h, state, now);
        } else {
            self.mbx
                .on_request_with(&req, Handlers::coe(&mut self.dict), state, now);
        }
        self.poll();
        self.after_request();
        must
    }

    /// Whether the server must answer `req` (as the runtime hands it over), from the
    /// documented rules; follows the server's view of the last request counter.
    fn expects_answer(&mut self, req: &[u8], cap: usize) -> bool {
        let counter = (req[5] >> 4) & 7;
        if counter != 0 && self.last_in == Some(counter) {
            return false; // a repetition: answered again only if an answer exists
        }
        self.last_in = Some(counter);
        let len = u16::from_le_bytes([req[0], req[1]]) as usize;
        let t = req[5] & 0x0F;
        if len == 0 || t == 0 || 6 + len > cap || req[4] & 0x3F != 0 {
            return true; // mailbox errors
        }
        if t == 3 && self.state == EsmState::PreOp {
            return false; // CoE: coe_fuzz.rs has its rules
        }
        let p = &req[6..6 + len];
        if t != 4 || p.len() < foe::HEADER_LEN {
            return true;
        }
        match p[0] {
            // ERR from the master: a silent abort.
            5 => false,
            // The ACK of a read's last DATA ends the transfer silently.
            4 => self.mbx.foe_active() != Some(foe::Direction::Read),
            _ => true,
        }
    }

    /// The master reads SM1 if something is there (then the runtime refills it at
    /// its next poll).
    fn read(&mut self) -> Option<Answer> {
        let f = self.sm1_frame.take()?;
        self.out_counter = self.out_counter % 7 + 1;
        let a = check_frame(
            &f,
            self.sm1,
            self.out_counter,
            self.state,
            self.read_segment(),
        );
        let kind = match &a {
            Answer::MailboxError(d) => {
                *self.stats.details.entry(*d).or_default() += 1;
                K_MBX_ERROR
            }
            Answer::Ack(_) => K_ACK,
            Answer::Data(..) => K_DATA,
            Answer::Err(c) => {
                *self.stats.codes.entry(*c).or_default() += 1;
                K_ERR
            }
            Answer::Busy => K_BUSY,
            Answer::Coe => K_COE,
        };
        self.stats.answers[kind] += 1;
        self.poll();
        Some(a)
    }

    /// The invariants of the backend and of the boot flash after every request.
    fn after_request(&mut self) {
        if let Some(file) = self.rec.finished.take() {
            let valid = self.files.valid.iter().find(|(_, f)| *f == file);
            let Some((version, _)) = valid else {
                panic!(
                    "an update was accepted from {} bytes that are none of the signed files",
                    file.len()
                );
            };
            assert_eq!(self.boot, Boot::Confirmed, "accepted while {:?}", self.boot);
            assert_eq!(
                self.rec.upd.take_event(),
                Some(Event::Accepted { version: *version })
            );
            self.boot = Boot::Marked { version: *version };
            self.stats.accepted += 1;
        } else if let Some(Event::Accepted { version }) = self.rec.upd.take_event() {
            panic!("Event::Accepted of {version:#x} without a finished transfer");
        }
        let marked = matches!(self.boot, Boot::Marked { .. });
        assert_eq!(
            self.rec.upd.accepted(),
            marked,
            "Update::accepted() vs {:?}",
            self.boot
        );
        let want = if self.boot == Boot::Confirmed {
            State::Boot
        } else {
            State::Swap
        };
        assert_eq!(
            self.fl.state(),
            want,
            "embassy-boot state in {:?}",
            self.boot
        );
    }

    /// The drive restarts (reset after an update, watchdog, power): embassy-boot's
    /// `prepare_boot`, the firmware's update built anew, the runtime in Init.
    fn power_cycle(&mut self) {
        self.stats.power_cycles += 1;
        let st = self.fl.boot();
        match self.boot {
            Boot::Confirmed => assert_eq!(st, State::Boot, "nothing to swap"),
            Boot::Marked { version } => {
                assert_eq!(st, State::Swap, "the accepted update is swapped in");
                assert!(self.fl.active_starts_with(&self.files.images[&version]));
                self.boot = Boot::Trial {
                    version,
                    prev: self.running,
                };
                self.running = Some(version);
                self.stats.swaps += 1;
            }
            Boot::Trial { prev, .. } => {
                // Not confirmed: reverted (embassy-boot reports it as the swap state).
                assert_eq!(st, State::Swap, "revert");
                self.boot = Boot::Confirmed;
                self.running = prev;
                self.stats.reverts += 1;
            }
        }
        self.rec.upd = Box::new(self.fl.update());
        self.rec.open = None;
        assert_eq!(
            self.rec.upd.running_version(),
            self.running,
            "running version"
        );
        match self.boot {
            Boot::Trial { .. } => {
                assert_eq!(
                    self.rec.upd.boot_state(),
                    firmware::update::BootState::Trial
                )
            }
            _ => {
                // A reverted image confirmed itself at once.
                assert_ne!(
                    self.rec.upd.boot_state(),
                    firmware::update::BootState::Trial
                );
                let _ = self.rec.upd.take_event();
            }
        }
        self.mbx = MailboxServer::new(self.sm1);
        self.mbx.set_foe_timeout_us(self.foe_timeout_us);
        self.state = EsmState::Init;
        self.mailbox_stopped();
        self.after_request();
    }

    fn mailbox_stopped(&mut self) {
        self.sm1_frame = None;
        self.last_handed = None;
        self.last_in = None;
        self.out_counter = 0;
        self.belief = Belief::default();
    }

    /// An ESM transition as the runtime makes it (`state_changed`, `activate_mailbox`)
    /// and the drive's hooks: the reset after an accepted update on Bootstrap → Init,
    /// the confirmation of a trial image in Pre-Op.
    fn set_state(&mut self, to: EsmState) {
        let from = self.state;
        if from == to {
            return;
        }
        self.stats.state_changes += 1;
        if from.mailbox_running() && !to.mailbox_running() {
            self.mbx.foe_abort(&mut self.rec);
            self.mbx.reset();
            self.mailbox_stopped();
        }
        if !from.mailbox_running() && to.mailbox_running() {
            self.mbx.set_mailbox_sizes(self.sm0, self.sm1);
            self.mailbox_stopped();
        }
        self.state = to;
        if from == EsmState::Bootstrap && self.rec.upd.accepted() {
            self.power_cycle();
            return;
        }
        if to == EsmState::PreOp && self.rec.upd.confirm(true, true) {
            let Boot::Trial { version, .. } = self.boot else {
                panic!("confirmed while {:?}", self.boot)
            };
            assert_eq!(
                self.rec.upd.take_event(),
                Some(Event::Confirmed { version })
            );
            self.boot = Boot::Confirmed;
        }
        self.after_request();
    }

    /// Via Init, as the ESM allows.
    fn go(&mut self, to: EsmState) {
        if self.state != to {
            self.set_state(EsmState::Init);
            self.set_state(to);
        }
    }

    /// Time passes; the runtime polls on its own.
    fn time_step(&mut self, r: &mut Rng) {
        self.now_us += r.below(20_000) as u64;
        if r.chance(8) {
            self.now_us += self.foe_timeout_us + 1 + r.below(20_000_000) as u64;
            self.stats.timeouts += 1;
            self.poll();
            self.after_request();
        }
    }

    /// Wraps a FoE (or other) payload into a mailbox frame.
    fn mailbox(&mut self, r: &mut Rng, payload: &[u8], mutate_header: bool) -> Vec<u8> {
        let mut len = payload.len() as u16;
        let mut t = 4u8;
        let mut ch = 0u8;
        if mutate_header {
            match r.below(12) {
                0 => len = r.next() as u16,
                1 => len = len.saturating_add(1 + r.below(8) as u16),
                2 => len = 0,
                3 => t = r.byte() & 0x0F,
                4 => t = *r.pick(&[0u8, 1, 2, 3, 5, 15]),
                5 => ch = 1 + r.byte() % 63,
                _ => {}
            }
        }
        // Counters: mostly the next one, sometimes a repetition or "no counter".
        let counter = match r.below(1000) {
            0..=11 => 0,
            12..=24 => self.counter,
            _ => self.next_counter(),
        };
        let mut f = vec![0u8; 6];
        f[0..2].copy_from_slice(&len.to_le_bytes());
        if r.chance(30) {
            f[2..4].copy_from_slice(&(r.next() as u16).to_le_bytes());
        }
        // Priority bits (7:6) are allowed; the channel must be 0.
        let priority = if r.chance(30) { r.byte() & 0xC0 } else { 0 };
        f[4] = ch | priority;
        f[5] = t | (counter << 4);
        f.extend_from_slice(payload);
        f
    }

    /// Updates the master's belief from an answer.
    fn learn(&mut self, a: &Answer) {
        match a {
            Answer::Ack(n) => {
                self.belief.write_next = Some(n.wrapping_add(1));
                self.belief.read_last = None;
            }
            Answer::Busy => {}
            Answer::Data(n, data) => {
                self.belief.write_next = None;
                self.belief.read_last = Some(*n);
                // The file as read, while its DATA came in order from the first.
                match self.read_next {
                    _ if *n == 1 => self.read_bytes.clear(),
                    Some(k) if k == *n => {}
                    _ => {
                        self.read_next = None;
                        return;
                    }
                }
                self.read_bytes.extend_from_slice(data);
                self.read_next = Some(n + 1);
                if data.len() < self.read_segment() {
                    self.read_next = None;
                    let t = String::from_utf8_lossy(&self.read_bytes);
                    assert!(
                        t.starts_with("vendor=0x")
                            && t.contains("\nesc=lan9252\n")
                            && t.contains("\nboot=")
                            && t.ends_with('\n'),
                        "information file: {t}"
                    );
                    self.stats.reads_completed += 1;
                }
            }
            Answer::Err(_) => self.belief = Belief::default(),
            Answer::MailboxError(_) | Answer::Coe => {}
        }
    }

    /// One random FoE payload: mostly a follow-up of the transfer the master
    /// believes open (so the random stream gets deep into transfers), else anything.
    fn random_foe(&mut self, r: &mut Rng) -> Vec<u8> {
        let class = if self.belief.write_next.is_some() && r.chance(600) {
            40
        } else if self.belief.read_last.is_some() && r.chance(600) {
            70
        } else if self.belief.write_next.is_none() && self.belief.read_last.is_none() {
            // No transfer open: requests more often, stray DATA / ACK less.
            *r.pick(&[
                0, 0, 0, 5, 5, 10, 10, 13, 14, 17, 20, 22, 30, 40, 50, 60, 67, 72, 77, 82, 86, 88,
                91, 93, 96, 98,
            ])
        } else {
            r.below(100)
        };
        self.foe_payload(r, class)
    }

    /// A FoE payload of the class `class` (0…99).
    fn foe_payload(&mut self, r: &mut Rng, class: usize) -> Vec<u8> {
        let seg = self.segment();
        let mut p = Vec::new();
        match class {
            // WRQ, with the file the DATA that follow will mostly be slices of.
            0..=13 => {
                p.extend_from_slice(&[2, 0]);
                let pw = if r.chance(850) { 0 } else { r.next() as u32 };
                p.extend_from_slice(&pw.to_le_bytes());
                name(r, &mut p);
                self.belief.file = r.below(self.files.valid.len());
            }
            // RRQ.
            14..=21 => {
                p.extend_from_slice(&[1, 0]);
                let pw = if r.chance(900) { 0 } else { r.next() as u32 };
                p.extend_from_slice(&pw.to_le_bytes());
                if r.chance(700) {
                    p.extend_from_slice(INFO_FILE);
                } else {
                    name(r, &mut p);
                }
            }
            // DATA.
            22..=66 => {
                let next = self.belief.write_next.unwrap_or(1);
                let n = match r.below(10) {
                    0..=5 => next,
                    6 => next.wrapping_sub(1),
                    7 => next.wrapping_add(1 + r.below(4) as u32),
                    8 => 0,
                    _ => r.next() as u32,
                };
                p.push(3);
                p.push(if r.chance(980) { 0 } else { r.byte() });
                p.extend_from_slice(&n.to_le_bytes());
                let len = match r.below(10) {
                    0..=5 => seg,
                    6 => 0,
                    7 => seg - 1,
                    8 => seg + 1 + r.below(40),
                    _ => r.below(seg + 1),
                };
                match r.below(10) {
                    // The slice of the WRQ's file (sometimes another one) where this
                    // packet sits: the header passes and the flash paths run; a file
                    // sent like this to its end is a valid update.
                    0..=6 => {
                        let k = if r.chance(900) {
                            self.belief.file
                        } else {
                            r.below(self.files.valid.len())
                        };
                        let f = &self.files.valid[k].1;
                        let at = (n.saturating_sub(1) as usize).saturating_mul(seg);
                        let s = f.get(at.min(f.len())..).unwrap_or(&[]);
                        let len = if r.chance(800) { seg } else { len };
                        p.extend_from_slice(&s[..len.min(s.len())]);
                        if r.chance(50) && p.len() > 6 {
                            let k = 6 + r.below(p.len() - 6);
                            p[k] ^= 1 << r.below(8);
                        }
                    }
                    7 => p.extend(std::iter::repeat_n(0, len)),
                    _ => p.extend((0..len).map(|_| r.byte())),
                }
            }
            // ACK from the master.
            67..=76 => {
                let n = match (self.belief.read_last, r.below(10)) {
                    (Some(k), 0..=6) => k,
                    (Some(k), 7) => k.wrapping_add(1),
                    (_, 8) => 0,
                    _ => r.below(5) as u32,
                };
                p.extend_from_slice(&[4, 0]);
                p.extend_from_slice(&n.to_le_bytes());
                if r.chance(100) {
                    p.extend((0..r.below(10)).map(|_| r.byte()));
                }
            }
            // ERR from the master (an abort).
            77..=81 => {
                let code = if r.chance(700) {
                    r.pick(ErrorCode::ALL).code()
                } else {
                    r.next() as u32
                };
                p.extend_from_slice(&[5, 0]);
                p.extend_from_slice(&code.to_le_bytes());
                p.extend((0..r.below(30)).map(|_| b' ' + r.byte() % 90));
            }
            // BUSY from the master.
            82..=85 => {
                p.extend_from_slice(&[6, 0, r.byte(), 0, 100, 0]);
                p.extend((0..r.below(10)).map(|_| r.byte()));
            }
            // A truncated FoE header.
            86..=90 => {
                let any = r.byte();
                let op = *r.pick(&[1u8, 2, 3, 4, 5, 6, any]);
                p.push(op);
                p.extend((0..r.below(5)).map(|_| r.byte()));
                p.truncate(r.below(6));
            }
            // Unknown opcodes.
            91..=95 => {
                let any = r.byte();
                let op = *r.pick(&[0u8, 7, 8, 0x83, 0xFF, any]);
                p.push(op);
                p.push(0);
                p.extend((0..4 + r.below(20)).map(|_| r.byte()));
            }
            // Random bytes.
            _ => p.extend((0..r.below(seg + 20)).map(|_| r.byte())),
        }
        if r.chance(60) {
            mutate(r, &mut p);
        }
        p
    }

    /// One random frame, served, maybe read.
    fn random_step(&mut self, r: &mut Rng) {
        let frame = if r.chance(20) {
            // A CoE SDO upload (of 0x1000 or another index) between the FoE
            // requests: served in Pre-Op, a protocol error in Bootstrap.
            let c = self.next_counter();
            let i = if r.chance(700) {
                0x1000u16
            } else {
                r.next() as u16
            };
            let [i0, i1] = i.to_le_bytes();
            vec![
                10,
                0,
                0,
                0,
                0,
                3 | c << 4,
                0x00,
                0x20,
                0x40,
                i0,
                i1,
                0,
                0,
                0,
                0,
                0,
            ]
        } else {
            let payload = self.random_foe(r);
            let mutate_header = r.chance(80);
            self.mailbox(r, &payload, mutate_header)
        };
        let sm1_free = self.sm1_frame.is_none();
        self.stats.random_frames += 1;
        let must = self.send(&frame, !r.chance(20)) && sm1_free;
        // Sometimes the master is slow: the next request comes before it read SM1.
        if r.chance(30) {
            return;
        }
        match self.read() {
            Some(a) => {
                self.stats.checked_answers += u64::from(must);
                self.learn(&a);
                // The repeat request hands out the same frame again.
                if r.chance(20) {
                    let mut again = vec![0u8; self.sm1];
                    let n = self.mbx.repeat_last(&mut again);
                    let last = self.last_handed.as_deref().unwrap_or(&[]);
                    assert_eq!(&again[..n], last, "repeat");
                    self.stats.repeats += 1;
                }
            }
            None => assert!(
                !must,
                "request without answer: {:02x?}",
                &frame[..frame.len().min(24)]
            ),
        }
    }

    /// A mailbox frame that does not touch the FoE transfer: a protocol without a
    /// handler in Bootstrap, a wrong channel, a zero length, type 0 from the master,
    /// or a repetition (same counter) of the last request. Its answer is read and
    /// dropped.
    fn harmless(&mut self, r: &mut Rng, last: &[u8]) {
        let f = match r.below(5) {
            0 => last.to_vec(),
            k => {
                let c = self.next_counter();
                let mut f = vec![10u8, 0, 0, 0, 0, 0];
                f.extend((0..10).map(|_| r.byte()));
                match k {
                    1 => f[5] = (*r.pick(&[1u8, 2, 3, 5, 15])) | c << 4,
                    2 => f[4..6].copy_from_slice(&[1 + r.byte() % 63, 4 | c << 4]),
                    3 => f[0..6].copy_from_slice(&[0, 0, 0, 0, 0, 4 | c << 4]),
                    _ => f[5] = c << 4,
                }
                f
            }
        };
        self.send(&f, true);
        while self.read().is_some() {}
    }

    /// One FoE request of a transfer and its answer (the master waits for it);
    /// with `disturb`, sometimes a harmless frame after it.
    fn foe_exchange(&mut self, r: &mut Rng, payload: &[u8], disturb: bool) -> Answer {
        let c = self.next_counter();
        let mut f = vec![0u8; 6];
        f[0..2].copy_from_slice(&(payload.len() as u16).to_le_bytes());
        f[5] = 4 | c << 4;
        f.extend_from_slice(payload);
        self.stats.injection_frames += 1;
        assert!(self.send(&f, true), "a transfer's request is answered");
        let a = self
            .read()
            .expect("an answer to each FoE request of a transfer");
        if disturb && r.chance(40) {
            self.harmless(r, &f);
        }
        a
    }

    /// Sends `file` as a master does (WRQ, DATA of the segment size each repeated
    /// after BUSY, an empty DATA after a file of whole segments); with `disturb`,
    /// harmless frames in between and sometimes one that ends the transfer (a random
    /// FoE frame, a timeout). Returns `Ok(())` when the last DATA was acknowledged,
    /// `Err(Some(code))` for an ERR, `Err(None)` for an ERR after the transfer was
    /// broken off.
    fn inject(&mut self, r: &mut Rng, file: &[u8], disturb: bool) -> Result<(), Option<u32>> {
        while self.read().is_some() {}
        let seg = self.segment();
        let mut p = vec![2u8, 0, 0, 0, 0, 0];
        p.extend_from_slice(b"ecs-lan9252.efw");
        match self.foe_exchange(r, &p, disturb) {
            Answer::Ack(0) => {}
            Answer::Err(c) => return Err(Some(c)),
            a => panic!("WRQ answered {a:?}"),
        }
        let mut chunks: Vec<&[u8]> = file.chunks(seg).collect();
        if file.len().is_multiple_of(seg) {
            chunks.push(&[]);
        }
        let mut broken = false;
        for (i, c) in chunks.iter().enumerate() {
            let n = i as u32 + 1;
            let mut p = vec![3u8, 0];
            p.extend_from_slice(&n.to_le_bytes());
            p.extend_from_slice(c);
            let mut busy = 0;
            loop {
                if disturb && r.chance(6) {
                    if r.chance(300) {
                        self.now_us += self.foe_timeout_us + 1;
                        self.poll();
                        self.after_request();
                    } else {
                        let q = self.random_foe(r);
                        let f = self.mailbox(r, &q, false);
                        self.send(&f, true);
                        while self.read().is_some() {}
                    }
                    // Intact when the server still waits for this DATA and the
                    // backend has taken exactly the bytes before it (a refused or
                    // BUSY-answered frame, a repetition, a WRQ that restarted a
                    // transfer at its start leave it so).
                    let intact = self.mbx.foe_active() == Some(foe::Direction::Write)
                        && self.rec.open == Some(foe::Direction::Write)
                        && self.rec.taken.len() == i * seg;
                    broken |= !intact;
                }
                self.now_us += r.below(2_000) as u64;
                match self.foe_exchange(r, &p, disturb) {
                    Answer::Ack(k) if k == n && !broken => break,
                    Answer::Busy => {
                        busy += 1;
                        assert!(busy < 50, "BUSY for ever");
                    }
                    Answer::Err(_) if broken => return Err(None),
                    Answer::Err(code) => return Err(Some(code)),
                    a => panic!(
                        "DATA {n} of {} answered {a:?} (broken off: {broken})",
                        chunks.len()
                    ),
                }
            }
        }
        Ok(())
    }

    /// A random injection in Bootstrap, with its expected outcome checked.
    fn random_injection(&mut self, r: &mut Rng) {
        let (version, good) = r.pick(&self.files.valid).clone();
        let kind = *r.pick(&[
            "valid",
            "valid",
            "valid",
            "tampered image",
            "tampered header",
            "truncated",
            "other ESC",
        ]);
        let file = match kind {
            "tampered image" => {
                let mut f = good.clone();
                let k = efw::HEADER_LEN + r.below(f.len() - efw::HEADER_LEN);
                f[k] ^= 1 << r.below(8);
                f
            }
            "tampered header" => {
                let mut f = good.clone();
                let k = r.below(efw::HEADER_LEN);
                f[k] ^= 1 << r.below(8);
                f
            }
            "truncated" => good[..efw::HEADER_LEN + r.below(good.len() - efw::HEADER_LEN)].to_vec(),
            "other ESC" => self.files.foreign.clone(),
            _ => good.clone(),
        };
        let disturb = r.chance(300);
        let before = self.boot;
        let res = self.inject(r, &file, disturb);
        let outcome: &'static str = match (&res, before) {
            (Err(None), _) => "broken",
            (Err(Some(c)), Boot::Trial { .. }) => {
                assert_eq!(*c, ErrorCode::AccessDenied.code(), "{kind} on trial");
                "refused on trial"
            }
            (Ok(()), Boot::Confirmed) => {
                assert_eq!(kind, "valid", "a {kind} file was accepted");
                assert_eq!(self.boot, Boot::Marked { version });
                "accepted"
            }
            (Err(Some(c)), Boot::Confirmed) => {
                let want: &[ErrorCode] = match kind {
                    "tampered image" => &[ErrorCode::InvalidChecksum],
                    "truncated" => &[ErrorCode::ProgramError],
                    "other ESC" => &[ErrorCode::FirmwareNotForHardware],
                    "tampered header" => &[
                        ErrorCode::InvalidChecksum,
                        ErrorCode::FirmwareNotForHardware,
                        ErrorCode::DiskFull,
                        ErrorCode::ProgramError,
                    ],
                    _ => panic!("a valid file was refused with {c:#x}"),
                };
                assert!(
                    want.iter().any(|w| w.code() == *c),
                    "{kind}: ERR {c:#x}, expected {want:?}"
                );
                "refused"
            }
            (r, b) => panic!("{kind}: {r:?} while {b:?}"),
        };
        *self
            .stats
            .injections
            .entry(format!("{kind}: {outcome}"))
            .or_default() += 1;
        self.after_download(r);
    }

    /// After a successful download the master's next step is Bootstrap → Init (the
    /// drive resets into the bootloader: swap, trial); then mostly Pre-Op (the new
    /// image confirms itself), sometimes a reset before that (reverted), or more
    /// fuzzing on trial.
    fn after_download(&mut self, r: &mut Rng) {
        if !self.rec.upd.accepted() {
            return;
        }
        self.set_state(EsmState::Init);
        match r.below(10) {
            0..=5 => self.set_state(EsmState::PreOp),
            6 | 7 => self.power_cycle(),
            _ => {}
        }
    }

    /// `steps` random frames with everything else in between.
    fn fuzz(&mut self, r: &mut Rng, steps: u64) {
        self.go(EsmState::Bootstrap);
        while self.stats.random_frames < steps {
            self.time_step(r);
            if self.state == EsmState::Init {
                // No mailbox in Init: the master's next step is a state request.
                let to = if r.chance(750) {
                    EsmState::Bootstrap
                } else {
                    EsmState::PreOp
                };
                self.set_state(to);
                continue;
            }
            if r.chance(5) {
                self.set_state(EsmState::Init);
                continue;
            }
            if r.chance(1) {
                self.power_cycle();
                continue;
            }
            if self.state == EsmState::Bootstrap && r.chance(7) {
                self.random_injection(r);
                continue;
            }
            self.random_step(r);
            if self.rec.upd.accepted() {
                // The random stream itself sent a whole valid file.
                self.stats.accepted_from_stream += 1;
                self.after_download(r);
            }
        }
        self.stats.backend_busy = self.rec.busy;
        self.stats.backend_aborts = self.rec.aborts;
    }

    /// After the fuzzing: a clean download still works, swaps and confirms.
    fn clean_update(&mut self, r: &mut Rng) {
        // A trial image confirms itself in Pre-Op first (else no update is taken).
        self.go(EsmState::PreOp);
        assert_eq!(self.boot, Boot::Confirmed);
        self.go(EsmState::Bootstrap);
        let (version, file) = self.files.valid[self.files.valid.len() - 1].clone();
        self.inject(r, &file, false)
            .expect("a clean download after the fuzzing");
        assert_eq!(self.boot, Boot::Marked { version });
        self.set_state(EsmState::Init);
        assert!(
            matches!(self.boot, Boot::Trial { version: v, .. } if v == version),
            "{:?}",
            self.boot
        );
        assert_eq!(self.rec.upd.running_version(), Some(version));
        self.set_state(EsmState::PreOp);
        assert_eq!(self.boot, Boot::Confirmed);
        assert_eq!(self.fl.state(), State::Boot);
        self.power_cycle();
        assert_eq!(
            self.running,
            Some(version),
            "the update stays after a reset"
        );
    }
}

fn mutate(r: &mut Rng, p: &mut Vec<u8>) {
    for _ in 0..1 + r.below(3) {
        match r.below(5) {
            0 if !p.is_empty() => {
                let k = r.below(p.len());
                p[k] ^= 1 << r.below(8);
            }
            1 if !p.is_empty() => {
                let k = r.below(p.len());
                p[k] = r.byte();
            }
            2 => p.truncate(r.below(p.len() + 1)),
            3 => p.extend((0..r.below(20)).map(|_| r.byte())),
            _ => {}
        }
    }
}

/// One mailbox configuration, fuzzed.
fn run(sm0: usize, sm1: usize, steps: u64, seed_no: u64) -> Stats {
    let mut r = Rng(0x9E37_79B9_7F4A_7C15 ^ seed_no.wrapping_mul(0x1234_5678_9ABC_DEF1));
    let fl = Flashes::new();
    let sm0_seg = sm0.min(256) - foe::OVERHEAD;
    let files = Files::new(sm0_seg, seed_no as u8);
    let mut w = World::new(&fl, &files, sm0, sm1);
    w.fuzz(&mut r, steps);
    w.clean_update(&mut r);
    w.stats
}

#[test]
fn random_and_mutated_foe_frames_never_update_and_get_well_formed_answers() {
    let t0 = std::time::Instant::now();
    // (SM0, SM1, random frames): the product's boot mailbox first; a large one; a
    // small one; SM1 shorter than SM0 (reads refused); SM0 shorter than SM1.
    let configs: [(usize, usize, u64); 5] = [
        (128, 128, 100_000),
        (256, 256, 50_000),
        (64, 64, 50_000),
        (128, 64, 50_000),
        (48, 128, 50_000),
    ];
    let results: Vec<(usize, usize, Stats)> = std::thread::scope(|s| {
        let handles: Vec<_> = configs
            .iter()
            .enumerate()
            .map(|(k, &(sm0, sm1, steps))| {
                std::thread::Builder::new()
                    .stack_size(16 << 20)
                    .spawn_scoped(s, move || (sm0, sm1, run(sm0, sm1, steps, k as u64 + 1)))
                    .expect("thread")
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    });
    let mut total = Stats::default();
    for (sm0, sm1, st) in &results {
        println!(
            "SM0 {sm0:3} / SM1 {sm1:3}: {} random + {} injection frames, answers {:?}, \
             accepted {}, swaps {}, reverts {}",
            st.random_frames, st.injection_frames, st.answers, st.accepted, st.swaps, st.reverts
        );
        total.add(st);
    }
    let kinds: Vec<String> = KIND_NAMES
        .iter()
        .zip(total.answers)
        .map(|(n, c)| format!("{n} {c}"))
        .collect();
    println!(
        "{} random frames, {} injection frames, {} answers checked as due; answers by kind: {}",
        total.random_frames,
        total.injection_frames,
        total.checked_answers,
        kinds.join(", ")
    );
    println!("mailbox error details: {:?}", total.details);
    let codes: Vec<String> = total
        .codes
        .iter()
        .map(|(c, n)| {
            format!(
                "{c:#06x} {} {n}",
                ErrorCode::from_code(*c).map_or("?", |e| e.text())
            )
        })
        .collect();
    println!("FoE ERR codes: {}", codes.join(", "));
    println!("injections: {:?}", total.injections);
    println!(
        "{} accepted ({} from the random stream), {} swaps, {} reverts, {} power cycles, {} ESM changes, {} timeouts, \
         {} repeat requests, {} information file reads, backend: {} BUSY, {} aborts; {:.1} s",
        total.accepted,
        total.accepted_from_stream,
        total.swaps,
        total.reverts,
        total.power_cycles,
        total.state_changes,
        total.timeouts,
        total.repeats,
        total.reads_completed,
        total.backend_busy,
        total.backend_aborts,
        t0.elapsed().as_secs_f64()
    );
    assert!(
        total.random_frames >= 100_000,
        "{} frames",
        total.random_frames
    );
    // Every kind of FoE answer and mailbox errors in volume (CoE answers come only
    // from the few other-type frames in Pre-Op).
    for (k, n) in KIND_NAMES.iter().zip(total.answers).take(K_COE) {
        assert!(n > 200, "{k}: {n}");
    }
    // The fuzzer reaches the deep states: the codes of the header checks, the
    // verification, the packet rules, the state and name checks.
    for c in [
        ErrorCode::NotFound,
        ErrorCode::AccessDenied,
        ErrorCode::Illegal,
        ErrorCode::PacketNumber,
        ErrorCode::BootstrapOnly,
        ErrorCode::NoRights,
        ErrorCode::ProgramError,
        ErrorCode::InvalidChecksum,
        ErrorCode::FirmwareNotForHardware,
    ] {
        assert!(
            total.codes.get(&c.code()).is_some_and(|&n| n > 10),
            "{c:?}: {:?}",
            total.codes
        );
    }
    for d in [2u16, 3, 5, 6, 8] {
        assert!(
            total.details.get(&d).is_some_and(|&n| n > 10),
            "detail {d}: {:?}",
            total.details
        );
    }
    assert!(total.accepted >= 20, "{} accepted", total.accepted);
    assert!(
        total.swaps >= 10 && total.reverts >= 3,
        "{} swaps {} reverts",
        total.swaps,
        total.reverts
    );
    assert!(
        total.reads_completed > 50,
        "{} reads",
        total.reads_completed
    );
}

/// Sends `file` straight to the backend as the FoE server would (116-byte DATA,
/// each again after BUSY).
fn send_file(u: &mut dyn FoeFiles, file: &[u8]) -> Result<(), ErrorCode> {
    u.open_write(b"ecs-lan9252.efw", 0, true)?;
    let mut off = 0u32;
    for c in file.chunks(116) {
        let mut busy = 0;
        loop {
            match u.write(off, c) {
                WriteStatus::Done => break,
                WriteStatus::Busy { .. } => busy += 1,
                WriteStatus::Err(e) => return Err(e),
            }
            assert!(busy < 50, "BUSY for ever");
        }
        off += c.len() as u32;
    }
    u.finish_write()
}

/// Found by this fuzzer's invariant "`Update::accepted()` while an update is marked":
/// a second download in the same Bootstrap, after one was accepted, is taken
/// (`open_write` only asks whether the *running* image is confirmed): it clears
/// `accepted()`, so Bootstrap → Init no longer resets the drive, and it erases and
/// rewrites the DFU partition while embassy-boot's state still says "swap". Its
/// `finish_write` is refused (embassy-boot's `verify_and_mark_updated` sees the
/// swap state: 0x8002) before any signature check — and the next power-up swaps in
/// the second image, never verified: here one with a valid header and a changed
/// image byte. A master that retries a download whose last ACK it missed gets the
/// same: an error, no reset, the image swapped in at some later power-up.
#[test]
fn a_second_download_after_an_accepted_one_cannot_smuggle_an_unverified_image() {
    let fl = Flashes::new();
    let files = Files::new(116, 7);
    let (_, first) = &files.valid[3];
    let (second_version, second) = &files.valid[4];
    let mut forged = second.clone();
    forged[efw::HEADER_LEN + 100] ^= 0x01;
    let mut u = fl.update();
    assert_eq!(send_file(&mut u, first), Ok(()), "the first download");
    assert!(FirmwareUpdate::accepted(&u));
    assert_eq!(fl.state(), State::Swap);
    // The same Bootstrap: a second download, of a forged image.
    let r = send_file(&mut u, &forged);
    assert!(r.is_err(), "the forged image is refused: {r:?}");
    assert!(
        FirmwareUpdate::accepted(&u),
        "the first update still waits for its reset on Bootstrap → Init"
    );
    drop(u);
    // The next power-up.
    assert_eq!(fl.boot(), State::Swap);
    let forged_image = &forged[efw::HEADER_LEN..];
    assert!(
        !fl.active_starts_with(forged_image),
        "the forged image (version {second_version:#x}, its signature never checked) \
         was swapped in"
    );
}

/// The FoE server hands the backend the data of a DATA resent after BUSY as it
/// comes (a master may send other bytes the second time): the backend must check the
/// header it takes, not the one it saw before the BUSY. The fuzzer above reaches this
/// through the mailbox (a bit of the header changed in the resend after the header
/// page's erase, a one-byte image in a 256-byte mailbox); here the fields one by one:
/// the header signature, the version, the product code, the ESC. Taken unchecked,
/// each would let a genuinely signed image run under a header its signature does not
/// cover (the image signature, all that is left, still verifies).
#[test]
fn a_header_changed_in_the_data_resent_after_busy_is_refused() {
    let files = Files::new(244, 3);
    // A one-byte image: header and image in one DATA (a 256-byte mailbox).
    let (_, good) = &files.valid[0];
    assert_eq!(good.len(), efw::HEADER_LEN + 1);
    for (what, at, flip) in [
        ("header signature", 99usize, 0x02u8),
        ("version", 21, 0x02),
        ("product code", 12, 0x02),
        ("ESC (LAN9252 → ET1100)", 16, 0x03),
    ] {
        let fl = Flashes::new();
        let mut u = fl.update();
        u.open_write(b"ecs-lan9252.efw", 0, true).unwrap();
        assert!(
            matches!(u.write(0, good), WriteStatus::Busy { .. }),
            "{what}: a valid header is answered BUSY first (its page is erased)"
        );
        let mut changed = good.clone();
        changed[at] ^= flip;
        let mut busy = 0;
        let end = loop {
            match u.write(0, &changed) {
                WriteStatus::Done => break u.finish_write(),
                WriteStatus::Busy { .. } => busy += 1,
                WriteStatus::Err(e) => break Err(e),
            }
            assert!(busy < 50, "BUSY for ever");
        };
        assert!(end.is_err(), "{what} changed after BUSY: accepted");
        assert!(!FirmwareUpdate::accepted(&u), "{what}");
        assert_eq!(fl.state(), State::Boot, "{what}: nothing marked");
    }
}
