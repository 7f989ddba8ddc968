//! The motion layer's configuration: the motor's mechanical constants and
//! [`MotionConfig`], taken from the vendor parameters (gain scaling: see the module
//! docs of [`super`]).

use super::{finite_pos, stall, SERVO_TS};
use crate::identity::Variant;
use crate::params::{Param, Params};
use crate::servo_tune::{TuneSetup, BASE_BANDWIDTH_HZ};
use foc::open_loop::OpenLoopConfig;
use foc::servo::ServoGains;
use foc::stall::StallConfig;

/// Mechanical constants the base gains need (not among the vendor parameters: the
/// board knows its motor).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorConstants {
    /// Rotor (+ load) inertia, kg·m².
    pub inertia: f32,
    /// Torque constant, N·m/A (FOC peak current); also the back-EMF constant, V·s/rad.
    pub kt: f32,
    /// Phase resistance, Ω (the stall detection's model until 0x2020/0x2021 hold a
    /// tuned motor).
    pub resistance: f32,
    /// Phase inductance, H (likewise).
    pub inductance: f32,
}

/// ECN57-20 (NEMA 23): 480 g·cm², 0.283 N·m/A, 0.40 Ω, 1.8 mH.
pub const ECN57_20: MotorConstants = MotorConstants {
    inertia: 480e-7,
    kt: 0.283,
    resistance: 0.40,
    inductance: 1.8e-3,
};
/// TC86-45 (NEMA 34): 1400 g·cm², 0.530 N·m/A, 0.325 Ω, 3.0 mH.
pub const TC86_45: MotorConstants = MotorConstants {
    inertia: 1400e-7,
    kt: 0.530,
    resistance: 0.325,
    inductance: 3.0e-3,
};

/// Configuration of [`Motion`](super::Motion) (from the parameters: [`MotionConfig::from_params`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionConfig {
    /// Servo period, s.
    pub ts: f32,
    /// Command units per revolution (0x2001, active copy).
    pub pulses_per_rev: u32,
    /// Encoder counts per revolution (0x2029 × 4; 0 = no encoder).
    pub counts_per_rev: u32,
    /// Closed loop (0x2024 = 2 and an encoder).
    pub closed_loop: bool,
    /// Peak current 0x2000, A.
    pub peak_current: f32,
    /// Holding current 0x2026, % (open loop).
    pub holding_percent: u8,
    /// Stand-still time before the holding current 0x2002, s.
    pub standby_s: f32,
    /// Soft start 0x2058, s.
    pub soft_start_s: f32,
    /// Command smoothing (0x2009 on: 0x2010:2), s; 0 = off.
    pub filter_s: f32,
    /// Direction reversal 0x2051.
    pub reverse: bool,
    /// Following-error limit 0x2030, counts.
    pub following_error_limit: u32,
    /// Servo gains (physical units, after the parameter scaling).
    pub gains: ServoGains,
    /// Open-loop anti-resonance damping gain 0x2059, s (0 = off; `foc::damping`).
    pub damping_s: f32,
    /// Open-loop stall detection (0x2060 = 1; 0x2061 → threshold), `None` when off.
    pub stall: Option<StallConfig>,
    /// The servo tune's move (0x2163, the motor; [`crate::servo_tune`]).
    pub tune: TuneSetup,
}

impl MotionConfig {
    /// The configuration the parameters describe for a motor with `motor` constants and
    /// servo period `ts` (see the module docs for the gain scaling).
    pub fn from_params(p: &Params, variant: Variant, motor: &MotorConstants, ts: f32) -> Self {
        let ts = if ts.is_finite() && ts > 0.0 {
            ts
        } else {
            SERVO_TS
        };
        let counts = if variant.has_encoder() {
            (p.get(Param::EncoderResolution).clamp(1, 1 << 20) as u32) * 4
        } else {
            0
        };
        let ppr = match p.active().pulses_per_rev {
            0 => p.get(Param::PulsesPerRev),
            n => n as i32,
        }
        .clamp(1, 1 << 24) as u32;
        // Peak and holding current, direction and smoothing: the objects' or the DIP
        // function switches' (`Params::settings`).
        let settings = p.settings();
        let peak = f32::from(settings.peak_current_ma) * 1e-3;
        // Parameter values are always inside their range in the `params` table (every
        // write is checked, internal sets are clamped): the gains and the holding
        // current need no clamp of their own here.
        let g = |x: Param| p.get(x) as u16;
        // Rotor inertia × (1 + load ratio 0x2160 %).
        let load = 1.0 + p.get(Param::LoadInertiaRatio).clamp(0, 5000) as f32 * 0.01;
        let base = ServoGains::from_bandwidth(
            finite_pos(motor.inertia).max(1e-9) * load,
            finite_pos(motor.kt).max(1e-6),
            counts.max(4),
            BASE_BANDWIDTH_HZ,
            peak,
        );
        let gains = base.scaled(
            g(Param::PosKp),
            g(Param::PosKi),
            g(Param::VelFf),
            g(Param::SpeedKp).max(1),
        );
        let filter_s = settings.smoothing_us.min(1_000_000) as f32 * 1e-6;
        MotionConfig {
            ts,
            pulses_per_rev: ppr,
            counts_per_rev: counts,
            closed_loop: counts > 0 && p.get(Param::LoopMode) == 2,
            peak_current: peak,
            holding_percent: settings.holding_percent,
            standby_s: p.get(Param::StandbyTime).clamp(0, 100_000) as f32 * 1e-3,
            soft_start_s: p.get(Param::SoftStart).clamp(0, 100_000) as f32 * 50e-6,
            filter_s,
            reverse: settings.direction_reversed,
            following_error_limit: p.get(Param::FollowingErrorLimit).clamp(1, 1 << 24) as u32,
            gains,
            damping_s: p.get(Param::ResonanceDamping) as f32 * 1e-6,
            stall: stall::config_from_params(p, motor, ts),
            tune: TuneSetup::from_params(p, counts, motor.kt, motor.inertia, load),
        }
    }

    pub(super) fn open_loop_config(&self) -> OpenLoopConfig {
        OpenLoopConfig {
            pulses_per_rev: self.pulses_per_rev.max(1),
            ts: self.ts,
            running_current: self.peak_current,
            holding_percent: self.holding_percent,
            standby: self.standby_s,
            soft_start: self.soft_start_s,
            filter_time: self.filter_s,
        }
    }
}
