//! The slave runtime's synchronisation: entering a sync mode, following the DC
//! registers, deriving the sync mode from the master's configuration.

use super::*;

impl<E: EscAccess> Slave<E> {
    /// Applies a sync mode (0x1C32/0x1C33 SI1, SI2, SI0A, supervision); entering DC
    /// mode acknowledges a SYNC0 event left over from before (0x098E), so the first
    /// cycle belongs to the first SYNC0 of the new configuration.
    pub(super) fn enter_sync(
        &mut self,
        mode: SyncMode,
        cycle: u32,
        outputs: bool,
    ) -> Result<(), EscError> {
        if mode == SyncMode::DcSync0 {
            self.esc.get(reg::DC_SYNC0_STATUS)?;
        }
        self.sync.enter(mode, cycle, outputs);
        Ok(())
    }

    /// Safe-Op: follows the DC activation 0x0981 and SYNC0 cycle 0x09A0 the master
    /// changed after Pre-Op→Safe-Op. SOEM arms SYNC0 only then (its
    /// `ecx_config_map_group` requests Safe-Op, `ecx_dcsync0` comes later), so the
    /// mode is derived again from the same rules as at P→S ([`sync::resolve_mode`]
    /// with the sync types written in Pre-Op): a consistent change switches the mode
    /// at once (0x1C32:01/02, 0x1C33:01 report it, SYNC0 supervision starts);
    /// an inconsistent one keeps the mode and is remembered as the code the S→O
    /// transition is refused with (0x0028 / 0x0030 / 0x0035 / 0x001F). Reads the two
    /// registers at most once per [`WD_CHECK_US`] unless `force` (the S→O request).
    pub(super) fn follow_dc(&mut self, now: u64, force: bool) -> Result<(), EscError> {
        if !force && now.saturating_sub(self.last_dc_check) < WD_CHECK_US {
            return Ok(());
        }
        self.last_dc_check = now;
        let outputs = self.plan.rx.bytes() > 0;
        let sm2 = self.active[2];
        let (mode, cycle, _) = match self.derive_sync(&sm2, outputs)? {
            Ok(d) => d,
            Err(c) => {
                self.dc_refusal = Some(c);
                return Ok(());
            }
        };
        self.dc_refusal = None;
        if mode == self.sync.mode
            && (mode != SyncMode::DcSync0 || cycle == self.sync.sm2.sync0_cycle_ns)
        {
            return Ok(());
        }
        self.enter_sync(mode, cycle, outputs)?;
        self.write_event_mask()
    }

    /// The sync decision shared by P→S and the Safe-Op follow-up: reads 0x0981 and
    /// 0x09A0, resolves the mode with the sync types written
    /// in Pre-Op ([`sync::resolve_mode`]) and checks the process-data watchdog against
    /// the cycle. Returns (mode, SYNC0 cycle, watchdog time 0x0420) or the refusal.
    pub(super) fn derive_sync(
        &mut self,
        sm2: &SmRegs,
        outputs: bool,
    ) -> Result<Result<(SyncMode, u32, u16), AlStatusCode>, EscError> {
        let activation = self.esc.get(reg::DC_ACTIVATION)?;
        let cycle = self.esc.get(reg::DC_SYNC0_CYCLE)?;
        let mode = match sync::resolve_mode(
            self.sync.sm2.written_type,
            self.sync.sm3.written_type,
            activation,
            cycle,
            outputs,
            self.sync.min_cycle_ns,
        ) {
            Ok(m) => m,
            Err(c) => return Ok(Err(c)),
        };
        let wd_div = self.esc.get(reg::WATCHDOG_DIVIDER)?;
        let wd_time = self.esc.get(reg::WATCHDOG_TIME_PD)?;
        let cycle_for_wd = if mode == SyncMode::DcSync0 {
            cycle
        } else {
            self.sync.sm2.cycle_ns
        };
        Ok(
            sm::validate_watchdog(sm2, outputs, wd_div, wd_time, cycle_for_wd)
                .map(|()| (mode, cycle, wd_time)),
        )
    }
}
