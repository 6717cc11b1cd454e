//! Optical path length below a micrometre in the secondary-edge boundary stage (issue 9,
//! part 5; Algorithm 2): a 3 nm pulse binned at 1 nm, OPLs near 4.24 m, where one f32 step is
//! 4.8·10⁻⁷ m.
//!
//! A point light at P = (−1, 0, 2) casts the shadow of a square occluder (z = 0.5, edge at
//! x = −0.25) on a floor z = 0: the edge's shadow is the line x = 0 (magnified 4/3). One pixel
//! at C = (0, 0, 2) looks straight down with a field of view so narrow that its footprint
//! [−aH, aH]² (a = tan(fov/2), H = 2) holds a 1.1 mm piece of that line, over which the OPL
//! d(y) = |P − (0, y, 0)| + |C − (0, y, 0)| spreads over 0.6 µm. Moving the occluder along x
//! moves the shadow line at v_s = 4/3, so with the pixel's mean over tan-plane coordinates
//! (u, v), the boundary derivative is the closed form
//!
//!   ∂I/∂θ (bin l) = −v_s / (4a² H) · ∫_{−a}^{a} L(0, Hv) · S_e(l, d(Hv)) dv,
//!   L(x, y) = (ρ/π) · I · 2 / r³, r² = (x + 1)² + y² + 4,
//!
//! S_e of supplemental Eq. 24. The camera sees neither the occluder nor its edges and the floor
//! radiance does not depend on θ off the line, so the secondary edges (light → occluder edge →
//! floor → camera) are the whole derivative.
//!
//! Before the boundary stage carried f64 OPLs, every boundary path of this scene landed
//! outside the 650 nm window (time-summed derivative 0 for −16.99): its d was summed in f32
//! (steps of 4.8·10⁻⁷ m) and measured to x_S found by a ray started ε ≈ 3.8·10⁻⁶ m off x_B,
//! which misses the shadow line by micrometres of OPL. Within the window the time integral of a
//! boundary path's S_e is 1 wherever its d lands (these paths carry no ḋ), so only the bin by
//! bin profile checks the OPLs themselves.

use crate::common;
use difftransient::temporal::Correlation;
use difftransient::{BoundaryMode, RenderOptions, Scene, render_diff};

const H: f64 = 2.0;
const SIGMA: f64 = 3e-9;
const BIN: f64 = 1e-9;
const FOV_DEG: f64 = 0.064;
const V_S: f64 = 4.0 / 3.0;
/// The first arrival, d(0) = √5 + 2.
fn d0() -> f64 {
    5f64.sqrt() + 2.0
}

fn scene_text() -> String {
    // 30 nm before the first arrival to 30 nm after the last (d(a) − d(0) ≈ 1.894 a²)
    let start = d0() - 30.0 * BIN;
    format!(
        r#"
[integrator]
kind = "path"
max_bounces = 1
spp = 1

[camera]
position = [0.0, 0.0, {H}]
look_at = [0.0, 0.0, 0.0]
fov = {FOV_DEG}
resolution = [1, 1]
filter = "box"

[film]
start_opl = {start:.12}
bin_width_opl = {BIN:e}
bins = 650
channels = "mono"

[[material]]
name = "grey"
type = "diffuse"
albedo = 0.5

[[shape]]
name = "floor"
type = "rectangle"
material = "grey"
scale = [0.005, 0.005, 1.0]

[[shape]]
name = "occluder"
type = "rectangle"
material = "grey"
translate = [-0.255, 0.0, 0.5]
scale = [0.005, 0.005, 1.0]

[[emitter]]
name = "lamp"
type = "point"
position = [-1.0, 0.0, 2.0]
intensity = 1.0
pulse = {{ type = "gaussian", sigma_opl = {SIGMA:e} }}

[[param]]
name = "occluder_x"
kind = "translate"
shape = "occluder"
axis = "x"
value = -0.255
"#
    )
}

fn load(text: &str) -> Scene {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("edge.toml");
    std::fs::write(&p, text).unwrap();
    Scene::load(&p, &[]).unwrap()
}

/// ∫_{−a}^{a} g(v) dv by the midpoint rule over `steps` points (g gets v and its weight).
fn over_line(steps: usize, mut g: impl FnMut(f64, f64)) {
    let a = (FOV_DEG.to_radians() * 0.5).tan();
    let dv = 2.0 * a / steps as f64;
    for i in 0..steps {
        g(-a + (i as f64 + 0.5) * dv, dv);
    }
}

/// The closed form's prefactor and integrand at tan-plane coordinate v on the shadow line:
/// (weight per unit v, OPL).
fn line_point(v: f64) -> (f64, f64) {
    let a = (FOV_DEG.to_radians() * 0.5).tan();
    let y = H * v;
    let r = (5.0 + y * y).sqrt();
    let l = 0.5 / std::f64::consts::PI * 2.0 / r.powi(3);
    (-V_S / (4.0 * a * a * H) * l, r + (H * H + y * y).sqrt())
}

/// The closed form per bin with every OPL moved by `shift` metres, and its time integral.
fn closed_form(corr: &Correlation, bins: usize, shift: f64) -> (Vec<f64>, f64) {
    let mut exact = vec![0.0f64; bins];
    let mut total = 0.0;
    over_line(200_000, |v, dv| {
        let (w, d) = line_point(v);
        total += w * dv;
        corr.for_each(d + shift, |bin, se, _| exact[bin] += w * dv * se);
    });
    (exact, total)
}

/// Bins per group of the profile check. A boundary path adds to the ~20 bins its pulse
/// (σ = 3 bins) reaches, so neighbouring bins' errors are correlated, and Σz² over single bins
/// has a spread several times the independent-entry formula's: over 6 seed bases it went from
/// 642 to 1168 (expected 896 ± 71) with independent numbers, and from 697 to 1306 with Sobol
/// points. Groups of 32 bins share paths only at their ends.
const GROUP: usize = 32;

/// Σz² over groups of `GROUP` bins (z of the runs' mean group sum against the closed form's,
/// by the runs' standard error), max |z|, and the number of groups.
fn group_z(runs: &[Vec<f32>], exact: &[f64]) -> (f64, f64, usize) {
    let (mut chi2, mut zmax, mut n) = (0.0, 0.0f64, 0);
    for g in 0..exact.len() / GROUP {
        let bins = g * GROUP..(g + 1) * GROUP;
        let est: Vec<f64> = runs
            .iter()
            .map(|r| r[bins.clone()].iter().map(|&v| v as f64).sum())
            .collect();
        let want: f64 = exact[bins].iter().sum();
        let (m, se) = common::mean_se(&est);
        // f32 film storage adds ~1e-7 relative on top of the Monte Carlo error
        let z = (m - want) / (se + 1e-6 * want.abs()).max(1e-30);
        chi2 += z * z;
        zmax = zmax.max(z.abs());
        n += 1;
    }
    (chi2, zmax, n)
}

#[test]
fn a_nanometre_pulse_over_a_shadow_edge_is_smooth_and_matches_the_closed_form() {
    let scene = load(&scene_text());
    let axis = scene.film.axis;
    let corr = Correlation::new(axis, scene.emitters[0].pulse, 0.0, scene.film.gate).unwrap();
    let (exact, exact_total) = closed_form(&corr, axis.bins, 0.0);
    let peak = exact.iter().map(|v| v.abs()).fold(0.0, f64::max);
    let kk = 8;
    let mut totals = Vec::new();
    let runs: Vec<Vec<f32>> = (0..kk)
        .map(|seed| {
            let o = RenderOptions {
                spp_boundary: Some(1 << 18),
                seed: Some(90 + seed),
                threads: Some(2),
                boundary: BoundaryMode::BoundaryOnly,
                ..Default::default()
            };
            let (_, d, stats) = render_diff(&scene, &["occluder_x".into()], &o).unwrap();
            assert!(stats.opl.f64_paths, "{:?}", stats.opl);
            totals.push(stats.deriv_energy[0].inside);
            d[0].pixel_series(0, 0)
        })
        .collect();
    // the time integral (blind to f32 OPLs, see the module doc) checks the closed form's scale
    let (m, se) = common::mean_se(&totals);
    eprintln!("time-summed ∂I/∂x = {m} ± {se} (closed form {exact_total})");
    // (the total's check: the group check below has its own power, against an OPL shift)
    common::power::Test::default()
        .one(common::power::Entry {
            scale: 4.0,
            ..common::power::Entry::new(totals.iter().map(|t| t - exact_total).collect(), totals.clone(), 0.0)
        })
        .power()
        .assert_enough("boundary_opl time-summed (8 seeds)");
    assert!(
        (m - exact_total).abs() <= 4.0 * se,
        "time-summed {m} ± {se} vs {exact_total}"
    );
    // smooth: no bin where the closed form is above 1% of its peak is empty in any run
    for (s, run) in runs.iter().enumerate() {
        let empty = (0..axis.bins)
            .filter(|&l| exact[l].abs() > 0.01 * peak && run[l] == 0.0)
            .count();
        let signal = (0..axis.bins).filter(|&l| exact[l].abs() > 0.01 * peak).count();
        assert!(
            empty == 0,
            "seed {s}: {empty} of {signal} bins inside the signal are empty"
        );
    }
    // and equal to the closed form within the standard error, 32 bins at a time
    let (chi2, zmax, n) = group_z(&runs, &exact);
    let (mean, sd) = common::t2_sum_moments(n as f64, (kk - 1) as f64);
    eprintln!("{n} groups of {GROUP} bins: Σz² = {chi2:.1} (expected {mean:.1} ± {sd:.1}), max |z| = {zmax:.2}");
    assert!(n == 20, "{n} groups");
    assert!(chi2 <= mean + 5.0 * sd, "Σz² = {chi2:.1} over {n} groups");
    assert!(zmax <= 7.0, "a group is {zmax:.1} standard errors off");
    // power: the profile with every OPL a tenth of a bin (0.1 nm) later is rejected
    let (late, _) = closed_form(&corr, axis.bins, 0.1 * BIN);
    let (chi2, zmax, _) = group_z(&runs, &late);
    eprintln!("closed form 0.1 nm late: Σz² = {chi2:.1}, max |z| = {zmax:.2}");
    assert!(
        chi2 > mean + 5.0 * sd || zmax > 7.0,
        "a 0.1 nm shift passes: Σz² = {chi2:.1}"
    );
}

#[test]
fn an_offset_opl_that_is_not_an_f32_shifts_the_peak_to_its_bin() {
    // the same scene's pulse offset τ = 1.0000000495 m (f32: 1.0): the peak of the boundary
    // derivative's first arrival, u = d(0) + τ, lands 99.5 bins after start_opl = d(0) + 0.99999995,
    // the centre of bin 99 (with τ read as an f32 it would land on the edge of bins 49 and 50)
    let text = scene_text()
        .replace(
            &format!("start_opl = {:.12}", d0() - 30.0 * BIN),
            &format!("start_opl = {:.15}", d0() + 0.99999995),
        )
        .replace("intensity = 1.0\n", "intensity = 1.0\noffset_opl = 1.0000000495\n");
    let scene = load(&text);
    let tau = scene.emitters[0].offset_opl;
    assert_eq!(tau as f64, 1.0000000495);
    // S_e as the renderer builds it (integrator::context): from the emitter's stored offset
    let corr = Correlation::new(scene.film.axis, scene.emitters[0].pulse, tau, scene.film.gate).unwrap();
    let (mut lo, mut hi, mut peak) = (0.0, 0.0, 0);
    let mut best = 0.0;
    corr.for_each(d0(), |bin, se, _| {
        if bin == 98 {
            lo = se;
        }
        if bin == 100 {
            hi = se;
        }
        if se > best {
            (best, peak) = (se, bin);
        }
    });
    // u − start = 99.5 bins: the centre of bin 99, between bins 98 and 100
    assert_eq!(peak, 99);
    // (start_opl is written to 10⁻¹⁵ m, ~10⁻⁶ bins: the two differ by ~10⁻⁶ relative)
    assert!((lo - hi).abs() <= 1e-5 * lo && lo > 0.1, "{lo} {hi}");
}
