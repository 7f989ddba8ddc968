//! `ecs-commission` refuses to start in one clear line, with a non-zero exit status,
//! when the interface does not exist, has no link, or the raw socket is not allowed.
//! The link and rights cases need root (a veth pair, dropping to an unprivileged user);
//! CI runs as root.

use std::process::Command;

/// Runs the tool (through `prefix`, e.g. `setpriv`) with `args`; exit code, stderr.
fn run(prefix: &[&str], args: &[&str]) -> (Option<i32>, String) {
    let tool = env!("CARGO_BIN_EXE_ecs-commission");
    let mut c = match prefix.split_first() {
        Some((p, rest)) => {
            let mut c = Command::new(p);
            c.args(rest).arg(tool);
            c
        }
        None => Command::new(tool),
    };
    let out = c.args(args).output().expect("run ecs-commission");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn one_line(err: &str, what: &str) {
    assert_eq!(err.lines().count(), 1, "one line: {err}");
    assert!(err.contains(what), "{err}");
}

#[test]
fn missing_interface_link_or_rights_is_one_line_and_a_failure() {
    let (code, err) = run(&[], &["--iface", "ecsnosuch0"]);
    assert_eq!(code, Some(1));
    one_line(&err, "does not exist");

    assert!(
        tests_host::netns::is_root(),
        "the link and rights cases need root (CI runs as root)"
    );
    // A veth end whose peer is down: no carrier.
    let (a, b) = (
        format!("ecl{}a", std::process::id() % 100_000),
        format!("ecl{}b", std::process::id() % 100_000),
    );
    let ip = |args: &[&str]| {
        Command::new("ip")
            .args(args)
            .status()
            .is_ok_and(|s| s.success())
    };
    assert!(
        ip(&["link", "add", &a, "type", "veth", "peer", "name", &b])
            && ip(&["link", "set", &a, "up"])
    );
    let (code, err) = run(&[], &["--iface", &a]);
    let _ = ip(&["link", "del", &a]);
    assert_eq!(code, Some(1));
    one_line(&err, "has no link");

    // An unprivileged user: no raw socket.
    let (code, err) = run(
        &[
            "setpriv",
            "--reuid=65534",
            "--regid=65534",
            "--clear-groups",
        ],
        &["--iface", "lo"],
    );
    assert_eq!(code, Some(1));
    one_line(&err, "no permission to open a raw socket");
}
