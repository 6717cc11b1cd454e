//! Edge topology, built once per scene (supplemental §2.1).
//!
//! Each record keeps integers only: its vertices v0 < v1, its faces (face1 = None on a mesh
//! boundary) and the vertex opposite the edge in each face. Geometry is gathered per use.
//! Edges whose two faces are coplanar (and consistently oriented) are dropped: they cannot be
//! silhouettes (supplemental Eq. 32), so they carry no boundary term.

use super::seams::{OpenEdge, join_collinear, weld};
use crate::scene::Geometry;
use std::collections::HashMap;

/// One mesh edge. `face1` is None for a boundary edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Edge {
    pub v0: u32,
    pub v1: u32,
    pub face0: u32,
    pub face1: Option<u32>,
    /// Vertex of face0 (and face1) not on the edge.
    pub opposite0: u32,
    pub opposite1: Option<u32>,
}

impl Edge {
    /// A boundary edge has one face; a sharp edge two.
    pub fn is_boundary(&self) -> bool {
        self.face1.is_none()
    }
}

/// Dihedral threshold: faces whose unit normals agree to within this cosine are coplanar.
pub const COPLANAR_COS: f32 = 1.0 - 1e-6;

/// Builds the edges of all triangles. Edges shared by more than two faces (non-manifold) are
/// kept as boundary edges of each extra face, so none is lost. Unwelded vertices and
/// T-junctions are seams, not edges (`seams.rs`); `offset_scale` is the scene's
/// (`Scene::offset_scale`), which sets the tolerance of a T-junction.
pub fn build_edges(geo: &Geometry, offset_scale: f32) -> Vec<Edge> {
    let canon = weld(geo);
    let mut map: HashMap<(u32, u32), usize> = HashMap::new();
    let mut edges: Vec<Edge> = Vec::new();
    for (f, tri) in geo.indices.iter().enumerate() {
        for k in 0..3 {
            let (a, b, o) = (
                canon[tri[k] as usize],
                canon[tri[(k + 1) % 3] as usize],
                tri[(k + 2) % 3],
            );
            if a == b {
                continue;
            }
            let key = (a.min(b), a.max(b));
            match map.get(&key) {
                Some(&i) if edges[i].face1.is_none() => {
                    edges[i].face1 = Some(f as u32);
                    edges[i].opposite1 = Some(o);
                }
                _ => {
                    map.insert(key, edges.len());
                    edges.push(Edge {
                        v0: key.0,
                        v1: key.1,
                        face0: f as u32,
                        face1: None,
                        opposite0: o,
                        opposite1: None,
                    });
                }
            }
        }
    }
    let mut edges = join_seams(geo, edges, offset_scale);
    edges.retain(|e| !is_coplanar(geo, e));
    edges
}

/// `edges` with the open edges that `seams::join_collinear` cuts replaced, where each stood,
/// by their pieces (each piece once; one with more than two faces as a pair and then open
/// edges, as for any non-manifold edge). Everything else is kept in order.
fn join_seams(geo: &Geometry, edges: Vec<Edge>, offset_scale: f32) -> Vec<Edge> {
    let open_at: Vec<usize> = (0..edges.len()).filter(|&i| edges[i].is_boundary()).collect();
    let open: Vec<OpenEdge> = open_at
        .iter()
        .map(|&i| OpenEdge {
            v0: edges[i].v0,
            v1: edges[i].v1,
            face: edges[i].face0,
            opposite: edges[i].opposite0,
        })
        .collect();
    let joins = join_collinear(geo, &open, offset_scale);
    if joins.pieces.iter().all(Vec::is_empty) {
        return edges;
    }
    let mut pieces_of: Vec<&[(u32, u32)]> = vec![&[]; edges.len()];
    for (k, &i) in open_at.iter().enumerate() {
        pieces_of[i] = &joins.pieces[k];
    }
    let mut emitted = std::collections::HashSet::new();
    let mut out = Vec::with_capacity(edges.len());
    for (e, pieces) in edges.iter().zip(pieces_of) {
        if pieces.is_empty() {
            out.push(*e);
            continue;
        }
        for &key in pieces {
            if !emitted.insert(key) {
                continue;
            }
            let faces = &joins.faces[&key];
            let edge = |f: &[(u32, u32)]| Edge {
                v0: key.0,
                v1: key.1,
                face0: f[0].0,
                opposite0: f[0].1,
                face1: f.get(1).map(|x| x.0),
                opposite1: f.get(1).map(|x| x.1),
            };
            out.push(edge(&faces[..faces.len().min(2)]));
            for extra in faces.iter().skip(2) {
                out.push(edge(std::slice::from_ref(extra)));
            }
        }
    }
    out
}

fn face_normal(geo: &Geometry, f: u32) -> glam::Vec3 {
    crate::scene::triangle_normal(geo.indices[f as usize].map(|i| geo.positions[i as usize]))
}

/// Two faces sharing an edge lie in one plane, facing the same way: their normals agree
/// within [`COPLANAR_COS`], or the thinner one lies in the other's plane to within the
/// rounding of the coordinates ([`within_rounding`]). `c0`, `c1`: each face's vertex off the
/// edge.
fn coplanar_faces(geo: &Geometry, (f0, c0): (u32, u32), (f1, c1): (u32, u32)) -> bool {
    let dot = face_normal(geo, f0).dot(face_normal(geo, f1));
    dot >= COPLANAR_COS || (dot > 0.0 && within_rounding(geo, (f0, c0), (f1, c1)))
}

/// Coordinate roundings (units of 2⁻²³ of the largest coordinate) within which a vertex
/// counts as in a plane: f32 world positions carry half of one each.
const PLANE_ROUNDINGS: f64 = 4.0;

/// Whether the thinner of two faces sharing an edge has its vertex off the edge within
/// [`PLANE_ROUNDINGS`] of the wider one's plane. A sliver (a mesh whose border an exporter
/// split with a vertex a hair off the line) has a normal that rounding alone tilts: 3·10⁻²
/// rad for a sliver 10⁻⁶ of its length wide on a plate turned about all three axes, twenty
/// times [`COPLANAR_COS`]'s angle, so its edges stood as creases and the boundary terms took
/// them for discontinuities (a shadow's derivative 7 standard errors off in one block, an
/// independent sweep). The wider face's normal is sound, and the sliver lies in its plane. A
/// finely tessellated curved mesh keeps its edges: 1 mm faces on a 1 m sphere stand 10⁻⁶ m
/// off each other's planes, twice this tolerance at 1 m from the origin.
fn within_rounding(geo: &Geometry, (f0, c0): (u32, u32), (f1, c1): (u32, u32)) -> bool {
    let tri = |f: u32| geo.indices[f as usize].map(|i| geo.positions[i as usize].as_dvec3());
    let (t0, t1) = (tri(f0), tri(f1));
    let normal = |t: &[glam::DVec3; 3]| (t[1] - t[0]).cross(t[2] - t[0]);
    let (n0, n1) = (normal(&t0), normal(&t1));
    // the thinner face (the smaller area over the shared edge) against the wider one's plane
    let (c, wide, n) = match n0.length() <= n1.length() {
        true => (c0, &t1, n1),
        false => (c1, &t0, n0),
    };
    let len = n.length();
    if len == 0.0 {
        return false;
    }
    let c = geo.positions[c as usize].as_dvec3();
    let d = (c - wide[0]).dot(n).abs() / len;
    let scale = t0.iter().chain(&t1).fold(0.0f64, |m, p| m.max(p.abs().max_element()));
    // the wide plane's own rounding tilts it by about a rounding over its size (√|n|), which
    // a vertex farther off than that size sees magnified
    let reach = wide.iter().map(|p| (c - *p).length()).fold(0.0f64, f64::max) / len.sqrt();
    d <= PLANE_ROUNDINGS * scale * f64::from(f32::EPSILON) * reach.max(1.0)
}

/// Two faces in one plane, facing the same way: the edge is invisible to visibility.
fn is_coplanar(geo: &Geometry, e: &Edge) -> bool {
    match (e.face1, e.opposite1) {
        (Some(f1), Some(c1)) => coplanar_faces(geo, (e.face0, e.opposite0), (f1, c1)),
        _ => false,
    }
}

/// Per face and edge slot k (the edge from vertex k to vertex k + 1 of the face), the face
/// across that edge and its slot of the same edge, where the two faces are coplanar: the
/// edges [`build_edges`] drops, across which the surface goes on without a discontinuity.
/// A sliver triangle along a mesh's border (an exporter's split of that border) is one such
/// face: the primary term's side rays walk through it into the rest of the surface
/// (`primary.rs`, `Estimator::side_offsets`).
pub struct CoplanarNeighbours(Vec<[Option<(u32, u8)>; 3]>);

impl CoplanarNeighbours {
    /// The table for the faces of the shapes `wanted` says (welded vertices are per shape, so
    /// neighbours never cross shapes); other faces have none.
    pub fn build(geo: &Geometry, wanted: impl Fn(u32) -> bool) -> Self {
        let canon = weld(geo);
        let mut sides: HashMap<(u32, u32), Vec<(u32, u8)>> = HashMap::new();
        for (f, tri) in geo.indices.iter().enumerate() {
            if !wanted(geo.tri_shape[f]) {
                continue;
            }
            for k in 0..3 {
                let (a, b) = (canon[tri[k] as usize], canon[tri[(k + 1) % 3] as usize]);
                if a != b {
                    sides.entry((a.min(b), a.max(b))).or_default().push((f as u32, k as u8));
                }
            }
        }
        let mut across = vec![[None; 3]; geo.indices.len()];
        for pair in sides.values() {
            let far = |f: u32, k: u8| geo.indices[f as usize][(k as usize + 2) % 3];
            if let [(f0, k0), (f1, k1)] = pair[..]
                && coplanar_faces(geo, (f0, far(f0, k0)), (f1, far(f1, k1)))
            {
                across[f0 as usize][k0 as usize] = Some((f1, k1));
                across[f1 as usize][k1 as usize] = Some((f0, k0));
            }
        }
        CoplanarNeighbours(across)
    }

    /// The face across edge slot `slot` of `face` and its slot of that edge, if coplanar.
    pub fn across(&self, face: u32, slot: usize) -> Option<(u32, usize)> {
        self.0[face as usize][slot].map(|(f, k)| (f, k as usize))
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::scene::shapes;

    /// A one-shape scene geometry of `mesh` (shared by the boundary tests).
    pub(crate) fn geometry(mesh: shapes::Mesh) -> Geometry {
        crate::scene::testutil::geometry_of(&[mesh])
    }

    #[test]
    fn cube_keeps_its_twelve_sharp_edges() {
        let edges = build_edges(&geometry(shapes::cube()), 0.0);
        assert_eq!(edges.len(), 12, "6 face diagonals are coplanar and dropped");
        assert!(edges.iter().all(|e| !e.is_boundary()));
    }

    #[test]
    fn rectangle_has_four_boundary_edges() {
        let edges = build_edges(&geometry(shapes::rectangle()), 0.0);
        assert_eq!(edges.len(), 4);
        assert!(edges.iter().all(Edge::is_boundary));
    }

    #[test]
    fn sphere_keeps_every_edge() {
        let m = shapes::icosphere(2);
        let tris = m.tris.len();
        let edges = build_edges(&geometry(m), 0.0);
        assert_eq!(edges.len(), tris * 3 / 2, "closed mesh: E = 3F/2, none coplanar");
        for e in &edges {
            let f1 = e.face1.unwrap() as usize;
            assert!(geometry(shapes::icosphere(2)).indices[f1].contains(&e.opposite1.unwrap()));
        }
    }
}
