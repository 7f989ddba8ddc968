//! Benchmarks of the current-loop supervision (`firmware::current_supervisor`): the
//! cost it adds to the current-loop interrupt. Compare with the `current loop step`
//! row of `foc_benches` (the bare `CurrentLoop::step`).

use core::hint::black_box;
use firmware::current_supervisor::{CurrentSupervisor, SupervisorConfig};
use firmware::identity::Variant;
use firmware::params::{Params, P};
use foc::angle::Angle;
use foc::current_loop::{AdcSample, CurrentLoop, CurrentLoopConfig, Sense};
use foc::modulation::Modulator;

const TS: f32 = 25e-6;

fn current_loop() -> CurrentLoop {
    let wc = 2.0 * core::f32::consts::PI / (20.0 * TS);
    let (kp, ki) = CurrentLoopConfig::gains_for(0.4, 1.8e-3, wc);
    CurrentLoop::new(CurrentLoopConfig {
        ts: TS,
        kp,
        ki,
        inductance: 1.8e-3,
        ke: 0.283,
        latency: 1.5,
        sense: Sense {
            amps_per_count: 20.0 / 4096.0,
            offset_a: 2048.0,
            offset_b: 2048.0,
            volts_per_count: 60.0 / 4096.0,
        },
        modulator: Modulator::new(2125),
    })
}

pub fn run() {
    let mut p = Params::new(Variant::HybridServo);
    p.set_internal(P::AutoTune, 0);
    let cfg = SupervisorConfig::from_params(&p, TS, 2125);

    // Normal operation: the loop is not saturated, the check is one branch. The same
    // step without the supervisor, same state and inputs, for comparison.
    let mut sup = CurrentSupervisor::new(cfg);
    let mut cl = current_loop();
    cl.iq_ref = 0.5;
    let adc = AdcSample {
        ia: 2100,
        ib: 1990,
        vbus: 3277,
    };
    for _ in 0..4 {
        sup.run_step(&mut cl, &adc, Angle(0x1234_5678), 900.0);
    }
    let mut bare = cl.clone();
    crate::bench("current loop step (unsaturated, bare)", || {
        bare.step(
            black_box(&adc),
            black_box(Angle(0x2345_6789)),
            black_box(1000.0),
        )
    });
    crate::bench("supervised current step (unsaturated)", || {
        sup.run_step(
            &mut cl,
            black_box(&adc),
            black_box(Angle(0x2345_6789)),
            black_box(1000.0),
        )
    });

    #[cfg(not(target_os = "none"))]
    assert!(!cl.saturated, "the unsaturated rows must not saturate");
    // Saturated with the current far from its reference (the check's full path).
    let mut sup = CurrentSupervisor::new(cfg);
    let mut cl = current_loop();
    cl.iq_ref = 5.0;
    let dead = AdcSample {
        ia: 2048,
        ib: 2048,
        vbus: 3277,
    };
    for _ in 0..2000 {
        sup.run_step(&mut cl, &dead, Angle(0), 0.0);
    }
    #[cfg(not(target_os = "none"))]
    assert!(cl.saturated);
    crate::bench(
        "supervised current step (saturated: follow and open-phase checks)",
        || {
            sup.run_step(
                &mut cl,
                black_box(&dead),
                black_box(Angle(0x2345_6789)),
                black_box(10.0),
            )
        },
    );

    // The power-up auto-tune, one PWM period (DC regulation of phase A).
    p.set_internal(P::AutoTune, 1);
    let mut sup = CurrentSupervisor::new(SupervisorConfig::from_params(&p, TS, 2125));
    let mut cl = current_loop();
    sup.permit_tune(true);
    for _ in 0..4 {
        sup.tune_step(&mut cl, &adc);
    }
    crate::bench("auto-tune step (voltage mode)", || {
        sup.tune_step(&mut cl, black_box(&adc))
    });
}
