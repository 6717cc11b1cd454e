//! Shapes: the built-in meshes in local space, OBJ files, and the concatenation of all
//! shapes into world-space [`Geometry`].
//!
//! Triangles of exactly zero area (a repeated index, or collinear corners, in local or in
//! world space) are left out of the geometry; their number is kept in
//! [`Geometry::dropped_degenerate`]. Tiny but nonzero triangles are kept. A transform with
//! an odd number of negative scale factors (a mirror) gets its triangles' winding reversed, so
//! the front side stays the front side; `flip_normals = true` reverses it (the front becomes
//! the other side: area emitters shine from it, one-sided materials reflect on it).

use super::context::{Ctx, Names, no_such};
use super::desc::{SceneDesc, ShapeDesc, ShapeType, Triple};
use super::error::item_field;
use super::{Emitter, EmitterKind, Geometry, SceneError, Shape, Transform};
use glam::{DVec3, Vec3};
use std::path::{Path, PathBuf};

/// Highest icosphere subdivision level (20·4⁷ = 327 680 triangles).
pub const MAX_SUBDIVISIONS: i64 = 7;
/// Default icosphere subdivision level (1 280 triangles).
pub const DEFAULT_SUBDIVISIONS: i64 = 3;

/// A triangle mesh in local space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions in local space (metres before the shape's scale).
    pub positions: Vec<Vec3>,
    /// Vertex indices of each triangle into `positions`.
    pub tris: Vec<[u32; 3]>,
}

impl Mesh {
    /// Orients every triangle so its normal points away from the origin (for convex shapes
    /// around the origin).
    fn orient_outward(mut self) -> Mesh {
        for t in &mut self.tris {
            let [a, b, c] = t.map(|i| self.positions[i as usize]);
            if (b - a).cross(c - a).dot(a + b + c) < 0.0 {
                t.swap(1, 2);
            }
        }
        self
    }
}

/// The square `[-1, 1]²` in the XY plane, normal +Z (counter-clockwise seen from +Z).
pub fn rectangle() -> Mesh {
    Mesh {
        positions: vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ],
        tris: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// The cube `[-1, 1]³`: 8 shared vertices, 12 triangles with outward normals.
pub fn cube() -> Mesh {
    // vertex i has x = bit 0, y = bit 1, z = bit 2 (0 → -1, 1 → +1)
    let positions = (0..8)
        .map(|i| {
            let s = |b: u32| if i & (1 << b) != 0 { 1.0 } else { -1.0 };
            Vec3::new(s(0), s(1), s(2))
        })
        .collect();
    let quads: [[u32; 4]; 6] = [
        [1, 3, 7, 5],
        [0, 4, 6, 2],
        [2, 6, 7, 3],
        [0, 1, 5, 4],
        [4, 5, 7, 6],
        [0, 2, 3, 1],
    ];
    let tris = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    Mesh { positions, tris }.orient_outward()
}

/// The unit sphere as an icosphere: the icosahedron, each triangle split in four `level`
/// times, vertices pushed onto the sphere. 20·4^level triangles, outward normals.
pub fn icosphere(level: u32) -> Mesh {
    let t = (1.0 + 5.0f32.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vec3::from(*p).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid = std::collections::HashMap::<(u32, u32), u32>::new();
        let mut midpoint = |a: u32, b: u32, positions: &mut Vec<Vec3>| {
            let key = (a.min(b), a.max(b));
            *mid.entry(key).or_insert_with(|| {
                positions.push(((positions[a as usize] + positions[b as usize]) * 0.5).normalize());
                positions.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(tris.len() * 4);
        for [a, b, c] in tris {
            let ab = midpoint(a, b, &mut positions);
            let bc = midpoint(b, c, &mut positions);
            let ca = midpoint(c, a, &mut positions);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    Mesh { positions, tris }.orient_outward()
}

/// A mesh in local space with f64 positions (OBJ vertices are read in f64, so that a mesh
/// modelled in far world coordinates keeps its precision until the render origin is
/// subtracted; see `origin.rs`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LocalMesh {
    /// Vertex positions in local space, f64.
    pub positions: Vec<DVec3>,
    /// Vertex indices of each triangle into `positions`.
    pub tris: Vec<[u32; 3]>,
}

impl From<Mesh> for LocalMesh {
    fn from(m: Mesh) -> Self {
        LocalMesh {
            positions: m.positions.iter().map(|p| p.as_dvec3()).collect(),
            tris: m.tris,
        }
    }
}

/// The largest OBJ file read (about 25M triangles).
pub(crate) const MAX_OBJ_BYTES: u64 = 2 << 30;

/// Why an OBJ could not be used (the caller adds the scene file, field and OBJ path).
type ObjResult<T> = Result<T, String>;

/// Reads a Wavefront OBJ (all objects and groups merged; polygons split by
/// `polygon::triangulate`; points, lines, normals, texture coordinates and materials ignored).
pub fn load_obj(path: &Path) -> ObjResult<LocalMesh> {
    let text = super::read::read_regular_file(path, MAX_OBJ_BYTES).map_err(|e| format!("cannot read it: {e}"))?;
    parse_obj(&text)
}

/// [`load_obj`] for OBJ text already read.
pub fn parse_obj(text: &str) -> ObjResult<LocalMesh> {
    check_obj_text(text)?;
    let opts = obj_options();
    let parsed = std::panic::catch_unwind(|| {
        tobj::load_obj_buf(&mut std::io::BufReader::new(text.as_bytes()), &opts, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
    })
    .map_err(|_| "the OBJ parser failed on this file".to_string())?;
    let (models, _materials) = parsed.map_err(|e| format!("cannot parse it: {e}"))?;
    let mut mesh = LocalMesh::default();
    for m in &models {
        let base = mesh.positions.len() as u32;
        let p = &m.mesh.positions;
        mesh.positions
            .extend(p.chunks_exact(3).map(|c| DVec3::new(c[0], c[1], c[2])));
        let idx = &m.mesh.indices;
        if idx.iter().any(|&i| i as usize >= p.len() / 3) {
            return Err(format!("object {:?} has a face index out of range", m.name));
        }
        let arities = face_arities(&m.mesh);
        let mut start = 0;
        for (f, &arity) in arities.iter().enumerate() {
            let face = &idx[start..start + arity];
            start += arity;
            let corners: Vec<DVec3> = face
                .iter()
                .map(|&i| DVec3::from_slice(&p[3 * i as usize..3 * i as usize + 3]))
                .collect();
            let tris = super::polygon::triangulate(&corners)
                .map_err(|e| format!("object {:?}, face {} ({arity} corners): {e}", m.name, f + 1))?;
            mesh.tris.extend(tris.iter().map(|t| t.map(|k| base + face[k])));
        }
    }
    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(format!(
            "a vertex is not finite ({:?}, vertex {} after reindexing)",
            mesh.positions[i].to_array(),
            i + 1
        ));
    }
    if mesh.tris.is_empty() {
        return Err("empty mesh: it has no faces (f lines with 3 or more vertices)".to_string());
    }
    Ok(mesh)
}

/// The number of corners of each face of a tobj mesh (tobj leaves `face_arities` empty when
/// every face is a triangle).
pub(crate) fn face_arities(mesh: &tobj::Mesh) -> Vec<usize> {
    match mesh.face_arities.is_empty() {
        true => vec![3; mesh.indices.len() / 3],
        false => mesh.face_arities.iter().map(|&a| a as usize).collect(),
    }
}

/// How tobj reads an OBJ here: one index per corner (positions and normals alike), faces as
/// written (polygons are split by `polygon::triangulate`: tobj's fan is wrong for concave
/// ones), no points or lines.
pub(crate) fn obj_options() -> tobj::LoadOptions {
    // `..Default::default()` covers fields that tobj's optional features add.
    #[allow(clippy::needless_update)]
    tobj::LoadOptions {
        single_index: true,
        triangulate: false,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    }
}

/// Checks the `v` and `f` lines before handing the text to tobj, so that a bad vertex is
/// reported with its index and line and no index can overflow the parser.
fn check_obj_text(text: &str) -> ObjResult<()> {
    let (mut nv, mut nvt, mut nvn) = (0usize, 0usize, 0usize);
    let total_v = text
        .lines()
        .filter(|l| l.split_whitespace().next() == Some("v"))
        .count();
    for (ln, line) in text.lines().enumerate() {
        let ln = ln + 1;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                nv += 1;
                let nums: Vec<&str> = words.collect();
                if nums.len() < 3 {
                    return Err(format!(
                        "vertex {nv} (line {ln}) has {} coordinates, expected 3",
                        nums.len()
                    ));
                }
                let mut xyz = [0.0f64; 3];
                for (k, w) in nums.iter().take(3).enumerate() {
                    xyz[k] = w
                        .parse::<f64>()
                        .map_err(|_| format!("vertex {nv} (line {ln}): {w:?} is not a number"))?;
                }
                if nums.len() == 4 {
                    let w = nums[3]
                        .parse::<f64>()
                        .map_err(|_| format!("vertex {nv} (line {ln}): w = {:?} is not a number", nums[3]))?;
                    if w == 0.0 || !w.is_finite() {
                        return Err(format!(
                            "vertex {nv} (line {ln}): w must be finite and nonzero (got {w})"
                        ));
                    }
                    xyz = xyz.map(|c| c / w);
                }
                if xyz.iter().any(|c| !(*c as f32).is_finite()) {
                    return Err(format!(
                        "vertex {nv} (line {ln}) is not finite: {xyz:?} (NaN and Inf coordinates are not allowed)"
                    ));
                }
            }
            Some("vt") => nvt += 1,
            Some("vn") => nvn += 1,
            Some(key @ ("f" | "l" | "p")) => {
                let words: Vec<&str> = words.collect();
                if key == "f" && words.len() < 3 {
                    // tobj drops such a face without a word: a file cut inside its last face
                    // line rendered a triangle short
                    return Err(format!(
                        "line {ln}: a face of {} corner{}, a face needs at least 3 (is the file cut short?)",
                        words.len(),
                        if words.len() == 1 { "" } else { "s" }
                    ));
                }
                for w in words {
                    for (k, part) in w.split('/').enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let (kind, kinds, so_far, total) = match k {
                            0 => ("vertex", "vertices", nv, total_v),
                            1 => ("texture coordinate", "texture coordinates", nvt, nvt),
                            2 => ("normal", "normals", nvn, nvn),
                            _ => return Err(format!("line {ln}: {w:?} has more than 3 indices")),
                        };
                        let i: i64 = part
                            .parse()
                            .map_err(|_| format!("line {ln}: index {part:?} is not an integer"))?;
                        let ok = if i > 0 {
                            (i as u64) <= total.max(so_far) as u64
                        } else {
                            i < 0 && i.unsigned_abs() <= so_far as u64
                        };
                        if !ok {
                            return Err(format!(
                                "line {ln}: {kind} index {i} is out of range (OBJ indices start at 1; {so_far} {kinds} defined so far)"
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// The transform of a shape description (defaults: no translation, no rotation, scale 1),
/// with its translation in f64 world coordinates (the returned transform's `translate` is
/// zero; `build` sets it relative to the render origin).
fn transform(ctx: &Ctx, i: usize, d: &ShapeDesc) -> Result<(Transform, DVec3), SceneError> {
    let scale = d.scale.unwrap_or(Triple::Scalar(1.0)).to_array();
    if scale.contains(&0.0) {
        let got = match d.scale {
            Some(Triple::Scalar(s)) => format!("{s}"),
            _ => format!("{scale:?}"),
        };
        return Err(ctx.invalid(
            item_field("shape", i, &d.name, "scale"),
            format!("every scale factor must be nonzero (got {got})"),
        ));
    }
    let t = Transform {
        translate: Vec3::ZERO,
        rotate_deg: Vec3::from(d.rotate.unwrap_or([0.0; 3])),
        scale: Vec3::from(scale),
    };
    Ok((t, DVec3::from(d.translate.unwrap_or([0.0; 3]))))
}

/// `translate + R · (scale ∘ p)` in f64, for every vertex of `mesh`.
fn world_f64(t: &Transform, translate: DVec3, mesh: &LocalMesh) -> impl Iterator<Item = DVec3> {
    let (rot, scale) = (t.rotation_f64(), t.scale.as_dvec3());
    mesh.positions.iter().map(move |&p| translate + rot * (scale * p))
}

/// Every shape's local mesh, in the order of `desc.shape` (OBJ files are read once).
pub(crate) fn local_meshes(desc: &SceneDesc, ctx: &Ctx) -> Result<Vec<LocalMesh>, SceneError> {
    desc.shape
        .iter()
        .enumerate()
        .map(|(i, d)| local_mesh(ctx, i, d))
        .collect()
}

/// The bounding box of every shape's world vertices and where their surface lies
/// (`super::origin::Extent`; f64, before the render origin is chosen); shapes whose transform
/// is invalid are skipped (they fail later with a message).
///
/// Where the surface lies is taken from each shape's own box, weighted by the box's surface
/// area (one pass over the vertices, as the bounding box alone took): the weighted mean of the
/// boxes' centres, and the weighted mean of their distances from it plus their half
/// diagonals.
pub(crate) fn world_extent(desc: &SceneDesc, meshes: &[LocalMesh], ctx: &Ctx) -> Option<super::origin::Extent> {
    let boxes: Vec<(DVec3, DVec3)> = desc
        .shape
        .iter()
        .enumerate()
        .zip(meshes)
        .filter_map(|((i, d), mesh)| {
            let (t, translate) = transform(ctx, i, d).ok()?;
            world_f64(&t, translate, mesh)
                .filter(|p| p.is_finite())
                .fold(None, |b: Option<(DVec3, DVec3)>, p| {
                    Some(b.map_or((p, p), |(lo, hi)| (lo.min(p), hi.max(p))))
                })
        })
        .collect();
    let lo = boxes.iter().map(|b| b.0).reduce(DVec3::min)?;
    let hi = boxes.iter().map(|b| b.1).reduce(DVec3::max)?;
    // about the whole box's centre (small numbers, for precision)
    let mid = (lo + hi) * 0.5;
    let weigh = |(a, b): &(DVec3, DVec3)| {
        let e = *b - *a;
        let area = 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
        ((*a + *b) * 0.5 - mid, 0.5 * e.length(), area)
    };
    let weighed: Vec<(DVec3, f64, f64)> = boxes.iter().map(weigh).filter(|w| w.2.is_finite()).collect();
    let area: f64 = weighed.iter().map(|w| w.2).sum();
    let bulk = (area > 0.0 && area.is_finite()).then(|| {
        let centre = weighed.iter().map(|(c, _, a)| *c * *a).sum::<DVec3>() / area;
        let spread = weighed
            .iter()
            .map(|(c, r, a)| a * ((*c - centre).length() + r))
            .sum::<f64>()
            / area;
        (mid + centre, spread)
    });
    Some(super::origin::Extent { lo, hi, bulk })
}

fn local_mesh(ctx: &Ctx, i: usize, d: &ShapeDesc) -> Result<LocalMesh, SceneError> {
    let at = |f: &str| item_field("shape", i, &d.name, f);
    if d.ty != ShapeType::Sphere && d.subdivisions.is_some() {
        return Err(ctx.invalid(
            at("subdivisions"),
            format!("only applies to type sphere (this shape is a {})", d.ty.as_str()),
        ));
    }
    if !matches!(d.ty, ShapeType::Obj | ShapeType::Ply) && d.file.is_some() {
        return Err(ctx.invalid(
            at("file"),
            format!("only applies to types obj and ply (this shape is a {})", d.ty.as_str()),
        ));
    }
    Ok(match d.ty {
        ShapeType::Rectangle => rectangle().into(),
        ShapeType::Cube => cube().into(),
        ShapeType::Sphere => {
            let level = d.subdivisions.unwrap_or(DEFAULT_SUBDIVISIONS);
            if !(0..=MAX_SUBDIVISIONS).contains(&level) {
                return Err(ctx.invalid(
                    at("subdivisions"),
                    format!("must be in 0..={MAX_SUBDIVISIONS} (got {level})"),
                ));
            }
            icosphere(level as u32).into()
        }
        ShapeType::Obj | ShapeType::Ply => {
            let kind = d.ty.as_str();
            let Some(file) = &d.file else {
                return Err(ctx.invalid(
                    at("file"),
                    format!(
                        "missing: an {kind} shape needs file = \"path/to/mesh.{kind}\" (relative to the scene file)"
                    ),
                ));
            };
            let mesh_path = obj_path(ctx.path, file);
            let (format, loaded) = match d.ty {
                ShapeType::Obj => ("OBJ", load_obj(&mesh_path)),
                _ => (
                    "PLY",
                    super::ply::load_ply(&mesh_path).map(|m| LocalMesh {
                        positions: m.positions,
                        tris: m.tris,
                    }),
                ),
            };
            loaded.map_err(|message| SceneError::Mesh {
                path: ctx.path.to_path_buf(),
                at: at("file"),
                format,
                mesh: mesh_path,
                message,
            })?
        }
    })
}

/// The error for vertex `k` (local `p`) of a shape whose transform sends it outside the range
/// of 32-bit floats, at the step of `translate + R · (scale ∘ p)` that left the range: its
/// field (`scale`, `rotate` or `translate`) is named, and with it the param that set it.
fn out_of_range(ctx: &Ctx, at: &dyn Fn(&str) -> String, t: &Transform, p: DVec3, k: usize, world: Vec3) -> SceneError {
    let scaled = t.scale.as_dvec3() * p;
    let rotated = t.rotation_f64() * scaled;
    let v = |x: DVec3| format!("{:?}", x.to_array());
    let (field, what, expected) = if !scaled.as_vec3().is_finite() {
        (
            "scale",
            format!("{:?} sends vertex {k} {} to {}", t.scale.to_array(), v(p), v(scaled)),
            "a smaller scale",
        )
    } else if !rotated.as_vec3().is_finite() {
        (
            "rotate",
            format!(
                "{:?} deg turns vertex {k}, scaled to {}, to {}",
                t.rotate_deg.to_array(),
                v(scaled),
                v(rotated)
            ),
            "a rotate that keeps every vertex within the range (or a smaller scale)",
        )
    } else {
        (
            "translate",
            format!(
                "the translation sends vertex {k} to the non-finite position {:?}",
                world.to_array()
            ),
            "a smaller translate",
        )
    };
    ctx.invalid(
        at(field),
        format!(
            "{what}, outside the range of 32-bit floats (±{:e}); expected {expected}",
            f32::MAX
        ),
    )
}

/// `file` relative to the scene file's folder (absolute paths stay).
pub fn obj_path(scene: &Path, file: &str) -> PathBuf {
    scene.parent().unwrap_or(Path::new("")).join(file)
}

/// The folder that the relative file names of `source` (a scene file; its names are relative
/// to its folder) must be joined to so that a description written into `out_dir` names the
/// same files: `source`'s folder, made absolute, when `out_dir` is another folder (or does
/// not exist yet); `None` when it is the same folder or `source`'s cannot be resolved (the
/// names are then kept as they are). `dtr import` and `dtr optimize`'s recovered scene use it.
pub fn file_base_for(source: &Path, out_dir: &Path) -> Option<PathBuf> {
    let canon = |p: &Path| std::fs::canonicalize(if p.as_os_str().is_empty() { Path::new(".") } else { p }).ok();
    let source_dir = canon(source.parent().unwrap_or(Path::new(".")))?;
    (canon(out_dir).as_ref() != Some(&source_dir)).then_some(source_dir)
}

/// Makes the relative file names in the scene document `doc` (a scene file's TOML or JSON as
/// a value; `[[shape]] file`, the only files a scene names) name the same files from a
/// description written into `out_dir` ([`file_base_for`]).
pub fn rebase_file_names(doc: &mut serde_json::Value, source: &Path, out_dir: &Path) {
    let Some(base) = file_base_for(source, out_dir) else {
        return;
    };
    let Some(shapes) = doc.get_mut("shape").and_then(|s| s.as_array_mut()) else {
        return;
    };
    for shape in shapes {
        if let Some(file) = shape.get_mut("file")
            && let Some(name) = file.as_str().filter(|n| Path::new(n).is_relative())
        {
            *file = serde_json::Value::String(base.join(name).to_string_lossy().into_owned());
        }
    }
}

/// Exactly zero area (in either space).
fn degenerate(a: Vec3, b: Vec3, c: Vec3) -> bool {
    (b - a).cross(c - a) == Vec3::ZERO
}

/// Builds every shape and concatenates them into world-space geometry, relative to the render
/// origin `origin` (subtracted in f64, then rounded to f32).
pub(crate) fn build(
    desc: &SceneDesc,
    names: &Names,
    emitters: &[Emitter],
    ctx: &Ctx,
    meshes: &[LocalMesh],
    origin: DVec3,
) -> Result<(Vec<Shape>, Geometry), SceneError> {
    let mut geo = Geometry::default();
    let mut shapes = Vec::with_capacity(desc.shape.len());
    for ((i, d), mesh) in desc.shape.iter().enumerate().zip(meshes) {
        let at = |f: &str| item_field("shape", i, &d.name, f);
        let material = match &d.material {
            Some(m) => names
                .material(m)
                .ok_or_else(|| ctx.invalid(at("material"), no_such("material", "materials", m, &names.materials)))?,
            None => {
                return Err(ctx.invalid(
                    at("material"),
                    format!(
                        "missing: every shape needs a material (materials: {})",
                        names.materials.join(", ")
                    ),
                ));
            }
        };
        if d.flip_normals == Some(true) && desc.material[material].ty.is_dielectric() {
            return Err(ctx.invalid(
                at("flip_normals"),
                format!(
                    "material {:?} is a dielectric, whose interior is the side its shape's normals point away \
                     from: flipped, the rest of the scene would lie inside it; give the shape a material that is \
                     not a dielectric, or leave flip_normals out",
                    desc.material[material].name
                ),
            ));
        }
        if d.ty == ShapeType::Rectangle && desc.material[material].ty.is_dielectric() {
            return Err(ctx.invalid(
                at("material"),
                format!(
                    "material {:?} is a dielectric, which needs a closed shape (cube, sphere or a closed obj) to have an inside; a rectangle has none",
                    desc.material[material].name
                ),
            ));
        }
        let (mut transform, translate) = transform(ctx, i, d)?;
        transform.translate = (translate - origin).as_vec3();
        let world: Vec<Vec3> = world_f64(&transform, translate - origin, mesh)
            .map(|p| p.as_vec3())
            .collect();
        let local: Vec<Vec3> = mesh.positions.iter().map(|p| p.as_vec3()).collect();
        if let Some(k) = world.iter().position(|p| !p.is_finite()) {
            return Err(out_of_range(ctx, &at, &transform, mesh.positions[k], k, world[k]));
        }
        // a mirror reverses the winding back, so the front stays the front; `flip_normals`
        // turns it to the other side
        let mirror = transform.scale.x * transform.scale.y * transform.scale.z < 0.0;
        let reverse = mirror != d.flip_normals.unwrap_or(false);
        let first_vertex = geo.positions.len();
        let first_tri = geo.indices.len();
        let mut dropped = 0usize;
        for &t in &mesh.tris {
            let [a, b, c] = t.map(|k| k as usize);
            if a == b
                || b == c
                || a == c
                || (mesh.positions[b] - mesh.positions[a]).cross(mesh.positions[c] - mesh.positions[a]) == DVec3::ZERO
                || degenerate(world[a], world[b], world[c])
            {
                dropped += 1;
                continue;
            }
            let t = if reverse { [t[0], t[2], t[1]] } else { t };
            geo.indices.push(t.map(|k| k + first_vertex as u32));
            geo.tri_shape.push(i as u32);
        }
        let tri_count = geo.indices.len() - first_tri;
        // triangles with area in the mesh's own coordinates, which the transform flattened: a
        // shape sent so far from the render origin that f32 no longer tells its corners apart
        // (`--set plate_x=1e30` was reported as a problem of its field 'scale')
        let flattened = tri_count == 0 && {
            let at_origin: Vec<Vec3> = world_f64(&transform, DVec3::ZERO, mesh).map(|p| p.as_vec3()).collect();
            mesh.tris.iter().any(|t| {
                !degenerate(
                    at_origin[t[0] as usize],
                    at_origin[t[1] as usize],
                    at_origin[t[2] as usize],
                )
            })
        };
        if flattened {
            let g = |v: f64| match v.abs() {
                a if a != 0.0 && !(1e-4..1e6).contains(&a) => format!("{v:e}"),
                _ => format!("{v}"),
            };
            return Err(ctx.invalid(
                at("translate"),
                format!(
                    "all {} triangles have zero area where the transform puts them (translated to [{}, {}, {}], {} m from the scene's render origin): f32 positions there cannot resolve a shape of its size; bring it nearer the rest of the scene",
                    mesh.tris.len(),
                    g(translate.x),
                    g(translate.y),
                    g(translate.z),
                    g((translate - origin).length())
                ),
            ));
        }
        if tri_count == 0 {
            let (what, of) = match &d.file {
                Some(f) if matches!(d.ty, ShapeType::Obj | ShapeType::Ply) => ("file", format!(" of {f}")),
                _ => ("scale", String::new()),
            };
            return Err(ctx.invalid(
                at(what),
                format!(
                    "empty mesh: all {} triangles{of} have zero area; a shape needs at least one triangle with nonzero area",
                    mesh.tris.len()
                ),
            ));
        }
        geo.dropped_degenerate += dropped;
        geo.positions.extend_from_slice(&world);
        if geo.positions.len() > u32::MAX as usize / 2 || geo.indices.len() > u32::MAX as usize / 2 {
            return Err(ctx.invalid(at("file"), "the scene has too many vertices or triangles (over 2^31)"));
        }
        let emitter = emitters
            .iter()
            .position(|e| matches!(e.kind, EmitterKind::Area { shape, .. } if shape as usize == i))
            .map(|e| e as u32);
        shapes.push(Shape {
            name: d.name.clone(),
            transform,
            local_positions: local,
            first_vertex: first_vertex as u32,
            vertex_count: world.len() as u32,
            first_tri: first_tri as u32,
            tri_count: tri_count as u32,
            material: material as u32,
            emitter,
        });
    }
    Ok((shapes, geo))
}

#[cfg(test)]
mod tests {
    use super::super::Scene;
    use super::super::testutil::*;
    use super::*;

    fn normal(m: &Mesh, t: [u32; 3]) -> Vec3 {
        let [a, b, c] = t.map(|i| m.positions[i as usize]);
        (b - a).cross(c - a)
    }

    fn geo_normal(s: &Scene, t: usize) -> Vec3 {
        let [a, b, c] = s.geometry.indices[t].map(|i| s.geometry.positions[i as usize]);
        (b - a).cross(c - a).normalize()
    }

    #[test]
    fn builtin_meshes() {
        let r = rectangle();
        assert!(r.tris.iter().all(|&t| normal(&r, t).normalize() == Vec3::Z));
        let c = cube();
        assert_eq!((c.positions.len(), c.tris.len()), (8, 12));
        let area: f32 = c.tris.iter().map(|&t| normal(&c, t).length() / 2.0).sum();
        assert!((area - 24.0).abs() < 1e-5);
        for &t in &c.tris {
            let n = normal(&c, t).normalize();
            let centre = t.iter().map(|&i| c.positions[i as usize]).sum::<Vec3>() / 3.0;
            // outward and axis-aligned: the normal is the face's axis, matching the centroid's sign
            assert!(
                (n.dot(centre.signum() * n.abs()) - 1.0).abs() < 1e-6 && n.dot(centre) > 0.0,
                "{n} {centre}"
            );
        }
        for level in [0, 1, 3] {
            let s = icosphere(level);
            assert_eq!(s.tris.len(), 20 * 4usize.pow(level));
            assert!(s.positions.iter().all(|p| (p.length() - 1.0).abs() < 1e-6));
            assert!(
                s.tris
                    .iter()
                    .all(|&t| normal(&s, t).dot(s.positions[t[0] as usize]) > 0.0)
            );
            // closed: volume by the divergence theorem approaches 4/3 pi from below
            let vol: f32 = s
                .tris
                .iter()
                .map(|&t| {
                    let [a, b, c] = t.map(|i| s.positions[i as usize]);
                    a.dot(b.cross(c)) / 6.0
                })
                .sum();
            assert!(vol > 0.0 && vol < 4.19, "{vol}");
        }
    }

    #[test]
    fn cornell_light_faces_down_and_walls_face_in() {
        let s = load_scene("cornell_box.toml");
        assert_eq!(s.film.channels, 3);
        assert_eq!(s.geometry.indices.len(), 36);
        let expect = [
            ("floor", Vec3::Y),
            ("ceiling", -Vec3::Y),
            ("back_wall", Vec3::Z),
            ("left_wall", Vec3::X),
            ("right_wall", -Vec3::X),
            ("light_quad", -Vec3::Y),
        ];
        for (name, n) in expect {
            let sh = s.shapes.iter().find(|x| x.name == name).unwrap();
            for t in sh.first_tri..sh.first_tri + sh.tri_count {
                assert!(
                    (geo_normal(&s, t as usize) - n).length() < 1e-5,
                    "{name}: {}",
                    geo_normal(&s, t as usize)
                );
            }
        }
        let light = s.shapes.iter().find(|x| x.name == "light_quad").unwrap();
        assert_eq!(light.emitter, Some(0));
        assert!(
            matches!(s.emitters[0].kind, super::super::EmitterKind::Area { shape, .. } if s.shapes[shape as usize].name == "light_quad")
        );
        // the light is inside the room, just under the ceiling
        for k in 0..light.vertex_count {
            let p = s.geometry.positions[(light.first_vertex + k) as usize];
            assert!(
                (p.y - 1.98).abs() < 1e-6 && p.x.abs() <= 0.25 + 1e-6 && p.z.abs() <= 0.25 + 1e-6,
                "{p}"
            );
        }
        // both boxes: outward normals, inside the room
        for name in ["short_box", "tall_box"] {
            let b = s.shapes.iter().find(|x| x.name == name).unwrap();
            let centre = b.transform.translate;
            for t in b.first_tri..b.first_tri + b.tri_count {
                let [p0, p1, p2] = s.geometry.indices[t as usize].map(|i| s.geometry.positions[i as usize]);
                assert!(
                    geo_normal(&s, t as usize).dot((p0 + p1 + p2) / 3.0 - centre) > 0.0,
                    "{name}"
                );
                for p in [p0, p1, p2] {
                    assert!(
                        p.x.abs() < 1.0 && p.z.abs() < 1.0 && p.y >= -1e-6 && p.y < 2.0,
                        "{name} {p}"
                    );
                }
            }
        }
    }

    #[test]
    fn cube_transform_places_vertices() {
        let text = mini_with(
            "type = \"rectangle\"\nmaterial = \"white\"",
            "type = \"cube\"\nmaterial = \"white\"\nscale = [1, 2, 3]\nrotate = [0, 90, 0]\ntranslate = [1, 0, 0]",
        );
        let s = load_text("cube.toml", &text, &[], &[]).unwrap();
        let sh = &s.shapes[0];
        let k = sh.local_positions.iter().position(|&p| p == Vec3::ONE).unwrap();
        let w = s.geometry.positions[sh.first_vertex as usize + k];
        // scale → (1,2,3); Ry(90°): (x,y,z) → (z, y, -x) → (3,2,-1); + (1,0,0)
        assert!((w - Vec3::new(4.0, 2.0, -1.0)).length() < 1e-5, "{w}");
        for (k, &p) in sh.local_positions.iter().enumerate() {
            // built in f64 and rounded once: within an f32 ulp or two of the f32 transform
            let d = s.geometry.positions[sh.first_vertex as usize + k] - sh.transform.apply(p);
            assert!(d.abs().max_element() <= 1e-6, "{d}");
        }
        // X rotation is applied first: (0,1,0) → Rx(90) → (0,0,1) → Ry(90) → (1,0,0)
        let t = Transform {
            rotate_deg: Vec3::new(90.0, 90.0, 0.0),
            ..Default::default()
        };
        assert!((t.apply(Vec3::Y) - Vec3::X).length() < 1e-6);
        // a mirror keeps normals outward
        let text = mini_with(
            "type = \"rectangle\"\nmaterial = \"white\"",
            "type = \"cube\"\nmaterial = \"white\"\nscale = [-1, 1, 1]",
        );
        let s = load_text("mirror.toml", &text, &[], &[]).unwrap();
        for t in 0..12 {
            let [a, b, c] = s.geometry.indices[t].map(|i| s.geometry.positions[i as usize]);
            assert!((b - a).cross(c - a).dot(a + b + c) > 0.0);
        }
    }

    #[test]
    fn sphere_subdivisions() {
        let sphere = |extra: &str| mini_with("type = \"rectangle\"", &format!("type = \"sphere\"{extra}"));
        let s = load_text("s.toml", &sphere(""), &[], &[]).unwrap();
        assert_eq!(s.shapes[0].tri_count, 1280);
        let s = load_text("s.toml", &sphere("\nsubdivisions = 1"), &[], &[]).unwrap();
        assert_eq!(s.shapes[0].tri_count, 80);
        expect_err(
            "sub.toml",
            &sphere("\nsubdivisions = 8"),
            &[],
            &["shape[0] \"quad\": field 'subdivisions'", "0..=7"],
        );
        let text = mini_with("material = \"white\"", "material = \"white\"\nsubdivisions = 2");
        expect_err(
            "sub2.toml",
            &text,
            &[],
            &["shape[0] \"quad\": field 'subdivisions'", "only applies to type sphere"],
        );
    }

    #[test]
    fn zero_scale_is_refused() {
        let text = mini_with("material = \"white\"", "material = \"white\"\nscale = 0");
        expect_err(
            "s0.toml",
            &text,
            &[],
            &["shape[0] \"quad\": field 'scale'", "nonzero", "got 0"],
        );
        let text = mini_with("material = \"white\"", "material = \"white\"\nscale = [1, 0, 1]");
        expect_err(
            "s1.toml",
            &text,
            &[],
            &["shape[0] \"quad\": field 'scale'", "nonzero", "[1.0, 0.0, 1.0]"],
        );
        // a rectangle may be flat along z: scale z is still required nonzero
        let text = mini_with(
            "material = \"white\"",
            "material = \"white\"\ntranslate = [3e38, 0, 0]\nscale = 3e38",
        );
        expect_err("huge.toml", &text, &[], &["shape[0] \"quad\"", "non-finite"]);
    }

    fn obj_scene(file: &str) -> String {
        format!("{MINI}\n[[shape]]\nname = \"mesh\"\ntype = \"obj\"\nfile = \"{file}\"\nmaterial = \"white\"\n")
    }

    #[test]
    fn obj_loads_and_drops_zero_area_triangles() {
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 0 0 1e-20\nf 1 2 3\nf 1 2 4\nf 1 2 2\nf 1 2 5\n";
        let s = load_text("o.toml", &obj_scene("m.obj"), &[("m.obj", obj)], &[]).unwrap();
        let m = &s.shapes[1];
        // kept: the real triangle and the tiny (1e-20 high) one; dropped: collinear and repeated
        assert_eq!(m.tri_count, 2);
        assert_eq!(s.geometry.dropped_degenerate, 2);
        assert_eq!(m.vertex_count, 5);
        assert!(
            s.geometry.indices[m.first_tri as usize..]
                .iter()
                .all(|t| t.iter().all(|&i| i >= m.first_vertex))
        );
        // quads are triangulated; pyramid: 5 vertices, 6 triangles, outward
        let s = load_scene("obj_mesh.toml");
        let p = s.shapes.iter().find(|x| x.name == "pyramid").unwrap();
        assert_eq!((p.vertex_count, p.tri_count), (5, 6));
        let centre = p.transform.apply(Vec3::new(0.0, 0.5, 0.0));
        for t in p.first_tri..p.first_tri + p.tri_count {
            let [a, b, c] = s.geometry.indices[t as usize].map(|i| s.geometry.positions[i as usize]);
            assert!((b - a).cross(c - a).dot((a + b + c) / 3.0 - centre) > 0.0);
        }
    }

    /// A U-shaped face (a 3 × 3 square with a 1 × 2 notch, area 7) in an OBJ: tobj's fan from
    /// its first corner covered 8.25 of the plane (11 counting overlaps), 5/8 of the notch filled.
    #[test]
    fn a_concave_obj_face_covers_its_own_area() {
        let text = "v 0 0 0\nv 3 0 0\nv 3 3 0\nv 2 3 0\nv 2 1 0\nv 1 1 0\nv 1 3 0\nv 0 3 0\nf 1 2 3 4 5 6 7 8\n";
        let m = parse_obj(text).unwrap();
        assert_eq!(m.tris.len(), 6);
        let area = crate::scene::polygon::area_facing_z(&m.positions, &m.tris);
        assert!((area - 7.0).abs() < 1e-12, "{area}");
    }

    #[test]
    fn obj_errors_name_the_obj_and_the_field() {
        let at = "shape[1] \"mesh\": field 'file': OBJ file";
        expect_err(
            "missing.toml",
            &obj_scene("nope.obj"),
            &[],
            &[at, "nope.obj", "cannot read"],
        );
        let nan = "v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n";
        expect_err(
            "nan.toml",
            &obj_scene("bad.obj"),
            &[("bad.obj", nan)],
            &[at, "bad.obj", "vertex 2 (line 2) is not finite"],
        );
        let inf = "v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n";
        expect_err(
            "inf.toml",
            &obj_scene("bad.obj"),
            &[("bad.obj", inf)],
            &[at, "bad.obj", "vertex 3 (line 3)"],
        );
        let star = "v 1 0 0\nv -0.809 0.588 0\nv 0.309 -0.951 0\nv 0.309 0.951 0\nv -0.809 -0.588 0\nf 1 2 3 4 5\n";
        expect_err(
            "star.toml",
            &obj_scene("star.obj"),
            &[("star.obj", star)],
            &[at, "star.obj", "face 1 (5 corners)", "cross each other"],
        );
        let garbage = "v 0 0 0\nv 1 zero 0\n";
        expect_err(
            "garbage.toml",
            &obj_scene("g.obj"),
            &[("g.obj", garbage)],
            &[at, "g.obj", "\"zero\" is not a number"],
        );
        // a file cut inside its last face line (tobj dropped the face without a word)
        let cut = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4";
        expect_err(
            "cut.toml",
            &obj_scene("cut.obj"),
            &[("cut.obj", cut)],
            &[at, "cut.obj", "line 6: a face of 2 corners", "cut short"],
        );
        let range = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n";
        expect_err(
            "range.toml",
            &obj_scene("r.obj"),
            &[("r.obj", range)],
            &[at, "r.obj", "line 4", "index 9 is out of range"],
        );
        let zero = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/0 2/1 3/1\n";
        expect_err(
            "zero.toml",
            &obj_scene("z.obj"),
            &[("z.obj", zero)],
            &[at, "z.obj", "index 0"],
        );
        let empty = "# nothing\nv 0 0 0\nv 1 0 0\n";
        expect_err(
            "empty.toml",
            &obj_scene("e.obj"),
            &[("e.obj", empty)],
            &[at, "e.obj", "empty mesh"],
        );
        let flat = "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n";
        expect_err(
            "flat.toml",
            &obj_scene("f.obj"),
            &[("f.obj", flat)],
            &["shape[1] \"mesh\": field 'file'", "empty mesh", "zero area"],
        );
        let no_file = format!("{MINI}\n[[shape]]\nname = \"mesh\"\ntype = \"obj\"\nmaterial = \"white\"\n");
        expect_err(
            "nofile.toml",
            &no_file,
            &[],
            &["shape[1] \"mesh\": field 'file'", "missing"],
        );
        let neg = "v 0 0 0\nf -1 -2 -3\n";
        expect_err(
            "neg.toml",
            &obj_scene("n.obj"),
            &[("n.obj", neg)],
            &[at, "n.obj", "out of range"],
        );
    }

    #[test]
    fn odd_obj_inputs_never_panic() {
        let cases = [
            "",
            "f\n",
            "v 1 2\n",
            "v 1 2 3 0\nf 1 1 1\n",
            "v 1 2 3 4 5\nf 1 1 1\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1 2/1/1 3/1/1\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//9 2//1 3//1\nvn 0 0 1\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -9223372036854775808 1 2\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/2/3/4 2 3\n",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\np 3\nf 1 2 3\nmtllib x.mtl\nusemtl y\n",
            "v 0 0 0 0.5 0.5 0.5\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            "\u{feff}v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n",
        ];
        for (i, obj) in cases.iter().enumerate() {
            let r = load_text("odd.toml", &obj_scene("odd.obj"), &[("odd.obj", obj)], &[]);
            if let Err(e) = r {
                let e = e.to_string();
                assert!(e.contains("odd.toml") && e.contains("odd.obj"), "case {i}: {e}");
            }
        }
    }
}
