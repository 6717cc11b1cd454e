//! The primary boundary term (src/boundary/primary.rs) closes the gap between the interior
//! derivative and central finite differences when a silhouette moves on the image.
//!
//! Each scene puts the point light at the camera with one bounce, so no shadow edge is seen
//! and the secondary boundary term vanishes (see the scene files). For each of K seeds the
//! interior derivative (render_diff), the primary term (render_primary) and central finite
//! differences with common random numbers (same seed, θ ± h) are aggregated two ways: the
//! time-summed image (one entry per pixel) and the per-bin totals (one entry per time bin).
//! D = interior + primary − FD must vanish within its standard error over seeds, widened by
//! the finite difference's own error (Richardson: (FD_2h − FD_h) / 3, plus f32 rounding):
//! Σ z² against its Student-t expectation and every |z| against a family-wise bound. The same
//! test applied to D = interior − FD must fail, which shows that the primary term matters.
//!
//! Where the derivative has a cusp in θ that the finite difference cannot resolve at a
//! testable h (the panel: [`Reference::Secant`]), FD_h is instead compared with what it equals
//! exactly, the mean of the derivative over [θ − h, θ + h], by Simpson's rule on derivative
//! renders across the interval.

use crate::common;
use common::power::{Entry, Power, Test};
use difftransient::accel::Device;
use difftransient::boundary::primary::render_primary;
use difftransient::integrator::RenderContext;
use difftransient::params::lanes::Motion;
use difftransient::render::thread_pool;
use difftransient::{BoundaryMode, RenderOptions, Scene, Transient, render, render_diff};
use glam::DVec3;

/// The usual settings: 12 seeds, 16 spp for the interior, 256 for the finite differences,
/// 8 boundary samples per pixel, Richardson's reference at the tangent.
impl Case {
    fn tangent(scene: &'static str, param: &'static str, value: f32, h: f32) -> Self {
        Case {
            scene,
            param,
            value,
            h,
            seeds: 12,
            spp: 16,
            spp_fd: 256,
            spp_boundary: 8,
            reference: Reference::Tangent,
        }
    }
}

struct Case {
    scene: &'static str,
    param: &'static str,
    value: f32,
    h: f32,
    seeds: u64,
    /// Samples per pixel of the interior derivative.
    spp: u32,
    /// Samples per pixel of the finite differences (more: they see a silhouette only through
    /// the few samples in the swept strip).
    spp_fd: u32,
    spp_boundary: u32,
    reference: Reference,
}

/// What the central difference FD_h = (I(θ + h) − I(θ − h)) / 2h is compared with.
#[derive(Clone, Copy, PartialEq)]
enum Reference {
    /// The derivative at θ; FD_h's truncation error is estimated by Richardson,
    /// (FD_2h − FD_h) / 3, which holds while I is smooth on the scale of 2h.
    Tangent,
    /// The mean of the derivative over [θ − h, θ + h], which FD_h equals for any h (I is the
    /// integral of its derivative, boundary term included): composite Simpson on 9 derivative
    /// renders at θ + k·h/4, k = −4 … 4, its error estimated as (S₉ − S₅) / 15 from the 5
    /// renders at even k. For a derivative with a cusp at θ, where FD_h converges at first
    /// order and only once h is far below the cusp's width.
    Secant,
}

fn opts(spp: u32, seed: u64) -> RenderOptions {
    RenderOptions {
        // the interior alone: this file adds the primary term itself, from `render_primary`
        boundary: BoundaryMode::InteriorOnly,
        ..common::options(spp, seed)
    }
}

fn load(case: &Case, value: Option<f32>) -> Scene {
    let set: Vec<(String, f64)> = value
        .map(|v| vec![(case.param.to_string(), v as f64)])
        .unwrap_or_default();
    Scene::load(&common::scene_path(case.scene), &set).unwrap()
}

/// Side of the pixel blocks the time-summed image is summed over: a finite difference across
/// a silhouette is a rare event per pixel (only samples in the swept strip change), and sums
/// over blocks make its standard error reliable.
const BLOCK: usize = 4;

/// Time-summed image in BLOCK × BLOCK sums, followed by per-bin totals.
fn aggregate(t: &Transient) -> Vec<f64> {
    let (bw, bh) = (t.width.div_ceil(BLOCK), t.height.div_ceil(BLOCK));
    let mut v = vec![0.0f64; bw * bh];
    for y in 0..t.height {
        for x in 0..t.width {
            v[(y / BLOCK) * bw + x / BLOCK] += t.time_sum(x, y, 0) as f64;
        }
    }
    v.extend(t.bin_totals().into_iter().map(f64::from));
    v
}

fn primary_on(scene: &Scene, params: &[&str], spp_boundary: u32, seed: u64, threads: usize) -> Vec<Transient> {
    let device = Device::new("").unwrap();
    let mut ctx = RenderContext::new(scene, &device).unwrap();
    let names: Vec<String> = params.iter().map(|p| p.to_string()).collect();
    ctx.motion = Motion::build(scene, &names).unwrap();
    let pool = thread_pool(Some(threads)).unwrap();
    render_primary(&ctx, spp_boundary, seed, &pool)
}

fn primary(scene: &Scene, param: &str, spp_boundary: u32, seed: u64) -> Transient {
    primary_on(scene, &[param], spp_boundary, seed, 2).remove(0)
}

/// Central difference of the aggregates, and f32 rounding of the film scaled like it.
fn central(plus: &Scene, minus: &Scene, spp: u32, seed: u64, step: f32) -> (Vec<f64>, Vec<f64>) {
    let p = aggregate(&render(plus, &opts(spp, seed)).unwrap().0);
    let m = aggregate(&render(minus, &opts(spp, seed)).unwrap().0);
    let scale = 1.0 / (2.0 * step as f64);
    let fd = p.iter().zip(&m).map(|(a, b)| (a - b) * scale).collect();
    let rounding = p
        .iter()
        .zip(&m)
        .map(|(a, b)| 4.0 * f32::EPSILON as f64 * (a.abs() + b.abs()) * scale)
        .collect();
    (fd, rounding)
}

/// Σ z², max |z| and the number of entries of D = mean over seeds of `diffs`, each entry's
/// standard error widened by `fd_err`.
fn z_test(diffs: &[Vec<f64>], fd_err: &[f64]) -> (f64, f64, usize) {
    let (mut chi2, mut zmax, mut n) = (0.0, 0.0f64, 0);
    for (i, err) in fd_err.iter().enumerate() {
        let col: Vec<f64> = diffs.iter().map(|d| d[i]).collect();
        let (m, se) = common::mean_se(&col);
        let sd = (se * se + err * err).sqrt();
        if sd == 0.0 {
            assert_eq!(m, 0.0, "entry {i}: exact disagreement");
            continue;
        }
        let z = m / sd;
        chi2 += z * z;
        zmax = zmax.max(z.abs());
        n += 1;
    }
    (chi2, zmax, n)
}

/// The power of [`z_test`]'s assertions (Σz² ≤ `bound`, every |z| ≤ 8) on `diffs`, whose
/// derivative is `ads` (seed × entry).
fn z_test_power(diffs: &[Vec<f64>], ads: &[Vec<f64>], fd_err: &[f64], bound: f64) -> Power {
    let col = |m: &[Vec<f64>], i: usize| -> Vec<f64> { m.iter().map(|d| d[i]).collect() };
    let entries: Vec<Entry> = (0..fd_err.len())
        .filter_map(|i| {
            let (_, se) = common::mean_se(&col(diffs, i));
            let sd = (se * se + fd_err[i] * fd_err[i]).sqrt();
            (sd > 0.0).then(|| Entry::new(col(diffs, i), col(ads, i), fd_err[i]))
        })
        .collect();
    Test::default()
        .sum_of_squares(entries.clone(), bound)
        .every(entries, 8.0)
        .power()
}

/// Upper bound for Σ z² over n entries: Student t with ν dof has E[t²] = ν/(ν−2) and
/// Var[t²] = 2ν²(ν−1)/((ν−2)²(ν−4)); mean + 5 sd.
fn chi2_bound(n: usize, seeds: u64) -> f64 {
    let (n, nu) = (n as f64, (seeds - 1) as f64);
    let mean = n * nu / (nu - 2.0);
    let var = n * 2.0 * nu * nu * (nu - 1.0) / ((nu - 2.0).powi(2) * (nu - 4.0));
    mean + 5.0 * var.sqrt()
}

/// Interior and interior + primary aggregates of the derivative at `scene` for one seed.
fn derivative(case: &Case, scene: &Scene, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let (_, ad, _) = render_diff(scene, &[case.param.to_string()], &opts(case.spp, seed)).unwrap();
    let interior = aggregate(&ad[0]);
    let prim_t = primary(scene, case.param, case.spp_boundary, seed);
    assert_eq!(prim_t.non_finite_count(), 0);
    assert!(prim_t.data.iter().any(|&v| v != 0.0), "the primary term is empty");
    let full = interior.iter().zip(aggregate(&prim_t)).map(|(i, p)| i + p).collect();
    (interior, full)
}

/// Composite Simpson means over [θ − h, θ + h] of `f` given at θ + k·h/4 (k = −4 … 4): the
/// 9-node rule and its error estimate (S₉ − S₅) / 15, S₅ from the even nodes.
fn simpson(f: &[Vec<f64>]) -> (Vec<f64>, Vec<f64>) {
    const W9: [f64; 9] = [1.0, 4.0, 2.0, 4.0, 2.0, 4.0, 2.0, 4.0, 1.0];
    const W5: [f64; 5] = [1.0, 4.0, 2.0, 4.0, 1.0];
    (0..f[0].len())
        .map(|i| {
            let s9 = (0..9).map(|k| W9[k] * f[k][i]).sum::<f64>() / 24.0;
            let s5 = (0..5).map(|k| W5[k] * f[2 * k][i]).sum::<f64>() / 12.0;
            (s9, (s9 - s5) / 15.0)
        })
        .unzip()
}

fn check(case: &Case) {
    let base = load(case, None);
    let (v, h) = (case.value, case.h);
    let (plus, minus) = (load(case, Some(v + h)), load(case, Some(v - h)));
    let (plus2, minus2) = (load(case, Some(v + 2.0 * h)), load(case, Some(v - 2.0 * h)));
    // θ + k·h/4, k = −4 … 4 (k = ±4 are θ ± h exactly: ×4 and ÷4 are exact in f32)
    let nodes: Vec<Scene> = match case.reference {
        Reference::Tangent => Vec::new(),
        Reference::Secant => (-4..=4).map(|k| load(case, Some(v + h * k as f32 / 4.0))).collect(),
    };
    let (mut d_full, mut d_int, mut ref_err) = (Vec::new(), Vec::new(), Vec::new());
    let (mut ads, mut references) = (Vec::new(), Vec::new());
    let mut round = Vec::new();
    for seed in 0..case.seeds {
        let (fd, rounding) = central(&plus, &minus, case.spp_fd, seed, h);
        round = rounding;
        let (interior, full, err) = match case.reference {
            Reference::Tangent => {
                let (interior, full) = derivative(case, &base, seed);
                let (fd2, _) = central(&plus2, &minus2, case.spp_fd, seed, 2.0 * h);
                let rich = fd2.iter().zip(&fd).map(|(a, b)| (a - b) / 3.0).collect();
                references.push(
                    fd.iter()
                        .zip(&fd2)
                        .map(|(a, b)| (4.0 * a - b) / 3.0)
                        .collect::<Vec<_>>(),
                );
                (interior, full, rich)
            }
            Reference::Secant => {
                let (ints, fulls): (Vec<_>, Vec<_>) = nodes.iter().map(|s| derivative(case, s, seed)).unzip();
                let (interior, _) = simpson(&ints);
                let (full, quad) = simpson(&fulls);
                // FD_h is the Simpson mean's estimate, no extrapolation
                references.push(fd.clone());
                (interior, full, quad)
            }
        };
        ref_err.push(err);
        d_full.push((0..fd.len()).map(|i| full[i] - fd[i]).collect::<Vec<_>>());
        ads.push(full.clone());
        d_int.push((0..fd.len()).map(|i| interior[i] - fd[i]).collect::<Vec<_>>());
    }
    let fd_err: Vec<f64> = (0..round.len())
        .map(|i| {
            let col: Vec<f64> = ref_err.iter().map(|r| r[i]).collect();
            let (m, se) = common::mean_se(&col);
            m.abs() + 2.0 * se + round[i]
        })
        .collect();
    let (chi2, zmax, n) = z_test(&d_full, &fd_err);
    let (chi2_i, zmax_i, _) = z_test(&d_int, &fd_err);
    let bound = chi2_bound(n, case.seeds);
    eprintln!(
        "{}: interior + primary Σz² = {chi2:.1} (max |z| {zmax:.2}); interior alone Σz² = {chi2_i:.1} \
         (max |z| {zmax_i:.2}); bound {bound:.1} over {n} entries",
        case.param
    );
    assert!(chi2 <= bound, "{}: interior + primary disagrees with FD", case.param);
    // family-wise over ≤ 1000 entries: P(|t₁₁| > 8) ≈ 4e-6 each
    assert!(zmax <= 8.0, "{}: an entry is {zmax:.1} standard errors off", case.param);
    // the relative bias fitted over every aggregate at once
    common::power::RelativeBias::fit(&ads, &references, &fd_err).assert_unbiased(case.param);
    let mut fit_test = Test::default();
    fit_test.fit(ads.clone(), references.clone(), fd_err.clone(), 4.0);
    z_test_power(&d_full, &ads, &fd_err, bound)
        .or(fit_test.power())
        .assert_enough(&format!(
            "{} {} ({} seeds, FD {} spp)",
            case.scene, case.param, case.seeds, case.spp_fd
        ));
    assert!(
        chi2_i > bound,
        "{}: the interior alone already matches FD, so this scene does not test the primary term",
        case.param
    );
    if case.reference == Reference::Secant {
        // and it sees a primary term 3 % off (Σz² 5851–9628 at seed bases 0, 100, …, 500)
        for scale in [0.97, 1.03] {
            let d: Vec<Vec<f64>> = d_full
                .iter()
                .zip(&d_int)
                .map(|(f, i)| f.iter().zip(i).map(|(f, i)| i + scale * (f - i)).collect())
                .collect();
            let (chi2_s, _, _) = z_test(&d, &fd_err);
            eprintln!("{}: primary term × {scale}: Σz² = {chi2_s:.1}", case.param);
            assert!(chi2_s > bound, "{}: a primary term × {scale} passes", case.param);
        }
    }
}

#[test]
fn sliding_cube_silhouette_matches_finite_differences() {
    check(&Case::tangent("silhouette_slide.toml", "cube_x", 0.1, 0.01));
}

#[test]
fn approaching_plate_matches_finite_differences() {
    check(&Case::tangent("plate_approach.toml", "plate_z", 0.0, 0.01));
}

#[test]
fn turning_obj_pyramid_matches_finite_differences() {
    check(&Case::tangent("pyramid_turn.toml", "pyramid_yaw", 30.0, 1.0));
}

#[test]
fn stretching_obj_pyramid_matches_finite_differences() {
    check(&Case::tangent("pyramid_turn.toml", "pyramid_height", 0.5, 0.01));
}

/// Same seed, same bytes, for 1 and 2 threads (chunks merged in a fixed order); another seed
/// gives another estimate. Two parameters at once give each its own film, equal to rendering
/// it alone, and a parameter that moves nothing gets zeros.
#[test]
fn primary_term_is_deterministic_and_per_parameter() {
    let scene = common::load("pyramid_turn.toml");
    let both = primary_on(&scene, &["pyramid_yaw", "pyramid_height"], 2, 7, 1);
    assert_eq!(both, primary_on(&scene, &["pyramid_yaw", "pyramid_height"], 2, 7, 2));
    // 13 threads bin in 13 bands of rows instead of 8: the same bytes
    assert_eq!(both, primary_on(&scene, &["pyramid_yaw", "pyramid_height"], 2, 7, 13));
    assert_ne!(both[0].data, primary_on(&scene, &["pyramid_yaw"], 2, 8, 2)[0].data);
    assert_eq!(both[1], primary_on(&scene, &["pyramid_height"], 2, 7, 2)[0]);
    assert!(
        both.iter()
            .all(|t| t.non_finite_count() == 0 && t.data.iter().any(|&v| v != 0.0))
    );
    let room = common::load("diff_room.toml");
    let none = primary_on(&room, &["albedo"], 2, 7, 2);
    assert!(none[0].data.iter().all(|&v| v == 0.0));
}

/// Creases seen from inside a closed mesh (back-facing edges that are not hidden).
#[test]
fn room_corner_creases_match_finite_differences() {
    check(&Case::tangent("room_corner.toml", "room_x", 0.0, 0.01));
}

/// Edges crossing the camera's plane are clipped at the near plane and to the film.
///
/// At panel_x = −0.6 the panel's top edge projects onto the image diagonal, through the
/// top-left corner, the farthest point seen: the bins of the pulse's tail past the latest
/// arrivals (86–93) hold only light from around that corner, and their derivative has a cusp
/// in panel_x there (FD_h is the mean of the derivative over [θ − h, θ + h]: bin 93's was
/// −0.64, −1.11, −1.60, −1.96 ·10⁻¹⁴ at h = 0.02 … 0.0025, against the primary term's −2.40,
/// as (1 − e^{−λh}) / λh with λ ≈ 170–185), so the check compares FD_h with that mean
/// ([`Reference::Secant`]). Finite differences at 1024 spp: a block beside the panel's far
/// corner changes only through the few samples the far edge sweeps there, which 256 spp ×
/// 12 seeds often miss altogether (a standard error of 0). Passed at seed bases 0, 100, …,
/// 500 (Σz² 142–182 against 261.5, max |z| ≤ 5.0), about 15 s.
#[test]
fn panel_crossing_the_camera_plane_matches_finite_differences() {
    check(&Case {
        scene: "near_plane_panel.toml",
        param: "panel_x",
        value: -0.6,
        h: 0.01,
        seeds: 12,
        spp: 16,
        spp_fd: 1024,
        spp_boundary: 8,
        reference: Reference::Secant,
    });
}

/// A flat-shaded ball: faces beside its silhouette are seen nearly edge-on, so creases lie
/// within a thousandth of a pixel of the silhouette and back creases millimetres behind it.
/// With fixed side offsets and a relative visibility margin the primary term counted the
/// silhouette's jump again at such creases (1.2–1.8× the finite difference in some pixels).
#[test]
fn sliding_ball_silhouette_matches_finite_differences() {
    check(&Case::tangent("ball_slide.toml", "ball_x", 0.1, 0.01));
}

/// An edge projected exactly onto the line between two pixels (the plate's left edge on the
/// line between the middle columns, scenes/edge_on_pixel_boundary.toml): each column's value
/// has a kink in θ, and the derivative is the mean of its one-sided derivatives, what the
/// central difference estimates, with the edge counting half in each column
/// (`FilterSampler::density`). Blocks of 4 columns part exactly on that line. With the whole
/// term in the upper column, an independent sweep saw z = −29 and +33 on a faceted ball's
/// creases there.
#[test]
fn an_edge_on_the_line_between_two_pixels_counts_half_in_each() {
    check(&Case::tangent("edge_on_pixel_boundary.toml", "plate_x", 0.25, 0.01));
}

/// The ball's limbs in time: the light of a limb arrives last (bins 8–11 of ball_slide.toml,
/// OPL 5.8–6.2 m), and its derivative there is the small sum of an interior and a primary
/// term of about ±2.5 each, of opposite signs at the two limbs. The primary term's side
/// paths started where each side ray met its surface, ε beside the edge: on a face seen
/// nearly edge-on that point lies far along the face in depth (up to half its sliver), so
/// the inside's light was binned late. Summed over the image the two limbs cancel (the
/// check above passed); per limb the derivative was 2–4× the finite difference in those
/// bins, with the wrong sign at the right limb (an independent sweep, 2026-11-30). The side
/// paths now start where the edge's own ray meets each side's surface (the limit ε → 0,
/// `PrimaryRays::limit`). Statistic: bins 8–11 summed over the image's left part minus its
/// right part (about −1.10), AD − FD over 16 seeds, FD at 1024 spp.
#[test]
fn a_balls_limbs_send_their_light_to_the_bins_it_arrives_in() {
    let path = common::scene_path("ball_slide.toml");
    let at = |v: f64| Scene::load(&path, &[("ball_x".to_string(), v)]).unwrap();
    // FD at h = 0.02 and 0.01 (its truncation is still quadratic there; at 0.005 the FD's
    // noise swamps the statistic)
    let (scene, h) = (at(0.1), 0.02);
    let (plus, minus, plus2, minus2) = (at(0.1 + h), at(0.1 - h), at(0.1 + h / 2.0), at(0.1 - h / 2.0));
    // the ball's centre projects to column 13.5 of 24: left of 13 against right of 14
    let statistic = |t: &Transient| -> f64 {
        let mut s = 0.0f64;
        for y in 0..t.height {
            for x in (0..13).chain(14..t.width) {
                let sign = if x < 13 { 1.0 } else { -1.0 };
                s += sign * (8..12).map(|l| t.at(x, y, l, 0) as f64).sum::<f64>();
            }
        }
        s
    };
    let (mut d, mut trunc, mut ads) = (Vec::new(), Vec::new(), Vec::new());
    for seed in 0..16 {
        let o = |spp: u32| common::options(spp, 7000 + seed);
        let ad = statistic(&render_diff(&scene, &["ball_x".to_string()], &o(256)).unwrap().1[0]);
        let fd = |p: &Scene, m: &Scene, h: f64| {
            (statistic(&render(p, &o(1024)).unwrap().0) - statistic(&render(m, &o(1024)).unwrap().0)) / (2.0 * h)
        };
        let (fd_h, fd_half) = (fd(&plus, &minus, h), fd(&plus2, &minus2, h / 2.0));
        d.push(ad - fd_h);
        ads.push(ad);
        // Richardson: FD_h's truncation error is about (4/3)(FD_h − FD_h/2)
        trunc.push(4.0 / 3.0 * (fd_h - fd_half));
    }
    let (m, se) = common::mean_se(&d);
    let (t, t_se) = common::mean_se(&trunc);
    let allowed = 4.0 * (se * se + t_se * t_se).sqrt() + t.abs();
    let ad_mean = common::mean_se(&ads).0;
    eprintln!("AD {ad_mean:.4}: AD − FD = {m:.4} ± {se:.4}, truncation {t:.4} ± {t_se:.4}, allowed {allowed:.4}");
    Test::default()
        .one(Entry {
            scale: 4.0,
            add: t.abs(),
            ..Entry::new(d.clone(), ads.clone(), t_se)
        })
        .power()
        .exempt(
            "ball_slide.toml ball_x limbs' late bins (16 seeds)",
            "resolves 5.4 % of a small difference of two limbs' terms (39 s at 16 seeds); \
             sliding_ball_silhouette_matches_finite_differences resolves 2.4 % of the whole",
        );
    assert!(
        m.abs() <= allowed,
        "limbs' late bins, left − right: AD {:.4}, AD − FD = {m:.4} ± {se:.4} (FD truncation {t:.4} ± {t_se:.4}), allowed {allowed:.4}",
        ad_mean
    );
}

/// A background seen edge-on behind a silhouette (scenes/grazing_floor_edge.toml): below the
/// hovering cube's front bottom edge the eye sees the floor 16 m away, at 89.3° from its
/// normal. The floor side of the edge's jump arrives where the edge's own ray meets the floor:
/// in each of the edge's pixels the derivative's OPL centroid (over the window, which holds
/// the floor's light only) is that point's round trip from the eye to the lamp, averaged over
/// the pixel's stretch of edge, and over the edge's middle pixels it matches finite
/// differences. Before, the floor side took the OPL of its side ray's hit, a thousandth of a
/// pixel away and 7 mm nearer in depth: 28 mm early against the geometry (1e-5 m after), and
/// z = −31 against finite differences (h = 1e-4, 16 seeds at 1024 spp).
#[test]
fn a_background_seen_edge_on_sends_its_light_to_the_bins_it_arrives_in() {
    let path = common::scene_path("grazing_floor_edge.toml");
    let at = |v: f64| Scene::load(&path, &[("box_y".to_string(), v)]).unwrap();
    let (scene, h) = (at(0.275), 1e-4);
    let axis = scene.film.axis;
    let opl = |l: usize| axis.start_opl + axis.bin_width_opl * (l as f64 + 0.5);
    // the edge crosses film row 9; columns 12–19 lie within 0.1 m of the middle
    let (row, columns) = (9, 12..20);
    // (first moment, total) of the pixels' derivatives over the window
    let moments = |t: &Transient, xs: std::ops::Range<usize>| -> (f64, f64) {
        let (mut m1, mut m0) = (0.0, 0.0);
        for x in xs {
            for l in 0..t.axis.bins {
                let v = t.at(x, row, l, 0) as f64;
                m1 += v * opl(l);
                m0 += v;
            }
        }
        (m1, m0)
    };
    let ad = render_diff(&scene, &["box_y".to_string()], &common::options(64, 1))
        .unwrap()
        .1
        .remove(0);
    // the geometry: the edge y = 0.175, z = −2 seen from the eye (0, 0.2, 0) meets the floor
    // at 8 times its distance; the lamp at (0, 1, 0); square pixels of a 10° vertical view
    let pixel = 2.0 * (5.0f64).to_radians().tan() / 8.0;
    let (eye, lamp) = (DVec3::new(0.0, 0.2, 0.0), DVec3::new(0.0, 1.0, 0.0));
    for x in columns.clone() {
        let (m1, m0) = moments(&ad, x..x + 1);
        let steps = 1000;
        let expected = (0..steps)
            .map(|i| {
                let e = (x as f64 + (i as f64 + 0.5) / steps as f64 - 16.0) * pixel;
                let floor = eye + (DVec3::new(e, 0.175, -2.0) - eye) * 8.0;
                (floor - eye).length() + (lamp - floor).length()
            })
            .sum::<f64>()
            / steps as f64;
        assert!(
            (m1 / m0 - expected).abs() < 1e-3,
            "column {x}: the derivative's centroid at {:.5} m of OPL, the edge's floor point at {expected:.5} m",
            m1 / m0
        );
    }
    let (m1, m0) = moments(&ad, columns.clone());
    let centroid = m1 / m0;
    let (plus, minus) = (at(0.275 + h), at(0.275 - h));
    let fd: Vec<f64> = (0..16)
        .map(|seed| {
            let (p, m) = (
                render(&plus, &common::options(1024, seed)).unwrap().0,
                render(&minus, &common::options(1024, seed)).unwrap().0,
            );
            let ((p1, p0), (q1, q0)) = (moments(&p, columns.clone()), moments(&m, columns.clone()));
            (p1 - q1) / (p0 - q0)
        })
        .collect();
    let (f, se) = common::mean_se(&fd);
    eprintln!("centroid: AD {centroid:.5} m, FD {f:.5} ± {se:.5} m");
    // no truncation shows at this noise: FD at h = 5e-5 differed by 1.0 ± 1.1 mm
    assert!(
        (centroid - f).abs() <= 4.0 * se,
        "the derivative's centroid {centroid:.5} m against FD {f:.5} ± {se:.5} m"
    );
}

/// The pose demo's plate (scenes/pose_plate.toml) sliding and turning in its plane: the
/// gradient is all primary term (the plate's shading does not change, and its shadow lies
/// behind it: tests/secondary_fd.rs checks that the secondary term adds nothing there). At
/// this strength (FD at 256 spp, 12 seeds, Richardson's error) a primary term 3 % too large
/// fails (`plate_x`: Σz² = 1697 against a bound of 224), which the full-gradient test there
/// is too coarse to see.
#[test]
fn the_pose_plate_matches_finite_differences() {
    for (param, value, h) in [("plate_x", 0.1, 0.02), ("plate_roll", 20.0, 1.0)] {
        check(&Case::tangent("pose_plate.toml", param, value, h));
    }
}

/// A dark cube resting on a floor (scenes/resting_box.toml), sliding and turning on it: the
/// edges of its bottom face lie on the floor, and where the eye sees one, its ray meets the
/// floor and the cube's face at the same point. The primary term took a floor hit that
/// rounding put a hair in front of the edge point for an occluder and skipped the point: in
/// the pixels along the seen contact edges it came out about a third short (`box_x`: Σz² =
/// 3874 against a bound of 172 before the fix, 24 after; 2026-11-29).
#[test]
fn a_box_resting_on_the_floor_matches_finite_differences() {
    resting_box_check("resting_box.toml");
}

/// The same cube sunk 5 µm into the floor, less than the 2ε within which the boundary stage
/// takes the floor for its bottom edges' support (src/boundary/interpenetration.rs refuses
/// deeper crossings). Seen from the camera, the floor is met 5 µm / sin(elevation) before the
/// bottom edge's points, more than 2ε along the ray; taking that for an occluder skipped them
/// (Σz² = 20885 against 172 for `box_x`), so the support is judged by the distance to the
/// floor's plane.
#[test]
fn a_box_sunk_less_than_the_contact_tolerance_matches_finite_differences() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(common::scene_path("resting_box.toml")).unwrap();
    let sunk = text.replace("translate = [0.1, 0.2, 0.0]", "translate = [0.1, 0.199995, 0.0]");
    assert_ne!(sunk, text);
    let path = dir.path().join("sunk_box.toml");
    std::fs::write(&path, sunk).unwrap();
    // an absolute name replaces the scenes folder in `common::scene_path`
    resting_box_check(Box::leak(path.to_string_lossy().into_owned().into_boxed_str()));
}

fn resting_box_check(scene: &'static str) {
    for (param, value, h) in [("box_x", 0.1, 0.01), ("box_yaw", 30.0, 1.0)] {
        check(&Case::tangent(scene, param, value, h));
    }
}

/// A unit cube [−1, 1]³ as OBJ text: the cube of `scenes/meshes` style with its front face
/// (z = 1) fanned from a vertex on its bottom edge that the bottom face does not share (a
/// T-junction) when `t_junction`, and every triangle given its own three vertices (a triangle
/// soup, as an STL file or an OBJ with per-face normals reads) when `soup`.
fn cube_obj(t_junction: bool, soup: bool) -> String {
    let mut v = vec![
        [-1.0, -1.0, -1.0],
        [1.0, -1.0, -1.0],
        [1.0, 1.0, -1.0],
        [-1.0, 1.0, -1.0],
        [-1.0, -1.0, 1.0],
        [1.0, -1.0, 1.0],
        [1.0, 1.0, 1.0],
        [-1.0, 1.0, 1.0],
    ];
    let mut f: Vec<[usize; 3]> = vec![
        [1, 4, 3],
        [1, 3, 2],
        [1, 5, 8],
        [1, 8, 4],
        [2, 3, 7],
        [2, 7, 6],
        [1, 2, 6],
        [1, 6, 5],
        [4, 8, 7],
        [4, 7, 3],
    ];
    if t_junction {
        v.push([0.2, -1.0, 1.0]);
        f.extend([[5, 9, 8], [9, 7, 8], [9, 6, 7]]);
    } else {
        f.extend([[5, 6, 7], [5, 7, 8]]);
    }
    let (v, f): (Vec<[f64; 3]>, Vec<[usize; 3]>) = if soup {
        let loose = f.iter().flat_map(|t| t.map(|i| v[i - 1])).collect();
        (loose, (0..f.len()).map(|k| [3 * k + 1, 3 * k + 2, 3 * k + 3]).collect())
    } else {
        (v, f)
    };
    let mut text = String::new();
    for p in v {
        text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for t in f {
        text += &format!("f {} {} {}\n", t[0], t[1], t[2]);
    }
    text
}

/// A cube turned about all three axes in front of a wall (scenes/pyramid_turn.toml with the
/// pyramid replaced), loaded from an OBJ whose front face has a T-junction, and from the same
/// cube as a triangle soup. Each bottom-front or crease edge was listed once per side as two
/// open edges, each taken for a silhouette, so its term was counted twice: `pyramid_yaw` Σz² =
/// 894 for the T-junction and 37666 for the soup before `boundary/seams.rs` (the interior alone:
/// 39109), against a bound of 183; 29.4 and 29.5 after (2026-11-29).
#[test]
fn an_unwelded_mesh_and_a_t_junction_match_finite_differences() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(common::scene_path("pyramid_turn.toml")).unwrap();
    for (name, t_junction, soup) in [("t_junction", true, false), ("soup", false, true)] {
        let obj = dir.path().join(format!("{name}.obj"));
        std::fs::write(&obj, cube_obj(t_junction, soup)).unwrap();
        let scene = text
            .replace(
                "file = \"meshes/pyramid.obj\"",
                &format!("file = {:?}", obj.to_string_lossy()),
            )
            .replace("translate = [0.0, 0.0, 0.0]", "translate = [0.0, 0.3, 0.0]")
            .replace("rotate = [0.0, 30.0, 0.0]", "rotate = [25.0, 30.0, 15.0]")
            .replace("scale = 0.5", "scale = [0.3, 0.3, 0.3]")
            .replace("axis = \"y\"\nvalue = 0.5", "axis = \"y\"\nvalue = 0.3");
        assert!(scene.contains("translate = [0.0, 0.3, 0.0]") && scene.contains("value = 0.3"));
        assert!(scene.contains("[25.0, 30.0, 15.0]") && scene.contains(&format!("{name}.obj")));
        let path = dir.path().join(format!("{name}.toml"));
        std::fs::write(&path, scene).unwrap();
        let path: &'static str = Box::leak(path.to_string_lossy().into_owned().into_boxed_str());
        check(&Case::tangent(path, "pyramid_yaw", 30.0, 1.0));
    }
}

/// A pulse far narrower than the bins has the film carry f64 OPLs (`integrator::opl`), and a
/// primary edge's side ray that met no surface then asked for the face of triangle u32::MAX:
/// `dtr render silhouette_slide.toml --diff cube_x` panicked for σ ≤ 3 mm (index out of
/// bounds in `face_normal64`; found by an independent sweep). All of the scene's light lies
/// in its window, so the time-summed derivative does not depend on the pulse: at σ = 1 mm it
/// is σ = 5 mm's (no f64 OPLs there) within f32 rounding, pixel by pixel, for each seed.
#[test]
fn a_narrow_pulse_leaves_the_time_summed_silhouette_derivative_as_it_was() {
    use difftransient::temporal::Pulse;
    let derivative = |sigma: f32, seed: u64| {
        let mut scene = common::load("silhouette_slide.toml");
        for e in &mut scene.emitters {
            e.pulse = Pulse::Gaussian { sigma_opl: sigma };
        }
        let opts = RenderOptions {
            spp_boundary: Some(16),
            ..common::options(16, seed)
        };
        let (_, d, _) = render_diff(&scene, &["cube_x".to_string()], &opts).unwrap();
        d.into_iter().next().unwrap()
    };
    for seed in 1..=3 {
        let (narrow, wide) = (derivative(0.001, seed), derivative(0.005, seed));
        let image = |t: &Transient| -> Vec<f32> {
            (0..t.height)
                .flat_map(|y| (0..t.width).map(move |x| (x, y)))
                .map(|(x, y)| t.time_sum(x, y, 0))
                .collect()
        };
        let (a, b) = (image(&narrow), image(&wide));
        let scale = b.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        assert!(
            scale > 0.1,
            "seed {seed}: the silhouette's derivative is missing ({scale})"
        );
        for (i, (p, q)) in a.iter().zip(&b).enumerate() {
            assert!(
                p.is_finite() && (p - q).abs() <= 1e-5 * scale,
                "seed {seed} pixel {i}: {p} at σ = 1 mm against {q} at 5 mm"
            );
        }
    }
}

/// The pose plate (scenes/pose_plate.toml) as an OBJ whose bottom border an exporter split
/// with a vertex a hair inside the line (`width` of the plate's half-size): a sliver triangle
/// along the silhouette, its two inner edges coplanar with their neighbours. The surface is
/// the rectangle's, so the boundary term must be the rectangle's. The side ray on the sliver
/// was shortened to half its width, below what f32 film points and directions resolve near
/// its corners, and saw the background: the sweep that found it measured the full derivative
/// 2.5 % short at a width of 10⁻⁵ and 14 % at 10⁻⁶ (`plate_roll`); here, before the fix,
/// `plate_x` at 10⁻⁵ gave Σz² = 3204 against a bound of 176 (max |z| 13). Walking the side
/// offset on into the coplanar neighbour, the side path also has to take that neighbour for
/// the edge's own face (start at the edge's limit): from the side ray's hit it was 10⁻⁴ short
/// (`plate_x`, z = −306). The plate is then turned about all three axes: rounding tilts the
/// sliver's f32 normal past the coplanar angle, its inner edges stood as creases, and the
/// shadow's term (secondary edges) went off in the blocks along them (a second sweep: one
/// block 7 standard errors off); here the whole boundary term, before the fix of
/// `edges::within_rounding`, gave Σz² = 7880 for `plate_roll` at 10⁻⁵ (max |z| 36) against
/// a bound of 176; 19.7 after. Per 4 × 4 block of the time-summed
/// image and per bin, the sliver plate's mean against the rectangle's (independent samples; a
/// floor of 10⁻⁵ of the value for the f32 films' rounding): Σz² within its bound, and the
/// standard errors small enough that a bias of 2.5 % on every entry would exceed four times
/// that bound.
#[test]
fn a_sliver_triangle_along_a_silhouette_leaves_its_term_whole() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(common::scene_path("pose_plate.toml")).unwrap();
    let rectangle = "name = \"plate\"\ntype = \"rectangle\"";
    let (flat, tilted) = ("rotate = [0.0, 0.0, 20.0]", "rotate = [35.0, 25.0, 20.0]");
    assert!(text.contains(rectangle) && text.contains(flat));
    // the plate as the rectangle or as the sliver OBJ of `width`, flat or turned
    let plate = |width: Option<f64>, turned: bool| -> Scene {
        let mut scene = text.clone();
        if turned {
            scene = scene.replace(flat, tilted);
        }
        if let Some(w) = width {
            let obj = dir.path().join(format!("sliver_{w:e}.obj"));
            let inner = -1.0 + w;
            let mesh =
                format!("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nv 0 {inner} 0\nf 1 2 5\nf 1 5 4\nf 5 3 4\nf 5 2 3\n");
            std::fs::write(&obj, mesh).unwrap();
            let shape = format!("name = \"plate\"\ntype = \"obj\"\nfile = {:?}", obj.to_string_lossy());
            scene = scene.replace(rectangle, &shape);
        }
        let path = dir.path().join(format!("plate_{width:?}_{turned}.toml"));
        std::fs::write(&path, scene).unwrap();
        let scene = Scene::load(&path, &[]).unwrap();
        let triangles = if width.is_some() { 4 } else { 2 };
        assert_eq!(scene.shapes[1].tri_count, triangles, "the sliver is kept");
        scene
    };
    let seeds = 8u64;
    // flat: the primary term alone; turned: the whole boundary term (the shadow's too)
    let runs = |scene: &Scene, param: &str, turned: bool| -> Vec<Vec<f64>> {
        (1..=seeds)
            .map(|s| match turned {
                false => aggregate(&primary(scene, param, 64, s)),
                true => {
                    let opts = RenderOptions {
                        boundary: BoundaryMode::BoundaryOnly,
                        spp_boundary: Some(64),
                        ..common::options(4, s)
                    };
                    aggregate(&render_diff(scene, &[param.to_string()], &opts).unwrap().1[0])
                }
            })
            .collect()
    };
    let stats = |runs: &[Vec<f64>], i: usize| common::mean_se(&runs.iter().map(|r| r[i]).collect::<Vec<_>>());
    for turned in [false, true] {
        let reference = plate(None, turned);
        for param in ["plate_x", "plate_roll"] {
            let rect = runs(&reference, param, turned);
            for width in [1e-5, 1e-6] {
                let sliver = runs(&plate(Some(width), turned), param, turned);
                let (mut chi2, mut power, mut zmax, mut n) = (0.0, 0.0, 0.0f64, 0);
                for i in 0..rect[0].len() {
                    let ((m0, se0), (m, se)) = (stats(&rect, i), stats(&sliver, i));
                    let sd = (se * se + se0 * se0).sqrt() + 1e-5 * m0.abs();
                    if sd == 0.0 {
                        assert_eq!(m, m0, "{param}, entry {i}: exact disagreement");
                        continue;
                    }
                    let z = (m - m0) / sd;
                    (chi2, zmax, n) = (chi2 + z * z, zmax.max(z.abs()), n + 1);
                    power += (0.025 * m0 / sd).powi(2);
                }
                let bound = chi2_bound(n, seeds);
                let case = format!("{param}, sliver {width:e}{}", if turned { ", turned" } else { "" });
                eprintln!("{case}: Σz² = {chi2:.1} (bound {bound:.1}), max |z| = {zmax:.2}, a 2.5 % bias {power:.0}");
                assert!(power > 4.0 * bound, "{case}: too noisy to see a bias of a few percent");
                assert!(chi2 <= bound, "{case}: the boundary term differs from the rectangle's");
            }
        }
    }
}
