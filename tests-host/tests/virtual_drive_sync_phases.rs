//! `virtual-drive`'s timing in simulated time (no socket, no wall clock): the frames
//! go through the ESCs at once, as its frame thread does
//! (`esc_sim::frame::process_frame_in_turn`), while its drives' thread
//! (`realtime::step`) wakes only every 0.7 ms, late for most SYNC0 pulses. The
//! master gives every drive its own time base (`vd_master::TimeBase::PerDrive`), so
//! the 16 drives' SYNC0 pulses have phases of their own. Each drive's cycle still
//! runs at its own pulse's time: every drive reaches Op and keeps it (no 0x002C,
//! no PLL error) for 500 cycles with the right working counter.

use tests_host::esc_sim::frame::process_frame_in_turn;
use tests_host::esc_sim::{Flavour, SharedEsc};
use tests_host::raw_master::{Master, Transport};
use tests_host::realtime;
use tests_host::segment::Segment;
use tests_host::sim_drive::{self, Motor, SimDrive, SimDriveConfig};
use tests_host::vd_master::{self, TimeBase};

const DRIVES: u16 = 16;
/// Simulated time a frame takes there and back.
const FRAME_NS: u64 = 100_000;
/// The drives' thread runs at most this often (a loaded machine).
const APP_EVERY_NS: u64 = 700_000;

/// The wire and the drives' thread of `virtual-drive`, in simulated time.
struct LateDrives {
    seg: Segment<SimDrive>,
    escs: Vec<SharedEsc>,
    now_ns: u64,
    app_next_ns: u64,
}

impl LateDrives {
    fn app(&mut self) {
        if self.now_ns >= self.app_next_ns {
            realtime::step(&mut self.seg, self.now_ns);
            self.app_next_ns = self.now_ns + APP_EVERY_NS;
        }
    }
}

impl Transport for LateDrives {
    fn exchange(&mut self, frame: &[u8]) -> Option<Vec<u8>> {
        let mut f = frame.to_vec();
        let hop = self.seg.config().hop_ns;
        process_frame_in_turn(&self.escs, &mut f, self.now_ns, hop);
        self.now_ns += FRAME_NS;
        self.app();
        Some(f)
    }
    fn now_ns(&self) -> u64 {
        self.now_ns
    }
    fn advance(&mut self, dt_ns: u64) {
        // The drives' thread wakes in between as well, as late as ever.
        let end = self.now_ns + dt_ns;
        while self.now_ns < end {
            self.now_ns = (self.now_ns + APP_EVERY_NS).min(end);
            self.app();
        }
    }
}

#[test]
fn drives_with_sync0_phases_of_their_own_keep_op_with_a_late_drives_thread() {
    let cfg = SimDriveConfig {
        motor: Motor::Ecn57_20,
        flavour: Flavour::Lan9252,
        flash_file: None,
        dips: sim_drive::DIPS_ALL_ON,
    };
    let mut seg = sim_drive::segment(&cfg, usize::from(DRIVES)).expect("segment");
    for d in seg.drives_mut() {
        d.app.axis.skip_rest(true);
    }
    let booted = realtime::power_up(&mut seg);
    let escs = seg.escs();
    let mut m = Master::over(LateDrives {
        seg,
        escs,
        now_ns: booted,
        app_next_ns: booted,
    });
    vd_master::to_pre_op(&mut m, DRIVES).expect("Pre-Op");
    vd_master::to_safe_op(&mut m, DRIVES, TimeBase::PerDrive).expect("Safe-Op");
    // The drives' pulses: phases of their own within the 1 ms cycle.
    let phases: Vec<u64> = (0..usize::from(DRIVES))
        .map(|i| {
            let next = m.link.seg.esc(i).next_sync0_ns().expect("SYNC0 on");
            next % 1_000_000
        })
        .collect();
    let spread = phases.iter().max().unwrap() - phases.iter().min().unwrap();
    assert!(spread > 300_000, "SYNC0 phases {phases:?}");
    vd_master::start_cyclic_between_pulses(&mut m, DRIVES);
    for st in vd_master::stations(DRIVES) {
        m.request_state(st, 0x0008);
    }
    for st in vd_master::stations(DRIVES) {
        let s = m.wait_state(st, 0x08, 5_000_000_000, 1_000_000, |_| {});
        assert_eq!(s, (0x08, 0), "Op of {st:#06x}");
    }
    let sent0 = m.cyclic.expect("cyclic").sent;
    while m.cyclic.expect("cyclic").sent < sent0 + 500 {
        m.wait(1_000_000, 1_000_000);
    }
    let c = m.cyclic.expect("cyclic");
    assert_eq!(c.good, c.sent, "LRWs with working counter {}", 3 * DRIVES);
    for st in vd_master::stations(DRIVES) {
        assert_eq!(m.al_status(st), (0x08, 0), "{st:#06x} after 500 cycles");
    }
}
