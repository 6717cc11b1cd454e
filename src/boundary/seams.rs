//! Seams: places where a surface is one piece but its triangles do not share vertex indices,
//! so that an edge of the surface would otherwise be listed once per side as two open
//! (boundary) edges, each treated as a silhouette, and its boundary term counted twice.
//!
//! - **Unwelded vertices.** A mesh given as separate triangles (an STL-style triangle soup),
//!   an OBJ whose faces carry their own normals or texture coordinates (the reader gives each
//!   combination its own vertex), or an OBJ split into groups that share positions. Vertices
//!   of one shape at bit-identical positions are one vertex here ([`weld`]).
//! - **T-junctions.** A vertex of one face lying on the edge of another (a quad split on one
//!   side only). Open edges of one shape that lie on one line and overlap are cut at each
//!   other's end points and the pieces that coincide are joined into one edge with a face on
//!   each side ([`join_collinear`]). End points within the tolerance of each other are one point.
//!
//! The rendered triangles are untouched: only the edge list of the boundary stage
//! (supplemental §2.1) sees the joins. Two different shapes are never joined: their edges
//! move with different parameters.

use crate::integrator::surface::self_intersection_eps;
use crate::kernel::V3;
use crate::scene::Geometry;
use glam::DVec3;
use std::collections::{HashMap, HashSet};

/// Distance, in self-intersection ε at the points concerned, within which a vertex lies on an
/// open edge or on another vertex (the 2ε within which the boundary stage takes a surface
/// for a support, `primary.rs`, `contact.rs`).
pub const SEAM_TOLERANCE: f64 = 2.0;

/// Most grid cells one open edge is entered into; a longer edge is compared with every open
/// edge of its shape instead.
const MAX_CELLS_PER_EDGE: usize = 512;

/// For every vertex, the first vertex of the same shape at the bit-identical position (itself
/// if none came before). Vertices no face uses map to themselves.
pub fn weld(geo: &Geometry) -> Vec<u32> {
    let mut canon: Vec<u32> = (0..geo.positions.len() as u32).collect();
    let mut first: HashMap<(u32, [u32; 3]), u32> = HashMap::new();
    for (f, tri) in geo.indices.iter().enumerate() {
        let shape = geo.tri_shape[f];
        for &v in tri {
            // +0 and −0 are one position
            let bits = geo.positions[v as usize].to_array().map(|c| (c + 0.0).to_bits());
            canon[v as usize] = *first.entry((shape, bits)).or_insert(v);
        }
    }
    canon
}

/// Union–find over vertex indices, created lazily.
#[derive(Default)]
struct Snap {
    parent: HashMap<u32, u32>,
}

impl Snap {
    fn find(&mut self, v: u32) -> u32 {
        let mut r = v;
        while let Some(&p) = self.parent.get(&r) {
            if p == r {
                break;
            }
            r = p;
        }
        // path compression
        let mut x = v;
        while x != r {
            let next = self.parent.get(&x).copied().unwrap_or(x);
            self.parent.insert(x, r);
            x = next;
        }
        r
    }
    fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            let (lo, hi) = (ra.min(rb), ra.max(rb));
            self.parent.insert(hi, lo);
            self.parent.entry(lo).or_insert(lo);
        }
    }
}

/// An open edge (one face) as `edges.rs` lists it: its end points and its face's side.
#[derive(Clone, Copy, Debug)]
pub struct OpenEdge {
    pub v0: u32,
    pub v1: u32,
    pub face: u32,
    /// The face's vertex opposite the edge.
    pub opposite: u32,
}

/// The open edges that overlap others, cut into pieces.
#[derive(Debug, Default)]
pub struct Joins {
    /// For each open edge given, its pieces as (snapped, sorted) end points, in order along
    /// it; empty for an edge that overlaps nothing.
    pub pieces: Vec<Vec<(u32, u32)>>,
    /// Every piece's faces, each with its vertex opposite the edge (one face: still open; two:
    /// joined; more: non-manifold).
    pub faces: HashMap<(u32, u32), Vec<(u32, u32)>>,
}

/// An open edge as a segment.
struct Segment {
    shape: u32,
    p: DVec3,
    q: DVec3,
    tol: f64,
}

/// Cuts the open edges `open` that lie on one line with others of their shape, and overlap
/// them, at each other's end points, and gathers the faces of the pieces that coincide
/// (module docs).
pub fn join_collinear(geo: &Geometry, open: &[OpenEdge], offset_scale: f32) -> Joins {
    let pos = |v: u32| geo.positions[v as usize].as_dvec3();
    let eps = |x: DVec3| self_intersection_eps(&V3::<f32>::splat(x.as_vec3()), offset_scale) as f64;
    let segments: Vec<Segment> = open
        .iter()
        .map(|e| {
            let (p, q) = (pos(e.v0), pos(e.v1));
            Segment {
                shape: geo.tri_shape[e.face as usize],
                p,
                q,
                tol: SEAM_TOLERANCE * eps(p).max(eps(q)),
            }
        })
        .collect();
    let mut joins = Joins {
        pieces: vec![Vec::new(); open.len()],
        faces: HashMap::new(),
    };
    if open.len() < 2 {
        return joins;
    }
    let mut splits: Vec<Vec<(f64, u32)>> = vec![Vec::new(); open.len()];
    let mut touched = vec![false; open.len()];
    let mut snap = Snap::default();
    for (i, j) in candidate_pairs(&segments) {
        let (a, b) = (&segments[i], &segments[j]);
        let tol = a.tol.max(b.tol);
        let (Some(ta), Some(tb)) = (along(a, b.p, b.q, tol), along(b, a.p, a.q, tol)) else {
            continue;
        };
        let (ea, eb) = (&open[i], &open[j]);
        touched[i] = true;
        touched[j] = true;
        for (t, v) in ta.into_iter().zip([eb.v0, eb.v1]) {
            splits[i].push((t, v));
        }
        for (t, v) in tb.into_iter().zip([ea.v0, ea.v1]) {
            splits[j].push((t, v));
        }
        for (x, vx) in [(a.p, ea.v0), (a.q, ea.v1)] {
            for (y, vy) in [(b.p, eb.v0), (b.q, eb.v1)] {
                if x.distance(y) <= tol {
                    snap.union(vx, vy);
                }
            }
        }
    }
    for (i, (e, sg)) in open.iter().zip(&segments).enumerate() {
        if !touched[i] {
            continue;
        }
        let len = sg.p.distance(sg.q);
        let inner = sg.tol / len.max(f64::MIN_POSITIVE);
        let mut cuts: Vec<(f64, u32)> = vec![(0.0, e.v0), (1.0, e.v1)];
        cuts.extend(splits[i].iter().copied().filter(|&(t, _)| t > inner && t < 1.0 - inner));
        cuts.sort_by(|x, y| x.0.total_cmp(&y.0));
        for w in cuts.windows(2) {
            let (u, v) = (snap.find(w[0].1), snap.find(w[1].1));
            if u == v || (w[1].0 - w[0].0) * len <= sg.tol {
                continue;
            }
            let key = (u.min(v), u.max(v));
            let faces = joins.faces.entry(key).or_default();
            if !faces.iter().any(|&(f, _)| f == e.face) {
                faces.push((e.face, e.opposite));
            }
            joins.pieces[i].push(key);
        }
    }
    joins
}

/// The parameters along `b` (0 at `b.p`, 1 at `b.q`) of the end points `x`, `y` of another
/// open edge, when both lie within `tol` of `b`'s line and the two segments overlap by more
/// than `tol`; None otherwise.
fn along(b: &Segment, x: DVec3, y: DVec3, tol: f64) -> Option<[f64; 2]> {
    let d = b.q - b.p;
    let len2 = d.length_squared();
    if !(len2 > 0.0) {
        return None;
    }
    let t = |z: DVec3| (z - b.p).dot(d) / len2;
    let off = |z: DVec3, tz: f64| (z - b.p - d * tz).length();
    let (tx, ty) = (t(x), t(y));
    if off(x, tx) > tol || off(y, ty) > tol {
        return None;
    }
    let overlap = (tx.max(ty).min(1.0) - tx.min(ty).max(0.0)) * len2.sqrt();
    (overlap > tol).then_some([tx, ty])
}

/// Pairs (i < j) of open edges of one shape whose boxes (grown by their tolerance) share a
/// cell of a uniform grid as fine as the mean open edge.
fn candidate_pairs(open: &[Segment]) -> Vec<(usize, usize)> {
    let mean = open.iter().map(|o| o.p.distance(o.q)).sum::<f64>() / open.len() as f64;
    let cell = mean.max(f64::MIN_POSITIVE);
    let mut grid: HashMap<(u32, [i64; 3]), Vec<usize>> = HashMap::new();
    let mut long: Vec<usize> = Vec::new();
    for (i, o) in open.iter().enumerate() {
        let lo = ((o.p.min(o.q) - o.tol) / cell).floor();
        let hi = ((o.p.max(o.q) + o.tol) / cell).floor();
        let n = (hi - lo + 1.0).max(DVec3::ONE);
        if !(n.x * n.y * n.z <= MAX_CELLS_PER_EDGE as f64) {
            long.push(i);
            continue;
        }
        let (lo, hi) = (lo.as_i64vec3(), hi.as_i64vec3());
        for x in lo.x..=hi.x {
            for y in lo.y..=hi.y {
                for z in lo.z..=hi.z {
                    grid.entry((o.shape, [x, y, z])).or_default().push(i);
                }
            }
        }
    }
    let mut pairs: HashSet<(usize, usize)> = HashSet::new();
    for members in grid.values() {
        for (k, &i) in members.iter().enumerate() {
            for &j in &members[k + 1..] {
                pairs.insert((i.min(j), i.max(j)));
            }
        }
    }
    for &i in &long {
        for j in 0..open.len() {
            if j != i && open[j].shape == open[i].shape {
                pairs.insert((i.min(j), i.max(j)));
            }
        }
    }
    let mut pairs: Vec<(usize, usize)> = pairs.into_iter().collect();
    pairs.sort_unstable();
    pairs
}

#[cfg(test)]
mod tests {
    use super::super::edges::tests::geometry;
    use super::super::edges::{Edge, build_edges};
    use crate::scene::{Geometry, shapes};
    use glam::Vec3;

    /// `mesh` with every triangle given its own three vertices.
    fn soup(mesh: &shapes::Mesh) -> shapes::Mesh {
        let mut out = mesh.clone();
        out.positions = mesh
            .tris
            .iter()
            .flat_map(|t| t.map(|i| mesh.positions[i as usize]))
            .collect();
        out.tris = (0..mesh.tris.len() as u32)
            .map(|f| [3 * f, 3 * f + 1, 3 * f + 2])
            .collect();
        out
    }

    /// The edges as sorted position pairs with their face count, for comparing edge lists of
    /// meshes indexed differently.
    fn by_position(geo: &Geometry, edges: &[Edge]) -> Vec<([[u32; 3]; 2], usize)> {
        let key = |v: u32| geo.positions[v as usize].to_array().map(f32::to_bits);
        let mut out: Vec<_> = edges
            .iter()
            .map(|e| {
                let (a, b) = (key(e.v0), key(e.v1));
                ([a.min(b), a.max(b)], 1 + e.face1.is_some() as usize)
            })
            .collect();
        out.sort();
        out
    }

    /// A unit cube [−1, 1]³ whose front face (z = 1) is fanned from `m`, a vertex on its bottom
    /// edge, while the bottom face keeps that edge whole: a T-junction at `m`.
    fn t_junction_cube(m: Vec3) -> Geometry {
        let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        let positions = vec![
            p(-1.0, -1.0, -1.0),
            p(1.0, -1.0, -1.0),
            p(1.0, 1.0, -1.0),
            p(-1.0, 1.0, -1.0),
            p(-1.0, -1.0, 1.0),
            p(1.0, -1.0, 1.0),
            p(1.0, 1.0, 1.0),
            p(-1.0, 1.0, 1.0),
            m,
        ];
        let tris = vec![
            [0, 3, 2],
            [0, 2, 1],
            [0, 4, 7],
            [0, 7, 3],
            [1, 2, 6],
            [1, 6, 5],
            [0, 1, 5],
            [0, 5, 4],
            [3, 7, 6],
            [3, 6, 2],
            // front, fanned from m (index 8) on the bottom edge 4–5
            [4, 8, 7],
            [8, 6, 7],
            [8, 5, 6],
        ];
        Geometry {
            tri_shape: vec![0; tris.len()],
            positions,
            indices: tris,
            ..Default::default()
        }
    }

    #[test]
    fn a_triangle_soup_has_the_edges_of_the_welded_mesh() {
        for mesh in [shapes::cube(), shapes::icosphere(1)] {
            let welded = geometry(mesh.clone());
            let loose = geometry(soup(&mesh));
            let (a, b) = (build_edges(&welded, 0.0), build_edges(&loose, 0.0));
            assert!(b.iter().all(|e| !e.is_boundary()), "a closed soup has no open edge");
            assert_eq!(by_position(&welded, &a), by_position(&loose, &b));
        }
    }

    /// A cube written as most exporters write a flat-shaded mesh: one normal per face, `f v//n`.
    /// The OBJ reader gives each (position, normal) pair its own vertex, so every cube edge
    /// came out as two open edges (the derivative of such a cube's pose: Σz² 4740 over 25
    /// blocks in a sweep, 20 after; 2026-11-29).
    #[test]
    fn an_obj_with_a_normal_per_face_has_the_cube_edges() {
        let cube = shapes::cube();
        let mut text = String::new();
        for p in &cube.positions {
            text += &format!("v {} {} {}\n", p.x, p.y, p.z);
        }
        for (k, t) in cube.tris.iter().enumerate() {
            let [a, b, c] = t.map(|i| cube.positions[i as usize]);
            let n = (b - a).cross(c - a).normalize();
            text += &format!("vn {} {} {}\n", n.x, n.y, n.z);
            let [i, j, l] = t.map(|i| i + 1);
            text += &format!("f {i}//{} {j}//{} {l}//{}\n", k + 1, k + 1, k + 1);
        }
        let read = shapes::parse_obj(&text).unwrap();
        assert!(
            read.positions.len() > cube.positions.len(),
            "the reader splits the vertices"
        );
        let mesh = shapes::Mesh {
            positions: read.positions.iter().map(|p| p.as_vec3()).collect(),
            tris: read.tris,
        };
        let edges = build_edges(&geometry(mesh), 0.0);
        assert_eq!(edges.len(), 12);
        assert!(edges.iter().all(|e| !e.is_boundary()));
    }

    #[test]
    fn a_t_junction_joins_the_split_edge_to_the_whole_one() {
        let geo = t_junction_cube(Vec3::new(0.0, -1.0, 1.0));
        let edges = build_edges(&geo, 0.0);
        assert!(edges.iter().all(|e| !e.is_boundary()), "{edges:?}");
        // 12 cube edges, the bottom-front one in two pieces joined at m
        assert_eq!(edges.len(), 13);
        let at_m: Vec<_> = edges.iter().filter(|e| e.v0 == 8 || e.v1 == 8).collect();
        assert_eq!(at_m.len(), 2, "{at_m:?}");
        for e in at_m {
            let faces = [e.face0, e.face1.unwrap()];
            assert!(
                faces.contains(&6) || faces.contains(&7),
                "the bottom face is on one side: {e:?}"
            );
        }
        // m a rounding away from the edge (f32 at 1 m: 6e-8) is still on it
        let geo = t_junction_cube(Vec3::new(0.3, -1.0 + 1.2e-7, 1.0 - 6e-8));
        assert!(build_edges(&geo, 0.0).iter().all(|e| !e.is_boundary()));
    }

    #[test]
    fn a_vertex_off_the_edge_is_not_a_t_junction() {
        // 1 mm above the bottom edge: a real notch, whose edges stay open
        let geo = t_junction_cube(Vec3::new(0.0, -0.999, 1.0));
        let open = build_edges(&geo, 0.0).iter().filter(|e| e.is_boundary()).count();
        assert_eq!(open, 3, "the bottom edge and the two notch edges");
    }

    #[test]
    fn two_shapes_are_never_joined() {
        // the soup cube's triangles alternately in two shapes: edges between them stay open
        let mut geo = geometry(soup(&shapes::cube()));
        geo.tri_shape = (0..geo.indices.len() as u32).map(|f| f % 2).collect();
        let edges = build_edges(&geo, 0.0);
        assert!(edges.iter().any(Edge::is_boundary));
        for e in edges.iter().filter(|e| !e.is_boundary()) {
            assert_eq!(
                geo.tri_shape[e.face0 as usize],
                geo.tri_shape[e.face1.unwrap() as usize]
            );
        }
    }
}
