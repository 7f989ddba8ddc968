//! The rate limit of the fault-history records ([`HistoryRate`]): a master that
//! resets a recurring fault must not wear out the two history slots.
//!
//! # The bound
//! A history slot is two 2 KiB pages (dual-bank) that are erased each time a record
//! goes to that slot; the two slots alternate, so each page is erased once per two
//! records. The STM32G4's flash is specified for at least 10 000 erase cycles per
//! page (data sheet, "Flash memory endurance"), i.e. ≥ 20 000 history records.
//!
//! A record is written only when the history changed (`Drive::persist_history`),
//! and then only when
//! - at least [`MIN_INTERVAL_MS`] (10 s) passed since the previous record: the
//!   changes of a fault storm are coalesced into one record, and
//! - a write credit is left: [`BURST`] (8) credits, one credit back every
//!   [`REFILL_MS`] (2 h) — at most `8 + hours / 2` records in any span of `hours`.
//!
//! A fault reset every second for 10 years therefore writes at most
//! 8 + 87 600 / 2 = 43 808 records, and the pages see ≤ 21 904 erases: the
//! specified endurance is reached only after ≈ 4.6 years of an uninterrupted fault
//! storm, while the sporadic faults of normal operation (fewer than 8 per 2 hours,
//! 10 s apart) are written within 10 s. The history in RAM (0x10F3, 0x2400) always
//! holds every entry; a changed history waits at most [`MAX_DELAY_MS`] (2 h) for its
//! record, and only a power cut inside that wait loses the newest entries from flash.

/// Least time between two history records, ms.
pub const MIN_INTERVAL_MS: u32 = 10_000;
/// Records that may be written back to back (10 s apart) after a quiet time.
pub const BURST: u32 = 8;
/// Time that gives one record credit back, ms (2 h: at most 0.5 records per hour
/// sustained).
pub const REFILL_MS: u32 = 2 * 3_600_000;
/// Longest time a changed history waits for its record, ms.
pub const MAX_DELAY_MS: u32 = if REFILL_MS > MIN_INTERVAL_MS {
    REFILL_MS
} else {
    MIN_INTERVAL_MS
};

/// The limiter (see the module docs). Feed it the drive's millisecond clock; it must
/// see the clock at least once every 24 days (the board polls it every millisecond).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HistoryRate {
    credits: u32,
    refill_ms: u32,
    since_write_ms: u32,
    prev_ms: Option<u32>,
    written: u32,
}

impl Default for HistoryRate {
    fn default() -> Self {
        Self::new()
    }
}

impl HistoryRate {
    /// Full credit; the first record may go at once.
    pub const fn new() -> Self {
        HistoryRate {
            credits: BURST,
            refill_ms: 0,
            since_write_ms: MIN_INTERVAL_MS,
            prev_ms: None,
            written: 0,
        }
    }

    fn advance(&mut self, now_ms: u32) {
        let dt = self.prev_ms.map_or(0, |p| now_ms.wrapping_sub(p));
        self.prev_ms = Some(now_ms);
        self.since_write_ms = self.since_write_ms.saturating_add(dt);
        if self.credits >= BURST {
            self.refill_ms = 0;
            return;
        }
        self.refill_ms = self.refill_ms.saturating_add(dt);
        while self.refill_ms >= REFILL_MS && self.credits < BURST {
            self.credits += 1;
            self.refill_ms -= REFILL_MS;
        }
        if self.credits >= BURST {
            self.refill_ms = 0;
        }
    }

    /// True when a record may be written at `now_ms` (then call
    /// [`HistoryRate::wrote`] once it was).
    pub fn may_write(&mut self, now_ms: u32) -> bool {
        self.advance(now_ms);
        self.credits > 0 && self.since_write_ms >= MIN_INTERVAL_MS
    }

    /// A record was written (or its write was attempted) at the last
    /// [`HistoryRate::may_write`] time.
    pub fn wrote(&mut self) {
        self.credits = self.credits.saturating_sub(1);
        self.since_write_ms = 0;
        self.written = self.written.wrapping_add(1);
    }

    /// Records written so far (tests, diagnostics).
    pub fn records(&self) -> u32 {
        self.written
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    /// A history that changes every `period_ms` for `span_ms`, written whenever the
    /// limiter lets it (polled every 100 ms): how many records, and the longest wait
    /// of a change.
    fn storm(period_ms: u32, span_ms: u64) -> (u64, u64) {
        let mut r = HistoryRate::new();
        let (mut records, mut dirty_since, mut worst) = (0u64, None::<u64>, 0u64);
        let mut t = 0u64;
        while t < span_ms {
            if t.is_multiple_of(u64::from(period_ms)) && dirty_since.is_none() {
                dirty_since = Some(t);
            }
            if let Some(since) = dirty_since {
                if r.may_write(t as u32) {
                    r.wrote();
                    records += 1;
                    worst = worst.max(t - since);
                    dirty_since = None;
                }
            } else {
                r.may_write(t as u32);
            }
            t += 100;
        }
        (records, worst)
    }

    #[test]
    fn a_fault_reset_every_second_writes_at_most_the_bound() {
        // 60 days of a fault that comes back every second (the u32 clock wraps
        // after 49.7 days: 60 days cover one wrap).
        let hours: u32 = 60 * 24;
        let (records, worst) = storm(1_000, u64::from(hours) * 3_600_000);
        assert!(
            records <= u64::from(BURST) + u64::from(hours) / 2,
            "{records} records in {hours} h"
        );
        // Without the limit it would be one record per change: 5.2 million.
        assert!(records >= u64::from(hours) / 2, "{records}: still written");
        assert!(worst <= u64::from(MAX_DELAY_MS), "waited {worst} ms");
    }

    #[test]
    fn sporadic_faults_are_written_within_the_interval() {
        // One change every 20 minutes for 160 minutes: 8 changes, inside the credit.
        let (records, worst) = storm(20 * 60_000, 8 * 20 * 60_000);
        assert_eq!(records, 8);
        assert!(worst <= u64::from(MIN_INTERVAL_MS), "waited {worst} ms");
        // One every 2 h for two days: each within the interval too.
        let (records, worst) = storm(REFILL_MS, 48 * 3_600_000);
        assert_eq!(records, 24);
        assert!(worst <= u64::from(MIN_INTERVAL_MS), "waited {worst} ms");
    }

    #[test]
    fn the_first_record_goes_at_once_and_the_next_waits_the_interval() {
        let mut r = HistoryRate::new();
        assert!(r.may_write(5));
        r.wrote();
        assert!(!r.may_write(5 + MIN_INTERVAL_MS - 1));
        assert!(r.may_write(5 + MIN_INTERVAL_MS));
        assert_eq!(r.records(), 1);
    }
}
