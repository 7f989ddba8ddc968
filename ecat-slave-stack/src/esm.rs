//! The EtherCAT state machine (ETG.1000.6): states, transitions, AL status.
//!
//! This module is pure logic, no ESC access: [`decide`] maps (current state, pending
//! error, AL control word) to a [`Decision`] through the transition table
//! [`TRANSITIONS`]; [`Esm`] holds the AL status (state, error indication, status code,
//! device-ID flag) and applies the outcome of a transition. The slave runtime
//! ([`crate::slave`]) runs the checks of each transition (SyncManagers, mapping, sync)
//! between [`Esm::request`] and [`Esm::finish`].
//!
//! Rules (ETG.1000.6, the EtherCAT state machine):
//! * upward steps one at a time (I→P→S→O), downward steps may skip;
//! * refused transitions (I→S, I→O, P→O, P→B, S→B, O→B, B→P/S/O) answer 0x0011 and
//!   stay in the current state with the error indication set; a state code outside
//!   {1, 2, 3, 4, 8} answers 0x0012 the same way. A refusal while in Op falls back to
//!   Safe-Op (outputs never keep running under an error indication);
//! * Bootstrap (ETG.1000.6) is an option ([`Esm::with_bootstrap`], off by default):
//!   off, Init→Boot answers 0x0013 and stays in Init; on, Init→Boot is allowed (the
//!   runtime checks SM0/SM1 against the bootstrap mailbox, else 0x0015 and Init) and
//!   Boot→Init is allowed; every other way into or out of Boot stays refused with
//!   0x0011, a refusal in Boot staying in Boot. In Boot the mailbox runs (FoE), the
//!   process data does not;
//! * while the error indication is set, requests without the acknowledge bit (0x0120
//!   bit 4) are ignored, except a request for Init (implicit acknowledge);
//! * a successful transition clears the status code;
//! * device identification: AL control bit 5 with no error pending puts the ID into
//!   0x0134 and sets AL status bit 5.

use crate::al_status::AlStatusCode;
use crate::registers::{AlControl, AlStatus};

/// An ESM state as encoded in AL control / AL status bits 3:0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
#[repr(u8)]
pub enum EsmState {
    /// Init.
    Init = 1,
    /// Pre-Operational: mailbox running.
    PreOp = 2,
    /// Bootstrap (firmware download over FoE); only when enabled
    /// ([`Esm::with_bootstrap`]), else refused with 0x0013.
    Bootstrap = 3,
    /// Safe-Operational: inputs running, outputs in safe state.
    SafeOp = 4,
    /// Operational.
    Op = 8,
}

impl EsmState {
    /// Decodes bits 3:0 of AL control / AL status.
    pub const fn from_bits(v: u8) -> Option<Self> {
        match v & 0x0F {
            1 => Some(Self::Init),
            2 => Some(Self::PreOp),
            3 => Some(Self::Bootstrap),
            4 => Some(Self::SafeOp),
            8 => Some(Self::Op),
            _ => None,
        }
    }
    /// The 4-bit code.
    pub const fn bits(self) -> u8 {
        self as u8
    }
    /// Position in the upward order Init < Pre-Op < Safe-Op < Op (Bootstrap ranks
    /// with Init: it is only reachable from Init).
    pub const fn level(self) -> u8 {
        match self {
            Self::Init | Self::Bootstrap => 0,
            Self::PreOp => 1,
            Self::SafeOp => 2,
            Self::Op => 3,
        }
    }
    /// Mailbox running (Pre-Op and above, and Bootstrap).
    pub const fn mailbox_running(self) -> bool {
        matches!(
            self,
            Self::PreOp | Self::SafeOp | Self::Op | Self::Bootstrap
        )
    }
    /// Process data running (Safe-Op and Op).
    pub const fn process_data_running(self) -> bool {
        matches!(self, Self::SafeOp | Self::Op)
    }
}

/// What one AL control write asks the slave to do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    /// Nothing to do: same state, or the request is ignored because an error
    /// indication is pending and the request carries no acknowledge.
    None,
    /// An allowed transition: the runtime runs its checks, then calls [`Esm::finish`].
    Transition {
        /// Current state.
        from: EsmState,
        /// Requested state.
        to: EsmState,
    },
    /// The request is refused: report `code` and go to `state` with the error
    /// indication set.
    Refuse {
        /// AL status code.
        code: AlStatusCode,
        /// Resulting state.
        state: EsmState,
    },
}

/// Outcome of a (current, requested) pair in the transition table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rule {
    /// Same state: no action.
    Stay,
    /// Allowed: run the transition's checks.
    Allowed,
    /// Refused with this code; the resulting state is the current one (Op falls to
    /// Safe-Op), except Bootstrap which resolves to Init.
    Refused(AlStatusCode),
}

use EsmState::{Bootstrap as B, Init as I, Op as O, PreOp as P, SafeOp as S};

/// The transition table of ETG.1000.6 for a slave without Bootstrap: (from, to,
/// rule), every pair of the five states exactly once. With Bootstrap enabled the
/// (Init, Bootstrap) entry becomes [`Rule::Allowed`] ([`rule_with`]).
pub const TRANSITIONS: &[(EsmState, EsmState, Rule)] = &[
    (I, I, Rule::Stay),
    (I, P, Rule::Allowed),
    (I, B, Rule::Refused(AlStatusCode::BootstrapNotSupported)),
    (I, S, Rule::Refused(AlStatusCode::InvalidStateChange)),
    (I, O, Rule::Refused(AlStatusCode::InvalidStateChange)),
    (P, I, Rule::Allowed),
    (P, P, Rule::Stay),
    (P, B, Rule::Refused(AlStatusCode::InvalidStateChange)),
    (P, S, Rule::Allowed),
    (P, O, Rule::Refused(AlStatusCode::InvalidStateChange)),
    (B, I, Rule::Allowed),
    (B, P, Rule::Refused(AlStatusCode::InvalidStateChange)),
    (B, B, Rule::Stay),
    (B, S, Rule::Refused(AlStatusCode::InvalidStateChange)),
    (B, O, Rule::Refused(AlStatusCode::InvalidStateChange)),
    (S, I, Rule::Allowed),
    (S, P, Rule::Allowed),
    (S, B, Rule::Refused(AlStatusCode::InvalidStateChange)),
    (S, S, Rule::Stay),
    (S, O, Rule::Allowed),
    (O, I, Rule::Allowed),
    (O, P, Rule::Allowed),
    (O, B, Rule::Refused(AlStatusCode::InvalidStateChange)),
    (O, S, Rule::Allowed),
    (O, O, Rule::Stay),
];

/// Looks a pair up in [`rule_with`] for a slave without Bootstrap.
pub fn rule(from: EsmState, to: EsmState) -> Rule {
    rule_with(from, to, false)
}

/// Looks a pair up in [`TRANSITIONS`]; with `bootstrap` Init→Bootstrap is allowed.
pub fn rule_with(from: EsmState, to: EsmState, bootstrap: bool) -> Rule {
    if bootstrap && from == EsmState::Init && to == EsmState::Bootstrap {
        return Rule::Allowed;
    }
    TRANSITIONS
        .iter()
        .find(|(f, t, _)| *f == from && *t == to)
        .map_or(
            Rule::Refused(AlStatusCode::InvalidStateChange),
            |(_, _, r)| *r,
        )
}

/// The state a refusal or a local error leaves the slave in when the error is reported
/// from `current` by a slave without Bootstrap: the current state, except that Op
/// falls to Safe-Op and Bootstrap (which such a slave is never in) resolves to Init.
pub const fn refusal_state(current: EsmState) -> EsmState {
    refusal_state_with(current, false)
}

/// [`refusal_state`]; with `bootstrap` a refusal in Bootstrap stays in Bootstrap.
pub const fn refusal_state_with(current: EsmState, bootstrap: bool) -> EsmState {
    match current {
        EsmState::Op => EsmState::SafeOp,
        EsmState::Bootstrap if !bootstrap => EsmState::Init,
        s => s,
    }
}

/// The state an AL status code leaves the slave in when a check or a supervision of
/// the runtime fails, for the AL status codes of ETG.1000.6 (other codes: the
/// current state, Op falling to Safe-Op). Never higher than `current`.
pub fn error_state(code: AlStatusCode, current: EsmState) -> EsmState {
    use AlStatusCode as C;
    let target = match code {
        C::InvalidMailboxConfig | C::InvalidMailboxBoot | C::BootstrapNotSupported => {
            EsmState::Init
        }
        C::InvalidOutputConfig
        | C::InvalidInputConfig
        | C::InvalidSmConfig
        | C::InvalidWatchdogConfig
        | C::InvalidInputMapping
        | C::InvalidOutputMapping
        | C::SyncModeNotSupported
        | C::FreeRunNotSupported
        | C::FreeRunNeeds3Buffer
        | C::NoSync
        | C::InvalidDcSync
        | C::DcInvalidCycleTime
        | C::DcSync0CycleTime
        | C::DcSync1CycleTime => EsmState::PreOp,
        C::SmWatchdog
        | C::FatalSyncError
        | C::PllError
        | C::SyncError
        | C::NoValidOutputs
        | C::NoValidInputs
        | C::InvalidSmTypes => EsmState::SafeOp,
        _ => refusal_state(current),
    };
    if target.level() < current.level() {
        target
    } else {
        refusal_state(current)
    }
}

/// Decides what an AL control word asks for, given the current state and whether the
/// error indication is set, for a slave without Bootstrap. Pure function of the table.
pub fn decide(current: EsmState, error_pending: bool, control: u16) -> Decision {
    decide_with(current, error_pending, control, false)
}

/// [`decide`] for a slave with (`bootstrap` = true) or without Bootstrap support.
pub fn decide_with(
    current: EsmState,
    error_pending: bool,
    control: u16,
    bootstrap: bool,
) -> Decision {
    let control = AlControl::from_raw(control);
    let requested = control.requested();
    if error_pending && !control.ack && requested != Some(EsmState::Init) {
        return Decision::None;
    }
    let Some(to) = requested else {
        return Decision::Refuse {
            code: AlStatusCode::UnknownState,
            state: refusal_state_with(current, bootstrap),
        };
    };
    match rule_with(current, to, bootstrap) {
        Rule::Stay => Decision::None,
        Rule::Allowed => Decision::Transition { from: current, to },
        Rule::Refused(code) => Decision::Refuse {
            code,
            state: refusal_state_with(current, bootstrap),
        },
    }
}

/// The AL status the slave shows the master: state, error indication, status code and
/// device-ID flag (registers 0x0130 and 0x0134).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Esm {
    state: EsmState,
    error: bool,
    code: u16,
    id_loaded: bool,
    /// A transition accepted but not complete yet (S→O waiting for sync lock).
    pending: Option<EsmState>,
    /// Bootstrap supported (Init→Boot allowed).
    bootstrap: bool,
}

impl Default for Esm {
    fn default() -> Self {
        Self::new()
    }
}

impl Esm {
    /// Init, no error, Bootstrap not supported.
    pub const fn new() -> Self {
        Self::with_bootstrap(false)
    }
    /// Init, no error; Bootstrap supported or not (see the module docs).
    pub const fn with_bootstrap(bootstrap: bool) -> Self {
        Esm {
            state: EsmState::Init,
            error: false,
            code: 0,
            id_loaded: false,
            pending: None,
            bootstrap,
        }
    }
    /// Bootstrap supported.
    pub const fn bootstrap_supported(&self) -> bool {
        self.bootstrap
    }
    /// Current state.
    pub const fn state(&self) -> EsmState {
        self.state
    }
    /// Error indication (AL status bit 4).
    pub const fn error(&self) -> bool {
        self.error
    }
    /// AL status code (0x0134); the device ID while [`Esm::id_loaded`].
    pub const fn code(&self) -> u16 {
        self.code
    }
    /// AL status bit 5.
    pub const fn id_loaded(&self) -> bool {
        self.id_loaded
    }
    /// A transition that was accepted and waits for a condition (S→O waiting for the
    /// sync lock).
    pub const fn pending(&self) -> Option<EsmState> {
        self.pending
    }
    /// The 16-bit AL status word (0x0130).
    pub const fn status_word(&self) -> u16 {
        self.status().to_raw()
    }
    /// AL status (0x0130).
    pub const fn status(&self) -> AlStatus {
        AlStatus {
            state: self.state,
            error: self.error,
            id_loaded: self.id_loaded,
        }
    }

    /// Handles one AL control word. An acknowledge (bit 4) or a request for Init
    /// clears a pending error indication (the status code too) before the request is
    /// decided. Refusals are applied here; for [`Decision::Transition`] the caller
    /// runs the checks and calls [`Esm::finish`].
    pub fn request(&mut self, control: u16) -> Decision {
        let d = decide_with(self.state, self.error, control, self.bootstrap);
        let control = AlControl::from_raw(control);
        let init = control.requested() == Some(EsmState::Init);
        if self.error && (control.ack || init) {
            self.error = false;
            self.code = 0;
        }
        if let Some(p) = self.pending {
            if control.state == p.bits() {
                // The same request again while it is waiting: keep waiting.
                return Decision::None;
            }
            // Any other request replaces the waiting one.
            self.pending = None;
        }
        if let Decision::Refuse { code, state } = d {
            self.fail(code, state);
        }
        d
    }

    /// Completes a transition decided by [`Esm::request`]: on `Ok` enters `to` and
    /// clears the status code; on `Err(code)` reports `code` and goes to
    /// [`error_state`]`(code, from)`. Returns the state entered.
    pub fn finish(
        &mut self,
        from: EsmState,
        to: EsmState,
        result: Result<(), AlStatusCode>,
    ) -> EsmState {
        self.pending = None;
        match result {
            Ok(()) => {
                self.state = to;
                self.error = false;
                if !self.id_loaded {
                    self.code = 0;
                }
            }
            Err(code) => {
                let s = error_state(code, from);
                self.fail(code, s);
            }
        }
        self.state
    }

    /// Marks a transition as accepted but waiting (the AL status keeps the current
    /// state until [`Esm::finish`]).
    pub fn set_pending(&mut self, to: EsmState) {
        self.pending = Some(to);
    }

    /// Reports a local error (watchdog, sync loss, application fault) or a refusal:
    /// sets the code and the error indication and moves to `state` (never up).
    pub fn fail(&mut self, code: AlStatusCode, state: EsmState) {
        if state.level() <= self.state.level() {
            self.state = state;
        }
        self.error = true;
        self.id_loaded = false;
        self.code = code.code();
        self.pending = None;
    }

    /// Reports a local error from the current state with the resulting state of
    /// [`error_state`]. Returns the state entered.
    pub fn local_error(&mut self, code: AlStatusCode) -> EsmState {
        let s = error_state(code, self.state);
        self.fail(code, s);
        self.state
    }

    /// Device identification (AL control bit 5): with the bit set and no error
    /// pending, `id` goes into the status code and AL status bit 5 is set; with the
    /// bit clear, a loaded ID is removed again.
    pub fn id_request(&mut self, control: u16, id: u16) {
        if AlControl::from_raw(control).id_request {
            if !self.error {
                self.id_loaded = true;
                self.code = id;
            }
        } else if self.id_loaded {
            self.id_loaded = false;
            if !self.error {
                self.code = 0;
            }
        }
    }
}

/// What the application does when the ESM changes state.
///
/// The CiA 402 coupling lives here: leaving Op while the power drive system is in
/// *Operation enabled* must fault the PDS, going to Init puts the PDS into *Switch on
/// disabled*. A PDS state change never changes the ESM state.
///
/// Bootstrap: [`EsmHooks::on_enter_bootstrap`] and [`EsmHooks::on_leave_bootstrap`]
/// frame the firmware download (power stage off on entry; on leaving, after an
/// accepted image, reset into the bootloader).
pub trait EsmHooks {
    /// Called after every state change the slave made (requested or local).
    fn on_state_change(&mut self, from: EsmState, to: EsmState);
    /// Init → Bootstrap done (after [`EsmHooks::on_state_change`]): the master will
    /// download firmware over FoE. The drive must keep its power stage off.
    fn on_enter_bootstrap(&mut self) {}
    /// Bootstrap → Init done (after [`EsmHooks::on_state_change`]); AL status Init is
    /// already written to the ESC, so the application may reset at once (e.g. into
    /// the bootloader when a downloaded image was accepted).
    fn on_leave_bootstrap(&mut self) {}
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: [EsmState; 5] = [I, P, B, S, O];

    #[test]
    fn table_covers_every_pair_once() {
        for f in ALL {
            for t in ALL {
                assert_eq!(
                    TRANSITIONS
                        .iter()
                        .filter(|(a, b, _)| *a == f && *b == t)
                        .count(),
                    1
                );
            }
        }
        assert_eq!(TRANSITIONS.len(), 25);
    }

    #[test]
    fn every_unknown_state_code_is_refused_with_0x0012() {
        for bits in 0u16..16 {
            if EsmState::from_bits(bits as u8).is_some() {
                continue;
            }
            for s in ALL {
                let d = decide(s, false, bits);
                assert_eq!(
                    d,
                    Decision::Refuse {
                        code: AlStatusCode::UnknownState,
                        state: refusal_state(s)
                    }
                );
            }
        }
    }

    #[test]
    fn error_state_never_goes_up() {
        for c in AlStatusCode::ALL {
            for s in ALL {
                assert!(error_state(*c, s).level() <= s.level());
            }
        }
    }
}
