//! Cost and variance of the boundary estimator (secondary edges, Algorithm 2).
//!
//! Scene: scenes/shadow_hidden_occluder.toml at 64×64 (30 bins of 0.1 m, Gaussian pulse,
//! 2 bounces), parameter `occluder_x`: the camera sees the moving shadow, not the occluder,
//! so interior + secondary is the whole gradient. Reports
//! 1. boundary samples per second (each sample runs the edge-directed and the light-directed
//!    strategy) and rays per second;
//! 2. the variance of the boundary estimate against its sample count, with and without the
//!    guiding grid: relative L2 error of the time-resolved derivative against a converged
//!    reference, and the standard deviation of its image total over seeds;
//! 3. the time of interior + boundary (one parameter) divided by the primal time, next to the
//!    relative errors of the primal and of the derivative against their references.
//!
//! Run: `cargo bench --bench boundary` (DTR_BENCH_THREADS; takes about half a minute).

mod common;
use difftransient::{BoundaryMode, RenderOptions, Scene, Transient, render, render_diff};
use std::path::PathBuf;

fn env_or<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d)
}

const PARAM: &str = "occluder_x";

fn diff_of(scene: &Scene, param: &str, o: &RenderOptions) -> (Transient, difftransient::RenderStats) {
    let (_, mut d, s) = render_diff(scene, &[param.to_string()], o).unwrap();
    (d.remove(0), s)
}

fn diff(scene: &Scene, o: &RenderOptions) -> (Transient, difftransient::RenderStats) {
    diff_of(scene, PARAM, o)
}

fn boundary_only(base: &RenderOptions, spp_b: u32, seed: u64, guiding: bool) -> RenderOptions {
    RenderOptions {
        spp: Some(1),
        spp_boundary: Some(spp_b),
        seed: Some(seed),
        boundary: BoundaryMode::BoundaryOnly,
        guiding,
        ..base.clone()
    }
}

/// Throughput, then rel. L2 error against a reference and the sd of the image total over 8
/// seeds, per sample count, guided and unguided.
fn variance_table(label: &str, scene: &Scene, param: &str, base: &RenderOptions, counts: &[u32], reference_spp: u32) {
    let (reference, _) = diff_of(scene, param, &boundary_only(base, reference_spp, 1000, true));
    let (_, s) = diff_of(scene, param, &boundary_only(base, counts[counts.len() - 1], 7, false));
    let b = s.boundary.clone().unwrap();
    println!(
        "{label}: {:.3e} boundary samples/s unguided ({} samples + {} pilot in {:.3} s wall, {:.3e} rays/s, {} edges)",
        b.secondary.samples as f64 / b.secondary.seconds,
        b.secondary.samples,
        b.secondary.pilot_samples,
        b.secondary.seconds,
        b.secondary.rays as f64 / b.secondary.seconds,
        b.edges
    );
    println!("   spp_boundary  samples   guided: relL2   sd(total)   unguided: relL2   sd(total)   seconds g/u");
    let pixels = (scene.film.width * scene.film.height) as u64;
    for &spp_b in counts {
        let mut row = Vec::new();
        for guiding in [true, false] {
            let (mut errs, mut totals, mut secs) = (0.0, Vec::new(), 0.0);
            for seed in 0..8 {
                let (d, s) = diff_of(scene, param, &boundary_only(base, spp_b, seed, guiding));
                errs += common::rel_l2(&d.data, &reference.data) / 8.0;
                totals.push(total(&d));
                secs += s.boundary_seconds / 8.0;
            }
            let m = totals.iter().sum::<f64>() / 8.0;
            let sd = (totals.iter().map(|t| (t - m).powi(2)).sum::<f64>() / 7.0).sqrt();
            row.push((errs, sd, secs));
        }
        println!(
            "   {spp_b:>12}  {:>7}   {:>13.4}   {:>9.3e}   {:>15.4}   {:>9.3e}   {:.3}/{:.3}",
            spp_b as u64 * pixels,
            row[0].0,
            row[0].1,
            row[1].0,
            row[1].1,
            row[0].2,
            row[1].2
        );
    }
}

fn total(t: &Transient) -> f64 {
    t.data.iter().map(|&v| v as f64).sum()
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mut scene = Scene::load(&root.join("scenes/shadow_hidden_occluder.toml"), &[]).expect("scene");
    let res: u32 = env_or("DTR_BENCH_RES", 64);
    scene.film.width = res;
    scene.film.height = res;
    // DTR_BENCH_SAMPLER=sobol: Sobol points for the interior and the boundary samples
    let sobol = std::env::var("DTR_BENCH_SAMPLER").is_ok_and(|s| s == "sobol");
    let sampler = if sobol {
        difftransient::kernel::SampleSequence::Sobol
    } else {
        difftransient::kernel::SampleSequence::Independent
    };
    scene.integrator.sampler = sampler;
    let threads: usize = env_or(
        "DTR_BENCH_THREADS",
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
    );
    let base = RenderOptions {
        threads: Some(threads),
        seed: Some(1),
        ..Default::default()
    };
    let only_ratio = std::env::var("DTR_BENCH_ONLY_RATIO").is_ok();
    if !only_ratio {
        println!("1-2. boundary samples per second; boundary estimate vs samples (8 seeds)");
        variance_table(
            &format!("shadow_hidden_occluder {res}x{res}, d/d{PARAM}"),
            &scene,
            PARAM,
            &base,
            &[1, 4, 16],
            256,
        );
        let cornell = Scene::load(&root.join("scenes/cornell_box.toml"), &[]).expect("scene");
        let mut cornell = common::with_pose_param(cornell);
        cornell.integrator.sampler = sampler;
        variance_table(
            "cornell_box 64x64 (secondary edges only; max 8 bounces), d/dtall_box_x",
            &cornell,
            "tall_box_x",
            &base,
            &[1, 4, 16],
            64,
        );
    }

    // 3. interior + boundary vs primal; references for both
    let reference_b = diff(&scene, &boundary_only(&base, 256, 1000, true)).0;
    let (reference_i, _) = diff(
        &scene,
        &RenderOptions {
            spp: Some(256),
            seed: Some(1001),
            boundary: BoundaryMode::InteriorOnly,
            ..base.clone()
        },
    );
    let reference_d: Vec<f32> = reference_b
        .data
        .iter()
        .zip(&reference_i.data)
        .map(|(a, b)| a + b)
        .collect();
    let (reference_p, _) = render(
        &scene,
        &RenderOptions {
            spp: Some(1024),
            seed: Some(1002),
            ..base.clone()
        },
    )
    .unwrap();
    let spp: u32 = env_or("DTR_BENCH_SPP", 16);
    let reps = 3;
    let o = RenderOptions {
        spp: Some(spp),
        ..base.clone()
    };
    let mut best_p = f64::MAX;
    let mut primal = None;
    for _ in 0..reps {
        let (p, sp) = render(&scene, &o).unwrap();
        best_p = best_p.min(sp.wall_seconds);
        primal = Some(p);
    }
    let e_p = common::rel_l2(&primal.unwrap().data, &reference_p.data);
    println!(
        "3. shadow_hidden_occluder {res}x{res}, {spp} spp: primal {best_p:.4} s wall (best of {reps}), rel. L2 {e_p:.3}"
    );
    println!("   guiding  spp_boundary  interior+boundary s  (boundary s)  rel. L2 of dI/dθ  time ratio");
    for (guiding, spp_b) in [(false, 4u32), (false, 16), (false, 64), (true, 4), (true, 16)] {
        let ob = RenderOptions {
            spp_boundary: Some(spp_b),
            guiding,
            ..o.clone()
        };
        let mut best_d = f64::MAX;
        let mut last = None;
        for _ in 0..reps {
            let (d, sd) = diff(&scene, &ob);
            best_d = best_d.min(sd.wall_seconds + sd.boundary_seconds);
            last = Some((d, sd));
        }
        let (d, sd) = last.unwrap();
        println!(
            "   {:>7}  {spp_b:>12}  {best_d:>19.4}  {:>12.4}  {:>16.3}  {:>9.2}x",
            if guiding { "on" } else { "off" },
            sd.boundary_seconds,
            common::rel_l2(&d.data, &reference_d),
            best_d / best_p
        );
    }
}
