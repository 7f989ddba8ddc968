//! The scope end to end on a real raw socket: `virtual-drive` in a network namespace
//! on one end of a veth pair, the `scope` program (ethercrab) on the other. It
//! enables the drive in CSP, arms the scope at standstill, commands a 25 000-unit
//! move and reads the record back over SDO (0x2503, segmented uploads); the CSV must
//! carry the requested channels, the trigger at the pre-trigger sample, and the
//! position demand crossing the trigger level there.
//!
//! Needs root (network namespaces, raw sockets) and iproute2, as
//! `tests/virtual_drive_veth.rs`: without root the test fails and says how to run it.
#![deny(clippy::undocumented_unsafe_blocks)]

use std::process::Command;
use tests_host::netns::{is_root, start_virtual_drive, Netns};

#[test]
fn scope_records_a_csp_move_of_virtual_drive_over_a_veth_pair() {
    assert!(
        is_root(),
        "the veth tests need root (network namespaces and raw sockets): run them as root, \
         e.g. `sudo -E env PATH=$PATH cargo test -p tests-host --test scope_veth` (CI runs as root)"
    );
    let net = Netns::create("sc").expect(
        "running as root, but the network namespace / veth pair could not be created \
         (iproute2 installed? kernel veth and netns support?)",
    );
    let (drive, _log) =
        start_virtual_drive(&net, env!("CARGO_BIN_EXE_virtual-drive"), &[]).expect("virtual-drive");
    let dir = std::env::temp_dir().join(format!("scope-veth-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("output directory");
    let prefix = dir.join("csp");
    let out = Command::new(env!("CARGO_BIN_EXE_scope"))
        .args([
            "--iface",
            &net.host_if,
            "--move",
            "csp",
            "--distance",
            "25000",
        ])
        .args(["--ch", "0x6062", "--ch", "0x6064", "--ch", "0x60F4"])
        .args(["--ch", "0x2510:3", "--divisor", "3", "--pre", "40"])
        .args(["--timeout", "20", "--out"])
        .arg(&prefix)
        .output()
        .expect("run scope");
    drop(drive);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "scope failed: {stdout}\n{stderr}");
    eprintln!("{stdout}");

    let csv = std::fs::read_to_string(prefix.with_extension("csv")).expect("CSV written");
    let png = std::fs::metadata(prefix.with_extension("png")).expect("PNG written");
    assert!(png.len() > 1000, "PNG of {} bytes", png.len());
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    assert_eq!(header.len(), 6, "{header:?}");
    assert_eq!(&header[..2], ["sample", "time_ms"]);
    for (col, key) in header[2..]
        .iter()
        .zip(["0x6062", "0x6064", "0x60f4", "0x2510:3"])
    {
        assert!(col.starts_with(key), "column {col}, expected {key}");
    }
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().expect("number")).collect())
        .collect();
    // Four channels: 192 samples per channel, the trigger at sample 40 (t = 0).
    assert_eq!(rows.len(), 192, "a full record");
    let trigger = rows
        .iter()
        .position(|r| r[1] == 0.0)
        .expect("a sample at t = 0");
    assert_eq!(trigger, 40, "the trigger after the 40 pre-trigger samples");
    assert_eq!(rows[41][1], 3.0, "3 ms per sample");
    // The move ends on its target, start + 25 000, and the position demand rises
    // through the level (start + 5 % of the distance) exactly at the trigger. (The
    // record starts 120 ms before the trigger, early in the move: the ring keeps the
    // last 40 samples before it.)
    let demand: Vec<f64> = rows.iter().map(|r| r[2]).collect();
    let start = *demand.last().expect("samples") - 25_000.0;
    let level = start + 1250.0;
    assert!(
        demand[trigger - 1] < level && demand[trigger] >= level,
        "demand {} → {} around the level {level}",
        demand[trigger - 1],
        demand[trigger]
    );
    assert!(demand[0] < level, "{demand:?}");
    // The actual position follows; the bus voltage (0x2510:03, mV) is the plant's.
    let actual_end = rows.last().expect("samples")[3];
    assert!(
        (actual_end - (start + 25_000.0)).abs() < 2_000.0,
        "{actual_end}"
    );
    assert!(rows.iter().all(|r| r[5] > 10_000.0), "bus voltage in mV");
    let _ = std::fs::remove_dir_all(&dir);
}
