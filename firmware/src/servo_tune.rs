//! Servo gains from the load inertia and a stiffness level (0x2160, 0x2161).
//!
//! The base gains of the motion layer ([`crate::motion`]) are designed for the rotor
//! inertia times `1 + 0x2160/100`, so with the load ratio known the parameters
//! 0x2137-0x2140 only choose the bandwidth. The stiffness 0x2161 names that choice:
//!
//! | 0x2161 | 1 | 2 | 3 | 4 | 5 | 6 | 7 | 8 | 9 | 10 | 11 | 12 | 13 | 14 | 15 | 16 |
//! |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|
//! | velocity bandwidth, Hz | 20 | 30 | 40 | 50 | 65 | 80 | 100 | 120 | 140 | 170 | 200 | 240 | 280 | 320 | 360 | 400 |
//!
//! For a velocity bandwidth `f` the gains are ([`StiffnessGains::for_level`]):
//! * 0x2140 (velocity loop) `= 100·f/BASE_BANDWIDTH_HZ`;
//! * 0x2137 (position gain) `= 2·0x2140` (the position bandwidth half the velocity
//!   bandwidth, ζ ≈ 0.5 as the defaults), at most 150;
//! * 0x2138 (position integral) `= 50·(0x2137/120)²` (its corner in the same
//!   proportion to the position bandwidth as with the defaults);
//! * 0x2139 (velocity feed-forward) `= 100`: with the inertia known the
//!   acceleration feed-forward is right, so the full velocity feed-forward does not
//!   overshoot.
//!
//! Level 12 gives the defaults' bandwidth (240 Hz; 120 / 50 / 100 / 60). Stiffer
//! levels reject load torque faster and amplify the encoder's quantisation more
//! (the current noise grows with the gain, so with the inertia).
//!
//! # The identification move ([`TuneRun`])
//! [`check_start`] decides whether a move may start: closed loop, Operation enabled,
//! the axis at rest (below 1 % of a revolution per second) and the travel, with a
//! 20 % margin for the following error of the move gains on both sides, inside the
//! software limits 0x607D. A refusal is 0x08000022 (state), a travel that does not
//! fit 0x06090030. [`TuneRun`] runs [`foc::identify::IdentMove`] from the actual
//! position; a stop (drive disabled, quick stop, fault: the caller's `running`
//! false) ends it as failed. Its outcome goes to the parameters with [`apply`].

use crate::motion::BASE_BANDWIDTH_HZ;
use crate::params::{Param, Params};
use ecat_slave_stack::od::SdoAbort;
use foc::identify::{IdentConfig, IdentMove, IdentState};
use foc::servo::Demand;

/// Velocity bandwidth of the stiffness levels 1..=16, Hz.
pub const STIFFNESS_HZ: [u16; 16] = [
    20, 30, 40, 50, 65, 80, 100, 120, 140, 170, 200, 240, 280, 320, 360, 400,
];

/// The servo parameters 0x2137-0x2140 of one stiffness level.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StiffnessGains {
    /// 0x2137.
    pub pos_kp: u16,
    /// 0x2138.
    pub pos_ki: u16,
    /// 0x2139.
    pub vel_ff: u16,
    /// 0x2140.
    pub speed_kp: u16,
}

impl StiffnessGains {
    /// The gains of stiffness `level` (clamped to 1..=16; see the module docs).
    pub fn for_level(level: u8) -> Self {
        let i = usize::from(level.clamp(1, 16)) - 1;
        let f = f32::from(STIFFNESS_HZ.get(i).copied().unwrap_or(240));
        let speed_kp = ((100.0 * f / BASE_BANDWIDTH_HZ + 0.5) as u16).clamp(1, 150);
        let pos_kp = (2 * speed_kp).min(150);
        let r = f32::from(pos_kp) / 120.0;
        let pos_ki = ((50.0 * r * r + 0.5) as u16).min(150);
        StiffnessGains {
            pos_kp,
            pos_ki,
            vel_ff: 100,
            speed_kp,
        }
    }
}

/// Writes a tune's result: the load ratio 0x2160 (%, clamped to its range) and the
/// gains 0x2137-0x2140 of the stiffness 0x2161 in effect. Not saved (a 'save' stores
/// them like any parameter).
pub fn apply(params: &mut Params, ratio_percent: f32) {
    let ratio = if ratio_percent.is_finite() {
        (ratio_percent + 0.5) as i32
    } else {
        0
    };
    params.set_internal(Param::LoadInertiaRatio, ratio);
    let g = StiffnessGains::for_level(params.get(Param::Stiffness) as u8);
    params.set_internal(Param::PosKp, i32::from(g.pos_kp));
    params.set_internal(Param::PosKi, i32::from(g.pos_ki));
    params.set_internal(Param::VelFf, i32::from(g.vel_ff));
    params.set_internal(Param::SpeedKp, i32::from(g.speed_kp));
}

/// State of a servo tune as 0x2162 reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum TuneState {
    /// No tune since power-up.
    Idle = 0,
    /// The move is running.
    Running = 1,
    /// Finished; the result is in the parameters.
    Done = 2,
    /// The last start was refused.
    Refused = 3,
    /// The move was stopped or gave no result.
    Failed = 4,
}

/// What [`check_start`] looks at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StartConditions {
    /// Closed loop in effect (0x2024 = 2 with an encoder).
    pub closed_loop: bool,
    /// CiA 402 state Operation enabled.
    pub operation_enabled: bool,
    /// Actual velocity, counts/s.
    pub velocity: f32,
    /// Encoder counts per revolution.
    pub counts_per_rev: u32,
    /// Actual position, command units.
    pub position: i32,
    /// Travel 0x2163, command units.
    pub travel: u32,
    /// Software limits 0x607D in effect (min, max), command units.
    pub limits: Option<(i32, i32)>,
}

/// Whether a tune may start (see the module docs).
pub fn check_start(c: &StartConditions) -> Result<(), SdoAbort> {
    let rest = c.counts_per_rev as f32 * 0.01;
    let still = c.velocity.is_finite() && c.velocity.abs() <= rest;
    if !(c.closed_loop && c.operation_enabled && still) {
        return Err(SdoAbort::StateConflict);
    }
    if c.travel == 0 {
        return Err(SdoAbort::ValueRangeExceeded);
    }
    if let Some((lo, hi)) = c.limits {
        let t = i64::from(c.travel);
        let p = i64::from(c.position);
        if p + t + t / 5 > i64::from(hi) || p - t / 5 < i64::from(lo) {
            return Err(SdoAbort::ValueRangeExceeded);
        }
    }
    Ok(())
}

/// A running identification move and its outcome.
#[derive(Debug, Clone, Copy)]
pub struct TuneRun {
    ident: IdentMove,
    j_rotor: f32,
}

impl TuneRun {
    /// Starts the move `cfg` at the actual position `start` (counts) for a motor of
    /// rotor inertia `j_rotor` (kg·m²).
    pub fn new(cfg: IdentConfig, start: i32, j_rotor: f32) -> Self {
        TuneRun {
            ident: IdentMove::new(cfg, start),
            j_rotor,
        }
    }

    /// One servo step (see [`IdentMove::step`]); `running` false (stop, fault,
    /// disable) fails the tune. `None` once the tune has ended.
    pub fn step(&mut self, running: bool, iq: f32, vel: f32) -> Option<Demand> {
        if !running {
            self.ident.abort();
        }
        match self.ident.state {
            IdentState::Running => Some(self.ident.step(iq, vel)),
            _ => None,
        }
    }

    /// The state 0x2162 reports.
    pub fn state(&self) -> TuneState {
        match self.ident.state {
            IdentState::Running => TuneState::Running,
            IdentState::Done(_) => TuneState::Done,
            IdentState::Failed(_) => TuneState::Failed,
        }
    }

    /// The identified load ratio (%, 0x2164) and Coulomb friction (mN·m, 0x2165).
    pub fn result(&self) -> Option<(f32, f32)> {
        match self.ident.state {
            IdentState::Done(i) => Some((i.load_ratio_percent(self.j_rotor), i.tc * 1e3)),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identity::Variant;
    use crate::motion::{MotionConfig, ECN57_20, SERVO_TS};
    use core::f32::consts::PI;

    #[test]
    fn level_12_is_the_default_bandwidth() {
        assert_eq!(
            StiffnessGains::for_level(12),
            StiffnessGains {
                pos_kp: 120,
                pos_ki: 50,
                vel_ff: 100,
                speed_kp: 60
            }
        );
        assert_eq!(StiffnessGains::for_level(16).speed_kp, 100);
        assert_eq!(StiffnessGains::for_level(16).pos_kp, 150);
        assert_eq!(StiffnessGains::for_level(1).speed_kp, 5);
        assert_eq!(StiffnessGains::for_level(0), StiffnessGains::for_level(1));
        assert_eq!(StiffnessGains::for_level(99), StiffnessGains::for_level(16));
        for l in 1..16u8 {
            let (a, b) = (
                StiffnessGains::for_level(l),
                StiffnessGains::for_level(l + 1),
            );
            assert!(b.speed_kp > a.speed_kp && b.pos_kp >= a.pos_kp, "level {l}");
        }
    }

    #[test]
    fn load_ratio_scales_the_base_gains() {
        let mut p = Params::new(Variant::HybridServo);
        let g0 = MotionConfig::from_params(&p, Variant::HybridServo, &ECN57_20, SERVO_TS).gains;
        p.set_internal(Param::LoadInertiaRatio, 500);
        let g5 = MotionConfig::from_params(&p, Variant::HybridServo, &ECN57_20, SERVO_TS).gains;
        // Same bandwidth on 6 × the inertia: 6 × the velocity gain and the acceleration
        // feed-forward, the same position gain.
        assert!((g5.kv / g0.kv - 6.0).abs() < 1e-3);
        assert!((g5.acc_ff / g0.acc_ff - 6.0).abs() < 1e-3);
        assert_eq!(g5.kp_pos, g0.kp_pos);
    }

    #[test]
    fn apply_sets_ratio_and_gains_of_the_stiffness() {
        let mut p = Params::new(Variant::HybridServo);
        p.set_internal(Param::Stiffness, 8);
        apply(&mut p, 1234.4);
        assert_eq!(p.get(Param::LoadInertiaRatio), 1234);
        let g = StiffnessGains::for_level(8);
        assert_eq!(p.get(Param::SpeedKp), i32::from(g.speed_kp));
        assert_eq!(p.get(Param::PosKp), i32::from(g.pos_kp));
        assert_eq!(p.get(Param::PosKi), i32::from(g.pos_ki));
        assert_eq!(p.get(Param::VelFf), 100);
        // The velocity bandwidth is the level's: Kv·b = 2π·120 Hz.
        let c = MotionConfig::from_params(&p, Variant::HybridServo, &ECN57_20, SERVO_TS);
        let j = ECN57_20.inertia * (1.0 + 12.34);
        let b = ECN57_20.kt * c.counts_per_rev as f32 / (2.0 * PI * j);
        assert!((c.gains.kv * b / (2.0 * PI * 120.0) - 1.0).abs() < 0.01);
        // Out of range and non-finite ratios are clamped / zero.
        apply(&mut p, 1e9);
        assert_eq!(p.get(Param::LoadInertiaRatio), 5000);
        apply(&mut p, f32::NAN);
        assert_eq!(p.get(Param::LoadInertiaRatio), 0);
    }

    fn ok_conditions() -> StartConditions {
        StartConditions {
            closed_loop: true,
            operation_enabled: true,
            velocity: 0.0,
            counts_per_rev: 4000,
            position: 0,
            travel: 12_500,
            limits: Some((-100_000, 100_000)),
        }
    }

    #[test]
    fn start_refused_in_the_wrong_state_or_beyond_the_limits() {
        assert_eq!(check_start(&ok_conditions()), Ok(()));
        let no_limits = StartConditions {
            limits: None,
            ..ok_conditions()
        };
        assert_eq!(check_start(&no_limits), Ok(()));
        for c in [
            StartConditions {
                closed_loop: false,
                ..ok_conditions()
            },
            StartConditions {
                operation_enabled: false,
                ..ok_conditions()
            },
            StartConditions {
                velocity: 100.0,
                ..ok_conditions()
            },
            StartConditions {
                velocity: f32::NAN,
                ..ok_conditions()
            },
        ] {
            assert_eq!(check_start(&c), Err(SdoAbort::StateConflict), "{c:?}");
        }
        for c in [
            StartConditions {
                travel: 0,
                ..ok_conditions()
            },
            // 90 000 + 1.2 × 12 500 > 100 000.
            StartConditions {
                position: 90_000,
                ..ok_conditions()
            },
            // The 20 % margin behind the start: −100 000 + 2 500 > −99 000.
            StartConditions {
                position: -99_000,
                ..ok_conditions()
            },
            StartConditions {
                travel: u32::MAX,
                ..ok_conditions()
            },
        ] {
            assert_eq!(check_start(&c), Err(SdoAbort::ValueRangeExceeded), "{c:?}");
        }
    }

    fn ident_cfg() -> IdentConfig {
        IdentConfig {
            ts: SERVO_TS,
            kt: ECN57_20.kt,
            cpr: 4000,
            travel: 1000.0,
            accel: 200.0 * 4000.0,
            accel_max: 1000.0 * 4000.0,
            speed_max: 10.0 * 4000.0,
            iq_target: 2.0,
            iq_max: 5.0,
            cycles: 2,
        }
    }

    #[test]
    fn run_identifies_an_ideal_load_and_a_stop_fails_it() {
        // Ideal shaft with 4 × the rotor inertia following the demand exactly.
        let c = ident_cfg();
        let j = ECN57_20.inertia * 5.0;
        let rad = 2.0 * PI / c.cpr as f32;
        let mut run = TuneRun::new(c, 0, ECN57_20.inertia);
        let mut d = run.step(true, 0.0, 0.0).unwrap();
        while let Some(next) = run.step(true, j * d.acc * rad / c.kt, d.vel + d.acc * c.ts) {
            d = next;
        }
        assert_eq!(run.state(), TuneState::Done);
        let (ratio, _) = run.result().unwrap();
        assert!((ratio - 400.0).abs() < 20.0, "{ratio}");
        let mut p = Params::new(Variant::HybridServo);
        apply(&mut p, ratio);
        assert!((p.get(Param::LoadInertiaRatio) - 400).abs() <= 20);

        let mut stopped = TuneRun::new(c, 0, ECN57_20.inertia);
        assert!(stopped.step(true, 0.0, 0.0).is_some());
        assert_eq!(stopped.state(), TuneState::Running);
        assert!(stopped.step(false, 0.0, 0.0).is_none());
        assert_eq!(stopped.state(), TuneState::Failed);
        assert_eq!(stopped.result(), None);
    }
}
