//! One-sided materials (`one_sided = true`: black from behind, as a Mitsuba BSDF without
//! `twosided`), in every estimator: the path tracer, both subpaths of BDPT and the boundary
//! stage's walks must end a path where it meets such a material from behind.
//!
//! scenes/one_sided_panel.toml holds a one-sided panel whose back faces the light and the
//! camera. Its reference is the same scene with a two-sided panel of the same albedo and a
//! two-sided black panel 0.5 mm behind it: light from behind meets the black one, light
//! from the front the white one (what reaches the gap between them through its 0.5 mm
//! sides is far below the noise here). The two must agree within noise; a plain two-sided
//! panel must not.

use crate::common;

use difftransient::scene::{IntegratorKind, NamedMaterial};
use difftransient::{RenderOptions, Scene, render};

/// Coarse aggregates of `seeds` renders of 32 spp from seed `first` on.
fn aggregates(scene: &Scene, integrator: IntegratorKind, first: u64, seeds: u64) -> Vec<Vec<f64>> {
    common::fd::coarse_runs(scene, Some(integrator), first..first + seeds)
}

fn panel_scene(edit: &str) -> Scene {
    let text = std::fs::read_to_string(common::scene_path("one_sided_panel.toml")).unwrap();
    let text = match edit {
        "two-sided" => text.replace("one_sided = true", "one_sided = false"),
        // the two-sided panel and a black one 0.5 mm above it, on its back's side (at panel_x)
        "black back" => {
            text.replace("one_sided = true", "one_sided = false")
                + r#"
[[shape]]
name = "backing"
type = "rectangle"
material = "black"
translate = [0.1, 1.0005, 0.0]
rotate = [90.0, 0.0, 0.0]
scale = [0.3, 0.3, 1.0]
"#
        }
        _ => text,
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("panel.toml");
    std::fs::write(&path, text).unwrap();
    Scene::load(&path, &[]).unwrap()
}

fn assert_black_from_behind(integrator: IntegratorKind) {
    let seeds = 12;
    // independent seeds on the two sides (the two-sample test assumes them)
    let one_sided = aggregates(&panel_scene("one-sided"), integrator, 500, seeds);
    let reference = aggregates(&panel_scene("black back"), integrator, 900, seeds);
    common::assert_agree(
        &one_sided,
        &reference,
        &format!("{integrator:?}: one-sided vs black back"),
    );
    let two_sided = aggregates(&panel_scene("two-sided"), integrator, 500, seeds);
    let (_, zmax, _) = common::two_sample_z(&two_sided, &reference);
    eprintln!("{integrator:?}: two-sided vs black back: max|z| = {zmax:.2}");
    assert!(
        zmax > 10.0,
        "a lit back is not told apart from a black one (max|z| {zmax:.2})"
    );
}

/// Before one-sided materials existed, every material was lit from behind (an imported
/// Mitsuba scene's bare BSDFs too: an independent sweep measured a back face at 0.14
/// against Mitsuba's 0).
#[test]
fn a_one_sided_panel_is_black_from_behind_in_the_path_tracer() {
    assert_black_from_behind(IntegratorKind::Path);
}

#[test]
fn a_one_sided_panel_is_black_from_behind_in_bdpt() {
    assert_black_from_behind(IntegratorKind::Bdpt);
}

/// Where no path meets a back (the Cornell box's walls face in and its boxes out, its lamp
/// kept two-sided: paths meet the lamp's top through the 2 cm gap under the ceiling), a
/// one-sided material renders the two-sided bytes, with the path tracer and BDPT.
#[test]
fn one_sided_materials_seen_only_from_the_front_change_no_byte() {
    let two = common::cornell(16, 16, 4);
    let mut one = two.clone();
    let lamp = one.shapes.iter().position(|s| s.name == "light_quad").unwrap();
    let own = NamedMaterial {
        name: "lamp".into(),
        ..one.materials[one.shapes[lamp].material as usize].clone()
    };
    one.materials.iter_mut().for_each(|m| m.one_sided = true);
    one.materials.push(own);
    one.shapes[lamp].material = one.materials.len() as u32 - 1;
    for integrator in [IntegratorKind::Path, IntegratorKind::Bdpt] {
        let opts = RenderOptions {
            spp: Some(8),
            seed: Some(3),
            threads: Some(2),
            integrator: Some(integrator),
            ..Default::default()
        };
        let a = render(&two, &opts).unwrap().0;
        let b = render(&one, &opts).unwrap().0;
        assert!(
            a.data == b.data,
            "{integrator:?}: a one-sided front changed the transient"
        );
    }
}

/// d/d`panel_x` against central finite differences with common random numbers
/// (tests/common/fd.rs): the interior and boundary terms of a scene whose moving panel is
/// black from behind; coarse aggregates must resolve a bias of 4 %. (Per pixel, central
/// differences cannot see the penumbra's thin tail: no shadow ray of 12 seeds
/// flips there, so their difference is exactly 0 where the edge term is not.)
#[test]
fn a_one_sided_panels_derivative_matches_finite_differences() {
    let fd = common::fd::FdCheck {
        scene: "one_sided_panel.toml",
        k: 12,
        spp: 64,
        integrator: None,
        edit: |_| {},
        require_signal: true,
        power_exemption: None,
        boundary: difftransient::render::BoundaryMode::Full,
    };
    let (_, resolution) = fd.check_aggregates("panel_x", 0.1, 0.03);
    assert!(resolution < 0.04, "resolves only a bias of {:.1} %", resolution * 100.0);
}

/// A relay wall of a one-sided material: facing the SPAD and the laser, it renders the
/// two-sided wall's bytes; turned away (`flip_normals`), its points are not seen and its laser
/// spots light nothing, so the capture is black.
#[test]
fn a_one_sided_relay_wall_turned_away_sees_nothing() {
    let text = std::fs::read_to_string(common::scene_path("nlos_hidden_patch.toml")).unwrap();
    let wall = "name = \"wall\"\ntype = \"diffuse\"\nalbedo = 0.8\n";
    assert!(text.contains(wall));
    let one_sided = text.replace(wall, &format!("{wall}one_sided = true\n"));
    let turned = one_sided.replacen("material = \"wall\"\n", "material = \"wall\"\nflip_normals = true\n", 1);
    assert_ne!(turned, one_sided);
    let render_text = |t: &str| {
        let s = Scene::from_str(
            t,
            difftransient::scene::Format::Toml,
            &common::scene_path("x.toml"),
            &[],
        )
        .unwrap();
        render(&s, &common::options(4, 1)).unwrap().0
    };
    let two = render_text(&text);
    assert!(two.data.iter().any(|&v| v > 0.0));
    assert!(
        render_text(&one_sided).data == two.data,
        "a one-sided wall seen from the front changed the capture"
    );
    assert!(
        render_text(&turned).data.iter().all(|&v| v == 0.0),
        "a wall turned away from the SPAD lit the capture"
    );
}
