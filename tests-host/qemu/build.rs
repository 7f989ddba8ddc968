//! For bare-metal targets: put the QEMU image linker script on the linker's search
//! path. Crates whose tests run under QEMU add `-Tqemu.x` for their test targets.
use std::{env, fs, path::PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=qemu.x");
    println!("cargo:rerun-if-changed=build.rs");
    let target = env::var("TARGET").unwrap_or_default();
    if target.starts_with("thumb") {
        let out = PathBuf::from(env::var("OUT_DIR").expect("OUT_DIR"));
        fs::copy("qemu.x", out.join("qemu.x")).expect("copy qemu.x");
        println!("cargo:rustc-link-search={}", out.display());
        println!("cargo:rustc-link-arg-examples=-Tqemu.x");
    }
}
