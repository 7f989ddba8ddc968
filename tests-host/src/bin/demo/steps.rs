//! The demo's motion steps in Op: self-test and enable, homing, a profile-position
//! move, a CSP S-curve and a fault with its reset; each prints its table.

use super::*;
/// Table 5: the power-up self-test, then the CiA 402 enable sequence; the auto-tune's
/// results. Returns the inputs in Operation enabled.
pub(super) async fn enable_after_self_test(
    op: &Op<'_>,
    problems: &mut Problems,
) -> Result<Tx, ethercrab::error::Error> {
    // The drive stays in Not ready to switch on while it auto-tunes its current loop
    // (0x2013 = 1); like a real master, wait for Switch on disabled first, then step
    // through the states, each until the statusword shows it.
    let mut rows = Vec::new();
    let (mut tx, waited) = op.until_state(0x0000, 0x40, 3000, 0).await?;
    problems.expect(
        tx.status & 0x6F == 0x40,
        "Switch on disabled after the power-up self-test",
    );
    rows.push(vec![
        format!("0x0000 (power-up self-test: {waited} ms)"),
        format!("{:#06x}", tx.status),
        pds_state(tx.status).into(),
    ]);
    for (cw, what, state) in [
        (0x0006u16, "shutdown", 0x21u16),
        (0x0007, "switch on", 0x23),
        (0x000F, "enable operation", 0x27),
    ] {
        let (t, n) = op.until_state(cw, state, 2000, tx.position).await?;
        tx = t;
        problems.expect(tx.status & 0x6F == state, what);
        rows.push(vec![
            format!("{cw:#06x} {what} ({n} cycles)"),
            format!("{:#06x}", tx.status),
            pds_state(tx.status).into(),
        ]);
    }
    table(
        "5. Enable through the CiA 402 power drive system",
        &["controlword", "statusword", "state"],
        &rows,
    );
    let mut tuned = Vec::new();
    for (i, what) in [
        (0x2020u16, "phase resistance (mΩ)"),
        (0x2021, "phase inductance (µH)"),
        (0x2015, "current Kp (0.01 V/A)"),
        (0x2016, "current Ki (10 V/(A·s))"),
    ] {
        let v: u16 = op.group.subdevice(op.md, 0)?.sdo_read(i, 0).await?;
        tuned.push(vec![format!("{i:#06X}:00"), what.into(), v.to_string()]);
    }
    table(
        "   The power-up auto-tune's results (0x2013 = 1), read by SDO",
        &["object", "meaning", "value"],
        &tuned,
    );
    Ok(tx)
}

/// Table 6: homing, method 19; the position and home-switch traces of the plot.
pub(super) async fn home(
    op: &Op<'_>,
    mut tx: Tx,
    problems: &mut Problems,
) -> Result<(Tx, Vec<(f64, f64)>, Vec<(f64, f64)>), ethercrab::error::Error> {
    let hold = tx.position;
    op.sdo_w(0x6098, 0, 19i8).await?;
    op.sdo_w(0x6099, 1, 40_000u32).await?;
    op.sdo_w(0x6099, 2, 4_000u32).await?;
    op.sdo_w(0x609A, 0, 400_000u32).await?;
    op.sdo_w(0x607C, 0, 0i32).await?;
    op.set_mode(6, hold).await?;
    let mut homing = Vec::new();
    let mut homing_switch = Vec::new();
    let start_ms = op.t_ms();
    let mut attained = None;
    for k in 0..6000 {
        tx = op.cycle(0x001F, 0).await?;
        let t = op.t_ms() - start_ms;
        homing.push((t, tx.position as f64 / UNITS_PER_REV));
        // 0x60FD bit 2: home switch, as the drive reports it.
        homing_switch.push((t, if tx.inputs & 0b100 != 0 { 0.5 } else { 0.0 }));
        if tx.status & (1 << 13) != 0 {
            break;
        }
        if tx.status & (1 << 12) != 0 && tx.status & (1 << 10) != 0 && k > 5 {
            attained = Some(t);
            break;
        }
    }
    tx = op.cycle(0x000F, 0).await?;
    problems.expect(attained.is_some(), "homing attained");
    table(
        "6. Homing, method 19 (home switch, positive side) on the simulated axis",
        &["0x6061", "result", "time", "position (units)", "statusword"],
        &[vec![
            tx.mode.to_string(),
            match attained {
                Some(_) => "homing attained".into(),
                None => "did not finish".into(),
            },
            attained.map_or("—".into(), |t| format!("{t:.0} ms")),
            tx.position.to_string(),
            format!("{:#06x}", tx.status),
        ]],
    );
    Ok((tx, homing, homing_switch))
}

/// Table 7: a profile-position move with the set-point handshake.
pub(super) async fn profile_position(
    op: &Op<'_>,
    mut tx: Tx,
    problems: &mut Problems,
) -> Result<Tx, ethercrab::error::Error> {
    tx = op.set_mode(1, tx.position).await?;
    let pp_start = tx.position;
    op.sdo_w(0x6081, 0, 100_000u32).await?;
    op.sdo_w(0x6083, 0, 500_000u32).await?;
    op.sdo_w(0x6084, 0, 500_000u32).await?;
    let target = pp_start + 100_000;
    let t_start = op.t_ms();
    let mut ack_at = None;
    let mut reached_at = None;
    for _ in 0..4000 {
        let cw = if ack_at.is_none() { 0x001F } else { 0x000F };
        tx = op.cycle(cw, target).await?;
        if ack_at.is_none() && tx.status & (1 << 12) != 0 {
            ack_at = Some(op.t_ms() - t_start);
        }
        if ack_at.is_some() && tx.status & (1 << 10) != 0 {
            reached_at = Some(op.t_ms() - t_start);
            break;
        }
    }
    problems.expect(reached_at.is_some(), "PP target reached");
    table(
        "7. Profile position move: 2 revolutions at 2 rev/s, 10 rev/s² (PP, set-point handshake)",
        &[
            "0x6061",
            "target",
            "set-point acknowledged",
            "target reached",
            "final position",
            "error (counts)",
        ],
        &[vec![
            tx.mode.to_string(),
            target.to_string(),
            ack_at.map_or("no".into(), |t| format!("after {t:.0} ms")),
            reached_at.map_or("no".into(), |t| format!("after {t:.0} ms")),
            tx.position.to_string(),
            format!(
                "{:.1}",
                (tx.position - target) as f64 / UNITS_PER_REV * COUNTS_PER_REV
            ),
        ]],
    );
    Ok(tx)
}

/// The CSP run's traces (cycle number, counts or revolutions).
pub(super) struct CspTraces {
    pub(super) error: Vec<(f64, f64)>,
    pub(super) following: Vec<(f64, f64)>,
    pub(super) target: Vec<(f64, f64)>,
}

/// Table 8: a CSP S-curve at 1 ms cycle with its tracking error.
pub(super) async fn csp_s_curve(
    op: &Op<'_>,
    mut tx: Tx,
    problems: &mut Problems,
) -> Result<(Tx, CspTraces), ethercrab::error::Error> {
    tx = op.set_mode(8, tx.position).await?;
    let p0 = tx.position as f64;
    // Backwards: the simulated positive limit switch sits at +4 revolutions.
    let dist = -5.0 * UNITS_PER_REV;
    let t_move = 1.5;
    let cycles = (t_move * 1000.0) as usize + 300;
    let (mut csp_error, mut csp_target) = (Vec::new(), Vec::new());
    let mut csp_following = Vec::new();
    let mut prev_target = p0 as i32;
    let mut max_err: f64 = 0.0;
    let mut max_following: f64 = 0.0;
    for k in 0..cycles {
        let t = (k as f64 / 1000.0).min(t_move);
        let s = t / t_move;
        let p =
            p0 + dist * (s - (2.0 * std::f64::consts::PI * s).sin() / (2.0 * std::f64::consts::PI));
        let target = p.round() as i32;
        tx = op.cycle(0x000F, target).await?;
        // The drive answers with the position at the cycle's start: compare with the
        // target of the previous cycle.
        let err = (prev_target - tx.position) as f64 / UNITS_PER_REV * COUNTS_PER_REV;
        prev_target = target;
        // The drive's own following error (position demand − actual at its cycle),
        // without the master's one-cycle transport delay.
        let fe = op
            .group
            .subdevice(op.md, 0)?
            .sdo_read::<i32>(0x60F4, 0)
            .await?;
        let fe = fe as f64 / UNITS_PER_REV * COUNTS_PER_REV;
        if k > 2 {
            max_err = max_err.max(err.abs());
            max_following = max_following.max(fe.abs());
            csp_error.push((k as f64, err));
            csp_following.push((k as f64, fe));
            csp_target.push((k as f64, target as f64 / UNITS_PER_REV));
        }
    }
    problems.expect(max_err < 500.0, "CSP tracking error below 500 counts");
    table(
        "8. CSP: 5 revolutions as an S-curve (cycloidal) in 1.5 s, target every 1 ms cycle",
        &[
            "peak speed",
            "max target − actual (master view)",
            "max 0x60F4 (drive)",
            "final position",
            "final error",
        ],
        &[vec![
            format!("{:.0} rpm", 2.0 * 5.0 / t_move * 60.0),
            format!("{max_err:.1} counts"),
            format!("{max_following:.1} counts"),
            tx.position.to_string(),
            format!(
                "{:.1} counts",
                (prev_target - tx.position) as f64 / UNITS_PER_REV * COUNTS_PER_REV
            ),
        ]],
    );
    Ok((
        tx,
        CspTraces {
            error: csp_error,
            following: csp_following,
            target: csp_target,
        },
    ))
}

/// Table 9: a following-error fault, its reset and a new enable.
pub(super) async fn fault_and_reset(
    op: &Op<'_>,
    mut tx: Tx,
    problems: &mut Problems,
) -> Result<(), ethercrab::error::Error> {
    op.sdo_w(0x6065, 0, 500u32).await?;
    op.sdo_w(0x6066, 0, 5u16).await?;
    let jump = tx.position + 50_000;
    let mut rows = Vec::new();
    // The demand follows the jump no faster than 0x6080; the axis lags, the fault
    // reaction ramps down from the actual speed, then the drive is in Fault.
    for _ in 0..2000 {
        tx = op.cycle(0x000F, jump).await?;
        if tx.status & 0x4F == 0x08 {
            break;
        }
    }
    problems.expect(tx.error == 0x8611, "following-error fault 0x8611");
    rows.push(vec![
        "target jumps by one revolution (following error window 500 units, 5 ms)".into(),
        format!("{:#06x}", tx.status),
        pds_state(tx.status).into(),
        format!("{:#06x}", tx.error),
    ]);
    let hold = tx.position;
    tx = op.cycle(0x0000, hold).await?;
    for _ in 0..3 {
        tx = op.cycle(0x0080, hold).await?;
    }
    rows.push(vec![
        "fault reset (controlword bit 7 rising edge)".into(),
        format!("{:#06x}", tx.status),
        pds_state(tx.status).into(),
        format!("{:#06x}", tx.error),
    ]);
    for (cw, state) in [(0x0006u16, 0x21u16), (0x0007, 0x23), (0x000F, 0x27)] {
        tx = op.until_state(cw, state, 2000, tx.position).await?.0;
    }
    problems.expect(
        tx.status & 0x6F == 0x27,
        "Operation enabled again after the reset",
    );
    rows.push(vec![
        "enable again".into(),
        format!("{:#06x}", tx.status),
        pds_state(tx.status).into(),
        format!("{:#06x}", tx.error),
    ]);
    op.sdo_w(0x6065, 0, 50_000u32).await?;
    table(
        "9. A fault and its reset",
        &["event", "statusword", "state", "0x603F"],
        &rows,
    );
    Ok(())
}
