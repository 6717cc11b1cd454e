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
use crate::scene::Scene;
use crate::temporal::{Gate, Pulse};
use glam::DVec3;

/// Whether a render carries f64 OPLs, and why (written to the run JSON).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct OplPrecision {
    /// True: each lane's OPL is also summed in f64 from f64 hit points.
    pub f64_paths: bool,
    /// The finest time scale of the film, OPL metres: the smallest of the bin width, the
    /// pulse widths (σ of a Gaussian, width of a box) and a Gaussian gate's σ.
    pub time_scale_opl: f64,
    /// One f32 step (ulp) at the largest magnitude an OPL or a coordinate reaches: the ends
    /// of the time axis, the scene's coordinates and the camera's.
    pub f32_step_opl: f64,
}

impl OplPrecision {
    /// f64 paths when the film's finest time scale is under [`Self::MIN_STEPS`] f32 steps: a
    /// path of up to ~10 segments, each rounded by a few steps, then stays well under 1% of
    /// the time scale in f32. The Cornell box (0.06 m bins, OPL to 15.6 m: 6·10⁴ steps) stays
    /// f32; 1 mm bins at 4 m (2·10³ steps) or a 3 nm pulse go f64.
    pub fn choose(scene: &Scene) -> Self {
        let axis = &scene.film.axis;
        let mut scale = axis.bin_width_opl;
        if let Gate::Gaussian { sigma_opl } = scene.film.gate {
            scale = scale.min(sigma_opl as f64);
        }
        let mut magnitude = axis.start_opl.abs().max(axis.end_opl().abs());
        for e in &scene.emitters {
            match e.pulse {
                Pulse::Delta => {}
                Pulse::Gaussian { sigma_opl } => scale = scale.min(sigma_opl as f64),
                Pulse::Box { width_opl } => scale = scale.min(width_opl as f64),
            }
            magnitude = magnitude.max(e.offset_opl.abs());
        }
        for p in scene.geometry.positions.iter().chain([&scene.camera.position]) {
            magnitude = magnitude.max(p.abs().max_element() as f64);
        }
        let step = f32_step(magnitude);
        Self {
            f64_paths: scale < Self::MIN_STEPS * step,
            time_scale_opl: scale,
            f32_step_opl: step,
        }
    }

    /// f32 steps per finest time scale below which paths carry f64 OPLs.
    pub const MIN_STEPS: f64 = 4096.0;
}

/// The distance between consecutive f32 values at magnitude `m` (at least that of 1).
fn f32_step(m: f64) -> f64 {
    let m = (m as f32).max(1.0);
    (f32::from_bits(m.to_bits() + 1) - m) as f64
}

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

#[cfg(test)]
mod tests {
    use super::f32_step;

    #[test]
    fn f32_steps() {
        assert_eq!(f32_step(4.0), 2f64.powi(-21));
        assert_eq!(f32_step(3.9), 2f64.powi(-22));
        assert_eq!(f32_step(0.01), 2f64.powi(-23));
        assert_eq!(f32_step(1.0e5), 2f64.powi(-7));
    }
}
