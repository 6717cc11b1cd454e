//! Objects that slide on what they rest on: said before a derivative render.
//!
//! A parameter that moves a shape along a surface it rests on (the Cornell box's tall box
//! moved along the floor) leaves the surface's path vertices where they are and moves the
//! shape's (material form, Algorithm 1). For a vertex on the support at distance a from the
//! plane of the shape's face near the contact line, and the next one on that face, the
//! geometry term's derivative gives the interior estimator a weight ∂log G/∂θ of order 1/a.
//! Its average over the directions that reach the face stays bounded (the two signs cancel),
//! but its magnitude does not: the probability of a weight above t falls only as 1/t, so the
//! estimator has no finite mean magnitude, and in practice its estimate is off at any sample
//! count. Measured: scenes/resting_cube_close.toml (the contact line across the image) gives
//! an interior of +495 ± 29 (256 seeds at 64 spp) where central differences less the primary
//! term leave about +1; a 0.3 m cube seen from 2.6 m came out 20 % short; with a gap of 1 mm
//! the full estimator matches (README, "An object sliding on its support"; BENCHMARKS.md, "The
//! Cornell rows"). The render says so, naming the parameter and the two shapes.

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
         near the contact line the interior derivative's weight grows as one over the distance to it, and its \
         estimate there is heavy-tailed and biased at any sample count (by 20 % on a cube seen from afar, by ten \
         times the derivative where the contact line fills the view); a gap of a millimetre between the two \
         removes it (README, \"An object sliding on its support\")",
        scene.source.display(),
        said.join("; ")
    ))
}
