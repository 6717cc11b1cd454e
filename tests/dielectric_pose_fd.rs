//! Pose derivatives of refractive objects (issue 13): the full derivative, interior
//! (Algorithm 1) + primary edges + secondary edges (Algorithm 2), against central finite
//! differences with common random numbers, with the path tracer and with BDPT as the
//! interior estimator.
//!
//! - scenes/glass_pose.toml: a rough glass ball floating over a lit floor moves sideways;
//!   the camera sees its silhouette (primary edges) and the shadow and caustic it casts
//!   (secondary edges, whose subpaths pass through the glass);
//! - scenes/glass_ball_floor.toml: the same ball resting on the floor (contact at a point);
//! - scenes/liquid_pose.toml: a liquid cube moves inside a glass block; its edges are seen
//!   through the glass only, so the whole boundary term is secondary, with segments inside
//!   the glass (index 1.5): their OPL must use the glass's index, not the scene's (the
//!   secondary term moved 0.4 of OPL early fails).
//!
//! For each of K seeds, D = AD − FD on aggregates of the transient (`common::
//! blocks_and_bin_groups`): 4×4 blocks of the
//! time-summed image and groups of bins of the whole image (so a wrong time of flight moves
//! the derivative between groups). The mean of D over seeds must vanish within its standard
//! error, widened by the FD's own truncation error (Richardson, steps h and 2h): Σz² against
//! the Student-t (K − 1 dof) expectation + 5 sd, every |z| ≤ 8. Each test also shows that
//! it can fail: the interior alone, and the full derivative without its secondary (or
//! primary) part, miss by far, and so does the full derivative scaled by 1 ± 20 % (BDPT).
//! A heavier BDPT run of the floating ball fits the relative bias over every pixel at once
//! (`relative_bias`) and resolves 4 %: the full derivative × 0.96 and × 1.04 fail.
//! `FD_DEBUG=1` prints the statistics of scaled derivatives, `FD_DEBUG=2` every aggregate.

use crate::common;
use common::power::{Entry, Power, Test};
use difftransient::scene::IntegratorKind;
use difftransient::{BoundaryMode, RenderOptions, Scene, render, render_diff_parts};

/// One finite-difference set-up.
struct Setup {
    scene: &'static str,
    param: &'static str,
    value: f32,
    h: f32,
    seeds: u64,
    spp: u32,
    spp_boundary: u32,
    spp_fd: u32,
    /// Samples per pixel of the renders at ±2h (Richardson's estimate of the truncation).
    spp_fd2: u32,
    /// Groups of this many bins form the time aggregates.
    bin_group: usize,
    /// The image aggregates are single pixels (`common::pixels_and_bin_groups`) rather than
    /// 4×4 blocks.
    pixels: bool,
    integrator: Option<IntegratorKind>,
}

fn load(scene: &str, name: &str, value: Option<f32>) -> Scene {
    let overrides: Vec<(String, f64)> = value.map(|v| vec![(name.to_string(), v as f64)]).unwrap_or_default();
    Scene::load(&common::scene_path(scene), &overrides).unwrap()
}

/// Per seed, the aggregates of each derivative part and of the two finite differences.
struct Runs {
    interior: Vec<Vec<f64>>,
    primary: Vec<Vec<f64>>,
    secondary: Vec<Vec<f64>>,
    fd: Vec<Vec<f64>>,
    fd2: Vec<Vec<f64>>,
}

impl Setup {
    fn opts(&self, seed: u64, spp: u32) -> RenderOptions {
        RenderOptions {
            spp: Some(spp),
            seed: Some(seed),
            threads: Some(2),
            spp_boundary: Some(self.spp_boundary),
            boundary: BoundaryMode::Full,
            integrator: self.integrator,
            ..Default::default()
        }
    }

    fn run(&self) -> Runs {
        let base = load(self.scene, self.param, None);
        let at = |d: f32| load(self.scene, self.param, Some(self.value + d));
        let steps = [at(self.h), at(-self.h), at(2.0 * self.h), at(-2.0 * self.h)];
        let g = self.bin_group;
        let aggregate = |t: &difftransient::Transient| {
            if self.pixels {
                common::pixels_and_bin_groups(t, g)
            } else {
                common::blocks_and_bin_groups(t, g)
            }
        };
        let mut r = Runs {
            interior: vec![],
            primary: vec![],
            secondary: vec![],
            fd: vec![],
            fd2: vec![],
        };
        for seed in 0..self.seeds {
            let parts = render_diff_parts(&base, &[self.param.to_string()], &self.opts(seed, self.spp)).unwrap();
            assert_eq!(parts.stats.non_finite_samples, 0);
            assert!(!parts.secondary.is_empty(), "the boundary stage did not run");
            r.interior.push(aggregate(&parts.interior[0]));
            r.primary.push(aggregate(&parts.primary[0]));
            r.secondary.push(aggregate(&parts.secondary[0]));
            let p: Vec<Vec<f64>> = steps
                .iter()
                .zip([self.spp_fd, self.spp_fd, self.spp_fd2, self.spp_fd2])
                .map(|(s, spp)| aggregate(&render(s, &self.opts(seed, spp)).unwrap().0))
                .collect();
            let diff = |a: &[f64], b: &[f64], step: f32| -> Vec<f64> {
                a.iter().zip(b).map(|(a, b)| (a - b) / (2.0 * step as f64)).collect()
            };
            r.fd.push(diff(&p[0], &p[1], self.h));
            r.fd2.push(diff(&p[2], &p[3], 2.0 * self.h));
        }
        r
    }
}

/// Σz² and max |z| of `ad` − FD over the aggregates and its bound (printed with the
/// resolution: the smallest relative bias of an aggregate's derivative that this run would
/// see at 4 standard errors, min over aggregates of 4·sd(AD − FD) / |AD|).
struct Verdict {
    chi2: f64,
    zmax: f64,
    bound: f64,
    /// The smallest relative bias of the judged derivative that Σz² ≤ bound or max|z| ≤ 8
    /// rejects.
    power: Power,
}

impl Verdict {
    fn passes(&self) -> bool {
        self.chi2 <= self.bound && self.zmax <= 8.0
    }
}

fn judge(label: &str, ad: &[Vec<f64>], r: &Runs) -> Verdict {
    let n = ad[0].len();
    let seeds = ad.len();
    let peak = ad.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let (mut chi2, mut zmax, mut used) = (0.0, 0.0f64, 0usize);
    let mut resolution = f64::INFINITY;
    let mut entries = Vec::new();
    for i in 0..n {
        let d: Vec<f64> = (0..seeds).map(|k| ad[k][i] - r.fd[k][i]).collect();
        let rich: Vec<f64> = (0..seeds).map(|k| (r.fd2[k][i] - r.fd[k][i]) / 3.0).collect();
        let (m, se) = common::mean_se(&d);
        let (mr, ser) = common::mean_se(&rich);
        let fd_err = mr.abs() + 2.0 * ser;
        if m == 0.0 && se == 0.0 {
            continue;
        }
        let sd = (se * se + fd_err * fd_err).sqrt();
        let (ma, _) = common::mean_se(&col(ad, i));
        let z = m / (sd + 1e-9 * peak);
        if std::env::var("FD_DEBUG").is_ok_and(|v| v == "2") {
            let (mf, sf) = common::mean_se(&col(&r.fd, i));
            let (_, sa) = common::mean_se(&col(ad, i));
            eprintln!(
                "  {label} {i}: AD {ma:.4e} ± {sa:.2e}, FD {mf:.4e} ± {sf:.2e}, AD−FD {m:.3e} (se {se:.2e}, fd err {fd_err:.2e}), z {z:.2}"
            );
        }
        resolution = resolution.min(4.0 * sd / ma.abs());
        entries.push(Entry {
            add: 1e-9 * peak,
            ..Entry::new(d, col(ad, i), fd_err)
        });
        chi2 += z * z;
        zmax = zmax.max(z.abs());
        used += 1;
    }
    let (mean, sd) = common::t2_sum_moments(used as f64, (seeds - 1) as f64);
    eprintln!(
        "{label}: Σz² = {chi2:.1} (bound {:.1}) over {used}, max|z| {zmax:.2}, resolves {:.1} %",
        mean + 5.0 * sd,
        100.0 * resolution
    );
    let bound = mean + 5.0 * sd;
    Verdict {
        chi2,
        zmax,
        bound,
        power: Test::default()
            .sum_of_squares(entries.clone(), bound)
            .every(entries, 8.0)
            .power(),
    }
}

/// The relative bias of `ad` against the finite differences, fitted over all aggregates at
/// once, as (mean, standard error) over seeds: [`common::power::RelativeBias::fit`] against
/// Richardson's extrapolation of the two central differences.
fn relative_bias(ad: &[Vec<f64>], r: &Runs) -> (f64, f64) {
    let reference = common::power::richardson_reference(&r.fd, &r.fd2);
    let fit = common::power::RelativeBias::fit(ad, &reference, &vec![0.0; ad[0].len()]);
    (fit.mean, fit.se)
}

/// Per aggregate, the finite difference's truncation error bound of [`judge`]: |mean| + 2 se of
/// Richardson's estimate (FD_2h − FD_h) / 3.
fn fd_errors(r: &Runs) -> Vec<f64> {
    (0..r.fd[0].len())
        .map(|i| {
            let rich: Vec<f64> = r.fd.iter().zip(&r.fd2).map(|(f, f2)| (f2[i] - f[i]) / 3.0).collect();
            let (mr, ser) = common::mean_se(&rich);
            mr.abs() + 2.0 * ser
        })
        .collect()
}

/// Every aggregate of every seed times `b`.
fn scaled(ad: &[Vec<f64>], b: f64) -> Vec<Vec<f64>> {
    ad.iter().map(|row| row.iter().map(|v| v * b).collect()).collect()
}

fn col(m: &[Vec<f64>], i: usize) -> Vec<f64> {
    m.iter().map(|r| r[i]).collect()
}

fn sum(parts: &[&[Vec<f64>]]) -> Vec<Vec<f64>> {
    (0..parts[0].len())
        .map(|k| {
            (0..parts[0][k].len())
                .map(|i| parts.iter().map(|p| p[k][i]).sum())
                .collect()
        })
        .collect()
}

/// The full derivative passes; the interior alone, the full derivative without its
/// secondary part (and without its primary part, when `primary_matters`) and, given `bias`,
/// the full derivative scaled by 1 ± `bias` fail. Returns the runs.
fn check(s: &Setup, primary_matters: bool, bias: Option<f64>) -> Runs {
    let r = s.run();
    let name = format!("{} {} ({:?})", s.scene, s.param, s.integrator);
    let full_ad = sum(&[&r.interior, &r.primary, &r.secondary]);
    let full = judge(&format!("{name} full"), &full_ad, &r);
    let mut failing = vec![
        (
            "the interior alone",
            judge(&format!("{name} interior alone"), &r.interior, &r),
        ),
        (
            "without the secondary term",
            judge(
                &format!("{name} without secondary"),
                &sum(&[&r.interior, &r.primary]),
                &r,
            ),
        ),
    ];
    if primary_matters {
        failing.push((
            "without the primary term",
            judge(
                &format!("{name} without primary"),
                &sum(&[&r.interior, &r.secondary]),
                &r,
            ),
        ));
    }
    let scaled = |b: f64| scaled(&full_ad, b);
    if std::env::var("FD_DEBUG").is_ok() {
        for b in [0.7, 0.8, 0.9, 1.1, 1.2, 1.3] {
            judge(&format!("{name} full × {b}"), &scaled(b), &r);
        }
    }
    for b in bias.map_or(vec![], |b| vec![1.0 - b, 1.0 + b]) {
        failing.push((
            "the full derivative scaled",
            judge(&format!("{name} full × {b}"), &scaled(b), &r),
        ));
    }
    assert!(
        full.passes(),
        "{name}: interior + boundary and FD disagree: Σz² = {:.1} (bound {:.1}), max|z| {:.1}",
        full.chi2,
        full.bound,
        full.zmax
    );
    // the relative bias fitted over every aggregate at once
    let reference = common::power::richardson_reference(&r.fd, &r.fd2);
    common::power::RelativeBias::fit(&full_ad, &reference, &fd_errors(&r)).assert_unbiased(&name);
    let mut fit_test = Test::default();
    fit_test.fit(full_ad.clone(), reference, fd_errors(&r), 4.0);
    // power audit (2026-12): 8.3 % (BDPT), 21 % (path tracer) on the floating ball, 37 % resting
    // on the floor, 48 % and 60 % for the liquid: heavy-tailed estimates through glass at
    // 20–30 s a test; glass_ball_pose_bdpt_resolves_four_percent resolves 2.9 % of the
    // floating ball's derivative, and the tests here check which terms are there
    full.power.or(fit_test.power()).exempt(
        &format!("{name} ({} seeds)", s.seeds),
        "refraction's heavy tails; the ball's size is glass_ball_pose_bdpt_resolves_four_percent's",
    );
    for (what, v) in &failing {
        assert!(
            !v.passes(),
            "{name}: {what} passes too (Σz² = {:.1}), so the test is too weak",
            v.chi2
        );
    }
    r
}

fn glass_ball(integrator: Option<IntegratorKind>) -> Setup {
    Setup {
        scene: "glass_pose.toml",
        param: "glass_x",
        value: 0.1,
        h: 0.03,
        seeds: 16,
        spp: 512,
        spp_boundary: 512,
        spp_fd: 512,
        spp_fd2: 512,
        bin_group: 4,
        pixels: false,
        integrator,
    }
}

/// With the path tracer the interior's derivative through the glass is heavy-tailed (light
/// reaches the floor through the ball by BSDF sampling only), so this run resolves only a
/// bias of about 20 % per aggregate: the full derivative × 1.3 fails, × 0.7 just does not
/// (Σz² 110.6 and 75.8 against a bound of 76.9, seeds 0..16). No scaled check here, then;
/// the BDPT test below has one.
///
/// Note (not about glass): with the 4 m floor this scene first had, the floor's far edge lay
/// right behind the ball's top silhouette, and there the primary-edge term came out 1.3–1.7
/// times the finite difference in three pixels (e.g. 0.82 against 0.48 at pixel (7, 3),
/// FD at h = 0.03 and 0.01 alike), for a diffuse ball too and in a diffuse-only scene, so
/// it is older than the dielectric support; the floor is 8 m wide now. Rechecked 2026-11-26
/// (tests/derivative_bias.rs, per pixel, diffuse ball on the 4 m floor, path tracer, 32
/// seeds, 2048-spp FD at h = 1 cm): Σz² 241 over 256 pixels, (7, 3) within 3.5 standard
/// errors, so the primary term agrees there; at h = 3 cm the same run gives Σz² 1062, from
/// pixels that a silhouette leaves within 2h, where Richardson's reference fails.
#[test]
fn glass_ball_pose_path_tracer() {
    check(&glass_ball(None), true, None);
}

/// BDPT: the full derivative × 0.8 and × 1.2 fail (Σz² 234.4 and 119.1 against 76.9; the
/// full derivative 18.0). With 128 boundary samples per pixel (before 2026-11-26) they failed
/// only just (87.6 and 114.5), and once the secondary edges' weights changed (other random
/// boundary rays, same expectation) × 1.2 passed at 48.6: 16 seeds of a heavy-tailed boundary
/// estimate sat ~8 % low. 512 samples keep the check's margin.
#[test]
fn glass_ball_pose_bdpt() {
    check(&glass_ball(Some(IntegratorKind::Bdpt)), true, Some(0.2));
}

/// The fitted relative bias (`relative_bias`) of the glass ball's full derivative (BDPT) must
/// vanish within 4 standard errors, and the full derivative scaled by 0.96 or 1.04 must not:
/// a 4 % bias fails (the tests above resolve 20 %). The fit runs over single pixels (and bin
/// groups), where the derivative's parts do not cancel as they do in 4×4 blocks, against
/// Richardson's reference from steps of 1 and 2 cm: at 3 and 6 cm that reference is off in
/// the pixels a silhouette leaves within the larger step (a diffuse ball, per pixel, 32
/// seeds: Σz² 1062 over 256 pixels at h = 3 cm, 241 at 1 cm).
///
/// History: the earlier form of this test (4×4 blocks, h = 3 cm, seeds 0..32) fitted the
/// full derivative 1.9 % low (z −2.0), an open question of the previous session. Measured
/// 2026-11-26 with tests/bias_probe.rs on seeds no test uses, the same fit over blocks gave
/// −0.75 % ± 0.64 % (seeds 1000..1064, h = 2 cm) and −0.24 % ± 0.53 % (seeds 2000..2128,
/// h = 3 cm), and the per-pixel fit at h = 1 cm −0.33 % ± 0.38 % (seeds 3000..3064, Σz² 261
/// over 256 pixels): no bias of the derivative at the 1 % level; seeds 0..32 sat low by
/// chance. The diffuse ball of the same scene fits −0.3 % ± 0.3 %.
#[test]
fn glass_ball_pose_bdpt_resolves_four_percent() {
    let s = Setup {
        h: 0.01,
        spp_boundary: 2048,
        spp_fd: 2048,
        spp_fd2: 1024,
        seeds: 32,
        pixels: true,
        ..glass_ball(Some(IntegratorKind::Bdpt))
    };
    let r = s.run();
    let full = sum(&[&r.interior, &r.primary, &r.secondary]);
    let v = judge("glass_pose.toml glass_x (BDPT, per pixel) full", &full, &r);
    assert!(
        v.passes(),
        "Σz² = {:.1} (bound {:.1}), max|z| {:.1}",
        v.chi2,
        v.bound,
        v.zmax
    );
    let z = |b: f64| {
        let (m, se) = relative_bias(&scaled(&full, b), &r);
        eprintln!(
            "full × {b}: relative bias {:.2} % ± {:.2} % (z {:.2})",
            100.0 * m,
            100.0 * se,
            m / se
        );
        m / se
    };
    let z_full = z(1.0);
    // the fit's power, with the per-pixel judge's
    let mut fit = Test::default();
    fit.fit(
        full.clone(),
        common::power::richardson_reference(&r.fd, &r.fd2),
        vec![0.0; full[0].len()],
        4.0,
    );
    v.power
        .or(fit.power())
        .assert_enough("glass_pose.toml glass_x (BDPT, per pixel, fit) (32 seeds)");
    assert!(
        z_full.abs() <= 4.0,
        "the full derivative's fitted relative bias is {z_full:.2} standard errors off"
    );
    for b in [0.96, 1.04] {
        let zb = z(b);
        assert!(
            zb.abs() > 4.0,
            "the full derivative × {b} passes too (z {zb:.2}): the test is too weak"
        );
    }
}

/// Contact: the glass ball resting on the floor at a point (scenes/glass_ball_floor.toml; a
/// glass face flush on the floor would be refused at load) slides sideways, with the path
/// tracer: the contact point, the shadow closing in on it and the light focused through the
/// ball onto the floor move with it. Same checks as the floating ball (the interior alone and
/// the full derivative without its primary or secondary part fail).
#[test]
fn glass_ball_resting_on_the_floor_pose_path_tracer() {
    check(
        &Setup {
            scene: "glass_ball_floor.toml",
            spp_boundary: 512,
            ..glass_ball(None)
        },
        true,
        None,
    );
}

fn liquid(integrator: Option<IntegratorKind>) -> Setup {
    Setup {
        scene: "liquid_pose.toml",
        param: "liquid_x",
        value: 0.05,
        h: 0.02,
        seeds: 16,
        spp: 256,
        spp_boundary: 64,
        spp_fd: 256,
        spp_fd2: 256,
        bin_group: 4,
        pixels: false,
        integrator,
    }
}

/// The liquid's edges are seen through the glass only (no primary term); the secondary
/// term's segments run inside the glass. Besides the checks of [`check`], the secondary term
/// moved two bin groups earlier (0.4 of OPL: what taking the scene's index 1 for the glass's
/// 1.5 does to a 0.8 m segment) must fail: the test sees the time of flight of the boundary
/// paths, not just their sum. Measured on the code itself (path tracer, seeds 0..16): the
/// secondary term with its segments in the scene's index instead of the glass's fails
/// (Σz² = 110 against a bound of 81), and so does the importance walk without its connection
/// to the pinhole through x_S's surface (the secondary term then vanishes: Σz² = 225, as the
/// interior alone).
fn check_liquid(integrator: Option<IntegratorKind>) {
    let s = liquid(integrator);
    let r = check(&s, false, None);
    let early = |row: &Vec<f64>| -> Vec<f64> {
        (0..row.len())
            .map(|i| {
                if i < 16 {
                    row[i]
                } else {
                    row.get(i + 2).copied().unwrap_or(0.0)
                }
            })
            .collect()
    };
    let shifted: Vec<Vec<f64>> = r.secondary.iter().map(early).collect();
    let v = judge(
        &format!("liquid_pose.toml ({integrator:?}): secondary 0.4 of OPL early"),
        &sum(&[&r.interior, &r.primary, &shifted]),
        &r,
    );
    assert!(
        !v.passes(),
        "a secondary term 0.4 of OPL early passes too (Σz² = {:.1})",
        v.chi2
    );
}

#[test]
fn liquid_in_glass_pose_path_tracer() {
    check_liquid(None);
}

#[test]
fn liquid_in_glass_pose_bdpt() {
    check_liquid(Some(IntegratorKind::Bdpt));
}
