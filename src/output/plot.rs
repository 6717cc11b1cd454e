//! A PNG line plot of radiance over time, one line per series, drawn with plotters into a
//! memory buffer and encoded by [`super::png`]. Needs a system font (see [`super::font`]).

use super::font::{FAMILY, ensure_font};
use super::png::write_png;
use super::{OutputError, SPEED_OF_LIGHT_M_PER_S, check_finite};
use plotters::prelude::*;
use std::path::Path;

const PLOT_WIDTH: usize = 1000;
const PLOT_HEIGHT: usize = 600;

/// Series whose peak is this many times below the largest peak are scaled up by a power of
/// ten (shown in the legend) so their shape is visible.
const RESCALE_RATIO: f64 = 10.0;

/// Line colours (Tableau 10).
pub(crate) const COLORS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Writes a 1000×600 PNG plot of radiance over time, atomically.
///
/// `axis` is `(start_opl, bin_width_opl, bins)` in metres of optical path length; each series
/// is `(legend label, one value per bin)` and is drawn through the bin centres. The bottom
/// axis is optical path length (m), the top axis the same as time (ns, OPL / c). A series
/// whose peak is at least 10× below the largest peak is multiplied by a power of ten, and its
/// legend entry says so (e.g. `pixel (3, 4) ×1000`).
///
/// Needs a TrueType font: see `OutputError::Font` for what to install (Debian:
/// `fonts-dejavu-core`), or set `DIFFTRANSIENT_FONT`.
pub fn write_time_plot(path: &Path, axis: (f32, f32, usize), series: &[(String, Vec<f64>)]) -> Result<(), OutputError> {
    let (start, width, bins) = axis;
    if bins == 0 {
        return Err(OutputError::empty(path, "the time axis has 0 bins"));
    }
    if !start.is_finite() || !width.is_finite() || width <= 0.0 {
        return Err(OutputError::invalid(
            path,
            format!("time axis start_opl={start}, bin_width_opl={width} must be finite with a positive bin width"),
        ));
    }
    if series.is_empty() {
        return Err(OutputError::empty(path, "no series to plot"));
    }
    for (name, values) in series {
        if values.len() != bins {
            return Err(OutputError::invalid(
                path,
                format!("series {name:?} has {} values for {bins} time bins", values.len()),
            ));
        }
    }
    check_finite(path, series.iter().flat_map(|(_, v)| v.iter().copied()))?;
    ensure_font().map_err(|detail| OutputError::Font {
        path: path.to_path_buf(),
        detail,
    })?;

    let mut pixels = vec![255u8; PLOT_WIDTH * PLOT_HEIGHT * 3];
    draw(&mut pixels, (start as f64, width as f64, bins), series)
        .map_err(|e| OutputError::encode(path, "PNG plot", e))?;
    write_png(path, &pixels, PLOT_WIDTH, PLOT_HEIGHT, 3)
}

type DrawResult = Result<(), Box<dyn std::error::Error>>;

fn draw(pixels: &mut [u8], (start, width, bins): (f64, f64, usize), series: &[(String, Vec<f64>)]) -> DrawResult {
    let factors = rescale_factors(series);
    let scaled: Vec<Vec<f64>> = series
        .iter()
        .zip(&factors)
        .map(|((_, v), &f)| v.iter().map(|&x| x * f).collect())
        .collect();
    let lo = scaled.iter().flatten().copied().fold(0.0f64, f64::min);
    let hi = scaled.iter().flatten().copied().fold(0.0f64, f64::max);
    let (y0, y1) = if hi > lo {
        (lo - 0.02 * (hi - lo) * (lo < 0.0) as u8 as f64, hi + 0.12 * (hi - lo))
    } else {
        (0.0, 1.0)
    };
    let (x0, x1) = (start, start + width * bins as f64);
    let ns = |opl: f64| opl / SPEED_OF_LIGHT_M_PER_S * 1e9;

    let root = BitMapBackend::with_buffer(pixels, (PLOT_WIDTH as u32, PLOT_HEIGHT as u32)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption("radiance over time", (FAMILY, 24))
        .margin(12)
        .x_label_area_size(48)
        .top_x_label_area_size(48)
        .y_label_area_size(84)
        .right_y_label_area_size(12)
        .build_cartesian_2d(x0..x1, y0..y1)?
        .set_secondary_coord(ns(x0)..ns(x1), y0..y1);
    chart
        .configure_mesh()
        .x_desc("optical path length (m)")
        .y_desc("radiance")
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| tick(*v))
        .label_style((FAMILY, 15))
        .axis_desc_style((FAMILY, 17))
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(210, 210, 210))
        .draw()?;
    chart
        .configure_secondary_axes()
        .x_desc("time (ns)")
        .x_label_formatter(&|v| tick(*v))
        .y_labels(0)
        .label_style((FAMILY, 15))
        .axis_desc_style((FAMILY, 17))
        .draw()?;

    for (i, (((name, _), values), &factor)) in series.iter().zip(&scaled).zip(&factors).enumerate() {
        let color = COLORS[i % COLORS.len()];
        let style = color.stroke_width(2);
        let points: Vec<(f64, f64)> = if bins == 1 {
            vec![(x0, values[0]), (x1, values[0])]
        } else {
            values
                .iter()
                .enumerate()
                .map(|(t, &v)| (start + (t as f64 + 0.5) * width, v))
                .collect()
        };
        let label = if factor == 1.0 {
            name.clone()
        } else {
            format!("{name} ×{}", factor_text(factor))
        };
        chart
            .draw_series(LineSeries::new(points, style))?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FAMILY, 16))
        .background_style(WHITE.mix(0.9))
        .border_style(RGBColor(160, 160, 160))
        .draw()?;
    root.present()?;
    Ok(())
}

/// 1, or a power of ten bringing a small series' peak within 10× of the largest peak.
fn rescale_factors(series: &[(String, Vec<f64>)]) -> Vec<f64> {
    let peaks: Vec<f64> = series
        .iter()
        .map(|(_, v)| v.iter().fold(0.0f64, |m, &x| m.max(x.abs())))
        .collect();
    let top = peaks.iter().copied().fold(0.0, f64::max);
    peaks
        .iter()
        .map(|&p| {
            if p > 0.0 && top / p >= RESCALE_RATIO {
                10f64.powi((top / p).log10().floor().min(300.0) as i32)
            } else {
                1.0
            }
        })
        .collect()
}

fn factor_text(f: f64) -> String {
    let k = f.log10().round() as i32;
    if k <= 6 {
        format!("{}", 10u64.pow(k as u32))
    } else {
        format!("1e{k}")
    }
}

/// A short tick label: up to 4 significant digits, scientific for very large or small values.
fn tick(v: f64) -> String {
    let a = v.abs();
    if a < 1e-12 {
        return "0".into();
    }
    if !(1e-3..1e5).contains(&a) {
        return format!("{v:.2e}");
    }
    let decimals = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_util::entries;
    use super::*;

    fn pulse(bins: usize, centre: f64, spread: f64, peak: f64) -> Vec<f64> {
        (0..bins)
            .map(|t| peak * (-((t as f64 - centre) / spread).powi(2)).exp())
            .collect()
    }

    #[test]
    fn writes_a_png_plot() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("plot.png");
        let bins = 120;
        let series = vec![
            ("whole image".to_string(), pulse(bins, 40.0, 8.0, 1200.0)),
            ("pixel (32, 32)".to_string(), pulse(bins, 55.0, 5.0, 0.8)),
            ("flat".to_string(), vec![300.0; bins]),
        ];
        write_time_plot(&p, (2.0, 0.05, bins), &series).unwrap();
        let meta = std::fs::metadata(&p).unwrap();
        assert!(meta.len() > 5_000, "suspiciously small PNG: {} bytes", meta.len());
        let img = image::open(&p).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (PLOT_WIDTH as u32, PLOT_HEIGHT as u32));
        // The first two line colours are present.
        for c in &COLORS[..2] {
            assert!(img.pixels().any(|px| px.0 == [c.0, c.1, c.2]), "colour {c:?} missing");
        }
        // Some dark (text/axis) pixels.
        assert!(img.pixels().filter(|px| px.0.iter().all(|&v| v < 60)).count() > 500);
        assert_eq!(entries(dir.path()), vec!["plot.png"]);

        // One bin still plots.
        write_time_plot(&p, (0.0, 0.1, 1), &[("only".to_string(), vec![1.0])]).unwrap();
        // All zero still plots.
        write_time_plot(&p, (0.0, 0.1, 3), &[("zero".to_string(), vec![0.0; 3])]).unwrap();
    }

    #[test]
    fn refusals_leave_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.png");
        let ok = vec![("a".to_string(), vec![1.0, 2.0])];
        assert!(matches!(
            write_time_plot(&p, (0.0, 0.1, 0), &[]).unwrap_err(),
            OutputError::Empty { .. }
        ));
        assert!(matches!(
            write_time_plot(&p, (0.0, 0.1, 2), &[]).unwrap_err(),
            OutputError::Empty { .. }
        ));
        let e = write_time_plot(&p, (0.0, -0.1, 2), &ok).unwrap_err();
        assert!(e.to_string().contains("bin width"), "{e}");
        let e = write_time_plot(&p, (f32::NAN, 0.1, 2), &ok).unwrap_err();
        assert!(e.to_string().contains("finite"), "{e}");
        let e = write_time_plot(&p, (0.0, 0.1, 3), &ok).unwrap_err();
        assert!(e.to_string().contains("has 2 values for 3 time bins"), "{e}");
        let e = write_time_plot(&p, (0.0, 0.1, 2), &[("a".to_string(), vec![f64::NAN, 1.0])]).unwrap_err();
        assert!(e.to_string().contains("1 of 2 values are not finite"), "{e}");
        let e = write_time_plot(&dir.path().join("gone/p.png"), (0.0, 0.1, 2), &ok).unwrap_err();
        assert!(e.to_string().contains("gone/p.png"), "{e}");
        assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
    }

    #[test]
    fn helpers() {
        assert_eq!(tick(0.0), "0");
        assert_eq!(tick(2.5), "2.5");
        assert_eq!(tick(1200.0), "1200");
        assert_eq!(tick(0.0125), "0.0125");
        assert_eq!(tick(3.0e-5), "3.00e-5");
        let f = rescale_factors(&[
            ("a".into(), vec![1000.0]),
            ("b".into(), vec![0.5]),
            ("c".into(), vec![200.0]),
        ]);
        assert_eq!(f, vec![1.0, 1000.0, 1.0]);
        assert_eq!(factor_text(1000.0), "1000");
        assert_eq!(factor_text(1e9), "1e9");
        assert_eq!(rescale_factors(&[("z".into(), vec![0.0])]), vec![1.0]);
    }
}
