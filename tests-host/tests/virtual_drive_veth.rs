//! `virtual-drive` on a real raw socket: a veth pair whose one end lives in a network
//! namespace of its own, with `virtual-drive` (2 drives) listening there, and
//! ethercrab as the master on the other end bringing both drives to Op with cyclic
//! exchange and the expected working counter.
//!
//! A second test stops the master in the middle of a PV move and checks over SDO that
//! the drive reacted on its own clock (issue 15).
//! A third runs `virtual-drive --fault bus-overvoltage@1s` and reads the drive's report
//! (0x603F, the newest 0x10F3 message) over SDO after the fault time (issue 19).
//!
//! Needs root (network namespaces, raw sockets) and iproute2. CI runs as root, so the
//! tests are plain `#[test]`s: without root they fail and say how to run them
//! (`sudo -E cargo test -p tests-host --test virtual_drive_veth`); as root a failed
//! namespace or veth setup is a failure too, never a skip.
#![deny(clippy::undocumented_unsafe_blocks)]

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use ethercrab::std::ethercat_now;
use ethercrab::{MainDevice, PduStorage};
use tests_host::netns::{Killed, Netns};

/// One frame store per test (each test has its own master).
type Storage = PduStorage<16, { PduStorage::element_size(1100) }>;
static PDU_STORAGE: Storage = PduStorage::new();
static PDU_STORAGE_PV: Storage = PduStorage::new();
static PDU_STORAGE_FAULT: Storage = PduStorage::new();

/// Fails unless running as root (what the veth tests need), with how to run them.
fn require_root() {
    // SAFETY: geteuid has no preconditions.
    let euid = unsafe { libc::geteuid() };
    assert_eq!(
        euid, 0,
        "the veth tests need root (network namespaces and raw sockets): run them as root, \
         e.g. `sudo -E env PATH=$PATH cargo test -p tests-host --test virtual_drive_veth` \
         (CI runs as root)"
    );
}

/// A namespace + veth pair with `virtual-drive --drives N` listening in it, ready.
fn start_virtual_drive(tag: char, drives: usize) -> (Netns, Killed) {
    let (net, child, _log) = start_virtual_drive_with(tag, drives, &[]);
    (net, child)
}

/// [`start_virtual_drive`] with `extra` options; also the lines it prints after
/// `ready`.
fn start_virtual_drive_with(
    tag: char,
    drives: usize,
    extra: &[&str],
) -> (Netns, Killed, mpsc::Receiver<String>) {
    require_root();
    let net = Netns::create(&format!("vd{tag}")).expect(
        "running as root, but the network namespace / veth pair could not be created \
         (iproute2 installed? kernel veth and netns support?)",
    );
    let child = Command::new("ip")
        .args([
            "netns",
            "exec",
            &net.ns,
            env!("CARGO_BIN_EXE_virtual-drive"),
            "--iface",
            &net.drive_if,
            "--drives",
            &drives.to_string(),
        ])
        .args(extra)
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
    (net, child, rx)
}

/// The master of [`tests_host::netns::veth_master`].
fn master(storage: &'static Storage, host_if: &str) -> MainDevice<'static> {
    tests_host::netns::veth_master(storage, host_if)
}

#[test]
fn ethercrab_brings_virtual_drive_to_op_over_a_veth_pair() {
    let _one = tests_host::netns::one_at_a_time();
    let (net, child) = start_virtual_drive('o', 2);
    let md = master(&PDU_STORAGE, &net.host_if);
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

/// `virtual-drive` (1 drive) in PV at 50 000 inc/s, Operation enabled, with ethercrab
/// over the veth pair; then the master stops sending for good (no process data). The
/// drive must react on its own clock: the SM2 watchdog (100 ms) and the 0x6007 = 1
/// fault reaction on the 0x6085 ramp (2 000 000 inc/s², 25 ms from 50 000 inc/s). Read
/// afterwards over SDO (mailbox traffic only): the statusword has left Operation
/// enabled 100 ms + one ramp after the last frame (plus a 10 ms allowance for the host
/// scheduler), and 0x6064 no longer changes (two reads 200 ms apart).
#[test]
fn silent_master_stops_virtual_drive_in_pv_over_a_veth_pair() {
    let _one = tests_host::netns::one_at_a_time();
    let (net, child) = start_virtual_drive('p', 1);
    let md = master(&PDU_STORAGE_PV, &net.host_if);
    type Found = (u16, u16, u16, i32, i32, Duration);
    let result: Result<Found, (&str, ethercrab::error::Error)> = async_io::block_on(async {
        let group = md
            .init_single_group::<4, 128>(ethercat_now)
            .await
            .map_err(|e| ("init", e))?;
        {
            let sd = group.subdevice(&md, 0).map_err(|e| ("drive 0", e))?;
            sd.sdo_write(0x6060, 0, 3i8)
                .await
                .map_err(|e| ("0x6060", e))?;
            sd.sdo_write(0x60FF, 0, 50_000i32)
                .await
                .map_err(|e| ("0x60FF", e))?;
        }
        let group = group.into_op(&md).await.map_err(|e| ("into_op", e))?;
        // TxPDO1: 603F, 6041, ...; RxPDO1: 6040, 607A, 60B0, 60B8.
        let mut statusword = 0u16;
        let cycle = |cw: u16| {
            let sd = group.subdevice(&md, 0).expect("drive 0");
            sd.outputs_raw_mut()[0..2].copy_from_slice(&cw.to_le_bytes());
        };
        let mut enabled_at = None;
        for k in 0..3000u32 {
            // State-driven enable: shutdown from Switch on disabled, switch on from
            // Ready to switch on, enable operation from Switched on.
            let cw = match statusword & 0x6F {
                0x21 => 0x0007,
                0x23 | 0x27 => 0x000F,
                _ if statusword & 0x4F == 0x40 => 0x0006,
                _ => 0x0000,
            };
            cycle(cw);
            if let Err(e) = group.tx_rx(&md).await {
                eprintln!("tx_rx failed in cycle {k} (statusword {statusword:#06x})");
                return Err(("tx_rx", e));
            }
            let sd = group.subdevice(&md, 0).map_err(|e| ("drive 0", e))?;
            let i = sd.inputs_raw();
            statusword = u16::from_le_bytes([i[2], i[3]]);
            if statusword & 0x6F == 0x27 && enabled_at.is_none() {
                enabled_at = Some(k);
            }
            // Moving for 300 cycles after the enable, then stop.
            if enabled_at.is_some_and(|e| k >= e + 300) {
                break;
            }
            async_io::Timer::after(Duration::from_millis(1)).await;
        }
        assert!(
            statusword & 0x6F == 0x27,
            "Operation enabled in PV before the pause: statusword {statusword:#06x}"
        );
        let last_frame = Instant::now();
        // The master stops: no frame at all for 100 ms + one ramp + 10 ms.
        std::thread::sleep(Duration::from_millis(135));
        let sd = group.subdevice(&md, 0).map_err(|e| ("drive 0", e))?;
        let sw: u16 = sd.sdo_read(0x6041, 0).await.map_err(|e| ("0x6041", e))?;
        let read_after = last_frame.elapsed();
        let err: u16 = sd.sdo_read(0x603F, 0).await.map_err(|e| ("0x603F", e))?;
        // The power is off: the unbraked plant rotor may still roll out a little
        // after the ramp; it must have come to rest 300 ms later.
        async_io::Timer::after(Duration::from_millis(300)).await;
        let p1: i32 = sd.sdo_read(0x6064, 0).await.map_err(|e| ("0x6064", e))?;
        async_io::Timer::after(Duration::from_millis(200)).await;
        let p2: i32 = sd.sdo_read(0x6064, 0).await.map_err(|e| ("0x6064", e))?;
        Ok((statusword, sw, err, p1, p2, read_after))
    });
    let (before, sw, err, p1, p2, read_after) =
        result.expect("ethercrab over the veth pair (PV, then silent)");
    eprintln!(
        "veth PV: statusword {before:#06x} in Op, {sw:#06x} read {} ms after the last frame, \
         0x603F {err:#06x}, 0x6064 {p1} → {p2}",
        read_after.as_millis()
    );
    assert_ne!(
        sw & 0x6F,
        0x27,
        "statusword {sw:#06x} still Operation enabled 135 ms after the master stopped"
    );
    assert_eq!(
        sw & 0x4F,
        0x08,
        "0x6007 = 1 (default): Fault, statusword {sw:#06x}"
    );
    assert_eq!(
        err, 0x8700,
        "0x603F after the fault reaction: the SM watchdog's code, as in its emergency"
    );
    // Power off: the unpowered rotor of the plant may still settle into its detent by
    // up to one encoder count (12.5 units); it must not move beyond that.
    assert!(
        p1.abs_diff(p2) <= 13,
        "0x6064 stopped changing (two reads 200 ms apart): {p1} → {p2}"
    );
    drop(child);
}

/// `virtual-drive --fault bus-overvoltage@1s` (1 drive) brought to Op by ethercrab:
/// after the fault time the drive's own over-voltage detection has reported it —
/// 0x603F = 0x3210 and the newest 0x10F3 message is its emergency (diagnosis code
/// 0xE800 | 0x3210 << 16), read over SDO — and the log shows the injection and the
/// red LED's two flashes.
#[test]
fn injected_bus_overvoltage_is_reported_over_sdo_on_a_veth_pair() {
    let _one = tests_host::netns::one_at_a_time();
    let (net, child, log) = start_virtual_drive_with('f', 1, &["--fault", "bus-overvoltage@1s"]);
    let md = master(&PDU_STORAGE_FAULT, &net.host_if);
    type Found = (u16, u16, u8, [u8; 28]);
    let result: Result<Found, (&str, ethercrab::error::Error)> = async_io::block_on(async {
        let group = md
            .init_single_group::<4, 128>(ethercat_now)
            .await
            .map_err(|e| ("init", e))?;
        let before: u16 = group
            .subdevice(&md, 0)
            .map_err(|e| ("drive 0", e))?
            .sdo_read(0x603F, 0)
            .await
            .map_err(|e| ("0x603F", e))?;
        let group = group.into_op(&md).await.map_err(|e| ("into_op", e))?;
        // Cyclic exchange until well after the fault time (1 s after start).
        let start = Instant::now();
        while start.elapsed() < Duration::from_millis(1500) {
            group.tx_rx(&md).await.map_err(|e| ("tx_rx", e))?;
            async_io::Timer::after(Duration::from_millis(1)).await;
        }
        let sd = group.subdevice(&md, 0).map_err(|e| ("drive 0", e))?;
        let err: u16 = sd.sdo_read(0x603F, 0).await.map_err(|e| ("0x603F", e))?;
        let newest: u8 = sd.sdo_read(0x10F3, 2).await.map_err(|e| ("0x10F3:02", e))?;
        let msg: [u8; 28] = sd
            .sdo_read(0x10F3, newest)
            .await
            .map_err(|e| ("0x10F3 message", e))?;
        Ok((before, err, newest, msg))
    });
    let (before, err, newest, msg) = result.expect("ethercrab over the veth pair (fault)");
    assert_eq!(before, 0, "no fault before the injection");
    assert_eq!(err, 0x3210, "0x603F after the injected over-voltage");
    assert!(newest >= 6, "0x10F3:02 {newest}");
    assert_eq!(
        u32::from_le_bytes([msg[0], msg[1], msg[2], msg[3]]),
        0x3210_E800,
        "newest diagnosis message {msg:02x?}"
    );
    drop(child);
    let lines: Vec<String> = log.try_iter().collect();
    assert!(
        lines
            .iter()
            .any(|l| l.contains("fault injected: bus-overvoltage")),
        "{lines:#?}"
    );
    assert!(
        lines
            .iter()
            .any(|l| l.contains("red fault LED 2 flash(es)")),
        "{lines:#?}"
    );
}
