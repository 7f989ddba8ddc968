//! A master played with raw datagrams: the building blocks (single-datagram frames,
//! SII reads through 0x0502, AL control, expedited and normal CoE SDO transfers, FoE
//! reads and writes through the mailbox SyncManagers) from which tests replay a real
//! master's start-up register by register (`tests/master_startup.rs`) or update a
//! drive's firmware (`tests/firmware_update.rs`, `tests/virtual_drive_update_veth.rs`).
//!
//! [`Master`] holds the protocol; every frame goes through a [`Transport`]:
//! * [`SegmentTransport`], a simulated [`Segment`] in the same process ([`RawMaster`]):
//!   every frame goes through [`Segment::process`] (so the slaves poll after each
//!   datagram, as with a real master whose frames are a few µs apart); `after` runs
//!   after every frame and every time step (e.g. the product drive's housekeeping).
//!   Time is simulated: waits advance the segment.
//! * [`SocketTransport`], real Ethernet frames on a network interface through an
//!   AF_PACKET [`RawSocket`] (e.g. `virtual-drive` behind a veth pair,
//!   [`SocketMaster`]): each exchange waits a bounded time for its frame to come
//!   back. Time is the wall clock: waits sleep.
//!
//! With [`Master::cyclic`] set, an LRW over the process image goes out at every cycle
//! boundary the transport's clock crosses, also while an SDO transfer waits — as a
//! real master's cyclic task keeps running beside its mailbox traffic.

use std::ops::{Deref, DerefMut};
use std::time::Duration;

use crate::esc_sim::frame::{datagrams, Command, DatagramView, FrameBuilder};
use crate::raw_socket::OpenError;
use crate::segment::Segment;
use ecat_slave_stack::slave::SlaveApplication;

mod transport;

pub use transport::{SegmentTransport, SocketTransport, Transport};

/// SDO abort code or a transport failure (no answer, wrong working counter).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SdoError {
    /// The slave answered with an abort.
    Abort(u32),
    /// No (valid) answer.
    Transport(String),
}

/// How an FoE transfer of a [`RawMaster`] ended badly.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FoeError {
    /// The slave answered ERR with this code.
    Err(u32),
    /// No (valid) answer, or an unexpected one.
    Transport(String),
}

/// Counts of a successful FoE write.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FoeStats {
    /// DATA packets acknowledged.
    pub packets: u32,
    /// BUSY answers (each followed by the same DATA again).
    pub busy: u32,
    /// Frames the transfer took.
    pub frames: u64,
}

/// The cyclic process-data exchange of a [`RawMaster`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cyclic {
    /// Cycle, ns.
    pub period_ns: u64,
    /// Time of the next LRW on the transport's clock, ns.
    pub next_ns: u64,
    /// Bytes of the LRW at logical address 0 (outputs and inputs).
    pub len: usize,
    /// LRWs sent.
    pub sent: u64,
    /// LRWs with working counter `wkc`.
    pub good: u64,
    /// Expected working counter.
    pub wkc: u16,
    /// Most bytes per LRW frame (a longer image goes out as several LRWs in a row,
    /// each expecting its share of `wkc`; choose it so that the frames split the
    /// image at slave boundaries). 0: one LRW.
    pub chunk: usize,
}

/// Raw-datagram master over a [`Transport`]. It dereferences to its transport: the
/// segment of a [`RawMaster`] is `m.seg`, its hook `m.after`.
pub struct Master<T> {
    /// How the frames travel.
    pub link: T,
    counter: u8,
    /// SM0 (out) and SM1 (in) start and length of the standard mailbox.
    pub mbx: (u16, u16, u16, u16),
    /// Frames sent.
    pub frames: u64,
    /// Cyclic process data (None: off).
    pub cyclic: Option<Cyclic>,
}

/// Raw-datagram master of one simulated segment.
pub type RawMaster<A> = Master<SegmentTransport<A>>;

/// Raw-datagram master on a real network interface.
pub type SocketMaster = Master<SocketTransport>;

impl<T> Deref for Master<T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.link
    }
}

impl<T> DerefMut for Master<T> {
    fn deref_mut(&mut self) -> &mut T {
        &mut self.link
    }
}

fn nothing<A: SlaveApplication>(_: &mut Segment<A>) {}

impl<A: SlaveApplication> Master<SegmentTransport<A>> {
    /// A master on `seg`.
    pub fn new(seg: Segment<A>) -> Self {
        Master::over(SegmentTransport {
            seg,
            after: nothing::<A>,
        })
    }
}

impl Master<SocketTransport> {
    /// A master on the interface `iface` (raw socket: root or CAP_NET_RAW); each
    /// frame is waited for up to `timeout`.
    pub fn open(iface: &str, timeout: Duration) -> Result<Self, OpenError> {
        SocketTransport::open(iface, timeout).map(Master::over)
    }
}

impl<T: Transport> Master<T> {
    /// A master whose frames go through `link`.
    pub fn over(link: T) -> Self {
        Master {
            link,
            counter: 0,
            mbx: (0x1000, 128, 0x1080, 128),
            frames: 0,
            cyclic: None,
        }
    }

    /// One frame through the transport (counted); its datagrams as they came back
    /// (none when the frame did not come back).
    fn frame(&mut self, fb: FrameBuilder) -> Vec<DatagramView> {
        let back = self.link.exchange(&fb.build());
        self.frames += 1;
        back.and_then(|f| datagrams(&f)).unwrap_or_default()
    }

    /// Starts the cyclic LRW of `len` bytes every `period_ns` (first one now).
    pub fn start_cyclic(&mut self, period_ns: u64, len: usize, wkc: u16) {
        self.cyclic = Some(Cyclic {
            period_ns: period_ns.max(1),
            next_ns: self.link.now_ns(),
            len,
            sent: 0,
            good: 0,
            wkc,
            chunk: 0,
        });
        self.service_cyclic();
    }

    /// Sends the LRW when a cycle boundary has been reached.
    fn service_cyclic(&mut self) {
        let Some(mut c) = self.cyclic else {
            return;
        };
        let now = self.link.now_ns();
        if now >= c.next_ns {
            let step = if c.chunk == 0 { c.len } else { c.chunk };
            let mut good = true;
            for at in (0..c.len).step_by(step.max(1)) {
                let n = step.min(c.len - at);
                let want = (u64::from(c.wkc) * n as u64 / c.len.max(1) as u64) as u16;
                let fb = FrameBuilder::new().logical(Command::Lrw, at as u32, &vec![0u8; n]);
                let d = self.frame(fb);
                good &= d.first().is_some_and(|v| v.wkc == want);
            }
            c.sent += 1;
            if good {
                c.good += 1;
            }
            c.next_ns += c.period_ns;
            if c.next_ns <= now {
                // Fell behind (a long blocking step): skip the lost cycles.
                c.next_ns = now + c.period_ns - (now - c.next_ns) % c.period_ns;
            }
            self.cyclic = Some(c);
        }
    }

    /// One datagram in its own frame; returns (data, working counter).
    pub fn dg(&mut self, cmd: Command, adp: u16, ado: u16, data: &[u8]) -> (Vec<u8>, u16) {
        let d = self.frame(FrameBuilder::new().physical(cmd, adp, ado, data));
        self.service_cyclic();
        match d.into_iter().next() {
            Some(v) => (v.data, v.wkc),
            None => (Vec::new(), 0),
        }
    }
    /// FPWR; returns the working counter.
    pub fn fpwr(&mut self, station: u16, ado: u16, data: &[u8]) -> u16 {
        self.dg(Command::Fpwr, station, ado, data).1
    }
    /// FPRD of `len` bytes (empty on a working counter other than 1).
    pub fn fprd(&mut self, station: u16, ado: u16, len: usize) -> Vec<u8> {
        let (d, wkc) = self.dg(Command::Fprd, station, ado, &vec![0; len]);
        if wkc == 1 {
            d
        } else {
            Vec::new()
        }
    }
    /// FPRD of a little-endian u16 (0 on no answer).
    pub fn fprd_u16(&mut self, station: u16, ado: u16) -> u16 {
        let d = self.fprd(station, ado, 2);
        if d.len() == 2 {
            u16::from_le_bytes([d[0], d[1]])
        } else {
            0
        }
    }
    /// FPRD of a little-endian u64 (0 on no answer).
    pub fn fprd_u64(&mut self, station: u16, ado: u16) -> u64 {
        let d = self.fprd(station, ado, 8);
        let mut b = [0u8; 8];
        if d.len() == 8 {
            b.copy_from_slice(&d);
        }
        u64::from_le_bytes(b)
    }
    /// BWR; returns the working counter.
    pub fn bwr(&mut self, ado: u16, data: &[u8]) -> u16 {
        self.dg(Command::Bwr, 0, ado, data).1
    }
    /// BRD; returns (data, working counter).
    pub fn brd(&mut self, ado: u16, len: usize) -> (Vec<u8>, u16) {
        self.dg(Command::Brd, 0, ado, &vec![0; len])
    }
    /// APWR to ring position `pos`; returns the working counter.
    pub fn apwr(&mut self, pos: u16, ado: u16, data: &[u8]) -> u16 {
        self.dg(Command::Apwr, 0u16.wrapping_sub(pos), ado, data).1
    }

    /// Moves the transport's time on by `dt_ns` (in steps of at most `step_ns`, ending
    /// at each cycle boundary of the cyclic exchange): the simulated segment advances
    /// and runs `after`; a real link sleeps.
    pub fn wait(&mut self, dt_ns: u64, step_ns: u64) {
        let end = self.link.now_ns() + dt_ns;
        loop {
            // One reading of the clock per round: a real link's moves on meanwhile.
            let now = self.link.now_ns();
            if now >= end {
                break;
            }
            let mut s = (end - now).min(step_ns.max(1));
            if let Some(c) = self.cyclic {
                s = s.min(c.next_ns.saturating_sub(now).max(1));
            }
            self.link.advance(s);
            self.service_cyclic();
        }
    }

    /// One SII word pair (4 bytes) at word `addr` through the EEPROM interface
    /// 0x0502-0x050B: read command, busy poll, data.
    pub fn sii_read(&mut self, station: u16, addr: u16) -> Option<u32> {
        let a = addr.to_le_bytes();
        if self.fpwr(station, 0x0502, &[0x00, 0x01, a[0], a[1], 0, 0]) != 1 {
            return None;
        }
        for _ in 0..100 {
            let c = self.fprd(station, 0x0502, 2);
            if c.len() == 2 && c[1] & 0x80 == 0 {
                let d = self.fprd(station, 0x0508, 4);
                return (d.len() == 4).then(|| u32::from_le_bytes([d[0], d[1], d[2], d[3]]));
            }
            self.wait(10_000, 10_000);
        }
        None
    }

    /// SM2 (outputs at 0x1100, `out` bytes) and SM3 (inputs at 0x1400, `inp` bytes)
    /// in one write, and two FMMUs: outputs at logical `log`, inputs behind them. 2
    /// when every write was taken.
    pub fn process_data_sms(&mut self, station: u16, log: u32, out: usize, inp: usize) -> u16 {
        let mut sm = [0u8; 16];
        sm[0..2].copy_from_slice(&0x1100u16.to_le_bytes());
        sm[2..4].copy_from_slice(&(out as u16).to_le_bytes());
        sm[4] = 0x64;
        sm[6] = 1;
        sm[8..10].copy_from_slice(&0x1400u16.to_le_bytes());
        sm[10..12].copy_from_slice(&(inp as u16).to_le_bytes());
        sm[12] = 0x20;
        sm[14] = 1;
        let wkc = self.fpwr(station, 0x0810, &sm);
        let fmmu = |log: u32, len: usize, phys: u16, ty: u8| {
            let mut f = [0u8; 16];
            f[0..4].copy_from_slice(&log.to_le_bytes());
            f[4..6].copy_from_slice(&(len as u16).to_le_bytes());
            f[7] = 7; // logical end bit
            f[8..10].copy_from_slice(&phys.to_le_bytes());
            f[11] = ty;
            f[12] = 1;
            f
        };
        let w0 = self.fpwr(station, 0x0600, &fmmu(log, out, 0x1100, 2));
        let w1 = self.fpwr(station, 0x0610, &fmmu(log + out as u32, inp, 0x1400, 1));
        wkc.min(w0).min(w1) * 2
    }

    /// SOEM ecx_configdc for one slave (ec_dc.c): latch receive times by BWR, read the
    /// port time and the local time, write the offset so the system time starts near
    /// `master_time` (the first DC slave has no delay to write).
    pub fn soem_configdc(&mut self, station: u16, master_time: u64) {
        self.bwr(0x0900, &[0; 4]);
        let _port0 = self.fprd(station, 0x0900, 4);
        let local = self.fprd_u64(station, 0x0918);
        self.fpwr(
            station,
            0x0920,
            &master_time.wrapping_sub(local).to_le_bytes(),
        );
        for port in [0x0904u16, 0x0908, 0x090C] {
            self.fprd(station, port, 4);
        }
    }

    /// SOEM ecx_dcsync0 / ecx_dcsync01 (ec_dc.c): SYNC unit off, ECAT owns it, local
    /// time, first pulse a whole number of cycles after time + 100 ms (+ `shift`),
    /// `cycle` (SYNC1 cycle 0 with activation 0x07), activation 0x03 / 0x07.
    pub fn soem_dcsync(&mut self, station: u16, cycle: u32, shift: i32, activation: u8) {
        self.fpwr(station, 0x0981, &[0]);
        self.fpwr(station, 0x0980, &[0]);
        let t1 = self.fprd_u64(station, 0x0910) as i64;
        let sync_delay = 100_000_000i64;
        let c = cycle as i64;
        let t = (t1 + sync_delay) / c * c + c + shift as i64;
        self.fpwr(station, 0x0990, &t.to_le_bytes());
        self.fpwr(station, 0x09A0, &cycle.to_le_bytes());
        if activation == 0x07 {
            self.fpwr(station, 0x09A4, &0u32.to_le_bytes());
        }
        self.fpwr(station, 0x0981, &[activation]);
    }

    /// Writes AL control.
    pub fn request_state(&mut self, station: u16, ctl: u16) -> u16 {
        self.fpwr(station, 0x0120, &ctl.to_le_bytes())
    }
    /// AL status and AL status code (one 6-byte read of 0x0130, as SOEM does).
    pub fn al_status(&mut self, station: u16) -> (u16, u16) {
        let s = self.fprd(station, 0x0130, 6);
        if s.len() == 6 {
            (
                u16::from_le_bytes([s[0], s[1]]),
                u16::from_le_bytes([s[4], s[5]]),
            )
        } else {
            (0, 0)
        }
    }
    /// Polls AL status every `step_ns` for up to `timeout_ns` until the state is
    /// `want` or the error bit is set; `cycle` runs between polls (process data).
    pub fn wait_state(
        &mut self,
        station: u16,
        want: u16,
        timeout_ns: u64,
        step_ns: u64,
        mut cycle: impl FnMut(&mut Self),
    ) -> (u16, u16) {
        let mut t = 0;
        loop {
            let st = self.al_status(station);
            if st.0 & 0x0F == want || st.0 & 0x10 != 0 || t >= timeout_ns {
                return st;
            }
            cycle(self);
            self.wait(step_ns, step_ns);
            t += step_ns;
        }
    }

    fn next_counter(&mut self) -> u8 {
        self.counter = self.counter % 7 + 1;
        self.counter
    }

    /// One CoE SDO request into SM0, the answer from SM1 (emergencies skipped).
    fn sdo_exchange(&mut self, station: u16, sdo: &[u8]) -> Result<Vec<u8>, SdoError> {
        let (out_start, out_len, in_start, in_len) = self.mbx;
        let mut m = vec![0u8; out_len as usize];
        let len = 2 + sdo.len();
        m[0..2].copy_from_slice(&(len as u16).to_le_bytes());
        m[5] = 0x03 | self.next_counter() << 4; // CoE
        m[6..8].copy_from_slice(&(2u16 << 12).to_le_bytes()); // SDO request
        m[8..8 + sdo.len()].copy_from_slice(sdo);
        if self.fpwr(station, out_start, &m) != 1 {
            return Err(SdoError::Transport("SM0 busy".into()));
        }
        for _ in 0..200 {
            let st = self.fprd(station, 0x080D, 1);
            if st.first().is_some_and(|s| s & 0x08 != 0) {
                let a = self.fprd(station, in_start, in_len as usize);
                if a.len() < 16 {
                    return Err(SdoError::Transport("SM1 read".into()));
                }
                let service = u16::from_le_bytes([a[6], a[7]]) >> 12;
                if a[5] & 0x0F == 0x03 && service == 1 {
                    continue; // emergency
                }
                if a[5] & 0x0F != 0x03 {
                    return Err(SdoError::Transport(format!("mailbox type {:#x}", a[5])));
                }
                if a[8] == 0x80 {
                    return Err(SdoError::Abort(u32::from_le_bytes([
                        a[12], a[13], a[14], a[15],
                    ])));
                }
                return Ok(a);
            }
            self.wait(20_000, 20_000);
        }
        Err(SdoError::Transport("no SDO answer".into()))
    }

    /// Writes SM0 (out) and SM1 (in) for the mailbox `mbx` (start, length each) and
    /// makes it the mailbox of the following requests.
    pub fn configure_mailbox(&mut self, station: u16, mbx: (u16, u16, u16, u16)) -> u16 {
        self.mbx = mbx;
        let (s0, l0, s1, l1) = mbx;
        let mut sms = [0u8; 16];
        sms[0..2].copy_from_slice(&s0.to_le_bytes());
        sms[2..4].copy_from_slice(&l0.to_le_bytes());
        sms[4] = 0x26;
        sms[6] = 1;
        sms[8..10].copy_from_slice(&s1.to_le_bytes());
        sms[10..12].copy_from_slice(&l1.to_le_bytes());
        sms[12] = 0x22;
        sms[14] = 1;
        self.fpwr(station, 0x0800, &sms)
    }

    /// Init → Bootstrap as SOEM does it: the boot mailbox from SII words 0x14-0x17
    /// into SM0/SM1, then AL control 0x03; returns the AL status and code reached.
    pub fn enter_bootstrap(&mut self, station: u16) -> (u16, u16) {
        let rx = self.sii_read(station, 0x14).unwrap_or(0);
        let tx = self.sii_read(station, 0x16).unwrap_or(0);
        self.configure_mailbox(
            station,
            (rx as u16, (rx >> 16) as u16, tx as u16, (tx >> 16) as u16),
        );
        self.request_state(station, 0x03);
        self.wait_state(station, 0x03, 50_000_000, 1_000_000, |_| {})
    }

    /// Sends one mailbox message of `kind` (4 = FoE) with `data` through SM0.
    fn mailbox_send(&mut self, station: u16, kind: u8, data: &[u8]) -> Result<(), String> {
        let (out_start, out_len, _, _) = self.mbx;
        if 6 + data.len() > out_len as usize {
            return Err(format!("{} bytes do not fit the mailbox", data.len()));
        }
        let mut m = vec![0u8; out_len as usize];
        m[0..2].copy_from_slice(&(data.len() as u16).to_le_bytes());
        m[5] = kind | self.next_counter() << 4;
        m[6..6 + data.len()].copy_from_slice(data);
        if self.fpwr(station, out_start, &m) != 1 {
            return Err("SM0 busy".into());
        }
        Ok(())
    }

    /// The next mailbox message of `kind` from SM1 (others skipped), its data.
    fn mailbox_receive(&mut self, station: u16, kind: u8) -> Result<Vec<u8>, String> {
        let (_, _, in_start, in_len) = self.mbx;
        for _ in 0..2000 {
            let st = self.fprd(station, 0x080D, 1);
            if st.first().is_some_and(|s| s & 0x08 != 0) {
                let a = self.fprd(station, in_start, in_len as usize);
                if a.len() < 6 {
                    return Err("SM1 read".into());
                }
                if a[5] & 0x0F != kind {
                    continue;
                }
                let n = (u16::from_le_bytes([a[0], a[1]]) as usize).min(a.len() - 6);
                return Ok(a[6..6 + n].to_vec());
            }
            self.wait(20_000, 20_000);
        }
        Err("no answer".into())
    }

    /// One FoE request and its answer.
    fn foe_exchange(
        &mut self,
        station: u16,
        req: &ecat_slave_stack::foe::Repr<'_>,
    ) -> Result<Vec<u8>, FoeError> {
        use ecat_slave_stack::foe::Frame;
        let mut b = vec![0u8; req.buffer_len()];
        req.emit(&mut Frame::new_unchecked(&mut b[..]));
        self.mailbox_send(station, 0x04, &b)
            .map_err(FoeError::Transport)?;
        self.mailbox_receive(station, 0x04)
            .map_err(FoeError::Transport)
    }

    /// FoE write of `file` as `name` with `password`, in DATA of the mailbox's size
    /// (SM0 length − 12), each DATA sent again after BUSY, as SOEM's `ecx_FOEwrite`.
    pub fn foe_write(
        &mut self,
        station: u16,
        name: &[u8],
        password: u32,
        file: &[u8],
    ) -> Result<FoeStats, FoeError> {
        self.foe_write_with(station, name, password, file, &mut |_| {})
    }

    /// [`Self::foe_write`], calling `progress` with the bytes acknowledged so far after
    /// every acknowledged DATA.
    pub fn foe_write_with(
        &mut self,
        station: u16,
        name: &[u8],
        password: u32,
        file: &[u8],
        progress: &mut dyn FnMut(usize),
    ) -> Result<FoeStats, FoeError> {
        use ecat_slave_stack::foe::{Frame, Repr, OVERHEAD};
        let frames0 = self.frames;
        let segment = self.mbx.1 as usize - OVERHEAD;
        let mut stats = FoeStats::default();
        let parse = |a: &[u8]| -> Result<(u8, u32), FoeError> {
            let f = Frame::new_checked(a).map_err(|e| FoeError::Transport(format!("{e:?}")))?;
            match Repr::parse(&f).map_err(|e| FoeError::Transport(format!("{e:?}")))? {
                Repr::Ack { packet } => Ok((4, packet)),
                Repr::Busy { .. } => Ok((6, 0)),
                Repr::Error { code, .. } => Err(FoeError::Err(code)),
                other => Err(FoeError::Transport(format!("unexpected {other:?}"))),
            }
        };
        let a = self.foe_exchange(station, &Repr::Write { password, name })?;
        if parse(&a)? != (4, 0) {
            return Err(FoeError::Transport("no ACK 0 for the WRQ".into()));
        }
        let mut packet = 1u32;
        let mut chunks = file.chunks(segment).peekable();
        // A file that fills whole DATA ends with an empty one.
        let empty_last = file.len().is_multiple_of(segment);
        loop {
            let data = match chunks.next() {
                Some(c) => c,
                None if empty_last && packet == stats.packets + 1 => &[][..],
                None => break,
            };
            loop {
                let a = self.foe_exchange(station, &Repr::Data { packet, data })?;
                match parse(&a)? {
                    (4, n) if n == packet => break,
                    (6, _) => {
                        stats.busy += 1;
                        if stats.busy > 100_000 {
                            return Err(FoeError::Transport("BUSY for ever".into()));
                        }
                    }
                    (_, n) => return Err(FoeError::Transport(format!("ACK {n} for {packet}"))),
                }
            }
            stats.packets += 1;
            progress((stats.packets as usize * segment).min(file.len()));
            packet += 1;
            if data.len() < segment {
                break;
            }
        }
        stats.frames = self.frames - frames0;
        Ok(stats)
    }

    /// FoE read of `name` with `password` (each DATA acknowledged).
    pub fn foe_read(
        &mut self,
        station: u16,
        name: &[u8],
        password: u32,
    ) -> Result<Vec<u8>, FoeError> {
        use ecat_slave_stack::foe::{Frame, Repr};
        let mut out = Vec::new();
        let mut a = self.foe_exchange(station, &Repr::Read { password, name })?;
        loop {
            let f =
                Frame::new_checked(&a[..]).map_err(|e| FoeError::Transport(format!("{e:?}")))?;
            match Repr::parse(&f).map_err(|e| FoeError::Transport(format!("{e:?}")))? {
                Repr::Data { packet, data } => {
                    out.extend_from_slice(data);
                    let last = data.len() < self.mbx.3 as usize - ecat_slave_stack::foe::OVERHEAD;
                    if last {
                        let mut b = vec![0u8; 8];
                        Repr::Ack { packet }.emit(&mut Frame::new_unchecked(&mut b[..]));
                        self.mailbox_send(station, 0x04, &b)
                            .map_err(FoeError::Transport)?;
                        return Ok(out);
                    }
                    a = self.foe_exchange(station, &Repr::Ack { packet })?;
                }
                Repr::Error { code, .. } => return Err(FoeError::Err(code)),
                other => return Err(FoeError::Transport(format!("unexpected {other:?}"))),
            }
        }
    }

    /// Expedited SDO download of 1..=4 bytes.
    pub fn sdo_download(
        &mut self,
        station: u16,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), SdoError> {
        if data.is_empty() || data.len() > 4 {
            return Err(SdoError::Transport("expedited: 1..4 bytes".into()));
        }
        let mut sdo = [0u8; 8];
        sdo[0] = 0x23 | ((4 - data.len() as u8) << 2);
        sdo[1..3].copy_from_slice(&index.to_le_bytes());
        sdo[3] = sub;
        sdo[4..4 + data.len()].copy_from_slice(data);
        let a = self.sdo_exchange(station, &sdo)?;
        if a[8] == 0x60 {
            Ok(())
        } else {
            Err(SdoError::Transport(format!("download answer {:#x}", a[8])))
        }
    }

    /// SDO upload (expedited or normal, unsegmented) as a little-endian value.
    pub fn sdo_upload(&mut self, station: u16, index: u16, sub: u8) -> Result<u64, SdoError> {
        let mut sdo = [0u8; 8];
        sdo[0] = 0x40;
        sdo[1..3].copy_from_slice(&index.to_le_bytes());
        sdo[3] = sub;
        let a = self.sdo_exchange(station, &sdo)?;
        let cmd = a[8];
        let bytes: Vec<u8> = if cmd & 0xE2 == 0x42 {
            // Expedited; size indicated or 4.
            let n = if cmd & 0x01 != 0 {
                4 - ((cmd >> 2) & 3) as usize
            } else {
                4
            };
            a[12..12 + n].to_vec()
        } else if cmd & 0xE3 == 0x41 {
            let n = u32::from_le_bytes([a[12], a[13], a[14], a[15]]) as usize;
            a.get(16..16 + n.min(8))
                .ok_or_else(|| SdoError::Transport("short normal upload".into()))?
                .to_vec()
        } else {
            return Err(SdoError::Transport(format!("upload answer {cmd:#x}")));
        };
        let mut b = [0u8; 8];
        b[..bytes.len().min(8)].copy_from_slice(&bytes[..bytes.len().min(8)]);
        Ok(u64::from_le_bytes(b))
    }
}
