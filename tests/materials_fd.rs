//! Derivatives through the materials beyond Lambertian (issue 13) against central finite
//! differences with common random numbers (tests/common/fd.rs): the GGX roughness of a rough
//! conductor, and the roughness and interior index of a rough dielectric, whose index moves
//! both the refraction (through f, with vertices in material form) and the time of flight
//! inside it (OPL = η_int × length). No parameter here moves geometry, so the interior
//! estimator is the whole derivative; the path tracer and BDPT. Each check runs per entry
//! (every pixel's time-summed derivative and every bin's total, `FdCheck::check`) and on coarse aggregates, which must
//! resolve a bias of 4 % (`FdCheck::check_aggregates`).

mod common;

use difftransient::scene::IntegratorKind;

fn check(scene: &'static str, name: &str, value: f32, h: f32) {
    check_with(None, scene, name, value, h);
}

fn check_with(integrator: Option<IntegratorKind>, scene: &'static str, name: &str, value: f32, h: f32) {
    let fd = common::fd::FdCheck {
        scene,
        k: 12,
        spp: 64,
        integrator,
        edit: |_| {},
        require_signal: true,
    };
    fd.check(name, value, h);
    let (_, resolution) = fd.check_aggregates(name, value, h);
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
        "rough_dielectric.toml",
        "glass_ior",
        1.5,
        0.01,
    );
}
