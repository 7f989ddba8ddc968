//! The motion layer's open-loop stall detection and its settings (see [`Stall`]).

use super::{clampf, Feedback, MotorConstants};
use crate::params::{Param, Params};
use foc::stall::{StallConfig, StallDetector, StallState};

/// The stall detector's settings: 0x2061 % as the threshold, the motor model from
/// 0x2020 / 0x2021 once 0x2021 holds a plausible inductance (≥ 100 µH, as after an
/// auto-tune; the rule of `control_core::LoopMotor::from_params`), else the
/// board motor's.
pub(super) fn config_from_params(
    p: &Params,
    motor: &MotorConstants,
    ts: f32,
) -> Option<StallConfig> {
    if p.get(Param::StallEnable) == 0 {
        return None;
    }
    let l_uh = p.get(Param::MotorInductance);
    let (r, l) = if l_uh >= 100 {
        (
            p.get(Param::MotorResistance).max(1) as f32 * 1e-3,
            l_uh as f32 * 1e-6,
        )
    } else {
        (motor.resistance, motor.inductance)
    };
    Some(StallConfig {
        ts,
        r,
        l,
        ke: motor.kt,
        threshold: p.get(Param::StallSensitivity) as f32 * 0.01,
    })
}

/// The open-loop stall detection of the motion layer: [`foc::stall`] on the current
/// loop's period means and the command speed, once per servo period while the open
/// loop drives. A confirmed stall is an event: [`Stall::seq`] moves and
/// [`Stall::position`] is the command position (axis units) at which the in-phase
/// back-EMF first fell below the threshold — where the rotor met the obstacle (the
/// stop position of stall homing). From then on the field is **held** there
/// ([`Stall::hold`]) until the demand comes back to that position or the drive is
/// disabled: a field running on past a blocked rotor pulls it back once the load
/// angle passes 180° and may leave it a whole electrical period (4 full steps) off;
/// held, the rotor stays pressed against the obstacle whatever the drive's reaction
/// (fault ramp, quick stop, stall homing's return) does with the demand meanwhile.
#[derive(Debug, Clone)]
pub(super) struct Stall {
    det: StallDetector,
    /// Command position at the detector's last onset (`StallDetector::onset`).
    onset: i32,
    pub(super) seq: u32,
    pub(super) position: i32,
    hold: Option<i32>,
}

impl Stall {
    pub(super) fn new(cfg: Option<StallConfig>, ts: f32) -> Self {
        let off = StallConfig {
            ts,
            r: 0.0,
            l: 0.0,
            ke: 0.0,
            threshold: 0.0,
        };
        Stall {
            det: StallDetector::new(cfg.unwrap_or(off)),
            onset: 0,
            seq: 0,
            position: 0,
            hold: None,
        }
    }

    /// Forgets the detector's state and any hold (enable, new settings).
    pub(super) fn reset(&mut self) {
        self.det.reset();
        self.hold = None;
    }

    /// The command position to drive for the demand `p`: the held stall position
    /// while a hold lasts (released when the demand reaches it).
    pub(super) fn command(&mut self, p: i32) -> i32 {
        match self.hold {
            Some(h) => {
                if p == h {
                    self.hold = None;
                }
                h
            }
            None => p,
        }
    }

    pub(super) fn configure(&mut self, cfg: Option<StallConfig>) {
        if let Some(c) = cfg {
            self.det.configure(c);
        }
        self.reset();
    }

    /// One servo period at the axis command position `pos`; the current loop frame
    /// turns at `omega_e` (motor direction).
    pub(super) fn step(&mut self, fb: &Feedback, omega_e: f32, pos: i32) {
        let before = self.det.state();
        let state = self.det.step(fb.v_dq, fb.i_dq, omega_e);
        if self.det.onset() {
            self.onset = pos;
        }
        match state {
            StallState::Stalled if before != StallState::Stalled => {
                self.seq = self.seq.wrapping_add(1);
                self.position = self.onset;
                self.hold = Some(self.onset);
            }
            // After the reaction has slowed the command below the detection speed the
            // detector starts over.
            StallState::Stalled if omega_e == 0.0 => self.det.reset(),
            _ => {}
        }
    }

    /// Estimated load angle, 0.1° electrical (0 while inactive).
    pub(super) fn load_angle_ddeg(&self) -> i16 {
        match self.det.state() {
            StallState::Inactive => 0,
            _ => clampf(
                self.det.load_angle() * (1800.0 / core::f32::consts::PI),
                -1800.0,
                1800.0,
            ) as i16,
        }
    }
}
