//! Mitsuba's `near_clip` and `far_clip` against the converted scene. Mitsuba's camera rays
//! start at the near-clip plane and end at the far-clip plane (camera-space depths
//! `near_clip` and `far_clip`), so what lies nearer or farther is hidden from the camera.
//! Our camera clips nothing. Where no shape can lie in those hidden parts of the view the two
//! agree and the values are ignored; otherwise the scene is refused, naming the shape. Until
//! the forty-third session both were ignored without a word, and a sphere 1.2 m away
//! rendered under `near_clip` 2.5, where Mitsuba shows nothing (helper 39).

use super::super::surface_distance::distance_to_triangle;
use crate::scene::{Scene, SceneError};
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
