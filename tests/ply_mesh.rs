//! PLY meshes (issue 15): a binary PLY of the same pyramid as meshes/pyramid.obj renders the
//! same bytes, derivatives included, and a broken PLY is refused naming the scene, the field
//! and the file.

use crate::common;
use difftransient::{RenderOptions, Scene, render_diff};

#[test]
fn a_ply_mesh_renders_like_the_same_obj() {
    let opts = RenderOptions {
        spp: Some(2),
        seed: Some(4),
        threads: Some(2),
        ..Default::default()
    };
    let obj = common::load("obj_mesh.toml");
    let ply = common::load("ply_mesh.toml");
    let param = obj.params[0].name.clone();
    let (a, da, _) = render_diff(&obj, std::slice::from_ref(&param), &opts).unwrap();
    let (b, db, _) = render_diff(&ply, &[param], &opts).unwrap();
    assert!(a.data.iter().any(|&v| v > 0.0));
    assert_eq!(a.data, b.data);
    assert_eq!(da[0].data, db[0].data);
}

#[test]
fn a_broken_ply_is_refused_with_its_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(common::scene_path("ply_mesh.toml")).unwrap();
    std::fs::create_dir(dir.path().join("meshes")).unwrap();
    std::fs::write(
        dir.path().join("meshes/pyramid.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n",
    )
    .unwrap();
    let scene = dir.path().join("s.toml");
    std::fs::write(&scene, text).unwrap();
    let err = Scene::load(&scene, &[]).unwrap_err().to_string();
    assert!(
        err.contains("s.toml") && err.contains("file") && err.contains("pyramid.ply") && err.contains("vertex 7"),
        "{err}"
    );
}

/// An error about a PLY mesh calls it a PLY file, as an error about an OBJ mesh calls it an
/// OBJ file. Before, every mesh error said "OBJ file" (the path was the PLY's).
#[test]
fn a_broken_ply_is_called_a_ply_file() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(common::scene_path("ply_mesh.toml")).unwrap();
    std::fs::create_dir(dir.path().join("meshes")).unwrap();
    let scene = dir.path().join("s.toml");
    std::fs::write(&scene, text).unwrap();
    // missing, then not a PLY at all
    let missing = Scene::load(&scene, &[]).unwrap_err().to_string();
    std::fs::write(dir.path().join("meshes/pyramid.ply"), "v 0 0 0\n").unwrap();
    let garbage = Scene::load(&scene, &[]).unwrap_err().to_string();
    for err in [missing, garbage] {
        assert!(
            err.contains("field 'file': PLY file ") && err.contains("pyramid.ply"),
            "{err}"
        );
        assert!(!err.contains("OBJ"), "{err}");
    }
}
