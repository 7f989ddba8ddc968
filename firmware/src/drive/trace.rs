//! The drive's side of the scope ([`crate::scope`]): the sample the supervision tick
//! takes while the scope records, the samples of the control path's servo periods
//! at the servo rate, and the values of the internal signals 0x2510.

use super::*;
use crate::scope::{self, ServoPoint, Source};
use ecat_slave_stack::od::{Entry, ObjectKey, Values};

impl<S: ParameterStore> Drive<S> {
    /// One tick of the recording scope: every `divisor`-th tick, each channel's value
    /// as the TxPDO reads it (the CiA 402 slots directly, other entries through the
    /// dictionary read; an entry that cannot be read records 0).
    // Measured (cargo xtask size, LAN9252 image): dropped with the other hot-path
    // attributes the image grew 1184 B; see `stack::other_tx_entry`.
    #[inline(never)]
    pub(super) fn sample_scope(&mut self) {
        if self.scope.at_servo_rate() || !self.scope.sample_due() {
            return;
        }
        let mut values = [0i32; scope::CHANNELS];
        for (v, s) in values.iter_mut().zip(self.scope.sources()) {
            *v = self.source_value(s);
        }
        self.scope.record(&values);
    }

    /// The scope records at the servo rate (0x2500:08 = 1): the control path is to
    /// hand over a [`ServoPoint`] every servo period.
    pub fn scope_wants_servo_points(&self) -> bool {
        self.scope.at_servo_rate()
    }

    /// One servo period's point for the scope at the servo rate (the board's tick
    /// passes the queued ones before [`Drive::tick`]): every `divisor`-th is a sample,
    /// the 0x2510 channels from the point, the others as the objects stand.
    pub fn scope_servo_point(&mut self, p: &ServoPoint) {
        if !self.scope.at_servo_rate() || !self.scope.sample_due() {
            return;
        }
        let mut values = [0i32; scope::CHANNELS];
        for (v, s) in values.iter_mut().zip(self.scope.sources()) {
            *v = if s.index == scope::SIGNALS {
                s.decode(scope::internal_signal(p, &self.command, s.sub))
            } else {
                self.source_value(s)
            };
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
    pub(super) fn read_scope(&self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        if key.index != scope::SIGNALS || key.sub == 0 {
            return dictionary::read(&self.scope, &(), key, buf);
        }
        let signals = InternalSignals(ServoPoint::of(&self.axis), &self.command);
        dictionary::read(&signals, &(), key, buf)
    }
}

/// The values of 0x2510:01-0A: the internal signals of a servo point and the last
/// command (read-only).
struct InternalSignals<'a>(ServoPoint, &'a DriveCommand);

impl Values for InternalSignals<'_> {
    fn get(&self, _: &(), key: ObjectKey, _: &Entry) -> Result<i64, SdoAbort> {
        Ok(i64::from(scope::internal_signal(&self.0, self.1, key.sub)))
    }
}
