//! Secondary edges: the boundary integral over visibility discontinuities of path segments
//! anywhere in the scene (Algorithm 2; supplemental Eqs. 18–19, 30–32).
//!
//! A boundary ray (x_B, ω) on a silhouette edge (Eq. 32) is traced both ways: x_S = first hit
//! along ω, x_L = first hit along −ω. The segment x_L → x_S grazes the edge: it lies on the
//! discontinuity set of G·V (Eqs. 30–31), where V jumps from 1 (the segment passes beside the
//! edge's faces) to 0 (it passes through them). With x_L held fixed, Eq. 18 on the surface of
//! x_S gives ∫ Δ(f) V_∂ dℓ(x_S) along the edge's shadow from x_L; Δf (Eq. 19) is the
//! unoccluded path throughput f_L · G(x_L, x_S) · f_S on the free side and 0 on the blocked
//! one. Changing variables from dA(x_L) dℓ(x_S) to dℓ(x_B) dω (the Jacobian J_B):
//!
//!   dA(x_L) dℓ(x_S) = t_L (t_L + t_S) sin α / (|cos_L| sin β) · dℓ(x_B) dω,
//!
//! (α: angle between edge and ω; β: between ω and the shadow curve). With the normal
//! velocity of `velocity.rs`, G · J_B · V_∂ collapses to
//!
//!   −s_o · (dh̃/dθ) / (ℓ_e (t_L + t_S)),
//!
//! where s_o = ±1 is the side of Π(x_L, edge) holding the edge's faces (the blocked side) and
//! ℓ_e the edge length; sin α, the cosines and |N| cancel. Divided by the sampling density
//! p_e/ℓ_e · p_ω (and the guiding density), each boundary ray contributes
//!
//!   f_L · f_S · (−s_o · dh̃/dθ) / ((t_L + t_S) · p_e · p_ω · p_guide)
//!
//! per parameter, binned through S_e (supplemental Eq. 24) at d = d_L + η|x_S − x_L| + d_S into
//! the pixel the sensor subpath reaches, η being the index of the medium the segment crosses. d is f64; when the render carries f64 OPLs
//! (`integrator::opl`) every length in it is measured between f64 points (hits rebuilt from
//! Embree's barycentrics, light samples from `EmitterTable::sample`'s `p64`), else it is the
//! sum of the f32 lengths the rays returned. dh̃/dθ uses the velocity of each point's own parameterisation, as
//! the interior does: material form for x_L, the edge and x_S, except that x_S moves along its
//! camera ray (ray form) when it is the vertex connected to the camera.
//!
//! `contact.rs` finds x_S and x_L, and handles **contact edges** (an edge lying on another
//! surface, e.g. the base of an object resting on the floor), where one side of the segment has
//! zero length: the contact vertex counts once, with its departing segment and a weight of its
//! own (x_L = x_B makes N vanish, so the collapsed form above does not apply there).
//!
//! Two strategies split the integrand between them (a partition, so no MIS weights):
//! - A, edge-directed: ω from the silhouette directions of the edge (`edge_sampler.rs`);
//!   it estimates every term whose x_L reflects (x_L's radiance from next-event estimation
//!   and BSDF-sampled bounces), and the emission of an area light at x_L where it draws that
//!   line more densely than B does (below).
//! - B, light-directed: x_B on an edge and y on an emitter (next-event sampling) fix
//!   ω = (x_B − y)/|x_B − y| and x_L = y; it estimates the other terms where x_L emits, i.e.
//!   the edges of direct shadows, which A would find only when a random ray happens to hit a
//!   small light (and never for a point light or a laser spot). A laser spot moves along its
//!   beam (ray form, as in the interior). Not covered: an edge crossing the laser beam itself.
//!
//! Which of the two takes an area light's emission at x_L is decided per line by
//! `EmissionSplit`: the strategy whose evaluations draw the line (x_B, ω) more densely, n_A
//! p_A against n_B p_B, B's density per steradian being pdf_A(y)·t_L²/|cos_L|. Near a light
//! that is A: an occluder 1 mm under a 1.2 m light has its shadow's lines end within about a
//! millimetre of the edge's footprint on the light, a strip B's light points almost never
//! land in (renders read 0, or hundreds where one did), while half of A's directions at such an
//! edge meet the light. Any rule that both strategies evaluate alike on the same line keeps
//! the partition, hence the estimator unbiased; the densities only make it an efficient one.
//!
//! **Rough dielectrics.** Glass is not dark behind a visibility edge, yet the jump is still
//! ΔV = 1: the integral runs over path space, where a path that passes through glass has
//! vertices on its surfaces (the refractions), so the straight segment x_L → x_S through the
//! glass has V = 0 like any other blocked segment, and the paths through the glass are other
//! paths, whose own segments' discontinuities are sampled at their own edges (as in Zhang et
//! al. 2020 and psdr-cpu's rough dielectric). What glass changes is where the segment lies:
//! inside a dielectric (between two of its surfaces, or beside a liquid inside a glass) its
//! OPL is that medium's η times its length, and both subpaths start in that medium
//! (`Secondary::segment_eta`: the side of x_S or x_L the segment meets when either is a
//! dielectric's surface, else the medium around the segment, `integrator::medium`). The
//! subpaths then refract on the kernel's own lobes: the source side is the path tracer
//! (radiance transport), the sensor side the importance walk (importance transport, Veach
//! 1997 §5.2; it joins a rough dielectric vertex to the pinhole through its surface too).
//! Smooth (Dirac) dielectrics are refused (`render::check_materials`, supplemental assumption
//! A.4). Contact edges of a glass object resting on a surface are handled as an opaque
//! object's (the covered side's departing segment meets the glass's bottom face at zero
//! distance); no test covers that case yet.
//!
//! **NLOS captures** (`integrator::nlos`). The SPAD sees fixed wall points, so there is no
//! primary stage; the paths run from a laser point l on the relay wall through the hidden
//! scene to a sensor point s, both points deltas in position (l a point source with
//! I ∝ cos θ_l, s a point of importance ρ/π·cos θ_s), and every segment's visibility
//! discontinuity is a secondary edge. Strategy A joins its sensor subpath to a sensor point
//! drawn uniformly (the film's), and its source subpath to that sensor's laser points (the
//! lane's own, or all of them in an exhaustive scan). Strategy B spends half of its draws on
//! segments from a laser point (its light point: a laser point drawn uniformly, and in an
//! exhaustive scan a sensor point too) and half on segments that end at a sensor point
//! (`Secondary::prepare_sensor`: strategy B's geometry with s in the light's place). In a
//! confocal scan l = s, and a path s → x → s crosses one discontinuity where both of its
//! segments cross it: it is counted once (`coincide`). Every vertex is in material form
//! (the interior's first vertex from s is too). The laser's beam to the wall and the SPAD's
//! line of sight to a sensor point join two fixed points (`integrator::nlos`, decided once
//! per render): whether a hidden shape blocks them is a step in the parameters, whose
//! derivative is 0 except at the values where an edge lies on the line (there the transient
//! itself jumps), so they add no boundary term.
//!
//! Each strategy draws its inputs through a guiding grid (`guiding.rs`; uniform unless
//! guiding is on). `pass.rs` runs the strategies (budget split by a pilot) and bins their
//! paths.

use super::contact::{SegmentEnds, segment_ends};
use super::edge_sampler::{EdgeRecord, EdgeSampler};
use super::edges::{Edge, build_edges};
use super::guiding::GuideGrid;
use super::hit::{SurfaceHit, pre_length};
use super::primary::{moving_shapes, steps_over};
use super::silhouette::Pinhole;
use super::subpaths::{SegmentSample, SensorTerm, SourceTerm, Terms, subpaths};
use super::velocity::{Crossing, ray_form_velocity};
use crate::integrator::context::RenderContext;
use crate::integrator::deposit::PathCounts;
use crate::integrator::medium::{has_dielectric, medium_around, side_eta};
use crate::integrator::nlos::NlosSensor;
use crate::integrator::opl::{on_plane64, segment};
use crate::integrator::surface::self_intersection_eps;
use crate::integrator::trace::RayCounts;
use crate::kernel::{PathSampler, V3};
use crate::params::MAX_PARAMS;
use crate::scene::EmitterKind;
use glam::{DVec3, Vec3};

/// Edges that a parameter moves across themselves are drawn up to this many times more often
/// per metre (`edge_sampler`): their shadows move whatever else does (edges of static shapes
/// contribute only where x_L or x_S moves). Any positive factor keeps the estimator unbiased.
const MOVING_EDGE_FACTOR: f32 = 8.0;
/// The edge table of the secondary pass: each edge weighted by its length and silhouette
/// fraction (`EdgeSampler`) times 1 + (F − 1)·s, F = [`MOVING_EDGE_FACTOR`] and s ∈ [0, 1] the
/// edge's speed across itself relative to the fastest edge, for the parameter that moves it
/// most: the component of its velocity perpendicular to the edge (largest at either end,
/// as velocities are affine along an edge) over the largest such speed of any edge under that
/// parameter. An edge sliding along itself (the sides of a plate translated along them) moves
/// no discontinuity (its dh̃/dθ vanishes), so it is drawn as often as a static edge.
///
/// Edges whose silhouette lines can join no two points of the scene are left out
/// ([`edges_that_can_bound`]).
fn edge_sampler(ctx: &RenderContext, list: &[Edge]) -> EdgeSampler {
    let list = edges_that_can_bound(ctx, list);
    let list = &list[..];
    let geo = &ctx.scene.geometry;
    let params = ctx.motion.len();
    let cross_speed = |k: usize, shape: u32, v0: Vec3, v1: Vec3| -> f32 {
        let t = (v1 - v0).normalize_or_zero();
        [v0, v1]
            .iter()
            .map(|&x| {
                let v = ctx.motion.velocity(k, shape as usize, x);
                (v - t * t.dot(v)).length()
            })
            .fold(0.0, f32::max)
    };
    EdgeSampler::from_edges(geo, list, |edges| {
        let speeds: Vec<Vec<f32>> = edges
            .iter()
            .map(|r| (0..params).map(|k| cross_speed(k, r.shape, r.v0, r.v1)).collect())
            .collect();
        let fastest: Vec<f32> = (0..params)
            .map(|k| speeds.iter().map(|s| s[k]).fold(0.0, f32::max))
            .collect();
        speeds
            .iter()
            .map(|s| {
                let rel = (0..params)
                    .filter(|&k| fastest[k] > 0.0)
                    .map(|k| s[k] / fastest[k])
                    .fold(0.0f32, f32::max);
                1.0 + (MOVING_EDGE_FACTOR - 1.0) * rel.clamp(0.0, 1.0)
            })
            .collect()
    })
}

/// The edges of `list` whose silhouette lines may join two points of the scene (each a
/// surface point or a light at both ends: `edge_sampler::silhouettes_join_nothing`, with the
/// corners of the box holding every vertex, light and the camera). The others carry no
/// boundary term, and drawing them cost a quarter of the CPU of `scenes/diff_room.toml
/// --diff room_z` (a closed convex room, all its edges creases seen from inside) for
/// segments that never found a surface at both ends (until the forty-third session). Since
/// the forty-seventh, the boundary edges of a face with the whole scene on one side of its
/// plane are left out too (a room's floor and walls built of open rectangles, a ground under
/// everything): a ground far larger than the scene had drawn nearly every sample.
fn edges_that_can_bound(ctx: &RenderContext, list: &[Edge]) -> Vec<Edge> {
    let scene = ctx.scene;
    let geo = &scene.geometry;
    let lights = scene.emitters.iter().filter_map(|e| match e.kind {
        EmitterKind::Point { position, .. } | EmitterKind::Laser { position, .. } => Some(position),
        EmitterKind::Area { .. } => None,
    });
    let every = geo
        .positions
        .iter()
        .copied()
        .chain(lights)
        .chain([scene.camera.position]);
    let (lo, hi) = every.fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
        (lo.min(p), hi.max(p))
    });
    if !(lo.is_finite() && hi.is_finite()) {
        return list.to_vec();
    }
    let corners = super::edge_sampler::box_corners(lo, hi);
    // the renderer's smallest ray offset (`self_intersection_eps` at the render origin): a
    // point that far off a face's plane may be told apart from it wherever it lies. The offset
    // at the scene's largest coordinate, taken before (the forty-seventh session), grew with
    // anything far away: beside a 40 km ground (or a point light 30 km off) a panel 5 cm under
    // a ceiling light counted the light as in its plane, and its shadow's derivative was 0.
    let slack = scene.offset_scale * crate::integrator::surface::OFFSET_PER_COORDINATE;
    list.iter()
        .copied()
        .filter(|e| !super::edge_sampler::silhouettes_join_nothing(geo, e, &corners, slack))
        .collect()
}

/// Stream of strategy B (light-directed boundary rays), relative to strategy A's.
pub(super) const LIGHT_STREAM: u64 = 0x11D1_2EC7_0000_0003;

/// Which strategy estimates the emission of an area light at x_L (module documentation):
/// each strategy's edge table and how many evaluations it makes in the pass.
#[derive(Clone, Copy)]
pub(super) struct EmissionSplit<'t> {
    pub(super) edges: [&'t EdgeSampler; 2],
    pub(super) evaluations: [u64; 2],
}

impl EmissionSplit<'_> {
    /// Whether strategy A takes the emission of area emitter `e` at x_L, |cos_L| and `t_l`
    /// from x_B on edge `edge`, along ω (x_L → x_S): n_A p_A > n_B p_B, both per unit of edge
    /// length per steradian (the guiding grids' densities left out: any rule both strategies
    /// evaluate alike is a partition).
    fn edge_directed(&self, ctx: &RenderContext, edge: usize, omega: Vec3, e: u32, t_l: f32, cos_l: f32) -> bool {
        let n_b = self.b_density(ctx, edge, e, t_l, cos_l);
        self.a_silhouette_density(edge) > n_b
            && self.evaluations[0] as f64 * self.edges[0].pdf(edge, omega) as f64 > n_b
    }

    /// Whether [`Self::edge_directed`] can hold for some direction: A's density is one value
    /// over the edge's silhouette directions and 0 elsewhere, so below B's even at that
    /// value the line is B's without a look at its direction (most lines, far from their
    /// lights, end here).
    fn edge_directed_somewhere(&self, ctx: &RenderContext, edge: usize, e: u32, t_l: f32, cos_l: f32) -> bool {
        self.a_silhouette_density(edge) > self.b_density(ctx, edge, e, t_l, cos_l)
    }

    /// n_A p_A at any silhouette direction of edge `edge`.
    fn a_silhouette_density(&self, edge: usize) -> f64 {
        self.evaluations[0] as f64 * self.edges[0].silhouette_density(edge) as f64
    }

    /// n_B p_B: B's evaluations times its density of the line.
    fn b_density(&self, ctx: &RenderContext, edge: usize, e: u32, t_l: f32, cos_l: f32) -> f64 {
        let b = self.edges[1];
        let rec = &b.edges[edge];
        let len = (rec.v1 - rec.v0).length() as f64;
        let (t_l, cos_l) = (t_l as f64, cos_l.abs() as f64);
        self.evaluations[1] as f64 * b.edge_pmf(edge) as f64 / len * ctx.emitters.area_pdf(e) as f64 * t_l * t_l / cos_l
    }
}

/// One full boundary path: where it reaches the film, its OPL and emitter, its throughput
/// f_L·f_S (per channel, before the pixel filter) and its derivative weight per parameter.
#[derive(Clone, Copy, Debug)]
pub struct BoundaryPath {
    pub fx: f32,
    pub fy: f32,
    /// d = d_L + d_B + d_S, f64 (see the module documentation).
    pub opl: f64,
    pub emitter: u32,
    pub rgb: [f32; 3],
    pub weight: [f32; MAX_PARAMS],
}

/// How x_L moves with the parameters: not at all (point light), with its surface (material
/// form), or along a fixed laser ray as its surface moves (ray form, as the interior's laser
/// spot).
#[derive(Clone, Copy, Debug)]
pub(super) enum SourceMotion {
    Fixed,
    Material(usize),
    Ray { shape: usize, dir: Vec3, n: Vec3 },
}

/// dh̃/dθ_k with x_S in material form and in ray form (the camera-connected vertex).
#[derive(Clone, Copy, Debug)]
struct Rates {
    material: [f32; MAX_PARAMS],
    ray: [f32; MAX_PARAMS],
}

impl Rates {
    fn is_zero(&self, params: usize) -> bool {
        self.material[..params]
            .iter()
            .chain(&self.ray[..params])
            .all(|&r| r == 0.0)
    }
}

/// What a worker keeps between boundary samples: term lists, and its tallies.
#[derive(Default)]
pub(super) struct Scratch {
    terms: Terms,
    /// Rays of the boundary rays and of the subpaths; subpath terms dropped as not finite.
    pub(super) counts: PathCounts,
    pub(super) valid: u64,
    /// The edge the last prepared sample drew (None when it drew none).
    pub(super) edge: Option<usize>,
}

impl Scratch {
    pub(super) fn rays(&self) -> u64 {
        self.counts.rays.intersect + self.counts.rays.occluded
    }
}

/// A boundary sample whose segment has been found, waiting for its subpaths: the weight of
/// its paths is `common · dh̃/dθ_k` (`rates`), times the subpaths' terms.
#[derive(Clone, Copy, Debug)]
pub(super) struct Prepared {
    pub(super) segment: SegmentSample,
    rates: Rates,
    common: f32,
    /// The point of the unit cube it was drawn from (the pilot's guiding cell).
    pub(super) u: [f32; 3],
    /// The edge it was drawn on (its index in the pass's edge table).
    pub(super) edge: usize,
    /// The eye sees x_S right beside the silhouette of the edge that casts its discontinuity
    /// (`primary::steps_over`): the primary term holds that jump, so the paths that join x_S
    /// itself to the camera add nothing here.
    beside_silhouette: bool,
}

/// The point end of a boundary segment (`Secondary::through_point`): a light point or a
/// sensor point, its f64 position, its surface normal (None: a point light) and how it moves.
struct PointEnd {
    p: Vec3,
    p64: DVec3,
    n: Option<Vec3>,
    motion: SourceMotion,
}

/// What `Secondary::through_point` finds: the surface beyond x_B, the blocked side s_o,
/// dh̃/dθ, the segment's length t + t_far, its medium's index and its OPL.
struct PointSegment {
    far: SurfaceHit,
    s_o: f32,
    rates: Rates,
    seg: f32,
    eta: f32,
    d_b: f64,
}

/// The estimator's fixed inputs.
pub struct Secondary<'a> {
    pub(super) ctx: &'a RenderContext<'a>,
    pub(super) edges: EdgeSampler,
    pub(super) params: usize,
    /// Per emitter: how its laser spot moves (None: not a laser, or the beam hits nothing).
    laser_spots: Vec<Option<SourceMotion>>,
    /// Whether the scene has dielectrics (else every segment is in the scene's medium).
    dielectrics: bool,
    /// The camera as the primary stage projects it, and the shapes whose edges that stage
    /// samples (`primary::moving_shapes`).
    pin: Pinhole,
    moving: Vec<bool>,
    /// The scan of an NLOS capture (`integrator::nlos`): sensor subpaths end at its sensor
    /// points, source subpaths at its laser points (module documentation).
    scan: Option<&'a NlosSensor>,
}

impl<'a> Secondary<'a> {
    pub fn new(ctx: &'a RenderContext<'a>) -> Self {
        let list = build_edges(&ctx.scene.geometry, ctx.scene.offset_scale);
        Self::with_edge_list(ctx, &list)
    }

    /// The pass over `ctx` on the scene's edge list `list` (`build_edges`), which the primary
    /// pass shares.
    pub fn with_edge_list(ctx: &'a RenderContext<'a>, list: &[Edge]) -> Self {
        Self::with_edges(ctx, edge_sampler(ctx, list))
    }

    /// The pass over `ctx` with the edge table of another pass over the same scene and
    /// parameters ([`Self::into_edges`]).
    pub fn with_edges(ctx: &'a RenderContext<'a>, edges: EdgeSampler) -> Self {
        Self {
            ctx,
            edges,
            params: ctx.motion.len().min(MAX_PARAMS),
            laser_spots: (0..ctx.scene.emitters.len())
                .map(|e| {
                    let spot = ctx.emitters.laser_spot(e)?;
                    Some(SourceMotion::Ray {
                        shape: ctx.scene.geometry.tri_shape[spot.prim as usize] as usize,
                        dir: spot.direction,
                        n: ctx.face_normal(spot.prim),
                    })
                })
                .collect(),
            dielectrics: has_dielectric(ctx),
            pin: Pinhole::new(&ctx.scene.camera, ctx.scene.film.width, ctx.scene.film.height),
            moving: moving_shapes(ctx),
            scan: ctx.nlos.as_ref(),
        }
    }

    /// Whether the eye sees x_S within the primary stage's side offset beside the silhouette
    /// of `rec` at x_B, farther than x_B (`primary::steps_over`).
    ///
    /// Under a light at the camera, a shadow edge lies exactly behind the silhouette that
    /// casts it: on a surface point x the eye sees, the light's visibility and the eye's jump
    /// together, and their product jumps once. The primary term takes that jump with the light
    /// seen from its far side ray (lit, `SIDE_OFFSET_PX` past the silhouette); by the product
    /// rule [V_L·V_E] = V_L⁺·[V_E] + V_E⁻·[V_L] the secondary term must then take the eye's
    /// visibility from the blocked side, which is 0. A light a hair off the camera casts a
    /// shadow sliver narrower than the side offset: the side ray steps over it in the same way.
    /// Counting both doubled the derivative of the wall behind a moving plate
    /// (tests/secondary_fd.rs, `a_light_at_the_camera_counts_each_silhouette_once`).
    ///
    /// x_S is taken on the boundary line itself (through x_B along `dir`, in f64): the ray
    /// that found it started ε off the edge, which moves its film point by a few percent of
    /// the side offset at millimetre scales, enough to blur the test where a shadow sliver is
    /// about as wide as the offset (an object hovering a tenth of a millimetre over a floor).
    fn beside_silhouette(&self, rec: &EdgeRecord, x_b: Vec3, dir: DVec3, x_s: &SurfaceHit) -> bool {
        // a capture has no primary stage: the SPAD sees fixed wall points
        if self.scan.is_some() || !self.moving.get(rec.shape as usize).copied().unwrap_or(false) {
            return false;
        }
        let x_b = x_b.as_dvec3();
        let on_line = on_plane64(self.ctx, x_s.prim, x_b, dir);
        let seen = self.shadow_line_as_seen(x_s.prim, x_b, dir, on_line);
        steps_over(&self.pin, x_b, (rec.v1 - rec.v0).as_dvec3(), seen)
    }

    /// Where the paths the eye starts see the shadow line through `on_line` (the point of the
    /// segment's line x_B + t·dir on the surface `prim`): their shadow rays leave a surface
    /// point P from P + ε·n − ε·ŵ (`integrator::trace::spawn_point`: off the surface towards
    /// the light, stepped back along the eye ray ŵ), so P is in shadow where that origin's
    /// segment to the light passes the edge: the segment's line meets the surface's plane
    /// moved by that offset, carried back onto the surface. The primary stage's far side ray
    /// sees the shadow there, so the hand-off between the two terms ([`steps_over`]) must test
    /// that point, not the shadow line itself: under an object hovering 0.1 mm over a floor
    /// (ε = 7.6 µm) the shadow line lies about the side offset from the silhouette, and
    /// testing the line itself lost the jump of the light points in between
    /// (scenes/hovering_mat.toml, d/d`mat_x` 2 % short; tests/secondary_fd.rs).
    fn shadow_line_as_seen(&self, prim: u32, x_b: DVec3, dir: DVec3, on_line: DVec3) -> DVec3 {
        let [p0, p1, p2] = self.ctx.tri_verts[prim as usize].map(|p| p.as_dvec3());
        let n = (p1 - p0).cross(p2 - p0).normalize_or_zero();
        // the light's side of the surface, which x_B (on the segment towards it) shares
        let n = if n.dot(x_b - on_line) < 0.0 { -n } else { n };
        let eye = (on_line - self.ctx.camera.position.as_dvec3()).normalize_or_zero();
        let eps = self_intersection_eps(&V3::<f32>::splat(on_line.as_vec3()), self.ctx.scene.offset_scale) as f64;
        let shift = (n - eye) * eps;
        let t = n.dot(shift) / n.dot(dir);
        if t.is_finite() {
            on_line + dir * t - shift
        } else {
            on_line
        }
    }

    /// The silhouette side test of Eq. 32 for edge `rec` and direction ω: s_o = ±1, the side
    /// of the plane Π(edge, ω) that holds the edge's faces, or None when ω is not a silhouette
    /// direction (faces on both sides).
    fn blocked_side(&self, rec: &EdgeRecord, omega: Vec3) -> Option<f32> {
        let geo = &self.ctx.scene.geometry;
        let n_pi = (rec.v1 - rec.v0).cross(omega);
        let side = |o: u32| n_pi.dot(geo.positions[o as usize] - rec.v0);
        let s0 = side(rec.edge.opposite0);
        if let Some(o1) = rec.edge.opposite1
            && s0 * side(o1) <= 0.0
        {
            return None;
        }
        (s0 != 0.0 && s0.is_finite()).then_some(s0.signum())
    }

    /// Whether strategy A takes the emission at x_L (`found`: the first surface along −ω from
    /// x_B on edge `edge`, as `contact::segment_ends` finds it on an open segment): x_L lies
    /// on an area emitter's front whose plane does not pass through x_B (as far as the segment
    /// search can tell, `contact::passes_through`), and `split` gives the line to A. Both
    /// strategies ask this of the same line, so each emitting line is counted by exactly one of
    /// them.
    #[allow(clippy::too_many_arguments)]
    fn takes_emission(
        &self,
        split: &EmissionSplit,
        rec: &EdgeRecord,
        edge: usize,
        x_b: Vec3,
        omega: Vec3,
        found: &Option<SurfaceHit>,
    ) -> bool {
        let Some(x_l) = found else {
            return false;
        };
        let ctx = self.ctx;
        let eps = self_intersection_eps(&V3::<f32>::splat(x_b), ctx.scene.offset_scale);
        self.emits_towards(x_l, omega)
            && !super::contact::passes_through(&ctx.scene.geometry, rec, x_b, x_l, eps)
            && split.edge_directed(
                ctx,
                edge,
                omega,
                ctx.tri_emitter[x_l.prim as usize],
                x_l.t,
                x_l.n.dot(omega),
            )
    }

    /// Whether x_L lies on an area emitter's front facing along ω (towards x_S), outside a
    /// capture (whose sources are its laser points). On a contact edge its emission is always
    /// the edge-directed sample's: an object resting on an area light's front frees and covers
    /// the light's area at the edge just as a reflecting support's (contact.rs), and strategy
    /// B's light points never land on the edge itself.
    fn emits_towards(&self, x_l: &SurfaceHit, omega: Vec3) -> bool {
        self.scan.is_none() && self.ctx.tri_emitter[x_l.prim as usize] != u32::MAX && x_l.n.dot(omega) > 0.0
    }

    /// dh̃/dθ_k (velocity.rs) with x_S in material form and in ray form; x_L moves as `motion_l`
    /// says.
    /// under x_L (None: a point light, which no parameter moves).
    fn rates(&self, rec: &EdgeRecord, x_l: Vec3, motion_l: SourceMotion, x_s: &SurfaceHit) -> Rates {
        let ctx = self.ctx;
        let motion = &ctx.motion;
        let shape_s = ctx.scene.geometry.tri_shape[x_s.prim as usize] as usize;
        let omega_c = (x_s.p - ctx.camera.position).normalize_or_zero();
        let mut r = Rates {
            material: [0.0; MAX_PARAMS],
            ray: [0.0; MAX_PARAMS],
        };
        for k in 0..self.params {
            let v_s = motion.velocity(k, shape_s, x_s.p);
            let mut c = Crossing {
                v0: rec.v0,
                v1: rec.v1,
                x_l,
                y: x_s.p,
                dv0: motion.velocity(k, rec.shape as usize, rec.v0),
                dv1: motion.velocity(k, rec.shape as usize, rec.v1),
                dx_l: match motion_l {
                    SourceMotion::Fixed => Vec3::ZERO,
                    SourceMotion::Material(s) => motion.velocity(k, s, x_l),
                    SourceMotion::Ray { shape, dir, n } => ray_form_velocity(dir, n, motion.velocity(k, shape, x_l)),
                },
                dy: v_s,
            };
            r.material[k] = c.rate();
            c.dy = ray_form_velocity(omega_c, x_s.n, v_s);
            r.ray[k] = c.rate();
        }
        if self.scan.is_some() {
            // a capture's first vertex from a sensor point is in material form (the interior's
            // too, `integrator::path`)
            r.ray = r.material;
        }
        r
    }

    /// The contact edge's derivative rates (contact.rs): −(v_edge − v_surface)·u_out at x_L,
    /// whichever vertex the sensor subpath connects to the camera.
    fn contact_rates(&self, rec: &EdgeRecord, x_l: &SurfaceHit, outward: Vec3) -> Rates {
        let motion = &self.ctx.motion;
        let surface = self.ctx.scene.geometry.tri_shape[x_l.prim as usize] as usize;
        let mut material = [0.0; MAX_PARAMS];
        for (k, m) in material.iter_mut().enumerate().take(self.params) {
            let v = motion.velocity(k, rec.shape as usize, x_l.p) - motion.velocity(k, surface, x_l.p);
            *m = -v.dot(outward);
        }
        Rates {
            material,
            ray: material,
        }
    }

    /// Runs the subpaths of `group` (at most 8 samples of one strategy, stream `seed`) on the
    /// kernel and calls `emit(sample, path)` for every (source term, sensor term) pair within
    /// the bounce budget, with derivative weight `common · dh̃/dθ_k`, sample by sample in the
    /// order of `group`.
    pub(super) fn complete(
        &self,
        seed: u64,
        group: &[Prepared],
        scratch: &mut Scratch,
        mut emit: impl FnMut(&Prepared, &BoundaryPath),
    ) {
        let ctx = self.ctx;
        let max_bounces = ctx.scene.integrator.max_bounces;
        let mut segments = [group[0].segment; 8];
        for (o, p) in segments.iter_mut().zip(group) {
            *o = p.segment;
        }
        let segments = &segments[..group.len()];
        let terms = &mut scratch.terms;
        match ctx.scene.film.channels {
            1 => subpaths::<1>(ctx, seed, segments, &mut scratch.counts, terms),
            _ => subpaths::<3>(ctx, seed, segments, &mut scratch.counts, terms),
        }
        for (i, p) in group.iter().enumerate() {
            for sen in &terms.sensor[i] {
                if sen.scatters == 1 && p.beside_silhouette {
                    continue;
                }
                let r = if sen.scatters == 1 {
                    &p.rates.ray
                } else {
                    &p.rates.material
                };
                let mut weight = [0.0f32; MAX_PARAMS];
                for k in 0..self.params {
                    weight[k] = p.common * r[k];
                }
                for src in &terms.source[i] {
                    if src.scatters + sen.scatters > max_bounces {
                        continue;
                    }
                    // x_S is a sensor point and x_L joins the laser point at that same point:
                    // the segment's jump is the light-directed draws' (product rule, below)
                    if let Some(scan) = self.scan
                        && sen.scatters == 0
                        && src.scatters == 1
                        && coincide(
                            ctx,
                            scan,
                            p.segment.sensor,
                            laser_index(scan, p.segment.sensor, src.laser),
                        )
                    {
                        continue;
                    }
                    let (fx, fy) = match self.scan {
                        None => (sen.fx, sen.fy),
                        Some(scan) => film_point(scan, p.segment.sensor, src.laser),
                    };
                    emit(
                        p,
                        &BoundaryPath {
                            fx,
                            fy,
                            opl: src.opl + sen.opl,
                            emitter: src.emitter,
                            rgb: std::array::from_fn(|c| src.rgb[c] * sen.rgb[c]),
                            weight,
                        },
                    );
                }
            }
        }
    }

    /// Strategy A, boundary sample `id` of stream `seed`: a boundary ray drawn from `grid` and
    /// the edge table `edges` (this pass's, `pass.rs`), traced both ways; x_L's emission is
    /// this sample's where `split` gives the line to this strategy, else strategy B's (a
    /// partition of the integrand, so no MIS is needed), and its reflected light is estimated
    /// by the source subpath ([`Secondary::complete`]). None when the sample adds nothing.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn prepare(
        &self,
        seed: u64,
        id: u64,
        grid: &GuideGrid,
        edges: &EdgeSampler,
        split: &EmissionSplit,
        scale: f32,
        scratch: &mut Scratch,
    ) -> Option<Prepared> {
        let ctx = self.ctx;
        let mut rng = boundary_numbers(ctx, seed, id);
        let (u, p_guide) = edge_numbers(&mut rng, grid);
        // a capture's sensor subpath ends at one sensor point, drawn uniformly
        let (sensor, scale) = match self.scan {
            Some(scan) => (
                pick(rng.next::<f32>(), scan.sensors.len()),
                scale * scan.sensors.len() as f32,
            ),
            None => (0, scale),
        };
        scratch.edge = None;
        let br = edges.sample(u[0], u[1], u[2])?;
        scratch.edge = Some(br.index);
        let rec = &edges.edges[br.index];
        let s_o = self.blocked_side(rec, br.omega)?;
        let rays = &mut scratch.counts.rays;
        // x_L as the segment search found it (None for a contact edge): what `EmissionSplit`
        // judges, in strategy B's draws too
        let mut open_l = None;
        let (mut x_l, mut x_s, rates, common, contact) = match segment_ends(self.ctx, rec, br.x_b, br.omega, s_o, rays)?
        {
            SegmentEnds::Open { x_s, x_l } => {
                let x_l = x_l?;
                open_l = Some(x_l);
                let seg = x_l.t + x_s.t;
                let shape_l = ctx.scene.geometry.tri_shape[x_l.prim as usize] as usize;
                let rates = self.rates(rec, x_l.p, SourceMotion::Material(shape_l), &x_s);
                (x_l, x_s, rates, -s_o / seg, false)
            }
            SegmentEnds::Contact { x_l, x_s, outward } => {
                let rates = self.contact_rates(rec, &x_l, outward);
                let cos_l = br.omega.dot(x_l.n).abs();
                (x_l, x_s, rates, cos_l * (rec.v1 - rec.v0).length(), true)
            }
        };
        scratch.valid += 1;
        let seg = x_l.t + x_s.t;
        if rates.is_zero(self.params) || !(seg > 0.0) || !common.is_finite() {
            return None;
        }
        let eta = self.segment_eta(Some(&x_l), &x_s, br.x_b, br.omega, &mut scratch.counts.rays);
        let omega64 = br.omega.as_dvec3();
        if contact {
            // x_L is x_B itself (contact.rs puts its f32 point a hair off the edge)
            if let Some(x_b64) = self.on_boundary_line(rec, br.x_b, |_| omega64, None, &mut x_s) {
                x_l.p64 = x_b64;
            }
        } else {
            self.on_boundary_line(rec, br.x_b, |_| omega64, Some(&mut x_l), &mut x_s);
        }
        let d_b = eta as f64 * segment(ctx, x_l.p64, x_s.p64, seg);
        // x_L's own emission, where this strategy takes it (`EmissionSplit`; on a contact
        // edge always, `emits_towards`)
        let e = ctx.tri_emitter[x_l.prim as usize];
        let emits = if contact {
            self.emits_towards(&x_l, br.omega)
        } else {
            self.takes_emission(split, rec, br.index, br.x_b, br.omega, &open_l)
        };
        let also_emitted = emits.then(|| SourceTerm {
            rgb: ctx.emitters.radiance(e),
            opl: d_b,
            emitter: e,
            scatters: 0,
            laser: 0,
        });
        Some(Prepared {
            segment: SegmentSample {
                id,
                x_l,
                x_s,
                omega: br.omega,
                eta,
                d_b,
                emitted: None,
                also_emitted,
                sensed: None,
                sensor,
                retro: false,
            },
            rates,
            common: common * scale / (br.pdf_edge_dir * p_guide),
            u,
            edge: br.index,
            beside_silhouette: self.beside_silhouette(rec, br.x_b, omega64, &x_s),
        })
    }

    /// Strategy B, boundary sample `id` of stream `seed`: shadow edges of direct light. A
    /// point x_B on an edge (drawn from `edges`, as in strategy A) and a point y on an
    /// emitter (next-event sampling) fix ω = (x_B − y)/t_L; x_L = y when nothing blocks
    /// y → x_B, and the line is not strategy A's (`split`, for area lights). The density of
    /// ω per steradian is pdf_A(y) · t_L² / |cos_L|, so the weight of strategy A becomes
    /// −s_o · (L_e / pdf_A) · |cos_L| / (t_L² (t_L + t_S) p_e); for a point light L_e/pdf_A · |cos_L|
    /// is I / p_select (the density is a delta in ω); a laser spot is such a point source with
    /// intensity ∝ cos_L, moving along the beam (ray form). The inputs (edge coordinate,
    /// the two numbers of the point on the emitter) come from `grid`, the emitter choice from
    /// a fourth number.
    ///
    /// `shadow_shares` holds, per edge of `edges`, the share q = t_S/(t_L + t_S) the shadow
    /// point's rotation ([`shadow_aligned`]) uses (none: an empty slice, or 0 for an edge).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn prepare_light(
        &self,
        seed: u64,
        id: u64,
        grid: &GuideGrid,
        edges: &EdgeSampler,
        split: &EmissionSplit,
        shadow_shares: &[f32],
        scale: f32,
        scratch: &mut Scratch,
    ) -> Option<Prepared> {
        let ctx = self.ctx;
        let mut rng = boundary_numbers(ctx, seed, id);
        let (u, p_guide) = edge_numbers(&mut rng, grid);
        // the point on the emitter from the cube's last two numbers (it covers the whole
        // emitter, `EmitterTable::sample`), the emitter choice from a fourth
        let select = rng.next::<f32>();
        let [u0, e0, e1] = u;
        scratch.edge = None;
        let (edge, s) = edges.point(u0)?;
        scratch.edge = Some(edge);
        let rec = &edges.edges[edge];
        // a capture: half of the draws end at a sensor point, half start at a laser point
        let (mut scale, mut sensor, mut laser) = (scale, 0, 0);
        let mut scan_spot = None;
        let ls = match self.scan {
            None => ctx.emitters.sample::<f32, 3>(ctx, select, e0, e1, true),
            Some(scan) => {
                if select >= 0.5 {
                    let j = pick(2.0 * select - 1.0, scan.sensors.len());
                    let factor = 2.0 * scan.sensors.len() as f32;
                    return self.prepare_sensor(
                        scan,
                        id,
                        j,
                        (rec, edge, s),
                        u,
                        p_guide,
                        edges,
                        scale * factor,
                        scratch,
                    );
                }
                let points = scan.spots.len();
                let i = pick(2.0 * select, points);
                scale *= 2.0 * points as f32;
                sensor = i;
                scan_spot = scan.spots[i].as_ref();
                if scan.exhaustive {
                    laser = i as u32;
                    sensor = pick(rng.next::<f32>(), scan.sensors.len());
                    scale *= scan.sensors.len() as f32;
                }
                ctx.emitters
                    .sample_laser_points::<f32, 3>(ctx, scan, &[i as u32; 8], true)
            }
        };
        if !ls.valid {
            return None;
        }
        let e = ls.emitter[0] as usize;
        let motion_l = match ctx.scene.emitters[e].kind {
            EmitterKind::Area { shape, .. } => SourceMotion::Material(shape as usize),
            EmitterKind::Point { .. } => SourceMotion::Fixed,
            // a scan's spot lies on the relay wall, which no parameter moves
            // (`render::check_nlos`), unless something in the beam holds it
            EmitterKind::Laser { .. } if self.scan.is_some() => {
                let spot = scan_spot?;
                SourceMotion::Ray {
                    shape: ctx.scene.geometry.tri_shape[spot.prim as usize] as usize,
                    dir: spot.direction,
                    n: ctx.face_normal(spot.prim),
                }
            }
            EmitterKind::Laser { .. } => self.laser_spots[e]?,
        };
        let y = ls.p.lane(0);
        let x_b = shadow_aligned(rec, s, y, shadow_shares.get(edge).copied().unwrap_or(0.0));
        let to = x_b - y;
        let t_l = to.length();
        if !(t_l > 0.0) {
            return None;
        }
        let omega = to / t_l;
        let cos_l = if ls.has_cos { ls.n.lane(0).dot(omega) } else { 1.0 };
        if !(cos_l > 0.0) {
            return None;
        }
        // an area light's emission along a line strategy A draws more densely is A's, where
        // A's own segment search on this line finds x_L on it (not, say, taking a light a
        // hair from the edge for a surface the edge rests on: contact.rs)
        let ends = self.ends_through(rec, x_b, omega, &mut scratch.counts.rays)?;
        if self.scan.is_none()
            && matches!(motion_l, SourceMotion::Material(_))
            && split.edge_directed_somewhere(ctx, edge, e as u32, t_l, cos_l)
            && let (_, SegmentEnds::Open { x_l: found, .. }) = &ends
            && self.takes_emission(split, rec, edge, x_b, omega, found)
        {
            return None;
        }
        let y64 = ls.p64[0];
        let end = PointEnd {
            p: y,
            p64: y64,
            n: ls.has_cos.then(|| ls.n.lane(0)),
            motion: motion_l,
        };
        let PointSegment {
            far: x_s,
            s_o,
            rates,
            seg,
            eta,
            d_b,
        } = self.through_point(rec, x_b, ends, &end, t_l, omega, scratch)?;
        // the light point in f64 where the render keeps one, else as drawn
        let y_line = if ctx.opl.f64_paths { y64 } else { y.as_dvec3() };
        let x_l = SurfaceHit {
            p: y,
            p64: y64,
            n: ls.n.lane(0),
            prim: 0,
            t: t_l,
        };
        let common = -s_o * scale * cos_l / (t_l * t_l * seg * edges.edge_pmf(edge) * p_guide);
        Some(Prepared {
            segment: SegmentSample {
                id,
                x_l,
                x_s,
                omega,
                eta,
                d_b,
                also_emitted: None,
                emitted: Some(SourceTerm {
                    rgb: ls.weight.0,
                    // the laser's beam runs in the scene's medium, as in the interior
                    opl: ctx.scene.eta as f64 * pre_length(ctx, &ls) + d_b,
                    emitter: e as u32,
                    scatters: 0,
                    laser,
                }),
                sensed: None,
                sensor,
                retro: self
                    .scan
                    .is_some_and(|scan| coincide(ctx, scan, sensor, laser_index(scan, sensor, laser))),
            },
            rates,
            common,
            u,
            edge,
            beside_silhouette: self.beside_silhouette(rec, x_b, (x_b.as_dvec3() - y_line).normalize(), &x_s),
        })
    }

    /// The sensor-directed draws of strategy B in an NLOS capture: the edges seen from a
    /// sensor point. Sensor point s_j (importance f_r·|cos θ_s| = ρ/π·cos θ_s per steradian, a
    /// delta in position like a point light) and x_B on edge `at` = (record, index, position)
    /// fix the line from s_j through x_B; x_L is the first surface beyond x_B and x_S = s_j,
    /// when nothing stands between s_j and x_B. This is strategy B's geometry with s_j in the
    /// light's place and x_L as the point the discontinuity sweeps over, since the integrand
    /// f_L·G·V·f_S and the segment's discontinuity do not depend on which end is the light:
    /// the weight is −s_o/(t_S²·(t_S + t_L)·p_e), times the importance ρ/π·cos θ_s as the
    /// sample's only sensor term (its OPL: the sensor point's counted leg to the SPAD), and the source
    /// subpath from x_L estimates the radiance it sends to s_j. `scale` holds the draw's
    /// probabilities (half of the draws, 1/N_s per sensor point).
    #[allow(clippy::too_many_arguments)]
    fn prepare_sensor(
        &self,
        scan: &NlosSensor,
        id: u64,
        j: usize,
        (rec, edge, s): (&EdgeRecord, usize, f32),
        u: [f32; 3],
        p_guide: f32,
        edges: &EdgeSampler,
        scale: f32,
        scratch: &mut Scratch,
    ) -> Option<Prepared> {
        let ctx = self.ctx;
        let sp = &scan.sensors[j];
        let x_b = rec.v0 + (rec.v1 - rec.v0) * s;
        // the sensor's importance towards x_B (none behind the wall, or unseen by the SPAD)
        let proj = scan.project(j, x_b)?;
        let (t_s, omega) = (proj.dist2.sqrt(), proj.dir);
        // beyond x_B the line meets x_L; s_j is the point end, as a light point is
        let end = PointEnd {
            p: sp.p,
            p64: sp.p.as_dvec3(),
            n: Some(sp.n),
            motion: SourceMotion::Fixed,
        };
        let PointSegment {
            far: x_l,
            s_o,
            rates,
            seg,
            eta,
            d_b,
        } = self.through_point(
            rec,
            x_b,
            self.ends_through(rec, x_b, omega, &mut scratch.counts.rays)?,
            &end,
            t_s,
            omega,
            scratch,
        )?;
        let x_s = SurfaceHit {
            p: sp.p,
            p64: end.p64,
            n: sp.n,
            prim: sp.prim,
            t: t_s,
        };
        let common = -s_o * scale / (t_s * t_s * seg * edges.edge_pmf(edge) * p_guide);
        Some(Prepared {
            segment: SegmentSample {
                id,
                x_l,
                x_s,
                // light leaves x_L towards s_j
                omega: -omega,
                eta,
                d_b,
                emitted: None,
                also_emitted: None,
                sensed: Some(SensorTerm {
                    rgb: proj.importance,
                    opl: ctx.scene.eta as f64 * scan.spad_leg[j],
                    fx: 0.0,
                    fy: 0.0,
                    scatters: 0,
                }),
                sensor: j,
                retro: false,
            },
            rates,
            common,
            u,
            edge,
            beside_silhouette: false,
        })
    }

    /// The side s_o of Π(edge, ω) that holds edge `rec`'s faces and the ends of the line through
    /// x_B along ω (`contact::segment_ends`), searched once per line of a point end. None: the
    /// edge is no silhouette for ω, or nothing lies beyond x_B.
    fn ends_through(
        &self,
        rec: &EdgeRecord,
        x_b: Vec3,
        omega: Vec3,
        rays: &mut RayCounts,
    ) -> Option<(f32, SegmentEnds)> {
        let s_o = self.blocked_side(rec, omega)?;
        Some((s_o, segment_ends(self.ctx, rec, x_b, omega, s_o, rays)?))
    }

    /// The segment of a boundary ray from a point end (a light point of strategy B, or a
    /// sensor point): `end` at distance `t` from x_B on edge `rec`, ω = (x_B − end)/t, with
    /// `ends` the line's (`ends_through`). Takes the first surface beyond x_B (the point the
    /// discontinuity sweeps over) and checks that
    /// nothing stands between x_B and the end (a hit more than 2ε in front of its tangent
    /// plane, or short of it by distance for a point light: `blocks_light_point`; a contact
    /// edge has x_L = x_B, never a point end, `contact.rs`). None when the sample adds nothing.
    #[allow(clippy::too_many_arguments)]
    fn through_point(
        &self,
        rec: &EdgeRecord,
        x_b: Vec3,
        (s_o, ends): (f32, SegmentEnds),
        end: &PointEnd,
        t: f32,
        omega: Vec3,
        scratch: &mut Scratch,
    ) -> Option<PointSegment> {
        let ctx = self.ctx;
        let SegmentEnds::Open {
            x_s: mut far,
            x_l: back,
        } = ends
        else {
            return None;
        };
        let eps = |p: Vec3| self_intersection_eps(&V3::<f32>::splat(p), ctx.scene.offset_scale);
        let reach = t - eps(end.p);
        let tol = 2.0 * eps(end.p).max(eps(x_b));
        if !(reach > 0.0) || back.is_some_and(|h| blocks_light_point(&h, end.p, end.n, reach, tol)) {
            return None;
        }
        scratch.valid += 1;
        let rates = self.rates(rec, end.p, end.motion, &far);
        let seg = t + far.t;
        if rates.is_zero(self.params) {
            return None;
        }
        let p64 = end.p64;
        self.on_boundary_line(rec, x_b, |x_b64| (x_b64 - p64).normalize(), None, &mut far);
        let eta = self.segment_eta(None, &far, x_b, omega, &mut scratch.counts.rays);
        let d_b = eta as f64 * segment(ctx, p64, far.p64, seg);
        Some(PointSegment {
            far,
            s_o,
            rates,
            seg,
            eta,
            d_b,
        })
    }

    /// With f64 OPLs: x_B projected in f64 onto its edge, the ends' `p64` moved onto the line
    /// through it along `omega64` (x_L given as `x_l64`, e.g. a light sample or x_B itself,
    /// stays), so that d_B = η|x_S − x_L| is the length of a segment that really grazes the
    /// edge. Returns x_B in f64. `contact::segment_ends` already put the ends on the line
    /// through the f32 x_B, which lies up to an ulp of its coordinates off the edge; this
    /// takes them onto the edge's own line, for the OPL. Without f64 OPLs, nothing changes.
    fn on_boundary_line(
        &self,
        rec: &EdgeRecord,
        x_b: Vec3,
        omega64: impl FnOnce(DVec3) -> DVec3,
        x_l: Option<&mut SurfaceHit>,
        x_s: &mut SurfaceHit,
    ) -> Option<DVec3> {
        let ctx = self.ctx;
        if !ctx.opl.f64_paths {
            return None;
        }
        let (v0, v1) = (rec.v0.as_dvec3(), rec.v1.as_dvec3());
        let e = v1 - v0;
        let x_b64 = v0 + e * ((x_b.as_dvec3() - v0).dot(e) / e.length_squared());
        let w = omega64(x_b64);
        x_s.p64 = on_plane64(ctx, x_s.prim, x_b64, w);
        if let Some(x_l) = x_l {
            x_l.p64 = on_plane64(ctx, x_l.prim, x_b64, -w);
        }
        Some(x_b64)
    }

    /// The index of the medium the segment x_L → x_S (direction ω, through x_B) crosses: the
    /// side of x_S (or else of x_L, when a surface point) that the segment meets, when that
    /// is a dielectric's surface; else the medium around the segment's free part
    /// (`integrator::medium`). With no dielectric in the scene, the scene's medium.
    fn segment_eta(
        &self,
        x_l: Option<&SurfaceHit>,
        x_s: &SurfaceHit,
        x_b: Vec3,
        omega: Vec3,
        rays: &mut RayCounts,
    ) -> f32 {
        let ctx = self.ctx;
        if !self.dielectrics {
            return ctx.scene.eta;
        }
        side_eta(ctx, x_s.prim, x_s.n, -omega)
            .or_else(|| x_l.and_then(|h| side_eta(ctx, h.prim, h.n, omega)))
            .unwrap_or_else(|| medium_around(ctx, x_b + omega * (0.5 * x_s.t), omega, rays))
    }

    pub fn edge_count(&self) -> usize {
        self.edges.edges.len()
    }

    /// The edge table, for a pass over the same scene with another context
    /// ([`Self::with_edges`]).
    pub fn into_edges(self) -> EdgeSampler {
        self.edges
    }
}

/// Whether `hit`, the first surface met from x_B back towards the light point `y` (`normal`
/// its surface's normal, None for a point light, which is tested by distance: a hit short of
/// `reach`, ε before y), lies in front of `y`.
///
/// The ray starts ε beside x_B (`contact::segment_ends`), parallel to the line x_B → y, so it
/// meets y's own surface up to ε·tan θ_L from y along the ray (θ_L: the angle between the ray
/// and that normal), short of y for half the samples: a test by distance (t < t_l − ε) took the
/// light itself for a blocker at oblique incidence and dropped those samples (a light tilted
/// 60° lost the whole far end of its shadow). A surface point is in front of y when it lies
/// more than `tol` off y's tangent plane, on the side the ray comes from.
fn blocks_light_point(hit: &SurfaceHit, y: Vec3, normal: Option<Vec3>, reach: f32, tol: f32) -> bool {
    match normal {
        Some(n) => n.dot(hit.p - y) > tol,
        None => hit.t < reach,
    }
}

/// The laser point of a capture's path that ends at `sensor` and whose source term ends at
/// laser point `laser` (the film's y, 0 in a confocal scan, where each sensor has its own).
fn laser_index(scan: &NlosSensor, sensor: usize, laser: u32) -> usize {
    if scan.exhaustive { laser as usize } else { sensor }
}

/// Whether laser point `laser`'s spot is sensor point `sensor` (a confocal scan's, unless
/// something stands in the beam): a path s → x → l then runs to and from x along one line.
///
/// Its two segments share one visibility V(s, x) = V(x, l), so as x crosses an edge's
/// silhouette seen from s the integrand V(s, x)·V(x, l) jumps once, not twice. By the product
/// rule [V·V'] = V'⁺·[V] + V⁻·[V'] (⁺ the free side, ⁻ the blocked one), the light-directed
/// draw from l takes the jump with the sensor connection from the free side (unblocked:
/// `SegmentSample::retro`) and the sensor-directed draw from s takes it with the laser
/// connection from the blocked side, 0: its x_L → l term is dropped. Counting both, as for two
/// separate points, doubled that part of a confocal capture's boundary term.
fn coincide(ctx: &RenderContext, scan: &NlosSensor, sensor: usize, laser: usize) -> bool {
    let (Some(spot), Some(s)) = (scan.spots.get(laser).and_then(|o| o.as_ref()), scan.sensors.get(sensor)) else {
        return false;
    };
    let [a, b, c] = ctx.tri_verts[spot.prim as usize];
    let l = a + (b - a) * spot.u + (c - a) * spot.v;
    let tol = 4.0 * self_intersection_eps(&V3::<f32>::splat(s.p), ctx.scene.offset_scale);
    (l - s.p).length() <= tol
}

/// Index ⌊u·n⌋ of one of `n` items drawn uniformly by `u` ∈ [0, 1).
fn pick(u: f32, n: usize) -> usize {
    ((u * n as f32) as usize).min(n.saturating_sub(1))
}

/// The film point (pixel centre) of a capture's boundary path that ends at sensor point
/// `sensor` and, in an exhaustive scan, starts at laser point `laser`: the sensor grid's cell
/// (confocal) or (sensor, laser) (exhaustive), as `NlosSensor::sensor_of` maps them.
fn film_point(scan: &NlosSensor, sensor: usize, laser: u32) -> (f32, f32) {
    let (x, y) = if scan.exhaustive {
        (sensor, laser as usize)
    } else {
        (sensor % scan.nx, sensor / scan.nx)
    };
    (x as f32 + 0.5, y as f32 + 0.5)
}

/// Strategy B's point x_B on edge `rec` at position `s` ∈ [0, 1] for the light point `y`:
/// s rotated (mod 1) by c = q · ((y − v0)·d)/ℓ_e, d the edge's unit direction, ℓ_e its length
/// and q the share t_S/(t_L + t_S) typical of the edge (the pilot's mean, `pass.rs`).
///
/// For each y the rotation maps a uniform s to a uniform s', so x_B keeps its density and the
/// sample its weight (the estimator stays unbiased for any q). What changes is where the
/// shadow point lands: x_S = x_B + (t_S/t_L)(x_B − y) moves along the edge's shadow as
/// ℓ_e·s'/(1 − q) − (y·d)·q/(1 − q) + const, in which y's part cancels when q is the sample's
/// own share. A pixel's samples then fill a box of (edge coordinate, light point across the
/// edge), which the first two dimensions of the 3D Sobol net stratify (`edge_numbers`),
/// instead of a slab across all three: how many samples a pixel receives, which is most of
/// the boundary estimate's variance, then varies far less. The rotation is taken in f64, so a
/// light far from a short edge (c in the thousands) does not quantise s.
fn shadow_aligned(rec: &EdgeRecord, s: f32, y: Vec3, q: f32) -> Vec3 {
    let e = rec.v1 - rec.v0;
    let len = e.length();
    let s = if q > 0.0 && q < 1.0 && len > 0.0 {
        let c = q as f64 * (y - rec.v0).as_dvec3().dot(e.as_dvec3()) / (len as f64 * len as f64);
        let r = (s as f64 + c).rem_euclid(1.0) as f32;
        if r < 1.0 { r } else { 0.0 }
    } else {
        s
    };
    rec.v0 + e * s
}

/// The numbers of boundary sample `id` of a stream: with Sobol points, the samples of the whole
/// stage are one sequence (one "pixel" whose sample index is `id`), so the edge, the point on
/// it and the direction are stratified over the stage.
fn boundary_numbers(ctx: &RenderContext, seed: u64, id: u64) -> PathSampler {
    PathSampler::with_sequence(ctx.scene.integrator.sampler, seed, &[id], u32::MAX)
}

/// A boundary sample's point u of the unit cube (strategy A: edge coordinate, azimuth,
/// cos θ; strategy B: edge coordinate and the two numbers of the point on the emitter) and
/// the guiding grid's density there. Where a sample lands on the film depends on all three
/// at once (in strategy B the shadow point moves with the edge point and the light point
/// together, less so once [`shadow_aligned`] has rotated the edge point), so with Sobol
/// points and no guiding u is one 3D net (`PathSampler::next3`), which stratifies how many
/// samples reach each pixel; otherwise the grid's pick, then its cell's three numbers.
fn edge_numbers(rng: &mut PathSampler, grid: &GuideGrid) -> ([f32; 3], f32) {
    if rng.is_sobol() && grid.is_uniform() {
        return (rng.next3(), 1.0);
    }
    let pick = rng.next::<f32>();
    let inner = [rng.next::<f32>(), rng.next::<f32>(), rng.next::<f32>()];
    grid.sample(pick, inner)
}

#[cfg(test)]
mod edge_weight_tests {
    use super::*;
    use crate::accel::Device;
    use crate::params::lanes::Motion;

    /// scenes/shadow_hidden_occluder.toml, d/d`occluder_x`: the occluder's two edges along z
    /// (moved across themselves at full speed) are drawn 8 times as often per metre as a static
    /// edge; its two edges along x (sliding along themselves: no discontinuity moves) once.
    /// They are the only edges drawn: the floor's and the light's have the whole scene on one
    /// side of their face ([`edges_that_can_bound`]).
    #[test]
    fn edges_are_weighted_by_their_speed_across_themselves() {
        let (scene, occluder) = crate::boundary::shadow_scene("occluder");
        let device = Device::new("").unwrap();
        let mut ctx = RenderContext::new(&scene, &device).unwrap();
        ctx.motion = Motion::build(&scene, &["occluder_x".to_string()]).unwrap();
        let all = build_edges(&scene.geometry, scene.offset_scale);
        let table = edge_sampler(&ctx, &all);
        let static_table = EdgeSampler::from_edges(&scene.geometry, &edges_that_can_bound(&ctx, &all), |e| {
            vec![1.0; e.len()]
        });
        assert_eq!(table.edges.len(), static_table.edges.len());
        assert!(
            table.edges.iter().all(|r| r.shape == occluder),
            "{} edges",
            table.edges.len()
        );
        // per-metre weight of each edge relative to the unweighted table
        let per_metre = |t: &EdgeSampler, i: usize| {
            let r = &t.edges[i];
            t.edge_pmf(i) * t.total_weight() / (r.v1 - r.v0).length()
        };
        let (mut across, mut along) = (0, 0);
        for (i, r) in table.edges.iter().enumerate() {
            let ratio = per_metre(&table, i) / per_metre(&static_table, i);
            let dir = (r.v1 - r.v0).normalize();
            if r.shape == occluder && dir.x.abs() < 1e-3 {
                across += 1;
                assert!((ratio - MOVING_EDGE_FACTOR).abs() < 1e-3, "edge {i} across: {ratio}");
            } else {
                if r.shape == occluder {
                    along += 1;
                }
                assert!((ratio - 1.0).abs() < 1e-3, "edge {i} (shape {}): {ratio}", r.shape);
            }
        }
        assert_eq!((across, along), (2, 2));
    }
}

#[cfg(test)]
mod shadow_alignment_tests {
    use super::*;

    /// scenes/shadow_hidden_occluder.toml: light at height 2, the occluder's edges at 1, the
    /// floor at 0, so every shadow point is x_S = 2·x_B − y and q = t_S/(t_L + t_S) = ½. With
    /// that q the rotated x_B puts x_S at the same place along the edge's shadow whatever the
    /// light point y; without the rotation it moves by up to the light's width.
    #[test]
    fn the_rotation_removes_the_light_points_part_of_the_shadow_position() {
        let (scene, occluder) = crate::boundary::shadow_scene("occluder");
        let table = EdgeSampler::new(&scene.geometry, scene.offset_scale);
        let mut checked = 0;
        for rec in table.edges.iter().filter(|r| r.shape == occluder) {
            let d = (rec.v1 - rec.v0).normalize();
            for s in [0.1f32, 0.3, 0.55, 0.8] {
                let along = |q: f32| -> Vec<f32> {
                    let mut out = Vec::new();
                    for i in 0..5 {
                        for j in 0..5 {
                            let y = Vec3::new(-0.2 + 0.1 * i as f32, 2.0, -0.2 + 0.1 * j as f32);
                            let x_b = shadow_aligned(rec, s, y, q);
                            // x_B stays on the edge
                            let t = (x_b - rec.v0).dot(d) / (rec.v1 - rec.v0).length();
                            assert!(
                                (-1e-6..=1.0 + 1e-6).contains(&t)
                                    && (rec.v0 + (rec.v1 - rec.v0) * t - x_b).length() < 1e-5
                            );
                            out.push((2.0 * x_b - y).dot(d));
                        }
                    }
                    out
                };
                let spread = |v: Vec<f32>| {
                    let (lo, hi) = v.iter().fold((f32::MAX, f32::MIN), |(a, b), &x| (a.min(x), b.max(x)));
                    hi - lo
                };
                let aligned = along(0.5);
                // s + c wraps past the edge's end for some y at large s: those land at the
                // other end, 2·ℓ_e away along the shadow
                let len = (rec.v1 - rec.v0).length();
                let first = aligned[0];
                assert!(
                    aligned
                        .iter()
                        .all(|&a| (a - first).abs() < 1e-4 || ((a - first).abs() - 2.0 * len).abs() < 1e-4),
                    "s {s}: {aligned:?}"
                );
                assert!(
                    spread(along(0.0)) > 0.3,
                    "without the rotation the light point moves x_S"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 16);
    }
}
