//! Strict masters against `virtual-drive` over a veth pair: how the real-time
//! behaviour of the virtual drive is measured (`tests/virtual_drive_realtime.rs`, the
//! `vd-bench` program behind the "Virtual drive in real time" section of
//! BENCHMARKS.md).
//!
//! [`soem_style`] is a synchronous raw-datagram master ([`SocketMaster`]) doing what
//! SOEM's `ecx_config_init` / `ecx_config_map_group` / `ecx_configdc` /
//! `ecx_dcsync0` do, one frame at a time with a 2 ms timeout and no resend, then
//! the cyclic LRW every 1 ms; every frame that does not come back counts.
//!
//! [`run`] starts `virtual-drive` in a network namespace ([`crate::netns`]), measures
//! its CPU time while idle (no master), then brings every drive to Op with ethercrab
//! set up strictly: a 2 ms PDU timeout and no resend
//! ([`ethercrab::RetryBehaviour::None`]), so one frame answered late fails the
//! set-up; DC SYNC0 at 1 ms; then runs the cyclic exchange, timing every round trip
//! and checking every working counter. CPU time is the child process's user + system
//! time from `/proc/PID/stat` (all its threads), not wall time.

use std::time::{Duration, Instant};

use ethercrab::error::{Error, TimeoutError};
use ethercrab::std::{ethercat_now, tx_rx_task};
use ethercrab::subdevice_group::DcConfiguration;
use ethercrab::{DcSync, MainDevice, MainDeviceConfig, PduStorage, RetryBehaviour, Timeouts};

use crate::netns::{self, Killed, Netns};
use crate::raw_master::{SocketMaster, Transport};

/// Frames in flight of one master.
pub type Storage = PduStorage<16, { PduStorage::element_size(1500) }>;

/// Most drives a run handles.
pub const MAX_DRIVES: usize = 128;
const MAX_PDI: usize = 8192;

/// What one run asks for.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Path of the `virtual-drive` program.
    pub program: String,
    /// Namespace tag (keeps parallel runs apart).
    pub tag: String,
    /// Drives simulated.
    pub drives: usize,
    /// Further options of `virtual-drive`.
    pub extra: Vec<String>,
    /// Idle time measured before the master starts.
    pub idle: Duration,
    /// Cycles in Op (1 ms DC cycle).
    pub cycles: usize,
    /// PDU timeout of the master (no resend).
    pub pdu_timeout: Duration,
}

/// What one run measured.
#[derive(Debug, Clone, Default)]
pub struct Report {
    /// Drives the master found.
    pub found: usize,
    /// CPU time of `virtual-drive` during the idle phase, s, and the phase's length, s.
    pub idle_cpu_s: (f64, f64),
    /// CPU time of `virtual-drive` during the cyclic phase, s, and its length, s.
    pub cyclic_cpu_s: (f64, f64),
    /// Cyclic exchanges run.
    pub cycles: usize,
    /// Exchanges that timed out (lost frames; nothing is resent).
    pub lost: usize,
    /// Exchanges whose working counter was not 3 per drive.
    pub wrong_wkc: usize,
    /// Round trip of every answered exchange, µs, sorted.
    pub rtt_us: Vec<f64>,
    /// Cycles from the Op request until every drive reported Op.
    pub cycles_to_op: usize,
    /// Longest time `virtual-drive` took from a frame's receipt to its answer, µs
    /// (from its last line).
    pub longest_answer_us: f64,
    /// Whether `virtual-drive` ended cleanly on SIGTERM, and how long it took.
    pub sigterm: (bool, Duration),
    /// Every drive still in Op at the last exchange.
    pub op_at_end: bool,
}

impl Report {
    /// The `p`-th percentile of the round trips, µs (0 without any).
    pub fn rtt_percentile(&self, p: f64) -> f64 {
        if self.rtt_us.is_empty() {
            return 0.0;
        }
        let k = ((p / 100.0) * (self.rtt_us.len() - 1) as f64).round() as usize;
        self.rtt_us[k.min(self.rtt_us.len() - 1)]
    }
    /// The longest round trip, µs.
    pub fn rtt_max(&self) -> f64 {
        self.rtt_us.last().copied().unwrap_or(0.0)
    }
}

/// User + system CPU time of process `pid` (all threads, exited ones included), s.
pub fn process_cpu_s(pid: u32) -> Option<f64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // Fields after the command name (which may hold spaces) in parentheses.
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    // utime and stime are fields 14 and 15 of the line, 12 and 13 after the name.
    let ticks: u64 = f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?;
    // SAFETY: sysconf has no preconditions.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) }.max(1) as f64;
    Some(ticks as f64 / hz)
}

/// A running `virtual-drive` in its namespace.
pub struct Running {
    /// The namespace and veth pair (removed on drop).
    pub net: Netns,
    /// The process (stopped on drop).
    pub child: Killed,
    /// Its output after the `ready` line.
    pub lines: std::sync::mpsc::Receiver<String>,
}

impl Running {
    /// Starts `program --drives N extra…` in a new namespace tagged `tag`.
    pub fn start(program: &str, tag: &str, drives: usize, extra: &[String]) -> Result<Self, String> {
        let net = Netns::create(tag).ok_or(
            "the network namespace / veth pair could not be created (root? iproute2?)",
        )?;
        let n = drives.to_string();
        let mut args: Vec<&str> = vec!["--drives", &n];
        args.extend(extra.iter().map(String::as_str));
        let (child, lines) = netns::start_virtual_drive(&net, program, &args)?;
        Ok(Running { net, child, lines })
    }
    /// The process id of `virtual-drive` (`ip netns exec` runs it in its place).
    pub fn pid(&self) -> u32 {
        self.child.0.id()
    }
    /// Sends SIGTERM and waits up to `limit` for the process to end: its exit status
    /// (`None`: still running at the limit, then killed), how long it took, and the
    /// lines it printed meanwhile.
    pub fn terminate(mut self, limit: Duration) -> (Option<std::process::ExitStatus>, Duration, Vec<String>) {
        let t0 = Instant::now();
        // SAFETY: plain kill(2) on our own child.
        unsafe { libc::kill(self.pid() as i32, libc::SIGTERM) };
        let mut status = None;
        while t0.elapsed() < limit {
            if let Ok(Some(s)) = self.child.0.try_wait() {
                status = Some(s);
                break;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        let took = t0.elapsed();
        let lines = self.lines.try_iter().collect();
        (status, took, lines)
    }
    /// Its CPU time so far, s.
    pub fn cpu_s(&self) -> Result<f64, String> {
        process_cpu_s(self.pid()).ok_or_else(|| "no /proc entry for virtual-drive".to_string())
    }
}

/// The strict master on `host_if` (its frame task on a thread of its own).
pub fn strict_master(
    storage: &'static Storage,
    host_if: &str,
    pdu_timeout: Duration,
) -> Result<MainDevice<'static>, String> {
    let (pdu_tx, pdu_rx, pdu_loop) = storage
        .try_split()
        .map_err(|_| "frame storage used twice".to_string())?;
    let task = tx_rx_task(host_if, pdu_tx, pdu_rx).map_err(|e| format!("raw socket: {e}"))?;
    std::thread::spawn(move || {
        let _ = async_io::block_on(task);
    });
    Ok(MainDevice::new(
        pdu_loop,
        Timeouts {
            pdu: pdu_timeout,
            eeprom: Duration::from_millis(100),
            wait_loop_delay: Duration::from_millis(1),
            mailbox_response: Duration::from_millis(1000),
            ..Timeouts::default()
        },
        MainDeviceConfig {
            dc_static_sync_iterations: 1000,
            retry_behaviour: RetryBehaviour::None,
        },
    ))
}

/// Runs `plan` with `storage` (one per run: ethercrab splits it once).
pub fn run(plan: &Plan, storage: &'static Storage) -> Result<Report, String> {
    let vd = Running::start(&plan.program, &plan.tag, plan.drives, &plan.extra)?;
    let mut rep = Report::default();
    let (c0, t0) = (vd.cpu_s()?, Instant::now());
    std::thread::sleep(plan.idle);
    rep.idle_cpu_s = (vd.cpu_s()? - c0, t0.elapsed().as_secs_f64());
    let md = strict_master(storage, &vd.net.host_if, plan.pdu_timeout)?;
    let cycles = plan.cycles;
    let expected = 3 * plan.drives as u16;
    let mut stage = "start";
    let r: Result<(), Error> = async_io::block_on(async {
        stage = "scan and PDO set-up (init_single_group)";
        let mut group = md
            .init_single_group::<MAX_DRIVES, MAX_PDI>(ethercat_now)
            .await?;
        rep.found = group.len();
        for mut sd in group.iter_mut(&md) {
            sd.set_dc_sync(DcSync::Sync0);
        }
        stage = "Pre-Op with process data";
        let group = group.into_pre_op_pdi(&md).await?;
        stage = "DC system time";
        for _ in 0..100 {
            group.tx_rx_sync_system_time(&md).await?;
            async_io::Timer::after(Duration::from_millis(1)).await;
        }
        stage = "SYNC0 set-up";
        let group = group
            .configure_dc_sync(
                &md,
                DcConfiguration {
                    start_delay: Duration::from_millis(20),
                    sync0_period: Duration::from_millis(1),
                    sync0_shift: Duration::from_micros(500),
                },
            )
            .await?;
        stage = "Safe-Op";
        let group = group.into_safe_op(&md).await?;
        stage = "Op";
        let group = group.request_into_op(&md).await?;
        loop {
            let r = group.tx_rx_dc(&md).await?;
            rep.cycles_to_op += 1;
            if r.all_op() {
                break;
            }
            if rep.cycles_to_op > 5000 {
                return Err(Error::Timeout(TimeoutError::StateTransition));
            }
            async_io::Timer::after(r.extra.next_cycle_wait).await;
        }
        stage = "cyclic";
        let (c1, t1) = (process_cpu_s(vd.pid()).unwrap_or(0.0), Instant::now());
        for _ in 0..cycles {
            let sent = Instant::now();
            match group.tx_rx_dc(&md).await {
                Ok(r) => {
                    rep.rtt_us.push(sent.elapsed().as_secs_f64() * 1e6);
                    if r.working_counter != expected {
                        rep.wrong_wkc += 1;
                    }
                    rep.op_at_end = r.all_op();
                    async_io::Timer::after(r.extra.next_cycle_wait).await;
                }
                Err(Error::Timeout(TimeoutError::Pdu)) => {
                    rep.lost += 1;
                    rep.op_at_end = false;
                    async_io::Timer::after(Duration::from_millis(1)).await;
                }
                Err(e) => return Err(e),
            }
            rep.cycles += 1;
        }
        rep.cyclic_cpu_s = (
            process_cpu_s(vd.pid()).unwrap_or(0.0) - c1,
            t1.elapsed().as_secs_f64(),
        );
        Ok(())
    });
    rep.rtt_us.sort_by(f64::total_cmp);
    let (status, took, lines) = vd.terminate(Duration::from_secs(5));
    rep.sigterm = (status.is_some_and(|s| s.success()), took);
    rep.longest_answer_us = lines
        .iter()
        .find_map(|l| {
            let ms = l.split("longest answer ").nth(1)?.split(' ').next()?;
            ms.parse::<f64>().ok()
        })
        .map_or(0.0, |ms| ms * 1e3);
    if let Err(e) = r {
        return Err(format!(
            "ethercrab ({:?} PDU timeout, no resend) against {} drive(s): {e:?} in {stage}; \
             virtual-drive said: {}",
            plan.pdu_timeout,
            plan.drives,
            lines.join(" / ")
        ));
    }
    Ok(rep)
}

/// Bytes of the product's default mapping (0x1600 outputs / 0x1A00 inputs).
pub const OUT_BYTES: usize = 12;
/// See [`OUT_BYTES`].
pub const IN_BYTES: usize = 19;

/// What [`soem_style`] saw.
#[derive(Debug, Clone, Copy, Default)]
pub struct SoemReport {
    /// Frames sent during the set-up, and how many did not come back.
    pub setup_frames: (u64, u64),
    /// LRWs sent in Op, and how many came back with working counter 3 per drive.
    pub lrw: (u64, u64),
    /// Frames lost in Op (LRWs and AL status reads).
    pub lost_in_op: u64,
    /// Frames that came back but not for the exchange waiting (late answers).
    pub stray: u64,
    /// AL status and status code of every drive after the cycles.
    pub al_after: [(u16, u16); 4],
}

/// A SOEM-style set-up of `drives` drives on `iface` (stations 0x1001…), every frame
/// waited for `timeout` and never resent, DC SYNC0 at 1 ms, Op (each state change
/// given up to 20 s: the drives' power-up work may run slower than real time on a
/// loaded machine or in a debug build); then `cycles` LRWs at 1 ms. Runs on the calling thread, at SCHED_FIFO priority 10 when the process
/// may (so that other load on the machine does not make the master miss its own
/// timeouts); back to normal priority after. An error names the step that failed.
pub fn soem_style(
    iface: &str,
    drives: u16,
    timeout: Duration,
    cycles: u64,
) -> Result<SoemReport, String> {
    let _ = crate::realtime::set_fifo(10);
    let r = soem_steps(iface, drives, timeout, cycles);
    crate::realtime::set_normal();
    r
}

fn soem_steps(
    iface: &str,
    drives: u16,
    timeout: Duration,
    cycles: u64,
) -> Result<SoemReport, String> {
    let mut m = SocketMaster::open(iface, timeout).map_err(|e| e.to_string())?;
    let mut rep = SoemReport::default();
    let lost = |m: &SocketMaster, step: &str| -> Result<(), String> {
        if m.lost == 0 {
            Ok(())
        } else {
            Err(format!("{step}: {} frame(s) not back within {timeout:?}", m.lost))
        }
    };
    let stations = || (0..drives).map(|i| 0x1001 + i);
    // ecx_config_init: Init + ack to all, count, station addresses, identity.
    m.bwr(0x0120, &0x0011u16.to_le_bytes());
    let (_, found) = m.brd(0x0000, 2);
    if found != drives {
        return Err(format!("{found} drive(s) answered the count, {drives} expected"));
    }
    for (pos, st) in stations().enumerate() {
        if m.apwr(pos as u16, 0x0010, &st.to_le_bytes()) != 1 {
            return Err(format!("station address of position {pos}"));
        }
        let product = m.sii_read(st, 0x000A);
        if product != Some(firmware::identity::Variant::HybridServo.product_code()) {
            return Err(format!("SII product code of {st:#06x}: {product:x?}"));
        }
        m.configure_mailbox(st, (0x1000, 128, 0x1080, 128));
        m.request_state(st, 0x0002);
    }
    for st in stations() {
        let s = m.wait_state(st, 0x02, 20_000_000_000, 1_000_000, |_| {});
        if s != (0x02, 0) {
            return Err(format!("Pre-Op of {st:#06x}: AL status {s:x?}"));
        }
        // ecx_readPDOmap starts with the SM types over SDO.
        m.sdo_upload(st, 0x1C00, 3)
            .map_err(|e| format!("SDO 0x1C00:03 of {st:#06x}: {e:?}"))?;
    }
    lost(&m, "Pre-Op")?;
    // ecx_config_map_group: SMs and FMMUs, Safe-Op; ecx_configdc, ecx_dcsync0.
    let per = OUT_BYTES + IN_BYTES;
    for (k, st) in stations().enumerate() {
        if m.process_data_sms(st, (k * per) as u32, OUT_BYTES, IN_BYTES) != 2 {
            return Err(format!("SyncManagers / FMMUs of {st:#06x}"));
        }
    }
    for st in stations() {
        m.soem_configdc(st, 789_000_000_000);
        m.soem_dcsync(st, 1_000_000, 0, 0x03);
        m.request_state(st, 0x0004);
    }
    for st in stations() {
        let s = m.wait_state(st, 0x04, 20_000_000_000, 1_000_000, |_| {});
        if s != (0x04, 0) {
            return Err(format!("Safe-Op of {st:#06x}: AL status {s:x?}"));
        }
    }
    lost(&m, "Safe-Op")?;
    // Process data before and during the Op request, as SOEM's applications do, in
    // the middle between two SYNC0 pulses (SOEM's examples align their cycle to the
    // DC time, `ec_sync`): the next pulse's system time (0x0990) against the system
    // time now (0x0910) gives the pulse on the master's clock.
    let wkc = 3 * drives;
    let t0 = m.link.now_ns();
    let st = m.fprd_u64(0x1001, 0x0910);
    let t1 = m.link.now_ns();
    let next = m.fprd_u64(0x1001, 0x0990);
    let pulse = (t0 + t1) / 2 + next.saturating_sub(st);
    m.start_cyclic(1_000_000, usize::from(drives) * per, wkc);
    if let Some(c) = m.cyclic.as_mut() {
        let aim = pulse + 500_000;
        let now = m.link.now_ns();
        c.next_ns = if aim >= now {
            aim - (aim - now) / 1_000_000 * 1_000_000
        } else {
            aim + (now - aim).div_ceil(1_000_000) * 1_000_000
        };
    }
    m.wait(20_000_000, 1_000_000);
    for st in stations() {
        m.request_state(st, 0x0008);
    }
    for st in stations() {
        let s = m.wait_state(st, 0x08, 20_000_000_000, 1_000_000, |_| {});
        if s != (0x08, 0) {
            return Err(format!("Op of {st:#06x}: AL status {s:x?}"));
        }
    }
    lost(&m, "Op")?;
    rep.setup_frames = (m.frames, m.lost);
    let counts = |m: &SocketMaster| m.cyclic.map_or((0, 0), |c| (c.sent, c.good));
    let (c0, l0) = (counts(&m), m.lost);
    m.wait(cycles * 1_000_000, 1_000_000);
    let c1 = counts(&m);
    rep.lrw = (c1.0 - c0.0, c1.1 - c0.1);
    rep.lost_in_op = m.lost - l0;
    rep.stray = m.stray;
    for (k, st) in stations().enumerate() {
        let s = m.al_status(st);
        if let Some(a) = rep.al_after.get_mut(k) {
            *a = s;
        }
    }
    for st in stations() {
        m.request_state(st, 0x0001);
    }
    Ok(rep)
}
