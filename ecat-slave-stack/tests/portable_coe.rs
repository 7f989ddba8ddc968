//! Byte-level request/response vectors of the mailbox and CoE services (SDO server,
//! SDO information, emergency), run on the host and under QEMU. The dictionary is
//! `coe::example`.
#![cfg_attr(target_os = "none", no_std, no_main)]

use ecat_slave_stack::coe::example::{ExampleDictionary, DEVICE_NAME};
use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::mailbox::MailboxServer;
use ecat_slave_stack::od::{ObjectKey, SdoAbort};

const MAX: usize = 256;

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
    fn counter(&self) -> u8 {
        (self.buf[5] >> 4) & 7
    }
}

struct H {
    srv: MailboxServer,
    dict: ExampleDictionary,
    size: usize,
    cnt: u8,
    now: u64,
    state: EsmState,
}

impl H {
    fn new(size: usize) -> Self {
        H {
            srv: MailboxServer::new(size),
            dict: ExampleDictionary::new(),
            size,
            cnt: 0,
            now: 0,
            state: EsmState::PreOp,
        }
    }
    fn next_cnt(&mut self) -> u8 {
        self.cnt = if self.cnt >= 7 { 1 } else { self.cnt + 1 };
        self.cnt
    }
    /// Sends a frame of mailbox type `t` with the next counter, padded to the mailbox size.
    fn send(&mut self, t: u8, payload: &[u8]) {
        let c = self.next_cnt();
        self.send_with(t, c, payload);
    }
    fn send_with(&mut self, t: u8, counter: u8, payload: &[u8]) {
        let mut f = [0u8; MAX];
        f[0..2].copy_from_slice(&(payload.len() as u16).to_le_bytes());
        f[5] = t | (counter << 4);
        f[6..6 + payload.len()].copy_from_slice(payload);
        self.raw(&f[..self.size]);
    }
    fn raw(&mut self, frame: &[u8]) {
        self.srv
            .on_request(frame, &mut self.dict, self.state, self.now);
    }
    /// The next SM1 frame, checked to be a well-formed mailbox frame.
    fn recv(&mut self) -> Out {
        let mut o = Out {
            buf: [0xAA; MAX],
            len: 0,
        };
        o.len = self.srv.next_output(&mut o.buf[..self.size], self.now);
        assert!(o.len >= 6 && o.len <= self.size, "frame length {}", o.len);
        assert_eq!(u16::from_le_bytes([o.buf[0], o.buf[1]]) as usize, o.len - 6);
        assert!((1..=7).contains(&o.counter()));
        o
    }
    fn none(&mut self) {
        let mut b = [0u8; MAX];
        assert_eq!(self.srv.next_output(&mut b[..self.size], self.now), 0);
    }
    /// CoE request → CoE answer.
    fn coe(&mut self, payload: &[u8]) -> Out {
        self.send(3, payload);
        let o = self.recv();
        assert_eq!(o.mtype(), 3);
        o
    }
    fn upload(&mut self, index: u16, sub: u8) -> Out {
        let i = index.to_le_bytes();
        self.coe(&[0x00, 0x20, 0x40, i[0], i[1], sub, 0, 0, 0, 0])
    }
    fn download4(&mut self, cmd: u8, index: u16, sub: u8, d: [u8; 4]) -> Out {
        let i = index.to_le_bytes();
        self.coe(&[0x00, 0x20, cmd, i[0], i[1], sub, d[0], d[1], d[2], d[3]])
    }
    fn expect_abort(&mut self, o: &Out, index: u16, sub: u8, a: SdoAbort) {
        let i = index.to_le_bytes();
        let c = a.code().to_le_bytes();
        assert_eq!(
            o.payload(),
            &[0x00, 0x20, 0x80, i[0], i[1], sub, c[0], c[1], c[2], c[3]]
        );
    }
    fn expect_mbx_error(&mut self, detail: u8) {
        let o = self.recv();
        assert_eq!(o.mtype(), 0);
        assert_eq!(o.payload(), &[0x01, 0x00, detail, 0x00]);
    }
}

const DL_OK_2000: [u8; 10] = [0x00, 0x30, 0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0];
const SEG_ACK0: [u8; 10] = [0x00, 0x30, 0x20, 0, 0, 0, 0, 0, 0, 0];
const SEG_ACK1: [u8; 10] = [0x00, 0x30, 0x30, 0, 0, 0, 0, 0, 0, 0];

fn pattern(i: usize) -> u8 {
    (i * 7 + 3) as u8
}

/// Writes `n` pattern bytes into 0x2002 through a 128-byte mailbox (initiate with 112
/// bytes, then segments of at most 50).
fn long_download(h: &mut H, n: usize) {
    let mut f = [0u8; 122];
    f[..10].copy_from_slice(&[
        0x00,
        0x20,
        0x21,
        0x02,
        0x20,
        0x00,
        n as u8,
        (n >> 8) as u8,
        0,
        0,
    ]);
    let first = n.min(112);
    for i in 0..first {
        f[10 + i] = pattern(i);
    }
    let o = h.coe(&f[..10 + first]);
    assert_eq!(
        o.payload(),
        &[0x00, 0x30, 0x60, 0x02, 0x20, 0x00, 0, 0, 0, 0]
    );
    let mut pos = first;
    let mut toggle = false;
    while pos < n {
        let k = (n - pos).min(50);
        let last = pos + k == n;
        let mut s = [0u8; 60];
        let pad = 7usize.saturating_sub(k);
        s[0] = 0x00;
        s[1] = 0x20;
        s[2] = (if toggle { 0x10 } else { 0 }) | ((pad as u8) << 1) | if last { 1 } else { 0 };
        for i in 0..k {
            s[3 + i] = pattern(pos + i);
        }
        let o = h.coe(&s[..3 + k + pad]);
        assert_eq!(o.payload(), if toggle { &SEG_ACK1 } else { &SEG_ACK0 });
        pos += k;
        toggle = !toggle;
    }
    assert_eq!(h.dict.long_text().len(), n);
    assert!(h
        .dict
        .long_text()
        .iter()
        .enumerate()
        .all(|(i, b)| *b == pattern(i)));
}

qemu_runner::tests! {
    fn expedited_upload_vectors() {
        let mut h = H::new(128);
        let o = h.upload(0x1000, 0);
        assert_eq!(&o.buf[..6], &[10, 0, 0, 0, 0, 0x13]);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00]);
        let o = h.upload(0x1001, 0);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x4F, 0x01, 0x10, 0x00, 0, 0, 0, 0]);
        h.dict.set_value(ObjectKey::new(0x6041, 0), 0x0237);
        let o = h.upload(0x6041, 0);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x4B, 0x41, 0x60, 0x00, 0x37, 0x02, 0, 0]);
        let o = h.upload(0x2003, 4);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x4B, 0x03, 0x20, 0x04, 0xFE, 0xFF, 0, 0]);
        let o = h.upload(0x2003, 1);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x4F, 0x03, 0x20, 0x01, 0, 0, 0, 0]);
    }

    fn expedited_download_vectors() {
        let mut h = H::new(128);
        let o = h.download4(0x23, 0x2000, 0, 500i32.to_le_bytes());
        assert_eq!(o.payload(), &DL_OK_2000);
        assert_eq!(h.dict.value(ObjectKey::new(0x2000, 0)) as u32 as i32, 500);
        let o = h.download4(0x23, 0x2000, 0, (-1000i32).to_le_bytes());
        assert_eq!(o.payload(), &DL_OK_2000);
        // 2-byte expedited with size indicated into a u16.
        let o = h.download4(0x2B, 0x6040, 0, [0x0F, 0x00, 0xEE, 0xEE]);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x60, 0x40, 0x60, 0x00, 0, 0, 0, 0]);
        assert_eq!(h.dict.value(ObjectKey::new(0x6040, 0)), 0x000F);
        // Size not indicated: the entry's length is used.
        let o = h.download4(0x22, 0x6040, 0, [0x06, 0x00, 0xEE, 0xEE]);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x60, 0x40, 0x60, 0x00, 0, 0, 0, 0]);
        assert_eq!(h.dict.value(ObjectKey::new(0x6040, 0)), 0x0006);
        // 1 byte into a u8 entry of a record.
        let o = h.download4(0x2F, 0x2003, 3, [200, 0, 0, 0]);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x60, 0x03, 0x20, 0x03, 0, 0, 0, 0]);
        assert_eq!(h.dict.value(ObjectKey::new(0x2003, 3)), 200);
        // Write-only entry accepts a write.
        let o = h.download4(0x2B, 0x2001, 0, [0x34, 0x12, 0, 0]);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x60, 0x01, 0x20, 0x00, 0, 0, 0, 0]);
        assert_eq!(h.dict.value(ObjectKey::new(0x2001, 0)), 0x1234);
        // A short string written expedited.
        let o = h.download4(0x27, 0x2002, 0, *b"abc\0");
        assert_eq!(o.payload(), &[0x00, 0x30, 0x60, 0x02, 0x20, 0x00, 0, 0, 0, 0]);
        assert_eq!(h.dict.long_text(), b"abc");
    }

    fn access_and_value_aborts() {
        let mut h = H::new(128);
        let o = h.upload(0x9999, 0);
        h.expect_abort(&o, 0x9999, 0, SdoAbort::ObjectDoesNotExist);
        let o = h.upload(0x1018, 9);
        h.expect_abort(&o, 0x1018, 9, SdoAbort::SubindexDoesNotExist);
        let o = h.upload(0x2001, 0);
        h.expect_abort(&o, 0x2001, 0, SdoAbort::ReadWriteOnly);
        let o = h.download4(0x23, 0x1000, 0, [1, 0, 0, 0]);
        h.expect_abort(&o, 0x1000, 0, SdoAbort::WriteReadOnly);
        let o = h.download4(0x23, 0x2000, 0, 1001i32.to_le_bytes());
        h.expect_abort(&o, 0x2000, 0, SdoAbort::ValueTooHigh);
        let o = h.download4(0x23, 0x2000, 0, (-1001i32).to_le_bytes());
        h.expect_abort(&o, 0x2000, 0, SdoAbort::ValueTooLow);
        let o = h.download4(0x2B, 0x2000, 0, [1, 0, 0, 0]);
        h.expect_abort(&o, 0x2000, 0, SdoAbort::LengthTooLow);
        let o = h.download4(0x23, 0x6040, 0, [1, 0, 0, 0]);
        h.expect_abort(&o, 0x6040, 0, SdoAbort::LengthTooHigh);
        let o = h.download4(0x2F, 0x6040, 0, [1, 0, 0, 0]);
        h.expect_abort(&o, 0x6040, 0, SdoAbort::LengthTooLow);
        let o = h.download4(0x23, 0x9999, 0, [1, 0, 0, 0]);
        h.expect_abort(&o, 0x9999, 0, SdoAbort::ObjectDoesNotExist);
        let o = h.download4(0x22, 0x1018, 7, [1, 0, 0, 0]);
        h.expect_abort(&o, 0x1018, 7, SdoAbort::SubindexDoesNotExist);
        // Mapping rule of the application: entries only while sub-index 0 is 0.
        let o = h.download4(0x23, 0x1600, 1, [0x08, 0, 0x60, 0x60]);
        h.expect_abort(&o, 0x1600, 1, SdoAbort::SubindexZeroFirst);
        // Pre-Op-only entries in Safe-Op.
        h.state = EsmState::SafeOp;
        let o = h.download4(0x2F, 0x1600, 0, [0, 0, 0, 0]);
        h.expect_abort(&o, 0x1600, 0, SdoAbort::StateConflict);
        let o = h.download4(0x2F, 0x2003, 3, [5, 0, 0, 0]);
        h.expect_abort(&o, 0x2003, 3, SdoAbort::StateConflict);
        // Read works in every state.
        let o = h.upload(0x1600, 0);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x4F, 0x00, 0x16, 0x00, 2, 0, 0, 0]);
        // Init: no SDO access at all.
        h.state = EsmState::Init;
        let o = h.upload(0x1000, 0);
        h.expect_abort(&o, 0x1000, 0, SdoAbort::StateConflict);
        assert_eq!(h.dict.writes, 0);
    }

    fn application_aborts_reach_the_master_unchanged() {
        let mut h = H::new(128);
        for a in SdoAbort::ALL {
            let o = h.download4(0x23, 0x2FFF, 0, a.code().to_le_bytes());
            h.expect_abort(&o, 0x2FFF, 0, *a);
        }
        // A code outside the table becomes a general error (the injector's choice).
        let o = h.download4(0x23, 0x2FFF, 0, [1, 2, 3, 4]);
        h.expect_abort(&o, 0x2FFF, 0, SdoAbort::GeneralError);
        let o = h.download4(0x23, 0x2FFF, 0, [0, 0, 0, 0]);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x60, 0xFF, 0x2F, 0x00, 0, 0, 0, 0]);
    }

    fn normal_upload_of_a_string() {
        let mut h = H::new(128);
        let o = h.upload(0x1008, 0);
        let n = DEVICE_NAME.len();
        assert_eq!(&o.payload()[..10], &[0x00, 0x30, 0x41, 0x08, 0x10, 0x00, n as u8, 0, 0, 0]);
        assert_eq!(&o.payload()[10..], DEVICE_NAME.as_bytes());
        // Empty string: normal transfer of size 0.
        let o = h.upload(0x2002, 0);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x41, 0x02, 0x20, 0x00, 0, 0, 0, 0]);
    }

    fn normal_download_in_one_frame() {
        let mut h = H::new(128);
        let mut f = [0u8; 40];
        f[..10].copy_from_slice(&[0x00, 0x20, 0x21, 0x02, 0x20, 0x00, 30, 0, 0, 0]);
        for i in 0..30 {
            f[10 + i] = pattern(i);
        }
        let o = h.coe(&f[..40]);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x60, 0x02, 0x20, 0x00, 0, 0, 0, 0]);
        assert_eq!(h.dict.long_text().len(), 30);
        // Declared size larger than the entry: refused before any segment.
        let o = h.coe(&[0x00, 0x20, 0x21, 0x00, 0x20, 0x00, 8, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8]);
        h.expect_abort(&o, 0x2000, 0, SdoAbort::LengthTooHigh);
        let o = h.coe(&[0x00, 0x20, 0x21, 0x00, 0x20, 0x00, 2, 0, 0, 0, 1, 2]);
        h.expect_abort(&o, 0x2000, 0, SdoAbort::LengthTooLow);
        let o = h.coe(&[0x00, 0x20, 0x21, 0x00, 0x10, 0x00, 4, 0, 0, 0, 1, 2, 3, 4]);
        h.expect_abort(&o, 0x1000, 0, SdoAbort::WriteReadOnly);
        h.state = EsmState::Op;
        let o = h.coe(&[0x00, 0x20, 0x21, 0x00, 0x16, 0x01, 4, 0, 0, 0, 1, 2, 3, 4]);
        h.expect_abort(&o, 0x1600, 1, SdoAbort::StateConflict);
        let o = h.coe(&[0x00, 0x20, 0x21, 0x02, 0x20, 0x00, 0x2D, 0x01, 0, 0, 1, 2, 3, 4]);
        h.expect_abort(&o, 0x2002, 0, SdoAbort::LengthTooHigh);
    }

    fn segmented_download_and_upload() {
        let mut h = H::new(128);
        long_download(&mut h, 300);
        assert!(!h.srv.transfer_active());
        // Upload of the 300 bytes: 112 in the initiate response, then 119 + 69.
        let o = h.upload(0x2002, 0);
        assert_eq!(o.len, 128);
        assert_eq!(&o.payload()[..10], &[0x00, 0x30, 0x41, 0x02, 0x20, 0x00, 0x2C, 0x01, 0, 0]);
        let mut got = [0u8; 300];
        got[..112].copy_from_slice(&o.payload()[10..]);
        assert!(h.srv.transfer_active());
        let o = h.coe(&[0x00, 0x20, 0x60, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(&o.payload()[..3], &[0x00, 0x30, 0x00]);
        assert_eq!(o.payload().len(), 122);
        got[112..231].copy_from_slice(&o.payload()[3..]);
        let o = h.coe(&[0x00, 0x20, 0x70, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(&o.payload()[..3], &[0x00, 0x30, 0x11]);
        assert_eq!(o.payload().len(), 72);
        got[231..].copy_from_slice(&o.payload()[3..]);
        assert!(got.iter().enumerate().all(|(i, b)| *b == pattern(i)));
        assert!(!h.srv.transfer_active());
    }

    fn resizing_mid_transfer_starts_over_like_a_new_server() {
        // A server in the middle of a segmented upload, with a reply and an emergency
        // waiting, is resized (what a state change does): from then on it answers
        // exactly as a new server of that size, and keeps only its overrun counter.
        let mut used = H::new(256);
        long_download(&mut used, 300);
        used.upload(0x2002, 0);
        assert!(used.srv.transfer_active());
        used.send(3, &[0x00, 0x20, 0x40, 0x00, 0x10, 0, 0, 0, 0, 0]);
        for _ in 0..12 {
            used.srv.emergency(0x5210, 0x01, [1, 2, 3, 4, 5]);
        }
        let overruns = used.srv.emergency_overruns();
        assert!(overruns > 0);
        used.srv.set_mailbox_size(128);
        used.size = 128;
        used.cnt = 0;
        assert!(!used.srv.transfer_active());
        assert_eq!(used.srv.mailbox_size(), 128);
        assert_eq!(used.srv.emergencies_queued(), 0);
        assert_eq!(used.srv.emergency_overruns(), overruns);
        used.none();
        let mut b = [0u8; MAX];
        assert_eq!(used.srv.repeat_last(&mut b), 0);
        let mut fresh = H::new(128);
        // Segment request without a transfer, a long upload, its segments.
        for h in [&mut used, &mut fresh] {
            long_download(h, 150);
        }
        let mut answers = [[[0u8; MAX]; 4]; 2];
        for (k, h) in [&mut used, &mut fresh].into_iter().enumerate() {
            let steps: [&[u8]; 4] = [
                &[0x00, 0x20, 0x60, 0, 0, 0, 0, 0, 0, 0],
                &[0x00, 0x20, 0x40, 0x02, 0x20, 0x00, 0, 0, 0, 0],
                &[0x00, 0x20, 0x60, 0, 0, 0, 0, 0, 0, 0],
                &[0x00, 0x20, 0x70, 0, 0, 0, 0, 0, 0, 0],
            ];
            for (j, req) in steps.iter().enumerate() {
                let o = h.coe(req);
                answers[k][j][..o.len].copy_from_slice(&o.buf[..o.len]);
            }
        }
        assert!(answers[0] == answers[1]);
    }

    fn short_last_segments_are_padded() {
        let mut h = H::new(128);
        long_download(&mut h, 115); // last segment 3 bytes, n = 4
        let o = h.upload(0x2002, 0);
        assert_eq!(&o.payload()[..10], &[0x00, 0x30, 0x41, 0x02, 0x20, 0x00, 115, 0, 0, 0]);
        let o = h.coe(&[0x00, 0x20, 0x60, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(
            o.payload(),
            &[0x00, 0x30, 0x09, pattern(112), pattern(113), pattern(114), 0, 0, 0, 0]
        );
        // 112 + 7 bytes: the segment is exactly 7 bytes, n = 0.
        long_download(&mut h, 119);
        let _ = h.upload(0x2002, 0);
        let o = h.coe(&[0x00, 0x20, 0x60, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(o.payload()[2], 0x01);
        assert_eq!(o.payload().len(), 10);
    }

    fn toggle_errors_abort() {
        let mut h = H::new(128);
        long_download(&mut h, 200);
        let _ = h.upload(0x2002, 0);
        let o = h.coe(&[0x00, 0x20, 0x70, 0, 0, 0, 0, 0, 0, 0]);
        h.expect_abort(&o, 0x2002, 0, SdoAbort::ToggleBit);
        assert!(!h.srv.transfer_active());
        // Download: first segment with toggle 1.
        let mut f = [0u8; 122];
        f[..10].copy_from_slice(&[0x00, 0x20, 0x21, 0x02, 0x20, 0x00, 150, 0, 0, 0]);
        let o = h.coe(&f);
        assert_eq!(o.payload()[2], 0x60);
        let o = h.coe(&[0x00, 0x20, 0x10, 1, 2, 3, 4, 5, 6, 7]);
        h.expect_abort(&o, 0x2002, 0, SdoAbort::ToggleBit);
        assert!(!h.srv.transfer_active());
        assert_eq!(h.dict.long_text().len(), 200);
    }

    fn segment_length_mismatch_aborts() {
        let mut h = H::new(128);
        let mut f = [0u8; 122];
        f[..10].copy_from_slice(&[0x00, 0x20, 0x21, 0x02, 0x20, 0x00, 115, 0, 0, 0]);
        let o = h.coe(&f);
        assert_eq!(o.payload()[2], 0x60);
        // 7 more bytes would make 119 > 115.
        let o = h.coe(&[0x00, 0x20, 0x00, 1, 2, 3, 4, 5, 6, 7]);
        h.expect_abort(&o, 0x2002, 0, SdoAbort::TypeMismatch);
        // Last segment before the announced size is reached.
        f[6] = 120;
        let _ = h.coe(&f);
        let o = h.coe(&[0x00, 0x20, 0x09, 1, 2, 3, 0, 0, 0, 0]);
        h.expect_abort(&o, 0x2002, 0, SdoAbort::TypeMismatch);
        assert_eq!(h.dict.writes, 0);
    }

    fn stalled_transfer_times_out() {
        let mut h = H::new(128);
        long_download(&mut h, 200);
        let _ = h.upload(0x2002, 0);
        h.srv.tick(999_000);
        h.none();
        assert!(h.srv.transfer_active());
        h.srv.tick(1_000_001);
        let o = h.recv();
        h.expect_abort(&o, 0x2002, 0, SdoAbort::Timeout);
        assert!(!h.srv.transfer_active());
        let o = h.coe(&[0x00, 0x20, 0x60, 0, 0, 0, 0, 0, 0, 0]);
        h.expect_abort(&o, 0, 0, SdoAbort::InvalidCommand);
        // A late segment without tick() in between gets the timeout abort.
        h.now = 5_000_000;
        let _ = h.upload(0x2002, 0);
        h.now += 1_500_000;
        let o = h.coe(&[0x00, 0x20, 0x60, 0, 0, 0, 0, 0, 0, 0]);
        h.expect_abort(&o, 0x2002, 0, SdoAbort::Timeout);
        // Activity keeps a transfer alive.
        let _ = h.upload(0x2002, 0);
        h.now += 900_000;
        let o = h.coe(&[0x00, 0x20, 0x60, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(o.payload()[2] & 0xE0, 0x00);
        h.now += 900_000;
        h.srv.tick(h.now);
        h.none();
    }

    fn new_request_cancels_and_master_abort_ends_transfer() {
        let mut h = H::new(128);
        let mut f = [0u8; 122];
        f[..10].copy_from_slice(&[0x00, 0x20, 0x21, 0x02, 0x20, 0x00, 200, 0, 0, 0]);
        let _ = h.coe(&f);
        assert!(h.srv.transfer_active());
        // A new initiate replaces the stale transfer.
        let o = h.upload(0x1000, 0);
        assert_eq!(o.payload()[2], 0x43);
        assert!(!h.srv.transfer_active());
        let o = h.coe(&[0x00, 0x20, 0x00, 1, 2, 3, 4, 5, 6, 7]);
        h.expect_abort(&o, 0, 0, SdoAbort::InvalidCommand);
        // Abort from the master: no answer, transfer gone.
        let _ = h.coe(&f);
        h.send(3, &[0x00, 0x20, 0x80, 0x02, 0x20, 0x00, 0x00, 0x00, 0x04, 0x05]);
        h.none();
        assert!(!h.srv.transfer_active());
        // Segment of the wrong direction: abort with the transfer's index.
        long_download(&mut h, 200);
        let _ = h.upload(0x2002, 0);
        let o = h.coe(&[0x00, 0x20, 0x00, 1, 2, 3, 4, 5, 6, 7]);
        h.expect_abort(&o, 0x2002, 0, SdoAbort::InvalidCommand);
        assert!(!h.srv.transfer_active());
    }

    fn unknown_commands_abort() {
        let mut h = H::new(128);
        for c in [0xA0u8, 0xA4, 0xC0, 0xC6, 0xE0, 0xFF] {
            let o = h.coe(&[0x00, 0x20, c, 0x00, 0x10, 0x00, 0, 0, 0, 0]);
            h.expect_abort(&o, 0x1000, 0, SdoAbort::InvalidCommand);
        }
        let o = h.coe(&[0x00, 0x20, 0x60, 0, 0, 0, 0, 0, 0, 0]);
        h.expect_abort(&o, 0, 0, SdoAbort::InvalidCommand);
    }

    fn complete_access_upload() {
        let mut h = H::new(128);
        let o = h.coe(&[0x00, 0x20, 0x50, 0x18, 0x10, 0x00, 0, 0, 0, 0]);
        assert_eq!(
            o.payload(),
            &[
                0x00, 0x30, 0x51, 0x18, 0x10, 0x00, 18, 0, 0, 0, 4, 0, 0x5C, 0x0E, 0, 0, 0x40, 0x58, 0, 0, 0,
                0, 1, 0, 0x78, 0x56, 0x34, 0x12
            ]
        );
        let o = h.coe(&[0x00, 0x20, 0x50, 0x18, 0x10, 0x01, 0, 0, 0, 0]);
        assert_eq!(&o.payload()[..10], &[0x00, 0x30, 0x51, 0x18, 0x10, 0x01, 16, 0, 0, 0]);
        assert_eq!(&o.payload()[10..14], &[0x5C, 0x0E, 0, 0]);
        // Bit packing, read-only and write-only (zeros) entries.
        h.dict.set_value(ObjectKey::new(0x2003, 1), 1);
        h.dict.set_value(ObjectKey::new(0x2003, 2), 2);
        h.dict.set_value(ObjectKey::new(0x2003, 3), 7);
        h.dict.set_value(ObjectKey::new(0x2003, 5), 0xDEAD_BEEF);
        let o = h.coe(&[0x00, 0x20, 0x50, 0x03, 0x20, 0x00, 0, 0, 0, 0]);
        assert_eq!(
            o.payload(),
            &[0x00, 0x30, 0x51, 0x03, 0x20, 0x00, 10, 0, 0, 0, 5, 0, 0x05, 7, 0xFE, 0xFF, 0, 0, 0, 0]
        );
        // Only the entries up to the current sub-index 0 value.
        let o = h.coe(&[0x00, 0x20, 0x50, 0x00, 0x16, 0x00, 0, 0, 0, 0]);
        assert_eq!(
            o.payload(),
            &[0x00, 0x30, 0x51, 0x00, 0x16, 0x00, 10, 0, 0, 0, 2, 0, 0x10, 0, 0x40, 0x60, 0x20, 0, 0x7A, 0x60]
        );
        // 40-byte array: normal transfer in one frame.
        let o = h.coe(&[0x00, 0x20, 0x50, 0x04, 0x20, 0x00, 0, 0, 0, 0]);
        assert_eq!(&o.payload()[..10], &[0x00, 0x30, 0x51, 0x04, 0x20, 0x00, 42, 0, 0, 0]);
        // Aborts.
        let o = h.coe(&[0x00, 0x20, 0x50, 0x00, 0x10, 0x00, 0, 0, 0, 0]);
        h.expect_abort(&o, 0x1000, 0, SdoAbort::UnsupportedAccess);
        let o = h.coe(&[0x00, 0x20, 0x50, 0x18, 0x10, 0x02, 0, 0, 0, 0]);
        h.expect_abort(&o, 0x1018, 2, SdoAbort::UnsupportedAccess);
        let o = h.coe(&[0x00, 0x20, 0x50, 0x05, 0x20, 0x00, 0, 0, 0, 0]);
        h.expect_abort(&o, 0x2005, 0, SdoAbort::CompleteAccessVariableLength);
        let o = h.coe(&[0x00, 0x20, 0x50, 0x99, 0x99, 0x00, 0, 0, 0, 0]);
        h.expect_abort(&o, 0x9999, 0, SdoAbort::ObjectDoesNotExist);
    }

    fn complete_access_upload_segmented_on_small_mailbox() {
        let mut h = H::new(32); // 26 bytes of mailbox data
        let o = h.coe(&[0x00, 0x20, 0x50, 0x04, 0x20, 0x00, 0, 0, 0, 0]);
        assert_eq!(&o.payload()[..10], &[0x00, 0x30, 0x51, 0x04, 0x20, 0x00, 42, 0, 0, 0]);
        assert_eq!(o.payload().len(), 26);
        assert_eq!(&o.payload()[10..12], &[40, 0]);
        let o = h.coe(&[0x00, 0x20, 0x60, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(o.payload()[2], 0x00);
        assert_eq!(o.payload().len(), 26);
        let o = h.coe(&[0x00, 0x20, 0x70, 0, 0, 0, 0, 0, 0, 0]);
        // 42 - 16 - 23 = 3 bytes left: last, n = 4.
        assert_eq!(&o.payload()[..3], &[0x00, 0x30, 0x19]);
        assert_eq!(o.payload().len(), 10);
    }

    fn complete_access_download_segmented_on_small_mailbox() {
        let mut h = H::new(32); // 26 bytes of mailbox data
        let mut image = [0u8; 42];
        image[0] = 40;
        for i in 0..40 {
            image[2 + i] = 200 - i as u8;
        }
        let mut f = [0u8; 26];
        f[..10].copy_from_slice(&[0x00, 0x20, 0x31, 0x04, 0x20, 0x00, 42, 0, 0, 0]);
        f[10..].copy_from_slice(&image[..16]);
        let o = h.coe(&f);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x70, 0x04, 0x20, 0x00, 0, 0, 0, 0]);
        assert_eq!(h.dict.writes, 0);
        let mut s = [0u8; 26];
        s[..3].copy_from_slice(&[0x00, 0x20, 0x00]);
        s[3..].copy_from_slice(&image[16..39]);
        let o = h.coe(&s);
        assert_eq!(o.payload(), &SEG_ACK0);
        let o = h.coe(&[0x00, 0x20, 0x19, image[39], image[40], image[41], 0, 0, 0, 0]);
        assert_eq!(o.payload(), &SEG_ACK1);
        assert_eq!(h.dict.writes, 40);
        assert_eq!(h.dict.value(ObjectKey::new(0x2004, 1)), 200);
        assert_eq!(h.dict.value(ObjectKey::new(0x2004, 40)), 161);
    }

    fn complete_access_download() {
        let mut h = H::new(128);
        // 0x1600 from sub-index 0 with three entries: sub 0 is set to 0 first, so the
        // application's "sub-index 0 first" rule is satisfied.
        let o = h.coe(&[
            0x00, 0x20, 0x31, 0x00, 0x16, 0x00, 14, 0, 0, 0, 3, 0, 0x10, 0x00, 0x40, 0x60, 0x20, 0x00, 0x7A,
            0x60, 0x08, 0x00, 0x60, 0x60,
        ]);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x70, 0x00, 0x16, 0x00, 0, 0, 0, 0]);
        assert_eq!(h.dict.value(ObjectKey::new(0x1600, 0)), 3);
        assert_eq!(h.dict.value(ObjectKey::new(0x1600, 3)), 0x6060_0008);
        assert_eq!(h.dict.writes, 5);
        // Record from sub-index 1: bits, byte, RO word (ignored), WO dword.
        let o = h.coe(&[0x00, 0x20, 0x31, 0x03, 0x20, 0x01, 8, 0, 0, 0, 0x03, 9, 0x34, 0x12, 1, 2, 3, 4]);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x70, 0x03, 0x20, 0x01, 0, 0, 0, 0]);
        assert_eq!(h.dict.value(ObjectKey::new(0x2003, 1)), 1);
        assert_eq!(h.dict.value(ObjectKey::new(0x2003, 2)), 1);
        assert_eq!(h.dict.value(ObjectKey::new(0x2003, 3)), 9);
        assert_eq!(h.dict.value(ObjectKey::new(0x2003, 4)) as u16 as i16, -2);
        assert_eq!(h.dict.value(ObjectKey::new(0x2003, 5)), 0x0403_0201);
        // Expedited complete access from sub-index 1 (3 bytes: bits, byte C, ... ) is too
        // short for the record's layout.
        let o = h.download4(0x37, 0x2003, 1, [0x01, 5, 0, 0]);
        h.expect_abort(&o, 0x2003, 1, SdoAbort::TypeMismatch);
        // Expedited complete access of two bytes of 0x1C12 from sub-index 1: one entry.
        let o = h.download4(0x3B, 0x1C12, 1, [0x01, 0x16, 0, 0]);
        assert_eq!(o.payload(), &[0x00, 0x30, 0x70, 0x12, 0x1C, 0x01, 0, 0, 0, 0]);
        assert_eq!(h.dict.value(ObjectKey::new(0x1C12, 1)), 0x1601);
        // Array 0x2004 from sub-index 0, all 40 entries (SI0 read-only: ignored).
        let mut f = [0u8; 52];
        f[..10].copy_from_slice(&[0x00, 0x20, 0x31, 0x04, 0x20, 0x00, 42, 0, 0, 0]);
        f[10] = 40;
        for i in 0..40 {
            f[12 + i] = i as u8 + 100;
        }
        let o = h.coe(&f);
        assert_eq!(o.payload()[2], 0x70);
        assert_eq!(h.dict.value(ObjectKey::new(0x2004, 40)), 139);
    }

    fn complete_access_download_is_all_or_nothing() {
        let mut h = H::new(128);
        let w = h.dict.writes;
        // Byte C = 250 is above its maximum 200: nothing written.
        let o = h.coe(&[0x00, 0x20, 0x31, 0x03, 0x20, 0x01, 8, 0, 0, 0, 0x03, 250, 0, 0, 1, 2, 3, 4]);
        h.expect_abort(&o, 0x2003, 1, SdoAbort::ValueTooHigh);
        assert_eq!(h.dict.writes, w);
        assert_eq!(h.dict.value(ObjectKey::new(0x2003, 1)), 0);
        // Safe-Op: byte C is Pre-Op-only.
        h.state = EsmState::SafeOp;
        let o = h.coe(&[0x00, 0x20, 0x31, 0x03, 0x20, 0x01, 8, 0, 0, 0, 0x03, 9, 0, 0, 1, 2, 3, 4]);
        h.expect_abort(&o, 0x2003, 1, SdoAbort::StateConflict);
        let o = h.coe(&[0x00, 0x20, 0x31, 0x00, 0x16, 0x00, 6, 0, 0, 0, 1, 0, 0x10, 0x00, 0x40, 0x60]);
        h.expect_abort(&o, 0x1600, 0, SdoAbort::StateConflict);
        assert_eq!(h.dict.writes, w);
        h.state = EsmState::PreOp;
        // Length does not match the layout.
        let o = h.coe(&[0x00, 0x20, 0x31, 0x03, 0x20, 0x01, 9, 0, 0, 0, 0x03, 9, 0, 0, 1, 2, 3, 4, 5]);
        h.expect_abort(&o, 0x2003, 1, SdoAbort::TypeMismatch);
        let o = h.coe(&[0x00, 0x20, 0x31, 0x00, 0x16, 0x00, 9, 0, 0, 0, 2, 0, 0x10, 0x00, 0x40, 0x60, 0, 0, 0]);
        h.expect_abort(&o, 0x1600, 0, SdoAbort::TypeMismatch);
        // Sub-index 0 above the capacity, above the range.
        let o = h.coe(&[0x00, 0x20, 0x31, 0x00, 0x16, 0x00, 2, 0, 0, 0, 5, 0]);
        h.expect_abort(&o, 0x1600, 0, SdoAbort::ValueTooHigh);
        let o = h.coe(&[0x00, 0x20, 0x31, 0x12, 0x1C, 0x00, 2, 0, 0, 0, 3, 0]);
        h.expect_abort(&o, 0x1C12, 0, SdoAbort::ValueTooHigh);
        // Strings, VAR objects, start sub-index, missing object, too large.
        let o = h.coe(&[0x00, 0x20, 0x31, 0x05, 0x20, 0x01, 10, 0, 0, 0, 1, 0, 0x41, 0x42, 0, 0, 0, 0, 0, 0]);
        h.expect_abort(&o, 0x2005, 1, SdoAbort::CompleteAccessVariableLength);
        let o = h.download4(0x33, 0x2000, 0, [0, 0, 0, 0]);
        h.expect_abort(&o, 0x2000, 0, SdoAbort::UnsupportedAccess);
        let o = h.coe(&[0x00, 0x20, 0x31, 0x18, 0x10, 0x02, 4, 0, 0, 0, 0, 0, 0, 0]);
        h.expect_abort(&o, 0x1018, 2, SdoAbort::UnsupportedAccess);
        let o = h.coe(&[0x00, 0x20, 0x31, 0x99, 0x99, 0x00, 4, 0, 0, 0, 0, 0, 0, 0]);
        h.expect_abort(&o, 0x9999, 0, SdoAbort::ObjectDoesNotExist);
        let o = h.coe(&[0x00, 0x20, 0x31, 0x04, 0x20, 0x00, 0x58, 0x02, 0, 0, 0, 0]);
        h.expect_abort(&o, 0x2004, 0, SdoAbort::OutOfMemory);
        assert_eq!(h.dict.writes, w);
    }

    fn mailbox_errors() {
        let mut h = H::new(128);
        h.raw(&[1, 0, 0, 0, 0]);
        h.expect_mbx_error(0x01);
        h.send(3, &[]);
        h.expect_mbx_error(0x05);
        h.send(0, &[1, 0, 1, 0]);
        h.expect_mbx_error(0x05);
        let mut f = [0u8; 128];
        f[0] = 200;
        f[5] = 0x33;
        h.raw(&f);
        h.expect_mbx_error(0x08);
        f[0] = 10;
        f[4] = 1;
        f[5] = 0x43;
        h.raw(&f);
        h.expect_mbx_error(0x03);
        for t in [1u8, 2, 4, 5, 6, 9, 0x0F] {
            h.send(t, &[0x00, 0x20, 0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]);
            h.expect_mbx_error(0x02);
        }
        for s in [0u8, 1, 3, 4, 5, 6, 7, 9, 0x0F] {
            h.send(3, &[0x00, s << 4, 0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]);
            h.expect_mbx_error(0x04);
        }
        h.send(3, &[0x00]);
        h.expect_mbx_error(0x06);
        h.send(3, &[0x00, 0x20, 0x40, 0x00, 0x10]);
        h.expect_mbx_error(0x06);
        h.send(3, &[0x00, 0x20, 0x00, 1, 2]);
        h.expect_mbx_error(0x06);
        h.send(3, &[0x00, 0x20]);
        h.expect_mbx_error(0x06);
        h.send(3, &[0x00, 0x80, 0x01]);
        h.expect_mbx_error(0x06);
        h.send(3, &[0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01]);
        h.expect_mbx_error(0x06);
        h.send(3, &[0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x00, 0x10, 0x00]);
        h.expect_mbx_error(0x06);
        // The whole error frame: type 0, length 4.
        h.send(4, &[0; 10]);
        let o = h.recv();
        assert_eq!(&o.buf[..10], &[4, 0, 0, 0, 0, (o.counter() << 4), 0x01, 0x00, 0x02, 0x00]);
        // A request longer than SM1 (SM0 may be larger) is still read.
        let mut big = [0u8; 200];
        big[0] = 150;
        big[5] = 0x03;
        big[6..16].copy_from_slice(&[0x00, 0x20, 0x21, 0x02, 0x20, 0x00, 140, 0, 0, 0]);
        big[16..156].fill(b'x');
        h.raw(&big);
        assert_eq!(h.recv().payload(), &[0x00, 0x30, 0x60, 0x02, 0x20, 0x00, 0, 0, 0, 0]);
        assert_eq!(h.dict.long_text(), &[b'x'; 140][..]);
        // ... but its length field must still fit the buffer.
        big[0] = 195;
        h.raw(&big);
        h.expect_mbx_error(0x08);
    }

    fn counters_wrap_and_repeats_are_not_executed_twice() {
        let mut h = H::new(128);
        for i in 0..9u8 {
            let o = h.upload(0x1000, 0);
            assert_eq!(o.counter(), i % 7 + 1);
        }
        let mut h = H::new(128);
        let req = [0x00, 0x20, 0x23, 0x00, 0x20, 0x00, 7, 0, 0, 0];
        h.send_with(3, 3, &req);
        let a = h.recv();
        assert_eq!(a.payload(), &DL_OK_2000);
        // The master missed the answer and repeats the request with the same counter.
        h.send_with(3, 3, &req);
        let b = h.recv();
        assert_eq!(b.payload(), &DL_OK_2000);
        assert_ne!(a.counter(), b.counter());
        assert_eq!(h.dict.writes, 1);
        // Repeated while the answer is still pending: one answer only.
        h.send_with(3, 4, &req);
        h.send_with(3, 4, &req);
        let _ = h.recv();
        h.none();
        assert_eq!(h.dict.writes, 2);
        // Counter 0 means "no counter": always executed.
        h.send_with(3, 0, &req);
        let _ = h.recv();
        h.send_with(3, 0, &req);
        let _ = h.recv();
        assert_eq!(h.dict.writes, 4);
        // Mailbox repeat request: the last frame, same counter.
        let mut r = [0u8; 128];
        let n = h.srv.repeat_last(&mut r);
        assert_eq!(n, 16);
        assert_eq!(&r[6..16], &DL_OK_2000);
        assert_eq!((r[5] >> 4) & 7, 5);
        let mut short = [0u8; 8];
        assert_eq!(h.srv.repeat_last(&mut short), 0);
        assert_eq!(MailboxServer::new(128).repeat_last(&mut r), 0);
    }

    fn emergencies_wait_for_replies_and_count_overruns() {
        let mut h = H::new(128);
        h.srv.emergency(0xA000, 0x11, [2, 0x24, 0, 0, 0]);
        h.send(3, &[0x00, 0x20, 0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]);
        let o = h.recv();
        assert_eq!(o.payload()[2], 0x43);
        let o = h.recv();
        assert_eq!(&o.buf[..o.len], &[10, 0, 0, 0, 0, 0x23, 0x00, 0x10, 0x00, 0xA0, 0x11, 2, 0x24, 0, 0, 0]);
        h.none();
        for i in 0..11u16 {
            h.srv.emergency(0xFF00 + i, 0x80, [i as u8, 0, 0, 0, 0]);
        }
        assert_eq!(h.srv.emergency_overruns(), 3);
        assert_eq!(h.srv.emergencies_queued(), 8);
        for i in 0..8u16 {
            let o = h.recv();
            assert_eq!(&o.payload()[..4], &[0x00, 0x10, i as u8, 0xFF]);
        }
        h.none();
        // Leaving Pre-Op: queue, transfer and counters restart; overruns are kept.
        h.srv.emergency(0x1234, 0, [0; 5]);
        long_download(&mut h, 200);
        let _ = h.upload(0x2002, 0);
        h.srv.reset();
        h.none();
        assert!(!h.srv.transfer_active());
        assert_eq!(h.srv.emergency_overruns(), 3);
        let o = h.upload(0x1000, 0);
        assert_eq!(o.counter(), 1);
    }

    fn sdo_info_od_lists() {
        let mut h = H::new(128);
        let o = h.coe(&[0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00]);
        assert_eq!(
            o.payload(),
            &[0x00, 0x80, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 16, 0, 3, 0, 3, 0, 3, 0, 3, 0]
        );
        let o = h.coe(&[0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x02, 0x00]);
        assert_eq!(
            o.payload(),
            &[0x00, 0x80, 0x02, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x20, 0x40, 0x60, 0x7A, 0x60]
        );
        let o = h.coe(&[0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x03, 0x00]);
        assert_eq!(&o.payload()[6..], &[0x03, 0x00, 0x01, 0x10, 0x00, 0x20, 0x41, 0x60]);
        for l in [4u8, 5] {
            let o = h.coe(&[0x00, 0x80, 0x01, 0x00, 0x00, 0x00, l, 0x00]);
            assert_eq!(&o.payload()[6..], &[l, 0x00, 0x00, 0x20, 0x03, 0x20, 0x7A, 0x60]);
        }
        let o = h.coe(&[0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00]);
        assert_eq!(o.payload().len(), 6 + 2 + 32);
        assert_eq!(&o.payload()[..10], &[0x00, 0x80, 0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x10]);
        let o = h.coe(&[0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x06, 0x00]);
        assert_eq!(o.payload(), &[0x00, 0x80, 0x07, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x06]);
    }

    fn sdo_info_od_list_fragments() {
        let mut h = H::new(24); // 18 bytes of mailbox data: 6 u16 per fragment
        h.send(3, &[0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00]);
        let mut items = [0u16; 17];
        let mut n = 0;
        for left in [2u16, 1, 0] {
            let o = h.recv();
            let p = o.payload();
            assert_eq!(&p[..2], &[0x00, 0x80]);
            assert_eq!(p[2], if left > 0 { 0x82 } else { 0x02 });
            assert_eq!(u16::from_le_bytes([p[4], p[5]]), left);
            for c in p[6..].chunks(2) {
                items[n] = u16::from_le_bytes([c[0], c[1]]);
                n += 1;
            }
        }
        h.none();
        assert_eq!(n, 17);
        assert_eq!(items[0], 1);
        assert_eq!(items[1], 0x1000);
        assert_eq!(items[16], 0x607A);
        assert!(items[1..].windows(2).all(|w| w[0] < w[1]));
        // Emergencies wait until the series is complete.
        h.send(3, &[0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00]);
        h.srv.emergency(0x8110, 0x10, [0; 5]);
        assert_eq!(h.recv().payload()[2], 0x82);
        assert_eq!(h.recv().payload()[2], 0x82);
        assert_eq!(h.recv().payload()[2], 0x02);
        assert_eq!(&h.recv().payload()[..4], &[0x00, 0x10, 0x10, 0x81]);
        // A repeated request restarts the series; a new request ends the old one.
        let c = h.cnt;
        h.send_with(3, c, &[0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00]);
        let o = h.recv();
        assert_eq!(u16::from_le_bytes([o.payload()[4], o.payload()[5]]), 2);
        assert_eq!(&o.payload()[6..8], &[0x01, 0x00]);
        let o = h.upload(0x1000, 0);
        assert_eq!(o.payload()[2], 0x43);
        h.none();
    }

    fn sdo_info_descriptions() {
        let mut h = H::new(128);
        let o = h.coe(&[0x00, 0x80, 0x03, 0x00, 0x00, 0x00, 0x18, 0x10]);
        assert_eq!(&o.payload()[..12], &[0x00, 0x80, 0x04, 0x00, 0x00, 0x00, 0x18, 0x10, 0x2A, 0x00, 4, 9]);
        assert_eq!(&o.payload()[12..], b"Identity");
        let o = h.coe(&[0x00, 0x80, 0x03, 0x00, 0x00, 0x00, 0x00, 0x16]);
        assert_eq!(&o.payload()[6..12], &[0x00, 0x16, 0x07, 0x00, 4, 8]);
        let o = h.coe(&[0x00, 0x80, 0x03, 0x00, 0x00, 0x00, 0x08, 0x10]);
        assert_eq!(&o.payload()[6..12], &[0x08, 0x10, 0x09, 0x00, 0, 7]);
        assert_eq!(&o.payload()[12..], b"Manufacturer device name");
        let o = h.coe(&[0x00, 0x80, 0x03, 0x00, 0x00, 0x00, 0x99, 0x99]);
        assert_eq!(o.payload(), &[0x00, 0x80, 0x07, 0x00, 0x00, 0x00, 0x00, 0x00, 0x02, 0x06]);
        // Entry with unit, default, minimum and maximum.
        let o = h.coe(&[0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x00, 0x20, 0x00, 0x70]);
        let p = o.payload();
        assert_eq!(
            &p[..28],
            &[
                0x00, 0x80, 0x06, 0x00, 0x00, 0x00, 0x00, 0x20, 0x00, 0x70, 0x04, 0x00, 0x20, 0x00, 0xFF, 0x03,
                100, 0, 0, 0, 0x18, 0xFC, 0xFF, 0xFF, 0xE8, 0x03, 0, 0
            ]
        );
        assert_eq!(&p[28..], b"Current limit [mA]");
        // Only the maximum requested; echo of bits 0-2; unit type never answered.
        let o = h.coe(&[0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x00, 0x20, 0x00, 0x4F]);
        assert_eq!(&o.payload()[6..20], &[0x00, 0x20, 0x00, 0x47, 0x04, 0x00, 0x20, 0x00, 0xFF, 0x03, 0xE8, 0x03, 0, 0]);
        // Read-only entry, no value info.
        let o = h.coe(&[0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x18, 0x10, 0x01, 0x00]);
        assert_eq!(&o.payload()[6..16], &[0x18, 0x10, 0x01, 0x00, 0x07, 0x00, 0x20, 0x00, 0x07, 0x00]);
        assert_eq!(&o.payload()[16..], b"Vendor ID");
        // String: no values even when requested; bit length is the maximum length.
        let o = h.coe(&[0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x08, 0x10, 0x00, 0x70]);
        assert_eq!(&o.payload()[6..16], &[0x08, 0x10, 0x00, 0x00, 0x09, 0x00, 0x00, 0x01, 0x07, 0x00]);
        // Write-only, Pre-Op-only, TxPDO-mappable, bit type.
        let o = h.coe(&[0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x01, 0x20, 0x00, 0x00]);
        assert_eq!(&o.payload()[14..16], &[0x38, 0x00]);
        let o = h.coe(&[0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x03, 0x20, 0x03, 0x00]);
        assert_eq!(&o.payload()[14..16], &[0x0F, 0x03]);
        let o = h.coe(&[0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x41, 0x60, 0x00, 0x00]);
        assert_eq!(&o.payload()[14..16], &[0x87, 0x00]);
        let o = h.coe(&[0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x03, 0x20, 0x02, 0x70]);
        assert_eq!(&o.payload()[6..18], &[0x03, 0x20, 0x02, 0x60, 0x31, 0x00, 0x02, 0x00, 0x3F, 0x00, 0, 3]);
        assert_eq!(&o.payload()[18..], b"Field B");
        // Errors.
        let o = h.coe(&[0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x18, 0x10, 0x09, 0x00]);
        assert_eq!(o.payload(), &[0x00, 0x80, 0x07, 0x00, 0x00, 0x00, 0x11, 0x00, 0x09, 0x06]);
        let o = h.coe(&[0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x99, 0x99, 0x00, 0x00]);
        assert_eq!(o.payload(), &[0x00, 0x80, 0x07, 0x00, 0x00, 0x00, 0x00, 0x00, 0x02, 0x06]);
        for op in [0x00u8, 0x02, 0x04, 0x06, 0x07, 0x08, 0x7F] {
            let o = h.coe(&[0x00, 0x80, op, 0x00, 0x00, 0x00, 0x00, 0x10, 0x00, 0x00]);
            assert_eq!(o.payload(), &[0x00, 0x80, 0x07, 0x00, 0x00, 0x00, 0x01, 0x00, 0x04, 0x05]);
        }
    }

    fn sdo_info_entry_description_fragments() {
        let mut h = H::new(24);
        h.send(3, &[0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x00, 0x20, 0x00, 0x70]);
        // 10 + 12 + 18 = 40 bytes of data, 12 per fragment: 4 fragments.
        let mut data = [0u8; 40];
        let mut n = 0;
        for left in [3u16, 2, 1, 0] {
            let o = h.recv();
            let p = o.payload();
            assert_eq!(p[2], if left > 0 { 0x86 } else { 0x06 });
            assert_eq!(u16::from_le_bytes([p[4], p[5]]), left);
            data[n..n + p.len() - 6].copy_from_slice(&p[6..]);
            n += p.len() - 6;
        }
        h.none();
        assert_eq!(n, 40);
        assert_eq!(&data[..4], &[0x00, 0x20, 0x00, 0x70]);
        assert_eq!(&data[22..], b"Current limit [mA]");
    }
}
