//! Camera and light subpaths: random walks that store every vertex with its throughput,
//! its optical path length and its forward/reverse area densities (Veach 1997, §10.2).
//!
//! Vertex positions follow the path tracer's parameterisation (Algorithm 1): the first
//! camera vertex in ray form (it slides along the fixed camera ray), every other vertex in
//! material form (it moves with its surface), with the derivative of G·J carried by the
//! ratio `[G·J]_dual / [G]_value` as in [`crate::integrator::path`].

use super::vertex::{Vertex, camera_dir_pdf, link, to_area};
use crate::integrator::bsdf::{Lobes, albedo, diffuse_eval, sample_cosine};
use crate::integrator::context::RenderContext;
use crate::integrator::entry::Crossings;
use crate::integrator::nlos_start::{start, weigh_first_hit};
use crate::integrator::path::{PacketLanes, ray_plane_point, traced};
use crate::integrator::surface::{behind_one_sided, geometry_ratio, offset_origin, surface_at};
use crate::integrator::trace::{RayCounts, next_hits, spawn_point};
use crate::integrator::transport::{scatter, scatter_lobes};
use crate::kernel::{Mask, PathSampler, Real, Spectrum, V3};
use glam::Vec3;

type V<R> = <R as Real>::Value;

/// What the light subpath started from, per lane.
#[derive(Clone, Copy, Debug)]
pub struct LightOrigin<R: Real> {
    pub emitter: [u32; 8],
    /// Delta in position (point light, laser spot): no camera path can hit it, so the
    /// s = 0 strategy has density 0 for its paths.
    pub delta: R::Mask,
}

/// Extends `path` (which holds its start vertex) by up to `new_vertices` surface vertices.
/// `ray_d` was sampled at the last vertex with solid-angle density `pdf_dir`, and `beta` is
/// the throughput carried along it. `camera` marks the camera subpath (first vertex in ray
/// form; its segment leaves the OPL when the film is unwarped).
#[allow(clippy::too_many_arguments)]
fn random_walk<R: Real, const C: usize>(
    ctx: &RenderContext,
    sampler: &mut PathSampler,
    path: &mut Vec<Vertex<R, C>>,
    mut ray_o: V3<V<R>>,
    mut ray_d: V3<V<R>>,
    mut pdf_dir: V<R>,
    mut beta: Spectrum<R, C>,
    mut active: R::Mask,
    new_vertices: usize,
    camera: bool,
    counts: &mut RayCounts,
) {
    // the index of the medium each lane's ray crosses (changes where it refracts)
    let mut eta = path.last().expect("a walk starts from a vertex").eta_in;
    let all = R::Mask::from_bools(&[true; 8][..R::LANES]);
    let none = R::Mask::from_bools(&[false; 8][..R::LANES]);
    // an NLOS capture's camera subpath starts at a sensor point, a fixed point of the wall:
    // its first vertex is in material form, as the path tracer's (`crate::integrator::nlos`)
    let first_ray_form = camera && ctx.nlos.is_none();
    // the direction of the ray that reached the last vertex
    let mut arrival = V3::<V<R>>::zero();
    for depth in 1..=new_vertices {
        let ray_form = first_ray_form && depth == 1;
        let prev = *path.last().expect("a walk starts from a vertex");
        // the window cut ahead of the last vertex: a camera subpath's strategies all end on
        // an emitter, a light subpath's at the pinhole (`crate::integrator::window`)
        let ends = if camera { &ctx.emitter_box } else { &ctx.camera_box };
        if let Some(b) = ends.as_ref().filter(|_| depth > 1) {
            active = active & b.reachable(ctx.opl_budget, prev.opl.value(), &prev.p.value());
            if active.none() {
                break;
            }
        }
        // the window cut (`crate::integrator::window`): any full path through a vertex
        // farther than the OPL left would land past the window
        let cut = !(ray_form && ctx.scene.film.unwarp);
        let (hit, found) = next_hits(
            &ctx.accel,
            ctx.opl_budget,
            &ray_o,
            &ray_d,
            prev.opl.value(),
            eta.value(),
            cut,
            active,
            ray_form,
            counts,
        );
        // a camera ray that entered a closed shape through an edge (`crate::integrator::entry`)
        active = match ray_form {
            true => {
                let tris = (&ctx.tri_verts[..], &ctx.scene.geometry.tri_shape[..]);
                ctx.entry
                    .admits::<R>(tris, &hit.prim, &ray_d, &[Crossings::default(); 8], found)
            }
            false => found,
        };
        if active.none() {
            break;
        }
        let mut x = surface_at::<R>(ctx, &hit.prim, hit.u, hit.v);
        // the back of a one-sided material is black: the walk ends before it
        active = active.and_not(behind_one_sided::<V<R>>(ctx, &hit.prim, &x.n.value(), &ray_d, active));
        if active.none() {
            break;
        }
        if R::DERIVS > 0 && ray_form {
            x.p = ray_plane_point(&prev.p, &V3::from_value(ray_d), &x.p, &x.n);
        }
        let seg = x.p - prev.p;
        let r2 = seg.length_squared();
        let r = r2.sqrt();
        let mut geo = R::one();
        if R::DERIVS > 0 && !ray_form {
            geo = geometry_carrier(&prev, &x.p, &x.n, ctx.scene.offset_scale) * x.jacobian;
            beta = beta.scale(geo);
            if !ctx.diffuse_only && path.len() >= 2 {
                // the previous vertex's f, now with both of its directions moving: ḟ/f on
                // its glossy lanes (its sampled value is already in β)
                let before = &path[path.len() - 2];
                let lobes = Lobes::<R, C>::gather(ctx, &prev.prim);
                // at the directions its value was drawn with (`path::traced`)
                let wo = traced(&(before.p - prev.p).normalize(), &-arrival);
                let wi = traced(&(x.p - prev.p).normalize(), &ray_d);
                let f = lobes.eval(&V3::select(prev.front, prev.n, -prev.n), &wo, &wi, camera);
                let glossy = lobes.glossy();
                beta = Spectrum(std::array::from_fn(|c| {
                    let r = R::safe_div(f.0[c], R::from_value(f.0[c].value()));
                    R::select(glossy, beta.0[c] * r, beta.0[c])
                }));
            }
        }
        let opl = if ray_form && ctx.scene.film.unwarp {
            prev.opl
        } else {
            prev.opl + eta * r
        };
        let (p64, opl64) = if ctx.opl.f64_paths {
            opl64_step(ctx, &prev, &hit, eta.value(), !(ray_form && ctx.scene.film.unwarp))
        } else {
            ([glam::DVec3::ZERO; 8], [0.0; 8])
        };
        let front = x.n.value().dot(ray_d).lt(V::<R>::zero());
        let f = diffuse_eval(albedo::<R, C>(ctx, &x.prim));
        let mut v = Vertex {
            p: x.p,
            n: V3::select(front, x.n, -x.n),
            on_surface: all,
            front,
            uniform_sphere: none,
            beta,
            f,
            pdf_fwd: V::<R>::zero(),
            pdf_rev: V::<R>::zero(),
            geo,
            opl,
            eta_in: eta,
            transmitted: none,
            delta: none,
            p64,
            opl64,
            prim: hit.prim,
            alive: active,
        };
        link(path.last_mut().expect("start vertex"), &mut v, pdf_dir);
        path.push(v);
        if depth == new_vertices {
            break;
        }
        let n_v = x.n.value();
        if ctx.diffuse_only {
            let (dir, pdf) = scatter(ctx, sampler, &n_v, &-ray_d, &f, &mut beta, &mut active, depth as u32);
            ray_o = spawn_point(&x.p.value(), &n_v, &ray_d, &dir, ctx.scene.offset_scale);
            ray_d = dir;
            pdf_dir = pdf;
            continue;
        }
        // any material: radiance transport on the camera subpath, importance on the light's
        let lobes = Lobes::<R, C>::gather(ctx, &x.prim);
        let s = scatter_lobes(
            ctx,
            sampler,
            &lobes,
            &n_v,
            &-ray_d,
            camera,
            &mut beta,
            &mut active,
            depth as u32,
        );
        if R::DERIVS > 0 && (s.delta & active).any() {
            // a Dirac lobe's weight with its derivatives (its value is in β). Only parameters
            // that move no vertex reach BDPT through a Dirac lobe (`render::check_materials`),
            // so the next vertex needs no ray form: all that moves here is the tint.
            let wo = traced(&(path[path.len() - 2].p - x.p).normalize(), &-ray_d);
            let (_, ratio) = lobes.delta_dual(&x.n, &wo, s.transmitted, camera);
            beta = Spectrum(std::array::from_fn(|c| {
                R::select(s.delta, beta.0[c] * ratio.0[c], beta.0[c])
            }));
        }
        let back = V3::select(s.transmitted, V3::zero(), ray_d);
        ray_o = spawn_point(&x.p.value(), &n_v, &back, &s.wi, ctx.scene.offset_scale);
        let inside = n_v.dot(s.wi).lt(V::<R>::zero());
        eta = R::select(s.transmitted, R::select(inside, lobes.eta_int, lobes.eta_ext), eta);
        let k = path.len() - 1;
        path[k].transmitted = s.transmitted;
        path[k].delta = lobes.delta;
        // the density of this vertex sampling its predecessor, arriving along the new ray (0
        // on delta lanes, as the one of the vertex it reaches: `vertex` module docs)
        let back_pdf = lobes.value().pdf(&n_v, &s.wi, &-ray_d);
        path[k - 1].pdf_rev = super::vertex::to_area(&x.p.value(), &path[k - 1], back_pdf);
        arrival = ray_d;
        ray_d = s.wi;
        pdf_dir = s.pdf.masked(!s.delta);
    }
}

/// `[G]_dual / [G]_value` of the segment from `prev` to the surface point `p` with normal
/// `n` (G = |cos θ_prev| |cos θ_p| / r², no cosine at point-like vertices): value 1, and the
/// derivative of the segment's geometry term relative to its value, none where a cosine is
/// rounding noise (`geometry_ratio`).
#[inline(always)]
pub fn geometry_carrier<R: Real, const C: usize>(prev: &Vertex<R, C>, p: &V3<R>, n: &V3<R>, scale: f32) -> R {
    let seg = *p - prev.p;
    let r2 = seg.length_squared();
    let w = seg * R::safe_div(R::one(), r2.sqrt());
    let cos_prev = R::select(prev.on_surface, prev.n.dot(w), R::one());
    geometry_ratio(&p.value(), scale, cos_prev, n.dot(w), r2)
}

/// The camera subpath of each lane's pixel: vertex 0 at the pinhole, then up to
/// `new_vertices` surface vertices. The filter offset is importance sampled, so the camera
/// throughput stays 1; its density h_j(u)/(a cos³θ)/N enters the MIS weights only.
pub fn camera_subpath<R: Real, const C: usize>(
    ctx: &RenderContext,
    sampler: &mut PathSampler,
    lanes: &PacketLanes,
    path: &mut Vec<Vertex<R, C>>,
    new_vertices: usize,
    counts: &mut RayCounts,
) {
    if let Some(scan) = &ctx.nlos {
        return sensor_subpath(ctx, scan, sampler, lanes, path, new_vertices, counts);
    }
    let cam = &ctx.camera;
    let pixels = (ctx.scene.film.width * ctx.scene.film.height) as f32;
    let (u1, u2) = sampler.next2::<V<R>>();
    let mut dirs = [Vec3::ZERO; 8];
    let mut pdf = [0.0f32; 8];
    for i in 0..R::LANES {
        let (ox, oy) = (cam.filter().sample(u1.lane(i)), cam.filter().sample(u2.lane(i)));
        dirs[i] = cam.direction(lanes.px[i] as f32 + 0.5 + ox, lanes.py[i] as f32 + 0.5 + oy);
        let h = cam.filter().density(ox) * cam.filter().density(oy);
        let importance = cam.project(cam.position + dirs[i]).map_or(0.0, |p| p.importance);
        pdf[i] = camera_dir_pdf(h, importance, pixels);
    }
    let in_use: [bool; 8] = std::array::from_fn(|i| i < lanes.count);
    let active = R::Mask::from_bools(&in_use[..R::LANES]);
    path.clear();
    let mut v0 = Vertex::point(V3::splat(cam.position), Spectrum::splat(R::one()), active);
    v0.eta_in = ctx.motion.eta::<R>(ctx.scene.eta);
    path.push(v0);
    random_walk(
        ctx,
        sampler,
        path,
        V3::splat(cam.position),
        V3::from_lane_vecs(&dirs[..R::LANES]),
        V::<R>::from_lanes(&pdf),
        Spectrum::splat(R::one()),
        active,
        new_vertices,
        true,
        counts,
    );
}

/// The sensor point of each lane's film cell in an NLOS capture, and its first
/// direction: [`camera_subpath`]'s counterpart for a capture. Vertex 0 is the sensor point s,
/// a point on the wall of importance f_r(s)·|cos θ_s| = ρ_s/π·|cos θ_s| for the radiance it
/// sends towards the SPAD (`crate::integrator::nlos`); the direction is cosine-weighted, so
/// the throughput after s is ρ_s; with `hidden_sampling`, a share of the lanes aims at the
/// hidden shapes as the path tracer's do, and the first hit turns the weight into
/// ρ_s·(cos θ_s/π)/p(ω) with the two strategies' mixture density p, which is also the first
/// vertex's density for the MIS weights (`sensor.rs` uses it for t = 1). Its OPL starts at the SPAD's leg where the capture counts it, so every
/// strategy's OPL includes it. Lanes whose sensor point the SPAD does not see carry nothing.
fn sensor_subpath<R: Real, const C: usize>(
    ctx: &RenderContext,
    scan: &crate::integrator::nlos::NlosSensor,
    sampler: &mut PathSampler,
    lanes: &PacketLanes,
    path: &mut Vec<Vertex<R, C>>,
    new_vertices: usize,
    counts: &mut RayCounts,
) {
    let (u1, u2) = sampler.next2::<V<R>>();
    let mut sensor = [0usize; 8];
    let mut seen = [false; 8];
    for i in 0..lanes.count.min(R::LANES) {
        sensor[i] = scan.sensor_of(lanes.px[i], lanes.py[i]);
        seen[i] = scan.seen[sensor[i]];
    }
    // the path tracer's start: cosine-weighted, or aimed at the hidden shapes in a share of
    // the lanes (`crate::integrator::nlos_start`); the first hit then sets the weight and the
    // first vertex's density
    let st = start::<R, C>(ctx, scan, &sensor, u1, u2);
    let active = R::Mask::from_bools(&seen[..R::LANES]) & st.alive;
    let prims: [u32; 8] = std::array::from_fn(|i| scan.sensors[sensor[i]].prim);
    let (p, n, dir) = (st.p.value(), st.n.value(), st.d);
    let eta = ctx.motion.eta::<R>(ctx.scene.eta);
    // the sensor point's importance towards the SPAD, ρ_s/π (what t = 1 joins to)
    let importance = st.beta.scale(R::from_value(V::<R>::splat(std::f32::consts::FRAC_1_PI)));
    let mut v0 = Vertex::point(st.p, importance, active);
    v0.n = st.n;
    v0.on_surface = active;
    v0.front = active;
    v0.prim = prims;
    v0.eta_in = eta;
    let leg: [f64; 8] = std::array::from_fn(|i| if i < R::LANES { scan.spad_leg[sensor[i]] } else { 0.0 });
    v0.opl = eta * R::from_lanes(&leg.map(|l| l as f32)[..R::LANES]);
    v0.opl64 = std::array::from_fn(|i| {
        if i < R::LANES {
            eta.value().lane(i) as f64 * leg[i]
        } else {
            0.0
        }
    });
    path.clear();
    path.push(v0);
    random_walk(
        ctx,
        sampler,
        path,
        st.o,
        dir,
        st.pdf,
        st.beta,
        active,
        new_vertices,
        true,
        counts,
    );
    let targets = scan.hidden.as_ref();
    if let Some((targets, aim)) = targets.zip(st.aim).filter(|_| path.len() >= 2) {
        let x1 = path[1];
        let r2 = (x1.p.value() - p).length_squared();
        let cos_1 = x1.n.value().dot(dir).abs();
        let (scale, pdf, keep) = weigh_first_hit::<R>(targets, &aim, &x1.prim, &n, &dir, r2, cos_1);
        // every vertex's throughput carries the first segment's weight
        for v in &mut path[1..] {
            v.beta = v.beta.scale(R::from_value(scale));
            v.alive = v.alive & keep;
        }
        path[1].pdf_fwd = to_area(&p, &path[1], pdf);
    }
}

/// Uniform direction on the sphere and its density 1/(4π).
#[inline(always)]
fn sample_sphere<V: Real>(u1: V, u2: V) -> (V3<V>, V) {
    let z = V::one() - u1.mul_f(2.0);
    let r = (V::one() - z * z).sqrt();
    let (s, c) = u2.mul_f(2.0 * std::f32::consts::PI).sin_cos();
    (V3::new(r * c, r * s, z), V::splat(0.25 * std::f32::consts::FRAC_1_PI))
}

/// The light subpath of each lane: vertex 0 on an emitter (area: point by area, direction
/// by cosine; point light: direction uniform on the sphere; laser: its spot, which radiates
/// like a small Lambertian source), then up to `new_vertices` surface vertices.
pub fn light_subpath<R: Real, const C: usize>(
    ctx: &RenderContext,
    sampler: &mut PathSampler,
    lanes: &PacketLanes,
    path: &mut Vec<Vertex<R, C>>,
    new_vertices: usize,
    counts: &mut RayCounts,
) -> LightOrigin<R> {
    let in_use: [bool; 8] = std::array::from_fn(|i| i < lanes.count);
    let active = R::Mask::from_bools(&in_use[..R::LANES]);
    let ls = match &ctx.nlos {
        // a capture's light subpath starts at the lane's laser point: its sensor's in a
        // confocal scan, its film row's in an exhaustive one
        Some(scan) => {
            let points: [u32; 8] = std::array::from_fn(|i| match (i < lanes.count, scan.exhaustive) {
                (false, _) => 0,
                (true, true) => lanes.py[i],
                (true, false) => scan.sensor_of(lanes.px[i], lanes.py[i]) as u32,
            });
            ctx.emitters.sample_laser_points::<R, C>(ctx, scan, &points, active)
        }
        None => {
            let (u0, u1) = sampler.next2::<V<R>>();
            let select = crate::integrator::path::draw_select::<R>(ctx, sampler, true);
            ctx.emitters.sample::<R, C>(ctx, select, u0, u1, active)
        }
    };
    let alive = active & ls.valid;
    let eta = ctx.motion.eta::<R>(ctx.scene.eta);
    let mut v0 = Vertex::point(ls.p, ls.weight, alive);
    v0.n = V3::select(ls.has_cos, ls.n, V3::zero());
    v0.on_surface = ls.has_cos;
    v0.front = ls.has_cos;
    v0.uniform_sphere = !ls.has_cos;
    v0.pdf_fwd = ls.pdf_area;
    v0.opl = eta * ls.pre_length;
    v0.eta_in = eta;
    if ctx.opl.f64_paths {
        v0.p64 = ls.p64;
        v0.opl64 = std::array::from_fn(|i| {
            if i < R::LANES {
                eta.value().lane(i) as f64 * ls.pre64[i]
            } else {
                0.0
            }
        });
    }
    path.clear();
    path.push(v0);
    let (b1, b2) = sampler.next2::<V<R>>();
    let (n_v, p_v) = (ls.n.value(), ls.p.value());
    let (dir_c, pdf_c) = sample_cosine(&n_v, &n_v, b1, b2);
    let (dir_s, pdf_s) = sample_sphere(b1, b2);
    let dir = V3::select(ls.has_cos, dir_c, dir_s);
    let pdf = V::<R>::select(ls.has_cos, pdf_c, pdf_s);
    let cos0 = V::<R>::select(ls.has_cos, n_v.dot(dir).abs(), V::<R>::one());
    let beta = ls.weight.scale(R::from_value(V::<R>::safe_div(cos0, pdf)));
    let origin = V3::select(ls.has_cos, offset_origin(&p_v, &n_v, &dir, ctx.scene.offset_scale), p_v);
    random_walk(
        ctx,
        sampler,
        path,
        origin,
        dir,
        pdf,
        beta,
        alive,
        new_vertices,
        false,
        counts,
    );
    LightOrigin {
        emitter: ls.emitter,
        delta: alive & !ls.pdf_area.gt(V::<R>::zero()),
    }
}

/// The new vertices' points rebuilt in f64 from the hit's barycentrics and their OPLs in f64
/// (`integrator::opl`), adding the segment from `prev` when `count` (not an unwarped camera
/// segment).
fn opl64_step<R: Real, const C: usize>(
    ctx: &RenderContext,
    prev: &Vertex<R, C>,
    hit: &crate::integrator::trace::HitLanes<R::Value>,
    eta: R::Value,
    count: bool,
) -> ([glam::DVec3; 8], [f64; 8]) {
    let u: [f32; 8] = std::array::from_fn(|i| if i < R::LANES { hit.u.lane(i) } else { 0.0 });
    let v: [f32; 8] = std::array::from_fn(|i| if i < R::LANES { hit.v.lane(i) } else { 0.0 });
    let p64 = crate::integrator::opl::points64(ctx, R::LANES, &hit.prim, &u, &v);
    let mut opl64 = prev.opl64;
    if count {
        for i in 0..R::LANES {
            opl64[i] += eta.lane(i) as f64 * (p64[i] - prev.p64[i]).length();
        }
    }
    (p64, opl64)
}

#[cfg(test)]
#[path = "walk_tests.rs"]
mod tests;
