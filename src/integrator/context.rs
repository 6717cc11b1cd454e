//! Everything a render needs, prepared once: the Embree scene, per-triangle lookups, emitter
//! tables, temporal correlations and the camera.

use super::camera::CameraSampler;
use super::emitter_table::EmitterTable;
use super::opl_precision::OplPrecision;
use crate::accel::{Accel, BuildQuality, Device};
use crate::error::Error;
use crate::film::{SteadyMode, TileFilm};
use crate::params::lanes::Motion;
use crate::scene::Scene;
use crate::temporal::Correlation;

pub struct RenderContext<'a> {
    pub scene: &'a Scene,
    pub accel: Accel,
    /// World-space vertices of each triangle (one gather per lane instead of three).
    pub tri_verts: Vec<[glam::Vec3; 3]>,
    /// Material index of each triangle.
    pub tri_material: Vec<u32>,
    /// Emitter index of each triangle (`u32::MAX` where it emits nothing).
    pub tri_emitter: Vec<u32>,
    /// The side of each closed shape a camera ray may first meet (`super::entry`).
    pub entry: super::entry::EntrySides,
    pub emitters: EmitterTable,
    /// S_e of each emitter's pulse with the film's gate (supplemental Eq. 24).
    pub correlations: Vec<Correlation>,
    pub camera: CameraSampler,
    pub motion: Motion,
    /// Whether paths also carry their OPL in f64 (the film's time scale is too fine for f32).
    pub opl: OplPrecision,
    /// What the films' steady images integrate; [`SteadyMode::Full`] unless the render driver
    /// chooses the window.
    pub steady: SteadyMode,
    /// The window cut (`super::window`): the largest OPL a traced path may reach, `None` to
    /// trace every path to its end (set with [`Self::cut_to_window`]).
    pub opl_budget: Option<f32>,
    /// Where the emitters lie, for the path tracer's part of the window cut
    /// ([`super::window::EndBox`]); used only with a budget.
    pub emitter_box: Option<super::window::EndBox>,
    /// The pinhole as such a box, for BDPT's light subpaths and the boundary stage's sensor
    /// walks (`super::importance`); `None` when the film is unwarped (the camera's leg is
    /// then not counted).
    pub camera_box: Option<super::window::EndBox>,
    /// The relay-wall sensor and laser spots of an NLOS capture (`super::nlos`).
    pub nlos: Option<super::nlos::NlosSensor>,
    /// Whether every material is Lambertian (`Scene::diffuse_only`): the kernels then keep
    /// their diffuse-only path.
    pub diffuse_only: bool,
    /// Whether any material is one-sided (`NamedMaterial::one_sided`): only then do the
    /// kernels look for backs (`super::surface::behind_one_sided`).
    pub any_one_sided: bool,
    /// Draws on the time edges for the path tracer's time term (`super::time_edges`), when
    /// the render asked for them and they apply; set with [`Self::use_time_edges`].
    pub time_edges: Option<super::time_edges::TimeEdges>,
    /// Stops the render's loops when set (`crate::cancel`; never set unless the render's
    /// options hold a flag someone sets).
    pub cancel: crate::cancel::Cancel,
}

impl<'a> RenderContext<'a> {
    /// A context whose BVH has robust (watertight) traversal.
    pub fn new(scene: &'a Scene, device: &Device) -> Result<Self, Error> {
        Self::with_traversal(scene, device, true)
    }

    /// A context whose BVH is robust or not (see [`Accel::build_with`]).
    pub fn with_traversal(scene: &'a Scene, device: &Device, robust: bool) -> Result<Self, Error> {
        let geo = &scene.geometry;
        let positions: Vec<[f32; 3]> = geo.positions.iter().map(|p| p.to_array()).collect();
        let accel = Accel::build_with(device, &positions, &geo.indices, BuildQuality::High, robust)?;
        let tri_verts = geo
            .indices
            .iter()
            .map(|t| t.map(|i| geo.positions[i as usize]))
            .collect();
        let tri_material = geo
            .tri_shape
            .iter()
            .map(|&s| scene.shapes[s as usize].material)
            .collect();
        let tri_emitter = geo
            .tri_shape
            .iter()
            .map(|&s| scene.shapes[s as usize].emitter.unwrap_or(u32::MAX))
            .collect();
        let emitters = EmitterTable::new(scene, &accel)?;
        // a capture's paths start on the relay wall, not at the camera
        let entry = match scene.nlos {
            Some(_) => super::entry::EntrySides::default(),
            None => super::entry::EntrySides::new(geo, scene.shapes.len(), scene.camera.position),
        };
        let nlos = scene
            .nlos
            .as_ref()
            .map(|n| super::nlos::NlosSensor::new(scene, n, &accel))
            .transpose()?;
        let correlations = scene
            .emitters
            .iter()
            .map(|e| Correlation::new(scene.film.axis, e.pulse, e.offset_opl, scene.film.gate))
            .collect::<Result<Vec<_>, _>>()?;
        let camera = CameraSampler::new(&scene.camera, scene.film.width, scene.film.height, scene.film.filter);
        // each spot with the leg its beam adds: always for a scene's laser, for a scan's
        // laser points where the relay legs count (`emitters::sample_with`)
        let spot = |s: &super::emitter_table::LaserSpot, leg: bool| {
            (s.origin + s.direction * s.distance, if leg { s.distance } else { 0.0 })
        };
        let spots = (0..emitters.count())
            .filter_map(|e| emitters.laser_spot(e))
            .map(|s| spot(s, true))
            .chain(
                nlos.iter()
                    .flat_map(|n| n.spots.iter().flatten().map(|s| spot(s, n.laser_leg))),
            );
        let emitter_box = super::window::EndBox::new(scene, spots);
        // a light subpath ends at the pinhole, or in a capture at a sensor point (with the
        // wall's leg to the SPAD where it counts)
        let camera_box = match &nlos {
            Some(n) => super::window::EndBox::around(
                scene,
                n.sensors.iter().zip(&n.spad_leg).map(|(s, &leg)| (s.p, leg as f32)),
            ),
            None => (!scene.film.unwarp).then(|| super::window::EndBox::point(scene, scene.camera.position)),
        };
        Ok(Self {
            scene,
            accel,
            tri_verts,
            tri_material,
            tri_emitter,
            entry,
            emitters,
            correlations,
            camera,
            motion: Motion::none(),
            opl: OplPrecision::choose(scene),
            steady: SteadyMode::Full,
            opl_budget: None,
            emitter_box,
            camera_box,
            nlos,
            diffuse_only: scene.diffuse_only(),
            any_one_sided: scene.materials.iter().any(|m| m.one_sided),
            time_edges: None,
            cancel: crate::cancel::Cancel::new(),
        })
    }

    /// Unit geometric normal of triangle `prim` (the winding's front side; zero for a
    /// degenerate triangle).
    pub fn face_normal(&self, prim: u32) -> glam::Vec3 {
        crate::scene::triangle_normal(self.tri_verts[prim as usize])
    }

    /// [`Self::face_normal`] computed in f64 from the f32 vertices, for tests against
    /// distances of a few ε.
    pub fn face_normal64(&self, prim: u32) -> glam::DVec3 {
        let [p0, p1, p2] = self.tri_verts[prim as usize].map(|p| p.as_dvec3());
        (p1 - p0).cross(p2 - p0).normalize_or_zero()
    }

    /// Draws the path tracer's time term on the time edges where they apply to this
    /// render's parameters ([`Self::motion`], set first) and emitters.
    pub fn use_time_edges(&mut self) {
        self.time_edges = super::time_edges::TimeEdges::build(self.scene, &self.motion);
    }

    /// Steady images integrate the time window and paths end where they leave it
    /// ([`SteadyMode::Window`]), or every path is traced and counted ([`SteadyMode::Full`]).
    pub fn cut_to_window(&mut self, steady: SteadyMode) {
        self.steady = steady;
        self.opl_budget = match steady {
            SteadyMode::Window => super::window::opl_budget(&self.correlations),
            SteadyMode::Full => None,
        };
    }

    /// A tile film of this render (its steady image integrating [`Self::steady`]).
    pub fn tile_film(&self, x0: usize, y0: usize, w: usize, h: usize, derivs: usize) -> TileFilm {
        let f = &self.scene.film;
        TileFilm::new(x0, y0, w, h, &f.axis, f.channels, derivs).with_steady(self.steady)
    }
}
