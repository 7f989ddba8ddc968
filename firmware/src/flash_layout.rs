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
//! | records | 0x0807_C000 | 16 KiB | parameters and fault history (`storage::region`) |
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
/// Bytes per bank in dual-bank mode: the flash's two halves.
pub const BANK_SIZE: u32 = FLASH_SIZE / 2;
/// The address after bank 1. The running firmware's code must end below it: the
/// records and the DFU partition (bank 2) are erased and programmed while the code
/// runs from bank 1 (read-while-write). `cargo xtask size` fails an image that
/// reaches past it.
pub const BANK1_END: u32 = FLASH_BASE + BANK_SIZE;

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
    // Every partition is whole pages in either bank mode (4 KiB pages single-bank).
    assert!(BOOTLOADER.size.is_multiple_of(4096) && BOOT_STATE.offset.is_multiple_of(4096));
    assert!(ACTIVE.offset.is_multiple_of(4096) && RECORDS.offset.is_multiple_of(4096));
};

#[cfg(test)]
mod tests {
    //! The linker's copy of the layout (`layout.x`, and the regions of
    //! `firmware/memory.x` and `bootloader/memory.x`) against the constants above.
    use super::*;

    const LAYOUT_X: &str = include_str!("../../layout.x");
    const MEMORY_X: &str = include_str!("../memory.x");
    const BOOTLOADER_MEMORY_X: &str = include_str!("../../bootloader/memory.x");

    /// The text of a linker script outside its `/* */` comments.
    fn code(script: &str) -> impl Iterator<Item = &str> {
        script
            .split("*/")
            .map(|chunk| chunk.split("/*").next().unwrap_or(""))
            .flat_map(str::lines)
            .map(str::trim)
            .filter(|line| !line.is_empty())
    }

    /// A linker-script number: decimal, `0x` hex, or decimal with a `K` suffix.
    fn number(text: &str) -> u32 {
        let text = text.trim();
        let value = if let Some(hex) = text.strip_prefix("0x") {
            u32::from_str_radix(hex, 16).ok()
        } else if let Some(kib) = text.strip_suffix('K') {
            kib.parse::<u32>().ok().and_then(|k| k.checked_mul(1024))
        } else {
            text.parse().ok()
        };
        value.unwrap_or_else(|| panic!("not a plain number: {text:?}"))
    }

    /// The symbol assignments `name = number;` of a script.
    fn assignments(script: &str) -> impl Iterator<Item = (&str, u32)> {
        code(script).filter_map(|line| {
            let (name, value) = line.strip_suffix(';')?.split_once('=')?;
            let name = name.trim();
            let symbol = name.chars().all(|c| c == '_' || c.is_ascii_alphanumeric());
            symbol.then(|| (name, number(value)))
        })
    }

    /// ORIGIN and LENGTH of a MEMORY region (`NAME : ORIGIN = a, LENGTH = b`).
    fn region(script: &str, name: &str) -> (u32, u32) {
        let line = code(script)
            .find(|line| {
                line.split_once(':')
                    .is_some_and(|(region, _)| region.trim() == name)
            })
            .unwrap_or_else(|| panic!("no MEMORY region {name}"));
        let (_, attributes) = line.split_once(':').unwrap();
        let (origin, length) = attributes
            .split_once(',')
            .expect("ORIGIN = .., LENGTH = ..");
        let value = |attribute: &str, key: &str| {
            let (k, v) = attribute.split_once('=').expect("key = value");
            assert_eq!(k.trim(), key, "{name}: {line}");
            number(v)
        };
        (value(origin, "ORIGIN"), value(length, "LENGTH"))
    }

    fn includes_layout(script: &str) -> bool {
        code(script).any(|line| line == "INCLUDE layout.x")
    }

    #[test]
    fn layout_x_states_the_rust_layout() {
        // Offsets from the flash base, as embassy-boot reads them.
        let end = |p: Partition| p.offset + p.size;
        let expected = [
            ("__flash_base", FLASH_BASE),
            ("__flash_page", PAGE),
            ("__bootloader_start", BOOTLOADER.offset),
            ("__bootloader_end", end(BOOTLOADER)),
            ("__bootloader_state_start", BOOT_STATE.offset),
            ("__bootloader_state_end", end(BOOT_STATE)),
            ("__bootloader_active_start", ACTIVE.offset),
            ("__bootloader_active_end", end(ACTIVE)),
            ("__bootloader_dfu_start", DFU.offset),
            ("__bootloader_dfu_end", end(DFU)),
            ("__records_start", RECORDS.offset),
            ("__records_end", end(RECORDS)),
        ];
        let mut seen = [false; 12];
        for (name, value) in assignments(LAYOUT_X) {
            let i = expected
                .iter()
                .position(|(n, _)| *n == name)
                .unwrap_or_else(|| panic!("layout.x: {name} is not in the Rust layout"));
            assert!(!seen[i], "layout.x: {name} twice");
            seen[i] = true;
            assert_eq!(value, expected[i].1, "layout.x: {name} = {value:#x}");
        }
        for ((name, _), seen) in expected.iter().zip(seen) {
            assert!(seen, "layout.x lacks {name}");
        }
    }

    #[test]
    fn memory_x_links_the_firmware_into_the_active_partition() {
        assert!(includes_layout(MEMORY_X));
        // The image, then the page of its update header.
        assert_eq!(region(MEMORY_X, "FLASH"), (ACTIVE.start(), HEADER_OFFSET));
        assert_eq!(HEADER_OFFSET, 226 * 1024);
        assert_eq!(region(MEMORY_X, "PARAMS"), (RECORDS.start(), RECORDS.size));
        assert_eq!(region(MEMORY_X, "RAM"), (0x2000_0000, 128 * 1024));
    }

    #[test]
    fn the_bootloader_links_into_its_partition() {
        assert!(includes_layout(BOOTLOADER_MEMORY_X));
        assert_eq!(
            region(BOOTLOADER_MEMORY_X, "FLASH"),
            (BOOTLOADER.start(), BOOTLOADER.size)
        );
        assert_eq!(region(BOOTLOADER_MEMORY_X, "RAM"), region(MEMORY_X, "RAM"));
    }

    #[test]
    fn the_script_reader() {
        let script = "/* a = 1; */ b = 0x10; /* c = 2;\n d = 3; */\ne = 4K;\nASSERT(x == 1);";
        let mut found = assignments(script);
        assert_eq!(found.next(), Some(("b", 16)));
        assert_eq!(found.next(), Some(("e", 4096)));
        assert_eq!(found.next(), None);
        assert_eq!(
            region("M {\n  R : ORIGIN = 0x100, LENGTH = 2K\n}", "R"),
            (0x100, 2048)
        );
    }
}
