//! A derivative render says when a parameter slides a shape along one it rests on
//! (`difftransient::render::sliding_contact_warning`, src/params/sliding.rs): there the
//! interior estimator's weight grows as one over the distance to the contact line, so its
//! variance is unbounded (BENCHMARKS.md, "The Cornell rows": the throughput term's variance
//! 4.7 × 10⁴ with the tall box resting, 539 with it 1 mm above the floor, 87 at 1 cm). Until
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
            "variance is unbounded",
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
