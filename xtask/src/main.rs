//! Project automation: `cargo xtask <command>`.
//!
//! * `test`   — installs what is missing (rustup target, qemu-system-arm via apt-get when
//!   root), then fmt check, clippy (host crates, bare-metal libraries, board firmware),
//!   host tests, the harness self-test, the QEMU tests of every logic crate, the
//!   firmware release builds with their flash/RAM budget, the bootloader release build
//!   in its partition; ends with `N passed, N failed`. Clippy covers the bootloader.
//! * `bench`  — instruction counts of the hot paths under QEMU (TCG plugin) and the
//!   control-quality figures of the plant simulation → `BENCHMARKS.md`.
//! * `demo`   — the simulated-drive commissioning demo (no hardware).
//! * `esi`    — writes the ESI XML files and the SII images into `docs/esi/`.
//! * `od-doc` — writes the object dictionary reference (`docs/object-dictionary.md`).
//! * `size`   — builds the board firmware and prints its flash/RAM use and its static
//!   worst-case stack (`stack/`); then the same for the bootloader, against its
//!   32 KiB partition; `stack <ELF>` prints that analysis for one ELF.
//! * `flash`  — builds and flashes the board firmware with probe-rs (needs a probe).
//! * `update-image` — the signed firmware update files `target/update/ecs-*.efw`
//!   (`update_image.rs`); `public-key [KEY FILE]` prints the public key of a signing
//!   key (default: the development key).

mod stack;
mod update_image;

use std::env;
use std::fmt::Write as _;
use std::fs;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};
use std::sync::mpsc;
use std::thread;

const THUMB: &str = "thumbv7em-none-eabihf";
/// Budget of the finished product. Issue 16 set 112 KiB of flash and 24 KiB of RAM (a
/// 128 KiB STM32G431-class part). Firmware update (issue 18) needs two image
/// partitions and a bootloader, so the product is the 512 KiB STM32G474RE; the update
/// itself (ed25519, SHA-512, embassy-boot, FoE) added 22 KiB of code and an 8 KiB
/// stack path (the signature check). The budget is now 144 KiB of flash (the active
/// partition holds 226 KiB: room for a second flavour of features) and 32 KiB of RAM
/// for the static RAM plus the static worst-case stack (of 128 KiB). `test` fails
/// above it.
const FLASH_BUDGET: u64 = 144 * 1024;
const RAM_BUDGET: u64 = 32 * 1024;
/// What the STM32G474RE can hold: flash, the active partition less its update-header
/// page (`firmware::flash_layout::IMAGE_MAX`, firmware/memory.x: 228 KiB − 2 KiB);
/// 128 KiB RAM. Above this the image cannot run at all: `test` fails.
const FLASH_CHIP: u64 = 226 * 1024;
const RAM_CHIP: u64 = 128 * 1024;
/// The bootloader's partition (`firmware::flash_layout::BOOTLOADER`, bootloader/memory.x).
const BOOTLOADER_FLASH: u64 = 32 * 1024;
/// Where each image's vector table must be: the bootloader at the flash base (the
/// reset vector), the firmware at the start of the active partition (the bootloader
/// starts it there). A memory.x at the workspace root would silently move them.
const BOOTLOADER_ORIGIN: u64 = 0x0800_0000;
const FIRMWARE_ORIGIN: u64 = 0x0800_9000;
/// Crates whose `tests/portable*.rs` run on the host and under QEMU.
const PORTABLE_CRATES: &[&str] = &["foc", "ecat-slave-stack", "firmware"];
/// Board firmware flavours (ESC chip), built and size-checked by `test`.
const FIRMWARE_FLAVOURS: &[&str] = &["esc-lan9252", "esc-et1100"];

fn main() -> ExitCode {
    let args: Vec<String> = env::args().skip(1).collect();
    let root = root();
    env::set_current_dir(&root).expect("cd to workspace root");
    let rest = &args.get(1..).unwrap_or(&[]);
    let ok = match args.first().map(String::as_str) {
        Some("test") => test(),
        Some("bench") => bench(),
        Some("demo") => run_status(
            cargo(&[
                "run",
                "-p",
                "tests-host",
                "--release",
                "--bin",
                "demo",
                "--",
            ])
            .args(*rest),
        ),
        Some("esi") => run_status(&mut cargo(&[
            "run",
            "-p",
            "tests-host",
            "--release",
            "--bin",
            "drive-docs",
            "--",
            "esi",
            "docs/esi",
        ])),
        Some("od-doc") => run_status(&mut cargo(&[
            "run",
            "-p",
            "tests-host",
            "--release",
            "--bin",
            "drive-docs",
            "--",
            "od-doc",
            "docs/object-dictionary.md",
        ])),
        Some("size") => size_report().is_ok_and(|f| f.chip && f.bootloader),
        // The static stack analysis of a given ELF (no build).
        Some("stack") => match rest.first().map(|p| stack::analyse(Path::new(p))) {
            Some(Ok(report)) => {
                print!("{}", report.text);
                true
            }
            Some(Err(e)) => {
                eprintln!("stack: {e}");
                false
            }
            None => {
                eprintln!("usage: cargo xtask stack <firmware ELF>");
                false
            }
        },
        Some("flash") => flash(rest),
        Some("public-key") => match update_image::public_key_of(rest.first().map(String::as_str)) {
            Ok(hex) => {
                println!("{hex}");
                true
            }
            Err(e) => {
                eprintln!("public-key: {e}");
                false
            }
        },
        Some("update-image") => match update_image::run(
            &root,
            &[
                ("esc-lan9252", efw::Esc::Lan9252),
                ("esc-et1100", efw::Esc::Et1100),
            ],
            build_board_elf,
        ) {
            Ok(()) => true,
            Err(e) => {
                eprintln!("update-image: {e}");
                false
            }
        },
        _ => {
            eprintln!("usage: cargo xtask <test|bench|demo|esi|od-doc|size|flash|update-image|public-key>");
            false
        }
    };
    if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

/// Builds the board firmware (the same command and code generation as [`size_report`]
/// and the QEMU test images: no board-only compiler flags) and runs it through
/// probe-rs (`probe-rs run`: flashes, resets, prints the defmt log). Extra arguments
/// go to cargo, e.g. `--features esc-et1100`. The firmware is linked at the active
/// partition (0x0800_9000): the board needs the bootloader (`bootloader/`, flashed
/// once) to start it after the reset.
fn flash(extra: &[String]) -> bool {
    run_status(
        cargo(&[
            "run",
            "--release",
            "-p",
            "firmware",
            "--features",
            "board",
            "--target",
            THUMB,
            "--bin",
            "firmware",
            "--target-dir",
            "target/firmware",
            "--config",
            &format!("target.{THUMB}.runner='probe-rs run --chip STM32G474RETx'"),
        ])
        .args(extra),
    )
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("workspace root")
        .to_path_buf()
}

fn cargo(args: &[&str]) -> Command {
    let mut c = Command::new(env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    c.args(args);
    c
}

fn run_status(cmd: &mut Command) -> bool {
    eprintln!("$ {}", show(cmd));
    cmd.status().map(|s| s.success()).unwrap_or(false)
}

fn show(cmd: &Command) -> String {
    let mut s = cmd.get_program().to_string_lossy().into_owned();
    for a in cmd.get_args() {
        s.push(' ');
        s.push_str(&a.to_string_lossy());
    }
    s
}

/// Runs a command, echoing its output live, and returns (success, stdout+stderr text).
fn run_capture(cmd: &mut Command) -> (bool, String) {
    eprintln!("$ {}", show(cmd));
    cmd.stdout(Stdio::piped()).stderr(Stdio::piped());
    let mut child = match cmd.spawn() {
        Ok(c) => c,
        Err(e) => return (false, format!("cannot start: {e}")),
    };
    let (tx, rx) = mpsc::channel::<String>();
    let mut handles = Vec::new();
    let out: Box<dyn Read + Send> = Box::new(child.stdout.take().expect("stdout"));
    let err: Box<dyn Read + Send> = Box::new(child.stderr.take().expect("stderr"));
    for (stream, is_err) in [(out, false), (err, true)] {
        let tx = tx.clone();
        handles.push(thread::spawn(move || {
            for line in BufReader::new(stream).lines().map_while(Result::ok) {
                if is_err {
                    eprintln!("{line}");
                } else {
                    println!("{line}");
                }
                let _ = tx.send(line);
            }
        }));
    }
    drop(tx);
    let status = child.wait();
    for h in handles {
        let _ = h.join();
    }
    let text: Vec<String> = rx.into_iter().collect();
    (
        status.map(|s| s.success()).unwrap_or(false),
        text.join("\n"),
    )
}

/// Sums libtest-style `test result: ... N passed; M failed` lines.
fn count_results(text: &str) -> (u64, u64) {
    let (mut passed, mut failed) = (0, 0);
    for line in text.lines() {
        let Some(pos) = line.find("test result:") else {
            continue;
        };
        let rest = &line[pos..];
        passed += number_before(rest, " passed").unwrap_or(0);
        failed += number_before(rest, " failed").unwrap_or(0);
    }
    (passed, failed)
}

fn number_before(s: &str, word: &str) -> Option<u64> {
    let end = s.find(word)?;
    let start = s[..end]
        .rfind(|c: char| !c.is_ascii_digit())
        .map_or(0, |i| i + 1);
    s[start..end].parse().ok()
}

// ---------------------------------------------------------------------------------------
// test
// ---------------------------------------------------------------------------------------

struct Tally {
    passed: u64,
    failed: u64,
    failed_steps: Vec<String>,
}

impl Tally {
    fn step(&mut self, name: &str, ok: bool) {
        if ok {
            self.passed += 1;
        } else {
            self.failed += 1;
            self.failed_steps.push(name.to_string());
        }
    }
    fn tests(&mut self, name: &str, ok: bool, text: &str) {
        let (p, f) = count_results(text);
        self.passed += p;
        self.failed += f;
        if !ok || f > 0 {
            if f == 0 {
                // The command failed without a failing test (build error, crash).
                self.failed += 1;
            }
            self.failed_steps.push(name.to_string());
        }
    }
}

fn ensure_tools() -> Result<(), String> {
    let installed = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .output();
    let has_target = installed
        .as_ref()
        .map(|o| {
            String::from_utf8_lossy(&o.stdout)
                .lines()
                .any(|l| l.trim() == THUMB)
        })
        .unwrap_or(false);
    if !has_target && !run_status(Command::new("rustup").args(["target", "add", THUMB])) {
        return Err(format!("could not install the rustup target {THUMB}"));
    }
    let has_qemu = Command::new("qemu-system-arm")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_qemu {
        let root = Command::new("id")
            .arg("-u")
            .output()
            .map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0");
        if root.unwrap_or(false) {
            let ok = run_status(Command::new("apt-get").args(["update", "-q"]))
                && run_status(
                    Command::new("apt-get")
                        .args(["install", "-y", "-q", "qemu-system-arm"])
                        .env("DEBIAN_FRONTEND", "noninteractive"),
                );
            if !ok {
                return Err("apt-get install qemu-system-arm failed".into());
            }
        } else {
            return Err(
                "qemu-system-arm is missing: run `sudo apt-get install -y qemu-system-arm`".into(),
            );
        }
    }
    Ok(())
}

fn test() -> bool {
    let mut t = Tally {
        passed: 0,
        failed: 0,
        failed_steps: Vec::new(),
    };
    if let Err(e) = ensure_tools() {
        eprintln!("error: {e}");
        t.step("install tools", false);
        return summary(&t);
    }

    t.step(
        "cargo fmt --check",
        run_status(&mut cargo(&["fmt", "--all", "--check"])),
    );
    t.step(
        "clippy (host crates)",
        run_status(&mut cargo(&[
            "clippy",
            "--all-targets",
            "--",
            "-D",
            "warnings",
        ])),
    );
    t.step(
        "clippy (bare-metal libraries)",
        run_status(&mut cargo(&[
            "clippy",
            "-p",
            "foc",
            "-p",
            "ecat-slave-stack",
            "-p",
            "firmware",
            "-p",
            "qemu-bench",
            "--target",
            THUMB,
            "--",
            "-D",
            "warnings",
        ])),
    );
    // The board image in both flavours, and the self-test image (README, "Board
    // self-test") in both.
    t.step(
        "clippy (bootloader)",
        run_status(&mut cargo(&[
            "clippy",
            "-p",
            "bootloader",
            "--target",
            THUMB,
            "--",
            "-D",
            "warnings",
        ])),
    );
    for (flavour, extra) in FIRMWARE_FLAVOURS
        .iter()
        .flat_map(|f| [(*f, ""), (*f, ",selftest")])
    {
        let features = format!("board,{flavour}{extra}");
        t.step(
            &format!("clippy (board firmware, {flavour}{extra})"),
            run_status(&mut cargo(&[
                "clippy",
                "-p",
                "firmware",
                "--features",
                &features,
                "--target",
                THUMB,
                "--",
                "-D",
                "warnings",
            ])),
        );
    }

    let (ok, text) = run_capture(&mut cargo(&["test"]));
    t.tests("host tests", ok, &text);

    // Harness self-test: an image with a deliberately failing test must fail, on the
    // host and under QEMU, and say which test failed.
    for (label, extra) in [("host", None), ("qemu", Some(THUMB))] {
        let mut cmd = cargo(&["run", "-q", "-p", "qemu-runner", "--example", "must_fail"]);
        if let Some(target) = extra {
            cmd.args(["--target", target]);
        }
        let (ok, text) = run_capture(&mut cmd);
        let detected = !ok
            && text.contains("deliberately_failing ... FAILED")
            && text.contains("test result: FAILED");
        eprintln!(
            "harness self-test ({label}): failing test {}",
            if detected {
                "detected as expected"
            } else {
                "NOT detected"
            }
        );
        t.step(&format!("harness self-test ({label})"), detected);
    }

    for krate in PORTABLE_CRATES {
        let (ok, text) = run_capture(&mut cargo(&[
            "test",
            "-p",
            krate,
            "--target",
            THUMB,
            "--test",
            "portable*",
        ]));
        let (p, _) = count_results(&text);
        eprintln!("QEMU: {krate}: {p} tests passed");
        t.tests(&format!("QEMU tests of {krate}"), ok && p > 0, &text);
    }

    match size_report() {
        Ok(fit) => {
            t.step("firmware release builds fit the chip", fit.chip);
            t.step(
                &format!(
                    "firmware release builds within the product budget ({} KiB flash, {} KiB RAM with the worst-case stack)",
                    FLASH_BUDGET / 1024,
                    RAM_BUDGET / 1024
                ),
                fit.budget,
            );
            t.step(
                &format!(
                    "bootloader release build fits its {} KiB partition",
                    BOOTLOADER_FLASH / 1024
                ),
                fit.bootloader,
            );
        }
        Err(e) => {
            eprintln!("error: {e}");
            t.step("firmware release build", false);
        }
    }
    summary(&t)
}

fn summary(t: &Tally) -> bool {
    if !t.failed_steps.is_empty() {
        eprintln!("\nfailed: {}", t.failed_steps.join(", "));
    }
    println!("{} passed, {} failed", t.passed, t.failed);
    t.failed == 0
}

// ---------------------------------------------------------------------------------------
// firmware size
// ---------------------------------------------------------------------------------------

/// Whether every firmware flavour, and the bootloader, fits.
struct Fit {
    /// The STM32G474RE (flash: the active partition less its header page; RAM).
    chip: bool,
    /// The product budget: flash, and static RAM plus the static worst-case stack.
    budget: bool,
    /// The bootloader: its partition, and the RAM with its worst-case stack.
    bootloader: bool,
}

/// Builds the board firmware of `flavour` (feature `esc-…`) in release (for
/// [`size_report`] and `update-image`) and returns the path of its ELF copy.
fn build_board_elf(flavour: &str) -> Result<String, String> {
    let features = format!("board,{flavour}");
    // One target directory for both flavours: the dependencies built without the
    // flavour feature are shared, the final ELF is copied out per flavour.
    let target_dir = "target/firmware";
    if !run_status(&mut cargo(&[
        "build",
        "-p",
        "firmware",
        "--release",
        "--features",
        &features,
        "--target",
        THUMB,
        "--target-dir",
        target_dir,
    ])) {
        return Err(format!("firmware build ({flavour}) failed"));
    }
    let elf = format!("{target_dir}/firmware-{flavour}.elf");
    std::fs::copy(format!("{target_dir}/{THUMB}/release/firmware"), &elf)
        .map_err(|e| format!("copy firmware ELF: {e}"))?;
    Ok(elf)
}

/// Builds every firmware flavour and the bootloader in release and prints flash/RAM
/// use and the static worst-case stack.
fn size_report() -> Result<Fit, String> {
    let mut within = true;
    let mut budget = true;
    for flavour in FIRMWARE_FLAVOURS {
        let elf = build_board_elf(flavour)?;
        let (flash, ram) = elf_usage(&elf)?;
        let in_budget = flash <= FLASH_BUDGET && ram <= RAM_BUDGET;
        within &= flash <= FLASH_CHIP && ram <= RAM_CHIP;
        within &= linked_at(&elf, FIRMWARE_ORIGIN)?;
        budget &= in_budget;
        println!(
            "firmware ({flavour}): flash {flash} B ({:.1} KiB; product budget {} KiB), RAM {ram} B ({:.1} KiB; budget {} KiB) — {}  [{elf}]",
            flash as f64 / 1024.0,
            FLASH_BUDGET / 1024,
            ram as f64 / 1024.0,
            RAM_BUDGET / 1024,
            if in_budget { "within budget" } else { "OVER THE PRODUCT BUDGET (fits the chip)" }
        );
        // Static worst-case stack: RAM = static RAM + stack.
        match stack::analyse(Path::new(&elf)) {
            Ok(report) => {
                print!("{}", report.text);
                let total = ram + report.worst;
                within &= !report.bounded || total <= RAM_CHIP;
                budget &= report.bounded && total <= RAM_BUDGET;
                println!(
                    "  RAM with the worst-case stack: static {ram} + stack {}{} = {total} B ({:.1} KiB) of the {} KiB budget — {}",
                    report.worst,
                    if report.bounded { "" } else { " (+ recursion)" },
                    total as f64 / 1024.0,
                    RAM_BUDGET / 1024,
                    if !report.bounded {
                        "UNBOUNDED (recursion)"
                    } else if total <= RAM_BUDGET {
                        "within budget"
                    } else {
                        "OVER THE PRODUCT BUDGET"
                    }
                );
                let coarse = ram + report.with_indirect;
                println!(
                    "  (coarse bound, unresolved indirect calls to every function no direct call reaches: {ram} + {} = {coarse} B, {})",
                    report.with_indirect,
                    if coarse <= RAM_BUDGET { "within budget" } else { "over the budget" }
                );
            }
            Err(e) => {
                println!("  stack analysis of {elf} failed: {e}");
                budget = false;
            }
        }
    }
    Ok(Fit {
        chip: within,
        budget,
        bootloader: bootloader_size()?,
    })
}

/// Builds the bootloader in release and prints its flash/RAM use against its
/// partition; whether it fits.
fn bootloader_size() -> Result<bool, String> {
    let target_dir = "target/bootloader";
    if !run_status(&mut cargo(&[
        "build",
        "-p",
        "bootloader",
        "--release",
        "--target",
        THUMB,
        "--target-dir",
        target_dir,
    ])) {
        return Err("bootloader build failed".into());
    }
    let elf = format!("{target_dir}/{THUMB}/release/bootloader");
    let (flash, ram) = elf_usage(&elf)?;
    let mut fits = flash <= BOOTLOADER_FLASH && linked_at(&elf, BOOTLOADER_ORIGIN)?;
    let stack = match stack::analyse(Path::new(&elf)) {
        Ok(report) => {
            fits &= report.bounded && ram + report.worst <= RAM_CHIP;
            format!(
                "+ stack {} B{}",
                report.worst,
                if report.bounded { "" } else { " (+ recursion)" }
            )
        }
        Err(e) => {
            fits = false;
            format!("(stack analysis failed: {e})")
        }
    };
    println!(
        "bootloader: flash {flash} B ({:.1} KiB of its {} KiB partition), RAM {ram} B {stack} — {}  [{elf}]",
        flash as f64 / 1024.0,
        BOOTLOADER_FLASH / 1024,
        if fits { "fits" } else { "DOES NOT FIT" }
    );
    Ok(fits)
}

/// Whether the ELF's vector table is at `origin`; says so when it is not.
fn linked_at(elf: &str, origin: u64) -> Result<bool, String> {
    let out = Command::new("size")
        .args(["-A", "-d", elf])
        .output()
        .map_err(|e| format!("size: {e}"))?;
    let at = String::from_utf8_lossy(&out.stdout)
        .lines()
        .find_map(|line| {
            let cols: Vec<&str> = line.split_whitespace().collect();
            (cols.len() >= 3 && cols[0] == ".vector_table")
                .then(|| cols[2].parse::<u64>().ok())
                .flatten()
        });
    match at {
        Some(a) if a == origin => Ok(true),
        Some(a) => {
            println!("{elf}: vector table at {a:#010x}, not at {origin:#010x} — wrong memory.x?");
            Ok(false)
        }
        None => Err(format!("{elf}: no .vector_table")),
    }
}

/// Flash = sections loaded into flash (.vector_table, .text, .rodata, .data image);
/// RAM = .data + .bss + .uninit (static RAM; the stack takes the rest).
fn elf_usage(elf: &str) -> Result<(u64, u64), String> {
    let out = Command::new("size")
        .args(["-A", "-d", elf])
        .output()
        .map_err(|e| format!("size: {e}"))?;
    if !out.status.success() {
        return Err(format!("size -A {elf} failed"));
    }
    let (mut flash, mut ram) = (0u64, 0u64);
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let cols: Vec<&str> = line.split_whitespace().collect();
        if cols.len() < 3 {
            continue;
        }
        let (name, Ok(size), Ok(addr)) = (cols[0], cols[1].parse::<u64>(), cols[2].parse::<u64>())
        else {
            continue;
        };
        match name {
            ".vector_table" | ".text" | ".rodata" | ".gnu.sgstubs" => flash += size,
            ".data" => {
                flash += size;
                ram += size;
            }
            ".bss" | ".uninit" => ram += size,
            _ if (0x0800_0000..0x0810_0000).contains(&addr)
                && size > 0
                && !name.starts_with(".defmt") =>
            {
                flash += size
            }
            _ => {}
        }
    }
    Ok((flash, ram))
}

// ---------------------------------------------------------------------------------------
// bench
// ---------------------------------------------------------------------------------------

/// Goals from the issues, by benchmark name.
const GOALS: &[(&str, &str)] = &[
    ("current loop step", "≤ 300"),
    // Issue 19: with the running checks, unsaturated (the saturated row says what the
    // checks cost when they run).
    ("supervised current step (unsaturated)", "≤ 300"),
    ("CSP cycle (unpack", "≤ 1500"),
];

/// The update time of a 100 KiB image over FoE, worked out from the FoE rows and the
/// flash's data-sheet timing (BENCHMARKS.md, "Firmware update over FoE").
fn foe_update_time(md: &mut String, rows: &[(String, u64)], overhead: u64) {
    let count = |prefix: &str| {
        rows.iter()
            .find(|(n, _)| n.starts_with(prefix))
            .map(|(_, c)| c.saturating_sub(overhead))
    };
    let (Some(header), Some(plain), Some(flush), Some(last)) = (
        count("FoE DATA 116 B completing the header"),
        count("FoE DATA 116 B, buffered"),
        count("FoE DATA 116 B with a 256 B write"),
        count("FoE last DATA"),
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
    // The last row hashes 4 KiB and verifies one signature (as the header row does).
    let hash_per_kib = last.saturating_sub(header) as f64 / 4.0;
    let verify_ms = ms(header as f64 + 100.0 * hash_per_kib);
    let cpu_ms = ms(packets * plain as f64 + chunks * (flush - plain.min(flush)) as f64)
        + ms(header as f64)
        + verify_ms;
    let mailbox_ms = 2.0 * MAILBOX_CYCLE_MS * (packets + pages);
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
         completes the header costs {header} (its ed25519 signature check); the last one \
         {last} for a 4 KiB image (embassy-boot's SHA-512 over the partition and the \
         image signature), so ≈ {hash_per_kib:.0} instructions per KiB hashed.\n\n\
         A 100 KiB image at a 1 ms mailbox cycle (each DATA and each BUSY one request \
         and one answer, 2 cycles), with the STM32G4's flash timing ({PROGRAM_US_PER_8B} µs \
         per 8 bytes programmed, {ERASE_MS_PER_PAGE} ms per 2 KiB page erased; \
         data-sheet figures, unverified on the board) and {CYCLES_PER_INSTRUCTION} cycles \
         per instruction at {MHZ} MHz: {packets} DATA and {pages} BUSY answers = \
         {mailbox_ms:.0} ms of mailbox cycles, {program_ms:.0} ms programming, \
         {erase_ms:.0} ms erasing, {cpu_ms:.0} ms of processor time (of which the final \
         verification {verify_ms:.0} ms, before the last ACK) — **about {total_s:.1} s**, \
         the flash's own time included and not overlapped. After Bootstrap → Init comes \
         embassy-boot's swap of the 114 pages of the active partition (several page \
         erases and programs per page: of the order of 10 s, the drive dark meanwhile).\n"
    );
}

fn bench() -> bool {
    if let Err(e) = ensure_tools() {
        eprintln!("error: {e}");
        return false;
    }
    let target_dir = "target/bench";
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
        return false;
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
        return false;
    }
    let (Some(start), Some(stop)) = (symbol(&elf, "bench_start"), symbol(&elf, "bench_stop"))
    else {
        eprintln!("error: marker symbols not found in {elf}");
        return false;
    };
    let (first, stacks) = match run_bench_image_full(&elf, &plugin, start, stop) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return false;
        }
    };
    let second = match run_bench_image(&elf, &plugin, start, stop) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return false;
        }
    };
    let repeat = first == second;
    eprintln!(
        "instruction counts of two runs {}",
        if repeat { "are identical" } else { "DIFFER" }
    );

    let overhead = first
        .iter()
        .find(|(n, _)| n == "(marker overhead)")
        .map_or(0, |(_, c)| *c);
    let mut md = String::new();
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
    for (name, count) in &first {
        if name == "(marker overhead)" {
            continue;
        }
        let goal = GOALS
            .iter()
            .find(|(g, _)| name.starts_with(g))
            .map_or("—", |(_, g)| g);
        let _ = writeln!(
            md,
            "| {name} | {goal} | {} |",
            count.saturating_sub(overhead)
        );
    }

    foe_update_time(&mut md, &first, overhead);

    md.push_str("\n## Stack depth of the library paths (painted, QEMU)\n\n");
    md.push_str(
        "Bytes of stack each path used, measured in the same image by painting the stack \
         below the caller and finding the deepest overwritten word \
         (`tests-host/qemu/bench/src/stack_benches.rs`; deepest of repeated runs).\n\n",
    );
    md.push_str("| path | context on the board | bytes |\n|---|---|---|\n");
    let context = |name: &str| {
        if name.starts_with("current-loop") {
            "ADC1_2 interrupt (priority 0)"
        } else if name.starts_with("start-up") {
            "start-up (before the interrupts run)"
        } else if name.starts_with("CSP") {
            "cyclic executor (priority 2) / 1 ms tick"
        } else {
            "thread mode (mailbox, storage tasks)"
        }
    };
    let mut worst = [0u64; 4];
    for (name, bytes) in &stacks {
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
         (static worst case, README \"Static stack report\"), and the board paints its \
         stack and reports the peak at run time (README \"Stack\").",
        worst[2], worst[1], worst[0], worst[3]
    );

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
            // Only the report's stdout goes into the file (the plot paths it prints
            // are kept out of the table).
            for line in String::from_utf8_lossy(&o.stdout).lines() {
                if line.starts_with('|') || line.is_empty() {
                    md.push_str(line);
                    md.push('\n');
                }
            }
            md.push_str("\nPlots: `target/plots/current_step.png`, `target/plots/csp_tracking_error.png`.\n");
        }
        _ => {
            eprintln!("error: control-report failed");
            return false;
        }
    }
    // Cycle time budget: SPI traffic from the chip models + this run's instruction
    // counts, written into docs/benchmarks-notes.md (appended below).
    if Path::new("tests-host/src/bin/cycle-budget.rs").exists() {
        let counts_file = format!("{target_dir}/instructions.tsv");
        let tsv: String = first.iter().map(|(n, c)| format!("{n}\t{c}\n")).collect();
        if fs::write(&counts_file, tsv).is_err() {
            eprintln!("error: cannot write {counts_file}");
            return false;
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
            eprintln!("error: cycle-budget failed");
            return false;
        }
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
