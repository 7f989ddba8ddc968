#![cfg_attr(target_os = "none", no_std, no_main)]
//! Decisions the board glue takes from the library: the SYNC0 edge against the SII's
//! 0x0151 value, and the power gate with its sticky halted state.
use ecat_slave_stack::sii::{self, EscFlavour, SyncDrive};
use firmware::identity::{self, PulseEdge, Variant};
use firmware::power_gate::{bridge_mode, BridgeMode, GateInputs, Halt, HaltExit};

qemu_runner::tests! {
    fn sync0_edge_agrees_with_the_sii_image() {
        for esc in [EscFlavour::Lan9252, EscFlavour::Et1100] {
            for v in [Variant::HybridServo, Variant::OpenLoop] {
                let d = identity::device_description(v, esc, 0);
                let mut img = [0u8; identity::EEPROM_BYTES as usize];
                let n = sii::build(&d, &mut img);
                assert!(n.is_ok());
                // SII word 1, high byte: what the ESC loads into 0x0151.
                let reg = img[3];
                assert_eq!(reg, identity::SYNC_LATCH_CONFIG);
                assert_eq!(
                    identity::sync0_active_edge(reg),
                    Some(identity::SYNC0_ACTIVE_EDGE)
                );
                // The board waits for the leading edge of the pulse the ESC drives.
                let drive = SyncDrive::from_code(reg & 0b11);
                assert_eq!(drive, identity::SYNC0_DRIVE);
                let expect = if drive.active_high() {
                    PulseEdge::Rising
                } else {
                    PulseEdge::Falling
                };
                assert_eq!(identity::SYNC0_ACTIVE_EDGE, expect);
            }
        }
        // The product's choice: push-pull active high, so the rising edge.
        assert_eq!(identity::SYNC0_ACTIVE_EDGE, PulseEdge::Rising);
    }

    fn sync0_edge_decoding_of_every_drive() {
        let out = sii::sync_latch::SYNC0_OUTPUT | sii::sync_latch::SYNC0_AL_EVENT;
        let cases = [
            (SyncDrive::PushPullActiveLow, PulseEdge::Falling),
            (SyncDrive::OpenDrainActiveLow, PulseEdge::Falling),
            (SyncDrive::PushPullActiveHigh, PulseEdge::Rising),
            (SyncDrive::OpenSourceActiveHigh, PulseEdge::Rising),
        ];
        for (drive, edge) in cases {
            assert_eq!(SyncDrive::from_code(drive.code()), drive);
            assert_eq!(identity::sync0_active_edge(out | drive.code()), Some(edge));
            // SYNC1 bits do not change the SYNC0 decision.
            let with_sync1 = out | drive.code() | sii::sync_latch::SYNC1_OUTPUT | 0x30;
            assert_eq!(identity::sync0_active_edge(with_sync1), Some(edge));
            // Pin used as LATCH0 input, or SYNC0 not mapped to the AL event: unusable.
            assert_eq!(
                identity::sync0_active_edge(sii::sync_latch::SYNC0_AL_EVENT | drive.code()),
                None
            );
            assert_eq!(
                identity::sync0_active_edge(sii::sync_latch::SYNC0_OUTPUT | drive.code()),
                None
            );
        }
    }

    fn halt_is_sticky_and_says_how_to_reset() {
        let h = Halt::new();
        assert!(!h.is_halted());
        // Before the watchdog runs, a halted chip must reset itself.
        assert_eq!(h.halt(), HaltExit::ResetNow);
        assert!(h.is_halted());
        // Starting the watchdog later does not clear the state.
        h.watchdog_started();
        assert!(h.is_halted());
        assert_eq!(h.halt(), HaltExit::AwaitWatchdog);
        assert!(h.is_halted());

        let w = Halt::default();
        w.watchdog_started();
        assert!(!w.is_halted());
        assert_eq!(w.halt(), HaltExit::AwaitWatchdog);
        assert!(w.is_halted());
    }

    fn bridges_never_on_while_halted_or_broken() {
        // Every combination of the six inputs.
        for bits in 0u8..64 {
            let i = GateInputs {
                halted: bits & 1 != 0,
                break_latched: bits & 2 != 0,
                tuning: bits & 4 != 0,
                permitted: bits & 8 != 0,
                power_wanted: bits & 16 != 0,
                tripped: bits & 32 != 0,
            };
            let m = bridge_mode(i);
            let expect = if i.halted || i.break_latched || i.tripped {
                BridgeMode::Off
            } else if i.tuning {
                BridgeMode::Tune
            } else if i.permitted && i.power_wanted {
                BridgeMode::Run
            } else {
                BridgeMode::Off
            };
            assert_eq!(m, expect, "{:?}", i);
            if i.halted {
                assert_eq!(m, BridgeMode::Off, "halted: {:?}", i);
            }
        }
    }

    fn halted_gate_stays_off_whatever_the_drive_asks() {
        let h = Halt::new();
        h.watchdog_started();
        let ask = |h: &Halt| {
            bridge_mode(GateInputs {
                halted: h.is_halted(),
                break_latched: false,
                tripped: false,
                tuning: false,
                permitted: true,
                power_wanted: true,
            })
        };
        assert_eq!(ask(&h), BridgeMode::Run);
        let _ = h.halt();
        // The drive keeps asking (its state is whatever the panic left): still off.
        for _ in 0..1000 {
            assert_eq!(ask(&h), BridgeMode::Off);
        }
    }
}
