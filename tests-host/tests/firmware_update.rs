//! Firmware update of the simulated drive through its mailbox, as a master does it:
//! Init → Bootstrap with the SII's boot mailbox, an FoE write of a signed `.efw`
//! file, Bootstrap → Init (the drive resets into embassy-boot, which swaps), the new
//! image on trial, its confirmation once the runtime reaches Pre-Op, 0x100A and
//! 0x2309; refused images (FoE error, the running image unchanged); the revert of
//! an image that never confirmed; the information file; the AL codes of Bootstrap.

use ecat_slave_stack::od::{Dictionary, ObjectKey};
use firmware::update::INFO_FILE;
use tests_host::esc_sim::Flavour;
use tests_host::raw_master::{FoeError, RawMaster};
use tests_host::segment::Segment;
use tests_host::sim_drive::{self, Motor, SimDrive, SimDriveConfig};

const STATION: u16 = 0x1001;
type Master = RawMaster<SimDrive>;

fn seed() -> [u8; 32] {
    efw::sign::dev_key()
}

fn image(len: usize, salt: u8) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u8).wrapping_mul(13) ^ salt)
        .collect()
}

fn efw(esc: efw::Esc, version: u32, img: &[u8]) -> Vec<u8> {
    efw::sign::update_file(
        &seed(),
        firmware::identity::VENDOR_ID,
        firmware::identity::Variant::HybridServo.product_code(),
        esc,
        version,
        img,
    )
}

fn master() -> Master {
    let cfg = SimDriveConfig {
        motor: Motor::Ecn57_20,
        flavour: Flavour::Lan9252,
        flash_file: None,
        dips: tests_host::sim_drive::DIPS_ALL_ON,
    };
    let mut seg = sim_drive::segment_with(&cfg, 1, tests_host::sim_axis::AxisModel::Kinematic)
        .expect("segment");
    sim_drive::attach_updates_in_memory(&mut seg, Flavour::Lan9252);
    let mut m = RawMaster::new(seg);
    // The board's loop: housekeeping, emergencies, and the reset an accepted update
    // asks for on Bootstrap → Init.
    m.after = |seg: &mut Segment<SimDrive>| {
        let now_us = seg.now_ns() / 1000;
        for d in seg.drives_mut() {
            d.app.catch_up(now_us);
        }
        sim_drive::forward_emergencies(seg);
        sim_drive::restart_requested(seg);
    };
    assert_eq!(m.apwr(0, 0x0010, &STATION.to_le_bytes()), 1);
    m
}

fn to_init(m: &mut Master) {
    m.request_state(STATION, 0x11);
    let st = m.wait_state(STATION, 0x01, 50_000_000, 1_000_000, |_| {});
    assert_eq!(st, (0x01, 0), "Init");
}

fn to_preop(m: &mut Master) {
    m.configure_mailbox(STATION, (0x1000, 128, 0x1080, 128));
    m.request_state(STATION, 0x02);
    let st = m.wait_state(STATION, 0x02, 50_000_000, 1_000_000, |_| {});
    assert_eq!(st, (0x02, 0), "Pre-Op");
}

fn read_u32(m: &mut Master, index: u16, sub: u8) -> u32 {
    m.sdo_upload(STATION, index, sub)
        .unwrap_or_else(|e| panic!("{index:#06x}:{sub}: {e:?}")) as u32
}

fn version_text(m: &mut Master) -> String {
    let v = m.sdo_upload(STATION, 0x100A, 0).expect("0x100A");
    let b: Vec<u8> = v
        .to_le_bytes()
        .into_iter()
        .take_while(|&c| c != 0)
        .collect();
    String::from_utf8(b).unwrap()
}

/// The newest 0x10F3 message's diagnosis code, read from the dictionary (after the
/// drive's next ticks, which turn the update's events into messages).
fn newest_diag_code(m: &mut Master) -> u32 {
    m.wait(3_000_000, 1_000_000);
    let app = &mut m.seg.drive_mut(0).app;
    let mut b = [0u8; 64];
    Dictionary::read(app, ObjectKey::new(0x10F3, 2), &mut b).unwrap();
    let newest = b[0];
    let n = Dictionary::read(app, ObjectKey::new(0x10F3, newest), &mut b).unwrap();
    u32::from_le_bytes([b[0], b[1], b[2], b[3]]) * u32::from(n >= 4)
}

#[test]
fn an_update_over_foe_swaps_runs_on_trial_and_confirms() {
    let mut m = master();
    to_preop(&mut m);
    assert_eq!(
        version_text(&mut m),
        env!("CARGO_PKG_VERSION"),
        "no header yet"
    );
    assert_eq!(read_u32(&mut m, 0x2309, 0), 0, "confirmed");
    to_init(&mut m);
    assert_eq!(m.enter_bootstrap(STATION), (0x03, 0), "Bootstrap");
    assert!(
        !m.seg.drive(0).app.drive.command().power_stage,
        "power stage off in Bootstrap"
    );
    assert_eq!(
        tests_host::fault_inject::led_state(&m.seg, 0).run,
        ecat_slave_stack::leds::Pattern::Flickering,
        "RUN LED flickers in Bootstrap"
    );
    let file = efw(efw::Esc::Lan9252, 0x0002_0300, &image(20_000, 0x3C));
    let stats = m
        .foe_write(STATION, b"ecs-lan9252.efw", 0, &file)
        .expect("accepted");
    assert_eq!(stats.packets as usize, file.len().div_ceil(116));
    assert!(stats.busy >= 10, "one BUSY per page erase: {stats:?}");
    assert_eq!(newest_diag_code(&mut m), 0xE010, "update accepted message");
    // Bootstrap → Init: the drive resets, embassy-boot swaps, the image runs on trial.
    to_init(&mut m);
    let app = &m.seg.drive(0).app;
    assert_eq!(app.boot_state(), Some(&Ok(embassy_boot::State::Swap)));
    // Pre-Op: the runtime is up, the start-up checks passed: confirmed.
    to_preop(&mut m);
    assert_eq!(version_text(&mut m), "2.3.0");
    m.wait(5_000_000, 1_000_000);
    assert_eq!(read_u32(&mut m, 0x2309, 0), 0, "confirmed once in Pre-Op");
    assert_eq!(newest_diag_code(&mut m), 0xE012, "confirmed message");
    // The next reset keeps it.
    to_init(&mut m);
    sim_drive::restart(&mut m.seg, 0);
    assert_eq!(
        m.seg.drive(0).app.boot_state(),
        Some(&Ok(embassy_boot::State::Boot))
    );
    to_preop(&mut m);
    assert_eq!(version_text(&mut m), "2.3.0");
}

#[test]
fn an_image_that_never_confirms_is_reverted_at_the_next_reset() {
    let mut m = master();
    to_init(&mut m);
    assert_eq!(m.enter_bootstrap(STATION), (0x03, 0));
    let file = efw(efw::Esc::Lan9252, 0x0003_0000, &image(5_000, 1));
    m.foe_write(STATION, b"new.efw", 0, &file)
        .expect("accepted");
    to_init(&mut m);
    assert_eq!(
        m.seg.drive(0).app.boot_state(),
        Some(&Ok(embassy_boot::State::Swap))
    );
    // It never reaches Pre-Op (a crash, the watchdog): the next reset reverts.
    sim_drive::restart(&mut m.seg, 0);
    assert_eq!(
        m.seg.drive(0).app.boot_state(),
        Some(&Ok(embassy_boot::State::Swap)),
        "embassy-boot reports the revert as the swap state"
    );
    to_preop(&mut m);
    assert_eq!(
        version_text(&mut m),
        env!("CARGO_PKG_VERSION"),
        "the old image"
    );
    assert_eq!(read_u32(&mut m, 0x2309, 0), 2, "reverted");
    assert_eq!(newest_diag_code(&mut m), 0xE013, "reverted message");
}

#[test]
fn bad_images_get_their_foe_error_and_change_nothing() {
    let mut m = master();
    to_init(&mut m);
    assert_eq!(m.enter_bootstrap(STATION), (0x03, 0));
    let img = image(3_000, 7);
    let good = efw(efw::Esc::Lan9252, 0x0004_0000, &img);
    let mut tampered = good.clone();
    tampered[efw::HEADER_LEN + 1234] ^= 0x40;
    let other_key = efw::sign::update_file(
        &[0x42; 32],
        firmware::identity::VENDOR_ID,
        firmware::identity::Variant::HybridServo.product_code(),
        efw::Esc::Lan9252,
        1,
        &img,
    );
    let cases: [(&str, Vec<u8>, u32); 5] = [
        ("other ESC", efw(efw::Esc::Et1100, 1, &img), 0x800D),
        ("other key", other_key, 0x800C),
        ("tampered", tampered, 0x800C),
        ("truncated", good[..good.len() - 300].to_vec(), 0x800B),
        (
            "too long",
            efw(
                efw::Esc::Lan9252,
                1,
                &image(firmware::flash_layout::IMAGE_MAX as usize + 1, 0),
            ),
            0x8003,
        ),
    ];
    for (what, file, code) in cases {
        let r = m.foe_write(STATION, b"ecs-lan9252.efw", 0, &file);
        assert_eq!(r, Err(FoeError::Err(code)), "{what}");
        assert_eq!(newest_diag_code(&mut m), 0xE011, "{what}: refused message");
    }
    assert_eq!(
        m.foe_write(STATION, b"firmware.bin", 0, &good),
        Err(FoeError::Err(0x8001)),
        "not an update file"
    );
    assert_eq!(
        m.foe_write(STATION, b"a.efw", 99, &good),
        Err(FoeError::Err(0x800A)),
        "password"
    );
    // The information file, in Bootstrap.
    let info = String::from_utf8(m.foe_read(STATION, INFO_FILE, 0).expect("info")).unwrap();
    assert!(
        info.contains("esc=lan9252") && info.contains("boot=confirmed"),
        "{info}"
    );
    // Bootstrap → Pre-Op is refused (0x0011); Init brings no reset.
    m.request_state(STATION, 0x02);
    let st = m.wait_state(STATION, 0x02, 20_000_000, 1_000_000, |_| {});
    assert_eq!(st.1, 0x0011, "Bootstrap → Pre-Op: {st:x?}");
    to_init(&mut m);
    assert_eq!(
        m.seg.drive(0).app.boot_state(),
        Some(&Ok(embassy_boot::State::Boot))
    );
    assert!(!m.seg.drive(0).app.drive.reset_requested());
    to_preop(&mut m);
    assert_eq!(version_text(&mut m), env!("CARGO_PKG_VERSION"));
}

#[test]
fn foe_write_outside_bootstrap_is_refused() {
    let mut m = master();
    to_preop(&mut m);
    let file = efw(efw::Esc::Lan9252, 1, &image(500, 0));
    assert_eq!(
        m.foe_write(STATION, b"ecs-lan9252.efw", 0, &file),
        Err(FoeError::Err(0x8008))
    );
}
