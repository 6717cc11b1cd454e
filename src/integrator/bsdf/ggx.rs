//! The GGX (Trowbridge–Reitz) microfacet distribution with isotropic roughness α, written with
//! cosines against the normal only, so its values and derivatives (α, and the directions of
//! moving vertices) need no tangent frame; and sampling of the visible normals (Heitz 2018,
//! "Sampling the GGX Distribution of Visible Normals") in a local frame. Shadowing–masking is
//! Smith's separable form G = G1(o)·G1(i), as in Mitsuba 3's microfacet distribution.

use crate::kernel::{Real, V3};
use std::f32::consts::PI;

/// D(m) = α² / (π ((α² − 1) cos²θ_m + 1)²) for cos θ_m > 0, 0 below (Walter et al. 2007,
/// Eq. 33), from cos θ_m and sin²θ_m. The denominator's root is taken as α² cos²θ_m + sin²θ_m:
/// in the form of Eq. 33, α² − 1 rounds to −1 in f32 below α ≈ 2.4·10⁻⁴, so the root vanished
/// at the peak, D was 0 there and a lobe sampled at m = n lost its sample (a rough conductor of
/// α 10⁻⁴ rendered 38 % dark). And sin²θ_m comes from the caller as |n × m|² ([`sin2`]):
/// 1 − cos²θ_m rounds in f32 to multiples of 6·10⁻⁸ near the peak, coarser than α² there below
/// α ≈ 10⁻³, and the roughness derivative ∂D/∂α, which changes sign across the peak, came
/// out biased: −8008 ± 16 against a finite difference of about 0 at α 10⁻⁴
/// (`tests::roughness_derivative_of_a_nearly_smooth_lobe`).
#[inline(always)]
pub fn d<R: Real>(alpha: R, cos_m: R, sin2_m: R) -> R {
    let a2 = alpha * alpha;
    let t = a2 * cos_m * cos_m + sin2_m;
    R::safe_div(a2, (t * t).mul_f(PI)).masked(cos_m.gt(R::zero()))
}

/// sin²θ between unit vectors `n` and `m`, as |n × m|²: exact to f32's relative precision
/// near θ = 0, where 1 − (n·m)² is not.
#[inline(always)]
pub fn sin2<R: Real>(n: &V3<R>, m: &V3<R>) -> R {
    n.cross(*m).length_squared()
}

/// Smith's G1 = 2 / (1 + √(1 + α² tan²θ_w)) of a direction with cosine `cos_w` against the
/// normal, 0 where it sees the back of the microfacet (`cos_wm` = w·m of the other sign;
/// Walter et al. 2007, Eq. 34).
#[inline(always)]
pub fn g1<R: Real>(alpha: R, cos_w: R, cos_wm: R) -> R {
    let c2 = cos_w * cos_w;
    let tan2 = R::safe_div(R::one() - c2, c2);
    let g = R::safe_div(R::splat(2.0), R::one() + (R::one() + alpha * alpha * tan2).sqrt());
    g.masked((cos_w * cos_wm).gt(R::zero()))
}

/// Density of the visible normal m seen from w, D_w(m) = G1(w)·|w·m|·D(m) / |cos θ_w|
/// (Heitz 2018, Eq. 1), per solid angle of m.
#[inline(always)]
pub fn visible_pdf<R: Real>(alpha: R, cos_w: R, cos_wm: R, cos_m: R, sin2_m: R) -> R {
    R::safe_div(
        g1(alpha, cos_w, cos_wm) * cos_wm.abs() * d(alpha, cos_m, sin2_m),
        cos_w.abs(),
    )
}

/// A visible normal (local frame, z up) for the direction `w` (local, w.z > 0), distributed by
/// [`visible_pdf`]: stretch to the unit-roughness configuration, sample the projected
/// hemisphere, unstretch (Heitz 2018, Listing 1).
#[inline(always)]
pub fn sample_visible<V: Real>(alpha: V, w: &V3<V>, u1: V, u2: V) -> V3<V> {
    let vh = V3::new(alpha * w.x, alpha * w.y, w.z).normalize();
    let lensq = vh.x * vh.x + vh.y * vh.y;
    let tilted = lensq.gt(V::splat(1e-14));
    let inv = V::safe_div(V::one(), lensq.sqrt());
    let t1 = V3::select(
        tilted,
        V3::new(-vh.y * inv, vh.x * inv, V::zero()),
        V3::new(V::one(), V::zero(), V::zero()),
    );
    let t2 = vh.cross(t1);
    let r = u1.sqrt();
    let (sn, cs) = u2.mul_f(2.0 * PI).sin_cos();
    let p1 = r * cs;
    let s = (V::one() + vh.z).mul_f(0.5);
    let p2 = (V::one() - s) * (V::one() - p1 * p1).sqrt() + s * (r * sn);
    let p3 = (V::one() - p1 * p1 - p2 * p2).sqrt();
    let nh = t1 * p1 + t2 * p2 + vh * p3;
    V3::new(alpha * nh.x, alpha * nh.y, nh.z.max(V::zero())).normalize()
}
