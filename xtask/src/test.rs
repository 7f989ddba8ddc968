//! `cargo xtask test`: every check in sequence, tallied into `N passed, N failed`.

use std::process::Command;

use crate::run::{cargo, run_capture, run_status};
use crate::size::{size_report, BOOTLOADER_FLASH, FIRMWARE_FLAVOURS, FLASH_BUDGET, RAM_BUDGET};
use crate::THUMB;

/// Crates whose `tests/portable*.rs` run on the host and under QEMU.
const PORTABLE_CRATES: &[&str] = &["foc", "ecat-slave-stack", "firmware"];

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

/// Installs what is missing: the rustup target, qemu-system-arm, chromium and
/// chromium-driver (apt-get, as root).
pub fn ensure_tools() -> Result<(), String> {
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
    let has = |program: &str| {
        Command::new(program)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
    };
    // (program, Debian package): QEMU for the portable tests, Chromium and its
    // WebDriver for the commissioning tool's browser test.
    let wanted = [
        ("qemu-system-arm", "qemu-system-arm"),
        ("chromium", "chromium"),
        ("chromedriver", "chromium-driver"),
    ];
    let missing: Vec<&str> = wanted
        .iter()
        .filter(|(program, _)| !has(program))
        .map(|&(_, package)| package)
        .collect();
    if !missing.is_empty() {
        let root = Command::new("id")
            .arg("-u")
            .output()
            .map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0");
        if root.unwrap_or(false) {
            let ok = run_status(Command::new("apt-get").args(["update", "-q"]))
                && run_status(
                    Command::new("apt-get")
                        .args(["install", "-y", "-q"])
                        .args(&missing)
                        .env("DEBIAN_FRONTEND", "noninteractive"),
                );
            if !ok {
                return Err(format!("apt-get install {} failed", missing.join(" ")));
            }
        } else {
            return Err(format!(
                "{} missing: run `sudo apt-get install -y {}`",
                missing.join(", "),
                missing.join(" ")
            ));
        }
    }
    Ok(())
}

/// Every check in sequence; prints `N passed, N failed`; whether all passed.
pub fn test() -> bool {
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
    clippy_steps(&mut t);
    let (ok, text) = run_capture(&mut cargo(&["test"]));
    t.tests("host tests", ok, &text);

    harness_self_test(&mut t);
    qemu_tests(&mut t);
    size_steps(&mut t);
    summary(&t)
}

fn summary(t: &Tally) -> bool {
    if !t.failed_steps.is_empty() {
        eprintln!("\nfailed: {}", t.failed_steps.join(", "));
    }
    println!("{} passed, {} failed", t.passed, t.failed);
    t.failed == 0
}

/// Clippy with warnings denied: host crates, bare-metal libraries, bootloader, every
/// board firmware flavour; rustdoc on the libraries after the host crates.
fn clippy_steps(t: &mut Tally) {
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
    rustdoc_step(t);
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
    board_clippy_steps(t);
}

/// Clippy on the bootloader, and on the board image in both flavours and the self-test
/// image (docs/board/bring-up.md, "Board self-test") in both.
fn board_clippy_steps(t: &mut Tally) {
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
}

/// Rustdoc on the libraries with warnings as errors: no broken or private doc links.
fn rustdoc_step(t: &mut Tally) {
    t.step(
        "rustdoc (libraries: no broken or private doc links)",
        run_status(
            cargo(&[
                "doc",
                "--no-deps",
                "-p",
                "foc",
                "-p",
                "ecat-slave-stack",
                "-p",
                "firmware",
                "-p",
                "efw",
            ])
            .env("RUSTDOCFLAGS", "-D warnings"),
        ),
    );
}

/// Harness self-test: an image with a deliberately failing test must fail, on the
/// host and under QEMU, and say which test failed.
fn harness_self_test(t: &mut Tally) {
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
}

/// The portable tests of each logic crate under QEMU.
fn qemu_tests(t: &mut Tally) {
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
}

/// The release images against the chip, the product budget and the bootloader
/// partition.
fn size_steps(t: &mut Tally) {
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
}
