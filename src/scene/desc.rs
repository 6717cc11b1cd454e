//! The scene file schema as serde structs, mirroring `scenes/README.md` one to one.
//!
//! These hold what the file says, before any check beyond types: ranges, references and
//! combinations are checked when the description is resolved into a [`super::Scene`].
//! Every table denies unknown fields. Counts are read as `i64` so that a negative or zero
//! value gets a range message ("must be at least 1") rather than a type error.

use super::IntegratorKind;
use serde::Deserialize;
use serde::de::{self, Deserializer, MapAccess, SeqAccess, Visitor};
use std::fmt;

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    #[serde(default)]
    pub integrator: IntegratorDesc,
    #[serde(default)]
    pub medium: MediumDesc,
    pub camera: CameraDesc,
    pub film: FilmDesc,
    #[serde(default)]
    pub material: Vec<MaterialDesc>,
    #[serde(default)]
    pub shape: Vec<ShapeDesc>,
    #[serde(default)]
    pub emitter: Vec<EmitterDesc>,
    #[serde(default)]
    pub param: Vec<ParamDesc>,
    /// A relay-wall capture (`[nlos]`, see the NLOS section at the end of this file).
    pub nlos: Option<NlosDesc>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct IntegratorDesc {
    pub kind: IntegratorKind,
    pub max_bounces: i64,
    pub spp: i64,
    pub seed: u64,
    pub rr_depth: Option<i64>,
    pub sampler: SamplerName,
}

/// `[integrator] sampler`.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum SamplerName {
    Independent,
    #[default]
    Sobol,
}

impl Default for IntegratorDesc {
    fn default() -> Self {
        Self {
            kind: IntegratorKind::Path,
            max_bounces: 8,
            spp: 16,
            seed: 0,
            rr_depth: None,
            sampler: SamplerName::Sobol,
        }
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MediumDesc {
    pub eta: f32,
}

impl Default for MediumDesc {
    fn default() -> Self {
        Self { eta: 1.0 }
    }
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}
fn default_fov() -> f32 {
    40.0
}
fn default_resolution() -> [i64; 2] {
    [64, 64]
}
fn default_box<T>() -> NameOr<T> {
    NameOr::Name("box".to_string())
}
fn default_delta<T>() -> NameOr<T> {
    NameOr::Name("delta".to_string())
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    /// World coordinates are read as f64 and made relative to the render origin before
    /// they become f32 (see `super::origin`).
    #[serde(deserialize_with = "exact::array")]
    pub position: [f64; 3],
    #[serde(deserialize_with = "exact::array")]
    pub look_at: [f64; 3],
    #[serde(default = "default_up", deserialize_with = "exact::array")]
    pub up: [f32; 3],
    #[serde(default = "default_fov")]
    pub fov: f32,
    #[serde(default = "default_resolution", deserialize_with = "exact::array")]
    pub resolution: [i64; 2],
    #[serde(default = "default_box")]
    pub filter: NameOr<FilterTable>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FilterType {
    Box,
    Tent,
    Gaussian,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FilterTable {
    #[serde(rename = "type")]
    pub ty: FilterType,
    pub radius: Option<f32>,
    pub sigma: Option<f32>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Channels {
    Mono,
    Rgb,
    Auto,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FilmDesc {
    #[serde(default)]
    pub start_opl: f64,
    pub bin_width_opl: f64,
    pub bins: i64,
    #[serde(default = "default_box")]
    pub gate: NameOr<GateTable>,
    #[serde(default = "default_channels")]
    pub channels: Channels,
    #[serde(default)]
    pub unwarp: bool,
}

fn default_channels() -> Channels {
    Channels::Auto
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GateType {
    Box,
    Gaussian,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GateTable {
    #[serde(rename = "type")]
    pub ty: GateType,
    pub sigma_opl: Option<f32>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MaterialType {
    Diffuse,
    Roughconductor,
    Conductor,
    Roughdielectric,
    Dielectric,
}

impl MaterialType {
    pub fn as_str(self) -> &'static str {
        match self {
            MaterialType::Diffuse => "diffuse",
            MaterialType::Roughconductor => "roughconductor",
            MaterialType::Conductor => "conductor",
            MaterialType::Roughdielectric => "roughdielectric",
            MaterialType::Dielectric => "dielectric",
        }
    }

    /// The fields a material of this type takes besides `name` and `type`.
    pub fn fields(self) -> &'static [&'static str] {
        match self {
            MaterialType::Diffuse => &["albedo", "one_sided"],
            MaterialType::Roughconductor => &["roughness", "specular_reflectance", "eta", "k", "one_sided"],
            MaterialType::Conductor => &["specular_reflectance", "eta", "k", "one_sided"],
            MaterialType::Roughdielectric => &["roughness", "int_ior", "exterior"],
            MaterialType::Dielectric => &["int_ior", "exterior"],
        }
    }

    pub fn is_dielectric(self) -> bool {
        matches!(self, MaterialType::Roughdielectric | MaterialType::Dielectric)
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialDesc {
    pub name: String,
    #[serde(rename = "type")]
    pub ty: MaterialType,
    /// diffuse: albedo in [0, 1]
    pub albedo: Option<Triple>,
    /// rough types: GGX α in [10⁻⁶, 1] (`limits::MIN_ROUGHNESS`)
    pub roughness: Option<f32>,
    /// conductors: reflectance multiplier in [0, 1] (default 1)
    pub specular_reflectance: Option<Triple>,
    /// conductors: complex index η + iκ per channel (both or neither; without them F = 1)
    pub eta: Option<Triple>,
    pub k: Option<Triple>,
    /// dielectrics: refractive index inside (on the side the normals point away from)
    pub int_ior: Option<f32>,
    /// dielectrics: the dielectric material whose interior lies outside this one (default:
    /// the scene's medium)
    pub exterior: Option<String>,
    /// diffuse and conductors: black from behind (default false: both sides reflect)
    pub one_sided: Option<bool>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ShapeType {
    Rectangle,
    Cube,
    Sphere,
    Obj,
    Ply,
}

impl ShapeType {
    pub fn as_str(self) -> &'static str {
        match self {
            ShapeType::Rectangle => "rectangle",
            ShapeType::Cube => "cube",
            ShapeType::Sphere => "sphere",
            ShapeType::Obj => "obj",
            ShapeType::Ply => "ply",
        }
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeDesc {
    pub name: String,
    #[serde(rename = "type")]
    pub ty: ShapeType,
    pub material: Option<String>,
    /// f64, like every world position (see `super::origin`).
    #[serde(default, deserialize_with = "exact::option_array")]
    pub translate: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "exact::option_array")]
    pub rotate: Option<[f32; 3]>,
    pub scale: Option<Triple>,
    /// sphere only
    pub subdivisions: Option<i64>,
    /// obj only
    pub file: Option<String>,
    /// Reverse every triangle's winding: the front side (where an area emitter shines and a
    /// one-sided material reflects) becomes the other one. Not on dielectrics.
    pub flip_normals: Option<bool>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EmitterType {
    Area,
    Point,
    Laser,
}

impl EmitterType {
    pub fn as_str(self) -> &'static str {
        match self {
            EmitterType::Area => "area",
            EmitterType::Point => "point",
            EmitterType::Laser => "laser",
        }
    }
    /// The field holding the emitted amount for this type.
    pub fn amount_field(self) -> &'static str {
        match self {
            EmitterType::Area => "radiance",
            EmitterType::Point => "intensity",
            EmitterType::Laser => "power",
        }
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EmitterDesc {
    pub name: String,
    #[serde(rename = "type")]
    pub ty: EmitterType,
    /// area
    pub shape: Option<String>,
    pub radiance: Option<Triple>,
    /// point, laser (f64, like every world position)
    #[serde(default, deserialize_with = "exact::option_array")]
    pub position: Option<[f64; 3]>,
    pub intensity: Option<Triple>,
    /// laser
    #[serde(default, deserialize_with = "exact::option_array")]
    pub direction: Option<[f32; 3]>,
    pub power: Option<Triple>,
    #[serde(default = "default_delta")]
    pub pulse: NameOr<PulseTable>,
    /// f64 like the time axis: an f32 would round 1.0000000495 to 1.0.
    #[serde(default)]
    pub offset_opl: f64,
}

impl EmitterDesc {
    /// The emitted amount (radiance, intensity or power, by type).
    pub fn amount(&self) -> Option<Triple> {
        match self.ty {
            EmitterType::Area => self.radiance,
            EmitterType::Point => self.intensity,
            EmitterType::Laser => self.power,
        }
    }
    /// The emitted amount (radiance, intensity or power, by type).
    pub fn amount_mut(&mut self) -> &mut Option<Triple> {
        match self.ty {
            EmitterType::Area => &mut self.radiance,
            EmitterType::Point => &mut self.intensity,
            EmitterType::Laser => &mut self.power,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PulseType {
    Delta,
    Gaussian,
    Box,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PulseTable {
    #[serde(rename = "type")]
    pub ty: PulseType,
    pub sigma_opl: Option<f32>,
    pub width_opl: Option<f32>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ParamKindDesc {
    Translate,
    Rotate,
    Scale,
    Albedo,
    Radiance,
    Eta,
    PulseOffset,
    Roughness,
    Ior,
}

impl ParamKindDesc {
    pub fn as_str(self) -> &'static str {
        match self {
            ParamKindDesc::Translate => "translate",
            ParamKindDesc::Rotate => "rotate",
            ParamKindDesc::Scale => "scale",
            ParamKindDesc::Albedo => "albedo",
            ParamKindDesc::Radiance => "radiance",
            ParamKindDesc::Eta => "eta",
            ParamKindDesc::PulseOffset => "pulse_offset",
            ParamKindDesc::Roughness => "roughness",
            ParamKindDesc::Ior => "ior",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AxisDesc {
    X,
    Y,
    Z,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ChannelDesc {
    R,
    G,
    B,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParamDesc {
    pub name: String,
    pub kind: ParamKindDesc,
    pub shape: Option<String>,
    pub material: Option<String>,
    pub emitter: Option<String>,
    pub axis: Option<AxisDesc>,
    pub channel: Option<ChannelDesc>,
    /// f64 so that a translate param can hold a far world coordinate exactly.
    pub value: f64,
}

/// A scalar or an `[a, b, c]` triple (colours, scale).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Triple {
    Scalar(f32),
    Three([f32; 3]),
}

impl Triple {
    pub fn to_array(self) -> [f32; 3] {
        match self {
            Triple::Scalar(s) => [s; 3],
            Triple::Three(v) => v,
        }
    }
    /// Written as three values with unequal channels.
    pub fn is_unequal(self) -> bool {
        match self {
            Triple::Scalar(_) => false,
            Triple::Three([a, b, c]) => a != b || b != c,
        }
    }
}

impl<'de> Deserialize<'de> for Triple {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Triple;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number or an array of 3 numbers")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Triple, E> {
                Ok(Triple::Scalar(v as f32))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Triple, E> {
                Ok(Triple::Scalar(v as f32))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Triple, E> {
                Ok(Triple::Scalar(v as f32))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Triple, A::Error> {
                let mut out = [0.0f32; 3];
                let mut n = 0usize;
                while let Some(x) = seq.next_element::<f32>()? {
                    if n < 3 {
                        out[n] = x;
                    }
                    n += 1;
                }
                if n != 3 {
                    return Err(de::Error::invalid_length(n, &"a number or an array of 3 numbers"));
                }
                Ok(Triple::Three(out))
            }
        }
        d.deserialize_any(V)
    }
}

/// A string naming a variant with its defaults (`"box"`), or a table with `type` and
/// parameters (`{ type = "tent", radius = 1.0 }`).
#[derive(Clone, Debug)]
pub enum NameOr<T> {
    Name(String),
    Table(T),
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for NameOr<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<T>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de>> Visitor<'de> for V<T> {
            type Value = NameOr<T>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a name (string) or a table with a `type` field")
            }
            fn visit_str<E: de::Error>(self, s: &str) -> Result<NameOr<T>, E> {
                Ok(NameOr::Name(s.to_string()))
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<NameOr<T>, A::Error> {
                T::deserialize(de::value::MapAccessDeserializer::new(map)).map(NameOr::Table)
            }
        }
        d.deserialize_any(V(std::marker::PhantomData))
    }
}

/// Fixed-length arrays that refuse extra or missing elements with the lengths in the
/// message, in TOML as in JSON (TOML's own `[T; N]` silently dropped extra elements).
mod exact {
    use serde::de::{self, Deserialize, Deserializer};

    fn fixed<T, E: de::Error, const N: usize>(v: Vec<T>) -> Result<[T; N], E> {
        let len = v.len();
        v.try_into()
            .map_err(|_| E::custom(format!("expected an array of length {N}, got {len} elements")))
    }

    pub fn array<'de, D: Deserializer<'de>, T: Deserialize<'de>, const N: usize>(d: D) -> Result<[T; N], D::Error> {
        fixed(Vec::<T>::deserialize(d)?)
    }

    pub fn option_array<'de, D: Deserializer<'de>, T: Deserialize<'de>, const N: usize>(
        d: D,
    ) -> Result<Option<[T; N]>, D::Error> {
        Option::<Vec<T>>::deserialize(d)?.map(fixed).transpose()
    }
}

// ---- [nlos]: a relay-wall capture, resolved by `super::nlos` ----

/// Which laser points each sensor point is measured with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum NlosScan {
    /// Laser point = sensor point.
    Confocal,
    /// Every laser point with every sensor point.
    Exhaustive,
}

/// Whether the laser-to-wall and wall-to-SPAD legs count in the time of flight.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RelayLegs {
    /// Time starts when light leaves the laser spot and stops when it reaches the sensor point.
    #[default]
    Excluded,
    /// Time runs from the laser to the SPAD.
    Included,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NlosDesc {
    /// The relay wall: a shape name.
    pub wall: String,
    /// The laser emitter whose position the scan aims from.
    pub laser: String,
    pub scan: NlosScan,
    /// Sensor points: a regular grid [nx, ny] over the wall ...
    #[serde(default, deserialize_with = "exact::option_array")]
    pub grid: Option<[i64; 2]>,
    /// ... or explicit points, each projected onto the wall.
    pub points: Option<Vec<Vec<f64>>>,
    /// Exhaustive scans: the laser grid (default: the sensor points).
    #[serde(default, deserialize_with = "exact::option_array")]
    pub laser_grid: Option<[i64; 2]>,
    #[serde(default)]
    pub relay_legs: RelayLegs,
    pub noise: Option<NoiseDesc>,
    /// Share of the paths whose first segment is aimed at a point drawn on the hidden shapes
    /// (the rest cosine-sample it), in [0, 1); 0 turns aiming off. Default 0.5.
    pub hidden_sampling: Option<f64>,
    /// The shapes aimed at (default: every shape but the wall).
    pub hidden_shapes: Option<Vec<String>>,
}

/// Photon noise of a synthetic capture, applied to a copy of the transient.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseDesc {
    /// Expected photon counts per unit of transient value.
    pub photons_per_unit: f64,
    /// Expected dark counts per bin of every histogram.
    #[serde(default)]
    pub dark_counts: f64,
    #[serde(default)]
    pub seed: u64,
}
