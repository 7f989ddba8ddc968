//! The ESC register map as the slave application sees it (ETG.1000.4 / ESC datasheets).
//! One place for every address the stack touches.

/// ESC type (u8).
pub const ESC_TYPE: u16 = 0x0000;
/// ESC revision (u8).
pub const ESC_REVISION: u16 = 0x0001;
/// ESC build (u16).
pub const ESC_BUILD: u16 = 0x0002;
/// Number of FMMUs supported (u8).
pub const FMMU_COUNT: u16 = 0x0004;
/// Number of SyncManagers supported (u8).
pub const SM_COUNT: u16 = 0x0005;
/// Process RAM size in KiB (u8).
pub const RAM_SIZE: u16 = 0x0006;
/// Port descriptor (u8, 2 bits per port).
pub const PORT_DESCRIPTOR: u16 = 0x0007;
/// ESC features supported (u16).
pub const FEATURES: u16 = 0x0008;
/// Configured station address (u16, written by the master).
pub const STATION_ADDRESS: u16 = 0x0010;
/// Configured station alias (u16, loaded from SII word 4; the application may overwrite it).
pub const STATION_ALIAS: u16 = 0x0012;
/// DL control (u32).
pub const DL_CONTROL: u16 = 0x0100;
/// DL status (u16): bit 0 PDI operational, bit 1 PDI watchdog OK, bits 4-7 link per port.
pub const DL_STATUS: u16 = 0x0110;
/// AL control (u16, master → slave): requested state, error acknowledge (bit 4), device ID request (bit 5).
pub const AL_CONTROL: u16 = 0x0120;
/// AL status (u16, slave → master): state, error indication (bit 4), device ID loaded (bit 5).
pub const AL_STATUS: u16 = 0x0130;
/// AL status code (u16).
pub const AL_STATUS_CODE: u16 = 0x0134;
/// RUN LED override (u8).
pub const RUN_LED_OVERRIDE: u16 = 0x0138;
/// ERR LED override (u8).
pub const ERR_LED_OVERRIDE: u16 = 0x0139;
/// PDI control (u8): PDI type.
pub const PDI_CONTROL: u16 = 0x0140;
/// ESC configuration (u8): bit 0 device emulation.
pub const ESC_CONFIG: u16 = 0x0141;
/// PDI configuration (u8 × 4, 0x0150-0x0153).
pub const PDI_CONFIG: u16 = 0x0150;
/// ECAT event mask (u16).
pub const ECAT_EVENT_MASK: u16 = 0x0200;
/// AL event mask (u32): which AL events raise the PDI IRQ.
pub const AL_EVENT_MASK: u16 = 0x0204;
/// ECAT event request (u16).
pub const ECAT_EVENT_REQUEST: u16 = 0x0210;
/// AL event request (u32).
pub const AL_EVENT_REQUEST: u16 = 0x0220;
/// Watchdog divider (u16): 40 ns ticks minus 2 per watchdog increment.
pub const WATCHDOG_DIVIDER: u16 = 0x0400;
/// PDI watchdog time (u16).
pub const WATCHDOG_TIME_PDI: u16 = 0x0410;
/// Process-data (SM) watchdog time (u16), 0 = disabled.
pub const WATCHDOG_TIME_PD: u16 = 0x0420;
/// Process-data watchdog status (u16): bit 0 = 1 OK, 0 expired.
pub const WATCHDOG_STATUS_PD: u16 = 0x0440;
/// Process-data watchdog expiry counter (u8).
pub const WATCHDOG_COUNTER_PD: u16 = 0x0442;
/// PDI watchdog expiry counter (u8).
pub const WATCHDOG_COUNTER_PDI: u16 = 0x0443;
/// SII EEPROM configuration (u8): bit 0 assigned to PDI.
pub const SII_CONFIG: u16 = 0x0500;
/// SII EEPROM PDI access state (u8).
pub const SII_PDI_ACCESS: u16 = 0x0501;
/// SII EEPROM control/status (u16).
pub const SII_CONTROL: u16 = 0x0502;
/// SII EEPROM word address (u32).
pub const SII_ADDRESS: u16 = 0x0504;
/// SII EEPROM data (4 or 8 bytes read, 2 bytes written).
pub const SII_DATA: u16 = 0x0508;
/// First FMMU; FMMU n is at `FMMU_BASE + 16·n`.
pub const FMMU_BASE: u16 = 0x0600;
/// Size of one FMMU register block.
pub const FMMU_SIZE: u16 = 16;
/// First SyncManager; SM n is at `SM_BASE + 8·n`.
pub const SM_BASE: u16 = 0x0800;
/// Size of one SyncManager register block.
pub const SM_SIZE: u16 = 8;
/// Offsets inside a SyncManager register block.
pub mod sm {
    /// Physical start address (u16).
    pub const START: u16 = 0;
    /// Length in bytes (u16).
    pub const LENGTH: u16 = 2;
    /// Control byte (mode, direction, interrupts, watchdog trigger).
    pub const CONTROL: u16 = 4;
    /// Status byte (mailbox full, buffer state).
    pub const STATUS: u16 = 5;
    /// Activate byte (enable, repeat request).
    pub const ACTIVATE: u16 = 6;
    /// PDI control byte (deactivate, repeat acknowledge).
    pub const PDI_CONTROL: u16 = 7;
}
/// Address of SyncManager `n`'s register block.
pub const fn sm_register(n: u8) -> u16 {
    SM_BASE + SM_SIZE * n as u16
}
/// Address of FMMU `n`'s register block.
pub const fn fmmu_register(n: u8) -> u16 {
    FMMU_BASE + FMMU_SIZE * n as u16
}
/// DC receive time port 0 (u32; a write latches all ports).
pub const DC_RECEIVE_TIME_PORT0: u16 = 0x0900;
/// DC local copy of the system time (u64, ns).
pub const DC_SYSTEM_TIME: u16 = 0x0910;
/// DC receive time of the processing unit (u64).
pub const DC_RECEIVE_TIME_PU: u16 = 0x0918;
/// DC system time offset (u64).
pub const DC_SYSTEM_TIME_OFFSET: u16 = 0x0920;
/// DC system time delay (u32).
pub const DC_SYSTEM_TIME_DELAY: u16 = 0x0928;
/// DC system time difference (u32, bit 31 sign).
pub const DC_SYSTEM_TIME_DIFF: u16 = 0x092C;
/// DC speed counter start (u16).
pub const DC_SPEED_COUNTER_START: u16 = 0x0930;
/// DC time difference filter depth (u16 at 0x0934).
pub const DC_FILTER_DEPTH: u16 = 0x0934;
/// DC cyclic unit control (u8).
pub const DC_CYCLIC_UNIT_CONTROL: u16 = 0x0980;
/// DC activation (u8): bit 0 SYNC-out unit active, bit 1 SYNC0, bit 2 SYNC1.
pub const DC_ACTIVATION: u16 = 0x0981;
/// SYNC pulse length (u16, 10 ns units).
pub const DC_PULSE_LENGTH: u16 = 0x0982;
/// DC activation status (u8).
pub const DC_ACTIVATION_STATUS: u16 = 0x0984;
/// SYNC0 status (u8; reading clears AL event bit 2).
pub const DC_SYNC0_STATUS: u16 = 0x098E;
/// SYNC1 status (u8).
pub const DC_SYNC1_STATUS: u16 = 0x098F;
/// Start time of cyclic operation (u64); reads back the next SYNC0 time.
pub const DC_START_TIME: u16 = 0x0990;
/// Next SYNC1 time (u64).
pub const DC_NEXT_SYNC1: u16 = 0x0998;
/// SYNC0 cycle time (u32, ns).
pub const DC_SYNC0_CYCLE: u16 = 0x09A0;
/// SYNC1 cycle time (u32, ns).
pub const DC_SYNC1_CYCLE: u16 = 0x09A4;
/// Latch 0 control (u8).
pub const DC_LATCH0_CONTROL: u16 = 0x09A8;
/// Latch 0 status (u8).
pub const DC_LATCH0_STATUS: u16 = 0x09AE;
/// Latch 0 positive-edge time (u64).
pub const DC_LATCH0_POS: u16 = 0x09B0;
/// First byte of process RAM.
pub const PROCESS_RAM: u16 = 0x1000;

/// AL event bits (0x0204 mask / 0x0220 request).
pub mod al_event {
    /// AL control written.
    pub const AL_CONTROL: u32 = 1 << 0;
    /// DC latch event.
    pub const DC_LATCH: u32 = 1 << 1;
    /// DC SYNC0.
    pub const SYNC0: u32 = 1 << 2;
    /// DC SYNC1.
    pub const SYNC1: u32 = 1 << 3;
    /// An SM activate register changed.
    pub const SM_CHANGE: u32 = 1 << 4;
    /// EEPROM emulation command pending.
    pub const EEPROM: u32 = 1 << 5;
    /// Process-data watchdog expired.
    pub const WATCHDOG: u32 = 1 << 6;
    /// SyncManager `n` event.
    pub const fn sm(n: u8) -> u32 {
        1 << (8 + n as u32)
    }
}
