//! The gate in front of the power stage: the one decision whether the bridges may be
//! on, and the sticky halted state a panic or a HardFault leaves behind.
//!
//! The board's current-loop interrupt asks [`bridge_mode`] every PWM period, and the
//! power-stage driver refuses to set MOE while [`Halt::is_halted`] holds (two checks,
//! so neither a stale decision nor a direct call can switch the bridges back on).
//! Once halted, nothing but a reset clears the state.
//!
//! What a fatal error does (the board's panic and HardFault handlers): mask the
//! interrupts, [`Halt::halt`] (which says how the chip gets out of it), bridges off,
//! then either wait for the running independent watchdog to reset the chip (the next
//! start logs the cause) or, before the watchdog has been started, reset at once —
//! a core that merely spins would otherwise hang with the drive dead until a power
//! cycle.
use core::sync::atomic::{AtomicBool, Ordering};

/// Sticky halted state (see the module docs). One static instance on the board.
pub struct Halt {
    halted: AtomicBool,
    watchdog_running: AtomicBool,
}

/// How a halted chip gets back to a clean start.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HaltExit {
    /// The independent watchdog runs and is no longer fed: it resets the chip.
    AwaitWatchdog,
    /// No watchdog runs yet: the handler must request a system reset itself.
    ResetNow,
}

impl Halt {
    /// Not halted, no watchdog running.
    pub const fn new() -> Self {
        Halt {
            halted: AtomicBool::new(false),
            watchdog_running: AtomicBool::new(false),
        }
    }

    /// Records that the independent watchdog has been started (it cannot be stopped).
    pub fn watchdog_started(&self) {
        self.watchdog_running.store(true, Ordering::Release);
    }

    /// Enters the halted state (for good: there is no way back but a reset) and says
    /// how the chip is to be reset.
    pub fn halt(&self) -> HaltExit {
        self.halted.store(true, Ordering::Release);
        if self.watchdog_running.load(Ordering::Acquire) {
            HaltExit::AwaitWatchdog
        } else {
            HaltExit::ResetNow
        }
    }

    /// A panic or HardFault has halted the drive.
    pub fn is_halted(&self) -> bool {
        self.halted.load(Ordering::Acquire)
    }
}

impl Default for Halt {
    fn default() -> Self {
        Self::new()
    }
}

/// What the current-loop interrupt knows each PWM period.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GateInputs {
    /// [`Halt::is_halted`].
    pub halted: bool,
    /// A break (hardware over-current) is latched.
    pub break_latched: bool,
    /// The current loop's fast protection has tripped
    /// (`current_supervisor::CurrentSupervisor::tripped`).
    pub tripped: bool,
    /// The power-up auto-tune drives the bridges (voltage mode).
    pub tuning: bool,
    /// The drive permits the power stage (power stage requested, no active fault) and
    /// the current-sensor offsets passed the start-up check.
    pub permitted: bool,
    /// The motion layer wants current (`CurrentReference::power`).
    pub power_wanted: bool,
}

/// What the bridges do this PWM period.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BridgeMode {
    /// Off (MOE = 0, duties centred).
    Off,
    /// On, driven by the power-up auto-tune.
    Tune,
    /// On, driven by the current loop.
    Run,
}

/// The bridge decision: never on while halted, with a latched break or a tripped fast
/// protection; the auto-tune
/// takes precedence over the current loop (the drive holds the motion layer meanwhile).
pub const fn bridge_mode(i: GateInputs) -> BridgeMode {
    if i.halted || i.break_latched || i.tripped {
        BridgeMode::Off
    } else if i.tuning {
        BridgeMode::Tune
    } else if i.permitted && i.power_wanted {
        BridgeMode::Run
    } else {
        BridgeMode::Off
    }
}

/// The brake output as the current-loop interrupt drives it: released only while
/// the runtime's decision (`board_glue::ControlCommand::brake_released`: the
/// bridges reported on for the release delay, no brake-close sequence, 0x60FE) says so
/// *and* the bridges are on in this period; engaged in the very period the bridges
/// go off (break latched, fast protection, a withdrawn permission, halted), without
/// waiting for the 1 ms tick. One writer of the pin: the control path.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BrakeOut {
    released: bool,
}

impl BrakeOut {
    /// The level for this period from the runtime's `decision` and whether the bridges
    /// are on after this period's bridge decision; `Some(released)` when the pin must
    /// change.
    pub fn update(&mut self, decision: bool, bridges_on: bool) -> Option<bool> {
        let released = decision && bridges_on;
        (released != self.released).then(|| {
            self.released = released;
            released
        })
    }

    /// The level last written (true: released).
    pub fn released(&self) -> bool {
        self.released
    }
}
