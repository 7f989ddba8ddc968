//! ETG.1300 RUN and ERR indicators: patterns, their exact timing, and how the ESM
//! state and error conditions select them.
//!
//! Timing (one period, starting with the "on" phase when a pattern is selected):
//!
//! | pattern | on/off sequence (ms) | period |
//! |---|---|---|
//! | [`Pattern::Off`] / [`Pattern::On`] | constant | — |
//! | [`Pattern::Flickering`] | 50 on, 50 off | 100 ms (10 Hz) |
//! | [`Pattern::Blinking`] | 200 on, 200 off | 400 ms (2.5 Hz) |
//! | [`Pattern::SingleFlash`] | 200 on, 1000 off | 1200 ms |
//! | [`Pattern::DoubleFlash`] | 200 on, 200 off, 200 on, 1000 off | 1600 ms |
//!
//! An [`Indicator`] remembers when its pattern was selected, so [`Indicator::level`]
//! is a pure function of the current time: no timer task, no state to advance.
//! Re-selecting the pattern that is already shown does not restart it.
//!
//! RUN (green): Init off, Pre-Op blinking, Safe-Op single flash, Op on, Bootstrap
//! flickering ([`run_pattern`]). ERR (red, [`ErrCondition`]): no error off, invalid
//! configuration blinking, local error single flash, process-data watchdog timeout
//! double flash, booting error flickering, PDI watchdog / application controller
//! failure on. When the LEDs hang on the ESC instead of a GPIO, [`Pattern::override_code`]
//! gives the value for the RUN/ERR LED override registers 0x0138/0x0139.

use crate::esm::EsmState;

/// Flickering half period, ms.
pub const FLICKER_MS: u32 = 50;
/// Blinking half period and flash length, ms.
pub const BLINK_MS: u32 = 200;
/// Pause after a (single or double) flash, ms.
pub const FLASH_PAUSE_MS: u32 = 1000;

/// An indicator pattern.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pattern {
    /// Constantly off.
    Off,
    /// Constantly on.
    On,
    /// 50 ms on, 50 ms off.
    Flickering,
    /// 200 ms on, 200 ms off.
    Blinking,
    /// 200 ms on, 1000 ms off.
    SingleFlash,
    /// 200 ms on, 200 ms off, 200 ms on, 1000 ms off.
    DoubleFlash,
}

impl Pattern {
    /// Length of one period in ms (0 for the constant patterns).
    pub const fn period_ms(self) -> u32 {
        match self {
            Pattern::Off | Pattern::On => 0,
            Pattern::Flickering => 2 * FLICKER_MS,
            Pattern::Blinking => 2 * BLINK_MS,
            Pattern::SingleFlash => BLINK_MS + FLASH_PAUSE_MS,
            Pattern::DoubleFlash => 3 * BLINK_MS + FLASH_PAUSE_MS,
        }
    }

    /// LED level `elapsed_ms` after the pattern started (true = lit).
    pub const fn level_at(self, elapsed_ms: u32) -> bool {
        let p = self.period_ms();
        let t = if p == 0 { 0 } else { elapsed_ms % p };
        match self {
            Pattern::Off => false,
            Pattern::On => true,
            Pattern::Flickering => t < FLICKER_MS,
            Pattern::Blinking | Pattern::SingleFlash => t < BLINK_MS,
            Pattern::DoubleFlash => t < BLINK_MS || (t >= 2 * BLINK_MS && t < 3 * BLINK_MS),
        }
    }

    /// Code for the ESC LED override registers 0x0138 (RUN) / 0x0139 (ERR), with the
    /// override-enable bit 4 set: 0x0 off, 0x1 single flash, 0x2 double flash,
    /// 0xD blinking, 0xE flickering, 0xF on.
    pub const fn override_code(self) -> u8 {
        0x10 | match self {
            Pattern::Off => 0x0,
            Pattern::SingleFlash => 0x1,
            Pattern::DoubleFlash => 0x2,
            Pattern::Blinking => 0xD,
            Pattern::Flickering => 0xE,
            Pattern::On => 0xF,
        }
    }
}

/// RUN indicator pattern for an ESM state.
pub const fn run_pattern(state: EsmState) -> Pattern {
    match state {
        EsmState::Init => Pattern::Off,
        EsmState::PreOp => Pattern::Blinking,
        EsmState::SafeOp => Pattern::SingleFlash,
        EsmState::Op => Pattern::On,
        EsmState::Bootstrap => Pattern::Flickering,
    }
}

/// What the ERR indicator shows, most severe last.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum ErrCondition {
    /// No error: off.
    None,
    /// Invalid configuration (refused state change, bad SM or mapping): blinking.
    InvalidConfiguration,
    /// Local error, the slave changed state by itself (e.g. sync error): single flash.
    LocalError,
    /// Process-data (SM) watchdog timeout: double flash.
    WatchdogTimeout,
    /// Booting error (SII/EEPROM load, firmware): flickering.
    BootingError,
    /// PDI watchdog timeout / application controller failure: on.
    PdiWatchdog,
}

impl ErrCondition {
    /// The ERR pattern.
    pub const fn pattern(self) -> Pattern {
        match self {
            ErrCondition::None => Pattern::Off,
            ErrCondition::InvalidConfiguration => Pattern::Blinking,
            ErrCondition::LocalError => Pattern::SingleFlash,
            ErrCondition::WatchdogTimeout => Pattern::DoubleFlash,
            ErrCondition::BootingError => Pattern::Flickering,
            ErrCondition::PdiWatchdog => Pattern::On,
        }
    }

    /// Derives the condition from AL status (0x0130) and AL status code (0x0134):
    /// no error indication (bit 4) or code 0 → none; 0x001B (SM watchdog) → watchdog
    /// timeout; the codes of a state change the slave made by itself (ETG.1000.6) →
    /// local error: 0x001A sync error, 0x002A background watchdog, 0x002C fatal sync
    /// error, 0x002D no sync, 0x0032 PLL error, 0x0033 / 0x0034 DC sync I/O error /
    /// timeout, 0x0052 external hardware not ready, 0x0060 restarted locally, 0x0080 /
    /// 0x0081 supply voltage too low / high; 0x0050, 0x0051, 0x0014 (EEPROM /
    /// firmware) → booting error; any other code (a refused request: state, sync
    /// manager, mapping, sync configuration) → invalid configuration.
    pub const fn from_al_status(al_status: u16, al_status_code: u16) -> Self {
        if al_status & 0x10 == 0 || al_status_code == 0 {
            return ErrCondition::None;
        }
        match al_status_code {
            0x001B => ErrCondition::WatchdogTimeout,
            0x001A | 0x002A | 0x002C | 0x002D | 0x0032 | 0x0033 | 0x0034 | 0x0052 | 0x0060
            | 0x0080 | 0x0081 => ErrCondition::LocalError,
            0x0014 | 0x0050 | 0x0051 => ErrCondition::BootingError,
            _ => ErrCondition::InvalidConfiguration,
        }
    }
}

/// One indicator: the pattern shown and when it was selected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Indicator {
    pattern: Pattern,
    since_ms: u32,
}

impl Indicator {
    /// An indicator that is off.
    pub const fn new() -> Self {
        Indicator {
            pattern: Pattern::Off,
            since_ms: 0,
        }
    }

    /// Selects `pattern` at `now_ms`; the same pattern again keeps its phase.
    pub fn set(&mut self, pattern: Pattern, now_ms: u32) {
        if pattern != self.pattern {
            self.pattern = pattern;
            self.since_ms = now_ms;
        }
    }

    /// The pattern shown.
    pub const fn pattern(&self) -> Pattern {
        self.pattern
    }

    /// LED level at `now_ms` (millisecond counter; wrap-around is handled).
    pub const fn level(&self, now_ms: u32) -> bool {
        self.pattern.level_at(now_ms.wrapping_sub(self.since_ms))
    }
}

impl Default for Indicator {
    fn default() -> Self {
        Self::new()
    }
}

/// The RUN and ERR indicators of one device.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StatusLeds {
    /// Green RUN indicator.
    pub run: Indicator,
    /// Red ERR indicator.
    pub err: Indicator,
}

impl StatusLeds {
    /// Both off.
    pub const fn new() -> Self {
        StatusLeds {
            run: Indicator::new(),
            err: Indicator::new(),
        }
    }

    /// Selects the patterns for the ESM state and error condition at `now_ms`.
    pub fn update(&mut self, state: EsmState, err: ErrCondition, now_ms: u32) {
        self.run.set(run_pattern(state), now_ms);
        self.err.set(err.pattern(), now_ms);
    }

    /// (RUN, ERR) levels at `now_ms`.
    pub const fn levels(&self, now_ms: u32) -> (bool, bool) {
        (self.run.level(now_ms), self.err.level(now_ms))
    }
}
