//! Current-loop robustness: the `foc` current loop on a plant with the non-idealities
//! of a real motor and board ([`super::motor`], "Non-idealities"), one at a time and
//! all together.
//!
//! Two measurements:
//! * **step**: a 0.5 A q-current step on a locked rotor, overshoot of the true i_q
//!   (the ensemble mean over noise seeds, as [`super::scenarios::current_step`]);
//! * **ripple**: the shaft held at a constant speed by a dynamometer, i_q* = 0.5 A,
//!   the loop on the encoder's angle and speed as in closed loop; the peak-to-peak of
//!   the true i_q over [`RIPPLE_WINDOW`] after [`RIPPLE_SETTLE`]. The ADC noise is
//!   off in the ripple runs: with 1 LSB of noise (4.9 mA) the peak-to-peak is the
//!   noise's, whatever the loop does, and the effect measured is lost in it.

use super::motor::{
    MotorParams, PlantConfig, ECN57_20, SATURATION_ECN57_20, SATURATION_TC86_45, TC86_45,
};
use super::rig::{Rig, TS};
use super::scenarios::{autotune_with, current_step_on, Figure, TUNE_CURRENT_FRACTION};
use foc::autotune::{TuneResult, TuneState};
use std::f64::consts::PI;
use std::sync::Mutex;

/// Settling time before a ripple measurement, s (the encoder PLL and the integrators).
pub const RIPPLE_SETTLE: f64 = 0.06;
/// Length of a ripple measurement, s (two electrical periods at 1 rev/s).
pub const RIPPLE_WINDOW: f64 = 0.04;
/// q-current held during the ripple runs, A.
pub const RIPPLE_IQ: f64 = 0.5;

/// The non-idealities of one run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conditions {
    /// Inductance multiplier (tuned L / true L⁻¹).
    pub l_scale: f64,
    /// Use the motor's L(i) curve.
    pub saturation: bool,
    /// Samples of delay to the duty update.
    pub delay: f64,
    /// Current-sensor gains (A, B).
    pub adc_gain: [f64; 2],
    /// Sensor offsets (A, B), A.
    pub offset_a: [f64; 2],
    /// Dead-time voltage loss, V.
    pub dead_time_v: f64,
}

impl Conditions {
    /// The ideal plant, no dead time.
    pub const IDEAL: Conditions = Conditions {
        l_scale: 1.0,
        saturation: false,
        delay: 1.0,
        adc_gain: [1.0, 1.0],
        offset_a: [0.0, 0.0],
        dead_time_v: 0.0,
    };

    /// Everything on: L 30 % below the motor data and falling with the current (L(i)),
    /// delay 1.5, ±3 % gains, ±20 mA offsets, 0.5 V dead time.
    pub const ALL: Conditions = Conditions {
        l_scale: 0.7,
        saturation: true,
        delay: 1.5,
        adc_gain: [1.03, 0.97],
        offset_a: [0.02, -0.02],
        dead_time_v: 0.5,
    };

    /// The ideal plant with `delay` samples of delay and the true L `l_scale` × the
    /// motor data.
    pub const fn delayed(delay: f64, l_scale: f64) -> Conditions {
        Conditions {
            l_scale,
            delay,
            ..Conditions::IDEAL
        }
    }

    /// The plant configuration of `motor` under these conditions.
    pub fn plant(&self, motor: MotorParams) -> PlantConfig {
        let mut cfg = PlantConfig::new(motor);
        cfg.l_scale = self.l_scale;
        cfg.saturation = if !self.saturation {
            0.0
        } else if motor.name == TC86_45.name {
            SATURATION_TC86_45
        } else {
            SATURATION_ECN57_20
        };
        cfg.delay = self.delay;
        cfg.adc_gain = self.adc_gain;
        cfg.dead_time_v = self.dead_time_v;
        cfg
    }

    fn offsets_counts(&self, cfg: &PlantConfig) -> [f64; 2] {
        let lsb = 2.0 * cfg.adc_full_scale / 4096.0;
        [self.offset_a[0] / lsb, self.offset_a[1] / lsb]
    }
}

/// The power-up auto-tune on the plant of `motor` under `c` (with its ADC noise).
/// Panics if the tune does not finish: every condition here is a healthy drive.
/// The tune is deterministic (seeded noise): each `(motor, c)` is tuned once per
/// process and its result reused.
pub fn tune(motor: MotorParams, c: &Conditions) -> TuneResult {
    static DONE: Mutex<Vec<(&'static str, Conditions, TuneResult)>> = Mutex::new(Vec::new());
    let known = |d: &Vec<(&'static str, Conditions, TuneResult)>| {
        d.iter()
            .find(|(n, k, _)| *n == motor.name && k == c)
            .map(|e| e.2)
    };
    if let Some(r) = known(&DONE.lock().unwrap_or_else(|e| e.into_inner())) {
        return r;
    }
    let cfg = c.plant(motor);
    let off = c.offsets_counts(&cfg);
    let t = autotune_with(cfg, |rig| rig.plant.adc_offset_error = off);
    let r = match t.state {
        TuneState::Done(r) => r,
        other => panic!("auto-tune on {} under {c:?}: {other:?}", motor.name),
    };
    DONE.lock()
        .unwrap_or_else(|e| e.into_inner())
        .push((motor.name, *c, r));
    r
}

/// Error (%) of the tuned inductance against the plant's true incremental inductance
/// at the test current, and the delay (samples) the tune measured, under `c`.
pub fn tuned_l_error(motor: MotorParams, c: &Conditions) -> (f64, f64) {
    let r = tune(motor, c);
    let i_test = TUNE_CURRENT_FRACTION * motor.i_rated;
    let truth = c.plant(motor).inductance(i_test);
    ((r.l as f64 / truth - 1.0) * 100.0, r.delay as f64)
}

/// Whether a run applies the auto-tune's calibration (offsets, channel gain, dead
/// time, L) before it measures, as the drive does after its power-up tune.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Calibration {
    /// The loop as configured from the motor data, nothing measured.
    Off,
    /// The auto-tune's results applied.
    Tuned,
}

fn rig(motor: MotorParams, c: &Conditions, cfg: PlantConfig, cal: Calibration) -> Rig {
    let off = c.offsets_counts(&cfg);
    let mut rig = Rig::new(cfg);
    rig.plant.adc_offset_error = off;
    if cal == Calibration::Tuned {
        rig.apply_tune(&tune(motor, c));
    }
    rig
}

/// Overshoot (%) of a 0.5 A q step under `c`.
pub fn step_overshoot(motor: MotorParams, c: &Conditions, cal: Calibration) -> f64 {
    step_overshoot_of(motor, c, Design::Robust(cal))
}

/// Overshoot (%) of a 0.5 A q step under `c` with the loop `design` (the encoder
/// does not matter: the rotor is locked).
pub fn step_overshoot_of(motor: MotorParams, c: &Conditions, design: Design) -> f64 {
    let cfg = c.plant(motor);
    let cal = match design {
        Design::Robust(cal) => cal,
        Design::Baseline => Calibration::Off,
    };
    let mut setup = rig(motor, c, cfg, cal);
    if design == Design::Baseline {
        setup
            .cl
            .set_gains_for_bandwidth(motor, 2.0 * PI / (20.0 * TS as f64));
    }
    current_step_on(cfg, 8, |r| {
        r.plant.adc_offset_error = setup.plant.adc_offset_error;
        r.cl = setup.cl.clone();
    })
    .overshoot_pct
}

/// Gains of the motor data for a bandwidth (the baseline's).
trait BaselineGains {
    fn set_gains_for_bandwidth(&mut self, motor: MotorParams, wc: f64);
}

impl BaselineGains for foc::current_loop::CurrentLoop {
    fn set_gains_for_bandwidth(&mut self, motor: MotorParams, wc: f64) {
        let (kp, ki) = foc::current_loop::CurrentLoopConfig::gains_for(
            motor.r as f32,
            motor.l as f32,
            wc as f32,
        );
        self.set_gains(kp, ki);
    }
}

/// Which current loop a run drives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Design {
    /// The loop before the robustness work, for the "before" figures: `ωc = 2π·f_s/20`,
    /// commutation on the encoder count and the PLL speed, no calibration.
    Baseline,
    /// The drive's loop: robust bandwidth, the commutation tracker, the calibration
    /// `cal`.
    Robust(Calibration),
}

/// Peak-to-peak of the true i_q (A) at `rev_s` revolutions per second under `c`.
pub fn iq_ripple(motor: MotorParams, c: &Conditions, cal: Calibration, rev_s: f64) -> f64 {
    ripple_of(motor, c, Design::Robust(cal), rev_s)
}

/// Peak-to-peak of the true i_q (A) at `rev_s` under `c` with the loop `design`.
pub fn ripple_of(motor: MotorParams, c: &Conditions, design: Design, rev_s: f64) -> f64 {
    spin(motor, c, design, rev_s).iq_pp
}

/// The true currents of a run at constant speed ([`spin`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spin {
    /// Peak-to-peak of i_q, A.
    pub iq_pp: f64,
    /// Peak-to-peak of i_d, A.
    pub id_pp: f64,
    /// Mean i_q over the window, A (the reference is [`RIPPLE_IQ`]).
    pub iq_mean: f64,
}

impl Spin {
    /// Steady error of the mean i_q against its reference, %.
    pub fn iq_error_pct(&self) -> f64 {
        (self.iq_mean / RIPPLE_IQ - 1.0) * 100.0
    }
}

/// The shaft at `rev_s` under `c` with the loop `design`, i_q* = [`RIPPLE_IQ`]:
/// the true currents over [`RIPPLE_WINDOW`] after [`RIPPLE_SETTLE`].
pub fn spin(motor: MotorParams, c: &Conditions, design: Design, rev_s: f64) -> Spin {
    let mut cfg = c.plant(motor);
    cfg.adc_noise_lsb = 0.0;
    let cal = match design {
        Design::Robust(cal) => cal,
        Design::Baseline => Calibration::Off,
    };
    let mut rig = rig(motor, c, cfg, cal);
    if design == Design::Baseline {
        rig.cl
            .set_gains_for_bandwidth(motor, 2.0 * PI / (20.0 * TS as f64));
    }
    spin_rig(rig, design, rev_s)
}

/// [`spin`] on a prepared rig.
fn spin_rig(mut rig: Rig, design: Design, rev_s: f64) -> Spin {
    rig.plant.forced_speed = Some(2.0 * PI * rev_s);
    rig.cl.iq_ref = RIPPLE_IQ as f32;
    let settle = (RIPPLE_SETTLE / TS as f64).round() as usize;
    let window = (RIPPLE_WINDOW / TS as f64).round() as usize;
    let (mut q_lo, mut q_hi, mut d_lo, mut d_hi) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    let mut sum = 0.0;
    for k in 0..settle + window {
        match design {
            Design::Robust(_) => rig.tick(),
            Design::Baseline => {
                rig.tick_with(|cl, enc, adc| cl.step(adc, enc.electrical_angle(), enc.omega_e()))
            }
        }
        if k >= settle {
            let (id, iq) = rig.plant.i_dq();
            (q_lo, q_hi) = (q_lo.min(iq), q_hi.max(iq));
            (d_lo, d_hi) = (d_lo.min(id), d_hi.max(id));
            sum += iq;
        }
    }
    Spin {
        iq_pp: q_hi - q_lo,
        id_pp: d_hi - d_lo,
        iq_mean: sum / window as f64,
    }
}

/// i_q ripple against speed, `(rev/s, mA p-p)`, for the tuning guide's plot: 0.013 to
/// 10.013 rev/s in steps of 0.25 (speeds whose count pattern does not repeat).
pub fn ripple_sweep(motor: MotorParams, c: &Conditions, design: Design) -> Vec<(f64, f64)> {
    (0..=40)
        .map(|n| {
            let v = n as f64 * 0.25 + 0.013;
            (v, 1e3 * ripple_of(motor, c, design, v))
        })
        .collect()
}

/// Peak-to-peak of the electromagnetic torque `Kt·i_q` (N·m) at `rev_s` under `c`.
pub fn torque_ripple(motor: MotorParams, c: &Conditions, cal: Calibration, rev_s: f64) -> f64 {
    motor.kt * iq_ripple(motor, c, cal, rev_s)
}

/// The "robustness" rows of BENCHMARKS.md: each figure of the robust loop with, in
/// brackets, the same figure before ([`Design::Baseline`], or the uncalibrated loop).
pub fn report() -> Vec<Figure> {
    let mut rows = Vec::new();
    for motor in [ECN57_20, TC86_45] {
        rows.extend(motor_rows(motor));
    }
    rows
}

fn figure(name: String, goal: &str, achieved: String, met: bool) -> Figure {
    Figure {
        name,
        goal: goal.into(),
        achieved,
        met,
    }
}

/// The delays (samples) of the overshoot rows, and the inductance multipliers.
pub const DELAYS: [f64; 3] = [0.5, 1.0, 1.5];
/// Inductance multipliers (true L / the motor data's) of the overshoot rows.
pub const L_SCALES: [f64; 3] = [0.7, 1.0, 1.3];
/// The delays of the tuned-L rows, samples.
pub const L_DELAYS: [f64; 5] = [0.5, 0.75, 1.0, 1.25, 1.5];
/// The sensor conditions of the gain / offset rows: gains 3 % apart each way,
/// offsets ±20 mA.
pub const SENSORS: Conditions = Conditions {
    adc_gain: [1.03, 0.97],
    offset_a: [0.02, -0.02],
    ..Conditions::IDEAL
};

/// `a / b / c` of figures with `digits` decimals.
fn joined(xs: impl IntoIterator<Item = f64>, digits: usize) -> String {
    xs.into_iter()
        .map(|x| format!("{x:.digits$}"))
        .collect::<Vec<_>>()
        .join(" / ")
}

fn motor_rows(motor: MotorParams) -> Vec<Figure> {
    let mut rows = Vec::new();
    step_rows(motor, &mut rows);
    tuned_l_rows(motor, &mut rows);
    ripple_rows(motor, &mut rows);
    sensor_rows(motor, &mut rows);
    combined_rows(motor, &mut rows);
    rows
}

/// Step overshoot after the tune against the loop delay and the true L.
fn step_rows(motor: MotorParams, rows: &mut Vec<Figure>) {
    use Calibration::Tuned;
    use Design::Baseline;
    let name = motor.name;
    for delay in DELAYS {
        let o: Vec<f64> = L_SCALES
            .iter()
            .map(|&l| step_overshoot(motor, &Conditions::delayed(delay, l), Tuned))
            .collect();
        let before = step_overshoot_of(motor, &Conditions::delayed(delay, 0.7), Baseline);
        let worst = o.iter().copied().fold(0.0, f64::max);
        rows.push(figure(
            format!(
                "{name}: 0.5 A step overshoot after the tune, delay {delay} samples, \
                 true L = 0.7 / 1.0 / 1.3 × the motor data"
            ),
            "≤ 5 %",
            format!("{} % (before, L 0.7: {before:.0} %)", joined(o, 1)),
            worst <= 5.0,
        ));
    }
}

/// The tuned L against the true L over the loop delays.
fn tuned_l_rows(motor: MotorParams, rows: &mut Vec<Figure>) {
    let name = motor.name;
    let mut worst_l = 0.0f64;
    let mut at_one = Vec::new();
    let mut delays = Vec::new();
    for delay in L_DELAYS {
        for l in L_SCALES {
            let (e, d) = tuned_l_error(motor, &Conditions::delayed(delay, l));
            worst_l = worst_l.max(e.abs());
            if l == 1.0 {
                at_one.push(e);
                delays.push(d);
            }
        }
    }
    rows.push(figure(
        format!(
            "{name}: tuned L against the true L, delay 0.5 / 0.75 / 1.0 / 1.25 / 1.5 \
             samples (measured delay)"
        ),
        "±10 %",
        format!(
            "{} % ({}), worst {worst_l:.1} % over L 0.7-1.3",
            joined(at_one, 1),
            joined(delays, 2)
        ),
        worst_l <= 10.0,
    ));
}

/// i_q ripple on the encoder after the tune: fixed speeds, the sweep, i_d beside i_q.
fn ripple_rows(motor: MotorParams, rows: &mut Vec<Figure>) {
    use Calibration::Tuned;
    use Design::{Baseline, Robust};
    let name = motor.name;
    let ideal = Conditions::IDEAL;
    for v in [1.0, 5.07, 10.13] {
        let r = 1e3 * iq_ripple(motor, &ideal, Tuned, v);
        let before = 1e3 * ripple_of(motor, &ideal, Baseline, v);
        rows.push(figure(
            format!("{name}: i_q ripple p-p on the encoder after the tune, {v} rev/s"),
            "≤ 10 mA",
            format!("{r:.1} mA (before {before:.0} mA)"),
            r <= 10.0,
        ));
    }
    let (v_worst, r_worst) = ripple_sweep(motor, &ideal, Robust(Tuned))
        .into_iter()
        .fold((0.0, 0.0), |w, p| if p.1 > w.1 { p } else { w });
    rows.push(figure(
        format!(
            "{name}: worst i_q ripple p-p on the encoder after the tune, 0.013-10.013 rev/s \
             in 0.25 steps"
        ),
        "≤ 10 mA",
        format!("{r_worst:.1} mA at {v_worst} rev/s"),
        r_worst <= 10.0,
    ));
    let beat = spin(motor, &ideal, Robust(Tuned), 10.013);
    rows.push(figure(
        format!("{name}: i_d / i_q ripple p-p on the encoder after the tune, 10.013 rev/s"),
        "— (i_d makes no torque: `foc::current_loop`, \"Decoupling\")",
        format!("{:.0} mA / {:.1} mA", 1e3 * beat.id_pp, 1e3 * beat.iq_pp),
        true,
    ));
}

/// Sensor gains and offsets, and dead time: ripple and steady error, tuned.
fn sensor_rows(motor: MotorParams, rows: &mut Vec<Figure>) {
    use Calibration::{Off, Tuned};
    use Design::Robust;
    let name = motor.name;
    let ideal = Conditions::IDEAL;
    let sensors = spin(motor, &SENSORS, Robust(Tuned), 5.0);
    let before = spin(motor, &SENSORS, Robust(Off), 5.0);
    rows.push(figure(
        format!("{name}: i_q ripple p-p, sensor gains ±3 %, offsets ±20 mA, 5 rev/s, tuned"),
        "≤ 10 mA",
        format!(
            "{:.1} mA (uncalibrated {:.0} mA)",
            1e3 * sensors.iq_pp,
            1e3 * before.iq_pp
        ),
        sensors.iq_pp <= 0.010,
    ));
    rows.push(figure(
        format!("{name}: steady i_q error, sensor gains ±3 %, offsets ±20 mA, 5 rev/s, tuned"),
        "≤ 1 %",
        format!(
            "{:+.2} % (uncalibrated {:+.1} %, B scaled to A only {:+.1} %)",
            sensors.iq_error_pct(),
            before.iq_error_pct(),
            b_to_a_error(motor)
        ),
        sensors.iq_error_pct().abs() <= 1.0,
    ));
    let c = Conditions {
        dead_time_v: 0.5,
        ..Conditions::IDEAL
    };
    // The base: the loop on the true motor constants without dead time.
    let base = 1e3 * iq_ripple(motor, &ideal, Off, 5.0);
    let r = 1e3 * iq_ripple(motor, &c, Tuned, 5.0) - base;
    let before = 1e3 * iq_ripple(motor, &c, Off, 5.0) - base;
    rows.push(figure(
        format!("{name}: i_q ripple added by 0.5 V of dead time, 5 rev/s, tuned"),
        "≤ 3 mA",
        format!("{r:.1} mA (uncompensated {before:.0} mA)"),
        r <= 3.0,
    ));
}

/// Every imperfection at once: step, ripple, steady error, tuned L; the torque ripple.
fn combined_rows(motor: MotorParams, rows: &mut Vec<Figure>) {
    use Calibration::Tuned;
    use Design::{Baseline, Robust};
    let name = motor.name;
    let all = Conditions::ALL;
    let o = step_overshoot(motor, &all, Tuned);
    let o_before = step_overshoot_of(motor, &all, Baseline);
    let s = spin(motor, &all, Robust(Tuned), 5.07);
    let before = 1e3 * ripple_of(motor, &all, Baseline, 5.07);
    let (l_err, _) = tuned_l_error(motor, &all);
    rows.push(figure(
        format!(
            "{name}: all combined (L −30 % and L(i), delay 1.5, gains, offsets, dead time, \
             encoder), tuned: step overshoot / i_q ripple p-p at 5.07 rev/s / steady i_q \
             error / tuned L"
        ),
        COMBINED_GOAL,
        format!(
            "{o:.1} % / {:.1} mA / {:+.2} % / {l_err:+.1} % (before {o_before:.0} % / \
             {before:.0} mA)",
            1e3 * s.iq_pp,
            s.iq_error_pct()
        ),
        combined_met(o, s, l_err),
    ));
    let t = torque_ripple(motor, &all, Tuned, 5.0);
    rows.push(figure(
        format!("{name}: torque ripple Kt·i_q p-p, 5 rev/s, encoder commutation, all combined"),
        "—",
        format!(
            "{:.1} mN·m ({:.2} % of the holding torque; the detent adds {:.0} mN·m p-p)",
            t * 1e3,
            t / motor.t_hold * 100.0,
            2e3 * motor.td
        ),
        true,
    ));
}

/// The goal of the combined row: overshoot / ripple / steady error / tuned L against
/// the true incremental L at the test current.
pub const COMBINED_GOAL: &str = "≤ 5 % / ≤ 10 mA / ≤ 1 % / ±10 %";

/// Whether the combined case meets [`COMBINED_GOAL`].
pub fn combined_met(overshoot: f64, s: Spin, l_err: f64) -> bool {
    overshoot <= 5.0 && s.iq_pp <= 0.010 && s.iq_error_pct().abs() <= 1.0 && l_err.abs() <= 10.0
}

/// Steady i_q error (%) under [`SENSORS`] at 5 rev/s with the tune's calibration but
/// only channel B scaled to channel A (the calibration before both channels were
/// referred to their mean): the "before" figure of the steady-error row.
pub fn b_to_a_error(motor: MotorParams) -> f64 {
    let mut cfg = SENSORS.plant(motor);
    cfg.adc_noise_lsb = 0.0;
    let mut rig = rig(motor, &SENSORS, cfg, Calibration::Tuned);
    let t = tune(motor, &SENSORS);
    rig.cl.set_channel_gains(1.0, t.gain_b);
    spin_rig(rig, Design::Robust(Calibration::Tuned), 5.0).iq_error_pct()
}
