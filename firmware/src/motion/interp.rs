//! The motion layer's linear interpolation of the cycle's set-points.

/// Linear interpolation of the cycle's set-points in counts (integer + fraction).
#[derive(Debug, Clone, Copy)]
pub(super) struct Interp {
    from_w: i32,
    from_f: f32,
    to_w: i32,
    to_f: f32,
    delta: f32,
    k: u32,
    n: u32,
    inv_n: f32,
    pub(super) vel: f32,
}

impl Interp {
    pub(super) fn at(w: i32, f: f32) -> Self {
        Interp {
            from_w: w,
            from_f: f,
            to_w: w,
            to_f: f,
            delta: 0.0,
            k: 1,
            n: 1,
            inv_n: 1.0,
            vel: 0.0,
        }
    }
    pub(super) fn target(&mut self, w: i32, f: f32, n: u32, cycle_s: f32) {
        self.from_w = self.to_w;
        self.from_f = self.to_f;
        self.to_w = w;
        self.to_f = f;
        self.delta = w.wrapping_sub(self.from_w) as f32 + (f - self.from_f);
        self.n = n.max(1);
        self.inv_n = 1.0 / self.n as f32;
        self.k = 0;
        self.vel = if cycle_s > 0.0 {
            self.delta / cycle_s
        } else {
            0.0
        };
    }
    /// Demand of the next step and whether the demand is still moving.
    pub(super) fn step(&mut self) -> (i32, f32, bool) {
        if self.k < self.n {
            self.k += 1;
        }
        let moving = self.k < self.n || self.delta != 0.0;
        if self.k >= self.n {
            // At the target: exact, no rounding of delta·k/n.
            self.delta = 0.0;
            self.from_w = self.to_w;
            self.from_f = self.to_f;
            return (self.to_w, self.to_f, moving);
        }
        let d = self.from_f + self.delta * (self.k as f32 * self.inv_n);
        // floor without the library call (`as` saturates, NaN → 0).
        let mut whole = d as i32;
        if (whole as f32) > d {
            whole -= 1;
        }
        (self.from_w.wrapping_add(whole), d - whole as f32, moving)
    }
}
