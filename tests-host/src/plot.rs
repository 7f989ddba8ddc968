//! PNG line plots (plotters, bitmap backend) shared by `control-report` and the demo.
//! Text uses DejaVu Sans from /usr/share/fonts when installed ([`load_font`]);
//! without it the plots are drawn without text.

use plotters::prelude::*;
use std::path::Path;

/// Font file registered as "sans-serif".
const FONT: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

/// Registers DejaVu Sans; false when it is not installed.
pub fn load_font() -> bool {
    match std::fs::read(FONT) {
        Ok(bytes) => {
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok()
        }
        Err(_) => false,
    }
}

/// One line: legend, points, colour.
pub type Series<'a> = (&'a str, &'a [(f64, f64)], RGBColor);

/// Draws `series` into a 1000×560 PNG at `path`; `text` = labels and legend.
pub fn plot(
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
