//! The [`Real`] trait: the number type the path kernel is generic over.

use super::mask::Mask;
use std::fmt::Debug;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};
use wide::f32x8;

/// A number carried through the path kernel: one lane (`f32`), eight lanes (`f32x8`), or eight
/// lanes with forward-mode derivative lanes (dual numbers).
///
/// Invariants every implementation keeps:
/// - `sqrt` clamps negative arguments to zero (never NaN from rounding noise);
/// - comparisons look at the value only; a mask never depends on derivatives;
/// - `value()` drops derivatives; `from_value` makes a constant (zero derivatives).
pub trait Real:
    Copy
    + Send
    + Sync
    + Debug
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
{
    type Mask: Mask;
    /// The plain (derivative-free) number with the same lanes.
    type Value: Real<Mask = Self::Mask, Value = Self::Value>;
    /// Paths carried at once.
    const LANES: usize;
    /// Derivative lanes (parameters) carried per path; 0 for plain numbers.
    const DERIVS: usize;

    fn splat(v: f32) -> Self;
    fn from_value(v: Self::Value) -> Self;
    fn value(self) -> Self::Value;
    /// A constant from `LANES` values.
    fn from_lanes(v: &[f32]) -> Self;
    /// The value of lane `i`.
    fn lane(self, i: usize) -> f32;
    /// Derivative `p` of lane `i` (0 for plain numbers).
    fn deriv_lane(self, p: usize, i: usize) -> f32;
    /// Sets derivative `p` from `LANES` values (ignored by plain numbers, which carry none).
    fn with_deriv_lanes(self, p: usize, d: &[f32]) -> Self;

    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    fn min(self, o: Self) -> Self;
    fn max(self, o: Self) -> Self;
    fn exp(self) -> Self;
    /// (sin, cos) of the value (derivatives by the chain rule).
    fn sin_cos(self) -> (Self, Self);
    fn select(m: Self::Mask, t: Self, f: Self) -> Self;
    fn lt(self, o: Self) -> Self::Mask;
    fn le(self, o: Self) -> Self::Mask;
    fn gt(self, o: Self) -> Self::Mask;
    fn ge(self, o: Self) -> Self::Mask;
    /// Lanes that are neither NaN nor infinite (value only).
    fn is_finite(self) -> Self::Mask;

    #[inline(always)]
    fn zero() -> Self {
        Self::splat(0.0)
    }
    #[inline(always)]
    fn one() -> Self {
        Self::splat(1.0)
    }
    #[inline(always)]
    fn recip(self) -> Self {
        Self::one() / self
    }
    #[inline(always)]
    fn mul_f(self, f: f32) -> Self {
        self * Self::splat(f)
    }
    /// `self` where `m`, zero elsewhere.
    #[inline(always)]
    fn masked(self, m: Self::Mask) -> Self {
        Self::select(m, self, Self::zero())
    }
    /// `a / b` where `b != 0`, zero elsewhere (never NaN or Inf from a zero denominator).
    #[inline(always)]
    fn safe_div(a: Self, b: Self) -> Self {
        let ok = b.value().abs().gt(Self::Value::zero());
        let den = Self::select(ok, b, Self::one());
        Self::select(ok, a / den, Self::zero())
    }
    /// Values as an 8-array (lanes beyond `LANES` are zero).
    #[inline(always)]
    fn to_array8(self) -> [f32; 8] {
        let mut a = [0.0; 8];
        for (i, o) in a.iter_mut().enumerate().take(Self::LANES) {
            *o = self.lane(i);
        }
        a
    }
}

impl Real for f32 {
    type Mask = bool;
    type Value = f32;
    const LANES: usize = 1;
    const DERIVS: usize = 0;

    #[inline(always)]
    fn splat(v: f32) -> Self {
        v
    }
    #[inline(always)]
    fn from_value(v: f32) -> Self {
        v
    }
    #[inline(always)]
    fn value(self) -> f32 {
        self
    }
    #[inline(always)]
    fn from_lanes(v: &[f32]) -> Self {
        v[0]
    }
    #[inline(always)]
    fn lane(self, _i: usize) -> f32 {
        self
    }
    #[inline(always)]
    fn deriv_lane(self, _p: usize, _i: usize) -> f32 {
        0.0
    }
    #[inline(always)]
    fn with_deriv_lanes(self, _p: usize, _d: &[f32]) -> Self {
        self
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32::sqrt(f32::max(self, 0.0))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::abs(self)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        f32::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        f32::max(self, o)
    }
    #[inline(always)]
    fn exp(self) -> Self {
        f32::exp(self)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        f32::sin_cos(self)
    }
    #[inline(always)]
    fn select(m: bool, t: Self, f: Self) -> Self {
        if m { t } else { f }
    }
    #[inline(always)]
    fn lt(self, o: Self) -> bool {
        self < o
    }
    #[inline(always)]
    fn le(self, o: Self) -> bool {
        self <= o
    }
    #[inline(always)]
    fn gt(self, o: Self) -> bool {
        self > o
    }
    #[inline(always)]
    fn ge(self, o: Self) -> bool {
        self >= o
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
}

impl Real for f32x8 {
    type Mask = f32x8;
    type Value = f32x8;
    const LANES: usize = 8;
    const DERIVS: usize = 0;

    #[inline(always)]
    fn splat(v: f32) -> Self {
        f32x8::splat(v)
    }
    #[inline(always)]
    fn from_value(v: f32x8) -> Self {
        v
    }
    #[inline(always)]
    fn value(self) -> f32x8 {
        self
    }
    #[inline(always)]
    fn from_lanes(v: &[f32]) -> Self {
        let mut a = [0.0f32; 8];
        a.copy_from_slice(&v[..8]);
        f32x8::from(a)
    }
    #[inline(always)]
    fn lane(self, i: usize) -> f32 {
        self.as_array()[i]
    }
    #[inline(always)]
    fn to_array8(self) -> [f32; 8] {
        self.to_array()
    }
    #[inline(always)]
    fn deriv_lane(self, _p: usize, _i: usize) -> f32 {
        0.0
    }
    #[inline(always)]
    fn with_deriv_lanes(self, _p: usize, _d: &[f32]) -> Self {
        self
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32x8::sqrt(f32x8::max(self, f32x8::ZERO))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32x8::abs(self)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        f32x8::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        f32x8::max(self, o)
    }
    #[inline(always)]
    fn exp(self) -> Self {
        f32x8::exp(self)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        f32x8::sin_cos(self)
    }
    #[inline(always)]
    fn select(m: f32x8, t: Self, f: Self) -> Self {
        m.select(t, f)
    }
    #[inline(always)]
    fn lt(self, o: Self) -> f32x8 {
        self.simd_lt(o)
    }
    #[inline(always)]
    fn le(self, o: Self) -> f32x8 {
        self.simd_le(o)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> f32x8 {
        self.simd_gt(o)
    }
    #[inline(always)]
    fn ge(self, o: Self) -> f32x8 {
        self.simd_ge(o)
    }
    #[inline(always)]
    fn is_finite(self) -> f32x8 {
        f32x8::is_finite(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each f32x8 lane equals the scalar implementation, on edge cases and ordinary values.
    #[test]
    fn f32x8_lanes_match_scalar() {
        let xs = [0.0f32, -0.0, 1e-30, 1e30, -2.5, 3.0, f32::MIN_POSITIVE, 7.25];
        let ys = [1.0f32, 2.0, -3.0, 1e-20, 0.5, -1e10, 4.0, 7.25];
        let a = f32x8::from_lanes(&xs);
        let b = f32x8::from_lanes(&ys);
        let checks: [(&str, f32x8, fn(f32, f32) -> f32); 6] = [
            ("add", a + b, |x, y| x + y),
            ("mul", a * b, |x, y| x * y),
            ("div", a / b, |x, y| x / y),
            ("min", Real::min(a, b), f32::min),
            ("max", Real::max(a, b), f32::max),
            ("sqrt", Real::sqrt(a), |x, _| Real::sqrt(x)),
        ];
        for (name, v, f) in checks {
            for i in 0..8 {
                let s = f(xs[i], ys[i]);
                let l = Real::lane(v, i);
                assert!(
                    s == l || (s - l).abs() <= 1e-6 * s.abs().max(1e-30),
                    "{name} lane {i}: {s} vs {l}"
                );
            }
        }
        let m = a.lt(b);
        for i in 0..8 {
            assert_eq!(m.bit(i), xs[i] < ys[i], "lt lane {i}");
        }
        let sel = f32x8::select(m, a, b);
        for i in 0..8 {
            assert_eq!(Real::lane(sel, i), if xs[i] < ys[i] { xs[i] } else { ys[i] });
        }
    }

    #[test]
    fn sqrt_of_negative_rounding_noise_is_zero() {
        assert_eq!(Real::sqrt(-1e-9f32), 0.0);
        assert_eq!(Real::sqrt(f32x8::splat(-1e-9)).lane(3), 0.0);
    }

    #[test]
    fn safe_div_never_produces_inf() {
        let r = <f32x8 as Real>::safe_div(
            f32x8::splat(1.0),
            f32x8::from_lanes(&[0.0, 2.0, 0.0, 4.0, 0.0, 1.0, 1.0, 1.0]),
        );
        assert_eq!(Real::lane(r, 0), 0.0);
        assert_eq!(Real::lane(r, 1), 0.5);
        assert!(r.to_array8().iter().all(|x| x.is_finite()));
    }
}
