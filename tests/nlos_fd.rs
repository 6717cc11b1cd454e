//! Interior derivatives of NLOS captures against central finite differences with common random
//! numbers (the statistics of tests/common/fd.rs: per-pixel time sums and per-bin totals,
//! Student-t z of AD − FD over 12 seeds widened by the finite difference's own error), for the
//! parameters that move no geometry: albedo (of the hidden object, and of the relay wall, which
//! weights the sensor points and the laser spots), laser power, pulse offset and η (with the
//! relay legs both left out and counted), with the path tracer and with BDPT (whose t = 1
//! strategy joins the light subpath to the sensor point: the wall's albedo weights it, and its
//! OPL ends with the wall's leg to the SPAD where that counts). Geometry:
//! tests/nlos_boundary_fd.rs.

use crate::common;
use difftransient::scene::{IntegratorKind, RelayLegs};
use difftransient::temporal::{Gate, Pulse};

fn check(name: &str, value: f32, h: f32, edit: fn(&mut difftransient::Scene)) {
    check_with("nlos_occluder.toml", None, name, value, h, edit);
}

fn check_with(
    scene: &'static str,
    integrator: Option<IntegratorKind>,
    name: &str,
    value: f32,
    h: f32,
    edit: fn(&mut difftransient::Scene),
) {
    common::fd::FdCheck {
        scene,
        k: 12,
        spp: 64,
        integrator,
        edit,
        require_signal: true,
        power_exemption: None,
        boundary: difftransient::render::BoundaryMode::Full,
    }
    .check(name, value, h);
}

/// Time derivatives: a wider pulse and gate than the scene's (σ 4 cm and 2 cm of OPL on
/// 2 cm bins) keep the finite difference's truncation error under a percent of the derivative.
fn smooth(s: &mut difftransient::Scene) {
    s.emitters[0].pulse = Pulse::Gaussian { sigma_opl: 0.04 };
    s.film.gate = Gate::Gaussian { sigma_opl: 0.02 };
}

/// [`smooth`] with the relay legs counted: a time axis over [5.5, 11.9] m, where the capture
/// then lies (laser and SPAD legs of 4.1 to 6.8 m).
fn legs_included(s: &mut difftransient::Scene) {
    smooth(s);
    s.nlos.as_mut().unwrap().relay_legs = RelayLegs::Included;
    s.film.axis.start_opl = 5.5;
    s.film.axis.bin_width_opl = 0.05;
}

#[test]
fn hidden_albedo_matches_finite_differences() {
    check("hidden_albedo", 0.7, 0.01, |_| {});
}

#[test]
fn wall_albedo_matches_finite_differences() {
    check("wall_albedo", 0.8, 0.01, |_| {});
}

#[test]
fn laser_power_matches_finite_differences() {
    check("laser_power", 1.0, 0.02, |_| {});
}

#[test]
fn pulse_offset_matches_finite_differences() {
    check("laser_offset", 0.0, 0.002, smooth);
    check("laser_offset", 0.0, 0.002, legs_included);
}

#[test]
fn eta_matches_finite_differences() {
    check("eta", 1.0, 0.001, smooth);
    check("eta", 1.0, 0.001, legs_included);
}

/// BDPT on the capture: the sensor point's importance (the wall's albedo) in the t = 1
/// strategy and in the camera subpath's start, the laser point's power in the light
/// subpath's, and the time derivatives of every strategy's OPL, relay legs left out and
/// counted.
#[test]
fn bdpt_derivatives_match_finite_differences() {
    let bdpt = Some(IntegratorKind::Bdpt);
    let scene = "nlos_occluder.toml";
    check_with(scene, bdpt, "wall_albedo", 0.8, 0.01, |_| {});
    check_with(scene, bdpt, "laser_power", 1.0, 0.02, |_| {});
    check_with(scene, bdpt, "laser_offset", 0.0, 0.002, smooth);
    check_with(scene, bdpt, "eta", 1.0, 0.001, smooth);
    check_with(scene, bdpt, "eta", 1.0, 0.001, legs_included);
}

/// BDPT on an exhaustive scan (scenes/nlos_occluder_exhaustive.toml, 4 × 4 laser × 4 × 4
/// sensor points): each film cell's light subpaths start at its own laser point.
#[test]
fn bdpt_derivatives_of_an_exhaustive_scan_match_finite_differences() {
    let bdpt = Some(IntegratorKind::Bdpt);
    let scene = "nlos_occluder_exhaustive.toml";
    check_with(scene, bdpt, "hidden_albedo", 0.7, 0.01, |_| {});
    check_with(scene, bdpt, "wall_albedo", 0.8, 0.01, |_| {});
    check_with(scene, bdpt, "laser_offset", 0.0, 0.002, smooth);
    check_with(scene, bdpt, "eta", 1.0, 0.001, legs_included);
}
