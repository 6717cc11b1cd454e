//! Surface points rebuilt from plain hits.
//!
//! Embree reports `(t, primitive, u, v)`. The kernel rebuilds `x = p0 + u·(p1 − p0) + v·(p2 − p0)`
//! from the mesh in its own number type. With dual numbers, the vertices carry their velocity
//! under each parameter and `u, v` stay fixed: path vertices move with the surface (the
//! material-form parameterisation of Algorithm 1), and the area Jacobian J is the ratio of
//! the moved triangle's area to its area at the current parameters.

use super::context::RenderContext;
use crate::kernel::{Real, V3};
use glam::Vec3;

/// A surface point in the kernel's number type.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint<R: Real> {
    pub p: V3<R>,
    /// Unit geometric normal (front side by the triangle's winding).
    pub n: V3<R>,
    /// Area Jacobian J = |dA(θ)| / |dA(θ₀)| (1 for plain numbers).
    pub jacobian: R,
    pub prim: [u32; 8],
}

/// The three vertices of triangle `prim` per lane, with their velocity under each parameter
/// as derivative lanes. Lanes with `prim == u32::MAX` get triangle 0.
#[inline]
fn gather_triangle<R: Real>(ctx: &RenderContext, prim: &[u32; 8]) -> [V3<R>; 3] {
    let last = ctx.tri_verts.len() as u32 - 1;
    let mut pos = [[Vec3::ZERO; 8]; 3];
    for i in 0..R::LANES {
        let tri = &ctx.tri_verts[prim[i].min(last) as usize];
        for c in 0..3 {
            pos[c][i] = tri[c];
        }
    }
    std::array::from_fn(|c| {
        let mut v = V3::<R>::from_lane_vecs(&pos[c][..R::LANES]);
        for k in 0..R::DERIVS {
            let mut vel = [[0.0f32; 8]; 3];
            for i in 0..R::LANES {
                let t = prim[i].min(last) as usize;
                let w = ctx
                    .motion
                    .velocity(k, ctx.scene.geometry.tri_shape[t] as usize, pos[c][i]);
                vel[0][i] = w.x;
                vel[1][i] = w.y;
                vel[2][i] = w.z;
            }
            v.x = v.x.with_deriv_lanes(k, &vel[0]);
            v.y = v.y.with_deriv_lanes(k, &vel[1]);
            v.z = v.z.with_deriv_lanes(k, &vel[2]);
        }
        v
    })
}

/// Rebuilds the surface point at barycentrics (u, v) of `prim` in every lane. Lanes with
/// `prim == u32::MAX` get triangle 0 (callers mask them out).
pub fn surface_at<R: Real>(ctx: &RenderContext, prim: &[u32; 8], u: R::Value, v: R::Value) -> SurfacePoint<R> {
    let [p0, p1, p2] = gather_triangle::<R>(ctx, prim);
    let e1 = p1 - p0;
    let e2 = p2 - p0;
    let p = p0 + e1 * R::from_value(u) + e2 * R::from_value(v);
    let c = e1.cross(e2);
    let area2 = c.length();
    let n = c * R::safe_div(R::one(), area2);
    let jacobian = if R::DERIVS > 0 {
        R::safe_div(area2, R::from_value(area2.value()))
    } else {
        R::one()
    };
    SurfacePoint {
        p,
        n,
        jacobian,
        prim: *prim,
    }
}

/// A ray origin offset from `p` off the surface, to the side of `dir`: scaled by the
/// coordinate magnitude so that scenes far from the origin stay self-intersection free.
#[inline(always)]
pub fn offset_origin<V: Real>(p: &V3<V>, n: &V3<V>, dir: &V3<V>) -> V3<V> {
    let eps = self_intersection_eps(p);
    let side = V::select(n.dot(*dir).ge(V::zero()), eps, -eps);
    p.add_scaled(*n, side)
}

/// 2⁻¹⁸ (≈3.8e-6, 32 f32 ulps) of the largest coordinate, at least 3.8e-6 m: f32 barycentric
/// reconstruction is accurate to a few ulps of the coordinates.
#[inline(always)]
pub fn self_intersection_eps<V: Real>(p: &V3<V>) -> V {
    let m = p.x.abs().max(p.y.abs()).max(p.z.abs()).max(V::one());
    m * V::splat(1.0 / 262_144.0)
}
