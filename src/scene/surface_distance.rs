//! How far a point lies from the scene's surfaces, and the camera refused where that is less
//! than the rays' offset.
//!
//! A pinhole within the rays' offset ε of a surface (2⁻¹⁸ of the coordinates,
//! `integrator::surface::self_intersection_eps`) is on neither side of it as far as rays can
//! tell: a connection to the camera stops ε short of it and so passes a wall the camera sits
//! on, while the camera's own rays start beyond it. With the camera of scenes/diff_room.toml
//! set on the room's wall (z = 3, or 3.0000001, outside, which rounds onto it) the path
//! tracer rendered black and BDPT a faint image through the wall on 164 of 256 pixels, with
//! no word (an independent sweep, 2026-12-02). The load now refuses such a camera, naming the
//! shape and the distance.

use super::Geometry;
use glam::{DVec3, Vec3};

/// The distance from `p` to triangle `abc` (the closest point by the triangle's Voronoi
/// regions: a vertex, an edge or the face; C. Ericson, Real-Time Collision Detection, 5.1.5).
pub(crate) fn distance_to_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (p - (a + ab * (d1 / (d1 - d3)))).length();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (p - (a + ac * (d2 / (d2 - d6)))).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return (p - (b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))))).length();
    }
    let denom = 1.0 / (va + vb + vc);
    if !denom.is_finite() {
        // a degenerate triangle: its nearest vertex
        return ap.length().min(bp.length()).min(cp.length());
    }
    (p - (a + ab * (vb * denom) + ac * (vc * denom))).length()
}

/// The triangle of `geo` nearest to `p` among those closer than `within`, with its distance.
pub(crate) fn nearest_within(geo: &Geometry, p: Vec3, within: f64) -> Option<(usize, f64)> {
    let q = p.as_dvec3();
    let mut best: Option<(usize, f64)> = None;
    for (t, tri) in geo.indices.iter().enumerate() {
        let [a, b, c] = tri.map(|i| geo.positions[i as usize].as_dvec3());
        // a box test first: most triangles are far
        let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
        let outside = (lo - q).max(q - hi).max(DVec3::ZERO);
        if outside.length() >= within {
            continue;
        }
        let d = distance_to_triangle(q, a, b, c);
        if d < within && best.is_none_or(|(_, e)| d < e) {
            best = Some((t, d));
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_to_a_triangle_from_each_region() {
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        let d = |p: DVec3| distance_to_triangle(p, a, b, c);
        assert!((d(DVec3::new(0.25, 0.25, 2.0)) - 2.0).abs() < 1e-12, "face");
        assert!((d(DVec3::new(-1.0, -1.0, 0.0)) - 2f64.sqrt()).abs() < 1e-12, "vertex a");
        assert!((d(DVec3::new(2.0, 0.0, 0.0)) - 1.0).abs() < 1e-12, "vertex b");
        assert!((d(DVec3::new(0.0, 3.0, 0.0)) - 2.0).abs() < 1e-12, "vertex c");
        assert!((d(DVec3::new(0.5, -1.0, 0.0)) - 1.0).abs() < 1e-12, "edge ab");
        assert!((d(DVec3::new(-2.0, 0.5, 0.0)) - 2.0).abs() < 1e-12, "edge ac");
        assert!((d(DVec3::new(1.0, 1.0, 0.0)) - 0.5f64.sqrt()).abs() < 1e-12, "edge bc");
        assert!(d(DVec3::new(0.2, 0.2, 0.0)).abs() < 1e-12, "on the face");
        // a random check against a fine sampling of the triangle
        let p = DVec3::new(0.9, -0.3, 0.4);
        let mut best = f64::MAX;
        for i in 0..=400 {
            for j in 0..=(400 - i) {
                let q = a + (b - a) * (i as f64 / 400.0) + (c - a) * (j as f64 / 400.0);
                best = best.min((p - q).length());
            }
        }
        assert!((d(p) - best).abs() < 2e-3 && d(p) <= best + 1e-12, "{} vs {best}", d(p));
    }
}
