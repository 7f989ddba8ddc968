//! Control-quality scenarios. Each returns its figures (and traces for plots); the
//! integration tests assert them and `control-report` prints them.
//!
//! Unless noted: ECN57-20 at 48 V, current loop 40 kHz, servo 10 kHz, 4000 counts/rev,
//! ADC noise σ = 1 LSB (4.9 mA), dead-time loss 0.2 V.

use super::motor::{MotorParams, PlantConfig, ECN57_20, TC86_45};
use super::rig::{Rig, Trapezoid, SERVO_DIV, TS, TS_SERVO};
use foc::autotune::{Autotune, AutotuneConfig, TuneResult, TuneState};
use foc::open_loop::{OpenLoop, OpenLoopConfig};
use foc::servo::{
    handover_currents, AlignConfig, AlignState, Alignment, Demand, Interpolator, Servo,
};
use std::f64::consts::{PI, SQRT_2};

mod report;

pub use report::report;

/// Velocity-loop bandwidth used by the closed-loop scenarios, Hz.
pub const SERVO_BW_HZ: f32 = 250.0;

/// One row of the report.
#[derive(Clone, Debug)]
pub struct Figure {
    /// What is measured.
    pub name: String,
    /// The goal.
    pub goal: String,
    /// What was achieved.
    pub achieved: String,
    /// Goal met.
    pub met: bool,
}

/// Current step response (ensemble average).
#[derive(Clone, Debug)]
pub struct CurrentStep {
    /// Step size, A.
    pub step: f64,
    /// 10-90 % rise time, µs.
    pub rise_us: f64,
    /// Overshoot, % of the step.
    pub overshoot_pct: f64,
    /// Averaged response `(t µs after the reference step, i_q A)`.
    pub trace: Vec<(f64, f64)>,
    /// Reference `(t µs, A)`.
    pub reference: Vec<(f64, f64)>,
}

/// 0.5 A q-current step on a locked rotor, averaged over `runs` noise seeds.
pub fn current_step(motor: MotorParams, runs: u32) -> CurrentStep {
    current_step_on(PlantConfig::new(motor), runs, |_| {})
}

/// [`current_step`] on the plant `cfg` (locked here); `prepare` adjusts each run's
/// rig before the step (fault or non-ideality injection).
pub fn current_step_on(cfg: PlantConfig, runs: u32, prepare: impl Fn(&mut Rig)) -> CurrentStep {
    let step = 0.5;
    let pre = 20usize;
    let post = 120usize;
    let mut acc = vec![0.0f64; pre + post];
    for seed in 0..runs.max(1) {
        let mut cfg = cfg;
        cfg.locked = true;
        cfg.seed = 100 + seed as u64;
        let mut rig = Rig::new(cfg);
        prepare(&mut rig);
        for _ in 0..40 {
            rig.tick();
        }
        for (n, a) in acc.iter_mut().enumerate() {
            rig.cl.iq_ref = if n >= pre { step as f32 } else { 0.0 };
            rig.tick();
            *a += rig.plant.i_dq().1;
        }
    }
    let n = runs.max(1) as f64;
    // Sample n (0-based) is the current at the end of tick n, i.e. (n+1)·Ts after the
    // sample that tick used; the reference changed at tick `pre`.
    let ts_us = TS as f64 * 1e6;
    let trace: Vec<(f64, f64)> = acc
        .iter()
        .enumerate()
        .map(|(k, a)| ((k as f64 + 1.0 - pre as f64) * ts_us, a / n))
        .collect();
    let reference = trace
        .iter()
        .map(|&(t, _)| (t, if t > 0.0 { step } else { 0.0 }))
        .collect();
    let cross = |level: f64| -> f64 {
        let mut prev = (0.0, 0.0);
        for &(t, i) in trace.iter().filter(|p| p.0 >= 0.0) {
            if i >= level {
                let (t0, i0) = prev;
                return t0 + (level - i0) / (i - i0) * (t - t0);
            }
            prev = (t, i);
        }
        f64::INFINITY
    };
    let rise_us = cross(0.9 * step) - cross(0.1 * step);
    let peak = trace.iter().map(|p| p.1).fold(f64::MIN, f64::max);
    CurrentStep {
        step,
        rise_us,
        overshoot_pct: ((peak - step) / step * 100.0).max(0.0),
        trace,
        reference,
    }
}

/// Closed-loop current bandwidth by sine sweep (locked rotor, 0.5 A amplitude).
#[derive(Clone, Debug)]
pub struct Bandwidth {
    /// −3 dB frequency, Hz (interpolated on a log frequency axis).
    pub f3db_hz: f64,
    /// `(f Hz, |i_q/i_q*|)`.
    pub points: Vec<(f64, f64)>,
}

/// Measures the gain of the current loop at a list of frequencies.
pub fn current_bandwidth(motor: MotorParams) -> Bandwidth {
    let freqs = [
        500.0, 1000.0, 1500.0, 2000.0, 2500.0, 3000.0, 3500.0, 4000.0, 5000.0, 6000.0,
    ];
    let mut points = Vec::new();
    for &f in &freqs {
        let mut cfg = PlantConfig::new(motor);
        cfg.locked = true;
        let mut rig = Rig::new(cfg);
        let amp = 0.5;
        let ts = TS as f64;
        let settle = ((2.0 / f) / ts).ceil().max(80.0) as usize;
        let periods = (f * 0.005).ceil().max(4.0);
        let meas = (periods / f / ts).round() as usize;
        let (mut re, mut im) = (0.0, 0.0);
        for k in 0..settle + meas {
            let t = k as f64 * ts;
            rig.cl.iq_ref = (amp * (2.0 * PI * f * t).sin()) as f32;
            rig.tick();
            if k >= settle {
                // The plant state after tick k is at time (k+1)·Ts.
                let tt = (k + 1) as f64 * ts;
                let i = rig.plant.i_dq().1;
                re += i * (2.0 * PI * f * tt).sin();
                im += i * (2.0 * PI * f * tt).cos();
            }
        }
        let gain = 2.0 * (re * re + im * im).sqrt() / meas as f64 / amp;
        points.push((f, gain));
    }
    let mut f3db = f64::INFINITY;
    let g3 = 0.5f64.sqrt();
    for w in points.windows(2) {
        let ((f0, g0), (f1, g1)) = (w[0], w[1]);
        if g0 >= g3 && g1 < g3 {
            let x = (g0 - g3) / (g0 - g1);
            f3db = (f0.ln() + x * (f1.ln() - f0.ln())).exp();
            break;
        }
    }
    Bandwidth {
        f3db_hz: f3db,
        points,
    }
}

/// Standstill with a load-torque step.
#[derive(Clone, Debug)]
pub struct LoadStep {
    /// Largest |error| before the step, counts.
    pub before_counts: f64,
    /// Largest |error| after the step, counts.
    pub peak_counts: f64,
    /// Time after the step until |error| stays ≤ 1 count, ms.
    pub recovery_ms: f64,
    /// Largest |error| in the last 20 ms, counts.
    pub final_counts: f64,
    /// `(t ms, error counts)`.
    pub trace: Vec<(f64, f64)>,
}

/// ECN57-20 in closed loop holding position; `torque` N·m load step.
pub fn standstill_load_step(torque: f64) -> LoadStep {
    standstill_load_step_with(torque, SERVO_BW_HZ)
}

/// [`standstill_load_step`] with velocity bandwidth `bw_hz`.
pub fn standstill_load_step_with(torque: f64, bw_hz: f32) -> LoadStep {
    let mut rig = Rig::new(PlantConfig::new(ECN57_20));
    let mut servo = Servo::new(rig.servo_gains(bw_hz), TS_SERVO, 1000);
    let hold = Demand {
        pos: rig.enc.position(),
        ..Demand::default()
    };
    let n_pre = 300; // 30 ms
    let n_post = 600; // 60 ms
    let mut trace = Vec::new();
    let (mut before, mut peak, mut last_bad, mut fin) = (0.0f64, 0.0f64, 0usize, 0.0f64);
    for n in 0..n_pre + n_post {
        if n == n_pre {
            rig.plant.load = torque;
        }
        rig.servo_period(&mut servo, &hold);
        let e = (hold.pos - rig.enc.position()) as f64;
        trace.push((n as f64 * TS_SERVO as f64 * 1e3, e));
        if n >= n_pre / 2 && n < n_pre {
            before = before.max(e.abs());
        }
        if n >= n_pre {
            peak = peak.max(e.abs());
            if e.abs() > 1.0 {
                last_bad = n - n_pre + 1;
            }
            if n >= n_pre + n_post - 200 {
                fin = fin.max(e.abs());
            }
        }
    }
    LoadStep {
        before_counts: before,
        peak_counts: peak,
        recovery_ms: last_bad as f64 * TS_SERVO as f64 * 1e3,
        final_counts: fin,
        trace,
    }
}

/// A point-to-point move.
#[derive(Clone, Debug)]
pub struct Move {
    /// Move length, counts.
    pub counts: f64,
    /// Profile duration, ms.
    pub profile_ms: f64,
    /// Largest following error during the profile, counts.
    pub max_fe_counts: f64,
    /// Overshoot past the target after the profile, counts.
    pub overshoot_counts: f64,
    /// Time after the profile end until |error| stays ≤ 2 counts, ms.
    pub settle_ms: f64,
}

/// ECN57-20, 90° (1000 counts) with a trapezoidal profile (10 rev/s, 500 rev/s²).
pub fn move_90() -> Move {
    move_90_with(SERVO_BW_HZ)
}

/// [`move_90`] with velocity bandwidth `bw_hz`.
pub fn move_90_with(bw_hz: f32) -> Move {
    let rig = Rig::new(PlantConfig::new(ECN57_20));
    let servo = Servo::new(rig.servo_gains(bw_hz), TS_SERVO, 1000);
    move_90_on(rig, servo, 500.0)
}

/// [`move_90`] on a given rig and servo, acceleration `acc_rev_s2` rev/s².
pub fn move_90_on(mut rig: Rig, mut servo: Servo, acc_rev_s2: f64) -> Move {
    let cpr = rig.enc.cpr() as f64;
    let p0 = rig.enc.position() as f64;
    let dist = cpr / 4.0;
    let prof = Trapezoid::new(p0, p0 + dist, 10.0 * cpr, acc_rev_s2 * cpr);
    let hold = Demand {
        pos: p0 as i32,
        ..Demand::default()
    };
    for _ in 0..100 {
        rig.servo_period(&mut servo, &hold);
    }
    let n_prof = (prof.duration() / TS_SERVO as f64).ceil() as usize;
    let n_after = 400;
    let target = p0 + dist;
    let (mut fe, mut over, mut last_bad) = (0.0f64, 0.0f64, 0usize);
    for n in 0..n_prof + n_after {
        let d = prof.demand((n + 1) as f64 * TS_SERVO as f64);
        rig.servo_period(&mut servo, &d);
        let pos = rig.enc.position() as f64;
        if n < n_prof {
            fe = fe.max(servo.following_error.abs() as f64);
        } else {
            over = over.max(pos - target);
            if (pos - target).abs() > 2.0 {
                last_bad = n - n_prof + 1;
            }
        }
    }
    Move {
        counts: dist,
        profile_ms: prof.duration() * 1e3,
        max_fe_counts: fe,
        overshoot_counts: over,
        settle_ms: last_bad as f64 * TS_SERVO as f64 * 1e3,
    }
}

/// CSP tracking.
#[derive(Clone, Debug)]
pub struct Tracking {
    /// Largest |FE| while the demand accelerates or decelerates, counts.
    pub fe_accel: f64,
    /// Largest |FE| at constant speed, counts.
    pub fe_const: f64,
    /// Largest |FE| at standstill after the move, counts.
    pub fe_rest: f64,
    /// `(t ms, FE counts)` every servo step.
    pub trace: Vec<(f64, f64)>,
    /// `(t ms, demand speed rpm)`.
    pub speed: Vec<(f64, f64)>,
}

/// TC86-45: 600 rpm trapezoidal profile (acceleration 200 rev/s², i.e. 50 ms ramps,
/// 300 ms at speed) sent as 1 ms set-points; the drive interpolates linearly (one
/// cycle of delay); FE = interpolated demand − encoder position.
pub fn csp_tracking() -> Tracking {
    csp_tracking_with(0.25, SERVO_BW_HZ)
}

/// [`csp_tracking`] with the interpolator's acceleration filter weight `acc_k`.
/// Phases are classified by the profile as the drive sees it (1 cycle later).
pub fn csp_tracking_with(acc_k: f32, bw_hz: f32) -> Tracking {
    let rig = Rig::new(PlantConfig::new(TC86_45));
    let servo = Servo::new(rig.servo_gains(bw_hz), TS_SERVO, 1000);
    csp_tracking_on(rig, servo, acc_k)
}

/// [`csp_tracking_with`] on a given rig and servo.
pub fn csp_tracking_on(mut rig: Rig, mut servo: Servo, acc_k: f32) -> Tracking {
    let cpr = rig.enc.cpr() as f64;
    let p0 = rig.enc.position();
    let v = 10.0 * cpr;
    let a = 200.0 * cpr;
    let dist = v * v / a + v * 0.3;
    let prof = Trapezoid::new(p0 as f64, p0 as f64 + dist, v, a);
    let per_cycle = 10u32; // 1 ms / 100 µs
    let mut ip = Interpolator::new(per_cycle, TS_SERVO, p0);
    ip.set_acc_filter(acc_k);
    let cycles = (prof.duration() * 1e3).ceil() as usize + 60;
    let mut trace = Vec::new();
    let mut speed = Vec::new();
    let (mut fa, mut fc, mut fr) = (0.0f64, 0.0f64, 0.0f64);
    let mut n = 0usize;
    for c in 0..cycles + 20 {
        let t_set = c as f64 * 1e-3;
        let (p, _, _) = prof.at(t_set - 0.02);
        ip.set_target(p.round() as i64 as i32);
        for _ in 0..per_cycle {
            let d = ip.step();
            rig.servo_period(&mut servo, &d);
            let e = servo.following_error as f64;
            let t_ms = n as f64 * TS_SERVO as f64 * 1e3;
            trace.push((t_ms, e));
            speed.push((t_ms, d.vel as f64 / cpr * 60.0));
            let (_, pv, pa) = prof.at(t_ms * 1e-3 - 0.021);
            if pa != 0.0 {
                fa = fa.max(e.abs());
            } else if pv != 0.0 {
                fc = fc.max(e.abs());
            } else if t_ms > 30.0 {
                fr = fr.max(e.abs());
            }
            n += 1;
        }
    }
    Tracking {
        fe_accel: fa,
        fe_const: fc,
        fe_rest: fr,
        trace,
        speed,
    }
}

/// Auto-tune result on one motor.
#[derive(Clone, Debug)]
pub struct Tune {
    /// Motor name.
    pub motor: &'static str,
    /// The procedure's final state.
    pub state: TuneState,
    /// Values (zero when failed).
    pub result: TuneResult,
    /// R error, %.
    pub r_err_pct: f64,
    /// L error, %.
    pub l_err_pct: f64,
    /// Simulated duration, s.
    pub duration_s: f64,
}

/// Runs auto-tune (test current 0.8·I_rated) on `motor`, optionally with modified
/// phase resistances (fault studies). Gives up after 2.5 s.
pub fn autotune(motor: MotorParams, r_scale: [f64; 2]) -> Tune {
    let mut cfg = PlantConfig::new(motor);
    cfg.r_scale = r_scale;
    autotune_on(cfg)
}

/// [`autotune`] on any plant configuration (initial angle, noise, seed...).
pub fn autotune_on(cfg: PlantConfig) -> Tune {
    autotune_with(cfg, |_| {})
}

/// The auto-tune's test current in the plant runs, fraction of the rated current (the
/// drive's `TEST_CURRENT_FRACTION` of its peak current 0x2000).
pub const TUNE_CURRENT_FRACTION: f64 = 0.8;

/// [`autotune_on`]; `prepare` adjusts the rig first (fault or non-ideality
/// injection).
pub fn autotune_with(cfg: PlantConfig, prepare: impl FnOnce(&mut Rig)) -> Tune {
    let motor = cfg.motor;
    let mut rig = Rig::new(cfg);
    prepare(&mut rig);
    let mut tune = Autotune::new(AutotuneConfig::new(
        TS,
        cfg.pwm_period,
        (TUNE_CURRENT_FRACTION * motor.i_rated) as f32,
    ));
    let max = (2.5 / TS as f64) as u64;
    while !tune.finished() && rig.k < max {
        rig.tick_with(|cl, _, adc| {
            let s = cl.config().sense;
            let i = s.currents(adc);
            let (va, vb) = tune.step(i.alpha, i.beta, s.vbus(adc));
            cl.voltage_step(adc, va, vb)
        });
    }
    let (result, r_err, l_err) = match tune.state {
        TuneState::Done(r) => (
            r,
            (r.r as f64 / motor.r - 1.0) * 100.0,
            (r.l as f64 / motor.l - 1.0) * 100.0,
        ),
        _ => (TuneResult::default(), f64::NAN, f64::NAN),
    };
    Tune {
        motor: motor.name,
        state: tune.state,
        result,
        r_err_pct: r_err,
        l_err_pct: l_err,
        duration_s: rig.time(),
    }
}

pub(crate) fn open_loop_config(ppr: u32, current: f64) -> OpenLoopConfig {
    OpenLoopConfig {
        pulses_per_rev: ppr,
        ts: TS_SERVO,
        running_current: current as f32,
        holding_percent: 50,
        standby: 0.1,
        soft_start: 0.005,
        filter_time: 0.0,
    }
}

/// One servo period of open loop: the open-loop step, then the FOC ticks on its angle.
pub(crate) fn open_loop_period(
    rig: &mut Rig,
    ol: &mut OpenLoop,
    cmd: i32,
) -> foc::open_loop::OpenLoopOutput {
    let o = ol.step(cmd);
    rig.cl.id_ref = o.current;
    rig.cl.iq_ref = 0.0;
    let mut limited = false;
    for _ in 0..SERVO_DIV {
        rig.tick_at(o.angle, o.omega_e);
        limited |= rig.cl.saturated;
    }
    ol.voltage_limited(limited);
    o
}

/// Open → closed switch.
#[derive(Clone, Debug)]
pub struct Switch {
    /// Largest |position − position at the switch| in the 50 ms after it, counts.
    pub jump_counts: f64,
    /// Torque current the open loop produced at the switch (encoder frame), A.
    pub iq_at_switch: f64,
}

/// ECN57-20: open loop (5 A) moves 1/40 rev and stands with a 0.2 N·m load, then
/// switches to closed loop at the actual position.
pub fn open_to_closed() -> Switch {
    let mut rig = Rig::new(PlantConfig::new(ECN57_20));
    let ppr = 10_000;
    let mut ol = OpenLoop::new(open_loop_config(ppr, 5.0), 0);
    // Map command 0 to the rotor's present electrical angle.
    ol.set_angle_offset(super::rig::angle_f64(rig.plant.theta_e()));
    ol.enable(0);
    rig.plant.load = 0.2;
    let mut last = ol.step(0);
    for n in 0..800i32 {
        let cmd = if n < 200 { 0 } else { (n - 200).min(250) };
        last = open_loop_period(&mut rig, &mut ol, cmd);
    }
    let (id0, iq) = handover_currents(last.angle, last.current, rig.enc.electrical_angle());
    let mut servo = Servo::new(rig.servo_gains(SERVO_BW_HZ), TS_SERVO, 1000);
    servo.bumpless_start(iq);
    let p_sw = rig.enc.position();
    let hold = Demand {
        pos: p_sw,
        ..Demand::default()
    };
    let mut jump = 0.0f64;
    let ramp = 200; // 20 ms
    for n in 0..500 {
        let id = id0 * (1.0 - n as f32 / ramp as f32).max(0.0);
        rig.cl.iq_ref = servo.step(&hold, rig.enc.position(), rig.enc.velocity());
        rig.cl.id_ref = id;
        for _ in 0..SERVO_DIV {
            rig.tick();
        }
        jump = jump.max((rig.enc.position() - p_sw).abs() as f64);
    }
    Switch {
        jump_counts: jump,
        iq_at_switch: iq as f64,
    }
}

/// Open loop at speed with load.
#[derive(Clone, Debug)]
pub struct OpenLoopRun {
    /// Running current (vector magnitude), A.
    pub current: f64,
    /// Load torque, N·m.
    pub load: f64,
    /// Largest |command − rotor| electrical angle during the run, degrees electrical
    /// (≥ 180° would be a lost step cycle).
    pub max_lag_deg: f64,
    /// Rotor − command after the stop, full steps (1.8°).
    pub final_error_steps: f64,
}

impl OpenLoopRun {
    /// No step was lost: the rotor never fell half an electrical turn behind and
    /// ended within one full step of the command.
    pub fn lost_nothing(&self) -> bool {
        self.max_lag_deg < 180.0 && self.final_error_steps.abs() < 1.0
    }
}

/// ECN57-20 open loop: 0 → 600 rpm in 100 ms, 300 ms at speed, 100 ms stop, with a
/// constant load `load` N·m opposing the motion, running current `current` A.
pub fn open_loop_600rpm(load: f64, current: f64) -> OpenLoopRun {
    let m = ECN57_20;
    let mut rig = Rig::new(PlantConfig::new(m));
    let ppr = 10_000u32;
    let mut ol = OpenLoop::new(open_loop_config(ppr, current), 0);
    let th0 = rig.plant.theta_e();
    ol.set_angle_offset(super::rig::angle_f64(th0));
    ol.enable(0);
    for _ in 0..100 {
        open_loop_period(&mut rig, &mut ol, 0);
    }
    rig.plant.load = load;
    let v = 10.0 * ppr as f64;
    let a = v / 0.1;
    let dist = v * v / a + v * 0.3;
    let prof = Trapezoid::new(0.0, dist, v, a);
    let n = (prof.duration() / TS_SERVO as f64).ceil() as usize + 500;
    let mut lag = 0.0f64;
    let mut last = 0;
    for k in 0..n {
        let (p, _, _) = prof.at((k + 1) as f64 * TS_SERVO as f64);
        let cmd = p.round() as i32;
        open_loop_period(&mut rig, &mut ol, cmd);
        let cmd_e = th0 + cmd as f64 / ppr as f64 * 2.0 * PI * 50.0;
        lag = lag.max((cmd_e - rig.plant.theta_e()).abs().to_degrees());
        last = cmd;
    }
    let cmd_mech = th0 / 50.0 + last as f64 / ppr as f64 * 2.0 * PI;
    let err_steps = (rig.plant.theta - cmd_mech) / (2.0 * PI / 200.0);
    OpenLoopRun {
        current,
        load,
        max_lag_deg: lag,
        final_error_steps: err_steps,
    }
}

/// Holding current after stand-by.
#[derive(Clone, Debug)]
pub struct Holding {
    /// Running current, A.
    pub running: f64,
    /// Measured current vector magnitude before the stand-by time, A.
    pub before: f64,
    /// Measured current vector magnitude after stand-by + ramp, A.
    pub after: f64,
    /// Stand-by time, ms.
    pub standby_ms: f64,
    /// Time from the last command change until the current was within 2 % of the
    /// holding value, ms.
    pub reached_ms: f64,
}

/// ECN57-20 open loop, 5 A running, 50 % holding after 100 ms.
pub fn holding_current() -> Holding {
    let mut rig = Rig::new(PlantConfig::new(ECN57_20));
    let cfg = open_loop_config(10_000, 5.0);
    let mut ol = OpenLoop::new(cfg, 0);
    ol.set_angle_offset(super::rig::angle_f64(rig.plant.theta_e()));
    ol.enable(0);
    let hold = cfg.running_current as f64 * cfg.holding_percent as f64 / 100.0;
    let mut before = 0.0;
    let mut after = 0.0;
    let mut reached = f64::INFINITY;
    let stop = 100usize;
    for n in 0..stop + 2000 {
        let cmd = (n.min(stop)) as i32;
        open_loop_period(&mut rig, &mut ol, cmd);
        let i = rig.plant.ia.hypot(rig.plant.ib);
        let since = (n as f64 - stop as f64) * TS_SERVO as f64 * 1e3;
        if (since - 50.0).abs() < 0.05 {
            before = i;
        }
        if (i - hold).abs() < 0.02 * hold && reached.is_infinite() && since > 0.0 {
            reached = since;
        }
        if (i - hold).abs() >= 0.1 * hold {
            reached = f64::INFINITY;
        }
        after = i;
    }
    Holding {
        running: cfg.running_current as f64,
        before,
        after,
        standby_ms: cfg.standby as f64 * 1e3,
        reached_ms: reached,
    }
}

/// Alignment.
#[derive(Clone, Debug)]
pub struct Align {
    /// Offset error against the truth, counts.
    pub error_counts: f64,
    /// Duration, ms.
    pub duration_ms: f64,
    /// Procedure succeeded.
    pub done: bool,
}

/// ECN57-20 power-up alignment with the wiggle (1 electrical turn each way).
pub fn alignment(wiggle: bool) -> Align {
    let mut rig = Rig::new_unaligned(PlantConfig::new(ECN57_20));
    let mut al = Alignment::new(AlignConfig {
        ts: TS_SERVO,
        current: 4.0,
        ramp: 0.02,
        settle: 0.05,
        wiggle,
        sweep_cycles: 1,
        sweep_speed: 10.0,
    });
    let mut n = 0u32;
    while n < 20_000 {
        if let AlignState::Done(_) | AlignState::Failed = al.state {
            break;
        }
        let (ang, i) = al.step(rig.enc.raw_electrical_angle());
        rig.cl.id_ref = i;
        rig.cl.iq_ref = 0.0;
        for _ in 0..SERVO_DIV {
            rig.tick_at(ang, 0.0);
        }
        n += 1;
    }
    let (err, done) = match al.state {
        AlignState::Done(off) => (rig.offset_error_counts(off), true),
        _ => (f64::NAN, false),
    };
    Align {
        error_counts: err,
        duration_ms: n as f64 * TS_SERVO as f64 * 1e3,
        done,
    }
}
