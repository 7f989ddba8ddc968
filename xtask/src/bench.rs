//! `cargo xtask bench`: instruction counts and painted stack depths under QEMU, the
//! control-quality report, the cycle budget → `BENCHMARKS.md`.

use std::fmt::Write as _;
use std::fs;
use std::path::Path;
use std::process::{Command, Stdio};

use crate::run::{cargo, run_capture, run_status};
use crate::test::ensure_tools;
use crate::THUMB;

/// Goals from the issues, by benchmark name.
const GOALS: &[(&str, &str)] = &[
    ("current loop step", "≤ 300"),
    // Issue 19: with the running checks, unsaturated (the saturated row says what the
    // checks cost when they run).
    ("supervised current step (unsaturated)", "≤ 300"),
    ("CSP cycle (unpack", "≤ 1500"),
];

/// Why a row may exceed its goal, by benchmark name: printed under the table when the
/// count is over the goal's bound.
const OVER_GOAL: &[(&str, &str)] = &[
    (
        "current loop step",
        "the step includes the dead-time compensation (two current-sign terms, linear \
         through zero; `foc::current_loop`, \"Dead-time compensation\") and the \
         current-sensing calibration's channel gains (folded into each channel's amperes \
         per count), about 28 instructions, and the \
         d/q decoupling on the measured currents on the encoder's angle (\"Decoupling\"), \
         about 6. They take the i_q ripple from 8-14 mA of dead time down to ≤ 2 mA, from \
         76-78 mA of sensor mismatch down to 4-7 mA, and near 10 rev/s, where the \
         encoder's count pattern beats against the commutation, from 26-31 mA down to \
         6-8 mA (\"Robustness\" below): what the motor's torque ripple and noise follow. \
         The current-loop interrupt stays at about 16 % of the CPU at 40 kHz (\"Cycle \
         time budget\").",
    ),
    (
        "CSP cycle (unpack",
        "1490 before the CSP set-points were limited by the acceleration limits \
         0x60C5 / 0x60C6 (a set-point jump is followed within 0x6080 and the acceleration \
         limits, `Params::csp_segment_speed`) and the position range 0x607B was added \
         (positions shown wrapped); 1685 before a limited segment started from the \
         demand at the new set-point's arrival and kept its speed under set-point jitter \
         (issue 33); not optimised yet. What it costs of a cycle: \
         \"Cycle time budget\" below.",
    ),
    (
        "supervised current step",
        "the same compensation inside the supervised step (see \"current loop step\").",
    ),
];

/// The bound of a goal "≤ N".
fn goal_bound(goal: &str) -> Option<u64> {
    goal.strip_prefix("≤ ")?.trim().parse().ok()
}

/// The update time of a 100 KiB image over FoE, worked out from the FoE rows and the
/// flash's data-sheet timing (BENCHMARKS.md, "Firmware update over FoE").
fn foe_update_time(md: &mut String, rows: &[(String, u64)], overhead: u64) {
    let count = |prefix: &str| {
        rows.iter()
            .find(|(n, _)| n.starts_with(prefix))
            .map(|(_, c)| c.saturating_sub(overhead))
    };
    let (Some(header), Some(plain), Some(flush), Some(hash4k), Some(sig)) = (
        count("FoE DATA 116 B completing the header"),
        count("FoE DATA 116 B, buffered"),
        count("FoE DATA 116 B with a 256 B write"),
        count("FoE last DATA repeat: SHA-512"),
        count("FoE last DATA repeat: ed25519"),
    ) else {
        md.push_str("\n(The FoE rows are missing: no update time.)\n");
        return;
    };
    const MHZ: f64 = 170.0;
    const CYCLES_PER_INSTRUCTION: f64 = 1.5; // flash wait states: a conservative guess
    const PROGRAM_US_PER_8B: f64 = 82.0;
    const ERASE_MS_PER_PAGE: f64 = 22.0;
    const MAILBOX_CYCLE_MS: f64 = 1.0;
    let image: f64 = 100.0 * 1024.0;
    let packets = ((image + 160.0) / 116.0).ceil();
    let chunks = (image / 256.0).ceil();
    let pages = (image / 2048.0).ceil() + 1.0;
    let ms = |instr: f64| instr * CYCLES_PER_INSTRUCTION / (MHZ * 1000.0);
    // The check of the complete image, in steps (`firmware::update`): 4 KiB hashed
    // per BUSY answer, then the image signature.
    let hash_per_kib = hash4k as f64 / 4.0;
    let steps = (image / 4096.0).ceil() + 4.0;
    let verify_ms = ms(sig as f64 + 100.0 * hash_per_kib);
    let cpu_ms = ms(packets * plain as f64 + chunks * (flush - plain.min(flush)) as f64)
        + ms(header as f64)
        + verify_ms;
    let mailbox_ms = 2.0 * MAILBOX_CYCLE_MS * (packets + pages + steps);
    let program_ms = image / 8.0 * PROGRAM_US_PER_8B / 1000.0;
    let erase_ms = pages * ERASE_MS_PER_PAGE;
    let total_s = (mailbox_ms + program_ms + erase_ms + cpu_ms) / 1000.0;
    let _ = write!(
        md,
        "\n### Firmware update over FoE\n\n\
         Instructions per FoE DATA of 116 bytes (boot mailbox of 128 bytes), SM0 to the \
         answer, through the product's backend (`firmware::update`) and embassy-boot: \
         **{plain}** when the data is only buffered, **{flush}** when it completes a \
         256-byte chunk that goes to the DFU partition (RAM flash here). The DATA that \
         completes the header costs {header} (its ed25519 signature check). The DATA \
         that completes the image is answered BUSY while its check runs, one step per \
         answer: {hash4k} for 4 KiB of SHA-512 (≈ {hash_per_kib:.0} instructions per \
         KiB), {sig} for the image signature and the mark for the swap.\n\n\
         A 100 KiB image at a 1 ms mailbox cycle (each DATA and each BUSY one request \
         and one answer, 2 cycles), with the STM32G4's flash timing ({PROGRAM_US_PER_8B} µs \
         per 8 bytes programmed, {ERASE_MS_PER_PAGE} ms per 2 KiB page erased; \
         data-sheet figures, unverified on the board) and {CYCLES_PER_INSTRUCTION} cycles \
         per instruction at {MHZ} MHz: {packets} DATA and {pages} + {steps} BUSY answers = \
         {mailbox_ms:.0} ms of mailbox cycles, {program_ms:.0} ms programming, \
         {erase_ms:.0} ms erasing, {cpu_ms:.0} ms of processor time (of which the \
         image check {verify_ms:.0} ms, in steps before the last ACK) — **about {total_s:.1} s**, \
         the flash's own time included and not overlapped. After Bootstrap → Init comes \
         embassy-boot's swap of the 114 pages of the active partition (several page \
         erases and programs per page: of the order of 10 s, the drive dark meanwhile).\n"
    );
}

/// Builds the benchmark image and the QEMU plugin, runs the image twice, writes
/// `BENCHMARKS.md`; whether the two runs counted the same.
pub fn bench() -> bool {
    if let Err(e) = ensure_tools() {
        eprintln!("error: {e}");
        return false;
    }
    let target_dir = "target/bench";
    let Some((elf, plugin)) = build_image(target_dir) else {
        return false;
    };
    let (first, stacks, repeat) = match measure(&elf, &plugin) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return false;
        }
    };
    let mut md = String::new();
    write_counts(&mut md, &first, repeat);
    write_stacks(&mut md, &stacks);
    if let Err(e) = write_control_quality(&mut md)
        .and_then(|()| cycle_budget(target_dir, &first))
        .and_then(|()| virtual_drive_realtime())
        .and_then(|()| {
            crate::size::images_md().map(|t| {
                md.push('\n');
                md.push_str(&t);
            })
        })
    {
        eprintln!("error: {e}");
        return false;
    }
    if let Ok(extra) = fs::read_to_string("docs/benchmarks-notes.md") {
        md.push('\n');
        md.push_str(&extra);
    }
    if fs::write("BENCHMARKS.md", &md).is_err() {
        eprintln!("error: cannot write BENCHMARKS.md");
        return false;
    }
    println!(
        "wrote BENCHMARKS.md ({} benchmarks)",
        first.len().saturating_sub(1)
    );
    repeat
}

/// `cargo xtask bench images`: rebuilds the board images and replaces only the
/// "Images" section of `BENCHMARKS.md` (the rest as the last full run wrote it).
pub fn images_only() -> bool {
    const HEADING: &str = "## Images: flash, RAM and stack";
    let table = match crate::size::images_md() {
        Ok(t) => t,
        Err(e) => {
            eprintln!("error: {e}");
            return false;
        }
    };
    let old = fs::read_to_string("BENCHMARKS.md").unwrap_or_default();
    let mut out = String::new();
    let mut lines = old.lines().peekable();
    let mut placed = false;
    while let Some(l) = lines.next() {
        if l == HEADING {
            while lines.peek().is_some_and(|n| !n.starts_with("## ")) {
                lines.next();
            }
        } else {
            out.push_str(l);
            out.push('\n');
            continue;
        }
        out.push_str(&table);
        out.push('\n');
        placed = true;
    }
    if !placed {
        out.push('\n');
        out.push_str(&table);
    }
    fs::write("BENCHMARKS.md", out).is_ok()
}

/// The benchmark image and the instruction-count plugin: their paths.
fn build_image(target_dir: &str) -> Option<(String, String)> {
    if !run_status(&mut cargo(&[
        "build",
        "-p",
        "qemu-bench",
        "--target",
        THUMB,
        "--profile",
        "bench-qemu",
        "--target-dir",
        target_dir,
    ])) {
        return None;
    }
    let elf = format!("{target_dir}/{THUMB}/bench-qemu/qemu-bench");
    let plugin = format!("{target_dir}/libinsn_count.so");
    if !run_status(Command::new("gcc").args([
        "-O2",
        "-shared",
        "-fPIC",
        "-Wall",
        "-o",
        &plugin,
        "xtask/qemu-plugin/insn_count.c",
    ])) {
        eprintln!("error: building the QEMU plugin needs gcc");
        return None;
    }
    Some((elf, plugin))
}

/// Runs the image twice: the counts and stack depths of the first run, and whether
/// the second counted the same.
#[allow(clippy::type_complexity)]
fn measure(
    elf: &str,
    plugin: &str,
) -> Result<(Vec<(String, u64)>, Vec<(String, u64)>, bool), String> {
    let (Some(start), Some(stop)) = (symbol(elf, "bench_start"), symbol(elf, "bench_stop")) else {
        return Err(format!("marker symbols not found in {elf}"));
    };
    let (first, stacks) = run_bench_image_full(elf, plugin, start, stop)?;
    let second = run_bench_image(elf, plugin, start, stop)?;
    let repeat = first == second;
    eprintln!(
        "instruction counts of two runs {}",
        if repeat { "are identical" } else { "DIFFER" }
    );
    Ok((first, stacks, repeat))
}

/// The instruction-count table and the FoE update time.
fn write_counts(md: &mut String, first: &[(String, u64)], repeat: bool) {
    let overhead = first
        .iter()
        .find(|(n, _)| n == "(marker overhead)")
        .map_or(0, |(_, c)| *c);
    md.push_str("# Benchmarks\n\nGenerated by `cargo xtask bench`; do not edit by hand.\n\n");
    md.push_str("## Executed instructions under QEMU (Cortex-M4F, mps2-an386)\n\n");
    let _ = writeln!(
        md,
        "Counted by a QEMU TCG plugin (`xtask/qemu-plugin/insn_count.c`) between the entry of \
         `bench_start` and the entry of `bench_stop`, minus the {overhead} instructions of the \
         markers themselves. Build profile `bench-qemu` (opt-level 3, LTO). These are executed \
         instructions, not cycles: QEMU has no timing model. Two runs gave {} counts.\n",
        if repeat { "identical" } else { "DIFFERENT" }
    );
    md.push_str("| benchmark | goal | instructions |\n|---|---|---|\n");
    let mut over = String::new();
    for (name, count) in first {
        if name == "(marker overhead)" {
            continue;
        }
        let goal = GOALS
            .iter()
            .find(|(g, _)| name.starts_with(g))
            .map_or("—", |(_, g)| g);
        let count = count.saturating_sub(overhead);
        let _ = writeln!(md, "| {name} | {goal} | {count} |");
        if goal_bound(goal).is_some_and(|b| count > b) {
            let why = OVER_GOAL.iter().find(|(n, _)| name.starts_with(n)).map_or(
                "no reason recorded (xtask/src/bench.rs, OVER_GOAL).",
                |(_, w)| w,
            );
            let _ = writeln!(over, "- **{name}: {count}, over its goal {goal}**: {why}");
        }
    }
    if !over.is_empty() {
        md.push_str("\nRows over their goal:\n\n");
        md.push_str(&over);
    }

    foe_update_time(md, first, overhead);
}

/// The painted stack depths and their worst nesting.
fn write_stacks(md: &mut String, stacks: &[(String, u64)]) {
    md.push_str("\n## Stack depth of the library paths (painted, QEMU)\n\n");
    md.push_str(
        "Bytes of stack each path used, measured in the same image by painting the stack \
         below the caller and finding the deepest overwritten word \
         (`tests-host/qemu/bench/src/stack_benches.rs`; deepest of repeated runs).\n\n",
    );
    md.push_str("| path | context on the board | bytes |\n|---|---|---|\n");
    let context = |name: &str| {
        if name.starts_with("current-loop") {
            "ADC1_2 interrupt (current-loop level, below the break)"
        } else if name.starts_with("start-up") {
            "start-up (before the interrupts run)"
        } else if name.starts_with("CSP") {
            "cyclic executor (cyclic level) / 1 ms tick"
        } else {
            "thread mode (mailbox, storage tasks)"
        }
    };
    let mut worst = [0u64; 4];
    for (name, bytes) in stacks {
        let _ = writeln!(md, "| {name} | {} | {bytes} |", context(name));
        let k = match context(name) {
            c if c.starts_with("ADC") => 0,
            c if c.starts_with("cyclic") => 1,
            c if c.starts_with("start-up") => 3,
            _ => 2,
        };
        worst[k] = worst[k].max(*bytes);
    }
    // Worst nesting: a thread-mode path, preempted by the cyclic path, preempted by the
    // current loop; each preemption stacks an exception frame with the FPU context
    // (26 words = 104 bytes).
    let nested = worst[..3].iter().sum::<u64>() + 2 * 104;
    let _ = writeln!(
        md,
        "\nWorst nesting of these paths (thread {} + cyclic {} + interrupt {} bytes, plus two \
         exception frames with FPU context, 2 × 104 bytes): **{nested} bytes** of library \
         stack. Start-up, before the interrupts run, needs {} bytes on its own. The board's \
         task bodies come on top: `cargo xtask size` adds them up from the firmware ELF \
         (static worst case, docs/board/bring-up.md, \"Static stack report\"), and the board paints its \
         stack and reports the peak at run time (docs/board/bring-up.md, \"Stack\").",
        worst[2], worst[1], worst[0], worst[3]
    );
}

/// The control-quality tables of the plant simulation.
fn write_control_quality(md: &mut String) -> Result<(), String> {
    md.push_str("\n## Control quality (plant simulation)\n\n");
    let report = cargo(&[
        "run",
        "-q",
        "-p",
        "tests-host",
        "--release",
        "--bin",
        "control-report",
        "--",
        "--plots",
        "target/plots",
    ])
    .stderr(Stdio::inherit())
    .output();
    match report {
        Ok(o) if o.status.success() => {
            // Only the report's stdout goes into the file: its tables and their
            // headings (the plot paths it prints are kept out).
            for line in String::from_utf8_lossy(&o.stdout).lines() {
                if line.starts_with('|') || line.starts_with('#') || line.is_empty() {
                    md.push_str(line);
                    md.push('\n');
                }
            }
            md.push_str(
                "\nPlots: `target/plots/current_step.png`, `target/plots/csp_tracking_error.png`, \
                 `target/plots/iq_ripple_vs_speed.png` (docs/guide/tuning.md, \"Quiet current on a real motor\").\n",
            );
        }
        _ => {
            return Err("control-report failed".into());
        }
    }
    Ok(())
}

/// The real-time behaviour of `virtual-drive` (CPU per drive, round trips, lost
/// frames, wrong working counters) measured by `vd-bench` over veth pairs, written
/// into docs/benchmarks-notes.md (appended to the report). Needs root (network
/// namespaces, raw sockets).
fn virtual_drive_realtime() -> Result<(), String> {
    let (ok, _) = run_capture(&mut cargo(&[
        "build",
        "-q",
        "-p",
        "tests-host",
        "--release",
        "--bin",
        "virtual-drive",
        "--bin",
        "vd-bench",
    ]));
    if !ok {
        return Err("building virtual-drive / vd-bench failed".into());
    }
    let (ok, _) =
        run_capture(Command::new("target/release/vd-bench").arg("docs/benchmarks-notes.md"));
    if !ok {
        return Err("vd-bench failed (it needs root)".into());
    }
    Ok(())
}

/// Cycle time budget: SPI traffic from the chip models + this run's instruction
/// counts, written into docs/benchmarks-notes.md (appended to the report).
fn cycle_budget(target_dir: &str, first: &[(String, u64)]) -> Result<(), String> {
    // Cycle time budget: SPI traffic from the chip models + this run's instruction
    // counts, written into docs/benchmarks-notes.md (appended below).
    if Path::new("tests-host/src/bin/cycle-budget").exists() {
        let counts_file = format!("{target_dir}/instructions.tsv");
        let tsv: String = first.iter().map(|(n, c)| format!("{n}\t{c}\n")).collect();
        if fs::write(&counts_file, tsv).is_err() {
            return Err(format!("cannot write {counts_file}"));
        }
        let (ok, _) = run_capture(&mut cargo(&[
            "run",
            "-q",
            "-p",
            "tests-host",
            "--release",
            "--bin",
            "cycle-budget",
            "--",
            "--counts",
            &counts_file,
            "docs/benchmarks-notes.md",
        ]));
        if !ok {
            return Err("cycle-budget failed".into());
        }
    }
    Ok(())
}

fn symbol(elf: &str, name: &str) -> Option<u64> {
    let out = Command::new("readelf").args(["-sW", elf]).output().ok()?;
    String::from_utf8_lossy(&out.stdout).lines().find_map(|l| {
        let cols: Vec<&str> = l.split_whitespace().collect();
        (cols.len() >= 8 && cols[7] == name)
            .then(|| u64::from_str_radix(cols[1], 16).ok())
            .flatten()
    })
}

/// Runs the benchmark image once; returns (name, instructions) in order.
fn run_bench_image(
    elf: &str,
    plugin: &str,
    start: u64,
    stop: u64,
) -> Result<Vec<(String, u64)>, String> {
    run_bench_image_full(elf, plugin, start, stop).map(|(c, _)| c)
}

/// Stack depths printed by the image (`STACK <name> <bytes>`): the deepest of the
/// runs of each name, in order of first appearance.
fn stack_lines(stdout: &str) -> Vec<(String, u64)> {
    let mut v: Vec<(String, u64)> = Vec::new();
    for l in stdout.lines().filter_map(|l| l.strip_prefix("STACK ")) {
        let Some((name, bytes)) = l.rsplit_once(' ') else {
            continue;
        };
        let Ok(b) = bytes.parse::<u64>() else {
            continue;
        };
        match v.iter_mut().find(|(n, _)| n == name) {
            Some((_, m)) => *m = (*m).max(b),
            None => v.push((name.to_string(), b)),
        }
    }
    v
}

/// [`run_bench_image`] plus the stack depths of that run.
#[allow(clippy::type_complexity)]
fn run_bench_image_full(
    elf: &str,
    plugin: &str,
    start: u64,
    stop: u64,
) -> Result<(Vec<(String, u64)>, Vec<(String, u64)>), String> {
    let log = format!("{elf}.plugin.log");
    let _ = fs::remove_file(&log);
    let plugin_arg = format!("{plugin},start={start:#x},stop={stop:#x}");
    let out = Command::new("qemu-system-arm")
        .args([
            "-machine",
            "mps2-an386",
            "-cpu",
            "cortex-m4",
            "-nographic",
            "-monitor",
            "none",
            "-serial",
            "none",
        ])
        .args([
            "-semihosting-config",
            "enable=on,target=native",
            "-d",
            "plugin",
            "-D",
            &log,
        ])
        .args(["-plugin", &plugin_arg, "-kernel", elf])
        .output()
        .map_err(|e| format!("qemu-system-arm: {e}"))?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        return Err(format!(
            "benchmark image failed:\n{stdout}{}",
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    let names: Vec<String> = stdout
        .lines()
        .filter_map(|l| l.strip_prefix("BENCH "))
        .map(str::to_string)
        .collect();
    let log_text = fs::read_to_string(&log).map_err(|e| format!("plugin log: {e}"))?;
    let counts: Vec<u64> = log_text
        .lines()
        .filter_map(|l| l.strip_prefix("count ")?.trim().parse().ok())
        .collect();
    if names.len() != counts.len() || !stdout.contains("BENCH-END") {
        return Err(format!(
            "{} benchmark names but {} counts",
            names.len(),
            counts.len()
        ));
    }
    let stacks = stack_lines(&stdout);
    Ok((names.into_iter().zip(counts).collect(), stacks))
}
