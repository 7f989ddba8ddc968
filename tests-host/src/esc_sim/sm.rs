//! Runtime state of one SyncManager: mailbox (1-buffer) and buffered (3-buffer) modes.
//!
//! Mailbox mode: the buffer lives in process RAM at the SM start address. The
//! producer may write only while the mailbox is empty; writing the last byte makes it
//! full. The consumer may read only while it is full; reading the last byte empties it.
//!
//! Buffered mode: three buffers of the SM length are kept here (the ESC hides them
//! behind the one visible window). The producer writes into a free buffer; writing the
//! last byte commits it as the newest. The consumer opens the newest complete buffer
//! on its first access and keeps it until it reads the last byte, so it always gets the
//! latest complete data and never a torn buffer.

/// Which way an access goes.
pub(crate) enum SmOp<'a> {
    Read(&'a mut [u8]),
    Write(&'a [u8]),
}

/// Buffer events produced by an access.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Event {
    /// The producer completed a buffer (last byte written).
    Written,
    /// The consumer finished a buffer (last byte read).
    Read,
}

pub(crate) struct Outcome {
    pub(crate) accepted: bool,
    pub(crate) event: Option<Event>,
}

#[derive(Default)]
pub(crate) struct SmRuntime {
    pub(crate) enabled: bool,
    full: bool,
    bufs: [Vec<u8>; 3],
    latest: Option<usize>,
    producer_open: Option<usize>,
    consumer_open: Option<usize>,
    irq_write: bool,
    irq_read: bool,
}

impl SmRuntime {
    /// Resets the buffer state (SM enabled or disabled); `buffered_len` > 0 allocates
    /// the three hidden buffers.
    pub(crate) fn reset(&mut self, enabled: bool, buffered_len: usize) {
        *self = SmRuntime {
            enabled,
            ..SmRuntime::default()
        };
        if enabled && buffered_len > 0 {
            for b in &mut self.bufs {
                *b = vec![0; buffered_len];
            }
        }
    }

    /// The status byte (+5): bit 0 write event, bit 1 read event, bit 3 mailbox full,
    /// bits 5:4 newest buffer (3 = none), bit 6 read buffer open, bit 7 write buffer
    /// open.
    pub(crate) fn status_byte(&self, mailbox: bool) -> u8 {
        let mut s = 0u8;
        if self.irq_write {
            s |= 0x01;
        }
        if self.irq_read {
            s |= 0x02;
        }
        if mailbox {
            if self.full {
                s |= 0x08;
            }
        } else {
            s |= (self.latest.unwrap_or(3) as u8 & 0x03) << 4;
            if self.consumer_open.is_some() {
                s |= 0x40;
            }
            if self.producer_open.is_some() {
                s |= 0x80;
            }
        }
        s
    }

    fn free_buffer(&self) -> usize {
        (0..3)
            .find(|&k| Some(k) != self.latest && Some(k) != self.consumer_open)
            .unwrap_or(0)
    }

    fn consumer_buffer(&self) -> usize {
        self.consumer_open
            .or(self.latest)
            .unwrap_or_else(|| (0..3).find(|&k| Some(k) != self.producer_open).unwrap_or(0))
    }

    /// Byte `off` of the window as the consumer would see it now (no side effects).
    pub(crate) fn peek(&self, mem: &[u8], start: usize, off: usize) -> u8 {
        if self.bufs[0].is_empty() {
            mem.get(start + off).copied().unwrap_or(0)
        } else {
            self.bufs[self.consumer_buffer()]
                .get(off)
                .copied()
                .unwrap_or(0)
        }
    }

    /// One access of the window: `off` is the offset inside the window, the access
    /// ends at most at the window end. The caller has checked the direction.
    pub(crate) fn access(
        &mut self,
        mem: &mut [u8],
        start: usize,
        win: usize,
        mailbox: bool,
        off: usize,
        op: SmOp<'_>,
    ) -> Outcome {
        let len = match &op {
            SmOp::Read(b) => b.len(),
            SmOp::Write(d) => d.len(),
        };
        let covers_last = off + len >= win;
        let event = if mailbox {
            match mem.get_mut(start + off..start + off + len) {
                Some(area) => self.mailbox_access(area, covers_last, op),
                None => Err(()),
            }
        } else if self.bufs[0].len() < win {
            Err(())
        } else {
            Ok(self.buffered_access(off..off + len, covers_last, op))
        };
        match event {
            Ok(event) => Outcome {
                accepted: true,
                event,
            },
            Err(()) => Outcome {
                accepted: false,
                event: None,
            },
        }
    }

    /// Mailbox mode: `area` is the accessed part of the buffer in process RAM; a
    /// write while full or a read while empty is refused (`Err`).
    fn mailbox_access(
        &mut self,
        area: &mut [u8],
        covers_last: bool,
        op: SmOp<'_>,
    ) -> Result<Option<Event>, ()> {
        match op {
            SmOp::Write(d) => {
                if self.full {
                    return Err(());
                }
                self.irq_read = false;
                area.copy_from_slice(d);
                if covers_last {
                    self.full = true;
                    self.irq_write = true;
                    return Ok(Some(Event::Written));
                }
            }
            SmOp::Read(b) => {
                if !self.full {
                    return Err(());
                }
                self.irq_write = false;
                b.copy_from_slice(area);
                if covers_last {
                    self.full = false;
                    self.irq_read = true;
                    return Ok(Some(Event::Read));
                }
            }
        }
        Ok(None)
    }

    /// Buffered mode: `range` inside the producer's free buffer (write) or the
    /// consumer's newest complete one (read).
    fn buffered_access(
        &mut self,
        range: std::ops::Range<usize>,
        covers_last: bool,
        op: SmOp<'_>,
    ) -> Option<Event> {
        match op {
            SmOp::Write(d) => {
                let k = match self.producer_open {
                    Some(k) => k,
                    None => {
                        let k = self.free_buffer();
                        self.producer_open = Some(k);
                        self.irq_read = false;
                        k
                    }
                };
                self.bufs[k][range].copy_from_slice(d);
                if covers_last {
                    self.latest = Some(k);
                    self.producer_open = None;
                    self.irq_write = true;
                    return Some(Event::Written);
                }
            }
            SmOp::Read(b) => {
                let k = self.consumer_buffer();
                if self.consumer_open.is_none() {
                    self.irq_write = false;
                }
                self.consumer_open = Some(k);
                b.copy_from_slice(&self.bufs[k][range]);
                if covers_last {
                    self.consumer_open = None;
                    self.irq_read = true;
                    return Some(Event::Read);
                }
            }
        }
        None
    }
}
