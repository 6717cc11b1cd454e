//! Hard cases: a scene far from the origin renders like the same scene at the origin (no
//! self-intersection leaks, no lost energy; more in far_from_origin.rs), and degenerate/tiny triangles never produce
//! NaN or Inf.

use crate::common;
use glam::Vec3;

fn small_cornell() -> difftransient::Scene {
    common::cornell(16, 16, 4)
}

/// `small_cornell` 10 km away, written as scene text (f64 positions, render origin).
fn far_cornell() -> difftransient::Scene {
    let text = std::fs::read_to_string(common::scene_path("cornell_box.toml")).unwrap();
    let far = common::translated(&text, [1.0e4, -3.0e3, 2.0e3]);
    let mut s = difftransient::Scene::from_str(
        &far,
        difftransient::scene::Format::Toml,
        std::path::Path::new("far.toml"),
        &[],
    )
    .unwrap();
    s.film.width = 16;
    s.film.height = 16;
    s.integrator.max_bounces = 4;
    s
}

#[test]
fn scene_far_from_the_origin_matches_the_scene_at_the_origin() {
    let near = small_cornell();
    let far = far_cornell();
    let k = 6;
    let (mut a, mut b) = (Vec::new(), Vec::new());
    let (mut ta, mut tb) = (Vec::new(), Vec::new());
    for seed in 0..k {
        let t0 = common::render_with(&near, 8, seed, 2);
        let t1 = common::render_with(&far, 8, 100 + seed, 2);
        assert_eq!(t1.non_finite_count(), 0);
        a.push(t0.steady.iter().map(|&v| v as f64).sum::<f64>());
        b.push(t1.steady.iter().map(|&v| v as f64).sum::<f64>());
        // mean arrival OPL of the whole image
        let m = |t: &difftransient::Transient| {
            let bt = t.bin_totals();
            let s0: f64 = bt.iter().map(|&v| v as f64).sum();
            bt.iter()
                .enumerate()
                .map(|(l, &v)| t.axis.bin_centre(l) * v as f64)
                .sum::<f64>()
                / s0
        };
        ta.push(m(&t0));
        tb.push(m(&t1));
    }
    let (ma, sa) = common::mean_se(&a);
    let (mb, sb) = common::mean_se(&b);
    let tol = 3.0 * (sa * sa + sb * sb).sqrt();
    assert!(
        (ma - mb).abs() <= tol,
        "image energy at origin {ma} vs far {mb} (tol {tol})"
    );
    let (oa, soa) = common::mean_se(&ta);
    let (ob, sob) = common::mean_se(&tb);
    let tol = 3.0 * (soa * soa + sob * sob).sqrt();
    assert!(
        (oa - ob).abs() <= tol,
        "mean arrival OPL at origin {oa} vs far {ob} (tol {tol})"
    );
}

/// The Cornell box with a sliver triangle (area ~1e-12) and a needle in the middle of the room.
fn with_degenerate_triangles() -> difftransient::Scene {
    let mut s = small_cornell();
    let base = s.geometry.positions.len() as u32;
    s.geometry.positions.extend([
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(1e-6, 1.0, 0.0),
        Vec3::new(0.0, 1.0 + 1e-6, 0.0),
        Vec3::new(-0.5, 0.5, 0.2),
        Vec3::new(0.5, 0.5, 0.2),
        Vec3::new(0.5, 0.5 + 1e-7, 0.2),
    ]);
    s.geometry
        .indices
        .extend([[base, base + 1, base + 2], [base + 3, base + 4, base + 5]]);
    s.geometry.tri_shape.extend([0, 0]);
    s
}

#[test]
fn tiny_and_degenerate_triangles_stay_finite() {
    let s = with_degenerate_triangles();
    let t = common::render_with(&s, 4, 1, 2);
    assert_eq!(t.non_finite_count(), 0);
    let opts = difftransient::RenderOptions {
        spp: Some(4),
        seed: Some(1),
        threads: Some(2),
        ..Default::default()
    };
    let (_, stats) = difftransient::render(&s, &opts).unwrap();
    assert_eq!(stats.non_finite_samples, 0, "no sample may be non-finite");
}

/// BDPT on the same hard cases (degenerate triangles; the Cornell box 10 km from the
/// origin): no non-finite sample, no non-finite output, and the far box keeps its energy.
#[test]
fn bdpt_stays_finite_on_hard_cases() {
    let opts = |seed| difftransient::RenderOptions {
        spp: Some(4),
        seed: Some(seed),
        threads: Some(2),
        integrator: Some(difftransient::scene::IntegratorKind::Bdpt),
        ..Default::default()
    };
    let (t, stats) = difftransient::render(&with_degenerate_triangles(), &opts(1)).unwrap();
    assert_eq!(t.non_finite_count(), 0);
    assert_eq!(stats.non_finite_samples, 0, "no sample may be non-finite");
    let far = far_cornell();
    let (mut near_e, mut far_e) = (Vec::new(), Vec::new());
    for seed in 0..6 {
        let (t, stats) = difftransient::render(&far, &opts(100 + seed)).unwrap();
        assert_eq!(t.non_finite_count(), 0);
        assert_eq!(stats.non_finite_samples, 0);
        far_e.push(t.steady.iter().map(|&v| v as f64).sum::<f64>());
        let (t, _) = difftransient::render(&small_cornell(), &opts(seed)).unwrap();
        near_e.push(t.steady.iter().map(|&v| v as f64).sum::<f64>());
    }
    let (ma, sa) = common::mean_se(&near_e);
    let (mb, sb) = common::mean_se(&far_e);
    assert!(
        (ma - mb).abs() <= 3.0 * (sa * sa + sb * sb).sqrt(),
        "BDPT image energy at origin {ma} ± {sa} vs far {mb} ± {sb}"
    );
}

/// A camera that sees the back of a two-sided black emitter turned by exactly 180° (the
/// rotation's f32 sine leaves its plane tilted by 10⁻⁷): each next-event connection from
/// the back to a point of the emitter's own plane has cos θ_y of rounding size, so the light
/// sample's density squared past f32's range and its MIS weight was inf/inf. 932 of 16 384
/// samples came out NaN and were dropped (an independent sweep, helper 41, forty-fourth
/// session); now none, and the image is black, as the back of the emitter is.
#[test]
fn an_emitter_seen_edge_on_from_behind_gives_no_nan() {
    let text = r#"
[integrator]
max_bounces = 1
spp = 64
[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov = 20.0
resolution = [16, 16]
filter = "box"
[film]
start_opl = 0.0
bin_width_opl = 100.0
bins = 4
[[material]]
name = "black"
type = "diffuse"
albedo = 0.0
[[shape]]
name = "lamp"
type = "rectangle"
material = "black"
rotate = [0.0, 180.0, 0.0]
[[emitter]]
name = "lamp_light"
type = "area"
shape = "lamp"
radiance = 1.0
"#;
    let s = difftransient::Scene::from_str(
        text,
        difftransient::scene::Format::Toml,
        std::path::Path::new("back.toml"),
        &[],
    )
    .unwrap();
    for integrator in [
        difftransient::scene::IntegratorKind::Path,
        difftransient::scene::IntegratorKind::Bdpt,
    ] {
        let opts = difftransient::RenderOptions {
            spp: Some(64),
            seed: Some(1),
            threads: Some(1),
            integrator: Some(integrator),
            ..Default::default()
        };
        let (t, stats) = difftransient::render(&s, &opts).unwrap();
        assert_eq!(stats.non_finite_samples, 0, "{integrator:?}: non-finite samples");
        assert!(
            t.data.iter().all(|&v| v == 0.0),
            "{integrator:?}: the emitter's back is black"
        );
    }
}
