//! Steps of path transport that every estimator takes the same way, written once: what a
//! ray found on an area emitter, and the scattering step at a vertex (BSDF sample, throughput
//! update, Russian roulette). The path tracer (`path.rs`, which also runs the boundary
//! stage's source subpaths), the importance walk (`importance.rs`, the boundary stage's sensor
//! subpaths) and BDPT's subpaths (`bdpt/walk.rs`, `bdpt/connect.rs`) call them, so a new BSDF
//! or emitter is added here for all of them.

use super::bsdf::{Lobes, Sampled, sample_cosine};
use super::context::RenderContext;
use crate::kernel::{Mask, PathSampler, Real, Spectrum, V3};

type V<R> = <R as Real>::Value;

/// The area emitters that the lanes of `mask` landed on (front side checked by the caller).
pub struct EmitterHits<R: Real, const C: usize> {
    /// Emitter index per lane (`u32::MAX` where none).
    pub emitter: [u32; 8],
    /// Emitted radiance L_e per lane, with its derivatives (radiance parameters).
    pub radiance: Spectrum<R, C>,
    /// The emitter's area density for light sampling (0 where none).
    pub area_pdf: V<R>,
    /// Lanes of `mask` on an emitter.
    pub mask: R::Mask,
}

/// What the lanes of `mask` find on the triangles `prims`: emitter, L_e and its area pdf.
#[inline]
pub fn emitter_hits<R: Real, const C: usize>(
    ctx: &RenderContext,
    prims: &[u32; 8],
    mask: R::Mask,
) -> EmitterHits<R, C> {
    let mut emitter = [u32::MAX; 8];
    let mut le = [[0.0f32; 3]; 8];
    let mut pdf = [0.0f32; 8];
    let mut has = [false; 8];
    for i in 0..R::LANES {
        if mask.bit(i) {
            let e = ctx.tri_emitter[prims[i] as usize];
            if e != u32::MAX {
                emitter[i] = e;
                le[i] = ctx.emitters.radiance(e);
                pdf[i] = ctx.emitters.area_pdf(e);
                has[i] = true;
            }
        }
    }
    let mask = R::Mask::from_bools(&has[..R::LANES]);
    let mut radiance = Spectrum::<R, C>::from_lane_rgb(&le[..R::LANES]);
    if R::DERIVS > 0 && mask.any() {
        ctx.motion.radiance_derivs(&emitter, &mut radiance);
    }
    EmitterHits {
        emitter,
        radiance,
        area_pdf: V::<R>::from_lanes(&pdf),
        mask,
    }
}

/// The scattering step at a Lambertian vertex with normal `n` and BSDF value `f`, for light
/// leaving on the side `side`: a cosine-weighted direction (two random dimensions), β ← β·f·
/// |cos|/pdf, lanes with a zero pdf ended, then Russian roulette from the scene's `rr_depth`
/// on (one more dimension, drawn whenever `rr_depth` is set) at path depth `depth`. Returns
/// the direction and its solid-angle pdf.
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn scatter<R: Real, const C: usize>(
    ctx: &RenderContext,
    sampler: &mut PathSampler,
    n: &V3<V<R>>,
    side: &V3<V<R>>,
    f: &Spectrum<R, C>,
    beta: &mut Spectrum<R, C>,
    active: &mut R::Mask,
    depth: u32,
) -> (V3<V<R>>, V<R>) {
    let (b1, b2) = sampler.next2::<V<R>>();
    let (dir, pdf) = sample_cosine(n, side, b1, b2);
    debug_assert!({
        let p2 = super::bsdf::cosine_pdf(n, side, &dir);
        (0..R::LANES).all(|i| (p2.lane(i) - pdf.lane(i)).abs() <= 1e-3 * pdf.lane(i).max(1.0))
    });
    let cos_o = n.dot(dir).abs();
    *beta = (*beta * *f).scale(R::from_value(V::<R>::safe_div(cos_o, pdf)));
    *active = *active & pdf.gt(V::<R>::zero());
    roulette(ctx, sampler, beta, active, depth);
    (dir, pdf)
}

/// The scattering step through any material (`lobes`, gathered at the vertex with normal
/// `n`, reached from direction `wo`): a direction from [`Lobes::sample`] (three random
/// dimensions) for radiance (`radiance`: camera paths) or importance transport, β ← β·f·
/// |cos|/pdf (on Lambertian lanes β·albedo with the albedo's derivative lanes; on the others
/// the value, their f's derivatives are the caller's to apply once the next vertex is
/// known), lanes with a zero pdf ended, then Russian roulette as in [`scatter`].
#[inline]
#[allow(clippy::too_many_arguments)]
pub fn scatter_lobes<R: Real, const C: usize>(
    ctx: &RenderContext,
    sampler: &mut PathSampler,
    lobes: &Lobes<R, C>,
    n: &V3<V<R>>,
    wo: &V3<V<R>>,
    radiance: bool,
    beta: &mut Spectrum<R, C>,
    active: &mut R::Mask,
    depth: u32,
) -> Sampled<V<R>, C> {
    let (b1, b2) = sampler.next2::<V<R>>();
    let uc = sampler.next::<V<R>>();
    let s = lobes.value().sample(n, wo, b1, b2, uc, radiance);
    let weight = Spectrum(std::array::from_fn(|c| {
        R::select(lobes.diffuse, lobes.tint.0[c], R::from_value(s.weight.0[c]))
    }));
    *beta = *beta * weight;
    *active = *active & s.pdf.gt(V::<R>::zero());
    roulette(ctx, sampler, beta, active, depth);
    s
}

/// Russian roulette from the scene's `rr_depth` on (one random dimension, drawn whenever
/// `rr_depth` is set) at path depth `depth`: lanes survive with probability min(1, max β).
#[inline]
fn roulette<R: Real, const C: usize>(
    ctx: &RenderContext,
    sampler: &mut PathSampler,
    beta: &mut Spectrum<R, C>,
    active: &mut R::Mask,
    depth: u32,
) {
    if let Some(rr) = ctx.scene.integrator.rr_depth {
        let u = sampler.next::<V<R>>();
        if depth >= rr {
            let q = beta.max_value().min(V::<R>::one());
            *active = *active & u.lt(q);
            *beta = beta.scale(R::from_value(V::<R>::safe_div(V::<R>::one(), q)));
        }
    }
}
