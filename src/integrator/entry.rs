//! Rays in ray form that would enter a closed shape through one of its edges.
//!
//! A camera ray that passes within rounding error of a closed shape's silhouette edge meets
//! the face turned towards the camera and the face turned away at the same distance, and the
//! watertight traversal may report either. Reported on the face turned away, the ray has
//! reached the shape's inside, which no light from the camera's side can reach. The path
//! then lives in the crack along the edge: its next segment is as short as the rounding
//! (micrometres), and light that leaks back out through the crack brings it a derivative
//! weight as large as the segment is short. The first vertex is in ray form (it slides along
//! its face as the shape moves, `super::path`), the second vertex on the other face moves
//! with the shape, so the derivative of the geometry term (the G·J of α = ρ·G·J in
//! Algorithm 1 of the supplemental) is their relative speed over a distance of micrometres.
//! The same holds for the ray a Dirac lobe turned (a mirror, smooth glass): the vertex it
//! reaches is in ray form too (`super::bsdf::delta`).
//!
//! Seen in the wild: `narrow_pulse_box` at 512 spp, one sample of one seed in 768 carried
//! ḟ = 1.8 × 10⁶, which put +2 695 into one voxel of `d/d tall_box_x` (a typical voxel of the
//! whole image is below 0.3), through a camera ray that met the tall box's right (back-facing) face at its
//! edge with the front face and a 13 µm segment inside the box. As the rounding shrinks,
//! such paths get rarer in proportion and heavier in inverse proportion, so they are a bias
//! of the derivative, not only a heavy tail.
//!
//! The camera's side of each closed shape is fixed for a render (outside, or inside a shape
//! that encloses it, a room built as one closed mesh), so a camera ray's first hit on the
//! other side is one of these cracks: such a camera ray starts no path. A path stays on the
//! camera's side of every closed shape except those it has crossed by transmission
//! ([`Crossings`]), so a turned ray's hit on the other side ends its path in the same way.
//! Not checked: shapes that are not closed and consistently wound (an open rectangle, a mesh
//! with a hole, a box made of several shapes), shapes the camera sits on, the rays of paths
//! that crossed more than [`Crossings::MAX`] shapes, and paths that start on a surface or on
//! a relay wall (their side of each shape is not known). Rays whose next vertex moves with
//! its surface (after a rough or diffuse vertex) carry no such weight and are not checked
//! either: their leaks are as rare as the rounding, and bounded.

use crate::kernel::{Mask, Real, V3};
use crate::scene::Geometry;
use glam::{DVec3, Vec3};

/// Which side of its triangle the camera is on, so a camera ray's first hit may lie on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Side {
    /// Not a closed shape, or the camera is on it: any hit.
    Any,
    /// The side the winding's normal points to (the ray arrives against the normal).
    Front,
    /// The other side.
    Back,
}

/// For each triangle, the side of it the camera is on (see the module's doc).
#[derive(Clone, Debug, Default)]
pub struct EntrySides {
    /// Per triangle; empty when no shape is checked.
    sides: Vec<Side>,
}

impl EntrySides {
    /// The sides for the camera at `eye` (in the frame of `geo`'s positions). Two passes over
    /// the triangles, the second only over shapes whose bounding box holds the camera.
    pub fn new(geo: &Geometry, shape_count: usize, eye: Vec3) -> Self {
        let shapes = ShapeSums::new(geo, shape_count);
        if !shapes.closed.iter().any(|&c| c) {
            return Self::default();
        }
        let eye = eye.as_dvec3();
        let around: Vec<bool> = (0..shape_count)
            .map(|s| shapes.closed[s] && eye.cmpge(shapes.lo[s]).all() && eye.cmple(shapes.hi[s]).all())
            .collect();
        let winding = winding_numbers(geo, &around, eye);
        let side: Vec<Side> = (0..shape_count)
            .map(|s| match shapes.closed[s] {
                true => camera_side(shapes.volume[s], winding[s]),
                false => Side::Any,
            })
            .collect();
        let sides = geo.tri_shape.iter().map(|&s| side[s as usize]).collect();
        Self { sides }
    }

    /// The lanes of `active` whose hit (`prim`, reached along `d`, with the triangles'
    /// vertices `tri_verts` and shapes `tri_shape`) lies on the side of its shape the
    /// lane's path is on: the camera's, or the other for the shapes it crossed (`crossed`).
    pub fn admits<R: Real>(
        &self,
        (tri_verts, tri_shape): (&[[Vec3; 3]], &[u32]),
        prim: &[u32; 8],
        d: &V3<R::Value>,
        crossed: &[Crossings; 8],
        active: R::Mask,
    ) -> R::Mask {
        if self.sides.is_empty() {
            return active;
        }
        let keep: [bool; 8] = std::array::from_fn(|i| {
            if i >= R::LANES || !active.bit(i) {
                return false;
            }
            let t = prim[i] as usize;
            let front = match (self.sides[t], crossed[i].holds(tri_shape[t])) {
                (Side::Any, _) | (_, None) => return true,
                (side, Some(c)) => (side == Side::Front) != c,
            };
            // the sign of the winding's normal along the ray (no need to normalise it)
            let [a, b, c] = tri_verts[t];
            let against = (b - a)
                .cross(c - a)
                .dot(Vec3::new(d.x.lane(i), d.y.lane(i), d.z.lane(i)))
                < 0.0;
            against == front
        });
        active & R::Mask::from_bools(&keep[..R::LANES])
    }

    /// Records in `crossed` that the lanes of `through` passed through the surface of their
    /// vertex's shape (triangle `prim`), where that shape is checked.
    pub fn cross<R: Real>(&self, tri_shape: &[u32], prim: &[u32; 8], through: R::Mask, crossed: &mut [Crossings; 8]) {
        if self.sides.is_empty() || through.none() {
            return;
        }
        for (i, c) in crossed.iter_mut().enumerate().take(R::LANES) {
            let t = prim[i] as usize;
            if through.bit(i) && self.sides[t] != Side::Any {
                c.toggle(tri_shape[t]);
            }
        }
    }
}

/// The closed shapes one path has crossed an odd number of times (by transmission, since the
/// camera): it is on the camera's side of every other one. Up to [`Crossings::MAX`] at once
/// (glass in glass in glass); past that the path is no longer checked.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Crossings {
    shapes: [u32; Crossings::MAX],
    /// How many of `shapes` are held; `u8::MAX` once more were.
    len: u8,
}

impl Crossings {
    pub const MAX: usize = 4;

    /// Whether the path has crossed `shape`; `None` when that is no longer known.
    fn holds(&self, shape: u32) -> Option<bool> {
        let n = self.len as usize;
        (n <= Self::MAX).then(|| self.shapes[..n].contains(&shape))
    }

    /// One more crossing of `shape`'s surface.
    fn toggle(&mut self, shape: u32) {
        let n = self.len as usize;
        if n > Self::MAX {
            return;
        }
        match self.shapes[..n].iter().position(|&s| s == shape) {
            Some(k) => {
                self.shapes[k] = self.shapes[n - 1];
                self.len -= 1;
            }
            None if n < Self::MAX => {
                self.shapes[n] = shape;
                self.len += 1;
            }
            None => self.len = u8::MAX,
        }
    }
}

/// What one pass over the triangles gathers per shape.
struct ShapeSums {
    /// Whether the shape's triangles close a surface: along every edge (between vertex
    /// positions, so a mesh whose vertices are repeated along seams, as an OBJ file's with a
    /// normal per face, counts) as many of them run one way as the other, so the edges' sum
    /// is empty and the winding number is a whole number off the surface. Tested with a sum
    /// of 64-bit hashes of the directed edges against that of the reversed ones (equal by
    /// chance with probability about 2⁻⁶⁴), in one pass, where sorting the edges of a
    /// million triangles took 60 ms per render.
    closed: Vec<bool>,
    /// Six times the enclosed volume, positive when the normals point out of it.
    volume: Vec<f64>,
    lo: Vec<DVec3>,
    hi: Vec<DVec3>,
}

impl ShapeSums {
    fn new(geo: &Geometry, shape_count: usize) -> Self {
        let mut edges = vec![0u64; shape_count];
        let mut has = vec![false; shape_count];
        let mut volume = vec![0.0f64; shape_count];
        let mut lo = vec![DVec3::INFINITY; shape_count];
        let mut hi = vec![DVec3::NEG_INFINITY; shape_count];
        // each shape's volume about a point of its own, for precision
        let mut origin = vec![None; shape_count];
        let keys: Vec<u64> = geo.positions.iter().map(|&p| position_key(p)).collect();
        for (t, &s) in geo.indices.iter().zip(&geo.tri_shape) {
            let s = s as usize;
            has[s] = true;
            let k = t.map(|i| keys[i as usize]);
            for j in 0..3 {
                let (a, b) = (k[j], k[(j + 1) % 3]);
                edges[s] = edges[s].wrapping_add(edge_hash(a, b)).wrapping_sub(edge_hash(b, a));
            }
            let p = t.map(|i| geo.positions[i as usize].as_dvec3());
            let o = *origin[s].get_or_insert(p[0]);
            let [a, b, c] = p.map(|q| q - o);
            volume[s] += a.dot(b.cross(c));
            for q in p {
                lo[s] = lo[s].min(q);
                hi[s] = hi[s].max(q);
            }
        }
        let closed = (0..shape_count).map(|s| has[s] && edges[s] == 0).collect();
        Self { closed, volume, lo, hi }
    }
}

/// A 64-bit key of a vertex position (its coordinates' bits, mixed): equal positions have
/// equal keys, whatever their index (−0 and +0 are one position).
fn position_key(p: Vec3) -> u64 {
    let [x, y, z] = (p + Vec3::ZERO).to_array().map(|c| c.to_bits() as u64);
    mix(mix(x << 32 | y) ^ z)
}

/// A 64-bit hash of the directed edge between the positions of keys `a` → `b`.
fn edge_hash(a: u64, b: u64) -> u64 {
    mix(a ^ b.rotate_left(29))
}

/// SplitMix64's step and finaliser.
fn mix(z: u64) -> u64 {
    let mut z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The camera's side of a closed shape of signed volume `volume` that winds `winding` times
/// around it (`None`: the camera is on its surface): which side of its triangles a ray from
/// the camera meets first.
fn camera_side(volume: f64, winding: Option<f64>) -> Side {
    let Some(winding) = winding.filter(|_| volume != 0.0 && volume.is_finite()) else {
        return Side::Any;
    };
    let turns = winding.round();
    if (winding - turns).abs() > 0.25 || turns.abs() > 1.0 {
        // inside a shape that winds around itself
        return Side::Any;
    }
    let inside = turns != 0.0;
    match (volume > 0.0) != inside {
        true => Side::Front,
        false => Side::Back,
    }
}

/// How many times each shape of `which` winds around `p` (0 for the others): the solid angles
/// of its triangles seen from `p` (Van Oosterom and Strackee, IEEE Trans. Biomed. Eng. 30(2),
/// 1983), summed, over 4π. `None` where `p` lies on one of them (within rounding), where the
/// count jumps.
fn winding_numbers(geo: &Geometry, which: &[bool], p: DVec3) -> Vec<Option<f64>> {
    let mut total = vec![Some(0.0); which.len()];
    if !which.iter().any(|&w| w) {
        return total;
    }
    for (t, &s) in geo.indices.iter().zip(&geo.tri_shape) {
        let s = s as usize;
        if !which[s] {
            continue;
        }
        let [a, b, c] = t.map(|i| geo.positions[i as usize].as_dvec3() - p);
        let (la, lb, lc) = (a.length(), b.length(), c.length());
        let num = a.dot(b.cross(c));
        let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
        total[s] = match num.abs() <= 1e-12 * la * lb * lc && den <= 0.0 {
            true => None,
            false => total[s].map(|w| w + 2.0 * num.atan2(den)),
        };
    }
    total
        .into_iter()
        .map(|w| w.map(|w| w / (4.0 * std::f64::consts::PI)))
        .collect()
}

#[cfg(test)]
#[path = "entry_tests.rs"]
pub(crate) mod tests;
