//! `SceneBuilder` (issue 15): a scene made in code is the scene its file would be (the Cornell
//! box renders the same bytes as scenes/cornell_box.toml), and bad input gets the messages a
//! scene file gets.

use crate::common;
use difftransient::{Entry, RenderOptions, Scene, SceneBuilder, render};

/// scenes/cornell_box.toml, in code.
fn cornell() -> SceneBuilder {
    let wall = |name: &str, material: &str| Entry::rectangle(name, material);
    SceneBuilder::new()
        .integrator(
            Entry::new()
                .set("kind", "path")
                .set("max_bounces", 8)
                .set("spp", 16)
                .set("seed", 0),
        )
        .eta(1.0)
        .camera(
            Entry::camera([0.0, 1.0, 3.9], [0.0, 1.0, 0.0])
                .set("up", [0.0, 1.0, 0.0])
                .set("fov", 39.3)
                .set("resolution", [64, 64])
                .set("filter", "box"),
        )
        .film(
            Entry::film(0.06, 200)
                .set("start_opl", 3.6)
                .set("gate", "box")
                .set("channels", "rgb")
                .set("unwarp", false),
        )
        .material(Entry::diffuse("white", [0.73, 0.73, 0.73]))
        .material(Entry::diffuse("red", [0.63, 0.065, 0.05]))
        .material(Entry::diffuse("green", [0.14, 0.45, 0.091]))
        .shape(wall("floor", "white").rotate([-90.0, 0.0, 0.0]))
        .shape(
            wall("ceiling", "white")
                .translate([0.0, 2.0, 0.0])
                .rotate([90.0, 0.0, 0.0]),
        )
        .shape(wall("back_wall", "white").translate([0.0, 1.0, -1.0]))
        .shape(
            wall("left_wall", "red")
                .translate([-1.0, 1.0, 0.0])
                .rotate([0.0, 90.0, 0.0]),
        )
        .shape(
            wall("right_wall", "green")
                .translate([1.0, 1.0, 0.0])
                .rotate([0.0, -90.0, 0.0]),
        )
        .shape(
            wall("light_quad", "white")
                .translate([0.0, 1.98, 0.0])
                .rotate([90.0, 0.0, 0.0])
                .scale([0.25, 0.25, 1.0]),
        )
        .shape(
            Entry::cube("short_box", "white")
                .translate([0.33, 0.3, 0.37])
                .rotate([0.0, -17.0, 0.0])
                .scale(0.3),
        )
        .shape(
            Entry::cube("tall_box", "white")
                .translate([-0.33, 0.6, -0.29])
                .rotate([0.0, 17.0, 0.0])
                .scale([0.3, 0.6, 0.3]),
        )
        .emitter(
            Entry::area("light", "light_quad", [17.0, 12.0, 4.0])
                .set("pulse", "delta")
                .set("offset_opl", 0.0),
        )
}

#[test]
fn a_cornell_box_in_code_renders_the_bytes_of_the_file() {
    let built = cornell().build().unwrap();
    let file = common::load("cornell_box.toml");
    assert_eq!(built.geometry.positions, file.geometry.positions);
    assert_eq!(built.geometry.indices, file.geometry.indices);
    let opts = RenderOptions {
        spp: Some(2),
        seed: Some(3),
        threads: Some(2),
        ..Default::default()
    };
    let (a, _) = render(&built, &opts).unwrap();
    let (b, _) = render(&file, &opts).unwrap();
    assert!(a.data.iter().any(|&v| v > 0.0));
    assert_eq!(a.data, b.data);
    assert_eq!(a.steady, b.steady);
    let (mut sa, mut sb) = (built.summary(), file.summary());
    sa["source"] = serde_json::Value::Null;
    sb["source"] = serde_json::Value::Null;
    assert_eq!(sa, sb);
}

#[test]
fn builder_scenes_take_meshes_params_and_set_params() {
    let meshes = common::scene_path("meshes");
    let build = |yaw: f64| {
        SceneBuilder::new()
            .base_dir(&meshes)
            .camera(Entry::camera([0.0, 1.5, 3.0], [0.0, 0.3, 0.0]).set("resolution", [12, 12]))
            .film(Entry::film(0.05, 60).set("start_opl", 2.5))
            .material(Entry::diffuse("clay", [0.7, 0.5, 0.3]))
            .shape(Entry::rectangle("floor", "clay").rotate([-90.0, 0.0, 0.0]).scale(2.0))
            .shape(Entry::mesh("pyramid", "pyramid.obj", "clay").scale(0.5))
            .shape(
                Entry::mesh("pyramid_ply", "pyramid.ply", "clay")
                    .translate([0.8, 0.0, 0.0])
                    .scale(0.3),
            )
            .emitter(Entry::point("bulb", [0.5, 2.0, 1.0], 8.0))
            .param(
                Entry::param("yaw", "rotate", yaw)
                    .set("shape", "pyramid")
                    .set("axis", "y"),
            )
    };
    let mut s = build(0.0).build().unwrap();
    assert_eq!(s.shapes.len(), 3);
    assert_eq!(s.film.channels, 3, "a coloured albedo makes channels = \"auto\" RGB");
    s.set_param("yaw", 25.0).unwrap();
    let direct = build(25.0).build().unwrap();
    assert_eq!(s.geometry.positions, direct.geometry.positions);
    assert_ne!(s.geometry.positions, build(0.0).build().unwrap().geometry.positions);
    let opts = RenderOptions {
        spp: Some(2),
        seed: Some(5),
        threads: Some(2),
        ..Default::default()
    };
    assert_eq!(
        render(&s, &opts).unwrap().0.data,
        render(&direct, &opts).unwrap().0.data
    );
}

fn err_of(b: SceneBuilder) -> String {
    b.build().unwrap_err().to_string()
}

fn assert_mentions(err: &str, parts: &[&str]) {
    for p in parts {
        assert!(err.contains(p), "{err:?} lacks {p:?}");
    }
}

#[test]
fn bad_input_gets_the_messages_of_a_scene_file() {
    // the same messages as the file with the same mistake
    let file_err = |from: &str, to: &str| {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.toml");
        let text = std::fs::read_to_string(common::scene_path("cornell_box.toml")).unwrap();
        assert!(text.contains(from));
        std::fs::write(&p, text.replacen(from, to, 1)).unwrap();
        let e = Scene::load(&p, &[]).unwrap_err().to_string();
        e.split_once(": ").unwrap().1.to_string()
    };
    let e = err_of(cornell().material(Entry::diffuse("white", 0.5)));
    assert_mentions(&e, &["<scene builder>", "duplicate", "white"]);

    let e = err_of(cornell().shape(Entry::cube("extra", "whte")));
    assert_mentions(
        &e,
        &[
            "shape[8] \"extra\": field 'material'",
            "no material named \"whte\"",
            "white, red, green",
        ],
    );

    let e = err_of(cornell().material(Entry::diffuse("grey", [0.5, 1.5, 0.5])));
    assert_mentions(&e, &["material[3] \"grey\": field 'albedo'", "in [0, 1]"]);

    let e = err_of(cornell().camera(Entry::camera([0.0, 1.0, 3.9], [0.0, 1.0, 0.0]).set("fov", f64::NAN)));
    let same = file_err("fov = 39.3", "fov = nan");
    assert_mentions(&e, &["camera: field 'fov'", "expected a finite number, got nan"]);
    assert!(e.ends_with(&same), "{e:?} vs the file's {same:?}");

    let e = err_of(cornell().camera(Entry::camera([0.0, 1.0, 3.9], [0.0, 1.0, 0.0]).set("fovv", 40.0)));
    assert_mentions(&e, &["camera: field 'fovv'", "unknown field 'fovv'"]);

    let e = err_of(cornell().film(Entry::film(0.06, 0)));
    let same = file_err("bins = 200", "bins = 0");
    assert_mentions(&e, &["film: field 'bins'", "must be at least 1 (got 0)"]);
    assert!(e.ends_with(&same), "{e:?} vs the file's {same:?}");

    let e = err_of(cornell().film(Entry::film(0.06, 200).set("bins", "many")));
    assert_mentions(&e, &["film: field 'bins'", "invalid type: string \"many\""]);

    let e = err_of(SceneBuilder::new().film(Entry::film(0.06, 200)));
    assert_mentions(&e, &["top level: missing field 'camera'"]);

    let e = err_of(cornell().shape(Entry::mesh("m", "no_such_mesh.obj", "white")));
    assert_mentions(&e, &["shape[8] \"m\": field 'file'", "no_such_mesh.obj"]);

    let e = err_of(cornell().param(Entry::param("x", "translate", 0.1).set("shape", "tall_box")));
    assert_mentions(&e, &["param[0] \"x\": field 'axis'", "missing"]);

    // a value no description can hold (a unit) is refused by field
    let e = err_of(cornell().material(Entry::diffuse("grey", ())));
    assert_mentions(&e, &["material[3] \"grey\": field 'albedo'"]);
}
