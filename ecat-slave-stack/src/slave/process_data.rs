//! The slave runtime's process data: outputs from SM2, the cycle, inputs to SM3.

use super::*;

impl<E: EscAccess> Slave<E> {
    pub(super) fn process_data<A: SlaveApplication>(
        &mut self,
        app: &mut A,
        ev: AlEvent,
        now: u64,
        external: bool,
    ) -> Result<(), EscError> {
        let rx_len = self.plan.rx.bytes() as usize;
        let got_sm2 = rx_len > 0 && ev.sm(2);
        if got_sm2 {
            let start = self.active[2].start;
            self.esc
                .read(start, &mut self.rx_buf[..rx_len.min(pdo::MAX_BYTES)])?;
            self.outputs_fresh = true;
            self.outputs_seen = true;
            self.sync.sm2_since_sync0 = true;
            self.sync.last_sm2 = Some(now);
        }
        let run = match self.sync.mode {
            SyncMode::DcSync0 => {
                let sync0 = ev.sync0 || external;
                if sync0 {
                    self.esc.get(reg::DC_SYNC0_STATUS)?;
                    self.on_sync0(app, now)?;
                }
                sync0
            }
            SyncMode::SmSync => external || got_sm2 || (rx_len == 0 && ev.sm(3)),
            SyncMode::FreeRun => {
                external
                    || self.sync.last_cycle.is_none_or(|t| {
                        now.saturating_sub(t) >= self.sync.free_run_period_us() as u64
                    })
            }
        };
        if run && self.esm.state().process_data_running() {
            self.run_cycle(app, now)?;
        }
        Ok(())
    }

    pub(super) fn on_sync0<A: SlaveApplication>(
        &mut self,
        app: &mut A,
        now: u64,
    ) -> Result<(), EscError> {
        let (event, interval) = self.sync.sup.on_sync0(now);
        if let Some(i) = interval {
            self.sync.diag.sync0_period(i);
        }
        if let Some(t) = self.sync.last_sm2 {
            if self.sync.sm2_since_sync0 {
                self.sync.diag.pdi_to_sync0 = now.saturating_sub(t).min(u32::MAX as u64) as u32;
            }
        }
        if let SyncEvent::Error(code) = event {
            if !self.esm.error() {
                return self.local_error(app, code);
            }
        }
        if self.esm.state() == EsmState::Op && self.plan.rx.bytes() > 0 && !self.esm.error() {
            let got = self.sync.sm2_since_sync0;
            if let Some(code) = self.sync.account_sm_event(got, app.sync_error_limit()) {
                self.sync.sm2_since_sync0 = false;
                return self.local_error(app, code);
            }
        }
        self.sync.sm2_since_sync0 = false;
        Ok(())
    }

    pub(super) fn run_cycle<A: SlaveApplication>(
        &mut self,
        app: &mut A,
        now: u64,
    ) -> Result<(), EscError> {
        if let Some(t) = self.sync.last_cycle {
            self.sync.diag.pdi_period = now.saturating_sub(t).min(u32::MAX as u64) as u32;
        }
        self.sync.last_cycle = Some(now);
        let start = app.now_us();
        let state = self.esm.state();
        let fresh = state == EsmState::Op && self.outputs_fresh;
        if fresh {
            pdo::unpack(&self.plan.rx, &self.rx_buf, app);
            self.outputs_fresh = false;
        }
        app.cycle(&CycleInfo {
            state,
            outputs_fresh: fresh,
            mode: self.sync.mode,
            now_us: now,
        });
        self.write_inputs(app)?;
        if let (Some(a), Some(b)) = (start, app.now_us()) {
            self.sync
                .computation(b.saturating_sub(a), app.sync_error_limit());
        }
        Ok(())
    }

    pub(super) fn write_inputs<A: SlaveApplication>(
        &mut self,
        app: &mut A,
    ) -> Result<(), EscError> {
        let tx_len = (self.plan.tx.bytes() as usize).min(pdo::MAX_BYTES);
        if tx_len == 0 {
            return Ok(());
        }
        pdo::pack(&self.plan.tx, app, &mut self.tx_buf[..tx_len]);
        self.esc.write(self.active[3].start, &self.tx_buf[..tx_len])
    }
}
