//! Multiple importance sampling over the (s, t) strategies of one path (Veach 1997, §10.2.1,
//! power heuristic Eq. 9.13 with β = 2).
//!
//! A path x̄ = x_0 … x_{n−1} (x_0 on a light, x_{n−1} the pinhole) can be made by n − 1
//! strategies: s vertices from the light subpath and t = n − s from the camera subpath.
//! With `pl[k]` the area density of x_k under light-side sampling and `pe[k]` under
//! camera-side sampling, the strategy densities satisfy p_{s+1} / p_s = `pl[s] / pe[s]`
//! (Veach Eq. 10.9), so the weight of strategy s is 1 / Σ_{s'} (p_{s'} / p_s)², computed from
//! these ratios without ever forming the (tiny) full-path densities. Zero densities are
//! remapped to 1 in ratios, as pbrt-v4's `MISWeight` does; strategies that cannot make the
//! path (a camera path cannot hit a delta light) are left out of the sum,
//! so the weights of the strategies that run still sum to 1.
//!
//! Weights are computed on values only: they are constants for the derivative (Algorithm 1).

use super::vertex::{Vertex, area_pdf, scatter_area_pdf};
use crate::integrator::context::RenderContext;
use crate::kernel::{Mask, Real};

/// pbrt's `remap0`: a zero density in a ratio stands for a delta and is replaced by 1.
#[inline(always)]
fn remap0<V: Real>(x: V) -> V {
    V::select(x.gt(V::zero()), x, V::one())
}

/// Σ (p_{s'} / p_s)² over the allowed strategies s' ≠ s, split into those with fewer light
/// vertices (s' < s) and those with more (s' > s). `allowed(s')` masks the lanes where
/// strategy s' can make the path.
pub fn ratio_sums<V: Real>(pl: &[V], pe: &[V], s: usize, allowed: impl Fn(usize) -> V::Mask) -> (V, V) {
    let n = pl.len();
    let mut lower = V::zero();
    let mut r = V::one();
    for sp in (0..s).rev() {
        let q = remap0(pe[sp]) / remap0(pl[sp]);
        r = r * q * q;
        lower += r.masked(allowed(sp));
    }
    let mut higher = V::zero();
    let mut r = V::one();
    for sp in s + 1..n {
        let q = remap0(pl[sp - 1]) / remap0(pe[sp - 1]);
        r = r * q * q;
        higher += r.masked(allowed(sp));
    }
    // a ratio that over- or underflowed into NaN (∞·0) counts as dominating: weight 0
    let clean = |x: V| V::select(x.ge(V::zero()), x, V::splat(f32::INFINITY));
    (clean(lower), clean(higher))
}

/// The power-heuristic weight from the two ratio sums.
#[inline(always)]
pub fn weight<V: Real>(lower: V, higher: V) -> V {
    V::safe_div(V::one(), V::one() + lower + higher)
}

/// Which strategies can make a path of `n` vertices, per lane: s' = 0 needs a light that a
/// camera path can hit (not a delta in position), t' = 1 needs at least one bounce (the
/// light seen directly through the pinhole is left to s = 0, as in the path tracer).
#[inline(always)]
pub fn allowed<M: Mask>(n: usize, sp: usize, delta_light: M) -> M {
    if sp == 0 {
        !delta_light
    } else if n - sp == 1 {
        M::splat(n >= 3)
    } else {
        M::splat(true)
    }
}

/// [`allowed`], and no connection at a vertex that cannot be a connection's end
/// (`no_connect[k]` for path vertex x_k, from [`path_pdfs`]): one where the path refracts
/// (connections leave on the arrival side only) or whose lobe is a Dirac (smooth conductor or
/// dielectric: f is zero in every direction but one; pbrt-v4's `delta` vertices). Strategy s'
/// joins x_{s'−1} and x_{s'}.
#[inline(always)]
pub fn allowed_through<M: Mask>(n: usize, sp: usize, delta_light: M, no_connect: &[M]) -> M {
    let mut m = allowed(n, sp, delta_light);
    if sp >= 1 {
        m = m.and_not(no_connect[sp - 1]);
    }
    if sp < n {
        m = m.and_not(no_connect[sp]);
    }
    m
}

/// Connection densities that the subpaths do not store: with `light = x_0..x_{s−1}` and
/// `camera = x_{n−1}..x_s` (camera order), fills `pl`, `pe` for the whole path, and
/// `no_connect` (the lanes where x_k cannot be a connection's end, see [`allowed_through`]). `origin_pdf` is the
/// emitter's area density at the camera's last vertex (s = 0 only); `camera_pdf` the
/// camera's area density at the light's last vertex (t = 1 only). The densities at the two
/// ends of a connection are their BSDFs' given the connection as the arriving direction
/// ([`scatter_area_pdf`]).
#[allow(clippy::too_many_arguments)]
pub fn path_pdfs<R: Real, const C: usize>(
    ctx: Option<&RenderContext>,
    light: &[Vertex<R, C>],
    camera: &[Vertex<R, C>],
    origin_pdf: R::Value,
    camera_pdf: R::Value,
    pl: &mut Vec<R::Value>,
    pe: &mut Vec<R::Value>,
    no_connect: &mut Vec<R::Mask>,
) {
    let (s, t) = (light.len(), camera.len());
    let n = s + t;
    pl.clear();
    pe.clear();
    no_connect.clear();
    pl.resize(n, R::Value::zero());
    pe.resize(n, R::Value::zero());
    no_connect.resize(n, R::Mask::splat(false));
    for (k, v) in light.iter().enumerate() {
        pl[k] = v.pdf_fwd;
        pe[k] = v.pdf_rev;
        no_connect[k] = v.transmitted | v.delta;
    }
    for (j, v) in camera.iter().enumerate() {
        pe[n - 1 - j] = v.pdf_fwd;
        pl[n - 1 - j] = v.pdf_rev;
        no_connect[n - 1 - j] = v.transmitted | v.delta;
    }
    // the connection's ends do not refract (connections stay on the arrival side); an end
    // that refracted in its own subpath continued past where this path turns (a Dirac end
    // makes no path: the strategies skip it before asking for densities)
    if s >= 1 {
        no_connect[s - 1] = R::Mask::splat(false);
    }
    if t >= 1 {
        no_connect[s] = R::Mask::splat(false);
    }
    if s == 0 {
        // the camera subpath's last vertex is on an emitter
        pl[0] = origin_pdf;
        if t >= 3 {
            pl[1] = area_pdf(&camera[t - 1], &camera[t - 2]);
        }
        return;
    }
    let qs = &light[s - 1];
    // the vertex on the camera side of the connection (the pinhole when t = 1)
    let pt = &camera[t - 1];
    if t == 1 {
        pe[s - 1] = camera_pdf;
    } else {
        pl[s] = match s {
            1 => area_pdf(qs, pt),
            _ => scatter_area_pdf(ctx, qs, &light[s - 2].p.value(), pt),
        };
        if t >= 3 {
            pl[s + 1] = scatter_area_pdf(ctx, pt, &qs.p.value(), &camera[t - 2]);
        }
        pe[s - 1] = scatter_area_pdf(ctx, pt, &camera[t - 2].p.value(), qs);
    }
    if s >= 2 {
        pe[s - 2] = scatter_area_pdf(ctx, qs, &pt.p.value(), &light[s - 2]);
    }
}

#[cfg(test)]
#[path = "mis_tests.rs"]
mod tests;
