//! Emergency messages (CoE service 1).
//!
//! Mailbox length 10: CoE header (service 1, number 0), u16 error code, u8 error register
//! (the value of 0x1001), 5 bytes of manufacturer data. EtherCAT-specific codes include
//! 0xA000 (Pre-Op → Safe-Op failed) and 0xA001 (Safe-Op → Op failed); 0xFFxx is
//! vendor-specific.
//!
//! The [`EmergencyQueue`] holds at most [`QUEUE_LEN`] messages until SM1 is free. When it
//! is full a new message is dropped and counted as an overrun — never silently.

use crate::mailbox::{Frame, MailboxType, Repr, HEADER_LEN};
pub use crate::wire::emcy::{Emergency, PAYLOAD_LEN};
use heapless::Deque;

/// Queue depth.
pub const QUEUE_LEN: usize = 8;
/// Bounded queue of emergencies with an overrun counter.
pub struct EmergencyQueue {
    q: Deque<Emergency, QUEUE_LEN>,
    overruns: u32,
}

impl Default for EmergencyQueue {
    fn default() -> Self {
        Self::new()
    }
}

impl EmergencyQueue {
    /// An empty queue.
    pub const fn new() -> Self {
        EmergencyQueue {
            q: Deque::new(),
            overruns: 0,
        }
    }
    /// Queues a message; when full, drops it and counts an overrun.
    pub fn push(&mut self, e: Emergency) {
        if self.q.push_back(e).is_err() {
            self.overruns = self.overruns.saturating_add(1);
        }
    }
    /// Messages dropped because the queue was full.
    pub fn overruns(&self) -> u32 {
        self.overruns
    }
    /// Drops every waiting message (the overrun counter is kept).
    pub(crate) fn clear(&mut self) {
        self.q.clear();
    }
    /// Messages waiting.
    pub fn len(&self) -> usize {
        self.q.len()
    }
    /// True when nothing waits.
    pub fn is_empty(&self) -> bool {
        self.q.is_empty()
    }
    /// Writes the oldest message as a whole mailbox frame (counter 0) into `out` and
    /// removes it; returns the frame length, 0 if the queue is empty or `out` too short
    /// (the message then stays queued).
    pub fn pop_frame(&mut self, out: &mut [u8]) -> usize {
        let Some(e) = self.q.front().copied() else {
            return 0;
        };
        let Some(buf) = out.get_mut(..HEADER_LEN + PAYLOAD_LEN) else {
            return 0;
        };
        let mut f = Frame::new_unchecked(&mut *buf);
        Repr {
            length: PAYLOAD_LEN as u16,
            address: 0,
            channel: 0,
            priority: 0,
            mailbox_type: MailboxType::Coe,
            counter: 0,
        }
        .emit(&mut f);
        e.emit(f.payload_mut());
        self.q.pop_front();
        HEADER_LEN + PAYLOAD_LEN
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn emergency_frame_bytes() {
        let mut q = EmergencyQueue::new();
        q.push(Emergency {
            error_code: 0xA000,
            error_register: 0x11,
            data: [2, 0x24, 0, 0, 0],
        });
        let mut out = [0xEEu8; 32];
        assert_eq!(q.pop_frame(&mut out), 16);
        assert_eq!(
            out[..16],
            [10, 0, 0, 0, 0, 0x03, 0x00, 0x10, 0x00, 0xA0, 0x11, 2, 0x24, 0, 0, 0]
        );
        assert_eq!(out[16], 0xEE);
        assert_eq!(q.pop_frame(&mut out), 0);
        assert_eq!(
            Emergency::parse(&out[6..16]),
            Some(Emergency {
                error_code: 0xA000,
                error_register: 0x11,
                data: [2, 0x24, 0, 0, 0]
            })
        );
        assert_eq!(Emergency::parse(&out[6..15]), None);
        assert_eq!(Emergency::parse(&[0, 0x20, 0, 0, 0, 0, 0, 0, 0, 0]), None);
    }

    #[test]
    fn emergency_round_trips() {
        let bytes = [0x00, 0x10, 0x10, 0x23, 0x81, 1, 2, 3, 4, 5];
        let e = Emergency::parse(&bytes).unwrap();
        assert_eq!(
            e,
            Emergency {
                error_code: 0x2310,
                error_register: 0x81,
                data: [1, 2, 3, 4, 5]
            }
        );
        let mut out = [0xEEu8; 12];
        assert_eq!(e.emit(&mut out), PAYLOAD_LEN);
        assert_eq!(out[..PAYLOAD_LEN], bytes);
        assert_eq!(out[PAYLOAD_LEN..], [0xEE, 0xEE]);
        assert_eq!(e.emit(&mut out[..PAYLOAD_LEN - 1]), 0);
        assert_eq!(Emergency::parse(&bytes[..1]), None);
        assert_eq!(
            Emergency::parse(&[0x00, 0x30, 0, 0, 0, 0, 0, 0, 0, 0]),
            None
        );
    }

    #[test]
    fn full_queue_counts_overruns_and_keeps_oldest() {
        let mut q = EmergencyQueue::new();
        for i in 0..(QUEUE_LEN as u16 + 3) {
            q.push(Emergency {
                error_code: i,
                error_register: 0,
                data: [0; 5],
            });
        }
        assert_eq!(q.len(), QUEUE_LEN);
        assert_eq!(q.overruns(), 3);
        let mut out = [0u8; 16];
        let mut short = [0u8; 15];
        assert_eq!(q.pop_frame(&mut short), 0);
        assert_eq!(q.len(), QUEUE_LEN);
        for i in 0..QUEUE_LEN as u16 {
            assert_eq!(q.pop_frame(&mut out), 16);
            assert_eq!(u16::from_le_bytes([out[8], out[9]]), i);
        }
        assert!(q.is_empty());
    }
}
