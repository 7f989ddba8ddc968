//! Open-loop speed sweep: where a microstepped hybrid stepper rings or loses steps.
//!
//! The rotor in open loop is a spring-mass system: the current vector of magnitude
//! `I` pulls the rotor with `T = Kt·I·sin δ` (δ the load angle, electrical), a spring
//! of stiffness `k = p·Kt·I` N·m/rad (mechanical) around the operating point, on the
//! rotor inertia `J`. Its natural frequency is `f_n = √(k/J)/2π`; its only damping is
//! the viscous friction `B`, because the current loop holds the current against the
//! back-EMF that would otherwise damp it (`ζ = B / (2√(kJ))`, well below 1 %).
//! Anything periodic in the torque excites it: the detent torque `Td·sin 4θe` at
//! `4·p·n` Hz at `n` rev/s, and the commutation of a rotor that lags by a varying
//! angle.
//!
//! [`sweep`] runs the drive's open loop (`foc::open_loop` + the current loop) on the
//! plant with its back-EMF, voltage limit (the bus) and detent torque, at constant
//! speeds from 0.5 to 20 rev/s with a light load, and measures the rotor's speed
//! ripple and whether a step was lost.

use super::motor::{MotorParams, PlantConfig};
use super::rig::{Rig, LATENCY, SERVO_DIV, TS_SERVO};
use super::scenarios::{open_loop_config, open_loop_period};
use foc::damping::{Damping, DampingConfig};
use foc::open_loop::OpenLoop;
use std::f64::consts::PI;

/// One speed of the sweep.
#[derive(Clone, Copy, Debug)]
pub struct SweepPoint {
    /// Commanded speed, rev/s.
    pub speed: f64,
    /// Rotor speed ripple at constant command speed, peak-to-peak, rev/s.
    pub ripple_pp: f64,
    /// Largest |command − rotor| electrical angle while running, degrees electrical.
    pub max_lag_deg: f64,
    /// Rotor − command at the end, full steps (1.8°).
    pub final_error_steps: f64,
}

impl SweepPoint {
    /// A step was lost: the rotor fell half an electrical turn behind or ended a full
    /// step away from the command.
    pub fn lost_steps(&self) -> bool {
        self.max_lag_deg >= 180.0 || self.final_error_steps.abs() >= 1.0
    }
    /// Speed ripple as a fraction of the speed.
    pub fn ripple_rel(&self) -> f64 {
        self.ripple_pp / self.speed
    }
}

/// Light load of the sweep: 5 % of the holding torque.
pub const LIGHT_LOAD: f64 = 0.05;
/// Acceleration to the sweep speed, rev/s².
pub const ACCEL: f64 = 100.0;
/// Time at constant speed before the ripple is measured, s.
pub const SETTLE: f64 = 0.1;
/// Time over which the ripple is measured, s.
pub const MEASURE: f64 = 0.1;

/// Runs `motor` in open loop at rated current to `speed` rev/s with
/// [`LIGHT_LOAD`], holds the speed and measures (see [`SweepPoint`]).
/// `damped`: with the anti-resonance term of [`foc::damping`] (default gain).
pub fn run_at(motor: MotorParams, speed: f64, damped: bool) -> SweepPoint {
    run_with(motor, speed, damped.then(|| damping_config(motor)))
}

/// The drive's damping configuration for `motor` at the open-loop step rate.
pub fn damping_config(motor: MotorParams) -> DampingConfig {
    DampingConfig::new(
        TS_SERVO,
        motor.r as f32,
        motor.l as f32,
        motor.kt as f32,
        LATENCY,
    )
}

/// [`run_at`] with a given damping configuration (`None`: off).
pub fn run_with(motor: MotorParams, speed: f64, damping: Option<DampingConfig>) -> SweepPoint {
    run_on(PlantConfig::new(motor), speed, damping)
}

/// [`run_with`] on a given plant configuration.
pub fn run_on(cfg: PlantConfig, speed: f64, damping: Option<DampingConfig>) -> SweepPoint {
    let motor = cfg.motor;
    let mut rig = Rig::new(cfg);
    // The dead-time compensation the power-up tune sets (docs/guide/tuning.md, "Quiet current").
    rig.cl.set_dead_time(
        (cfg.dead_time_v / cfg.vbus) as f32,
        foc::current_loop::DEAD_TIME_BAND,
    );
    let ppr = 10_000u32;
    let mut ol = OpenLoop::new(open_loop_config(ppr, motor.i_rated), 0);
    let mut damping = damping.map(Damping::new);
    let th0 = rig.plant.theta_e();
    ol.set_angle_offset(super::rig::angle_f64(th0));
    ol.enable(0);
    for _ in 0..100 {
        open_loop_period(&mut rig, &mut ol, 0);
    }
    rig.plant.load = LIGHT_LOAD * motor.t_hold;
    let ts = TS_SERVO as f64;
    let t_acc = speed / ACCEL;
    let n_acc = (t_acc / ts).ceil() as usize;
    let n_settle = (SETTLE / ts) as usize;
    let n_meas = (MEASURE / ts) as usize;
    let mut pos = 0.0f64; // command, revolutions
    let (mut lag, mut w_min, mut w_max) = (0.0f64, f64::MAX, f64::MIN);
    let mut cmd = 0;
    for k in 0..n_acc + n_settle + n_meas {
        let v = if k < n_acc {
            ACCEL * (k + 1) as f64 * ts
        } else {
            speed
        };
        pos += v * ts;
        cmd = (pos * ppr as f64).round() as i32;
        match damping.as_mut() {
            Some(d) => damped_period(&mut rig, &mut ol, d, cmd),
            None => {
                open_loop_period(&mut rig, &mut ol, cmd);
            }
        }
        let cmd_e = th0 + cmd as f64 / ppr as f64 * 2.0 * PI * 50.0;
        lag = lag.max((cmd_e - rig.plant.theta_e()).abs().to_degrees());
        if k >= n_acc + n_settle {
            let w = rig.plant.omega / (2.0 * PI);
            w_min = w_min.min(w);
            w_max = w_max.max(w);
        }
    }
    let cmd_mech = th0 / 50.0 + cmd as f64 / ppr as f64 * 2.0 * PI;
    SweepPoint {
        speed,
        ripple_pp: w_max - w_min,
        max_lag_deg: lag,
        final_error_steps: (rig.plant.theta - cmd_mech) / (2.0 * PI / 200.0),
    }
}

/// One servo period of open loop with the damping term on the command angle.
fn damped_period(rig: &mut Rig, ol: &mut OpenLoop, damping: &mut Damping, cmd: i32) {
    let o = ol.step(cmd);
    let corr = damping.update(rig.cl.i_ab, o.omega_e);
    let angle = o.angle.wrapping_add(corr);
    rig.cl.id_ref = o.current;
    rig.cl.iq_ref = 0.0;
    let mut limited = false;
    for _ in 0..SERVO_DIV {
        rig.tick_at(angle, o.omega_e);
        damping.tick(rig.cl.v_ab);
        limited |= rig.cl.saturated;
    }
    ol.voltage_limited(limited);
}

/// The sweep's speeds: 0.5 to 20 rev/s.
pub fn speeds() -> Vec<f64> {
    let mut v = Vec::new();
    let mut s = 0.5;
    while s <= 20.0 + 1e-9 {
        v.push(s);
        s += if s < 3.0 { 0.125 } else { 0.5 };
    }
    v
}

/// The sweep on `motor`.
pub fn sweep(motor: MotorParams, damped: bool) -> Vec<SweepPoint> {
    speeds()
        .into_iter()
        .map(|s| run_at(motor, s, damped))
        .collect()
}

/// Speed bands of the report, rev/s: the low-speed resonance, the middle, and the
/// high band where the voltage limit matters.
pub const BANDS: [(f64, f64); 3] = [(0.5, 3.0), (3.0, 8.0), (8.0, 20.0)];

/// The worst point of `points` within `band` (largest relative speed ripple).
pub fn worst_in(points: &[SweepPoint], band: (f64, f64)) -> Option<SweepPoint> {
    points
        .iter()
        .filter(|p| p.speed >= band.0 - 1e-9 && p.speed < band.1 + 1e-9)
        .copied()
        .max_by(|a, b| a.ripple_rel().total_cmp(&b.ripple_rel()))
}

/// Both sweeps of one motor: damping off, then on.
pub struct MotorSweep {
    /// The motor.
    pub motor: MotorParams,
    /// Damping off.
    pub off: Vec<SweepPoint>,
    /// Damping on (default gain, 0x2059 = 1000 µs).
    pub on: Vec<SweepPoint>,
}

/// The sweeps of both motors.
pub fn sweeps() -> Vec<MotorSweep> {
    [super::motor::ECN57_20, super::motor::TC86_45]
        .into_iter()
        .map(|motor| MotorSweep {
            motor,
            off: sweep(motor, false),
            on: sweep(motor, true),
        })
        .collect()
}

fn ripple_text(p: &SweepPoint) -> String {
    format!(
        "{:.0} % ({:.2} rev/s p-p at {} rev/s)",
        100.0 * p.ripple_rel(),
        p.ripple_pp,
        p.speed
    )
}

fn lost_text(points: &[SweepPoint]) -> String {
    let lost: Vec<f64> = points
        .iter()
        .filter(|p| p.lost_steps())
        .map(|p| p.speed)
        .collect();
    match (lost.first(), lost.last()) {
        (Some(a), Some(b)) => format!("from {a} to {b} rev/s ({} of {})", lost.len(), points.len()),
        _ => "none".into(),
    }
}

/// The report's rows for the sweeps `s` (BENCHMARKS.md, "Open-loop resonance").
///
/// Goals: in the resonance band the damping at least halves the worst ripple; in the
/// middle band the ripple stays ≤ 10 % of the speed; in the high band ≤ 2 %; and no
/// step is lost anywhere with the damping on.
pub fn report_of(s: &[MotorSweep]) -> Vec<super::scenarios::Figure> {
    let mut rows = Vec::new();
    for m in s {
        let name = m.motor.name;
        for (k, band) in BANDS.iter().enumerate() {
            let (Some(off), Some(on)) = (worst_in(&m.off, *band), worst_in(&m.on, *band)) else {
                continue;
            };
            let (goal, met) = match k {
                0 => (
                    "damped ≤ ½ undamped".to_string(),
                    on.ripple_rel() <= 0.5 * off.ripple_rel(),
                ),
                1 => ("damped ≤ 10 %".to_string(), on.ripple_rel() <= 0.10),
                _ => ("damped ≤ 2 %".to_string(), on.ripple_rel() <= 0.02),
            };
            rows.push(super::scenarios::Figure {
                name: format!(
                    "{name}: worst speed ripple p-p / speed, {}-{} rev/s",
                    band.0, band.1
                ),
                goal,
                achieved: format!("{} (undamped {})", ripple_text(&on), ripple_text(&off)),
                met,
            });
        }
        rows.push(super::scenarios::Figure {
            name: format!("{name}: lost steps, 0.5-20 rev/s"),
            goal: "none with damping".into(),
            achieved: format!("{} (undamped {})", lost_text(&m.on), lost_text(&m.off)),
            met: m.on.iter().all(|p| !p.lost_steps()),
        });
    }
    rows
}
