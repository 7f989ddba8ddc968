//! The drive's own clock: the supervision tick ([`Drive::tick`], protections from the
//! measured values, input functions, then a control step unless the master's cycle
//! did one) and the control steps ([`Drive::step`]) with their time base.

use super::*;

impl<S: ParameterStore> Drive<S> {
    /// The supervision tick, on the drive's own clock (`now_us`, µs; every
    /// [`TICK_US`] on the board, in every ESM state and sync mode): input filter and
    /// functions, protections from the measured values, fault reset by input,
    /// monitoring, then — unless the master's cycle did one within
    /// [`TICK_STEP_AFTER_US`] — a control step ([`Drive::step`]): the power drive
    /// system, the fault reactions and stop ramps, the profile and homing generators
    /// and the brake advance whether or not frames arrive. A fault this tick detects
    /// starts its reaction in the same tick. Last, the scope's sample when it records
    /// ([`crate::scope`]). `raw_inputs`: bit n = level of IN n+1.
    pub fn tick(&mut self, now_us: u64, raw_inputs: u8) {
        let now = now_us as Stamp;
        let dt_ms = self.advance_clock(now_us);
        self.faults.set_clock(self.now_ms);
        self.monitor.tick_ms(dt_ms);
        self.update_housekeeping();
        self.inputs
            .update(raw_inputs, dt_ms.saturating_mul(1000), &self.params);
        self.params.set_raw_inputs(self.inputs.raw());
        // Input function "probe" (0x2152 bit 5): an edge latches the position at this
        // tick for touch probe 1, beside IN1's capture.
        if let Some(active) = self.inputs.probe_edge() {
            self.probe_tick = self.probe_tick.or(active, self.axis.position);
        }
        let snap = self.snapshot();
        let now_ms = self.now_ms;
        if self.axis.bus_mv > 0 {
            self.faults
                .check_bus_voltage(self.axis.bus_mv, snap, now_ms);
        }
        // Over-current: the measured phase currents against the limit (software check)
        // and the power stage's break latch. The condition is gone once the currents
        // are below the limit and the latch is re-armed; then a fault reset (with
        // 0x2057 = 1, the fault being latched) clears it.
        self.faults.check_phase_currents(
            i32::from(self.axis.ia_ma),
            i32::from(self.axis.ib_ma),
            snap,
            now_ms,
        );
        if self.axis.overcurrent_trip {
            self.faults.raise(FaultKind::OverCurrent, snap, now_ms);
        }
        if self.inputs.fault_clear_edge() {
            self.faults.fault_reset();
        }
        if self.params.take_fault_history_clear() {
            self.faults.clear_history();
        }
        self.servo_tune_tick(dt_ms);
        let after = match self.cycles_running(now) {
            Some(p) => (TICK_STEP_AFTER_US as u32).max(p + p / 2),
            None => TICK_STEP_AFTER_US as u32,
        };
        let due = self
            .last_step_us
            .is_none_or(|t| elapsed_us(now, t).is_none_or(|d| d >= after));
        // A fault the PDS has not taken yet starts its reaction in this tick.
        let fault_news = self.faults.any_active()
            && !matches!(
                self.cia402.state(),
                crate::cia402::pds::PdsState::Fault
                    | crate::cia402::pds::PdsState::FaultReactionActive
            );
        if due || fault_news || core::mem::take(&mut self.react_now) {
            self.step_at(now, SetpointArrival::Stale);
        }
        if self.cia402.take_following_error_fault() {
            // The CiA 402 following-error supervision (0x6065 / 0x6066) faulted the
            // PDS: the fault module reports it like every other fault (emergency,
            // history, red LED 7, alarm output); an event, so a reset clears it.
            let snap = self.snapshot();
            self.faults
                .raise(FaultKind::FollowingError, snap, self.now_ms);
            self.faults.condition_gone(FaultKind::FollowingError);
        }
        if self.scope.running() {
            self.sample_scope();
        }
    }

    /// Advances the drive's millisecond clock to `now_us`: returns the whole
    /// milliseconds of the clock since the last tick (the clock's millisecond
    /// boundaries, as `now_us / 1000` counts them).
    fn advance_clock(&mut self, now_us: u64) -> u32 {
        let now = now_us as Stamp;
        let dt_ms = match self.last_tick_us.map(|prev| elapsed_us(now, prev)) {
            Some(Some(d)) => {
                let us = self.tick_phase_us + d;
                self.tick_phase_us = us % 1000;
                us / 1000
            }
            Some(None) => 0,
            None => {
                self.tick_phase_us = (now_us % 1000) as u32;
                (TICK_US / 1000) as u32
            }
        };
        self.last_tick_us = Some(now);
        self.now_ms = self.now_ms.wrapping_add(dt_ms);
        dt_ms
    }

    /// One control step at `now_us` on the drive's clock: [`Drive::run_cycle`] over the
    /// time since the previous step. Called by the supervision tick and by the
    /// master's cycle (`setpoint`: whether that cycle brought new outputs).
    pub fn step(&mut self, now_us: u64, setpoint: SetpointArrival) -> DriveCommand {
        self.step_at(now_us as Stamp, setpoint)
    }

    /// [`Drive::step`] at a [`Stamp`]: steps of at most 10 ms (a longer pause is not
    /// integrated), 1 µs when the clock stood still or went back.
    pub(super) fn step_at(&mut self, now: Stamp, setpoint: SetpointArrival) -> DriveCommand {
        let dt = match self.last_step_us.map(|prev| elapsed_us(now, prev)) {
            Some(Some(d)) if d > 0 => d.min(10_000) as f32 * 1e-6,
            Some(_) => 1e-6,
            None => TICK_US as f32 * 1e-6,
        };
        self.last_step_us = Some(now);
        self.monitor.set_step_us(now);
        self.steps = self.steps.wrapping_add(1);
        self.control_step(dt, setpoint)
    }

    /// The period of the master's cycles (µs) while they run at 1 ms or faster (the
    /// last one less than two periods ago).
    pub(super) fn cycles_running(&self, now: Stamp) -> Option<u32> {
        let p = self.cycle_period_us;
        let since = elapsed_us(now, self.last_cycle_us?)?;
        (p > 0 && p <= TICK_US as u32 && since < 2 * p).then_some(p)
    }

    /// How long the motion layer takes to reach a new step's set-points, s: the
    /// master's cycle while it runs at 1 ms or faster (the steps come with it), else
    /// the tick period. Not the length of the last step: the tick and the cycle may
    /// land close together, and the motion layer must not rush to the second one.
    pub fn segment_s(&self) -> f32 {
        let us = self
            .last_step_us
            .and_then(|t| self.cycles_running(t))
            .unwrap_or(TICK_US as u32);
        us as f32 * 1e-6
    }

    /// Control steps so far (wrapping): a new value means new set-points in
    /// [`Drive::command`], for the motion layer to start a new segment with.
    pub fn steps(&self) -> u32 {
        self.steps
    }
}
