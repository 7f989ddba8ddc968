//! Benchmarks of the `foc` area. Each call to [`crate::bench`] is one row of BENCHMARKS.md.

use core::hint::black_box;
use foc::angle::Angle;
use foc::current_loop::{AdcSample, CurrentLoop, CurrentLoopConfig, Sense};
use foc::encoder::{Encoder, EncoderConfig};
use foc::modulation::Modulator;
use foc::open_loop::{OpenLoop, OpenLoopConfig};
use foc::pi::Pi;
use foc::servo::{Demand, Servo, ServoGains};
use foc::transforms::{park, AlphaBeta};
use foc::trig::{PolySinCos, SinCos};

const TS: f32 = 25e-6;

pub fn run() {
    current_loop();
    servo_rows();
    math_rows();
}

/// The current-loop step and the encoder update (both at 40 kHz).
fn current_loop() {
    // Current loop: ECN57-20 gains, 40 kHz, 2125-count PWM period.
    let wc = 2.0 * core::f32::consts::PI / (20.0 * TS);
    let (kp, ki) = CurrentLoopConfig::gains_for(0.4, 1.8e-3, wc);
    let mut cl = CurrentLoop::new(CurrentLoopConfig {
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
    });
    cl.iq_ref = 1.5;
    let adc = AdcSample {
        ia: 2100,
        ib: 1990,
        vbus: 3277,
    };
    for _ in 0..4 {
        cl.step(&adc, Angle(0x1234_5678), 900.0);
    }
    crate::bench("current loop step", || {
        cl.step(
            black_box(&adc),
            black_box(Angle(0x2345_6789)),
            black_box(1000.0),
        )
    });

    // Encoder + PLL update (runs at the current-loop rate too).
    let mut enc = Encoder::new(EncoderConfig::default(), 0);
    enc.update(3);
    crate::bench("encoder update (count + PLL)", || {
        let d = enc.update(black_box(5));
        (d, enc.electrical_angle())
    });
}

/// The servo-rate steps: position + velocity loop, open loop.
fn servo_rows() {
    // Servo: position + velocity loop, 10 kHz.
    let g = ServoGains::from_bandwidth(4.8e-5, 0.283, 4000, 250.0, 7.07);
    let mut servo = Servo::new(g, 1e-4, 1000);
    let d = Demand {
        pos: 1234,
        frac: 0.25,
        vel: 4000.0,
        acc: 1.0e5,
    };
    servo.step(&d, 1230, 3900.0);
    crate::bench("servo step (position+velocity)", || {
        servo.step(black_box(&d), black_box(1231), black_box(3950.0))
    });

    // Open loop with a 2 ms command filter (20 taps at 10 kHz), moving.
    let mut ol = OpenLoop::new(
        OpenLoopConfig {
            pulses_per_rev: 10_000,
            ts: 1e-4,
            running_current: 5.0,
            holding_percent: 50,
            standby: 0.5,
            soft_start: 0.005,
            filter_time: 0.002,
        },
        0,
    );
    ol.enable(0);
    for k in 0..100 {
        ol.step(k * 7);
    }
    crate::bench("open-loop step", || ol.step(black_box(707)));
}

/// The PI update and the sin/cos + Park transform.
fn math_rows() {
    let mut pi = Pi::new(22.6, 5026.0, TS, 45.6);
    pi.update(0.1, 0.0);
    crate::bench("PI update", || pi.update(black_box(0.3), black_box(0.0)));

    crate::bench("sin/cos + Park", || {
        let (s, c) = PolySinCos.sin_cos(black_box(Angle(0x3456_789A)));
        park(
            black_box(AlphaBeta {
                alpha: 1.0,
                beta: -0.5,
            }),
            s,
            c,
        )
    });
}
