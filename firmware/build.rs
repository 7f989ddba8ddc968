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
