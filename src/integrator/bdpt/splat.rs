//! The t = 1 strategy (light tracing): the light subpath's vertex s − 1 joined to the
//! pinhole. It lands on whichever pixels the filter around its film point reaches, so it
//! is splatted into the chunk's full-frame film.
//!
//! Contribution to pixel j: β_L · f(q_s) · |cos θ_q| / r² · W_j / N, with the importance
//! W_j = h_j(u) / (a cos³θ) (`CameraProjection`) and N pixels (one light subpath per camera
//! subpath, so each pixel gets N times more light-tracing samples than camera samples).
//!
//! Derivatives: q_s moves with its surface, so its film point u moves too. The splat weight
//! h_j(u(θ)) is differentiated through the filter, ḣ_j = ∂h/∂u_x·u̇_x + ∂h/∂u_y·u̇_y, which
//! needs a continuous filter (tent, Gaussian). A box filter's h_j jumps at pixel borders,
//! where the derivative would be a boundary term that we do not estimate; so with a box
//! filter a derivative render disables t = 1 altogether (density 0 in the MIS, so the other
//! strategies' weights still sum to 1, see [`super::mis::allowed`]).

use super::Packet;
use super::connect::towards;
use super::mis::{allowed, path_pdfs, ratio_sums};
use super::vertex::{camera_dir_pdf, to_area};
use crate::integrator::deposit::LaneContribution;
use crate::integrator::surface::offset_origin;
use crate::integrator::trace::unoccluded;
use crate::kernel::{Mask, Real, V3};

type V<R> = <R as Real>::Value;

/// s ≥ 2, t = 1.
pub fn splat_to_camera<R: Real, const C: usize>(pk: &mut Packet<'_, '_, R, C>, s: usize) {
    let ctx = pk.ctx;
    let cam = &ctx.camera;
    let qs = pk.light[s - 1];
    let proj = cam.project_lanes(&qs.p);
    let (dir, dist, _) = towards(&qs.p, &V3::splat(cam.position));
    let cos_q = qs.n.dot(dir);
    let zero = V::<R>::zero();
    let ok = qs.alive & proj.visible & cos_q.value().gt(zero);
    if ok.none() {
        return;
    }
    let o = offset_origin(&qs.p.value(), &qs.n.value(), &dir.value());
    let to_o = V3::splat(cam.position) - o;
    let len = to_o.length();
    let ray_d = to_o * V::<R>::safe_div(V::<R>::one(), len);
    let ok = ok & unoccluded(&ctx.accel, &o, &ray_d, zero, len, ok, &mut pk.counts.rays);
    if ok.none() {
        return;
    }
    let pixels = (ctx.scene.film.width * ctx.scene.film.height) as f32;
    // camera density at q_s with h = 1; the light-side ratio sums all carry pe[s−1]², so the
    // weight for pixel j is 1 / (1 + h_j² · lower)
    let camera_pdf = to_area(
        &V3::splat(cam.position),
        &qs,
        camera_dir_pdf(V::<R>::one(), proj.importance.value(), pixels),
    );
    path_pdfs(&pk.light[..s], &pk.camera[..1], zero, camera_pdf, pk.pl, pk.pe);
    let (delta, t1, n) = (pk.origin.delta, pk.t1_enabled, s + 1);
    let (lower, _) = ratio_sums(pk.pl, pk.pe, s, |sp| allowed(n, sp, delta, t1));
    let g = cos_q * proj.importance / proj.dist2;
    let contrib = (qs.beta * qs.f).scale(g.mul_f(1.0 / pixels));
    let d = if ctx.scene.film.unwarp {
        qs.opl
    } else {
        qs.opl + pk.eta * dist
    };
    let cam64 = cam.position.as_dvec3();
    let d64: [f64; 8] = std::array::from_fn(|i| match i < R::LANES && !ctx.scene.film.unwarp {
        true => qs.opl64[i] + pk.eta.value().lane(i) as f64 * (qs.p64[i] - cam64).length(),
        false => qs.opl64[i],
    });
    let exact = ctx.opl.f64_paths.then_some(&d64);
    let n_k = R::DERIVS.min(ctx.motion.len()).min(16);
    for i in 0..R::LANES {
        if !ok.bit(i) {
            continue;
        }
        let Some(lc) = LaneContribution::<C>::extract(ctx, pk.origin.emitter[i], d, exact, &contrib, i) else {
            pk.counts.non_finite += 1;
            continue;
        };
        let (fx, fy) = (proj.fx.lane(i), proj.fy.lane(i));
        let dfx: [f32; 16] = std::array::from_fn(|k| if k < n_k { proj.fx.deriv_lane(k, i) } else { 0.0 });
        let dfy: [f32; 16] = std::array::from_fn(|k| if k < n_k { proj.fy.deriv_lane(k, i) } else { 0.0 });
        if !dfx.iter().chain(&dfy).all(|v| v.is_finite()) {
            pk.counts.non_finite += 1;
            continue;
        }
        let lower_i = lower.lane(i);
        let film = &mut *pk.film;
        cam.for_each_pixel(fx, fy, |px, py, h, dh_dx, dh_dy| {
            let w = 1.0 / (1.0 + h * h * lower_i);
            let hdot: [f32; 16] = std::array::from_fn(|k| (dh_dx * dfx[k] + dh_dy * dfy[k]) * w);
            film.add(ctx, (s, 1), px as usize, py as usize, &lc, h * w, &hdot[..n_k]);
        });
    }
}

#[cfg(test)]
mod tests {
    use crate::integrator::camera::CameraSampler;
    use crate::kernel::{Dual8, Real, V3};
    use crate::scene::{Camera, PixelFilter};
    use glam::Vec3;

    /// The film point, importance and distance of a moving scene point carry the derivatives
    /// of their f32 counterparts (central differences), which is what the t = 1 splat weight
    /// h_j(u(θ)) is differentiated through.
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
