//! Display mapping for previews: a global exposure from a robust percentile, clamping, and
//! the sRGB transfer curve.

use super::OutputError;
use std::path::Path;

/// Which quantile of the positive values becomes display white.
pub(crate) const WHITE_QUANTILE: f64 = 0.995;

/// At most this many values enter the percentile; more are subsampled evenly.
const MAX_PERCENTILE_SAMPLES: usize = 1 << 22;

/// The [`WHITE_QUANTILE`] of the positive values produced by `values` (called twice: once to
/// count, once to collect), or `None` if no value is positive.
pub(crate) fn robust_white<I, F>(values: F) -> Option<f32>
where
    I: Iterator<Item = f32>,
    F: Fn() -> I,
{
    let positive = values().filter(|&v| v > 0.0).count();
    if positive == 0 {
        return None;
    }
    let stride = positive.div_ceil(MAX_PERCENTILE_SAMPLES);
    let mut sample: Vec<f32> = values().filter(|&v| v > 0.0).step_by(stride).collect();
    let k = ((sample.len() - 1) as f64 * WHITE_QUANTILE).round() as usize;
    let (_, v, _) = sample.select_nth_unstable_by(k, f32::total_cmp);
    Some(*v)
}

/// The linear factor that maps data to display (1.0 = white): `exposure` if given (must be
/// finite and positive), else `1 / white`, else 1.
pub(crate) fn exposure_scale(path: &Path, exposure: Option<f32>, white: Option<f32>) -> Result<f64, OutputError> {
    match exposure {
        Some(e) if e.is_finite() && e > 0.0 => Ok(e as f64),
        Some(e) => Err(OutputError::invalid(
            path,
            format!("exposure must be a finite positive factor, got {e}"),
        )),
        None => Ok(white.map(|w| 1.0 / w as f64).filter(|s| s.is_finite()).unwrap_or(1.0)),
    }
}

/// Scaled linear value → 8-bit sRGB (negative values are black, over-white values clip).
#[inline]
pub(crate) fn to_srgb8(linear: f64) -> u8 {
    let x = linear.clamp(0.0, 1.0);
    let s = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5).clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_curve() {
        assert_eq!(to_srgb8(0.0), 0);
        assert_eq!(to_srgb8(-3.0), 0);
        assert_eq!(to_srgb8(1.0), 255);
        assert_eq!(to_srgb8(7.0), 255);
        assert_eq!(to_srgb8(0.215_861), 128); // sRGB 128/255
        assert_eq!(to_srgb8(0.212_231), 127); // sRGB 127/255
        assert_eq!(to_srgb8(f64::NAN.max(0.0)), 0);
    }

    #[test]
    fn percentile_ignores_zeros_and_outliers() {
        let mut v = vec![0.0f32; 10_000];
        v.extend((1..=1000).map(|i| i as f32 / 1000.0));
        v.push(1e9); // a firefly
        let white = robust_white(|| v.iter().copied()).unwrap();
        assert!((0.99..=1.0).contains(&white), "{white}");
        assert_eq!(robust_white(|| [0.0f32, -1.0].into_iter()), None);
        assert_eq!(robust_white(|| std::iter::once(2.0f32)), Some(2.0));
    }

    #[test]
    fn exposure_choices() {
        let p = Path::new("x.png");
        assert_eq!(exposure_scale(p, Some(2.0), Some(4.0)).unwrap(), 2.0);
        assert_eq!(exposure_scale(p, None, Some(4.0)).unwrap(), 0.25);
        assert_eq!(exposure_scale(p, None, None).unwrap(), 1.0);
        assert!(exposure_scale(p, Some(0.0), None).is_err());
        assert!(exposure_scale(p, Some(f32::NAN), None).is_err());
        assert!(
            exposure_scale(p, Some(-1.0), None)
                .unwrap_err()
                .to_string()
                .contains("exposure")
        );
    }
}
