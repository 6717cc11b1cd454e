//! Unidirectional transient path tracing with next-event estimation and MIS, written once
//! for every number type.
//!
//! Each lane carries one path of one pixel. Per vertex x_i the kernel adds
//! - emission found by the BSDF-sampled ray (MIS-weighted against light sampling), and
//! - next-event estimation to a sampled emitter point (MIS-weighted against BSDF sampling),
//!
//! each with its optical path length d = η · Σ‖x_{j+1} − x_j‖ (supplemental Eq. 24's
//! tof(x̄) = d / c), binned by the film through S_e.
//!
//! Throughput is kept in the area-measure form of Algorithm 1: with dual numbers, vertices
//! move with their surfaces and the ratio `[cos_{i-1} cos_i / r² · J]_dual / [...]_value`
//! carries the derivative of the geometry term G and the area Jacobian J; with plain
//! numbers that ratio is 1 and is skipped at compile time. Two vertices are in ray form
//! instead, and take no such ratio: the first camera vertex (it slides along its fixed camera
//! ray) and every vertex reached through a Dirac lobe (the hit of the ray the mirror or Snell
//! direction sends from the moving previous vertex, with the lobe's weight differentiated:
//! `super::bsdf::delta`).

use super::bsdf::{Lobes, albedo, diffuse_eval};
use super::context::RenderContext;
use super::deposit::{PathCounts, for_each_lane};
use super::entry::Crossings;
use super::opl::points64;
use super::power_heuristic;
use super::sink::Sink;
use super::surface::{behind_one_sided, geometry_ratio, resolvable, surface_at};
use super::trace::{SegmentEnd, next_hits, spawn_point, visible_between};
use super::transport::{emitter_hits, scatter, scatter_lobes};
use super::window;
use crate::kernel::{Mask, PathSampler, Real, Spectrum, V3};

/// The lanes of one packet: pixel coordinates and a global path id per lane.
#[derive(Clone, Copy, Debug)]
pub struct PacketLanes {
    pub px: [u32; 8],
    pub py: [u32; 8],
    pub ids: [u64; 8],
    /// Lanes in use (the rest are padding and stay inactive).
    pub count: usize,
    /// Samples per pixel when `ids` are `pixel · spp + sample` (as [`PacketLanes::row`]
    /// makes them), which a Sobol sequence needs apart; 0 for ids of another form.
    pub spp: u32,
}

impl PacketLanes {
    /// `n` (≤ 8) consecutive pixels of film row `py` starting at column `px0`, for sample `s`
    /// of `spp`: path id = (py · width + px) · spp + s, so every path's random numbers depend
    /// only on its pixel and sample index.
    pub fn row(px0: usize, py: usize, n: usize, width: usize, spp: u32, s: u64) -> Self {
        let mut lanes = PacketLanes {
            px: [0; 8],
            py: [0; 8],
            ids: [0; 8],
            count: n,
            spp,
        };
        for i in 0..n {
            let px = px0 + i;
            lanes.px[i] = px as u32;
            lanes.py[i] = py as u32;
            lanes.ids[i] = (py * width + px) as u64 * spp as u64 + s;
        }
        lanes
    }
}

/// Camera rays chosen by the caller instead of filter samples through each lane's pixel: the
/// primary-edge estimator traces both sides of a silhouette point (`boundary::primary`). Each
/// lane still splats into `lanes.px/py` of the film it is given.
#[derive(Clone, Copy, Debug)]
pub struct PrimaryRays {
    /// Unit directions from the camera position, one per lane.
    pub dirs: [glam::Vec3; 8],
    /// Where given, each lane's edge ray: the primary edge estimator traces each side of an
    /// edge ε beside it to find that side's surface, and wants that side's light at the edge
    /// itself, the limit ε → 0. The edge ray meets the plane of the face the side ray found at
    /// that side's limit point, whose OPL the path takes for every segment that meets its first
    /// vertex (the eye's, the next-event connection and the next bounce's; `opl_at`). Where
    /// that face is one of the lane's `own`, the vertex itself also moves there, to a few
    /// offsets from it on the face (`near_limit`). On a surface seen nearly edge-on, the side
    /// ray's own hit lies far from the limit in depth: on a face beside a silhouette up to half
    /// its sliver (its light was binned late), on a floor seen at 89° behind a silhouette 7 mm
    /// a thousandth of a pixel away (binned early).
    pub limit: Option<[glam::Vec3; 8]>,
    /// Each lane's edge's faces, and the faces coplanar with them that its side's offset point
    /// lands on (a sliver along the edge's own face passes the side ray on to them;
    /// `u32::MAX` for none). On any other surface the side ray finds,
    /// the vertex stays at its hit (the OPL only is the limit's): the edge ray may meet such a
    /// surface where its light is ambiguous (a shadow line that continues the silhouette under
    /// a light at the camera, the floor under a resting or hovering edge).
    pub own: [[u32; 4]; 8],
}

/// First vertices chosen by the caller instead of a camera ray: the source subpaths of the
/// boundary stage (Algorithm 2, EstimateSourceSubpath) start at x_L and estimate the radiance
/// it sends towards x_S, with the kernel's own next-event estimation, MIS and BSDF sampling.
/// Each lane hands its terms to the sink at (x, y) = (lane, 0). Plain numbers only (the
/// boundary stage differentiates the visibility, not the subpaths).
#[derive(Clone, Copy, Debug)]
pub struct SurfaceStarts {
    /// Triangle of each start point (its material and emitter).
    pub prim: [u32; 8],
    pub p: [glam::Vec3; 8],
    /// `p` in f64 (used when the render carries f64 OPLs, `super::opl`).
    pub p64: [glam::DVec3; 8],
    /// Unit geometric normal.
    pub n: [glam::Vec3; 8],
    /// Direction the light leaves each start point in (x_L → x_S): the side it reflects to.
    pub out: [glam::Vec3; 8],
    /// Index of the medium on the side `out` points into (`super::medium`): where the walk
    /// starts, before any refraction.
    pub eta: [f32; 8],
    /// OPL already travelled by the rest of the path (d_B), which counts against the window
    /// cut; every term's d includes it.
    pub opl: [f64; 8],
    /// Scattering vertices at most, the start included.
    pub max_scatters: u32,
    /// First random dimension of the walk (past what the caller drew for the start).
    pub dim: u64,
    /// In an NLOS capture, each lane's sensor point on the relay wall (`super::nlos`): the
    /// radiance walk's next-event estimation ends at the laser points that sensor pairs with,
    /// the importance walk's connections at the sensor point itself. Unused otherwise.
    pub sensor: [usize; 8],
    /// Importance walk only: lanes whose first connection (the start point to its sensor
    /// point) is taken as unblocked without a shadow ray (`crate::boundary::secondary`: a
    /// confocal laser point's boundary segment, which that connection runs back along).
    pub unblocked_first: [bool; 8],
}

/// Where the paths of a packet start.
#[derive(Clone, Copy, Debug)]
pub enum PathStart<'a> {
    /// A filter sample through each lane's pixel.
    Camera,
    /// The caller's camera rays (the filter sample is still drawn, so later dimensions match).
    Rays(&'a PrimaryRays),
    /// Given surface points (no emission of their own is counted).
    Surface(&'a SurfaceStarts),
}

/// Traces `R::LANES` paths and hands their contributions to `sink` (at each lane's pixel).
#[inline]
pub fn trace_packet<R: Real, const C: usize, S: Sink<C>>(
    ctx: &RenderContext,
    seed: u64,
    lanes: &PacketLanes,
    sink: &mut S,
    counts: &mut PathCounts,
) {
    trace_packet_from::<R, C, S>(ctx, seed, lanes, PathStart::Camera, sink, counts)
}

/// [`trace_packet`] with the paths starting as `start` says.
pub fn trace_packet_from<R: Real, const C: usize, S: Sink<C>>(
    ctx: &RenderContext,
    seed: u64,
    lanes: &PacketLanes,
    start: PathStart,
    sink: &mut S,
    counts: &mut PathCounts,
) {
    type V<R> = <R as Real>::Value;
    let scene = ctx.scene;
    let surface = match start {
        PathStart::Surface(s) => Some(s),
        _ => None,
    };
    debug_assert!(surface.is_none() || R::DERIVS == 0);
    let max_bounces = surface.map_or(scene.integrator.max_bounces, |s| s.max_scatters);
    let eta = ctx.motion.eta::<R>(scene.eta);
    let mut sampler = PathSampler::with_sequence(
        scene.integrator.sampler,
        seed,
        &lanes.ids[..lanes.count.max(1)],
        lanes.spp,
    );
    let mut in_use = [false; 8];
    in_use[..lanes.count].iter_mut().for_each(|b| *b = true);
    let mut active = R::Mask::from_bools(&in_use[..R::LANES]);

    let (f1, f2) = sampler.next2::<V<R>>();
    let mut ray_d: V3<V<R>> = match start {
        PathStart::Rays(p) => V3::from_lane_vecs(&p.dirs[..R::LANES]),
        PathStart::Camera => ctx.camera.sample(&lanes.px, &lanes.py, f1, f2),
        // the direction light arrives from, as if a ray had come to x_L against `out`
        PathStart::Surface(s) => -V3::from_lane_vecs(&s.out[..R::LANES]),
    };
    if let Some(s) = surface {
        sampler.set_dim(s.dim);
    }
    let mut ray_o: V3<V<R>> = V3::splat(ctx.camera.position);
    let mut prev_p: V3<R> = V3::splat(ctx.camera.position);
    let mut prev_n: V3<R> = V3::zero();
    let mut prev_pdf: V<R> = V::<R>::zero();
    let mut beta = Spectrum::<R, C>::splat(R::one());
    let mut opl = R::zero();
    // Materials beyond Lambertian (`super::bsdf::Lobes`): the index of the medium each lane
    // is in (the scene's until a lane refracts), lanes whose last scattering was a delta lobe
    // or a refraction (emission they find takes no MIS weight: light sampling cannot make
    // those paths), and the previous vertex's material and direction towards its own
    // predecessor, for the derivative of its f once this vertex is known. A diffuse-only
    // scene never touches them past the medium, which stays η.
    let general = !ctx.diffuse_only;
    let mut eta_med = eta;
    let mut no_mis = R::Mask::splat(false);
    let mut prev_lobes: Option<(Lobes<R, C>, V3<R>)> = None;
    // with derivative lanes, the lanes whose last scattering was a Dirac lobe and the
    // direction it sent them in with its derivatives: their next vertex is in ray form
    // (`super::bsdf::delta`)
    let mut attached: Option<(R::Mask, V3<R>)> = None;
    // A path from the camera stays on the camera's side of each closed body but those it
    // crossed; its rays in ray form (the camera's, and those a Dirac lobe turned, `turned`)
    // that meet one from the other side came through an edge (`super::entry`). Paths from
    // given surface points or the relay wall start on no known side.
    let camera_path = surface.is_none() && ctx.nlos.is_none();
    let mut crossed = [Crossings::default(); 8];
    let mut turned = R::Mask::splat(false);
    // each lane's OPL in f64 from f64 hit points, when the film needs it (`super::opl`)
    let exact = ctx.opl.f64_paths;
    let mut opl64 = [0.0f64; 8];
    let mut prev64 = [ctx.camera.position.as_dvec3(); 8];
    // An NLOS capture starts each camera path at its lane's sensor point on the relay wall
    // (`super::nlos`): the first vertex is then an ordinary (material-form) vertex.
    let nlos = ctx.nlos.as_ref().filter(|_| matches!(start, PathStart::Camera));
    // Paths from given surface points of a capture (the boundary stage's source subpaths)
    // end at the laser points of their lane's sensor too: `targets` is the scan wherever
    // next-event estimation goes to laser points. Their sensor point's leg to the SPAD is
    // counted by the sensor side (`crate::boundary::subpaths`), so `spad_head` stays 0.
    let targets = ctx.nlos.as_ref().filter(|_| !matches!(start, PathStart::Rays(_)));
    let mut sensor = match surface {
        Some(s) if targets.is_some() => s.sensor,
        _ => [0usize; 8],
    };
    let mut aim = None;
    // the OPL every connection of the lane adds beyond its own: the sensor point's leg to
    // the SPAD where the capture counts it, taken a hair short for the window cut's bound
    let mut spad_head = [0.0f32; 8];
    if let Some(n) = nlos {
        let mut seen = [false; 8];
        for i in 0..lanes.count.min(R::LANES) {
            sensor[i] = n.sensor_of(lanes.px[i], lanes.py[i]);
            seen[i] = n.seen[sensor[i]];
            spad_head[i] = (n.spad_leg[sensor[i]] * scene.eta as f64 * (1.0 - 1e-5)) as f32;
        }
        active = active & R::Mask::from_bools(&seen[..R::LANES]);
        let st = super::nlos_start::start::<R, C>(ctx, n, &sensor, f1, f2);
        (ray_o, ray_d, prev_p, prev_n, prev_pdf, beta) = (st.o, st.d, st.p, st.n, st.pdf, st.beta);
        prev64 = st.p64;
        active = active & st.alive;
        aim = st.aim;
    }
    let spad_head = V::<R>::from_lanes(&spad_head[..R::LANES]);
    let mut x64 = prev64;
    // The time term f·Ṡ_e·ḋ from draws on the time edges where they apply
    // (`super::time_edge_nee`): then the ordinary contributions they replace drop it.
    let time_edges = ctx
        .time_edges
        .as_ref()
        .filter(|_| R::DERIVS > 0 && nlos.is_none() && surface.is_none());
    let mut edge_sampler = time_edges.map(|_| {
        PathSampler::with_sequence(
            scene.integrator.sampler,
            seed ^ super::time_edge_nee::SEED,
            &lanes.ids[..lanes.count.max(1)],
            lanes.spp,
        )
    });
    let no_lanes = R::Mask::splat(false);
    // The laser spots' samples, once per packet: they do not depend on the vertex, and an
    // exhaustive scan connects every vertex to every spot. Taken for the lanes alive at the
    // first vertex, a superset of those alive later; each lane's values do not depend on
    // the others, so a later vertex gets what it would have drawn itself.
    let mut spot_samples = Vec::new();
    if let Some(s) = surface {
        opl = R::from_lanes(&s.opl.map(|d| d as f32)[..R::LANES]);
        opl64 = s.opl;
        eta_med = R::from_lanes(&s.eta[..R::LANES]);
    }

    // the points whose OPL this vertex and the previous one take, where they stand in for
    // the limit of a primary edge's side (`PrimaryRays::limit`, `near_limit`): set at the
    // first vertex only, so every other path measures its OPL between its own vertices
    let (mut opl_at, mut opl_prev): (Option<V3<R>>, Option<V3<R>>) = (None, None);
    for depth in 1..=max_bounces + 1 {
        let (x, w_in) = match surface.filter(|_| depth == 1) {
            Some(s) => {
                x64 = s.p64;
                // light arrives at the start point against `out` (`ray_d`)
                (start_point::<R>(s), V3::from_value(ray_d))
            }
            None => {
                // the window cut: no hit farther than the OPL left can reach a bin (`super::window`)
                let counted = !(depth == 1 && scene.film.unwarp);
                let (hit, found) = next_hits(
                    &ctx.accel,
                    ctx.opl_budget,
                    &ray_o,
                    &ray_d,
                    opl.value(),
                    eta_med.value(),
                    counted,
                    active,
                    depth == 1,
                    &mut counts.rays,
                );
                let from_camera = depth == 1 && nlos.is_none();
                // a ray in ray form met a closed body from the other side of it than the
                // path is on: it entered through an edge (`super::entry`)
                let checked = match (from_camera, camera_path) {
                    (true, _) => found,
                    (false, true) => found & turned,
                    (false, false) => no_lanes,
                };
                active = match checked.any() {
                    true => {
                        let tris = (&ctx.tri_verts[..], &ctx.scene.geometry.tri_shape[..]);
                        found.and_not(checked) | ctx.entry.admits::<R>(tris, &hit.prim, &ray_d, &crossed, checked)
                    }
                    false => found,
                };
                if active.none() {
                    break;
                }
                let mut x = surface_at::<R>(ctx, &hit.prim, hit.u, hit.v);
                // a primary edge's side rays: their edge rays and the edge's faces
                let limit = match start {
                    PathStart::Rays(PrimaryRays {
                        limit: Some(l), own, ..
                    }) if depth == 1 => Some((l, own)),
                    _ => None,
                };
                // lanes whose vertex takes the OPL of the edge ray's limit (`PrimaryRays::limit`)
                let mut at_limit = [false; 8];
                if let Some((l, faces)) = limit {
                    let mut own = [false; 8];
                    for (i, o) in own.iter_mut().enumerate().take(R::LANES) {
                        *o = faces[i].contains(&hit.prim[i]) && hit.prim[i] != u32::MAX;
                    }
                    let own = R::Mask::from_bools(&own[..R::LANES]);
                    let w = V3::from_value(V3::from_lane_vecs(&l[..R::LANES]));
                    // where the edge ray meets the plane of the face the side ray found
                    let lim = ray_plane_point(&prev_p, &w, &x.p, &x.n);
                    let steady = limit_is_steady::<R>(&x.n.value(), &w.value(), &ray_d);
                    // the edge's own faces: the vertex itself moves to the edge ray
                    ray_d = V3::select(own, w.value(), ray_d);
                    x.p = V3::select(own, near_limit(&lim, &x.p, scene.offset_scale), x.p);
                    let m = own | steady;
                    // (a lane whose side ray missed has no face to take the limit on)
                    for (i, a) in at_limit.iter_mut().enumerate().take(R::LANES) {
                        *a = m.bit(i) && active.bit(i);
                    }
                    opl_at = Some(V3::select(m, lim, x.p));
                }
                if R::DERIVS > 0 && from_camera {
                    // The camera ray is fixed in the image plane: the first vertex moves along it
                    // (x₁ = o + t(θ)·ω), so the pixel filter is never differentiated.
                    x.p = ray_plane_point(&prev_p, &V3::from_value(ray_d), &x.p, &x.n);
                }
                // after a Dirac lobe, the vertex is the hit of the ray the lobe turned
                let after_delta = match &attached {
                    Some((m, w)) => {
                        x.p = V3::select(*m, ray_plane_point(&prev_p, w, &x.p, &x.n), x.p);
                        *m
                    }
                    None => R::Mask::splat(false),
                };
                let seg = x.p - prev_p;
                let r2 = seg.length_squared();
                let r = r2.sqrt();
                let w_in = seg * R::safe_div(R::one(), r);
                let cos_i = x.n.dot(w_in).abs();
                if let Some((a, t)) = aim
                    .as_ref()
                    .zip(nlos.and_then(|n| n.hidden.as_ref()))
                    .filter(|_| depth == 1)
                {
                    // the first segment's two strategies (`super::nlos_aim`)
                    let (scale, pdf, keep) = super::nlos_start::weigh_first_hit::<R>(
                        t,
                        a,
                        &hit.prim,
                        &prev_n.value(),
                        &ray_d,
                        r2.value(),
                        cos_i.value(),
                    );
                    active = active & keep;
                    beta = beta.scale(R::from_value(scale));
                    prev_pdf = pdf;
                }
                if R::DERIVS > 0 && !from_camera {
                    // G·J (dual) over its value: the derivative of the geometry of this segment
                    // (none where a cosine is rounding noise: `geometry_ratio`)
                    let cos_prev = prev_n.dot(w_in);
                    let g = geometry_ratio(&x.p.value(), scene.offset_scale, cos_prev, cos_i, r2);
                    let ratio = g * x.jacobian;
                    // no G·J after a Dirac lobe: the delta took the segment's measure
                    beta = beta.scale(R::select(after_delta, R::one(), ratio));
                    if let Some((lobes, wo)) = &prev_lobes {
                        // the previous vertex's f, now with both of its directions moving: ḟ/f,
                        // at the directions its value in β was drawn with (`traced`)
                        let f = lobes.eval(&prev_n, wo, &traced(&w_in, &ray_d), true);
                        let glossy = lobes.glossy();
                        beta = Spectrum(std::array::from_fn(|c| {
                            let r = R::safe_div(f.0[c], R::from_value(f.0[c].value()));
                            R::select(glossy, beta.0[c] * r, beta.0[c])
                        }));
                    }
                }
                if exact {
                    let u: [f32; 8] = std::array::from_fn(|i| if i < R::LANES { hit.u.lane(i) } else { 0.0 });
                    let v: [f32; 8] = std::array::from_fn(|i| if i < R::LANES { hit.v.lane(i) } else { 0.0 });
                    x64 = points64(ctx, R::LANES, &hit.prim, &u, &v);
                    if let Some((l, _)) = limit {
                        let o = ctx.camera.position.as_dvec3();
                        for i in (0..R::LANES).filter(|&i| at_limit[i]) {
                            let (n, w) = (ctx.face_normal64(hit.prim[i]), l[i].as_dvec3());
                            // the OPL is the limit's (`opl_at`); x64 carries OPLs only
                            x64[i] = o + w * (n.dot(x64[i] - o) / n.dot(w));
                        }
                    }
                }
                if counted {
                    // a stand-in for the edge ray's limit takes that point's OPL
                    let r_opl = match (&opl_at, &opl_prev) {
                        (None, None) => r,
                        (to, from) => (to.unwrap_or(x.p) - from.unwrap_or(prev_p)).length(),
                    };
                    opl += eta_med * r_opl;
                    if exact {
                        for i in 0..R::LANES {
                            opl64[i] += eta_med.value().lane(i) as f64 * (x64[i] - prev64[i]).length();
                        }
                    }
                }

                // Emission found by this ray (Veach 1997, Eq. 9.13 weights against light sampling).
                let front = x.n.value().dot(ray_d).lt(V::<R>::zero());
                let hits = emitter_hits::<R, C>(ctx, &hit.prim, active & front);
                let (emitter, emits) = (hits.emitter, hits.mask);
                if emits.any() {
                    let w = if depth == 1 {
                        V::<R>::one()
                    } else {
                        let p_l = hits.area_pdf * r2.value() / cos_i.value();
                        V::<R>::select(no_mis, V::<R>::one(), power_heuristic(prev_pdf, p_l))
                    };
                    let contrib = (beta * hits.radiance).scale(R::from_value(w));
                    // after a vertex with next-event estimation, the draws carry the time term
                    // of the emitters they cover
                    let drop_time = match time_edges {
                        Some(te) if depth > 1 => !no_mis & te.covered::<R>(&emitter),
                        _ => no_lanes,
                    };
                    splat(
                        ctx,
                        sink,
                        (0, depth as usize + 1),
                        lanes,
                        &emitter,
                        opl,
                        exact.then_some(&opl64),
                        &contrib,
                        (emits, drop_time),
                        counts,
                    );
                }
                (x, w_in)
            }
        };
        // the back of a one-sided material is black: paths end there
        active = active.and_not(behind_one_sided::<V<R>>(ctx, &x.prim, &x.n.value(), &ray_d, active));
        if depth > max_bounces || active.none() {
            break;
        }
        // the window cut ahead of this vertex: no emitter within the OPL left (`super::window`)
        if let Some(b) = &ctx.emitter_box {
            active = active & b.reachable(ctx.opl_budget, opl.value() + spad_head, &x.p.value());
            if active.none() {
                break;
            }
        }

        // Next-event estimation: one sampled emitter point, or the laser points of an NLOS
        // scan (the lane's own, or every one in turn: `super::nlos`).
        let lobes = general.then(|| Lobes::<R, C>::gather(ctx, &x.prim));
        let f = match &lobes {
            None => diffuse_eval(albedo::<R, C>(ctx, &x.prim)),
            Some(_) => Spectrum::zero(),
        };
        let not_delta = lobes.as_ref().map_or(R::Mask::splat(true), |l| !l.delta);
        // the point on the emitter from one 2D pair (stratified per pixel), the emitter
        // choice from a third number
        let (u0, u1) = sampler.next2::<V<R>>();
        let select = draw_select::<R>(ctx, &mut sampler, targets.is_none());
        for target in 0..targets.map_or(1, |n| n.laser_points()) {
            let (ls, to_lanes, spad_leg) = match targets {
                None => (ctx.emitters.sample::<R, C>(ctx, select, u0, u1, active), *lanes, None),
                Some(n) => {
                    let points: [u32; 8] =
                        std::array::from_fn(|i| if n.exhaustive { target as u32 } else { sensor[i] as u32 });
                    let mut to_lanes = *lanes;
                    if n.exhaustive {
                        to_lanes.py = [target as u32; 8];
                    }
                    // (from a surface start the sensor side counts the leg)
                    let leg: [f64; 8] =
                        std::array::from_fn(|i| if surface.is_some() { 0.0 } else { n.spad_leg[sensor[i]] });
                    if spot_samples.is_empty() {
                        spot_samples.resize(n.laser_points(), None);
                    }
                    let ls = *spot_samples[target]
                        .get_or_insert_with(|| ctx.emitters.sample_laser_points::<R, C>(ctx, n, &points, active));
                    (ls, to_lanes, Some(leg))
                }
            };
            let to = ls.p - x.p;
            let d2 = to.length_squared();
            let dist = d2.sqrt();
            let wl = to * R::safe_div(R::one(), dist);
            let cos_x_signed = x.n.dot(wl);
            let incoming_side = x.n.value().dot(-ray_d);
            let same_side = (cos_x_signed.value() * incoming_side).gt(V::<R>::zero());
            let cos_y = R::select(ls.has_cos, -ls.n.dot(wl), R::one());
            // the connection runs in the medium the path is in; the laser's beam and the
            // sensor point's leg to the SPAD in the scene's
            let dist_opl = match &opl_at {
                Some(from) => (ls.p - *from).length(),
                None => dist,
            };
            let mut d = opl + eta_med * dist_opl + eta * ls.pre_length;
            if let Some(leg) = &spad_leg {
                d += eta * R::from_lanes(&leg.map(|l| l as f32));
            }
            let lit = active
                & ls.valid
                & same_side
                & not_delta
                & cos_y.value().gt(V::<R>::zero())
                & d2.value().gt(V::<R>::zero())
                & resolvable(
                    &x.p.value(),
                    ctx.scene.offset_scale,
                    cos_x_signed.value(),
                    cos_y.value(),
                    dist.value(),
                );
            let lit = lit & window::within(ctx.opl_budget, d.value());
            if lit.any() {
                let p_bsdf = match &lobes {
                    None => cos_x_signed.value().abs() * V::<R>::splat(std::f32::consts::FRAC_1_PI),
                    Some(l) => l.value().pdf(&x.n.value(), &-ray_d, &wl.value()),
                };
                let p_l = R::Value::safe_div(ls.pdf_area * d2.value(), cos_y.value());
                let w = V::<R>::select(
                    ls.pdf_area.gt(V::<R>::zero()),
                    power_heuristic(p_l, p_bsdf),
                    V::<R>::one(),
                );
                let here = SegmentEnd {
                    p: x.p.value(),
                    n: x.n.value(),
                    w_in: ray_d,
                };
                let light = SegmentEnd {
                    p: ls.p.value(),
                    n: V3::select(ls.has_cos, ls.n.value(), V3::zero()),
                    w_in: V3::zero(),
                };
                let scale = ctx.scene.offset_scale;
                let lit = lit & visible_between(&ctx.accel, &here, &light, scale, lit, &mut counts.rays);
                if lit.any() {
                    let g = cos_x_signed.abs() * cos_y / d2;
                    let f = match &lobes {
                        None => f,
                        Some(l) => l.eval(&x.n, &-w_in, &wl, true),
                    };
                    let contrib = (beta * f * ls.weight).scale(g * R::from_value(w));
                    let mut d64 = [0.0f64; 8];
                    if exact {
                        for i in 0..R::LANES {
                            let leg = spad_leg.map_or(0.0, |l| l[i]);
                            let free = ls.pre64[i] + leg;
                            d64[i] = opl64[i]
                                + eta_med.value().lane(i) as f64 * (ls.p64[i] - x64[i]).length()
                                + eta.value().lane(i) as f64 * free;
                        }
                    }
                    // (a point light's, a laser's or a wide pulse's time term stays here)
                    let drop_time = match time_edges {
                        Some(te) => lit & te.covered::<R>(&ls.emitter),
                        None => no_lanes,
                    };
                    splat(
                        ctx,
                        sink,
                        (1, depth as usize + 1),
                        &to_lanes,
                        &ls.emitter,
                        d,
                        exact.then_some(&d64),
                        &contrib,
                        (lit, drop_time),
                        counts,
                    );
                }
            }
        }
        if let (Some(te), Some(es)) = (time_edges, edge_sampler.as_mut()) {
            let vertex = super::time_edge_nee::Vertex {
                x: &x,
                x64: &x64,
                w_in: &w_in,
                ray_d: &ray_d,
                beta: &beta,
                lobes: lobes.as_ref(),
                f_diffuse: &f,
                opl,
                opl64: &opl64,
                eta: eta_med,
            };
            super::time_edge_nee::connect::<R, C, S>(
                ctx,
                te,
                es,
                depth,
                &vertex,
                active & not_delta,
                (&lanes.px, &lanes.py),
                sink,
                counts,
            );
        }

        // Continue by sampling the BSDF.
        let n_v = x.n.value();
        let (dir, pdf) = match lobes {
            None => {
                let (dir, pdf) = scatter(ctx, &mut sampler, &n_v, &-ray_d, &f, &mut beta, &mut active, depth);
                ray_o = spawn_point(&x.p.value(), &n_v, &ray_d, &dir, ctx.scene.offset_scale);
                (dir, pdf)
            }
            Some(l) => {
                let s = scatter_lobes(
                    ctx,
                    &mut sampler,
                    &l,
                    &n_v,
                    &-ray_d,
                    true,
                    &mut beta,
                    &mut active,
                    depth,
                );
                // a refracted ray starts off the far side, not stepped back along its arrival
                let back = V3::select(s.transmitted, V3::zero(), ray_d);
                ray_o = spawn_point(&x.p.value(), &n_v, &back, &s.wi, ctx.scene.offset_scale);
                let inside = n_v.dot(s.wi).lt(V::<R>::zero());
                eta_med = R::select(s.transmitted, R::select(inside, l.eta_int, l.eta_ext), eta_med);
                no_mis = s.delta | s.transmitted;
                if camera_path {
                    turned = s.delta;
                    ctx.entry.cross::<R>(
                        &ctx.scene.geometry.tri_shape,
                        &x.prim,
                        s.transmitted & active,
                        &mut crossed,
                    );
                }
                if R::DERIVS > 0 {
                    let wo = -traced(&w_in, &ray_d);
                    attached = None;
                    if (s.delta & active).any() {
                        // the lobe's weight with its derivatives (its value is in β) and the
                        // turned direction, for the next vertex, from the traced arrival as
                        // the lobe was drawn (`traced`)
                        let (w, ratio) = l.delta_dual(&x.n, &wo, s.transmitted, true);
                        beta = Spectrum(std::array::from_fn(|c| {
                            R::select(s.delta, beta.0[c] * ratio.0[c], beta.0[c])
                        }));
                        attached = Some((s.delta, w));
                    }
                    prev_lobes = Some((l, wo));
                }
                (s.wi, s.pdf)
            }
        };
        ray_d = dir;
        prev_p = x.p;
        opl_prev = opl_at.take();
        prev64 = x64;
        prev_n = x.n;
        prev_pdf = pdf;
    }
}

/// The direction `w` rebuilt from two vertices (with their motion), at the value of `ray`, the
/// direction the ray between them was traced along and a lobe was drawn and weighed at. They
/// differ by up to ε/r: the ray left its vertex from an origin moved off the surface by the
/// offset ε (`spawn_point`). A lobe narrower than that (a rough dielectric nearly matched to
/// what surrounds it, whose ḟ/f changes over 10⁻³ rad) evaluated at the rebuilt direction
/// gave its derivative a bias: on liquid_glass.toml at 1.52 with the glass's walls 1 cm from
/// the liquid, −76.5 against +2.2 by finite differences over the whole image
/// (`materials_fd::nearly_matched_liquid_in_thin_glass_matches_finite_differences`).
#[inline(always)]
pub fn traced<R: Real>(w: &V3<R>, ray: &V3<R::Value>) -> V3<R> {
    w.with_value(*ray)
}

/// The given start points as kernel vertices (plain numbers: no motion, J = 1).
fn start_point<R: Real>(s: &SurfaceStarts) -> super::surface::SurfacePoint<R> {
    super::surface::SurfacePoint {
        p: V3::from_value(V3::from_lane_vecs(&s.p[..R::LANES])),
        n: V3::from_value(V3::from_lane_vecs(&s.n[..R::LANES])),
        jacobian: R::one(),
        prim: s.prim,
    }
}

/// Hands each lane of `mask` its contribution (and its derivatives) to `sink` at its pixel,
/// for `strategy`, with OPL `d` (the value from `exact` when given, f64 per lane); lanes of
/// `drop_time` without their time term f·Ṡ_e·ḋ (`super::time_edge_nee` estimates it).
#[allow(clippy::too_many_arguments)]
fn splat<R: Real, const C: usize, S: Sink<C>>(
    ctx: &RenderContext,
    sink: &mut S,
    strategy: (usize, usize),
    lanes: &PacketLanes,
    emitter: &[u32; 8],
    d: R,
    exact: Option<&[f64; 8]>,
    contrib: &Spectrum<R, C>,
    (mask, drop_time): (R::Mask, R::Mask),
    counts: &mut PathCounts,
) {
    for_each_lane(ctx, emitter, d, exact, contrib, mask, counts, |i, lc| {
        let (x, y) = (lanes.px[i] as usize, lanes.py[i] as usize);
        if drop_time.bit(i) {
            let mut lc = *lc;
            lc.ddot = [0.0; crate::params::MAX_PARAMS];
            sink.add(ctx, strategy, x, y, &lc, 1.0);
        } else {
            sink.add(ctx, strategy, x, y, lc, 1.0);
        }
    });
}

/// How far from the edge a side path of the primary edge estimator starts on the edge's own
/// face, in self-intersection offsets ([`super::surface::self_intersection_eps`]).
const LIMIT_MARGIN: f64 = 4.0;

/// The first vertex of a side path on the edge's own face (`PrimaryRays::limit`): `p`, the
/// side ray's hit, moved along the face towards `lim`, where the edge's own ray meets the
/// face's plane (on the edge), until it is [`LIMIT_MARGIN`] offsets from it. On a face seen
/// nearly edge-on the side ray's hit lies far along the face in depth (up to half its
/// sliver), and the side's light was binned that much late; the margin keeps the start off
/// the edge itself, where a surface the edge rests on or is sunk into (a floor) would block
/// its shadow rays. The path's OPL is taken from `lim` for the segments that meet it (the
/// eye's, the next-event connection's and the next bounce's): the statistic of
/// `boundary_primary::a_balls_limbs_send_their_light_to_the_bins_it_arrives_in` moved by
/// 0.006 per offset of margin otherwise, the limbs' jumps being many times their last bins.
#[inline(always)]
fn near_limit<R: Real>(lim: &V3<R>, p: &V3<R>, scale: f32) -> V3<R> {
    let keep = super::surface::self_intersection_eps(lim, scale) * R::splat(LIMIT_MARGIN as f32);
    let d = *p - *lim;
    let len = d.length();
    lim.add_scaled(d, R::safe_div(keep.min(len), len))
}

/// Per lane, whether the edge ray `w` meets the plane (normal `n`) of the surface the side ray
/// `d` found about as squarely as the side ray did: then that point is the side's limit as
/// the side ray's offset goes to zero, and its OPL the side's (`PrimaryRays::limit`). A plane
/// the edge ray meets far more obliquely, or from its other side, has no limit near the side
/// ray's hit, which keeps its own OPL.
#[inline(always)]
fn limit_is_steady<R: Real>(n: &V3<R::Value>, w: &V3<R::Value>, d: &V3<R::Value>) -> R::Mask {
    let (nw, nd) = (n.dot(*w), n.dot(*d));
    (nw * nd).gt(R::Value::zero()) & nw.abs().ge(nd.abs() * R::Value::splat(0.5))
}

/// The point where the ray `o + t·ω` meets the plane through `p` with normal `n`, with `p`
/// and `n` carrying the surface's motion: t = n·(p − o) / (n·ω) (ray-form vertex).
#[inline(always)]
pub fn ray_plane_point<R: Real>(o: &V3<R>, w: &V3<R>, p: &V3<R>, n: &V3<R>) -> V3<R> {
    let t = R::safe_div(n.dot(*p - *o), n.dot(*w));
    o.add_scaled(*w, t)
}

/// The number that picks the emitter for next-event estimation (`EmitterTable::sample`), or
/// its dimension skipped where nothing reads it (one emitter of few triangles, or an NLOS
/// scan's laser points, `sampled` false): computing a Sobol pair for it cost 2 % of a
/// Cornell-box render. The numbers drawn after it, hence the render, are the same.
#[inline(always)]
pub fn draw_select<R: Real>(ctx: &RenderContext, sampler: &mut PathSampler, sampled: bool) -> R::Value {
    if sampled && ctx.emitters.reads_select() {
        sampler.next::<R::Value>()
    } else {
        sampler.skip();
        R::Value::zero()
    }
}
