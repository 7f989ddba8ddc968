//! Closed-loop (hybrid servo) position and velocity control, set-point
//! interpolation, following-error supervision and power-up angle alignment.
//!
//! Cascade, all positions in encoder counts, velocities in counts/s:
//!
//! ```text
//! e     = x* − x
//! v_cmd = ff_v·v* + Kp·e + Ki·∫e                          (position loop)
//! i_q*  = PI_v(v_cmd − v̂) + K_a·a*                       (velocity loop + acc. FF)
//! ```
//!
//! `v̂` is the encoder PLL velocity, `K_a = J/Kt · 2π/cpr` (A per count/s²) turns the
//! demanded acceleration into the current that produces it. The velocity PI's
//! integrator also cancels load torque, so the cascade has no steady-state position
//! error under constant load.
//!
//! Tuning by [`ServoGains::from_bandwidth`]: with `b = Kt·cpr/(2π·J)` (counts/s² per
//! A) the velocity loop gain `Kv = ωv/b` gives a velocity bandwidth ωv; the velocity
//! PI zero sits at ωv/4 and the position gain is ωv/4 as well. For the plant `b/s²`
//! the characteristic polynomial is `s³ + ωv·s² + ½ωv²·s + ωv³/16`, roots
//! ≈ −0.18ωv and −0.41ωv ± 0.43jωv (ζ ≈ 0.69). The real drive adds the encoder PLL
//! lag, the current loop and the servo period; in the plant simulation the loop stays
//! well damped up to ωv ≈ 2π·300 Hz with a PLL of ω = 8000 rad/s (250 Hz is the
//! scenarios' choice).
//!
//! # Torque control with a speed limit ([`Servo::step_torque`])
//! In torque mode the q-current reference is the demand `i_t` (A) itself; the only
//! loop left is a speed limit `v_max` (counts/s, ≥ 0) in the direction of the demand,
//! `s = sgn(i_t)` (`+1` for 0). The velocity PI (same gains) runs on the speed margin
//! with its output range narrowed to the demand ([`crate::pi::Pi::update_within`]):
//!
//! ```text
//! e    = s·v_max − v̂                              (margin to the limit, sign of s)
//! i_q* = clamp(Kv·e + x, −i_max, i_t)   for s = +1
//! i_q* = clamp(Kv·e + x, i_t, +i_max)   for s = −1
//! x   ← x + Ki·Ts·e, kept inside the same range
//! ```
//!
//! This is a speed controller on `s·v_max` whose output may never pass the demand
//! (the clamp is its anti-windup: the integrator stops while the output sits at
//! `i_t` and the margin pushes further). Far below the limit `Kv·e` holds the output
//! at `i_t` exactly (no effect). Approaching the limit the proportional term takes
//! torque off once `Kv·e + x < i_t`, and the integrator brings the speed to `v_max`
//! with no steady-state error: the velocity loop's dynamics (its bandwidth and
//! damping as above). A shaft held below the limit by its load ends with the output
//! at `i_t` (the integrator rises until `Kv·e + x ≥ i_t`). How early the torque comes
//! off depends on `x` (the current that held the limit last time, or what the
//! previous mode left): taking the whole demand off needs a margin of
//! `(x − i_t)/Kv`, so a shaft that reaches the limit at full acceleration may
//! overshoot it by up to `i_t/Kv` (1 rev/s for 1.6 A on the ECN57-20 at 240 Hz)
//! before the integrator brings it back. A shaft driven past the limit by its load is
//! braked (down to `−i_max` against it). The integrator is not the applied current
//! while the output sits at the demand: a switch to [`Servo::step`] /
//! [`Servo::step_velocity`] afterwards is bumpless after [`Servo::bumpless_start`]
//! with [`Servo::iq_ref`].

use crate::angle::Angle;
use crate::pi::Pi;
use core::f32::consts::PI;

/// Servo gains in physical units (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServoGains {
    /// Position proportional gain, 1/s.
    pub kp_pos: f32,
    /// Position integral gain, 1/s².
    pub ki_pos: f32,
    /// Velocity feed-forward, fraction (1.0 = full).
    pub vel_ff: f32,
    /// Velocity proportional gain, A per count/s.
    pub kv: f32,
    /// Velocity integral gain, A per count.
    pub ki_vel: f32,
    /// Acceleration feed-forward, A per count/s².
    pub acc_ff: f32,
    /// Current limit, A.
    pub iq_max: f32,
}

impl ServoGains {
    /// Gains for velocity-loop bandwidth `bw_hz` on a motor with inertia `j` (kg·m²,
    /// motor + load), torque constant `kt` (N·m/A), encoder `cpr` counts/rev, current
    /// limit `iq_max` (A). Full velocity and acceleration feed-forward.
    pub fn from_bandwidth(j: f32, kt: f32, cpr: u32, bw_hz: f32, iq_max: f32) -> Self {
        let b = kt * cpr as f32 / (2.0 * PI * j);
        let wv = 2.0 * PI * bw_hz;
        let kv = wv / b;
        ServoGains {
            kp_pos: wv * 0.25,
            ki_pos: 0.0,
            vel_ff: 1.0,
            kv,
            ki_vel: kv * wv * 0.25,
            acc_ff: 1.0 / b,
            iq_max,
        }
    }
}

impl ServoGains {
    /// The drive's integer servo parameters applied to these base gains (our
    /// definition of their scaling; 100 = the base value):
    /// * `kp` (0x2137): position gain `kp_pos·kp/100`;
    /// * `ki` (0x2138): position integral `ki_pos = (kp_pos_base)²/10 · ki/100`
    ///   (at 100 its corner is a tenth of the base position bandwidth);
    /// * `ff` (0x2139): velocity feed-forward `ff/100` (70 = 0.7);
    /// * `kv` (0x2140): velocity loop `kv·kv/100`, `ki_vel·(kv/100)²` (scales the
    ///   velocity bandwidth with the same damping).
    ///
    /// Values above 150 (the parameters' range) are clamped to 150.
    pub fn scaled(&self, kp: u16, ki: u16, ff: u16, kv: u16) -> Self {
        let f = |x: u16| x.min(150) as f32 * 0.01;
        let kvs = f(kv);
        ServoGains {
            kp_pos: self.kp_pos * f(kp),
            ki_pos: self.kp_pos * self.kp_pos * 0.1 * f(ki),
            vel_ff: f(ff),
            kv: self.kv * kvs,
            ki_vel: self.ki_vel * kvs * kvs,
            acc_ff: self.acc_ff,
            iq_max: self.iq_max,
        }
    }
}

/// One step's demand (from the interpolator or the profile generator).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Demand {
    /// Position, integer counts.
    pub pos: i32,
    /// Fraction of a count added to `pos`.
    pub frac: f32,
    /// Velocity, counts/s.
    pub vel: f32,
    /// Acceleration, counts/s².
    pub acc: f32,
}

/// Position + velocity controller.
#[derive(Clone, Debug)]
pub struct Servo {
    gains: ServoGains,
    ts: f32,
    pos_int: f32,
    vel_pi: Pi,
    fe_limit: u32,
    /// Last following error (demand − actual), counts.
    pub following_error: f32,
    /// Following-error fault latched (cleared by [`Servo::clear_fault`]).
    pub fault: bool,
    /// Last current reference, A.
    pub iq_ref: f32,
    /// Last output of the position loop (the velocity command of [`Servo::step`]:
    /// feed-forward, proportional and integral parts), counts/s; 0 after a velocity or
    /// torque step (no position loop runs).
    pub velocity_command: f32,
    /// The last [`Servo::step_torque`] took torque off the demand (speed limit).
    pub speed_limited: bool,
    /// Torque feed-forward added inside the velocity PI of [`Servo::step`] and
    /// [`Servo::step_velocity`], A ([`Servo::set_torque_offset`]).
    iq_offset: f32,
}

impl Servo {
    /// New controller, step period `ts` (s), following-error limit in counts.
    pub fn new(gains: ServoGains, ts: f32, fe_limit: u32) -> Self {
        Servo {
            gains,
            ts,
            pos_int: 0.0,
            vel_pi: Pi::new(gains.kv, gains.ki_vel, ts, gains.iq_max),
            fe_limit,
            following_error: 0.0,
            fault: false,
            iq_ref: 0.0,
            velocity_command: 0.0,
            speed_limited: false,
            iq_offset: 0.0,
        }
    }

    /// Torque feed-forward of the position and velocity steps, A (CiA 402 0x60B2): added
    /// to the velocity PI's output inside its limit, so the anti-windup sees it. Non-finite
    /// values are taken as 0.
    #[inline]
    pub fn set_torque_offset(&mut self, iq: f32) {
        self.iq_offset = if iq.is_finite() { iq } else { 0.0 };
    }

    /// Gains in use.
    pub fn gains(&self) -> &ServoGains {
        &self.gains
    }

    /// Changes gains (integrators kept).
    pub fn set_gains(&mut self, g: ServoGains) {
        self.gains = g;
        self.vel_pi.set_gains(g.kv, g.ki_vel, self.ts);
        self.vel_pi.set_limit(g.iq_max);
    }

    /// Changes the following-error limit (counts).
    pub fn set_following_error_limit(&mut self, limit: u32) {
        self.fe_limit = limit;
    }

    /// Clears the following-error fault.
    pub fn clear_fault(&mut self) {
        self.fault = false;
    }

    /// Bumpless start: integrators preset so that the first output equals `iq_now`
    /// (A, e.g. the torque current the open loop was producing) with zero error.
    /// The caller starts the demand at the actual position.
    pub fn bumpless_start(&mut self, iq_now: f32) {
        self.pos_int = 0.0;
        self.vel_pi.preset(iq_now);
        self.following_error = 0.0;
        self.velocity_command = 0.0;
        self.iq_ref = iq_now;
    }

    /// Velocity-only step (profile velocity / CSV modes): velocity demand `vel_dem`
    /// (counts/s) with acceleration feed-forward `acc_dem` (counts/s²) against the
    /// velocity estimate `vel`. The position integrator is cleared and the following
    /// error is not supervised; switching back to [`Servo::step`] is bumpless for the
    /// velocity integrator (start the position demand at the actual position).
    #[inline]
    pub fn step_velocity(&mut self, vel_dem: f32, acc_dem: f32, vel: f32) -> f32 {
        self.pos_int = 0.0;
        self.following_error = 0.0;
        self.velocity_command = 0.0;
        let iq = self
            .vel_pi
            .update(vel_dem - vel, self.gains.acc_ff * acc_dem + self.iq_offset);
        self.iq_ref = iq;
        iq
    }

    /// Torque step (cyclic synchronous torque): q-current demand `iq_dem` (A, limited
    /// to `±iq_max`) with the speed limit `v_max` (counts/s, magnitude) against the
    /// velocity estimate `vel`; see the module docs. Returns the q-current reference
    /// (A). The position integrator is cleared and no following error is kept; non-finite
    /// inputs count as 0 (demand, velocity) or as no margin (limit).
    #[inline]
    pub fn step_torque(&mut self, iq_dem: f32, v_max: f32, vel: f32) -> f32 {
        let finite = |x: f32| if x.is_finite() { x } else { 0.0 };
        let lim = self.gains.iq_max.abs();
        let it = crate::num::clamp(finite(iq_dem), -lim, lim);
        let v_max = finite(v_max).abs();
        let vel = finite(vel);
        self.pos_int = 0.0;
        self.following_error = 0.0;
        self.velocity_command = 0.0;
        let iq = if it >= 0.0 {
            self.vel_pi.update_within(v_max - vel, -lim, it)
        } else {
            self.vel_pi.update_within(-v_max - vel, it, lim)
        };
        self.speed_limited = iq != it;
        self.iq_ref = iq;
        iq
    }

    /// One step: demand, actual position (counts) and velocity estimate (counts/s).
    /// Returns the q-current reference (A), limited to `±iq_max`.
    #[inline]
    pub fn step(&mut self, d: &Demand, pos: i32, vel: f32) -> f32 {
        let g = &self.gains;
        let e = d.pos.wrapping_sub(pos) as f32 + d.frac;
        self.following_error = e;
        // Beyond the limit, or NaN: fault.
        if matches!(
            e.abs().partial_cmp(&(self.fe_limit as f32)),
            Some(core::cmp::Ordering::Greater) | None
        ) {
            self.fault = true;
        }
        self.pos_int += g.ki_pos * self.ts * e;
        // Limit the position integrator's contribution to a sane speed (1 rev/s per
        // 1000 counts of error limit): it is a slow trim, not a driver.
        let lim = 1e3 + self.fe_limit as f32 * 4.0;
        self.pos_int = crate::num::clamp(self.pos_int, -lim, lim);
        let v_cmd = g.vel_ff * d.vel + g.kp_pos * e + self.pos_int;
        self.velocity_command = v_cmd;
        let iq = self
            .vel_pi
            .update(v_cmd - vel, g.acc_ff * d.acc + self.iq_offset);
        self.iq_ref = iq;
        iq
    }
}

/// Open → closed loop handover: the open loop's current vector (`current` A on the
/// electrical angle `open_angle`) expressed in the encoder frame `enc_angle` as
/// `(i_d, i_q)`. Preset the servo with `i_q` ([`Servo::bumpless_start`]), keep `i_d`
/// as the d reference and ramp it to zero: the current vector, and so the torque,
/// does not jump even though the encoder angle is quantised (a 5 A vector and
/// ±½ count = ±2.25° electrical would otherwise change i_q by ±0.2 A at once).
pub fn handover_currents(open_angle: Angle, current: f32, enc_angle: Angle) -> (f32, f32) {
    let delta = open_angle.wrapping_sub(enc_angle);
    let (s, c) = (crate::trig::sin(delta), crate::trig::cos(delta));
    (current * c, current * s)
}

/// Linear interpolation of cyclic set-points (CSP): a new target every `n` servo
/// steps; the demand moves from the previous to the latest target over the next
/// cycle (one cycle of delay, the usual CSP behaviour), with the cycle's velocity as
/// velocity feed-forward.
///
/// The acceleration feed-forward is the change of velocity between cycles passed
/// through a first-order low-pass per cycle, `a ← a + k·(Δv/T − a)` with `k` =
/// [`Interpolator::set_acc_filter`] (default 0.25, time constant ≈ 3.5 cycles):
/// integer set-points make the raw second difference very noisy (±1 count per cycle
/// is ±1/T² counts/s²), which would otherwise shake the current reference.
#[derive(Clone, Copy, Debug)]
pub struct Interpolator {
    n: u32,
    k: u32,
    from: i32,
    delta: i32,
    vel: f32,
    acc: f32,
    cycle: f32,
    acc_k: f32,
}

impl Interpolator {
    /// `n` servo steps of `ts` seconds per set-point cycle (n ≥ 1), starting at `pos`.
    pub fn new(n: u32, ts: f32, pos: i32) -> Self {
        let n = n.max(1);
        Interpolator {
            n,
            k: n,
            from: pos,
            delta: 0,
            vel: 0.0,
            acc: 0.0,
            cycle: n as f32 * ts,
            acc_k: 0.25,
        }
    }

    /// Sets the acceleration filter weight `k` (0 = no acceleration feed-forward,
    /// 1 = raw second difference).
    pub fn set_acc_filter(&mut self, k: f32) {
        self.acc_k = if k.is_finite() {
            k.clamp(0.0, 1.0)
        } else {
            0.0
        };
    }

    /// A new set-point arrived (call once per cycle, before the cycle's steps).
    pub fn set_target(&mut self, target: i32) {
        let to = self.from.wrapping_add(self.delta);
        self.from = to;
        self.delta = target.wrapping_sub(to);
        let v = self.delta as f32 / self.cycle;
        self.acc += self.acc_k * ((v - self.vel) / self.cycle - self.acc);
        self.vel = v;
        self.k = 0;
    }

    /// Demand for the next servo step.
    #[inline]
    pub fn step(&mut self) -> Demand {
        if self.k < self.n {
            self.k += 1;
        }
        let f = self.delta as f32 * (self.k as f32 / self.n as f32);
        let whole = f as i32;
        let (vel, acc) = if self.k >= self.n && self.delta == 0 {
            (0.0, 0.0)
        } else {
            (self.vel, self.acc)
        };
        Demand {
            pos: self.from.wrapping_add(whole),
            frac: f - whole as f32,
            vel,
            acc,
        }
    }
}

/// Power-up electrical-angle alignment.
///
/// 1. `Ramp`: a current vector on electrical angle 0 ramps to the alignment current;
///    the rotor pulls into the nearest electrical zero.
/// 2. `Settle`: wait for the rotor to come to rest.
/// 3. With the wiggle option: `Sweep` the vector angle forward by `sweep_cycles`
///    electrical turns and back again, slowly; at every step the difference
///    `command − encoder` is accumulated. Without it only the final rest position is
///    used.
/// 4. `Done(offset)`: the electrical offset to add to the encoder's raw electrical
///    angle ([`crate::encoder::Encoder::set_electrical_offset`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlignState {
    /// Current ramp on angle 0.
    Ramp,
    /// Waiting for the rotor to settle.
    Settle,
    /// Forward sweep.
    SweepForward,
    /// Backward sweep.
    SweepBack,
    /// Finished: electrical offset.
    Done(Angle),
    /// The encoder did not follow the sweep (wrong direction, wrong line count or no
    /// encoder).
    Failed,
}

/// Alignment configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlignConfig {
    /// Step period, s.
    pub ts: f32,
    /// Alignment current, A.
    pub current: f32,
    /// Ramp time, s.
    pub ramp: f32,
    /// Settle time, s.
    pub settle: f32,
    /// Sweep (wiggle) enabled.
    pub wiggle: bool,
    /// Electrical turns per sweep direction.
    pub sweep_cycles: u32,
    /// Sweep speed, electrical turns per second.
    pub sweep_speed: f32,
}

/// Alignment state machine (see [`AlignState`]).
#[derive(Clone, Copy, Debug)]
pub struct Alignment {
    cfg: AlignConfig,
    /// Present state.
    pub state: AlignState,
    t: u32,
    ramp_steps: u32,
    settle_steps: u32,
    cmd: Angle,
    step_lsb: u32,
    sweep_steps: u32,
    sum: i64,
    samples: u32,
    start_raw: Angle,
    start_o: i32,
    moved: i64,
}

impl Alignment {
    /// New procedure.
    pub fn new(cfg: AlignConfig) -> Self {
        let ts = if cfg.ts > 0.0 && cfg.ts.is_finite() {
            cfg.ts
        } else {
            1e-4
        };
        let speed = cfg.sweep_speed.clamp(0.01, 100.0);
        let step_lsb = (speed * ts * 4_294_967_296.0) as u32;
        let sweep_steps = ((cfg.sweep_cycles.clamp(1, 50) as f32) / (speed * ts)) as u32;
        Alignment {
            cfg,
            state: AlignState::Ramp,
            t: 0,
            ramp_steps: ((cfg.ramp.max(0.0) / ts) as u32).saturating_add(1),
            settle_steps: ((cfg.settle.max(0.0) / ts) as u32).saturating_add(1),
            cmd: Angle::ZERO,
            step_lsb: step_lsb.max(1),
            sweep_steps: sweep_steps.max(1),
            sum: 0,
            samples: 0,
            start_raw: Angle::ZERO,
            start_o: 0,
            moved: 0,
        }
    }

    /// One step. `raw_elec`: the encoder's electrical angle without offset. Returns
    /// the vector angle and current magnitude (i_d* on that angle) to apply.
    pub fn step(&mut self, raw_elec: Angle) -> (Angle, f32) {
        self.t = self.t.saturating_add(1);
        match self.state {
            AlignState::Ramp => {
                let i = self.cfg.current * (self.t as f32 / self.ramp_steps as f32).min(1.0);
                if self.t >= self.ramp_steps {
                    self.state = AlignState::Settle;
                    self.t = 0;
                }
                (self.cmd, i)
            }
            AlignState::Settle => {
                if self.t >= self.settle_steps {
                    self.t = 0;
                    if self.cfg.wiggle {
                        self.state = AlignState::SweepForward;
                        self.start_raw = raw_elec;
                        self.moved = 0;
                        self.accumulate(raw_elec);
                    } else {
                        self.sum = 0;
                        self.samples = 0;
                        self.accumulate(raw_elec);
                        self.finish();
                    }
                }
                (self.cmd, self.cfg.current)
            }
            AlignState::SweepForward | AlignState::SweepBack => {
                let fwd = self.state == AlignState::SweepForward;
                // Track the encoder motion to verify direction and scale.
                let d = raw_elec.diff(self.start_raw) as i64;
                self.start_raw = raw_elec;
                self.moved += if fwd { d } else { -d };
                self.accumulate(raw_elec);
                self.cmd = if fwd {
                    self.cmd.wrapping_add(Angle(self.step_lsb))
                } else {
                    self.cmd.wrapping_sub(Angle(self.step_lsb))
                };
                if self.t >= self.sweep_steps {
                    self.t = 0;
                    if fwd {
                        self.state = AlignState::SweepBack;
                    } else {
                        // Both directions together moved 2·cycles electrical turns.
                        let expect = 2 * self.cfg.sweep_cycles.clamp(1, 50) as i64 * (1i64 << 32);
                        if self.moved < expect / 2 || self.moved > expect * 3 / 2 {
                            self.state = AlignState::Failed;
                        } else {
                            self.finish();
                        }
                    }
                }
                (self.cmd, self.cfg.current)
            }
            AlignState::Done(_) | AlignState::Failed => (self.cmd, 0.0),
        }
    }

    fn accumulate(&mut self, raw_elec: Angle) {
        // Offset sample = command − encoder, as a signed difference to the first
        // sample so the average does not suffer from wrapping.
        let o = self.cmd.diff(raw_elec);
        if self.samples == 0 {
            self.sum = 0;
            self.start_o = o;
        }
        self.sum += o.wrapping_sub(self.start_o) as i64;
        self.samples += 1;
    }

    fn finish(&mut self) {
        let n = self.samples.max(1) as i64;
        let mean = self.start_o.wrapping_add((self.sum / n) as i32);
        self.state = AlignState::Done(Angle(mean as u32));
    }
}
