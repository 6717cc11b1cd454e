//! Adjoint gradients (`render_adjoint`, src/adjoint.rs) equal Σ ∂L/∂I · İ of `render_diff` on
//! the same samples, to float rounding: interior (path tracer and BDPT), primary edges and
//! secondary edges, several parameters at once. The bound is the rounding of the derivative
//! films (each part summed in f64, stored as f32, the parts added in f32), not Monte Carlo
//! noise: a missing term, a wrong scale or another sample stream fails it by far.

use crate::common;
use difftransient::render::{DiffParts, render_diff_parts};
use difftransient::scene::IntegratorKind;
use difftransient::{RenderOptions, Transient, render_adjoint};

const U: f64 = 1.0 / 16_777_216.0;

/// Σ ∂L/∂I·İ_k of `parts` (parameter k) and the rounding bound of comparing it with an
/// adjoint: 8u · Σ |∂L/∂I| · (|interior| + |primary| + |secondary|), since each part is summed
/// in f64, stored as f32, and the parts are added in f32.
fn contracted(adj: &Transient, parts: &DiffParts, k: usize) -> (f64, f64) {
    let sum = &parts.sum()[k];
    let dot: f64 = adj.data.iter().zip(&sum.data).map(|(&a, &d)| a as f64 * d as f64).sum();
    let part = |v: &[Transient], i: usize| v.get(k).map_or(0.0, |t| t.data[i].abs() as f64);
    let mag: f64 = (0..adj.data.len())
        .map(|i| {
            adj.data[i].abs() as f64 * (part(&parts.interior, i) + part(&parts.primary, i) + part(&parts.secondary, i))
        })
        .sum();
    (dot, 8.0 * U * mag)
}

fn check(name: &str, params: &[&str], integrator: IntegratorKind) {
    let mut scene = common::load(name);
    scene.film.width = 16;
    scene.film.height = 16;
    let params: Vec<String> = params.iter().map(|p| p.to_string()).collect();
    let opts = RenderOptions {
        spp: Some(4),
        spp_boundary: Some(2),
        seed: Some(5),
        threads: Some(2),
        integrator: Some(integrator),
        ..Default::default()
    };
    let parts = render_diff_parts(&scene, &params, &opts).unwrap();
    let adj = common::adjoint_like(&parts.primal);
    let (grad, stats) = render_adjoint(&scene, &params, &adj, &opts).unwrap();
    assert_eq!(grad.len(), params.len());
    for (k, p) in params.iter().enumerate() {
        let (dot, bound) = contracted(&adj, &parts, k);
        assert!(bound > 0.0, "{name} {p}: the derivative is zero");
        let err = (grad[k] - dot).abs();
        eprintln!(
            "{name} {p}: adjoint {} vs {dot}: relative difference {:.1e}, bound {:.1e}",
            grad[k],
            err / dot.abs(),
            bound / dot.abs()
        );
        assert!(
            err <= bound,
            "{name} {p} ({integrator:?}): adjoint {} vs Σ ∂L/∂I·İ {dot}: off by {err:.3e}, bound {bound:.3e}",
            grad[k],
        );
        // the bound is tight: a relative error of 0.1% (a missing sample, a term off by a
        // little) exceeds it (measured: bounds 9e-6 to 3.4e-4 of the value, differences 4e-10 to 2e-7)
        assert!(bound < 1e-3 * dot.abs(), "{name} {p}: the bound is too loose to test");
    }
    assert_eq!(stats.non_finite_samples, 0);
    if parts.primary.is_empty() {
        assert!(stats.boundary.is_none(), "{name}: no boundary stage when nothing moves");
    } else {
        assert!(stats.boundary.is_some());
    }
}

#[test]
fn adjoint_equals_the_contracted_derivative_films() {
    // interior only (albedo, radiance, pulse offset)
    check("diff_room.toml", &["albedo", "intensity"], IntegratorKind::Path);
    // primary edges (a sliding cube's silhouette)
    check("silhouette_slide.toml", &["cube_x"], IntegratorKind::Path);
    // secondary edges (a hidden occluder's shadow) and a moving light, together
    check(
        "shadow_hidden_occluder.toml",
        &["occluder_x", "light_x"],
        IntegratorKind::Path,
    );
}

#[test]
fn bdpt_adjoint_equals_the_contracted_derivative_films() {
    check("diff_room.toml", &["room_z", "albedo"], IntegratorKind::Bdpt);
}

#[test]
fn a_wrong_adjoint_shape_is_refused() {
    let scene = common::load("diff_room.toml");
    let f = &scene.film;
    let bad = Transient::zeros(f.width as usize + 1, f.height as usize, f.axis, f.channels);
    let e = render_adjoint(&scene, &["albedo".to_string()], &bad, &RenderOptions::default()).unwrap_err();
    assert!(e.to_string().contains("the adjoint (dL/dI) has shape"), "{e}");
}

/// More parameters than the kernel's derivative lanes (16): the adjoint runs them in groups
/// with the same samples, and each group equals the contraction of `render_diff` over it.
#[test]
fn the_adjoint_takes_more_parameters_than_the_dual_lanes() {
    let mut text = std::fs::read_to_string(common::scene_path("diff_room.toml")).unwrap();
    text.push_str(
        r#"
[[material]]
name = "panel_paint"
type = "diffuse"
albedo = 0.3

[[shape]]
name = "panel"
type = "rectangle"
material = "panel_paint"
translate = [0.3, -0.2, -2.0]
scale = [0.2, 0.2, 1.0]
"#,
    );
    let mut names: Vec<String> = [
        "room_z",
        "room_rot_y",
        "room_scale_z",
        "albedo",
        "intensity",
        "eta",
        "lamp_offset",
        "room_pitch",
    ]
    .map(String::from)
    .to_vec();
    let extra = [
        ("room", "translate", "x", 0.0),
        ("room", "translate", "y", 0.0),
        ("room", "rotate", "z", 0.0),
        ("room", "scale", "x", 2.0),
        ("room", "scale", "y", 1.5),
        ("panel", "translate", "x", 0.3),
        ("panel", "translate", "y", -0.2),
        ("panel", "translate", "z", -2.0),
        ("panel", "rotate", "x", 0.0),
        ("panel", "rotate", "y", 0.0),
        ("panel", "scale", "x", 0.2),
    ];
    for (shape, kind, axis, value) in extra {
        let name = format!("{shape}_{kind}_{axis}");
        text.push_str(&format!(
            "\n[[param]]\nname = \"{name}\"\nkind = \"{kind}\"\nshape = \"{shape}\"\naxis = \"{axis}\"\nvalue = {value}\n"
        ));
        names.push(name);
    }
    text.push_str("\n[[param]]\nname = \"panel_albedo\"\nkind = \"albedo\"\nmaterial = \"panel_paint\"\nvalue = 0.3\n");
    names.push("panel_albedo".into());
    assert!(names.len() > 16);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("many.toml");
    std::fs::write(&path, text).unwrap();
    let scene = difftransient::Scene::load(&path, &[]).unwrap();
    let opts = RenderOptions {
        spp: Some(2),
        spp_boundary: Some(1),
        seed: Some(9),
        threads: Some(2),
        ..Default::default()
    };
    let (primal, _) = difftransient::render(&scene, &opts).unwrap();
    let adj = common::adjoint_like(&primal);
    let (grad, _) = render_adjoint(&scene, &names, &adj, &opts).unwrap();
    assert_eq!(grad.len(), names.len());
    for (g, group) in names.chunks(16).enumerate() {
        let parts = render_diff_parts(&scene, group, &opts).unwrap();
        for (k, name) in group.iter().enumerate() {
            let (dot, bound) = contracted(&adj, &parts, k);
            let a = grad[g * 16 + k];
            assert!(
                (a - dot).abs() <= bound + 1e-12,
                "{name}: adjoint {a} vs Σ ∂L/∂I·İ {dot}"
            );
        }
    }
}

/// The boundary stage contracts each chunk of samples with ∂L/∂I on the thread that traced
/// it and adds the chunks in order (src/boundary/primary.rs, pass.rs): the gradient has the
/// same bits on 1, 2 and 3 threads, whose waves and batches hold different numbers of
/// chunks (262 144 boundary samples: 128 primary chunks, 64 or more secondary ones).
#[test]
fn the_adjoint_gradient_has_the_same_bits_on_any_thread_count() {
    for (name, params) in [
        ("silhouette_slide.toml", vec!["cube_x"]),
        ("shadow_hidden_occluder.toml", vec!["occluder_x", "light_x"]),
    ] {
        let mut scene = common::load(name);
        scene.film.width = 16;
        scene.film.height = 16;
        let params: Vec<String> = params.iter().map(|p| p.to_string()).collect();
        let opts = |threads: usize| RenderOptions {
            spp: Some(1),
            spp_boundary: Some(1024),
            seed: Some(9),
            threads: Some(threads),
            // the boundary stage alone: an interior term would swamp its last bits
            boundary: difftransient::BoundaryMode::BoundaryOnly,
            ..Default::default()
        };
        let parts = render_diff_parts(
            &scene,
            &params,
            &RenderOptions {
                boundary: difftransient::BoundaryMode::Full,
                ..opts(2)
            },
        )
        .unwrap();
        let adj = common::adjoint_like(&parts.primal);
        let grads: Vec<Vec<u64>> = [1, 2, 3]
            .iter()
            .map(|&t| {
                let (g, stats) = render_adjoint(&scene, &params, &adj, &opts(t)).unwrap();
                assert!(stats.boundary.is_some(), "{name}: the boundary stage ran");
                g.iter().map(|v| v.to_bits()).collect()
            })
            .collect();
        assert!(
            grads.iter().flatten().any(|&b| f64::from_bits(b) != 0.0),
            "{name}: a zero gradient"
        );
        assert_eq!(grads[0], grads[1], "{name}: 1 and 2 threads");
        assert_eq!(grads[0], grads[2], "{name}: 1 and 3 threads");
    }
}
