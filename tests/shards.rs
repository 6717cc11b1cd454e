//! Shards (`RenderOptions::shard`, `dtr render --shard I/N`) add up to the whole render:
//! shard I of N traces the whole render's paths for its part of every estimator's samples
//! and normalises by the whole sample counts, so the sum of the shards' films
//! (`shard::add_films`, what `dtr merge` runs) equals the render up to the order of float
//! additions. The bounds below are the rounding error of that order, not Monte Carlo noise:
//! a shard that traced one wrong path, or normalised by its own count, fails them by orders
//! of magnitude.

use crate::common;
use difftransient::kernel::SampleSequence;
use difftransient::render::{DiffParts, render_diff_parts};
use difftransient::scene::IntegratorKind;
use difftransient::shard::add_films;
use difftransient::{RenderOptions, Shard, Transient, render};

/// f32 unit roundoff.
const U: f64 = 1.0 / 16_777_216.0;

fn opts(spp: u32, shard: Shard, integrator: IntegratorKind) -> RenderOptions {
    RenderOptions {
        spp: Some(spp),
        seed: Some(11),
        threads: Some(2),
        integrator: Some(integrator),
        shard,
        ..Default::default()
    }
}

fn shards(count: u32) -> impl Iterator<Item = Shard> {
    (0..count).map(move |i| Shard::new(i, count).unwrap())
}

/// Largest |a − b| / bound(i) over the values.
fn worst(a: &[f32], b: &[f32], bound: impl Fn(usize) -> f64) -> f64 {
    a.iter()
        .zip(b)
        .enumerate()
        .map(|(i, (&x, &y))| (x as f64 - y as f64).abs() / bound(i).max(f64::MIN_POSITIVE))
        .fold(0.0, f64::max)
}

#[test]
fn path_tracer_shards_add_up_to_the_whole_render() {
    let mut scene = common::load("cornell_box.toml");
    scene.film.width = 16;
    scene.film.height = 16;
    let spp = 7;
    // both sample sequences: a Sobol point depends on the pixel and the global sample index
    for sampler in [SampleSequence::Independent, SampleSequence::Sobol] {
        scene.integrator.sampler = sampler;
        let (whole, ws) = render(&scene, &opts(spp, Shard::WHOLE, IntegratorKind::Path)).unwrap();
        // 9 shards of 7 samples: two are empty
        for count in [3, 9] {
            let parts: Vec<(Transient, _)> = shards(count)
                .map(|s| render(&scene, &opts(spp, s, IntegratorKind::Path)).unwrap())
                .collect();
            let paths: u64 = parts.iter().map(|p| p.1.paths).sum();
            assert_eq!(paths, ws.paths, "{count} shards trace the whole render's paths");
            let merged = add_films(&parts.iter().map(|p| &p.0).collect::<Vec<_>>()).unwrap();
            // A pixel-bin of the whole render sums at most spp·2·(B + 1) non-negative terms in f32
            // (emission and next-event at each vertex): recursive summation errs by at most
            // (n − 1)·u of the sum; the shards' sums the same, then three roundings.
            let n = (spp as f64) * 2.0 * (scene.integrator.max_bounces as f64 + 1.0);
            let tol = |v: f32| (2.0 * n + 8.0) * U * v.abs() as f64;
            let r = worst(&merged.data, &whole.data, |i| tol(whole.data[i]));
            assert!(r <= 1.0, "{count} shards: transient off by {r} × the rounding bound");
            let r = worst(&merged.steady, &whole.steady, |i| tol(whole.steady[i]));
            assert!(r <= 1.0, "{count} shards: steady image off by {r} × the rounding bound");
            assert!(whole.data.iter().sum::<f32>() > 0.0);
        }
    }
}

#[test]
fn a_shard_normalised_by_its_own_samples_would_fail() {
    // the check above has teeth: one shard's film scaled as if it were the whole render
    let mut scene = common::load("cornell_box.toml");
    scene.film.width = 8;
    scene.film.height = 8;
    let (whole, _) = render(&scene, &opts(4, Shard::WHOLE, IntegratorKind::Path)).unwrap();
    let (half, _) = render(&scene, &opts(4, Shard::new(0, 2).unwrap(), IntegratorKind::Path)).unwrap();
    let mut wrong = half.clone();
    wrong.scale(2.0);
    let merged = add_films(&[&wrong, &half]).unwrap();
    let r = worst(&merged.data, &whole.data, |i| 200.0 * U * whole.data[i].abs() as f64);
    assert!(r > 1000.0, "{r}");
}

#[test]
fn bdpt_shards_add_up_to_the_whole_render() {
    let scene = common::cornell(16, 16, 4);
    let spp = 5;
    let (whole, _) = render(&scene, &opts(spp, Shard::WHOLE, IntegratorKind::Bdpt)).unwrap();
    let parts: Vec<Transient> = shards(2)
        .map(|s| render(&scene, &opts(spp, s, IntegratorKind::Bdpt)).unwrap().0)
        .collect();
    let merged = add_films(&parts.iter().collect::<Vec<_>>()).unwrap();
    // Light-tracing splats from every tile of a chunk land in one pixel-bin, so the count of
    // terms has no small bound: 10⁻⁵ of the value is ~170 roundings, far above the
    // √n·u the reordering of a few thousand terms gives.
    let r = worst(&merged.data, &whole.data, |i| 1e-5 * whole.data[i].abs() as f64);
    assert!(r <= 1.0, "BDPT: transient off by {r} × 10⁻⁵");
}

/// Interior, primary and secondary parts of every shard and of the whole render.
fn diff(scene: &difftransient::Scene, params: &[String], shard: Shard) -> DiffParts {
    let o = RenderOptions {
        spp_boundary: Some(3),
        ..opts(4, shard, IntegratorKind::Path)
    };
    render_diff_parts(scene, params, &o).unwrap()
}

#[test]
fn derivative_shards_add_up_with_both_boundary_terms() {
    // a sliding cube (primary edges) and a hidden occluder's shadow (secondary edges)
    for (name, param) in [
        ("silhouette_slide.toml", "cube_x"),
        ("shadow_hidden_occluder.toml", "occluder_x"),
    ] {
        let mut scene = common::load(name);
        scene.film.width = 16;
        scene.film.height = 16;
        let params = vec![param.to_string()];
        let whole = diff(&scene, &params, Shard::WHOLE);
        let parts: Vec<DiffParts> = shards(3).map(|s| diff(&scene, &params, s)).collect();
        let boundary = whole.stats.boundary.as_ref().expect("the boundary stage ran");
        assert!(boundary.secondary.samples > 0);
        let sums: Vec<Transient> = parts.iter().map(|p| p.sum().remove(0)).collect();
        let merged = add_films(&sums.iter().collect::<Vec<_>>()).unwrap();
        let w = whole.sum().remove(0);
        // Every derivative part is summed in f64 and rounded to f32 once or twice, and the
        // parts are added in f32: each value is within 5u of its parts' magnitudes.
        let mag = |p: &DiffParts, i: usize| {
            (p.interior[0].data[i].abs() + p.primary[0].data[i].abs() + p.secondary[0].data[i].abs()) as f64
        };
        let bound = |i: usize| 8.0 * U * (parts.iter().map(|p| mag(p, i)).sum::<f64>() + mag(&whole, i));
        let r = worst(&merged.data, &w.data, bound);
        assert!(r <= 1.0, "{name}: derivative off by {r} × the rounding bound");
        let moved: f64 = w.data.iter().map(|v| v.abs() as f64).sum();
        assert!(moved > 0.0, "{name}: the derivative is not zero");
        let primal = add_films(&parts.iter().map(|p| &p.primal).collect::<Vec<_>>()).unwrap();
        let r = worst(&primal.data, &whole.primal.data, |i| {
            200.0 * U * whole.primal.data[i].abs() as f64
        });
        assert!(r <= 1.0, "{name}: primal off by {r} × the rounding bound");
    }
}
