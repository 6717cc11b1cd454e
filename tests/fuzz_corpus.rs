//! Replays the fuzz corpus (fuzz/corpus/<target>/, seeds and what `cargo fuzz` runs kept)
//! and any saved crash inputs (fuzz/artifacts/<target>/) through the same entry points as
//! the fuzz targets (`scene::fuzzing`), on stable Rust: every input must give a value or an
//! error, never a panic (issue 14; fuzz/README.md).

use difftransient::scene::{Format, fuzzing};
use std::path::PathBuf;

fn inputs(target: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut out = Vec::new();
    for kind in ["corpus", "artifacts"] {
        let Ok(dir) = std::fs::read_dir(root.join(kind).join(target)) else {
            continue;
        };
        for e in dir {
            let p = e.unwrap().path();
            if p.is_file() {
                let bytes = std::fs::read(&p).unwrap();
                out.push((p, bytes));
            }
        }
    }
    out.sort();
    out
}

fn replay(target: &str, min: usize, run: impl Fn(&[u8])) {
    let all = inputs(target);
    assert!(all.len() >= min, "{target}: only {} corpus inputs", all.len());
    for (path, bytes) in &all {
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run(bytes)));
        assert!(caught.is_ok(), "{target}: {} panics", path.display());
    }
}

#[test]
fn the_scene_corpus_parses_without_panics() {
    replay("scene_toml", 15, |b| fuzzing::scene(b, Format::Toml));
    replay("scene_json", 15, |b| fuzzing::scene(b, Format::Json));
}

#[test]
fn the_obj_corpus_reads_without_panics() {
    replay("obj", 5, fuzzing::obj);
}
