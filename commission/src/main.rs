//! `ecs-commission`: commissioning the drives of an EtherCAT segment from a browser.
//!
//! ```text
//! ecs-commission --iface NAME [--listen ADDR:PORT]
//! ecs-commission --virtual N [--virtual-drive PATH] [--fault KIND@TIME]... [--listen ADDR:PORT]
//! ```
//!
//! Runs an ethercrab master on the network interface `NAME` (raw socket: root or
//! CAP_NET_RAW) and serves the page on 127.0.0.1:8036 (another address only with
//! `--listen`). `--virtual N` starts `virtual-drive --drives N` in a network
//! namespace of its own (root) and commissions those drives: the quick start without
//! hardware; `--fault KIND@TIME` makes the virtual drives' plant develop a fault
//! (`virtual-drive --fault`). See docs/guide/commissioning-tool.md.

mod dict;
mod master;
mod texts;
mod web;

use std::net::SocketAddr;
use std::process::ExitCode;
use std::sync::{Arc, Mutex};

struct Options {
    iface: Option<String>,
    virtual_drives: Option<usize>,
    virtual_drive: Option<String>,
    /// `--fault KIND@TIME` options handed to `virtual-drive`.
    faults: Vec<String>,
    listen: SocketAddr,
}

const USAGE: &str = "usage: ecs-commission --iface NAME [--listen ADDR:PORT]\n       \
ecs-commission --virtual N [--virtual-drive PATH] [--fault KIND@TIME]... [--listen ADDR:PORT]";

fn options() -> Result<Options, String> {
    let mut o = Options {
        iface: None,
        virtual_drives: None,
        virtual_drive: None,
        faults: Vec::new(),
        listen: SocketAddr::from(([127, 0, 0, 1], 8036)),
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = |name: &str| args.next().ok_or(format!("{name} needs a value"));
        match a.as_str() {
            "--iface" => o.iface = Some(value("--iface")?),
            "--virtual" => {
                let n: usize = value("--virtual")?
                    .parse()
                    .map_err(|_| "--virtual N: a number of drives")?;
                if !(1..=master::MAX_DRIVES).contains(&n) {
                    return Err(format!("--virtual: 1 to {} drives", master::MAX_DRIVES));
                }
                o.virtual_drives = Some(n);
            }
            "--virtual-drive" => o.virtual_drive = Some(value("--virtual-drive")?),
            "--fault" => {
                let f = value("--fault")?;
                o.faults.push("--fault".into());
                o.faults.push(f);
            }
            "--listen" => {
                o.listen = value("--listen")?
                    .parse()
                    .map_err(|_| "--listen ADDR:PORT, e.g. 127.0.0.1:8036")?
            }
            "-h" | "--help" => return Err(USAGE.into()),
            other => return Err(format!("unknown argument '{other}'\n{USAGE}")),
        }
    }
    if o.iface.is_some() && !o.faults.is_empty() {
        return Err("--fault is for --virtual drives".into());
    }
    if o.iface.is_some() == o.virtual_drives.is_some() {
        return Err(format!("give --iface or --virtual\n{USAGE}"));
    }
    Ok(o)
}

/// Whether `iface` has a link (carrier).
fn has_link(iface: &str) -> bool {
    std::fs::read_to_string(format!("/sys/class/net/{iface}/carrier"))
        .is_ok_and(|c| c.trim() == "1")
}

/// `--virtual N`: `virtual-drive --drives N` started in a network namespace of its
/// own (kept for the tool's life), or what is missing.
fn start_virtual(o: &Options, n: usize) -> Result<tests_host::vd_master::Running, String> {
    let program = o.virtual_drive.clone().unwrap_or_else(|| {
        std::env::current_exe()
            .ok()
            .and_then(|p| Some(p.parent()?.join("virtual-drive")))
            .map(|p| p.display().to_string())
            .unwrap_or_default()
    });
    if !std::path::Path::new(&program).exists() {
        return Err(format!(
            "no virtual-drive at '{program}': build it with \
             `cargo build -p tests-host --bin virtual-drive` or give --virtual-drive PATH"
        ));
    }
    if !tests_host::netns::is_root() {
        return Err("--virtual needs root (network namespace and raw socket)".into());
    }
    tests_host::vd_master::Running::start(&program, "cm", n, &o.faults)
        .map_err(|e| format!("virtual-drive: {e}"))
}

fn main() -> ExitCode {
    let o = match options() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(2);
        }
    };
    // `--virtual`: the drives in a namespace of their own, kept for the tool's life.
    let mut vd_running = None;
    let iface = match (&o.iface, o.virtual_drives) {
        (Some(i), _) => i.clone(),
        (None, Some(n)) => match start_virtual(&o, n) {
            Ok(r) => {
                let i = r.net.host_if.clone();
                vd_running = Some(r);
                i
            }
            Err(e) => {
                eprintln!("ecs-commission: {e}");
                return ExitCode::FAILURE;
            }
        },
        _ => unreachable!("checked by options()"),
    };
    // One clear line when the socket or the link is missing.
    if let Err(e) = tests_host::raw_socket::RawSocket::open(&iface) {
        eprintln!("ecs-commission: {e}");
        return ExitCode::FAILURE;
    }
    if !has_link(&iface) {
        eprintln!("ecs-commission: network interface '{iface}' has no link (cable plugged in, interface up?)");
        return ExitCode::FAILURE;
    }
    let shared = Arc::new(master::Shared {
        view: Mutex::new(master::View {
            iface: iface.clone(),
            status: "starting".into(),
            ..master::View::default()
        }),
        hold: Mutex::new(None),
        t0: std::time::Instant::now(),
    });
    let (tx, rx) = std::sync::mpsc::channel();
    {
        let shared = shared.clone();
        let iface = iface.clone();
        std::thread::spawn(move || master::run(&iface, shared, rx));
    }
    let rt = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("ecs-commission: {e}");
            return ExitCode::FAILURE;
        }
    };
    let r = rt.block_on(web::serve(o.listen, shared, tx));
    // The virtual drives end before their namespace goes.
    if let Some(vd) = vd_running {
        vd.terminate(std::time::Duration::from_secs(3));
    }
    match r {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("ecs-commission: {e}");
            ExitCode::FAILURE
        }
    }
}
