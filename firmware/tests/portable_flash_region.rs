#![cfg_attr(target_os = "none", no_std, no_main)]
//! The flash window given to the parameter records: every access outside it or
//! misaligned is refused before it reaches the flash; the record store works through it.
use embedded_storage::nor_flash::{NorFlash, ReadNorFlash};
use firmware::flash_region::{FlashRegion, RegionError};
use firmware::storage::{RamFlash, SlotStatus, Storage};

type Ram = RamFlash<256>;

fn window() -> FlashRegion<Ram> {
    FlashRegion::new(Ram::new(), 64, 128).unwrap()
}

qemu_runner::tests! {
    fn construction_checks_geometry() {
        assert!(FlashRegion::new(Ram::new(), 0, 256).is_some());
        assert!(FlashRegion::new(Ram::new(), 64, 128).is_some());
        assert!(FlashRegion::new(Ram::new(), 16, 128).is_none()); // base not a page start
        assert!(FlashRegion::new(Ram::new(), 64, 100).is_none()); // not whole pages
        assert!(FlashRegion::new(Ram::new(), 192, 96).is_none()); // past the end
        assert!(FlashRegion::new(Ram::new(), u32::MAX - 31, 64).is_none()); // overflow
    }

    fn accesses_land_inside_the_window_only() {
        let mut w = window();
        assert_eq!(w.capacity(), 128);
        w.write(0, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
        w.write(120, &[9; 8]).unwrap();
        let mut b = [0u8; 8];
        w.read(120, &mut b).unwrap();
        assert_eq!(b, [9; 8]);
        let ram = w.release();
        assert_eq!(&ram.mem[64..72], &[1, 2, 3, 4, 5, 6, 7, 8]);
        assert_eq!(&ram.mem[184..192], &[9; 8]);
        assert!(ram.mem[..64].iter().all(|&x| x == 0xFF));
        assert!(ram.mem[192..].iter().all(|&x| x == 0xFF));
    }

    fn erase_stays_inside() {
        let mut w = window();
        w.write(0, &[0; 8]).unwrap();
        w.erase(0, 32).unwrap();
        let mut b = [0u8; 8];
        w.read(0, &mut b).unwrap();
        assert_eq!(b, [0xFF; 8]);
        assert_eq!(w.erase(96, 160), Err(RegionError::OutOfBounds));
        assert_eq!(w.erase(64, 32), Err(RegionError::OutOfBounds));
        assert_eq!(w.erase(8, 32), Err(RegionError::NotAligned));
    }

    fn out_of_window_and_garbage_offsets_are_refused() {
        let mut w = window();
        let mut b = [0u8; 8];
        assert_eq!(w.read(128, &mut b), Err(RegionError::OutOfBounds));
        assert_eq!(w.read(124, &mut b), Err(RegionError::OutOfBounds));
        assert_eq!(w.read(u32::MAX, &mut b), Err(RegionError::OutOfBounds));
        assert_eq!(w.write(u32::MAX - 3, &[0; 8]), Err(RegionError::OutOfBounds));
        assert_eq!(w.write(128, &[0; 8]), Err(RegionError::OutOfBounds));
        assert_eq!(w.erase(u32::MAX - 31, u32::MAX), Err(RegionError::OutOfBounds));
        let ram = w.release();
        assert!(ram.mem.iter().all(|&x| x == 0xFF));
    }

    fn misaligned_writes_are_refused() {
        let mut w = window();
        assert_eq!(w.write(4, &[0; 8]), Err(RegionError::NotAligned));
        assert_eq!(w.write(0, &[0; 5]), Err(RegionError::NotAligned));
    }

    fn flash_errors_pass_through() {
        let mut w = window();
        w.write(0, &[0; 8]).unwrap();
        // Programming a byte that is not erased fails on the chip (and in RamFlash).
        assert!(matches!(w.write(0, &[1; 8]), Err(RegionError::Flash(_))));
    }

    fn record_store_scans_through_the_window() {
        let store = Storage::new(0, 64);
        let mut w = window();
        store.check(&w).unwrap();
        let (slots, newest) = store.scan(&mut w);
        assert_eq!(slots, [SlotStatus::Erased, SlotStatus::Erased]);
        assert_eq!(newest, None);
        // Garbage in slot 1: reported as corrupt, nothing panics.
        w.write(64, &[0x45, 0x43, 0x53, 0x50, 1, 0, 0, 0]).unwrap();
        w.write(72, &[0xAA; 8]).unwrap();
        let (slots, newest) = store.scan(&mut w);
        assert_eq!(slots, [SlotStatus::Erased, SlotStatus::Corrupt]);
        assert_eq!(newest, None);
    }
}
