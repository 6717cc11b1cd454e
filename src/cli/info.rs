//! `dtr info`.

use crate::scene::Scene;
use std::path::Path;

pub fn run(path: &Path, json: bool, set: &[String]) -> anyhow::Result<()> {
    let overrides = super::parse_sets(set)?;
    let scene = Scene::load(path, &overrides)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&scene.summary())?);
    } else {
        print!("{scene}");
    }
    Ok(())
}
