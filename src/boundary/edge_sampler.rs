//! Sampling boundary rays (x_B, ω_B) for the secondary-edge estimator (Algorithm 2, first line:
//! "Sample (x_B, ω_B) ← P_boundaryRay").
//!
//! Three uniform numbers (u0, u1, u2) map to
//! - an edge, chosen by inverting the CDF of its weight with u0, and a point x_B uniform on it
//!   from the rest of u0 (so u0 is one continuous coordinate over all edges, which the guiding
//!   grid of [`super::guiding`] can refine);
//! - a direction ω_B uniform over the directions for which the edge is a silhouette
//!   (supplemental Eq. 32): a boundary edge is a silhouette for every direction; a sharp edge
//!   only where the line through x_B along ω leaves both faces on one side of the plane that
//!   it spans with the edge. In the cross-section perpendicular to the edge the faces are two
//!   rays at an angle ψ (ψ = π − the angle between the faces' normals); the silhouette
//!   azimuths γ around the edge are (ψ, π) ∪ (ψ + π, 2π), measure 2(π − ψ), so with cos θ
//!   uniform along the edge (Archimedes) the set covers 4(π − ψ) sr of the sphere.
//!
//! An edge's weight is its length times the fraction of the sphere where it is a silhouette
//! (1 for a boundary edge, (π − ψ)/π for a sharp one): the measure of the boundary rays it
//! carries, times a caller's factor per shape (the secondary pass favours edges that move).
//! The pdf of a sample is p_e/ℓ_e per unit length times p_ω per steradian.

use super::edges::{Edge, build_edges};
use crate::scene::Geometry;
use glam::Vec3;
use std::f32::consts::PI;

/// One edge with what sampling needs, gathered once per render.
#[derive(Clone, Copy, Debug)]
pub struct EdgeRecord {
    pub edge: Edge,
    /// Shape that owns the edge's faces (its velocity moves v0 and v1).
    pub shape: u32,
    pub v0: Vec3,
    pub v1: Vec3,
    /// Unit vector ⊥ edge, from the edge into face0; `b` completes the frame (e × a), oriented
    /// so that face1 (if any) lies at azimuth ψ ∈ [0, π] from `a`.
    a: Vec3,
    b: Vec3,
    /// Angle between the faces in the cross-section (π on a boundary edge: none excluded).
    psi: f32,
}

/// A boundary ray: x_B on edge `index` and unit direction ω. Its density per unit length per
/// steradian is p_e/ℓ_e · p_ω; the estimator needs only p_e · p_ω, since ℓ_e cancels against
/// the Jacobian (see `secondary.rs`).
#[derive(Clone, Copy, Debug)]
pub struct BoundaryRay {
    pub index: usize,
    pub x_b: Vec3,
    pub omega: Vec3,
    /// p_e (edge selection) · p_ω (per steradian).
    pub pdf_edge_dir: f32,
}

/// Edge table with a CDF by weight.
#[derive(Clone, Debug, Default)]
pub struct EdgeSampler {
    /// Shared by the tables [`EdgeSampler::with_weights`] derives (a mesh's edges can be
    /// millions).
    pub edges: std::sync::Arc<Vec<EdgeRecord>>,
    /// Normalised cumulative weights, `cdf[i]` = P(edge ≤ i).
    cdf: Vec<f32>,
    /// Σ weights (length × silhouette fraction), metres.
    total: f32,
}

/// Normalised cumulative weights: entry i is P(edge ≤ i).
fn cdf_of(weights: &[f64]) -> Vec<f32> {
    let total: f64 = weights.iter().sum();
    let mut acc = 0.0f64;
    weights
        .iter()
        .map(|w| {
            acc += w;
            (acc / total.max(1e-300)) as f32
        })
        .collect()
}

/// An edge in its cross-section: its ends and length, `a` the unit vector ⊥ the edge into
/// face0, `b` = e × a oriented so that face1 (if any) lies at azimuth ψ ∈ [0, π] from `a`
/// (π for a boundary edge). `None` for an edge of no length or a degenerate face0.
struct CrossSection {
    v0: Vec3,
    v1: Vec3,
    len: f32,
    a: Vec3,
    b: Vec3,
    psi: f32,
}

fn cross_section(geo: &Geometry, e: &Edge) -> Option<CrossSection> {
    let v0 = geo.positions[e.v0 as usize];
    let v1 = geo.positions[e.v1 as usize];
    let dir = v1 - v0;
    let len = dir.length();
    if !(len > 0.0) || !len.is_finite() {
        return None;
    }
    let t = dir / len;
    let perp = |o: u32| {
        let w = geo.positions[o as usize] - v0;
        (w - t * t.dot(w)).normalize_or_zero()
    };
    let a = perp(e.opposite0);
    if a == Vec3::ZERO {
        return None;
    }
    let mut b = t.cross(a);
    let psi = match e.opposite1 {
        None => PI,
        Some(o1) => {
            let a1 = perp(o1);
            let (c, s) = (a1.dot(a), a1.dot(b));
            if s < 0.0 {
                b = -b;
            }
            s.abs().atan2(c)
        }
    };
    Some(CrossSection { v0, v1, len, a, b, psi })
}

/// Whether no line through edge `e` along its silhouette directions can join two points of
/// `points`. In the cross-section of a sharp edge the faces bound a wedge of angle ψ and its
/// vertical opposite; the silhouette lines run through the other two wedges, one end in each.
/// So when every point lies in the closed wedge between the faces, or every one in its
/// opposite, a boundary ray through the edge finds no surface at one of its ends, and the
/// edge's term is 0: a crease of a closed convex room seen from inside. A boundary edge (one
/// face) is a silhouette every way, but a line through it meets the face's plane there, so it
/// joins two points only if they lie on the two sides of that plane (or both in it, along the
/// face, a set of no measure): when every point lies on one side, its term is 0 too (the floor
/// of a room, a ground plane under everything, the front edges of an open box). Each of those
/// wedges and half-spaces is convex, so the corners of a box holding the scene stand for every
/// point in it. `slack` (metres) counts a point that far outside a face's plane as on it:
/// positions within the renderer's ray offsets of a plane are not told apart.
pub fn silhouettes_join_nothing(geo: &Geometry, e: &Edge, points: &[Vec3], slack: f32) -> bool {
    let Some(c) = cross_section(geo, e) else {
        return false;
    };
    if e.is_boundary() {
        // b is the face's normal: the height of each point over its plane
        let height = |p: &Vec3| (*p - c.v0).dot(c.b);
        return points.iter().all(|p| height(p) >= -slack) || points.iter().all(|p| height(p) <= slack);
    }
    let (sin, cos) = c.psi.sin_cos();
    // (x, y) in the (a, b) frame: between the faces means y ≥ 0 and x·sinψ − y·cosψ ≥ 0
    let sides = |p: &Vec3| {
        let w = *p - c.v0;
        let (x, y) = (w.dot(c.a), w.dot(c.b));
        (y, x * sin - y * cos)
    };
    let inside = points.iter().all(|p| {
        let (u, v) = sides(p);
        u >= -slack && v >= -slack
    });
    let opposite = points.iter().all(|p| {
        let (u, v) = sides(p);
        u <= slack && v <= slack
    });
    inside || opposite
}

/// The eight corners of the box from `lo` to `hi`: the points that stand for all of it in
/// [`silhouettes_join_nothing`].
pub fn box_corners(lo: Vec3, hi: Vec3) -> [Vec3; 8] {
    std::array::from_fn(|i| Vec3::select(glam::BVec3::new(i & 1 != 0, i & 2 != 0, i & 4 != 0), hi, lo))
}

impl EdgeSampler {
    /// Builds the edge table of the scene's world-space geometry, every edge weighted alike.
    pub fn new(geo: &Geometry, offset_scale: f32) -> Self {
        Self::with_edge_factors(geo, offset_scale, |edges| vec![1.0; edges.len()])
    }

    /// Builds the edge table with each edge's weight multiplied by its entry of
    /// `factors(edges)` (given every edge's record; a factor > 0 keeps the edge reachable, so any
    /// such factors leave the estimator unbiased).
    pub fn with_edge_factors(
        geo: &Geometry,
        offset_scale: f32,
        factors: impl FnOnce(&[EdgeRecord]) -> Vec<f32>,
    ) -> Self {
        Self::from_edges(geo, &build_edges(geo, offset_scale), factors)
    }

    /// [`Self::with_edge_factors`] over an edge list already built by `build_edges` for `geo`.
    pub fn from_edges(geo: &Geometry, list: &[Edge], factors: impl FnOnce(&[EdgeRecord]) -> Vec<f32>) -> Self {
        let mut edges = Vec::new();
        let mut weights = Vec::new();
        for &e in list {
            let Some(CrossSection { v0, v1, len, a, b, psi }) = cross_section(geo, &e) else {
                continue;
            };
            let frac = if e.is_boundary() { 1.0 } else { (PI - psi) / PI };
            let w = len * frac;
            if !(w > 0.0) {
                continue;
            }
            edges.push(EdgeRecord {
                edge: e,
                shape: geo.tri_shape[e.face0 as usize],
                v0,
                v1,
                a,
                b,
                psi: if e.is_boundary() { 0.0 } else { psi },
            });
            weights.push(w as f64);
        }
        for (w, f) in weights.iter_mut().zip(factors(&edges)) {
            *w *= f as f64;
        }
        Self {
            cdf: cdf_of(&weights),
            edges: std::sync::Arc::new(edges),
            total: weights.iter().sum::<f64>() as f32,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.edges.is_empty()
    }

    /// The same edges drawn with probabilities ∝ `weights` (one entry ≥ 0 per edge, not all
    /// 0; an edge keeps being reachable where its entry is positive). `total_weight` stays
    /// this table's.
    pub fn with_weights(&self, weights: &[f64]) -> Self {
        assert_eq!(weights.len(), self.edges.len());
        Self {
            edges: self.edges.clone(),
            cdf: cdf_of(weights),
            total: self.total,
        }
    }

    /// The edge that edge coordinate `u0` ∈ [0, 1) selects (as [`EdgeSampler::sample`] does).
    fn index_of(&self, u0: f32) -> usize {
        self.cdf
            .partition_point(|&c| c <= u0)
            .min(self.edges.len().saturating_sub(1))
    }

    /// Probability of choosing edge `i`.
    pub fn edge_pmf(&self, i: usize) -> f32 {
        let lo = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        self.cdf[i] - lo
    }

    /// The edge that edge coordinate `u0` ∈ [0, 1) selects and the position s ∈ [0, 1] on it
    /// (x_B = v0 + s·(v1 − v0)): `u0` rescaled within the edge's share. None when there are
    /// no edges.
    pub fn point(&self, u0: f32) -> Option<(usize, f32)> {
        if self.edges.is_empty() {
            return None;
        }
        let i = self.index_of(u0);
        let lo = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        let pmf = self.cdf[i] - lo;
        Some((i, ((u0 - lo) / pmf.max(f32::MIN_POSITIVE)).clamp(0.0, 1.0)))
    }

    /// Maps (u0, u1, u2) ∈ [0, 1)³ to a boundary ray. None when there are no edges.
    pub fn sample(&self, u0: f32, u1: f32, u2: f32) -> Option<BoundaryRay> {
        let (i, s) = self.point(u0)?;
        let pmf = self.edge_pmf(i);
        let r = &self.edges[i];
        let x_b = r.v0 + (r.v1 - r.v0) * s;
        let t = (r.v1 - r.v0).normalize();
        // azimuth over the silhouette set: (ψ, π) ∪ (ψ + π, 2π); ψ = 0 on boundary edges
        let width = PI - r.psi;
        let (half, v) = if u1 < 0.5 {
            (0.0, 2.0 * u1)
        } else {
            (PI, 2.0 * u1 - 1.0)
        };
        let gamma = r.psi + v * width + half;
        let cos_t = 2.0 * u2 - 1.0;
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let omega = t * cos_t + (r.a * gamma.cos() + r.b * gamma.sin()) * sin_t;
        let pdf_dir = 1.0 / (4.0 * width);
        Some(BoundaryRay {
            index: i,
            x_b,
            omega,
            pdf_edge_dir: pmf * pdf_dir,
        })
    }

    /// Density of a boundary ray (x_B on edge `i`, ω) per unit length per steradian: zero
    /// where the edge is not a silhouette for ω (for the χ² test and MIS).
    pub fn pdf(&self, i: usize, omega: Vec3) -> f32 {
        let r = &self.edges[i];
        let mut gamma = omega.dot(r.b).atan2(omega.dot(r.a));
        if gamma < 0.0 {
            gamma += 2.0 * PI;
        }
        let g = gamma % PI;
        if g < r.psi {
            return 0.0;
        }
        self.silhouette_density(i)
    }

    /// [`Self::pdf`] of edge `i` at any of its silhouette directions (one value over them).
    pub fn silhouette_density(&self, i: usize) -> f32 {
        let r = &self.edges[i];
        self.edge_pmf(i) / (r.v1 - r.v0).length() / (4.0 * (PI - r.psi))
    }

    /// Σ over edges of length × silhouette fraction (metres).
    pub fn total_weight(&self) -> f32 {
        self.total
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boundary::edges::tests::geometry;
    use crate::kernel::PathSampler;
    use crate::scene::shapes;

    /// A lone cube's edges join nothing (every line through an edge in a silhouette direction
    /// leaves the cube's box at both ends); in a box twice its size every edge can bound a
    /// segment; a boundary edge can where points lie on both sides of its face's plane, not
    /// where all lie on one side or in the plane; a point beyond a face's plane by less than
    /// the slack counts as on it.
    #[test]
    fn silhouettes_join_nothing_only_where_every_point_lies_in_the_faces_wedge() {
        let geo = geometry(shapes::cube());
        let edges = build_edges(&geo, 0.0);
        assert_eq!(edges.len(), 12);
        let (lo, hi) = geo
            .positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), &p| (l.min(p), h.max(p)));
        let box_of = |lo: Vec3, hi: Vec3| box_corners(lo, hi).to_vec();
        let own = box_of(lo, hi);
        let (c, h) = ((lo + hi) * 0.5, (hi - lo) * 0.5);
        let twice = box_of(c - 2.0 * h, c + 2.0 * h);
        for e in &edges {
            assert!(silhouettes_join_nothing(&geo, e, &own, 0.0), "{e:?}");
            assert!(!silhouettes_join_nothing(&geo, e, &twice, 0.0), "{e:?}");
            // a point 10⁻⁴ m into the wedge beside the faces' (azimuth (ψ + π)/2): a
            // silhouette line can reach it, unless the slack counts it as on the planes
            let x = cross_section(&geo, e).unwrap();
            let g = 0.5 * (x.psi + PI);
            let mut near = own.clone();
            near.push(x.v0 + 1e-4 * (x.a * g.cos() + x.b * g.sin()));
            assert!(!silhouettes_join_nothing(&geo, e, &near, 0.0), "{e:?}");
            assert!(silhouettes_join_nothing(&geo, e, &near, 1e-3), "{e:?}");
        }
        // a boundary edge: points on both sides of its face's plane can be joined through it;
        // points on one side (or in the plane, or within the slack of it) cannot
        let flap = geometry(shapes::rectangle());
        let [p0, p1, p2] = flap.indices[0].map(|i| flap.positions[i as usize]);
        let normal = (p1 - p0).cross(p2 - p0).normalize();
        let edge_point = |e: &Edge| flap.positions[e.v0 as usize];
        for e in build_edges(&flap, 0.0) {
            assert!(e.is_boundary());
            assert!(!silhouettes_join_nothing(&flap, &e, &own, 0.0));
            for side in [1.0, -1.0] {
                let one_side: Vec<Vec3> = box_corners(Vec3::splat(-3.0), Vec3::splat(3.0))
                    .iter()
                    .map(|&p| p - normal * (p - edge_point(&e)).dot(normal) + side * normal * (1.0 + p.x.abs()))
                    .chain([edge_point(&e) + Vec3::new(5.0, -4.0, 2.0).cross(normal)])
                    .collect();
                assert!(silhouettes_join_nothing(&flap, &e, &one_side, 0.0), "{e:?} {side}");
                let mut beyond = one_side.clone();
                beyond.push(edge_point(&e) - side * 1e-4 * normal);
                assert!(!silhouettes_join_nothing(&flap, &e, &beyond, 0.0), "{e:?} {side}");
                assert!(silhouettes_join_nothing(&flap, &e, &beyond, 1e-3), "{e:?} {side}");
            }
        }
    }

    /// A cube's edges have ψ = π/2: silhouette for half the sphere; every sampled direction
    /// passes the geometric test of Eq. 32 (both faces on one side of the plane of edge and ω).
    #[test]
    fn sampled_directions_are_silhouettes() {
        let s = EdgeSampler::new(&geometry(shapes::cube()), 0.0);
        assert_eq!(s.edges.len(), 12);
        for r in s.edges.iter() {
            assert!((r.psi - PI / 2.0).abs() < 1e-5, "psi {}", r.psi);
        }
        let geo = geometry(shapes::cube());
        let mut rng = PathSampler::new(5, &[0]);
        for _ in 0..2000 {
            let (u0, u1) = rng.next2::<f32>();
            let u2 = rng.next::<f32>();
            let b = s.sample(u0, u1, u2).unwrap();
            let r = &s.edges[b.index];
            let n = (r.v1 - r.v0).cross(b.omega);
            let side = |o: u32| n.dot(geo.positions[o as usize] - r.v0);
            let (s0, s1) = (side(r.edge.opposite0), side(r.edge.opposite1.unwrap()));
            assert!(s0 * s1 >= -1e-5, "not a silhouette: {s0} {s1}");
            assert!((b.omega.length() - 1.0).abs() < 1e-4);
            let p = s.pdf(b.index, b.omega) * (r.v1 - r.v0).length();
            assert!((p - b.pdf_edge_dir).abs() < 1e-4 * p, "{p} vs {}", b.pdf_edge_dir);
        }
    }

    /// χ² test: the histogram of (edge, azimuth bin, cos θ bin) cells matches the mass the
    /// sampler's pdf puts on each cell (computed exactly: uniform on the silhouette set), and
    /// the pdf integrates to 1 over the sphere (uniform-sphere quadrature within 4 se).
    #[test]
    fn pdf_matches_histogram_and_integrates_to_one() {
        // a rectangle with a flap: boundary edges and one sharp edge at an odd angle
        let mut m = shapes::rectangle();
        m.positions.push(Vec3::new(0.2, 0.3, 0.9));
        let n = m.positions.len() as u32 - 1;
        m.tris.push([0, 1, n]);
        let s = EdgeSampler::new(&geometry(m), 0.0);
        assert!(s.edges.iter().any(|r| r.psi > 0.1), "needs a sharp edge");
        let (nz, ng) = (4usize, 16usize);
        let cells = s.edges.len() * ng * nz;
        let azimuth = |r: &EdgeRecord, w: Vec3| {
            let g = w.dot(r.b).atan2(w.dot(r.a));
            if g < 0.0 { g + 2.0 * PI } else { g }
        };
        let cell = |i: usize, w: Vec3| {
            let r = &s.edges[i];
            let t = (r.v1 - r.v0).normalize();
            let z = (((t.dot(w) + 1.0) * 0.5 * nz as f32) as usize).min(nz - 1);
            let g = ((azimuth(r, w) / (2.0 * PI) * ng as f32) as usize).min(ng - 1);
            (i * ng + g) * nz + z
        };
        let draws = 200_000usize;
        let mut hist = vec![0.0f64; cells];
        let mut rng = PathSampler::new(11, &[1]);
        for _ in 0..draws {
            let (u0, u1) = rng.next2::<f32>();
            let u2 = rng.next::<f32>();
            let b = s.sample(u0, u1, u2).unwrap();
            hist[cell(b.index, b.omega)] += 1.0;
        }
        let overlap = |a0: f64, a1: f64, b0: f64, b1: f64| (a1.min(b1) - a0.max(b0)).max(0.0);
        let mut chi2 = 0.0;
        let mut dof = 0usize;
        for (i, r) in s.edges.iter().enumerate() {
            let psi = r.psi as f64;
            let allowed = 2.0 * (std::f64::consts::PI - psi);
            for g in 0..ng {
                let (g0, g1) = (
                    g as f64 * 2.0 * std::f64::consts::PI / ng as f64,
                    (g + 1) as f64 * 2.0 * std::f64::consts::PI / ng as f64,
                );
                let pi = std::f64::consts::PI;
                let inside = overlap(g0, g1, psi, pi) + overlap(g0, g1, psi + pi, 2.0 * pi);
                for z in 0..nz {
                    let e = s.edge_pmf(i) as f64 * inside / allowed / nz as f64 * draws as f64;
                    let h = hist[(i * ng + g) * nz + z];
                    if e == 0.0 {
                        assert!(
                            h <= 2.0,
                            "edge {i} azimuth bin {g}: {h} samples outside the silhouette set"
                        );
                        continue;
                    }
                    chi2 += (h - e).powi(2) / e;
                    dof += 1;
                }
            }
        }
        let dof_f = dof as f64;
        assert!(
            chi2 < dof_f + 5.0 * (2.0 * dof_f).sqrt(),
            "χ² = {chi2:.1} over {dof} cells"
        );

        let q = 200_000usize;
        let mut qs = PathSampler::new(12, &[2]);
        let mut vals = Vec::with_capacity(q);
        for _ in 0..q {
            let (a, b) = qs.next2::<f32>();
            let z = 2.0 * a - 1.0;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let w = Vec3::new(r * (2.0 * PI * b).cos(), r * (2.0 * PI * b).sin(), z);
            let v: f64 = (0..s.edges.len())
                .map(|i| (s.pdf(i, w) * (s.edges[i].v1 - s.edges[i].v0).length()) as f64 * 4.0 * std::f64::consts::PI)
                .sum();
            vals.push(v);
        }
        let m = vals.iter().sum::<f64>() / q as f64;
        let se = (vals.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (q as f64 - 1.0) / q as f64).sqrt();
        assert!((m - 1.0).abs() < 4.0 * se + 1e-6, "pdf integrates to {m} ± {se}");
    }
}
