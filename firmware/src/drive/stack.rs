//! The drive as the slave runtime sees it: the dictionary ([`Dictionary`]), the
//! cyclic data ([`ProcessData`]: CiA 402 slots plus the other TxPDO entries), the ESM
//! hooks and the application cycle ([`SlaveApplication`]).

use super::*;
use crate::dictionary::fault_history::FaultHistory;
use crate::dictionary::Owner;
use ecat_slave_stack::od::ObjectKey;

/// The whole dictionary as 'save' sees it: the drive's objects plus those the slave
/// runtime serves (mapping, assignment, sync).
pub(super) struct WholeDictionary<'a, S: ParameterStore> {
    pub(super) drive: &'a mut Drive<S>,
    pub(super) runtime: &'a mut dyn Dictionary,
}

pub(super) fn is_runtime_index(index: u16) -> bool {
    dictionary::owner_of(index) == Some(Owner::SlaveRuntime)
}

impl<S: ParameterStore> Dictionary for WholeDictionary<'_, S> {
    fn objects(&self) -> &'static [Object] {
        dictionary::OBJECTS
    }
    fn read(&mut self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        if is_runtime_index(key.index) {
            self.runtime.read(key, buf)
        } else {
            self.drive.read(key, buf)
        }
    }
    fn write(&mut self, key: ObjectKey, data: &[u8], state: EsmState) -> Result<(), SdoAbort> {
        if is_runtime_index(key.index) {
            self.runtime.write(key, data, state)
        } else {
            self.drive.write(key, data, state)
        }
    }
}

impl<S: ParameterStore> Dictionary for Drive<S> {
    fn objects(&self) -> &'static [Object] {
        dictionary::OBJECTS
    }

    fn read(&mut self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        let ObjectKey { index, sub } = key;
        if index == 0x10F3 {
            // Reading the newest diagnosis message clears "new messages available".
            od::find_entry(dictionary::OBJECTS, ObjectKey::new(index, sub))?;
            return self.faults.diagnosis_mut().read(sub, buf);
        }
        if let (0x100A, Some(v)) = (
            index,
            self.update.as_deref().and_then(|u| u.running_version()),
        ) {
            // The version of the running image's update header.
            od::find_entry(dictionary::OBJECTS, ObjectKey::new(index, sub))?;
            let n = crate::update::format_version(v, buf);
            return if n == 0 {
                Err(SdoAbort::ExceedsMailbox)
            } else {
                Ok(n)
            };
        }
        let r = self.read_entry(index, sub, buf);
        if index == crate::scope::DATA && r.is_ok() {
            // The normal-mode scope re-arms once its record's last block was read.
            self.scope.block_read(sub);
        }
        r
    }

    fn write(&mut self, key: ObjectKey, data: &[u8], _state: EsmState) -> Result<(), SdoAbort> {
        let ObjectKey { index, sub } = key;
        match dictionary::owner_of(index) {
            // Without the runtime's objects a save would miss the PDO mapping.
            Some(Owner::Comm) => self.write_comm(key, data, &mut NoRuntime),
            Some(Owner::Params) => {
                if (index, sub) == (0x2013, 0) && data.first() == Some(&1) {
                    // The current auto-tune energises the motor without an enable: only
                    // with the power stage off and the brake engaged, never in
                    // Bootstrap (`Drive::tune_permitted`).
                    if !self.tune_state_allows() {
                        return Err(SdoAbort::StateConflict);
                    }
                    dictionary::write(&mut self.params, &mut (), key, data)?;
                    // A new request: a failed tune may run again.
                    self.tune_failed = false;
                    self.faults.configure_from(&self.params);
                    return Ok(());
                }
                dictionary::write(&mut self.params, &mut (), key, data)?;
                if index == 0x2001 {
                    // 0x6091-0x6093 show the new value.
                    let units = self.params.get(crate::params::Param::PulsesPerRev) as u32;
                    self.cia402.set_scaling_units(units);
                }
                if let Some(start) = self.params.take_servo_tune_request() {
                    return self.servo_tune_command(start);
                }
                self.faults.configure_from(&self.params);
                // 0x2024 decides whether CST is available, 0x2024 / 0x2060 whether
                // stall homing is.
                self.control_config_changed();
                Ok(())
            }
            Some(Owner::Monitor) => dictionary::write(&mut self.monitor, &mut (), key, data),
            Some(Owner::Scope) => dictionary::write(&mut self.scope, &mut (), key, data),
            Some(Owner::Cia402) if (0x6091..=0x6093).contains(&index) => {
                // The scaling views: a whole result goes to 0x2001 (its range
                // decides), then the other views follow (`cia402::scaling`).
                dictionary::write(&mut self.cia402, &mut (), key, data)?;
                if let Some(units) = self.cia402.scaling_candidate() {
                    let k = ObjectKey::new(0x2001, 0);
                    if dictionary::write(&mut self.params, &mut (), k, &units.to_le_bytes()).is_ok()
                    {
                        self.cia402.settle_scaling();
                    }
                }
                Ok(())
            }
            Some(Owner::Cia402) => dictionary::write(&mut self.cia402, &mut (), key, data),
            Some(Owner::Faults | Owner::SlaveRuntime) | None => Err(SdoAbort::WriteReadOnly),
        }
    }

    fn write_with_runtime(
        &mut self,
        key: ObjectKey,
        data: &[u8],
        state: EsmState,
        runtime: &mut dyn Dictionary,
    ) -> Result<(), SdoAbort> {
        let ObjectKey { index, sub } = key;
        if dictionary::owner_of(index) == Some(Owner::Comm) {
            return self.write_comm(ObjectKey::new(index, sub), data, runtime);
        }
        self.write(key, data, state)
    }
}

/// Stand-in for the slave runtime's objects where there is no runtime (no ESC on the
/// board) or a write does not come through it: the product's objects, none of the
/// runtime's (a save through it keeps no PDO mapping).
pub struct NoRuntime;

impl Dictionary for NoRuntime {
    fn objects(&self) -> &'static [Object] {
        dictionary::OBJECTS
    }
    fn read(&mut self, _key: ObjectKey, _buf: &mut [u8]) -> Result<usize, SdoAbort> {
        Err(SdoAbort::ObjectDoesNotExist)
    }
    fn write(&mut self, _key: ObjectKey, _data: &[u8], _state: EsmState) -> Result<(), SdoAbort> {
        Err(SdoAbort::ObjectDoesNotExist)
    }
}

/// Slots of TxPDO-mappable entries outside the CiA 402 range start here; they are
/// served through the dictionary read (not a hot path: the default maps use none).
pub(super) const OTHER_TX_SLOT: u16 = 0x8000;
/// Highest number of such entries.
const OTHER_TX_MAX: usize = 32;

pub(super) fn other_tx_entries() -> impl Iterator<Item = (u16, u8)> {
    dictionary::OBJECTS
        .iter()
        .filter(|o| dictionary::owner_of(o.index) != Some(Owner::Cia402))
        .flat_map(|o| {
            o.entries()
                .iter()
                .filter(|e| e.pdo_mappable().tx())
                .map(move |e| (o.index, e.sub))
        })
        .take(OTHER_TX_MAX)
}

/// Slots of RxPDO-mappable vendor parameters (such as 0x2000) start here, numbered
/// as `params::KEYS`; a mapped value goes through the SDO write (same checks: a value
/// the SDO write would refuse is not taken over).
pub(super) const OTHER_RX_SLOT: u16 = 0x8000;

/// Entry number `n` of [`other_tx_entries`]: a plain walk (the chain's generic
/// `Iterator::nth` is three times as large).
// Measured (cargo xtask size, LAN9252 image): dropped with the other hot-path attributes
// the image grew 1184 B; this, `set_rx_other` and `sample_scope` inline into the PDO paths.
#[inline(never)]
pub(super) fn other_tx_entry(n: usize) -> Option<(u16, u8)> {
    for (k, e) in other_tx_entries().enumerate() {
        if k == n {
            return Some(e);
        }
    }
    None
}

impl<S: ParameterStore> ProcessData for Drive<S> {
    fn rx_slot(&self, key: ObjectKey) -> Option<u16> {
        let ObjectKey { index, sub } = key;
        if dictionary::owner_of(index) == Some(Owner::Cia402) {
            return ProcessData::rx_slot(&self.cia402, key);
        }
        if dictionary::owner_of(index) != Some(Owner::Params) {
            return None;
        }
        let e = od::find_entry(dictionary::OBJECTS, ObjectKey::new(index, sub)).ok()?;
        if !e.pdo_mappable().rx() {
            return None;
        }
        crate::params::slot_of(index, sub).map(|n| OTHER_RX_SLOT + n as u16)
    }

    fn tx_slot(&self, key: ObjectKey) -> Option<u16> {
        let ObjectKey { index, sub } = key;
        if dictionary::owner_of(index) == Some(Owner::Cia402) {
            return ProcessData::tx_slot(&self.cia402, key);
        }
        other_tx_entries()
            .position(|k| k == (index, sub))
            .map(|n| OTHER_TX_SLOT + n as u16)
    }

    #[inline]
    fn set_rx(&mut self, slot: u16, raw: u64) {
        if slot < OTHER_RX_SLOT {
            return ProcessData::set_rx(&mut self.cia402, slot, raw);
        }
        self.set_rx_other(slot - OTHER_RX_SLOT, raw);
    }

    #[inline]
    fn get_tx(&self, slot: u16) -> u64 {
        if slot < OTHER_TX_SLOT {
            return ProcessData::get_tx(&self.cia402, slot);
        }
        let Some((index, sub)) = other_tx_entry(usize::from(slot - OTHER_TX_SLOT)) else {
            return 0;
        };
        let mut buf = [0u8; 8];
        // (`other_tx_entry` never names a 0x6xxx entry.)
        match self.read_entry(index, sub, &mut buf) {
            Ok(_) => u64::from_le_bytes(buf),
            Err(_) => 0,
        }
    }
}

impl<S: ParameterStore> Drive<S> {
    /// An RxPDO entry outside 0x6xxx (a vendor parameter): the SDO write's checks
    /// decide; a refused value is not taken over (a PDO write cannot be answered with
    /// an abort).
    // Measured (cargo xtask size, LAN9252 image): dropped with the other hot-path
    // attributes the image grew 1184 B; see `other_tx_entry`.
    #[inline(never)]
    fn set_rx_other(&mut self, n: u16, raw: u64) {
        let Some(&(index, sub)) = crate::params::KEYS.get(usize::from(n)) else {
            return;
        };
        // (`KEYS` holds vendor parameters only.)
        if let Ok(e) = od::find_entry(dictionary::OBJECTS, ObjectKey::new(index, sub)) {
            if e.pdo_mappable().rx() {
                let bytes = raw.to_le_bytes();
                let len = e.byte_len().min(8);
                let _ = Dictionary::write(
                    self,
                    ObjectKey::new(index, sub),
                    &bytes[..len],
                    EsmState::Op,
                );
            }
        }
    }

    /// SDO read of a product entry, dispatched on the owner of the index (the
    /// dictionary read and the TxPDO entries outside 0x6xxx share it): the owner's
    /// `Values` through [`dictionary::read`].
    pub(super) fn read_entry(
        &self,
        index: u16,
        sub: u8,
        buf: &mut [u8],
    ) -> Result<usize, SdoAbort> {
        let key = ObjectKey::new(index, sub);
        match dictionary::owner_of(index) {
            Some(Owner::Comm) => dictionary::read(&self.comm, &self.faults, key, buf),
            Some(Owner::Params) => dictionary::read(&self.params, &(), key, buf),
            Some(Owner::Monitor) => dictionary::read(&self.monitor, &(), key, buf),
            Some(Owner::Faults) => dictionary::read(&FaultHistory(&self.faults), &(), key, buf),
            Some(Owner::Scope) => self.read_scope(key, buf),
            Some(Owner::Cia402) => dictionary::read(&self.cia402, &(), key, buf),
            Some(Owner::SlaveRuntime) | None => Err(SdoAbort::ObjectDoesNotExist),
        }
    }

    /// SDO write of a communication object; a store / restore command it decoded runs
    /// against the whole dictionary (`runtime`: the slave runtime's objects).
    fn write_comm(
        &mut self,
        key: ObjectKey,
        data: &[u8],
        runtime: &mut dyn Dictionary,
    ) -> Result<(), SdoAbort> {
        match dictionary::write_comm(&mut self.comm, &mut self.faults, key, data)? {
            Some(cmd) => self.run_store(cmd, runtime),
            None => Ok(()),
        }
    }

    /// The master's commands stopped: the ESM left Op (requested or forced), the
    /// outputs were lost (SM watchdog) or SYNC0 stopped. Applies 0x6007
    /// ([`Cia402::on_connection_lost`]); the reaction then runs on the drive's own
    /// clock (every [`Drive::tick`]). While the motor side aligns for transition 4 the
    /// PDS drops to Switch on disabled (no drive function yet: no fault). With the
    /// drive function enabled, 0x6007 = 1 raises the EtherCAT fault `code` with `diag`
    /// (emergency, history; an event, so a fault reset may clear it); 2 and 3 send the
    /// emergency `code` without a fault; 0 does nothing.
    fn left_op(&mut self, code: u16, diag: [u8; 2]) {
        use crate::cia402::pds::PdsState;
        let before = self.cia402.state();
        let had_function = matches!(
            before,
            PdsState::OperationEnabled | PdsState::QuickStopActive
        ) && !self.cia402.enable_waiting();
        let option = self.cia402.on_connection_lost(code);
        // The master's cycles are over: the reaction starts at the next tick. A PDS
        // that lost its voltage here (0x6007 = 2) shows it at once (statusword, power
        // off, brake engaged): a step of no length.
        self.last_cycle_us = None;
        self.react_now = option != AbortConnection::NoAction;
        if self.cia402.state() != before && !self.cia402.state().voltage_enabled() {
            self.control_step(1e-6, SetpointArrival::Stale);
        }
        // Reported once: a second report of the same loss (the outputs lost, then the
        // ESM change) finds the reaction already running.
        if !had_function || self.cia402.state() == before {
            return;
        }
        match option {
            AbortConnection::NoAction => {}
            AbortConnection::Fault => {
                self.faults.raise_ecat(code, diag, self.now_ms);
                self.faults.condition_gone(FaultKind::Ecat);
            }
            AbortConnection::DisableVoltage | AbortConnection::QuickStop => {
                self.faults.notify(code, diag);
            }
        }
    }
}

impl<S: ParameterStore> EsmHooks for Drive<S> {
    fn on_state_change(&mut self, from: EsmState, to: EsmState) {
        self.esm = to;
        if matches!(to, EsmState::PreOp | EsmState::SafeOp | EsmState::Op) {
            self.reached_preop = true;
        }
        if from == EsmState::Op && to != EsmState::Op {
            let code = if to == EsmState::Init { 0xA000 } else { 0xA001 };
            self.left_op(code, [from.bits(), to.bits()]);
        } else if matches!(to, EsmState::Init | EsmState::Bootstrap)
            && matches!(from, EsmState::PreOp | EsmState::SafeOp)
        {
            // An axis enabled outside Op (by SDO) loses its master's configuration:
            // the 0x6007 reaction, as for the loss of Op.
            self.left_op(0xA000, [from.bits(), to.bits()]);
        }
        if to == EsmState::Bootstrap {
            // Nothing of the motion survives the Bootstrap: the power stage goes off
            // once a running stop has ended (`Drive::control_step`), at once when
            // nothing stops.
            self.bootstrap_stop();
        }
        if to == EsmState::Init {
            self.cia402.on_esm_init();
        }
    }

    fn on_leave_bootstrap(&mut self) {
        if self.update.as_deref().is_some_and(|u| u.accepted()) {
            self.reset_request = true;
        }
    }
}

impl<S: ParameterStore> SlaveApplication for Drive<S> {
    /// The master's cycle: the set-points it brought take effect in a control step
    /// now (the supervision tick steps the drive as well, on its own clock).
    fn cycle(&mut self, info: &CycleInfo) {
        let now = info.now_us as Stamp;
        if let Some(t) = self.last_cycle_us {
            self.cycle_period_us = elapsed_us(now, t).unwrap_or(0);
        }
        self.last_cycle_us = Some(now);
        let arrival = if info.outputs_fresh {
            SetpointArrival::Fresh
        } else {
            SetpointArrival::Stale
        };
        self.step_at(now, arrival);
    }

    fn on_outputs_lost(&mut self, code: AlStatusCode) {
        self.left_op(ERR_COMMUNICATION_LOST, code.code().to_le_bytes());
    }

    fn sync_error_limit(&self) -> u16 {
        self.comm.sync_error_limit()
    }

    fn foe(&mut self) -> Option<&mut dyn FoeFiles> {
        match self.update.as_deref_mut() {
            Some(u) => Some(u),
            None => None,
        }
    }
}

/// True when `index` is stored by 'save' somewhere in the dictionary (for tests and
/// the storage layout documentation).
pub fn is_saved(index: u16, sub: u8) -> bool {
    od::find_entry(dictionary::OBJECTS, ObjectKey::new(index, sub)).is_ok_and(|e| e.is_saved())
}
