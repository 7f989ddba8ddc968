//! The motion layer: what the board's servo interrupt runs at 10 kHz between the
//! CiA 402 cycle ([`DriveCommand`], once per EtherCAT cycle) and the FOC current loop
//! (40 kHz, `foc::current_loop`).
//!
//! ```text
//!  DriveCommand (cycle) ─▶ set_command ─▶ interpolation (command units → counts)
//!                                              │ every servo period
//!  encoder (counts, PLL velocity) ─▶ step ─────┤ closed loop: foc::servo (i_d = 0, i_q)
//!                                              │ open loop:  foc::open_loop (angle, |i|)
//!                                              ▼
//!                                   CurrentReference ─▶ current loop
//!  AxisState fields (position/velocity in command units, following error in counts,
//!  current limited) ◀─ fill_axis_state
//! ```
//!
//! # Units and conventions
//! * Command units: 0x2001 pulses per revolution (`U`); encoder counts: 0x2029 × 4
//!   per revolution (`C`). A command position `p` is the count position `p·C/U`
//!   (exact: integer part by 64-bit division once per cycle, fraction as `f32`). A
//!   count position `n` is reported as `round(n·U/C)` command units, so a reported
//!   position converted back lies within ½ unit of the count (`p → n` never moves by a
//!   count at enable).
//! * Direction (0x2051 = 1): the *axis* runs opposite to the motor. All loops work in
//!   axis counts (`dir · motor counts`); the q current is multiplied by `dir`, the
//!   open-loop command by `dir`.
//! * Interpolation: the position set-point of a cycle is reached at the end of the
//!   next cycle (linear, `n = cycle/ts` servo steps; one cycle of delay, as CSP
//!   expects), the slope is the velocity feed-forward; the acceleration feed-forward is
//!   the command's acceleration through a first-order filter per cycle (weight ¼).
//!   Without a new set-point the demand rests at the last one.
//!
//! # Gains (0x2137-0x2140 → [`ServoGains`])
//! Base gains are [`ServoGains::from_bandwidth`] for the motor's inertia times
//! `1 + 0x2160/100` (load inertia ratio, [`crate::servo_tune`]) and torque constant
//! ([`MotorConstants`]) at [`BASE_BANDWIDTH_HZ`](crate::servo_tune::BASE_BANDWIDTH_HZ)
//! and the peak current 0x2000; the parameters apply [`ServoGains::scaled`]: 0x2137
//! scales the position gain (100 % = ¼ of the base velocity bandwidth), 0x2138 the
//! position integral (`Kp_base²/10 · x/100`), 0x2139 is the velocity feed-forward in
//! %, 0x2140 scales the velocity loop (its bandwidth is `BASE_BANDWIDTH_HZ · x/100`).
//! With the defaults (120 / 50 / 70 / 60) the velocity bandwidth is 240 Hz and the
//! position gain half of it (ζ ≈ 0.5). 0x2140 = 0 is taken as 1 (the velocity loop
//! cannot be switched off).
//!
//! # Enable, disable, switching
//! * Disabled (`drive_enabled` false): zero current, bridges off; the demand tracks the
//!   actual position.
//! * Enable: integrators cleared, the demand starts at the actual position (no jump);
//!   the closed loop's current limit and the open loop's current ramp up over the soft
//!   start 0x2058 (× 50 µs).
//! * Open → closed ([`Motion::configure`] with another loop mode while enabled): the
//!   open-loop current vector is expressed in the encoder frame
//!   ([`foc::servo::handover_currents`]), the servo's velocity integrator is preset to
//!   its q part and the d part ramps to 0 in [`D_RAMP_S`]: the current vector does not
//!   jump. The demand starts at the actual position.
//! * Closed → open: the open loop starts on the rotor's electrical angle (encoder) at
//!   the actual position, so the rotor is held where it is (soft start from zero).
//!
//! Following error: reported in encoder counts (demand − actual); the drive's fault
//! module compares it with 0x2030 (the servo's own latch is not used). With velocity
//! set-points (PV, CSV) it is the following error of the position that the velocity
//! demand describes, ∫(v_demand − v_actual) dt from the enable: bounded while the
//! velocity loop follows (its integrator brings the speed error's integral back),
//! growing without bound when the shaft cannot follow — a blocked axis, a speed beyond
//! what the bus allows, or an encoder whose signals are lost (the counter stops, the
//! velocity loop drives the current to its limit on a frozen commutation angle and the
//! rotor stalls). So the 0x2030 fault (7 flashes, 0x8611) covers every closed-loop mode.
//!
//! Nothing here panics on any parameter value: ratios are guarded, divisions are by
//! values ≥ 1, non-finite inputs fall back to zero.
//!
//! Submodules: `config` (motor constants, [`MotionConfig`] from the parameters),
//! `signals` (the current loop's feedback and reference), `scale` (command units ↔
//! counts), `interp` (set-point interpolation), `stall` (open-loop stall detection),
//! `torque` (CST and the measured torque), `tune` (the servo tune's move).
//!
//! [`ServoGains`]: foc::servo::ServoGains
//! [`ServoGains::from_bandwidth`]: foc::servo::ServoGains::from_bandwidth
//! [`ServoGains::scaled`]: foc::servo::ServoGains::scaled

use crate::cia402::{DriveCommand, SetpointKind};
use foc::angle::{Angle, CountScale, POLE_PAIRS};
use foc::open_loop::OpenLoop;
use foc::servo::{handover_currents, Demand, Servo};
use interp::Interp;
use stall::Stall;

mod config;
mod interp;
mod scale;
mod signals;
mod stall;

pub use config::{MotionConfig, MotorConstants, ECN57_20, TC86_45};
#[cfg(test)]
use scale::floor_div_i32;
pub(crate) use scale::floor_div_i64;
use scale::Scale;
pub use signals::{AxisState, CurrentReference, Feedback, Frame};

/// Time in which the d current left over from an open → closed handover ramps to 0, s.
pub const D_RAMP_S: f32 = 0.01;
/// Servo period of the board, s (10 kHz).
pub const SERVO_TS: f32 = 1e-4;
/// Time constant of the first-order filter on the reported velocity (0x606C), s: the
/// encoder PLL's estimate carries the count quantisation (±5 % at 2 rev/s with 4000
/// counts/rev); the loops use the unfiltered estimate.
pub const VELOCITY_REPORT_TAU: f32 = 0.005;
/// Bound of the velocity set-points' following error, counts: well beyond the largest
/// 0x2030 (60 000), small enough that the sum keeps its resolution in an `f32`.
pub const LAG_LIMIT: f32 = 1.0e6;

fn finite_pos(x: f32) -> f32 {
    if x.is_finite() && x > 0.0 {
        x
    } else {
        0.0
    }
}

fn clampf(x: f32, lo: f32, hi: f32) -> f32 {
    let y = if x < lo { lo } else { x };
    if y > hi {
        hi
    } else {
        y
    }
}

/// The motion layer's state (see the module docs).
// In declaration order, the two smoothing windows (inside `open` and `smooth`, 1 KiB
// each) last: the per-step fields stay within the short load/store offsets of Thumb-2
// and the FPU (VLDR reaches 1020 bytes), which the CSP cycle's instruction count shows.
#[repr(C)]
pub struct Motion {
    cfg: MotionConfig,
    scale: Scale,
    dir: i32,
    servo: Servo,
    elec: CountScale,
    open_offset: Angle,
    interp: Interp,
    // Latest command.
    cmd: DriveCommand,
    cycle_steps: u32,
    acc_ff: f32,
    smooth_prev: i32,
    soft_k: f32,
    soft_step: f32,
    iq_limit: f32,
    iq_limit_set: f32,
    /// q current of one per mille of the rated torque (0x2000 / 1000), A.
    iq_per_permille: f32,
    id_handover: f32,
    id_ramp: f32,
    // Last values for the report.
    last_fb: Feedback,
    last_ref: CurrentReference,
    demand: (i32, f32),
    following_error: f32,
    /// Velocity set-points: ∫(demand − actual velocity) dt since the drive was enabled
    /// or left the position set-points, counts (the following error of the position
    /// the velocity demand describes).
    velocity_lag: f32,
    open_pos_units: i32,
    open_vel_units: f32,
    vel_report: f32,
    vel_k: f32,
    smooth_on: bool,
    enabled: bool,
    reset_pending: bool,
    current_limited: bool,
    stall: Stall,
    tune: tune::Tuning,
    open: OpenLoop,
    // Closed-loop command smoothing (moving average in command units), in use when
    // `smooth_on`. Always present so that reconfiguring re-initialises it in place.
    smooth: foc::open_loop::MovingAverage,
}

impl Motion {
    /// A disabled motion layer at position 0.
    pub fn new(cfg: MotionConfig) -> Self {
        let mut cfg = cfg;
        cfg.ts = if cfg.ts.is_finite() && cfg.ts > 0.0 {
            cfg.ts
        } else {
            SERVO_TS
        };
        if cfg.counts_per_rev == 0 {
            cfg.closed_loop = false;
        }
        let scale = Scale::new(cfg.pulses_per_rev, cfg.counts_per_rev);
        Motion {
            cfg,
            scale,
            dir: if cfg.reverse { -1 } else { 1 },
            servo: Servo::new(cfg.gains, cfg.ts, cfg.following_error_limit),
            open: OpenLoop::new(cfg.open_loop_config(), 0),
            elec: CountScale::new(cfg.pulses_per_rev.max(1), POLE_PAIRS),
            open_offset: Angle::ZERO,
            interp: Interp::at(0, 0.0),
            cmd: DriveCommand::default(),
            cycle_steps: 10,
            acc_ff: 0.0,
            smooth: foc::open_loop::MovingAverage::new(Self::smooth_taps(&cfg).unwrap_or(1), 0),
            smooth_on: Self::smooth_taps(&cfg).is_some(),
            smooth_prev: 0,
            enabled: false,
            reset_pending: false,
            soft_k: 1.0,
            soft_step: 1.0,
            iq_limit: cfg.gains.iq_max,
            iq_limit_set: cfg.gains.iq_max,
            iq_per_permille: finite_pos(cfg.peak_current) * 1e-3,
            id_handover: 0.0,
            id_ramp: 0.0,
            last_fb: Feedback::default(),
            last_ref: CurrentReference::OFF,
            demand: (0, 0.0),
            following_error: 0.0,
            velocity_lag: 0.0,
            open_pos_units: 0,
            open_vel_units: 0.0,
            vel_report: 0.0,
            vel_k: cfg.ts / (VELOCITY_REPORT_TAU + cfg.ts),
            current_limited: false,
            stall: Stall::new(cfg.stall, cfg.ts),
            tune: tune::Tuning::new(),
        }
    }

    /// Taps of the closed-loop smoothing window; `None` when smoothing is off.
    fn smooth_taps(cfg: &MotionConfig) -> Option<usize> {
        let taps = (cfg.filter_s / cfg.ts + 0.5) as usize;
        (cfg.closed_loop && taps > 1).then_some(taps)
    }

    /// Configuration in use.
    pub fn config(&self) -> &MotionConfig {
        &self.cfg
    }

    /// True while the drive function is enabled (current flows).
    pub fn enabled(&self) -> bool {
        self.enabled
    }

    /// Closed loop in use.
    pub fn closed_loop(&self) -> bool {
        self.cfg.closed_loop
    }

    /// Applies a new configuration (parameter change). Gains, limits and filters change
    /// at once; a change of the loop mode while enabled is the bumpless handover of the
    /// module docs. The command scaling (0x2001, 0x2029) and direction keep their
    /// values until the drive is disabled.
    pub fn configure(&mut self, cfg: MotionConfig) {
        let mut cfg = cfg;
        cfg.ts = self.cfg.ts;
        if self.enabled {
            cfg.pulses_per_rev = self.cfg.pulses_per_rev;
            cfg.counts_per_rev = self.cfg.counts_per_rev;
            cfg.reverse = self.cfg.reverse;
        }
        if cfg.counts_per_rev == 0 {
            cfg.closed_loop = false;
        }
        let was_closed = self.cfg.closed_loop;
        let old = self.cfg;
        self.cfg = cfg;
        self.apply_gains();
        self.servo
            .set_following_error_limit(cfg.following_error_limit);
        if old.stall != cfg.stall {
            self.stall.configure(cfg.stall);
        }
        self.iq_limit_set = cfg.gains.iq_max;
        self.iq_per_permille = finite_pos(cfg.peak_current) * 1e-3;
        if !self.enabled {
            self.scale = Scale::new(cfg.pulses_per_rev, cfg.counts_per_rev);
            self.dir = if cfg.reverse { -1 } else { 1 };
            self.elec = CountScale::new(cfg.pulses_per_rev.max(1), POLE_PAIRS);
        }
        if old.open_loop_config() != cfg.open_loop_config() {
            let pos = self.open_pos_units;
            let enabled_open = self.enabled && !was_closed;
            self.open
                .reconfigure(cfg.open_loop_config(), self.dir * pos);
            self.open.set_angle_offset(self.open_offset);
            if enabled_open {
                self.open.enable(self.dir * pos);
            }
        }
        if old.filter_s != cfg.filter_s || old.closed_loop != cfg.closed_loop {
            let taps = Self::smooth_taps(&cfg);
            self.smooth_on = taps.is_some();
            if let Some(n) = taps {
                self.smooth.reinit(n, 0);
            }
        }
        if self.enabled && was_closed != cfg.closed_loop {
            if cfg.closed_loop {
                self.handover_to_closed();
            } else {
                self.handover_to_open();
            }
        }
    }

    /// The latest set-points of the drive cycle; `cycle_s` is the cycle period (the
    /// interpolation spreads the move over it).
    pub fn set_command(&mut self, cmd: &DriveCommand, cycle_s: f32) {
        let cycle_s = if cycle_s.is_finite() {
            clampf(cycle_s, self.cfg.ts, 0.1)
        } else {
            self.cfg.ts
        };
        let n = (cycle_s / self.cfg.ts + 0.5) as u32;
        self.cycle_steps = n.max(1);
        if self.cmd.kind != cmd.kind {
            self.kind_changes(cmd);
        }
        self.cmd = *cmd;
        if !self.enabled {
            return;
        }
        let c = self.scale.counts_per_unit();
        let a = if cmd.acceleration.is_finite() {
            cmd.acceleration * c
        } else {
            0.0
        };
        self.acc_ff += 0.25 * (a - self.acc_ff);
        // Torque feed-forward of the position and velocity set-points (0x60B2).
        self.servo
            .set_torque_offset(cmd.torque as f32 * self.iq_per_permille);
        if cmd.kind == SetpointKind::Position && self.cfg.closed_loop && !self.smooth_on {
            let (w, f) = self.scale.to_counts(cmd.position);
            self.interp.target(w, f, self.cycle_steps, cycle_s);
        } else {
            // Open loop and smoothing interpolate in command units (whole units).
            self.interp
                .target(cmd.position, 0.0, self.cycle_steps, cycle_s);
        }
    }

    /// The set-points change kind from `self.cmd.kind` to `to` (out of line: rare).
    // Measured (cargo xtask size, LAN9252 image): dropped with the other hot-path
    // attributes the image grew 1184 B; see `Cia402::run_cst`.
    #[inline(never)]
    fn kind_changes(&mut self, cmd: &DriveCommand) {
        let to = cmd.kind;
        if self.cmd.kind == SetpointKind::Torque {
            // Leaving torque set-points: the velocity loop starts from the current
            // applied last (`foc::servo`, "Torque control with a speed limit").
            self.servo.bumpless_start(self.servo.iq_ref);
        }
        if (self.cmd.kind == SetpointKind::Tune) != (to == SetpointKind::Tune) {
            // The move's speed limit: the command's velocity (command units/s).
            let limit = cmd.velocity * self.scale.counts_per_unit();
            self.tune_setpoints(to == SetpointKind::Tune, limit);
        }
    }

    fn actual_axis_counts(&self, fb: &Feedback) -> i32 {
        self.dir.wrapping_mul(fb.position)
    }

    fn enable(&mut self, fb: &Feedback) {
        self.enabled = true;
        self.reset_pending = true;
        self.acc_ff = 0.0;
        self.id_handover = 0.0;
        self.soft_k = 0.0;
        self.stall.reset();
        self.soft_step = if self.cfg.soft_start_s > self.cfg.ts {
            self.cfg.ts / self.cfg.soft_start_s
        } else {
            1.0
        };
        if self.cfg.closed_loop {
            self.start_closed_at_actual(fb, 0.0);
        } else {
            self.start_open(fb);
        }
    }

    fn start_closed_at_actual(&mut self, fb: &Feedback, iq: f32) {
        let n = self.actual_axis_counts(fb);
        self.rest_at(n);
        self.servo.bumpless_start(iq);
        self.servo.clear_fault();
    }

    /// Closed loop: the demand (interpolation, smoothing window) rests at the actual
    /// axis count `n`.
    // Measured (cargo xtask size, LAN9252 image): dropped with the other hot-path
    // attributes the image grew 1184 B (this one kept with the group).
    #[inline(never)]
    fn rest_at(&mut self, n: i32) {
        if self.smooth_on {
            let u = self.scale.to_units(n);
            self.interp = Interp::at(u, 0.0);
            self.smooth.reset(u);
            self.smooth_prev = u;
        } else {
            self.interp = Interp::at(n, 0.0);
        }
        self.demand = (n, 0.0);
    }

    fn start_open(&mut self, fb: &Feedback) {
        let pos = if self.cfg.counts_per_rev > 0 {
            self.scale.to_units(self.actual_axis_counts(fb))
        } else {
            self.open_pos_units
        };
        self.open_pos_units = pos;
        let motor_pos = self.dir.wrapping_mul(pos);
        // Place the command angle of `pos` on the rotor (needs the encoder).
        if self.cfg.counts_per_rev > 0 {
            let n = motor_pos.rem_euclid(self.cfg.pulses_per_rev.max(1) as i32) as u32;
            self.open_offset = fb.electrical_angle.wrapping_sub(self.elec.angle(n));
            self.open.set_angle_offset(self.open_offset);
        }
        self.open.enable(motor_pos);
        self.interp = Interp::at(pos, 0.0);
    }

    fn handover_to_closed(&mut self) {
        let fb = self.last_fb;
        let (angle, current) = match self.last_ref.frame {
            Frame::Command { angle, .. } => (angle, self.last_ref.id),
            Frame::Encoder => (fb.electrical_angle, 0.0),
        };
        let (id, iq) = handover_currents(angle, current, fb.electrical_angle);
        self.start_closed_at_actual(&fb, self.dir as f32 * iq);
        self.id_handover = id;
        self.id_ramp = finite_pos(self.cfg.peak_current) * self.cfg.ts / D_RAMP_S;
        self.soft_k = 1.0;
    }

    fn handover_to_open(&mut self) {
        let fb = self.last_fb;
        self.start_open(&fb);
        self.soft_k = 1.0;
    }

    /// One servo period with the encoder's measurement; returns the current reference
    /// for the current loop until the next call.
    pub fn step(&mut self, fb: &Feedback) -> CurrentReference {
        let fb_ok = Feedback {
            velocity: if fb.velocity.is_finite() {
                fb.velocity
            } else {
                0.0
            },
            ..*fb
        };
        self.last_fb = fb_ok;
        if !self.cmd.drive_enabled {
            return self.hold(&fb_ok);
        }
        if !self.enabled {
            self.enable(&fb_ok);
        }
        if self.soft_k < 1.0 {
            self.soft_k = clampf(self.soft_k + self.soft_step, 0.0, 1.0);
        }
        let r = if self.cfg.closed_loop {
            self.step_closed(&fb_ok)
        } else {
            self.step_open(&fb_ok)
        };
        let r = CurrentReference {
            reset: core::mem::take(&mut self.reset_pending),
            ..r
        };
        self.filter_velocity();
        self.last_ref = r;
        r
    }

    /// One servo period while the current loop is busy with something else (the
    /// power-up auto-tune, [`crate::current_supervisor`]): behaves as disabled — no
    /// current reference, the demand tracks the actual position — whatever the
    /// command says; the next [`Motion::step`] with the drive enabled starts at the
    /// actual position with the soft start, as after an enable.
    pub fn step_held(&mut self, fb: &Feedback) -> CurrentReference {
        let fb_ok = Feedback {
            velocity: if fb.velocity.is_finite() {
                fb.velocity
            } else {
                0.0
            },
            ..*fb
        };
        self.last_fb = fb_ok;
        self.hold(&fb_ok)
    }

    fn hold(&mut self, fb: &Feedback) -> CurrentReference {
        if self.enabled {
            self.enabled = false;
            self.open.disable();
        }
        self.track_disabled(fb);
        self.filter_velocity();
        self.last_ref = CurrentReference::OFF;
        self.last_ref
    }

    fn track_disabled(&mut self, fb: &Feedback) {
        self.current_limited = false;
        self.following_error = 0.0;
        self.velocity_lag = 0.0;
        self.acc_ff = 0.0;
        if self.cfg.counts_per_rev > 0 {
            let n = self.actual_axis_counts(fb);
            self.demand = (n, 0.0);
            self.open_pos_units = self.scale.to_units(n);
        }
        self.open_vel_units = 0.0;
    }

    fn step_closed(&mut self, fb: &Feedback) -> CurrentReference {
        let pos = self.actual_axis_counts(fb);
        let vel = self.dir as f32 * fb.velocity;
        // Current limit: 0x6072 / 0x6073 (per mille of the rated = peak current, never
        // above the peak current), soft start.
        let lim_pm = self.cmd.torque_limit.min(self.cmd.current_limit);
        let lim = self.iq_limit_set
            * f32::from(lim_pm.min(crate::cia402::PEAK_PERMILLE))
            * 1e-3
            * self.soft_k;
        if lim != self.iq_limit {
            self.iq_limit = lim;
            self.apply_gains();
        }
        let iq = match self.cmd.kind {
            SetpointKind::Velocity => {
                let c = self.scale.counts_per_unit();
                let v = if self.cmd.velocity.is_finite() {
                    self.cmd.velocity * c
                } else {
                    0.0
                };
                // Keep the position demand on the actual position: bumpless return.
                self.rest_at(pos);
                self.velocity_lag = clampf(
                    self.velocity_lag + (v - vel) * self.cfg.ts,
                    -LAG_LIMIT,
                    LAG_LIMIT,
                );
                self.following_error = self.velocity_lag;
                self.servo.step_velocity(v, self.acc_ff, vel)
            }
            SetpointKind::Position => {
                let d = self.next_demand();
                self.demand = (d.pos, d.frac);
                let iq = self.servo.step(&d, pos, vel);
                self.velocity_lag = 0.0;
                self.following_error = self.servo.following_error;
                iq
            }
            SetpointKind::Torque => self.torque_step(pos, vel),
            SetpointKind::Tune => self.tune_step(pos, vel),
        };
        self.current_limited = lim <= 0.0 || libm::fabsf(iq) >= lim * 0.999;
        let mut id = 0.0;
        if self.id_handover != 0.0 {
            let s = self.id_ramp;
            self.id_handover = if self.id_handover > s {
                self.id_handover - s
            } else if self.id_handover < -s {
                self.id_handover + s
            } else {
                0.0
            };
            id = self.id_handover;
        }
        CurrentReference {
            power: true,
            reset: false,
            frame: Frame::Encoder,
            id,
            iq: self.dir as f32 * iq,
        }
    }

    fn next_demand(&mut self) -> Demand {
        let (w, f, moving) = self.interp.step();
        let vel_ff = if moving { self.interp.vel } else { 0.0 };
        let acc = if moving { self.acc_ff } else { 0.0 };
        if !self.smooth_on {
            return Demand {
                pos: w,
                frac: f,
                vel: vel_ff,
                acc,
            };
        }
        let u = self.smooth.step(w);
        let du = u.wrapping_sub(self.smooth_prev);
        self.smooth_prev = u;
        let (cw, cf) = self.scale.to_counts(u);
        Demand {
            pos: cw,
            frac: cf,
            vel: du as f32 * self.scale.counts_per_unit() / self.cfg.ts,
            acc: 0.0,
        }
    }

    fn step_open(&mut self, fb: &Feedback) -> CurrentReference {
        let (p, _, _) = self.interp.step();
        let p = self.stall.command(p);
        let motor_cmd = self.dir.wrapping_mul(p);
        self.open.voltage_limited(fb.voltage_limited);
        let o = self.open.step(motor_cmd);
        let pos = self.dir.wrapping_mul(o.position);
        self.open_vel_units = pos.wrapping_sub(self.open_pos_units) as f32 / self.cfg.ts;
        self.open_pos_units = pos;
        let (cw, cf) = self.scale.to_counts(pos);
        self.demand = (cw, cf);
        self.following_error = if self.cfg.counts_per_rev > 0 {
            cw.wrapping_sub(self.actual_axis_counts(fb)) as f32 + cf
        } else {
            0.0
        };
        self.current_limited = false;
        if self.cfg.stall.is_some() {
            self.stall.step(fb, o.omega_e, pos);
        }
        CurrentReference {
            power: true,
            reset: false,
            frame: Frame::Command {
                angle: o.angle,
                omega_e: o.omega_e,
            },
            id: o.current,
            iq: 0.0,
        }
    }

    /// Actual position in command units (encoder; the smoothed command without one).
    pub fn position_units(&self) -> i32 {
        if self.cfg.counts_per_rev > 0 {
            self.scale.to_units(self.actual_axis_counts(&self.last_fb))
        } else {
            self.open_pos_units
        }
    }

    /// Output of the position controller (CiA 402 0x60FA), command units/s: closed
    /// loop, the servo's position-loop velocity command; open loop (the commanded
    /// position is the position), the commanded velocity; 0 while disabled.
    pub fn control_effort(&self) -> f32 {
        if !self.enabled {
            0.0
        } else if self.cfg.closed_loop {
            self.dir as f32 * self.servo.velocity_command * self.scale.units_per_count()
        } else {
            self.open_vel_units
        }
    }

    /// Actual velocity in command units/s.
    pub fn velocity_units(&self) -> f32 {
        self.vel_report
    }

    /// Unfiltered velocity of this step, command units/s.
    fn velocity_now(&self) -> f32 {
        if self.cfg.counts_per_rev > 0 {
            self.dir as f32 * self.last_fb.velocity * self.scale.units_per_count()
        } else {
            self.open_vel_units
        }
    }

    fn filter_velocity(&mut self) {
        let k = self.vel_k;
        let v = self.velocity_now();
        if v.is_finite() {
            self.vel_report += k * (v - self.vel_report);
        }
        if !self.vel_report.is_finite() {
            self.vel_report = 0.0;
        }
    }

    /// Servo demand (axis counts, integer + fraction) of the last step.
    pub fn demand_counts(&self) -> (i32, f32) {
        self.demand
    }

    /// Following error of the last step, counts (demand − actual).
    pub fn following_error(&self) -> f32 {
        self.following_error
    }

    /// The servo is at its current limit.
    pub fn current_limited(&self) -> bool {
        self.current_limited
    }

    /// The last current reference.
    pub fn last_reference(&self) -> &CurrentReference {
        &self.last_ref
    }

    /// Writes what the motion layer knows into the drive's [`AxisState`]: position and
    /// velocity (command units), servo following error (counts, rounded), current
    /// limited, torque current (per mille of the peak current). Currents, angle and bus
    /// voltage are the board's.
    pub fn fill_axis_state(&self, a: &mut AxisState) {
        a.position = self.position_units();
        let v = self.velocity_units();
        a.velocity = if v.is_finite() { v as i32 } else { 0 };
        let fe = libm::roundf(self.following_error);
        a.servo_following_error = if fe.is_finite() { fe as i32 } else { 0 };
        a.current_limited = self.current_limited || self.speed_limited();
        let peak = self.cfg.peak_current;
        let i = match self.last_ref.frame {
            Frame::Encoder => self.dir as f32 * self.last_ref.iq,
            Frame::Command { .. } => 0.0,
        };
        a.current_permille = if peak > 0.0 {
            clampf(i / peak * 1000.0, -32000.0, 32000.0) as i16
        } else {
            0
        };
        let effort = self.control_effort();
        a.control_effort = if effort.is_finite() { effort as i32 } else { 0 };
        a.stall_seq = self.stall.seq;
        a.stall_position = self.stall.position;
        a.load_angle_ddeg = self.stall.load_angle_ddeg();
        a.servo_tune = self.tune.report;
    }
}

mod torque;
mod tune;

#[cfg(test)]
mod tests;
