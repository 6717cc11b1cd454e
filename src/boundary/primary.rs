//! The primary boundary term: silhouettes (and flat-shading creases) seen from the camera are
//! discontinuities of the pixel integrand, sampled in image space (Li et al. 2018, "Differentiable
//! Monte Carlo ray tracing through edge sampling", primary visibility).
//!
//! The interior estimator keeps each camera ray fixed on the film (its first vertex moves
//! along the ray), so pixel j measures I_j(θ) = ∫ h_j(u) L(u, θ) du over a fixed film, with
//! h_j the normalised pixel filter and L the transient radiance through film point u. L jumps
//! across the projected discontinuity edges, which move with the geometry. The transport
//! theorem with discontinuities (supplemental Eq. 18, on the film: it does not move, so only
//! the boundary integral is new) adds
//!
//! ```text
//!   dI_j/dθ ⊇ ∫_{projected edges} h_j(u) · ΔL(u) · V(u) dℓ(u),   ΔL = L⁻ − L⁺  (Eq. 19)
//! ```
//!
//! with n the film normal of the projected edge, L^∓ the radiance just on the −n and +n sides,
//! and V = u̇ · n the film normal velocity: u̇ = (∂π/∂x) · ẋ, the pinhole projection's
//! Jacobian applied to the edge point's 3-D velocity ẋ = `motion.velocity(k, shape, x)`.
//! The product ΔL·V does not depend on which of the two normals is n, so no inside/outside
//! convention is needed. Both L⁻ and L⁺ are transients: each side's path is binned by its own
//! optical path length through S_e, so a plate moving towards the camera changes its arrival
//! time (interior) and its silhouette (this term). In path space this is the boundary of the
//! first segment of Eqs. 30–31, with x₀ the eye.
//!
//! Estimator: a film point u is drawn on the edges with density 1/ℓ_total per pixel of
//! projected length ([`SilhouetteSet`]), jittered: sample i of N in the i-th of N equal parts
//! of the concatenated length; an edge point hidden from the eye is skipped (both
//! sides would see the same occluder, ΔL = 0): hidden when the eye ray meets a surface clearly
//! before it, or a face other than the edge's own before it at all (a back crease just behind
//! a silhouette, which a relative margin alone would call seen), unless that face's plane
//! passes through the edge point itself (within 2ε: the floor under the bottom edge of a box
//! resting on it, a contact edge). Otherwise two camera rays through u ∓ ε_∓·n are traced
//! by the ordinary path kernel with common random numbers (`trace_packet_from`, four samples
//! per packet of eight lanes). ε_∓ is [`SIDE_OFFSET_PX`],
//! shortened to half the width of the edge's own face on that side along n: a face seen
//! nearly edge-on beside a silhouette projects to a sliver thinner than a fixed offset, and a
//! side ray past it would take the silhouette's jump for the crease's. A side ray only finds
//! its side's surface: the side path takes the OPL of the point where the edge's own ray
//! (through u) meets that surface's plane, the limit ε → 0, and where the surface is one of
//! the edge's own faces it also starts a few offsets from that point (`PrimaryRays::limit`;
//! on other surfaces its vertex stays at the side ray's hit, whose light is unambiguous).
//! From the side ray's own hit, a face seen nearly edge-on put the inside's light up to half
//! the face's depth late, and a floor seen at 89° behind a silhouette its light 28 mm of OPL
//! early; the time-summed image shows neither (tests/boundary_primary.rs,
//! `a_balls_limbs_send_their_light_to_the_bins_it_arrives_in`,
//! `a_background_seen_edge_on_sends_its_light_to_the_bins_it_arrives_in`). Their difference is
//! splatted with weight h_j(u)·V_k / (pdf · N) into every pixel j the filter reaches, in
//! derivative film k. N = `spp_boundary` × pixels samples are split into fixed chunks traced in
//! parallel; each chunk keeps its jumps (only the bins the side paths reached) and they are
//! splatted in chunk order, so the same seed gives the same bytes for any thread count, and no
//! chunk holds a full-frame film.

use super::edges::{CoplanarNeighbours, Edge, build_edges};
use super::silhouette::{Pinhole, SilhouetteSet, Z_NEAR};
use crate::film::{TileFilm, Transient};
use crate::integrator::RenderContext;
use crate::integrator::deposit::PathCounts;
use crate::integrator::path::{PacketLanes, PathStart, PrimaryRays, trace_packet_from};
use crate::integrator::surface::self_intersection_eps;
use crate::kernel::{PathSampler, V3, f32x8};
use crate::params::MAX_PARAMS;
use crate::shard::Shard;
use glam::{DVec2, DVec3, Vec3};
use rayon::prelude::*;

/// Offset of the two side rays from the projected edge, pixels. A discontinuity the eye sees
/// closer than this to the silhouette is inside the jump the side rays measure; the secondary
/// term leaves the shadow edges there to this term (`steps_over`).
pub const SIDE_OFFSET_PX: f64 = 1e-3;

/// Most faces a side offset walks through to find where the own face's surface ends
/// (`Estimator::surface_walk`): a fan of coplanar slivers around a vertex the line passes
/// through ends the walk there.
const MAX_COPLANAR_WALK: usize = 16;

/// Per shape, whether a parameter moves it: the shapes whose edges the primary stage samples.
pub(super) fn moving_shapes(ctx: &RenderContext) -> Vec<bool> {
    let mut moving = vec![false; ctx.scene.shapes.len()];
    for (s, _) in ctx.motion.fields.iter().flatten() {
        moving[*s] = true;
    }
    moving
}

/// Whether the primary stage's side rays step over the film point of `behind` at a silhouette
/// of the edge through `x_b` (direction `along`): `behind` lies farther from the eye than x_B
/// and its film point within [`SIDE_OFFSET_PX`] of the edge's projected line at x_B. Such a
/// point's discontinuity (a shadow edge the eye sees right beside the silhouette that casts
/// it, as under a light at the camera) is already inside the primary term's jump, whose far
/// side ray lands past it; the secondary term must not count it a second time.
pub(super) fn steps_over(pin: &Pinhole, x_b: DVec3, along: DVec3, behind: DVec3) -> bool {
    let (z_b, z_s) = (pin.depth(x_b), pin.depth(behind));
    if !(z_b >= Z_NEAR && z_s > z_b) {
        return false;
    }
    let d = pin.film(behind) - pin.film(x_b);
    let t = pin.film_velocity(x_b, along).normalize_or_zero();
    let off = if t == DVec2::ZERO {
        d.length()
    } else {
        d.perp_dot(t).abs()
    };
    off < SIDE_OFFSET_PX
}
/// Samples per chunk (the unit of parallel work and of the fixed merge order).
const CHUNK: u64 = 2048;
/// Seed streams: edge points and side paths are independent of the interior's paths.
const EDGE_STREAM: u64 = 0x5052_494D_4544_4745;
const PATH_STREAM: u64 = 0x5052_494D_5041_5448;
/// Relative margin before the edge point when testing whether the eye sees it: a false
/// "hidden" would bias. Within the margin only the edge's own faces may be met first (see
/// `Estimator::sample`): a false "visible" point just behind a silhouette would count its jump.
const VISIBILITY_MARGIN: f64 = 1e-3;

/// What the primary-edge stage did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PrimaryStats {
    /// Film points drawn on edges.
    pub samples: u64,
    /// Of those, seen by the eye and moving (two paths traced each).
    pub traced: u64,
    /// Side-path contributions and edge weights dropped because they were not finite.
    pub non_finite: u64,
}

/// The primary boundary term of every parameter in `ctx.motion` order: one derivative
/// transient each, `[H, W, T, C]` like the interior's, to be added to it. `spp_boundary` × W × H
/// film points are drawn on the edges (two side paths each where the eye sees them); `seed`
/// may be the interior's: this stage derives its own streams. Zero (and nothing traced) when
/// no parameter moves geometry, `spp_boundary` is 0 or the scene is an NLOS capture.
pub fn render_primary(ctx: &RenderContext, spp_boundary: u32, seed: u64, pool: &rayon::ThreadPool) -> Vec<Transient> {
    let edges = build_edges(&ctx.scene.geometry, ctx.scene.offset_scale);
    render_primary_with_stats(ctx, &edges, spp_boundary, seed, Shard::WHOLE, pool).0
}

/// [`render_primary`] with its tallies, for the samples of `shard` (normalised by all
/// `spp_boundary · W · H` samples, so the shards' films add up to the whole), over `edges`,
/// the scene's edge list (`build_edges`, which the secondary pass shares).
pub fn render_primary_with_stats(
    ctx: &RenderContext,
    edges: &[Edge],
    spp_boundary: u32,
    seed: u64,
    shard: Shard,
    pool: &rayon::ThreadPool,
) -> (Vec<Transient>, PrimaryStats) {
    let scene = ctx.scene;
    let (w, h) = (scene.film.width as usize, scene.film.height as usize);
    let films = ctx.motion.len().min(MAX_PARAMS);
    let mut out = Transient::zeros_many(films, w, h, scene.film.axis, scene.film.channels);
    // Bands of rows add each wave's jumps in parallel, each band every jump in sample order:
    // a pixel lies in one band, so neither the band count nor the thread count changes a byte.
    let bands = super::row_bands(h, pool);
    let mut sums: Vec<Vec<SumFilm>> = (0..bands)
        .map(|b| {
            let rows = b * h / bands..(b + 1) * h / bands;
            out.iter().map(|t| SumFilm::new(t, rows.clone())).collect()
        })
        .collect();
    let stats = for_each_wave(
        ctx,
        edges,
        spp_boundary,
        seed,
        shard,
        pool,
        |jumps| jumps,
        |wave| {
            pool.install(|| {
                sums.par_iter_mut().for_each(|band| {
                    wave.iter().flatten().for_each(|jump| jump.splat(ctx, band));
                })
            })
        },
    );
    for band in &sums {
        band.iter().zip(out.iter_mut()).for_each(|(s, t)| s.store(t));
    }
    (out, stats)
}

/// The primary term contracted with an adjoint volume (`crate::adjoint`): Σ over the jumps
/// of ⟨∂L/∂I, h_j·weight_k·(L⁻ − L⁺)⟩, per parameter, without a derivative film.
pub fn primary_adjoint(
    ctx: &RenderContext,
    edges: &[Edge],
    spp_boundary: u32,
    seed: u64,
    shard: Shard,
    pool: &rayon::ThreadPool,
    adjoint: &Transient,
) -> ([f64; MAX_PARAMS], PrimaryStats) {
    // each chunk's jumps contracted where they were traced, the chunks' sums added in chunk
    // order (chunks have a fixed size: the same gradient for any thread count)
    let mut grad = [0.0f64; MAX_PARAMS];
    let contract = |jumps: Vec<Jump>| {
        let mut part = [0.0f64; MAX_PARAMS];
        jumps.iter().for_each(|jump| jump.contract(ctx, adjoint, &mut part));
        part
    };
    let stats = for_each_wave(ctx, edges, spp_boundary, seed, shard, pool, contract, |parts| {
        for part in parts {
            grad.iter_mut().zip(part).for_each(|(g, p)| *g += p);
        }
    });
    (grad, stats)
}

/// Draws the primary-edge samples of `shard` in chunks of a fixed size, maps each chunk's
/// jumps by `per_chunk` on the thread that traced them, and hands the results to `consume`,
/// a wave at a time: each wave's chunks in sample order (the same order for any thread count).
#[allow(clippy::too_many_arguments)]
fn for_each_wave<T: Send>(
    ctx: &RenderContext,
    edges: &[Edge],
    spp_boundary: u32,
    seed: u64,
    shard: Shard,
    pool: &rayon::ThreadPool,
    per_chunk: impl Fn(Vec<Jump>) -> T + Sync,
    mut consume: impl FnMut(&[T]),
) -> PrimaryStats {
    let scene = ctx.scene;
    let (w, h) = (scene.film.width as usize, scene.film.height as usize);
    let derivs = ctx.motion.len().min(MAX_PARAMS);
    let mut stats = PrimaryStats::default();
    // an NLOS capture's SPAD sees fixed points of the relay wall: no silhouette moves over
    // its film (the edges its sensor points see are the secondary pass's, `secondary.rs`)
    if spp_boundary == 0 || derivs == 0 || !ctx.motion.moves_geometry() || ctx.nlos.is_some() {
        return stats;
    }
    let moving = moving_shapes(ctx);
    let pin = Pinhole::new(&scene.camera, scene.film.width, scene.film.height);
    let margin = ctx.camera.filter().radius() as f64;
    let set = SilhouetteSet::build(&scene.geometry, edges, &pin, margin, |s| moving[s as usize]);
    if set.is_empty() {
        return stats;
    }
    let total = spp_boundary as u64 * (w * h) as u64;
    let est = Estimator {
        ctx,
        edges,
        coplanar: CoplanarNeighbours::build(&scene.geometry, |s| moving[s as usize]),
        set: &set,
        pin: &pin,
        seed,
        weight: set.total_length / total as f64,
        samples: total,
        derivs,
    };
    let mine = shard.range(total);
    let trace = |ids: std::ops::Range<u64>| {
        let (jumps, tally) = match scene.film.channels {
            1 => est.chunk::<1>(ids.start, ids.end),
            _ => est.chunk::<3>(ids.start, ids.end),
        };
        (per_chunk(jumps), tally)
    };
    super::waves::in_waves(pool, mine, CHUNK, &ctx.cancel, trace, |done| {
        let (parts, tallies): (Vec<T>, Vec<PrimaryStats>) = done.into_iter().unzip();
        consume(&parts);
        for s in &tallies {
            stats.samples += s.samples;
            stats.traced += s.traced;
            stats.non_finite += s.non_finite;
        }
    });
    stats
}

/// The traced jump L⁻ − L⁺ of one sample, over bins `lo..` (channels interleaved), and of its
/// time-integrated value, with the weight V_k / (pdf · N) of each parameter.
struct Jump {
    film: DVec2,
    weight: [f32; MAX_PARAMS],
    lo: usize,
    delta: Vec<f32>,
    steady: [f32; 3],
}

impl Jump {
    /// Adds h_j · weight_k · (L⁻ − L⁺) to every pixel j of the films' rows that the filter
    /// reaches, in film k.
    fn splat(&self, ctx: &RenderContext, films: &mut [SumFilm]) {
        let c_n = ctx.scene.film.channels;
        let (fx, fy) = (self.film.x as f32, self.film.y as f32);
        let Some(rows) = films.first().map(|f| f.rows.start as u32..f.rows.end as u32) else {
            return;
        };
        ctx.camera.for_each_pixel_in_rows(fx, fy, rows, |px, py, hj| {
            for (film, &wk) in films.iter_mut().zip(&self.weight) {
                let w = (hj * wk) as f64;
                if w == 0.0 {
                    continue;
                }
                let pixel = (py as usize - film.rows.start) * film.width + px as usize;
                let base = (pixel * film.bins + self.lo) * c_n;
                let bins = &mut film.data[base..base + self.delta.len()];
                bins.iter_mut().zip(&self.delta).for_each(|(d, &v)| *d += w * v as f64);
                let steady = &mut film.steady[pixel * c_n..(pixel + 1) * c_n];
                steady
                    .iter_mut()
                    .zip(&self.steady)
                    .for_each(|(d, &v)| *d += w * v as f64);
            }
        });
    }
}

impl Jump {
    /// Adds ⟨∂L/∂I, h_j · weight_k · (L⁻ − L⁺)⟩ over every pixel j the filter reaches to
    /// `grad[k]`.
    fn contract(&self, ctx: &RenderContext, adjoint: &Transient, grad: &mut [f64; MAX_PARAMS]) {
        let (fx, fy) = (self.film.x as f32, self.film.y as f32);
        ctx.camera.for_each_pixel(fx, fy, |px, py, hj| {
            let base = adjoint.index(px as usize, py as usize, self.lo, 0);
            let a = &adjoint.data[base..base + self.delta.len()];
            let dot: f64 = a.iter().zip(&self.delta).map(|(&a, &d)| a as f64 * d as f64).sum();
            if dot == 0.0 {
                return;
            }
            for (g, &wk) in grad.iter_mut().zip(&self.weight) {
                *g += (hj * wk) as f64 * dot;
            }
        });
    }
}

/// Rows of a derivative film while the jumps are added: f64, like the interior's derivative
/// tiles, so that ± jumps cancel without f32 rounding of the running sums.
struct SumFilm {
    width: usize,
    bins: usize,
    rows: std::ops::Range<usize>,
    data: Vec<f64>,
    steady: Vec<f64>,
}

impl SumFilm {
    /// Rows `rows` of a film shaped like `t`.
    fn new(t: &Transient, rows: std::ops::Range<usize>) -> Self {
        let (per_row, steady_row) = (t.data.len() / t.height.max(1), t.steady.len() / t.height.max(1));
        Self {
            width: t.width,
            bins: t.axis.bins,
            data: vec![0.0; per_row * rows.len()],
            steady: vec![0.0; steady_row * rows.len()],
            rows,
        }
    }
    /// Writes these rows into `t`.
    fn store(&self, t: &mut Transient) {
        let (per_row, steady_row) = (t.data.len() / t.height.max(1), t.steady.len() / t.height.max(1));
        let (d, s) = (self.rows.start * per_row, self.rows.start * steady_row);
        t.data[d..d + self.data.len()]
            .iter_mut()
            .zip(&self.data)
            .for_each(|(o, &v)| *o = v as f32);
        t.steady[s..s + self.steady.len()]
            .iter_mut()
            .zip(&self.steady)
            .for_each(|(o, &v)| *o = v as f32);
    }
}

/// A film point on an edge that the eye sees, with its weight per parameter.
#[derive(Clone, Copy, Debug)]
struct SideSample {
    id: u64,
    film: DVec2,
    normal: DVec2,
    /// Film offsets of the −n and +n side rays (pixels).
    offset: [f64; 2],
    /// Per side, the edge's faces (`u32::MAX` for a border edge's missing one) and the faces
    /// coplanar with them that the side's offset point lands on.
    own: [[u32; 4]; 2],
    /// V_k / (pdf · N) per parameter.
    weight: [f32; MAX_PARAMS],
}

/// The faces a side offset's line crosses on one surface, each with the distance along the
/// line at which it leaves that face (`Estimator::surface_walk`).
#[derive(Default)]
struct SurfaceWalk {
    faces: [(u32, f64); MAX_COPLANAR_WALK],
    len: usize,
}

impl SurfaceWalk {
    /// Where the line leaves the surface.
    fn exit(&self) -> f64 {
        self.faces[self.len - 1].1
    }

    /// The face the line is on at distance `s`, where that is a face beyond the first
    /// (`u32::MAX` on the first face, the edge's own, or past the walk).
    fn face_at(&self, s: f64) -> u32 {
        match self.faces[..self.len].iter().position(|&(_, exit)| s < exit) {
            Some(k) if k > 0 => self.faces[k].0,
            _ => u32::MAX,
        }
    }
}

struct Estimator<'a> {
    ctx: &'a RenderContext<'a>,
    edges: &'a [Edge],
    coplanar: CoplanarNeighbours,
    set: &'a SilhouetteSet,
    pin: &'a Pinhole,
    seed: u64,
    /// 1 / (pdf · N) = total projected length / N.
    weight: f64,
    /// N, the number of film points drawn on the edges.
    samples: u64,
    derivs: usize,
}

impl Estimator<'_> {
    fn chunk<const C: usize>(&self, first: u64, end: u64) -> (Vec<Jump>, PrimaryStats) {
        let mut jumps = Vec::new();
        let mut stats = PrimaryStats::default();
        let mut batch = Vec::with_capacity(4);
        for id in first..end {
            stats.samples += 1;
            if let Some(s) = self.sample(id, &mut stats) {
                stats.traced += 1;
                batch.push(s);
                if batch.len() == 4 {
                    stats.non_finite += self.trace_sides::<C>(&batch, &mut jumps);
                    batch.clear();
                }
            }
        }
        if !batch.is_empty() {
            stats.non_finite += self.trace_sides::<C>(&batch, &mut jumps);
        }
        (jumps, stats)
    }

    /// Draws film point `id` on the edges; None when the eye does not see it, it does not
    /// move under any parameter, or its weight is not finite (counted, never splatted).
    fn sample(&self, id: u64, stats: &mut PrimaryStats) -> Option<SideSample> {
        // Jittered: sample i lies in the i-th of N equal parts of the concatenated length.
        let xi = PathSampler::new(self.seed ^ EDGE_STREAM, &[id]).next::<f32>();
        let e = self.set.sample_at((id as f64 + xi as f64) / self.samples as f64)?;
        let projected = &self.set.edges[e.index];
        let edge = &self.edges[projected.edge];
        let shape = projected.shape as usize;
        let x = e.world.as_vec3();
        let mut weight = [0.0f32; MAX_PARAMS];
        for (k, wk) in weight.iter_mut().enumerate().take(self.derivs) {
            let v = self.ctx.motion.velocity(k, shape, x).as_dvec3();
            let vn = self.pin.film_velocity(e.world, v).dot(e.normal);
            *wk = (vn * self.weight) as f32;
        }
        if !weight.iter().all(|w| w.is_finite()) {
            stats.non_finite += 1;
            return None;
        }
        if weight.iter().all(|&w| w == 0.0) {
            return None;
        }
        let to = e.world - self.pin.eye;
        let dist = to.length();
        let dir = (to / dist).as_vec3().to_array();
        let tfar = (dist * (1.0 + VISIBILITY_MARGIN)) as f32;
        if let Some(hit) = self
            .ctx
            .accel
            .intersect1(self.pin.eye.as_vec3().to_array(), dir, 0.0, tfar)
        {
            let t = hit.t as f64;
            let own = hit.prim == edge.face0 || Some(hit.prim) == edge.face1;
            // A face whose plane passes through the edge point itself (within 2ε) supports it:
            // the floor under a box resting on it. Its hit lands on either side of x_B by
            // rounding, and at a grazing view farther than 2ε along the ray; it hides nothing
            // (each side ray sees what is there), so it never skips the point.
            let eps = self_intersection_eps(&V3::<f32>::splat(x), self.ctx.scene.offset_scale) as f64;
            let p0 = self.ctx.tri_verts[hit.prim as usize][0].as_dvec3();
            let supports = self.ctx.face_normal64(hit.prim).dot(e.world - p0).abs() <= 2.0 * eps;
            // Hidden: a surface clearly in front, or another face than the edge's own in front
            // of it within the margin (a back crease just behind a silhouette: its side rays
            // would straddle that silhouette and count its jump a second time).
            if t < dist * (1.0 - VISIBILITY_MARGIN) || (!own && !supports && t < dist) {
                return None;
            }
        }
        let (offset, landing) = self.side_offsets(edge, e.film, e.normal);
        let faces = [edge.face0, edge.face1.unwrap_or(u32::MAX)];
        Some(SideSample {
            id,
            film: e.film,
            normal: e.normal,
            offset,
            own: landing.map(|l| [faces[0], faces[1], l[0], l[1]]),
            weight,
        })
    }

    /// Offsets of the two side rays: [`SIDE_OFFSET_PX`], shortened to half the extent of the
    /// edge's own face on that side (its projected triangle, along ±n from `film`), so that
    /// the side ray still sees that face. A face seen nearly edge-on projects to a sliver
    /// thinner than the fixed offset; a side ray beyond it would see what lies past the
    /// sliver's far edge (often the background behind a silhouette) and count that edge's
    /// jump a second time. The extent runs on through faces coplanar with the own face
    /// ([`Estimator::surface_walk`]); the second array holds, per side, the faces coplanar
    /// with an own face that the offset point lands on (`u32::MAX` for none), which the side
    /// path then takes for the edge's own (`PrimaryRays::own`).
    fn side_offsets(&self, edge: &Edge, film: DVec2, normal: DVec2) -> ([f64; 2], [[u32; 2]; 2]) {
        let geo = &self.ctx.scene.geometry;
        let world = |v: u32| geo.positions[v as usize].as_dvec3();
        let mut offset = [SIDE_OFFSET_PX; 2];
        let mut landing = [[u32::MAX; 2]; 2];
        let (a, b) = (world(edge.v0), world(edge.v1));
        if self.pin.depth(a) < Z_NEAR || self.pin.depth(b) < Z_NEAR {
            return (offset, landing);
        }
        let faces = [Some((edge.face0, edge.opposite0)), edge.face1.zip(edge.opposite1)];
        let mut walks = [None, None];
        for (j, (face, c)) in faces.into_iter().enumerate().filter_map(|(j, f)| Some((j, f?))) {
            let far = world(c);
            if self.pin.depth(far) < Z_NEAR {
                continue;
            }
            let side = if (self.pin.film(far) - film).dot(normal) < 0.0 {
                0
            } else {
                1
            };
            let m = if side == 0 { -normal } else { normal };
            // the edge's slot in its face: the one whose far vertex is `c`
            let tri = geo.indices[face as usize];
            let slot = (0..3).find(|&k| tri[(k + 2) % 3] == c).unwrap_or(0);
            let walk = self.surface_walk(face, slot, film, m);
            offset[side] = offset[side].min(0.5 * walk.exit());
            walks[j] = Some((side, walk));
        }
        for (j, (side, walk)) in walks.into_iter().enumerate().filter_map(|(j, w)| Some((j, w?))) {
            landing[side][j] = walk.face_at(offset[side]);
        }
        (offset, landing)
    }

    /// The faces a line from `film` along `m` crosses on the surface that `face` begins at its
    /// edge slot `slot`: `face`, then the faces coplanar with it beyond its far edges
    /// (`CoplanarNeighbours`), up to [`MAX_COPLANAR_WALK`] and no farther than the side offset
    /// could reach. A sliver triangle along a silhouette (a mesh whose border an exporter
    /// split with a vertex a hair off the line) ends within rounding of the edge, and the side
    /// ray on it was shortened until f32 film points and directions no longer told it from
    /// the edge: the sliver's border lost 2.5 % of its jump at a width of 10⁻⁵ of the plate,
    /// 14 % at 10⁻⁶. Its coplanar neighbour goes on with no discontinuity between them (the
    /// edge is dropped), so the side ray may land there. A face behind the near plane ends
    /// the walk with no limit (no shortening, as before).
    fn surface_walk(&self, face: u32, slot: usize, film: DVec2, m: DVec2) -> SurfaceWalk {
        let geo = &self.ctx.scene.geometry;
        let mut walk = SurfaceWalk::default();
        let (mut face, mut slot, mut s_in) = (face, slot, 0.0f64);
        while walk.len < MAX_COPLANAR_WALK {
            let tri = geo.indices[face as usize].map(|v| geo.positions[v as usize].as_dvec3());
            let p = tri.map(|x| self.pin.film(x));
            // the first of the face's two other edges that the line film + s·m crosses
            let exit = [(slot + 1) % 3, (slot + 2) % 3]
                .into_iter()
                .filter_map(|k| {
                    let (q, d) = (p[k], p[(k + 1) % 3] - p[k]);
                    let den = m.perp_dot(d);
                    let s = (q - film).perp_dot(d) / den;
                    (den != 0.0 && s > s_in).then_some((s, k))
                })
                .min_by(|x, y| x.0.total_cmp(&y.0));
            let behind = tri.iter().any(|&x| self.pin.depth(x) < Z_NEAR);
            let s = match exit {
                Some((s, _)) if !behind => s,
                _ => f64::INFINITY,
            };
            walk.faces[walk.len] = (face, s);
            walk.len += 1;
            match exit.and_then(|(_, k)| self.coplanar.across(face, k)) {
                Some((next, next_slot)) if s < 2.0 * SIDE_OFFSET_PX => (face, slot, s_in) = (next, next_slot, s),
                _ => break,
            }
        }
        walk
    }

    /// Traces the −n and +n sides of up to four samples in one packet (lanes 2i and 2i + 1,
    /// same path id: common random numbers) and keeps their jumps L⁻ − L⁺. Returns the
    /// number of non-finite side contributions the kernel dropped.
    fn trace_sides<const C: usize>(&self, batch: &[SideSample], jumps: &mut Vec<Jump>) -> u64 {
        let ctx = self.ctx;
        let axis = ctx.scene.film.axis;
        let mut lanes = PacketLanes {
            px: std::array::from_fn(|i| i as u32),
            py: [0; 8],
            ids: [0; 8],
            count: 2 * batch.len(),
            spp: 0,
        };
        let (mut dirs, mut limit, mut own) = ([Vec3::Z; 8], [Vec3::Z; 8], [[u32::MAX; 4]; 8]);
        for (i, s) in batch.iter().enumerate() {
            let edge_ray = ctx.camera.direction(s.film.x as f32, s.film.y as f32);
            for (side, sign) in [(0, -1.0), (1, 1.0)] {
                let f = s.film + s.normal * (sign * s.offset[side]);
                dirs[2 * i + side] = ctx.camera.direction(f.x as f32, f.y as f32);
                limit[2 * i + side] = edge_ray;
                own[2 * i + side] = s.own[side];
                lanes.ids[2 * i + side] = s.id;
            }
        }
        let mut scratch = TileFilm::new(0, 0, 8, 1, &axis, C, 0).with_steady(ctx.steady);
        let mut counts = PathCounts::default();
        // each side's light at the edge itself (`PrimaryRays::limit`)
        let rays = PrimaryRays {
            dirs,
            limit: Some(limit),
            own,
        };
        trace_packet_from::<f32x8, C, _>(
            ctx,
            self.seed ^ PATH_STREAM,
            &lanes,
            PathStart::Rays(&rays),
            &mut scratch,
            &mut counts,
        );
        let mut sides = [Transient::zeros(8, 1, axis, C)];
        scratch.store_into(&mut sides);
        let sides = &sides[0];
        let block = axis.bins * C;
        for (i, s) in batch.iter().enumerate() {
            let (m, p) = (2 * i * block, (2 * i + 1) * block);
            let delta: Vec<f32> = (0..block).map(|j| sides.data[m + j] - sides.data[p + j]).collect();
            let mut steady = [0.0f32; 3];
            for (c, v) in steady.iter_mut().enumerate().take(C) {
                *v = sides.steady[2 * i * C + c] - sides.steady[(2 * i + 1) * C + c];
            }
            // Only the bins the two paths reached (S_e.range of their OPLs), whole bins.
            let lo = delta.iter().position(|&v| v != 0.0).unwrap_or(block) / C;
            let hi = delta.iter().rposition(|&v| v != 0.0).map_or(lo, |h| h / C + 1);
            if lo >= hi && steady.iter().all(|&v| v == 0.0) {
                continue;
            }
            jumps.push(Jump {
                film: s.film,
                weight: s.weight,
                lo,
                delta: delta[lo * C..hi.max(lo) * C].to_vec(),
                steady,
            });
        }
        counts.non_finite
    }
}
