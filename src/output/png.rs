//! 8-bit PNG encoding through the `image` crate, written atomically.

use super::OutputError;
use super::atomic::write_atomic;
use image::ImageEncoder;
use image::codecs::png::PngEncoder;
use std::path::Path;

/// Writes 8-bit `pixels` (`height` rows of `width` pixels of `channels` = 1 (grey) or 3 (RGB)
/// bytes) as a PNG, atomically.
pub(crate) fn write_png(
    path: &Path,
    pixels: &[u8],
    width: usize,
    height: usize,
    channels: usize,
) -> Result<(), OutputError> {
    let color = match channels {
        1 => image::ExtendedColorType::L8,
        3 => image::ExtendedColorType::Rgb8,
        _ => {
            return Err(OutputError::Channels {
                path: path.to_path_buf(),
                channels,
            });
        }
    };
    let too_large = || OutputError::invalid(path, format!("a {width}x{height} PNG is too large"));
    let w = u32::try_from(width).map_err(|_| too_large())?;
    let h = u32::try_from(height).map_err(|_| too_large())?;
    if w == 0 || h == 0 {
        return Err(OutputError::empty(path, format!("a {width}x{height} image")));
    }
    if width.checked_mul(height).and_then(|n| n.checked_mul(channels)) != Some(pixels.len()) {
        return Err(OutputError::invalid(
            path,
            format!("{} bytes do not make a {width}x{height}x{channels} image", pixels.len()),
        ));
    }
    write_atomic(path, |out| {
        PngEncoder::new(&mut *out)
            .write_image(pixels, w, h, color)
            .map_err(|e| match e {
                image::ImageError::IoError(io) => OutputError::io(path, io),
                other => OutputError::encode(path, "PNG", other),
            })
    })
}
