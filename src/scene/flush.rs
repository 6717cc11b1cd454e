//! Emitters flush with other surfaces.
//!
//! An area emitter modelled coplanar with a surface it overlaps (a light panel flush with a
//! ceiling, as exported scenes often have) leaves Embree two triangles at the same distance:
//! it returns either, so the panel's light was lost on a random part of the hits (issue 9:
//! the Cornell light at the ceiling's height lost 20% of the image's energy, differently per
//! seed). Here a coplanar emitter means **the emitting face wins**: at load time, an emitter
//! shape whose triangles overlap a parallel triangle of another shape closer than [`lift`]
//! is moved along its emitting normal until it lies `lift` in front of that surface. Camera
//! rays, BSDF-sampled rays, shadow rays to the light, BDPT light subpaths and the boundary
//! stage then all see one well-separated surface, with no per-hit cost. `lift` is 2⁻¹³ of the
//! coordinates' magnitude (0.12 mm for a room near the render origin; the magnitude is taken
//! at least the scene's offset scale, `super::origin::offset_scale`, so a scene of a few
//! millimetres gets a lift of its own size, not a room's): 32× the ray-origin offset of
//! `integrator::surface::self_intersection_eps`, and far above Embree's f32 distance error,
//! so the emitter is always the nearer hit from its front side.
//!
//! Only a surface behind the emitting face (or in its plane, to within that ray-origin
//! offset) is one it lies flush on. A surface in front of it, however close, covers it: the
//! emitter is never moved through it, nor past half the gap to it.

use super::{Geometry, Shape, triangle_normal};
use glam::Vec3;

/// Unit normals this close (cosine) count as parallel.
const COPLANAR_COS: f32 = 1.0 - 1e-6;

/// The separation a flush emitter is given from the surface behind it, at coordinate
/// magnitude `m` (largest absolute coordinate, at least the scene's offset scale).
pub fn lift(m: f32) -> f32 {
    m / 8192.0
}

/// How far in front of an emitting face a parallel surface may lie and still count as in its
/// plane, at coordinate magnitude `m`: the ray-origin offset there (2⁻¹⁸ m), within which no
/// ray tells the two apart.
fn in_plane(m: f32) -> f32 {
    m * crate::integrator::surface::OFFSET_PER_COORDINATE
}

fn corners(geo: &Geometry, t: usize) -> [Vec3; 3] {
    geo.indices[t].map(|i| geo.positions[i as usize])
}

/// The corners (lowest, highest) of the box around `shape`'s vertices.
fn bounds(shape: &Shape, geo: &Geometry) -> (Vec3, Vec3) {
    let verts = shape.first_vertex as usize..(shape.first_vertex + shape.vertex_count) as usize;
    geo.positions[verts]
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        })
}

/// The heights of the smaller triangle's corners over the larger one's plane, signed so that
/// a positive height puts `e` in front of `o` along `n` (`e`'s unit normal; `o` parallel to
/// it). Measured in f64 on the larger triangle's plane, as its own vertices give it: the
/// plane of a small face is known only to the rounding of its normal times the distance, and
/// the corners of a 40 km ground lie that far from a panel over it, so the ground's corners
/// over the panel's plane came out centimetres off.
fn heights(e: [Vec3; 3], o: [Vec3; 3], n: Vec3) -> [f64; 3] {
    let area = |t: [Vec3; 3]| (t[1] - t[0]).cross(t[2] - t[0]).length();
    let (big, small, sign) = if area(o) >= area(e) { (o, e, 1.0) } else { (e, o, -1.0) };
    let [b0, b1, b2] = big.map(|p| p.as_dvec3());
    let normal = (b1 - b0).cross(b2 - b0).normalize_or_zero();
    let normal = if normal.dot(n.as_dvec3()) < 0.0 {
        -normal
    } else {
        normal
    };
    small.map(|p| sign * (p.as_dvec3() - b0).dot(normal))
}

/// The largest absolute coordinate where triangles `a` and `b` can overlap (within both, so at
/// most the smaller of their largest coordinates), at least `scale`: the magnitude that sets
/// the rounding there, whatever else either shape reaches (a 40 km ground under a room).
fn overlap_magnitude(a: [Vec3; 3], b: [Vec3; 3], scale: f32) -> f32 {
    let largest = |t: [Vec3; 3]| t.iter().fold(0.0f32, |m, p| m.max(p.abs().max_element()));
    largest(a).min(largest(b)).max(scale)
}

/// Orientation of (a, b, c) seen along the plane normal `n` (twice the signed area).
fn orient(a: Vec3, b: Vec3, c: Vec3, n: Vec3) -> f32 {
    (b - a).cross(c - a).dot(n)
}

fn inside(p: Vec3, [a, b, c]: [Vec3; 3], n: Vec3) -> bool {
    let (d0, d1, d2) = (orient(a, b, p, n), orient(b, c, p, n), orient(c, a, p, n));
    (d0 > 0.0 && d1 > 0.0 && d2 > 0.0) || (d0 < 0.0 && d1 < 0.0 && d2 < 0.0)
}

fn segments_cross(p: Vec3, q: Vec3, r: Vec3, s: Vec3, n: Vec3) -> bool {
    let (o1, o2) = (orient(p, q, r, n), orient(p, q, s, n));
    let (o3, o4) = (orient(r, s, p, n), orient(r, s, q, n));
    o1 * o2 < 0.0 && o3 * o4 < 0.0
}

/// Two coplanar triangles (normal `n`) share an area: a vertex or centroid of one inside the
/// other, or two edges crossing.
fn overlap(e: [Vec3; 3], o: [Vec3; 3], n: Vec3) -> bool {
    let centroid = |t: [Vec3; 3]| (t[0] + t[1] + t[2]) / 3.0;
    let o_flat = o.map(|p| p - n * (p - e[0]).dot(n));
    if e.iter().chain([&centroid(e)]).any(|&p| inside(p, o_flat, n))
        || o_flat.iter().chain([&centroid(o_flat)]).any(|&p| inside(p, e, n))
    {
        return true;
    }
    (0..3).any(|i| (0..3).any(|j| segments_cross(e[i], e[(i + 1) % 3], o_flat[j], o_flat[(j + 1) % 3], n)))
}

/// The faces of other shapes that `shape` lies flush on: for each parallel triangle `o` of
/// another shape that one of its triangles overlaps less than `lift` in front of or behind,
/// `(o, n, d)` with `n` that triangle's unit normal and `d` its signed distance in front of
/// `o`'s plane along `n`; and the coordinate magnitude `m` that `lift(m)` was taken at (the
/// shape's largest coordinate, at least `scale`, the scene's offset scale).
fn flush_faces(shape: &Shape, geo: &Geometry, scale: f32) -> (Vec<(usize, Vec3, f32)>, f32) {
    let tris = shape.first_tri as usize..(shape.first_tri + shape.tri_count) as usize;
    let verts = shape.first_vertex as usize..(shape.first_vertex + shape.vertex_count) as usize;
    let m = geo.positions[verts]
        .iter()
        .fold(scale, |m, p| m.max(p.abs().max_element()));
    let delta = lift(m);
    let (lo, hi) = bounds(shape, geo);
    let (lo, hi) = (lo - delta, hi + delta);
    let mut found = Vec::new();
    for o in 0..geo.indices.len() {
        if tris.contains(&o) {
            continue;
        }
        let oc = corners(geo, o);
        let (olo, ohi) = (oc[0].min(oc[1]).min(oc[2]), oc[0].max(oc[1]).max(oc[2]));
        if olo.cmpgt(hi).any() || ohi.cmplt(lo).any() {
            continue;
        }
        let on = triangle_normal(oc);
        for t in tris.clone() {
            let ec = corners(geo, t);
            let n = triangle_normal(ec);
            if n == Vec3::ZERO || on == Vec3::ZERO || n.dot(on).abs() < COPLANAR_COS {
                continue;
            }
            let d = heights(ec, oc, n).into_iter().fold(f64::INFINITY, f64::min) as f32;
            if d.abs() < delta && overlap(ec, oc, n) {
                found.push((o, n, d));
            }
        }
    }
    (found, m)
}

/// Moves every area-emitter shape that lies flush on (or less than [`lift`] in front of)
/// a parallel surface behind it that it overlaps, along its emitting normal, to `lift` in
/// front of that surface, but never past half the gap to a surface in front of it (which
/// covers it, `in_plane`). `scale` is the scene's offset scale. Returns the names of the
/// shapes moved.
pub(crate) fn lift_flush_emitters(shapes: &mut [Shape], geo: &mut Geometry, scale: f32) -> Vec<String> {
    let mut moved = Vec::new();
    for shape in shapes.iter_mut().filter(|s| s.emitter.is_some()) {
        let (faces, m) = flush_faces(shape, geo, scale);
        let (delta, plane) = (lift(m), in_plane(m));
        // the largest shift along each flagged normal, from the surfaces behind
        let shift = faces
            .iter()
            .filter(|&&(_, _, d)| d >= -plane)
            .map(|&(_, n, d)| (n, delta - d))
            .fold(None, |best: Option<(Vec3, f32)>, (n, need)| match best {
                Some((_, k)) if k >= need => best,
                _ => Some((n, need)),
            });
        // at most half the way to the nearest surface in front along that normal
        let shift = shift.map(|(n, need)| {
            let room = faces
                .iter()
                .filter(|&&(_, face_n, d)| d < -plane && face_n.dot(n) > COPLANAR_COS)
                .map(|&(_, _, d)| -d / 2.0)
                .fold(f32::INFINITY, f32::min);
            (n, need.min(room))
        });
        if let Some((n, k)) = shift.filter(|&(_, k)| k > 0.0) {
            let by = n * k;
            let verts = shape.first_vertex as usize..(shape.first_vertex + shape.vertex_count) as usize;
            for p in &mut geo.positions[verts] {
                *p += by;
            }
            shape.transform.translate += by;
            moved.push(shape.name.clone());
        }
    }
    moved
}

/// The first dielectric shape found lying flush on another surface it overlaps (a glass
/// block standing on a floor, a liquid filling its container to the walls), with that other
/// shape and the separation needed: two triangles at the same distance leave it to rounding
/// which one a ray meets, so whether a path enters the glass, or stays in it, is undefined
/// there (and differs between renderers). Such scenes are refused (`resolve.rs`), not
/// repaired: lifting the glass off a floor is a small air gap, but the same gap between a
/// liquid and its container would be wrong.
pub(crate) fn flush_dielectric(
    shapes: &[Shape],
    geo: &Geometry,
    materials: &[super::NamedMaterial],
    scale: f32,
) -> Option<(usize, usize, f32)> {
    shapes.iter().enumerate().find_map(|(i, shape)| {
        if !matches!(
            materials[shape.material as usize].material,
            super::Material::Dielectric { .. }
        ) {
            return None;
        }
        let (faces, m) = flush_faces(shape, geo, scale);
        faces.first().map(|&(o, _, _)| (i, geo.tri_shape[o] as usize, lift(m)))
    })
}

/// Candidate triangle pairs beyond which [`faces_flush`] gives up on a pair of shapes (two
/// large meshes overlapping in space): the check gives a warning (and refuses derivatives),
/// which is not worth minutes of loading.
const MAX_PAIRS: usize = 1 << 24;

/// Pairs of shapes of different materials with faces that lie in one plane, facing the same
/// way, and overlap (a decal modelled on a floor): which of the two a ray meets there is left
/// to rounding, so the picture shows a speckled mix of both. Emitters (lifted off such faces
/// by [`lift_flush_emitters`]) and dielectrics (refused: [`flush_dielectric`]) are not
/// looked at. Faces that face each other, as a box's bottom on the floor it rests on, are
/// not a clash: the overlap lies inside the box. Returns (shape, other shape) index pairs,
/// each once.
pub(crate) fn flush_surfaces(
    shapes: &[Shape],
    geo: &Geometry,
    materials: &[super::NamedMaterial],
    scale: f32,
) -> Vec<(usize, usize)> {
    let boxes: Vec<(Vec3, Vec3)> = shapes.iter().map(|s| bounds(s, geo)).collect();
    let material = |s: &Shape| &materials[s.material as usize].material;
    let mut found = Vec::new();
    for (i, a) in shapes.iter().enumerate() {
        for (j, b) in shapes.iter().enumerate().skip(i + 1) {
            if unlooked(a, materials) || unlooked(b, materials) || material(a) == material(b) {
                continue;
            }
            if faces_flush((a, boxes[i]), (b, boxes[j]), geo, scale) {
                found.push((i, j));
            }
        }
    }
    found
}

/// A shape that lies flush on `shape` as [`flush_surfaces`] finds them, whatever the two
/// materials: moving either one has no derivative, since which of the two a ray meets there
/// is left to rounding (even where the two look alike, the interior estimator moves the
/// surface points of the one it happened to meet, and the edges between them show no
/// difference for the boundary estimator to weigh). `params::lanes::Motion` refuses such
/// parameters.
pub(crate) fn flush_partner(
    shapes: &[Shape],
    geo: &Geometry,
    materials: &[super::NamedMaterial],
    scale: f32,
    shape: usize,
) -> Option<usize> {
    let a = &shapes[shape];
    if unlooked(a, materials) {
        return None;
    }
    let own = (a, bounds(a, geo));
    (0..shapes.len()).find(|&j| {
        let b = &shapes[j];
        j != shape && !unlooked(b, materials) && faces_flush(own, (b, bounds(b, geo)), geo, scale)
    })
}

/// Shapes [`flush_surfaces`] leaves alone: emitters (lifted off flush faces) and dielectrics
/// (refused where flush).
fn unlooked(s: &Shape, materials: &[super::NamedMaterial]) -> bool {
    s.emitter.is_some()
        || matches!(
            materials[s.material as usize].material,
            super::Material::Dielectric { .. }
        )
}

/// Whether shapes `a` and `b` (each with the box around its vertices) have faces in one
/// plane, facing the same way, that overlap.
fn faces_flush(a: (&Shape, (Vec3, Vec3)), b: (&Shape, (Vec3, Vec3)), geo: &Geometry, scale: f32) -> bool {
    flush_pair(a, b, geo, scale).is_some()
}

/// A triangle of `a` and one of `b` in one plane, facing the same way, that overlap, if any
/// ([`faces_flush`]).
fn flush_pair(
    a: (&Shape, (Vec3, Vec3)),
    b: (&Shape, (Vec3, Vec3)),
    geo: &Geometry,
    scale: f32,
) -> Option<(usize, usize)> {
    coplanar_pair(a, b, geo, scale, Facing::Same)
}

/// How the two faces of a [`coplanar_pair`] face.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Facing {
    /// The same way, within the ray-origin offset of one plane (`in_plane`): flush.
    Same,
    /// Either way, less than half of [`lift`] apart: one rests on the other (a box's bottom
    /// on the floor), or nearly (an open mat 0.05 mm over it).
    Either,
}

/// A triangle of `a` and one of `b`, parallel, facing as `facing` says, close enough and
/// overlapping, if any.
fn coplanar_pair(
    (a, abox): (&Shape, (Vec3, Vec3)),
    (b, bbox): (&Shape, (Vec3, Vec3)),
    geo: &Geometry,
    scale: f32,
    facing: Facing,
) -> Option<(usize, usize)> {
    let tris = |s: &Shape| s.first_tri as usize..(s.first_tri + s.tri_count) as usize;
    let ((alo, ahi), (blo, bhi)) = (abox, bbox);
    let m = alo
        .abs()
        .max(ahi.abs())
        .max(blo.abs())
        .max(bhi.abs())
        .max_element()
        .max(scale);
    // how far apart two faces may be: at the shapes' largest coordinate, which picks the
    // candidates; two faces in one plane are told apart by the rounding where they overlap,
    // which a far corner of either shape (a 40 km ground under a room) does not widen, so
    // each such pair takes its own (`overlap_magnitude`); a resting contact keeps the shapes'
    // magnitude, its threshold being about the estimator's variance rather than rounding
    let gap = match facing {
        Facing::Same => in_plane(m),
        Facing::Either => lift(m) / 2.0,
    };
    let pair_gap = |sc: [Vec3; 3], oc: [Vec3; 3]| match facing {
        Facing::Same => in_plane(overlap_magnitude(sc, oc, scale)),
        Facing::Either => gap,
    };
    let (lo, hi) = (alo.max(blo) - gap, ahi.min(bhi) + gap);
    if lo.cmpgt(hi).any() {
        return None;
    }
    let near = |t: &usize| {
        let c = corners(geo, *t);
        let (clo, chi) = (c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2]));
        !(clo.cmpgt(hi).any() || chi.cmplt(lo).any())
    };
    let (ta, tb): (Vec<usize>, Vec<usize>) = (tris(a).filter(near).collect(), tris(b).filter(near).collect());
    if ta.len().saturating_mul(tb.len()) > MAX_PAIRS {
        return None;
    }
    ta.iter().find_map(|&s| {
        let sc = corners(geo, s);
        let n = triangle_normal(sc);
        if n == Vec3::ZERO {
            return None;
        }
        tb.iter()
            .find(|&&o| {
                let oc = corners(geo, o);
                let c = n.dot(triangle_normal(oc));
                let gap = pair_gap(sc, oc) as f64;
                (if facing == Facing::Same { c } else { c.abs() }) >= COPLANAR_COS
                    && heights(sc, oc, n).iter().all(|h| h.abs() <= gap)
                    && overlap(sc, oc, n)
            })
            .map(|&o| (s, o))
    })
}

/// The shapes `shape` rests on or is rested on by: each other shape with a face parallel to
/// one of `shape`'s, less than half of [`lift`] apart (0.06 mm in a room), overlapping (a
/// box's bottom on the floor, an open mat 0.05 mm over it), with that triangle of `shape`'s.
/// Emitters, lifted off the surfaces they lie flush on ([`lift_flush_emitters`]), are not
/// looked at. Contacts along an edge or at a vertex only (a cube balanced on an edge) are
/// not found.
pub(crate) fn resting(shapes: &[Shape], geo: &Geometry, scale: f32, shape: usize) -> Vec<(usize, usize)> {
    let a = &shapes[shape];
    if a.emitter.is_some() {
        return Vec::new();
    }
    let own = (a, bounds(a, geo));
    (0..shapes.len())
        .filter(|&j| j != shape && shapes[j].emitter.is_none())
        .filter_map(|j| {
            let b = &shapes[j];
            coplanar_pair(own, (b, bounds(b, geo)), geo, scale, Facing::Either).map(|(t, _)| (j, t))
        })
        .collect()
}

/// Two emitters in one plane: pairs of area-emitter shapes with faces in one plane, facing the
/// same way, that overlap (a light panel drawn inside a larger light quad), each with one such
/// pair of triangles. Both emit there, and [`lift_flush_emitters`] can lift only one in
/// front: the other's light is then lost where they overlap ([`front_of`] says which).
pub(crate) fn flush_emitters(shapes: &[Shape], geo: &Geometry, scale: f32) -> Vec<[(usize, usize); 2]> {
    let boxes: Vec<(Vec3, Vec3)> = shapes.iter().map(|s| bounds(s, geo)).collect();
    let mut found = Vec::new();
    for (i, a) in shapes.iter().enumerate().filter(|(_, s)| s.emitter.is_some()) {
        for (j, b) in shapes
            .iter()
            .enumerate()
            .skip(i + 1)
            .filter(|(_, s)| s.emitter.is_some())
        {
            if let Some((ta, tb)) = flush_pair((a, boxes[i]), (b, boxes[j]), geo, scale) {
                found.push([(i, ta), (j, tb)]);
            }
        }
    }
    found
}

/// Pairs (emitter shape, other shape) where a face of the other, not an emitter, lies on the
/// emitter's front within the rays' offset (`in_plane`): a panel held against a light, a box
/// standing on a light panel. [`lift_flush_emitters`] takes such a face for one the emitter
/// lies flush on and moves the emitter in front of it, so the other shape no longer shades the
/// light there, though a little farther off it would. Each pair once, with the distance within
/// which a face counts as in the emitter's plane.
pub(crate) fn facing_emitters(shapes: &[Shape], geo: &Geometry, scale: f32) -> Vec<(usize, usize, f32)> {
    let mut found = Vec::new();
    for (i, shape) in shapes.iter().enumerate().filter(|(_, s)| s.emitter.is_some()) {
        let (faces, m) = flush_faces(shape, geo, scale);
        for (o, n, d) in faces {
            let other = geo.tri_shape[o] as usize;
            // in front: facing the emitter (a plate against a light, a box's bottom on a light
            // panel) from anywhere on its front, else clearly beyond the rounding of a face
            // in its plane (a ceiling the light hangs from, facing the way it does)
            let faces_it = triangle_normal(corners(geo, o)).dot(n) < 0.0;
            let in_front = if faces_it { d <= 0.0 } else { d < -in_plane(m) / 4.0 };
            let pair = (i, other, in_plane(m));
            if in_front && d >= -in_plane(m) && shapes[other].emitter.is_none() && !found.contains(&pair) {
                found.push(pair);
            }
        }
    }
    found
}

/// Of a pair [`flush_emitters`] found (shape, triangle), the shape now in front along the
/// first triangle's normal, then the other.
pub(crate) fn front_of(geo: &Geometry, [(i, ti), (j, tj)]: [(usize, usize); 2]) -> (usize, usize) {
    let (a, b) = (corners(geo, ti), corners(geo, tj));
    match (b[0] - a[0]).dot(triangle_normal(a)) > 0.0 {
        true => (j, i),
        false => (i, j),
    }
}
