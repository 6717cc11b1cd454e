//! The two ends of a boundary path (Algorithm 2: EstimateSourceSubpath, EstimateSensorSubpath),
//! plain `f32`, no derivatives: unbiased estimates of the radiance leaving x_L towards x_S and
//! of the importance arriving at x_S from x_L, each split into terms with their own optical
//! path length (so that S_e bins every full path at its own d).
//!
//! Both use the interior's conventions (integrator/path.rs): two-sided Lambertian reflection
//! on the side light arrives from, one-sided area emitters, next-event estimation with the
//! power heuristic (Veach 1997, Eq. 9.13) against BSDF-sampled emission, and a path has at
//! most `max_bounces` scattering vertices.
//!
//! Optical path lengths are f64: when the render carries f64 OPLs (`integrator::opl`), each
//! segment is measured between points rebuilt in f64 from Embree's barycentrics (a narrow
//! pulse's S_e, supplemental Eq. 24, would otherwise see f32 lengths quantised to ~10⁻⁷ m).

use crate::integrator::bsdf::sample_cosine;
use crate::integrator::context::RenderContext;
use crate::integrator::emitters::LightSample;
use crate::integrator::opl::{point64, segment};
use crate::integrator::power_heuristic;
use crate::integrator::surface::{offset_origin, self_intersection_eps};
use crate::integrator::trace::RayCounts;
use crate::kernel::{PathSampler, V3};
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
    trace_within(ctx, o, d, f32::INFINITY, counts)
}

/// Closest hit of the ray `o + t·d` (d unit), t ∈ (0, t_far).
fn trace_within(ctx: &RenderContext, o: Vec3, d: Vec3, t_far: f32, counts: &mut RayCounts) -> Option<SurfaceHit> {
    if !(t_far > 0.0) {
        return None;
    }
    let t0 = crate::timing::ticks();
    counts.intersect += 1;
    let hit = ctx.accel.intersect1(o.to_array(), d.to_array(), 0.0, t_far);
    counts.trace_ticks += crate::timing::ticks() - t0;
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
        n: (p1 - p0).cross(p2 - p0).normalize_or_zero(),
        prim: h.prim,
        t: h.t,
    })
}

/// Whether nothing blocks the segment from `x` (on a surface of normal `n`) to `target`.
pub fn visible(ctx: &RenderContext, x: Vec3, n: Vec3, target: Vec3, counts: &mut RayCounts) -> bool {
    let t0 = crate::timing::ticks();
    counts.occluded += 1;
    let to = target - x;
    let o = offset(x, n, to);
    let to_o = target - o;
    let len = to_o.length();
    let tfar = len - self_intersection_eps(&V3::<f32>::splat(target));
    let free = tfar > 0.0 && !ctx.accel.occluded1(o.to_array(), (to_o / len).to_array(), 0.0, tfar);
    counts.trace_ticks += crate::timing::ticks() - t0;
    free
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

/// How far a ray may go from a subpath of OPL `opl` before every path through its hit lands
/// past `budget` (+∞ without a cut); ≤ 0 once the subpath is past it.
fn t_far(budget: f64, opl: f64, eta: f64) -> f32 {
    ((budget - opl) / eta) as f32
}

/// `offset_origin` for one plain point.
fn offset(p: Vec3, n: Vec3, dir: Vec3) -> Vec3 {
    offset_origin::<f32>(&V3::splat(p), &V3::splat(n), &V3::splat(dir)).lane(0)
}

/// Samples a cosine-weighted direction on the `side` of x and traces it as far as `t_far`:
/// the next vertex and the direction and its solid-angle pdf, or None when the sample or the
/// ray goes nowhere. With a Lambertian BSDF the weight f·cos/pdf is the albedo, which the
/// caller multiplies in.
fn scatter(
    ctx: &RenderContext,
    sampler: &mut PathSampler,
    x: &SurfaceHit,
    side: Vec3,
    t_far: f32,
    counts: &mut RayCounts,
) -> Option<(SurfaceHit, Vec3, f32)> {
    let (b1, b2) = sampler.next2::<f32>();
    let (dir, pdf) = sample_cosine(&V3::splat(x.n), &V3::splat(side), b1, b2);
    let dir = dir.lane(0);
    if !(pdf > 0.0) {
        return None;
    }
    let y = trace_within(ctx, offset(x.p, x.n, dir), dir, t_far, counts)?;
    Some((y, dir, pdf))
}

/// The albedo of a diffuse triangle (the boundary stage refuses scenes with other materials:
/// `Motion::build`).
fn albedo(ctx: &RenderContext, prim: u32) -> [f32; 3] {
    ctx.scene.materials[ctx.tri_material[prim as usize] as usize]
        .material
        .tint()
}

fn mul(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    std::array::from_fn(|c| a[c] * b[c])
}

fn scale(a: [f32; 3], s: f32) -> [f32; 3] {
    a.map(|v| v * s)
}

/// One term of the source estimate: radiance `rgb` from `emitter`, optical length `opl` from
/// the emitter (pulse offsets excluded: S_e holds them) to x_L, `scatters` scattering vertices
/// (x_L included when it reflects).
#[derive(Clone, Copy, Debug)]
pub struct SourceTerm {
    pub rgb: [f32; 3],
    pub opl: f64,
    pub emitter: u32,
    pub scatters: u32,
}

/// Radiance leaving x_L in direction `out` (towards x_S): emission when x_L is on the front
/// of an area emitter (if `with_emission`), plus reflected light by next-event estimation and BSDF sampling over
/// at most `max_scatters` scattering vertices. Terms whose OPL would exceed `budget` (the
/// window cut, `integrator::window`: what the rest of the path may still add is ≥ 0) are
/// neither traced nor kept.
#[allow(clippy::too_many_arguments)]
pub fn source_subpath(
    ctx: &RenderContext,
    x_l: &SurfaceHit,
    out: Vec3,
    max_scatters: u32,
    with_emission: bool,
    budget: f64,
    sampler: &mut PathSampler,
    counts: &mut RayCounts,
    terms: &mut Vec<SourceTerm>,
) {
    let eta = ctx.scene.eta;
    let eta64 = eta as f64;
    let e = ctx.tri_emitter[x_l.prim as usize];
    if with_emission && e != u32::MAX && x_l.n.dot(out) > 0.0 {
        terms.push(SourceTerm {
            rgb: ctx.emitters.radiance(e),
            opl: 0.0,
            emitter: e,
            scatters: 0,
        });
    }
    let mut x = *x_l;
    let mut side = out;
    let mut beta = [1.0f32; 3];
    let mut opl = 0.0f64;
    for i in 1..=max_scatters {
        let alb = albedo(ctx, x.prim);
        let f = scale(alb, std::f32::consts::FRAC_1_PI);
        if f.iter().all(|&v| v == 0.0) {
            break;
        }
        // next-event estimation
        let (u0, u1) = sampler.next2::<f32>();
        let u2 = sampler.next::<f32>();
        let ls = ctx.emitters.sample::<f32, 3>(ctx, u0, u1, u2, true);
        let lp = ls.p.lane(0);
        let to = lp - x.p;
        let d2 = to.length_squared();
        let dist = d2.sqrt();
        let wl = to / dist;
        let cos_x = x.n.dot(wl);
        let cos_y = if ls.has_cos { -ls.n.lane(0).dot(wl) } else { 1.0 };
        let nee_opl = opl + eta64 * (segment(ctx, x.p64, ls.p64[0], dist) + pre_length(ctx, &ls));
        if ls.valid
            && cos_x * x.n.dot(side) > 0.0
            && cos_y > 0.0
            && d2 > 0.0
            && nee_opl <= budget
            && visible(ctx, x.p, x.n, lp, counts)
        {
            let p_bsdf = cos_x.abs() * std::f32::consts::FRAC_1_PI;
            let w = if ls.pdf_area > 0.0 {
                power_heuristic(ls.pdf_area * d2 / cos_y, p_bsdf)
            } else {
                1.0
            };
            let g = cos_x.abs() * cos_y / d2;
            let weight: [f32; 3] = ls.weight.0;
            terms.push(SourceTerm {
                rgb: scale(mul(mul(beta, f), weight), g * w),
                opl: nee_opl,
                emitter: ls.emitter[0],
                scatters: i,
            });
        }
        // BSDF sampling; emission found this way counts i scattering vertices
        beta = mul(beta, alb);
        let Some((y, dir, pdf)) = scatter(ctx, sampler, &x, side, t_far(budget, opl, eta64), counts) else {
            break;
        };
        opl += eta64 * segment(ctx, x.p64, y.p64, y.t);
        let ey = ctx.tri_emitter[y.prim as usize];
        let cos_y = y.n.dot(dir);
        if ey != u32::MAX && cos_y < 0.0 {
            let p_l = ctx.emitters.area_pdf(ey) * y.t * y.t / cos_y.abs();
            terms.push(SourceTerm {
                rgb: scale(mul(beta, ctx.emitters.radiance(ey)), power_heuristic(pdf, p_l)),
                opl,
                emitter: ey,
                scatters: i,
            });
        }
        x = y;
        side = -dir;
    }
}

/// One term of the sensor estimate: importance `rgb` (f_s·|cos|/r²·W_e without the pixel
/// filter) reaching film point (fx, fy), optical length `opl` from x_S to the camera,
/// `scatters` scattering vertices (x_S included). `direct`: x_S itself connects to the
/// camera, so it is the ray-form first vertex of Algorithm 1.
#[derive(Clone, Copy, Debug)]
pub struct SensorTerm {
    pub rgb: [f32; 3],
    pub opl: f64,
    pub fx: f32,
    pub fy: f32,
    pub scatters: u32,
    pub direct: bool,
}

/// Importance arriving at x_S from direction `-incoming` (light travels along `incoming`):
/// a connection to the pinhole from x_S and from each of up to `max_scatters − 1` further
/// cosine-sampled bounces. Terms whose OPL would exceed `budget` are neither traced nor kept
/// (as in [`source_subpath`]).
#[allow(clippy::too_many_arguments)]
pub fn sensor_subpath(
    ctx: &RenderContext,
    x_s: &SurfaceHit,
    incoming: Vec3,
    max_scatters: u32,
    budget: f64,
    sampler: &mut PathSampler,
    counts: &mut RayCounts,
    terms: &mut Vec<SensorTerm>,
) {
    let eta = ctx.scene.eta;
    let eta64 = eta as f64;
    let cam = ctx.camera.position;
    let mut x = *x_s;
    let mut side = -incoming;
    let mut beta = [1.0f32; 3];
    let mut opl = 0.0f64;
    for j in 1..=max_scatters {
        let alb = albedo(ctx, x.prim);
        if alb.iter().all(|&v| v == 0.0) {
            break;
        }
        let to_cam = cam - x.p;
        if let Some(pr) = ctx.camera.project(x.p) {
            let cos_x = x.n.dot(to_cam) / pr.dist2.sqrt();
            let cam_seg = if ctx.scene.film.unwarp {
                0.0
            } else {
                eta64 * segment(ctx, x.p64, cam.as_dvec3(), pr.dist2.sqrt())
            };
            if cos_x * x.n.dot(side) > 0.0 && opl + cam_seg <= budget && visible(ctx, x.p, x.n, cam, counts) {
                let w = std::f32::consts::FRAC_1_PI * cos_x.abs() / pr.dist2 * pr.importance;
                terms.push(SensorTerm {
                    rgb: scale(mul(beta, alb), w),
                    opl: opl + cam_seg,
                    fx: pr.fx,
                    fy: pr.fy,
                    scatters: j,
                    direct: j == 1,
                });
            }
        }
        if j == max_scatters {
            break;
        }
        beta = mul(beta, alb);
        let Some((y, dir, _)) = scatter(ctx, sampler, &x, side, t_far(budget, opl, eta64), counts) else {
            break;
        };
        opl += eta64 * segment(ctx, x.p64, y.p64, y.t);
        x = y;
        side = -dir;
    }
}
