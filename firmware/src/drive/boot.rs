//! The firmware update on the drive's side ([`crate::update`]): attaching it, the
//! start-up checks that let a trial image confirm itself, the update's events as
//! diagnosis messages, and Bootstrap's power-stage stop.

use super::*;

impl<S: ParameterStore> Drive<S> {
    /// Gives the drive its firmware update ([`crate::update`]): FoE in Bootstrap, the
    /// boot state 0x2309, 0x100A from the running image's header, and the trial
    /// image's confirmation once [`Drive::startup_checks_done`] reported success and
    /// the runtime reached Pre-Op.
    pub fn attach_update(&mut self, update: &'static mut (dyn FirmwareUpdate + Send)) {
        self.monitor.set_boot_state(update.boot_state() as u8);
        self.update = Some(update);
    }

    /// The board's start-up checks (current-sensor offsets, the board self-test) are
    /// over: `passed` or not. A trial image is confirmed only after a pass.
    pub fn startup_checks_done(&mut self, passed: bool) {
        self.startup_checks = Some(passed);
    }

    /// An accepted update waits for the reset into the bootloader (set on Bootstrap →
    /// Init): the board resets; the simulation restarts the drive.
    pub fn reset_requested(&self) -> bool {
        self.reset_request
    }

    /// The update's housekeeping, every tick: its events as diagnosis messages, the
    /// boot state 0x2309. (No flash access here: the tick may run in an interrupt.)
    pub(super) fn update_housekeeping(&mut self) {
        let Some(u) = self.update.as_deref_mut() else {
            return;
        };
        if let Some(e) = u.take_event() {
            self.faults
                .diagnosis_mut()
                .push(crate::diagnosis::update_message(e, self.now_ms));
        }
        self.monitor.set_boot_state(u.boot_state() as u8);
    }

    /// Confirms a new image on trial (embassy-boot's `mark_booted`) once its start-up
    /// checks passed and the runtime reached Pre-Op, and only while the power stage
    /// is off: the confirmation writes embassy-boot's state partition, in the flash
    /// bank the code runs from, which stalls the current-loop interrupt for the page
    /// erase. Call it from thread mode, where the flash is used (the board's `ecat`
    /// task after `poll`); returns true when it confirmed now.
    pub fn confirm_update(&mut self) -> bool {
        // Not while the current auto-tune may drive the bridges either.
        let due = self.startup_checks == Some(true)
            && !self.command.power_stage
            && self.power_up_tune_over;
        let runtime_up = self.reached_preop;
        match self.update.as_deref_mut() {
            Some(u) => u.confirm(due, runtime_up),
            None => false,
        }
    }

    /// A stop ramp runs (quick stop or fault reaction).
    #[cold]
    pub(super) fn stopping(&self) -> bool {
        use crate::cia402::pds::PdsState;
        matches!(
            self.cia402.state(),
            PdsState::QuickStopActive | PdsState::FaultReactionActive
        )
    }

    /// Entering Bootstrap: the power stage goes off now unless a stop ramp runs (the
    /// 0x6007 reaction of the ESM change), in which case it goes off at its end.
    pub(super) fn bootstrap_stop(&mut self) {
        if !self.stopping() {
            self.command.power_stage = false;
            self.command.drive_enabled = false;
            self.command.brake_release = false;
            // The PDS leaves the enabled states (disable voltage, as with 0x6007 = 2):
            // leaving Bootstrap re-energises nothing without a new enable.
            self.cia402.set_controlword(0);
            self.react_now = true;
        }
    }
}
