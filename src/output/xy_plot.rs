//! A log–log PNG plot of (x, y) series, e.g. error against time for several estimators.

use super::OutputError;
use super::font::{FAMILY, ensure_font};
use super::plot::COLORS;
use super::png::write_png;
use plotters::prelude::*;
use std::path::Path;

const W: usize = 900;
const H: usize = 600;

/// Writes a log–log line plot (points with both coordinates > 0 and finite), atomically.
pub fn write_loglog_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[(String, Vec<(f64, f64)>)],
) -> Result<(), OutputError> {
    let pts: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|(_, v)| v.iter().copied())
        .filter(|(x, y)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
        .collect();
    if pts.is_empty() {
        return Err(OutputError::empty(path, "no positive finite points to plot"));
    }
    ensure_font().map_err(|detail| OutputError::Font {
        path: path.to_path_buf(),
        detail,
    })?;
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in &pts {
        x0 = x0.min(*x);
        x1 = x1.max(*x);
        y0 = y0.min(*y);
        y1 = y1.max(*y);
    }
    let (x0, x1, y0, y1) = (x0 / 1.5, x1 * 1.5, y0 / 1.5, y1 * 1.5);
    let mut pixels = vec![255u8; W * H * 3];
    {
        let mut draw = || -> Result<(), Box<dyn std::error::Error>> {
            let root = BitMapBackend::with_buffer(&mut pixels, (W as u32, H as u32)).into_drawing_area();
            root.fill(&WHITE)?;
            let mut chart = ChartBuilder::on(&root)
                .caption(title, (FAMILY, 22))
                .margin(12)
                .x_label_area_size(48)
                .y_label_area_size(80)
                .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
            chart
                .configure_mesh()
                .x_desc(x_label)
                .y_desc(y_label)
                .x_label_formatter(&|v| short(*v))
                .y_label_formatter(&|v| short(*v))
                .label_style((FAMILY, 14))
                .axis_desc_style((FAMILY, 16))
                .draw()?;
            for (i, (name, v)) in series.iter().enumerate() {
                let c = COLORS[i % COLORS.len()];
                let p: Vec<(f64, f64)> = v.iter().copied().filter(|(x, y)| *x > 0.0 && *y > 0.0).collect();
                chart
                    .draw_series(LineSeries::new(p.clone(), c.stroke_width(2)))?
                    .label(name.as_str())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
                chart.draw_series(p.into_iter().map(|q| Circle::new(q, 4, c.filled())))?;
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .background_style(WHITE.mix(0.9))
                .border_style(BLACK)
                .label_font((FAMILY, 14))
                .draw()?;
            root.present()?;
            Ok(())
        };
        draw().map_err(|e| OutputError::encode(path, "PNG plot", e))?;
    }
    write_png(path, &pixels, W, H, 3)
}

/// A compact tick label: up to 3 significant digits, no float noise.
fn short(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let digits = (2 - v.abs().log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}
