//! Optical path length in f64 beside the kernel's number type.
//!
//! The kernel carries each path's OPL d in its number type R (f32, f32x8, `Dual8<P>`): that
//! gives ḋ for Algorithm 1, but at 4 m an f32 step is 4.8·10⁻⁷ m, so a pulse of a few
//! nanometres (the paper validates with 0.01 fs ≈ 3·10⁻⁹ m) sees OPLs quantised into a comb.
//! Accumulating R in f64 would not help either: each segment length is computed from f32
//! points and is itself rounded to ~10⁻⁷ m.
//!
//! So when the film needs it ([`OplPrecision::choose`]), every lane also carries its OPL in
//! f64, summed from segment lengths between points rebuilt in f64 from the f32 barycentrics
//! Embree returned. A rebuilt point is exactly a point of its (f32) triangle, so the f64 OPL
//! is exact for that sample; that the sample sits a few f32 steps away from where the f32
//! kernel put it is harmless (it only jitters where on the surface the sample was taken).
//! Derivatives ḋ stay in R. Otherwise the f64 value is the f32 one widened at the film.

use super::context::RenderContext;
use glam::DVec3;

// Defined in `opl_precision.rs`, below the render context that holds one; named here too,
// beside the f64 arithmetic it switches on.
pub use super::opl_precision::OplPrecision;

/// The point at barycentrics (u, v) of triangle `prim`, in f64 (Embree's convention
/// p = p0 + u·(p1 − p0) + v·(p2 − p0), as `surface::surface_at`).
#[inline]
pub fn point64(ctx: &RenderContext, prim: u32, u: f32, v: f32) -> DVec3 {
    let [p0, p1, p2] = ctx.tri_verts[prim as usize].map(|p| p.as_dvec3());
    p0 + (p1 - p0) * u as f64 + (p2 - p0) * v as f64
}

/// The length of the segment a → b for a path's OPL: from the f64 points when the render
/// carries f64 OPLs, else `f32_len` (the kernel's own length, with whatever f32 rounding and
/// ray-origin offset it carries) widened.
#[inline]
pub fn segment(ctx: &RenderContext, a: DVec3, b: DVec3, f32_len: f32) -> f64 {
    if ctx.opl.f64_paths {
        (b - a).length()
    } else {
        f32_len as f64
    }
}

/// Where the line o + t·dir meets the plane of triangle `prim`, in f64 (the origin when they
/// are parallel). For a path constrained to pass through a given point (a boundary segment
/// through x_B, Algorithm 2), whose vertex the renderer found with a ray offset from that
/// point by the self-intersection ε: the vertex on the constrained line itself.
#[inline]
pub fn on_plane64(ctx: &RenderContext, prim: u32, o: DVec3, dir: DVec3) -> DVec3 {
    let [p0, p1, p2] = ctx.tri_verts[prim as usize].map(|p| p.as_dvec3());
    let n = (p1 - p0).cross(p2 - p0);
    let t = n.dot(p0 - o) / n.dot(dir);
    if t.is_finite() { o + dir * t } else { o }
}

/// Every lane's hit point in f64 (`prim == u32::MAX` lanes get the origin; callers mask them).
#[inline]
pub fn points64(ctx: &RenderContext, lanes: usize, prim: &[u32; 8], u: &[f32], v: &[f32]) -> [DVec3; 8] {
    let mut out = [DVec3::ZERO; 8];
    for i in 0..lanes {
        if prim[i] != u32::MAX {
            out[i] = point64(ctx, prim[i], u[i], v[i]);
        }
    }
    out
}
