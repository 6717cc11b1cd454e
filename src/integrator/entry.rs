//! Camera rays that would enter a closed shape through one of its edges.
//!
//! A camera ray that passes within rounding error of a closed shape's silhouette edge meets
//! the face turned towards the camera and the face turned away at the same distance, and the
//! watertight traversal may report either. Reported on the face turned away, the ray has
//! reached the shape's inside, which no light from the camera's side can reach. The path
//! then lives in the crack along the edge: its next segment is as short as the rounding
//! (micrometres), and light that leaks back out through the crack brings it a derivative
//! weight as large as the segment is short. The first vertex is in ray form (it slides along
//! its face as the shape moves, `super::path`), the second vertex on the other face moves
//! with the shape, so the geometry term's derivative (supplemental Eq. 14, the G·J factor)
//! is their relative speed over a distance of micrometres.
//!
//! Seen in the wild: `narrow_pulse_box` at 512 spp, one sample of one seed in 768 put
//! +1.8 × 10⁶ into one voxel of `d/d tall_box_x` (a typical voxel of the whole image is
//! below 0.3), through a camera ray that met the tall box's right (back-facing) face at its
//! edge with the front face and a 13 µm segment inside the box. As the rounding shrinks,
//! such paths get rarer in proportion and heavier in inverse proportion, so they are a bias
//! of the derivative, not only a heavy tail.
//!
//! The camera's side of each closed shape is fixed for a render (outside, or inside a shape
//! that encloses it, a room built as one closed mesh), so a first hit on the other side is
//! one of these cracks: such a camera ray starts no path. Shapes that are not closed and
//! consistently wound (an open rectangle, a mesh with duplicated vertices along its seams or
//! a hole), and shapes the camera sits on, are not checked.

use crate::kernel::{Mask, Real, V3};
use crate::scene::Geometry;
use glam::{DVec3, Vec3};

/// Which side of its triangle a camera ray's first hit may lie on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Side {
    /// Not a closed shape, or the camera is on it: any hit.
    Any,
    /// The side the winding's normal points to (the ray arrives against the normal).
    Front,
    /// The other side.
    Back,
}

/// For each triangle, the side of it a camera ray may first hit (see the module's doc).
#[derive(Clone, Debug, Default)]
pub struct EntrySides {
    /// Per triangle; empty when no shape is checked.
    sides: Vec<Side>,
}

impl EntrySides {
    /// The sides for the camera at `eye` (in the frame of `geo`'s positions).
    pub fn new(geo: &Geometry, shape_count: usize, eye: Vec3) -> Self {
        let closed = closed_shapes(geo, shape_count);
        if !closed.iter().any(|&c| c) {
            return Self::default();
        }
        let eye = eye.as_dvec3();
        let side: Vec<Side> = (0..shape_count)
            .map(|s| match closed[s] {
                true => camera_side(geo, s as u32, eye),
                false => Side::Any,
            })
            .collect();
        let sides = geo.tri_shape.iter().map(|&s| side[s as usize]).collect();
        Self { sides }
    }

    /// The lanes of `active` whose first hit (`prim`, reached along `d`, with the triangles'
    /// vertices `tri_verts`) lies on the side of its shape the camera is on.
    pub fn admits<R: Real>(
        &self,
        tri_verts: &[[Vec3; 3]],
        prim: &[u32; 8],
        d: &V3<R::Value>,
        active: R::Mask,
    ) -> R::Mask {
        if self.sides.is_empty() {
            return active;
        }
        let keep: [bool; 8] = std::array::from_fn(|i| {
            if i >= R::LANES || !active.bit(i) {
                return false;
            }
            let side = self.sides[prim[i] as usize];
            if side == Side::Any {
                return true;
            }
            // the sign of the winding's normal along the ray (no need to normalise it)
            let [a, b, c] = tri_verts[prim[i] as usize];
            let against = (b - a)
                .cross(c - a)
                .dot(Vec3::new(d.x.lane(i), d.y.lane(i), d.z.lane(i)))
                < 0.0;
            against == (side == Side::Front)
        });
        active & R::Mask::from_bools(&keep[..R::LANES])
    }
}

/// For each shape, whether its triangles close a surface with one orientation: every edge
/// (by vertex index) is shared by exactly two of the shape's triangles, which run along it
/// in opposite directions.
pub fn closed_shapes(geo: &Geometry, shape_count: usize) -> Vec<bool> {
    // (shape, lower index, higher index, runs from lower to higher)
    let mut edges: Vec<(u32, u32, u32, bool)> = Vec::with_capacity(geo.indices.len() * 3);
    for (t, &s) in geo.indices.iter().zip(&geo.tri_shape) {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            edges.push((s, a.min(b), a.max(b), a < b));
        }
    }
    edges.sort_unstable();
    let mut has_triangles = vec![false; shape_count];
    let mut open = vec![false; shape_count];
    for group in edges.chunk_by(|x, y| (x.0, x.1, x.2) == (y.0, y.1, y.2)) {
        has_triangles[group[0].0 as usize] = true;
        if group.len() != 2 || group[0].3 == group[1].3 {
            open[group[0].0 as usize] = true;
        }
    }
    (0..shape_count).map(|s| has_triangles[s] && !open[s]).collect()
}

/// The camera's side of the closed shape `shape`: which side of its triangles a ray from
/// `eye` meets first.
fn camera_side(geo: &Geometry, shape: u32, eye: DVec3) -> Side {
    let tris = || {
        geo.indices
            .iter()
            .zip(&geo.tri_shape)
            .filter(move |(_, s)| **s == shape)
            .map(|(t, _)| t.map(|i| geo.positions[i as usize].as_dvec3()))
    };
    // the enclosed volume's sign: positive when the normals point out of it
    let volume: f64 = tris().map(|[a, b, c]| a.dot(b.cross(c))).sum::<f64>() / 6.0;
    if volume == 0.0 || !volume.is_finite() {
        return Side::Any;
    }
    let (lo, hi) = tris()
        .flatten()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        });
    let inside_box = eye.cmpge(lo).all() && eye.cmple(hi).all();
    let winding = match inside_box {
        true => winding_number(tris(), eye),
        false => Some(0.0),
    };
    let Some(winding) = winding else {
        return Side::Any;
    };
    let turns = winding.round();
    if (winding - turns).abs() > 0.25 || turns.abs() > 1.0 {
        // on the surface, or inside a shape that winds around itself
        return Side::Any;
    }
    let inside = turns != 0.0;
    match (volume > 0.0) != inside {
        true => Side::Front,
        false => Side::Back,
    }
}

/// How many times the triangles wind around `p`: their solid angles seen from `p` (Van
/// Oosterom and Strackee, IEEE Trans. Biomed. Eng. 30(2), 1983), summed, over 4π. `None`
/// when `p` lies on one of them (within rounding), where the count jumps.
fn winding_number(tris: impl Iterator<Item = [DVec3; 3]>, p: DVec3) -> Option<f64> {
    let mut total = 0.0;
    for t in tris {
        let [a, b, c] = t.map(|v| v - p);
        let (la, lb, lc) = (a.length(), b.length(), c.length());
        let num = a.dot(b.cross(c));
        let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
        if num.abs() <= 1e-12 * la * lb * lc && den <= 0.0 {
            return None;
        }
        total += 2.0 * num.atan2(den);
    }
    Some(total / (4.0 * std::f64::consts::PI))
}

#[cfg(test)]
#[path = "entry_tests.rs"]
pub(crate) mod tests;
