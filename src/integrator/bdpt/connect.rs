//! The strategies that end on the camera subpath's pixel: s = 0 (the camera subpath hits an
//! emitter) and s ≥ 1, t ≥ 2 (the last light vertex q_s joined to the last camera vertex p_t
//! by a shadow ray; s = 1 is next-event estimation).
//!
//! Contribution (Veach 1997, Eq. 10.8, area form): C = β_L(q_s) · f(q_s) · G(q_s ↔ p_t) ·
//! f(p_t) · β_E(p_t), with G = cos θ_q cos θ_p / ‖q_s − p_t‖². The OPL is
//! d = d_light(q_s) + d_camera(p_t) + η‖q_s − p_t‖. Positions carry derivatives (material
//! form), so G and d are differentiated here; J is already inside each β.

use super::Packet;
use super::mis::{allowed_through, path_pdfs, ratio_sums, weight};
use super::vertex::segment_end;
use crate::integrator::sink::Sink;
use crate::integrator::surface::resolvable;
use crate::integrator::trace::visible_between;
use crate::integrator::transport::emitter_hits;
use crate::integrator::window;
use crate::kernel::{Mask, Real, V3};

type V<R> = <R as Real>::Value;

/// s = 0: emission found by the camera subpath at its vertex t − 1 (area emitters, front
/// side only).
pub fn emission<R: Real, const C: usize, S: Sink<C>>(pk: &mut Packet<'_, '_, R, C, S>, t: usize) {
    let ctx = pk.ctx;
    let pt = pk.camera[t - 1];
    let hits = emitter_hits::<R, C>(ctx, &pt.prim, pt.alive & pt.front);
    let (emitter, emits, radiance) = (hits.emitter, hits.mask, hits.radiance);
    if emits.none() {
        return;
    }
    path_pdfs(
        Some(ctx),
        &[],
        &pk.camera[..t],
        hits.area_pdf,
        V::<R>::zero(),
        pk.pl,
        pk.pe,
        pk.no_connect,
    );
    let no_connect = &*pk.no_connect;
    let (lower, higher) = ratio_sums(pk.pl, pk.pe, 0, |sp| {
        allowed_through(t, sp, R::Mask::splat(false), no_connect)
    });
    let contrib = (pt.beta * radiance).scale(R::from_value(weight(lower, higher)));
    let exact = ctx.opl.f64_paths.then_some(&pt.opl64);
    pk.deposit_own_pixels((0, t), &emitter, pt.opl, exact, &contrib, emits);
}

/// s ≥ 1, t ≥ 2: the light subpath's vertex s − 1 joined to the camera subpath's vertex t − 1.
pub fn connect<R: Real, const C: usize, S: Sink<C>>(pk: &mut Packet<'_, '_, R, C, S>, s: usize, t: usize) {
    let ctx = pk.ctx;
    let qs = pk.light[s - 1];
    let pt = pk.camera[t - 1];
    let (dir, dist, d2) = towards(&qs.p, &pt.p);
    // q_s radiates (or reflects) into its own hemisphere; p_t reflects on its arrival side
    let cos_q = R::select(qs.on_surface, qs.n.dot(dir), R::one());
    let cos_p = -pt.n.dot(dir);
    let zero = V::<R>::zero();
    // the connection crosses the medium the camera subpath arrived in
    let d = qs.opl + pt.opl + pt.eta_in * dist;
    // no connection ends at a Dirac lobe (`vertex` module docs)
    let ok = (qs.alive & pt.alive).and_not(qs.delta | pt.delta);
    let ok = ok & cos_q.value().gt(zero) & cos_p.value().gt(zero) & d2.value().gt(zero);
    let ok = ok
        & resolvable(
            &qs.p.value(),
            ctx.scene.offset_scale,
            cos_q.value(),
            cos_p.value(),
            dist.value(),
        );
    // the window cut (`integrator::window`): connections that land past it cast no shadow ray
    let ok = ok & window::within(ctx.opl_budget, d.value());
    if ok.none() {
        return;
    }
    let ok = ok
        & visible_between(
            &ctx.accel,
            &segment_end(pk.camera, t - 1),
            &segment_end(pk.light, s - 1),
            ctx.scene.offset_scale,
            ok,
            &mut pk.counts.rays,
        );
    if ok.none() {
        return;
    }
    path_pdfs(
        Some(ctx),
        &pk.light[..s],
        &pk.camera[..t],
        zero,
        zero,
        pk.pl,
        pk.pe,
        pk.no_connect,
    );
    let (delta, n) = (pk.origin.delta, s + t);
    let no_connect = &*pk.no_connect;
    let (lower, higher) = ratio_sums(pk.pl, pk.pe, s, |sp| allowed_through(n, sp, delta, no_connect));
    let g = cos_q * cos_p / d2;
    // f at both ends, with the connection's direction (light origins keep f = 1)
    let f_q = match s {
        1 => qs.f,
        _ => qs.f_between(ctx, &(pk.light[s - 2].p - qs.p).normalize(), &dir, false),
    };
    let f_p = pt.f_between(ctx, &(pk.camera[t - 2].p - pt.p).normalize(), &-dir, true);
    let contrib = (qs.beta * f_q * f_p * pt.beta).scale(g * R::from_value(weight(lower, higher)));
    let d64 = joined_opl64(ctx, &qs, &pt);
    let emitter = pk.origin.emitter;
    let exact = d64.as_ref();
    pk.deposit_own_pixels((s, t), &emitter, d, exact, &contrib, ok);
}

/// The unit vector and distance from `a` to `b`.
#[inline(always)]
pub fn towards<R: Real>(a: &V3<R>, b: &V3<R>) -> (V3<R>, R, R) {
    let to = *b - *a;
    let d2 = to.length_squared();
    let dist = d2.sqrt();
    (to * R::safe_div(R::one(), dist), dist, d2)
}

/// The f64 OPL of light vertex `q` joined to camera vertex `p` (through the medium `p`
/// arrived in), or `None` when the render carries no f64 OPLs (this runs for every (s, t)
/// pair).
#[inline(always)]
pub fn joined_opl64<R: Real, const C: usize>(
    ctx: &crate::integrator::context::RenderContext,
    q: &super::vertex::Vertex<R, C>,
    p: &super::vertex::Vertex<R, C>,
) -> Option<[f64; 8]> {
    ctx.opl.f64_paths.then(|| {
        std::array::from_fn::<f64, 8, _>(|i| {
            let e = if i < R::LANES {
                p.eta_in.value().lane(i) as f64
            } else {
                0.0
            };
            q.opl64[i] + p.opl64[i] + e * (q.p64[i] - p.p64[i]).length()
        })
    })
}
