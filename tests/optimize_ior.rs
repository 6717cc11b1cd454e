//! The paper's IOR application (issue 13): the index of refraction of a liquid sealed in a
//! glass block, seen through the glass (scenes/liquid_glass.toml), recovered from its
//! transient by the optimizer (`optimize::Problem`: Adam on adjoint gradients) from a start
//! 0.12 off. Light that crosses the liquid arrives (η − 1) × its path in the liquid later,
//! so a loss on the transient pins η down (to within 0.01, from either side); the same runs
//! on the steady image (time summed) stall more than 0.05 away. Each run prints its loss
//! every ten iterations (`cargo test --release --test optimize_ior -- --nocapture`).

mod common;
use difftransient::optimize::loss::Loss;

fn run(loss: Loss, start: f64) -> f64 {
    let p = common::small_problem("liquid_glass.toml", &["liquid_ior"], loss, vec![(1.0, 2.0)]);
    let steps = p.optimize(&[start], 80, &[0.01], 0.1, |_| true).unwrap();
    for s in steps.iter().step_by(10) {
        eprintln!("{loss:?}: {:?} loss {:.4e}", s.values, s.loss);
    }
    steps.last().unwrap().values[0]
}

#[test]
fn the_liquid_ior_is_recovered_from_a_transient_but_not_from_the_steady_image() {
    // truth: 1.33
    for start in [1.45, 1.21] {
        let timed = run(Loss::Smooth { sigma_bins: 4.0 }, start);
        eprintln!("transient loss from {start}: {timed}");
        assert!((timed - 1.33).abs() < 0.01, "from {start}: ended at {timed}");
        // the steady image: the same run stalls (from 1.45 it ended at 1.398, from 1.21 at
        // 1.210 when this test was written; the steady loss barely changes with η)
        let steady = run(Loss::Steady, start);
        eprintln!("steady loss from {start}: {steady}");
        assert!(
            (steady - 1.33).abs() > 0.05,
            "the steady loss should not pin η down (from {start}: {steady})"
        );
    }
}
