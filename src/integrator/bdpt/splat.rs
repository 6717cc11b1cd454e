//! The t = 1 strategy (light tracing): the light subpath's vertex s − 1 joined to the
//! pinhole. It lands on whichever pixels the filter around its film point reaches, so it
//! goes to the unit's sink, which keeps what lands outside its tile for the driver
//! (`super::film`).
//!
//! Contribution to pixel j: β_L · f(q_s) · |cos θ_q| / r² · W_j / N, with the importance
//! W_j = h_j(u) / (a cos³θ) (`CameraProjection`) and N pixels (one light subpath per camera
//! subpath, so each pixel gets N times more light-tracing samples than camera samples).
//!
//! **Derivatives: one parameterisation for every strategy.** The MIS weights are constants
//! for the derivative (Algorithm 1), and Σ_s w_s = 1 makes the weighted sum of the
//! strategies' derivatives the derivative of the image only when every strategy moves a
//! path the same way as θ changes (the weights' derivatives then sum to 0 along that one
//! motion). The path tracer and the strategies with t ≥ 2 move the vertex next to the
//! pinhole along its fixed camera ray and every other vertex with its surface. So here too
//! the vertex q that the pinhole sees is moved along the camera ray through its film point
//! u: y(θ) = o + t(θ)·ω (`ray_plane_point`), with u, and so h_j(u), fixed. In film
//! coordinates W_j·G(y ↔ pinhole)·dA(y)/du depends on u alone, so that factor (the
//! importance, cos θ_q / r² and q's area Jacobian) is a constant, and the derivative comes
//! from the rest of the path through y: the geometry term of the segment q_{s−2} → y (q's
//! material-form carrier `geo` is divided out of β_L and y's put in), the BSDF at y, and the
//! OPL d = d(q_{s−2}) + η(‖y − q_{s−2}‖ + ‖pinhole − y‖). Any pixel filter, box included,
//! then gives the derivative of the rendered image (tests/bdpt_fd.rs).

use super::Packet;
use super::connect::towards;
use super::vertex::segment_end;
use super::vertex::{camera_dir_pdf, to_area};
use super::walk::geometry_carrier;
use crate::integrator::deposit::LaneContribution;
use crate::integrator::path::ray_plane_point;
use crate::integrator::sink::Sink;
use crate::integrator::trace::{SegmentEnd, visible_between};
use crate::integrator::window;
use crate::kernel::{Mask, Real, V3};

type V<R> = <R as Real>::Value;

/// s ≥ 2, t = 1.
pub fn splat_to_camera<R: Real, const C: usize, S: Sink<C>>(pk: &mut Packet<'_, '_, R, C, S>, s: usize) {
    let ctx = pk.ctx;
    let cam = &ctx.camera;
    let qs = pk.light[s - 1];
    let q = qs.p.value();
    let eye = V3::splat(cam.position);
    let proj = cam.project_lanes(&q);
    let (dir, _, _) = towards(&q, &eye);
    let cos_q = qs.n.value().dot(dir);
    let zero = V::<R>::zero();
    // the window cut (`integrator::window`): light paths that reach the pinhole past it
    let d_value = qs.opl.value() + camera_leg(ctx, qs.eta_in.value(), &q, &eye);
    // a Dirac lobe at q sends nothing towards the pinhole
    let ok = qs.alive.and_not(qs.delta) & proj.visible & cos_q.gt(zero);
    let ok = ok & window::within(ctx.opl_budget, d_value);
    if ok.none() {
        return;
    }
    let pinhole = SegmentEnd {
        p: eye,
        n: V3::zero(),
        w_in: V3::zero(),
    };
    let end = segment_end(pk.light, s - 1);
    let ok = ok
        & visible_between(
            &ctx.accel,
            &end,
            &pinhole,
            ctx.scene.offset_scale,
            ok,
            &mut pk.counts.rays,
        );
    if ok.none() {
        return;
    }
    let pixels = (ctx.scene.film.width * ctx.scene.film.height) as f32;
    // camera density at q_s with h = 1; the light-side ratio sums all carry pe[s−1]², so the
    // weight for pixel j is 1 / (1 + h_j² · lower)
    let camera_pdf = to_area(&eye, &qs, camera_dir_pdf(V::<R>::one(), proj.importance, pixels));
    let lower = pk.light_tracing_ratios(s, camera_pdf);
    let camera_factor = (cos_q * proj.importance / proj.dist2).mul_f(1.0 / pixels);
    let prev = &pk.light[s - 2];
    let (beta, d, y) = if R::DERIVS > 0 {
        // q slides along its camera ray (module docs): y(θ), with q's own motion divided out
        let y = ray_plane_point(&V3::from_value(eye), &V3::from_value(-dir), &qs.p, &qs.n);
        let carrier = geometry_carrier(prev, &y, &qs.n, ctx.scene.offset_scale);
        let beta = qs.beta.scale(R::safe_div(carrier, qs.geo));
        (
            beta,
            prev.opl + qs.eta_in * (y - prev.p).length() + camera_leg(ctx, qs.eta_in, &y, &eye),
            y,
        )
    } else {
        (qs.beta, qs.opl + camera_leg(ctx, qs.eta_in, &qs.p, &eye), qs.p)
    };
    // f at q (importance transport) between its predecessor and the pinhole
    let to_eye = (V3::from_value(eye) - y).normalize();
    let f = qs.f_between(ctx, &(prev.p - y).normalize(), &to_eye, false);
    let contrib = (beta * f).scale(R::from_value(camera_factor));
    let cam64 = cam.position.as_dvec3();
    let d64 = ctx.opl.f64_paths.then(|| {
        std::array::from_fn::<f64, 8, _>(|i| match i < R::LANES && !ctx.scene.film.unwarp {
            true => qs.opl64[i] + qs.eta_in.value().lane(i) as f64 * (qs.p64[i] - cam64).length(),
            false => qs.opl64[i],
        })
    });
    let exact = d64.as_ref();
    for i in 0..R::LANES {
        if !ok.bit(i) {
            continue;
        }
        let Some(lc) = LaneContribution::<C>::extract(ctx, pk.origin.emitter[i], d, exact, &contrib, i) else {
            pk.counts.non_finite += 1;
            continue;
        };
        let lower_i = lower.lane(i);
        let sink = &mut *pk.sink;
        cam.for_each_pixel(proj.fx.lane(i), proj.fy.lane(i), |px, py, h| {
            let w = 1.0 / (1.0 + h * h * lower_i);
            sink.add(ctx, (s, 1), px as usize, py as usize, &lc, h * w);
        });
    }
}

/// η‖pinhole − y‖, the last leg of a light-tracing path, or 0 when the film is unwarped.
#[inline(always)]
fn camera_leg<R: Real>(ctx: &crate::integrator::context::RenderContext, eta: R, y: &V3<R>, eye: &V3<V<R>>) -> R {
    if ctx.scene.film.unwarp {
        R::zero()
    } else {
        eta * (V3::from_value(*eye) - *y).length()
    }
}

#[cfg(test)]
mod tests {
    use crate::integrator::camera::CameraSampler;
    use crate::kernel::{Dual8, Real, V3};
    use crate::scene::{Camera, PixelFilter};
    use glam::Vec3;

    /// The film point, importance and distance of a moving scene point carry the derivatives
    /// of their f32 counterparts (central differences): `project_lanes` is right for any
    /// number type, though light tracing now calls it with plain lanes only.
    #[test]
    fn projection_derivatives_match_finite_differences() {
        let cam = Camera {
            position: Vec3::new(0.3, 1.0, 3.0),
            look_at: Vec3::new(0.0, 0.9, 0.0),
            up: Vec3::Y,
            fov_y_deg: 45.0,
        };
        let cs = CameraSampler::new(&cam, 40, 30, PixelFilter::Tent { radius: 1.0 });
        let points = [
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.5, 0.4, -0.5),
            Vec3::new(-0.7, 1.6, 0.3),
        ];
        let vel = Vec3::new(0.3, -0.8, 0.5);
        for p in points {
            let lanes = [p; 8];
            let mut pd = V3::<Dual8<1>>::from_lane_vecs(&lanes);
            pd.x = pd.x.with_deriv_lanes(0, &[vel.x; 8]);
            pd.y = pd.y.with_deriv_lanes(0, &[vel.y; 8]);
            pd.z = pd.z.with_deriv_lanes(0, &[vel.z; 8]);
            let pr = cs.project_lanes(&pd);
            let e = 1e-3;
            let (a, b) = (cs.project(p + vel * e).unwrap(), cs.project(p - vel * e).unwrap());
            let c = cs.project(p).unwrap();
            assert!((pr.fx.lane(0) - c.fx).abs() < 1e-3 && (pr.fy.lane(0) - c.fy).abs() < 1e-3);
            for (name, ad, fd, scale) in [
                ("fx", pr.fx.deriv_lane(0, 0), (a.fx - b.fx) / (2.0 * e), 1.0),
                ("fy", pr.fy.deriv_lane(0, 0), (a.fy - b.fy) / (2.0 * e), 1.0),
                (
                    "importance",
                    pr.importance.deriv_lane(0, 0),
                    (a.importance - b.importance) / (2.0 * e),
                    c.importance,
                ),
                ("dist2", pr.dist2.deriv_lane(0, 0), (a.dist2 - b.dist2) / (2.0 * e), 1.0),
            ] {
                assert!(
                    (ad - fd).abs() <= 2e-2 * (fd.abs() + scale),
                    "{name} at {p}: AD {ad} vs FD {fd}"
                );
            }
        }
    }
}
