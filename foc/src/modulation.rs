//! Voltage limit and PWM duty cycles for two full H-bridges.
//!
//! Each phase has its own H-bridge with legs 1 and 2 driven three-level,
//! centre-aligned: `duty₁ = ½ + v/(2·Vbus)`, `duty₂ = ½ − v/(2·Vbus)`, so the average
//! bridge voltage is `(duty₁ − duty₂)·Vbus = v` and both legs switch symmetrically
//! around the period centre (ripple at twice the PWM frequency). Dividing by the
//! measured bus voltage is the bus-voltage compensation.
//!
//! The voltage vector `(v_A, v_B)` is limited to a circle of radius `m_max·Vbus`
//! ([`M_MAX`] = 0.95 leaves room for dead time and current-sampling blanking).

use crate::num;

/// Default modulation limit as a fraction of the bus voltage.
pub const M_MAX: f32 = 0.95;

/// Compare values of the four PWM legs, in timer counts (`0..=period`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Duties {
    /// Phase A, leg 1.
    pub a1: u16,
    /// Phase A, leg 2.
    pub a2: u16,
    /// Phase B, leg 1.
    pub b1: u16,
    /// Phase B, leg 2.
    pub b2: u16,
}

impl Duties {
    /// All legs at 50 %: zero volts on both phases (bridges active, motor shorted).
    pub fn zero(period: u16) -> Self {
        // Same rounding as `Modulator::duties` (half period rounded up).
        let h = period.div_ceil(2);
        Duties {
            a1: h,
            a2: h,
            b1: h,
            b2: h,
        }
    }
}

/// Limits `(a, b)` to the circle of radius `vmax` (direction kept). Returns the
/// limited pair and whether it was limited. `vmax ≤ 0` or non-finite input gives 0.
#[inline]
pub fn limit_circle(a: f32, b: f32, vmax: f32) -> (f32, f32, bool) {
    let m2 = a * a + b * b;
    let v2 = vmax * vmax;
    if m2 <= v2 {
        (a, b, false)
    } else if m2.is_finite() && vmax > 0.0 {
        let k = vmax * num::rsqrt(m2);
        (a * k, b * k, true)
    } else {
        (0.0, 0.0, true)
    }
}

/// PWM modulator: converts phase voltages into compare values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Modulator {
    /// Timer period in counts (compare value for 100 % duty).
    pub period: u16,
    /// Modulation limit, fraction of the bus voltage.
    pub m_max: f32,
}

impl Modulator {
    /// New modulator for a timer with `period` counts and the default [`M_MAX`].
    pub fn new(period: u16) -> Self {
        Modulator {
            period,
            m_max: M_MAX,
        }
    }

    /// Largest voltage-vector magnitude at bus voltage `vbus` (V).
    #[inline]
    pub fn vmax(&self, vbus: f32) -> f32 {
        num::pos(self.m_max * vbus)
    }

    /// Duties for phase voltages `va`, `vb` (V) at bus voltage `vbus` (V). Each
    /// normalised voltage is clamped to `[-1, 1]`; a bus voltage below 1 V gives 0 V.
    #[inline]
    pub fn duties(&self, va: f32, vb: f32, vbus: f32) -> Duties {
        let half = 0.5 * self.period as f32;
        let g = if vbus > 1.0 { half / vbus } else { 0.0 };
        // Offsets in counts from the half period, clamped to ±half.
        let da = num::clamp(va * g, -half, half);
        let db = num::clamp(vb * g, -half, half);
        // + 0.5 rounds to nearest; `as u16` saturates.
        Duties {
            a1: (half + da + 0.5) as u16,
            a2: (half - da + 0.5) as u16,
            b1: (half + db + 0.5) as u16,
            b2: (half - db + 0.5) as u16,
        }
    }

    /// Average bridge voltages `(v_A, v_B)` produced by `d` at bus voltage `vbus`
    /// (the ideal average model; the inverse of [`Modulator::duties`]).
    pub fn voltages(&self, d: &Duties, vbus: f32) -> (f32, f32) {
        let p = self.period.max(1) as f32;
        (
            (d.a1 as f32 - d.a2 as f32) / p * vbus,
            (d.b1 as f32 - d.b2 as f32) / p * vbus,
        )
    }
}
