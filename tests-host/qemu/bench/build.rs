//! The benchmark image links with the QEMU image script; the FoE rows' update file
//! (a 4 KiB image signed with the development key) is made here, on the host.
fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=../../../keys/dev-signing-key.hex");
    let seed = efw::sign::dev_key();
    let image: Vec<u8> = (0..4096u32).map(|i| (i * 7 + 1) as u8).collect();
    let file = efw::sign::update_file(
        &seed,
        firmware::identity::VENDOR_ID,
        firmware::identity::BOARD_VARIANT.product_code(),
        efw::Esc::Lan9252,
        0x0001_0000,
        &image,
    );
    let out = std::path::Path::new(&std::env::var("OUT_DIR").expect("OUT_DIR")).join("bench.efw");
    std::fs::write(out, file).expect("bench.efw");
    if std::env::var("TARGET")
        .unwrap_or_default()
        .starts_with("thumb")
    {
        println!("cargo:rustc-link-arg-bins=-Tqemu.x");
    }
}
