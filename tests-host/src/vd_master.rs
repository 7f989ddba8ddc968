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
//! [`measure`] starts `virtual-drive` in a network namespace ([`crate::netns`]),
//! measures its CPU time while idle (no master), then runs [`soem_style`] against it,
//! timing every round trip. CPU time is the child process's user + system time from
//! `/proc/PID/stat` (all its threads), not wall time. The master is synchronous and
//! runs at SCHED_FIFO when it may: a master whose frame task waits for a normal
//! thread to be scheduled (ethercrab's) misses a 2 ms timeout on a loaded machine
//! by itself, whatever the drive does.

use std::time::{Duration, Instant};

use crate::netns::{self, Killed, Netns};
use crate::raw_master::{Cyclic, Master, SocketMaster, Transport};

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
    pub fn start(
        program: &str,
        tag: &str,
        drives: usize,
        extra: &[String],
    ) -> Result<Self, String> {
        let net = Netns::create(tag)
            .ok_or("the network namespace / veth pair could not be created (root? iproute2?)")?;
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
    pub fn terminate(
        mut self,
        limit: Duration,
    ) -> (Option<std::process::ExitStatus>, Duration, Vec<String>) {
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
        // Everything it printed, up to the end of its output.
        let mut lines = Vec::new();
        while let Ok(l) = self.lines.recv_timeout(Duration::from_millis(500)) {
            lines.push(l);
        }
        (status, took, lines)
    }
    /// Its CPU time so far, s.
    pub fn cpu_s(&self) -> Result<f64, String> {
        process_cpu_s(self.pid()).ok_or_else(|| "no /proc entry for virtual-drive".to_string())
    }
}

/// What [`measure`] measured.
#[derive(Debug, Clone)]
pub struct Measured {
    /// CPU time of `virtual-drive` during the idle phase (no master), s, and the
    /// phase's length, s.
    pub idle_cpu_s: (f64, f64),
    /// The SOEM-style master's run (CPU of the cyclic phase included), or the step
    /// that failed with what `virtual-drive` printed.
    pub run: Result<SoemReport, String>,
    /// Longest time `virtual-drive` took from a frame's receipt to its answer, µs
    /// (from its last line).
    pub longest_answer_us: f64,
    /// Whether `virtual-drive` ended cleanly on SIGTERM, and how long it took.
    pub sigterm: (bool, Duration),
    /// What `virtual-drive` printed after `ready`.
    pub log: Vec<String>,
}

/// Time after `virtual-drive`'s `ready` before [`measure`] measures it idle (the
/// drives' power-up runs before `ready`; what is left of the start settles).
pub const SETTLE: Duration = Duration::from_secs(2);

/// Starts `virtual-drive --drives N` (`program`) in a namespace tagged `tag`,
/// measures its CPU time for `idle` with no master after [`SETTLE`], runs [`soem_style`] with a 2 ms
/// timeout and `cycles` cycles, then ends it with SIGTERM.
pub fn measure(
    program: &str,
    tag: &str,
    drives: u16,
    idle: Duration,
    cycles: u64,
) -> Result<Measured, String> {
    let vd = Running::start(program, tag, usize::from(drives), &[])?;
    std::thread::sleep(SETTLE);
    let (c0, t0) = (vd.cpu_s()?, Instant::now());
    std::thread::sleep(idle);
    let mut m = Measured {
        idle_cpu_s: (vd.cpu_s()? - c0, t0.elapsed().as_secs_f64()),
        run: Err(String::new()),
        longest_answer_us: 0.0,
        sigterm: (false, Duration::ZERO),
        log: Vec::new(),
    };
    let r = soem_style(
        &vd.net.host_if,
        drives,
        Duration::from_millis(2),
        cycles,
        Some(vd.pid()),
    );
    let (status, took, lines) = vd.terminate(Duration::from_secs(5));
    m.sigterm = (status.is_some_and(|s| s.success()), took);
    m.longest_answer_us = lines
        .iter()
        .find_map(|l| {
            let ms = l.split("longest answer ").nth(1)?.split(' ').next()?;
            ms.parse::<f64>().ok()
        })
        .map_or(0.0, |ms| ms * 1e3);
    m.run = r.map_err(|e| format!("{e}; virtual-drive said: {}", lines.join(" / ")));
    m.log = lines;
    Ok(m)
}

/// Bytes of the product's default mapping (0x1600 outputs / 0x1A00 inputs).
pub const OUT_BYTES: usize = 12;
/// See [`OUT_BYTES`].
pub const IN_BYTES: usize = 19;

/// What [`soem_style`] saw.
#[derive(Debug, Clone, Default)]
pub struct SoemReport {
    /// Frames sent during the set-up, and how many did not come back.
    pub setup_frames: (u64, u64),
    /// LRWs sent in Op, and how many came back with working counter 3 per drive.
    pub lrw: (u64, u64),
    /// Frames lost in Op (LRWs and AL status reads).
    pub lost_in_op: u64,
    /// Frames that came back but not for the exchange waiting (late answers).
    pub stray: u64,
    /// AL status and status code of every drive right after the cycles (LRWs between
    /// the reads).
    pub al_after: Vec<(u16, u16)>,
    /// Round trip of every frame answered in Op, µs, sorted.
    pub rtt_us: Vec<f64>,
    /// CPU time of the process given to [`soem_style`] during the cycles, s, and the
    /// time they took, s.
    pub cyclic_cpu_s: (f64, f64),
}

impl SoemReport {
    /// The `p`-th percentile of the round trips in Op, µs (0 without any).
    pub fn rtt_percentile(&self, p: f64) -> f64 {
        if self.rtt_us.is_empty() {
            return 0.0;
        }
        let k = ((p / 100.0) * (self.rtt_us.len() - 1) as f64).round() as usize;
        self.rtt_us[k.min(self.rtt_us.len() - 1)]
    }
    /// The longest round trip in Op, µs.
    pub fn rtt_max(&self) -> f64 {
        self.rtt_us.last().copied().unwrap_or(0.0)
    }
}

/// SCHED_FIFO priority of [`soem_style`]'s thread: above `virtual-drive`'s threads
/// (20 and 19), as a master on a machine of its own is never delayed by the drives;
/// it sleeps while it waits for a frame.
pub const MASTER_PRIORITY: i32 = 30;

/// Drives per LRW frame of the cyclic exchange (992 bytes with the default maps).
const DRIVES_PER_FRAME: usize = 32;

/// SCHED_FIFO at [`MASTER_PRIORITY`] for the calling thread (when the process may)
/// until dropped.
struct MasterPriority;

impl MasterPriority {
    fn take() -> Self {
        let _ = crate::realtime::set_fifo(MASTER_PRIORITY);
        MasterPriority
    }
}

impl Drop for MasterPriority {
    fn drop(&mut self) {
        crate::realtime::set_normal();
    }
}

/// SOEM's `ecx_configdc` (ec_dc.c) for every station at once: one broadcast write
/// latches the receive times of all drives as the same frame passes them, then each
/// drive's offset (0x0920) makes its system time `master_time` at that pass. The
/// drives then share one time base, and SYNC0 pulses started for the same system
/// time come together.
fn configdc_all<T: Transport>(
    m: &mut Master<T>,
    stations: impl Iterator<Item = u16>,
    master_time: u64,
) {
    m.bwr(0x0900, &[0; 4]);
    for st in stations {
        let _ports = m.fprd(st, 0x0900, 16);
        let local = m.fprd_u64(st, 0x0918);
        m.fpwr(st, 0x0920, &master_time.wrapping_sub(local).to_le_bytes());
    }
}

/// Waits (up to 20 s each, polling every 1 ms) until every station is in `state`.
fn all_in<T: Transport>(
    m: &mut Master<T>,
    stations: impl Iterator<Item = u16>,
    state: u16,
    name: &str,
) -> Result<(), String> {
    for st in stations {
        let s = m.wait_state(st, state, 20_000_000_000, 1_000_000, |_| {});
        if s != (state, 0) {
            return Err(format!("{name} of {st:#06x}: AL status {s:x?}"));
        }
    }
    Ok(())
}

/// A SOEM-style set-up of `drives` drives on `iface` (stations 0x1001…), every frame
/// waited for `timeout` and never resent, DC SYNC0 at 1 ms, Op (each state change
/// given up to 20 s: the drives' power-up work may run slower than real time on a
/// loaded machine or in a debug build); then `cycles` LRWs at 1 ms (one frame per
/// 32 drives), measuring the CPU time of process `pid` meanwhile when given. Runs on
/// the calling thread, at SCHED_FIFO [`MASTER_PRIORITY`] when the process may (so
/// that other load on the machine does not make the master miss its own timeouts);
/// back to normal priority after. An error names the step that failed.
pub fn soem_style(
    iface: &str,
    drives: u16,
    timeout: Duration,
    cycles: u64,
    pid: Option<u32>,
) -> Result<SoemReport, String> {
    let _priority = MasterPriority::take();
    let mut m = SocketMaster::open(iface, timeout).map_err(|e| e.to_string())?;
    let lost = |m: &SocketMaster, step: &str| -> Result<(), String> {
        if m.lost == 0 {
            Ok(())
        } else {
            Err(format!(
                "{step}: {} frame(s) not back within {timeout:?}",
                m.lost
            ))
        }
    };
    to_pre_op(&mut m, drives)?;
    lost(&m, "Pre-Op")?;
    to_safe_op(&mut m, drives, TimeBase::Shared)?;
    lost(&m, "Safe-Op")?;
    start_cyclic_between_pulses(&mut m, drives);
    for st in stations(drives) {
        m.request_state(st, 0x0008);
    }
    all_in(&mut m, stations(drives), 0x08, "Op")?;
    lost(&m, "Op")?;
    let rep = run_cycles(&mut m, drives, cycles, pid);
    for st in stations(drives) {
        m.request_state(st, 0x0001);
    }
    Ok(rep)
}

/// The station addresses of `drives` drives: 0x1001…
pub fn stations(drives: u16) -> impl Iterator<Item = u16> {
    (0..drives).map(|i| 0x1001 + i)
}

/// `ecx_config_init`: Init + ack to all, count, station addresses, identity,
/// mailboxes, Pre-Op; then the SM types over SDO as `ecx_readPDOmap` starts.
pub fn to_pre_op<T: Transport>(m: &mut Master<T>, drives: u16) -> Result<(), String> {
    m.bwr(0x0120, &0x0011u16.to_le_bytes());
    let (_, found) = m.brd(0x0000, 2);
    if found != drives {
        return Err(format!(
            "{found} drive(s) answered the count, {drives} expected"
        ));
    }
    for (pos, st) in stations(drives).enumerate() {
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
    all_in(m, stations(drives), 0x02, "Pre-Op")?;
    for st in stations(drives) {
        m.sdo_upload(st, 0x1C00, 3)
            .map_err(|e| format!("SDO 0x1C00:03 of {st:#06x}: {e:?}"))?;
    }
    Ok(())
}

/// How a master gives the drives their distributed-clock time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimeBase {
    /// One time base for all drives, as SOEM's `ecx_configdc` ([`configdc_all`]):
    /// SYNC0 pulses started for the same system time come together.
    Shared,
    /// A latch and an offset per drive, one drive after the other: each drive's
    /// system time is off by the time between the set-up of the drives, so their
    /// SYNC0 pulses have phases of their own (what a master may do; the drives must
    /// keep their cycles whatever the phases).
    PerDrive,
}

/// `ecx_config_map_group` (SMs and FMMUs), the distributed clocks (`base`),
/// `ecx_dcsync0` at 1 ms, Safe-Op.
pub fn to_safe_op<T: Transport>(
    m: &mut Master<T>,
    drives: u16,
    base: TimeBase,
) -> Result<(), String> {
    let per = OUT_BYTES + IN_BYTES;
    for (k, st) in stations(drives).enumerate() {
        if m.process_data_sms(st, (k * per) as u32, OUT_BYTES, IN_BYTES) != 2 {
            return Err(format!("SyncManagers / FMMUs of {st:#06x}"));
        }
    }
    match base {
        TimeBase::Shared => configdc_all(m, stations(drives), 789_000_000_000),
        TimeBase::PerDrive => {
            for st in stations(drives) {
                m.soem_configdc(st, 789_000_000_000);
            }
        }
    }
    for st in stations(drives) {
        m.soem_dcsync(st, 1_000_000, 0, 0x03);
        m.request_state(st, 0x0004);
    }
    all_in(m, stations(drives), 0x04, "Safe-Op")
}

/// Process data before and during the Op request, as SOEM's applications do, in
/// the middle between two SYNC0 pulses (SOEM's examples align their cycle to the
/// DC time, `ec_sync`): the next pulse's system time (0x0990) against the system
/// time now (0x0910) gives the pulse on the master's clock.
pub fn start_cyclic_between_pulses<T: Transport>(m: &mut Master<T>, drives: u16) {
    let per = OUT_BYTES + IN_BYTES;
    let wkc = 3 * drives;
    let t0 = m.link.now_ns();
    let st = m.fprd_u64(0x1001, 0x0910);
    let t1 = m.link.now_ns();
    let next = m.fprd_u64(0x1001, 0x0990);
    let pulse = (t0 + t1) / 2 + next.saturating_sub(st);
    let aim = pulse + 500_000;
    let now = m.link.now_ns();
    // Set up whole, chunks included, before the first LRW (`start_cyclic` would send
    // one LRW of every drive's data at once: more than one frame holds beyond 47
    // drives).
    m.cyclic = Some(Cyclic {
        period_ns: 1_000_000,
        next_ns: if aim >= now {
            aim - (aim - now) / 1_000_000 * 1_000_000
        } else {
            aim + (now - aim).div_ceil(1_000_000) * 1_000_000
        },
        len: usize::from(drives) * per,
        sent: 0,
        good: 0,
        wkc,
        chunk: DRIVES_PER_FRAME * per,
    });
    m.wait(20_000_000, 1_000_000);
}

/// `cycles` LRWs in Op, measured: counts, round trips, CPU time of process `pid`,
/// then the AL status of every drive (LRWs between the reads).
fn run_cycles(m: &mut SocketMaster, drives: u16, cycles: u64, pid: Option<u32>) -> SoemReport {
    let mut rep = SoemReport {
        setup_frames: (m.frames, m.lost),
        ..SoemReport::default()
    };
    let counts = |m: &SocketMaster| m.cyclic.map_or((0, 0), |c| (c.sent, c.good));
    let (c0, l0, r0) = (counts(m), m.lost, m.rtt_ns.len());
    let cpu0 = (pid.and_then(process_cpu_s).unwrap_or(0.0), Instant::now());
    // `cycles` LRWs, however long the host keeps the master itself from running (given
    // up after three times their time and a second).
    let limit = Instant::now() + Duration::from_millis(3 * cycles + 1000);
    while counts(m).0 < c0.0 + cycles && Instant::now() < limit {
        m.wait(1_000_000, 1_000_000);
    }
    rep.cyclic_cpu_s = (
        pid.and_then(process_cpu_s).unwrap_or(0.0) - cpu0.0,
        cpu0.1.elapsed().as_secs_f64(),
    );
    let c1 = counts(m);
    rep.rtt_us = m.rtt_ns[r0..].iter().map(|&n| n as f64 * 1e-3).collect();
    rep.rtt_us.sort_by(f64::total_cmp);
    rep.lrw = (c1.0 - c0.0, c1.1 - c0.1);
    rep.lost_in_op = m.lost - l0;
    rep.stray = m.stray;
    // LRWs between the reads: a drive whose outputs stop coming leaves Op (0x001A)
    // within a few SYNC0 pulses, as it should.
    rep.al_after = stations(drives)
        .map(|st| {
            let s = m.al_status(st);
            m.wait(50_000, 50_000);
            s
        })
        .collect();
    rep
}
