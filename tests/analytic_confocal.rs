//! A diffuse plane lit by a point light at the camera (confocal), one bounce: every pixel's
//! radiance and arrival time are known in closed form.
//!
//! Radiance at plane point x seen from the camera at height h: L = ρ I h / (π r³) with
//! r = ‖x − camera‖ (light and camera coincide, so both cosines are h / r). The path's
//! OPL is 2 η r. The pixel value is L averaged over the pixel footprint (box filter),
//! integrated here by Gauss–Legendre quadrature.

use crate::common;
use difftransient::integrator::camera::CameraSampler;
use difftransient::scene::{EmitterKind, Material, PixelFilter};

/// Gauss–Legendre nodes and weights on [0, 1], 8 points.
fn gauss8() -> Vec<(f64, f64)> {
    let x = [
        0.1834346424956498,
        0.525532409916329,
        0.7966664774136267,
        0.9602898564975363,
    ];
    let w = [
        0.362683783378362,
        0.3137066458778873,
        0.2223810344533745,
        0.1012285362903763,
    ];
    let mut v = Vec::new();
    for i in 0..4 {
        v.push((0.5 - 0.5 * x[i], 0.5 * w[i]));
        v.push((0.5 + 0.5 * x[i], 0.5 * w[i]));
    }
    v
}

struct Setup {
    scene: difftransient::Scene,
    cam: CameraSampler,
    h: f64,
    k: f64,
}

fn setup() -> Setup {
    let mut scene = common::load("confocal_plane.toml");
    scene.film.filter = PixelFilter::Box;
    let Material::Diffuse { albedo } = scene.materials[0].material else {
        panic!("the confocal plane is diffuse")
    };
    let EmitterKind::Point { position, intensity } = scene.emitters[0].kind else {
        panic!("expected a point light")
    };
    assert!(
        (position - scene.camera.position).length() < 1e-6,
        "the scene must be confocal"
    );
    assert_eq!(scene.integrator.max_bounces, 1);
    let cam = CameraSampler::new(&scene.camera, scene.film.width, scene.film.height, PixelFilter::Box);
    let h = scene.camera.position.z as f64; // plane z = 0, normal +Z
    let k = albedo[0] as f64 * intensity[0] as f64 / std::f64::consts::PI;
    Setup { scene, cam, h, k }
}

/// r for the ray through film point (fx, fy) hitting the plane z = 0.
fn distance(s: &Setup, fx: f64, fy: f64) -> f64 {
    let d = s.cam.direction(fx as f32, fy as f32);
    s.h / (-d.z as f64)
}

#[test]
fn pixel_energy_matches_closed_form_within_three_standard_errors() {
    let s = setup();
    let (w, h) = (s.scene.film.width as usize, s.scene.film.height as usize);
    let k = 16;
    let runs: Vec<_> = (0..k)
        .map(|seed| common::render_with(&s.scene, 4, 100 + seed, 2))
        .collect();
    let q = gauss8();
    let mut worst = 0.0f64;
    let mut chi2 = 0.0f64;
    let mut total_exact = 0.0f64;
    let mut totals = vec![0.0f64; k as usize];
    for py in 0..h {
        for px in 0..w {
            let mut exact = 0.0;
            for &(a, wa) in &q {
                for &(b, wb) in &q {
                    let r = distance(&s, px as f64 + a, py as f64 + b);
                    exact += wa * wb * s.k * s.h / r.powi(3);
                }
            }
            let est: Vec<f64> = runs.iter().map(|t| t.time_sum(px, py, 0) as f64).collect();
            for (t, e) in totals.iter_mut().zip(&est) {
                *t += e;
            }
            total_exact += exact;
            let (m, se) = common::mean_se(&est);
            // f32 accumulation adds ~1e-6 relative on top of the Monte Carlo error
            let z = (m - exact) / (se + 1e-6 * exact);
            chi2 += z * z;
            worst = worst.max(z.abs());
            // 256 pixels, se from 16 runs (Student t, 15 dof): |t| > 6 has p < 3e-5 per pixel
            assert!(
                z.abs() <= 6.0,
                "pixel ({px},{py}): {m} vs exact {exact} (se {se}, z {z:.2})"
            );
        }
    }
    let n = (w * h) as f64;
    // Σ z² over n pixels: mean n·15/13 for t(15); allow 5 standard deviations (≈ sqrt(2n)·1.2)
    let mean_chi2 = n * 15.0 / 13.0;
    assert!(
        chi2 <= mean_chi2 + 5.0 * 1.2 * (2.0 * n).sqrt(),
        "Σ z² = {chi2:.1} for {n} pixels"
    );
    let (m, se) = common::mean_se(&totals);
    assert!(
        (m - total_exact).abs() <= 3.0 * se + 1e-6 * total_exact,
        "image energy {m} vs exact {total_exact} (se {se})"
    );
    eprintln!("worst |z| = {worst:.2}, Σz² = {chi2:.1} over {n} pixels, energy {m} vs {total_exact} ± {se}");
}

#[test]
fn first_arrival_bin_is_exact() {
    let mut s = setup();
    // A needle-thin filter: every sample goes through the pixel centre (± 1e-3 px), so each
    // pixel sees one OPL and its arrival bin is exact.
    s.scene.film.filter = PixelFilter::Tent { radius: 1e-3 };
    let t = common::render_with(&s.scene, 4, 7, 2);
    let axis = s.scene.film.axis;
    let eta = s.scene.eta as f64;
    let bin_of = |d: f64| ((d - axis.start_opl) / axis.bin_width_opl).floor() as i64;
    let mut checked = 0;
    for py in 0..t.height {
        for px in 0..t.width {
            // the OPL over the pixel footprint is monotone along the footprint's edges; sample it densely
            let (mut dmin, mut dmax) = (f64::MAX, f64::MIN);
            for i in 0..=4 {
                for j in 0..=4 {
                    let (fx, fy) = (
                        px as f64 + 0.499 + 0.0005 * i as f64,
                        py as f64 + 0.499 + 0.0005 * j as f64,
                    );
                    let d = 2.0 * eta * distance(&s, fx, fy);
                    dmin = dmin.min(d);
                    dmax = dmax.max(d);
                }
            }
            let series = t.pixel_series(px, py);
            let nonzero: Vec<i64> = series
                .iter()
                .enumerate()
                .filter(|(_, v)| **v > 0.0)
                .map(|(i, _)| i as i64)
                .collect();
            assert!(!nonzero.is_empty(), "pixel ({px},{py}) received nothing");
            let (lo, hi) = (bin_of(dmin), bin_of(dmax));
            assert!(
                nonzero.iter().all(|&b| b >= lo && b <= hi),
                "pixel ({px},{py}) bins {nonzero:?} outside [{lo},{hi}]"
            );
            if lo == hi {
                assert_eq!(nonzero[0], lo, "pixel ({px},{py}) first arrival");
                checked += 1;
            }
        }
    }
    assert!(
        checked > t.width * t.height * 9 / 10,
        "too few pixels with a single-bin footprint ({checked})"
    );
}
