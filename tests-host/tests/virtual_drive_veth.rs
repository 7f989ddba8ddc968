//! `virtual-drive` on a real raw socket: a veth pair whose one end lives in a network
//! namespace of its own, with `virtual-drive` (2 drives) listening there, and
//! ethercrab as the master on the other end bringing both drives to Op with cyclic
//! exchange and the expected working counter.
//!
//! Needs root (network namespaces, raw sockets) and iproute2; otherwise the test says
//! it skipped and passes.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use ethercrab::std::{ethercat_now, tx_rx_task};
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, Timeouts};

static PDU_STORAGE: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

struct Netns {
    ns: String,
    host_if: String,
}

impl Netns {
    fn create() -> Option<Netns> {
        let id = std::process::id() % 100_000;
        let ns = format!("ecsvd{id}");
        let host_if = format!("vd{id}a");
        let drive_if = format!("vd{id}b");
        let ok = |args: &[&str]| {
            Command::new("ip")
                .args(args)
                .status()
                .is_ok_and(|s| s.success())
        };
        if !ok(&["netns", "add", &ns]) {
            return None;
        }
        let n = Netns {
            ns: ns.clone(),
            host_if: host_if.clone(),
        };
        let steps: [&[&str]; 5] = [
            &[
                "link", "add", &host_if, "type", "veth", "peer", "name", &drive_if,
            ],
            &["link", "set", &drive_if, "netns", &ns],
            &["link", "set", &host_if, "up"],
            &["-n", &ns, "link", "set", &drive_if, "up"],
            &["-n", &ns, "link", "set", "lo", "up"],
        ];
        for s in steps {
            if !ok(s) {
                return None;
            }
        }
        Some(n)
    }
    fn drive_if(&self) -> String {
        self.host_if.replace('a', "b")
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

struct Killed(Child);
impl Drop for Killed {
    fn drop(&mut self) {
        // SIGTERM first: virtual-drive closes cleanly on it.
        // SAFETY: plain kill(2) on our own child.
        unsafe { libc::kill(self.0.id() as i32, libc::SIGTERM) };
        let deadline = Instant::now() + Duration::from_secs(3);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.0.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn ethercrab_brings_virtual_drive_to_op_over_a_veth_pair() {
    // SAFETY: getuid has no preconditions.
    if unsafe { libc::getuid() } != 0 {
        eprintln!("skipped: the veth test needs root (network namespaces and raw sockets)");
        return;
    }
    let Some(net) = Netns::create() else {
        eprintln!("skipped: could not create a network namespace and veth pair (iproute2 / kernel support)");
        return;
    };
    let child = Command::new("ip")
        .args([
            "netns",
            "exec",
            &net.ns,
            env!("CARGO_BIN_EXE_virtual-drive"),
            "--iface",
            &net.drive_if(),
            "--drives",
            "2",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start virtual-drive");
    let mut child = Killed(child);
    let stdout = child.0.stdout.take().expect("stdout");
    let (tx, rx) = mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let ready = rx
        .recv_timeout(Duration::from_secs(30))
        .expect("virtual-drive printed nothing");
    assert!(ready.contains("ready"), "first line: {ready}");

    let (pdu_tx, pdu_rx, pdu_loop) = PDU_STORAGE.try_split().expect("split once");
    let task = tx_rx_task(&net.host_if, pdu_tx, pdu_rx).expect("raw socket on the host end");
    std::thread::spawn(move || {
        let _ = async_io::block_on(task);
    });
    let md = MainDevice::new(
        pdu_loop,
        Timeouts {
            wait_loop_delay: Duration::from_millis(2),
            mailbox_response: Duration::from_millis(2000),
            ..Timeouts::default()
        },
        MainDeviceConfig {
            dc_static_sync_iterations: 100,
            ..MainDeviceConfig::default()
        },
    );
    let result: Result<(usize, Vec<u16>, u32), ethercrab::error::Error> =
        async_io::block_on(async {
            let group = md.init_single_group::<4, 128>(ethercat_now).await?;
            let n = group.len();
            let mut product = 0;
            for sd in group.iter(&md) {
                product = sd.sdo_read::<u32>(0x1018, 2).await?;
            }
            let group = group.into_op(&md).await?;
            let mut wkcs = Vec::new();
            for _ in 0..50 {
                let r = group.tx_rx(&md).await?;
                wkcs.push(r.working_counter);
                async_io::Timer::after(Duration::from_millis(1)).await;
            }
            let group = group.into_safe_op(&md).await?;
            let group = group.into_pre_op(&md).await?;
            let _ = group.into_init(&md).await?;
            Ok((n, wkcs, product))
        });
    let (n, wkcs, product) = result.expect("ethercrab over the veth pair");
    eprintln!(
        "veth: {n} drives, product code {product:#010x}, {} cycles in Op, working counters {:?}…",
        wkcs.len(),
        &wkcs[..5]
    );
    assert_eq!(n, 2, "two drives discovered");
    assert_eq!(
        product,
        firmware::identity::Variant::HybridServo.product_code()
    );
    // LRW over two drives: read+write on each = 3 per drive.
    assert!(wkcs.iter().all(|&w| w == 6), "working counters {wkcs:?}");
    drop(child);
}
