//! Rough dielectric: GGX microfacet reflection and refraction (Walter et al. 2007, Eqs. 20–21,
//! with the generalized half vector of Eq. 16), sampled by choosing a visible normal (Heitz
//! 2018) and then reflection with probability F, refraction otherwise; the pdf sums both lobes
//! (Walter et al. 2007, Eqs. 38–41 with D_o in place of D·|m·n|).
//!
//! Conventions: `n` points to the exterior; `eta` = η_interior / η_exterior; `wo` is the
//! direction towards the previous vertex of the path and `wi` the next. Radiance transport
//! (camera paths) divides the refraction lobe by η'² = (η_i/η_o)², importance transport (light
//! paths) does not (Veach 1997, §5.2: the BSDF of refraction is not symmetric).

use super::fresnel;
use super::ggx;
use crate::kernel::{Real, V3};

/// The generalized half vector and the cosines both lobes need.
pub struct Half<R: Real> {
    /// cos θ_o, cos θ_i against `n` (signed).
    pub co: R,
    pub ci: R,
    /// cos θ_m of the half vector oriented to the exterior, its sin²θ_m, o·m, i·m.
    pub cm: R,
    pub sm2: R,
    pub om: R,
    pub im: R,
    /// η_i / η_o: 1 for reflection, η or 1/η for refraction.
    pub etap: R,
    pub reflect: R::Mask,
    /// Lanes with a usable half vector that neither direction sees from behind.
    pub valid: R::Mask,
}

/// The half vector m ∝ η'·i + o (Walter et al. 2007, Eq. 16) oriented to the exterior.
#[inline(always)]
pub fn half<R: Real>(n: &V3<R>, wo: &V3<R>, wi: &V3<R>, eta: R) -> Half<R> {
    let co = n.dot(*wo);
    let ci = n.dot(*wi);
    let reflect = (co * ci).gt(R::zero());
    let etap = R::select(reflect, R::one(), R::select(co.gt(R::zero()), eta, eta.recip()));
    let raw = *wi * etap + *wo;
    let len2 = raw.length_squared();
    let m = raw.normalize();
    let m = V3::select(n.dot(m).lt(R::zero()), -m, m);
    let (cm, om, im) = (n.dot(m), wo.dot(m), wi.dot(m));
    let nonzero = co.abs().gt(R::zero()) & ci.abs().gt(R::zero()) & len2.gt(R::zero());
    let front = (om * co).gt(R::zero()) & (im * ci).gt(R::zero());
    Half {
        co,
        ci,
        cm,
        sm2: ggx::sin2(n, &m),
        om,
        im,
        etap,
        reflect,
        valid: nonzero & front,
    }
}

/// cos θ_m below which the refraction lobe's microfacets are faded out ([`grazing_taper`]).
pub const GRAZING_TAPER_COS: f32 = 0.01;

/// A smoothstep from 0 at cos θ_m = 0 to 1 at [`GRAZING_TAPER_COS`] (the last 0.57° of
/// microfacet normals), applied to the refraction lobe.
///
/// GGX's D(m) does not vanish as m turns to the tangent plane (α²/π at θ_m = 90°, then zero
/// past it), so Walter et al.'s refraction BTDF jumps to zero where the generalized half vector
/// η'·i + o lies in the tangent plane. Where that set sits in direction space depends on η'
/// and on the normal, so the BTDF has a discontinuity that moves with the index and with the
/// pose, which the interior estimator (Algorithm 1: f differentiated at fixed directions)
/// cannot see. Near η' = 1 the whole lobe lies within about |η' − 1| of −o and 1/|η'·i + o|²
/// is huge at its rim, so the missing jump term dominates: at α 0.3 and η' = 1.49/1.5 the
/// derivative of the transmitted energy came out 3.8× its finite difference (z = 51,
/// `tests::rough_dielectric_index_derivative_near_one`). Faded out, the lobe is continuous
/// and its derivative whole. Reflection has no such rim (o + i never lies in the tangent
/// plane for two directions on one side), and sampling still draws the plain visible
/// normals, so weights f·cos/pdf stay exact. The fade takes 3·10⁻⁵ of the light a lobe of
/// α 0.1 passes at η' → 1 seen at 40°, 1.7·10⁻⁴ seen at 77°, 7·10⁻⁴ and 2.2·10⁻³ at α 0.5
/// (`tests::index_matched_rough_dielectric_passes_straight_through` prints them), against
/// 1.8·10⁻³ … 0.42 that Smith masking takes there.
#[inline(always)]
pub fn grazing_taper<R: Real>(cm: R) -> R {
    let x = (cm * R::splat(1.0 / GRAZING_TAPER_COS)).min(R::one()).max(R::zero());
    x * x * (R::splat(3.0) - x.mul_f(2.0))
}

/// f of the rough dielectric (both lobes; zero outside `h.valid`).
#[inline(always)]
pub fn eval<R: Real>(alpha: R, eta: R, h: &Half<R>, radiance: bool) -> R {
    let f = fresnel::dielectric(h.om, eta);
    let dg = ggx::d(alpha, h.cm, h.sm2) * ggx::g1(alpha, h.co, h.om) * ggx::g1(alpha, h.ci, h.im);
    let fr = R::safe_div(dg * f, (h.ci * h.co).abs().mul_f(4.0));
    let s = h.im + R::safe_div(h.om, h.etap);
    let ft = R::safe_div(dg * (R::one() - f) * (h.im * h.om).abs(), (s * s * h.ci * h.co).abs());
    let ft = if radiance { R::safe_div(ft, h.etap * h.etap) } else { ft };
    let ft = ft * grazing_taper(h.cm);
    R::select(h.reflect, fr, ft).masked(h.valid)
}

/// Solid-angle pdf of [`super::Lobes::sample`] on a rough dielectric lane: D_o(m) times the
/// Jacobian of the lobe's map from m to i, times the lobe's probability F or 1 − F.
#[inline(always)]
pub fn pdf<R: Real>(alpha: R, eta: R, h: &Half<R>) -> R {
    let f = fresnel::dielectric(h.om, eta);
    let dv = ggx::visible_pdf(alpha, h.co, h.om, h.cm, h.sm2);
    let pr = R::safe_div(dv * f, h.om.abs().mul_f(4.0));
    let s = h.im + R::safe_div(h.om, h.etap);
    let pt = R::safe_div(dv * (R::one() - f) * h.im.abs(), s * s);
    R::select(h.reflect, pr, pt).masked(h.valid)
}

/// `w` refracted through unit `m` (w·m = `c` > 0) into relative index `eta_l` (η on the far
/// side over η on w's side): −w/η' + (c/η' − cos θ_t)·m; callers use it only off total
/// internal reflection (where F = 1 and refraction is never chosen).
#[inline(always)]
pub fn refract<R: Real>(w: &V3<R>, m: &V3<R>, c: R, eta_l: R) -> V3<R> {
    let inv = eta_l.recip();
    let ct = (R::one() - (R::one() - c * c) * inv * inv).sqrt();
    *m * (c * inv - ct) - *w * inv
}
