//! The t = 1 strategy of an NLOS capture: the light subpath's vertex s − 1 joined to the
//! lane's sensor point, the capture's counterpart of light tracing to the pinhole
//! ([`super::splat`]).
//!
//! Sensor point s measures the radiance the wall sends towards the SPAD, with importance
//! W(ω) = f_r(s)·|cos θ_s| = ρ_s/π·|cos θ_s| (`crate::integrator::nlos`). Joined to q_s the
//! contribution is β_L(q_s) · f(q_s) · G(q_s ↔ s) · ρ_s/π (Veach 1997, Eq. 10.8 with t = 1),
//! G = cos θ_q cos θ_s / ‖q_s − s‖², and it lands in the lane's own film cell: the cell's
//! light subpath starts at that cell's laser point (confocal: the sensor point's own;
//! exhaustive: the cell's laser point), so no other cell can use it and the camera density
//! needs no 1/N (one light subpath per camera subpath and cell).
//!
//! Every vertex of a capture's path is in material form (the sensor point is a fixed point of
//! the wall, the camera subpath's first vertex moves with its surface as the path tracer's
//! does), so this strategy moves the path as the others do and G, f and the OPL carry the
//! derivatives of q_s directly.

use super::Packet;
use super::connect::{joined_opl64, towards};
use super::mis::weight;
use super::vertex::{segment_end, to_area};
use crate::integrator::sink::Sink;
use crate::integrator::surface::resolvable;
use crate::integrator::trace::visible_between;
use crate::integrator::window;
use crate::kernel::{Mask, Real};

type V<R> = <R as Real>::Value;

/// s ≥ 2, t = 1 in a capture (confocal or exhaustive): q_{s−1} joined to the sensor point (the camera subpath's
/// vertex 0).
pub fn connect_to_sensor<R: Real, const C: usize, S: Sink<C>>(pk: &mut Packet<'_, '_, R, C, S>, s: usize) {
    let ctx = pk.ctx;
    let qs = pk.light[s - 1];
    let sensor = pk.camera[0];
    let (dir, dist, d2) = towards(&qs.p, &sensor.p);
    let cos_q = qs.n.dot(dir);
    let cos_s = -sensor.n.dot(dir);
    let zero = V::<R>::zero();
    // the wall's leg to the SPAD is in the sensor vertex's OPL (`walk::sensor_subpath`)
    let d = qs.opl + sensor.opl + sensor.eta_in * dist;
    // a Dirac lobe at q sends nothing towards one point
    let ok = (qs.alive & sensor.alive).and_not(qs.delta);
    let ok = ok & cos_q.value().gt(zero) & cos_s.value().gt(zero) & d2.value().gt(zero);
    let ok = ok
        & resolvable(
            &qs.p.value(),
            ctx.scene.offset_scale,
            cos_q.value(),
            cos_s.value(),
            dist.value(),
        );
    let ok = ok & window::within(ctx.opl_budget, d.value());
    if ok.none() {
        return;
    }
    let ok = ok
        & visible_between(
            &ctx.accel,
            &segment_end(pk.light, s - 1),
            &segment_end(pk.camera, 0),
            ctx.scene.offset_scale,
            ok,
            &mut pk.counts.rays,
        );
    if ok.none() {
        return;
    }
    // the sensor's first direction towards q_s, in area measure at q_s: cosine-weighted, or
    // the mixture with aiming at the hidden shapes (q_s is the first hit: the join is clear)
    let mut pdf_dir = cos_s.value().mul_f(std::f32::consts::FRAC_1_PI);
    if let Some(targets) = ctx.nlos.as_ref().and_then(|n| n.hidden.as_ref()) {
        let (p_cos, r2, cos_1) = (pdf_dir, d2.value(), cos_q.value());
        let mixed: [f32; 8] =
            std::array::from_fn(|i| targets.mixture_pdf(p_cos.lane(i), qs.prim[i], r2.lane(i), cos_1.lane(i)));
        pdf_dir = V::<R>::from_lanes(&mixed[..R::LANES]);
    }
    let camera_pdf = to_area(&sensor.p.value(), &qs, pdf_dir);
    let lower = pk.light_tracing_ratios(s, camera_pdf);
    let f_q = qs.f_between(ctx, &(pk.light[s - 2].p - qs.p).normalize(), &dir, false);
    // the sensor vertex's weight is its importance ρ_s/π (`walk::sensor_subpath`)
    let g = cos_q * cos_s / d2;
    let contrib = (qs.beta * f_q * sensor.beta).scale(g * R::from_value(weight(lower, V::<R>::zero())));
    let d64 = joined_opl64(ctx, &qs, &sensor);
    let emitter = pk.origin.emitter;
    pk.deposit_own_pixels((s, 1), &emitter, d, d64.as_ref(), &contrib, ok);
}
