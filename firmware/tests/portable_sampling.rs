#![cfg_attr(target_os = "none", no_std, no_main)]
//! Current-sensor calibration: nominal and garbage inputs.
use firmware::sampling::{AnalogScale, OffsetCalibrator, OffsetFault, Phase, RawSample};

const SCALE: AnalogScale = AnalogScale {
    amps_per_count: 0.006,
    volts_per_count: 0.016,
    offset_nominal: 2048,
    offset_tolerance: 200,
    noise_tolerance: 40,
};

fn s(ia: u16, ib: u16) -> RawSample {
    RawSample { ia, ib, vbus: 1500 }
}

qemu_runner::tests! {
    fn nominal_offsets_are_the_mean() {
        let mut c = OffsetCalibrator::new(4);
        for (a, b) in [(2040, 2060), (2042, 2062), (2044, 2058), (2046, 2060)] {
            c.add(s(a, b));
        }
        let o = c.finish(&SCALE).unwrap();
        assert!((o.ia - 2043.0).abs() < 1e-3);
        assert!((o.ib - 2060.0).abs() < 1e-3);
    }

    fn too_few_samples_is_the_current_sensing_fault() {
        let mut c = OffsetCalibrator::new(8);
        assert!(!c.add(s(2048, 2048)));
        assert_eq!(c.finish(&SCALE), Err(OffsetFault::TooFewSamples { got: 1, wanted: 8 }));
        assert_eq!(OffsetFault::KIND.flashes(), Some(9));
        assert_eq!(OffsetFault::KIND.code(), 0x5210);
    }

    fn zero_wanted_still_needs_one_sample() {
        let c = OffsetCalibrator::new(0);
        assert!(matches!(c.finish(&SCALE), Err(OffsetFault::TooFewSamples { got: 0, wanted: 1 })));
    }

    fn offset_out_of_range_names_the_phase() {
        let mut c = OffsetCalibrator::new(2);
        c.add(s(2048, 3000));
        c.add(s(2048, 3000));
        assert_eq!(c.finish(&SCALE), Err(OffsetFault::OutOfRange { phase: Phase::B, mean: 3000 }));
        let mut c = OffsetCalibrator::new(2);
        c.add(s(0, 2048));
        c.add(s(0, 2048));
        assert_eq!(c.finish(&SCALE), Err(OffsetFault::OutOfRange { phase: Phase::A, mean: 0 }));
    }

    fn garbage_extremes_do_not_panic() {
        let mut c = OffsetCalibrator::new(1000);
        for i in 0..2000u32 {
            let v = if i % 2 == 0 { u16::MAX } else { 0 };
            c.add(s(v, u16::MAX));
        }
        assert_eq!(c.count(), 1000);
        // mean of 0/65535 alternating is ~32767: out of range for phase A
        assert!(matches!(c.finish(&SCALE), Err(OffsetFault::OutOfRange { phase: Phase::A, .. })));
    }

    fn noisy_sensor_is_rejected() {
        let mut c = OffsetCalibrator::new(2);
        c.add(s(2000, 2048));
        c.add(s(2100, 2048));
        assert_eq!(c.finish(&SCALE), Err(OffsetFault::Noisy { phase: Phase::A, spread: 100 }));
    }

    fn scaling_to_amps_and_volts() {
        assert!((SCALE.amps(2148, 2048.0) - 0.6).abs() < 1e-4);
        assert!((SCALE.amps(1948, 2048.0) + 0.6).abs() < 1e-4);
        assert!((SCALE.volts(1500) - 24.0).abs() < 1e-3);
    }
}
