//! Identity of the product: the values that 0x1000, 0x1008-0x100A and 0x1018 report
//! and that the SII image and the ESI file carry.
//!
//! Two variants share the firmware: the hybrid servo (encoder feedback, closed loop by
//! default) and the open-loop stepper. The variant is chosen by the board at start-up
//! (board strap or build option) and decides the product code, the device type, the
//! names and the default of 0x2024.

/// ETG vendor ID (placeholder until the vendor is registered with the ETG).
pub const VENDOR_ID: u32 = 0x0000_0E5C;
/// Revision number (0x1018:03, SII words 0x0C-0x0D).
pub const REVISION: u32 = 0x0001_0000;
/// ESI device group.
pub const GROUP: &str = "Drives";
/// Hardware version (0x1009).
pub const HARDWARE_VERSION: &str = "1.0";
/// Software version (0x100A): the crate version.
pub const SOFTWARE_VERSION: &str = env!("CARGO_PKG_VERSION");

use ecat_slave_stack::sii;

/// Longest device name of any variant (0x1008 is described with this maximum length).
pub const MAX_NAME_LEN: usize = 32;

/// The product variant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    /// "ECS-HS": hybrid servo with incremental encoder, closed loop by default.
    HybridServo,
    /// "ECS-OL": open-loop stepper, no feedback.
    OpenLoop,
}

impl Variant {
    /// Product code (0x1018:02).
    pub const fn product_code(self) -> u32 {
        match self {
            Self::HybridServo => 0x0000_5840,
            Self::OpenLoop => 0x0000_5841,
        }
    }
    /// Device type (0x1000): CiA 402 servo 0x00020192, stepper 0x00040192.
    pub const fn device_type(self) -> u32 {
        match self {
            Self::HybridServo => 0x0002_0192,
            Self::OpenLoop => 0x0004_0192,
        }
    }
    /// Device name (0x1008, SII/ESI name).
    pub const fn device_name(self) -> &'static str {
        match self {
            Self::HybridServo => "ECS-HS EtherCAT hybrid servo",
            Self::OpenLoop => "ECS-OL EtherCAT stepper",
        }
    }
    /// Short type name ("ECS-HS" / "ECS-OL").
    pub const fn type_name(self) -> &'static str {
        match self {
            Self::HybridServo => "ECS-HS",
            Self::OpenLoop => "ECS-OL",
        }
    }
    /// Default of 0x2024 (1 open loop, 2 closed loop).
    pub const fn default_loop_mode(self) -> u8 {
        match self {
            Self::HybridServo => 2,
            Self::OpenLoop => 1,
        }
    }
    /// Highest 0x2024 value the variant accepts (an open-loop drive has no encoder).
    pub const fn max_loop_mode(self) -> u8 {
        match self {
            Self::HybridServo => 2,
            Self::OpenLoop => 1,
        }
    }
    /// Highest peak current 0x2000 the variant accepts, mA (the hybrid servo's motor
    /// side is rated 8.0 A peak, the open-loop stepper 8.4 A).
    pub const fn max_peak_current_ma(self) -> u16 {
        match self {
            Self::HybridServo => 8000,
            Self::OpenLoop => 8400,
        }
    }
    /// True when the variant has encoder feedback.
    pub const fn has_encoder(self) -> bool {
        matches!(self, Self::HybridServo)
    }
}

/// Everything that identifies one drive (the serial number comes from the chip's
/// unique ID or the production data; 0 when unknown).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Identity {
    /// The variant.
    pub variant: Variant,
    /// Serial number (0x1018:04).
    pub serial: u32,
}

impl Identity {
    /// Identity of a drive of `variant` with serial number `serial`.
    pub const fn new(variant: Variant, serial: u32) -> Self {
        Identity { variant, serial }
    }
    /// Vendor ID (0x1018:01).
    pub const fn vendor_id(&self) -> u32 {
        VENDOR_ID
    }
    /// Product code (0x1018:02).
    pub const fn product_code(&self) -> u32 {
        self.variant.product_code()
    }
    /// Revision (0x1018:03).
    pub const fn revision(&self) -> u32 {
        REVISION
    }
    /// Device name (0x1008).
    pub const fn device_name(&self) -> &'static str {
        self.variant.device_name()
    }
}

/// The variant the board binary is built as (its product code in update images).
pub const BOARD_VARIANT: Variant = Variant::HybridServo;

/// Vendor name (ESI).
pub const VENDOR_NAME: &str = "ECS open drive firmware";
/// SII EEPROM size in bytes (16 Kibit part).
pub const EEPROM_BYTES: u16 = 2048;

/// The Bootstrap mailbox of firmware updates over FoE (`update`).
pub const BOOTSTRAP: Option<ecat_slave_stack::sm::BootMailbox> =
    Some(ecat_slave_stack::sm::BootMailbox::STANDARD);

/// The mailbox lengths the product accepts at Init → Pre-Op: SM0 32-256, SM1 40-256
/// bytes, the limits of the drives this product replaces (a master configured for them
/// stays within them). The stack's own default is every length its server can hold.
pub const MAILBOX_LIMITS: ecat_slave_stack::sm::MailboxLimits =
    ecat_slave_stack::sm::MailboxLimits {
        sm0_len: (32, 256),
        sm1_len: (40, 256),
    };

/// Index of the timing diagnostics object the slave runtime serves
/// (`ecat_slave_stack::sync::timing_diag_object`, listed in `dictionary`).
pub const TIMING_DIAG: u16 = 0x2200;

/// The slave runtime's configuration of the product (the board's and the
/// simulation's): the mailbox limits, the default PDO maps, the Bootstrap mailbox and
/// the timing diagnostics object.
pub fn slave_config() -> ecat_slave_stack::slave::SlaveConfig {
    ecat_slave_stack::slave::SlaveConfig {
        mailbox_limits: MAILBOX_LIMITS,
        pdo_defaults: crate::pdo_defaults::PDO_DEFAULTS,
        bootstrap: BOOTSTRAP,
        timing_diag_index: Some(TIMING_DIAG),
        ..ecat_slave_stack::slave::SlaveConfig::default()
    }
}

/// The device description for the SII image and the ESI file of `variant` built with
/// `esc` (standard SyncManager/FMMU layout, DC SYNC0 and SM-synchronous op modes, two
/// MII ports, CiA 402 profile, FoE with the Bootstrap mailbox). `serial` is 0 in the
/// generic image.
pub const fn device_description(
    variant: Variant,
    esc: sii::EscFlavour,
    serial: u32,
) -> sii::DeviceDescription {
    sii::DeviceDescription {
        vendor_id: VENDOR_ID,
        vendor_name: VENDOR_NAME,
        product_code: variant.product_code(),
        revision: REVISION,
        serial,
        type_name: variant.type_name(),
        name: variant.device_name(),
        group_type: GROUP,
        group_name: GROUP,
        hardware_version: HARDWARE_VERSION,
        software_version: SOFTWARE_VERSION,
        esc,
        // 10 µs SYNC pulse (1000 × 10 ns), the usual ESC default.
        sync_pulse_length: 1000,
        sync0_drive: SYNC0_DRIVE,
        station_alias: 0,
        mailbox_protocols: sii::MBOX_COE | sii::MBOX_FOE,
        mailbox_data_link_layer: true,
        coe: sii::STANDARD_COE,
        fmmus: &sii::STANDARD_FMMUS,
        sync_managers: &sii::STANDARD_SYNC_MANAGERS,
        dc_op_modes: &sii::STANDARD_DC_OP_MODES,
        eeprom_bytes: EEPROM_BYTES,
        physical_ports: 0x0011,
        profile_no: 402,
        ebus_current_ma: 0,
        bootstrap: BOOTSTRAP,
    }
}

/// The pin edge that starts a pulse.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PulseEdge {
    /// Low → high.
    Rising,
    /// High → low.
    Falling,
}

/// The edge of the SYNC0 pin at which a SYNC0 event starts, decoded from the value
/// of register 0x0151 (`sync_latch_config`, the high byte of SII word 1) that the ESC
/// loads from the SII: the leading edge of the pulse its SYNC0 drive field describes.
/// `None` when that value does not make the pin a SYNC0 output mapped to the AL
/// event (the board could not use it).
pub const fn sync0_active_edge(sync_latch_config: u8) -> Option<PulseEdge> {
    use sii::sync_latch::{SYNC0_AL_EVENT, SYNC0_OUTPUT};
    if sync_latch_config & (SYNC0_OUTPUT | SYNC0_AL_EVENT) != SYNC0_OUTPUT | SYNC0_AL_EVENT {
        return None;
    }
    Some(
        if sii::SyncDrive::from_code(sync_latch_config).active_high() {
            PulseEdge::Rising
        } else {
            PulseEdge::Falling
        },
    )
}

/// SYNC0 pin drive of this product (both ESC flavours): the one definition of the
/// SYNC0 polarity, written to the SII's 0x0151 value ([`device_description`]) and
/// waited for by the board ([`SYNC0_ACTIVE_EDGE`]).
pub const SYNC0_DRIVE: sii::SyncDrive = sii::SyncDrive::PushPullActiveHigh;

/// Value of 0x0151 in SII word 1 (high byte) of this product.
pub const SYNC_LATCH_CONFIG: u8 = sii::sync_latch_config(SYNC0_DRIVE);

/// The edge the board's SYNC0 input waits for: derived from the SII image's 0x0151
/// value, which [`SYNC0_DRIVE`] defines (the same for both ESC flavours; checked
/// at compile time and in `tests/portable_board_glue.rs`).
pub const SYNC0_ACTIVE_EDGE: PulseEdge = {
    let lan = sync0_active_edge((sii::EscFlavour::Lan9252.pdi_config(SYNC0_DRIVE) >> 8) as u8);
    let et = sync0_active_edge((sii::EscFlavour::Et1100.pdi_config(SYNC0_DRIVE) >> 8) as u8);
    match (lan, et) {
        (Some(PulseEdge::Rising), Some(PulseEdge::Rising)) => PulseEdge::Rising,
        (Some(PulseEdge::Falling), Some(PulseEdge::Falling)) => PulseEdge::Falling,
        _ => panic!("the SII does not configure SYNC0 as an output the board can use"),
    }
};

/// A serial number derived from the 96-bit unique device ID of the MCU (CRC-32 of
/// the 12 bytes), so every board reports a different 0x1018:04 without production data.
pub fn serial_from_unique_id(uid: &[u8; 12]) -> u32 {
    crate::storage::crc32(uid)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_product_refuses_mailboxes_shorter_than_its_limits() {
        use ecat_slave_stack::al_status::AlStatusCode;
        use ecat_slave_stack::sm::{
            validate_mailbox, Activate, Control, PdiControl, RamWindow, SmRegs, Status,
        };
        let sm = |start: u16, len: u16, control: u8| SmRegs {
            start,
            len,
            control: Control(control),
            status: Status(0),
            activate: Activate(1),
            pdi_control: PdiControl(0),
        };
        let ram = RamWindow::from_kib(4);
        let cfg = slave_config();
        assert_eq!(cfg.mailbox_limits, MAILBOX_LIMITS);
        let check = |l0: u16, l1: u16| {
            validate_mailbox(
                &sm(0x1000, l0, 0x26),
                &sm(0x1080, l1, 0x22),
                &[],
                &cfg.mailbox_limits,
                ram,
            )
        };
        assert_eq!(check(32, 40), Ok(()));
        assert_eq!(check(30, 128), Err(AlStatusCode::InvalidMailboxConfig));
        assert_eq!(check(128, 32), Err(AlStatusCode::InvalidMailboxConfig));
        // The stack alone takes them (its default is what its server can hold).
        let any = ecat_slave_stack::sm::MailboxLimits::default();
        let stack_only =
            validate_mailbox(&sm(0x1000, 30, 0x26), &sm(0x1080, 32, 0x22), &[], &any, ram);
        assert_eq!(stack_only, Ok(()));
    }

    #[test]
    fn variants_differ_and_names_fit() {
        assert_ne!(
            Variant::HybridServo.product_code(),
            Variant::OpenLoop.product_code()
        );
        assert_eq!(Variant::HybridServo.device_type() & 0xFFFF, 0x0192);
        assert_eq!(Variant::OpenLoop.device_type(), 0x0004_0192);
        for v in [Variant::HybridServo, Variant::OpenLoop] {
            assert!(v.device_name().len() <= MAX_NAME_LEN);
            assert!(v.device_name().starts_with(v.type_name()));
            assert!(v.default_loop_mode() <= v.max_loop_mode());
        }
        assert!(!SOFTWARE_VERSION.is_empty());
    }

    #[test]
    fn device_descriptions_are_valid_sii_sources() {
        for v in [Variant::HybridServo, Variant::OpenLoop] {
            for esc in [sii::EscFlavour::Lan9252, sii::EscFlavour::Et1100] {
                let d = device_description(v, esc, 0);
                assert_eq!(d.validate(), Ok(()));
                assert_eq!(
                    (d.vendor_id, d.product_code, d.revision),
                    (VENDOR_ID, v.product_code(), REVISION)
                );
                assert_eq!(d.profile_no as u32, v.device_type() & 0xFFFF);
                let mut img = [0u8; EEPROM_BYTES as usize];
                let n = sii::build(&d, &mut img).unwrap();
                assert!(n > 0x80 && n <= img.len());
            }
        }
    }

    #[test]
    fn serial_from_uid_is_stable_and_distinct() {
        let a = serial_from_unique_id(&[1; 12]);
        let b = serial_from_unique_id(&[2; 12]);
        assert_ne!(a, b);
        assert_eq!(a, serial_from_unique_id(&[1; 12]));
    }
}
