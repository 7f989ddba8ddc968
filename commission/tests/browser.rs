//! `ecs-commission` in a real browser: headless Chromium (Debian's `chromium` and
//! `chromium-driver`, installed by `cargo xtask test`) driven over WebDriver (plain
//! HTTP to chromedriver), against `virtual-drive` in a network namespace
//! (`ecs-commission --virtual 2`: two drives on one segment).
//!
//! The page loads and lists the drive; a parameter edit round-trips; an out-of-range
//! edit shows the drive's abort text and changes nothing; enable + jog moves the axis,
//! releasing the button stops it, and losing the page switches the drive off (the
//! dead-man); a scope capture renders; an FoE update completes and the drive reports
//! the new version. A screenshot of each view goes to docs/img/commission-*.png.
//!
//! Needs root (network namespaces, raw sockets) like the other veth tests; CI runs as
//! root. Without root it fails and says so.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{json, Value};

/// A child process ended (SIGTERM, then SIGKILL) when dropped.
use tests_host::netns::Killed as Proc;

/// One HTTP/1.1 request to 127.0.0.1:`port`; the JSON answer (`Null` when none).
fn http(port: u16, method: &str, path: &str, body: Option<&Value>) -> Value {
    let Ok(mut s) = TcpStream::connect(("127.0.0.1", port)) else {
        return Value::Null;
    };
    s.set_read_timeout(Some(Duration::from_secs(120))).ok();
    let body = body.map(Value::to_string).unwrap_or_default();
    let req = format!(
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\
         Content-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    );
    if s.write_all(req.as_bytes()).is_err() {
        return Value::Null;
    }
    let mut r = BufReader::new(s);
    let mut len = None;
    loop {
        let mut line = String::new();
        if r.read_line(&mut line).unwrap_or(0) == 0 {
            return Value::Null;
        }
        let line = line.trim();
        if line.is_empty() {
            break;
        }
        if let Some((k, v)) = line.split_once(':') {
            if k.eq_ignore_ascii_case("content-length") {
                len = v.trim().parse::<usize>().ok();
            }
        }
    }
    let mut out = Vec::new();
    match len {
        Some(n) => {
            out.resize(n, 0);
            if r.read_exact(&mut out).is_err() {
                return Value::Null;
            }
        }
        None => {
            let _ = r.read_to_end(&mut out);
        }
    }
    serde_json::from_slice(&out).unwrap_or(Value::Null)
}

/// A WebDriver session on chromedriver.
struct Browser {
    port: u16,
    session: String,
    _driver: Proc,
}

impl Browser {
    fn start(profile: &Path) -> Browser {
        let port = TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("a free port")
            .port();
        let driver = Proc(
            Command::new("chromedriver")
                .arg(format!("--port={port}"))
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .expect(
                    "chromedriver (Debian package chromium-driver; `cargo xtask test` installs it)",
                ),
        );
        wait_for("chromedriver", Duration::from_secs(20), || {
            TcpStream::connect(("127.0.0.1", port)).is_ok()
                && http(port, "GET", "/status", None)["value"]["ready"] == json!(true)
        });
        let caps = json!({"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:chromeOptions": {
                "binary": "/usr/bin/chromium",
                "args": ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                         "--no-first-run", "--disable-background-networking",
                         "--disable-component-update", "--disable-sync",
                         "--window-size=1400,1000",
                         format!("--user-data-dir={}", profile.display())],
            }
        }}});
        let r = http(port, "POST", "/session", Some(&caps));
        let session = r["value"]["sessionId"]
            .as_str()
            .unwrap_or_else(|| panic!("no WebDriver session: {r}"))
            .to_string();
        Browser {
            port,
            session,
            _driver: driver,
        }
    }

    fn call(&self, method: &str, path: &str, body: Option<Value>) -> Value {
        let r = http(
            self.port,
            method,
            &format!("/session/{}{path}", self.session),
            body.as_ref(),
        );
        assert!(
            r["value"].get("error").is_none(),
            "WebDriver {method} {path}: {r}"
        );
        r["value"].clone()
    }

    fn go(&self, url: &str) {
        self.call("POST", "/url", Some(json!({ "url": url })));
    }

    /// The element of `css`, waited for.
    fn find(&self, css: &str) -> String {
        let mut found = None;
        wait_for(css, Duration::from_secs(20), || {
            let r = http(
                self.port,
                "POST",
                &format!("/session/{}/element", self.session),
                Some(&json!({"using": "css selector", "value": css})),
            );
            found = r["value"]
                .as_object()
                .and_then(|o| o.values().next())
                .and_then(Value::as_str)
                .map(str::to_string);
            found.is_some()
        });
        found.unwrap_or_default()
    }

    fn click(&self, css: &str) {
        let e = self.find(css);
        self.call("POST", &format!("/element/{e}/click"), Some(json!({})));
    }

    fn text(&self, css: &str) -> String {
        let e = self.find(css);
        self.call("GET", &format!("/element/{e}/text"), None)
            .as_str()
            .unwrap_or("")
            .to_string()
    }

    fn type_into(&self, css: &str, text: &str) {
        let e = self.find(css);
        self.call("POST", &format!("/element/{e}/clear"), Some(json!({})));
        self.send_keys(css, text);
    }

    fn send_keys(&self, css: &str, text: &str) {
        let e = self.find(css);
        self.call(
            "POST",
            &format!("/element/{e}/value"),
            Some(json!({ "text": text })),
        );
    }

    fn js(&self, script: &str) -> Value {
        self.call(
            "POST",
            "/execute/sync",
            Some(json!({"script": script, "args": []})),
        )
    }

    /// Waits until `css`'s text contains `what`; the text.
    fn wait_text(&self, css: &str, what: &str, limit: Duration) -> String {
        let t0 = Instant::now();
        loop {
            let t = self.text(css);
            if t.contains(what) {
                return t;
            }
            assert!(
                t0.elapsed() < limit,
                "waited {limit:?} for '{what}' in {css}; it reads: {t}"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    fn view(&self, name: &str) {
        self.click(&format!("nav button[data-view='{name}']"));
    }

    /// Pointer down (`down`) or up on the element of `css` (WebDriver actions).
    fn pointer(&self, css: &str, down: bool) {
        let e = self.find(css);
        let origin = json!({ "element-6066-11e4-a52e-4f735466cecf": e });
        let mut actions =
            vec![json!({"type": "pointerMove", "duration": 0, "origin": origin, "x": 0, "y": 0})];
        actions.push(json!({"type": if down { "pointerDown" } else { "pointerUp" }, "button": 0}));
        self.call(
            "POST",
            "/actions",
            Some(json!({"actions": [{"type": "pointer", "id": "mouse",
                "parameters": {"pointerType": "mouse"}, "actions": actions}]})),
        );
    }

    /// A screenshot of the page into docs/img/commission-`name`.png.
    fn screenshot(&self, name: &str) {
        let b64 = self.call("GET", "/screenshot", None);
        let png = base64(b64.as_str().unwrap_or(""));
        assert!(png.starts_with(b"\x89PNG"), "screenshot {name}");
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/img");
        std::fs::create_dir_all(&dir).expect("docs/img");
        std::fs::write(dir.join(format!("commission-{name}.png")), png).expect("write screenshot");
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = http(
            self.port,
            "DELETE",
            &format!("/session/{}", self.session),
            None,
        );
    }
}

/// Standard base64 (WebDriver's screenshots).
fn base64(s: &str) -> Vec<u8> {
    let val = |c: u8| match c {
        b'A'..=b'Z' => Some(c - b'A'),
        b'a'..=b'z' => Some(c - b'a' + 26),
        b'0'..=b'9' => Some(c - b'0' + 52),
        b'+' => Some(62),
        b'/' => Some(63),
        _ => None,
    };
    let bits: Vec<u8> = s.bytes().filter_map(val).collect();
    bits.chunks(4)
        .flat_map(|c| {
            let n = c.iter().fold(0u32, |a, &v| a << 6 | u32::from(v)) << (6 * (4 - c.len()));
            let b = n.to_be_bytes();
            b[1..c.len()].to_vec()
        })
        .collect()
}

/// Polls `ok` every 50 ms until it holds; fails naming `what` after `limit`.
fn wait_for(what: &str, limit: Duration, mut ok: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !ok() {
        assert!(t0.elapsed() < limit, "waited {limit:?} for {what}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// `virtual-drive` beside the test's binaries (built when missing).
fn virtual_drive() -> PathBuf {
    let tool = PathBuf::from(env!("CARGO_BIN_EXE_ecs-commission"));
    let vd = tool.with_file_name("virtual-drive");
    if !vd.exists() {
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let ok = Command::new(cargo)
            .args(["build", "-p", "tests-host", "--bin", "virtual-drive"])
            .status()
            .is_ok_and(|s| s.success());
        assert!(ok && vd.exists(), "building virtual-drive");
    }
    vd
}

/// The state the tool serves.
fn state(page_port: u16) -> Value {
    http(page_port, "GET", "/api/state", None)
}

fn drive0(page_port: u16) -> Value {
    state(page_port)["drives"][0].clone()
}

fn position(page_port: u16) -> i64 {
    drive0(page_port)["actual_position"].as_i64().unwrap_or(0)
}

/// Waits until the position stops changing (two reads 300 ms apart within 5 inc: a
/// closed loop at rest may dither by a count).
fn at_rest(page_port: u16) -> i64 {
    let mut last = position(page_port);
    wait_for("the axis at rest", Duration::from_secs(10), || {
        std::thread::sleep(Duration::from_millis(300));
        let p = position(page_port);
        let rest = (p - last).abs() <= 5;
        last = p;
        rest
    });
    last
}

/// A temporary directory of the test `tag`, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!("ecs-commission-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("temporary directory");
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// `ecs-commission --virtual N extra…` on a free port: the process, the page's URL
/// and port.
fn start_tool(drives: &str, extra: &[&str]) -> (Proc, String, u16) {
    assert!(
        tests_host::netns::is_root(),
        "this test needs root (network namespace and raw socket for virtual-drive): \
         `sudo -E env PATH=$PATH cargo test -p commission --test browser` (CI runs as root)"
    );
    let mut tool = Command::new(env!("CARGO_BIN_EXE_ecs-commission"))
        .args(["--virtual", drives, "--listen", "127.0.0.1:0"])
        .args(extra)
        .arg("--virtual-drive")
        .arg(virtual_drive())
        .stdout(Stdio::piped())
        .spawn()
        .expect("ecs-commission");
    let out = tool.stdout.take().expect("stdout");
    let tool = Proc(tool);
    let mut line = String::new();
    BufReader::new(out)
        .read_line(&mut line)
        .expect("its first line");
    let url = line
        .split("page on ")
        .nth(1)
        .map(str::trim)
        .unwrap_or_else(|| panic!("ecs-commission said: {line}"))
        .to_string();
    let port: u16 = url
        .trim_end_matches('/')
        .rsplit(':')
        .next()
        .and_then(|p| p.parse().ok())
        .expect("port");
    (tool, url, port)
}

#[test]
fn an_emergency_arrives_with_its_text_and_led_code() {
    let _one = tests_host::netns::one_at_a_time();
    // The plant's bus voltage rises 2 s after the start: the drive trips on
    // over-voltage and sends its emergency.
    let (tool, url, page_port) = start_tool("1", &["--fault", "bus-overvoltage@2s"]);
    let dir = TempDir::new("emcy");
    let b = Browser::start(&dir.0.join("profile"));
    b.go(&url);
    b.wait_text(
        "#segment tbody",
        "Bus over-voltage",
        Duration::from_secs(30),
    );
    b.wait_text(
        "#segment tbody",
        "red LED: 2 flashes",
        Duration::from_secs(5),
    );
    b.view("faults");
    b.wait_text(
        "#emcy-list tbody",
        "Bus over-voltage",
        Duration::from_secs(30),
    );
    b.click("#faults-read");
    b.wait_text(
        "#faults-history tbody",
        "Bus over-voltage",
        Duration::from_secs(20),
    );
    b.screenshot("emergency");
    let s = state(page_port);
    assert!(
        s["emergencies"][0]["code"] == json!("0x3210"),
        "{}",
        s["emergencies"]
    );
    drop(b);
    drop(tool);
}

#[test]
fn commissioning_in_a_browser_against_virtual_drive() {
    let _one = tests_host::netns::one_at_a_time();
    // The tool with two virtual drives, on a free port.
    let (tool, url, page_port) = start_tool("2", &[]);
    let tmp = TempDir::new("browser");
    let dir = tmp.0.clone();

    let b = Browser::start(&dir.join("profile"));

    // Segment: the drive, in Op.
    b.go(&url);
    b.wait_text("#segment tbody", "ECS-HS", Duration::from_secs(30));
    b.wait_text("#segment tbody", "Op", Duration::from_secs(30));
    b.wait_text("#segment tbody", "no error", Duration::from_secs(10));
    // Two drives on the segment, both in Op.
    let mut last = Value::Null;
    let t0 = Instant::now();
    while !last["drives"].as_array().is_some_and(|d| {
        d.len() == 2
            && d.iter()
                .all(|d| d["esm"] == json!("Op") && d["al_code"] == json!(0))
    }) {
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "two drives in Op: {last}"
        );
        std::thread::sleep(Duration::from_millis(50));
        last = state(page_port);
        last["live"] = Value::Null;
    }
    let rows = b.js("return document.querySelectorAll('#segment tbody tr').length");
    assert_eq!(rows, json!(2), "both drives listed");
    b.screenshot("segment");

    // Dictionary: the list from SDO information, an edit that round-trips, an
    // out-of-range edit refused by the drive with its abort text, nothing changed.
    b.view("dict");
    b.click("#dict-load");
    b.wait_text("#dict-msg", "objects", Duration::from_secs(30));
    let n = b.js("return document.querySelectorAll('#dict-objects li').length");
    assert!(n.as_u64().unwrap_or(0) > 50, "objects listed: {n}");
    b.type_into("#dict-index", "0x2000");
    b.click("#dict-open");
    b.wait_text("#dict-title", "0x2000", Duration::from_secs(10));
    b.type_into("input.edit[data-index='8192'][data-sub='0']", "2500");
    b.click("button.write[data-sub='0']");
    b.wait_text("#dict-msg", "= 2500 (read back)", Duration::from_secs(10));
    let read = |p: u16| {
        http(p, "GET", "/api/objects?drive=0&index=0x2000", None)["ok"]["entries"][0]["value"]
            .clone()
    };
    assert_eq!(read(page_port), json!("2500"), "0x2000 after the edit");
    b.type_into("input.edit[data-index='8192'][data-sub='0']", "9000");
    b.click("button.write[data-sub='0']");
    let msg = b.wait_text("#dict-msg", "refused", Duration::from_secs(10));
    assert!(
        msg.contains("0x06090031") && msg.contains("too high"),
        "{msg}"
    );
    assert_eq!(
        read(page_port),
        json!("2500"),
        "0x2000 unchanged by the refused edit"
    );
    b.screenshot("dictionary");
    // Bad requests get an answer in words and change nothing.
    let bad = [
        json!({"drive": 7, "index": 0x2000, "sub": 0, "value": "1"}),
        json!({"drive": 0, "index": 0x2000, "sub": 0, "value": "abc"}),
        json!({"drive": 0, "index": 0x2000, "sub": 0, "value": "70000"}),
        json!({"drive": 0, "index": 0x5FFF, "sub": 0, "value": "1"}),
    ];
    for req in bad {
        let r = http(page_port, "POST", "/api/write", Some(&req));
        assert!(
            r["error"].as_str().is_some_and(|e| !e.is_empty()),
            "{req}: {r}"
        );
    }
    assert_eq!(
        read(page_port),
        json!("2500"),
        "0x2000 unchanged by bad requests"
    );

    // Enable and jog, the dead-man.
    b.view("jog");
    b.click("#enable");
    b.wait_text("#jog-state", "OperationEnabled", Duration::from_secs(10));
    let p0 = at_rest(page_port);
    b.pointer("#jog-plus", true);
    wait_for("the axis moving forward", Duration::from_secs(10), || {
        position(page_port) > p0 + 2000
    });
    b.screenshot("jog");
    b.pointer("#jog-plus", false);
    let p1 = at_rest(page_port);
    assert!(p1 > p0 + 2000, "moved {p0} → {p1}");
    assert_eq!(
        drive0(page_port)["cia402"],
        json!("OperationEnabled"),
        "released: at rest, still enabled"
    );
    // Losing the page while jogging: the hold runs out, the drive switches off.
    b.pointer("#jog-plus", true);
    wait_for("the axis moving again", Duration::from_secs(10), || {
        position(page_port) > p1 + 1000
    });
    b.go("about:blank");
    wait_for("the dead-man", Duration::from_secs(10), || {
        let s = state(page_port);
        s["hold"] == json!([false, 0]) && s["drives"][0]["cia402"] != json!("OperationEnabled")
    });
    let p2 = at_rest(page_port);
    assert!(p2 > p1, "{p1} → {p2}");
    b.call("DELETE", "/actions", None);
    b.go(&url);
    b.wait_text("#segment tbody", "ECS-HS", Duration::from_secs(30));

    // Live plot.
    b.view("plots");
    b.find("#live-plot canvas");
    b.screenshot("plots");

    // Scope: triggered by the position rising through a level while the axis jogs
    // (the hold renewed here, as the page does).
    b.view("scope");
    let level = at_rest(page_port) + 1500;
    b.type_into("#scope-channels", "0x6064, 0x6041");
    b.js("document.querySelector('#scope-cond').value = 'rising'; return 0");
    b.type_into("#scope-level", &level.to_string());
    b.type_into("#scope-pre", "100");
    b.type_into("#scope-div", "2");
    let jogging = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
    let jog = {
        let jogging = jogging.clone();
        std::thread::spawn(move || {
            let hold = json!({"drive": 0, "enable": true, "dir": 1, "speed": 4000});
            for _ in 0..300 {
                if !jogging.load(std::sync::atomic::Ordering::Relaxed) {
                    break;
                }
                http(page_port, "POST", "/api/hold", Some(&hold));
                std::thread::sleep(Duration::from_millis(100));
            }
        })
    };
    b.click("#scope-run");
    let msg = b.wait_text("#scope-msg", "samples", Duration::from_secs(30));
    jogging.store(false, std::sync::atomic::Ordering::Relaxed);
    let _ = jog.join();
    assert!(!msg.contains("forced"), "the trigger fired: {msg}");
    b.find("#scope-plot canvas");
    b.screenshot("scope");
    at_rest(page_port);

    // Servo tune: enabled at rest, the tuning view switches to profile position and
    // starts it; the results show "done" (0x2162:02 = 2) and the identified ratio.
    b.view("jog");
    b.click("#enable");
    b.wait_text("#jog-state", "OperationEnabled", Duration::from_secs(10));
    b.view("tune");
    b.click("#tune-servo");
    b.wait_text("#tune-msg", "tune started", Duration::from_secs(10));
    wait_for("the servo tune done", Duration::from_secs(30), || {
        b.click("#tune-results");
        std::thread::sleep(Duration::from_millis(200));
        b.text("#tune-out")
            .contains("servo tune state 0x2162:02: 2")
    });
    b.screenshot("tuning");
    b.view("jog");
    b.click("#enable");
    wait_for("the drive off", Duration::from_secs(10), || {
        drive0(page_port)["cia402"] != json!("OperationEnabled")
    });

    // Restoring the defaults (0x1011) is a message of the history; the faults view
    // shows it with its text.
    b.view("dict");
    b.click("#dict-restore");
    b.wait_text("#dict-msg", "defaults stored", Duration::from_secs(10));
    b.view("faults");
    b.click("#faults-read");
    b.wait_text(
        "#faults-history tbody",
        "Parameters restored to defaults",
        Duration::from_secs(20),
    );
    b.screenshot("faults");

    // Firmware update over FoE: version 2.3.0, signed with the development key.
    let image: Vec<u8> = (0..20_000usize)
        .map(|i| (i as u8).wrapping_mul(13) ^ 0x3C)
        .collect();
    let file = efw::sign::update_file(
        &efw::sign::dev_key(),
        firmware::identity::VENDOR_ID,
        firmware::identity::Variant::HybridServo.product_code(),
        efw::Esc::Lan9252,
        0x0002_0300,
        &image,
    );
    let efw_path = dir.join("update-2.3.0.efw");
    std::fs::write(&efw_path, &file).expect("update file");
    b.view("update");
    b.send_keys("#update-file", &efw_path.display().to_string());
    b.click("#update-run");
    let answer = b.wait_text("#update-answer", "version 2.3.0", Duration::from_secs(90));
    assert!(answer.contains("update done"), "{answer}");
    assert_eq!(drive0(page_port)["version"], json!("2.3.0"));
    assert_eq!(
        state(page_port)["drives"][1]["version"],
        json!(env!("CARGO_PKG_VERSION")),
        "the other drive keeps its firmware"
    );
    b.screenshot("update");

    drop(b);
    drop(tool);
}
