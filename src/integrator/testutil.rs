//! Helpers for the integrator's unit tests: scenes from text at chosen parameter values, the
//! loader's own vertex positions a step either side of a parameter's value (the reference
//! for derivatives of geometry).

use crate::scene::testutil::header;
use crate::scene::{Format, ParamKind, Scene};
use glam::Vec3;
use std::path::Path;

/// A shape posed away from the world origin (the render origin, which positions and
/// transforms are relative to, is then not the world's) with a rotation about all three axes
/// and an unequal scale, and a mirrored plate (negative scale: the loader flips its winding).
/// Every pose component of both is a parameter, at the value the shape states.
pub const POSED: &str = concat!(
    header!(),
    r#"
[[shape]]
name = "box"
type = "cube"
material = "white"
translate = [10.3, -0.4, 0.7]
rotate = [25.0, -40.0, 15.0]
scale = [1.25, 0.625, 0.875]

[[shape]]
name = "plate"
type = "rectangle"
material = "white"
translate = [9.0, 1.5, -0.5]
rotate = [-70.0, 20.0, 10.0]
scale = [-0.75, 1.125, 1.0]

[[emitter]]
name = "lamp"
type = "point"
position = [10.0, 3.0, 3.0]
intensity = 1.0

[[param]]
name = "tx"
kind = "translate"
shape = "box"
axis = "x"
value = 10.3

[[param]]
name = "ty"
kind = "translate"
shape = "box"
axis = "y"
value = -0.4

[[param]]
name = "rx"
kind = "rotate"
shape = "box"
axis = "x"
value = 25.0

[[param]]
name = "ry"
kind = "rotate"
shape = "box"
axis = "y"
value = -40.0

[[param]]
name = "rz"
kind = "rotate"
shape = "box"
axis = "z"
value = 15.0

[[param]]
name = "sx"
kind = "scale"
shape = "box"
axis = "x"
value = 1.25

[[param]]
name = "sy"
kind = "scale"
shape = "box"
axis = "y"
value = 0.625

[[param]]
name = "sz"
kind = "scale"
shape = "box"
axis = "z"
value = 0.875

[[param]]
name = "plate_sx"
kind = "scale"
shape = "plate"
axis = "x"
value = -0.75

[[param]]
name = "plate_ry"
kind = "rotate"
shape = "plate"
axis = "y"
value = 20.0
"#
);

/// Parameters of [`POSED`] (the dual number's derivative lanes in the tests).
pub const POSED_PARAMS: usize = 10;

/// Loads scene `text` with `--set` overrides.
pub fn load(text: &str, overrides: &[(String, f64)]) -> Scene {
    Scene::from_str(text, Format::Toml, Path::new("unit_test.toml"), overrides).unwrap_or_else(|e| panic!("{e}"))
}

/// Every parameter's name, in file order.
pub fn param_names(scene: &Scene) -> Vec<String> {
    scene.params.iter().map(|p| p.name.clone()).collect()
}

/// The central-difference step of a pose parameter, a power of two so that value ± step is
/// exact in the f32 the loader keeps (the values of [`POSED`] are exact in f32 too). Positions
/// are linear in a translation and in a scale factor, so the step only has to keep the f32
/// rounding of the loaded positions (≤ 2⁻²⁴ of a coordinate) small against the move: 2⁻⁷
/// m or 2⁻⁷ leaves about 10⁻⁵. In a rotation they are sinusoids of the angle: 0.125° =
/// 2.2·10⁻³ rad leaves a truncation error of (2.2·10⁻³)²/6 ≈ 8·10⁻⁷ of the derivative.
pub fn step(kind: &ParamKind) -> f64 {
    match kind {
        ParamKind::Rotate { .. } => 0.125,
        _ => 1.0 / 128.0,
    }
}

/// The loader's world vertex positions with parameter `k` of `scene` (loaded from `text`) set
/// to its value − h and + h. Both keep the render origin, so positions compare directly.
pub fn positions_either_side(text: &str, scene: &Scene, k: usize, h: f64) -> [Vec<Vec3>; 2] {
    let p = &scene.params[k];
    [-h, h].map(|s| {
        let moved = load(text, &[(p.name.clone(), p.value + s)]);
        assert_eq!(
            moved.render_origin, scene.render_origin,
            "{}: the render origin moved",
            p.name
        );
        moved.geometry.positions
    })
}
