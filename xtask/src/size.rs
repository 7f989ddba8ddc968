//! `cargo xtask size`: flash/RAM use of the release images and their static
//! worst-case stack, against the chip, the product budget and the bootloader partition.

use std::path::Path;
use std::process::Command;

use crate::run::{cargo, run_status};
use crate::{stack, THUMB};

/// Budget of the finished product. Issue 16 set 112 KiB of flash and 24 KiB of RAM (a
/// 128 KiB STM32G431-class part). Firmware update (issue 18) needs two image
/// partitions and a bootloader, so the product is the 512 KiB STM32G474RE; the update
/// itself (ed25519, SHA-512, embassy-boot, FoE) added 22 KiB of code and an 8 KiB
/// stack path (the signature check). That made 144 KiB of flash; the motion features
/// of issue 20 (cyclic synchronous torque, open-loop stall detection and damping, the
/// servo tune's inertia and stiffness, the scope) added about 15 KiB of code (160
/// KiB), the servo tune's move on the drive and the scope at the servo rate another
/// 7 KiB, so the budget became 168 KiB (the active partition holds 226 KiB: room left
/// for a second flavour of features). The runtime, safety and drop-in work of issues
/// 32-34 (DIP function bank and outputs wired, one fault table, the brake-close hold,
/// CSV/CSP acceleration limits, 0x607B, 0x60FA, the probe input) added about 3 KiB
/// (172.9 KiB, budget 176 KiB for a while); issue 32 brought the image back to 168 KiB
/// without removing a feature (the record stage out of `.data`, no soft-float f64 or
/// `memmove` in the current loop, the update's signature check at opt-level "z", the
/// dependencies' panic file names shortened, one copy loop for `firmware.info`'s text:
/// 166.1 KiB). The hard limits are the end
/// of flash bank 1 (the read-while-write argument, checked below) and the partition.
/// RAM: 40 KiB for the static RAM plus the static worst-case
/// stack (of the chip's 128 KiB). It was 32 KiB until the servo tune's move (its fit
/// state lives in the control state, and the start-up frame that builds the control
/// state, 8 KiB, is counted as if the interrupts nested on it) and the scope's 3 KiB
/// buffer took it to 33 KiB. `test` fails above it.
pub const FLASH_BUDGET: u64 = 168 * 1024;
pub const RAM_BUDGET: u64 = 40 * 1024;
/// What the STM32G474RE can hold: flash, the active partition less its update-header
/// page (`firmware::flash_layout::IMAGE_MAX`, firmware/memory.x: 228 KiB − 2 KiB);
/// 128 KiB RAM. Above this the image cannot run at all: `test` fails.
const FLASH_CHIP: u64 = 226 * 1024;
const RAM_CHIP: u64 = 128 * 1024;
/// The bootloader's partition (`firmware::flash_layout::BOOTLOADER`, bootloader/memory.x).
pub const BOOTLOADER_FLASH: u64 = 32 * 1024;
/// Where each image's vector table must be: the bootloader at the flash base (the
/// reset vector), the firmware at the start of the active partition (the bootloader
/// starts it there). A memory.x at the workspace root would silently move them.
const BOOTLOADER_ORIGIN: u64 = firmware::flash_layout::BOOTLOADER.start() as u64;
const FIRMWARE_ORIGIN: u64 = firmware::flash_layout::ACTIVE.start() as u64;
/// The address after flash bank 1 (`firmware::flash_layout::BANK1_END`, from the
/// layout): the firmware's code must end below it, or a record or DFU write (bank 2)
/// would stall the code it runs (read-while-write).
const BANK1_END: u64 = firmware::flash_layout::BANK1_END as u64;
/// Board firmware flavours (ESC chip), built and size-checked by `test`.
pub const FIRMWARE_FLAVOURS: &[&str] = &["esc-lan9252", "esc-et1100"];

/// Whether every firmware flavour, and the bootloader, fits.
pub struct Fit {
    /// The STM32G474RE (flash: the active partition less its header page; RAM).
    pub chip: bool,
    /// The product budget: flash, and static RAM plus the static worst-case stack.
    pub budget: bool,
    /// The bootloader: its partition, and the RAM with its worst-case stack.
    pub bootloader: bool,
}

/// The `--config` value of the board image's builds (`size`, `update-image`,
/// `flash`): each crates.io source directory of cargo's registry
/// (`$CARGO_HOME/registry/src/index.crates.io-…/`) remapped to nothing, so the panic
/// locations of the dependencies name `embassy-stm32-0.6.0/src/…` instead of a
/// 60-character absolute prefix stored in flash with each (about 1 KiB in all). Only
/// file-name strings change, not the code.
pub fn board_rustflags() -> String {
    let home = std::env::var_os("CARGO_HOME")
        .map(std::path::PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| Path::new(&h).join(".cargo")));
    let mut dirs: Vec<String> = home
        .and_then(|h| std::fs::read_dir(h.join("registry").join("src")).ok())
        .into_iter()
        .flatten()
        .filter_map(|e| e.ok())
        .filter(|e| e.path().is_dir())
        .filter_map(|e| e.path().to_str().map(str::to_owned))
        .collect();
    dirs.sort();
    let flags: Vec<String> = dirs
        .iter()
        .map(|d| format!("\"--remap-path-prefix={}/=\"", toml_escape(d)))
        .collect();
    format!("target.{THUMB}.rustflags=[{}]", flags.join(","))
}

/// `s` inside a TOML basic string.
fn toml_escape(s: &str) -> String {
    s.replace('\\', "\\\\").replace('"', "\\\"")
}

/// Builds the board firmware of `flavour` (feature `esc-…`) in release (for
/// [`size_report`] and `update-image`) and returns the path of its ELF copy.
pub fn build_board_elf(flavour: &str) -> Result<String, String> {
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
        "--config",
        &board_rustflags(),
    ])) {
        return Err(format!("firmware build ({flavour}) failed"));
    }
    let elf = format!("{target_dir}/firmware-{flavour}.elf");
    std::fs::copy(format!("{target_dir}/{THUMB}/release/firmware"), &elf)
        .map_err(|e| format!("copy firmware ELF: {e}"))?;
    Ok(elf)
}

/// Builds the bootloader in release and returns the path of its ELF.
fn build_bootloader_elf() -> Result<String, String> {
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
    Ok(format!("{target_dir}/{THUMB}/release/bootloader"))
}

/// Builds every firmware flavour and the bootloader in release and prints flash/RAM
/// use and the static worst-case stack.
pub fn size_report() -> Result<Fit, String> {
    let mut within = true;
    let mut budget = true;
    for flavour in FIRMWARE_FLAVOURS {
        let elf = build_board_elf(flavour)?;
        let (flash, ram) = elf_usage(&elf)?;
        let in_budget = flash <= FLASH_BUDGET && ram <= RAM_BUDGET;
        within &= flash <= FLASH_CHIP && ram <= RAM_CHIP;
        within &= linked_at(&elf, FIRMWARE_ORIGIN)?;
        let end = flash_end(&elf)?;
        let in_bank1 = ends_in_bank1(end);
        within &= in_bank1;
        println!(
            "firmware ({flavour}): flash image ends at {end:#010x}, bank 1 ends at {BANK1_END:#010x} — {}",
            if in_bank1 {
                "in bank 1"
            } else {
                "REACHES BANK 2 (read-while-write broken)"
            }
        );
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
    let elf = build_bootloader_elf()?;
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

/// The address after the last byte the ELF loads into flash: the largest physical
/// (load) address + file size of its `LOAD` segments in flash (`.data`'s image
/// included, which the start-up code copies to RAM).
fn flash_end(elf: &str) -> Result<u64, String> {
    let out = Command::new("readelf")
        .args(["-lW", elf])
        .output()
        .map_err(|e| format!("readelf: {e}"))?;
    if !out.status.success() {
        return Err(format!("readelf -l {elf} failed"));
    }
    load_end(&String::from_utf8_lossy(&out.stdout))
        .ok_or_else(|| format!("{elf}: no LOAD segment in flash"))
}

/// [`flash_end`] from the text of `readelf -lW`.
fn load_end(readelf: &str) -> Option<u64> {
    let hex = |t: &str| u64::from_str_radix(t.trim_start_matches("0x"), 16).ok();
    readelf
        .lines()
        .filter_map(|line| {
            let cols: Vec<&str> = line.split_whitespace().collect();
            if cols.first() != Some(&"LOAD") || cols.len() < 5 {
                return None;
            }
            let (phys, size) = (hex(cols[3])?, hex(cols[4])?);
            (size > 0 && (0x0800_0000..0x1000_0000).contains(&phys)).then_some(phys + size)
        })
        .max()
}

/// Whether a firmware image ending at `end` (exclusive) stays in flash bank 1.
fn ends_in_bank1(end: u64) -> bool {
    end <= BANK1_END
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

/// The "Images" section of BENCHMARKS.md: flash, static RAM and the static worst-case
/// stack of both board images and the bootloader, against their budgets, and the
/// stack report of the LAN9252 image (what `cargo xtask size` prints).
pub fn images_md() -> Result<String, String> {
    let mut md = String::from(
        "## Images: flash, RAM and stack\n\n\
         The release images as `cargo xtask size` builds and measures them (fat LTO, \
         opt-level \"s\"): flash = `.vector_table + .text + .rodata + .data`, static RAM = \
         `.data + .bss + .uninit`, stack = the static worst case of `xtask/src/stack/` \
         (every interrupt level nested on the deepest thread path). `cargo xtask test` \
         fails above the budget.\n\n\
         | image | flash | static RAM | stack (worst case) | RAM + stack | budget |\n\
         |---|---|---|---|---|---|\n",
    );
    let mut lan_report = String::new();
    for flavour in FIRMWARE_FLAVOURS {
        let elf = build_board_elf(flavour)?;
        let (flash, ram) = elf_usage(&elf)?;
        let report = stack::analyse(Path::new(&elf))?;
        md.push_str(&format!(
            "| firmware, {flavour} | {flash} B ({:.1} KiB) | {ram} B | {} B | {} B ({:.1} KiB) | {} KiB / {} KiB |\n",
            flash as f64 / 1024.0,
            report.worst,
            ram + report.worst,
            (ram + report.worst) as f64 / 1024.0,
            FLASH_BUDGET / 1024,
            RAM_BUDGET / 1024,
        ));
        if lan_report.is_empty() {
            lan_report = report.text;
        }
    }
    {
        let elf = build_bootloader_elf()?;
        let (flash, ram) = elf_usage(&elf)?;
        let report = stack::analyse(Path::new(&elf))?;
        md.push_str(&format!(
            "| bootloader | {flash} B ({:.1} KiB) | {ram} B | {} B | {} B | {} KiB partition |\n",
            flash as f64 / 1024.0,
            report.worst,
            ram + report.worst,
            BOOTLOADER_FLASH / 1024,
        ));
    }
    md.push_str(&format!(
        "\nStatic stack report of the {} image:\n\n```text\n{}```\n",
        FIRMWARE_FLAVOURS[0], lan_report
    ));
    Ok(md)
}

#[cfg(test)]
mod tests {
    use super::*;

    const READELF: &str = "
Program Headers:
  Type           Offset   VirtAddr   PhysAddr   FileSiz MemSiz  Flg Align
  LOAD           0x000114 0x08009000 0x08009000 0x001d8 0x001d8 R   0x4
  LOAD           0x0002f0 0x080091d8 0x080091d8 0x2390c 0x2390c R E 0x8
  LOAD           0x023c00 0x0802cae8 0x0802cae8 0x06050 0x06050 R   0x8
  LOAD           0x029c50 0x20000000 0x08032b38 0x00050 0x00050 RW  0x8
  LOAD           0x029ca0 0x20000060 0x20000060 0x00000 0x052e0 RW  0x20
  GNU_STACK      0x000000 0x00000000 0x00000000 0x00000 0x00000 RW  0
";

    #[test]
    fn the_flash_end_is_the_data_image_end() {
        // .data's load image (PhysAddr 0x08032b38 + 0x50) is the last thing in flash;
        // .bss (in RAM, nothing in the file) does not count.
        assert_eq!(load_end(READELF), Some(0x0803_2b88));
        assert_eq!(load_end("no segments"), None);
    }

    #[test]
    fn bank_1_ends_where_the_layout_halves_the_flash() {
        assert_eq!(BANK1_END, 0x0804_0000);
        assert!(ends_in_bank1(0x0803_2b88));
        assert!(ends_in_bank1(BANK1_END));
        assert!(!ends_in_bank1(BANK1_END + 1));
        // An image that fills the active partition (which runs into bank 2) fails.
        let full = READELF.replace(
            "0x0802cae8 0x0802cae8 0x06050",
            "0x0802cae8 0x0802cae8 0x16050",
        );
        assert!(!ends_in_bank1(load_end(&full).unwrap()));
        assert!(u64::from(firmware::flash_layout::ACTIVE.end()) > BANK1_END);
    }
}
