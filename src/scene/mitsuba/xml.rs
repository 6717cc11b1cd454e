//! The XML layer of the Mitsuba 3 importer: `<default>` values and `$name` substitution,
//! where each element is (its line, for messages), and the named properties of a plugin
//! (`<float name=... value=...>` and the like), each of which must be used by the converter
//! or is refused by name.

use super::ImportError;
use roxmltree::Node;
use std::cell::Cell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The document with its `<default>` values.
pub(crate) struct Doc<'a, 'input> {
    pub root: Node<'a, 'input>,
    text: &'input str,
    defaults: HashMap<String, String>,
    /// For a file the scene `<include>`s: its path (errors name it) and its folder relative
    /// to the scene file's folder (mesh file names in it are relative to that).
    included: Option<(PathBuf, PathBuf)>,
}

/// The tags that hold a property value (the others are plugins or structure).
const PROPERTY_TAGS: [&str; 10] = [
    "float",
    "integer",
    "boolean",
    "string",
    "point",
    "vector",
    "rgb",
    "spectrum",
    "transform",
    "ref",
];

impl<'a, 'input> Doc<'a, 'input> {
    pub fn new(root: Node<'a, 'input>, text: &'input str) -> Self {
        Doc {
            root,
            text,
            defaults: HashMap::new(),
            included: None,
        }
    }

    /// Marks this document as the included file `path`, in the folder `rel_dir` relative to
    /// the scene file's folder.
    pub fn included(&mut self, path: PathBuf, rel_dir: PathBuf) {
        self.included = Some((path, rel_dir));
    }

    /// The folder of this file relative to the scene file's folder (empty for the scene file).
    pub fn rel_dir(&self) -> &Path {
        self.included.as_ref().map_or(Path::new(""), |(_, d)| d.as_path())
    }

    /// The `<default>` values recorded so far.
    pub fn defaults(&self) -> &HashMap<String, String> {
        &self.defaults
    }

    /// Takes the values of the file that includes this one; they win over this file's own.
    pub fn inherit(&mut self, defaults: HashMap<String, String>) {
        self.defaults.extend(defaults);
    }

    /// Records a `<default name=... value=...>` (the first definition wins, as in Mitsuba,
    /// where a value given at load time overrides the file's default).
    pub fn add_default(&mut self, node: Node) -> Result<(), ImportError> {
        let name = self.raw_attr(node, "name")?;
        let value = self.raw_attr(node, "value")?;
        self.defaults
            .entry(name.to_string())
            .or_insert_with(|| value.to_string());
        Ok(())
    }

    /// 1-based line of `node`'s start tag.
    pub fn line(&self, node: Node) -> u32 {
        self.text_pos(node.range().start)
    }

    fn text_pos(&self, byte: usize) -> u32 {
        1 + self.text[..byte.min(self.text.len())]
            .bytes()
            .filter(|&b| b == b'\n')
            .count() as u32
    }

    /// `<shape type="rectangle" id="floor"> (line 12)`: how messages name an element.
    pub fn describe(&self, node: Node) -> String {
        let mut s = format!("<{}", node.tag_name().name());
        for key in ["type", "name", "id"] {
            if let Some(v) = node.attribute(key) {
                s.push_str(&format!(" {key}=\"{v}\""));
            }
        }
        match &self.included {
            None => format!("{s}> (line {})", self.line(node)),
            Some((path, _)) => format!("{s}> (line {} of {})", self.line(node), path.display()),
        }
    }

    /// An error about `node`.
    pub fn err(&self, node: Node, message: impl Into<String>) -> ImportError {
        ImportError {
            file: self.included.as_ref().map(|(p, _)| p.clone()),
            at: self.describe(node),
            message: message.into(),
        }
    }

    fn raw_attr<'n>(&self, node: Node<'n, 'input>, key: &str) -> Result<&'n str, ImportError> {
        node.attribute(key)
            .ok_or_else(|| self.err(node, format!("missing attribute '{key}'")))
    }

    /// Attribute `key` with `$name` replaced by its `<default>` value.
    pub fn attr(&self, node: Node, key: &str) -> Result<Option<String>, ImportError> {
        match node.attribute(key) {
            None => Ok(None),
            Some(v) => self.substitute(node, v).map(Some),
        }
    }

    /// A required attribute, substituted.
    pub fn req_attr(&self, node: Node, key: &str) -> Result<String, ImportError> {
        self.attr(node, key)?
            .ok_or_else(|| self.err(node, format!("missing attribute '{key}'")))
    }

    fn substitute(&self, node: Node, v: &str) -> Result<String, ImportError> {
        let mut out = String::new();
        let mut rest = v;
        while let Some(i) = rest.find('$') {
            out.push_str(&rest[..i]);
            let tail = &rest[i + 1..];
            let len = tail
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .unwrap_or(tail.len());
            let name = &tail[..len];
            match self.defaults.get(name) {
                Some(val) if !name.is_empty() => out.push_str(val),
                _ => {
                    return Err(self.err(
                        node,
                        format!("${name} has no value: declare it with <default name=\"{name}\" value=\"...\"/>"),
                    ));
                }
            }
            rest = &tail[len..];
        }
        out.push_str(rest);
        Ok(out)
    }

    /// The element children of `node` (comments and text skipped).
    pub fn children(&self, node: Node<'a, 'input>) -> impl Iterator<Item = Node<'a, 'input>> {
        node.children().filter(|c| c.is_element())
    }

    /// The properties and nested plugins of a plugin element.
    pub fn props(&self, node: Node<'a, 'input>) -> Props<'a, 'input> {
        let mut props = Vec::new();
        let mut nested = Vec::new();
        for c in self.children(node) {
            if PROPERTY_TAGS.contains(&c.tag_name().name()) {
                props.push((c, Cell::new(false)));
            } else {
                nested.push((c, Cell::new(false)));
            }
        }
        Props { node, props, nested }
    }

    /// Numbers separated by commas and/or spaces.
    pub fn numbers(&self, node: Node, s: &str) -> Result<Vec<f64>, ImportError> {
        s.split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .map(|t| {
                t.parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| self.err(node, format!("expected a finite number, got {t:?}")))
            })
            .collect()
    }

    /// One number.
    pub fn number(&self, node: Node, s: &str) -> Result<f64, ImportError> {
        match self.numbers(node, s)?.as_slice() {
            [x] => Ok(*x),
            v => Err(self.err(node, format!("expected one number, got {} in {s:?}", v.len()))),
        }
    }

    /// A 3-vector from `value="x, y, z"` or `x=".." y=".." z=".."` (missing ones are
    /// `default`).
    /// Three numbers from `value` (one or three of them) or from `x`, `y`, `z`, which may not
    /// be mixed with `value` (Mitsuba refuses that too). A missing coordinate is `default`,
    /// or, with `None` (a `<point>` or `<vector>`), an error as in Mitsuba (until the
    /// forty-fourth session it became 0, helper 41).
    pub fn vector3(&self, node: Node, default: Option<f64>) -> Result<[f64; 3], ImportError> {
        let xyz = ["x", "y", "z"];
        if let Some(v) = self.attr(node, "value")? {
            if let Some(k) = xyz.iter().find(|k| node.attribute(**k).is_some()) {
                return Err(self.err(node, format!("give either 'value' or 'x', 'y', 'z', not both ('{k}')")));
            }
            let n = self.numbers(node, &v)?;
            return match n.as_slice() {
                [a, b, c] => Ok([*a, *b, *c]),
                [a] => Ok([*a; 3]),
                _ => Err(self.err(node, format!("expected 1 or 3 numbers, got {} in {v:?}", n.len()))),
            };
        }
        let mut out = [0.0; 3];
        for (i, k) in xyz.iter().enumerate() {
            out[i] = match (self.attr(node, k)?, default) {
                (Some(v), _) => self.number(node, &v)?,
                (None, Some(d)) => d,
                (None, None) => return Err(self.err(node, format!("missing attribute '{k}' (or give 'value')"))),
            };
        }
        Ok(out)
    }

    /// Refuses an attribute Mitsuba 3 does not know on its element (a misspelt `X=` was
    /// dropped without a word until the forty-fourth session, helper 41). Elements of other
    /// tags are left to whoever reads them.
    pub fn check_attributes(&self) -> Result<(), ImportError> {
        for node in self.root.descendants().filter(|n| n.is_element()) {
            let tag = node.tag_name().name();
            let Some(allowed) = allowed_attributes(tag) else {
                continue;
            };
            if let Some(a) = node.attributes().find(|a| !allowed.contains(&a.name())) {
                return Err(self.err(
                    node,
                    format!(
                        "unexpected attribute '{}' on <{tag}> (Mitsuba 3 takes: {})",
                        a.name(),
                        allowed.join(", ")
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// The attributes Mitsuba 3's parser accepts on element `tag` (`None`: a tag it does not know).
fn allowed_attributes(tag: &str) -> Option<&'static [&'static str]> {
    Some(match tag {
        "scene" => &["version"],
        "default" => &["name", "value"],
        "include" => &["filename"],
        "alias" => &["id", "as"],
        "path" => &["value"],
        "ref" => &["id", "name"],
        "float" | "integer" | "boolean" | "string" => &["name", "value"],
        "rgb" => &["name", "value"],
        "spectrum" => &["name", "value", "filename"],
        "point" | "vector" => &["name", "value", "x", "y", "z"],
        "transform" => &["name"],
        "translate" | "scale" => &["value", "x", "y", "z"],
        "rotate" => &["value", "x", "y", "z", "angle"],
        "matrix" => &["value"],
        "lookat" => &["origin", "target", "up"],
        "bsdf" | "shape" | "emitter" | "sensor" | "film" | "sampler" | "rfilter" | "integrator" | "texture"
        | "medium" | "phase" | "volume" => &["type", "id", "name"],
        _ => return None,
    })
}

/// Linear sRGB of the equal-energy illuminant of luminance 1 (CIE XYZ (1, 1, 1)): the row sums
/// of the usual XYZ → linear sRGB matrix (IEC 61966-2-1, to six digits, as pbrt writes it),
/// (1.2048, 0.9483, 0.9089). Mitsuba 3.9.1's `scalar_rgb` variant renders a constant
/// `<spectrum value="1">` emitter as (1.205, 0.948, 0.909) (measured, helper 39).
pub(crate) const EQUAL_ENERGY_SRGB: [f64; 3] = [
    3.240479 - 1.537150 - 0.498535,
    -0.969256 + 1.875991 + 0.041556,
    0.055648 - 0.204043 + 1.057311,
];

/// A colour (or a scalar given where a colour is expected).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Colour {
    Scalar(f64),
    Rgb([f64; 3]),
}

/// The named properties and nested plugins of one plugin element; each is marked when the
/// converter reads it, and [`Props::finish`] refuses what was never read.
pub(crate) struct Props<'a, 'input> {
    pub node: Node<'a, 'input>,
    props: Vec<(Node<'a, 'input>, Cell<bool>)>,
    nested: Vec<(Node<'a, 'input>, Cell<bool>)>,
}

impl<'a, 'input> Props<'a, 'input> {
    /// The property named `name` (marked as used).
    pub fn get(&self, doc: &Doc, name: &str) -> Result<Option<Node<'a, 'input>>, ImportError> {
        for (n, used) in &self.props {
            if n.tag_name().name() != "ref" && doc.attr(*n, "name")?.as_deref() == Some(name) {
                used.set(true);
                return Ok(Some(*n));
            }
        }
        Ok(None)
    }

    fn typed(&self, doc: &Doc, name: &str, tags: &[&str]) -> Result<Option<Node<'a, 'input>>, ImportError> {
        match self.get(doc, name)? {
            Some(n) if !tags.contains(&n.tag_name().name()) => Err(doc.err(
                n,
                format!("property '{name}' must be given as <{}>", tags.join("> or <")),
            )),
            other => Ok(other),
        }
    }

    pub fn float(&self, doc: &Doc, name: &str) -> Result<Option<f64>, ImportError> {
        match self.typed(doc, name, &["float", "integer"])? {
            Some(n) => Ok(Some(doc.number(n, &doc.req_attr(n, "value")?)?)),
            None => Ok(None),
        }
    }

    pub fn integer(&self, doc: &Doc, name: &str) -> Result<Option<i64>, ImportError> {
        match self.typed(doc, name, &["integer"])? {
            Some(n) => {
                let v = doc.req_attr(n, "value")?;
                v.trim()
                    .parse::<i64>()
                    .map(Some)
                    .map_err(|_| doc.err(n, format!("expected an integer, got {v:?}")))
            }
            None => Ok(None),
        }
    }

    pub fn boolean(&self, doc: &Doc, name: &str) -> Result<Option<bool>, ImportError> {
        match self.typed(doc, name, &["boolean"])? {
            Some(n) => match doc.req_attr(n, "value")?.trim() {
                "true" => Ok(Some(true)),
                "false" => Ok(Some(false)),
                v => Err(doc.err(n, format!("expected true or false, got {v:?}"))),
            },
            None => Ok(None),
        }
    }

    pub fn string(&self, doc: &Doc, name: &str) -> Result<Option<(String, Node<'a, 'input>)>, ImportError> {
        match self.typed(doc, name, &["string"])? {
            Some(n) => Ok(Some((doc.req_attr(n, "value")?, n))),
            None => Ok(None),
        }
    }

    pub fn point(&self, doc: &Doc, name: &str) -> Result<Option<[f64; 3]>, ImportError> {
        match self.typed(doc, name, &["point", "vector"])? {
            Some(n) => Ok(Some(doc.vector3(n, None)?)),
            None => Ok(None),
        }
    }

    pub fn transform(&self, doc: &Doc, name: &str) -> Result<Option<Node<'a, 'input>>, ImportError> {
        self.typed(doc, name, &["transform"])
    }

    /// A colour: `<rgb value="r, g, b">` (or one value), `<spectrum value="v">` (a constant
    /// spectrum), or `<float>`. Textures and sampled spectra are refused.
    pub fn colour(&self, doc: &Doc, name: &str) -> Result<Option<Colour>, ImportError> {
        Ok(self.colour_and_tag(doc, name)?.map(|(c, _)| c))
    }

    /// An emitter's colour (`radiance`, `intensity`) as [`Props::colour`], except that a
    /// constant `<spectrum value="v">` is the light of that spectrum, as Mitsuba 3 reads it in
    /// an emitter: an equal-energy illuminant, which is not white in linear sRGB (its CIE 1931
    /// XYZ is (v, v, v), [`EQUAL_ENERGY_SRGB`] · v in sRGB). Until the forty-third session it
    /// became (v, v, v): light 20 % too blue-green against Mitsuba (helper 39).
    pub fn emission(&self, doc: &Doc, name: &str) -> Result<Option<Colour>, ImportError> {
        Ok(self
            .colour_and_tag(doc, name)?
            .map(|(c, spectrum)| match (c, spectrum) {
                (Colour::Scalar(v), true) => Colour::Rgb(EQUAL_ENERGY_SRGB.map(|k| k * v)),
                (c, _) => c,
            }))
    }

    /// [`Props::colour`], and whether it was given as a `<spectrum>`.
    fn colour_and_tag(&self, doc: &Doc, name: &str) -> Result<Option<(Colour, bool)>, ImportError> {
        if let Some(t) = self.nested_named(doc, name)? {
            return Err(doc.err(
                t,
                format!(
                    "'{name}' given as a <{}>: textures are not supported, give a constant <rgb> or <float>",
                    t.tag_name().name()
                ),
            ));
        }
        let Some(n) = self.typed(doc, name, &["rgb", "spectrum", "float"])? else {
            return Ok(None);
        };
        if n.attribute("filename").is_some() {
            return Err(doc.err(
                n,
                "spectra from files are not supported: give a constant <rgb> or <float>",
            ));
        }
        let v = doc.req_attr(n, "value")?;
        if n.tag_name().name() == "spectrum" && v.contains(':') {
            return Err(doc.err(
                n,
                "sampled spectra (wavelength:value pairs) are not supported: give an <rgb> or one constant value",
            ));
        }
        let spectrum = n.tag_name().name() == "spectrum";
        match doc.numbers(n, &v)?.as_slice() {
            [x] => Ok(Some((Colour::Scalar(*x), spectrum))),
            [r, g, b] if n.tag_name().name() == "rgb" => Ok(Some((Colour::Rgb([*r, *g, *b]), false))),
            other => Err(doc.err(
                n,
                format!("expected one value or an rgb triple, got {} values", other.len()),
            )),
        }
    }

    /// A nested plugin element given as the property `name` (a texture, say).
    fn nested_named(&self, doc: &Doc, name: &str) -> Result<Option<Node<'a, 'input>>, ImportError> {
        for (n, used) in &self.nested {
            if doc.attr(*n, "name")?.as_deref() == Some(name) {
                used.set(true);
                return Ok(Some(*n));
            }
        }
        Ok(None)
    }

    /// The nested plugins with tag `tag` and the `<ref>`s (marked as used).
    pub fn nested(&self, tag: &str) -> Vec<Node<'a, 'input>> {
        self.nested
            .iter()
            .filter(|(n, _)| n.tag_name().name() == tag)
            .map(|(n, used)| {
                used.set(true);
                *n
            })
            .collect()
    }

    /// The `<ref id=..>` children (marked as used).
    pub fn refs(&self) -> Vec<Node<'a, 'input>> {
        self.props
            .iter()
            .filter(|(n, _)| n.tag_name().name() == "ref")
            .map(|(n, used)| {
                used.set(true);
                *n
            })
            .collect()
    }

    /// Marks `names` as read without using them (properties with no effect here).
    pub fn ignore(&self, doc: &Doc, names: &[&str]) -> Result<(), ImportError> {
        for n in names {
            self.get(doc, n)?;
        }
        Ok(())
    }

    /// Refuses the first property or nested element that was never read, naming what the
    /// plugin supports.
    pub fn finish(&self, doc: &Doc, supported: &str) -> Result<(), ImportError> {
        for (n, used) in self.props.iter().chain(&self.nested) {
            let name = n.attribute("name");
            let twice = name.is_some()
                && self
                    .props
                    .iter()
                    .chain(&self.nested)
                    .any(|(m, u)| u.get() && m != n && m.attribute("name") == name);
            if !used.get() && twice {
                return Err(doc.err(
                    *n,
                    format!(
                        "property '{}' is given twice inside {} (Mitsuba 3 refuses that too)",
                        name.unwrap_or_default(),
                        doc.describe(self.node)
                    ),
                ));
            }
            if !used.get() {
                return Err(doc.err(
                    *n,
                    format!(
                        "not supported inside {} (supported: {supported})",
                        doc.describe(self.node)
                    ),
                ));
            }
        }
        Ok(())
    }
}
