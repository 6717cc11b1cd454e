//! Setting values on a loaded [`Scene`] (`[[param]]` values, or any number of the
//! description as `--set` does) without reading or parsing a file again.
//!
//! [`Scene::set_params`] resolves the description the scene keeps (`described.rs`) again with
//! the new overrides, through the same `resolve` as [`Scene::load`] and with the meshes read
//! when the scene was loaded, so the scene it leaves is the one `Scene::load(path, overrides)`
//! gives for the same overrides, field for field (and a render of it the same bytes). What
//! depends on a value is re-derived because everything is: world vertices, flush emitters,
//! materials, emitters, film and the relay wall; the meshes are not re-read, and the renderer
//! builds its BVH and emitter tables from the scene at every render anyway.

use super::desc::SceneDesc;
use super::described::Described;
use super::{Scene, SceneError};
use std::sync::Arc;

/// Replaces or adds `(name, value)` in `list`, keeping one entry per name.
fn put(list: &mut Vec<(String, f64)>, name: &str, value: f64) {
    list.retain(|(n, _)| n != name);
    list.push((name.to_string(), value));
}

/// Whether two descriptions give the same local meshes (type, file, subdivisions per shape).
fn same_meshes(a: &SceneDesc, b: &SceneDesc) -> bool {
    a.shape.len() == b.shape.len()
        && a.shape
            .iter()
            .zip(&b.shape)
            .all(|(x, y)| x.ty == y.ty && x.file == y.file && x.subdivisions == y.subdivisions)
}

impl Scene {
    /// Sets the value of one parameter; see [`Scene::set_params`].
    pub fn set_param(&mut self, name: &str, value: f64) -> Result<(), SceneError> {
        self.set_params(&[(name, value)])
    }

    /// Sets values on the loaded scene, as [`Scene::load`]'s overrides do: a plain name sets
    /// the value of that `[[param]]`, a dotted path (`film.bins`, `camera.fov`,
    /// `material.white.albedo.1`) sets that number of the description. Earlier settings of
    /// other names stay. The scene is then resolved again from the description it was loaded
    /// from, without reading the scene file or its meshes, and is the same scene (a render
    /// of it the same bytes) as `Scene::load(path, overrides)` with every value set so far.
    ///
    /// An unknown name or a value out of range gives the error loading with that override
    /// would give, naming the parameter or field, and leaves the scene unchanged.
    ///
    /// ```
    /// use difftransient::Scene;
    /// # fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/occluder_shadow.toml");
    /// let mut scene = Scene::load(&path, &[])?;
    /// scene.set_param("occluder_x", 0.35)?;
    /// let reloaded = Scene::load(&path, &[("occluder_x".to_string(), 0.35)])?;
    /// assert_eq!(scene.geometry.positions, reloaded.geometry.positions);
    /// // an unknown name is refused by name, and the scene keeps its values
    /// let err = scene.set_param("occluder_z", 1.0).unwrap_err();
    /// assert!(err.to_string().contains("occluder_z"));
    /// assert_eq!(scene.params[0].value, 0.35);
    /// # Ok(())
    /// # }
    /// ```
    pub fn set_params<S: AsRef<str>>(&mut self, values: &[(S, f64)]) -> Result<(), SceneError> {
        let d = &self.described;
        let (mut fields, mut params) = (d.fields.clone(), d.params.clone());
        for (name, value) in values {
            let name = name.as_ref();
            let list = if super::field_set::is_field_path(name) {
                &mut fields
            } else {
                &mut params
            };
            put(list, name, *value);
        }
        self.resolve_again(d.raw.clone(), fields, params)
    }

    /// Sets fields of the description to values other than numbers, written as in a TOML
    /// file (`("nlos.scan", "exhaustive")`, `("nlos.grid", "[8, 8]")`), as
    /// [`Scene::load_with_text`] does at load; numbers set so far stay. The scene is then
    /// resolved again from its description (meshes are read again only where a shape's file
    /// or type changed). An error names the field and leaves the scene unchanged.
    pub fn set_text<S: AsRef<str>>(&mut self, values: &[(S, S)]) -> Result<(), SceneError> {
        let d = &self.described;
        let texts: Vec<(String, String)> = values
            .iter()
            .map(|(n, v)| (n.as_ref().to_string(), v.as_ref().to_string()))
            .collect();
        let mut raw = (*d.raw).clone();
        super::field_set::apply_text(&mut raw, &texts, &self.source)?;
        self.resolve_again(Arc::new(raw), d.fields.clone(), d.params.clone())
    }

    /// Resolves the scene again from the description tree `raw` with the number overrides
    /// `fields` and `params`: the typed description and the meshes are kept where `raw` and
    /// `fields` are the scene's own, and the meshes are read again only where a shape's file
    /// or type changed. On an error the scene is left as it was.
    fn resolve_again(
        &mut self,
        raw: Arc<serde_json::Value>,
        fields: Vec<(String, f64)>,
        params: Vec<(String, f64)>,
    ) -> Result<(), SceneError> {
        let d = &self.described;
        let (desc, meshes) = if Arc::ptr_eq(&raw, &d.raw) && fields == d.fields {
            (d.desc.clone(), d.meshes.clone())
        } else {
            let desc = super::load::desc_from_tree(&raw, &self.source, &fields)?;
            let meshes = d.meshes.clone().filter(|_| same_meshes(&d.desc, &desc));
            (desc, meshes)
        };
        let described = Described {
            raw,
            fields,
            desc,
            params,
            meshes,
        };
        *self = super::resolve::resolve(described, &self.source.clone())?;
        Ok(())
    }
}
