//! The EtherCAT state machine (ETG.1000.6): states, transitions, AL status.

/// An ESM state as encoded in AL control / AL status bits 3:0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
#[repr(u8)]
pub enum EsmState {
    /// Init.
    Init = 1,
    /// Pre-Operational: mailbox running.
    PreOp = 2,
    /// Bootstrap (firmware update); refused by this stack with 0x0013.
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
}
