use super::*;

#[test]
fn every_opcode_round_trips() {
    let name = b"app.bin";
    let reprs = [
        (
            Repr::Read {
                password: 0x1234_5678,
                name,
            },
            &[
                1u8, 0, 0x78, 0x56, 0x34, 0x12, b'a', b'p', b'p', b'.', b'b', b'i', b'n',
            ][..],
        ),
        (
            Repr::Write {
                password: 0,
                name: b"x",
            },
            &[2, 0, 0, 0, 0, 0, b'x'][..],
        ),
        (
            Repr::Data {
                packet: 0x0102_0304,
                data: &[9, 8, 7],
            },
            &[3, 0, 4, 3, 2, 1, 9, 8, 7][..],
        ),
        (
            Repr::Data {
                packet: 7,
                data: &[],
            },
            &[3, 0, 7, 0, 0, 0][..],
        ),
        (Repr::Ack { packet: 0 }, &[4, 0, 0, 0, 0, 0][..]),
        (
            Repr::Error {
                code: ErrorCode::PacketNumber.code(),
                text: b"no",
            },
            &[5, 0, 0x05, 0x80, 0, 0, b'n', b'o'][..],
        ),
        (
            Repr::Busy {
                done: 42,
                entire: 100,
                text: &[],
            },
            &[6, 0, 42, 0, 100, 0][..],
        ),
    ];
    for (r, bytes) in reprs {
        let f = Frame::new_checked(bytes).unwrap();
        assert_eq!(Repr::parse(&f), Ok(r));
        assert_eq!(r.buffer_len(), bytes.len());
        let mut buf = [0xEEu8; 32];
        let n = r.emit(&mut Frame::new_unchecked(&mut buf[..]));
        assert_eq!(&buf[..n], bytes);
        assert_eq!(buf[n], 0xEE);
        // Too short a buffer is left alone.
        let mut short = [0xEEu8; 32];
        let m = bytes.len() - 1;
        assert_eq!(r.emit(&mut Frame::new_unchecked(&mut short[..m])), 0);
        assert!(short.iter().all(|b| *b == 0xEE));
    }
}

#[test]
fn accessors_never_panic() {
    for len in 0..HEADER_LEN {
        let b = [3u8, 1, 2, 3, 4, 5];
        let f = Frame::new_unchecked(&b[..len]);
        assert_eq!(f.check_len(), Err(WireError::Truncated));
        assert_eq!(Repr::parse(&f), Err(WireError::Truncated));
        let _ = (
            f.opcode(),
            f.arg(),
            f.busy_done(),
            f.busy_entire(),
            f.reserved(),
        );
        assert!(f.payload().is_empty());
        let mut m = [0u8; 6];
        let mut f = Frame::new_unchecked(&mut m[..len]);
        f.set_opcode(Opcode::Ack);
        f.set_arg(1);
        f.set_busy(1, 2);
        assert!(f.payload_mut().is_empty());
    }
    let b = [0u8, 0, 0, 0, 0, 0];
    assert_eq!(
        Repr::parse(&Frame::new_unchecked(&b[..])),
        Err(WireError::UnknownOpcode(0))
    );
    let b = [7u8, 0, 0, 0, 0, 0];
    assert_eq!(
        Repr::parse(&Frame::new_unchecked(&b[..])),
        Err(WireError::UnknownOpcode(7))
    );
    let f = Frame::new_checked(&[6u8, 0, 0x34, 0x12, 0x78, 0x56][..]).unwrap();
    assert_eq!((f.busy_done(), f.busy_entire()), (0x1234, 0x5678));
    assert_eq!(f.arg(), 0x5678_1234);
}

/// A file of `len` bytes of 0x55 that accepts any write.
struct OneFile {
    len: u32,
    aborts: u32,
}

impl FoeFiles for OneFile {
    fn open_write(&mut self, _: &[u8], _: u32, _: bool) -> Result<(), ErrorCode> {
        Ok(())
    }
    fn write(&mut self, _: u32, _: &[u8]) -> WriteStatus {
        WriteStatus::Done
    }
    fn finish_write(&mut self) -> Result<(), ErrorCode> {
        Ok(())
    }
    fn open_read(&mut self, _: &[u8], _: u32, _: bool) -> Result<u32, ErrorCode> {
        Ok(self.len)
    }
    fn read(&mut self, _: u32, buf: &mut [u8]) -> usize {
        buf.fill(0x55);
        // A backend claiming more than the buffer is clamped by the server.
        buf.len() + 10
    }
    fn abort(&mut self) {
        self.aborts += 1;
    }
}

#[test]
fn server_edge_cases() {
    let ctx = Context {
        in_boot: true,
        write_segment: 8,
        read_segment: 8,
        now_us: 0,
    };
    let mut files = OneFile { len: 20, aborts: 0 };
    let mut srv = FoeServer::new();
    let mut out = [0u8; 32];
    assert!(!srv.tick(u64::MAX, &mut files));
    assert!(!srv.abort(&mut files));
    // A read into an output buffer too short for the segment: ERR 0x800B, aborted.
    let rrq = [1u8, 0, 0, 0, 0, 0, b'f'];
    let a = srv.on_request(&rrq, &mut files, ctx, &mut out[..10]);
    assert_eq!(a, Answer::Frame(6));
    assert_eq!(out[..6], [5, 0, 0x0B, 0x80, 0, 0]);
    assert_eq!((srv.active(), files.aborts), (None, 1));
    // A read of 20 bytes in segments of 8: 8, 8, 4.
    let mut got = 0;
    let mut a = srv.on_request(&rrq, &mut files, ctx, &mut out);
    for packet in 1..=3u8 {
        let Answer::Frame(n) = a else { panic!("{a:?}") };
        assert_eq!(out[..3], [3, 0, packet]);
        got += n - HEADER_LEN;
        assert_eq!(srv.active(), Some(Direction::Read));
        a = srv.on_request(&[4, 0, packet, 0, 0, 0], &mut files, ctx, &mut out);
    }
    assert_eq!((a, got, srv.active()), (Answer::None, 20, None));
    // Reads refused without a read segment; the write offset is reported.
    let ctx0 = Context {
        read_segment: 0,
        ..ctx
    };
    srv.on_request(&rrq, &mut files, ctx0, &mut out);
    assert_eq!(out[..6], [5, 0, 0x04, 0x80, 0, 0]);
    srv.on_request(&[2, 0, 0, 0, 0, 0], &mut files, ctx, &mut out);
    srv.on_request(
        &[3, 0, 1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8],
        &mut files,
        ctx,
        &mut out,
    );
    assert_eq!(srv.write_offset(), 8);
    // No output room at all: nothing is answered, nothing panics.
    assert_eq!(
        srv.on_request(&[3, 0, 2, 0, 0, 0], &mut files, ctx, &mut []),
        Answer::None
    );
    assert_eq!(srv.active(), None);
    srv.set_timeout_us(5);
    assert_eq!(srv.timeout_us(), 5);
}

#[test]
fn opcodes_and_error_codes() {
    for v in 0..=255u8 {
        assert_eq!(Opcode::from_u8(v).code(), v);
    }
    assert_eq!(ErrorCode::ALL.len(), 17);
    for w in ErrorCode::ALL.windows(2) {
        assert!(w[0].code() < w[1].code());
    }
    for c in ErrorCode::ALL {
        assert_eq!(ErrorCode::from_code(c.code()), Some(*c));
        assert!(!c.text().is_empty());
    }
    assert_eq!(ErrorCode::from_code(0x800E), None);
    assert_eq!(ErrorCode::from_code(0x7FFF), None);
    assert_eq!(ErrorCode::from_code(0x8012), None);
    assert_eq!(ErrorCode::BootstrapOnly.code(), 0x8008);
    assert_eq!(ErrorCode::NotInBootstrap.code(), 0x8009);
    assert_eq!(ErrorCode::FlashError.code(), 0x8011);
}
