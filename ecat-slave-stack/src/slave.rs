//! The slave runtime: ties the ESC, the state machine, the mailbox, the process data
//! and the synchronisation together.
//!
//! ```text
//! let mut slave = Slave::new(esc, SlaveConfig { .. });
//! slave.init()?;
//! loop {
//!     slave.poll(&mut app, now_us)?;      // main loop / ESC IRQ
//! }
//! // DC SYNC0 interrupt (optional, instead of letting poll() see the SYNC0 event):
//! slave.cycle(&mut app, now_us)?;
//! ```
//!
//! [`Slave::poll`] reads the AL event request register once and then handles, in this
//! order: AL control (ESM requests and their checks), SyncManager activation changes
//! (mailbox repeat request, process-data SM switched off), supervision (pending S→O
//! waiting for the SYNC0 lock, process-data watchdog, SYNC0 missing, application
//! error; in Safe-Op also the DC registers 0x0981/0x09A0, for masters that arm SYNC0
//! after requesting Safe-Op — see [`crate::sync`]), the mailbox (SM0 received → [`MailboxServer::on_request`], SM1 free →
//! [`MailboxServer::next_output`]) and, in Safe-Op/Op, the process data: SM2 event →
//! outputs read; the cycle (unpack → [`SlaveApplication::cycle`] → pack → SM3) runs
//! per SM2 event (SM-synchronous), per local period (free run) or per SYNC0 (DC).
//! Outputs are handed to the application only in Op.
//!
//! In DC SYNC0 mode every SYNC0 must be seen on its own: call [`Slave::cycle`] from
//! the SYNC0 interrupt, or [`Slave::poll`] at least once per SYNC0 period (coalesced
//! SYNC0 events look like a wrong period and the slave never locks → 0x002D).
//!
//! Bootstrap ([`SlaveConfig::bootstrap`], off by default): Init→Boot checks SM0/SM1
//! against the product's [`BootMailbox`] (0x0015 otherwise) and starts the mailbox
//! with FoE only — CoE requests answer the mailbox error "protocol not supported", no
//! process data; [`EsmHooks::on_enter_bootstrap`] / [`EsmHooks::on_leave_bootstrap`]
//! tell the application.
//!
//! FoE: mailbox type 4 goes to [`SlaveApplication::foe`] ([`crate::foe`]); an
//! application without files keeps answering "protocol not supported". A FoE
//! transfer is aborted when the mailbox stops (→ Init) and after
//! [`SlaveConfig::foe_timeout_us`] without a request.
//!
//! Objects 0x1600-0x1C33 and the timing diagnostics object
//! ([`SlaveConfig::timing_diag_index`]) are served by the runtime itself (its
//! [`PdoConfig`] and [`SyncState`]); every other index goes to the application's
//! [`Dictionary`] ([`CommDictionary`]).

use crate::al_status::AlStatusCode;
use crate::esc::{EscAccess, EscError};
use crate::esm::{Decision, Esm, EsmHooks, EsmState};
use crate::foe::FoeFiles;
use crate::mailbox::{Frame as MailboxFrame, Handlers, MailboxServer, MailboxType};
use crate::od::{Dictionary, Object, ObjectKey, SdoAbort};
use crate::pdo::{self, CopyPlan, PdoConfig, PdoDefaults, ProcessData};
use crate::registers::{self as reg, AlControl, AlEvent};
use crate::sm::{self, BootMailbox, MailboxLimits, PdDirection, RamWindow, SmRegs};
use crate::sync::{self, SyncEvent, SyncMode, SyncState};

mod dc;
mod mailbox;
mod objects;
mod process_data;
pub use objects::{CommDictionary, RuntimeObjects};

/// Longest time between two reads of the process-data watchdog status, µs.
pub const WD_CHECK_US: u64 = 1000;

/// Largest mailbox SyncManager handled.
pub const MAX_MAILBOX: usize = crate::mailbox::MAX_MAILBOX_SIZE;

/// What the application gives the runtime: its dictionary, its cyclic data, the ESM
/// hooks ([`EsmHooks::on_state_change`] carries the CiA 402 coupling), and a few
/// optional callbacks.
pub trait SlaveApplication: Dictionary + ProcessData + EsmHooks {
    /// One application cycle, between unpacking the outputs and packing the inputs.
    fn cycle(&mut self, info: &CycleInfo) {
        let _ = info;
    }
    /// Fresh outputs stopped (process-data watchdog 0x001B, SYNC0 lost 0x002C /
    /// 0x0032, sync error 0x001A): apply the communication-loss reaction now. The
    /// ESM change itself is reported through [`EsmHooks::on_state_change`] too.
    fn on_outputs_lost(&mut self, code: AlStatusCode) {
        let _ = code;
    }
    /// Device identification value (AL control bit 5); `None` = the station alias
    /// register 0x0012.
    fn device_id(&mut self) -> Option<u16> {
        None
    }
    /// A local error that must take the slave out of Op (e.g. supply voltage); the
    /// S→O transition is refused with it while it is pending. Drive faults are not ESM
    /// errors: a PDS state change never changes the ESM state.
    fn local_error(&mut self) -> Option<AlStatusCode> {
        None
    }
    /// 0x10F1:02, the sync error counter limit.
    fn sync_error_limit(&self) -> u16 {
        4
    }
    /// A µs clock for the computation-time diagnostic; `None` = not measured.
    fn now_us(&mut self) -> Option<u64> {
        None
    }
    /// The files served over FoE (mailbox type 4), e.g. the firmware image writer;
    /// `None` (the default): FoE requests answer the mailbox error "protocol not
    /// supported".
    fn foe(&mut self) -> Option<&mut dyn FoeFiles> {
        None
    }
}

/// What one cycle is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CycleInfo {
    /// ESM state.
    pub state: EsmState,
    /// New outputs were unpacked into the application in this cycle (Op only).
    pub outputs_fresh: bool,
    /// Synchronisation mode.
    pub mode: SyncMode,
    /// Time of the cycle (caller's clock, µs).
    pub now_us: u64,
}

/// Product configuration of the runtime.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SlaveConfig {
    /// Written into 0x0012 by [`Slave::init`] (from DIP switches or 0x2150).
    pub station_alias: Option<u16>,
    /// Mailbox limits checked at I→P.
    pub mailbox_limits: MailboxLimits,
    /// Default PDO mapping and assignment.
    pub pdo_defaults: PdoDefaults,
    /// Calc-and-copy times reported in 0x1C32:06 / 0x1C33:06, ns.
    pub calc_copy_ns: (u32, u32),
    /// Shortest DC SYNC0 cycle the product supports (0x1C32:05), ns: 125 000 by
    /// default; 62 500 also accepts the 62.5 µs cycle.
    pub min_cycle_ns: u32,
    /// Bootstrap support with this mailbox layout (the SII words 0x14–0x17 must say
    /// the same); `None` (default): Init→Boot is refused with 0x0013.
    pub bootstrap: Option<BootMailbox>,
    /// A FoE transfer without a request for this long is aborted, µs (default
    /// [`crate::foe::DEFAULT_TIMEOUT_US`], 10 s; applied by [`Slave::init`]).
    pub foe_timeout_us: u64,
    /// Index at which the runtime serves the timing diagnostics object (the product
    /// lists [`sync::timing_diag_object`] of the same index); `None` (default): none.
    pub timing_diag_index: Option<u16>,
}

impl Default for SlaveConfig {
    fn default() -> Self {
        SlaveConfig {
            station_alias: None,
            mailbox_limits: MailboxLimits::ANY,
            pdo_defaults: PdoDefaults::EMPTY,
            calc_copy_ns: (0, 0),
            min_cycle_ns: sync::MIN_CYCLE_NS,
            bootstrap: None,
            foe_timeout_us: crate::foe::DEFAULT_TIMEOUT_US,
            timing_diag_index: None,
        }
    }
}

/// ESC information registers 0x0000-0x0009.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EscInfo {
    /// 0x0000.
    pub esc_type: u8,
    /// 0x0001.
    pub revision: u8,
    /// 0x0002.
    pub build: u16,
    /// 0x0004.
    pub fmmus: u8,
    /// 0x0005.
    pub sync_managers: u8,
    /// 0x0006, KiB.
    pub ram_kib: u8,
    /// 0x0008.
    pub features: u16,
}

enum Step {
    Done(Result<(), AlStatusCode>),
    Pending,
}

/// The slave runtime over any [`EscAccess`].
pub struct Slave<E: EscAccess> {
    esc: E,
    cfg: SlaveConfig,
    info: EscInfo,
    ram: RamWindow,
    esm: Esm,
    pdo: PdoConfig,
    sync: SyncState,
    plan: CopyPlan,
    mbx: MailboxServer,
    sms: [SmRegs; 4],
    /// SM0/SM1 as validated at I→P, SM2/SM3 as validated at P→S: the buffers the
    /// runtime accesses (never a configuration it has not checked).
    active: [SmRegs; 4],
    station: u16,
    rx_buf: [u8; pdo::MAX_BYTES],
    tx_buf: [u8; pdo::MAX_BYTES],
    mbx_buf: [u8; MAX_MAILBOX],
    sm1_busy: bool,
    repeat_ack: bool,
    outputs_fresh: bool,
    outputs_seen: bool,
    wd_armed: bool,
    last_wd_check: u64,
    pending_since: u64,
    last_status: Option<(u16, u16)>,
    /// What the DC registers seen in Safe-Op are refused with at S→O.
    dc_refusal: Option<AlStatusCode>,
    last_dc_check: u64,
}

impl<E: EscAccess> Slave<E> {
    /// A runtime in Init; no ESC access until [`Slave::init`].
    pub fn new(esc: E, cfg: SlaveConfig) -> Self {
        Slave {
            esc,
            info: EscInfo::default(),
            ram: RamWindow::from_kib(4),
            esm: Esm::with_bootstrap(cfg.bootstrap.is_some()),
            pdo: PdoConfig::new(cfg.pdo_defaults),
            sync: SyncState {
                min_cycle_ns: cfg.min_cycle_ns,
                diag_index: cfg.timing_diag_index,
                ..SyncState::new(cfg.calc_copy_ns)
            },
            plan: CopyPlan::EMPTY,
            mbx: MailboxServer::new(128),
            sms: [SmRegs::default(); 4],
            active: [SmRegs::default(); 4],
            station: 0,
            rx_buf: [0; pdo::MAX_BYTES],
            tx_buf: [0; pdo::MAX_BYTES],
            mbx_buf: [0; MAX_MAILBOX],
            sm1_busy: false,
            repeat_ack: false,
            outputs_fresh: false,
            outputs_seen: false,
            wd_armed: false,
            last_wd_check: 0,
            pending_since: 0,
            last_status: None,
            dc_refusal: None,
            last_dc_check: 0,
            cfg,
        }
    }

    /// Sets the station alias [`Slave::init`] writes into 0x0012 (`None`: keep the
    /// value the ESC loaded from the SII). For products whose alias comes from stored
    /// parameters, which are loaded through [`Slave::runtime_objects`] after
    /// [`Slave::new`].
    pub fn set_station_alias(&mut self, alias: Option<u16>) {
        self.cfg.station_alias = alias;
    }

    /// Reads the ESC information, writes the alias (if configured), the AL event mask
    /// and AL status Init without error; applies the FoE timeout.
    pub fn init(&mut self) -> Result<EscInfo, EscError> {
        let mut b = [0u8; 10];
        self.esc.read(reg::ESC_TYPE.addr(), &mut b)?;
        self.info = EscInfo {
            esc_type: b[0],
            revision: b[1],
            build: u16::from_le_bytes([b[2], b[3]]),
            fmmus: b[4],
            sync_managers: b[5],
            ram_kib: b[6],
            features: u16::from_le_bytes([b[8], b[9]]),
        };
        self.ram = RamWindow::from_kib(self.info.ram_kib);
        if let Some(a) = self.cfg.station_alias {
            self.esc.set(reg::STATION_ALIAS, a)?;
        }
        self.esm = Esm::with_bootstrap(self.cfg.bootstrap.is_some());
        self.mbx.set_foe_timeout_us(self.cfg.foe_timeout_us);
        self.last_status = None;
        self.write_event_mask()?;
        self.write_status()?;
        Ok(self.info)
    }

    /// Current ESM state.
    pub fn state(&self) -> EsmState {
        self.esm.state()
    }
    /// The AL status (state, error, code).
    pub fn esm(&self) -> &Esm {
        &self.esm
    }
    /// ESC information read by [`Slave::init`].
    pub fn esc_info(&self) -> EscInfo {
        self.info
    }
    /// The ESC.
    pub fn esc_mut(&mut self) -> &mut E {
        &mut self.esc
    }
    /// Mapping and assignment.
    pub fn pdo(&self) -> &PdoConfig {
        &self.pdo
    }
    /// Mapping and assignment (e.g. restore defaults on 0x1011).
    pub fn pdo_mut(&mut self) -> &mut PdoConfig {
        &mut self.pdo
    }
    /// Sync state, 0x1C32/0x1C33 and diagnostics.
    pub fn sync(&self) -> &SyncState {
        &self.sync
    }
    /// The compiled copy plan (valid in Safe-Op/Op).
    pub fn plan(&self) -> &CopyPlan {
        &self.plan
    }
    /// Station address read at I→P.
    pub fn station_address(&self) -> u16 {
        self.station
    }
    /// The dictionary as the mailbox sees it (communication objects first).
    pub fn dictionary<'a, A: Dictionary + ?Sized>(
        &'a mut self,
        app: &'a mut A,
    ) -> CommDictionary<'a, A> {
        CommDictionary {
            pdo: &mut self.pdo,
            sync: &mut self.sync,
            app,
        }
    }
    /// The objects this runtime serves (mapping, assignment, sync) as a dictionary, for
    /// the parameter store at power-up; `objects` is the whole product table.
    pub fn runtime_objects(&mut self, objects: &'static [Object]) -> RuntimeObjects<'_> {
        RuntimeObjects {
            pdo: &mut self.pdo,
            sync: &mut self.sync,
            objects,
        }
    }

    /// Queues an emergency message (sent when SM1 is free, in Pre-Op and above). In
    /// Bootstrap, whose mailbox serves FoE only, the message is dropped.
    pub fn emergency(&mut self, error_code: u16, error_register: u8, data: [u8; 5]) {
        if self.esm.state() == EsmState::Bootstrap {
            return;
        }
        self.mbx.emergency(error_code, error_register, data);
    }
    /// Emergencies dropped because the mailbox's emergency queue was full.
    pub fn emergency_overruns(&self) -> u32 {
        self.mbx.emergency_overruns()
    }

    /// One pass of the runtime (module docs).
    pub fn poll<A: SlaveApplication>(&mut self, app: &mut A, now_us: u64) -> Result<(), EscError> {
        // Before the AL event request is read: a switch to DC mode acknowledges a
        // SYNC0 event left from SM-synchronous operation, which then runs no cycle.
        if self.esm.state() == EsmState::SafeOp {
            self.follow_dc(now_us, false)?;
        }
        let ev = AlEvent::from_raw(self.esc.al_event()?);
        if ev.al_control {
            self.handle_al_control(app, now_us)?;
        }
        if ev.sm_change {
            self.handle_sm_change(app)?;
        }
        self.supervise(app, ev, now_us)?;
        if self.esm.state().mailbox_running() {
            if ev.sm(0) {
                self.receive_mailbox(app, now_us)?;
            }
            self.mbx.tick(now_us);
            if self.mbx.foe_active().is_some() {
                if let Some(files) = app.foe() {
                    self.mbx.foe_tick(now_us, files);
                }
            }
            self.send_mailbox(now_us)?;
        }
        if self.esm.state().process_data_running() {
            self.process_data(app, ev, now_us, false)?;
        }
        self.write_status()
    }

    /// One process-data cycle triggered from outside (DC SYNC0 interrupt, or a
    /// free-run timer): acknowledges SYNC0, takes new outputs if the master wrote
    /// them, runs the cycle. Does nothing outside Safe-Op/Op.
    pub fn cycle<A: SlaveApplication>(&mut self, app: &mut A, now_us: u64) -> Result<(), EscError> {
        if !self.esm.state().process_data_running() {
            return Ok(());
        }
        let ev = AlEvent::from_raw(self.esc.al_event()?);
        self.process_data(app, ev, now_us, true)?;
        self.write_status()
    }

    // ---- ESM -------------------------------------------------------------------

    fn handle_al_control<A: SlaveApplication>(
        &mut self,
        app: &mut A,
        now: u64,
    ) -> Result<(), EscError> {
        let ctl = self.esc.get(reg::AL_CONTROL)?;
        let before = self.esm.state();
        match self.esm.request(ctl) {
            Decision::None | Decision::Refuse { .. } => {}
            Decision::Transition { from, to } => match self.transition(app, from, to, now)? {
                Step::Done(r) => {
                    self.esm.finish(from, to, r);
                }
                Step::Pending => {
                    self.esm.set_pending(to);
                    self.pending_since = now;
                }
            },
        }
        let id = if AlControl::from_raw(ctl).id_request {
            match app.device_id() {
                Some(id) => id,
                None => self.esc.get(reg::STATION_ALIAS)?,
            }
        } else {
            0
        };
        self.esm.id_request(ctl, id);
        self.state_changed(app, before)
    }

    fn transition<A: SlaveApplication>(
        &mut self,
        app: &mut A,
        from: EsmState,
        to: EsmState,
        now: u64,
    ) -> Result<Step, EscError> {
        use EsmState::*;
        Ok(match (from, to) {
            (Init, PreOp) => Step::Done(self.start_mailbox()?),
            (Init, Bootstrap) => Step::Done(self.start_boot_mailbox()?),
            (PreOp, SafeOp) => Step::Done(self.start_process_data(app)?),
            (SafeOp, Op) => {
                self.follow_dc(now, true)?;
                if let Some(code) = self.dc_refusal {
                    Step::Done(Err(code))
                } else if let Some(code) = app.local_error() {
                    Step::Done(Err(code))
                } else if self.sync.mode == SyncMode::DcSync0 && !self.sync.sup.locked() {
                    Step::Pending
                } else {
                    Step::Done(Ok(()))
                }
            }
            _ => Step::Done(Ok(())),
        })
    }

    fn read_sms(&mut self) -> Result<(), EscError> {
        let mut b = [0u8; 32];
        self.esc.read(reg::SM_BASE, &mut b)?;
        for (n, s) in self.sms.iter_mut().enumerate() {
            *s = SmRegs::from_block(&b, n);
        }
        Ok(())
    }

    fn start_mailbox(&mut self) -> Result<Result<(), AlStatusCode>, EscError> {
        self.station = self.esc.get(reg::STATION_ADDRESS)?;
        self.read_sms()?;
        let [sm0, sm1, sm2, sm3] = self.sms;
        if let Err(c) =
            sm::validate_mailbox(&sm0, &sm1, &[sm2, sm3], &self.cfg.mailbox_limits, self.ram)
        {
            return Ok(Err(c));
        }
        self.activate_mailbox(sm0, sm1)?;
        Ok(Ok(()))
    }

    /// I→B: SM0/SM1 must be the bootstrap mailbox of the configuration.
    fn start_boot_mailbox(&mut self) -> Result<Result<(), AlStatusCode>, EscError> {
        let Some(boot) = self.cfg.bootstrap else {
            return Ok(Err(AlStatusCode::BootstrapNotSupported));
        };
        self.station = self.esc.get(reg::STATION_ADDRESS)?;
        self.read_sms()?;
        let [sm0, sm1, _, _] = self.sms;
        if let Err(c) = sm::validate_boot_mailbox(&sm0, &sm1, &boot, self.ram) {
            return Ok(Err(c));
        }
        self.activate_mailbox(sm0, sm1)?;
        Ok(Ok(()))
    }

    /// Takes validated SM0/SM1 into use and starts the mailbox.
    fn activate_mailbox(&mut self, sm0: SmRegs, sm1: SmRegs) -> Result<(), EscError> {
        self.active[0] = sm0;
        self.active[1] = sm1;
        self.mbx
            .set_mailbox_sizes(sm0.len as usize, sm1.len as usize);
        self.sm1_busy = false;
        self.repeat_ack = sm1.repeat_request();
        // Make sure neither mailbox SM is deactivated from the PDI side; start the
        // repeat handshake from the master's current toggle value.
        self.esc.write_u8(
            reg::sm_register(0) + reg::sm::PDI_CONTROL,
            sm::PdiControl::new(false, false).0,
        )?;
        let ack = sm::PdiControl::new(false, self.repeat_ack);
        self.esc
            .write_u8(reg::sm_register(1) + reg::sm::PDI_CONTROL, ack.0)
    }

    fn start_process_data<A: SlaveApplication>(
        &mut self,
        app: &mut A,
    ) -> Result<Result<(), AlStatusCode>, EscError> {
        self.read_sms()?;
        let [sm0, sm1, sm2, sm3] = self.sms;
        let plan = match self.pdo.compile(app, app.objects()) {
            Ok(p) => p,
            Err(c) => return Ok(Err(c)),
        };
        let rx = plan.rx.bytes();
        let tx = plan.tx.bytes();
        if let Err(c) =
            sm::validate_process_data(&sm2, PdDirection::Outputs, rx, &[sm0, sm1, sm3], self.ram)
        {
            return Ok(Err(c));
        }
        if let Err(c) =
            sm::validate_process_data(&sm3, PdDirection::Inputs, tx, &[sm0, sm1, sm2], self.ram)
        {
            return Ok(Err(c));
        }
        let (mode, cycle, wd_time) = match self.derive_sync(&sm2, rx > 0)? {
            Ok(d) => d,
            Err(c) => return Ok(Err(c)),
        };
        self.plan = plan;
        self.active[2] = sm2;
        self.active[3] = sm3;
        self.dc_refusal = None;
        self.enter_sync(mode, cycle, rx > 0)?;
        self.wd_armed = rx > 0 && wd_time != 0;
        self.outputs_fresh = false;
        self.outputs_seen = false;
        self.rx_buf = [0; pdo::MAX_BYTES];
        self.tx_buf = [0; pdo::MAX_BYTES];
        // First inputs, so the master never reads an undefined image.
        self.write_inputs(app)?;
        Ok(Ok(()))
    }

    /// Side effects of a state change (both directions) and the application hook.
    fn state_changed<A: SlaveApplication>(
        &mut self,
        app: &mut A,
        before: EsmState,
    ) -> Result<(), EscError> {
        let after = self.esm.state();
        if after == before {
            return Ok(());
        }
        if before.process_data_running() && !after.process_data_running() {
            self.sync.leave();
            self.plan = CopyPlan::EMPTY;
            self.wd_armed = false;
            self.outputs_fresh = false;
        }
        if before.mailbox_running() && !after.mailbox_running() {
            if let Some(files) = app.foe() {
                self.mbx.foe_abort(files);
            }
            self.mbx.reset();
            self.sm1_busy = false;
            self.sync.reset_written();
        }
        if before == EsmState::Op {
            self.outputs_fresh = false;
        }
        self.write_event_mask()?;
        app.on_state_change(before, after);
        if after == EsmState::Bootstrap {
            app.on_enter_bootstrap();
        } else if before == EsmState::Bootstrap {
            // The hook may reset the device: the master must see Init first.
            self.write_status()?;
            app.on_leave_bootstrap();
        }
        Ok(())
    }

    fn write_event_mask(&mut self) -> Result<(), EscError> {
        let mut m = AlEvent {
            al_control: true,
            sm_change: true,
            watchdog: true,
            ..AlEvent::NONE
        };
        let s = self.esm.state();
        if s.mailbox_running() {
            m = m.with_sm(0).with_sm(1);
        }
        if s.process_data_running() {
            if self.plan.rx.bytes() > 0 {
                m = m.with_sm(2);
            } else if self.plan.tx.bytes() > 0 {
                m = m.with_sm(3);
            }
            m.sync0 = self.sync.mode == SyncMode::DcSync0;
        }
        self.esc.set(reg::AL_EVENT_MASK, m.to_raw())
    }

    fn write_status(&mut self) -> Result<(), EscError> {
        let st = (self.esm.status_word(), self.esm.code());
        if self.last_status != Some(st) {
            self.esc.set(reg::AL_STATUS_CODE, st.1)?;
            self.esc.set(reg::AL_STATUS, st.0)?;
            self.last_status = Some(st);
        }
        Ok(())
    }

    fn local_error<A: SlaveApplication>(
        &mut self,
        app: &mut A,
        code: AlStatusCode,
    ) -> Result<(), EscError> {
        let before = self.esm.state();
        self.esm.local_error(code);
        if matches!(
            code,
            AlStatusCode::SmWatchdog
                | AlStatusCode::FatalSyncError
                | AlStatusCode::PllError
                | AlStatusCode::SyncError
        ) {
            app.on_outputs_lost(code);
        }
        self.outputs_seen = false;
        self.state_changed(app, before)
    }

    fn supervise<A: SlaveApplication>(
        &mut self,
        app: &mut A,
        ev: AlEvent,
        now: u64,
    ) -> Result<(), EscError> {
        if let Some(to) = self.esm.pending() {
            if self.sync.sup.locked() {
                let before = self.esm.state();
                self.esm.finish(before, to, Ok(()));
                self.state_changed(app, before)?;
            } else if now.saturating_sub(self.pending_since) > sync::LOCK_TIMEOUT_US {
                let before = self.esm.state();
                self.esm.finish(before, to, Err(AlStatusCode::NoSync));
                self.state_changed(app, before)?;
            }
        }
        let s = self.esm.state();
        if !s.process_data_running() || self.esm.error() {
            return Ok(());
        }
        // The watchdog status is read at most once per WD_CHECK_US (the watchdog
        // itself is milliseconds), at once when the ESC flags the watchdog event, and
        // not when fresh outputs just arrived (they re-trigger it).
        let wd_due = ev.watchdog
            || now.saturating_sub(self.last_wd_check) >= WD_CHECK_US
            || now < self.last_wd_check;
        if self.wd_armed && (s == EsmState::Op || self.outputs_seen) && !ev.sm(2) && wd_due {
            self.last_wd_check = now;
            let st = self.esc.get(reg::WATCHDOG_STATUS_PD)?;
            if st & 1 == 0 {
                return self.local_error(app, AlStatusCode::SmWatchdog);
            }
        }
        if let SyncEvent::Error(code) = self.sync.sup.check(now) {
            return self.local_error(app, code);
        }
        if s == EsmState::Op {
            if let Some(code) = app.local_error() {
                return self.local_error(app, code);
            }
        }
        Ok(())
    }

    fn handle_sm_change<A: SlaveApplication>(&mut self, app: &mut A) -> Result<(), EscError> {
        self.read_sms()?;
        let s = self.esm.state();
        if s.mailbox_running() {
            let sm1 = self.sms[1];
            if sm1.repeat_request() != self.repeat_ack {
                let buf = SmRegs {
                    status: sm1.status,
                    activate: sm1.activate,
                    ..self.active[1]
                };
                self.repeat_mailbox(buf)?;
            }
        }
        if s.process_data_running() && !self.esm.error() {
            if self.plan.rx.bytes() > 0 && !self.sms[2].enabled() {
                return self.local_error(app, AlStatusCode::InvalidOutputConfig);
            }
            if self.plan.tx.bytes() > 0 && !self.sms[3].enabled() {
                return self.local_error(app, AlStatusCode::InvalidInputConfig);
            }
        }
        Ok(())
    }
}
