//! Colour with a compile-time channel count: `C = 1` (mono) or `C = 3` (RGB).

use super::real::Real;
use std::ops::{Add, AddAssign, Mul};

/// `C` channels of `R`. A mono scene runs with `C = 1`, so it does a third of the work.
#[derive(Clone, Copy, Debug)]
pub struct Spectrum<R, const C: usize>(pub [R; C]);

impl<R: Real, const C: usize> Spectrum<R, C> {
    #[inline(always)]
    pub fn splat(v: R) -> Self {
        Self([v; C])
    }
    #[inline(always)]
    pub fn zero() -> Self {
        Self::splat(R::zero())
    }
    /// From an RGB triple: mono takes the first channel (scenes store mono as equal channels).
    #[inline(always)]
    pub fn from_rgb(rgb: [f32; 3]) -> Self {
        Self(std::array::from_fn(|c| R::splat(rgb[c])))
    }
    /// Per lane RGB triples gathered into lanes.
    #[inline(always)]
    pub fn from_lane_rgb(rgb: &[[f32; 3]]) -> Self {
        Self(std::array::from_fn(|c| {
            let mut a = [0.0f32; 8];
            for (i, v) in rgb.iter().enumerate().take(R::LANES) {
                a[i] = v[c];
            }
            R::from_lanes(&a)
        }))
    }
    #[inline(always)]
    pub fn scale(self, s: R) -> Self {
        Self(self.0.map(|v| v * s))
    }
    #[inline(always)]
    pub fn select(m: R::Mask, t: Self, f: Self) -> Self {
        Self(std::array::from_fn(|c| R::select(m, t.0[c], f.0[c])))
    }
    #[inline(always)]
    pub fn masked(self, m: R::Mask) -> Self {
        Self(self.0.map(|v| v.masked(m)))
    }
    /// Largest channel value (for Russian roulette).
    #[inline(always)]
    pub fn max_value(self) -> R::Value {
        let mut m = self.0[0].value();
        for c in 1..C {
            m = m.max(self.0[c].value());
        }
        m
    }
}

impl<R: Real, const C: usize> Mul for Spectrum<R, C> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self(std::array::from_fn(|c| self.0[c] * o.0[c]))
    }
}
impl<R: Real, const C: usize> Add for Spectrum<R, C> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self(std::array::from_fn(|c| self.0[c] + o.0[c]))
    }
}
impl<R: Real, const C: usize> AddAssign for Spectrum<R, C> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        for c in 0..C {
            self.0[c] += o.0[c];
        }
    }
}
