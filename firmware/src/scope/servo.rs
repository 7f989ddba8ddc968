//! The scope at the servo rate (0x2500:08 = 1): what the control path hands the drive
//! each servo period ([`ServoPoint`], through a [`PointRing`]) and the internal
//! signals 0x2510 it carries ([`internal_signal`]).

use core::sync::atomic::{AtomicU32, Ordering};

use crate::cia402::DriveCommand;
use crate::motion::AxisState;

/// The internal signals of one servo period (the fields of [`AxisState`] that
/// 0x2510 shows).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ServoPoint {
    /// Motor-side position, command units.
    pub position: i32,
    /// Motor-side velocity, command units/s.
    pub velocity: i32,
    /// Servo demand minus encoder, counts.
    pub following_error: i32,
    /// q current demand, per mille of the rated current.
    pub current_demand: i16,
    /// q current measured, per mille of the rated current.
    pub current_actual: i16,
    /// Phase currents, mA.
    pub ia_ma: i16,
    /// See `ia_ma`.
    pub ib_ma: i16,
    /// DC bus voltage, mV.
    pub bus_mv: u32,
    /// The servo is at its current limit.
    pub current_limited: bool,
}

impl ServoPoint {
    /// The point of the axis state `a`.
    pub fn of(a: &AxisState) -> Self {
        ServoPoint {
            position: a.position,
            velocity: a.velocity,
            following_error: a.servo_following_error,
            current_demand: a.current_permille,
            current_actual: a.torque_permille,
            ia_ma: a.ia_ma,
            ib_ma: a.ib_ma,
            bus_mv: a.bus_mv,
            current_limited: a.current_limited,
        }
    }

    fn to_words(self) -> [u32; WORDS] {
        let pair = |hi: i16, lo: i16| u32::from(hi as u16) << 16 | u32::from(lo as u16);
        [
            self.position as u32,
            self.velocity as u32,
            self.following_error as u32,
            pair(self.current_demand, self.current_actual),
            pair(self.ia_ma, self.ib_ma),
            self.bus_mv,
            u32::from(self.current_limited),
        ]
    }

    fn from_words(w: [u32; WORDS]) -> Self {
        let hi = |x: u32| (x >> 16) as u16 as i16;
        let lo = |x: u32| x as u16 as i16;
        ServoPoint {
            position: w[0] as i32,
            velocity: w[1] as i32,
            following_error: w[2] as i32,
            current_demand: hi(w[3]),
            current_actual: lo(w[3]),
            ia_ma: hi(w[4]),
            ib_ma: lo(w[4]),
            bus_mv: w[5],
            current_limited: w[6] != 0,
        }
    }
}

/// Internal signal 0x2510:`sub` of the servo period `p` with the drive's last
/// command `c` (the acceleration demand and the power flags change with the drive's
/// steps, not within a servo period). 0 for a sub-index without a signal.
pub fn internal_signal(p: &ServoPoint, c: &DriveCommand, sub: u8) -> u32 {
    match sub {
        1 => p.following_error as u32,
        // Rounded toward zero, saturated (`as`; NaN → 0).
        2 => c.acceleration as i32 as u32,
        3 => p.bus_mv,
        4 => {
            u32::from(c.power_stage)
                | u32::from(c.drive_enabled) << 1
                | u32::from(p.current_limited) << 2
                | u32::from(c.brake_release) << 3
        }
        5 => p.position as u32,
        6 => p.velocity as u32,
        7 => p.current_demand as u32,
        8 => p.current_actual as u32,
        9 => p.ia_ma as u32,
        10 => p.ib_ma as u32,
        _ => 0,
    }
}

/// Words of one point in the ring.
const WORDS: usize = 7;

/// Single-producer single-consumer queue of [`ServoPoint`]s between the current-loop
/// interrupt (producer, [`PointRing::push`]) and the drive's tick (consumer,
/// [`PointRing::pop`]) on one core, of `N` points. Every word is an atomic, so there is
/// no `unsafe`: the producer writes a free slot, then publishes it by moving the head
/// (release); the consumer reads the slot at the tail once the head shows it
/// (acquire), then frees it by moving the tail (release). A full ring drops the new
/// point and counts it ([`PointRing::dropped`]).
pub struct PointRing<const N: usize> {
    slots: [[AtomicU32; WORDS]; N],
    head: AtomicU32,
    tail: AtomicU32,
    dropped: AtomicU32,
}

impl<const N: usize> Default for PointRing<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> PointRing<N> {
    /// Empty.
    pub const fn new() -> Self {
        PointRing {
            slots: [const { [const { AtomicU32::new(0) }; WORDS] }; N],
            head: AtomicU32::new(0),
            tail: AtomicU32::new(0),
            dropped: AtomicU32::new(0),
        }
    }

    /// Queues `p` (producer); false when the ring is full (the point is dropped).
    pub fn push(&self, p: &ServoPoint) -> bool {
        let head = self.head.load(Ordering::Relaxed);
        let tail = self.tail.load(Ordering::Acquire);
        if head.wrapping_sub(tail) as usize >= N {
            self.dropped.fetch_add(1, Ordering::Relaxed);
            return false;
        }
        let Some(slot) = self.slots.get(head as usize % N) else {
            return false;
        };
        for (w, v) in slot.iter().zip(p.to_words()) {
            w.store(v, Ordering::Relaxed);
        }
        self.head.store(head.wrapping_add(1), Ordering::Release);
        true
    }

    /// The oldest queued point (consumer).
    pub fn pop(&self) -> Option<ServoPoint> {
        let tail = self.tail.load(Ordering::Relaxed);
        if self.head.load(Ordering::Acquire) == tail {
            return None;
        }
        let slot = self.slots.get(tail as usize % N)?;
        let mut w = [0u32; WORDS];
        for (v, a) in w.iter_mut().zip(slot) {
            *v = a.load(Ordering::Relaxed);
        }
        self.tail.store(tail.wrapping_add(1), Ordering::Release);
        Some(ServoPoint::from_words(w))
    }

    /// Points dropped because the ring was full (wrapping).
    pub fn dropped(&self) -> u32 {
        self.dropped.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(k: i32) -> ServoPoint {
        ServoPoint {
            position: k,
            velocity: -k,
            following_error: 3 * k,
            current_demand: -1000,
            current_actual: 999,
            ia_ma: -32000,
            ib_ma: 32000,
            bus_mv: 48_000 + k as u32,
            current_limited: k % 2 == 0,
        }
    }

    #[test]
    fn ring_keeps_order_and_values_and_drops_when_full() {
        let r: PointRing<4> = PointRing::new();
        assert_eq!(r.pop(), None);
        for round in 0..3 {
            for k in 0..4 {
                assert!(r.push(&point(10 * round + k)));
            }
            assert!(!r.push(&point(99)), "full");
            for k in 0..4 {
                assert_eq!(r.pop(), Some(point(10 * round + k)));
            }
            assert_eq!(r.pop(), None);
        }
        assert_eq!(r.dropped(), 3);
    }

    #[test]
    fn signals_of_a_point() {
        let p = point(5);
        let c = DriveCommand {
            power_stage: true,
            drive_enabled: true,
            brake_release: true,
            acceleration: -1234.7,
            ..DriveCommand::default()
        };
        assert_eq!(internal_signal(&p, &c, 1), 15);
        assert_eq!(internal_signal(&p, &c, 2) as i32, -1234);
        assert_eq!(internal_signal(&p, &c, 3), 48_005);
        assert_eq!(internal_signal(&p, &c, 4), 0b1011);
        assert_eq!(internal_signal(&p, &c, 5), 5);
        assert_eq!(internal_signal(&p, &c, 6) as i32, -5);
        assert_eq!(internal_signal(&p, &c, 7) as i32, -1000);
        assert_eq!(internal_signal(&p, &c, 8), 999);
        assert_eq!(internal_signal(&p, &c, 9) as i32, -32000);
        assert_eq!(internal_signal(&p, &c, 10), 32000);
        assert_eq!(internal_signal(&p, &c, 11), 0);
        let nan = DriveCommand {
            acceleration: f32::NAN,
            ..c
        };
        assert_eq!(internal_signal(&p, &nan, 2), 0);
    }
}
