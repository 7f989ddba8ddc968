//! The EtherCAT mailbox (ETG.1000.4/.6): the 6-byte header, mailbox error replies, the
//! counter rules, and the [`MailboxServer`] that the slave runtime drives with the SM0
//! buffers it receives and the SM1 buffers it sends.
//!
//! The frame format (header, error replies, counters) is [`crate::wire::mailbox`]; its
//! items are re-exported here.
//!
//! # The server
//!
//! [`MailboxServer::on_request`] parses one SM0 buffer, executes it (CoE SDO, SDO
//! information; with [`MailboxServer::on_request_with`] also FoE, [`crate::foe`]) and
//! keeps the answer; [`MailboxServer::next_output`] hands out the next
//! frame for SM1 — the pending reply or the next SDO information fragment first, then
//! queued emergencies — and gives it the next counter (1…7, wrapping to 1). The last frame
//! handed out stays available for the mailbox repeat request ([`MailboxServer::repeat_last`]).
//!
//! Rules:
//! * A request whose counter is not 0 and equals the counter of the previous request is a
//!   repetition (the master did not get our answer): it is **not executed again**; if the
//!   answer to the original was already handed out it is queued once more (with a new
//!   counter), an SDO information answer is restarted from its first fragment.
//! * One answer is kept per request. A new request that arrives before the previous
//!   answer was fetched replaces that answer (the master breaks the protocol if it does
//!   not wait for the answer).
//! * Malformed frames get a mailbox error reply (type 0, see [`ErrorDetail`]); so do
//!   mailbox types without a handler ([`Handlers`]: CoE with a dictionary, FoE with a
//!   file backend; every other type) and CoE services other than SDO request and SDO
//!   information.
//! * No heap: the answer, the last sent frame and the SDO transfer data live in fixed
//!   buffers of [`MAX_MAILBOX_SIZE`] and [`crate::coe::sdo::TRANSFER_MAX`] bytes.

use crate::coe::{self, emcy::EmergencyQueue, info::InfoJob, sdo::SdoServer};
use crate::esm::EsmState;
use crate::foe::{self, FoeFiles, FoeServer};
use crate::od::{Dictionary, ObjectKey};

pub use crate::wire::mailbox::*;

/// Largest mailbox (SM0/SM1 length) the server handles; larger ones are used only up to
/// this size.
pub const MAX_MAILBOX_SIZE: usize = 256;
/// Smallest mailbox the server handles (an SDO initiate frame is 16 bytes).
pub const MIN_MAILBOX_SIZE: usize = 16;

/// The mailbox data area of an answer buffer for a mailbox of `size` bytes (`size` is
/// always within the buffer; empty otherwise).
fn reply_area(reply: &mut [u8], size: usize) -> &mut [u8] {
    reply.get_mut(HEADER_LEN..size).unwrap_or_default()
}

/// What the kept answer to the last request was, for re-answering a repeated request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LastAnswer {
    /// Nothing to repeat (no answer, or answered nothing, e.g. a master abort).
    None,
    /// The single frame in `reply`.
    Frame,
    /// An SDO information series (restarted from its first fragment).
    Info,
}

/// The protocol handlers one request may be given to. A request of a protocol
/// without a handler is answered with the mailbox error "protocol not supported".
/// The runtime passes only the handler the request's mailbox type needs (both borrow
/// the application), and no CoE handler in Bootstrap.
pub struct Handlers<'a, D: Dictionary> {
    /// CoE (SDO, SDO information): the object dictionary.
    pub coe: Option<&'a mut D>,
    /// FoE: the application's files.
    pub foe: Option<&'a mut dyn FoeFiles>,
}

impl<'a, D: Dictionary> Handlers<'a, D> {
    /// CoE only.
    pub fn coe(dict: &'a mut D) -> Self {
        Handlers {
            coe: Some(dict),
            foe: None,
        }
    }
    /// FoE only (`None`: no protocol at all).
    pub fn foe(files: Option<&'a mut dyn FoeFiles>) -> Self {
        Handlers {
            coe: None,
            foe: files,
        }
    }
}

/// The mailbox side of the slave: executes SM0 requests and produces SM1 frames.
pub struct MailboxServer {
    size: usize,
    /// The receive mailbox (SM0) length, which sizes FoE segments.
    rx_size: usize,
    /// The answer to the last request (counter not yet set).
    reply: [u8; MAX_MAILBOX_SIZE],
    reply_len: usize,
    reply_pending: bool,
    last_answer: LastAnswer,
    /// The SDO information series of the last request (restartable copy in `info_orig`).
    info: Option<InfoJob>,
    info_orig: Option<InfoJob>,
    /// The last frame handed out (for the repeat request).
    sent: [u8; MAX_MAILBOX_SIZE],
    sent_len: usize,
    /// Counter of the last frame handed out (0 before the first).
    out_counter: u8,
    /// Counter of the last request (None before the first).
    in_counter: Option<u8>,
    sdo: SdoServer,
    emcy: EmergencyQueue,
    foe: FoeServer,
}

/// The mailbox size clamped to [`MIN_MAILBOX_SIZE`]…[`MAX_MAILBOX_SIZE`].
const fn clamp_size(mailbox_size: usize) -> usize {
    if mailbox_size < MIN_MAILBOX_SIZE {
        MIN_MAILBOX_SIZE
    } else if mailbox_size > MAX_MAILBOX_SIZE {
        MAX_MAILBOX_SIZE
    } else {
        mailbox_size
    }
}

impl MailboxServer {
    /// A server for a mailbox of `mailbox_size` bytes (the SM1 length, or the smaller of
    /// SM0 and SM1), clamped to [`MIN_MAILBOX_SIZE`]…[`MAX_MAILBOX_SIZE`]. The size bounds
    /// the frames handed out by [`Self::next_output`]; requests are accepted up to
    /// [`MAX_MAILBOX_SIZE`] bytes (SM0 may be the larger one).
    pub const fn new(mailbox_size: usize) -> Self {
        MailboxServer {
            size: clamp_size(mailbox_size),
            rx_size: clamp_size(mailbox_size),
            reply: [0; MAX_MAILBOX_SIZE],
            reply_len: 0,
            reply_pending: false,
            last_answer: LastAnswer::None,
            info: None,
            info_orig: None,
            sent: [0; MAX_MAILBOX_SIZE],
            sent_len: 0,
            out_counter: 0,
            in_counter: None,
            sdo: SdoServer::new(),
            emcy: EmergencyQueue::new(),
            foe: FoeServer::new(),
        }
    }

    /// The mailbox size in use.
    pub const fn mailbox_size(&self) -> usize {
        self.size
    }

    /// Changes the mailbox size (e.g. after the master configured SM0/SM1; both
    /// directions the same size) and resets like [`Self::reset`] (the emergency
    /// overrun counter is kept).
    ///
    /// In place (the same state as [`Self::new`] with the counter kept): the
    /// slave runtime calls this from the cyclic path on a state change, where a new
    /// server built on the stack would cost its size (≈ 1.1 KiB) of stack. The reply
    /// and repeat buffers keep stale bytes, which their zero lengths hide.
    #[inline(never)]
    pub fn set_mailbox_size(&mut self, mailbox_size: usize) {
        self.size = clamp_size(mailbox_size);
        self.rx_size = self.size;
        self.clear();
    }

    /// Sets the sizes from the SyncManager lengths (SM0 receive, SM1 send), each
    /// clamped like [`Self::new`], and resets like [`Self::reset`]: answers are
    /// bounded by the smaller one ([`Self::mailbox_size`]), FoE segments follow SM0
    /// ([`Self::foe_segment`]).
    // Measured (cargo xtask size, LAN9252 image): without it, `clear`'s and
    // `answer_error`'s, +104 B flash.
    #[inline(never)]
    pub fn set_mailbox_sizes(&mut self, sm0_len: usize, sm1_len: usize) {
        self.size = clamp_size(if sm0_len < sm1_len { sm0_len } else { sm1_len });
        self.rx_size = clamp_size(sm0_len);
        self.clear();
    }

    /// The largest FoE DATA payload the master sends (receive mailbox − 12 bytes).
    pub const fn foe_segment(&self) -> usize {
        self.rx_size - foe::OVERHEAD
    }

    /// Drops every transfer and answer, restarts the counters (sizes and the
    /// emergency overrun counter are kept). The FoE transfer is forgotten without
    /// telling its backend: call [`Self::foe_abort`] first.
    // Measured (cargo xtask size, LAN9252 image): see `set_mailbox_sizes`.
    #[inline(never)]
    fn clear(&mut self) {
        self.reply_len = 0;
        self.reply_pending = false;
        self.last_answer = LastAnswer::None;
        self.info = None;
        self.info_orig = None;
        self.sent_len = 0;
        self.out_counter = 0;
        self.in_counter = None;
        self.sdo.reset();
        self.emcy.clear();
        self.foe.reset();
    }

    /// A whole SM0 buffer arrived (or its header plus the bytes the header announces):
    /// parse, execute, keep the answer for [`Self::next_output`]. CoE only: a FoE
    /// request answers "protocol not supported" ([`Self::on_request_with`] serves
    /// FoE too).
    pub fn on_request(
        &mut self,
        frame: &[u8],
        dict: &mut impl Dictionary,
        state: EsmState,
        now_us: u64,
    ) {
        self.on_request_with(frame, Handlers::coe(dict), state, now_us);
    }

    /// [`Self::on_request`] with the protocol handlers given explicitly.
    pub fn on_request_with<D: Dictionary>(
        &mut self,
        frame: &[u8],
        handlers: Handlers<'_, D>,
        state: EsmState,
        now_us: u64,
    ) {
        let expired = self.sdo.expire(now_us);
        // The request may be as long as SM0 (which can be longer than SM1, whose size
        // bounds the answers); only the first MAX_MAILBOX_SIZE bytes are looked at.
        let frame = match frame.get(..MAX_MAILBOX_SIZE) {
            Some(f) => f,
            None => frame,
        };
        let view = Frame::new_unchecked(frame);
        if frame.len() < HEADER_LEN {
            self.answer_error(ErrorDetail::Syntax);
            return;
        }
        // Repetition of the previous request: do not execute again.
        let counter = view.counter();
        if counter != 0 && self.in_counter == Some(counter) {
            if !self.reply_pending && self.info.is_none() {
                match self.last_answer {
                    LastAnswer::Frame => self.reply_pending = true,
                    LastAnswer::Info => self.info = self.info_orig,
                    LastAnswer::None => {}
                }
            }
            return;
        }
        self.in_counter = Some(counter);
        let length = view.length() as usize;
        if length == 0 || view.mailbox_type() == MailboxType::Error {
            self.answer_error(ErrorDetail::InvalidHeader);
            return;
        }
        if view.check_len().is_err() {
            self.answer_error(ErrorDetail::InvalidSize);
            return;
        }
        if view.channel() != 0 {
            self.answer_error(ErrorDetail::InvalidChannel);
            return;
        }
        match (view.mailbox_type(), handlers.coe, handlers.foe) {
            (MailboxType::Coe, Some(dict), _) => {
                self.on_coe(view.payload(), dict, state, now_us, expired)
            }
            (MailboxType::Foe, _, Some(files)) => self.on_foe(view.payload(), files, state, now_us),
            _ => self.answer_error(ErrorDetail::UnsupportedProtocol),
        }
    }

    fn on_foe(&mut self, payload: &[u8], files: &mut dyn FoeFiles, state: EsmState, now_us: u64) {
        let segment = self.foe_segment();
        let ctx = foe::Context {
            in_boot: state == EsmState::Bootstrap,
            write_segment: segment,
            // SOEM and IgH expect read segments of SM0 − 12 bytes: they must fit SM1.
            read_segment: if self.rx_size <= self.size {
                segment
            } else {
                0
            },
            now_us,
        };
        let out = reply_area(&mut self.reply, self.size);
        match self.foe.on_request(payload, files, ctx, out) {
            foe::Answer::None => self.answer_none(),
            foe::Answer::Frame(n) => self.answer_frame(MailboxType::Foe, n),
            foe::Answer::MailboxError(detail) => self.answer_error(detail),
        }
    }

    fn on_coe<D: Dictionary>(
        &mut self,
        payload: &[u8],
        dict: &mut D,
        state: EsmState,
        now_us: u64,
        expired: Option<ObjectKey>,
    ) {
        let Some(hdr) = coe::Header::parse(payload) else {
            self.answer_error(ErrorDetail::SizeTooShort);
            return;
        };
        let body = payload.get(coe::HEADER_LEN..).unwrap_or(&[]);
        let cap = self.size - HEADER_LEN;
        match hdr.service {
            coe::Service::SdoRequest => {
                let out = reply_area(&mut self.reply, self.size);
                match self.sdo.on_request(body, out, dict, state, now_us, expired) {
                    Ok(0) => self.answer_none(),
                    Ok(n) => self.answer_coe(n),
                    Err(detail) => self.answer_error(detail),
                }
            }
            coe::Service::SdoInformation => {
                let out = reply_area(&mut self.reply, self.size);
                match coe::info::on_request(body, out, dict, cap) {
                    Ok(coe::info::Answer::Frame(n)) => self.answer_coe(n),
                    Ok(coe::info::Answer::Series(job)) => {
                        self.reply_pending = false;
                        self.info = Some(job);
                        self.info_orig = Some(job);
                        self.last_answer = LastAnswer::Info;
                    }
                    Err(detail) => self.answer_error(detail),
                }
            }
            _ => self.answer_error(ErrorDetail::ServiceNotSupported),
        }
    }

    fn answer_none(&mut self) {
        self.reply_pending = false;
        self.info = None;
        self.last_answer = LastAnswer::None;
    }

    // Measured (cargo xtask size, LAN9252 image): see `set_mailbox_sizes`.
    #[inline(never)]
    fn answer_error(&mut self, detail: ErrorDetail) {
        self.reply_len = emit_error(&mut self.reply, detail);
        self.reply_pending = true;
        self.info = None;
        self.last_answer = LastAnswer::Frame;
    }

    /// The CoE payload of `n` bytes is in `reply[6..]`: add the header and keep it.
    fn answer_coe(&mut self, n: usize) {
        self.answer_frame(MailboxType::Coe, n);
    }

    /// The payload of `n` bytes of protocol `t` is in `reply[6..]`: add the header and
    /// keep it.
    fn answer_frame(&mut self, t: MailboxType, n: usize) {
        let mut f = Frame::new_unchecked(&mut self.reply[..]);
        Repr {
            length: n as u16,
            address: 0,
            channel: 0,
            priority: 0,
            mailbox_type: t,
            counter: 0,
        }
        .emit(&mut f);
        self.reply_len = HEADER_LEN + n;
        self.reply_pending = true;
        self.info = None;
        self.last_answer = LastAnswer::Frame;
    }

    /// The next frame for SM1 (call when SM1 is free): the pending answer or the next SDO
    /// information fragment first, then emergencies. Returns its length (0 = nothing to
    /// send). The frame gets the next counter. `out` must hold a whole mailbox
    /// ([`Self::mailbox_size`] bytes); bytes after the returned length are left as they
    /// are (the runtime writes up to the last byte of SM1 to hand the buffer over).
    pub fn next_output(&mut self, out: &mut [u8], now_us: u64) -> usize {
        let _ = now_us;
        let cap = self.size.min(out.len());
        let n = if self.reply_pending {
            self.reply_pending = false;
            match out.get_mut(..self.reply_len) {
                Some(dst) => {
                    dst.copy_from_slice(&self.reply[..self.reply_len]);
                    self.reply_len
                }
                None => 0,
            }
        } else if let Some(job) = self.info.as_mut() {
            let (n, done) = match out.get_mut(HEADER_LEN..cap) {
                Some(dst) if cap == self.size => {
                    let (n, done) = job.next_fragment(dst);
                    (n, done)
                }
                _ => (0, true),
            };
            if done {
                self.info = None;
            }
            if n > 0 {
                let mut f = Frame::new_unchecked(&mut out[..]);
                Repr {
                    length: n as u16,
                    address: 0,
                    channel: 0,
                    priority: 0,
                    mailbox_type: MailboxType::Coe,
                    counter: 0,
                }
                .emit(&mut f);
                HEADER_LEN + n
            } else {
                0
            }
        } else {
            self.emcy.pop_frame(out)
        };
        if n == 0 {
            return 0;
        }
        self.out_counter = next_counter(self.out_counter);
        Frame::new_unchecked(&mut out[..]).set_counter(self.out_counter);
        // Kept for a repeat request (n is never longer than either buffer).
        self.sent_len = match (self.sent.get_mut(..n), out.get(..n)) {
            (Some(s), Some(o)) => {
                s.copy_from_slice(o);
                n
            }
            _ => 0,
        };
        n
    }

    /// The mailbox repeat request: copies the last frame handed out by
    /// [`Self::next_output`] (same counter) into `out`; returns its length (0 if none
    /// was sent yet or `out` is too short).
    pub fn repeat_last(&self, out: &mut [u8]) -> usize {
        match out.get_mut(..self.sent_len) {
            Some(dst) => {
                dst.copy_from_slice(&self.sent[..self.sent_len]);
                self.sent_len
            }
            None => 0,
        }
    }

    /// Timeouts: a segmented SDO transfer without a request for
    /// [`crate::coe::sdo::TRANSFER_TIMEOUT_US`] is aborted with 0x05040000 (the abort is
    /// queued as the answer).
    pub fn tick(&mut self, now_us: u64) {
        if let Some(key) = self.sdo.expire(now_us) {
            let abort = coe::sdo::Response::abort(key, crate::od::SdoAbort::Timeout);
            let n = abort.emit_coe(reply_area(&mut self.reply, self.size));
            self.answer_coe(n);
        }
    }

    /// Leaving Pre-Op (or Bootstrap) towards Init: drops the transfers, pending
    /// answers and queued emergencies (the mailbox is off), restarts both counters.
    /// The sizes and the emergency overrun counter are kept. An open FoE transfer is
    /// forgotten without telling its backend: call [`Self::foe_abort`] first.
    pub fn reset(&mut self) {
        self.clear();
    }

    /// FoE timeout supervision ([`FoeServer::tick`]): a stalled transfer is aborted
    /// (backend told, no answer). Returns whether one was.
    pub fn foe_tick(&mut self, now_us: u64, files: &mut dyn FoeFiles) -> bool {
        self.foe.tick(now_us, files)
    }

    /// Aborts the open FoE transfer (backend told, no answer), e.g. before the mailbox
    /// stops. Returns whether one was open.
    pub fn foe_abort(&mut self, files: &mut dyn FoeFiles) -> bool {
        self.foe.abort(files)
    }

    /// The direction of the open FoE transfer, if any.
    pub fn foe_active(&self) -> Option<foe::Direction> {
        self.foe.active()
    }

    /// Sets the FoE transfer timeout, µs ([`foe::DEFAULT_TIMEOUT_US`] by default).
    pub fn set_foe_timeout_us(&mut self, us: u64) {
        self.foe.set_timeout_us(us);
    }

    /// Queues an emergency message (CoE service 1): error code, error register (0x1001)
    /// and 5 manufacturer bytes. When the queue is full the message is dropped and
    /// counted ([`Self::emergency_overruns`]).
    pub fn emergency(&mut self, error_code: u16, error_register: u8, data: [u8; 5]) {
        self.emcy.push(coe::emcy::Emergency {
            error_code,
            error_register,
            data,
        });
    }

    /// Emergencies dropped because the queue was full (since start, saturating).
    pub fn emergency_overruns(&self) -> u32 {
        self.emcy.overruns()
    }

    /// Emergencies waiting for SM1.
    pub fn emergencies_queued(&self) -> usize {
        self.emcy.len()
    }

    /// True when a segmented SDO transfer is in progress.
    pub fn transfer_active(&self) -> bool {
        self.sdo.active()
    }

    /// True when an answer or SDO information fragment waits for SM1.
    pub fn reply_pending(&self) -> bool {
        self.reply_pending || self.info.is_some()
    }
}

#[cfg(test)]
mod tests;
