//! Scenes made in code: [`SceneBuilder`] assembles the description a scene file holds, table
//! by table ([`Entry`]), and resolves it through the same path as a file: the same schema
//! (`scenes/README.md`), the same checks and the same messages, with the builder's label in
//! place of the file name. A builder scene and a file with the same values are the same scene
//! (and render the same bytes); [`Scene::set_params`] works on both.

use super::described::Described;
use super::{Scene, SceneError};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// One table of a scene description: `[camera]`, `[film]`, `[integrator]`, `[medium]`,
/// `[nlos]`, an entry of `[[material]]`, `[[shape]]`, `[[emitter]]` or `[[param]]`, or a
/// nested table such as a pulse. Fields and values are those of the scene file
/// (`scenes/README.md`); [`Entry::set`] sets any of them, the constructors the required ones.
#[derive(Clone, Debug, Default, Serialize)]
#[serde(transparent)]
pub struct Entry {
    table: toml::Table,
    /// (field, why) of values that could not be turned into a description value, reported
    /// by [`SceneBuilder::build`].
    #[serde(skip)]
    refused: Vec<(String, String)>,
}

impl Entry {
    /// An empty table (every field at its default).
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets `field` to `value`: a number, a string, a bool, an array of them (`[0.5, 0.5,
    /// 0.5]`) or a nested [`Entry`]. Checked when the scene is built, as a file's field is.
    pub fn set(mut self, field: &str, value: impl Serialize) -> Self {
        match toml::Value::try_from(value) {
            Ok(v) => {
                self.table.insert(field.to_string(), v);
            }
            Err(e) => self.refused.push((field.to_string(), e.to_string())),
        }
        self
    }

    /// A named entry of `type` `ty` (`name` and `type` set).
    pub fn named(name: &str, ty: &str) -> Self {
        Self::new().set("name", name).set("type", ty)
    }

    /// `[camera]` at `position` looking at `look_at` (world metres).
    pub fn camera(position: [f64; 3], look_at: [f64; 3]) -> Self {
        Self::new().set("position", position).set("look_at", look_at)
    }

    /// `[film]` of `bins` bins of `bin_width_opl` metres of optical path length.
    pub fn film(bin_width_opl: f64, bins: i64) -> Self {
        Self::new().set("bin_width_opl", bin_width_opl).set("bins", bins)
    }

    /// A `diffuse` material of albedo `albedo` (a number or three).
    pub fn diffuse(name: &str, albedo: impl Serialize) -> Self {
        Self::named(name, "diffuse").set("albedo", albedo)
    }

    /// A shape of type `ty` (`rectangle`, `cube`, `sphere`, `obj`, `ply`) made of `material`.
    pub fn shape(name: &str, ty: &str, material: &str) -> Self {
        Self::named(name, ty).set("material", material)
    }

    /// A `rectangle` shape ([-1, 1]² in the XY plane, normal +Z) made of `material`.
    pub fn rectangle(name: &str, material: &str) -> Self {
        Self::shape(name, "rectangle", material)
    }

    /// A `cube` shape ([-1, 1]³) made of `material`.
    pub fn cube(name: &str, material: &str) -> Self {
        Self::shape(name, "cube", material)
    }

    /// A `sphere` shape (unit icosphere) made of `material`.
    pub fn sphere(name: &str, material: &str) -> Self {
        Self::shape(name, "sphere", material)
    }

    /// A mesh shape read from `file` (`.obj` or `.ply` by its extension, any other as OBJ),
    /// relative to [`SceneBuilder::base_dir`], made of `material`.
    pub fn mesh(name: &str, file: &str, material: &str) -> Self {
        let ply = Path::new(file)
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("ply"));
        Self::shape(name, if ply { "ply" } else { "obj" }, material).set("file", file)
    }

    /// Sets a shape's `translate` (world metres).
    pub fn translate(self, t: [f64; 3]) -> Self {
        self.set("translate", t)
    }

    /// Sets a shape's `rotate` (degrees about X, Y, Z, applied X first).
    pub fn rotate(self, degrees: [f64; 3]) -> Self {
        self.set("rotate", degrees)
    }

    /// Sets a shape's `scale` (a factor or three).
    pub fn scale(self, s: impl Serialize) -> Self {
        self.set("scale", s)
    }

    /// An `area` emitter on shape `shape` with radiance `radiance` (W·sr⁻¹·m⁻², one or three).
    pub fn area(name: &str, shape: &str, radiance: impl Serialize) -> Self {
        Self::named(name, "area").set("shape", shape).set("radiance", radiance)
    }

    /// A `point` emitter at `position` with intensity `intensity` (W·sr⁻¹, one or three).
    pub fn point(name: &str, position: [f64; 3], intensity: impl Serialize) -> Self {
        Self::named(name, "point")
            .set("position", position)
            .set("intensity", intensity)
    }

    /// A `[[param]]` named `name` of kind `kind` (`translate`, `albedo`, `eta`, ...) with
    /// value `value`; its target (`shape`, `axis`, `material`, `emitter`, `channel`) is set
    /// with [`Entry::set`].
    pub fn param(name: &str, kind: &str, value: f64) -> Self {
        Self::new().set("name", name).set("kind", kind).set("value", value)
    }
}

/// Builds a [`Scene`] in code, table by table, as a scene file would describe it.
///
/// ```
/// use difftransient::scene::{Entry, SceneBuilder};
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// let scene = SceneBuilder::new()
///     .camera(Entry::camera([0.0, 1.0, 3.0], [0.0, 0.0, 0.0]).set("resolution", [16, 16]))
///     .film(Entry::film(0.05, 100).set("start_opl", 2.0))
///     .material(Entry::diffuse("white", 0.8))
///     .shape(Entry::rectangle("floor", "white").rotate([-90.0, 0.0, 0.0]))
///     .emitter(Entry::point("lamp", [0.0, 1.0, 1.0], 5.0))
///     .param(Entry::param("floor_y", "translate", 0.0).set("shape", "floor").set("axis", "y"))
///     .build()?;
/// assert_eq!(scene.geometry.indices.len(), 2);
/// assert_eq!((scene.film.width, scene.film.height), (16, 16));
///
/// // The same checks and messages as a scene file:
/// let err = SceneBuilder::new()
///     .camera(Entry::camera([0.0, 1.0, 3.0], [0.0, 0.0, 0.0]))
///     .film(Entry::film(0.05, 100))
///     .material(Entry::diffuse("white", 1.5))
///     .build()
///     .unwrap_err();
/// assert!(err.to_string().contains("material[0] \"white\": field 'albedo'"), "{err}");
/// # Ok(())
/// # }
/// ```
#[derive(Clone, Debug)]
pub struct SceneBuilder {
    table: toml::Table,
    /// (location, why) of the values entries refused.
    refused: Vec<(String, String)>,
    base_dir: PathBuf,
}

impl Default for SceneBuilder {
    fn default() -> Self {
        Self::new()
    }
}

/// What messages call a built scene, and the file name its mesh paths are relative to.
const LABEL: &str = "<scene builder>";

impl SceneBuilder {
    /// An empty description; mesh files are looked up relative to the current directory.
    pub fn new() -> Self {
        Self {
            table: toml::Table::new(),
            refused: Vec::new(),
            base_dir: PathBuf::new(),
        }
    }

    /// The folder relative mesh `file`s are looked up in.
    pub fn base_dir(mut self, dir: impl Into<PathBuf>) -> Self {
        self.base_dir = dir.into();
        self
    }

    /// Sets table `key` (`camera`, `film`, `integrator`, `medium`, `nlos`) to `entry`.
    pub fn table(mut self, key: &str, entry: Entry) -> Self {
        let at = |f: &str| super::error::table_field(key, f);
        self.refused
            .extend(entry.refused.iter().map(|(f, why)| (at(f), why.clone())));
        self.table.insert(key.to_string(), toml::Value::Table(entry.table));
        self
    }

    /// Appends `entry` to the array of entries `key` (`material`, `shape`, `emitter`, `param`).
    pub fn push(mut self, key: &str, entry: Entry) -> Self {
        let list = self
            .table
            .entry(key.to_string())
            .or_insert_with(|| toml::Value::Array(Vec::new()));
        if let toml::Value::Array(list) = list {
            let (i, name) = (
                list.len(),
                entry.table.get("name").and_then(|n| n.as_str()).unwrap_or(""),
            );
            let at = |f: &str| super::error::item_field(key, i, name, f);
            self.refused
                .extend(entry.refused.iter().map(|(f, why)| (at(f), why.clone())));
            list.push(toml::Value::Table(entry.table));
        }
        self
    }

    /// The `[camera]` (see [`Entry::camera`]).
    pub fn camera(self, entry: Entry) -> Self {
        self.table("camera", entry)
    }

    /// The `[film]` (see [`Entry::film`]).
    pub fn film(self, entry: Entry) -> Self {
        self.table("film", entry)
    }

    /// The `[integrator]` (estimator, bounces, spp, seed).
    pub fn integrator(self, entry: Entry) -> Self {
        self.table("integrator", entry)
    }

    /// The refractive index `eta` of the medium (`[medium]`).
    pub fn eta(self, eta: f64) -> Self {
        self.table("medium", Entry::new().set("eta", eta))
    }

    /// Adds a `[[material]]` (see [`Entry::diffuse`], [`Entry::named`]).
    pub fn material(self, entry: Entry) -> Self {
        self.push("material", entry)
    }

    /// Adds a `[[shape]]` (see [`Entry::rectangle`], [`Entry::cube`], [`Entry::sphere`],
    /// [`Entry::mesh`]).
    pub fn shape(self, entry: Entry) -> Self {
        self.push("shape", entry)
    }

    /// Adds an `[[emitter]]` (see [`Entry::area`], [`Entry::point`]).
    pub fn emitter(self, entry: Entry) -> Self {
        self.push("emitter", entry)
    }

    /// Adds a `[[param]]` (see [`Entry::param`]).
    pub fn param(self, entry: Entry) -> Self {
        self.push("param", entry)
    }

    /// Checks and resolves the description into a [`Scene`], exactly as a scene file with
    /// these tables is loaded; errors name the entry and field as they would in a file.
    pub fn build(self) -> Result<Scene, SceneError> {
        let source = self.base_dir.join(LABEL);
        if let Some((at, message)) = self.refused.into_iter().next() {
            return Err(SceneError::Invalid {
                path: source,
                at,
                message,
            });
        }
        let raw = super::load::toml_tree(&toml::Value::Table(self.table), &source)?;
        let desc = super::load::desc_from_tree(&raw, &source, &[])?;
        let described = Described {
            raw: Arc::new(raw),
            fields: Vec::new(),
            desc,
            params: Vec::new(),
            meshes: None,
        };
        super::resolve::resolve(described, &source)
    }
}
