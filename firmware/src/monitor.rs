//! Monitoring objects (the Xinje U0 group, in our vendor range 0x2300-0x230A):
//! electrical angle, phase currents set and measured, bus voltage, power-on count,
//! running time, the time of the last control step. All read-only over SDO; the
//! values that change every cycle are TxPDO-mappable.
//!
//! The power-on count and the accumulated running time are `saved` entries: they are
//! written to flash with every 'save' and restored at power-up (the storage restore is
//! the only writer, through the `Values` binding); [`Monitor::power_up`] then counts the new
//! power-up. They are thus exact up to the last save (the board may also save on a
//! power-fail warning).

use ecat_slave_stack::od::{Access, DataType, EntryDesc, PdoMappable};

use crate::bind::bound_objects;

const fn tx(name: &'static str, t: DataType, unit: &'static str) -> EntryDesc {
    EntryDesc::new(0, name, t, Access::RO)
        .pdo(PdoMappable::Tx)
        .unit(unit)
}

// The monitoring objects and their values (only the storage restore of the two saved
// counters writes: SDO writes are refused by the generic read-only check before).
bound_objects! {
    impl Values<()> for Monitor;
    var 0x2300, "Electrical angle", "Electrical angle used by the current loop", {
        tx("Electrical angle", DataType::Unsigned16, "1/65536 turn") => get |m| m.m.electrical_angle;
    }
    var 0x2301, "Phase A current set", "Phase A current set-point", {
        tx("Phase A current set", DataType::Integer16, "mA") => get |m| m.m.ia_set_ma;
    }
    var 0x2302, "Phase B current set", "Phase B current set-point", {
        tx("Phase B current set", DataType::Integer16, "mA") => get |m| m.m.ib_set_ma;
    }
    var 0x2303, "Phase A current", "Measured phase A current", {
        tx("Phase A current", DataType::Integer16, "mA") => get |m| m.m.ia_ma;
    }
    var 0x2304, "Phase B current", "Measured phase B current", {
        tx("Phase B current", DataType::Integer16, "mA") => get |m| m.m.ib_ma;
    }
    var 0x2305, "Bus voltage", "Measured DC bus voltage", {
        tx("Bus voltage", DataType::Unsigned16, "10mV") => get |m| m.m.bus_10mv;
    }
    var 0x2306, "Power-on count", "Number of power-ups (as of the last save)", {
        EntryDesc::new(0, "Power-on count", DataType::Unsigned32, Access::RO)
            .default(0)
            .saved()
            => get |m| m.power_on_count, set |m, v| m.power_on_count = v as u32;
    }
    var 0x2307, "Running time", "Accumulated powered time (as of the last save)", {
        EntryDesc::new(0, "Running time", DataType::Unsigned32, Access::RO)
            .unit("s")
            .default(0)
            .saved()
            => get |m| m.running_time_s(), set |m, v| {
                m.base_running_s = v as u32;
                m.since_power_up_ms %= 1000;
            };
    }
    var 0x2308, "Time since power-up", "Milliseconds since this power-up", {
        tx("Time since power-up", DataType::Unsigned32, "ms") => get |m| m.since_power_up_ms();
    }
    var 0x2309, "Firmware boot state", "0 confirmed, 1 on trial (a new image not yet confirmed: a reset reverts it), 2 reverted (an unconfirmed image was replaced by the previous one), 3 no firmware update", {
        EntryDesc::new(0, "Firmware boot state", DataType::Unsigned8, Access::RO).default(3)
            => get |m| m.boot_state;
    }
    var 0x230A, "Control step time", "The drive's clock (us, wrapping) at its last control step: the instant of the 0x6064 and 0x606C in the same TxPDO", {
        tx("Control step time", DataType::Unsigned32, "us") => get |m| m.step_us;
    }
}

/// Values measured by the control loops, updated by the application.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Measurements {
    /// Electrical angle, 1/65536 turn.
    pub electrical_angle: u16,
    /// Phase A set-point, mA.
    pub ia_set_ma: i16,
    /// Phase B set-point, mA.
    pub ib_set_ma: i16,
    /// Phase A measured, mA.
    pub ia_ma: i16,
    /// Phase B measured, mA.
    pub ib_ma: i16,
    /// Bus voltage, 10 mV.
    pub bus_10mv: u16,
}

/// Monitoring state.
#[derive(Debug, Clone)]
pub struct Monitor {
    /// Latest measurements.
    pub m: Measurements,
    power_on_count: u32,
    base_running_s: u32,
    since_power_up_ms: u64,
    boot_state: u8,
    step_us: u32,
}

/// 0x2309 of a drive without firmware update.
pub const NO_UPDATE: u8 = 3;

impl Default for Monitor {
    fn default() -> Self {
        Monitor {
            m: Measurements::default(),
            power_on_count: 0,
            base_running_s: 0,
            since_power_up_ms: 0,
            boot_state: NO_UPDATE,
            step_us: 0,
        }
    }
}

impl Monitor {
    /// Zeroed state.
    pub fn new() -> Self {
        Self::default()
    }

    /// 0x2309 ([`crate::update::BootState`] as a number, or [`NO_UPDATE`]).
    pub fn set_boot_state(&mut self, state: u8) {
        self.boot_state = state;
    }

    /// 0x230A: a control step ran at `now_us` (µs, the drive's clock, wrapping).
    pub fn set_step_us(&mut self, now_us: u32) {
        self.step_us = now_us;
    }

    /// Counts this power-up (after the stored values were restored).
    pub fn power_up(&mut self) {
        self.power_on_count = self.power_on_count.wrapping_add(1);
    }

    /// Advances the powered time.
    pub fn tick_ms(&mut self, dt_ms: u32) {
        self.since_power_up_ms += u64::from(dt_ms);
    }

    /// Power-up: raises the running time to `seconds` if it is less (a counter kept
    /// elsewhere — the fault-history record — was written after the last 'save').
    pub fn running_time_at_least(&mut self, seconds: u32) {
        if seconds > self.running_time_s() {
            let since_s = (self.since_power_up_ms / 1000).min(u64::from(u32::MAX)) as u32;
            self.base_running_s = seconds.saturating_sub(since_s);
        }
    }

    /// Power-ups counted.
    pub fn power_on_count(&self) -> u32 {
        self.power_on_count
    }

    /// Accumulated running time, s.
    pub fn running_time_s(&self) -> u32 {
        self.base_running_s
            .saturating_add((self.since_power_up_ms / 1000).min(u64::from(u32::MAX)) as u32)
    }

    /// Milliseconds since power-up (wrapping).
    pub fn since_power_up_ms(&self) -> u32 {
        self.since_power_up_ms as u32
    }
}

#[cfg(test)]
mod tests {
    /// The table as the product packs it (with the plain names of its words).
    static PACKED: &[ecat_slave_stack::od::Object] =
        ecat_slave_stack::packed_dictionary!(&[super::OBJECTS]);

    use super::*;
    use crate::dictionary::Sdo;
    use ecat_slave_stack::od::{self, ObjectKey, SdoAbort};

    #[test]
    fn objects_and_values() {
        assert!(od::is_well_formed(PACKED));
        let mut m = Monitor::new();
        m.m = Measurements {
            electrical_angle: 0x8000,
            ia_set_ma: -1500,
            ib_set_ma: 200,
            ia_ma: -1490,
            ib_ma: 190,
            bus_10mv: 2400,
        };
        let mut buf = [0u8; 4];
        let rd = |m: &Monitor, i: u16, buf: &mut [u8; 4]| {
            let n = m.read(i, 0, buf).unwrap();
            od::decode_int(
                od::find_entry(PACKED, ObjectKey::new(i, 0))
                    .unwrap()
                    .data_type,
                &buf[..n],
            )
            .unwrap()
        };
        assert_eq!(rd(&m, 0x2300, &mut buf), 0x8000);
        assert_eq!(rd(&m, 0x2301, &mut buf), -1500);
        assert_eq!(rd(&m, 0x2304, &mut buf), 190);
        assert_eq!(rd(&m, 0x2305, &mut buf), 2400);
        assert_eq!(m.write(0x2306, 0, &41u32.to_le_bytes()), Ok(()));
        assert_eq!(m.write(0x2307, 0, &3600u32.to_le_bytes()), Ok(()));
        m.power_up();
        m.tick_ms(2500);
        assert_eq!(rd(&m, 0x2306, &mut buf), 42);
        assert_eq!(rd(&m, 0x2307, &mut buf), 3602);
        assert_eq!(rd(&m, 0x2308, &mut buf), 2500);
        assert_eq!(m.write(0x2300, 0, &[0, 0]), Err(SdoAbort::WriteReadOnly));
        assert_eq!(m.write(0x2306, 0, &[0, 0]), Err(SdoAbort::LengthTooLow));
        assert_eq!(m.write(0x2306, 0, &[0; 5]), Err(SdoAbort::LengthTooHigh));
        assert_eq!(rd(&m, 0x2309, &mut buf), i64::from(NO_UPDATE));
        m.set_boot_state(1);
        assert_eq!(rd(&m, 0x2309, &mut buf), 1);
        m.set_step_us(0x8000_0001);
        assert_eq!(rd(&m, 0x230A, &mut buf), 0x8000_0001);
        assert_eq!(
            m.read(0x230B, 0, &mut buf),
            Err(SdoAbort::ObjectDoesNotExist)
        );
        assert_eq!(
            m.read(0x2300, 1, &mut buf),
            Err(SdoAbort::SubindexDoesNotExist)
        );
        let mut small = [0u8; 1];
        assert_eq!(m.read(0x2306, 0, &mut small), Err(SdoAbort::ExceedsMailbox));
        // Every entry is read-only for the SDO server.
        for o in PACKED {
            assert!(!o.entries()[0].access.writable());
        }
    }
}
