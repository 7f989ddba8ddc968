//! The scope: a trace buffer in RAM that records up to [`CHANNELS`] signals of the
//! drive on its own clock, started by a level or an edge of one of them, with
//! pre-trigger samples — the commissioning oscilloscope of a servo drive, configured
//! and read over SDO.
//!
//! # Objects (0x2500-0x2510)
//!
//! | object | what |
//! |---|---|
//! | 0x2500 | configuration: sample divisor, trigger channel, level, condition, pre-trigger samples, mode, command |
//! | 0x2501 | channels: an ARRAY of UNSIGNED32 `index << 16 \| sub << 8 \| bits`, as a PDO mapping entry; `:00` is the number of channels |
//! | 0x2502 | status: state, samples recorded, trigger position, samples per channel, records completed |
//! | 0x2503 | data: the record in blocks of [`BLOCK_BYTES`] (OCTET_STRING, segmented upload) |
//! | 0x2510 | internal signals the dictionary has no object for (mappable like any object) |
//!
//! A channel is any PDO-mappable entry (Rx or Tx) of at most 32 bits. A channel that
//! is not mappable or too wide is refused with 0x06040041, a bit length other than
//! the entry's with 0x06040043 (the rules of a PDO mapping entry). Configuration
//! writes while the scope records are refused with 0x08000022; the command (0x2500:07)
//! is always accepted. Arming checks the configuration as a whole: no channel, a
//! trigger channel beyond the channels, or pre-trigger samples not below the samples
//! per channel are refused with 0x06040043.
//!
//! # Sampling
//!
//! The supervision tick (`Drive::tick`, every `drive::TICK_US` = 1 ms on the
//! board, in every ESM state) takes one sample every `divisor` ticks while the scope is
//! armed or triggered: each channel read as the TxPDO would read it (the CiA 402
//! objects through their slots, the others through the dictionary read), sign- or
//! zero-extended from the entry's length to 32 bits and stored as `i32` (UNSIGNED32
//! values above `i32::MAX` wrap). The master's cycle never samples: its instruction
//! budget is for the set-points. Disarmed, the tick pays one test of [`Scope::running`].
//!
//! With the servo period as time base (0x2500:08 = 1) the control path hands the
//! drive one [`ServoPoint`] per servo period (100 µs) through a [`PointRing`]: the
//! internal signals of 0x2510 as the motion layer and the current loop had them in
//! that period. Every `divisor`-th point is a sample: the 0x2510 channels from the
//! point ([`internal_signal`]), the other channels as the drive's objects stand (they
//! change at its tick). The drive takes the queued points at each tick.
//!
//! The buffer holds [`BUFFER_WORDS`] values: `BUFFER_WORDS / n` samples per channel
//! with `n` channels (768 with one, 96 with eight).
//!
//! # Trigger
//!
//! Armed, the scope fills its ring continuously and looks for the trigger on the
//! trigger channel's value `v` (the previous sample `p`, level `L`):
//!
//! | 0x2500:04 | condition |
//! |---|---|
//! | 0 | immediate (the first sample that may trigger) |
//! | 1 | rising edge: `p < L ≤ v` |
//! | 2 | falling edge: `p > L ≥ v` |
//! | 3 | either edge |
//! | 4 | level: `v ≥ L` |
//! | 5 | level: `v ≤ L` |
//!
//! A trigger is taken only once the ring holds the pre-trigger samples, so a record
//! has exactly `pre` samples before the trigger sample; the force command
//! (0x2500:07 = 2) triggers at the next sample whatever the condition and the fill,
//! and then the record may start later than `pre` samples before it. After the
//! trigger the scope records `depth − pre` samples (the trigger sample included), then
//! the record is done: `min(recorded, depth)` samples, the trigger at
//! `samples − (depth − pre)`.
//!
//! Mode 0 (single): done stays done until the next arm. Mode 1 (normal): once the
//! master has read the last block of the record, the scope re-arms itself with the
//! same channels and trigger, and 0x2502:05 counts the records.
//!
//! # Record
//!
//! 0x2503:k holds bytes `512·(k−1)` to `512·k` of the record: the samples oldest
//! first, each sample the `n` channel values as `i32` little-endian in channel order.
//! The last block is shorter; blocks past the end, and every block while no record is
//! done, answer 0x08000024 (no data available).

use ecat_slave_stack::od::{
    self, Access, DataType, EntryDesc, Object, ObjectKey, PdoMappable, SdoAbort,
};

use crate::bind::bound_objects;

/// Channels of one record at most.
pub const CHANNELS: usize = 8;
/// Values the buffer holds (`i32`, 3 KiB; BENCHMARKS.md "Images" for the RAM budget).
pub const BUFFER_WORDS: usize = 768;
/// Bytes of one block of 0x2503 (one segmented SDO upload; at most the SDO server's
/// transfer buffer).
pub const BLOCK_BYTES: usize = 512;
/// Blocks of 0x2503.
pub const BLOCKS: usize = BUFFER_WORDS * 4 / BLOCK_BYTES;

const _: () = assert!(BLOCK_BYTES <= ecat_slave_stack::coe::sdo::TRANSFER_MAX);
const _: () = assert!(BLOCKS == 6, "0x2503 describes six blocks");

/// 0x2500, the configuration.
pub const CONFIG: u16 = 0x2500;
/// 0x2501, the channels.
pub const CHANNEL_LIST: u16 = 0x2501;
/// 0x2502, the status.
pub const STATUS: u16 = 0x2502;
/// 0x2503, the data.
pub const DATA: u16 = 0x2503;
/// 0x2510, the internal signals (values served by the drive).
pub const SIGNALS: u16 = 0x2510;

/// 0x2500:07 commands.
pub mod command {
    /// Stop: back to idle (a done record is dropped).
    pub const STOP: u8 = 0;
    /// Arm (again): a new record with the present configuration.
    pub const ARM: u8 = 1;
    /// Trigger at the next sample (while armed).
    pub const FORCE: u8 = 2;
}

/// A read-write configuration entry.
const fn rw(sub: u8, name: &'static str, t: DataType, def: i64, min: i64, max: i64) -> EntryDesc {
    EntryDesc::new(sub, name, t, Access::RW)
        .range(min, max)
        .default(def)
}

const fn ro(sub: u8, name: &'static str, t: DataType) -> EntryDesc {
    EntryDesc::new(sub, name, t, Access::RO)
}

const fn channel(sub: u8, name: &'static str, def: u32) -> EntryDesc {
    EntryDesc::new(sub, name, DataType::Unsigned32, Access::RW).default(def as i64)
}

const fn signal(sub: u8, name: &'static str, t: DataType, unit: &'static str) -> EntryDesc {
    EntryDesc::new(sub, name, t, Access::RO)
        .pdo(PdoMappable::Tx)
        .unit(unit)
}

use DataType::{
    Integer16 as I16, Integer32 as I32, Unsigned16 as U16, Unsigned32 as U32, Unsigned8 as U8,
};

// The scope's objects and their values (those of 0x2510 are the drive's, see `Drive`):
// configuration writes follow the scope's rules (module docs).
bound_objects! {
    impl Values<()> for Scope, bytes by Scope::data_bytes;
    record CONFIG, "Scope configuration", "Scope: sub 1 sample every n time-base periods; 2 trigger channel (0x2501 sub); 3 trigger level; 4 condition 0 immediate, 1 rising, 2 falling, 3 either edge, 4 value >= level, 5 value <= level; 5 samples kept before the trigger; 6 mode 0 single, 1 normal (re-arms after the record was read); 7 command 0 stop, 1 arm, 2 force trigger; 8 time base 0 supervision tick (1 ms), 1 servo period (100 us: the internal signals 0x2510 at that rate, the other channels as the last tick left them)", {
        EntryDesc::count(8) => count;
        rw(1, "Sample divisor", U16, 1, 1, 1000)
            => get |s| s.divisor, set |s, v| s.idle()?.divisor = v as u16;
        rw(2, "Trigger channel", U8, 1, 1, CHANNELS as i64)
            => get |s| s.trigger_channel, set |s, v| s.idle()?.trigger_channel = v as u8;
        rw(3, "Trigger level", I32, 0, i32::MIN as i64, i32::MAX as i64)
            => get |s| s.level, set |s, v| s.idle()?.level = v as i32;
        rw(4, "Trigger condition", U8, 1, 0, 5)
            => get |s| s.condition, set |s, v| s.idle()?.condition = v as u8;
        rw(5, "Pre-trigger samples", U16, 0, 0, BUFFER_WORDS as i64 - 1)
            => get |s| s.pretrigger, set |s, v| s.idle()?.pretrigger = v as u16;
        rw(6, "Trigger mode", U8, 0, 0, 1)
            => get |s| s.normal, set |s, v| s.idle()?.normal = v == 1;
        rw(7, "Command", U8, 0, 0, 2)
            => get |s| s.running(), set |s, v| s.command(v as u8);
        rw(8, "Time base", U8, 0, 0, 1)
            => get |s| s.servo_rate, set |s, v| s.idle()?.servo_rate = v == 1;
    }
    array CHANNEL_LIST, "Scope channels", "Signals recorded: index << 16 | sub-index << 8 | bit length of a PDO-mappable entry of at most 32 bits (0x2510 for the internal signals); sub 0 the number of channels", {
        EntryDesc::new(0, "Number of entries", U8, Access::RW)
            .range(0, CHANNELS as i64)
            .default(2)
            => get |s| s.count, set |s, v| s.idle()?.count = v as u8;
        channel(1, "Channel 1", 0x6064_0020) => get |s| s.channels[0], set |s, v| s.set_channel(0, v);
        channel(2, "Channel 2", 0x60F4_0020) => get |s| s.channels[1], set |s, v| s.set_channel(1, v);
        channel(3, "Channel 3", 0x606C_0020) => get |s| s.channels[2], set |s, v| s.set_channel(2, v);
        channel(4, "Channel 4", 0x6078_0010) => get |s| s.channels[3], set |s, v| s.set_channel(3, v);
        channel(5, "Channel 5", 0x2301_0010) => get |s| s.channels[4], set |s, v| s.set_channel(4, v);
        channel(6, "Channel 6", 0x2303_0010) => get |s| s.channels[5], set |s, v| s.set_channel(5, v);
        channel(7, "Channel 7", 0x2305_0010) => get |s| s.channels[6], set |s, v| s.set_channel(6, v);
        channel(8, "Channel 8", 0x2510_0120) => get |s| s.channels[7], set |s, v| s.set_channel(7, v);
    }
    record STATUS, "Scope status", "Scope: sub 1 state 0 idle, 1 armed, 2 triggered, 3 done; 2 samples per channel in the record; 3 sample number of the trigger (oldest = 0); 4 samples per channel the buffer holds (of the record being or last recorded); 5 records completed (wrapping)", {
        EntryDesc::count(5) => count;
        ro(1, "State", U8) => get |s| s.state as u8;
        ro(2, "Samples recorded", U16) => get |s| match s.state {
            State::Idle => 0,
            _ => s.stored,
        };
        ro(3, "Trigger position", U16) => get |s| s.trigger_position();
        ro(4, "Samples per channel", U16) => get |s| s.depth;
        ro(5, "Records completed", U16) => get |s| s.records;
    }
    array DATA, "Scope data", "The done record, 512 bytes per sub-index: samples oldest first, each the channels' values as INTEGER32 little-endian in channel order; the last block is shorter; no record or a block past its end: abort 0x08000024", {
        EntryDesc::count(BLOCKS as u8) => count;
        EntryDesc::octets(1, "Block 1", BLOCK_BYTES as u16) => bytes;
        EntryDesc::octets(2, "Block 2", BLOCK_BYTES as u16) => bytes;
        EntryDesc::octets(3, "Block 3", BLOCK_BYTES as u16) => bytes;
        EntryDesc::octets(4, "Block 4", BLOCK_BYTES as u16) => bytes;
        EntryDesc::octets(5, "Block 5", BLOCK_BYTES as u16) => bytes;
        EntryDesc::octets(6, "Block 6", BLOCK_BYTES as u16) => bytes;
    }
    record SIGNALS, "Scope internal signals", "Signals without an object of their own, also at the servo rate (0x2500:08 = 1): sub 1 servo demand minus encoder, encoder counts; 2 acceleration feed-forward of the demand; 3 DC bus voltage; 4 bit 0 power stage on, bit 1 drive function enabled, bit 2 at the current limit, bit 3 brake released; 5 position, 6 velocity of the motor side, command units; 7 q current demand, 8 q current actual, per mille of the rated current; 9, 10 phase currents", {
        EntryDesc::count(10) => count;
        signal(1, "Motor following error", I32, "") => elsewhere;
        signal(2, "Acceleration demand", I32, "inc/s²") => elsewhere;
        signal(3, "Bus voltage", U32, "mV") => elsewhere;
        signal(4, "Drive flags", U16, "") => elsewhere;
        signal(5, "Motor position", I32, "inc") => elsewhere;
        signal(6, "Motor velocity", I32, "inc/s") => elsewhere;
        signal(7, "Current demand", I16, "0.1 %") => elsewhere;
        signal(8, "Current actual", I16, "0.1 %") => elsewhere;
        signal(9, "Phase A current", I16, "mA") => elsewhere;
        signal(10, "Phase B current", I16, "mA") => elsewhere;
    }
}

/// What the scope is doing (0x2502:01).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum State {
    /// Not recording; no record.
    Idle = 0,
    /// Recording into the ring, waiting for the trigger.
    Armed = 1,
    /// Triggered, recording the samples after the trigger.
    Triggered = 2,
    /// A record is ready in 0x2503.
    Done = 3,
}

/// Where a channel's value comes from, resolved once when the scope is armed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Source {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// The CiA 402 TxPDO slot of the entry ([`crate::cia402::objects::tx_slot`]), if it
    /// has one: read without the dictionary lookup.
    pub slot: Option<u8>,
    bits: u8,
    signed: bool,
}

impl Source {
    const NONE: Source = Source {
        index: 0,
        sub: 0,
        slot: None,
        bits: 32,
        signed: false,
    };

    /// The source of channel value `v` (`index << 16 | sub << 8 | bits`) in the
    /// dictionary `objects`: the PDO mapping rules (0x06040041 not mappable or wider than 32 bits, 0x06040043 a
    /// length other than the entry's).
    pub fn resolve(objects: &'static [Object], v: u32) -> Result<Source, SdoAbort> {
        let key = ObjectKey::from_mapping_word(v);
        let ObjectKey { index, sub } = key;
        let bits = v as u8;
        let e = od::find_entry(objects, key).map_err(|_| SdoAbort::NotMappable)?;
        if e.pdo_mappable() == PdoMappable::No || e.bits() == 0 || e.bits() > 32 {
            return Err(SdoAbort::NotMappable);
        }
        if e.bits() != u16::from(bits) {
            return Err(SdoAbort::ParameterIncompatibility);
        }
        Ok(Source {
            index,
            sub,
            slot: crate::cia402::objects::tx_slot(index, sub),
            bits,
            signed: e.data_type.is_signed(),
        })
    }

    /// The value of the entry's little-endian image `raw` (its low `bits`), sign- or
    /// zero-extended to 32 bits.
    #[inline]
    pub fn decode(&self, raw: u32) -> i32 {
        let shift = 32 - u32::from(self.bits.clamp(1, 32));
        if self.signed {
            ((raw << shift) as i32) >> shift
        } else {
            ((raw << shift) >> shift) as i32
        }
    }
}

/// Whether the trigger condition `cond` (0x2500:04) holds for the sample `v` after
/// `prev` (none: the first sample of the record) at level `level`.
pub fn condition_met(cond: u8, prev: Option<i32>, v: i32, level: i32) -> bool {
    let rising = prev.is_some_and(|p| p < level && v >= level);
    let falling = prev.is_some_and(|p| p > level && v <= level);
    match cond {
        0 => true,
        1 => rising,
        2 => falling,
        3 => rising || falling,
        4 => v >= level,
        _ => v <= level,
    }
}

/// The scope: configuration, state and the buffer.
pub struct Scope {
    /// The dictionary the channels are resolved in.
    objects: &'static [Object],
    divisor: u16,
    trigger_channel: u8,
    level: i32,
    condition: u8,
    pretrigger: u16,
    normal: bool,
    /// 0x2500:08: samples at the servo rate (`true`) or on the tick.
    servo_rate: bool,
    count: u8,
    channels: [u32; CHANNELS],
    state: State,
    /// The record being (or last) recorded: its sources, channels, samples per
    /// channel, and samples from the trigger to the end.
    sources: [Source; CHANNELS],
    n: u8,
    depth: u16,
    post: u16,
    /// The trigger of the running record: channel (0-based), level, condition,
    /// pre-trigger samples.
    run_trigger: (u8, i32, u8, u16),
    /// Ticks until the next sample.
    wait: u16,
    run_divisor: u16,
    /// Ring position of the next sample, samples in the ring, samples still to record
    /// after the trigger.
    head: u16,
    stored: u16,
    post_left: u16,
    prev: Option<i32>,
    force: bool,
    records: u16,
    buf: [i32; BUFFER_WORDS],
}

/// The default of entry `sub` of `index` in [`OBJECTS`] (compile time).
const fn default_of(index: u16, sub: u8) -> i64 {
    let mut o = 0;
    while o < OBJECTS.len() {
        if OBJECTS[o].index == index {
            let entries = OBJECTS[o].entries();
            let mut e = 0;
            while e < entries.len() {
                if entries[e].sub() == sub {
                    if let od::DefaultValue::Int(v) = entries[e].default_value() {
                        return v;
                    }
                }
                e += 1;
            }
        }
        o += 1;
    }
    panic!("no default in the scope table");
}

/// The default channels of 0x2501.
const fn default_channels() -> [u32; CHANNELS] {
    let mut c = [0u32; CHANNELS];
    let mut k = 0;
    while k < CHANNELS {
        c[k] = default_of(CHANNEL_LIST, k as u8 + 1) as u32;
        k += 1;
    }
    c
}

/// The table's defaults, evaluated at compile time (the power-up writes constants).
const DEF_DIVISOR: u16 = default_of(CONFIG, 1) as u16;
const DEF_TRIGGER_CHANNEL: u8 = default_of(CONFIG, 2) as u8;
const DEF_LEVEL: i32 = default_of(CONFIG, 3) as i32;
const DEF_CONDITION: u8 = default_of(CONFIG, 4) as u8;
const DEF_PRETRIGGER: u16 = default_of(CONFIG, 5) as u16;
const DEF_NORMAL: bool = default_of(CONFIG, 6) == 1;
const DEF_COUNT: u8 = default_of(CHANNEL_LIST, 0) as u8;
const DEF_CHANNELS: [u32; CHANNELS] = default_channels();

impl Scope {
    /// Idle, at the defaults of the table; channels are entries of `objects` (the
    /// drive's dictionary).
    pub const fn new(objects: &'static [Object]) -> Self {
        Scope {
            objects,
            divisor: DEF_DIVISOR,
            trigger_channel: DEF_TRIGGER_CHANNEL,
            level: DEF_LEVEL,
            condition: DEF_CONDITION,
            pretrigger: DEF_PRETRIGGER,
            normal: DEF_NORMAL,
            servo_rate: false,
            count: DEF_COUNT,
            channels: DEF_CHANNELS,
            state: State::Idle,
            sources: [Source::NONE; CHANNELS],
            n: 0,
            depth: 0,
            post: 0,
            run_trigger: (0, 0, 0, 0),
            wait: 0,
            run_divisor: 1,
            head: 0,
            stored: 0,
            post_left: 0,
            prev: None,
            force: false,
            records: 0,
            buf: [0; BUFFER_WORDS],
        }
    }

    /// State (0x2502:01).
    pub fn state(&self) -> State {
        self.state
    }

    /// Armed or triggered: the tick samples ([`Scope::sample_due`]).
    #[inline(always)]
    pub fn running(&self) -> bool {
        matches!(self.state, State::Armed | State::Triggered)
    }

    /// Running at the servo rate (0x2500:08 = 1): the samples come from the control
    /// path's [`ServoPoint`]s, not from the tick.
    #[inline(always)]
    pub fn at_servo_rate(&self) -> bool {
        self.servo_rate && self.running()
    }

    /// Counts one period of the time base of the running scope; true when this one
    /// takes a sample (every `divisor`-th, the first after arming included).
    pub fn sample_due(&mut self) -> bool {
        if self.wait > 1 {
            self.wait -= 1;
            false
        } else {
            self.wait = self.run_divisor;
            true
        }
    }

    /// The sources of the running record's channels, in channel order.
    pub fn sources(&self) -> &[Source] {
        &self.sources[..usize::from(self.n)]
    }

    /// Samples per channel of the running (or last) record.
    pub fn depth(&self) -> u16 {
        self.depth
    }

    /// Stores one sample (`values`: one per channel, as [`Scope::sources`]) and
    /// advances the trigger: armed → triggered → done.
    pub fn record(&mut self, values: &[i32]) {
        if !self.running() {
            return;
        }
        let n = usize::from(self.n);
        let depth = self.depth;
        let at = usize::from(self.head) * n;
        if let (Some(dst), Some(src)) = (self.buf.get_mut(at..at + n), values.get(..n)) {
            dst.copy_from_slice(src);
        }
        self.head = if self.head + 1 >= depth {
            0
        } else {
            self.head + 1
        };
        self.stored = (self.stored + 1).min(depth);
        if self.state == State::Armed {
            let (ch, level, cond, pre) = self.run_trigger;
            let v = values.get(usize::from(ch)).copied().unwrap_or(0);
            let hit = self.force || (self.stored > pre && condition_met(cond, self.prev, v, level));
            self.prev = Some(v);
            if !hit {
                return;
            }
            self.state = State::Triggered;
            self.post_left = self.post;
        }
        self.post_left = self.post_left.saturating_sub(1);
        if self.post_left == 0 {
            self.state = State::Done;
            self.records = self.records.wrapping_add(1);
        }
    }

    /// Starts a record with the present configuration (0x2500:07 = 1).
    fn arm(&mut self) -> Result<(), SdoAbort> {
        let n = self.count;
        if n == 0 || self.trigger_channel > n {
            return Err(SdoAbort::ParameterIncompatibility);
        }
        let depth = (BUFFER_WORDS / usize::from(n)) as u16;
        if self.pretrigger >= depth {
            return Err(SdoAbort::ParameterIncompatibility);
        }
        let mut sources = [Source::NONE; CHANNELS];
        for (s, &v) in sources.iter_mut().zip(&self.channels[..usize::from(n)]) {
            *s = Source::resolve(self.objects, v)?;
        }
        self.sources = sources;
        self.n = n;
        self.depth = depth;
        self.post = depth - self.pretrigger;
        self.run_trigger = (
            self.trigger_channel - 1,
            self.level,
            self.condition,
            self.pretrigger,
        );
        self.run_divisor = self.divisor;
        self.restart();
        Ok(())
    }

    /// A new record with the armed record's channels and trigger.
    fn restart(&mut self) {
        self.wait = 0;
        self.head = 0;
        self.stored = 0;
        self.post_left = 0;
        self.prev = None;
        self.force = false;
        self.state = State::Armed;
    }

    /// Bytes of the done record.
    fn record_bytes(&self) -> usize {
        usize::from(self.stored) * usize::from(self.n) * 4
    }

    /// Sample number of the trigger in the record (oldest = 0).
    fn trigger_position(&self) -> u16 {
        match self.state {
            State::Done => self.stored.saturating_sub(self.post),
            _ => 0,
        }
    }

    /// Block `sub` (1-based) of the done record into `buf`: the bytes `BLOCK_BYTES ·
    /// (sub − 1)` onwards, at most one block.
    fn read_block(&self, sub: u8, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        let total = self.record_bytes();
        let start = usize::from(sub.saturating_sub(1)) * BLOCK_BYTES;
        if self.state != State::Done || start >= total {
            return Err(SdoAbort::NoDataAvailable);
        }
        let len = (total - start).min(BLOCK_BYTES);
        let out = buf.get_mut(..len).ok_or(SdoAbort::ExceedsMailbox)?;
        let (n, depth) = (usize::from(self.n), usize::from(self.depth));
        let oldest = (usize::from(self.head) + depth - usize::from(self.stored)) % depth;
        for (k, dst) in out.chunks_exact_mut(4).enumerate() {
            let w = start / 4 + k;
            let sample = (oldest + w / n) % depth;
            let v = self.buf.get(sample * n + w % n).copied().unwrap_or(0);
            dst.copy_from_slice(&v.to_le_bytes());
        }
        Ok(len)
    }

    /// After an SDO read of 0x2503:`sub`: in normal mode, the last block of the
    /// record read re-arms the scope.
    pub fn block_read(&mut self, sub: u8) {
        let end = usize::from(sub) * BLOCK_BYTES;
        let total = self.record_bytes();
        if self.normal && self.state == State::Done && end >= total && end < total + BLOCK_BYTES {
            self.restart();
        }
    }
}

/// The record's blocks (0x2503:01-06); the numbers are bound in the table.
impl Scope {
    /// SDO read of a block of 0x2503 (the bytes the dictionary answers the read with).
    fn data_bytes(
        &self,
        _: &(),
        key: ObjectKey,
        buf: &mut [u8],
    ) -> Option<Result<usize, SdoAbort>> {
        (key.index == DATA && key.sub > 0).then(|| self.read_block(key.sub, buf))
    }
}

impl Scope {
    /// The scope for a configuration write: refused while it records.
    #[inline(never)]
    fn idle(&mut self) -> Result<&mut Self, SdoAbort> {
        if self.running() {
            return Err(SdoAbort::StateConflict);
        }
        Ok(self)
    }

    /// 0x2501:`n + 1` = `v`: a source the dictionary has, while idle.
    fn set_channel(&mut self, n: usize, v: i64) -> Result<(), SdoAbort> {
        let s = self.idle()?;
        Source::resolve(s.objects, v as u32)?;
        s.channels[n] = v as u32;
        Ok(())
    }

    /// 0x2500:07.
    fn command(&mut self, c: u8) -> Result<(), SdoAbort> {
        match c {
            command::STOP => {
                self.state = State::Idle;
                Ok(())
            }
            command::ARM => self.arm(),
            _ if self.running() => {
                self.force = true;
                Ok(())
            }
            _ => Err(SdoAbort::StateConflict),
        }
    }
}

mod servo;
pub use servo::{internal_signal, PointRing, ServoPoint};

#[cfg(test)]
mod tests;
