//! The drive's side of the scope ([`crate::scope`]): the sample the supervision tick
//! takes while the scope records, and the values of the internal signals 0x2510.

use super::*;
use crate::scope::{self, Source};

impl<S: ParameterStore> Drive<S> {
    /// One tick of the recording scope: every `divisor`-th tick, each channel's value
    /// as the TxPDO reads it (the CiA 402 slots directly, other entries through the
    /// dictionary read; an entry that cannot be read records 0).
    #[inline(never)]
    pub(super) fn sample_scope(&mut self) {
        if !self.scope.sample_due() {
            return;
        }
        let mut values = [0i32; scope::CHANNELS];
        for (v, s) in values.iter_mut().zip(self.scope.sources()) {
            *v = self.source_value(s);
        }
        self.scope.record(&values);
    }

    fn source_value(&self, s: &Source) -> i32 {
        let raw = match s.slot {
            Some(slot) => self.cia402.get_tx_raw(slot),
            None => {
                let mut b = [0u8; 8];
                match self.read_entry(s.index, s.sub, &mut b) {
                    Ok(_) => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
                    Err(_) => 0,
                }
            }
        };
        s.decode(raw)
    }

    /// SDO / PDO read of 0x2500-0x25FF: the internal signals 0x2510 from the axis and
    /// the last command, the rest from the scope.
    pub(super) fn read_scope(
        &self,
        index: u16,
        sub: u8,
        buf: &mut [u8],
    ) -> Result<usize, SdoAbort> {
        if index != scope::SIGNALS || sub == 0 {
            return self.scope.read(index, sub, buf);
        }
        let entry = dictionary::find_entry_in(dictionary::SCOPE, index, sub)?;
        let c = &self.command;
        let v: u32 = match sub {
            1 => self.axis.servo_following_error as u32,
            2 => sat_i32(c.acceleration) as u32,
            3 => self.axis.bus_mv,
            _ => {
                u32::from(c.power_stage)
                    | u32::from(c.drive_enabled) << 1
                    | u32::from(self.axis.current_limited) << 2
                    | u32::from(c.brake_release) << 3
            }
        };
        dictionary::put_le(entry, u64::from(v), buf)
    }
}

/// `v` rounded toward zero and saturated to `i32` (`as` does both; NaN → 0).
fn sat_i32(v: f32) -> i32 {
    v as i32
}
