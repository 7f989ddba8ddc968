//! [`PlantAxis`]: the full electrical axis (plant, `foc` current loop, the firmware's
//! motion layer and current supervisor), one PWM period at a time.

use super::Switches;
use crate::fault_inject::InjectedFault;
use crate::plant::motor::{PlantConfig, ECN57_20, TC86_45};
use crate::plant::rig::{Rig, SERVO_DIV, TS, TS_SERVO};
use crate::sim_drive::{Axis, Motor};
use firmware::cia402::DriveCommand;
use firmware::commutation::{CommutatedMotion, Commutation};
use firmware::current_supervisor::{CurrentReport, CurrentSupervisor, SupervisorConfig};
use firmware::drive::AxisState;
use firmware::identity::Variant;
use firmware::motion::{CurrentReference, Feedback, Frame, MotionConfig, MotorConstants};
use firmware::params::Params;
use firmware::power_gate::{bridge_mode, BridgeMode, GateInputs};
use foc::modulation::Duties;
use foc::transforms::{inverse_park, Dq};

/// The full electrical axis: the motor and power-stage plant
/// ([`crate::plant::motor::Plant`], 48 V) with the `foc` current loop and encoder at
/// 40 kHz ([`Rig`]) and the firmware's motion layer ([`firmware::motion::Motion`]) at
/// 10 kHz inside the board's [`CommutatedMotion`], configured from the drive's vendor
/// parameters (0x2083 included). Switches and the index pulse
/// are those of [`KinematicAxis`](super::KinematicAxis) (true shaft position; the index latches at the
/// encoder count `index_phase` within each revolution). Positions count from the
/// shaft angle at construction. With the bridges off the current loop outputs 50 %
/// on all legs (the coils are shorted through the bridge: a mild back-EMF brake).
///
/// The current loop runs under the firmware's [`CurrentSupervisor`] as on the board:
/// with 0x2013 = 1 the power-up auto-tune runs once the drive permits it
/// ([`Axis::current_control`], from `Drive::tune_permitted`, i.e. within the first
/// millisecond of a [`crate::sim_drive::SimDrive`]; a bare `PlantAxis` never gets the
/// permission and keeps the gains from the true R and L), holding the motion layer
/// meanwhile; the "current does not follow" check runs in every PWM period.
///
/// Commutation: [`PlantAxis::new`] starts with the encoder's electrical offset known
/// (the rig's true offset, the motion layer aligned: the drive can be enabled at once);
/// [`PlantAxis::new_unaligned`] / [`PlantAxis::with_plant`] start as the board does
/// after power-up — offset unknown, the first closed-loop enable runs the commutation
/// alignment ([`firmware::commutation`]) whose offset goes into the rig's encoder;
/// until it is done [`AxisState::commutation_pending`] is reported and CiA 402 waits in
/// Switched on. Failed alignments are counted in [`Axis::commutation_failures`] (the
/// board's 1 ms tick raises 0x8611 for them; [`crate::sim_drive::SimDrive`] does too).
pub struct PlantAxis {
    /// Plant + current loop + encoder.
    pub rig: Rig,
    /// The firmware's motion layer with the commutation alignment (as on the board).
    pub motion: CommutatedMotion,
    /// The firmware's current-loop supervisor (power-up tune, follow check).
    pub supervisor: CurrentSupervisor,
    /// Switch positions (command units) and index phase.
    pub switches: Switches,
    /// Trip level of the power stage's over-current comparator (the board's break
    /// input), A, on the true phase current. Default: the drive's over-current limit
    /// (`firmware::faults::FaultConfig::default().over_current_ma`).
    pub trip_amps: f64,
    tripped: bool,
    motor: MotorConstants,
    wiggle: bool,
    reference: CurrentReference,
    cmd: DriveCommand,
    seen_cmd: DriveCommand,
    t_left: f64,
    theta0: f64,
    last_count: i64,
    index: Option<i32>,
    /// Sums of the current loop's v_dq / i_dq since the last servo period (the
    /// board's `ControlCore` passes their means to the motion layer).
    v_sum: Dq,
    i_sum: Dq,
    /// Servo points for the scope at the servo rate, `None` while not asked for.
    trace: Option<Vec<firmware::scope::ServoPoint>>,
    /// [`PlantAxis::set_rest_skip`].
    rest_skip: bool,
    /// Servo periods in a row at rest with the same state (noise aside), and that state.
    rest: (u32, Option<AxisState>),
}

/// Servo periods at rest with an unchanged state after which [`PlantAxis`] skips the
/// PWM periods (when allowed: [`PlantAxis::set_rest_skip`]): 1 ms.
pub const REST_PERIODS: u32 = 10;

impl PlantAxis {
    /// An axis of `motor` at rest, default vendor parameters, commutation aligned.
    pub fn new(motor: Motor) -> Self {
        Self::with_plant(motor, true, |_| {})
    }

    /// An axis of `motor` at rest, default vendor parameters, the encoder's electrical
    /// offset unknown ([`Rig::new_unaligned`]): the first closed-loop enable runs the
    /// power-up alignment.
    pub fn new_unaligned(motor: Motor) -> Self {
        Self::with_plant(motor, false, |_| {})
    }

    /// An axis of `motor` whose plant configuration `plant` may change (rotor angle
    /// `theta0`, a locked rotor, …) before the rig is built; `aligned`: as
    /// [`PlantAxis::new`] (offset known) or [`PlantAxis::new_unaligned`].
    pub fn with_plant(motor: Motor, aligned: bool, plant: impl FnOnce(&mut PlantConfig)) -> Self {
        let (params, consts) = match motor {
            Motor::Ecn57_20 => (ECN57_20, firmware::motion::ECN57_20),
            Motor::Tc86_45 => (TC86_45, firmware::motion::TC86_45),
        };
        let mut pc = PlantConfig::new(params);
        plant(&mut pc);
        let rig = if aligned {
            Rig::new(pc)
        } else {
            Rig::new_unaligned(pc)
        };
        let p = Params::new(Variant::HybridServo);
        let cfg = MotionConfig::from_params(&p, Variant::HybridServo, &consts, TS_SERVO);
        let wiggle = Self::wiggle(&p);
        let motion = if aligned {
            CommutatedMotion::new_aligned(cfg, wiggle)
        } else {
            CommutatedMotion::new(cfg, wiggle)
        };
        let theta0 = rig.plant.theta;
        let last = i64::from(rig.enc.position());
        let sup = SupervisorConfig::from_params(&p, TS, rig.plant.cfg.pwm_period);
        PlantAxis {
            rig,
            motion,
            wiggle,
            supervisor: CurrentSupervisor::new(sup),
            switches: Switches::default(),
            trip_amps: f64::from(firmware::faults::FaultConfig::default().over_current_ma) / 1000.0,
            tripped: false,
            motor: consts,
            reference: CurrentReference::OFF,
            cmd: DriveCommand::default(),
            seen_cmd: DriveCommand::default(),
            t_left: 0.0,
            theta0,
            last_count: last,
            index: None,
            v_sum: Dq::default(),
            i_sum: Dq::default(),
            trace: None,
            rest_skip: false,
            rest: (0, None),
        }
    }

    /// With `on`, [`Axis::advance`] skips the PWM periods while the axis rests
    /// ([`PlantAxis::resting`]): the drive asks for no power (command off, no power
    /// reference, no tune or phase check, no trip), the plant is at rest (no current,
    /// the rotor held), no scope trace is taken, and the axis state apart from the
    /// measured currents has stayed the same for [`REST_PERIODS`] servo periods.
    /// Nothing in the model would change then but the noise of the current sensors
    /// (the measured currents keep their last sample); the period counter moves on.
    /// What keeps an idle `virtual-drive` cheap. Off by default: the tests' runs keep
    /// every sample.
    pub fn set_rest_skip(&mut self, on: bool) {
        self.rest_skip = on;
        self.rest = (0, None);
    }

    /// The PWM periods are being skipped (see [`PlantAxis::set_rest_skip`]).
    pub fn resting(&self) -> bool {
        self.rest_skip
            && self.rest.0 >= REST_PERIODS
            && self.power_off()
            && self.rig.plant.at_rest()
    }

    /// Nothing asks for power: command off, no power reference, no tune or check, no
    /// trip, no scope trace.
    fn power_off(&self) -> bool {
        !self.reference.power
            && !self.cmd.power_stage
            && !self.cmd.drive_enabled
            && !self.supervisor.tuning()
            && !self.supervisor.tripped()
            && !self.tripped
            && self.trace.is_none()
    }

    /// At a servo period: counts the periods at rest with the same state, the
    /// measured currents and what follows from them aside.
    fn watch_rest(&mut self) {
        if !(self.power_off() && self.rig.plant.at_rest() && self.rig.enc.omega_e().abs() < 1e-3) {
            self.rest = (0, None);
            return;
        }
        let mut a = self.measured();
        (a.ia_ma, a.ib_ma, a.ia_set_ma, a.ib_set_ma) = (0, 0, 0, 0);
        (a.current_permille, a.torque_permille, a.load_angle_ddeg) = (0, 0, 0);
        let same = self.rest.1 == Some(a);
        self.rest = (
            if same {
                self.rest.0.saturating_add(1)
            } else {
                0
            },
            Some(a),
        );
    }

    /// 0x2083: the alignment sweeps the field and checks the encoder (as the board's
    /// `align_wiggle`).
    fn wiggle(p: &Params) -> bool {
        p.get(firmware::params::P::PowerUpWiggle) != 0
    }

    /// Where the commutation stands.
    pub fn commutation(&self) -> Commutation {
        self.motion.state()
    }

    /// The axis state the motion layer and the current loop have now (without the
    /// index latch, which [`Axis::state`] hands over once).
    fn measured(&self) -> AxisState {
        let cl = &self.rig.cl;
        let (angle, id, iq) = match self.reference.frame {
            Frame::Encoder => (self.rig.enc.electrical_angle(), cl.id_ref, cl.iq_ref),
            Frame::Command { angle, .. } => (angle, cl.id_ref, cl.iq_ref),
        };
        let (s, c) = (foc::trig::sin(angle), foc::trig::cos(angle));
        let set = inverse_park(Dq { d: id, q: iq }, s, c);
        let to_milliamps = |a: f32| (a * 1000.0).clamp(-32000.0, 32000.0) as i16;
        let mut a = AxisState {
            ia_ma: to_milliamps(cl.i_ab.alpha),
            ib_ma: to_milliamps(cl.i_ab.beta),
            ia_set_ma: to_milliamps(set.alpha),
            ib_set_ma: to_milliamps(set.beta),
            electrical_angle: (self.rig.enc.electrical_angle().0 >> 16) as u16,
            bus_mv: (self.rig.plant.cfg.vbus * 1000.0) as u32,
            overcurrent_trip: self.tripped,
            ..AxisState::default()
        };
        self.motion.motion().fill_axis_state(&mut a);
        self.motion.motion().fill_measured_torque(&mut a);
        a.commutation_pending = self.motion.enable_pending();
        a
    }

    /// Load torque opposing positive rotation, N·m.
    pub fn set_load(&mut self, torque: f64) {
        self.rig.plant.load = torque;
    }

    /// Fault injection: DC bus voltage of the plant, V (measured by the bus ADC and
    /// reported in [`AxisState::bus_mv`]; also the bridges' supply).
    pub fn set_bus_voltage(&mut self, volts: f64) {
        self.rig.plant.cfg.vbus = volts;
    }

    /// Fault injection: short circuit across the terminals of phase `phase` (0 = A,
    /// 1 = B) on or off (see [`crate::plant::motor::Plant::short`]).
    pub fn inject_phase_short(&mut self, phase: usize, on: bool) {
        if let Some(s) = self.rig.plant.short.get_mut(phase) {
            *s = on;
        }
    }

    /// Fault injection: phase `phase` (0 = A, 1 = B) open (no current) or connected.
    /// Opening interrupts the phase current at once.
    pub fn open_phase(&mut self, phase: usize, open: bool) {
        if open {
            match phase {
                0 => self.rig.plant.ia = 0.0,
                1 => self.rig.plant.ib = 0.0,
                _ => {}
            }
        }
        if let Some(r) = self.rig.plant.cfg.r_scale.get_mut(phase) {
            *r = if open {
                crate::plant::motor::OPEN_SCALE
            } else {
                1.0
            };
        }
    }

    /// Fault injection: the encoder signals are lost, the counter stops where it is.
    pub fn lose_encoder(&mut self) {
        let p = &mut self.rig.plant;
        p.encoder_frozen = Some(p.encoder_raw());
    }

    /// Fault injection: the current sensor of phase `phase` (0 = A, 1 = B) reads the
    /// ADC value `counts` whatever the current (`None`: healthy again).
    pub fn stick_current_sensor(&mut self, phase: usize, counts: Option<u16>) {
        if let Some(s) = self.rig.plant.adc_stuck.get_mut(phase) {
            *s = counts;
        }
    }

    /// Fault injection: zero-current error of the current sensors (A, B), ADC counts.
    pub fn set_adc_offset_error(&mut self, counts: [f64; 2]) {
        self.rig.plant.adc_offset_error = counts;
    }

    /// The over-current comparator tripped and the bridges are off (the break latch;
    /// re-armed once the drive has withdrawn the power permission and the currents are
    /// below the trip level, as the board's `over_current` does).
    pub fn tripped(&self) -> bool {
        self.tripped
    }

    /// True shaft position in command units (axis direction).
    pub fn true_position(&self) -> f64 {
        let dir = if self.motion.config().reverse {
            -1.0
        } else {
            1.0
        };
        dir * (self.rig.plant.theta - self.theta0) / (2.0 * std::f64::consts::PI)
            * f64::from(self.motion.config().pulses_per_rev)
    }

    fn feedback(&mut self) -> Feedback {
        let k = 1.0 / SERVO_DIV as f32;
        let mean = |x: Dq| Dq {
            d: x.d * k,
            q: x.q * k,
        };
        let fb = Feedback {
            position: self.rig.enc.position(),
            velocity: self.rig.enc.velocity(),
            electrical_angle: self.rig.enc.electrical_angle(),
            voltage_limited: self.rig.cl.saturated,
            v_dq: mean(self.v_sum),
            i_dq: mean(self.i_sum),
        };
        self.v_sum = Dq::default();
        self.i_sum = Dq::default();
        fb
    }

    fn units_of_count(&self, n: i64) -> i32 {
        let c = self.motion.config();
        let (u, k) = (
            i64::from(c.pulses_per_rev.max(1)),
            i64::from(c.counts_per_rev.max(1)),
        );
        (2 * n * u + k).div_euclid(2 * k) as i32
    }

    /// One PWM period (25 µs), in the board's order: the motion layer every
    /// [`SERVO_DIV`]-th period, the bridge decision and the current loop, the
    /// period's sums for the servo step, the over-current comparator, the index pulse.
    fn tick(&mut self) {
        if self.rig.k.is_multiple_of(SERVO_DIV) {
            self.servo_step();
        }
        let r = self.reference;
        self.current_loop(r);
        self.sum_period();
        self.protect(r);
        self.index_pulse();
    }

    /// The servo period: the motion layer's step (held while the current loop is
    /// tuned) on the means of the last PWM periods, its reference to the current loop.
    fn servo_step(&mut self) {
        let fb = self.feedback();
        let step = if self.supervisor.tuning() {
            self.motion.step_held(&fb)
        } else {
            self.motion.step(&fb, self.rig.enc.raw_electrical_angle())
        };
        if let Some(offset) = step.offset {
            self.rig.enc.set_electrical_offset(offset);
        }
        self.reference = step.reference;
        self.supervisor.request_power(self.reference.power);
        if self.reference.reset {
            self.rig.cl.reset();
        }
        self.rig.cl.id_ref = self.reference.id;
        self.rig.cl.iq_ref = self.reference.iq;
        if self.trace.is_some() {
            let p = firmware::scope::ServoPoint::of(&self.measured());
            self.trace.get_or_insert_with(Vec::new).push(p);
        }
        if self.rest_skip {
            self.watch_rest();
        }
    }

    /// The board's bridge decision and one current-loop period on reference `r`,
    /// with the fast protection of the current-loop interrupt.
    fn current_loop(&mut self, r: CurrentReference) {
        let period = self.rig.plant.cfg.pwm_period;
        let break_latched = self.tripped;
        let sup = &mut self.supervisor;
        if !r.power {
            // The drive no longer asks for power: a trip of the fast protection ends.
            sup.rearm();
        }
        // The board's bridge decision. The drive's power permission reaches the plant
        // as the motion layer's power request (the command's `drive_enabled` is masked
        // by it, `firmware::board_glue::BoardGlue::publish`); nothing halts the plant.
        let mode = bridge_mode(GateInputs {
            halted: false,
            break_latched,
            tripped: sup.tripped(),
            tuning: sup.tuning(),
            permitted: true,
            power_wanted: r.power,
        });
        self.rig.tick_with(|cl, enc, adc| {
            let d = match mode {
                BridgeMode::Tune => sup.tune_step(cl, adc),
                BridgeMode::Off => {
                    sup.idle();
                    cl.id_ref = 0.0;
                    cl.iq_ref = 0.0;
                    // Measures the currents, applies 0 V (50 % on every leg), clears
                    // the PIs.
                    let _ = cl.voltage_step(adc, 0.0, 0.0);
                    Duties::zero(period)
                }
                BridgeMode::Run => match r.frame {
                    // The count's angle and the PLL speed, the decoupling on the
                    // references. The board (`firmware::control_core`) and the
                    // control-quality rig commutate on the commutation tracker with the
                    // measured-current decoupling; on this axis that leaves a free
                    // shaft's CST torque step 9 % short after 1 ms (the tracker's speed
                    // lags the step of acceleration in the back-EMF feed-forward): open.
                    Frame::Encoder => sup.run_step(cl, adc, enc.electrical_angle(), enc.omega_e()),
                    Frame::Command { angle, omega_e } => sup.run_step(cl, adc, angle, omega_e),
                },
            };
            // The fast protection (as the board's current-loop interrupt): bridges
            // off in this period.
            if sup.protect(cl) {
                Duties::zero(period)
            } else {
                d
            }
        });
    }

    /// The period's v_dq / i_dq added to the sums the next servo step takes the
    /// means of ([`PlantAxis::feedback`]).
    fn sum_period(&mut self) {
        let cl = &self.rig.cl;
        self.v_sum.d += cl.v_dq.d;
        self.v_sum.q += cl.v_dq.q;
        self.i_sum.d += cl.i_dq.d;
        self.i_sum.q += cl.i_dq.q;
    }

    /// Over-current comparator → break input: every switch off at once (the board's
    /// timer break acts within the PWM period); re-armed when the drive no longer
    /// asks for power (`r`) and the currents are below the trip level.
    fn protect(&mut self, r: CurrentReference) {
        let peak = self.rig.plant.ia.abs().max(self.rig.plant.ib.abs());
        if peak > self.trip_amps {
            self.tripped = true;
        } else if self.tripped && !r.power {
            self.tripped = false;
        }
        self.rig.plant.bridges_off = self.tripped || self.supervisor.tripped();
    }

    /// Index pulse: axis count ≡ phase (mod counts per revolution).
    fn index_pulse(&mut self) {
        let c = self.motion.config();
        let cpr = i64::from(c.counts_per_rev.max(1));
        let dir = if c.reverse { -1 } else { 1 };
        let phase = (self.switches.index_phase * cpr as f64 / f64::from(c.pulses_per_rev.max(1)))
            .round() as i64;
        let now = dir * i64::from(self.rig.enc.position());
        let prev = self.last_count;
        if now != prev {
            let rev = |n: i64| (n - phase).div_euclid(cpr);
            if rev(now) != rev(prev) {
                let k = rev(now).max(rev(prev));
                self.index = Some(self.units_of_count(k * cpr + phase));
            }
            self.last_count = now;
        }
    }
}

impl Axis for PlantAxis {
    fn advance(&mut self, dt_s: f64, cmd: &DriveCommand) {
        if *cmd != self.seen_cmd {
            // A command that did not come through `command` (e.g. shutdown).
            self.seen_cmd = *cmd;
            self.cmd = *cmd;
            self.motion.set_command(cmd, 1e-3);
            self.rest = (0, None);
        }
        self.t_left += dt_s;
        let ts = f64::from(TS);
        if self.resting() {
            // Whole PWM periods skipped (`set_rest_skip`): the plant's and the
            // periods' clocks move on, nothing else would change.
            let n = (self.t_left / ts + 0.001).floor().max(0.0);
            self.t_left -= n * ts;
            self.rig.k += n as u64;
            self.rig.plant.time += n * self.rig.plant.cfg.ts;
            return;
        }
        while self.t_left >= ts * 0.999 {
            self.t_left -= ts;
            self.tick();
        }
    }

    fn command(&mut self, cmd: &DriveCommand, cycle_s: f64) {
        if *cmd != self.cmd {
            self.rest = (0, None);
        }
        self.seen_cmd = *cmd;
        self.cmd = *cmd;
        self.motion.set_command(cmd, cycle_s as f32);
    }

    fn skip_rest(&mut self, on: bool) {
        self.set_rest_skip(on);
    }

    fn resting(&self) -> bool {
        PlantAxis::resting(self)
    }

    fn parameters(&mut self, p: &Params) {
        let cfg = MotionConfig::from_params(p, Variant::HybridServo, &self.motor, TS_SERVO);
        let wiggle = Self::wiggle(p);
        if cfg != *self.motion.config() || wiggle != self.wiggle {
            self.wiggle = wiggle;
            self.motion.configure(cfg, wiggle);
            self.rest = (0, None);
        }
        let sup = SupervisorConfig::from_params(p, TS, self.rig.plant.cfg.pwm_period);
        if sup != *self.supervisor.config() {
            self.supervisor.configure(sup);
            self.rest = (0, None);
        }
    }

    fn current_control(&mut self, tune_permitted: bool) -> CurrentReport {
        self.supervisor.permit_tune(tune_permitted);
        self.supervisor.report()
    }

    fn state(&mut self) -> AxisState {
        let mut a = self.measured();
        a.index = self.index.take();
        a
    }

    fn servo_points(&mut self, on: bool, out: &mut Vec<firmware::scope::ServoPoint>) {
        if let Some(v) = self.trace.as_mut() {
            out.append(v);
        }
        self.trace = on.then(|| self.trace.take().unwrap_or_default());
    }

    fn commutation_failures(&self) -> u32 {
        self.motion.failures()
    }

    /// The electrical plant models every kind.
    fn inject(&mut self, fault: InjectedFault) -> bool {
        self.rest = (0, None);
        match fault {
            InjectedFault::OpenPhaseA => self.open_phase(0, true),
            InjectedFault::OpenPhaseB => self.open_phase(1, true),
            InjectedFault::PhaseShort => self.inject_phase_short(0, true),
            InjectedFault::BusOvervoltage => {
                self.set_bus_voltage(crate::fault_inject::OVERVOLTAGE_V)
            }
            InjectedFault::BusUndervoltage => {
                self.set_bus_voltage(crate::fault_inject::UNDERVOLTAGE_V)
            }
            InjectedFault::EncoderLoss => self.lose_encoder(),
        }
        true
    }

    fn true_position(&self) -> Option<f64> {
        Some(PlantAxis::true_position(self))
    }

    fn raw_inputs(&self) -> u8 {
        let s = &self.switches;
        let pos = PlantAxis::true_position(self);
        let mut raw = 0u8;
        if (s.home.0..=s.home.1).contains(&pos) {
            raw |= 1;
        }
        if pos <= s.limit_neg {
            raw |= 2;
        }
        if pos >= s.limit_pos {
            raw |= 4;
        }
        raw
    }
}

/// A [`PlantAxis`] shared between a [`crate::sim_drive::SimDrive`] (as its
/// `Box<dyn Axis>`) and a test that injects faults into the plant or reads it.
pub struct SharedPlant(pub std::rc::Rc<std::cell::RefCell<PlantAxis>>);

impl Axis for SharedPlant {
    fn advance(&mut self, dt_s: f64, cmd: &DriveCommand) {
        self.0.borrow_mut().advance(dt_s, cmd)
    }
    fn state(&mut self) -> AxisState {
        self.0.borrow_mut().state()
    }
    fn raw_inputs(&self) -> u8 {
        self.0.borrow().raw_inputs()
    }
    fn command(&mut self, cmd: &DriveCommand, cycle_s: f64) {
        self.0.borrow_mut().command(cmd, cycle_s)
    }
    fn parameters(&mut self, p: &Params) {
        self.0.borrow_mut().parameters(p)
    }
    fn true_position(&self) -> Option<f64> {
        Axis::true_position(&*self.0.borrow())
    }
    fn servo_points(&mut self, on: bool, out: &mut Vec<firmware::scope::ServoPoint>) {
        self.0.borrow_mut().servo_points(on, out)
    }
    fn current_control(&mut self, tune_permitted: bool) -> CurrentReport {
        self.0.borrow_mut().current_control(tune_permitted)
    }
    fn commutation_failures(&self) -> u32 {
        self.0.borrow().commutation_failures()
    }
    fn inject(&mut self, fault: InjectedFault) -> bool {
        self.0.borrow_mut().inject(fault)
    }
    fn skip_rest(&mut self, on: bool) {
        self.0.borrow_mut().set_rest_skip(on)
    }
    fn resting(&self) -> bool {
        self.0.borrow().resting()
    }
}
