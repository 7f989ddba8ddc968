//! The SDO abort codes.

/// SDO abort codes (CiA 301 / ETG.1000.6), the single table of the stack.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum SdoAbort {
    /// Toggle bit not changed.
    ToggleBit = 0x0503_0000,
    /// SDO protocol timed out.
    Timeout = 0x0504_0000,
    /// Client/server command specifier not valid or unknown.
    InvalidCommand = 0x0504_0001,
    /// Out of memory.
    OutOfMemory = 0x0504_0005,
    /// Unsupported access to an object (e.g. complete access where not possible).
    UnsupportedAccess = 0x0601_0000,
    /// Attempt to read a write-only object.
    ReadWriteOnly = 0x0601_0001,
    /// Attempt to write a read-only object.
    WriteReadOnly = 0x0601_0002,
    /// Sub-index cannot be written, sub-index 0 must be 0 for write access.
    SubindexZeroFirst = 0x0601_0003,
    /// Complete access not supported for variable-length objects.
    CompleteAccessVariableLength = 0x0601_0004,
    /// Object length exceeds mailbox size.
    ExceedsMailbox = 0x0601_0005,
    /// Object mapped to an RxPDO, SDO download blocked.
    MappedToRxPdo = 0x0601_0006,
    /// Object does not exist in the object dictionary.
    ObjectDoesNotExist = 0x0602_0000,
    /// Object cannot be mapped to the PDO.
    NotMappable = 0x0604_0041,
    /// Number and length of the objects to be mapped would exceed the PDO length.
    PdoLengthExceeded = 0x0604_0042,
    /// General parameter incompatibility.
    ParameterIncompatibility = 0x0604_0043,
    /// General internal incompatibility in the device.
    InternalIncompatibility = 0x0604_0047,
    /// Access failed due to a hardware error.
    HardwareError = 0x0606_0000,
    /// Data type does not match, length of service parameter does not match.
    TypeMismatch = 0x0607_0010,
    /// Data type does not match, length of service parameter too high.
    LengthTooHigh = 0x0607_0012,
    /// Data type does not match, length of service parameter too low.
    LengthTooLow = 0x0607_0013,
    /// Sub-index does not exist.
    SubindexDoesNotExist = 0x0609_0011,
    /// Value range of parameter exceeded (write access).
    ValueRangeExceeded = 0x0609_0030,
    /// Value of parameter written too high.
    ValueTooHigh = 0x0609_0031,
    /// Value of parameter written too low.
    ValueTooLow = 0x0609_0032,
    /// Maximum value is less than minimum value.
    MaxLessThanMin = 0x0609_0036,
    /// General error.
    GeneralError = 0x0800_0000,
    /// Data cannot be transferred or stored to the application.
    DataCannotBeStored = 0x0800_0020,
    /// … because of local control.
    LocalControl = 0x0800_0021,
    /// … because of the present device (ESM) state.
    StateConflict = 0x0800_0022,
    /// No data available.
    NoDataAvailable = 0x0800_0024,
}

impl SdoAbort {
    /// The raw 32-bit code sent in the abort frame.
    pub const fn code(self) -> u32 {
        self as u32
    }
}

impl SdoAbort {
    /// Every code of the table, in numeric order.
    pub const ALL: &'static [SdoAbort] = &[
        Self::ToggleBit,
        Self::Timeout,
        Self::InvalidCommand,
        Self::OutOfMemory,
        Self::UnsupportedAccess,
        Self::ReadWriteOnly,
        Self::WriteReadOnly,
        Self::SubindexZeroFirst,
        Self::CompleteAccessVariableLength,
        Self::ExceedsMailbox,
        Self::MappedToRxPdo,
        Self::ObjectDoesNotExist,
        Self::NotMappable,
        Self::PdoLengthExceeded,
        Self::ParameterIncompatibility,
        Self::InternalIncompatibility,
        Self::HardwareError,
        Self::TypeMismatch,
        Self::LengthTooHigh,
        Self::LengthTooLow,
        Self::SubindexDoesNotExist,
        Self::ValueRangeExceeded,
        Self::ValueTooHigh,
        Self::ValueTooLow,
        Self::MaxLessThanMin,
        Self::GeneralError,
        Self::DataCannotBeStored,
        Self::LocalControl,
        Self::StateConflict,
        Self::NoDataAvailable,
    ];

    /// The abort with this raw code, if it is in the table.
    pub fn from_code(code: u32) -> Option<Self> {
        Self::ALL.iter().copied().find(|a| a.code() == code)
    }
}
