//! `Scene::set_params` (issue 15): values set on a loaded scene give the scene
//! `Scene::load(path, overrides)` gives, so its renders (transient and derivative) are the same
//! bytes; bad names and values are refused by name and leave the scene as it was.

use crate::common;
use difftransient::{BoundaryMode, RenderOptions, Scene, render_diff};

fn opts() -> RenderOptions {
    RenderOptions {
        spp: Some(2),
        seed: Some(11),
        threads: Some(2),
        boundary: BoundaryMode::InteriorOnly,
        ..Default::default()
    }
}

fn owned(set: &[(&str, f64)]) -> Vec<(String, f64)> {
    set.iter().map(|(n, v)| (n.to_string(), *v)).collect()
}

/// Everything of the scene a render reads, compared exactly (f32 bits through `Debug` of the
/// plain-data parts and through `==` of the arrays).
fn assert_same_scene(a: &Scene, b: &Scene, what: &str) {
    assert_eq!(a.geometry.positions, b.geometry.positions, "{what}: positions");
    assert_eq!(a.geometry.indices, b.geometry.indices, "{what}: indices");
    assert_eq!(a.geometry.tri_shape, b.geometry.tri_shape, "{what}: tri_shape");
    assert_eq!(format!("{:?}", a.shapes), format!("{:?}", b.shapes), "{what}: shapes");
    assert_eq!(
        format!("{:?}", a.materials),
        format!("{:?}", b.materials),
        "{what}: materials"
    );
    assert_eq!(
        format!("{:?}", a.emitters),
        format!("{:?}", b.emitters),
        "{what}: emitters"
    );
    assert_eq!(format!("{:?}", a.camera), format!("{:?}", b.camera), "{what}: camera");
    assert_eq!(format!("{:?}", a.film), format!("{:?}", b.film), "{what}: film");
    assert_eq!(format!("{:?}", a.params), format!("{:?}", b.params), "{what}: params");
    assert_eq!(format!("{:?}", a.nlos), format!("{:?}", b.nlos), "{what}: nlos");
    assert_eq!(a.eta.to_bits(), b.eta.to_bits(), "{what}: eta");
    assert_eq!(a.render_origin, b.render_origin, "{what}: render origin");
    assert_eq!(a.lifted_emitters, b.lifted_emitters, "{what}: lifted emitters");
    assert_eq!(a.summary(), b.summary(), "{what}: summary");
}

/// Renders of `a` and `b` at `spp` (transient, steady image and the derivative of `param`)
/// are the same bytes, and not all zero.
fn assert_same_renders(a: &Scene, b: &Scene, param: &str, spp: u32, what: &str) {
    let o = RenderOptions {
        spp: Some(spp),
        ..opts()
    };
    let (ia, da, _) = render_diff(a, &[param.to_string()], &o).unwrap_or_else(|e| panic!("{what}: {e}"));
    let (ib, db, _) = render_diff(b, &[param.to_string()], &o).unwrap();
    assert!(
        ia.data.iter().any(|&v| v != 0.0),
        "{what}: an empty render proves nothing"
    );
    assert_eq!(ia.data, ib.data, "{what}: transient");
    assert_eq!(ia.steady, ib.steady, "{what}: steady image");
    assert_eq!(da[0].data, db[0].data, "{what}: derivative");
}

/// Sets `steps` one after another on the scene as loaded, then compares it with the scene
/// loaded with every value as an override.
fn check(scene: &str, steps: &[&[(&str, f64)]], render_param: &str) {
    check_at(scene, steps, render_param, 2)
}

/// `check` with renders of `spp` samples per pixel (or sensor point).
fn check_at(scene: &str, steps: &[&[(&str, f64)]], render_param: &str, spp: u32) {
    let path = common::scene_path(scene);
    let mut set = Scene::load(&path, &[]).unwrap();
    let mut all = Vec::new();
    for step in steps {
        set.set_params(step).unwrap_or_else(|e| panic!("{scene}: {e}"));
        all.extend(owned(step));
    }
    let loaded = Scene::load(&path, &all).unwrap();
    let what = format!("{scene} with {all:?}");
    assert_same_scene(&set, &loaded, &what);
    assert_same_renders(&set, &loaded, render_param, spp, &what);
    // and the value did change the scene
    let unset = Scene::load(&path, &[]).unwrap();
    assert_ne!(format!("{:?}", unset.params), format!("{:?}", set.params), "{what}");
}

#[test]
fn pose_parameters_move_geometry_like_a_reload() {
    check("occluder_shadow.toml", &[&[("occluder_x", 0.35)]], "occluder_x");
    check(
        "diff_room.toml",
        &[&[("room_z", 0.1)], &[("room_rot_y", 7.0)]],
        "room_z",
    );
    check(
        "diff_room.toml",
        &[&[("room_scale_z", 3.2), ("room_pitch", -3.0)]],
        "room_pitch",
    );
}

#[test]
fn obj_meshes_are_not_read_again_and_move_like_a_reload() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(common::scene_path("obj_mesh.toml")).unwrap();
    std::fs::create_dir(dir.path().join("meshes")).unwrap();
    let mesh = dir.path().join("meshes/pyramid.obj");
    std::fs::copy(common::scene_path("meshes/pyramid.obj"), &mesh).unwrap();
    let path = dir.path().join("obj_mesh.toml");
    std::fs::write(&path, text).unwrap();
    let mut scene = Scene::load(&path, &[]).unwrap();
    // the mesh and the scene file are gone: setting values reads neither
    std::fs::remove_file(&mesh).unwrap();
    std::fs::remove_file(&path).unwrap();
    scene
        .set_params(&[("pyramid_yaw", 30.0), ("pyramid_height", 1.3)])
        .unwrap();
    let reference = Scene::load(
        &common::scene_path("obj_mesh.toml"),
        &owned(&[("pyramid_yaw", 30.0), ("pyramid_height", 1.3)]),
    )
    .unwrap();
    assert_eq!(scene.geometry.positions, reference.geometry.positions);
    assert_same_renders(&scene, &reference, "pyramid_yaw", 2, "obj_mesh.toml");
    check(
        "obj_mesh.toml",
        &[&[("pyramid_yaw", 30.0)], &[("pyramid_height", 1.3)]],
        "pyramid_height",
    );
}

#[test]
fn material_emitter_medium_and_pulse_parameters_match_a_reload() {
    check("diff_room.toml", &[&[("albedo", 0.45)]], "albedo");
    check("diff_room.toml", &[&[("intensity", 7.5)]], "intensity");
    check("diff_room.toml", &[&[("eta", 1.33)]], "eta");
    check("diff_room.toml", &[&[("lamp_offset", 0.25)]], "lamp_offset");
    check("rough_conductor.toml", &[&[("gold_roughness", 0.15)]], "gold_roughness");
    check(
        "rough_conductor.toml",
        &[&[("gold_reflectance", 0.7)]],
        "gold_reflectance",
    );
    check(
        "rough_dielectric.toml",
        &[&[("glass_ior", 1.4)], &[("glass_roughness", 0.3)]],
        "glass_ior",
    );
}

#[test]
fn a_relay_wall_capture_and_fields_match_a_reload() {
    // 64 paths per sensor point: the capture holds light at every seed tried (seeds 0–11);
    // at 2 it held none at 16 of 16 seeds with Sobol points, 13 of 16 with independent numbers
    check_at("nlos_hidden_patch.toml", &[&[("patch_z", 0.45)]], "patch_albedo", 64);
    // dotted paths set numbers of the description, as `--set` does
    check(
        "diff_room.toml",
        &[
            &[("camera.fov", 50.0), ("film.bins", 40.0)],
            &[("albedo", 0.3)],
            &[("film.bins", 30.0)],
        ],
        "albedo",
    );
}

/// `Scene::set_text` sets fields to words, lists and tables on a loaded scene: the scene (and
/// its renders) is the one `Scene::load_with_text` gives, with numbers set before and after
/// kept; a bad value is refused by name and leaves the scene as it was.
#[test]
fn fields_set_to_words_and_lists_match_a_reload() {
    let path = common::scene_path("nlos_occluder.toml");
    let texts = [
        ("nlos.scan", "exhaustive"),
        ("nlos.grid", "[3, 2]"),
        ("film.channels", "rgb"),
    ];
    let mut set = Scene::load(&path, &owned(&[("film.bins", 40.0)])).unwrap();
    set.set_text(&texts).unwrap();
    set.set_params(&[("hidden_x", 0.45)]).unwrap();
    let owned_texts: Vec<(String, String)> = texts.iter().map(|(n, v)| (n.to_string(), v.to_string())).collect();
    let loaded =
        Scene::load_with_text(&path, &owned(&[("film.bins", 40.0), ("hidden_x", 0.45)]), &owned_texts).unwrap();
    assert_same_scene(&set, &loaded, "words and lists");
    assert_eq!(set.film.channels, 3);
    assert_same_renders(&set, &loaded, "hidden_albedo", 64, "words and lists");
    let before = format!("{:?}", set.nlos);
    let err = set.set_text(&[("nlos.scan", "sideways")]).unwrap_err().to_string();
    assert!(
        err.contains("scan") && err.contains("'confocal' or 'exhaustive'"),
        "{err}"
    );
    assert_eq!(format!("{:?}", set.nlos), before, "a refused value changed the scene");
}

#[test]
fn setting_a_value_back_gives_the_scene_as_loaded() {
    let path = common::scene_path("diff_room.toml");
    let loaded = Scene::load(&path, &[]).unwrap();
    let z = loaded.params.iter().find(|p| p.name == "room_z").unwrap().value;
    let mut s = loaded.clone();
    s.set_param("room_z", z + 0.3).unwrap();
    assert_ne!(s.geometry.positions, loaded.geometry.positions);
    s.set_param("room_z", z).unwrap();
    assert_same_scene(&s, &loaded, "room_z back");
}

/// A refused value: the error, and the scene left bit for bit as it was.
fn refused(scene: &str, name: &str, value: f64, expect: &[&str]) {
    let path = common::scene_path(scene);
    let mut s = Scene::load(&path, &[("albedo".to_string(), 0.4)]).unwrap_or_else(|_| Scene::load(&path, &[]).unwrap());
    let before = s.clone();
    let err = s.set_param(name, value).unwrap_err().to_string();
    for e in expect {
        assert!(err.contains(e), "{scene} {name}={value}: {err:?} lacks {e:?}");
    }
    assert!(err.contains(scene), "{err}");
    assert_same_scene(&s, &before, "after a refused value");
    // it still takes good values afterwards, and remembers the earlier ones
    if before.params.iter().any(|p| p.name == "intensity") {
        s.set_param("intensity", 3.0).unwrap();
        let reference = Scene::load(&path, &owned(&[("albedo", 0.4), ("intensity", 3.0)])).unwrap();
        assert_same_scene(&s, &reference, "after a refused value, a good one");
    }
}

#[test]
fn unknown_names_and_out_of_range_values_are_refused_by_name() {
    refused(
        "diff_room.toml",
        "albdo",
        0.5,
        &["albdo", "no parameter named", "albedo"],
    );
    refused(
        "diff_room.toml",
        "albedo",
        1.5,
        &["param[3] \"albedo\": field 'value'", "must be in [0, 1] (got 1.5)"],
    );
    refused("diff_room.toml", "room_scale_z", 0.0, &["room_scale_z", "nonzero"]);
    refused(
        "diff_room.toml",
        "eta",
        -1.0,
        &["\"eta\": field 'value'", "must be >= 1e-6"],
    );
    refused("diff_room.toml", "intensity", f64::NAN, &["intensity", "finite"]);
    refused(
        "diff_room.toml",
        "film.bins",
        0.0,
        &["film: field 'bins'", "at least 1"],
    );
    refused(
        "diff_room.toml",
        "film.binz",
        3.0,
        &["film: field 'binz'", "unknown field 'binz'"],
    );
    refused(
        "rough_conductor.toml",
        "gold_roughness",
        -0.2,
        &["gold_roughness", "roughness"],
    );
}

#[test]
fn the_optimizer_takes_the_steps_it_took_when_it_reloaded_the_scene() {
    use difftransient::optimize::{Problem, loss::Loss};
    let path = common::scene_path("diff_room.toml");
    let target = difftransient::render(&Scene::load(&path, &[]).unwrap(), &opts())
        .unwrap()
        .0;
    let p = Problem {
        scene: path,
        fixed: owned(&[("intensity", 6.0)]),
        fixed_text: Vec::new(),
        params: vec!["room_z".into(), "albedo".into()],
        target,
        loss: Loss::L2,
        opts: RenderOptions {
            boundary: BoundaryMode::Full,
            ..opts()
        },
        bounds: vec![(-0.5, 0.5), (0.1, 0.9)],
    };
    let steps = p.optimize(&[0.2, 0.4], 3, &[0.05, 0.05], 1.0, |_| true).unwrap();
    assert_eq!(steps.len(), 3);
    assert_ne!(steps[0].values, steps[2].values);
    for s in &steps {
        // each step's loss and gradient as before: the scene loaded with the values as overrides
        let seed = 11 + 2 * s.iteration as u64;
        let (l, g) = p.loss_and_gradient(&s.values, seed).unwrap();
        assert_eq!(
            (l.to_bits(), g.iter().map(|v| v.to_bits()).collect::<Vec<_>>()),
            (s.loss.to_bits(), s.grad.iter().map(|v| v.to_bits()).collect()),
            "iteration {}",
            s.iteration
        );
    }
}
