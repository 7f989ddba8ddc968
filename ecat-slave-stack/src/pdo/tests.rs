use super::copy::mask;
use super::*;

#[test]
fn read_every_sub_index_and_the_errors() {
    const RX0: &[u32] = &[
        ObjectKey::new(0x6040, 0).mapping_word(16),
        ObjectKey::new(0x607A, 0).mapping_word(32),
    ];
    const TX3: &[u32] = &[ObjectKey::new(0x6041, 0).mapping_word(16)];
    let c = PdoConfig::new(PdoDefaults {
        rx: [RX0, &[], &[], &[]],
        tx: [&[], &[], &[], TX3],
        rx_assign: &[0x1600],
        tx_assign: &[0x1A03, 0x1A01],
    });
    let rd = |index: u16, sub: u8| {
        let mut b = [0xEEu8; 8];
        c.read(ObjectKey::new(index, sub), &mut b)
            .map(|n| b[..n].to_vec())
    };
    assert_eq!(rd(0x1600, 0), Ok(vec![2]));
    assert_eq!(rd(0x1600, 1), Ok(0x6040_0010u32.to_le_bytes().to_vec()));
    assert_eq!(rd(0x1600, 2), Ok(0x607A_0020u32.to_le_bytes().to_vec()));
    // Entries behind the count still read (their stored value), up to 16.
    assert_eq!(rd(0x1600, 16), Ok(vec![0; 4]));
    assert_eq!(rd(0x1A03, 0), Ok(vec![1]));
    assert_eq!(rd(0x1A03, 1), Ok(0x6041_0010u32.to_le_bytes().to_vec()));
    for sub in [17, 0x80, 0xFF] {
        assert_eq!(rd(0x1603, sub), Err(SdoAbort::SubindexDoesNotExist));
    }
    assert_eq!(rd(SM_COMM_TYPE, 0), Ok(vec![4]));
    for sub in 1..=4 {
        assert_eq!(rd(SM_COMM_TYPE, sub), Ok(vec![sub]));
    }
    assert_eq!(rd(RX_ASSIGN, 0), Ok(vec![1]));
    assert_eq!(rd(RX_ASSIGN, 1), Ok(vec![0x00, 0x16]));
    assert_eq!(rd(TX_ASSIGN, 0), Ok(vec![2]));
    assert_eq!(rd(TX_ASSIGN, 2), Ok(vec![0x01, 0x1A]));
    assert_eq!(rd(TX_ASSIGN, 4), Ok(vec![0, 0]));
    for index in [SM_COMM_TYPE, RX_ASSIGN, TX_ASSIGN] {
        for sub in [5, 0xFF] {
            assert_eq!(rd(index, sub), Err(SdoAbort::SubindexDoesNotExist));
        }
    }
    for index in [0x1604, 0x15FF, 0x1A04, 0x1C11, 0x1C14, 0x0000, 0xFFFF] {
        assert_eq!(rd(index, 0), Err(SdoAbort::ObjectDoesNotExist));
    }
    // A buffer too short for the value: the mailbox-size abort, nothing panics.
    let mut short = [0u8; 3];
    assert_eq!(
        c.read(ObjectKey::new(0x1600, 1), &mut short),
        Err(SdoAbort::ExceedsMailbox)
    );
    assert_eq!(
        c.read(ObjectKey::new(RX_ASSIGN, 0), &mut []),
        Err(SdoAbort::ExceedsMailbox)
    );
    assert_eq!(
        c.read(ObjectKey::new(TX_ASSIGN, 1), &mut short[..1]),
        Err(SdoAbort::ExceedsMailbox)
    );
}

#[test]
fn objects_are_well_formed() {
    assert!(od::is_well_formed(crate::packed_dictionary!(&[OBJECTS])));
    assert!(OBJECTS.windows(2).all(|w| w[0].index < w[1].index));
}

#[test]
fn extract_insert_round_trip_at_every_offset() {
    for bits in 1u8..=64 {
        for off in 0u16..24 {
            let mut buf = [0xA5u8; 16];
            let v = 0x0123_4567_89AB_CDEFu64 & mask(bits);
            insert(&mut buf, off, bits, v);
            assert_eq!(extract(&buf, off, bits), v, "bits {bits} off {off}");
            // Bits outside the field are untouched.
            let mut ref_buf = [0xA5u8; 16];
            insert(&mut ref_buf, off, bits, extract(&[0xA5u8; 16], off, bits));
            for i in 0..128u16 {
                if i < off || i >= off + bits as u16 {
                    assert_eq!(extract(&buf, i, 1), extract(&ref_buf, i, 1));
                }
            }
        }
    }
}

#[test]
fn extract_beyond_buffer_is_zero_and_insert_drops() {
    let buf = [0xFFu8; 2];
    assert_eq!(extract(&buf, 8, 16), 0xFF);
    assert_eq!(extract(&buf, 40, 8), 0);
    let mut b = [0u8; 2];
    insert(&mut b, 12, 16, 0xFFFF);
    assert_eq!(b, [0x00, 0xF0]);
}
