//! Import of Mitsuba 3 XML scenes (a documented subset, scenes/README.md "Mitsuba 3 XML"),
//! so that scenes written for mitransient render here: the XML is converted to our TOML
//! description, which then loads like any other (`dtr render scene.xml`, `Scene::load`,
//! Python's `Scene.load`), or is written out by `dtr import` to be read and edited.
//!
//! One file per concept: `xml.rs` (defaults, `$name` substitution, properties, line numbers),
//! `include.rs` (`<include>`d files), `transform.rs`, `bsdf.rs`, `conductors.rs`, `shape.rs`,
//! `emitter.rs`, `sensor.rs`, `integrator.rs`.
//! Anything outside the subset is refused with the file, the element (tag, type, id, line)
//! and what is supported.

mod bsdf;
mod clip;
mod conductors;
mod emitter;
mod include;
mod integrator;
mod mesh_front;
mod sensor;
mod shape;
mod transform;
mod xml;

use super::SceneError;
use roxmltree::Node;
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use toml::{Table, Value};
use xml::Doc;

/// The first line of every description `dtr import` writes begins so: it marks a file that a
/// later import may replace (`cli::import_cmd`).
pub const IMPORT_HEADER: &str = "# Converted from the Mitsuba 3 scene ";

/// An element the importer cannot convert: where (`<tag type=".." id=".."> (line N)`) and why.
#[derive(Debug)]
pub(crate) struct ImportError {
    /// The included file the element is in (`None`: the scene file itself).
    file: Option<PathBuf>,
    at: String,
    message: String,
}

/// A converted scene: our TOML description and, for each of its entries, the XML element it
/// came from (so that a later error about the entry can name that element).
pub struct Imported {
    /// The scene as our TOML description.
    pub toml: String,
    /// `(location prefix in our errors, XML element)`, e.g. `("shape[2]", "<shape ...> (line 9)")`.
    origins: Vec<(String, String)>,
    /// The files the scene `<include>`s (each once), as named from the scene file's folder.
    pub included: Vec<PathBuf>,
    /// The sensor's clip depths, checked against the converted scene ([`Imported::check`]).
    clip: clip::Clip,
    /// What renders otherwise than in Mitsuba and is documented rather than refused, said
    /// once per process when the scene loads ([`Imported::check`]).
    warnings: Vec<String>,
}

impl Imported {
    /// Says, once per process, what renders otherwise than in Mitsuba and is documented
    /// (`warnings`), and refuses the converted `scene` where Mitsuba would render it otherwise
    /// in a way the conversion could not see before the geometry was built: a shape in the
    /// part of the view the sensor's clip planes hide (`clip.rs`).
    pub fn check(&self, scene: &crate::scene::Scene, path: &Path) -> Result<(), SceneError> {
        for w in &self.warnings {
            crate::scene::warnings::warn_once(format!("{}: {w}", path.display()));
        }
        self.clip.check(scene, path)
    }

    /// Adds the XML element to an error about one of the converted entries (its value, or
    /// the mesh file it names: a PLY error named only `shape[3] "ply": field 'file'` until
    /// the forty-fourth session).
    pub fn annotate(&self, e: SceneError) -> SceneError {
        let with_origin = |at: String| {
            let origin = self
                .origins
                .iter()
                .filter(|(prefix, _)| at.starts_with(prefix.as_str()))
                .max_by_key(|(prefix, _)| prefix.len());
            match origin {
                Some((_, el)) => format!("{el}, converted to {at}"),
                None => at,
            }
        };
        match e {
            SceneError::Invalid { path, at, message } => SceneError::Invalid {
                path,
                at: with_origin(at),
                message,
            },
            SceneError::Mesh {
                path,
                at,
                format,
                mesh,
                message,
            } => SceneError::Mesh {
                path,
                at: with_origin(at),
                format,
                mesh,
                message,
            },
            other => other,
        }
    }
}

/// Whether `path` names a Mitsuba XML scene (extension `.xml`, any case).
pub fn is_xml(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("xml"))
}

/// Converts Mitsuba 3 XML text; `source` names the file in messages. Mesh file names are
/// kept as written (relative to the XML file's folder).
pub fn import_str(text: &str, source: &Path) -> Result<Imported, SceneError> {
    import_str_for(text, source, None)
}

/// [`import_str`] for a description that will live in another folder: relative mesh file
/// names are joined to `mesh_base` (the XML file's folder).
fn import_str_for(text: &str, source: &Path, mesh_base: Option<&Path>) -> Result<Imported, SceneError> {
    let invalid = |e: ImportError| SceneError::Invalid {
        path: e.file.unwrap_or_else(|| source.to_path_buf()),
        at: e.at,
        message: e.message,
    };
    let files = include::gather(text, source)?;
    let trees = files
        .sources
        .iter()
        .map(|s| parse(&s.text, &s.path))
        .collect::<Result<Vec<_>, _>>()?;
    let mut docs: Vec<Doc> = Vec::with_capacity(trees.len());
    for (k, (tree, s)) in trees.iter().zip(&files.sources).enumerate() {
        let mut doc = Doc::new(tree.root_element(), &s.text);
        if k > 0 {
            doc.included(s.path.clone(), s.rel_dir.clone());
        }
        doc.check_attributes().map_err(invalid)?;
        docs.push(doc);
    }
    let root = docs[0].root;
    if root.tag_name().name() != "scene" {
        return Err(invalid(
            docs[0].err(root, "the root element must be <scene version=\"3.0.0\">"),
        ));
    }
    match root
        .attribute("version")
        .map(|v| v.split('.').next().unwrap_or("").parse::<u32>())
    {
        Some(Ok(major)) if major >= 2 => {}
        Some(_) => {
            return Err(invalid(docs[0].err(
                root,
                "a Mitsuba 0.x scene (version < 2): its names differ (toWorld, intIOR, ...); \
                 upgrade it to Mitsuba 3 syntax first",
            )));
        }
        None => {
            return Err(invalid(
                docs[0].err(root, "missing attribute 'version' (e.g. version=\"3.0.0\")"),
            ));
        }
    }
    // `<default>` values: a file's own, after those of the file including it (the first
    // definition wins, so the including file's values override an included file's defaults)
    for k in 0..docs.len() {
        if let Some(parent) = files.sources[k].parent {
            let inherited = docs[parent].defaults().clone();
            docs[k].inherit(inherited);
        }
        let doc = &mut docs[k];
        for c in doc
            .root
            .children()
            .filter(|c| c.is_element() && c.tag_name().name() == "default")
        {
            doc.add_default(c).map_err(invalid)?;
        }
    }
    let mut items = Vec::new();
    include::flatten(&docs, &files.links, 0, &mut items).map_err(invalid)?;
    let scene_dir = source.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut conv = Converter::new(&docs[0], mesh_base, scene_dir);
    conv.scene(root, &items).map_err(invalid)?;
    let mut imported = conv.finish(source);
    for s in &files.sources[1..] {
        if !imported.included.contains(&s.path) {
            imported.included.push(s.path.clone());
        }
    }
    Ok(imported)
}

/// Parses one file of the scene (DTDs refused).
fn parse<'t>(text: &'t str, path: &Path) -> Result<roxmltree::Document<'t>, SceneError> {
    let opts = roxmltree::ParsingOptions {
        allow_dtd: false,
        ..Default::default()
    };
    roxmltree::Document::parse_with_options(text, opts).map_err(|e| {
        let pos = e.pos();
        SceneError::Syntax {
            path: path.to_path_buf(),
            format: "XML",
            line: pos.row as usize,
            column: pos.col as usize,
            message: e.to_string(),
        }
    })
}

/// Reads and converts a Mitsuba XML file.
pub fn import(path: &Path) -> Result<Imported, SceneError> {
    import_for(path, None)
}

/// Reads and converts a Mitsuba XML file for a description written into the folder
/// `out_dir`: when that is not the XML file's folder, relative mesh file names are made
/// absolute (joined to the XML file's folder), so the description finds them.
pub fn import_for(path: &Path, out_dir: Option<&Path>) -> Result<Imported, SceneError> {
    let text = super::read::read_regular_file(path, super::read::MAX_SCENE_BYTES).map_err(|err| SceneError::Io {
        path: path.to_path_buf(),
        err,
    })?;
    let base = out_dir.and_then(|out| crate::scene::shapes::file_base_for(path, out));
    import_str_for(&text, path, base.as_deref())
}

struct Converter<'d, 'a, 'input> {
    doc: &'d Doc<'a, 'input>,
    mesh_base: Option<&'d Path>,
    /// The scene file's folder (mesh files are read from it to check what Mitsuba reads).
    scene_dir: PathBuf,
    /// top-level `<bsdf id>` elements (of this file and the files it includes)
    bsdf_ids: bsdf::BsdfIds<'d, 'a, 'input>,
    /// id → material name, for BSDFs already converted
    converted: HashMap<String, (String, bool)>,
    names: HashMap<&'static str, HashSet<String>>,
    materials: Vec<Value>,
    shapes: Vec<Value>,
    emitters: Vec<Value>,
    integrator: Option<(Table, bool)>,
    sensor: Option<sensor::Sensor>,
    origins: Vec<(String, String)>,
    warnings: Vec<String>,
}

impl<'d, 'a, 'input> Converter<'d, 'a, 'input> {
    fn new(doc: &'d Doc<'a, 'input>, mesh_base: Option<&'d Path>, scene_dir: PathBuf) -> Self {
        Converter {
            doc,
            mesh_base,
            scene_dir,
            bsdf_ids: HashMap::new(),
            converted: HashMap::new(),
            names: HashMap::new(),
            materials: Vec::new(),
            shapes: Vec::new(),
            emitters: Vec::new(),
            integrator: None,
            sensor: None,
            origins: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// A unique name in `section`, from `wanted`.
    fn name(&mut self, section: &'static str, wanted: &str) -> String {
        let set = self.names.entry(section).or_default();
        let mut name = wanted.to_string();
        let mut k = 2;
        while set.contains(&name) {
            name = format!("{wanted}_{k}");
            k += 1;
        }
        set.insert(name.clone());
        name
    }

    /// Converts the scene's elements, `items`: the children of `root` with each `<include>`
    /// replaced by the children of the file it names, each with the file it is in.
    fn scene(
        &mut self,
        root: Node<'a, 'input>,
        items: &[(&'d Doc<'a, 'input>, Node<'a, 'input>)],
    ) -> Result<(), ImportError> {
        let main = self.doc;
        // Mitsuba 3 refuses two objects of one id, whatever their kinds: so do we, for the
        // top-level elements and the emitters and BSDFs inside shapes (before, a second
        // <shape> or <emitter> of an id was renamed "_2" without a word)
        let mut ids: HashMap<String, String> = HashMap::new();
        for &(doc, c) in items {
            let nested = c
                .children()
                .filter(|n| c.tag_name().name() == "shape" && matches!(n.tag_name().name(), "emitter" | "bsdf"));
            for node in std::iter::once(c).chain(nested) {
                if let Some(id) = doc.attr(node, "id")?
                    && let Some(first) = ids.insert(id.clone(), doc.describe(node))
                {
                    return Err(doc.err(
                        node,
                        format!("a second element with id {id:?} (the first is {first}); ids must be unique"),
                    ));
                }
            }
            if c.tag_name().name() == "bsdf" {
                let id = doc.attr(c, "id")?.ok_or_else(|| {
                    doc.err(
                        c,
                        "a top-level <bsdf> needs an id (shapes refer to it with <ref id=...>)",
                    )
                })?;
                self.bsdf_ids.insert(id, (doc, c));
            }
        }
        for &(doc, c) in items {
            self.doc = doc;
            match c.tag_name().name() {
                "bsdf" => {
                    let id = doc.req_attr(c, "id")?;
                    self.material_by_id(&id, c)?;
                }
                "shape" => self.shape(c)?,
                "emitter" => {
                    let mut t = emitter::top_level(doc, c)?;
                    let name = self.name("emitter", &doc.attr(c, "id")?.unwrap_or_else(|| "point".into()));
                    self.origins
                        .push((format!("emitter[{}]", self.emitters.len()), doc.describe(c)));
                    t.insert("name".into(), name.into());
                    self.emitters.push(Value::Table(t));
                }
                "sensor" => {
                    if self.sensor.is_some() {
                        return Err(doc.err(c, "a second <sensor>: one camera per scene"));
                    }
                    self.origins.push(("camera".into(), doc.describe(c)));
                    self.origins.push(("film".into(), doc.describe(c)));
                    self.sensor = Some(sensor::sensor(doc, c)?);
                }
                "integrator" => {
                    if self.integrator.is_some() {
                        return Err(doc.err(c, "a second <integrator>"));
                    }
                    self.origins.push(("integrator".into(), doc.describe(c)));
                    self.integrator = Some(integrator::integrator(doc, c)?);
                }
                other => {
                    return Err(doc.err(
                        c,
                        format!(
                            "<{other}> is not supported at the top level (supported: default, include, bsdf, \
                             shape, emitter, sensor, integrator)"
                        ),
                    ));
                }
            }
        }
        self.doc = main;
        let doc = main;
        if self.sensor.is_none() {
            return Err(doc.err(
                root,
                "no <sensor>: a perspective sensor with a transient_hdr_film is required",
            ));
        }
        if self.integrator.is_none() {
            return Err(doc.err(root, "no <integrator>: add <integrator type=\"transient_path\">"));
        }
        Ok(())
    }

    /// The material of a top-level BSDF (converted once) and whether it is a dielectric.
    fn material_by_id(&mut self, id: &str, at: Node) -> Result<(String, bool), ImportError> {
        if let Some(m) = self.converted.get(id) {
            return Ok(m.clone());
        }
        let &(doc, node) = self
            .bsdf_ids
            .get(id)
            .ok_or_else(|| self.doc.err(at, format!("no <bsdf id={id:?}> in this file")))?;
        let m = self.add_material(doc, node, id)?;
        self.converted.insert(id.to_string(), m.clone());
        Ok(m)
    }

    fn add_material(&mut self, doc: &Doc, node: Node, wanted: &str) -> Result<(String, bool), ImportError> {
        let m = bsdf::material(doc, node, &self.bsdf_ids, &[])?;
        let name = self.name("material", wanted);
        self.origins
            .push((format!("material[{}]", self.materials.len()), doc.describe(node)));
        let mut t = m.table;
        t.insert("name".into(), name.clone().into());
        self.materials.push(Value::Table(t));
        Ok((name, m.dielectric))
    }

    /// Whether the converted material named `name` is one-sided.
    fn is_one_sided(&self, name: &str) -> bool {
        self.materials.iter().any(|m| {
            m.get("name").and_then(Value::as_str) == Some(name)
                && m.get("one_sided").and_then(Value::as_bool) == Some(true)
        })
    }

    /// The diffuse material of albedo `albedo` that shapes with no `<bsdf>` share, made once
    /// under `key` with the name `wanted`: one-sided, as Mitsuba's default BSDF.
    fn default_diffuse(&mut self, key: &str, wanted: &str, albedo: f64) -> (String, bool) {
        if let Some(m) = self.converted.get(key) {
            return m.clone();
        }
        let name = self.name("material", wanted);
        let mut t = Table::new();
        t.insert("name".into(), name.clone().into());
        t.insert("type".into(), "diffuse".into());
        t.insert("albedo".into(), Value::Float(albedo));
        t.insert("one_sided".into(), Value::Boolean(true));
        self.materials.push(Value::Table(t));
        self.converted.insert(key.into(), (name.clone(), false));
        (name, false)
    }

    fn shape(&mut self, node: Node<'a, 'input>) -> Result<(), ImportError> {
        let doc = self.doc;
        let p = doc.props(node);
        let ty = doc.req_attr(node, "type")?;
        let name = self.name("shape", &doc.attr(node, "id")?.unwrap_or_else(|| ty.clone()));
        let (material, dielectric) = match shape::bsdf_source(doc, &p)? {
            shape::BsdfSource::Ref(id, r) => self.material_by_id(&id, r)?,
            shape::BsdfSource::Inline(b) => {
                let wanted = doc.attr(b, "id")?.unwrap_or_else(|| format!("{name}_bsdf"));
                self.add_material(doc, b, &wanted)?
            }
            // Mitsuba's default: diffuse 0.5, but black on an emitting shape (its Shape gives an
            // emitter without a BSDF a reflectance of 0; an emitter read 0.5 here, and a lit
            // lamp shone 5.6× too bright, until the forty-third session: helper 39)
            shape::BsdfSource::Default => match p.nested("emitter").is_empty() {
                true => self.default_diffuse("\0default", "default_diffuse", 0.5),
                false => self.default_diffuse("\0default_emitter", "default_emitter_black", 0.0),
            },
        };
        let emitters = p.nested("emitter");
        if emitters.len() > 1 {
            return Err(doc.err(emitters[1], "a shape takes at most one emitter"));
        }
        let emitter = match emitters.first() {
            Some(e) => Some((emitter::area(doc, *e)?, *e)),
            None => None,
        };
        let geo = shape::geometry(doc, &p)?;
        if geo.smooth_in_mitsuba {
            // documented, not refused: a flat-faced mesh renders alike (helper 39: z 16.5 on
            // a curved one, silently, until the forty-third session)
            self.warnings.push(format!(
                "{}: shaded with its face normals here, while Mitsuba 3 interpolates this mesh's vertex normals \
                 (face_normals is not true): a curved mesh shades differently; add <boolean name=\"face_normals\" \
                 value=\"true\"/> to render it alike in both",
                doc.describe(node)
            ));
        }
        // where a side is told apart, ours must be Mitsuba's (`shape::Geometry`); a mesh
        // Mitsuba shades with its vertex normals faces where they point (`mesh_front.rs`)
        let sided = emitter.is_some() || dielectric || self.is_one_sided(&material);
        // the mesh file as this process reads it (`file` is relative to the XML file naming it)
        let mesh = geo.table.get("file").and_then(Value::as_str).map(|f| {
            let ply = geo.table.get("type").and_then(Value::as_str) == Some("ply");
            (f.to_string(), self.scene_dir.join(doc.rel_dir()).join(f), ply)
        });
        if let Some((f, on_disk, true)) = &mesh
            && let Some(what) = crate::scene::ply::integer_coordinates(on_disk)
        {
            return Err(doc.err(
                node,
                format!(
                    "{f}: its vertex coordinates are stored as integers ({what}), which Mitsuba 3 does not read \
                     as metres (its mesh shrinks to almost nothing there); store them as float"
                ),
            ));
        }
        let mut front_flipped = geo.front_flipped;
        if let (true, true, Some((f, on_disk, ply))) = (sided, geo.smooth_in_mitsuba, &mesh) {
            use mesh_front::StoredNormals;
            // (a file that cannot be read is the scene loader's to report)
            match mesh_front::stored_normals(on_disk, *ply) {
                Ok(StoredNormals::None) | Err(_) => {}
                Ok(StoredNormals::WithWinding) => front_flipped = geo.flip_normals,
                Ok(StoredNormals::AgainstWinding) => front_flipped = !geo.flip_normals,
                Ok(StoredNormals::Mixed { against, faces }) => {
                    return Err(doc.err(
                        node,
                        format!(
                            "{f}: Mitsuba shades this mesh with its vertex normals (face_normals is not true) and takes \
                             each face's front from them, but they point against the winding on {against} of its \
                             {faces} faces; it emits, is a dielectric or has a one-sided BSDF, where the side matters: \
                             orient the mesh's faces, or add <boolean name=\"face_normals\" value=\"true\"/>"
                        ),
                    ));
                }
            }
        }
        if front_flipped && dielectric {
            return Err(doc.err(
                node,
                "this dielectric shape is turned inside out (flip_normals or a mirroring to_world), so the rest of \
                 the scene would lie inside it; remove the mirror or flip_normals",
            ));
        }
        self.origins
            .push((format!("shape[{}]", self.shapes.len()), doc.describe(node)));
        let mut t = geo.table;
        if front_flipped {
            t.insert("flip_normals".into(), Value::Boolean(true));
        }
        // mesh file names are relative to the file that names them: to the scene file's
        // folder through an included file's folder, then to where the description will live
        if let Some(Value::String(f)) = t.get("file")
            && Path::new(f).is_relative()
        {
            let mut name = doc.rel_dir().join(f);
            if let Some(base) = self.mesh_base {
                name = base.join(name);
            }
            t.insert("file".into(), name.to_string_lossy().into_owned().into());
        }
        t.insert("name".into(), name.clone().into());
        t.insert("material".into(), material.into());
        self.shapes.push(Value::Table(t));
        if let Some((mut e, e_node)) = emitter {
            let wanted = doc.attr(e_node, "id")?.unwrap_or_else(|| format!("{name}_emitter"));
            let en = self.name("emitter", &wanted);
            self.origins
                .push((format!("emitter[{}]", self.emitters.len()), doc.describe(e_node)));
            e.insert("name".into(), en.into());
            e.insert("shape".into(), name.into());
            self.emitters.push(Value::Table(e));
        }
        Ok(())
    }

    fn finish(self, source: &Path) -> Imported {
        let (mut integ, unwarp) = self.integrator.unwrap_or_default();
        let s = self.sensor.expect("checked in scene()");
        integ.insert("spp".into(), s.spp.into());
        integ.insert("seed".into(), s.seed.into());
        let mut film = s.film;
        film.insert("unwarp".into(), unwarp.into());
        let mut text = format!(
            "{IMPORT_HEADER}{} by dtr import (scenes/README.md, \"Mitsuba 3 XML\").\n",
            source.display()
        );
        for (at, el) in &self.origins {
            text.push_str(&format!("# {at} <- {el}\n"));
        }
        write_table(&mut text, "[integrator]", &integ);
        write_table(&mut text, "[camera]", &s.camera);
        write_table(&mut text, "[film]", &film);
        for (header, items) in [
            ("[[material]]", &self.materials),
            ("[[shape]]", &self.shapes),
            ("[[emitter]]", &self.emitters),
        ] {
            for item in items {
                if let Value::Table(t) = item {
                    write_table(&mut text, header, t);
                }
            }
        }
        let element = self
            .origins
            .iter()
            .find(|(at, _)| at == "camera")
            .map(|(_, el)| el.clone());
        Imported {
            toml: text,
            clip: clip::Clip {
                near: s.clip.0,
                far: s.clip.1,
                element: element.unwrap_or_else(|| "<sensor>".into()),
            },
            origins: self.origins,
            included: Vec::new(),
            warnings: self.warnings,
        }
    }
}

/// Appends `header` and the table's `key = value` lines, `name` and `type` first.
fn write_table(out: &mut String, header: &str, t: &Table) {
    out.push('\n');
    out.push_str(header);
    out.push('\n');
    let first = ["name", "type"];
    let keys = first
        .iter()
        .filter(|k| t.contains_key(**k))
        .copied()
        .chain(t.keys().map(String::as_str).filter(|k| !first.contains(k)));
    for k in keys {
        out.push_str(&format!("{k} = {}\n", t[k]));
    }
}
