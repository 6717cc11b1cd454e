//! `dtr info`.

use crate::scene::Scene;
use std::path::Path;

pub fn run(path: &Path, json: bool, set: &[String]) -> anyhow::Result<()> {
    let sets = super::parse_sets(set)?;
    let scene = Scene::load_with_text(path, &sets.numbers, &sets.texts)?;
    let text = if json {
        serde_json::to_string_pretty(&scene.summary())? + "\n"
    } else {
        scene.to_string()
    };
    Ok(super::write_stdout(text.as_bytes())?)
}
