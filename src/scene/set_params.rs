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

    /// Sets the estimator and the numbers paths draw (`[integrator] kind` and `sampler`) in
    /// the description the scene keeps, so that they stay through every later
    /// [`Scene::set_params`] or [`Scene::set_text`], which resolve the scene again from that
    /// description. (Written on `Scene::integrator` alone, they went back to the file's at the
    /// next value set: Python's `with_sampler("independent").with_params(...)` rendered with
    /// Sobol points.) `None` keeps what the scene has.
    pub fn set_integrator(
        &mut self,
        kind: Option<crate::scene::IntegratorKind>,
        sampler: Option<crate::kernel::SampleSequence>,
    ) -> Result<(), SceneError> {
        let d = &self.described;
        let ctx = super::context::Ctx::new(&self.source);
        let mut raw = (*d.raw).clone();
        let Some(root) = raw.as_object_mut() else {
            return Err(ctx.invalid("the scene", "expected a table"));
        };
        let table = root
            .entry("integrator")
            .or_insert_with(|| serde_json::Value::Object(Default::default()));
        let Some(table) = table.as_object_mut() else {
            return Err(ctx.invalid("integrator", "expected a table"));
        };
        if let Some(k) = kind {
            table.insert("kind".into(), k.name().into());
        }
        if let Some(s) = sampler {
            table.insert("sampler".into(), s.name().into());
        }
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

#[cfg(test)]
mod tests {
    use crate::kernel::SampleSequence;
    use crate::scene::{IntegratorKind, Scene};

    #[test]
    fn the_estimator_and_sampler_set_stay_through_later_settings() {
        // pose_plate.toml has an [integrator] table, `bare` none
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pose_plate.toml");
        let bare = "[camera]\nposition = [0.0, 0.0, 1.0]\nlook_at = [0.0, 0.0, 0.0]\nresolution = [4, 4]\n[film]\nbins = 8\nbin_width_opl = 0.1\n\
                    [[material]]\nname = \"w\"\ntype = \"diffuse\"\nalbedo = 0.5\n\
                    [[shape]]\nname = \"p\"\ntype = \"rectangle\"\nmaterial = \"w\"\ntranslate = [0.0, 0.0, -1.0]\n\
                    [[param]]\nname = \"p_x\"\nkind = \"translate\"\nshape = \"p\"\naxis = \"x\"\nvalue = 0.0\n";
        let scenes = [
            Scene::load(&path, &[]).unwrap(),
            Scene::from_str(bare, crate::scene::Format::Toml, std::path::Path::new("bare.toml"), &[]).unwrap(),
        ];
        for mut scene in scenes {
            assert_eq!(scene.integrator.kind, IntegratorKind::Path);
            assert_eq!(scene.integrator.sampler, SampleSequence::Sobol);
            scene.set_integrator(Some(IntegratorKind::Bdpt), None).unwrap();
            scene.set_integrator(None, Some(SampleSequence::Independent)).unwrap();
            let name = scene.params[0].name.clone();
            scene.set_param(&name, 0.01).unwrap();
            scene.set_text(&[("film.bins", "9")]).unwrap();
            assert_eq!(
                scene.integrator.kind,
                IntegratorKind::Bdpt,
                "{}",
                scene.source.display()
            );
            assert_eq!(scene.integrator.sampler, SampleSequence::Independent);
            let back = Scene::from_state(scene.state()).unwrap();
            assert_eq!(back.integrator.kind, IntegratorKind::Bdpt);
            assert_eq!(back.integrator.sampler, SampleSequence::Independent);
        }
    }
}
