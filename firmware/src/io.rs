//! Digital inputs and outputs (0x2005/0x2008/0x2053 and
//! 0x2152-0x2155; CiA 402 0x60FD bit assembly).
//!
//! Inputs IN1-IN5: the raw electrical level (0x2155) goes through a digital filter (a
//! new level is accepted once it was stable for 0x2153:n × 50 µs), then the polarity
//! (0x2154 bit n inverts input n+1) gives the logical level; each input's function bits
//! (0x2152:n: 1 home, 2 limit−, 4 limit+, 8 fault clear, 16 quick stop, 32 probe) are
//! active while the input is logically active. Several inputs may share a function (OR).
//! The edges of "probe" latch the position at that tick for touch probe 1
//! (`crate::cia402::probe`), beside IN1's capture.
//!
//! Outputs OUT1-OUT3: output n+1 is active when any condition selected by 0x2005:n+1
//! (bit 0 alarm, bit 1 ready, bit 2 in-position, bit 3 brake released, bit 4 operation
//! enabled) is true, or — where the master's mask bit 0x60FE:02 is set — when the
//! master's bit 0x60FE:01 (bits 16-18) is. The pin level is the active state for an
//! active-high output (0x2008 bit n = 1), inverted otherwise; an output whose function
//! is *in-position only* (value 4) uses 0x2053 for its active level instead.
//! The brake output is energised (released) only while the drive holds the motor and
//! the master does not set the brake (0x60FE bit 0).

use crate::params::{Param, Params};

/// Number of inputs.
pub const INPUTS: usize = 5;
/// Number of function outputs (OUT1-OUT3).
pub const OUTPUTS: usize = 3;

/// Input function bits (0x2152).
pub mod function {
    /// Home switch.
    pub const HOME: u16 = 1;
    /// Negative limit switch.
    pub const LIMIT_NEG: u16 = 2;
    /// Positive limit switch.
    pub const LIMIT_POS: u16 = 4;
    /// Fault clear (rising edge).
    pub const FAULT_CLEAR: u16 = 8;
    /// Quick stop.
    pub const QUICK_STOP: u16 = 16;
    /// Touch probe.
    pub const PROBE: u16 = 32;
}

/// Filtered, polarity-corrected inputs and their functions.
#[derive(Debug, Clone, Copy, Default)]
pub struct Inputs {
    raw: u8,
    stable: u8,
    pending_us: [u32; INPUTS],
    logical: u8,
    functions: u16,
    prev_functions: u16,
}

impl Inputs {
    /// All inputs low, nothing active.
    pub const fn new() -> Self {
        Inputs {
            raw: 0,
            stable: 0,
            pending_us: [0; INPUTS],
            logical: 0,
            functions: 0,
            prev_functions: 0,
        }
    }

    /// Takes a sample of the raw levels (bit n = IN n+1) `dt_us` after the previous
    /// one, with filter times in 50 µs units, the polarity byte and the function word
    /// of each input.
    pub fn update_with(
        &mut self,
        raw: u8,
        dt_us: u32,
        filters: [u16; INPUTS],
        polarity: u8,
        functions: [u16; INPUTS],
    ) {
        self.raw = raw & 0x1F;
        for (i, pending) in self.pending_us.iter_mut().enumerate() {
            let bit = 1u8 << i;
            if (self.raw ^ self.stable) & bit == 0 {
                *pending = 0;
                continue;
            }
            *pending = pending.saturating_add(dt_us);
            if *pending >= u32::from(filters[i].max(1)) * 50 {
                self.stable ^= bit;
                *pending = 0;
            }
        }
        self.logical = self.stable ^ (polarity & 0x1F);
        self.prev_functions = self.functions;
        self.functions = functions
            .iter()
            .enumerate()
            .filter(|(i, _)| self.logical & (1 << i) != 0)
            .fold(0, |acc, (_, &f)| acc | f);
    }

    /// [`Inputs::update_with`] with the configuration from the parameters.
    pub fn update(&mut self, raw: u8, dt_us: u32, p: &Params) {
        let mut filters = [0u16; INPUTS];
        let mut functions = [0u16; INPUTS];
        for i in 0..INPUTS {
            filters[i] = p.input_filter(i);
            functions[i] = p.input_function(i);
        }
        self.update_with(
            raw,
            dt_us,
            filters,
            p.get(Param::InputPolarity) as u8,
            functions,
        );
    }

    /// Raw electrical levels (0x2155).
    pub fn raw(&self) -> u8 {
        self.raw
    }
    /// Filtered electrical levels.
    pub fn filtered(&self) -> u8 {
        self.stable
    }
    /// Logical levels after polarity (bit n = IN n+1 active).
    pub fn logical(&self) -> u8 {
        self.logical
    }
    /// Function bits currently active.
    pub fn functions(&self) -> u16 {
        self.functions
    }
    /// True while `f` (a [`function`] bit) is active.
    pub fn is(&self, f: u16) -> bool {
        self.functions & f != 0
    }
    /// True in the update where `f` became active.
    pub fn rising(&self, f: u16) -> bool {
        self.functions & f != 0 && self.prev_functions & f == 0
    }
    /// Home switch.
    pub fn home(&self) -> bool {
        self.is(function::HOME)
    }
    /// Negative limit switch.
    pub fn limit_neg(&self) -> bool {
        self.is(function::LIMIT_NEG)
    }
    /// Positive limit switch.
    pub fn limit_pos(&self) -> bool {
        self.is(function::LIMIT_POS)
    }
    /// Quick stop requested by an input.
    pub fn quick_stop(&self) -> bool {
        self.is(function::QUICK_STOP)
    }
    /// Fault clear edge (call [`crate::faults::Faults::fault_reset`]).
    pub fn fault_clear_edge(&self) -> bool {
        self.rising(function::FAULT_CLEAR)
    }
    /// Probe input level.
    pub fn probe(&self) -> bool {
        self.is(function::PROBE)
    }
    /// The probe function's edge in this update: `Some(true)` when it became active,
    /// `Some(false)` when it ended (touch probe 1's rising / falling edge).
    pub fn probe_edge(&self) -> Option<bool> {
        let now = self.probe();
        (now != (self.prev_functions & function::PROBE != 0)).then_some(now)
    }

    /// 0x60FD value: bit 0 negative limit, bit 1 positive limit, bit 2 home, bits
    /// 16-20 the logical levels of IN1-IN5.
    pub fn digital_inputs_60fd(&self) -> u32 {
        u32::from(self.limit_neg())
            | u32::from(self.limit_pos()) << 1
            | u32::from(self.home()) << 2
            | u32::from(self.logical) << 16
    }
}

/// Conditions the outputs can show.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct OutputStatus {
    /// A fault is active.
    pub alarm: bool,
    /// Ready (no fault, PDS at least ready to switch on).
    pub ready: bool,
    /// Target reached / in position.
    pub in_position: bool,
    /// The brake is released (its output energised).
    pub brake_released: bool,
    /// Operation enabled: the drive holds the motor.
    pub enabled: bool,
}

/// Output function bits (0x2005).
pub mod output {
    /// Alarm.
    pub const ALARM: u16 = 1;
    /// Ready.
    pub const READY: u16 = 2;
    /// In position.
    pub const IN_POSITION: u16 = 4;
    /// Brake released (for an external brake relay).
    pub const BRAKE: u16 = 8;
    /// Operation enabled.
    pub const ENABLED: u16 = 16;
}

/// 0x60FE:01 / :02 bits of this drive (CiA 402: bit 0 "set brake", bits 16-31
/// manufacturer-specific): bit 0 engages the brake, bits 16-18 drive OUT1-OUT3.
pub mod master {
    /// "Set brake": the brake is engaged whatever the drive wants (it can never be
    /// released by the master).
    pub const SET_BRAKE: u32 = 1;
    /// Bit of OUT1; OUT2 and OUT3 follow.
    pub const OUT1_SHIFT: u32 = 16;
}

/// Pin levels (bit n = output n+1 high) from the functions (0x2005), the level byte
/// (0x2008), the in-position level (0x2053) and the master's outputs (0x60FE:01 masked
/// by 0x60FE:02): where the master's mask bit is set, the output shows the master's
/// bit (as an active state: the level byte applies); elsewhere the function does.
/// Function 0 is an output only the master drives.
pub fn output_levels_with(
    functions: [u16; OUTPUTS],
    level_2008: u8,
    in_pos_level_2053: u8,
    s: OutputStatus,
    master: (u32, u32),
) -> u8 {
    let mut pins = 0u8;
    for (n, &f) in functions.iter().enumerate() {
        let bit = 1u32 << (master::OUT1_SHIFT + n as u32);
        let active = if master.1 & bit != 0 {
            master.0 & bit != 0
        } else {
            (f & output::ALARM != 0 && s.alarm)
                || (f & output::READY != 0 && s.ready)
                || (f & output::IN_POSITION != 0 && s.in_position)
                || (f & output::BRAKE != 0 && s.brake_released)
                || (f & output::ENABLED != 0 && s.enabled)
        };
        let active_high = if f == output::IN_POSITION {
            in_pos_level_2053 & 1 != 0
        } else {
            level_2008 & (1 << n) != 0
        };
        if active == active_high {
            pins |= 1 << n;
        }
    }
    pins
}

/// [`output_levels_with`] with the configuration from the parameters and the
/// master's outputs `(0x60FE:01, 0x60FE:02)`.
pub fn output_levels(p: &Params, s: OutputStatus, master: (u32, u32)) -> u8 {
    output_levels_with(
        [
            p.get(Param::Out1Function) as u16,
            p.get(Param::Out2Function) as u16,
            p.get(Param::Out3Function) as u16,
        ],
        p.get(Param::OutputLevel) as u8,
        p.get(Param::InPositionLevel) as u8,
        s,
        master,
    )
}

/// The brake may be released: the drive holds the motor (also through a fault
/// reaction's stop ramp), no fault that cuts the power is active, and the master does
/// not set the brake (0x60FE bit 0 with its mask bit).
pub fn brake_released(operation_enabled: bool, power_cut: bool, master: (u32, u32)) -> bool {
    let set_by_master = master.0 & master.1 & master::SET_BRAKE != 0;
    operation_enabled && !power_cut && !set_by_master
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identity::Variant;

    const F: [u16; INPUTS] = [1, 2, 4, 8, 0];

    #[test]
    fn filter_accepts_after_stable_time() {
        let mut io = Inputs::new();
        // 20 × 50 µs = 1 ms filter, sampled every 100 µs.
        for k in 0..9 {
            io.update_with(0b1, 100, [20; 5], 0, F);
            assert_eq!(io.filtered(), 0, "sample {k}");
            assert_eq!(io.raw(), 1);
        }
        io.update_with(0b1, 100, [20; 5], 0, F);
        assert_eq!(io.filtered(), 1);
        assert!(io.home());
        // A glitch shorter than the filter is ignored and restarts the count.
        io.update_with(0, 500, [20; 5], 0, F);
        io.update_with(1, 100, [20; 5], 0, F);
        io.update_with(0, 900, [20; 5], 0, F);
        assert_eq!(io.filtered(), 1);
        io.update_with(0, 100, [20; 5], 0, F);
        assert_eq!(io.filtered(), 0);
        // Minimum filter 1 unit = 50 µs.
        io.update_with(0b10, 49, [1; 5], 0, F);
        assert_eq!(io.filtered(), 0);
        io.update_with(0b10, 1, [1; 5], 0, F);
        assert_eq!(io.filtered(), 0b10);
        // Filter 0 (never in range) acts as 1.
        io.update_with(0, 50, [0; 5], 0, F);
        assert_eq!(io.filtered(), 0);
    }

    #[test]
    fn polarity_functions_and_60fd() {
        let mut io = Inputs::new();
        io.update_with(0b0_0111, 10_000, [1; 5], 0, F);
        assert!(io.home() && io.limit_neg() && io.limit_pos());
        assert_eq!(io.digital_inputs_60fd(), 0b111 | 0b111 << 16);
        // Invert IN1 and IN4: IN1 inactive, IN4 (fault clear) active.
        io.update_with(0b0_0111, 10_000, [1; 5], 0b0_1001, F);
        assert!(!io.home());
        assert!(io.fault_clear_edge());
        assert_eq!(io.digital_inputs_60fd(), 0b011 | 0b1110 << 16);
        io.update_with(0b0_0111, 10_000, [1; 5], 0b0_1001, F);
        assert!(!io.fault_clear_edge(), "edge only once");
        assert!(io.is(function::FAULT_CLEAR));
        // Shared function and the vendor functions.
        io.update_with(
            0b1_0000,
            10_000,
            [1; 5],
            0,
            [
                0,
                0,
                0,
                0,
                function::QUICK_STOP | function::PROBE | function::HOME,
            ],
        );
        assert!(io.quick_stop() && io.probe() && io.home());
        assert_eq!(io.raw(), 0x10);
        // Bits above 5 of garbage raw/polarity are ignored.
        io.update_with(0xE0, 10_000, [1; 5], 0xE0, F);
        assert_eq!((io.raw(), io.logical()), (0, 0));
    }

    #[test]
    fn update_from_params() {
        let p = Params::new(Variant::HybridServo);
        let mut io = Inputs::new();
        io.update(0b0_0100, 1000, &p);
        assert!(io.limit_pos());
        assert_eq!(io.digital_inputs_60fd(), 0b010 | 0b100 << 16);
    }

    #[test]
    fn output_levels_table() {
        let on = OutputStatus {
            alarm: true,
            ..OutputStatus::default()
        };
        let off = OutputStatus::default();
        let ready = OutputStatus { ready: true, ..off };
        let inpos = OutputStatus {
            in_position: true,
            ..off
        };
        // (functions, 2008, 2053, status, pins)
        let t: &[([u16; 3], u8, u8, OutputStatus, u8)] = &[
            ([1, 1, 0], 0, 0, off, 0b11), // active-low alarm, inactive → high
            ([1, 1, 0], 0, 0, on, 0b00),
            ([1, 1, 0], 0b11, 0, on, 0b11),    // active-high
            ([1, 2, 0], 0b01, 0, ready, 0b00), // out1 alarm active-high inactive → low; out2 ready active-low active → low
            ([2, 3, 0], 0b11, 0, ready, 0b11),
            ([4, 1, 0], 0b11, 0, inpos, 0b00), // in-position uses 2053 = 0: active-low → low; out2 alarm inactive, active-high → low
            ([4, 1, 0], 0b00, 1, inpos, 0b11), // 2053 = 1: active-high → high; out2 active-low inactive → high
            ([4, 4, 0], 0, 1, off, 0b00),
        ];
        for (i, &(f, l, ip, s, pins)) in t.iter().enumerate() {
            // OUT3 (function 0, active-low) stays inactive: high.
            assert_eq!(
                output_levels_with(f, l, ip, s, (0, 0)),
                pins | 0b100,
                "case {i}"
            );
        }
        // Defaults: OUT3 only the master's, active-high, so low while it is not set.
        let p = Params::new(Variant::HybridServo);
        assert_eq!(output_levels(&p, on, (0, 0)), 0);
        assert_eq!(output_levels(&p, off, (0, 0)), 0b11);
        assert!(brake_released(true, false, (0, 0)));
        assert!(!brake_released(true, true, (0, 0)));
        assert!(!brake_released(false, false, (0, 0)));
        // The master sets the brake; without the mask bit it cannot.
        assert!(!brake_released(true, false, (1, 1)));
        assert!(brake_released(true, false, (1, 0)));
        assert!(brake_released(true, false, (0, 1)));
    }

    #[test]
    fn master_outputs_and_new_functions() {
        let off = OutputStatus::default();
        // OUT3 driven by the master (bit 18 with its mask), active-high.
        let f = [0, 0, 0];
        assert_eq!(
            output_levels_with(f, 0b111, 0, off, (1 << 18, 1 << 18)),
            0b100
        );
        assert_eq!(output_levels_with(f, 0b111, 0, off, (1 << 18, 0)), 0b000);
        assert_eq!(output_levels_with(f, 0b111, 0, off, (0, 1 << 18)), 0b000);
        // The mask overrides the function: an alarm output driven by the master.
        let alarm = OutputStatus { alarm: true, ..off };
        assert_eq!(
            output_levels_with([1, 0, 0], 0b111, 0, alarm, (0, 1 << 16)),
            0
        );
        // Brake and enabled functions.
        let st = OutputStatus {
            brake_released: true,
            ..off
        };
        assert_eq!(output_levels_with([8, 16, 0], 0b111, 0, st, (0, 0)), 0b001);
        let st = OutputStatus {
            enabled: true,
            ..off
        };
        assert_eq!(output_levels_with([8, 16, 24], 0b111, 0, st, (0, 0)), 0b110);
    }
}
