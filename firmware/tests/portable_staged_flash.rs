#![cfg_attr(target_os = "none", no_std, no_main)]
//! Staged parameter saves: the record is built in RAM through the storage's normal
//! save, programmed by `commit` in the storage's power-loss order, and loads back;
//! oversize records, a disabled store, misaligned or out-of-range accesses and a
//! second save before the commit are refused; a power cut during the commit keeps
//! the previous record.
use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::od::{Dictionary, ObjectKey};
use embedded_storage::nor_flash::{NorFlash, ReadNorFlash};
use firmware::drive::Drive;
use firmware::identity::Variant;
use firmware::staged_flash::{commit, Stage, StageError, StagedFlash};
use firmware::storage::{RamFlash, Scope, Storage, HEADER_LEN};

const SLOT: u32 = 2048;
type Ram = RamFlash<4096>;
type Staged<'a> = StagedFlash<'a, &'a mut Ram, 2048, 32>;

fn store() -> Storage {
    Storage::new(0, SLOT)
}

fn drive_with_peak(ma: u16) -> Drive {
    let mut d = Drive::new(Variant::HybridServo, 7);
    d.write(
        ObjectKey::new(0x2000, 0),
        &ma.to_le_bytes(),
        EsmState::PreOp,
    )
    .unwrap();
    d
}

fn peak(d: &mut Drive) -> u16 {
    let mut b = [0u8; 4];
    let n = d.read(ObjectKey::new(0x2000, 0), &mut b).unwrap();
    assert_eq!(n, 2);
    u16::from_le_bytes([b[0], b[1]])
}

/// Saves `d` through a staged view and commits; returns the commit result.
fn save_and_commit(ram: &mut Ram, d: &mut Drive, cut_after: Option<usize>) -> bool {
    let mut stage = Stage::<2048>::new();
    let taken = {
        let mut sf: Staged = StagedFlash::new(&mut *ram, &mut stage, true);
        store().save(&mut sf, d, Scope::All).unwrap();
        sf.take_ready().is_some()
    };
    assert!(taken);
    if let Some(n) = cut_after {
        ram.cut_power_after(n);
    }
    commit(ram, &stage, HEADER_LEN).is_ok()
}

qemu_runner::tests! {
    fn staged_save_commits_and_loads_back() {
        let mut ram = Ram::new();
        let mut d = drive_with_peak(3100);
        let mut stage = Stage::<2048>::new();
        {
            let mut sf: Staged = StagedFlash::new(&mut ram, &mut stage, true);
            let rep = store().save(&mut sf, &mut d, Scope::All).unwrap();
            assert!(rep.entries > 0);
            // The finished image is visible through the view before the commit.
            let mut head = [0u8; 4];
            sf.read(0, &mut head).unwrap();
            assert_eq!(u32::from_le_bytes(head), firmware::storage::RECORD_MAGIC);
            assert!(sf.take_ready().is_some());
            assert!(sf.take_ready().is_none());
        }
        // Nothing reached the flash before the commit.
        assert!(ram.mem.iter().all(|&b| b == 0xFF));
        commit(&mut ram, &stage, HEADER_LEN).unwrap();
        let mut fresh = Drive::new(Variant::HybridServo, 7);
        let rep = store().load(&mut ram, &mut fresh);
        assert!(rep.applied > 0);
        assert_eq!(rep.skipped, 0);
        assert_eq!(peak(&mut fresh), 3100);
    }

    fn record_too_large_for_the_image_is_refused() {
        let mut ram = Ram::new();
        let mut d = drive_with_peak(3100);
        let mut small = Stage::<256>::new();
        {
            let mut sf: StagedFlash<&mut Ram, 256, 32> =
                StagedFlash::new(&mut ram, &mut small, true);
            assert!(store().save(&mut sf, &mut d, Scope::All).is_err());
            assert!(sf.take_ready().is_none());
        }
        assert!(ram.mem.iter().all(|&b| b == 0xFF));
    }

    fn disabled_store_reads_erased_and_refuses_saves() {
        let mut ram = Ram::new();
        ram.write(0, &[0u8; 8]).unwrap();
        let mut d = drive_with_peak(3100);
        let mut stage = Stage::<2048>::new();
        let mut sf: Staged = StagedFlash::new(&mut ram, &mut stage, false);
        let mut b = [0u8; 8];
        sf.read(0, &mut b).unwrap();
        assert_eq!(b, [0xFF; 8]);
        assert!(store().save(&mut sf, &mut d, Scope::All).is_err());
        assert_eq!(sf.erase(0, 32), Err(StageError::Unavailable));
    }

    fn bad_accesses_are_refused() {
        let mut ram = Ram::new();
        let mut stage = Stage::<2048>::new();
        let mut sf: Staged = StagedFlash::new(&mut ram, &mut stage, true);
        let mut b = [0u8; 8];
        assert_eq!(sf.read(4090, &mut b), Err(StageError::OutOfBounds));
        assert_eq!(sf.read(u32::MAX, &mut b), Err(StageError::OutOfBounds));
        assert_eq!(sf.erase(0, 20), Err(StageError::NotAligned));
        assert_eq!(sf.erase(64, 32), Err(StageError::OutOfBounds));
        assert_eq!(sf.erase(0, 8192), Err(StageError::OutOfBounds));
        // Writes need an erased range around them and whole units.
        assert_eq!(sf.write(0, &[1; 8]), Err(StageError::OutOfBounds));
        sf.erase(2048, 4096).unwrap();
        assert_eq!(sf.write(2048, &[1; 4]), Err(StageError::NotAligned));
        assert_eq!(sf.write(2052, &[1; 8]), Err(StageError::NotAligned));
        assert_eq!(sf.write(0, &[1; 8]), Err(StageError::OutOfBounds));
        sf.write(2056, &[2; 8]).unwrap();
        assert!(sf.take_ready().is_none()); // header not written yet
        sf.write(2048, &[3; 8]).unwrap();
        // A finished image blocks further staging until it was committed.
        assert_eq!(sf.erase(0, 32), Err(StageError::Unavailable));
        assert_eq!(sf.write(2064, &[4; 8]), Err(StageError::Unavailable));
        let st = sf.take_ready().unwrap();
        assert_eq!(st.erased_range(), Some((2048, 4096)));
        sf.give_back(st);
        // Inside the erased range but beyond the 2 KiB image.
        sf.erase(0, 4096).unwrap();
        assert_eq!(sf.write(2048, &[1; 8]), Err(StageError::OutOfBounds));
        sf.write(2040, &[1; 8]).unwrap();
    }

    fn power_cut_during_commit_keeps_the_previous_record() {
        let mut base = Ram::new();
        let mut d = drive_with_peak(2500);
        assert!(save_and_commit(&mut base, &mut d, None));
        let mut d2 = drive_with_peak(4100);
        let mut cuts = 0;
        let mut n = 1;
        while n < 5000 {
            let mut ram = base.clone();
            if !save_and_commit(&mut ram, &mut d2, Some(n)) {
                cuts += 1;
            }
            ram.power_on();
            let mut fresh = Drive::new(Variant::HybridServo, 7);
            let rep = store().load(&mut ram, &mut fresh);
            let p = peak(&mut fresh);
            assert!(p == 2500 || p == 4100, "cut after {n}: peak {p}");
            assert_eq!(rep.skipped, 0);
            n += 97;
        }
        assert!(cuts > 10);
    }
}
