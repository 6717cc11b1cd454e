//! Primary rays: pixel filter importance sampling and the pinhole projection.

use crate::kernel::{Real, V3};
use crate::scene::{Camera, PixelFilter};
use glam::Vec3;

/// Samples 1-D offsets (pixels) from a separable filter by inverting its tabulated CDF.
/// With filter importance sampling every sample has weight 1 (pbrt-v4's `FilterSampler`).
#[derive(Clone, Debug)]
pub struct FilterSampler {
    filter: PixelFilter,
    /// 1 / ∫ f over [-radius, radius]: turns the filter into the density h that it samples.
    norm: f32,
    radius: f32,
    /// The table's half-width: the radius, or `GAUSSIAN_REACH` σ when that is less.
    span: f32,
    /// CDF at `TABLE` uniformly spaced offsets over [-span, span]; empty for the box.
    cdf: Vec<f32>,
}

const TABLE: usize = 512;

/// How far out, in standard deviations, a Gaussian filter's table reaches: beyond it the
/// filter is below e⁻⁵⁰ of its peak. A narrow Gaussian (σ = 0.01 px under the default radius
/// 1.5) thus keeps its 512 rows on its bell instead of spreading them over [−r, r], where
/// every row but one read 0.
const GAUSSIAN_REACH: f64 = 10.0;

/// The separable filter f(x) (unnormalised) at offset `x` pixels, in f64 for the table.
/// The Gaussian is e^(−x²/2σ²) − e^(−r²/2σ²), written as e^(−r²/2σ²)·expm1((r² − x²)/2σ²)
/// where the two terms are close (σ ≫ r), which subtracted as written left 0 in f32 for
/// σ = 10⁶ and r = 1.5, and the table then sampled the filter's edge alone.
fn filter_value(filter: PixelFilter, x: f64) -> f64 {
    match filter {
        PixelFilter::Box => f64::from(u8::from(x.abs() <= 0.5)),
        PixelFilter::Tent { radius } => (radius as f64 - x.abs()).max(0.0),
        PixelFilter::Gaussian { sigma, radius } => {
            let (r, inv) = (radius as f64, 1.0 / (2.0 * sigma as f64 * sigma as f64));
            if x.abs() >= r {
                0.0
            } else if r * r * inv < 20.0 {
                (-r * r * inv).exp() * ((r * r - x * x) * inv).exp_m1()
            } else {
                (-x * x * inv).exp() - (-r * r * inv).exp()
            }
        }
    }
}

impl FilterSampler {
    pub fn new(filter: PixelFilter) -> Self {
        let radius = match filter {
            PixelFilter::Box => {
                return Self {
                    filter,
                    norm: 1.0,
                    radius: 0.5,
                    span: 0.5,
                    cdf: Vec::new(),
                };
            }
            PixelFilter::Tent { radius } | PixelFilter::Gaussian { radius, .. } => radius,
        };
        // the table's half-width: the radius, or GAUSSIAN_REACH σ inside it
        let span = match filter {
            PixelFilter::Gaussian { sigma, radius } => (radius as f64).min(GAUSSIAN_REACH * sigma as f64),
            _ => radius as f64,
        };
        // trapezoid rule on a fine grid, then normalise
        let mut cdf = vec![0.0f64; TABLE + 1];
        let h = 2.0 * span / TABLE as f64;
        for i in 0..TABLE {
            let x0 = -span + i as f64 * h;
            cdf[i + 1] = cdf[i] + 0.5 * h * (filter_value(filter, x0) + filter_value(filter, x0 + h));
        }
        // ∫ f by Simpson's rule on the same grid (exact for the tent, whose kink at 0 is a
        // node; the Gaussian's table spans at least 25 rows per σ), for the density h = f / ∫f
        let simpson = (0..=TABLE)
            .map(|i| {
                let w = if i == 0 || i == TABLE { 1.0 } else { [2.0, 4.0][i % 2] };
                w * filter_value(filter, -span + i as f64 * h)
            })
            .sum::<f64>()
            * h
            / 3.0;
        let total = cdf[TABLE];
        Self {
            filter,
            norm: (1.0 / simpson) as f32,
            radius,
            span: span as f32,
            cdf: cdf.iter().map(|c| (c / total) as f32).collect(),
        }
    }

    /// Support half-width in pixels.
    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// The normalised 1-D filter density h(x) (∫h = 1) at offset `x` pixels from a pixel
    /// centre. The box has h = 1 on (-½, ½) and ½ at ±½, where it steps. No estimator
    /// differentiates it: film points stay fixed under the parameters (the vertex the pinhole
    /// sees moves along its ray).
    ///
    /// A film point exactly on the line between two pixels thus counts half in each. Only a
    /// point drawn on an edge lands there with any probability: an edge whose projection lies
    /// on that line (a silhouette or crease in the plane of the camera's axis, seen by an even
    /// number of columns or rows). Each pixel's value then has a kink in θ: its derivative
    /// from one side takes the whole boundary term and from the other side none of it. The
    /// half in each is their mean, the derivative a central finite difference estimates.
    /// Before, the pixel on the upper side took it all (independent sweep: a faceted ball
    /// centred in a 16-pixel-wide image, z = −29 and +33 on columns 7 and 8).
    #[inline]
    pub fn density(&self, x: f32) -> f32 {
        match self.filter {
            PixelFilter::Box => {
                if x.abs() < 0.5 {
                    1.0
                } else if x.abs() == 0.5 {
                    0.5
                } else {
                    0.0
                }
            }
            PixelFilter::Tent { radius } => (radius - x.abs()).max(0.0) * self.norm,
            PixelFilter::Gaussian { .. } => filter_value(self.filter, x as f64) as f32 * self.norm,
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
        let h = 2.0 * self.span / TABLE as f32;
        -self.span + (i as f32 - 1.0 + frac) * h
    }
}

/// Where a world point lands on the film, and the pinhole's importance towards it.
///
/// A pixel j measures I_j = ∫ h_j(u) L(ω(u)) du over film points u (pixels), with h_j the
/// normalised filter around its centre. Changing variables to directions, du = dω / (a cos³θ)
/// with a the pixel area on the image plane at unit distance, so the importance per unit solid
/// angle is W_j(ω) = h_j(u(ω)) · `importance`, `importance` = 1 / (a cos³θ). A connection from
/// a scene point x to the camera adds β · f_s · |cos θ_x| / `dist2` · W_j.
#[derive(Clone, Copy, Debug)]
pub struct CameraProjection {
    /// Film coordinates in pixels (origin top-left, y down), as [`CameraSampler::direction`].
    pub fx: f32,
    pub fy: f32,
    /// Cosine between the camera's forward axis and the direction to the point.
    pub cos: f32,
    /// 1 / (a cos³θ), per steradian.
    pub importance: f32,
    /// Squared distance from the pinhole.
    pub dist2: f32,
}

/// [`CameraProjection`] per lane, in the kernel's number type.
#[derive(Clone, Copy, Debug)]
pub struct LaneProjection<R: Real> {
    pub fx: R,
    pub fy: R,
    /// 1 / (a cos³θ), per steradian.
    pub importance: R,
    pub dist2: R,
    pub visible: R::Mask,
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

    /// The film point a world point projects to, for connections to the camera (light tracing
    /// and the sensor end of boundary paths). `None` behind the camera or outside the film
    /// (widened by the filter radius, since a filter reaches neighbouring pixels).
    pub fn project(&self, p: Vec3) -> Option<CameraProjection> {
        let d = p - self.position;
        let z = d.dot(self.fwd);
        let dist2 = d.length_squared();
        if !(z > 0.0) || !dist2.is_finite() {
            return None;
        }
        let sx = d.dot(self.right) / z;
        let sy = d.dot(self.up) / z;
        let fx = (sx / (self.tan_half * self.aspect) + 1.0) * 0.5 * self.width;
        let fy = (1.0 - sy / self.tan_half) * 0.5 * self.height;
        let r = self.filter.radius;
        if !(fx > -r && fx < self.width + r && fy > -r && fy < self.height + r) {
            return None;
        }
        let cos = z / dist2.sqrt();
        // Pixel area on the image plane at distance 1.
        let a = (2.0 * self.tan_half * self.aspect / self.width) * (2.0 * self.tan_half / self.height);
        Some(CameraProjection {
            fx,
            fy,
            cos,
            importance: 1.0 / (a * cos * cos * cos),
            dist2,
        })
    }

    /// Calls `f(px, py, h)` for every pixel whose filter reaches film point (fx, fy), with the
    /// separable filter weight h = h(fx − px − ½)·h(fy − py − ½). The weights of one point
    /// sum to 1 over the film's interior.
    pub fn for_each_pixel(&self, fx: f32, fy: f32, f: impl FnMut(u32, u32, f32)) {
        self.for_each_pixel_in_rows(fx, fy, 0..self.height as u32, f);
    }

    /// [`for_each_pixel`](Self::for_each_pixel) for the pixels of film rows `rows` only (a
    /// band of the film that one worker bins): a point whose filter misses them costs two
    /// comparisons.
    pub fn for_each_pixel_in_rows(
        &self,
        fx: f32,
        fy: f32,
        rows: std::ops::Range<u32>,
        mut f: impl FnMut(u32, u32, f32),
    ) {
        let r = self.filter.radius;
        let (x0, x1) = (
            (fx - 0.5 - r).floor().max(0.0),
            (fx - 0.5 + r).ceil().min(self.width - 1.0),
        );
        let (y0, y1) = (
            (fy - 0.5 - r).floor().max(rows.start as f32),
            (fy - 0.5 + r).ceil().min(self.height.min(rows.end as f32) - 1.0),
        );
        let mut py = y0;
        while py <= y1 {
            let hy = self.filter.density(fy - py - 0.5);
            let mut px = x0;
            while px <= x1 {
                let hx = self.filter.density(fx - px - 0.5);
                if hx * hy != 0.0 {
                    f(px as u32, py as u32, hx * hy);
                }
                px += 1.0;
            }
            py += 1.0;
        }
    }

    /// [`project`](Self::project) for a packet of points (light-tracing splats, BDPT t = 1,
    /// call it with plain lanes: film points never move under the parameters). Generic over
    /// the number type, so dual inputs carry derivatives through film coordinates, importance
    /// 1/(a cos³θ) and squared distance. `visible` marks lanes in front of the camera and on
    /// the film (widened by the filter radius).
    pub fn project_lanes<R: Real>(&self, p: &V3<R>) -> LaneProjection<R> {
        let d = *p - V3::splat(self.position);
        let z = d.dot(V3::splat(self.fwd));
        let dist2 = d.length_squared();
        let inv_z = R::safe_div(R::one(), z);
        let sx = d.dot(V3::splat(self.right)) * inv_z;
        let sy = d.dot(V3::splat(self.up)) * inv_z;
        let fx = (sx.mul_f(1.0 / (self.tan_half * self.aspect)) + R::one()).mul_f(0.5 * self.width);
        let fy = (R::one() - sy.mul_f(1.0 / self.tan_half)).mul_f(0.5 * self.height);
        let cos = z * R::safe_div(R::one(), dist2.sqrt());
        let a = (2.0 * self.tan_half * self.aspect / self.width) * (2.0 * self.tan_half / self.height);
        let importance = R::safe_div(R::one(), (cos * cos * cos).mul_f(a));
        let r = R::Value::splat(self.filter.radius);
        let (fxv, fyv) = (fx.value(), fy.value());
        let visible = z.value().gt(R::Value::zero())
            & fxv.gt(-r)
            & fxv.lt(R::Value::splat(self.width) + r)
            & fyv.gt(-r)
            & fyv.lt(R::Value::splat(self.height) + r)
            & importance.value().is_finite();
        LaneProjection {
            fx,
            fy,
            importance,
            dist2,
            visible,
        }
    }

    pub fn filter(&self) -> &FilterSampler {
        &self.filter
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

    /// The filter density integrates to 1.
    #[test]
    fn filter_density_is_normalised() {
        for filter in [
            PixelFilter::Box,
            PixelFilter::Tent { radius: 1.0 },
            PixelFilter::Tent { radius: 1.7 },
            PixelFilter::Gaussian {
                sigma: 0.5,
                radius: 1.5,
            },
        ] {
            let fs = FilterSampler::new(filter);
            let n = 40_000;
            let h = 2.0 * fs.radius() as f64 / n as f64;
            let total: f64 = (0..n)
                .map(|i| fs.density(-fs.radius() + (i as f32 + 0.5) * h as f32) as f64 * h)
                .sum();
            assert!((total - 1.0).abs() < 1e-3, "{filter:?}: integral {total}");
        }
    }

    /// Filters at the limits of what a scene may declare (`scene::limits::MIN_FILTER_WIDTH`,
    /// `MAX_FILTER_WIDTH`) are sampled with their own variance, and their density integrates
    /// to 1. Before, a Gaussian of σ = 10⁻³ under radius 1.5 was drawn uniformly over the
    /// table's rows around 0 (variance 11 σ²), and one of σ = 10⁶ (beyond the limits now) read
    /// 0 everywhere in f32, so its table drew the edge alone.
    #[test]
    fn filters_at_the_width_limits_keep_their_shape() {
        let n = 200_000;
        // a Gaussian cut at r = σ, less its edge value e^(−½): ∫t²f / ∫f over t ∈ [−1, 1]
        let (mass, edge) = (
            (2.0 * std::f64::consts::PI).sqrt() * libm::erf(std::f64::consts::FRAC_1_SQRT_2),
            (-0.5f64).exp(),
        );
        let truncated = (mass - 2.0 * edge - 2.0 / 3.0 * edge) / (mass - 2.0 * edge);
        let cases = [
            (
                PixelFilter::Gaussian {
                    sigma: 1e-3,
                    radius: 1.5,
                },
                1e-6,
            ),
            (
                PixelFilter::Gaussian {
                    sigma: 64.0,
                    radius: 1.5,
                },
                // nearly the parabola r² − x² (variance r²/5), to O(r²/σ²) = 5·10⁻⁴
                1.5 * 1.5 / 5.0,
            ),
            (
                PixelFilter::Gaussian {
                    sigma: 1e-3,
                    radius: 1e-3,
                },
                1e-6 * truncated,
            ),
            (PixelFilter::Tent { radius: 1e-3 }, 1e-6 / 6.0),
            (PixelFilter::Tent { radius: 64.0 }, 64.0 * 64.0 / 6.0),
        ];
        for (filter, want) in cases {
            let fs = FilterSampler::new(filter);
            let var = (0..n)
                .map(|i| fs.sample((i as f32 + 0.5) / n as f32) as f64)
                .map(|x| x * x)
                .sum::<f64>()
                / n as f64;
            assert!(
                (var / want - 1.0).abs() < 0.01,
                "{filter:?}: variance {var}, want {want}"
            );
            let m = 400_000;
            let h = 2.0 * fs.radius() as f64 / m as f64;
            let total: f64 = (0..m)
                .map(|i| fs.density((-fs.radius() as f64 + (i as f64 + 0.5) * h) as f32) as f64 * h)
                .sum();
            assert!((total - 1.0).abs() < 1e-3, "{filter:?}: integral {total}");
        }
    }

    /// `project` inverts `direction`, splat weights sum to 1 inside the film, and the
    /// importance integrates to one pixel per pixel: Σ_j ∫ W_j dω = number of pixels.
    #[test]
    fn projection_inverts_primary_rays() {
        let cam = Camera {
            position: Vec3::new(0.3, 1.0, 3.0),
            look_at: Vec3::new(0.0, 0.9, 0.0),
            up: Vec3::Y,
            fov_y_deg: 45.0,
        };
        for filter in [PixelFilter::Box, PixelFilter::Tent { radius: 1.0 }] {
            let cs = CameraSampler::new(&cam, 40, 30, filter);
            for &(fx, fy) in &[(20.0f32, 15.0f32), (3.3, 27.9), (39.5, 0.5), (11.25, 8.75)] {
                let d = cs.direction(fx, fy);
                let p = cs.position + d * 2.5;
                let pr = cs.project(p).expect("in front of the camera");
                assert!(
                    (pr.fx - fx).abs() < 1e-3 && (pr.fy - fy).abs() < 1e-3,
                    "{fx},{fy} -> {pr:?}"
                );
                let mut sum = 0.0;
                cs.for_each_pixel(pr.fx, pr.fy, |_, _, h| sum += h);
                if fx > 1.0 && fy > 1.0 && fx < 39.0 && fy < 29.0 {
                    assert!((sum - 1.0).abs() < 1e-4, "{filter:?}: weights sum {sum}");
                }
            }
            assert!(cs.project(cs.position - cs.fwd * 2.0).is_none());
            // ∫ importance dω over the film = number of pixels, with the solid angle of each
            // sub-pixel taken from the Jacobian of `direction` (not from the cos³ formula).
            let mut integral = 0.0f64;
            let sub = 4;
            let e = 1e-2f32;
            for y in 0..30 * sub {
                for x in 0..40 * sub {
                    let (fx, fy) = ((x as f32 + 0.5) / sub as f32, (y as f32 + 0.5) / sub as f32);
                    let pr = cs.project(cs.position + cs.direction(fx, fy)).unwrap();
                    let dx = (cs.direction(fx + e, fy) - cs.direction(fx - e, fy)) / (2.0 * e);
                    let dy = (cs.direction(fx, fy + e) - cs.direction(fx, fy - e)) / (2.0 * e);
                    let d_omega = dx.cross(dy).length() as f64 / (sub * sub) as f64;
                    integral += pr.importance as f64 * d_omega;
                }
            }
            assert!((integral - 1200.0).abs() < 1e-2 * 1200.0, "{integral}");
        }
    }
}
