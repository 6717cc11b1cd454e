//! Plain rays of the boundary stage: the boundary ray's two ends x_S and x_L (`contact.rs`),
//! traced one at a time, and the length a light sample travelled before its point.

use crate::integrator::context::RenderContext;
use crate::integrator::emitters::LightSample;
use crate::integrator::opl::point64;
use crate::integrator::trace::RayCounts;
use glam::{DVec3, Vec3};

/// A surface point found by a plain ray.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    pub p: Vec3,
    /// `p` in f64: rebuilt from Embree's barycentrics when the render carries f64 OPLs
    /// (`integrator::opl::point64`), else `p` widened.
    pub p64: DVec3,
    /// Unit geometric normal (winding order).
    pub n: Vec3,
    pub prim: u32,
    /// Distance from the ray origin.
    pub t: f32,
}

/// Closest hit of the ray `o + t·d` (d unit), t ∈ (0, ∞).
pub fn trace(ctx: &RenderContext, o: Vec3, d: Vec3, counts: &mut RayCounts) -> Option<SurfaceHit> {
    trace_past(ctx, o, d, 0.0, counts)
}

/// Closest hit of the ray `o + t·d` (d unit) with t ≥ `t_near`.
pub fn trace_past(ctx: &RenderContext, o: Vec3, d: Vec3, t_near: f32, counts: &mut RayCounts) -> Option<SurfaceHit> {
    let t0 = counts.clock.start();
    counts.intersect += 1;
    let hit = ctx.accel.intersect1(o.to_array(), d.to_array(), t_near, f32::INFINITY);
    counts.trace_ticks += counts.clock.stop(t0);
    let h = hit?;
    let [p0, p1, p2] = ctx.tri_verts[h.prim as usize];
    let p = p0 + (p1 - p0) * h.u + (p2 - p0) * h.v;
    Some(SurfaceHit {
        p,
        p64: if ctx.opl.f64_paths {
            point64(ctx, h.prim, h.u, h.v)
        } else {
            p.as_dvec3()
        },
        n: ctx.face_normal(h.prim),
        prim: h.prim,
        t: h.t,
    })
}

/// The length travelled before a light sample's point (laser to spot, else 0), in f64 when the
/// render carries f64 OPLs.
pub fn pre_length(ctx: &RenderContext, ls: &LightSample<f32, 3>) -> f64 {
    if ctx.opl.f64_paths {
        ls.pre64[0]
    } else {
        ls.pre_length as f64
    }
}
