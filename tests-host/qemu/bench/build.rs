//! The benchmark image links with the QEMU image script.
fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    if std::env::var("TARGET")
        .unwrap_or_default()
        .starts_with("thumb")
    {
        println!("cargo:rustc-link-arg-bins=-Tqemu.x");
    }
}
