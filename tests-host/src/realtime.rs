//! Real time for `virtual-drive`: the ESC answers frames like hardware, the
//! microcontroller side runs beside it.
//!
//! On a board the ESC processes every frame in hardware whatever the MCU does; the
//! MCU reaches the ESC memory over SPI, one access at a time, and learns of events
//! through the PDI interrupt line (SYNC0, SyncManager, AL control). `virtual-drive`
//! splits the same way:
//!
//! * the **wire thread** ([`spawn_wire`]) owns the raw socket. It sleeps until a
//!   frame arrives, moves the ESC simulators' clocks to the wall clock, runs the
//!   frame through them ([`process_frame_in_turn`]: each ESC busy only while the
//!   frame passes it) and sends it back at once, then raises
//!   the interrupt line ([`Irq`]). It never waits for the application or the plant,
//!   only for a PDI access in progress ([`SharedEsc`] holds its lock for one
//!   access).
//! * the **application thread** (the caller of [`step`]) runs the MCU side of every
//!   drive — the slave runtime's `poll` / cycle, the drive's 1 ms tick and the axis
//!   model ([`SimDrive::catch_up`]), the work after each poll
//!   ([`sim_drive::forward_emergencies`]) — against the same simulators, each
//!   drive's cycle at its own SYNC0 pulse's time. It sleeps until the interrupt line
//!   rises or the next deadline ([`next_deadline_ns`]: the next SYNC0 pulse of any
//!   drive, at most one wake per [`PULSE_WAKE_NS`] for them, the next 1 ms tick),
//!   whichever comes first.
//!
//! Nothing busy-waits: with no master the process wakes once per tick, once per
//! [`IDLE_TICKS`] ticks while every axis rests (the plant model then skips its PWM
//! periods too: [`crate::sim_axis::PlantAxis::set_rest_skip`]). When the
//! application thread falls behind (a loaded machine), frames are still answered;
//! on its next wake the missed SYNC0 pulses raise one event (as a DC unit's pulses
//! happen at their times: the drive runs one cycle, not a burst), the drive's ticks
//! run up to the present on its own clock, each after the axis moved to its time
//! (ticks due before a cycle run before it: [`SimDrive::catch_up`]).
//!
//! [`step`] takes the time as an argument, so the in-process tests drive it with
//! simulated time.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::esc_sim::frame::process_frame_in_turn;
use crate::esc_sim::SharedEsc;
use crate::raw_socket::RawSocket;
use crate::segment::Segment;
use crate::sim_drive::{self, SimDrive};

/// Period of the drive's supervision tick ([`SimDrive::catch_up`]), ns.
pub const TICK_NS: u64 = 1_000_000;

/// The PDI interrupt line from the wire thread to the application thread.
#[derive(Default)]
pub struct Irq {
    pending: Mutex<bool>,
    cv: Condvar,
}

impl Irq {
    /// Raises the line (a frame was processed).
    pub fn raise(&self) {
        *self.pending.lock().unwrap_or_else(|e| e.into_inner()) = true;
        self.cv.notify_one();
    }

    /// Sleeps until the line is raised or `deadline`; takes the line down. True when
    /// it was raised.
    pub fn wait_until(&self, deadline: Instant) -> bool {
        let mut p = self.pending.lock().unwrap_or_else(|e| e.into_inner());
        while !*p {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return false;
            }
            p = match self.cv.wait_timeout(p, left) {
                Ok((g, _)) => g,
                Err(e) => e.into_inner().0,
            };
        }
        *p = false;
        true
    }
}

/// Gives the calling thread the real-time policy SCHED_FIFO at `priority` (1-99), so
/// that it runs as soon as it wakes whatever else the machine does (root or
/// CAP_SYS_NICE needed; the kernel's real-time throttling still leaves the rest of
/// the machine 5 % of every second).
pub fn set_fifo(priority: i32) -> std::io::Result<()> {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: pid 0 is the calling thread; `param` is valid for the call.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Back to the normal policy (SCHED_OTHER) for the calling thread.
pub fn set_normal() {
    let param = libc::sched_param { sched_priority: 0 };
    // SAFETY: pid 0 is the calling thread; `param` is valid for the call.
    unsafe { libc::sched_setscheduler(0, libc::SCHED_OTHER, &param) };
}

/// CPU time of the calling thread, s.
pub fn thread_cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is valid for the call.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// The application thread's scheduling: SCHED_FIFO (below the frame thread) while it
/// uses at most [`AppPriority::HIGH`] of a core, so that its SYNC0 cycles are not
/// delayed by other load on the machine (a locked drive reports 0x002C after 2 ms
/// without SYNC0, as a board's MCU would if it stalled); the normal policy while it
/// needs more (a heavy simulation never takes a whole core from the rest of the
/// machine), back to SCHED_FIFO once it needs at most [`AppPriority::LOW`].
pub struct AppPriority {
    priority: Option<i32>,
    fifo: bool,
    since: Instant,
    cpu: f64,
}

impl AppPriority {
    /// Share of a core above which the thread leaves SCHED_FIFO.
    pub const HIGH: f64 = 0.8;
    /// Share of a core below which it returns to SCHED_FIFO.
    pub const LOW: f64 = 0.5;

    /// Starts with SCHED_FIFO at `priority` for the calling thread (none: normal
    /// policy throughout); the outcome of the first request.
    pub fn new(priority: Option<i32>) -> (Self, Option<std::io::Result<()>>) {
        let r = priority.map(set_fifo);
        let fifo = matches!(r, Some(Ok(())));
        let me = AppPriority {
            priority: priority.filter(|_| fifo),
            fifo,
            since: Instant::now(),
            cpu: thread_cpu_s(),
        };
        (me, r)
    }

    /// Once a second: measures the thread's share of a core and changes the policy
    /// when it crossed a bound; a line saying so.
    pub fn update(&mut self) -> Option<String> {
        let prio = self.priority?;
        let wall = self.since.elapsed().as_secs_f64();
        if wall < 1.0 {
            return None;
        }
        let cpu = thread_cpu_s();
        let share = (cpu - self.cpu) / wall;
        (self.since, self.cpu) = (Instant::now(), cpu);
        if self.fifo && share > Self::HIGH {
            set_normal();
            self.fifo = false;
            Some(format!(
                "drives' thread at {:.0} % of a core: normal priority from now on",
                share * 100.0
            ))
        } else if !self.fifo && share < Self::LOW && set_fifo(prio).is_ok() {
            self.fifo = true;
            Some(format!(
                "drives' thread at {:.0} % of a core: SCHED_FIFO {prio} again",
                share * 100.0
            ))
        } else {
            None
        }
    }
}

/// Counters of the wire thread, readable while it runs.
#[derive(Debug, Default)]
pub struct WireStats {
    /// Frames answered.
    pub frames: AtomicU64,
    /// Frames whose answer could not be sent.
    pub send_errors: AtomicU64,
    /// Longest time from a frame's receipt to its answer being sent, ns.
    pub longest_ns: AtomicU64,
}

/// How long the wire thread sleeps in one wait when no frame comes: the bound on
/// how late it sees `stop`.
const WIRE_WAIT_US: u64 = 20_000;

/// Starts the wire thread: frames from `sock` through `escs` (in line order, `hop_ns`
/// per hop) at the wall-clock time since `start`, answered at once, `irq` raised
/// after each. With `fifo`, the thread first asks for that SCHED_FIFO priority
/// ([`set_fifo`]); `on_start` gets the outcome. Ends when `stop` is set (within
/// [`WIRE_WAIT_US`]) or the socket fails (the error).
#[allow(clippy::too_many_arguments)]
pub fn spawn_wire(
    fifo: Option<i32>,
    on_start: impl FnOnce(Option<std::io::Result<()>>) + Send + 'static,
    sock: RawSocket,
    escs: Vec<SharedEsc>,
    hop_ns: u64,
    start: Instant,
    stop: &'static AtomicBool,
    irq: Arc<Irq>,
    stats: Arc<WireStats>,
) -> std::io::Result<JoinHandle<Result<(), String>>> {
    std::thread::Builder::new()
        .name("ecat-wire".into())
        .spawn(move || {
            on_start(fifo.map(set_fifo));
            let mut buf = vec![0u8; 2048];
            while !stop.load(Ordering::SeqCst) {
                match sock.wait_readable(WIRE_WAIT_US) {
                    Ok(true) => {}
                    Ok(false) => continue,
                    Err(e) => return Err(format!("poll: {e}")),
                }
                loop {
                    let n = match sock.recv(&mut buf) {
                        Ok(Some(n)) => n,
                        Ok(None) => break,
                        Err(e) => return Err(format!("receive: {e}")),
                    };
                    let received = Instant::now();
                    let now_ns = received.duration_since(start).as_nanos() as u64;
                    let frame = &mut buf[..n];
                    process_frame_in_turn(&escs, frame, now_ns, hop_ns);
                    if sock.send(frame).is_err() {
                        stats.send_errors.fetch_add(1, Ordering::Relaxed);
                    }
                    let took = received.elapsed().as_nanos() as u64;
                    stats.longest_ns.fetch_max(took, Ordering::Relaxed);
                    stats.frames.fetch_add(1, Ordering::Relaxed);
                    irq.raise();
                }
            }
            Ok(())
        })
}

/// The application side at time `now_ns`: every ESC's clock moves on (SYNC0,
/// watchdogs: one event for any number of pulses due); each slave whose ESC raised
/// SYNC0 since its last poll is polled at that pulse's own time, as the board's SYNC0
/// interrupt runs the cycle then (however late this thread wakes, and whatever the
/// phase of each drive's pulses: a master may give every drive its own); then the
/// slaves poll as on the board — each one whose ESC raises its interrupt, every one
/// at least once per millisecond ([`Segment::poll_pending`]) — the drives' 1 ms
/// ticks due by `now_ns` run ([`SimDrive::catch_up`]; a cycle brings its axis up to
/// its own time), then the work after the poll for the drives polled
/// ([`sim_drive::forward_emergencies_where`]). A time not ahead of the segment's
/// polls without moving time.
///
/// The cost is per drive with work: a drive without a pulse, an interrupt or a tick
/// due costs one look at its ESC.
pub fn step(seg: &mut Segment<SimDrive>, now_ns: u64) {
    let polls: Vec<u64> = seg.drives_mut().iter().map(|d| d.polls).collect();
    let now_ns = now_ns.max(seg.now_ns());
    for i in 0..seg.len() {
        let pulse = {
            let mut e = seg.esc(i);
            e.advance_to(now_ns);
            e.sync0_pending_since()
        };
        if let Some(t) = pulse {
            seg.poll_at(i, t);
        }
    }
    seg.advance_pending(now_ns);
    let now_us = seg.now_ns() / 1000;
    for d in seg.drives_mut() {
        if d.app.tick_due(now_us) {
            d.app.catch_up(now_us);
        }
    }
    // The work after each poll, for the drives polled in this step.
    let polled: Vec<bool> = seg
        .drives_mut()
        .iter()
        .zip(&polls)
        .map(|(d, &p)| d.polls != p)
        .collect();
    sim_drive::forward_emergencies_where(seg, |i| polled[i]);
}

/// Ticks run per wake while every axis rests ([`crate::sim_drive::Axis::resting`])
/// and no frame comes: the ticks still run on the drive's clock, 1 ms apart, but
/// `IDLE_TICKS` of them at once.
pub const IDLE_TICKS: u64 = 10;

/// Shortest time between two wakes for SYNC0 pulses, ns: with many drives whose
/// pulses have different phases, one wake serves every pulse of the last
/// `PULSE_WAKE_NS` (each at its own time, [`step`]) instead of one wake per drive.
/// Shorter than half a 1 ms cycle, so that each drive's cycle has run before a
/// master that exchanges in the middle between two pulses reads it.
pub const PULSE_WAKE_NS: u64 = 200_000;

/// When the application next has work without a frame, ns: the next SYNC0 pulse of
/// any drive (not before [`PULSE_WAKE_NS`] after the last step) or the next 1 ms tick
/// after the segment's time — the [`IDLE_TICKS`]-th while every axis rests.
pub fn next_deadline_ns(seg: &mut Segment<SimDrive>) -> u64 {
    let idle = seg.drives_mut().iter().all(|d| d.app.axis.resting());
    let ticks = if idle { IDLE_TICKS } else { 1 };
    let now = seg.now_ns();
    let tick = (now / TICK_NS + ticks) * TICK_NS;
    (0..seg.len())
        .filter_map(|i| seg.esc(i).next_sync0_ns())
        .min()
        .map_or(tick, |p| tick.min(p.max(now + PULSE_WAKE_NS)))
}

/// Longest power-up [`power_up`] runs, ns of simulated time.
pub const POWER_UP_MAX_NS: u64 = 3_000_000_000;

/// The drives' power-up before the frames are answered: [`step`] 1 ms at a time, in
/// simulated time as fast as the machine goes, until every axis rests
/// ([`crate::sim_drive::Axis::resting`]: the plant model's current-loop tune is done)
/// or [`POWER_UP_MAX_NS`]. Returns the simulated time reached, ns. Without it the
/// tune of four plant models would take the drives' thread a whole core for the
/// first half second, while a master sets them up.
pub fn power_up(seg: &mut Segment<SimDrive>) -> u64 {
    while seg.now_ns() < POWER_UP_MAX_NS && !seg.drives_mut().iter().all(|d| d.app.axis.resting()) {
        let t = seg.now_ns() + TICK_NS;
        step(seg, t);
    }
    seg.now_ns()
}

/// `t_ns` since `start` as an instant.
pub fn instant_at(start: Instant, t_ns: u64) -> Instant {
    start + Duration::from_nanos(t_ns)
}
