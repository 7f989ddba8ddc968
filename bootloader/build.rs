//! Linker set-up of the bootloader: cortex-m-rt's link.x with bootloader/memory.x,
//! which includes the workspace's layout.x (both copied to OUT_DIR, on the link path).
//! Only for the board target; on the host the crate is an empty stub. No memory.x may
//! sit at the workspace root: the linker would take it first (see firmware/build.rs).
use std::{env, fs, path::PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=../layout.x");
    assert!(
        fs::metadata("../memory.x").is_err(),
        "a memory.x at the workspace root would be linked instead of bootloader/memory.x"
    );
    if env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("none") {
        let out = PathBuf::from(env::var("OUT_DIR").expect("OUT_DIR"));
        fs::copy("memory.x", out.join("memory.x")).expect("copy memory.x");
        fs::copy("../layout.x", out.join("layout.x")).expect("copy layout.x");
        println!("cargo:rustc-link-search={}", out.display());
        println!("cargo:rustc-link-arg-bins=--nmagic");
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
    }
}
