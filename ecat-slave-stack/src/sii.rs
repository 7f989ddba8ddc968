//! The device description and the SII EEPROM image built from it.
//!
//! One [`DeviceDescription`] value (chosen by the product) feeds the SII image
//! ([`build`]) and the ESI XML ([`crate::esi::write`]), so the two can never
//! disagree: identity, names, mailbox SyncManagers, CoE details, FMMU and
//! SyncManager lists, DC op modes and the ESC configuration area come from the same
//! fields. [`Sii`] is a zero-copy, panic-free view of an image (used by the tests,
//! the ESC simulator and anyone who must read an EEPROM dump back).
//!
//! # Image layout (ETG.1000.6 / ETG.2010, word addresses)
//! | words | content |
//! |---|---|
//! | 0x00-0x07 | ESC configuration area: PDI control (→0x0140), PDI configuration (→0x0150), SYNC pulse length (→0x0982), extended PDI configuration (→0x0152), station alias (→0x0012), 2 reserved, checksum (CRC-8 over bytes 0-13 in the low byte) |
//! | 0x08-0x0F | vendor ID, product code, revision, serial number (u32 each) |
//! | 0x10-0x13 | reserved (0) |
//! | 0x14-0x17 | bootstrap mailbox receive/send offset and size (0: Bootstrap is not supported; [`set_bootstrap_mailbox`] fills them in) |
//! | 0x18-0x1B | standard mailbox out (SM0) / in (SM1) offset and size |
//! | 0x1C | mailbox protocols (0x0004 = CoE, 0x0008 = FoE) |
//! | 0x3E | EEPROM size in Kibit − 1 |
//! | 0x3F | version (1) |
//! | 0x40… | categories: strings (10), general (30; order string = the ESI type name), FMMU (40), SyncManager (41), DC (60), TxPDO (50 = 0x32) and RxPDO (51 = 0x33) with [`build_with_pdos`], end (0xFFFF) |
//!
//! # PDI configuration per ESC flavour
//! * **LAN9252**: PDI type 0x80 (the ESC core's on-chip bus to the LAN9252 host
//!   interface; the host interface itself is strapped to SPI). 0x0150 unused (0).
//! * **ET1100**: PDI type 0x05 (SPI slave); 0x0150 = 0x03: SPI mode 3, SPI_IRQ
//!   push-pull active low, SPI_SEL active low, normal data-out sampling.
//!
//! Both: 0x0141 = 0x0C (device emulation off — the µC runs the ESM —, no enhanced link
//! detection, DC SYNC-out and latch-in units on); 0x0151 = [`sync_latch_config`] of
//! the product's [`DeviceDescription::sync0_drive`] (SYNC0 pin is an output driven
//! that way and mapped to AL event bit 2; SYNC1/LATCH1 pin as latch input); SYNC pulse
//! length as described ([`DeviceDescription::sync_pulse_length`]). The drive is the
//! product's choice (its board waits for the edge it names), not the stack's.

mod build;
mod read;
pub use build::*;
pub use read::*;

/// Mailbox protocol bit of SII word 0x1C: CoE.
pub const MBOX_COE: u16 = 0x0004;
/// Mailbox protocol bit of SII word 0x1C: FoE (IgH refuses FoE without it). With it
/// the general category's FoE details byte is 1 and the ESI mailbox lists `<FoE/>`.
pub const MBOX_FOE: u16 = 0x0008;
/// All protocol bits defined by ETG.1000.6 (AoE, EoE, CoE, FoE, SoE, VoE).
pub const MBOX_VALID: u16 = 0x003F;

/// Category types.
pub mod category {
    /// Strings.
    pub const STRINGS: u16 = 10;
    /// General.
    pub const GENERAL: u16 = 30;
    /// FMMU usage.
    pub const FMMU: u16 = 40;
    /// SyncManagers.
    pub const SYNC_MANAGER: u16 = 41;
    /// TxPDO (0x32): the default TxPDOs, for masters that configure from the SII.
    pub const TXPDO: u16 = 50;
    /// RxPDO (0x33): the default RxPDOs.
    pub const RXPDO: u16 = 51;
    /// Distributed clocks op modes.
    pub const DC: u16 = 60;
    /// End marker.
    pub const END: u16 = 0xFFFF;
}

/// Word addresses of the fixed part.
pub mod word {
    /// PDI control.
    pub const PDI_CONTROL: usize = 0x00;
    /// PDI configuration.
    pub const PDI_CONFIG: usize = 0x01;
    /// SYNC impulse length.
    pub const SYNC_PULSE: usize = 0x02;
    /// Extended PDI configuration.
    pub const PDI_CONFIG2: usize = 0x03;
    /// Configured station alias.
    pub const ALIAS: usize = 0x04;
    /// Checksum.
    pub const CHECKSUM: usize = 0x07;
    /// Vendor ID (2 words).
    pub const VENDOR_ID: usize = 0x08;
    /// Product code (2 words).
    pub const PRODUCT_CODE: usize = 0x0A;
    /// Revision (2 words).
    pub const REVISION: usize = 0x0C;
    /// Serial number (2 words).
    pub const SERIAL: usize = 0x0E;
    /// Bootstrap receive mailbox offset.
    pub const BOOT_RX_OFFSET: usize = 0x14;
    /// Standard receive mailbox (SM0) offset.
    pub const MBX_RX_OFFSET: usize = 0x18;
    /// Standard receive mailbox size.
    pub const MBX_RX_SIZE: usize = 0x19;
    /// Standard send mailbox (SM1) offset.
    pub const MBX_TX_OFFSET: usize = 0x1A;
    /// Standard send mailbox size.
    pub const MBX_TX_SIZE: usize = 0x1B;
    /// Mailbox protocols.
    pub const MBX_PROTOCOLS: usize = 0x1C;
    /// EEPROM size.
    pub const SIZE: usize = 0x3E;
    /// Version.
    pub const VERSION: usize = 0x3F;
    /// First category.
    pub const CATEGORIES: usize = 0x40;
}

/// CRC-8 of the configuration area: polynomial x⁸+x²+x+1 (0x07), initial value
/// 0xFF, MSB first, no reflection, no final XOR.
pub const fn crc8(data: &[u8]) -> u8 {
    let mut crc: u8 = 0xFF;
    let mut i = 0;
    while i < data.len() {
        crc ^= data[i];
        let mut b = 0;
        while b < 8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ 0x07
            } else {
                crc << 1
            };
            b += 1;
        }
        i += 1;
    }
    crc
}

/// Which ESC the device is built with (selects the PDI configuration words).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EscFlavour {
    /// Microchip LAN9252 (host SPI), 4 KiB process RAM.
    Lan9252,
    /// Beckhoff ET1100 with SPI PDI, 8 KiB process RAM.
    Et1100,
}

impl EscFlavour {
    /// SII word 0: PDI control (0x0140) and ESC configuration (0x0141).
    pub const fn pdi_control(self) -> u16 {
        match self {
            EscFlavour::Lan9252 => 0x0C80,
            EscFlavour::Et1100 => 0x0C05,
        }
    }
    /// SII word 1: PDI configuration (0x0150) and SYNC/latch configuration (0x0151,
    /// [`sync_latch_config`] of `sync0`, the same for both flavours).
    pub const fn pdi_config(self, sync0: SyncDrive) -> u16 {
        let pdi: u8 = match self {
            EscFlavour::Lan9252 => 0x00,
            EscFlavour::Et1100 => 0x03,
        };
        u16::from_le_bytes([pdi, sync_latch_config(sync0)])
    }
    /// SII word 3: extended PDI configuration (0x0152:0x0153); unused for both.
    pub const fn pdi_config2(self) -> u16 {
        0
    }
    /// One past the last process-RAM address.
    pub const fn ram_end(self) -> u32 {
        match self {
            EscFlavour::Lan9252 => 0x2000,
            EscFlavour::Et1100 => 0x3000,
        }
    }
}

/// How the ESC drives a SYNC output pin: bits 1:0 (SYNC0) or 5:4 (SYNC1) of the
/// SYNC/latch PDI configuration register 0x0151.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SyncDrive {
    /// Push-pull, idle high, pulse low (code 0b00).
    PushPullActiveLow,
    /// Open drain, pulse low (code 0b01).
    OpenDrainActiveLow,
    /// Push-pull, idle low, pulse high (code 0b10).
    PushPullActiveHigh,
    /// Open source, pulse high (code 0b11).
    OpenSourceActiveHigh,
}

impl SyncDrive {
    /// The two-bit code of the register field.
    pub const fn code(self) -> u8 {
        match self {
            SyncDrive::PushPullActiveLow => 0b00,
            SyncDrive::OpenDrainActiveLow => 0b01,
            SyncDrive::PushPullActiveHigh => 0b10,
            SyncDrive::OpenSourceActiveHigh => 0b11,
        }
    }
    /// The drive a two-bit field code stands for (only the low two bits are used).
    pub const fn from_code(code: u8) -> Self {
        match code & 0b11 {
            0b00 => SyncDrive::PushPullActiveLow,
            0b01 => SyncDrive::OpenDrainActiveLow,
            0b10 => SyncDrive::PushPullActiveHigh,
            _ => SyncDrive::OpenSourceActiveHigh,
        }
    }
    /// The pulse is high (its leading edge rises).
    pub const fn active_high(self) -> bool {
        matches!(
            self,
            SyncDrive::PushPullActiveHigh | SyncDrive::OpenSourceActiveHigh
        )
    }
}

/// Bits of register 0x0151 (SYNC/latch PDI configuration) besides the drive fields.
pub mod sync_latch {
    /// Bit 2: the SYNC0/LATCH0 pin is the SYNC0 output (0: LATCH0 input).
    pub const SYNC0_OUTPUT: u8 = 1 << 2;
    /// Bit 3: SYNC0 is mapped to the AL event request register (0x0220 bit 2).
    pub const SYNC0_AL_EVENT: u8 = 1 << 3;
    /// Bit 6: the SYNC1/LATCH1 pin is the SYNC1 output (0: LATCH1 input).
    pub const SYNC1_OUTPUT: u8 = 1 << 6;
}

/// Value of 0x0151 in SII word 1 (high byte): SYNC0 output driven as `sync0`, mapped
/// to the AL event; SYNC1/LATCH1 as latch input.
pub const fn sync_latch_config(sync0: SyncDrive) -> u8 {
    sync0.code() | sync_latch::SYNC0_OUTPUT | sync_latch::SYNC0_AL_EVENT
}

/// What a SyncManager is for (SII category 41 type byte, ESI `Sm` text).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum SmType {
    /// Unused.
    Unused = 0,
    /// Mailbox out (master → slave), SM0.
    MailboxOut = 1,
    /// Mailbox in (slave → master), SM1.
    MailboxIn = 2,
    /// Process-data outputs (RxPDO), SM2.
    Outputs = 3,
    /// Process-data inputs (TxPDO), SM3.
    Inputs = 4,
}

impl SmType {
    /// From the SII type byte.
    pub const fn from_u8(v: u8) -> Option<Self> {
        match v {
            0 => Some(SmType::Unused),
            1 => Some(SmType::MailboxOut),
            2 => Some(SmType::MailboxIn),
            3 => Some(SmType::Outputs),
            4 => Some(SmType::Inputs),
            _ => None,
        }
    }
    /// ESI `Sm` element text.
    pub const fn esi(self) -> &'static str {
        match self {
            SmType::Unused => "",
            SmType::MailboxOut => "MBoxOut",
            SmType::MailboxIn => "MBoxIn",
            SmType::Outputs => "Outputs",
            SmType::Inputs => "Inputs",
        }
    }
}

/// One SyncManager of the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SyncManager {
    /// Purpose.
    pub kind: SmType,
    /// Physical start address.
    pub start: u16,
    /// Default length in bytes (mailbox size; 0 for process data whose length
    /// follows from the mapping).
    pub default_size: u16,
    /// Smallest length accepted (ESI `MinSize`; 0 = not stated).
    pub min_size: u16,
    /// Largest length accepted (ESI `MaxSize`; 0 = not stated).
    pub max_size: u16,
    /// Control byte (0x0804 + 8n).
    pub control: u8,
    /// Enabled by default.
    pub enable: bool,
}

/// FMMU usage (SII category 40, ESI `Fmmu`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum FmmuUsage {
    /// Unused.
    Unused = 0,
    /// Process-data outputs.
    Outputs = 1,
    /// Process-data inputs.
    Inputs = 2,
    /// Mailbox state (SM1 status bit polled by the master).
    MailboxState = 3,
}

impl FmmuUsage {
    /// From the SII byte (0xFF also means unused).
    pub const fn from_u8(v: u8) -> Option<Self> {
        match v {
            0 | 0xFF => Some(FmmuUsage::Unused),
            1 => Some(FmmuUsage::Outputs),
            2 => Some(FmmuUsage::Inputs),
            3 => Some(FmmuUsage::MailboxState),
            _ => None,
        }
    }
    /// ESI `Fmmu` text.
    pub const fn esi(self) -> &'static str {
        match self {
            FmmuUsage::Unused => "",
            FmmuUsage::Outputs => "Outputs",
            FmmuUsage::Inputs => "Inputs",
            FmmuUsage::MailboxState => "MBoxState",
        }
    }
}

/// CoE features (SII general byte 5, ESI `Mailbox/CoE` attributes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CoeDetails {
    /// SDO information service.
    pub sdo_info: bool,
    /// PDO assignment (0x1C12/0x1C13) writable.
    pub pdo_assign: bool,
    /// PDO mapping (0x16xx/0x1Axx) writable.
    pub pdo_config: bool,
    /// Master uploads the PDO configuration at start-up.
    pub pdo_upload: bool,
    /// SDO complete access.
    pub complete_access: bool,
}

impl CoeDetails {
    /// The general-category byte: b0 SDO, b1 SDO info, b2 PDO assign, b3 PDO config,
    /// b4 upload at start-up, b5 complete access.
    pub const fn bits(&self) -> u8 {
        1 | (self.sdo_info as u8) << 1
            | (self.pdo_assign as u8) << 2
            | (self.pdo_config as u8) << 3
            | (self.pdo_upload as u8) << 4
            | (self.complete_access as u8) << 5
    }
}

/// One DC operation mode (SII category 60 record, ESI `Dc/OpMode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DcOpMode {
    /// Short name ("DC", "SM").
    pub name: &'static str,
    /// Description ("DC-Synchron").
    pub description: &'static str,
    /// Value for 0x0980:0x0981 (0x0300 = SYNC-out unit + SYNC0; 0 = no DC).
    pub assign_activate: u16,
    /// Fixed SYNC0 cycle time in ns (0 = the master's cycle × factor).
    pub cycle_time_sync0: u32,
    /// SYNC0 cycle factor.
    pub sync0_factor: i16,
    /// SYNC0 shift time, ns.
    pub shift_time_sync0: u32,
    /// SYNC1 cycle factor.
    pub sync1_factor: i16,
    /// SYNC1 shift time, ns.
    pub shift_time_sync1: u32,
}

/// Everything the SII image and the ESI file say about the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeviceDescription {
    /// ETG vendor ID.
    pub vendor_id: u32,
    /// Vendor name (ESI).
    pub vendor_name: &'static str,
    /// Product code (0x1018:02).
    pub product_code: u32,
    /// Revision (0x1018:03).
    pub revision: u32,
    /// Serial number (0x1018:04; 0 in the generic image).
    pub serial: u32,
    /// Type name (ESI `Type` text), e.g. "ECS-HS"; also the SII general category's
    /// order string, so the two cannot disagree.
    pub type_name: &'static str,
    /// Device name (SII name string, ESI `Name`).
    pub name: &'static str,
    /// Group type (SII group string, ESI `GroupType`), e.g. "Drives".
    pub group_type: &'static str,
    /// Group display name (ESI `Groups/Group/Name`).
    pub group_name: &'static str,
    /// Hardware version (0x1009; SII string).
    pub hardware_version: &'static str,
    /// Software version (0x100A; SII string).
    pub software_version: &'static str,
    /// ESC the device is built with.
    pub esc: EscFlavour,
    /// SYNC pulse length in 10 ns units (SII word 2 → 0x0982).
    pub sync_pulse_length: u16,
    /// How the ESC drives the SYNC0 pin (SII word 1 → 0x0151, [`sync_latch_config`]):
    /// the board's SYNC0 input waits for the edge this names.
    pub sync0_drive: SyncDrive,
    /// Configured station alias (SII word 4 → 0x0012).
    pub station_alias: u16,
    /// Mailbox protocols (SII word 0x1C); this stack: [`MBOX_COE`].
    pub mailbox_protocols: u16,
    /// Mailbox supports the data-link layer (counter, repeat).
    pub mailbox_data_link_layer: bool,
    /// CoE features.
    pub coe: CoeDetails,
    /// FMMUs in order.
    pub fmmus: &'static [FmmuUsage],
    /// SyncManagers in order (SM0 mailbox out, SM1 mailbox in, SM2 outputs, SM3 inputs).
    pub sync_managers: &'static [SyncManager],
    /// DC op modes (empty: no DC category).
    pub dc_op_modes: &'static [DcOpMode],
    /// EEPROM size in bytes (a multiple of 128).
    pub eeprom_bytes: u16,
    /// Physical ports, 4 bits each (port 0 = bits 3:0): 1 MII, 3 EBUS.
    pub physical_ports: u16,
    /// CoE profile number (low word of 0x1000), e.g. 402.
    pub profile_no: u16,
    /// E-bus current in mA (0: not E-bus powered).
    pub ebus_current_ma: i16,
    /// Bootstrap mailbox (SII words 0x14-0x17, ESI `Eeprom/BootStrap`); `None`: the
    /// device has no Bootstrap state (the words stay 0).
    pub bootstrap: Option<crate::sm::BootMailbox>,
}

/// The standard FMMU use: outputs, inputs, mailbox state.
pub const STANDARD_FMMUS: [FmmuUsage; 3] = [
    FmmuUsage::Outputs,
    FmmuUsage::Inputs,
    FmmuUsage::MailboxState,
];

/// The standard SyncManager layout of the project: SM0 mailbox out 0x1000/128 (0x26),
/// SM1 mailbox in 0x1080/128 (0x22), SM2 outputs 0x1100 (0x64, watchdog on),
/// SM3 inputs 0x1400 (0x20); process data up to 64 bytes each.
pub const STANDARD_SYNC_MANAGERS: [SyncManager; 4] = [
    SyncManager {
        kind: SmType::MailboxOut,
        start: 0x1000,
        default_size: 128,
        min_size: 34,
        max_size: 128,
        control: 0x26,
        enable: true,
    },
    SyncManager {
        kind: SmType::MailboxIn,
        start: 0x1080,
        default_size: 128,
        min_size: 34,
        max_size: 128,
        control: 0x22,
        enable: true,
    },
    SyncManager {
        kind: SmType::Outputs,
        start: 0x1100,
        default_size: 0,
        min_size: 0,
        max_size: 64,
        control: 0x64,
        enable: true,
    },
    SyncManager {
        kind: SmType::Inputs,
        start: 0x1400,
        default_size: 0,
        min_size: 0,
        max_size: 64,
        control: 0x20,
        enable: true,
    },
];

/// The standard op modes: SM-synchronous (no DC) and DC SYNC0 (AssignActivate 0x0300,
/// SYNC0 cycle = the master's cycle).
pub const STANDARD_DC_OP_MODES: [DcOpMode; 2] = [
    DcOpMode {
        name: "SM",
        description: "SM-Synchron",
        assign_activate: 0x0000,
        cycle_time_sync0: 0,
        sync0_factor: 0,
        shift_time_sync0: 0,
        sync1_factor: 0,
        shift_time_sync1: 0,
    },
    DcOpMode {
        name: "DC",
        description: "DC-Synchron",
        assign_activate: 0x0300,
        cycle_time_sync0: 0,
        sync0_factor: 1,
        shift_time_sync0: 0,
        sync1_factor: 0,
        shift_time_sync1: 0,
    },
];

/// The CoE features this stack implements: SDO information, PDO assignment and
/// configuration, complete access; no PDO upload.
pub const STANDARD_COE: CoeDetails = CoeDetails {
    sdo_info: true,
    pdo_assign: true,
    pdo_config: true,
    pdo_upload: false,
    complete_access: true,
};

impl DeviceDescription {
    /// The first SyncManager of `kind` and its number.
    pub fn sync_manager(&self, kind: SmType) -> Option<(u8, &SyncManager)> {
        self.sync_managers
            .iter()
            .enumerate()
            .find(|(_, s)| s.kind == kind)
            .map(|(i, s)| (i as u8, s))
    }

    /// Words 0-7 of the image (configuration area with its checksum), as bytes.
    pub fn config_area(&self) -> [u8; 16] {
        let mut b = [0u8; 16];
        let words = [
            self.esc.pdi_control(),
            self.esc.pdi_config(self.sync0_drive),
            self.sync_pulse_length,
            self.esc.pdi_config2(),
            self.station_alias,
            0,
            0,
        ];
        for (i, w) in words.iter().enumerate() {
            b[2 * i..2 * i + 2].copy_from_slice(&w.to_le_bytes());
        }
        b[14] = crc8(&b[..14]);
        b
    }

    /// Checks what the image and the ESI depend on: both mailbox SMs present and
    /// inside process RAM, every SM inside process RAM, protocol bits valid, EEPROM
    /// size a multiple of 128 bytes and at least 1 Kibit.
    pub fn validate(&self) -> Result<(), SiiError> {
        if self.sync_manager(SmType::MailboxOut).is_none()
            || self.sync_manager(SmType::MailboxIn).is_none()
        {
            return Err(SiiError::MissingMailbox);
        }
        if self.sync_managers.len() > 16 || self.fmmus.len() > 16 || self.dc_op_modes.len() > 8 {
            return Err(SiiError::InvalidDescription);
        }
        for sm in self.sync_managers {
            let end = sm.start as u32 + sm.default_size.max(sm.max_size) as u32;
            if sm.kind != SmType::Unused && (sm.start < 0x1000 || end > self.esc.ram_end()) {
                return Err(SiiError::InvalidDescription);
            }
        }
        if self.mailbox_protocols & !MBOX_VALID != 0 || self.mailbox_protocols & MBOX_COE == 0 {
            return Err(SiiError::InvalidDescription);
        }
        if self.eeprom_bytes < 128 || !self.eeprom_bytes.is_multiple_of(128) {
            return Err(SiiError::InvalidDescription);
        }
        Ok(())
    }
}

/// Why an image could not be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SiiError {
    /// The output buffer is too small.
    BufferTooSmall,
    /// The image does not fit in the declared EEPROM size.
    EepromTooSmall,
    /// More than 255 strings, or a string longer than 255 bytes.
    StringTable,
    /// SM0 / SM1 mailbox missing from the SyncManager list.
    MissingMailbox,
    /// Another inconsistency (see [`DeviceDescription::validate`]).
    InvalidDescription,
}
