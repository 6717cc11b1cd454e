//! Importance transport from given surface points to the pinhole, 8 lanes at a time: the
//! sensor subpaths of the boundary stage (Algorithm 2, EstimateSensorSubpath).
//!
//! From a start point x_S that light reaches along a given direction, the walk joins each
//! vertex to the pinhole (the t = 1 connection of light tracing, Veach 1997 §10.2) and
//! continues by BSDF sampling. A pinhole cannot be hit by a ray, so the connections are the
//! only strategy and need no MIS weights. Each connection is a term: β · f_s · |cos θ_x| / r² ·
//! W (W = 1/(a cos³θ), `CameraProjection`), without the pixel filter, which the caller applies
//! at the term's film point. The steps are the kernel's own: the scattering step
//! (`transport::scatter`), Embree's 8-wide queries with the window cut on t_far, surface
//! points rebuilt from barycentrics, and shadow segments moved off both ends.
//!
//! In an NLOS capture (`super::nlos`) each lane's walk joins its vertices to the lane's sensor
//! point on the relay wall instead (`SurfaceStarts::sensor`), a point with importance
//! f_r·|cos θ_s| = ρ/π·cos θ_s per steradian (`NlosSensor::project`; no pixel filter: the film
//! point is the sensor's), its counted leg to the SPAD added to each term's OPL; the shadow
//! segment stops short of the wall's surface at the sensor point, as at a laser spot.

use super::bsdf::{Lobes, albedo, diffuse_eval};
use super::camera::LaneProjection;
use super::context::RenderContext;
use super::deposit::PathCounts;
use super::opl::points64;
use super::path::SurfaceStarts;
use super::surface::{SurfacePoint, behind_one_sided, resolvable, surface_at};
use super::trace::{SegmentEnd, next_hits, spawn_point, visible_between};
use super::transport::{scatter, scatter_lobes};
use super::window;
use crate::kernel::{Mask, PathSampler, Real, Spectrum, V3};

type V<R> = <R as Real>::Value;

/// One connection of an importance walk to the pinhole.
#[derive(Clone, Copy, Debug)]
pub struct ImportanceTerm<const C: usize> {
    /// β · f_s · |cos θ_x| / r² · W per channel (no pixel filter).
    pub value: [f32; C],
    /// OPL from the start point to the pinhole (the start's own `opl` not included); 0 for
    /// the camera leg of an unwarped film.
    pub opl: f64,
    /// Film point (pixels).
    pub fx: f32,
    pub fy: f32,
    /// Scattering vertices, the start included (1: the start point itself is joined).
    pub scatters: u32,
}

/// Walks from each lane's start point (`starts.out`: the side light leaves it to, i.e. the
/// reverse of its arrival direction; `starts.opl`: the OPL the path already has, for the
/// window cut) over at most `max_scatters[lane]` scattering vertices, and calls
/// `emit(lane, term)` for every finite connection to the pinhole. Lanes whose limit is 0 stay
/// idle. Random numbers: path ids `ids`, from dimension `starts.dim` on.
pub fn trace_importance_packet<R: Real, const C: usize>(
    ctx: &RenderContext,
    seed: u64,
    ids: &[u64],
    starts: &SurfaceStarts,
    max_scatters: &[u32; 8],
    counts: &mut PathCounts,
    mut emit: impl FnMut(usize, &ImportanceTerm<C>),
) {
    debug_assert!(R::DERIVS == 0 && ids.len() <= R::LANES);
    let zero = V::<R>::zero();
    let scene = ctx.scene;
    let exact = ctx.opl.f64_paths;
    let unwarp = scene.film.unwarp;
    let cam = &ctx.camera;
    let eye = V3::<V<R>>::splat(cam.position);
    let eye64 = cam.position.as_dvec3();
    let lanes = ids.len();
    let mut sampler = PathSampler::new(seed, ids);
    sampler.set_dim(starts.dim);
    let limit = V::<R>::from_lanes(&max_scatters.map(|m| m as f32)[..R::LANES]);
    let deepest = max_scatters[..lanes].iter().copied().max().unwrap_or(0);
    let mut in_use = [false; 8];
    in_use[..lanes].iter_mut().for_each(|b| *b = true);
    let mut active = <R as Real>::Mask::from_bools(&in_use[..R::LANES]);

    let mut x = SurfacePoint::<R> {
        p: V3::from_lane_vecs(&starts.p[..R::LANES]),
        n: V3::from_lane_vecs(&starts.n[..R::LANES]),
        jacobian: R::one(),
        prim: starts.prim,
    };
    // the direction the path arrived along (light travels x_L → x_S, then on to the pinhole)
    let mut ray_d: V3<V<R>> = -V3::from_lane_vecs(&starts.out[..R::LANES]);
    let mut beta = Spectrum::<R, C>::splat(R::one());
    let mut opl = R::from_lanes(&starts.opl.map(|d| d as f32)[..R::LANES]);
    let mut opl64 = starts.opl;
    let mut x64 = starts.p64;
    // the index of the medium each lane is in (`starts.eta`, then changed by each refraction)
    let mut eta_med = V::<R>::from_lanes(&starts.eta[..R::LANES]);
    // an NLOS capture's walks end at each lane's sensor point (`super::nlos`), whose leg to
    // the SPAD is in every term's OPL where the capture counts it
    let sensors = ctx
        .nlos
        .as_ref()
        .map(|n| SensorPoints::<R, C>::new(n, &starts.sensor, scene.eta));
    let unblocked_first = <R as Real>::Mask::from_bools(&starts.unblocked_first[..R::LANES]);
    let spad_leg = sensors
        .as_ref()
        .map_or(zero, |s| V::<R>::from_lanes(&s.spad_leg.map(|l| l as f32)[..R::LANES]));

    for j in 1..=deepest {
        active = active & V::<R>::splat(j as f32).le(limit);
        // the back of a one-sided material is black: the walk ends there
        active = active.and_not(behind_one_sided::<V<R>>(ctx, &x.prim, &x.n.value(), &ray_d, active));
        // Lambertian scenes keep their path; any other material goes through its lobes
        let lobes = (!ctx.diffuse_only).then(|| Lobes::<R, C>::gather(ctx, &x.prim));
        let f = match &lobes {
            None => diffuse_eval(albedo::<R, C>(ctx, &x.prim)),
            Some(_) => Spectrum::zero(),
        };
        if lobes.is_none() {
            active = active & f.max_value().gt(zero);
        }
        if active.none() {
            break;
        }
        let (p, n) = (x.p.value(), x.n.value());
        let side = -ray_d;

        // the connection to the pinhole, or to each lane's sensor point
        // a sensor point is a surface point too, with its own cosine (the pinhole is not)
        let (proj, eye, rho, cos_s) = match &sensors {
            None => (cam.project_lanes(&p), eye, None, V::<R>::one()),
            Some(s) => {
                let (proj, rho, cos_s) = s.project(&p);
                (proj, s.points, Some(rho), cos_s)
            }
        };
        let dist = proj.dist2.sqrt();
        let cos_x = n.dot(eye - p) * V::<R>::safe_div(V::<R>::one(), dist);
        // a rough dielectric also sends light on through itself to a pinhole on its far
        // side (the only strategy that reaches a pinhole, so it must), in that side's medium
        let (through, leg_eta) = match &lobes {
            Some(l) if l.dielectric.any() => {
                let d = l.dielectric.and_not(l.delta);
                let far = V::<R>::select(cos_x.gt(zero), l.eta_ext.value(), l.eta_int.value());
                (d, V::<R>::select(d, far, eta_med))
            }
            _ => (<R as Real>::Mask::splat(false), eta_med),
        };
        let transmits = through & (cos_x * n.dot(side)).lt(zero);
        let facing = (cos_x * n.dot(side)).gt(zero) | transmits;
        let leg = if unwarp { zero } else { dist * leg_eta + spad_leg };
        let d = opl.value() + leg;
        let ok = active
            & proj.visible
            & facing
            & window::within(ctx.opl_budget, d)
            & resolvable(&p, ctx.scene.offset_scale, cos_x, cos_s, dist);
        if ok.any() {
            // leaving through the surface, the origin is not stepped back along the arrival
            let here = SegmentEnd {
                p,
                n,
                w_in: V3::select(transmits, V3::zero(), ray_d),
            };
            // a sensor point lies on the wall: the segment stops short of its surface
            let pinhole = SegmentEnd {
                p: eye,
                n: sensors.as_ref().map_or(V3::zero(), |s| s.normals),
                w_in: V3::zero(),
            };
            // lanes whose first connection is taken as unblocked (`SurfaceStarts`)
            let given = if j == 1 {
                unblocked_first
            } else {
                <R as Real>::Mask::splat(false)
            };
            let scale = ctx.scene.offset_scale;
            let ok =
                ok & (visible_between(&ctx.accel, &here, &pinhole, scale, ok.and_not(given), &mut counts.rays) | given);
            let factor = cos_x.abs() * V::<R>::safe_div(proj.importance, proj.dist2);
            let f = match &lobes {
                None => f,
                Some(l) => {
                    // light arrives from `side`, leaves towards the pinhole (zero on Dirac lobes)
                    let to_eye = (eye - p) * V::<R>::safe_div(V::<R>::one(), dist);
                    l.eval(&V3::from_value(n), &V3::from_value(to_eye), &V3::from_value(side), true)
                }
            };
            let mut value = (beta * f).scale(R::from_value(factor));
            if let Some(rho) = &rho {
                value = value * *rho;
            }
            for i in 0..R::LANES {
                if !ok.bit(i) {
                    continue;
                }
                let eye64 = sensors.as_ref().map_or(eye64, |s| s.points64[i]);
                let opl_i = match (exact, unwarp) {
                    (true, false) => {
                        opl64[i]
                            + leg_eta.lane(i) as f64 * (eye64 - x64[i]).length()
                            + sensors.as_ref().map_or(0.0, |s| s.spad_leg[i])
                    }
                    (true, true) => opl64[i],
                    (false, _) => d.lane(i) as f64,
                };
                let term = ImportanceTerm {
                    value: std::array::from_fn(|c| value.0[c].lane(i)),
                    opl: opl_i - starts.opl[i],
                    fx: proj.fx.lane(i),
                    fy: proj.fy.lane(i),
                    scatters: j,
                };
                if term.opl.is_finite() && term.value.iter().all(|v| v.is_finite()) {
                    emit(i, &term);
                } else {
                    counts.non_finite += 1;
                }
            }
        }
        if j == deepest {
            break;
        }
        active = active & V::<R>::splat(j as f32).lt(limit);
        // the window cut ahead of this vertex: the pinhole beyond the OPL left (`super::window`)
        if let Some(b) = ctx.camera_box.as_ref().filter(|_| sensors.is_none()) {
            active = active & b.reachable(ctx.opl_budget, opl.value(), &p);
        }
        if active.none() {
            break;
        }

        // on by sampling the BSDF
        let (dir, back) = match &lobes {
            None => (
                scatter(ctx, &mut sampler, &n, &side, &f, &mut beta, &mut active, j).0,
                ray_d,
            ),
            // importance transport: the direction the light leaves in, given where it came from
            Some(l) => {
                let s = scatter_lobes(ctx, &mut sampler, l, &n, &side, false, &mut beta, &mut active, j);
                // a refracted ray starts off the far side, in the medium there
                let inside = n.dot(s.wi).lt(zero);
                let lv = l.value();
                eta_med = V::<R>::select(s.transmitted, V::<R>::select(inside, lv.eta_int, lv.eta_ext), eta_med);
                (s.wi, V3::select(s.transmitted, V3::zero(), ray_d))
            }
        };
        let o = spawn_point(&p, &n, &back, &dir, ctx.scene.offset_scale);
        let (hit, found) = next_hits(
            &ctx.accel,
            ctx.opl_budget,
            &o,
            &dir,
            opl.value(),
            eta_med,
            true,
            active,
            false,
            &mut counts.rays,
        );
        active = found;
        if active.none() {
            break;
        }
        let y = surface_at::<R>(ctx, &hit.prim, hit.u, hit.v);
        opl += (y.p - x.p).length() * R::from_value(eta_med);
        if exact {
            let u: [f32; 8] = std::array::from_fn(|i| if i < R::LANES { hit.u.lane(i) } else { 0.0 });
            let v: [f32; 8] = std::array::from_fn(|i| if i < R::LANES { hit.v.lane(i) } else { 0.0 });
            let y64 = points64(ctx, R::LANES, &hit.prim, &u, &v);
            for i in 0..R::LANES {
                if active.bit(i) {
                    opl64[i] += eta_med.lane(i) as f64 * (y64[i] - x64[i]).length();
                }
            }
            x64 = y64;
        }
        x = y;
        ray_d = dir;
    }
}

/// The sensor point each lane's walk connects to in an NLOS capture (`super::nlos`): its
/// position, the wall's ρ there, and its counted leg to the SPAD (η times its length, or 0).
struct SensorPoints<R: Real, const C: usize> {
    points: V3<V<R>>,
    points64: [glam::DVec3; 8],
    normals: V3<V<R>>,
    rho: Spectrum<R, C>,
    seen: <R as Real>::Mask,
    spad_leg: [f64; 8],
}

impl<R: Real, const C: usize> SensorPoints<R, C> {
    fn new(scan: &super::nlos::NlosSensor, sensor: &[usize; 8], eta: f32) -> Self {
        let at = |i: usize| &scan.sensors[sensor[i]];
        let pts: [glam::Vec3; 8] = std::array::from_fn(|i| at(i).p);
        let nrm: [glam::Vec3; 8] = std::array::from_fn(|i| at(i).n);
        let seen: [bool; 8] = std::array::from_fn(|i| scan.seen[sensor[i]]);
        let rho = Spectrum(std::array::from_fn(|c| {
            let v: [f32; 8] = std::array::from_fn(|i| scan.albedo[sensor[i]][c]);
            R::from_lanes(&v[..R::LANES])
        }));
        Self {
            points: V3::from_lane_vecs(&pts[..R::LANES]),
            points64: pts.map(|q| q.as_dvec3()),
            normals: V3::from_lane_vecs(&nrm[..R::LANES]),
            rho,
            seen: <R as Real>::Mask::from_bools(&seen[..R::LANES]),
            spad_leg: std::array::from_fn(|i| eta as f64 * scan.spad_leg[sensor[i]]),
        }
    }

    /// The connection from `p` to each lane's sensor point s as the pinhole's projection
    /// gives it (film point unused: the caller knows the sensor), with importance
    /// |cos θ_s|/π per steradian (f_r = ρ/π, ρ returned per channel: the scan's importance,
    /// the lane form of `NlosSensor::project`); not visible behind the wall or where the SPAD
    /// does not see s. Also returns cos θ_s, for the connection's [`resolvable`] test.
    fn project(&self, p: &V3<V<R>>) -> (LaneProjection<V<R>>, Spectrum<R, C>, V<R>) {
        let zero = V::<R>::zero();
        let d = *p - self.points;
        let dist2 = d.length_squared();
        let cos = self.normals.dot(d) * V::<R>::safe_div(V::<R>::one(), dist2.sqrt());
        let visible = self.seen & cos.gt(zero) & dist2.gt(zero) & dist2.is_finite();
        let proj = LaneProjection {
            fx: zero,
            fy: zero,
            importance: cos * V::<R>::splat(std::f32::consts::FRAC_1_PI),
            dist2,
            visible,
        };
        (proj, self.rho, cos)
    }
}
