//! The Dirac lobes (smooth conductor and dielectric) of a vertex in the kernel's number type:
//! the direction a delta lobe sent the path in and its weight f·|cos|/pdf, recomputed from
//! the vertex's moving normal, the moving direction it was reached from and the indices with
//! their derivative lanes.
//!
//! Why: a Dirac lobe fixes the next direction, so the next vertex is no free variable of the
//! path integral. Integrating the delta out in solid angle at x_k leaves ρ(θ)·L(x_k, ω_s(θ)),
//! with ω_s the mirror or Snell direction and ρ the lobe's weight (F·tint, F, or (1 − F)/η'²
//! in radiance transport), so x_{k+1} is the hit of the ray x_k + t·ω_s(θ) ("attached", ray
//! form, as the first camera vertex) and the segment x_k → x_{k+1} has no G·J. The
//! derivative then follows by the chain rule (`integrator::path`); a material-form x_{k+1}
//! would keep the direction from x_k fixed on the surface and miss how ω_s turns.

use super::{Lobes, conductor, dielectric, fresnel, ggx};
use crate::kernel::{Mask, Real, Spectrum, V3};

impl<R: Real, const C: usize> Lobes<R, C> {
    /// On the delta lanes of a vertex with unit normal `n`, reached from unit direction `wo`
    /// (towards the previous vertex): the direction the sampled lobe continues in (refraction
    /// on lanes `transmitted`, else reflection) and its weight over the weight's value (value
    /// 1, with the derivatives of F, the tint, 1/η'² and an index-matched rough lane's masking
    /// G1), for `radiance` or importance transport. The values are those of [`Lobes::sample`]
    /// on the same lanes.
    pub fn delta_dual(&self, n: &V3<R>, wo: &V3<R>, transmitted: R::Mask, radiance: bool) -> (V3<R>, Spectrum<R, C>) {
        let co = n.dot(*wo);
        let nn = V3::select(co.lt(R::zero()), -*n, *n);
        let c = co.abs();
        let mut dir = conductor::reflect(wo, &nn);
        let relative = |w: R| R::safe_div(w, R::from_value(w.value()));
        let mut ratio = Spectrum::<R, C>::splat(R::one());
        if self.conductor.any() {
            let f = self.conductor_reflectance(c);
            let r = Spectrum(f.0.map(relative));
            ratio = Spectrum::select(self.conductor, r, ratio);
        }
        if self.dielectric.any() {
            let eta = self.eta_int / self.eta_ext;
            let eta_l = R::select(co.gt(R::zero()), eta, eta.recip());
            let f = fresnel::dielectric(c, eta_l);
            let t = self.dielectric & transmitted;
            dir = V3::select(t, dielectric::refract(wo, &nn, c, eta_l), dir);
            // Smith's masking of an index-matched rough lane (1 on smooth lanes: α = 0); the
            // fade of the microfacet `sample` drew stays a constant of the path
            let mut wt = relative(R::one() - f) * relative(ggx::g1(self.alpha, c, c));
            if radiance {
                wt *= relative(R::safe_div(R::one(), eta_l * eta_l));
            }
            let w = R::select(transmitted, wt, relative(f));
            ratio = Spectrum::select(self.dielectric, Spectrum::splat(w), ratio);
        }
        (dir, ratio)
    }
}
