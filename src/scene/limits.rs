//! Bounds on scene values that the renderer's 32-bit floats set (emitted amounts, pulse and
//! gate widths, offsets): the scene's load refuses values beyond them, naming the field
//! (`context`), and the optimiser's parameter domains stay within them (`crate::params`).

/// Largest emitted amount, per channel: an area light's radiance, a point light's intensity,
/// a laser's power (and a `radiance` parameter's value, [`crate::params::ParamKind::domain`]).
///
/// A film value is an average over samples of each path's contribution, the emitted amount
/// times the path's own factor (BSDFs, whose albedo is at most 1, and the geometry of its
/// connections), stored as a 32-bit float, whose largest value is 3.4·10³⁸. The largest film
/// holds 16384² pixels × 2²⁴ bins × 3 channels < 2⁵⁴ ≈ 1.8·10¹⁶ values, so at 10¹⁸ even the
/// sum of all of them, as a preview or a reader adds them up in 32-bit floats, stays below
/// 1.8·10³⁴: 2¹⁴ to spare for a path's own factor. A physical source is far below it (the
/// Sun's radiance is about 2·10⁷ W/(m²·sr)); a stronger light is the same render scaled, so
/// scale the result instead. Before, radiance 3·10³⁸ rendered the whole scene and only then
/// failed adding up the preview's time plot (exit 1).
pub const MAX_EMISSION: f64 = 1e18;

/// Largest pulse width (a Gaussian's σ, a box's width), gate σ, and emitter offset (either
/// sign), metres of OPL: 2²⁴ m, about 16 800 km or 56 ms of light travel. The renderer holds
/// optical path lengths in 32-bit floats (the kernel's path lengths and its window bound, the
/// film's axis in the time plot), which from 2²⁴ m on are 2 m or more apart: light delayed or
/// spread that far lands where those floats no longer resolve a metre, so no window can show
/// it sharper than the floats themselves. Before, `sigma_opl = 1e30` rendered with exit 0
/// and `--auto-window` chose a window of [-3.4·10³⁰, 2.6·10³⁰] m.
pub const MAX_TIME_OPL: f64 = (1u64 << 24) as f64;

/// Smallest GGX roughness α of a rough conductor or dielectric (and a `roughness`
/// parameter's value). The microfacet lobe is evaluated in 32-bit floats through α⁴, which
/// below about 3·10⁻¹⁰ falls under the smallest normal float and is flushed to zero: the
/// lobe then lost 20 % of its light at α = 10⁻¹⁰ and 68 % at 10⁻²⁰, silently (an independent
/// sweep, 2026-12-02; exact down to 10⁻⁹ against the smooth material). At 10⁻⁶, α⁴ = 10⁻²⁴
/// leaves 14 orders of magnitude for the factors it is multiplied by; a lobe that narrow is
/// a mirror to any camera (for α = 0 use the smooth types).
pub const MIN_ROUGHNESS: f64 = 1e-6;

/// Smallest refractive index: a dielectric's `int_ior`, the medium's `eta` (and `ior` and
/// `eta` parameters' values). Fresnel terms and their derivatives take squares and fourth
/// powers of relative indices in 32-bit floats; at `int_ior` 10⁻¹⁹ those flushed to zero and
/// the derivative read −130 where the image does not change (an independent sweep,
/// 2026-12-02), and a medium `eta` of 10⁻³⁸ made every path vanish. No material has an index
/// near 10⁻⁶.
pub const MIN_INDEX: f64 = 1e-6;

/// Narrowest pixel filter: a tent's radius, a Gaussian's σ and radius, in pixels. The density
/// a light path splats with (BDPT's connections to the camera) is 1/r² for a tent of radius r,
/// and the Gaussian's exponent takes 1/σ², in 32-bit floats: at r = 10⁻²⁰ both overflow, and a
/// Gaussian with σ = 10⁻²⁰ rendered another image than the box (an independent sweep,
/// 2026-12-02). A filter a thousandth of a pixel wide already samples the pixel's centre
/// alone, which is what a narrower one would mean.
pub const MIN_FILTER_WIDTH: f64 = 1e-3;

/// Widest pixel filter: a tent's or Gaussian's radius, and a Gaussian's σ, in pixels. Film
/// points drawn that far off the pixel become directions through the image plane at up to
/// 64 pixels times the image's own half-width: at a radius of 10³⁰ every ray left sideways,
/// the image was black and the warning blamed the emitter, and a Gaussian of σ = 10³⁰ made
/// the transient non-finite (an independent sweep, 2026-12-02). A pixel filter reaches a few
/// pixels (pbrt's and Mitsuba's defaults: 1.5 and 2); blur an image wider than 64 pixels
/// after rendering it.
pub const MAX_FILTER_WIDTH: f64 = 64.0;

/// `{v}` for numbers of ordinary size, `{v:e}` for the very large or small (1e18, not
/// 1000000000000000000).
pub fn number<T: Copy + Into<f64> + std::fmt::Display + std::fmt::LowerExp>(v: T) -> String {
    let x: f64 = v.into();
    if x != 0.0 && !(1e-4..1e6).contains(&x.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}
