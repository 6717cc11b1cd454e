//! BDPT's interior derivative (Algorithm 1 with MIS over every (s, t) strategy) against
//! central finite differences with common random numbers, on diff_room.toml (camera and
//! point light inside a convex room: no parameter moves a visibility boundary). Statistics
//! as in tests/interior_fd.rs (tests/common/fd.rs).
//!
//! Two pixel filters:
//! - box (the scene's): a derivative render leaves out the t = 1 strategy (its splat weight
//!   is discontinuous in the moving film point). The finite differences are taken of the
//!   primal that the derivative render returns, i.e. of the same estimator, so common random
//!   numbers cancel its noise (with t = 1 in the FD renders only, AD − FD would carry the
//!   rare, heavy-tailed t = 1 splats; tests/bdpt_forward.rs checks separately that leaving
//!   out t = 1 does not change the expectation);
//! - tent: t = 1 runs and its splat weight h_j(u(θ)) is differentiated.
//!
//! Also: laser_room.toml, where the laser spot (the first light vertex) has intensity Φ·ρ/π,
//! for BDPT and the path tracer; and splat_plane.toml, where t = 1 carries most of the image.

mod common;
use common::fd::FdCheck;
use difftransient::scene::{IntegratorKind, PixelFilter};

fn bdpt(edit: fn(&mut difftransient::Scene)) -> FdCheck {
    FdCheck {
        scene: "diff_room.toml",
        k: 12,
        spp: 4,
        integrator: Some(IntegratorKind::Bdpt),
        edit,
        fd_from_diff_render: true,
        require_signal: true,
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

/// scenes/splat_plane.toml (tent filter): t = 1 carries most of the image and its splats
/// move on the film.
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
        fd_from_diff_render: true,
        require_signal,
    }
}

/// Sliding the plane within itself changes nothing: the t = 1 terms in G, J and ∂h_j/∂u must
/// cancel pixel by pixel (leaving out ∂h_j/∂u leaves a dipole around the light).
#[test]
fn bdpt_splat_weight_derivative_cancels_for_a_sliding_plane() {
    splat_plane(false).check("plane_x", 0.0, 0.01);
}

#[test]
fn bdpt_splat_weight_derivative_matches_finite_differences_for_a_tilt() {
    splat_plane(true).check("plane_tilt", 0.0, 0.2);
}

/// The same slide with a box filter: t = 1 is left out of the derivative render (a box splat
/// weight has no usable derivative), and the remaining strategies give exactly 0 like the
/// finite differences. Were t = 1 kept, its G and J terms would not cancel without ∂h_j/∂u
/// and this test fails (Σz² ≈ 1900 over 220 pixels when tried).
#[test]
fn bdpt_box_filter_leaves_out_t1_for_a_sliding_plane() {
    splat_plane_with(false, |s| s.film.filter = PixelFilter::Box).check("plane_x", 0.0, 0.01);
}

#[test]
fn bdpt_tent_pulse_offset_matches_finite_differences() {
    tent().check("lamp_offset", 0.0, 0.005);
}

/// scenes/laser_room.toml: the laser spot is the first light vertex; its intensity Φ·ρ/π
/// depends on the power Φ and on the albedo ρ of the wall it lights.
fn laser(integrator: IntegratorKind) -> FdCheck {
    FdCheck {
        scene: "laser_room.toml",
        k: 12,
        spp: 4,
        integrator: Some(integrator),
        edit: |_| {},
        fd_from_diff_render: true,
        require_signal: true,
    }
}

#[test]
fn laser_spot_derivatives_match_finite_differences_in_both_integrators() {
    for kind in [IntegratorKind::Path, IntegratorKind::Bdpt] {
        laser(kind).check("wall_albedo", 0.6, 0.01);
        laser(kind).check("laser_power", 10.0, 0.2);
        laser(kind).check("room_z", 0.0, 0.004);
    }
}
