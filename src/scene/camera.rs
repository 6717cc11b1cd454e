//! The perspective sensor and its pixel filter.

use glam::Vec3;

/// Pixel reconstruction filter. Samples are drawn from the filter itself (filter importance
/// sampling), so every sample has weight 1 and lands in exactly one pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PixelFilter {
    /// Uniform over the pixel (radius 0.5 px).
    Box,
    /// Triangle of the given radius in pixels (default 1).
    Tent {
        /// Half-width of the triangle, pixels (> 0).
        radius: f32,
    },
    /// Gaussian with `sigma` pixels, truncated at `radius` pixels (defaults 0.5 and 1.5).
    Gaussian {
        /// Standard deviation, pixels (> 0).
        sigma: f32,
        /// Truncation radius, pixels (> 0).
        radius: f32,
    },
}

/// A pinhole camera looking from `position` to `look_at`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Centre of projection, metres relative to [`super::Scene::render_origin`].
    pub position: Vec3,
    /// A point the optical axis passes through (same frame as `position`).
    pub look_at: Vec3,
    /// Up direction; only its component orthogonal to the view direction is used.
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
