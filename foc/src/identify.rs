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
//! Least squares on `y = φᵀ·θ`, `φ = (α, ω, sgn ω)`, `θ = (J, B, Tc)`: per step the
//! running sums of the normal equations `Σφφᵀ` (6 distinct terms) and `Σφy` are
//! accumulated (no heap, no sample storage); [`Fit::solve`] solves the 3×3 system at
//! the end. Before solving, the matrix is normalised to unit diagonal
//! (`Âij = Aij/√(Aii·Ajj)`, a correlation matrix); its determinant, between 0 and 1,
//! is the conditioning: 1 for uncorrelated regressors, 0 when one is a combination
//! of the others (no acceleration, or a move in one direction only). Below
//! [`MIN_CONDITIONING`] the result is refused.
//!
//! # Move
//! [`IdentMove`] strokes `travel` counts forward and back with a triangular velocity
//! profile (accelerate for `T`, decelerate for `T`, `T = √(travel/a)`): `α` changes
//! sign in the middle of every stroke and `ω` at every stroke end, so the three
//! regressors are nearly uncorrelated (conditioning ≈ 0.5). The first cycle is a
//! probe at the configured acceleration, not fitted: its peak current rescales the
//! acceleration so that the measured cycles reach `iq_target` (J·α then dominates
//! the friction), limited to `accel_max` and to the range ×¼..×16. The demand never
//! leaves `[start, start + travel]` (forward first).
//!
//! # Numeric behaviour
//! `f32` throughout. The sums are normalised per sample by fixed scales
//! ([`IdentConfig::accel_max`] for `α`, its speed for `ω`) so every term is of order
//! one; over 10⁴ samples the accumulated rounding is ≈ 10⁻³ relative, well below
//! the ±10 % the drive asks of the inertia. A current reference at the limit
//! (`|i_q| ≥ 0.98·iq_max`) during the fitted cycles fails the tune
//! ([`IdentError::Saturated`]): the torque is then not what the motor could have
//! given. Cost while running: ~60 FPU operations per servo step.

use crate::num;
use crate::servo::{Demand, ServoGains};
use core::f32::consts::PI;

/// Corner frequency of the common low-pass of the fit's signals, Hz.
pub const FIT_CORNER_HZ: f32 = 60.0;
/// Smallest conditioning (determinant of the normalised normal matrix) accepted.
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
}

/// Running least-squares sums of `y = J·α + B·ω + Tc·s` (see the module docs).
#[derive(Clone, Copy, Debug, Default)]
pub struct Fit {
    /// Σφφᵀ: aa, aw, as, ww, ws, ss.
    m: [f32; 6],
    /// Σφy.
    r: [f32; 3],
    n: u32,
}

impl Fit {
    /// Adds one sample: torque `y` (N·m), acceleration `a`, velocity `w`, sign
    /// regressor `s`, each already divided by its scale.
    pub fn push(&mut self, y: f32, a: f32, w: f32, s: f32) {
        let m = &mut self.m;
        m[0] += a * a;
        m[1] += a * w;
        m[2] += a * s;
        m[3] += w * w;
        m[4] += w * s;
        m[5] += s * s;
        self.r[0] += a * y;
        self.r[1] += w * y;
        self.r[2] += s * y;
        self.n += 1;
    }

    /// Samples accumulated.
    pub fn samples(&self) -> u32 {
        self.n
    }

    /// Solves the normal equations: `(θa, θw, θs, conditioning)` in the scaled units
    /// of [`Fit::push`], or [`IdentError::IllConditioned`].
    pub fn solve(&self) -> Result<([f32; 3], f32), IdentError> {
        let m = &self.m;
        if self.n < 16 || !(m[0] > 0.0 && m[3] > 0.0 && m[5] > 0.0) {
            return Err(IdentError::IllConditioned);
        }
        let d = [num::sqrtf(m[0]), num::sqrtf(m[3]), num::sqrtf(m[5])];
        // Correlation matrix (unit diagonal) and right-hand side.
        let (p, q, t) = (
            m[1] / (d[0] * d[1]),
            m[2] / (d[0] * d[2]),
            m[4] / (d[1] * d[2]),
        );
        let r = [self.r[0] / d[0], self.r[1] / d[1], self.r[2] / d[2]];
        // | 1 p q |
        // | p 1 t |  det = 1 + 2pqt − p² − q² − t²
        // | q t 1 |
        let det = 1.0 + 2.0 * p * q * t - p * p - q * q - t * t;
        if !(det >= MIN_CONDITIONING) {
            return Err(IdentError::IllConditioned);
        }
        // Cramer's rule with the adjugate of the symmetric matrix.
        let c00 = 1.0 - t * t;
        let c01 = q * t - p;
        let c02 = p * t - q;
        let c11 = 1.0 - q * q;
        let c12 = p * q - t;
        let c22 = 1.0 - p * p;
        let x0 = (c00 * r[0] + c01 * r[1] + c02 * r[2]) / det;
        let x1 = (c01 * r[0] + c11 * r[1] + c12 * r[2]) / det;
        let x2 = (c02 * r[0] + c12 * r[1] + c22 * r[2]) / det;
        Ok(([x0 / d[0], x1 / d[1], x2 / d[2]], det))
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
    peak_iq: f32,
    flt: [f32; 3],
    fit: Fit,
    saturated: bool,
    /// Present state.
    pub state: IdentState,
}

impl IdentMove {
    /// A move starting at `start` (counts, the actual position at standstill).
    pub fn new(cfg: IdentConfig, start: i32) -> Self {
        let ok = cfg.ts > 0.0
            && cfg.kt > 0.0
            && cfg.cpr > 0
            && cfg.travel >= 1.0
            && cfg.accel > 0.0
            && cfg.accel_max >= cfg.accel
            && cfg.iq_target > 0.0
            && cfg.iq_max > 0.0
            && cfg.travel.is_finite()
            && cfg.accel_max.is_finite();
        let mut m = IdentMove {
            cfg,
            start,
            accel: cfg.accel,
            half: 1,
            k: 0,
            stroke: 0,
            peak_iq: 0.0,
            flt: [0.0; 3],
            fit: Fit::default(),
            saturated: false,
            state: if ok {
                IdentState::Running
            } else {
                IdentState::Failed(IdentError::BadConfig)
            },
        };
        m.cfg.cycles = cfg.cycles.clamp(1, 16);
        m.set_accel(cfg.accel);
        m
    }

    fn set_accel(&mut self, a: f32) {
        self.accel = a;
        // Half a stroke (acceleration or deceleration) in steps, at least 4.
        let t = num::sqrtf(self.cfg.travel / a);
        self.half = ((t / self.cfg.ts) as u32).max(4);
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
        let (p, v, acc) = if self.stroke % 2 == 0 {
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
                // End of the probe: rescale the acceleration (module docs).
                let scale = if self.peak_iq > 0.0 {
                    num::clamp(self.cfg.iq_target / self.peak_iq, 0.25, 16.0)
                } else {
                    16.0
                };
                self.set_accel((self.accel * scale).min(self.cfg.accel_max));
            }
            if self.stroke >= 2 * (self.cfg.cycles + 1) {
                self.state = self.finish();
                return self.step(0.0, 0.0);
            }
        }
        self.demand()
    }

    fn measure(&mut self, iq: f32, vel: f32) {
        let c = &self.cfg;
        let k = num::clamp(2.0 * PI * FIT_CORNER_HZ * c.ts, 0.0, 1.0);
        let w = vel * (2.0 * PI / c.cpr as f32);
        let s = if w > 0.0 {
            1.0
        } else if w < 0.0 {
            -1.0
        } else {
            0.0
        };
        // The current `iq` acted over the step that ends with `vel`: `α` is the change
        // of the filtered velocity over that step, `ω` and the sign their means over
        // it (the current is constant within it).
        let prev = [self.flt[1], self.flt[2]];
        let f = &mut self.flt;
        f[0] += k * (iq - f[0]);
        f[1] += k * (w - f[1]);
        f[2] += k * (s - f[2]);
        let alpha = (f[1] - prev[0]) / c.ts;
        let (iqf, wf, sf) = (f[0], 0.5 * (f[1] + prev[0]), 0.5 * (f[2] + prev[1]));
        if self.stroke < 2 {
            self.peak_iq = self.peak_iq.max(iq.abs());
            return;
        }
        if iq.abs() >= 0.98 * c.iq_max {
            self.saturated = true;
        }
        // Scales: α by the highest acceleration, ω by the speed it reaches over the
        // travel (rad/s² and rad/s).
        let rad = 2.0 * PI / c.cpr as f32;
        let a_sc = c.accel_max * rad;
        let w_sc = num::sqrtf(c.accel_max * c.travel) * rad;
        self.fit.push(c.kt * iqf, alpha / a_sc, wf / w_sc, sf);
    }

    fn finish(&self) -> IdentState {
        if self.saturated {
            return IdentState::Failed(IdentError::Saturated);
        }
        let c = &self.cfg;
        let rad = 2.0 * PI / c.cpr as f32;
        let a_sc = c.accel_max * rad;
        let w_sc = num::sqrtf(c.accel_max * c.travel) * rad;
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
    fn probe_rescales_acceleration() {
        let c = cfg();
        let mut m = IdentMove::new(c, 0);
        // A constant 0.75 A peak in the probe: target 3 A → ×4.
        let mut n = 0;
        while m.stroke < 2 {
            m.step(0.75, 100.0);
            n += 1;
            assert!(n < 100_000);
        }
        assert!((m.accel() / (4.0 * c.accel) - 1.0).abs() < 1e-6);
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
            f.push(x, x, 2.0 * x, 1.0);
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
