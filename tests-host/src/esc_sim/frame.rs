//! EtherCAT frames on the wire and their processing by a chain of [`EscSim`]s.
//!
//! Layout (ETG.1000.4): Ethernet header (destination, source, optionally one 802.1Q
//! VLAN tag, EtherType 0x88A4), the
//! 2-byte EtherCAT header (bits 10:0 length of the datagrams, bits 15:12 type, 1 =
//! datagrams), then datagrams: 10-byte header (command, index, address (ADP/ADO or
//! 32-bit logical), length word with bits 10:0 data length, bit 14 circulating, bit 15
//! more datagrams follow, IRQ), data, 16-bit working counter.
//!
//! The whole structure is checked before any ESC touches the frame: a frame whose
//! lengths do not add up is not processed at all (a real ESC would detect the broken
//! frame and discard its write effects) and comes back unchanged, so the master sees
//! it as lost. Frames of another EtherType, or EtherCAT frames of another type, pass
//! through unchanged.

use super::{EscSim, FrameTiming, SharedEsc, Side};
use core::ops::DerefMut;

/// EtherType of EtherCAT.
pub const ETHERTYPE_ETHERCAT: u16 = 0x88A4;
/// Ethernet header length (no VLAN tag).
pub const ETH_HEADER_LEN: usize = 14;
/// EtherType of an IEEE 802.1Q VLAN tag (4 bytes before the real EtherType).
pub const ETHERTYPE_VLAN: u16 = 0x8100;
/// Datagram header length.
pub const DATAGRAM_HEADER_LEN: usize = 10;
/// Largest number of datagrams a frame may carry here (a 1500-byte payload holds at
/// most 125 empty datagrams).
pub const MAX_DATAGRAMS: usize = 128;

/// Datagram commands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Command {
    /// No operation.
    Nop = 0,
    /// Auto-increment physical read.
    Aprd = 1,
    /// Auto-increment physical write.
    Apwr = 2,
    /// Auto-increment physical read-write.
    Aprw = 3,
    /// Configured-address physical read.
    Fprd = 4,
    /// Configured-address physical write.
    Fpwr = 5,
    /// Configured-address physical read-write.
    Fprw = 6,
    /// Broadcast read.
    Brd = 7,
    /// Broadcast write.
    Bwr = 8,
    /// Broadcast read-write.
    Brw = 9,
    /// Logical read.
    Lrd = 10,
    /// Logical write.
    Lwr = 11,
    /// Logical read-write.
    Lrw = 12,
    /// Auto-increment read, multiple write.
    Armw = 13,
    /// Configured-address read, multiple write.
    Frmw = 14,
}

impl Command {
    /// Decodes a command byte.
    pub fn from_u8(v: u8) -> Option<Self> {
        use Command::*;
        Some(match v {
            0 => Nop,
            1 => Aprd,
            2 => Apwr,
            3 => Aprw,
            4 => Fprd,
            5 => Fpwr,
            6 => Fprw,
            7 => Brd,
            8 => Bwr,
            9 => Brw,
            10 => Lrd,
            11 => Lwr,
            12 => Lrw,
            13 => Armw,
            14 => Frmw,
            _ => return None,
        })
    }
}

/// What happened to a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameOutcome {
    /// EtherCAT datagrams were processed by every ESC.
    Processed {
        /// Number of datagrams in the frame.
        datagrams: usize,
    },
    /// Not an EtherCAT datagram frame: passed through unchanged.
    PassedThrough,
    /// Broken frame: passed through unchanged, nothing executed.
    Malformed(Malformed),
    /// A circulating frame reached an ESC whose port 0 loop is closed a second time
    /// and was destroyed: nothing comes back (the ESCs before it did process it).
    Destroyed {
        /// Position of the ESC that destroyed it.
        at: usize,
    },
}

/// Why a frame was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Malformed {
    /// Shorter than the Ethernet + EtherCAT headers.
    TooShort,
    /// The EtherCAT header length runs past the end of the frame.
    LengthBeyondFrame,
    /// A datagram header or its data + WKC runs past the EtherCAT length.
    DatagramTruncated,
    /// The EtherCAT length is zero.
    Empty,
    /// More datagrams than [`MAX_DATAGRAMS`].
    TooManyDatagrams,
}

/// One datagram as found in a frame (offsets into the frame).
#[derive(Debug, Clone, Copy)]
struct DatagramPos {
    header: usize,
    len: usize,
}

/// Checks the structure of `frame`; returns the datagram positions.
fn parse(frame: &[u8]) -> Result<Option<Vec<DatagramPos>>, Malformed> {
    if frame.len() < ETH_HEADER_LEN {
        return Err(Malformed::TooShort);
    }
    // One IEEE 802.1Q tag may precede the EtherType.
    let mut eth = ETH_HEADER_LEN;
    let mut ethertype = u16::from_be_bytes([frame[12], frame[13]]);
    if ethertype == ETHERTYPE_VLAN {
        if frame.len() < ETH_HEADER_LEN + 4 {
            return Err(Malformed::TooShort);
        }
        ethertype = u16::from_be_bytes([frame[16], frame[17]]);
        eth += 4;
    }
    if ethertype != ETHERTYPE_ETHERCAT {
        return Ok(None);
    }
    if frame.len() < eth + 2 {
        return Err(Malformed::TooShort);
    }
    let hdr = u16::from_le_bytes([frame[eth], frame[eth + 1]]);
    let len = (hdr & 0x07FF) as usize;
    let typ = hdr >> 12;
    if typ != 1 {
        return Ok(None);
    }
    if len == 0 {
        return Err(Malformed::Empty);
    }
    let base = eth + 2;
    if base + len > frame.len() {
        return Err(Malformed::LengthBeyondFrame);
    }
    let mut out = Vec::new();
    let mut off = 0usize;
    loop {
        if out.len() >= MAX_DATAGRAMS {
            return Err(Malformed::TooManyDatagrams);
        }
        if off + DATAGRAM_HEADER_LEN > len {
            return Err(Malformed::DatagramTruncated);
        }
        let h = base + off;
        let lw = u16::from_le_bytes([frame[h + 6], frame[h + 7]]);
        let dlen = (lw & 0x07FF) as usize;
        let next = off + DATAGRAM_HEADER_LEN + dlen + 2;
        if next > len {
            return Err(Malformed::DatagramTruncated);
        }
        out.push(DatagramPos {
            header: h,
            len: dlen,
        });
        off = next;
        if lw & 0x8000 == 0 {
            break;
        }
    }
    Ok(Some(out))
}

/// Runs `frame` (a complete Ethernet II frame without FCS) through `escs` in order, as
/// the frame travels down the line and back: the ESC at index `i` sees it at
/// `t_ns + i·hop_ns` on port 0 and, if it has a successor, gets it back on port 1 at
/// `t_ns + (2·(n−1) − i)·hop_ns`. The first ESC sets the locally administered bit of
/// the source MAC address, as a real port 0 does. Bit 14 of each datagram's length
/// word (circulating) is left alone unless an ESC has its port 0 loop closed
/// ([`EscSim::set_port0_loop_closed`]): that ESC sets it, or destroys the frame when
/// it is already set.
///
/// `escs` are anything that dereferences to an [`EscSim`]: `&mut EscSim`, a
/// `RefMut` of a shared simulator, or the simulators themselves.
pub fn process_frame<E: DerefMut<Target = EscSim>>(
    escs: &mut [E],
    frame: &mut [u8],
    t_ns: u64,
    hop_ns: u64,
) -> FrameOutcome {
    let n = escs.len();
    through_chain(escs.iter_mut().map(|e| &mut **e), n, frame, t_ns, hop_ns)
}

/// [`process_frame`] through shared simulators, each locked only while the frame
/// passes it (as an ESC's memory is busy for the frame only while the frame passes
/// that ESC), after moving its clock to `t_ns`: the microcontroller side
/// ([`SharedEsc`]'s other users) reaches every other ESC meanwhile.
pub fn process_frame_in_turn(
    escs: &[SharedEsc],
    frame: &mut [u8],
    t_ns: u64,
    hop_ns: u64,
) -> FrameOutcome {
    let locked = escs.iter().map(|e| {
        let mut esc = e.borrow_mut();
        esc.advance_to(t_ns);
        esc
    });
    through_chain(locked, escs.len(), frame, t_ns, hop_ns)
}

/// The frame through the `n` ESCs `escs` yields, one after the other.
fn through_chain<E: DerefMut<Target = EscSim>>(
    escs: impl Iterator<Item = E>,
    n: usize,
    frame: &mut [u8],
    t_ns: u64,
    hop_ns: u64,
) -> FrameOutcome {
    let dgs = match parse_for_processing(frame) {
        Ok(d) => d,
        Err(outcome) => return outcome,
    };
    for (i, mut esc) in escs.enumerate() {
        if !pass_esc(&mut esc, (i, n), &dgs, frame, t_ns, hop_ns) {
            return FrameOutcome::Destroyed { at: i };
        }
    }
    processed(frame, n, dgs.len())
}

/// The datagrams of `frame`, or the outcome when there is nothing to process.
fn parse_for_processing(frame: &[u8]) -> Result<Vec<DatagramPos>, FrameOutcome> {
    match parse(frame) {
        Err(m) => Err(FrameOutcome::Malformed(m)),
        Ok(None) => Err(FrameOutcome::PassedThrough),
        Ok(Some(d)) => Ok(d),
    }
}

/// The frame at ESC `i` of `n` (`at`); false when that ESC destroys it.
fn pass_esc(
    esc: &mut EscSim,
    at: (usize, usize),
    dgs: &[DatagramPos],
    frame: &mut [u8],
    t_ns: u64,
    hop_ns: u64,
) -> bool {
    let (i, n) = (at.0 as u64, at.1 as u64);
    let timing = FrameTiming {
        port0_ns: t_ns + i * hop_ns,
        port1_ns: (i + 1 < n).then(|| t_ns + (2 * (n - 1) - i) * hop_ns),
    };
    esc.set_frame_timing(timing);
    if esc.port0_loop_closed() {
        // Circulating-frame rule: an ESC with a closed port 0 marks frames passing
        // its processing unit; a frame already marked has gone round once without
        // reaching a master and is destroyed.
        if dgs.iter().any(|d| frame[d.header + 7] & 0x40 != 0) {
            return false;
        }
        for d in dgs {
            frame[d.header + 7] |= 0x40;
        }
    }
    for d in dgs {
        process_datagram(
            esc,
            &mut frame[d.header..d.header + DATAGRAM_HEADER_LEN + d.len + 2],
        );
    }
    true
}

fn processed(frame: &mut [u8], n: usize, datagrams: usize) -> FrameOutcome {
    if n > 0 {
        frame[6] |= 0x02;
    }
    FrameOutcome::Processed { datagrams }
}

/// Executes one datagram (header + data + WKC, structure already checked) in `esc`.
fn process_datagram(esc: &mut EscSim, dg: &mut [u8]) {
    let (hdr, rest) = dg.split_at_mut(DATAGRAM_HEADER_LEN);
    let dlen = rest.len() - 2;
    let (data, wkc_bytes) = rest.split_at_mut(dlen);
    let Some(cmd) = Command::from_u8(hdr[0]) else {
        // Unknown command: ignored, WKC unchanged.
        return;
    };
    let adp = u16::from_le_bytes([hdr[2], hdr[3]]);
    let ado = u16::from_le_bytes([hdr[4], hdr[5]]);
    let logical = u32::from_le_bytes([hdr[2], hdr[3], hdr[4], hdr[5]]);
    // The IRQ field passes the ESC before the data: it carries the events as they
    // were when the datagram arrived.
    let irq = u16::from_le_bytes([hdr[8], hdr[9]]) | esc.ecat_irq();
    hdr[8..10].copy_from_slice(&irq.to_le_bytes());
    let mut wkc_add: u16 = 0;
    use Command::*;
    match cmd {
        Nop => {}
        Aprd | Apwr | Aprw | Armw => {
            let addressed = adp == 0;
            match cmd {
                Aprd if addressed => wkc_add = phys_read(esc, ado, data, false),
                Apwr if addressed => wkc_add = phys_write(esc, ado, data),
                Aprw if addressed => wkc_add = phys_rw(esc, ado, data, false),
                Armw if addressed => wkc_add = phys_read(esc, ado, data, false),
                Armw => wkc_add = phys_write(esc, ado, data),
                _ => {}
            }
            hdr[2..4].copy_from_slice(&adp.wrapping_add(1).to_le_bytes());
        }
        Fprd | Fpwr | Fprw | Frmw => {
            let addressed = esc.matches_configured(adp);
            match cmd {
                Fprd if addressed => wkc_add = phys_read(esc, ado, data, false),
                Fpwr if addressed => wkc_add = phys_write(esc, ado, data),
                Fprw if addressed => wkc_add = phys_rw(esc, ado, data, false),
                Frmw if addressed => wkc_add = phys_read(esc, ado, data, false),
                Frmw => wkc_add = phys_write(esc, ado, data),
                _ => {}
            }
        }
        Brd => {
            wkc_add = phys_read(esc, ado, data, true);
            hdr[2..4].copy_from_slice(&adp.wrapping_add(1).to_le_bytes());
        }
        Bwr => {
            wkc_add = phys_write(esc, ado, data);
            hdr[2..4].copy_from_slice(&adp.wrapping_add(1).to_le_bytes());
        }
        Brw => {
            wkc_add = phys_rw(esc, ado, data, true);
            hdr[2..4].copy_from_slice(&adp.wrapping_add(1).to_le_bytes());
        }
        Lrd | Lwr | Lrw => wkc_add = logical_access(esc, cmd, logical, data),
    }
    let wkc = u16::from_le_bytes([wkc_bytes[0], wkc_bytes[1]]).wrapping_add(wkc_add);
    wkc_bytes.copy_from_slice(&wkc.to_le_bytes());
}

fn phys_read(esc: &mut EscSim, ado: u16, data: &mut [u8], or: bool) -> u16 {
    if or {
        let mut tmp = vec![0u8; data.len()];
        let ok = esc.side_read(Side::Ecat, ado, &mut tmp);
        if ok {
            let valid = esc_valid_len(esc, ado, data.len());
            for (d, t) in data[..valid].iter_mut().zip(&tmp) {
                *d |= *t;
            }
        }
        ok as u16
    } else {
        esc.side_read(Side::Ecat, ado, data) as u16
    }
}

fn esc_valid_len(esc: &EscSim, ado: u16, len: usize) -> usize {
    esc.flavour()
        .address_space()
        .saturating_sub(ado as usize)
        .min(len)
}

fn phys_write(esc: &mut EscSim, ado: u16, data: &[u8]) -> u16 {
    esc.side_write(Side::Ecat, ado, data) as u16
}

fn phys_rw(esc: &mut EscSim, ado: u16, data: &mut [u8], or: bool) -> u16 {
    let incoming = data.to_vec();
    let r = phys_read(esc, ado, data, or);
    let w = esc.side_write(Side::Ecat, ado, &incoming);
    r + if w { 2 } else { 0 }
}

/// One FMMU as configured in 0x0600 + 16·n.
#[derive(Debug, Clone, Copy)]
struct Fmmu {
    /// First logical bit (absolute bit number).
    log_start_bit: u64,
    /// Last logical bit, inclusive.
    log_end_bit: u64,
    /// First physical bit.
    phys_start_bit: u64,
    read: bool,
    write: bool,
}

fn fmmus(esc: &EscSim) -> Vec<Fmmu> {
    let mut v = Vec::new();
    for n in 0..esc.flavour().fmmu_count() {
        let r = esc.peek(ecat_slave_stack::registers::fmmu_register(n), 16);
        if r.len() < 16 || r[0x0C] & 0x01 == 0 {
            continue;
        }
        let log = u32::from_le_bytes([r[0], r[1], r[2], r[3]]) as u64;
        let len = u16::from_le_bytes([r[4], r[5]]) as u64;
        if len == 0 {
            continue;
        }
        let log_start_bit = log * 8 + (r[6] & 7) as u64;
        let log_end_bit = (log + len - 1) * 8 + (r[7] & 7) as u64;
        if log_end_bit < log_start_bit {
            continue;
        }
        let phys = u16::from_le_bytes([r[8], r[9]]) as u64;
        v.push(Fmmu {
            log_start_bit,
            log_end_bit,
            phys_start_bit: phys * 8 + (r[0x0A] & 7) as u64,
            read: r[0x0B] & 0x01 != 0,
            write: r[0x0B] & 0x02 != 0,
        });
    }
    v
}

fn get_bit(buf: &[u8], bit: u64) -> bool {
    buf[(bit / 8) as usize] & (1 << (bit % 8)) != 0
}
fn set_bit(buf: &mut [u8], bit: u64, v: bool) {
    let b = &mut buf[(bit / 8) as usize];
    if v {
        *b |= 1 << (bit % 8);
    } else {
        *b &= !(1 << (bit % 8));
    }
}

/// LRD/LWR/LRW in one ESC: every active FMMU whose logical window overlaps the
/// datagram moves the overlapping bits between the datagram and its physical memory
/// (through the SyncManagers). Reads see the memory as it was before this datagram's
/// writes; writes take the datagram data as it arrived. WKC: LRD/LWR +1; LRW +1 for
/// a read, +2 for a write, +3 for both.
fn logical_access(esc: &mut EscSim, cmd: Command, logical: u32, data: &mut [u8]) -> u16 {
    if data.is_empty() {
        return 0;
    }
    let dg_start = logical as u64 * 8;
    let dg_end = dg_start + data.len() as u64 * 8 - 1;
    let incoming = data.to_vec();
    let mut did_read = false;
    let mut did_write = false;
    let space = esc.flavour().address_space() as u64;
    for f in fmmus(esc) {
        let lo = f.log_start_bit.max(dg_start);
        let hi = f.log_end_bit.min(dg_end);
        if lo > hi {
            continue;
        }
        let p_lo = f.phys_start_bit + (lo - f.log_start_bit);
        let p_hi = f.phys_start_bit + (hi - f.log_start_bit);
        let pb0 = p_lo / 8;
        let pb1 = p_hi / 8;
        if pb1 >= space || pb0 > u16::MAX as u64 {
            continue;
        }
        let nbytes = (pb1 - pb0 + 1) as usize;
        let aligned = lo % 8 == 0 && hi % 8 == 7 && p_lo % 8 == 0;
        if f.read && matches!(cmd, Command::Lrd | Command::Lrw) {
            let mut tmp = vec![0u8; nbytes];
            if esc.side_read(Side::Ecat, pb0 as u16, &mut tmp) {
                did_read = true;
                if aligned {
                    let d0 = ((lo - dg_start) / 8) as usize;
                    data[d0..d0 + nbytes].copy_from_slice(&tmp);
                } else {
                    for k in 0..=(hi - lo) {
                        let v = get_bit(&tmp, p_lo - pb0 * 8 + k);
                        set_bit(data, lo - dg_start + k, v);
                    }
                }
            }
        }
        if f.write && matches!(cmd, Command::Lwr | Command::Lrw) {
            let mut tmp = vec![0u8; nbytes];
            if aligned {
                let d0 = ((lo - dg_start) / 8) as usize;
                tmp.copy_from_slice(&incoming[d0..d0 + nbytes]);
            } else {
                esc.peek_for_rmw(pb0 as usize, &mut tmp);
                for k in 0..=(hi - lo) {
                    let v = get_bit(&incoming, lo - dg_start + k);
                    set_bit(&mut tmp, p_lo - pb0 * 8 + k, v);
                }
            }
            if esc.side_write(Side::Ecat, pb0 as u16, &tmp) {
                did_write = true;
            }
        }
    }
    match cmd {
        Command::Lrw => (did_read as u16) + if did_write { 2 } else { 0 },
        _ => (did_read || did_write) as u16,
    }
}

/// Anything that turns an outgoing frame into the returned frame: a chain of
/// simulators with their firmware (the segment), or a real interface. Masters
/// (the ethercrab seam, `virtual-drive`) talk to this.
pub trait Wire {
    /// Processes `frame` in place (the frame comes back in the same buffer).
    fn transfer(&mut self, frame: &mut [u8]) -> FrameOutcome;
    /// Simulated time, ns.
    fn now_ns(&self) -> u64;
}

/// Builds EtherCAT frames for tests and tools (the master side of the wire).
#[derive(Debug, Clone)]
pub struct FrameBuilder {
    datagrams: Vec<(u8, u8, u32, Vec<u8>)>,
    src: [u8; 6],
}

impl Default for FrameBuilder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameBuilder {
    /// An empty frame from source MAC 10:10:10:10:10:10.
    pub fn new() -> Self {
        FrameBuilder {
            datagrams: Vec::new(),
            src: [0x10; 6],
        }
    }
    /// Adds a datagram with a physical address (ADP, ADO).
    pub fn physical(mut self, cmd: Command, adp: u16, ado: u16, data: &[u8]) -> Self {
        let addr = adp as u32 | (ado as u32) << 16;
        let idx = self.datagrams.len() as u8;
        self.datagrams.push((cmd as u8, idx, addr, data.to_vec()));
        self
    }
    /// Adds a datagram with a logical address.
    pub fn logical(mut self, cmd: Command, addr: u32, data: &[u8]) -> Self {
        let idx = self.datagrams.len() as u8;
        self.datagrams.push((cmd as u8, idx, addr, data.to_vec()));
        self
    }
    /// Adds a datagram with a raw command byte (for garbage tests).
    pub fn raw(mut self, cmd: u8, addr: u32, data: &[u8]) -> Self {
        let idx = self.datagrams.len() as u8;
        self.datagrams.push((cmd, idx, addr, data.to_vec()));
        self
    }
    /// The Ethernet frame.
    pub fn build(&self) -> Vec<u8> {
        let mut f = vec![0xFF; 6];
        f.extend_from_slice(&self.src);
        f.extend_from_slice(&ETHERTYPE_ETHERCAT.to_be_bytes());
        let len: usize = self
            .datagrams
            .iter()
            .map(|d| DATAGRAM_HEADER_LEN + d.3.len() + 2)
            .sum();
        f.extend_from_slice(&((len as u16 & 0x07FF) | 0x1000).to_le_bytes());
        let n = self.datagrams.len();
        for (i, (cmd, idx, addr, data)) in self.datagrams.iter().enumerate() {
            f.push(*cmd);
            f.push(*idx);
            f.extend_from_slice(&addr.to_le_bytes());
            let more = if i + 1 < n { 0x8000 } else { 0 };
            f.extend_from_slice(&((data.len() as u16 & 0x07FF) | more).to_le_bytes());
            f.extend_from_slice(&[0, 0]);
            f.extend_from_slice(data);
            f.extend_from_slice(&[0, 0]);
        }
        while f.len() < 60 {
            f.push(0);
        }
        f
    }
}

/// A datagram read back from a processed frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DatagramView {
    /// Command byte.
    pub cmd: u8,
    /// Address field (ADP in the low half for physical commands).
    pub addr: u32,
    /// IRQ field.
    pub irq: u16,
    /// Data.
    pub data: Vec<u8>,
    /// Working counter.
    pub wkc: u16,
}

/// Splits a processed frame into its datagrams (None if it is not a well-formed
/// EtherCAT frame).
pub fn datagrams(frame: &[u8]) -> Option<Vec<DatagramView>> {
    let pos = parse(frame).ok()??;
    Some(
        pos.iter()
            .map(|d| {
                let h = d.header;
                let data = frame[h + DATAGRAM_HEADER_LEN..h + DATAGRAM_HEADER_LEN + d.len].to_vec();
                let w = h + DATAGRAM_HEADER_LEN + d.len;
                DatagramView {
                    cmd: frame[h],
                    addr: u32::from_le_bytes([
                        frame[h + 2],
                        frame[h + 3],
                        frame[h + 4],
                        frame[h + 5],
                    ]),
                    irq: u16::from_le_bytes([frame[h + 8], frame[h + 9]]),
                    data,
                    wkc: u16::from_le_bytes([frame[w], frame[w + 1]]),
                }
            })
            .collect(),
    )
}
