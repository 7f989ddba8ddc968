//! Control-quality report: runs the scenarios of `tests_host::plant::scenarios`
//! (the same code the `control_quality` tests assert) and prints a Markdown table
//! `| figure | goal | achieved | met |`.
//!
//! `--plots DIR` also writes `current_step.png` and `csp_tracking_error.png` into DIR.
//! Text in the plots uses DejaVu Sans from /usr/share/fonts if it is installed;
//! without it the plots are drawn without text.

use plotters::prelude::*;
use std::path::{Path, PathBuf};
use tests_host::plant::motor::ECN57_20;
use tests_host::plant::scenarios;

const FONT: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

fn load_font() -> bool {
    match std::fs::read(FONT) {
        Ok(bytes) => {
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok()
        }
        Err(_) => false,
    }
}

type Series<'a> = (&'a str, &'a [(f64, f64)], RGBColor);

fn plot(
    path: &Path,
    title: &str,
    xdesc: &str,
    ydesc: &str,
    series: &[Series],
    text: bool,
) -> Result<(), Box<dyn std::error::Error>> {
    let root = BitMapBackend::new(path, (1000, 560)).into_drawing_area();
    root.fill(&WHITE)?;
    let pts = series.iter().flat_map(|s| s.1.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in pts {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x0 >= x1 {
        x1 = x0 + 1.0;
    }
    let pad = ((y1 - y0) * 0.08).max(1e-3);
    let mut b = ChartBuilder::on(&root);
    b.margin(15);
    if text {
        b.caption(title, ("sans-serif", 22))
            .x_label_area_size(45)
            .y_label_area_size(60);
    } else {
        b.x_label_area_size(10).y_label_area_size(10);
    }
    let mut chart = b.build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))?;
    let mut mesh = chart.configure_mesh();
    if text {
        mesh.x_desc(xdesc).y_desc(ydesc);
    } else {
        mesh.x_labels(0).y_labels(0);
    }
    mesh.draw()?;
    for &(name, data, color) in series {
        let s = chart.draw_series(LineSeries::new(data.iter().copied(), color.stroke_width(2)))?;
        if text {
            s.label(name).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        }
    }
    if text {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    root.present()?;
    Ok(())
}

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
