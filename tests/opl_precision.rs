//! Optical path length below a micrometre (issue 9, part 5): a 3 nm pulse (the paper's
//! 0.01 fs) binned at 1 nm, 4 m from the camera, where one f32 step is 4.8·10⁻⁷ m.
//!
//! The scene is confocal_plane.toml's (a diffuse plane z = 0 lit by a point light at the
//! camera, h = 2 m above it, one bounce), seen through one pixel with a field of view so
//! narrow that the OPL 2r over the pixel spreads over 0.2 µm: a continuous spread of about
//! 200 bins whose profile is known in closed form. The plane is 2 cm wide, so that Embree's
//! f32 barycentrics place hit points to ~10⁻⁹ m.

mod common;
use difftransient::scene::IntegratorKind;
use difftransient::temporal::Correlation;
use difftransient::{BoundaryMode, RenderOptions, Scene, render, render_diff};

const H: f64 = 2.0;
const SIGMA: f64 = 3e-9;
const BIN: f64 = 1e-9;
/// tan of half the field of view: the pixel spans tan-plane coordinates [−A, A]².
const FOV_DEG: f64 = 0.0256;

fn scene_text(start: &str, bins: usize, filter: &str) -> String {
    format!(
        r#"
[integrator]
kind = "path"
max_bounces = 1
spp = 16

[camera]
position = [0.0, 0.0, 2.0]
look_at = [0.0, 0.0, 0.0]
fov = {FOV_DEG}
resolution = [1, 1]
filter = {filter}

[film]
start_opl = {start}
bin_width_opl = {BIN:e}
bins = {bins}
channels = "mono"

[[material]]
name = "grey"
type = "diffuse"
albedo = 0.5

[[shape]]
name = "plane"
type = "rectangle"
material = "grey"
scale = [0.01, 0.01, 1.0]

[[emitter]]
name = "lamp"
type = "point"
position = [0.0, 0.0, 2.0]
intensity = 1.0
pulse = {{ type = "gaussian", sigma_opl = {SIGMA:e} }}

[[param]]
name = "plane_z"
kind = "translate"
shape = "plane"
axis = "z"
value = 0.0
"#
    )
}

fn load(text: &str) -> Scene {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("nano.toml");
    std::fs::write(&p, text).unwrap();
    Scene::load(&p, &[]).unwrap()
}

fn opts(spp: u32, seed: u64) -> RenderOptions {
    RenderOptions {
        spp: Some(spp),
        seed: Some(seed),
        threads: Some(2),
        ..Default::default()
    }
}

/// k = ρ·I/π: the radiance at tan-plane radius² s is k / (h² (1 + s)^{3/2}) and its OPL
/// 2h·√(1 + s).
fn k() -> f64 {
    0.5 / std::f64::consts::PI
}

/// ∫ over the pixel (uniform in tan-plane coordinates on [−A, A]²) of g(s), by the midpoint
/// rule in s = ρ²: the circle of radius ρ meets the square in an arc of length 2πρ (ρ ≤ A)
/// or 2πρ − 8ρ·acos(A/ρ), and arc·dρ = arc/(2ρ)·ds.
fn over_pixel(steps: usize, mut g: impl FnMut(f64, f64)) {
    let a = (FOV_DEG.to_radians() * 0.5).tan();
    let smax = 2.0 * a * a;
    let ds = smax / steps as f64;
    for i in 0..steps {
        let s = (i as f64 + 0.5) * ds;
        let arc = if s <= a * a {
            std::f64::consts::PI
        } else {
            std::f64::consts::PI - 4.0 * (a / s.sqrt()).acos()
        };
        g(s, arc * ds / (4.0 * a * a));
    }
}

#[test]
fn a_nanometre_pulse_over_a_continuous_spread_is_smooth_and_matches_the_closed_form() {
    smooth_and_closed_form(IntegratorKind::Path);
}

/// The same with BDPT: camera subpaths, light subpaths and the light-tracing splats all carry
/// f64 OPLs.
#[test]
fn bdpt_a_nanometre_pulse_over_a_continuous_spread_is_smooth_and_matches_the_closed_form() {
    smooth_and_closed_form(IntegratorKind::Bdpt);
}

fn smooth_and_closed_form(kind: IntegratorKind) {
    // from 30 nm before the first arrival (2h = 4 m) to 30 nm after the last (4 m + 0.2 µm)
    let scene = load(&scene_text("3.99999997", 260, "\"box\""));
    let axis = scene.film.axis;
    let corr = Correlation::new(axis, scene.emitters[0].pulse, 0.0, scene.film.gate).unwrap();
    let mut exact = vec![0.0f64; axis.bins];
    over_pixel(200_000, |s, w| {
        let l = k() / (H * H * (1.0 + s).powf(1.5));
        corr.for_each(2.0 * H * (1.0 + s).sqrt(), |bin, se, _| exact[bin] += w * l * se);
    });
    let peak = exact.iter().cloned().fold(0.0, f64::max);
    let kk = 8;
    let runs: Vec<Vec<f32>> = (0..kk)
        .map(|seed| {
            let o = RenderOptions {
                integrator: Some(kind),
                ..opts(4096, 40 + seed)
            };
            let (t, stats) = render(&scene, &o).unwrap();
            assert!(stats.opl.f64_paths, "{:?}", stats.opl);
            t.pixel_series(0, 0)
        })
        .collect();
    // smooth: no bin where the closed form is above 1% of its peak is empty in any run
    for (s, run) in runs.iter().enumerate() {
        let empty: Vec<usize> = (0..axis.bins)
            .filter(|&l| exact[l] > 0.01 * peak && run[l] == 0.0)
            .collect();
        assert!(empty.is_empty(), "seed {s}: empty bins {empty:?} inside the signal");
    }
    // and equal to the closed form within the standard error, bin by bin
    let (mut chi2, mut n, mut zmax) = (0.0, 0usize, 0.0f64);
    for l in 0..axis.bins {
        let est: Vec<f64> = runs.iter().map(|r| r[l] as f64).collect();
        let (m, se) = common::mean_se(&est);
        if exact[l] < 1e-3 * peak && m == 0.0 {
            continue;
        }
        // f32 film storage adds ~1e-7 relative on top of the Monte Carlo error
        let z = (m - exact[l]) / (se + 1e-6 * exact[l]).max(1e-30);
        chi2 += z * z;
        zmax = zmax.max(z.abs());
        n += 1;
    }
    let (mean, sd) = common::t2_sum_moments(n as f64, (kk - 1) as f64);
    eprintln!("{kind:?}: {n} bins: Σz² = {chi2:.1} (expected {mean:.1} ± {sd:.1}), max |z| = {zmax:.2}");
    assert!(n > 150, "only {n} bins carry signal");
    assert!(chi2 <= mean + 5.0 * sd, "Σz² = {chi2:.1} over {n} bins");
    assert!(zmax <= 7.0, "a bin is {zmax:.1} standard errors off");
}

#[test]
fn a_start_opl_that_is_not_an_f32_lands_the_peak_in_its_bin() {
    // 3.9999999505 is 49.5 bins of 1 nm before the arrival at exactly 2h = 4 m; as an f32
    // it would read 4.0 and put the peak at bin 0. A needle filter sends every sample through
    // the pixel centre, where the OPL is 2h.
    let scene = load(&scene_text("3.9999999505", 100, "{ type = \"tent\", radius = 1e-3 }"));
    assert_eq!(scene.film.axis.start_opl, 3.9999999505);
    assert_eq!(scene.film.axis.bin_width_opl, 1e-9);
    let (t, _) = render(&scene, &opts(16, 1)).unwrap();
    let series = t.pixel_series(0, 0);
    let peak = (0..series.len())
        .max_by(|&a, &b| series[a].total_cmp(&series[b]))
        .unwrap();
    assert_eq!(peak, 49, "{series:?}");
    // symmetric about the centre of bin 49
    for j in 1..10 {
        let (a, b) = (series[49 - j] as f64, series[49 + j] as f64);
        assert!(
            (a - b).abs() <= 1e-3 * series[49] as f64,
            "bins {} and {}: {a} vs {b}",
            49 - j,
            49 + j
        );
    }
}

#[test]
fn a_nanometre_pulse_time_summed_derivative_matches_the_closed_form() {
    let scene = load(&scene_text("3.99999997", 260, "\"box\""));
    // ∂/∂z of the plane height: h' = h − z, L = k / (h'² (1 + s)^{3/2}), so
    // ∂L/∂z = 2k / (h'³ (1 + s)^{3/2}) (0.0398 at the pixel); no edge or shadow is in view,
    // so the interior estimator is the whole derivative
    let mut exact = 0.0;
    over_pixel(10_000, |s, w| {
        exact += w * 2.0 * k() / (H.powi(3) * (1.0 + s).powf(1.5))
    });
    let o = RenderOptions {
        boundary: BoundaryMode::InteriorOnly,
        ..opts(4096, 0)
    };
    let (mut sums, mut stored) = (Vec::new(), Vec::new());
    let mut storage = 0.0f64;
    for seed in 0..8 {
        let o = RenderOptions {
            seed: Some(70 + seed),
            ..o.clone()
        };
        let (_, d, stats) = render_diff(&scene, &["plane_z".into()], &o).unwrap();
        // the time integral as the tiles summed it in f64 (the run JSON's energy record)
        sums.push(stats.deriv_energy[0].inside);
        let series = d[0].pixel_series(0, 0);
        stored.push(series.iter().map(|&v| v as f64).sum::<f64>());
        // each f32 bin of the written film is rounded by at most half an ulp; its ±lobes are
        // ~10⁷ times the answer, so Σ of the f32 bins cannot be closer than that
        storage = storage.max(series.iter().map(|&v| v.abs() as f64).sum::<f64>() * 2f64.powi(-24));
    }
    let (m, se) = common::mean_se(&sums);
    // the kernel's f32 arithmetic: a few f32 ulps of the answer
    let tol = 3.0 * se + 8.0 * f32::EPSILON as f64 * exact;
    eprintln!("time-summed ∂I/∂z = {m} ± {se} (exact {exact}, tol {tol}); f32 bins: {stored:?} (±{storage})");
    assert!(
        (m - exact).abs() <= tol,
        "time-summed ∂I/∂z = {m} ± {se}, exact {exact} (tol {tol})"
    );
    for s in stored {
        assert!(
            (s - exact).abs() <= storage + tol,
            "Σ of the f32 bins {s} vs {exact} (storage ±{storage})"
        );
    }
}
