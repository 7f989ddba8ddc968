//! The board self-test for the first power-up (`cargo flash --features selftest`):
//! what each check concludes from what the board measured.
//!
//! The board image built with the `selftest` feature never enables the bridges. It
//! runs these checks once at start-up, prints one `PASS` / `FAIL` line per check over
//! defmt and a summary line, and then idles with the power stage off. The peripheral
//! work (SPI, GPIO, ADC, timers, flash) is in the board binary; every decision is here,
//! where host and QEMU tests run it against the ESC chip models, RAM flash and
//! made-up readings.
//!
//! | check | what it proves | a FAIL points at |
//! |---|---|---|
//! | ESC identity | the SPI wiring, clock and mode reach the chip the image was built for (type register 0x0000) | SPI pins, chip select, ESC supply or clock, wrong ESC flavour |
//! | process RAM | a word of process RAM keeps two complementary patterns | SPI data lines (a stuck MOSI/MISO bit), the LAN9252 FIFO path |
//! | DIP banks | repeated matrix scans agree | a floating column, a missing pull-up, a broken row driver |
//! | current offsets | both sensors read their zero-current offset with little noise (fault 9's check) | current-sense amplifier, reference, ADC input |
//! | bus voltage | the bus divider reads a voltage inside the drive's operating window | divider, ADC channel, supply |
//! | encoder | the encoder counts when the shaft is turned by hand | encoder supply, A/B wiring, timer pins |
//! | LEDs, outputs, brake | each pin follows its driven level at the pad (input data register) | a shorted or overloaded output, a missing part |
//! | parameter slot | a 'save' of the present parameters lands in the spare slot as a valid record that loads back | flash option bytes, the parameter region |
//! | break input | the pin sits at its inactive level, a forced break turns the outputs off and is latched, and it re-arms | gate-driver fault line, break polarity, the break interrupt |
use ecat_slave_stack::EscAccess;
use embedded_storage::nor_flash::NorFlash;

use crate::sampling::{OffsetFault, Offsets};
use crate::storage::{SlotStatus, Storage};

/// The result of one check.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// The check passed.
    Pass,
    /// The check failed, with what was seen.
    Fail(&'static str),
}

impl Verdict {
    /// True for [`Verdict::Pass`].
    pub fn passed(self) -> bool {
        self == Verdict::Pass
    }
}

/// Counts the verdicts for the summary line.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Summary {
    /// Checks that passed.
    pub passed: u8,
    /// Checks that failed.
    pub failed: u8,
}

impl Summary {
    /// Counts `v` and hands it back (for the check's own line).
    pub fn add(&mut self, v: Verdict) -> Verdict {
        match v {
            Verdict::Pass => self.passed = self.passed.saturating_add(1),
            Verdict::Fail(_) => self.failed = self.failed.saturating_add(1),
        }
        v
    }

    /// No check failed, and at least one ran.
    pub fn all_passed(&self) -> bool {
        self.failed == 0 && self.passed > 0
    }
}

/// A process-RAM word no default SyncManager uses: the last four bytes of the
/// LAN9252's 4 KiB (the ET1100 has 8 KiB, so it is free there as well). The slave
/// runtime has not configured any SyncManager while the self-test runs.
pub const SCRATCH_PRAM: u16 = 0x1FFC;

/// The ESC type register (0x0000) names the chip the image was built for.
pub fn esc_identity<E: EscAccess + ?Sized>(esc: &mut E, expected_type: u8) -> Verdict {
    match esc.get(ecat_slave_stack::registers::ESC_TYPE) {
        Ok(t) if t == expected_type => Verdict::Pass,
        Ok(0x00) | Ok(0xFF) => Verdict::Fail("type register reads 0x00/0xFF: no chip on the bus"),
        Ok(_) => Verdict::Fail("type register names another ESC than this image's"),
        Err(_) => Verdict::Fail("the ESC driver reported an error"),
    }
}

/// Writes two complementary patterns to the process-RAM word at `addr`, reads each
/// back, and leaves the word zero. Every data bit is seen at 0 and at 1 both ways.
pub fn process_ram_word<E: EscAccess + ?Sized>(esc: &mut E, addr: u16) -> Verdict {
    for pattern in [0xA55A_0FF0u32, 0x5AA5_F00F] {
        let mut back = [0u8; 4];
        if esc.write(addr, &pattern.to_le_bytes()).is_err() || esc.read(addr, &mut back).is_err() {
            return Verdict::Fail("the ESC driver reported an error");
        }
        if u32::from_le_bytes(back) != pattern {
            return Verdict::Fail("the word read back differs from the one written");
        }
    }
    if esc.write(addr, &[0; 4]).is_err() {
        return Verdict::Fail("the ESC driver reported an error");
    }
    Verdict::Pass
}

/// Repeated scans of the DIP matrix agree (the value itself is the user's choice).
pub fn dip_stable<T: PartialEq>(scans: &[T]) -> Verdict {
    match scans.split_first() {
        None => Verdict::Fail("no scan"),
        Some((first, rest)) if rest.iter().all(|s| s == first) => Verdict::Pass,
        Some(_) => Verdict::Fail("scans disagree: a floating column or a bouncing switch"),
    }
}

/// The current sensors' offset calibration (the drive's fault 9 check at power-up).
pub fn current_offsets(result: &Result<Offsets, OffsetFault>) -> Verdict {
    match result {
        Ok(_) => Verdict::Pass,
        Err(OffsetFault::TooFewSamples { .. }) => {
            Verdict::Fail("too few samples: the PWM/ADC chain is not running")
        }
        Err(OffsetFault::OutOfRange { .. }) => {
            Verdict::Fail("offset outside its window: sensor, reference or ADC input")
        }
        Err(OffsetFault::Noisy { .. }) => Verdict::Fail("samples spread too wide: noisy sensor"),
    }
}

/// The bus voltage, mV, lies inside the drive's operating window (`min_mv` = the
/// under-voltage threshold, `max_mv` = the over-voltage threshold).
pub fn bus_voltage(mv: u32, min_mv: u32, max_mv: u32) -> Verdict {
    if mv < 500 {
        Verdict::Fail("about 0 V: no supply or an open divider")
    } else if mv < min_mv {
        Verdict::Fail("below the under-voltage threshold")
    } else if mv > max_mv {
        Verdict::Fail("above the over-voltage threshold")
    } else {
        Verdict::Pass
    }
}

/// Watches the encoder count while the user turns the shaft: passes once the count
/// has moved `needed` counts away from where it started, either way.
#[derive(Debug, Clone, Copy)]
pub struct EncoderTurn {
    start: u32,
    needed: u32,
    moved: u32,
}

impl EncoderTurn {
    /// Starts at count `start` (the timer's raw counter, wrapping).
    pub fn new(start: u32, needed: u32) -> Self {
        EncoderTurn {
            start,
            needed,
            moved: 0,
        }
    }

    /// Takes a new count; true once the shaft has turned far enough.
    pub fn update(&mut self, count: u32) -> bool {
        let d = count.wrapping_sub(self.start) as i32;
        self.moved = self.moved.max(d.unsigned_abs());
        self.done()
    }

    /// The shaft has turned far enough.
    pub fn done(&self) -> bool {
        self.moved >= self.needed
    }

    /// The largest distance from the start seen so far, counts.
    pub fn moved(&self) -> u32 {
        self.moved
    }

    /// The verdict when the time for turning is over.
    pub fn verdict(&self) -> Verdict {
        if self.done() {
            Verdict::Pass
        } else if self.moved == 0 {
            Verdict::Fail("no counts: encoder supply or A/B wiring")
        } else {
            Verdict::Fail("too few counts: turn further, or a channel is missing")
        }
    }
}

/// An output's pad level (read from the input data register) with the pin driven
/// high and then low.
pub fn pin_follows(reads_high_when_high: bool, reads_high_when_low: bool) -> Verdict {
    match (reads_high_when_high, reads_high_when_low) {
        (true, false) => Verdict::Pass,
        (false, false) => Verdict::Fail("stuck low: short to ground or overload"),
        (true, true) => Verdict::Fail("stuck high: short to the supply"),
        (false, true) => Verdict::Fail("inverted: wrong pin"),
    }
}

/// Where the next 'save' goes: the spare slot (the one that does not hold the newest
/// record) and the sequence number it gets. The parameter-slot check takes this,
/// runs the drive's own 'save' of the present parameters (0x1010:01, through the
/// runtime objects so the PDO mapping is kept), programs it, and reads it back with
/// [`record_check`]. The saved values are the ones in use, so the drive starts with
/// the same parameters; the record replaced is the older, spare one.
pub fn record_probe<F: NorFlash>(store: &Storage, flash: &mut F) -> RecordProbe {
    let newest = store.scan(flash).1;
    RecordProbe {
        spare: newest.map_or(0, |(slot, _, _)| 1 - slot),
        sequence: newest.map_or(1, |(_, seq, _)| seq.wrapping_add(1)),
    }
}

/// Where the self-test's 'save' is expected ([`record_probe`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RecordProbe {
    /// The slot a save writes.
    pub spare: usize,
    /// The sequence number it gets.
    pub sequence: u32,
}

/// Reads back the record the self-test's save wrote (see [`record_probe`]).
pub fn record_check<F: NorFlash>(store: &Storage, flash: &mut F, probe: RecordProbe) -> Verdict {
    match store.slot_status(flash, probe.spare) {
        SlotStatus::Valid { sequence, .. } if sequence == probe.sequence => {
            match store.scan(flash).1 {
                Some((slot, seq, _)) if slot == probe.spare && seq == probe.sequence => {
                    Verdict::Pass
                }
                _ => Verdict::Fail("the record is valid but not the newest"),
            }
        }
        SlotStatus::Valid { .. } => Verdict::Fail("the spare slot holds another record"),
        SlotStatus::Erased => Verdict::Fail("the spare slot is still erased: nothing programmed"),
        SlotStatus::Corrupt => Verdict::Fail("the record read back is corrupt"),
    }
}

/// What the break check saw, in the order it does it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BreakObservation {
    /// A break input pin was at its active level before anything was forced.
    pub active_at_rest: bool,
    /// After a forced break event: the timers' main outputs are off.
    pub outputs_off_after_force: bool,
    /// After a forced break event: the break was latched (flag and the drive's latch).
    pub latched_after_force: bool,
    /// The latch re-armed once the break was over.
    pub rearmed: bool,
}

/// The break input's path: inactive at rest, a forced break cuts the outputs and is
/// latched, and it re-arms.
pub fn break_path(o: BreakObservation) -> Verdict {
    if o.active_at_rest {
        Verdict::Fail("break input active at rest: gate-driver fault line or polarity")
    } else if !o.outputs_off_after_force {
        Verdict::Fail("a break did not turn the outputs off")
    } else if !o.latched_after_force {
        Verdict::Fail("a break was not latched (break interrupt)")
    } else if !o.rearmed {
        Verdict::Fail("the break latch did not re-arm")
    } else {
        Verdict::Pass
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ecat_slave_stack::od::ObjectKey;

    #[test]
    fn summary_counts_and_needs_one_check() {
        let mut s = Summary::default();
        assert!(!s.all_passed());
        assert_eq!(s.add(Verdict::Pass), Verdict::Pass);
        assert!(s.all_passed());
        s.add(Verdict::Fail("x"));
        assert_eq!((s.passed, s.failed), (1, 1));
        assert!(!s.all_passed());
    }

    #[test]
    fn dip_scans_must_agree() {
        assert_eq!(dip_stable(&[(1u8, 2u8); 4]), Verdict::Pass);
        assert!(!dip_stable(&[(1u8, 2u8), (1, 2), (1, 3)]).passed());
        assert!(!dip_stable::<u8>(&[]).passed());
    }

    #[test]
    fn bus_voltage_window() {
        assert!(bus_voltage(24_000, 18_000, 60_000).passed());
        assert!(!bus_voltage(0, 18_000, 60_000).passed());
        assert!(!bus_voltage(12_000, 18_000, 60_000).passed());
        assert!(!bus_voltage(70_000, 18_000, 60_000).passed());
    }

    #[test]
    fn encoder_turn_either_way_and_across_the_wrap() {
        let mut e = EncoderTurn::new(5, 100);
        assert!(!e.update(50));
        assert_eq!(
            e.verdict(),
            Verdict::Fail("too few counts: turn further, or a channel is missing")
        );
        assert!(e.update(5u32.wrapping_sub(100)));
        assert!(e.verdict().passed());
        let idle = EncoderTurn::new(u32::MAX, 10);
        assert_eq!(
            idle.verdict(),
            Verdict::Fail("no counts: encoder supply or A/B wiring")
        );
        let mut wrap = EncoderTurn::new(u32::MAX - 3, 10);
        assert!(wrap.update(7));
    }

    #[test]
    fn pins_must_follow() {
        assert!(pin_follows(true, false).passed());
        for (h, l) in [(false, false), (true, true), (false, true)] {
            assert!(!pin_follows(h, l).passed());
        }
    }

    #[test]
    fn break_path_in_order() {
        let good = BreakObservation {
            active_at_rest: false,
            outputs_off_after_force: true,
            latched_after_force: true,
            rearmed: true,
        };
        assert!(break_path(good).passed());
        for bad in [
            BreakObservation {
                active_at_rest: true,
                ..good
            },
            BreakObservation {
                outputs_off_after_force: false,
                ..good
            },
            BreakObservation {
                latched_after_force: false,
                ..good
            },
            BreakObservation {
                rearmed: false,
                ..good
            },
        ] {
            assert!(!break_path(bad).passed());
        }
    }

    #[test]
    fn offsets_map_to_verdicts() {
        assert!(current_offsets(&Ok(Offsets {
            ia: 2048.0,
            ib: 2050.0
        }))
        .passed());
        for e in [
            OffsetFault::TooFewSamples { got: 1, wanted: 8 },
            OffsetFault::OutOfRange {
                phase: crate::sampling::Phase::B,
                mean: 100,
            },
            OffsetFault::Noisy {
                phase: crate::sampling::Phase::A,
                spread: 400,
            },
        ] {
            assert!(!current_offsets(&Err(e)).passed());
        }
    }

    #[test]
    fn record_round_trip_through_the_drive_save() {
        use crate::drive::{Drive, FlashStore, NoRuntime};
        use crate::identity::Variant;
        use crate::storage::RamFlash;
        use ecat_slave_stack::esm::EsmState;
        use ecat_slave_stack::od::Dictionary;

        let storage = Storage::new(0, 4096);
        let mut d = Drive::with_store(
            Variant::HybridServo,
            3,
            FlashStore {
                storage,
                history: None,
                flash: RamFlash::<8192>::new(),
            },
        );
        d.power_up(&mut NoRuntime);
        d.write(
            ObjectKey::new(0x2000, 0),
            &2100u16.to_le_bytes(),
            EsmState::PreOp,
        )
        .expect("2000");
        let save = u32::from_le_bytes(*b"save").to_le_bytes();
        for (round, spare) in [(1u32, 0usize), (2, 1), (3, 0)] {
            let st = d.store_mut().expect("store");
            let probe = record_probe(&storage, &mut st.flash);
            assert_eq!(
                probe,
                RecordProbe {
                    spare,
                    sequence: round
                }
            );
            d.write_with_runtime(
                ObjectKey::new(0x1010, 1),
                &save,
                EsmState::PreOp,
                &mut NoRuntime,
            )
            .expect("save");
            let st = d.store_mut().expect("store");
            assert_eq!(record_check(&storage, &mut st.flash, probe), Verdict::Pass);
        }
        // A save that never reached the flash (power cut at once) is a FAIL, and the
        // parameters in the other slot still load.
        let st = d.store_mut().expect("store");
        let probe = record_probe(&storage, &mut st.flash);
        st.flash.cut_power_after(0);
        let _ = d.write_with_runtime(
            ObjectKey::new(0x1010, 1),
            &save,
            EsmState::PreOp,
            &mut NoRuntime,
        );
        let st = d.store_mut().expect("store");
        st.flash.power_on();
        assert!(!record_check(&storage, &mut st.flash, probe).passed());
        let flash = core::mem::take(&mut d.store_mut().expect("store").flash);
        let mut d2 = Drive::with_store(
            Variant::HybridServo,
            3,
            FlashStore {
                storage,
                history: None,
                flash,
            },
        );
        assert!(d2.power_up(&mut NoRuntime).source.is_some());
        let mut b = [0u8; 8];
        d2.read(ObjectKey::new(0x2000, 0), &mut b).expect("read");
        assert_eq!(u16::from_le_bytes([b[0], b[1]]), 2100);
    }

    #[test]
    fn esc_checks_against_a_memory_esc() {
        /// An ESC of plain memory; `stuck` forces a data bit to 1 on reads.
        struct MemEsc {
            mem: [u8; 0x3000],
            stuck: u8,
            fail: bool,
        }
        impl EscAccess for MemEsc {
            fn read(
                &mut self,
                addr: u16,
                buf: &mut [u8],
            ) -> Result<(), ecat_slave_stack::EscError> {
                if self.fail {
                    return Err(ecat_slave_stack::EscError::Timeout);
                }
                for (i, b) in buf.iter_mut().enumerate() {
                    *b = self.mem[usize::from(addr) + i] | self.stuck;
                }
                Ok(())
            }
            fn write(&mut self, addr: u16, data: &[u8]) -> Result<(), ecat_slave_stack::EscError> {
                self.mem[usize::from(addr)..usize::from(addr) + data.len()].copy_from_slice(data);
                Ok(())
            }
        }
        let mut esc = MemEsc {
            mem: [0; 0x3000],
            stuck: 0,
            fail: false,
        };
        esc.mem[0] = 0x11;
        assert_eq!(esc_identity(&mut esc, 0x11), Verdict::Pass);
        assert!(!esc_identity(&mut esc, 0xC0).passed());
        assert_eq!(process_ram_word(&mut esc, SCRATCH_PRAM), Verdict::Pass);
        assert_eq!(
            esc.mem[usize::from(SCRATCH_PRAM)..][..4],
            [0; 4],
            "left zero"
        );
        esc.stuck = 0x04;
        assert!(!process_ram_word(&mut esc, SCRATCH_PRAM).passed());
        assert!(!esc_identity(&mut esc, 0x11).passed());
        esc.stuck = 0;
        esc.fail = true;
        assert!(!esc_identity(&mut esc, 0x11).passed());
        assert!(!process_ram_word(&mut esc, SCRATCH_PRAM).passed());
        let mut absent = MemEsc {
            mem: [0xFF; 0x3000],
            stuck: 0,
            fail: false,
        };
        assert_eq!(
            esc_identity(&mut absent, 0x11),
            Verdict::Fail("type register reads 0x00/0xFF: no chip on the bus")
        );
    }
}
