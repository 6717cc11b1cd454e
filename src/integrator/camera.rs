//! Primary rays: pixel filter importance sampling and the pinhole projection.

use crate::kernel::{Real, V3};
use crate::scene::{Camera, PixelFilter};
use glam::Vec3;

/// Samples 1-D offsets (pixels) from a separable filter by inverting its tabulated CDF.
/// With filter importance sampling every sample has weight 1 (pbrt-v4's `FilterSampler`).
#[derive(Clone, Debug)]
pub struct FilterSampler {
    radius: f32,
    /// CDF at `TABLE` uniformly spaced offsets over [-radius, radius]; empty for the box.
    cdf: Vec<f32>,
}

const TABLE: usize = 512;

impl FilterSampler {
    pub fn new(filter: PixelFilter) -> Self {
        let (radius, f): (f32, Box<dyn Fn(f32) -> f32>) = match filter {
            PixelFilter::Box => {
                return Self {
                    radius: 0.5,
                    cdf: Vec::new(),
                };
            }
            PixelFilter::Tent { radius } => (radius, Box::new(move |x: f32| (radius - x.abs()).max(0.0))),
            PixelFilter::Gaussian { sigma, radius } => {
                let edge = (-radius * radius / (2.0 * sigma * sigma)).exp();
                (
                    radius,
                    Box::new(move |x: f32| ((-x * x / (2.0 * sigma * sigma)).exp() - edge).max(0.0)),
                )
            }
        };
        // trapezoid rule on a fine grid, then normalise
        let mut cdf = vec![0.0f64; TABLE + 1];
        let h = 2.0 * radius as f64 / TABLE as f64;
        for i in 0..TABLE {
            let x0 = -radius as f64 + i as f64 * h;
            cdf[i + 1] = cdf[i] + 0.5 * h * (f(x0 as f32) as f64 + f((x0 + h) as f32) as f64);
        }
        let total = cdf[TABLE].max(1e-30);
        Self {
            radius,
            cdf: cdf.iter().map(|c| (c / total) as f32).collect(),
        }
    }

    /// Offset in pixels for uniform `u`.
    #[inline]
    pub fn sample(&self, u: f32) -> f32 {
        if self.cdf.is_empty() {
            return u - 0.5;
        }
        let i = self.cdf.partition_point(|&c| c <= u).clamp(1, TABLE);
        let (c0, c1) = (self.cdf[i - 1], self.cdf[i]);
        let frac = if c1 > c0 { (u - c0) / (c1 - c0) } else { 0.5 };
        let h = 2.0 * self.radius / TABLE as f32;
        -self.radius + (i as f32 - 1.0 + frac) * h
    }
}

/// The pinhole camera in the form the kernel uses.
#[derive(Clone, Debug)]
pub struct CameraSampler {
    pub position: Vec3,
    right: Vec3,
    up: Vec3,
    fwd: Vec3,
    tan_half: f32,
    aspect: f32,
    width: f32,
    height: f32,
    filter: FilterSampler,
}

impl CameraSampler {
    pub fn new(cam: &Camera, width: u32, height: u32, filter: PixelFilter) -> Self {
        let (right, up, fwd) = cam.frame();
        Self {
            position: cam.position,
            right,
            up,
            fwd,
            tan_half: (cam.fov_y_deg.to_radians() * 0.5).tan(),
            aspect: width as f32 / height as f32,
            width: width as f32,
            height: height as f32,
            filter: FilterSampler::new(filter),
        }
    }

    /// Unit directions through pixel (px, py) offset by the filter sample (u1, u2).
    pub fn sample<V: Real>(&self, px: &[u32; 8], py: &[u32; 8], u1: V, u2: V) -> V3<V> {
        let mut d = [Vec3::ZERO; 8];
        for i in 0..V::LANES {
            let fx = px[i] as f32 + 0.5 + self.filter.sample(u1.lane(i));
            let fy = py[i] as f32 + 0.5 + self.filter.sample(u2.lane(i));
            d[i] = self.direction(fx, fy);
        }
        V3::from_lane_vecs(&d[..V::LANES])
    }

    /// Unit direction through film point (fx, fy) in pixels (origin top-left, y down).
    pub fn direction(&self, fx: f32, fy: f32) -> Vec3 {
        let sx = (2.0 * fx / self.width - 1.0) * self.tan_half * self.aspect;
        let sy = (1.0 - 2.0 * fy / self.height) * self.tan_half;
        (self.fwd + self.right * sx + self.up * sy).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sampled offsets follow the filter: tent of radius 1 has variance r²/6, Gaussian σ²
    /// (slightly less when truncated), and the box is uniform on [-0.5, 0.5).
    #[test]
    fn filter_samples_have_the_filter_variance() {
        let n = 20_000;
        let var = |fs: &FilterSampler| {
            (0..n)
                .map(|i| fs.sample((i as f32 + 0.5) / n as f32))
                .map(|x| (x * x) as f64)
                .sum::<f64>()
                / n as f64
        };
        assert!((var(&FilterSampler::new(PixelFilter::Box)) - 1.0 / 12.0).abs() < 1e-3);
        assert!((var(&FilterSampler::new(PixelFilter::Tent { radius: 1.0 })) - 1.0 / 6.0).abs() < 2e-3);
        let g = var(&FilterSampler::new(PixelFilter::Gaussian {
            sigma: 0.5,
            radius: 3.0,
        }));
        assert!((g - 0.25).abs() < 3e-3, "gaussian variance {g}");
    }
}
