//! Mitsuba's `near_clip` and `far_clip` against the converted scene. Mitsuba's camera rays
//! start at the near-clip plane and end at the far-clip plane (camera-space depths
//! `near_clip` and `far_clip`), so what lies nearer or farther is hidden from the camera.
//! Our camera clips nothing. Where no shape can lie in those hidden parts of the view the two
//! agree and the values are ignored; otherwise the scene is refused, naming the shape. Until
//! the forty-third session both were ignored without a word, and a sphere 1.2 m away
//! rendered under `near_clip` 2.5, where Mitsuba shows nothing (helper 39).

use crate::scene::{Scene, SceneError};
use glam::DVec3;
use std::path::Path;

/// The sensor's clip depths and its XML element (for messages).
#[derive(Clone, Debug)]
pub(crate) struct Clip {
    pub near: f64,
    pub far: f64,
    pub element: String,
}

impl Clip {
    /// Refuses `scene` (the conversion of `path`) where a shape may lie in the part of the view
    /// nearer than `near` or farther than `far`: within the distance from the camera at which
    /// the near plane meets the view's corners, or a vertex in front of the camera deeper than
    /// `far` (conservative: a shape beside the view counts too).
    pub fn check(&self, scene: &Scene, path: &Path) -> Result<(), SceneError> {
        let cam = &scene.camera;
        let (_, _, fwd) = cam.frame();
        let (eye, fwd) = (cam.position.as_dvec3(), fwd.as_dvec3());
        let ty = (0.5 * (cam.fov_y_deg as f64).to_radians()).tan();
        let tx = ty * scene.film.width as f64 / scene.film.height.max(1) as f64;
        // the distance from the eye to the view's corner ray at depth 1
        let corner = (1.0 + tx * tx + ty * ty).sqrt();
        let reach = self.near * corner;
        let geo = &scene.geometry;
        let shape_of = |tri: usize| {
            let s = geo.tri_shape[tri] as usize;
            scene
                .shapes
                .get(s)
                .map_or_else(|| format!("shape {s}"), |s| format!("shape {:?}", s.name))
        };
        let refuse = |message: String| SceneError::Invalid {
            path: path.to_path_buf(),
            at: self.element.clone(),
            message,
        };
        let mut deepest: Option<(f64, usize)> = None;
        for (t, tri) in geo.indices.iter().enumerate() {
            let [a, b, c] = tri.map(|i| geo.positions[i as usize].as_dvec3());
            let d = distance_to_triangle(eye, a, b, c);
            if d < reach {
                return Err(refuse(format!(
                    "near_clip {}: Mitsuba 3 hides from the camera what lies nearer than that along the view axis, and \
                     {} comes within {d:.6} m of the camera, where it may be hidden there and is seen here (this \
                     importer does not clip); set near_clip below {:.6} or move the camera",
                    self.near,
                    shape_of(t),
                    d / corner
                )));
            }
            let z = [a, b, c]
                .map(|v| (v - eye).dot(fwd))
                .into_iter()
                .fold(f64::MIN, f64::max);
            if deepest.is_none_or(|(best, _)| z > best) {
                deepest = Some((z, t));
            }
        }
        if let Some((z, t)) = deepest.filter(|&(z, _)| z > self.far) {
            return Err(refuse(format!(
                "far_clip {}: Mitsuba 3 hides from the camera what lies deeper than that along the view axis, and {} \
                 reaches {z:.3} m (this importer does not clip); set far_clip above {z:.3}",
                self.far,
                shape_of(t)
            )));
        }
        Ok(())
    }
}

/// The distance from `p` to triangle `abc` (the closest point by the triangle's Voronoi
/// regions: a vertex, an edge or the face; C. Ericson, Real-Time Collision Detection, 5.1.5).
fn distance_to_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
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
