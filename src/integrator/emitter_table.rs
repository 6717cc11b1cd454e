//! Emitter tables, built once per render from the scene: what next-event estimation samples,
//! and the pdf and radiance of an area emitter that a path hits.
//!
//! Emitters are chosen uniformly; an area emitter then picks a triangle by area (its CDF is
//! here) and a point uniformly on it. A laser is a delta in position and direction: it lights
//! one spot, found here once per render (one ray), which then radiates like a small Lambertian
//! source (I(ω) = Φ · albedo/π · cos θ), the usual NLOS treatment. The tables need only the
//! scene and the BVH, so the render context can hold one; sampling them, which rebuilds points
//! through that context, is in `emitters.rs`.

use crate::accel::Accel;
use crate::scene::{EmitterKind, Material, Scene};
use glam::Vec3;

/// Largest area emitter (in triangles) whose triangle is picked by the first number of the
/// point it samples (`EmitterTable::sample`, in `emitters.rs`): its rescaled remainder keeps
/// at least 14 of the number's 24 bits for the point on a triangle of average area.
pub const REUSE_MAX_TRIANGLES: usize = 1024;

/// The spot a laser lights.
#[derive(Clone, Debug)]
pub struct LaserSpot {
    pub prim: u32,
    pub u: f32,
    pub v: f32,
    /// Geometric distance from the laser to the spot.
    pub distance: f32,
    /// Φ · albedo / π (W·sr⁻¹ per unit cos θ).
    pub intensity: [f32; 3],
    /// ∂intensity/∂Φ = albedo / π, per channel.
    pub intensity_per_power: [f32; 3],
    /// +1 if the triangle's winding normal faces the laser, else -1 (the lit side).
    pub side: f32,
    /// The laser's position and unit direction.
    pub origin: Vec3,
    pub direction: Vec3,
}

/// The spot a laser at `position` aimed along `direction` lights: the first surface its beam
/// meets (`None` if it meets nothing), radiating Φ·albedo/π·cos θ.
pub fn laser_spot(
    scene: &Scene,
    accel: &Accel,
    position: Vec3,
    direction: Vec3,
    power: [f32; 3],
) -> Result<Option<LaserSpot>, String> {
    let Some(h) = accel.intersect1(position.to_array(), direction.to_array(), 0.0, f32::INFINITY) else {
        return Ok(None);
    };
    let distance = h.t * direction.length();
    spot_at(scene, (h.prim, h.u, h.v), distance, position, direction, power)
}

/// The spot of a beam from `position` along `direction` that lands `distance` away at
/// barycentrics (u, v) of triangle `prim`, given as `(prim, u, v)`: an error unless that
/// triangle is diffuse, and `None` (a spot that lights nothing) where the beam meets a
/// one-sided material from behind.
pub fn spot_at(
    scene: &Scene,
    (prim, u, v): (u32, f32, f32),
    distance: f32,
    position: Vec3,
    direction: Vec3,
    power: [f32; 3],
) -> Result<Option<LaserSpot>, String> {
    let geo = &scene.geometry;
    let mat = scene.shapes[geo.tri_shape[prim as usize] as usize].material;
    let material = &scene.materials[mat as usize];
    let Material::Diffuse { albedo } = material.material else {
        return Err(format!(
            "its spot lands on material {:?} of type {}; a laser's spot must be on a diffuse surface",
            material.name,
            material.material.type_name()
        ));
    };
    let [a, b, c] = geo.indices[prim as usize].map(|i| geo.positions[i as usize]);
    let side = if (b - a).cross(c - a).dot(direction) < 0.0 {
        1.0
    } else {
        -1.0
    };
    if scene.behind_one_sided(prim, -direction) {
        return Ok(None);
    }
    Ok(Some(LaserSpot {
        side,
        origin: position,
        direction: direction.normalize(),
        prim,
        u,
        v,
        distance,
        intensity: std::array::from_fn(|c| power[c] * albedo[c] * std::f32::consts::FRAC_1_PI),
        intensity_per_power: albedo.map(|a| a * std::f32::consts::FRAC_1_PI),
    }))
}

/// One emitter as the sampler sees it (`emitters.rs` reads the variants).
#[derive(Clone, Debug)]
pub(super) enum Entry {
    Area {
        tris: Vec<u32>,
        cdf: Vec<f32>,
        area: f32,
        radiance: [f32; 3],
    },
    Point {
        position: Vec3,
        intensity: [f32; 3],
    },
    Laser {
        spot: Option<LaserSpot>,
    },
}

/// Per-emitter sampling data. [`EmitterTable::sample`], which rebuilds the sampled points
/// through the render context, is in `emitters.rs`.
#[derive(Clone, Debug)]
pub struct EmitterTable {
    pub(super) entries: Vec<Entry>,
    /// Whether the point's first number also chooses the emitter (`EmitterTable::sample`):
    /// with several emitters, each of whose triangles, shares of `1/n` of the unit interval,
    /// still leave the point enough bits.
    pub(super) by_point: bool,
}

impl EmitterTable {
    /// The tables of `scene`'s emitters; a laser whose spot lands on a material that is not
    /// diffuse is refused (its spot is a Lambertian secondary source). A capture's laser has
    /// no spot of its own here: the scan's spots are `NlosSensor::spots`.
    pub fn new(scene: &Scene, accel: &Accel) -> Result<Self, crate::error::Error> {
        let geo = &scene.geometry;
        let entries = scene
            .emitters
            .iter()
            .enumerate()
            .map(|(index, e)| match &e.kind {
                EmitterKind::Area { shape, radiance } => {
                    let s = &scene.shapes[*shape as usize];
                    let tris: Vec<u32> = (s.first_tri..s.first_tri + s.tri_count).collect();
                    let mut cdf = Vec::with_capacity(tris.len());
                    let mut acc = 0.0f64;
                    for &t in &tris {
                        let [a, b, c] = geo.indices[t as usize].map(|i| geo.positions[i as usize]);
                        acc += 0.5 * (b - a).cross(c - a).length() as f64;
                        cdf.push(acc as f32);
                    }
                    let area = acc as f32;
                    cdf.iter_mut().for_each(|c| *c /= area.max(1e-30));
                    Ok(Entry::Area {
                        tris,
                        cdf,
                        area,
                        radiance: *radiance,
                    })
                }
                EmitterKind::Point { position, intensity } => Ok(Entry::Point {
                    position: *position,
                    intensity: *intensity,
                }),
                // a capture aims its laser at each laser point (`super::nlos`): its own
                // direction lights nothing
                EmitterKind::Laser { .. } if scene.nlos.as_ref().is_some_and(|n| n.laser as usize == index) => {
                    Ok(Entry::Laser { spot: None })
                }
                EmitterKind::Laser {
                    position,
                    direction,
                    power,
                } => {
                    let spot = laser_spot(scene, accel, *position, *direction, *power).map_err(|why| {
                        crate::error::Error::Invalid(format!(
                            "{}: emitter {:?} (laser): {why}",
                            scene.source.display(),
                            e.name
                        ))
                    })?;
                    Ok(Entry::Laser { spot })
                }
            })
            .collect::<Result<Vec<_>, crate::error::Error>>()?;
        let n_e = entries.len();
        let by_point = n_e > 1
            && entries.iter().all(|e| match e {
                Entry::Area { tris, .. } => tris.len() * n_e <= REUSE_MAX_TRIANGLES,
                _ => true,
            });
        Ok(Self { entries, by_point })
    }

    pub fn count(&self) -> usize {
        self.entries.len()
    }

    /// Area pdf (with selection) of emitter `e` sampling a point on its surface.
    #[inline]
    pub fn area_pdf(&self, e: u32) -> f32 {
        match self.entries.get(e as usize) {
            Some(Entry::Area { area, .. }) if *area > 0.0 => 1.0 / (*area * self.entries.len() as f32),
            _ => 0.0,
        }
    }

    /// The spot laser `e` lights (None: not a laser, or its beam hits nothing).
    pub fn laser_spot(&self, e: usize) -> Option<&LaserSpot> {
        match self.entries.get(e) {
            Some(Entry::Laser { spot }) => spot.as_ref(),
            _ => None,
        }
    }

    /// Radiance of area emitter `e` (0 for others).
    #[inline]
    pub fn radiance(&self, e: u32) -> [f32; 3] {
        match self.entries.get(e as usize) {
            Some(Entry::Area { radiance, .. }) => *radiance,
            _ => [0.0; 3],
        }
    }
}

/// The index of the cdf entry (cumulative shares, last ≈ 1) that `u` ∈ [0, 1) falls in, and
/// `u` rescaled to [0, 1) within it.
pub(super) fn pick_and_rescale(cdf: &[f32], u: f32) -> (usize, f32) {
    let k = cdf.partition_point(|&c| c <= u).min(cdf.len() - 1);
    let lo = if k == 0 { 0.0 } else { cdf[k - 1] };
    let share = cdf[k] - lo;
    let rest = if share > 0.0 { (u - lo) / share } else { 0.5 };
    (k, rest.clamp(0.0, 1.0 - f32::EPSILON))
}

/// Barycentrics (u, v) of a point uniform on a triangle, from two numbers in [0, 1) (the
/// square-root warp: u0 sets the distance from the first vertex, u1 the side).
pub(super) fn uniform_in_triangle(u0: f32, u1: f32) -> (f32, f32) {
    let s = u0.sqrt();
    (s * (1.0 - u1), s * u1)
}
