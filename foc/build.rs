//! Cross-compiled test images of this crate run under QEMU: link them with qemu.x.
fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    if std::env::var("TARGET")
        .unwrap_or_default()
        .starts_with("thumb")
    {
        println!("cargo:rustc-link-arg-tests=-Tqemu.x");
    }
}
