//! The `sobol` sample sequence (`[integrator] sampler`, `kernel::sobol`): padded
//! Owen-scrambled Sobol points per pixel. Each point is uniform, so renders keep the
//! independent sequence's expectation (checked per bin, per image block and per block × bin
//! group over independent seeds, for the path tracer and BDPT); stratification over a pixel's
//! samples lowers the error per sample (checked against a converged reference). Shards with
//! Sobol points add up to the whole render (tests/shards.rs).

use crate::common;
use difftransient::kernel::SampleSequence;
use difftransient::scene::IntegratorKind;
use difftransient::{RenderOptions, Scene, Transient, render};

const K: u64 = 12;

fn run(scene: &Scene, sampler: SampleSequence, kind: IntegratorKind, spp: u32, seed: u64) -> Transient {
    let mut s = scene.clone();
    s.integrator.sampler = sampler;
    let opts = RenderOptions {
        spp: Some(spp),
        seed: Some(seed),
        threads: Some(2),
        integrator: Some(kind),
        ..Default::default()
    };
    let (t, stats) = render(&s, &opts).unwrap();
    assert_eq!(stats.non_finite_samples, 0);
    t
}

fn small_cornell() -> Scene {
    let mut scene = common::load("cornell_box.toml");
    scene.film.width = 16;
    scene.film.height = 16;
    scene
}

/// Per-bin totals, the time-summed image, and 4×4 blocks × groups of 10 bins.
fn aggregates(t: &Transient) -> [Vec<f64>; 3] {
    [
        t.bin_totals().into_iter().map(|v| v as f64).collect(),
        t.steady.iter().map(|&v| v as f64).collect(),
        common::blocks_and_bin_groups(t, 10),
    ]
}

/// Sobol renders and independent renders (K seeds each) have the same mean: Σz² of every
/// aggregate within its Student-t expectation + 5 sd, every |z| ≤ 8.
fn same_expectation(name: &str, scene: &Scene, kind: IntegratorKind, spp: u32) {
    let seqs = [SampleSequence::Independent, SampleSequence::Sobol];
    let runs: Vec<Vec<[Vec<f64>; 3]>> = seqs
        .iter()
        .enumerate()
        .map(|(j, &q)| {
            (0..K)
                .map(|k| aggregates(&run(scene, q, kind, spp, 100 * j as u64 + k)))
                .collect()
        })
        .collect();
    assert_same_means(name, ["bins", "image", "blocks x bin groups"], &runs);
}

/// Independent-number runs (`runs[0]`) and Sobol runs (`runs[1]`), K seeds each, have the same
/// mean for every aggregate `names[a]`: Σz² within its Student-t expectation + 5 sd, every
/// |z| ≤ 8.
fn assert_same_means<const A: usize>(label: &str, names: [&str; A], runs: &[Vec<[Vec<f64>; A]>]) {
    for (a, what) in names.iter().enumerate() {
        let x: Vec<Vec<f64>> = runs[0].iter().map(|r| r[a].clone()).collect();
        let y: Vec<Vec<f64>> = runs[1].iter().map(|r| r[a].clone()).collect();
        let (chi2, zmax, n) = common::two_sample_z(&x, &y);
        let (mean, sd) = common::t2_sum_moments(n as f64, (K - 1) as f64);
        eprintln!("{label} {what}: Σz² = {chi2:.1} (expect {mean:.1} ± {sd:.1}) over {n}, max|z| = {zmax:.2}");
        assert!(n > 0, "{label} {what}: nothing rendered");
        assert!(
            chi2 <= mean + 5.0 * sd,
            "{label} {what}: Sobol and independent renders disagree"
        );
        assert!(zmax <= 8.0, "{label} {what}: an entry is {zmax:.1} standard errors off");
    }
}

#[test]
fn sobol_points_keep_the_expectation_path_tracer() {
    same_expectation("cornell path", &small_cornell(), IntegratorKind::Path, 64);
}

#[test]
fn sobol_points_keep_the_expectation_bdpt() {
    let mut scene = small_cornell();
    scene.film.width = 8;
    scene.film.height = 8;
    scene.integrator.max_bounces = 4;
    same_expectation("cornell bdpt", &scene, IntegratorKind::Bdpt, 32);
}

/// The point of the sequence: at 64 spp a single render's squared error against a converged
/// reference is at most half the independent sequence's (measured ≈ 0.06 of it on this box
/// at 64×64; a sequence that stratified nothing, e.g. pairs not scrambled apart, would give
/// about 1).
#[test]
fn sobol_points_lower_the_error_per_sample() {
    let scene = small_cornell();
    // reference: independent renders, 16 × 1024 spp
    let refs: Vec<Transient> = (0..16)
        .map(|k| {
            run(
                &scene,
                SampleSequence::Independent,
                IntegratorKind::Path,
                1024,
                5000 + k,
            )
        })
        .collect();
    let reference: Vec<f64> = (0..refs[0].data.len())
        .map(|i| refs.iter().map(|t| t.data[i] as f64).sum::<f64>() / refs.len() as f64)
        .collect();
    let sq = |t: &Transient| -> f64 {
        t.data
            .iter()
            .zip(&reference)
            .map(|(&a, &b)| (a as f64 - b).powi(2))
            .sum()
    };
    let mse = |q: SampleSequence| -> f64 {
        (0..4)
            .map(|k| sq(&run(&scene, q, IntegratorKind::Path, 64, 900 + k)))
            .sum::<f64>()
            / 4.0
    };
    let (ind, sob) = (mse(SampleSequence::Independent), mse(SampleSequence::Sobol));
    eprintln!(
        "64 spp squared error: independent {ind:.4e}, sobol {sob:.4e}, ratio {:.3}",
        sob / ind
    );
    assert!(
        sob <= 0.5 * ind,
        "Sobol error {sob:.3e} not below half the independent {ind:.3e}"
    );
}

#[test]
fn an_unknown_sampler_is_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(common::scene_path("cornell_box.toml"))
        .unwrap()
        .replace("seed = 0\n", "seed = 0\nsampler = \"halton\"\n");
    let path = dir.path().join("bad_sampler.toml");
    std::fs::write(&path, text).unwrap();
    let e = Scene::load(&path, &[]).unwrap_err().to_string();
    assert!(e.contains("bad_sampler.toml") && e.contains("sampler"), "{e}");
}

/// `--sampler` overrides the scene's, is recorded in the JSON (and in the shard identity, so
/// shards of different sequences cannot be merged), and a bad name is refused.
#[test]
fn the_cli_flag_selects_and_records_the_sequence() {
    let dir = tempfile::tempdir().unwrap();
    let scene = common::scene_path("cornell_box.toml");
    let args = |prefix: &str, sampler: &str| {
        vec![
            "render".to_string(),
            scene.display().to_string(),
            "--spp".into(),
            "2".into(),
            "--set".into(),
            "camera.resolution.0=8".into(),
            "--set".into(),
            "camera.resolution.1=8".into(),
            "--sampler".into(),
            sampler.into(),
            "-o".into(),
            dir.path().join(prefix).display().to_string(),
        ]
    };
    let mut outputs = Vec::new();
    for q in ["independent", "sobol"] {
        let a = args(q, q);
        let out = common::dtr(&a.iter().map(String::as_str).collect::<Vec<_>>(), dir.path());
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path().join(format!("{q}.json"))).unwrap()).unwrap();
        assert_eq!(json["sampler"], q);
        assert_eq!(json["identity"]["sampler"], q);
        outputs.push(std::fs::read(dir.path().join(format!("{q}.npy"))).unwrap());
    }
    assert_ne!(outputs[0], outputs[1], "the flag changed nothing");
    let a = args("bad", "halton");
    let out = common::dtr(&a.iter().map(String::as_str).collect::<Vec<_>>(), dir.path());
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("halton"));
}

/// With Sobol points the boundary stage's samples are one sequence over the stage
/// (`boundary::secondary`): the boundary term keeps its expectation (K seeds each, guided and
/// unguided, 4×4 blocks × groups of 4 bins of the derivative, and per-bin totals) and the
/// spread of the derivative's total over seeds falls (measured 1.34 → 0.22 at 16,384 samples
/// in `cargo bench --bench boundary`).
#[test]
fn sobol_points_keep_the_boundary_terms_expectation() {
    use difftransient::BoundaryMode;
    let mut scene = common::load("shadow_hidden_occluder.toml");
    scene.film.width = 16;
    scene.film.height = 16;
    for guiding in [false, true] {
        let runs = derivative_runs(&scene, "occluder_x", |seed| RenderOptions {
            spp: Some(1),
            spp_boundary: Some(16),
            seed: Some(seed),
            threads: Some(2),
            boundary: BoundaryMode::BoundaryOnly,
            guiding,
            ..Default::default()
        });
        assert_same_means(
            &format!("boundary (guiding {guiding})"),
            ["blocks x bin groups", "bins"],
            &runs,
        );
    }
}

/// Derivatives with Sobol points keep the expectation of those with independent numbers
/// (the dual kernel draws the same points as the primal): the liquid's index in the glass
/// block of scenes/liquid_glass.toml, 4×4 blocks × groups of 4 bins of ∂I/∂η and per-bin
/// totals, K seeds each.
#[test]
fn sobol_points_keep_the_derivatives_expectation() {
    let scene = common::load("liquid_glass.toml");
    let runs = derivative_runs(&scene, "liquid_ior", |seed| RenderOptions {
        spp: Some(16),
        seed: Some(seed),
        threads: Some(2),
        ..Default::default()
    });
    assert_same_means("d/d liquid_ior", ["blocks x bin groups", "bins"], &runs);
}

/// ∂I/∂`param` with independent numbers and with Sobol points, K seeds each (`opts(seed)`):
/// 4×4 blocks × groups of 4 bins, and per-bin totals, per render.
fn derivative_runs(scene: &Scene, param: &str, opts: impl Fn(u64) -> RenderOptions) -> Vec<Vec<[Vec<f64>; 2]>> {
    [SampleSequence::Independent, SampleSequence::Sobol]
        .iter()
        .enumerate()
        .map(|(j, &q)| {
            let mut s = scene.clone();
            s.integrator.sampler = q;
            (0..K)
                .map(|k| {
                    let (_, d, _) =
                        difftransient::render_diff(&s, &[param.to_string()], &opts(1000 * j as u64 + k)).unwrap();
                    [
                        common::blocks_and_bin_groups(&d[0], 4),
                        d[0].bin_totals().into_iter().map(|v| v as f64).collect(),
                    ]
                })
                .collect()
        })
        .collect()
}
