//! Shapes that cross each other, where a parameter moves one of them.
//!
//! Where two surfaces cross (a box sunk a few centimetres into the floor), the crossing curve
//! is a crease of what the camera and the light see: the floor on one side, the box's face on
//! the other. It moves with the box, so it is a discontinuity of the path integrand
//! (supplemental Eq. 20's visibility, and the shading across it), yet it lies on no mesh edge.
//! The boundary stage samples mesh edges only (Algorithm 2: silhouettes and creases of the
//! meshes, contact edges resting on a surface: `contact.rs`), so it would miss this term and
//! the derivative would come out silently wrong (the sunk box's image derivative: 37 % short,
//! `tests/interpenetration.rs`). [`find_crossing`] finds such a crossing so that the render can
//! refuse it by name.
//!
//! Two triangles that cross meet along a segment whose ends lie where an edge of one passes
//! through the other, so it suffices to trace every edge of the moving shapes against the
//! whole scene and every edge of the others against the moving shapes alone (a second, small
//! BVH). A hit counts when the edge's ends lie on opposite sides of the hit triangle's plane,
//! each farther than twice the self-intersection ε there (`TOUCH`), and the hit lies inside
//! the triangle by more than that: shapes that only touch (a face or an edge resting on a
//! surface, a vertex on it, a floor's edge running under a pyramid's base edge) are the
//! contact edges' business and are not crossings. Hits on triangles that share an end point
//! with the edge (its own fan) are stepped over.
use super::primary::moving_shapes;
use crate::accel::{Accel, AccelError, Device};
use crate::integrator::context::RenderContext;
use crate::integrator::surface::self_intersection_eps;
use crate::kernel::V3;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// How far (in units of the self-intersection ε) an edge's end may reach past a face, or a
/// crossing lie from the face's border, and still be a touch: the 2ε within which the
/// boundary stage takes a surface for an edge's support (`contact.rs`, `primary.rs`), so a
/// shape sunk by less is handled as resting on it (tests/boundary_primary.rs: a cube sunk
/// 5 µm), and one sunk deeper is refused.
const TOUCH: f64 = 2.0;

/// Hits stepped over along one edge before it is given up (its own fan, coplanar faces).
const MAX_STEPS: usize = 16;

/// An edge of shape `edge_shape` passing through a triangle of shape `face_shape`; `moved` is
/// the one of the two that a parameter moves (the edge's shape when both move).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crossing {
    pub edge_shape: u32,
    pub face_shape: u32,
    pub moved: u32,
    /// Where the edge passes through the face, relative to the scene's render origin.
    pub at: DVec3,
}

/// The first crossing (in triangle order) of a shape that a parameter of `ctx.motion` moves
/// with any shape, itself included; `None` when the moving shapes cross nothing. Runs on
/// `pool`.
pub fn find_crossing(
    ctx: &RenderContext,
    device: &Device,
    pool: &rayon::ThreadPool,
) -> Result<Option<Crossing>, AccelError> {
    let moving = moving_shapes(ctx);
    let geo = &ctx.scene.geometry;
    let tri_moves = |t: usize| moving[geo.tri_shape[t] as usize];
    let moved: Vec<u32> = (0..geo.indices.len())
        .filter(|&t| tri_moves(t))
        .map(|t| t as u32)
        .collect();
    if moved.is_empty() {
        return Ok(None);
    }
    let positions: Vec<[f32; 3]> = geo.positions.iter().map(|p| p.to_array()).collect();
    let moved_indices: Vec<[u32; 3]> = moved.iter().map(|&t| geo.indices[t as usize]).collect();
    let moved_accel = Accel::build(device, &positions, &moved_indices)?;
    Ok(pool.install(|| {
        (0..geo.indices.len()).into_par_iter().find_map_first(|t| {
            // a moving triangle's edges against everything; another's against the moving
            let (accel, faces): (&Accel, Option<&[u32]>) = if tri_moves(t) {
                (&ctx.accel, None)
            } else {
                (&moved_accel, Some(&moved))
            };
            let v = ctx.tri_verts[t];
            (0..3).find_map(|i| {
                crossing_along(ctx, accel, faces, v[i], v[(i + 1) % 3]).map(|(face, at)| {
                    let (edge_shape, face_shape) = (geo.tri_shape[t], geo.tri_shape[face]);
                    let moved = if tri_moves(t) { edge_shape } else { face_shape };
                    Crossing {
                        edge_shape,
                        face_shape,
                        moved,
                        at,
                    }
                })
            })
        })
    }))
}

/// The first triangle (global index) that the edge a→b passes through, with the crossing
/// point. `faces` maps the accel's primitives to global triangles (`None`: the same).
fn crossing_along(
    ctx: &RenderContext,
    accel: &Accel,
    faces: Option<&[u32]>,
    a: Vec3,
    b: Vec3,
) -> Option<(usize, DVec3)> {
    let len = a.distance(b);
    if !(len > 0.0) {
        return None;
    }
    let dir = (b - a) / len;
    let mut tnear = 0.0f32;
    for _ in 0..MAX_STEPS {
        let hit = accel.intersect1(a.to_array(), dir.to_array(), tnear, len)?;
        let face = faces.map_or(hit.prim as usize, |f| f[hit.prim as usize] as usize);
        let tri = ctx.tri_verts[face];
        if !tri.contains(&a) && !tri.contains(&b) {
            let [p0, p1, p2] = tri.map(|p| p.as_dvec3());
            let n = ctx.face_normal64(face as u32);
            let (da, db) = (n.dot(a.as_dvec3() - p0), n.dot(b.as_dvec3() - p0));
            let at = a + dir * hit.t;
            let tol = TOUCH * self_intersection_eps(&V3::<f32>::splat(at), ctx.scene.offset_scale) as f64;
            let at = at.as_dvec3();
            let inside = [(p0, p1), (p1, p2), (p2, p0)]
                .iter()
                .all(|&(u, w)| distance_to_segment(at, u, w) > tol);
            if da * db < 0.0 && da.abs().min(db.abs()) > tol && inside {
                return Some((face, at));
            }
        }
        tnear = hit.t + (hit.t * 1e-6).max(len * 1e-7);
        if tnear >= len {
            return None;
        }
    }
    None
}

/// Distance from `p` to the segment u–w.
fn distance_to_segment(p: DVec3, u: DVec3, w: DVec3) -> f64 {
    let e = w - u;
    let s = if e.length_squared() > 0.0 {
        ((p - u).dot(e) / e.length_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(u + e * s)
}
