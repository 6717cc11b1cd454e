//! [`SceneError`]: everything that can be wrong with a scene description, each message naming
//! the file, where in it (a field path such as `shape[2] "box": field 'scale'`) and what was
//! expected.

use std::path::{Path, PathBuf};

/// A scene that could not be loaded. `Display` gives one line:
/// `FILE: LOCATION: WHAT WAS WRONG AND WHAT WAS EXPECTED`.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read.
    #[error("{}: cannot read the scene file: {err}", path.display())]
    Io {
        /// The scene file.
        path: PathBuf,
        /// The error of the read.
        err: std::io::Error,
    },
    /// The file name has none of the extensions `.toml`, `.json`, `.xml`.
    #[error("{}: unknown scene format: expected a file ending in .toml, .json or .xml (Mitsuba 3)", path.display())]
    UnknownFormat {
        /// The scene file.
        path: PathBuf,
    },
    /// The text is not valid TOML / JSON / XML.
    #[error("{}: {format} syntax error at line {line}, column {column}: {message}", path.display())]
    Syntax {
        /// The scene file.
        path: PathBuf,
        /// "TOML" or "JSON".
        format: &'static str,
        /// Line of the error, counted from 1 (0 when the parser gave no position).
        line: usize,
        /// Column of the error, counted from 1 (0 when the parser gave no position).
        column: usize,
        /// The parser's description of the error.
        message: String,
    },
    /// A value in the description is missing, of the wrong type, out of range or refers to
    /// something that does not exist. `at` is the location, e.g. `camera: field 'fov'`.
    #[error("{}: {at}: {message}", path.display())]
    Invalid {
        /// The scene file.
        path: PathBuf,
        /// Where in the description, e.g. `shape[2] "box": field 'scale'`.
        at: String,
        /// What was wrong and what was expected.
        message: String,
    },
    /// A `--set NAME=VALUE` override that cannot be applied.
    #[error("{}: --set {name}: {message}", path.display())]
    Override {
        /// The scene file.
        path: PathBuf,
        /// The overridden name: a `[[param]]` or a dotted field path such as `camera.fov`.
        name: String,
        /// What was wrong and what was expected.
        message: String,
    },
    /// An OBJ or PLY mesh referenced by a shape is missing or malformed.
    #[error("{}: {at}: {format} file {}: {message}", path.display(), mesh.display())]
    Mesh {
        /// The scene file.
        path: PathBuf,
        /// The shape that names the mesh, e.g. `shape[0] "bunny": field 'file'`.
        at: String,
        /// The format the mesh was read as: "OBJ" or "PLY" (the shape's type).
        format: &'static str,
        /// The mesh file.
        mesh: PathBuf,
        /// What was wrong with it.
        message: String,
    },
}

impl SceneError {
    /// The scene file the error is about.
    pub fn path(&self) -> &Path {
        match self {
            SceneError::Io { path, .. }
            | SceneError::UnknownFormat { path }
            | SceneError::Syntax { path, .. }
            | SceneError::Invalid { path, .. }
            | SceneError::Override { path, .. }
            | SceneError::Mesh { path, .. } => path,
        }
    }
}

/// One step of a path into the description: a table key or an array index.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Seg {
    Key(String),
    Index(usize),
}

/// The arrays of named tables (`[[shape]]`, ...) whose entries are called by index and name.
pub(crate) const ITEM_SECTIONS: [&str; 4] = ["shape", "material", "emitter", "param"];

/// `shape[1] "wall"` (name if known).
pub(crate) fn item(section: &str, index: usize, name: Option<&str>) -> String {
    match name {
        Some(n) => format!("{section}[{index}] {n:?}"),
        None => format!("{section}[{index}]"),
    }
}

/// `shape[1] "wall": field 'material'`.
pub(crate) fn item_field(section: &str, index: usize, name: &str, field: &str) -> String {
    format!("{}: field '{field}'", item(section, index, Some(name)))
}

/// `camera: field 'fov'`.
pub(crate) fn table_field(table: &str, field: &str) -> String {
    format!("{table}: field '{field}'")
}

/// Renders a path (from serde or from the non-finite scan) as a location. `name_of` looks up
/// the `name` of an entry of one of [`ITEM_SECTIONS`].
pub(crate) fn location(path: &[Seg], name_of: &dyn Fn(&str, usize) -> Option<String>) -> String {
    fn join(rest: &[Seg]) -> String {
        let mut s = String::new();
        for seg in rest {
            match seg {
                Seg::Key(k) => {
                    if !s.is_empty() {
                        s.push('.');
                    }
                    s.push_str(k);
                }
                Seg::Index(i) => s.push_str(&format!("[{i}]")),
            }
        }
        s
    }
    match path {
        [] => "top level".to_string(),
        [Seg::Key(section), Seg::Index(i), rest @ ..] if ITEM_SECTIONS.contains(&section.as_str()) => {
            let head = item(section, *i, name_of(section, *i).as_deref());
            if rest.is_empty() {
                head
            } else {
                format!("{head}: field '{}'", join(rest))
            }
        }
        [Seg::Key(k)] => format!("field '{k}'"),
        [Seg::Key(table), rest @ ..] => format!("{table}: field '{}'", join(rest)),
        _ => join(path),
    }
}

/// 1-based line and column of a byte offset.
pub(crate) fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_locations_read_well() {
        let names = |s: &str, i: usize| (s == "shape" && i == 1).then(|| "wall".to_string());
        let p = |v: &[&str]| -> Vec<Seg> {
            v.iter()
                .map(|s| s.parse::<usize>().map(Seg::Index).unwrap_or(Seg::Key(s.to_string())))
                .collect()
        };
        assert_eq!(
            location(&p(&["shape", "1", "scale", "2"]), &names),
            "shape[1] \"wall\": field 'scale[2]'"
        );
        assert_eq!(location(&p(&["shape", "0"]), &names), "shape[0]");
        assert_eq!(location(&p(&["camera", "fov"]), &names), "camera: field 'fov'");
        assert_eq!(
            location(&p(&["film", "gate", "sigma_opl"]), &names),
            "film: field 'gate.sigma_opl'"
        );
        assert_eq!(location(&p(&["foo"]), &names), "field 'foo'");
        assert_eq!(location(&[], &names), "top level");
        assert_eq!(line_column("ab\ncd", 4), (2, 2));
    }
}
