//! BDPT's interior derivative (Algorithm 1 with MIS over every (s, t) strategy) against
//! central finite differences with common random numbers, on diff_room.toml (camera and
//! point light inside a convex room: no parameter moves a visibility boundary). Statistics
//! as in tests/interior_fd.rs (tests/common/fd.rs).
//!
//! Two pixel filters, box (the scene's) and tent; every strategy runs in both, t = 1 moving
//! the vertex the pinhole sees along its camera ray like the others (src/integrator/bdpt/
//! splat.rs). tests/bdpt_parameterisation.rs checks moving lit surfaces with every filter on
//! coarse aggregates, with the statistical power to see a bias of a few percent.
//!
//! Also: laser_room.toml, where the laser spot (the first light vertex) has intensity Φ·ρ/π,
//! for BDPT and the path tracer; and splat_plane.toml, where t = 1 carries most of the image.

use crate::common;
use common::fd::FdCheck;
use difftransient::scene::{IntegratorKind, PixelFilter};

fn bdpt(edit: fn(&mut difftransient::Scene)) -> FdCheck {
    FdCheck {
        scene: "diff_room.toml",
        k: 12,
        spp: 4,
        integrator: Some(IntegratorKind::Bdpt),
        edit,
        require_signal: true,
        power_exemption: None,
        boundary: difftransient::render::BoundaryMode::Full,
    }
}

fn boxed() -> FdCheck {
    bdpt(|_| {})
}

fn tent() -> FdCheck {
    bdpt(|s| s.film.filter = PixelFilter::Tent { radius: 1.0 })
}

#[test]
fn bdpt_box_albedo_matches_finite_differences() {
    boxed().check("albedo", 0.6, 0.01);
}

#[test]
fn bdpt_box_radiance_matches_finite_differences() {
    boxed().check("intensity", 5.0, 0.1);
}

#[test]
fn bdpt_box_eta_matches_finite_differences() {
    boxed().check("eta", 1.0, 0.005);
}

#[test]
fn bdpt_box_translate_matches_finite_differences() {
    boxed().check("room_z", 0.0, 0.004);
}

#[test]
fn bdpt_tent_albedo_matches_finite_differences() {
    tent().check("albedo", 0.6, 0.01);
}

#[test]
fn bdpt_tent_radiance_matches_finite_differences() {
    tent().check("intensity", 5.0, 0.1);
}

#[test]
fn bdpt_tent_eta_matches_finite_differences() {
    tent().check("eta", 1.0, 0.005);
}

#[test]
fn bdpt_tent_translate_matches_finite_differences() {
    tent().check("room_z", 0.0, 0.004);
}

#[test]
fn bdpt_tent_rotate_matches_finite_differences() {
    tent().check("room_rot_y", 0.0, 0.2);
}

/// scenes/splat_plane.toml (tent filter): t = 1 carries most of the image.
fn splat_plane(require_signal: bool) -> FdCheck {
    splat_plane_with(require_signal, |_| {})
}

fn splat_plane_with(require_signal: bool, edit: fn(&mut difftransient::Scene)) -> FdCheck {
    FdCheck {
        scene: "splat_plane.toml",
        k: 12,
        spp: 4,
        integrator: Some(IntegratorKind::Bdpt),
        edit,
        require_signal,
        power_exemption: None,
        boundary: difftransient::render::BoundaryMode::Full,
    }
}

/// Sliding the plane within itself changes nothing, pixel by pixel.
#[test]
fn bdpt_derivative_vanishes_for_a_sliding_plane() {
    splat_plane(false).check("plane_x", 0.0, 0.01);
}

#[test]
fn bdpt_derivative_matches_finite_differences_for_a_tilt() {
    splat_plane(true).check("plane_tilt", 0.0, 0.2);
}

/// The same slide with a box filter: film points never move, so no pixel border is crossed
/// and the box filter needs no special case.
#[test]
fn bdpt_box_filter_derivative_vanishes_for_a_sliding_plane() {
    splat_plane_with(false, |s| s.film.filter = PixelFilter::Box).check("plane_x", 0.0, 0.01);
}

#[test]
fn bdpt_tent_pulse_offset_matches_finite_differences() {
    tent().check("lamp_offset", 0.0, 0.005);
}

/// scenes/laser_room.toml: the laser spot is the first light vertex; its intensity Φ·ρ/π
/// depends on the power Φ and on the albedo ρ of the wall it lights.
fn laser(integrator: IntegratorKind, edit: fn(&mut difftransient::Scene)) -> FdCheck {
    FdCheck {
        scene: "laser_room.toml",
        k: 12,
        spp: 4,
        integrator: Some(integrator),
        edit,
        require_signal: true,
        power_exemption: None,
        boundary: difftransient::render::BoundaryMode::Full,
    }
}

/// Per pixel: the path tracer with the scene's box filter, BDPT with a tent filter. With a
/// box filter, a light-tracing (t = 1) splat of the finite-difference renders that crosses a
/// pixel border as the room moves adds ±f/2h to two pixels: per-pixel finite differences
/// are then unbiased but heavy-tailed (rare entries 18 standard errors off over 12 seeds),
/// so BDPT's box filter is checked on coarse aggregates, where such crossings cancel.
#[test]
fn laser_spot_derivatives_match_finite_differences_in_both_integrators() {
    let tent: fn(&mut difftransient::Scene) = |s| s.film.filter = PixelFilter::Tent { radius: 1.0 };
    for (kind, edit) in [
        (IntegratorKind::Path, (|_| {}) as fn(&mut _)),
        (IntegratorKind::Bdpt, tent),
    ] {
        laser(kind, edit).check("wall_albedo", 0.6, 0.01);
        laser(kind, edit).check("laser_power", 10.0, 0.2);
        laser(kind, edit).check("room_z", 0.0, 0.004);
    }
    let mut boxed = laser(IntegratorKind::Bdpt, |_| {});
    boxed.spp = 16;
    for (name, value, h) in [
        ("wall_albedo", 0.6, 0.01),
        ("laser_power", 10.0, 0.2),
        ("room_z", 0.0, 0.004),
    ] {
        let (_, resolution) = boxed.check_aggregates(name, value, h);
        assert!(
            resolution < 0.04,
            "{name}: resolves only a bias of {:.1} %",
            resolution * 100.0
        );
    }
}
