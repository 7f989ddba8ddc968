//! The power drive system (PDS) state machine of IEC 61800-7-201 (CiA 402).
//!
//! Everything about states, controlword commands, statusword state patterns and the
//! transitions 0-16 lives here, in one table ([`TRANSITIONS`]). The drive actions that
//! go with a transition (option codes 0x605A-0x605E, power stage, ramps) are applied by
//! [`super::Cia402`]; this module only answers "which transition fires".

/// PDS states.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PdsState {
    /// Initialising; no communication-driven transitions yet.
    NotReadyToSwitchOn,
    /// Power stage off, drive waits for "shutdown".
    SwitchOnDisabled,
    /// Power stage off, ready for "switch on".
    ReadyToSwitchOn,
    /// Power stage on, drive function disabled.
    SwitchedOn,
    /// Drive function enabled: the operating mode runs.
    OperationEnabled,
    /// Quick stop reaction running or finished (0x605A).
    QuickStopActive,
    /// Fault reaction running (0x605E).
    FaultReactionActive,
    /// Fault: power stage off, waits for fault reset.
    Fault,
}

impl PdsState {
    /// Every state (for tests and table checks).
    pub const ALL: [PdsState; 8] = [
        PdsState::NotReadyToSwitchOn,
        PdsState::SwitchOnDisabled,
        PdsState::ReadyToSwitchOn,
        PdsState::SwitchedOn,
        PdsState::OperationEnabled,
        PdsState::QuickStopActive,
        PdsState::FaultReactionActive,
        PdsState::Fault,
    ];

    /// Statusword bits 0-3, 5 and 6 for this state (bit 5 "quick stop" is 1 when no
    /// quick stop is active).
    pub const fn statusword_bits(self) -> u16 {
        match self {
            PdsState::NotReadyToSwitchOn => 0x0000,
            PdsState::SwitchOnDisabled => 0x0040,
            PdsState::ReadyToSwitchOn => 0x0021,
            PdsState::SwitchedOn => 0x0023,
            PdsState::OperationEnabled => 0x0027,
            PdsState::QuickStopActive => 0x0007,
            PdsState::FaultReactionActive => 0x000F,
            PdsState::Fault => 0x0008,
        }
    }

    /// Decodes a statusword into a state with the standard masks (what a master does).
    pub const fn from_statusword(sw: u16) -> Option<PdsState> {
        Some(match (sw & 0x004F, sw & 0x006F) {
            (0x0000, _) => PdsState::NotReadyToSwitchOn,
            (0x0040, _) => PdsState::SwitchOnDisabled,
            (_, 0x0021) => PdsState::ReadyToSwitchOn,
            (_, 0x0023) => PdsState::SwitchedOn,
            (_, 0x0027) => PdsState::OperationEnabled,
            (_, 0x0007) => PdsState::QuickStopActive,
            (0x000F, _) => PdsState::FaultReactionActive,
            (0x0008, _) => PdsState::Fault,
            _ => return None,
        })
    }

    /// High voltage applied to the power stage (statusword bit 4).
    pub const fn voltage_enabled(self) -> bool {
        matches!(
            self,
            PdsState::SwitchedOn
                | PdsState::OperationEnabled
                | PdsState::QuickStopActive
                | PdsState::FaultReactionActive
        )
    }

    const fn bit(self) -> u8 {
        1 << (self as u8)
    }
}

/// The controlword "quick stop" (`0000 0010`: enable voltage, quick stop active):
/// what the drive keeps in 0x6040 while a quick stop it started itself runs (0x6007 = 3).
pub const QUICK_STOP_COMMAND: u16 = 0x0002;

/// A controlword command (bits 0-3 and 7, decoded with the standard masks).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// `xxxx x110` (bit 7 = 0): transitions 2, 6, 8.
    Shutdown,
    /// `xxxx 0111`: transition 3; in Operation enabled this is "disable operation" (5).
    SwitchOn,
    /// `xxxx 1111`: transitions 3 + 4, 16.
    EnableOperation,
    /// `xxxx xx0x`: transitions 7, 9, 10, 12.
    DisableVoltage,
    /// `xxxx x01x`: transitions 7, 10, 11.
    QuickStop,
    /// Bit 7 set: fault reset (acts on the rising edge; no other command while set).
    FaultReset,
}

impl Command {
    /// Decodes a controlword.
    pub const fn decode(cw: u16) -> Command {
        if cw & 0x0080 != 0 {
            Command::FaultReset
        } else if cw & 0x0002 == 0 {
            Command::DisableVoltage
        } else if cw & 0x0004 == 0 {
            Command::QuickStop
        } else if cw & 0x0001 == 0 {
            Command::Shutdown
        } else if cw & 0x0008 == 0 {
            Command::SwitchOn
        } else {
            Command::EnableOperation
        }
    }

    const fn bit(self) -> u16 {
        1 << (self as u16)
    }
}

/// Events that trigger the automatic transitions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    /// A controlword command.
    Cmd(Command),
    /// Initialisation and self-test done (transition 1).
    InitDone,
    /// A fault was detected (transition 13).
    FaultDetected,
    /// The fault reaction has finished (transition 14).
    FaultReactionDone,
    /// The quick-stop reaction has finished (transition 12 for 0x605A = 0-4).
    QuickStopDone,
    /// Rising edge of controlword bit 7 (transition 15).
    FaultResetEdge,
}

impl Event {
    const fn bit(self) -> u16 {
        match self {
            Event::Cmd(c) => c.bit(),
            Event::InitDone => 1 << 8,
            Event::FaultDetected => 1 << 9,
            Event::FaultReactionDone => 1 << 10,
            Event::QuickStopDone => 1 << 11,
            Event::FaultResetEdge => 1 << 12,
        }
    }
}

/// Extra condition a transition needs besides its trigger.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Guard {
    /// Always allowed.
    None,
    /// 0x605A is 5-8 (quick stop ends in Quick stop active): transition 16.
    QuickStopStays,
    /// 0x605A is 0-4 (quick stop ends in Switch on disabled): automatic transition 12.
    QuickStopEnds,
    /// The fault condition is gone: transition 15.
    FaultCleared,
    /// The power stage can follow set-points (no commutation alignment pending,
    /// [`super::DriveFeedback::enable_pending`]): transition 4.
    ReadyToFollow,
}

/// One row of the transition table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Transition {
    /// Transition number of IEC 61800-7-201.
    pub number: u8,
    /// Bit set of the states it leaves (bit n = `PdsState` discriminant n); 0 = power-on.
    pub from: u8,
    /// Bit set of the events that trigger it.
    pub trigger: u16,
    /// Extra condition.
    pub guard: Guard,
    /// State it enters.
    pub to: PdsState,
}

const fn states(list: &[PdsState]) -> u8 {
    let mut m = 0;
    let mut i = 0;
    while i < list.len() {
        m |= list[i].bit();
        i += 1;
    }
    m
}

const fn events(list: &[Event]) -> u16 {
    let mut m = 0;
    let mut i = 0;
    while i < list.len() {
        m |= list[i].bit();
        i += 1;
    }
    m
}

use Command as C;
use Event as E;
use PdsState as S;

/// The transitions 0-16, the single place where the PDS is defined. Searched in order;
/// the first row whose state, trigger and guard match fires.
pub const TRANSITIONS: &[Transition] = &[
    // 0: power-on / reset; done by `Cia402::new()` (no state to leave).
    Transition {
        number: 0,
        from: 0,
        trigger: 0,
        guard: Guard::None,
        to: S::NotReadyToSwitchOn,
    },
    Transition {
        number: 1,
        from: states(&[S::NotReadyToSwitchOn]),
        trigger: events(&[E::InitDone]),
        guard: Guard::None,
        to: S::SwitchOnDisabled,
    },
    Transition {
        number: 2,
        from: states(&[S::SwitchOnDisabled]),
        trigger: events(&[E::Cmd(C::Shutdown)]),
        guard: Guard::None,
        to: S::ReadyToSwitchOn,
    },
    Transition {
        number: 3,
        from: states(&[S::ReadyToSwitchOn]),
        trigger: events(&[E::Cmd(C::SwitchOn), E::Cmd(C::EnableOperation)]),
        guard: Guard::None,
        to: S::SwitchedOn,
    },
    Transition {
        number: 4,
        from: states(&[S::SwitchedOn]),
        trigger: events(&[E::Cmd(C::EnableOperation)]),
        guard: Guard::ReadyToFollow,
        to: S::OperationEnabled,
    },
    Transition {
        number: 5,
        from: states(&[S::OperationEnabled]),
        trigger: events(&[E::Cmd(C::SwitchOn)]),
        guard: Guard::None,
        to: S::SwitchedOn,
    },
    Transition {
        number: 6,
        from: states(&[S::SwitchedOn]),
        trigger: events(&[E::Cmd(C::Shutdown)]),
        guard: Guard::None,
        to: S::ReadyToSwitchOn,
    },
    Transition {
        number: 7,
        from: states(&[S::ReadyToSwitchOn]),
        trigger: events(&[E::Cmd(C::DisableVoltage), E::Cmd(C::QuickStop)]),
        guard: Guard::None,
        to: S::SwitchOnDisabled,
    },
    Transition {
        number: 8,
        from: states(&[S::OperationEnabled]),
        trigger: events(&[E::Cmd(C::Shutdown)]),
        guard: Guard::None,
        to: S::ReadyToSwitchOn,
    },
    Transition {
        number: 9,
        from: states(&[S::OperationEnabled]),
        trigger: events(&[E::Cmd(C::DisableVoltage)]),
        guard: Guard::None,
        to: S::SwitchOnDisabled,
    },
    Transition {
        number: 10,
        from: states(&[S::SwitchedOn]),
        trigger: events(&[E::Cmd(C::DisableVoltage), E::Cmd(C::QuickStop)]),
        guard: Guard::None,
        to: S::SwitchOnDisabled,
    },
    Transition {
        number: 11,
        from: states(&[S::OperationEnabled]),
        trigger: events(&[E::Cmd(C::QuickStop)]),
        guard: Guard::None,
        to: S::QuickStopActive,
    },
    Transition {
        number: 12,
        from: states(&[S::QuickStopActive]),
        trigger: events(&[E::Cmd(C::DisableVoltage)]),
        guard: Guard::None,
        to: S::SwitchOnDisabled,
    },
    Transition {
        number: 12,
        from: states(&[S::QuickStopActive]),
        trigger: events(&[E::QuickStopDone]),
        guard: Guard::QuickStopEnds,
        to: S::SwitchOnDisabled,
    },
    Transition {
        number: 13,
        from: states(&[
            S::NotReadyToSwitchOn,
            S::SwitchOnDisabled,
            S::ReadyToSwitchOn,
            S::SwitchedOn,
            S::OperationEnabled,
            S::QuickStopActive,
        ]),
        trigger: events(&[E::FaultDetected]),
        guard: Guard::None,
        to: S::FaultReactionActive,
    },
    Transition {
        number: 14,
        from: states(&[S::FaultReactionActive]),
        trigger: events(&[E::FaultReactionDone]),
        guard: Guard::None,
        to: S::Fault,
    },
    Transition {
        number: 15,
        from: states(&[S::Fault]),
        trigger: events(&[E::FaultResetEdge]),
        guard: Guard::FaultCleared,
        to: S::SwitchOnDisabled,
    },
    Transition {
        number: 16,
        from: states(&[S::QuickStopActive]),
        trigger: events(&[E::Cmd(C::EnableOperation)]),
        guard: Guard::QuickStopStays,
        to: S::OperationEnabled,
    },
];

/// Per state (index = `PdsState` discriminant): the events some transition leaving it
/// reacts to. Lets [`find`] answer the every-cycle case (a controlword that asks for the
/// state the drive is already in) without walking the table.
const EVENTS_FROM: [u16; 8] = {
    let mut m = [0u16; 8];
    let mut t = 0;
    while t < TRANSITIONS.len() {
        let mut s = 0;
        while s < 8 {
            if TRANSITIONS[t].from & (1 << s) != 0 {
                m[s] |= TRANSITIONS[t].trigger;
            }
            s += 1;
        }
        t += 1;
    }
    m
};

/// Whether some transition leaves `state` on `event` (guards aside): one look-up in
/// the per-state event masks.
#[inline(always)]
pub fn leaves_on(state: PdsState, event: Event) -> bool {
    EVENTS_FROM[state as usize & 7] & event.bit() != 0
}

/// Finds the transition that fires for `event` in `state`; `guard_ok` decides guards.
pub fn find(
    state: PdsState,
    event: Event,
    guard_ok: impl Fn(Guard) -> bool,
) -> Option<&'static Transition> {
    let sb = state.bit();
    let eb = event.bit();
    if !leaves_on(state, event) {
        return None;
    }
    TRANSITIONS
        .iter()
        .find(|t| t.from & sb != 0 && t.trigger & eb != 0 && guard_ok(t.guard))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn find_shortcut_agrees_with_the_table() {
        use Command as C;
        let events = [
            Event::Cmd(C::Shutdown),
            Event::Cmd(C::SwitchOn),
            Event::Cmd(C::EnableOperation),
            Event::Cmd(C::DisableVoltage),
            Event::Cmd(C::QuickStop),
            Event::Cmd(C::FaultReset),
            Event::InitDone,
            Event::FaultDetected,
            Event::FaultReactionDone,
            Event::QuickStopDone,
            Event::FaultResetEdge,
        ];
        for st in PdsState::ALL {
            for ev in events {
                for guard_result in [true, false] {
                    let naive = TRANSITIONS.iter().find(|t| {
                        t.from & st.bit() != 0 && t.trigger & ev.bit() != 0 && guard_result
                    });
                    assert_eq!(
                        find(st, ev, |_| guard_result).map(|t| t.number),
                        naive.map(|t| t.number),
                        "{st:?} {ev:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn decode_typical_controlwords() {
        assert_eq!(Command::decode(0x0006), Command::Shutdown);
        assert_eq!(Command::decode(0x0007), Command::SwitchOn);
        assert_eq!(Command::decode(0x000F), Command::EnableOperation);
        assert_eq!(Command::decode(0x0000), Command::DisableVoltage);
        assert_eq!(Command::decode(0x0002), Command::QuickStop);
        assert_eq!(Command::decode(0x000B), Command::QuickStop);
        assert_eq!(Command::decode(0x0080), Command::FaultReset);
        assert_eq!(Command::decode(0x008F), Command::FaultReset);
        // Mode-specific and manufacturer bits do not change the command.
        assert_eq!(Command::decode(0xFF7F & !0x0080), Command::EnableOperation);
    }

    #[test]
    fn every_controlword_decodes_like_the_standard_masks() {
        for cw in 0..=u16::MAX {
            let c = Command::decode(cw);
            let expect = if cw & 0x80 != 0 {
                Command::FaultReset
            } else if cw & 0x82 == 0x00 {
                Command::DisableVoltage
            } else if cw & 0x86 == 0x02 {
                Command::QuickStop
            } else if cw & 0x87 == 0x06 {
                Command::Shutdown
            } else if cw & 0x8F == 0x07 {
                Command::SwitchOn
            } else {
                assert_eq!(cw & 0x8F, 0x0F);
                Command::EnableOperation
            };
            assert_eq!(c, expect, "cw {cw:#06x}");
        }
    }

    #[test]
    fn statusword_patterns_round_trip() {
        for s in PdsState::ALL {
            let sw = s.statusword_bits() | 0x0200 | (0x0010 * s.voltage_enabled() as u16);
            assert_eq!(PdsState::from_statusword(sw), Some(s));
        }
    }

    #[test]
    fn transition_4_waits_for_the_power_stage_and_nothing_else_does() {
        let t = |ok: bool| {
            find(
                PdsState::SwitchedOn,
                Event::Cmd(Command::EnableOperation),
                |g| g != Guard::ReadyToFollow || ok,
            )
        };
        assert_eq!(t(true).map(|t| t.number), Some(4));
        assert_eq!(t(false), None);
        for row in TRANSITIONS {
            assert_eq!(row.guard == Guard::ReadyToFollow, row.number == 4);
        }
    }

    #[test]
    fn table_has_every_transition_number() {
        for n in 0..=16u8 {
            assert!(TRANSITIONS.iter().any(|t| t.number == n), "transition {n}");
        }
    }
}
