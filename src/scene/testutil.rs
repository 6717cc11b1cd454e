//! Helpers for the scene tests: temp scene files and error assertions, and geometry made of
//! local meshes.

use super::{Geometry, Scene, SceneError};
use std::path::{Path, PathBuf};

pub fn scenes_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

pub fn load_scene(name: &str) -> Scene {
    Scene::load(&scenes_dir().join(name), &[]).unwrap_or_else(|e| panic!("{name}: {e}"))
}

pub fn scene_text(name: &str) -> String {
    std::fs::read_to_string(scenes_dir().join(name)).unwrap()
}

/// The start of a test scene: a camera, a film of ten bins and a white diffuse material (a
/// macro, so that `concat!` makes constants of the scenes that start with it).
macro_rules! header {
    () => {
        r#"
[camera]
position = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]

[film]
bin_width_opl = 0.1
bins = 10

[[material]]
name = "white"
type = "diffuse"
albedo = 0.5
"#
    };
}
pub(crate) use header;

/// A minimal valid scene to edit: one white quad, a point light.
pub const MINI: &str = concat!(
    header!(),
    r#"
[[shape]]
name = "quad"
type = "rectangle"
material = "white"

[[emitter]]
name = "lamp"
type = "point"
position = [0.0, 0.0, 3.0]
intensity = 1.0
"#
);

pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Writes `text` as `name` in a fresh temp dir (plus `extra` files) and loads it.
pub fn load_text(
    name: &str,
    text: &str,
    extra: &[(&str, &str)],
    overrides: &[(String, f64)],
) -> Result<Scene, SceneError> {
    let dir = tempfile::tempdir().unwrap();
    for (n, t) in extra {
        write(dir.path(), n, t);
    }
    let p = write(dir.path(), name, text);
    Scene::load(&p, overrides)
}

/// Loads `text` as `name`, expects an error whose message contains the file name and each
/// of `parts`; returns the message.
pub fn expect_err(name: &str, text: &str, extra: &[(&str, &str)], parts: &[&str]) -> String {
    expect_err_set(name, text, extra, &[], parts)
}

pub fn expect_err_set(
    name: &str,
    text: &str,
    extra: &[(&str, &str)],
    overrides: &[(String, f64)],
    parts: &[&str],
) -> String {
    let msg = match load_text(name, text, extra, overrides) {
        Ok(_) => panic!("{name}: expected an error containing {parts:?}, but it loaded"),
        Err(e) => e.to_string(),
    };
    assert!(msg.contains(name), "message does not name the file {name}: {msg}");
    for p in parts {
        assert!(msg.contains(p), "message lacks {p:?}: {msg}");
    }
    eprintln!("{msg}");
    assert!(!msg.contains('\n'), "message should be one line: {msg}");
    msg
}

/// `MINI` with `from` replaced by `to` (which must occur).
pub fn mini_with(from: &str, to: &str) -> String {
    assert!(MINI.contains(from), "{from:?} not in MINI");
    MINI.replacen(from, to, 1)
}

/// A scene geometry of `meshes` as they are (local space), each its own shape, in order.
pub(crate) fn geometry_of(meshes: &[super::shapes::Mesh]) -> Geometry {
    let mut geo = Geometry::default();
    for (s, m) in meshes.iter().enumerate() {
        let base = geo.positions.len() as u32;
        geo.positions.extend(&m.positions);
        geo.indices.extend(m.tris.iter().map(|t| t.map(|i| i + base)));
        geo.tri_shape.extend(m.tris.iter().map(|_| s as u32));
    }
    geo
}
