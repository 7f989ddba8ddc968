//! `scope`: records signals of a drive with its scope (objects 0x2500-0x2510) over a
//! Linux network interface — a real drive on a cable or `virtual-drive` on a veth
//! pair — and writes the record as CSV and as a PNG plot.
//!
//! ```text
//! scope --iface NAME [--ch INDEX[:SUB]]... [--divisor N] [--servo-rate]
//!       [--trigger-ch N] [--level V]
//!       [--edge immediate|rising|falling|either|above|below] [--pre N]
//!       [--mode single|normal] [--move none|csp|pv] [--distance UNITS]
//!       [--velocity UNITS/S] [--out PREFIX] [--timeout S]
//! ```
//!
//! ethercrab brings the first drive to Pre-Op and writes the configuration. Without
//! a move the scope is armed in Pre-Op and records what the drive does on its own.
//! `--move csp` (the default) enables the drive in CSP in Op, arms the scope at
//! standstill and commands a cycloidal move of `--distance` units in 300 ms;
//! `--move pv` commands `--velocity` for 300 ms in PV, on the drive's own ramps. Then
//! it waits for the record, reads it by SDO (0x2503, segmented) and writes
//! `PREFIX.csv` (`sample,time_ms,<channels>`, time 0 at the trigger) and `PREFIX.png`.
//!
//! Defaults: channels 0x6062 (position demand), 0x6064 (position actual), 0x60F4
//! (following error), 0x606C (velocity actual), 0x2303 (phase A current); one sample
//! every 3 ms; trigger on channel 1, rising edge, 40 samples before it; single. The
//! level defaults, for a position channel with a move, to the start position plus
//! 5 % of the distance, else 0. `--servo-rate` makes the 100 µs servo period the time
//! base (the internal signals 0x2510 at that rate, e.g. `--ch 0x2510:7` the q current
//! demand). Exit code 2 for bad options, 1 for a failure.
#![deny(clippy::undocumented_unsafe_blocks)]

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use ethercrab::std::{ethercat_now, tx_rx_task};
use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, Timeouts};
use firmware::scope::command;
use tests_host::scope_host::{self, Channel, Record, ScopeConfig, CONDITIONS};

static PDU_STORAGE: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Move {
    None,
    Csp,
    Pv,
}

struct Options {
    iface: String,
    cfg: ScopeConfig,
    level_given: bool,
    motion: Move,
    distance: i32,
    velocity: i32,
    out: PathBuf,
    timeout: Duration,
}

const USAGE: &str = "usage: scope --iface NAME [--ch INDEX[:SUB]]... [--divisor N] [--servo-rate] \
[--trigger-ch N] [--level V] [--edge immediate|rising|falling|either|above|below] [--pre N] \
[--mode single|normal] [--move none|csp|pv] [--distance UNITS] [--velocity UNITS/S] \
[--out PREFIX] [--timeout S]";

fn number<T: std::str::FromStr>(name: &str, v: &str) -> Result<T, String> {
    v.parse()
        .map_err(|_| format!("{name}: '{v}' is not a valid number"))
}

/// The options before the command line: the default channels come in [`checked`].
fn defaults() -> Options {
    Options {
        iface: String::new(),
        cfg: ScopeConfig {
            channels: Vec::new(),
            divisor: 3,
            servo_rate: false,
            trigger_channel: 1,
            level: 0,
            condition: 1,
            pretrigger: 40,
            normal: false,
        },
        level_given: false,
        motion: Move::Csp,
        distance: 25_000,
        velocity: 50_000,
        out: PathBuf::from("scope"),
        timeout: Duration::from_secs(10),
    }
}

fn parse(args: &[String]) -> Result<Options, String> {
    let mut o = defaults();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = |name: &str| {
            it.next()
                .cloned()
                .ok_or_else(|| format!("{name} needs a value"))
        };
        match a.as_str() {
            "--iface" => o.iface = value(a)?,
            "--ch" => o.cfg.channels.push(Channel::parse(&value(a)?)?),
            "--divisor" => o.cfg.divisor = number(a, &value(a)?)?,
            "--servo-rate" => o.cfg.servo_rate = true,
            "--trigger-ch" => o.cfg.trigger_channel = number(a, &value(a)?)?,
            "--level" => {
                o.cfg.level = number(a, &value(a)?)?;
                o.level_given = true;
            }
            "--edge" => {
                let v = value(a)?;
                o.cfg.condition = CONDITIONS
                    .iter()
                    .find(|c| c.0 == v)
                    .map(|c| c.1)
                    .ok_or_else(|| format!("--edge: unknown condition '{v}'"))?;
            }
            "--pre" => o.cfg.pretrigger = number(a, &value(a)?)?,
            "--mode" => {
                o.cfg.normal = match value(a)?.as_str() {
                    "single" => false,
                    "normal" => true,
                    m => return Err(format!("--mode: '{m}' (single or normal)")),
                }
            }
            "--move" => {
                o.motion = match value(a)?.as_str() {
                    "none" => Move::None,
                    "csp" => Move::Csp,
                    "pv" => Move::Pv,
                    m => return Err(format!("--move: '{m}' (none, csp or pv)")),
                }
            }
            "--distance" => o.distance = number(a, &value(a)?)?,
            "--velocity" => o.velocity = number(a, &value(a)?)?,
            "--out" => o.out = PathBuf::from(value(a)?),
            "--timeout" => o.timeout = Duration::from_secs_f64(number(a, &value(a)?)?),
            "-h" | "--help" => return Err(USAGE.into()),
            other => return Err(format!("unknown argument '{other}'\n{USAGE}")),
        }
    }
    checked(o)
}

/// `o` with the default channels when none was given, or what is wrong with it.
fn checked(mut o: Options) -> Result<Options, String> {
    if o.iface.is_empty() {
        return Err(format!("--iface is required\n{USAGE}"));
    }
    if o.cfg.channels.is_empty() {
        for ch in ["0x6062", "0x6064", "0x60F4", "0x606C", "0x2303"] {
            o.cfg.channels.push(Channel::parse(ch)?);
        }
    }
    let n = o.cfg.channels.len();
    if n > firmware::scope::CHANNELS {
        return Err(format!(
            "{n} channels: the scope records {} at most",
            firmware::scope::CHANNELS
        ));
    }
    if !(1..=n).contains(&usize::from(o.cfg.trigger_channel)) {
        return Err(format!("--trigger-ch: 1 to {n}"));
    }
    if usize::from(o.cfg.pretrigger) >= o.cfg.depth() {
        return Err(format!(
            "--pre: below the {} samples per channel of {n} channel(s)",
            o.cfg.depth()
        ));
    }
    Ok(o)
}

/// What went wrong, for the message.
type Failure = String;

/// The message of a failed step `what`.
fn at(what: &'static str) -> impl Fn(ethercrab::error::Error) -> Failure {
    move |e| format!("{what}: {e}")
}

/// Inputs of the default TxPDO 0x1A00: statusword and position actual value.
fn decode(inputs: &[u8]) -> (u16, i32) {
    let sw = inputs
        .get(2..4)
        .map_or(0, |b| u16::from_le_bytes([b[0], b[1]]));
    let pos = inputs
        .get(5..9)
        .map_or(0, |b| i32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    (sw, pos)
}

/// The CiA 402 enable sequence from the statusword (shutdown, switch on, enable).
fn enable_controlword(sw: u16) -> u16 {
    match sw & 0x6F {
        0x21 => 0x0007,
        0x23 | 0x27 => 0x000F,
        _ if sw & 0x4F == 0x40 => 0x0006,
        _ => 0x0000,
    }
}

fn is_position(ch: &Channel) -> bool {
    matches!(ch.index, 0x6062 | 0x6063 | 0x6064 | 0x607A | 0x60FC) && ch.sub == 0
}

async fn wait_done<S>(
    sd: &ethercrab::SubDeviceRef<'_, S>,
    until: Instant,
) -> Result<scope_host::Status, Failure>
where
    S: std::ops::Deref<Target = ethercrab::SubDevice>,
{
    loop {
        let st = scope_host::status(sd).await.map_err(at("0x2502"))?;
        if st.state == 3 || Instant::now() > until {
            return Ok(st);
        }
        async_io::Timer::after(Duration::from_millis(20)).await;
    }
}

/// Pre-Op only: arms and waits.
async fn record_in_preop(md: &MainDevice<'static>, o: &Options) -> Result<Record, Failure> {
    let group = md
        .init_single_group::<4, 128>(ethercat_now)
        .await
        .map_err(at("init"))?;
    let sd = group.subdevice(md, 0).map_err(at("drive 0"))?;
    scope_host::configure(&sd, &o.cfg)
        .await
        .map_err(at("configure"))?;
    scope_host::send_command(&sd, command::ARM)
        .await
        .map_err(at("arm"))?;
    let st = wait_done(&sd, Instant::now() + o.timeout).await?;
    if st.state != 3 {
        let _ = scope_host::send_command(&sd, command::FORCE).await;
        return Err(format!(
            "no record before --timeout (scope state {})",
            st.state
        ));
    }
    scope_host::read_record(&sd, &o.cfg, &st)
        .await
        .map_err(at("0x2503"))
}

/// The group in Op.
type OpGroup =
    ethercrab::SubDeviceGroup<4, 128, ethercrab::DefaultLock, ethercrab::subdevice_group::Op>;

/// Writes controlword `cw` and target `target` into the outputs of drive 0.
fn set_outputs(
    md: &MainDevice<'static>,
    group: &OpGroup,
    cw: u16,
    target: i32,
) -> Result<(), Failure> {
    let sd = group.subdevice(md, 0).map_err(at("drive 0"))?;
    let mut out = sd.outputs_raw_mut();
    out[0..2].copy_from_slice(&cw.to_le_bytes());
    out[2..6].copy_from_slice(&target.to_le_bytes());
    Ok(())
}

/// One cycle: the outputs, the exchange, the statusword and position that came back.
async fn exchange(
    md: &MainDevice<'static>,
    group: &OpGroup,
    cw: u16,
    target: i32,
) -> Result<(u16, i32), Failure> {
    set_outputs(md, group, cw, target)?;
    group.tx_rx(md).await.map_err(at("tx_rx"))?;
    Ok(decode(
        &group.subdevice(md, 0).map_err(at("drive 0"))?.inputs_raw(),
    ))
}

/// Enables drive 0 (the drive's power-up self-test may take a few seconds first);
/// returns the position it holds.
async fn enable(md: &MainDevice<'static>, group: &OpGroup) -> Result<i32, Failure> {
    let (mut sw, mut pos) = (0u16, 0i32);
    let deadline = Instant::now() + Duration::from_secs(8);
    while sw & 0x6F != 0x27 {
        if Instant::now() > deadline {
            return Err(format!("enable: statusword {sw:#06x} after 8 s"));
        }
        (sw, pos) = exchange(md, group, enable_controlword(sw), pos).await?;
        async_io::Timer::after(Duration::from_millis(1)).await;
    }
    Ok(pos)
}

/// Op: enable in CSP or PV, arm at standstill, move, wait for the record, Pre-Op, read.
async fn record_with_move(md: &MainDevice<'static>, o: &Options) -> Result<Record, Failure> {
    let mut cfg = o.cfg.clone();
    let group = md
        .init_single_group::<4, 128>(ethercat_now)
        .await
        .map_err(at("init"))?;
    {
        let sd = group.subdevice(md, 0).map_err(at("drive 0"))?;
        let mode: i8 = if o.motion == Move::Csp { 8 } else { 3 };
        sd.sdo_write(0x6060, 0, mode).await.map_err(at("0x6060"))?;
        sd.sdo_write(0x60FF, 0, 0i32).await.map_err(at("0x60FF"))?;
    }
    let group = group.into_op(md).await.map_err(at("into_op"))?;
    let p0 = enable(md, &group).await?;
    if !o.level_given && o.motion == Move::Csp {
        if let Some(ch) = cfg.channels.get(usize::from(cfg.trigger_channel) - 1) {
            if is_position(ch) {
                cfg.level = p0.saturating_add(o.distance / 20);
            }
        }
    }
    {
        let sd = group.subdevice(md, 0).map_err(at("drive 0"))?;
        scope_host::configure(&sd, &cfg)
            .await
            .map_err(at("configure"))?;
        scope_host::send_command(&sd, command::ARM)
            .await
            .map_err(at("arm"))?;
    }
    let target = run_move(md, &group, o, &cfg, p0).await?;
    for _ in 0..20 {
        exchange(md, &group, 0x0006, target).await?;
        async_io::Timer::after(Duration::from_millis(1)).await;
    }
    let group = group.into_safe_op(md).await.map_err(at("into_safe_op"))?;
    let group = group.into_pre_op(md).await.map_err(at("into_pre_op"))?;
    let sd = group.subdevice(md, 0).map_err(at("drive 0"))?;
    let st = scope_host::status(&sd).await.map_err(at("0x2502"))?;
    if st.state != 3 {
        return Err(format!(
            "no record before --timeout (scope state {})",
            st.state
        ));
    }
    scope_host::read_record(&sd, &cfg, &st)
        .await
        .map_err(at("0x2503"))
}

/// Standstill long enough for the pre-trigger samples, the move (a CSP S-curve of
/// `--distance` or a PV run at `--velocity`), then holding until the record is done or
/// `--timeout`. Returns the last target.
async fn run_move(
    md: &MainDevice<'static>,
    group: &OpGroup,
    o: &Options,
    cfg: &ScopeConfig,
    p0: i32,
) -> Result<i32, Failure> {
    let pre_ms = u64::from(cfg.pretrigger) * u64::from(cfg.divisor) + 50;
    let move_ms = 300u64;
    let start = Instant::now();
    let mut pv_sent = (false, false);
    let mut last_poll = Instant::now();
    let mut fault_seen = false;
    let until = Instant::now() + o.timeout;
    let mut target = p0;
    loop {
        let t_ms = start.elapsed().as_secs_f64() * 1e3 - pre_ms as f64;
        if o.motion == Move::Csp {
            let s = (t_ms / move_ms as f64).clamp(0.0, 1.0);
            let tau = std::f64::consts::TAU;
            let p = f64::from(o.distance) * (s - (tau * s).sin() / tau);
            target = p0.saturating_add(p.round() as i32);
        }
        let (sw, _) = exchange(md, group, 0x000F, target).await?;
        let sd = group.subdevice(md, 0).map_err(at("drive 0"))?;
        if o.motion == Move::Pv && t_ms >= 0.0 && !pv_sent.0 {
            sd.sdo_write(0x60FF, 0, o.velocity)
                .await
                .map_err(at("0x60FF"))?;
            pv_sent.0 = true;
        }
        if o.motion == Move::Pv && t_ms >= move_ms as f64 && !pv_sent.1 {
            sd.sdo_write(0x60FF, 0, 0i32).await.map_err(at("0x60FF"))?;
            pv_sent.1 = true;
        }
        if t_ms > move_ms as f64 && last_poll.elapsed() > Duration::from_millis(50) {
            last_poll = Instant::now();
            let st: u8 = sd
                .sdo_read(firmware::scope::STATUS, 1)
                .await
                .map_err(at("0x2502"))?;
            if st == 3 || Instant::now() > until {
                return Ok(target);
            }
        }
        if sw & 0x08 != 0 && !fault_seen {
            // Reported once; the scope keeps recording (the record may show why).
            fault_seen = true;
            let code: u16 = sd.sdo_read(0x603F, 0).await.map_err(at("0x603F"))?;
            eprintln!("scope: the drive reports fault {code:#06x} (statusword {sw:#06x})");
        }
        async_io::Timer::after(Duration::from_millis(1)).await;
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let o = match parse(&args) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("scope: {e}");
            return ExitCode::from(2);
        }
    };
    let Ok((pdu_tx, pdu_rx, pdu_loop)) = PDU_STORAGE.try_split() else {
        eprintln!("scope: PDU storage");
        return ExitCode::from(1);
    };
    let task = match tx_rx_task(&o.iface, pdu_tx, pdu_rx) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("scope: raw socket on {}: {e}", o.iface);
            return ExitCode::from(1);
        }
    };
    std::thread::spawn(move || {
        let _ = async_io::block_on(task);
    });
    let md = MainDevice::new(
        pdu_loop,
        Timeouts {
            wait_loop_delay: Duration::from_millis(2),
            mailbox_response: Duration::from_millis(2000),
            pdu: Duration::from_millis(300),
            eeprom: Duration::from_millis(100),
            ..Timeouts::default()
        },
        MainDeviceConfig {
            dc_static_sync_iterations: 100,
            ..MainDeviceConfig::default()
        },
    );
    let result = async_io::block_on(async {
        match o.motion {
            Move::None => record_in_preop(&md, &o).await,
            _ => record_with_move(&md, &o).await,
        }
    });
    let record = match result {
        Ok(r) => r,
        Err(e) => {
            eprintln!("scope: {e}");
            return ExitCode::from(1);
        }
    };
    let csv = o.out.with_extension("csv");
    let png = o.out.with_extension("png");
    if let Err(e) = std::fs::write(&csv, record.csv()) {
        eprintln!("scope: {}: {e}", csv.display());
        return ExitCode::from(1);
    }
    let text = tests_host::plot::load_font();
    let title = format!(
        "Scope: {} samples every {} ms, trigger at sample {}",
        record.rows.len(),
        record.period_ms,
        record.trigger
    );
    if let Err(e) = record.plot(&png, &title, text) {
        eprintln!("scope: {}: {e}", png.display());
        return ExitCode::from(1);
    }
    println!(
        "scope: {} samples × {} channels, every {} ms, trigger at sample {} → {} and {}",
        record.rows.len(),
        record.channels.len(),
        record.period_ms,
        record.trigger,
        csv.display(),
        png.display()
    );
    ExitCode::SUCCESS
}
