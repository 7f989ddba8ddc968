//! Portable tests of the `foc` crate: the same file runs on the host and under QEMU
//! (Cortex-M4F). No std, no heap.
#![cfg_attr(target_os = "none", no_std, no_main)]

use foc::angle::{Angle, CountScale};
use foc::autotune::{self, Autotune, AutotuneConfig, Phase, TuneError, TuneResult, TuneState};
use foc::current_loop::{AdcSample, CurrentLoop, CurrentLoopConfig, Sense};
use foc::damping::{Damping, DampingConfig, DEFAULT_GAIN, DEFAULT_MAX_CORRECTION};
use foc::encoder::{Encoder, EncoderConfig};
use foc::modulation::{limit_circle, Duties, Modulator};
use foc::open_loop::{MovingAverage, OpenLoop, OpenLoopConfig};
use foc::pi::Pi;
use foc::servo::{AlignConfig, AlignState, Alignment, Demand, Interpolator, Servo, ServoGains};
use foc::transforms::{inverse_park, park, rotate_small, AlphaBeta, Dq};
use foc::trig::{self, LibmSinCos, PolySinCos, SinCos, POLY_MAX_ERROR};

const TS: f32 = 25e-6;
const PERIOD: u16 = 2125;

fn near(a: f32, b: f32, tol: f32) -> bool {
    (a - b).abs() <= tol
}

fn sense() -> Sense {
    Sense {
        amps_per_count: 20.0 / 4096.0,
        offset_a: 2048.0,
        offset_b: 2048.0,
        volts_per_count: 60.0 / 4096.0,
    }
}

fn adc_of(ia: f32, ib: f32, vbus: f32) -> AdcSample {
    let c = |i: f32| (2048.0 + i / (20.0 / 4096.0) + 0.5).clamp(0.0, 4095.0) as u16;
    AdcSample {
        ia: c(ia),
        ib: c(ib),
        vbus: (vbus / (60.0 / 4096.0) + 0.5) as u16,
    }
}

fn loop_config(r: f32, l: f32) -> CurrentLoopConfig {
    let wc = 2.0 * core::f32::consts::PI / (20.0 * TS);
    let (kp, ki) = CurrentLoopConfig::gains_for(r, l, wc);
    CurrentLoopConfig {
        ts: TS,
        kp,
        ki,
        inductance: l,
        ke: 0.283,
        latency: 1.5,
        sense: sense(),
        modulator: Modulator::new(PERIOD),
    }
}

/// Two independent R-L coils (no rotor), exact discretisation, one period of delay.
struct Coils {
    i: [f32; 2],
    r: [f32; 2],
    l: f32,
    vbus: f32,
    next: Duties,
}

impl Coils {
    fn new(r: f32, l: f32) -> Self {
        Coils {
            i: [0.0; 2],
            r: [r, r],
            l,
            vbus: 48.0,
            next: Duties::zero(PERIOD),
        }
    }
    fn sample(&self) -> AdcSample {
        adc_of(self.i[0], self.i[1], self.vbus)
    }
    fn advance(&mut self, d: Duties) {
        let m = Modulator::new(PERIOD);
        let (va, vb) = m.voltages(&self.next, self.vbus);
        self.next = d;
        for (k, v) in [va, vb].into_iter().enumerate() {
            let a = libm::expf(-self.r[k] * TS / self.l);
            self.i[k] = self.i[k] * a + (1.0 - a) * v / self.r[k];
        }
    }
}

/// A rotor turning at `omega_m` rad/s (mechanical) in a current vector `i_mag` A that
/// turns at `omega_c_e` rad/s (electrical): feeds `d` the voltages a motor with `r`,
/// `l`, `ke` needs, `ticks` current-loop steps of `ts` per update (no delay), for
/// `updates` updates. Returns the last correction (electrical rad).
fn run_damping(d: &mut Damping, omega_m: f32, omega_c_e: f32, updates: u32) -> f32 {
    let (r, l, ke, i_mag, ts, ticks) = (0.4f32, 1.8e-3f32, 0.283f32, 5.0f32, 25e-6f32, 4);
    let current = |k: u32| {
        let th = omega_c_e * ts * k as f32;
        AlphaBeta {
            alpha: i_mag * libm::cosf(th),
            beta: i_mag * libm::sinf(th),
        }
    };
    let mut last = 0.0;
    for u in 0..updates {
        for t in 0..ticks {
            let k = u * ticks + t;
            let (i0, i1) = (current(k), current(k + 1));
            // Back-EMF at the middle of the step: Ke·ω·(−sin θr, cos θr).
            let th_r = 50.0 * omega_m * ts * (k as f32 + 0.5);
            let e = ke * omega_m;
            let v = |a: f32, b: f32, e: f32| r * 0.5 * (a + b) + l * (b - a) / ts + e;
            d.tick(AlphaBeta {
                alpha: v(i0.alpha, i1.alpha, -e * libm::sinf(th_r)),
                beta: v(i0.beta, i1.beta, e * libm::cosf(th_r)),
            });
        }
        last = d.update(current((u + 1) * ticks), omega_c_e).to_radians();
    }
    last
}

fn damper() -> Damping {
    let mut c = DampingConfig::new(1e-4, 0.4, 1.8e-3, 0.283, 1.5);
    c.delay_ticks = 0.0;
    Damping::new(c)
}

qemu_runner::tests! {
    fn angle_electrical_is_fifty_times_mechanical() {
        // One full step (1/200 turn) is a quarter electrical turn.
        let a = Angle::from_turns(1.0 / 200.0).electrical();
        assert!(near(a.to_turns(), 0.25, 1e-6));
        // Wrapping: 1/50 turn mechanical = one electrical turn = 0.
        let b = Angle::from_turns(1.0 / 50.0).electrical();
        assert!(b.0 < 400 || b.0 > u32::MAX - 400);
        assert_eq!(Angle::from_turns(f32::NAN), Angle::ZERO);
        assert!(near(Angle::from_radians(-1.0).to_radians(), -1.0, 1e-6));
        assert_eq!(Angle(10).diff(Angle(u32::MAX - 9)), 20);
    }

    fn count_scale_is_exact_for_4000_counts() {
        let s = CountScale::new(4000, 50);
        for c in [0u32, 1, 20, 40, 79, 80, 81, 1999, 3999] {
            let exact = (((c as u64 * 50) << 32) / 4000) as u32;
            let d = s.angle(c).0.wrapping_sub(exact) as i32;
            assert!(d.abs() <= 2, "count {c}: {d}");
        }
        // 80 counts per electrical turn.
        assert!(s.angle(80).diff(Angle::ZERO).abs() <= 2);
        assert!(s.angle(20).diff(Angle::QUARTER).abs() <= 2);
        // Degenerate periods do not panic.
        let z = CountScale::new(0, 0);
        let _ = z.angle(u32::MAX);
    }

    fn sincos_error_bound() {
        let mut max = 0.0f32;
        let n = 20_000u32;
        for k in 0..n {
            // Dense sweep plus the fold points.
            let a = Angle(k.wrapping_mul(214_748) ^ (k << 20));
            let r = a.0 as f64 * (2.0 * core::f64::consts::PI / 4_294_967_296.0);
            let (s, c) = PolySinCos.sin_cos(a);
            max = max.max((s as f64 - libm::sin(r)).abs() as f32);
            max = max.max((c as f64 - libm::cos(r)).abs() as f32);
        }
        for a in [0u32, 1 << 30, (1 << 30) + 1, 1 << 31, (1 << 31) + 1, 3 << 30, u32::MAX] {
            let r = a as f64 * (2.0 * core::f64::consts::PI / 4_294_967_296.0);
            max = max.max((trig::sin(Angle(a)) as f64 - libm::sin(r)).abs() as f32);
        }
        assert!(max <= POLY_MAX_ERROR, "max error {max}");
        // The libm reference agrees too.
        let (s, c) = LibmSinCos.sin_cos(Angle::from_turns(0.125));
        assert!(near(s, core::f32::consts::FRAC_1_SQRT_2, 1e-6) && near(c, s, 1e-6));
    }

    fn park_round_trip_and_torque_axis() {
        let th = Angle::from_turns(0.37);
        let (s, c) = PolySinCos.sin_cos(th);
        let ab = AlphaBeta { alpha: 1.5, beta: -0.7 };
        let back = inverse_park(park(ab, s, c), s, c);
        assert!(near(back.alpha, 1.5, 1e-5) && near(back.beta, -0.7, 1e-5));
        // A pure q vector is perpendicular to the rotor: i_A = −sin, i_B = cos.
        let v = inverse_park(Dq { d: 0.0, q: 1.0 }, s, c);
        assert!(near(v.alpha, -s, 1e-6) && near(v.beta, c, 1e-6));
        // Small rotation.
        let (s2, c2) = rotate_small(s, c, 0.2);
        let (se, ce) = LibmSinCos.sin_cos(th.add_radians(0.2));
        assert!(near(s2, se, 2e-5) && near(c2, ce, 2e-5));
    }

    fn pi_limits_and_does_not_wind_up() {
        let mut pi = Pi::new(2.0, 1000.0, 1e-3, 10.0);
        for _ in 0..10_000 {
            let u = pi.update(100.0, 0.0);
            assert!(u <= 10.0);
        }
        assert!(pi.x <= 10.0);
        // Error reverses: output leaves the limit at once.
        let u = pi.update(-1.0, 0.0);
        assert!(u < 10.0, "{u}");
        // Without saturation it integrates Ki·Ts·e per step.
        let mut p = Pi::new(0.0, 100.0, 0.01, 100.0);
        p.update(1.0, 0.0);
        assert!(near(p.x, 1.0, 1e-6));
        p.preset(3.0);
        assert!(near(p.update(0.0, 0.0), 3.0, 1e-6));
        // Garbage limits do not panic.
        let mut g = Pi::new(1.0, 1.0, 1.0, f32::NAN);
        let _ = g.update(1.0, 0.0);
    }

    fn modulation_circle_and_bus_compensation() {
        let (a, b, lim) = limit_circle(30.0, 40.0, 25.0);
        assert!(lim && near(a, 15.0, 1e-4) && near(b, 20.0, 1e-4));
        let (a, b, lim) = limit_circle(3.0, 4.0, 25.0);
        assert!(!lim && a == 3.0 && b == 4.0);
        let (a, b, _) = limit_circle(f32::NAN, 1.0, 25.0);
        assert!(a == 0.0 && b == 0.0);
        let m = Modulator::new(PERIOD);
        assert_eq!(m.duties(0.0, 0.0, 48.0), Duties::zero(PERIOD));
        for vbus in [24.0f32, 48.0] {
            let d = m.duties(10.0, -5.0, vbus);
            let (va, vb) = m.voltages(&d, vbus);
            let q = 2.0 * vbus / PERIOD as f32;
            assert!(near(va, 10.0, q) && near(vb, -5.0, q), "{va} {vb}");
            // Legs symmetric around the centre.
            assert!((d.a1 as i32 + d.a2 as i32 - PERIOD as i32).abs() <= 1);
        }
        // Over-range and garbage clamp to the period.
        let d = m.duties(1e9, f32::NAN, 48.0);
        assert!(d.a1 <= PERIOD && d.a2 <= PERIOD && d.b1 <= PERIOD);
        assert_eq!(m.duties(10.0, 10.0, 0.0), Duties::zero(PERIOD));
    }

    fn current_loop_tracks_reference_on_coils() {
        let mut coils = Coils::new(0.4, 1.8e-3);
        let mut cl = CurrentLoop::new(loop_config(0.4, 1.8e-3));
        let th = Angle::from_turns(0.3);
        cl.iq_ref = 2.0;
        cl.id_ref = -0.5;
        for _ in 0..400 {
            let d = cl.step(&coils.sample(), th, 0.0);
            coils.advance(d);
        }
        let (s, c) = PolySinCos.sin_cos(th);
        let dq = park(AlphaBeta { alpha: coils.i[0], beta: coils.i[1] }, s, c);
        assert!(near(dq.q, 2.0, 0.03) && near(dq.d, -0.5, 0.03), "{dq:?}");
        assert!(!cl.saturated);
    }

    fn current_loop_saturates_cleanly_and_survives_garbage_adc() {
        let mut coils = Coils::new(0.4, 1.8e-3);
        let mut cl = CurrentLoop::new(loop_config(0.4, 1.8e-3));
        cl.iq_ref = 500.0;
        for _ in 0..200 {
            let d = cl.step(&coils.sample(), Angle::ZERO, 0.0);
            assert!(d.a1 <= PERIOD && d.b1 <= PERIOD && d.a2 <= PERIOD && d.b2 <= PERIOD);
            coils.advance(d);
        }
        assert!(cl.saturated);
        let vmax = 0.95 * 48.0;
        assert!(libm::hypotf(cl.v_dq.d, cl.v_dq.q) <= vmax * 1.001);
        for raw in [
            AdcSample { ia: 0, ib: 4095, vbus: 0 },
            AdcSample { ia: u16::MAX, ib: u16::MAX, vbus: u16::MAX },
        ] {
            let d = cl.step(&raw, Angle(123), f32::MAX);
            assert!(d.a1 <= PERIOD && d.b2 <= PERIOD);
            let d = cl.step(&raw, Angle(123), f32::NAN);
            assert!(d.a1 <= PERIOD && d.b2 <= PERIOD);
        }
    }

    fn encoder_counts_angle_and_wraps() {
        let mut e = Encoder::new(EncoderConfig::default(), 65_530);
        assert_eq!(e.cpr(), 4000);
        assert_eq!(e.update(10), 16); // across the 16-bit wrap
        assert_eq!(e.position(), 16);
        // 80 counts per electrical turn: count 20 = quarter turn.
        let mut e = Encoder::new(EncoderConfig::default(), 0);
        e.update(20);
        assert!(e.electrical_angle().diff(Angle::QUARTER).abs() <= 2);
        e.update(0u16.wrapping_sub(1)); // −1
        assert_eq!(e.count_in_rev(), 3999);
        assert_eq!(e.position(), -1);
        e.set_electrical_offset(Angle::HALF);
        assert!(e.electrical_angle().diff(e.raw_electrical_angle().wrapping_add(Angle::HALF)) == 0);
        // Configurable lines; garbage clamped.
        assert_eq!(Encoder::new(EncoderConfig { lines: 2500, ..Default::default() }, 0).cpr(), 10_000);
        assert_eq!(Encoder::new(EncoderConfig { lines: 0, ..Default::default() }, 0).cpr(), 4);
        let mut g = Encoder::new(EncoderConfig { lines: u32::MAX, pll_omega: f32::NAN, ..Default::default() }, 0);
        g.update(30_000);
        let _ = g.electrical_angle();
    }

    fn encoder_pll_velocity_converges() {
        let mut e = Encoder::new(EncoderConfig::default(), 0);
        // 40 000 counts/s = 10 rev/s = 1 count per step at 40 kHz.
        let mut raw = 0u16;
        for _ in 0..8000 {
            raw = raw.wrapping_add(1);
            e.update(raw);
        }
        assert!(near(e.velocity(), 40_000.0, 40.0), "{}", e.velocity());
        assert!(near(e.omega(), 20.0 * core::f32::consts::PI, 0.1));
        // Slow speed with quantisation: 1 count every 10 steps.
        let mut e = Encoder::new(EncoderConfig::default(), 0);
        let mut sum = 0.0;
        for k in 0..16_000u32 {
            e.update((k / 10) as u16);
            if k >= 8000 {
                sum += e.velocity();
            }
        }
        assert!(near(sum / 8000.0, 4000.0, 40.0), "{}", sum / 8000.0);
    }

    fn encoder_commutation_tracker_interpolates_and_stays_bounded() {
        // 10.013 rev/s at 4000 counts/rev and 40 kHz: 1.0013 counts per step, a count
        // pattern that repeats only every ~770 steps. The tracker's angle moves by the
        // shaft's advance every step, not by whole counts.
        let mut e = Encoder::new(EncoderConfig::default(), 0);
        let per_step = 1.0013f64;
        let mut worst_jump = 0.0f64;
        let mut worst_error = 0.0f64;
        let mut last = e.commutation_angle();
        let count_angle = 50.0 / 4000.0; // electrical turns per count
        for k in 1..20_000u32 {
            let true_counts = k as f64 * per_step;
            e.update((libm::floor(true_counts) as u32) as u16);
            let a = e.commutation_angle();
            if k > 8000 {
                let step_turns = a.diff(last) as f64 / 4_294_967_296.0;
                worst_jump = worst_jump.max((step_turns / count_angle - per_step).abs());
                let est = a.0 as f64 / 4_294_967_296.0;
                // The count covers [n, n + 1): its centre is the best a tracker of n can do.
                let x = (true_counts - 0.5) * count_angle;
                let truth = x - libm::floor(x);
                let mut err = est - truth;
                err -= libm::round(err);
                worst_error = worst_error.max((err / count_angle).abs());
            }
            last = a;
        }
        // Steps within 0.01 count of the true advance (the count jumps by 0 or 2 at the
        // pattern's slips; 0.004 measured); the angle within 0.4 count of the true
        // shaft (0.34 measured: the 52 Hz beat through the 80 rad/s tracker; 0.53 with
        // a linear tracker at 250 rad/s).
        assert!(worst_jump < 0.01, "jump {worst_jump} counts");
        assert!(worst_error < 0.4, "error {worst_error} counts");
        let w = e.commutation_omega_e();
        let w_true = (per_step * 40_000.0 / 4000.0 * 50.0 * 2.0 * core::f64::consts::PI) as f32;
        assert!(near(w, w_true, 0.01 * w_true), "omega {w} vs {w_true}");

        // A jump of 1000 counts (a shock, a lost counter) restarts the tracker on the
        // count: the commutation angle stays within ±2 counts of it.
        let before = e.electrical_angle();
        let raw = libm::floor(19_999.0f64 * per_step) as u32 + 1000;
        e.update(raw as u16);
        let off = e.commutation_angle().diff(e.electrical_angle()) as f64 / 4_294_967_296.0;
        assert!((off / count_angle).abs() <= 2.0 + 1e-3, "{off}");
        assert_ne!(before, e.electrical_angle());
        // Standing still: the angle is the count's.
        let mut e = Encoder::new(EncoderConfig::default(), 7);
        for _ in 0..4000 {
            e.update(7);
        }
        assert!(e.commutation_angle().diff(e.electrical_angle()).abs() < 1000);
        assert!(e.commutation_omega_e().abs() < 1e-3);
    }

    fn current_loop_dead_time_and_channel_gain() {
        let mut cl = CurrentLoop::new(loop_config(0.4, 1.8e-3));
        let m = Modulator::new(PERIOD);
        // At zero reference and zero current, nothing is added.
        cl.set_dead_time(0.5 / 48.0, 0.05);
        let d = cl.step(&adc_of(0.0, 0.0, 48.0), Angle::ZERO, 0.0);
        let (va, vb) = m.voltages(&d, 48.0);
        assert!(va.abs() < 0.05 && vb.abs() < 0.05, "{va} {vb}");
        // Well outside the band the full loss is added by the current's sign; inside it
        // the correction is linear (continuous through zero).
        let at = |cl: &mut CurrentLoop, ia: f32, ib: f32| {
            cl.reset();
            cl.id_ref = ia;
            cl.iq_ref = ib;
            let d0 = cl.step(&adc_of(ia, ib, 48.0), Angle::ZERO, 0.0);
            m.voltages(&d0, 48.0)
        };
        let (pa, pb) = at(&mut cl, 1.0, -1.0);
        // At its reference the loop (integrators cleared) adds only the compensation.
        assert!(near(pa, 0.5, 0.06), "{pa}");
        assert!(near(pb, -0.5, 0.06), "{pb}");
        let (sa, _) = at(&mut cl, 0.0244, 0.0);
        assert!(sa > 0.05 && sa < 0.4, "{sa}");
        // Nonsense settings are refused or clamped: the loss to 0..10 % of the bus.
        cl.set_dead_time(f32::NAN, 0.05);
        cl.set_dead_time(1.0, f32::NAN);
        cl.set_gain_b(f32::NAN);
        cl.set_gain_b(5.0);
        let (pa, _) = at(&mut cl, 1.0, 0.0);
        assert!(near(pa, 4.8, 0.1), "{pa}");

        // Channel B reading 3 % low, calibrated: i_q on B's axis is regulated to the
        // reference as channel A would see it.
        let mut cl = CurrentLoop::new(loop_config(0.4, 1.8e-3));
        cl.set_gain_b(1.0 / 0.97);
        let mut coils = Coils::new(0.4, 1.8e-3);
        cl.iq_ref = 1.0;
        for _ in 0..8000 {
            let mut adc = coils.sample();
            adc.ib = adc_of(0.0, coils.i[1] * 0.97, 48.0).ib;
            let d = cl.step(&adc, Angle::ZERO, 0.0);
            coils.advance(d);
        }
        assert!(near(coils.i[1], 1.0, 0.01), "{}", coils.i[1]);
    }

    fn autotune_calibrates_offsets_gains_and_dead_time() {
        // Channel B reads 3 % high, channel A 20 mA high; the bridges lose 0.5 V each
        // (applied as a current-signed voltage loss).
        let run = |gain_b: f32, offset_a: f32, loss: f32| {
            let mut coils = Coils::new(0.4, 1.8e-3);
            let m = Modulator::new(PERIOD);
            let mut t = Autotune::new(AutotuneConfig::new(TS, PERIOD, 4.0));
            let s = sense();
            let mut n = 0;
            while !t.finished() && n < 100_000 {
                let adc = coils.sample();
                let i = s.currents(&adc);
                let (va, vb) = t.step(i.alpha + offset_a, i.beta * gain_b, s.vbus(&adc));
                let lose = |v: f32, i: f32| v - loss * libm::tanhf(i / 0.02);
                let (ca, cb) = (coils.i[0], coils.i[1]);
                coils.advance(m.duties(lose(va, ca), lose(vb, cb), s.vbus(&adc)));
                n += 1;
            }
            t.state
        };
        let r = match run(1.03, 0.02, 0.5) {
            TuneState::Done(r) => r,
            s => panic!("{s:?}"),
        };
        assert!(near(r.gain_b, 1.0 / 1.03, 0.005), "gain_b {}", r.gain_b);
        assert!(near(r.offset[0], 0.02, 0.004) && near(r.offset[1], 0.0, 0.004), "{:?}", r.offset);
        assert!(near(r.dead_time_v, 0.5, 0.05), "dead time {}", r.dead_time_v);
        assert!(near(r.r, 0.4 * 0.5 * (1.0 + 1.0 / 1.03), 0.01), "R {}", r.r);
        // A channel 12 % off, or an offset of 0.5 A, is a sensing fault.
        assert_eq!(run(0.88, 0.0, 0.0), TuneState::Failed(TuneError::Sensing));
        assert_eq!(run(1.0, 0.5, 0.0), TuneState::Failed(TuneError::Sensing));
    }

    fn encoder_index_reference_and_lost_counts() {
        let mut e = Encoder::new(EncoderConfig::default(), 0);
        e.update(1000);
        e.on_index(998);
        assert!(e.index.seen && e.index.reference == 998 && e.index.last_position == 998);
        // One revolution later, exactly: no error.
        e.update(5000);
        e.on_index(4998);
        assert_eq!(e.index.last_error, 0);
        assert_eq!(e.index.error_count, 0);
        // A revolution with 5 counts lost: detected and the angle corrected.
        e.update(8995);
        e.on_index(8993);
        assert_eq!(e.index.last_error, -5);
        assert_eq!(e.index.error_count, 1);
        assert_eq!(e.count_in_rev(), 1000);
    }

    fn open_loop_microsteps_and_holds() {
        let cfg = OpenLoopConfig {
            pulses_per_rev: 200,
            ts: 1e-4,
            running_current: 4.0,
            holding_percent: 50,
            standby: 0.1,
            soft_start: 0.01,
            filter_time: 0.0,
        };
        let mut ol = OpenLoop::new(cfg, 0);
        ol.enable(0);
        // Soft start: 10 ms ramp = 100 steps.
        let o = ol.step(0);
        assert!(near(o.current, 0.04, 1e-4), "{}", o.current);
        for _ in 0..98 {
            ol.step(0);
        }
        let o = ol.step(1);
        assert!(near(o.current, 4.0, 1e-3));
        // One full step = quarter electrical turn.
        assert!(o.angle.diff(Angle::QUARTER).abs() <= 4);
        assert!(o.omega_e > 0.0);
        // Stand-by after 100 ms, then a 10 ms ramp to 50 %.
        for _ in 0..999 {
            assert!(!ol.step(1).holding);
        }
        let mut o = ol.step(1);
        assert!(o.holding);
        for _ in 0..100 {
            o = ol.step(1);
        }
        assert!(near(o.current, 2.0, 1e-3));
        // Motion: running current at once.
        assert!(near(ol.step(2).current, 4.0, 1e-6));
        // Negative positions wrap.
        assert!(ol.angle_of(-1).diff(Angle(3u32 << 30)).abs() <= 4);
    }

    fn open_loop_derates_when_voltage_limited() {
        let cfg = OpenLoopConfig {
            pulses_per_rev: 200,
            ts: 1e-4,
            running_current: 4.0,
            holding_percent: 50,
            standby: 1.0,
            soft_start: 0.0,
            filter_time: 0.0,
        };
        let mut ol = OpenLoop::new(cfg, 0);
        ol.enable(0);
        let mut k = 1.0;
        for n in 1..=1000 {
            ol.step(n);
            k = ol.voltage_limited(true);
        }
        assert!(near(k, foc::open_loop::DERATE_MIN, 1e-6));
        assert!(near(ol.step(1001).current, 4.0 * k, 1e-4));
        // Recovers slowly while moving without limiting...
        ol.voltage_limited(false);
        assert!(ol.voltage_limited(false) > k);
        // ...and at once at standstill.
        for _ in 0..20 {
            ol.step(1001);
        }
        assert!(near(ol.step(1001).current, 4.0, 1e-4));
    }

    fn open_loop_survives_garbage_config() {
        let cfg = OpenLoopConfig {
            pulses_per_rev: 0,
            ts: f32::NAN,
            running_current: f32::INFINITY,
            holding_percent: 255,
            standby: -1.0,
            soft_start: f32::NAN,
            filter_time: 1e9,
        };
        let mut ol = OpenLoop::new(cfg, i32::MAX);
        ol.enable(i32::MAX);
        for x in [i32::MIN, 0, i32::MAX, 17] {
            let o = ol.step(x);
            assert!(o.current >= 0.0);
        }
    }

    fn reconfigure_in_place_matches_a_fresh_open_loop() {
        let first = OpenLoopConfig {
            pulses_per_rev: 200,
            ts: 1e-4,
            running_current: 4.0,
            holding_percent: 50,
            standby: 0.1,
            soft_start: 0.01,
            filter_time: 0.02,
        };
        let second = OpenLoopConfig {
            pulses_per_rev: 51_200,
            ts: 1e-4,
            running_current: 2.5,
            holding_percent: 30,
            standby: 0.05,
            soft_start: 0.0,
            filter_time: 0.005,
        };
        // A used open loop (enabled, window full of motion, offset set) reconfigured
        // behaves exactly like a new one, step for step.
        let mut used = OpenLoop::new(first, 0);
        used.enable(0);
        used.set_angle_offset(foc::angle::Angle::from_radians(1.0));
        for k in 0..300 {
            used.step(k * 37);
        }
        used.reconfigure(second, 5000);
        let mut fresh = OpenLoop::new(second, 5000);
        for ol in [&mut used, &mut fresh] {
            ol.enable(5000);
        }
        for k in 0..400 {
            let x = 5000 + if k < 200 { k * 91 } else { 200 * 91 };
            assert_eq!(used.step(x), fresh.step(x), "step {k}");
        }
        // The same for the window alone, also when it grows.
        let mut m = MovingAverage::new(3, 0);
        for k in 0..10 {
            m.step(k * 1000);
        }
        m.reinit(200, -7);
        let mut n = MovingAverage::new(200, -7);
        for k in 0..500 {
            let x = -7 + (k % 97) * 13;
            assert_eq!(m.step(x), n.step(x));
        }
        assert_eq!(m.len(), 200);
        // Longer than the maximum: clamped like `new`.
        m.reinit(usize::MAX, 0);
        assert_eq!(m.len(), foc::open_loop::MAX_TAPS);
    }

    fn moving_average_is_exact_and_smooth() {
        let mut f = MovingAverage::new(10, 0);
        let mut last = 0;
        for _ in 0..5 {
            let y = f.step(1000);
            assert!(y >= last && y <= 1000);
            last = y;
        }
        assert!(last > 0 && last < 1000);
        for _ in 0..10 {
            last = f.step(1000);
        }
        assert_eq!(last, 1000);
        assert!(!f.busy());
        // Ramps of odd slope land exactly.
        let mut f = MovingAverage::new(7, -5);
        for k in 0..100 {
            f.step(-5 + 3 * k);
        }
        for _ in 0..7 {
            f.step(-5 + 3 * 99);
        }
        assert_eq!(f.output(), -5 + 3 * 99);
        // Huge jumps do not panic.
        let mut f = MovingAverage::new(1024, i32::MAX);
        f.step(i32::MIN);
        f.step(i32::MAX);
    }

    fn servo_following_error_and_bumpless() {
        let g = ServoGains::from_bandwidth(4.8e-5, 0.283, 4000, 200.0, 7.0);
        assert!(g.kv > 0.0 && g.ki_vel > 0.0 && g.kp_pos > 0.0 && g.acc_ff > 0.0);
        let mut s = Servo::new(g, 1e-4, 100);
        s.bumpless_start(1.25);
        let d = Demand { pos: 500, ..Demand::default() };
        let iq = s.step(&d, 500, 0.0);
        assert!(near(iq, 1.25, 1e-4), "{iq}");
        assert!(!s.fault);
        let _ = s.step(&d, 399, 0.0);
        assert!(s.fault, "101 counts > limit 100");
        s.clear_fault();
        assert!(!s.fault);
        // Output limited.
        let far = Demand { pos: 50_000, vel: 1e9, acc: 1e12, frac: 0.0 };
        s.set_following_error_limit(u32::MAX);
        assert!(s.step(&far, 0, 0.0) <= 7.0);
        let nan = Demand { pos: 0, frac: f32::NAN, vel: 0.0, acc: 0.0 };
        let _ = s.step(&nan, 0, f32::NAN);
        assert!(s.fault);
    }

    fn servo_velocity_mode_integrates_to_the_demand() {
        // Rigid body: counts/s² = b·i_q, b from the ECN57-20.
        let (j, kt, cpr) = (4.8e-5f32, 0.283f32, 4000u32);
        let b = kt * cpr as f32 / (2.0 * core::f32::consts::PI * j);
        let mut s = Servo::new(ServoGains::from_bandwidth(j, kt, cpr, 100.0, 7.0), 1e-4, 100);
        let mut v = 0.0f32;
        // Constant load of 0.5 A equivalent: the integrator must take it over.
        for _ in 0..5000 {
            let iq = s.step_velocity(20_000.0, 0.0, v);
            v += (b * (iq - 0.5)) * 1e-4;
        }
        assert!(near(v, 20_000.0, 20.0), "{v}");
        assert!(near(s.iq_ref, 0.5, 0.01), "{}", s.iq_ref);
        assert!(!s.fault);
    }

    fn servo_torque_mode_passes_the_demand_below_the_speed_limit() {
        let (j, kt, cpr) = (4.8e-5f32, 0.283f32, 4000u32);
        let b = kt * cpr as f32 / (2.0 * core::f32::consts::PI * j);
        let mut s = Servo::new(ServoGains::from_bandwidth(j, kt, cpr, 200.0, 7.0), 1e-4, 100);
        // Below the limit the output is the demand, exactly, whatever the speed does.
        let mut v = 0.0f32;
        for _ in 0..200 {
            let iq = s.step_torque(1.0, 40_000.0, v);
            assert_eq!(iq, 1.0);
            assert!(!s.speed_limited);
            v += b * iq * 1e-4 * 0.01;
        }
        // Beyond the demand's range the output is limited to ±iq_max.
        assert_eq!(s.step_torque(50.0, 40_000.0, 0.0), 7.0);
        assert_eq!(s.step_torque(-50.0, 40_000.0, 0.0), -7.0);
        // Non-finite inputs: no current, no NaN.
        assert_eq!(s.step_torque(f32::NAN, 40_000.0, 0.0), 0.0);
        assert!(s.step_torque(1.0, f32::NAN, f32::INFINITY).is_finite());
    }

    fn servo_torque_mode_holds_the_speed_limit_both_ways() {
        // Rigid body with friction: the demand alone would run away to 2.5e5 counts/s.
        let (j, kt, cpr) = (4.8e-5f32, 0.283f32, 4000u32);
        let b = kt * cpr as f32 / (2.0 * core::f32::consts::PI * j);
        for sign in [1.0f32, -1.0] {
            let mut s = Servo::new(ServoGains::from_bandwidth(j, kt, cpr, 200.0, 7.0), 1e-4, 100);
            let mut v = 0.0f32;
            let mut peak = 0.0f32;
            for _ in 0..4000 {
                let iq = s.step_torque(sign * 2.0, 20_000.0, v);
                v += b * (iq - 2.0e-5 * v) * 1e-4;
                peak = peak.max(sign * v);
            }
            assert!(near(v, sign * 20_000.0, 20.0), "{sign}: {v}");
            assert!(s.speed_limited, "{sign}");
            // The limit acts from the first step past it: an approach at 7.5e6
            // counts/s² overshoots by less than a quarter of the limit.
            assert!(peak < 25_000.0, "{sign}: peak {peak}");
            // Holding the limit takes only the friction's current.
            assert!(near(s.iq_ref, sign * 0.4, 0.05), "{sign}: {}", s.iq_ref);
        }
        // A shaft driven past the limit by its load is braked (zero demand).
        let mut s = Servo::new(ServoGains::from_bandwidth(j, kt, cpr, 200.0, 7.0), 1e-4, 100);
        assert!(s.step_torque(0.0, 20_000.0, 30_000.0) < 0.0);
    }

    fn servo_torque_to_velocity_is_bumpless_and_offset_adds() {
        let g = ServoGains::from_bandwidth(4.8e-5, 0.283, 4000, 200.0, 7.0);
        let mut s = Servo::new(g, 1e-4, 100);
        for _ in 0..10 {
            s.step_torque(1.5, 40_000.0, 10_000.0);
        }
        // The velocity step that follows at the same speed starts from the same current
        // (after the hand-over preset).
        s.bumpless_start(s.iq_ref);
        let iq = s.step_velocity(10_000.0, 0.0, 10_000.0);
        assert!(near(iq, 1.5, 1e-5), "{iq}");
        let iq = s.step(&Demand { pos: 7, ..Demand::default() }, 7, 0.0);
        assert!(near(iq, 1.5, 1e-5), "{iq}");
        // The torque offset is added inside the limit.
        s.set_torque_offset(0.5);
        let iq = s.step(&Demand { pos: 7, ..Demand::default() }, 7, 0.0);
        assert!(near(iq, 2.0, 1e-5), "{iq}");
        s.set_torque_offset(100.0);
        assert_eq!(s.step_velocity(0.0, 0.0, 0.0), 7.0);
        s.set_torque_offset(f32::NAN);
        let iq = s.step_velocity(0.0, 0.0, 0.0);
        assert!(iq.is_finite() && iq <= 7.0, "{iq}");
    }

    fn pi_update_within_keeps_the_integrator_in_the_narrowed_range() {
        let mut pi = Pi::new(1.0, 1000.0, 1e-3, 10.0);
        pi.preset(8.0);
        // Narrowed to [−10, 2]: the integrator is pulled to 2 at once.
        assert_eq!(pi.update_within(5.0, -10.0, 2.0), 2.0);
        assert_eq!(pi.x, 2.0);
        // Negative error: proportional at once, the integrator moves from 2.
        let u = pi.update_within(-1.0, -10.0, 2.0);
        assert!(near(u, 1.0, 1e-6) && near(pi.x, 1.0, 1e-6), "{u} {}", pi.x);
        // Bounds outside the controller's own limits are cut to them.
        assert_eq!(pi.update_within(100.0, -50.0, 50.0), 10.0);
    }

    fn pi_integrate_is_one_rule_for_every_limit() {
        // Not limited: Ki·Ts·e, kept inside the range.
        let mut pi = Pi::new(1.0, 1000.0, 1e-3, 10.0);
        pi.integrate(2.0, 3.0, false, -10.0, 10.0);
        assert!(near(pi.x, 2.0, 1e-6), "{}", pi.x);
        pi.integrate(100.0, 3.0, false, -10.0, 10.0);
        assert_eq!(pi.x, 10.0);
        // Limited: frozen while the step points the way of the output, moves when it
        // points back (the current loop's circle, the auto-tune's ±vmax).
        pi.integrate(1.0, 12.0, true, -10.0, 10.0);
        assert_eq!(pi.x, 10.0);
        pi.integrate(-1.0, 12.0, true, -10.0, 10.0);
        assert!(near(pi.x, 9.0, 1e-6), "{}", pi.x);
        pi.integrate(1.0, -12.0, true, -10.0, 10.0);
        assert!(near(pi.x, 10.0, 1e-6), "{}", pi.x);
        // The update's limits use it: a feed-forward beyond the upper limit with an
        // error pulling back hard leaves the integrator inside the range.
        let mut p = Pi::new(1.0, 1000.0, 1e-3, 10.0);
        p.preset(-9.0);
        assert_eq!(p.update(-5.0, 40.0), 10.0);
        assert_eq!(p.x, -10.0);
    }

    fn servo_gain_parameters_scale_the_base() {
        let g = ServoGains::from_bandwidth(4.8e-5, 0.283, 4000, 250.0, 7.0);
        let same = g.scaled(100, 0, 100, 100);
        assert!(near(same.kp_pos, g.kp_pos, 1e-3) && near(same.kv, g.kv, 1e-9));
        assert!(same.ki_pos == 0.0 && near(same.vel_ff, 1.0, 1e-6));
        let e5 = g.scaled(120, 50, 70, 60);
        assert!(near(e5.kp_pos, 1.2 * g.kp_pos, 1e-3));
        assert!(near(e5.vel_ff, 0.7, 1e-6));
        assert!(near(e5.ki_vel, 0.36 * g.ki_vel, 1e-6 * g.ki_vel.max(1.0)));
        assert!(e5.ki_pos > 0.0);
        // Out-of-range values clamp to 150.
        let hi = g.scaled(u16::MAX, u16::MAX, u16::MAX, u16::MAX);
        assert!(near(hi.vel_ff, 1.5, 1e-6));
    }

    fn interpolator_is_linear_with_one_cycle_delay() {
        let mut ip = Interpolator::new(10, 1e-4, 0);
        ip.set_target(100);
        let mut d = Demand::default();
        for k in 1..=10 {
            d = ip.step();
            assert_eq!(d.pos, 10 * k);
        }
        assert!(near(d.vel, 100_000.0, 1.0));
        // Holds after the cycle.
        assert_eq!(ip.step().pos, 100);
        ip.set_target(100);
        let d = ip.step();
        assert_eq!(d.pos, 100);
        assert!(d.vel == 0.0);
    }

    fn alignment_finds_offset_and_detects_dead_encoder() {
        let cfg = AlignConfig {
            ts: 1e-4,
            current: 3.0,
            ramp: 0.01,
            settle: 0.01,
            wiggle: true,
            sweep_cycles: 1,
            sweep_speed: 20.0,
        };
        // Ideal rotor follows the vector; the encoder reads angle − offset.
        let offset = Angle(0x1234_5678);
        let mut al = Alignment::new(cfg);
        let mut rotor = Angle::ZERO;
        for _ in 0..10_000 {
            if let AlignState::Done(_) | AlignState::Failed = al.state {
                break;
            }
            let (cmd, i) = al.step(rotor.wrapping_sub(offset));
            assert!(i <= 3.0);
            rotor = cmd;
        }
        match al.state {
            AlignState::Done(o) => assert!(o.diff(offset).abs() < 1 << 24, "{o:?}"),
            s => panic!("{s:?}"),
        }
        // An encoder that does not move fails.
        let mut al = Alignment::new(cfg);
        for _ in 0..10_000 {
            al.step(Angle::ZERO);
        }
        assert_eq!(al.state, AlignState::Failed);
    }

    fn autotune_measures_r_and_l() {
        let mut coils = Coils::new(0.4, 1.8e-3);
        let m = Modulator::new(PERIOD);
        let mut t = Autotune::new(AutotuneConfig::new(TS, PERIOD, 4.0));
        let s = sense();
        let mut n = 0;
        while !t.finished() && n < 100_000 {
            let adc = coils.sample();
            let i = s.currents(&adc);
            let (va, vb) = t.step(i.alpha, i.beta, s.vbus(&adc));
            coils.advance(m.duties(va, vb, s.vbus(&adc)));
            n += 1;
        }
        let r = match t.state {
            TuneState::Done(r) => r,
            s => panic!("{s:?}"),
        };
        assert!(near(r.r, 0.4, 0.02), "R {}", r.r);
        assert!(near(r.l, 1.8e-3, 0.18e-3), "L {}", r.l);
        assert!((n as f32) * TS < 2.0);
        let wc = foc::current_loop::robust_bandwidth(TS);
        assert!(near(r.kp, r.l * wc, 1e-3) && near(r.ki, r.r * wc, 1e-2));
        // Ideal sensing and bridges: the calibration finds nothing to correct, and L is
        // the same at both test currents.
        assert!(near(r.gain_b, 1.0, 0.01), "gain_b {}", r.gain_b);
        assert!(r.offset.iter().all(|o| o.abs() < 0.01), "offsets {:?}", r.offset);
        assert!(r.dead_time_v.abs() < 0.05, "dead time {}", r.dead_time_v);
        assert!(r.l_low.iter().all(|&l| near(l, 1.8e-3, 0.18e-3)), "L low {:?}", r.l_low);
    }

    fn autotune_detects_open_and_unbalanced_phase() {
        let m = Modulator::new(PERIOD);
        let s = sense();
        let run = |coils: &mut Coils| {
            let mut t = Autotune::new(AutotuneConfig::new(TS, PERIOD, 4.0));
            let mut n = 0;
            while !t.finished() && n < 100_000 {
                let adc = coils.sample();
                let i = s.currents(&adc);
                let (va, vb) = t.step(i.alpha, i.beta, s.vbus(&adc));
                coils.advance(m.duties(va, vb, s.vbus(&adc)));
                n += 1;
            }
            t.state
        };
        let mut open = Coils::new(0.4, 1.8e-3);
        open.r[1] = 1e6;
        assert_eq!(run(&mut open), TuneState::Failed(TuneError::OpenPhase(Phase::B)));
        let mut unbalanced = Coils::new(0.4, 1.8e-3);
        unbalanced.r[0] = 0.6;
        assert_eq!(run(&mut unbalanced), TuneState::Failed(TuneError::Unbalanced));
        // Garbage inputs do not panic.
        let mut t = Autotune::new(AutotuneConfig::new(f32::NAN, 0, f32::NAN));
        for _ in 0..10 {
            let _ = t.step(f32::NAN, f32::INFINITY, -5.0);
        }
    }

    fn state_machines_survive_extreme_configs() {
        for x in [f32::NAN, f32::INFINITY, -1.0, 0.0, 1e30] {
            let mut al = Alignment::new(AlignConfig {
                ts: x,
                current: x,
                ramp: x,
                settle: x,
                wiggle: true,
                sweep_cycles: u32::MAX,
                sweep_speed: x,
            });
            for k in 0..50u32 {
                let _ = al.step(Angle(k.wrapping_mul(0x9E37_79B9)));
            }
            let mut cfg = AutotuneConfig::new(TS, PERIOD, 4.0);
            cfg.settle = x;
            cfg.average = x;
            cfg.toggle_time = x;
            cfg.toggle_half = u32::MAX;
            cfg.delay = u32::MAX;
            cfg.max_modulation = x;
            cfg.kp_init = x;
            let mut t = Autotune::new(cfg);
            for k in 0..200 {
                let _ = t.step(k as f32 * 0.1, x, 48.0);
            }
        }
    }

    fn autotune_parameter_scaling() {
        let r = TuneResult { r: 0.4, l: 1.8e-3, kp: 22.62, ki: 5026.5, ..TuneResult::default() };
        assert_eq!(r.resistance_mohm(), 400);
        assert_eq!(r.inductance_uh(), 1800);
        assert_eq!(r.kp_param(), 2262);
        assert_eq!(r.ki_param(), 503);
        assert!(near(autotune::kp_from_param(1000), 10.0, 1e-5));
        assert!(near(autotune::ki_from_param(200), 2000.0, 1e-3));
        let z = TuneResult { r: f32::NAN, l: -1.0, kp: 1e12, ki: 0.0, ..TuneResult::default() };
        assert_eq!(z.resistance_mohm(), 1);
        assert_eq!(z.inductance_uh(), 1);
        assert_eq!(z.kp_param(), 32767);
        assert_eq!(z.ki_param(), 0);
    }
    fn sqrtf_matches_libm_bit_for_bit() {
        let specials = [
            0.0f32,
            -0.0,
            1.0,
            2.0,
            0.25,
            f32::MIN_POSITIVE,
            f32::from_bits(1),
            f32::from_bits(0x007F_FFFF),
            f32::MAX,
            f32::INFINITY,
            1e-30,
            3.0e38,
            123_456.79,
        ];
        for x in specials {
            assert_eq!(foc::num::sqrtf(x).to_bits(), libm::sqrtf(x).to_bits(), "{}", x);
        }
        for x in [-1.0f32, -0.5, f32::NEG_INFINITY, f32::NAN, -f32::MIN_POSITIVE] {
            assert!(foc::num::sqrtf(x).is_nan());
            assert!(libm::sqrtf(x).is_nan());
        }
        // A spread of bit patterns over the whole positive range.
        let mut bits: u32 = 1;
        while bits < 0x7F80_0000 {
            let x = f32::from_bits(bits);
            assert_eq!(foc::num::sqrtf(x).to_bits(), libm::sqrtf(x).to_bits(), "{}", bits);
            bits += 0x0001_2345;
        }
    }

    fn count_wrapping_matches_rem_euclid_on_edges() {
        // Encoder: the count within the revolution follows rem_euclid of the moved
        // counts for every cpr the constructor allows (4 up to 2^24).
        for lines in [1u32, 2500, 1 << 22] {
            let mut e = Encoder::new(EncoderConfig { lines, ..Default::default() }, 0);
            let cpr = e.cpr() as i64;
            let mut moved: i64 = 0;
            for step in [32767i32, -32768, 1, -1, 30000, -30001, 0, 12345] {
                let raw = (moved as i32).wrapping_add(step) as u16;
                moved += i64::from(e.update(raw));
                assert_eq!(i64::from(e.count_in_rev()), moved.rem_euclid(cpr));
            }
            e.on_index(e.count_in_rev() as u16);
            assert!(i64::from(e.count_in_rev()) < cpr);
        }
        // Open loop: the angle of a position is the angle of its count within the
        // revolution, for extreme positions and pulse counts; the one case rem_euclid
        // itself would overflow on (i32::MIN, u32::MAX pulses) gives the exact
        // remainder 0 instead of a panic.
        for ppr in [1u32, 200, 51_200, i32::MAX as u32, u32::MAX] {
            let cfg = OpenLoopConfig {
                pulses_per_rev: ppr,
                ts: 1e-4,
                running_current: 1.0,
                holding_percent: 50,
                standby: 0.1,
                soft_start: 0.01,
                filter_time: 0.0,
            };
            let ol = OpenLoop::new(cfg, 0);
            for pos in [i32::MIN, i32::MIN + 1, -1, 0, 1, 199, 200, i32::MAX] {
                let n = if ppr == u32::MAX && pos == i32::MIN {
                    0
                } else {
                    pos.rem_euclid(ppr as i32)
                };
                assert_eq!(ol.angle_of(pos), ol.angle_of(n), "{} {}", ppr, pos);
            }
        }
        // Moving average at its largest window: the ring index wraps inside the taps.
        let mut m = MovingAverage::new(1000, 0);
        assert_eq!(m.len(), 256);
        let mut x = 0i32;
        for k in 0..600 {
            x = x.wrapping_add(if k < 300 { 256 } else { -256 });
            let _ = m.step(x);
        }
        for _ in 0..256 {
            let _ = m.step(x);
        }
        assert_eq!(m.step(x), x);
    }

    fn damping_reads_the_rotor_speed_from_the_back_emf() {
        // 5 rev/s: 1570.8 electrical rad/s. A rotor 10 % slow reads as such, and the
        // correction advances the angle by Kd times the difference.
        let w_c = 2.0 * core::f32::consts::PI * 250.0;
        for slow in [1.0f32, 0.9] {
            let mut d = damper();
            let corr = run_damping(&mut d, w_c * slow / 50.0, w_c, 200);
            assert!(near(d.rotor_speed(), w_c * slow, 0.01 * w_c), "{}", d.rotor_speed());
            let want = DEFAULT_GAIN * w_c * (1.0 - slow);
            assert!(near(corr, want, 0.01 * w_c * DEFAULT_GAIN + 1e-3), "{corr} {want}");
        }
    }

    fn damping_is_bounded_signed_and_fades_out_at_low_speed() {
        // A stalled rotor: the largest advance, in the command's direction.
        let w_c = 2.0 * core::f32::consts::PI * 500.0;
        let mut d = damper();
        assert!(near(run_damping(&mut d, 0.0, w_c, 50), DEFAULT_MAX_CORRECTION, 1e-4));
        let mut d = damper();
        assert!(near(run_damping(&mut d, 0.0, -w_c, 50), -DEFAULT_MAX_CORRECTION, 1e-4));
        // Below the fade-in speed nothing is corrected.
        let mut d = damper();
        assert_eq!(run_damping(&mut d, 0.0, 20.0, 50), 0.0);
        // Gain 0: off.
        let mut d = damper();
        d.set_gain(0.0);
        assert_eq!(run_damping(&mut d, 0.0, w_c, 50), 0.0);
        // After a reset the first update only starts the period.
        let mut d = damper();
        run_damping(&mut d, 0.0, w_c, 50);
        d.reset();
        assert_eq!(d.update(AlphaBeta::default(), w_c).to_radians(), 0.0);
    }

    fn damping_survives_garbage() {
        let c = DampingConfig {
            ts: 0.0,
            gain: f32::NAN,
            r: f32::INFINITY,
            l: -1.0,
            ke: 0.0,
            cutoff_hz: f32::NAN,
            min_speed: -5.0,
            max_correction: 1.0,
            delay_ticks: f32::NAN,
        };
        let mut d = Damping::new(c);
        d.set_gain(f32::NAN);
        d.set_motor(f32::NAN, 1.0);
        for x in [f32::NAN, 0.0, f32::INFINITY, -1e30] {
            d.tick(AlphaBeta { alpha: x, beta: 1.0 });
            let _ = d.update(AlphaBeta { alpha: x, beta: x }, x);
        }
    }
}
