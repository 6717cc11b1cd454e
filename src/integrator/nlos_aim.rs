//! Aiming the first segment of an NLOS path at the hidden scene (`[nlos] hidden_sampling`,
//! `hidden_shapes`; `crate::scene::nlos::HiddenSampling`).
//!
//! From a sensor point s on the relay wall, a cosine-sampled direction finds a small hidden
//! object only in proportion to the solid angle it covers: a 30 cm box a metre from the wall
//! takes a few percent of the paths, and the rest light the capture only through the rest of
//! the scene. So the first vertex x₁ is drawn by one of two strategies, picked per path
//! (Veach's one-sample model, 1997 §9.2.4, with the balance heuristic):
//! - with probability 1 − α, a cosine-weighted direction about the wall's normal: density
//!   cos θ_s / π per steradian;
//! - with probability α, a point y drawn on the hidden shapes with density p_A(y) per unit
//!   area (triangles by weight, [`HiddenTargets::new`], uniform within each), the ray cast
//!   from s towards it. The draw counts only where y is the first surface that ray meets, so
//!   in area measure this strategy has density p_A at a point of the hidden shapes that s
//!   sees, and 0 elsewhere.
//!
//! Both in solid angle at the first hit x₁ at distance r:
//! p(ω) = (1 − α)·cos θ_s/π + α·p_A(x₁)·r²/|cos θ₁|, and the path's weight is
//! f_r·cos θ_s / p(ω) = ρ_s · (cos θ_s/π) / p(ω), which [`super::nlos_start::weigh_first_hit`] makes of the
//! cosine strategy's ρ_s. The density is a plain number: in the area-measure form of
//! Algorithm 1 (`super::path`), the derivative is that of f and of G·J along the path the
//! strategies sampled, whichever strategy it was. The kernel's side (the directions and the
//! weight at the first hit) is in `super::nlos_start`.
//!
//! Checking a derivative by finite differences through this sampling: the triangle weights
//! depend on the hidden shapes' pose, so with common random numbers an aimed sample slides
//! as θ changes and now and then jumps to another triangle. Its value is a sawtooth in θ
//! whose mean is flat (the estimate is unbiased at every θ), and a central difference with
//! small h sees the slide but almost never a jump. At a sensor point lit only by a static
//! shape among the targets, the derivative is 0 while such differences read −6·10⁻³ of the
//! value per degree in every seed (over 0–40°, 32 seeds, the slides summed to −3.4·10⁻⁶
//! and 18 jumps to +2.8·10⁻⁶). Compare with aiming off (`hidden_sampling = 0`), or aim
//! only at shapes the parameter does not move.

use super::emitter_table::{pick_and_rescale, uniform_in_triangle};
use crate::scene::Scene;
use crate::scene::nlos::{HiddenSampling, WallPoint};
use glam::DVec3;

/// The hidden shapes' triangles, each drawn with a weight, a point uniformly within it.
#[derive(Clone, Debug)]
pub struct HiddenTargets {
    /// Share of the paths aimed (α), in (0, 1).
    pub probability: f32,
    /// Triangle indices of the hidden shapes with a weight > 0.
    tris: Vec<u32>,
    /// Their cumulative weights (last ≈ 1).
    cdf: Vec<f32>,
    /// Density per unit area of the aimed points on each scene triangle (0 off the hidden
    /// shapes): the triangle's share of the weight over its area.
    pdf_area: Vec<f32>,
}

/// One path's aim, for the check at its first hit.
#[derive(Clone, Copy, Debug, Default)]
pub struct Aim {
    /// The lanes aimed (the rest were cosine-sampled).
    pub aimed: [bool; 8],
    /// Triangle of the aimed point.
    pub prim: [u32; 8],
    /// Distance from the sensor point to the aimed point.
    pub dist: [f32; 8],
}

/// Sensor points the triangle weights average over, at most.
const WEIGHT_SENSORS: usize = 64;

impl HiddenTargets {
    /// `None` when no path is aimed (α = 0, or nothing to aim at).
    ///
    /// A triangle's weight is its area times the mean over (up to [`WEIGHT_SENSORS`] of) the
    /// sensor points of G(s, c)², G = cos θ_s·cos θ_c / r² from sensor point s to the
    /// triangle's centroid c. The light a hidden point returns to a confocal scan goes out and
    /// back over the same segment, so it scales as G², and cosine sampling already draws
    /// points in proportion to G alone: the aimed paths go where the second factor is large
    /// (near, facing surfaces), not to large shapes seen at grazing angles. Triangles no
    /// sensor point faces get no aimed paths (the cosine-sampled ones still find them).
    pub fn new(scene: &Scene, hidden: &HiddenSampling, sensors: &[WallPoint]) -> Option<Self> {
        if hidden.probability <= 0.0 || sensors.is_empty() {
            return None;
        }
        let geo = &scene.geometry;
        let step = sensors.len().div_ceil(WEIGHT_SENSORS);
        let from: Vec<(DVec3, DVec3)> = sensors
            .iter()
            .step_by(step)
            .map(|s| (s.p.as_dvec3(), s.n.as_dvec3()))
            .collect();
        let mut tris = Vec::new();
        let mut weights = Vec::new();
        for &s in &hidden.shapes {
            let shape = &scene.shapes[s as usize];
            for t in shape.first_tri..shape.first_tri + shape.tri_count {
                let [a, b, c] = geo.indices[t as usize].map(|i| geo.positions[i as usize].as_dvec3());
                let cross = (b - a).cross(c - a);
                let area = 0.5 * cross.length();
                if !(area > 0.0) {
                    continue;
                }
                let (n_t, centre) = (cross / (2.0 * area), (a + b + c) / 3.0);
                let g2: f64 = from
                    .iter()
                    .map(|(p, n)| {
                        let d = centre - *p;
                        let r2 = d.length_squared();
                        let w = d / r2.sqrt();
                        let g = n.dot(w).max(0.0) * n_t.dot(w).abs() / r2;
                        if g.is_finite() { g * g } else { 0.0 }
                    })
                    .sum::<f64>()
                    / from.len() as f64;
                if area * g2 > 0.0 {
                    tris.push(t);
                    weights.push((area * g2, area));
                }
            }
        }
        let total: f64 = weights.iter().map(|w| w.0).sum();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let mut pdf_area = vec![0.0f32; geo.indices.len()];
        let mut acc = 0.0;
        let mut cdf = Vec::with_capacity(tris.len());
        for (&t, &(w, area)) in tris.iter().zip(&weights) {
            acc += w;
            cdf.push((acc / total) as f32);
            pdf_area[t as usize] = (w / total / area) as f32;
        }
        Some(Self {
            probability: hidden.probability,
            tris,
            cdf,
            pdf_area,
        })
    }

    /// A point from two numbers in [0, 1): `u0` picks the triangle by weight and is rescaled
    /// within its share, then the point is uniform on it. Returns (triangle, barycentrics).
    pub fn draw(&self, u0: f32, u1: f32) -> (u32, f32, f32) {
        let (k, ua) = pick_and_rescale(&self.cdf, u0);
        let (u, v) = uniform_in_triangle(ua, u1);
        (self.tris[k], u, v)
    }

    /// Density per unit area of the aimed points on scene triangle `t` (0 off the hidden
    /// shapes).
    pub fn pdf_area(&self, t: u32) -> f32 {
        self.pdf_area.get(t as usize).copied().unwrap_or(0.0)
    }

    /// The first direction's density per steradian at the sensor point, the mixture of the
    /// two strategies (module docs): p(ω) = (1 − α)·`p_cos` + α·p_A(x₁)·r²/|cos θ₁|, for a
    /// first hit x₁ on triangle `t` at distance² `r2` with |cos θ₁| = `cos_1`. The aimed
    /// strategy has no density where the hit is off the hidden shapes or seen edge-on.
    pub fn mixture_pdf(&self, p_cos: f32, t: u32, r2: f32, cos_1: f32) -> f32 {
        let p_a = self.pdf_area(t);
        let p_aim = if p_a > 0.0 && cos_1 > 0.0 {
            p_a * r2 / cos_1
        } else {
            0.0
        };
        (1.0 - self.probability) * p_cos + self.probability * p_aim
    }
}
