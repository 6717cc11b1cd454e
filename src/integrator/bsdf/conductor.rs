//! Rough conductor (two-sided): f = F(o·h)·D(h)·G1(o)·G1(i) / (4 |cos θ_o| |cos θ_i|) with the
//! half vector h of o and i (Walter et al. 2007, Eq. 20), sampled by GGX visible normals and
//! mirrored about them, so its pdf is D_o(h) / (4 o·h) (Heitz 2018, Eq. 17).

use super::ggx;
use crate::kernel::{Real, V3};

/// The cosines a conductor needs for unit `wo`, `wi` at normal `n`, mirrored to the side of
/// `wo`: (|cos θ_o|, cos θ_i on that side, cos θ_h, o·h, sin²θ_h), and the lanes where both
/// leave on the same side.
#[inline(always)]
pub fn cosines<R: Real>(n: &V3<R>, wo: &V3<R>, wi: &V3<R>) -> ([R; 5], R::Mask) {
    let co = n.dot(*wo);
    let ci = R::select(co.lt(R::zero()), -n.dot(*wi), n.dot(*wi));
    let h = (*wo + *wi).normalize();
    let ch = n.dot(h).abs();
    let oh = wo.dot(h);
    let co = co.abs();
    ([co, ci, ch, oh, ggx::sin2(n, &h)], co.gt(R::zero()) & ci.gt(R::zero()))
}

/// D·G / (4 cos θ_o cos θ_i): f without Fresnel and tint.
#[inline(always)]
pub fn eval<R: Real>(alpha: R, [co, ci, ch, oh, sh]: [R; 5], valid: R::Mask) -> R {
    let g = ggx::g1(alpha, co, oh) * ggx::g1(alpha, ci, oh);
    R::safe_div(ggx::d(alpha, ch, sh) * g, (co * ci).mul_f(4.0)).masked(valid)
}

/// Solid-angle pdf of mirroring `wo` about a visible normal: G1(o)·D(h) / (4 cos θ_o).
#[inline(always)]
pub fn pdf<R: Real>(alpha: R, [co, _ci, ch, oh, sh]: [R; 5], valid: R::Mask) -> R {
    R::safe_div(ggx::g1(alpha, co, oh) * ggx::d(alpha, ch, sh), co.mul_f(4.0)).masked(valid)
}

/// `w` mirrored about unit `m`: 2(w·m)m − w.
#[inline(always)]
pub fn reflect<R: Real>(w: &V3<R>, m: &V3<R>) -> V3<R> {
    *m * (w.dot(*m) * R::splat(2.0)) - *w
}
