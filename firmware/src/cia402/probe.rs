//! Touch probe (0x60B8 function, 0x60B9 status, 0x60BA-0x60BD latched positions).
//!
//! Two channels. Each latches the position of its trigger — the channel's digital input
//! (probe 1: input 1, probe 2: input 2; the positions are latched by hardware and
//! reported in [`super::DriveFeedback`]; probe 1 also takes the edges of any input
//! assigned the function "probe", 0x2152 bit 5, latched at the drive's 1 ms tick) or
//! the encoder index pulse — on the rising
//! and/or falling edge, once ("first event") or on every event ("continuous"). Values
//! and status bits change in the very cycle in which the event is reported.
//!
//! 0x60B8 per channel (channel 2 = bits 8-15): bit 0 enable, bit 1 continuous, bits 2-3
//! trigger source (00 input, 01 index pulse; 10/11 are not supported), bit 4 latch the
//! rising edge, bit 5 latch the falling edge.
//! 0x60B9 per channel: bit 0 enabled, bit 1 rising value stored, bit 2 falling value
//! stored, bits 6 / 7 toggle on every new rising / falling value in continuous mode.
//! A single-event edge is re-armed by switching the channel off and on or by setting
//! its edge bit (4 or 5) from 0 to 1.

/// Positions latched by hardware on the edges of one input during the last cycle (raw,
/// motor-side command units).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EdgeLatch {
    /// Position at a rising edge.
    pub rising: Option<i32>,
    /// Position at a falling edge.
    pub falling: Option<i32>,
}

impl EdgeLatch {
    /// This latch with position `p` at a rising (`rising`) or falling edge where it
    /// has none yet.
    pub fn or(self, rising: bool, p: i32) -> Self {
        self.merge(if rising {
            EdgeLatch {
                rising: Some(p),
                falling: None,
            }
        } else {
            EdgeLatch {
                rising: None,
                falling: Some(p),
            }
        })
    }
    /// Per edge, this latch's position, else `other`'s.
    pub fn merge(self, other: Self) -> Self {
        EdgeLatch {
            rising: self.rising.or(other.rising),
            falling: self.falling.or(other.falling),
        }
    }
}

/// Touch-probe state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TouchProbe {
    function: u16,
    prev_function: u16,
    status: u16,
    values: [i32; 4],
}

/// True when `f` (0x60B8) uses a trigger source this drive does not have.
pub const fn function_valid(f: u16) -> bool {
    // Bit 3 / bit 11 (source via 0x60D0) and the reserved bits 6-7 / 14-15 are unsupported.
    f & 0xC8C8 == 0
}

impl TouchProbe {
    /// 0x60B8.
    pub fn function(&self) -> u16 {
        self.function
    }
    /// 0x60B9.
    pub fn status(&self) -> u16 {
        self.status
    }
    /// 0x60BA + `i` (0 = probe 1 rising, 1 = probe 1 falling, 2 = probe 2 rising,
    /// 3 = probe 2 falling).
    pub fn value(&self, i: usize) -> i32 {
        self.values.get(i).copied().unwrap_or(0)
    }
    /// Writes 0x60B8 (takes effect in the next [`TouchProbe::update`]).
    pub fn set_function(&mut self, f: u16) {
        self.function = f;
    }

    /// Processes one cycle. `to_user` converts a raw latched position to user units.
    pub fn update(
        &mut self,
        input1: EdgeLatch,
        input2: EdgeLatch,
        index: Option<i32>,
        to_user: impl Fn(i32) -> i32,
    ) {
        let f = if function_valid(self.function) {
            self.function
        } else {
            0
        };
        for ch in 0..2 {
            let shift = 8 * ch;
            let cf = (f >> shift) & 0xFF;
            let pf = (self.prev_function >> shift) & 0xFF;
            let mut st = (self.status >> shift) & 0xFF;
            if cf & 1 == 0 {
                st = 0;
            } else {
                if pf & 1 == 0 {
                    st = 0;
                }
                st |= 1;
                // Re-arm edges whose enable bit rose.
                if cf & 0x10 != 0 && pf & 0x10 == 0 {
                    st &= !0x02;
                }
                if cf & 0x20 != 0 && pf & 0x20 == 0 {
                    st &= !0x04;
                }
                let continuous = cf & 0x02 != 0;
                let (rise, fall) = if cf & 0x04 != 0 {
                    (index, index)
                } else if ch == 0 {
                    (input1.rising, input1.falling)
                } else {
                    (input2.rising, input2.falling)
                };
                if cf & 0x10 != 0 {
                    if let Some(p) = rise {
                        if continuous || st & 0x02 == 0 {
                            self.values[2 * ch] = to_user(p);
                            if continuous && st & 0x02 != 0 {
                                st ^= 0x40;
                            }
                            st |= 0x02;
                        }
                    }
                }
                if cf & 0x20 != 0 {
                    if let Some(p) = fall {
                        if continuous || st & 0x04 == 0 {
                            self.values[2 * ch + 1] = to_user(p);
                            if continuous && st & 0x04 != 0 {
                                st ^= 0x80;
                            }
                            st |= 0x04;
                        }
                    }
                }
            }
            self.status = (self.status & !(0xFF << shift)) | (st << shift);
        }
        self.prev_function = f;
    }
}
