//! Pictures of light in flight: an animated GIF of the time bins, a streak image (one film row
//! against time, as a streak camera records it) and diverging-colour previews of derivatives.
//!
//! Transients span decades (the direct bounce outshines the third by orders of magnitude), so
//! the animation and the streak image use a logarithmic display curve over [`DECADES`]
//! decades below display white: indirect light stays visible next to the direct flash.
//! Display white is the 99.5th percentile of the positive values of the whole film, or of
//! each frame with [`Normalise::Frame`].

use super::atomic::write_atomic;
use super::png::write_png;
use super::tonemap::robust_white;
use super::{FilmView, OutputError};
use image::codecs::gif::{GifEncoder, Repeat};
use image::{Delay, Frame, RgbaImage};
use std::path::Path;

/// Decades of radiance below display white that the logarithmic curve shows.
pub const DECADES: f64 = 3.0;
/// At most this many time bins become animation frames; more are subsampled evenly.
pub const MAX_GIF_FRAMES: usize = 200;
/// Small films are enlarged (nearest neighbour) towards this many pixels on the longer side.
const MIN_SIDE: usize = 256;
const MAX_UPSCALE: usize = 8;
/// Milliseconds per animation frame.
const FRAME_MS: u32 = 50;

/// Where display white comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Normalise {
    /// One white for the whole film (frames compare).
    #[default]
    Global,
    /// Each frame its own white (every frame shows its structure; brightness no longer
    /// compares between frames).
    Frame,
}

/// Linear value over display white → [0, 1] on a logarithmic scale of [`DECADES`] decades
/// (0 at or below 10^−DECADES, 1 at white and above).
#[inline]
pub fn log_display(x: f64) -> f64 {
    if !(x > 0.0) {
        return 0.0;
    }
    (1.0 + x.log10() / DECADES).clamp(0.0, 1.0)
}

/// The enlargement of a film of `h` × `w` pixels for previews.
fn upscale(h: usize, w: usize) -> usize {
    (MIN_SIDE / h.max(w).max(1)).clamp(1, MAX_UPSCALE)
}

/// The bins shown: all, or `max` evenly spaced ones (first and last included).
fn chosen(bins: usize, max: usize) -> Vec<usize> {
    if bins <= max {
        return (0..bins).collect();
    }
    (0..max).map(|k| k * (bins - 1) / (max - 1)).collect()
}

/// One 8-bit display value per channel of pixel `p` at bin `t` (grey films give three equal
/// channels).
fn rgb(film: &FilmView, p: usize, t: usize, scale: f64) -> [u8; 3] {
    let ch = film.channels;
    let at = |c: usize| film.data[(p * film.bins + t) * ch + c.min(ch - 1)] as f64;
    std::array::from_fn(|c| (log_display(at(c) * scale) * 255.0 + 0.5) as u8)
}

fn white_scale(w: Option<f32>) -> f64 {
    w.map(|w| 1.0 / w as f64).filter(|s| s.is_finite()).unwrap_or(1.0)
}

/// Writes the animation: one frame per time bin (at most [`MAX_GIF_FRAMES`]), looping.
pub fn write_flight_gif(path: &Path, film: FilmView, normalise: Normalise) -> Result<(), OutputError> {
    film.validate(path)?;
    let (h, w, bins, ch) = (film.height, film.width, film.bins, film.channels);
    let up = upscale(h, w);
    let (gw, gh) = (w * up, h * up);
    let too_large = || OutputError::invalid(path, format!("a {gw}x{gh} GIF is too large"));
    let (gw32, gh32) = (
        u32::try_from(gw).map_err(|_| too_large())?,
        u32::try_from(gh).map_err(|_| too_large())?,
    );
    if gw > u16::MAX as usize || gh > u16::MAX as usize {
        return Err(too_large());
    }
    let frames = chosen(bins, MAX_GIF_FRAMES);
    let global = white_scale(robust_white(|| film.data.iter().copied()));
    write_atomic(path, |out| {
        let mut enc = GifEncoder::new_with_speed(&mut *out, 10);
        let gif_err = |e: image::ImageError| match e {
            image::ImageError::IoError(io) => OutputError::io(path, io),
            other => OutputError::encode(path, "GIF", other),
        };
        enc.set_repeat(Repeat::Infinite).map_err(gif_err)?;
        for &t in &frames {
            let scale = match normalise {
                Normalise::Global => global,
                Normalise::Frame => white_scale(robust_white(|| {
                    (0..h * w).flat_map(move |p| (0..ch).map(move |c| film.data[(p * bins + t) * ch + c]))
                })),
            };
            let mut img = RgbaImage::new(gw32, gh32);
            for (x, y, px) in img.enumerate_pixels_mut() {
                let p = (y as usize / up) * w + x as usize / up;
                let [r, g, b] = rgb(&film, p, t, scale);
                *px = image::Rgba([r, g, b, 255]);
            }
            let delay = Delay::from_numer_denom_ms(FRAME_MS, 1);
            enc.encode_frame(Frame::from_parts(img, 0, 0, delay)).map_err(gif_err)?;
        }
        Ok(())
    })
}

/// Writes the streak image of film row `row`: x to the right, time downward, one image row
/// per bin (enlarged like the film), on the logarithmic curve with the film's white.
pub fn write_streak_png(path: &Path, film: FilmView, row: usize) -> Result<(), OutputError> {
    film.validate(path)?;
    let (h, w, bins) = (film.height, film.width, film.bins);
    if row >= h {
        return Err(OutputError::invalid(
            path,
            format!("row {row} is outside the {h}-row film"),
        ));
    }
    let up = upscale(h, w);
    let (sw, sh) = (w * up, bins);
    let scale = white_scale(robust_white(|| {
        (0..w).flat_map(move |x| {
            (0..bins * film.channels).map(move |k| film.data[(row * w + x) * bins * film.channels + k])
        })
    }));
    let mut px = vec![0u8; sw * sh * 3];
    for t in 0..bins {
        for x in 0..sw {
            let v = rgb(&film, row * w + x / up, t, scale);
            px[(t * sw + x) * 3..][..3].copy_from_slice(&v);
        }
    }
    write_png(path, &px, sw, sh, 3)
}

/// Writes a derivative's time-integrated image (channels averaged) in a diverging colour map:
/// blue negative, white zero, red positive, symmetric about zero with the 99.5th percentile of
/// |value| at full colour; enlarged like the film.
pub fn write_derivative_png(path: &Path, film: FilmView) -> Result<(), OutputError> {
    film.validate(path)?;
    let (h, w, bins, ch) = (film.height, film.width, film.bins, film.channels);
    let img: Vec<f64> = (0..h * w)
        .map(|p| {
            film.data[p * bins * ch..(p + 1) * bins * ch]
                .iter()
                .map(|&v| v as f64)
                .sum::<f64>()
                / ch as f64
        })
        .collect();
    let scale = white_scale(robust_white(|| img.iter().map(|v| v.abs() as f32)));
    let up = upscale(h, w);
    let (iw, ih) = (w * up, h * up);
    let mut px = vec![0u8; iw * ih * 3];
    for y in 0..ih {
        for x in 0..iw {
            px[(y * iw + x) * 3..][..3].copy_from_slice(&diverging(img[(y / up) * w + x / up] * scale));
        }
    }
    write_png(path, &px, iw, ih, 3)
}

/// A value in [−1, 1] (clamped) → blue, white at 0, red; sRGB-encoded.
pub fn diverging(v: f64) -> [u8; 3] {
    let v = if v.is_finite() { v.clamp(-1.0, 1.0) } else { 0.0 };
    let fade = 1.0 - v.abs();
    // white fades to red (positive) or blue (negative), keeping some of the other channels
    let (r, g, b) = if v >= 0.0 { (1.0, fade, fade) } else { (fade, fade, 1.0) };
    [r, g, b].map(super::tonemap::to_srgb8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_curve_spans_its_decades() {
        assert_eq!(log_display(1.0), 1.0);
        assert_eq!(log_display(5.0), 1.0);
        assert!((log_display(0.1) - (1.0 - 1.0 / DECADES)).abs() < 1e-12);
        assert_eq!(log_display(10f64.powf(-DECADES)), 0.0);
        assert_eq!(log_display(0.0), 0.0);
        assert_eq!(log_display(-1.0), 0.0);
        assert_eq!(log_display(f64::NAN), 0.0);
    }

    #[test]
    fn diverging_map_is_white_at_zero_and_saturates() {
        assert_eq!(diverging(0.0), [255, 255, 255]);
        assert_eq!(diverging(1.0), [255, 0, 0]);
        assert_eq!(diverging(-7.0), [0, 0, 255]);
        assert_eq!(diverging(f64::NAN), [255, 255, 255]);
        let [r, g, b] = diverging(0.5);
        assert!(r == 255 && g == b && g < 255);
    }

    #[test]
    fn frames_are_all_bins_or_an_even_subsample() {
        assert_eq!(chosen(3, 200), vec![0, 1, 2]);
        let c = chosen(1000, 200);
        assert_eq!((c.len(), c[0], c[199]), (200, 0, 999));
        assert!(c.windows(2).all(|p| p[1] > p[0]));
    }
}
