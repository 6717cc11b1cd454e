//! Discontinuity edges of the pixel integrand, seen from the camera, and sampling them in
//! proportion to their projected length (Li et al. 2018, "Differentiable Monte Carlo ray
//! tracing through edge sampling": primary edges are sampled in image space).
//!
//! A film point u sees radiance L(u) that jumps where the projection of a mesh edge separates
//! two different surfaces: silhouettes (boundary edges, and sharp edges whose faces lie on the
//! same side of the plane through the eye and the edge: supplemental Eq. 32 with x the eye),
//! and, because shading uses flat per-face normals, creases between two visible faces (their
//! two sides are shaded differently; redner makes the same choice for meshes without shading
//! normals). Coplanar edges were dropped by [`build_edges`](super::edges::build_edges).
//!
//! Geometry is in f64 here: an edge is clipped to the near plane, projected, and clipped to the
//! film widened by the filter radius; the map between the film and the 3-D edge is projective,
//! so the point at film parameter s is found by perspective-correct interpolation.

use super::edges::Edge;
use crate::scene::{Camera, Geometry};
use glam::{DVec2, DVec3};

/// Edges closer to the eye than this (metres, along the view axis) are clipped away.
pub const Z_NEAR: f64 = 1e-4;

/// The pinhole map from world points to film coordinates in pixels (origin top-left, y down),
/// the same map as `CameraSampler::project`, in f64 and without the film bounds.
#[derive(Clone, Copy, Debug)]
pub struct Pinhole {
    pub eye: DVec3,
    right: DVec3,
    up: DVec3,
    fwd: DVec3,
    /// Pixels per unit of x/z and y/z on the image plane.
    scale_x: f64,
    scale_y: f64,
    pub width: f64,
    pub height: f64,
}

impl Pinhole {
    pub fn new(cam: &Camera, width: u32, height: u32) -> Self {
        let (right, up, fwd) = cam.frame();
        let tan_half = ((cam.fov_y_deg as f64).to_radians() * 0.5).tan();
        let (w, h) = (width as f64, height as f64);
        Self {
            eye: cam.position.as_dvec3(),
            right: right.as_dvec3(),
            up: up.as_dvec3(),
            fwd: fwd.as_dvec3(),
            scale_x: 0.5 * w / (tan_half * w / h),
            scale_y: 0.5 * h / tan_half,
            width: w,
            height: h,
        }
    }

    /// Distance of `p` in front of the eye along the view axis.
    pub fn depth(&self, p: DVec3) -> f64 {
        (p - self.eye).dot(self.fwd)
    }

    /// Film coordinates of `p` (meaningful for depth > 0).
    pub fn film(&self, p: DVec3) -> DVec2 {
        let d = p - self.eye;
        let z = d.dot(self.fwd);
        DVec2::new(
            0.5 * self.width + self.scale_x * d.dot(self.right) / z,
            0.5 * self.height - self.scale_y * d.dot(self.up) / z,
        )
    }

    /// Film velocity of point `p` moving with world velocity `v`: the projection's Jacobian
    /// applied to `v` (pixels per unit of the parameter).
    pub fn film_velocity(&self, p: DVec3, v: DVec3) -> DVec2 {
        let d = p - self.eye;
        let z = d.dot(self.fwd);
        let vz = v.dot(self.fwd);
        let z2 = z * z;
        DVec2::new(
            self.scale_x * (v.dot(self.right) * z - d.dot(self.right) * vz) / z2,
            -self.scale_y * (v.dot(self.up) * z - d.dot(self.up) * vz) / z2,
        )
    }
}

/// How an edge looks from the eye.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EdgeView {
    /// One face (a mesh boundary): always a silhouette.
    Boundary,
    /// Two faces, one facing the eye and one facing away (supplemental Eq. 32).
    Silhouette,
    /// Two faces both facing the eye: a shading discontinuity (flat normals).
    FrontCrease,
    /// Two faces both facing away: hidden behind the mesh when the eye is outside a closed
    /// mesh, but seen from inside one (a room) or from behind an open one.
    BackCrease,
    /// A face contains the eye: measure zero, skipped.
    EdgeOn,
}

fn face_side(geo: &Geometry, f: u32, eye: DVec3) -> f64 {
    let [a, b, c] = geo.indices[f as usize].map(|i| geo.positions[i as usize].as_dvec3());
    (b - a).cross(c - a).dot(eye - a)
}

/// Classifies `e` as seen from `eye` (face orientation by winding, front = counter-clockwise).
pub fn classify(geo: &Geometry, e: &Edge, eye: DVec3) -> EdgeView {
    let s0 = face_side(geo, e.face0, eye);
    let Some(f1) = e.face1 else {
        return if s0 == 0.0 {
            EdgeView::EdgeOn
        } else {
            EdgeView::Boundary
        };
    };
    let s1 = face_side(geo, f1, eye);
    if s0 == 0.0 || s1 == 0.0 {
        EdgeView::EdgeOn
    } else if (s0 > 0.0) != (s1 > 0.0) {
        EdgeView::Silhouette
    } else if s0 > 0.0 {
        EdgeView::FrontCrease
    } else {
        EdgeView::BackCrease
    }
}

/// An edge clipped to the near plane and projected to the film: `x0, x1` are the clipped
/// world end points, `p0, p1` their film points, and `[s_lo, s_hi]` the part of `p0 → p1`
/// inside the (widened) film.
#[derive(Clone, Copy, Debug)]
pub struct ProjectedEdge {
    /// Index into the edge list.
    pub edge: usize,
    /// The shape the edge belongs to.
    pub shape: u32,
    pub x0: DVec3,
    pub x1: DVec3,
    z0: f64,
    z1: f64,
    pub p0: DVec2,
    pub p1: DVec2,
    pub s_lo: f64,
    pub s_hi: f64,
    /// Projected length inside the film, pixels.
    pub length: f64,
}

impl ProjectedEdge {
    /// Film point and world point at film parameter `s` (1/z is affine in s).
    pub fn point(&self, s: f64) -> (DVec2, DVec3) {
        let film = self.p0 + (self.p1 - self.p0) * s;
        let t = s * self.z0 / ((1.0 - s) * self.z1 + s * self.z0);
        (film, self.x0 + (self.x1 - self.x0) * t)
    }

    /// Unit normal of the projected edge on the film (one of the two; the boundary term does
    /// not depend on which).
    pub fn normal(&self) -> DVec2 {
        let d = (self.p1 - self.p0).normalize_or_zero();
        DVec2::new(-d.y, d.x)
    }
}

/// Clips segment a→b (parameter s ∈ [0, 1]) to the rectangle [lo, hi] (Liang–Barsky).
fn clip_to_rect(a: DVec2, b: DVec2, lo: DVec2, hi: DVec2) -> Option<(f64, f64)> {
    let d = b - a;
    let (mut s0, mut s1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-d.x, a.x - lo.x),
        (d.x, hi.x - a.x),
        (-d.y, a.y - lo.y),
        (d.y, hi.y - a.y),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                s0 = s0.max(r);
            } else {
                s1 = s1.min(r);
            }
        }
    }
    (s0 < s1).then_some((s0, s1))
}

/// Projects one edge (end points `a`, `b`), or None when it is behind the eye or off the film.
pub fn project_edge(pin: &Pinhole, a: DVec3, b: DVec3, margin: f64) -> Option<(DVec3, DVec3, f64, f64, f64)> {
    let (za, zb) = (pin.depth(a), pin.depth(b));
    if za < Z_NEAR && zb < Z_NEAR {
        return None;
    }
    let cut = |p: DVec3, zp: f64, q: DVec3, zq: f64| p + (q - p) * ((Z_NEAR - zp) / (zq - zp));
    let (x0, x1) = match (za < Z_NEAR, zb < Z_NEAR) {
        (true, _) => (cut(a, za, b, zb), b),
        (_, true) => (a, cut(b, zb, a, za)),
        _ => (a, b),
    };
    let (p0, p1) = (pin.film(x0), pin.film(x1));
    let lo = DVec2::splat(-margin);
    let hi = DVec2::new(pin.width + margin, pin.height + margin);
    let (s_lo, s_hi) = clip_to_rect(p0, p1, lo, hi)?;
    let length = (s_hi - s_lo) * (p1 - p0).length();
    (length > 0.0 && length.is_finite()).then_some((x0, x1, s_lo, s_hi, length))
}

/// One sampled film point on a discontinuity edge.
#[derive(Clone, Copy, Debug)]
pub struct EdgeSample {
    /// Index into [`SilhouetteSet::edges`].
    pub index: usize,
    pub film: DVec2,
    pub world: DVec3,
    pub normal: DVec2,
    /// Density per unit of projected length (pixels⁻¹): 1 / total length.
    pub pdf: f64,
}

/// The candidate discontinuity edges of one view, with a CDF over their projected lengths.
#[derive(Clone, Debug, Default)]
pub struct SilhouetteSet {
    pub edges: Vec<ProjectedEdge>,
    cdf: Vec<f64>,
    pub total_length: f64,
}

impl SilhouetteSet {
    /// Projects the edges of shapes for which `wanted(shape)` holds and that can be
    /// discontinuities from the pinhole's eye: every edge but the edge-on ones. Back creases
    /// are kept: whether one is hidden depends on the eye being outside a closed mesh, which
    /// the estimator's visibility ray decides per sample. `margin` widens the film (the filter
    /// radius, in pixels).
    pub fn build(geo: &Geometry, edges: &[Edge], pin: &Pinhole, margin: f64, wanted: impl Fn(u32) -> bool) -> Self {
        let shape_of = |e: &Edge| geo.tri_shape[e.face0 as usize];
        let mut set = Self::default();
        for (i, e) in edges.iter().enumerate() {
            let shape = shape_of(e);
            if !wanted(shape) {
                continue;
            }
            if classify(geo, e, pin.eye) == EdgeView::EdgeOn {
                continue;
            }
            let (a, b) = (
                geo.positions[e.v0 as usize].as_dvec3(),
                geo.positions[e.v1 as usize].as_dvec3(),
            );
            let Some((x0, x1, s_lo, s_hi, length)) = project_edge(pin, a, b, margin) else {
                continue;
            };
            set.total_length += length;
            set.cdf.push(set.total_length);
            set.edges.push(ProjectedEdge {
                edge: i,
                shape,
                x0,
                x1,
                z0: pin.depth(x0),
                z1: pin.depth(x1),
                p0: pin.film(x0),
                p1: pin.film(x1),
                s_lo,
                s_hi,
                length,
            });
        }
        set
    }

    pub fn is_empty(&self) -> bool {
        self.edges.is_empty()
    }

    /// Picks an edge with probability ∝ projected length (`u_edge`) and a point uniformly
    /// along its visible part (`u_pos`): density 1 / total length per pixel of length.
    pub fn sample(&self, u_edge: f64, u_pos: f64) -> Option<EdgeSample> {
        let index = self.pick(u_edge)?;
        Some(self.at(index, u_pos))
    }

    /// The point at fraction `u` of the concatenated projected length of all edges: the same
    /// density as [`Self::sample`] from one number, so that N samples at u = (i + ξ_i) / N
    /// stratify the whole length (a jittered 1-D sampling of the edges).
    pub fn sample_at(&self, u: f64) -> Option<EdgeSample> {
        let index = self.pick(u)?;
        let e = &self.edges[index];
        let start = self.cdf[index] - e.length;
        let u_pos = ((u * self.total_length - start) / e.length).clamp(0.0, 1.0);
        Some(self.at(index, u_pos))
    }

    fn pick(&self, u: f64) -> Option<usize> {
        if self.edges.is_empty() || self.total_length.is_nan() || self.total_length <= 0.0 {
            return None;
        }
        let target = u * self.total_length;
        Some(self.cdf.partition_point(|&c| c <= target).min(self.edges.len() - 1))
    }

    fn at(&self, index: usize, u_pos: f64) -> EdgeSample {
        let e = &self.edges[index];
        let (film, world) = e.point(e.s_lo + (e.s_hi - e.s_lo) * u_pos);
        EdgeSample {
            index,
            film,
            world,
            normal: e.normal(),
            pdf: 1.0 / self.total_length,
        }
    }
}
