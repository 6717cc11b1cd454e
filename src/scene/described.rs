//! A loaded scene's description, kept with the scene (`Scene::described`) so that values can
//! be set on it without reading or parsing a file again (`set_params.rs`).

use super::desc::SceneDesc;
use super::shapes::LocalMesh;
use std::sync::Arc;

/// What a [`super::Scene`] was resolved from.
#[derive(Clone)]
pub(crate) struct Described {
    /// The description as a generic tree, before the `--set` overrides of fields.
    pub raw: Arc<serde_json::Value>,
    /// Overrides of fields (dotted paths, `field_set`) applied to `raw` to give `desc`.
    pub fields: Vec<(String, f64)>,
    /// The typed description with `fields` applied, parameters at their written values.
    pub desc: SceneDesc,
    /// Overrides of `[[param]]` values, applied while resolving.
    pub params: Vec<(String, f64)>,
    /// Every shape's local mesh, in the order of `desc.shape`; `None` until read.
    pub meshes: Option<Arc<[LocalMesh]>>,
}

impl std::fmt::Debug for Described {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Described")
            .field("fields", &self.fields)
            .field("params", &self.params)
            .finish_non_exhaustive()
    }
}
