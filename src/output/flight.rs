//! Pictures of light in flight: an animated GIF of the time bins, a streak image (one film row
//! against time, as a streak camera records it) and diverging-colour previews of derivatives.
//!
//! Transients span decades (the direct bounce outshines the third by orders of magnitude), so
//! the animation and the streak image use a logarithmic display curve over [`DECADES`]
//! decades below display white: indirect light stays visible next to the direct flash.
//! Display white is the 99.5th percentile of the positive values of the whole film, or of
//! each frame with [`Normalise::Frame`].

use super::atomic::write_atomic;
use super::label::{LABEL_H, bin_label, draw_labels, label_axis};
use super::png::write_png;
use super::tonemap::robust_white;
use super::{FilmView, OutputError};
use crate::temporal::TimeAxis;
use image::codecs::gif::{GifEncoder, Repeat};
use image::imageops::{self, FilterType};
use image::{Delay, DynamicImage, Frame, ImageBuffer, Rgb, RgbImage};
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

/// Linear value over display white → 8 bits on the logarithmic curve ([`log_display`]).
pub(crate) fn display8(x: f64) -> u8 {
    (log_display(x) * 255.0 + 0.5) as u8
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
    std::array::from_fn(|c| display8(at(c) * scale))
}

pub(crate) fn white_scale(w: Option<f32>) -> f64 {
    w.map(|w| 1.0 / w as f64).filter(|s| s.is_finite()).unwrap_or(1.0)
}

/// Enlarges `img` `up` times in each direction (nearest neighbour: film pixels stay sharp).
fn enlarge(img: RgbImage, up: usize) -> RgbImage {
    if up == 1 {
        return img;
    }
    let (w, h) = img.dimensions();
    imageops::resize(&img, w * up as u32, h * up as u32, FilterType::Nearest)
}

/// Writes the animation: one frame per time bin (at most [`MAX_GIF_FRAMES`]), looping. With
/// the film's time axis each frame carries its time label in a strip above the picture.
pub fn write_flight_gif(
    path: &Path,
    film: FilmView,
    normalise: Normalise,
    axis: Option<&TimeAxis>,
) -> Result<(), OutputError> {
    film.validate(path)?;
    let (h, w, bins) = (film.height, film.width, film.bins);
    let up = upscale(h, w);
    let (gw, gh) = (w * up, h * up);
    let labelled = label_axis(axis, bins, gw);
    let strip = if labelled.is_some() { LABEL_H } else { 0 };
    let too_large = || OutputError::invalid(path, format!("a {gw}x{} GIF is too large", gh + strip));
    if gw > u16::MAX as usize || gh + strip > u16::MAX as usize {
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
                Normalise::Frame => white_scale(robust_white(|| film.bin_values(t))),
            };
            let small = ImageBuffer::from_fn(w as u32, h as u32, |x, y| {
                Rgb(rgb(&film, y as usize * w + x as usize, t, scale))
            });
            let mut img = RgbImage::new(gw as u32, (gh + strip) as u32);
            imageops::replace(&mut img, &enlarge(small, up), 0, strip as i64);
            if let Some(text) = labelled.and_then(|a| bin_label(a, t, gw)) {
                draw_labels(&mut img, gw, gh + strip, gw, &[((0, 0), text)]);
            }
            let delay = Delay::from_numer_denom_ms(FRAME_MS, 1);
            let rgba = DynamicImage::ImageRgb8(img).into_rgba8();
            enc.encode_frame(Frame::from_parts(rgba, 0, 0, delay))
                .map_err(gif_err)?;
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
    let scale = white_scale(robust_white(|| {
        (0..w).flat_map(move |x| {
            (0..bins * film.channels).map(move |k| film.data[(row * w + x) * bins * film.channels + k])
        })
    }));
    let streak: RgbImage = ImageBuffer::from_fn(w as u32, bins as u32, |x, t| {
        Rgb(rgb(&film, row * w + x as usize, t as usize, scale))
    });
    let wide = imageops::resize(&streak, (w * up) as u32, bins as u32, FilterType::Nearest);
    write_png(path, wide.as_raw(), w * up, bins, 3)
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
    let small: RgbImage = ImageBuffer::from_fn(w as u32, h as u32, |x, y| {
        Rgb(diverging(img[y as usize * w + x as usize] * scale))
    });
    write_png(path, enlarge(small, up).as_raw(), w * up, h * up, 3)
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
