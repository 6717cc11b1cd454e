//! Subpath vertices and the area-measure pdfs that link them (Veach 1997, §10.2; the
//! `pdfFwd` / `pdfRev` bookkeeping of pbrt-v4's BDPT, `src/pbrt/cpu/integrators.h`).
//!
//! Delta flags: pbrt-v4 marks vertices scattered by a specular lobe (`delta`) and lights that
//! are deltas in position (`IsDeltaLight`). Here [`Vertex::delta`] marks the lanes whose
//! material is a Dirac lobe (smooth conductor or dielectric): the walk continues through them
//! by sampling the lobe, stores 0 as the area density of the vertex it reaches (`pdf_fwd`)
//! and of the one it came from (`pdf_rev`, from `Lobes::pdf`, zero on delta lanes), and no
//! connection ends there (f is zero towards any other point). The light origin's flag is
//! [`super::walk::LightOrigin::delta`] (point lights, laser spots). Zero (delta) densities are
//! remapped to 1 in the MIS ratios as pbrt's `MISWeight` does ([`super::mis`]). A vertex
//! where the subpath refracted cannot be a connection's end either (connections leave on the
//! arrival side), which `transmitted` records; both feed [`super::mis::allowed_through`].
//!
//! Materials beyond Lambertian: a vertex's f and direction density depend on both of its
//! neighbours, so they are evaluated where both are known, from the vertex's material
//! (`Lobes::gather` on its triangle) and the true normal (`n` turned back by `front`):
//! [`scatter_area_pdf`] here, `f` at connections in `connect.rs` and `splat.rs`.
//!
//! Each vertex holds eight lanes (one subpath per lane). `pdf_fwd` is the area density with
//! which the subpath's own walk generated the vertex, `pdf_rev` the density with which the
//! other direction would generate it. The MIS weights ([`super::mis`]) read only these values;
//! derivatives never flow through them (the weights are constants for differentiation, as in
//! the paper's Algorithm 1).

use crate::integrator::trace::SegmentEnd;
use crate::kernel::{Mask, Real, Spectrum, V3};
use std::f32::consts::{FRAC_1_PI, PI};

type V<R> = <R as Real>::Value;

/// One vertex of a camera or light subpath, per lane.
#[derive(Clone, Copy, Debug)]
pub struct Vertex<R: Real, const C: usize> {
    pub p: V3<R>,
    /// Unit normal turned to the side the subpath arrived from (surface vertices) or to the
    /// emitting side (light origin on a surface); zero for point-like vertices.
    pub n: V3<R>,
    /// Lanes whose vertex lies on a surface (a cosine applies there).
    pub on_surface: R::Mask,
    /// Lanes that arrived on the winding-front side (area emitters emit only there).
    pub front: R::Mask,
    /// Lanes whose vertex is a light origin with a uniform (point-light) direction density.
    pub uniform_sphere: R::Mask,
    /// Throughput up to this vertex, divided by the sampling pdfs (pbrt's `beta`).
    pub beta: Spectrum<R, C>,
    /// BSDF value albedo/π at surface vertices; 1 at a light origin (its emission is in
    /// `beta`).
    pub f: Spectrum<R, C>,
    pub pdf_fwd: V<R>,
    pub pdf_rev: V<R>,
    /// The derivative carrier of this vertex's material-form motion that `beta` holds:
    /// `[G·J]_dual / [G]_value` of the segment that reached it (value 1; exactly 1 for the
    /// ray-form first camera vertex, light origins and plain numbers). Light tracing
    /// (`splat.rs`) divides it out to move the vertex along its camera ray instead.
    pub geo: R,
    /// Optical path length from the subpath's start to this vertex.
    pub opl: R,
    /// Index of the medium crossed by the segment that reached this vertex (the scene's η at
    /// a subpath's start); a connection leaves on the arrival side, so it crosses it too.
    pub eta_in: R,
    /// Lanes whose subpath refracted here (see the module docs).
    pub transmitted: R::Mask,
    /// Lanes whose material here is a Dirac lobe (see the module docs).
    pub delta: R::Mask,
    /// The point and `opl` per lane in f64 (see `integrator::opl`); kept only when the render
    /// carries f64 OPLs (`ctx.opl.f64_paths`), else zero.
    pub p64: [glam::DVec3; 8],
    pub opl64: [f64; 8],
    pub prim: [u32; 8],
    pub alive: R::Mask,
}

/// Solid-angle density of the direction from `v` towards `to` under `v`'s own sampling:
/// cos/π on the lit side of a surface (diffuse BSDF and area/laser-spot emission), 1/(4π) at
/// a point light.
#[inline(always)]
pub fn dir_pdf<R: Real, const C: usize>(v: &Vertex<R, C>, to: &V3<V<R>>) -> V<R> {
    let w = (*to - v.p.value()).normalize();
    let cos = v.n.value().dot(w);
    let surface = cos.abs().mul_f(FRAC_1_PI);
    let surface = V::<R>::select(v.on_surface, surface, V::<R>::splat(0.25 / PI));
    V::<R>::select(v.uniform_sphere, V::<R>::splat(0.25 / PI), surface)
}

/// Turns a solid-angle density at `from` into an area density at `to`: ·|cos θ_to| / r²
/// (no cosine at point-like vertices).
#[inline(always)]
pub fn to_area<R: Real, const C: usize>(from: &V3<V<R>>, to: &Vertex<R, C>, pdf_dir: V<R>) -> V<R> {
    let d = *from - to.p.value();
    let r2 = d.length_squared();
    let cos = V::<R>::select(
        to.on_surface,
        to.n.value().dot(d).abs() * V::<R>::safe_div(V::<R>::one(), r2.sqrt()),
        V::<R>::one(),
    );
    V::<R>::safe_div(pdf_dir * cos, r2)
}

/// Area density of generating `to` from `from` by `from`'s own direction sampling.
#[inline(always)]
pub fn area_pdf<R: Real, const C: usize>(from: &Vertex<R, C>, to: &Vertex<R, C>) -> V<R> {
    to_area(&from.p.value(), to, dir_pdf(from, &to.p.value()))
}

/// Area density at `to` of the direction that surface vertex `v`, reached from `from`, samples
/// towards `to` (its BSDF's density; the diffuse one when every material is). Light origins
/// and the pinhole keep [`area_pdf`], and so does every vertex without a render context (the
/// MIS unit tests).
#[inline]
pub fn scatter_area_pdf<R: Real, const C: usize>(
    ctx: Option<&crate::integrator::context::RenderContext>,
    v: &Vertex<R, C>,
    from: &V3<V<R>>,
    to: &Vertex<R, C>,
) -> V<R> {
    let Some(ctx) = ctx.filter(|c| !c.diffuse_only) else {
        return area_pdf(v, to);
    };
    let lobes = crate::integrator::bsdf::Lobes::<V<R>, C>::gather(ctx, &v.prim);
    let p = v.p.value();
    let wo = (*from - p).normalize();
    let wi = (to.p.value() - p).normalize();
    to_area(&p, to, lobes.pdf(&v.true_normal(), &wo, &wi))
}

impl<R: Real, const C: usize> Vertex<R, C> {
    /// The surface's own normal (as built from its winding), which the material's inside and
    /// outside refer to: `n` turned back where the subpath arrived from behind.
    #[inline(always)]
    pub fn true_normal(&self) -> V3<V<R>> {
        let n = self.n.value();
        V3::select(self.front, n, -n)
    }

    /// f at this surface vertex for light between directions towards `a` (unit, dual) and
    /// `b`: f(a, b) in radiance transport (`radiance`: `a` towards the camera) or importance
    /// transport. The stored diffuse `f` when every material is diffuse.
    #[inline]
    pub fn f_between(
        &self,
        ctx: &crate::integrator::context::RenderContext,
        a: &V3<R>,
        b: &V3<R>,
        radiance: bool,
    ) -> Spectrum<R, C> {
        if ctx.diffuse_only {
            return self.f;
        }
        let lobes = crate::integrator::bsdf::Lobes::<R, C>::gather(ctx, &self.prim);
        let n = V3::select(self.front, self.n, -self.n);
        lobes.eval(&n, a, b, radiance)
    }
}

/// The pinhole's direction density towards film point u for pixel j, relative to the light
/// subpaths: h_j(u) / (a cos³θ) / N. One light subpath is traced per camera subpath, so each
/// pixel receives N (pixels) times as many light-tracing samples as camera samples; dividing
/// the camera density by N is Veach's sample-count weighting (1997, Eq. 9.11).
#[inline(always)]
pub fn camera_dir_pdf<V: Real>(h: V, importance: V, pixels: f32) -> V {
    (h * importance).mul_f(1.0 / pixels)
}

/// Records that `next` was reached from `cur` by sampling a direction with solid-angle
/// density `pdf_dir` (one walk step): `next.pdf_fwd` is that density in area measure, and
/// `cur.pdf_rev` the area density with which `next`'s own sampling would generate `cur`.
/// The diffuse BSDF's density does not depend on the incoming direction, so `cur.pdf_rev`
/// is final as soon as `next` exists.
#[inline(always)]
pub fn link<R: Real, const C: usize>(cur: &mut Vertex<R, C>, next: &mut Vertex<R, C>, pdf_dir: V<R>) {
    next.pdf_fwd = to_area(&cur.p.value(), next, pdf_dir);
    cur.pdf_rev = area_pdf(next, cur);
}

impl<R: Real, const C: usize> Vertex<R, C> {
    /// A point-like vertex at `p` (the camera or a point light) with throughput `beta`.
    pub fn point(p: V3<R>, beta: Spectrum<R, C>, alive: R::Mask) -> Self {
        let no = R::Mask::from_bools(&[false; 8][..R::LANES]);
        // camera and point-light positions are f32 values: exact in f64
        let pv = p.value();
        let p64 = std::array::from_fn(|i| {
            if i < R::LANES {
                glam::DVec3::new(pv.x.lane(i) as f64, pv.y.lane(i) as f64, pv.z.lane(i) as f64)
            } else {
                glam::DVec3::ZERO
            }
        });
        Self {
            p,
            p64,
            opl64: [0.0; 8],
            n: V3::zero(),
            on_surface: no,
            front: no,
            uniform_sphere: no,
            beta,
            f: Spectrum::splat(R::one()),
            pdf_fwd: V::<R>::zero(),
            pdf_rev: V::<R>::zero(),
            geo: R::one(),
            opl: R::zero(),
            eta_in: R::one(),
            transmitted: no,
            delta: no,
            prim: [u32::MAX; 8],
            alive,
        }
    }
}

/// Vertex `k` of a subpath as one end of a shadow segment: its position, its normal (zero at
/// point-like vertices) and the direction along which the subpath reached it (zero at the
/// subpath's start).
#[inline(always)]
pub fn segment_end<R: Real, const C: usize>(path: &[Vertex<R, C>], k: usize) -> SegmentEnd<V<R>> {
    let v = &path[k];
    let w_in = if k == 0 {
        V3::zero()
    } else {
        (v.p.value() - path[k - 1].p.value()).normalize()
    };
    SegmentEnd {
        p: v.p.value(),
        n: V3::select(v.on_surface, v.n.value(), V3::zero()),
        w_in,
    }
}
