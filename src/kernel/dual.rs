//! `Dual8<P>`: eight paths with P forward-mode derivative lanes each.
//!
//! `v` holds the value of eight paths; `d[k]` holds ∂v/∂θ_k for each of them. The derivative
//! count is a compile-time constant; the renderer monomorphises a few sizes (1, 2, 4, 8, 16)
//! and picks the smallest that fits the requested parameters, so unused lanes cost nothing.

use super::real::Real;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};
use wide::f32x8;

#[derive(Clone, Copy, Debug)]
pub struct Dual8<const P: usize> {
    pub v: f32x8,
    pub d: [f32x8; P],
}

impl<const P: usize> Dual8<P> {
    #[inline(always)]
    pub fn constant(v: f32x8) -> Self {
        Self { v, d: [f32x8::ZERO; P] }
    }
    /// Applies the chain rule for a unary function with value `fv` and slope `slope`.
    #[inline(always)]
    fn chain(self, fv: f32x8, slope: f32x8) -> Self {
        Self {
            v: fv,
            d: self.d.map(|x| x * slope),
        }
    }
    /// 1/√x, with zero value and derivative where x ≤ 0.
    #[inline(always)]
    pub fn rsqrt(self) -> Self {
        let pos = self.v.simd_gt(f32x8::ZERO);
        let s = f32x8::sqrt(f32x8::max(self.v, f32x8::splat(f32::MIN_POSITIVE)));
        let r = pos.select(f32x8::ONE / s, f32x8::ZERO);
        // d(x^-1/2) = -1/2 x^-3/2
        self.chain(r, r * r * r * f32x8::splat(-0.5))
    }
    /// Error function (Abramowitz–Stegun 7.1.26, |error| < 1.5e-7) with exact slope 2/√π·e^{-x²}.
    #[inline(always)]
    pub fn erf(self) -> Self {
        let x = self.v;
        let ax = x.abs();
        let t = f32x8::ONE / (f32x8::ONE + f32x8::splat(0.327_591_1) * ax);
        let poly = t
            * (f32x8::splat(0.254_829_6)
                + t * (f32x8::splat(-0.284_496_74)
                    + t * (f32x8::splat(1.421_413_8)
                        + t * (f32x8::splat(-1.453_152_1) + t * f32x8::splat(1.061_405_4)))));
        let g = (-(x * x)).exp();
        let y = f32x8::ONE - poly * g;
        let v = x.simd_lt(f32x8::ZERO).select(-y, y);
        self.chain(v, g * f32x8::splat(std::f32::consts::FRAC_2_SQRT_PI))
    }
}

impl<const P: usize> Add for Dual8<P> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self {
            v: self.v + o.v,
            d: std::array::from_fn(|k| self.d[k] + o.d[k]),
        }
    }
}
impl<const P: usize> Sub for Dual8<P> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self {
            v: self.v - o.v,
            d: std::array::from_fn(|k| self.d[k] - o.d[k]),
        }
    }
}
impl<const P: usize> Mul for Dual8<P> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self {
            v: self.v * o.v,
            d: std::array::from_fn(|k| self.d[k] * o.v + self.v * o.d[k]),
        }
    }
}
impl<const P: usize> Div for Dual8<P> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        let inv = f32x8::ONE / o.v;
        let v = self.v * inv;
        Self {
            v,
            d: std::array::from_fn(|k| (self.d[k] - v * o.d[k]) * inv),
        }
    }
}
impl<const P: usize> Neg for Dual8<P> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self {
            v: -self.v,
            d: self.d.map(|x| -x),
        }
    }
}
impl<const P: usize> AddAssign for Dual8<P> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}
impl<const P: usize> SubAssign for Dual8<P> {
    #[inline(always)]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}
impl<const P: usize> MulAssign for Dual8<P> {
    #[inline(always)]
    fn mul_assign(&mut self, o: Self) {
        *self = *self * o;
    }
}

impl<const P: usize> Real for Dual8<P> {
    type Mask = f32x8;
    type Value = f32x8;
    const LANES: usize = 8;
    const DERIVS: usize = P;

    #[inline(always)]
    fn splat(v: f32) -> Self {
        Self::constant(f32x8::splat(v))
    }
    #[inline(always)]
    fn from_value(v: f32x8) -> Self {
        Self::constant(v)
    }
    #[inline(always)]
    fn value(self) -> f32x8 {
        self.v
    }
    #[inline(always)]
    fn from_lanes(v: &[f32]) -> Self {
        Self::constant(<f32x8 as Real>::from_lanes(v))
    }
    #[inline(always)]
    fn lane(self, i: usize) -> f32 {
        self.v.as_array()[i]
    }
    #[inline(always)]
    fn deriv_lane(self, p: usize, i: usize) -> f32 {
        if p < P { self.d[p].as_array()[i] } else { 0.0 }
    }
    #[inline(always)]
    fn with_deriv_lanes(mut self, p: usize, d: &[f32]) -> Self {
        if p < P {
            self.d[p] = <f32x8 as Real>::from_lanes(d);
        }
        self
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let s = <f32x8 as Real>::sqrt(self.v);
        let pos = s.simd_gt(f32x8::ZERO);
        let slope = pos.select(f32x8::splat(0.5) / s, f32x8::ZERO);
        self.chain(s, slope)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        let neg = self.v.simd_lt(f32x8::ZERO);
        self.chain(self.v.abs(), neg.select(f32x8::splat(-1.0), f32x8::ONE))
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        Self::select(self.v.simd_le(o.v), self, o)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        Self::select(self.v.simd_ge(o.v), self, o)
    }
    #[inline(always)]
    fn exp(self) -> Self {
        let e = self.v.exp();
        self.chain(e, e)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = self.v.sin_cos();
        (self.chain(s, c), self.chain(c, -s))
    }
    #[inline(always)]
    fn select(m: f32x8, t: Self, f: Self) -> Self {
        Self {
            v: m.select(t.v, f.v),
            d: std::array::from_fn(|k| m.select(t.d[k], f.d[k])),
        }
    }
    #[inline(always)]
    fn lt(self, o: Self) -> f32x8 {
        self.v.simd_lt(o.v)
    }
    #[inline(always)]
    fn le(self, o: Self) -> f32x8 {
        self.v.simd_le(o.v)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> f32x8 {
        self.v.simd_gt(o.v)
    }
    #[inline(always)]
    fn ge(self, o: Self) -> f32x8 {
        self.v.simd_ge(o.v)
    }
    #[inline(always)]
    fn is_finite(self) -> f32x8 {
        self.v.is_finite()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type D = Dual8<2>;

    fn var(xs: [f32; 8]) -> D {
        // derivative 0 is d/dx (x is the variable), derivative 1 is d/dy (zero here)
        D::from_lanes(&xs).with_deriv_lanes(0, &[1.0; 8])
    }

    /// Each lane's derivative equals a central finite difference of the scalar function.
    fn check(name: &str, xs: [f32; 8], f: impl Fn(D) -> D, g: impl Fn(f64) -> f64) {
        let y = f(var(xs));
        for i in 0..8 {
            let x = xs[i] as f64;
            let h = 1e-4 * x.abs().max(1e-2);
            let fd = (g(x + h) - g(x - h)) / (2.0 * h);
            let ad = y.deriv_lane(0, i) as f64;
            // FD truncation error ~h² f''' plus f32 rounding of the dual maths
            let tol = 2e-3 * fd.abs().max(1.0);
            assert!((ad - fd).abs() <= tol, "{name} lane {i} x={x}: dual {ad} vs fd {fd}");
            assert!(
                (y.lane(i) as f64 - g(x)).abs() <= 1e-5 * g(x).abs().max(1.0),
                "{name} value lane {i}"
            );
            assert_eq!(y.deriv_lane(1, i), 0.0, "{name}: untouched lane must stay zero");
        }
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let xs = [0.1f32, 0.5, 1.0, 2.0, 3.5, 7.0, 0.03, 1.7];
        check("mul", xs, |x| x * x * x, |x| x * x * x);
        check("div", xs, |x| D::splat(1.0) / (x + D::splat(1.0)), |x| 1.0 / (x + 1.0));
        check("sqrt", xs, |x| x.sqrt(), |x| x.sqrt());
        check("rsqrt", xs, |x| x.rsqrt(), |x| 1.0 / x.sqrt());
        check("exp", xs, |x| (-x).exp(), |x| (-x).exp());
        check("erf", xs, |x| x.erf(), libm_erf);
        check("abs", xs.map(|x| x - 0.9), |x| x.abs(), |x| x.abs());
    }

    #[test]
    fn guarded_edge_cases_stay_finite() {
        let xs = [0.0f32, -1e-9, -3.0, 1e-38, 1e30, -0.0, f32::MIN_POSITIVE, 1e-20];
        // d(x^-1/2)/dx = -x^-3/2/2 exceeds f32 below x ≈ 1e-25: rsqrt's tiny input is 1e-20.
        let xr = [0.0f32, -1e-9, -3.0, 1e-20, 1e30, -0.0, 1e-12, 1e-20];
        for (name, y) in [
            ("sqrt", var(xs).sqrt()),
            ("rsqrt", var(xr).rsqrt()),
            ("erf", var(xs).erf()),
        ] {
            for i in 0..8 {
                assert!(
                    y.lane(i).is_finite() && y.deriv_lane(0, i).is_finite(),
                    "{name} lane {i} x={}",
                    xs[i]
                );
            }
        }
        assert_eq!(var(xs).sqrt().lane(2), 0.0, "sqrt of a negative is clamped to zero");
    }

    fn libm_erf(x: f64) -> f64 {
        // Abramowitz–Stegun 7.1.28-level accuracy is not enough for an FD reference; use a
        // series that converges fast for |x| < 4 and the asymptote beyond.
        if x.abs() > 4.0 {
            return x.signum();
        }
        let mut sum = 0.0;
        let mut term = x;
        let mut n = 0.0;
        while term.abs() > 1e-17 {
            sum += term / (2.0 * n + 1.0);
            n += 1.0;
            term *= -x * x / n;
        }
        sum * 2.0 / std::f64::consts::PI.sqrt()
    }
}
