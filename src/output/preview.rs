//! PNG previews: a contact sheet of tone-mapped time bins and the time-integrated image.

use super::png::write_png;
use super::tonemap::{exposure_scale, robust_white, to_srgb8};
use super::{FilmView, OutputError, check_channels, check_data};
use std::path::Path;

/// At most this many time bins appear on a contact sheet; more are subsampled evenly.
pub const MAX_SHEET_FRAMES: usize = 64;
/// Frames are shrunk (box filter) so the sheet's longer side stays within this many pixels.
const MAX_SHEET_SIDE: usize = 4096;
/// Small frames are enlarged (nearest neighbour, at most 8×) towards this many pixels.
const MIN_SHEET_SIDE: usize = 1024;
const MAX_UPSCALE: usize = 8;
/// Border between and around frames, and its grey level.
const GAP: usize = 2;
const GAP_GREY: u8 = 64;

/// Writes a PNG grid of tone-mapped time bins, in time order left to right, top to bottom.
///
/// All bins are shown, or [`MAX_SHEET_FRAMES`] evenly spaced ones (first and last included)
/// when there are more. One exposure is used for every frame so they compare: display white
/// is `1 / exposure` when `exposure` is given (a linear factor, finite and positive), else
/// the 99.5th percentile of the positive values of the frames shown. sRGB curve; mono films
/// give a grey PNG, RGB films an RGB PNG; negative values show black. Frames are enlarged
/// (small films) or box-filtered down (large ones) to keep the sheet a sensible size.
pub fn write_contact_sheet(path: &Path, film: FilmView, exposure: Option<f32>) -> Result<(), OutputError> {
    film.validate(path)?;
    let (h, w, bins, ch) = (film.height, film.width, film.bins, film.channels);
    let frames = chosen_bins(bins);
    let white = robust_white(|| {
        let frames = &frames;
        (0..h * w).flat_map(move |p| {
            frames
                .iter()
                .flat_map(move |&t| (0..ch).map(move |c| film.data[(p * bins + t) * ch + c]))
        })
    });
    let scale = exposure_scale(path, exposure, white)?;

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
    let sheet_w = cols * (cell_w + GAP) + GAP;
    let sheet_h = rows * (cell_h + GAP) + GAP;

    let mut sheet = vec![GAP_GREY; sheet_w * sheet_h * ch];
    let mut acc = vec![0.0f64; ch];
    for (k, &t) in frames.iter().enumerate() {
        let (x0, y0) = (GAP + (k % cols) * (cell_w + GAP), GAP + (k / cols) * (cell_h + GAP));
        for oy in 0..cell_h {
            for ox in 0..cell_w {
                // Source block: one pixel when enlarging, a down×down box when shrinking.
                let (sy0, sx0) = ((oy / up) * down, (ox / up) * down);
                let (sy1, sx1) = ((sy0 + down).min(h), (sx0 + down).min(w));
                acc.iter_mut().for_each(|a| *a = 0.0);
                for sy in sy0..sy1 {
                    for sx in sx0..sx1 {
                        for (c, a) in acc.iter_mut().enumerate() {
                            *a += film.data[film.index(sy, sx, t, c)] as f64;
                        }
                    }
                }
                let count = ((sy1 - sy0) * (sx1 - sx0)) as f64;
                let o = ((y0 + oy) * sheet_w + x0 + ox) * ch;
                for (c, a) in acc.iter().enumerate() {
                    sheet[o + c] = to_srgb8(a / count * scale);
                }
            }
        }
    }
    write_png(path, &sheet, sheet_w, sheet_h, ch)
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
            None,
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
            Some(0.5),
        )
        .unwrap();
        let img = image::open(&pm).unwrap();
        assert_eq!(img.color(), image::ColorType::L8);
        assert_eq!(entries(dir.path()), vec!["frames.png", "mono.png"]);
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
            None,
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
        let e = write_contact_sheet(&p, film, None).unwrap_err();
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
            None,
        )
        .unwrap_err();
        assert!(matches!(e, OutputError::Empty { .. }), "{e}");
        let ok = vec![0.5f32; 12];
        let e = write_contact_sheet(&p, FilmView { data: &ok, ..film }, Some(-1.0)).unwrap_err();
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
