//! How requested parameters move the scene: the derivative lanes the kernel fills.
//!
//! A primal render has no parameters and this is empty; the plain kernel never reads it.

use super::context::RenderContext;
use crate::kernel::{Real, Spectrum};
use glam::{Mat3, Vec3};

/// Affine velocity field `v(x) = A·x + b` of one shape under one parameter.
#[derive(Clone, Copy, Debug)]
pub struct Velocity {
    pub a: Mat3,
    pub b: Vec3,
}

/// The derivative lanes requested for a render, in lane order.
#[derive(Clone, Debug, Default)]
pub struct Motion {
    /// `fields[k]`: (shape index, velocity) pairs moved by parameter k.
    pub fields: Vec<Vec<(usize, Velocity)>>,
    /// `albedo[k]`: (material index, channel mask) whose albedo is parameter k.
    pub albedo: Vec<Vec<(usize, [bool; 3])>>,
}

impl Motion {
    pub fn none() -> Self {
        Self::default()
    }

    /// Velocity of world point `x` of `shape` under parameter `k`.
    #[inline]
    pub fn velocity(&self, k: usize, shape: usize, x: Vec3) -> Vec3 {
        match self.fields.get(k) {
            Some(f) => f
                .iter()
                .filter(|(s, _)| *s == shape)
                .map(|(_, v)| v.a * x + v.b)
                .sum(),
            None => Vec3::ZERO,
        }
    }

    /// Sets the derivative lanes of a gathered albedo: ∂albedo/∂θ_k is 1 on the channels that
    /// parameter k controls.
    pub fn albedo_derivs<R: Real, const C: usize>(
        &self,
        prim: &[u32; 8],
        ctx: &RenderContext,
        s: &mut Spectrum<R, C>,
    ) {
        for (k, targets) in self.albedo.iter().enumerate().take(R::DERIVS) {
            for c in 0..C {
                let mut d = [0.0f32; 8];
                for (i, di) in d.iter_mut().enumerate().take(R::LANES) {
                    let t = prim[i].min(ctx.tri_material.len() as u32 - 1) as usize;
                    let m = ctx.tri_material[t] as usize;
                    if targets.iter().any(|(tm, ch)| *tm == m && ch[c]) {
                        *di = 1.0;
                    }
                }
                s.0[c] = s.0[c].with_deriv_lanes(k, &d);
            }
        }
    }
}
