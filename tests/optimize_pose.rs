//! Inverse rendering, the pose demo (issue 12): recover a cube's translation and yaw from a
//! transient camera view (scenes/pose_plate.toml) by Adam on the adjoint gradient, starting
//! 0.15 m and 8° away. The gradient needs the boundary term: the interior derivative of an
//! in-plane motion is zero (only the silhouette moves), so the same run with the interior
//! alone ends where it started.

use crate::common;
use difftransient::RenderOptions;
use difftransient::optimize::{Problem, loss::Loss};
use difftransient::render::BoundaryMode;

const TRUTH: [f64; 2] = [0.1, 20.0];
const START: [f64; 2] = [0.25, 28.0];

fn problem(boundary: BoundaryMode) -> Problem {
    let scene = common::scene_path("pose_plate.toml");
    let target = common::converged_target(&scene);
    Problem {
        scene,
        fixed: vec![],
        fixed_text: Vec::new(),
        params: vec!["plate_x".into(), "plate_roll".into()],
        target,
        loss: Loss::L2,
        opts: RenderOptions {
            spp: Some(4),
            spp_boundary: Some(4),
            seed: Some(1),
            threads: Some(2),
            boundary,
            ..Default::default()
        },
        bounds: vec![(-0.5, 0.5), (0.0, 90.0)],
    }
}

fn run(boundary: BoundaryMode) -> Vec<f64> {
    let p = problem(boundary);
    let steps = p.optimize(&START, 80, &[0.01, 0.8], 0.1, |_| true).unwrap();
    let last = &steps[steps.len() - 1];
    let first = &steps[0];
    eprintln!(
        "{boundary:?}: loss {:.3e} → {:.3e}, values {:?} → {:?}",
        first.loss, last.loss, first.values, last.values
    );
    // the mean of the last 10 iterates: Adam's noise around the answer averages out
    let tail = &steps[steps.len() - 10..];
    (0..2)
        .map(|k| tail.iter().map(|s| s.values[k]).sum::<f64>() / tail.len() as f64)
        .collect()
}

#[test]
fn pose_is_recovered_with_the_boundary_term_and_not_without() {
    let full = run(BoundaryMode::Full);
    // (a 64-spp target left the answer 0.65° off: the noise of the target moves the
    // loss's minimum; at 1024 spp it is 0.001°)
    assert!((full[0] - TRUTH[0]).abs() < 0.005, "translation {full:?}");
    assert!((full[1] - TRUTH[1]).abs() < 0.5, "roll {full:?}");
    let interior = run(BoundaryMode::InteriorOnly);
    assert!(
        (interior[0] - TRUTH[0]).abs() > 0.1 && (interior[1] - TRUTH[1]).abs() > 5.0,
        "the interior alone should not find the pose: {interior:?}"
    );
}
