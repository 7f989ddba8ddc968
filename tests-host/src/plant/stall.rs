//! Open-loop stall detection ([`foc::stall`]) on the plant: detection time against a
//! hard stop, false trips over the acceleration range of the control-quality
//! scenarios, and the position error of stall homing.
//!
//! The rig is the open loop of [`super::scenarios`] (open-loop step at 10 kHz, FOC on
//! its angle at 40 kHz) with the detector stepping once per servo period on the
//! current loop's `v_dq`, `i_dq` averaged over the servo period's four current-loop
//! steps and the command's electrical speed, as the firmware does
//! (`firmware::control_core` averages, `firmware::motion` steps the detector). The detector's motor model is
//! the plant's R, L and Ke (the values the drive's auto-tune and motor data give);
//! its threshold is the drive's default ([`DEFAULT_THRESHOLD`], 0x2061 = 30 %).

use super::motor::{HardStop, MotorParams, PlantConfig, ECN57_20, TC86_45};
use super::rig::{angle_f64, Rig, Trapezoid, SERVO_DIV, TS_SERVO};
use super::scenarios::Figure;
use foc::open_loop::{OpenLoop, OpenLoopConfig};
use foc::stall::{StallConfig, StallDetector, StallState};
use foc::transforms::Dq;
use std::f64::consts::PI;

/// The drive's default threshold (0x2061 = 30 %).
pub const DEFAULT_THRESHOLD: f32 = 0.30;
/// Command pulses per revolution of the rigs.
pub const PPR: u32 = 10_000;
/// Accelerations of the control-quality scenarios, rev/s²: the open loop at 600 rpm
/// (100), CSP tracking (200) and the 90° move (500).
pub const ACCELERATIONS: [f64; 3] = [100.0, 200.0, 500.0];
/// Speed of the stall-homing search (0x6099:01), rev/s.
pub const HOMING_SPEED: f64 = 2.0;
/// Goal of the stall-homing position error: one full step, degrees.
pub const HOMING_GOAL_DEG: f64 = 1.8;

fn add(a: Dq, b: Dq) -> Dq {
    Dq {
        d: a.d + b.d,
        q: a.q + b.q,
    }
}

/// Open loop + detector on the plant.
pub struct StallRig {
    /// Plant, current loop, encoder (the encoder is not used by the open loop).
    pub rig: Rig,
    /// The open loop.
    pub ol: OpenLoop,
    /// The detector.
    pub det: StallDetector,
    /// Rotor electrical angle at command 0, rad.
    pub th0: f64,
    /// Command position of the last step, pulses.
    pub cmd: i32,
    /// Command position at the detector's last onset ([`StallDetector::onset`]).
    pub onset: i32,
}

impl StallRig {
    /// `motor` at rest, open loop enabled at its rated current, `seed` for the noise.
    pub fn new(motor: MotorParams, seed: u64, theta0: f64) -> Self {
        let mut cfg = PlantConfig::new(motor);
        cfg.seed = seed;
        cfg.theta0 = theta0;
        let rig = Rig::new(cfg);
        let mut ol = OpenLoop::new(
            OpenLoopConfig {
                pulses_per_rev: PPR,
                ts: TS_SERVO,
                running_current: motor.i_rated as f32,
                holding_percent: 100,
                standby: 0.1,
                soft_start: 0.005,
                filter_time: 0.0,
            },
            0,
        );
        let th0 = rig.plant.theta_e();
        ol.set_angle_offset(angle_f64(th0));
        ol.enable(0);
        let det = StallDetector::new(StallConfig {
            ts: TS_SERVO,
            r: motor.r as f32,
            l: motor.l as f32,
            ke: motor.kt as f32,
            threshold: DEFAULT_THRESHOLD,
        });
        StallRig {
            rig,
            ol,
            det,
            th0,
            cmd: 0,
            onset: 0,
        }
    }

    /// One servo period at command `cmd` (pulses); returns the detector's verdict.
    pub fn period(&mut self, cmd: i32) -> StallState {
        let o = self.ol.step(cmd);
        self.rig.cl.id_ref = o.current;
        self.rig.cl.iq_ref = 0.0;
        let mut limited = false;
        let (mut v, mut i) = (Dq::default(), Dq::default());
        for _ in 0..SERVO_DIV {
            self.rig.tick_at(o.angle, o.omega_e);
            limited |= self.rig.cl.saturated;
            v = add(v, self.rig.cl.v_dq);
            i = add(i, self.rig.cl.i_dq);
        }
        self.ol.voltage_limited(limited);
        let k = 1.0 / SERVO_DIV as f32;
        let s = self.det.step(
            Dq {
                d: v.d * k,
                q: v.q * k,
            },
            Dq {
                d: i.d * k,
                q: i.q * k,
            },
            o.omega_e,
        );
        if self.det.onset() {
            self.onset = o.position;
        }
        self.cmd = o.position;
        s
    }

    /// Rotor position relative to command 0, pulses.
    pub fn rotor_pulses(&self) -> f64 {
        (self.rig.plant.theta_e() - self.th0) / (2.0 * PI * 50.0) * f64::from(PPR)
    }

    /// Shaft angle of command position `p` (pulses), rad.
    pub fn shaft_at(&self, p: f64) -> f64 {
        self.th0 / 50.0 + p / f64::from(PPR) * 2.0 * PI
    }
}

/// Detection against a hard stop at speed.
#[derive(Clone, Debug)]
pub struct Detection {
    /// Speed, rev/s.
    pub rev_s: f64,
    /// Time from the impact to the detection, ms (∞: not detected in 100 ms).
    pub time_ms: f64,
    /// Two electrical periods, ms (the goal).
    pub goal_ms: f64,
}

/// ECN57-20, rated current: accelerates at 100 rev/s² to `rev_s`, runs 50 ms at speed
/// and hits a steel stop; time from the impact to the detection.
pub fn detection_time(motor: MotorParams, rev_s: f64) -> Detection {
    let mut r = StallRig::new(motor, 1, 0.0123);
    let ppr = f64::from(PPR);
    let v = rev_s * ppr;
    let a = 100.0 * ppr;
    let d_acc = v * v / (2.0 * a);
    let stop_p = d_acc + v * 0.05;
    let prof = Trapezoid::new(0.0, 100.0 * ppr, v, a);
    r.rig.plant.hard_stop = Some(HardStop::steel(r.shaft_at(stop_p), 1.0, motor.j));
    for _ in 0..100 {
        r.period(0);
    }
    let stop = r.rig.plant.hard_stop.map_or(0.0, |h| h.at);
    let (mut impact, mut found) = (None, None);
    let n_max = ((d_acc / v * 2.0 + 0.05 + 0.1) / TS_SERVO as f64) as usize;
    for k in 0..n_max {
        let t = (k + 1) as f64 * TS_SERVO as f64;
        let (p, _, _) = prof.at(t);
        let s = r.period(p.round() as i32);
        if impact.is_none() && r.rig.plant.theta >= stop {
            impact = Some(t);
        }
        if s == StallState::Stalled {
            found = Some(t);
            break;
        }
    }
    let time_ms = match (impact, found) {
        (Some(i), Some(f)) => (f - i) * 1e3,
        _ => f64::INFINITY,
    };
    Detection {
        rev_s,
        time_ms,
        goal_ms: 2.0 / (50.0 * rev_s) * 1e3,
    }
}

/// A free run (no stop) with a trapezoidal move.
#[derive(Clone, Debug)]
pub struct FreeRun {
    /// Motor.
    pub motor: &'static str,
    /// Acceleration, rev/s².
    pub accel: f64,
    /// Top speed, rev/s.
    pub rev_s: f64,
    /// Load torque, N·m.
    pub load: f64,
    /// The detector tripped.
    pub tripped: bool,
    /// Largest |command − rotor|, degrees electrical (≥ 180: the rotor really slipped).
    pub max_lag_deg: f64,
    /// Smallest ratio `s` seen while the detector was active.
    pub min_ratio: f64,
}

/// `motor` at rated current with `load` N·m opposing the motion: 0 → `rev_s` at
/// `accel`, 100 ms at speed, stop at `accel`.
pub fn free_run(motor: MotorParams, accel: f64, rev_s: f64, load: f64) -> FreeRun {
    let mut r = StallRig::new(motor, 7, 0.0123);
    let ppr = f64::from(PPR);
    let v = rev_s * ppr;
    let a = accel * ppr;
    let dist = v * v / a + v * 0.1;
    let prof = Trapezoid::new(0.0, dist, v, a);
    for _ in 0..100 {
        r.period(0);
    }
    r.rig.plant.load = load;
    let n = (prof.duration() / TS_SERVO as f64).ceil() as usize + 300;
    let (mut tripped, mut lag, mut min_ratio) = (false, 0.0f64, f64::INFINITY);
    for k in 0..n {
        let (p, _, _) = prof.at((k + 1) as f64 * TS_SERVO as f64);
        let s = r.period(p.round() as i32);
        tripped |= s == StallState::Stalled;
        if matches!(s, StallState::InStep | StallState::Suspect) {
            min_ratio = min_ratio.min(f64::from(r.det.ratio()));
        }
        let e = (f64::from(r.cmd) - r.rotor_pulses()) / ppr * 360.0 * 50.0;
        lag = lag.max(e.abs());
    }
    FreeRun {
        motor: motor.name,
        accel,
        rev_s,
        load,
        tripped,
        max_lag_deg: lag,
        min_ratio,
    }
}

/// The free runs of the false-trip figure: both motors, every acceleration of
/// [`ACCELERATIONS`], to 10 rev/s (ECN57-20, as the 600 rpm open-loop scenario) or
/// 5 rev/s (TC86-45: at 48 V its 6 A reach 5 rev/s, `ωe·L·I` alone is 56 V at 10),
/// unloaded and with 25 % of the holding torque.
pub fn false_trip_runs() -> Vec<FreeRun> {
    let mut runs = Vec::new();
    for (motor, rev_s) in [(ECN57_20, 10.0), (TC86_45, 5.0)] {
        for accel in ACCELERATIONS {
            for load in [0.0, 0.25 * motor.t_hold] {
                runs.push(free_run(motor, accel, rev_s, load));
            }
        }
    }
    runs
}

/// One stall homing run.
#[derive(Clone, Debug)]
pub struct Homing {
    /// The stall was detected.
    pub found: bool,
    /// Home error: where the drive puts the stop minus where it is, degrees
    /// (mechanical).
    pub error_deg: f64,
}

/// Stall homing as the drive's method −1 does it (`firmware::cia402::homing`): search
/// at [`HOMING_SPEED`] towards a steel stop until the stall is confirmed, take the
/// command position where the ratio first fell below the threshold as the stop, hold
/// there, back off 0.1 rev; the error compares the stop the drive took with the true
/// stop face. `seed` sets the noise and the stop's place (any fraction of a step).
pub fn stall_homing(motor: MotorParams, seed: u64) -> Homing {
    let mut rng = super::rng::Rng::new(seed * 7919 + 1);
    let theta0 = rng.uniform() * 2.0 * PI;
    let mut r = StallRig::new(motor, seed, theta0);
    let ppr = f64::from(PPR);
    let stop_p = (0.2 + 0.05 * rng.uniform()) * ppr;
    r.rig.plant.hard_stop = Some(HardStop::steel(r.shaft_at(stop_p), 1.0, motor.j));
    for _ in 0..100 {
        r.period(0);
    }
    let v = HOMING_SPEED * ppr;
    let prof = Trapezoid::new(0.0, 10.0 * ppr, v, 100.0 * ppr);
    let mut home = None;
    for k in 0..((1.0 / TS_SERVO as f64) as usize) {
        let (p, _, _) = prof.at((k + 1) as f64 * TS_SERVO as f64);
        if r.period(p.round() as i32) == StallState::Stalled {
            home = Some(r.onset);
            break;
        }
    }
    let Some(home) = home else {
        return Homing {
            found: false,
            error_deg: f64::NAN,
        };
    };
    for _ in 0..500 {
        r.period(home);
    }
    let back = home - PPR as i32 / 10;
    for k in 0..3000 {
        r.period(home - (k.min(PPR as i32 / 10)));
    }
    // The drive's stop is `home`; the rotor stands at `back` (as far as the drive
    // knows): the stop face lies (stop − rotor) from it in truth.
    let stop_true = r.rig.plant.hard_stop.map_or(0.0, |h| h.at);
    let rotor = r.rig.plant.theta;
    let claimed = f64::from(home - back) / ppr * 360.0;
    let actual = (stop_true - rotor).to_degrees();
    Homing {
        found: true,
        error_deg: claimed - actual,
    }
}

/// The figures for the report.
pub fn report() -> Vec<Figure> {
    let mut rows = Vec::new();
    for rev_s in [2.0, 5.0, 10.0] {
        let d = detection_time(ECN57_20, rev_s);
        rows.push(Figure {
            name: format!("ECN57-20 open loop {rev_s} rev/s into a hard stop: detection time"),
            goal: format!("≤ {:.1} ms (2 el. periods)", d.goal_ms),
            achieved: format!("{:.2} ms", d.time_ms),
            met: d.time_ms <= d.goal_ms,
        });
    }
    let runs = false_trip_runs();
    let trips = runs.iter().filter(|r| r.tripped).count();
    let slipped = runs.iter().filter(|r| r.max_lag_deg >= 180.0).count();
    let min_ratio = runs
        .iter()
        .map(|r| r.min_ratio)
        .fold(f64::INFINITY, f64::min);
    rows.push(Figure {
        name: format!(
            "false trips, {} runs: ECN57-20 to 10 rev/s, TC86-45 to 5 rev/s, at 100, 200, 500 rev/s², 0 / 25 % T_hold load",
            runs.len()
        ),
        goal: "0".into(),
        achieved: format!(
            "{trips} (lowest ratio {min_ratio:.2} vs threshold {DEFAULT_THRESHOLD}; {slipped} runs slipped)"
        ),
        met: trips == 0 && slipped == 0,
    });
    let homes: Vec<Homing> = (1..=20).map(|s| stall_homing(ECN57_20, s)).collect();
    let found = homes.iter().filter(|h| h.found).count();
    let worst = homes
        .iter()
        .map(|h| h.error_deg.abs())
        .fold(
            0.0f64,
            |a, b| if b.is_nan() { f64::INFINITY } else { a.max(b) },
        );
    let mean = homes.iter().map(|h| h.error_deg).sum::<f64>() / homes.len() as f64;
    rows.push(Figure {
        name: format!(
            "stall homing ECN57-20 at {HOMING_SPEED} rev/s, 20 runs with noise: position error"
        ),
        goal: format!("≤ ±{HOMING_GOAL_DEG}° (1 full step)"),
        achieved: format!("largest {worst:.2}° (mean {mean:+.2}°), {found}/20 found"),
        met: found == 20 && worst <= HOMING_GOAL_DEG,
    });
    rows
}
