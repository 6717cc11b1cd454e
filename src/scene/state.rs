//! A loaded scene as plain data and back: what a Python pickle of a `Scene` holds, so that a
//! scene can be sent to other processes (`multiprocessing`, a job queue) or kept, and come
//! back as the same scene without any file being read again.
//!
//! The state is what the scene was resolved from (`described.rs`): the description tree, the
//! overrides of fields and of `[[param]]` values, and every shape's local mesh. Resolving it
//! again gives the same scene, field for field (a render of it the same bytes), through the
//! same `resolve` as [`Scene::load`]. A state that does not hold together (meshes that do not
//! match the shapes, an index past a mesh's vertices, a position that is not finite) is
//! refused with a [`SceneError`] naming the shape, never a panic.

use super::described::Described;
use super::shapes::LocalMesh;
use super::{Scene, SceneError};
use std::path::PathBuf;
use std::sync::Arc;

/// A scene as plain data ([`Scene::state`], [`Scene::from_state`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SceneState {
    /// The file the scene came from (for messages, and relative paths in later settings).
    pub source: PathBuf,
    /// The description tree, as JSON text, before the overrides of fields.
    pub description: String,
    /// Overrides of numbers of the description (dotted paths, as `--set camera.fov=40`).
    pub fields: Vec<(String, f64)>,
    /// Overrides of `[[param]]` values.
    pub params: Vec<(String, f64)>,
    /// Every shape's mesh in its local space, in the order of the description's shapes.
    pub meshes: Vec<LocalMesh>,
}

impl Scene {
    /// The scene as plain data, from which [`Scene::from_state`] builds the same scene.
    pub fn state(&self) -> SceneState {
        let d = &self.described;
        SceneState {
            source: self.source.clone(),
            description: d.raw.to_string(),
            fields: d.fields.clone(),
            params: d.params.clone(),
            meshes: d.meshes.as_deref().map(<[LocalMesh]>::to_vec).unwrap_or_default(),
        }
    }

    /// The scene whose [`Scene::state`] `state` is, without reading any file.
    pub fn from_state(state: SceneState) -> Result<Scene, SceneError> {
        let SceneState {
            source,
            description,
            fields,
            params,
            meshes,
        } = state;
        let ctx = super::context::Ctx::new(&source);
        let invalid = |at: String, message: String| ctx.invalid(at, message);
        let raw: serde_json::Value = serde_json::from_str(&description)
            .map_err(|e| invalid("the saved scene".into(), format!("its description is not JSON: {e}")))?;
        let desc = super::load::desc_from_tree(&raw, &source, &fields)?;
        if meshes.len() != desc.shape.len() {
            return Err(invalid(
                "the saved scene".into(),
                format!("{} meshes for {} shapes", meshes.len(), desc.shape.len()),
            ));
        }
        for (k, (m, s)) in meshes.iter().zip(&desc.shape).enumerate() {
            let at = || format!("shape[{k}] {:?}", s.name);
            if let Some(p) = m.positions.iter().find(|p| !p.is_finite()) {
                return Err(invalid(at(), format!("the saved mesh has a vertex at {p}, not finite")));
            }
            let n = m.positions.len();
            if let Some(t) = m.tris.iter().find(|t| t.iter().any(|&i| i as usize >= n)) {
                return Err(invalid(
                    at(),
                    format!("the saved mesh has a triangle {t:?} past its {n} vertices"),
                ));
            }
        }
        let described = Described {
            raw: Arc::new(raw),
            fields,
            desc,
            params,
            meshes: Some(meshes.into()),
        };
        super::resolve::resolve(described, &source)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Format;
    use std::path::Path;

    fn scene_file(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes").join(name)
    }

    #[test]
    fn a_scene_comes_back_from_its_state_as_it_was() {
        // an OBJ mesh, a PLY mesh, a set field and a set parameter
        for (name, set) in [
            ("obj_mesh.toml", vec![("camera.fov".to_string(), 41.0)]),
            ("ply_mesh.toml", vec![]),
            (
                "pose_plate.toml",
                vec![("plate_x".to_string(), 0.07), ("film.bins".to_string(), 40.0)],
            ),
        ] {
            let scene = Scene::load(&scene_file(name), &set).unwrap();
            let back = Scene::from_state(scene.state()).unwrap();
            assert_eq!(back.geometry.positions, scene.geometry.positions, "{name}");
            assert_eq!(back.geometry.indices, scene.geometry.indices, "{name}");
            let values = |s: &Scene| s.params.iter().map(|p| (p.name.clone(), p.value)).collect::<Vec<_>>();
            assert_eq!(values(&back), values(&scene), "{name}");
            assert_eq!(back.film.axis, scene.film.axis, "{name}");
            assert_eq!(back.state(), scene.state(), "{name}");
            assert_eq!(back.inputs, scene.inputs, "{name}");
        }
    }

    #[test]
    fn a_state_reads_no_file() {
        // the OBJ's scene from text in a folder without the OBJ: from its state, the mesh is
        // the one held
        let path = scene_file("obj_mesh.toml");
        let scene = Scene::load(&path, &[]).unwrap();
        let mut state = scene.state();
        state.source = std::env::temp_dir().join("no-such-folder-dtr/obj_mesh.toml");
        let back = Scene::from_state(state).unwrap();
        assert_eq!(back.geometry.positions, scene.geometry.positions);
        let text = std::fs::read_to_string(&path).unwrap();
        let from_text = Scene::from_str(&text, Format::Toml, &back.source, &[]);
        assert!(from_text.is_err(), "the mesh file is not there to read");
    }

    #[test]
    fn a_state_that_does_not_hold_together_is_refused_by_shape() {
        let scene = Scene::load(&scene_file("pose_plate.toml"), &[]).unwrap();
        let good = scene.state();
        let mut fewer = good.clone();
        fewer.meshes.pop();
        let e = Scene::from_state(fewer).unwrap_err().to_string();
        assert!(e.contains("meshes for"), "{e}");
        let mut past = good.clone();
        past.meshes[0].tris[0] = [0, 1, 1 << 30];
        let e = Scene::from_state(past).unwrap_err().to_string();
        assert!(e.contains("shape[0]") && e.contains("past its"), "{e}");
        let mut nan = good.clone();
        nan.meshes[0].positions[0].x = f64::NAN;
        let e = Scene::from_state(nan).unwrap_err().to_string();
        assert!(e.contains("shape[0]") && e.contains("not finite"), "{e}");
        let mut text = good;
        text.description = "{".into();
        let e = Scene::from_state(text).unwrap_err().to_string();
        assert!(e.contains("not JSON"), "{e}");
    }
}
