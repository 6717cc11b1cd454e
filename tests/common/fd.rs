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

use super::power::{Entry, Power, RelativeBias, Test, richardson_reference};
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
    /// Why this check may resolve less than [`super::power::MAX_DETECTABLE_BIAS`] (its
    /// measured detectable bias, and why more seeds or samples do not fit the CI budget): its
    /// power is then printed, not asserted. `None` for every check that can be strong enough.
    pub power_exemption: Option<&'static str>,
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
/// in standard errors (to show the derivative is not trivially zero) and the judged entries
/// (for the test's power). `fd_err[i]` is the finite difference's own error bound for entry i.
fn z_stats(diffs: &[Vec<f64>], ads: &[Vec<f64>], fd_err: &[f64]) -> (f64, f64, usize, f64, Vec<Entry>) {
    let n = diffs[0].len();
    let (mut chi2, mut zmax, mut used, mut signal) = (0.0, 0.0f64, 0, 0.0f64);
    let mut entries = Vec::new();
    for i in 0..n {
        let col: Vec<f64> = diffs.iter().map(|d| d[i]).collect();
        let (m, se) = super::mean_se(&col);
        let ad: Vec<f64> = ads.iter().map(|d| d[i]).collect();
        let (ma, sea) = super::mean_se(&ad);
        signal = signal.max(ma.abs() / (sea + 1e-12));
        if se == 0.0 && m == 0.0 {
            continue;
        }
        let sd = (se * se + fd_err[i] * fd_err[i])
            .sqrt()
            .max(1e-12 * ma.abs().max(1e-30));
        let z = m / sd;
        entries.push(Entry {
            floor: 1e-12 * ma.abs().max(1e-30),
            ..Entry::new(col, ad, fd_err[i])
        });
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
    (chi2, zmax, used, signal, entries)
}

/// The three views the checks judge of one transient: the time-summed image, the bin totals
/// and the [`coarse_aggregates`].
struct Views {
    image: Vec<f64>,
    bins: Vec<f64>,
    coarse: Vec<f64>,
}

impl Views {
    fn of(t: &Transient) -> Self {
        Views {
            image: image(t),
            bins: bins(t),
            coarse: coarse_aggregates(t).into_iter().map(|(_, v)| v).collect(),
        }
    }
}

/// One check's renders, reduced to [`Views`]: per seed, the derivative at the value and the
/// primals at value + h, − h, + 2h and − 2h (common random numbers: one seed for all five).
/// The per-entry check and the coarse aggregates judge the same renders, so a test that runs
/// both renders once.
struct Runs {
    h: f64,
    ad: Vec<Views>,
    primals: Vec<[Views; 4]>,
    labels: Vec<String>,
}

impl Runs {
    /// Per seed, the central difference of `view` at step h (`wide` false) or 2h (true).
    fn fd(&self, view: fn(&Views) -> &Vec<f64>, wide: bool) -> Vec<Vec<f64>> {
        let (a, b, step) = if wide { (2, 3, 2.0 * self.h) } else { (0, 1, self.h) };
        self.primals
            .iter()
            .map(|p| {
                view(&p[a])
                    .iter()
                    .zip(view(&p[b]))
                    .map(|(x, y)| (x - y) / (2.0 * step))
                    .collect()
            })
            .collect()
    }

    /// Per seed, Richardson's estimate of the step-h difference's truncation error,
    /// (FD_2h − FD_h) / 3.
    fn richardson(&self, view: fn(&Views) -> &Vec<f64>) -> Vec<Vec<f64>> {
        let (fd, fd2) = (self.fd(view, false), self.fd(view, true));
        fd2.iter()
            .zip(&fd)
            .map(|(w, n)| w.iter().zip(n).map(|(a, b)| (a - b) / 3.0).collect())
            .collect()
    }

    /// Per seed, a bound on f32 rounding of the film in the step-h difference:
    /// 4ε(|I₊| + |I₋|) / 2h.
    fn rounding(&self, view: fn(&Views) -> &Vec<f64>) -> Vec<Vec<f64>> {
        let eps = f32::EPSILON as f64;
        self.primals
            .iter()
            .map(|p| {
                view(&p[0])
                    .iter()
                    .zip(view(&p[1]))
                    .map(|(x, y)| 4.0 * eps * (x.abs() + y.abs()) / (2.0 * self.h))
                    .collect()
            })
            .collect()
    }

    /// Per seed, the derivative's `view`.
    fn ads(&self, view: fn(&Views) -> &Vec<f64>) -> Vec<Vec<f64>> {
        self.ad.iter().map(|v| view(v).clone()).collect()
    }

    /// Per seed, AD − FD (step h) on `view`.
    fn diffs(&self, view: fn(&Views) -> &Vec<f64>) -> Vec<Vec<f64>> {
        self.ads(view)
            .iter()
            .zip(self.fd(view, false))
            .map(|(a, f)| a.iter().zip(&f).map(|(a, f)| a - f).collect())
            .collect()
    }
}

impl FdCheck {
    /// Renders the derivative and the four primals of every seed.
    fn runs(&self, name: &str, value: f32, h: f32) -> Runs {
        let base = self.load_with(name, None);
        let steps = [h, -h, 2.0 * h, -2.0 * h].map(|s| self.load_with(name, Some(value + s)));
        let mut runs = Runs {
            h: h as f64,
            ad: Vec::new(),
            primals: Vec::new(),
            labels: Vec::new(),
        };
        for seed in 0..self.k {
            let (_, d, _) = render_diff(&base, &[name.to_string()], &self.opts(seed)).unwrap();
            if runs.labels.is_empty() {
                runs.labels = coarse_aggregates(&d[0]).into_iter().map(|(l, _)| l).collect();
            }
            runs.ad.push(Views::of(&d[0]));
            runs.primals
                .push(steps.each_ref().map(|s| Views::of(&self.primal(s, seed))));
        }
        runs
    }

    /// Checks ∂I/∂`name` at `value` against central differences with step `h`, per entry
    /// (every pixel's time-summed derivative and every bin's total), and that the check
    /// rejects a relative bias of the derivative of [`super::power::MAX_DETECTABLE_BIAS`].
    pub fn check(&self, name: &str, value: f32, h: f32) {
        let test = self.judge_entries(name, &self.runs(name, value, h));
        self.judge_power(name, test.power());
    }

    /// [`FdCheck::check`] and [`FdCheck::check_aggregates`] on one set of renders; the power
    /// asked for is the two checks' together (either failing fails the test).
    pub fn check_entries_and_aggregates(&self, name: &str, value: f32, h: f32) -> (f64, f64) {
        let runs = self.runs(name, value, h);
        let mut test = self.judge_entries(name, &runs);
        let (zmax, resolution, aggregates) = self.judge_aggregates(name, &runs);
        self.judge_power(name, test.and(aggregates).power());
        (zmax, resolution)
    }

    /// Asserts the power of the check of `name`, unless its derivative is truly 0 (no signal
    /// required: there is nothing to scale, and the test is that every term cancels) or the
    /// check carries a documented `power_exemption`.
    fn judge_power(&self, name: &str, power: Power) {
        let label = format!(
            "{} {name} ({:?}, {} seeds × {} spp)",
            self.scene, self.integrator, self.k, self.spp
        );
        match (self.require_signal, self.power_exemption) {
            (false, _) => power.exempt(&label, "the true derivative is 0"),
            (true, Some(reason)) => power.exempt(&label, reason),
            (true, None) => power.assert_enough(&label),
        }
    }

    /// The per-entry check; returns its assertions, for their power.
    fn judge_entries(&self, name: &str, runs: &Runs) -> Test {
        let k_seeds = self.k;
        let img: fn(&Views) -> &Vec<f64> = |v| &v.image;
        let bin: fn(&Views) -> &Vec<f64> = |v| &v.bins;
        let dof = (k_seeds - 1) as f64;
        // FD error per entry: |mean Richardson estimate| + its standard error + rounding (of
        // the last seed's renders)
        let fd_err = |view: fn(&Views) -> &Vec<f64>| -> Vec<f64> {
            let rich = runs.richardson(view);
            let round = runs.rounding(view).pop().unwrap();
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
        let (a_img, a_bin) = (runs.ads(img), runs.ads(bin));
        let (d_img, d_bin) = (runs.diffs(img), runs.diffs(bin));
        let err_img = floor(fd_err(img), &a_img);
        let err_bin = floor(fd_err(bin), &a_bin);
        let mut best_signal = 0.0f64;
        let mut test = Test::default();
        for (what, d, a, e) in [("image", &d_img, &a_img, &err_img), ("bins", &d_bin, &a_bin, &err_bin)] {
            let (chi2, zmax, n, signal, entries) = z_stats(d, a, e);
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
            test.sum_of_squares(entries.clone(), mean + 5.0 * sd)
                .every(entries, 8.0);
        }
        assert!(
            !self.require_signal || best_signal > 5.0,
            "{name}: the derivative is not distinguishable from zero ({best_signal:.1} se)"
        );
        let totals: Vec<f64> = d_bin.iter().map(|d| d.iter().sum::<f64>()).collect();
        let (m, se) = super::mean_se(&totals);
        let total_fd_err: f64 = err_bin.iter().sum();
        assert!(
            m.abs() <= 3.0 * se + total_fd_err,
            "{name}: total AD − FD = {m} (se {se}, fd error {total_fd_err})"
        );
        let ad_totals: Vec<f64> = a_bin.iter().map(|a| a.iter().sum::<f64>()).collect();
        test.one(Entry {
            scale: 3.0,
            add: total_fd_err,
            ..Entry::new(totals, ad_totals, 0.0)
        });
        test
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
    /// Also asserts that the check rejects a relative bias of the derivative of
    /// [`super::power::MAX_DETECTABLE_BIAS`].
    pub fn check_aggregates(&self, name: &str, value: f32, h: f32) -> (f64, f64) {
        let (zmax, resolution, test) = self.judge_aggregates(name, &self.runs(name, value, h));
        self.judge_power(name, test.power());
        (zmax, resolution)
    }

    /// The check on coarse aggregates: the largest |z|, the resolution and the assertions (for
    /// their power).
    fn judge_aggregates(&self, name: &str, runs: &Runs) -> (f64, f64, Test) {
        let coarse: fn(&Views) -> &Vec<f64> = |v| &v.coarse;
        let (diffs, ads, rich, round) = (
            runs.diffs(coarse),
            runs.ads(coarse),
            runs.richardson(coarse),
            runs.rounding(coarse),
        );
        let labels = &runs.labels;
        let col = |m: &[Vec<f64>], i: usize| -> Vec<f64> { m.iter().map(|r| r[i]).collect() };
        let mut zmax = 0.0f64;
        let mut resolution = f64::INFINITY;
        let (mut entries, mut errs) = (Vec::new(), Vec::new());
        let mut failures = Vec::new();
        for (i, label) in labels.iter().enumerate() {
            let (m, se) = super::mean_se(&col(&diffs, i));
            let (ma, sea) = super::mean_se(&col(&ads, i));
            let (mr, ser) = super::mean_se(&col(&rich, i));
            let fd_err = mr.abs() + 2.0 * ser + col(&round, i).iter().sum::<f64>() / self.k as f64;
            let sd = (se * se + fd_err * fd_err).sqrt();
            errs.push(fd_err);
            if sd == 0.0 && m == 0.0 {
                continue;
            }
            let z = m / sd.max(1e-12 * ma.abs().max(1e-30));
            eprintln!(
                "{name} {label}: AD {ma:.5e} ± {sea:.1e}, AD − FD {m:.3e} (se {se:.1e}, fd err {fd_err:.1e}), z {z:.2}"
            );
            zmax = zmax.max(z.abs());
            resolution = resolution.min(4.0 * sd / ma.abs());
            entries.push(Entry {
                floor: 1e-12 * ma.abs().max(1e-30),
                ..Entry::new(col(&diffs, i), col(&ads, i), fd_err)
            });
            if z.abs() > 4.0 {
                failures.push(format!("{label}: z = {z:.1}"));
            }
        }
        assert!(failures.is_empty(), "{name}: AD and FD disagree on {failures:?}");
        let mut test = Test::default();
        test.every(entries, 4.0);
        // the relative bias fitted over every aggregate at once (against Richardson's
        // extrapolation): the statistic aimed at a uniform bias of a few percent (not where
        // the derivative is 0: there is nothing to scale)
        if self.require_signal {
            let reference = richardson_reference(&runs.fd(coarse, false), &runs.fd(coarse, true));
            RelativeBias::fit(&ads, &reference, &errs).assert_unbiased(name);
            test.fit(ads, reference, errs, 4.0);
        }
        (zmax, resolution, test)
    }
}

/// The [`coarse_aggregates`] values of forward renders of `scene` at 32 spp on two threads,
/// one per seed of `seeds`, with `integrator` (the scene's when `None`) and steady images over
/// all time.
pub fn coarse_runs(scene: &Scene, integrator: Option<IntegratorKind>, seeds: std::ops::Range<u64>) -> Vec<Vec<f64>> {
    seeds
        .map(|seed| {
            let opts = RenderOptions {
                spp: Some(32),
                seed: Some(seed),
                threads: Some(2),
                integrator,
                steady: difftransient::film::SteadyMode::Full,
                ..Default::default()
            };
            let t = render(scene, &opts).unwrap().0;
            coarse_aggregates(&t).into_iter().map(|(_, v)| v).collect()
        })
        .collect()
}
