//! Scenes: what is rendered, resolved from a description file into flat arrays.
//!
//! Loading (`load.rs`) turns `scenes/*.toml` (or the same schema as JSON) into a [`Scene`]:
//! parameters are applied first (their values override the description), then shapes are
//! built in local space and transformed to world space. The integrator sees only world-space
//! triangles plus, per shape, its transform, from which a parameter's velocity field is derived.

mod builder;
pub use builder::{Entry, SceneBuilder};
mod camera;
pub use camera::{Camera, PixelFilter};
mod camera_film;
pub(crate) mod context;
pub(crate) mod desc;
mod described;
mod emitters;
pub(crate) mod error;
pub(crate) mod f32_value;
pub(crate) mod field_set;
mod flush;
#[doc(hidden)]
pub mod fuzzing;
mod info;
pub mod limits;
pub(crate) mod load;
mod materials;
pub mod mitsuba;
pub mod nlos;
mod set_params;
mod state;
pub use desc::{NlosScan, RelayLegs};
pub use nlos::{NlosSpec, NoiseSpec, WallGrid, WallPoint};
pub use state::SceneState;
mod origin;
pub mod ply;
pub(crate) mod polygon;
mod read;
pub(crate) use read::{MAX_SCENE_BYTES, read_regular_file};
mod resolve;
pub mod shapes;
mod surface_distance;
#[cfg(test)]
pub(crate) mod testutil;
pub(crate) mod warnings;
pub use crate::params::{Axis, Param, ParamKind};
pub use error::SceneError;
pub use load::Format;

use crate::temporal::{Gate, Pulse, TimeAxis};
use glam::{DMat3, Mat3, Vec3};
use std::path::PathBuf;

/// A shape's transform: `x_world = translate + R · (scale ∘ x_local)`, where
/// `R = Rz · Ry · Rx` from `rotate_deg` (degrees about the world axes, X applied first).
/// Rotation and scale pivot on the shape's local origin. `translate` is relative to
/// [`Scene::render_origin`], like every position of a loaded scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Translation in metres (after rotation and scale).
    pub translate: Vec3,
    /// Rotation angles about the world X, Y and Z axes, in degrees, applied X first.
    pub rotate_deg: Vec3,
    /// Per-axis scale factors, applied first (component-wise, in local space).
    pub scale: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Self {
            translate: Vec3::ZERO,
            rotate_deg: Vec3::ZERO,
            scale: Vec3::ONE,
        }
    }
}

impl Transform {
    /// The rotation matrix `R = Rz · Ry · Rx` of [`Self::rotate_deg`].
    pub fn rotation(&self) -> Mat3 {
        let r = self.rotate_deg * (std::f32::consts::PI / 180.0);
        Mat3::from_rotation_z(r.z) * Mat3::from_rotation_y(r.y) * Mat3::from_rotation_x(r.x)
    }
    /// Maps a local point to world: `translate + R · (scale ∘ p)`.
    pub fn apply(&self, p: Vec3) -> Vec3 {
        self.translate + self.rotation() * (self.scale * p)
    }
    /// [`Self::rotation`] in f64 (the loader builds world vertices in f64).
    pub fn rotation_f64(&self) -> DMat3 {
        let r = self.rotate_deg.as_dvec3() * (std::f64::consts::PI / 180.0);
        DMat3::from_rotation_z(r.z) * DMat3::from_rotation_y(r.y) * DMat3::from_rotation_x(r.x)
    }
}

/// One named shape after loading: its triangles occupy `first_tri .. first_tri + tri_count`
/// of [`Geometry`], and its vertices `first_vertex .. first_vertex + vertex_count`.
#[derive(Clone, Debug)]
pub struct Shape {
    /// The shape's `name` in the scene file (unique; parameters and messages refer to it).
    pub name: String,
    /// Local-to-world transform, with parameters applied.
    pub transform: Transform,
    /// Vertex positions before the transform, rounded to f32 (the world vertices are built
    /// from the f64 local mesh; see `origin.rs`).
    pub local_positions: Vec<Vec3>,
    /// Index of the shape's first vertex in [`Geometry::positions`].
    pub first_vertex: u32,
    /// Number of vertices of the shape.
    pub vertex_count: u32,
    /// Index of the shape's first triangle in [`Geometry::indices`].
    pub first_tri: u32,
    /// Number of triangles of the shape (after dropping degenerate ones).
    pub tri_count: u32,
    /// Index into [`Scene::materials`].
    pub material: u32,
    /// Index into [`Scene::emitters`] if the shape is an area emitter.
    pub emitter: Option<u32>,
}

/// All triangles of the scene in world space, as handed to Embree.
#[derive(Clone, Debug, Default)]
pub struct Geometry {
    /// World-space vertex positions, metres relative to [`Scene::render_origin`].
    pub positions: Vec<Vec3>,
    /// Vertex indices of each triangle into `positions`; the winding gives the geometric
    /// normal `(p1 − p0) × (p2 − p0)` (the front side).
    pub indices: Vec<[u32; 3]>,
    /// Shape index of each triangle.
    pub tri_shape: Vec<u32>,
    /// Triangles of exactly zero area left out while loading (see `shapes.rs`).
    pub dropped_degenerate: usize,
}

/// Surface reflectance, evaluated, sampled and given a pdf by `integrator::bsdf`.
#[derive(Clone, Debug, PartialEq)]
pub enum Material {
    /// Lambertian: f = albedo / π. Mono albedos are stored as three equal channels.
    Diffuse {
        /// Reflectance per channel, in [0, 1].
        albedo: [f32; 3],
    },
    /// GGX microfacet conductor of roughness α (0: a smooth mirror, a Dirac lobe), reflecting
    /// `specular` times the Fresnel term of the complex index `ior` = (η, κ) per channel, or
    /// times 1 without one.
    Conductor {
        /// GGX roughness α (≥ 0; 0 is a smooth mirror).
        roughness: f32,
        /// Reflectance scale per channel, in [0, 1].
        specular: [f32; 3],
        /// Complex index of refraction (η, κ) per channel; `None` for a Fresnel term of 1.
        ior: Option<([f32; 3], [f32; 3])>,
    },
    /// GGX microfacet dielectric of roughness α (0: smooth, Dirac lobes) with index `int_ior`
    /// on the side the shape's normals point away from; on the other side is the interior of
    /// material `exterior` (a dielectric), or the scene's medium (`[medium] eta`) when `None`.
    Dielectric {
        /// GGX roughness α (≥ 0; 0 is smooth).
        roughness: f32,
        /// Refractive index of the interior (the side the normals point away from).
        int_ior: f32,
        /// Index into [`Scene::materials`] of the dielectric whose interior surrounds this
        /// one; `None` for the scene's medium.
        exterior: Option<u32>,
    },
}

impl Material {
    /// The albedo of a diffuse material, a conductor's specular reflectance, 1 for a dielectric.
    pub fn tint(&self) -> [f32; 3] {
        match *self {
            Material::Diffuse { albedo } => albedo,
            Material::Conductor { specular, .. } => specular,
            Material::Dielectric { .. } => [1.0; 3],
        }
    }

    /// Whether this is a Lambertian material.
    pub fn is_diffuse(&self) -> bool {
        matches!(self, Material::Diffuse { .. })
    }

    /// Whether its lobe is a Dirac delta (a smooth conductor or dielectric).
    pub fn is_delta(&self) -> bool {
        match *self {
            Material::Diffuse { .. } => false,
            Material::Conductor { roughness, .. } | Material::Dielectric { roughness, .. } => roughness == 0.0,
        }
    }

    /// A short name for messages: "diffuse", "roughconductor", "dielectric", ...
    pub fn type_name(&self) -> &'static str {
        match (self, self.is_delta()) {
            (Material::Diffuse { .. }, _) => "diffuse",
            (Material::Conductor { .. }, false) => "roughconductor",
            (Material::Conductor { .. }, true) => "conductor",
            (Material::Dielectric { .. }, false) => "roughdielectric",
            (Material::Dielectric { .. }, true) => "dielectric",
        }
    }
}

/// A `[[material]]` of the scene file: its name and what it is.
#[derive(Clone, Debug)]
pub struct NamedMaterial {
    /// The material's `name` in the scene file (shapes refer to it).
    pub name: String,
    /// The reflectance model and its values.
    pub material: Material,
    /// Black from behind (the side the triangles' normals point away from), as a Mitsuba BSDF
    /// without `twosided`: a path that meets it there ends. Diffuse and conductors only.
    pub one_sided: bool,
}

/// Emission in space; its time profile is in [`Emitter::pulse`].
#[derive(Clone, Debug, PartialEq)]
pub enum EmitterKind {
    /// One-sided (front = geometric normal side) diffuse emitter covering a shape. Where the
    /// shape is coplanar with another surface it overlaps, the emitting face wins: the loader
    /// moves it a tiny distance off that surface towards its front (`flush.rs`).
    /// Radiance in W·sr⁻¹·m⁻².
    Area {
        /// Index into [`Scene::shapes`] of the emitting shape.
        shape: u32,
        /// Radiance per channel, W·sr⁻¹·m⁻².
        radiance: [f32; 3],
    },
    /// Isotropic point light with intensity in W·sr⁻¹.
    Point {
        /// Position in metres, relative to [`Scene::render_origin`].
        position: Vec3,
        /// Intensity per channel, W·sr⁻¹.
        intensity: [f32; 3],
    },
    /// A laser beam (delta position and direction) with power in W. The spot it lights is
    /// connected to by next-event estimation (the usual NLOS set-up).
    Laser {
        /// Where the beam starts, metres relative to [`Scene::render_origin`].
        position: Vec3,
        /// Unit direction of the beam.
        direction: Vec3,
        /// Power per channel, W.
        power: [f32; 3],
    },
}

/// One light source: where and how it emits ([`EmitterKind`]) and when ([`Pulse`]).
#[derive(Clone, Debug)]
pub struct Emitter {
    /// The emitter's `name` in the scene file.
    pub name: String,
    /// Its spatial emission.
    pub kind: EmitterKind,
    /// Temporal profile of the emission (unit area).
    pub pulse: Pulse,
    /// Emission time offset, in OPL metres (τ of supplemental Eq. 24), f64 from the scene
    /// file to S_e.
    pub offset_opl: f64,
}

/// The transient film: time axis, gate, channels, and whether the camera segment is counted.
#[derive(Clone, Debug)]
pub struct FilmSpec {
    /// Width in pixels (for an NLOS capture, from [`NlosSpec::film_size`]).
    pub width: u32,
    /// Height in pixels (for an NLOS capture, from [`NlosSpec::film_size`]).
    pub height: u32,
    /// The time bins, in metres of OPL.
    pub axis: TimeAxis,
    /// The sensor gate of each bin.
    pub gate: Gate,
    /// 1 (mono) or 3 (RGB).
    pub channels: usize,
    /// Leave out the camera-to-first-hit distance from the OPL ("unwarped" / confocal NLOS
    /// convention).
    pub unwarp: bool,
    /// Pixel reconstruction filter.
    pub filter: PixelFilter,
}

/// Which estimator renders the interior integral.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum IntegratorKind {
    /// Unidirectional path tracing with next-event estimation and MIS (the default).
    Path,
    /// Bidirectional path tracing with MIS over every (s, t) strategy (Algorithm 1;
    /// `integrator::bdpt`).
    Bdpt,
}

impl IntegratorKind {
    /// The name used in scene files, the JSON and `--integrator`.
    pub fn name(self) -> &'static str {
        match self {
            IntegratorKind::Path => "path",
            IntegratorKind::Bdpt => "bdpt",
        }
    }

    /// The estimator called `name` (`dtr render --integrator`, Python's
    /// `Scene.with_integrator`), or a message naming the ones there are.
    pub fn from_name(name: &str) -> Result<Self, String> {
        [IntegratorKind::Path, IntegratorKind::Bdpt]
            .into_iter()
            .find(|k| k.name() == name)
            .ok_or_else(|| format!("unknown integrator {name:?}: expected \"path\" or \"bdpt\""))
    }
}

/// The scene's `[integrator]`: estimator, path length and sampling defaults.
#[derive(Clone, Debug)]
pub struct IntegratorSpec {
    /// Which estimator renders the interior integral.
    pub kind: IntegratorKind,
    /// Maximum number of scattering events (1 = direct illumination only).
    pub max_bounces: u32,
    /// Samples per pixel (≥ 1), the default when [`crate::RenderOptions::spp`] is `None`.
    pub spp: u32,
    /// Random seed, the default when [`crate::RenderOptions::seed`] is `None`.
    pub seed: u64,
    /// Russian roulette starts after this many bounces (None = off).
    pub rr_depth: Option<u32>,
    /// The numbers paths draw: independent (the default) or Owen-scrambled Sobol points
    /// stratified over each pixel's samples (`[integrator] sampler`).
    pub sampler: crate::kernel::SampleSequence,
}

/// A loaded scene. Everything the renderer needs, with parameters already applied.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The file it came from (for messages).
    pub source: PathBuf,
    /// Every file the scene was read from: the scene file and the OBJ meshes it names. No
    /// output may replace one of them (`cli::output_set`).
    pub inputs: Vec<PathBuf>,
    /// Every shape, in file order; a shape's index is its position here.
    pub shapes: Vec<Shape>,
    /// All world-space triangles.
    pub geometry: Geometry,
    /// Every material, in file order.
    pub materials: Vec<NamedMaterial>,
    /// Every emitter, in file order (`[[emitter]]`).
    pub emitters: Vec<Emitter>,
    /// The sensor (for an NLOS capture, its position is the SPAD's).
    pub camera: Camera,
    /// The transient film.
    pub film: FilmSpec,
    /// Refractive index of the medium: OPL = η × geometric length.
    pub eta: f32,
    /// Estimator and sampling defaults.
    pub integrator: IntegratorSpec,
    /// The differentiable parameters (`[[param]]`), with the values applied to this scene.
    pub params: Vec<Param>,
    /// Where the renderer's f32 world sits in the file's coordinates: every position in this
    /// struct (geometry, transforms, camera, emitters) is the file's position minus this
    /// origin, subtracted in f64 (`origin.rs`). OPL does not depend on it.
    pub render_origin: [f64; 3],
    /// The least coordinate magnitude the offsets off surfaces are scaled to: 1 m, or less
    /// for a scene smaller than that (`origin::offset_scale`).
    pub offset_scale: f32,
    /// Area-emitter shapes that lay flush on another surface and were moved off it towards
    /// their emitting side (`flush.rs`: the emitting face wins).
    pub lifted_emitters: Vec<String>,
    /// A relay-wall capture (`[nlos]`, `nlos.rs`): the film is then the capture's grid and the
    /// camera position is the SPAD's.
    pub nlos: Option<NlosSpec>,
    /// The description this scene was resolved from, its overrides and its meshes, from
    /// which [`Scene::set_params`] resolves the scene again without reading any file.
    pub(crate) described: std::sync::Arc<described::Described>,
}

/// Unit geometric normal of the triangle with corners `c` (the winding's front side; zero
/// for a degenerate triangle).
pub fn triangle_normal(c: [Vec3; 3]) -> Vec3 {
    (c[1] - c[0]).cross(c[2] - c[0]).normalize_or_zero()
}

impl Scene {
    /// World coordinates of a position stored relative to [`Scene::render_origin`].
    pub fn to_world(&self, p: glam::DVec3) -> glam::DVec3 {
        p + glam::DVec3::from_array(self.render_origin)
    }

    /// Refractive index outside dielectric material `m`: the interior of its `exterior`
    /// material, or the scene's medium (also for a material that is not a dielectric).
    pub fn exterior_eta(&self, m: u32) -> f32 {
        match self.materials[m as usize].material {
            Material::Dielectric { exterior: Some(e), .. } => match self.materials[e as usize].material {
                Material::Dielectric { int_ior, .. } => int_ior,
                _ => self.eta,
            },
            _ => self.eta,
        }
    }

    /// Another shape that shape `shape` lies flush on (faces in one plane, facing the same
    /// way, that overlap: `flush.rs`), whatever the two materials: a ray meets one or the
    /// other by rounding, so moving either has no derivative.
    pub fn flush_partner(&self, shape: usize) -> Option<usize> {
        flush::flush_partner(&self.shapes, &self.geometry, &self.materials, self.offset_scale, shape)
    }

    /// The shapes that `shape` rests on, or that rest on it: (other shape, a triangle of
    /// `shape`'s in contact), parallel faces less than half the emitter lift apart
    /// (`flush::resting`).
    pub fn resting(&self, shape: usize) -> Vec<(usize, usize)> {
        flush::resting(&self.shapes, &self.geometry, self.offset_scale, shape)
    }

    /// Whether triangle `prim`'s material is one-sided ([`NamedMaterial::one_sided`]) and
    /// `towards` (a direction from its surface) points to its back, where it is black.
    pub fn behind_one_sided(&self, prim: u32, towards: Vec3) -> bool {
        let shape = &self.shapes[self.geometry.tri_shape[prim as usize] as usize];
        let [a, b, c] = self.geometry.indices[prim as usize].map(|i| self.geometry.positions[i as usize]);
        self.materials[shape.material as usize].one_sided && (b - a).cross(c - a).dot(towards) < 0.0
    }

    /// Whether every material is Lambertian (the kernels then keep their diffuse-only path).
    pub fn diffuse_only(&self) -> bool {
        self.materials.iter().all(|m| m.material.is_diffuse())
    }

    /// Whether material `m`'s lobe is a Dirac delta in this scene: a smooth conductor or
    /// dielectric, or a rough dielectric whose index equals the one outside it. Index-matched,
    /// every microfacet refracts straight through, so the rough lobe (its width goes as
    /// |η' − 1|) collapses onto −ω_o; the kernels render it as a smooth interface that passes
    /// what the rough lobe passes in that limit (Smith's G1 of ω_o, `Lobes::sample`).
    pub fn is_dirac(&self, m: u32) -> bool {
        match self.materials[m as usize].material {
            Material::Dielectric { int_ior, .. } if int_ior == self.exterior_eta(m) => true,
            ref other => other.is_delta(),
        }
    }

    /// The index of the first material whose lobe is a Dirac delta in this scene
    /// ([`Self::is_dirac`]).
    pub fn first_delta_material(&self) -> Option<u32> {
        (0..self.materials.len() as u32).find(|&m| self.is_dirac(m))
    }
}
