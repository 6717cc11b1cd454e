//! Light points on the time edges: where next-event estimation samples the interior's time
//! term f·Ṡ_e·ḋ (Algorithm 1) under a narrow pulse. This file is the part a render context
//! holds (the emitters as flat polygons, the film's bin edges); `time_edge_nee.rs` is the
//! kernel step that traces and deposits.
//!
//! With a box gate, ∂S_e(l, d)/∂d = p(a_l − u) − p(b_l − u) with u = d + τ
//! (`crate::temporal`): the pulse density p centred on the bin's two edges. A path adds to
//! the time term only where its OPL lies within the pulse's width of a bin edge, and there by
//! ±f·ḋ·p, about f·ḋ/(2.5σ) for a Gaussian pulse of σ. Light points chosen uniformly on an
//! emitter land there rarely: the estimate's variance grows as the bin width over σ, and a
//! bin's derivative, the difference of its two edges' terms, is a small difference of two
//! noisy ones.
//!
//! For a vertex x with prefix OPL d_p in a medium of index η, a light point y gives the OPL
//! D = d_p + η·|x − y|, constant on spheres around x. On a flat emitter polygon at height h
//! below x, the sphere of radius r meets the plane in a circle of radius ρ = √(r² − h²)
//! around the foot point of x, and dA = ρ dρ dφ = r dr dφ. So a light point is drawn as
//! (r, φ):
//! - D from a mixture with one component per film edge E_j within reach of the OPLs the
//!   polygon allows: a logistic density of scale σ·√3/π centred on E_j and cut at the
//!   Gaussian's own cut (a heavier tail than the Gaussian, so p/q stays below 1.2), or the
//!   pulse's own uniform density for a box pulse;
//! - K = ⌈M⌉ draws (M the components' total mass within the polygon's OPLs, at most
//!   [`MAX_SLOTS`]), stratified over the components laid end to end, so that every edge the
//!   polygon reaches gets about one draw per unit of its mass; with M < 1, one draw made
//!   with probability M (Russian roulette on the line of length 1 the mass lies on);
//! - φ uniform on the arcs of that circle inside the polygon (total angle Θ).
//!
//! The K draws of a vertex share their two numbers (one offset for every stratum, one
//! fraction of every circle's arcs), so draws on neighbouring edges are positively
//! correlated and a bin's derivative, the difference of its two edges' terms, varies less.
//!
//! The area density is q(D)·η/(r·Θ) times the emitter and polygon choice. Each draw hands
//! the film f/(K·density) as a time-only contribution: the film evaluates Ṡ_e at the draw's
//! exact OPL, so every bin edge is estimated from draws aimed at it.
//!
//! A delta pulse's Ṡ_e is a Dirac on each edge (supplemental Lemma 2.5), which no sampled
//! OPL meets: its draws put one point on each reached edge's circle, and the film adds f·ḋ to
//! the bin after that edge and takes it from the bin before ([`Draw::edge`]).
//!
//! The kernel uses this only where next-event estimation covers every path it replaces: the
//! box gate, the area emitters (a point or a laser spot leaves no r to aim: their
//! contributions keep their own time term, so their pulses must be smooth where a derivative
//! shifts time), and no NLOS capture. `time_edge_nee.rs` says how the other estimators' time
//! terms are left out so that nothing is counted twice; [`TimeEdges::cover`] when a
//! delta pulse's derivative may be taken from the draws alone (and when a narrow pulse's is
//! left in part to the ordinary contributions, which a render then says).

use crate::kernel::{Mask, Real};
use crate::params::lanes::Motion;
use crate::scene::{Emitter, EmitterKind, FilmSpec, Scene};
use crate::temporal::{GAUSSIAN_CUTOFF_SIGMAS, Gate, Pulse};
use glam::{DVec2, DVec3};

/// Most draws per vertex and lane (the strata of the edge mixture).
pub const MAX_SLOTS: usize = 16;

/// Random dimensions a vertex may take (2 for the emitter and polygon, 2 its draws share),
/// with room.
pub const DIMS_PER_VERTEX: u64 = 64;

/// Widest pulse the draws take, as its standard deviation over the bin width (a box pulse's is
/// its width over √12): wider pulses keep their time term in the ordinary contributions. On
/// narrow_pulse_box.toml (an independent sweep, 32 seeds × 16 spp a mode, per-bin totals of
/// the box's translation and the pulse offset) the draws' standard error against the ordinary
/// one was 0.20–0.26 at σ/w 0.083, 0.39–0.50 at 0.33, 0.51–0.58 at 0.5, 0.81–0.87 at 1 and
/// 0.99–1.10 at 2, at 3.8–5.2× the interior's CPU time (2.0–2.6× the whole derivative's with
/// its boundary stage): at equal time they stop paying between 0.3 and 0.8.
pub const MAX_SIGMA_PER_BIN: f64 = 0.5;

/// Narrowest smooth pulse, as its standard deviation over the bin width, whose time term a
/// render leaves to the ordinary contributions without saying so ([`Needs::Narrow`]): in the
/// sweep above, those had 4–5× the draws' standard error at σ/w 0.083; on a camera-seen moving
/// panel (another sweep, 48 seeds × 64 spp, 6 cm bins) the derivative's relative error was
/// ±0.6 % at σ 3 cm, ±2.5 % at 1 mm and ±16 % at 0.1 mm.
pub const NARROW_SIGMA_PER_BIN: f64 = 0.1;

/// Film edges a plan keeps the cumulative masses of (a vertex reaching more walks them).
const CACHED_EDGES: usize = 24;

/// Most sides of a polygon kept whole; an emitter whose triangles form a larger one is
/// sampled triangle by triangle.
const MAX_SIDES: usize = 12;

/// A flat convex emitter polygon: its plane, its corners in the plane's frame (counter-
/// clockwise about the emitting normal) and its sides as half-planes m·q ≤ k.
#[derive(Clone, Debug)]
pub struct Polygon {
    origin: DVec3,
    /// The emitting side's unit normal.
    pub normal: DVec3,
    e1: DVec3,
    e2: DVec3,
    corners: Vec<DVec2>,
    sides: Vec<(DVec2, f64)>,
    /// Direction angle of each side's outward normal, in [0, 2π).
    angles: Vec<f64>,
    area: f64,
}

impl Polygon {
    /// The polygon through `corners` (3D, in order around `normal`), or `None` if degenerate.
    fn new(corners3: &[DVec3], normal: DVec3) -> Option<Self> {
        let origin = corners3[0];
        let e1 = (corners3[1] - origin).try_normalize()?;
        let e2 = normal.cross(e1);
        let corners: Vec<DVec2> = corners3
            .iter()
            .map(|&p| DVec2::new((p - origin).dot(e1), (p - origin).dot(e2)))
            .collect();
        let n = corners.len();
        let mut area = 0.0;
        let mut sides = Vec::with_capacity(n);
        for i in 0..n {
            let (a, b) = (corners[i], corners[(i + 1) % n]);
            area += 0.5 * a.perp_dot(b);
            // outward normal of a counter-clockwise side: its direction turned clockwise
            let m = DVec2::new(b.y - a.y, a.x - b.x).try_normalize()?;
            sides.push((m, m.dot(a)));
        }
        let angles = sides
            .iter()
            .map(|(m, _)| m.y.atan2(m.x).rem_euclid(std::f64::consts::TAU))
            .collect();
        (area > 0.0).then_some(Self {
            origin,
            normal,
            e1,
            e2,
            corners,
            sides,
            angles,
            area,
        })
    }

    /// The point at in-plane coordinates `q`.
    fn point(&self, q: DVec2) -> DVec3 {
        self.origin + self.e1 * q.x + self.e2 * q.y
    }

    /// (Nearest, farthest) in-plane distance from `c` to the polygon.
    fn distance_range(&self, c: DVec2) -> (f64, f64) {
        let far = self.corners.iter().map(|&v| (v - c).length()).fold(0.0, f64::max);
        if self.sides.iter().all(|&(m, k)| m.dot(c) <= k) {
            return (0.0, far);
        }
        let n = self.corners.len();
        let near = (0..n)
            .map(|i| {
                let (a, b) = (self.corners[i], self.corners[(i + 1) % n]);
                let t = ((c - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
                (a + (b - a) * t - c).length()
            })
            .fold(f64::INFINITY, f64::min);
        (near, far)
    }

    /// The arcs of the circle of radius `rho` around `c` that lie inside the polygon, as
    /// angle intervals in [0, 2π) (at most `MAX_SIDES` of them), and their total angle.
    fn arcs(&self, c: DVec2, rho: f64, out: &mut [(f64, f64); MAX_SIDES]) -> (usize, f64) {
        use std::f64::consts::TAU;
        // the angles each side forbids: |φ − α| < β where cos(φ − α) > s; the sides that
        // reach the circle (s < 1) take β = acos s, four sides to one vector call
        let n_sides = self.sides.len();
        let mut s = [1.0f64; MAX_SIDES];
        for (s, &(m, k)) in s.iter_mut().zip(&self.sides) {
            *s = (k - m.dot(c)) / rho;
            if *s <= -1.0 {
                return (0, 0.0);
            }
        }
        let mut beta = [0.0f64; MAX_SIDES];
        for (b, s) in beta
            .chunks_exact_mut(4)
            .zip(s.chunks_exact(4))
            .take(n_sides.div_ceil(4))
        {
            if s.iter().any(|&s| s < 1.0) {
                let v = wide::f64x4::from([s[0], s[1], s[2], s[3]].map(|s| s.min(1.0))).acos();
                b.copy_from_slice(&v.to_array());
            }
        }
        let mut cut = [(0.0f64, 0.0f64); 2 * MAX_SIDES];
        let mut n_cut = 0;
        for ((&alpha, &s), &beta) in self.angles.iter().zip(&s).zip(&beta) {
            if s >= 1.0 {
                continue;
            }
            let (lo, hi) = (alpha - beta, alpha + beta);
            if lo < 0.0 {
                cut[n_cut] = (lo + TAU, TAU);
                cut[n_cut + 1] = (0.0, hi);
                n_cut += 2;
            } else if hi > TAU {
                cut[n_cut] = (lo, TAU);
                cut[n_cut + 1] = (0.0, hi - TAU);
                n_cut += 2;
            } else {
                cut[n_cut] = (lo, hi);
                n_cut += 1;
            }
        }
        let cut = &mut cut[..n_cut];
        cut.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        // the complement of the forbidden intervals' union
        let (mut n, mut total, mut from) = (0, 0.0, 0.0);
        for &(lo, hi) in cut.iter() {
            if lo > from && n < MAX_SIDES {
                out[n] = (from, lo);
                total += lo - from;
                n += 1;
            }
            from = from.max(hi);
        }
        if from < TAU && n < MAX_SIDES {
            out[n] = (from, TAU);
            total += TAU - from;
            n += 1;
        }
        (n, total)
    }
}

/// The pulse's spread around a bin edge, as the draws' density in OPL.
#[derive(Clone, Copy, Debug)]
enum Spread {
    /// Logistic of scale `s`, cut at ±`cut` (a Gaussian pulse: s = σ·√3/π, cut at
    /// `GAUSSIAN_CUTOFF_SIGMAS`·σ, where the film's ∂S_e/∂d ends too). `per_edge` =
    /// e^{−w/s} for film edges w apart: the factor by which e^{−t/s} changes from one edge's
    /// component to the next, which lets a run of components share one `exp`
    /// ([`Spread::component_masses`], [`Spread::density_at`]).
    Logistic { s: f64, cut: f64, per_edge: f64 },
    /// Uniform on ±`half` (a box pulse: ∂S_e/∂d is ±1/width there).
    Uniform { half: f64 },
    /// The edge itself (a delta pulse: ∂S_e/∂d is a Dirac on each edge, supplemental
    /// Lemma 2.5). Each edge the polygon reaches gets one draw on its circle, r = (E_j − d_p)/η.
    Delta,
}

impl Spread {
    /// The draws' spread for `pulse`, on film edges `width` apart.
    fn of(pulse: Pulse, width: f64) -> Self {
        match pulse {
            Pulse::Gaussian { sigma_opl } => {
                let sigma = sigma_opl as f64;
                let s = sigma * 3f64.sqrt() / std::f64::consts::PI;
                Spread::Logistic {
                    s,
                    cut: GAUSSIAN_CUTOFF_SIGMAS * sigma,
                    per_edge: (-width / s).exp(),
                }
            }
            Pulse::Box { width_opl } => Spread::Uniform {
                half: 0.5 * width_opl as f64,
            },
            Pulse::Delta => Spread::Delta,
        }
    }

    fn reach(self) -> f64 {
        match self {
            Spread::Logistic { cut, .. } => cut,
            Spread::Uniform { half } => half,
            Spread::Delta => 0.0,
        }
    }

    /// The distribution function at `t` (in its own units: logistic or uniform mass).
    fn cdf(self, t: f64) -> f64 {
        match self {
            Spread::Logistic { s, .. } => 1.0 / (1.0 + (-t / s).exp()),
            Spread::Uniform { half } => (t + half) / (2.0 * half),
            // a unit mass at t = 0 (the callers' windows hold it or not)
            Spread::Delta => (t >= 0.0) as u8 as f64,
        }
    }

    fn inverse_cdf(self, p: f64) -> f64 {
        match self {
            Spread::Logistic { s, .. } => s * (p / (1.0 - p)).ln(),
            Spread::Uniform { half } => p * 2.0 * half - half,
            Spread::Delta => 0.0,
        }
    }

    /// The density at `t` inside the cut (the caller keeps |t| within reach).
    fn pdf(self, t: f64) -> f64 {
        match self {
            Spread::Logistic { s, .. } => {
                let e = (-t.abs() / s).exp();
                e / (s * (1.0 + e) * (1.0 + e))
            }
            Spread::Uniform { half } => 0.5 / half,
            // not a density: the delta's draws take their weight without it (`TimeEdges::draw`)
            Spread::Delta => 1.0,
        }
    }

    /// The bounds (in t = `edge` − D) of the component centred on `edge` over OPLs
    /// [`d_lo`, `d_hi`], within reach.
    fn window(self, edge: f64, d_lo: f64, d_hi: f64) -> (f64, f64) {
        let reach = self.reach();
        ((edge - d_hi).max(-reach), (edge - d_lo).min(reach))
    }

    /// The mixture's density at OPL `d` (unnormalised): Σ pdf(t_j) over the components j in
    /// `js` whose t_j = `first` + j·`w` − d lies within reach. For the logistic,
    /// e^{−|t|/s} is carried outward from t = 0 on each side by `per_edge`, so a draw takes
    /// two `exp` however many components overlap (within about n ulp of evaluating each).
    fn density_at(self, first: f64, w: f64, d: f64, js: std::ops::Range<usize>) -> f64 {
        let t = |j: usize| first + j as f64 * w - d;
        let Spread::Logistic { s, cut, per_edge } = self else {
            let reach = self.reach();
            return js.map(|j| if t(j).abs() <= reach { self.pdf(t(j)) } else { 0.0 }).sum();
        };
        let pdf = |e: f64| e / (s * (1.0 + e) * (1.0 + e));
        // the first component at or past t = 0; those before it have t < 0
        let mut mid = ((d - first) / w).ceil().clamp(js.start as f64, js.end as f64) as usize;
        while mid > js.start && t(mid - 1) >= 0.0 {
            mid -= 1;
        }
        while mid < js.end && t(mid) < 0.0 {
            mid += 1;
        }
        let mut sum = 0.0;
        // outward from t = 0 on one side, while |t| is within the cut
        let mut side = |outward: &mut dyn Iterator<Item = usize>| {
            let mut e = None;
            for j in outward {
                let a = t(j).abs();
                if a > cut {
                    break;
                }
                let v = e.map_or_else(|| (-a / s).exp(), |e: f64| e * per_edge);
                sum += pdf(v);
                e = Some(v);
            }
        };
        side(&mut (mid..js.end));
        side(&mut (js.start..mid).rev());
        sum
    }

    /// `f(i, mass)` for the components j = `js`.start + i, in order, until `f` returns false:
    /// each one's mass between
    /// t = `first` + j·w − `d_hi` and `first` + j·w − `d_lo`, within the cut (0 where that
    /// window is empty), as [`Spread::cdf`] gives it. For the logistic, e^{−t/s} at both ends
    /// is carried from one component to the next by `per_edge` while the end lies inside the
    /// cut, and taken afresh from `exp` where it enters it.
    fn component_masses(
        self,
        first: f64,
        w: f64,
        d_lo: f64,
        d_hi: f64,
        js: std::ops::Range<usize>,
        mut f: impl FnMut(usize, f64) -> bool,
    ) {
        let Spread::Logistic { s, cut, per_edge } = self else {
            for (i, j) in js.enumerate() {
                let (a, b) = self.window(first + j as f64 * w, d_lo, d_hi);
                let m = match self {
                    Spread::Delta => (a <= b) as u8 as f64,
                    _ if a >= b => 0.0,
                    _ => self.cdf(b) - self.cdf(a),
                };
                if !f(i, m) {
                    return;
                }
            }
            return;
        };
        let (at_lo, at_hi) = (self.cdf(-cut), self.cdf(cut));
        // e^{−t/s} at each end while it lies inside the cut
        let (mut ea, mut eb): (Option<f64>, Option<f64>) = (None, None);
        let carried = |e: &mut Option<f64>, t: f64, clipped: bool, at_cut: f64| -> f64 {
            if clipped {
                *e = None;
                return at_cut;
            }
            let v = e.map_or_else(|| (-t / s).exp(), |e| e * per_edge);
            *e = Some(v);
            1.0 / (1.0 + v)
        };
        for (i, j) in js.enumerate() {
            let edge = first + j as f64 * w;
            let (a, b) = self.window(edge, d_lo, d_hi);
            if a >= b {
                ea = None;
                eb = None;
                if !f(i, 0.0) {
                    return;
                }
                continue;
            }
            let ca = carried(&mut ea, a, edge - d_hi <= -cut, at_lo);
            let cb = carried(&mut eb, b, edge - d_lo >= cut, at_hi);
            if !f(i, cb - ca) {
                return;
            }
        }
    }
}

/// One emitter's polygons with their area shares.
#[derive(Clone, Debug)]
struct EmitterPolygons {
    /// The scene's index of the emitter, and its shape.
    emitter: u32,
    shape: usize,
    polygons: Vec<Polygon>,
    /// Cumulative area shares (last = 1).
    cdf: Vec<f64>,
    radiance: [f32; 3],
}

impl EmitterPolygons {
    /// `polygons` of emitter shape `shape`, chosen by area; `None` if they have no area.
    fn new(emitter: u32, shape: usize, polygons: Vec<Polygon>, radiance: [f32; 3]) -> Option<Self> {
        let total: f64 = polygons.iter().map(|p| p.area).sum();
        if polygons.is_empty() || !(total > 0.0) {
            return None;
        }
        let mut acc = 0.0;
        let cdf = polygons
            .iter()
            .map(|p| {
                acc += p.area / total;
                acc
            })
            .collect();
        Some(Self {
            emitter,
            shape,
            polygons,
            cdf,
            radiance,
        })
    }
}

/// What the time-edge draws need of a render, built once ([`TimeEdges::build`]).
#[derive(Clone, Debug)]
pub struct TimeEdges {
    /// The area emitters whose light points the draws take (`spreads` and `first` follow
    /// them), and each of the scene's emitters' place among them (`None`: a point light, a
    /// laser or a pulse wider than [`MAX_SIGMA_PER_BIN`], whose contributions keep their time
    /// term).
    emitters: Vec<EmitterPolygons>,
    slot: Vec<Option<u32>>,
    spreads: Vec<Spread>,
    /// OPL of film edge 0 less each emitter's offset τ (the edges then lie at `first + j·w`).
    first: Vec<f64>,
    width: f64,
    /// Film edges: bins + 1.
    edges: usize,
    /// Every lane's OPL may move whatever its vertices do: a pulse-offset parameter, or an
    /// emitter that moves.
    pub always: bool,
    /// Some parameter moves an emitter (its light points then carry velocities).
    pub emitters_move: bool,
}

/// A vertex's draws: the polygon and the OPL components it reaches.
#[derive(Clone, Copy, Debug)]
pub struct Plan {
    /// The scene's index of the emitter, and its place among the draws' (`TimeEdges::emitters`).
    pub emitter: u32,
    slot: u32,
    polygon: u32,
    /// Emitter and polygon choice probability.
    p_choice: f64,
    /// Foot point of x in the polygon's plane, and the height of x above it.
    foot: DVec2,
    h: f64,
    d_p: f64,
    eta: f64,
    /// OPL range the polygon allows.
    d_lo: f64,
    d_hi: f64,
    /// Film edges reached: j0..j1.
    j0: usize,
    j1: usize,
    /// Cumulative masses of edges j0.. (when j1 − j0 ≤ `CACHED_EDGES`).
    cum: [f64; CACHED_EDGES],
    /// Total mixture mass, the length of the line the draws stratify (max(mass, 1): with
    /// less mass than one draw, a draw past the mass is not made), and draws.
    mass: f64,
    line: f64,
    pub slots: usize,
}

/// One light point drawn for a vertex: the point and 1/(K·density) (area, choice included);
/// for a delta pulse, the film edge it lies on, and 1/(K·density) of the edge's circle
/// (dℓ(edge) = r·dφ·dr = r·dφ·dD/η).
#[derive(Clone, Copy, Debug)]
pub struct Draw {
    pub y: DVec3,
    pub weight: f64,
    pub edge: Option<u32>,
}

impl TimeEdges {
    /// The draws' data, on the area emitters whose pulse is delta or at most
    /// [`MAX_SIGMA_PER_BIN`] of a bin wide, when the film's gate is a box, there is no NLOS
    /// capture and some parameter shifts paths in time; `None` otherwise (the kernel then keeps
    /// the time term in its ordinary contributions; a delta pulse's is then refused,
    /// [`Self::cover`]). Point lights, lasers and wider pulses are left to their ordinary
    /// contributions, which keep their time term ([`Self::covers`]).
    pub fn build(scene: &Scene, motion: &Motion) -> Option<Self> {
        if scene.nlos.is_some() || scene.film.gate != Gate::Box || scene.emitters.is_empty() {
            return None;
        }
        if !(0..motion.len()).any(|k| motion.shifts_time(k)) {
            return None;
        }
        let geo = &scene.geometry;
        let mut emitters = Vec::new();
        let mut slot = Vec::new();
        let mut spreads = Vec::new();
        let mut first = Vec::new();
        let mut emitters_move = false;
        for (index, e) in scene.emitters.iter().enumerate() {
            let narrow = e.pulse.std_dev() <= MAX_SIGMA_PER_BIN * scene.film.axis.bin_width_opl;
            let (&EmitterKind::Area { shape, radiance }, true) = (&e.kind, narrow) else {
                slot.push(None);
                continue;
            };
            slot.push(Some(emitters.len() as u32));
            spreads.push(Spread::of(e.pulse, scene.film.axis.bin_width_opl));
            first.push(scene.film.axis.start_opl - e.offset_opl);
            emitters_move |= motion
                .fields
                .iter()
                .any(|f| f.iter().any(|(s, _)| *s == shape as usize));
            let s = &scene.shapes[shape as usize];
            let tris: Vec<[DVec3; 3]> = (s.first_tri..s.first_tri + s.tri_count)
                .map(|t| geo.indices[t as usize].map(|i| geo.positions[i as usize].as_dvec3()))
                .collect();
            emitters.push(EmitterPolygons::new(
                index as u32,
                shape as usize,
                polygons(&tris),
                radiance,
            )?);
        }
        if emitters.is_empty() {
            return None;
        }
        Some(Self {
            emitters,
            slot,
            spreads,
            first,
            width: scene.film.axis.bin_width_opl,
            edges: scene.film.axis.bins + 1,
            always: emitters_move || motion.pulse_offset.iter().any(Option::is_some),
            emitters_move,
        })
    }

    /// Whether the draws take the whole time term of the paths to the emitters `needs` picks
    /// (a delta pulse's, whose Ṡ_e is a Dirac on each bin edge that no ordinary contribution
    /// can estimate, supplemental Lemma 2.5; or a narrow one's, [`Needs`]): `Ok` when no
    /// emitter is picked, or when the path tracer draws (`path_draws`: its kernel, the draws
    /// on), every picked emitter is an area emitter, no material has a Dirac lobe or transmits
    /// (a path whose last vertex before the light is such would reach it without a draw), and
    /// no parameter shifts the paths that see a picked emitter from the camera (its pulse
    /// offset, the medium's index, its motion). Else why not.
    pub fn cover(scene: &Scene, motion: &Motion, path_draws: bool, needs: Needs) -> Result<(), Uncovered> {
        let picked = |e: &Emitter| needs.of(e, &scene.film);
        if !scene.emitters.iter().any(picked) {
            return Ok(());
        }
        if !path_draws {
            return Err("the draws on the time edges are off (--time-edges off; auto turns them on)".into());
        }
        if scene.nlos.is_some() {
            return Err("an NLOS capture's laser spots leave no light point to draw".into());
        }
        // (the draws cover the area emitters; a point light or a laser is not)
        if let Some(i) = scene
            .emitters
            .iter()
            .position(|e| picked(e) && !matches!(e.kind, EmitterKind::Area { .. }))
        {
            return Err(Uncovered {
                emitter: Some(i),
                ..format!(
                    "emitter {:?} has a {} pulse but is not an area emitter (no light point to draw)",
                    scene.emitters[i].name,
                    needs.pulse()
                )
                .into()
            });
        }
        if let Some(m) = scene
            .materials
            .iter()
            .find(|m| m.material.is_delta() || matches!(m.material, crate::scene::Material::Dielectric { .. }))
        {
            return Err(format!(
                "material {:?} (type {}) reaches the light along paths the draws do not make (a Dirac lobe or a refraction)",
                m.name,
                m.material.type_name()
            )
            .into());
        }
        for k in 0..motion.len() {
            let picked_offset = motion.pulse_offset[k].filter(|&e| picked(&scene.emitters[e]));
            // (a moving emitter the draws need not cover keeps the time term of the paths that
            // see it from the camera in its ordinary contributions)
            let moved = scene.emitters.iter().position(|e| match e.kind {
                EmitterKind::Area { shape, .. } => {
                    picked(e) && motion.fields[k].iter().any(|(s, _)| *s == shape as usize)
                }
                _ => false,
            });
            if picked_offset.is_some() || motion.eta[k] || moved.is_some() {
                let what = if picked_offset.is_some() {
                    format!("the pulse offset of a {} emitter", needs.pulse())
                } else if motion.eta[k] {
                    "the medium's index".to_string()
                } else {
                    format!(
                        "the motion of {} emitter {:?}",
                        needs.pulse(),
                        moved.map_or("", |i| scene.emitters[i].name.as_str())
                    )
                };
                return Err(Uncovered {
                    param: Some(k),
                    emitter: picked_offset.or(moved),
                    why: format!(
                        "it shifts the emitter seen from the camera in time ({what}), along paths with no vertex to draw from"
                    ),
                });
            }
        }
        match Self::build(scene, motion) {
            Some(_) => Ok(()),
            None if scene.film.gate != Gate::Box => Ok(()),
            None => Err("an emitter has no area to draw light points on".into()),
        }
    }
}

/// The emitters whose time term [`TimeEdges::cover`] asks the draws to take whole.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Needs {
    /// A delta pulse under a box gate: Ṡ_e is a Dirac on each bin edge, so a derivative whose
    /// paths leave it to the ordinary contributions is refused
    /// (`super::time_terms::refuse_uncovered_delta`).
    Delta,
    /// A smooth pulse under a box gate narrower than [`NARROW_SIGMA_PER_BIN`] of a bin: the
    /// ordinary contributions estimate its time term without bias, but with a variance that
    /// grows as the bin width over σ; a render whose paths leave it to them says so
    /// (`super::time_terms::narrow_warning`).
    Narrow,
}

impl Needs {
    /// Whether emitter `e` under `film`'s gate is one of these.
    pub fn of(self, e: &Emitter, film: &FilmSpec) -> bool {
        film.gate == Gate::Box
            && match self {
                Needs::Delta => e.pulse == Pulse::Delta,
                Needs::Narrow => {
                    e.pulse != Pulse::Delta && e.pulse.std_dev() < NARROW_SIGMA_PER_BIN * film.axis.bin_width_opl
                }
            }
    }

    /// The pulse's word in messages.
    pub fn pulse(self) -> &'static str {
        match self {
            Needs::Delta => "delta",
            Needs::Narrow => "narrow",
        }
    }
}

/// Why the draws on the time edges cannot take the whole time term of a delta (or narrow)
/// pulse ([`TimeEdges::cover`]): the reason, and the parameter (its index among the render's)
/// and the emitter (scene index) it is about where there is one, which are then the ones to
/// name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Uncovered {
    pub param: Option<usize>,
    pub emitter: Option<usize>,
    pub why: String,
}

impl From<&str> for Uncovered {
    fn from(why: &str) -> Self {
        String::from(why).into()
    }
}

impl From<String> for Uncovered {
    fn from(why: String) -> Self {
        Uncovered {
            param: None,
            emitter: None,
            why,
        }
    }
}

impl TimeEdges {
    /// The draws' own data of scene emitter `e` (an area emitter).
    fn own(&self, e: u32) -> &EmitterPolygons {
        &self.emitters[self.slot[e as usize].expect("an area emitter") as usize]
    }

    /// The shape area emitter `e` covers (its light points move with it).
    pub fn shape(&self, e: u32) -> usize {
        self.own(e).shape
    }

    pub fn radiance(&self, e: u32) -> [f32; 3] {
        self.own(e).radiance
    }

    /// Whether the draws take the time term of the paths that end on scene emitter `e` (an
    /// area emitter), which its ordinary contributions then leave out.
    pub fn covers(&self, e: u32) -> bool {
        self.slot.get(e as usize).is_some_and(Option::is_some)
    }

    /// The lanes whose emitter (scene index per lane; `u32::MAX`: none) the draws cover.
    pub fn covered<R: Real>(&self, emitters: &[u32; 8]) -> R::Mask {
        let covered: [bool; 8] = std::array::from_fn(|i| self.covers(emitters[i]));
        R::Mask::from_bools(&covered[..R::LANES])
    }

    /// The emitting normal of the plan's polygon.
    pub fn normal(&self, plan: &Plan) -> DVec3 {
        self.emitters[plan.slot as usize].polygons[plan.polygon as usize].normal
    }

    /// The draws for vertex `x` (prefix OPL `d_p`, medium index `eta`): the emitter from
    /// `u_e`, its polygon from `u_p`, and how many draws the edges it reaches need. `None`
    /// when x is behind the polygon or no film edge is within reach.
    pub fn plan(&self, x: DVec3, d_p: f64, eta: f64, u_e: f64, u_p: f64) -> Option<Plan> {
        let n_e = self.emitters.len();
        let e = ((u_e * n_e as f64) as usize).min(n_e - 1);
        let em = &self.emitters[e];
        let k = em.cdf.partition_point(|&c| c <= u_p).min(em.cdf.len() - 1);
        let p_poly = em.cdf[k] - if k == 0 { 0.0 } else { em.cdf[k - 1] };
        let poly = &em.polygons[k];
        let h = (x - poly.origin).dot(poly.normal);
        if !(h > 0.0) || !(eta > 0.0) {
            return None;
        }
        let rel = x - poly.origin;
        let foot = DVec2::new(rel.dot(poly.e1), rel.dot(poly.e2));
        let (near, far) = poly.distance_range(foot);
        let d_lo = d_p + eta * (h * h + near * near).sqrt();
        let d_hi = d_p + eta * (h * h + far * far).sqrt();
        let spread = self.spreads[e];
        let reach = spread.reach();
        let (first, w) = (self.first[e], self.width);
        let j0 = ((d_lo - reach - first) / w).ceil().max(0.0);
        let j1 = ((d_hi + reach - first) / w).floor() + 1.0;
        let j1 = j1.min(self.edges as f64);
        if !(j0 < j1) {
            return None;
        }
        let (j0, j1) = (j0 as usize, j1 as usize);
        let mut cum = [0.0; CACHED_EDGES];
        let mut mass = 0.0;
        spread.component_masses(first, w, d_lo, d_hi, j0..j1, |i, m| {
            mass += m;
            if i < CACHED_EDGES {
                cum[i] = mass;
            }
            true
        });
        if !(mass > 0.0) {
            return None;
        }
        Some(Plan {
            emitter: em.emitter,
            slot: e as u32,
            polygon: k as u32,
            p_choice: p_poly / n_e as f64,
            foot,
            h,
            d_p,
            eta,
            d_lo,
            d_hi,
            j0,
            j1,
            cum,
            mass,
            line: mass.max(1.0),
            slots: (mass.ceil() as usize).clamp(1, MAX_SLOTS),
        })
    }

    /// The bounds (in the spread's t = E_j − D) of edge j's component over [d_lo, d_hi].
    fn window(&self, e: usize, j: usize, d_lo: f64, d_hi: f64) -> (f64, f64) {
        self.spreads[e].window(self.first[e] + j as f64 * self.width, d_lo, d_hi)
    }

    /// Draw `slot` of `plan` from the numbers `xi` (position in its stratum) and `v` (angle):
    /// the light point and its weight 1/(K·density), or `None` past the mass (Russian
    /// roulette when it is under one draw's worth) or where the circle misses the polygon
    /// (only at its rim, in rounding).
    pub fn draw(&self, plan: &Plan, slot: usize, xi: f64, v: f64) -> Option<Draw> {
        let e = plan.slot as usize;
        let spread = self.spreads[e];
        // the stratum's point of the components laid end to end
        let mut u = (slot as f64 + xi.clamp(0.0, 1.0)) / plan.slots as f64 * plan.line;
        if u >= plan.mass {
            return None;
        }
        if let Spread::Delta = spread {
            // one unit of mass per edge in reach, in order: the point's edge, on its circle
            let j = (plan.j0 + u as usize).min(plan.j1 - 1);
            let d = self.first[e] + j as f64 * self.width;
            let (y, r_theta) = self.on_circle(plan, d, v)?;
            return Some(Draw {
                y,
                weight: plan.line / plan.slots as f64 * r_theta / (plan.eta * plan.p_choice),
                edge: Some(j as u32),
            });
        }
        // the edge the point falls on (found from the cumulative masses when the plan kept
        // them, else by walking the components' masses as the plan took them) and the point's
        // mass within it
        let n = plan.j1 - plan.j0;
        let (first, w) = (self.first[e], self.width);
        let (j, u) = if n <= CACHED_EDGES {
            let i = plan.cum[..n].partition_point(|&c| c <= u).min(n - 1);
            (plan.j0 + i, u - if i == 0 { 0.0 } else { plan.cum[i - 1] })
        } else {
            let mut found = (plan.j1 - 1, 0.0);
            spread.component_masses(first, w, plan.d_lo, plan.d_hi, plan.j0..plan.j1, |i, m| {
                if u < m || i + 1 == n {
                    found = (plan.j0 + i, u);
                    return false;
                }
                u -= m;
                true
            });
            found
        };
        let (a, b) = self.window(e, j, plan.d_lo, plan.d_hi);
        if a >= b {
            return None;
        }
        let (ca, cb) = (spread.cdf(a), spread.cdf(b));
        let p = (ca + u).clamp(ca, cb);
        let t = first + j as f64 * w - spread.inverse_cdf(p).clamp(a, b);
        let d = t.clamp(plan.d_lo, plan.d_hi);
        // the mixture's density in D at d: every component whose window holds d
        let reach = spread.reach();
        let lo = ((d - reach - first) / w).ceil().max(plan.j0 as f64) as usize;
        let hi = (((d + reach - first) / w).floor() + 1.0).min(plan.j1 as f64) as usize;
        let q = spread.density_at(first, w, d, lo..hi.max(lo)) / plan.line;
        if !(q > 0.0) {
            return None;
        }
        let (y, r_theta) = self.on_circle(plan, d, v)?;
        // area density: q(D)·η per unit r, over r·Θ per unit area, times the choice
        let density = q * plan.eta / r_theta * plan.p_choice;
        Some(Draw {
            y,
            weight: 1.0 / (plan.slots as f64 * density),
            edge: None,
        })
    }

    /// The light point at angle number `v` on the circle of the plan's polygon where the OPL
    /// is `d`, and r·Θ (the circle's radius r around x times its angle inside the polygon).
    fn on_circle(&self, plan: &Plan, d: f64, v: f64) -> Option<(DVec3, f64)> {
        let r = (d - plan.d_p) / plan.eta;
        let rho = (r * r - plan.h * plan.h).max(0.0).sqrt();
        let poly = &self.emitters[plan.slot as usize].polygons[plan.polygon as usize];
        let mut arcs = [(0.0, 0.0); MAX_SIDES];
        let (n, theta) = poly.arcs(plan.foot, rho, &mut arcs);
        if !(theta > 0.0) {
            return None;
        }
        let mut along = v.clamp(0.0, 1.0) * theta;
        let mut phi = arcs[n - 1].1;
        for &(a, b) in &arcs[..n] {
            if along < b - a {
                phi = a + along;
                break;
            }
            along -= b - a;
        }
        Some((
            poly.point(plan.foot + DVec2::new(phi.cos(), phi.sin()) * rho),
            r * theta,
        ))
    }
}

/// An emitter's triangles as convex polygons: one when they are coplanar, face the same way
/// and their union is convex (a quad light's two triangles), else one per triangle.
fn polygons(tris: &[[DVec3; 3]]) -> Vec<Polygon> {
    let normal_of = |t: &[DVec3; 3]| (t[1] - t[0]).cross(t[2] - t[0]);
    let per_triangle = || {
        tris.iter()
            .filter_map(|t| Polygon::new(t, normal_of(t).try_normalize()?))
            .collect::<Vec<_>>()
    };
    let Some(n) = tris.first().and_then(|t| normal_of(t).try_normalize()) else {
        return Vec::new();
    };
    let o = tris[0][0];
    let scale = tris.iter().flatten().map(|p| (*p - o).length()).fold(0.0, f64::max);
    let flat = tris.iter().all(|t| {
        normal_of(t).try_normalize().is_some_and(|m| m.dot(n) > 1.0 - 1e-9)
            && t.iter().all(|p| (*p - o).dot(n).abs() <= 1e-6 * scale.max(1e-30))
    });
    if tris.len() == 1 || !flat {
        return per_triangle();
    }
    // the convex hull of the corners in the plane (monotone chain), kept if it has the
    // triangles' area (their union is then that convex polygon)
    let e1 = (tris[0][1] - o).normalize();
    let e2 = n.cross(e1);
    let mut pts: Vec<DVec2> = tris
        .iter()
        .flatten()
        .map(|p| DVec2::new((*p - o).dot(e1), (*p - o).dot(e2)))
        .collect();
    pts.sort_unstable_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    pts.dedup_by(|a, b| (*a - *b).length() <= 1e-9 * scale);
    let hull = convex_hull(&pts);
    let tri_area: f64 = tris.iter().map(|t| 0.5 * normal_of(t).length()).sum();
    let corners: Vec<DVec3> = hull.iter().map(|q| o + e1 * q.x + e2 * q.y).collect();
    match Polygon::new(&corners, n) {
        Some(p) if hull.len() <= MAX_SIDES && (p.area - tri_area).abs() <= 1e-6 * tri_area => vec![p],
        _ => per_triangle(),
    }
}

/// Counter-clockwise convex hull of points sorted by (x, y).
fn convex_hull(pts: &[DVec2]) -> Vec<DVec2> {
    if pts.len() < 3 {
        return pts.to_vec();
    }
    let turn = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<DVec2> = Vec::with_capacity(2 * pts.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &DVec2>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2 && turn(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0 {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

#[cfg(test)]
#[path = "time_edges_tests.rs"]
mod tests;
