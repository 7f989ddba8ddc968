//! Linker set-up. Board binary: cortex-m-rt's link.x with firmware/memory.x (which
//! includes the workspace's layout.x), plus defmt's table. Cross-compiled library
//! tests: the QEMU image script (qemu.x).
//!
//! cortex-m-rt's link.x says `INCLUDE memory.x`, and the linker looks in its working
//! directory — cargo's, the workspace root — before the `-L` paths. So there must be
//! no memory.x at the root: the firmware's and the bootloader's each sit in their
//! crate and reach the linker through OUT_DIR.
use std::{env, fs, path::PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=../layout.x");
    assert!(
        fs::metadata("../memory.x").is_err(),
        "a memory.x at the workspace root would be linked into every cortex-m-rt image \
         instead of the crate's own (see firmware/build.rs)"
    );
    test_update_files();
    let thumb = env::var("TARGET").unwrap_or_default().starts_with("thumb");
    let board = env::var_os("CARGO_FEATURE_BOARD").is_some();
    if thumb && board {
        let out = PathBuf::from(env::var("OUT_DIR").expect("OUT_DIR"));
        fs::copy("memory.x", out.join("memory.x")).expect("copy memory.x");
        fs::copy("../layout.x", out.join("layout.x")).expect("copy layout.x");
        println!("cargo:rustc-link-search={}", out.display());
        println!("cargo:rustc-link-arg-bins=--nmagic");
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    } else if thumb {
        println!("cargo:rustc-link-arg-tests=-Tqemu.x");
    }
}

/// The update files of `tests/portable_update.rs` (which runs under QEMU too, where
/// nothing can be signed): a 6 KiB image signed with the development key, and the
/// same image signed with another key. The identity (vendor 0x0ECA, product 0x5702,
/// LAN9252) is the test's own; it reads it back from the header.
fn test_update_files() {
    println!("cargo:rerun-if-changed=../keys/dev-signing-key.hex");
    let seed = efw::sign::dev_key();
    let image: Vec<u8> = (0..6144u32).map(|i| (i * 31 + 7) as u8).collect();
    let out = PathBuf::from(env::var("OUT_DIR").expect("OUT_DIR"));
    for (name, key) in [
        ("test-update.efw", seed),
        ("test-update-other-key.efw", [0x5A; 32]),
    ] {
        let file =
            efw::sign::update_file(&key, 0x0ECA, 0x5702, efw::Esc::Lan9252, 0x0002_0001, &image);
        fs::write(out.join(name), file).expect("test update file");
    }
}
