//! The board's runtime seen by a real master: `virtual-drive` (which runs the same
//! `firmware::runtime` as the board's tasks) in a network namespace, ethercrab on the
//! other end of a veth pair.
//!
//! * The DIP function bank (`--dip-function`) sets the current and the direction
//!   while 0x2025 = 0, and is ignored otherwise; the ID bank (`--dip-id`) gives the
//!   station alias.
//! * 0x60FE drives OUT3 (in the pin log and in 0x2157); the alarm outputs follow a
//!   fault; the brake output follows the drive's enable.
//! * An axis enabled by SDO in Pre-Op: 0x2013 (current auto-tune) is refused and the
//!   axis holds; the master taking the ESM to Init stops it (the 0x6007 reaction: the
//!   brake engages). That it stays at rest and needs a new enable is
//!   `firmware/src/drive/safety_tests.rs`.
//!
//! Needs root (network namespaces, raw sockets) and iproute2, as
//! `virtual_drive_veth.rs`: without root the tests fail and say how to run them.
#![deny(clippy::undocumented_unsafe_blocks)]

use std::sync::mpsc;
use std::time::Duration;

use ethercrab::std::ethercat_now;
use ethercrab::{MainDevice, PduStorage, SubDeviceGroup};
use tests_host::netns::{start_one_drive, veth_master, Killed, Netns};

type Storage = PduStorage<16, { PduStorage::element_size(1100) }>;
static PDU_DIP_ON: Storage = PduStorage::new();
static PDU_DIP_OFF: Storage = PduStorage::new();
static PDU_OUTPUTS: Storage = PduStorage::new();
static PDU_PREOP: Storage = PduStorage::new();

type Group = SubDeviceGroup<4, 128, ethercrab::DefaultLock, ethercrab::subdevice_group::Op>;
type Failed = (&'static str, ethercrab::error::Error);

/// `virtual-drive` (1 drive, `extra` options) in a namespace of its own, ready; its
/// log lines after `ready`.
fn start(tag: &str, extra: &[&str]) -> (Netns, Killed, mpsc::Receiver<String>) {
    start_one_drive(
        &format!("rt{tag}"),
        env!("CARGO_BIN_EXE_virtual-drive"),
        extra,
    )
}

fn master(storage: &'static Storage, host_if: &str) -> MainDevice<'static> {
    veth_master(storage, host_if)
}

/// PV (0x6060 = 3) with target velocity `$v` (0x60FF) over SDO.
macro_rules! pv_mode {
    ($sd:expr, $v:expr) => {
        $sd.sdo_write(0x6060, 0, 3i8)
            .await
            .map_err(|e| ("0x6060", e))?;
        $sd.sdo_write(0x60FF, 0, $v)
            .await
            .map_err(|e| ("0x60FF", e))?;
    };
}

/// One process-data cycle with controlword `cw` (RxPDO1 starts with 0x6040); returns
/// the statusword (TxPDO1: 0x603F, 0x6041, …).
async fn cycle(md: &MainDevice<'static>, group: &Group, cw: u16) -> Result<u16, Failed> {
    {
        let sd = group.subdevice(md, 0).map_err(|e| ("drive 0", e))?;
        sd.outputs_raw_mut()[0..2].copy_from_slice(&cw.to_le_bytes());
    }
    group.tx_rx(md).await.map_err(|e| ("tx_rx", e))?;
    let sd = group.subdevice(md, 0).map_err(|e| ("drive 0", e))?;
    let i = sd.inputs_raw();
    Ok(u16::from_le_bytes([i[2], i[3]]))
}

/// Cycles until Operation enabled (state-driven CiA 402 enable), then `extra` more.
async fn enable(md: &MainDevice<'static>, group: &Group, extra: u32) -> Result<u16, Failed> {
    let mut sw = 0u16;
    let mut enabled = None;
    for k in 0..3000u32 {
        let cw = match sw & 0x6F {
            0x21 => 0x0007,
            0x23 | 0x27 => 0x000F,
            _ if sw & 0x4F == 0x40 => 0x0006,
            _ => 0x0000,
        };
        sw = cycle(md, group, cw).await?;
        if sw & 0x6F == 0x27 && enabled.is_none() {
            enabled = Some(k);
        }
        if enabled.is_some_and(|e| k >= e + extra) {
            break;
        }
        async_io::Timer::after(Duration::from_millis(1)).await;
    }
    Ok(sw)
}

/// What one PV run at +1000 inc/s in open loop showed.
#[derive(Debug)]
struct PvRun {
    /// 0x2158:1..7 read in Pre-Op.
    dip: [u32; 7],
    /// The station alias the master read.
    alias: u16,
    /// Current set-point amplitude (0x2301 / 0x2302), mA.
    amplitude_ma: f64,
    /// Electrical angle change over ≈ 100 ms (0x2300, signed 1/65536 turns).
    angle_step: i32,
    /// 0x6064 change over the same time.
    moved: i32,
    /// Statusword after the enable.
    statusword: u16,
}

/// `--dip-id 01111111` (S1 OFF: station 1) and `--dip-function 10111111` (SW1 ON,
/// SW2 OFF, SW3 ON → 4.5 A; SW4 ON full standstill current; SW5 ON reversed; SW6/SW7
/// ON no smoothing); 0x2025 = `control_mode`; PV in Op: at standstill in open loop
/// (the current set-point is the running current), then at +1000 inc/s in closed loop.
fn pv_run(storage: &'static Storage, tag: &str, control_mode: u8) -> PvRun {
    let (net, child, _log) = start(tag, &["--dip-id", "01111111", "--dip-function", "10111111"]);
    let md = master(storage, &net.host_if);
    let result: Result<PvRun, Failed> = async_io::block_on(async {
        let group = md
            .init_single_group::<4, 128>(ethercat_now)
            .await
            .map_err(|e| ("init", e))?;
        let mut dip = [0u32; 7];
        let alias;
        {
            let sd = group.subdevice(&md, 0).map_err(|e| ("drive 0", e))?;
            alias = sd.alias_address();
            sd.sdo_write(0x2025, 0, control_mode)
                .await
                .map_err(|e| ("0x2025", e))?;
            sd.sdo_write(0x2024, 0, 1u8)
                .await
                .map_err(|e| ("0x2024", e))?;
            pv_mode!(sd, 0i32);
            // The runtime reconfigures every 10 ms.
            async_io::Timer::after(Duration::from_millis(50)).await;
            for (k, v) in dip.iter_mut().enumerate() {
                *v = match k {
                    0 | 1 | 4 | 5 => u32::from(
                        sd.sdo_read::<u8>(0x2158, k as u8 + 1)
                            .await
                            .map_err(|e| ("0x2158", e))?,
                    ),
                    2 | 3 => u32::from(
                        sd.sdo_read::<u16>(0x2158, k as u8 + 1)
                            .await
                            .map_err(|e| ("0x2158", e))?,
                    ),
                    _ => sd
                        .sdo_read::<u32>(0x2158, 7)
                        .await
                        .map_err(|e| ("0x2158", e))?,
                };
            }
        }
        let group = group.into_op(&md).await.map_err(|e| ("into_op", e))?;
        // Open loop at standstill: the set-point amplitude is the running current.
        let statusword = enable(&md, &group, 200).await?;
        let sd = group.subdevice(&md, 0).map_err(|e| ("drive 0", e))?;
        let ia: i16 = sd.sdo_read(0x2301, 0).await.map_err(|e| ("0x2301", e))?;
        let ib: i16 = sd.sdo_read(0x2302, 0).await.map_err(|e| ("0x2302", e))?;
        // Closed loop at +1000 inc/s: the field turns with the shaft.
        for _ in 0..20 {
            cycle(&md, &group, 0x0006).await?;
            async_io::Timer::after(Duration::from_millis(1)).await;
        }
        sd.sdo_write(0x2024, 0, 2u8)
            .await
            .map_err(|e| ("0x2024", e))?;
        sd.sdo_write(0x60FF, 0, 1000i32)
            .await
            .map_err(|e| ("0x60FF", e))?;
        enable(&md, &group, 300).await?;
        let a0: u16 = sd.sdo_read(0x2300, 0).await.map_err(|e| ("0x2300", e))?;
        let p0: i32 = sd.sdo_read(0x6064, 0).await.map_err(|e| ("0x6064", e))?;
        for _ in 0..100 {
            cycle(&md, &group, 0x000F).await?;
            async_io::Timer::after(Duration::from_millis(1)).await;
        }
        let a1: u16 = sd.sdo_read(0x2300, 0).await.map_err(|e| ("0x2300", e))?;
        let p1: i32 = sd.sdo_read(0x6064, 0).await.map_err(|e| ("0x6064", e))?;
        Ok(PvRun {
            dip,
            alias,
            amplitude_ma: f64::from(ia).hypot(f64::from(ib)),
            angle_step: i32::from(a1.wrapping_sub(a0) as i16),
            moved: p1 - p0,
            statusword,
        })
    });
    drop(child);
    result.expect("ethercrab over the veth pair")
}

#[test]
fn dip_function_switches_set_current_and_direction_with_0x2025_zero() {
    let _one = tests_host::netns::one_at_a_time();
    let on = pv_run(&PDU_DIP_ON, "d", 0);
    let off = pv_run(&PDU_DIP_OFF, "e", 5);
    eprintln!("0x2025 = 0: {on:?}\n0x2025 = 5: {off:?}");
    for r in [&on, &off] {
        assert_eq!(r.statusword & 0x6F, 0x27, "Operation enabled: {r:?}");
        assert_eq!(r.alias, 1, "station alias from the ID bank (S1 OFF)");
        assert_eq!(r.dip[0], 0xFE, "0x2158:1 ID bank");
        assert_eq!(r.dip[1], 0xFD, "0x2158:2 function bank");
        assert_eq!(r.dip[2], 1, "0x2158:3 station address");
    }
    // The switches rule: 4.5 A, full standstill current, reversed.
    assert_eq!(&on.dip[3..], &[4500, 100, 1, 0]);
    assert!(
        (on.amplitude_ma - 4500.0).abs() < 150.0,
        "current set-point {} mA with the switches' 4.5 A",
        on.amplitude_ma
    );
    // 0x2025 ≠ 0: the objects (0x2000 = 3.2 A, not reversed).
    assert_eq!(off.dip[3], 3200);
    assert_eq!(off.dip[5], 0);
    assert!(
        (off.amplitude_ma - 3200.0).abs() < 150.0,
        "current set-point {} mA with 0x2000 = 3.2 A",
        off.amplitude_ma
    );
    // +1000 inc/s = 1 electrical turn per second: ≈ 6500 / 65536 turn in 100 ms; the
    // reversal turns the field (the motor) the other way for the same set-point, and
    // the master sees the same positive motion.
    assert!(
        off.angle_step.abs() > 1000 && on.angle_step.abs() > 1000,
        "{on:?} {off:?}"
    );
    assert!(on.moved > 50 && off.moved > 50, "{on:?} {off:?}");
    assert!(
        on.angle_step.signum() == -off.angle_step.signum(),
        "direction reversed by SW5: {} vs {}",
        on.angle_step,
        off.angle_step
    );
}

#[test]
fn outputs_follow_0x60fe_the_alarm_and_the_brake() {
    let _one = tests_host::netns::one_at_a_time();
    let (net, child, log) = start("o", &["--fault", "bus-overvoltage@3s"]);
    let md = master(&PDU_OUTPUTS, &net.host_if);
    type Found = (u16, u16, u16, u16, u16);
    let result: Result<Found, Failed> = async_io::block_on(async {
        let group = md
            .init_single_group::<4, 128>(ethercat_now)
            .await
            .map_err(|e| ("init", e))?;
        let (idle, out3);
        {
            let sd = group.subdevice(&md, 0).map_err(|e| ("drive 0", e))?;
            idle = sd
                .sdo_read::<u16>(0x2157, 0)
                .await
                .map_err(|e| ("0x2157", e))?;
            sd.sdo_write(0x60FE, 2, 1u32 << 18)
                .await
                .map_err(|e| ("0x60FE:2", e))?;
            sd.sdo_write(0x60FE, 1, 1u32 << 18)
                .await
                .map_err(|e| ("0x60FE:1", e))?;
            async_io::Timer::after(Duration::from_millis(20)).await;
            out3 = sd
                .sdo_read::<u16>(0x2157, 0)
                .await
                .map_err(|e| ("0x2157", e))?;
            pv_mode!(sd, 0i32);
        }
        let group = group.into_op(&md).await.map_err(|e| ("into_op", e))?;
        let sw = enable(&md, &group, 50).await?;
        assert_eq!(sw & 0x6F, 0x27, "Operation enabled: {sw:#06x}");
        let sd = group.subdevice(&md, 0).map_err(|e| ("drive 0", e))?;
        let enabled = sd
            .sdo_read::<u16>(0x2157, 0)
            .await
            .map_err(|e| ("0x2157", e))?;
        // Keep the exchange going past the injected over-voltage (3 s after start).
        let mut sw = 0;
        for _ in 0..4000 {
            sw = cycle(&md, &group, 0x000F).await?;
            if sw & 0x4F == 0x08 {
                break;
            }
            async_io::Timer::after(Duration::from_millis(1)).await;
        }
        for _ in 0..20 {
            cycle(&md, &group, 0x000F).await?;
            async_io::Timer::after(Duration::from_millis(1)).await;
        }
        let faulted = sd
            .sdo_read::<u16>(0x2157, 0)
            .await
            .map_err(|e| ("0x2157", e))?;
        Ok((idle, out3, enabled, sw, faulted))
    });
    drop(child);
    let (idle, out3, enabled, sw, faulted) = result.expect("ethercrab over the veth pair");
    eprintln!("0x2157: idle {idle:#06x}, OUT3 set {out3:#06x}, enabled {enabled:#06x}, fault {faulted:#06x} (statusword {sw:#06x})");
    // Defaults: OUT1/OUT2 alarm, active-low → high while no fault; OUT3 the master's,
    // active-high; brake engaged; green LED on.
    assert_eq!(idle & 0x107, 0x003, "idle {idle:#06x}");
    assert_eq!(idle >> 9 & 1, 1, "green LED");
    assert_eq!(out3 & 0x107, 0x007, "OUT3 set by 0x60FE: {out3:#06x}");
    assert_eq!(
        enabled & 0x100,
        0x100,
        "brake released while enabled: {enabled:#06x}"
    );
    assert_eq!(
        sw & 0x4F,
        0x08,
        "the injected over-voltage faulted the drive: {sw:#06x}"
    );
    assert_eq!(
        faulted & 0x103,
        0x000,
        "alarm outputs active (low), brake engaged: {faulted:#06x}"
    );
    let lines: Vec<String> = log.try_iter().collect();
    let has = |s: &str| lines.iter().any(|l| l.contains(s));
    assert!(
        has("pins OUT1 high OUT2 high OUT3 high, brake engaged"),
        "{lines:#?}"
    );
    assert!(has("OUT3 high, brake released"), "{lines:#?}");
    assert!(
        has("pins OUT1 low OUT2 low OUT3 high, brake engaged"),
        "{lines:#?}"
    );
}

#[test]
fn pre_op_motion_tune_refused_and_init_stops_the_axis() {
    let _one = tests_host::netns::one_at_a_time();
    let (net, child, log) = start("i", &[]);
    let md = master(&PDU_PREOP, &net.host_if);
    type Found = (String, u16, i32, i32, i32, u16);
    let result: Result<Found, Failed> = async_io::block_on(async {
        let group = md
            .init_single_group::<4, 128>(ethercat_now)
            .await
            .map_err(|e| ("init", e))?;
        let sd = group.subdevice(&md, 0).map_err(|e| ("drive 0", e))?;
        pv_mode!(sd, 0i32);
        // Enable by SDO in Pre-Op (motion outside Op).
        let mut sw = 0u16;
        for _ in 0..300 {
            let cw: u16 = match sw & 0x6F {
                0x21 => 0x0007,
                0x23 | 0x27 => 0x000F,
                _ if sw & 0x4F == 0x40 => 0x0006,
                _ => 0x0000,
            };
            sd.sdo_write(0x6040, 0, cw)
                .await
                .map_err(|e| ("0x6040", e))?;
            async_io::Timer::after(Duration::from_millis(10)).await;
            sw = sd.sdo_read(0x6041, 0).await.map_err(|e| ("0x6041", e))?;
            if sw & 0x6F == 0x27 {
                break;
            }
        }
        // The current auto-tune is refused while enabled; the axis holds.
        let refused = match sd.sdo_write(0x2013, 0, 1u8).await {
            Ok(()) => "accepted".to_string(),
            Err(e) => format!("{e:?}"),
        };
        let p0: i32 = sd.sdo_read(0x6064, 0).await.map_err(|e| ("0x6064", e))?;
        async_io::Timer::after(Duration::from_millis(100)).await;
        let p1: i32 = sd.sdo_read(0x6064, 0).await.map_err(|e| ("0x6064", e))?;
        // Moving; then the master takes the ESM to Init.
        sd.sdo_write(0x60FF, 0, 20_000i32)
            .await
            .map_err(|e| ("0x60FF", e))?;
        async_io::Timer::after(Duration::from_millis(200)).await;
        let moving: i32 = sd.sdo_read(0x6064, 0).await.map_err(|e| ("0x6064", e))?;
        // The master takes the ESM to Init (AL control) and leaves the drive there.
        sd.register_write(0x0120u16, 0x0001u16)
            .await
            .map_err(|e| ("AL control", e))?;
        let mut st = 0u16;
        for _ in 0..100 {
            st = sd
                .register_read(0x0130u16)
                .await
                .map_err(|e| ("AL status", e))?;
            if st & 0x0F == 0x01 {
                break;
            }
            async_io::Timer::after(Duration::from_millis(10)).await;
        }
        async_io::Timer::after(Duration::from_millis(500)).await;
        Ok((refused, sw, p0, p1, moving, st))
    });
    drop(child);
    let (refused, sw, p0, p1, moving, st) = result.expect("ethercrab over the veth pair");
    let lines: Vec<String> = log.try_iter().collect();
    eprintln!(
        "Pre-Op enable {sw:#06x}; 0x2013 write: {refused}; hold {p0} → {p1}, moving to \
         {moving}; AL status {st:#06x} after the Init request"
    );
    assert_eq!(sw & 0x6F, 0x27, "enabled by SDO in Pre-Op");
    assert!(
        refused.contains("InvalidState"),
        "0x2013 while enabled: {refused}"
    );
    assert!(
        p0.abs_diff(p1) <= 13,
        "holds while the tune is refused: {p0} → {p1}"
    );
    assert!(
        moving.abs_diff(p1) > 500,
        "moving in PV before Init: {p1} → {moving}"
    );
    assert_eq!(st & 0x0F, 0x01, "Init");
    // The drive stopped on its own clock (0x6007 = 1: the fault reaction's ramp, then
    // no power): the brake, released while enabled, is engaged again.
    let released = lines.iter().position(|l| l.contains("brake released"));
    let engaged =
        released.and_then(|r| lines[r..].iter().position(|l| l.contains("brake engaged")));
    assert!(
        engaged.is_some(),
        "brake released, then engaged: {lines:#?}"
    );
}
