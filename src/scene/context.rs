//! What every resolution step shares: where errors go ([`Ctx`]: the file, and which locations
//! a parameter set) and the names of the entries ([`Names`]), which references are checked
//! against ([`no_such`]).

use super::SceneError;
use std::collections::HashMap;
use std::path::Path;

/// Where errors go: the file, and which locations got their value from a parameter.
pub(crate) struct Ctx<'a> {
    pub path: &'a Path,
    /// location → note such as `value from param "occluder_x" (--set)`.
    pub set_by: HashMap<String, String>,
}

impl Ctx<'_> {
    pub fn invalid(&self, at: impl Into<String>, message: impl Into<String>) -> SceneError {
        let at = at.into();
        let mut message = message.into();
        if let Some(note) = self.set_by.get(&at) {
            message = format!("{message} ({note})");
        }
        SceneError::Invalid {
            path: self.path.to_path_buf(),
            at,
            message,
        }
    }
}

/// Name → index for each kind of named entry.
pub(crate) struct Names {
    pub materials: Vec<String>,
    pub shapes: Vec<String>,
    pub emitters: Vec<String>,
    pub params: Vec<String>,
}

impl Names {
    fn find(list: &[String], name: &str) -> Option<usize> {
        list.iter().position(|n| n == name)
    }
    pub fn material(&self, name: &str) -> Option<usize> {
        Self::find(&self.materials, name)
    }
    pub fn shape(&self, name: &str) -> Option<usize> {
        Self::find(&self.shapes, name)
    }
}

/// `no material named "whte" (materials: white, red, green)`.
pub(crate) fn no_such(what: &str, plural: &str, name: &str, all: &[String]) -> String {
    if all.is_empty() {
        format!("no {what} named {name:?} (the scene has no {plural})")
    } else {
        format!("no {what} named {name:?} ({plural}: {})", all.join(", "))
    }
}
