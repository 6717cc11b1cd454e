//! Writing results to disk: the transient as `.npy`, metadata as `.json`, a multi-layer
//! OpenEXR (one layer per time bin), PNG previews (contact sheet, steady image) and a PNG plot
//! of radiance over time.
//!
//! Every writer is atomic: it writes a temporary file in the destination's folder and renames
//! it into place, so on any error no partial file is left behind (and an existing file is
//! kept as it was). Every writer refuses NaN/±Inf data and empty shapes with an
//! [`OutputError`] naming the file.
//!
//! Film layout everywhere: `[H, W, T, C]` row-major, index `((y*W + x)*T + t)*C + c`.

mod atomic;
pub(crate) use atomic::{Staged, stage_atomic, write_atomic};
mod error;
mod exr_layers;
mod flight;
mod font;
mod json;
mod label;
mod le_bytes;
#[cfg(feature = "hdf5")]
mod nlos_h5;
mod npy;
mod plot;
mod png;
mod preview;
mod tonemap;
mod xy_plot;

pub use error::OutputError;
pub use exr_layers::{too_many_channels, write_exr_layers, write_exr_layers_with_axis};
pub use flight::{
    DECADES, MAX_GIF_FRAMES, Normalise, diverging, log_display, write_derivative_png, write_flight_gif,
    write_streak_png,
};
pub use font::FONT_ENV;
pub(crate) use json::stage_json;
pub use json::write_json;
#[cfg(feature = "hdf5")]
pub use nlos_h5::{h_array, write_nlos_h5, write_nlos_h5_mapped};
pub use npy::{write_npy, write_npy_mapped};
pub use plot::write_time_plot;
pub use preview::{MAX_SHEET_FRAMES, SheetStyle, write_contact_sheet, write_steady_png};
pub use xy_plot::{write_line_plot, write_loglog_plot};

pub(crate) use le_bytes::{write_le, write_le_sparse};

use std::path::Path;

/// Speed of light in vacuum (m/s), to label optical path length as time.
pub(crate) const SPEED_OF_LIGHT_M_PER_S: f64 = 299_792_458.0;

/// A borrowed transient film: `data` is `[height, width, bins, channels]` in row-major order.
#[derive(Clone, Copy, Debug)]
pub struct FilmView<'a> {
    /// The values, `height · width · bins · channels` of them.
    pub data: &'a [f32],
    /// Rows (pixels).
    pub height: usize,
    /// Columns (pixels).
    pub width: usize,
    /// Time bins per pixel.
    pub bins: usize,
    /// Channels per bin: 1 (mono) or 3 (RGB).
    pub channels: usize,
}

impl<'a> FilmView<'a> {
    /// `[height, width, bins, channels]`.
    pub fn shape(&self) -> [usize; 4] {
        [self.height, self.width, self.bins, self.channels]
    }

    /// Every value (all pixels and channels) of time bin `t`.
    pub(crate) fn bin_values(self, t: usize) -> impl Iterator<Item = f32> + 'a {
        let (bins, ch) = (self.bins, self.channels);
        (0..self.height * self.width).flat_map(move |p| (0..ch).map(move |c| self.data[(p * bins + t) * ch + c]))
    }

    /// Flat index of `(y, x, t, c)`.
    #[inline]
    pub(crate) fn index(&self, y: usize, x: usize, t: usize, c: usize) -> usize {
        ((y * self.width + x) * self.bins + t) * self.channels + c
    }

    /// Checks everything a writer relies on: 1 or 3 channels, no zero dimension, a length
    /// that matches the shape, and only finite values.
    pub(crate) fn validate(&self, path: &Path) -> Result<(), OutputError> {
        check_channels(path, self.channels)?;
        check_data(path, &self.shape(), self.data)
    }
}

pub(crate) fn check_channels(path: &Path, channels: usize) -> Result<(), OutputError> {
    if channels == 1 || channels == 3 {
        Ok(())
    } else {
        Err(OutputError::Channels {
            path: path.to_path_buf(),
            channels,
        })
    }
}

/// The element count of `shape`; an error if a dimension is zero or the product overflows.
pub(crate) fn element_count(path: &Path, shape: &[usize]) -> Result<usize, OutputError> {
    if let Some(i) = shape.iter().position(|&d| d == 0) {
        return Err(OutputError::empty(
            path,
            format!("dimension {i} of shape {shape:?} is zero"),
        ));
    }
    shape
        .iter()
        .try_fold(1usize, |acc, &d| acc.checked_mul(d))
        .ok_or_else(|| OutputError::ShapeOverflow {
            path: path.to_path_buf(),
            shape: shape.to_vec(),
        })
}

/// Shape matches length, no zero dimension, all values finite.
pub(crate) fn check_data(path: &Path, shape: &[usize], data: &[f32]) -> Result<(), OutputError> {
    let expected = element_count(path, shape)?;
    if expected != data.len() {
        return Err(OutputError::ShapeMismatch {
            path: path.to_path_buf(),
            shape: shape.to_vec(),
            expected,
            actual: data.len(),
        });
    }
    check_finite(path, data.iter().copied())
}

/// An error counting the NaN/±Inf values (32- or 64-bit), if there are any.
pub(crate) fn check_finite<T: Into<f64>>(path: &Path, values: impl IntoIterator<Item = T>) -> Result<(), OutputError> {
    let (mut count, mut total) = (0, 0);
    for v in values {
        count += usize::from(!v.into().is_finite());
        total += 1;
    }
    if count > 0 {
        Err(OutputError::NonFinite {
            path: path.to_path_buf(),
            count,
            total,
        })
    } else {
        Ok(())
    }
}

#[cfg(test)]
pub(crate) mod test_util {
    use super::FilmView;

    /// A film whose value encodes its position, so layout mistakes show.
    pub fn coded_film(h: usize, w: usize, t: usize, c: usize) -> Vec<f32> {
        let mut v = vec![0.0; h * w * t * c];
        let f = FilmView {
            data: &[],
            height: h,
            width: w,
            bins: t,
            channels: c,
        };
        for y in 0..h {
            for x in 0..w {
                for b in 0..t {
                    for ch in 0..c {
                        v[f.index(y, x, b, ch)] = (y * 1000 + x * 100 + b * 10 + ch) as f32 + 0.25;
                    }
                }
            }
        }
        v
    }

    /// Names in a folder, sorted.
    pub fn entries(dir: &std::path::Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation_messages() {
        let p = Path::new("out/x.exr");
        let data = vec![1.0f32; 12];
        let ok = FilmView {
            data: &data,
            height: 2,
            width: 2,
            bins: 3,
            channels: 1,
        };
        ok.validate(p).unwrap();

        let e = FilmView {
            channels: 2,
            bins: 3,
            ..ok
        }
        .validate(p)
        .unwrap_err();
        assert!(e.to_string().contains("channel count 2"), "{e}");
        let e = FilmView {
            data: &[],
            height: 0,
            ..ok
        }
        .validate(p)
        .unwrap_err();
        assert!(matches!(e, OutputError::Empty { .. }), "{e}");
        let e = FilmView { bins: 4, ..ok }.validate(p).unwrap_err();
        assert!(e.to_string().contains("16 values, but 12"), "{e}");
        let e = FilmView {
            height: usize::MAX,
            ..ok
        }
        .validate(p)
        .unwrap_err();
        assert!(matches!(e, OutputError::ShapeOverflow { .. }), "{e}");

        let mut bad = data.clone();
        bad[0] = f32::NAN;
        bad[5] = f32::INFINITY;
        bad[7] = f32::NEG_INFINITY;
        let e = FilmView { data: &bad, ..ok }.validate(p).unwrap_err();
        assert!(e.to_string().contains("3 of 12 values are not finite"), "{e}");
        assert!(e.to_string().contains("out/x.exr"), "{e}");
        assert_eq!(e.path(), p);
    }
}
