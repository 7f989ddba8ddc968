//! Project automation: `cargo xtask <command>`.
//!
//! * `test`   — installs what is missing (rustup target, qemu-system-arm via apt-get when
//!   root), then fmt check, clippy (host crates, bare-metal libraries, board firmware),
//!   host tests, the harness self-test, the QEMU tests of every logic crate, the
//!   firmware release builds with their flash/RAM budget, the bootloader release build
//!   in its partition; ends with `N passed, N failed`. Clippy covers the bootloader.
//! * `bench`  — (`bench images`: only the image sizes) instruction counts of the hot paths under QEMU (TCG plugin) and the
//!   control-quality figures of the plant simulation → `BENCHMARKS.md`.
//! * `demo`   — the simulated-drive commissioning demo (no hardware).
//! * `esi`    — writes the ESI XML files and the SII images into `docs/esi/`.
//! * `od-doc` — writes the object dictionary reference (`docs/object-dictionary.md`).
//! * `faults-doc` — writes the fault table (`docs/faults.md`) from
//!   `firmware::faults::TABLE`.
//! * `migration` — writes the migration guides from the replaced drives
//!   (`docs/migration/*.md`, from `tests-host/src/migration/`).
//! * `size`   — builds the board firmware and prints its flash/RAM use and its static
//!   worst-case stack (`stack/`); then the same for the bootloader, against its
//!   32 KiB partition; `stack <ELF>` prints that analysis for one ELF.
//! * `flash`  — builds and flashes the board firmware with probe-rs (needs a probe).
//! * `update-image` — the signed firmware update files `target/update/ecs-*.efw`
//!   (`update_image.rs`); `public-key [KEY FILE]` prints the public key of a signing
//!   key (default: the development key).

mod bench;
mod run;
mod size;
mod stack;
mod test;
mod update_image;

use std::env;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use run::{cargo, run_status};

const THUMB: &str = "thumbv7em-none-eabihf";

/// `drive-docs CMD OUT` (tests-host): a file generated from the drive's one description.
fn drive_docs(cmd: &str, out: &str) -> bool {
    run_status(&mut cargo(&[
        "run",
        "-p",
        "tests-host",
        "--release",
        "--bin",
        "drive-docs",
        "--",
        cmd,
        out,
    ]))
}

fn main() -> ExitCode {
    let args: Vec<String> = env::args().skip(1).collect();
    let root = root();
    env::set_current_dir(&root).expect("cd to workspace root");
    let rest = &args.get(1..).unwrap_or(&[]);
    let ok = match args.first().map(String::as_str) {
        Some("test") => test::test(),
        Some("bench") if rest.first().map(String::as_str) == Some("images") => bench::images_only(),
        Some("bench") => bench::bench(),
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
        Some("esi") => drive_docs("esi", "docs/esi"),
        Some("od-doc") => drive_docs("od-doc", "docs/object-dictionary.md"),
        Some("faults-doc") => drive_docs("faults-doc", "docs/faults.md"),
        Some("migration") => drive_docs("migration", "docs/migration"),
        Some("size") => size::size_report().is_ok_and(|f| f.chip && f.bootloader),
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
            size::build_board_elf,
        ) {
            Ok(()) => true,
            Err(e) => {
                eprintln!("update-image: {e}");
                false
            }
        },
        _ => {
            eprintln!("usage: cargo xtask <test|bench|demo|esi|od-doc|faults-doc|migration|size|flash|update-image|public-key>");
            false
        }
    };
    if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

/// Builds the board firmware (the same command and code generation as [`size::size_report`]
/// and the QEMU test images: no board-only code-generation flags; the one flag,
/// [`size::board_rustflags`], shortens file names) and runs it through
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
            "--config",
            &size::board_rustflags(),
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
