//! The STM32G474RE's 512 KiB of flash (dual-bank mode, 2 KiB pages), described once.
//! `layout.x` (included by the bootloader's and the firmware's `memory.x`) states the
//! same partitions for the linker; a test checks that the two agree.
//!
//! | partition | start | size | holds |
//! |---|---|---|---|
//! | bootloader | 0x0800_0000 | 32 KiB | embassy-boot (`bootloader/`) |
//! | boot state | 0x0800_8000 | 4 KiB | embassy-boot's swap state and progress |
//! | active | 0x0800_9000 | 228 KiB | the running firmware; its last page the `.efw` header of the image |
//! | DFU | 0x0804_2000 | 230 KiB | an update being received, then the previous image |
//! | (spare) | 0x0807_B800 | 2 KiB | |
//! | records | 0x0807_C000 | 16 KiB | parameters and fault history ([`crate::storage::region`]) |
//!
//! The DFU partition is one page larger than the active one, as embassy-boot's swap
//! needs. The records sit outside every partition that an update touches, so the
//! parameters survive updates.

/// A part of the flash: offset from the flash base, and size, bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Partition {
    /// Offset from [`FLASH_BASE`].
    pub offset: u32,
    /// Size.
    pub size: u32,
}

impl Partition {
    /// Its first address.
    pub const fn start(&self) -> u32 {
        FLASH_BASE + self.offset
    }
    /// The address after it.
    pub const fn end(&self) -> u32 {
        self.start() + self.size
    }
}

/// Address of the flash.
pub const FLASH_BASE: u32 = 0x0800_0000;
/// Size of the flash.
pub const FLASH_SIZE: u32 = 512 * 1024;
/// Erase page (dual-bank mode).
pub const PAGE: u32 = 2048;

/// The bootloader.
pub const BOOTLOADER: Partition = Partition {
    offset: 0,
    size: 32 * 1024,
};
/// embassy-boot's state.
pub const BOOT_STATE: Partition = Partition {
    offset: 32 * 1024,
    size: 4 * 1024,
};
/// The running firmware.
pub const ACTIVE: Partition = Partition {
    offset: 36 * 1024,
    size: 228 * 1024,
};
/// The update partition.
pub const DFU: Partition = Partition {
    offset: 264 * 1024,
    size: 230 * 1024,
};
/// Parameter and fault-history records.
pub const RECORDS: Partition = Partition {
    offset: 496 * 1024,
    size: 16 * 1024,
};

/// Offset, in the active and the DFU partition, of the page that holds the image's
/// `.efw` header (the last page of the active partition's size).
pub const HEADER_OFFSET: u32 = ACTIVE.size - PAGE;
/// Largest firmware image: the active partition less its header page.
pub const IMAGE_MAX: u32 = HEADER_OFFSET;

const _: () = {
    assert!(BOOT_STATE.offset == BOOTLOADER.offset + BOOTLOADER.size);
    assert!(ACTIVE.offset == BOOT_STATE.offset + BOOT_STATE.size);
    assert!(DFU.offset == ACTIVE.offset + ACTIVE.size);
    assert!(DFU.size == ACTIVE.size + PAGE);
    assert!(DFU.offset + DFU.size <= RECORDS.offset);
    assert!(RECORDS.offset + RECORDS.size == FLASH_SIZE);
    assert!(RECORDS.size == crate::storage::region::SIZE);
    // Every partition is whole pages in either bank mode (4 KiB pages single-bank).
    assert!(BOOTLOADER.size.is_multiple_of(4096) && BOOT_STATE.offset.is_multiple_of(4096));
    assert!(ACTIVE.offset.is_multiple_of(4096) && RECORDS.offset.is_multiple_of(4096));
};
