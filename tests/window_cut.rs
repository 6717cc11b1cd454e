//! The window cut (`integrator::window`): paths end once their optical path length can no
//! longer reach a bin. The transient and every derivative film are the same bytes as with
//! the cut off (`SteadyMode::Full`), for any seed, while fewer rays are traced; the steady
//! image then integrates the window (the time sum of the transient).

use crate::common;
use difftransient::film::SteadyMode;
use difftransient::integrator::bdpt;
use difftransient::render::{Lanes, RenderStats};
use difftransient::scene::IntegratorKind;
use difftransient::{RenderOptions, Scene, Transient, render, render_diff};

fn opts(seed: u64, spp: u32, steady: SteadyMode) -> RenderOptions {
    RenderOptions {
        spp: Some(spp),
        seed: Some(seed),
        threads: Some(2),
        steady,
        ..Default::default()
    }
}

fn rays(s: &RenderStats) -> u64 {
    s.intersect_rays + s.occluded_rays
}

/// The Cornell box at 16×16 with a window that ends early: 40 bins of 0.06 m from 3.6 m
/// (light arrives from 3.78 m; the steady image needs paths to about 30 m).
fn early_cornell() -> Scene {
    let mut s = common::load("cornell_box.toml");
    s.film.width = 16;
    s.film.height = 16;
    s.film.axis.bins = 40;
    s
}

fn assert_same_bytes(what: &str, a: &Transient, b: &Transient) {
    let differ = a
        .data
        .iter()
        .zip(&b.data)
        .filter(|(x, y)| x.to_bits() != y.to_bits())
        .count();
    assert_eq!(
        differ,
        0,
        "{what}: {differ} of {} bins differ with the cut",
        a.data.len()
    );
    assert!(a.data.iter().any(|&v| v != 0.0), "{what}: nothing rendered");
}

/// Renders with and without the cut; asserts equal transients and fewer rays with it.
fn check_forward(what: &str, scene: &Scene, o: RenderOptions) -> (RenderStats, RenderStats) {
    for seed in [1, 2, 3] {
        let cut = RenderOptions {
            seed: Some(seed),
            ..o.clone()
        };
        let full = RenderOptions {
            steady: SteadyMode::Full,
            ..cut.clone()
        };
        let (a, sa) = render(scene, &cut).unwrap();
        let (b, sb) = render(scene, &full).unwrap();
        assert_same_bytes(&format!("{what}, seed {seed}"), &a, &b);
        assert!(
            rays(&sa) < rays(&sb),
            "{what}: the cut traced {} rays, the full render {}",
            rays(&sa),
            rays(&sb)
        );
        if seed == 3 {
            return (sa, sb);
        }
    }
    unreachable!()
}

#[test]
fn the_path_tracer_gives_the_same_transient_with_fewer_rays() {
    let scene = early_cornell();
    let (cut, full) = check_forward("path, 8 lanes", &scene, opts(1, 8, SteadyMode::Window));
    assert_eq!(cut.steady, SteadyMode::Window);
    assert!(cut.opl_cut.is_some() && full.opl_cut.is_none());
    // this window ends 3 m after the first light: most of each path's bounces are cut
    assert!(
        (rays(&cut) as f64) < 0.75 * rays(&full) as f64,
        "{} vs {}",
        rays(&cut),
        rays(&full)
    );
    let scalar = RenderOptions {
        lanes: Lanes::Scalar,
        ..opts(1, 2, SteadyMode::Window)
    };
    check_forward("path, scalar", &scene, scalar);
}

#[test]
fn bdpt_gives_the_same_transient_with_fewer_rays() {
    let mut scene = early_cornell();
    scene.integrator.max_bounces = 5;
    let o = RenderOptions {
        integrator: Some(IntegratorKind::Bdpt),
        ..opts(1, 4, SteadyMode::Window)
    };
    check_forward("bdpt", &scene, o);
}

#[test]
fn a_laser_a_gaussian_pulse_and_an_unwarped_film_keep_their_transients() {
    // laser_room: the laser-to-spot leg counts in the OPL; Gaussian pulse (reach 8σ); light
    // arrives from 9.5 m, and the window is cut to [2, 10.5] m
    let mut laser = common::load("laser_room.toml");
    laser.film.axis.bins = 85;
    check_forward("laser, Gaussian pulse", &laser, opts(1, 4, SteadyMode::Window));
    // gated_laser_room: paths end where the spot, plus the beam's leg, is out of reach
    let gated = common::load("gated_laser_room.toml");
    check_forward("gated laser", &gated, opts(1, 4, SteadyMode::Window));
    let mut unwarped = early_cornell();
    unwarped.film.unwarp = true;
    unwarped.film.axis.start_opl = 0.0;
    check_forward("unwarped", &unwarped, opts(1, 4, SteadyMode::Window));
}

/// An NLOS capture that counts its relay legs: each connection adds the sensor point's leg to
/// the SPAD and the laser's leg to its spot, so a vertex is ended where, with both legs, no
/// spot is within reach. On a window that ends soon after the hidden box's first returns
/// ([6.0, 6.8] m with both legs, 8 bounces): the same bytes, and at most 0.9× the bounce rays
/// of the uncut render (0.83× at seed 3; with neither leg in the bound, or the laser's alone,
/// the cut saved under 1 %).
#[test]
fn a_capture_that_counts_its_relay_legs_ends_paths_with_both_legs_in_the_bound() {
    let mut scene = common::load("nlos_occluder.toml");
    scene.nlos.as_mut().unwrap().relay_legs = difftransient::scene::RelayLegs::Included;
    (scene.film.axis.start_opl, scene.film.axis.bins) = (6.0, 40);
    scene.integrator.max_bounces = 8;
    let (cut, full) = check_forward("legs included", &scene, opts(1, 16, SteadyMode::Window));
    assert!(
        (cut.intersect_rays as f64) <= 0.9 * full.intersect_rays as f64,
        "bounce rays: {} with the cut, {} without",
        cut.intersect_rays,
        full.intersect_rays
    );
}

/// BDPT on a capture: a light subpath ends at a sensor point, not at the SPAD, so its cut
/// measures the distance to the sensor points' box (plus the wall's leg to the SPAD where it
/// counts); measured to the SPAD, it would end light subpaths that can still reach a sensor
/// point within the window, and the bytes would differ. Both legs left out and counted.
#[test]
fn bdpt_on_a_capture_ends_light_subpaths_by_their_distance_to_the_sensor_points() {
    let mut scene = common::load("nlos_occluder.toml");
    (scene.film.axis.start_opl, scene.film.axis.bins) = (1.0, 100);
    scene.integrator.max_bounces = 6;
    let bdpt = RenderOptions {
        integrator: Some(IntegratorKind::Bdpt),
        ..opts(1, 64, SteadyMode::Window)
    };
    // (with the SPAD's point as the light subpaths' end, bytes differed at this count)
    check_forward("bdpt capture", &scene, bdpt.clone());
    scene.nlos.as_mut().unwrap().relay_legs = difftransient::scene::RelayLegs::Included;
    (scene.film.axis.start_opl, scene.film.axis.bins) = (6.0, 40);
    check_forward("bdpt capture, legs included", &scene, bdpt.clone());
    let mut exhaustive = common::load("nlos_occluder_exhaustive.toml");
    (exhaustive.film.axis.start_opl, exhaustive.film.axis.bins) = (1.0, 100);
    exhaustive.integrator.max_bounces = 6;
    check_forward("bdpt exhaustive capture", &exhaustive, bdpt);
}

#[test]
fn derivative_films_interior_and_boundary_are_the_same_bytes() {
    // the pyramid of contact_wall slides (contact edges; floor and wall keep paths bouncing),
    // 4 bounces, a window of [3, 4] m
    let mut scene = common::load("contact_wall.toml");
    scene.integrator.max_bounces = 4;
    scene.film.axis.bins = 20;
    check_derivatives(&scene, &["pyramid_z"]);
    // a pose parameter: interior (Algorithm 1) + primary + secondary boundary films
    let mut scene = common::load("shadow_hidden_occluder.toml");
    scene.film.width = 16;
    scene.film.height = 16;
    // [4, 4.3] m: 2-bounce paths reach 6 m, so the cut ends many of them
    scene.film.axis.bins = 3;
    check_derivatives(&scene, &["occluder_x", "light_x"]);
    // a window ending before most secondary-edge paths land ([3.6, 5.4] m): the secondary
    // pass's pilot, which splits its budget between the two strategies, must see the same
    // paths with and without the cut (before, it ran cut in one mode and uncut in the other,
    // split the budget differently and drew other samples)
    let mut scene = common::load("narrow_pulse_box.toml");
    scene.film.axis.bins = 30;
    check_derivatives(&scene, &["tall_box_x"]);
}

fn check_derivatives(scene: &Scene, params: &[&str]) {
    let params: Vec<String> = params.iter().map(|p| p.to_string()).collect();
    for seed in [1, 2] {
        let o = opts(seed, 4, SteadyMode::Window);
        let full = RenderOptions {
            steady: SteadyMode::Full,
            ..o.clone()
        };
        let (p, d, sa) = render_diff(scene, &params, &o).unwrap();
        let (q, e, sb) = render_diff(scene, &params, &full).unwrap();
        // a cut render's derivative energy integrates the window alone and says so (before,
        // the window-energy pilot left the context uncut and the report read it as full:
        // `outside` a number and the total from the cut steady images)
        for (k, (x, y)) in sa.deriv_energy.iter().zip(&sb.deriv_energy).enumerate() {
            assert_eq!(x.outside, None, "d/d{}: {x:?}", params[k]);
            assert_eq!(x.total, x.inside, "d/d{}: {x:?}", params[k]);
            assert!(y.outside.is_some(), "d/d{}: {y:?}", params[k]);
        }
        assert_same_bytes("primal", &p, &q);
        for (k, (x, y)) in d.iter().zip(&e).enumerate() {
            assert_same_bytes(&format!("d/d{}", params[k]), x, y);
        }
        assert!(
            sa.intersect_rays < sb.intersect_rays,
            "{} vs {}",
            sa.intersect_rays,
            sb.intersect_rays
        );
        // the secondary-edge subpaths are cut too (they skip what lands past the window)
        let sec = |s: &RenderStats| s.boundary.as_ref().unwrap().secondary.rays;
        assert!(sec(&sa) < sec(&sb), "secondary-edge rays: {} vs {}", sec(&sa), sec(&sb));
    }
}

#[test]
fn the_steady_image_integrates_the_window_or_all_time() {
    let scene = early_cornell();
    let (cut, _) = render(&scene, &opts(4, 8, SteadyMode::Window)).unwrap();
    let (full, _) = render(&scene, &opts(4, 8, SteadyMode::Full)).unwrap();
    let c = cut.channels;
    let (mut in_window, mut all_time) = (0.0, 0.0);
    for y in 0..cut.height {
        for x in 0..cut.width {
            for ch in 0..c {
                let sum = cut.time_sum(x, y, ch) as f64;
                let steady = cut.steady[(y * cut.width + x) * c + ch] as f64;
                // the same Σ, once over f32 bins, once in f64 as the paths were added
                assert!(
                    (sum - steady).abs() <= 1e-5 * steady.max(1e-6),
                    "({x}, {y}, {ch}): {sum} vs {steady}"
                );
                in_window += steady;
                all_time += full.steady[(y * cut.width + x) * c + ch] as f64;
            }
        }
    }
    // the window ends early: the full image holds more light than the window (1.4× here)
    assert!(all_time > 1.2 * in_window, "{all_time} vs {in_window}");
}

#[test]
fn the_energy_after_a_cut_window_is_estimated_by_the_pilot() {
    // the pilot's estimate of the energy after the window agrees with the uncut render's
    // measurement within their noise (four uncut pilot passes over the 256 pixels, for the
    // pilot's least of 1024 paths, against 8 spp)
    let scene = early_cornell();
    let (mut pilot, mut exact, mut totals, mut reported) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for seed in 1..=8 {
        let (_, a) = render(&scene, &opts(seed, 8, SteadyMode::Window)).unwrap();
        let (_, b) = render(&scene, &opts(seed + 100, 8, SteadyMode::Full)).unwrap();
        assert_eq!(a.energy.after_pilot_paths, 1024);
        assert_eq!(b.energy.after_pilot_paths, 0);
        assert_eq!(b.energy.after_standard_error, None);
        reported.push(a.energy.after_standard_error.unwrap());
        let t = a.energy.before + a.energy.inside + a.energy.after;
        assert!((a.energy.total - t).abs() <= 1e-12 * t);
        pilot.push(a.energy.after);
        totals.push(b.energy.total);
        exact.push(b.energy.after);
    }
    let (mp, sp) = common::mean_se(&pilot);
    let (me, se) = common::mean_se(&exact);
    let z = (mp - me) / (sp * sp + se * se).sqrt();
    assert!(z.abs() < 4.0, "pilot {mp} ± {sp}, uncut {me} ± {se}: z = {z}");
    // the standard error each render reports is the spread of the pilot's estimate from seed
    // to seed
    assert_reported_error_is_the_spread(&pilot, &reported, 0.6..=1.6);
    // and it is a good part of the light (about 30%): this window ends 2.2 m after the first
    // arrival
    let (mt, _) = common::mean_se(&totals);
    assert!(mp > 0.2 * mt, "after {mp} of {mt}");
}

/// On a film larger than the pilot covers (the Cornell box at 64 × 64: a pass of 512 paths
/// for 4096 pixels) the pilot's estimate is still unbiased and its standard error honest.
/// Until 2026-11-30 it took every 8th tile, here one column of tiles along the left wall:
/// 152 against 403 for this window (reported standard error 9).
#[test]
fn the_pilot_of_a_film_it_does_not_cover_is_unbiased() {
    let mut scene = common::load("cornell_box.toml");
    scene.film.axis.bins = 50;
    let (_, full) = render(&scene, &opts(99, 64, SteadyMode::Full)).unwrap();
    let exact = full.energy.after;
    let (mut pilot, mut reported) = (Vec::new(), Vec::new());
    for seed in 1..=8 {
        let (_, a) = render(&scene, &opts(seed, 4, SteadyMode::Window)).unwrap();
        assert_eq!(a.energy.after_pilot_paths, 1024);
        pilot.push(a.energy.after);
        reported.push(a.energy.after_standard_error.unwrap());
    }
    let (mp, sp) = common::mean_se(&pilot);
    // the uncut render's own noise, at 64 spp, is far below the pilot's
    let z = (mp - exact) / sp;
    assert!(z.abs() < 4.0, "pilot {mp} ± {sp} against {exact}: z = {z}");
    assert_reported_error_is_the_spread(&pilot, &reported, 0.5..=2.0);
}

/// An exhaustive NLOS scan of 4 × 4 sensor points (one pilot path per pixel is 16) still has
/// its pilot of 1024 paths, in passes whose spread gives an honest standard error. Until
/// 2026-11-30 it sent 2 × 16 paths: 0.031 ± 0.013 and 0.065 ± 0.004 where the energy after the
/// window is 0.083 (Σz² ≈ 50 over 6 seeds; found by an independent sweep).
#[test]
fn the_pilot_of_a_small_film_sends_its_paths_in_more_passes() {
    let mut scene = common::load("nlos_occluder_exhaustive.toml");
    scene.film.axis.bins = 40;
    let (mut exact, mut pilot, mut reported) = (Vec::new(), Vec::new(), Vec::new());
    for seed in 1..=8 {
        let (_, full) = render(&scene, &opts(100 + seed, 16, SteadyMode::Full)).unwrap();
        exact.push(full.energy.after);
        let (_, a) = render(&scene, &opts(seed, 8, SteadyMode::Window)).unwrap();
        assert_eq!(a.energy.after_pilot_paths, 1024);
        pilot.push(a.energy.after);
        reported.push(a.energy.after_standard_error.unwrap());
    }
    let (mp, sp) = common::mean_se(&pilot);
    let (me, se) = common::mean_se(&exact);
    let z = (mp - me) / (sp * sp + se * se).sqrt();
    assert!(z.abs() < 4.0, "pilot {mp} ± {sp}, uncut {me} ± {se}: z = {z}");
    assert_reported_error_is_the_spread(&pilot, &reported, 0.5..=2.0);
}

/// Asserts that the mean standard error the renders reported for the energy after the window
/// is within `share` of the spread of their estimates (`pilot`) from seed to seed.
fn assert_reported_error_is_the_spread(pilot: &[f64], reported: &[f64], share: std::ops::RangeInclusive<f64>) {
    let (_, sp) = common::mean_se(pilot);
    let spread = sp * (pilot.len() as f64).sqrt();
    let (said, _) = common::mean_se(reported);
    eprintln!("pilot spread over seeds {spread}, reported standard error {said} (mean)");
    assert!(
        (share.start() * spread..=share.end() * spread).contains(&said),
        "reported {said} against a spread of {spread}"
    );
}

#[test]
fn per_strategy_bdpt_films_are_unchanged() {
    let mut scene = early_cornell();
    scene.integrator.max_bounces = 3;
    let o = RenderOptions {
        integrator: Some(IntegratorKind::Bdpt),
        ..opts(2, 2, SteadyMode::Window)
    };
    let full = RenderOptions {
        steady: SteadyMode::Full,
        ..o.clone()
    };
    let (_, a, _) = difftransient::render::render_strategies(&scene, &o).unwrap();
    let (_, b, _) = difftransient::render::render_strategies(&scene, &full).unwrap();
    assert_eq!(a.len(), bdpt::film::strategy_list(3).len());
    for ((st, x), (_, y)) in a.iter().zip(&b) {
        let differ = x
            .data
            .iter()
            .zip(&y.data)
            .filter(|(p, q)| p.to_bits() != q.to_bits())
            .count();
        assert_eq!(differ, 0, "strategy {st:?}");
    }
}
