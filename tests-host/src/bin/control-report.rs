//! Control-quality report: runs the scenarios of `tests_host::plant::scenarios`
//! (the same code the `control_quality` tests assert) and prints a Markdown table
//! `| figure | goal | achieved | met |`.
//!
//! `--plots DIR` also writes `current_step.png` and `csp_tracking_error.png` into DIR.
//! Text in the plots uses DejaVu Sans from /usr/share/fonts if it is installed;
//! without it the plots are drawn without text.
#![deny(clippy::undocumented_unsafe_blocks)]

use plotters::prelude::*;
use std::path::PathBuf;
use tests_host::plant::motor::ECN57_20;
use tests_host::plant::scenarios;
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

    println!("| figure | goal | achieved | met |");
    println!("|---|---|---|---|");
    for f in scenarios::report() {
        println!(
            "| {} | {} | {} | {} |",
            f.name,
            f.goal,
            f.achieved,
            if f.met { "yes" } else { "no" }
        );
    }

    if let Some(dir) = plots {
        if let Err(e) = std::fs::create_dir_all(&dir) {
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
        for (p, r) in [(p1, r1), (p2, r2)] {
            match r {
                Ok(()) => eprintln!("wrote {}", p.display()),
                Err(e) => {
                    eprintln!("plot {} failed: {e}", p.display());
                    std::process::exit(1);
                }
            }
        }
    }
}
