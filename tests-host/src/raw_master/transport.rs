//! The transports a [`Master`](super::Master) sends its frames through: a simulated
//! segment in the same process, or an AF_PACKET socket on a network interface.

use std::time::{Duration, Instant};

use crate::esc_sim::frame::{ETHERTYPE_ETHERCAT, ETH_HEADER_LEN};
use crate::raw_socket::{OpenError, RawSocket};
use crate::segment::Segment;
use ecat_slave_stack::slave::SlaveApplication;

/// How the frames of a [`Master`] reach the slaves and come back, and its clock.
pub trait Transport {
    /// Sends one Ethernet frame; returns the frame that came back, or `None` when
    /// none did (within the transport's timeout).
    fn exchange(&mut self, frame: &[u8]) -> Option<Vec<u8>>;
    /// The transport's clock, ns (simulated time, or the wall clock since it opened).
    fn now_ns(&self) -> u64;
    /// Lets `dt_ns` pass (simulated: the segment advances; real: a sleep).
    fn advance(&mut self, dt_ns: u64);
}

/// The in-process transport: a simulated segment, and the hook that runs after every
/// frame and every time step.
pub struct SegmentTransport<A: SlaveApplication> {
    /// The segment.
    pub seg: Segment<A>,
    /// Runs after every frame and every time step.
    pub after: fn(&mut Segment<A>),
}

impl<A: SlaveApplication> Transport for SegmentTransport<A> {
    fn exchange(&mut self, frame: &[u8]) -> Option<Vec<u8>> {
        let mut f = frame.to_vec();
        self.seg.process(&mut f);
        (self.after)(&mut self.seg);
        Some(f)
    }
    fn now_ns(&self) -> u64 {
        self.seg.now_ns()
    }
    fn advance(&mut self, dt_ns: u64) {
        self.seg.advance(dt_ns);
        (self.after)(&mut self.seg);
    }
}

/// Offset of the first datagram's index byte in a frame built by [`FrameBuilder`]
/// (no VLAN tag): the socket transport numbers its frames there.
const FIRST_INDEX: usize = ETH_HEADER_LEN + 2 + 1;

/// Real frames on a network interface: an AF_PACKET raw socket, a bounded wait for
/// each frame to come back, the wall clock.
///
/// Every frame sent carries a number in its first datagram's index byte (slaves
/// leave the index alone). A received frame with another number (one that came back
/// after its exchange had given up, or any other EtherCAT traffic on the link) is
/// dropped and counted, so a late frame is never taken for the answer to the next.
pub struct SocketTransport {
    sock: RawSocket,
    /// How long an exchange waits for its frame to come back.
    pub timeout: Duration,
    start: Instant,
    tag: u8,
    buf: Vec<u8>,
    /// Frames that did not come back within `timeout`.
    pub lost: u64,
    /// Frames received that were not the one awaited (dropped).
    pub stray: u64,
    /// Round trip of every exchange answered, ns.
    pub rtt_ns: Vec<u64>,
}

impl SocketTransport {
    /// A raw socket on `iface` (needs root or CAP_NET_RAW); each exchange waits up to
    /// `timeout` for its frame.
    pub fn open(iface: &str, timeout: Duration) -> Result<Self, OpenError> {
        Ok(SocketTransport {
            sock: RawSocket::open(iface)?,
            timeout,
            start: Instant::now(),
            tag: 0,
            buf: vec![0u8; 2048],
            lost: 0,
            stray: 0,
            rtt_ns: Vec::new(),
        })
    }

    /// The next received frame that carries `tag`, until `deadline`.
    fn receive(&mut self, tag: u8, deadline: Instant) -> Option<Vec<u8>> {
        loop {
            while let Ok(Some(n)) = self.sock.recv(&mut self.buf) {
                let r = &self.buf[..n];
                if r.len() > FIRST_INDEX
                    && r[12..14] == ETHERTYPE_ETHERCAT.to_be_bytes()
                    && r[FIRST_INDEX] == tag
                {
                    return Some(r.to_vec());
                }
                self.stray += 1;
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return None;
            }
            // A failed poll is retried until the deadline.
            let _ = self.sock.wait_readable(left.as_micros().max(1) as u64);
        }
    }
}

impl Transport for SocketTransport {
    fn exchange(&mut self, frame: &[u8]) -> Option<Vec<u8>> {
        let mut f = frame.to_vec();
        self.tag = self.tag.wrapping_add(1);
        if let Some(b) = f.get_mut(FIRST_INDEX) {
            *b = self.tag;
        }
        let sent = Instant::now();
        if self.sock.send(&f).is_err() {
            self.lost += 1;
            return None;
        }
        let back = self.receive(self.tag, sent + self.timeout);
        match back {
            Some(_) => self.rtt_ns.push(sent.elapsed().as_nanos() as u64),
            None => self.lost += 1,
        }
        back
    }
    fn now_ns(&self) -> u64 {
        self.start.elapsed().as_nanos() as u64
    }
    fn advance(&mut self, dt_ns: u64) {
        std::thread::sleep(Duration::from_nanos(dt_ns));
    }
}
