//! Running commands: cargo with this toolchain, echoed, with status or output.

use std::env;
use std::io::{BufRead, BufReader, Read};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::thread;

/// `cargo` (the one running xtask) with `args`.
pub fn cargo(args: &[&str]) -> Command {
    let mut c = Command::new(env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    c.args(args);
    c
}

/// Runs `cmd` after echoing it; whether it succeeded.
pub fn run_status(cmd: &mut Command) -> bool {
    eprintln!("$ {}", show(cmd));
    cmd.status().map(|s| s.success()).unwrap_or(false)
}

/// `cmd` as a shell line, for the echo.
fn show(cmd: &Command) -> String {
    let mut s = cmd.get_program().to_string_lossy().into_owned();
    for a in cmd.get_args() {
        s.push(' ');
        s.push_str(&a.to_string_lossy());
    }
    s
}

/// Runs a command, echoing its output live, and returns (success, stdout+stderr text).
pub fn run_capture(cmd: &mut Command) -> (bool, String) {
    eprintln!("$ {}", show(cmd));
    cmd.stdout(Stdio::piped()).stderr(Stdio::piped());
    let mut child = match cmd.spawn() {
        Ok(c) => c,
        Err(e) => return (false, format!("cannot start: {e}")),
    };
    let (tx, rx) = mpsc::channel::<String>();
    let mut handles = Vec::new();
    let out: Box<dyn Read + Send> = Box::new(child.stdout.take().expect("stdout"));
    let err: Box<dyn Read + Send> = Box::new(child.stderr.take().expect("stderr"));
    for (stream, is_err) in [(out, false), (err, true)] {
        let tx = tx.clone();
        handles.push(thread::spawn(move || {
            for line in BufReader::new(stream).lines().map_while(Result::ok) {
                if is_err {
                    eprintln!("{line}");
                } else {
                    println!("{line}");
                }
                let _ = tx.send(line);
            }
        }));
    }
    drop(tx);
    let status = child.wait();
    for h in handles {
        let _ = h.join();
    }
    let text: Vec<String> = rx.into_iter().collect();
    (
        status.map(|s| s.success()).unwrap_or(false),
        text.join("\n"),
    )
}
