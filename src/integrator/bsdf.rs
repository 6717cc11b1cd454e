//! Materials in a local shading frame. Each lobe offers `eval`, `sample` and `pdf`; the
//! diffuse lobe is the only one today, and the per-lane material gather is the place where a
//! rough conductor will branch in.

use super::context::RenderContext;
use crate::kernel::{Real, Spectrum, V3};
use crate::scene::Material;

/// Albedo of the material of each lane's triangle, as a spectrum.
pub fn albedo<R: Real, const C: usize>(ctx: &RenderContext, prim: &[u32; 8]) -> Spectrum<R, C> {
    let mut rgb = [[0.0f32; 3]; 8];
    for i in 0..R::LANES {
        let t = prim[i].min(ctx.tri_material.len() as u32 - 1) as usize;
        let Material::Diffuse { albedo } = &ctx.scene.materials[ctx.tri_material[t] as usize].material;
        rgb[i] = *albedo;
    }
    let mut s = Spectrum::<R, C>::from_lane_rgb(&rgb[..R::LANES]);
    if R::DERIVS > 0 {
        ctx.motion.albedo_derivs(prim, &ctx.tri_material, &mut s);
    }
    s
}

/// Lambertian BSDF value f = albedo / π (two-sided).
#[inline(always)]
pub fn diffuse_eval<R: Real, const C: usize>(albedo: Spectrum<R, C>) -> Spectrum<R, C> {
    albedo.scale(R::splat(std::f32::consts::FRAC_1_PI))
}

/// Cosine-weighted direction about `n` oriented towards `side` (the incoming side), with its
/// solid-angle pdf cos θ / π. (Malley's method on a concentric disk.)
#[inline(always)]
pub fn sample_cosine<V: Real>(n: &V3<V>, side: &V3<V>, u1: V, u2: V) -> (V3<V>, V) {
    let flip = n.dot(*side).lt(V::zero());
    let nn = V3::select(flip, -*n, *n);
    let (s, t) = nn.orthonormal_basis();
    // concentric mapping (Shirley & Chiu 1997), branch-free by selects
    let a = u1 * V::splat(2.0) - V::one();
    let b = u2 * V::splat(2.0) - V::one();
    let use_a = (a * a).gt(b * b);
    let r = V::select(use_a, a, b);
    let q = std::f32::consts::FRAC_PI_4;
    let phi_a = V::safe_div(b, a).mul_f(q);
    let phi_b = V::splat(std::f32::consts::FRAC_PI_2) - V::safe_div(a, b).mul_f(q);
    let phi = V::select(use_a, phi_a, phi_b);
    let (sn, cs) = phi.sin_cos();
    let x = r * cs;
    let y = r * sn;
    let z = (V::one() - x * x - y * y).sqrt();
    let dir = s * x + t * y + nn * z;
    (dir, z.mul_f(std::f32::consts::FRAC_1_PI))
}

/// Solid-angle pdf of [`sample_cosine`] for direction `dir` (unit) given the same frame.
#[inline(always)]
pub fn cosine_pdf<V: Real>(n: &V3<V>, side: &V3<V>, dir: &V3<V>) -> V {
    let c = n.dot(*dir);
    let same = (c * n.dot(*side)).gt(V::zero());
    c.abs().mul_f(std::f32::consts::FRAC_1_PI).masked(same)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::PathSampler;

    /// The sampled directions follow cos θ / π: E[cos θ] = 2/3 and every sample matches its pdf.
    #[test]
    fn cosine_sampling_moments_and_pdf() {
        let n = V3::<f32>::splat(glam::Vec3::new(0.2, 0.9, -0.3).normalize());
        let mut s = PathSampler::new(3, &[0]);
        let count = 50_000;
        let mut sum = 0.0f64;
        for _ in 0..count {
            let (u1, u2) = s.next2::<f32>();
            let (d, pdf) = sample_cosine(&n, &n, u1, u2);
            let c = n.dot(d);
            assert!(c >= 0.0 && (d.length() - 1.0).abs() < 1e-4);
            assert!((pdf - cosine_pdf(&n, &n, &d)).abs() < 1e-4);
            sum += c as f64;
        }
        let mean = sum / count as f64;
        // Var[cos] = 1/2 - 4/9 = 1/18
        let se = (1.0 / 18.0 / count as f64).sqrt();
        assert!((mean - 2.0 / 3.0).abs() < 4.0 * se, "mean cos {mean}");
    }
}
