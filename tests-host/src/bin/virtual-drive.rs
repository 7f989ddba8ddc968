//! `virtual-drive`: N simulated drives (firmware library + ESC simulator + motor plant)
//! on a Linux network interface, so real EtherCAT masters (SOEM, IgH, TwinCAT,
//! ethercrab) on the other end of a cable or veth pair see real drives.
//!
//! ```text
//! virtual-drive --iface NAME [--drives N] [--motor ECN57-20|TC86-45]
//!               [--esc lan9252|et1100] [--flash FILE] [--rt-priority 1..99|off]
//!               [--fault KIND@TIME]... [--dip-id BITS] [--dip-function BITS]
//!               [--input INn=on|off|pulse:PERIOD]...
//! ```
//!
//! Runs in real time: simulated time follows the wall clock, from the end of the
//! drives' power-up (run first in simulated time, as fast as the machine goes: the
//! plant models tune their current loops; [`tests_host::realtime::power_up`]). As on a board, where
//! the ESC answers every frame in hardware whatever the MCU is doing, one thread
//! answers the frames at once against the simulated ESCs and another runs the drives
//! (slave runtimes, drive ticks, axis models) beside it: see
//! [`tests_host::realtime`]. The frame thread runs at SCHED_FIFO priority 20 when the
//! process may (`--rt-priority`), the drives' thread at 19 while it needs less than
//! 80 % of a core ([`tests_host::realtime::AppPriority`]). Neither thread busy-waits: with no master the
//! process wakes once per 1 ms tick. Prints one line containing `ready` once it
//! listens; SIGINT/SIGTERM close it within a few ms.
//!
//! `--dip-id` / `--dip-function` set the board's two DIP banks as they stand at
//! power-up (eight characters 1 = ON / 0 = OFF, switch 1 first; default all ON): the
//! ID bank gives the station alias, the function bank the peak and standstill
//! current, the direction and the smoothing while 0x2025 = 0 (0x2158 shows what they
//! select). The log shows every change of the output pins and the brake.
//!
//! `--input INn=LEVEL` (repeatable) holds input n of every drive at a level (`on`,
//! `off`) or toggles it (`pulse:200ms`: high the first half of every period), so
//! that the input functions of 0x2152 (e.g. "probe" for touch probe 1) can be tried;
//! see [`tests_host::sim_inputs`].
//!
//! `--fault KIND@TIME` (repeatable) makes every drive's plant develop a fault TIME
//! after the start (`5s`, `250ms`): see `tests_host::fault_inject` for the kinds; the
//! drive's own detections then report it. The log shows each injection and every
//! change of the LEDs (RUN, ERR, red fault LED) with its time. Bad options: a message
//! and exit code 2.
#![deny(clippy::undocumented_unsafe_blocks)]

use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use ecat_slave_stack::od::{Dictionary, ObjectKey};
use firmware::runtime::DipBanks;
use tests_host::esc_sim::Flavour;
use tests_host::fault_inject::{self, Injection, LedLog, PinLog, Schedule};
use tests_host::raw_socket::RawSocket;
use tests_host::realtime::{self, Irq, WireStats};
use tests_host::segment::Segment;
use tests_host::sim_drive::{self, Motor, SimDrive, SimDriveConfig};
use tests_host::sim_inputs::{ForcedInput, ForcedInputs};

/// Set by SIGINT / SIGTERM; both threads end within a wait.
static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

struct Options {
    iface: String,
    drives: usize,
    motor: Motor,
    flavour: Flavour,
    flash: Option<String>,
    faults: Vec<Injection>,
    dips: DipBanks,
    inputs: ForcedInputs,
    /// SCHED_FIFO priority of the frame thread (`None`: normal priority).
    rt_priority: Option<i32>,
}

/// SCHED_FIFO priority of the frame thread unless `--rt-priority` says otherwise.
const DEFAULT_RT_PRIORITY: i32 = 20;

fn usage() -> String {
    let mut u = String::from(
        "usage: virtual-drive --iface NAME [--drives N] [--motor ECN57-20|TC86-45] \
         [--esc lan9252|et1100] [--flash FILE] [--rt-priority 1..99|off] \
         [--fault KIND@TIME]... [--dip-id BITS] [--dip-function BITS] [--input INn=LEVEL]...\n\
         \n  --rt-priority P    SCHED_FIFO priority of the thread that answers frames\n\
         \x20                    (default 20; needs root or CAP_SYS_NICE, else normal);\n\
         \x20                    the drives' thread runs at P-1 while it needs < 80 %\n\
         \x20                    of a core. off: normal priority\n\
         \n  --dip-id BITS      the ID bank's 8 switches as they stand, 1 = ON, switch 1\n\
         \x20                    first (default 11111111: no DIP station address)\n\
         \x20 --dip-function BITS  the function bank likewise: SW1-3 peak current, SW4\n\
         \x20                    standstill current, SW5 direction, SW6-7 smoothing; used\n\
         \x20                    while 0x2025 = 0 (default 11111111)\n\
         \n  --input INn=LEVEL  holds input n (1-5) of every drive at LEVEL: on, off, or\n\
         \x20                    pulse:PERIOD (high the first half of every PERIOD, e.g.\n\
         \x20                    pulse:200ms); repeatable. Without it IN1-IN3 follow the\n\
         \x20                    model's home and limit switches, IN4-IN5 stay low\n\
         \n  --fault KIND@TIME  the plant develops a fault TIME after start (e.g. 5s, 250ms);\n\
         \x20                    repeatable. KIND:",
    );
    for k in fault_inject::InjectedFault::ALL {
        u.push_str(&format!("\n    {:<18} {}", k.name(), k.effect()));
    }
    u
}

fn parse(args: &[String]) -> Result<Options, String> {
    let mut o = Options {
        iface: String::new(),
        drives: 1,
        motor: Motor::Ecn57_20,
        flavour: Flavour::Lan9252,
        flash: None,
        faults: Vec::new(),
        dips: sim_drive::DIPS_ALL_ON,
        inputs: ForcedInputs::default(),
        rt_priority: Some(DEFAULT_RT_PRIORITY),
    };
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = |name: &str| {
            it.next()
                .cloned()
                .ok_or_else(|| format!("{name} needs a value"))
        };
        match a.as_str() {
            "--iface" => o.iface = value("--iface")?,
            "--drives" => {
                o.drives = value("--drives")?
                    .parse()
                    .map_err(|_| "--drives needs a number".to_string())?;
                if !(1..=256).contains(&o.drives) {
                    return Err("--drives must be 1..256".into());
                }
            }
            "--motor" => {
                o.motor = match value("--motor")?.to_ascii_uppercase().as_str() {
                    "ECN57-20" => Motor::Ecn57_20,
                    "TC86-45" => Motor::Tc86_45,
                    m => return Err(format!("unknown motor '{m}' (ECN57-20 or TC86-45)")),
                }
            }
            "--esc" => {
                o.flavour = match value("--esc")?.to_ascii_lowercase().as_str() {
                    "lan9252" => Flavour::Lan9252,
                    "et1100" => Flavour::Et1100,
                    e => return Err(format!("unknown ESC '{e}' (lan9252 or et1100)")),
                }
            }
            "--flash" => o.flash = Some(value("--flash")?),
            "--dip-id" => o.dips.id = fault_inject::parse_dip(&value("--dip-id")?)?,
            "--dip-function" => {
                o.dips.function = fault_inject::parse_dip(&value("--dip-function")?)?
            }
            "--input" => o.inputs.0.push(ForcedInput::parse(&value("--input")?)?),
            "--rt-priority" => {
                o.rt_priority = match value("--rt-priority")?.as_str() {
                    "off" => None,
                    p => match p.parse() {
                        Ok(n @ 1..=99) => Some(n),
                        _ => return Err("--rt-priority needs 1..99 or off".into()),
                    },
                }
            }
            "--fault" => o
                .faults
                .push(fault_inject::parse_injection(&value("--fault")?)?),
            "-h" | "--help" => return Err(usage()),
            other => return Err(format!("unknown argument '{other}'\n{}", usage())),
        }
    }
    if o.iface.is_empty() {
        return Err(format!("--iface is required\n{}", usage()));
    }
    Ok(o)
}

/// A drive whose update was accepted resets on Bootstrap → Init, as the board does:
/// the bootloader swaps, the new image starts on trial.
fn restart_after_update(seg: &mut Segment<SimDrive>, log: &mut dyn FnMut(String)) {
    for i in sim_drive::restart_requested(seg) {
        let d = &mut seg.drive_mut(i).app;
        let mut v = [0u8; 16];
        let n = Dictionary::read(d, ObjectKey::new(0x100A, 0), &mut v).unwrap_or(0);
        log(format!(
            "drive {}: firmware update accepted; reset into the bootloader ({:?}); now \
             running {} on trial (0x2309 = 1) until it reaches Pre-Op",
            i + 1,
            d.boot_state(),
            String::from_utf8_lossy(&v[..n])
        ));
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let opts = match parse(&args) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("virtual-drive: {e}");
            return ExitCode::from(2);
        }
    };
    let (sock, mut seg, booted_ns) = match start_drives(&opts) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("virtual-drive: {e}");
            return ExitCode::from(1);
        }
    };
    // SAFETY: installing a handler that only stores to an atomic.
    unsafe {
        libc::signal(libc::SIGINT, on_signal as *const () as libc::sighandler_t);
        libc::signal(libc::SIGTERM, on_signal as *const () as libc::sighandler_t);
    }
    announce(&opts);
    // The wire thread answers frames; this thread is the drives' microcontrollers.
    let now = Instant::now();
    let start = now
        .checked_sub(Duration::from_nanos(booted_ns))
        .unwrap_or(now);
    let irq = Arc::new(Irq::default());
    let wire_stats = Arc::new(WireStats::default());
    let wire = match realtime::spawn_wire(
        opts.rt_priority,
        |fifo| match fifo {
            Some(Ok(())) => {}
            Some(Err(e)) => {
                println!("virtual-drive: frame thread at normal priority (SCHED_FIFO refused: {e})")
            }
            None => println!("virtual-drive: frame thread at normal priority (--rt-priority off)"),
        },
        sock,
        seg.escs(),
        seg.config().hop_ns,
        start,
        &STOP,
        irq.clone(),
        wire_stats.clone(),
    ) {
        Ok(w) => w,
        Err(e) => {
            eprintln!("virtual-drive: cannot start the frame thread: {e}");
            return ExitCode::from(1);
        }
    };
    let app = run_drives(&mut seg, &opts, start, &irq, &wire_stats, &wire);
    STOP.store(true, Ordering::SeqCst);
    let mut code = ExitCode::SUCCESS;
    match wire.join() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => {
            eprintln!("virtual-drive: {e}");
            code = ExitCode::from(1);
        }
        Err(_) => {
            eprintln!("virtual-drive: the frame thread panicked");
            code = ExitCode::from(1);
        }
    }
    sim_drive::shutdown(&mut seg);
    report_stop(&seg, &wire_stats, &app);
    code
}

/// The last line: frames, the frame thread's longest answer, the drives' thread's
/// timing, and the AL control writes an ESC did not take.
fn report_stop(seg: &Segment<SimDrive>, wire_stats: &WireStats, app: &AppTiming) {
    // AL control writes an ESC did not take because the drive had not read the
    // previous one yet (ETG.1000.4): a master's state request lost that way.
    let not_taken: u64 = (0..seg.len())
        .map(|i| seg.esc(i).stats().al_control_writes_ignored)
        .sum();
    println!(
        "virtual-drive: stopped after {} frames ({} send errors, longest answer {:.3} ms; \
         drives' thread: latest wake {:.3} ms, longest step {:.3} ms; AL control writes \
         not taken: {not_taken})",
        wire_stats.frames.load(Ordering::Relaxed),
        wire_stats.send_errors.load(Ordering::Relaxed),
        wire_stats.longest_ns.load(Ordering::Relaxed) as f64 * 1e-6,
        app.late_ns as f64 * 1e-6,
        app.step_ns as f64 * 1e-6
    );
}

/// The raw socket and the powered-up drives (the plant models tune their current
/// loops before the frames are answered); the simulated time reached, ns.
fn start_drives(opts: &Options) -> Result<(RawSocket, Segment<SimDrive>, u64), String> {
    let sock = RawSocket::open(&opts.iface).map_err(|e| e.to_string())?;
    let cfg = SimDriveConfig {
        motor: opts.motor,
        flavour: opts.flavour,
        flash_file: opts.flash.clone().map(Into::into),
        dips: opts.dips,
    };
    let mut seg = sim_drive::segment(&cfg, opts.drives)
        .map_err(|e| format!("cannot start the simulated drives: {e}"))?;
    // Real time: the plant models may skip their work while the axes rest.
    for d in seg.drives_mut() {
        d.app.axis.skip_rest(true);
        d.app.inputs = opts.inputs.clone();
    }
    if cfg.flash_file.is_none() {
        // Without --flash the update's partitions live in memory (lost at exit).
        sim_drive::attach_updates_in_memory(&mut seg, opts.flavour);
    }
    // Real time then goes on from the simulated time reached.
    let booted_ns = realtime::power_up(&mut seg);
    Ok((sock, seg, booted_ns))
}

/// The `ready` line and the faults scheduled.
fn announce(opts: &Options) {
    println!(
        "virtual-drive: {} drive(s), {:?} ESC, motor {:?}, parameter flash {} — ready on {}",
        opts.drives,
        opts.flavour,
        opts.motor,
        opts.flash.as_deref().unwrap_or("in RAM"),
        opts.iface
    );
    for f in &opts.faults {
        println!(
            "virtual-drive: fault {} scheduled at {:.3} s",
            f.fault.name(),
            f.at_ns as f64 * 1e-9
        );
    }
}

/// How the drives' thread kept time: how late it woke for a deadline at worst, and
/// its longest step, ns.
struct AppTiming {
    late_ns: u64,
    step_ns: u64,
}

/// The drives' thread until SIGINT / SIGTERM or the end of the frame thread: steps
/// the drives, applies the faults due, restarts updated drives, logs LEDs and pins
/// once per tick and the AL states every 10 s, and sleeps until a frame or the next
/// deadline.
fn run_drives(
    seg: &mut Segment<SimDrive>,
    opts: &Options,
    start: Instant,
    irq: &Irq,
    wire_stats: &WireStats,
    wire: &std::thread::JoinHandle<Result<(), String>>,
) -> AppTiming {
    let mut schedule = Schedule::new(opts.faults.clone());
    let (mut leds, mut pins) = (LedLog::default(), PinLog::default());
    let mut log = |line: String| println!("virtual-drive: {line}");
    leds.observe(seg, &mut log);
    pins.observe(seg, &mut log);
    // The drives' thread just below the frame thread (see `AppPriority`).
    let (mut app_priority, _) = realtime::AppPriority::new(opts.rt_priority.map(|p| p.max(2) - 1));
    let mut last_report = Instant::now();
    let mut timing = AppTiming {
        late_ns: 0,
        step_ns: 0,
    };
    let (mut deadline, mut raised, mut observed_tick) = (0u64, true, 0);
    while !STOP.load(Ordering::SeqCst) {
        if let Some(line) = app_priority.update() {
            log(line);
        }
        let now_ns = start.elapsed().as_nanos() as u64;
        if !raised {
            timing.late_ns = timing.late_ns.max(now_ns.saturating_sub(deadline));
        }
        realtime::step(seg, now_ns);
        let took = (start.elapsed().as_nanos() as u64).saturating_sub(now_ns);
        timing.step_ns = timing.step_ns.max(took);
        schedule.apply_due(seg, &mut log);
        restart_after_update(seg, &mut log);
        // LEDs and pins change in the drives' 1 ms ticks: looked at once per tick.
        let tick = seg.now_ns() / realtime::TICK_NS;
        if tick != observed_tick {
            observed_tick = tick;
            leds.observe(seg, &mut log);
            pins.observe(seg, &mut log);
        }
        if last_report.elapsed() > Duration::from_secs(10) {
            last_report = Instant::now();
            let states: Vec<String> = (0..seg.len())
                .map(|i| format!("{:#04x}", seg.al_status(i).0))
                .collect();
            println!(
                "virtual-drive: {} frames, AL status [{}]",
                wire_stats.frames.load(Ordering::Relaxed),
                states.join(" ")
            );
        }
        if wire.is_finished() {
            break;
        }
        deadline = realtime::next_deadline_ns(seg);
        raised = irq.wait_until(realtime::instant_at(start, deadline));
    }
    timing
}
