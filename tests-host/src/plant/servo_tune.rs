//! Servo auto-tuning on the plant: the identification move of [`foc::identify`] in
//! closed loop on a motor carrying an extra load inertia, then the servo figures with
//! the gains set for the identified inertia.
//!
//! Per load (1×, 5×, 20× the rotor inertia added to the motor's): the move strokes
//! 90° (1000 counts) back and forth with the rotor-only gains of
//! [`foc::identify::move_gains`]; the identified total inertia gives the load ratio
//! `J/J_rotor − 1`. The servo is then tuned by [`ServoGains::from_bandwidth`] on
//! `J_rotor·(1 + ratio)` at [`SERVO_BW_HZ`], as `MotionConfig::from_params` does with
//! 0x2160, and runs the 90° move (ECN57-20) and the 600 rpm CSP profile (TC86-45) of
//! [`super::scenarios`]. The 90° move's acceleration is the scenario's 500 rev/s²
//! where the motor's torque allows it, else the acceleration that half the peak
//! torque gives to the identified inertia (a heavier load cannot follow that profile
//! at all).

use super::motor::{MotorParams, PlantConfig, ECN57_20, TC86_45};
use super::rig::{Rig, TS_SERVO};
use super::scenarios::{csp_tracking_on, move_90_on, Figure, Move, Tracking, SERVO_BW_HZ};
use crate::sim_drive::Motor;
use foc::identify::{move_gains, IdentConfig, IdentMove, IdentState, Identified};
use foc::servo::{Demand, Servo, ServoGains};
use std::f64::consts::{PI, SQRT_2};

/// Loads of the figures, multiples of the rotor inertia.
pub const LOADS: [f64; 3] = [1.0, 5.0, 20.0];

/// Acceleration of the probe cycle, rev/s².
pub const PROBE_ACCEL: f32 = 50.0;

/// One identification run.
#[derive(Clone, Debug)]
pub struct Identification {
    /// Load added, multiple of the rotor inertia.
    pub load: f64,
    /// The fit's result (`None`: the move failed).
    pub result: Option<Identified>,
    /// Identified load ratio, % of the rotor inertia.
    pub ratio_percent: f64,
    /// Error of the identified load inertia against the true one, %.
    pub error_percent: f64,
    /// Largest excursion of the actual position outside the commanded travel, counts.
    pub overtravel_counts: f64,
    /// Acceleration of the fitted cycles, rev/s².
    pub accel_rev_s2: f64,
}

/// Plant configuration of `motor` with `load` × its rotor inertia added.
pub fn loaded(motor: MotorParams, load: f64) -> PlantConfig {
    let mut m = motor;
    m.j *= 1.0 + load;
    PlantConfig::new(m)
}

fn base_gains(motor: &MotorParams, cpr: u32, ratio_percent: f64) -> ServoGains {
    ServoGains::from_bandwidth(
        (motor.j * (1.0 + ratio_percent * 0.01)) as f32,
        motor.kt as f32,
        cpr,
        SERVO_BW_HZ,
        (motor.i_rated * SQRT_2) as f32,
    )
}

/// Runs the identification move on `motor` carrying `load` × its rotor inertia.
pub fn identify(motor: MotorParams, load: f64) -> Identification {
    let mut rig = Rig::new(loaded(motor, load));
    let cpr = rig.enc.cpr();
    let rotor = base_gains(&motor, cpr, 0.0);
    let mut servo = Servo::new(move_gains(&rotor), TS_SERVO, 100_000);
    let start = rig.enc.position();
    let hold = Demand {
        pos: start,
        ..Demand::default()
    };
    for _ in 0..100 {
        rig.servo_period(&mut servo, &hold);
    }
    let travel = cpr as f32 / 4.0;
    let rev = cpr as f32;
    let mut m = IdentMove::new(
        IdentConfig {
            ts: TS_SERVO,
            kt: motor.kt as f32,
            cpr,
            travel,
            accel: PROBE_ACCEL * rev,
            accel_max: 1000.0 * rev,
            speed_max: 10.0 * rev,
            iq_target: rotor.iq_max * 0.4,
            iq_max: rotor.iq_max,
            cycles: 3,
        },
        start,
    );
    let mut over = 0.0f64;
    let mut accel = 0.0f64;
    while m.state == IdentState::Running {
        let d = m.step(servo.iq_ref, rig.enc.velocity());
        accel = m.accel() as f64 / cpr as f64;
        rig.servo_period(&mut servo, &d);
        let x = (rig.enc.position() - start) as f64;
        over = over.max(-x).max(x - travel as f64);
    }
    let result = match m.state {
        IdentState::Done(r) => Some(r),
        _ => None,
    };
    let ratio = result.map_or(f64::NAN, |r| r.load_ratio_percent(motor.j as f32) as f64);
    Identification {
        load,
        result,
        ratio_percent: ratio,
        error_percent: (ratio / (load * 100.0) - 1.0) * 100.0,
        overtravel_counts: over,
        accel_rev_s2: accel,
    }
}

/// The servo of `rig` tuned for the load ratio `ratio_percent`.
fn tuned_servo(rig: &Rig, motor: &MotorParams, ratio_percent: f64) -> Servo {
    let g = base_gains(motor, rig.enc.cpr(), ratio_percent);
    Servo::new(g, TS_SERVO, 1000)
}

/// 90° move on the ECN57-20 with `load`, tuned for `ratio_percent`; returns the move
/// and the acceleration used (rev/s²).
pub fn move_90_tuned(load: f64, ratio_percent: f64) -> (Move, f64) {
    let rig = Rig::new(loaded(ECN57_20, load));
    let servo = tuned_servo(&rig, &ECN57_20, ratio_percent);
    let t_max = ECN57_20.kt * ECN57_20.i_rated * SQRT_2;
    let j = ECN57_20.j * (1.0 + ratio_percent * 0.01);
    let acc = (0.5 * t_max / j / (2.0 * PI)).min(500.0);
    (move_90_on(rig, servo, acc), acc)
}

/// 600 rpm CSP profile on the TC86-45 with `load`, tuned for `ratio_percent`.
pub fn csp_tuned(load: f64, ratio_percent: f64) -> Tracking {
    let rig = Rig::new(loaded(TC86_45, load));
    let servo = tuned_servo(&rig, &TC86_45, ratio_percent);
    csp_tracking_on(rig, servo, 0.25)
}

/// Phase voltage (V) the CSP profile's acceleration needs on the TC86-45 with `load`
/// at its top speed (600 rpm), and the torque (N·m): `|R·i + Ke·ω + j·L·ωe·i|` with
/// `i = J·α/Kt`.
pub fn csp_voltage(load: f64) -> (f64, f64) {
    let m = TC86_45;
    let torque = m.j * (1.0 + load) * 200.0 * 2.0 * PI;
    let i = torque / m.kt;
    let w = 10.0 * 2.0 * PI;
    let v = (m.r * i + m.kt * w).hypot(m.l * 50.0 * w * i);
    (v, torque)
}

fn row(rows: &mut Vec<Figure>, name: String, goal: &str, achieved: String, met: bool) {
    rows.push(Figure {
        name,
        goal: goal.into(),
        achieved,
        met,
    });
}

fn ident_row(rows: &mut Vec<Figure>, motor: &str, id: &Identification) {
    row(
        rows,
        format!("{motor}, load {}× rotor: identified load inertia", id.load),
        "±10 %",
        format!(
            "{:.0} % of rotor ({:+.1} %; {:.0} rev/s², {:.0} counts past travel)",
            id.ratio_percent, id.error_percent, id.accel_rev_s2, id.overtravel_counts
        ),
        id.error_percent.abs() <= 10.0,
    );
}

/// The tune as the drive runs it ([`super::drive_tune`]).
fn drive_row(rows: &mut Vec<Figure>, motor: Motor, load: f64) {
    let t = super::drive_tune::tune_on_drive(motor, load);
    let name = match motor {
        Motor::Ecn57_20 => "ECN57-20",
        Motor::Tc86_45 => "TC86-45",
    };
    row(
        rows,
        format!("{name}, load {load}× rotor: tune on the drive (0x2162), 0x2164"),
        "±10 %",
        format!(
            "{} % ({:+.1} %) in {} ms; standstill p-p {:.0} → {:.0} counts",
            t.ratio_percent,
            t.error_percent,
            t.duration_ms,
            t.standstill_before,
            t.standstill_after
        ),
        t.state == 2 && t.error_percent.abs() <= 10.0,
    );
}

/// The figures on every load of [`LOADS`].
pub fn report() -> Vec<Figure> {
    let mut rows = Vec::new();
    for load in LOADS {
        let a = identify(ECN57_20, load);
        ident_row(&mut rows, "ECN57-20", &a);
        let (m, acc) = move_90_tuned(load, a.ratio_percent);
        row(
            &mut rows,
            format!("ECN57-20, load {load}× tuned: 90° move settle to ±2 counts"),
            "≤ 20 ms",
            format!("{:.1} ms ({acc:.0} rev/s²)", m.settle_ms),
            m.settle_ms <= 20.0,
        );
        row(
            &mut rows,
            format!("ECN57-20, load {load}× tuned: 90° move overshoot"),
            "≤ 2 counts",
            format!("{:.0} counts", m.overshoot_counts),
            m.overshoot_counts <= 2.0,
        );
        drive_row(&mut rows, Motor::Ecn57_20, load);
        let b = identify(TC86_45, load);
        ident_row(&mut rows, "TC86-45", &b);
        drive_row(&mut rows, Motor::Tc86_45, load);
        let t = csp_tuned(load, b.ratio_percent);
        let why = if t.fe_accel > 20.0 || t.fe_const > 5.0 {
            let (v, torque) = csp_voltage(load);
            format!(
                " (the ramps need {torque:.1} N·m at up to 600 rpm: {v:.0} V, beyond the \
                 48 V bus; the current cannot follow)"
            )
        } else {
            String::new()
        };
        row(
            &mut rows,
            format!("TC86-45, load {load}× tuned: CSP 600 rpm FE during acceleration"),
            "≤ 20 counts",
            format!("{:.1} counts{why}", t.fe_accel),
            t.fe_accel <= 20.0,
        );
        row(
            &mut rows,
            format!("TC86-45, load {load}× tuned: CSP 600 rpm FE at constant speed"),
            "≤ 5 counts",
            format!("{:.1} counts{why}", t.fe_const),
            t.fe_const <= 5.0,
        );
    }
    rows
}
