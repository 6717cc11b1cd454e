//! Optical path length below a micrometre (issue 9, part 5): a 3 nm pulse (the paper's
//! 0.01 fs) binned at 1 nm, 4 m from the camera, where one f32 step is 4.8·10⁻⁷ m.
//!
//! The scene is confocal_plane.toml's (a diffuse plane z = 0 lit by a point light at the
//! camera, h = 2 m above it, one bounce), seen through one pixel with a field of view so
//! narrow that the OPL 2r over the pixel spreads over 0.2 µm: a continuous spread of about
//! 200 bins whose profile is known in closed form. The plane is 2 cm wide, so that Embree's
//! f32 barycentrics place hit points to ~10⁻⁹ m.

use crate::common;
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
    // the closed form with the OPL shifted by `shift` metres
    let closed_form = |shift: f64| {
        let mut exact = vec![0.0f64; axis.bins];
        over_pixel(200_000, |s, w| {
            let l = k() / (H * H * (1.0 + s).powf(1.5));
            corr.for_each(2.0 * H * (1.0 + s).sqrt() + shift, |bin, se, _| {
                exact[bin] += w * l * se
            });
        });
        exact
    };
    let exact = closed_form(0.0);
    let peak = exact.iter().cloned().fold(0.0, f64::max);
    let base = SEED_BASE;
    let runs: Vec<Vec<f64>> = (base..base + RUNS as u64)
        .map(|seed| {
            let o = RenderOptions {
                integrator: Some(kind),
                ..common::options(4096, seed)
            };
            let (t, stats) = render(&scene, &o).unwrap();
            assert!(stats.opl.f64_paths, "{:?}", stats.opl);
            t.pixel_series(0, 0).iter().map(|&v| v as f64).collect()
        })
        .collect();
    // smooth: no bin where the closed form is above 1% of its peak is empty in any run
    for (s, run) in runs.iter().enumerate() {
        let empty: Vec<usize> = (0..axis.bins)
            .filter(|&l| exact[l] > 0.01 * peak && run[l] == 0.0)
            .collect();
        assert!(empty.is_empty(), "run {s}: empty bins {empty:?} inside the signal");
    }
    // the bins that carry signal: the closed form above 10⁻³ of the peak, or any run non-zero
    let signal: Vec<usize> = (0..axis.bins)
        .filter(|&l| exact[l] >= 1e-3 * peak || runs.iter().any(|r| r[l] != 0.0))
        .collect();
    assert!(signal.len() > 150, "only {} bins carry signal", signal.len());
    // the far tail: past the peak and below 10⁻⁴ of it
    let argmax = (0..axis.bins).max_by(|&a, &b| exact[a].total_cmp(&exact[b])).unwrap();
    let tail = signal
        .iter()
        .position(|&l| l > argmax && exact[l] < 1e-4 * peak)
        .unwrap_or(signal.len());
    let v = Verdict::new(&runs, &exact, &signal, tail);
    eprintln!("{kind:?}: {v}");
    assert!(v.passes(), "{kind:?}: the render disagrees with the closed form: {v}");
    // power: the same check rejects the closed form shifted by a tenth of a bin or scaled by 1%
    for (what, other) in [
        ("shifted by +0.1 bin", closed_form(0.1 * BIN)),
        ("shifted by -0.1 bin", closed_form(-0.1 * BIN)),
        ("scaled by 1.01", exact.iter().map(|e| e * 1.01).collect()),
        ("scaled by 0.99", exact.iter().map(|e| e * 0.99).collect()),
    ] {
        let w = Verdict::new(&runs, &other, &signal, tail);
        eprintln!("{kind:?}: against the closed form {what}: {w}");
        assert!(!w.passes(), "{kind:?}: cannot tell the closed form {what}: {w}");
    }
}

/// Independent renders compared with the closed form: 256 seeds of one pixel at 4096 spp
/// (~4 s per integrator on one core). Over 20 other seed bases (1000, 2000, …, 20000) the
/// check passed for both integrators; the former check (8 seeds, Σz² against independent
/// bins, max |z| ≤ 7) failed for 364 of 1024 disjoint sets of 8 seeds.
const RUNS: usize = 256;
const SEED_BASE: u64 = 40;
/// Bins per group in the Hotelling test: wider than the pulse (σ = 3 bins).
const GROUP: usize = 8;
/// False-alarm rates of the shape test and of the bin-by-bin test.
const ALPHA_SHAPE: f64 = 1e-4;
const ALPHA_BINS: f64 = 1e-4;

/// The comparison of K independent renders `runs[k][l]` with the closed form `exact[l]` over
/// the signal bins. The bins are not independent (the pulse spans several bins, and each
/// run's pixel positions move mass between early and late bins together), so no statistic
/// here assumes they are; and the far-tail bins (`signal[tail..]`, 6–9 σ after the last
/// arrival) come from rare samples near the pixel corners, so that one run in a hundred
/// carries a quarter of a bin: their per-run values are far from normal, and they are tested
/// only through their sum, one tail entry, whose mean over the runs is close to normal
/// (checked by resampling 8192 runs: its |t| and the others' behave as Student's, and over
/// 1500 resampled sets of 256 runs the T² p-value fell below 10⁻² in 1.0 % of the sets,
/// below 10⁻³ in 0.2 %, and the Bonferroni p-value below 10⁻² in 0.3 %).
/// The entries are the bins `signal[..tail]` and that tail sum. Three parts:
///
/// - total: Σ over all bins is the pixel's radiance, which barely varies over the pixel (its
///   spread over the runs is ~10⁻⁷ relative), so it must match the closed form to within
///   5 standard errors plus 8 f32 ulps (the kernel's f32 arithmetic; measured: −4.6·10⁻⁷,
///   the same for every seed set);
/// - shape: each run's entries, as fractions of its total, are summed in groups of `GROUP`
///   consecutive entries (p + 1 groups; the last is 1 − the others and is dropped). The
///   fractions keep the total's f32 offset out of T²: the total barely varies, so S⁻¹ would
///   turn that offset into T² ~ 10⁴ had the groups' raw sums been compared. With d
///   the mean over runs minus the closed form's fractions and S the sample covariance of
///   the p group fractions over the runs, Hotelling's T² = K·dᵀS⁻¹d, and
///   T²·(K − p)/(p·(K − 1)) ~ F(p, K − p) for any covariance (the group means are close to
///   normal by the CLT over 4096 samples per run); the test fails below `ALPHA_SHAPE`;
/// - bins: each entry's Student t (K − 1 dof, the standard error widened by 10⁻⁶ relative
///   for f32 film storage); the largest |t| must have a two-sided p-value above
///   `ALPHA_BINS` over the number of entries (Bonferroni, valid for any correlation).
struct Verdict {
    k: usize,
    total_rel: f64,
    total_z: f64,
    p: usize,
    t2: f64,
    t2_p: f64,
    entries: usize,
    t_max: f64,
    t_entry: usize,
    t_p: f64,
}

impl Verdict {
    fn new(runs: &[Vec<f64>], exact: &[f64], signal: &[usize], tail: usize) -> Verdict {
        let k = runs.len();
        let entries = |r: &[f64]| -> Vec<f64> {
            let mut e: Vec<f64> = signal[..tail].iter().map(|&l| r[l]).collect();
            if tail < signal.len() {
                e.push(signal[tail..].iter().map(|&l| r[l]).sum());
            }
            e
        };
        let x: Vec<Vec<f64>> = runs.iter().map(|r| entries(r)).collect();
        let ex = entries(exact);
        let n = ex.len();
        // total
        let totals: Vec<f64> = runs.iter().map(|r| r.iter().sum()).collect();
        let exact_total: f64 = exact.iter().sum();
        let (m, se) = common::mean_se(&totals);
        let slack = 8.0 * f32::EPSILON as f64 * exact_total;
        let total_z = ((m - exact_total).abs() - slack).max(0.0) / se.max(1e-300);
        // shape
        let groups: Vec<std::ops::Range<usize>> = (0..n.div_ceil(GROUP))
            .map(|g| g * GROUP..((g + 1) * GROUP).min(n))
            .collect();
        let p = groups.len() - 1;
        let fractions = |e: &[f64]| -> Vec<f64> {
            let t: f64 = e.iter().sum();
            groups[..p]
                .iter()
                .map(|g| e[g.clone()].iter().sum::<f64>() / t)
                .collect()
        };
        let f: Vec<Vec<f64>> = x.iter().map(|e| fractions(e)).collect();
        let fe = fractions(&ex);
        let mean: Vec<f64> = (0..p).map(|i| f.iter().map(|r| r[i]).sum::<f64>() / k as f64).collect();
        let mut s = vec![vec![0.0; p]; p];
        for r in &f {
            for i in 0..p {
                for j in 0..p {
                    s[i][j] += (r[i] - mean[i]) * (r[j] - mean[j]) / (k - 1) as f64;
                }
            }
        }
        let d: Vec<f64> = (0..p).map(|i| mean[i] - fe[i]).collect();
        let t2 = k as f64 * quadratic_form_inverse(&s, &d);
        let fstat = t2 * (k - p) as f64 / (p as f64 * (k - 1) as f64);
        let t2_p = f_sf(fstat, p as f64, (k - p) as f64);
        // bins
        let (mut t_max, mut t_entry) = (0.0f64, 0);
        for i in 0..n {
            let (m, se) = common::mean_se(&x.iter().map(|r| r[i]).collect::<Vec<_>>());
            let t = (m - ex[i]) / (se + 1e-6 * ex[i]).max(1e-300);
            if t.abs() > t_max {
                (t_max, t_entry) = (t.abs(), i);
            }
        }
        let t_p = t_sf2(t_max, (k - 1) as f64) * n as f64;
        Verdict {
            k,
            total_rel: m / exact_total - 1.0,
            total_z,
            p,
            t2,
            t2_p,
            entries: n,
            t_max,
            t_entry,
            t_p,
        }
    }

    fn passes(&self) -> bool {
        self.total_z <= 5.0 && self.t2_p >= ALPHA_SHAPE && self.t_p >= ALPHA_BINS
    }
}

impl std::fmt::Display for Verdict {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(
            f,
            "{} runs: total {:+.2e} relative (z beyond the f32 slack {:.1}); \
             shape T² = {:.1} over {} groups (p = {:.1e}); {} entries: max |t| = {:.2} at {} \
             (Bonferroni p = {:.1e})",
            self.k,
            self.total_rel,
            self.total_z,
            self.t2,
            self.p,
            self.t2_p,
            self.entries,
            self.t_max,
            self.t_entry,
            self.t_p
        )
    }
}

/// dᵀ S⁻¹ d for a symmetric positive definite S, by Cholesky on S scaled to unit diagonal.
fn quadratic_form_inverse(s: &[Vec<f64>], d: &[f64]) -> f64 {
    let p = d.len();
    let sc: Vec<f64> = (0..p).map(|i| s[i][i].sqrt()).collect();
    let mut l = vec![vec![0.0; p]; p];
    for i in 0..p {
        for j in 0..=i {
            let mut v = s[i][j] / (sc[i] * sc[j]);
            for m in 0..j {
                v -= l[i][m] * l[j][m];
            }
            if i == j {
                assert!(v > 0.0, "sample covariance not positive definite");
                l[i][i] = v.sqrt();
            } else {
                l[i][j] = v / l[j][j];
            }
        }
    }
    // solve L y = d / sc; dᵀS⁻¹d = |y|²
    let mut y = vec![0.0; p];
    for i in 0..p {
        let mut v = d[i] / sc[i];
        for m in 0..i {
            v -= l[i][m] * y[m];
        }
        y[i] = v / l[i][i];
    }
    y.iter().map(|v| v * v).sum()
}

/// P(F > f) for F ~ F(d1, d2).
fn f_sf(f: f64, d1: f64, d2: f64) -> f64 {
    use statrs::distribution::{ContinuousCDF, FisherSnedecor};
    FisherSnedecor::new(d1, d2).unwrap().sf(f)
}

/// P(|T| > t) for T ~ Student t with `nu` degrees of freedom.
fn t_sf2(t: f64, nu: f64) -> f64 {
    use statrs::distribution::{ContinuousCDF, StudentsT};
    2.0 * StudentsT::new(0.0, 1.0, nu).unwrap().sf(t.abs())
}

#[test]
fn the_f_and_t_tails_match_tabulated_values() {
    // F(0.95; 10, 20) = 2.348, t(0.975; 30) = 2.042 (two-sided 5 %), t(0.9995; 10) = 4.587
    assert!((f_sf(2.348, 10.0, 20.0) - 0.05).abs() < 2e-4);
    assert!((t_sf2(2.042, 30.0) - 0.05).abs() < 2e-4);
    assert!((t_sf2(4.587, 10.0) - 1e-3).abs() < 2e-5);
}

#[test]
fn a_start_opl_that_is_not_an_f32_lands_the_peak_in_its_bin() {
    // 3.9999999505 is 49.5 bins of 1 nm before the arrival at exactly 2h = 4 m; as an f32
    // it would read 4.0 and put the peak at bin 0. A needle filter sends every sample through
    // the pixel centre, where the OPL is 2h.
    let scene = load(&scene_text("3.9999999505", 100, "{ type = \"tent\", radius = 1e-3 }"));
    assert_eq!(scene.film.axis.start_opl, 3.9999999505);
    assert_eq!(scene.film.axis.bin_width_opl, 1e-9);
    let (t, _) = render(&scene, &common::options(16, 1)).unwrap();
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
        ..common::options(4096, 0)
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
