//! The scalar descriptions of entries: data type, access, PDO mappability, default
//! value and object code.

use super::*;

/// CoE data type codes (ETG.1000.6), as used by SDO information, the SII and the ESI.
/// The codes used here all fit a byte (`as u16` gives the 16-bit wire code), which
/// keeps [`Entry`] at 24 bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum DataType {
    /// BOOL (1 bit).
    Boolean = 0x0001,
    /// INT8.
    Integer8 = 0x0002,
    /// INT16.
    Integer16 = 0x0003,
    /// INT32.
    Integer32 = 0x0004,
    /// UINT8 (USINT).
    Unsigned8 = 0x0005,
    /// UINT16 (UINT).
    Unsigned16 = 0x0006,
    /// UINT32 (UDINT).
    Unsigned32 = 0x0007,
    /// REAL32.
    Real32 = 0x0008,
    /// VISIBLE_STRING.
    VisibleString = 0x0009,
    /// OCTET_STRING.
    OctetString = 0x000A,
    /// INT64.
    Integer64 = 0x0015,
    /// UINT64.
    Unsigned64 = 0x001B,
    /// BIT1 … BIT8 are 0x0030 + n − 1; padding entries use these.
    Bit1 = 0x0030,
    /// BIT2.
    Bit2 = 0x0031,
    /// BIT3.
    Bit3 = 0x0032,
    /// BIT4.
    Bit4 = 0x0033,
    /// BIT5.
    Bit5 = 0x0034,
    /// BIT6.
    Bit6 = 0x0035,
    /// BIT7.
    Bit7 = 0x0036,
    /// BIT8.
    Bit8 = 0x0037,
}

impl DataType {
    /// Every data type, in the order the ESI lists its base types.
    pub const ALL: [DataType; 20] = [
        DataType::Boolean,
        DataType::Integer8,
        DataType::Integer16,
        DataType::Integer32,
        DataType::Integer64,
        DataType::Unsigned8,
        DataType::Unsigned16,
        DataType::Unsigned32,
        DataType::Unsigned64,
        DataType::Real32,
        DataType::Bit1,
        DataType::Bit2,
        DataType::Bit3,
        DataType::Bit4,
        DataType::Bit5,
        DataType::Bit6,
        DataType::Bit7,
        DataType::Bit8,
        DataType::VisibleString,
        DataType::OctetString,
    ];
    /// The raw code.
    pub const fn code(self) -> u16 {
        self as u16
    }
    /// Name as written in ESI files (ETG.2000).
    pub const fn esi_name(self) -> &'static str {
        match self {
            Self::Boolean => "BOOL",
            Self::Integer8 => "SINT",
            Self::Integer16 => "INT",
            Self::Integer32 => "DINT",
            Self::Unsigned8 => "USINT",
            Self::Unsigned16 => "UINT",
            Self::Unsigned32 => "UDINT",
            Self::Real32 => "REAL",
            Self::VisibleString => "STRING",
            Self::OctetString => "OCTET_STRING",
            Self::Integer64 => "LINT",
            Self::Unsigned64 => "ULINT",
            Self::Bit1 => "BIT1",
            Self::Bit2 => "BIT2",
            Self::Bit3 => "BIT3",
            Self::Bit4 => "BIT4",
            Self::Bit5 => "BIT5",
            Self::Bit6 => "BIT6",
            Self::Bit7 => "BIT7",
            Self::Bit8 => "BIT8",
        }
    }
    /// True for the signed integer types.
    pub const fn is_signed(self) -> bool {
        matches!(
            self,
            Self::Integer8 | Self::Integer16 | Self::Integer32 | Self::Integer64
        )
    }
    /// True for types whose length is not fixed by the type (strings).
    pub const fn is_variable_length(self) -> bool {
        matches!(self, Self::VisibleString | Self::OctetString)
    }
}

/// Access rights of one entry, per ESM state (Pre-Op, Safe-Op, Op). In Init there is
/// no mailbox, hence no SDO access.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Access(pub(super) u8);

impl Access {
    const R_PREOP: u8 = 1 << 0;
    const R_SAFEOP: u8 = 1 << 1;
    const R_OP: u8 = 1 << 2;
    const W_PREOP: u8 = 1 << 3;
    const W_SAFEOP: u8 = 1 << 4;
    const W_OP: u8 = 1 << 5;
    const R_ALL: u8 = Self::R_PREOP | Self::R_SAFEOP | Self::R_OP;
    const W_ALL: u8 = Self::W_PREOP | Self::W_SAFEOP | Self::W_OP;

    /// Read-only in every state.
    pub const RO: Access = Access(Self::R_ALL);
    /// Read and write in every state.
    pub const RW: Access = Access(Self::R_ALL | Self::W_ALL);
    /// Readable always, writable only in Pre-Op (mapping and assignment objects).
    pub const RW_PREOP: Access = Access(Self::R_ALL | Self::W_PREOP);
    /// Readable always, writable in Pre-Op and Safe-Op but not in Op.
    pub const RW_PREOP_SAFEOP: Access = Access(Self::R_ALL | Self::W_PREOP | Self::W_SAFEOP);
    /// Write-only in every state.
    pub const WO: Access = Access(Self::W_ALL);

    /// Readable in at least one state.
    pub const fn readable(self) -> bool {
        self.0 & Self::R_ALL != 0
    }
    /// Writable in at least one state.
    pub const fn writable(self) -> bool {
        self.0 & Self::W_ALL != 0
    }
    /// Readable in `state`.
    pub fn readable_in(self, state: EsmState) -> bool {
        self.0 & Self::read_bit(state) != 0
    }
    /// Writable in `state`.
    pub fn writable_in(self, state: EsmState) -> bool {
        self.0 & (Self::read_bit(state) << 3) != 0
    }
    fn read_bit(state: EsmState) -> u8 {
        match state {
            EsmState::PreOp => Self::R_PREOP,
            EsmState::SafeOp => Self::R_SAFEOP,
            EsmState::Op => Self::R_OP,
            EsmState::Init | EsmState::Bootstrap => 0,
        }
    }
    /// The 16-bit access word of SDO information's entry description
    /// (bits 0-2 read in PreOp/SafeOp/Op, bits 3-5 write in PreOp/SafeOp/Op; the PDO
    /// bits 6 and 7 are added by [`Entry::sdo_info_access`]).
    pub const fn bits(self) -> u16 {
        self.0 as u16
    }
    /// ESI `<Access>` text: "ro", "rw", "wo".
    pub const fn esi(self) -> &'static str {
        match (self.readable(), self.writable()) {
            (true, true) => "rw",
            (false, true) => "wo",
            _ => "ro",
        }
    }
}

/// Whether an entry may be mapped into process data, and in which direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum PdoMappable {
    /// Not mappable.
    No = 0,
    /// Mappable into an RxPDO (outputs of the master).
    Rx = 1,
    /// Mappable into a TxPDO (inputs of the master).
    Tx = 2,
    /// Mappable in both directions.
    RxTx = 3,
}

impl PdoMappable {
    /// Mappable into an RxPDO.
    pub const fn rx(self) -> bool {
        matches!(self, Self::Rx | Self::RxTx)
    }
    /// Mappable into a TxPDO.
    pub const fn tx(self) -> bool {
        matches!(self, Self::Tx | Self::RxTx)
    }
}

/// Default value of an entry (also the ESI `DefaultData`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DefaultValue {
    /// No meaningful default (measured values, counters filled at run time).
    None,
    /// A numeric default.
    Int(i64),
    /// A text default (visible strings).
    Text(&'static str),
}

/// CoE object codes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum ObjectCode {
    /// A single variable (sub-index 0 only).
    Var = 7,
    /// An array: sub-index 0 holds the count, entries 1..n share a type.
    Array = 8,
    /// A record: sub-index 0 holds the count, entries have their own types.
    Record = 9,
}

/// True for the types whose [`Entry::min`]/[`Entry::max`] are meaningful.
pub const fn has_numeric_range(t: DataType) -> bool {
    !matches!(
        t,
        DataType::Real32 | DataType::VisibleString | DataType::OctetString
    )
}
