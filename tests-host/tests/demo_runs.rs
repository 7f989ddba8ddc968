//! The README's main command (`cargo xtask demo` runs the `demo` binary): the
//! commissioning demo must run to the end with every step as expected — the binary
//! checks its own results (power-up self-test over, each CiA 402 state reached, homing
//! attained, PP target reached, CSP tracking, the following-error fault and its reset)
//! and exits non-zero otherwise.
use std::process::Command;

#[test]
fn commissioning_demo_runs_to_the_end_as_expected() {
    let out_dir = std::env::temp_dir().join(format!("ecs-demo-test-{}", std::process::id()));
    let out = Command::new(env!("CARGO_BIN_EXE_demo"))
        .arg("--out")
        .arg(&out_dir)
        .output()
        .expect("demo binary runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "demo failed:\n{stdout}\n{stderr}");
    for text in [
        "power-up self-test",
        "Operation enabled",
        "homing attained",
        "0x8611",
        "Back to Init.",
    ] {
        assert!(stdout.contains(text), "missing {text:?} in:\n{stdout}");
    }
    for plot in [
        "current_step.png",
        "csp_tracking_error.png",
        "homing_trace.png",
    ] {
        let meta = std::fs::metadata(out_dir.join(plot)).expect("plot written");
        assert!(meta.len() > 1000, "{plot} is empty");
    }
    let _ = std::fs::remove_dir_all(&out_dir);
}
