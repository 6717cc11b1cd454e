//! Cost of the interior derivative (Algorithm 1) against the primal render, Cornell box.
//!
//! Same workload as `forward` (64×64, 200 bins of 0.06 m from 3.6 m, up to 8 bounces) with a Gaussian
//! pulse (σ = 0.01 m; a delta pulse with box bins has no time derivative), and one
//! parameter: the tall box's x position. Reports primal and derivative wall time and paths per
//! CPU-second, and their ratio (goal ≤ 1.6×). The derivative render also produces the primal,
//! whose error against the plain render's is reported to show both estimate the same thing.
//!
//! Run: `cargo bench --bench interior_diff` (DTR_BENCH_SPP, DTR_BENCH_THREADS).

mod common;
use difftransient::{RenderOptions, Scene, render, render_diff};
use std::path::PathBuf;

fn env_or<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d)
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::load(&root.join("scenes/cornell_box.toml"), &[]).expect("scene");
    let scene = common::with_pose_param(scene);
    let spp: u32 = env_or("DTR_BENCH_SPP", 32);
    let threads: usize = env_or(
        "DTR_BENCH_THREADS",
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
    );
    let opts = RenderOptions {
        spp: Some(spp),
        seed: Some(3),
        threads: Some(threads),
        ..Default::default()
    };
    render(
        &scene,
        &RenderOptions {
            spp: Some(2),
            ..opts.clone()
        },
    )
    .unwrap(); // warm-up
    let reps = 3;
    let mut best_p = f64::MAX;
    let mut best_d = f64::MAX;
    let mut last = None;
    for _ in 0..reps {
        let (p, sp) = render(&scene, &opts).unwrap();
        let (q, d, sd) = render_diff(&scene, &["tall_box_x".to_string()], &opts).unwrap();
        best_p = best_p.min(sp.wall_seconds);
        best_d = best_d.min(sd.wall_seconds);
        last = Some((p, q, d, sp, sd));
    }
    let (p, q, d, sp, sd) = last.unwrap();
    let same: f64 = {
        let num: f64 = p.data.iter().zip(&q.data).map(|(a, b)| ((a - b) as f64).powi(2)).sum();
        let den: f64 = p.data.iter().map(|a| (*a as f64).powi(2)).sum();
        (num / den).sqrt()
    };
    let dsum: f64 = d[0].data.iter().map(|&v| v as f64).sum();
    println!(
        "Cornell box 64x64, 200 bins x 0.06 m from 3.6 m, max 8 bounces, Gaussian pulse, {spp} spp, {threads} threads, best of {reps}"
    );
    println!(
        "  primal          : {best_p:.3} s wall, {:.3e} paths/CPU-s",
        sp.paths_per_cpu_second
    );
    println!(
        "  primal + d/dθ (1 parameter, Dual8<1>): {best_d:.3} s wall, {:.3e} paths/CPU-s",
        sd.paths_per_cpu_second
    );
    println!("  ratio derivative/primal = {:.2}x (goal <= 1.6x)", best_d / best_p);
    println!("  primal of the derivative render vs plain render (same seed): rel. L2 {same:.2e}; Σ dI/dθ = {dsum:.4e}");
}
