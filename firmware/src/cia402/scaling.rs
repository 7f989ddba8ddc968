//! The position scaling objects 0x6091 (gear ratio), 0x6092 (feed constant) and 0x6093
//! (position factor), three views of one number: the command units per motor
//! revolution, 0x2001 (effective after a restart, like 0x2001 itself).
//!
//! * units per motor revolution = 0x6092:01 · 0x6091:02 / (0x6092:02 · 0x6091:01)
//!   (feed per shaft revolution times shaft revolutions per motor revolution);
//! * position factor 0x6093:01 / 0x6093:02 = encoder increments per command unit =
//!   0x608F:01 / units per revolution.
//!
//! Every sub-index takes any value from 1 (0 is refused by the range). A master writes
//! the sub-indices one after the other, so a write stores its value even when the set
//! does not describe a whole number of units per revolution yet; the drive
//! (`drive::Drive`'s SDO write) hands a whole result to 0x2001, and when 0x2001
//! takes it (its range) the other view follows: after 0x6091 / 0x6092 the factor is
//! derived again, after 0x6093 the gear ratio becomes 1:1 and the feed (units, 1). A
//! write of 0x2001 sets gear 1:1, feed (0x2001, 1) and the derived factor.
//!
//! Without an encoder (the open-loop variant, 0x608F:01 = 0) the factor has no
//! increments to count: it reads 1 / units, and a write of it never gives 0x2001 a
//! value (0 units); such a drive is scaled by 0x2001 or 0x6091 / 0x6092.

/// The scaling objects' values (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Scaling {
    /// 0x6091:01 motor revolutions, :02 shaft revolutions.
    pub gear: [u32; 2],
    /// 0x6092:01 feed, :02 shaft revolutions.
    pub feed: [u32; 2],
    /// 0x6093 as written (numerator, divisor); `None`: derived from the units.
    factor: Option<[u32; 2]>,
    /// Command units per revolution the views agree on (0x2001 as written).
    units: u32,
    /// The object written last (0x6091-0x6093) and the whole number of units per
    /// revolution it gives, waiting for 0x2001 to take it.
    candidate: Option<(u16, u32)>,
}

fn gcd(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

/// `n / d` when it is a whole number that fits a `u32` (and `d` is not 0).
fn whole(n: u64, d: u64) -> Option<u32> {
    if d == 0 || !n.is_multiple_of(d) {
        return None;
    }
    u32::try_from(n / d).ok()
}

impl Scaling {
    /// Gear 1:1, feed (`units`, 1), derived factor.
    pub const fn new(units: u32) -> Self {
        Scaling {
            gear: [1, 1],
            feed: [units, 1],
            factor: None,
            units,
            candidate: None,
        }
    }

    /// 0x6093 (numerator, divisor) with `increments` encoder increments per motor
    /// revolution: as written, else `increments / units` in lowest terms.
    pub fn factor(&self, increments: u32) -> [u32; 2] {
        if let Some(f) = self.factor {
            return f;
        }
        let (n, d) = (u64::from(increments.max(1)), u64::from(self.units.max(1)));
        let g = gcd(n, d);
        [(n / g) as u32, (d / g) as u32]
    }

    /// Stores sub-index `sub` (1 or 2) of `index` (0x6091-0x6093); notes the units
    /// per revolution the set then gives, when whole.
    pub fn set(&mut self, index: u16, sub: u8, v: u32, increments: u32) {
        let i = usize::from(sub.saturating_sub(1)).min(1);
        let units = match index {
            0x6091 => {
                self.gear[i] = v;
                self.units_of_gear_and_feed()
            }
            0x6092 => {
                self.feed[i] = v;
                self.units_of_gear_and_feed()
            }
            _ => {
                let mut f = self.factor(increments);
                f[i] = v;
                self.factor = Some(f);
                whole(u64::from(increments) * u64::from(f[1]), u64::from(f[0]))
            }
        };
        self.candidate = units.map(|u| (index, u));
    }

    fn units_of_gear_and_feed(&self) -> Option<u32> {
        let n = u64::from(self.feed[0]) * u64::from(self.gear[1]);
        let d = u64::from(self.feed[1]) * u64::from(self.gear[0]);
        whole(n, d)
    }

    /// The whole number of units per revolution the last write gave, for 0x2001.
    pub fn candidate(&self) -> Option<u32> {
        self.candidate.map(|(_, u)| u)
    }

    /// 0x2001 took the candidate: the other view follows (see the module docs).
    pub fn settle(&mut self) {
        if let Some((index, units)) = self.candidate.take() {
            self.units = units;
            if index == 0x6093 {
                self.gear = [1, 1];
                self.feed = [units, 1];
            } else {
                self.factor = None;
            }
        }
    }

    /// 0x2001 was written: gear 1:1, feed (`units`, 1), derived factor.
    pub fn set_units(&mut self, units: u32) {
        *self = Scaling::new(units);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gear_and_feed_give_the_units_and_the_factor_follows() {
        let mut s = Scaling::new(50_000);
        assert_eq!(s.factor(4000), [2, 25]);
        // 10 000 units per shaft revolution, 1 shaft revolution per 5 motor revolutions.
        s.set(0x6092, 1, 10_000, 4000);
        assert_eq!(s.candidate(), Some(10_000));
        s.settle();
        s.set(0x6091, 1, 5, 4000);
        assert_eq!(s.candidate(), Some(2000));
        s.settle();
        assert_eq!(s.factor(4000), [2, 1]);
        // Not whole: stored, no candidate, the last agreed units stay.
        s.set(0x6091, 1, 3, 4000);
        assert_eq!((s.gear, s.candidate()), ([3, 1], None));
        assert_eq!(s.factor(4000), [2, 1]);
    }

    #[test]
    fn the_factor_gives_the_units_and_resets_gear_and_feed() {
        let mut s = Scaling::new(50_000);
        s.set(0x6092, 2, 2, 4000);
        s.set(0x6093, 1, 4000, 4000);
        // 4000 · 25 / 4000 (the divisor still the derived 25): whole, but 0x2001
        // refuses 25 (the drive's part), so it stays a candidate only.
        assert_eq!(s.candidate(), Some(25));
        s.set(0x6093, 2, 10_000, 4000);
        assert_eq!(s.candidate(), Some(10_000));
        s.settle();
        assert_eq!((s.gear, s.feed), ([1, 1], [10_000, 1]));
        assert_eq!(s.factor(4000), [4000, 10_000], "as written");
        s.set_units(8000);
        assert_eq!(
            (s.gear, s.feed, s.factor(4000)),
            ([1, 1], [8000, 1], [1, 2])
        );
        // A huge feed that overflows u32 units: no candidate.
        s.set(0x6092, 1, u32::MAX, 4000);
        s.set(0x6091, 2, 3, 4000);
        assert_eq!(s.candidate(), None);
    }
}
