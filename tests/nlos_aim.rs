//! NLOS paths aimed at the hidden shapes (`[nlos] hidden_sampling`, `hidden_shapes`;
//! src/integrator/nlos_aim.rs) on scenes/nlos_occluder.toml: a 30 cm box behind an occluding
//! panel, seen through a 2 m relay wall, 3 bounces.
//!
//! - The capture's mean is the same with and without aiming, and with aiming at the box
//!   alone (two-sample z over seeds, on the per-bin totals in groups of 4 bins and on the
//!   time-summed image in 4 × 4 sensor blocks), while its variance falls several times.
//! - The closed-form check of the aimed estimator is tests/nlos_forward.rs
//!   (`confocal_patch_matches_closed_form`, at several shares of aimed paths).
//! - Bad `hidden_sampling` and `hidden_shapes` values are refused, naming the field.

use crate::common;

use difftransient::scene::Format;
use difftransient::{RenderOptions, Scene, Transient, render};

const SEEDS: u64 = 12;

fn occluder(probability: Option<f32>, box_only: bool) -> Scene {
    let mut s = common::load("nlos_occluder.toml");
    let n = s.nlos.as_mut().unwrap();
    if let Some(p) = probability {
        n.hidden.probability = p;
    }
    if box_only {
        let hidden = s.shapes.iter().position(|x| x.name == "hidden").unwrap() as u32;
        s.nlos.as_mut().unwrap().hidden.shapes = vec![hidden];
    }
    s
}

fn runs(scene: &Scene, spp: u32) -> Vec<Transient> {
    (0..SEEDS)
        .map(|seed| {
            let opts = RenderOptions {
                spp: Some(spp),
                seed: Some(1000 + seed),
                threads: Some(2),
                ..Default::default()
            };
            render(scene, &opts).unwrap().0
        })
        .collect()
}

/// Per-bin totals in groups of 4 bins, then the time-summed image in 4 × 4 sensor blocks.
fn aggregates(t: &Transient) -> Vec<f64> {
    let mut v: Vec<f64> = t
        .bin_totals()
        .chunks(4)
        .map(|c| c.iter().map(|&x| x as f64).sum())
        .collect();
    for by in 0..t.height / 4 {
        for bx in 0..t.width / 4 {
            let mut s = 0.0;
            for y in 4 * by..4 * by + 4 {
                for x in 4 * bx..4 * bx + 4 {
                    s += t.time_sum(x, y, 0) as f64;
                }
            }
            v.push(s);
        }
    }
    v
}

/// Σ over bins of the per-bin total's variance over seeds.
fn bin_variance(runs: &[Transient]) -> f64 {
    let totals: Vec<Vec<f32>> = runs.iter().map(|t| t.bin_totals()).collect();
    (0..totals[0].len())
        .map(|b| {
            let col: Vec<f64> = totals.iter().map(|r| r[b] as f64).collect();
            let (_, se) = common::mean_se(&col);
            se * se * col.len() as f64
        })
        .sum()
}

fn agree(what: &str, a: &[Transient], b: &[Transient]) {
    let aa: Vec<Vec<f64>> = a.iter().map(aggregates).collect();
    let bb: Vec<Vec<f64>> = b.iter().map(aggregates).collect();
    let (chi2, zmax, n) = common::two_sample_z(&aa, &bb);
    // each z is a difference of two t-like means over 12 seeds: E[z²] ≈ ν/(ν − 2) per entry
    let (mean, sd) = common::t2_sum_moments(n as f64, (SEEDS - 1) as f64);
    eprintln!("{what}: Σz² = {chi2:.1} (expect {mean:.1} ± {sd:.1}) over {n}, max |z| {zmax:.2}");
    assert!(n >= 40, "{what}: only {n} aggregates carry light");
    assert!(
        chi2 <= mean + 5.0 * sd,
        "{what}: the means differ: Σz² = {chi2:.1} over {n}"
    );
    assert!(zmax <= 6.0, "{what}: an aggregate is {zmax:.1} standard errors off");
}

#[test]
fn aiming_keeps_the_capture_and_cuts_its_variance() {
    let cosine = runs(&occluder(Some(0.0), false), 64);
    let aimed = runs(&occluder(None, false), 64);
    let at_box = runs(&occluder(Some(0.5), true), 64);
    agree("aimed (default) against cosine sampling", &aimed, &cosine);
    agree("aimed at the box alone against cosine sampling", &at_box, &cosine);
    // the same paths per sensor point each
    let (vc, va, vb) = (bin_variance(&cosine), bin_variance(&aimed), bin_variance(&at_box));
    eprintln!(
        "per-bin variance: cosine {vc:.3e}, aimed {va:.3e} ({:.1}×), at the box {vb:.3e} ({:.1}×)",
        vc / va,
        vc / vb
    );
    assert!(
        vc > 4.0 * va,
        "aiming at every shape but the wall: variance {va:.3e} against cosine {vc:.3e}"
    );
    assert!(
        vc > 4.0 * vb,
        "aiming at the box: variance {vb:.3e} against cosine {vc:.3e}"
    );
}

fn load_edited(from: &str, to: &str) -> Result<Scene, String> {
    let path = common::scene_path("nlos_occluder.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains(from), "the scene text has {from:?}");
    Scene::from_str(&text.replacen(from, to, 1), Format::Toml, &path, &[]).map_err(|e| e.to_string())
}

#[test]
fn bad_aiming_fields_are_refused() {
    let at = "grid = [16, 16]\n";
    for (set, says) in [
        ("hidden_sampling = 1.0", "[0, 1)"),
        ("hidden_sampling = -0.25", "[0, 1)"),
        ("hidden_sampling = nan", "finite"),
        ("hidden_shapes = [\"hiden\"]", "no shape named \"hiden\""),
        ("hidden_shapes = [\"wall\"]", "is the relay wall"),
    ] {
        let err = load_edited(at, &format!("{at}{set}\n")).expect_err(set);
        assert!(err.contains("nlos"), "{set}: the error names the table: {err}");
        assert!(
            err.contains(set.split(' ').next().unwrap()),
            "{set}: the error names the field: {err}"
        );
        assert!(err.contains(says), "{set}: {err}");
        assert!(
            err.contains("nlos_occluder.toml"),
            "{set}: the error names the file: {err}"
        );
    }
    // 0 turns aiming off, and the default aims half of the paths at every shape but the wall
    let off = load_edited(at, &format!("{at}hidden_sampling = 0\n")).unwrap();
    assert_eq!(off.nlos.as_ref().unwrap().hidden.probability, 0.0);
    let default = common::load("nlos_occluder.toml");
    let h = &default.nlos.as_ref().unwrap().hidden;
    assert_eq!(h.probability, 0.5);
    let names: Vec<&str> = h
        .shapes
        .iter()
        .map(|&s| default.shapes[s as usize].name.as_str())
        .collect();
    assert_eq!(names, ["occluder", "hidden"]);
}
