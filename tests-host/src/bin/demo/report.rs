//! The demo's report tables: the segment, the dictionary, the PDO configuration and the
//! emergencies, as a commissioning engineer reads them.

use super::*;
pub(super) fn table(title: &str, headers: &[&str], rows: &[Vec<String>]) {
    let mut w: Vec<usize> = headers.iter().map(|h| h.chars().count()).collect();
    for r in rows {
        for (i, c) in r.iter().enumerate() {
            w[i] = w[i].max(c.chars().count());
        }
    }
    println!("\n{title}");
    let line = |cells: Vec<String>| {
        let s: Vec<String> = cells
            .iter()
            .enumerate()
            .map(|(i, c)| format!("{c:<width$}", width = w[i]))
            .collect();
        println!("  | {} |", s.join(" | "));
    };
    line(headers.iter().map(|s| s.to_string()).collect());
    println!(
        "  |{}|",
        w.iter()
            .map(|n| "-".repeat(n + 2))
            .collect::<Vec<_>>()
            .join("|")
    );
    for r in rows {
        line(r.clone());
    }
}

/// Table 1: the drives found on the segment, identity and names from the SII.
pub(super) async fn scan_report(
    md: &MainDevice<'static>,
    group: &PreOpGroup,
) -> Result<(), ethercrab::error::Error> {
    let mut rows = Vec::new();
    for sd in group.iter(md) {
        let id = sd.identity();
        rows.push(vec![
            format!("{:#06x}", sd.configured_address()),
            sd.name().to_string(),
            sd.description()
                .await?
                .map(|s| s.to_string())
                .unwrap_or_default(),
            format!("{:#010x}", id.vendor_id),
            format!("{:#010x}", id.product_id),
            format!("{:#010x}", id.revision),
            format!("{}", id.serial),
        ]);
    }
    table(
        "1. Scan: drives found on the segment (identity and names from the SII EEPROM)",
        &[
            "address", "order", "name", "vendor", "product", "revision", "serial",
        ],
        &rows,
    );
    Ok(())
}

/// Table 2: SDO reads of key objects, and the abort for a missing one.
pub(super) async fn sdo_report(
    md: &MainDevice<'static>,
    group: &PreOpGroup,
) -> Result<(), ethercrab::error::Error> {
    let sd = group.subdevice(md, 0)?;
    let mut rows = Vec::new();
    let u32s: [(u16, u8, &str); 6] = [
        (0x1000, 0, "device type (CiA 402 servo)"),
        (0x1018, 2, "product code"),
        (
            0x6502,
            0,
            "supported drive modes (bit 0 PP, 2 PV, 5 HM, 7 CSP, 8 CSV)",
        ),
        (0x2001, 0, "pulses per revolution (command units)"),
        (0x2029, 0, "encoder lines"),
        (0x2030, 0, "following error limit (counts)"),
    ];
    for (i, s, what) in u32s {
        let v: u32 = if i == 0x2001 || i == 0x2029 || i == 0x2030 {
            sd.sdo_read::<u16>(i, s)
                .await
                .map(u32::from)
                .or(sd.sdo_read::<u32>(i, s).await)?
        } else {
            sd.sdo_read::<u32>(i, s).await?
        };
        rows.push(vec![
            format!("{i:#06x}:{s:02}"),
            what.into(),
            format!("{v} ({v:#x})"),
        ]);
    }
    let peak: u16 = sd.sdo_read(0x2000, 0).await?;
    rows.push(vec![
        "0x2000:00".into(),
        "peak current (mA)".into(),
        peak.to_string(),
    ]);
    let mode_loop: u8 = sd.sdo_read(0x2024, 0).await?;
    rows.push(vec![
        "0x2024:00".into(),
        "open/closed loop (2 = closed)".into(),
        mode_loop.to_string(),
    ]);
    // A missing object is answered with an abort, the drive keeps running.
    let missing = sd.sdo_read::<u32>(0x5FFF, 0).await;
    rows.push(vec![
        "0x5FFF:00".into(),
        "object that does not exist".into(),
        match missing {
            Err(e) => format!("refused: {e:?}"),
            Ok(v) => format!("unexpected value {v}"),
        },
    ]);
    table(
        "2. SDO reads through the CoE mailbox",
        &["object", "meaning", "value"],
        &rows,
    );
    Ok(())
}

/// Table 3: the default PDO mapping, read back by SDO.
pub(super) async fn pdo_report(
    md: &MainDevice<'static>,
    group: &PreOpGroup,
) -> Result<(), ethercrab::error::Error> {
    let sd = group.subdevice(md, 0)?;
    let mut rows = Vec::new();
    for (assign, dir) in [(0x1C12u16, "RxPDO (outputs)"), (0x1C13, "TxPDO (inputs)")] {
        let n: u8 = sd.sdo_read(assign, 0).await?;
        for k in 1..=n {
            let map: u16 = sd.sdo_read(assign, k).await?;
            let entries: u8 = sd.sdo_read(map, 0).await?;
            let mut list = Vec::new();
            let mut bits = 0u32;
            for e in 1..=entries {
                let raw: u32 = sd.sdo_read(map, e).await?;
                bits += raw & 0xFF;
                list.push(format!(
                    "{:04X}:{:02X}/{}",
                    raw >> 16,
                    (raw >> 8) & 0xFF,
                    raw & 0xFF
                ));
            }
            rows.push(vec![
                dir.into(),
                format!("{map:#06x}"),
                list.join(" "),
                format!("{}", bits.div_ceil(8)),
            ]);
        }
    }
    table(
        "3. Process data mapping (default maps, read back by SDO)",
        &["direction", "map", "entries (index:sub/bits)", "bytes"],
        &rows,
    );
    Ok(())
}

/// Table 10: the emergencies the master read from the mailbox (times from `t0`).
pub(super) fn emergency_report(w: &SimWire, t0: u64) {
    let rows: Vec<Vec<String>> = w
        .emergencies
        .iter()
        .map(|(t, code, reg, m)| {
            vec![
                format!("{:.0} ms", (*t - t0) as f64 * 1e-6),
                format!("{code:#06x}"),
                format!("{reg:#04x}"),
                m.iter()
                    .map(|b| format!("{b:02x}"))
                    .collect::<Vec<_>>()
                    .join(" "),
            ]
        })
        .collect();
    table(
        "10. Emergency messages the master read from the mailbox",
        &[
            "read by the master at",
            "error code",
            "error register",
            "manufacturer bytes",
        ],
        &rows,
    );
}
