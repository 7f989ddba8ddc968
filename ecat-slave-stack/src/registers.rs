//! The ESC register map as the slave application sees it (ETG.1000.4 / ESC datasheets).
//! One place for every address the stack touches, and typed views of the registers
//! with bit fields the stack decodes ([`AlControl`], [`AlStatus`], [`AlEvent`],
//! [`DcActivation`]).

use crate::esm::EsmState;
use core::marker::PhantomData;

/// An ESC register: its address, with the type of its value (its width) as the type
/// parameter. Integer registers are read and written with [`crate::EscAccess::get`] /
/// [`crate::EscAccess::set`]; `.addr()` gives the address for byte-wise access.
#[derive(Debug, PartialEq, Eq)]
pub struct Register<T> {
    addr: u16,
    value: PhantomData<T>,
}

impl<T> Clone for Register<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for Register<T> {}

impl<T> Register<T> {
    /// The register at ESC address `addr`.
    pub const fn new(addr: u16) -> Self {
        Register {
            addr,
            value: PhantomData,
        }
    }
    /// Its ESC address.
    pub const fn addr(self) -> u16 {
        self.addr
    }
    /// Its width, bytes.
    pub const fn len(self) -> usize {
        core::mem::size_of::<T>()
    }
    /// False: no register is zero bytes wide.
    pub const fn is_empty(self) -> bool {
        self.len() == 0
    }
}

/// ESC type.
pub const ESC_TYPE: Register<u8> = Register::new(0x0000);
/// ESC revision.
pub const ESC_REVISION: Register<u8> = Register::new(0x0001);
/// ESC build.
pub const ESC_BUILD: Register<u16> = Register::new(0x0002);
/// Number of FMMUs supported.
pub const FMMU_COUNT: Register<u8> = Register::new(0x0004);
/// Number of SyncManagers supported.
pub const SM_COUNT: Register<u8> = Register::new(0x0005);
/// Process RAM size in KiB.
pub const RAM_SIZE: Register<u8> = Register::new(0x0006);
/// Port descriptor (2 bits per port).
pub const PORT_DESCRIPTOR: Register<u8> = Register::new(0x0007);
/// ESC features supported.
pub const FEATURES: Register<u16> = Register::new(0x0008);
/// Configured station address (written by the master).
pub const STATION_ADDRESS: Register<u16> = Register::new(0x0010);
/// Configured station alias (loaded from SII word 4; the application may overwrite it).
pub const STATION_ALIAS: Register<u16> = Register::new(0x0012);
/// DL control.
pub const DL_CONTROL: Register<u32> = Register::new(0x0100);
/// DL status: bit 0 PDI operational, bit 1 PDI watchdog OK, bits 4-7 link per port.
pub const DL_STATUS: Register<u16> = Register::new(0x0110);
/// AL control (master → slave): requested state, error acknowledge (bit 4), device ID request (bit 5).
pub const AL_CONTROL: Register<u16> = Register::new(0x0120);
/// AL status (slave → master): state, error indication (bit 4), device ID loaded (bit 5).
pub const AL_STATUS: Register<u16> = Register::new(0x0130);
/// AL status code.
pub const AL_STATUS_CODE: Register<u16> = Register::new(0x0134);
/// RUN LED override.
pub const RUN_LED_OVERRIDE: Register<u8> = Register::new(0x0138);
/// ERR LED override.
pub const ERR_LED_OVERRIDE: Register<u8> = Register::new(0x0139);
/// PDI control: PDI type.
pub const PDI_CONTROL: Register<u8> = Register::new(0x0140);
/// ESC configuration: bit 0 device emulation.
pub const ESC_CONFIG: Register<u8> = Register::new(0x0141);
/// PDI configuration (0x0150-0x0153).
pub const PDI_CONFIG: Register<[u8; 4]> = Register::new(0x0150);
/// ECAT event mask.
pub const ECAT_EVENT_MASK: Register<u16> = Register::new(0x0200);
/// AL event mask: which AL events raise the PDI IRQ.
pub const AL_EVENT_MASK: Register<u32> = Register::new(0x0204);
/// ECAT event request.
pub const ECAT_EVENT_REQUEST: Register<u16> = Register::new(0x0210);
/// AL event request.
pub const AL_EVENT_REQUEST: Register<u32> = Register::new(0x0220);
/// Watchdog divider: 40 ns ticks minus 2 per watchdog increment.
pub const WATCHDOG_DIVIDER: Register<u16> = Register::new(0x0400);
/// PDI watchdog time.
pub const WATCHDOG_TIME_PDI: Register<u16> = Register::new(0x0410);
/// Process-data (SM) watchdog time, 0 = disabled.
pub const WATCHDOG_TIME_PD: Register<u16> = Register::new(0x0420);
/// Process-data watchdog status: bit 0 = 1 OK, 0 expired.
pub const WATCHDOG_STATUS_PD: Register<u16> = Register::new(0x0440);
/// Process-data watchdog expiry counter.
pub const WATCHDOG_COUNTER_PD: Register<u8> = Register::new(0x0442);
/// PDI watchdog expiry counter.
pub const WATCHDOG_COUNTER_PDI: Register<u8> = Register::new(0x0443);
/// SII EEPROM configuration: bit 0 assigned to PDI.
pub const SII_CONFIG: Register<u8> = Register::new(0x0500);
/// SII EEPROM PDI access state.
pub const SII_PDI_ACCESS: Register<u8> = Register::new(0x0501);
/// SII EEPROM control/status.
pub const SII_CONTROL: Register<u16> = Register::new(0x0502);
/// SII EEPROM word address.
pub const SII_ADDRESS: Register<u32> = Register::new(0x0504);
/// SII EEPROM data (4 or 8 bytes read, 2 bytes written).
pub const SII_DATA: Register<[u8; 8]> = Register::new(0x0508);
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
/// DC receive time port 0 (a write latches all ports).
pub const DC_RECEIVE_TIME_PORT0: Register<u32> = Register::new(0x0900);
/// DC local copy of the system time (ns).
pub const DC_SYSTEM_TIME: Register<u64> = Register::new(0x0910);
/// DC receive time of the processing unit.
pub const DC_RECEIVE_TIME_PU: Register<u64> = Register::new(0x0918);
/// DC system time offset.
pub const DC_SYSTEM_TIME_OFFSET: Register<u64> = Register::new(0x0920);
/// DC system time delay.
pub const DC_SYSTEM_TIME_DELAY: Register<u32> = Register::new(0x0928);
/// DC system time difference (bit 31 sign).
pub const DC_SYSTEM_TIME_DIFF: Register<u32> = Register::new(0x092C);
/// DC speed counter start.
pub const DC_SPEED_COUNTER_START: Register<u16> = Register::new(0x0930);
/// DC time difference filter depth.
pub const DC_FILTER_DEPTH: Register<u16> = Register::new(0x0934);
/// DC cyclic unit control.
pub const DC_CYCLIC_UNIT_CONTROL: Register<u8> = Register::new(0x0980);
/// DC activation: bit 0 SYNC-out unit active, bit 1 SYNC0, bit 2 SYNC1.
pub const DC_ACTIVATION: Register<u8> = Register::new(0x0981);
/// SYNC pulse length (10 ns units).
pub const DC_PULSE_LENGTH: Register<u16> = Register::new(0x0982);
/// DC activation status.
pub const DC_ACTIVATION_STATUS: Register<u8> = Register::new(0x0984);
/// SYNC0 status (reading clears AL event bit 2).
pub const DC_SYNC0_STATUS: Register<u8> = Register::new(0x098E);
/// SYNC1 status.
pub const DC_SYNC1_STATUS: Register<u8> = Register::new(0x098F);
/// Start time of cyclic operation; reads back the next SYNC0 time.
pub const DC_START_TIME: Register<u64> = Register::new(0x0990);
/// Next SYNC1 time.
pub const DC_NEXT_SYNC1: Register<u64> = Register::new(0x0998);
/// SYNC0 cycle time (ns).
pub const DC_SYNC0_CYCLE: Register<u32> = Register::new(0x09A0);
/// SYNC1 cycle time (ns).
pub const DC_SYNC1_CYCLE: Register<u32> = Register::new(0x09A4);
/// Latch 0 control.
pub const DC_LATCH0_CONTROL: Register<u8> = Register::new(0x09A8);
/// Latch 0 status.
pub const DC_LATCH0_STATUS: Register<u8> = Register::new(0x09AE);
/// Latch 0 positive-edge time.
pub const DC_LATCH0_POS: Register<u64> = Register::new(0x09B0);
/// First byte of process RAM.
pub const PROCESS_RAM: u16 = 0x1000;

/// AL event bits (0x0204 mask / 0x0220 request) as raw masks, for register images (the
/// stack itself uses [`AlEvent`]).
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

/// AL control (0x0120, master → slave).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AlControl {
    /// Requested state, bits 3:0, raw: the master may write a code that is no state
    /// ([`AlControl::requested`]).
    pub state: u8,
    /// Error indication acknowledge, bit 4.
    pub ack: bool,
    /// Device identification request, bit 5.
    pub id_request: bool,
}

impl AlControl {
    const STATE: u16 = 0x000F;
    const ACK: u16 = 1 << 4;
    const ID_REQUEST: u16 = 1 << 5;

    /// Decodes the register (bits 15:6 are reserved and ignored).
    pub const fn from_raw(v: u16) -> Self {
        AlControl {
            state: (v & Self::STATE) as u8,
            ack: v & Self::ACK != 0,
            id_request: v & Self::ID_REQUEST != 0,
        }
    }
    /// The register value.
    pub const fn to_raw(self) -> u16 {
        (self.state as u16 & Self::STATE)
            | if self.ack { Self::ACK } else { 0 }
            | if self.id_request { Self::ID_REQUEST } else { 0 }
    }
    /// The requested state, None for a code that is no state.
    pub const fn requested(self) -> Option<EsmState> {
        EsmState::from_bits(self.state)
    }
}

impl From<u16> for AlControl {
    fn from(v: u16) -> Self {
        Self::from_raw(v)
    }
}

/// AL status (0x0130, slave → master).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AlStatus {
    /// Current state, bits 3:0.
    pub state: EsmState,
    /// Error indication, bit 4 (the reason is in AL status code 0x0134).
    pub error: bool,
    /// Device identification loaded into 0x0134, bit 5.
    pub id_loaded: bool,
}

impl AlStatus {
    const STATE: u16 = 0x000F;
    const ERROR: u16 = 1 << 4;
    const ID_LOADED: u16 = 1 << 5;

    /// Decodes the register; None when bits 3:0 are no state.
    pub const fn from_raw(v: u16) -> Option<Self> {
        match EsmState::from_bits((v & Self::STATE) as u8) {
            Some(state) => Some(AlStatus {
                state,
                error: v & Self::ERROR != 0,
                id_loaded: v & Self::ID_LOADED != 0,
            }),
            None => None,
        }
    }
    /// The register value.
    pub const fn to_raw(self) -> u16 {
        self.state.bits() as u16
            | if self.error { Self::ERROR } else { 0 }
            | if self.id_loaded { Self::ID_LOADED } else { 0 }
    }
}

/// AL event mask (0x0204) and request (0x0220): which events the PDI interrupt
/// reports ([`al_event`] holds the same bits as raw masks).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AlEvent {
    /// AL control written, bit 0.
    pub al_control: bool,
    /// DC latch event, bit 1.
    pub dc_latch: bool,
    /// DC SYNC0, bit 2.
    pub sync0: bool,
    /// DC SYNC1, bit 3.
    pub sync1: bool,
    /// An SM activate register changed, bit 4.
    pub sm_change: bool,
    /// EEPROM emulation command pending, bit 5.
    pub eeprom: bool,
    /// Process-data watchdog expired, bit 6.
    pub watchdog: bool,
    /// SyncManager events, bit n = SM n (register bits 23:8).
    pub sm: u16,
}

impl AlEvent {
    /// No event.
    pub const NONE: Self = AlEvent {
        al_control: false,
        dc_latch: false,
        sync0: false,
        sync1: false,
        sm_change: false,
        eeprom: false,
        watchdog: false,
        sm: 0,
    };

    /// Decodes the register (bits 31:24 are reserved and ignored).
    pub const fn from_raw(v: u32) -> Self {
        AlEvent {
            al_control: v & al_event::AL_CONTROL != 0,
            dc_latch: v & al_event::DC_LATCH != 0,
            sync0: v & al_event::SYNC0 != 0,
            sync1: v & al_event::SYNC1 != 0,
            sm_change: v & al_event::SM_CHANGE != 0,
            eeprom: v & al_event::EEPROM != 0,
            watchdog: v & al_event::WATCHDOG != 0,
            sm: (v >> 8) as u16,
        }
    }
    /// The register value.
    pub const fn to_raw(self) -> u32 {
        const fn bit(on: bool, b: u32) -> u32 {
            if on {
                b
            } else {
                0
            }
        }
        bit(self.al_control, al_event::AL_CONTROL)
            | bit(self.dc_latch, al_event::DC_LATCH)
            | bit(self.sync0, al_event::SYNC0)
            | bit(self.sync1, al_event::SYNC1)
            | bit(self.sm_change, al_event::SM_CHANGE)
            | bit(self.eeprom, al_event::EEPROM)
            | bit(self.watchdog, al_event::WATCHDOG)
            | (self.sm as u32) << 8
    }
    /// The event of SyncManager `n`.
    pub const fn sm(self, n: u8) -> bool {
        self.sm & (1 << n) != 0
    }
    /// With the event of SyncManager `n` set.
    pub const fn with_sm(mut self, n: u8) -> Self {
        self.sm |= 1 << n;
        self
    }
}

impl From<u32> for AlEvent {
    fn from(v: u32) -> Self {
        Self::from_raw(v)
    }
}

/// DC activation (0x0981), written by the master (or the PDI when it owns the sync
/// unit).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DcActivation {
    /// Cyclic (SYNC-out) unit active, bit 0.
    pub cyclic: bool,
    /// SYNC0 generated, bit 1.
    pub sync0: bool,
    /// SYNC1 generated, bit 2.
    pub sync1: bool,
    /// Bits 7:3 (auto-activation, start time checks, debug pulse), raw.
    pub upper: u8,
}

impl DcActivation {
    /// Decodes the register.
    pub const fn from_raw(v: u8) -> Self {
        DcActivation {
            cyclic: v & 1 != 0,
            sync0: v & 2 != 0,
            sync1: v & 4 != 0,
            upper: v >> 3,
        }
    }
    /// The register value.
    pub const fn to_raw(self) -> u8 {
        (self.cyclic as u8) | (self.sync0 as u8) << 1 | (self.sync1 as u8) << 2 | self.upper << 3
    }
    /// DC off: cyclic unit, SYNC0 and SYNC1 all inactive (bits 2:0 = 000).
    pub const fn off(self) -> bool {
        !self.cyclic && !self.sync0 && !self.sync1
    }
    /// SYNC0 running: cyclic unit and SYNC0 active, SYNC1 not (bits 2:0 = 011).
    pub const fn sync0_only(self) -> bool {
        self.cyclic && self.sync0 && !self.sync1
    }
}

impl From<u8> for DcActivation {
    fn from(v: u8) -> Self {
        Self::from_raw(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn register_widths() {
        assert_eq!((AL_CONTROL.addr(), AL_CONTROL.len()), (0x0120, 2));
        assert_eq!(
            (AL_EVENT_REQUEST.addr(), AL_EVENT_REQUEST.len()),
            (0x0220, 4)
        );
        assert_eq!((DC_ACTIVATION.addr(), DC_ACTIVATION.len()), (0x0981, 1));
        assert_eq!(
            (DC_SYSTEM_TIME.len(), PDI_CONFIG.len(), SII_DATA.len()),
            (8, 4, 8)
        );
    }

    #[test]
    fn al_control_bits() {
        let c = AlControl::from_raw(0x0032);
        assert_eq!(
            c,
            AlControl {
                state: 2,
                ack: true,
                id_request: true
            }
        );
        assert_eq!(c.to_raw(), 0x0032);
        assert_eq!(c.requested(), Some(EsmState::PreOp));
        assert_eq!(AlControl::from_raw(0xFFC7).to_raw(), 0x0007);
        assert_eq!(AlControl::from_raw(0x0007).requested(), None);
        assert!(AlControl::from(0x0013).ack);
    }

    #[test]
    fn al_status_bits() {
        let s = AlStatus {
            state: EsmState::SafeOp,
            error: true,
            id_loaded: false,
        };
        assert_eq!(s.to_raw(), 0x0014);
        assert_eq!(AlStatus::from_raw(0x0014), Some(s));
        assert_eq!(AlStatus::from_raw(0x0028).map(|s| s.to_raw()), Some(0x0028));
        assert_eq!(AlStatus::from_raw(0x0000), None);
    }

    #[test]
    fn al_event_bits() {
        let e = AlEvent::from_raw(0x0000_0511);
        assert!(e.al_control && e.sm_change && e.sm(0) && e.sm(2));
        assert!(!e.sync0 && !e.watchdog && !e.sm(1));
        assert_eq!(e.to_raw(), 0x0000_0511);
        for (bit, raw) in [
            (
                AlEvent {
                    dc_latch: true,
                    ..AlEvent::NONE
                },
                1 << 1,
            ),
            (
                AlEvent {
                    sync0: true,
                    ..AlEvent::NONE
                },
                1 << 2,
            ),
            (
                AlEvent {
                    sync1: true,
                    ..AlEvent::NONE
                },
                1 << 3,
            ),
            (
                AlEvent {
                    eeprom: true,
                    ..AlEvent::NONE
                },
                1 << 5,
            ),
            (
                AlEvent {
                    watchdog: true,
                    ..AlEvent::NONE
                },
                1 << 6,
            ),
            (AlEvent::NONE.with_sm(3), 1 << 11),
            (AlEvent::NONE.with_sm(15), 1 << 23),
        ] {
            assert_eq!(bit.to_raw(), raw);
            assert_eq!(AlEvent::from(raw), bit);
        }
        assert_eq!(AlEvent::from_raw(0xFF00_0000), AlEvent::NONE);
    }

    #[test]
    fn dc_activation_bits() {
        let a = DcActivation::from_raw(0x03);
        assert!(a.cyclic && a.sync0 && !a.sync1 && a.sync0_only() && !a.off());
        assert_eq!(a.to_raw(), 0x03);
        assert!(DcActivation::from_raw(0xF8).off());
        assert_eq!(DcActivation::from(0xF8).to_raw(), 0xF8);
        assert!(!DcActivation::from_raw(0x07).sync0_only());
        assert!(!DcActivation::from_raw(0x02).sync0_only());
        assert!(!DcActivation::from_raw(0x01).off());
    }
}
