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

/// issue 33: the power-cut flash model has the chip's ECC: a cut inside a double
/// word tears it, every read touching it fails (the double ECC error), and the
/// storage takes that slot for corrupt and uses the other record; the next write
/// erases the torn word.
#[test]
fn a_torn_double_word_fails_its_reads_and_the_other_record_is_used() {
    let h = region::HISTORY;
    let mut f = RamFlash::<{ region::SIZE as usize }>::new();
    h.write_bytes(&mut f, &[1; 40]).unwrap();
    // How many byte operations the next record takes.
    let mut probe = f.clone();
    probe.power_on();
    h.write_bytes(&mut probe, &[2; 40]).unwrap();
    let total = probe.ops;
    for (cut, torn_at) in [
        // Inside the last write, the magic's double word (the commit).
        (total - 4, h.slot_address(1)),
        // Inside the payload's first double word (the payload, padded to 64 bytes,
        // and the 32-byte header follow the erase).
        (total - 64 - 32 + 3, h.slot_address(1) + HEADER_LEN as u32),
    ] {
        let mut g = f.clone();
        g.power_on();
        g.cut_power_after(cut);
        assert!(h.write_bytes(&mut g, &[2; 40]).is_err(), "cut {cut}");
        g.power_on();
        assert!(g.is_torn(torn_at), "cut {cut}: torn word at {torn_at:#x}");
        let mut b = [0u8; 8];
        assert_eq!(
            embedded_storage::nor_flash::ReadNorFlash::read(&mut g, torn_at, &mut b),
            Err(NorFlashErrorKind::Other)
        );
        assert_eq!(h.slot_status(&mut g, 1), SlotStatus::Corrupt);
        let mut out = [0u8; 64];
        assert_eq!(h.read_newest(&mut g, &mut out), Some(40));
        assert_eq!(out[..40], [1; 40], "cut {cut}: the old record");
        // The next record goes over the torn slot; all reads are good again.
        h.write_bytes(&mut g, &[3; 40]).unwrap();
        assert!(!g.is_torn(torn_at));
        assert_eq!(h.read_newest(&mut g, &mut out), Some(40));
        assert_eq!(out[..40], [3; 40]);
    }
}

/// issue 33 (the lock held during a 'save'): starting a new record reads the two
/// headers and the payload of the newest record only — not the older record's
/// payload as a full scan of both slots does — and still picks the same slot and
/// sequence as the scan, also when the newer record is corrupt.
#[test]
fn a_new_record_checks_only_the_newest_payload() {
    let h = region::HISTORY;
    let mut f = RamFlash::<{ region::SIZE as usize }>::new();
    h.write_bytes(&mut f, &[1; 400]).unwrap();
    h.write_bytes(&mut f, &[2; 400]).unwrap();
    let read = |f: &mut RamFlash<{ region::SIZE as usize }>| core::mem::take(&mut f.reads);
    read(&mut f);
    let (_, scanned) = h.scan(&mut f);
    let scan_bytes = read(&mut f);
    assert_eq!(h.newest(&mut f), scanned);
    assert_eq!(scanned.map(|(slot, seq, _)| (slot, seq)), Some((1, 2)));
    let newest_bytes = read(&mut f);
    // The two headers (the newer one read again by its check) and one 400-byte
    // payload (read in whole 32-byte units).
    assert!(newest_bytes <= 3 * HEADER_LEN + 416, "{newest_bytes}");
    // The older payload is not read (less the one header read twice).
    assert!(
        scan_bytes >= newest_bytes + 416 - HEADER_LEN,
        "{scan_bytes} vs {newest_bytes}"
    );
    // A new record reads no more than that.
    let r = h.write_bytes(&mut f, &[3; 400]).unwrap();
    assert!(read(&mut f) <= newest_bytes);
    assert_eq!((r.slot, r.sequence), (0, 3));
    // The newer record's payload corrupt (its header intact): the older one is
    // found, as the scan finds it, and the next record goes over the corrupt one.
    let at = (h.slot_address(0) + HEADER_LEN as u32) as usize;
    f.mem[at + 10] ^= 0x01;
    let (_, scanned) = h.scan(&mut f);
    assert_eq!(scanned.map(|(slot, seq, _)| (slot, seq)), Some((1, 2)));
    assert_eq!(h.newest(&mut f), scanned);
    let r = h.write_bytes(&mut f, &[4; 400]).unwrap();
    assert_eq!((r.slot, r.sequence), (0, 3));
}

/// The header view writes the version-1 layout byte for byte (records stored by
/// earlier images load), reads it back, and a short buffer reads zeros without a panic.
#[test]
fn record_header_view_keeps_the_layout() {
    let mut h = RecordHeader::new(RECORD_MAGIC, 0x0102_0304, 0x20);
    h.set_crc(0xA1B2_C3D4);
    let b = h.into_inner();
    let mut want = [0u8; HEADER_LEN];
    want[..20].copy_from_slice(&[
        0x45, 0x43, 0x53, 0x50, 1, 0, 0, 0, 4, 3, 2, 1, 0x20, 0, 0, 0, 0xD4, 0xC3, 0xB2, 0xA1,
    ]);
    assert_eq!(b, want);
    let v = RecordHeader::new_checked(&b[..]).expect("whole header");
    assert_eq!(
        (
            v.magic(),
            v.format_version(),
            v.flags(),
            v.sequence(),
            v.payload_len(),
            v.crc()
        ),
        (
            RECORD_MAGIC,
            FORMAT_VERSION,
            0,
            0x0102_0304,
            0x20,
            0xA1B2_C3D4
        )
    );
    assert_eq!(v.checked_part(), &b[..16]);
    assert!(RecordHeader::new_checked(&b[..HEADER_LEN - 1]).is_none());
    let mut short = [0xFFu8; 6];
    let mut s = RecordHeader::new_unchecked(&mut short[..]);
    s.set_sequence(7);
    assert_eq!((s.sequence(), s.format_version()), (0, 0xFFFF));
    assert_eq!(short, [0xFF; 6]);
}
