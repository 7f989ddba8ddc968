//! One control step of the drive profile ([`Cia402::step`]), in its order: the
//! feedback, the PDS transitions, the mode switch, the state's motion, supervision,
//! the statusword, and the set-points for the motor side.

use super::*;

impl Cia402 {
    /// One control step of `dt` seconds whose set-points are of unknown age
    /// ([`SetpointArrival::PerCycle`]): the step of a caller that runs one step per master
    /// cycle (tests, benchmarks).
    pub fn cycle(&mut self, fb: &DriveFeedback, dt: f32) -> DriveCommand {
        self.step(fb, dt, SetpointArrival::PerCycle)
    }

    /// One control step of `dt` seconds: PDS, the stop ramps and reactions, the
    /// active mode's generator, supervision, statusword. The drive calls it from its
    /// own clock (every supervision tick) and from the master's cycle; `setpoint`
    /// says whether that cycle brought new outputs.
    ///
    /// **CSP** takes a new 0x607A at each [`SetpointArrival::Fresh`] step. Its set-point
    /// period is 0x60C2, or the measured time between set-points when that differs
    /// from 0x60C2 by more than a quarter. A period shorter than 1.5 steps
    /// ([`STEP_PERIOD_S`]) is followed directly (the demand is the target, with the
    /// segment's velocity as feed-forward); a longer one is interpolated linearly, one
    /// period behind. Without a new set-point the demand runs on with the last
    /// segment's velocity for **at most one period** (the lost or late frame of a
    /// master at constant speed costs nothing), then **holds** (velocity 0) until the
    /// next set-point. With [`SetpointArrival::PerCycle`] there is no run-on: the demand
    /// stops at the target. **CSV** keeps the last 0x60FF: a velocity set-point holds
    /// by being a velocity; a lost master is stopped by 0x6007.
    pub fn step(&mut self, fb: &DriveFeedback, dt: f32, setpoint: SetpointArrival) -> DriveCommand {
        let dt = if dt > 0.0 && dt < 1.0 { dt } else { 0.001 };
        let index = self.take_feedback(fb);
        let cmd = self.run_transitions(fb);
        self.switch_mode();
        let (drive_enabled, kind) = self.run_state(fb, index, dt, setpoint);
        if !drive_enabled {
            self.motion.reset(self.actual_position);
        }
        // Transition 4 waiting for the power stage: the motor side gets the enable (at
        // the actual position) so that it can get ready.
        self.enable_waiting = self.state == PdsState::SwitchedOn
            && self.enable_pending
            && cmd == Command::EnableOperation;

        self.supervise(fb, drive_enabled, dt);
        self.statusword = self.build_statusword(fb);
        self.prev_cw = self.controlword;
        self.drive_command(drive_enabled, kind, dt)
    }

    /// Step 1: the measured values in user units and the touch probes; returns the
    /// index pulse position (raw), if an index exists and was seen.
    #[inline(always)]
    pub(super) fn take_feedback(&mut self, fb: &DriveFeedback) -> Option<i32> {
        self.raw_position = fb.position;
        self.actual_position = self.raw_to_user(fb.position);
        self.actual_velocity = pol(self.vel_neg(), fb.velocity);
        self.control_effort = pol(self.pos_neg(), fb.control_effort);
        // Raw (motor-side) torques; the objects apply the polarity when read.
        self.actual_torque = fb.torque;
        self.servo_torque = fb.torque_demand;
        self.actual_current = fb.current;
        self.digital_inputs = fb.digital_inputs;
        self.enable_pending = fb.enable_pending;
        self.stall = fb.stall;
        let index = if self.has_index { fb.index } else { None };
        {
            let neg = self.pos_neg();
            let shift = self.shift;
            self.probe.update(fb.probe1, fb.probe2, index, |r| {
                pol(neg, r).wrapping_add(shift)
            });
        }
        index
    }

    /// Step 3: the mode switch (0x6061 follows 0x6060 once the new mode runs).
    #[inline(always)]
    pub(super) fn switch_mode(&mut self) {
        if self.mode != self.mode_request {
            self.mode = self.mode_request;
            self.pp = Pp {
                last_target: self.motion.position(),
                ..Pp::default()
            };
            self.hm.reset();
            self.cyc = Cyclic::default();
            self.torque_cmd = 0;
            // CST starts from the torque the servo loops demand now (see the module
            // docs: bumpless with a torque slope).
            self.torque_demand = f32::from(self.servo_torque_user());
        }
    }

    /// Step 6: the set-points for the motor side (raw coordinates), with the demand
    /// acceleration from the change of the demand velocity.
    #[inline(always)]
    pub(super) fn drive_command(
        &mut self,
        drive_enabled: bool,
        kind: SetpointKind,
        dt: f32,
    ) -> DriveCommand {
        let power = self.state.voltage_enabled();
        let v = self.motion.velocity();
        let acc = if drive_enabled {
            (v - self.prev_demand_vel) / dt.max(ACCELERATION_MIN_DT_S)
        } else {
            0.0
        };
        self.prev_demand_vel = if drive_enabled { v } else { 0.0 };
        let sign = if self.vel_neg() { -1.0 } else { 1.0 };
        let motor_enabled = drive_enabled || self.enable_waiting;
        // Torque control: the velocity is the speed limit (a magnitude); the servo
        // tune's move: its speed limit min(0x607F, 0x6080).
        let velocity = if kind == SetpointKind::Torque {
            self.params.max_motor_speed as f32
        } else if kind == SetpointKind::Tune {
            self.params.vmax()
        } else {
            sign * v
        };
        DriveCommand {
            power_stage: power,
            drive_enabled: motor_enabled,
            kind,
            position: self.user_to_raw(self.motion.position()),
            velocity,
            acceleration: sign * acc,
            torque_limit: self.params.torque_limit(),
            current_limit: self.params.current_limit(),
            torque: i32::from(pol16(self.vel_neg(), self.torque_cmd)),
            brake_release: motor_enabled,
        }
    }
}
