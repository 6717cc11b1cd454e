//! Lane masks: `bool` for one path, an all-bits `f32x8` for eight.

use std::ops::{BitAnd, BitOr, Not};
use wide::f32x8;

/// A per-lane boolean. Lanes are either all-ones (true) or all-zeros (false).
pub trait Mask:
    Copy + Send + Sync + std::fmt::Debug + BitAnd<Output = Self> + BitOr<Output = Self> + Not<Output = Self>
{
    fn splat(b: bool) -> Self;
    fn from_bools(b: &[bool]) -> Self;
    fn bit(self, i: usize) -> bool;
    fn any(self) -> bool;
    fn all(self) -> bool;
    fn none(self) -> bool {
        !self.any()
    }
    /// Bit `i` set where lane `i` is true.
    #[inline(always)]
    fn bits(self) -> u32 {
        (0..8).fold(0, |b, i| b | ((self.bit(i) as u32) << i))
    }
    /// `self & !other`.
    fn and_not(self, other: Self) -> Self {
        self & !other
    }
}

impl Mask for bool {
    #[inline(always)]
    fn splat(b: bool) -> Self {
        b
    }
    #[inline(always)]
    fn from_bools(b: &[bool]) -> Self {
        b[0]
    }
    #[inline(always)]
    fn bit(self, _i: usize) -> bool {
        self
    }
    #[inline(always)]
    fn any(self) -> bool {
        self
    }
    #[inline(always)]
    fn all(self) -> bool {
        self
    }
}

const TRUE_BITS: f32 = f32::from_bits(u32::MAX);

impl Mask for f32x8 {
    #[inline(always)]
    fn splat(b: bool) -> Self {
        f32x8::splat(if b { TRUE_BITS } else { 0.0 })
    }
    #[inline(always)]
    fn from_bools(b: &[bool]) -> Self {
        let mut a = [0.0f32; 8];
        for (o, &x) in a.iter_mut().zip(b) {
            *o = if x { TRUE_BITS } else { 0.0 };
        }
        f32x8::from(a)
    }
    #[inline(always)]
    fn bit(self, i: usize) -> bool {
        (self.to_bitmask() >> i) & 1 == 1
    }
    #[inline(always)]
    fn bits(self) -> u32 {
        self.to_bitmask()
    }
    #[inline(always)]
    fn any(self) -> bool {
        f32x8::any(self)
    }
    #[inline(always)]
    fn all(self) -> bool {
        f32x8::all(self)
    }
}
