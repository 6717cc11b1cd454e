//! BDPT against the path tracer on the Cornell box, and the cost of BDPT's derivative.
//!
//! 1. Forward: both integrators at the same samples per pixel; paths per CPU-second, and the
//!    relative L2 error each reached against a converged BDPT reference (independent seed) (of the
//!    time-summed image and of the whole transient), so speed is reported with the error
//!    bought; "efficiency" is 1 / (error² · CPU-s), higher is better.
//! 2. Derivative: BDPT with one parameter (the tall box's x position, Gaussian pulse so the
//!    time derivative exists) ÷ BDPT primal, wall time, for the scene's box filter (t = 1
//!    left out of the derivative render) and for a tent filter (t = 1 splats differentiated).
//!
//! Run: `cargo bench --bench bdpt` (DTR_BENCH_SPP, DTR_BENCH_REF_SPP, DTR_BENCH_DIFF_SPP,
//! DTR_BENCH_THREADS).

mod common;
use difftransient::scene::{IntegratorKind, PixelFilter};
use difftransient::{RenderOptions, Scene, render, render_diff};
use std::path::PathBuf;

fn env_or<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d)
}

fn opts(kind: IntegratorKind, spp: u32, seed: u64, threads: usize) -> RenderOptions {
    RenderOptions {
        spp: Some(spp),
        seed: Some(seed),
        threads: Some(threads),
        integrator: Some(kind),
        ..Default::default()
    }
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mut scene = Scene::load(&root.join("scenes/cornell_box.toml"), &[]).expect("scene");
    scene.film.width = 32;
    scene.film.height = 32;
    let spp: u32 = env_or("DTR_BENCH_SPP", 16);
    let ref_spp: u32 = env_or("DTR_BENCH_REF_SPP", 512);
    let threads: usize = env_or(
        "DTR_BENCH_THREADS",
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
    );
    // BDPT reference (independent seed): the path tracer's rare high-energy paths (light
    // reaching the ceiling beside the lamp) make a path-traced reference itself the largest
    // error term at this sample count
    let (reference, _) = render(&scene, &opts(IntegratorKind::Bdpt, ref_spp, 99, threads)).unwrap();
    println!(
        "Cornell box 32x32, 200 bins x 0.06 m from 3.6 m, max 8 bounces, delta pulse, {spp} spp, {threads} threads; \
         reference: BDPT, {ref_spp} spp, another seed"
    );
    // pixels that see the light directly: their error is the filter sampling of the light's
    // edge, which both integrators do the same way (s = 0); the rest is where they differ
    let peak = reference.steady.iter().fold(0.0f32, |m, v| m.max(*v));
    let lit: Vec<bool> = reference.steady.iter().map(|&v| v > 0.1 * peak).collect();
    let off_light = |v: &[f32]| -> Vec<f32> { v.iter().zip(&lit).filter(|(_, l)| !**l).map(|(x, _)| *x).collect() };
    // different seeds: with the same seed both integrators would share their pixel-filter
    // samples, and with them the antialiasing error that dominates at this sample count
    for (kind, seed) in [(IntegratorKind::Path, 1), (IntegratorKind::Bdpt, 2)] {
        let (t, s) = render(&scene, &opts(kind, spp, seed, threads)).unwrap();
        let e_img = common::rel_l2(&t.steady, &reference.steady);
        let e_ind = common::rel_l2(&off_light(&t.steady), &off_light(&reference.steady));
        let e_tr = common::rel_l2(&t.data, &reference.data);
        println!(
            "  {kind:?}: {:.3e} paths/CPU-s, {:.3} CPU-s; rel. L2 error: image {e_img:.4}, image without the \
             light's pixels {e_ind:.4}, transient {e_tr:.4}; efficiency 1/(err² CPU-s) without the light's pixels {:.3e}",
            s.paths_per_cpu_second,
            s.cpu_seconds,
            1.0 / (e_ind * e_ind * s.cpu_seconds)
        );
    }

    let mut scene = common::with_pose_param(scene);
    let names = ["tall_box_x".to_string()];
    let diff_spp: u32 = env_or("DTR_BENCH_DIFF_SPP", 64);
    for (label, filter) in [
        ("box filter (t = 1 off in the derivative render)", PixelFilter::Box),
        (
            "tent filter r = 1 (t = 1 splats differentiated)",
            PixelFilter::Tent { radius: 1.0 },
        ),
    ] {
        scene.film.filter = filter;
        let o = opts(IntegratorKind::Bdpt, diff_spp, 3, threads);
        let reps = 3;
        let (mut best_p, mut best_d) = (f64::MAX, f64::MAX);
        for _ in 0..reps {
            best_p = best_p.min(render(&scene, &o).unwrap().1.wall_seconds);
            best_d = best_d.min(render_diff(&scene, &names, &o).unwrap().2.wall_seconds);
        }
        println!(
            "  BDPT derivative, Gaussian pulse, {diff_spp} spp, {label}: primal {best_p:.3} s, primal + d/dθ (Dual8<1>) {best_d:.3} s wall, \
             ratio {:.2}x (goal <= 1.6x), best of {reps}",
            best_d / best_p
        );
    }
}
