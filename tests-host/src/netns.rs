//! A network namespace with one end of a veth pair, and `virtual-drive` running in
//! it: the set-up of the real-socket tests (root and iproute2 needed).

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// A namespace holding the drive end of a veth pair; removed on drop.
pub struct Netns {
    /// Namespace name.
    pub ns: String,
    /// The master's end (in the caller's namespace).
    pub host_if: String,
    /// The drive's end (in [`Netns::ns`]).
    pub drive_if: String,
}

impl Netns {
    /// A namespace with one end of a new veth pair; `tag` keeps the names of tests
    /// running in parallel apart. `None` when a step fails.
    pub fn create(tag: &str) -> Option<Netns> {
        let id = std::process::id() % 100_000;
        let ns = format!("ecs{tag}{id}");
        let host_if = format!("{tag}{id}h");
        let drive_if = format!("{tag}{id}d");
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
            drive_if: drive_if.clone(),
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
}

impl Drop for Netns {
    fn drop(&mut self) {
        let _ = Command::new("ip")
            .args(["link", "del", &self.host_if])
            .status();
        let _ = Command::new("ip").args(["netns", "del", &self.ns]).status();
    }
}

/// A child process stopped on drop: SIGTERM, then SIGKILL after 3 s.
pub struct Killed(pub Child);

impl Drop for Killed {
    fn drop(&mut self) {
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

/// True when running as root (what namespaces and raw sockets need).
pub fn is_root() -> bool {
    // SAFETY: geteuid has no preconditions.
    unsafe { libc::geteuid() == 0 }
}

/// Runs `program` (the `virtual-drive` binary) with `args` in `net`'s namespace on its
/// drive end; returns once it printed its `ready` line, with the lines that follow.
pub fn start_virtual_drive(
    net: &Netns,
    program: &str,
    args: &[&str],
) -> Result<(Killed, mpsc::Receiver<String>), String> {
    let child = Command::new("ip")
        .args(["netns", "exec", &net.ns, program, "--iface", &net.drive_if])
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .map_err(|e| format!("start virtual-drive: {e}"))?;
    let mut child = Killed(child);
    let stdout = child.0.stdout.take().ok_or("no stdout")?;
    let (tx, rx) = mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let ready = rx
        .recv_timeout(Duration::from_secs(30))
        .map_err(|_| "virtual-drive printed nothing".to_string())?;
    if !ready.contains("ready") {
        return Err(format!("virtual-drive's first line: {ready}"));
    }
    Ok((child, rx))
}

/// An ethercrab master on the host end `host_if` of a veth pair, its frame task on a
/// thread of its own, with the timeouts of a shared machine: several veth tests run at
/// once, virtual drives and masters side by side, and ethercrab's 30 ms PDU and 10 ms
/// EEPROM timeouts were seen to expire during init.
pub fn veth_master<const N: usize, const DATA: usize>(
    storage: &'static ethercrab::PduStorage<N, DATA>,
    host_if: &str,
) -> ethercrab::MainDevice<'static> {
    let (pdu_tx, pdu_rx, pdu_loop) = storage.try_split().expect("split once");
    let task =
        ethercrab::std::tx_rx_task(host_if, pdu_tx, pdu_rx).expect("raw socket on the host end");
    std::thread::spawn(move || {
        let _ = async_io::block_on(task);
    });
    ethercrab::MainDevice::new(
        pdu_loop,
        ethercrab::Timeouts {
            wait_loop_delay: Duration::from_millis(2),
            mailbox_response: Duration::from_millis(2000),
            pdu: Duration::from_millis(300),
            eeprom: Duration::from_millis(100),
            ..ethercrab::Timeouts::default()
        },
        ethercrab::MainDeviceConfig {
            dc_static_sync_iterations: 100,
            ..ethercrab::MainDeviceConfig::default()
        },
    )
}

/// The veth tests of one test program, one at a time: held for the whole test. Two
/// `virtual-drive` processes (each with its real-time frame and drives' threads) and
/// two masters at once on a 2-core machine starve a master's own thread, and its scan
/// then times out (seen as ethercrab `Timeout(Pdu)` at `init_single_group`), which
/// says nothing about the drive.
pub fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static ONE: std::sync::Mutex<()> = std::sync::Mutex::new(());
    ONE.lock().unwrap_or_else(|e| e.into_inner())
}

/// One `virtual-drive` (`program`, 1 drive, `extra` options) in a namespace of its own
/// named after `tag`, ready; its log lines after `ready`. Panics with the reason when
/// not root or when the namespace cannot be made (a veth test needs both).
pub fn start_one_drive(
    tag: &str,
    program: &str,
    extra: &[&str],
) -> (Netns, Killed, std::sync::mpsc::Receiver<String>) {
    assert!(
        is_root(),
        "the veth tests need root (network namespaces and raw sockets): run them as root, \
         e.g. `sudo -E env PATH=$PATH cargo test -p tests-host` (CI runs as root)"
    );
    let net = Netns::create(tag)
        .expect("running as root, but the namespace / veth pair could not be created");
    let mut args = vec!["--drives", "1"];
    args.extend_from_slice(extra);
    let (child, rx) = start_virtual_drive(&net, program, &args).expect("virtual-drive");
    (net, child, rx)
}
