//! A derivative render says when a parameter slides a shape along one it rests on
//! (`difftransient::render::sliding_contact_warning`, src/params/sliding.rs): there the
//! interior estimator's weight grows as one over the distance to the contact line, so its
//! estimate is heavy-tailed and biased there (BENCHMARKS.md, "The Cornell rows": the throughput
//! term's variance 4.7 × 10⁴ with the tall box resting, 539 with it 1 mm above the floor, 87
//! at 1 cm; README, "An object sliding on its support"). Until
//! the forty-eighth session nothing was said: resting_box.toml's `box_x` and `box_yaw`
//! rendered without a word.

use difftransient::Scene;
use difftransient::render::sliding_contact_warning;

/// scenes/resting_box.toml (a cube resting on the floor, turned 30° about the vertical) with
/// the cube's centre at height `y` (0.2: resting) and a parameter `box_y` that lifts it.
fn box_at(y: f64) -> Scene {
    let path = crate::common::scene_path("resting_box.toml");
    let text = std::fs::read_to_string(&path).unwrap()
        + "\n[[param]]\nname = \"box_y\"\nkind = \"translate\"\nshape = \"box\"\naxis = \"y\"\nvalue = 0.2\n";
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("resting_box.toml");
    std::fs::write(&copy, text).unwrap();
    Scene::load(&copy, &[("box_y".to_string(), y)]).unwrap()
}

fn warning(scene: &Scene, params: &[&str]) -> Option<String> {
    let params: Vec<String> = params.iter().map(|p| p.to_string()).collect();
    sliding_contact_warning(scene, &params).unwrap()
}

#[test]
fn sliding_a_resting_shape_is_said() {
    // resting, and sunk by less than the contact tolerance (handled as resting by the
    // boundary stage: tests/boundary_primary.rs)
    for y in [0.2, 0.2 - 5e-6] {
        let scene = box_at(y);
        let w = warning(&scene, &["box_x", "box_yaw"]).unwrap_or_else(|| panic!("y = {y}: nothing said"));
        for needle in [
            "box_x slides shape \"box\" along shape \"floor\"",
            "box_yaw slides shape \"box\" along shape \"floor\"",
            "biased at any sample count",
            "resting_box.toml",
        ] {
            assert!(w.contains(needle), "y = {y}: {needle:?} not in {w}");
        }
        // lifting it off the floor does not slide it
        assert_eq!(warning(&scene, &["box_y"]), None, "y = {y}");
    }
    // a millimetre above the floor the weight is bounded: nothing to say
    assert_eq!(warning(&box_at(0.201), &["box_x", "box_yaw"]), None);
}

/// `dtr render --diff` says it (once), and says nothing when the interior does not run
/// (`--estimators boundary`) or no parameter slides anything.
#[test]
fn the_render_says_it_where_the_interior_runs() {
    let dir = tempfile::tempdir().unwrap();
    let scene = crate::common::scene_path("resting_box.toml");
    let said = |out: &str, args: &[&str]| {
        let mut all = vec![
            "render",
            scene.to_str().unwrap(),
            "--spp",
            "1",
            "--threads",
            "1",
            "-o",
            out,
        ];
        all.extend_from_slice(args);
        let o = crate::common::dtr(&all, dir.path());
        assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).matches("slides shape").count()
    };
    assert_eq!(said("a", &["--diff", "box_x"]), 1);
    assert_eq!(said("b", &["--diff", "box_x", "--estimators", "boundary"]), 0);
    assert_eq!(said("c", &[]), 0);
}

/// scenes/resting_cube_close.toml (a cube resting on a floor, its front face meeting the floor
/// across the view, sliding towards the camera) zoomed to a field 14 µm wide at the contact
/// line, with a Gaussian pulse for BDPT. Paths there bounce between the floor and the face
/// within a few ε of the contact line (ε = 2⁻¹⁸ of the coordinates, the rays' offset), where
/// a segment's cosines are rounding noise. Until the fifty-first session the geometry term's
/// relative derivative ċos/cos was taken from that noise: up to 10⁸ per segment here, and
/// 10¹² in one sample of a 0.3 m cube seen from 2.6 m (2 of 1500 renders at 64 spp;
/// src/integrator/surface.rs, `geometry_ratio`). Now those segments keep their value and take
/// no derivative, and no pixel's derivative comes near 1/ε times the brightest pixel, a rate
/// of change no resolvable segment gives (each resolvable cosine changes by at most its motion
/// over ε relative to its value). Measured, max |d| / max I over 100 seeds: before 0.9–19 ×
/// 10⁵, now 2.7–4.4 × 10⁴ (path tracer; BDPT alike), against 1/ε = 2.6 × 10⁵.
#[test]
fn a_face_resting_on_a_floor_takes_no_derivative_from_rounding() {
    use difftransient::integrator::surface::OFFSET_PER_COORDINATE;
    use difftransient::render::BoundaryMode;
    use difftransient::scene::IntegratorKind;
    use difftransient::{RenderOptions, render_diff};
    let scene = difftransient::Scene::load_with_text(
        &crate::common::scene_path("resting_cube_close.toml"),
        &[("camera.fov".to_string(), 0.002)],
        &[(
            "emitter.light.pulse".to_string(),
            "{ type = \"gaussian\", sigma_opl = 0.1 }".to_string(),
        )],
    )
    .unwrap();
    let bound = 1.0 / (scene.offset_scale * OFFSET_PER_COORDINATE) as f64;
    for integrator in [IntegratorKind::Path, IntegratorKind::Bdpt] {
        let mut worst = 0.0f64;
        for seed in 1..=32 {
            let opts = RenderOptions {
                spp: Some(16),
                seed: Some(seed),
                threads: Some(1),
                integrator: Some(integrator),
                boundary: BoundaryMode::InteriorOnly,
                ..Default::default()
            };
            let (primal, d, _) = render_diff(&scene, &["cube_z".to_string()], &opts).unwrap();
            let brightest = primal.data.iter().fold(0.0f64, |m, &v| m.max(v as f64));
            assert!(brightest > 0.0, "{integrator:?} seed {seed}: no light");
            assert!(d[0].data.iter().all(|v| v.is_finite()), "{integrator:?} seed {seed}");
            let steepest = d[0].data.iter().fold(0.0f64, |m, &v| m.max((v as f64).abs()));
            worst = worst.max(steepest / brightest);
        }
        assert!(
            worst < bound,
            "{integrator:?}: max |d| / max I = {worst:.3e}, at or above 1/ε = {bound:.3e}"
        );
    }
}
