//! The slave runtime's mailbox: SM0 requests in, SM1 answers out, and the repeat
//! request.

use super::*;

impl<E: EscAccess> Slave<E> {
    pub(super) fn receive_mailbox<A: SlaveApplication>(
        &mut self,
        app: &mut A,
        now: u64,
    ) -> Result<(), EscError> {
        let sm0 = self.active[0];
        let len = (sm0.len as usize).min(MAX_MAILBOX);
        if len == 0 {
            return Ok(());
        }
        // Header first, then only the bytes it announces (clamped to the buffer), then
        // the last byte of the buffer: reading it hands the buffer back to the master.
        let hdr = crate::mailbox::HEADER_LEN.min(len);
        self.esc.read(sm0.start, &mut self.mbx_buf[..hdr])?;
        let announced = u16::from_le_bytes([self.mbx_buf[0], self.mbx_buf[1]]) as usize;
        let total = (hdr + announced).clamp(hdr, len);
        if total > hdr {
            self.esc
                .read(sm0.start + hdr as u16, &mut self.mbx_buf[hdr..total])?;
        }
        if total < len {
            let mut last = [0u8; 1];
            self.esc.read(sm0.last_byte(), &mut last)?;
        }
        let state = self.esm.state();
        let frame = &self.mbx_buf[..total];
        // Only the handler of the request's protocol is lent out (both borrow `app`);
        // Bootstrap serves FoE only.
        if MailboxFrame::new_unchecked(frame).mailbox_type() == MailboxType::Foe {
            let h = Handlers::<CommDictionary<'_, A>>::foe(app.foe());
            self.mbx.on_request_with(frame, h, state, now);
        } else if state == EsmState::Bootstrap {
            let h = Handlers::<CommDictionary<'_, A>>::foe(None);
            self.mbx.on_request_with(frame, h, state, now);
        } else {
            let mut dict = CommDictionary {
                pdo: &mut self.pdo,
                sync: &mut self.sync,
                app,
            };
            self.mbx
                .on_request_with(frame, Handlers::coe(&mut dict), state, now);
        }
        Ok(())
    }

    pub(super) fn send_mailbox(&mut self, now: u64) -> Result<(), EscError> {
        let sm1 = self.active[1];
        let len = (sm1.len as usize).min(MAX_MAILBOX);
        if len == 0 {
            return Ok(());
        }
        if self.sm1_busy {
            let st = self.esc.read_u8(reg::sm_register(1) + reg::sm::STATUS)?;
            if sm::Status(st).mailbox_full() {
                return Ok(());
            }
            self.sm1_busy = false;
        }
        let n = self.mbx.next_output(&mut self.mbx_buf[..len], now);
        if n > 0 {
            self.write_sm1(sm1, n)?;
        }
        Ok(())
    }

    /// Writes `mbx_buf[..n]` into SM1 so that the last byte of the buffer is written
    /// (buffer hand-over rule).
    pub(super) fn write_sm1(&mut self, sm1: SmRegs, n: usize) -> Result<(), EscError> {
        let len = (sm1.len as usize).min(MAX_MAILBOX);
        let n = n.min(len);
        self.esc.write(sm1.start, &self.mbx_buf[..n])?;
        if n < len {
            self.esc.write_u8(sm1.last_byte(), 0)?;
        }
        self.sm1_busy = true;
        Ok(())
    }

    pub(super) fn repeat_mailbox(&mut self, sm1: SmRegs) -> Result<(), EscError> {
        let len = (sm1.len as usize).min(MAX_MAILBOX);
        let n = self.mbx.repeat_last(&mut self.mbx_buf[..len]);
        let pdi = reg::sm_register(1) + reg::sm::PDI_CONTROL;
        let new_ack = sm1.repeat_request();
        if n > 0 {
            if sm1.status.mailbox_full() {
                // An unread mailbox is in the way: flush SM1 by deactivating it.
                self.esc
                    .write_u8(pdi, sm::PdiControl::new(true, !new_ack).0)?;
                self.esc
                    .write_u8(pdi, sm::PdiControl::new(false, !new_ack).0)?;
            }
            self.write_sm1(sm1, n)?;
        }
        self.esc
            .write_u8(pdi, sm::PdiControl::new(false, new_ack).0)?;
        self.repeat_ack = new_ack;
        Ok(())
    }
}
