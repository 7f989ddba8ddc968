use super::*;

#[test]
fn read_lengths_of_every_sub_index() {
    let mut s = SyncState::new((11, 22));
    s.sm2.sync_type = 2;
    s.sm2.cycle_ns = 1_000_000;
    s.sm3.sm_event_missed = 7;
    s.sm3.sync_error = true;
    s.measuring = true;
    let rd = |s: &SyncState, index: u16, sub: u8| {
        let mut b = [0xEEu8; 8];
        s.read(ObjectKey::new(index, sub), &mut b)
            .map(|n| b[..n].to_vec())
    };
    let len = [1, 2, 4, 4, 2, 4, 4, 4, 2, 4, 4, 2, 2, 2, 2];
    for index in [SM2_SYNC, SM3_SYNC] {
        for (sub, n) in len.iter().enumerate() {
            assert_eq!(rd(&s, index, sub as u8).map(|v| v.len()), Ok(*n));
        }
        assert_eq!(rd(&s, index, 0x20).map(|v| v.len()), Ok(1));
        for sub in [0x0F, 0x1F, 0x21, 0xFF] {
            assert_eq!(rd(&s, index, sub), Err(SdoAbort::SubindexDoesNotExist));
        }
    }
    assert_eq!(rd(&s, SM2_SYNC, 0), Ok(vec![0x20]));
    assert_eq!(rd(&s, SM2_SYNC, 1), Ok(vec![2, 0]));
    assert_eq!(rd(&s, SM2_SYNC, 2), Ok(1_000_000u32.to_le_bytes().to_vec()));
    assert_eq!(
        rd(&s, SM2_SYNC, 4),
        Ok(SUPPORTED_TYPES.to_le_bytes().to_vec())
    );
    assert_eq!(rd(&s, SM2_SYNC, 5), Ok(MIN_CYCLE_NS.to_le_bytes().to_vec()));
    assert_eq!(rd(&s, SM2_SYNC, 6), Ok(11u32.to_le_bytes().to_vec()));
    assert_eq!(rd(&s, SM3_SYNC, 6), Ok(22u32.to_le_bytes().to_vec()));
    assert_eq!(rd(&s, SM3_SYNC, 8), Ok(vec![1, 0]));
    assert_eq!(rd(&s, SM3_SYNC, 0x0B), Ok(vec![7, 0]));
    assert_eq!(rd(&s, SM3_SYNC, 0x20), Ok(vec![1]));
    assert_eq!(rd(&s, SM2_SYNC, 0x20), Ok(vec![0]));
    assert_eq!(rd(&s, 0x1C31, 0), Err(SdoAbort::ObjectDoesNotExist));
    let mut short = [0u8; 3];
    assert_eq!(
        s.read(ObjectKey::new(SM2_SYNC, 2), &mut short),
        Err(SdoAbort::ExceedsMailbox)
    );
    assert_eq!(
        s.read(ObjectKey::new(SM2_SYNC, 0), &mut []),
        Err(SdoAbort::ExceedsMailbox)
    );
}

#[test]
fn cycle_times() {
    for k in 1..=32u32 {
        assert_eq!(check_cycle(k * 125_000), Ok(()));
    }
    for bad in [0, 62_500, 124_999, 125_001, 4_125_000, 1_000_001, u32::MAX] {
        assert_eq!(check_cycle(bad), Err(AlStatusCode::DcInvalidCycleTime));
    }
    assert_eq!(check_cycle_min(62_500, 62_500), Ok(()));
    assert_eq!(check_cycle_min(125_000, 62_500), Ok(()));
    assert_eq!(
        check_cycle_min(93_750, 62_500),
        Err(AlStatusCode::DcInvalidCycleTime)
    );
    assert_eq!(
        check_cycle_min(125_000, 250_000),
        Err(AlStatusCode::DcInvalidCycleTime)
    );
    assert_eq!(check_cycle_min(250_000, 250_000), Ok(()));
}

#[test]
fn resolve_mode_table() {
    use AlStatusCode::*;
    use SyncMode::*;
    let ms = 1_000_000;
    // (0x1C32:01 written, 0x1C33:01 written, 0x0981, 0x09A0, outputs, result)
    type Case = (
        Option<u16>,
        Option<u16>,
        u8,
        u32,
        bool,
        Result<SyncMode, AlStatusCode>,
    );
    let cases: &[Case] = &[
        (None, None, 0, 0, true, Ok(SmSync)),
        (None, None, 0, 0, false, Ok(SmSync)),
        (None, Some(0), 0, 0, false, Ok(FreeRun)),
        (Some(0), None, 0, 0, true, Ok(FreeRun)),
        (Some(0), Some(0), 0, 0, true, Ok(FreeRun)),
        (Some(0), Some(0x22), 0, 0, true, Err(SyncModeNotSupported)),
        (Some(1), None, 0, 0, true, Ok(SmSync)),
        (Some(1), Some(0x22), 0, 0, true, Ok(SmSync)),
        (None, Some(1), 0, 0, false, Ok(SmSync)),
        (Some(1), Some(2), 0, 0, true, Err(SyncModeNotSupported)),
        (Some(2), None, 0, ms, true, Err(SyncModeNotSupported)),
        (Some(3), None, 0, 0, true, Err(SyncModeNotSupported)),
        (Some(0x22), None, 0, 0, true, Err(SyncModeNotSupported)),
        (None, None, 3, ms, true, Ok(DcSync0)),
        (Some(2), Some(2), 3, ms, true, Ok(DcSync0)),
        (Some(1), None, 3, ms, true, Err(SyncModeNotSupported)),
        (None, Some(0x22), 3, ms, true, Err(SyncModeNotSupported)),
        (None, None, 0x0B, ms, true, Ok(DcSync0)),
        (None, None, 3, 300_000, true, Err(DcInvalidCycleTime)),
        (None, None, 1, ms, true, Err(InvalidDcSync)),
        (None, None, 7, ms, true, Err(InvalidDcSync)),
        (Some(2), None, 5, ms, true, Err(InvalidDcSync)),
    ];
    for (i, c) in cases.iter().enumerate() {
        assert_eq!(
            resolve_mode(c.0, c.1, c.2, c.3, c.4, MIN_CYCLE_NS),
            c.5,
            "case {i}"
        );
    }
}

#[test]
fn lock_and_loss() {
    let mut s = Sync0Supervisor::default();
    s.start(1_000_000);
    let mut t = 0;
    let mut locked_at = None;
    for i in 0..10 {
        if let (SyncEvent::Locked, _) = s.on_sync0(t) {
            locked_at = Some(i);
        }
        t += 1000;
    }
    assert_eq!(locked_at, Some(LOCK_COUNT as usize));
    assert_eq!(s.check(t), SyncEvent::None);
    assert_eq!(
        s.check(t + 2000),
        SyncEvent::Error(AlStatusCode::FatalSyncError)
    );
}
