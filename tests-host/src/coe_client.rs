//! A CoE client on the drive's mailbox sync managers over ethercrab's register access:
//! SDO upload (expedited, normal, segmented), SDO download (expedited, normal), SDO
//! information (ETG.1000.6 5.6.3, fragments joined), and the emergencies that arrive
//! in between, kept instead of dropped.
//!
//! Why not ethercrab's `sdo_read` / `sdo_write`: ethercrab 0.7.1 reads what fits one
//! mailbox frame only, has no SDO information, and takes an emergency arriving in
//! place of an SDO response for a protocol error. Here requests go to SM0 and answers
//! come from SM1 with mailbox counter 0, which the drive never takes for a repeat.
//! Use one [`Mailbox`] per drive while nothing else uses that drive's mailbox.
//!
//! Used by the scope's host side ([`crate::scope_host`]) and the commissioning tool.

use ecat_slave_stack::coe::info;
use ethercrab::error::{Error, MailboxError, TimeoutError};
use ethercrab::SubDeviceRef;
use std::ops::Deref;
use std::time::{Duration, Instant};

/// Bytes of the drive's mailboxes (SM0, SM1; the ESI's `MBoxOut` / `MBoxIn`).
pub const MBX: usize = 128;
/// Mailbox header (6) + CoE header (2) before the service's first byte.
const SDO_AT: usize = 8;
/// How long an answer may take.
const ANSWER_TIMEOUT: Duration = Duration::from_secs(2);

/// An emergency as it arrived: error code (2), error register (1), manufacturer
/// bytes (5).
pub type Emergency = [u8; 8];

/// Mailbox type of CoE.
const COE: u8 = 3;
/// Mailbox type of FoE.
const FOE: u8 = 4;

/// CoE services (CoE header bits 12-15).
mod service {
    pub const EMERGENCY: u8 = 1;
    pub const SDO_REQUEST: u8 = 2;
    pub const SDO_RESPONSE: u8 = 3;
    pub const SDO_INFORMATION: u8 = 8;
}

/// The mailbox sync managers of one drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Mailbox {
    out_at: u16,
    in_at: u16,
}

fn aborted(code: u32, index: u16, sub: u8) -> Error {
    Error::Mailbox(MailboxError::Aborted {
        code: code.into(),
        address: index,
        sub_index: sub,
    })
}

impl Mailbox {
    /// The mailbox of `sd` as configured in SM0 / SM1 (both [`MBX`] bytes long, as the
    /// drive's are; anything else is [`Error::Internal`]).
    pub async fn of<S>(sd: &SubDeviceRef<'_, S>) -> Result<Mailbox, Error>
    where
        S: Deref<Target = ethercrab::SubDevice>,
    {
        let sm0: [u8; 8] = sd.register_read(0x0800u16).await?;
        let sm1: [u8; 8] = sd.register_read(0x0808u16).await?;
        let len = |sm: &[u8; 8]| usize::from(u16::from_le_bytes([sm[2], sm[3]]));
        if len(&sm0) != MBX || len(&sm1) != MBX {
            return Err(Error::Internal);
        }
        Ok(Mailbox {
            out_at: u16::from_le_bytes([sm0[0], sm0[1]]),
            in_at: u16::from_le_bytes([sm1[0], sm1[1]]),
        })
    }

    /// Writes one CoE frame (`coe_service` and the bytes after the CoE header) to SM0.
    async fn send<S>(
        &self,
        sd: &SubDeviceRef<'_, S>,
        coe_service: u8,
        body: &[u8],
    ) -> Result<(), Error>
    where
        S: Deref<Target = ethercrab::SubDevice>,
    {
        let mut coe = vec![0, coe_service << 4];
        coe.extend_from_slice(body);
        self.send_raw(sd, COE, &coe).await
    }

    /// Writes one mailbox message of type `kind` (3 CoE, 4 FoE) with `data` to SM0.
    async fn send_raw<S>(
        &self,
        sd: &SubDeviceRef<'_, S>,
        kind: u8,
        data: &[u8],
    ) -> Result<(), Error>
    where
        S: Deref<Target = ethercrab::SubDevice>,
    {
        if data.len() > MBX - 6 {
            return Err(Error::Internal);
        }
        let mut req = [0u8; MBX];
        // Mailbox header: length, address 0, channel 0, the type with counter 0.
        req[..2].copy_from_slice(&(data.len() as u16).to_le_bytes());
        req[5] = kind;
        req[6..6 + data.len()].copy_from_slice(data);
        sd.register_write(self.out_at, req).await.map(|_| ())
    }

    /// The frame in SM1 if there is one (the read frees the mailbox).
    async fn take<S>(&self, sd: &SubDeviceRef<'_, S>) -> Result<Option<[u8; MBX]>, Error>
    where
        S: Deref<Target = ethercrab::SubDevice>,
    {
        let status: u8 = sd.register_read(0x080Du16).await?;
        if status & 0x08 == 0 {
            return Ok(None);
        }
        Ok(Some(sd.register_read(self.in_at).await?))
    }

    /// Keeps `frame` in `emcy` if it is an emergency; says whether it was one.
    fn keep_emergency(frame: &[u8; MBX], emcy: &mut Vec<Emergency>) -> bool {
        let is = frame[5] & 0x0F == 0x03 && frame[7] >> 4 == service::EMERGENCY;
        if is {
            let mut e = [0u8; 8];
            e.copy_from_slice(&frame[SDO_AT..SDO_AT + 8]);
            emcy.push(e);
        }
        is
    }

    /// Reads every frame waiting in SM1: emergencies go to `emcy`, anything else (a
    /// late answer) is dropped.
    pub async fn poll_emergencies<S>(
        &self,
        sd: &SubDeviceRef<'_, S>,
        emcy: &mut Vec<Emergency>,
    ) -> Result<(), Error>
    where
        S: Deref<Target = ethercrab::SubDevice>,
    {
        while let Some(f) = self.take(sd).await? {
            Self::keep_emergency(&f, emcy);
        }
        Ok(())
    }

    /// The next CoE frame of service `want` (or, for SDO responses, an abort sent as
    /// a request) from SM1; emergencies in between go to `emcy`.
    async fn receive<S>(
        &self,
        sd: &SubDeviceRef<'_, S>,
        want: u8,
        emcy: &mut Vec<Emergency>,
    ) -> Result<[u8; MBX], Error>
    where
        S: Deref<Target = ethercrab::SubDevice>,
    {
        let deadline = Instant::now() + ANSWER_TIMEOUT;
        loop {
            if let Some(f) = self.take(sd).await? {
                let service = f[7] >> 4;
                if !Self::keep_emergency(&f, emcy)
                    && f[5] & 0x0F == 0x03
                    && (service == want
                        || (want == service::SDO_RESPONSE && service == service::SDO_REQUEST))
                {
                    return Ok(f);
                }
            } else if Instant::now() > deadline {
                return Err(Error::Timeout(TimeoutError::MailboxResponse));
            } else {
                async_io::Timer::after(Duration::from_millis(1)).await;
            }
        }
    }

    /// One SDO request (the bytes after the CoE header) and its answer; an abort
    /// becomes [`Error::Mailbox`].
    async fn sdo<S>(
        &self,
        sd: &SubDeviceRef<'_, S>,
        req: &[u8],
        emcy: &mut Vec<Emergency>,
    ) -> Result<[u8; MBX], Error>
    where
        S: Deref<Target = ethercrab::SubDevice>,
    {
        // An SDO request is at least 8 bytes (command, index, sub-index, data).
        let mut body = req.to_vec();
        if body.len() < 8 {
            body.resize(8, 0);
        }
        self.send(sd, service::SDO_REQUEST, &body).await?;
        let a = self.receive(sd, service::SDO_RESPONSE, emcy).await?;
        if a[SDO_AT] == 0x80 {
            let code = u32::from_le_bytes([a[12], a[13], a[14], a[15]]);
            return Err(aborted(code, u16::from_le_bytes([a[9], a[10]]), a[11]));
        }
        Ok(a)
    }

    /// An SDO upload of any length.
    pub async fn upload<S>(
        &self,
        sd: &SubDeviceRef<'_, S>,
        index: u16,
        sub: u8,
        emcy: &mut Vec<Emergency>,
    ) -> Result<Vec<u8>, Error>
    where
        S: Deref<Target = ethercrab::SubDevice>,
    {
        let [i0, i1] = index.to_le_bytes();
        let answer = self.sdo(sd, &[0x40, i0, i1, sub], emcy).await?;
        let cmd = answer[SDO_AT];
        if cmd & 0xE0 != 0x40 {
            return Err(Error::Internal);
        }
        if cmd & 0x02 != 0 {
            // Expedited: 4 − n bytes.
            let n = if cmd & 0x01 != 0 {
                4 - usize::from((cmd >> 2) & 3)
            } else {
                4
            };
            return Ok(answer[SDO_AT + 4..SDO_AT + 4 + n].to_vec());
        }
        let size = u32::from_le_bytes([answer[12], answer[13], answer[14], answer[15]]) as usize;
        let len = usize::from(u16::from_le_bytes([answer[0], answer[1]]));
        let first = (len.saturating_sub(10)).min(size).min(MBX - 16);
        let mut data = answer[16..16 + first].to_vec();
        let mut toggle = false;
        while data.len() < size {
            let answer = self
                .sdo(sd, &[0x60 | (u8::from(toggle) << 4), 0, 0, 0], emcy)
                .await?;
            let cmd = answer[SDO_AT];
            if cmd & 0xE0 != 0 || (cmd & 0x10 != 0) != toggle {
                return Err(Error::Internal);
            }
            let len = usize::from(u16::from_le_bytes([answer[0], answer[1]]));
            let mut n = len.saturating_sub(3).min(MBX - SDO_AT - 1);
            if n == 7 {
                n -= usize::from((cmd >> 1) & 7);
            }
            data.extend_from_slice(&answer[SDO_AT + 1..SDO_AT + 1 + n]);
            if cmd & 0x01 != 0 {
                break;
            }
            toggle = !toggle;
        }
        data.truncate(size);
        Ok(data)
    }

    /// An SDO download of `data` (expedited up to 4 bytes, else one normal transfer
    /// of at most 112 bytes).
    pub async fn download<S>(
        &self,
        sd: &SubDeviceRef<'_, S>,
        index: u16,
        sub: u8,
        data: &[u8],
        emcy: &mut Vec<Emergency>,
    ) -> Result<(), Error>
    where
        S: Deref<Target = ethercrab::SubDevice>,
    {
        let [i0, i1] = index.to_le_bytes();
        let mut req = vec![0u8, i0, i1, sub];
        if (1..=4).contains(&data.len()) {
            req[0] = 0x23 | (((4 - data.len()) as u8) << 2);
            req.extend_from_slice(data);
        } else {
            req[0] = 0x21;
            req.extend_from_slice(&(data.len() as u32).to_le_bytes());
            req.extend_from_slice(data);
        }
        let a = self.sdo(sd, &req, emcy).await?;
        if a[SDO_AT] & 0xE0 != 0x60 {
            return Err(Error::Internal);
        }
        Ok(())
    }

    /// An SDO information request and its answer: the service data of all fragments
    /// joined (after the information header); the drive's error becomes
    /// [`Error::Mailbox`].
    pub async fn info<S>(
        &self,
        sd: &SubDeviceRef<'_, S>,
        req: info::Repr,
        emcy: &mut Vec<Emergency>,
    ) -> Result<Vec<u8>, Error>
    where
        S: Deref<Target = ethercrab::SubDevice>,
    {
        let (index, sub) = match req {
            info::Repr::ObjectDescription { index } => (index, 0),
            info::Repr::EntryDescription { key, .. } => (key.index, key.sub),
            _ => (0, 0),
        };
        let mut buf = [0u8; 16];
        let n = req.emit(&mut info::Frame::new(&mut buf[..]));
        self.send(sd, service::SDO_INFORMATION, &buf[..n]).await?;
        let mut data = Vec::new();
        loop {
            let f = self.receive(sd, service::SDO_INFORMATION, emcy).await?;
            let len = usize::from(u16::from_le_bytes([f[0], f[1]]));
            let end = (6 + len).min(MBX);
            if end < SDO_AT + info::INFO_HEADER_LEN {
                return Err(Error::Internal);
            }
            let frame = info::Frame::new(&f[SDO_AT..end]);
            if frame.opcode() == info::opcode::ERROR {
                let d = frame.data();
                let code = d
                    .get(..4)
                    .map_or(0, |c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]));
                return Err(aborted(code, index, sub));
            }
            data.extend_from_slice(frame.data());
            if !frame.incomplete() {
                return Ok(data);
            }
        }
    }
}

/// Why an FoE write failed.
#[derive(Debug)]
pub enum FoeFailure {
    /// The drive answered ERR: its code and text (the standard text where it sent none).
    Refused(u32, String),
    /// No (valid) answer.
    Transport(Error),
}

impl From<Error> for FoeFailure {
    fn from(e: Error) -> Self {
        FoeFailure::Transport(e)
    }
}

impl Mailbox {
    /// The next FoE message from SM1 (after the mailbox header); emergencies go to
    /// `emcy`, other messages are dropped.
    async fn receive_foe<S>(
        &self,
        sd: &SubDeviceRef<'_, S>,
        emcy: &mut Vec<Emergency>,
    ) -> Result<Vec<u8>, Error>
    where
        S: Deref<Target = ethercrab::SubDevice>,
    {
        let deadline = Instant::now() + ANSWER_TIMEOUT;
        loop {
            if let Some(f) = self.take(sd).await? {
                if !Self::keep_emergency(&f, emcy) && f[5] & 0x0F == FOE {
                    let n = usize::from(u16::from_le_bytes([f[0], f[1]])).min(MBX - 6);
                    return Ok(f[6..6 + n].to_vec());
                }
            } else if Instant::now() > deadline {
                return Err(Error::Timeout(TimeoutError::MailboxResponse));
            } else {
                async_io::Timer::after(Duration::from_millis(1)).await;
            }
        }
    }

    /// An FoE write of `file` as `name` (ETG.1000.6 5.8): DATA of the mailbox's size,
    /// each sent again after BUSY; `progress` gets the bytes acknowledged so far.
    pub async fn foe_write<S>(
        &self,
        sd: &SubDeviceRef<'_, S>,
        name: &[u8],
        password: u32,
        file: &[u8],
        progress: &mut dyn FnMut(usize),
        emcy: &mut Vec<Emergency>,
    ) -> Result<(), FoeFailure>
    where
        S: Deref<Target = ethercrab::SubDevice>,
    {
        use ecat_slave_stack::foe::{ErrorCode, Frame, Repr, OVERHEAD};
        let segment = MBX - OVERHEAD;
        // The answer to `req`: Some(acknowledged packet), None for BUSY.
        let exchange =
            async |req: Repr<'_>, emcy: &mut Vec<Emergency>| -> Result<Option<u32>, FoeFailure> {
                let mut b = vec![0u8; req.buffer_len()];
                req.emit(&mut Frame::new_unchecked(&mut b[..]));
                self.send_raw(sd, FOE, &b).await?;
                let a = self.receive_foe(sd, emcy).await?;
                let f = Frame::new_checked(&a[..])
                    .map_err(|_| FoeFailure::Transport(Error::Internal))?;
                match Repr::parse(&f).map_err(|_| FoeFailure::Transport(Error::Internal))? {
                    Repr::Ack { packet } => Ok(Some(packet)),
                    Repr::Busy { .. } => Ok(None),
                    Repr::Error { code, text } => {
                        let words = if text.is_empty() {
                            ErrorCode::from_code(code)
                                .map_or("", ErrorCode::text)
                                .to_string()
                        } else {
                            String::from_utf8_lossy(text).into_owned()
                        };
                        Err(FoeFailure::Refused(code, words))
                    }
                    _ => Err(FoeFailure::Transport(Error::Internal)),
                }
            };
        if exchange(Repr::Write { password, name }, emcy).await? != Some(0) {
            return Err(FoeFailure::Transport(Error::Internal));
        }
        // A file that fills whole DATA ends with an empty one.
        let count = file.len() / segment + 1;
        for k in 0..count {
            let data = &file[(k * segment).min(file.len())..((k + 1) * segment).min(file.len())];
            let packet = k as u32 + 1;
            let mut busy = 0u32;
            loop {
                match exchange(Repr::Data { packet, data }, emcy).await? {
                    Some(n) if n == packet => break,
                    None if busy < 100_000 => busy += 1,
                    _ => return Err(FoeFailure::Transport(Error::Internal)),
                }
            }
            progress((k * segment + data.len()).min(file.len()));
        }
        Ok(())
    }
}

/// An SDO upload of any length through the mailbox of `sd` (emergencies arriving
/// meanwhile are dropped).
pub async fn sdo_upload<S>(sd: &SubDeviceRef<'_, S>, index: u16, sub: u8) -> Result<Vec<u8>, Error>
where
    S: Deref<Target = ethercrab::SubDevice>,
{
    let mbx = Mailbox::of(sd).await?;
    mbx.upload(sd, index, sub, &mut Vec::new()).await
}
