//! The master: ethercrab on the network card, every drive of the segment in Op with
//! the PV process data (0x1602 / 0x1A00), the cyclic exchange every 2 ms on the
//! tool's own clock, and the page's requests served between the cycles.
//!
//! * Cyclic ([`cyclic`]): inputs decoded into the view; the controlword, target
//!   velocity and mode written from the page's hold ([`Hold`]). The hold is a
//!   dead-man: the page renews it every 100 ms while "Enable" is on; a hold older
//!   than [`DEADMAN`] (page closed, tab hidden, network lost) or a released jog button
//!   sets the target velocity to 0, and a stale hold switches the drive off
//!   (controlword "shutdown": the drive brings the axis to rest on its own ramp).
//! * Requests ([`commands`]): SDO, SDO information, 0x10F3, scope, tunes and FoE go
//!   through each drive's mailbox ([`tests_host::coe_client`]; served in
//!   `master/requests.rs`); between requests the AL status and the emergencies are
//!   polled.
//! * A firmware update takes the drive Init → Bootstrap, writes the file over FoE and
//!   returns to Init; the session then ends and a new one brings the segment up again
//!   (the drive runs the new firmware and reports its version in 0x100A).

use std::cell::Cell;
use std::sync::mpsc::{Receiver, TryRecvError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use ethercrab::std::ethercat_now;
use ethercrab::{MainDevice, PduStorage, SubDeviceGroup};
use serde::Serialize;
use serde_json::Value;
use tests_host::coe_client::{Emergency, Mailbox};

use crate::dict;
use crate::texts;

mod requests;

/// Drives the tool handles on one segment.
pub const MAX_DRIVES: usize = 8;
const PDI: usize = 512;
type Group =
    SubDeviceGroup<MAX_DRIVES, PDI, ethercrab::DefaultLock, ethercrab::subdevice_group::Op>;

/// Cycle time of the process data.
const CYCLE: Duration = Duration::from_millis(2);
/// A hold older than this stops the axis and switches the drive off.
pub const DEADMAN: Duration = Duration::from_millis(400);

/// The 0x1602 (PV) output bytes: controlword, target velocity, acceleration,
/// deceleration, mode.
const OUT_LEN: usize = 15;
/// Samples of the live plot the view keeps.
const LIVE_SAMPLES: usize = 600;

/// A drive as the page shows it.
#[derive(Debug, Clone, Default, Serialize)]
pub struct DriveView {
    /// Position on the segment.
    pub position: usize,
    /// Station address.
    pub address: u16,
    /// Station alias.
    pub alias: u16,
    /// Name from the SII.
    pub name: String,
    /// Vendor ID, product code, revision, serial number.
    pub identity: [u32; 4],
    /// Firmware version (0x100A).
    pub version: String,
    /// ESM state in words.
    pub esm: String,
    /// AL status code and its text.
    pub al_code: u16,
    /// AL status code in words.
    pub al_text: String,
    /// Statusword (0x6041) and its CiA 402 state.
    pub statusword: u16,
    /// CiA 402 state.
    pub cia402: String,
    /// Modes of operation display (0x6061).
    pub mode: i8,
    /// Position actual value (0x6064).
    pub actual_position: i32,
    /// Digital inputs (0x60FD).
    pub inputs: u32,
    /// Active fault (0x603F) in words, and its LED code.
    pub fault: String,
    /// LED code of the fault.
    pub led: String,
}

/// One emergency as it arrived.
#[derive(Debug, Clone, Serialize)]
pub struct EmcyView {
    /// Drive position.
    pub drive: usize,
    /// Seconds since the tool started.
    pub time_s: f64,
    /// Error code.
    pub code: String,
    /// Text.
    pub text: String,
}

/// The firmware update's progress and the drive's answer.
#[derive(Debug, Clone, Default, Serialize)]
pub struct UpdateView {
    /// The drive updated.
    pub drive: usize,
    /// "", "running", "done", "failed".
    pub state: String,
    /// Bytes acknowledged.
    pub sent: usize,
    /// Bytes of the file.
    pub total: usize,
    /// The drive's answer in words.
    pub answer: String,
}

/// Everything the page polls.
#[derive(Debug, Clone, Default, Serialize)]
pub struct View {
    /// The network interface.
    pub iface: String,
    /// What the master does, in words.
    pub status: String,
    /// The drives.
    pub drives: Vec<DriveView>,
    /// Emergencies, oldest first.
    pub emergencies: Vec<EmcyView>,
    /// The last update.
    pub update: UpdateView,
    /// Live samples: seconds, then per drive position and statusword.
    pub live: Vec<(f64, Vec<(i32, u16)>)>,
    /// Whether the hold is in force, and the jog direction.
    pub hold: (bool, i8),
}

/// What the page asks the cyclic exchange to do.
#[derive(Debug, Clone, Copy)]
pub struct Hold {
    /// Drive position.
    pub drive: usize,
    /// Enable the drive.
    pub enable: bool,
    /// Jog direction: -1, 0, +1.
    pub dir: i8,
    /// Jog speed, inc/s.
    pub speed: i32,
    /// Mode of operation while enabled (3 PV, 1 PP for the servo tune).
    pub mode: i8,
    /// Renewed at.
    pub at: Instant,
}

/// A request of the page.
#[derive(Debug)]
pub enum Cmd {
    /// The objects of the dictionary.
    Objects(usize),
    /// The entries of one object, with their values.
    Object(usize, u16),
    /// Write a value given as text.
    Write(usize, u16, u8, String),
    /// Save (0x1010:01) or restore defaults (0x1011:01).
    Store(usize, bool),
    /// The 0x10F3 history.
    History(usize),
    /// A scope record.
    Scope(usize, ScopeRequest),
    /// Start a tune (true: servo tune 0x2162, false: current tune 0x2013).
    Tune(usize, bool),
    /// Read the tune results.
    TuneResults(usize),
    /// FoE update with this file.
    Update(usize, Vec<u8>),
}

impl Cmd {
    /// The drive the request is for.
    fn drive(&self) -> usize {
        match self {
            Cmd::Objects(k)
            | Cmd::Object(k, _)
            | Cmd::Write(k, ..)
            | Cmd::Store(k, _)
            | Cmd::History(k)
            | Cmd::Scope(k, _)
            | Cmd::Tune(k, _)
            | Cmd::TuneResults(k)
            | Cmd::Update(k, _) => *k,
        }
    }
}

/// A scope capture as the page asks for it.
#[derive(Debug, Clone, serde::Deserialize)]
pub struct ScopeRequest {
    /// Channels as `INDEX[:SUB]`.
    pub channels: Vec<String>,
    /// Trigger condition name ([`scope_host::CONDITIONS`]).
    pub condition: String,
    /// Trigger level.
    pub level: i32,
    /// Samples before the trigger.
    pub pretrigger: u16,
    /// One sample every `divisor` periods.
    pub divisor: u16,
    /// Servo-rate time base.
    pub servo_rate: bool,
}

/// The answer to a request: JSON, or what went wrong in words.
pub type Reply = Result<Value, String>;
/// A request with where its answer goes.
pub type Job = (Cmd, tokio::sync::oneshot::Sender<Reply>);

/// What the page and the master share.
pub struct Shared {
    /// The view.
    pub view: Mutex<View>,
    /// The hold.
    pub hold: Mutex<Option<Hold>>,
    /// When the tool started.
    pub t0: Instant,
}

impl Shared {
    fn view(&self) -> std::sync::MutexGuard<'_, View> {
        self.view.lock().unwrap_or_else(|p| p.into_inner())
    }
    fn hold(&self) -> std::sync::MutexGuard<'_, Option<Hold>> {
        self.hold.lock().unwrap_or_else(|p| p.into_inner())
    }
}

static PDU: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

/// Runs the master on `iface` for ever (a new session after an update or a failure).
pub fn run(iface: &str, shared: Arc<Shared>, jobs: Receiver<Job>) {
    let md = tests_host::netns::veth_master(&PDU, iface);
    loop {
        let r = async_io::block_on(session(&md, &shared, &jobs));
        if let Err(e) = r {
            shared.view().status = format!("no segment: {e}; trying again");
            // Answer what waited meanwhile.
            while let Ok((_, reply)) = jobs.try_recv() {
                let _ = reply.send(Err(format!("no segment: {e}")));
            }
            std::thread::sleep(Duration::from_secs(1));
        }
    }
}

fn e2s(what: &str) -> impl Fn(ethercrab::error::Error) -> String + '_ {
    move |e| format!("{what}: {}", texts::error(&e))
}

/// One session: the segment up to Op, then cycles and requests until an update ends it.
async fn session(
    md: &MainDevice<'static>,
    shared: &Shared,
    jobs: &Receiver<Job>,
) -> Result<(), String> {
    shared.view().status = "scanning the segment".into();
    let group = md
        .init_single_group::<MAX_DRIVES, PDI>(ethercat_now)
        .await
        .map_err(e2s("scan"))?;
    let mut drives = Vec::new();
    let mut mailboxes = Vec::new();
    let mut emcy = Vec::new();
    for (k, sd) in group.iter(md).enumerate() {
        let mbx = Mailbox::of(&sd).await.map_err(e2s("mailbox"))?;
        // PV process data: 0x1C12 = {0x1602}.
        mbx.download(&sd, 0x1C12, 0, &[0], &mut emcy)
            .await
            .map_err(e2s("0x1C12"))?;
        mbx.download(&sd, 0x1C12, 1, &0x1602u16.to_le_bytes(), &mut emcy)
            .await
            .map_err(e2s("0x1C12"))?;
        mbx.download(&sd, 0x1C12, 0, &[1], &mut emcy)
            .await
            .map_err(e2s("0x1C12"))?;
        let version = mbx
            .upload(&sd, 0x100A, 0, &mut emcy)
            .await
            .map(|v| dict::format_value(0x0009, &v))
            .unwrap_or_default();
        let id = sd.identity();
        drives.push(DriveView {
            position: k,
            address: sd.configured_address(),
            alias: sd.alias_address(),
            name: sd.name().to_string(),
            identity: [id.vendor_id, id.product_id, id.revision, id.serial],
            version,
            ..DriveView::default()
        });
        mailboxes.push(mbx);
    }
    if drives.is_empty() {
        return Err("no drive answers".into());
    }
    {
        let mut v = shared.view();
        v.drives = drives;
        v.live.clear();
        if v.update.state == "running" {
            let version = v
                .drives
                .get(v.update.drive)
                .map(|d| d.version.clone())
                .unwrap_or_default();
            v.update.state = "done".into();
            v.update.answer = format!(
                "update done; drive {} reports version {version}",
                v.update.drive
            );
        }
        v.status = "taking the drives to Op".into();
    }
    let group = group.into_op(md).await.map_err(e2s("Op"))?;
    shared.view().status = "holding the master: drives in Op".into();
    let end = Cell::new(false);
    let paused = Cell::new(false);
    let state = Session {
        md,
        group: &group,
        shared,
        mailboxes,
        end: &end,
        paused: &paused,
    };
    futures_lite::future::zip(state.cyclic(), state.commands(jobs, emcy)).await;
    Ok(())
}

struct Session<'a> {
    md: &'a MainDevice<'static>,
    group: &'a Group,
    shared: &'a Shared,
    mailboxes: Vec<Mailbox>,
    end: &'a Cell<bool>,
    paused: &'a Cell<bool>,
}

/// The controlword that takes the state machine towards Operation enabled.
fn enable_step(sw: u16) -> u16 {
    match sw & 0x6F {
        0x21 => 0x0007,
        0x23 | 0x27 => 0x000F,
        _ if sw & 0x08 != 0 => 0x0000,
        _ if sw & 0x4F == 0x40 => 0x0006,
        _ => 0x0000,
    }
}

impl Session<'_> {
    /// The process data every [`CYCLE`].
    async fn cyclic(&self) {
        let mut next = Instant::now();
        let mut sample = 0u32;
        while !self.end.get() {
            next += CYCLE;
            async_io::Timer::at(next.max(Instant::now())).await;
            if self.paused.get() {
                continue;
            }
            let hold = {
                let mut h = self.shared.hold();
                if h.is_some_and(|h| h.at.elapsed() > DEADMAN) {
                    *h = None;
                }
                *h
            };
            for (k, sd) in self.group.iter(self.md).enumerate() {
                let sw = {
                    let i = sd.inputs_raw();
                    if i.len() < 4 {
                        continue;
                    }
                    u16::from_le_bytes([i[2], i[3]])
                };
                let mine = hold.filter(|h| h.drive == k && h.enable);
                let (cw, v, mode) = match mine {
                    Some(h) => (enable_step(sw), i32::from(h.dir) * h.speed, h.mode),
                    // Off: "shutdown" from the enabled states, else nothing.
                    None if sw & 0x6F == 0x27 || sw & 0x6F == 0x23 => (0x0006, 0, 3),
                    None => (0x0000, 0, 3),
                };
                let mut o = sd.outputs_raw_mut();
                if o.len() >= OUT_LEN {
                    o[0..2].copy_from_slice(&cw.to_le_bytes());
                    o[2..6].copy_from_slice(&v.to_le_bytes());
                    o[6..10].copy_from_slice(&100_000u32.to_le_bytes());
                    o[10..14].copy_from_slice(&100_000u32.to_le_bytes());
                    o[14] = mode as u8;
                }
            }
            if self.group.tx_rx(self.md).await.is_err() {
                continue;
            }
            sample += 1;
            let mut v = self.shared.view();
            let t = self.shared.t0.elapsed().as_secs_f64();
            let mut row = Vec::new();
            for (k, sd) in self.group.iter(self.md).enumerate() {
                let i = sd.inputs_raw();
                if i.len() < 19 {
                    continue;
                }
                let Some(d) = v.drives.get_mut(k) else {
                    continue;
                };
                let ec = u16::from_le_bytes([i[0], i[1]]);
                d.statusword = u16::from_le_bytes([i[2], i[3]]);
                d.cia402 = texts::cia402(d.statusword);
                d.mode = i[4] as i8;
                d.actual_position = i32::from_le_bytes([i[5], i[6], i[7], i[8]]);
                d.inputs = u32::from_le_bytes([i[15], i[16], i[17], i[18]]);
                (d.fault, d.led) = texts::active_fault(ec);
                row.push((d.actual_position, d.statusword));
            }
            v.hold = hold.map_or((false, 0), |h| (h.enable, h.dir));
            // 20 ms per live sample.
            if sample.is_multiple_of(10) {
                v.live.push((t, row));
                if v.live.len() > LIVE_SAMPLES {
                    v.live.remove(0);
                }
            }
        }
    }

    /// The page's requests, and the AL status and emergencies between them.
    async fn commands(&self, jobs: &Receiver<Job>, mut emcy: Vec<Emergency>) {
        let mut polled = Instant::now() - Duration::from_secs(1);
        loop {
            match jobs.try_recv() {
                Ok((cmd, reply)) => {
                    let update = matches!(cmd, Cmd::Update(..));
                    let k = cmd.drive();
                    let r = self.handle(cmd, &mut emcy).await;
                    self.record_emergencies(&mut emcy, k);
                    let _ = reply.send(r);
                    if update {
                        self.end.set(true);
                        return;
                    }
                }
                Err(TryRecvError::Disconnected) => {
                    self.end.set(true);
                    return;
                }
                Err(TryRecvError::Empty) if polled.elapsed() > Duration::from_millis(200) => {
                    polled = Instant::now();
                    for (k, sd) in self.group.iter(self.md).enumerate() {
                        let Some(mbx) = self.mailboxes.get(k) else {
                            continue;
                        };
                        let _ = mbx.poll_emergencies(&sd, &mut emcy).await;
                        self.record_emergencies(&mut emcy, k);
                        let al: Result<[u8; 6], _> = sd.register_read(0x0130u16).await;
                        if let Ok(al) = al {
                            let st = u16::from_le_bytes([al[0], al[1]]);
                            let code = u16::from_le_bytes([al[4], al[5]]);
                            if st & 0x1F != 0x08 && !self.paused.get() {
                                // Out of Op (e.g. a watchdog on a loaded host): back
                                // to Op, the error acknowledged.
                                let _ = sd.register_write(0x0120u16, 0x0018u16).await;
                            }
                            let mut v = self.shared.view();
                            if let Some(d) = v.drives.get_mut(k) {
                                d.esm = texts::esm(st);
                                d.al_code = code;
                                d.al_text = texts::al_code(code);
                            }
                        }
                    }
                }
                Err(TryRecvError::Empty) => {
                    async_io::Timer::after(Duration::from_millis(5)).await;
                }
            }
        }
    }

    fn record_emergencies(&self, emcy: &mut Vec<Emergency>, drive: usize) {
        if emcy.is_empty() {
            return;
        }
        let t = self.shared.t0.elapsed().as_secs_f64();
        let mut v = self.shared.view();
        for e in emcy.drain(..) {
            v.emergencies.push(EmcyView {
                drive,
                time_s: t,
                code: format!("{:#06x}", u16::from_le_bytes([e[0], e[1]])),
                text: texts::emergency(&e),
            });
        }
    }
}
