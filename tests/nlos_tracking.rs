//! NLOS tracking (issue 12, demo 1): the 3D position of a hidden square from confocal
//! relay-wall transients (scenes/nlos_tracking.toml).
//!
//! The tracking runs with `--estimators interior` (`BoundaryMode::InteriorOnly`), which skips
//! the boundary stage (tests/nlos_boundary_fd.rs checks the full gradient of a capture). That
//! is the whole gradient only where the boundary term vanishes: here the square faces the wall with nothing in between, so no
//! visibility changes as it moves (scene file). The first test checks exactly that claim: the
//! interior derivative of each coordinate against central finite differences with common random
//! numbers, on coarse aggregates, strong enough to see a few percent of bias. The second
//! recovers the position from a perturbed start. The last tracks a black plate before a
//! backdrop (scenes/nlos_moving_plate.toml), seen only through its silhouette and its shadow:
//! its gradient is the boundary term alone, so the default (full) estimators recover it and the
//! interior alone never moves.

use crate::common;
use common::power::{Entry, Test};
use difftransient::optimize::{Problem, loss::Loss};
use difftransient::{BoundaryMode, RenderOptions, Scene, render, render_diff};

fn opts(spp: u32, seed: u64) -> RenderOptions {
    RenderOptions {
        boundary: BoundaryMode::InteriorOnly,
        ..common::options(spp, seed)
    }
}

fn load(file: &str, set: &[(&str, f64)]) -> Scene {
    let o: Vec<(String, f64)> = set.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    Scene::load(&common::scene_path(file), &o).unwrap()
}

/// AD − FD over 16 seeds of `spp` paths per sensor point on the coarse aggregates (total, halves, quadrants, time slices):
/// every aggregate within 4 standard errors (widened by the Richardson estimate of the finite
/// difference's truncation), and the run resolves a 5% bias of the largest aggregate.
///
/// The paths per sensor point resolve 5% of every coordinate's strongest aggregate about four
/// times over (`best` 80 or more against the 20 required; measured 2026-11-28: 83–120 on the
/// flat wall at 2048 paths, 99–189 on the curved one at 4096). The curved wall needs more
/// paths for the same resolution.
#[test]
fn interior_position_derivative_matches_finite_differences() {
    check_derivatives("nlos_tracking.toml", 2048);
}

#[test]
fn interior_position_derivative_matches_finite_differences_on_a_curved_wall() {
    check_derivatives("nlos_tracking_curved.toml", 4096);
}

fn check_derivatives(file: &str, spp: u32) {
    let params = [
        ("target_x", 0.1, 0.02),
        ("target_y", -0.05, 0.02),
        ("target_z", 0.6, 0.02),
    ];
    let names: Vec<String> = params.iter().map(|(n, _, _)| n.to_string()).collect();
    let base = load(file, &[]);
    let agg = |t: &difftransient::Transient| -> Vec<f64> {
        common::fd::coarse_aggregates(t).into_iter().map(|(_, v)| v).collect()
    };
    // one derivative render per seed gives all three coordinates (their lanes share its paths)
    let ad_runs: Vec<Vec<Vec<f64>>> = (0..16)
        .map(|seed| {
            let (_, d, _) = render_diff(&base, &names, &opts(spp, seed)).unwrap();
            d.iter().map(agg).collect()
        })
        .collect();
    for (p, (name, value, h)) in params.into_iter().enumerate() {
        let at = |d: f64| load(file, &[(name, value + d)]);
        let (p1, m1, p2, m2) = (at(h), at(-h), at(2.0 * h), at(-2.0 * h));
        let (mut diffs, mut ads, mut rich) = (Vec::new(), Vec::new(), Vec::new());
        for (seed, ad_seed) in ad_runs.iter().enumerate() {
            let ad = ad_seed[p].clone();
            let r = |s: &Scene| agg(&render(s, &opts(spp, seed as u64)).unwrap().0);
            let (a, b, c, e) = (r(&p1), r(&m1), r(&p2), r(&m2));
            let fd: Vec<f64> = a.iter().zip(&b).map(|(x, y)| (x - y) / (2.0 * h)).collect();
            let fd2: Vec<f64> = c.iter().zip(&e).map(|(x, y)| (x - y) / (4.0 * h)).collect();
            rich.push(fd2.iter().zip(&fd).map(|(x, y)| (x - y) / 3.0).collect::<Vec<_>>());
            diffs.push(ad.iter().zip(&fd).map(|(x, y)| x - y).collect::<Vec<_>>());
            ads.push(ad);
        }
        let col = |m: &[Vec<f64>], i: usize| -> Vec<f64> { m.iter().map(|r| r[i]).collect() };
        let mut best = 0.0f64;
        let mut entries = Vec::new();
        for i in 0..diffs[0].len() {
            let (m, se) = common::mean_se(&col(&diffs, i));
            let (ma, _) = common::mean_se(&col(&ads, i));
            let (mr, ser) = common::mean_se(&col(&rich, i));
            let sd = (se * se + (mr.abs() + 2.0 * ser).powi(2)).sqrt();
            if ma == 0.0 && m == 0.0 {
                continue;
            }
            eprintln!("{file} {name} aggregate {i}: AD {ma:.4e}, AD − FD {m:.3e} ± {sd:.2e}");
            assert!(
                m.abs() <= 4.0 * sd.max(1e-9 * ma.abs()),
                "{name} aggregate {i}: AD {ma} vs FD off by {m} (sd {sd})"
            );
            if ma.abs() > 0.0 {
                best = best.max(ma.abs() / (4.0 * sd));
            }
            entries.push(Entry {
                floor: 1e-9 * ma.abs(),
                ..Entry::new(col(&diffs, i), col(&ads, i), mr.abs() + 2.0 * ser)
            });
        }
        // the strongest aggregate's derivative is at least 20 of its 4-sd bands: a 5% bias fails
        eprintln!("{file} {name}: best {best:.1} (at least 20)");
        assert!(best > 20.0, "{name}: the check cannot see a 5% bias (best {best:.1})");
        Test::default()
            .every(entries, 4.0)
            .power()
            .assert_enough(&format!("{file} {name} (16 seeds × {spp} spp)"));
    }
}

/// From 8–10 cm off in each coordinate, Adam on a smoothed transient loss recovers the
/// square's position to 1 cm, on the planar and on the curved relay wall.
#[test]
fn tracking_recovers_the_position() {
    track("nlos_tracking.toml");
}

#[test]
fn tracking_recovers_the_position_on_a_curved_wall() {
    track("nlos_tracking_curved.toml");
}

fn track(file: &str) {
    let scene = common::scene_path(file);
    // a converged target (16384 paths per sensor point), so that its noise barely moves the
    // loss's minimum
    let target = render(&Scene::load(&scene, &[]).unwrap(), &opts(16384, 1000))
        .unwrap()
        .0;
    let p = Problem {
        scene,
        fixed: vec![],
        fixed_text: Vec::new(),
        params: vec!["target_x".into(), "target_y".into(), "target_z".into()],
        target,
        loss: Loss::Smooth { sigma_bins: 2.0 },
        opts: opts(1024, 1),
        bounds: vec![(-0.6, 0.6), (-0.6, 0.6), (0.3, 1.0)],
    };
    let truth = [0.1, -0.05, 0.6];
    let start = [0.2, 0.04, 0.68];
    let steps = p.optimize(&start, 150, &[0.01, 0.01, 0.01], 0.1, |_| true).unwrap();
    let last = &steps.last().unwrap().values;
    eprintln!(
        "{file}: {start:?} → {last:?} (truth {truth:?}), loss {} → {}",
        steps[0].loss,
        steps.last().unwrap().loss
    );
    for k in 0..3 {
        assert!((last[k] - truth[k]).abs() < 0.01, "{file}: {last:?} vs truth {truth:?}");
    }
}

/// A black plate between the relay wall and a backdrop reflects nothing: the capture sees it
/// only as a silhouette against the backdrop and as the shadow it casts there, so the interior
/// derivative of its position is exactly zero and the whole gradient is the boundary term at
/// the sensor and laser points. From 6–7 cm off in each coordinate, Adam on the full gradient
/// recovers the position to 1 cm (measured: within 4 mm, `dtr optimize` 150 iterations at 1024
/// spp); with the interior alone the plate does not move.
#[test]
fn tracking_a_black_plate_needs_the_boundary_term() {
    let scene = common::scene_path("nlos_moving_plate.toml");
    let target = render(&Scene::load(&scene, &[]).unwrap(), &opts(65536, 1000))
        .unwrap()
        .0;
    let problem = |boundary: BoundaryMode| Problem {
        scene: scene.clone(),
        fixed: vec![],
        fixed_text: Vec::new(),
        params: vec!["plate_x".into(), "plate_y".into(), "plate_z".into()],
        target: target.clone(),
        loss: Loss::Smooth { sigma_bins: 2.0 },
        opts: RenderOptions {
            boundary,
            ..opts(1024, 1)
        },
        bounds: vec![(-0.6, 0.6), (-0.6, 0.6), (0.3, 1.0)],
    };
    let truth = [0.1, -0.05, 0.6];
    let start = [0.17, 0.01, 0.66];
    let steps = problem(BoundaryMode::Full)
        .optimize(&start, 150, &[0.01, 0.01, 0.01], 0.1, |_| true)
        .unwrap();
    let last = &steps.last().unwrap().values;
    eprintln!("full: {start:?} → {last:?} (truth {truth:?})");
    for k in 0..3 {
        assert!((last[k] - truth[k]).abs() < 0.01, "{last:?} vs truth {truth:?}");
    }
    let steps = problem(BoundaryMode::InteriorOnly)
        .optimize(&start, 10, &[0.01, 0.01, 0.01], 0.1, |_| true)
        .unwrap();
    let last = &steps.last().unwrap().values;
    eprintln!("interior: {start:?} → {last:?}");
    assert_eq!(
        last.as_slice(),
        start.as_slice(),
        "the interior gradient of a black plate is zero"
    );
}
