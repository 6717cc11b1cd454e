//! Derivatives of NLOS captures with respect to geometry, interior and boundary term together,
//! against central finite differences with common random numbers on the coarse aggregates
//! (tests/common/fd.rs `check_aggregates`: image halves, quadrants and time slices, 12 seeds,
//! each within 4 standard errors widened by the finite difference's own error; every run must
//! resolve a relative bias of 6 %, and resolves 4 to 5.4 %). Per-pixel entries are not judged:
//! at 4096 samples the finite difference of a pixel that a shadow edge crosses rarely is 0 in
//! all 12 seeds, which its standard error cannot tell from a true 0 (an exhaustive pixel with
//! derivative 2·10⁻⁴ read 0 ± 2·10⁻⁷; at 8192 samples and 4 seeds it read 2·10⁻⁴).
//!
//! scenes/nlos_moving_plate.toml hangs a black plate between the relay wall and a white
//! backdrop: the plate reflects nothing, so the derivative of its position is the boundary
//! term alone, the edges its sensor points see (the sensor-directed draws of
//! `boundary::secondary`) and the shadows its laser points cast (the light-directed draws).
//! In a confocal scan each laser point is its sensor point, so a path s → x → s crosses one
//! discontinuity, not two: counted twice, as for two separate points (`secondary::coincide`),
//! the confocal check failed with z = 17.7 on the image's left half and −14.1 on its right.
//! The exhaustive scan's laser points are apart from its sensor points, so both kinds of draw
//! count; there a sensor subpath's last shadow ray ran into the wall at its sensor point
//! (before `integrator::importance` stopped the segment short of the wall), and the check
//! failed with z = −57.5 on bins 87..105 and −25.1 on the image's top half. A white plate adds
//! its interior derivative to the same boundary term. scenes/nlos_plate_between_panels.toml
//! hangs the plate between two hidden panels, where its shadow falls from one onto the other:
//! the edge-directed draws' check (with their weight scaled by 1.06 in a scratch edit, it
//! failed with z = 4.0 on the total and 4.4 on bins 137..165).

use crate::common;
use difftransient::render::BoundaryMode;
use difftransient::scene::{IntegratorKind, Material};

fn check(scene: &'static str, name: &str, value: f32, h: f32, edit: fn(&mut difftransient::Scene)) {
    check_with(None, scene, name, value, h, 4096, edit);
}

fn check_at(scene: &'static str, name: &str, value: f32, h: f32, spp: u32) {
    check_with(None, scene, name, value, h, spp, |_| {});
}

fn check_with(
    integrator: Option<IntegratorKind>,
    scene: &'static str,
    name: &str,
    value: f32,
    h: f32,
    spp: u32,
    edit: fn(&mut difftransient::Scene),
) {
    let (_, resolution) = common::fd::FdCheck {
        scene,
        k: 12,
        spp,
        integrator,
        edit,
        require_signal: true,
        power_exemption: power_exemption(scene),
        boundary: BoundaryMode::Full,
    }
    .check_aggregates(name, value, h);
    eprintln!(
        "{scene} {name}: resolves a relative bias of {:.1} %",
        100.0 * resolution
    );
    assert!(resolution < 0.06, "{scene} {name}: resolves only {resolution}");
}

/// The checks that resolve a little less than a 5 % bias of the derivative (measured in the
/// power audit of 2026-12: detectable bias with the scaled derivative's own spread): their
/// renders cost 15–150 s each at 12 seeds, and the finite difference's Richardson error
/// (1.1–1.4 % of the fitted bias) is part of what they allow, so more seeds alone would not
/// bring them under 5 % within the CI budget. Every other scene here must reach it.
fn power_exemption(scene: &str) -> Option<&'static str> {
    match scene {
        "nlos_moving_plate_exhaustive.toml" => Some("resolves 5.1 % (12 seeds × 4096 spp, 146 s)"),
        "nlos_plate_between_panels.toml" => Some("resolves 5.2 % (12 seeds × 24576 spp, 69 s)"),
        "nlos_occluder.toml" => Some("resolves 6.0 % (path tracer) and 6.1 % (BDPT) (12 seeds × 4096 spp, 17–29 s)"),
        _ => None,
    }
}

/// The plate as a white one (ρ = 0.5): an interior derivative besides the boundary term.
fn white_plate(s: &mut difftransient::Scene) {
    let m = s.materials.iter_mut().find(|m| m.name == "black").unwrap();
    m.material = Material::Diffuse { albedo: [0.5; 3] };
}

#[test]
fn a_black_plate_in_a_confocal_scan_matches_finite_differences() {
    check("nlos_moving_plate.toml", "plate_x", 0.1, 0.02, |_| {});
}

#[test]
fn a_black_plate_in_an_exhaustive_scan_matches_finite_differences() {
    check("nlos_moving_plate_exhaustive.toml", "plate_x", 0.1, 0.02, |_| {});
}

#[test]
fn a_white_plate_matches_finite_differences() {
    check("nlos_moving_plate.toml", "plate_x", 0.1, 0.02, white_plate);
}

/// scenes/nlos_occluder.toml's hidden box behind its panel, three bounces: the shadows the box
/// casts from the laser points, with sensor subpaths of up to three vertices, and the interior
/// alone is biased here: run with `BoundaryMode::InteriorOnly`, this check fails on its last
/// two time slices (z = −5.5 and −6.5). (The edge-directed draws add nothing inside this
/// window: every segment they find between two hidden surfaces is longer than it allows, and
/// one with an end on the planar wall joins the wall's own points at cos θ = 0, its longer
/// continuations leaving the window.)
/// Cosine-sampled first segments, as in the other scenes.
#[test]
fn a_hidden_box_behind_an_occluder_matches_finite_differences() {
    check("nlos_occluder.toml", "hidden_x", 0.5, 0.01, cosine_first_segments);
}

fn cosine_first_segments(s: &mut difftransient::Scene) {
    s.nlos.as_mut().unwrap().hidden.probability = 0.0
}

/// The same box rendered with BDPT: its interior derivative through every (s, t) strategy of
/// a capture (all vertices in material form, `integrator::bdpt::sensor`), plus the same
/// boundary term.
#[test]
fn bdpt_on_a_hidden_box_behind_an_occluder_matches_finite_differences() {
    let bdpt = Some(IntegratorKind::Bdpt);
    check_with(
        bdpt,
        "nlos_occluder.toml",
        "hidden_x",
        0.5,
        0.01,
        4096,
        cosine_first_segments,
    );
}

/// scenes/nlos_plate_between_panels.toml: the black plate between two white panels that face
/// each other, two bounces. All of the derivative is the shadow the plate casts from one
/// panel onto the other: segments between two hidden surfaces, which only the edge-directed
/// draws find (the light- and sensor-directed draws add exactly 0 here; without the
/// edge-directed ones the derivative would be 0). Its finite difference is noisier than the
/// other scenes' (each path the plate's edge sweeps over is a jump of a two-bounce path), so
/// the check takes 24576 samples to resolve 6 %.
#[test]
fn a_black_plate_between_two_panels_matches_finite_differences() {
    check_at("nlos_plate_between_panels.toml", "plate_z", 0.95, 0.02, 24576);
}
