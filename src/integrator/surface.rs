//! Surface points rebuilt from plain hits.
//!
//! Embree reports `(t, primitive, u, v)`. The kernel rebuilds `x = p0 + u·(p1 − p0) + v·(p2 − p0)`
//! from the mesh in its own number type. With dual numbers, the vertices carry their velocity
//! under each parameter and `u, v` stay fixed: path vertices move with the surface (the
//! material-form parameterisation of Algorithm 1), and the area Jacobian J is the ratio of
//! the moved triangle's area to its area at the current parameters.

use super::context::RenderContext;
use crate::kernel::{Mask, Real, V3};
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

/// The lanes of `active` whose vertex (triangle `prim`, unit normal `n`) was reached along
/// `w_in` from the back of a one-sided material (`NamedMaterial::one_sided`): black there, as
/// a Mitsuba BSDF without `twosided`, so every path through it ends. Emission is one-sided
/// already, and the same sides hold whichever end a path is traced from, so the path tracer,
/// both subpaths of BDPT and the boundary stage's walks drop the same paths.
pub fn behind_one_sided<V: Real>(
    ctx: &RenderContext,
    prim: &[u32; 8],
    n: &V3<V>,
    w_in: &V3<V>,
    active: V::Mask,
) -> V::Mask {
    if !ctx.any_one_sided {
        return V::Mask::splat(false);
    }
    let materials = &ctx.scene.materials;
    let mut listed = [false; 8];
    for i in (0..V::LANES).filter(|&i| active.bit(i) && prim[i] != u32::MAX) {
        listed[i] = materials[ctx.tri_material[prim[i] as usize] as usize].one_sided;
    }
    active & V::Mask::from_bools(&listed[..V::LANES]) & n.dot(*w_in).gt(V::zero())
}

/// A ray origin offset from `p` off the surface, to the side of `dir`: scaled by the
/// coordinate magnitude so that scenes far from the origin stay self-intersection free
/// (`scale`: the scene's offset scale, [`self_intersection_eps`]).
#[inline(always)]
pub fn offset_origin<V: Real>(p: &V3<V>, n: &V3<V>, dir: &V3<V>, scale: f32) -> V3<V> {
    let eps = self_intersection_eps(p, scale);
    let side = V::select(n.dot(*dir).ge(V::zero()), eps, -eps);
    p.add_scaled(*n, side)
}

/// The ray offset off a surface as a fraction of the coordinates there ([`self_intersection_eps`]):
/// 2⁻¹⁸, 32 f32 ulps.
pub const OFFSET_PER_COORDINATE: f32 = 1.0 / 262_144.0;

/// 2⁻¹⁸ (32 f32 ulps, [`OFFSET_PER_COORDINATE`]) of the largest coordinate, taken at least
/// `scale` (the scene's offset scale, `Scene::offset_scale`: 1 m, or the extent of a smaller
/// scene), so at least 3.8e-6 m in a room: f32 barycentric reconstruction is accurate to a few
/// ulps of the coordinates. A fixed floor of 1 m made the offset 0.2 % of a 2 mm scene, which
/// biased its boundary derivatives by 1.6 %.
#[inline(always)]
pub fn self_intersection_eps<V: Real>(p: &V3<V>, scale: f32) -> V {
    let m = p.x.abs().max(p.y.abs()).max(p.z.abs()).max(V::splat(scale));
    m * V::splat(OFFSET_PER_COORDINATE)
}

/// The lanes of a connection of length `dist` between two surface points (`p` either end)
/// whose cosines `cos_a`, `cos_b` at its ends stand above their rounding error. Each end is
/// rebuilt to within about [`self_intersection_eps`] ε (barycentrics in f32), so the direction
/// between them, and each cosine, is known to about ε / `dist`: a smaller cosine cannot be
/// told from a grazing one, and G = cos_a·cos_b / dist² would be that rounding noise
/// amplified by 1/dist². A path vertex on a curved relay wall 0.12 mm from a laser spot on it
/// (true cosines about 10⁻⁴) took G from cosines of rounding alone: 0.8 in the plain kernel and
/// 275 in the dual one on the same path, one sample holding twice the transient's energy.
/// The lanes left out carry G < (ε/dist)/dist² on connections that graze one end: a set of
/// paths that vanishes as ε does (a disc of radius of order √(ε·R) around the point on a
/// surface of curvature radius R, cosines below ε/dist elsewhere), far below the Monte Carlo
/// noise. Pass `V::one()` for a point with no surface (a point light).
#[inline(always)]
pub fn resolvable<V: Real>(p: &V3<V>, scale: f32, cos_a: V, cos_b: V, dist: V) -> V::Mask {
    let noise = self_intersection_eps(p, scale) * V::safe_div(V::one(), dist);
    cos_a.abs().min(cos_b.abs()).gt(noise)
}

/// `[G]_dual / [G]_value` of a traced segment of squared length `r2` from `p` (either end),
/// G = |cos_a|·|cos_b| / r²: value 1, and the derivative of the segment's geometry term
/// relative to its value (Algorithm 1's area-form throughput). Where a cosine stands below
/// its rounding ([`resolvable`]), its value is rounding noise, and the relative derivative
/// ċos/cos that noise amplified without bound: a path on a floor within ε of the plane of a
/// box's face resting on it, bouncing to that face, carried a derivative of 10¹² in one
/// sample (a 0.3 m cube at contact, 2 of 1500 renders at 64 spp). Those lanes keep the value
/// and take no derivative from the segment: they are the vertices within about ε of the
/// other end's plane, whose true relative derivatives average out over the directions that
/// reach it (the face's irradiance at a point a from its plane changes as a log, not as 1/a).
#[inline(always)]
pub fn geometry_ratio<R: Real>(p: &V3<R::Value>, scale: f32, cos_a: R, cos_b: R, r2: R) -> R {
    let g = cos_a.abs() * cos_b.abs() / r2;
    let clear = resolvable(p, scale, cos_a.value(), cos_b.value(), r2.value().sqrt());
    R::select(clear, R::safe_div(g, R::from_value(g.value())), R::one())
}

#[cfg(test)]
mod tests {
    use super::surface_at;
    use crate::accel::Device;
    use crate::integrator::RenderContext;
    use crate::integrator::testutil::{POSED, POSED_PARAMS, load, param_names, positions_either_side, step};
    use crate::kernel::{Dual8, Real, V3, f32x8};
    use crate::params::lanes::Motion;
    use crate::scene::{ParamKind, Scene};
    use glam::{DVec3, Vec3};

    type D = Dual8<POSED_PARAMS>;

    /// (point at barycentrics (u, v), unit normal, area) of triangle `t` with vertex positions
    /// `pos`, in f64.
    fn triangle(scene: &Scene, pos: &[Vec3], t: u32, u: f32, v: f32) -> (DVec3, DVec3, f64) {
        let [a, b, c] = scene.geometry.indices[t as usize].map(|i| pos[i as usize].as_dvec3());
        let cr = (b - a).cross(c - a);
        (
            a + (b - a) * u as f64 + (c - a) * v as f64,
            cr.normalize(),
            0.5 * cr.length(),
        )
    }

    /// Derivative lane `k` of lane `i` of a vector.
    fn deriv(v: &V3<D>, k: usize, i: usize) -> DVec3 {
        DVec3::new(
            v.x.deriv_lane(k, i) as f64,
            v.y.deriv_lane(k, i) as f64,
            v.z.deriv_lane(k, i) as f64,
        )
    }

    /// d ln(area)/d s_k of a triangle with local vertices `l` under the scale S of its shape,
    /// in closed form: the world cross product is R·cof(S)·(local cross product), cof(S) =
    /// diag(s_y s_z, s_x s_z, s_x s_y), so |c|² = Σ_m (cof_m c_m)² and each term but the k-th
    /// is linear in s_k.
    fn scale_log_rate(l: [DVec3; 3], s: DVec3, k: usize) -> f64 {
        let c = (l[1] - l[0]).cross(l[2] - l[0]);
        let cof = DVec3::new(s.y * s.z, s.x * s.z, s.x * s.y) * c;
        let others: f64 = (0..3).filter(|&m| m != k).map(|m| cof[m] * cof[m]).sum();
        others / (s[k] * cof.length_squared())
    }

    /// `surface_at` with dual numbers, eight lanes on eight triangles of both shapes of
    /// [`POSED`] (the mirrored plate among them), against the loader's geometry a step either
    /// side of every parameter:
    /// - J = 1 at the current parameters, and ∂J/∂θ = the central difference of the
    ///   triangle's area over its area: 0 under translation and rotation (rigid motions),
    ///   d ln A/d s_k in closed form under scale (1/s_k for a face containing axis k, negative
    ///   for the mirrored plate's s_x < 0);
    /// - ∂x/∂θ and ∂n/∂θ = the central differences of the point at the same (u, v) and of
    ///   the unit normal.
    ///
    /// Bugs caught: J of the wrong form (|dA(θ₀)|/|dA(θ)|, a missing normalisation, the sign
    /// of a mirrored triangle's area), velocities gathered for the wrong vertex, shape or lane,
    /// a normal whose derivative ignores the renormalisation, and any velocity that is not
    /// the motion of the loader's geometry.
    #[test]
    fn area_jacobian_point_and_normal_match_finite_differences() {
        let scene = load(POSED, &[]);
        let device = Device::new("").unwrap();
        let mut ctx = RenderContext::new(&scene, &device).unwrap();
        ctx.motion = Motion::build(&scene, &param_names(&scene)).unwrap();
        assert_eq!(scene.params.len(), POSED_PARAMS);
        // box: triangles 0..12, plate: 12, 13
        let prims: [u32; 8] = [0, 3, 5, 6, 8, 11, 12, 13];
        let us = [0.2f32, 0.1, 0.6, 0.3, 0.25, 0.05, 0.4, 0.15];
        let vs = [0.3f32, 0.7, 0.1, 0.3, 0.5, 0.9, 0.2, 0.6];
        let sp = surface_at::<D>(&ctx, &prims, f32x8::from(us), f32x8::from(vs));
        let pos = &scene.geometry.positions;
        let eps = f32::EPSILON as f64;
        for (k, p) in scene.params.iter().enumerate() {
            let h = step(&p.kind);
            let [minus, plus] = positions_either_side(POSED, &scene, k, h);
            for (i, &t) in prims.iter().enumerate() {
                let (x0, _, a0) = triangle(&scene, pos, t, us[i], vs[i]);
                let (xm, nm, am) = triangle(&scene, &minus, t, us[i], vs[i]);
                let (xp, np, ap) = triangle(&scene, &plus, t, us[i], vs[i]);
                let at = format!("param {} ({:?}), lane {i}, triangle {t}", p.name, p.kind);
                // area/area through the dual division's a·(1/b): 1 to an ulp
                let j = sp.jacobian.lane(i);
                assert!((j - 1.0).abs() <= f32::EPSILON, "{at}: J at θ₀ is {j}");
                // f32 rounding of the loaded vertices (≤ 2⁻²⁴·|x| per coordinate) moves the
                // area by up to |x|·ε·perimeter and the normal by |x|·ε·perimeter/(2A); a
                // central difference divides those by h. The dual lanes are f32 sums of
                // products of O(1) terms: a few ulps.
                let [va, vb, vc] = scene.geometry.indices[t as usize].map(|j| pos[j as usize].as_dvec3());
                let size = va.abs().max(vb.abs()).max(vc.abs()).max_element().max(1.0);
                let perimeter = (vb - va).length() + (vc - vb).length() + (va - vc).length();
                let area_noise = size * eps * perimeter / a0 / h + 1e-5;
                let point_noise = size * eps * 3f64.sqrt() / h + 1e-5;
                let jd = sp.jacobian.deriv_lane(k, i) as f64;
                let j_fd = (ap - am) / (2.0 * h * a0);
                assert!(
                    (jd - j_fd).abs() <= 1e-3 * j_fd.abs() + area_noise,
                    "{at}: dJ {jd} vs central difference {j_fd} (noise {area_noise:.1e})"
                );
                let s = scene.geometry.tri_shape[t as usize];
                let shape = &scene.shapes[s as usize];
                let exact = match p.kind {
                    ParamKind::Scale { shape: moved, axis } if moved == s => {
                        let local = scene.geometry.indices[t as usize]
                            .map(|j| shape.local_positions[(j - shape.first_vertex) as usize].as_dvec3());
                        scale_log_rate(local, shape.transform.scale.as_dvec3(), axis as usize)
                    }
                    _ => 0.0,
                };
                assert!(
                    (jd - exact).abs() <= 1e-4 * exact.abs().max(1.0),
                    "{at}: dJ {jd}, closed form {exact}"
                );
                let xd = deriv(&sp.p, k, i);
                let x_fd = (xp - xm) / (2.0 * h);
                assert!(
                    (xd - x_fd).length() <= 1e-3 * x_fd.length() + point_noise,
                    "{at}: dx {xd} vs central difference {x_fd}"
                );
                assert!((sp.p.lane(i).as_dvec3() - x0).length() <= 4.0 * size * eps, "{at}: x");
                let nd = deriv(&sp.n, k, i);
                let n_fd = (np - nm) / (2.0 * h);
                assert!(
                    (nd - n_fd).length() <= 1e-3 * n_fd.length() + area_noise,
                    "{at}: dn {nd} vs central difference {n_fd}"
                );
            }
        }
    }
}
