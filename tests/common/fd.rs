//! Interior derivatives against central finite differences with common random numbers,
//! shared by the path tracer's and BDPT's tests (see tests/interior_fd.rs for the method).
//!
//! For each of K seeds, D_k = AD_k − FD_k is computed on two aggregates: the per-pixel
//! time-summed derivative image and the per-bin totals. Its mean over seeds must vanish
//! within its standard error: Σ z² over the aggregate's entries is tested against the
//! Student-t (K − 1 dof) expectation, every |z| against a family-wise bound, and the grand
//! total within 3 standard errors. The standard error is widened by the finite difference's
//! own error: its truncation error, estimated by Richardson from steps h and 2h
//! ((FD_2h − FD_h) / 3), and f32 rounding of the film (2⁻²³ · |I| / h).

use difftransient::render::BoundaryMode;
use difftransient::scene::IntegratorKind;
use difftransient::{RenderOptions, Scene, Transient, render, render_diff};

/// One finite-difference set-up: the scene, seeds, samples, integrator and an edit applied
/// to every loaded scene (e.g. a different pixel filter).
pub struct FdCheck {
    pub scene: &'static str,
    pub k: u64,
    pub spp: u32,
    pub integrator: Option<IntegratorKind>,
    pub edit: fn(&mut Scene),
    /// Require the derivative to stand out from its noise (off for parameters whose true
    /// derivative is 0, where the test is that every term cancels).
    pub require_signal: bool,
    /// Which estimators the derivative renders run (`Full` unless a scene's derivative is the
    /// interior alone and the boundary stage cannot run on it).
    pub boundary: BoundaryMode,
}

impl FdCheck {
    fn opts(&self, seed: u64) -> RenderOptions {
        RenderOptions {
            spp: Some(self.spp),
            seed: Some(seed),
            threads: Some(2),
            integrator: self.integrator,
            boundary: self.boundary,
            ..Default::default()
        }
    }

    fn primal(&self, scene: &Scene, seed: u64) -> Transient {
        render(scene, &self.opts(seed)).unwrap().0
    }

    fn load_with(&self, name: &str, value: Option<f32>) -> Scene {
        let overrides: Vec<(String, f64)> = value.map(|v| vec![(name.to_string(), v as f64)]).unwrap_or_default();
        let mut s = Scene::load(&super::scene_path(self.scene), &overrides).unwrap();
        (self.edit)(&mut s);
        s
    }
}

fn image(t: &Transient) -> Vec<f64> {
    (0..t.height)
        .flat_map(|y| (0..t.width).map(move |x| (x, y)))
        .map(|(x, y)| t.time_sum(x, y, 0) as f64)
        .collect()
}
fn bins(t: &Transient) -> Vec<f64> {
    t.bin_totals().into_iter().map(|v| v as f64).collect()
}

/// Σ z², max |z| and entries for `diffs[k][i]` (seed k, entry i), plus the mean AD magnitude
/// in standard errors (to show the derivative is not trivially zero). `fd_err[i]` is the
/// finite difference's own error bound for entry i.
fn z_stats(diffs: &[Vec<f64>], ads: &[Vec<f64>], fd_err: &[f64]) -> (f64, f64, usize, f64) {
    let n = diffs[0].len();
    let (mut chi2, mut zmax, mut used, mut signal) = (0.0, 0.0f64, 0, 0.0f64);
    for i in 0..n {
        let col: Vec<f64> = diffs.iter().map(|d| d[i]).collect();
        let (m, se) = super::mean_se(&col);
        let ad: Vec<f64> = ads.iter().map(|d| d[i]).collect();
        let (ma, sea) = super::mean_se(&ad);
        signal = signal.max(ma.abs() / (sea + 1e-12));
        if se == 0.0 && m == 0.0 {
            continue;
        }
        let z = m
            / (se * se + fd_err[i] * fd_err[i])
                .sqrt()
                .max(1e-12 * ma.abs().max(1e-30));
        chi2 += z * z;
        if z.abs() > zmax {
            eprintln!(
                "  entry {i}: mean AD−FD {m:.4e}, se {se:.3e}, fd err {:.3e}, AD {ma:.4e}",
                fd_err[i]
            );
        }
        zmax = zmax.max(z.abs());
        used += 1;
    }
    (chi2, zmax, used, signal)
}

impl FdCheck {
    /// Checks ∂I/∂`name` at `value` against central differences with step `h`.
    pub fn check(&self, name: &str, value: f32, h: f32) {
        let k_seeds = self.k;
        let base = self.load_with(name, None);
        let plus = self.load_with(name, Some(value + h));
        let minus = self.load_with(name, Some(value - h));
        let plus2 = self.load_with(name, Some(value + 2.0 * h));
        let minus2 = self.load_with(name, Some(value - 2.0 * h));
        let mut d_img = Vec::new();
        let mut d_bin = Vec::new();
        let mut a_img = Vec::new();
        let mut a_bin = Vec::new();
        let mut totals = Vec::new();
        let mut rich_img = Vec::new();
        let mut rich_bin = Vec::new();
        let mut round_img = vec![0.0f64; 0];
        let mut round_bin = vec![0.0f64; 0];
        for seed in 0..k_seeds {
            let (_, d, _) = render_diff(&base, &[name.to_string()], &self.opts(seed)).unwrap();
            let ad = &d[0];
            let p = self.primal(&plus, seed);
            let m = self.primal(&minus, seed);
            let fd_img: Vec<f64> = image(&p)
                .iter()
                .zip(image(&m))
                .map(|(a, b)| (a - b) / (2.0 * h as f64))
                .collect();
            let fd_bin: Vec<f64> = bins(&p)
                .iter()
                .zip(bins(&m))
                .map(|(a, b)| (a - b) / (2.0 * h as f64))
                .collect();
            let p2 = self.primal(&plus2, seed);
            let m2 = self.primal(&minus2, seed);
            let fd2_img: Vec<f64> = image(&p2)
                .iter()
                .zip(image(&m2))
                .map(|(a, b)| (a - b) / (4.0 * h as f64))
                .collect();
            let fd2_bin: Vec<f64> = bins(&p2)
                .iter()
                .zip(bins(&m2))
                .map(|(a, b)| (a - b) / (4.0 * h as f64))
                .collect();
            rich_img.push(
                fd2_img
                    .iter()
                    .zip(&fd_img)
                    .map(|(a, b)| (a - b) / 3.0)
                    .collect::<Vec<_>>(),
            );
            rich_bin.push(
                fd2_bin
                    .iter()
                    .zip(&fd_bin)
                    .map(|(a, b)| (a - b) / 3.0)
                    .collect::<Vec<_>>(),
            );
            let eps = f32::EPSILON as f64;
            let rnd = |a: Vec<f64>, b: Vec<f64>| -> Vec<f64> {
                a.iter()
                    .zip(&b)
                    .map(|(x, y)| 4.0 * eps * (x.abs() + y.abs()) / (2.0 * h as f64))
                    .collect()
            };
            round_img = rnd(image(&p), image(&m));
            round_bin = rnd(bins(&p), bins(&m));
            let (ai, ab) = (image(ad), bins(ad));
            d_img.push(ai.iter().zip(&fd_img).map(|(a, f)| a - f).collect::<Vec<_>>());
            d_bin.push(ab.iter().zip(&fd_bin).map(|(a, f)| a - f).collect::<Vec<_>>());
            totals.push(ab.iter().sum::<f64>() - fd_bin.iter().sum::<f64>());
            a_img.push(ai);
            a_bin.push(ab);
        }
        let dof = (k_seeds - 1) as f64;
        // FD error per entry: |mean Richardson estimate| + its standard error + rounding
        let fd_err = |rich: &[Vec<f64>], round: &[f64]| -> Vec<f64> {
            (0..round.len())
                .map(|i| {
                    let col: Vec<f64> = rich.iter().map(|r| r[i]).collect();
                    let (m, se) = super::mean_se(&col);
                    m.abs() + 2.0 * se + round[i]
                })
                .collect()
        };
        // floor: S_e's Gaussian cut at 8σ leaves a jump of φ(8) ≈ 5e-15 of a path's peak, and f32
        // films resolve ~1e-7 of the largest entry; entries far below that carry no information
        let floor = |e: Vec<f64>, ads: &[Vec<f64>]| -> Vec<f64> {
            let peak = ads.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
            e.into_iter().map(|x| x + 1e-12 * peak).collect()
        };
        let err_img = floor(fd_err(&rich_img, &round_img), &a_img);
        let err_bin = floor(fd_err(&rich_bin, &round_bin), &a_bin);
        let mut best_signal = 0.0f64;
        for (what, d, a, e) in [("image", &d_img, &a_img, &err_img), ("bins", &d_bin, &a_bin, &err_bin)] {
            let (chi2, zmax, n, signal) = z_stats(d, a, e);
            best_signal = best_signal.max(signal);
            let n_f = n as f64;
            // Student t with ν dof: E[t²] = ν/(ν−2), Var[t²] = 2ν²(ν−1)/((ν−2)²(ν−4))
            let (mean, sd) = super::t2_sum_moments(n_f, dof);
            eprintln!(
                "{name} {what}: Σz² = {chi2:.1} (expect {mean:.1} ± {sd:.1}), max|z| = {zmax:.2}, signal {signal:.1} se"
            );
            assert!(
                chi2 <= mean + 5.0 * sd,
                "{name} {what}: AD and FD disagree: Σz² = {chi2:.1} over {n} entries"
            );
            // family-wise: P(|t_11| > 8) ≈ 4e-6 per entry
            assert!(zmax <= 8.0, "{name} {what}: an entry is {zmax:.1} standard errors off");
        }
        assert!(
            !self.require_signal || best_signal > 5.0,
            "{name}: the derivative is not distinguishable from zero ({best_signal:.1} se)"
        );
        let (m, se) = super::mean_se(&totals);
        let total_fd_err: f64 = err_bin.iter().sum();
        assert!(
            m.abs() <= 3.0 * se + total_fd_err,
            "{name}: total AD − FD = {m} (se {se}, fd error {total_fd_err})"
        );
    }
}

/// Coarse aggregates of a transient, for tests whose statistics must expose a bias of a few
/// percent: the grand total, the four image halves (left, right, top, bottom), the four
/// quadrants and the bin totals grouped into eight time slices (channels summed).
pub fn coarse_aggregates(t: &Transient) -> Vec<(String, f64)> {
    let (w, h) = (t.width, t.height);
    let img = image(t);
    let region = |f: &dyn Fn(usize, usize) -> bool| -> f64 {
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| f(x, y))
            .map(|(x, y)| img[y * w + x])
            .sum()
    };
    let mut out = vec![
        ("total".to_string(), img.iter().sum()),
        ("left".into(), region(&|x, _| x < w / 2)),
        ("right".into(), region(&|x, _| x >= w / 2)),
        ("top".into(), region(&|_, y| y < h / 2)),
        ("bottom".into(), region(&|_, y| y >= h / 2)),
    ];
    for (qx, qy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let v = region(&|x, y| (x >= w / 2) as usize == qx && (y >= h / 2) as usize == qy);
        out.push((format!("quadrant {qx}{qy}"), v));
    }
    let b = bins(t);
    let slices = 8.min(b.len());
    for k in 0..slices {
        let (lo, hi) = (k * b.len() / slices, (k + 1) * b.len() / slices);
        out.push((format!("bins {lo}..{hi}"), b[lo..hi].iter().sum()));
    }
    out
}

impl FdCheck {
    /// Checks ∂I/∂`name` at `value` on [`coarse_aggregates`] against central differences with
    /// step `h` and common random numbers: per seed D = AD − FD, and its mean over the K seeds
    /// must lie within 4 standard errors (widened by the finite difference's Richardson
    /// truncation estimate and f32 rounding) for every aggregate. Returns the largest |z| and
    /// the resolution: the smallest relative bias of an aggregate's derivative that this run
    /// would see at 4 standard errors (min over aggregates of 4·sd(AD − FD) / |AD|).
    pub fn check_aggregates(&self, name: &str, value: f32, h: f32) -> (f64, f64) {
        let base = self.load_with(name, None);
        let steps = [h, -h, 2.0 * h, -2.0 * h].map(|s| self.load_with(name, Some(value + s)));
        let agg = |t: &Transient| -> Vec<f64> { coarse_aggregates(t).into_iter().map(|(_, v)| v).collect() };
        let labels: Vec<String> = coarse_aggregates(&render(&base, &self.opts(0)).unwrap().0)
            .into_iter()
            .map(|(l, _)| l)
            .collect();
        let (mut diffs, mut ads, mut rich, mut round) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for seed in 0..self.k {
            let (_, d, _) = render_diff(&base, &[name.to_string()], &self.opts(seed)).unwrap();
            let ad = agg(&d[0]);
            let p: Vec<Vec<f64>> = steps.iter().map(|s| agg(&self.primal(s, seed))).collect();
            let fd: Vec<f64> = (0..ad.len()).map(|i| (p[0][i] - p[1][i]) / (2.0 * h as f64)).collect();
            let fd2: Vec<f64> = (0..ad.len()).map(|i| (p[2][i] - p[3][i]) / (4.0 * h as f64)).collect();
            rich.push(fd2.iter().zip(&fd).map(|(a, b)| (a - b) / 3.0).collect::<Vec<_>>());
            let eps = f32::EPSILON as f64;
            round.push(
                (0..ad.len())
                    .map(|i| 4.0 * eps * (p[0][i].abs() + p[1][i].abs()) / (2.0 * h as f64))
                    .collect::<Vec<_>>(),
            );
            diffs.push(ad.iter().zip(&fd).map(|(a, f)| a - f).collect::<Vec<_>>());
            ads.push(ad);
        }
        let col = |m: &[Vec<f64>], i: usize| -> Vec<f64> { m.iter().map(|r| r[i]).collect() };
        let mut zmax = 0.0f64;
        let mut resolution = f64::INFINITY;
        let mut failures = Vec::new();
        for (i, label) in labels.iter().enumerate() {
            let (m, se) = super::mean_se(&col(&diffs, i));
            let (ma, sea) = super::mean_se(&col(&ads, i));
            let (mr, ser) = super::mean_se(&col(&rich, i));
            let fd_err = mr.abs() + 2.0 * ser + col(&round, i).iter().sum::<f64>() / self.k as f64;
            let sd = (se * se + fd_err * fd_err).sqrt();
            if sd == 0.0 && m == 0.0 {
                continue;
            }
            let z = m / sd.max(1e-12 * ma.abs().max(1e-30));
            eprintln!(
                "{name} {label}: AD {ma:.5e} ± {sea:.1e}, AD − FD {m:.3e} (se {se:.1e}, fd err {fd_err:.1e}), z {z:.2}"
            );
            zmax = zmax.max(z.abs());
            resolution = resolution.min(4.0 * sd / ma.abs());
            if z.abs() > 4.0 {
                failures.push(format!("{label}: z = {z:.1}"));
            }
        }
        assert!(failures.is_empty(), "{name}: AD and FD disagree on {failures:?}");
        (zmax, resolution)
    }
}
