//! A firmware update of `virtual-drive` over a real raw socket: a veth pair whose one
//! end lives in a network namespace of its own with `virtual-drive --flash FILE`
//! listening there, and on the other end a master of our own
//! ([`tests_host::raw_master::SocketMaster`]: the same raw-datagram master as the
//! in-process tests, over an AF_PACKET socket; ethercrab has no FoE). With real
//! Ethernet frames it sets the station address, reads the identity and the boot
//! mailbox (SII words 0x14–0x17), takes the drive Init → Bootstrap, writes a signed
//! `.efw` (version 2.3.0) over FoE in 116-byte DATA with BUSY handling, and
//! Bootstrap → Init (the drive resets into its bootloader, which swaps); then the
//! standard mailbox, Pre-Op: 0x100A reads "2.3.0", 0x2309 turns 0 (confirmed) right
//! after Pre-Op, the information file says so. Then `virtual-drive` is killed
//! (SIGKILL, like a power cut) and started again on the same `--flash FILE`: the
//! update is in the boot flash `FILE.boot`, so 0x100A still reads "2.3.0", confirmed.
//!
//! Needs root (network namespaces, raw sockets) and iproute2, as the tests of
//! `virtual_drive_veth.rs`. CI runs as root, so this is a plain `#[test]`: without
//! root it fails and says how to run it (`sudo -E cargo test -p tests-host --test
//! virtual_drive_update_veth`); as root a failed namespace or veth setup is a failure
//! too, never a skip.
#![deny(clippy::undocumented_unsafe_blocks)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use firmware::identity::{Variant, VENDOR_ID};
use tests_host::raw_master::SocketMaster;

const STATION: u16 = 0x1001;
const VERSION: u32 = 0x0002_0300;

struct Netns {
    ns: String,
    host_if: String,
    drive_if: String,
}

impl Netns {
    /// A namespace with one end of a new veth pair (names unique per process).
    fn create(tag: char) -> Option<Netns> {
        let id = std::process::id() % 100_000;
        let n = Netns {
            ns: format!("ecsvu{id}{tag}"),
            host_if: format!("vu{id}{tag}h"),
            drive_if: format!("vu{id}{tag}d"),
        };
        let ok = |args: &[&str]| {
            Command::new("ip")
                .args(args)
                .status()
                .is_ok_and(|s| s.success())
        };
        if !ok(&["netns", "add", &n.ns]) {
            return None;
        }
        let steps: [&[&str]; 5] = [
            &[
                "link",
                "add",
                &n.host_if,
                "type",
                "veth",
                "peer",
                "name",
                &n.drive_if,
            ],
            &["link", "set", &n.drive_if, "netns", &n.ns],
            &["link", "set", &n.host_if, "up"],
            &["-n", &n.ns, "link", "set", &n.drive_if, "up"],
            &["-n", &n.ns, "link", "set", "lo", "up"],
        ];
        steps.iter().all(|s| ok(s)).then_some(n)
    }
}

impl Drop for Netns {
    fn drop(&mut self) {
        let _ = Command::new("ip")
            .args(["link", "del", &self.host_if])
            .status();
        let _ = Command::new("ip").args(["netns", "del", &self.ns]).status();
    }
}

/// A running `virtual-drive`, stopped when dropped; its output lines after `ready`.
struct VirtualDrive {
    child: Child,
    log: mpsc::Receiver<String>,
}

impl VirtualDrive {
    /// `virtual-drive --iface … --flash FILE` (one drive) in the namespace, ready.
    fn start(net: &Netns, flash: &Path) -> VirtualDrive {
        let mut child = Command::new("ip")
            .args([
                "netns",
                "exec",
                &net.ns,
                env!("CARGO_BIN_EXE_virtual-drive"),
            ])
            .args(["--iface", &net.drive_if, "--drives", "1", "--flash"])
            .arg(flash)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start virtual-drive");
        let stdout = child.stdout.take().expect("stdout");
        let (tx, log) = mpsc::channel::<String>();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                let _ = tx.send(line);
            }
        });
        let ready = log
            .recv_timeout(Duration::from_secs(30))
            .expect("virtual-drive printed nothing");
        assert!(ready.contains("ready"), "first line: {ready}");
        VirtualDrive { child, log }
    }

    /// Stops it with `signal` and waits for it (SIGKILL after 3 s).
    fn stop(&mut self, signal: i32) {
        // SAFETY: plain kill(2) on our own child.
        unsafe { libc::kill(self.child.id() as i32, signal) };
        let deadline = Instant::now() + Duration::from_secs(3);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// The next output line containing `what`, within `timeout`.
    fn wait_line(&self, what: &str, timeout: Duration) -> Option<String> {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.log.recv_timeout(left) {
                Ok(l) if l.contains(what) => return Some(l),
                Ok(_) => {}
                Err(_) => return None,
            }
        }
    }
}

impl Drop for VirtualDrive {
    fn drop(&mut self) {
        // SIGTERM: virtual-drive closes cleanly on it.
        self.stop(libc::SIGTERM);
    }
}

/// A directory of its own under the system's temporary directory, removed at the end.
struct TempDir(PathBuf);

impl TempDir {
    fn new() -> TempDir {
        let p = std::env::temp_dir().join(format!("vd-update-veth-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).expect("temporary directory");
        TempDir(p)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Fails unless running as root (what the veth tests need), with how to run them.
fn require_root() {
    // SAFETY: geteuid has no preconditions.
    let euid = unsafe { libc::geteuid() };
    assert_eq!(
        euid, 0,
        "the veth tests need root (network namespaces and raw sockets): run them as root, \
         e.g. `sudo -E env PATH=$PATH cargo test -p tests-host --test virtual_drive_update_veth` \
         (CI runs as root)"
    );
}

fn seed() -> [u8; 32] {
    efw::sign::dev_key()
}

/// A master on the host end of the veth pair that has given the drive its station
/// address (retried while the link comes up).
fn master(net: &Netns) -> SocketMaster {
    let mut m = SocketMaster::open(&net.host_if, Duration::from_millis(200))
        .unwrap_or_else(|e| panic!("raw socket on {}: {e}", net.host_if));
    station_address(&mut m);
    m
}

fn station_address(m: &mut SocketMaster) {
    let deadline = Instant::now() + Duration::from_secs(5);
    while m.apwr(0, 0x0010, &STATION.to_le_bytes()) != 1 {
        assert!(
            Instant::now() < deadline,
            "no drive answers on the veth pair"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    assert_eq!(m.fprd_u16(STATION, 0x0010), STATION, "station address");
}

/// SII word pair at `addr`.
fn sii(m: &mut SocketMaster, addr: u16) -> u32 {
    m.sii_read(STATION, addr)
        .unwrap_or_else(|| panic!("SII word {addr:#06x}"))
}

fn request(m: &mut SocketMaster, ctl: u16, want: u16, what: &str) {
    m.request_state(STATION, ctl);
    let st = m.wait_state(STATION, want, 2_000_000_000, 1_000_000, |_| {});
    assert_eq!(st, (want, 0), "{what}: AL status, AL status code");
}

/// Init → Pre-Op with the standard mailbox of SII words 0x18–0x1B.
fn to_preop(m: &mut SocketMaster) {
    let rx = sii(m, 0x18);
    let tx = sii(m, 0x1A);
    let mbx = (rx as u16, (rx >> 16) as u16, tx as u16, (tx >> 16) as u16);
    assert_eq!(m.configure_mailbox(STATION, mbx), 1, "SM0/SM1");
    request(m, 0x02, 0x02, "Init → Pre-Op");
}

/// 0x100A as text.
fn version_text(m: &mut SocketMaster) -> String {
    let v = m.sdo_upload(STATION, 0x100A, 0).expect("0x100A");
    let b: Vec<u8> = v
        .to_le_bytes()
        .into_iter()
        .take_while(|&c| c != 0)
        .collect();
    String::from_utf8(b).expect("0x100A text")
}

fn boot_state(m: &mut SocketMaster) -> u64 {
    m.sdo_upload(STATION, 0x2309, 0).expect("0x2309")
}

/// Polls 0x2309 until it reads 0 (confirmed); returns how long that took.
fn wait_confirmed(m: &mut SocketMaster) -> Duration {
    let t0 = Instant::now();
    loop {
        let s = boot_state(m);
        if s == 0 {
            return t0.elapsed();
        }
        assert_eq!(s, 1, "0x2309 on the way to confirmed: trial");
        assert!(
            t0.elapsed() < Duration::from_secs(2),
            "0x2309 still {s} 2 s after Pre-Op"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The version in the header page of the active partition of the boot file.
fn boot_file_version(boot: &Path) -> u32 {
    use firmware::flash_layout::{ACTIVE, BOOT_STATE, HEADER_OFFSET};
    let bytes = std::fs::read(boot).expect("boot file");
    assert_eq!(
        bytes.len(),
        tests_host::sim_update::BOOT_FILE_SIZE,
        "boot file size"
    );
    let at = (ACTIVE.offset - BOOT_STATE.offset + HEADER_OFFSET) as usize;
    let expected = efw::Expected {
        vendor_id: VENDOR_ID,
        product_code: Variant::HybridServo.product_code(),
        esc: efw::Esc::Lan9252,
        capacity: firmware::flash_layout::IMAGE_MAX,
        public_key: firmware::update::PUBLIC_KEY.expect("the simulation trusts the dev key"),
        min_security_version: 0,
    };
    efw::check_header(&bytes[at..at + efw::HEADER_LEN], &expected)
        .expect("a signed header in the active partition")
        .version
}

#[test]
fn foe_update_over_a_veth_pair_survives_a_restart_of_virtual_drive() {
    require_root();
    let t0 = Instant::now();
    let net = Netns::create('u').expect(
        "running as root, but the network namespace / veth pair could not be created \
         (iproute2 installed? kernel veth and netns support?)",
    );
    let dir = TempDir::new();
    let flash = dir.0.join("drive.flash");
    let boot = tests_host::sim_update::boot_file(&flash);
    let mut vd = VirtualDrive::start(&net, &flash);
    let mut m = master(&net);

    // Identity and the boot mailbox from the SII.
    assert_eq!(sii(&mut m, 0x08), VENDOR_ID, "vendor ID");
    assert_eq!(sii(&mut m, 0x0A), Variant::HybridServo.product_code());
    let (rx, tx) = (sii(&mut m, 0x14), sii(&mut m, 0x16));
    assert_eq!(
        (rx as u16, (rx >> 16) as u16, tx as u16, (tx >> 16) as u16),
        (0x1000, 128, 0x1080, 128),
        "boot mailbox (SII 0x14-0x17)"
    );
    // Before: the image has no update header, 0x100A is the crate version.
    to_preop(&mut m);
    assert_eq!(version_text(&mut m), env!("CARGO_PKG_VERSION"));
    assert_eq!(boot_state(&mut m), 0, "0x2309 confirmed");
    request(&mut m, 0x11, 0x01, "Pre-Op → Init");

    // Init → Bootstrap (the boot mailbox into SM0/SM1, as SOEM does), the download.
    assert_eq!(m.enter_bootstrap(STATION), (0x03, 0), "Init → Bootstrap");
    assert_eq!(m.mbx, (0x1000, 128, 0x1080, 128));
    let image: Vec<u8> = (0..20_000usize)
        .map(|i| (i as u8).wrapping_mul(13) ^ 0x3C)
        .collect();
    let file = efw::sign::update_file(
        &seed(),
        VENDOR_ID,
        Variant::HybridServo.product_code(),
        efw::Esc::Lan9252,
        VERSION,
        &image,
    );
    let t_foe = Instant::now();
    let stats = m
        .foe_write(STATION, b"ecs-lan9252.efw", 0, &file)
        .expect("the download is accepted");
    let foe_time = t_foe.elapsed();
    assert_eq!(
        stats.packets as usize,
        file.len().div_ceil(116),
        "116-byte DATA"
    );
    assert!(stats.busy >= 10, "one BUSY per page erase: {stats:?}");

    // Bootstrap → Init: the drive resets into its bootloader, which swaps.
    request(&mut m, 0x11, 0x01, "Bootstrap → Init");
    let line = vd
        .wait_line("firmware update accepted", Duration::from_secs(5))
        .expect("virtual-drive logs the reset into the bootloader");
    assert!(line.contains("2.3.0") && line.contains("Swap"), "{line}");
    to_preop(&mut m);
    assert_eq!(version_text(&mut m), "2.3.0", "0x100A after the update");
    let confirmed_after = wait_confirmed(&mut m);
    let info = String::from_utf8(
        m.foe_read(STATION, firmware::update::INFO_FILE, 0)
            .expect("the information file"),
    )
    .expect("text");
    assert!(
        info.contains("version=2.3.0")
            && info.contains("signature=valid")
            && info.contains("boot=confirmed"),
        "{info}"
    );
    let frames_first = m.frames;

    // A power cut: the update is in the boot flash FILE.boot.
    vd.stop(libc::SIGKILL);
    assert_eq!(boot_file_version(&boot), VERSION, "{}", boot.display());
    let vd2 = VirtualDrive::start(&net, &flash);
    station_address(&mut m);
    to_preop(&mut m);
    assert_eq!(version_text(&mut m), "2.3.0", "0x100A after the restart");
    assert_eq!(boot_state(&mut m), 0, "0x2309 after the restart: confirmed");
    request(&mut m, 0x11, 0x01, "Pre-Op → Init");
    drop(vd2);
    eprintln!(
        "veth update: {} bytes in {} DATA + {} BUSY, {} frames, {:.2} s; confirmed {} ms \
         after Pre-Op; {} frames in all ({} lost, {} stray), {:.1} s",
        file.len(),
        stats.packets,
        stats.busy,
        stats.frames,
        foe_time.as_secs_f64(),
        confirmed_after.as_millis(),
        m.frames,
        m.lost,
        m.stray,
        t0.elapsed().as_secs_f64()
    );
    assert!(frames_first > 0);
    assert_eq!(m.lost, 0, "no frame lost on the veth pair");
}
