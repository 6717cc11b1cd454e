//! The NLOS sensor: points on a relay wall seen by a SPAD, and the laser spots of the scan
//! (the scene's `[nlos]`, `crate::scene::nlos`), in the form the path kernel uses.
//!
//! Sensor point s measures the radiance the wall sends from s towards the SPAD,
//! L_o(s → SPAD) = ∫ f_r(s) L_i(s, ω) |cos θ| dω with the wall's diffuse f_r = ρ_s/π: its
//! importance is f_r × cos, a delta in position at s. The kernel starts each lane's path at its
//! sensor point with a cosine-sampled direction about the wall's normal, so the path's weight
//! starts at f_r·cos/pdf = ρ_s (`nlos_start.rs`), or, for a share of the paths, with a
//! direction aimed at a point on the hidden shapes (`nlos_aim.rs`); it ends by next-event estimation at
//! the laser spots: the lane's own spot (confocal) or every laser point in turn (exhaustive),
//! each a point source I(θ) = Φ·ρ/π·cos θ (`emitter_table::laser_spot`). One traced path thus
//! serves every laser point of an exhaustive scan.
//!
//! BDPT renders captures with the same two ends, one path per film cell (an exhaustive scan's
//! cells are (sensor, laser) pairs): camera subpaths from the sensor point, light subpaths
//! from the laser point (`super::bdpt::walk`, `super::bdpt::sensor`).
//!
//! Film points: (x, y) = the sensor grid cell (confocal), or (sensor index, laser index)
//! (exhaustive). The time of flight counts the hidden legs always, and the laser-to-spot and
//! wall-to-SPAD legs with `relay_legs = "included"`.
//!
//! [`NlosSensor::project`] is the sensor's projection for connections that end at the sensor
//! (the boundary stage's draws that end at a sensor point), as `CameraSampler::project` is the
//! pinhole's: a scene point → (sensor index, importance, squared distance); the importance
//! walk's packets use its lane form (`super::importance`).

use super::emitter_table::{LaserSpot, laser_spot, spot_at};
use crate::accel::Accel;
use crate::scene::{EmitterKind, Material, NlosSpec, RelayLegs, Scene, WallPoint};
use glam::Vec3;

/// A connection from a scene point to one sensor point.
#[derive(Clone, Copy, Debug)]
pub struct SensorProjection {
    /// Index of the sensor point.
    pub index: usize,
    /// f_r(s)·|cos θ_s| towards the point per channel (RGB; per steradian at s, for radiance
    /// towards the SPAD).
    pub importance: [f32; 3],
    /// Squared distance from the sensor point.
    pub dist2: f32,
    /// Unit direction from the sensor point to the scene point.
    pub dir: Vec3,
}

/// The spot the laser at `position` lights when the scan aims it at wall point `l`: `l` itself
/// (its triangle and barycentrics, so its normal) when nothing stands in the beam up to just
/// short of it, else the first surface the beam meets.
///
/// The beam's hit on the wall is not used: where `l` lies on an edge two wall triangles share
/// (every grid point of a wall meshed along the grid's lines does), the ray meets both at the
/// same distance and the BVH's traversal order picks one. That order changes with geometry
/// elsewhere in the scene, so the spot's normal, hence its light (I ∝ cos θ to the normal),
/// would jump as an unrelated shape moves, and the spot could take another normal than the
/// sensor point at the same place. The wall point is the scene's own resolution of `l`.
fn scan_spot(
    scene: &Scene,
    accel: &Accel,
    position: Vec3,
    l: &WallPoint,
    power: [f32; 3],
) -> Result<Option<LaserSpot>, String> {
    let to = l.p - position;
    let len = to.length();
    let dir = to / len;
    if !clear_to_wall(accel, position, l.p) {
        return laser_spot(scene, accel, position, dir, power)
            .map_err(|why| format!("the beam is stopped before the wall: {why}"));
    }
    spot_at(scene, (l.prim, l.u, l.v), len, position, dir, power)
        .map_err(|why| format!("the beam reaches the wall: {why}"))
}

/// Whether nothing stands between `from` (a point on no surface: the SPAD, a laser) and wall
/// point `p`, up to just short of it (so the wall's own surface does not count).
fn clear_to_wall(accel: &Accel, from: Vec3, p: Vec3) -> bool {
    let to = p - from;
    let len = to.length();
    !accel.occluded1(from.to_array(), (to / len).to_array(), 0.0, len * (1.0 - 1e-5))
}

/// The scan as the kernel sees it. Built once per render.
#[derive(Clone, Debug)]
pub struct NlosSensor {
    /// The laser emitter (its pulse and S_e are the scan's).
    pub laser: u32,
    pub exhaustive: bool,
    /// Sensor grid width (confocal film x = ix, y = iy).
    pub nx: usize,
    pub sensors: Vec<WallPoint>,
    /// ρ of the wall at each sensor point, RGB.
    pub albedo: Vec<[f32; 3]>,
    /// Whether the SPAD sees each sensor point (an occluder between them makes it read 0).
    pub seen: Vec<bool>,
    /// Wall-to-SPAD length per sensor point when it is counted, else 0 (f64).
    pub spad_leg: Vec<f64>,
    /// The spot each laser point lights (`None`: the beam meets nothing).
    pub spots: Vec<Option<LaserSpot>>,
    /// Whether the laser-to-spot length counts in the time of flight.
    pub laser_leg: bool,
    /// The hidden shapes the first segments aim at (`super::nlos_aim`), if any.
    pub hidden: Option<super::nlos_aim::HiddenTargets>,
}

impl NlosSensor {
    pub fn new(scene: &Scene, spec: &NlosSpec, accel: &Accel) -> Result<Self, crate::error::Error> {
        let spad = scene.camera.position;
        let EmitterKind::Laser { position, power, .. } = scene.emitters[spec.laser as usize].kind else {
            unreachable!("scene::nlos checks that the scan's emitter is a laser")
        };
        let included = spec.relay_legs == RelayLegs::Included;
        let sensors = spec.sensors.points.clone();
        let albedo = sensors
            .iter()
            .map(|s| {
                let shape = scene.geometry.tri_shape[s.prim as usize] as usize;
                match scene.materials[scene.shapes[shape].material as usize].material {
                    Material::Diffuse { albedo } => albedo,
                    // the scene refuses relay walls that are not diffuse (scene/nlos.rs)
                    _ => [0.0; 3],
                }
            })
            .collect();
        // (a one-sided wall seen from behind is black there)
        let seen = sensors
            .iter()
            .map(|s| clear_to_wall(accel, spad, s.p) && !scene.behind_one_sided(s.prim, spad - s.p))
            .collect();
        let spad_leg = sensors
            .iter()
            .map(|s| {
                if included {
                    (spad.as_dvec3() - s.p.as_dvec3()).length()
                } else {
                    0.0
                }
            })
            .collect();
        let spots = spec
            .lasers
            .points
            .iter()
            .enumerate()
            .map(|(k, l)| {
                scan_spot(scene, accel, position, l, power).map_err(|why| {
                    let [x, y, z] = l.p.to_array();
                    crate::error::Error::Invalid(format!(
                        "{}: [nlos] laser: aimed at laser point {k} of {} ([{x:.4}, {y:.4}, {z:.4}]), {why}",
                        scene.source.display(),
                        spec.lasers.points.len(),
                    ))
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            laser: spec.laser,
            exhaustive: spec.exhaustive(),
            nx: spec.sensors.nx,
            sensors,
            albedo,
            seen,
            spad_leg,
            spots,
            laser_leg: included,
            hidden: super::nlos_aim::HiddenTargets::new(scene, &spec.hidden, &spec.sensors.points),
        })
    }

    /// The sensor point of film pixel (x, y): the grid cell (confocal) or column x (exhaustive).
    #[inline]
    pub fn sensor_of(&self, x: u32, y: u32) -> usize {
        if self.exhaustive {
            x as usize
        } else {
            y as usize * self.nx + x as usize
        }
    }

    /// Laser points each sensor path connects to: the lane's own (confocal) or all of them.
    pub fn laser_points(&self) -> usize {
        if self.exhaustive { self.spots.len() } else { 1 }
    }

    /// The projection of scene point `x` onto sensor point `i` (visibility not tested).
    pub fn project(&self, i: usize, x: Vec3) -> Option<SensorProjection> {
        let s = self.sensors.get(i)?;
        if !self.seen[i] {
            return None;
        }
        let d = x - s.p;
        let dist2 = d.length_squared();
        let dir = d / dist2.sqrt();
        let cos = s.n.dot(dir);
        if !(dist2 > 0.0 && cos > 0.0) {
            return None;
        }
        let rho = self.albedo[i];
        Some(SensorProjection {
            index: i,
            importance: rho.map(|r| r * std::f32::consts::FRAC_1_PI * cos),
            dist2,
            dir,
        })
    }
}
