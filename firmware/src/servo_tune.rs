//! Servo gains from the load inertia and a stiffness level (0x2160, 0x2161).
//!
//! The base gains of the motion layer (`motion`) are designed for the rotor
//! inertia times `1 + 0x2160/100`, so with the load ratio known the parameters
//! 0x2137-0x2140 only choose the bandwidth. The stiffness 0x2161 names that choice:
//!
//! | 0x2161 | 1 | 2 | 3 | 4 | 5 | 6 | 7 | 8 | 9 | 10 | 11 | 12 | 13 | 14 | 15 | 16 |
//! |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|
//! | velocity bandwidth, Hz | 20 | 30 | 40 | 50 | 65 | 80 | 100 | 120 | 140 | 170 | 200 | 240 | 280 | 320 | 360 | 400 |
//!
//! For a velocity bandwidth `f` the gains are ([`StiffnessGains::for_level`]):
//! * 0x2140 (velocity loop) `= 100·f/`[`BASE_BANDWIDTH_HZ`];
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
//! # The identification move
//! * **Start** (0x2162:01 = 1, [`TuneControl::start`], [`check_start`]): closed loop,
//!   Operation enabled in PP or CSP without halt, the demand at rest (below 1 % of a
//!   revolution per second; the actual axis may hunt about its position: a load the
//!   gains do not suit yet is what the tune is for), and the travel 0x2163 (0.1° of
//!   the shaft, forward from the actual position), with 20 % of it on both sides for
//!   the following error of the move, inside the software limits 0x607D, and no
//!   hardware limit switch active (0x60FD bits 0/1). A refusal is 0x08000022 (state,
//!   a limit switch) or 0x06090030 (travel), and 0x2162:02 reads 3. The move's speed
//!   is at most min([`SPEED_MAX`], 0x607F, 0x6080); a limit switch or the axis
//!   outside 0x607D during the move ends it (failed), and the mode stops the axis
//!   from where it is.
//! * **Move** (`motion`, `motion/tune.rs`): the drive hands the set-points to
//!   the motion layer ([`crate::cia402::SetpointKind::Tune`]); its generator follows
//!   the actual position and speed, so that any stop ramp starts from the actual
//!   motion. The motion layer runs a [`TuneRun`] ([`foc::identify::IdentMove`]: a
//!   probe cycle at [`PROBE_ACCEL`], three fitted cycles at the acceleration that
//!   gives [`IQ_TARGET`] of the current limit, at most [`ACCEL_MAX`] and
//!   [`SPEED_MAX`]) with the gains of [`move_gains`], then holds the start until the
//!   axis stands there ([`SETTLE_S`] within [`SETTLE_WINDOW`], [`settle_gains`]) and
//!   reports the result in the axis state ([`TuneReport`]).
//! * **End** ([`TuneControl::update`], once per tick): a result goes to the
//!   parameters with [`apply`] (0x2160 and the gains of 0x2161; not saved) and to
//!   0x2164 (ratio, %) and 0x2165 (Coulomb friction, mN·m), and the mode takes the
//!   set-points back at rest. A stop (0x2162:01 = 0), halt, quick stop, disable,
//!   fault or another mode fails the tune (0x2162:02 = 4) and stops the axis on the
//!   state's own ramp from where it is; so does a run that gives no result (too
//!   little travel, the current at its limit, an ill-conditioned fit).
//!
//! The inertia is what the tune is for (±3 % on the plant, `tests-host`
//! `servo_tune`); the friction is a by-product: the Coulomb term is of the order of
//! the fit's noise on a lightly loaded axis, so 0x2165 is indicative.

use crate::params::{Param, Params};
use ecat_slave_stack::od::SdoAbort;
use foc::identify::{IdentConfig, IdentMove, IdentState};
use foc::servo::{Demand, ServoGains};

/// Velocity bandwidth of the base gains (0x2140 = 100), Hz: the motion layer designs
/// its base gains for it (`motion::MotionConfig`), the stiffness levels scale from it.
pub const BASE_BANDWIDTH_HZ: f32 = 400.0;

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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u8)]
pub enum TuneState {
    /// No tune since power-up.
    #[default]
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

/// The move's configuration from the parameters and the motor (part of
/// `motion::MotionConfig`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TuneSetup {
    /// Stroke 0x2163 in encoder counts.
    pub travel: f32,
    /// Torque constant, N·m/A.
    pub kt: f32,
    /// Rotor inertia, kg·m².
    pub j_rotor: f32,
    /// The factor `1 + 0x2160/100` the base gains were designed with.
    pub load: f32,
}

impl TuneSetup {
    /// Travel 0x2163 (0.1°) at `counts_per_rev`, for a motor of torque constant `kt` and
    /// rotor inertia `j_rotor`, gains designed for `load` × the rotor inertia.
    pub fn from_params(p: &Params, counts_per_rev: u32, kt: f32, j_rotor: f32, load: f32) -> Self {
        TuneSetup {
            travel: p.get(Param::TuneTravel) as f32 * counts_per_rev as f32 / 3600.0,
            kt,
            j_rotor,
            load,
        }
    }
}

/// Acceleration of the probe cycle, rev/s² (module docs of [`foc::identify`]).
pub const PROBE_ACCEL: f32 = 50.0;
/// Highest acceleration of the fitted cycles, rev/s².
pub const ACCEL_MAX: f32 = 1000.0;
/// Highest speed of the move, rev/s.
pub const SPEED_MAX: f32 = 10.0;
/// Peak current the fitted cycles aim at, fraction of the current limit.
pub const IQ_TARGET: f32 = 0.4;

/// The identification move of `tune` at the servo period `ts` (s), `counts_per_rev`
/// encoder counts per revolution and the current limit `iq_max` (A): [`PROBE_ACCEL`],
/// [`ACCEL_MAX`], [`SPEED_MAX`], [`IQ_TARGET`] of `iq_max`, three fitted cycles.
pub fn ident_config(tune: &TuneSetup, ts: f32, counts_per_rev: u32, iq_max: f32) -> IdentConfig {
    let rev = counts_per_rev as f32;
    IdentConfig {
        ts,
        kt: tune.kt,
        cpr: counts_per_rev,
        travel: tune.travel,
        accel: PROBE_ACCEL * rev,
        accel_max: ACCEL_MAX * rev,
        speed_max: SPEED_MAX * rev,
        iq_target: IQ_TARGET * iq_max,
        iq_max,
        cycles: 3,
    }
}

/// The load factor `1 + 0x2160/100` the configured gains were designed for.
fn designed_load(tune: &TuneSetup) -> f32 {
    if tune.load >= 1.0 {
        tune.load
    } else {
        1.0
    }
}

/// The servo gains of the move: [`foc::identify::move_gains`] of the base gains for
/// the rotor alone (the configured `gains`, designed for `tune.load` × the rotor
/// inertia, the velocity loop's gains divided by it).
pub fn move_gains(gains: &ServoGains, tune: &TuneSetup) -> ServoGains {
    let load = designed_load(tune);
    foc::identify::move_gains(&ServoGains {
        kv: gains.kv / load,
        ki_vel: gains.ki_vel / load,
        acc_ff: gains.acc_ff / load,
        ..*gains
    })
}

/// The gains while a finished move settles at its start: the move's ([`move_gains`]:
/// the rotor's velocity loop, whose bandwidth falls as `1/(1 + ratio)` with the load,
/// and a soft position loop: no current step from the last stroke's following error,
/// and encoder noise amplified no more than during the move) plus the velocity
/// loop's integral for that lower bandwidth (`ki_vel/(1 + ratio)`, the corner in the
/// same proportion as designed): the move has none, and friction would hold the axis
/// off the start.
pub fn settle_gains(gains: &ServoGains, tune: &TuneSetup, ratio_percent: f32) -> ServoGains {
    let found = 1.0 + foc::num::clamp(ratio_percent, 0.0, 5000.0) * 0.01;
    ServoGains {
        ki_vel: gains.ki_vel / designed_load(tune) / found,
        ..move_gains(gains, tune)
    }
}

/// What the motion layer reports of its tunes (`motion::AxisState::servo_tune`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TuneReport {
    /// Moves started so far (wrapping).
    pub runs: u8,
    /// State of the last one.
    pub state: TuneState,
    /// Identified load ratio, % (0x2164), when `state` is [`TuneState::Done`].
    pub ratio_percent: u16,
    /// Identified Coulomb friction, mN·m (0x2165), likewise.
    pub friction_mnm: u16,
}

/// What [`check_start`] looks at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StartConditions {
    /// Closed loop in effect (0x2024 = 2 with an encoder).
    pub closed_loop: bool,
    /// CiA 402 state Operation enabled in a position mode (PP or CSP) without halt.
    pub operation_enabled: bool,
    /// Velocity demand, command units/s (the axis is commanded to stand; it may hunt
    /// about its position: a load the gains do not suit yet is what the tune is for).
    pub velocity: f32,
    /// Command units per revolution.
    pub units_per_rev: u32,
    /// Actual position, command units.
    pub position: i32,
    /// Travel 0x2163, command units.
    pub travel: u32,
    /// Software limits 0x607D in effect (min, max), command units.
    pub limits: Option<(i32, i32)>,
    /// A hardware limit switch is active (0x60FD bit 0 or 1).
    pub limit_switch: bool,
}

/// Whether a tune may start (see the module docs).
pub fn check_start(c: &StartConditions) -> Result<(), SdoAbort> {
    let rest = c.units_per_rev as f32 * 0.01;
    let still = c.velocity.is_finite() && c.velocity.abs() <= rest;
    if !(c.closed_loop && c.operation_enabled && still) || c.limit_switch {
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

/// How long a finished move holds its start position within [`SETTLE_WINDOW`] before
/// it reports done, s ([`TunePhase::Settling`]): the following error of the last
/// stroke settles, so the axis stands at the start when the drive takes the
/// set-points back.
pub const SETTLE_S: f32 = 0.1;
/// Position window of the settling, encoder counts.
pub const SETTLE_WINDOW: i32 = 3;
/// Longest settling, s: then the tune reports done wherever the axis stands.
pub const SETTLE_MAX_S: f32 = 1.0;

/// Where a [`TuneRun`] stands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TunePhase {
    /// The identification move runs (the move's gains).
    Moving,
    /// The move gave the load ratio (%) and holds its start until it has stood
    /// within [`SETTLE_WINDOW`] for [`SETTLE_S`] ([`settle_gains`]).
    Settling(f32),
    /// Over (done or failed).
    Ended,
}

/// A running identification move and its outcome.
#[derive(Debug, Clone, Copy)]
pub struct TuneRun {
    ident: IdentMove,
    j_rotor: f32,
    /// Servo steps the axis must still stand in the window ([`SETTLE_S`]).
    settle_left: u32,
    /// Servo steps of settling left ([`SETTLE_MAX_S`]).
    settle_max: u32,
    settle_steps: u32,
}

impl TuneRun {
    /// Starts the move `cfg` at the actual position `start` (counts) for a motor of
    /// rotor inertia `j_rotor` (kg·m²).
    pub fn new(cfg: IdentConfig, start: i32, j_rotor: f32) -> Self {
        let mut run = TuneRun {
            ident: IdentMove::new(cfg, start),
            j_rotor,
            settle_left: 0,
            settle_max: 0,
            settle_steps: 0,
        };
        run.restart(cfg, start, j_rotor);
        run
    }

    /// [`TuneRun::new`] in place (the servo interrupt starts runs with it).
    pub fn restart(&mut self, cfg: IdentConfig, start: i32, j_rotor: f32) {
        let steps = |s: f32| {
            let n = if cfg.ts > 0.0 { s / cfg.ts } else { 0.0 };
            foc::num::clamp(n, 1.0, 1e6) as u32
        };
        self.ident.restart(cfg, start);
        self.j_rotor = j_rotor;
        self.settle_steps = steps(SETTLE_S);
        self.settle_left = self.settle_steps;
        self.settle_max = steps(SETTLE_MAX_S);
    }

    /// One servo step (see [`IdentMove::step`]) with the axis at `pos` (counts): the
    /// demand for the next step; once the move has ended, the start position at
    /// rest, reported running until the axis has settled there.
    pub fn step(&mut self, iq: f32, vel: f32, pos: i32) -> Demand {
        let d = self.ident.step(iq, vel);
        if matches!(self.ident.state, IdentState::Done(_)) && self.settle_left > 0 {
            self.settle_max = self.settle_max.saturating_sub(1);
            self.settle_left = if self.settle_max == 0 {
                0
            } else if d.pos.wrapping_sub(pos).unsigned_abs() <= SETTLE_WINDOW as u32 {
                self.settle_left - 1
            } else {
                self.settle_steps
            };
        }
        d
    }

    /// Ends a running move as failed (stop, fault, disable, another set-point).
    pub fn abort(&mut self) {
        self.ident.abort();
    }

    /// Where the run stands.
    pub fn phase(&self) -> TunePhase {
        match self.ident.state {
            IdentState::Running => TunePhase::Moving,
            IdentState::Done(i) if self.settle_left > 0 => {
                TunePhase::Settling(i.load_ratio_percent(self.j_rotor))
            }
            _ => TunePhase::Ended,
        }
    }

    /// The state 0x2162 reports.
    pub fn state(&self) -> TuneState {
        match self.ident.state {
            IdentState::Running => TuneState::Running,
            IdentState::Done(_) if self.settle_left > 0 => TuneState::Running,
            IdentState::Done(_) => TuneState::Done,
            IdentState::Failed(_) => TuneState::Failed,
        }
    }

    /// The identified load ratio (%, 0x2164) and Coulomb friction (mN·m, 0x2165).
    pub fn result(&self) -> Option<(f32, f32)> {
        match self.ident.state {
            IdentState::Done(i) if self.settle_left == 0 => {
                Some((i.load_ratio_percent(self.j_rotor), i.tc * 1e3))
            }
            _ => None,
        }
    }

    /// The report of this run, the `runs`th.
    pub fn report(&self, runs: u8) -> TuneReport {
        let (ratio, friction) = self.result().unwrap_or((0.0, 0.0));
        let u16_of = |x: f32| {
            if x.is_finite() {
                foc::num::clamp(x + 0.5, 0.0, 65535.0) as u16
            } else {
                0
            }
        };
        TuneReport {
            runs,
            state: self.state(),
            ratio_percent: u16_of(ratio),
            friction_mnm: u16_of(friction),
        }
    }
}

/// How long an accepted start waits for the motion layer to begin the move, ms.
pub const START_TIMEOUT_MS: u32 = 50;

/// The drive's side of the tune (0x2162): the start and stop requests, the run the
/// motion layer reports ([`TuneReport`] in the axis state), the end.
#[derive(Debug, Clone, Copy, Default)]
pub struct TuneControl {
    state: TuneState,
    /// [`TuneReport::runs`] when the start was accepted: the run is this start's once
    /// the count has moved.
    runs_at_start: u8,
    /// Milliseconds the start has waited for its run.
    waited_ms: u32,
}

impl TuneControl {
    /// The state 0x2162:02 reports.
    pub fn state(&self) -> TuneState {
        self.state
    }

    /// The CiA 402 layer is to run the move's set-points.
    pub fn running(&self) -> bool {
        self.state == TuneState::Running
    }

    /// 0x2162:01 = 1 under the conditions `c`; `report`: the motion layer's latest.
    /// A tune already running is not restarted (0x08000022); a refusal
    /// ([`check_start`]) is reported as [`TuneState::Refused`].
    pub fn start(&mut self, c: &StartConditions, report: &TuneReport) -> Result<(), SdoAbort> {
        if self.running() {
            return Err(SdoAbort::StateConflict);
        }
        if let Err(e) = check_start(c) {
            self.state = TuneState::Refused;
            return Err(e);
        }
        *self = TuneControl {
            state: TuneState::Running,
            runs_at_start: report.runs,
            waited_ms: 0,
        };
        Ok(())
    }

    /// 0x2162:01 = 0: a running tune fails (stopped by the user).
    pub fn stop(&mut self) {
        if self.running() {
            self.state = TuneState::Failed;
        }
    }

    /// Once per tick (`dt_ms` since the last): the motion layer's `report` and whether
    /// the CiA 402 layer still runs the move (`active`). Returns the report of a run
    /// that has just finished with a result (to be applied, [`apply`]). The tune
    /// fails when its run fails, when the set-points go elsewhere (stop, fault,
    /// disable, halt, another mode) or when no run begins within
    /// [`START_TIMEOUT_MS`].
    pub fn update(&mut self, report: &TuneReport, active: bool, dt_ms: u32) -> Option<TuneReport> {
        if !self.running() {
            return None;
        }
        if report.runs != self.runs_at_start {
            match report.state {
                TuneState::Done => {
                    self.state = TuneState::Done;
                    return Some(*report);
                }
                TuneState::Running => {}
                _ => self.state = TuneState::Failed,
            }
        } else {
            self.waited_ms = self.waited_ms.saturating_add(dt_ms);
            if self.waited_ms > START_TIMEOUT_MS {
                self.state = TuneState::Failed;
            }
        }
        if !active {
            self.state = TuneState::Failed;
        }
        None
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
            units_per_rev: 4000,
            position: 0,
            travel: 12_500,
            limits: Some((-100_000, 100_000)),
            limit_switch: false,
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
                limit_switch: true,
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
    fn run_identifies_an_ideal_load_and_an_abort_fails_it() {
        // Ideal shaft with 4 × the rotor inertia following the demand exactly.
        let c = ident_cfg();
        let j = ECN57_20.inertia * 5.0;
        let rad = 2.0 * PI / c.cpr as f32;
        let mut run = TuneRun::new(c, 0, ECN57_20.inertia);
        let mut d = run.step(0.0, 0.0, 0);
        let mut n = 0;
        while run.state() == TuneState::Running {
            d = run.step(j * d.acc * rad / c.kt, d.vel + d.acc * c.ts, d.pos);
            assert!((-1..=1001).contains(&d.pos), "{d:?}");
            n += 1;
            assert!(n < 100_000);
        }
        assert_eq!(run.state(), TuneState::Done);
        // Once ended: the start position at rest.
        assert_eq!(run.step(0.0, 0.0, 0), Demand::default());
        let (ratio, _) = run.result().unwrap();
        assert!((ratio - 400.0).abs() < 20.0, "{ratio}");
        let r = run.report(3);
        assert_eq!((r.runs, r.state), (3, TuneState::Done));
        assert!((i32::from(r.ratio_percent) - 400).abs() <= 20, "{r:?}");
        let mut p = Params::new(Variant::HybridServo);
        apply(&mut p, ratio);
        assert!((p.get(Param::LoadInertiaRatio) - 400).abs() <= 20);

        let mut stopped = TuneRun::new(c, 0, ECN57_20.inertia);
        stopped.step(0.0, 0.0, 0);
        assert_eq!(stopped.state(), TuneState::Running);
        stopped.abort();
        assert_eq!(stopped.state(), TuneState::Failed);
        assert_eq!(stopped.result(), None);
        assert_eq!(stopped.report(1).ratio_percent, 0);
        // A configuration without travel fails at once.
        let bad = TuneRun::new(IdentConfig { travel: 0.0, ..c }, 0, ECN57_20.inertia);
        assert_eq!(bad.state(), TuneState::Failed);
    }

    fn report(runs: u8, state: TuneState) -> TuneReport {
        TuneReport {
            runs,
            state,
            ratio_percent: 480,
            friction_mnm: 12,
        }
    }

    #[test]
    fn control_follows_its_own_run_to_the_result() {
        let mut t = TuneControl::default();
        assert_eq!(t.state(), TuneState::Idle);
        // The previous run's Done is not this start's.
        let old = report(4, TuneState::Done);
        t.start(&ok_conditions(), &old).unwrap();
        assert!(t.running());
        assert_eq!(t.update(&old, true, 1), None);
        assert_eq!(
            t.start(&ok_conditions(), &old),
            Err(SdoAbort::StateConflict),
            "no restart while running"
        );
        assert_eq!(t.update(&report(5, TuneState::Running), true, 1), None);
        assert!(t.running());
        let done = report(5, TuneState::Done);
        assert_eq!(t.update(&done, true, 1), Some(done));
        assert_eq!(t.state(), TuneState::Done);
        // Reported once.
        assert_eq!(t.update(&done, true, 1), None);
        assert_eq!(t.state(), TuneState::Done);
    }

    #[test]
    fn control_fails_on_stop_lost_setpoints_failed_run_or_no_run() {
        let idle = report(0, TuneState::Idle);
        let running = report(1, TuneState::Running);
        let mut t = TuneControl::default();
        t.start(&ok_conditions(), &idle).unwrap();
        t.stop();
        assert_eq!(t.state(), TuneState::Failed);

        t.start(&ok_conditions(), &idle).unwrap();
        assert_eq!(t.update(&running, false, 1), None);
        assert_eq!(t.state(), TuneState::Failed, "the CiA 402 layer took over");

        t.start(&ok_conditions(), &running).unwrap();
        assert_eq!(t.update(&report(2, TuneState::Failed), true, 1), None);
        assert_eq!(t.state(), TuneState::Failed);

        t.start(&ok_conditions(), &running).unwrap();
        for _ in 0..START_TIMEOUT_MS {
            t.update(&running, true, 1);
        }
        assert!(t.running());
        t.update(&running, true, 1);
        assert_eq!(t.state(), TuneState::Failed, "no run began");

        // A refused start is reported as refused, and keeps nothing running.
        let far = StartConditions {
            position: 95_000,
            ..ok_conditions()
        };
        assert_eq!(t.start(&far, &running), Err(SdoAbort::ValueRangeExceeded));
        assert_eq!(t.state(), TuneState::Refused);
        assert!(!t.running());
    }
}
