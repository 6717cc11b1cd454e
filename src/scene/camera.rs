//! The perspective sensor and its pixel filter.

use glam::Vec3;

/// Pixel reconstruction filter. Samples are drawn from the filter itself (filter importance
/// sampling), so every sample has weight 1 and lands in exactly one pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PixelFilter {
    /// Uniform over the pixel (radius 0.5 px).
    Box,
    /// Triangle of the given radius in pixels (default 1).
    Tent { radius: f32 },
    /// Gaussian with `sigma` pixels, truncated at `radius` pixels (defaults 0.5 and 1.5).
    Gaussian { sigma: f32, radius: f32 },
}

/// A pinhole camera looking from `position` to `look_at`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub position: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    /// Vertical field of view, degrees.
    pub fov_y_deg: f32,
}

impl Camera {
    /// Orthonormal frame (right, up, forward).
    pub fn frame(&self) -> (Vec3, Vec3, Vec3) {
        let fwd = (self.look_at - self.position).normalize();
        let right = fwd.cross(self.up).normalize();
        let up = right.cross(fwd);
        (right, up, fwd)
    }
}
