extern crate std;
use super::*;
use crate::storage::PagedRamFlash;
use core::cell::RefCell;
use embassy_boot::{BootLoader, BootLoaderConfig};
use embassy_embedded_hal::flash::partition::BlockingPartition;
use embassy_sync::blocking_mutex::{raw::NoopRawMutex, Mutex};
use std::boxed::Box;
use std::vec::Vec;

const ACTIVE_SIZE: usize = flash_layout::ACTIVE.size as usize;
const DFU_SIZE: usize = flash_layout::DFU.size as usize;
const STATE_SIZE: usize = flash_layout::BOOT_STATE.size as usize;
const VENDOR: u32 = 0x0ECA;
const PRODUCT: u32 = 0x5702;

type Part<const N: usize> = Mutex<NoopRawMutex, RefCell<PagedRamFlash<N>>>;

/// The three partitions, each its own RAM flash.
struct Flashes {
    active: Part<ACTIVE_SIZE>,
    dfu: Part<DFU_SIZE>,
    state: Part<STATE_SIZE>,
}

impl Flashes {
    fn new() -> Box<Self> {
        Box::new(Flashes {
            active: Mutex::new(RefCell::new(PagedRamFlash::new())),
            dfu: Mutex::new(RefCell::new(PagedRamFlash::new())),
            state: Mutex::new(RefCell::new(PagedRamFlash::new())),
        })
    }

    fn update(&self) -> Update<impl Updater + '_> {
        self.update_with(TRUST)
    }

    fn update_with(&self, trust: Trust) -> Update<impl Updater + '_> {
        let aligned = Box::leak(Box::new([0u8; 8]));
        let u = EmbassyUpdater::new(
            BlockingPartition::new(&self.dfu, 0, DFU_SIZE as u32),
            BlockingPartition::new(&self.state, 0, STATE_SIZE as u32),
            BlockingPartition::new(&self.active, 0, ACTIVE_SIZE as u32),
            aligned,
        );
        Update::with_trust(u, VENDOR, PRODUCT, Esc::Lan9252, trust)
    }

    /// DFU bytes read and DFU byte operations (erased + programmed) so far.
    fn dfu_work(&self) -> (usize, usize) {
        self.dfu.lock(|f| {
            let f = f.borrow();
            (f.0.reads, f.0.ops)
        })
    }

    /// A reset: embassy-boot's `prepare_boot` (swap or revert).
    fn boot(&self) -> embassy_boot::State {
        let mut bl = BootLoader::new(BootLoaderConfig {
            active: BlockingPartition::new(&self.active, 0, ACTIVE_SIZE as u32),
            dfu: BlockingPartition::new(&self.dfu, 0, DFU_SIZE as u32),
            state: BlockingPartition::new(&self.state, 0, STATE_SIZE as u32),
        });
        let mut page = [0u8; flash_layout::PAGE as usize];
        bl.prepare_boot(&mut page).expect("prepare_boot")
    }

    fn active_starts_with(&self, image: &[u8]) -> bool {
        self.active
            .lock(|f| f.borrow().0.mem[..image.len()] == *image)
    }
}

fn seed() -> [u8; 32] {
    efw::sign::dev_key()
}

fn image(len: usize, salt: u8) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u8).wrapping_mul(31) ^ salt)
        .collect()
}

fn file(esc: Esc, version: u32, img: &[u8]) -> Vec<u8> {
    efw::sign::update_file(&seed(), VENDOR, PRODUCT, esc, version, img)
}

/// Sends `f` as FoE does: open, DATA of 116 bytes (repeated after BUSY), finish.
fn send(u: &mut dyn FoeFiles, f: &[u8]) -> Result<(), ErrorCode> {
    send_counting(u, f).map(|_| ())
}

/// [`send`]; returns how many BUSY answers came.
fn send_counting(u: &mut dyn FoeFiles, f: &[u8]) -> Result<usize, ErrorCode> {
    u.open_write(b"ecs-lan9252.efw", 0, true)?;
    let (mut off, mut busy) = (0, 0);
    for c in f.chunks(116) {
        loop {
            match u.write(off, c) {
                WriteStatus::Done => break,
                WriteStatus::Err(e) => return Err(e),
                WriteStatus::Busy { .. } => busy += 1,
            }
            assert!(busy < 10_000, "BUSY for ever");
        }
        off += c.len() as u32;
    }
    u.finish_write()?;
    Ok(busy)
}

#[test]
fn each_erase_is_one_busy_answer() {
    let fl = Flashes::new();
    let img = image(20_000, 9);
    // The header page, then ⌈20 000 / 2048⌉ = 10 image pages (the last one erased
    // at the finish if the last chunk is short).
    // Then the check of the complete image: taken, last chunk, header, ⌈20 000 /
    // VERIFY_STEP⌉ = 5 hash steps (the signature answers Done).
    let busy = send_counting(&mut fl.update(), &file(Esc::Lan9252, 1, &img)).unwrap();
    let check = 3 + 20_000usize.div_ceil(VERIFY_STEP as usize);
    assert!((10 + check..=11 + check).contains(&busy), "{busy}");
}

#[test]
fn the_dev_key_pair_belongs_together() {
    assert_eq!(Some(efw::sign::public_key(&seed())), PUBLIC_KEY);
}

#[test]
fn an_update_is_taken_swapped_on_trial_and_confirmed() {
    let fl = Flashes::new();
    let new = image(3000, 0x5A);
    {
        let mut u = fl.update();
        assert_eq!(u.running().header, None, "probe-rs image: no header");
        assert_eq!(u.boot_state(), BootState::Confirmed);
        assert_eq!(send(&mut u, &file(Esc::Lan9252, 0x0002_0100, &new)), Ok(()));
        assert_eq!(u.accepted().map(|h| h.version), Some(0x0002_0100));
        assert_eq!(
            u.take_event(),
            Some(Event::Accepted {
                version: 0x0002_0100
            })
        );
    }
    assert_eq!(fl.boot(), embassy_boot::State::Swap);
    assert!(fl.active_starts_with(&new));
    let mut u = fl.update();
    assert_eq!(u.boot_state(), BootState::Trial);
    assert_eq!(u.running_version(), Some(0x0002_0100));
    // No update while on trial.
    assert_eq!(
        send(&mut u, &file(Esc::Lan9252, 3, &new)),
        Err(ErrorCode::AccessDenied)
    );
    assert!(!u.confirm(true, false), "runtime not up yet");
    assert!(!u.confirm(false, true), "checks failed");
    assert!(u.confirm(true, true));
    assert_eq!(u.boot_state(), BootState::Confirmed);
    drop(u);
    assert_eq!(fl.boot(), embassy_boot::State::Boot);
    assert!(fl.active_starts_with(&new), "confirmed: stays");
}

#[test]
fn an_unconfirmed_image_is_reverted() {
    let fl = Flashes::new();
    let old = image(2000, 0x11);
    fl.active
        .lock(|f| f.borrow_mut().0.mem[..old.len()].copy_from_slice(&old));
    let new = image(2500, 0x77);
    assert_eq!(send(&mut fl.update(), &file(Esc::Lan9252, 9, &new)), Ok(()));
    assert_eq!(fl.boot(), embassy_boot::State::Swap);
    assert!(fl.active_starts_with(&new));
    // Reset before the confirmation: reverted.
    assert_eq!(fl.boot(), embassy_boot::State::Swap);
    assert!(fl.active_starts_with(&old));
    let mut u = fl.update();
    assert_eq!(u.boot_state(), BootState::Reverted);
    assert_eq!(u.take_event(), Some(Event::Reverted));
    assert_eq!(u.running_version(), None);
    drop(u);
    assert_eq!(fl.boot(), embassy_boot::State::Boot, "confirmed itself");
    assert!(fl.active_starts_with(&old));
}

#[test]
fn bad_images_are_refused_and_the_running_image_stays() {
    let fl = Flashes::new();
    let img = image(1500, 3);
    let good = file(Esc::Lan9252, 5, &img);
    let mut tampered = good.clone();
    tampered[HEADER_LEN + 700] ^= 1;
    let other_key = efw::sign::update_file(&[1; 32], VENDOR, PRODUCT, Esc::Lan9252, 5, &img);
    let other_product = efw::sign::update_file(&seed(), VENDOR, 0x9999, Esc::Lan9252, 5, &img);
    let big = file(
        Esc::Lan9252,
        5,
        &image(flash_layout::IMAGE_MAX as usize + 8, 0),
    );
    let cases: [(&str, Vec<u8>, ErrorCode); 7] = [
        (
            "other ESC",
            file(Esc::Et1100, 5, &img),
            ErrorCode::FirmwareNotForHardware,
        ),
        (
            "other product",
            other_product,
            ErrorCode::FirmwareNotForHardware,
        ),
        ("other key", other_key, ErrorCode::InvalidChecksum),
        ("tampered byte", tampered, ErrorCode::InvalidChecksum),
        ("too long", big, ErrorCode::DiskFull),
        (
            "truncated",
            good[..good.len() - 100].to_vec(),
            ErrorCode::ProgramError,
        ),
        ("header only", good[..100].to_vec(), ErrorCode::ProgramError),
    ];
    for (what, f, code) in cases {
        let mut u = fl.update();
        assert_eq!(send(&mut u, &f), Err(code), "{what}");
        assert_eq!(u.accepted(), None, "{what}");
        assert_eq!(u.take_event(), Some(Event::Refused(code)), "{what}");
        drop(u);
        assert_eq!(
            fl.boot(),
            embassy_boot::State::Boot,
            "{what}: nothing marked"
        );
    }
    // Refused requests: name, password, outside Bootstrap.
    let mut u = fl.update();
    assert_eq!(
        u.open_write(b"firmware.bin", 0, true),
        Err(ErrorCode::NotFound)
    );
    assert_eq!(u.open_write(b"a.efw", 7, true), Err(ErrorCode::NoRights));
    assert_eq!(
        u.open_write(b"a.efw", 0, false),
        Err(ErrorCode::BootstrapOnly)
    );
    assert_eq!(u.write(0, &[1, 2, 3]), WriteStatus::Err(ErrorCode::Illegal));
    // Half a transfer, then abort: nothing marked, the next one works.
    u.open_write(b"x/Y.EFW", 0, true).unwrap();
    while u.write(0, &good[..500]) != WriteStatus::Done {}
    u.abort();
    assert_eq!(u.finish_write(), Err(ErrorCode::Illegal));
    assert_eq!(send(&mut u, &good), Ok(()));
}

#[test]
fn the_info_file_describes_the_running_image() {
    let fl = Flashes::new();
    let read = |u: &mut dyn FoeFiles| {
        let n = u.open_read(INFO_FILE, 0, false).unwrap() as usize;
        let mut b = std::vec![0u8; n];
        assert_eq!(u.read(0, &mut b), n);
        std::string::String::from_utf8(b).unwrap()
    };
    let t = read(&mut fl.update());
    assert!(
        t.contains("signature=none") && t.contains("boot=confirmed"),
        "{t}"
    );
    assert!(
        t.contains("esc=lan9252") && t.contains("product=0x00005702"),
        "{t}"
    );
    let own = std::format!(
        "version={}\nbuild=none\n",
        crate::identity::SOFTWARE_VERSION
    );
    assert!(t.contains(&own), "{t}");
    let f = file(Esc::Lan9252, 0x0001_0203, &image(900, 1));
    assert_eq!(send(&mut fl.update(), &f), Ok(()));
    fl.boot();
    let t = read(&mut fl.update());
    assert!(
        t.contains("version=1.2.3") && t.contains("signature=valid"),
        "{t}"
    );
    assert!(
        t.contains("boot=trial") && t.contains("image-length=900"),
        "{t}"
    );
    let sig = efw::Frame::new_checked(&f[..]).unwrap().image_signature();
    let build: std::string::String = sig[..8].iter().map(|x| std::format!("{x:02x}")).collect();
    assert!(t.contains(&std::format!("build={build}\n")), "{t}");
    let mut u = fl.update();
    assert_eq!(u.open_read(b"other", 0, false), Err(ErrorCode::NotFound));
    assert_eq!(u.open_read(INFO_FILE, 1, false), Err(ErrorCode::NoRights));
}

/// issue 33: the check of the image (SHA-512 over the DFU partition, the ed25519
/// image signature) is spread over the BUSY answers of the DATA that
/// completes it: no FoE call reads more than `VERIFY_STEP` bytes or erases more than
/// one page, whatever the image length, and the finish reads nothing. Before, the
/// finish hashed the whole image in one call (≈ 230 ms for the largest image).
#[test]
fn the_last_packets_check_runs_in_bounded_steps() {
    let fl = Flashes::new();
    let len = 60_000usize;
    let f = file(Esc::Lan9252, 4, &image(len, 3));
    let mut u = fl.update();
    u.open_write(b"ecs-lan9252.efw", 0, true).unwrap();
    let (mut off, mut calls, mut last_busy) = (0u32, 0usize, 0usize);
    let (mut max_read, mut max_ops) = (0usize, 0usize);
    let chunks: Vec<&[u8]> = f.chunks(116).collect();
    for (i, c) in chunks.iter().enumerate() {
        loop {
            let before = fl.dfu_work();
            let r = u.write(off, c);
            let after = fl.dfu_work();
            calls += 1;
            max_read = max_read.max(after.0 - before.0);
            max_ops = max_ops.max(after.1 - before.1);
            match r {
                WriteStatus::Done => break,
                WriteStatus::Busy { .. } if i + 1 == chunks.len() => last_busy += 1,
                WriteStatus::Busy { .. } => {}
                WriteStatus::Err(e) => panic!("refused: {e:?}"),
            }
            assert!(calls < 100_000, "BUSY for ever");
        }
        off += c.len() as u32;
    }
    let before = fl.dfu_work();
    assert_eq!(u.finish_write(), Ok(()));
    assert_eq!(fl.dfu_work().0, before.0, "the finish reads nothing");
    assert!(u.accepted().is_some());
    assert!(
        max_read <= VERIFY_STEP as usize,
        "{max_read} bytes read in one call"
    );
    assert!(
        max_ops <= flash_layout::PAGE as usize + WRITE_CHUNK,
        "{max_ops} byte operations in one call"
    );
    // Taken, flush, header, ⌈60 000 / 4096⌉ = 15 hash steps (signature: Done).
    assert!(
        last_busy >= len.div_ceil(VERIFY_STEP as usize) + 3,
        "{last_busy} BUSY answers for the last DATA"
    );
    fl.boot();
    assert!(fl.active_starts_with(&image(len, 3)));
}

/// A repeat of the completing DATA with another offset or length ends the transfer.
#[test]
fn a_changed_repeat_during_the_check_is_refused() {
    let fl = Flashes::new();
    let f = file(Esc::Lan9252, 4, &image(1000, 3));
    let mut u = fl.update();
    u.open_write(b"ecs-lan9252.efw", 0, true).unwrap();
    let mut off = 0u32;
    let chunks: Vec<&[u8]> = f.chunks(116).collect();
    for c in &chunks[..chunks.len() - 1] {
        while u.write(off, c) != WriteStatus::Done {}
        off += c.len() as u32;
    }
    let last = chunks[chunks.len() - 1];
    // Erases until the data is taken, then the check's first BUSY.
    let mut n = 0;
    while matches!(u.write(off, last), WriteStatus::Busy { .. }) && n < 3 {
        n += 1;
    }
    assert_eq!(u.write(off + 1, last), WriteStatus::Err(ErrorCode::Illegal));
    assert_eq!(u.finish_write(), Err(ErrorCode::Illegal));
    assert!(u.accepted().is_none());
}

/// issue 33, anti-rollback: after an image with security version 2 confirmed
/// itself, a correctly signed file with security version 1 is refused with FoE
/// "access denied" before anything is erased; 2 and above are taken.
#[test]
fn an_image_below_the_kept_security_version_is_refused() {
    let fl = Flashes::new();
    let secured = |version: u32, sv: u32, salt: u8| {
        efw::sign::update_file_secured(
            &seed(),
            VENDOR,
            PRODUCT,
            Esc::Lan9252,
            version,
            sv,
            &image(3000, salt),
        )
    };
    assert_eq!(send(&mut fl.update(), &secured(5, 2, 1)), Ok(()));
    fl.boot();
    let mut u = fl.update();
    assert!(u.confirm(true, true));
    let mut u = fl.update();
    assert_eq!(u.min_security_version(), 2);
    let ops = fl.dfu_work().1;
    assert_eq!(
        send(&mut u, &secured(9, 1, 2)),
        Err(ErrorCode::AccessDenied),
        "older security version"
    );
    assert_eq!(fl.dfu_work().1, ops, "nothing erased");
    assert_eq!(
        u.take_event(),
        Some(Event::Refused(ErrorCode::AccessDenied))
    );
    let mut u = fl.update();
    assert_eq!(
        send(&mut u, &secured(4, 2, 3)),
        Ok(()),
        "same security version, older version"
    );
    // The floor reads back in the information file.
    let n = u.open_read(INFO_FILE, 0, false).unwrap() as usize;
    let mut b = std::vec![0u8; n];
    u.read(0, &mut b);
    let t = std::string::String::from_utf8(b).unwrap();
    assert!(t.contains("security-version=2\n"), "{t}");
}

/// issue 33: a release build trusts the development key only when asked for; one
/// without a key refuses every file and says so in `firmware.info`.
#[test]
fn the_trusted_key_follows_the_build_and_is_reported() {
    let dev = efw::sign::public_key(&seed());
    let other = "11".repeat(32);
    assert_eq!(trust(None, false, false), Trust::Development(dev));
    assert_eq!(trust(None, false, true), Trust::None);
    assert_eq!(trust(None, true, true), Trust::Development(dev));
    assert_eq!(trust(Some(DEV_PUBLIC_KEY_HEX), false, true), Trust::None);
    assert_eq!(
        trust(Some(&other), false, true),
        Trust::Production([0x11; 32])
    );
    assert_eq!(
        trust(Some(&other), false, false),
        Trust::Production([0x11; 32])
    );

    let info = |u: &mut dyn FoeFiles| {
        let n = u.open_read(INFO_FILE, 0, false).unwrap() as usize;
        let mut b = std::vec![0u8; n];
        assert_eq!(u.read(0, &mut b), n);
        std::string::String::from_utf8(b).unwrap()
    };
    let fl = Flashes::new();
    let f = file(Esc::Lan9252, 1, &image(900, 1));
    let mut none = fl.update_with(trust(None, false, true));
    assert_eq!(send(&mut none, &f), Err(ErrorCode::AccessDenied));
    let t = info(&mut none);
    assert!(
        t.contains("key=none\n") && !t.contains("key-fingerprint"),
        "{t}"
    );
    let mut u = fl.update_with(trust(None, true, true));
    let t = info(&mut u);
    let fp: std::string::String = efw::image_digest(&dev)[..8]
        .iter()
        .map(|x| std::format!("{x:02x}"))
        .collect();
    assert!(t.contains("key=development\n"), "{t}");
    assert!(t.contains(&std::format!("key-fingerprint={fp}\n")), "{t}");
    assert_eq!(send(&mut u, &f), Ok(()));
    let t = info(&mut fl.update_with(Trust::Production([0x11; 32])));
    assert!(t.contains("key=production\n"), "{t}");
}

/// A transfer aborted after its image was checked (the completing DATA answered
/// Done, no finish) marks nothing: the next boot keeps the running image.
#[test]
fn a_transfer_aborted_after_the_check_marks_nothing() {
    let fl = Flashes::new();
    let f = file(Esc::Lan9252, 4, &image(3000, 5));
    let mut u = fl.update();
    u.open_write(b"ecs-lan9252.efw", 0, true).unwrap();
    let mut off = 0u32;
    for c in f.chunks(116) {
        while u.write(off, c) != WriteStatus::Done {}
        off += c.len() as u32;
    }
    u.abort();
    assert!(u.accepted().is_none());
    assert_eq!(fl.boot(), embassy_boot::State::Boot);
    assert!(!fl.active_starts_with(&image(3000, 5)));
}
