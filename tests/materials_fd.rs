//! Derivatives through the materials beyond Lambertian (issue 13) against central finite
//! differences with common random numbers (tests/common/fd.rs): the GGX roughness of a rough
//! conductor, and the roughness and interior index of a rough dielectric, whose index moves
//! both the refraction (through f, with vertices in material form) and the time of flight
//! inside it (OPL = η_int × length). No parameter here moves geometry, so the interior
//! estimator is the whole derivative; the path tracer and BDPT. Each check runs per entry
//! (every pixel's time-summed derivative and every bin's total, `FdCheck::check`) and on coarse aggregates, which must
//! resolve a bias of 4 % (`FdCheck::check_aggregates`).

use crate::common;

use difftransient::scene::IntegratorKind;

fn check(scene: &'static str, name: &str, value: f32, h: f32) {
    check_with(None, 64, scene, name, value, h);
}

fn check_with(integrator: Option<IntegratorKind>, spp: u32, scene: &'static str, name: &str, value: f32, h: f32) {
    let fd = common::fd::FdCheck {
        scene,
        k: 12,
        spp,
        integrator,
        edit: |_| {},
        require_signal: true,
        power_exemption: None,
        boundary: difftransient::render::BoundaryMode::Full,
    };
    check_resolved(&fd, name, value, h);
}

/// The per-entry check and the coarse aggregates (on the same renders), which must resolve a
/// bias of 4 %.
fn check_resolved(fd: &common::fd::FdCheck, name: &str, value: f32, h: f32) {
    let (_, resolution) = fd.check_entries_and_aggregates(name, value, h);
    assert!(
        resolution < 0.04,
        "{name}: resolves only a bias of {:.1} %",
        resolution * 100.0
    );
}

#[test]
fn conductor_roughness_matches_finite_differences() {
    check("rough_conductor.toml", "gold_roughness", 0.3, 0.01);
}

/// The albedo kind on a rough conductor: its specular reflectance.
#[test]
fn conductor_reflectance_matches_finite_differences() {
    check("rough_conductor.toml", "gold_reflectance", 0.9, 0.01);
}

#[test]
fn dielectric_roughness_matches_finite_differences() {
    check("rough_dielectric.toml", "glass_roughness", 0.2, 0.004);
}

#[test]
fn dielectric_ior_matches_finite_differences() {
    check("rough_dielectric.toml", "glass_ior", 1.5, 0.01);
}

/// BDPT: the same derivatives through its subpaths (the deferred ḟ/f of glossy walk vertices,
/// f at both ends of each connection, in importance transport on the light side).
#[test]
fn bdpt_conductor_roughness_matches_finite_differences() {
    check_with(
        Some(IntegratorKind::Bdpt),
        64,
        "rough_conductor.toml",
        "gold_roughness",
        0.3,
        0.01,
    );
}

#[test]
fn bdpt_dielectric_ior_matches_finite_differences() {
    check_with(
        Some(IntegratorKind::Bdpt),
        64,
        "rough_dielectric.toml",
        "glass_ior",
        1.5,
        0.01,
    );
}

/// Nested media (scenes/liquid_glass.toml: a liquid sealed in a glass block, seen through
/// it): the liquid's index moves its own interface and the time spent in it; the glass's index
/// moves the glass's interfaces, the time spent in the glass, and the liquid's interface too,
/// whose exterior it is (`Motion::material_derivs`, whose lanes a unit test in
/// `integrator/motion.rs` checks). Per entry only (`FdCheck::check`): through four rough
/// interfaces and ten bounces this CI-sized run resolves only a 15 % (liquid) to 50 % (glass)
/// bias on the coarse aggregates (the faint reflections between glass and liquid carry large
/// ḟ/f), so it checks the nesting, not the last few percent; the single-interface tests
/// above do that.
#[test]
fn nested_media_iors_match_finite_differences() {
    for (name, value) in [("liquid_ior", 1.33), ("glass_ior", 1.5)] {
        common::fd::FdCheck {
            scene: "liquid_glass.toml",
            k: 12,
            spp: 256,
            integrator: None,
            edit: |_| {},
            require_signal: true,
            // power audit: the per-entry check rejects a 0.6 % bias of glass_ior's derivative
            // but only an 8.8 % one of liquid_ior's (94 s for both; see above)
            power_exemption: (name == "liquid_ior").then_some("liquid_ior resolves 8.8 % (12 seeds × 256 spp)"),
            boundary: difftransient::render::BoundaryMode::Full,
        }
        // a wider step: a change of index flips some lanes between reflection and refraction
        // (F moves), which makes narrow central differences noisy
        .check(name, value, 0.04);
    }
}

/// The liquid of liquid_glass.toml at 1.52, nearly matched to its glass (1.5), with the
/// glass's walls 1 cm thin (the liquid's cube at 0.39 of the glass's 0.4), over one bin that
/// holds all the light (so the time term is zero): the derivative of the whole image against
/// central differences. The refraction lobe there is about 10⁻³ rad wide, and its ḟ/f was
/// evaluated at the direction rebuilt from the two vertices, which differs from the one the
/// ray was traced along (and the lobe drawn at) by up to ε/r, ε the ray's offset off the
/// surface: it read −76.5 ± 2.6 against +2.2 ± 0.6 (16 seeds × 1024 spp; BDPT alike), and on
/// the shipped scene (walls 10 cm) 11 % short in its late bins (`path::traced`).
#[test]
fn nearly_matched_liquid_in_thin_glass_matches_finite_differences() {
    let text = std::fs::read_to_string(common::scene_path("liquid_glass.toml"))
        .unwrap()
        .replacen("scale = 0.3\n", "scale = 0.39\n", 1);
    assert!(
        text.contains("scale = 0.39\n"),
        "the liquid's cube was not found to resize"
    );
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("thin.toml"), &text).unwrap();
    let render = |seed: u64, value: f32, diff: bool| -> f64 {
        let (seed, set) = (seed.to_string(), format!("liquid_ior={value}"));
        let mut args = vec![
            "-q",
            "render",
            "thin.toml",
            "--spp",
            "512",
            "--seed",
            &seed,
            "-o",
            "out",
            "--set",
            &set,
            "--set",
            "film.start_opl=0",
            "--set",
            "film.bin_width_opl=100",
            "--set",
            "film.bins=1",
        ];
        if diff {
            args.extend(["--diff", "liquid_ior"]);
        }
        let out = common::dtr(&args, dir.path());
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let file = if diff { "out.d_liquid_ior.npy" } else { "out.npy" };
        common::npy(&dir.path().join(file)).1.iter().map(|&x| x as f64).sum()
    };
    let (value, h) = (1.52f32, 0.004f32);
    let (ads, diffs): (Vec<f64>, Vec<f64>) = (0..8)
        .map(|s| {
            let ad = render(s, value, true);
            (
                ad,
                ad - (render(s, value + h, false) - render(s, value - h, false)) / (2.0 * h as f64),
            )
        })
        .unzip();
    let (mean, se) = common::mean_se(&diffs);
    common::power::Test::default()
        .one(common::power::Entry {
            scale: 4.0,
            ..common::power::Entry::new(diffs.clone(), ads, 0.0)
        })
        .power()
        .exempt(
            "thin liquid_glass liquid_ior whole image (8 seeds)",
            "a regression guard (−76.5 against +2.2): the whole image's derivative is not resolved from 0 \
             at 8 seeds, so no relative bias fails it",
        );
    assert!(
        mean.abs() < 4.0 * se,
        "derivative − central difference: {mean:.2} ± {se:.2}"
    );
}

/// Pose of a glossy object: the closed room of diff_room.toml with rough-conductor walls (GGX
/// α 0.3, reflectance 0.6, F = 1), moved (`room_z`, translate) and turned (`room_rot_y`).
/// Every vertex moves with its wall (material form), so the f of each glossy vertex changes
/// with the directions to both its neighbours: the ḟ/f that the path tracer and BDPT apply
/// once a vertex's successor is known. The room is convex (no visibility changes), so the
/// interior is the whole derivative (`BoundaryMode::InteriorOnly`: the boundary stage, which
/// would find nothing here, is Lambertian only so far and refuses glossy scenes).
fn glossy_room(integrator: Option<IntegratorKind>) -> common::fd::FdCheck {
    common::fd::FdCheck {
        scene: "diff_room.toml",
        k: 12,
        spp: 64,
        integrator,
        edit: |s| {
            s.materials[0].material = difftransient::scene::Material::Conductor {
                roughness: 0.3,
                specular: [0.6; 3],
                ior: None,
            };
        },
        require_signal: true,
        power_exemption: None,
        boundary: difftransient::render::BoundaryMode::InteriorOnly,
    }
}

#[test]
fn glossy_pose_matches_finite_differences() {
    for integrator in [None, Some(IntegratorKind::Bdpt)] {
        for (name, value, h) in [("room_z", 0.0, 0.004), ("room_rot_y", 0.0, 0.2)] {
            let fd = glossy_room(integrator);
            let (_, resolution) = fd.check_entries_and_aggregates(name, value, h);
            assert!(
                resolution < 0.04,
                "{name} ({integrator:?}): resolves only a bias of {:.1} %",
                resolution * 100.0
            );
        }
    }
}

/// An FD check on a scene whose conductors and dielectrics are smooth, with the path tracer.
fn smooth_check(scene: &'static str, spp: u32, boundary: difftransient::render::BoundaryMode) -> common::fd::FdCheck {
    smooth_check_with(IntegratorKind::Path, scene, spp, boundary)
}

fn smooth_check_with(
    integrator: IntegratorKind,
    scene: &'static str,
    spp: u32,
    boundary: difftransient::render::BoundaryMode,
) -> common::fd::FdCheck {
    common::fd::FdCheck {
        scene,
        k: 12,
        spp,
        integrator: Some(integrator),
        edit: common::make_smooth,
        require_signal: true,
        power_exemption: None,
        boundary,
    }
}

/// Through Dirac lobes (`integrator::bsdf::delta`): the index of a smooth glass slab that the
/// wall is seen through (scenes/slab_ior.toml). It turns both refractions, so it moves where
/// each camera ray lands on the wall (the vertices past the slab are in ray form: hits of the
/// turned rays), the Fresnel weights (1 − F) and 1/η'², and the time spent in the slab. The
/// interior term alone (a smooth dielectric's index moves edges seen through it in general;
/// none is in view here, see the scene).
#[test]
fn smooth_dielectric_ior_matches_finite_differences() {
    let fd = smooth_check("slab_ior.toml", 512, difftransient::render::BoundaryMode::InteriorOnly);
    // a wide step: a change of index flips lanes between reflection and refraction (F moves),
    // whole paths at a time, which makes narrow central differences noisy
    check_resolved(&fd, "slab_ior", 1.5, 0.05);
}

/// The albedo of a wall seen through the smooth slab (two Dirac refractions before it).
#[test]
fn albedo_seen_through_smooth_glass_matches_finite_differences() {
    let fd = smooth_check("slab_ior.toml", 64, difftransient::render::BoundaryMode::Full);
    check_resolved(&fd, "wall_albedo", 0.7, 0.01);
}

/// The reflectance of a smooth (mirror) gold sphere: its weight F·tint with the tint's
/// derivative lanes, and everything seen in the mirror.
#[test]
fn smooth_conductor_reflectance_matches_finite_differences() {
    let fd = smooth_check("rough_conductor.toml", 64, difftransient::render::BoundaryMode::Full);
    check_resolved(&fd, "gold_reflectance", 0.9, 0.01);
}

/// BDPT through Dirac lobes, for parameters that move no vertex: the albedo of the wall seen
/// through the smooth slab (camera subpaths through two Dirac refractions, light subpaths
/// connected or splatted from the wall) and the smooth gold sphere's reflectance (F·tint of
/// delta vertices on both subpaths, in the MIS chain with their zero densities).
#[test]
fn bdpt_through_dirac_lobes_matches_finite_differences() {
    use difftransient::render::BoundaryMode;
    let fd = smooth_check_with(IntegratorKind::Bdpt, "slab_ior.toml", 64, BoundaryMode::Full);
    check_resolved(&fd, "wall_albedo", 0.7, 0.01);
    let fd = smooth_check_with(IntegratorKind::Bdpt, "rough_conductor.toml", 64, BoundaryMode::Full);
    check_resolved(&fd, "gold_reflectance", 0.9, 0.01);
}

/// What stays refused with Dirac lobes: a parameter that moves geometry (the boundary stage
/// assumes no Dirac BSDFs) and a smooth dielectric's index (edges seen through it move), each
/// unless the interior alone is asked for, and with BDPT in any case (its strategies would
/// move the specular chain in different ways).
#[test]
fn derivatives_through_dirac_lobes_refuse_what_is_not_computed() {
    use difftransient::render::BoundaryMode;
    let scene = |name: &str| {
        let mut s = common::load(name);
        common::make_smooth(&mut s);
        s
    };
    let opts = |kind: IntegratorKind, boundary: BoundaryMode| difftransient::RenderOptions {
        spp: Some(1),
        integrator: Some(kind),
        boundary,
        ..Default::default()
    };
    let err = |s: &difftransient::Scene, p: &str, o: &difftransient::RenderOptions| match difftransient::render_diff(
        s,
        &[p.to_string()],
        o,
    ) {
        Ok(_) => panic!("{p}: not refused"),
        Err(e) => e.to_string(),
    };
    let slab = scene("slab_ior.toml");
    let e = err(&slab, "slab_ior", &opts(IntegratorKind::Path, BoundaryMode::Full));
    assert!(e.contains("\"glass\"") && e.contains("--estimators interior"), "{e}");
    let e = err(
        &slab,
        "slab_ior",
        &opts(IntegratorKind::Bdpt, BoundaryMode::InteriorOnly),
    );
    assert!(e.contains("BDPT") && e.contains("kind = \"path\""), "{e}");
    // a rough dielectric at the index outside it renders as a smooth one, and the refusal
    // says so and how to keep it rough
    let matched = difftransient::Scene::load(
        &common::scene_path("rough_dielectric.toml"),
        &[("glass_ior".to_string(), 1.0)],
    )
    .unwrap();
    let e = err(&matched, "glass_ior", &opts(IntegratorKind::Path, BoundaryMode::Full));
    assert!(
        e.contains("material \"glass\" (type roughdielectric, int_ior 1 equal to the index outside it")
            && e.contains("a little off"),
        "{e}"
    );
    let glass = scene("glass_slab.toml");
    let e = err(&glass, "slab_x", &opts(IntegratorKind::Path, BoundaryMode::Full));
    assert!(e.contains("A.4") && e.contains("--estimators interior"), "{e}");
    let e = err(
        &glass,
        "slab_x",
        &opts(IntegratorKind::Bdpt, BoundaryMode::InteriorOnly),
    );
    assert!(e.contains("BDPT"), "{e}");
    // the interior alone runs
    for (s, p) in [(&slab, "slab_ior"), (&glass, "slab_x")] {
        difftransient::render_diff(
            s,
            &[p.to_string()],
            &opts(IntegratorKind::Path, BoundaryMode::InteriorOnly),
        )
        .unwrap();
    }
}
