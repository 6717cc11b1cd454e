//! Inverse rendering, time against a steady image (issue 12, demo 4): the depth of a wall
//! and its albedo (scenes/diff_room.toml: the camera sees only the back wall) set its
//! steady brightness together, so a steady-state loss is nearly flat along a valley and
//! stays far from the answer, while a loss on the transient (the wall's light arrives 2·Δz
//! of OPL earlier or later) recovers both from the same start.

use crate::common;
use difftransient::optimize::loss::Loss;

fn run(loss: Loss) -> Vec<f64> {
    let p = common::small_problem(
        "diff_room.toml",
        &["room_z", "albedo"],
        loss,
        vec![(-1.0, 1.0), (0.01, 1.0)],
    );
    let steps = p.optimize(&[0.3, 0.5], 150, &[0.02, 0.02], 0.1, |_| true).unwrap();
    let last = steps.last().unwrap();
    eprintln!("{loss:?}: {:?} → {:?}", steps[0].values, last.values);
    last.values.clone()
}

#[test]
fn a_transient_loss_finds_depth_and_albedo_where_a_steady_loss_stalls() {
    // truth: room_z = 0, albedo = 0.6
    let timed = run(Loss::Smooth { sigma_bins: 4.0 });
    assert!(timed[0].abs() < 0.01 && (timed[1] - 0.6).abs() < 0.02, "{timed:?}");
    let steady = run(Loss::Steady);
    assert!(
        steady[0].abs() > 0.1,
        "the steady loss should stall along its valley: {steady:?}"
    );
}
