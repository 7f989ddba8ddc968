//! The red fault LED and the green power LED (blink codes: `docs/guide/drive-behaviour.md`).
//!
//! While a fault with a flash code N is active the red LED gives N pulses of 150 ms
//! on / 150 ms off, then stays dark until 3 s after the burst began, and repeats. The
//! code shown is the most severe active one ([`crate::faults::Faults::led_code`]); a
//! change of code takes effect at the next burst so a burst is never cut short. When no
//! fault is active the LED is off at once. The green LED is on while powered.

/// Pulse on time, ms.
pub const ON_MS: u32 = 150;
/// Gap after each pulse, ms.
pub const OFF_MS: u32 = 150;
/// Burst repetition period, ms.
pub const PERIOD_MS: u32 = 3000;

/// Blink pattern generator of the red LED.
#[derive(Debug, Clone, Copy, Default)]
pub struct FaultLed {
    burst: Option<(u32, u8)>,
}

impl FaultLed {
    /// LED off, no burst running.
    pub const fn new() -> Self {
        FaultLed { burst: None }
    }

    /// Red LED level at `now_ms` (wrapping millisecond clock) for the active code
    /// (`None` or 0: no fault).
    pub fn update(&mut self, code: Option<u8>, now_ms: u32) -> bool {
        let n = match code {
            Some(n) if n > 0 => n.min((PERIOD_MS / (ON_MS + OFF_MS)) as u8),
            _ => {
                self.burst = None;
                return false;
            }
        };
        let (start, shown) = match self.burst {
            None => (now_ms, n),
            Some((start, shown)) => {
                let age = now_ms.wrapping_sub(start);
                if age >= PERIOD_MS {
                    (now_ms.wrapping_sub(age % PERIOD_MS), n)
                } else {
                    (start, shown)
                }
            }
        };
        self.burst = Some((start, shown));
        let phase = now_ms.wrapping_sub(start);
        phase < u32::from(shown) * (ON_MS + OFF_MS) && phase % (ON_MS + OFF_MS) < ON_MS
    }

    /// Green power LED: on while the firmware runs.
    pub const fn power_led(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    /// (level, from_ms, to_ms) intervals sampled every ms.
    fn timeline(
        led: &mut FaultLed,
        code: impl Fn(u32) -> Option<u8>,
        from: u32,
        to: u32,
    ) -> Vec<(bool, u32, u32)> {
        let mut out: Vec<(bool, u32, u32)> = Vec::new();
        for t in from..to {
            let l = led.update(code(t), t);
            match out.last_mut() {
                Some(last) if last.0 == l => last.2 = t + 1,
                _ => out.push((l, t, t + 1)),
            }
        }
        out
    }

    #[test]
    fn three_flashes_repeat_every_three_seconds() {
        let mut led = FaultLed::new();
        let tl = timeline(&mut led, |_| Some(3), 1000, 7000);
        assert_eq!(
            tl,
            [
                (true, 1000, 1150),
                (false, 1150, 1300),
                (true, 1300, 1450),
                (false, 1450, 1600),
                (true, 1600, 1750),
                (false, 1750, 4000),
                (true, 4000, 4150),
                (false, 4150, 4300),
                (true, 4300, 4450),
                (false, 4450, 4600),
                (true, 4600, 4750),
                (false, 4750, 7000),
            ]
        );
    }

    #[test]
    fn every_code_has_n_pulses_per_period() {
        for n in [1u8, 2, 3, 4, 7, 9] {
            let mut led = FaultLed::new();
            let tl = timeline(&mut led, |_| Some(n), 0, 3000);
            let on: Vec<_> = tl.iter().filter(|i| i.0).collect();
            assert_eq!(on.len(), n as usize);
            assert!(on.iter().all(|i| i.2 - i.1 == ON_MS));
            let last_off = tl.last().unwrap();
            assert_eq!(*last_off, (false, u32::from(n) * 300 - 150, 3000));
        }
    }

    #[test]
    fn off_at_once_when_fault_clears_and_code_changes_at_next_burst() {
        let mut led = FaultLed::new();
        let tl = timeline(&mut led, |t| if t < 200 { Some(2) } else { None }, 0, 400);
        assert_eq!(tl, [(true, 0, 150), (false, 150, 400)]);
        let mut led = FaultLed::new();
        // Code 1 → 9 at 100 ms: the running burst stays 1 pulse, the next has 9.
        let tl = timeline(&mut led, |t| Some(if t < 100 { 1 } else { 9 }), 0, 6000);
        assert_eq!(tl[0], (true, 0, 150));
        assert_eq!(tl[1], (false, 150, 3000));
        assert_eq!(tl.iter().filter(|i| i.0 && i.1 >= 3000).count(), 9);
        assert!(led.power_led());
    }

    #[test]
    fn clock_wrap_and_sparse_calls() {
        let mut led = FaultLed::new();
        let start = u32::MAX - 100;
        assert!(led.update(Some(1), start));
        assert!(!led.update(Some(1), start.wrapping_add(200)));
        // Called again 10 periods + 50 ms later: inside a pulse.
        assert!(led.update(Some(1), start.wrapping_add(30_050)));
        assert!(!led.update(Some(1), start.wrapping_add(30_200)));
        assert!(!led.update(Some(0), start.wrapping_add(30_210)));
        // Absurd codes are limited to what fits in a period.
        let mut led = FaultLed::new();
        let tl = timeline(&mut led, |_| Some(200), 0, 3000);
        assert_eq!(tl.iter().filter(|i| i.0).count(), 10);
    }
}
