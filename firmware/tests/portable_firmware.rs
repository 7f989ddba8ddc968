//! Drive-level tests of the firmware library that run on the host and under QEMU:
//! the merged dictionary and the drive application seen through it.
#![cfg_attr(target_os = "none", no_std, no_main)]

use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::od::{self, Dictionary, ObjectKey, SdoAbort};
use firmware::cia402::pds::PdsState;
use firmware::dictionary::OBJECTS;
use firmware::drive::{AxisState, Drive};
use firmware::identity::Variant;

fn write(d: &mut Drive, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoAbort> {
    let e = od::find_entry(OBJECTS, ObjectKey::new(index, sub))?;
    od::check_write(e, data, EsmState::PreOp)?;
    d.write(ObjectKey::new(index, sub), data, EsmState::PreOp)
}

qemu_runner::tests! {
    fn dictionary_is_sorted_with_sorted_entries() {
        assert!(od::is_well_formed(OBJECTS));
        assert!(OBJECTS.len() > 60);
    }

    fn every_readable_entry_reads_without_error() {
        let mut d = Drive::new(Variant::HybridServo, 1);
        let mut buf = [0u8; 64];
        for o in OBJECTS {
            // Mapping/sync objects are served by the slave runtime, not the drive.
            if (0x1600..=0x1C33).contains(&o.index) || o.index == 0x2200 {
                continue;
            }
            for e in o.entries() {
                if o.index == firmware::scope::DATA && e.sub > 0 {
                    // The scope's blocks: no record yet.
                    assert_eq!(d.read(ObjectKey::new(o.index, e.sub), &mut buf), Err(SdoAbort::NoDataAvailable));
                    continue;
                }
                if e.access.readable() {
                    let n = d.read(ObjectKey::new(o.index, e.sub), &mut buf);
                    assert!(n.is_ok(), "{:#06x}:{} read failed: {:?}", o.index, e.sub, n);
                    if !e.data_type.is_variable_length() {
                        assert_eq!(n.unwrap_or(0), e.byte_len(), "{:#06x}:{} length", o.index, e.sub);
                    }
                }
            }
        }
    }

    fn range_edges_of_vendor_parameters() {
        let mut d = Drive::new(Variant::HybridServo, 1);
        let mut above_checked = 0;
        for o in OBJECTS.iter().filter(|o| (0x2000..=0x21FF).contains(&o.index)) {
            for e in o.entries().iter().filter(|e| e.access.writable() && e.byte_len() <= 4 && e.max() > e.min()) {
                let n = e.byte_len();
                // 0x2000's upper edge is the variant's (the table holds the largest).
                let max = match (o.index, e.sub) {
                    (0x2000, 0) => i64::from(Variant::HybridServo.max_peak_current_ma()),
                    _ => e.max(),
                };
                let lo = (e.min() as i32).to_le_bytes();
                let hi = (max as u32).to_le_bytes();
                // Edges accepted unless the product forbids the write in this state.
                let r_lo = write(&mut d, o.index, e.sub, &lo[..n]);
                let r_hi = write(&mut d, o.index, e.sub, &hi[..n]);
                for r in [r_lo, r_hi] {
                    assert!(r.is_ok() || r == Err(SdoAbort::LocalControl) || r == Err(SdoAbort::WriteReadOnly)
                        || r == Err(SdoAbort::StateConflict),
                        "{:#06x}:{} edge refused: {:?}", o.index, e.sub, r);
                }
                if max < i64::from(u32::MAX) && n == 4 || (n < 4 && max < (1i64 << (8 * n)) - 1) {
                    let above = ((max + 1) as u32).to_le_bytes();
                    assert_eq!(write(&mut d, o.index, e.sub, &above[..n]), Err(SdoAbort::ValueTooHigh),
                        "{:#06x}:{} above max", o.index, e.sub);
                    above_checked += 1;
                }
            }
        }
        assert!(above_checked >= 20, "only {above_checked} parameters checked above their maximum");
    }

    fn enable_and_quick_stop() {
        let mut d = Drive::new(Variant::HybridServo, 1);
        d.set_axis(AxisState { bus_mv: 48_000, ..AxisState::default() });
        for cw in [0x06u16, 0x07, 0x0F] {
            d.cia402.set_controlword(cw);
            for _ in 0..3 {
                d.run_cycle(0.001);
            }
        }
        assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
        d.cia402.set_controlword(0x0B); // quick stop
        for _ in 0..2000 {
            d.run_cycle(0.001);
        }
        assert!(matches!(d.cia402.state(), PdsState::SwitchOnDisabled | PdsState::QuickStopActive));
        assert!(!d.command().drive_enabled || d.cia402.state() == PdsState::QuickStopActive);
    }
}
