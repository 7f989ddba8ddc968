//! Scale (issue 9 item 4): virtual segments of N simulated drives — each the complete
//! firmware `Drive` behind the slave runtime and the ESC simulator, with the kinematic
//! axis — driven by ethercrab 0.7 in-process at a 1 ms cycle in simulated time. Every
//! drive is enabled in CSP and follows a ramp.
//!
//! Measured per N: the CPU time this process spends per simulated second (thread CPU
//! time, so other load on the machine does not count), split into the segment (ESC
//! frame processing, slave runtimes, firmware, axes, the 100 µs time steps) and
//! everything else (ethercrab, the executor). One core keeps N drives in real time
//! when the segment's time per 1 ms cycle stays below 1 ms — the same work
//! `virtual-drive` does per cycle (plus socket I/O). A measurement, not a test: the
//! figures depend on the machine.
//!
//! Usage: `scale [--seconds S] [--drives 8,16,32,64,128,256] [OUT.md]` (release build);
//! with `OUT.md` the section "Scale" of that file is replaced (or appended).
#![deny(clippy::undocumented_unsafe_blocks)]

use std::cell::RefCell;
use std::fmt::Write as _;
use std::rc::Rc;

use ethercrab::{MainDevice, PduStorage};
use tests_host::esc_sim::frame::{datagrams, FrameOutcome, Wire};
use tests_host::esc_sim::Flavour;
use tests_host::ethercrab_seam::{sim_config, sim_now_ns, sim_timeouts, MasterHarness};
use tests_host::segment::Segment;
use tests_host::sim_drive::{self, AxisModel, Motor, SimDrive, SimDriveConfig};

const SECTION: &str = "## Scale";
const MAX_DRIVES: usize = 512;
const MAX_PDI: usize = 16384;
/// Bytes of the default maps: 0x1600 12 B outputs, 0x1A00 19 B inputs.
const OUT_BYTES: usize = 12;
const CYCLE_NS: u64 = 1_000_000;

static PDU_STORAGE: PduStorage<16, { PduStorage::element_size(1500) }> = PduStorage::new();

/// CPU time of this thread, s.
fn thread_cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid timespec to write to.
    let r = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    if r != 0 {
        return 0.0;
    }
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// The segment as ethercrab's wire, timing its own work.
struct TimedWire {
    seg: Segment<SimDrive>,
    /// CPU seconds spent in the segment (frames and time steps).
    busy_s: f64,
    /// (logical address, length) of the LRW datagrams seen since the last clear.
    lrw: Vec<(u32, usize)>,
}

impl TimedWire {
    fn advance(&mut self, dt_ns: u64) {
        let t0 = thread_cpu_s();
        sim_drive::advance(&mut self.seg, dt_ns);
        self.busy_s += thread_cpu_s() - t0;
    }
}

impl Wire for TimedWire {
    fn transfer(&mut self, frame: &mut [u8]) -> FrameOutcome {
        let t0 = thread_cpu_s();
        let o = sim_drive::process(&mut self.seg, frame);
        self.busy_s += thread_cpu_s() - t0;
        for d in datagrams(frame).unwrap_or_default() {
            if d.cmd == 0x0C {
                self.lrw.push((d.addr, d.data.len()));
            }
        }
        o
    }
    fn now_ns(&self) -> u64 {
        self.seg.now_ns()
    }
}

/// Result of one N.
#[derive(Debug, Default, Clone)]
struct Run {
    drives: usize,
    cycles: u64,
    wkc_ok: u64,
    enabled: usize,
    expected_wkc: u16,
    lrw_chunks: usize,
    segment_s: f64,
    total_s: f64,
}

/// The group in Op.
type OpGroup = ethercrab::SubDeviceGroup<
    MAX_DRIVES,
    MAX_PDI,
    ethercrab::DefaultLock,
    ethercrab::subdevice_group::Op,
>;

async fn scenario(
    md: Rc<MainDevice<'static>>,
    wire: Rc<RefCell<TimedWire>>,
    n: usize,
    cycles: u64,
) -> Result<Run, ethercrab::error::Error> {
    let group = md
        .init_single_group::<MAX_DRIVES, MAX_PDI>(sim_now_ns)
        .await?;
    for sd in group.iter(&md) {
        sd.sdo_write(0x6060, 0, 8i8).await?;
    }
    let group = group.into_op(&md).await?;
    let mut run = Run {
        drives: n,
        ..Run::default()
    };
    let (expected_wkc, lrw_chunks) = expected_working_counter(&md, &group, &wire).await?;
    run.lrw_chunks = lrw_chunks;
    // Enable first (not timed), then the timed cycles.
    let mut target = vec![0i32; n];
    for k in 0..10 {
        set_outputs(&md, &group, k, &mut target);
        group.tx_rx(&md).await?;
        let left = CYCLE_NS - sim_now_ns() % CYCLE_NS;
        wire.borrow_mut().advance(left);
    }
    wire.borrow_mut().busy_s = 0.0;
    let t_cpu = thread_cpu_s();
    for k in 10..10 + cycles {
        set_outputs(&md, &group, k, &mut target);
        let r = group.tx_rx(&md).await?;
        run.cycles += 1;
        if r.working_counter == expected_wkc {
            run.wkc_ok += 1;
        }
        let left = CYCLE_NS - sim_now_ns() % CYCLE_NS;
        wire.borrow_mut().advance(left);
    }
    run.total_s = thread_cpu_s() - t_cpu;
    run.segment_s = wire.borrow().busy_s;
    // Statusword (bytes 2..4 of 0x1A00) "operation enabled".
    run.expected_wkc = expected_wkc;
    run.enabled = group
        .iter(&md)
        .filter(|sd| {
            let i = sd.inputs_raw();
            i.len() >= 4 && u16::from_le_bytes([i[2], i[3]]) & 0x6F == 0x27
        })
        .count();
    let group = group.into_safe_op(&md).await?;
    let group = group.into_pre_op(&md).await?;
    let _ = group.into_init(&md).await?;
    Ok(run)
}

/// The expected working counter of one `tx_rx` and the number of LRW datagrams it
/// takes. The PDI of N drives may need several LRW datagrams (one per frame); a drive
/// whose image straddles two of them counts in both. Expected working counter = Σ over
/// the LRW chunks of (2 per drive whose outputs it touches + 1 per drive whose inputs
/// it touches), from each drive's place in ethercrab's PDI.
async fn expected_working_counter(
    md: &MainDevice<'static>,
    group: &OpGroup,
    wire: &RefCell<TimedWire>,
) -> Result<(u16, usize), ethercrab::error::Error> {
    let mut segs = Vec::new();
    for sd in group.iter(md) {
        let i = sd.inputs_raw();
        let ip = (i.as_ptr() as usize, i.len());
        drop(i);
        let o = sd.outputs_raw_mut();
        segs.push((ip, (o.as_ptr() as usize, o.len())));
    }
    let base = segs.iter().flat_map(|(i, o)| [i.0, o.0]).min().unwrap_or(0);
    wire.borrow_mut().lrw.clear();
    group.tx_rx(md).await?;
    let chunks = std::mem::take(&mut wire.borrow_mut().lrw);
    let start = chunks.first().map_or(0, |c| c.0);
    let overlaps = |(p, len): (usize, usize), (a, l): (u32, usize)| {
        let s0 = (p - base) as u64 + start as u64;
        let c0 = a as u64;
        len > 0 && s0 < c0 + l as u64 && c0 < s0 + len as u64
    };
    let expected_wkc: u16 = chunks
        .iter()
        .map(|&c| {
            segs.iter()
                .map(|&(i, o)| 2 * overlaps(o, c) as u16 + overlaps(i, c) as u16)
                .sum::<u16>()
        })
        .sum();
    Ok((expected_wkc, chunks.len()))
}

/// The outputs of cycle `k`: the CiA 402 enable sequence, then a CSP target moving
/// one revolution per second (50 000 units).
fn set_outputs(md: &MainDevice<'static>, group: &OpGroup, k: u64, target: &mut [i32]) {
    let cw: u16 = match k {
        0..=2 => 0x0006,
        3..=5 => 0x0007,
        _ => 0x000F,
    };
    for (i, sd) in group.iter(md).enumerate() {
        if k > 8 {
            target[i] += 50;
        } else {
            // Follow the actual position until enabled (inputs and outputs share
            // one lock: read before writing).
            let inp = sd.inputs_raw();
            if inp.len() >= 9 {
                target[i] = i32::from_le_bytes([inp[5], inp[6], inp[7], inp[8]]);
            }
        }
        let mut o = sd.outputs_raw_mut();
        if o.len() < OUT_BYTES {
            continue;
        }
        o[0..2].copy_from_slice(&cw.to_le_bytes());
        o[2..6].copy_from_slice(&target[i].to_le_bytes());
    }
}

fn main() {
    let (seconds, drives, out) = parse_args();
    let cycles = (seconds * 1000.0).round().max(1.0) as u64;
    let runs = measure(&drives, cycles);
    let md = report(&runs, cycles);
    print!("{md}");
    if let Some(path) = out {
        if let Err(e) = tests_host::markdown::replace_section(&path, SECTION, &md) {
            eprintln!("scale: cannot write {path}: {e}");
            std::process::exit(1);
        }
    }
}

/// `--seconds S` (simulated seconds per N), `--drives N,N,…` and the Markdown file to
/// write into, with their defaults.
fn parse_args() -> (f64, Vec<usize>, Option<String>) {
    let mut seconds = 2.0f64;
    let mut drives = vec![8usize, 16, 32, 64, 128, 256];
    let mut out = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--seconds" => seconds = args.next().and_then(|s| s.parse().ok()).unwrap_or(seconds),
            "--drives" => {
                if let Some(list) = args.next() {
                    drives = list
                        .split(',')
                        .filter_map(|s| s.trim().parse().ok())
                        .filter(|n| (1..=MAX_DRIVES).contains(n))
                        .collect();
                }
            }
            _ => out = Some(a),
        }
    }
    (seconds, drives, out)
}

/// One run per segment size in `drives`, `cycles` timed cycles each; exits the
/// program when a segment cannot start or the master reports an error.
fn measure(drives: &[usize], cycles: u64) -> Vec<Run> {
    let cfg = SimDriveConfig {
        motor: Motor::Ecn57_20,
        flavour: Flavour::Lan9252,
        flash_file: None,
        dips: tests_host::sim_drive::DIPS_ALL_ON,
    };
    let mut h = match MasterHarness::new(&PDU_STORAGE) {
        Some(h) => h,
        None => {
            eprintln!("scale: PDU storage already in use");
            std::process::exit(1);
        }
    };
    let mut runs = Vec::new();
    for &n in drives {
        let seg = match sim_drive::segment_with(&cfg, n, AxisModel::Kinematic) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("scale: {n} drives: {e}");
                std::process::exit(1);
            }
        };
        let wire = Rc::new(RefCell::new(TimedWire {
            seg,
            busy_s: 0.0,
            lrw: Vec::new(),
        }));
        let w2 = wire.clone();
        let (res, stats) = h.run(wire.clone(), sim_timeouts(), sim_config(), |md| {
            scenario(md, w2, n, cycles)
        });
        match res {
            Ok(r) => {
                eprintln!(
                    "scale: {n} drives: segment {:.3} s, total {:.3} s CPU for {} cycles",
                    r.segment_s, r.total_s, r.cycles
                );
                runs.push(r);
            }
            Err(e) => {
                eprintln!("scale: {n} drives: ethercrab error {e:?}; {stats:?}");
                std::process::exit(1);
            }
        }
    }

    runs
}

/// The Markdown section of the runs.
fn report(runs: &[Run], cycles: u64) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "{SECTION}\n");
    let _ = writeln!(
        md,
        "Generated by `cargo run -p tests-host --release --bin scale -- docs/benchmarks-notes.md` \
         on the machine named below; a measurement, repeat it on yours. N simulated drives (the \
         complete firmware `Drive` + slave runtime + ESC simulator, LAN9252 flavour, direct PDI, \
         kinematic axis) in one segment, driven by ethercrab 0.7 in-process at a 1 ms cycle in \
         simulated time (LRW + ethercrab's AL status checks per cycle, SM-synchronous); every \
         drive enabled in CSP following a ramp; {cycles} timed cycles per N after 10 start-up \
         cycles. Times are CPU time of the one thread that runs everything (`CLOCK_THREAD_CPUTIME_ID`). \
         'segment' = the drives' side (ESC frame processing, slave runtimes polled every 100 µs \
         of simulated time, firmware cycles, axes) — the work `virtual-drive` does per cycle \
         besides socket I/O; 'master' = ethercrab and its executor. Expected WKC: 3 per drive, plus the \
         share counted twice where ethercrab splits the process image over several LRW datagrams \
         (one per frame) inside a drive's image.\n"
    );
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let _ = writeln!(md, "Machine: {cpu}, release build.\n");
    let _ = writeln!(
        md,
        "| drives | LRW datagrams per cycle | expected WKC | cycles with that WKC | enabled at the end | segment CPU per simulated s | master CPU per simulated s | segment per 1 ms cycle | per drive per cycle | real time on one core |\n|---|---|---|---|---|---|---|---|---|---|"
    );
    let mut best = None;
    for r in runs {
        let sim_s = r.cycles as f64 * 1e-3;
        let seg_per_s = r.segment_s / sim_s;
        let master_per_s = (r.total_s - r.segment_s).max(0.0) / sim_s;
        let per_cycle_us = r.segment_s / r.cycles as f64 * 1e6;
        let rt = per_cycle_us < 1000.0;
        if rt && r.wkc_ok == r.cycles {
            best = Some(r.drives);
        }
        let _ = writeln!(
            md,
            "| {} | {} | {} | {}/{} | {}/{} | {:.3} s | {:.3} s | {:.0} µs | {:.1} µs | {} |",
            r.drives,
            r.lrw_chunks,
            r.expected_wkc,
            r.wkc_ok,
            r.cycles,
            r.enabled,
            r.drives,
            seg_per_s,
            master_per_s,
            per_cycle_us,
            per_cycle_us / r.drives as f64,
            if rt { "yes" } else { "no" }
        );
    }
    let _ = writeln!(md);
    conclusion(&mut md, runs, best);
    md
}

/// The sentence under the table: the largest N that kept real time on one core.
fn conclusion(md: &mut String, runs: &[Run], best: Option<usize>) {
    match best {
        Some(n) => {
            let next = runs.iter().find(|r| r.drives > n).map(|r| {
                format!(
                    " ({} drives needed {:.0} µs)",
                    r.drives,
                    r.segment_s / r.cycles as f64 * 1e6
                )
            });
            let _ = writeln!(
                md,
                "Largest measured N whose segment work per 1 ms cycle stays below 1 ms on one core: \
                 **{n} drives**{}. The cost per drive grows with N: the segment polls every drive \
                 after every frame, and ethercrab needs more frames per cycle as N grows (LRW \
                 chunks and its AL status checks). For comparison, the Xinje drives advertise 32 \
                 axes at 1 ms; on real hardware every drive has its own CPU, so this figure is \
                 about the simulator (`virtual-drive`), not the firmware.",
                next.unwrap_or_default()
            );
        }
        None => {
            let _ = writeln!(
                md,
                "No measured N stayed below 1 ms of segment work per 1 ms cycle on one core."
            );
        }
    }
}
