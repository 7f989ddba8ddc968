//! The writable CiA 402 parameters ([`Params`]: the values of the RW objects of
//! [`super::objects`]) and the limits derived from them (maximum velocity,
//! acceleration and deceleration, the stop ramps of the option codes, the software
//! position limits, the interpolation period).

use super::AbortConnection;
use foc::num::clamp;

/// The peak current 0x2000 in per mille of the rated current 0x6075 (which follows
/// it): no torque or current limit goes above it.
pub const PEAK_PERMILLE: u16 = 1000;

/// The writable CiA 402 parameters (values of the RW objects).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Params {
    /// 0x6007 abort connection option code ([`AbortConnection`]).
    pub abort_connection_option: i16,
    /// 0x605A quick stop option code.
    pub quick_stop_option: i16,
    /// 0x605B shutdown option code.
    pub shutdown_option: i16,
    /// 0x605C disable operation option code.
    pub disable_op_option: i16,
    /// 0x605D halt option code.
    pub halt_option: i16,
    /// 0x605E fault reaction option code.
    pub fault_reaction_option: i16,
    /// 0x6065 following error window (0xFFFFFFFF = off).
    pub following_error_window: u32,
    /// 0x6066 following error time-out (ms).
    pub following_error_timeout: u16,
    /// 0x6067 position window.
    pub position_window: u32,
    /// 0x6068 position window time (ms).
    pub position_window_time: u16,
    /// 0x606D velocity window.
    pub velocity_window: u16,
    /// 0x606E velocity window time (ms).
    pub velocity_window_time: u16,
    /// 0x606F velocity threshold (speed zero).
    pub velocity_threshold: u16,
    /// 0x6071 target torque (per mille).
    pub target_torque: i16,
    /// 0x6072 max torque (per mille).
    pub max_torque: u16,
    /// 0x6073 max current (per mille).
    pub max_current: u16,
    /// 0x607A target position.
    pub target_position: i32,
    /// 0x607B:01 min position range limit.
    pub range_min: i32,
    /// 0x607B:02 max position range limit.
    pub range_max: i32,
    /// 0x607C home offset.
    pub home_offset: i32,
    /// 0x607D:01 min software position limit.
    pub sw_limit_min: i32,
    /// 0x607D:02 max software position limit.
    pub sw_limit_max: i32,
    /// 0x607E polarity.
    pub polarity: u8,
    /// 0x607F max profile velocity.
    pub max_profile_velocity: u32,
    /// 0x6080 max motor speed (command units/s).
    pub max_motor_speed: u32,
    /// 0x6081 profile velocity.
    pub profile_velocity: u32,
    /// 0x6082 start/stop speed (E5).
    pub start_stop_speed: u32,
    /// 0x6083 profile acceleration.
    pub profile_acceleration: u32,
    /// 0x6084 profile deceleration.
    pub profile_deceleration: u32,
    /// 0x6085 quick stop deceleration.
    pub quick_stop_deceleration: u32,
    /// 0x6086 motion profile type (0 = trapezoid).
    pub motion_profile_type: i16,
    /// 0x6087 torque slope (per mille/s, 0 = no slope limit).
    pub torque_slope: u32,
    /// 0x6088 torque profile type (0 = linear, the only one).
    pub torque_profile_type: i16,
    /// 0x60C0 interpolation sub mode select (0 = linear, the only one).
    pub interpolation_submode: i16,
    /// 0x6098 homing method.
    pub homing_method: i8,
    /// 0x6099:01 speed during search for switch.
    pub homing_speed_switch: u32,
    /// 0x6099:02 speed during search for zero.
    pub homing_speed_zero: u32,
    /// 0x609A homing acceleration.
    pub homing_acceleration: u32,
    /// 0x60B0 position offset.
    pub position_offset: i32,
    /// 0x60B1 velocity offset.
    pub velocity_offset: i32,
    /// 0x60B2 torque offset (per mille).
    pub torque_offset: i16,
    /// 0x60C2:01 interpolation period value.
    pub interpolation_period: u8,
    /// 0x60C2:02 interpolation period index (power of ten).
    pub interpolation_index: i8,
    /// 0x60C5 max acceleration.
    pub max_acceleration: u32,
    /// 0x60C6 max deceleration.
    pub max_deceleration: u32,
    /// 0x60F2 positioning option code.
    pub positioning_option: u16,
    /// 0x60FE:01 physical outputs.
    pub digital_outputs: u32,
    /// 0x60FE:02 output bit mask.
    pub digital_outputs_mask: u32,
    /// 0x60FF target velocity.
    pub target_velocity: i32,
}

impl Params {
    /// The defaults (same values as the `default` of the dictionary entries).
    pub const DEFAULT: Params = Params {
        abort_connection_option: AbortConnection::Fault as i16,
        quick_stop_option: 2,
        shutdown_option: 0,
        disable_op_option: 1,
        halt_option: 1,
        fault_reaction_option: 2,
        following_error_window: 50_000,
        following_error_timeout: 100,
        position_window: 100,
        position_window_time: 0,
        velocity_window: 100,
        velocity_window_time: 0,
        velocity_threshold: 100,
        target_torque: 0,
        max_torque: 1000,
        max_current: 1000,
        target_position: 0,
        range_min: i32::MIN,
        range_max: i32::MAX,
        home_offset: 0,
        sw_limit_min: i32::MIN,
        sw_limit_max: i32::MAX,
        polarity: 0,
        max_profile_velocity: 5_000_000,
        max_motor_speed: 5_000_000,
        profile_velocity: 50_000,
        start_stop_speed: 0,
        profile_acceleration: 500_000,
        profile_deceleration: 500_000,
        quick_stop_deceleration: 2_000_000,
        motion_profile_type: 0,
        torque_slope: 0,
        torque_profile_type: 0,
        interpolation_submode: 0,
        homing_method: 37,
        homing_speed_switch: 20_000,
        homing_speed_zero: 2_000,
        homing_acceleration: 200_000,
        position_offset: 0,
        velocity_offset: 0,
        torque_offset: 0,
        interpolation_period: 1,
        interpolation_index: -3,
        max_acceleration: 100_000_000,
        max_deceleration: 100_000_000,
        positioning_option: 0,
        digital_outputs: 0,
        digital_outputs_mask: 0,
        target_velocity: 0,
    };

    /// The torque limit in effect: 0x6072, at most the peak current 0x2000 (1000 ‰:
    /// the rated current 0x6075 is the peak current).
    pub(super) fn torque_limit(&self) -> u16 {
        self.max_torque.min(PEAK_PERMILLE)
    }
    /// The current limit in effect: 0x6073, at most the peak current 0x2000.
    pub(super) fn current_limit(&self) -> u16 {
        self.max_current.min(PEAK_PERMILLE)
    }
    /// CSP: the speed of a segment of period `t` (s) that should cover `dist` when the
    /// last segment ran at `v0` and the target itself moves at `vt` (command units,
    /// /s). `None`: `dist / t` is inside the limits (the segment reaches its target);
    /// else the limited speed: at most [`Params::vmax`], changed from `v0` by at most
    /// 0x60C5 × `t` away from standstill and 0x60C6 × `t` towards it, and no faster
    /// than the target's speed plus the speed from which 0x60C6 stops at it.
    pub(super) fn csp_segment_speed(&self, dist: f32, t: f32, v0: f32, vt: f32) -> Option<f32> {
        let want = dist / t;
        let vmax = self.vmax();
        let (acc, dec) = (self.max_acceleration as f32, self.max_deceleration as f32);
        let up = if v0 >= 0.0 { acc } else { dec } * t;
        let down = if v0 <= 0.0 { acc } else { dec } * t;
        if t.is_nan() || t <= 0.0 || (want.abs() <= vmax && want <= v0 + up && want >= v0 - down) {
            return None;
        }
        // The largest speed whose stop, one 0x60C6 step per period, ends within |dist|.
        let dt = dec * t;
        let brake = dt * (foc::num::sqrtf(2.0 * dist.abs() / (dt * t) + 0.25) - 0.5);
        // (`foc::num::clamp`: `f32::clamp`'s panic would bring float formatting in.)
        let vt = clamp(vt, -vmax, vmax);
        let v = if dist >= 0.0 {
            (vt + brake).min(want)
        } else {
            (vt - brake).max(want)
        };
        Some(clamp(clamp(v, v0 - down, v0 + up), -vmax, vmax))
    }
    pub(super) fn vmax(&self) -> f32 {
        self.max_profile_velocity.min(self.max_motor_speed) as f32
    }
    pub(super) fn acc(&self, a: u32) -> f32 {
        a.min(self.max_acceleration) as f32
    }
    pub(super) fn dec(&self, a: u32) -> f32 {
        a.min(self.max_deceleration) as f32
    }
    /// Deceleration of a stop option (1 slow-down, 2 quick-stop, 3/4 limit); `None` =
    /// disable the drive function at once. Out of line: the stop paths of several
    /// states and modes share it.
    // Measured (cargo xtask size, LAN9252 image): dropped with the other hot-path
    // attributes the image grew 1184 B; this, `sw_limits` and `wrap_position` inline into
    // the CSP/PP paths.
    #[inline(never)]
    pub(super) fn option_decel(&self, code: i16) -> Option<f32> {
        match code {
            1 | 5 => Some(self.dec(self.profile_deceleration)),
            2 | 6 => Some(self.quick_stop_deceleration as f32),
            3 | 4 | 7 | 8 => Some(self.max_deceleration as f32),
            _ => None,
        }
    }
    /// The software position limits 0x607D in effect: min < max, not the type limits,
    /// and no position range 0x607B (a wrapping axis has no ends to limit).
    // Measured (cargo xtask size, LAN9252 image): dropped with the other hot-path
    // attributes the image grew 1184 B; see `option_decel`.
    #[inline(never)]
    pub(super) fn sw_limits(&self) -> Option<(i32, i32)> {
        if self.sw_limit_min < self.sw_limit_max
            && (self.sw_limit_min != i32::MIN || self.sw_limit_max != i32::MAX)
            && self.position_range().is_none()
        {
            Some((self.sw_limit_min, self.sw_limit_max))
        } else {
            None
        }
    }
    /// The position range 0x607B in effect: (min, number of positions) when min < max
    /// and the range is narrower than the type's (which wraps by itself).
    pub(super) fn position_range(&self) -> Option<(i32, i64)> {
        let span = i64::from(self.range_max) - i64::from(self.range_min) + 1;
        (span > 1 && span < 1 << 32).then_some((self.range_min, span))
    }
    /// `x` wrapped into the position range 0x607B (unchanged without one).
    // Measured (cargo xtask size, LAN9252 image): dropped with the other hot-path
    // attributes the image grew 1184 B; see `option_decel`.
    #[inline(never)]
    pub(super) fn wrap_position(&self, x: i32) -> i32 {
        match self.position_range() {
            Some((min, span)) => {
                min.wrapping_add((i64::from(x) - i64::from(min)).rem_euclid(span) as i32)
            }
            None => x,
        }
    }
    /// The continuous position an absolute target `t` of the range 0x607B means when
    /// the axis stands at the continuous position `from`: `way` 0 inside the range
    /// (never across its ends, as a linear axis), 1 negative direction only, 2 positive
    /// direction only, 3 the shortest way (0x60F2 bits 6-7). `t` without a range.
    pub(super) fn target_in_range(&self, from: i32, t: i32, way: u16) -> i32 {
        let Some((_, span)) = self.position_range() else {
            return t;
        };
        let mut d = i64::from(self.wrap_position(t)) - i64::from(self.wrap_position(from));
        match way {
            1 if d > 0 => d -= span,
            2 if d < 0 => d += span,
            3 => {
                d = d.rem_euclid(span);
                if d > span / 2 {
                    d -= span;
                }
            }
            _ => {}
        }
        from.wrapping_add(d as i32)
    }
    /// Interpolation period of 0x60C2 in seconds (0 if unset).
    pub fn interpolation_period_s(&self) -> f32 {
        // 10^index for the indices a period can have (-6 µs … +1); the CSP path reads
        // it every step, so a table, not a loop. Others: 0 (unset).
        const POW10: [f32; 8] = [1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0, 10.0];
        let k = (i16::from(self.interpolation_index) + 6) as usize;
        POW10
            .get(k)
            .map_or(0.0, |p| f32::from(self.interpolation_period) * p)
    }
}

impl Default for Params {
    fn default() -> Self {
        Self::DEFAULT
    }
}
