//! Position latches of the board's fast inputs and the encoder index, from the control
//! path to the drive's touch probe (0x60B8-0x60BD) — the chip-independent part.
//!
//! ```text
//!  capture / EXTI ─ raw count + pin level ─▶ control interrupt: units_at_count ─▶
//!  Edges<i32> (per electrical edge: sequence + position) ─ published ─▶
//!  ProbeInput::update (0x2154 polarity → rising/falling, pending until a cycle ran)
//!  ─▶ AxisState::probe1 / probe2 ─▶ CiA 402 touch probe
//! ```
//!
//! * A latch holds the encoder count at the edge; the control path converts it to the
//!   axis position in command units: the present position minus the counts moved
//!   since the edge ([`units_at_count`]), so the motion layer's scaling and direction
//!   (0x2001, 0x2029, 0x2051) apply exactly as to the actual position.
//! * Edges are *electrical*: an opto input is active while its transistor conducts,
//!   which pulls the pin low. The touch probe's rising edge is the input becoming
//!   logically active, so 0x2154 (bit n inverts input n+1) swaps the two
//!   ([`ProbeInput::update`]).
//! * Each electrical edge kind keeps its latest latch with a sequence number
//!   ([`Edges`]): several readers per cycle see the same value, none is lost between
//!   two publications unless the same edge kind occurs twice (then the later one is
//!   reported). On the drive side an edge is kept pending until a drive cycle has seen
//!   it ([`ProbeInput::consumed`]); of several edges of one kind within a cycle the
//!   first is reported (the one a single-event probe must latch).

use crate::cia402::EdgeLatch;
use crate::motion::MotionConfig;

/// Axis position, command units, at an edge latched `counts_since` motor encoder counts
/// ago (present count − latched count, wrapping), given the present axis position
/// `now_units`. Without an encoder the present position is returned.
pub fn units_at_count(cfg: &MotionConfig, now_units: i32, counts_since: i32) -> i32 {
    if cfg.counts_per_rev == 0 {
        return now_units;
    }
    let dir: i64 = if cfg.reverse { -1 } else { 1 };
    // round(dir · moved · U / C) in 64 bits (exact, no float rounding of large moves;
    // saturating only for U beyond what the parameters allow).
    let c = i64::from(cfg.counts_per_rev);
    let x = (dir * i64::from(counts_since)).saturating_mul(i64::from(cfg.pulses_per_rev));
    // `div_euclid` by the positive 2·C as one unsigned division (no overflow checks).
    let two_c = core::num::NonZeroU64::new(2 * c as u64).unwrap_or(core::num::NonZeroU64::MIN);
    let back = crate::motion::floor_div_i64(x.saturating_mul(2).saturating_add(c), two_c);
    let back = back.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
    now_units.wrapping_sub(back)
}

/// The latest latch of each electrical edge of one input, with sequence numbers
/// (`T`: raw count on the way to the control path, command units after it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Edges<T> {
    /// Incremented at each edge to the active level (pin low).
    pub active_seq: u32,
    /// Latch of the last edge to the active level.
    pub active: T,
    /// Incremented at each edge to the inactive level (pin high).
    pub inactive_seq: u32,
    /// Latch of the last edge to the inactive level.
    pub inactive: T,
}

/// Sequence numbers of [`Edges`] a reader has already taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Seen {
    active: u32,
    inactive: u32,
}

impl<T: Copy> Edges<T> {
    /// Records an edge: `to_active` true when the input became electrically active.
    pub fn record(&mut self, to_active: bool, v: T) {
        if to_active {
            self.active = v;
            self.active_seq = self.active_seq.wrapping_add(1);
        } else {
            self.inactive = v;
            self.inactive_seq = self.inactive_seq.wrapping_add(1);
        }
    }

    /// The edges not yet taken by the reader `seen` (to active, to inactive); marks
    /// them taken.
    pub fn take_new(&self, seen: &mut Seen) -> (Option<T>, Option<T>) {
        let a = (self.active_seq != seen.active).then_some(self.active);
        let i = (self.inactive_seq != seen.inactive).then_some(self.inactive);
        seen.active = self.active_seq;
        seen.inactive = self.inactive_seq;
        (a, i)
    }
}

/// Drive-side state of one touch-probe input: logical edges pending for the next
/// drive cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ProbeInput {
    seen: Seen,
    pending: EdgeLatch,
}

impl ProbeInput {
    /// Takes the new edges of `e` (positions in command units); `inverted` is the
    /// input's 0x2154 bit. Returns the edges pending for the next cycle.
    pub fn update(&mut self, e: &Edges<i32>, inverted: bool) -> EdgeLatch {
        let (to_active, to_inactive) = e.take_new(&mut self.seen);
        let (rising, falling) = if inverted {
            (to_inactive, to_active)
        } else {
            (to_active, to_inactive)
        };
        self.pending.rising = self.pending.rising.or(rising);
        self.pending.falling = self.pending.falling.or(falling);
        self.pending
    }

    /// Edges pending for the next cycle.
    pub fn pending(&self) -> EdgeLatch {
        self.pending
    }

    /// A drive cycle has seen the pending edges.
    pub fn consumed(&mut self) {
        self.pending = EdgeLatch::default();
    }
}
