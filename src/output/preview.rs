//! PNG previews: a contact sheet of time bins and the time-integrated image.

use super::flight::{Normalise, display8, white_scale};
use super::label::{LABEL_H, bin_label, draw_labels, label_axis};
use super::png::write_png;
use super::tonemap::{exposure_scale, robust_white, to_srgb8};
use super::{FilmView, OutputError, check_channels, check_data};
use crate::temporal::TimeAxis;
use image::imageops::{self, FilterType};
use image::{ImageBuffer, Rgb, Rgb32FImage, RgbImage};
use std::path::Path;

/// At most this many time bins appear on a contact sheet; more are subsampled evenly.
pub const MAX_SHEET_FRAMES: usize = 64;
/// Frames are shrunk (area average) so the sheet's longer side stays within this many pixels.
const MAX_SHEET_SIDE: usize = 4096;
/// Small frames are enlarged (nearest neighbour, at most 8×) towards this many pixels.
const MIN_SHEET_SIDE: usize = 1024;
const MAX_UPSCALE: usize = 8;
/// Border between and around frames, and its grey level.
const GAP: usize = 2;
const GAP_GREY: u8 = 64;
/// Background of the label strips.
const LABEL_GREY: u8 = 24;

/// How a contact sheet is drawn.
#[derive(Clone, Copy, Debug, Default)]
pub struct SheetStyle {
    /// The film's time axis: each frame is then labelled with its bin's centre (OPL in metres
    /// and time of flight in nanoseconds) in a strip above it.
    pub axis: Option<TimeAxis>,
    /// Display white for the whole sheet (frames compare) or per frame.
    pub normalise: Normalise,
    /// A fixed linear exposure (display white = 1 / exposure; finite and positive) instead of
    /// the automatic white; it applies to every frame.
    pub exposure: Option<f32>,
}

/// Writes a PNG grid of time bins, in time order left to right, top to bottom.
///
/// All bins are shown, or [`MAX_SHEET_FRAMES`] evenly spaced ones (first and last included)
/// when there are more. Values go through the logarithmic display curve of the animation
/// (`flight.rs`: [`super::DECADES`] decades below display white), so the indirect bounces stay
/// visible beside the direct flash. Display white is `1 / exposure` when given, else the
/// 99.5th percentile of the positive values of the frames shown (or of each frame, with
/// [`Normalise::Frame`]). Mono films give a grey PNG, RGB films an RGB PNG; negative values
/// show black. Frames are enlarged (nearest neighbour) or shrunk (area average) with
/// `image::imageops` to keep the sheet a sensible size; with an axis each frame carries its
/// time label (left out, with a warning, when no font is installed).
pub fn write_contact_sheet(path: &Path, film: FilmView, style: &SheetStyle) -> Result<(), OutputError> {
    film.validate(path)?;
    let (h, w, bins, ch) = (film.height, film.width, film.bins, film.channels);
    let frames = chosen_bins(bins);
    let sheet_white = robust_white(|| frames.iter().flat_map(|&t| film.bin_values(t)));
    let sheet_scale = exposure_scale(path, style.exposure, sheet_white)?;

    let n = frames.len();
    let (cols, rows) = grid(n, h, w);
    let raw_side = (cols * w).max(rows * h);
    let down = raw_side.div_ceil(MAX_SHEET_SIDE).max(1);
    let up = if down == 1 {
        (MIN_SHEET_SIDE / raw_side).clamp(1, MAX_UPSCALE)
    } else {
        1
    };
    let (cell_w, cell_h) = (w.div_ceil(down) * up, h.div_ceil(down) * up);
    let labelled = label_axis(style.axis.as_ref(), bins, cell_w);
    let strip = if labelled.is_some() { LABEL_H } else { 0 };
    let sheet_w = cols * (cell_w + GAP) + GAP;
    let sheet_h = rows * (cell_h + strip + GAP) + GAP;
    let too_large = || OutputError::invalid(path, format!("a {sheet_w}x{sheet_h} sheet is too large"));
    let mut sheet = RgbImage::from_pixel(
        u32::try_from(sheet_w).map_err(|_| too_large())?,
        u32::try_from(sheet_h).map_err(|_| too_large())?,
        Rgb([GAP_GREY; 3]),
    );

    let mut labels = Vec::new();
    for (k, &t) in frames.iter().enumerate() {
        let (x0, y0) = (
            GAP + (k % cols) * (cell_w + GAP),
            GAP + (k / cols) * (cell_h + strip + GAP),
        );
        let scale = match (style.normalise, style.exposure) {
            (Normalise::Frame, None) => white_scale(robust_white(|| film.bin_values(t))),
            _ => sheet_scale,
        };
        // relative to display white before resizing: imageops clamps f32 pixels to [0, 1]
        // (the display range, so nothing shown is lost)
        let frame: Rgb32FImage = ImageBuffer::from_fn(w as u32, h as u32, |x, y| {
            Rgb(std::array::from_fn(|c| {
                (film.data[film.index(y as usize, x as usize, t, c.min(ch - 1))] as f64 * scale) as f32
            }))
        });
        let (cw, chh) = (cell_w as u32, cell_h as u32);
        let sized = if down > 1 {
            imageops::thumbnail(&frame, cw, chh)
        } else if up > 1 {
            imageops::resize(&frame, cw, chh, FilterType::Nearest)
        } else {
            frame
        };
        let shown: RgbImage =
            ImageBuffer::from_fn(cw, chh, |x, y| Rgb(sized.get_pixel(x, y).0.map(|v| display8(v as f64))));
        imageops::replace(&mut sheet, &shown, x0 as i64, (y0 + strip) as i64);
        if let Some(axis) = &labelled {
            for y in y0..y0 + strip {
                for x in x0..x0 + cell_w {
                    sheet.put_pixel(x as u32, y as u32, Rgb([LABEL_GREY; 3]));
                }
            }
            labels.extend(bin_label(axis, t, cell_w).map(|text| ((x0, y0), text)));
        }
    }
    if !labels.is_empty() {
        draw_labels(&mut sheet, sheet_w, sheet_h, cell_w, &labels);
    }
    let pixels = sheet.into_raw();
    if ch == 1 {
        // grey frames, white text on grey strips: every pixel has three equal channels
        let grey: Vec<u8> = pixels.chunks_exact(3).map(|p| p[0]).collect();
        return write_png(path, &grey, sheet_w, sheet_h, 1);
    }
    write_png(path, &pixels, sheet_w, sheet_h, 3)
}

/// Writes the time-integrated image `data` (`[h, w, c]` row-major, c = 1 or 3) as a PNG with
/// the same tone mapping as [`write_contact_sheet`] (auto exposure, sRGB), at its own size.
pub fn write_steady_png(path: &Path, data: &[f32], h: usize, w: usize, c: usize) -> Result<(), OutputError> {
    check_channels(path, c)?;
    check_data(path, &[h, w, c], data)?;
    let scale = exposure_scale(path, None, robust_white(|| data.iter().copied()))?;
    let pixels: Vec<u8> = data.iter().map(|&v| to_srgb8(v as f64 * scale)).collect();
    write_png(path, &pixels, w, h, c)
}

/// Columns and rows for `n` frames of `h`×`w`: a sheet about 1.4 times wider than tall, with
/// few empty cells.
fn grid(n: usize, h: usize, w: usize) -> (usize, usize) {
    let score = |cols: usize| {
        let rows = n.div_ceil(cols);
        let aspect = (cols * w) as f64 / (rows * h) as f64;
        (aspect / 1.4).ln().abs() + (rows * cols - n) as f64 / n as f64
    };
    let cols = (1..=n).min_by(|&a, &b| score(a).total_cmp(&score(b))).unwrap_or(1);
    (cols, n.div_ceil(cols))
}

/// All bins, or [`MAX_SHEET_FRAMES`] evenly spaced ones including the first and last.
fn chosen_bins(bins: usize) -> Vec<usize> {
    if bins <= MAX_SHEET_FRAMES {
        return (0..bins).collect();
    }
    let n = MAX_SHEET_FRAMES;
    (0..n)
        .map(|i| ((i as f64 * (bins - 1) as f64 / (n - 1) as f64).round() as usize).min(bins - 1))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::test_util::entries;
    use super::*;

    /// A moving bright square on a dim background, growing brighter over time.
    fn moving_square(h: usize, w: usize, bins: usize, ch: usize) -> Vec<f32> {
        let mut v = vec![0.0f32; h * w * bins * ch];
        let f = FilmView {
            data: &[],
            height: h,
            width: w,
            bins,
            channels: ch,
        };
        for t in 0..bins {
            let cx = (t * w) / bins.max(1);
            for y in 0..h {
                for x in 0..w {
                    let inside = x >= cx && x < cx + w / 6 + 1 && y >= h / 3 && y < 2 * h / 3;
                    for c in 0..ch {
                        let tint = [1.0, 0.6, 0.3][c.min(2)];
                        let base = if (x + y) % 7 == 0 { 0.02 } else { 0.0 };
                        v[f.index(y, x, t, c)] = if inside {
                            (0.2 + t as f32 / bins as f32) * tint
                        } else {
                            base
                        };
                    }
                }
            }
        }
        v
    }

    #[test]
    fn grids() {
        assert_eq!(grid(64, 48, 64), (8, 8));
        assert_eq!(grid(1, 10, 10), (1, 1));
        assert_eq!(grid(3, 100, 10), (3, 1));
        for n in 1..=64 {
            let (c, r) = grid(n, 7, 13);
            assert!(c * r >= n && c * (r - 1) < n, "{n}: {c}x{r}");
        }
    }

    #[test]
    fn frame_choice() {
        assert_eq!(chosen_bins(3), vec![0, 1, 2]);
        let c = chosen_bins(1000);
        assert_eq!(c.len(), MAX_SHEET_FRAMES);
        assert_eq!((c[0], *c.last().unwrap()), (0, 999));
        assert!(c.windows(2).all(|p| p[0] < p[1]));
        assert_eq!(chosen_bins(65).len(), 64);
    }

    #[test]
    fn contact_sheet_rgb_and_mono_decode() {
        let dir = tempfile::tempdir().unwrap();
        let (h, w) = (24, 32);
        let rgb = moving_square(h, w, 10, 3);
        let p = dir.path().join("frames.png");
        write_contact_sheet(
            &p,
            FilmView {
                data: &rgb,
                height: h,
                width: w,
                bins: 10,
                channels: 3,
            },
            &SheetStyle::default(),
        )
        .unwrap();
        let img = image::open(&p).unwrap();
        assert_eq!(img.color(), image::ColorType::Rgb8);
        // 10 frames of 24x32 → 4 columns, 3 rows, enlarged 8× (the most).
        assert_eq!(grid(10, 24, 32), (4, 3));
        assert_eq!(
            (img.width(), img.height()),
            (4 * (32 * 8 + GAP) as u32 + 2, 3 * (24 * 8 + GAP) as u32 + 2)
        );
        let px = img.to_rgb8();
        assert_eq!(px.get_pixel(0, 0).0, [GAP_GREY; 3]);
        // The last frame's square is the brightest thing: it clips to white in red.
        let max_r = px.pixels().map(|p| p.0[0]).max().unwrap();
        assert_eq!(max_r, 255);

        let mono = moving_square(h, w, 200, 1);
        let pm = dir.path().join("mono.png");
        write_contact_sheet(
            &pm,
            FilmView {
                data: &mono,
                height: h,
                width: w,
                bins: 200,
                channels: 1,
            },
            &SheetStyle {
                exposure: Some(0.5),
                ..Default::default()
            },
        )
        .unwrap();
        let img = image::open(&pm).unwrap();
        assert_eq!(img.color(), image::ColorType::L8);
        assert_eq!(entries(dir.path()), vec!["frames.png", "mono.png"]);
    }

    /// Two frames 1000× apart in brightness, each a flat square on black.
    fn two_exposures() -> (Vec<f32>, FilmView<'static>) {
        let (h, w) = (8, 8);
        let mut v = vec![0.0f32; h * w * 2];
        for y in 2..6 {
            for x in 2..6 {
                v[(y * w + x) * 2] = 1.0;
                v[(y * w + x) * 2 + 1] = 1e-3;
            }
        }
        let view = FilmView {
            data: &[],
            height: h,
            width: w,
            bins: 2,
            channels: 1,
        };
        (v, view)
    }

    /// The brightest grey of each frame cell of a two-frame, unlabelled mono sheet.
    fn cell_peaks(p: &Path) -> Vec<u8> {
        let img = image::open(p).unwrap().to_luma8();
        let (cols, _) = grid(2, 8, 8);
        assert_eq!(cols, 2);
        let cell = (img.width() as usize - GAP) / 2;
        (0..2)
            .map(|k| {
                img.enumerate_pixels()
                    .filter(|(x, y, _)| {
                        let (x, y) = (*x as usize, *y as usize);
                        x >= GAP + k * cell && x < (k + 1) * cell && y >= GAP && y + GAP < img.height() as usize
                    })
                    .map(|(_, _, p)| p.0[0])
                    .max()
                    .unwrap()
            })
            .collect()
    }

    #[test]
    fn log_exposure_keeps_dim_frames_visible_and_frame_normalisation_lifts_them() {
        let dir = tempfile::tempdir().unwrap();
        let (data, view) = two_exposures();
        let film = FilmView { data: &data, ..view };
        let pg = dir.path().join("global.png");
        write_contact_sheet(&pg, film, &SheetStyle::default()).unwrap();
        // one white: the bright frame is white, the dim one (3 decades down) at the curve's foot
        assert_eq!(cell_peaks(&pg), vec![255, 0]);
        let pf = dir.path().join("frame.png");
        let per_frame = SheetStyle {
            normalise: Normalise::Frame,
            ..Default::default()
        };
        write_contact_sheet(&pf, film, &per_frame).unwrap();
        assert_eq!(cell_peaks(&pf), vec![255, 255]);
        // a frame 10× below white shows at 2/3 of the display range, where a linear sRGB
        // curve at that exposure would show 89/255
        assert_eq!(display8(0.1), (255.0 * 2.0 / 3.0 + 0.5) as u8);
        // a fixed exposure holds for every frame, whatever the normalisation
        let fixed = SheetStyle {
            normalise: Normalise::Frame,
            exposure: Some(1.0),
            axis: None,
        };
        write_contact_sheet(&pf, film, &fixed).unwrap();
        assert_eq!(cell_peaks(&pf), vec![255, 0]);
    }

    #[test]
    fn frames_carry_their_time_labels() {
        let dir = tempfile::tempdir().unwrap();
        let (h, w, bins) = (24, 32, 10);
        let rgb = moving_square(h, w, bins, 3);
        let film = FilmView {
            data: &rgb,
            height: h,
            width: w,
            bins,
            channels: 3,
        };
        let axis = TimeAxis {
            start_opl: 3.0,
            bin_width_opl: 0.3,
            bins,
        };
        let p = dir.path().join("labelled.png");
        let style = SheetStyle {
            axis: Some(axis),
            ..Default::default()
        };
        write_contact_sheet(&p, film, &style).unwrap();
        let img = image::open(&p).unwrap().to_rgb8();
        // 4 × 3 cells of 256 × 192 pixels, each under an 18-pixel label strip
        let (cell_w, cell_h) = (32 * 8, 24 * 8);
        assert_eq!(
            img.dimensions(),
            (
                (4 * (cell_w + GAP) + GAP) as u32,
                (3 * (cell_h + LABEL_H + GAP) + GAP) as u32
            )
        );
        // every strip holds white text on its dark grey, and nothing else
        for k in 0..bins {
            let (x0, y0) = (GAP + (k % 4) * (cell_w + GAP), GAP + (k / 4) * (cell_h + LABEL_H + GAP));
            let strip: Vec<[u8; 3]> = (y0..y0 + LABEL_H)
                .flat_map(|y| (x0..x0 + cell_w).map(move |x| (x, y)))
                .map(|(x, y)| img.get_pixel(x as u32, y as u32).0)
                .collect();
            let text = strip.iter().filter(|p| p[0] > 200).count();
            assert!(text > 30, "frame {k}: {text} text pixels");
            assert!(
                strip.iter().all(|p| p[0] == p[1] && p[1] == p[2]),
                "frame {k}: coloured strip"
            );
        }
        // an axis of another length labels nothing (it is not this film's)
        let other = SheetStyle {
            axis: Some(TimeAxis { bins: 11, ..axis }),
            ..Default::default()
        };
        write_contact_sheet(&p, film, &other).unwrap();
        assert_eq!(image::open(&p).unwrap().height() as usize, 3 * (cell_h + GAP) + GAP);
    }

    #[test]
    fn large_frames_are_shrunk() {
        let dir = tempfile::tempdir().unwrap();
        let (h, w, bins) = (600, 900, 20);
        let data = moving_square(h, w, bins, 1);
        let p = dir.path().join("big.png");
        write_contact_sheet(
            &p,
            FilmView {
                data: &data,
                height: h,
                width: w,
                bins,
                channels: 1,
            },
            &SheetStyle::default(),
        )
        .unwrap();
        let img = image::open(&p).unwrap();
        assert!(img.width() as usize <= MAX_SHEET_SIDE + 64 && img.height() as usize <= MAX_SHEET_SIDE + 64);
    }

    #[test]
    fn steady_png_decodes() {
        let dir = tempfile::tempdir().unwrap();
        let (h, w) = (40, 60);
        let mut data = vec![0.0f32; h * w * 3];
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) * 3;
                data[i] = x as f32 / w as f32;
                data[i + 1] = y as f32 / h as f32;
                data[i + 2] = 0.25;
            }
        }
        let p = dir.path().join("steady.png");
        write_steady_png(&p, &data, h, w, 3).unwrap();
        let img = image::open(&p).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (60, 40));
        assert_eq!(img.get_pixel(0, 0).0[0], 0);
        assert!(img.get_pixel(59, 39).0[0] > 240);

        let grey = vec![1.0f32; 12];
        let pg = dir.path().join("grey.png");
        write_steady_png(&pg, &grey, 3, 4, 1).unwrap();
        let g = image::open(&pg).unwrap();
        assert_eq!(g.color(), image::ColorType::L8);
        assert!(g.to_luma8().pixels().all(|p| p.0[0] == 255));

        // All zero: a black image, not an error.
        write_steady_png(&pg, &[0.0; 12], 3, 4, 1).unwrap();
        assert!(image::open(&pg).unwrap().to_luma8().pixels().all(|p| p.0[0] == 0));
    }

    #[test]
    fn refusals_leave_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.png");
        let mut data = vec![0.5f32; 12];
        data[4] = f32::INFINITY;
        let film = FilmView {
            data: &data,
            height: 2,
            width: 2,
            bins: 3,
            channels: 1,
        };
        let e = write_contact_sheet(&p, film, &SheetStyle::default()).unwrap_err();
        assert!(e.to_string().contains("1 of 12 values are not finite"), "{e}");
        let e = write_contact_sheet(
            &p,
            FilmView {
                data: &[],
                height: 2,
                width: 2,
                bins: 0,
                channels: 1,
            },
            &SheetStyle::default(),
        )
        .unwrap_err();
        assert!(matches!(e, OutputError::Empty { .. }), "{e}");
        let ok = vec![0.5f32; 12];
        let bad = SheetStyle {
            exposure: Some(-1.0),
            ..Default::default()
        };
        let e = write_contact_sheet(&p, FilmView { data: &ok, ..film }, &bad).unwrap_err();
        assert!(e.to_string().contains("exposure"), "{e}");
        let e = write_steady_png(&p, &[f32::NAN; 4], 2, 2, 1).unwrap_err();
        assert!(matches!(e, OutputError::NonFinite { count: 4, .. }), "{e}");
        let e = write_steady_png(&p, &[0.0; 8], 2, 2, 2).unwrap_err();
        assert!(matches!(e, OutputError::Channels { .. }), "{e}");
        let e = write_steady_png(&p, &[0.0; 5], 2, 2, 1).unwrap_err();
        assert!(matches!(e, OutputError::ShapeMismatch { .. }), "{e}");
        let e = write_steady_png(&dir.path().join("none/s.png"), &[0.0; 4], 2, 2, 1).unwrap_err();
        assert!(e.to_string().contains("none/s.png"), "{e}");
        assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
    }
}
