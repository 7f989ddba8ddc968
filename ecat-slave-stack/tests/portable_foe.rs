//! Byte-level FoE transfers through the mailbox server (mailbox type 4) against an
//! in-memory file backend: writes (whole and partial last segments, BUSY, packet
//! number errors, timeouts, Bootstrap-only files), reads, and the error answers.
//! Runs on the host and under QEMU.
#![cfg_attr(target_os = "none", no_std, no_main)]

use ecat_slave_stack::coe::example::ExampleDictionary;
use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::foe::{self, ErrorCode, FoeFiles, WriteStatus};
use ecat_slave_stack::mailbox::{Handlers, MailboxServer};

const MAX: usize = 256;
/// Capacity of the image file.
const IMAGE: usize = 1024;
/// Length of the readable log file.
const LOG_LEN: u32 = 300;
/// Password of the "secret" file.
const SECRET: u32 = 0x1234_5678;

fn pattern(i: usize) -> u8 {
    (i * 7 + 3) as u8
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Open {
    None,
    Image,
    Log,
}

/// Files: "app.bin" (write, Bootstrap only, up to IMAGE bytes), "log.txt" (read,
/// LOG_LEN pattern bytes, also writable outside Bootstrap), "secret" (read, password).
struct MemFiles {
    image: [u8; IMAGE],
    len: usize,
    open: Open,
    /// BUSY answers still to give at `busy_at` before taking the data.
    busy_left: u8,
    busy_at: u32,
    write_calls: u32,
    finished: u32,
    aborted: u32,
    reads_finished: u32,
    finish_error: Option<ErrorCode>,
    write_error_at: Option<u32>,
    read_len: u32,
}

impl MemFiles {
    fn new() -> Self {
        MemFiles {
            image: [0; IMAGE],
            len: 0,
            open: Open::None,
            busy_left: 0,
            busy_at: 0,
            write_calls: 0,
            finished: 0,
            aborted: 0,
            reads_finished: 0,
            finish_error: None,
            write_error_at: None,
            read_len: LOG_LEN,
        }
    }
}

impl FoeFiles for MemFiles {
    fn open_write(&mut self, name: &[u8], password: u32, in_boot: bool) -> Result<(), ErrorCode> {
        assert_eq!(self.open, Open::None, "open while a transfer is open");
        match name {
            b"app.bin" if !in_boot => Err(ErrorCode::BootstrapOnly),
            b"app.bin" | b"log.txt" if password == 0 => {
                self.open = Open::Image;
                self.len = 0;
                Ok(())
            }
            b"app.bin" | b"log.txt" => Err(ErrorCode::NoRights),
            _ => Err(ErrorCode::NotFound),
        }
    }
    fn write(&mut self, offset: u32, data: &[u8]) -> WriteStatus {
        assert_eq!(self.open, Open::Image);
        assert!(!data.is_empty());
        self.write_calls += 1;
        if self.busy_left > 0 && offset == self.busy_at {
            self.busy_left -= 1;
            return WriteStatus::Busy {
                done_percent: 40 + self.busy_left * 100,
            };
        }
        if self.write_error_at == Some(offset) {
            return WriteStatus::Err(ErrorCode::FlashError);
        }
        assert_eq!(offset as usize, self.len, "writes are contiguous");
        let Some(dst) = self.image.get_mut(self.len..self.len + data.len()) else {
            return WriteStatus::Err(ErrorCode::DiskFull);
        };
        dst.copy_from_slice(data);
        self.len += data.len();
        WriteStatus::Done
    }
    fn finish_write(&mut self) -> Result<(), ErrorCode> {
        assert_eq!(self.open, Open::Image);
        if let Some(e) = self.finish_error {
            return Err(e);
        }
        self.open = Open::None;
        self.finished += 1;
        Ok(())
    }
    fn open_read(&mut self, name: &[u8], password: u32, _in_boot: bool) -> Result<u32, ErrorCode> {
        assert_eq!(self.open, Open::None, "open while a transfer is open");
        match (name, password) {
            (b"log.txt", _) => {
                self.open = Open::Log;
                Ok(self.read_len)
            }
            (b"secret", SECRET) => {
                self.open = Open::Log;
                Ok(4)
            }
            (b"secret", _) => Err(ErrorCode::NoRights),
            _ => Err(ErrorCode::NotFound),
        }
    }
    fn read(&mut self, offset: u32, buf: &mut [u8]) -> usize {
        assert_eq!(self.open, Open::Log);
        assert!(offset as usize + buf.len() <= self.read_len as usize);
        for (i, b) in buf.iter_mut().enumerate() {
            *b = pattern(offset as usize + i);
        }
        buf.len()
    }
    fn finish_read(&mut self) {
        assert_eq!(self.open, Open::Log);
        self.open = Open::None;
        self.reads_finished += 1;
    }
    fn abort(&mut self) {
        assert_ne!(self.open, Open::None, "abort without an open transfer");
        self.open = Open::None;
        self.aborted += 1;
    }
}

struct Out {
    buf: [u8; MAX],
    len: usize,
}

impl Out {
    fn payload(&self) -> &[u8] {
        &self.buf[6..self.len]
    }
    fn mtype(&self) -> u8 {
        self.buf[5] & 0x0F
    }
}

struct H {
    srv: MailboxServer,
    dict: ExampleDictionary,
    files: MemFiles,
    size: usize,
    cnt: u8,
    now: u64,
    state: EsmState,
    /// Serve FoE (false: no backend, as an application without files).
    with_foe: bool,
}

impl H {
    fn new(size: usize) -> Self {
        H {
            srv: MailboxServer::new(size),
            dict: ExampleDictionary::new(),
            files: MemFiles::new(),
            size,
            cnt: 0,
            now: 0,
            state: EsmState::Bootstrap,
            with_foe: true,
        }
    }
    fn segment(&self) -> usize {
        self.size - foe::OVERHEAD
    }
    fn next_cnt(&mut self) -> u8 {
        self.cnt = if self.cnt >= 7 { 1 } else { self.cnt + 1 };
        self.cnt
    }
    fn send(&mut self, t: u8, payload: &[u8]) {
        let c = self.next_cnt();
        self.send_with(t, c, payload);
    }
    fn send_with(&mut self, t: u8, counter: u8, payload: &[u8]) {
        let mut f = [0u8; MAX];
        f[0..2].copy_from_slice(&(payload.len() as u16).to_le_bytes());
        f[5] = t | (counter << 4);
        f[6..6 + payload.len()].copy_from_slice(payload);
        let len = self.size.max(6 + payload.len());
        self.raw(&f[..len]);
    }
    fn raw(&mut self, frame: &[u8]) {
        let foe: Option<&mut dyn FoeFiles> = if self.with_foe {
            Some(&mut self.files)
        } else {
            None
        };
        let h = Handlers {
            coe: Some(&mut self.dict),
            foe,
        };
        self.srv.on_request_with(frame, h, self.state, self.now);
    }
    fn recv(&mut self) -> Out {
        let mut o = Out {
            buf: [0xAA; MAX],
            len: 0,
        };
        o.len = self.srv.next_output(&mut o.buf[..self.size], self.now);
        assert!(o.len >= 6 && o.len <= self.size, "frame length {}", o.len);
        assert_eq!(u16::from_le_bytes([o.buf[0], o.buf[1]]) as usize, o.len - 6);
        o
    }
    fn none(&mut self) {
        let mut b = [0u8; MAX];
        assert_eq!(self.srv.next_output(&mut b[..self.size], self.now), 0);
    }
    /// FoE request → FoE answer.
    fn foe(&mut self, payload: &[u8]) -> Out {
        self.send(4, payload);
        let o = self.recv();
        assert_eq!(o.mtype(), 4);
        o
    }
    fn wrq(&mut self, name: &[u8], password: u32) -> Out {
        self.foe(&request(2, password, name)[..req_len(name)])
    }
    fn rrq(&mut self, name: &[u8], password: u32) -> Out {
        self.foe(&request(1, password, name)[..req_len(name)])
    }
    fn data(&mut self, packet: u32, data: &[u8]) -> Out {
        let mut p = [0u8; MAX];
        p[0] = 3;
        p[2..6].copy_from_slice(&packet.to_le_bytes());
        p[6..6 + data.len()].copy_from_slice(data);
        self.foe(&p[..6 + data.len()])
    }
    fn ack(&mut self, packet: u32) {
        let mut p = [4u8, 0, 0, 0, 0, 0];
        p[2..6].copy_from_slice(&packet.to_le_bytes());
        self.send(4, &p);
    }
    fn expect_mbx_error(&mut self, detail: u8) {
        let o = self.recv();
        assert_eq!(o.mtype(), 0);
        assert_eq!(o.payload(), &[0x01, 0x00, detail, 0x00]);
    }
    /// Writes `n` pattern bytes to "app.bin" the way SOEM does; returns the packets sent.
    fn write_file(&mut self, n: usize) -> u32 {
        assert_eq!(self.wrq(b"app.bin", 0).payload(), ack(0));
        let seg = self.segment();
        let mut img = [0u8; IMAGE + MAX];
        for (i, b) in img.iter_mut().enumerate() {
            *b = pattern(i);
        }
        let mut sent = 0;
        let mut at = 0;
        loop {
            let k = (n - at).min(seg);
            sent += 1;
            let o = self.data(sent, &img[at..at + k]);
            assert_eq!(o.payload(), ack(sent));
            at += k;
            if k < seg {
                return sent;
            }
        }
    }
}

fn request(op: u8, password: u32, name: &[u8]) -> [u8; 64] {
    assert!(name.len() <= 58);
    let mut p = [0u8; 64];
    p[0] = op;
    p[2..6].copy_from_slice(&password.to_le_bytes());
    p[6..6 + name.len()].copy_from_slice(name);
    p
}

/// The request above, cut to its real length.
fn req_len(name: &[u8]) -> usize {
    6 + name.len()
}

fn ack(packet: u32) -> &'static [u8] {
    // Small table of the ACK frames the tests expect.
    const ACKS: [[u8; 6]; 8] = [
        [4, 0, 0, 0, 0, 0],
        [4, 0, 1, 0, 0, 0],
        [4, 0, 2, 0, 0, 0],
        [4, 0, 3, 0, 0, 0],
        [4, 0, 4, 0, 0, 0],
        [4, 0, 5, 0, 0, 0],
        [4, 0, 6, 0, 0, 0],
        [4, 0, 7, 0, 0, 0],
    ];
    &ACKS[packet as usize]
}

fn err(code: ErrorCode) -> [u8; 6] {
    let c = code.code().to_le_bytes();
    [5, 0, c[0], c[1], c[2], c[3]]
}

fn check_image(h: &H, n: usize) {
    assert_eq!(h.files.len, n);
    for (i, b) in h.files.image[..n].iter().enumerate() {
        assert_eq!(*b, pattern(i), "image byte {i}");
    }
}

qemu_runner::tests! {
    fn write_of_whole_segments_ends_with_a_zero_byte_data() {
        let mut h = H::new(128);
        assert_eq!(h.segment(), 116);
        let n = 3 * 116;
        assert_eq!(h.write_file(n), 4);
        check_image(&h, n);
        assert_eq!(h.files.finished, 1);
        assert_eq!(h.files.aborted, 0);
        assert_eq!(h.files.write_calls, 3);
        assert_eq!(h.srv.foe_active(), None);
    }

    fn write_of_a_partial_last_segment() {
        let mut h = H::new(128);
        let n = 2 * 116 + 17;
        assert_eq!(h.write_file(n), 3);
        check_image(&h, n);
        assert_eq!(h.files.finished, 1);
        // A second file after the first: numbering starts again at 1.
        assert_eq!(h.write_file(5), 1);
        check_image(&h, 5);
        assert_eq!(h.files.finished, 2);
        // An empty file.
        assert_eq!(h.write_file(0), 1);
        assert_eq!(h.files.len, 0);
        assert_eq!(h.files.finished, 3);
    }

    fn busy_answer_then_the_resent_data_is_written() {
        let mut h = H::new(128);
        assert_eq!(h.wrq(b"app.bin", 0).payload(), ack(0));
        let seg = [0x5Au8; 116];
        assert_eq!(h.data(1, &seg).payload(), ack(1));
        h.files.busy_left = 2;
        h.files.busy_at = 116;
        // BUSY, progress in percent of 100; the master resends DATA 2 (new counter).
        assert_eq!(h.data(2, &seg).payload(), &[6, 0, 100, 0, 100, 0]);
        assert_eq!(h.data(2, &seg).payload(), &[6, 0, 40, 0, 100, 0]);
        assert_eq!(h.files.len, 116);
        assert_eq!(h.data(2, &seg).payload(), ack(2));
        assert_eq!(h.files.len, 232);
        assert_eq!(h.data(3, &[1, 2]).payload(), ack(3));
        assert_eq!(h.files.len, 234);
        assert_eq!(h.files.finished, 1);
        assert_eq!(h.files.write_calls, 5);
    }

    fn repeated_packet_number_aborts_with_0x8005() {
        let mut h = H::new(128);
        h.wrq(b"app.bin", 0);
        let seg = [1u8; 116];
        assert_eq!(h.data(1, &seg).payload(), ack(1));
        assert_eq!(h.data(1, &seg).payload(), err(ErrorCode::PacketNumber));
        assert_eq!(h.files.aborted, 1);
        assert_eq!(h.srv.foe_active(), None);
        // The transfer is gone: the next DATA is illegal, a new WRQ works.
        assert_eq!(h.data(2, &seg).payload(), err(ErrorCode::Illegal));
        assert_eq!(h.files.aborted, 1);
        assert_eq!(h.write_file(10), 1);
    }

    fn out_of_order_packet_aborts_with_0x8005() {
        let mut h = H::new(128);
        h.wrq(b"app.bin", 0);
        assert_eq!(h.data(2, &[1u8; 116]).payload(), err(ErrorCode::PacketNumber));
        assert_eq!(h.files.aborted, 1);
        assert_eq!(h.files.write_calls, 0);
        h.wrq(b"app.bin", 0);
        assert_eq!(h.data(1, &[1u8; 116]).payload(), ack(1));
        assert_eq!(h.data(3, &[1u8; 116]).payload(), err(ErrorCode::PacketNumber));
        assert_eq!(h.files.aborted, 2);
    }

    fn mailbox_repetition_of_a_data_is_not_written_twice() {
        let mut h = H::new(128);
        h.wrq(b"app.bin", 0);
        let seg = [7u8; 116];
        assert_eq!(h.data(1, &seg).payload(), ack(1));
        // Same mailbox counter again: the master did not get the ACK; it is repeated.
        let c = h.cnt;
        let mut p = [0u8; 122];
        p[0] = 3;
        p[2] = 1;
        p[6..].copy_from_slice(&seg);
        h.send_with(4, c, &p);
        assert_eq!(h.recv().payload(), ack(1));
        assert_eq!(h.files.write_calls, 1);
        assert_eq!(h.data(2, &[]).payload(), ack(2));
        assert_eq!(h.files.finished, 1);
    }

    fn oversized_data_is_illegal() {
        // Server for a 64-byte mailbox (segment 52) fed a longer frame.
        let mut h = H::new(64);
        h.wrq(b"app.bin", 0);
        let mut f = [0u8; 6 + 6 + 53];
        f[0] = 59;
        f[5] = 4 | (h.next_cnt() << 4);
        f[6] = 3;
        f[8] = 1;
        h.raw(&f);
        assert_eq!(h.recv().payload(), err(ErrorCode::Illegal));
        assert_eq!(h.files.aborted, 1);
        assert_eq!(h.files.write_calls, 0);
    }

    fn data_and_ack_without_a_transfer_are_illegal() {
        let mut h = H::new(128);
        assert_eq!(h.data(1, &[1, 2, 3]).payload(), err(ErrorCode::Illegal));
        h.ack(1);
        assert_eq!(h.recv().payload(), err(ErrorCode::Illegal));
        // ACK during a write, DATA during a read: illegal, transfer aborted.
        h.wrq(b"app.bin", 0);
        h.ack(0);
        assert_eq!(h.recv().payload(), err(ErrorCode::Illegal));
        assert_eq!(h.files.aborted, 1);
        assert_eq!(h.rrq(b"log.txt", 0).payload()[..6], [3, 0, 1, 0, 0, 0]);
        assert_eq!(h.data(1, &[1]).payload(), err(ErrorCode::Illegal));
        assert_eq!(h.files.aborted, 2);
        // BUSY and unknown opcodes from the master.
        h.wrq(b"app.bin", 0);
        assert_eq!(h.foe(&[6, 0, 0, 0, 0, 0]).payload(), err(ErrorCode::Illegal));
        assert_eq!(h.files.aborted, 3);
        for op in [0u8, 7, 0xFF] {
            assert_eq!(h.foe(&[op, 0, 0, 0, 0, 0]).payload(), err(ErrorCode::Illegal));
        }
        assert_eq!(h.files.aborted, 3);
        // Shorter than the FoE header: mailbox error "size too short"; aborts.
        h.wrq(b"app.bin", 0);
        h.send(4, &[3, 0, 1]);
        h.expect_mbx_error(0x06);
        assert_eq!(h.files.aborted, 4);
        assert_eq!(h.srv.foe_active(), None);
        // The server keeps running.
        assert_eq!(h.write_file(3), 1);
    }

    fn master_error_aborts_silently() {
        let mut h = H::new(128);
        h.wrq(b"app.bin", 0);
        assert_eq!(h.data(1, &[1u8; 116]).payload(), ack(1));
        h.send(4, &[5, 0, 0x00, 0x80, 0, 0, b'x']);
        h.none();
        assert_eq!(h.files.aborted, 1);
        assert_eq!(h.srv.foe_active(), None);
        // ERR without a transfer: nothing at all.
        h.send(4, &[5, 0, 0x01, 0x80, 0, 0]);
        h.none();
        assert_eq!(h.files.aborted, 1);
        // During a read.
        h.rrq(b"log.txt", 0);
        h.send(4, &[5, 0, 0x00, 0x80, 0, 0]);
        h.none();
        assert_eq!(h.files.aborted, 2);
    }

    fn stalled_transfer_times_out() {
        let mut h = H::new(128);
        h.now = 1_000_000;
        h.wrq(b"app.bin", 0);
        h.now = 3_000_000;
        assert_eq!(h.data(1, &[1u8; 116]).payload(), ack(1));
        let t = foe::DEFAULT_TIMEOUT_US;
        assert!(!h.srv.foe_tick(3_000_000 + t, &mut h.files));
        assert_eq!(h.files.aborted, 0);
        assert!(h.srv.foe_tick(3_000_001 + t, &mut h.files));
        assert_eq!(h.files.aborted, 1);
        h.none();
        // The late DATA finds no transfer.
        h.now = 3_000_002 + t;
        assert_eq!(h.data(2, &[1]).payload(), err(ErrorCode::Illegal));
        // Shorter timeout, and a read that stops being acknowledged.
        h.srv.set_foe_timeout_us(500);
        h.rrq(b"log.txt", 0);
        assert!(!h.srv.foe_tick(h.now + 500, &mut h.files));
        assert!(h.srv.foe_tick(h.now + 501, &mut h.files));
        assert_eq!(h.files.aborted, 2);
        assert!(!h.srv.foe_tick(h.now + 10_000, &mut h.files));
    }

    fn write_outside_bootstrap_is_refused() {
        for state in [EsmState::PreOp, EsmState::SafeOp, EsmState::Op] {
            let mut h = H::new(128);
            h.state = state;
            assert_eq!(h.wrq(b"app.bin", 0).payload(), err(ErrorCode::BootstrapOnly));
            assert_eq!(h.data(1, &[1]).payload(), err(ErrorCode::Illegal));
            assert_eq!(h.files.aborted, 0);
            // The backend allows another file outside Bootstrap, and reads.
            assert_eq!(h.wrq(b"log.txt", 0).payload(), ack(0));
            assert_eq!(h.data(1, &[1, 2]).payload(), ack(1));
            assert_eq!(h.rrq(b"log.txt", 0).payload()[..6], [3, 0, 1, 0, 0, 0]);
        }
        let mut h = H::new(128);
        assert_eq!(h.wrq(b"nope.bin", 0).payload(), err(ErrorCode::NotFound));
        assert_eq!(h.wrq(b"app.bin", 1).payload(), err(ErrorCode::NoRights));
        assert_eq!(h.wrq(b"", 0).payload(), err(ErrorCode::NotFound));
    }

    fn new_write_request_replaces_the_open_transfer() {
        let mut h = H::new(128);
        h.wrq(b"app.bin", 0);
        assert_eq!(h.data(1, &[1u8; 116]).payload(), ack(1));
        assert_eq!(h.wrq(b"app.bin", 0).payload(), ack(0));
        assert_eq!(h.files.aborted, 1);
        assert_eq!(h.files.len, 0);
        assert_eq!(h.data(1, &[9; 3]).payload(), ack(1));
        assert_eq!(h.files.finished, 1);
        // A read request replaces a write too.
        h.wrq(b"app.bin", 0);
        assert_eq!(h.rrq(b"secret", SECRET).payload(), &[3, 0, 1, 0, 0, 0, 3, 10, 17, 24]);
        assert_eq!(h.files.aborted, 2);
    }

    fn backend_errors_are_answered_and_abort() {
        let mut h = H::new(128);
        h.files.finish_error = Some(ErrorCode::InvalidChecksum);
        h.wrq(b"app.bin", 0);
        assert_eq!(h.data(1, &[1u8; 116]).payload(), ack(1));
        assert_eq!(h.data(2, &[1u8; 5]).payload(), err(ErrorCode::InvalidChecksum));
        assert_eq!(h.files.aborted, 1);
        h.files.finish_error = None;
        h.files.write_error_at = Some(116);
        h.wrq(b"app.bin", 0);
        assert_eq!(h.data(1, &[1u8; 116]).payload(), ack(1));
        assert_eq!(h.data(2, &[1u8; 116]).payload(), err(ErrorCode::FlashError));
        assert_eq!(h.files.aborted, 2);
        // A file too large for its partition.
        h.files.write_error_at = None;
        h.wrq(b"app.bin", 0);
        let mut last = [0u8; 6];
        for p in 1..=9 {
            last.copy_from_slice(&h.data(p, &[0u8; 116]).payload()[..6]);
        }
        assert_eq!(last, err(ErrorCode::DiskFull));
        assert_eq!(h.files.aborted, 3);
    }

    fn read_of_a_file() {
        let mut h = H::new(128);
        h.state = EsmState::PreOp;
        assert_eq!(h.rrq(b"nope", 0).payload(), err(ErrorCode::NotFound));
        assert_eq!(h.rrq(b"secret", 1).payload(), err(ErrorCode::NoRights));
        // 300 bytes = 116 + 116 + 68.
        let mut got = [0u8; 512];
        let mut n = 0;
        let mut o = h.rrq(b"log.txt", 0);
        for packet in 1..=3u32 {
            let p = o.payload();
            assert_eq!(p[..6], [3, 0, packet as u8, 0, 0, 0]);
            let d = &p[6..];
            got[n..n + d.len()].copy_from_slice(d);
            n += d.len();
            h.ack(packet);
            if packet < 3 {
                assert_eq!(d.len(), 116);
                o = h.recv();
            } else {
                assert_eq!(d.len(), 68);
            }
        }
        h.none();
        assert_eq!(n, LOG_LEN as usize);
        for (i, b) in got[..n].iter().enumerate() {
            assert_eq!(*b, pattern(i));
        }
        assert_eq!(h.files.reads_finished, 1);
        assert_eq!(h.srv.foe_active(), None);
    }

    fn read_of_whole_segments_ends_with_a_zero_byte_data() {
        let mut h = H::new(128);
        h.files.read_len = 232;
        let o = h.rrq(b"log.txt", 0);
        assert_eq!(o.payload().len(), 6 + 116);
        h.ack(1);
        assert_eq!(h.recv().payload().len(), 6 + 116);
        h.ack(2);
        assert_eq!(h.recv().payload(), &[3, 0, 3, 0, 0, 0]);
        h.ack(3);
        h.none();
        assert_eq!(h.files.reads_finished, 1);
        // An empty file is one 0-byte DATA.
        h.files.read_len = 0;
        assert_eq!(h.rrq(b"log.txt", 0).payload(), &[3, 0, 1, 0, 0, 0]);
        h.ack(1);
        h.none();
        assert_eq!(h.files.reads_finished, 2);
        // An ACK of the wrong DATA aborts.
        h.files.read_len = 232;
        h.rrq(b"log.txt", 0);
        h.ack(2);
        assert_eq!(h.recv().payload(), err(ErrorCode::PacketNumber));
        assert_eq!(h.files.aborted, 1);
    }

    fn read_is_refused_when_sm1_is_shorter_than_sm0() {
        let mut h = H::new(128);
        h.srv.set_mailbox_sizes(128, 64);
        h.size = 64;
        assert_eq!(h.srv.foe_segment(), 116);
        assert_eq!(h.rrq(b"log.txt", 0).payload(), err(ErrorCode::Illegal));
        assert_eq!(h.files.aborted, 0);
        // Writes still use SM0's segment.
        assert_eq!(h.wrq(b"app.bin", 0).payload(), ack(0));
    }

    fn without_a_backend_foe_answers_unsupported_protocol() {
        let mut h = H::new(128);
        h.with_foe = false;
        h.state = EsmState::PreOp;
        h.send(4, &request(2, 0, b"app.bin")[..req_len(b"app.bin")]);
        h.expect_mbx_error(0x02);
        // The plain CoE entry point behaves the same.
        let mut f = [0u8; 128];
        f[0] = 6;
        f[5] = 4 | (h.next_cnt() << 4);
        f[6] = 1;
        h.srv.on_request(&f, &mut h.dict, EsmState::PreOp, 0);
        h.expect_mbx_error(0x02);
        // CoE is still served next to FoE.
        h.with_foe = true;
        h.send(3, &[0x00, 0x20, 0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]);
        let o = h.recv();
        assert_eq!(o.mtype(), 3);
        assert_eq!(o.payload()[..2], [0x00, 0x30]);
        // No CoE handler (Bootstrap): CoE answers unsupported protocol.
        let c = h.next_cnt();
        let mut f = [0u8; 128];
        f[0] = 10;
        f[5] = 3 | (c << 4);
        f[6..16].copy_from_slice(&[0x00, 0x20, 0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]);
        let h2 = Handlers::<ExampleDictionary>::foe(Some(&mut h.files));
        h.srv.on_request_with(&f, h2, EsmState::Bootstrap, 0);
        h.expect_mbx_error(0x02);
    }
}
