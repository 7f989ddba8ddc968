//! Torque control of the motion layer (CiA 402 CST, closed loop) and the measured
//! torque.
//!
//! # Torque demand → q current
//! The rated torque (0x6076) is the torque constant times the rated current, and the
//! rated current (0x6075) is the peak current 0x2000 on q, so a torque of `T` per
//! mille of the rated torque is the q current
//!
//! ```text
//! i_q* = T/1000 · I_peak          (A; Kt cancels: T/T_rated = i_q/I_rated)
//! ```
//!
//! limited to ±(0x6072, 0x6073, soft start) as in the other modes, with the speed
//! limit of the command (0x6080, command units/s → counts/s) applied by
//! [`foc::servo::Servo::step_torque`]: past it the velocity loop takes torque off.
//! The detent torque of the motor is not modelled: at constant q current the shaft
//! torque carries it (the plant's `Td·sin(4θe)`), as every FOC drive's does.
//!
//! The position demand rests on the actual position each period (as with velocity
//! set-points): a switch to position or velocity set-points starts at the actual
//! position with the velocity integrator holding the current applied last, so the
//! current reference does not jump (`foc::servo`, "Torque control with a speed
//! limit").
//!
//! # Measured torque (0x6077)
//! The phase currents `(i_A, i_B)` are the α/β currents of the two-phase machine; on
//! the encoder's electrical angle θe the torque-producing current is the Park
//! q component `i_q = i_B·cos θe − i_A·sin θe` (motor direction), reported in the axis
//! direction per mille of the peak current. Without an encoder there is no rotor
//! angle: 0.

use super::{clampf, Motion};
use crate::motion::AxisState;

impl Motion {
    /// One closed-loop servo period with a torque set-point: the rest of the position
    /// demand at `pos` (axis counts) and the q current (A, axis direction) of the
    /// demand with the speed limit, against the velocity `vel` (axis counts/s).
    pub(super) fn torque_step(&mut self, pos: i32, vel: f32) -> f32 {
        self.rest_at(pos);
        self.velocity_lag = 0.0;
        self.following_error = 0.0;
        let demand = self.cmd.torque as f32 * self.iq_per_permille;
        let v_max = self.cmd.velocity * self.scale.counts_per_unit();
        self.servo.step_torque(demand, v_max, vel)
    }

    /// The speed limit of torque control took torque off in the last period.
    pub(super) fn speed_limited(&self) -> bool {
        self.cmd.kind == crate::cia402::SetpointKind::Torque
            && self.enabled
            && self.cfg.closed_loop
            && self.servo.speed_limited
    }

    /// Writes the measured torque into `a.torque_permille` from the phase currents
    /// already in `a` (`ia_ma`, `ib_ma`) and the encoder's electrical angle of the last
    /// period (see the module docs).
    pub fn fill_measured_torque(&self, a: &mut AxisState) {
        let peak = self.cfg.peak_current;
        if self.cfg.counts_per_rev == 0 || peak <= 0.0 {
            a.torque_permille = 0;
            return;
        }
        let theta = self.last_fb.electrical_angle;
        let (s, c) = (foc::trig::sin(theta), foc::trig::cos(theta));
        let (ia, ib) = (f32::from(a.ia_ma) * 1e-3, f32::from(a.ib_ma) * 1e-3);
        let iq = self.dir as f32 * (ib * c - ia * s);
        a.torque_permille = clampf(iq / peak * 1000.0, -32000.0, 32000.0) as i16;
    }
}
