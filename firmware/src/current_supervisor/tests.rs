use super::*;
use crate::identity::Variant;
use foc::current_loop::{CurrentLoopConfig, Sense};
use foc::modulation::Modulator;

const TS: f32 = 25e-6;
const PERIOD: u16 = 2125;
const APC: f32 = 20.0 / 4096.0;

/// Two RL coils (no rotor), ADC with a sensor gain per phase.
struct Coils {
    r: [f32; 2],
    l: f32,
    i: [f32; 2],
    gain: [f32; 2],
    /// Sensor reading added to gain × current, A.
    bias: [f32; 2],
    vbus: f32,
    /// Duties computed in the previous period (one period of computation delay).
    pending: Duties,
}

impl Coils {
    fn new() -> Self {
        Coils {
            r: [0.4, 0.4],
            l: 1.8e-3,
            i: [0.0; 2],
            gain: [1.0; 2],
            bias: [0.0; 2],
            vbus: 48.0,
            pending: Duties::zero(PERIOD),
        }
    }
    fn adc(&self) -> AdcSample {
        let c =
            |k: usize| (2048.0 + (self.gain[k] * self.i[k] + self.bias[k]) / APC).round() as u16;
        AdcSample {
            ia: c(0),
            ib: c(1),
            vbus: (self.vbus / (60.0 / 4096.0)).round() as u16,
        }
    }
    fn apply(&mut self, d: &Duties) {
        let m = Modulator::new(PERIOD);
        let (va, vb) = m.voltages(&self.pending, self.vbus);
        self.pending = *d;
        for (k, v) in [va, vb].into_iter().enumerate() {
            if self.r[k] > 100.0 {
                self.i[k] = 0.0;
                continue;
            }
            // Exact RL step over one period.
            let a = libm::expf(-self.r[k] / self.l * TS);
            let inf = v / self.r[k];
            self.i[k] = inf + (self.i[k] - inf) * a;
        }
    }
}

fn current_loop() -> CurrentLoop {
    let (kp, ki) =
        CurrentLoopConfig::gains_for(0.4, 1.8e-3, 2.0 * core::f32::consts::PI / (20.0 * TS));
    CurrentLoop::new(CurrentLoopConfig {
        ts: TS,
        kp: kp * 0.5,
        ki: ki * 0.5,
        inductance: 1.0e-3,
        ke: 0.283,
        latency: 1.5,
        sense: Sense {
            amps_per_count: APC,
            offset_a: 2048.0,
            offset_b: 2048.0,
            volts_per_count: 60.0 / 4096.0,
        },
        modulator: Modulator::new(PERIOD),
    })
}

fn cfg(auto_tune: bool) -> SupervisorConfig {
    let mut p = Params::new(Variant::HybridServo);
    p.set_internal(Param::AutoTune, i32::from(auto_tune));
    SupervisorConfig::from_params(&p, TS, PERIOD)
}

/// Runs the tune to its end (at most 1 s).
fn run_tune(s: &mut CurrentSupervisor, cl: &mut CurrentLoop, m: &mut Coils) -> u32 {
    let mut n = 0;
    while s.tuning() && n < 40_000 {
        let d = s.tune_step(cl, &m.adc());
        m.apply(&d);
        n += 1;
    }
    n
}

#[test]
fn held_motion_gives_no_current_and_restarts_an_alignment() {
    use crate::cia402::DriveCommand;
    use crate::commutation::{CommutatedMotion, Commutation};
    use crate::motion::{Feedback, MotionConfig, ECN57_20, SERVO_TS};
    let p = Params::new(Variant::HybridServo);
    let mut c = MotionConfig::from_params(&p, Variant::HybridServo, &ECN57_20, SERVO_TS);
    c.closed_loop = true;
    let mut m = CommutatedMotion::new(c, false);
    let cmd = DriveCommand {
        power_stage: true,
        drive_enabled: true,
        torque_limit: 1000,
        current_limit: 1000,
        ..DriveCommand::default()
    };
    m.set_command(&cmd, 1e-3);
    let fb = Feedback::default();
    let s = m.step(&fb, Angle(0));
    assert!(s.reference.power);
    assert_eq!(m.state(), Commutation::Aligning);
    let s = m.step_held(&fb);
    assert!(!s.reference.power && !s.failed && s.offset.is_none());
    assert_eq!(m.state(), Commutation::Unaligned);
    assert!(!m.motion().enabled());
    // Released: the alignment starts again.
    let s = m.step(&fb, Angle(0));
    assert!(s.reference.power);
    assert_eq!(m.state(), Commutation::Aligning);
}

#[test]
fn config_from_parameters() {
    let c = cfg(true);
    assert!(c.auto_tune);
    assert!((c.test_current - 0.8 * 3.2).abs() < 1e-4);
    assert_eq!(c.follow_periods, 800);
    let mut p = Params::new(Variant::HybridServo);
    p.set_internal(Param::AutoTune, 0);
    let c = SupervisorConfig::from_params(&p, f32::NAN, 0);
    assert!(!c.auto_tune);
    assert_eq!((c.ts, c.pwm_period), (25e-6, 2));
}

#[test]
fn tune_waits_for_permission_then_sets_the_loop_gains() {
    let mut s = CurrentSupervisor::new(cfg(true));
    let mut cl = current_loop();
    let mut m = Coils::new();
    assert_eq!(s.report().tune, TuneStatus::Pending);
    assert!(!s.tuning(), "not before the permission");
    s.permit_tune(true);
    assert!(s.tuning());
    let n = run_tune(&mut s, &mut cl, &mut m);
    let rep = s.report();
    assert_eq!(rep.tune, TuneStatus::Done, "{rep:?}");
    assert_eq!(rep.tune_seq, 1);
    // R and L at two currents, then the offsets after 12 L/R: about 0.4 s.
    assert!(n < 18_000, "about 0.4 s: {n} periods");
    let t = rep.tuned;
    // Ideal coils and sensing: nothing to calibrate.
    let c = t.calibration;
    assert!(c.gain_b_e4.abs_diff(10_000) <= 100, "{c:?}");
    assert!(c.offset_ma.iter().all(|o| o.abs() <= 10), "{c:?}");
    assert!(c.l_low_uh.abs_diff(1800) <= 180, "{c:?}");
    assert!(t.r_mohm.abs_diff(400) <= 40, "{t:?}");
    assert!(t.l_uh.abs_diff(1800) <= 180, "{t:?}");
    // The loop uses what 0x2015 / 0x2016 / 0x2021 will report.
    let c = cl.config();
    assert!((c.kp - kp_from_param(t.kp)).abs() < 1e-6);
    assert!((c.ki - ki_from_param(t.ki)).abs() < 1e-3);
    assert!((c.inductance - f32::from(t.l_uh) * 1e-6).abs() < 1e-9);
    assert!(!s.tuning());
    // Once per power cycle: neither a new permission nor a reconfiguration re-tunes.
    s.permit_tune(false);
    s.permit_tune(true);
    s.configure(cfg(true));
    assert!(!s.tuning());
    assert_eq!(s.report().tune_seq, 1);
}

#[test]
fn open_phase_fails_and_is_retried_on_a_new_permission() {
    let mut s = CurrentSupervisor::new(cfg(true));
    let mut cl = current_loop();
    let mut m = Coils::new();
    m.r[1] = 1e6;
    s.permit_tune(true);
    run_tune(&mut s, &mut cl, &mut m);
    assert_eq!(
        s.report().tune,
        TuneStatus::Failed(TuneError::OpenPhase(Phase::B))
    );
    assert_eq!(s.report().tune_seq, 1);
    assert!(!s.tuning(), "no retry while the permission stays");
    // The fault withdraws the permission; after the reset it comes back: retry.
    s.permit_tune(false);
    m.r[1] = 0.4;
    s.permit_tune(true);
    assert!(s.tuning());
    run_tune(&mut s, &mut cl, &mut m);
    assert_eq!(s.report().tune, TuneStatus::Done);
    assert_eq!(s.report().tune_seq, 2);
}

#[test]
fn first_enable_phase_check_without_the_tune() {
    let mut s = CurrentSupervisor::new(cfg(false));
    let mut cl = current_loop();
    let kp = cl.config().kp;
    let mut m = Coils::new();
    s.permit_tune(true);
    assert!(!s.tuning(), "nothing before the first power request");
    s.request_power(true);
    assert!(s.tuning());
    let n = run_tune(&mut s, &mut cl, &mut m);
    assert!(n < 40, "under 1 ms: {n} periods");
    let r = s.report();
    assert_eq!(
        (r.tune, r.tune_seq),
        (TuneStatus::Off, 0),
        "passed: nothing reported"
    );
    assert_eq!(cl.config().kp, kp, "gains untouched");
    s.request_power(true);
    assert!(!s.tuning(), "once");
    // Open phase B at the next power cycle: the motor-open report.
    let mut s = CurrentSupervisor::new(cfg(false));
    m.r[1] = 1e6;
    s.permit_tune(true);
    s.request_power(true);
    let n = run_tune(&mut s, &mut cl, &mut m);
    assert!(n <= 230, "phase A, then 5 ms on phase B at most: {n}");
    let r = s.report();
    assert_eq!(
        (r.tune, r.tune_seq),
        (TuneStatus::Failed(TuneError::OpenPhase(Phase::B)), 1)
    );
    // The fault withdraws the permission; after the reset the next enable checks
    // again (no full tune with 0x2013 = 0).
    s.permit_tune(false);
    s.permit_tune(true);
    assert!(!s.tuning());
    assert_eq!(s.report().tune, TuneStatus::Off);
    m.r[1] = 0.4;
    s.request_power(true);
    assert!(s.tuning());
    run_tune(&mut s, &mut cl, &mut m);
    assert_eq!(s.report().tune_seq, 1, "passed");
    // With the tune on, no phase check.
    let mut s = CurrentSupervisor::new(cfg(true));
    s.permit_tune(true);
    s.request_power(true);
    assert_eq!(s.report().tune, TuneStatus::Pending);
}

#[test]
fn withdrawn_permission_stops_the_tune_and_off_means_no_tune() {
    let mut s = CurrentSupervisor::new(cfg(true));
    let mut cl = current_loop();
    let adc = Coils::new().adc();
    s.permit_tune(true);
    for _ in 0..100 {
        s.tune_step(&mut cl, &adc);
    }
    assert_eq!(s.report().tune, TuneStatus::Running);
    s.permit_tune(false);
    assert_eq!(s.report().tune, TuneStatus::Pending);
    assert!(!s.tuning());
    // Not tuning: a stray call applies 0 V.
    let d = s.tune_step(&mut cl, &adc);
    assert_eq!(d, Duties::zero(PERIOD));
    s.configure(cfg(false));
    s.permit_tune(true);
    assert_eq!(s.report().tune, TuneStatus::Off);
    assert!(!s.tuning());
    let s2 = CurrentSupervisor::new(cfg(false));
    assert_eq!(s2.report(), CurrentReport::default());
}

/// Runs the closed loop at a fixed reference for `periods`.
fn run_loop(
    s: &mut CurrentSupervisor,
    cl: &mut CurrentLoop,
    m: &mut Coils,
    iq: f32,
    omega_e: f32,
    periods: u32,
) {
    cl.id_ref = 0.0;
    cl.iq_ref = iq;
    for _ in 0..periods {
        // Rotor at θe = 0: q is phase B, d is phase A.
        let d = s.run_step(cl, &m.adc(), Angle(0), omega_e);
        m.apply(&d);
    }
}

#[test]
fn fast_protection_trips_in_the_period_and_holds_until_rearmed() {
    // These coils' sensors read ±10 A: an 8 A trip level for the test.
    let c = SupervisorConfig {
        trip_current_a: 8.0,
        ..cfg(false)
    };
    assert!(
        (cfg(false).trip_current_a - 10.5).abs() < 1e-3,
        "the product's level"
    );
    let mut s = CurrentSupervisor::new(c);
    let mut cl = current_loop();
    let mut m = Coils::new();
    run_loop(&mut s, &mut cl, &mut m, 3.0, 0.0, 400);
    assert!(!s.protect(&cl), "healthy");
    // Bus above 55 V (braking energy): the period that measures it trips.
    m.vbus = 56.0;
    let _ = s.run_step(&mut cl, &m.adc(), Angle(0), 0.0);
    assert!(s.protect(&cl));
    let r = s.report();
    assert_eq!((r.trip_seq, r.trip), (1, Trip::OverVoltage));
    assert!((559..=561).contains(&r.trip_bus_dv), "{}", r.trip_bus_dv);
    // The bus is back: still tripped (no re-enable by itself), counted once.
    m.vbus = 48.0;
    for _ in 0..100 {
        let _ = cl.voltage_step(&m.adc(), 0.0, 0.0);
        assert!(s.protect(&cl));
    }
    assert_eq!(s.report().trip_seq, 1);
    assert!(!s.tuning(), "no tune while tripped");
    s.rearm();
    assert!(!s.protect(&cl));
    // A phase current above the level (a short the break comparator missed).
    m.i = [0.0, -9.0];
    let _ = cl.voltage_step(&m.adc(), 0.0, 0.0);
    assert!(s.protect(&cl));
    let r = s.report();
    assert_eq!((r.trip_seq, r.trip), (2, Trip::OverCurrent));
    assert!(
        (-9_010..=-8_990).contains(&r.trip_ib_ma),
        "{}",
        r.trip_ib_ma
    );
}

#[test]
fn stuck_current_sensor_is_detected_once_after_20_ms() {
    let mut s = CurrentSupervisor::new(cfg(false));
    let mut cl = current_loop();
    let mut m = Coils::new();
    run_loop(&mut s, &mut cl, &mut m, 3.0, 0.0, 4000);
    assert_eq!(s.report().follow_seq, 0, "healthy: follows");
    // Phase B (q at θe = 0) sensor stuck at −1 A: the loop saturates. (A sensor
    // stuck at 0 A is indistinguishable from an open phase and reported as one.)
    m.gain[1] = 0.0;
    m.bias[1] = -1.0;
    // The integrator needs a few ms to reach the voltage limit.
    let mut k = 0;
    while !cl.saturated && k < 2000 {
        run_loop(&mut s, &mut cl, &mut m, 3.0, 0.0, 1);
        k += 1;
    }
    assert!(cl.saturated && k < 2000, "{k}");
    run_loop(&mut s, &mut cl, &mut m, 3.0, 0.0, 790);
    assert_eq!(s.report().follow_seq, 0, "not before 20 ms");
    run_loop(&mut s, &mut cl, &mut m, 3.0, 0.0, 60);
    assert_eq!(s.report().follow_seq, 1);
    assert_eq!(s.report().follow_ref_ma, 3000);
    run_loop(&mut s, &mut cl, &mut m, 3.0, 0.0, 2000);
    assert_eq!(s.report().follow_seq, 1, "once until the bridges were off");
    s.idle();
    run_loop(&mut s, &mut cl, &mut m, 3.0, 0.0, 900);
    assert_eq!(s.report().follow_seq, 2);
}

#[test]
fn open_phase_while_running_is_detected() {
    let mut s = CurrentSupervisor::new(cfg(false));
    let mut cl = current_loop();
    let mut m = Coils::new();
    run_loop(&mut s, &mut cl, &mut m, 2.0, 0.0, 400);
    m.r[1] = 1e6;
    // The integrator needs a few ms to reach the voltage limit, then 10 ms.
    run_loop(&mut s, &mut cl, &mut m, 2.0, 0.0, 300);
    assert_eq!(s.report().open_seq, 0, "not before 10 ms");
    run_loop(&mut s, &mut cl, &mut m, 2.0, 0.0, 1700);
    let r = s.report();
    assert_eq!((r.open_seq, r.open_phase), (1, Phase::B));
    assert_eq!(r.follow_seq, 0, "one fault for one event");
    // Once until the bridges were off.
    run_loop(&mut s, &mut cl, &mut m, 2.0, 0.0, 2000);
    assert_eq!(s.report().open_seq, 1);
    s.idle();
    run_loop(&mut s, &mut cl, &mut m, 2.0, 0.0, 2000);
    assert_eq!(s.report().open_seq, 2);
}

#[test]
fn small_references_and_a_healthy_motor_are_not_an_open_phase() {
    let mut s = CurrentSupervisor::new(cfg(false));
    let mut cl = current_loop();
    let mut m = Coils::new();
    m.r[1] = 1e6;
    run_loop(&mut s, &mut cl, &mut m, 0.5, 0.0, 4000);
    assert!(cl.saturated);
    assert_eq!(s.report().open_seq, 0, "below 0.6 A: not counted");
    let mut s = CurrentSupervisor::new(cfg(false));
    let mut m = Coils::new();
    for k in 0..40 {
        let i = if k % 2 == 0 { 6.0 } else { -6.0 };
        run_loop(&mut s, &mut cl, &mut m, i, 0.0, 200);
    }
    assert_eq!(s.report().open_seq, 0, "reversals cross zero current");
}

#[test]
fn saturation_explained_by_the_motor_model_is_not_a_fault() {
    let mut s = CurrentSupervisor::new(cfg(false));
    let mut cl = current_loop();
    let mut m = Coils::new();
    m.gain[1] = 0.0;
    // Back-EMF feed-forward of 0.283/50·ωe ≥ 0.8·vmax: the reference is not
    // reachable at this speed, so the saturation says nothing.
    let omega_e = 0.9 * 0.95 * 48.0 / (0.283 / 50.0);
    run_loop(&mut s, &mut cl, &mut m, 3.0, omega_e, 4000);
    assert_eq!(s.report().follow_seq, 0);
    // Short saturation (a current step) is not counted either.
    let mut s = CurrentSupervisor::new(cfg(false));
    let mut m = Coils::new();
    let mut cl = current_loop();
    for k in 0..40 {
        let i = if k % 2 == 0 { 6.0 } else { -6.0 };
        run_loop(&mut s, &mut cl, &mut m, i, 0.0, 200);
    }
    assert_eq!(s.report().follow_seq, 0);
    // Errors under 0.3 A are not counted even when saturated (dead sensor,
    // reference 0.2 A).
    m.gain[1] = 0.0;
    run_loop(&mut s, &mut cl, &mut m, 0.2, 0.0, 4000);
    assert!(cl.saturated);
    assert_eq!(s.report().follow_seq, 0);
}
