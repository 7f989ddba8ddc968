//! Control-quality report: runs the scenarios of `tests_host::plant::scenarios`
//! (the same code the `control_quality` tests assert) and prints a Markdown table
//! `| figure | goal | achieved | met |`.
//!
//! Then the "Robustness" table (`tests_host::plant::robustness`): the current loop on
//! the plant with a real motor's and board's non-idealities; then the "Cyclic
//! synchronous torque (CST)" table (`tests_host::plant::torque`): torque step and
//! torque ripple through the firmware's CiA 402 profile and motion layer; the "Open-loop
//! resonance" table (`tests_host::plant::resonance`) and the "Stall detection (open
//! loop)" table (`tests_host::plant::stall`).
//!
//! `--plots DIR` also writes `current_step.png`, `csp_tracking_error.png` and
//! `iq_ripple_vs_speed.png` and `open_loop_resonance.png` (the tuning guide's plots, docs/guide/tuning.md) into DIR.
//! Text in the plots uses DejaVu Sans from /usr/share/fonts if it is installed;
//! without it the plots are drawn without text.
#![deny(clippy::undocumented_unsafe_blocks)]

use plotters::prelude::*;
use std::path::PathBuf;
use tests_host::plant::motor::{ECN57_20, TC86_45};
use tests_host::plant::resonance;
use tests_host::plant::robustness::{self, Calibration, Conditions, Design};
use tests_host::plant::scenarios::{self, Figure};
use tests_host::plant::stall;
use tests_host::plant::torque;
use tests_host::plot::{load_font, plot};

fn main() {
    let mut args = std::env::args().skip(1);
    let mut plots: Option<PathBuf> = None;
    while let Some(a) = args.next() {
        match a.as_str() {
            "--plots" => match args.next() {
                Some(d) => plots = Some(PathBuf::from(d)),
                None => {
                    eprintln!("--plots needs a directory");
                    std::process::exit(2);
                }
            },
            "-h" | "--help" => {
                println!("usage: control-report [--plots DIR]");
                return;
            }
            other => {
                eprintln!("unknown argument {other}");
                std::process::exit(2);
            }
        }
    }

    print_table(&scenarios::report());
    println!();
    println!("### Robustness (current loop on a non-ideal plant)");
    println!();
    print_table(&robustness::report());
    println!();
    println!("### Open-loop resonance (sweep 0.5-20 rev/s, 5 % load, rated current)");
    println!();
    let sweeps = resonance::sweeps();
    print_table(&resonance::report_of(&sweeps));
    println!();
    println!("### Cyclic synchronous torque (CST)");
    println!();
    print_table(&torque::report());
    println!();
    println!("### Stall detection (open loop)");
    println!();
    print_table(&stall::report());
    println!();
    println!("### Servo auto-tuning (closed loop)");
    println!();
    print_table(&tests_host::plant::servo_tune::report());

    if let Some(dir) = plots {
        write_plots(&dir, &sweeps);
    }
}

/// The report's PNG plots into `dir`; exits the process when one fails.
fn write_plots(dir: &std::path::Path, sweeps: &[resonance::MotorSweep]) {
    if let Err(e) = std::fs::create_dir_all(dir) {
        eprintln!("cannot create {}: {e}", dir.display());
        std::process::exit(1);
    }
    let text = load_font();
    let step = scenarios::current_step(ECN57_20, 8);
    let p1 = dir.join("current_step.png");
    let r1 = plot(
        &p1,
        "ECN57-20, 0.5 A q-current step, 40 kHz (mean of 8 seeds)",
        "time after the reference step (µs)",
        "i_q (A)",
        &[
            ("reference", &step.reference, RED),
            ("i_q (plant)", &step.trace, BLUE),
        ],
        text,
    );
    let csp = scenarios::csp_tracking();
    let p2 = dir.join("csp_tracking_error.png");
    let r2 = plot(
        &p2,
        "TC86-45, 600 rpm CSP (1 ms set-points): following error",
        "time (ms)",
        "following error (counts)",
        &[("following error", &csp.trace, BLUE)],
        text,
    );
    let p3 = dir.join("iq_ripple_vs_speed.png");
    let r3 = ripple_plot(&p3, text);
    let p4 = dir.join("open_loop_resonance.png");
    let r4 = resonance_plot(&p4, sweeps, text);
    for (p, r) in [(p1, r1), (p2, r2), (p3, r3), (p4, r4)] {
        match r {
            Ok(()) => eprintln!("wrote {}", p.display()),
            Err(e) => {
                eprintln!("plot {} failed: {e}", p.display());
                std::process::exit(1);
            }
        }
    }
}

fn print_table(rows: &[Figure]) {
    println!("| figure | goal | achieved | met |");
    println!("|---|---|---|---|");
    for f in rows {
        println!(
            "| {} | {} | {} | {} |",
            f.name,
            f.goal,
            f.achieved,
            if f.met { "yes" } else { "no" }
        );
    }
}

/// Open-loop speed ripple against speed, both motors, damping off and on.
fn resonance_plot(
    path: &std::path::Path,
    sweeps: &[resonance::MotorSweep],
    text: bool,
) -> Result<(), Box<dyn std::error::Error>> {
    // Relative ripple in %, capped at 150 % (a lost rotor's ripple is its speed).
    let pts = |v: &[resonance::SweepPoint]| -> Vec<(f64, f64)> {
        v.iter()
            .map(|p| (p.speed, (100.0 * p.ripple_rel()).min(150.0)))
            .collect()
    };
    let (e, t) = (&sweeps[0], &sweeps[1]);
    let (e_off, e_on, t_off, t_on) = (pts(&e.off), pts(&e.on), pts(&t.off), pts(&t.on));
    plot(
        path,
        "Open loop at rated current, 5 % load, 48 V: speed ripple p-p / speed",
        "commanded speed (rev/s)",
        "speed ripple p-p (% of speed, capped at 150)",
        &[
            ("ECN57-20 undamped", &e_off, RGBColor(255, 150, 150)),
            ("TC86-45 undamped", &t_off, RGBColor(150, 150, 255)),
            ("ECN57-20 damped (0x2059 = 1 ms)", &e_on, RED),
            ("TC86-45 damped", &t_on, BLUE),
        ],
        text,
    )
}

/// i_q ripple against speed on the encoder, both motors, before (the baseline loop)
/// and after (the robust loop).
fn ripple_plot(path: &std::path::Path, text: bool) -> Result<(), Box<dyn std::error::Error>> {
    let c = Conditions::IDEAL;
    let after = Design::Robust(Calibration::Off);
    let ecn_before = robustness::ripple_sweep(ECN57_20, &c, Design::Baseline);
    let ecn_after = robustness::ripple_sweep(ECN57_20, &c, after);
    let tc_before = robustness::ripple_sweep(TC86_45, &c, Design::Baseline);
    let tc_after = robustness::ripple_sweep(TC86_45, &c, after);
    let goal: Vec<(f64, f64)> = vec![(0.0, 10.0), (10.013, 10.0)];
    plot(
        path,
        "i_q ripple p-p on the encoder (4000 counts/rev), i_q* = 0.5 A, 40 kHz",
        "speed (rev/s), 0.013 + n·0.25",
        "i_q ripple p-p (mA)",
        &[
            ("ECN57-20 before", &ecn_before, RGBColor(255, 150, 150)),
            ("TC86-45 before", &tc_before, RGBColor(150, 150, 255)),
            ("ECN57-20 after", &ecn_after, RED),
            ("TC86-45 after", &tc_after, BLUE),
            ("goal 10 mA", &goal, BLACK),
        ],
        text,
    )
}
