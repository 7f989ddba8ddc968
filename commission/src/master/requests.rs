//! The page's requests, served between the cycles through each drive's mailbox:
//! the object dictionary (SDO information, upload, download), store / restore, the
//! diagnosis history 0x10F3, the scope, the tunes and the firmware update over FoE
//! (Init → Bootstrap → Init).

use ecat_slave_stack::od::ObjectKey;
use std::ops::Deref;
use std::time::{Duration, Instant};

use ecat_slave_stack::coe::info;
use serde_json::{json, Value};
use tests_host::coe_client::{Emergency, FoeFailure, Mailbox};
use tests_host::scope_host::{self, Channel, ScopeConfig};

use super::{Cmd, Reply, ScopeRequest, Session, UpdateView};
use crate::dict::{self, EntryInfo, ObjectInfo};
use crate::texts;

/// A drive of the segment as the requests reach it.
type Drive<'a, S> = ethercrab::SubDeviceRef<'a, S>;

/// The text of a mailbox error.
fn err(e: ethercrab::error::Error) -> String {
    texts::error(&e)
}

impl Session<'_> {
    /// One request of the page, through drive `cmd.drive()`'s mailbox.
    pub(super) async fn handle(&self, cmd: Cmd, emcy: &mut Vec<Emergency>) -> Reply {
        let k = cmd.drive();
        let sd = self
            .group
            .subdevice(self.md, k)
            .map_err(|_| format!("no drive at position {k}"))?;
        let mbx = *self.mailboxes.get(k).ok_or("no mailbox")?;
        match cmd {
            Cmd::Objects(_) => objects(&sd, mbx, emcy).await,
            Cmd::Object(_, index) => object(&sd, mbx, index, emcy).await,
            Cmd::Write(_, index, sub, text) => write(&sd, mbx, (index, sub), &text, emcy).await,
            Cmd::Store(_, load) => store(&sd, mbx, load, emcy).await,
            Cmd::History(_) => history(&sd, mbx, emcy).await,
            Cmd::Scope(_, req) => self.scope(&sd, mbx, req, emcy).await,
            Cmd::Tune(_, servo) => {
                let r = if servo {
                    mbx.download(&sd, 0x2162, 1, &[1], emcy).await
                } else {
                    mbx.download(&sd, 0x2013, 0, &[1], emcy).await
                };
                r.map_err(err)?;
                Ok(json!("started"))
            }
            Cmd::TuneResults(_) => tune_results(&sd, mbx, emcy).await,
            Cmd::Update(_, file) => self.update(k, &sd, mbx, &file, emcy).await,
        }
    }

    async fn scope<S: Deref<Target = ethercrab::SubDevice>>(
        &self,
        sd: &Drive<'_, S>,
        mbx: Mailbox,
        req: ScopeRequest,
        emcy: &mut Vec<Emergency>,
    ) -> Reply {
        let channels = req
            .channels
            .iter()
            .map(|c| Channel::parse(c))
            .collect::<Result<Vec<_>, _>>()?;
        if channels.is_empty() || channels.len() > 8 {
            return Err("1 to 8 channels".into());
        }
        let condition = scope_host::CONDITIONS
            .iter()
            .find(|c| c.0 == req.condition)
            .map(|c| c.1)
            .ok_or_else(|| format!("trigger condition '{}'", req.condition))?;
        let cfg = ScopeConfig {
            channels,
            divisor: req.divisor.max(1),
            servo_rate: req.servo_rate,
            trigger_channel: 1,
            level: req.level,
            condition,
            pretrigger: req.pretrigger,
            normal: false,
        };
        // ethercrab's own SDO writes must not meet an emergency.
        mbx.poll_emergencies(sd, emcy).await.map_err(err)?;
        scope_host::configure(sd, &cfg).await.map_err(err)?;
        scope_host::send_command(sd, firmware::scope::command::ARM)
            .await
            .map_err(err)?;
        let t0 = Instant::now();
        let mut forced = false;
        let st = loop {
            let st = scope_host::status(sd).await.map_err(err)?;
            if st.state == 3 {
                break st;
            }
            if !forced && t0.elapsed() > Duration::from_secs(3) {
                // No trigger within 3 s: take what the buffer holds.
                scope_host::send_command(sd, firmware::scope::command::FORCE)
                    .await
                    .map_err(err)?;
                forced = true;
            }
            if t0.elapsed() > Duration::from_secs(15) {
                return Err(format!("the scope did not finish (state {})", st.state));
            }
            async_io::Timer::after(Duration::from_millis(20)).await;
        };
        let rec = scope_host::read_record(sd, &cfg, &st).await.map_err(err)?;
        Ok(json!({
            "labels": rec.channels.iter().map(Channel::label).collect::<Vec<_>>(),
            "time_ms": (0..rec.rows.len()).map(|k| rec.time_ms(k)).collect::<Vec<_>>(),
            "rows": rec.rows,
            "csv": rec.csv(),
            "forced": forced,
        }))
    }

    async fn update<S: Deref<Target = ethercrab::SubDevice>>(
        &self,
        k: usize,
        sd: &Drive<'_, S>,
        mbx: Mailbox,
        file: &[u8],
        emcy: &mut Vec<Emergency>,
    ) -> Reply {
        self.paused.set(true);
        *self.shared.hold() = None;
        let set = |state: &str, sent: usize, answer: String| {
            self.shared.view().update = UpdateView {
                drive: k,
                state: state.into(),
                sent,
                total: file.len(),
                answer,
            };
        };
        set("running", 0, "taking the drive to Bootstrap".into());
        let r = self.foe(sd, mbx, file, emcy).await;
        match &r {
            Ok(()) => set(
                "running",
                file.len(),
                "the drive accepted the file; restarting the segment".into(),
            ),
            Err(e) => set("failed", 0, e.clone()),
        }
        self.shared.view().status = "restarting the segment after the update".into();
        r.map(|()| json!("accepted"))
    }

    async fn al_request<S: Deref<Target = ethercrab::SubDevice>>(
        &self,
        sd: &Drive<'_, S>,
        ctl: u16,
        want: u16,
    ) -> Result<(), String> {
        sd.register_write(0x0120u16, ctl).await.map_err(err)?;
        let t0 = Instant::now();
        loop {
            let al: [u8; 6] = sd.register_read(0x0130u16).await.map_err(err)?;
            let st = u16::from_le_bytes([al[0], al[1]]);
            if st & 0x1F == want {
                return Ok(());
            }
            if t0.elapsed() > Duration::from_secs(5) || st & 0x10 != 0 {
                let code = u16::from_le_bytes([al[4], al[5]]);
                return Err(format!(
                    "{} refused: {}",
                    texts::esm(want),
                    texts::al_code(code)
                ));
            }
            async_io::Timer::after(Duration::from_millis(5)).await;
        }
    }

    async fn foe<S: Deref<Target = ethercrab::SubDevice>>(
        &self,
        sd: &Drive<'_, S>,
        mbx: Mailbox,
        file: &[u8],
        emcy: &mut Vec<Emergency>,
    ) -> Result<(), String> {
        self.al_request(sd, 0x0011, 0x01).await?;
        // The boot mailbox (SII words 0x14-0x17) into SM0 / SM1.
        let boot: [u8; 8] = sd.eeprom_read(self.md, 0x14).await.map_err(err)?;
        let mut sms = [0u8; 16];
        sms[0..4].copy_from_slice(&boot[0..4]);
        sms[4] = 0x26;
        sms[6] = 1;
        sms[8..12].copy_from_slice(&boot[4..8]);
        sms[12] = 0x22;
        sms[14] = 1;
        sd.register_write(0x0800u16, sms).await.map_err(err)?;
        self.al_request(sd, 0x0003, 0x03).await?;
        let boot_mbx = Mailbox::of(sd).await.map_err(err)?;
        let _ = mbx;
        let total = file.len();
        let shared = self.shared;
        let mut progress = |n: usize| {
            let mut v = shared.view();
            v.update.sent = n;
            v.update.answer = format!("{n} of {total} bytes acknowledged");
        };
        let name = b"ecs-update.efw";
        let r = boot_mbx
            .foe_write(sd, name, 0, file, &mut progress, emcy)
            .await;
        // Back to Init either way: after a good file the drive starts the new image.
        let back = self.al_request(sd, 0x0011, 0x01).await;
        match r {
            Ok(()) => back,
            Err(FoeFailure::Refused(code, text)) => Err(format!(
                "the drive refused the file: FoE error {code:#x}: {text}"
            )),
            Err(FoeFailure::Transport(e)) => Err(format!("FoE: {}", texts::error(&e))),
        }
    }
}

/// The object list (SDO information): every object's description.
async fn objects<S: Deref<Target = ethercrab::SubDevice>>(
    sd: &Drive<'_, S>,
    mbx: Mailbox,
    emcy: &mut Vec<Emergency>,
) -> Reply {
    let list = mbx
        .info(sd, info::Repr::OdList { list: 1 }, emcy)
        .await
        .map_err(err)?;
    let mut objects: Vec<ObjectInfo> = Vec::new();
    for index in dict::parse_list(&list) {
        let d = mbx
            .info(sd, info::Repr::ObjectDescription { index }, emcy)
            .await
            .map_err(err)?;
        objects.extend(dict::parse_object(&d));
    }
    Ok(json!(objects))
}

/// Object `index`: its description, its entries' descriptions and their values.
async fn object<S: Deref<Target = ethercrab::SubDevice>>(
    sd: &Drive<'_, S>,
    mbx: Mailbox,
    index: u16,
    emcy: &mut Vec<Emergency>,
) -> Reply {
    let d = mbx
        .info(sd, info::Repr::ObjectDescription { index }, emcy)
        .await
        .map_err(err)?;
    let obj = dict::parse_object(&d).ok_or("bad object description")?;
    let mut entries: Vec<(EntryInfo, Result<String, String>)> = Vec::new();
    let first = u8::from(obj.code != 7 && obj.max_sub > 0);
    for sub in (0..=obj.max_sub).filter(|&s| s == 0 || s >= first) {
        let req = info::Repr::EntryDescription {
            key: ObjectKey::new(index, sub),
            value_info: 0x70,
        };
        let Ok(d) = mbx.info(sd, req, emcy).await else {
            continue;
        };
        let Some(e) = dict::parse_entry(&d) else {
            continue;
        };
        let value = if e.access & 0x07 != 0 {
            mbx.upload(sd, index, sub, emcy)
                .await
                .map(|v| dict::format_value(e.data_type, &v))
                .map_err(err)
        } else {
            Err("write only".into())
        };
        entries.push((e, value));
    }
    Ok(
        json!({"object": obj, "entries": entries.iter().map(|(e, v)| json!({
        "entry": e, "value": v.as_ref().ok(), "error": v.as_ref().err()
    })).collect::<Vec<_>>()}),
    )
}

/// Writes `text` (parsed by the entry's data type) to `index:sub`; the value read back.
async fn write<S: Deref<Target = ethercrab::SubDevice>>(
    sd: &Drive<'_, S>,
    mbx: Mailbox,
    (index, sub): (u16, u8),
    text: &str,
    emcy: &mut Vec<Emergency>,
) -> Reply {
    let req = info::Repr::EntryDescription {
        key: ObjectKey::new(index, sub),
        value_info: 0,
    };
    let d = mbx.info(sd, req, emcy).await.map_err(err)?;
    let e = dict::parse_entry(&d).ok_or("bad entry description")?;
    let bytes = dict::parse_value(e.data_type, e.bits, text)?;
    mbx.download(sd, index, sub, &bytes, emcy)
        .await
        .map_err(err)?;
    let back = mbx.upload(sd, index, sub, emcy).await.map_err(err)?;
    Ok(json!(dict::format_value(e.data_type, &back)))
}

/// Save the parameters (0x1010) or restore the defaults (0x1011, `load`).
async fn store<S: Deref<Target = ethercrab::SubDevice>>(
    sd: &Drive<'_, S>,
    mbx: Mailbox,
    load: bool,
    emcy: &mut Vec<Emergency>,
) -> Reply {
    // "save" / "load" signatures of CiA 301.
    let (index, sig) = if load {
        (0x1011, *b"load")
    } else {
        (0x1010, *b"save")
    };
    mbx.download(sd, index, 1, &sig, emcy).await.map_err(err)?;
    Ok(json!(if load {
        "defaults stored; they apply from the next power-up (CiA 301 0x1011)"
    } else {
        "parameters saved"
    }))
}

/// The diagnosis history 0x10F3, oldest message first.
async fn history<S: Deref<Target = ethercrab::SubDevice>>(
    sd: &Drive<'_, S>,
    mbx: Mailbox,
    emcy: &mut Vec<Emergency>,
) -> Reply {
    let n = firmware::diagnosis::HISTORY_LEN as u8;
    let mut out = Vec::new();
    for sub in 6..6 + n {
        let Ok(b) = mbx.upload(sd, 0x10F3, sub, emcy).await else {
            break;
        };
        if let Some(m) = ecat_slave_stack::diag::DiagMessage::parse(&b) {
            if m.code == 0 && m.text_id == 0 {
                continue;
            }
            out.push((
                m.time_ns,
                json!({
                    "time_ms": m.time_ns / 1_000_000,
                    "code": format!("{:#010x}", m.code),
                    "severity": format!("{:?}", m.severity),
                    "text": texts::message(&m),
                }),
            ));
        }
    }
    out.sort_by_key(|(t, _)| *t);
    Ok(json!(out.into_iter().map(|(_, v)| v).collect::<Vec<_>>()))
}

/// The tunes' state and results (0x2162:02, 0x2164, 0x2165, 0x2160, 0x2161, 0x2013).
async fn tune_results<S: Deref<Target = ethercrab::SubDevice>>(
    sd: &Drive<'_, S>,
    mbx: Mailbox,
    emcy: &mut Vec<Emergency>,
) -> Reply {
    let mut out = serde_json::Map::new();
    for (name, index, sub) in [
        ("servo tune state 0x2162:02", 0x2162u16, 2u8),
        ("load inertia ratio 0x2164 [%]", 0x2164, 0),
        ("Coulomb friction 0x2165 [mN·m]", 0x2165, 0),
        ("inertia ratio in use 0x2160 [%]", 0x2160, 0),
        ("stiffness 0x2161", 0x2161, 0),
        ("current tune 0x2013", 0x2013, 0),
    ] {
        let v = match mbx.upload(sd, index, sub, emcy).await {
            Ok(b) => {
                let mut w = [0u8; 8];
                w[..b.len().min(8)].copy_from_slice(&b[..b.len().min(8)]);
                json!(u64::from_le_bytes(w))
            }
            Err(e) => json!(texts::error(&e)),
        };
        out.insert(name.into(), v);
    }
    Ok(Value::Object(out))
}
