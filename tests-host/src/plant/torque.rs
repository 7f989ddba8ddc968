//! Cyclic synchronous torque (CST) on the plant: the firmware's CiA 402 profile
//! ([`firmware::cia402::Cia402`], CST, 1 ms cycles) in front of the firmware's motion
//! layer, the `foc` current loop and the motor model ([`PlantAxis`]: 40 kHz current
//! loop, 10 kHz servo), as on the board.
//!
//! * **Torque step**: 0 → 50 % of the rated torque 0x6076 (Kt · 0x6075, 0x2000 =
//!   3.2 A) with no slope limit (0x6087 = 0), the rotor free at standstill (it
//!   accelerates the rotor's inertia); the electromagnetic torque `Kt·i_q` of the
//!   true plant current, averaged over noise seeds, from the start of the cycle
//!   whose 0x6071 changed. Rise 10-90 % and overshoot of the final value. The goal
//!   follows from the current loop (≈ 170 µs rise, ≤ 5 % overshoot) plus at most one
//!   servo period before the new demand reaches it: rise ≤ 1 ms, overshoot ≤ 5 %.
//! * **Torque ripple at constant speed**: 50 % rated torque demanded, a dynamometer
//!   holds the shaft at 5 rev/s ([`crate::plant::motor::Plant::forced_speed`]), the
//!   loop on the encoder; the peak-to-peak of `Kt·i_q` (true current, ADC noise on)
//!   over [`RIPPLE_WINDOW_S`] after [`RIPPLE_SETTLE_S`], in % of the rated torque
//!   (the detent torque `Td·sin 4θe` comes on top at the shaft: it is the motor's,
//!   not the drive's). Goal ≤ 2 % of the rated torque.

use super::scenarios::Figure;
use crate::sim_axis::PlantAxis;
use crate::sim_drive::{Axis, Motor};
use firmware::cia402::{mode, Cia402, DriveFeedback};

/// Drive cycle, s.
pub const CYCLE_S: f64 = 1e-3;
/// Current-loop period, s (the samples of the traces).
pub const TICK_S: f64 = 25e-6;
/// The torque of both figures, per mille of the rated torque.
pub const TORQUE_PM: i16 = 500;
/// Speed of the ripple measurement, rev/s.
pub const RIPPLE_REV_S: f64 = 5.0;
/// Settling time before the ripple window, s.
pub const RIPPLE_SETTLE_S: f64 = 0.06;
/// Ripple window, s (ten electrical periods at 5 rev/s).
pub const RIPPLE_WINDOW_S: f64 = 0.04;

/// The CiA 402 profile in CST in front of a plant axis.
pub struct CstAxis {
    /// The drive profile.
    pub cia: Cia402,
    /// The plant, current loop and motion layer.
    pub axis: PlantAxis,
    /// Torque constant of the plant's motor, N·m/A.
    pub kt: f64,
}

impl CstAxis {
    /// `motor` at rest, ADC noise seed `seed`, `prepare` adjusts the plant; the
    /// profile enabled in CST with 0x6071 = 0 (20 ms of standstill done).
    pub fn enabled(motor: Motor, seed: u64) -> CstAxis {
        let axis = PlantAxis::with_plant(motor, true, |pc| pc.seed = seed);
        let kt = axis.rig.plant.cfg.motor.kt;
        let mut cia = Cia402::new();
        cia.set_torque_constant(kt as f32);
        cia.set_rated_current_ma(3200);
        cia.set_mode(mode::CST);
        let mut a = CstAxis { cia, axis, kt };
        for cw in [0x0000u16, 0x0006, 0x0007, 0x000F] {
            a.cia.set_controlword(cw);
            a.cycle(|_| {});
        }
        for _ in 0..20 {
            a.cycle(|_| {});
        }
        a
    }

    /// One drive cycle: the profile steps on the axis state, its command goes to the
    /// motion layer, then the plant runs one cycle; `sample` sees the axis after
    /// every current-loop period.
    pub fn cycle(&mut self, mut sample: impl FnMut(&PlantAxis)) {
        let s = self.axis.state();
        let fb = DriveFeedback {
            position: s.position,
            velocity: s.velocity,
            control_effort: s.control_effort,
            torque: s.torque_permille,
            torque_demand: s.current_permille,
            current: s.torque_permille,
            current_limited: s.current_limited,
            enable_pending: s.commutation_pending,
            ..DriveFeedback::default()
        };
        let c = self.cia.cycle(&fb, CYCLE_S as f32);
        self.axis.command(&c, CYCLE_S);
        let n = (CYCLE_S / TICK_S).round() as usize;
        for _ in 0..n {
            self.axis.advance(TICK_S, &c);
            sample(&self.axis);
        }
    }

    /// Electromagnetic torque of the true plant current, N·m.
    pub fn torque_nm(&self) -> f64 {
        self.kt * self.axis.rig.plant.i_dq().1
    }

    /// The rated torque 0x6076, N·m.
    pub fn rated_nm(&self) -> f64 {
        f64::from(self.cia.rated_torque_mnm()) * 1e-3
    }
}

/// A CST torque step (ensemble mean).
#[derive(Clone, Debug)]
pub struct TorqueStep {
    /// Final value, N·m (50 % of the rated torque).
    pub target_nm: f64,
    /// 10-90 % rise time, µs.
    pub rise_us: f64,
    /// Overshoot, % of the final value.
    pub overshoot_pct: f64,
    /// `(t µs after the start of the cycle that brought the step, Kt·i_q N·m)`.
    pub trace: Vec<(f64, f64)>,
}

/// The CST torque step of `motor`, averaged over `runs` noise seeds.
pub fn torque_step(motor: Motor, runs: u32) -> TorqueStep {
    let cycles = 4;
    let n = (cycles as f64 * CYCLE_S / TICK_S).round() as usize;
    let mut acc = vec![0.0f64; n];
    let mut target_nm = 0.0;
    for seed in 0..runs.max(1) {
        let mut a = CstAxis::enabled(motor, 100 + u64::from(seed));
        target_nm = a.rated_nm() * f64::from(TORQUE_PM) * 1e-3;
        a.cia.params.target_torque = TORQUE_PM;
        let mut k = 0;
        for _ in 0..cycles {
            let kt = a.kt;
            a.cycle(|ax| {
                acc[k] += kt * ax.rig.plant.i_dq().1;
                k += 1;
            });
        }
    }
    let runs = f64::from(runs.max(1));
    let trace: Vec<(f64, f64)> = acc
        .iter()
        .enumerate()
        .map(|(k, s)| ((k + 1) as f64 * TICK_S * 1e6, s / runs))
        .collect();
    let cross = |level: f64| -> f64 {
        let mut prev = (0.0, 0.0);
        for &(t, y) in &trace {
            if y >= level {
                let (t0, y0) = prev;
                return t0 + (level - y0) / (y - y0) * (t - t0);
            }
            prev = (t, y);
        }
        f64::INFINITY
    };
    let rise_us = cross(0.9 * target_nm) - cross(0.1 * target_nm);
    let peak = trace.iter().map(|p| p.1).fold(f64::MIN, f64::max);
    TorqueStep {
        target_nm,
        rise_us,
        overshoot_pct: ((peak - target_nm) / target_nm * 100.0).max(0.0),
        trace,
    }
}

/// Torque ripple in CST at constant speed.
#[derive(Clone, Debug)]
pub struct TorqueRipple {
    /// Peak-to-peak of `Kt·i_q`, N·m.
    pub pp_nm: f64,
    /// The same in % of the rated torque.
    pub pp_pct: f64,
    /// Mean of `Kt·i_q` over the window, N·m.
    pub mean_nm: f64,
    /// The demanded torque, N·m.
    pub target_nm: f64,
}

/// The CST torque ripple of `motor` at `rev_s` (dynamometer), 50 % rated torque.
pub fn torque_ripple(motor: Motor, rev_s: f64) -> TorqueRipple {
    let mut a = CstAxis::enabled(motor, 7);
    a.axis.rig.plant.forced_speed = Some(2.0 * std::f64::consts::PI * rev_s);
    a.cia.params.target_torque = TORQUE_PM;
    let settle = (RIPPLE_SETTLE_S / CYCLE_S).round() as usize;
    let window = (RIPPLE_WINDOW_S / CYCLE_S).round() as usize;
    for _ in 0..settle {
        a.cycle(|_| {});
    }
    let (mut lo, mut hi, mut sum, mut n) = (f64::MAX, f64::MIN, 0.0, 0usize);
    let kt = a.kt;
    for _ in 0..window {
        a.cycle(|ax| {
            let t = kt * ax.rig.plant.i_dq().1;
            lo = lo.min(t);
            hi = hi.max(t);
            sum += t;
            n += 1;
        });
    }
    let rated = a.rated_nm();
    TorqueRipple {
        pp_nm: hi - lo,
        pp_pct: (hi - lo) / rated * 100.0,
        mean_nm: sum / n.max(1) as f64,
        target_nm: rated * f64::from(TORQUE_PM) * 1e-3,
    }
}

/// Goal of the step's rise time, µs.
pub const RISE_GOAL_US: f64 = 1000.0;
/// Goal of the step's overshoot, %.
pub const OVERSHOOT_GOAL_PCT: f64 = 5.0;
/// Goal of the ripple, % of the rated torque.
pub const RIPPLE_GOAL_PCT: f64 = 2.0;

fn motor_name(m: Motor) -> &'static str {
    match m {
        Motor::Ecn57_20 => "ECN57-20",
        Motor::Tc86_45 => "TC86-45",
    }
}

/// The rows of the "Cyclic synchronous torque (CST)" table.
pub fn report() -> Vec<Figure> {
    let mut rows = Vec::new();
    for m in [Motor::Ecn57_20, Motor::Tc86_45] {
        let name = motor_name(m);
        let s = torque_step(m, 4);
        rows.push(Figure {
            name: format!(
                "{name}: CST torque step 0 → 50 % rated ({:.0} mN·m), rise 10-90 % / overshoot of Kt·i_q",
                s.target_nm * 1e3
            ),
            goal: format!("≤ {RISE_GOAL_US:.0} µs / ≤ {OVERSHOOT_GOAL_PCT:.0} %"),
            achieved: format!("{:.0} µs / {:.1} %", s.rise_us, s.overshoot_pct),
            met: s.rise_us <= RISE_GOAL_US && s.overshoot_pct <= OVERSHOOT_GOAL_PCT,
        });
        let r = torque_ripple(m, RIPPLE_REV_S);
        rows.push(Figure {
            name: format!(
                "{name}: CST torque ripple Kt·i_q p-p at {RIPPLE_REV_S} rev/s, 50 % rated torque (mean {:.0} of {:.0} mN·m)",
                r.mean_nm * 1e3,
                r.target_nm * 1e3
            ),
            goal: format!("≤ {RIPPLE_GOAL_PCT:.0} % of rated"),
            achieved: format!("{:.1} mN·m ({:.2} % of rated)", r.pp_nm * 1e3, r.pp_pct),
            met: r.pp_pct <= RIPPLE_GOAL_PCT,
        });
    }
    rows
}
