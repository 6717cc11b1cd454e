//! What `Scene::set_params` saves over loading the scene again with overrides (issue 15): the
//! time of one change of a parameter both ways on scenes with built-in shapes and with OBJ
//! meshes, and optimizer iterations per second on the IOR problem (examples/ior:
//! scenes/liquid_glass.toml, `liquid_ior`, 4 spp per render, as `dtr optimize` runs it)
//! with the scene loaded at every iteration (as before) and set in place (as now).
//!
//! Run: `cargo bench --bench set_params` (DTR_BENCH_THREADS, DTR_BENCH_ITERS).

use difftransient::optimize::{Problem, loss::Loss};
use difftransient::{RenderOptions, Scene, render};
use std::path::PathBuf;
use std::time::Instant;

fn env_or<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d)
}

/// Median seconds of `reps` runs of `f`.
fn median(reps: usize, mut f: impl FnMut(usize)) -> f64 {
    let mut t: Vec<f64> = (0..reps)
        .map(|i| {
            let t0 = Instant::now();
            f(i);
            t0.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[reps / 2]
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes");
    println!("one parameter change (median of 21):");
    for (file, param, base) in [
        ("liquid_glass.toml", "liquid_ior", 1.33),
        ("ball_slide.toml", "ball_x", 0.0),
        ("nlos_curved_wall.toml", "hidden_albedo", 0.5),
        ("pyramid_turn.toml", "pyramid_yaw", 10.0),
    ] {
        let path = root.join(file);
        let value = |i: usize| base + 0.001 * i as f64;
        let load = median(21, |i| {
            Scene::load(&path, &[(param.to_string(), value(i))]).unwrap();
        });
        let mut scene = Scene::load(&path, &[]).unwrap();
        let set = median(21, |i| scene.set_param(param, value(i)).unwrap());
        println!(
            "  {file:<24} {param:<14} load {:8.3} ms   set_params {:8.3} ms   ({:.1}x)",
            load * 1e3,
            set * 1e3,
            load / set
        );
    }

    let threads: usize = env_or(
        "DTR_BENCH_THREADS",
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
    );
    let iters: usize = env_or("DTR_BENCH_ITERS", 20);
    let scene_path = root.join("liquid_glass.toml");
    let opts = RenderOptions {
        spp: Some(64),
        seed: Some(1000),
        threads: Some(threads),
        ..Default::default()
    };
    let target = render(&Scene::load(&scene_path, &[]).unwrap(), &opts).unwrap().0;
    let p = Problem {
        scene: scene_path.clone(),
        fixed: vec![],
        fixed_text: Vec::new(),
        params: vec!["liquid_ior".into()],
        target,
        loss: Loss::Smooth { sigma_bins: 4.0 },
        opts: RenderOptions { spp: Some(4), ..opts },
        bounds: vec![(1.0, 2.0)],
    };
    let x = |i: usize| 1.45 - 0.002 * i as f64;
    let _ = p.loss_and_gradient(&[x(0)], 0).unwrap(); // warm-up
    let reload = median(iters, |i| {
        p.loss_and_gradient(&[x(i)], 2 * i as u64).unwrap();
    });
    let mut scene = Scene::load(&scene_path, &[]).unwrap();
    let set = median(iters, |i| {
        scene.set_param("liquid_ior", x(i)).unwrap();
        p.loss_and_gradient_of(&scene, 2 * i as u64).unwrap();
    });
    println!(
        "optimizer iteration, liquid_glass.toml, 4 spp, {threads} threads (median of {iters}): \
         reload {:.1} ms ({:.2} it/s), set_params {:.1} ms ({:.2} it/s)",
        reload * 1e3,
        1.0 / reload,
        set * 1e3,
        1.0 / set
    );
}
