//! The ESC's registers as both sides read and write them: dynamic values, read side
//! effects (events cleared), and each side's access rights per register byte
//! (ETG.1000.4); writes that trigger something (AL control, the EEPROM command, the
//! system time, the SYNC activation) act once the whole write is in.
use super::sii::SII_CTRL_BUSY;
use super::{get_u16, put_u16, put_u64, reg, EscSim, Side, ECAT_EVENT_AL_STATUS};

/// The ESC's state before a register write, for its byte-wise rules.
struct WriteCtx {
    /// First address of the write.
    start: usize,
    /// Device emulation (0x0141 bit 0): AL status follows AL control.
    emulation: bool,
    /// The PDI owns the SYNC unit (0x0980 bit 0).
    sync_owner_pdi: bool,
    /// The EEPROM interface is busy: its registers are not taken.
    sii_busy: bool,
}

/// What the bytes of one register write triggered.
#[derive(Default)]
struct Written {
    al_control: bool,
    sii_cmd: bool,
}

impl EscSim {
    pub(super) fn read_registers(&mut self, side: Side, start: usize, buf: &mut [u8]) {
        let end = start + buf.len();
        let overlaps = |a: usize, len: usize| start < a + len && a < end;
        // Dynamic values first.
        if overlaps(reg::DC_SYSTEM_TIME.addr() as usize, 8) {
            let st = self.system_time_at(self.access_time(side));
            put_u64(&mut self.mem, reg::DC_SYSTEM_TIME.addr() as usize, st);
        }
        buf.copy_from_slice(&self.mem[start..end]);
        // Read side effects.
        match side {
            Side::Pdi => {
                if overlaps(reg::AL_CONTROL.addr() as usize, 2) {
                    self.al_control_unread = false;
                    self.al_event_clear(reg::al_event::AL_CONTROL);
                }
                if overlaps(reg::DC_SYNC0_STATUS.addr() as usize, 1) {
                    self.mem[reg::DC_SYNC0_STATUS.addr() as usize] = 0;
                    self.al_event_clear(reg::al_event::SYNC0);
                }
                if overlaps(reg::WATCHDOG_STATUS_PD.addr() as usize, 2) {
                    self.al_event_clear(reg::al_event::WATCHDOG);
                }
                for n in 0..self.sms.len() {
                    if overlaps(reg::sm_register(n as u8) as usize + 6, 1) {
                        self.al_event_clear(reg::al_event::SM_CHANGE);
                    }
                }
            }
            Side::Ecat => {
                if overlaps(reg::AL_STATUS.addr() as usize, 2) {
                    self.ecat_event_clear(ECAT_EVENT_AL_STATUS);
                }
            }
        }
        if overlaps(reg::SII_CONTROL.addr() as usize + 1, 1) && self.sii_busy_reads > 0 {
            self.sii_busy_reads -= 1;
            if self.sii_busy_reads == 0 {
                self.sii_finish_busy();
            }
        }
    }

    /// Who may drive the EEPROM interface: the PDI once the master has offered it
    /// (0x0500 bit 0) and the PDI has taken it (0x0501 bit 0); the master otherwise.
    fn sii_owner(&self) -> Side {
        let offered = self.mem[reg::SII_CONFIG.addr() as usize] & 0x01 != 0;
        let taken = self.mem[reg::SII_PDI_ACCESS.addr() as usize] & 0x01 != 0;
        if offered && taken {
            Side::Pdi
        } else {
            Side::Ecat
        }
    }

    pub(super) fn write_registers(&mut self, side: Side, start: usize, data: &[u8]) {
        let ctx = WriteCtx {
            start,
            emulation: self.mem[reg::ESC_CONFIG.addr() as usize] & 0x01 != 0,
            sync_owner_pdi: self.mem[reg::DC_CYCLIC_UNIT_CONTROL.addr() as usize] & 0x01 != 0,
            sii_busy: get_u16(&self.mem, reg::SII_CONTROL.addr() as usize) & SII_CTRL_BUSY != 0,
        };
        let old_activation = self.mem[reg::DC_ACTIVATION.addr() as usize];
        let mut w = Written::default();
        for (i, &v) in data.iter().enumerate() {
            match side {
                Side::Ecat => self.ecat_register_byte(start + i, v, &ctx, &mut w),
                Side::Pdi => self.pdi_register_byte(start + i, v, &ctx, &mut w),
            }
        }
        let end = start + data.len();
        let overlaps = |a: usize, len: usize| start < a + len && a < end;
        if w.al_control {
            if ctx.emulation {
                let ctl = get_u16(&self.mem, reg::AL_CONTROL.addr() as usize);
                put_u16(&mut self.mem, reg::AL_STATUS.addr() as usize, ctl & 0x000F);
            } else {
                self.al_control_unread = true;
                self.al_event_set(reg::al_event::AL_CONTROL);
            }
        } else if side == Side::Ecat && overlaps(reg::AL_CONTROL.addr() as usize, 2) {
            self.stats.al_control_writes_ignored += 1;
        }
        if w.sii_cmd {
            self.sii_execute();
        }
        if side == Side::Ecat && overlaps(reg::DC_SYSTEM_TIME.addr() as usize, 8) {
            self.system_time_write(start, data);
        }
        let owner_wrote = (side == Side::Pdi) == ctx.sync_owner_pdi;
        if owner_wrote
            && overlaps(reg::DC_ACTIVATION.addr() as usize, 1)
            && old_activation != self.mem[reg::DC_ACTIVATION.addr() as usize]
        {
            self.sync_activation_changed();
        }
    }

    #[allow(clippy::collapsible_match)] // one arm per register range reads better
    /// One byte of a master's register write at `a`: the ECAT side's access rights.
    fn ecat_register_byte(&mut self, a: usize, v: u8, ctx: &WriteCtx, w: &mut Written) {
        match a {
            0x0010..=0x0011 | 0x0100..=0x0103 | 0x0108..=0x0109 | 0x0138..=0x0139 => {
                self.mem[a] = v
            }
            0x0120..=0x0121 => {
                if self.al_control_unread && !ctx.emulation {
                    // AL control behaves like a mailbox: the PDI has not read the
                    // previous request yet, the write is not taken.
                    return;
                }
                self.mem[a] = v;
                w.al_control = true;
            }
            0x0200..=0x0201 => self.mem[a] = v,
            // Error counters: any write clears them.
            0x0300..=0x0313 | 0x0442..=0x0443 => self.mem[a] = 0,
            0x0400..=0x0401 | 0x0410..=0x0411 | 0x0420..=0x0421 => self.mem[a] = v,
            0x0500 => {
                self.mem[a] = v & 0x03;
                if v & 0x02 != 0 {
                    // Force ECAT access: reset the PDI access flag.
                    self.mem[reg::SII_PDI_ACCESS.addr() as usize] &= !0x01;
                    self.mem[a] &= !0x01;
                }
            }
            0x0502..=0x050F => self.sii_register_byte(Side::Ecat, a, v, ctx, w),
            0x0510..=0x0517 => self.mem[a] = v,
            _ if (0x0600..self.fmmu_end()).contains(&a) => {
                if (a - 0x0600) % 16 < 0x0D {
                    self.mem[a] = v;
                }
            }
            _ if (0x0800..self.sm_end()).contains(&a) => self.sm_reg_write_ecat(a, v),
            0x0900..=0x0903 => {
                // A write to receive time port 0 latches the receive times.
                if a == ctx.start || a == 0x0900 {
                    self.latch_receive_times();
                }
            }
            0x0920..=0x092B | 0x0930..=0x0935 => self.mem[a] = v,
            0x0980 => self.mem[a] = v,
            0x0981 | 0x0990..=0x0997 | 0x09A0..=0x09A7 if !ctx.sync_owner_pdi => self.mem[a] = v,
            0x09A8..=0x09A9 => self.mem[a] = v,
            0x0F80..=0x0FFF => self.mem[a] = v,
            _ => {}
        }
    }

    #[allow(clippy::collapsible_match)] // as above
    /// One byte of a microcontroller's register write at `a`: the PDI side's access
    /// rights.
    fn pdi_register_byte(&mut self, a: usize, v: u8, ctx: &WriteCtx, w: &mut Written) {
        match a {
            0x0012..=0x0013 | 0x0138..=0x0139 | 0x0204..=0x0207 => self.mem[a] = v,
            0x0130..=0x0135 => {
                if !ctx.emulation {
                    self.mem[a] = v;
                    if a <= 0x0131 {
                        self.ecat_event_set(ECAT_EVENT_AL_STATUS);
                    }
                }
            }
            0x0501 => self.mem[a] = v & 0x01,
            0x0502..=0x050F => self.sii_register_byte(Side::Pdi, a, v, ctx, w),
            _ if (0x0800..self.sm_end()).contains(&a) => {
                if (a - 0x0800) % 8 == 7 {
                    self.sm_pdi_control_write(a, v);
                }
            }
            0x0981 | 0x0990..=0x0997 | 0x09A0..=0x09A7 if ctx.sync_owner_pdi => self.mem[a] = v,
            0x0F80..=0x0FFF => self.mem[a] = v,
            _ => {}
        }
    }

    /// A byte of the EEPROM interface (0x0502-0x050F), taken from its owner while the
    /// interface is not busy.
    fn sii_register_byte(&mut self, side: Side, a: usize, v: u8, ctx: &WriteCtx, w: &mut Written) {
        if self.sii_owner() == side && !ctx.sii_busy {
            self.sii_reg_write(a, v);
            w.sii_cmd |= a == 0x0503;
        }
    }
}
