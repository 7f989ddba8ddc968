//! Input pins set from outside the axis model: `virtual-drive --input INn=LEVEL`.
//!
//! The axis models give IN1-IN3 from their home and limit switches
//! ([`crate::sim_drive::Axis::raw_inputs`]); IN4 and IN5 stay low. A [`ForcedInput`]
//! replaces one input's electrical level (bit n = IN n+1, before the drive's filter
//! and polarity, 0x2153 / 0x2154) with a constant level or a square wave on the
//! drive's clock, so that the input functions of 0x2152 (fault clear, quick stop,
//! probe…) can be tried without a board.

use crate::fault_inject::parse_time;

/// Number of inputs (IN1-IN5).
pub const INPUTS: u8 = firmware::io::INPUTS as u8;

/// The level an input is held at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    /// High (the pin energised).
    On,
    /// Low.
    Off,
    /// A square wave of this period (µs): high for the first half of every period,
    /// counted from the drive's power-on.
    Pulse {
        /// Period, µs.
        period_us: u64,
    },
}

/// One input held at a level.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ForcedInput {
    /// Input index: 0 = IN1.
    pub input: u8,
    /// Its level.
    pub level: Level,
}

impl ForcedInput {
    /// `INn=on`, `INn=off` or `INn=pulse:PERIOD` (PERIOD with a unit, e.g. `200ms`;
    /// at least 2 ms, so that each half lasts a 1 ms tick or more).
    pub fn parse(s: &str) -> Result<Self, String> {
        let usage = || {
            format!("input '{s}': INn=on, INn=off or INn=pulse:PERIOD (n 1..{INPUTS}, PERIOD e.g. 200ms)")
        };
        let (name, level) = s.split_once('=').ok_or_else(usage)?;
        let n: u8 = name
            .to_ascii_uppercase()
            .strip_prefix("IN")
            .and_then(|n| n.parse().ok())
            .filter(|n| (1..=INPUTS).contains(n))
            .ok_or_else(usage)?;
        let level = match level.to_ascii_lowercase().as_str() {
            "on" => Level::On,
            "off" => Level::Off,
            l => {
                let period = l.strip_prefix("pulse:").ok_or_else(usage)?;
                let period_us = parse_time(period)? / 1000;
                if period_us < 2000 {
                    return Err(format!("input '{s}': the period must be at least 2ms"));
                }
                Level::Pulse { period_us }
            }
        };
        Ok(ForcedInput {
            input: n - 1,
            level,
        })
    }

    /// The level at `t_us` of the drive's clock.
    pub fn high_at(&self, t_us: u64) -> bool {
        match self.level {
            Level::On => true,
            Level::Off => false,
            Level::Pulse { period_us } => t_us % period_us < period_us / 2,
        }
    }
}

/// The inputs set from outside; later entries win over earlier ones for the same
/// input.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ForcedInputs(pub Vec<ForcedInput>);

impl ForcedInputs {
    /// `raw` (the axis model's levels, bit n = IN n+1) with the forced inputs'
    /// levels at `t_us` in their place.
    pub fn apply(&self, raw: u8, t_us: u64) -> u8 {
        self.0.iter().fold(raw, |raw, f| {
            let bit = 1u8 << f.input;
            if f.high_at(t_us) {
                raw | bit
            } else {
                raw & !bit
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_levels_and_reject_bad_ones() {
        assert_eq!(
            ForcedInput::parse("IN4=pulse:200ms"),
            Ok(ForcedInput {
                input: 3,
                level: Level::Pulse { period_us: 200_000 }
            })
        );
        assert_eq!(
            ForcedInput::parse("in1=ON").map(|f| (f.input, f.level)),
            Ok((0, Level::On))
        );
        assert_eq!(
            ForcedInput::parse("IN5=off").map(|f| (f.input, f.level)),
            Ok((4, Level::Off))
        );
        for bad in [
            "IN0=on",
            "IN6=on",
            "IN4",
            "IN4=high",
            "OUT1=on",
            "IN4=pulse:200",
            "IN4=pulse:1ms",
            "IN4=pulse:",
        ] {
            assert!(ForcedInput::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn levels_replace_the_models_bits() {
        let f = ForcedInputs(vec![
            ForcedInput::parse("IN4=pulse:10ms").unwrap(),
            ForcedInput::parse("IN1=off").unwrap(),
            ForcedInput::parse("IN5=on").unwrap(),
        ]);
        // The model says IN1 and IN2; IN1 forced low, IN5 high, IN4 the wave.
        assert_eq!(f.apply(0b00011, 0), 0b11010);
        assert_eq!(f.apply(0b00011, 4_999), 0b11010);
        assert_eq!(f.apply(0b00011, 5_000), 0b10010);
        assert_eq!(f.apply(0b00011, 10_000), 0b11010);
        assert_eq!(ForcedInputs::default().apply(0b101, 7), 0b101);
    }
}
