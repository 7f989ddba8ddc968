//! The power drive system in a step: entering a state, the guards of the transition
//! table ([`super::pds`]), the controlword commands, and what each state lets the
//! axis do (the mode, or a stop ramp by the option codes 0x605A-0x605E).

use super::*;

impl Cia402 {
    pub(super) fn enter(&mut self, to: PdsState) {
        let from = self.state;
        self.state = to;
        self.pending = Pending::None;
        self.enable_waiting = false;
        // A new state starts without torque command (the modes set theirs).
        self.torque_cmd = 0;
        if to == PdsState::OperationEnabled && from != PdsState::QuickStopActive {
            // Transition 4: clear internal set-points, start from where the axis is.
            self.motion.reset(self.actual_position);
            self.pp = Pp {
                last_target: self.actual_position,
                ..Pp::default()
            };
            if self.hm.running() {
                self.hm.reset();
            }
            self.cyc = Cyclic::default();
            self.fe_time = 0.0;
            self.fe_flag = false;
        }
        if to == PdsState::OperationEnabled {
            // Transitions 4 and 16: CST starts from the servo loops' torque demand.
            self.torque_demand = f32::from(self.servo_torque_user());
        }
        if to == PdsState::FaultReactionActive {
            // A fault: the demand may be what went wrong (a jump of the master's
            // target, a load the motor cannot hold). The reaction ramp starts from the
            // demand position at the lower of the demand and the actual speed (none
            // when they point in opposite directions).
            let vd = self.motion.velocity();
            let va = self.actual_velocity as f32;
            let v = if vd * va > 0.0 {
                vd.signum() * vd.abs().min(va.abs())
            } else {
                0.0
            };
            self.motion.set(self.motion.position(), v);
        }
        if from == PdsState::OperationEnabled && to != PdsState::OperationEnabled {
            // Leaving operation enabled voids the motion tasks (PP set-points, homing,
            // CSP segment); transition 16 starts again from standstill.
            self.pp = Pp {
                last_target: self.motion.position(),
                ..Pp::default()
            };
            if self.hm.running() {
                self.hm.reset();
            }
            self.cyc = Cyclic::default();
        }
    }

    pub(super) fn fault_detected(&mut self, code: u16) {
        if matches!(self.state, PdsState::Fault | PdsState::FaultReactionActive) {
            return;
        }
        self.error_code = code;
        if let Some(t) = pds::find(self.state, Event::FaultDetected, |_| true) {
            self.enter(t.to);
        }
    }

    pub(super) fn guard_ok(&self, g: Guard, fault_now: u16) -> bool {
        match g {
            Guard::None => true,
            Guard::QuickStopStays => (5..=8).contains(&self.params.quick_stop_option),
            Guard::QuickStopEnds => !(5..=8).contains(&self.params.quick_stop_option),
            Guard::FaultCleared => fault_now == 0,
            Guard::ReadyToFollow => !self.enable_pending,
        }
    }

    /// Fires the transition for `ev`, if any. Returns its number. Inline, the check
    /// whether the state has a transition for `ev` at all (the steady state of every
    /// cycle, Operation enabled with "enable operation", has none): the search only
    /// when it does.
    #[inline(always)]
    pub(super) fn fire(&mut self, ev: Event, fault_now: u16) -> Option<u8> {
        if !pds::leaves_on(self.state, ev) {
            return None;
        }
        self.fire_found(ev, fault_now)
    }

    fn fire_found(&mut self, ev: Event, fault_now: u16) -> Option<u8> {
        let t = pds::find(self.state, ev, |g| self.guard_ok(g, fault_now))?;
        self.enter(t.to);
        Some(t.number)
    }

    /// Step 2: the PDS transitions of this step (initialisation, faults, fault reset,
    /// the controlword command with the quick-stop input); returns the command.
    #[inline(always)]
    pub(super) fn run_transitions(&mut self, fb: &DriveFeedback) -> Command {
        if !self.init_done && !self.self_test {
            self.init_done = true;
            self.fire(Event::InitDone, fb.fault);
        }
        if fb.fault != 0 {
            self.fault_detected(fb.fault);
        }
        let cwv = self.controlword;
        let reset_edge = cwv.fault_reset_edge(self.prev_cw);
        if reset_edge
            && self.state == PdsState::Fault
            && self.fire(Event::FaultResetEdge, fb.fault).is_some()
        {
            self.error_code = 0;
            self.fe_flag = false;
        }
        let mut cmd = cwv.command();
        if fb.quick_stop_input
            && matches!(
                cmd,
                Command::Shutdown | Command::SwitchOn | Command::EnableOperation
            )
        {
            cmd = Command::QuickStop;
        }
        if cmd != Command::FaultReset {
            self.apply_command(cmd, fb);
        }
        cmd
    }

    pub(super) fn apply_command(&mut self, cmd: Command, fb: &DriveFeedback) {
        // Transitions 5 and 8 with a slow-down option wait for the ramp.
        if self.state == PdsState::OperationEnabled
            && matches!(cmd, Command::SwitchOn | Command::Shutdown)
        {
            let code = if cmd == Command::Shutdown {
                self.params.shutdown_option
            } else {
                self.params.disable_op_option
            };
            if code == 1 && self.motion.velocity() != 0.0 {
                self.pending = Pending::Transition(cmd);
                return;
            }
        }
        if self.state == PdsState::OperationEnabled && self.pending != Pending::None {
            self.pending = Pending::None;
        }
        self.fire(Event::Cmd(cmd), fb.fault);
    }

    /// Step 4: what the PDS state lets the axis do: the active mode in Operation
    /// enabled, the stop ramps of a pending transition, of Quick stop active and of
    /// Fault reaction active. Returns whether the drive function is enabled and the
    /// set-point kind.
    #[inline(always)]
    pub(super) fn run_state(
        &mut self,
        fb: &DriveFeedback,
        index: Option<i32>,
        dt: f32,
        setpoint: SetpointArrival,
    ) -> (bool, SetpointKind) {
        self.internal_limit = false;
        self.abnormal_stop = false;
        self.halted = false;
        let mut drive_enabled = false;
        let mut kind = SetpointKind::Position;
        match self.state {
            PdsState::OperationEnabled => {
                drive_enabled = true;
                if let Pending::Transition(c) = self.pending {
                    self.servo_tune = false;
                    let code = if c == Command::Shutdown {
                        self.params.shutdown_option
                    } else {
                        self.params.disable_op_option
                    };
                    let dec = self.params.option_decel(code).unwrap_or(0.0);
                    self.torque_cmd = 0;
                    if self.motion.stop(dec, dt) {
                        let ev = Event::Cmd(c);
                        self.fire(ev, fb.fault);
                        drive_enabled = false;
                    }
                } else {
                    kind = self.run_mode(index, dt, setpoint);
                }
            }
            PdsState::QuickStopActive => {
                self.servo_tune = false;
                self.abnormal_stop = true;
                drive_enabled = true;
                let code = self.params.quick_stop_option;
                let stopped = match self.params.option_decel(code) {
                    Some(dec) => self.motion.stop(dec, dt),
                    None => {
                        drive_enabled = false;
                        true
                    }
                };
                self.target_reached = stopped;
                if stopped && self.fire(Event::QuickStopDone, fb.fault).is_some() {
                    drive_enabled = false;
                }
            }
            PdsState::FaultReactionActive => {
                self.servo_tune = false;
                drive_enabled = !fb.power_stage_tripped;
                let stopped = match (
                    fb.power_stage_tripped,
                    self.params.option_decel(self.params.fault_reaction_option),
                ) {
                    (false, Some(dec)) => self.motion.stop(dec, dt),
                    _ => true,
                };
                if stopped {
                    self.fire(Event::FaultReactionDone, fb.fault);
                    drive_enabled = false;
                }
            }
            // The servo tune needs Operation enabled (also in the arms above).
            _ => self.servo_tune = false,
        }
        (drive_enabled, kind)
    }
}
