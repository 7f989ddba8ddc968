//! The servo tune's identification move in the motion layer ([`crate::servo_tune`]).
//!
//! The drive hands the move over with [`crate::cia402::SetpointKind::Tune`] set-points (CiA 402
//! Operation enabled in PP or CSP, 0x2162 = 1 accepted). On the first of them
//! [`Motion::tune_setpoints`] starts a [`TuneRun`] at the actual position with the
//! move's servo gains ([`crate::servo_tune::move_gains`]: the velocity loop of the
//! rotor alone, a soft position loop) and the current limit in effect. Every closed-loop
//! servo period [`Motion::tune_step`] gives the run the q current of the period just
//! done and the velocity, and servoes on the demand it returns; the interpolation
//! rests on the actual position, so that set-points of another kind start from there.
//! A move that has found the load holds its start position (where it ends) with
//! [`crate::servo_tune::settle_gains`] until the axis stands there, then, reported
//! done, with the configured gains until the set-points change.
//!
//! Set-points of another kind end the tune: a running move is aborted (failed), the
//! normal gains return and the new set-points take over from the actual position
//! (their generator followed it meanwhile, `Cia402::run_mode`). Open loop has no tune
//! (the drive refuses the start); tune set-points there hold the position.

use super::Motion;
use crate::servo_tune::{self, TunePhase, TuneReport, TuneRun};

/// The motion layer's tune: the run in progress or the last one, and its report.
#[derive(Debug, Clone, Copy)]
pub(super) struct Tuning {
    /// Restarted in place for each tune (no copy of it on the interrupt's stack).
    run: TuneRun,
    /// `run` belongs to the present tune set-points.
    active: bool,
    /// What [`Motion::fill_axis_state`] reports.
    pub(super) report: TuneReport,
}

impl Tuning {
    /// No tune yet.
    pub(super) fn new() -> Self {
        let idle = foc::identify::IdentConfig {
            ts: 0.0,
            kt: 0.0,
            cpr: 0,
            travel: 0.0,
            accel: 0.0,
            accel_max: 0.0,
            speed_max: 0.0,
            iq_target: 0.0,
            iq_max: 0.0,
            cycles: 1,
        };
        Tuning {
            run: TuneRun::new(idle, 0, 0.0),
            active: false,
            report: TuneReport::default(),
        }
    }
}

impl Motion {
    /// Tune set-points begin (`on`, the move no faster than `speed_limit` counts/s)
    /// or end (module docs).
    pub(super) fn tune_setpoints(&mut self, on: bool, speed_limit: f32) {
        let runs = self.tune.report.runs;
        if on {
            let start = self.actual_axis_counts(&self.last_fb);
            let c = &self.cfg;
            let mut cfg = servo_tune::ident_config(&c.tune, c.ts, c.counts_per_rev, self.iq_limit);
            if speed_limit.is_finite() && speed_limit > 0.0 {
                cfg.speed_max = cfg.speed_max.min(speed_limit);
            }
            let j_rotor = self.cfg.tune.j_rotor;
            self.tune.run.restart(cfg, start, j_rotor);
            self.tune.active = true;
            // The move's velocity loop is proportional only: its integrator starts
            // empty (what it held would act as a constant torque the fit has no term
            // for).
            self.servo.bumpless_start(0.0);
            self.tune.report = self.tune.run.report(runs.wrapping_add(1));
        } else if self.tune.active {
            self.tune.run.abort();
            self.tune.active = false;
            self.tune.report = self.tune.run.report(runs);
        }
        self.apply_gains();
    }

    /// One closed-loop servo period of the move at the axis position `pos` (counts)
    /// and velocity `vel` (counts/s): the q current (A, axis direction).
    pub(super) fn tune_step(&mut self, pos: i32, vel: f32) -> f32 {
        self.rest_at(pos);
        if !self.tune.active {
            return self.servo.step_velocity(0.0, 0.0, vel);
        }
        let run = &mut self.tune.run;
        let phase = run.phase();
        let d = run.step(self.servo.iq_ref, vel, pos);
        self.tune.report = run.report(self.tune.report.runs);
        if run.phase() != phase {
            self.apply_gains();
        }
        self.demand = (d.pos, d.frac);
        let iq = self.servo.step(&d, pos, vel);
        self.following_error = self.servo.following_error;
        iq
    }

    /// The servo gains in effect, limited to the current limit in effect: the
    /// configured ones; while a tune's move runs in closed loop the move's; while it
    /// settles the configured ones for the load it found
    /// ([`crate::servo_tune::TunePhase`]).
    pub(super) fn apply_gains(&mut self) {
        let phase = if self.tune.active && self.cfg.closed_loop {
            self.tune.run.phase()
        } else {
            TunePhase::Ended
        };
        let mut g = match phase {
            TunePhase::Moving => servo_tune::move_gains(&self.cfg.gains, &self.cfg.tune),
            TunePhase::Settling(ratio) => {
                servo_tune::settle_gains(&self.cfg.gains, &self.cfg.tune, ratio)
            }
            TunePhase::Ended => self.cfg.gains,
        };
        g.iq_max = self.iq_limit;
        self.servo.set_gains(g);
    }
}
