extern crate std;
use super::*;
use crate::dictionary::Sdo;
use std::vec;
use std::vec::Vec;

static PACKED: &[od::Object] = ecat_slave_stack::packed_dictionary!(&[OBJECTS]);

fn w8(s: &mut Scope, index: u16, sub: u8, v: u8) -> Result<(), SdoAbort> {
    s.write(index, sub, &[v])
}
fn w16(s: &mut Scope, index: u16, sub: u8, v: u16) -> Result<(), SdoAbort> {
    s.write(index, sub, &v.to_le_bytes())
}
fn w32(s: &mut Scope, index: u16, sub: u8, v: u32) -> Result<(), SdoAbort> {
    s.write(index, sub, &v.to_le_bytes())
}
fn rd(s: &Scope, index: u16, sub: u8) -> i64 {
    let mut b = [0u8; 8];
    let n = s.read(index, sub, &mut b).expect("read");
    let t = od::find_entry(PACKED, ObjectKey::new(index, sub))
        .unwrap()
        .data_type;
    od::decode_int(t, &b[..n]).unwrap()
}

/// The done record as rows of channel values (all blocks, as a master reads them).
fn record(s: &Scope) -> Vec<Vec<i32>> {
    let n = rd(s, CHANNEL_LIST, 0) as usize;
    let mut bytes = Vec::new();
    for sub in 1..=BLOCKS as u8 {
        let mut b = [0u8; BLOCK_BYTES];
        match s.read(DATA, sub, &mut b) {
            Ok(k) => bytes.extend_from_slice(&b[..k]),
            Err(e) => {
                assert_eq!(e, SdoAbort::NoDataAvailable);
                break;
            }
        }
    }
    let words: Vec<i32> = bytes
        .chunks_exact(4)
        .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    words.chunks(n).map(|c| c.to_vec()).collect()
}

/// Feeds `values(k)` for sample k = 0.. until the scope stops running or `max` ticks.
fn run(s: &mut Scope, max: usize, mut values: impl FnMut(usize) -> Vec<i32>) -> usize {
    let mut k = 0;
    let mut ticks = 0;
    while s.running() && ticks < max {
        ticks += 1;
        if s.sample_due() {
            s.record(&values(k));
            k += 1;
        }
    }
    k
}

/// One channel, ramp k, rising edge through 100 with 10 pre-trigger samples.
fn one_channel_rising(s: &mut Scope) {
    w8(s, CHANNEL_LIST, 0, 1).unwrap();
    w32(s, CHANNEL_LIST, 1, 0x6064_0020).unwrap();
    w32(s, CONFIG, 3, 100).unwrap();
    w8(s, CONFIG, 4, 1).unwrap();
    w16(s, CONFIG, 5, 10).unwrap();
}

#[test]
fn table_is_well_formed_and_defaults_resolve() {
    assert!(od::is_well_formed(PACKED));
    let s = Scope::new(crate::dictionary::OBJECTS);
    for sub in 1..=CHANNELS as u8 {
        let v = rd(&s, CHANNEL_LIST, sub) as u32;
        assert!(
            Source::resolve(crate::dictionary::OBJECTS, v).is_ok(),
            "default channel {v:#010x}"
        );
    }
    assert_eq!(rd(&s, CONFIG, 0), 8);
    assert_eq!(rd(&s, CONFIG, 1), 1);
    assert_eq!(rd(&s, CONFIG, 8), 0, "the tick's time base");
    assert_eq!(rd(&s, CHANNEL_LIST, 0), 2);
    assert_eq!(rd(&s, STATUS, 1), State::Idle as i64);
    assert_eq!(rd(&s, DATA, 0), BLOCKS as i64);
}

#[test]
fn edge_trigger_keeps_the_pre_trigger_samples() {
    let mut s = Scope::new(crate::dictionary::OBJECTS);
    one_channel_rising(&mut s);
    w8(&mut s, CONFIG, 7, command::ARM).unwrap();
    assert_eq!(s.state(), State::Armed);
    assert_eq!(s.depth(), 768);
    // Ramp 0, 1, 2, …: the edge through 100 is sample 100.
    let taken = run(&mut s, 5000, |k| vec![k as i32]);
    assert_eq!(s.state(), State::Done);
    assert_eq!(taken, 100 + 768 - 10);
    assert_eq!(rd(&s, STATUS, 2), 768);
    assert_eq!(rd(&s, STATUS, 3), 10);
    assert_eq!(rd(&s, STATUS, 5), 1);
    let r = record(&s);
    assert_eq!(r.len(), 768);
    assert_eq!(r[10][0], 100, "the trigger sample at the trigger position");
    for (k, row) in r.iter().enumerate() {
        assert_eq!(row[0], 90 + k as i32, "oldest first");
    }
    // Done: the scope no longer samples.
    assert!(!s.running());
}

#[test]
fn trigger_waits_for_the_pre_trigger_fill() {
    let mut s = Scope::new(crate::dictionary::OBJECTS);
    one_channel_rising(&mut s);
    w32(&mut s, CONFIG, 3, 3).unwrap();
    w16(&mut s, CONFIG, 5, 20).unwrap();
    w8(&mut s, CONFIG, 7, command::ARM).unwrap();
    // A rising edge through 3 at sample 3 and again at sample 53 (a saw of 50).
    run(&mut s, 5000, |k| vec![(k % 50) as i32]);
    let r = record(&s);
    assert_eq!(rd(&s, STATUS, 3), 20);
    assert_eq!(r[20][0], 3);
    assert_eq!(r[19][0], 2);
    assert_eq!(r[0][0], 33, "the trigger at sample 53, 20 before it");
}

#[test]
fn falling_either_and_level_conditions() {
    assert!(condition_met(2, Some(5), 3, 4));
    assert!(condition_met(2, Some(5), 4, 4));
    assert!(!condition_met(2, Some(4), 3, 4), "already at the level");
    assert!(!condition_met(1, Some(5), 3, 4));
    assert!(condition_met(3, Some(5), 3, 4));
    assert!(condition_met(3, Some(3), 5, 4));
    assert!(!condition_met(3, Some(5), 6, 4));
    assert!(
        !condition_met(1, None, 10, 4),
        "no edge without a previous sample"
    );
    assert!(condition_met(4, None, 4, 4));
    assert!(!condition_met(4, None, 3, 4));
    assert!(condition_met(5, None, -7, -7));
    assert!(!condition_met(5, None, -6, -7));
    assert!(condition_met(0, None, 0, 1000));

    // A falling edge on the second of two channels (a triangle around 0).
    let mut s = Scope::new(crate::dictionary::OBJECTS);
    w8(&mut s, CHANNEL_LIST, 0, 2).unwrap();
    w8(&mut s, CONFIG, 2, 2).unwrap();
    w32(&mut s, CONFIG, 3, 0).unwrap();
    w8(&mut s, CONFIG, 4, 2).unwrap();
    w16(&mut s, CONFIG, 5, 5).unwrap();
    w8(&mut s, CONFIG, 7, command::ARM).unwrap();
    assert_eq!(s.depth(), 384);
    let tri = |k: usize| 20 - (k as i32 % 40 - 20).abs() - 10;
    run(&mut s, 5000, |k| vec![k as i32, tri(k)]);
    let r = record(&s);
    assert_eq!(r.len(), 384);
    assert_eq!(rd(&s, STATUS, 3), 5);
    let t = &r[5];
    assert!(
        t[1] <= 0 && r[4][1] > 0,
        "falling through 0: {:?} {:?}",
        r[4],
        t
    );
    assert_eq!(tri(t[0] as usize), t[1], "channels stay paired");
}

#[test]
fn divisor_samples_every_nth_tick() {
    let mut s = Scope::new(crate::dictionary::OBJECTS);
    w8(&mut s, CHANNEL_LIST, 0, 8).unwrap();
    w16(&mut s, CONFIG, 1, 4).unwrap();
    w8(&mut s, CONFIG, 4, 0).unwrap();
    w8(&mut s, CONFIG, 7, command::ARM).unwrap();
    assert_eq!(s.depth(), 96);
    let mut due = Vec::new();
    for tick in 0..12 {
        if s.sample_due() {
            due.push(tick);
            s.record(&[tick; 8]);
        }
    }
    assert_eq!(due, [0, 4, 8]);
    // Immediate trigger with no pre-trigger: the first sample is the trigger.
    let mut tick = 12;
    while s.running() {
        if s.sample_due() {
            s.record(&[tick; 8]);
        }
        tick += 1;
    }
    let r = record(&s);
    assert_eq!(r.len(), 96);
    assert_eq!(rd(&s, STATUS, 3), 0);
    for (k, row) in r.iter().enumerate() {
        assert_eq!(row, &[4 * k as i32; 8]);
    }
}

#[test]
fn force_trigger_before_the_pre_trigger_fill() {
    let mut s = Scope::new(crate::dictionary::OBJECTS);
    one_channel_rising(&mut s);
    w16(&mut s, CONFIG, 5, 100).unwrap();
    w32(&mut s, CONFIG, 3, 1_000_000).unwrap();
    w8(&mut s, CONFIG, 7, command::ARM).unwrap();
    for k in 0..30 {
        s.sample_due();
        s.record(&[k]);
    }
    assert_eq!(s.state(), State::Armed, "no edge through the level");
    w8(&mut s, CONFIG, 7, command::FORCE).unwrap();
    run(&mut s, 5000, |k| vec![30 + k as i32]);
    let r = record(&s);
    // 30 samples before the forced trigger, then depth − pre = 668 from it.
    assert_eq!(r.len(), 30 + 668);
    assert_eq!(rd(&s, STATUS, 3), 30);
    assert_eq!(r[30][0], 30);
    assert_eq!(r[0][0], 0);
    assert_eq!(rd(&s, STATUS, 2), 698);
}

#[test]
fn single_stays_done_normal_rearms_after_the_last_block() {
    let mut s = Scope::new(crate::dictionary::OBJECTS);
    w8(&mut s, CHANNEL_LIST, 0, 8).unwrap();
    w8(&mut s, CONFIG, 4, 0).unwrap();
    w8(&mut s, CONFIG, 7, command::ARM).unwrap();
    run(&mut s, 5000, |k| vec![k as i32; 8]);
    // 96 samples × 8 channels × 4 bytes = 3072 bytes: blocks 1-6.
    for sub in 1..=6 {
        s.block_read(sub);
    }
    assert_eq!(s.state(), State::Done, "single: done until armed again");

    w8(&mut s, CONFIG, 7, command::STOP).unwrap();
    assert_eq!(s.state(), State::Idle);
    let mut b = [0u8; BLOCK_BYTES];
    assert_eq!(s.read(DATA, 1, &mut b), Err(SdoAbort::NoDataAvailable));
    w8(&mut s, CONFIG, 6, 1).unwrap();
    w8(&mut s, CHANNEL_LIST, 0, 5).unwrap();
    w8(&mut s, CONFIG, 7, command::ARM).unwrap();
    assert_eq!(s.depth(), 153);
    run(&mut s, 5000, |k| vec![k as i32, 0, 0, 0, 0]);
    assert_eq!(rd(&s, STATUS, 5), 2);
    // 153 × 5 × 4 = 3060 bytes: the last block is block 6 with 500 bytes.
    assert_eq!(s.read(DATA, 6, &mut b), Ok(500));
    assert_eq!(s.read(DATA, 7, &mut b), Err(SdoAbort::SubindexDoesNotExist));
    for sub in 1..=5 {
        s.block_read(sub);
        assert_eq!(s.state(), State::Done);
    }
    s.block_read(6);
    assert_eq!(
        s.state(),
        State::Armed,
        "normal: re-armed after the last block"
    );
    run(&mut s, 5000, |k| vec![1000 + k as i32, 0, 0, 0, 0]);
    assert_eq!(rd(&s, STATUS, 5), 3);
    assert_eq!(record(&s)[0][0], 1000);
}

#[test]
fn short_record_ends_early_in_the_blocks() {
    let mut s = Scope::new(crate::dictionary::OBJECTS);
    one_channel_rising(&mut s);
    w8(&mut s, CONFIG, 4, 0).unwrap();
    w16(&mut s, CONFIG, 5, 700).unwrap();
    w8(&mut s, CONFIG, 7, command::ARM).unwrap();
    // Immediate, but the trigger waits for 700 samples; forced at once instead.
    w8(&mut s, CONFIG, 7, command::FORCE).unwrap();
    run(&mut s, 5000, |k| vec![-(k as i32)]);
    assert_eq!(rd(&s, STATUS, 2), 68);
    let r = record(&s);
    assert_eq!(r.len(), 68);
    assert_eq!(r[67][0], -67);
    let mut b = [0u8; BLOCK_BYTES];
    assert_eq!(s.read(DATA, 1, &mut b), Ok(272));
    assert_eq!(s.read(DATA, 2, &mut b), Err(SdoAbort::NoDataAvailable));
    let mut small = [0u8; 8];
    assert_eq!(s.read(DATA, 1, &mut small), Err(SdoAbort::ExceedsMailbox));
}

#[test]
fn bad_configuration_gets_the_standard_aborts() {
    let mut s = Scope::new(crate::dictionary::OBJECTS);
    // The table's ranges.
    assert_eq!(w16(&mut s, CONFIG, 1, 0), Err(SdoAbort::ValueTooLow));
    assert_eq!(w16(&mut s, CONFIG, 1, 1001), Err(SdoAbort::ValueTooHigh));
    assert_eq!(w8(&mut s, CONFIG, 2, 0), Err(SdoAbort::ValueTooLow));
    assert_eq!(w8(&mut s, CONFIG, 2, 9), Err(SdoAbort::ValueTooHigh));
    assert_eq!(w8(&mut s, CONFIG, 4, 6), Err(SdoAbort::ValueTooHigh));
    assert_eq!(w16(&mut s, CONFIG, 5, 768), Err(SdoAbort::ValueTooHigh));
    assert_eq!(w8(&mut s, CONFIG, 6, 2), Err(SdoAbort::ValueTooHigh));
    assert_eq!(w8(&mut s, CONFIG, 7, 3), Err(SdoAbort::ValueTooHigh));
    assert_eq!(w8(&mut s, CHANNEL_LIST, 0, 9), Err(SdoAbort::ValueTooHigh));
    assert_eq!(s.write(CONFIG, 1, &[1]), Err(SdoAbort::LengthTooLow));
    assert_eq!(s.write(CONFIG, 3, &[0; 5]), Err(SdoAbort::LengthTooHigh));
    // Read-only and missing entries.
    assert_eq!(w8(&mut s, STATUS, 1, 0), Err(SdoAbort::WriteReadOnly));
    assert_eq!(w8(&mut s, CONFIG, 0, 7), Err(SdoAbort::WriteReadOnly));
    assert_eq!(
        w8(&mut s, CONFIG, 9, 0),
        Err(SdoAbort::SubindexDoesNotExist)
    );
    assert_eq!(w8(&mut s, 0x2504, 0, 0), Err(SdoAbort::ObjectDoesNotExist));
    // Channels: the PDO mapping entry rules.
    for (v, abort) in [
        (0u32, SdoAbort::NotMappable),
        (0x6040_0010, SdoAbort::NotMappable), // controlword: Rx, mappable → accepted below
        (0x1000_0020, SdoAbort::NotMappable), // device type: not mappable
        (0x2001_0020, SdoAbort::NotMappable), // a parameter: not mappable
        (0x6064_0010, SdoAbort::ParameterIncompatibility), // 32-bit entry as 16
        (0x6064_0120, SdoAbort::NotMappable), // no sub-index 1
        (0x7000_0020, SdoAbort::NotMappable), // no object
        (0x2503_0100, SdoAbort::NotMappable), // the scope's own data
    ] {
        let r = w32(&mut s, CHANNEL_LIST, 1, v);
        if v == 0x6040_0010 {
            assert_eq!(r, Ok(()), "an RxPDO entry is a channel too");
        } else {
            assert_eq!(r, Err(abort), "{v:#010x}");
        }
    }
    // Arming checks the whole configuration.
    w8(&mut s, CHANNEL_LIST, 0, 0).unwrap();
    assert_eq!(
        w8(&mut s, CONFIG, 7, command::ARM),
        Err(SdoAbort::ParameterIncompatibility),
        "no channel"
    );
    w8(&mut s, CHANNEL_LIST, 0, 2).unwrap();
    w8(&mut s, CONFIG, 2, 3).unwrap();
    assert_eq!(
        w8(&mut s, CONFIG, 7, command::ARM),
        Err(SdoAbort::ParameterIncompatibility),
        "trigger channel beyond the channels"
    );
    w8(&mut s, CONFIG, 2, 2).unwrap();
    w16(&mut s, CONFIG, 5, 384).unwrap();
    assert_eq!(
        w8(&mut s, CONFIG, 7, command::ARM),
        Err(SdoAbort::ParameterIncompatibility),
        "pre-trigger not below 384 samples per channel"
    );
    assert_eq!(s.state(), State::Idle);
    assert_eq!(
        w8(&mut s, CONFIG, 7, command::FORCE),
        Err(SdoAbort::StateConflict),
        "force while idle"
    );
    w16(&mut s, CONFIG, 5, 383).unwrap();
    w8(&mut s, CONFIG, 7, command::ARM).unwrap();
    // Armed: configuration refused, commands accepted.
    assert_eq!(w16(&mut s, CONFIG, 1, 2), Err(SdoAbort::StateConflict));
    assert_eq!(
        w32(&mut s, CHANNEL_LIST, 1, 0x6064_0020),
        Err(SdoAbort::StateConflict)
    );
    assert_eq!(w8(&mut s, CHANNEL_LIST, 0, 1), Err(SdoAbort::StateConflict));
    assert_eq!(rd(&s, CONFIG, 7), 1);
    w8(&mut s, CONFIG, 7, command::ARM).unwrap();
    w8(&mut s, CONFIG, 7, command::FORCE).unwrap();
    w8(&mut s, CONFIG, 7, command::STOP).unwrap();
    assert_eq!(rd(&s, CONFIG, 7), 0);
    w16(&mut s, CONFIG, 1, 2).unwrap();
    assert_eq!(rd(&s, CONFIG, 1), 2);
}

#[test]
fn sources_decode_their_entries() {
    let s = Source::resolve(crate::dictionary::OBJECTS, 0x6078_0010).unwrap();
    assert_eq!(s.decode(0xFFFF), -1);
    assert_eq!(s.decode(0x1_7FFF), 0x7FFF, "only the entry's bits");
    let u = Source::resolve(crate::dictionary::OBJECTS, 0x2305_0010).unwrap();
    assert_eq!(u.decode(0xFFFF), 0xFFFF);
    assert_eq!(u.slot, None);
    let p = Source::resolve(crate::dictionary::OBJECTS, 0x6064_0020).unwrap();
    assert_eq!(p.decode(0xFFFF_FFFE), -2);
    assert_eq!(
        p.slot,
        crate::cia402::objects::tx_slot(0x6064, 0),
        "CiA 402 entries read through their slot"
    );
    assert!(p.slot.is_some());
    let b = Source::resolve(crate::dictionary::OBJECTS, 0x2510_0410).unwrap();
    assert_eq!(b.decode(0x0000_0009), 9);
}

/// An SDO download into the drive as the stack does it: the generic checks of the
/// entry, then the drive's write.
fn sdo_write(
    d: &mut crate::drive::Drive,
    index: u16,
    sub: u8,
    data: &[u8],
) -> Result<(), SdoAbort> {
    use ecat_slave_stack::esm::EsmState;
    use ecat_slave_stack::od::Dictionary;
    let e = od::find_entry(crate::dictionary::OBJECTS, ObjectKey::new(index, sub))?;
    od::check_write(e, data, EsmState::PreOp)?;
    d.write(ObjectKey::new(index, sub), data, EsmState::PreOp)
}

/// The scope in the drive: armed over the dictionary, sampled by the supervision tick
/// (a CiA 402 slot, a dictionary read, the internal signals), read back block by
/// block; normal mode re-arms after the last block.
#[test]
fn the_drive_samples_on_its_tick() {
    use crate::drive::{AxisState, Drive};
    use crate::identity::Variant;
    use ecat_slave_stack::od::Dictionary;

    let mut d = Drive::new(Variant::HybridServo, 1);
    let w = sdo_write;
    w(&mut d, CHANNEL_LIST, 0, &[0]).unwrap();
    for (sub, ch) in [0x6064_0020u32, 0x2305_0010, 0x2510_0120, 0x2510_0320]
        .into_iter()
        .enumerate()
    {
        w(&mut d, CHANNEL_LIST, sub as u8 + 1, &ch.to_le_bytes()).unwrap();
    }
    w(&mut d, CHANNEL_LIST, 0, &[4]).unwrap();
    w(&mut d, CONFIG, 1, &2u16.to_le_bytes()).unwrap();
    w(&mut d, CONFIG, 3, &5000i32.to_le_bytes()).unwrap();
    w(&mut d, CONFIG, 5, &10u16.to_le_bytes()).unwrap();
    w(&mut d, CONFIG, 6, &[1]).unwrap();
    assert_eq!(w(&mut d, SIGNALS, 1, &[0; 4]), Err(SdoAbort::WriteReadOnly));
    w(&mut d, CONFIG, 7, &[command::ARM]).unwrap();
    assert_eq!(d.scope.depth(), 192);
    let axis = |t: u64| AxisState {
        position: t as i32 * 100,
        bus_mv: 24_000 + t as u32,
        servo_following_error: -(t as i32),
        ..AxisState::default()
    };
    for t in 1..=600u64 {
        d.set_axis(axis(t));
        d.tick(t * 1000, 0);
    }
    assert_eq!(d.scope.state(), State::Done);
    let mut b = [0u8; BLOCK_BYTES];
    let mut status = |d: &mut Drive, sub: u8| {
        let n = d.read(ObjectKey::new(STATUS, sub), &mut b).unwrap();
        od::decode_int(DataType::Unsigned16, &b[..n]).unwrap()
    };
    assert_eq!(status(&mut d, 2), 192);
    assert_eq!(status(&mut d, 3), 10);
    // 192 samples × 4 channels × 4 bytes: blocks 1-6, the last one ends the record.
    let mut rows = Vec::new();
    for sub in 1..=BLOCKS as u8 {
        let n = d.read(ObjectKey::new(DATA, sub), &mut b).unwrap();
        assert_eq!(n, BLOCK_BYTES);
        let words: Vec<i32> = b[..n]
            .chunks_exact(4)
            .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        rows.extend(words.chunks(4).map(|c| c.to_vec()));
        let rearmed = d.scope.state() == State::Armed;
        assert_eq!(rearmed, sub == BLOCKS as u8, "re-armed after block {sub}");
    }
    // Ticks 1, 3, 5, …: the edge through 5000 is tick 51, ten samples before it 31.
    for (k, row) in rows.iter().enumerate() {
        let t = 31 + 2 * k as i32;
        assert_eq!(row[0], t * 100, "0x6064 at sample {k}");
        assert_eq!(row[1], (24_000 + t) / 10, "0x2305 at sample {k}");
        assert_eq!(row[2], -t, "0x2510:01 at sample {k}");
        assert_eq!(row[3], 24_000 + t, "0x2510:03 at sample {k}");
    }
    assert_eq!(rows[10][0], 5100);
    // Disarmed, the tick leaves the record alone.
    w(&mut d, CONFIG, 7, &[command::STOP]).unwrap();
    d.tick(601_000, 0);
    assert_eq!(d.scope.state(), State::Idle);
    assert_eq!(
        d.read(ObjectKey::new(DATA, 1), &mut b),
        Err(SdoAbort::NoDataAvailable)
    );
}

/// The scope at the servo rate (0x2500:08 = 1): the control path's points are the
/// samples (every divisor-th), the 0x2510 channels from each point, the others as the
/// objects stand; the tick takes no sample of its own; the drive asks for points only
/// while it records so.
#[test]
fn the_drive_samples_the_servo_points_at_the_servo_rate() {
    use crate::drive::{AxisState, Drive};
    use crate::identity::Variant;
    use ecat_slave_stack::od::Dictionary;

    let mut d = Drive::new(Variant::HybridServo, 1);
    let w = sdo_write;
    w(&mut d, CHANNEL_LIST, 0, &[0]).unwrap();
    for (sub, ch) in [0x2510_0710u32, 0x2510_0520, 0x6064_0020]
        .into_iter()
        .enumerate()
    {
        w(&mut d, CHANNEL_LIST, sub as u8 + 1, &ch.to_le_bytes()).unwrap();
    }
    w(&mut d, CHANNEL_LIST, 0, &[3]).unwrap();
    assert_eq!(w(&mut d, CONFIG, 8, &[2]), Err(SdoAbort::ValueTooHigh));
    w(&mut d, CONFIG, 8, &[1]).unwrap();
    w(&mut d, CONFIG, 1, &3u16.to_le_bytes()).unwrap();
    w(&mut d, CONFIG, 3, &500i32.to_le_bytes()).unwrap();
    w(&mut d, CONFIG, 5, &4u16.to_le_bytes()).unwrap();
    assert!(!d.scope_wants_servo_points(), "not armed yet");
    w(&mut d, CONFIG, 7, &[command::ARM]).unwrap();
    assert!(d.scope_wants_servo_points());
    assert_eq!(
        w(&mut d, CONFIG, 8, &[0]),
        Err(SdoAbort::StateConflict),
        "no change while recording"
    );
    d.set_axis(AxisState {
        position: 777,
        ..AxisState::default()
    });
    // Ten servo points per tick: the current demand steps by 10 per mille a point.
    let mut k = 0i16;
    for t in 1..=100u64 {
        for _ in 0..10 {
            k += 1;
            let p = ServoPoint {
                current_demand: 10 * k,
                position: 1000 + i32::from(k),
                ..ServoPoint::default()
            };
            d.scope_servo_point(&p);
        }
        d.tick(t * 1000, 0);
        if d.scope.state() == State::Done {
            break;
        }
    }
    assert_eq!(d.scope.state(), State::Done);
    assert!(!d.scope_wants_servo_points(), "done");
    let depth = usize::from(d.scope.depth());
    assert_eq!(depth, BUFFER_WORDS / 3);
    let rows = record(&d.scope);
    assert_eq!(rows.len(), depth);
    // Points 1, 4, 7, …: the edge through 500 is point 52 (520 ≥ 500 > 490), four
    // samples before it 40.
    for (n, row) in rows.iter().enumerate() {
        let k = 40 + 3 * n as i32;
        assert_eq!(row[0], 10 * k, "0x2510:07 at sample {n}");
        assert_eq!(row[1], 1000 + k, "0x2510:05 at sample {n}");
        assert_eq!(row[2], 777, "0x6064 as the object stands");
    }
    // The internal signals read over SDO are the axis state's.
    let mut b = [0u8; 4];
    let n = d.read(ObjectKey::new(SIGNALS, 5), &mut b).unwrap();
    assert_eq!(od::decode_int(DataType::Integer32, &b[..n]), Some(777));
}
