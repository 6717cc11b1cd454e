//! Estimators of the transient path integral (supplemental Eq. 21).
//!
//! - [`path`]: unidirectional path tracing with next-event estimation and MIS, 8 paths per
//!   packet, generic over the number type (`f32`, `f32x8`, duals).
//! - [`bdpt`]: bidirectional path tracing with MIS over every (s, t) strategy (Algorithm 1),
//!   the same number types.
//!
//! Shared pieces: [`trace`] turns lanes into Embree queries, [`surface`] rebuilds hit points
//! from (primitive, u, v) in the kernel's number type, [`bsdf`] evaluates materials,
//! [`emitters`] samples lights, [`camera`] samples primary rays.

pub mod bdpt;
pub mod bsdf;
pub mod camera;
pub mod context;
pub mod deposit;
pub mod emitter_table;
pub mod emitters;
#[cfg(test)]
mod emitters_tests;
pub mod entry;
pub mod importance;
pub mod medium;
pub mod nlos;
pub mod nlos_aim;
pub mod nlos_start;
pub mod opl;
pub mod opl_precision;
pub mod path;
pub mod sink;
pub mod surface;
#[cfg(test)]
pub(crate) mod testutil;
pub mod time_edge_nee;
pub mod time_edges;
pub mod time_terms;
pub mod trace;
pub mod transport;
pub mod window;

pub use context::RenderContext;

/// Power heuristic with exponent 2 (Veach 1997, Eq. 9.13), on solid-angle pdfs: a²/(a² + b²).
/// A density past √f32::MAX (a light sample at grazing emission: p_l ∝ 1/cos θ_y) squares to
/// inf, so there the weight is taken as 1/(1 + (b/a)²), which is 1 for an infinite `a` and a
/// finite `b` (inf/inf made it NaN: a sample that looks at an emitter's back and connects to
/// a point in the emitter's own plane, helper 41).
#[inline(always)]
pub fn power_heuristic<R: crate::kernel::Real>(a: R, b: R) -> R {
    use crate::kernel::Mask;
    let a2 = a * a;
    let w = R::safe_div(a2, a2 + b * b);
    let finite = a2.is_finite();
    if finite.all() {
        return w;
    }
    let r = R::safe_div(b, a);
    R::select(finite, w, R::one() / (R::one() + r * r))
}
