//! What the fuzz targets (fuzz/fuzz_targets/) and the corpus replay (tests/fuzz_corpus.rs)
//! run on arbitrary bytes: the scene parser and resolver (TOML and JSON) and the OBJ reader.
//! Each must return a value or an error for any input: never panic, hang or allocate without
//! bound (issue 14). Run a target for 10 minutes with
//! `cargo fuzz run scene_toml -- -max_total_time=600` (fuzz/README.md).

use super::{Format, Scene};
use std::path::Path;

/// Parses and resolves `data` as a scene description in `format` (OBJ paths it names are
/// looked up beside a scene file that does not exist, so they fail as missing files).
pub fn scene(data: &[u8], format: Format) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let source = Path::new("/nonexistent/fuzz/scene");
    let _ = Scene::from_str(text, format, source, &[]);
}

/// Reads `data` as Wavefront OBJ text.
pub fn obj(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = super::shapes::parse_obj(text);
}
