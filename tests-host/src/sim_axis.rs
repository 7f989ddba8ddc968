//! Simulated axes for [`crate::sim_drive`].
//!
//! [`KinematicAxis`] follows the drive's set-points with the dynamics of a well-tuned
//! servo (a critically damped second-order lag of configurable bandwidth, velocity
//! and acceleration limits of the motor), quantised to the encoder, with a home switch,
//! two limit switches and an index pulse once per revolution placed on the shaft.
//! It is cheap enough for 64 drives in real time.
//!
//! [`PlantAxis`] is the full electrical axis: the plant of [`crate::plant`] with the
//! `foc` current loop and encoder at 40 kHz and the firmware's motion layer
//! ([`firmware::motion`], behind the board's commutation wrapper
//! [`firmware::commutation`]) at 10 kHz. [`AxisModel`] chooses between them; the rule for
//! [`AxisModel::Auto`] is [`PLANT_MAX_DRIVES`].

use crate::fault_inject::InjectedFault;
use crate::sim_drive::{Axis, Motor};
use firmware::cia402::{DriveCommand, SetpointKind};
use firmware::drive::AxisState;

/// Command units per revolution (0x2001 default).
pub const UNITS_PER_REV: f64 = 50_000.0;
/// Encoder counts per revolution (0x2029 default × 4).
pub const COUNTS_PER_REV: f64 = 4_000.0;

/// Where the switches sit on the shaft, in command units (active while the position
/// is inside the window / beyond the limit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Switches {
    /// Home switch active from `home.0` to `home.1`.
    pub home: (f64, f64),
    /// Negative limit active at or below this position.
    pub limit_neg: f64,
    /// Positive limit active at or above this position.
    pub limit_pos: f64,
    /// Index pulse position within a revolution (command units).
    pub index_phase: f64,
}

impl Default for Switches {
    fn default() -> Self {
        Switches {
            home: (20_000.0, 30_000.0),
            limit_neg: -200_000.0,
            limit_pos: 200_000.0,
            index_phase: 1_250.0,
        }
    }
}

/// A servo axis at the kinematic level.
pub struct KinematicAxis {
    /// Position, command units.
    pub pos: f64,
    /// Velocity, command units/s.
    pub vel: f64,
    /// Natural frequency of the position loop, rad/s.
    pub omega: f64,
    /// Acceleration limit, command units/s².
    pub acc_max: f64,
    /// Switch positions.
    pub switches: Switches,
    /// Bus voltage, mV.
    pub bus_mv: u32,
    /// Peak current, mA (0x2000), for the current read-back.
    pub peak_ma: f64,
    /// Index latch since the last `state()`.
    index: Option<i32>,
    enabled: bool,
    demand: f64,
    accel: f64,
}

impl KinematicAxis {
    /// An axis of `motor` (its inertia sets the acceleration limit) at position 0.
    pub fn new(motor: Motor) -> Self {
        let acc_rev = match motor {
            Motor::Ecn57_20 => 400.0,
            Motor::Tc86_45 => 250.0,
        };
        KinematicAxis {
            pos: 0.0,
            vel: 0.0,
            omega: 2.0 * std::f64::consts::PI * 40.0,
            acc_max: acc_rev * UNITS_PER_REV,
            switches: Switches::default(),
            bus_mv: 48_000,
            peak_ma: 3200.0,
            index: None,
            enabled: false,
            demand: 0.0,
            accel: 0.0,
        }
    }

    fn encoder_units(&self) -> i32 {
        let counts = (self.pos / UNITS_PER_REV * COUNTS_PER_REV).floor();
        (counts * UNITS_PER_REV / COUNTS_PER_REV).round() as i32
    }
}

impl Axis for KinematicAxis {
    fn advance(&mut self, dt_s: f64, cmd: &DriveCommand) {
        self.enabled = cmd.drive_enabled;
        let steps = (dt_s / 50e-6).ceil().max(1.0) as usize;
        let h = dt_s / steps as f64;
        if !self.enabled {
            // Motor not controlled: friction brings it to rest, the holding brake
            // (engaged unless the drive releases it) within a few milliseconds.
            let tau = if cmd.brake_release { 0.05 } else { 0.005 };
            for _ in 0..steps {
                self.vel *= (-h / tau).exp();
                self.pos += self.vel * h;
            }
            self.demand = self.pos;
            self.accel = 0.0;
            return;
        }
        let ff = f64::from(cmd.velocity);
        for _ in 0..steps {
            let before = self.pos;
            let acc = match cmd.kind {
                SetpointKind::Position => {
                    self.demand = f64::from(cmd.position);
                    self.omega * self.omega * (self.demand - self.pos)
                        + 2.0 * self.omega * (ff - self.vel)
                }
                SetpointKind::Velocity => 4.0 * self.omega * (ff - self.vel),
                // No motion layer here to run the tune's move: the axis holds (the
                // drive's tune fails for want of a run).
                SetpointKind::Tune => -2.0 * self.omega * self.vel,
                SetpointKind::Torque => {
                    // The torque's acceleration (rated torque = the acceleration
                    // limit), the speed limit `ff` held by a velocity loop past it.
                    self.demand = self.pos;
                    let a = f64::from(cmd.torque) * 1e-3 * self.acc_max;
                    let lim = a.signum() * ff.abs();
                    if self.vel * a.signum() >= ff.abs() {
                        (4.0 * self.omega * (lim - self.vel)).clamp(-a.abs(), a.abs())
                    } else {
                        a
                    }
                }
            };
            self.accel = acc.clamp(-self.acc_max, self.acc_max);
            self.vel += self.accel * h;
            self.pos += self.vel * h;
            // Index pulse once per revolution.
            let rev = |p: f64| ((p - self.switches.index_phase) / UNITS_PER_REV).floor();
            if rev(before) != rev(self.pos) {
                let k = rev(before).max(rev(self.pos));
                self.index = Some((k * UNITS_PER_REV + self.switches.index_phase).round() as i32);
            }
        }
    }

    fn state(&mut self) -> AxisState {
        let current = if self.enabled {
            (self.accel / self.acc_max).abs().min(1.0) * 1000.0
        } else {
            0.0
        };
        let ia = (current * self.peak_ma / 1000.0) as i16;
        AxisState {
            position: self.encoder_units(),
            velocity: self.vel.round() as i32,
            ia_ma: ia,
            ib_ma: 0,
            ia_set_ma: ia,
            ib_set_ma: 0,
            current_permille: current as i16,
            torque_permille: current as i16,
            electrical_angle: ((self.pos / UNITS_PER_REV * 50.0).fract() * 65536.0) as u16,
            bus_mv: self.bus_mv,
            index: self.index.take(),
            probe1: Default::default(),
            probe2: Default::default(),
            overcurrent_trip: false,
            current_limited: self.accel.abs() >= self.acc_max,
            servo_following_error: ((self.demand - self.pos) / UNITS_PER_REV * COUNTS_PER_REV)
                .round() as i32,
            commutation_pending: false,
            ..AxisState::default()
        }
    }

    fn true_position(&self) -> Option<f64> {
        Some(self.pos)
    }

    /// Not controlled and (practically) still.
    fn resting(&self) -> bool {
        !self.enabled && self.vel.abs() < 1e-3
    }

    /// The kinematic model has a bus voltage but no phases.
    fn inject(&mut self, fault: InjectedFault) -> bool {
        let v = match fault {
            InjectedFault::BusOvervoltage => crate::fault_inject::OVERVOLTAGE_V,
            InjectedFault::BusUndervoltage => crate::fault_inject::UNDERVOLTAGE_V,
            _ => return false,
        };
        self.bus_mv = (v * 1000.0) as u32;
        true
    }

    fn raw_inputs(&self) -> u8 {
        // Default input functions (0x2152): IN1 home, IN2 limit−, IN3 limit+.
        let s = &self.switches;
        let mut raw = 0u8;
        if (s.home.0..=s.home.1).contains(&self.pos) {
            raw |= 1;
        }
        if self.pos <= s.limit_neg {
            raw |= 2;
        }
        if self.pos >= s.limit_pos {
            raw |= 4;
        }
        raw
    }
}

/// The axis model used by `virtual-drive` and the demo.
pub fn boxed(motor: Motor) -> Box<dyn Axis> {
    Box::new(KinematicAxis::new(motor))
}

/// Which axis model a simulated drive uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AxisModel {
    /// [`PlantAxis`] for small segments, [`KinematicAxis`] for large ones (see
    /// [`AxisModel::resolve`]).
    #[default]
    Auto,
    /// The electrical plant with the firmware's motion layer and the FOC current loop.
    Plant,
    /// The cheap kinematic model.
    Kinematic,
}

/// Largest segment that [`AxisModel::Auto`] simulates with [`PlantAxis`].
///
/// Measured with `cargo test [--release] -p tests-host --test drive_e2e
/// plant_axis_real_time_factor -- --nocapture` (ECN57-20, holding position): one
/// `PlantAxis` simulates ≈ 26 s per wall second, in a release build and in the test
/// profile alike (≈ 6 s while parallel builds load the 2-core machine). Four drives
/// therefore need about 15 % of a core and stay in real time even on a loaded machine;
/// larger segments (up to the 64+ drives of `virtual-drive`) use [`KinematicAxis`].
pub const PLANT_MAX_DRIVES: usize = 4;

impl AxisModel {
    /// The model used for a segment of `n` drives: `Auto` is `Plant` for
    /// `n ≤ PLANT_MAX_DRIVES`, else `Kinematic`.
    pub fn resolve(self, n: usize) -> AxisModel {
        match self {
            AxisModel::Auto if n <= PLANT_MAX_DRIVES => AxisModel::Plant,
            AxisModel::Auto => AxisModel::Kinematic,
            m => m,
        }
    }
}

/// The axis model `model` (resolved for a segment of `n` drives) for `motor`.
pub fn boxed_model(motor: Motor, model: AxisModel, n: usize) -> Box<dyn Axis> {
    match model.resolve(n) {
        AxisModel::Plant => Box::new(PlantAxis::new(motor)),
        _ => Box::new(KinematicAxis::new(motor)),
    }
}

mod plant_axis;
pub use plant_axis::{PlantAxis, SharedPlant, REST_PERIODS};
