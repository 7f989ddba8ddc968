//! Start-up lists of the drives this one replaces, replayed by a real master: ethercrab
//! on one end of a veth pair, `virtual-drive` (1 drive, the hybrid servo) in a network
//! namespace on the other. In Pre-Op the master writes the list — parameters, scaling,
//! mode, and a PDO map of its own through 0x1C12 / 0x1C13 / 0x1600-0x1A01 — then takes
//! the drive to Op, enables it through the mapped controlword and checks the image:
//!
//! * DP3CL style (open-loop bus stepper's CSP list): 0x6091 / 0x6092 gear and feed,
//!   0x60C0 linear interpolation, 0x6065 / 0x6066 following error, 0x605A, a position
//!   range 0x607B of 0-9999; RxPDO 0x1600 = 6040, 6060, 607A, 60B8, 6066, 6068, 605A;
//!   TxPDO 0x1A00 = 603F, 6041, 6061, 6064, 606C, 60F4, 6077, 60FD, 60FA. CSP, the
//!   target following the actual position (in the range).
//! * E5 style (hybrid servo's PP list): 0x2000 peak current, 0x2001 pulses per
//!   revolution, 0x6093 position factor, profile values; 0x1C12 = {0x1601, 0x1603}
//!   (PP map, and 0x1603 = 2000: the peak current by PDO);
//!   0x1C13 = {0x1A00, 0x1A01} with 0x1A01 = 606C, 6077. PP by the mapped 0x6060.
//!
//! Every row: each write answered without abort, Op with the working counter 3,
//! Operation enabled in the mode the list chose (0x6061 in the inputs), the values a
//! PDO wrote readable over SDO, and 0x2001 what the scaling objects set.
//!
//! Needs root (network namespaces, raw sockets) and iproute2, like
//! `virtual_drive_veth.rs`: without root the tests fail and say so.

use ecat_slave_stack::od::ObjectKey;
use std::time::Duration;

use ethercrab::std::ethercat_now;
use ethercrab::{MainDevice, PduStorage};
use tests_host::netns::{self, Killed, Netns};

type Storage = PduStorage<16, { PduStorage::element_size(1100) }>;
static PDU_DP3CL: Storage = PduStorage::new();
static PDU_E5: Storage = PduStorage::new();

/// One SDO write of a start-up list.
#[derive(Debug, Clone, Copy)]
enum V {
    U8(u8),
    I8(i8),
    U16(u16),
    I16(i16),
    U32(u32),
    I32(i32),
}

/// `(index, sub, value)`.
type Step = (u16, u8, V);

const fn map(index: u16, sub: u8, bits: u8) -> V {
    V::U32(ObjectKey::new(index, sub).mapping_word(bits))
}

/// The DP3CL-style list: scaling, interpolation, supervision, then the maps.
const DP3CL: &[Step] = &[
    (0x6091, 1, V::U32(1)),
    (0x6091, 2, V::U32(1)),
    (0x6092, 1, V::U32(10_000)),
    (0x6092, 2, V::U32(1)),
    (0x60C0, 0, V::I16(0)),
    (0x6065, 0, V::U32(20_000)),
    (0x6066, 0, V::U16(200)),
    (0x605A, 0, V::I16(2)),
    (0x607B, 1, V::I32(0)),
    (0x607B, 2, V::I32(9_999)),
    (0x6060, 0, V::I8(8)),
    (0x1C12, 0, V::U8(0)),
    (0x1600, 0, V::U8(0)),
    (0x1600, 1, map(0x6040, 0, 16)),
    (0x1600, 2, map(0x6060, 0, 8)),
    (0x1600, 3, map(0x607A, 0, 32)),
    (0x1600, 4, map(0x60B8, 0, 16)),
    (0x1600, 5, map(0x6066, 0, 16)),
    (0x1600, 6, map(0x6068, 0, 16)),
    (0x1600, 7, map(0x605A, 0, 16)),
    (0x1600, 0, V::U8(7)),
    (0x1C12, 1, V::U16(0x1600)),
    (0x1C12, 0, V::U8(1)),
    (0x1C13, 0, V::U8(0)),
    (0x1A00, 0, V::U8(0)),
    (0x1A00, 1, map(0x603F, 0, 16)),
    (0x1A00, 2, map(0x6041, 0, 16)),
    (0x1A00, 3, map(0x6061, 0, 8)),
    (0x1A00, 4, map(0x6064, 0, 32)),
    (0x1A00, 5, map(0x606C, 0, 32)),
    (0x1A00, 6, map(0x60F4, 0, 32)),
    (0x1A00, 7, map(0x6077, 0, 16)),
    (0x1A00, 8, map(0x60FD, 0, 32)),
    (0x1A00, 9, map(0x60FA, 0, 32)),
    (0x1A00, 0, V::U8(9)),
    (0x1C13, 1, V::U16(0x1A00)),
    (0x1C13, 0, V::U8(1)),
];

/// The E5-style list: current, resolution, position factor, profile, then the maps.
const E5: &[Step] = &[
    (0x2000, 0, V::U16(4000)),
    (0x2001, 0, V::U32(10_000)),
    (0x6093, 1, V::U32(4000)),
    (0x6093, 2, V::U32(20_000)),
    (0x6081, 0, V::U32(20_000)),
    (0x6083, 0, V::U32(200_000)),
    (0x6084, 0, V::U32(200_000)),
    (0x6068, 0, V::U16(10)),
    (0x1C12, 0, V::U8(0)),
    (0x1C12, 1, V::U16(0x1601)),
    (0x1603, 0, V::U8(0)),
    (0x1603, 1, map(0x2000, 0, 16)),
    (0x1603, 0, V::U8(1)),
    (0x1C12, 2, V::U16(0x1603)),
    (0x1C12, 0, V::U8(2)),
    (0x1C13, 0, V::U8(0)),
    (0x1A01, 0, V::U8(0)),
    (0x1A01, 1, map(0x606C, 0, 32)),
    (0x1A01, 2, map(0x6077, 0, 16)),
    (0x1A01, 0, V::U8(2)),
    (0x1C13, 1, V::U16(0x1A00)),
    (0x1C13, 2, V::U16(0x1A01)),
    (0x1C13, 0, V::U8(2)),
];

/// Where the rows find their values in the images (byte offsets).
struct Layout {
    out_bytes: usize,
    in_bytes: usize,
    /// Controlword, modes of operation (None: set by SDO), target position.
    controlword: usize,
    mode: Option<usize>,
    target: usize,
    /// Statusword, modes of operation display, position actual value.
    statusword: usize,
    mode_display: usize,
    actual: usize,
    /// PDO-written values to read back over SDO: (offset, index, value).
    written: &'static [(usize, u16, u16)],
}

/// 6040 @0, 6060 @2, 607A @3, 60B8 @7, 6066 @9, 6068 @11, 605A @13 → 15 bytes;
/// 603F @0, 6041 @2, 6061 @4, 6064 @5, 606C @9, 60F4 @13, 6077 @17, 60FD @19,
/// 60FA @23 → 27.
const DP3CL_LAYOUT: Layout = Layout {
    out_bytes: 15,
    in_bytes: 27,
    controlword: 0,
    mode: Some(2),
    target: 3,
    statusword: 2,
    mode_display: 4,
    actual: 5,
    written: &[(9, 0x6066, 150), (11, 0x6068, 7), (13, 0x605A, 6)],
};

/// 0x1601 (6040 @0, 607A @2, 6081 @6, 6083 @10, 6084 @14, 6060 @18) + 0x1603 (2000
/// @19) → 21 bytes; 0x1A00 (19 bytes: 603F @0, 6041 @2, 6061 @4, 6064 @5, ...) + 606C
/// @19, 6077 @23 → 25.
const E5_LAYOUT: Layout = Layout {
    out_bytes: 21,
    in_bytes: 25,
    controlword: 0,
    mode: Some(18),
    target: 2,
    statusword: 2,
    mode_display: 4,
    actual: 5,
    written: &[(19, 0x2000, 3500)],
};

fn start(tag: &str) -> (Netns, Killed) {
    assert!(
        netns::is_root(),
        "the veth tests need root (network namespaces and raw sockets): run them as root, \
         e.g. `sudo -E env PATH=$PATH cargo test -p tests-host --test seed_startup_veth` \
         (CI runs as root)"
    );
    let net = Netns::create(tag).expect(
        "running as root, but the network namespace / veth pair could not be created \
         (iproute2 installed? kernel veth and netns support?)",
    );
    let (child, _lines) =
        netns::start_virtual_drive(&net, env!("CARGO_BIN_EXE_virtual-drive"), &[])
            .unwrap_or_else(|e| panic!("{e}"));
    (net, child)
}

/// The master of [`tests_host::netns::veth_master`].
fn master(storage: &'static Storage, host_if: &str) -> MainDevice<'static> {
    tests_host::netns::veth_master(storage, host_if)
}

/// What a row saw: Op cycles' working counters, the statusword and 0x6061 of the last
/// cycle, the PDO-written values read back, 0x2001.
struct Seen {
    wkcs: Vec<u16>,
    statusword: u16,
    mode_display: i8,
    read_back: Vec<(u16, u16, u16)>,
    ppr: u32,
}

/// Replays `list`, goes to Op, enables in `mode`, returns what it saw.
fn replay(tag: &str, storage: &'static Storage, list: &[Step], l: &Layout, mode: i8) -> Seen {
    let (net, child) = start(tag);
    let md = master(storage, &net.host_if);
    type R = Result<Seen, (String, ethercrab::error::Error)>;
    let result: R = async_io::block_on(async {
        let at = |what: &str| {
            let what = what.to_string();
            move |e| (what, e)
        };
        let group = md
            .init_single_group::<4, 128>(ethercat_now)
            .await
            .map_err(at("scan"))?;
        {
            let sd = group.subdevice(&md, 0).map_err(at("drive 0"))?;
            for &(index, sub, v) in list {
                let what = format!("{index:#06x}:{sub} = {v:?}");
                match v {
                    V::U8(x) => sd.sdo_write(index, sub, x).await,
                    V::I8(x) => sd.sdo_write(index, sub, x).await,
                    V::U16(x) => sd.sdo_write(index, sub, x).await,
                    V::I16(x) => sd.sdo_write(index, sub, x).await,
                    V::U32(x) => sd.sdo_write(index, sub, x).await,
                    V::I32(x) => sd.sdo_write(index, sub, x).await,
                }
                .map_err(at(&what))?;
            }
        }
        let group = group.into_op(&md).await.map_err(at("into_op"))?;
        {
            let sd = group.subdevice(&md, 0).map_err(at("drive 0"))?;
            assert_eq!(sd.outputs_raw().len(), l.out_bytes, "{tag}: output image");
            assert_eq!(sd.inputs_raw().len(), l.in_bytes, "{tag}: input image");
        }
        let mut wkcs = Vec::new();
        let (mut statusword, mut mode_display, mut actual) = (0u16, 0i8, 0i32);
        let mut enabled_cycles = 0;
        for k in 0..4000u32 {
            let cw: u16 = match statusword & 0x6F {
                0x21 => 0x0007,
                0x23 | 0x27 => 0x000F,
                _ if statusword & 0x4F == 0x40 => 0x0006,
                _ => 0x0000,
            };
            {
                let sd = group.subdevice(&md, 0).map_err(at("drive 0"))?;
                let mut o = sd.outputs_raw_mut();
                o[l.controlword..l.controlword + 2].copy_from_slice(&cw.to_le_bytes());
                if let Some(m) = l.mode {
                    o[m] = mode as u8;
                }
                // The target follows the actual position (CSP: no jump; PP: no move).
                o[l.target..l.target + 4].copy_from_slice(&actual.to_le_bytes());
                for &(off, _, v) in l.written {
                    o[off..off + 2].copy_from_slice(&v.to_le_bytes());
                }
            }
            let r = group.tx_rx(&md).await.map_err(at(&format!("tx_rx {k}")))?;
            wkcs.push(r.working_counter);
            let sd = group.subdevice(&md, 0).map_err(at("drive 0"))?;
            let i = sd.inputs_raw();
            let s = l.statusword;
            statusword = u16::from_le_bytes([i[s], i[s + 1]]);
            mode_display = i[l.mode_display] as i8;
            let a = l.actual;
            actual = i32::from_le_bytes([i[a], i[a + 1], i[a + 2], i[a + 3]]);
            if statusword & 0x6F == 0x27 && mode_display == mode {
                enabled_cycles += 1;
                if enabled_cycles >= 50 {
                    break;
                }
            }
            async_io::Timer::after(Duration::from_millis(1)).await;
        }
        let sd = group.subdevice(&md, 0).map_err(at("drive 0"))?;
        let mut read_back = Vec::new();
        for &(_, index, v) in l.written {
            let got: u16 = sd.sdo_read(index, 0).await.map_err(at("read back"))?;
            read_back.push((index, v, got));
        }
        let ppr: u32 = sd.sdo_read(0x2001, 0).await.map_err(at("0x2001"))?;
        // Disable, then back to Init.
        {
            let sd = group.subdevice(&md, 0).map_err(at("drive 0"))?;
            sd.outputs_raw_mut()[l.controlword..l.controlword + 2]
                .copy_from_slice(&0u16.to_le_bytes());
        }
        group.tx_rx(&md).await.map_err(at("disable"))?;
        let group = group.into_safe_op(&md).await.map_err(at("safe-op"))?;
        let group = group.into_pre_op(&md).await.map_err(at("pre-op"))?;
        let _ = group.into_init(&md).await.map_err(at("init"))?;
        Ok(Seen {
            wkcs,
            statusword,
            mode_display,
            read_back,
            ppr,
        })
    });
    drop(child);
    result.unwrap_or_else(|(what, e)| panic!("{tag}: {what}: {e:?}"))
}

fn check(tag: &str, s: &Seen, mode: i8, ppr: u32) {
    eprintln!(
        "{tag}: {} cycles in Op, statusword {:#06x}, 0x6061 {}, 0x2001 {}, read back {:?}",
        s.wkcs.len(),
        s.statusword,
        s.mode_display,
        s.ppr,
        s.read_back
    );
    assert!(
        s.wkcs.iter().all(|&w| w == 3),
        "{tag}: working counters {:?}",
        s.wkcs
    );
    assert_eq!(s.statusword & 0x6F, 0x27, "{tag}: Operation enabled");
    assert_eq!(s.mode_display, mode, "{tag}: 0x6061 in the inputs");
    for &(index, want, got) in &s.read_back {
        assert_eq!(got, want, "{tag}: {index:#06x} written by the RxPDO");
    }
    assert_eq!(s.ppr, ppr, "{tag}: 0x2001 from the scaling objects");
}

#[test]
fn dp3cl_style_startup_list_reaches_op_in_csp() {
    let _one = tests_host::netns::one_at_a_time();
    let s = replay("sd", &PDU_DP3CL, DP3CL, &DP3CL_LAYOUT, 8);
    // Feed 10 000 per shaft revolution at gear 1:1: 0x2001 = 10 000.
    check("DP3CL", &s, 8, 10_000);
}

#[test]
fn e5_style_startup_list_reaches_op_in_pp() {
    let _one = tests_host::netns::one_at_a_time();
    let s = replay("se", &PDU_E5, E5, &E5_LAYOUT, 1);
    // 4000 encoder increments per 20 000 units: 0x2001 = 20 000 (the factor's write
    // after the 0x2001 write of the list).
    check("E5", &s, 1, 20_000);
}
