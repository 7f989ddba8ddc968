//! AL status codes (register 0x0134), the single table of the stack.

/// An AL status code as reported in register 0x0134.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u16)]
pub enum AlStatusCode {
    /// No error.
    NoError = 0x0000,
    /// Unspecified error.
    Unspecified = 0x0001,
    /// No memory.
    NoMemory = 0x0002,
    /// Invalid device setup.
    InvalidDeviceSetup = 0x0003,
    /// SII/EEPROM information does not match the firmware.
    SiiMismatch = 0x0006,
    /// Invalid requested state change.
    InvalidStateChange = 0x0011,
    /// Unknown requested state.
    UnknownState = 0x0012,
    /// Bootstrap not supported.
    BootstrapNotSupported = 0x0013,
    /// No valid firmware.
    NoValidFirmware = 0x0014,
    /// Invalid mailbox configuration (bootstrap).
    InvalidMailboxBoot = 0x0015,
    /// Invalid mailbox configuration (Pre-Op).
    InvalidMailboxConfig = 0x0016,
    /// Invalid sync manager configuration.
    InvalidSmConfig = 0x0017,
    /// No valid inputs available.
    NoValidInputs = 0x0018,
    /// No valid outputs.
    NoValidOutputs = 0x0019,
    /// Synchronisation error.
    SyncError = 0x001A,
    /// Sync manager (process-data) watchdog.
    SmWatchdog = 0x001B,
    /// Invalid sync manager types.
    InvalidSmTypes = 0x001C,
    /// Invalid output configuration (SM2).
    InvalidOutputConfig = 0x001D,
    /// Invalid input configuration (SM3).
    InvalidInputConfig = 0x001E,
    /// Invalid watchdog configuration.
    InvalidWatchdogConfig = 0x001F,
    /// Slave needs cold start.
    NeedsColdStart = 0x0020,
    /// Slave needs Init.
    NeedsInit = 0x0021,
    /// Slave needs Pre-Op.
    NeedsPreOp = 0x0022,
    /// Slave needs Safe-Op.
    NeedsSafeOp = 0x0023,
    /// Invalid input (TxPDO) mapping.
    InvalidInputMapping = 0x0024,
    /// Invalid output (RxPDO) mapping.
    InvalidOutputMapping = 0x0025,
    /// Inconsistent settings.
    InconsistentSettings = 0x0026,
    /// Free-run not supported.
    FreeRunNotSupported = 0x0027,
    /// Sync mode not supported.
    SyncModeNotSupported = 0x0028,
    /// Free-run needs 3-buffer mode.
    FreeRunNeeds3Buffer = 0x0029,
    /// Background watchdog.
    BackgroundWatchdog = 0x002A,
    /// No valid inputs and outputs.
    NoValidInputsOutputs = 0x002B,
    /// Fatal sync error (SYNC0 events missing).
    FatalSyncError = 0x002C,
    /// No sync error (control loop not locked to SYNC0 in time).
    NoSync = 0x002D,
    /// Invalid DC SYNC configuration.
    InvalidDcSync = 0x0030,
    /// Invalid DC latch configuration.
    InvalidDcLatch = 0x0031,
    /// PLL error (lock lost).
    PllError = 0x0032,
    /// DC sync IO error.
    DcSyncIo = 0x0033,
    /// DC sync timeout.
    DcSyncTimeout = 0x0034,
    /// DC invalid sync cycle time.
    DcInvalidCycleTime = 0x0035,
    /// DC SYNC0 cycle time.
    DcSync0CycleTime = 0x0036,
    /// DC SYNC1 cycle time.
    DcSync1CycleTime = 0x0037,
    /// Mailbox CoE error.
    MailboxCoe = 0x0043,
    /// EEPROM no access.
    EepromNoAccess = 0x0050,
    /// EEPROM error.
    EepromError = 0x0051,
    /// External hardware not ready.
    ExternalHardwareNotReady = 0x0052,
    /// Slave restarted locally.
    RestartedLocally = 0x0060,
    /// Device identification value updated.
    DeviceIdUpdated = 0x0061,
    /// Supply voltage too low.
    SupplyVoltageTooLow = 0x0080,
    /// Supply voltage too high.
    SupplyVoltageTooHigh = 0x0081,
}

impl AlStatusCode {
    /// Every code in the table, for round-trip tests and documentation.
    pub const ALL: &'static [AlStatusCode] = &[
        Self::NoError,
        Self::Unspecified,
        Self::NoMemory,
        Self::InvalidDeviceSetup,
        Self::SiiMismatch,
        Self::InvalidStateChange,
        Self::UnknownState,
        Self::BootstrapNotSupported,
        Self::NoValidFirmware,
        Self::InvalidMailboxBoot,
        Self::InvalidMailboxConfig,
        Self::InvalidSmConfig,
        Self::NoValidInputs,
        Self::NoValidOutputs,
        Self::SyncError,
        Self::SmWatchdog,
        Self::InvalidSmTypes,
        Self::InvalidOutputConfig,
        Self::InvalidInputConfig,
        Self::InvalidWatchdogConfig,
        Self::NeedsColdStart,
        Self::NeedsInit,
        Self::NeedsPreOp,
        Self::NeedsSafeOp,
        Self::InvalidInputMapping,
        Self::InvalidOutputMapping,
        Self::InconsistentSettings,
        Self::FreeRunNotSupported,
        Self::SyncModeNotSupported,
        Self::FreeRunNeeds3Buffer,
        Self::BackgroundWatchdog,
        Self::NoValidInputsOutputs,
        Self::FatalSyncError,
        Self::NoSync,
        Self::InvalidDcSync,
        Self::InvalidDcLatch,
        Self::PllError,
        Self::DcSyncIo,
        Self::DcSyncTimeout,
        Self::DcInvalidCycleTime,
        Self::DcSync0CycleTime,
        Self::DcSync1CycleTime,
        Self::MailboxCoe,
        Self::EepromNoAccess,
        Self::EepromError,
        Self::ExternalHardwareNotReady,
        Self::RestartedLocally,
        Self::DeviceIdUpdated,
        Self::SupplyVoltageTooLow,
        Self::SupplyVoltageTooHigh,
    ];

    /// The raw register value.
    pub const fn code(self) -> u16 {
        self as u16
    }

    /// Looks a raw value up in the table.
    pub fn from_code(code: u16) -> Option<Self> {
        Self::ALL.iter().copied().find(|c| c.code() == code)
    }

    /// Human-readable text for diagnostics and the ESI.
    pub const fn text(self) -> &'static str {
        match self {
            Self::NoError => "no error",
            Self::Unspecified => "unspecified error",
            Self::NoMemory => "no memory",
            Self::InvalidDeviceSetup => "invalid device setup",
            Self::SiiMismatch => "SII/EEPROM information does not match firmware",
            Self::InvalidStateChange => "invalid requested state change",
            Self::UnknownState => "unknown requested state",
            Self::BootstrapNotSupported => "bootstrap not supported",
            Self::NoValidFirmware => "no valid firmware",
            Self::InvalidMailboxBoot => "invalid mailbox configuration (bootstrap)",
            Self::InvalidMailboxConfig => "invalid mailbox configuration",
            Self::InvalidSmConfig => "invalid sync manager configuration",
            Self::NoValidInputs => "no valid inputs available",
            Self::NoValidOutputs => "no valid outputs",
            Self::SyncError => "synchronisation error",
            Self::SmWatchdog => "sync manager watchdog",
            Self::InvalidSmTypes => "invalid sync manager types",
            Self::InvalidOutputConfig => "invalid output configuration",
            Self::InvalidInputConfig => "invalid input configuration",
            Self::InvalidWatchdogConfig => "invalid watchdog configuration",
            Self::NeedsColdStart => "slave needs cold start",
            Self::NeedsInit => "slave needs INIT",
            Self::NeedsPreOp => "slave needs PREOP",
            Self::NeedsSafeOp => "slave needs SAFEOP",
            Self::InvalidInputMapping => "invalid input mapping",
            Self::InvalidOutputMapping => "invalid output mapping",
            Self::InconsistentSettings => "inconsistent settings",
            Self::FreeRunNotSupported => "free-run not supported",
            Self::SyncModeNotSupported => "sync mode not supported",
            Self::FreeRunNeeds3Buffer => "free-run needs 3-buffer mode",
            Self::BackgroundWatchdog => "background watchdog",
            Self::NoValidInputsOutputs => "no valid inputs and outputs",
            Self::FatalSyncError => "fatal sync error",
            Self::NoSync => "no sync error",
            Self::InvalidDcSync => "invalid DC SYNC configuration",
            Self::InvalidDcLatch => "invalid DC latch configuration",
            Self::PllError => "PLL error",
            Self::DcSyncIo => "DC sync IO error",
            Self::DcSyncTimeout => "DC sync timeout",
            Self::DcInvalidCycleTime => "DC invalid sync cycle time",
            Self::DcSync0CycleTime => "DC SYNC0 cycle time",
            Self::DcSync1CycleTime => "DC SYNC1 cycle time",
            Self::MailboxCoe => "mailbox CoE error",
            Self::EepromNoAccess => "EEPROM no access",
            Self::EepromError => "EEPROM error",
            Self::ExternalHardwareNotReady => "external hardware not ready",
            Self::RestartedLocally => "slave restarted locally",
            Self::DeviceIdUpdated => "device identification value updated",
            Self::SupplyVoltageTooLow => "supply voltage too low",
            Self::SupplyVoltageTooHigh => "supply voltage too high",
        }
    }
}
