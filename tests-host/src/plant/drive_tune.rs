//! The servo tune as the drive runs it: the drive (`firmware::drive`, its 1 ms tick as
//! on the board without frames) on the plant axis with the firmware's motion layer
//! ([`crate::sim_axis::PlantAxis`]), a motor carrying a load inertia, PP. 0x2162:01 =
//! 1 starts the identification move of `firmware::servo_tune`; the figures are what
//! the drive then reports (0x2164) and how the axis stands with the gains it set.

use crate::sim_axis::PlantAxis;
use crate::sim_drive::{Axis, Motor};
use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::od::{Dictionary, ObjectKey, SdoAbort};
use firmware::cia402::pds::PdsState;
use firmware::drive::Drive;
use firmware::identity::Variant;

/// Encoder counts per command unit (4000 counts and 50 000 units per revolution).
const COUNTS_PER_UNIT: f64 = 4000.0 / 50_000.0;

/// The drive on its plant axis, stepped by its own 1 ms tick.
pub struct DriveBench {
    /// The drive.
    pub d: Drive,
    /// The plant axis with the firmware's motion layer.
    pub ax: PlantAxis,
    t_us: u64,
    steps: u32,
}

impl DriveBench {
    /// `motor` carrying `load` × its rotor inertia, closed loop, PP, no power-up
    /// current-loop tune, and the objects `extra` written in Pre-Op.
    pub fn new(motor: Motor, load: f64, extra: &[(u16, u8, &[u8])]) -> Self {
        let mut d: Drive = Drive::new(Variant::HybridServo, 0);
        let base: [(u16, u8, &[u8]); 3] = [(0x2013, 0, &[0]), (0x2024, 0, &[2]), (0x6060, 0, &[1])];
        for &(i, s, v) in base.iter().chain(extra) {
            Dictionary::write(&mut d, ObjectKey::new(i, s), v, EsmState::PreOp)
                .unwrap_or_else(|e| panic!("{i:x}: {e:?}"));
        }
        let mut ax = PlantAxis::with_plant(motor, true, |pc| {
            pc.motor.j *= 1.0 + load;
        });
        ax.parameters(&d.params);
        DriveBench {
            d,
            ax,
            t_us: 0,
            steps: 0,
        }
    }

    /// `n` ticks of 1 ms with the controlword `cw` (the axis gets each step's
    /// set-points and, every 10 ms, the parameters, the drive the servo points of a
    /// scope at the servo rate, as on the board); `each` sees the bench after every
    /// tick.
    pub fn run(&mut self, cw: u16, n: u32, mut each: impl FnMut(&DriveBench)) {
        self.d.cia402.set_controlword(cw);
        for _ in 0..n {
            self.t_us += 1000;
            self.d.set_axis(self.ax.state());
            crate::sim_drive::hand_servo_points(&mut self.ax, &mut self.d);
            self.d.tick(self.t_us, 0);
            let c = *self.d.command();
            if self.d.steps() != self.steps {
                self.steps = self.d.steps();
                self.ax.command(&c, f64::from(self.d.segment_s()));
            }
            if (self.t_us / 1000).is_multiple_of(10) {
                self.ax.parameters(&self.d.params);
            }
            self.ax.advance(0.001, &c);
            each(self);
        }
    }

    /// Shutdown, switch on, enable operation: Operation enabled.
    pub fn enable(&mut self) {
        self.run(0x06, 5, |_| {});
        self.run(0x07, 5, |_| {});
        self.run(0x0F, 50, |_| {});
        assert_eq!(self.d.cia402.state(), PdsState::OperationEnabled);
    }

    /// SDO download.
    pub fn write(&mut self, index: u16, sub: u8, v: &[u8]) -> Result<(), SdoAbort> {
        Dictionary::write(&mut self.d, ObjectKey::new(index, sub), v, EsmState::Op)
    }

    /// SDO upload of an entry of up to 16 bits.
    pub fn read_u16(&mut self, index: u16, sub: u8) -> u16 {
        let mut b = [0u8; 4];
        let n = Dictionary::read(&mut self.d, ObjectKey::new(index, sub), &mut b).unwrap_or(0);
        assert!(n <= 2);
        u16::from_le_bytes([b[0], b[1]])
    }

    /// Encoder counts of the true rotor position.
    pub fn counts(&self) -> f64 {
        self.ax.true_position() * COUNTS_PER_UNIT
    }

    /// Encoder counts per command unit.
    pub fn counts_per_unit(&self) -> f64 {
        COUNTS_PER_UNIT
    }

    /// Lowest and highest rotor position (counts from `from`) over `ms` ticks with the
    /// drive enabled.
    pub fn range(&mut self, ms: u32, from: f64) -> (f64, f64) {
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        self.run(0x0F, ms, |b| {
            lo = lo.min(b.counts() - from);
            hi = hi.max(b.counts() - from);
        });
        (lo, hi)
    }

    /// Runs while 0x2162:02 reads "running", at most 5 s; returns the time (ms) and
    /// the lowest and highest rotor position (counts from `from`) meanwhile.
    pub fn until_tune_over(&mut self, from: f64) -> (u32, (f64, f64)) {
        let (mut lo, mut hi) = (0.0f64, 0.0f64);
        let mut ms = 0;
        while self.read_u16(0x2162, 2) == 1 && ms < 5000 {
            let (a, b) = self.range(10, from);
            lo = lo.min(a);
            hi = hi.max(b);
            ms += 10;
        }
        (ms, (lo, hi))
    }
}

/// What a tune on the drive gave.
#[derive(Clone, Debug)]
pub struct DriveTune {
    /// 0x2162:02 at the end (2 = done).
    pub state: u16,
    /// 0x2164, % of the rotor inertia.
    pub ratio_percent: u16,
    /// Error against the true load, %.
    pub error_percent: f64,
    /// How long 0x2162:02 read "running", ms.
    pub duration_ms: u32,
    /// Lowest and highest rotor position during the move, counts from the start.
    pub travel_counts: (f64, f64),
    /// Peak-to-peak rotor position at standstill before the tune (rotor-only gains)
    /// and after it (the gains it set), counts over 200 ms.
    pub standstill_before: f64,
    /// See `standstill_before`.
    pub standstill_after: f64,
    /// Rotor position 200 ms after the tune, counts from the start.
    pub end_counts: f64,
}

/// Peak-to-peak of the rotor over `ms` ticks with the drive enabled.
fn standstill(b: &mut DriveBench, ms: u32) -> f64 {
    let (lo, hi) = b.range(ms, 0.0);
    hi - lo
}

/// Runs a tune with the default travel (90°) on `motor` carrying `load` × its rotor
/// inertia, up to 5 s.
pub fn tune_on_drive(motor: Motor, load: f64) -> DriveTune {
    let mut b = DriveBench::new(motor, load, &[]);
    b.enable();
    let before = standstill(&mut b, 200);
    let start = b.counts();
    let (ms, travel) = match b.write(0x2162, 1, &[1]) {
        Ok(()) => b.until_tune_over(start),
        Err(_) => (0, (0.0, 0.0)),
    };
    let state = b.read_u16(0x2162, 2);
    let ratio = b.read_u16(0x2164, 0);
    let after = standstill(&mut b, 200);
    DriveTune {
        state,
        ratio_percent: ratio,
        error_percent: (f64::from(ratio) / (load * 100.0) - 1.0) * 100.0,
        duration_ms: ms,
        travel_counts: travel,
        standstill_before: before,
        standstill_after: after,
        end_counts: b.counts() - start,
    }
}
