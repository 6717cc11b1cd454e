//! Objects that slide on what they rest on: said before a derivative render.
//!
//! A parameter that moves a shape along a surface it rests on (the Cornell box's tall box
//! moved along the floor) leaves the surface's path vertices where they are and moves the
//! shape's (material form, Algorithm 1). For a vertex on the support at distance a from the
//! contact line and the next one on the shape, r apart, the geometry term's derivative gives
//! the interior estimator a weight ∂log G/∂θ of order 1/a; the second moment of that weight
//! grows as ∫ da/a², which diverges. The estimate stays unbiased, but its variance is
//! unbounded: it converges slowly and erratically, a few paths near the contact carrying
//! huge derivatives (BENCHMARKS.md, "The Cornell rows": the throughput term's variance 4.7 ×
//! 10⁴ resting, 539 with the box 1 mm above the floor, 87 at 1 cm). The render says so, naming
//! the parameter and the two shapes; a gap between them bounds the weight.

use super::lanes::Motion;
use crate::scene::{Scene, triangle_normal};
use glam::Vec3;

/// Relative tangential speed (against the larger of the two shapes' speeds there) above which
/// a contact slides.
const SLIDING: f32 = 1e-6;

/// The warning for the parameters of `motion` that slide a shape along one it rests on (or
/// nearly: `Scene::resting`), `None` when none does. Contacts along an edge or at a vertex
/// alone are not looked at.
pub(crate) fn sliding_warning(scene: &Scene, motion: &Motion) -> Option<String> {
    let geo = &scene.geometry;
    let mut said = Vec::new();
    let mut resting: Vec<Option<Vec<(usize, usize)>>> = vec![None; scene.shapes.len()];
    for k in 0..motion.len() {
        for &(shape, _) in &motion.fields[k] {
            let pairs = resting[shape].get_or_insert_with(|| scene.resting(shape));
            for &(other, tri) in pairs.iter() {
                let corners = geo.indices[tri].map(|i| geo.positions[i as usize]);
                let n = triangle_normal(corners);
                let centroid = (corners[0] + corners[1] + corners[2]) / 3.0;
                let slides = corners.iter().chain([&centroid]).any(|&p| {
                    let (a, b) = (motion.velocity(k, shape, p), motion.velocity(k, other, p));
                    let v = a - b;
                    let tangential: Vec3 = v - n * n.dot(v);
                    tangential.length() > SLIDING * a.length().max(b.length())
                });
                if slides {
                    said.push(format!(
                        "{} slides shape {:?} along shape {:?}",
                        motion.names[k], scene.shapes[shape].name, scene.shapes[other].name
                    ));
                }
            }
        }
    }
    if said.is_empty() {
        return None;
    }
    Some(format!(
        "{}: {}, which it rests on (parallel faces that overlap, in contact or closer than 2⁻¹⁴ of the scene's coordinates): \
         near the contact line the interior derivative's weight grows as one over the distance to it, so its \
         variance is unbounded. The mean is right, but it converges slowly, with rare huge samples; a gap of a \
         few millimetres between the two bounds it (README, \"An object sliding on its support\")",
        scene.source.display(),
        said.join("; ")
    ))
}
