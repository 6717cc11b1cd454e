//! Cost and noise of the primary boundary term (src/boundary/primary.rs).
//!
//! Scene: scenes/silhouette_slide.toml (a tilted cube sliding in front of a wall) at 64×64,
//! parameter `cube_x`. Reports, for spp_boundary ∈ {1, 4, 16}: edge samples per second (and
//! how many were traced: seen by the eye), wall time against the primal render at the scene's
//! spp, and the relative standard deviation across seeds of the time-summed derivative in 8×8
//! pixel blocks (the error reached next to the time; film points are jittered over the edges
//! and this scene has no path noise (one bounce, point light), so it falls faster than
//! 1/√spp_boundary).
//!
//! Run: `cargo bench --bench primary_edges` (DTR_BENCH_THREADS; a few seconds on 2 cores).

use difftransient::accel::Device;
use difftransient::boundary::primary::render_primary_with_stats;
use difftransient::integrator::RenderContext;
use difftransient::params::lanes::Motion;
use difftransient::render::thread_pool;
use difftransient::{RenderOptions, Scene, Transient, render};
use std::path::PathBuf;
use std::time::Instant;

fn blocks(t: &Transient) -> Vec<f64> {
    let bw = t.width.div_ceil(8);
    let mut v = vec![0.0f64; bw * t.height.div_ceil(8)];
    for y in 0..t.height {
        for x in 0..t.width {
            v[(y / 8) * bw + x / 8] += t.time_sum(x, y, 0) as f64;
        }
    }
    v
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mut scene = Scene::load(&root.join("scenes/silhouette_slide.toml"), &[]).expect("scene");
    scene.film.width = 64;
    scene.film.height = 64;
    let threads: usize = std::env::var("DTR_BENCH_THREADS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1));
    let opts = RenderOptions {
        threads: Some(threads),
        ..Default::default()
    };
    let (_, primal) = render(&scene, &opts).expect("render");
    let device = Device::new("").expect("device");
    let mut ctx = RenderContext::new(&scene, &device).expect("context");
    ctx.motion = Motion::build(&scene, &["cube_x".to_string()]).expect("param");
    let edges = difftransient::boundary::edges::build_edges(&scene.geometry, scene.offset_scale);
    let pool = thread_pool(Some(threads)).expect("pool");
    println!(
        "silhouette_slide 64x64, {} bins, cube_x, {threads} threads; primal {} spp: {:.3} s wall",
        scene.film.axis.bins, scene.integrator.spp, primal.wall_seconds
    );
    let seeds = 6;
    for spp_b in [1u32, 4, 16] {
        let mut runs = Vec::new();
        let mut secs = f64::MAX;
        let mut stats = None;
        for seed in 0..seeds {
            let t0 = Instant::now();
            let (films, s) = render_primary_with_stats(&ctx, &edges, spp_b, seed, difftransient::Shard::WHOLE, &pool);
            secs = secs.min(t0.elapsed().as_secs_f64());
            runs.push(blocks(&films[0]));
            stats = Some(s);
        }
        let s = stats.unwrap();
        let n = runs[0].len();
        let (mut var, mut mean2) = (0.0, 0.0);
        for i in 0..n {
            let col: Vec<f64> = runs.iter().map(|r| r[i]).collect();
            let m = col.iter().sum::<f64>() / seeds as f64;
            var += col.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (seeds as f64 - 1.0);
            mean2 += m * m;
        }
        println!(
            "  spp_boundary {spp_b:2}: {:.3} s wall (×{:.2} primal), {:.3e} edge samples/s, {:.0}% traced, \
             relative sd of 8x8 block sums {:.2e}, non-finite {}",
            secs,
            secs / primal.wall_seconds,
            s.samples as f64 / secs,
            100.0 * s.traced as f64 / s.samples.max(1) as f64,
            (var / mean2.max(1e-300)).sqrt(),
            s.non_finite
        );
    }
}
