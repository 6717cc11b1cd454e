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
    write_xy_plot(path, title, x_label, y_label, series, true)
}

/// Writes a line plot with linear axes (finite points), atomically: e.g. parameter values
/// over the iterations of an optimisation.
pub fn write_line_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[(String, Vec<(f64, f64)>)],
) -> Result<(), OutputError> {
    write_xy_plot(path, title, x_label, y_label, series, false)
}

/// Both plots: a log–log plot draws (log10 x, log10 y) on linear axes labelled with 10^v.
fn write_xy_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[(String, Vec<(f64, f64)>)],
    log: bool,
) -> Result<(), OutputError> {
    let map = |(x, y): (f64, f64)| -> Option<(f64, f64)> {
        let q = if log {
            (x > 0.0 && y > 0.0).then(|| (x.log10(), y.log10()))?
        } else {
            (x, y)
        };
        (q.0.is_finite() && q.1.is_finite()).then_some(q)
    };
    let series: Vec<(&str, Vec<(f64, f64)>)> = series
        .iter()
        .map(|(n, v)| (n.as_str(), v.iter().copied().filter_map(map).collect()))
        .collect();
    let pts: Vec<(f64, f64)> = series.iter().flat_map(|(_, v)| v.iter().copied()).collect();
    if pts.is_empty() {
        return Err(OutputError::empty(
            path,
            if log {
                "no positive finite points to plot"
            } else {
                "no finite points to plot"
            },
        ));
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
    // a margin of 1.5× on log axes, 5% of the span (or ±1 for a flat series) on linear ones
    let pad = |lo: f64, hi: f64| {
        if log {
            (lo - 0.176, hi + 0.176)
        } else {
            let m = if hi > lo {
                0.05 * (hi - lo)
            } else {
                lo.abs().max(1.0) * 0.05
            };
            (lo - m, hi + m)
        }
    };
    let ((x0, x1), (y0, y1)) = (pad(x0, x1), pad(y0, y1));
    let label = |v: f64| if log { short(10f64.powf(v)) } else { short(v) };
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
                .build_cartesian_2d(x0..x1, y0..y1)?;
            chart
                .configure_mesh()
                .x_desc(x_label)
                .y_desc(y_label)
                .x_label_formatter(&|v| label(*v))
                .y_label_formatter(&|v| label(*v))
                .label_style((FAMILY, 14))
                .axis_desc_style((FAMILY, 16))
                .draw()?;
            for (i, (name, p)) in series.iter().enumerate() {
                let c = COLORS[i % COLORS.len()];
                chart
                    .draw_series(LineSeries::new(p.clone(), c.stroke_width(2)))?
                    .label(*name)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
                chart.draw_series(p.iter().map(|&q| Circle::new(q, 3, c.filled())))?;
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
