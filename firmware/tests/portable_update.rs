//! The firmware update on the host and under QEMU: the product's FoE files
//! (`firmware::update`) over embassy-boot's updater on RAM partitions of the real
//! sizes (2 KiB pages), embassy-boot's `BootLoader` for the swap and the revert, and
//! the ed25519 / SHA-512 checks compiled for the board's core. The update files are
//! signed on the host by build.rs.
#![cfg_attr(target_os = "none", no_std, no_main)]

use core::cell::RefCell;

use ecat_slave_stack::foe::{ErrorCode, FoeFiles, WriteStatus};
use embassy_boot::{BootLoader, BootLoaderConfig, State};
use embassy_embedded_hal::flash::partition::BlockingPartition;
use embassy_sync::blocking_mutex::{raw::NoopRawMutex, Mutex};
use firmware::flash_layout::{ACTIVE, BOOT_STATE, DFU, PAGE};
use firmware::storage::PagedRamFlash;
use firmware::update::{BootState, EmbassyUpdater, Update};

static GOOD: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/test-update.efw"));
static OTHER_KEY: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/test-update-other-key.efw"));

const A: usize = ACTIVE.size as usize;
const D: usize = DFU.size as usize;
const S: usize = BOOT_STATE.size as usize;

/// The partitions (statics: 462 KiB is no stack value).
static mut ACTIVE_MEM: PagedRamFlash<A> = PagedRamFlash::new();
static mut DFU_MEM: PagedRamFlash<D> = PagedRamFlash::new();
static mut STATE_MEM: PagedRamFlash<S> = PagedRamFlash::new();

struct Flashes {
    active: Mutex<NoopRawMutex, RefCell<&'static mut PagedRamFlash<A>>>,
    dfu: Mutex<NoopRawMutex, RefCell<&'static mut PagedRamFlash<D>>>,
    state: Mutex<NoopRawMutex, RefCell<&'static mut PagedRamFlash<S>>>,
}

/// The partitions, erased (one test at a time uses them).
fn flashes() -> Flashes {
    // SAFETY: the tests run one after the other; each takes the statics once.
    let (a, d, s) = unsafe {
        (
            &mut *core::ptr::addr_of_mut!(ACTIVE_MEM),
            &mut *core::ptr::addr_of_mut!(DFU_MEM),
            &mut *core::ptr::addr_of_mut!(STATE_MEM),
        )
    };
    a.0.mem.fill(0xFF);
    d.0.mem.fill(0xFF);
    s.0.mem.fill(0xFF);
    Flashes {
        active: Mutex::new(RefCell::new(a)),
        dfu: Mutex::new(RefCell::new(d)),
        state: Mutex::new(RefCell::new(s)),
    }
}

fn identity() -> (u32, u32) {
    let f = efw::Frame::new_checked(GOOD).unwrap();
    (f.vendor_id(), f.product_code())
}

impl Flashes {
    fn update<'a>(
        &'a self,
        aligned: &'a mut [u8; 8],
    ) -> Update<impl firmware::update::Updater + 'a> {
        let (v, p) = identity();
        let u = EmbassyUpdater::new(
            whole(&self.dfu),
            whole(&self.state),
            whole(&self.active),
            aligned,
        );
        Update::new(u, v, p, efw::Esc::Lan9252)
    }

    fn boot(&self) -> State {
        let mut page = [0u8; PAGE as usize];
        BootLoader::new(BootLoaderConfig {
            active: whole(&self.active),
            dfu: whole(&self.dfu),
            state: whole(&self.state),
        })
        .prepare_boot(&mut page)
        .unwrap()
    }

    fn active_holds_the_image(&self) -> bool {
        let img = &GOOD[efw::HEADER_LEN..];
        self.active.lock(|f| f.borrow().0.mem[..img.len()] == *img)
    }
}

type Part<'a, const N: usize> = BlockingPartition<'a, NoopRawMutex, &'static mut PagedRamFlash<N>>;

/// A whole partition over one of the RAM flashes (embedded-storage implements the
/// flash traits for `&mut F`).
fn whole<'a, const N: usize>(
    m: &'a Mutex<NoopRawMutex, RefCell<&'static mut PagedRamFlash<N>>>,
) -> Part<'a, N> {
    BlockingPartition::new(m, 0, N as u32)
}

/// `f` as FoE brings it: DATA of 116 bytes, each again after BUSY; `flip` changes one
/// byte on the way.
fn send(u: &mut dyn FoeFiles, f: &[u8], flip: Option<usize>) -> Result<(), ErrorCode> {
    u.open_write(b"ecs-lan9252.efw", 0, true)?;
    let mut buf = [0u8; 116];
    for (k, c) in f.chunks(116).enumerate() {
        let b = &mut buf[..c.len()];
        b.copy_from_slice(c);
        if let Some(at) = flip {
            if at / 116 == k {
                b[at % 116] ^= 0x10;
            }
        }
        loop {
            match u.write((k * 116) as u32, b) {
                WriteStatus::Done => break,
                WriteStatus::Busy { .. } => {}
                WriteStatus::Err(e) => return Err(e),
            }
        }
    }
    u.finish_write()
}

qemu_runner::tests! {
    fn a_signed_image_is_taken_swapped_and_confirmed() {
        let fl = flashes();
        let mut al = [0u8; 8];
        {
            let mut u = fl.update(&mut al);
            assert_eq!(send(&mut u, GOOD, None), Ok(()));
            assert!(u.accepted().is_some());
        }
        assert_eq!(fl.boot(), State::Swap);
        assert!(fl.active_holds_the_image());
        let mut al = [0u8; 8];
        let mut u = fl.update(&mut al);
        assert_eq!(u.boot_state(), BootState::Trial);
        assert_eq!(u.running_version(), Some(0x0002_0001));
        assert!(u.confirm(true, true));
        drop(u);
        assert_eq!(fl.boot(), State::Boot);
        assert!(fl.active_holds_the_image());
    }

    fn an_unconfirmed_image_is_reverted() {
        let fl = flashes();
        let mut al = [0u8; 8];
        assert_eq!(send(&mut fl.update(&mut al), GOOD, None), Ok(()));
        assert_eq!(fl.boot(), State::Swap);
        assert_eq!(fl.boot(), State::Swap, "the revert");
        assert!(!fl.active_holds_the_image());
        let mut al = [0u8; 8];
        assert_eq!(fl.update(&mut al).boot_state(), BootState::Reverted);
    }

    fn tampered_and_foreign_images_are_refused() {
        let fl = flashes();
        let mut al = [0u8; 8];
        let mut u = fl.update(&mut al);
        assert_eq!(send(&mut u, OTHER_KEY, None), Err(ErrorCode::InvalidChecksum));
        assert_eq!(send(&mut u, GOOD, Some(efw::HEADER_LEN + 3000)), Err(ErrorCode::InvalidChecksum));
        assert_eq!(send(&mut u, GOOD, Some(13)), Err(ErrorCode::InvalidChecksum), "header byte");
        assert_eq!(send(&mut u, &GOOD[..GOOD.len() - 1], None), Err(ErrorCode::ProgramError));
        assert!(u.accepted().is_none());
        drop(u);
        assert_eq!(fl.boot(), State::Boot);
        assert!(!fl.active_holds_the_image());
    }
}
