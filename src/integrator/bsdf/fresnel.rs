//! Fresnel reflectance of unpolarised light: at a dielectric interface (real relative index)
//! and at a conductor (complex index η + iκ per channel).

use crate::kernel::{Real, Spectrum};

/// Reflectance at a dielectric interface of relative index `eta` = η_interior / η_exterior for
/// light arriving with cosine `cos_i` against the normal, positive on the exterior side and
/// negative from inside (then the index is inverted); 1 under total internal reflection.
#[inline(always)]
pub fn dielectric<R: Real>(cos_i: R, eta: R) -> R {
    let e = R::select(cos_i.lt(R::zero()), eta.recip(), eta);
    let c = cos_i.abs().min(R::one());
    let sin2_t = R::safe_div(R::one() - c * c, e * e);
    let ct = (R::one() - sin2_t).sqrt();
    let r_par = R::safe_div(e * c - ct, e * c + ct);
    let r_perp = R::safe_div(c - e * ct, c + e * ct);
    let f = (r_par * r_par + r_perp * r_perp).mul_f(0.5);
    R::select(sin2_t.ge(R::one()), R::one(), f)
}

/// Reflectance of a conductor of complex index η + iκ (per channel, relative to the exterior)
/// for light arriving with cosine `cos_i` ≥ 0: the exact unpolarised form, R = (R_s + R_p)/2
/// with R_s = (a² + b² − 2a cos + cos²)/(a² + b² + 2a cos + cos²) and
/// R_p = R_s·(cos²(a² + b²) − 2a cos sin² + sin⁴)/(cos²(a² + b²) + 2a cos sin² + sin⁴),
/// a² + b² = √((η² − κ² − sin²)² + 4η²κ²), a² = (a² + b² + η² − κ² − sin²)/2.
#[inline(always)]
pub fn conductor<R: Real, const C: usize>(cos_i: R, eta: &Spectrum<R, C>, k: &Spectrum<R, C>) -> Spectrum<R, C> {
    let c2 = cos_i * cos_i;
    let s2 = R::one() - c2;
    Spectrum(std::array::from_fn(|ch| {
        let (e2, k2) = (eta.0[ch] * eta.0[ch], k.0[ch] * k.0[ch]);
        let t0 = e2 - k2 - s2;
        let a2pb2 = (t0 * t0 + (e2 * k2).mul_f(4.0)).sqrt();
        let a = ((a2pb2 + t0).mul_f(0.5)).sqrt();
        let t1 = a2pb2 + c2;
        let t2 = (a * cos_i).mul_f(2.0);
        let rs = R::safe_div(t1 - t2, t1 + t2);
        let t3 = c2 * a2pb2 + s2 * s2;
        let t4 = t2 * s2;
        let rp = rs * R::safe_div(t3 - t4, t3 + t4);
        (rs + rp).mul_f(0.5)
    }))
}
