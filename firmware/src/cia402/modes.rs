//! The operating modes in Operation enabled: the dispatch by 0x6061 and the
//! generators of PP (trapezoid or jerk-limited), PV, HM, CSP, CSV and CST.

use super::*;

impl Cia402 {
    /// Runs the active mode in Operation enabled; returns the set-point kind.
    pub(super) fn run_mode(
        &mut self,
        index: Option<i32>,
        dt: f32,
        setpoint: SetpointArrival,
    ) -> SetpointKind {
        let cwv = self.controlword;
        let halt = cwv.halt();
        let p = &self.params;
        let di = self.digital_inputs;
        let homing = self.mode == OperationMode::Hm;
        // Hardware limits (not while homing: homing uses them as references).
        let pos_lim = !homing && di & homing::DI_POS_LIMIT != 0;
        let neg_lim = !homing && di & homing::DI_NEG_LIMIT != 0;
        if pos_lim || neg_lim {
            self.internal_limit = true;
        }
        let qs_dec = p.quick_stop_deceleration as f32;
        if self.servo_tune && self.servo_tune_moves(halt || pos_lim || neg_lim) {
            return SetpointKind::Tune;
        }
        match self.mode {
            OperationMode::Pp => {
                self.run_pp(halt, pos_lim, neg_lim, dt);
                SetpointKind::Position
            }
            OperationMode::Pv => {
                self.run_pv(halt, pos_lim, neg_lim, dt);
                SetpointKind::Velocity
            }
            OperationMode::Hm => {
                self.run_hm(halt, index, dt);
                SetpointKind::Position
            }
            OperationMode::Csp | OperationMode::Csv => {
                self.run_cyclic(halt, pos_lim, neg_lim, dt, setpoint)
            }
            OperationMode::Cst | OperationMode::Pt => self.run_cst(halt, pos_lim, neg_lim, dt),
            OperationMode::None => {
                self.motion.stop(qs_dec, dt);
                SetpointKind::Position
            }
        }
    }

    /// The servo tune's move goes on (`servo_tune`) in PP and CSP unless
    /// `stopped` (halt, a limit switch) or the axis is outside the software limits;
    /// otherwise it ends here.
    fn servo_tune_moves(&mut self, stopped: bool) -> bool {
        let outside = self
            .params
            .sw_limits()
            .is_some_and(|(lo, hi)| self.actual_position >= hi || self.actual_position <= lo);
        if matches!(self.mode, OperationMode::Pp | OperationMode::Csp) && !stopped && !outside {
            // The drive's servo tune moves the axis: the generator follows the actual
            // position and speed (the start of any stop ramp, and of the mode's
            // set-points once the tune ends).
            self.motion
                .set(self.actual_position, self.actual_velocity as f32);
            return true;
        }
        // Halt or another mode ends it.
        self.servo_tune = false;
        false
    }

    /// CSP and CSV: 0x60B2 as the torque feed-forward, halt on the 0x605D ramp, else
    /// the mode's set-point. (Inlined: the CSP cycle's path, `cargo xtask bench`.)
    #[inline(always)]
    fn run_cyclic(
        &mut self,
        halt: bool,
        pos_lim: bool,
        neg_lim: bool,
        dt: f32,
        setpoint: SetpointArrival,
    ) -> SetpointKind {
        let p = &self.params;
        let csv = self.mode == OperationMode::Csv;
        // 0x60B2: torque feed-forward of the servo loops.
        self.torque_cmd = p.torque_offset;
        if halt {
            self.halted = true;
            self.abnormal_stop = true;
            self.cyc.started = false;
            self.motion
                .stop(p.option_decel(p.halt_option).unwrap_or(0.0), dt);
            return if csv {
                SetpointKind::Velocity
            } else {
                SetpointKind::Position
            };
        }
        if csv {
            self.run_csv(pos_lim, neg_lim, dt);
            SetpointKind::Velocity
        } else {
            self.run_csp(pos_lim, neg_lim, dt, setpoint);
            SetpointKind::Position
        }
    }

    /// CSV: 0x60FF + 0x60B1 as a direct set-point every cycle, its changes limited by
    /// 0x60C5 / 0x60C6 (statusword bit 11 while limited); the position integrates it
    /// from the actual position (see PV).
    fn run_csv(&mut self, pos_lim: bool, neg_lim: bool, dt: f32) {
        let p = &self.params;
        let vmax = p.vmax();
        let mut v = (p.target_velocity.saturating_add(p.velocity_offset) as f32).clamp(-vmax, vmax);
        if (pos_lim && v > 0.0) || (neg_lim && v < 0.0) {
            self.abnormal_stop = true;
            v = 0.0;
        }
        self.motion.rebase(self.actual_position);
        let (acc, dec) = (p.max_acceleration as f32, p.max_deceleration as f32);
        if !self.motion.ramp_velocity(v, acc, dec, dt) {
            self.internal_limit = true;
        }
        self.clamp_sw_limit();
    }

    /// PT and CST: the torque demand 0x6071 + 0x60B2, limited to ±0x6072 and moved at the
    /// slope 0x6087; the motion generator shows the actual position and speed (the
    /// start of any stop ramp). Halt, a hardware limit switch or a software position
    /// limit in the direction of the torque or of the motion stop the axis in velocity
    /// control instead (halt: 0x605D ramp; limits: 0x6085), the demand then follows
    /// the servo loops' torque so that torque control resumes from it. Out of line:
    /// the CSP path that shares the dispatch stays as it was.
    // Measured (cargo xtask size, LAN9252 image): dropped with the other hot-path
    // attributes the image grew 1184 B; this and `Motion::kind_changes` inline into the
    // control step (+1120 B there).
    #[inline(never)]
    pub(super) fn run_cst(
        &mut self,
        halt: bool,
        pos_lim: bool,
        neg_lim: bool,
        dt: f32,
    ) -> SetpointKind {
        let p = &self.params;
        let tmax = f32::from(p.torque_limit());
        let wanted = (i32::from(p.target_torque) + i32::from(p.torque_offset)) as f32;
        let target = foc::num::clamp(wanted, -tmax, tmax);
        let v = self.motion.velocity();
        let (mut up, mut down) = (pos_lim, neg_lim);
        if let Some((lo, hi)) = p.sw_limits() {
            let pos = self.actual_position;
            if pos >= hi || pos <= lo {
                self.internal_limit = true;
            }
            up |= pos >= hi;
            down |= pos <= lo;
        }
        let blocked = (up && (target > 0.0 || v > 0.0)) || (down && (target < 0.0 || v < 0.0));
        if halt || blocked {
            let dec = if halt {
                self.halted = true;
                p.option_decel(p.halt_option).unwrap_or(0.0)
            } else {
                p.quick_stop_deceleration as f32
            };
            self.abnormal_stop = true;
            self.motion.stop(dec, dt);
            self.torque_demand = f32::from(self.servo_torque_user());
            self.torque_cmd = 0;
            // PT: halted once at rest (statusword bit 10).
            self.target_reached = halt && self.motion.velocity() == 0.0;
            return SetpointKind::Velocity;
        }
        if wanted != target {
            self.internal_limit = true;
        }
        let slope = p.torque_slope as f32 * dt;
        let d = self.torque_demand;
        self.torque_demand = if p.torque_slope == 0 {
            target
        } else {
            d + foc::num::clamp(target - d, -slope, slope)
        };
        self.torque_cmd = round_i16(self.torque_demand);
        // PT: the demand has reached the (limited) target (statusword bit 10).
        self.target_reached = self.torque_demand == target;
        self.motion
            .set(self.actual_position, self.actual_velocity as f32);
        SetpointKind::Torque
    }

    /// PV: the velocity ramp to 0x60FF, stopped by halt, a hardware limit in the
    /// direction of travel or the software limits ahead (braking distance).
    pub(super) fn run_pv(&mut self, halt: bool, pos_lim: bool, neg_lim: bool, dt: f32) {
        let p = &self.params;
        let qs_dec = p.quick_stop_deceleration as f32;
        // Velocity modes: the servo follows the velocity; the position demand is
        // re-based on the actual position (keeping its fraction) so that it shows
        // where the axis is and a later position mode starts bumpless.
        self.motion.rebase(self.actual_position);
        let vmax = p.vmax();
        let mut target = (p.target_velocity as f32).clamp(-vmax, vmax);
        let mut dec = p.dec(p.profile_deceleration);
        if halt {
            self.halted = true;
            self.abnormal_stop = true;
            target = 0.0;
            dec = p.option_decel(p.halt_option).unwrap_or(0.0);
        }
        let v = self.motion.velocity();
        if (pos_lim && (target > 0.0 || v > 0.0)) || (neg_lim && (target < 0.0 || v < 0.0)) {
            self.abnormal_stop = true;
            target = 0.0;
            dec = qs_dec;
        }
        if let Some((lo, hi)) = p.sw_limits() {
            let pos = self.motion.position() as f32;
            let brake = v * v / (2.0 * dec.max(1.0));
            if (v >= 0.0 && target > 0.0 && pos + brake >= hi as f32)
                || (v <= 0.0 && target < 0.0 && pos - brake <= lo as f32)
            {
                self.internal_limit = true;
                target = 0.0;
            }
        }
        self.motion
            .ramp_velocity(target, p.acc(p.profile_acceleration), dec, dt);
        let tv = target as i32;
        let reached =
            self.actual_velocity.wrapping_sub(tv).unsigned_abs() <= p.velocity_window as u32;
        self.vel_window_time = if reached {
            self.vel_window_time + dt
        } else {
            0.0
        };
        self.target_reached = if halt {
            self.motion.velocity() == 0.0
        } else {
            reached && self.vel_window_time * 1000.0 >= p.velocity_window_time as f32
        };
    }

    /// CSP: 0x607A + 0x60B0 (within the software limits and the position range) as
    /// segments interpolated or taken directly (see [`Cia402::step`]); a hardware limit
    /// switch in the direction of the demand holds the axis.
    pub(super) fn run_csp(
        &mut self,
        pos_lim: bool,
        neg_lim: bool,
        dt: f32,
        setpoint: SetpointArrival,
    ) {
        let p = &self.params;
        let mut target = p.target_position.wrapping_add(p.position_offset);
        if let Some((lo, hi)) = p.sw_limits() {
            if target > hi {
                target = hi;
                self.internal_limit = true;
            } else if target < lo {
                target = lo;
                self.internal_limit = true;
            }
        }
        // A target of the position range 0x607B: the shortest way from the demand.
        let target = p.target_in_range(self.motion.position(), target, 3);
        let velocity_offset = p.velocity_offset as f32;
        let cur = self.motion.position();
        let nominal = p.interpolation_period_s();
        if !self.cyc.started {
            // No segment yet: stand at the demand; the first set-point starts one. The
            // time since the "last" set-point starts at one nominal period, so the
            // first segment gets the nominal period.
            self.cyc = Cyclic {
                from: cur,
                to: cur,
                elapsed: 1.0e9,
                since_fresh: nominal,
                last_gap: nominal,
                period: nominal,
                interpolate: false,
                extrapolate: false,
                started: true,
                v: 0.0,
                last_target: cur,
            };
        }
        self.cyc.since_fresh += dt;
        self.cyc.elapsed += dt;
        let was_interpolating = self.cyc.interpolate;
        // Where the running segment's demand is now, by that segment's own period and
        // kind (`csp_segment_due` sets the next one's).
        let now_demand = self.cyc.demand(0.0).0;
        let new_segment = self.csp_segment_due(setpoint, nominal, dt);
        if new_segment {
            self.csp_segment(target, setpoint, was_interpolating, now_demand, dt);
        }
        let (mut demand, moving) = self.cyc.demand(velocity_offset);
        let mut vel = moving;
        let d = demand.wrapping_sub(cur);
        if (pos_lim && d > 0) || (neg_lim && d < 0) {
            self.abnormal_stop = true;
            demand = cur;
            vel = 0.0;
            self.cyc.to = cur;
            self.cyc.from = cur;
            self.cyc.v = 0.0;
        }
        self.motion.set(demand, vel);
    }

    /// CSP: a new segment towards `target` (this step's set-point arrival `setpoint`;
    /// `was_interpolating`: the last segment was interpolated; `now_demand`: where its
    /// demand is at this step), its speed limited by
    /// `Params::csp_segment_speed`. (Inlined: the CSP cycle's path.)
    #[inline(always)]
    fn csp_segment(
        &mut self,
        target: i32,
        setpoint: SetpointArrival,
        was_interpolating: bool,
        now_demand: i32,
        dt: f32,
    ) {
        // An interpolated segment starts where the last one's demand is now (on
        // time that is its target; early or after a run-on, no step); a direct one
        // from the last target (its velocity is the set-points' difference).
        let fresh = setpoint == SetpointArrival::Fresh;
        self.cyc.from = if fresh && (self.cyc.interpolate || was_interpolating) {
            now_demand
        } else {
            self.cyc.to
        };
        // A segment's speed is at most min(0x607F, 0x6080) and changes from the
        // last segment's by at most 0x60C5 / 0x60C6 over its period: a jump of the
        // target is followed on that profile (statusword bit 11, internal limit),
        // segment by segment, not at once; no run-on then. With set-points on
        // their own clock (fresh), a limited segment's speed is planned over the
        // longer of its period and the time since the last set-point (and it runs
        // on at that speed, below), so that the speed holds whatever the master's
        // jitter.
        let dist = target.wrapping_sub(self.cyc.from) as f32;
        let t = if fresh {
            self.cyc.period.max(self.cyc.last_gap)
        } else {
            self.cyc.period
        };
        let vt = target.wrapping_sub(self.cyc.last_target) as f32 / t;
        self.cyc.last_target = target;
        match self.params.csp_segment_speed(dist, t, self.cyc.v, vt) {
            None => {
                self.cyc.to = target;
                self.cyc.extrapolate = fresh;
                self.cyc.v = dist / t;
            }
            Some(v) => {
                // The limited speed (not its whole increments) carries over. With
                // set-points on their own clock the segment runs on at it until the
                // next one (for up to twice the longer of its period and a tick, when
                // that stays short of the target): a late set-point does not halt the
                // demand, the next starts where it is, and it is never faster than
                // `v` on the drive's clock.
                let run = 2.0 * t.max(STEP_PERIOD_S);
                let span = if fresh && v * dist >= 0.0 && (v * run).abs() <= dist.abs() {
                    run
                } else {
                    t
                };
                self.cyc.to = self.cyc.from.wrapping_add(round_i32(v * span));
                self.cyc.extrapolate = false;
                self.internal_limit = true;
                self.cyc.v = v;
                if fresh {
                    self.cyc.period = span;
                    self.cyc.interpolate = true;
                }
            }
        }
        self.cyc.elapsed = match (setpoint, self.cyc.interpolate) {
            // The boundary step itself is the segment's first step.
            (SetpointArrival::PerCycle, true) => dt,
            // Every step is a boundary: the next one that is not is a new segment.
            (SetpointArrival::PerCycle, false) => 1.0e9,
            _ => 0.0,
        };
    }

    /// CSP: whether this step starts a new segment, and if so its period and kind
    /// (interpolated or direct) from 0x60C2 (`nominal`, s) and the time between
    /// set-points.
    #[inline(always)]
    fn csp_segment_due(&mut self, setpoint: SetpointArrival, nominal: f32, dt: f32) -> bool {
        match setpoint {
            SetpointArrival::PerCycle => {
                // One step per master cycle: a new set-point every step, or every
                // 0x60C2 period (at the step that ends nearest to its boundary) when
                // the steps are shorter.
                let ratio = nominal / dt;
                let interpolate = ratio >= 1.5;
                let due = !interpolate || self.cyc.elapsed - 0.5 * dt >= nominal;
                if due {
                    self.cyc.interpolate = interpolate;
                    self.cyc.period = if interpolate || ratio > 0.75 {
                        nominal
                    } else {
                        dt
                    };
                    self.cyc.since_fresh = 0.0;
                }
                self.cyc.extrapolate = false;
                due
            }
            SetpointArrival::Fresh => {
                // The master's period: 0x60C2, unless the time since the last set-point
                // differs from it by more than a quarter and agrees with the time
                // before (a master whose cycle is not 0x60C2); a one-off gap (lost
                // frames, a master coming back) keeps 0x60C2.
                let gap = self.cyc.since_fresh;
                let near = |a: f32, b: f32| a >= 0.75 * b && a <= 1.33 * b;
                let (period, interpolate) = if nominal > 0.0 && near(gap, nominal) {
                    (nominal, nominal >= 1.5 * STEP_PERIOD_S)
                } else {
                    let steady = if near(gap, self.cyc.last_gap) || nominal <= 0.0 {
                        gap
                    } else {
                        nominal
                    };
                    let interpolate = steady >= 1.5 * STEP_PERIOD_S;
                    // A direct segment's velocity is the set-points' difference over
                    // the time between them.
                    (if interpolate { steady } else { gap }, interpolate)
                };
                self.cyc.last_gap = gap;
                self.cyc.since_fresh = 0.0;
                self.cyc.period = period;
                self.cyc.interpolate = interpolate;
                true
            }
            SetpointArrival::Stale => false,
        }
    }

    /// PP: takes a new set-point (0x607A with the profile values) on the rising edge of
    /// controlword bit 4, into the running slot or the buffer, and clears the
    /// acknowledge once bit 4 is low and the buffer is free.
    pub(super) fn pp_accept_setpoint(&mut self, m: &Motion) {
        let cwv = self.controlword;
        let p = &self.params;
        let rising = cwv.new_setpoint_edge(self.prev_cw);
        let params_ok =
            p.profile_velocity != 0 && p.profile_acceleration != 0 && p.profile_deceleration != 0;
        if rising && params_ok {
            let base = self
                .pp
                .buffered
                .or(self.pp.active)
                .map_or(self.pp.last_target, |s| s.target);
            let target = if cwv.relative() {
                let reference = match p.positioning_option & 0x3 {
                    1 => m.position(),
                    2 => self.actual_position,
                    _ => base,
                };
                reference.wrapping_add(p.target_position)
            } else {
                // From where the axis will be when this set-point starts.
                let from = self
                    .pp
                    .buffered
                    .or(self.pp.active)
                    .map_or(m.position(), |s| s.target);
                p.target_in_range(from, p.target_position, p.positioning_option >> 6)
            };
            let sp = Setpoint {
                target,
                vel: (p.profile_velocity as f32).min(p.vmax()),
                acc: p.acc(p.profile_acceleration),
                dec: p.dec(p.profile_deceleration),
            };
            self.pp.clamped = false;
            if self.pp.active.is_none() || cwv.change_immediately() {
                if let Some(a) = self.pp.active {
                    self.pp.last_target = a.target;
                }
                self.pp.active = Some(sp);
                self.pp.buffered = None;
                self.pp.ack = true;
            } else if self.pp.buffered.is_none() {
                self.pp.buffered = Some(sp);
                self.pp.ack = true;
            }
        }
        if !cwv.new_setpoint() && self.pp.buffered.is_none() {
            self.pp.ack = false;
        }
    }

    /// PP: the software limits clamp the running and the buffered target (statusword
    /// bit 11 while a target is clamped).
    fn pp_clamp_targets(&mut self) {
        if let Some((lo, hi)) = self.params.sw_limits() {
            for sp in [self.pp.active.as_mut(), self.pp.buffered.as_mut()]
                .into_iter()
                .flatten()
            {
                if sp.target > hi {
                    sp.target = hi;
                    self.pp.clamped = true;
                } else if sp.target < lo {
                    sp.target = lo;
                    self.pp.clamped = true;
                }
            }
        }
        if self.pp.clamped {
            self.internal_limit = true;
        }
    }

    /// The PP set-point handling and trapezoid on `m`; returns true when `m` stands still
    /// after a halt or with no set-point left.
    pub(super) fn pp_generate(
        &mut self,
        m: &mut Motion,
        halt: bool,
        pos_lim: bool,
        neg_lim: bool,
        dt: f32,
    ) -> bool {
        self.pp_accept_setpoint(m);
        let cwv = self.controlword;
        self.pp_clamp_targets();
        let p = &self.params;
        let qs_dec = p.quick_stop_deceleration as f32;
        if halt {
            self.halted = true;
            self.abnormal_stop = true;
            self.pp.active = None;
            self.pp.buffered = None;
            let dec = p.option_decel(p.halt_option).unwrap_or(0.0);
            let stopped = m.stop(dec, dt);
            self.pp.last_target = m.position();
            return stopped;
        }
        // Hardware limit in the direction of travel: abort with the quick-stop ramp.
        let v = m.velocity();
        let toward = |t: i32, pos: i32| t.wrapping_sub(pos);
        if let Some(a) = self.pp.active {
            let d = toward(a.target, m.position());
            if (pos_lim && (d > 0 || v > 0.0)) || (neg_lim && (d < 0 || v < 0.0)) {
                self.pp.active = None;
                self.pp.buffered = None;
            }
        }
        if self.pp.active.is_none() && ((pos_lim && v > 0.0) || (neg_lim && v < 0.0)) {
            self.abnormal_stop = true;
        }
        if let Some(a) = self.pp.active {
            let through = cwv.change_on_setpoint()
                && self.pp.buffered.is_some_and(|b| {
                    let d1 = a.target.wrapping_sub(m.position());
                    let d2 = b.target.wrapping_sub(a.target);
                    (d1 >= 0) == (d2 >= 0) && d2 != 0
                });
            let vt = if through {
                a.vel.min(self.pp.buffered.map_or(0.0, |b| b.vel))
            } else {
                0.0
            };
            let st = m.to_position(
                a.target,
                a.vel,
                a.acc,
                a.dec,
                vt,
                p.start_stop_speed as f32,
                dt,
            );
            if st != MoveStatus::Moving {
                self.pp.last_target = a.target;
                self.pp.active = self.pp.buffered.take();
            }
        } else {
            let dec = if self.abnormal_stop {
                qs_dec
            } else {
                p.dec(p.profile_deceleration)
            };
            m.stop(dec, dt);
        }
        self.pp.active.is_none() && m.velocity() == 0.0
    }

    pub(super) fn run_pp(&mut self, halt: bool, pos_lim: bool, neg_lim: bool, dt: f32) {
        let p = &self.params;
        let (stopped, settled) = if p.motion_profile_type == 3 || self.pp.smooth.active() {
            if !self.pp.smooth.active() {
                self.pp.gen = self.motion;
                self.pp.smooth.start(self.motion.position(), 1);
            }
            // Jerk phases as long as one acceleration from 0 to the profile velocity.
            let acc = p.acc(p.profile_acceleration).max(1.0);
            let n = ((p.profile_velocity as f32).min(p.vmax()) / acc / dt) as usize;
            let mut g = self.pp.gen;
            let stopped = self.pp_generate(&mut g, halt, pos_lim, neg_lim, dt);
            self.pp.gen = g;
            let prev = self.motion.position();
            let y = self.pp.smooth.push(g.position(), n);
            let settled = self.pp.smooth.settled();
            if settled && self.params.motion_profile_type != 3 {
                self.pp.smooth.stop();
            }
            if settled {
                self.motion = g;
            } else {
                self.motion.set(y, y.wrapping_sub(prev) as f32 / dt);
            }
            (stopped, settled)
        } else {
            let mut m = self.motion;
            let stopped = self.pp_generate(&mut m, halt, pos_lim, neg_lim, dt);
            self.motion = m;
            (stopped, true)
        };
        if halt {
            self.target_reached = stopped && settled;
            return;
        }
        // Target reached: no set-point left and the axis in the window for 0x6068 ms.
        let done = stopped && settled;
        let inwin = self
            .motion
            .position()
            .wrapping_sub(self.actual_position)
            .unsigned_abs()
            <= self.params.position_window;
        self.window_time = if done && inwin {
            self.window_time + dt
        } else {
            0.0
        };
        self.target_reached =
            done && inwin && self.window_time * 1000.0 >= self.params.position_window_time as f32;
    }

    pub(super) fn run_hm(&mut self, halt: bool, index: Option<i32>, dt: f32) {
        let cwv = self.controlword;
        let p = &self.params;
        let inp = HomingInputs {
            digital_inputs: self.digital_inputs,
            actual: self.actual_position,
            index: index.map(|r| self.raw_to_user(r)),
            stall: self.stall.map(|r| self.raw_to_user(r)),
        };
        let start = cwv.new_setpoint_edge(self.prev_cw);
        let mut shift = None;
        if halt || !cwv.homing_start() {
            // Halt or bit 4 cleared: interrupt (stop, status "interrupted").
            let dec = if halt {
                self.halted = true;
                self.abnormal_stop = true;
                p.option_decel(p.halt_option).unwrap_or(0.0)
            } else {
                p.acc(p.homing_acceleration)
                    .min(p.dec(p.homing_acceleration))
            };
            if self.motion.stop(dec, dt) && self.hm.running() {
                self.hm.abort();
            }
        } else if start {
            let hp = HomingParams {
                method: p.homing_method,
                fast: (p.homing_speed_switch as f32).min(p.vmax()),
                slow: (p.homing_speed_zero as f32).min(p.vmax()),
                acc: p
                    .acc(p.homing_acceleration)
                    .min(p.dec(p.homing_acceleration)),
                offset: p.home_offset,
                has_index: self.has_index,
                assigned: self.assigned_inputs,
                stall_min_speed: self.stall_homing,
            };
            shift = self.hm.start(hp, &inp);
        } else {
            shift = self.hm.cycle(&mut self.motion, &inp, dt);
        }
        if let Some(delta) = shift {
            self.shift = self.shift.wrapping_add(delta);
            self.actual_position = self.actual_position.wrapping_add(delta);
            self.motion.shift(delta);
        }
        let done = !self.hm.running() && self.motion.velocity() == 0.0;
        let inwin = self
            .motion
            .position()
            .wrapping_sub(self.actual_position)
            .unsigned_abs()
            <= p.position_window;
        self.window_time = if done && inwin {
            self.window_time + dt
        } else {
            0.0
        };
        self.target_reached =
            done && inwin && self.window_time * 1000.0 >= p.position_window_time as f32;
    }
}

/// `x` rounded to the nearest whole number (halves away from zero), saturated.
fn round_i32(x: f32) -> i32 {
    (x + if x < 0.0 { -0.5 } else { 0.5 }) as i32
}

/// `x` rounded to the nearest whole number (halves away from zero), saturated.
pub(super) fn round_i16(x: f32) -> i16 {
    (x + if x < 0.0 { -0.5 } else { 0.5 }) as i16
}
