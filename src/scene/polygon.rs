//! Polygon faces of OBJ and PLY meshes split into triangles.
//!
//! A convex polygon becomes a fan from its first corner (what most readers do, and what these
//! files were triangulated as before). A fan of a non-convex polygon (an L-, U- or T-shaped face,
//! common in CAD and architectural exports) covers area outside the polygon or covers some
//! twice, so such a polygon is projected onto the plane its normal is closest to and
//! ear-clipped (`earcutr`, a port of Mapbox's earcut). A polygon that still does not come out
//! as triangles covering exactly its own area (its edges cross each other) is refused with the
//! reason, for the caller to name the file and face.

use glam::{DVec2, DVec3};

/// Relative mismatch between the area of the triangles and of the polygon above which a
/// polygon is taken to cross itself.
const AREA_TOLERANCE: f64 = 1e-6;

/// The triangles of the polygon `corners` (in order around it), as positions into `corners`,
/// each wound as the polygon is. Fewer than 3 corners give no triangle.
pub fn triangulate(corners: &[DVec3]) -> Result<Vec<[usize; 3]>, String> {
    let n = corners.len();
    if n < 3 {
        return Ok(Vec::new());
    }
    let fan = || (1..n - 1).map(|k| [0, k, k + 1]).collect::<Vec<_>>();
    if n == 3 {
        return Ok(fan());
    }
    let normal = newell_normal(corners);
    if normal == DVec3::ZERO {
        // every corner on one line: zero area whatever the split (dropped later as degenerate)
        let (a, b) = (corners[0], corners[1]);
        if corners.iter().all(|&c| (b - a).cross(c - a) == DVec3::ZERO) {
            return Ok(fan());
        }
        return Err(format!(
            "its {n} corners do not bound one simple polygon (its edges cross each other, \
             enclosing no net area)"
        ));
    }
    let flat = project(corners, normal);
    if is_convex(&flat) {
        return Ok(fan());
    }
    let coords: Vec<f64> = flat.iter().flat_map(|p| [p.x, p.y]).collect();
    let idx = earcutr::earcut(&coords, &[], 2).map_err(|e| format!("cannot split it into triangles ({e:?})"))?;
    let mut covered = 0.0;
    let tris: Vec<[usize; 3]> = idx
        .chunks_exact(3)
        .map(|t| {
            let twice_area = (flat[t[1]] - flat[t[0]]).perp_dot(flat[t[2]] - flat[t[0]]);
            covered += 0.5 * twice_area.abs();
            // wound as the polygon: positive area in the projection
            if twice_area >= 0.0 {
                [t[0], t[1], t[2]]
            } else {
                [t[0], t[2], t[1]]
            }
        })
        .collect();
    let polygon_area = signed_area(&flat);
    if !((covered - polygon_area).abs() <= AREA_TOLERANCE * polygon_area.abs()) {
        return Err(format!(
            "its {n} corners do not bound one simple polygon (its edges cross each other): \
             triangles would cover {covered:.6} of its {polygon_area:.6} (projected area)"
        ));
    }
    Ok(tris)
}

/// Newell's normal (twice the vector area) of a polygon, zero for a degenerate one.
fn newell_normal(corners: &[DVec3]) -> DVec3 {
    let mut n = DVec3::ZERO;
    for (i, a) in corners.iter().enumerate() {
        let b = corners[(i + 1) % corners.len()];
        n += DVec3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    if n.length_squared() > 0.0 { n } else { DVec3::ZERO }
}

/// The corners in a 2D frame of the plane with normal `normal`, oriented so that the polygon
/// winds counter-clockwise (positive area).
fn project(corners: &[DVec3], normal: DVec3) -> Vec<DVec2> {
    let n = normal.normalize();
    let u = n.any_orthonormal_vector();
    let v = n.cross(u);
    corners.iter().map(|p| DVec2::new(p.dot(u), p.dot(v))).collect()
}

fn signed_area(p: &[DVec2]) -> f64 {
    (0..p.len()).map(|i| p[i].perp_dot(p[(i + 1) % p.len()])).sum::<f64>() * 0.5
}

/// Every turn of the (counter-clockwise) polygon is to the left or straight, and the turns add
/// up to one full turn (a star polygon turns left throughout but twice round).
fn is_convex(p: &[DVec2]) -> bool {
    let n = p.len();
    let mut turning = 0.0;
    for i in 0..n {
        let (a, b) = (p[(i + 1) % n] - p[i], p[(i + 2) % n] - p[(i + 1) % n]);
        let c = a.perp_dot(b);
        if c < 0.0 {
            return false;
        }
        turning += c.atan2(a.dot(b));
    }
    (turning - std::f64::consts::TAU).abs() < 1e-6
}

/// The area of triangles `tris` over `positions`, each asserted to face +z (the tests' faces
/// lie in z = 0, wound counter-clockwise).
#[cfg(test)]
pub(crate) fn area_facing_z(positions: &[DVec3], tris: &[[u32; 3]]) -> f64 {
    tris.iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            let n = (b - a).cross(c - a);
            assert!(n.z > 0.0, "{t:?} is not wound as its face (+z)");
            0.5 * n.length()
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area3(c: &[DVec3], tris: &[[usize; 3]]) -> f64 {
        tris.iter()
            .map(|t| 0.5 * (c[t[1]] - c[t[0]]).cross(c[t[2]] - c[t[0]]).length())
            .sum()
    }

    /// A U-shaped face 3 × 3 with a 1 × 2 notch (area 7), in the plane z = 0.5 x (tilted).
    fn u_shape() -> Vec<DVec3> {
        [(0, 0), (3, 0), (3, 3), (2, 3), (2, 1), (1, 1), (1, 3), (0, 3)]
            .map(|(x, y)| DVec3::new(x as f64, y as f64, 0.5 * x as f64))
            .to_vec()
    }

    #[test]
    fn a_convex_polygon_is_a_fan() {
        let quad = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
        assert_eq!(triangulate(&quad).unwrap(), vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn a_non_convex_polygon_is_covered_exactly_once() {
        let c = u_shape();
        let tris = triangulate(&c).unwrap();
        assert_eq!(tris.len(), 6);
        let scale = (1.0f64 + 0.25).sqrt(); // the tilt of z = 0.5 x
        assert!((area3(&c, &tris) - 7.0 * scale).abs() < 1e-9, "{}", area3(&c, &tris));
        // each triangle wound as the polygon (normal towards −x + z, like Newell's)
        let n = newell_normal(&c);
        for t in &tris {
            assert!((c[t[1]] - c[t[0]]).cross(c[t[2]] - c[t[0]]).dot(n) > 0.0, "{t:?}");
        }
        // the same corners the other way round: wound the other way
        let rev: Vec<DVec3> = c.iter().rev().copied().collect();
        let n = newell_normal(&rev);
        for t in triangulate(&rev).unwrap() {
            assert!((rev[t[1]] - rev[t[0]]).cross(rev[t[2]] - rev[t[0]]).dot(n) > 0.0);
        }
        // the fan from the first corner covers the notch and overlaps itself: its triangles
        // add up to 11 units (× the tilt) against the face's 7 (tobj's split before this module)
        let fan: Vec<[usize; 3]> = (1..c.len() - 1).map(|k| [0, k, k + 1]).collect();
        assert!(area3(&c, &fan) > 7.0 * scale + 0.1);
    }

    #[test]
    fn a_self_crossing_polygon_is_refused() {
        // a bow tie (no net area) and a pentagram (its centre enclosed twice)
        let bow = [DVec3::ZERO, DVec3::new(1.0, 1.0, 0.0), DVec3::X, DVec3::Y];
        let star: Vec<DVec3> = (0..5)
            .map(|k| {
                let a = std::f64::consts::TAU * (2 * k) as f64 / 5.0;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        for c in [&bow[..], &star[..]] {
            let e = triangulate(c).unwrap_err();
            assert!(e.contains("cross each other"), "{e}");
        }
        // corners on one line are left to the degenerate-triangle rule
        let line = [DVec3::ZERO, DVec3::X, DVec3::X * 2.0, DVec3::X * 3.0];
        assert_eq!(triangulate(&line).unwrap().len(), 2);
    }
}
