//! Property test of the mailbox server: random and mutated mailbox frames (at least
//! 100 000 per run, several mailbox sizes, with random ticks, emergencies, resets and ESM
//! states in between) never panic, and every frame the server hands to SM1 is a
//! well-formed mailbox frame of at most the mailbox size: mailbox error (type 0) with a
//! known detail, or CoE with an emergency, an SDO abort (service 2, command 0x80, a code
//! of the table), an SDO response or an SDO information frame. Every request that is not
//! a repetition and not an abort from the master gets an answer.
//!
//! Own small PRNG (xorshift64*), fixed seeds: runs are repeatable.

use ecat_slave_stack::coe::example::{ExampleDictionary, OBJECTS};
use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::mailbox::MailboxServer;
use ecat_slave_stack::od::SdoAbort;

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    fn byte(&mut self) -> u8 {
        self.next() as u8
    }
    fn chance(&mut self, percent: usize) -> bool {
        self.below(100) < percent
    }
}

/// What the fuzzer's master sent, to follow the server's answers into segmented
/// transfers.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Sent {
    Other,
    NormalDownload { size: usize, carried: usize },
    DownloadSegment { len: usize, last: bool },
}

/// The fuzzer's view of the transfer in progress.
#[derive(Default)]
struct Master {
    /// Upload in progress: next toggle.
    up: Option<bool>,
    /// Download in progress: next toggle, bytes remaining.
    down: Option<(bool, usize)>,
}

/// Follows the transfer in progress with a segment (usually with the right toggle).
fn follow_up(r: &mut Rng, m: &Master, size: usize, out: &mut Vec<u8>) -> Option<Sent> {
    if let Some(t) = m.up {
        if r.chance(85) {
            let t = if r.chance(95) { t } else { !t };
            out.extend_from_slice(&[
                0x00,
                0x20,
                0x60 | if t { 0x10 } else { 0 },
                0,
                0,
                0,
                0,
                0,
                0,
                0,
            ]);
            return Some(Sent::Other);
        }
    }
    if let Some((t, rem)) = m.down {
        if r.chance(85) {
            let t = if r.chance(95) { t } else { !t };
            let room = size - 6 - 3;
            let k = rem.min(1 + r.below(room));
            let last = if r.chance(95) { k == rem } else { k != rem };
            let pad = 7usize.saturating_sub(k);
            out.extend_from_slice(&[
                0x00,
                0x20,
                (if t { 0x10 } else { 0 }) | ((pad as u8) << 1) | last as u8,
            ]);
            out.extend((0..k).map(|i| i as u8));
            out.extend((0..pad).map(|_| 0));
            return Some(Sent::DownloadSegment { len: k, last });
        }
    }
    None
}

/// A request from a template (then maybe mutated by the caller).
fn coe_template(r: &mut Rng, size: usize, out: &mut Vec<u8>) -> Sent {
    let obj = &OBJECTS[r.below(OBJECTS.len())];
    let index = if r.chance(90) {
        obj.index
    } else {
        r.next() as u16
    };
    let sub = if r.chance(85) {
        obj.entries()[r.below(obj.entries().len())].sub
    } else if r.chance(50) {
        r.below(3) as u8
    } else {
        r.byte()
    };
    let i = index.to_le_bytes();
    let toggle = if r.chance(50) { 0x10 } else { 0 };
    match r.below(14) {
        // Initiate upload, with or without complete access; long objects often.
        0..=2 => {
            let (i, sub) = match r.below(4) {
                0 => ([0x02, 0x20], 0),
                1 => ([0x04, 0x20], 0),
                _ => (i, sub),
            };
            let c = if r.chance(30) { 0x50 } else { 0x40 };
            out.extend_from_slice(&[0x00, 0x20, c, i[0], i[1], sub, 0, 0, 0, 0]);
        }
        // Expedited download, any n / size bit / CA bit.
        3 | 4 => {
            let c = 0x22 | (r.byte() & 0x1D);
            out.extend_from_slice(&[
                0x00,
                0x20,
                c,
                i[0],
                i[1],
                sub,
                r.byte(),
                r.byte(),
                r.byte(),
                r.byte(),
            ]);
        }
        // Normal download: mostly the long string, sometimes complete access.
        5 | 6 => {
            let max = if r.chance(10) { 700 } else { 300 };
            let total = r.below(max);
            let (c, i, sub) = if r.chance(70) {
                (0x21, [0x02, 0x20], 0)
            } else {
                (0x31, i, sub)
            };
            out.extend_from_slice(&[0x00, 0x20, c, i[0], i[1], sub]);
            out.extend_from_slice(&(total as u32).to_le_bytes());
            let carried = total.min(r.below(size - 16 + 1));
            out.extend((0..carried).map(|k| k as u8));
            return Sent::NormalDownload {
                size: total,
                carried,
            };
        }
        // Stray download segment.
        7 => {
            let n = r.below(8) as u8;
            let last = r.byte() & 1;
            out.extend_from_slice(&[0x00, 0x20, toggle | (n << 1) | last]);
            for _ in 0..(7 + r.below(4) * r.below(30)) {
                out.push(r.byte());
            }
        }
        // Stray upload segment.
        8 => out.extend_from_slice(&[0x00, 0x20, 0x60 | toggle, 0, 0, 0, 0, 0, 0, 0]),
        // Abort from the master, block/unknown commands.
        9 => {
            let c = [0x80, 0xA0, 0xC0, 0xE0][r.below(4)];
            out.extend_from_slice(&[
                0x00,
                0x20,
                c,
                i[0],
                i[1],
                sub,
                r.byte(),
                r.byte(),
                0x04,
                0x05,
            ]);
        }
        // SDO information.
        10 => {
            let list = if r.chance(85) {
                r.below(6) as u8
            } else {
                r.byte()
            };
            out.extend_from_slice(&[0x00, 0x80, 0x01, 0x00, 0x00, 0x00, list, 0x00]);
        }
        11 => out.extend_from_slice(&[0x00, 0x80, 0x03, 0x00, 0x00, 0x00, i[0], i[1]]),
        12 => out.extend_from_slice(&[
            0x00,
            0x80,
            0x05,
            0x00,
            0x00,
            0x00,
            i[0],
            i[1],
            sub,
            r.byte(),
        ]),
        // Other services / opcodes.
        _ => out.extend_from_slice(&[r.byte(), r.byte(), r.byte(), i[0], i[1], sub, 0, 0, 0, 0]),
    }
    Sent::Other
}

/// Updates the master's view from the last answer to a request.
fn learn(m: &mut Master, sent: Sent, kind: usize, p: &[u8]) {
    match kind {
        K_UPLOAD => {
            m.down = None;
            m.up = None;
            if p[2] & 0x02 == 0 {
                let size = u32::from_le_bytes([p[6], p[7], p[8], p[9]]) as usize;
                if p.len() - 10 < size {
                    m.up = Some(false);
                }
            }
        }
        K_UPLOAD_SEGMENT => {
            let t = p[2] & 0x10 != 0;
            m.up = if p[2] & 1 != 0 { None } else { Some(!t) };
        }
        K_DOWNLOAD_ACK => {
            m.up = None;
            m.down = match sent {
                Sent::NormalDownload { size, carried } if carried < size => {
                    Some((false, size - carried))
                }
                _ => None,
            };
        }
        K_DOWNLOAD_SEGMENT_ACK => {
            m.down = match (sent, m.down) {
                (Sent::DownloadSegment { len, last: false }, Some((t, rem))) if len < rem => {
                    Some((!t, rem - len))
                }
                _ => None,
            };
        }
        _ => {
            m.up = None;
            m.down = None;
        }
    }
}

fn mutate(r: &mut Rng, p: &mut Vec<u8>) {
    for _ in 0..r.below(4) {
        match r.below(5) {
            0 if !p.is_empty() => {
                let k = r.below(p.len());
                p[k] ^= 1 << r.below(8);
            }
            1 if !p.is_empty() => {
                let k = r.below(p.len());
                p[k] = r.byte();
            }
            2 => p.truncate(r.below(p.len() + 1)),
            3 => {
                for _ in 0..r.below(20) {
                    p.push(r.byte());
                }
            }
            _ => {}
        }
    }
}

/// Builds one SM0 buffer.
fn make_frame(r: &mut Rng, size: usize, counter: &mut u8, m: &Master, sent: &mut Sent) -> Vec<u8> {
    *sent = Sent::Other;
    if r.chance(2) {
        // Pure garbage of any length.
        let n = r.below(size + 12);
        return (0..n).map(|_| r.byte()).collect();
    }
    let mut payload = Vec::new();
    if let Some(s) = follow_up(r, m, size, &mut payload) {
        *sent = s;
    } else if r.chance(97) {
        *sent = coe_template(r, size, &mut payload);
    } else {
        payload.extend((0..r.below(size)).map(|_| r.byte()));
    }
    if r.chance(12) {
        mutate(r, &mut payload);
        *sent = Sent::Other;
    }
    // Never longer than the mailbox (mutations may have extended it).
    payload.truncate(size - 6);
    let mut len = payload.len() as u16;
    if r.chance(2) {
        len = r.next() as u16;
    }
    let t = if r.chance(96) { 3 } else { r.byte() & 0x0F };
    *counter = if r.chance(4) {
        // Repetition or "no counter".
        if r.chance(50) {
            *counter
        } else {
            0
        }
    } else if *counter >= 7 {
        1
    } else {
        *counter + 1
    };
    let mut ch = 0u8;
    if r.chance(1) {
        ch = r.byte();
    }
    let mut f = vec![0u8; 6];
    f[0..2].copy_from_slice(&len.to_le_bytes());
    f[2] = r.byte() * (r.chance(3) as u8);
    f[4] = ch;
    f[5] = t | (*counter << 4);
    f.extend_from_slice(&payload);
    // SM0 buffers are whole mailboxes: pad (sometimes give a short or long buffer).
    if r.chance(95) {
        f.resize(size, 0);
    } else {
        f.resize(r.below(size + 12), r.byte());
    }
    f
}

/// Whether the server must answer this buffer (mirror of the documented rules).
fn expects_answer(frame: &[u8], size: usize, last_counter: &mut Option<u8>) -> bool {
    let _ = size; // requests are read up to the largest mailbox, whatever SM1's size
    let f = &frame[..frame.len().min(256)];
    if f.len() < 6 {
        return true; // mailbox error "syntax"
    }
    let counter = (f[5] >> 4) & 7;
    if counter != 0 && *last_counter == Some(counter) {
        return false; // repetition: answered again only if an answer exists
    }
    *last_counter = Some(counter);
    let len = u16::from_le_bytes([f[0], f[1]]) as usize;
    let t = f[5] & 0x0F;
    if len == 0 || t != 3 || len > f.len() - 6 || f[4] & 0x3F != 0 {
        return true;
    }
    let p = &f[6..6 + len];
    // An abort from the master is the one request without an answer.
    !(p.len() >= 10 && (p[1] >> 4) == 2 && (p[2] >> 5) == 4)
}

/// Kinds of frames sent by the slave, for the coverage counts.
const K_MBX_ERROR: usize = 0;
const K_EMERGENCY: usize = 1;
const K_ABORT: usize = 2;
const K_UPLOAD_SEGMENT: usize = 3;
const K_DOWNLOAD_SEGMENT_ACK: usize = 4;
const K_UPLOAD: usize = 5;
const K_DOWNLOAD_ACK: usize = 6;
const K_INFO: usize = 7;
const K_INFO_FRAGMENT: usize = 8;
const K_INFO_ERROR: usize = 9;

/// Checks one frame from next_output; returns its kind.
fn check_frame(o: &[u8], size: usize, expected_counter: u8) -> usize {
    assert!(
        o.len() >= 6 && o.len() <= size,
        "frame length {} for mailbox {}",
        o.len(),
        size
    );
    let len = u16::from_le_bytes([o[0], o[1]]) as usize;
    assert_eq!(len, o.len() - 6, "length field");
    assert_eq!((o[5] >> 4) & 7, expected_counter, "counter sequence");
    assert_eq!(&o[2..5], &[0, 0, 0], "address/channel/priority");
    let p = &o[6..];
    match o[5] & 0x0F {
        0 => {
            assert_eq!(p.len(), 4);
            assert_eq!(u16::from_le_bytes([p[0], p[1]]), 1);
            assert!((1..=9).contains(&u16::from_le_bytes([p[2], p[3]])));
            K_MBX_ERROR
        }
        3 => {
            assert!(p.len() >= 2);
            let h = u16::from_le_bytes([p[0], p[1]]);
            assert_eq!(h & 0x0FFF, 0, "CoE number/reserved");
            match h >> 12 {
                1 => {
                    assert_eq!(p.len(), 10);
                    K_EMERGENCY
                }
                2 => {
                    assert_eq!(p.len(), 10);
                    assert_eq!(p[2], 0x80, "service 2 from the slave is an abort");
                    let code = u32::from_le_bytes([p[6], p[7], p[8], p[9]]);
                    assert!(
                        SdoAbort::from_code(code).is_some(),
                        "abort code {code:#010x}"
                    );
                    K_ABORT
                }
                3 => {
                    assert!(p.len() >= 10);
                    let c = p[2];
                    match c >> 5 {
                        // Upload segment: data after the command, padded to 7.
                        0 => {
                            let n = ((c >> 1) & 7) as usize;
                            if n > 0 {
                                assert_eq!(p.len(), 10);
                                assert_eq!(c & 1, 1, "only the last segment is short");
                            }
                            K_UPLOAD_SEGMENT
                        }
                        1 => {
                            assert!(c == 0x20 || c == 0x30, "download segment response {c:#04x}");
                            K_DOWNLOAD_SEGMENT_ACK
                        }
                        2 => {
                            if c & 0x02 != 0 {
                                assert_eq!(p.len(), 10);
                                assert_eq!(c & 0x10, 0, "expedited complete access");
                            } else {
                                assert_eq!(c & 0x0F, 0x01, "normal upload response {c:#04x}");
                                let size = u32::from_le_bytes([p[6], p[7], p[8], p[9]]) as usize;
                                assert!(p.len() - 10 <= size);
                            }
                            K_UPLOAD
                        }
                        3 => {
                            assert!(c == 0x60 || c == 0x70, "download response {c:#04x}");
                            K_DOWNLOAD_ACK
                        }
                        _ => panic!("SDO response command {c:#04x}"),
                    }
                }
                8 => {
                    assert!(p.len() >= 6);
                    let op = p[2] & 0x7F;
                    assert!(matches!(op, 2 | 4 | 6 | 7), "info opcode {op}");
                    if op == 7 {
                        assert_eq!(p.len(), 10);
                        let code = u32::from_le_bytes([p[6], p[7], p[8], p[9]]);
                        assert!(SdoAbort::from_code(code).is_some());
                    }
                    let left = u16::from_le_bytes([p[4], p[5]]);
                    assert_eq!(
                        p[2] & 0x80 != 0,
                        left > 0,
                        "incomplete flag vs fragments left"
                    );
                    match (op, left) {
                        (7, _) => K_INFO_ERROR,
                        (_, 0) => K_INFO,
                        _ => K_INFO_FRAGMENT,
                    }
                }
                s => panic!("CoE service {s} sent by the slave"),
            }
        }
        t => panic!("mailbox type {t} sent by the slave"),
    }
}

#[test]
fn random_and_mutated_mailboxes_get_well_formed_answers() {
    let sizes = [16usize, 17, 24, 32, 48, 64, 100, 128, 256];
    let per_size = 24_000;
    let mut total = 0usize;
    let mut answered = 0usize;
    let mut kinds = [0usize; 10];
    for (k, &size) in sizes.iter().enumerate() {
        let mut r = Rng(0x9E37_79B9_7F4A_7C15 ^ (k as u64 + 1).wrapping_mul(0x1234_5678_9ABC_DEF1));
        let mut srv = MailboxServer::new(size);
        let mut dict = ExampleDictionary::new();
        let mut now = 0u64;
        let mut counter = 0u8;
        let mut out_counter = 0u8;
        let mut last_in: Option<u8> = None;
        let mut state = EsmState::PreOp;
        let mut out = vec![0u8; size];
        let mut master = Master::default();
        let mut sent = Sent::Other;
        for _ in 0..per_size {
            // Background events.
            now += r.below(300_000) as u64;
            if r.chance(1) {
                now += 1_200_000;
            }
            if r.chance(3) {
                state = [
                    EsmState::PreOp,
                    EsmState::PreOp,
                    EsmState::SafeOp,
                    EsmState::Op,
                    EsmState::Init,
                ][r.below(5)];
            }
            if r.chance(2) {
                srv.emergency(r.next() as u16, r.byte(), [r.byte(); 5]);
            }
            if r.chance(1) {
                srv.reset();
                out_counter = 0;
                last_in = None;
                master = Master::default();
            }
            if r.chance(10) {
                srv.tick(now);
            }
            let frame = make_frame(&mut r, size, &mut counter, &master, &mut sent);
            let must_answer = expects_answer(&frame, size, &mut last_in);
            srv.on_request(&frame, &mut dict, state, now);
            total += 1;
            // Sometimes the master is slow: a second request before the answer was read.
            if r.chance(3) {
                master = Master::default();
                continue;
            }
            let mut got_answer = false;
            let mut frames = 0;
            loop {
                out.fill(0x5A);
                let n = srv.next_output(&mut out, now);
                if n == 0 {
                    break;
                }
                out_counter = if out_counter >= 7 { 1 } else { out_counter + 1 };
                let kind = check_frame(&out[..n], size, out_counter);
                if kind != K_EMERGENCY {
                    got_answer = true;
                    learn(&mut master, sent, kind, &out[6..n]);
                }
                kinds[kind] += 1;
                frames += 1;
                assert!(frames < 200, "next_output never runs dry");
                // Repeat request: the same frame again.
                if r.chance(2) {
                    let mut again = vec![0u8; size];
                    let m = srv.repeat_last(&mut again);
                    assert_eq!(&again[..m], &out[..n]);
                }
            }
            if must_answer {
                assert!(
                    got_answer,
                    "request without answer: {:02x?}",
                    &frame[..frame.len().min(24)]
                );
                answered += 1;
            }
        }
    }
    println!("{total} requests, {answered} checked answers, frames by kind: {kinds:?}");
    assert!(total >= 100_000, "{total} requests");
    // The generator reaches both answer kinds in volume.
    assert!(answered > total / 2, "{answered} of {total} answered");
    // Every kind of answer is reached in volume (segmented transfers included).
    assert!(kinds.iter().all(|&k| k > 500), "{kinds:?}");
}
