use super::*;

#[test]
fn memory_flash_range_checks() {
    use NorFlashErrorKind::{NotAligned, Other, OutOfBounds};
    assert_eq!(read_range(64, 60, 4), Ok(60..64));
    assert_eq!(read_range(64, 61, 4), Err(OutOfBounds));
    assert_eq!(read_range(64, u32::MAX, usize::MAX), Err(OutOfBounds));
    assert_eq!(erase_range(64, 32, 0, 64), Ok(0..64));
    assert_eq!(erase_range(64, 32, 32, 0), Err(OutOfBounds));
    assert_eq!(erase_range(64, 32, 0, 96), Err(OutOfBounds));
    assert_eq!(erase_range(64, 32, 8, 32), Err(NotAligned));
    let mut mem = [0xFFu8; 32];
    mem[20] = 0;
    assert_eq!(write_range(&mem, 8, 8, 8), Ok(8..16));
    assert_eq!(write_range(&mem, 8, 4, 8), Err(NotAligned));
    assert_eq!(write_range(&mem, 8, 8, 4), Err(NotAligned));
    assert_eq!(write_range(&mem, 8, 32, 8), Err(OutOfBounds));
    assert_eq!(write_range(&mem, 8, 16, 8), Err(Other));
    assert_eq!(
        write_range(&mem, 8, u32::MAX - 7, usize::MAX - 7),
        Err(OutOfBounds)
    );
}

#[test]
fn crc32_known_values() {
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    assert_eq!(crc32(b""), 0);
    let mut c = Crc32::new();
    c.update(b"1234");
    c.update(b"56789");
    assert_eq!(c.finish(), 0xCBF4_3926);
}

#[test]
fn sequence_comparison_wraps() {
    assert!(newer(2, 1));
    assert!(!newer(1, 2));
    assert!(newer(0, u32::MAX));
    assert!(!newer(5, 5));
}

#[test]
fn scope_from_sub() {
    assert_eq!(Scope::from_sub(1), Some(Scope::All));
    assert_eq!(Scope::from_sub(4), Some(Scope::All));
    assert_eq!(Scope::from_sub(2), Some(Scope::Communication));
    assert_eq!(Scope::from_sub(3), Some(Scope::Application));
    assert_eq!(Scope::from_sub(0), None);
    assert_eq!(Scope::from_sub(5), None);
    assert!(Scope::Communication.contains(0x1C12));
    assert!(!Scope::Communication.contains(0x2000));
    assert!(Scope::Application.contains(0x6060));
}

#[test]
fn geometry_is_checked() {
    let mut f = RamFlash::<1024>::new();
    assert_eq!(Storage::new(0, 512).check(&f), Ok(()));
    assert_eq!(Storage::new(0, 513).check(&f), Err(StorageError::Geometry));
    assert_eq!(
        Storage::new(32, 512).check(&f),
        Err(StorageError::Geometry),
        "beyond capacity"
    );
    assert_eq!(
        Storage::new(16, 256).check(&f),
        Err(StorageError::Geometry),
        "unaligned base"
    );
    assert_eq!(
        Storage::new(0, 32).check(&f),
        Err(StorageError::Geometry),
        "too small"
    );
    let mut d = NoDict;
    let r = Storage::new(0, 513).load(&mut f, &mut d);
    assert_eq!(r.source, None);
    assert_eq!(
        Storage::new(0, 513).restore_defaults(&mut f, Scope::All),
        Err(StorageError::Geometry)
    );
    assert_eq!(StorageError::Geometry.abort(), SdoAbort::DataCannotBeStored);
    assert_eq!(
        StorageError::Flash(NorFlashErrorKind::Other).abort(),
        SdoAbort::HardwareError
    );
}
