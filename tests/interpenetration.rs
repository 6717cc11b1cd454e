//! Moving shapes that cross another surface are refused by the boundary stage
//! (src/boundary/interpenetration.rs): the curve where two surfaces cross moves with them
//! and lies on no mesh edge, so the edge samplers never see it.
//!
//! Before the refusal, a dark cube sunk 5 cm into the floor of scenes/resting_box.toml's
//! kind rendered without complaint and its image derivative came out 37 % short of central
//! finite differences (z = 80, 12 seeds × 256 spp; the pixels along the sunk faces' crossing
//! with the floor got almost none of their derivative). Touching is not crossing: the cube
//! resting on the floor, a floor edge running under its bottom edge, and a cube hovering above
//! it all render.

use difftransient::{BoundaryMode, Error, RenderOptions, Scene, render_diff};
use std::path::Path;

fn opts(boundary: BoundaryMode) -> RenderOptions {
    RenderOptions {
        spp: Some(1),
        seed: Some(1),
        threads: Some(2),
        boundary,
        ..Default::default()
    }
}

/// scenes/resting_box.toml with the cube's centre at height `y` (0.2: resting on the floor).
fn box_at(y: f64) -> Scene {
    let path = crate::common::scene_path("resting_box.toml");
    Scene::load(&path, &[("shape.box.translate.1".to_string(), y)]).unwrap()
}

fn diff(scene: &Scene, param: &str, boundary: BoundaryMode) -> Result<(), Error> {
    render_diff(scene, &[param.to_string()], &opts(boundary)).map(|_| ())
}

fn refusal(scene: &Scene, param: &str) -> String {
    match diff(scene, param, BoundaryMode::Full) {
        Err(Error::Invalid(msg)) => msg,
        other => panic!("{param}: expected a refusal, got {other:?}"),
    }
}

#[test]
fn a_moving_box_sunk_into_the_floor_is_refused_by_name() {
    // sunk 20 µm (more than 2ε) is refused as well
    let msg = refusal(&box_at(0.19998), "box_x");
    assert!(
        msg.contains("crosses shape") && msg.contains("\"floor\"") && msg.contains("\"box\""),
        "{msg}"
    );
    let sunk = box_at(0.15);
    for param in ["box_x", "box_yaw"] {
        let msg = refusal(&sunk, param);
        for part in [
            "resting_box.toml",
            "\"box\"",
            "\"floor\"",
            "no mesh edge",
            "--estimators interior",
        ] {
            assert!(msg.contains(part), "{param}: {part:?} missing from: {msg}");
        }
        // the interior alone, asked for by name, and the forward render still run
        diff(&sunk, param, BoundaryMode::InteriorOnly).unwrap();
    }
    difftransient::render(&sunk, &opts(BoundaryMode::Full)).unwrap();
}

#[test]
fn touching_is_not_crossing() {
    // resting (bottom face in the floor's plane), sunk 5 µm (less than 2ε, handled as
    // resting: tests/boundary_primary.rs), 0.1 mm and 5 cm above it
    for y in [0.2, 0.199995, 0.2001, 0.25] {
        diff(&box_at(y), "box_x", BoundaryMode::Full).unwrap_or_else(|e| panic!("y = {y}: {e}"));
    }
    // the shipped scenes whose moving shapes rest on a surface: a pyramid's base on the floor
    // (the floor's diagonal runs under its base edges), a glass ball's vertex on the floor
    for (scene, param) in [
        ("contact_pyramid.toml", "pyramid_yaw"),
        ("obj_mesh.toml", "pyramid_height"),
        ("glass_ball_floor.toml", "glass_x"),
        ("narrow_pulse_box.toml", "tall_box_x"),
    ] {
        let s = crate::common::load(scene);
        diff(&s, param, BoundaryMode::Full).unwrap_or_else(|e| panic!("{scene}: {e}"));
    }
}

/// Writes `scene.toml` (and `cross.obj`) into `dir`: a floor, a point light at the camera and
/// the shapes in `shapes`, with a parameter `x` translating the shape `moving`.
fn scene_with(dir: &Path, shapes: &str, moving: &str) -> Scene {
    // a 0.4 m square and a 0.4 × 0.3 m one through it at right angles: one mesh that
    // crosses itself
    std::fs::write(
        dir.join("cross.obj"),
        "v -0.2 0 0\nv 0.2 0 0\nv 0.2 0.4 0\nv -0.2 0.4 0\n\
         v 0 0.05 -0.2\nv 0 0.05 0.2\nv 0 0.35 0.2\nv 0 0.35 -0.2\n\
         f 1 2 3 4\nf 5 6 7 8\n",
    )
    .unwrap();
    let text = format!(
        r#"
[integrator]
max_bounces = 1
spp = 1

[camera]
position = [0.0, 1.2, 2.2]
look_at = [0.0, 0.1, 0.0]
fov = 32.0
resolution = [8, 8]

[film]
start_opl = 2.8
bin_width_opl = 0.1
bins = 40
channels = "mono"

[[material]]
name = "grey"
type = "diffuse"
albedo = 0.5

[[shape]]
name = "floor"
type = "rectangle"
material = "grey"
rotate = [-90.0, 0.0, 0.0]
scale = [2.0, 2.0, 1.0]
{shapes}
[[emitter]]
name = "lamp"
type = "point"
position = [0.0, 1.2, 2.2]
intensity = 10.0
pulse = {{ type = "gaussian", sigma_opl = 0.1 }}

[[param]]
name = "x"
kind = "translate"
shape = "{moving}"
axis = "x"
value = 0.0
"#
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    Scene::load(&path, &[]).unwrap()
}

#[test]
fn a_moving_mesh_that_crosses_itself_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    // lifted 1 cm off the floor: the only crossing is its own
    let shapes = "[[shape]]\nname = \"cross\"\ntype = \"obj\"\nfile = \"cross.obj\"\nmaterial = \"grey\"\ntranslate = [0.0, 0.01, 0.0]\n";
    let msg = refusal(&scene_with(dir.path(), shapes, "cross"), "x");
    assert!(msg.contains("shape \"cross\" crosses itself"), "{msg}");
}

/// A static plate pushed halfway into the side of a moving box: no edge of the box meets the
/// plate, only the plate's edges pass through the box's face (found by the second BVH, of the
/// moving shapes alone).
#[test]
fn a_static_plate_through_a_moving_box_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let shapes = "[[shape]]\nname = \"box\"\ntype = \"cube\"\nmaterial = \"grey\"\ntranslate = [0.0, 0.3, 0.0]\nscale = 0.2\n\
                  [[shape]]\nname = \"plate\"\ntype = \"rectangle\"\nmaterial = \"grey\"\ntranslate = [0.2, 0.3, 0.0]\n\
                  rotate = [-90.0, 0.0, 0.0]\nscale = [0.1, 0.1, 1.0]\n";
    let scene = scene_with(dir.path(), shapes, "box");
    let msg = refusal(&scene, "x");
    assert!(msg.contains("shape \"plate\" crosses shape \"box\""), "{msg}");
    // moved apart, both render
    let apart = shapes.replace("translate = [0.2, 0.3, 0.0]", "translate = [0.35, 0.3, 0.0]");
    diff(&scene_with(dir.path(), &apart, "box"), "x", BoundaryMode::Full).unwrap();
}

/// A box resting on an area light: the light is lifted off the box's bottom face at load
/// (src/scene/flush.rs, so that its light wins), which makes the two cross; the refusal says
/// why, since the file shows them merely touching.
#[test]
fn a_box_resting_on_an_area_light_is_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(crate::common::scene_path("resting_box.toml")).unwrap();
    let point = "type = \"point\"\nposition = [0.0, 1.2, 2.2]\nintensity = 10.0";
    assert!(text.contains(point));
    let path = dir.path().join("on_light.toml");
    std::fs::write(
        &path,
        text.replace(point, "type = \"area\"\nshape = \"floor\"\nradiance = 1.0"),
    )
    .unwrap();
    let scene = Scene::load(&path, &[]).unwrap();
    assert_eq!(scene.lifted_emitters, ["floor"]);
    let msg = refusal(&scene, "box_x");
    assert!(
        msg.contains("an object resting on an emitter is not supported"),
        "{msg}"
    );
}
