//! Load identification in closed loop: inertia, viscous and Coulomb friction from a
//! commanded back-and-forth move.
//!
//! # Model
//! The mechanical equation of the shaft with its load, in SI units:
//!
//! ```text
//! Kt·i_q = J·α + B·ω + Tc·sgn(ω)        (N·m; J kg·m², B N·m·s/rad, Tc N·m)
//! ```
//!
//! `i_q` is the q-current reference (A; the current loop tracks it within its
//! 2 kHz bandwidth), `ω` the encoder velocity converted from counts/s to rad/s.
//! Every signal goes through the same first-order low-pass `x_f ← x_f + k·(x − x_f)`
//! (corner [`FIT_CORNER_HZ`]), `α` is the difference of the filtered velocity over one
//! step. A linear filter applied to both sides keeps the equation exact, so the
//! filter's lag costs no accuracy while it removes the encoder quantisation from `α`
//! (one count per step is 10⁴ counts/s of velocity noise at 10 kHz, unfiltered
//! `α` would be 10⁸ counts/s²). The sign regressor is filtered too (`LPF(sgn ω)`).
//!
//! # Fit
//! Instrumental variables on `y = φᵀ·θ`, `φ = (α, ω, sgn ω)`, `θ = (J, B, Tc)`, with
//! the instruments `z` = the same three signals built from the *demand* (velocity
//! set-point, same filter). Ordinary least squares (`z = φ`) is biased here: the
//! encoder noise in the measured `α` adds to `Σα²` and, in closed loop, the servo
//! turns that noise into current, so J comes out low (by 30-60 % on the plant at
//! 50-100 rev/s²). The demand carries no measurement noise, and the estimate
//! `θ = (Σzφᵀ)⁻¹·Σzy` is unbiased as long as the noise is uncorrelated with the
//! demand. Per step the running sums `Σzφᵀ` (3×3), `Σzy` and the squares `Σz²`,
//! `Σφ²` are accumulated (no heap, no sample storage); [`Fit::solve`] solves the
//! 3×3 system by Cramer's rule at the end. Its conditioning is `|det|` of `Σzφᵀ`
//! with each element divided by `√(Σz_i²·Σφ_j²)`: at most 1, 0 when the regressors
//! are dependent (no acceleration, a move in one direction only). Below
//! [`MIN_CONDITIONING`] the result is refused.
//!
//! # Move
//! [`IdentMove`] strokes `travel` counts forward and back with a triangular velocity
//! profile (accelerate for `T`, decelerate for `T`, `T = √(travel/a)`): `α` changes
//! sign in the middle of every stroke and `ω` at every stroke end, so the regressors
//! are nearly uncorrelated (conditioning 0.1-0.2 on the plant). The first cycle is a
//! probe at the configured acceleration: a fit of its own gives a first inertia, and
//! the fitted cycles run at the acceleration that gives that inertia `iq_target`
//! (J·α then dominates the friction), limited to ×¼..×16 the probe's, to
//! `accel_max` and to `speed_max²/travel`. The demand never leaves
//! `[start, start + travel]` (forward first); the actual position lags it by the
//! following error (with the move gains and 20× the rotor inertia, ≈ 10 % of a
//! 90° travel on the plant).
//!
//! # Numeric behaviour
//! `f32` throughout. The sums are normalised per sample by fixed scales
//! ([`IdentConfig::accel_max`] for `α`, its speed for `ω`) so every term is of order
//! one; over 10⁴ samples the accumulated rounding is ≈ 10⁻³ relative, well below
//! the ±10 % the drive asks of the inertia (the plant gives ±3 % for loads of 1×
//! to 20× the rotor inertia, `tests-host` `servo_tune`). A current reference at the limit
//! (`|i_q| ≥ 0.98·iq_max`) during the fitted cycles fails the tune
//! ([`IdentError::Saturated`]): the torque is then not what the motor could have
//! given. Cost while running: ~120 FPU operations per servo step (nothing when idle).

use crate::num;
use crate::servo::{Demand, ServoGains};
use core::f32::consts::PI;

/// Corner frequency of the common low-pass of the fit's signals, Hz.
pub const FIT_CORNER_HZ: f32 = 60.0;
/// Smallest conditioning accepted (|det| of the normalised `Σzφᵀ`, see the module docs).
pub const MIN_CONDITIONING: f32 = 1e-2;

/// Identified mechanical parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Identified {
    /// Total inertia (rotor + load), kg·m².
    pub j: f32,
    /// Viscous friction, N·m·s/rad.
    pub b: f32,
    /// Coulomb friction, N·m.
    pub tc: f32,
    /// Conditioning of the fit, 0..1 (see the module docs).
    pub conditioning: f32,
}

impl Identified {
    /// Load inertia as a percentage of `j_rotor` (kg·m²): `(J/J_rotor − 1)·100`,
    /// not below 0.
    pub fn load_ratio_percent(&self, j_rotor: f32) -> f32 {
        if j_rotor > 0.0 {
            num::pos((self.j / j_rotor - 1.0) * 100.0)
        } else {
            0.0
        }
    }
}

/// Why an identification gave no result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IdentError {
    /// Too few samples or regressors too correlated (conditioning below
    /// [`MIN_CONDITIONING`]).
    IllConditioned,
    /// The fit gave a non-positive inertia or a non-finite value.
    NonPhysical,
    /// The current reached its limit during the fitted cycles.
    Saturated,
    /// The travel or the configuration does not allow a move.
    BadConfig,
    /// The caller ended the move ([`IdentMove::abort`]: stop, fault, disable).
    Stopped,
}

/// Running sums of the instrumental-variable fit of `y = J·α + B·ω + Tc·s` (see the
/// module docs): `Σzφᵀ` (3×3), `Σzy`, and the squares `Σz²`, `Σφ²` for the
/// conditioning. With `z = φ` it is ordinary least squares.
#[derive(Clone, Copy, Debug, Default)]
pub struct Fit {
    /// Σ z_i·φ_j, row-major.
    m: [[f32; 3]; 3],
    /// Σ z_i·y.
    r: [f32; 3],
    /// Σ z_i², Σ φ_j².
    zz: [f32; 3],
    pp: [f32; 3],
    n: u32,
}

impl Fit {
    /// Adds one sample: torque `y` (N·m), regressors `phi` = (α, ω, s) and instruments
    /// `z` (the same from the demand), each already divided by its scale.
    pub fn push(&mut self, y: f32, phi: [f32; 3], z: [f32; 3]) {
        for (i, &zi) in z.iter().enumerate() {
            for (m, &pj) in self.m[i].iter_mut().zip(&phi) {
                *m += zi * pj;
            }
            self.r[i] += zi * y;
            self.zz[i] += zi * zi;
            self.pp[i] += phi[i] * phi[i];
        }
        self.n += 1;
    }

    /// Back to no samples.
    pub fn clear(&mut self) {
        self.m = [[0.0; 3]; 3];
        self.r = [0.0; 3];
        self.zz = [0.0; 3];
        self.pp = [0.0; 3];
        self.n = 0;
    }

    /// Samples accumulated.
    pub fn samples(&self) -> u32 {
        self.n
    }

    /// Solves `Σzφᵀ·θ = Σzy`: `(θ, conditioning)` in the scaled units of
    /// [`Fit::push`], or [`IdentError::IllConditioned`]. The conditioning is `|det|`
    /// of `Σzφᵀ` with every element divided by `√(Σz_i²·Σφ_j²)` (≤ 1).
    pub fn solve(&self) -> Result<([f32; 3], f32), IdentError> {
        if self.n < 16 || !self.zz.iter().chain(&self.pp).all(|&x| x > 0.0) {
            return Err(IdentError::IllConditioned);
        }
        let dz = self.zz.map(num::sqrtf);
        let dp = self.pp.map(num::sqrtf);
        let mut a = [[0.0f32; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                a[i][j] = self.m[i][j] / (dz[i] * dp[j]);
            }
        }
        let r = [self.r[0] / dz[0], self.r[1] / dz[1], self.r[2] / dz[2]];
        let det3 = |m: &[[f32; 3]; 3]| {
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        };
        let det = det3(&a);
        // NaN fails too.
        if det.abs().partial_cmp(&MIN_CONDITIONING) != Some(core::cmp::Ordering::Greater) {
            return Err(IdentError::IllConditioned);
        }
        // Cramer's rule: column j replaced by the right-hand side.
        let mut x = [0.0f32; 3];
        for (j, xj) in x.iter_mut().enumerate() {
            let mut c = a;
            for i in 0..3 {
                c[i][j] = r[i];
            }
            *xj = det3(&c) / det / dp[j];
        }
        Ok((x, det.abs()))
    }
}

/// Identification configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdentConfig {
    /// Servo step period, s.
    pub ts: f32,
    /// Torque constant, N·m/A.
    pub kt: f32,
    /// Encoder counts per revolution.
    pub cpr: u32,
    /// Stroke length, counts (> 0; the move stays within `[start, start + travel]`).
    pub travel: f32,
    /// Acceleration of the probe cycle, counts/s².
    pub accel: f32,
    /// Highest acceleration of the fitted cycles, counts/s².
    pub accel_max: f32,
    /// Highest speed, counts/s: limits the acceleration to `speed_max²/travel` (the
    /// peak speed of a stroke is `√(a·travel)`; near the bus voltage's limit the
    /// current would no longer follow its reference).
    pub speed_max: f32,
    /// Peak current the fitted cycles aim at, A.
    pub iq_target: f32,
    /// Current limit of the servo, A (saturation check).
    pub iq_max: f32,
    /// Fitted back-and-forth cycles (after the probe), 1..=16.
    pub cycles: u32,
}

/// Progress of the identification.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum IdentState {
    /// Moving.
    Running,
    /// Finished with a result.
    Done(Identified),
    /// Finished without a result.
    Failed(IdentError),
}

/// The back-and-forth move with the fit (see the module docs). Call
/// [`IdentMove::step`] once per servo step; it returns the demand for the servo.
#[derive(Clone, Copy, Debug)]
pub struct IdentMove {
    cfg: IdentConfig,
    start: i32,
    accel: f32,
    half: u32,
    k: u32,
    stroke: u32,
    dem_vel: f32,
    flt: [f32; 5],
    probe: Fit,
    fit: Fit,
    saturated: bool,
    /// Present state.
    pub state: IdentState,
}

impl IdentMove {
    /// A move starting at `start` (counts, the actual position at standstill).
    pub fn new(cfg: IdentConfig, start: i32) -> Self {
        let mut m = IdentMove {
            cfg,
            start,
            accel: cfg.accel,
            half: 1,
            k: 0,
            stroke: 0,
            dem_vel: 0.0,
            flt: [0.0; 5],
            probe: Fit::default(),
            fit: Fit::default(),
            saturated: false,
            state: IdentState::Running,
        };
        m.restart(cfg, start);
        m
    }

    /// [`IdentMove::new`] in place (no copy of the move's ~250 bytes: the servo
    /// interrupt starts moves with it).
    pub fn restart(&mut self, cfg: IdentConfig, start: i32) {
        let ok = cfg.ts > 0.0
            && cfg.kt > 0.0
            && cfg.cpr > 0
            && cfg.travel >= 1.0
            && cfg.accel > 0.0
            && cfg.accel_max >= cfg.accel
            && cfg.speed_max > 0.0
            && cfg.iq_target > 0.0
            && cfg.iq_max > 0.0
            && cfg.travel.is_finite()
            && cfg.accel_max.is_finite();
        self.cfg = cfg;
        self.cfg.cycles = cfg.cycles.clamp(1, 16);
        self.start = start;
        self.k = 0;
        self.stroke = 0;
        self.dem_vel = 0.0;
        self.flt = [0.0; 5];
        self.probe.clear();
        self.fit.clear();
        self.saturated = false;
        self.state = if ok {
            IdentState::Running
        } else {
            IdentState::Failed(IdentError::BadConfig)
        };
        self.set_accel(cfg.accel);
    }

    fn set_accel(&mut self, a: f32) {
        let c = &self.cfg;
        let a = a.min(c.speed_max * c.speed_max / c.travel);
        self.accel = a;
        // Half a stroke (acceleration or deceleration) in steps, at least 4.
        let t = num::sqrtf(self.cfg.travel / a);
        self.half = ((t / self.cfg.ts) as u32).max(4);
    }

    /// Ends a running move as [`IdentError::Stopped`] (no effect once finished).
    pub fn abort(&mut self) {
        if self.state == IdentState::Running {
            self.state = IdentState::Failed(IdentError::Stopped);
        }
    }

    /// Acceleration of the present cycle, counts/s².
    pub fn accel(&self) -> f32 {
        self.accel
    }

    /// Demand of the present step, positions from the start of the stroke.
    fn demand(&self) -> Demand {
        let ts = self.cfg.ts;
        // The acceleration is re-derived from the whole number of steps so the stroke
        // is exactly `travel` long.
        let th = self.half as f32 * ts;
        let a = self.cfg.travel / (th * th);
        let t = self.k as f32 * ts;
        let (p, v, acc) = if self.k < self.half {
            (0.5 * a * t * t, a * t, a)
        } else {
            let u = 2.0 * th - t;
            (self.cfg.travel - 0.5 * a * u * u, a * u, -a)
        };
        let (p, v, acc) = if self.stroke.is_multiple_of(2) {
            (p, v, acc)
        } else {
            (self.cfg.travel - p, -v, -acc)
        };
        let whole = p as i32;
        Demand {
            pos: self.start.wrapping_add(whole),
            frac: p - whole as f32,
            vel: v,
            acc,
        }
    }

    /// One servo step: the current reference `iq` (A) applied during the step just
    /// done and the encoder velocity `vel` (counts/s) at its end. Returns the demand for the
    /// next step (the start position at rest once finished).
    pub fn step(&mut self, iq: f32, vel: f32) -> Demand {
        if self.state != IdentState::Running {
            return Demand {
                pos: self.start,
                ..Demand::default()
            };
        }
        self.measure(iq, vel);
        self.k += 1;
        if self.k >= 2 * self.half {
            self.k = 0;
            self.stroke += 1;
            if self.stroke == 2 {
                // End of the probe: the acceleration that gives the probe's inertia
                // the target current (module docs).
                let a = match self.probe.solve() {
                    Ok((x, _)) if x[0] > 0.0 => {
                        let j = x[0] / self.scales()[0];
                        let rad = 2.0 * PI / self.cfg.cpr as f32;
                        self.cfg.iq_target * self.cfg.kt / (j * rad)
                    }
                    _ => self.accel,
                };
                let a = num::clamp(a, 0.25 * self.accel, 16.0 * self.accel);
                self.set_accel(a.min(self.cfg.accel_max));
            }
            if self.stroke >= 2 * (self.cfg.cycles + 1) {
                self.state = self.finish();
                return self.step(0.0, 0.0);
            }
        }
        let d = self.demand();
        self.dem_vel = d.vel;
        d
    }

    fn measure(&mut self, iq: f32, vel: f32) {
        let c = &self.cfg;
        let k = num::clamp(2.0 * PI * FIT_CORNER_HZ * c.ts, 0.0, 1.0);
        let rad = 2.0 * PI / c.cpr as f32;
        let sgn = |x: f32| {
            if x > 0.0 {
                1.0
            } else if x < 0.0 {
                -1.0
            } else {
                0.0
            }
        };
        // The current `iq` acted over the step that ends with `vel`: `α` is the change
        // of the filtered velocity over that step, `ω` and the sign their means over
        // it. The instruments are the same three built from the demand of that step.
        let (w, wd) = (vel * rad, self.dem_vel * rad);
        let sc = self.scales();
        let prev = self.flt;
        let f = &mut self.flt;
        for (x, v) in f.iter_mut().zip([iq, w, sgn(w), wd, sgn(wd)]) {
            *x += k * (v - *x);
        }
        let mean = |i: usize| 0.5 * (f[i] + prev[i]);
        let phi = [(f[1] - prev[1]) / c.ts, mean(1), mean(2)];
        let z = [(f[3] - prev[3]) / c.ts, mean(3), mean(4)];
        // Scales: α by the highest acceleration, ω by the speed it reaches over the
        // travel (rad/s² and rad/s).
        let phi = [phi[0] / sc[0], phi[1] / sc[1], phi[2]];
        let z = [z[0] / sc[0], z[1] / sc[1], z[2]];
        let y = c.kt * f[0];
        if self.stroke < 2 {
            self.probe.push(y, phi, z);
            return;
        }
        if iq.abs() >= 0.98 * c.iq_max {
            self.saturated = true;
        }
        self.fit.push(y, phi, z);
    }

    /// Scales of α (rad/s²) and ω (rad/s) in the fit.
    fn scales(&self) -> [f32; 2] {
        let c = &self.cfg;
        let rad = 2.0 * PI / c.cpr as f32;
        [c.accel_max * rad, num::sqrtf(c.accel_max * c.travel) * rad]
    }

    fn finish(&self) -> IdentState {
        if self.saturated {
            return IdentState::Failed(IdentError::Saturated);
        }
        let [a_sc, w_sc] = self.scales();
        match self.fit.solve() {
            Err(e) => IdentState::Failed(e),
            Ok((x, cond)) => {
                let r = Identified {
                    j: x[0] / a_sc,
                    b: x[1] / w_sc,
                    tc: x[2],
                    conditioning: cond,
                };
                if r.j > 0.0 && r.j.is_finite() && r.b.is_finite() && r.tc.is_finite() {
                    IdentState::Done(r)
                } else {
                    IdentState::Failed(IdentError::NonPhysical)
                }
            }
        }
    }
}

/// Servo gains for the identification move, from `base` gains designed for the rotor
/// alone: the velocity loop proportional only (its crossover falls as `1/(1 + ratio)`
/// with the unknown load, first order, stable for any load), the position loop at a
/// tenth of the base gain (below the velocity crossover up to a ratio of ≈ 20) and
/// without integral; full velocity and rotor acceleration feed-forward.
pub fn move_gains(base: &ServoGains) -> ServoGains {
    ServoGains {
        kp_pos: base.kp_pos * 0.1,
        ki_pos: 0.0,
        vel_ff: 1.0,
        kv: base.kv,
        ki_vel: 0.0,
        acc_ff: base.acc_ff,
        iq_max: base.iq_max,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> IdentConfig {
        IdentConfig {
            ts: 1e-4,
            kt: 0.3,
            cpr: 4000,
            travel: 1000.0,
            accel: 200.0 * 4000.0,
            accel_max: 1000.0 * 4000.0,
            speed_max: 20.0 * 4000.0,
            iq_target: 3.0,
            iq_max: 7.0,
            cycles: 3,
        }
    }

    /// Ideal plant `Kt·i = J·α + B·ω + Tc·sgn ω` driven by the move's own demand
    /// (perfect tracking): the fit returns the plant's constants.
    fn run_ideal(j: f32, b: f32, tc: f32) -> IdentState {
        let c = cfg();
        let mut m = IdentMove::new(c, 0);
        let rad = 2.0 * PI / c.cpr as f32;
        let mut d = m.step(0.0, 0.0);
        for _ in 0..200_000 {
            if m.state != IdentState::Running {
                break;
            }
            // The current of the demand's acceleration acts over the step; the
            // velocity is the one at its end.
            let w = d.vel * rad;
            let s = if w > 0.0 {
                1.0
            } else if w < 0.0 {
                -1.0
            } else {
                0.0
            };
            let iq = (j * d.acc * rad + b * w + tc * s) / c.kt;
            assert!(d.pos >= 0 && d.pos <= 1000, "left the travel: {}", d.pos);
            d = m.step(iq, d.vel + d.acc * c.ts);
        }
        m.state
    }

    #[test]
    fn ideal_plant_is_identified() {
        for j in [5e-5, 2.5e-4, 1e-3] {
            let IdentState::Done(r) = run_ideal(j, 2e-4, 0.015) else {
                panic!("no result for J = {j}");
            };
            assert!((r.j / j - 1.0).abs() < 0.03, "J {} vs {j}", r.j);
            assert!(r.j > 0.0, "{r:?}");
            assert!((r.tc / 0.015 - 1.0).abs() < 0.1, "Tc {} (J {})", r.tc, j);
            assert!(r.conditioning > 0.1, "conditioning {}", r.conditioning);
        }
    }

    #[test]
    fn probe_sets_the_acceleration_for_the_target_current() {
        // J = 2.5e-4 kg·m², 3 A·0.3 N·m/A = 0.9 N·m → 3600 rad/s² = 2292 counts/s²·1e3.
        let c = cfg();
        let (j, kt) = (2.5e-4f32, c.kt);
        let rad = 2.0 * PI / c.cpr as f32;
        let mut m = IdentMove::new(c, 0);
        let mut d = m.step(0.0, 0.0);
        while m.stroke < 2 {
            d = m.step(j * d.acc * rad / kt, d.vel + d.acc * c.ts);
        }
        let expect = c.iq_target * kt / (j * rad);
        assert!(
            (m.accel() / expect - 1.0).abs() < 0.03,
            "{} vs {expect}",
            m.accel()
        );
    }

    #[test]
    fn saturation_fails() {
        let c = cfg();
        let mut m = IdentMove::new(c, 0);
        let mut d = m.step(0.0, 0.0);
        for _ in 0..200_000 {
            if m.state != IdentState::Running {
                break;
            }
            d = m.step(if d.acc > 0.0 { 7.0 } else { -7.0 }, d.vel);
        }
        assert_eq!(m.state, IdentState::Failed(IdentError::Saturated));
    }

    #[test]
    fn one_direction_is_ill_conditioned() {
        // α and ω proportional: the fit must refuse.
        let mut f = Fit::default();
        for i in 0..100 {
            let x = i as f32 * 0.01;
            f.push(x, [x, 2.0 * x, 1.0], [x, 2.0 * x, 1.0]);
        }
        assert_eq!(f.solve(), Err(IdentError::IllConditioned));
        assert_eq!(Fit::default().solve(), Err(IdentError::IllConditioned));
    }

    #[test]
    fn bad_config_refused() {
        let mut c = cfg();
        c.travel = 0.0;
        assert_eq!(
            IdentMove::new(c, 0).state,
            IdentState::Failed(IdentError::BadConfig)
        );
        c = cfg();
        c.accel = f32::NAN;
        assert_eq!(
            IdentMove::new(c, 0).state,
            IdentState::Failed(IdentError::BadConfig)
        );
    }

    #[test]
    fn ratio_from_inertia() {
        let r = Identified {
            j: 3e-4,
            b: 0.0,
            tc: 0.0,
            conditioning: 1.0,
        };
        assert!((r.load_ratio_percent(1e-4) - 200.0).abs() < 1e-3);
        assert_eq!(r.load_ratio_percent(0.0), 0.0);
    }
}
