//! Scale, the cheap version (issue 9 item 4): 64 simulated drives (firmware `Drive` +
//! slave runtime + ESC simulator, kinematic axes) reach Op under ethercrab 0.7 and
//! exchange process data at a 1 ms cycle in simulated time with the right working
//! counter. No timing: the measurement is the `scale` binary
//! (`cargo run -p tests-host --release --bin scale`).

use std::cell::RefCell;
use std::rc::Rc;

use ethercrab::{MainDevice, PduStorage, SubDeviceState};
use tests_host::esc_sim::frame::{datagrams, FrameOutcome, Wire};
use tests_host::esc_sim::Flavour;
use tests_host::ethercrab_seam::{sim_config, sim_now_ns, sim_timeouts, MasterHarness};
use tests_host::segment::Segment;
use tests_host::sim_drive::{self, AxisModel, Motor, SimDrive, SimDriveConfig};

const N: usize = 64;

static PDU_STORAGE: PduStorage<16, { PduStorage::element_size(1500) }> = PduStorage::new();

/// The segment as ethercrab's wire, noting the LRW datagrams (address, length).
struct LrwWire {
    seg: Segment<SimDrive>,
    lrw: Vec<(u32, usize)>,
}

impl Wire for LrwWire {
    fn transfer(&mut self, frame: &mut [u8]) -> FrameOutcome {
        let o = sim_drive::process(&mut self.seg, frame);
        for d in datagrams(frame).unwrap_or_default() {
            if d.cmd == 0x0C {
                self.lrw.push((d.addr, d.data.len()));
            }
        }
        o
    }
    fn now_ns(&self) -> u64 {
        self.seg.now_ns()
    }
}

#[derive(Debug, Default)]
struct Report {
    subdevices: usize,
    lrw_chunks: usize,
    expected_wkc: u16,
    wkc: Vec<u16>,
    all_op: bool,
    enabled: usize,
}

async fn run(
    md: Rc<MainDevice<'static>>,
    wire: Rc<RefCell<LrwWire>>,
) -> Result<Report, ethercrab::error::Error> {
    let group = md.init_single_group::<N, 2048>(sim_now_ns).await?;
    let mut r = Report {
        subdevices: group.len(),
        all_op: true,
        ..Report::default()
    };
    for sd in group.iter(&md) {
        sd.sdo_write(0x6060, 0, 8i8).await?;
    }
    let group = group.into_op(&md).await?;
    // Where each drive's inputs and outputs sit in ethercrab's process image.
    let mut segs = Vec::new();
    for sd in group.iter(&md) {
        let i = sd.inputs_raw();
        let ip = (i.as_ptr() as usize, i.len());
        drop(i);
        let o = sd.outputs_raw_mut();
        segs.push((ip, (o.as_ptr() as usize, o.len())));
    }
    let base = segs.iter().flat_map(|(i, o)| [i.0, o.0]).min().unwrap_or(0);
    for k in 0..30u32 {
        let cw: u16 = match k {
            0..=2 => 0x0006,
            3..=5 => 0x0007,
            _ => 0x000F,
        };
        for sd in group.iter(&md) {
            let pos = {
                let i = sd.inputs_raw();
                (i.len() >= 9).then(|| i32::from_le_bytes([i[5], i[6], i[7], i[8]]))
            };
            let mut o = sd.outputs_raw_mut();
            if o.len() >= 6 {
                o[0..2].copy_from_slice(&cw.to_le_bytes());
                o[2..6].copy_from_slice(&pos.unwrap_or(0).to_le_bytes());
            }
        }
        wire.borrow_mut().lrw.clear();
        let res = group.tx_rx(&md).await?;
        r.wkc.push(res.working_counter);
        r.all_op &= res
            .subdevice_states
            .iter()
            .all(|s| *s == SubDeviceState::Op);
        let left = 1_000_000 - sim_now_ns() % 1_000_000;
        sim_drive::advance(&mut wire.borrow_mut().seg, left);
    }
    // Expected working counter: per LRW datagram, 2 for every drive whose outputs it
    // touches and 1 for every drive whose inputs it touches (a drive whose image is
    // split over two datagrams counts in both).
    let chunks = wire.borrow().lrw.clone();
    let start = chunks.first().map_or(0, |c| c.0);
    let overlaps = |(p, len): (usize, usize), (a, l): (u32, usize)| {
        let s0 = (p - base) as u64 + u64::from(start);
        let c0 = u64::from(a);
        len > 0 && s0 < c0 + l as u64 && c0 < s0 + len as u64
    };
    r.lrw_chunks = chunks.len();
    r.expected_wkc = chunks
        .iter()
        .map(|&c| {
            segs.iter()
                .map(|&(i, o)| 2 * overlaps(o, c) as u16 + overlaps(i, c) as u16)
                .sum::<u16>()
        })
        .sum();
    r.enabled = group
        .iter(&md)
        .filter(|sd| {
            let i = sd.inputs_raw();
            i.len() >= 4 && u16::from_le_bytes([i[2], i[3]]) & 0x6F == 0x27
        })
        .count();
    let group = group.into_safe_op(&md).await?;
    let _ = group.into_pre_op(&md).await?.into_init(&md).await?;
    Ok(r)
}

#[test]
fn sixty_four_drives_reach_op_with_the_right_working_counter() {
    let cfg = SimDriveConfig {
        motor: Motor::Ecn57_20,
        flavour: Flavour::Lan9252,
        flash_file: None,
        dips: tests_host::sim_drive::DIPS_ALL_ON,
    };
    let seg = sim_drive::segment_with(&cfg, N, AxisModel::Kinematic).expect("segment");
    let wire = Rc::new(RefCell::new(LrwWire {
        seg,
        lrw: Vec::new(),
    }));
    let mut h = MasterHarness::new(&PDU_STORAGE).expect("storage split once");
    let w2 = wire.clone();
    let (res, stats) = h.run(wire.clone(), sim_timeouts(), sim_config(), |md| run(md, w2));
    let r = res.unwrap_or_else(|e| panic!("ethercrab error {e:?}; {stats:?}"));
    assert_eq!(r.subdevices, N);
    assert!(r.all_op, "every drive stayed in Op");
    // 64 × (12 + 19) bytes do not fit one frame: ethercrab sends two LRW datagrams.
    assert_eq!(r.lrw_chunks, 2);
    // 3 per drive (outputs written + inputs read) plus the split drive counted twice.
    assert!(r.expected_wkc >= 3 * N as u16 && r.expected_wkc <= 3 * N as u16 + 3);
    assert!(
        r.wkc.iter().all(|w| *w == r.expected_wkc),
        "expected {} every cycle: {:?}",
        r.expected_wkc,
        r.wkc
    );
    assert_eq!(r.enabled, N, "every drive enabled in CSP");
    let s = wire.borrow();
    for i in 0..N {
        assert_eq!(s.seg.al_status(i), (0x01, 0), "drive {i} back in Init");
    }
}
