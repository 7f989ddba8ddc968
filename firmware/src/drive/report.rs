//! The current-loop supervisor's report on the drive's side
//! ([`crate::current_supervisor`]): the power-up self-test, the auto-tune's result
//! into the parameters, and its events (failed tune, fast-protection trip, a phase
//! without current, current that does not follow) as faults.

use super::*;

impl<S: ParameterStore> Drive<S> {
    /// The current-loop supervisor's report (control path → drive; call every tick,
    /// before [`Drive::tick`]). A finished tune writes 0x2020 (mΩ), 0x2021 (µH), 0x2015
    /// and 0x2016 (the gains the loop now uses) and the calibration 0x2022; a failed one, or a phase without
    /// current while running, raises motor open 0x7120; a "current does not follow" detection raises 0x5210; a trip of the fast
    /// protection raises over-current 0x2310 or over-voltage 0x3210. Both are events:
    /// the condition is reported gone at once, so a fault reset clears them (see the
    /// module docs of [`crate::current_supervisor`] for the retry).
    ///
    /// Until the first tune since power-up has finished (with 0x2013 = 1) the power-up
    /// self-test is running: the PDS stays in Not ready to switch on.
    pub fn current_report(&mut self, r: &CurrentReport) {
        if !self.power_up_tune_over {
            let running = self.params.get(Param::AutoTune) == 1
                && r.tune_seq == 0
                && matches!(r.tune, TuneStatus::Pending | TuneStatus::Running);
            self.power_up_tune_over = !running;
            self.cia402.set_self_test(running);
        }
        if r.tune_seq != self.seen_tune_seq {
            self.seen_tune_seq = r.tune_seq;
            self.tune_finished(r);
        }
        self.protection_events(r);
    }

    /// A tune finished (new `tune_seq`): its result into the parameters, or the fault
    /// of a failed one.
    fn tune_finished(&mut self, r: &CurrentReport) {
        match r.tune {
            TuneStatus::Done => {
                let t = r.tuned;
                self.params
                    .set_internal(Param::MotorResistance, i32::from(t.r_mohm));
                self.params
                    .set_internal(Param::MotorInductance, i32::from(t.l_uh));
                self.params.set_internal(Param::CurrentKp, i32::from(t.kp));
                self.params.set_internal(Param::CurrentKi, i32::from(t.ki));
                self.params.set_calibration(t.calibration);
            }
            TuneStatus::Failed(e) => {
                use foc::autotune::{Phase, TuneError};
                // No retry of the auto-tune by itself: a new 0x2013 write asks
                // for one. (With 0x2013 = 0 this was the first enable's phase
                // check, which a fault reset re-arms.)
                self.tune_failed = self.params.get(Param::AutoTune) == 1;
                // A calibration outside its band is the current sensing's fault
                // (0x5210, detail 2); the others are the motor's.
                let (kind, detail) = match e {
                    TuneError::OpenPhase(Phase::A) => (FaultKind::MotorOpen, [1, 0]),
                    TuneError::OpenPhase(Phase::B) => (FaultKind::MotorOpen, [1, 1]),
                    TuneError::Unbalanced => (FaultKind::MotorOpen, [2, 0]),
                    TuneError::Implausible => (FaultKind::MotorOpen, [3, 0]),
                    TuneError::Sensing => (FaultKind::PhaseSensing, [2, 0]),
                };
                let snap = self.snapshot();
                self.faults.raise_detail(kind, detail, snap, self.now_ms);
                self.faults.condition_gone(kind);
            }
            _ => {}
        }
    }

    /// The events of the running loop: a trip of the fast protection, a phase without
    /// current, current that does not follow.
    fn protection_events(&mut self, r: &CurrentReport) {
        if r.trip_seq != self.seen_trip_seq {
            // The current loop's fast protection switched the bridges off: the fault
            // with the sample it tripped on (the tick's checks then follow the
            // condition until it is gone).
            self.seen_trip_seq = r.trip_seq;
            let kind = match r.trip {
                crate::current_supervisor::Trip::OverVoltage => Some(FaultKind::OverVoltage),
                crate::current_supervisor::Trip::OverCurrent => Some(FaultKind::OverCurrent),
                crate::current_supervisor::Trip::None => None,
            };
            if let Some(kind) = kind {
                let snap = Snapshot {
                    ia_ma: r.trip_ia_ma,
                    ib_ma: r.trip_ib_ma,
                    bus_dv: r.trip_bus_dv,
                    ..self.snapshot()
                };
                // The trip has already latched the bridges off: reported whatever
                // 0x2056 says (a masked detection would leave the drive enabled with
                // no torque and nothing to see).
                self.faults.raise_unmaskable(kind, snap, self.now_ms);
            }
        }
        if r.open_seq != self.seen_open_seq {
            // A phase without current while running: motor open, detail 4 and the
            // phase (0 = A, 1 = B).
            self.seen_open_seq = r.open_seq;
            let phase = u8::from(r.open_phase == foc::autotune::Phase::B);
            let snap = self.snapshot();
            self.faults
                .raise_detail(FaultKind::MotorOpen, [4, phase], snap, self.now_ms);
            self.faults.condition_gone(FaultKind::MotorOpen);
        }
        if r.follow_seq != self.seen_follow_seq {
            self.seen_follow_seq = r.follow_seq;
            let snap = self.snapshot();
            self.faults.raise_detail(
                FaultKind::PhaseSensing,
                r.follow_ref_ma.to_le_bytes(),
                snap,
                self.now_ms,
            );
            self.faults.condition_gone(FaultKind::PhaseSensing);
        }
    }
}
