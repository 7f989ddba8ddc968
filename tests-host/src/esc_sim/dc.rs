//! Time in the simulated ESC: distributed clocks (receive-time latching, system-time
//! writes, SYNC0 activation and pulses), the process-data and PDI watchdogs, and
//! [`EscSim::advance_to`].
use super::{get_u16, get_u32, get_u64, put_u32, put_u64, reg, EscSim, Sync0};

impl EscSim {
    pub(super) fn latch_receive_times(&mut self) {
        let t0 = self.timing.port0_ns.wrapping_add(self.clock_base_ns);
        put_u32(
            &mut self.mem,
            reg::DC_RECEIVE_TIME_PORT0.addr() as usize,
            t0 as u32,
        );
        if let Some(t1) = self.timing.port1_ns {
            let t1 = t1.wrapping_add(self.clock_base_ns);
            put_u32(
                &mut self.mem,
                reg::DC_RECEIVE_TIME_PORT0.addr() as usize + 4,
                t1 as u32,
            );
        }
        put_u64(&mut self.mem, reg::DC_RECEIVE_TIME_PU.addr() as usize, t0);
    }

    pub(super) fn system_time_write(&mut self, start: usize, data: &[u8]) {
        // Only a write that starts at 0x0910 carries a comparable time value.
        if start != reg::DC_SYSTEM_TIME.addr() as usize || data.len() < 4 {
            return;
        }
        let delay = get_u32(&self.mem, reg::DC_SYSTEM_TIME_DELAY.addr() as usize) as u64;
        let local = self.system_time_at(self.timing.port0_ns);
        let diff: i64 = if data.len() >= 8 {
            let mut b = [0u8; 8];
            b.copy_from_slice(&data[..8]);
            u64::from_le_bytes(b)
                .wrapping_add(delay)
                .wrapping_sub(local) as i64
        } else {
            let v = u32::from_le_bytes([data[0], data[1], data[2], data[3]]);
            v.wrapping_add(delay as u32).wrapping_sub(local as u32) as i32 as i64
        };
        // 0x092C: bit 31 set when the local copy is smaller than the received time.
        let mag = diff.unsigned_abs().min(0x7FFF_FFFF) as u32;
        let reg_v = if diff > 0 { mag | 0x8000_0000 } else { mag };
        put_u32(
            &mut self.mem,
            reg::DC_SYSTEM_TIME_DIFF.addr() as usize,
            reg_v,
        );
        // Drift compensation: the simulated clocks do not drift, so the control loop
        // settles at once on the measured difference.
        self.pll_correction = self.pll_correction.wrapping_add(diff);
    }

    pub(super) fn sync_activation_changed(&mut self) {
        let act = self.mem[reg::DC_ACTIVATION.addr() as usize];
        let status = reg::DC_ACTIVATION_STATUS.addr() as usize;
        if act & 0x03 == 0x03 {
            let start = get_u64(&self.mem, reg::DC_START_TIME.addr() as usize);
            let cycle = get_u32(&self.mem, reg::DC_SYNC0_CYCLE.addr() as usize);
            self.sync0 = Sync0 {
                active: true,
                next: start,
                cycle,
                last_ns: 0,
            };
            let now = self.system_time_at(self.now_ns.max(self.timing.port0_ns));
            self.mem[status] = 0x01;
            if start < now {
                // Start time already past: the chip would wait for the 64-bit system
                // time to wrap around; no SYNC0 in any simulated lifetime.
                self.mem[status] |= 0x04;
                self.sync0.active = false;
            }
        } else {
            self.sync0.active = false;
            self.mem[status] = 0;
        }
    }

    /// Simulated time (ns) of the latest SYNC0 pulse while its AL event is still
    /// pending (the PDI has not read 0x098E yet): when the microcontroller's SYNC0
    /// interrupt would have run.
    pub fn sync0_pending_since(&self) -> Option<u64> {
        let req = get_u32(&self.mem, reg::AL_EVENT_REQUEST.addr() as usize);
        (req & reg::al_event::SYNC0 != 0).then_some(self.sync0.last_ns)
    }

    // ---------------------------------------------------------------- watchdogs

    pub(super) fn watchdog_period_ns(&self, time_reg: u16) -> u64 {
        let div = get_u16(&self.mem, reg::WATCHDOG_DIVIDER.addr() as usize) as u64;
        let t = get_u16(&self.mem, time_reg as usize) as u64;
        (div + 2) * 40 * t
    }

    pub(super) fn pd_watchdog_trigger(&mut self) {
        self.pd_wd_armed = true;
        self.pd_wd_last_ns = self.now_ns;
        self.mem[reg::WATCHDOG_STATUS_PD.addr() as usize] |= 0x01;
    }

    /// True while the process-data watchdog has not expired (0x0440 bit 0).
    pub fn pd_watchdog_ok(&self) -> bool {
        self.mem[reg::WATCHDOG_STATUS_PD.addr() as usize] & 0x01 != 0
    }

    // ---------------------------------------------------------------- time

    /// Simulated time (ns) of the next SYNC0 pulse, `None` while the SYNC unit is
    /// off: the instant a real-time runner wakes the application for its SYNC0
    /// interrupt. A pulse already due gives the current time.
    pub fn next_sync0_ns(&self) -> Option<u64> {
        if !self.sync0.active {
            return None;
        }
        let st = self.system_time_at(self.now_ns);
        Some(self.now_ns + self.sync0.next.saturating_sub(st))
    }

    /// Advances simulated time to `t_ns` (never backwards): generates SYNC0 pulses,
    /// runs the process-data and PDI watchdogs, and ends a pending EEPROM busy phase.
    ///
    /// The pulses due since the last call are counted in [`super::SimStats::sync0_pulses`]
    /// but raise one SYNC0 event, as a DC unit's pulses happen at their times
    /// whatever the microcontroller does: one whose interrupt was still pending sees
    /// one interrupt, never a burst of them.
    pub fn advance_to(&mut self, t_ns: u64) {
        if t_ns < self.now_ns {
            return;
        }
        self.now_ns = t_ns;
        if self.sii_busy_reads > 0 {
            self.sii_finish_busy();
        }
        if self.sync0.active {
            let st = self.system_time_at(t_ns);
            if st >= self.sync0.next {
                let pulses = if self.sync0.cycle == 0 {
                    self.sync0.active = false;
                    1
                } else {
                    (st - self.sync0.next) / self.sync0.cycle as u64 + 1
                };
                // The latest of the pulses due, on the simulated clock.
                let last = self
                    .sync0
                    .next
                    .wrapping_add((pulses - 1).wrapping_mul(self.sync0.cycle as u64));
                self.sync0.last_ns = t_ns - st.wrapping_sub(last).min(t_ns);
                self.sync0.next = self
                    .sync0
                    .next
                    .wrapping_add(pulses.wrapping_mul(self.sync0.cycle as u64));
                self.stats.sync0_pulses += pulses;
                self.mem[reg::DC_SYNC0_STATUS.addr() as usize] |= 0x01;
                self.mem[reg::DC_ACTIVATION_STATUS.addr() as usize] &= !0x01;
                self.al_event_set(reg::al_event::SYNC0);
                put_u64(
                    &mut self.mem,
                    reg::DC_START_TIME.addr() as usize,
                    self.sync0.next,
                );
            }
        }
        let pd_period = self.watchdog_period_ns(reg::WATCHDOG_TIME_PD.addr());
        if self.pd_wd_armed
            && pd_period != 0
            && self.pd_watchdog_ok()
            && t_ns.saturating_sub(self.pd_wd_last_ns) > pd_period
        {
            self.mem[reg::WATCHDOG_STATUS_PD.addr() as usize] &= !0x01;
            let c = reg::WATCHDOG_COUNTER_PD.addr() as usize;
            self.mem[c] = self.mem[c].saturating_add(1);
            self.stats.pd_watchdog_expiries += 1;
            self.al_event_set(reg::al_event::WATCHDOG);
        }
        let pdi_period = self.watchdog_period_ns(reg::WATCHDOG_TIME_PDI.addr());
        let dl = reg::DL_STATUS.addr() as usize;
        if pdi_period != 0
            && self.mem[dl] & 0x02 != 0
            && t_ns.saturating_sub(self.pdi_last_ns) > pdi_period
        {
            self.mem[dl] &= !0x02;
            let c = reg::WATCHDOG_COUNTER_PDI.addr() as usize;
            self.mem[c] = self.mem[c].saturating_add(1);
            self.stats.pdi_watchdog_expiries += 1;
        }
    }
}
