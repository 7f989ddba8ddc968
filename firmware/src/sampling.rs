//! Analog samples of the power stage and the start-up calibration of the current
//! sensors.
//!
//! Chip-independent. The board binary reads the ADC injected data registers in the
//! ADC end-of-sequence interrupt (once per PWM period, at the PWM centre) into a
//! [`RawSample`] and runs the current loop on it there
//! (`control_core::ControlCore::period`); the rest of the drive reads the
//! supervised values through `board_glue::Exchange`, the one seqlock of the
//! board.
//!
//! * [`OffsetCalibrator`] — with the PWM outputs off, the phase currents are zero, so
//!   the mean of N samples is the sensor's zero-current offset. A mean outside the
//!   window of the [`AnalogScale`], or samples spread wider than the window allows,
//!   is the phase / current-sensing fault ([`OffsetFault::KIND`]), reported as an
//!   [`OffsetFault`].
//! * [`AnalogScale`] — raw counts → amperes / volts.

/// One set of raw ADC counts taken at the same PWM centre.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RawSample {
    /// Phase A current sensor, raw counts.
    pub ia: u16,
    /// Phase B current sensor, raw counts.
    pub ib: u16,
    /// DC-bus voltage divider, raw counts.
    pub vbus: u16,
}

/// Conversion of raw counts into physical units, and the acceptance window of the
/// current-sensor offsets. The board fills it from its analog front end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnalogScale {
    /// Amperes per count of a phase-current sample (positive: current into the motor
    /// phase's `+` terminal).
    pub amps_per_count: f32,
    /// Volts per count of the bus-voltage sample.
    pub volts_per_count: f32,
    /// Zero-current reading the design expects (e.g. mid-scale for a bipolar sensor).
    pub offset_nominal: u16,
    /// Largest allowed distance of the measured offset from `offset_nominal`, counts.
    pub offset_tolerance: u16,
    /// Largest allowed peak-to-peak spread of the samples taken at zero current, counts.
    pub noise_tolerance: u16,
}

impl AnalogScale {
    /// Phase current in amperes from a raw sample and the calibrated offset (counts).
    pub fn amps(&self, raw: u16, offset: f32) -> f32 {
        (f32::from(raw) - offset) * self.amps_per_count
    }

    /// Bus voltage in volts from a raw sample.
    pub fn volts(&self, raw: u16) -> f32 {
        f32::from(raw) * self.volts_per_count
    }
}

/// Calibrated zero-current readings of the two phase-current sensors, counts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Offsets {
    /// Phase A offset, counts.
    pub ia: f32,
    /// Phase B offset, counts.
    pub ib: f32,
}

/// Which current sensor failed the start-up check.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "board", derive(defmt::Format))]
pub enum Phase {
    /// Phase A.
    A,
    /// Phase B.
    B,
}

/// Why the current-sensor offset check failed. Every variant is drive fault 9.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "board", derive(defmt::Format))]
pub enum OffsetFault {
    /// Fewer samples than the calibration asked for arrived (no ADC trigger: PWM
    /// timer or ADC not running).
    TooFewSamples {
        /// Samples that arrived.
        got: u32,
        /// Samples required.
        wanted: u32,
    },
    /// The mean zero-current reading is outside the window.
    OutOfRange {
        /// Failing sensor.
        phase: Phase,
        /// Its mean reading, counts (rounded down).
        mean: u16,
    },
    /// The readings at zero current spread wider than the noise tolerance.
    Noisy {
        /// Failing sensor.
        phase: Phase,
        /// Peak-to-peak spread, counts.
        spread: u16,
    },
}

impl OffsetFault {
    /// The drive fault of every offset fault (its code, LED flashes and reaction are
    /// the fault table's, [`crate::faults::TABLE`]).
    pub const KIND: crate::faults::FaultKind = crate::faults::FaultKind::PhaseSensing;
}

#[derive(Debug, Clone, Copy)]
struct Stats {
    sum: u64,
    min: u16,
    max: u16,
}

impl Stats {
    const EMPTY: Stats = Stats {
        sum: 0,
        min: u16::MAX,
        max: 0,
    };

    fn add(&mut self, v: u16) {
        self.sum += u64::from(v);
        self.min = self.min.min(v);
        self.max = self.max.max(v);
    }
}

/// Accumulates zero-current samples and judges the sensor offsets.
#[derive(Debug, Clone)]
pub struct OffsetCalibrator {
    wanted: u32,
    n: u32,
    a: Stats,
    b: Stats,
}

impl OffsetCalibrator {
    /// A calibration over `wanted` samples (at least 1). Samples beyond `wanted` are
    /// ignored.
    pub fn new(wanted: u32) -> Self {
        OffsetCalibrator {
            wanted: wanted.max(1),
            n: 0,
            a: Stats::EMPTY,
            b: Stats::EMPTY,
        }
    }

    /// Adds one sample (taken with the bridges off). Returns `true` once enough
    /// samples are in.
    pub fn add(&mut self, s: RawSample) -> bool {
        if self.n < self.wanted {
            self.a.add(s.ia);
            self.b.add(s.ib);
            self.n += 1;
        }
        self.is_complete()
    }

    /// Enough samples are in.
    pub fn is_complete(&self) -> bool {
        self.n >= self.wanted
    }

    /// Samples taken so far.
    pub fn count(&self) -> u32 {
        self.n
    }

    /// The offsets, or the reason they cannot be trusted (fault 9).
    pub fn finish(&self, scale: &AnalogScale) -> Result<Offsets, OffsetFault> {
        if !self.is_complete() {
            return Err(OffsetFault::TooFewSamples {
                got: self.n,
                wanted: self.wanted,
            });
        }
        let ia = Self::judge(Phase::A, &self.a, self.n, scale)?;
        let ib = Self::judge(Phase::B, &self.b, self.n, scale)?;
        Ok(Offsets { ia, ib })
    }

    fn judge(phase: Phase, st: &Stats, n: u32, scale: &AnalogScale) -> Result<f32, OffsetFault> {
        let n64 = u64::from(n.max(1));
        // The mean of u16 values is a u16.
        let mean_int = u16::try_from(st.sum / n64).unwrap_or(u16::MAX);
        let distance = mean_int.abs_diff(scale.offset_nominal);
        if distance > scale.offset_tolerance {
            return Err(OffsetFault::OutOfRange {
                phase,
                mean: mean_int,
            });
        }
        let spread = st.max.saturating_sub(st.min);
        if spread > scale.noise_tolerance {
            return Err(OffsetFault::Noisy { phase, spread });
        }
        Ok(st.sum as f32 / n64 as f32)
    }
}
