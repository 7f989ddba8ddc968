//! The scenarios as the rows of the control-quality report: each figure with its goal.

use super::*;
/// All scenarios as report rows.
pub fn report() -> Vec<Figure> {
    let mut rows = Vec::new();
    current_loop_rows(&mut rows);
    servo_rows(&mut rows);
    autotune_rows(&mut rows);
    open_loop_rows(&mut rows);
    rows
}

/// One report row: `name`, its `goal`, what was `achieved`, whether it `met` the goal.
fn row(rows: &mut Vec<Figure>, name: &str, goal: &str, achieved: String, met: bool) {
    rows.push(Figure {
        name: name.into(),
        goal: goal.into(),
        achieved,
        met,
    })
}

/// The current loop's step response and bandwidth.
fn current_loop_rows(rows: &mut Vec<Figure>) {
    let s = current_step(ECN57_20, 8);
    row(
        rows,
        "current step 0.5 A: 10-90 % rise",
        "≤ 175 µs",
        format!("{:.0} µs", s.rise_us),
        s.rise_us <= 175.0,
    );
    row(
        rows,
        "current step 0.5 A: overshoot",
        "≤ 5 %",
        format!("{:.1} %", s.overshoot_pct),
        s.overshoot_pct <= 5.0,
    );
    let b = current_bandwidth(ECN57_20);
    row(
        rows,
        "current-loop bandwidth (−3 dB, 40 kHz)",
        "≥ 2 kHz",
        format!("{:.0} Hz", b.f3db_hz),
        b.f3db_hz >= 2000.0,
    );
}

/// The servo loops: load step at standstill, a 90° move, CSP tracking.
fn servo_rows(rows: &mut Vec<Figure>) {
    let l = standstill_load_step(0.5);
    row(
        rows,
        "standstill error before load step",
        "±1 count",
        format!("±{:.0} counts", l.before_counts),
        l.before_counts <= 1.0,
    );
    row(
        rows,
        "0.5 N·m load step: recovery to ±1 count",
        "≤ 20 ms",
        format!("{:.1} ms (peak {:.0} counts)", l.recovery_ms, l.peak_counts),
        l.recovery_ms <= 20.0,
    );
    let m = move_90();
    row(
        rows,
        "90° move: settle to ±2 counts after profile end",
        "≤ 20 ms",
        format!("{:.1} ms", m.settle_ms),
        m.settle_ms <= 20.0,
    );
    row(
        rows,
        "90° move: overshoot",
        "≤ 2 counts",
        format!("{:.0} counts", m.overshoot_counts),
        m.overshoot_counts <= 2.0,
    );
    let t = csp_tracking();
    row(
        rows,
        "CSP 600 rpm TC86-45: FE during acceleration",
        "≤ 20 counts",
        format!("{:.1} counts", t.fe_accel),
        t.fe_accel <= 20.0,
    );
    row(
        rows,
        "CSP 600 rpm TC86-45: FE at constant speed",
        "≤ 5 counts",
        format!("{:.1} counts", t.fe_const),
        t.fe_const <= 5.0,
    );
}

/// The auto-tune on both motors and the open → closed loop switch.
fn autotune_rows(rows: &mut Vec<Figure>) {
    for motor in [ECN57_20, TC86_45] {
        let a = autotune(motor, [1.0, 1.0]);
        let ok = matches!(a.state, TuneState::Done(_));
        row(
            rows,
            &format!("auto-tune {}: R error", a.motor),
            "±5 %",
            format!("{:+.2} %", a.r_err_pct),
            ok && a.r_err_pct.abs() <= 5.0,
        );
        row(
            rows,
            &format!("auto-tune {}: L error", a.motor),
            "±10 %",
            format!("{:+.2} %", a.l_err_pct),
            ok && a.l_err_pct.abs() <= 10.0,
        );
        row(
            rows,
            &format!("auto-tune {}: duration", a.motor),
            "≤ 2 s",
            format!("{:.2} s", a.duration_s),
            ok && a.duration_s <= 2.0,
        );
    }
    let sw = open_to_closed();
    row(
        rows,
        "open → closed switch: position jump",
        "≤ 1 count",
        format!("{:.0} counts", sw.jump_counts),
        sw.jump_counts <= 1.0,
    );
}

/// Open loop at 600 rpm, the holding current and the power-up alignment.
fn open_loop_rows(rows: &mut Vec<Figure>) {
    let load = 0.5 * ECN57_20.t_hold;
    for (name, current) in [
        (
            "open loop 600 rpm, 1 N·m (50 % T_hold), 5 A: lost steps",
            ECN57_20.i_rated,
        ),
        (
            "open loop 600 rpm, 1 N·m, 7.07 A (√2·I_rated; voltage-limited, current derating)",
            SQRT_2 * ECN57_20.i_rated,
        ),
    ] {
        let o = open_loop_600rpm(load, current);
        row(
            rows,
            name,
            "none",
            format!(
                "{}: max lag {:.0}° el., end error {:+.2} full steps",
                if o.lost_nothing() { "none" } else { "LOST" },
                o.max_lag_deg,
                o.final_error_steps
            ),
            o.lost_nothing(),
        );
    }
    let h = holding_current();
    row(
        rows,
        "holding current after stand-by (50 %)",
        "reached after stand-by",
        format!(
            "{:.2} A → {:.2} A, {:.0} ms after stop (stand-by {:.0} ms)",
            h.before, h.after, h.reached_ms, h.standby_ms
        ),
        (h.after / h.running - 0.5).abs() < 0.02 && h.reached_ms >= h.standby_ms,
    );
    let al = alignment(true);
    row(
        rows,
        "power-up alignment (wiggle) offset error",
        "≤ 1 count",
        format!("{:.2} counts in {:.0} ms", al.error_counts, al.duration_ms),
        al.done && al.error_counts.abs() <= 1.0,
    );
}
