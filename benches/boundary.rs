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
//! 3. the CPU time the full one-parameter gradient (interior + primary + secondary) needs to
//!    reach a relative error, over the time the primal needs to reach the same: mean CPU
//!    seconds × relative variance over seeds (the squared error of an unbiased estimator,
//!    free of the reference's own noise; the rel. L2 against the reference is printed beside
//!    it as a check of the mean), at several (spp, spp_boundary), here and on the Cornell box
//!    (d/d`tall_box_x`).
//!
//! Run: `cargo bench --bench boundary` (DTR_BENCH_THREADS, DTR_BENCH_SEEDS (4),
//! DTR_BENCH_SAMPLER (sobol, the scenes' default, or independent), DTR_BENCH_ONLY_RATIO:
//! section 3 on the shadow scene alone; about two minutes in all).

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
    // the scene's sampler (Sobol points, the default); DTR_BENCH_SAMPLER=independent for
    // independent numbers, for the interior and the boundary samples alike
    let sampler = match std::env::var("DTR_BENCH_SAMPLER").as_deref() {
        Ok("independent") => difftransient::kernel::SampleSequence::Independent,
        Ok("sobol") | Err(_) => difftransient::kernel::SampleSequence::Sobol,
        Ok(other) => panic!("DTR_BENCH_SAMPLER: expected sobol or independent, got {other:?}"),
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
    let cornell = || {
        let mut cornell =
            common::with_pose_param(Scene::load(&root.join("scenes/cornell_box.toml"), &[]).expect("scene"));
        cornell.integrator.sampler = sampler;
        cornell
    };
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
        variance_table(
            "cornell_box 64x64 (boundary terms only; max 8 bounces), d/dtall_box_x",
            &cornell(),
            "tall_box_x",
            &base,
            &[1, 4, 16],
            64,
        );
    }

    // 3. CPU time at equal error: the full one-parameter gradient against the primal
    let seeds: u64 = env_or("DTR_BENCH_SEEDS", 4);
    let configs = [(16, 4), (16, 16), (16, 64), (4, 16), (4, 64)];
    equal_error_table(
        &format!("shadow_hidden_occluder {res}x{res}, d/d{PARAM}"),
        &scene,
        PARAM,
        &base,
        &[16, 64],
        &configs,
        seeds,
        (1024, 1024, 4096),
    );
    if !only_ratio {
        equal_error_table(
            "cornell_box 64x64, d/dtall_box_x",
            &cornell(),
            "tall_box_x",
            &base,
            &[16, 64],
            &configs,
            seeds,
            (256, 256, 1024),
        );
    }
}

/// Mean CPU seconds, mean squared relative L2 error against the reference, and the
/// reference-free squared relative error: the variance over seeds, Σ_i Σ_k (x_ki − x̄_i)² /
/// (K − 1) over ‖reference‖² (for an unbiased estimator, its expected squared error; the
/// reference's own noise, which the former includes, cannot inflate it).
struct Cost {
    cpu: f64,
    mse: f64,
    var: f64,
}

impl Cost {
    /// CPU seconds × squared error (the variance's): for unbiased estimators whose error falls
    /// as 1/√time, the CPU time needed to reach a relative error of 1 (÷ E² for error E).
    fn work(&self) -> f64 {
        self.cpu * self.var
    }
}

/// Σ_i Σ_k (x_ki − x̄_i)² / (K − 1) / ‖reference‖²: the relative variance of one render.
fn relative_variance(runs: &[Vec<f32>], reference: &[f32]) -> f64 {
    let k = runs.len() as f64;
    let norm: f64 = reference.iter().map(|&r| (r as f64).powi(2)).sum();
    let mut sum = 0.0;
    for i in 0..reference.len() {
        let mean = runs.iter().map(|r| r[i] as f64).sum::<f64>() / k;
        sum += runs.iter().map(|r| (r[i] as f64 - mean).powi(2)).sum::<f64>();
    }
    sum / (k - 1.0) / norm.max(f64::MIN_POSITIVE)
}

/// Section 3: the primal render at `primal_spp`, the full gradient (interior + primary +
/// secondary, one parameter) at each (spp, spp_boundary) of `configs`, `seeds` renders each
/// (seeds 1..), relative L2 errors against converged references (primal at `refs.2` spp; the
/// derivative as an interior render at `refs.0` spp plus a guided boundary-only render at
/// `refs.1` samples per pixel, their own seeds). The time ratio at equal error is the gradient's
/// CPU seconds × relative variance over the primal's: the CPU time the gradient needs to reach
/// a given relative error over the time the primal needs to reach the same.
#[allow(clippy::too_many_arguments)]
fn equal_error_table(
    label: &str,
    scene: &Scene,
    param: &str,
    base: &RenderOptions,
    primal_spp: &[u32],
    configs: &[(u32, u32)],
    seeds: u64,
    refs: (u32, u32, u32),
) {
    let reference_b = diff_of(scene, param, &boundary_only(base, refs.1, 1000, true)).0;
    let (reference_i, _) = diff_of(
        scene,
        param,
        &RenderOptions {
            spp: Some(refs.0),
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
    let reference_p = render(
        scene,
        &RenderOptions {
            spp: Some(refs.2),
            seed: Some(1002),
            ..base.clone()
        },
    )
    .unwrap()
    .0;
    // a row renders a seed and returns the derivative or transient and its CPU seconds
    enum Row {
        Primal(u32),
        Gradient(u32, u32),
    }
    let run = |row: &Row, seed: u64| -> (Vec<f32>, f64) {
        match *row {
            Row::Primal(spp) => {
                let o = RenderOptions {
                    spp: Some(spp),
                    seed: Some(seed),
                    ..base.clone()
                };
                let (t, s) = render(scene, &o).unwrap();
                (t.data, s.total_cpu_seconds)
            }
            Row::Gradient(spp, spp_b) => {
                let o = RenderOptions {
                    spp: Some(spp),
                    spp_boundary: Some(spp_b),
                    seed: Some(seed),
                    ..base.clone()
                };
                let (d, s) = diff_of(scene, param, &o);
                (d.data, s.total_cpu_seconds)
            }
        }
    };
    let rows: Vec<Row> = primal_spp
        .iter()
        .map(|&spp| Row::Primal(spp))
        .chain(configs.iter().map(|&(spp, spp_b)| Row::Gradient(spp, spp_b)))
        .collect();
    // warm-up (first-use costs), then the rows interleaved seed by seed, so that a drift of
    // the machine's speed weighs on every row alike
    for row in &rows {
        run(row, 0);
    }
    let mut runs: Vec<(Vec<Vec<f32>>, f64)> = rows.iter().map(|_| (Vec::new(), 0.0)).collect();
    for seed in 1..=seeds {
        for (row, (data, cpu)) in rows.iter().zip(runs.iter_mut()) {
            let (d, seconds) = run(row, seed);
            data.push(d);
            *cpu += seconds / seeds as f64;
        }
    }
    let costs: Vec<Cost> = rows
        .iter()
        .zip(&runs)
        .map(|(row, (data, cpu))| {
            let reference = match row {
                Row::Primal(_) => &reference_p.data,
                Row::Gradient(..) => &reference_d,
            };
            let mse = data.iter().map(|d| common::rel_l2(d, reference).powi(2)).sum::<f64>() / seeds as f64;
            Cost {
                cpu: *cpu,
                mse,
                var: relative_variance(data, reference),
            }
        })
        .collect();
    println!(
        "3. {label}: CPU time at equal error, {seeds} seeds per row, rows interleaved (mean CPU s; rms rel. L2 \
         against the reference, and without it: √ of the relative variance over seeds, which the time ratio uses)"
    );
    // the primal's efficiency: the best of its rows (the larger spp amortises start-up)
    let primal_work = rows
        .iter()
        .zip(&costs)
        .filter(|(r, _)| matches!(r, Row::Primal(_)))
        .map(|(_, c)| c.work())
        .fold(f64::MAX, f64::min);
    for (row, c) in rows.iter().zip(&costs) {
        match row {
            Row::Primal(spp) => println!(
                "   primal          spp {spp:>3}                 {:>8.4} s  rel. L2 {:.4} (sd {:.4})  CPU s × sd² {:.3e}",
                c.cpu,
                c.mse.sqrt(),
                c.var.sqrt(),
                c.work()
            ),
            Row::Gradient(spp, spp_b) => println!(
                "   gradient        spp {spp:>3}  spp_boundary {spp_b:>3}  {:>8.4} s  rel. L2 {:.4} (sd {:.4})  CPU s × sd² {:.3e}  time at equal error {:.2}× the primal",
                c.cpu,
                c.mse.sqrt(),
                c.var.sqrt(),
                c.work(),
                c.work() / primal_work
            ),
        }
    }
}
