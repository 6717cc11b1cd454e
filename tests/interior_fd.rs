//! The interior derivative (Algorithm 1) against central finite differences with common
//! random numbers, for every parameter kind, on a scene where no parameter moves a visibility
//! boundary (scenes/diff_room.toml: camera and point light inside a convex room).
//!
//! The statistics (Student-t z of AD − FD over seeds, widened by the finite difference's own
//! error) are in tests/common/fd.rs, shared with the BDPT tests (tests/bdpt_fd.rs).

use crate::common;

/// The path tracer on diff_room.toml: 12 seeds of 4 samples per pixel.
fn check_param(name: &str, value: f32, h: f32) {
    common::fd::FdCheck {
        scene: "diff_room.toml",
        k: 12,
        spp: 4,
        integrator: None,
        edit: |_| {},
        require_signal: true,
        power_exemption: None,
        boundary: difftransient::render::BoundaryMode::Full,
    }
    .check(name, value, h);
}

#[test]
fn translate_matches_finite_differences() {
    check_param("room_z", 0.0, 0.004);
}

#[test]
fn rotate_matches_finite_differences() {
    check_param("room_rot_y", 0.0, 0.2);
}

#[test]
fn scale_matches_finite_differences() {
    check_param("room_scale_z", 3.0, 0.004);
}

#[test]
fn albedo_matches_finite_differences() {
    check_param("albedo", 0.6, 0.01);
}

#[test]
fn radiance_matches_finite_differences() {
    check_param("intensity", 5.0, 0.1);
}

#[test]
fn eta_matches_finite_differences() {
    check_param("eta", 1.0, 0.005);
}

#[test]
fn pulse_offset_matches_finite_differences() {
    check_param("lamp_offset", 0.0, 0.005);
}
