//! Benchmark rows of a firmware update over FoE: from `MailboxServer::on_request_with`
//! (a whole 128-byte boot-mailbox SM0 buffer holding one FoE DATA) to the answer
//! written by `next_output`, through the product's backend (`firmware::update`) over
//! embassy-boot's updater on RAM partitions with the STM32G4's 2 KiB pages. The flash
//! is a RAM copy here: on the board the program time of the flash adds to these rows
//! (BENCHMARKS.md works the update time out from both).
//!
//! The update file (a 4 KiB image, signed with the development key) is made on the
//! host by build.rs.

use core::cell::RefCell;
use core::hint::black_box;

use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::foe::{Frame, Repr};
use ecat_slave_stack::mailbox::{Handlers, MailboxServer};
use ecat_slave_stack::od::{Dictionary, Object, ObjectKey, SdoAbort};
use embassy_embedded_hal::flash::partition::BlockingPartition;
use embassy_sync::blocking_mutex::{raw::NoopRawMutex, Mutex};
use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash};
use firmware::flash_layout::{ACTIVE, BOOT_STATE, DFU, PAGE};
use firmware::update::{EmbassyUpdater, Update};

/// The signed update file (build.rs).
static FILE: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/bench.efw"));

/// Boot state, active and DFU partitions in one RAM flash (2 KiB pages, 8-byte
/// writes; .bss: erased by the first erase of each page).
const SIZE: usize = (BOOT_STATE.size + ACTIVE.size + DFU.size) as usize;
struct RamFlash(&'static mut [u8; SIZE]);
static mut MEM: [u8; SIZE] = [0; SIZE];

impl ErrorType for RamFlash {
    type Error = NorFlashErrorKind;
}
impl ReadNorFlash for RamFlash {
    const READ_SIZE: usize = 1;
    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        let a = offset as usize;
        let src = self
            .0
            .get(a..a + bytes.len())
            .ok_or(NorFlashErrorKind::OutOfBounds)?;
        bytes.copy_from_slice(src);
        Ok(())
    }
    fn capacity(&self) -> usize {
        SIZE
    }
}
impl NorFlash for RamFlash {
    const WRITE_SIZE: usize = 8;
    const ERASE_SIZE: usize = PAGE as usize;
    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let r = self
            .0
            .get_mut(from as usize..to as usize)
            .ok_or(NorFlashErrorKind::OutOfBounds)?;
        r.fill(0xFF);
        Ok(())
    }
    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        let a = offset as usize;
        let dst = self
            .0
            .get_mut(a..a + bytes.len())
            .ok_or(NorFlashErrorKind::OutOfBounds)?;
        dst.copy_from_slice(bytes);
        Ok(())
    }
}

struct NoDict;
impl Dictionary for NoDict {
    fn objects(&self) -> &'static [Object] {
        &[]
    }
    fn read(&mut self, _: ObjectKey, _: &mut [u8]) -> Result<usize, SdoAbort> {
        Err(SdoAbort::ObjectDoesNotExist)
    }
    fn write(&mut self, _: ObjectKey, _: &[u8], _: EsmState) -> Result<(), SdoAbort> {
        Err(SdoAbort::ObjectDoesNotExist)
    }
}

/// A 128-byte SM0 buffer holding `req` (mailbox type 4, FoE).
fn sm0(counter: u8, req: &Repr<'_>) -> [u8; 128] {
    let mut f = [0u8; 128];
    let n = req.emit(&mut Frame::new_unchecked(&mut f[6..]));
    f[0..2].copy_from_slice(&(n as u16).to_le_bytes());
    f[5] = 0x04 | (counter << 4);
    f
}

/// The FoE opcode of the answer in `out`.
fn opcode(out: &[u8]) -> u8 {
    out[6]
}

/// Packet numbers of the measured rows (116-byte DATA; the image starts at file byte
/// 160, 256-byte chunks, 2 KiB pages).
const HEADER_PACKET: u32 = 2; // completes the header: its checks, then the header page erase (BUSY)
const PLAIN_PACKET: u32 = 5; // image bytes 304..420: buffered only
const FLUSH_PACKET: u32 = 6; // completes the chunk at image byte 512: a write to the DFU

pub fn run() {
    // SAFETY: run once, the only reference to MEM.
    let mem = unsafe { &mut *core::ptr::addr_of_mut!(MEM) };
    let chip: Mutex<NoopRawMutex, RefCell<RamFlash>> = Mutex::new(RefCell::new(RamFlash(mem)));
    let part = |p: firmware::flash_layout::Partition| {
        BlockingPartition::new(&chip, p.offset - BOOT_STATE.offset, p.size)
    };
    let mut aligned = [0u8; 8];
    let updater = EmbassyUpdater::new(part(DFU), part(BOOT_STATE), part(ACTIVE), &mut aligned);
    let mut files = Update::new(
        updater,
        firmware::identity::VENDOR_ID,
        firmware::identity::BOARD_VARIANT.product_code(),
        efw::Esc::Lan9252,
    );
    let mut srv = MailboxServer::new(128);
    let mut out = [0u8; 128];
    let mut counter = 0u8;
    let mut exchange = |req: &Repr<'_>| {
        counter = counter % 7 + 1;
        let f = sm0(counter, req);
        srv.on_request_with(
            &f,
            Handlers::<NoDict>::foe(Some(&mut files)),
            EsmState::Bootstrap,
            0,
        );
        srv.next_output(&mut out, 0);
        opcode(&out)
    };
    assert_eq!(
        exchange(&Repr::Write {
            password: 0,
            name: b"bench.efw"
        }),
        4,
        "WRQ"
    );
    let seg = 116;
    let last = FILE.len().div_ceil(seg) as u32;
    // The number of the next repeat of the last DATA (its check's steps, from 1).
    let mut repeats = 1;
    for (k, data) in FILE.chunks(seg).enumerate() {
        let packet = k as u32 + 1;
        let req = Repr::Data { packet, data };
        let (name, want) = data_row(packet, last);
        if let Some(n) = name {
            let op = crate::bench(n, || exchange(black_box(&req)));
            assert_eq!(op, want, "packet {packet}");
        }
        if packet == last {
            // The image check, one step per repeat of the last DATA
            // (`firmware::update`): last chunk, header, SHA-512 of the 4 KiB image
            // (each → BUSY), the image signature and embassy-boot's mark (→ ACK).
            for (step, row, want) in CHECK_ROWS {
                while step > repeats {
                    assert_eq!(exchange(&req), 6, "check step {repeats}");
                    repeats += 1;
                }
                let op = crate::bench(row, || exchange(black_box(&req)));
                assert_eq!(op, want, "{row}");
                repeats += 1;
            }
            continue;
        }
        // The rest of the packet: sent again after BUSY (a page erase), not measured.
        loop {
            if name.is_some() && want == 4 {
                break;
            }
            let op = exchange(&req);
            if op != 6 {
                assert_eq!(op, 4, "packet {packet} acknowledged");
                break;
            }
        }
    }
    assert!(files.accepted().is_some(), "the update is accepted");
    digest_row();
}

/// The measured row of DATA packet `packet` (of `last`) and the opcode it answers
/// (4 ACK, 6 BUSY); `None` for the packets sent unmeasured.
fn data_row(packet: u32, last: u32) -> (Option<&'static str>, u8) {
    match packet {
        HEADER_PACKET => (
            Some("FoE DATA 116 B completing the header: checks (ed25519) + page erase → BUSY"),
            6,
        ),
        PLAIN_PACKET => (Some("FoE DATA 116 B, buffered (SM0 → ACK)"), 4),
        FLUSH_PACKET => (
            Some("FoE DATA 116 B with a 256 B write to the DFU (SM0 → ACK)"),
            4,
        ),
        p if p == last => (
            Some("FoE last DATA: 4 KiB image complete, taken → BUSY (the check follows)"),
            6,
        ),
        _ => (None, 0),
    }
}

/// The measured repeats of the last DATA: the check step (from 1), the row and the
/// opcode it answers.
const CHECK_ROWS: [(u32, &str, u8); 2] = [
    (
        3,
        "FoE last DATA repeat: SHA-512 of 4 KiB of image → BUSY",
        6,
    ),
    (
        4,
        "FoE last DATA repeat: ed25519 image signature + mark → ACK",
        4,
    ),
];

/// The image digest alone, on 1 KiB.
fn digest_row() {
    let img = &FILE[efw::HEADER_LEN..efw::HEADER_LEN + 1024];
    let d = crate::bench("SHA-512 of 1 KiB of image (efw::image_digest)", || {
        efw::image_digest(black_box(img))
    });
    black_box(d);
}
