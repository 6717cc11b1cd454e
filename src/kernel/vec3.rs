//! Structure-of-arrays 3-vectors over any [`Real`].

use super::real::Real;
use std::ops::{Add, Mul, Neg, Sub};

/// A 3-vector whose components are `R` (one lane, eight lanes, or duals).
#[derive(Clone, Copy, Debug)]
pub struct V3<R> {
    pub x: R,
    pub y: R,
    pub z: R,
}

impl<R: Real> V3<R> {
    #[inline(always)]
    pub fn new(x: R, y: R, z: R) -> Self {
        Self { x, y, z }
    }
    #[inline(always)]
    pub fn zero() -> Self {
        Self::splat(glam::Vec3::ZERO)
    }
    /// The same vector in every lane.
    #[inline(always)]
    pub fn splat(v: glam::Vec3) -> Self {
        Self::new(R::splat(v.x), R::splat(v.y), R::splat(v.z))
    }
    /// Gathers one vector per lane.
    #[inline(always)]
    pub fn from_lane_vecs(v: &[glam::Vec3]) -> Self {
        let mut x = [0.0f32; 8];
        let mut y = [0.0f32; 8];
        let mut z = [0.0f32; 8];
        for (i, p) in v.iter().enumerate().take(R::LANES) {
            x[i] = p.x;
            y[i] = p.y;
            z[i] = p.z;
        }
        Self::new(R::from_lanes(&x), R::from_lanes(&y), R::from_lanes(&z))
    }
    /// The value of lane `i` as a plain vector.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> glam::Vec3 {
        glam::Vec3::new(self.x.lane(i), self.y.lane(i), self.z.lane(i))
    }
    /// Drops derivatives.
    #[inline(always)]
    pub fn value(&self) -> V3<R::Value> {
        V3::new(self.x.value(), self.y.value(), self.z.value())
    }
    /// A constant (zero derivatives) from a plain vector.
    #[inline(always)]
    pub fn from_value(v: V3<R::Value>) -> Self {
        Self::new(R::from_value(v.x), R::from_value(v.y), R::from_value(v.z))
    }
    /// The same derivatives with the value `v`.
    #[inline(always)]
    pub fn with_value(&self, v: V3<R::Value>) -> Self {
        *self - Self::from_value(self.value()) + Self::from_value(v)
    }
    #[inline(always)]
    pub fn dot(self, o: Self) -> R {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    #[inline(always)]
    pub fn cross(self, o: Self) -> Self {
        Self::new(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }
    #[inline(always)]
    pub fn length_squared(self) -> R {
        self.dot(self)
    }
    #[inline(always)]
    pub fn length(self) -> R {
        self.length_squared().sqrt()
    }
    /// Unit vector; a zero vector stays zero (no NaN).
    #[inline(always)]
    pub fn normalize(self) -> Self {
        let inv = R::safe_div(R::one(), self.length());
        self * inv
    }
    #[inline(always)]
    pub fn select(m: R::Mask, t: Self, f: Self) -> Self {
        Self::new(R::select(m, t.x, f.x), R::select(m, t.y, f.y), R::select(m, t.z, f.z))
    }
    /// Lanes whose three components are all finite.
    #[inline(always)]
    pub fn is_finite(self) -> R::Mask {
        self.x.is_finite() & self.y.is_finite() & self.z.is_finite()
    }
    /// Componentwise `a + b * s`.
    #[inline(always)]
    pub fn add_scaled(self, b: Self, s: R) -> Self {
        self + b * s
    }
    /// An orthonormal basis (s, t) around unit `n` (Duff et al. 2017, branchless).
    #[inline(always)]
    pub fn orthonormal_basis(self) -> (Self, Self) {
        let n = self;
        let sign = R::select(n.z.ge(R::zero()), R::one(), -R::one());
        let a = -R::one() / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Self::new(R::one() + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Self::new(b, sign + n.y * n.y * a, -n.y);
        (s, t)
    }
}

impl<R: Real> Add for V3<R> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl<R: Real> Sub for V3<R> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl<R: Real> Neg for V3<R> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self::new(-self.x, -self.y, -self.z)
    }
}
impl<R: Real> Mul<R> for V3<R> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, s: R) -> Self {
        Self::new(self.x * s, self.y * s, self.z * s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wide::f32x8;

    #[test]
    fn basis_is_orthonormal_including_poles() {
        for n in [
            glam::Vec3::Z,
            -glam::Vec3::Z,
            glam::Vec3::new(0.3, -0.5, 0.1).normalize(),
            glam::Vec3::new(1e-7, 0.0, -1.0).normalize(),
        ] {
            let (s, t) = V3::<f32>::splat(n).orthonormal_basis();
            let (s, t) = (s.lane(0), t.lane(0));
            assert!((s.length() - 1.0).abs() < 1e-5 && (t.length() - 1.0).abs() < 1e-5);
            assert!(s.dot(t).abs() < 1e-5 && s.dot(n).abs() < 1e-5 && t.dot(n).abs() < 1e-5);
        }
    }

    #[test]
    fn normalize_zero_is_zero() {
        let v = V3::<f32x8>::zero().normalize();
        assert_eq!(v.lane(4), glam::Vec3::ZERO);
    }
}
