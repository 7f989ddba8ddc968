//! Trajectory generation: the position / velocity demand of the profile modes.
//!
//! [`Motion`] holds the demand state of the axis — position (an `i32` in command units
//! plus an `f32` fraction in `[0, 1)`, so that long moves never lose counts) and
//! velocity (`f32`, command units/s) — and advances it by one cycle at a time:
//!
//! * [`Motion::ramp_velocity`]: velocity ramp towards a target velocity with separate
//!   acceleration (speed magnitude rising) and deceleration (falling) limits; the
//!   position integrates the velocity (profile velocity, homing searches, stops).
//! * [`Motion::to_position`]: on-line trapezoidal profile to a target position. Each
//!   cycle the allowed speed is the lowest of the profile velocity and the braking
//!   curve `v_b(d) = sqrt(v_e² + 2·a_d·d + (a_d·T/2)²) − a_d·T/2` (`d` the remaining
//!   distance, `v_e` the speed wanted at the target, `T` the cycle time; the `T/2` terms
//!   are the exact discrete-time braking curve), approached with the acceleration limit.
//!   Target, speed and ramps may change at any cycle (PP "change immediately"); a
//!   target behind the axis is reached after a stop and a reversal. The final step lands
//!   exactly on the target, so the demand position of a finished move is the target.
//! * [`Motion::stop`]: ramp to standstill.
//!
//! The generator is on-line (no pre-planned segments), so it costs a fixed, small amount
//! of work per cycle: one square root in [`Motion::to_position`], none otherwise.

/// Result of one [`Motion::to_position`] step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MoveStatus {
    /// Still travelling.
    Moving,
    /// Standing on the target (demand position = target, velocity 0).
    Reached,
    /// Passed the target with the requested through-speed (moving on).
    Passed,
}

/// Demand state of the axis (user position units).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Motion {
    pos: i32,
    frac: f32,
    vel: f32,
}

/// Square root for the braking curve (exact to the last bit: the FPU's `vsqrt` on the
/// target, libm on the host).
#[inline]
fn sqrt(x: f32) -> f32 {
    foc::num::sqrtf(x)
}

/// `floor` for values well inside the `i32` range.
#[inline]
fn floor_i32(x: f32) -> i32 {
    let t = x as i32; // saturating
    if (t as f32) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

impl Motion {
    /// A demand standing at `pos`.
    pub const fn at(pos: i32) -> Self {
        Motion {
            pos,
            frac: 0.0,
            vel: 0.0,
        }
    }

    /// Demand position (integer part, command units).
    #[inline]
    pub fn position(&self) -> i32 {
        self.pos
    }

    /// Demand velocity (command units/s).
    #[inline]
    pub fn velocity(&self) -> f32 {
        self.vel
    }

    /// Places the demand at `pos` with velocity 0 (bumpless enable, CSP take-over).
    pub fn reset(&mut self, pos: i32) {
        self.pos = pos;
        self.frac = 0.0;
        self.vel = 0.0;
    }

    /// Sets the demand directly (cyclic modes): position and velocity feed-forward.
    pub fn set(&mut self, pos: i32, vel: f32) {
        self.pos = pos;
        self.frac = 0.0;
        self.vel = vel;
    }

    /// Moves the integer position to `pos`, keeping the fraction and the velocity
    /// (velocity modes follow the actual position without losing sub-count motion).
    pub fn rebase(&mut self, pos: i32) {
        self.pos = pos;
    }

    /// Shifts the coordinate system by `delta` (homing sets the zero).
    pub fn shift(&mut self, delta: i32) {
        self.pos = self.pos.wrapping_add(delta);
    }

    /// Integrates the current velocity over `dt`.
    #[inline]
    fn advance(&mut self, dt: f32) {
        let d = self.vel * dt + self.frac;
        let w = floor_i32(d);
        self.pos = self.pos.wrapping_add(w);
        self.frac = d - w as f32;
    }

    /// Moves the velocity one step towards `target` and advances the position.
    /// `acc` applies while the speed magnitude rises, `dec` while it falls (a change of
    /// direction first decelerates to 0). A limit ≤ 0 means "no limit" for `dec` (jump)
    /// and "cannot change" for `acc`. Returns true when the velocity equals `target`.
    pub fn ramp_velocity(&mut self, target: f32, acc: f32, dec: f32, dt: f32) -> bool {
        self.vel = ramp(self.vel, target, acc, dec, dt);
        self.advance(dt);
        self.vel == target
    }

    /// Runs at velocity `v` (no ramp) for one cycle (CSV).
    pub fn run_at(&mut self, v: f32, dt: f32) {
        self.vel = v;
        self.advance(dt);
    }

    /// Ramp to standstill with deceleration `dec` (≤ 0: stop at once). True when stopped.
    pub fn stop(&mut self, dec: f32, dt: f32) -> bool {
        self.ramp_velocity(0.0, 0.0, dec, dt)
    }

    /// One step of the on-line trapezoid to `target`.
    ///
    /// `vmax` profile speed, `acc`/`dec` ramps (> 0), `v_through` speed to keep when the
    /// target is reached (0 = stop there; > 0 = pass it, PP "change on set-point"), `v_ss`
    /// start/stop speed (0x6082: the speed may jump from/to 0 below it).
    #[allow(clippy::too_many_arguments)]
    pub fn to_position(
        &mut self,
        target: i32,
        vmax: f32,
        acc: f32,
        dec: f32,
        v_through: f32,
        v_ss: f32,
        dt: f32,
    ) -> MoveStatus {
        let dist = target.wrapping_sub(self.pos) as f32 - self.frac;
        let ad = if dec > 0.0 { dec } else { f32::MAX / 4.0 };
        if dist == 0.0 && self.vel == 0.0 && v_through == 0.0 {
            return MoveStatus::Reached;
        }
        let s = if dist >= 0.0 { 1.0 } else { -1.0 };
        let adist = dist * s;
        let v_floor = if v_through > v_ss { v_through } else { v_ss };
        let h = ad * dt * 0.5;
        let vb = sqrt(v_floor * v_floor + 2.0 * ad * adist + h * h) - h;
        let vlim = if vb < vmax { vb } else { vmax };
        let vdes = s * vlim;
        let mut v = ramp(self.vel, vdes, acc, dec, dt);
        // Start/stop speed: from standstill the speed may jump to v_ss.
        if self.vel == 0.0 && v_ss > 0.0 && v * s < v_ss && v * s >= 0.0 {
            v = s * if vlim < v_ss { vlim } else { v_ss };
        }
        let step = v * dt;
        // Arrives (or would pass) within this cycle while moving towards the target.
        if step * s >= adist && v * s > 0.0 {
            if v_through > 0.0 {
                self.vel = v;
                self.advance(dt);
                return MoveStatus::Passed;
            }
            if v * s <= v_floor + 2.0 * ad * dt {
                self.pos = target;
                self.frac = 0.0;
                self.vel = 0.0;
                return MoveStatus::Reached;
            }
        }
        self.vel = v;
        self.advance(dt);
        MoveStatus::Moving
    }
}

/// Longest moving-average window of [`Smoother`] (cycles).
pub const SMOOTH_MAX: usize = 64;
const _: () = assert!(SMOOTH_MAX.is_power_of_two());

/// Jerk limitation by a moving average over the last `n` demand positions (0x6086 = 3,
/// "jerk-limited ramp"). A trapezoid filtered by an `n`-sample average becomes an
/// S-curve whose jerk phases last `n` cycles (jerk = acceleration / (n·T)); the move
/// takes `(n − 1)·T` longer and ends exactly on the same position, because the average
/// of `n` equal samples is that sample. Positions are kept relative to a base so that
/// the `i64` sum never overflows; one division per cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Smoother {
    ring: [i32; SMOOTH_MAX],
    n: usize,
    idx: usize,
    base: i32,
    sum: i64,
    same: usize,
    last: i32,
    active: bool,
}

impl Default for Smoother {
    fn default() -> Self {
        Smoother {
            ring: [0; SMOOTH_MAX],
            n: 1,
            idx: 0,
            base: 0,
            sum: 0,
            same: 0,
            last: 0,
            active: false,
        }
    }
}

impl Smoother {
    /// True while filtering (from [`Smoother::start`] until settled and switched off).
    pub fn active(&self) -> bool {
        self.active
    }

    /// Starts filtering at the standing position `pos` with a window of `n` cycles.
    pub fn start(&mut self, pos: i32, n: usize) {
        let n = n.clamp(1, SMOOTH_MAX);
        self.ring = [0; SMOOTH_MAX];
        self.n = n;
        self.idx = 0;
        self.base = pos;
        self.sum = 0;
        self.same = n;
        self.last = pos;
        self.active = true;
    }

    /// Stops filtering.
    pub fn stop(&mut self) {
        self.active = false;
    }

    /// True when the last `n` inputs were equal (output = input).
    pub fn settled(&self) -> bool {
        self.same >= self.n
    }

    /// Feeds one input; returns the filtered position. When settled, a different window
    /// `n` is taken over (never in the middle of a move).
    pub fn push(&mut self, pos: i32, n: usize) -> i32 {
        let n = n.clamp(1, SMOOTH_MAX);
        if self.settled() && n != self.n {
            self.start(self.last, n);
        }
        if pos == self.last {
            self.same = self.same.saturating_add(1);
        } else {
            self.same = 1;
        }
        self.last = pos;
        let rel = pos.wrapping_sub(self.base);
        // `idx < n ≤ SMOOTH_MAX` (a power of two): the mask only drops the bounds check.
        let slot = &mut self.ring[self.idx % SMOOTH_MAX];
        self.sum += rel as i64 - *slot as i64;
        *slot = rel;
        self.idx += 1;
        if self.idx >= self.n {
            self.idx = 0;
        }
        if self.settled() {
            // Exactly the input; rebase so that the relative values stay small.
            self.base = pos;
            self.ring = [0; SMOOTH_MAX];
            self.sum = 0;
            return pos;
        }
        // Rounded half away from zero: |sum| ≤ 64·2^32, one unsigned division by n ≥ 1.
        let n = self.n as u64;
        let q = (self.sum.unsigned_abs() + n / 2)
            / core::num::NonZeroU64::new(n).unwrap_or(core::num::NonZeroU64::MIN);
        let q = if self.sum >= 0 { q as i64 } else { -(q as i64) };
        self.base.wrapping_add(q as i32)
    }
}

/// One velocity ramp step (see [`Motion::ramp_velocity`]).
#[inline]
fn ramp(v: f32, target: f32, acc: f32, dec: f32, dt: f32) -> f32 {
    if v == target {
        return v;
    }
    let slowing = (v > 0.0 && target < v) || (v < 0.0 && target > v);
    if slowing {
        if dec <= 0.0 {
            // Unlimited deceleration: at most down to zero when reversing.
            return if (v > 0.0) == (target > 0.0) {
                target
            } else {
                0.0
            };
        }
        let step = dec * dt;
        if v > 0.0 {
            let n = v - step;
            let floor = if target > 0.0 { target } else { 0.0 };
            if n < floor {
                floor
            } else {
                n
            }
        } else {
            let n = v + step;
            let ceil = if target < 0.0 { target } else { 0.0 };
            if n > ceil {
                ceil
            } else {
                n
            }
        }
    } else {
        if acc <= 0.0 {
            return v;
        }
        let step = acc * dt;
        if target > v {
            let n = v + step;
            if n > target {
                target
            } else {
                n
            }
        } else {
            let n = v - step;
            if n < target {
                target
            } else {
                n
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f32 = 0.001;

    fn run_move(start: i32, target: i32, vmax: f32, acc: f32, dec: f32) -> (Motion, u32, f32) {
        let mut m = Motion::at(start);
        let mut n = 0;
        let mut peak = 0.0f32;
        let mut last_v = 0.0f32;
        let mut max_dv = 0.0f32;
        loop {
            let st = m.to_position(target, vmax, acc, dec, 0.0, 0.0, DT);
            peak = peak.max(m.velocity().abs());
            max_dv = max_dv.max((m.velocity() - last_v).abs());
            last_v = m.velocity();
            n += 1;
            if st == MoveStatus::Reached {
                break;
            }
            assert!(n < 1_000_000);
        }
        (m, n, max_dv)
    }

    #[test]
    fn trapezoid_lands_exactly_and_respects_limits() {
        for &(s, t) in &[
            (0, 100_000),
            (5, -77_777),
            (-1_000_000, 1_000_003),
            (0, 3),
            (i32::MAX - 10, i32::MIN + 10),
        ] {
            let (m, n, max_dv) = run_move(s, t, 50_000.0, 200_000.0, 100_000.0);
            assert_eq!(m.position(), t);
            assert_eq!(m.velocity(), 0.0);
            assert!(max_dv <= 200_000.0 * DT * 1.01 + 1.0, "dv {max_dv}");
            let d = t.wrapping_sub(s).unsigned_abs() as f32;
            // Time close to the analytic trapezoid (or triangle) time.
            let ideal = if d > 50_000.0f32.powi(2) / 2.0 * (1.0 / 200_000.0 + 1.0 / 100_000.0) {
                d / 50_000.0 + 50_000.0 / 2.0 * (1.0 / 200_000.0 + 1.0 / 100_000.0)
            } else {
                let vp = libm::sqrtf(2.0 * d / (1.0 / 200_000.0 + 1.0 / 100_000.0));
                vp / 200_000.0 + vp / 100_000.0
            };
            let t_run = n as f32 * DT;
            assert!(
                t_run >= ideal * 0.98 - 2.0 * DT && t_run <= ideal * 1.05 + 0.01,
                "{t_run} vs {ideal}"
            );
        }
    }

    #[test]
    fn target_behind_reverses() {
        let mut m = Motion::at(0);
        for _ in 0..200 {
            m.to_position(1_000_000, 50_000.0, 100_000.0, 100_000.0, 0.0, 0.0, DT);
        }
        assert!(m.velocity() > 0.0);
        let mut n = 0;
        while m.to_position(0, 50_000.0, 100_000.0, 100_000.0, 0.0, 0.0, DT) != MoveStatus::Reached
        {
            n += 1;
            assert!(n < 100_000);
        }
        assert_eq!(m.position(), 0);
    }

    #[test]
    fn velocity_ramp_and_stop() {
        let mut m = Motion::at(0);
        let mut n = 0;
        while !m.ramp_velocity(10_000.0, 100_000.0, 50_000.0, DT) {
            n += 1;
        }
        assert_eq!(n, 99);
        n = 0;
        while !m.ramp_velocity(-10_000.0, 100_000.0, 50_000.0, DT) {
            n += 1;
        }
        // 200 ms down at 50 000/s², then 100 ms up at 100 000/s².
        assert!((295..=305).contains(&n), "{n}");
        while !m.stop(50_000.0, DT) {}
        assert_eq!(m.velocity(), 0.0);
        assert!(m.stop(0.0, DT));
    }

    #[test]
    fn smoothed_trapezoid_is_an_s_curve_ending_on_target() {
        // 1 000 counts/cycle, 10 counts/cycle², window 20 cycles.
        let mut m = Motion::at(100);
        let mut f = Smoother::default();
        f.start(100, 20);
        let mut y_prev = 100;
        let mut v_prev = 0i32;
        let mut max_dv = 0;
        let mut n = 0;
        loop {
            m.to_position(
                1_000_100,
                1_000_000.0,
                10_000_000.0,
                10_000_000.0,
                0.0,
                0.0,
                DT,
            );
            let y = f.push(m.position(), 20);
            let v = y - y_prev;
            max_dv = max_dv.max((v - v_prev).abs());
            y_prev = y;
            v_prev = v;
            n += 1;
            if n == 10 {
                // Jerk-limited start: v ≈ a·k²/(2·20) = 25 instead of a·k = 100.
                assert!((15..=35).contains(&v), "{v}");
            }
            if f.settled() && y == 1_000_100 {
                break;
            }
            assert!(n < 10_000);
        }
        assert!(max_dv <= 11, "{max_dv}");
        assert_eq!(y_prev, 1_000_100);
        // The trapezoid alone takes 1.1 s; the filter adds 19 cycles.
        assert!((1115..=1125).contains(&n), "{n}");
    }

    #[test]
    fn extreme_values_do_not_panic() {
        let mut m = Motion::at(i32::MIN);
        m.run_at(-1.0e12, 1.0);
        m.run_at(f32::MAX, 1.0);
        m.ramp_velocity(f32::MAX, f32::MAX, f32::MAX, 1.0);
        m.to_position(i32::MAX, f32::MAX, f32::MAX, 0.0, f32::MAX, f32::MAX, 1.0);
        m.to_position(i32::MIN, 1.0, 1.0e-30, 1.0e-30, 0.0, 0.0, 1.0e-6);
        m.stop(0.0, 1.0);
        assert_eq!(m.velocity(), 0.0);
        let mut f = Smoother::default();
        f.start(i32::MAX, 1000);
        for p in [i32::MIN, i32::MAX, 0, i32::MIN] {
            f.push(p, 0);
        }
        assert_eq!(floor_i32(-1.0e20), i32::MIN);
        assert_eq!(floor_i32(1.0e20), i32::MAX);
    }

    #[test]
    fn floor_is_floor() {
        for x in [-2.5f32, -2.0, -0.1, 0.0, 0.1, 1.0, 1.9] {
            assert_eq!(floor_i32(x), libm::floorf(x) as i32);
        }
    }
}
