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
//! What is checked are closed bodies (`Bodies`): a shape that closes a surface on its own,
//! or open shapes that close one together along the edges they share (a box built of six
//! rectangles). The camera's side of each closed body is fixed for a render (outside, or
//! inside one that encloses it, a room built as one closed mesh), so a camera ray's first
//! hit on the other side is one of these cracks: such a camera ray starts no path. A path
//! stays on the camera's side of every closed body except those it has crossed by
//! transmission ([`Crossings`]), so a turned ray's hit on the other side ends its path in the
//! same way. Not checked: surfaces that are not closed and consistently wound (an open
//! rectangle, a mesh with a hole), open shapes of more than `JOIN_MAX_TRIANGLES` (16 384)
//! triangles (not joined with others; none are joined past 65 536 in all), bodies the
//! camera sits on, the rays of paths that crossed more than [`Crossings::MAX`] bodies, and
//! paths that start on a surface or on a relay wall (their side of each body is not known).
//! Rays whose next vertex moves with its surface (after a rough or diffuse vertex) carry no
//! such weight and are not checked either: their leaks are as rare as the rounding, and
//! bounded.

use crate::kernel::{Mask, Real, V3};
use crate::scene::Geometry;
use glam::{DVec3, Vec3};

/// Which side of its triangle the camera is on, so a camera ray's first hit may lie on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Side {
    /// Not a closed body, or the camera is on it: any hit.
    Any,
    /// The side the winding's normal points to (the ray arrives against the normal).
    Front,
    /// The other side.
    Back,
}

/// For each triangle, the side of it the camera is on (see the module's doc).
#[derive(Clone, Debug, Default)]
pub struct EntrySides {
    /// Per triangle; empty when no body is checked.
    sides: Vec<Side>,
    /// Per shape, its body ([`Bodies`]): the closed surface [`Crossings`] records.
    body: Vec<u32>,
}

impl EntrySides {
    /// The sides for the camera at `eye` (in the frame of `geo`'s positions). Two passes over
    /// the triangles (the second only over bodies whose bounding box holds the camera), and
    /// one over the edges of the open shapes small enough to join ([`Bodies::new`]).
    pub fn new(geo: &Geometry, shape_count: usize, eye: Vec3) -> Self {
        let bodies = Bodies::new(geo, shape_count);
        if !bodies.closed.iter().any(|&c| c) {
            return Self::default();
        }
        let eye = eye.as_dvec3();
        let around: Vec<bool> = (0..bodies.closed.len())
            .map(|b| bodies.closed[b] && eye.cmpge(bodies.lo[b]).all() && eye.cmple(bodies.hi[b]).all())
            .collect();
        let winding = winding_numbers(geo, &bodies.of_shape, &around, eye);
        let side: Vec<Side> = (0..bodies.closed.len())
            .map(|b| match bodies.closed[b] {
                true => camera_side(bodies.volume[b], winding[b]),
                false => Side::Any,
            })
            .collect();
        let sides = geo
            .tri_shape
            .iter()
            .map(|&s| side[bodies.of_shape[s as usize] as usize])
            .collect();
        Self {
            sides,
            body: bodies.of_shape,
        }
    }

    /// The lanes of `active` whose hit (`prim`, reached along `d`, with the triangles'
    /// vertices `tri_verts` and shapes `tri_shape`) lies on the side of its body the lane's
    /// path is on: the camera's, or the other for the bodies it crossed (`crossed`).
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
            let front = match (self.sides[t], crossed[i].holds(self.body[tri_shape[t] as usize])) {
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
    /// vertex's body (triangle `prim`), where that body is checked.
    pub fn cross<R: Real>(&self, tri_shape: &[u32], prim: &[u32; 8], through: R::Mask, crossed: &mut [Crossings; 8]) {
        if self.sides.is_empty() || through.none() {
            return;
        }
        for (i, c) in crossed.iter_mut().enumerate().take(R::LANES) {
            let t = prim[i] as usize;
            if through.bit(i) && self.sides[t] != Side::Any {
                c.toggle(self.body[tri_shape[t] as usize]);
            }
        }
    }
}

/// The closed bodies one path has crossed an odd number of times (by transmission, since the
/// camera): it is on the camera's side of every other one. Up to [`Crossings::MAX`] at once
/// (glass in glass in glass); past that the path is no longer checked.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Crossings {
    bodies: [u32; Crossings::MAX],
    /// How many of `bodies` are held; `u8::MAX` once more were.
    len: u8,
}

impl Crossings {
    pub const MAX: usize = 4;

    /// Whether the path has crossed `body`; `None` when that is no longer known.
    fn holds(&self, body: u32) -> Option<bool> {
        let n = self.len as usize;
        (n <= Self::MAX).then(|| self.bodies[..n].contains(&body))
    }

    /// One more crossing of `body`'s surface.
    fn toggle(&mut self, body: u32) {
        let n = self.len as usize;
        if n > Self::MAX {
            return;
        }
        match self.bodies[..n].iter().position(|&s| s == body) {
            Some(k) => {
                self.bodies[k] = self.bodies[n - 1];
                self.len -= 1;
            }
            None if n < Self::MAX => {
                self.bodies[n] = body;
                self.len += 1;
            }
            None => self.len = u8::MAX,
        }
    }
}

/// Open shapes of more triangles than this are not joined with others into a body: joining
/// sorts every edge of the shapes it considers.
const JOIN_MAX_TRIANGLES: usize = 1 << 14;

/// No open shapes are joined when those small enough hold more triangles than this together
/// (a bound on the sort: 257 346 triangles in 17 open meshes took 45 ms per render).
const JOIN_MAX_TOTAL: usize = 1 << 16;

/// The closed surfaces of a scene, its bodies: each shape that closes a surface on its own,
/// and each set of open shapes that close one together along edges they share (a box built
/// of six rectangles, a mesh exported in pieces). Every other shape is a body of its own, open.
struct Bodies {
    /// Per shape, its body.
    of_shape: Vec<u32>,
    /// Per body: whether its triangles close a surface. Along every edge (between vertex
    /// positions, so a mesh whose vertices are repeated along seams, as an OBJ file's with a
    /// normal per face, counts) as many of them run one way as the other, so the edges' sum
    /// is empty and the winding number is a whole number off the surface. Tested with a sum
    /// of 64-bit hashes of the directed edges against that of the reversed ones (equal by
    /// chance with probability about 2⁻⁶⁴), in one pass, where sorting the edges of a
    /// million triangles took 60 ms per render.
    closed: Vec<bool>,
    /// Per body: six times the enclosed volume, positive when the normals point out of it.
    volume: Vec<f64>,
    lo: Vec<DVec3>,
    hi: Vec<DVec3>,
}

impl Bodies {
    fn new(geo: &Geometry, shape_count: usize) -> Self {
        let keys: Vec<u64> = geo.positions.iter().map(|&p| position_key(p)).collect();
        let corners = |t: &[u32; 3]| t.map(|i| keys[i as usize]);
        let mut edges = vec![0u64; shape_count];
        let mut size = vec![0usize; shape_count];
        for (t, &s) in geo.indices.iter().zip(&geo.tri_shape) {
            let k = corners(t);
            let s = s as usize;
            size[s] += 1;
            for j in 0..3 {
                let (a, b) = (k[j], k[(j + 1) % 3]);
                edges[s] = edges[s].wrapping_add(edge_hash(a, b)).wrapping_sub(edge_hash(b, a));
            }
        }
        // open shapes that share an edge (by position) are one body
        let joinable: Vec<bool> = (0..shape_count)
            .map(|s| size[s] > 0 && edges[s] != 0 && size[s] <= JOIN_MAX_TRIANGLES)
            .collect();
        let mut parent: Vec<u32> = (0..shape_count as u32).collect();
        let total: usize = (0..shape_count).filter(|&s| joinable[s]).map(|s| size[s]).sum();
        if joinable.iter().filter(|&&j| j).count() > 1 && total <= JOIN_MAX_TOTAL {
            // each edge of each joinable shape, either way round, with its shape
            let mut undirected: Vec<(u64, u32)> = Vec::new();
            for (t, &s) in geo.indices.iter().zip(&geo.tri_shape) {
                if joinable[s as usize] {
                    let k = corners(t);
                    for j in 0..3 {
                        let (a, b) = (k[j], k[(j + 1) % 3]);
                        undirected.push((edge_hash(a.min(b), a.max(b)), s));
                    }
                }
            }
            undirected.sort_unstable();
            for w in undirected.windows(2) {
                if w[0].0 == w[1].0 && w[0].1 != w[1].1 {
                    let (a, b) = (root(&mut parent, w[0].1), root(&mut parent, w[1].1));
                    parent[a.max(b) as usize] = a.min(b);
                }
            }
        }
        // bodies numbered in the order of their first shape
        let mut number = vec![u32::MAX; shape_count];
        let mut of_shape = vec![0u32; shape_count];
        let mut count = 0;
        for s in 0..shape_count {
            let r = root(&mut parent, s as u32) as usize;
            if number[r] == u32::MAX {
                number[r] = count;
                count += 1;
            }
            of_shape[s] = number[r];
        }
        let n = count as usize;
        let mut sum = vec![0u64; n];
        let mut has = vec![false; n];
        for s in 0..shape_count {
            let b = of_shape[s] as usize;
            sum[b] = sum[b].wrapping_add(edges[s]);
            has[b] |= size[s] > 0;
        }
        let mut volume = vec![0.0f64; n];
        let mut lo = vec![DVec3::INFINITY; n];
        let mut hi = vec![DVec3::NEG_INFINITY; n];
        // each body's volume about a point of its own, for precision
        let mut origin = vec![None; n];
        for (t, &s) in geo.indices.iter().zip(&geo.tri_shape) {
            let b = of_shape[s as usize] as usize;
            let p = t.map(|i| geo.positions[i as usize].as_dvec3());
            let o = *origin[b].get_or_insert(p[0]);
            let [a, q, c] = p.map(|q| q - o);
            volume[b] += a.dot(q.cross(c));
            for q in p {
                lo[b] = lo[b].min(q);
                hi[b] = hi[b].max(q);
            }
        }
        let closed = (0..n).map(|b| has[b] && sum[b] == 0).collect();
        Self {
            of_shape,
            closed,
            volume,
            lo,
            hi,
        }
    }
}

/// The root of `x`'s set in the union–find forest `parent`, halving the path on the way.
fn root(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let up = parent[parent[x as usize] as usize];
        parent[x as usize] = up;
        x = up;
    }
    x
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

/// The camera's side of a closed body of signed volume `volume` that winds `winding` times
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

/// How many times each body of `which` winds around `p` (0 for the others; `body` gives each
/// shape's): the solid angles of its triangles seen from `p` (Van Oosterom and Strackee, IEEE
/// Trans. Biomed. Eng. 30(2), 1983), summed, over 4π. `None` where `p` lies on one of them
/// (within rounding), where the count jumps.
fn winding_numbers(geo: &Geometry, body: &[u32], which: &[bool], p: DVec3) -> Vec<Option<f64>> {
    let mut total = vec![Some(0.0); which.len()];
    if !which.iter().any(|&w| w) {
        return total;
    }
    for (t, &s) in geo.indices.iter().zip(&geo.tri_shape) {
        let b = body[s as usize] as usize;
        if !which[b] {
            continue;
        }
        let [a, q, c] = t.map(|i| geo.positions[i as usize].as_dvec3() - p);
        let (la, lq, lc) = (a.length(), q.length(), c.length());
        let num = a.dot(q.cross(c));
        let den = la * lq * lc + a.dot(q) * lc + q.dot(c) * la + c.dot(a) * lq;
        total[b] = match num.abs() <= 1e-12 * la * lq * lc && den <= 0.0 {
            true => None,
            false => total[b].map(|w| w + 2.0 * num.atan2(den)),
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
