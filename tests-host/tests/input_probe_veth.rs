//! Input function "probe" (0x2152 bit 5) seen by a real master: `virtual-drive
//! --input IN4=pulse:100ms` toggles IN4, ethercrab on the other end of a veth pair
//! arms touch probe 1 (0x60B8) and reads what it stored (0x60B9-0x60BB).
//!
//! * IN4 with its default function (none): its edges store nothing.
//! * IN4 assigned "probe" (0x2152:04 = 32) while the axis moves in PV: the rising and
//!   the falling edge each store the position of their tick, two different positions
//!   within the stretch the axis moved meanwhile.
//!
//! Needs root (network namespaces, raw sockets) and iproute2, as
//! `runtime_veth.rs`: without root the test fails and says how to run it.
#![deny(clippy::undocumented_unsafe_blocks)]

use std::time::Duration;

use ethercrab::std::ethercat_now;
use ethercrab::PduStorage;
use tests_host::netns::{start_one_drive, veth_master};

type Storage = PduStorage<16, { PduStorage::element_size(1100) }>;
static PDU: Storage = PduStorage::new();

type Failed = (&'static str, ethercrab::error::Error);

/// What the master read.
#[derive(Debug)]
struct Probe {
    /// 0x60B9 after the input toggled with no function assigned.
    status_unassigned: u16,
    /// 0x60B9 after it toggled assigned "probe" while the axis moved.
    status: u16,
    /// 0x60BA / 0x60BB: positions at the rising / falling edge.
    rising: i32,
    falling: i32,
    /// 0x6064 before touch probe 1 was armed the second time, and after both edges.
    before: i32,
    after: i32,
    /// Statusword once enabled.
    statusword: u16,
}

/// The CiA 402 enable sequence over SDO (controlword 0x6040, statusword 0x6041),
/// 10 ms per step; the statusword reached.
async fn enable_by_sdo(
    sd: &ethercrab::SubDeviceRef<'_, &ethercrab::SubDevice>,
) -> Result<u16, Failed> {
    let mut statusword = 0u16;
    for _ in 0..300 {
        let cw: u16 = match statusword & 0x6F {
            0x21 => 0x0007,
            0x23 | 0x27 => 0x000F,
            _ if statusword & 0x4F == 0x40 => 0x0006,
            _ => 0x0000,
        };
        sd.sdo_write(0x6040, 0, cw)
            .await
            .map_err(|e| ("0x6040", e))?;
        async_io::Timer::after(Duration::from_millis(10)).await;
        statusword = sd.sdo_read(0x6041, 0).await.map_err(|e| ("0x6041", e))?;
        if statusword & 0x6F == 0x27 {
            break;
        }
    }
    Ok(statusword)
}

#[test]
fn input_function_probe_latches_touch_probe_1_over_a_veth_pair() {
    let _one = tests_host::netns::one_at_a_time();
    let (net, child, _log) = start_one_drive(
        "rtprobe",
        env!("CARGO_BIN_EXE_virtual-drive"),
        &["--input", "IN4=pulse:100ms"],
    );
    let md = veth_master(&PDU, &net.host_if);
    let result: Result<Probe, Failed> = async_io::block_on(async {
        let group = md
            .init_single_group::<2, 128>(ethercat_now)
            .await
            .map_err(|e| ("init", e))?;
        let sd = group.subdevice(&md, 0).map_err(|e| ("drive 0", e))?;
        let wait = |ms| async_io::Timer::after(Duration::from_millis(ms));
        // Touch probe 1 on, input trigger, rising and falling edge, first event.
        sd.sdo_write(0x60B8, 0, 0x0031u16)
            .await
            .map_err(|e| ("0x60B8", e))?;
        wait(300).await;
        let status_unassigned: u16 = sd.sdo_read(0x60B9, 0).await.map_err(|e| ("0x60B9", e))?;
        // PV at 20000 inc/s, enabled by SDO in Pre-Op: the positions move.
        sd.sdo_write(0x6060, 0, 3i8)
            .await
            .map_err(|e| ("0x6060", e))?;
        sd.sdo_write(0x60FF, 0, 20_000i32)
            .await
            .map_err(|e| ("0x60FF", e))?;
        let statusword = enable_by_sdo(&sd).await?;
        wait(200).await;
        // IN4 assigned "probe"; touch probe 1 re-armed (off, then on).
        sd.sdo_write(0x2152, 4, 32u16)
            .await
            .map_err(|e| ("0x2152:04", e))?;
        sd.sdo_write(0x60B8, 0, 0x0000u16)
            .await
            .map_err(|e| ("0x60B8", e))?;
        let before: i32 = sd.sdo_read(0x6064, 0).await.map_err(|e| ("0x6064", e))?;
        sd.sdo_write(0x60B8, 0, 0x0031u16)
            .await
            .map_err(|e| ("0x60B8", e))?;
        // Two periods of IN4: at least one rising and one falling edge.
        wait(250).await;
        let status: u16 = sd.sdo_read(0x60B9, 0).await.map_err(|e| ("0x60B9", e))?;
        let rising: i32 = sd.sdo_read(0x60BA, 0).await.map_err(|e| ("0x60BA", e))?;
        let falling: i32 = sd.sdo_read(0x60BB, 0).await.map_err(|e| ("0x60BB", e))?;
        let after: i32 = sd.sdo_read(0x6064, 0).await.map_err(|e| ("0x6064", e))?;
        Ok(Probe {
            status_unassigned,
            status,
            rising,
            falling,
            before,
            after,
            statusword,
        })
    });
    drop(child);
    let p = result.expect("ethercrab over the veth pair");
    eprintln!("{p:?}");
    assert_eq!(
        p.status_unassigned & 0x7,
        0x1,
        "enabled, nothing stored while IN4 has no function: {p:?}"
    );
    assert_eq!(p.statusword & 0x6F, 0x27, "Operation enabled: {p:?}");
    assert_eq!(p.status & 0x7, 0x7, "both edges stored: {p:?}");
    assert!(p.after - p.before > 1000, "the axis moved: {p:?}");
    for v in [p.rising, p.falling] {
        assert!(
            (p.before..=p.after).contains(&v),
            "a stored position lies in the stretch moved: {p:?}"
        );
    }
    // 50 ms between the edges at 20000 inc/s: about 1000 increments apart.
    assert!(
        p.rising.abs_diff(p.falling) > 300,
        "the edges' positions differ: {p:?}"
    );
}
